"""The ``mdr`` trial of an older commit against the same streaming probe, side by side with today's.

``history_law.py`` rates a trial as probe time / trial time, the probe being a minimal
parallel kernel that streams the bytes of the springs in contact.  This script measures the
same ratio for the code of an older commit (default ``e015820^``, the code before the law
protocol, where the history law cost about 20 x the ``paper`` law), so that the ratio of today
can be read against a starting point measured on this machine with this probe:

1. a detached git worktree of the old commit in a temporary folder;
2. alternately (``--rounds`` times), each in a fresh process: the old code (R1, n = 500 000,
   k = 16, the same constant-normal-stress path as ``history_law.py``; its ``paper`` and
   ``mdr`` shear increments, then the median of 7 trials at the end state, and the probe of
   its springs in contact) and today's code (``history_law.py --trial-only``);
3. the probe in other forms, for both byte counts, to show how much the ratio depends on the
   probe: with fastmath (a vectorised sum), on one thread, and from memory (a 2 GiB array,
   scaled to the bytes).

Run:   python benchmarks/history_law_baseline.py [--commit e015820^] [--rounds 2]
Writes outputs/history_law_baseline.json and prints a table.  About 1.5 minutes with --rounds 3 (2026-11-27).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np
from streaming import best_of, memory_seconds_per_byte, stream, stream_fastmath, stream_one_thread

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "outputs"

# Run in the old worktree, with the API of that commit (MDRHistory, evaluate_unchecked(pop, d, law, ...)).
OLD = r"""
import json, sys, time
import numpy as np
from asperity_sim import Population, paths, presets, simulate
from asperity_sim import state as state_module
from asperity_sim.assemble import Workspace, evaluate_unchecked
sys.path.insert(0, sys.argv[2])
from streaming import best_of, stream

n, UM = int(sys.argv[1]), 1e-6
S, D = paths.STRESS, paths.DISPLACEMENT

def cns_path(sigma_n=300e6, d2=10 * UM, normal=10, shear=40):  # as history_law.cns_path
    return paths.LoadPath((paths.Stage((S, D, D), (sigma_n, 0, 0), normal, name="normal"),
                           paths.Stage((S, D, D), (sigma_n, d2, 0), shear, name="shear")), name="cns")

def increment_time(pop, path, **kw):
    marks, kept = [], []
    commit = state_module.MDRHistory.commit
    def keep(self, *a, **k):  # the driver's history, at the end state after the run
        kept[:] = [self]
        return commit(self, *a, **k)
    state_module.MDRHistory.commit = keep
    try:
        simulate(pop.params, path, population=pop, progress=lambda st, *a: marks.append((st, time.perf_counter())),
                 **kw)
    finally:
        state_module.MDRHistory.commit = commit
    last = [t for s, t in marks if s == len(path.stages)]
    first = [t for s, t in marks if s == len(path.stages) - 1]
    return (last[-1] - first[-1]) / len(last), (kept[0] if kept else None)

pop = Population.sample(presets.R1, n, seed=1)
path = cns_path()
simulate(pop.params, cns_path(normal=2, shear=2), population=Population.sample(presets.R1, 2000, seed=0), law="mdr")
t_paper, _ = increment_time(pop, path, law="paper")
t_mdr, hist = increment_time(pop, path, law="mdr", k=16)
ws = Workspace(pop.n)
d = hist.delta_c + np.array([1e-3, 2e-3, 0.0]) * UM
evaluate_unchecked(pop, d, "mdr", None, ws, hist)
trial, _ = best_of(lambda: evaluate_unchecked(pop, d, "mdr", None, ws, hist), 7)
asp = np.flatnonzero(hist.slot >= 0)
sl = hist.slot[asp]
live = hist.dn_c[sl] > 0.0
n_in = np.ceil(np.sqrt(pop.R[asp][live] * hist.dn_c[sl][live]) / hist.h[sl][live] - 0.5)
m = int(np.minimum(n_in, hist.k).sum())  # springs with u_i > 0 at the committed overlap, as history_law counts
probe = np.ones(2 * m)
stream(probe)
probe_s, _ = best_of(lambda: stream(probe), 7)
print(json.dumps(dict(paper_increment_s=t_paper, mdr_increment_s=t_mdr, mdr_over_paper=t_mdr / t_paper,
                      contacts=int(live.sum()), springs_in_contact=m, spring_bytes_in_contact=int(probe.nbytes),
                      trial_s=trial, probe_s=probe_s, trial_over_probe_speed=probe_s / trial)))
