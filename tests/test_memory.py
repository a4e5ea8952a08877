"""Reserved arrays (asperity_sim.memory): zeroed, writable, usable by the kernels, and memory only where written."""

import os
import sys

import numba
import numpy as np
import pytest

from asperity_sim.memory import SMALL, reserve


def resident_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.parametrize("shape, dtype", [((10,), np.float64), ((1000, 2, 32), np.float32), ((300_000,), np.int8),
                                          ((4, 500_000), np.float64)])
def test_a_reserved_array_is_a_zeroed_writable_c_array_of_its_shape(shape, dtype):
    a = reserve(shape, dtype)
    assert a.shape == shape and a.dtype == dtype
    assert a.flags.c_contiguous and a.flags.writeable
    assert not np.any(a)
    a[-1] = 3
    assert a[-1].sum() == 3 * (a[-1].size if a.ndim > 1 else 1)


def test_small_arrays_are_ordinary():
    a = reserve(SMALL // 8 - 1)
    assert a.base is None  # owns its data: can be resized


@numba.njit
def fill_rows(a, lo, hi):
    for i in range(lo, hi):
        for j in range(a.shape[1]):
            a[i, j] = i + j
    return a[lo:hi].sum()


def test_kernels_read_and_write_a_reserved_array():
    a = reserve((100_000, 64))
    assert fill_rows(a, 10, 20) == sum(i + j for i in range(10, 20) for j in range(64))
    assert a[:10].sum() == 0 and a[20:].sum() == 0


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="resident memory read from /proc")
def test_only_the_rows_written_take_memory():
    before = resident_bytes()
    a = reserve((1_000_000, 2, 32))  # 512 MB reserved
    reserved = resident_bytes()
    a[:10_000] = 1.0  # 5.12 MB written
    written = resident_bytes()
    assert reserved - before < 8 * 2**20
    assert 4 * 2**20 < written - reserved < 12 * 2**20
