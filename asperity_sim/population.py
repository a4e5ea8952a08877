"""A sampled population of asperity contacts (SPEC §2–§3).

Owns sampling: this is the only module that touches random generators.  A population
is struct-of-arrays (no Python object per asperity): heights r, relative radii R and
fixed shifted orientation coordinates (u, phi), stored sorted by height so that a
kernel can skip every asperity that cannot touch at a given displacement.

Each draw maps one point of the unit hypercube [0, 1)^4 through the inverse CDFs of
the independent densities: gamma heights (SPEC §2, corrected normalisation), the
truncated Gaussian radius, the marginal of cos u, and the conditional of phi given u
(Eq. 10, corrected).  ``sampler="random"`` takes the points from numpy's PCG64,
``sampler="sobol"`` from scrambled Sobol' points (randomised QMC).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numba
import numpy as np
from scipy import special

from .params import InterfaceParams
from .sobol import BITS as SOBOL_BITS
from .sobol import net_directions, net_next, net_point, sobol_points

SAMPLERS = ("random", "sobol")
_EMPTY = np.empty(0)
N_MAX = 2**31 - 1
NET_BLOCK = 4096  # Sobol' points per parallel block of _sample_net


@numba.njit(cache=True, inline="always")
def _bracketed_newton(x, f, fp, lo, hi):
    """(next x, lo, hi): a Newton step on an increasing function with value f and slope fp at x,
    the bracket [lo, hi] of the root narrowed by the sign of f, and bisection when the step
    leaves it (or the slope is not positive)."""
    if f > 0.0:
        hi = x
    else:
        lo = x
    xn = x - f / fp if fp > 0.0 else 0.5 * (lo + hi)
    if not (lo < xn < hi):
        xn = 0.5 * (lo + hi)
    return xn, lo, hi


@numba.njit(cache=True, inline="always")
def _cos_u_at(target, b):
    """Invert F(x) = x + b (x³ - x)/2 on [0, 1] at F = target: marginal CDF of x = cos u (Eq. 10)."""
    lo, hi = 0.0, 1.0
    x = target
    for _ in range(100):
        f = x + 0.5 * b * (x * x * x - x) - target
        fp = 1.0 + 0.5 * b * (3.0 * x * x - 1.0)
        xn, lo, hi = _bracketed_newton(x, f, fp, lo, hi)
        if abs(xn - x) <= 1e-15:
            return xn
        x = xn
    return x


@numba.njit(cache=True, inline="always")
def _phi_at(p, xi, b, c, d):
    """Invert the conditional CDF of phi given x = cos u (Eq. 10) on [0, 2 pi) at probability p."""
    two_pi = 2.0 * math.pi
    a0 = 1.0 + 0.5 * b * (3.0 * xi * xi - 1.0)
    a2 = 3.0 * (1.0 - xi * xi)
    target = p * two_pi * a0
    lo, hi = 0.0, two_pi
    ph = p * two_pi
    for _ in range(100):
        f = a0 * ph + 0.5 * a2 * (c * math.sin(2.0 * ph) + d * (1.0 - math.cos(2.0 * ph))) - target
        fp = a0 + a2 * (c * math.cos(2.0 * ph) + d * math.sin(2.0 * ph))
        pn, lo, hi = _bracketed_newton(ph, f, fp, lo, hi)
        if abs(pn - ph) <= 1e-15:
            return pn
        ph = pn
    return ph


@numba.njit(cache=True)
def _cos_u_from_uniform(p, b):
    out = np.empty_like(p)
    for i in range(p.size):
        out[i] = _cos_u_at(p[i], b)
    return out


@numba.njit(cache=True)
def _phi_from_uniform(p, x, b, c, d):
    out = np.empty_like(p)
    for i in range(p.size):
        out[i] = _phi_at(p[i], x[i], b, c, d)
    return out


# Standard normal quantile by Wichura's algorithm AS 241 (PPND16, Applied Statistics 37, 1988):
# rational functions of degree 7 in three regions, about 1e-16 relative.  Coefficients from
# the published algorithm, lowest degree first.
_AS241_A = (3.387132872796366608, 133.14166789178437745, 1971.5909503065514427, 13731.693765509461125,
            45921.953931549871457, 67265.770927008700853, 33430.575583588128105, 2509.0809287301226727)
_AS241_B = (1.0, 42.313330701600911252, 687.1870074920579083, 5394.1960214247511077, 21213.794301586595867,
            39307.89580009271061, 28729.085735721942674, 5226.495278852545925)
_AS241_C = (1.42343711074968357734, 4.6303378461565452959, 5.7694972214606914055, 3.64784832476320460504,
            1.27045825245236838258, 0.24178072517745061177, 0.0227238449892691845833, 7.7454501427834140764e-4)
_AS241_D = (1.0, 2.05319162663775882187, 1.6763848301838038494, 0.68976733498510000455,
            0.14810397642748007459, 0.0151986665636164571966, 5.475938084995344946e-4,
            1.05075007164441684324e-9)
_AS241_E = (6.6579046435011037772, 5.4637849111641143699, 1.7848265399172913358, 0.29656057182850489123,
            0.026532189526576123093, 0.0012426609473880784386, 2.71155556874348757815e-5,
            2.01033439929228813265e-7)
_AS241_F = (1.0, 0.59983220655588793769, 0.13692988092273580531, 0.0148753612908506148525,
            7.868691311456132591e-4, 1.8463183175100546818e-5, 1.4215117583164458887e-7,
            2.04426310338993978564e-15)


@numba.njit(cache=True, inline="always")
def _ratio7(num, den, t):
    """num(t) / den(t) for two degree-7 polynomials (coefficients lowest degree first), Horner."""
    a = num[7]
    b = den[7]
    for k in range(6, -1, -1):
        a = a * t + num[k]
        b = b * t + den[k]
    return a / b


@numba.njit(cache=True, inline="always")
def _ndtri_at(p):
    """Standard normal quantile Phi^-1(p) for p in [0, 1] (-inf at 0, +inf at 1)."""
    q = p - 0.5
    if abs(q) <= 0.425:
        return q * _ratio7(_AS241_A, _AS241_B, 0.180625 - q * q)
    t = p if q < 0.0 else 1.0 - p
    if not t > 0.0:
        return -math.inf if q < 0.0 else math.inf
    t = math.sqrt(-math.log(t))
    if t <= 5.0:
        x = _ratio7(_AS241_C, _AS241_D, t - 1.6)
    else:
        x = _ratio7(_AS241_E, _AS241_F, t - 5.0)
    return -x if q < 0.0 else x


@numba.njit(cache=True, inline="always")
def _radius_at(p, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi):
    """Truncated Gaussian relative radius [m] at probability p (SPEC §2); never 0."""
    R = R_m + R_sigma * _ndtri_at(lo_cdf + p * (hi_cdf - lo_cdf))
    R = min(max(R, lo), hi)
    return max(R, 5e-324)  # R = 0 has probability zero but the quantile can return the bound itself


# Inverse gamma CDF by table: cubic Hermite interpolation of the quantile function x(p), nodes
# and slopes exact from scipy, in three pieces: x(p) on [P_LO, P_HI]; the lower tail in
# t = p^(1/shape) on [0, P_LO^(1/shape)] (x is analytic in t at p = 0, about (Gamma(shape + 1)
# p)^(1/shape)); the upper tail in t = -log(1 - p) on [-log(1 - P_HI), T_MAX] (x is nearly
# linear in t as p -> 1; every sampler's uniform has 1 - p >= 2^-53, t <= 36.8).  Each piece is
# checked against scipy at every cell midpoint when built and used only if it is within
# TABLE_RTOL there (about 1e-14 for the presets); where a piece is not accurate (shapes far
# below 1, whose quantile is too steep near p = 0) or does not reach, scipy's gammaincinv
# (about 0.5 s per million) is used.
P_LO, P_HI, N_NODES = 0.02, 0.98, 2**15
N_TAIL, T_MAX = 2**13, 40.0
TABLE_RTOL = 1e-13


def _checked_piece(t, x, slope, exact_at):
    """(x, slope, cells) of one piece if its Hermite interpolant meets TABLE_RTOL at every cell
    midpoint, else cells = -1 (never used).

    The spacing is (t[-1] - t[0]) / cells, as the kernel computes it (t[1] - t[0] differs in its
    last digits, which shifts the far cells by up to 1e-13)."""
    cells = t.size - 1
    h = (t[-1] - t[0]) / cells
    mid = 0.5 * (t[1:] + t[:-1])
    got = np.empty_like(mid)
    nodes = np.stack([x, slope])
    _hermite_many(mid, nodes, t[0], h, cells, got)
    exact = exact_at(mid)
    ok = np.all(np.isfinite(slope)) and np.all(np.abs(got - exact) <= TABLE_RTOL * exact)
    return x, slope, cells if ok else -1


@lru_cache(maxsize=8)
def _quantile_table(shape: float):
    """The tables of the unit-scale gamma quantile: nodes (6, N_NODES + 1), the values and slopes
    of the middle, lower and upper pieces (padded), and grid = (start, spacing, cells) of each
    piece then 1/shape; cells = -1 marks a piece that is not accurate."""
    gamma_pdf = lambda x: np.exp(special.xlogy(shape - 1.0, x) - x - special.gammaln(shape))  # noqa: E731
    t_lo, t_hi = P_LO ** (1.0 / shape), -math.log1p(-P_HI)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        p = np.linspace(P_LO, P_HI, N_NODES + 1)
        x = special.gammaincinv(shape, p)
        pieces = [_checked_piece(p, x, 1.0 / gamma_pdf(x), lambda m: special.gammaincinv(shape, m))]
        if t_lo > 0.0:  # else shape is so small that P_LO^(1/shape) underflows: scipy
            t = np.linspace(0.0, t_lo, N_TAIL + 1)  # lower tail, p = t^shape
            x = special.gammaincinv(shape, t**shape)
            slope = shape * t ** (shape - 1.0) / gamma_pdf(x)
            slope[0] = special.gamma(shape + 1.0) ** (1.0 / shape)  # the limit of dx/dt at t = 0
            pieces.append(_checked_piece(t, x, slope, lambda m: special.gammaincinv(shape, m**shape)))
        else:
            pieces.append((_EMPTY, _EMPTY, -1))
        t = np.linspace(t_hi, T_MAX, N_TAIL + 1)  # upper tail, 1 - p = exp(-t)
        q = np.exp(-t)
        x = special.gammainccinv(shape, q)
        pieces.append(_checked_piece(t, x, q / gamma_pdf(x), lambda m: special.gammainccinv(shape, np.exp(-m))))
    nodes = np.full((6, N_NODES + 1), np.nan)
    for i, (x, slope, _) in enumerate(pieces):
        nodes[2 * i, :x.size], nodes[2 * i + 1, :x.size] = x, slope
    starts, spans = (P_LO, 0.0, t_hi), (P_HI - P_LO, t_lo, T_MAX - t_hi)
    grid = [v for (_, _, cells), t0, span in zip(pieces, starts, spans)
            for v in (t0, span / cells if cells > 0 else 1.0, cells)]
    return nodes, np.array(grid + [1.0 / shape])


@numba.njit(cache=True, inline="always")
def _hermite_at(t, nodes, piece, t0, h, cells):
    """Cubic Hermite interpolant of piece ``piece`` of the quantile tables at t (NaN outside it)."""
    s = (t - t0) / h
    if not (0.0 <= s <= cells):
        return np.nan
    k = min(int(s), int(cells) - 1)
    s -= k
    s2, s3 = s * s, s * s * s
    x, d = nodes[2 * piece], nodes[2 * piece + 1]
    return ((2.0 * s3 - 3.0 * s2 + 1.0) * x[k] + (s3 - 2.0 * s2 + s) * h * d[k]
            + (-2.0 * s3 + 3.0 * s2) * x[k + 1] + (s3 - s2) * h * d[k + 1])


@numba.njit(cache=True, parallel=True)
def _hermite_many(t, nodes, t0, h, cells, out):
    """out = :func:`_hermite_at` of piece 0 at every t."""
    for i in numba.prange(t.size):
        out[i] = _hermite_at(t[i], nodes, 0, t0, h, cells)


@numba.njit(cache=True, inline="always")
def _gamma_quantile_at(p, nodes, grid):
    """Unit-scale gamma quantile at probability p from the tables of :func:`_quantile_table`
    (NaN where no accurate table reaches: the caller uses scipy there)."""
    if p < grid[0]:
        return _hermite_at(p ** grid[9], nodes, 1, grid[3], grid[4], grid[5])
    if p > P_HI:
        return _hermite_at(-math.log1p(-p), nodes, 2, grid[6], grid[7], grid[8])
    return _hermite_at(p, nodes, 0, grid[0], grid[1], grid[2])


@numba.njit(cache=True, parallel=True)
def _gamma_quantiles(p, nodes, grid, out):
    """out = :func:`_gamma_quantile_at` at every p."""
    for i in numba.prange(p.size):
        out[i] = _gamma_quantile_at(p[i], nodes, grid)


def heights_from_uniform(params: InterfaceParams, p):
    """Gamma heights r [m] (shape alpha+1, scale beta) from uniforms, SPEC §2 (inverse CDF)."""
    p = np.ascontiguousarray(p, dtype=float)
    shape = params.alpha + 1.0
    x = np.empty_like(p)
    _gamma_quantiles(p.ravel(), *_quantile_table(shape), x.ravel())
    tail = np.isnan(x)
    x[tail] = special.gammaincinv(shape, p[tail])
    return x * params.beta


def band_probability(params: InterfaceParams, r_max) -> float:
    """P(r <= r_max) [1] for the gamma heights of SPEC §2 (1 for None or inf)."""
    if r_max is None:
        return 1.0
    if isinstance(r_max, bool) or not isinstance(r_max, numbers.Real) or not r_max > 0.0:
        raise ValueError(f"r_max = {r_max!r} is not a valid height band [m] (valid range: > 0, inf allowed)")
    if math.isinf(r_max):
        return 1.0
    return float(special.gammainc(params.alpha + 1.0, r_max / params.beta))


def _radius_constants(params: InterfaceParams):
    """(R_m, R_sigma, Phi(a), Phi(b), lo, hi) of the truncated Gaussian of SPEC §2 [m, m, 1, 1, m, m]."""
    lo, hi = params.R_bounds
    a = (lo - params.R_m) / params.R_sigma
    b = (hi - params.R_m) / params.R_sigma
    return params.R_m, params.R_sigma, float(special.ndtr(a)), float(special.ndtr(b)), lo, hi


@numba.njit(cache=True, parallel=True)
def _radii(p, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi, out):
    for i in numba.prange(p.size):
        out[i] = _radius_at(p[i], R_m, R_sigma, lo_cdf, hi_cdf, lo, hi)


def radii_from_uniform(params: InterfaceParams, p):
    """Truncated Gaussian relative radii R [m] from uniforms, SPEC §2 (inverse CDF)."""
    p = np.ascontiguousarray(p, dtype=float)
    if params.R_sigma == 0.0:
        return np.full_like(p, params.R_m)
    out = np.empty_like(p)
    _radii(p.ravel(), *_radius_constants(params), out.ravel())
    return out


def orientation_from_uniform(params: InterfaceParams, p_u, p_phi):
    """Shifted meridional coordinate u [rad] and azimuth phi [rad] from uniforms (Eq. 10)."""
    if params.b == 0.0:
        x = np.asarray(p_u, dtype=float).copy()  # cos u uniform on [0, 1]
    else:
        x = _cos_u_from_uniform(np.ascontiguousarray(p_u, dtype=float), params.b)
    if params.c == 0.0 and params.d == 0.0:
        phi = 2.0 * math.pi * np.asarray(p_phi, dtype=float)
    else:
        phi = _phi_from_uniform(np.ascontiguousarray(p_phi, dtype=float), x, params.b, params.c, params.d)
    u = np.arccos(np.clip(x, 0.0, 1.0))
    return u, phi


@numba.njit(cache=True)
def _argsort_unit(p):
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


@numba.njit(cache=True, parallel=True)
def _gather(U, order, c0, c1, c2, c3):
    """c_k[i] = U[order[i], k]: the points in sorted order, one contiguous column per coordinate."""
    for i in numba.prange(order.size):
        j = order[i]
        c0[i], c1[i], c2[i], c3[i] = U[j, 0], U[j, 1], U[j, 2], U[j, 3]


@numba.njit(cache=True, inline="always")
def _asperity_at(p_r, p_R, p_u, p_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi, b, c, d):
    """(unit-scale gamma height, radius [m], u [rad], cos phi, sin phi) of the uniforms (p_r, p_R, p_u, p_phi),
    SPEC §2–§3 (Eq. 10).

    A height the quantile tables do not give is returned as -p, its probability negated (sign
    bit set, also for p = 0), for scipy's inverse.
    """
    p = p_r * p_band
    x = _gamma_quantile_at(p, nodes, grid)
    r = -p if math.isnan(x) else x
    R = _radius_at(p_R, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi) if radius else R_m
    x = p_u if b == 0.0 else _cos_u_at(p_u, b)
    x = min(max(x, 0.0), 1.0)
    ph = 2.0 * math.pi * p_phi if c == 0.0 and d == 0.0 else _phi_at(p_phi, x, b, c, d)
    return r, R, math.acos(x), math.cos(ph), math.sin(ph)


@numba.njit(cache=True, parallel=True)
def _inverse_cdfs(r, R, u, cos_phi, sin_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi,
                  b, c, d):
    """In place, from the sorted uniforms held in r, R, u, cos_phi: :func:`_asperity_at` of each."""
    for i in numba.prange(r.size):
        r[i], R[i], u[i], cos_phi[i], sin_phi[i] = _asperity_at(
            r[i], R[i], u[i], cos_phi[i], p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi, b, c, d)


@numba.njit(cache=True, inline="always")
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


@numba.njit(cache=True, parallel=True)
def _sample_net(W, shift, s, r, R, u, cos_phi, sin_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf,
                lo, hi, b, c, d):
    """The scrambled Sobol' net of r.size = 2^m points (:func:`asperity_sim.sobol.net_directions`) through
    :func:`_asperity_at`, generated in increasing order of the height uniform: already sorted, no
    array of uniforms.  Blocks of points run in parallel, each from its first point computed directly."""
    for blk in numba.prange((r.size + NET_BLOCK - 1) // NET_BLOCK):
        _net_block(blk, W, shift, s, r, R, u, cos_phi, sin_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf,
                   hi_cdf, lo, hi, b, c, d)


@numba.njit(cache=True)
def _sample_net_serial(W, shift, s, r, R, u, cos_phi, sin_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf,
                       hi_cdf, lo, hi, b, c, d):
    """:func:`_sample_net` of one block (r.size <= NET_BLOCK) on the calling thread: the same points, without
    the cost of starting a parallel region, which exceeds the work itself for small nets."""
    _net_block(0, W, shift, s, r, R, u, cos_phi, sin_phi, p_band, nodes, grid, radius, R_m, R_sigma, lo_cdf, hi_cdf,
               lo, hi, b, c, d)


@numba.njit(cache=True)
def _clip_running_max(r, r_band):
    """r = running max of min(r, r_band), in place: round-off in the quantile never breaks the sort."""
    m = 0.0
    for i in range(r.size):
        v = min(r[i], r_band)
        m = max(m, v)
        r[i] = m


def unit_points(n: int, seed, sampler: str) -> np.ndarray:
    """n points of [0, 1)^4 from the chosen sampler (the only random source)."""
    if sampler == "random":
        return np.random.default_rng(seed).random((n, 4))
    return sobol_points(n, seed)


def _check_n(n):
    if isinstance(n, bool) or not isinstance(n, numbers.Integral) or not 1 <= n <= N_MAX:
        raise ValueError(f"n = {n!r} is not a valid sample size (valid range: integer in [1, {N_MAX}])")
    return int(n)


def _check_seed(seed):
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ValueError(f"seed = {seed!r} is not a valid seed (valid range: None or integer >= 0)")
    return int(seed)


@numba.njit(cache=True)
def reach(r, R_min, r_o, k_e, beta, d1, d2, d3, theta_max):
    """(n_active, theta bound): asperities, lowest first, that can touch at Delta (SPEC §3–§4).

    Under policy follow theta = (2/pi) u theta_m(c, R) <= theta_m(c, R_min); ``theta_max``
    [rad] raises the bound for frozen (``birth``) angles.  delta_n = cos(theta)(Delta_1 - r)
    + sin(theta) s with s <= |Delta_shear|, so contact needs r < Delta_1 + |Delta_shear| tan(theta).
    ``r`` is sorted.
    """
    shear = math.hypot(d2, d3)
    closure = max(0.0, r_o + d1)
    y = 1.0 - k_e * closure / R_min
    theta = max(math.acos(min(max(y, 0.0), 1.0)), theta_max)
    if shear == 0.0:
        r_max = d1
    elif theta >= 0.5 * math.pi - 1e-9:
        return r.size, theta
    else:
        r_max = d1 + shear * math.tan(theta)
    r_max += 1e-12 * max(abs(r_max), beta)  # round-off margin at the contact edge
    return np.searchsorted(r, r_max, side="right"), theta


UNIT_TOL = 1e-12  # largest |cos² phi + sin² phi - 1| accepted in a Population


@numba.njit(cache=True)
def _all_valid(r, R, u, cos_phi, sin_phi):
    """True if every asperity keeps the invariants of :func:`_first_invalid`; branch-free (vectorises)."""
    half_pi = 0.5 * math.pi
    ok = True
    prev = 0.0
    for i in range(r.shape[0]):
        ri = r[i]
        c = cos_phi[i]
        s = sin_phi[i]
        ok &= ((ri >= prev) & (ri < math.inf) & (R[i] > 0.0) & (R[i] < math.inf) & (u[i] >= 0.0)
               & (u[i] <= half_pi) & (abs(c * c + s * s - 1.0) <= UNIT_TOL))
        prev = ri
    return ok


@numba.njit(cache=True)
def _first_invalid(r, R, u, cos_phi, sin_phi):
    """(code, i): the first asperity i that breaks an invariant the kernels rely on, code 0 if none.

    Codes: 1 r not finite or < 0; 2 r[i] < r[i-1] (heights must be sorted: the kernels stop at
    the first height out of reach); 3 R not finite or <= 0; 4 u outside [0, pi/2] (or NaN);
    5 cos phi or sin phi not finite, or |cos² + sin² - 1| > UNIT_TOL.
    """
    half_pi = 0.5 * math.pi
    prev = 0.0
    for i in range(r.shape[0]):
        ri = r[i]
        if not (0.0 <= ri < math.inf):
            return 1, i
        if ri < prev:
            return 2, i
        prev = ri
        if not (0.0 < R[i] < math.inf):
            return 3, i
        if not (0.0 <= u[i] <= half_pi):
            return 4, i
        c = cos_phi[i]
        s = sin_phi[i]
        if not abs(c * c + s * s - 1.0) <= UNIT_TOL:
            return 5, i
    return 0, -1


_ARRAYS = ("r", "R", "u", "cos_phi", "sin_phi")


@dataclass(frozen=True, eq=False)
class Population:
    """n sampled asperities as struct-of-arrays, sorted by height r.

    Attributes
    ----------
    params : InterfaceParams
    r : ndarray (n,) [m]        asperity height below the highest summit
    R : ndarray (n,) [m]        relative radius of curvature
    u : ndarray (n,) [rad]      shifted meridional coordinate in [0, pi/2]
    cos_phi, sin_phi : ndarray (n,) [1]  azimuth phi as its cosine and sine
    weight : float [1]          probability weight of each sample: P(r <= r_band) / n (1/n without a band)
    seed, sampler : how it was drawn
    r_band : float [m]          heights were drawn from the gamma density truncated to [0, r_band]
                                (inf: no band); see :meth:`sample` and :mod:`asperity_sim.pruning`
    """

    params: InterfaceParams
    r: np.ndarray
    R: np.ndarray
    u: np.ndarray
    cos_phi: np.ndarray
    sin_phi: np.ndarray
    weight: float
    seed: int | None
    sampler: str
    r_band: float = math.inf

    def __post_init__(self):
        """Check every invariant the kernels rely on (SPEC §2–§3); O(n), one pass, no copies.

        A Population built directly (from a checkpoint, or by hand) with unsorted heights, NaN,
        out-of-range values or arrays of unequal length would make the kernels skip asperities,
        read out of bounds or return garbage; it is refused with a ``ValueError`` naming the array,
        the first bad element and the valid range.
        """
        if not isinstance(self.params, InterfaceParams):
            raise ValueError(f"params = {self.params!r} is not an InterfaceParams")
        n = None
        for name in _ARRAYS:
            a = getattr(self, name)
            if not isinstance(a, np.ndarray):
                raise ValueError(f"Population.{name} is a {type(a).__name__}, not a numpy array "
                                 "(valid: 1-D float64 ndarray)")
            if a.dtype != np.float64 or a.ndim != 1:
                raise ValueError(f"Population.{name} has dtype {a.dtype} and shape {a.shape} "
                                 "(valid: 1-D float64 array)")
            if n is None:
                n = a.shape[0]
                if n < 1:
                    raise ValueError("Population.r is empty (valid range: n >= 1 asperities)")
            elif a.shape[0] != n:
                raise ValueError(f"Population.{name} has length {a.shape[0]}, r has length {n} "
                                 "(valid: all five arrays of equal length)")
        if not _all_valid(self.r, self.R, self.u, self.cos_phi, self.sin_phi):  # the fast pass; then find why
            code, i = _first_invalid(self.r, self.R, self.u, self.cos_phi, self.sin_phi)
            raise ValueError(self._invalid_text(code, i))
        w = self.weight
        if isinstance(w, bool) or not isinstance(w, numbers.Real) or not (0.0 < w < math.inf):
            raise ValueError(f"Population.weight = {w!r} is not valid (valid range: finite and > 0)")
        if self.seed is not None and (isinstance(self.seed, bool) or not isinstance(self.seed, numbers.Integral)
                                      or self.seed < 0):
            raise ValueError(f"Population.seed = {self.seed!r} is not valid (valid range: None or integer >= 0)")
        if not isinstance(self.sampler, str):
            raise ValueError(f"Population.sampler = {self.sampler!r} is not a string")
        rb = self.r_band
        if isinstance(rb, bool) or not isinstance(rb, numbers.Real) or not rb > 0.0:
            raise ValueError(f"Population.r_band = {rb!r} is not valid (valid range: > 0 [m], inf for no band)")

    def _invalid_text(self, code, i):
        if code == 0:  # _all_valid and _first_invalid disagree: cannot happen, but never pass silently
            return "Population arrays failed the validity check (r, R, u, cos_phi, sin_phi)"
        if code == 1:
            return f"Population.r[{i}] = {float(self.r[i])!r} is not valid (valid range: finite and >= 0 [m])"
        if code == 2:
            return (f"Population.r is not sorted: r[{i}] = {float(self.r[i])!r} < r[{i - 1}] = {float(self.r[i - 1])!r} "
                    "(valid: heights sorted non-decreasing [m]; Population.from_arrays sorts them)")
        if code == 3:
            return f"Population.R[{i}] = {float(self.R[i])!r} is not valid (valid range: finite and > 0 [m])"
        if code == 4:
            return f"Population.u[{i}] = {float(self.u[i])!r} is not valid (valid range: [0, pi/2] [rad])"
        c, s = float(self.cos_phi[i]), float(self.sin_phi[i])
        return (f"Population.cos_phi[{i}] = {c!r}, sin_phi[{i}] = {s!r} are not the cosine and sine of one angle "
                f"(valid: finite with |cos² + sin² - 1| <= {UNIT_TOL:g})")

    @classmethod
    def sample(cls, params: InterfaceParams, n: int, seed: int | None = 0, sampler: str = "random",
               r_max: float | None = None) -> "Population":
        """Draw n asperities from SPEC §2–§3; same (params, n, seed, sampler, r_max) gives identical arrays.

        With ``r_max`` [m] (a height band, see :mod:`asperity_sim.pruning`) the heights are drawn
        from the gamma density truncated to [0, r_max] (inverse CDF of the band) and every sample
        carries the weight p / n, p = P(r <= r_max) exactly (regularised incomplete gamma), so
        sigma = N (p / n) sum f is unbiased for Eq. (23) whenever no asperity above r_max touches.
        ``r_max=None`` or inf is the full density (identical arrays to no band).
        """
        if not isinstance(params, InterfaceParams):
            raise ValueError(f"params = {params!r} is not an InterfaceParams")
        n = _check_n(n)
        seed = _check_seed(seed)
        if sampler not in SAMPLERS:
            raise ValueError(f"sampler = {sampler!r} is not known (valid: {', '.join(SAMPLERS)})")
        p_band, r_band = band_probability(params, r_max), math.inf if r_max is None else float(r_max)
        if not p_band > 0.0:
            raise ValueError(f"r_max = {r_max!r} m holds no probability (P(r <= r_max) = {p_band!r}): band too narrow")
        # the height is monotone in its uniform, so sorting the points by it sorts by height.
        # Sobol', n = 2^m: the first coordinate is a (0, m, 1)-net (one point per cell of width
        # 1/n), so the points are generated directly in that order (no sort, no array of uniforms).
        # Otherwise an O(n) counting sort; the sorted uniforms go straight into the output arrays
        # (allocated by numpy, which asks for huge pages) and the inverse CDFs replace them in place.
        radius = params.R_sigma > 0.0
        R_const = _radius_constants(params) if radius else (params.R_m, 0.0, 0.0, 1.0, params.R_m, params.R_m)
        shape = params.alpha + 1.0
        constants = (p_band, *_quantile_table(shape), radius, *R_const, params.b, params.c, params.d)
        if sampler == "sobol" and n & (n - 1) == 0:
            r, R, u, cos_phi, sin_phi = (np.empty(n) for _ in range(5))
            kernel = _sample_net_serial if n <= NET_BLOCK else _sample_net
            kernel(*net_directions(n.bit_length() - 1, seed), r, R, u, cos_phi, sin_phi, *constants)
        else:
            U = unit_points(n, seed, sampler)
            order = _argsort_unit(U[:, 0])  # before the outputs exist: the sort's work arrays are freed
            r, R, u, cos_phi, sin_phi = (np.empty(n) for _ in range(5))
            _gather(U, order, r, R, u, cos_phi)
            del U, order
            _inverse_cdfs(r, R, u, cos_phi, sin_phi, *constants)
        tail = np.signbit(r)  # where no table is accurate: scipy's inverse
        r[tail] = special.gammaincinv(shape, -r[tail])
        r *= params.beta
        _clip_running_max(r, r_band)
        return cls(
            params=params,
            r=r,
            R=R,
            u=u,
            cos_phi=cos_phi,
            sin_phi=sin_phi,
            weight=p_band / n,
            seed=seed,
            sampler=sampler,
            r_band=r_band,
        )

    @classmethod
    def from_arrays(cls, params: InterfaceParams, r, R, u, phi) -> "Population":
        """A population of given asperities (heights r [m], radii R [m], u [rad], phi [rad]), equally weighted."""
        if not isinstance(params, InterfaceParams):
            raise ValueError(f"params = {params!r} is not an InterfaceParams")
        arrays = [np.atleast_1d(np.asarray(a, dtype=float)) for a in (r, R, u, phi)]
        n = arrays[0].size
        if n == 0:
            raise ValueError("r is empty: a population needs at least one asperity (valid range: n >= 1)")
        names = ("r", "R", "u", "phi")
        for name, a in zip(names, arrays):
            if a.shape != (n,) or not np.all(np.isfinite(a)):
                raise ValueError(f"{name} must be a finite 1-D array of length {n}, got {a!r}")
        r, R, u, phi = arrays
        if np.any(r < 0) or np.any(R <= 0) or np.any((u < 0) | (u > 0.5 * math.pi)):
            raise ValueError("need r >= 0 [m], R > 0 [m] and u in [0, pi/2] [rad]")
        order = np.argsort(r, kind="stable")
        return cls(params=params, r=r[order].copy(), R=R[order].copy(), u=u[order].copy(),
                   cos_phi=np.cos(phi[order]), sin_phi=np.sin(phi[order]), weight=1.0 / n,
                   seed=None, sampler="given")

    @property
    def n(self) -> int:
        return self.r.size

    @property
    def phi(self) -> np.ndarray:
        """Azimuth phi [rad] in [0, 2 pi)."""
        phi = np.mod(np.arctan2(self.sin_phi, self.cos_phi), 2.0 * math.pi)
        return np.where(phi >= 2.0 * math.pi, 0.0, phi)  # a tiny negative angle rounds up to 2 pi

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.r, self.R, self.u, self.cos_phi, self.sin_phi))

    @cached_property
    def R_min(self) -> float:
        """Smallest relative radius in the population [m] (largest orientation extent)."""
        return float(self.R.min())

    def n_reachable(self, delta, theta_max: float = 0.0) -> int:
        """Number of asperities, lowest first, that can touch at displacement delta (:func:`reach`).

        ``theta_max`` [rad] raises the angle bound for frozen (``birth``) angles.
        """
        p = self.params
        return int(reach(self.r, self.R_min, p.r_o, p.k_e, p.beta, float(delta[0]), float(delta[1]),
                         float(delta[2]), float(theta_max))[0])

    @cached_property
    def kernel_constants(self) -> tuple:
        """(r_o, k_e, E_star, lam, mu, beta, N w): the scalars every evaluation passes to the kernels."""
        p = self.params
        return p.r_o, p.k_e, p.E_star, p.lam, p.mu, p.beta, p.N * self.weight

    def evaluate(self, delta, law: str = "paper", policy: str = "follow", theta_birth=None):
        """Interface stress, standard error, tangent and contact counts at delta (SPEC §6).

        See :func:`asperity_sim.assemble.evaluate`.
        """
        from .assemble import evaluate

        return evaluate(self, delta, law=law, policy=policy, theta_birth=theta_birth)
