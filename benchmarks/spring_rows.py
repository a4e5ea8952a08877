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

Over the whole run (``--run-n`` asperities, the whole benchmark path): after every commit, each
slot's need N + 1 as above, and a replay of stores against those needs, peak [springs] over the
run per contact at the run's largest contact count, and the ratio it would give against the
record:

- ``fixed``: today's 2k springs per slot (a check of the replay);
- ``exact``: every row exactly its need at every commit, up and down (a contact that coarsens
  halves its need), with no holes: rows moved in place at every commit. Reported beside it, the
  springs that would move (every row after the first whose size changes, in slot order) over the
  springs the commits write;
- ``relocate s``: rows of need + s; a row that outgrows its room moves to the end of the store and
  leaves a hole, as does a lost contact; once the holes exceed 5 % of the rows, the store is
  compacted after the commit (rows refitted to need + s). The peak counts the holes a commit makes
  before its compaction;
- ``stage``: ``relocate 0`` with each row sized at birth for the largest need its contact reaches
  before the end of its stage (known only afterwards: an oracle no store has);
- ``paged g``: pages of g springs (both directions) that never move: a slot's page table (2k / g
  int32 entries, every slot) names its pages, a row takes ceil(need / g) pages, a row that grows
  takes more, and the pages a commit frees (a lost contact, a row that coarsened) are reused from
  the next commit on (a free list, one int32 per page). The peak counts the pages in use before a
  commit plus those it takes, the page tables and the free list, in springs (16 B each);
- ``paged g prepass``: the same, with each commit's pages freed and taken in a pass before it
  writes (a contact's springs in contact follow from its converged overlap, before its springs
  are computed), from a free list kept in the free pages themselves;
- ``paged g inline k prepass``: the first k springs of every slot in place (every contact has
  about k or more), pages only beyond them (a page table of k / g entries).

Run:   python benchmarks/spring_rows.py [--n 1000000] [--run-n 500000] [--record docs/results/whole_run_52ef0e9.json]
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
from asperity_sim.solve import run as driver
from asperity_sim.solve import run_checkpoint

from whole_run import K, bench_path, springs_in_contact

ROOT = Path(__file__).resolve().parent.parent
GRANULARITIES = (1, 2, 4, 8)


def normal_stage():
    """The normal stage of the history benchmark's path, alone: where the spring rows fill."""
    return paths.LoadPath((bench_path().stages[0],), name="normal stage of the history benchmark")


def end_state(path, n: int, k: int = K):
    """(population, committed state arrays, Dataset) of an `mdr` run of ``path`` on n asperities (seed 1): the state
    read from the run's checkpoint, written at the end of its last stage."""
    pop = Population.sample(presets.R1, n, seed=1)
    with tempfile.TemporaryDirectory() as tmp:
        ckpt = Path(tmp) / "state.ckpt"
        ds = simulate(presets.R1, path, population=pop, law="mdr", k=k, checkpoint=ckpt)
        arrays = run_checkpoint.read(ckpt).arrays
    return pop, arrays, ds


def normal_stage_springs(n: int, k: int = K):
    """(N per contact, springs stored per contact) at the end of the normal stage of the benchmark path, n asperities."""
    pop, arrays, _ = end_state(normal_stage(), n, k)
    asp, w = arrays["state_asp"], arrays["state_law0"]
    live = asp >= 0
    return springs_in_contact(arrays["state_dn_c"][live], arrays["state_law1"][live], pop.R[asp[live]]), w.shape[-1]


def projection(N, stored, record):
    """Per granularity g: the mean row [springs], bytes per contact, and the ratio at each size of the record."""
    need = np.minimum(N + 1, stored)
    out = {}
    for g in GRANULARITIES:
        row = float(np.minimum(np.ceil(need / g) * g, stored).mean())
        out[g] = {"row_springs": row, "bytes_per_contact": row * 2 * 8, "sizes": with_rows_of(row, stored, record)}
    return out


def with_rows_of(springs, stored, record):
    """Per size of the record: the `mdr` peak [B] with ``springs`` per contact in place of the ``stored`` of the
    fixed rows (two tangential directions, float64, at the run's largest contact count), and its ratio."""
    sizes = {}
    for n, res in record.items():
        peak = res["mdr"]["peak_rss"] - (stored - springs) * 2 * 8 * res["mdr"]["contacts_max"]
        sizes[n] = {"mdr_peak_rss": peak, "ratio": peak / (res["paper"]["peak_rss"] + res["springs_bytes"])}
    return sizes


