"""The ``paper`` asperity law, Eqs. (16)–(22) (SPEC §5): path independent.

Hertz normal force and the Cattaneo–Mindlin tangential force at constant normal force:
with delta_st = |(delta_s, delta_t)| and delta_slip = lam mu delta_n,

    F = mu f_n [1 - (1 - delta_st/delta_slip)^(3/2)]   (stick, delta_st < delta_slip)
    F = mu f_n                                         (full slip)

along (delta_s, delta_t).  Valid for monotonic shear in a fixed direction at constant
normal force: on other paths (reversal, turning, normal change during shear) it is not a
history law and can return energy on a closed loop; use ``mdr`` there.

The physics is written once, in :func:`paper_core`, without branches (selects), so the
population loop that calls it vectorises; :func:`paper_values` is the law's kernel
(:mod:`asperity_sim.laws` protocol) and :func:`paper_local` the form the quadrature
reference and the grid method use.
"""

from __future__ import annotations

import math

from ..jit import kernel
from ..vectormath import fsqrt
from .options import Cost
from .registry import Law, register


@kernel(inline="always", error_model="numpy")
def paper_core(dn, dst, sqrt_R, E_star, lam, mu):
    """(f_n, k_n, k_sec, dF_dst, dF_dn, xs, stick) of a contact with overlap dn > 0 and shear dst >= 0.

    k_n = d f_n/d dn; k_sec = F/dst (secant shear stiffness, finite at dst = 0); dF_dst, dF_dn
    the partial derivatives of the shear force magnitude F(dn, dst); xs = dst/delta_slip.
    1 - (1 - x)^(3/2) = x (1 + om + om²)/(1 + om) with om = sqrt(1 - x): free of cancellation.
    """
    C = (4.0 / 3.0) * E_star * sqrt_R
    sq = fsqrt(dn)
    f_n = C * dn * sq
    k_n = 1.5 * C * sq
    slip_len = lam * mu * dn
    xs = dst / slip_len if slip_len > 0.0 else math.inf  # mu = 0: no stick region
    stick = xs < 1.0
    om = fsqrt(1.0 - xs if stick else 0.0)
    q = (1.0 + om + om * om) / (1.0 + om)
    inv_dst = 1.0 / dst if dst > 0.0 else 0.0
    k_sec = C * sq * q / lam if stick else mu * f_n * inv_dst
    dF_dst = k_n * om / lam if stick else 0.0
    dF_dn = mu * k_n * xs * (q - om) if stick else mu * k_n
    return f_n, k_n, k_sec, dF_dst, dF_dn, xs, stick


@kernel(inline="always", error_model="numpy")
def paper_values(dn, ds, dt, R, consts):
    """The law's kernel: force (f_n, f_s, f_t), Jacobian J (row-major) and state code of one contact."""
    E_star, lam, mu = consts[0], consts[1], consts[2]
    dst = fsqrt(ds * ds + dt * dt)
    f_n, k_n, k_sec, dF_dst, dF_dn, xs, stick = paper_core(dn, dst, fsqrt(R), E_star, lam, mu)
    inv_dst = 1.0 / dst if dst > 0.0 else 0.0
    es, et = ds * inv_dst, dt * inv_dst
    extra = dF_dst - k_sec
    J12 = extra * es * et
    code = 3.0 if xs >= 1.0 else (2.0 if stick & (dst > 0.0) else 1.0)
    return (f_n, k_sec * ds, k_sec * dt,
            k_n, 0.0, 0.0,
            dF_dn * es, k_sec + extra * es * es, J12,
            dF_dn * et, J12, k_sec + extra * et * et,
            code)


@kernel(inline="always", error_model="numpy")
def paper_local(delta_n, delta_s, delta_t, sqrt_R, E_star, lam, mu):
    """Force and Jacobian terms of one contact (delta_n > 0), for the quadrature and the grid method.

    Returns ``(f_n, f_s, f_t, k_n, k_sec, dF_dst, dF_dn, slip)`` (see :func:`paper_core`).
    """
    dst = math.sqrt(delta_s * delta_s + delta_t * delta_t)
    f_n, k_n, k_sec, dF_dst, dF_dn, xs, stick = paper_core(delta_n, dst, sqrt_R, E_star, lam, mu)
    return f_n, k_sec * delta_s, k_sec * delta_t, k_n, k_sec, dF_dst, dF_dn, not stick


@kernel(error_model="numpy")
def paper_force(delta_n, delta_s, delta_t, R, E_star, lam, mu):
    """Local force (f_n, f_s, f_t) [N] of one asperity; zero out of contact."""
    if delta_n <= 0.0:
        return 0.0, 0.0, 0.0
    r = paper_local(delta_n, delta_s, delta_t, math.sqrt(R), E_star, lam, mu)
    return r[0], r[1], r[2]


def constants(params, options=None):
    return (params.E_star, params.lam, params.mu)


PAPER = register(Law(
    name="paper",
    summary="Hertz + Cattaneo-Mindlin at constant normal force, path independent (Eqs. 16-22)",
    constants=constants,
    local=paper_values,
    domain="monotonic shear in a fixed direction at constant normal force",
    # fitted to serial runs of the 120-increment constant-normal-shear path on 2 shared cores (2 numba
    # threads): 0.045 s at n = 2000 and 0.19 s at n = 20 000
    cost=Cost(per_increment=2.4e-4, per_asperity_increment=1.3e-7),
))
