"""Inverse CDFs of the asperity densities (SPEC §2–§3): heights, radii and orientations.

Owns the maps from uniforms in [0, 1) to asperity attributes: gamma heights (tabulated
quantiles with Hermite interpolation, exact tail), the truncated Gaussian relative radius,
the marginal of cos u and the conditional of phi given u (Eq. 10, corrected), and the
probability of a height band.  Deterministic: the random points come from
:mod:`asperity_sim.sampling.draws`.
"""

from __future__ import annotations

import math
import numbers
from functools import lru_cache

import numba
import numpy as np
from scipy import special

from ..jit import kernel
from ..params import InterfaceParams

_EMPTY = np.empty(0)


@kernel(inline="always")
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


@kernel(inline="always")
def cos_u_at(target, b):
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


@kernel(inline="always")
def phi_at(p, xi, b, c, d):
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


@kernel()
def _cos_u_from_uniform(p, b):
    out = np.empty_like(p)
    for i in range(p.size):
        out[i] = cos_u_at(p[i], b)
    return out


@kernel()
def _phi_from_uniform(p, x, b, c, d):
    out = np.empty_like(p)
    for i in range(p.size):
        out[i] = phi_at(p[i], x[i], b, c, d)
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


@kernel(inline="always")
def _ratio7(num, den, t):
    """num(t) / den(t) for two degree-7 polynomials (coefficients lowest degree first), Horner."""
    a = num[7]
    b = den[7]
    for k in range(6, -1, -1):
        a = a * t + num[k]
        b = b * t + den[k]
    return a / b


@kernel(inline="always")
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


@kernel(inline="always")
def radius_at(p, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi):
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
def quantile_table(shape: float):
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


@kernel(inline="always")
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


@kernel()
def _hermite_many(t, nodes, t0, h, cells, out):
    """out = :func:`_hermite_at` of piece 0 at every t (a table check: tens of thousands of points, once per shape)."""
    for i in range(t.size):
        out[i] = _hermite_at(t[i], nodes, 0, t0, h, cells)


@kernel(inline="always")
def gamma_quantile_at(p, nodes, grid):
    """Unit-scale gamma quantile at probability p from the tables of :func:`quantile_table`
    (NaN where no accurate table reaches: the caller uses scipy there)."""
    if p < grid[0]:
        return _hermite_at(p ** grid[9], nodes, 1, grid[3], grid[4], grid[5])
    if p > P_HI:
        return _hermite_at(-math.log1p(-p), nodes, 2, grid[6], grid[7], grid[8])
    return _hermite_at(p, nodes, 0, grid[0], grid[1], grid[2])


@kernel(parallel=True)
def _gamma_quantiles(p, nodes, grid, out):
    """out = :func:`gamma_quantile_at` at every p."""
    for i in numba.prange(p.size):
        out[i] = gamma_quantile_at(p[i], nodes, grid)


def heights_from_uniform(params: InterfaceParams, p):
    """Gamma heights r [m] (shape alpha+1, scale beta) from uniforms, SPEC §2 (inverse CDF)."""
    p = np.ascontiguousarray(p, dtype=float)
    shape = params.alpha + 1.0
    x = np.empty_like(p)
    _gamma_quantiles(p.ravel(), *quantile_table(shape), x.ravel())
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


def radius_constants(params: InterfaceParams):
    """(R_m, R_sigma, Phi(a), Phi(b), lo, hi) of the truncated Gaussian of SPEC §2 [m, m, 1, 1, m, m]."""
    lo, hi = params.R_bounds
    a = (lo - params.R_m) / params.R_sigma
    b = (hi - params.R_m) / params.R_sigma
    return params.R_m, params.R_sigma, float(special.ndtr(a)), float(special.ndtr(b)), lo, hi


@kernel(parallel=True)
def _radii(p, R_m, R_sigma, lo_cdf, hi_cdf, lo, hi, out):
    for i in numba.prange(p.size):
        out[i] = radius_at(p[i], R_m, R_sigma, lo_cdf, hi_cdf, lo, hi)


def radii_from_uniform(params: InterfaceParams, p):
    """Truncated Gaussian relative radii R [m] from uniforms, SPEC §2 (inverse CDF)."""
    p = np.ascontiguousarray(p, dtype=float)
    if params.R_sigma == 0.0:
        return np.full_like(p, params.R_m)
    out = np.empty_like(p)
    _radii(p.ravel(), *radius_constants(params), out.ravel())
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
