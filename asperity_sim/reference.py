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

import functools
import math
import numbers

import numba
import numpy as np
from scipy import special

from .geometry import theta_m_and_slope
from .laws.paper import paper_local
from .params import InterfaceParams

__all__ = [
    "LEVELS",
    "stress",
    "tangent",
    "stress_and_tangent",
    "theta_am",
    "orientation_density",
    "radius_rule",
    "orientation_rule",
    "mean_sqrt_R",
    "sigma_gw",
    "sigma_1_gw",
]

HALF_PI = 0.5 * math.pi
_GRADE = 8.0  # largest ratio b/a of a radius piece [a, b] with a > 0 (see radius_rule)

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


# --------------------------------------------------------------------------------------
# numba kernels
# --------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _height_integral(a_n, a_s, d_t, ct, st, sqrt_R, E_star, lam, mu, alpha, beta, log_norm,
                     r_max, chunk, tj, wj, tg, wg, brk):
    """Integral over r of H(r) (f_n, f_s, f_t) for one orientation (SPEC §2, §4, §5).

    delta_n = a_n - ct r, delta_s = a_s + st r, delta_t = d_t.  ``log_norm`` is
    lgamma(alpha+1) + (alpha+1) log(beta).  ``tj, wj``: Gauss–Jacobi rule on [0, 1] with
    weight t^alpha; ``tg, wg``: Gauss–Legendre rule on [0, 1]; ``brk``: scratch (>= 8).
    """
    i_n = 0.0
    i_s = 0.0
    i_t = 0.0
    if ct <= 0.0:
        return i_n, i_s, i_t
    r_c = a_n / ct  # end of contact, delta_n(r_c) = 0
    if r_c <= 0.0:
        return i_n, i_s, i_t
    r_hi = min(r_c, r_max)
    nb = 0
    brk[nb] = 0.0
    nb += 1
    m = lam * mu
    if m > 0.0:
        # stick/slip boundaries: g(r) = delta_s² + delta_t² - m² delta_n² = 0
        a2 = st * st - m * m * ct * ct
        a1 = 2.0 * (a_s * st + m * m * a_n * ct)
        a0 = a_s * a_s + d_t * d_t - m * m * a_n * a_n
        disc = a1 * a1 - 4.0 * a2 * a0
        if disc >= 0.0:
            sq = math.sqrt(disc)
            q = -0.5 * (a1 + sq) if a1 >= 0.0 else -0.5 * (a1 - sq)
            if q != 0.0:
                x = a0 / q
                if 0.0 < x < r_hi:
                    brk[nb] = x
                    nb += 1
                if a2 != 0.0:
                    x = q / a2
                    if 0.0 < x < r_hi:
                        brk[nb] = x
                        nb += 1
        elif a2 != 0.0 and disc > -1e-24 * a1 * a1:
            x = -a1 / (2.0 * a2)  # (near) tangency
            if 0.0 < x < r_hi:
                brk[nb] = x
                nb += 1
        # delta_s = 0 inside a stick zone: delta_st = |delta_s| there if delta_t = 0
        if st > 0.0:
            x = -a_s / st
            if 0.0 < x < r_hi and abs(d_t) < m * (a_n - ct * x):
                brk[nb] = x
                nb += 1
    brk[nb] = r_hi
    nb += 1
    # sort (insertion, tiny)
    for i in range(1, nb):
        v = brk[i]
        j = i - 1
        while j >= 0 and brk[j] > v:
            brk[j + 1] = brk[j]
            j -= 1
        brk[j + 1] = v
    L = chunk * beta
    for k in range(nb - 1):
        a = brk[k]
        b = brk[k + 1]
        if b <= a:
            continue
        npc = int(math.ceil((b - a) / L))
        if npc < 1:
            npc = 1
        h = (b - a) / npc
        for p in range(npc):
            lo = a + p * h
            hi = lo + h
            if k == 0 and p == 0:
                # Gauss–Jacobi t^alpha, r = hi t (2 - t): H(r) dr = t^alpha * rest dt
                pref = math.exp((alpha + 1.0) * math.log(hi) - log_norm)
                for q in range(tj.shape[0]):
                    t = tj[q]
                    r = hi * t * (2.0 - t)
                    dn = a_n - ct * r
                    if dn <= 0.0:
                        continue
                    w = wj[q] * pref * (2.0 - t) ** alpha * 2.0 * (1.0 - t) * math.exp(-r / beta)
                    f_n, f_s, f_t, _, _, _, _, _ = paper_local(dn, a_s + st * r, d_t, sqrt_R,
                                                               E_star, lam, mu)
                    i_n += w * f_n
                    i_s += w * f_s
                    i_t += w * f_t
            else:
                for q in range(tg.shape[0]):
                    t = tg[q]
                    r = lo + h * t * t * (3.0 - 2.0 * t)
                    dn = a_n - ct * r
                    if dn <= 0.0:
                        continue
                    w = wg[q] * h * 6.0 * t * (1.0 - t) * math.exp(
                        alpha * math.log(r) - r / beta - log_norm)
                    f_n, f_s, f_t, _, _, _, _, _ = paper_local(dn, a_s + st * r, d_t, sqrt_R,
                                                               E_star, lam, mu)
                    i_n += w * f_n
                    i_s += w * f_s
                    i_t += w * f_t
    return i_n, i_s, i_t


