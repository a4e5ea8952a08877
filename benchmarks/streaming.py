"""The streaming probe of the history-law benchmarks, its other forms, and a timer.

No import of ``asperity_sim``: ``history_law_baseline.py`` runs it beside the code of an older commit.
"""

from __future__ import annotations

import time

import numba
import numpy as np

N_CHUNKS = 64  # parts of the array summed in parallel


@numba.njit(parallel=True, cache=True)
def stream(a):
    """The probe: the sum of ``a`` in N_CHUNKS parallel parts, each a plain loop over its bytes."""
    size = (a.size + N_CHUNKS - 1) // N_CHUNKS
    part = np.zeros(N_CHUNKS)
    for c in numba.prange(N_CHUNKS):
        s = 0.0
        for i in range(c * size, min(a.size, (c + 1) * size)):
            s += a[i]
        part[c] = s
    return part.sum()


# the same loop with its sums reassociated: LLVM vectorises it, so it waits less on each addition (not cached:
# numba's cache would file it under the same function as ``stream``)
stream_fastmath = numba.njit(parallel=True, fastmath=True)(stream.py_func)


@numba.njit(cache=True)
def stream_one_thread(a):
    """The probe on one thread."""
    s = 0.0
    for i in range(a.size):
        s += a[i]
    return s


def best_of(f, repeat):
    """(median, minimum) wall time [s] of ``repeat`` calls of ``f``."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return float(np.median(times)), float(np.min(times))


def memory_seconds_per_byte(probe=stream, repeat=3, nbytes=2**31):
    """Wall time per byte [s/B] of ``probe`` over an array far beyond the shared cache (2 GiB): the probe
    streaming from memory, to be scaled to a byte count that would otherwise stay in cache."""
    big = np.ones(nbytes // 8)
    probe(big)
    return best_of(lambda: probe(big), repeat)[0] / big.nbytes
