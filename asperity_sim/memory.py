"""Arrays whose memory exists only where they are written: :func:`reserve`.

A store that grows with the contacts of a run (slots, springs) is reserved once for the most
it can hold, as an anonymous private memory map: the operating system gives a page the first
time it is written, so the store costs the pages its rows fill, never its reserved size, and
it never moves (no copy, no transient double while it grows, no room kept spare).  Where the
system refuses the reservation, an ordinary zeroed array stands in (and numpy's MemoryError
says when even that cannot be had).
"""

from __future__ import annotations

import mmap

import numpy as np

PAGE = mmap.PAGESIZE
SMALL = 64 * PAGE  # below this, an ordinary array


def reserve(shape, dtype=np.float64) -> np.ndarray:
    """A zeroed C-contiguous array of ``shape`` whose pages are backed only once written (small ones, or where
    no map can be made: an ordinary zeroed array)."""
    dtype = np.dtype(dtype)
    n = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    if n < SMALL:
        return np.zeros(shape, dtype=dtype)
    try:
        buf = mmap.mmap(-1, n, flags=mmap.MAP_PRIVATE)
    except (OSError, ValueError, AttributeError):  # no room to map it, or no anonymous maps here
        return np.zeros(shape, dtype=dtype)
    return np.frombuffer(buf, dtype=dtype, count=n // dtype.itemsize).reshape(shape)
