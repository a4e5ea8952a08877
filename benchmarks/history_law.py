"""Cost of the history law ``mdr`` against the ``paper`` law, measured side by side in one run.

What it measures (R1, k = 16, constant-normal-stress shear at 300 MPa; every number a ratio to
something timed in the same process, because absolute times drift on a shared machine):

1. **Increment cost**: the same population and path (sigma_1 to 300 MPa in 10 increments, then
   Delta_2 to 10 um in 40), run with ``paper`` and with ``mdr``, alternately (``--rounds``
   times); the mean wall time of a shear increment (from the progress callback), the median
   over the rounds, and mdr / paper of the medians.  Target: <= 5.
2. **Trial against a streaming probe**: after the mdr run, a trial evaluation near the last
   converged state, against a minimal parallel kernel that streams the same number of spring
   bytes (the springs in contact: u_i > 0 at the committed overlap).  The ratio probe time /
   trial time is the fraction of streaming speed a trial reaches.  Target: >= 0.4.  At n = 500 000
   the springs stay in the shared cache, and so do the probe's bytes; the same ratio against the
   probe streaming the same bytes from memory (timed on 2 GiB, scaled) is reported too.  The trial
   finds its fresh contacts among the asperities listed for a box around the path, as most
   trials of a run do (the run's count of trials that built the list and that used it is
   reported); the same trial testing every asperity is reported too.
3. **Commit against trial**: the commit of the same increment as the trial (from the same
   committed state, restored before each repeat), as the driver makes it: after a trial there,
   whose workspace tells where contacts are born (restore and trial not timed).  Target: <= 1.
   The same commit searching every asperity for new contacts is reported too.
   Trial and commit are also timed as a run makes them (:func:`as_in_a_run`: consecutive
   increments of the same size, no restore between them), where the springs stay as warm as
   in a run; the restore of 2. and 3. rewrites the whole spring store and slows the trials
   after it.
4. **float32 springs**: the mdr run again with ``spring_dtype="float32"``: its increment cost
   and the largest stress difference to float64 along the path, relative to the largest stress.
5. **Scaling**: the shear increment at n / 10 asperities (mdr), as the ratio of the two.

With ``--scale`` it also runs (each in a fresh process) the trial, commit and probe of 2. and 3.
at n = 10 000 000 (about 0.7 GB of springs in contact: they stream from memory, where at n =
500 000 they stay in the shared cache), the 10 000 000-asperity, 300-increment mdr path and
the same path with the paper law: wall time and peak resident memory, against
the paper law's peak plus the bytes of the springs (target: <= 1.1 x), and the 570-increment
cyclic path at 1 000 000 asperities (target: under a minute).

Run:   python benchmarks/history_law.py [--n 500000] [--scale]
Writes outputs/history_law.json and prints a table.  About 1.5 minutes; --scale adds about 3 (2026-11-27).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np

from asperity_sim import paths, Population, presets, simulate
from asperity_sim.solve import run as driver
from asperity_sim.kernels.evaluate import evaluate_unchecked, Workspace
from asperity_sim.kernels.state import ContactState
from streaming import best_of, memory_seconds_per_byte, stream

OUT = Path(__file__).resolve().parent.parent / "outputs"
S, D = paths.STRESS, paths.DISPLACEMENT
UM = 1e-6


def cns_path(sigma_n=300e6, d2=10 * UM, normal=10, shear=40):
    return paths.LoadPath((paths.Stage((S, D, D), (sigma_n, 0, 0), normal, name="normal"),
                           paths.Stage((S, D, D), (sigma_n, d2, 0), shear, name="shear")), name="cns")


class _Counted(Workspace):
    """The driver's workspace, kept so that its count of trials by fresh-contact index can be read."""

    made = []

    def __init__(self, n, index=True):
        super().__init__(n, index)
        self.made.append(self)


def timed_run(pop, path, **kw):
    """(dataset, mean wall time of the increments of the last stage [s])."""
    marks = []

    def progress(stage, n_stages, fraction, step, iterations):
        marks.append((stage, time.perf_counter()))

    t0 = time.perf_counter()
    driver.Workspace, plain = _Counted, driver.Workspace
    try:
        ds = simulate(pop.params, path, population=pop, progress=progress, **kw)
    finally:
        driver.Workspace = plain
    last = [t for s, t in marks if s == len(path.stages)]
    first = [t for s, t in marks if s == len(path.stages) - 1]
    start = first[-1] if first else t0
    return ds, (last[-1] - start) / len(last)


