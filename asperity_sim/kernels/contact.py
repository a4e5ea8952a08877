"""One contact inside the reduction kernels: its angle, frame, force and tangent, branch-free.

Owns the per-asperity steps every reduction shares (SPEC §3–§4, §6): the follow angle theta
= (2/pi) u theta_m(c, R) and d theta / d Delta_1, the birth angle while a contact lasts, the
closure and its slope, the global force and its exact tangent from the law's local values,
and the block loops that store and sum them.

Tangent of one contact (:func:`accumulate`), with Q = [n; s; t] (rows), the law's local
Jacobian J and theta_1 = d theta / d Delta_1 (policy follow only; SPEC §3):

    d f / d Delta = Q^T J K + (f_n s - f_s n) theta_1 e_1^T

where K = d(delta_n, a_s, a_t)/d Delta has rows n + delta_s theta_1 e_1, s - rho theta_1 e_1
and t, (a_s, a_t) the law's tangential variables (totals, rho = delta_n; or increments since
the committed state, rho = n.dDelta), using dn/dtheta = s, ds/dtheta = -n, dt/dtheta = 0.
"""

from __future__ import annotations

import math

from ..geometry import closure_and_slope, local_displacement, theta_m_and_slope
from ..jit import kernel
from ..vectormath import acos_unit, fsqrt, sin_cos_quarter
from .layout import (
    BLOCK,
    G_CP,
    G_CT,
    G_DDS,
    G_DDT,
    G_DN,
    G_DS,
    G_R,
    G_RHO,
    G_SP,
    G_ST,
    G_TH,
    G_TH1,
    G_U,
    G_X,
    I_A,
    I_AA,
    I_AF,
    I_AT,
    I_F,
    I_FF,
    I_NC,
    I_NP,
    I_NS,
    I_T,
    I_TH,
    V_A,
    V_AT,
    V_G,
    V_NC,
    V_NP,
    V_NS,
    V_T,
    V_TH,
)


@kernel(inline="always")
def asperity_theta(u_j, inv_R, closure, k_e, dclosure_d1):
    """Physical meridional angle theta = (2/pi) u theta_m(c, R) and d theta/d Delta_1 (SPEC §3)."""
    th_m, slope = theta_m_and_slope(closure, inv_R, k_e)
    scale = u_j / (0.5 * math.pi)
    return scale * th_m, scale * slope * dclosure_d1


@kernel(inline="always", error_model="numpy")
def global_force_tangent(ct, st, cp, sp, out, ds_tot, rho, th1):
    """(g (3), T (9, row-major)): one contact's global force and its tangent d f / d Delta.

    ``out`` is the law's 13 values (f_n, f_s, f_t, J row-major, state code); see the module
    docstring for K and the frame-rotation term.  Shared by the scalar and the vectorised loops.
    """
    f_n, f_s, f_t, J00, J01, J02, J10, J11, J12, J20, J21, J22, _ = out
    n0, n1, n2 = ct, st * cp, st * sp
    s0, s1, s2 = -st, ct * cp, ct * sp
    t1, t2 = -sp, cp
    g0 = f_n * n0 + f_s * s0
    g1 = f_n * n1 + f_s * s1 + f_t * t1
    g2 = f_n * n2 + f_s * s2 + f_t * t2
    k00, k10 = n0 + ds_tot * th1, s0 - rho * th1  # column 0 of K (theta enters it only)
    A00 = J00 * k00 + J01 * k10
    A01 = J00 * n1 + J01 * s1 + J02 * t1
    A02 = J00 * n2 + J01 * s2 + J02 * t2
    A10 = J10 * k00 + J11 * k10
    A11 = J10 * n1 + J11 * s1 + J12 * t1
    A12 = J10 * n2 + J11 * s2 + J12 * t2
    A20 = J20 * k00 + J21 * k10
    A21 = J20 * n1 + J21 * s1 + J22 * t1
    A22 = J20 * n2 + J21 * s2 + J22 * t2
    return (g0, g1, g2,
            n0 * A00 + s0 * A10 + (f_n * s0 - f_s * n0) * th1, n0 * A01 + s0 * A11, n0 * A02 + s0 * A12,
            n1 * A00 + s1 * A10 + t1 * A20 + (f_n * s1 - f_s * n1) * th1, n1 * A01 + s1 * A11 + t1 * A21,
            n1 * A02 + s1 * A12 + t1 * A22,
            n2 * A00 + s2 * A10 + t2 * A20 + (f_n * s2 - f_s * n2) * th1, n2 * A01 + s2 * A11 + t2 * A21,
            n2 * A02 + s2 * A12 + t2 * A22)


