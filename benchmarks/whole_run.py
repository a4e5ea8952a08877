"""Whole runs of the two laws, side by side: time from the call to the return, peak memory, threads.

What it measures (R1, mdr with k = 16; every speed a ratio to something timed in the same
process, because absolute times drift on a shared machine):

1. **Whole-run cost of history**: ``simulate`` on one population, from the call to the return
   (setup, normal stage, shear stage, dataset), ``paper`` and ``mdr`` alternately (``--rounds``
   times), at n = 50 000 and 500 000, on two paths: the history benchmark's (sigma_1 to 300 MPa
   in 10 increments, Delta_2 to 10 um in 40) and the paper's Fig. 13 path (500 MPa in 40, 30 um
   in 40).  Reported: mdr / paper of the medians (target <= 5), and the time per increment at
   n = 500 000 over that at n = 50 000 for each law (target >= 8: no fixed per-increment work
   that small runs would see).  Sampling is not timed (the same for both laws).
2. **Peak memory**: each law on the history benchmark's path at ``--memory-sizes`` asperities,
   each in a fresh process, sampling included: the process's peak resident set (VmHWM), against
   the ``paper`` peak plus the springs of the contacts, read two ways: k springs in each of the
   two tangential directions (2 k float64) per contact at the largest contact count of the run
   (the issue's reading; target <= 1.1), and the springs the contacts have in contact at the end
   of the run (between k and 2k each: a contact grows after its springs are spaced).  The bytes
   the mdr state holds in use at the end are reported beside it, and the same run with the
   springs stored in float32 (``spring_dtype``, an option; float64 is the default): its peak
   against the same reference, and its largest stress difference from the float64 run.  A kernel
   compiled in the measured run (a cold cache, or the package's source edited while the benchmark
   runs) would put the compiler's memory in the peak: the record lists any (``compiled_in_run``),
   and the benchmark warns.
3. **Threads**: the same path at ``--thread-n`` asperities with 1 and with every thread numba
   has, alternately; the parallel efficiency t_1 / (p t_p) of each law's increments (target
   >= 0.9 from 1 to 2 threads).  On a machine shared with other jobs this is a lower bound.

Runs take the compiled increments wherever they cover a stage (:mod:`asperity_sim.solve.span`): the
warm-up compiles them, as ``asperity-sim warmup`` or a first run's compile-ahead helper would.

``--one-thread`` adds item 1 on one thread: the increment scaling without the hand-offs to the
other threads (what the fixed per-increment work of the Newton loop costs alone).

``--split`` measures only item 1 for ``paper`` in the Python loop (the compiled increments off), split
into the time in the evaluations (the kernel calls with their thin Python) and the rest of the run
(the predictor, the Newton loop, the commit and the recording, all Python): the increment scaling
each part would have alone (writes outputs/whole_run_split.json).

``--against COMMIT`` measures only item 1, for the code of COMMIT (a detached worktree in a
temporary folder) and for this checkout, each in fresh processes, alternating ``--alternations``
times: a change's effect read through the machine's drift (the medians of the processes are
compared).

Run:   python benchmarks/whole_run.py [--rounds 3] [--memory-sizes 1000000] [--thread-n 1000000] [--one-thread]
       python benchmarks/whole_run.py --split [--rounds 9]
       python benchmarks/whole_run.py --against COMMIT [--alternations 3]
Writes outputs/whole_run.json (``--against``: outputs/whole_run_against.json) and prints a table.
About 3 minutes on 2 cores (2026-11-27); ``--against`` about 5 minutes.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse
import json
import math
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

from asperity_sim import Population, paths, presets, simulate
from asperity_sim.laws.mdr.springs import springs_below
from asperity_sim.solve import span as compiled_span

OUT = Path(__file__).resolve().parent.parent / "outputs"
S, D = paths.STRESS, paths.DISPLACEMENT
K = 16


def bench_path():
    return paths.LoadPath((paths.Stage((S, D, D), (300e6, 0, 0), 10, name="normal"),
                           paths.Stage((S, D, D), (300e6, 10e-6, 0), 40, name="shear")), name="benchmark")


PATHS = {"benchmark": bench_path, "fig13": lambda: paths.constant_normal_shear(500e6, 30e-6)}


def law_kw(law):
    """Keywords of ``simulate`` for ``law``; ``mdr32`` is ``mdr`` with its springs stored in float32."""
    if law == "mdr32":
        return {"law": "mdr", "k": K, "spring_dtype": "float32"}
    return {"law": law, "k": K} if law == "mdr" else {"law": law}


def springs_in_contact(dn_c, h, R):
    """Springs in contact of each `mdr` contact from its committed overlap dn_c [m], spacing h [m] and radius R [m],
    counted as the kernels count them (:func:`asperity_sim.laws.mdr.springs.springs_below`)."""
    out = np.empty(dn_c.size, dtype=np.int64)
    _count_springs(np.ascontiguousarray(dn_c, dtype=float), np.ascontiguousarray(h * h / R, dtype=float), out)
    return out


@numba.njit(cache=True)
def _count_springs(dn_c, c, out):
    for i in range(dn_c.size):
        out[i] = springs_below(dn_c[i], c[i], math.sqrt(dn_c[i] / c[i]) if dn_c[i] > 0.0 else 0.0)


def run_time(pop, path, law):
    """Wall time [s] of ``simulate`` from the call to the return, and its increments."""
    t = time.perf_counter()
    ds = simulate(pop.params, path, population=pop, **law_kw(law))
    return time.perf_counter() - t, int(ds.sizes["step"] - 1)


def side_by_side(pop, path, rounds):
    """Median whole-run time of each law [s], alternating, and the increments of the path."""
    times = {"paper": [], "mdr": []}
    for _ in range(rounds):
        for law in times:
            t, n_inc = run_time(pop, path, law)
            times[law].append(t)
    return {law: float(np.median(t)) for law, t in times.items()}, n_inc, times


def whole_runs(sizes, rounds, label=""):
    out = {}
    for name, make in PATHS.items():
        path = make()
        res = {}
        for n in sizes:
            pop = Population.sample(presets.R1, n, seed=1)
            med, n_inc, every = side_by_side(pop, path, rounds)
            res[str(n)] = dict(paper_s=med["paper"], mdr_s=med["mdr"], mdr_over_paper=med["mdr"] / med["paper"],
                               increments=n_inc, rounds=every)
            print(f"  {label}{name:9s} n = {n:>7d}: paper {med['paper']:.3f} s, mdr {med['mdr']:.3f} s "
                  f"-> mdr / paper {med['mdr'] / med['paper']:.2f} (target <= 5)", flush=True)
        lo, hi = str(min(sizes)), str(max(sizes))
        res["increment_scaling"] = {law: res[hi][f"{law}_s"] / res[lo][f"{law}_s"] for law in ("paper", "mdr")}
        print(f"  {label}{name:9s} time per increment at n = {hi} over n = {lo}: "
              + ", ".join(f"{law} {v:.1f}" for law, v in res["increment_scaling"].items()) + " (target >= 8)")
        out[name] = res
    return out


def one_thread(sizes, rounds):
    """Item 1 on one thread: the increment scaling without hand-offs to other threads (``--one-thread``)."""
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        return whole_runs(sizes, rounds, label="1 thread: ")
    finally:
        numba.set_num_threads(threads)


def split(sizes, rounds):
    """Item 1 for ``paper`` in the Python loop (the compiled increments off), split: the time in the evaluations
    (``evaluate_unchecked``: the kernel calls and their thin Python) and the rest of the run (predictor, Newton loop,
    commit, recording: Python), medians over ``rounds`` runs after a first; the increment scaling of each part
    (``--split``)."""
    from asperity_sim.solve import run as run_module

    plain = run_module.evaluate_unchecked
    spent = [0.0, 0]

    def timed(*args):
        t = time.perf_counter()
        try:
            return plain(*args)
        finally:
            spent[0] += time.perf_counter() - t
            spent[1] += 1

    out = {}
    run_module.evaluate_unchecked = timed
    mode, compiled_span.MODE = compiled_span.MODE, "never"  # the Python loop, the one that calls evaluate_unchecked
    try:
        for name, make in PATHS.items():
            path, res = make(), {}
            for n in sizes:
                pop = Population.sample(presets.R1, n, seed=1)
                rows = []
                for _ in range(rounds + 1):
                    spent[:] = [0.0, 0]
                    t, _ = run_time(pop, path, "paper")
                    rows.append((t, spent[0], spent[1]))
                whole, evaluations, calls = (float(np.median(c)) for c in zip(*rows[1:]))
                res[str(n)] = {"whole_s": whole, "evaluations_s": evaluations, "rest_s": whole - evaluations,
                               "evaluations": calls}
                print(f"  split {name:9s} n = {n:>7d}: paper {1e3 * whole:.1f} ms, of which {1e3 * evaluations:.1f} ms in "
                      f"{calls:.0f} evaluations and {1e3 * (whole - evaluations):.1f} ms the rest", flush=True)
            lo, hi = str(min(sizes)), str(max(sizes))
            res["increment_scaling"] = {part: res[hi][f"{part}_s"] / res[lo][f"{part}_s"]
                                        for part in ("whole", "evaluations")}
            print(f"  split {name:9s} time at n = {hi} over n = {lo}: whole run "
                  f"{res['increment_scaling']['whole']:.2f}, evaluations alone {res['increment_scaling']['evaluations']:.2f}"
                  " (target >= 8)", flush=True)
            out[name] = res
    finally:
        run_module.evaluate_unchecked, compiled_span.MODE = plain, mode
    return out


MEMORY = r"""
import json, resource, sys
import numpy as np
sys.path.insert(0, sys.argv[3])
from whole_run import bench_path, law_kw, springs_in_contact
from asperity_sim import Population, presets, simulate
from asperity_sim.solve import run as driver
from numba.core import event

