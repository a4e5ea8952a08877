"""Serial against a 2-worker local Dask cluster at three sweep sizes, and what the automatic choice picks.

Question (issue 26): on 2 shared cores a local cluster costs seconds to start (worker
processes import asperity_sim and load the numba cache), so it only pays for sweeps big
enough.  ``run_sweep(scheduler=None)`` chooses serial or cluster from a cost model
(:func:`asperity_sim.runs.engine.choose_engine`); this benchmark times, at three sizes of the
constant-normal-stress path of scenarios/constant_normal_shear_R1.toml (120 increments):

- serial: ``run_sweep(scheduler="serial")`` (numba's default thread count);
- cluster: ``run_sweep(scheduler="local", workers=2)``, *including* the cluster start (what a
  user pays for one sweep);
- auto: ``run_sweep(scheduler=None)``, and which engine it chose.

Configurations are interleaved and repeated; the best of the repeats is reported, with the
load average (other engineers share the machine).  Every configuration must give the same
bits (checked).

Run:   python benchmarks/sweep_auto.py [--repeat 2]
Writes outputs/sweep_auto.json and prints a table.  Takes about 2-4 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "outputs"

SIZES = {  # name: (runs, law, n, k)
    "small: 4 runs, paper, n = 2000": (4, "paper", 2000, 16),
    "medium: 8 runs, mdr k = 8, n = 5000": (8, "mdr", 5000, 8),
    "large: 16 runs, mdr k = 8, n = 20000": (16, "mdr", 20000, 8),
}


def make_sweep(runs, law, n, k):
    from asperity_sim.runs.scene import load_scene
    from asperity_sim.runs.sweep import Sweep

    scene = load_scene(ROOT / "scenarios" / "constant_normal_shear_R1.toml").replace(n=n, law=law, k=k, seed=1)
    return Sweep(scene=scene, seeds=tuple(range(1, runs + 1)), source="benchmarks/sweep_auto.py")


def timed(sweep, scheduler):
    from asperity_sim.runs.engine import run_sweep

    t = time.perf_counter()
    ds = run_sweep(sweep, scheduler=scheduler, workers=2, note=lambda m: None)
    return time.perf_counter() - t, ds


def main(argv=None):
    from asperity_sim.runs.engine import choose_engine, estimate_run_seconds, run_sweep

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=2)
    args = p.parse_args(argv)
    for law in ("paper", "mdr"):  # compile (or load the cache) before timing
        run_sweep(make_sweep(1, law, 500, 8), scheduler="serial")
    load_before = os.getloadavg()
    results = {}
    for name, (runs, law, n, k) in SIZES.items():
        sweep = make_sweep(runs, law, n, k)
        times = {"serial": [], "local cluster (2 workers, incl. start)": [], "auto": []}
        engines, reference, identical = [], None, True
        for rep in range(args.repeat):
            for config, scheduler in (("serial", "serial"), ("local cluster (2 workers, incl. start)", "local"),
                                      ("auto", None)):
                seconds, ds = timed(sweep, scheduler)
                times[config].append(seconds)
                if config == "auto":
                    engines.append(ds.attrs["engine"])
                data = {v: ds[v].values for v in ("stress", "displacement", "n_contact")}
                reference = reference or data
                identical &= all(np.array_equal(reference[v], data[v], equal_nan=True) for v in data)
                print(f"  {name:40s} repeat {rep + 1} {config:40s} {seconds:7.2f} s", file=sys.stderr, flush=True)
        best = {c: min(v) for c, v in times.items()}
        choice, reason = choose_engine(sweep.scenes(), workers=2)
        faster = "serial" if best["serial"] <= best["local cluster (2 workers, incl. start)"] else "local"
        results[name] = {
            "runs": runs, "law": law, "n": n, "k": k if law == "mdr" else None,
            "increments": sum(s.increments for s in sweep.scene.path.stages),
            "seconds": times, "seconds_best": best,
            "speedup_cluster_vs_serial": best["serial"] / best["local cluster (2 workers, incl. start)"],
            "estimated_serial_seconds": sum(estimate_run_seconds(s, os.cpu_count() or 1) for s in sweep.scenes()),
            "auto_choice": choice, "auto_reason": reason, "auto_engines": engines,
            "measured_faster": faster, "auto_picked_the_faster": choice == faster,
            "bit_identical_across_engines": bool(identical),
        }
    result = {
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "processor": platform.machine()},
        "scene": "scenarios/constant_normal_shear_R1.toml", "repeat": args.repeat,
        "loadavg_before": load_before, "loadavg_after": os.getloadavg(), "sizes": results,
    }
    OUT.mkdir(exist_ok=True)
    (OUT / "sweep_auto.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"\n{'size':40s} {'serial [s]':>10s} {'cluster [s]':>11s} {'speed-up':>9s} {'est. serial':>11s} "
          f"{'auto':>7s} {'right?':>6s}")
    for name, r in results.items():
        b = r["seconds_best"]
        print(f"{name:40s} {b['serial']:10.2f} {b['local cluster (2 workers, incl. start)']:11.2f} "
              f"{r['speedup_cluster_vs_serial']:9.2f} {r['estimated_serial_seconds']:11.2f} {r['auto_choice']:>7s} "
              f"{str(r['auto_picked_the_faster']):>6s}")
    print(f"load average {load_before[0]:.1f} before, {os.getloadavg()[0]:.1f} after; wrote {OUT / 'sweep_auto.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
