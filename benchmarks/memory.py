"""Bytes per asperity and peak memory of 1e6 and 1e7 populations (``paper`` law), issue 5.

What a scene does not need is left out, and this measures it:
- the population is struct-of-arrays r, R, u, cos phi, sin phi (5 float64 = 40 bytes per
  asperity), nothing per asperity for the ``paper`` law beyond that (no tangential history:
  the law is path independent; the ``mdr`` history is per contact, see kernel_throughput.py);
- per-asperity outputs only on request: a run without ``snapshots`` records per-step arrays
  only; one snapshot adds (n, 3) forces etc.;
- height-band pruning: asperities above the reachable band are never drawn nor stored;
  the same variance as a full population of n / P(band) asperities costs n of them;
- sampling: pseudo-random points are drawn as an (n, 4) array and sorted by height (80 bytes
  per asperity at the peak); a Sobol' net of 2^m points is generated directly in height order
  (case "sobol", the power of two nearest to n), with no array of uniforms.

Each case runs in a fresh Python process (so peaks do not mix): peak resident set size
(ru_maxrss) after imports and warm-up, then after sampling and after a run, and the
tracemalloc peak of the numpy allocations of each phase, in bytes and bytes per asperity.

Run:   python benchmarks/memory.py [--sizes 1000000,10000000]
Writes outputs/memory.json and prints a table.  About 1 minute; needs ~2 GB of memory.
"""

from __future__ import annotations

import os

# idle OpenMP threads sleep instead of spinning: with other processes on the cores a spinning
# thread steals the time its partner needs, and small parallel regions then take milliseconds
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse
import json
import subprocess
import sys
from pathlib import Path

OUT = Path(__file__).resolve().parent.parent / "outputs"

CASE = r"""
import json, math, resource, sys, time, tracemalloc
import numpy as np
from asperity_sim import Population, paths, presets, simulate
n, kind = int(sys.argv[1]), sys.argv[2]
sampler = "sobol" if kind == "sobol" else "random"
if kind == "sobol":  # a net of 2^m points is generated directly in height order
    n = 1 << round(math.log2(n))
S, D = paths.STRESS, paths.DISPLACEMENT
p = presets.R1
# warm-up: kernels loaded from the numba cache, small arrays
simulate(p, paths.three_step(15e-6, 1), population=Population.sample(p, 1000, seed=0))
def rss():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
out = {"n": n, "case": kind, "rss_after_imports": rss()}
band = 19.3e-6 if kind == "band" else None   # reachable band of the closure to 500 MPa (R1), see pruning
tracemalloc.start()
t = time.perf_counter()
pop = Population.sample(p, n, seed=1, sampler=sampler, r_max=band)
out["sample_s"] = time.perf_counter() - t
out["sample_peak_traced"] = tracemalloc.get_traced_memory()[1]
out["population_bytes"] = pop.nbytes
out["band_probability"] = pop.weight * pop.n
out["rss_after_sample"] = rss()
tracemalloc.reset_peak()
if kind == "snapshot":
    path = paths.LoadPath((paths.Stage((D, D, D), (15e-6, 0, 0), 2), paths.Stage((D, D, D), (15e-6, 5e-6, 0), 2)))
    ds = simulate(p, path, population=pop, snapshots=[4])
else:
    path = paths.LoadPath((paths.Stage((S, D, D), (500e6, 0, 0), 3),))
    if kind == "shear":
        path = paths.LoadPath(path.stages + (paths.Stage((S, D, D), (500e6, 10e-6, 0), 2),))
    ds = simulate(p, path, population=pop)
out["run_peak_traced"] = tracemalloc.get_traced_memory()[1]
out["dataset_bytes"] = int(ds.nbytes)
out["rss_after_run"] = rss()
print(json.dumps(out))
"""

CASES = {
    "closure": "full population, sigma_1 to 500 MPa (3 increments), no snapshots",
    "shear": "full population, sigma_1 to 500 MPa then Delta_2 to 10 um (2 increments)",
    "snapshot": "full population, 4 displacement-controlled increments, one per-asperity snapshot",
    "band": "height band r <= 19.3 um (closure to 500 MPa of R1), same run as 'closure'",
    "sobol": "Sobol' population of the nearest power of two (generated in height order), same run as 'closure'",
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1000000,10000000")
    args = ap.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    rows = []
    for size in sizes:
        for kind in CASES:
            res = subprocess.run([sys.executable, "-c", CASE, str(size), kind], capture_output=True, text=True,
                                 env=dict(os.environ))
            if res.returncode:
                raise RuntimeError(res.stderr)
            r = json.loads(res.stdout.strip().splitlines()[-1])
            n = r["n"]
            r["per_asperity"] = {
                "population": r["population_bytes"] / n,
                "sample_peak_traced": r["sample_peak_traced"] / n,
                "run_peak_traced": r["run_peak_traced"] / n,
                "rss_growth": (r["rss_after_run"] - r["rss_after_imports"]) / n,
                "dataset": r["dataset_bytes"] / n,
                # bytes per asperity of a full population with the same variance (band: n / P asperities)
                "population_per_equivalent_full": r["population_bytes"] * r["band_probability"] / n,
            }
            rows.append(r)
            pa = r["per_asperity"]
            print(f"n = {n:>9d} {kind:9s} population {pa['population']:5.1f} B/asperity, sampling peak "
                  f"{r['sample_peak_traced'] / 2**20:7.1f} MiB ({pa['sample_peak_traced']:5.1f} B), run peak "
                  f"{r['run_peak_traced'] / 2**20:7.1f} MiB ({pa['run_peak_traced']:5.1f} B), peak RSS "
                  f"{r['rss_after_run'] / 2**20:7.1f} MiB (+{pa['rss_growth']:5.1f} B/asperity), dataset "
                  f"{r['dataset_bytes'] / 2**10:9.1f} KiB", flush=True)
    OUT.mkdir(exist_ok=True)
    (OUT / "memory.json").write_text(json.dumps({"cases": CASES, "rows": rows}, indent=2))
    print(f"wrote {OUT / 'memory.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
