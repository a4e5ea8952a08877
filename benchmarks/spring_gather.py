"""What reading the `mdr` springs from a paged store would cost the trial, in a harness.

A paged store (``benchmarks/spring_rows.py``: the first ``inline`` springs of each contact in
place, the rest in pages of G = 4 that never move, named by a page table) is the only store
replayed that could bring the `mdr` peak under issue 37's 1.1 at 10⁷. Its price is in the trial:
the spring loops (``asperity_sim.laws.mdr.trial.committed_springs_scaled``) read one contiguous
row of 2k springs per direction. This harness runs that function over every contact of a real
`mdr` state, one thread, in slot order with the law's prefetch, two ways:

- ``fixed``: from the rows of 2k springs, in place (today's store);
- ``paged``: a contact whose springs in contact fit the inline row (n_in <= inline: then the loops
  read nothing beyond it and the row's length changes no sum) is read in place; the others are
  first gathered, inline row and pages, into a buffer of 2k (zeros beyond the held pages).

Both must give the same bits (checked). The pages are laid out in contact order, as a fresh store
would hold them, and shuffled, as many commits would leave them. The states: the end of the normal
stage of the history benchmark's path (where the rows fill) and of the Fig. 13 path, each read
from the run's checkpoint.

Run:   python benchmarks/spring_gather.py [--n 500000] [--inline 24,16] [--rounds 15]
Writes outputs/spring_gather.json. About a minute.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numba
import numpy as np

from asperity_sim import paths
from asperity_sim.laws.mdr.blocks import AHEAD
from asperity_sim.laws.mdr.springs import LANES
from asperity_sim.laws.mdr.trial import committed_springs_scaled, contact_scales
from asperity_sim.vectormath import prefetch

from spring_rows import end_state, normal_stage
from whole_run import K

ROOT = Path(__file__).resolve().parent.parent
G = 4  # springs per page
STATES = {"history, end of normal stage": normal_stage, "Fig. 13, end": lambda: paths.constant_normal_shear(500e6, 30e-6)}


def contacts_of(path, n):
    """(w, h, dn_c, R, consts, steps) of the live contacts of an `mdr` run of ``path`` at its end (the checkpoint's
    state), and the run's steps."""
    pop, a, ds = end_state(path, n)
    live = a["state_asp"] >= 0
    E_star, lam, mu = pop.params.E_star, pop.params.lam, pop.params.mu
    return (np.ascontiguousarray(a["state_law0"][live]), a["state_law1"][live].copy(), a["state_dn_c"][live].copy(),
            pop.R[a["state_asp"][live]], (E_star, lam, mu), int(ds.sizes["step"]))


def paged_store(w, inline, shuffle):
    """(inline rows, page table, pages) holding the springs of ``w`` (m, 2, S): pages only where a spring beyond
    the inline row is not zero; ``shuffle``: the pages in a random order."""
    m, _, S = w.shape
    n_pages = (S - inline) // G
    tail = np.any(w[:, :, inline:] != 0.0, axis=1).reshape(m, n_pages, G).any(axis=2)  # (m, n_pages)
    # a page is needed up to the last one holding a spring (the ones before it too: rows are prefixes)
    last = np.where(tail.any(axis=1), n_pages - np.argmax(tail[:, ::-1], axis=1), 0)
    table = np.full((m, n_pages), -1, dtype=np.int32)
    used = np.arange(n_pages)[None, :] < last[:, None]
    table[used] = np.arange(int(used.sum()), dtype=np.int32)
    pages = w[:, :, inline:].reshape(m, 2, n_pages, G).transpose(0, 2, 1, 3)[used]  # (pages, 2, G)
    if shuffle and len(pages):
        perm = np.random.default_rng(1).permutation(len(pages))
        where = np.empty_like(perm)
        where[perm] = np.arange(len(perm))
        pages = pages[perm]
        table[used] = where[table[used]]
    return np.ascontiguousarray(w[:, :, :inline]), table, np.ascontiguousarray(pages.reshape(-1, 2, G))


@numba.njit(inline="always")
def ask_ahead(w, i):
    """The law's prefetch: the first cache lines of both components of the row AHEAD contacts on."""
    if i + AHEAD < w.shape[0]:
        for a in range(2):
            prefetch(w, i + AHEAD, a, 0)
            prefetch(w, i + AHEAD, a, 16)


@numba.njit(inline="always")
def keep(out, i, r):
    """Column i of ``out``: F_s, F_t, J11, J12 and the slipping springs of :func:`committed_springs_scaled`."""
    out[0, i], out[1, i], out[2, i], out[3, i], out[4, i] = r[0], r[1], r[3], r[4], r[9]


@numba.njit(fastmath={"reassoc", "contract"}, error_model="numpy")
def trial_fixed(dn, dds, ddt, dn_c, R, h, w, consts, out):
    E_star, lam, mu = consts
    for i in range(dn.size):
        ask_ahead(w, i)
        c, q, f_n, k_n, n_in, rho, drho, n_c, _, _ = contact_scales(dn[i], dn_c[i], R[i], h[i], E_star, lam)
        keep(out, i, committed_springs_scaled(dn[i], dds[i], ddt[i], dn_c[i], lam, mu, w[i], c, q, f_n, k_n, n_in,
                                              rho, drho, n_c))


