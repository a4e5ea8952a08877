"""Numba kernels of the reference quadrature: the height integral and the sum over the other axes.

Owns the integrand of Eq. (23) for the ``paper`` law: the height integral at fixed
(R, u, phi), split at the end of contact and the stick/slip boundaries (the structure is
described in :mod:`asperity_sim.reference.quadrature`), the breaks of the azimuth axis, and
the kernel that sums over R, u and phi.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import HALF_PI, theta_m_and_slope
from ..jit import kernel
from ..laws.paper import paper_local
from ..vectormath import borrowed

# --------------------------------------------------------------------------------------
# numba kernels
# --------------------------------------------------------------------------------------


@kernel()
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


@kernel()
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


@kernel()
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


@kernel(nogil=True)  # no Python objects: callers may integrate several displacements on threads
def stress_kernel(d1, S, c_psi, s_psi, mode, closure, k_e, E_star, lam, mu, alpha, beta,
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
    R_x, R_w, tu, wu, tp, wp, tj, wj, tg, wg = borrowed(
        (R_x, R_w, tu, wu, tp, wp, tj, wj, tg, wg))  # shared by threads: no reference counts (vectormath.borrowed)
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