def timed_increment(pop, state, d, ws):
    """(trial, commit) [s] of one increment to ``d`` as the driver makes it: a first trial (untimed), a
    second one at ``d`` (timed), then the commit (timed), which uses the trial's workspace."""
    evaluate_unchecked(pop, d, state, ws)
    t = time.perf_counter()
    evaluate_unchecked(pop, d, state, ws)
    t1 = time.perf_counter()
    state.commit(d, workspace=ws)
    return t1 - t, time.perf_counter() - t1


def trial_and_commit(pop, state, d, ws, repeat):
    """Median times [s] of a trial at ``d`` and of the commit of that increment, measured in pairs,
    and of the same trial testing every asperity for fresh contacts.

    Each repeat restores the same committed state and makes a first trial at ``d`` (untimed: a
    restore leaves the state out of the caches), then times a second trial there, and the commit
    as the driver makes it (:func:`timed_increment`); pairs, because the speed of this
    shared machine drifts between runs.  Then, the same way (restore, a first trial, a timed
    one), a trial whose workspace has no index of the asperities that may touch.
    """
    start = state.state_arrays()
    ws_all = Workspace(pop.n, index=False)
    trial, trial_all, commit = [], [], []
    for _ in range(repeat):
        state.restore(start)
        tt, tc = timed_increment(pop, state, d, ws)
        trial.append(tt)
        commit.append(tc)
        state.restore(start)
        evaluate_unchecked(pop, d, state, ws_all)
        t = time.perf_counter()
        evaluate_unchecked(pop, d, state, ws_all)
        trial_all.append(time.perf_counter() - t)
    state.restore(start)
    return float(np.median(trial)), float(np.median(trial_all)), float(np.median(commit))


def as_in_a_run(pop, state, step, ws, repeat):
    """Median times [s] of the trial and the commit of ``repeat`` consecutive increments ``step`` from the
    current state, as a run makes them (:func:`timed_increment`).

    Nothing rewrites the spring store between them but the commits, in place, so the springs are as
    warm as in a run; after a restore they are not (the restore writes the whole store, and the
    trials that follow run up to 40 % slower, the first five getting faster in turn).  The first two
    increments are not counted.  Leaves ``state`` moved on by ``repeat`` + 2 increments.
    """
    times = np.array([timed_increment(pop, state, state.delta_c + step, ws) for _ in range(repeat + 2)])
    return float(np.median(times[2:, 0])), float(np.median(times[2:, 1]))


def springs_in_contact(state) -> int:
    """Springs with u_i > 0 at the committed overlap, summed over the committed contacts."""
    live = np.flatnonzero(state.asp[:state.n_slots] >= 0)
    R = state.pop.R[state.asp[live]]
    h = state.arrays[1][live]
    n = np.ceil(np.sqrt(R * state.dn_c[live]) / h - 0.5)
    return int(np.minimum(n, state.n_stored).sum())


def rebuild_state(pop, path, k, dtype):
    """The mdr state at the end of ``path``, committed increment by increment at the run's displacements."""
    ds = simulate(pop.params, path, population=pop, law="mdr", k=k, spring_dtype=dtype)
    state = ContactState(pop, "mdr", k=k, spring_dtype=dtype)
    ws = Workspace(pop.n)
    for d in ds.displacement.values[1:]:
        evaluate_unchecked(pop, d, state, ws)
        state.commit(d)
    return state, ds