"""


def probe_forms(n_bytes: list[int]) -> dict:
    """Median times [s] of the probe in its other forms for each byte count (warm in cache, and from memory)."""
    from_memory = {name: memory_seconds_per_byte(f) for name, f in (("benchmark", stream),
                                                                    ("one_thread", stream_one_thread))}
    out = {}
    for b in n_bytes:
        a = np.ones(b // 8)
        row = {}
        for name, f in (("benchmark", stream), ("fastmath", stream_fastmath), ("one_thread", stream_one_thread)):
            f(a)
            row[name] = best_of(lambda f=f: f(a), 9)[0]
        row.update({f"{name}_from_memory": per_byte * b for name, per_byte in from_memory.items()})
        out[str(b)] = row
    return out


def run_json(cmd, cwd, env=None) -> dict:
    p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(f"{' '.join(map(str, cmd[:3]))} failed:\n{p.stderr[-3000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--commit", default="e015820^", help="the older commit (default: e015820^)")
    ap.add_argument("--n", type=int, default=500_000)
    ap.add_argument("--rounds", type=int, default=2, help="alternating old/new runs; medians are reported")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    sha = subprocess.run(["git", "rev-parse", args.commit], cwd=ROOT, capture_output=True, text=True,
                         check=True).stdout.strip()
    old, new = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "old"
        subprocess.run(["git", "worktree", "add", "--detach", str(tree), sha], cwd=ROOT, check=True,
                       capture_output=True)
        try:
            env = dict(os.environ, PYTHONPATH=str(tree))
            for r in range(args.rounds):
                old.append(run_json([sys.executable, "-c", OLD, str(args.n), str(Path(__file__).parent)], tree, env))
                new.append(run_json([sys.executable, str(Path(__file__).parent / "history_law.py"), "--trial-only",
                                     "--n", str(args.n), "--k", "16", "--repeat", "7"], ROOT))
                print(f"round {r + 1}: old trial {1e3 * old[-1]['trial_s']:.1f} ms -> "
                      f"{old[-1]['trial_over_probe_speed']:.3f} of streaming speed; today "
                      f"{1e3 * new[-1]['trial_s']:.2f} ms -> {new[-1]['trial_over_probe_speed']:.3f} "
                      f"({time.perf_counter() - t0:.0f} s)", flush=True)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=ROOT, capture_output=True)

    def med(rows, key):
        return float(np.median([r[key] for r in rows]))

    summary = {}
    for name, rows in (("old", old), ("today", new)):
        summary[name] = {key: med(rows, key) for key in ("trial_s", "probe_s", "trial_over_probe_speed",
                                                         "springs_in_contact", "spring_bytes_in_contact")}
    summary["old"].update(mdr_over_paper=med(old, "mdr_over_paper"), mdr_increment_s=med(old, "mdr_increment_s"),
                          paper_increment_s=med(old, "paper_increment_s"))
    summary["today"]["run_trial_s"] = med(new, "run_trial_s")  # consecutive increments, as in a run
    forms = probe_forms([int(summary[s]["spring_bytes_in_contact"]) for s in ("old", "today")])
    for s in ("old", "today"):
        row = forms[str(int(summary[s]["spring_bytes_in_contact"]))]
        summary[s]["trial_over_probe_forms"] = {name: t / summary[s]["trial_s"] for name, t in row.items()}
    summary["today"]["run_trial_over_probe_forms"] = {
        name: t / summary["today"]["run_trial_s"]
        for name, t in forms[str(int(summary["today"]["spring_bytes_in_contact"]))].items()}
    gain = summary["today"]["trial_over_probe_speed"] / summary["old"]["trial_over_probe_speed"]
    out = {"commit": args.commit, "sha": sha, "n": args.n, "k": 16, "threads": numba.get_num_threads(),
           "summary": summary, "probe_forms_s": forms, "gain_in_trial_over_probe": gain,
           "rounds_old": old, "rounds_today": new, "wall_s": time.perf_counter() - t0}
    print(f"\n{'':46}{'old (' + args.commit + ')':>18}{'today':>12}{'today, as in a run':>20}")
    for label, key, f in (("springs in contact", "springs_in_contact", "{:.0f}"),
                          ("trial [ms]", "trial_s", "{:.2f}"), ("probe [ms]", "probe_s", "{:.3f}"),
                          ("trial / probe (speed)", "trial_over_probe_speed", "{:.3f}")):
        scale = 1e3 if key.endswith("_s") else 1.0
        run = {"trial_s": 1e3 * summary["today"]["run_trial_s"],
               "trial_over_probe_speed": summary["today"]["probe_s"] / summary["today"]["run_trial_s"]}.get(key)
        print(f"{label:46}{f.format(scale * summary['old'][key]):>18}{f.format(scale * summary['today'][key]):>12}"
              f"{'' if run is None else f.format(run):>20}")
    for name in forms[str(int(summary["old"]["spring_bytes_in_contact"]))]:
        print(f"{'  trial / probe, probe ' + name:46}{summary['old']['trial_over_probe_forms'][name]:>18.3f}"
              f"{summary['today']['trial_over_probe_forms'][name]:>12.3f}"
              f"{summary['today']['run_trial_over_probe_forms'][name]:>20.3f}")
    print(f"old mdr / paper increment: {summary['old']['mdr_over_paper']:.1f}; trial / probe today / old: {gain:.1f}")
    OUT.mkdir(exist_ok=True)
    (OUT / "history_law_baseline.json").write_text(json.dumps(out, indent=1))
    print(f"wrote {OUT / 'history_law_baseline.json'} ({out['wall_s']:.0f} s)")


if __name__ == "__main__":
    main()
