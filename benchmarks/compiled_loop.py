"""What a Newton loop compiled whole would leave of a run: its increment scaling (issue 37, target 2).

The increment scaling of `paper` (time per increment at n = 500 000 over n = 50 000, target >= 8)
is held back by work that does not grow with n: the Python of the Newton loop, and for each
evaluation its own Python and the hand-off of its chunks to the other thread. ``whole_run.py
--split`` takes away the first (the evaluations alone); this harness takes away both. It records
the displacements at which a real run evaluates (``simulate``, the history benchmark's path or
Fig. 13's) and evaluates the same sequence again, back to back, two ways:

- ``python``: ``evaluate_unchecked`` for each, as the run does (the package's hand-off per call);
- ``compiled``: one compiled loop over the whole sequence, handed to the threads once
  (:func:`asperity_sim.threads.run_calls`): the calling thread posts each evaluation to the other
  through a flag and takes its share of the chunks (claimed, as the package's reduction does); the
  other thread waits for the next post in compiled code. No Python and no GIL between evaluations.
  Evaluations whose asperities fit ``SERIAL_ACTIVE_CHUNKS`` chunks run on the calling thread, as in
  the package.

Both read the same kernels (``reduce_parallel``, ``reduce_serial``, ``bounds``, ``finish``) and must
give the same bits (checked: every field of every evaluation). The two ways alternate, in both
orders, in one process; medians over ``--rounds``. What the compiled loop leaves out: the Newton
updates, predictors and recording between the evaluations (scalar arithmetic, or per step), so
its scaling is what such a loop could reach at best.

For both laws (an `mdr` trial reads the state its commits leave, so it cannot be replayed alone),
``kernels``: whole runs at both sizes, alternating, with the calling thread's time inside the
package's kernels summed (its share of each parallel call, and the serial kernels it calls): what a
loop compiled whole, trials and commits, with hand-offs that cost nothing, would take. It counts
the calls' dispatch from Python, which such a loop would not pay, and not the wait for a slower
thread, which it would; for `paper` it reads a little below the compiled replay above.

Run:   python benchmarks/compiled_loop.py [--rounds 9] [--paths benchmark,fig13]
Writes outputs/compiled_loop.json. About 90 s on 2 cores (67 s with --rounds 7).
"""

from __future__ import annotations

import argparse
import os
import platform
import threading
import time

import numba
import numpy as np

from asperity_sim import Population, laws, presets, simulate
from asperity_sim.atomics import cpu_pause, load_acquire, store_release
from asperity_sim.kernels import evaluate as evaluate_module
from asperity_sim.kernels import state as state_module
from asperity_sim.kernels.evaluate import Workspace, evaluate_unchecked, evaluation_from
from asperity_sim.kernels.layout import CHUNK, N_OUT, O_NA, SERIAL_ACTIVE_CHUNKS, finish
from asperity_sim.kernels.reach import bounds
from asperity_sim.kernels.specialise import kernels
from asperity_sim.kernels.state import ContactState
from asperity_sim.solve import run as run_module
from asperity_sim.solve import span as compiled_span
from asperity_sim.threads import run_calls

from whole_run import PATHS, law_kw, write

SIZES = (50_000, 500_000)
MAIL, DONE, CLAIMS, STOP = 0, 8, 16, -1  # the flags: a post, its done, the chunk counter (cache lines apart)
FIELDS = ("stress", "stderr", "covariance", "tangent", "n_contact", "n_slip", "n_partial", "mean_theta", "n_active",
          "contact_area", "contact_area_var", "contact_area_cov", "contact_area_grad")
_K = kernels("paper")
reduce_parallel, reduce_serial = _K["reduce_parallel"], _K["reduce_serial"]


@numba.njit(nogil=True)
def serve(flags, r, R, u, cos_phi, sin_phi, counts, reals, d, consts, theta_birth, partial):
    """The other thread: each posted evaluation's claimed chunks, until STOP is posted."""
    seen = 0
    while True:
        v = load_acquire(flags, MAIL)
        if v == seen:
            cpu_pause()
            continue
        if v == STOP:
            return
        seen = v
        reduce_parallel(r, R, u, cos_phi, sin_phi, counts[0], d, reals[0], reals[1], consts, theta_birth, reals[2],
                        partial, flags[CLAIMS:CLAIMS + 1], 0, counts[1])
        store_release(flags, DONE, v)


