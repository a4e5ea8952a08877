"""The first run on a fresh machine: wall time with an empty numba cache, and where it goes.

A newcomer's first run compiles the kernels it needs; every later run loads them from numba's
on-disk cache.  This benchmark times, each in a fresh Python process with its own empty cache
folder (``NUMBA_CACHE_DIR``), from the start of the process to the return of the run:

1. a small ``paper`` run (R1, n = 2000, constant-normal-stress shear, 50 increments);
2. the same run with ``mdr``;
3. the README's main job (``scenarios/paper_figures.py``: the paper's three scenarios);

then each again with the cache the first filled (warm).  The compile time of a run is its cold
time less its warm time; the compile time of each compiled function (numba's own timers: the
time under the compiler lock, which includes the functions it calls that were compiled for it,
and the part of it in LLVM) is listed largest first, so that a change can be aimed at what costs.
A history law's run starts its compile-ahead helper (:mod:`asperity_sim.kernels.ahead`) as any
first run does: the kernels the helper compiled are loaded, not listed, and its time on the other
core is not counted (the wall time a user waits).

Run:   python3 benchmarks/cold_start.py [--skip-main-job]
Writes outputs/cold_start.json and prints a table.  About 2 minutes on 2 cores (2026-11-27).

Against an older commit: ``--against COMMIT [--rounds R] [--laws paper,mdr]`` times the cold
small runs of that commit's code (a temporary git worktree) and of this checkout in turn, R
rounds, each run in a fresh process with its own empty cache, and writes
outputs/cold_start_against.json (every time, and the medians): on a shared machine whose speed
drifts, runs side by side in time are the comparison that holds.
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

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "outputs"

SMALL = r"""
import json, sys, time
t0 = time.perf_counter()
import asperity_sim as asim
from asperity_sim import paths, presets
t_import = time.perf_counter() - t0
law = sys.argv[1]
path = paths.constant_normal_shear(300e6, 10e-6, increments=50)
t1 = time.perf_counter()
ds = asim.simulate(presets.R1, path, n=2000, seed=1, law=law)
t_run = time.perf_counter() - t1
compiled = []
import gc
import numba.core.registry
from numba.core.dispatcher import Dispatcher
for obj in gc.get_objects():
    if isinstance(obj, Dispatcher):
        for sig, cres in obj.overloads.items():
            timers = (cres.metadata or {}).get("timers", {})
            if "compiler_lock" in timers:
                compiled.append((obj.py_func.__qualname__.split("__")[0], timers["compiler_lock"], timers.get("llvm_lock", 0.0)))
print(json.dumps({"import_s": t_import, "run_s": t_run, "total_s": time.perf_counter() - t0,
                  "stress_end": ds.stress.values[-1].tolist(), "compiled": sorted(compiled, key=lambda c: -c[1])}))
"""


def small_run(law: str, cache: Path, root: Path = ROOT) -> dict:
    """The small run of ``law`` in a fresh process, with the package of the checkout ``root`` and numba's cache in
    ``cache``."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(root)}
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", SMALL, law], env=env, capture_output=True, text=True, cwd=root)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(done.stderr[-3000:])
    out = json.loads(done.stdout.strip().splitlines()[-1])
    out["process_s"] = wall
    return out


def main_job(cache: Path, outdir: Path) -> float:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, str(ROOT / "scenarios" / "paper_figures.py"), "--outdir", str(outdir)],
                          env=env, capture_output=True, text=True, cwd=ROOT)
    if done.returncode != 0:
        raise SystemExit(done.stderr[-3000:])
    return time.perf_counter() - t0


def machine() -> dict:
    """What a record says of the machine it was taken on."""
    return {"cpus": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()}


def head() -> str:
    """The commit of this checkout."""
    return subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()