def run_needs(n: int, k: int = K):
    """Each slot's need N + 1 (at most the springs stored; 0 for a free slot) and its asperity after every commit of the
    benchmark path at n asperities: a list of (asp, need), and the stage of each commit."""
    pop = Population.sample(presets.R1, n, seed=1)
    needs = []
    plain = driver.ContactState

    class Traced(plain):
        def commit(self, *a, **kw):
            result = super().commit(*a, **kw)
            m = self.n_slots
            asp = self.asp[:m].copy()
            live = asp >= 0
            need = np.zeros(m, dtype=np.int64)
            N = springs_in_contact(self.dn_c[:m][live], self.arrays[1][:m][live], pop.R[asp[live]])
            need[live] = np.minimum(N + 1, self.n_stored)
            needs.append((asp, need))
            return result

    driver.ContactState = Traced
    try:
        ds = simulate(presets.R1, bench_path(), population=pop, law="mdr", k=k)
    finally:
        driver.ContactState = plain
    return needs, ds.stage.values[1:], 2 * k


def stage_oracle(needs, stages, i):
    """Each slot's largest need from commit i to the end of its stage, while the same contact holds it."""
    asp, most = needs[i][0], needs[i][1].copy()
    j = i + 1
    while j < len(needs) and stages[j] == stages[i]:
        a2, n2 = needs[j]
        m = min(asp.size, a2.size)
        same = a2[:m] == asp[:m]
        most[:m] = np.where(same, np.maximum(most[:m], n2[:m]), most[:m])
        j += 1
    return most


def replay(needs, stages, stored, rows, slack=0, hole_fraction=0.05):
    """(peak [springs], compactions, springs moved) of a store of ``rows`` ("fixed", "exact", "relocate", "stage")."""
    size = max(a.size for a, _ in needs)
    room, owner = np.zeros(size, dtype=np.int64), np.full(size, -1, dtype=np.int64)
    top = used = peak = compactions = moved = 0
    for i, (asp, need) in enumerate(needs):
        m, live = asp.size, asp >= 0
        if rows == "fixed":  # a row per slot, reused by the next contact in the slot
            peak = max(peak, stored * m)
            continue
        if rows == "exact":
            changed = np.flatnonzero(np.where(live, need, 0) != room[:m])
            moved += int(need[changed[0]:].sum()) if changed.size else 0
            room[:m] = np.where(live, need, 0)
            peak = max(peak, int(room.sum()))
            continue
        fresh = owner[:m] != asp  # a lost contact, or a slot given to another
        used -= int(room[:m][fresh].sum())
        room[:m][fresh] = 0
        want = np.minimum(stored, (stage_oracle(needs, stages, i) if rows == "stage" else need) + slack)
        placed = live & (fresh | (need > room[:m]))  # rows put at the end of the store
        new = np.where(placed, want, room[:m])
        used += int((new - room[:m]).sum())
        top += int(new[placed].sum())
        room[:m], owner[:m] = np.where(live, new, 0), asp
        peak = max(peak, top)
        if top > (1.0 + hole_fraction) * used:  # compacted after the commit, every row refitted
            compactions += 1
            room[:m] = np.where(live, want, 0)
            used = top = int(room.sum())
            moved += used
    return peak, compactions, moved