@kernel(inline="always", error_model="numpy")
def contact_area(R_j, dn, ct, st, cp, sp, ds, th1):
    """(a, da/dDelta_1, da/dDelta_2, da/dDelta_3): the Hertz contact area projected on the nominal plane,
    a = pi R delta_n cos(theta) [m²] (a² = R delta_n, SPEC §5), and its gradient [m].

    d delta_n / d Delta = n + delta_s theta_1 e_1 and d cos(theta) / d Delta = -sin(theta) theta_1 e_1
    (module docstring); ``ds`` = delta_s, ``th1`` = d theta / d Delta_1 (0 for a frozen angle).
    """
    c = math.pi * R_j
    return (c * dn * ct, c * (ct * (ct + ds * th1) - dn * st * th1), c * ct * st * cp, c * ct * st * sp)


@kernel(inline="always", error_model="numpy")
def accumulate(acc, ct, st, cp, sp, out, ds_tot, rho, th1, dn, R_j):
    """Add one contact's global force, force products, tangent, counts and contact area to ``acc``."""
    g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8 = global_force_tangent(ct, st, cp, sp, out, ds_tot, rho, th1)
    a, a0, a1, a2 = contact_area(R_j, dn, ct, st, cp, sp, ds_tot, th1)
    code = out[12]
    acc[0] += g0
    acc[1] += g1
    acc[2] += g2
    acc[3] += g0 * g0
    acc[4] += g1 * g1
    acc[5] += g2 * g2
    acc[6] += g0 * g1
    acc[7] += g0 * g2
    acc[8] += g1 * g2
    acc[9] += T0
    acc[10] += T1
    acc[11] += T2
    acc[12] += T3
    acc[13] += T4
    acc[14] += T5
    acc[15] += T6
    acc[16] += T7
    acc[17] += T8
    acc[18] += 1.0
    if code == 3.0:
        acc[19] += 1.0
    elif code == 2.0:
        acc[21] += 1.0
    acc[I_A] += a
    acc[I_AA] += a * a
    acc[I_AF] += a * g0
    acc[I_AF + 1] += a * g1
    acc[I_AF + 2] += a * g2
    acc[I_AT] += a0
    acc[I_AT + 1] += a1
    acc[I_AT + 2] += a2


@kernel(inline="always")
def contact_angle(j, r, u, inv_R, cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth, has_birth):
    """theta and d theta/d Delta_1 of asperity j: its birth angle while that contact lasts, else ``follow``."""
    th, th1 = asperity_theta(u[j], inv_R, closure, k_e, dc)
    if has_birth and not math.isnan(theta_birth[j]):
        tb = theta_birth[j]
        if math.cos(tb) * (d1 - r[j]) + math.sin(tb) * (cp * d2 + sp * d3) > 0.0:
            return tb, 0.0
    return th, th1


@kernel(inline="always", error_model="numpy")
def follow_angle(R_j, u_j, closure, k_e):
    """(theta, sin theta, cos theta, 1/R, cos theta_m unclipped, clipped, 2u/pi) under policy follow, branch-free.

    theta = (2/pi) u theta_m(c, R) (SPEC §3, Eq. 9) with the series :func:`acos_unit` and
    :func:`sin_cos_quarter` instead of libm.
    """
    inv_R = 1.0 / R_j
    y = 1.0 - k_e * closure * inv_R
    yc = 0.0 if y < 0.0 else (1.0 if y > 1.0 else y)  # min/max would not vectorise
    scale = u_j * (2.0 / math.pi)
    th = scale * acos_unit(yc)
    st, ct = sin_cos_quarter(th)
    return th, st, ct, inv_R, y, yc, scale


@kernel(inline="always", error_model="numpy")
def follow_slope(touch, y, yc, scale, k_e, inv_R, dc):
    """d theta / d Delta_1 of a contact as in :func:`asperity_theta` (zero where theta_m is clipped)."""
    inner = touch & (y > 0.0) & (y < 1.0)
    return scale * k_e * inv_R / fsqrt((1.0 - yc) * (1.0 + yc)) * dc if inner else 0.0


@kernel(inline="always")
def committed_overlap(j, r, u, inv_R, cp, sp, delta_c, r_o, k_e):
    """delta_n of asperity j at displacement ``delta_c`` (the committed one, or a reference), at its follow angle."""
    closure_c, _ = closure_and_slope(r_o, delta_c[0])
    th_c, _ = asperity_theta(u[j], inv_R, closure_c, k_e, 0.0)
    dn_c, _, _ = local_displacement(delta_c[0] - r[j], delta_c[1], delta_c[2], math.cos(th_c), math.sin(th_c), cp, sp)
    return dn_c