@numba.njit(nogil=True)
def evaluate_all(flags, r, R, u, cos_phi, sin_phi, R_min, counts, reals, d, consts, theta_birth, partial, deltas,
                 beta, scale, n, out, shared):
    """Row i of ``out``: the flat result at ``deltas[i]``, as ``at_contacts`` computes it; with ``shared`` the
    other thread (:func:`serve`) takes its share of each parallel evaluation."""
    r_o, k_e = reals[0], reals[1]
    epoch = 0
    for i in range(deltas.shape[0]):
        for a in range(3):
            d[a] = deltas[i, a]
        n_active, tan_max = bounds(r, R_min, r_o, k_e, beta, d, theta_birth)
        n_chunks = (n_active + CHUNK - 1) // CHUNK
        if n_chunks <= SERIAL_ACTIVE_CHUNKS:
            reduce_serial(r, R, u, cos_phi, sin_phi, R_min, deltas[i:i + 1], r_o, k_e, consts, beta, theta_birth, n,
                          scale, partial, out[i:i + 1])
            continue
        if shared:
            counts[0], counts[1], reals[2] = n_active, n_chunks, tan_max
            flags[CLAIMS] = 0
            epoch += 1
            store_release(flags, MAIL, epoch)
            reduce_parallel(r, R, u, cos_phi, sin_phi, n_active, d, r_o, k_e, consts, theta_birth, tan_max, partial,
                            flags[CLAIMS:CLAIMS + 1], 0, n_chunks)
            while load_acquire(flags, DONE) != epoch:
                cpu_pause()
        else:
            reduce_parallel(r, R, u, cos_phi, sin_phi, n_active, d, r_o, k_e, consts, theta_birth, tan_max, partial,
                            flags[0:0], 0, n_chunks)
        finish(partial, n_chunks, n, scale, out[i])
        out[i, O_NA] = n_active


@numba.njit(nogil=True)
def drive(flags, r, R, u, cos_phi, sin_phi, R_min, counts, reals, d, consts, theta_birth, partial, deltas, beta,
          scale, n, out, lo, hi):
    """Part ``lo .. hi`` of :func:`run_calls` (2 parts): 0 evaluates and then posts STOP, 1 serves; both on one
    thread: evaluates alone."""
    if lo == 1:
        serve(flags, r, R, u, cos_phi, sin_phi, counts, reals, d, consts, theta_birth, partial)
    elif hi == 1:
        evaluate_all(flags, r, R, u, cos_phi, sin_phi, R_min, counts, reals, d, consts, theta_birth, partial, deltas,
                     beta, scale, n, out, True)
        store_release(flags, MAIL, STOP)
    else:
        evaluate_all(flags, r, R, u, cos_phi, sin_phi, R_min, counts, reals, d, consts, theta_birth, partial, deltas,
                     beta, scale, n, out, False)


class Replay:
    """A population, the displacements its `paper` run evaluates at, and the two ways to evaluate them again."""

    def __init__(self, n, path):
        self.pop = pop = Population.sample(presets.R1, n, seed=1)
        self.deltas = self._deltas(path)
        self.state = ContactState(pop, laws.get("paper"), "follow")
        self.ws = Workspace(pop.n)
        r_o, k_e, _, _, _, self.beta, self.scale = pop.kernel_constants
        self.flags = np.zeros(3 * 8, dtype=np.int64)
        self.counts = np.zeros(2, dtype=np.int64)
        self.reals = np.array([r_o, k_e, 0.0])
        self.d = np.zeros(3)
        self.partial = np.zeros_like(self.ws.partial)
        self.out = np.zeros((len(self.deltas), N_OUT))

    def _deltas(self, path):
        seen, plain = [], run_module.evaluate_unchecked

        def recording(pop, d, state, ws):
            seen.append(d.copy())
            return plain(pop, d, state, ws)

        run_module.evaluate_unchecked = recording
        mode, compiled_span.MODE = compiled_span.MODE, "never"  # the Python loop, whose evaluations are seen here
        try:
            simulate(self.pop.params, path, population=self.pop, law="paper")
        finally:
            run_module.evaluate_unchecked, compiled_span.MODE = plain, mode
        return np.array(seen)

    def python(self):
        """Wall time [s] of the sequence through ``evaluate_unchecked``, and its evaluations."""
        t = time.perf_counter()
        evs = [evaluate_unchecked(self.pop, d, self.state, self.ws) for d in self.deltas]
        return time.perf_counter() - t, evs

    def compiled(self):
        """Wall time [s] of the sequence from :func:`drive`."""
        p = self.pop
        self.flags[:] = 0
        t = time.perf_counter()
        run_calls((drive, 2, (self.flags, *p.arrays, p.R_min, self.counts, self.reals, self.d, self.state.consts,
                              np.zeros(0), self.partial, self.deltas, self.beta, self.scale, p.n, self.out)))
        return time.perf_counter() - t

    def same_bits(self, evs):
        """Every field of every evaluation equal, bit for bit."""
        for i, ev in enumerate(evs):
            mine = evaluation_from(self.deltas[i], self.out[i])
            if not all(np.array_equal(np.asarray(getattr(ev, f)), np.asarray(getattr(mine, f))) for f in FIELDS):
                return False
        return True


