"""Quadrature rules over the densities of the model, and the average orientation extent theta_am.

Owns the Gauss rules of the reference quadrature: the radius rule over the truncated
Gaussian (split where theta_m is clipped and where theta_m = arctan(lam mu), graded
geometrically), the orientation density (Eq. 10, corrected) and its rule in (u, phi), and
theta_am of Eq. (29), recorded at every step of a run.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import special

from ..geometry import HALF_PI
from ..params import InterfaceParams


def check_params(params):
    if not isinstance(params, InterfaceParams):
        raise ValueError(f"params = {params!r} is not an InterfaceParams")


_GRADE = 8.0  # largest ratio b/a of a radius piece [a, b] with a > 0 (see radius_rule)


# --------------------------------------------------------------------------------------
# quadrature rules (Python side, cached)
# --------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=64)
def gauss_legendre01(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


@functools.lru_cache(maxsize=64)
def gauss_jacobi01(n, alpha):
    """Nodes and weights on [0, 1] for the weight t^alpha (alpha > -1)."""
    x, w = special.roots_jacobi(n, 0.0, alpha)
    return 0.5 * (x + 1.0), w * 0.5 ** (alpha + 1.0)


def radius_rule(params: InterfaceParams, closure: float = 0.0, n: int = 20, slip_cut: bool = True):
    """Nodes R [m] and weights (summing to 1) for E[.] over the truncated Gaussian (SPEC §2).

    Split at R = k_e c, where theta_m(c, R) of Eq. (9) is clipped to pi/2, and (``slip_cut``,
    for forces) where theta_m = arctan(lam mu) (beyond it, at zero shear, whole asperities slip); pieces
    [a, b] with a > 0 and b > 8 a are graded geometrically (theta_m ~ sqrt(2 k_e c / R)).
    A support starting at R = 0 uses the map R = b t² on its first piece (sqrt(R) of the
    Hertz law). Built in the standard variable z = (R - R_m)/R_sigma, so that very narrow
    Gaussians lose no accuracy. ``R_sigma = 0`` gives the single node R_m with weight 1.
    """
    if params.R_sigma == 0.0:
        return np.array([params.R_m]), np.array([1.0])
    R_m, sd = params.R_m, params.R_sigma
    lo, hi = params.R_bounds
    kc = params.k_e * closure
    cuts = [lo, hi]
    m = params.lam * params.mu
    for R_cut in (kc, kc / (1.0 - 1.0 / math.sqrt(1.0 + m * m)) if m > 0 and slip_cut else 0.0):
        if lo < R_cut < hi:
            cuts.append(R_cut)
    cuts.sort()
    graded = [cuts[0]]
    for a, b in zip(cuts[:-1], cuts[1:]):
        x = a * _GRADE
        while 0.0 < a and x < b / 1.5:
            graded.append(x)
            x *= _GRADE
        graded.append(b)
    z_cuts = [(R - R_m) / sd for R in graded]
    z_cuts[0] = max(-3.0, -R_m / sd)
    z_cuts[-1] = 3.0
    Z = special.ndtr(3.0) - special.ndtr(z_cuts[0])
    zs, ws = [], []
    for k, (a, b) in enumerate(zip(z_cuts[:-1], z_cuts[1:])):
        m = max((n + 1) // 2, int(math.ceil(n * (b - a) / (z_cuts[-1] - z_cuts[0]))))
        t, w = gauss_legendre01(m)
        if k == 0 and lo == 0.0:
            z = a + (b - a) * t * t
            w = w * (b - a) * 2.0 * t
        else:
            z = a + (b - a) * t
            w = w * (b - a)
        zs.append(z)
        ws.append(w * np.exp(-0.5 * z * z) / (math.sqrt(2.0 * math.pi) * Z))
    z = np.concatenate(zs)
    R = R_m + sd * z
    if lo == 0.0:
        R = np.maximum(R, 1e-12 * R_m)  # never R = 0 (1/R in Eq. 9)
    return R, np.concatenate(ws)


def orientation_density(params: InterfaceParams, u, phi):
    """xi(u, phi) of Eq. (10) (SPEC §3, corrected) w.r.t. sin u du dphi [1/sr]."""
    u = np.asarray(u, dtype=float)
    phi = np.asarray(phi, dtype=float)
    cu = np.cos(u)
    p2 = 0.5 * (3.0 * cu * cu - 1.0)
    return (1.0 + params.b * p2
            + 3.0 * np.sin(u) ** 2 * (params.c * np.cos(2 * phi) + params.d * np.sin(2 * phi))
            ) / (2.0 * math.pi)


def orientation_rule(n_u: int, n_phi: int, half: bool = False):
    """(u, w_u, phi, w_phi): rules for the orientation integral of Eq. (23).

    u [rad] on [0, pi/2] by Gauss–Legendre, ``w_u`` including sin u; phi [rad] by the
    trapezoid rule on [0, 2 pi) or, with ``half``, on [0, pi] for an integrand even in phi;
    ``w_phi`` sums to 1 (a mean over phi), so sum_ij w_u[i] w_phi[j] 2 pi xi(u_i, phi_j) ~ 1,
    Eq. (11). ``n_phi <= 1`` gives the single node phi = 0.
    """
    t, w = gauss_legendre01(n_u)
    u = HALF_PI * t
    w_u = HALF_PI * w * np.sin(u)
    if n_phi <= 1:
        return u, w_u, np.zeros(1), np.ones(1)
    if half:
        m = max(2, n_phi // 2)
        phi = np.linspace(0.0, math.pi, m + 1)
        w_phi = np.full(m + 1, 1.0 / m)
        w_phi[0] *= 0.5
        w_phi[-1] *= 0.5
    else:
        phi = 2.0 * math.pi * np.arange(n_phi) / n_phi
        w_phi = np.full(n_phi, 1.0 / n_phi)
    return u, w_u, phi, w_phi


@functools.lru_cache(maxsize=64)
def _theta_rule(params: InterfaceParams, n: int):
    """:func:`radius_rule` without cuts, for theta_am at closures with k_e c outside the support."""
    R, w = radius_rule(params, 0.0, n, slip_cut=False)
    R.flags.writeable = w.flags.writeable = False  # shared by every caller
    return R, w


def theta_am(params: InterfaceParams, closure, n: int = 48):
    """Average orientation extent theta_am(c) [rad], Eq. (29) (SPEC §3).

    Integral of theta_m(c, R) p(R) dR over the truncated Gaussian, by Gauss–Legendre split
    at R = k_e c (the rule without a split is built once per parameter set). ``closure`` [m] is c itself (the caller adds r_o); scalar or array.
    """
    check_params(params)
    if isinstance(closure, float):  # the common scalar call, without the array machinery
        if not (math.isfinite(closure) and closure >= 0.0):
            raise ValueError(f"closure = {closure!r} must be finite and >= 0 [m]")
        return _theta_am_at(params, closure, n)
    c_arr = np.asarray(closure, dtype=float)
    if not np.all(np.isfinite(c_arr)) or np.any(c_arr < 0):
        raise ValueError(f"closure = {closure!r} must be finite and >= 0 [m]")
    res = np.array([_theta_am_at(params, float(c), n) for c in c_arr.ravel()])
    return res.reshape(c_arr.shape) if c_arr.ndim else float(res[0])


def _theta_am_at(params, c, n):
    lo, hi = params.R_bounds
    kc = params.k_e * c
    # theta_m(c, R) has its only kink at R = k_e c; elsewhere the rule does not depend on c
    R, w = radius_rule(params, c, n, slip_cut=False) if lo < kc < hi else _theta_rule(params, n)
    y = 1.0 - kc / R
    np.clip(y, 0.0, 1.0, out=y)
    return float(np.dot(w, np.arccos(y, out=y)))