def peak_rss():
    # this process's own peak [B]: VmHWM starts anew at exec, where ru_maxrss keeps the parent's peak
    try:
        with open("/proc/self/status") as f:
            return next(int(l.split()[1]) * 1024 for l in f if l.startswith("VmHWM:"))
    except (OSError, StopIteration):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024

n, law = int(sys.argv[1]), sys.argv[2]
simulate(presets.R1, bench_path(), n=2000, **law_kw(law))  # kernels from the cache, small arrays
states = []
plain = driver.ContactState
class Kept(plain):
    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        states.append(self)
driver.ContactState = Kept
before = peak_rss()
with event.install_recorder("numba:compile") as compiles:  # a cache miss compiles here, and compiling costs memory
    pop = Population.sample(presets.R1, n, seed=1)
    ds = simulate(presets.R1, bench_path(), population=pop, **law_kw(law))
st = states[-1]
peak = peak_rss()  # before the accounting below copies the springs
held = 0
if st.has_history:  # the springs in contact at the end (the largest contact count): N of springs_below, per contact
    sa = st.state_arrays()
    live = sa["asp"] >= 0
    N = springs_in_contact(sa["dn_c"][live], sa["law1"][live], pop.R[sa["asp"][live]])
    held = int(np.minimum(N, st.n_stored).sum())
