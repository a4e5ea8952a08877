"""Throughput of the assembly kernels (stress + tangent + standard error), `paper` and `mdr` laws.

Measures, on the R1 set at Delta = (15, 3, 1) um (the issue's reference point):
- asperity evaluations per second on 1 and 2 threads, counted two ways: per asperity of
  the population (the skipped ones, sorted out by height, cost nothing) and per asperity
  actually visited (those that could touch);
- for the history law `mdr` (k = 16 springs), after committing a short path to that point:
  tangential spring updates per second in a trial evaluation (springs in contact visited),
  the commit time, and the bytes held per asperity;
- the time of the first call in a fresh process with an empty numba cache (JIT compile)
  against a fresh process with a warm cache.

Run:   python benchmarks/kernel_throughput.py [--n 1000000] [--repeat 30]
Writes outputs/benchmark_kernel.json and prints a table.  About 30 seconds with the defaults
(29 s measured on this 2-core machine under load, half of it the cold-cache compile).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

from asperity_sim import Population, presets
from asperity_sim.kernels.evaluate import evaluate, Workspace
from asperity_sim.kernels.state import ContactState

OUT = Path(__file__).resolve().parent.parent / "outputs"
DELTA = np.array([15e-6, 3e-6, 1e-6])

FIRST_CALL = """
import time
t0 = time.perf_counter()
import numpy as np
from asperity_sim import Population, presets
pop = Population.sample(presets.R1, 1000, seed=1)
t1 = time.perf_counter()
evaluate(pop, np.array([15e-6, 3e-6, 1e-6]))
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def time_evaluate(pop, repeat):
    ws = Workspace(pop.n)
    evaluate(pop, DELTA, workspace=ws)
    best = np.inf
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        ev = evaluate(pop, DELTA, workspace=ws)
        times.append(time.perf_counter() - t)
    best = min(times)
    return ev, best, float(np.median(times))


def time_mdr(pop, repeat, k=16):
    """Trial evaluations of the mdr law at DELTA with a committed history reaching DELTA."""
    hist = ContactState(pop, "mdr", k=k)
    hist.reference = DELTA.copy()
    ws = Workspace(pop.n)
    for s in np.linspace(0.0, 1.0, 11)[1:]:
        d = DELTA * s
        ev = evaluate(pop, d, law="mdr", state=hist, workspace=ws)
        t = time.perf_counter()
        hist.commit(d, ev.n_active)
        commit_s = time.perf_counter() - t
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        ev = evaluate(pop, DELTA, law="mdr", state=hist, workspace=ws)
        times.append(time.perf_counter() - t)
    live = np.flatnonzero(hist.asp[:hist.n_slots] >= 0)
    a = np.sqrt(pop.R[hist.asp[live]] * hist.dn_c[live])
    springs = int(np.sum(np.minimum(np.ceil(a / hist.arrays[1][live] - 0.5), hist.n_stored)))
    median = float(np.median(times))
    slot_bytes = hist.nbytes - hist.flag.nbytes
    return {"k": k, "n_contact": ev.n_contact, "springs_in_contact": springs, "seconds_median": median,
            "spring_updates_per_s": springs / median, "visited_evals_per_s": ev.n_active / median,
            "commit_seconds": commit_s, "slots": hist.n_slots,
            "bytes_per_asperity_population": pop.nbytes / pop.n,
            "bytes_per_asperity_history": hist.nbytes / pop.n,
            "bytes_per_contact_slot": slot_bytes / max(hist.n_slots, 1)}


def first_call(cache_dir):
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    out = subprocess.run([sys.executable, "-c", FIRST_CALL], env=env, capture_output=True, text=True, check=True)
    imp, call = (float(x) for x in out.stdout.split())
    return imp, call


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=1_000_000)
    p.add_argument("--repeat", type=int, default=30)
    args = p.parse_args(argv)
    pop = Population.sample(presets.R1, args.n, seed=1)
    rows = []
    max_threads = numba.config.NUMBA_NUM_THREADS
    mdr_rows = []
    for threads in sorted({1, min(2, max_threads)}):
        numba.set_num_threads(threads)
        ev, best, median = time_evaluate(pop, args.repeat)
        rows.append({
            "threads": threads, "n": pop.n, "n_visited": ev.n_active, "n_contact": ev.n_contact,
            "seconds_best": best, "seconds_median": median,
            "population_evals_per_s": pop.n / median, "visited_evals_per_s": ev.n_active / median,
        })
        mdr_rows.append({"threads": threads, **time_mdr(pop, max(3, args.repeat // 3))})
    numba.set_num_threads(max_threads)
    with tempfile.TemporaryDirectory() as cache:
        cold = first_call(cache)
        warm = first_call(cache)
    result = {
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "numba": numba.__version__,
                    "numpy": np.__version__, "processor": platform.processor() or platform.machine()},
        "point": {"params": "R1", "delta_m": DELTA.tolist()},
        "throughput": rows,
        "mdr": mdr_rows,
        "first_call_s": {"cold_cache": {"import_and_sample": cold[0], "first_evaluate": cold[1]},
                         "warm_cache": {"import_and_sample": warm[0], "first_evaluate": warm[1]}},
    }
    OUT.mkdir(exist_ok=True)
    (OUT / "benchmark_kernel.json").write_text(json.dumps(result, indent=2))
    print(f"R1 at Delta = (15, 3, 1) um, n = {pop.n}: {rows[0]['n_visited']} asperities can touch, "
          f"{rows[0]['n_contact']} touch")
    print(f"{'threads':>7} {'median [ms]':>12} {'population evals/s':>19} {'visited evals/s':>16}")
    for r in rows:
        print(f"{r['threads']:>7} {r['seconds_median'] * 1e3:>12.2f} {r['population_evals_per_s']:>19.3e} "
              f"{r['visited_evals_per_s']:>16.3e}")
    print(f"law mdr, k = {mdr_rows[0]['k']}: {mdr_rows[0]['n_contact']} contacts, "
          f"{mdr_rows[0]['springs_in_contact']} springs in contact")
    print(f"{'threads':>7} {'median [ms]':>12} {'spring updates/s':>17} {'commit [ms]':>12}")
    for r in mdr_rows:
        print(f"{r['threads']:>7} {r['seconds_median'] * 1e3:>12.2f} {r['spring_updates_per_s']:>17.3e} "
              f"{r['commit_seconds'] * 1e3:>12.1f}")
    m = mdr_rows[-1]
    print(f"bytes per asperity: population {m['bytes_per_asperity_population']:.0f}, mdr history "
          f"{m['bytes_per_asperity_history']:.1f} (flag 1 + {m['bytes_per_contact_slot']:.0f} per asperity "
          f"that has touched; {m['slots']} of {pop.n} have)")
    print(f"first evaluate in a fresh process: {cold[1]:.2f} s with an empty numba cache (JIT), "
          f"{warm[1]:.3f} s with a warm cache")
    return 0


if __name__ == "__main__":
    sys.exit(main())
