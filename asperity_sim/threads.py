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

__all__ = ["run_chunks", "chunks_of"]

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
    threads = min(numba.get_num_threads(), n_chunks)
    if threads <= 1:
        kernel(*args, 0, n_chunks)
        return
    edges = [n_chunks * t // threads for t in range(threads + 1)]
    others = [_pool().submit(kernel, *args, edges[t], edges[t + 1]) for t in range(1, threads)]
    try:
        kernel(*args, edges[0], edges[1])
    finally:
        for f in others:
            f.result()
