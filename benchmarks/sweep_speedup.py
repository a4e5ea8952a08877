"""Speed-up of a sweep on a 2-worker local Dask cluster over the same sweep run serially.

The sweep: 8 replicas (seeds 1-8) of the paper's constant-normal-shear path (Fig. 13,
scenarios/constant_normal_shear_R1.toml: sigma_1 to 500 MPa, then Delta_2 to 50 um,
120 increments) at n = 100 000 asperities each.  Configurations, interleaved and repeated
so that the load of other processes on the machine spreads over all of them:

- serial, numba's default thread count (what `asperity-sim sweep --serial` does);
- serial, 1 numba thread;
- LocalCluster, 2 worker processes x 1 task x 1 numba thread (the default of `asperity-sim sweep`);
- LocalCluster, 2 worker processes x 1 task x 2 numba threads (oversubscribed on 2 cores).

Each set runs in a fresh process twice: with OpenMP's default wait policy (idle threads
spin) and with OMP_WAIT_POLICY=PASSIVE (idle threads sleep; what `asperity-sim` sets),
because on a shared machine the spinning costs more than the parallelism gains.  The
cluster is started once per configuration and its start-up time is reported apart; the
sweep time is the time of `run_sweep` on the running cluster.  Every configuration must
give the same bits (checked).  Records the load average before and after.

Run:   python benchmarks/sweep_speedup.py [--runs 8] [--n 100000] [--repeat 2]
Writes outputs/sweep_speedup.json and prints a table.  Takes about 5-10 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np

from asperity_sim.runs.scene import load_scene
from asperity_sim.runs.engine import run_sweep
from asperity_sim.runs.sweep import Sweep

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "outputs"


def make_sweep(runs, n):
    scene = load_scene(ROOT / "scenarios" / "constant_normal_shear_R1.toml").replace(n=n, seed=1)
    return Sweep(scene=scene, seeds=tuple(range(1, runs + 1)), source="benchmarks/sweep_speedup.py")


def _warm_up():
    from asperity_sim.runs.engine import run_one

    run_one(make_sweep(1, 1000).scenes()[0])


def timed_serial(sweep, threads):
    t = time.perf_counter()
    ds = run_sweep(sweep, scheduler="serial", threads=threads)
    return time.perf_counter() - t, 0.0, ds


def timed_cluster(sweep, workers, threads):
    from dask.distributed import Client, LocalCluster

    t0 = time.perf_counter()
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        client.run(_warm_up)  # import asperity_sim and load the numba cache in every worker
        start = time.perf_counter() - t0
        t = time.perf_counter()
        ds = run_sweep(sweep, scheduler=client, threads=threads)
        return time.perf_counter() - t, start, ds


def measure(runs, n, repeat):
    """Time every configuration in this process; returns a dict for the JSON file."""
    sweep = make_sweep(runs, n)
    run_sweep(dataclasses.replace(sweep, scene=sweep.scene.replace(n=1000), seeds=(1,)), scheduler="serial")  # JIT
    default_threads = numba.get_num_threads()
    serial = f"serial, {default_threads} numba threads"
    configs = {
        serial: lambda: timed_serial(sweep, None),
        "serial, 1 numba thread": lambda: timed_serial(sweep, 1),
        "LocalCluster 2 workers x 1 numba thread": lambda: timed_cluster(sweep, 2, 1),
        "LocalCluster 2 workers x 2 numba threads": lambda: timed_cluster(sweep, 2, 2),
    }
    load_before = os.getloadavg()
    times = {k: [] for k in configs}
    starts = {k: [] for k in configs if "Cluster" in k}
    reference, identical = None, True
    for rep in range(repeat):
        for name, fn in configs.items():
            seconds, start, ds = fn()
            times[name].append(seconds)
            if name in starts:
                starts[name].append(start)
            data = {v: ds[v].values for v in ("stress", "displacement", "stress_stderr", "n_contact")}
            reference = reference or data
            identical &= all(np.array_equal(reference[v], data[v]) for v in data)
            print(f"  repeat {rep + 1}: {name:42s} {seconds:7.2f} s"
                  + (f" (cluster start {start:.2f} s)" if name in starts else ""), file=sys.stderr, flush=True)
    best = {k: min(v) for k, v in times.items()}
    return {
        "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY", "default (spin)"),
        "numba_default_threads": default_threads,
        "loadavg_before": load_before, "loadavg_after": os.getloadavg(),
        "seconds": times, "cluster_start_seconds": starts,
        "seconds_best": best,
        "seconds_median": {k: statistics.median(v) for k, v in times.items()},
        "speedup_best_vs_serial_default_threads": {k: best[serial] / v for k, v in best.items()},
        "speedup_best_vs_serial_1_thread": {k: best["serial, 1 numba thread"] / v for k, v in best.items()},
        "bit_identical_across_configurations": bool(identical),
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=8)
    p.add_argument("--n", type=int, default=100_000)
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        print(json.dumps(measure(args.runs, args.n, args.repeat)))
        return 0
    policies = {}
    for policy in ("default (spin)", "PASSIVE"):
        env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
        if policy == "PASSIVE":
            env["OMP_WAIT_POLICY"] = "PASSIVE"
        print(f"OMP_WAIT_POLICY = {policy}", file=sys.stderr, flush=True)
        child = subprocess.run([sys.executable, __file__, "--child", "--runs", str(args.runs), "--n", str(args.n),
                                "--repeat", str(args.repeat)], env=env, check=True, stdout=subprocess.PIPE, text=True)
        policies[policy] = json.loads(child.stdout.strip().splitlines()[-1])
    sweep = make_sweep(args.runs, args.n)
    result = {
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "numba": numba.__version__,
                    "numba_threading_layer_config": numba.config.THREADING_LAYER, "processor": platform.machine()},
        "sweep": {"scene": "scenarios/constant_normal_shear_R1.toml", "runs": args.runs, "n": args.n,
                  "seeds": list(sweep.seeds), "increments": sum(s.increments for s in sweep.scene.path.stages)},
        "repeat": args.repeat,
        "by_omp_wait_policy": policies,
    }
    OUT.mkdir(exist_ok=True)
    (OUT / "sweep_speedup.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"\n{'OMP_WAIT_POLICY':16s} {'configuration':42s} {'best [s]':>9s} {'median [s]':>11s} {'speed-up':>9s}")
    for policy, r in policies.items():
        for k, best in r["seconds_best"].items():
            print(f"{policy:16s} {k:42s} {best:9.2f} {r['seconds_median'][k]:11.2f} "
                  f"{r['speedup_best_vs_serial_default_threads'][k]:9.2f}")
        print(f"{'':16s} bit-identical: {r['bit_identical_across_configurations']}; load average "
              f"{r['loadavg_before'][0]:.1f} before, {r['loadavg_after'][0]:.1f} after")
    print(f"wrote {OUT / 'sweep_speedup.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
