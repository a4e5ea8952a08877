"""What handing a kernel's chunks to the other threads costs: the package's workers against numba's own.

Every parallel kernel of the package is serial code that takes a range of chunks and releases
the GIL; :func:`asperity_sim.threads.run_chunks` gives the other threads their ranges through
the package's worker threads (which wait for the next part awake, polling without the GIL, for
up to ``ASPERITY_SIM_SPIN_US``).  This benchmark times one call of a small kernel over 2, 20 and
200 chunks (1000 additions each, about 1.6 us) three ways, medians of ``--calls`` back-to-back
calls:

- ``direct``: the calling thread does every chunk;
- ``pool``: :func:`~asperity_sim.threads.run_chunks`;
- ``claimed``: the same chunks claimed (:func:`~asperity_sim.threads.claim`, as the kernels over
  contacts take theirs), through :func:`~asperity_sim.threads.run_calls`: the part is posted with the
  GIL given up, and the caller starts once the worker has claimed a chunk;
- ``prange``: a numba ``parallel=True`` launcher whose loop over the threads calls the kernel
  (numba's threading layer: OpenMP here; ``OMP_WAIT_POLICY`` as in the environment).

The difference between ``pool`` (or ``prange``) at 2 chunks and ``direct`` is the hand-off.  Why
the package does not use the launcher: numba compiles it once per kernel (the kernel is part of
its argument types, and such a launcher is not served from the on-disk cache: a second compile in
every process), and numba's parallel loops take only arrays and scalars, where the package's
kernels take tuples (the law's constants and history arrays).  ``ASPERITY_SIM_SPIN_US=0
python3 benchmarks/handoff.py`` times the workers that sleep at once after each part.

Run:   python3 benchmarks/handoff.py [--calls 2000]
       OMP_WAIT_POLICY=ACTIVE python3 benchmarks/handoff.py
Prints a table (nothing is written).  About 10 s.
"""

from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np
from numba import prange

from asperity_sim.threads import claim, run_calls, run_chunks

WORK = 1000  # additions per chunk


@numba.njit(nogil=True)
def chunks(a, x, out, lo, hi):
    """Chunks lo .. hi: WORK additions each, the sum of chunk lo into out[lo]."""
    s = x
    for i in range(lo * WORK, hi * WORK):
        s += a[i % a.size]
    out[lo] = s


@numba.njit(nogil=True)
def claimed_chunks(a, x, out, claims, lo, hi):
    """:func:`chunks`, each thread taking the next chunk nobody has taken."""
    for kk0 in range(lo, hi):
        kk = claim(claims, kk0)
        if kk >= hi:
            break
        s = x
        for i in range(kk * WORK, (kk + 1) * WORK):
            s += a[i % a.size]
        out[kk] = s


@numba.njit(parallel=True, nogil=True)
def launch(kernel, a, x, out, edges):
    """``kernel`` over the ranges edges[t] .. edges[t + 1], one per thread of numba's threading layer."""
    for t in prange(edges.size - 1):
        kernel(a, x, out, edges[t], edges[t + 1])


def median_us(call, n_chunks, calls):
    call(n_chunks)
    times = []
    for _ in range(calls):
        t = time.perf_counter()
        call(n_chunks)
        times.append(time.perf_counter() - t)
    return 1e6 * float(np.median(times))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--calls", type=int, default=2000)
    args = ap.parse_args(argv)
    a, out = np.ones(WORK), np.zeros(256)
    threads = numba.get_num_threads()

    def edges(m):
        return np.array([m * t // threads for t in range(threads + 1)], dtype=np.int64)

    ways = {"direct": lambda m: chunks(a, 0.0, out, 0, m),
            "pool": lambda m: run_chunks(chunks, m, a, 0.0, out),
            "claimed": lambda m: run_calls((claimed_chunks, m, (a, 0.0, out), True)),
            "prange": lambda m: launch(chunks, a, 0.0, out, edges(m))}
    t = time.perf_counter()
    launch(chunks, a, 0.0, out, edges(2))
    compile_s = time.perf_counter() - t
    print(f"{threads} threads, numba threading layer {numba.threading_layer()}, OMP_WAIT_POLICY = "
          f"{os.environ.get('OMP_WAIT_POLICY', '(unset)')}; the launcher compiled in {compile_s:.1f} s")
    print(f"{'chunks':>7s} " + " ".join(f"{w + ' [us]':>12s}" for w in ways))
    for m in (2, 20, 200):
        print(f"{m:7d} " + " ".join(f"{median_us(call, m, args.calls):12.1f}" for call in ways.values()), flush=True)


if __name__ == "__main__":
    main()
