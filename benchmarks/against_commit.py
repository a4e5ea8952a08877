"""A benchmark of this checkout against the same benchmark of an older commit, run side by side.

Absolute times drift on a shared machine; a speed is only worth quoting as a ratio to something
timed in the same run.  This script answers "did this change make the benchmark slower?": it
checks out ``--commit`` into a temporary git worktree and runs the benchmark script in both
checkouts, alternately (``--rounds`` times, each in a fresh process with that checkout first on
the path and its own numba cache in the worktree), reads the JSON record each run writes, and
prints the median of every number of both, with new / old.

The benchmark must exist in both checkouts and write a JSON record (``--record``, relative to the
checkout, default ``outputs/history_law.json``); ``--key`` picks a sub-dictionary (default
``side_by_side``).  One warm-up run per side compiles the kernels first (not counted).

Run:   python3 benchmarks/against_commit.py --commit 1a1f7a4 [--rounds 3] -- benchmarks/history_law.py --rounds 1
Writes outputs/against_commit.json and prints a table.  About 2 x rounds x the benchmark's time.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run_side(checkout: Path, script: str, args: list, record: str, key: str | None) -> dict:
    env = {**os.environ, "PYTHONPATH": str(checkout), "OMP_WAIT_POLICY": "PASSIVE"}
    done = subprocess.run([sys.executable, str(checkout / script), *args], cwd=checkout, env=env,
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{checkout / script} failed:\n{done.stderr[-3000:]}")
    data = json.loads((checkout / record).read_text())
    return data[key] if key else data


def numbers(d: dict) -> dict:
    return {k: float(v) for k, v in d.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--commit", required=True, help="the older commit (any git ref)")
    ap.add_argument("--rounds", type=int, default=3, help="alternating runs per side (default 3)")
    ap.add_argument("--record", default="outputs/history_law.json", help="the JSON the benchmark writes")
    ap.add_argument("--key", default="side_by_side", help="the sub-dictionary of the record to compare ('' for all)")
    ap.add_argument("script", help="the benchmark, relative to the checkout (e.g. benchmarks/history_law.py)")
    ap.add_argument("args", nargs=argparse.REMAINDER, help="its arguments (after --)")
    a = ap.parse_args(argv)
    if a.rounds < 1:
        ap.error(f"--rounds = {a.rounds} is out of range (valid range: integer >= 1)")
    bench_args = [x for x in a.args if x != "--"]
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", a.commit], capture_output=True, text=True,
                            check=True).stdout.strip()
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                          check=True).stdout.strip()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="against_") as tmp:
        old = Path(tmp) / "old"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(old), commit], check=True,
                       capture_output=True)
        try:
            sides = {"old": old, "new": ROOT}
            for name, checkout in sides.items():  # warm-up: compile
                run_side(checkout, a.script, bench_args, a.record, a.key or None)
            runs = {"old": [], "new": []}
            for r in range(a.rounds):
                order = ("old", "new") if r % 2 == 0 else ("new", "old")
                for name in order:
                    runs[name].append(numbers(run_side(sides[name], a.script, bench_args, a.record, a.key or None)))
                    print(f"round {r + 1}: {name} done", flush=True)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(old)], capture_output=True)
    keys = [k for k in runs["new"][0] if all(k in x for x in runs["old"] + runs["new"])]
    table = {k: {"old": statistics.median(x[k] for x in runs["old"]), "new": statistics.median(x[k] for x in runs["new"])}
             for k in keys}
    for v in table.values():
        v["new_over_old"] = v["new"] / v["old"] if v["old"] else float("nan")
    print(f"\n{a.script} {' '.join(bench_args)}: new {head[:10]} against old {commit[:10]}, median of {a.rounds}")
    print(f"{'quantity':40s} {'old':>12s} {'new':>12s} {'new/old':>8s}")
    for k, v in table.items():
        print(f"{k:40s} {v['old']:12.5g} {v['new']:12.5g} {v['new_over_old']:8.3f}")
    out = ROOT / "outputs" / "against_commit.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"script": a.script, "args": bench_args, "old": commit, "new": head,
                               "rounds": a.rounds, "seconds": time.perf_counter() - t0, "median": table,
                               "runs": runs}, indent=1) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