print(json.dumps({"n": n, "law": law, "peak_rss": peak, "peak_rss_before": before,
                  "contacts_max": int(ds.n_contact.values.max()), "contacts_end": int(ds.n_contact.values[-1]),
                  "springs_in_contact_end": held, "state_bytes": int(st.nbytes), "population_bytes": int(pop.nbytes),
                  "compiled_in_run": sorted({e.data["dispatcher"].py_func.__name__ for _, e in compiles.buffer}),
                  "stress": ds.stress.values.tolist()}))
"""


def memory_case(n, law):
    """The MEMORY script's record of ``law`` at n asperities, in a fresh process."""
    here = str(Path(__file__).resolve().parent)
    p = subprocess.run([sys.executable, "-c", MEMORY, str(n), law, here], capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(f"memory case n = {n}, law {law} failed:\n{p.stderr[-2000:]}")
    record = json.loads(p.stdout.strip().splitlines()[-1])
    if record["compiled_in_run"]:  # e.g. the package's source edited while the benchmark ran
        print(f"  warning: n = {n}, law {law} compiled {', '.join(record['compiled_in_run'])} in the measured "
              "run: its peak counts the compiler's memory", flush=True)
    return record


def memory(sizes):
    laws = ("paper", "mdr", "mdr32")
    for law in laws:  # fill the numba cache first: a compile in the measured process would set its peak
        memory_case(2000, law)
    out = {}
    for n in sizes:
        res = {law: memory_case(n, law) for law in laws}
        springs = res["mdr"]["contacts_max"] * 2 * K * 8
        ratio = res["mdr"]["peak_rss"] / (res["paper"]["peak_rss"] + springs)
        held = res["mdr"]["springs_in_contact_end"] * 2 * 8  # both components, float64
        ratio_held = res["mdr"]["peak_rss"] / (res["paper"]["peak_rss"] + held)
        # the float32 option: the same springs in half the bytes, against the same float64 reference
        ratio32 = res["mdr32"]["peak_rss"] / (res["paper"]["peak_rss"] + springs)
        s64, s32 = (np.array(res[law].pop("stress")) for law in ("mdr", "mdr32"))
        res["paper"].pop("stress")
        diff32 = float(np.abs(s32 - s64).max() / np.abs(s64).max())
        res.update(springs_bytes=springs, ratio=ratio, springs_in_contact_bytes=held, ratio_in_contact=ratio_held,
                   ratio_float32=ratio32, stress_difference_float32=diff32)
        out[str(n)] = res
        print(f"  n = {n}: peak paper {res['paper']['peak_rss'] / 2**20:.0f} MiB, mdr {res['mdr']['peak_rss'] / 2**20:.0f}"
              f" MiB; k springs for each of {res['mdr']['contacts_max']} contacts {springs / 2**20:.0f} MiB -> mdr / "
              f"(paper + springs) = {ratio:.2f} (target <= 1.1); the springs in contact at the end "
              f"({res['mdr']['springs_in_contact_end'] / res['mdr']['contacts_end']:.1f} per contact) "
              f"{held / 2**20:.0f} MiB -> {ratio_held:.2f}; the mdr state holds {res['mdr']['state_bytes'] / 2**20:.0f} MiB"
              f"; with float32 springs mdr {res['mdr32']['peak_rss'] / 2**20:.0f} MiB -> {ratio32:.2f} (largest stress "
              f"difference / largest stress {diff32:.1e})", flush=True)
    return out


def threads(n, rounds):
    """Increment time [s] per law with 1 and with every thread, alternating; efficiency t_1 / (p t_p)."""
    p_max = numba.get_num_threads()
    pop = Population.sample(presets.R1, n, seed=1)
    path = bench_path()
    out = {"n": n, "threads": p_max}
    for law in ("paper", "mdr"):
        t = {1: [], p_max: []}
        for _ in range(rounds):
            for p in t:
                numba.set_num_threads(p)
                s, n_inc = run_time(pop, path, law)
                t[p].append(s / n_inc)
        numba.set_num_threads(p_max)
        t1, tp = float(np.median(t[1])), float(np.median(t[p_max]))
        out[law] = dict(increment_1_s=t1, increment_p_s=tp, efficiency=t1 / (p_max * tp))
        print(f"  {law:5s} n = {n}: increment {1e3 * t1:.2f} ms on 1 thread, {1e3 * tp:.2f} ms on {p_max} -> "
              f"efficiency {t1 / (p_max * tp):.2f} (target >= 0.9)", flush=True)
    return out


AGAINST = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
import whole_run
import asperity_sim
from asperity_sim import Population, presets
print("CODE " + asperity_sim.__file__, flush=True)
warm = Population.sample(presets.R1, 2000, seed=0)
for law in ("paper", "mdr"):
    whole_run.run_time(warm, whole_run.bench_path(), law)
print("JSON " + json.dumps(whole_run.whole_runs([int(s) for s in sys.argv[2].split(",")], int(sys.argv[3]))))
"""


def against(commit, sizes, rounds, alternations):
    """Item 1 for the code of ``commit`` and for this checkout, fresh processes in turn; medians over them."""
    root = Path(__file__).resolve().parent.parent
    runs = {"old": [], "new": []}
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "old"
        subprocess.run(["git", "-C", str(root), "worktree", "add", "--detach", str(old), commit], check=True,
                       capture_output=True)
        try:
            for i in range(alternations):
                for label, code in (("old", old), ("new", root)):
                    p = subprocess.run([sys.executable, "-c", AGAINST, str(code / "benchmarks"), sizes, str(rounds)],
                                       capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(code)),
                                       cwd=str(code))  # "" heads sys.path: the working folder's package would win
                    line = [x for x in p.stdout.splitlines() if x.startswith("JSON ")]
                    if p.returncode or not line:
                        raise RuntimeError(f"{label} code ({code}) failed:\n{p.stderr[-2000:]}")
                    runs[label].append(json.loads(line[0][5:]))
                    print(f"  round {i + 1}, {label} code done ({p.stdout.split('CODE ')[1].split()[0]})", flush=True)
        finally:
            subprocess.run(["git", "-C", str(root), "worktree", "remove", "--force", str(old)], capture_output=True)
    out = {"commit": commit, "runs": runs}
    for name in PATHS:
        for n in sizes.split(","):
            row = {}
            for label in runs:
                for law in ("paper", "mdr"):
                    row[f"{label}_{law}_s"] = float(np.median([r[name][n][f"{law}_s"] for r in runs[label]]))
                row[f"{label}_mdr_over_paper"] = row[f"{label}_mdr_s"] / row[f"{label}_paper_s"]
            out[f"{name} {n}"] = row
            print(f"  {name:9s} n = {n:>7s}: " + ", ".join(
                f"{label} paper {row[f'{label}_paper_s']:.3f} s, mdr {row[f'{label}_mdr_s']:.3f} s "
                f"(mdr / paper {row[f'{label}_mdr_over_paper']:.2f})" for label in runs))
        ordered = sorted(sizes.split(","), key=int)
        lo, hi = ordered[0], ordered[-1]
        for label in runs:
            out[f"{name} scaling {label}"] = {law: out[f"{name} {hi}"][f"{label}_{law}_s"]
                                              / out[f"{name} {lo}"][f"{label}_{law}_s"] for law in ("paper", "mdr")}
            print(f"  {name:9s} time per increment at n = {hi} over n = {lo}, {label} code: "
                  + ", ".join(f"{law} {v:.1f}" for law, v in out[f"{name} scaling {label}"].items()))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--sizes", default="50000,500000")
    ap.add_argument("--memory-sizes", default="1000000")
    ap.add_argument("--thread-n", type=int, default=1_000_000)
    ap.add_argument("--against", metavar="COMMIT", help="compare the whole runs with the code of COMMIT")
    ap.add_argument("--alternations", type=int, default=3)
    ap.add_argument("--one-thread", action="store_true",
                    help="also item 1 on one thread (the increment scaling without hand-offs)")
    ap.add_argument("--split", action="store_true",
                    help="only item 1 for paper, split into the evaluations and the rest of the run")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    if args.against:
        out = against(args.against, args.sizes, args.rounds, args.alternations)
        out["load"] = os.getloadavg()[0]
        return write(out, "whole_run_against.json", t0)
    out = {"machine": {"cpus": os.cpu_count(), "threads": numba.get_num_threads(), "python": platform.python_version(),
                       "numba": numba.__version__, "load_start": os.getloadavg()[0]}, "k": K}
    compiled_span.MODE = "always"  # the compiled increments, as every run after a first finds them (solve.span)
    warm = Population.sample(presets.R1, 2000, seed=0)
    for law in ("paper", "mdr"):  # compile, or load from the cache
        run_time(warm, bench_path(), law)
    sizes = [int(s) for s in args.sizes.split(",")]
    if args.split:
        out["split"] = split(sizes, args.rounds)
        return write(out, "whole_run_split.json", t0)
    print("whole runs (from the call to the return):")
    out["whole_run"] = whole_runs(sizes, args.rounds)
    if args.one_thread:
        out["whole_run_one_thread"] = one_thread(sizes, args.rounds)
    print("peak memory (fresh processes, sampling included):")
    out["memory"] = memory([int(s) for s in args.memory_sizes.split(",") if s])
    print("threads:")
    out["threads"] = threads(args.thread_n, args.rounds)
    out["machine"]["load_end"] = os.getloadavg()[0]
    write(out, "whole_run.json", t0)


def write(out, name, t0):
    """``out``, with the benchmark's wall time since ``t0``, to outputs/``name``."""
    out["wall_s"] = time.perf_counter() - t0
    OUT.mkdir(exist_ok=True)
    (OUT / name).write_text(json.dumps(out, indent=1))
    print(f"wrote {OUT / name} ({out['wall_s']:.0f} s)")


if __name__ == "__main__":
    main()
