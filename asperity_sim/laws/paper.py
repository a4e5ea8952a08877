"""The ``paper`` asperity law, Eqs. (16)–(22) (SPEC §5).

Hertz normal force and the Cattaneo–Mindlin tangential force at constant normal
force, path independent.  Everything here is a scalar numba function of the local
displacements (delta_n, delta_s, delta_t) of one asperity; the assembly kernels
call them once per asperity.
"""

from __future__ import annotations

import math

import numba


@numba.njit(cache=True, inline="always")
def paper_local(delta_n, delta_s, delta_t, sqrt_R, E_star, lam, mu):
    """Local force and its Jacobian for one asperity in contact (delta_n > 0).

    Returns ``(f_n, f_s, f_t, k_n, k_sec, dF_dst, dF_dn, slip)`` where
    k_n = d f_n / d delta_n, k_sec = F / delta_st (secant shear stiffness, finite at
    delta_st = 0), dF_dst and dF_dn are the partial derivatives of the shear force
    magnitude F(delta_n, delta_st), and slip is True when delta_st >= lam mu delta_n.

    f_n = (4/3) E* sqrt(R) delta_n^(3/2)                         (Eq. 16)
    F   = mu f_n [1 - (1 - delta_st/delta_slip)^(3/2)], stick   (Eqs. 18–19)
    F   = mu f_n, slip                                          (Eqs. 20–21)
    """
    C = (4.0 / 3.0) * E_star * sqrt_R
    sq = math.sqrt(delta_n)
    f_n = C * delta_n * sq
    k_n = 1.5 * C * sq
    delta_st = math.sqrt(delta_s * delta_s + delta_t * delta_t)
    delta_slip = lam * mu * delta_n
    if delta_st < delta_slip:
        x = delta_st / delta_slip
        om = math.sqrt(1.0 - x)
        # 1 - (1-x)^(3/2) = x (1 + om + om²)/(1 + om), exact and free of cancellation
        q = (1.0 + om + om * om) / (1.0 + om)
        k_sec = C * sq * q / lam
        dF_dst = k_n * om / lam
        dF_dn = mu * k_n * x * (q - om)
        slip = False
    else:
        if delta_st > 0.0:
            k_sec = mu * f_n / delta_st
        else:  # mu = 0 with no shear displacement: no shear force
            k_sec = 0.0
        dF_dst = 0.0
        dF_dn = mu * k_n
        slip = True
    return f_n, k_sec * delta_s, k_sec * delta_t, k_n, k_sec, dF_dst, dF_dn, slip


@numba.njit(cache=True)
def paper_force(delta_n, delta_s, delta_t, R, E_star, lam, mu):
    """Local force (f_n, f_s, f_t) [N] of one asperity; zero out of contact."""
    if delta_n <= 0.0:
        return 0.0, 0.0, 0.0
    r = paper_local(delta_n, delta_s, delta_t, math.sqrt(R), E_star, lam, mu)
    return r[0], r[1], r[2]
