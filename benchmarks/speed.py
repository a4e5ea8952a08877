"""Speed of the `paper` law: kernel throughput, JIT against warm cache, and the Fig. 13 target (issue 5).

1. Asperity evaluations per second (stress + exact tangent + standard-error sums) of the
   Monte Carlo kernel, on 1 and 2 threads, R1 population of 2^20, at four states: the
   benchmark point of kernel_throughput.py (15, 3, 1) um, R1 at 500 MPa before shear
   (18.37, 0, 0) um, the end of the Fig. 13 shear (13.13, 50, 0) um and the end of the 3-step
   path (15, 15, 15) um.  Counted three ways: per asperity of the population (the ones the
   height sort skips cost nothing), per asperity visited (could touch by the height bound)
   and per contact.  Next to it, grid points per second of the paper's grid method at its
   published resolution at the same states (force only, no tangent).
2. First run against warm numba cache: a fresh process (import + sample + the Fig. 13 run
   of R1 with 2^14 Sobol points) with an empty cache directory, then again with it filled.
3. The Fig. 13 target: both curves (R1 and S1, shear_path(500e6, 50e-6, 20), as in
   studies/convergence.py) by randomised QMC (Sobol', n = 2^16 for R1, 2^14 for S1), in a
   fresh process with a warm cache; wall time of the runs alone and of the whole process
   (imports included); the error of each curve (max relative error of sigma_2/sigma_1 over
   the shear stages) against the quadrature, for 3 seeds.  The side-by-side ratio against
   the grid method comes from the convergence study (outputs/convergence.md), which runs
   both in one process.

Run:   python benchmarks/speed.py            (about 2 minutes; report the machine load with it)
Writes outputs/speed.json and prints a table.
"""

from __future__ import annotations

import os

# idle OpenMP threads sleep instead of spinning: with other processes on the cores a spinning
# thread steals the time its partner needs, and small parallel regions then take milliseconds
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "studies"), str(ROOT / "scenarios")]
from convergence import errors, nominal_steps, reference_path  # noqa: E402

from asperity_sim import Population, presets  # noqa: E402
from asperity_sim.analysis import gridmethod  # noqa: E402
from asperity_sim.kernels.evaluate import evaluate, Workspace  # noqa: E402
from streaming import best_of  # noqa: E402

OUT = ROOT / "outputs"
STATES = {"benchmark point": (15, 3, 1), "R1 at 500 MPa": (18.37, 0, 0), "end of Fig. 13 shear": (13.13, 50, 0),
          "end of 3-step": (15, 15, 15)}

FIG13 = r"""
import sys, time, json
t0 = time.perf_counter()
sys.path.insert(0, {scen!r})
from constant_normal_shear import shear_path
from asperity_sim import Population, SolverSettings, presets, simulate
t1 = time.perf_counter()
out = {{"import_s": t1 - t0, "runs": {{}}}}
path = shear_path(500e6, 50e-6, 20)
for name, n in {sizes!r}.items():
    t = time.perf_counter()
    pop = Population.sample(presets.TABLE1[name], n, seed={seed}, sampler="sobol")
    ds = simulate(presets.TABLE1[name], path, population=pop, settings=SolverSettings(rtol=1e-9))
    out["runs"][name] = {{"seconds": time.perf_counter() - t, "n": n,
                          "displacement": ds.displacement.values.tolist(), "stress": ds.stress.values.tolist()}}
out["runs_s"] = time.perf_counter() - t1
out["process_s"] = time.perf_counter() - t0
print(json.dumps(out))
"""


def median_time(fn, repeat):
    """(median, minimum) wall time [s] of ``repeat`` calls of ``fn`` after one untimed call."""
    fn()
    return best_of(fn, repeat)