@numba.njit(cache=True)
def _add_roots(c2, c1, c0, lim, out, nb):
    """Append the real roots h of c2 h² + c1 h + c0 = 0 with |h| < lim to ``out[nb:]``."""
    if c2 == 0.0:
        if c1 != 0.0:
            h = -c0 / c1
            if -lim < h < lim:
                out[nb] = h
                nb += 1
        return nb
    disc = c1 * c1 - 4.0 * c2 * c0
    if disc < 0.0:
        return nb
    sq = math.sqrt(disc)
    q = -0.5 * (c1 + sq) if c1 >= 0.0 else -0.5 * (c1 - sq)
    if q != 0.0:
        for h in (c0 / q, q / c2):
            if -lim < h < lim:
                out[nb] = h
                nb += 1
    elif c0 == 0.0:  # c1 = 0 and c0 = 0: double root at 0
        out[nb] = 0.0
        nb += 1
    return nb


@numba.njit(cache=True)
def _phi_breaks(d1, S, ct, st, m, out):
    """Angles phi' in (0, pi) from the shear direction where the height integral is not smooth.

    With phi' = phi - psi (psi the direction of the shear (Delta_2, Delta_3), magnitude S)
    the projected shear is h = S cos phi' and delta_t² = S² - h², so every quantity that
    decides the structure of the height integral (SPEC §4–§5) is a polynomial of degree <= 2
    in h: the end of contact at r = 0 (a_n = 0), a stick/slip boundary crossing r = 0
    (a0 = 0, the constant term of the quadratic in ``_height_integral``), a stick zone
    appearing inside the contact (discriminant = 0) and delta_s = 0 crossing r = 0. Their
    roots in (-S, S) give phi' = arccos(h/S); the integrand is analytic between them and
    even in (phi' -> -phi') up to the sign of delta_t, so the same breaks serve [-pi, 0].
    Returns the number of breaks written (sorted) to ``out`` (>= 8).
    """
    nb = 0
    if S <= 0.0:
        return 0
    n0 = ct * d1  # a_n = n0 + st h
    s0 = -st * d1  # a_s = s0 + ct h
    if st != 0.0:
        h = -n0 / st
        if -S < h < S:
            out[nb] = h
            nb += 1
    if m > 0.0:
        m2 = m * m
        c0 = s0 * s0 + S * S - m2 * n0 * n0
        c1 = 2.0 * (s0 * ct - m2 * n0 * st)
        c2 = ct * ct - 1.0 - m2 * st * st
        nb = _add_roots(c2, c1, c0, S, out, nb)
        a2 = st * st - m2 * ct * ct
        A0 = s0 * st + m2 * n0 * ct
        A1 = ct * st + m2 * st * ct
        nb = _add_roots(A1 * A1 - a2 * c2, 2.0 * A0 * A1 - a2 * c1, A0 * A0 - a2 * c0, S, out, nb)
        if ct != 0.0:
            h = -s0 / ct
            if -S < h < S:
                out[nb] = h
                nb += 1
    for i in range(nb):
        out[i] = math.acos(min(1.0, max(-1.0, out[i] / S)))
    for i in range(1, nb):  # insertion sort, tiny
        v = out[i]
        j = i - 1
        while j >= 0 and out[j] > v:
            out[j + 1] = out[j]
            j -= 1
        out[j + 1] = v
    return nb