@kernel(inline="always")
def gather_slots(geo, asp, b0, m, d1, r, R, u, cos_phi, sin_phi):
    """Copy the inputs of slots b0..b0+m into ``geo``, contiguous; a free slot gets inputs out of contact."""
    for i in range(m):
        j = asp[b0 + i]
        if j < 0:
            geo[G_X, i], geo[G_CP, i], geo[G_SP, i], geo[G_R, i], geo[G_U, i] = -1.0, 1.0, 0.0, 1.0, 0.0
            continue
        geo[G_X, i] = d1 - r[j]
        geo[G_CP, i] = cos_phi[j]
        geo[G_SP, i] = sin_phi[j]
        geo[G_R, i] = R[j]
        geo[G_U, i] = u[j]


@kernel(inline="always", error_model="numpy")
def slot_geometry(geo, i, d2, d3, D0, D1, D2, closure, dc, k_e):
    """Column i of ``geo``: overlap, local displacement and increment of a committed contact, policy follow.

    Branch-free (series trigonometry of :func:`follow_angle`), so that the loop vectorises; the
    angle is theta = (2/pi) u theta_m(c, R) (SPEC §3) and the frame that of SPEC §4.
    """
    x, cp, sp = geo[G_X, i], geo[G_CP, i], geo[G_SP, i]
    th, st, ct, inv_R, y, yc, scale = follow_angle(geo[G_R, i], geo[G_U, i], closure, k_e)
    shear_ph = cp * d2 + sp * d3
    dn = ct * x + st * shear_ph
    inc_ph = cp * D1 + sp * D2
    geo[G_DN, i] = dn
    geo[G_DS, i] = -st * x + ct * shear_ph
    geo[G_RHO, i] = ct * D0 + st * inc_ph
    geo[G_DDS, i] = -st * D0 + ct * inc_ph
    geo[G_DDT, i] = -sp * D1 + cp * D2
    geo[G_CT, i] = ct
    geo[G_ST, i] = st
    geo[G_TH, i] = th
    geo[G_TH1, i] = follow_slope(dn > 0.0, y, yc, scale, k_e, inv_R, dc)


@kernel(inline="always", error_model="numpy")
def store_values(vals, i, touch, code, th, g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8, a, a0, a1, a2):
    """Column i of ``vals``: global force, tangent, counts, angle and contact area (with its gradient) of
    one asperity; zeros out of contact (selects, so that the loop stays vectorised)."""
    vals[V_G * BLOCK + i] = g0 if touch else 0.0
    vals[(V_G + 1) * BLOCK + i] = g1 if touch else 0.0
    vals[(V_G + 2) * BLOCK + i] = g2 if touch else 0.0
    vals[V_T * BLOCK + i] = T0 if touch else 0.0
    vals[(V_T + 1) * BLOCK + i] = T1 if touch else 0.0
    vals[(V_T + 2) * BLOCK + i] = T2 if touch else 0.0
    vals[(V_T + 3) * BLOCK + i] = T3 if touch else 0.0
    vals[(V_T + 4) * BLOCK + i] = T4 if touch else 0.0
    vals[(V_T + 5) * BLOCK + i] = T5 if touch else 0.0
    vals[(V_T + 6) * BLOCK + i] = T6 if touch else 0.0
    vals[(V_T + 7) * BLOCK + i] = T7 if touch else 0.0
    vals[(V_T + 8) * BLOCK + i] = T8 if touch else 0.0
    vals[V_NC * BLOCK + i] = 1.0 if touch else 0.0
    vals[V_NS * BLOCK + i] = 1.0 if touch & (code == 3.0) else 0.0
    vals[V_NP * BLOCK + i] = 1.0 if touch & (code == 2.0) else 0.0
    vals[V_TH * BLOCK + i] = th if touch else 0.0
    vals[V_A * BLOCK + i] = a if touch else 0.0
    vals[V_AT * BLOCK + i] = a0 if touch else 0.0
    vals[(V_AT + 1) * BLOCK + i] = a1 if touch else 0.0
    vals[(V_AT + 2) * BLOCK + i] = a2 if touch else 0.0