def measure(name, rounds):
    replays = {n: Replay(n, PATHS[name]()) for n in SIZES}
    res = {}
    for n, rp in replays.items():
        rp.compiled()  # compiles the loop (not timed)
        _, evs = rp.python()
        res[str(n)] = {"evaluations": len(rp.deltas), "same_bits": rp.same_bits(evs)}
    times = {(n, way): [] for n in SIZES for way in ("python", "compiled")}
    for k in range(rounds):
        for n, rp in replays.items():
            first_python = k % 2 == 0  # both orders
            for way in (("python", "compiled") if first_python else ("compiled", "python")):
                times[(n, way)].append(rp.python()[0] if way == "python" else rp.compiled())
    for n in SIZES:
        for way in ("python", "compiled"):
            res[str(n)][f"{way}_s"] = float(np.median(times[(n, way)]))
        print(f"  {name:9s} n = {n:>7d}: {res[str(n)]['evaluations']} evaluations, python "
              f"{1e3 * res[str(n)]['python_s']:.1f} ms, compiled {1e3 * res[str(n)]['compiled_s']:.1f} ms, "
              f"same bits: {res[str(n)]['same_bits']}", flush=True)
    lo, hi = str(SIZES[0]), str(SIZES[1])
    res["scaling"] = {way: res[hi][f"{way}_s"] / res[lo][f"{way}_s"] for way in ("python", "compiled")}
    print(f"  {name:9s} evaluations at n = {hi} over n = {lo}: python {res['scaling']['python']:.2f}, "
          f"compiled {res['scaling']['compiled']:.2f} (target >= 8)", flush=True)
    return res


class InKernels:
    """A kernel that adds the calling thread's time inside it to ``spent[0]`` (other threads: not counted)."""

    def __init__(self, kernel, spent):
        self.kernel, self.spent = kernel, spent

    def __call__(self, *args):
        if threading.current_thread() is not threading.main_thread():
            return self.kernel(*args)
        t = time.perf_counter()
        try:
            return self.kernel(*args)
        finally:
            self.spent[0] += time.perf_counter() - t

    def __getattr__(self, name):  # py_func etc., for kernels.ahead
        return getattr(self.kernel, name)


SERIAL = ((evaluate_module, ("bounds", "finish")), (state_module, ("bounds", "assign_slots", "find_fresh")))
"""The kernels the Python of a run calls by name, besides its law's reductions (``kernels(law)``)."""


def kernel_time(law, name, rounds):
    """Whole runs of ``law`` on path ``name`` at both sizes, alternating: medians of the wall time and of the calling
    thread's time inside the kernels [s], and the scaling of each."""
    spent, table = [0.0], kernels(law)
    saved = dict(table), [(m, k, getattr(m, k)) for m, names in SERIAL for k in names]
    table.update({k: InKernels(f, spent) for k, f in saved[0].items()})
    for module, k, f in saved[1]:
        setattr(module, k, InKernels(f, spent))
    try:
        pops = {n: Population.sample(presets.R1, n, seed=1) for n in SIZES}
        path, rows = PATHS[name](), {n: [] for n in SIZES}
        for k in range(rounds + 1):
            for n, pop in pops.items():
                spent[0] = 0.0
                t = time.perf_counter()
                simulate(pop.params, path, population=pop, **law_kw(law))
                if k:  # the first round warms up
                    rows[n].append((time.perf_counter() - t, spent[0]))
    finally:
        table.update(saved[0])
        for module, k, f in saved[1]:
            setattr(module, k, f)
    res = {str(n): {"whole_s": float(np.median([r[0] for r in rows[n]])),
                    "kernels_s": float(np.median([r[1] for r in rows[n]]))} for n in SIZES}
    lo, hi = str(SIZES[0]), str(SIZES[1])
    res["scaling"] = {part: res[hi][f"{part}_s"] / res[lo][f"{part}_s"] for part in ("whole", "kernels")}
    print(f"  {law:5s} {name:9s} whole run {1e3 * res[lo]['whole_s']:.1f} and {1e3 * res[hi]['whole_s']:.1f} ms, in "
          f"kernels {1e3 * res[lo]['kernels_s']:.1f} and {1e3 * res[hi]['kernels_s']:.1f} ms: scaling whole "
          f"{res['scaling']['whole']:.2f}, kernels alone {res['scaling']['kernels']:.2f} (target >= 8)", flush=True)
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=9, help="alternations of the two ways (default 9)")
    ap.add_argument("--paths", default="benchmark,fig13", help="paths of whole_run.py (default both)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    out = {"machine": {"cpus": os.cpu_count(), "threads": numba.get_num_threads(), "python": platform.python_version(),
                       "numba": numba.__version__, "load_start": os.getloadavg()[0]}, "rounds": args.rounds}
    print("a paper run's evaluations replayed:")
    for name in args.paths.split(","):
        out[name] = measure(name, args.rounds)
    print("whole runs, the calling thread's time in kernels:")
    out["kernels"] = {f"{law} {name}": kernel_time(law, name, args.rounds)
                      for law in ("paper", "mdr") for name in args.paths.split(",")}
    out["machine"]["load_end"] = os.getloadavg()[0]
    write(out, "compiled_loop.json", t0)


if __name__ == "__main__":
    main()
