"""Drawing the points of a population: the only module that touches random generators.

Owns :func:`unit_points` (numpy's PCG64 for ``sampler="random"``, scrambled Sobol' points
of :mod:`asperity_sim.sampling.sobol` for ``"sobol"``) and the kernels that turn points into
height-sorted struct-of-arrays: an O(n) sort of the height uniforms, the inverse CDFs of
:mod:`asperity_sim.sampling.distributions` applied block by block, and the Sobol' net drawn
directly in height order.  Blocks run on the threads (:func:`asperity_sim.threads.run_chunks`;
each block the same bits on any thread).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import kernel
from ..threads import chunks_of, run_chunks
from .distributions import cos_u_at, gamma_quantile_at, phi_at, radius_at
from .sobol import BITS as SOBOL_BITS
from .sobol import net_next, net_point, sobol_points

NET_BLOCK = 4096  # Sobol' points per block of sample_net (each block starts from a point computed directly)
POINT_BLOCK = 16384  # points per block of gather and inverse_cdfs


@kernel()
def argsort_unit(p):
    """Stable argsort of values in [0, 1) in O(n): counting sort into n equal buckets, then
    insertion sort inside each bucket (about one value per bucket for uniform points)."""
    n = p.size
    start = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        start[min(int(p[i] * n), n - 1) + 1] += 1
    for b in range(n):
        start[b + 1] += start[b]
    fill = start[:n].copy()
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        b = min(int(p[i] * n), n - 1)
        order[fill[b]] = i
        fill[b] += 1
    for b in range(n):
        lo = start[b]
        for k in range(lo + 1, start[b + 1]):
            j = order[k]
            m = k
            while m > lo and p[order[m - 1]] > p[j]:
                order[m] = order[m - 1]
                m -= 1
            order[m] = j
    return order


def gather(U, order, c0, c1, c2, c3):
    """c_k[i] = U[order[i], k]: the points in sorted order, one contiguous column per coordinate."""
    run_chunks(gather_in, chunks_of(order.size, POINT_BLOCK), U, order, c0, c1, c2, c3)


@kernel(nogil=True)
def gather_in(U, order, c0, c1, c2, c3, b_lo, b_hi):
    """:func:`gather` of the points of blocks b_lo .. b_hi."""
    for i in range(b_lo * POINT_BLOCK, min(order.size, b_hi * POINT_BLOCK)):
        j = order[i]
        c0[i], c1[i], c2[i], c3[i] = U[j, 0], U[j, 1], U[j, 2], U[j, 3]


@kernel()
def _asperity_at(p_r, p_R, p_u, p_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi, b, c, d):
    """(unit-scale gamma height, radius [m], u [rad], cos phi, sin phi) of the uniforms (p_r, p_R, p_u, p_phi),
    SPEC §2–§3 (Eq. 10).

    A height the quantile tables do not give is returned as -p, its probability negated (sign
    bit set, also for p = 0), for scipy's inverse.
    """
    p = p_r * p_band
    x = gamma_quantile_at(p, nodes, grid)
    r = -p if math.isnan(x) else x
    R = radius_at(p_R, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi) if radius else R_m
    x = p_u if b == 0.0 else cos_u_at(p_u, b)
    x = min(max(x, 0.0), 1.0)
    ph = 2.0 * math.pi * p_phi if c == 0.0 and d == 0.0 else phi_at(p_phi, x, b, c, d)
    return r, R, math.acos(x), math.cos(ph), math.sin(ph)


def inverse_cdfs(r, R, u, cos_phi, sin_phi, *constants):
    """In place, from the sorted uniforms held in r, R, u, cos_phi: :func:`_asperity_at` of each (``constants``:
    p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi, b, c, d)."""
    run_chunks(inverse_cdfs_in, chunks_of(r.size, POINT_BLOCK), r, R, u, cos_phi, sin_phi, *constants)


@kernel(nogil=True)
def inverse_cdfs_in(r, R, u, cos_phi, sin_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi,
                    b, c, d, b_lo, b_hi):
    """:func:`inverse_cdfs` of the points of blocks b_lo .. b_hi."""
    for i in range(b_lo * POINT_BLOCK, min(r.size, b_hi * POINT_BLOCK)):
        r[i], R[i], u[i], cos_phi[i], sin_phi[i] = _asperity_at(
            r[i], R[i], u[i], cos_phi[i], p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi, b, c, d)


@kernel(inline="always")
def _net_block(blk, W, shift, s, r, R, u, cos_phi, sin_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf,
               hi_cdf, lo, hi, b, c, d):
    """Points blk NET_BLOCK .. (blk + 1) NET_BLOCK - 1 of the net, from the first one computed directly."""
    scale = 1.0 / float(1 << SOBOL_BITS)
    i0, i1 = blk * NET_BLOCK, min(r.size, (blk + 1) * NET_BLOCK)
    x = np.empty(4, dtype=np.int64)
    net_point(W, shift, s, i0, x)
    for i in range(i0, i1):
        r[i], R[i], u[i], cos_phi[i], sin_phi[i] = _asperity_at(
            float(x[0]) * scale, float(x[1]) * scale, float(x[2]) * scale, float(x[3]) * scale, p_band,
            nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi, b, c, d)
        net_next(W, i, x)


def sample_net(W, shift, s, r, R, u, cos_phi, sin_phi, *constants):
    """The scrambled Sobol' net of r.size = 2^m points (:func:`asperity_sim.sampling.sobol.net_directions`) through
    :func:`_asperity_at`, generated in increasing order of the height uniform: already sorted, no
    array of uniforms.  Blocks of NET_BLOCK points run on the threads, each from its first point
    computed directly; a net of one block runs on the calling thread."""
    run_chunks(sample_net_in, chunks_of(r.size, NET_BLOCK), W, shift, s, r, R, u, cos_phi, sin_phi, *constants)


@kernel(nogil=True)
def sample_net_in(W, shift, s, r, R, u, cos_phi, sin_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf,
                  lo, hi, b, c, d, b_lo, b_hi):
    """:func:`sample_net` of blocks b_lo .. b_hi."""
    for blk in range(b_lo, b_hi):
        _net_block(blk, W, shift, s, r, R, u, cos_phi, sin_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf,
                   hi_cdf, lo, hi, b, c, d)


def clip_running_max(r, r_band):
    """r = running max of min(r, r_band), in place: round-off in the quantile never breaks the sort.

    numpy, not a kernel: min and max are exact, so the bits are those of any loop, and nothing is compiled."""
    np.minimum(r, r_band, out=r)
    np.maximum.accumulate(r, out=r)


def unit_points(n: int, seed, sampler: str) -> np.ndarray:
    """n points of [0, 1)^4 from the chosen sampler (the only random source)."""
    if sampler == "random":
        return np.random.default_rng(seed).random((n, 4))
    return sobol_points(n, seed)
