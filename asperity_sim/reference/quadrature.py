"""Deterministic reference quadrature of Eq. (23) for the ``paper`` law, policy ``follow``.

Owns the converged references that Monte Carlo is tested against (SPEC §6): the
interface stress ``sigma_i = N E[f_i]`` as a nested quadrature over the radius R, the
orientation (u, phi) and the height r, its finite-difference tangent, the average
orientation extent theta_am of Eq. (29), and independent closed-ish 1-D forms for e = 0.

Quadrature (SPEC §2–§5)
-----------------------
* R: truncated Gaussian (SPEC §2), Gauss–Legendre, split where theta_m(c, R) is clipped
  to pi/2 (R = k_e c, Eq. 9) and where theta_m = arctan(lam mu); pieces spanning more than
  a factor 8 in R are graded geometrically. R_sigma = 0 is a delta at R_m. A support
  starting at R = 0 gets the map R = b t² (sqrt(R) of the Hertz law).
* u in [0, pi/2]: Gauss–Legendre, weight sin u xi(u, phi) (Eq. 10 corrected). With no
  shear, split where tan(theta) = lam mu (there whole asperities turn from stick to slip).
* phi: measured from the shear direction psi, phi = psi + phi'. The projected shear is
  h = S cos phi' and delta_t² = S² - h², so everything that decides the structure of the
  height integral is a polynomial of degree <= 2 in h: the end of contact at r = 0
  (a_n = 0), a stick/slip boundary crossing r = 0 (a0 = 0), a stick zone appearing inside
  the contact (discriminant = 0) and delta_s = 0 at r = 0. Their roots (``_phi_breaks``) cut
  [0, pi] into pieces on which the integrand is smooth; each piece (no longer than
  ``phi_chunk``) gets Gauss–Legendre under the map phi' = a + L (3t² - 2t³), and
  [-pi, 0] reuses the same breaks (phi' -> -phi' only flips delta_t). For an isotropic-in-phi
  density (c = d = 0) the integrand is even in phi' and only [0, pi] is used; with no shear
  the phi integral is exact (sigma_2 = sigma_3 = 0, weight 1 + b P2(cos u)).
  Why: a trapezoid rule over the period (used before issue 24) converges only algebraically
  across these kinks; with mu = 0.3 and large shears it was off by up to 7e-6 relative,
  isotropic or not.
* r (gamma height, SPEC §2): for fixed (R, u, phi) the angle theta does not depend on r,
  so delta_n, delta_s are affine in r and delta_t is constant (SPEC §4). The r-axis is
  split at the end of contact (delta_n = 0), at the stick/slip boundaries (roots of the
  quadratic delta_st² = (lam mu delta_n)²) and where delta_s = 0 inside a stick zone.
  The piece starting at r = 0 uses a Gauss–Jacobi rule with weight t^alpha and the map
  r = p t (2 - t); the other pieces use Gauss–Legendre with the map r = a + (b-a)(3t² - 2t³).
  Both maps make the (.)^(3/2) end-point behaviour of the law analytic. The height axis is
  cut at r_max, where the gamma upper tail is 1e-17, and pieces longer than ``chunk`` beta
  are cut into equal chunks.

Accuracy and cost
-----------------
Measured against ``level="ultra", refine=1.5`` on the Table 1 sets at the paper's
displacements (R1 at (5|15, 0, 0), (15, 3, 1), (15, 15, 0), (15, 15, 15), (10, -4, 6) um;
S1 at (6, 0, 0), (6, 6, 0), (6, 6, 6), (3, 1, 2) um; R2, S2 at Delta_1 = 0.05, 0.1, 0.2 mm;
R2 at (0.1, 0.05, 0.02) mm; R1 with (b, c, d) = (0.8, 0.1, -0.05), R1 with e = 0.3, and R1
with (b, c, d, e, r_o, mu) = (0.5, 0.1, -0.05, 0.3, 2 um, 0.3), all at (15, 3, 1) um),
error = max_i |sigma_i - sigma_i^ref| / max_i |sigma_i^ref|:

=========  ===========
level      worst error
=========  ===========
fast       3.0e-06
default    3.8e-10
fine       4.4e-11
ultra      6.1e-13
=========  ===========

Over the parameter box (``benchmarks/reference_accuracy.py``: random valid b, c, d, e, r_o,
mu, R_sigma, alpha, beta around the four presets, Delta_1 of 0.5 to 2 mean heights, shears up
to Delta_1), default against ultra: worst 3.6e-8 over 30 sets with mu = 0.3 (seed 4; 90 %
below 1.2e-10) and 5.1e-9 over 30 sets with mu in [0.05, 1.5] (seed 5).  The trapezoid rule
in phi it replaced reached 7e-6 on such sets.  Time per default call (single thread, numba
compiled, 2-core machine shared with other jobs, so +-30 %): see ``stress``.

Robustness (default vs refined, same measure): alpha = -0.99 ... 20, R_sigma = 0, a
support reaching R = 0, clipped theta_m (R1 at Delta_1 = 40 um), mu = 0 and mu = 0.05,
anisotropic densities at the edge of non-negativity: all below 3e-7 (tests/test_reference.py).
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from scipy import special

from .. import geometry
from ..params import InterfaceParams
from .integrand import stress_kernel
from .rules import check_params, gauss_jacobi01, gauss_legendre01, radius_rule

# Node counts per accuracy level: (n_R, n_u, n_phi, n_r, chunk, phi_chunk) where n_R is the number
# of Gauss–Legendre nodes over the whole R support (shared between the pieces in proportion to
# their length), n_u the Gauss–Legendre nodes in u, n_phi the Gauss–Legendre nodes per piece of
# the azimuth phi' in [0, pi] (pieces cut where the height integral changes structure, see
# _phi_breaks, and no longer than phi_chunk [rad]), n_r the nodes per height piece and chunk the
# longest height piece in units of beta.
LEVELS = {
    "fast": (12, 12, 8, 10, 8.0, 1.6),
    "default": (24, 16, 12, 20, 8.0, 1.6),
    "fine": (32, 32, 24, 24, 6.0, 1.0),
    "ultra": (48, 48, 40, 32, 4.0, 0.8),
}


def _check_delta(delta):
    try:
        arr = np.asarray(delta, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"delta = {delta!r} is not an array of 3 real numbers [m]") from None
    if arr.shape != (3,):
        raise ValueError(f"delta = {delta!r} must have shape (3,) [m], got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"delta = {delta!r} must be finite [m]")
    return arr


def _settings(level, refine):
    if level not in LEVELS:
        raise ValueError(f"level = {level!r} is not one of {sorted(LEVELS)}")
    if not (isinstance(refine, numbers.Real) and math.isfinite(refine) and refine > 0):
        raise ValueError(f"refine = {refine!r} must be a finite number > 0")
    n_R, n_u, n_phi, n_r, chunk, phi_chunk = LEVELS[level]
    sc = lambda k: max(2, int(math.ceil(k * refine)))  # noqa: E731
    return sc(n_R), sc(n_u), sc(n_phi), sc(n_r), chunk / max(refine, 1.0), phi_chunk / max(refine, 1.0)


# --------------------------------------------------------------------------------------
# public API
# --------------------------------------------------------------------------------------


def stress(params: InterfaceParams, delta, *, level: str = "default", refine: float = 1.0,
           symmetry: bool = True) -> np.ndarray:
    """Interface stress sigma_i = N E[f_i] of Eq. (23), ``paper`` law, policy ``follow``.

    Parameters
    ----------
    params : InterfaceParams
    delta : array_like (3,) [m]
        Interface displacement (Delta_1 closure positive, Delta_2, Delta_3 shear), SPEC §4.
    level : {"fast", "default", "fine", "ultra"}
        Node counts (``LEVELS``). "default" reaches 4e-10 relative accuracy on the Table 1
        sets at the paper's displacements and better than 1e-7 (worst measured 3.6e-8) over
        sampled anisotropic sets (b, c, d, e != 0, r_o > 0, mu = 0.3). Time per call for R1 at (15, 3, 1) um:
        ~26-37 ms (the trapezoid rule it replaced: ~18-25 ms, measured interleaved on the
        same loaded 2-core machine); at zero shear ~0.6 ms (unchanged). See the module docstring.
    refine : float
        Multiplies every node count (and divides the height chunk length) of ``level``;
        used to show convergence under refinement.
    symmetry : bool
        Exploit exact symmetries (no shear: phi integral in closed form; c = d = 0: rotate
        the shear onto axis 2 and integrate phi over [0, pi]). ``False`` always integrates
        phi over the full period (a check of the symmetry reduction).

    Returns
    -------
    sigma : ndarray (3,) [Pa]
        sigma_1 > 0 is compression (SPEC §6).
    """
    check_params(params)
    d = _check_delta(delta)
    n_R, n_u, n_phi, n_r, chunk, phi_chunk = _settings(level, refine)
    p = params
    closure = float(geometry.closure(p, d[0]))
    shear = math.hypot(d[1], d[2])
    b, c, dd = p.b, p.c, p.d
    if symmetry and shear == 0.0:
        mode = 0
        c = dd = 0.0  # integrate to zero over phi (cos 2 phi, sin 2 phi)
    elif symmetry and c == 0.0 and dd == 0.0:
        mode = 1  # even in phi' = phi - psi
    else:
        mode = 2
    c_psi, s_psi = (d[1] / shear, d[2] / shear) if shear > 0.0 else (1.0, 0.0)
    R_x, R_w = radius_rule(p, closure, n_R)
    tu, wu = gauss_legendre01(n_u)
    tp, wp = gauss_legendre01(n_phi)
    tj, wj = gauss_jacobi01(n_r, p.alpha)
    tg, wg = gauss_legendre01(n_r)
    log_norm = special.gammaln(p.alpha + 1.0) + (p.alpha + 1.0) * math.log(p.beta)
    r_max = p.beta * float(special.gammainccinv(p.alpha + 1.0, 1e-17))
    out = np.empty(3)
    k_psi = (1.0, 0.0) if mode == 1 else (c_psi, s_psi)  # mode 1: shear rotated onto axis 2
    stress_kernel(float(d[0]), shear, k_psi[0], k_psi[1], mode, closure, p.k_e, p.E_star, p.lam,
                   p.mu, p.alpha, p.beta, log_norm, r_max, chunk, R_x, R_w, tu, wu,
                   shear == 0.0, tp, wp, phi_chunk, b, c, dd, tj, wj, tg, wg, out)
    out *= p.N
    if mode == 0:
        out[1] = out[2] = 0.0
    elif mode == 1:
        out[1], out[2] = c_psi * out[1], s_psi * out[1]  # sigma_3' = 0 by symmetry
    return out


def _fd_step(params, step):
    if step is None:
        return 1e-3 * params.beta
    if not (isinstance(step, numbers.Real) and math.isfinite(step) and step > 0):
        raise ValueError(f"step = {step!r} must be a finite length > 0 [m]")
    return float(step)


def stress_and_tangent(params: InterfaceParams, delta, *, step: float | None = None, **kw):
    """(sigma [Pa], T [Pa/m]) with T_ik = d sigma_i / d Delta_k (SPEC §6).

    Central finite differences of :func:`stress` with step ``step`` [m] (default
    1e-3 beta): truncation error ~ (step/beta)² ~ 1e-6 relative; the quadrature error of
    ``stress`` (~1e-9 relative, not smooth in delta where node counts change) divided by
    step/beta adds ~1e-6. Measured against step/10 at refine 2: 1e-7 (R1, (15, 3, 1) um)
    to 6e-6 (R1, (15, 0, 0) um) relative to max |T|. Under policy ``follow`` this includes
    the change of theta with Delta_1 through theta_m(c, R) (SPEC §6).
    Where a shear component Delta_k (k = 2, 3) is exactly 0, the Mindlin law makes sigma
    contain a |Delta_k| Delta_k term, so the central difference has an O(step) error; that
    column is Richardson-extrapolated from steps h and h/2 (2 D(h/2) - D(h)).
    Near c = 0 (Delta_1 = -r_o) theta_m has an infinite slope and T is only an estimate.
    ``kw`` is passed to :func:`stress`.

    Parameters
    ----------
    params : InterfaceParams
    delta : array_like (3,) [m]
    step : float [m], optional
    """
    d = _check_delta(delta)
    h = _fd_step(params, step)
    sig = stress(params, d, **kw)

    def column(k, hk):
        e = np.zeros(3)
        e[k] = hk
        return (stress(params, d + e, **kw) - stress(params, d - e, **kw)) / (2.0 * hk)

    T = np.empty((3, 3))
    for k in range(3):
        T[:, k] = column(k, h)
        if k > 0 and d[k] == 0.0:
            T[:, k] = 2.0 * column(k, 0.5 * h) - T[:, k]
    return sig, T


def tangent(params: InterfaceParams, delta, *, step: float | None = None, **kw) -> np.ndarray:
    """T_ik = d sigma_i / d Delta_k [Pa/m] (3, 3); see :func:`stress_and_tangent`."""
    return stress_and_tangent(params, delta, step=step, **kw)[1]