@numba.njit(fastmath={"reassoc", "contract"}, error_model="numpy")
def trial_paged(dn, dds, ddt, dn_c, R, h, w_in, table, pages, stored, consts, out):
    """:func:`trial_fixed` from the paged store; returns the contacts gathered."""
    E_star, lam, mu = consts
    inline = w_in.shape[2]
    buf = np.zeros((2, stored))
    gathered = 0
    for i in range(dn.size):
        ask_ahead(w_in, i)
        c, q, f_n, k_n, n_in, rho, drho, n_c, _, _ = contact_scales(dn[i], dn_c[i], R[i], h[i], E_star, lam)
        w = w_in[i]
        if n_in > inline:  # the loops read up to the whole vectors of the continuing springs, or n_in
            gathered += 1
            for a in range(2):
                for j in range(inline):
                    buf[a, j] = w[a, j]
            top = min(stored, max((min(n_c, n_in) + LANES - 1) // LANES * LANES, n_in))
            for p in range((top - inline + G - 1) // G):
                pg = table[i, p]
                lo = inline + p * G
                if pg >= 0:
                    page = pages[pg]
                    for a in range(2):
                        for j in range(G):
                            buf[a, lo + j] = page[a, j]
                else:
                    for a in range(2):
                        for j in range(G):
                            buf[a, lo + j] = 0.0
            r = committed_springs_scaled(dn[i], dds[i], ddt[i], dn_c[i], lam, mu, buf, c, q, f_n, k_n, n_in, rho,
                                         drho, n_c)
        else:  # a second call site: with one, fed either row, the loops ran 1.3-1.4 times slower
            r = committed_springs_scaled(dn[i], dds[i], ddt[i], dn_c[i], lam, mu, w, c, q, f_n, k_n, n_in, rho, drho,
                                         n_c)
        keep(out, i, r)
    return gathered


def measure(name, n, inlines, rounds):
    w, h, dn_c, R, consts, steps = contacts_of(STATES[name](), n)
    rng = np.random.default_rng(0)
    dn = dn_c * 1.002  # a trial a little further on: every contact continues, some springs enter
    dds, ddt = rng.normal(0.0, 1e-9, dn.size), rng.normal(0.0, 1e-9, dn.size)
    args = (dn, dds, ddt, dn_c, R, h)
    stored = w.shape[2]
    ref = np.empty((5, dn.size))
    trial_fixed(*args, w, consts, ref)
    rows = {"contacts": int(dn.size), "stored": int(stored), "steps": steps, "stores": {}}
    for inline in inlines:
        for shuffle in (False, True):
            w_in, table, pages = paged_store(w, inline, shuffle)
            out = np.empty_like(ref)
            gathered = trial_paged(*args, w_in, table, pages, stored, consts, out)
            t_fixed, t_paged = [], []
            for _ in range(rounds):  # alternating, medians
                t = time.perf_counter()
                trial_fixed(*args, w, consts, ref)
                t_fixed.append(time.perf_counter() - t)
                t = time.perf_counter()
                trial_paged(*args, w_in, table, pages, stored, consts, out)
                t_paged.append(time.perf_counter() - t)
            a, b = float(np.median(t_fixed)), float(np.median(t_paged))
            key = f"inline {inline}" + (", pages shuffled" if shuffle else "")
            rows["stores"][key] = {
                "same_bits": bool(np.array_equal(ref, out)), "gathered_fraction": gathered / dn.size,
                "store_springs_per_contact": inline + G * len(pages) / dn.size + table.shape[1] / 4.0,
                "fixed_ns_per_contact": 1e9 * a / dn.size, "paged_ns_per_contact": 1e9 * b / dn.size,
                "paged_over_fixed": b / a}
            r = rows["stores"][key]
            print(f"  {key:28s}: gathered {r['gathered_fraction']:.2f} of the contacts, store "
                  f"{r['store_springs_per_contact']:.1f} springs per contact (table included) against {stored}; "
                  f"{r['fixed_ns_per_contact']:.0f} -> {r['paged_ns_per_contact']:.0f} ns per contact, "
                  f"paged / fixed {r['paged_over_fixed']:.3f}; same bits: {r['same_bits']}", flush=True)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=500_000, help="asperities of each run")
    ap.add_argument("--inline", default="24,16", help="springs held in place per contact, comma separated")
    ap.add_argument("--rounds", type=int, default=15)
    args = ap.parse_args(argv)
    numba.set_num_threads(1)
    t = time.perf_counter()
    inlines = [int(x) for x in args.inline.split(",")]
    out = {"n": args.n, "k": K, "page": G, "rounds": args.rounds, "states": {}}
    for name in STATES:
        print(f"{name}, n = {args.n}:", flush=True)
        out["states"][name] = measure(name, args.n, inlines, args.rounds)
    out["seconds"] = time.perf_counter() - t
    same = all(r["same_bits"] for s in out["states"].values() for r in s["stores"].values())
    path = ROOT / "outputs" / "spring_gather.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(out, indent=1))
    print(f"wrote {path} ({out['seconds']:.0f} s)")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
