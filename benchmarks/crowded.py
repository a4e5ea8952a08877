"""Threads that wait awake on a crowded machine: several runs at once, each on every thread numba has.

The package's worker threads poll for the next part for up to ``ASPERITY_SIM_SPIN_US`` before
they sleep (:mod:`asperity_sim.threads`).  Where runs together have more threads than the machine
has cores, a polling thread could take a core from a thread with work; the polling yields the
core every 32 polls and polls less after long waits, so that it does not.  This benchmark starts
``--processes`` processes at once (default: as many as there are cores), each running the `mdr`
history benchmark's path (sigma_1 to 300 MPa in 10 increments, Delta_2 to 10 um in 40, R1, k = 16)
at ``--n`` asperities ``--runs`` times, with the default polling and with
``ASPERITY_SIM_SPIN_US=0`` (workers that sleep at once), alternating ``--rounds`` times; and one
process alone with each setting.  Reported: the median time of a run in each setting, and crowded
over alone.

Run:   python3 benchmarks/crowded.py [--processes 2] [--n 50000] [--runs 15] [--rounds 3]
Writes outputs/crowded.json and prints a table.  About a minute on 2 cores (2026-11-28).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parent.parent / "outputs"
HERE = Path(__file__).resolve().parent

CHILD = """
import json, os, sys, time
sys.path.insert(0, {here!r})
from asperity_sim import Population, presets, simulate
from whole_run import bench_path, law_kw
pop = Population.sample(presets.R1, {n}, seed=1)
path = bench_path()
simulate(presets.R1, path, population=pop, **law_kw("mdr"))
open({ready!r}, "a").close()
while not os.path.exists({go!r}):
    time.sleep(0.005)
times = []
for _ in range({runs}):
    t = time.perf_counter()
    simulate(presets.R1, path, population=pop, **law_kw("mdr"))
    times.append(time.perf_counter() - t)
print(json.dumps(times))
"""


def together(processes: int, n: int, runs: int, spin: str | None) -> list:
    """Run times [s] of ``processes`` processes started at once (after each has warmed up)."""
    env = dict(os.environ)
    if spin is not None:
        env["ASPERITY_SIM_SPIN_US"] = spin
    with tempfile.TemporaryDirectory() as tmp:
        go = os.path.join(tmp, "go")
        children = []
        for k in range(processes):
            ready = os.path.join(tmp, f"ready{k}")
            code = CHILD.format(here=str(HERE), n=n, runs=runs, ready=ready, go=go)
            children.append((ready, subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                                                     stderr=subprocess.PIPE, text=True)))
        while not all(os.path.exists(ready) for ready, _ in children):
            if any(p.poll() is not None for _, p in children):
                break
            time.sleep(0.01)
        open(go, "a").close()
        times = []
        for _, p in children:
            out, err = p.communicate()
            if p.returncode != 0:
                raise RuntimeError(f"a run failed:\n{err[-2000:]}")
            times += json.loads(out.strip().splitlines()[-1])
    return times


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--processes", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--n", type=int, default=50_000)
    ap.add_argument("--runs", type=int, default=15)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    settings = {"polling (default)": None, "ASPERITY_SIM_SPIN_US=0": "0"}
    times = {(name, k): [] for name in settings for k in (1, args.processes)}
    t0 = time.perf_counter()
    for r in range(args.rounds):
        for k in (args.processes, 1):
            for name, spin in settings.items():
                times[(name, k)] += together(k, args.n, args.runs, spin)
                print(f"  round {r + 1}: {k} process(es), {name} done", file=sys.stderr, flush=True)
    med = {key: float(np.median(v)) for key, v in times.items()}
    print(f"mdr, history path, n = {args.n}, {os.cpu_count()} cores; median time of a run [s]:")
    print(f"{'setting':26s} {'alone':>8s} {f'{args.processes} at once':>11s} {'at once / alone':>16s}")
    for name in settings:
        a, c = med[(name, 1)], med[(name, args.processes)]
        print(f"{name:26s} {a:8.3f} {c:11.3f} {c / a:16.2f}")
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=HERE, capture_output=True, text=True).stdout.strip()
    record = {"commit": commit, "n": args.n, "runs": args.runs, "rounds": args.rounds, "processes": args.processes,
              "cores": os.cpu_count(), "median_s": {f"{name} / {k}": v for (name, k), v in med.items()},
              "times_s": {f"{name} / {k}": v for (name, k), v in times.items()},
              "load": os.getloadavg(), "wall_s": time.perf_counter() - t0}
    OUT.mkdir(exist_ok=True)
    (OUT / "crowded.json").write_text(json.dumps(record, indent=1))
    print(f"wrote {OUT / 'crowded.json'} ({record['wall_s']:.0f} s)")


if __name__ == "__main__":
    main()