def end_state_timings(pop, path, k, repeat):
    """Trial, commit and streaming probe at the end state of ``path`` (mdr, float64 springs): times [s] and ratios."""
    state, _ = rebuild_state(pop, path, k, "float64")
    ws = Workspace(pop.n)
    step = np.array([1e-3, 2e-3, 0.0]) * UM
    d = state.delta_c + step
    evaluate_unchecked(pop, d, state, ws)
    trial_med, trial_all, commit_med = trial_and_commit(pop, state, d, ws, repeat)
    start = state.state_arrays()
    full = []
    for _ in range(repeat):  # the same commit searching every asperity for new contacts
        state.restore(start)
        t = time.perf_counter()
        state.commit(d)
        full.append(time.perf_counter() - t)
    state.restore(start)
    m = springs_in_contact(state)
    probe = np.ones(2 * m)  # the spring bytes in contact, float64
    stream(probe)
    probe_med, _ = best_of(lambda: stream(probe), repeat)
    out = dict(springs_in_contact=m, spring_bytes_in_contact=int(probe.nbytes), trial_s=trial_med,
               trial_testing_all_s=trial_all, commit_s=commit_med, commit_full_search_s=float(np.median(full)),
               probe_s=probe_med, trial_over_probe_speed=probe_med / trial_med,
               commit_over_trial=commit_med / trial_med, state_bytes=state.nbytes, population_bytes=pop.nbytes,
               contacts_at_trial=state.n_contacts)
    run_trial, run_commit = as_in_a_run(pop, state, step, ws, repeat)  # last: it moves the state on
    out.update(run_trial_s=run_trial, run_commit_s=run_commit, run_trial_over_probe_speed=probe_med / run_trial,
               run_commit_over_trial=run_commit / run_trial)
    memory = memory_seconds_per_byte() * probe.nbytes  # the same bytes streamed from memory
    out.update(probe_from_memory_s=memory, trial_over_memory_probe_speed=memory / trial_med,
               run_trial_over_memory_probe_speed=memory / run_trial)
    return out


def peak_friction(ds) -> float:
    """Largest sigma_2 / sigma_1 after the first (unloaded) step."""
    s = ds.stress.values[1:]
    return float((s[:, 1] / s[:, 0]).max())


