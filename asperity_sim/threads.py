"""How a kernel's work is spread over the threads: Python threads calling kernels that release the GIL.

Owns :func:`run_chunks`.  A kernel that works chunk by chunk (each chunk writes its own row of
partial sums, or its own asperities) is compiled serial with ``nogil=True`` and takes the range
``lo .. hi`` of chunks it does as its last two arguments; :func:`run_chunks` splits the chunks
into one contiguous range per thread and runs them at once, the calling thread taking the
first.  The number of threads is numba's (``numba.get_num_threads()``, as
``numba.set_num_threads`` or ``NUMBA_NUM_THREADS`` set it).  Each chunk gives the same bits
whatever range it falls in, so no result depends on the number of threads.

Why not numba's ``parallel=True``: numba compiles the body of a parallel loop twice (in the
function, then again as the loop's own kernel), which doubles the first-run compile time of the
reductions.  The price is at run time: a pool thread takes 70-100 us to pick up its part, where
numba's spinning OpenMP threads take 2-3 us (docs/performance.md, "The price of the pool").
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numba

__all__ = ["run_chunks", "run_calls", "chunks_of"]

_POOL: list = []
_LOCK = threading.Lock()


def _pool() -> ThreadPoolExecutor:
    """The process's worker threads (started at the first parallel call; the caller is the other thread)."""
    with _LOCK:
        if not _POOL:
            workers = max(1, numba.config.NUMBA_NUM_THREADS - 1)
            _POOL.append(ThreadPoolExecutor(max_workers=workers, thread_name_prefix="asperity_sim"))
        return _POOL[0]


def chunks_of(n: int, size: int) -> int:
    """How many chunks of ``size`` items hold n items."""
    return (n + size - 1) // size


def run_chunks(kernel, n_chunks: int, *args) -> None:
    """``kernel(*args, lo, hi)`` over chunks 0 .. n_chunks, one contiguous range per thread, all at once."""
    run_calls((kernel, n_chunks, args))


def run_calls(*calls) -> None:
    """Several chunked kernels handed to the threads at once: each ``(kernel, n_chunks, args)`` as :func:`run_chunks`.

    Each thread runs its range of every call, in the order given, so the calls must not read what
    another writes.  One hand-off for all of them: a pool thread takes 70-100 us to pick up its
    part, as long as a small kernel takes.  The extra chunk of an odd split goes to the last
    thread in the first call, to the first in the second, and so on, so that the parts stay even.
    """
    threads = min(numba.get_num_threads(), max(n for _, n, _ in calls))
    if threads <= 1:
        for kernel, n_chunks, args in calls:
            kernel(*args, 0, n_chunks)
        return
    parts: list[list] = [[] for _ in range(threads)]
    for c, (kernel, n_chunks, args) in enumerate(calls):
        edges = [n_chunks * t // threads if c % 2 == 0 else n_chunks - n_chunks * (threads - t) // threads
                 for t in range(threads + 1)]
        for t in range(threads):
            if edges[t] < edges[t + 1]:
                parts[t].append((kernel, args, edges[t], edges[t + 1]))
    others = [_pool().submit(_run_part, part) for part in parts[1:] if part]
    try:
        _run_part(parts[0])
    finally:
        for f in others:
            f.result()


def _run_part(part) -> None:
    """One thread's ranges of the calls of :func:`run_calls`, in order."""
    for kernel, args, lo, hi in part:
        kernel(*args, lo, hi)