def paged(needs, stored, g, inline=0, prepass=False):
    """Peak [springs] of a store of pages of g springs over the commits of ``needs`` (module docstring, ``paged``),
    page tables and free list included; ``inline``: springs every slot holds in place, pages only beyond them;
    ``prepass``: the pages of a commit are freed and taken before it writes, from a free list kept in the free
    pages themselves (no list, and what a commit frees it can take at once)."""
    size = max(a.size for a, _ in needs)
    pages, owner = np.zeros(size, dtype=np.int64), np.full(size, -1, dtype=np.int64)
    used = peak = slots = 0
    for asp, need in needs:
        m, live = asp.size, asp >= 0
        same = owner[:m] == asp
        new = np.where(live, -(-np.maximum(need - inline, 0) // g), 0)
        kept = np.where(same, pages[:m], 0)
        taken = int(np.maximum(new - kept, 0).sum())
        freed = int(pages[:m].sum() - np.minimum(new, kept).sum())
        peak = max(peak, used + taken - (freed if prepass else 0))
        used += taken - freed
        pages[:m], owner[:m] = new, asp
        slots = max(slots, m)
    table = slots * ((stored - inline) // g) * 4  # int32 page numbers per slot [B]
    free_list = 0 if prepass else peak * 4  # an int32 per page [B]
    return peak * g + slots * inline + (table + free_list) / 16.0


def move_cost(n, springs):
    """What the ``exact`` store's moves would cost: an in-place shift of ``springs`` float64 pairs (numpy's memmove, one
    thread), against the time per increment of an `mdr` run of the benchmark path at n asperities, both timed here."""
    pop = Population.sample(presets.R1, n, seed=2)
    simulate(presets.R1, bench_path(), population=pop, law="mdr", k=K)
    ds = simulate(presets.R1, bench_path(), population=pop, law="mdr", k=K)
    increment = ds.attrs["wall_time_increment_loop_s"] / (ds.sizes["step"] - 1)
    store = np.random.default_rng(0).random(2 * springs + 64)
    shifts = []
    for _ in range(15):
        t = time.perf_counter()
        store[64:] = store[:-64]
        shifts.append(time.perf_counter() - t)
    shift = float(np.median(shifts))
    return {"springs": springs, "shift_s": shift, "mdr_increment_s": increment, "shift_over_increment": shift / increment}


STORES = (("fixed", 0), ("exact", 0), ("relocate", 0), ("relocate", 2), ("relocate", 4), ("stage", 0))
PAGES = ((2, 0, False), (4, 0, False), (8, 0, False), (4, 0, True), (4, K, True), (2, K, True))
"""Paged stores replayed: (springs per page, springs held in place per slot, pre-pass)."""


def stores(n, record):
    """The replay of every store in STORES over the whole run at n asperities, with the ratios against ``record``."""
    needs, stages, stored = run_needs(n)
    contacts = max(int((a >= 0).sum()) for a, _ in needs)
    written = sum(int(need.sum()) for _, need in needs)
    out = {"contacts_max": contacts, "commits": len(needs), "springs_written": written,
           "need_per_contact_by_commit": [float(need[a >= 0].mean()) for a, need in needs],
           "exact_move": move_cost(n, max(int(need.sum()) for _, need in needs))}
    for rows, slack in STORES:
        peak, compactions, moved = replay(needs, stages, stored, rows, slack)
        per_contact = peak / contacts
        sizes = with_rows_of(per_contact, stored, record)
        out[f"{rows} {slack}" if rows == "relocate" else rows] = {
            "peak_springs_per_contact": per_contact, "compactions": compactions, "moved_over_written": moved / written,
            "sizes": sizes}
    for g, inline, prepass in PAGES:
        per_contact = paged(needs, stored, g, inline, prepass) / contacts
        name = f"paged {g}" + (f" inline {inline}" if inline else "") + (" prepass" if prepass else "")
        out[name] = {"peak_springs_per_contact": per_contact, "compactions": 0, "moved_over_written": 0.0,
                     "sizes": with_rows_of(per_contact, stored, record)}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="asperities of the normal-stage run")
    ap.add_argument("--run-n", type=int, default=500_000, help="asperities of the whole-run replay")
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
    run = stores(args.run_n, record)
    print(f"over the whole run at n = {args.run_n} ({run['commits']} commits, {run['contacts_max']} contacts at most), "
          "the store's peak per contact at the largest contact count:")
    for name, r in run.items():
        if isinstance(r, dict) and "sizes" in r:
            sizes = ", ".join(f"n = {int(n):.0e}: ratio {s['ratio']:.3f}" for n, s in r["sizes"].items())
            print(f"  {name:10s}: {r['peak_springs_per_contact']:.1f} springs; {r['compactions']} compactions, moved "
                  f"{r['moved_over_written']:.2f} of the springs the commits write; {sizes}")
    mv = run["exact_move"]
    print(f"  a move of the exact store's {mv['springs'] * 16 / 2**20:.0f} MiB in place takes {1e3 * mv['shift_s']:.2f} ms, "
          f"{mv['shift_over_increment']:.1%} of an mdr increment ({1e3 * mv['mdr_increment_s']:.1f} ms) at n = {args.run_n}")
    out = {"n": args.n, "contacts": int(N.size), "stored": int(stored), "mean": float(N.mean()), "quantiles": q,
           "histogram": np.bincount(N.astype(np.int64)).tolist(), "record": str(shown),
           "projection": {str(g): p for g, p in proj.items()}, "run_n": args.run_n, "whole_run": run,
           "seconds": time.perf_counter() - t}
    path = ROOT / "outputs" / "spring_rows.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(out, indent=1))
    print(f"wrote {path} ({out['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
