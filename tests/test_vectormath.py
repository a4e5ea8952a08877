"""Software prefetch (a hint that changes no value) and borrowed views (the same data without a reference count)."""

import numba
import numpy as np
import pytest

from asperity_sim.vectormath import borrowed, prefetch


@numba.njit
def _sum(a, ahead, hint):
    s = 0.0
    for i in range(a.shape[0]):
        if hint:
            prefetch(a, i + ahead, 1, 3)  # also beyond the end: a prefetch of any address is harmless
        for j in range(a.shape[1]):
            for k in range(a.shape[2]):
                s += a[i, j, k]
    return s


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_prefetch_changes_no_value(dtype):
    a = np.random.default_rng(0).random((1000, 2, 32)).astype(dtype)
    plain = _sum(a, 0, False)
    assert plain == pytest.approx(a.sum(dtype=np.float64), rel=1e-6)
    for ahead in (0, 4, 5000):
        assert _sum(a, ahead, True) == plain


def test_prefetch_refuses_what_it_is_not_for():
    @numba.njit
    def flat(a):
        prefetch(a, 0, 0, 0)

    with pytest.raises(numba.core.errors.TypingError):
        flat(np.zeros(8))


@numba.njit(inline="always")
def _scaled_sum(a, lo, hi, x):
    s = 0.0
    for i in range(lo, hi):
        s += a[i] * x if a[i] > 0.5 else a[i]
    return s


@numba.njit
def _through(arrays, borrow, scale):
    """Writes through, and sums over, the arrays of ``arrays`` (a nested tuple), borrowed or owned."""
    if borrow:
        arrays = borrowed(arrays)
    a, (b, c), k = arrays
    s = 0.0
    for i in range(a.size):
        a[i] = a[i] * scale
        s += _scaled_sum(b, 0, i % b.size, k) + c[i % c.shape[0], 1]
    return s


def test_borrowed_views_hold_the_same_data():
    rng = np.random.default_rng(1)
    a, b, c = rng.random(500), rng.random(40), rng.random((7, 3))
    a1, a2 = a.copy(), a.copy()
    owned = _through((a1, (b, c), 2.0), False, 3.0)
    assert _through((a2, (b, c), 2.0), True, 3.0) == owned  # the same bits: only the owner is dropped
    np.testing.assert_array_equal(a2, a * 3.0)  # writes reach the caller's array
    np.testing.assert_array_equal(a2, a1)


def test_borrowed_refuses_what_it_is_not_for():
    @numba.njit
    def scalar(x):
        return borrowed(x)

    with pytest.raises(numba.core.errors.TypingError):
        scalar(1.0)