def measure(n, k, repeat, rounds=3):
    pop = Population.sample(presets.R1, n, seed=1)
    path = cns_path()
    out = {"n": n, "k": k}
    simulate(pop.params, cns_path(normal=2, shear=2), population=Population.sample(presets.R1, 2000, seed=0),
             law="mdr", k=k)  # compile
    # paper and mdr alternate, ``rounds`` times: the ratio of the medians, and each round's ratio
    t_ps, t_ms = [], []
    for _ in range(rounds):
        ds_p, t = timed_run(pop, path, law="paper")
        t_ps.append(t)
        ds_m, t = timed_run(pop, path, law="mdr", k=k)
        t_ms.append(t)
        by_index = _Counted.made[-1].trials_by_index
    t_p, t_m = float(np.median(t_ps)), float(np.median(t_ms))
    out.update(rounds_mdr_over_paper=[m / q for m, q in zip(t_ms, t_ps)], rounds_paper_s=t_ps, rounds_mdr_s=t_ms)
    ds_m32, t_m32 = timed_run(pop, path, law="mdr", k=k, spring_dtype="float32")
    smax = np.abs(ds_m.stress.values).max()
    out.update(paper_increment_s=t_p, mdr_increment_s=t_m, mdr_over_paper=t_m / t_p,
               mdr_f32_increment_s=t_m32, mdr_f32_over_f64=t_m32 / t_m,
               f32_max_stress_error=float(np.abs(ds_m32.stress.values - ds_m.stress.values).max() / smax),
               peak_ratio_mdr_over_paper=float(peak_friction(ds_m) / peak_friction(ds_p)),
               contacts=int(ds_m.n_contact.values[-1]),
               run_trials_testing_all=by_index[0], run_trials_building_list=by_index[1],
               run_trials_using_list=by_index[2])
    out.update(end_state_timings(pop, path, k, repeat))
    # scaling: the same path at n / 10
    small = Population.sample(presets.R1, n // 10, seed=1)
    _, t_small = timed_run(small, path, law="mdr", k=k)
    out.update(mdr_increment_small_s=t_small, scaling_n_over_n10=t_m / t_small)
    return out


SCALE = r"""
import json, resource, sys, time
import numpy as np
from asperity_sim import Population, paths, presets, simulate

def peak_rss():
    # this process's own peak [B]: VmHWM starts anew at exec, where ru_maxrss keeps the parent's peak
    try:
        with open("/proc/self/status") as f:
            return next(int(l.split()[1]) * 1024 for l in f if l.startswith("VmHWM:"))
    except (OSError, StopIteration):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


n, law, which = int(sys.argv[1]), sys.argv[2], sys.argv[3]
S, D = paths.STRESS, paths.DISPLACEMENT
if which == "long":   # 300 increments: normal 50, shear 250
    path = paths.LoadPath((paths.Stage((S, D, D), (300e6, 0, 0), 50), paths.Stage((S, D, D), (300e6, 10e-6, 0), 250)))
else:                 # cyclic: normal 30, then 6 cycles of +-3 um in 90 increments each
    st = [paths.Stage((S, D, D), (300e6, 0, 0), 30)]
    for _ in range(6):
        st += [paths.Stage((S, D, D), (300e6, 3e-6, 0), 22), paths.Stage((S, D, D), (300e6, -3e-6, 0), 45),
               paths.Stage((S, D, D), (300e6, 0, 0), 23)]
    path = paths.LoadPath(tuple(st))
simulate(presets.R1, paths.LoadPath(path.stages[:1]), n=2000, law=law, k=16)  # compile
t = time.perf_counter()
pop = Population.sample(presets.R1, n, seed=1)
t_sample = time.perf_counter() - t
t = time.perf_counter()
ds = simulate(presets.R1, path, population=pop, law=law, k=16)
wall = time.perf_counter() - t
out = {"n": n, "law": law, "path": which, "increments": int(ds.sizes["step"] - 1), "sample_s": t_sample,
       "run_s": wall, "peak_rss": peak_rss(),
       "contacts_end": int(ds.n_contact.values[-1]), "contacts_max": int(ds.n_contact.values.max())}
print(json.dumps(out))
"""


def scale_runs(k):
    res = {}
    t = time.perf_counter()  # the trial against the probe where the springs stream from memory
    p = subprocess.run([sys.executable, __file__, "--trial-only", "--n", "10000000", "--k", str(k), "--repeat", "7"],
                       capture_output=True, text=True)
    res["trial_10000000"] = json.loads(p.stdout.strip().splitlines()[-1]) if not p.returncode else {
        "error": p.stderr[-2000:]}
    print(f"  mdr trial at n=10000000: {time.perf_counter() - t:.0f} s", flush=True)
    for n, law, which in ((10_000_000, "paper", "long"), (10_000_000, "mdr", "long"), (1_000_000, "mdr", "cyclic")):
        t = time.perf_counter()
        p = subprocess.run([sys.executable, "-c", SCALE, str(n), law, which], capture_output=True, text=True)
        if p.returncode:
            res[f"{law}_{which}_{n}"] = {"error": p.stderr[-2000:]}
            continue
        res[f"{law}_{which}_{n}"] = json.loads(p.stdout.strip().splitlines()[-1])
        print(f"  {law} {which} n={n}: {time.perf_counter() - t:.0f} s", flush=True)
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=500_000)
    ap.add_argument("--k", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--rounds", type=int, default=3, help="alternating paper/mdr runs; medians are reported")
    ap.add_argument("--scale", action="store_true",
                    help="also the trial at n = 10M, the 10M-asperity runs and the 1M cyclic run (~4 min)")
    ap.add_argument("--trial-only", action="store_true",
                    help="only the trial, commit and probe at the end state of n asperities (JSON on stdout)")
    args = ap.parse_args(argv)
    if args.trial_only:
        pop = Population.sample(presets.R1, args.n, seed=1)
        r = end_state_timings(pop, cns_path(), args.k, args.repeat)
        print(json.dumps(dict(r, n=args.n, k=args.k)))
        return
    t0 = time.perf_counter()
    out = {"machine": {"cpus": os.cpu_count(), "threads": numba.get_num_threads(), "python": platform.python_version(),
                       "numba": numba.__version__, "load_start": os.getloadavg()[0]}}
    out["side_by_side"] = r = measure(args.n, args.k, args.repeat, args.rounds)
    print(f"n = {r['n']}, k = {r['k']}, contacts at the end: {r['contacts']}")
    print(f"shear increment: paper {1e3 * r['paper_increment_s']:.1f} ms, mdr {1e3 * r['mdr_increment_s']:.1f} ms "
          f"-> mdr / paper = {r['mdr_over_paper']:.2f} (target <= 5; rounds: "
          f"{', '.join(f'{x:.2f}' for x in r['rounds_mdr_over_paper'])})")
    print(f"trial {1e3 * r['trial_s']:.2f} ms, streaming probe of {r['spring_bytes_in_contact'] / 1e6:.1f} MB "
          f"{1e3 * r['probe_s']:.2f} ms -> trial at {r['trial_over_probe_speed']:.2f} of streaming speed (target >= 0.4)")
    print(f"  as in a run (consecutive increments, no restore): trial {1e3 * r['run_trial_s']:.2f} ms -> "
          f"{r['run_trial_over_probe_speed']:.2f} of streaming speed; commit / trial {r['run_commit_over_trial']:.2f}")
    print(f"  against the probe streaming the same bytes from memory ({1e3 * r['probe_from_memory_s']:.2f} ms): trial "
          f"at {r['trial_over_memory_probe_speed']:.2f}, as in a run {r['run_trial_over_memory_probe_speed']:.2f}")
    print(f"  (the same trial testing every asperity: {1e3 * r['trial_testing_all_s']:.2f} ms; trials of the mdr run: "
          f"{r['run_trials_using_list']} used the list of asperities that may touch, {r['run_trials_building_list']} "
          f"built it, {r['run_trials_testing_all']} tested every asperity)")
    print(f"commit {1e3 * r['commit_s']:.2f} ms -> commit / trial = {r['commit_over_trial']:.2f} (target <= 1); "
          f"a commit searching every asperity for new contacts {1e3 * r['commit_full_search_s']:.2f} ms")
    print(f"float32 springs: increment x{r['mdr_f32_over_f64']:.2f} of float64, max stress error "
          f"{r['f32_max_stress_error']:.1e} of the largest stress")
    print(f"peak sigma2/sigma1 mdr / paper = {r['peak_ratio_mdr_over_paper']:.4f}")
    print(f"scaling: mdr increment at n / n/10 = {r['scaling_n_over_n10']:.1f}")
    if args.scale:
        out["scale"] = s = scale_runs(args.k)
        p, m = s.get("paper_long_10000000", {}), s.get("mdr_long_10000000", {})
        if "peak_rss" in p and "peak_rss" in m:
            k2 = 2 * args.k
            springs = m["contacts_max"] * (k2 * 2 * 8 + 8)
            s["memory_ratio"] = m["peak_rss"] / (p["peak_rss"] + springs)
            print(f"10M x 300 increments: mdr {m['run_s']:.0f} s (target < 300), paper {p['run_s']:.0f} s; peak RSS "
                  f"mdr {m['peak_rss'] / 2**30:.2f} GiB, paper {p['peak_rss'] / 2**30:.2f} GiB + springs "
                  f"{springs / 2**30:.2f} GiB -> ratio {s['memory_ratio']:.2f} (target <= 1.1)")
        b = s.get("trial_10000000", {})
        if "trial_s" in b:
            print(f"n = 10 000 000 end state ({b['spring_bytes_in_contact'] / 1e6:.0f} MB of springs in contact): trial "
                  f"{1e3 * b['trial_s']:.0f} ms, probe {1e3 * b['probe_s']:.0f} ms -> {b['trial_over_probe_speed']:.2f} "
                  f"of streaming speed; commit / trial {b['commit_over_trial']:.2f}; as in a run: trial "
                  f"{1e3 * b['run_trial_s']:.0f} ms -> {b['run_trial_over_probe_speed']:.2f}, commit / trial "
                  f"{b['run_commit_over_trial']:.2f}")
        c = s.get("mdr_cyclic_1000000", {})
        if "run_s" in c:
            print(f"1M cyclic, {c['increments']} increments: {c['run_s']:.1f} s (target < 60)")
    out["wall_s"] = time.perf_counter() - t0
    OUT.mkdir(exist_ok=True)
    (OUT / "history_law.json").write_text(json.dumps(out, indent=1))
    print(f"wrote {OUT / 'history_law.json'} ({out['wall_s']:.0f} s)")


if __name__ == "__main__":
    main()
