"""Scrambled Sobol' points in [0, 1)^4: the randomised QMC source of ``sampler="sobol"``.

Owns the digital net the population sampler draws from.  The four dimensions use the
primitive polynomials and initial direction numbers of Joe & Kuo (2008), the same as every
common Sobol' generator (the unscrambled points equal scipy's bit for bit, which a test
checks).  The randomisation is a linear matrix scramble (a random lower-triangular binary
matrix with unit diagonal per dimension) followed by a random digital shift, drawn from
``numpy.random.default_rng(seed)``: each point is uniform on [0, 1)^4, and the first 2^m
points keep the net's stratification (one point per cell of width 2^-m in every
coordinate).  Points come in Gray-code order, one XOR per point; blocks of points are
generated in parallel, each starting from its first point computed directly, so the result
does not depend on the number of threads.  :func:`net_directions` walks the same 2^m points
in increasing order of their first coordinate instead (the population sampler's height
order), with no sort.

Written here rather than taken from ``scipy.stats.qmc`` because importing ``scipy.stats``
costs about 0.8 s of every start-up, more than sampling 2^22 asperities.
"""

from __future__ import annotations

import numba
import numpy as np

from ..jit import kernel
from ..vectormath import copy_into

BITS = 32  # digits per coordinate (N_MAX < 2^31 points); held in int64: uint64 -> float is slow on x86-64
DIM = 4
BLOCK = 1 << 16  # points per parallel block
# (degree s, coefficients a of the inner terms, initial m_1..m_s) of the primitive
# polynomials of dimensions 2..4; dimension 1 is the van der Corput sequence
_POLYNOMIALS = ((1, 0, (1,)), (2, 1, (1, 3)), (3, 1, (1, 3, 1)))


def direction_numbers() -> np.ndarray:
    """(DIM, BITS) int64 direction numbers v_k = m_k 2^(BITS-k), k = 1..BITS (Bratley & Fox recurrence)."""
    v = np.zeros((DIM, BITS), dtype=np.int64)
    v[0] = [1 << (BITS - 1 - k) for k in range(BITS)]
    for j, (s, a, m_init) in enumerate(_POLYNOMIALS, start=1):
        m = list(m_init)
        for k in range(s, BITS):
            new = m[k - s] ^ (m[k - s] << s)
            for i in range(1, s):
                if (a >> (s - 1 - i)) & 1:
                    new ^= m[k - i] << i
            m.append(new)
        v[j] = [m[k] << (BITS - 1 - k) for k in range(BITS)]
    return v


_DIRECTIONS = direction_numbers()