def against(commit: str, rounds: int, laws: list) -> dict:
    """Cold small runs of the code of ``commit`` and of this checkout, in turn (module docstring)."""
    times = {label: {law: [] for law in laws} for label in ("old", "new")}
    with tempfile.TemporaryDirectory(prefix="cold_start_") as tmp:
        old = Path(tmp) / "old"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(old), commit], check=True,
                       capture_output=True)
        try:
            for i in range(rounds):
                for law in laws:
                    for label, root in (("old", old), ("new", ROOT)):
                        with tempfile.TemporaryDirectory(prefix="cache_", dir=tmp) as cache:
                            times[label][law].append(small_run(law, Path(cache), root)["process_s"])
                    print(f"  round {i + 1} {law}: old {times['old'][law][-1]:.1f} s, new {times['new'][law][-1]:.1f} s",
                          flush=True)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(old)], capture_output=True)
    medians = {label: {law: float(np.median(t)) for law, t in by_law.items()} for label, by_law in times.items()}
    return {"commit": commit, "cold_s": times, "median_cold_s": medians}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-main-job", action="store_true", help="only the two small runs")
    ap.add_argument("--against", metavar="COMMIT", help="cold small runs of COMMIT's code and of this checkout, in turn")
    ap.add_argument("--rounds", type=int, default=4, help="rounds of --against (default 4)")
    ap.add_argument("--laws", default="paper,mdr", help="the laws of --against (default paper,mdr)")
    a = ap.parse_args(argv)
    if a.against:
        t0 = time.perf_counter()
        record = {"machine": {**machine(), "load": os.getloadavg()[0]}, "new": head(),
                  **against(a.against, a.rounds, a.laws.split(","))}
        record["wall_s"] = time.perf_counter() - t0
        OUT.mkdir(exist_ok=True)
        (OUT / "cold_start_against.json").write_text(json.dumps(record, indent=1) + "\n")
        for law, m in record["median_cold_s"]["new"].items():
            print(f"{law}: median cold {record['median_cold_s']['old'][law]:.1f} s ({a.against}), {m:.1f} s (this checkout)")
        print(f"wrote {OUT / 'cold_start_against.json'}")
        return 0
    record = {"machine": machine(), "commit": head()}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="cold_start_") as tmp:
        for law in ("paper", "mdr"):
            cache = Path(tmp) / f"cache_{law}"
            cold, warm = small_run(law, cache), small_run(law, cache)
            if cold["stress_end"] != warm["stress_end"]:
                raise SystemExit(f"{law}: cold and warm runs differ: {cold['stress_end']} != {warm['stress_end']}")
            record[law] = {"cold_s": cold["process_s"], "warm_s": warm["process_s"], "cold_run_s": cold["run_s"],
                           "warm_run_s": warm["run_s"], "import_s": cold["import_s"],
                           "compile_s": cold["run_s"] - warm["run_s"], "compiled": cold["compiled"]}
        if not a.skip_main_job:
            cache = Path(tmp) / "cache_main"
            record["main_job"] = {"cold_s": main_job(cache, Path(tmp) / "out_cold"),
                                  "warm_s": main_job(cache, Path(tmp) / "out_warm")}
    record["wall_s"] = time.perf_counter() - t0
    OUT.mkdir(exist_ok=True)
    (OUT / "cold_start.json").write_text(json.dumps(record, indent=1) + "\n")
    print(f"{'run':10s} {'cold [s]':>9s} {'warm [s]':>9s}")
    for name in ("paper", "mdr", "main_job"):
        if name in record:
            print(f"{name:10s} {record[name]['cold_s']:9.1f} {record[name]['warm_s']:9.1f}")
    for law in ("paper", "mdr"):
        print(f"\n{law}: compiled functions (time under the compiler lock, of it in LLVM) [s], largest first")
        for name, total, llvm in record[law]["compiled"][:15]:
            print(f"  {total:7.2f} {llvm:7.2f}  {name}")
    print(f"wrote {OUT / 'cold_start.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