@numba.njit(cache=True)
def _stress_kernel(d1, S, c_psi, s_psi, mode, closure, k_e, E_star, lam, mu, alpha, beta,
                   log_norm, r_max, chunk, R_x, R_w, tu, wu, split_u, tp, wp, phi_chunk, b, c,
                   d, tj, wj, tg, wg, out):
    """sigma / N = E[f] (SPEC §6) by tensor quadrature; R weights normalised.

    The shear (Delta_2, Delta_3) = S (cos psi, sin psi). ``tu, wu``: Gauss–Legendre rule on
    [0, 1] mapped onto u in [0, pi/2] (or, with ``split_u``, onto [0, u*] and [u*, pi/2]
    where tan(theta) = lam mu: for zero shear the whole asperity changes from stick to slip
    there). The weight sin u and 2 pi xi(u, phi) of Eq. (10) are applied here.
    phi = psi + phi': ``mode`` 0 is the single node phi = 0 with weight 1 (zero shear, c, d
    integrated out by the caller); otherwise [0, pi] in phi' is cut at the breaks of
    :func:`_phi_breaks`, pieces longer than ``phi_chunk`` [rad] into equal parts, and each
    part gets the Gauss–Legendre rule ``tp, wp`` under the map
    phi' = lo + L (3 t² - 2 t³) (end-point kinks of the integrand become smooth); mode 1
    (integrand even in phi': c = d = 0) uses [0, pi] only, mode 2 adds phi' -> -phi'.
    ``out`` (3,).
    """
    brk = np.empty(8)
    pb = np.empty(8)
    upts = np.empty(3)
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    m = lam * mu
    th_slip = math.atan(m)
    n_side = 1 if mode == 1 else 2
    for iR in range(R_x.shape[0]):
        R = R_x[iR]
        th_m, _ = theta_m_and_slope(closure, 1.0 / R, k_e)
        sqrt_R = math.sqrt(R)
        upts[0] = 0.0
        npts = 1
        if split_u and 0.0 < th_slip < th_m:
            upts[npts] = HALF_PI * th_slip / th_m
            npts += 1
        upts[npts] = HALF_PI
        npts += 1
        for iu in range((npts - 1) * tu.shape[0]):
            piece = iu // tu.shape[0]
            jq = iu - piece * tu.shape[0]
            ulen = upts[piece + 1] - upts[piece]
            u = upts[piece] + ulen * tu[jq]
            th = u * th_m / HALF_PI
            ct = math.cos(th)
            st = math.sin(th)
            cu = math.cos(u)
            su2 = 1.0 - cu * cu
            iso = 1.0 + b * 0.5 * (3.0 * cu * cu - 1.0)
            wru = R_w[iR] * wu[jq] * ulen * math.sin(u)
            if mode == 0:
                nbk = 0  # one piece with the one node phi = 0
            else:
                nbk = _phi_breaks(d1, S, ct, st, m, pb)
            for k in range(nbk + 1):
                a = 0.0 if k == 0 else pb[k - 1]
                L = (math.pi if k == nbk else pb[k]) - a
                if mode != 0 and L <= 0.0:
                    continue
                npc = 1 if mode == 0 else max(1, int(math.ceil(L / phi_chunk)))
                L /= npc
                nq = 1 if mode == 0 else tp.shape[0]
                for iq in range(nq * npc):
                    lo = a + (iq // nq) * L
                    q = iq % nq
                    if mode == 0:
                        php = 0.0
                        wq = 1.0
                    else:
                        t = tp[q]
                        php = lo + L * t * t * (3.0 - 2.0 * t)
                        wq = wp[q] * L * 6.0 * t * (1.0 - t) / (n_side * math.pi)
                    for side in range(n_side if mode != 0 else 1):
                        pp = php if side == 0 else -php
                        cpp = math.cos(pp)
                        spp = math.sin(pp)
                        cp = c_psi * cpp - s_psi * spp  # phi = psi + phi'
                        sp = s_psi * cpp + c_psi * spp
                        xi = iso + 3.0 * su2 * (c * (cp * cp - sp * sp) + d * 2.0 * sp * cp)
                        w = wru * wq * xi
                        if w == 0.0:
                            continue
                        h = S * cpp
                        a_n = ct * d1 + st * h
                        a_s = -st * d1 + ct * h
                        d_t = -S * spp
                        i_n, i_s, i_t = _height_integral(a_n, a_s, d_t, ct, st, sqrt_R, E_star,
                                                         lam, mu, alpha, beta, log_norm, r_max,
                                                         chunk, tj, wj, tg, wg, brk)
                        s1 += w * (ct * i_n - st * i_s)
                        s2 += w * (st * cp * i_n + ct * cp * i_s - sp * i_t)
                        s3 += w * (st * sp * i_n + ct * sp * i_s + cp * i_t)
    out[0] = s1
    out[1] = s2
    out[2] = s3


# --------------------------------------------------------------------------------------
# quadrature rules (Python side, cached)
# --------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=64)
def _gauss_legendre01(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


@functools.lru_cache(maxsize=64)
def _gauss_jacobi01(n, alpha):
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
        t, w = _gauss_legendre01(m)
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
    t, w = _gauss_legendre01(n_u)
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


def _check_params(params):
    if not isinstance(params, InterfaceParams):
        raise ValueError(f"params = {params!r} is not an InterfaceParams")


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
    _check_params(params)
    d = _check_delta(delta)
    n_R, n_u, n_phi, n_r, chunk, phi_chunk = _settings(level, refine)
    p = params
    closure = max(0.0, p.r_o + d[0])
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
    tu, wu = _gauss_legendre01(n_u)
    tp, wp = _gauss_legendre01(n_phi)
    tj, wj = _gauss_jacobi01(n_r, p.alpha)
    tg, wg = _gauss_legendre01(n_r)
    log_norm = special.gammaln(p.alpha + 1.0) + (p.alpha + 1.0) * math.log(p.beta)
    r_max = p.beta * float(special.gammainccinv(p.alpha + 1.0, 1e-17))
    out = np.empty(3)
    k_psi = (1.0, 0.0) if mode == 1 else (c_psi, s_psi)  # mode 1: shear rotated onto axis 2
    _stress_kernel(float(d[0]), shear, k_psi[0], k_psi[1], mode, closure, p.k_e, p.E_star, p.lam,
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
    _check_params(params)
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


def mean_sqrt_R(params: InterfaceParams) -> float:
    """E[sqrt(R)] [m^0.5] over the truncated Gaussian of SPEC §2 (scipy quad)."""
    if params.R_sigma == 0.0:
        return math.sqrt(params.R_m)
    lo, hi = params.R_bounds
    s = params.R_sigma
    Z = special.ndtr((hi - params.R_m) / s) - special.ndtr((lo - params.R_m) / s)
    norm = math.sqrt(2.0 * math.pi) * s * Z

    def integrand(R):
        return math.sqrt(R) * math.exp(-0.5 * ((R - params.R_m) / s) ** 2) / norm

    from scipy import integrate  # here, not at module level: ~0.2 s of every start-up

    return integrate.quad(integrand, lo, hi, epsabs=0.0, epsrel=1e-13, limit=200)[0]


def sigma_gw(params: InterfaceParams, delta_1: float, shear: float = 0.0):
    """(sigma_1, sigma_shear) [Pa] for e = 0 (flat on rough), by scipy quad; independent check.

    With e = 0, k_e = 0 and every contact has theta = 0 (Eq. 9), so Eq. (23) reduces to
    1-D integrals over the gamma heights (SPEC §2, §5):
    sigma_1 = N (4/3) E* E[sqrt R] int_0^Delta_1 (Delta_1 - r)^(3/2) H(r) dr, and the shear
    stress along a shear displacement of magnitude ``shear`` [m] is
    N mu (4/3) E* E[sqrt R] int_0^Delta_1 (Delta_1 - r)^(3/2) g(x) H(r) dr,
    x = shear / (lam mu (Delta_1 - r)), g = 1 - (1-x)^(3/2) for x < 1, else 1.
    ``params.e`` is ignored: the result is the model's stress for ``params.replace(e=0)``
    (for any e it is the theta = 0 approximation; it ignores the orientation density too).

    Parameters
    ----------
    delta_1 : float [m]   normal displacement Delta_1
    shear : float [m]     magnitude of (Delta_2, Delta_3)
    """
    delta_1 = float(delta_1)
    shear = abs(float(shear))
    if not (math.isfinite(delta_1) and math.isfinite(shear)):
        raise ValueError(f"delta_1 = {delta_1!r}, shear = {shear!r} must be finite [m]")
    p = params
    if delta_1 <= 0.0:
        return 0.0, 0.0
    a = p.alpha
    # H(r) dr with r = delta_1 s: s^alpha (quad's 'alg' weight) times the rest
    scale = math.exp((a + 1.0) * math.log(delta_1) - special.gammaln(a + 1.0)
                     - (a + 1.0) * math.log(p.beta))
    C = p.N * (4.0 / 3.0) * p.E_star * mean_sqrt_R(p) * scale
    opts = dict(epsabs=0.0, epsrel=1e-13, limit=200)
    from scipy import integrate  # here, not at module level: ~0.2 s of every start-up

    def f_n(s):
        return (delta_1 * (1.0 - s)) ** 1.5 * math.exp(-delta_1 * s / p.beta)

    s1, _ = integrate.quad(f_n, 0.0, 1.0, weight="alg", wvar=(a, 0.0), **opts)
    if shear == 0.0 or p.mu == 0.0:
        return C * s1, 0.0
    m = p.lam * p.mu

    def f_t(s):
        dn = delta_1 * (1.0 - s)
        x = shear / (m * dn) if dn > 0.0 else math.inf
        g = 1.0 - (1.0 - x) ** 1.5 if x < 1.0 else 1.0
        return p.mu * dn ** 1.5 * g * math.exp(-delta_1 * s / p.beta)

    s_slip = 1.0 - shear / (m * delta_1)  # x = 1 here; stick for s < s_slip
    if 0.0 < s_slip < 1.0:
        s2a, _ = integrate.quad(f_t, 0.0, s_slip, weight="alg", wvar=(a, 0.0), **opts)
        s2b, _ = integrate.quad(lambda s: f_t(s) * s ** a, s_slip, 1.0, **opts)
        s2 = s2a + s2b
    else:
        s2, _ = integrate.quad(f_t, 0.0, 1.0, weight="alg", wvar=(a, 0.0), **opts)
    return C * s1, C * s2


def sigma_1_gw(params: InterfaceParams, delta_1: float) -> float:
    """sigma_1 [Pa] for e = 0, Eq. (23) reduced to 1-D (see :func:`sigma_gw`)."""
    return sigma_gw(params, delta_1)[0]
