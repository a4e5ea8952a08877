"""Software prefetch: a hint that compiles for the spring store's arrays and changes no value."""

import numba
import numpy as np
import pytest

from asperity_sim.vectormath import prefetch


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
