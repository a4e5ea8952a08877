"""How many springs the `mdr` contacts hold where the spring rows fill, and what packed rows would take.

The `mdr` law stores 2k springs per tangential direction for every contact (fixed rows), because a
contact born under stress control outgrows the k springs it was spaced for. This script runs the
stress-controlled normal stage of the history benchmark's path (``whole_run.bench_path``), where
the rows fill, reads the committed state from the run's own checkpoint at the stage's end, and
counts each contact's springs in contact N from its committed overlap and spacing, as the kernels
count them (``whole_run.springs_in_contact``). A contact's row must hold N + 1
springs (the one beyond the edge), at most the 2k stored.

It reports the distribution of N and, for rows rounded up to g springs with nothing else (no
holes, no index), what the `mdr` peak and the ratio ``mdr / (paper + k springs per contact)``
(issue 37's memory target) would become, from the peaks and contact counts of a record of
``whole_run.py --memory-sizes ...``: the fixed rows' 32 springs replaced by the rounded rows.

Run:   python benchmarks/spring_rows.py [--n 1000000] [--record docs/results/whole_run_52ef0e9.json]
Writes outputs/spring_rows.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from asperity_sim import Population, paths, presets, simulate
from asperity_sim.solve import run_checkpoint

from whole_run import K, bench_path, springs_in_contact

ROOT = Path(__file__).resolve().parent.parent
GRANULARITIES = (1, 2, 4, 8)


def normal_stage_springs(n: int, k: int = K):
    """(N per contact, springs stored per contact) at the end of the normal stage of the benchmark path, n asperities."""
    normal = bench_path().stages[0]
    path = paths.LoadPath((normal,), name="normal stage of the history benchmark")
    pop = Population.sample(presets.R1, n, seed=1)
    with tempfile.TemporaryDirectory() as tmp:
        ckpt = Path(tmp) / "normal.ckpt"
        simulate(presets.R1, path, population=pop, law="mdr", k=k, checkpoint=ckpt)  # written at the stage's end
        arrays = run_checkpoint.read(ckpt).arrays
    asp, w = arrays["state_asp"], arrays["state_law0"]
    live = asp >= 0
    return springs_in_contact(arrays["state_dn_c"][live], arrays["state_law1"][live], pop.R[asp[live]]), w.shape[-1]


def projection(N, stored, record):
    """Per granularity g: the mean row [springs], bytes per contact, and the ratio at each size of the record."""
    need = np.minimum(N + 1, stored)
    out = {}
    for g in GRANULARITIES:
        row = float(np.minimum(np.ceil(need / g) * g, stored).mean())
        per_contact = row * 2 * 8  # two tangential directions, float64
        sizes = {}
        for n, res in record.items():
            contacts = res["mdr"]["contacts_max"]
            saved = (stored * 2 * 8 - per_contact) * contacts
            peak = res["mdr"]["peak_rss"] - saved
            sizes[n] = {"mdr_peak_rss": peak, "ratio": peak / (res["paper"]["peak_rss"] + res["springs_bytes"])}
        out[g] = {"row_springs": row, "bytes_per_contact": per_contact, "sizes": sizes}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="asperities of the normal-stage run")
    ap.add_argument("--record", default=str(ROOT / "docs/results/whole_run_52ef0e9.json"),
                    help="a whole_run.py record with memory peaks")
    args = ap.parse_args(argv)
    record_path = Path(args.record).resolve()
    shown = record_path.relative_to(ROOT) if record_path.is_relative_to(ROOT) else record_path
    t = time.perf_counter()
    N, stored = normal_stage_springs(args.n)
    record = json.loads(record_path.read_text())["memory"]
    q = np.percentile(N, [10, 25, 50, 75, 90, 99]).tolist()
    print(f"n = {args.n}: {N.size} contacts at the end of the normal stage, {stored} springs stored per direction; "
          f"springs in contact: mean {N.mean():.2f}, quantiles 10/25/50/75/90/99 % {q}; "
          f"more than {K}: {(N > K).mean():.1%}, at the store's {stored} or more: {(N >= stored).mean():.1%}")
    proj = projection(N, stored, record)
    print(f"packed rows of N + 1 springs rounded up to g, against the peaks of {shown}:")
    for g, p in proj.items():
        sizes = ", ".join(f"n = {int(n):.0e}: mdr {s['mdr_peak_rss'] / 2**20:.0f} MiB, ratio {s['ratio']:.3f}"
                          for n, s in p["sizes"].items())
        print(f"  g = {g}: {p['row_springs']:.1f} springs, {p['bytes_per_contact']:.0f} B per contact; {sizes}")
    fixed = ", ".join(f"n = {int(n):.0e}: {r['ratio']:.3f}" for n, r in record.items())
    print(f"  fixed rows of {stored}: {stored * 16} B per contact; {fixed}")
    out = {"n": args.n, "contacts": int(N.size), "stored": int(stored), "mean": float(N.mean()), "quantiles": q,
           "histogram": np.bincount(N.astype(np.int64)).tolist(), "record": str(shown),
           "projection": {str(g): p for g, p in proj.items()}, "seconds": time.perf_counter() - t}
    path = ROOT / "outputs" / "spring_rows.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(out, indent=1))
    print(f"wrote {path} ({out['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