@kernel(inline="always", error_model="numpy")
def slot_values(vals, i, geo, out):
    """Column i of ``vals`` (as :func:`values_follow`) from the law's values ``out`` of a committed contact."""
    touch = geo[G_DN, i] > 0.0
    o = (out[0, i], out[1, i], out[2, i], out[3, i], out[4, i], out[5, i], out[6, i], out[7, i], out[8, i],
         out[9, i], out[10, i], out[11, i], out[12, i])
    g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8 = global_force_tangent(
        geo[G_CT, i], geo[G_ST, i], geo[G_CP, i], geo[G_SP, i], o, geo[G_DS, i], geo[G_RHO, i], geo[G_TH1, i])
    code = out[12, i]
    a, a0, a1, a2 = contact_area(geo[G_R, i], geo[G_DN, i], geo[G_CT, i], geo[G_ST, i], geo[G_CP, i], geo[G_SP, i],
                                 geo[G_DS, i], geo[G_TH1, i])
    store_values(vals, i, touch, code, geo[G_TH, i], g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8, a, a0, a1, a2)


@kernel(inline="always")
def add_values(vals, m, acc):
    """Add columns 0..m of ``vals`` to the sums ``acc`` (N_ACC), in order."""
    F0, F1, F2 = acc[I_F], acc[I_F + 1], acc[I_F + 2]
    P00, P11, P22, P01, P02, P12 = acc[I_FF], acc[I_FF + 1], acc[I_FF + 2], acc[I_FF + 3], acc[I_FF + 4], acc[I_FF + 5]
    T0, T1, T2, T3, T4 = acc[I_T], acc[I_T + 1], acc[I_T + 2], acc[I_T + 3], acc[I_T + 4]
    T5, T6, T7, T8 = acc[I_T + 5], acc[I_T + 6], acc[I_T + 7], acc[I_T + 8]
    n_c, n_s, n_p, th_sum = acc[I_NC], acc[I_NS], acc[I_NP], acc[I_TH]
    A, AA, AF0, AF1, AF2 = acc[I_A], acc[I_AA], acc[I_AF], acc[I_AF + 1], acc[I_AF + 2]
    AT0, AT1, AT2 = acc[I_AT], acc[I_AT + 1], acc[I_AT + 2]
    for i in range(m):
        g0, g1, g2 = vals[V_G * BLOCK + i], vals[(V_G + 1) * BLOCK + i], vals[(V_G + 2) * BLOCK + i]
        F0 += g0
        F1 += g1
        F2 += g2
        P00 += g0 * g0
        P11 += g1 * g1
        P22 += g2 * g2
        P01 += g0 * g1
        P02 += g0 * g2
        P12 += g1 * g2
        T0 += vals[V_T * BLOCK + i]
        T1 += vals[(V_T + 1) * BLOCK + i]
        T2 += vals[(V_T + 2) * BLOCK + i]
        T3 += vals[(V_T + 3) * BLOCK + i]
        T4 += vals[(V_T + 4) * BLOCK + i]
        T5 += vals[(V_T + 5) * BLOCK + i]
        T6 += vals[(V_T + 6) * BLOCK + i]
        T7 += vals[(V_T + 7) * BLOCK + i]
        T8 += vals[(V_T + 8) * BLOCK + i]
        n_c += vals[V_NC * BLOCK + i]
        n_s += vals[V_NS * BLOCK + i]
        n_p += vals[V_NP * BLOCK + i]
        th_sum += vals[V_TH * BLOCK + i]
        a = vals[V_A * BLOCK + i]
        A += a
        AA += a * a
        AF0 += a * g0
        AF1 += a * g1
        AF2 += a * g2
        AT0 += vals[V_AT * BLOCK + i]
        AT1 += vals[(V_AT + 1) * BLOCK + i]
        AT2 += vals[(V_AT + 2) * BLOCK + i]
    acc[I_F], acc[I_F + 1], acc[I_F + 2] = F0, F1, F2
    acc[I_FF], acc[I_FF + 1], acc[I_FF + 2], acc[I_FF + 3], acc[I_FF + 4], acc[I_FF + 5] = P00, P11, P22, P01, P02, P12
    acc[I_T], acc[I_T + 1], acc[I_T + 2], acc[I_T + 3], acc[I_T + 4] = T0, T1, T2, T3, T4
    acc[I_T + 5], acc[I_T + 6], acc[I_T + 7], acc[I_T + 8] = T5, T6, T7, T8
    acc[I_NC], acc[I_NS], acc[I_NP], acc[I_TH] = n_c, n_s, n_p, th_sum
    acc[I_A], acc[I_AA], acc[I_AF], acc[I_AF + 1], acc[I_AF + 2] = A, AA, AF0, AF1, AF2
    acc[I_AT], acc[I_AT + 1], acc[I_AT + 2] = AT0, AT1, AT2