def throughput(n, repeat):
    pop = Population.sample(presets.R1, n, seed=1)
    rule = gridmethod.grid_rule(presets.R1, gridmethod.PAPER)
    ws = Workspace(pop.n)
    rows = []
    before = numba.get_num_threads()
    for threads in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
        numba.set_num_threads(threads)
        for label, d_um in STATES.items():
            d = np.array(d_um) * 1e-6
            ev = evaluate(pop, d, workspace=ws)
            med, best = median_time(lambda: evaluate(pop, d, workspace=ws), repeat)
            F = gridmethod.GridEvaluator(presets.R1, rule)
            g_med, _ = median_time(lambda: F(d), max(2, repeat // 10))
            visited_grid = F.points / F.calls
            rows.append({"threads": threads, "state": label, "delta_um": list(d_um), "n": pop.n,
                         "n_visited": ev.n_active, "n_contact": ev.n_contact, "seconds_median": med,
                         "seconds_best": best, "population_evals_per_s": pop.n / med,
                         "visited_evals_per_s": ev.n_active / med, "contacts_per_s": ev.n_contact / med,
                         "grid_seconds": g_med, "grid_points_visited": visited_grid,
                         "grid_points_per_s": visited_grid / g_med})
    numba.set_num_threads(before)
    return rows


def fresh_process(code, cache_dir=None):
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    t = time.perf_counter()
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t
    if res.returncode:
        raise RuntimeError(res.stderr)
    return json.loads(res.stdout.strip().splitlines()[-1]), wall


def curve_errors(out):
    from constant_normal_shear import shear_path

    path = shear_path(500e6, 50e-6, 20)
    stage = np.array([st for st, *_ in nominal_steps(path)])
    res = {}
    for name, run in out["runs"].items():
        ref_d, ref_s = REFS.setdefault(name, reference_path(presets.TABLE1[name], path))
        disp, sig = np.array(run["displacement"]), np.array(run["stress"])
        if disp.shape != ref_d.shape:
            raise RuntimeError("cut-backs changed the recorded steps; match them as in convergence.py")
        res[name] = errors("fig13", disp, sig, ref_d, ref_s, stage)["curve"]
    return res


REFS = {}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2**20)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--n-r1", type=int, default=2**16)
    ap.add_argument("--n-s1", type=int, default=2**14)
    args = ap.parse_args(argv)
    load0 = os.getloadavg()
    print(f"load average at start: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}", flush=True)
    rows = throughput(args.n, args.repeat)
    print(f"{'threads':>7} {'state':>22} {'median ms':>10} {'best ms':>8} {'pop. evals/s':>13} {'visited/s':>11} "
          f"{'contacts/s':>11} {'grid pts/s':>11}")
    for r in rows:
        print(f"{r['threads']:>7} {r['state']:>22} {r['seconds_median'] * 1e3:>10.2f} "
              f"{r['seconds_best'] * 1e3:>8.2f} "
              f"{r['population_evals_per_s']:>13.3e} {r['visited_evals_per_s']:>11.3e} {r['contacts_per_s']:>11.3e} "
              f"{r['grid_points_per_s']:>11.3e}", flush=True)
    scen = str(ROOT / "scenarios")
    code_jit = FIG13.format(scen=scen, sizes={"R1": 2**14}, seed=1)
    with tempfile.TemporaryDirectory() as cache:
        cold, cold_wall = fresh_process(code_jit, cache)
        warm, warm_wall = fresh_process(code_jit, cache)
    print(f"Fig. 13 R1 (2^14 Sobol) in a fresh process: empty numba cache {cold['runs_s']:.2f} s run "
          f"({cold_wall:.2f} s process), warm cache {warm['runs_s']:.2f} s run ({warm_wall:.2f} s process)", flush=True)
    target = []
    for seed in (1, 2, 3):
        out, wall = fresh_process(FIG13.format(scen=scen, sizes={"R1": args.n_r1, "S1": args.n_s1}, seed=seed))
        errs = curve_errors(out)
        target.append({"seed": seed, "runs_s": out["runs_s"], "process_s": wall, "import_s": out["import_s"],
                       "seconds": {k: v["seconds"] for k, v in out["runs"].items()},
                       "n": {k: v["n"] for k, v in out["runs"].items()}, "curve_error": errs})
        print(f"Fig. 13 R1 + S1 curves (Sobol n = {args.n_r1}, {args.n_s1}), seed {seed}: runs {out['runs_s']:.2f} s, "
              f"whole process {wall:.2f} s; max relative error of the curve R1 {errs['R1']:.2e}, "
              f"S1 {errs['S1']:.2e}", flush=True)
    load1 = os.getloadavg()
    result = {
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "numba": numba.__version__,
                    "numpy": np.__version__, "threading_layer": numba.threading_layer(),
                    "load_average_start": list(load0), "load_average_end": list(load1)},
        "throughput": rows,
        "first_run": {"cold_cache": {"runs_s": cold["runs_s"], "process_s": cold_wall},
                      "warm_cache": {"runs_s": warm["runs_s"], "process_s": warm_wall}},
        "fig13_target": target,
    }
    OUT.mkdir(exist_ok=True)
    (OUT / "speed.json").write_text(json.dumps(result, indent=2))
    print(f"load average at end: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}; wrote {OUT / 'speed.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
