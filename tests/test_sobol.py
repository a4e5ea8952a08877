"""Scrambled Sobol' points (asperity_sim.sampling.sobol): scipy's unscrambled sequence, net structure, unbiasedness."""

import numba
import numpy as np
import pytest
from scipy.stats import qmc

from asperity_sim.sampling import sobol
from asperity_sim.sampling.sobol import sobol_points


def t_value(x, y, m):
    """Smallest t such that every elementary box of area 2^(t-m) holds 2^t of the 2^m points (x, y)."""
    for t in range(m + 1):
        k = m - t
        if all(np.bincount((np.floor(x * 2**a).astype(np.int64) << (k - a)) + np.floor(y * 2**(k - a)).astype(np.int64),
                           minlength=2**k).min() == 2**t for a in range(k + 1)):
            return t
    raise AssertionError("not a net")


def test_unscrambled_points_are_scipys_sobol_sequence_across_blocks_and_threads():
    """Same primitive polynomials and direction numbers as scipy (Joe & Kuo), Gray-code order."""
    n = 3 * sobol.BLOCK + 123  # several parallel blocks, the last one partial
    with pytest.warns(UserWarning, match="balance"):
        expected = qmc.Sobol(d=4, scramble=False, bits=sobol.BITS).random(n)
    before = numba.get_num_threads()
    try:
        for threads in sorted({1, before}):
            numba.set_num_threads(threads)
            np.testing.assert_array_equal(sobol_points(n, None, scramble=False), expected)
    finally:
        numba.set_num_threads(before)


@pytest.mark.parametrize("m", [4, 10])
def test_scrambled_points_keep_the_net_structure(m):
    """A linear matrix scramble and a digital shift keep every coordinate stratified (one point per
    cell of width 2^-m) and the t-value of every two-dimensional projection."""
    plain = sobol_points(2**m, None, scramble=False)
    for seed in range(3):
        x = sobol_points(2**m, seed)
        assert np.all((x >= 0.0) & (x < 1.0))
        for j in range(4):
            np.testing.assert_array_equal(np.sort(np.floor(x[:, j] * 2**m)), np.arange(2**m))
        for j in range(4):
            for k in range(j + 1, 4):
                assert t_value(x[:, j], x[:, k], m) == t_value(plain[:, j], plain[:, k], m)
        assert t_value(x[:, 0], x[:, 1], m) == 0


def test_seed_reproduces_the_points_and_different_seeds_differ():
    a, b, c = sobol_points(1000, 7), sobol_points(1000, 7), sobol_points(1000, 8)
    np.testing.assert_array_equal(a, b)
    assert not np.any(np.all(a == c, axis=0))


@pytest.mark.statistical
def test_randomised_qmc_estimate_is_unbiased_and_beats_monte_carlo():
    """f(x) = prod_j 3 x_j^2 has integral 1 over [0, 1]^4: the mean over scrambles lies within 4
    standard errors of 1, and its replica variance is far below Monte Carlo's Var f / n."""
    n, replicas = 2**10, 64
    est = np.array([np.prod(3.0 * sobol_points(n, seed) ** 2, axis=1).mean() for seed in range(replicas)])
    se = est.std(ddof=1) / np.sqrt(replicas)
    assert abs(est.mean() - 1.0) < 4.0 * se
    var_mc = ((9.0 / 5.0) ** 4 - 1.0) / n  # Var f = E f^2 - 1, E (3x^2)^2 = 9/5
    assert est.var(ddof=1) < var_mc / 100.0


@pytest.mark.parametrize("n", [-1, 2**31 + 1])
def test_bad_sample_size_names_the_range(n):
    with pytest.raises(ValueError, match="valid range"):
        sobol_points(n, 0)


def test_net_directions_visit_the_scrambled_points_in_order_of_their_first_coordinate():
    """net_point at cell c, then net_next, give the points of sobol_points (same seed) sorted by
    their first coordinate, which falls in cell c; a block may start anywhere.  The walk calls the
    compiled net_point and net_next from Python (a jitted walk here would be compiled on every run,
    ~2.5 s, while theirs are cached with their module)."""

    def walk(W, shift, s, start, count):
        out = np.empty((count, sobol.DIM), dtype=np.int64)
        x = np.empty(sobol.DIM, dtype=np.int64)
        sobol.net_point(W, shift, s, start, x)
        for i in range(count):
            out[i] = x
            sobol.net_next(W, start + i, x)
        return out

    for m, seed in ((0, 1), (1, 0), (6, 2), (13, 5)):
        n = 2**m
        W, shift, s = sobol.net_directions(m, seed)
        got = walk(W, shift, s, 0, n) / 2.0**sobol.BITS
        expected = sobol_points(n, seed)
        np.testing.assert_array_equal(got, expected[np.argsort(expected[:, 0])])
        np.testing.assert_array_equal(np.floor(got[:, 0] * n), np.arange(n))
        np.testing.assert_array_equal(walk(W, shift, s, n // 3, n - n // 3) / 2.0**sobol.BITS, got[n // 3:])


def test_matrix_scramble_is_the_product_with_a_unit_lower_triangular_matrix():
    """Digits of the scrambled direction numbers = L_j (digits of v) mod 2, with L_j built from the
    coins below its diagonal; computed here on digit arrays with numpy."""
    rng = np.random.default_rng(8)
    coins = rng.integers(0, 2, size=(sobol.DIM, sobol.BITS, sobol.BITS), dtype=np.int64)
    got = sobol._scramble(sobol._DIRECTIONS, coins)
    place = 1 << np.arange(sobol.BITS - 1, -1, -1, dtype=np.int64)  # digit i has weight 2^(BITS-1-i)
    for j in range(sobol.DIM):
        L = np.tril(coins[j], k=-1) + np.eye(sobol.BITS, dtype=np.int64)
        digits = (sobol._DIRECTIONS[j][None, :] & place[:, None]) != 0  # digits[i, k] of v[j, k]
        expected = ((L @ digits.astype(np.int64)) % 2 * place[:, None]).sum(axis=0)
        np.testing.assert_array_equal(got[j], expected)