def scrambled_directions(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Direction numbers after a random linear matrix scramble, and a random digital shift.

    Digit i (most significant first) of every direction number of dimension j becomes digit i
    xor a random sum (mod 2) of the more significant digits, i.e. the digits are multiplied by
    a random unit lower-triangular binary matrix L_j; L_j is invertible, so the points remain
    a digital net.
    """
    coins = rng.integers(0, 2, size=(DIM, BITS, BITS), dtype=np.int64)  # coins[j, i, l], l < i: digit l enters i
    shift = rng.integers(0, 1 << BITS, size=DIM, dtype=np.int64)
    return _scramble(_DIRECTIONS, coins), shift


@kernel()
def _scramble(v, coins):
    """out[j, k] = L_j v[j, k] over GF(2): digit i = digit i of v xor the digits l < i with coins[j, i, l] = 1."""
    out = np.zeros_like(v)
    for j in range(v.shape[0]):
        for i in range(BITS):  # row i of L_j as a BITS-bit mask (digit 0 is the most significant bit)
            mask = 1 << (BITS - 1 - i)
            for l in range(i):
                mask |= coins[j, i, l] << (BITS - 1 - l)
            for k in range(v.shape[1]):
                w, parity = mask & v[j, k], 0
                while w:
                    parity ^= 1
                    w &= w - 1
                out[j, k] |= parity << (BITS - 1 - i)
    return out


@kernel(inline="always")
def _xor_columns(x, v, key):
    """x[j] ^= v[j, b] for every set bit b of key."""
    b = 0
    while key:
        if key & 1:
            for j in range(DIM):
                x[j] ^= v[j, b]
        key >>= 1
        b += 1


@kernel(inline="always")
def _trailing_zeros(m):
    c = 0
    while not m & 1:
        m >>= 1
        c += 1
    return c


@kernel(parallel=True)
def _fill(v, shift, out):
    """out[i, j] = (shift_j xor (xor of v[j, k] over the bits k of gray(i))) / 2^BITS, Gray-code order."""
    n = out.shape[0]
    scale = 1.0 / float(1 << BITS)
    for b in numba.prange((n + BLOCK - 1) // BLOCK):
        lo, hi = b * BLOCK, min(n, (b + 1) * BLOCK)
        x = shift.copy()
        _xor_columns(x, v, lo ^ (lo >> 1))
        for i in range(lo, hi):
            for j in range(DIM):
                out[i, j] = float(x[j]) * scale
            c = _trailing_zeros(i + 1)  # gray(i + 1) = gray(i) xor 2^c
            if c < BITS:
                for j in range(DIM):
                    x[j] ^= v[j, c]


def net_directions(m: int, seed) -> tuple[np.ndarray, np.ndarray, int]:
    """The scrambled net of 2^m points from ``seed``, indexed by its first coordinate's cell.

    Returns (W, shift, s): the point whose first coordinate lies in cell c, [c, c + 1) 2^-m,
    is shift xor (xor of W[:, b] over the bits b of c xor s), as BITS-bit integers, so
    c = 0, 1, ... visits the points of :func:`sobol_points` (same seed) in increasing order
    of their first coordinate, with no sort.  The cell of a point is an affine bijection of
    its Gray code g (top m digits of shift_1 xor L_1 g); W composes its inverse with the
    scrambled direction numbers.
    """
    v, shift = scrambled_directions(np.random.default_rng(seed))
    return _cell_directions(v, m), shift, int(shift[0]) >> (BITS - m) if m > 0 else 0


@kernel()
def _cell_directions(v, m):
    """W of :func:`net_directions`: column b is the xor of v[:, k] over the Gray-code digits k of the point
    in cell 2^b xor s, found by a triangular solve over GF(2) (v[0, k] has its highest cell digit at m - 1 - k)."""
    W = np.zeros((DIM, m), dtype=np.int64)
    for b in range(m):
        rest = 1 << b
        for k in range(m):
            if rest >> (m - 1 - k) & 1:
                rest ^= v[0, k] >> (BITS - m)
                for j in range(DIM):
                    W[j, b] ^= v[j, k]
    return W


@kernel(inline="always")
def net_point(W, shift, s, c, x):
    """x = the BITS-bit digits of the point in first-coordinate cell c (see :func:`net_directions`)."""
    copy_into(x, shift)
    _xor_columns(x, W, c ^ s)


@kernel(inline="always")
def net_next(W, c, x):
    """Move x from the point in cell c to the point in cell c + 1 (the bits of c xor (c + 1))."""
    _xor_columns(x, W, c ^ (c + 1))


def sobol_points(n: int, seed, scramble: bool = True) -> np.ndarray:
    """The first n points, shape (n, 4), of the Sobol' sequence scrambled from ``seed`` (or unscrambled)."""
    if not 0 <= n <= 1 << (BITS - 1):
        raise ValueError(f"n = {n!r} is outside the range of the sequence (valid range: 0 to 2^{BITS - 1})")
    if scramble:
        v, shift = scrambled_directions(np.random.default_rng(seed))
    else:
        v, shift = _DIRECTIONS, np.zeros(DIM, dtype=np.int64)
    out = np.empty((n, DIM))
    _fill(v, shift, out)
    return out
