"""Parallel reductions over asperities: stress, standard error, tangent, counts (SPEC §6).

Owns the assembly of Eq. (23) as a Monte Carlo sum, sigma_i = N sum_j w_j f_ij, and
of its exact tangent T_ik = d sigma_i / d Delta_k.  The kernel loops over the
asperities that can touch (the population is sorted by height) in fixed-size chunks
under ``prange``; each chunk writes its partial sums to its own row of a caller-owned
array, so the result does not depend on the number of threads.

Speed (``paper`` law, issue 5): an asperity above the closure is dropped before any
trigonometry when it cannot touch at the largest angle in use (:func:`cannot_touch`) or,
under policy follow, at its own largest angle (:func:`may_touch_follow`, from
cos theta_m = 1 - k_e c / R alone).  Under policy follow the rest go through a branch-free
loop that LLVM vectorises (:func:`paper_chunk_follow`, :func:`follow_values`: series
trigonometry, selects instead of branches), about 3x faster per contact than the scalar libm
loop kept for policy birth (:func:`paper_chunk_birth`); the two agree to round-off.  Without
fastmath, vector and scalar code give the same bits, and the per-asperity values are summed in
a fixed order after the vector loop, so a result is bit-identical in every process whether
its kernels were compiled or loaded from the numba cache.  Chunks go to the threads in a
strided order (:func:`chunk_stride`) so that both threads get low (costly, in contact) and
high (cheap) heights; small workloads run on the calling thread (:func:`assemble_paper_serial`, which
also evaluates a batch of displacements in one call).

Tangent of one asperity (see :func:`accumulate`), with Q = [n; s; t] (rows), the law's local
Jacobian J and theta_1 = d theta / d Delta_1 (policy ``follow`` only; SPEC §3):

    d f / d Delta = Q^T J K + (f_n s - f_s n) theta_1 e_1^T

using dn/dtheta = s, ds/dtheta = -n, dt/dtheta = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from .geometry import acos_unit, fsqrt, local_displacement, sin_cos_quarter, theta_m_and_slope
from .laws.mdr import mdr_springs
from .laws.paper import paper_local
from .population import Population, reach

CHUNK = 2048
SERIAL_CHUNKS = 16  # up to this many chunks (32768 asperities that can touch) the paper kernel runs serially
# layout of one row of partial sums: forces (3), products f_i f_j (11, 22, 33, 12, 13, 23),
# tangent (9), contact and full-slip counts, sum of theta over contacts, partial-slip count
I_F, I_FF, I_T, I_NC, I_NS, I_TH, I_NP = 0, 3, 9, 18, 19, 20, 21
N_ACC = 22
_FF_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))  # (i, j) of the products f_i f_j, in their order
POLICIES = ("follow", "birth")
LAWS = ("paper", "mdr")


@numba.njit(cache=True, inline="always")
def asperity_theta(u_j, inv_R, closure, k_e, dclosure_d1):
    """Physical meridional angle theta = (2/pi) u theta_m(c, R) and d theta/d Delta_1 (SPEC §3)."""
    th_m, slope = theta_m_and_slope(closure, inv_R, k_e)
    scale = u_j / (0.5 * math.pi)
    return scale * th_m, scale * slope * dclosure_d1


@numba.njit(cache=True, inline="always")
def accumulate(acc, ct, st, cp, sp, f_n, f_s, f_t, J, ds_tot, rho, th1, state):
    """Add one contact's global force, force products, tangent and counts to ``acc``.

    ``J`` (3x3) is d(f_n, f_s, f_t)/d(delta_n, a_s, a_t) for the law's local variables
    (a_s, a_t) = (delta_s, delta_t) (``paper``) or their increments (history laws).  Their
    kinematic Jacobian K = d(delta_n, a_s, a_t)/d Delta has rows n + delta_s theta_1 e_1,
    s - rho theta_1 e_1 and t, with rho = delta_n for totals and n.dDelta for increments.
    T = Q^T J K + (f_n s - f_s n) theta_1 e_1^T.
    """
    n0, n1, n2 = ct, st * cp, st * sp
    s0, s1, s2 = -st, ct * cp, ct * sp
    t0, t1, t2 = 0.0, -sp, cp
    g0 = f_n * n0 + f_s * s0 + f_t * t0
    g1 = f_n * n1 + f_s * s1 + f_t * t1
    g2 = f_n * n2 + f_s * s2 + f_t * t2
    # K, row by row (theta enters column 0 only)
    k00, k01, k02 = n0 + ds_tot * th1, n1, n2
    k10, k11, k12 = s0 - rho * th1, s1, s2
    k20, k21, k22 = t0, t1, t2
    # A = J K
    A00 = J[0, 0] * k00 + J[0, 1] * k10 + J[0, 2] * k20
    A01 = J[0, 0] * k01 + J[0, 1] * k11 + J[0, 2] * k21
    A02 = J[0, 0] * k02 + J[0, 1] * k12 + J[0, 2] * k22
    A10 = J[1, 0] * k00 + J[1, 1] * k10 + J[1, 2] * k20
    A11 = J[1, 0] * k01 + J[1, 1] * k11 + J[1, 2] * k21
    A12 = J[1, 0] * k02 + J[1, 1] * k12 + J[1, 2] * k22
    A20 = J[2, 0] * k00 + J[2, 1] * k10 + J[2, 2] * k20
    A21 = J[2, 0] * k01 + J[2, 1] * k11 + J[2, 2] * k21
    A22 = J[2, 0] * k02 + J[2, 1] * k12 + J[2, 2] * k22
    # frame rotation at fixed local force: dn/dtheta = s, ds/dtheta = -n
    v0 = (f_n * s0 - f_s * n0) * th1
    v1 = (f_n * s1 - f_s * n1) * th1
    v2 = (f_n * s2 - f_s * n2) * th1
    acc[0] += g0
    acc[1] += g1
    acc[2] += g2
    acc[3] += g0 * g0
    acc[4] += g1 * g1
    acc[5] += g2 * g2
    acc[6] += g0 * g1
    acc[7] += g0 * g2
    acc[8] += g1 * g2
    acc[9] += n0 * A00 + s0 * A10 + t0 * A20 + v0
    acc[10] += n0 * A01 + s0 * A11 + t0 * A21
    acc[11] += n0 * A02 + s0 * A12 + t0 * A22
    acc[12] += n1 * A00 + s1 * A10 + t1 * A20 + v1
    acc[13] += n1 * A01 + s1 * A11 + t1 * A21
    acc[14] += n1 * A02 + s1 * A12 + t1 * A22
    acc[15] += n2 * A00 + s2 * A10 + t2 * A20 + v2
    acc[16] += n2 * A01 + s2 * A11 + t2 * A21
    acc[17] += n2 * A02 + s2 * A12 + t2 * A22
    acc[18] += 1.0
    if state == 3:
        acc[19] += 1.0
    elif state == 2:
        acc[21] += 1.0


@numba.njit(cache=True, inline="always")
def contact_angle(j, r, u, inv_R, cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth, has_birth):
    """theta and d theta/d Delta_1 of asperity j: its birth angle while that contact lasts, else ``follow``."""
    th, th1 = asperity_theta(u[j], inv_R, closure, k_e, dc)
    if has_birth and not math.isnan(theta_birth[j]):
        tb = theta_birth[j]
        if math.cos(tb) * (d1 - r[j]) + math.sin(tb) * (cp * d2 + sp * d3) > 0.0:
            return tb, 0.0
    return th, th1


@numba.njit(cache=True, inline="always")
def closure_and_slope(r_o, d1):
    """c = max(0, r_o + Delta_1) and dc/dDelta_1 (SPEC §3)."""
    closure = r_o + d1
    if closure <= 0.0:
        return 0.0, 0.0
    return closure, 1.0


@numba.njit(cache=True, inline="always")
def cannot_touch(x, shear_ph, tan_max):
    """True when delta_n = cos(theta) x + sin(theta) shear_ph <= 0 for every theta in [0, theta_max].

    ``x`` = Delta_1 - r, ``shear_ph`` = cos(phi) Delta_2 + sin(phi) Delta_3 and ``tan_max`` =
    tan(theta_max) (inf for theta_max = pi/2).  Above the closure (x <= 0) contact needs
    shear_ph > 0 and tan(theta) > -x / shear_ph; the relative margin 1e-9 keeps the test on the
    safe side of round-off, so a skipped asperity is one the exact test also finds out of contact.
    """
    if x > 0.0:
        return False
    if shear_ph <= 0.0:
        return True
    return -x > shear_ph * tan_max * (1.0 + 1e-9)


@numba.njit(cache=True, inline="always")
def chunk_stride(n_chunks):
    """A stride g coprime with n_chunks, near n_chunks / golden ratio.

    Chunk ic = (k g) mod n_chunks for k = 0 .. n_chunks-1 visits every chunk once and spreads
    the chunks of each thread's contiguous block of k over the whole height range.  The
    population is sorted by height, so contiguous blocks would give one thread all the
    contacts (low heights) and the other the cheap skipped asperities.  Each chunk still
    writes its own row, so the result does not depend on the threads.
    """
    g = max(1, int(0.6180339887498949 * n_chunks))
    while True:
        a, b = g, n_chunks
        while b:
            a, b = b, a % b
        if a == 1:
            return g
        g -= 1


@numba.njit(cache=True, inline="always")
def paper_chunk_birth(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, E_star, lam, mu,
                      theta_birth, tan_max, partial):
    """Row ic of ``partial`` under policy birth: the sums of :func:`accumulate` over chunk ic."""
    acc = np.zeros(N_ACC)
    J = np.zeros((3, 3))
    for j in range(ic * CHUNK, min(n_active, (ic + 1) * CHUNK)):
        cp, sp = cos_phi[j], sin_phi[j]
        x = d1 - r[j]
        if cannot_touch(x, cp * d2 + sp * d3, tan_max):
            continue
        th, th1 = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth, True)
        ct, st = math.cos(th), math.sin(th)
        dn, ds, dt = local_displacement(x, d2, d3, ct, st, cp, sp)
        if dn <= 0.0:
            continue
        f_n, f_s, f_t, k_n, k_sec, dF_dst, dF_dn, slip = paper_local(
            dn, ds, dt, math.sqrt(R[j]), E_star, lam, mu)
        dst = math.sqrt(ds * ds + dt * dt)
        if dst > 0.0:
            es, et = ds / dst, dt / dst
        else:
            es, et = 0.0, 0.0
        extra = dF_dst - k_sec
        J[0, 0] = k_n
        J[1, 0], J[2, 0] = dF_dn * es, dF_dn * et
        J[1, 1], J[1, 2] = k_sec + extra * es * es, extra * es * et
        J[2, 1], J[2, 2] = extra * es * et, k_sec + extra * et * et
        state = 3 if slip else (2 if dst > 0.0 else 1)
        accumulate(acc, ct, st, cp, sp, f_n, f_s, f_t, J, ds, dn, th1, state)
        acc[20] += th
    partial[ic, :] = acc


# per-asperity values of the follow kernel, one row of BLOCK each: global force (3), tangent (9,
# row-major), contact, full slip, partial slip (0 or 1) and theta of a contact
V_G, V_T, V_NC, V_NS, V_NP, V_TH = 0, 3, 12, 13, 14, 15
N_VAL = 16
BLOCK = 256  # asperities per block (16 x 256 doubles of values = 32 KiB)
# inputs of one block, one row of BLOCK each: Delta_1 - r, cos phi, sin phi, R, u
X_X, X_CP, X_SP, X_R, X_U = 0, 1, 2, 3, 4
N_IN = 5


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
def follow_slope(touch, y, yc, scale, k_e, inv_R, dc):
    """d theta / d Delta_1 of a contact as in :func:`asperity_theta` (zero where theta_m is clipped)."""
    inner = touch & (y > 0.0) & (y < 1.0)
    return scale * k_e * inv_R / fsqrt((1.0 - yc) * (1.0 + yc)) * dc if inner else 0.0


@numba.njit(cache=True, inline="always", error_model="numpy")
def paper_law_selects(touch, dn, dst, R_j, c_hertz, lam, mu):
    """:func:`paper_local` with selects instead of branches: (f_n, k_n, k_sec, dF_dst, dF_dn, xs, stick, 1/dst).

    Both the stick and the slip form are computed with safe arguments; out of contact
    (``touch`` False) the forces and stiffnesses are zero.
    """
    dn_safe = dn if touch else 1.0
    C = c_hertz * fsqrt(R_j)
    sq = fsqrt(dn_safe)
    f_n = C * dn_safe * sq
    k_n = 1.5 * C * sq
    xs = dst / (lam * mu * dn_safe)
    stick = xs < 1.0
    om = fsqrt(1.0 - xs if stick else 0.0)
    q = (1.0 + om + om * om) / (1.0 + om)
    inv_dst = 1.0 / dst if dst > 0.0 else 0.0
    k_sec = C * sq * q / lam if stick else mu * f_n * inv_dst
    dF_dst = k_n * om / lam if stick else 0.0
    dF_dn = mu * k_n * xs * (q - om) if stick else mu * k_n
    f_n = f_n if touch else 0.0
    k_n = k_n if touch else 0.0
    k_sec = k_sec if touch else 0.0
    dF_dst = dF_dst if touch else 0.0
    dF_dn = dF_dn if touch else 0.0
    return f_n, k_n, k_sec, dF_dst, dF_dn, xs, stick, inv_dst


@numba.njit(cache=True, inline="always", error_model="numpy")
def store_counts(vals, i, touch, xs, stick, dst, th):
    """Contact, full-slip and partial-slip flags and theta of a contact into column i of ``vals``."""
    vals[V_NC * BLOCK + i] = 1.0 if touch else 0.0
    vals[V_NS * BLOCK + i] = 1.0 if touch & (xs >= 1.0) else 0.0
    vals[V_NP * BLOCK + i] = 1.0 if touch & stick & (dst > 0.0) else 0.0
    vals[V_TH * BLOCK + i] = th if touch else 0.0


@numba.njit(cache=True, inline="always", error_model="numpy")
def follow_values(vals, i, x, cp, sp, R_j, u_j, d2, d3, closure, dc, k_e, c_hertz, lam, mu):
    """Column i of ``vals``: force, tangent and counts of one asperity under policy follow, branch-free.

    ``x`` = Delta_1 - r.  The same physics as :func:`paper_local` and :func:`accumulate` (with
    J[0, 1] = J[0, 2] = 0: Hertz does not depend on the slip), written with selects instead of
    branches, :func:`fsqrt` and series trigonometry instead of libm, so that LLVM vectorises
    the loop that calls it.  An asperity out of contact gets zeros.
    """
    shear_ph = cp * d2 + sp * d3
    dt = -sp * d2 + cp * d3
    th, st, ct, inv_R, y, yc, scale = follow_angle(R_j, u_j, closure, k_e)
    dn = ct * x + st * shear_ph
    ds = -st * x + ct * shear_ph
    touch = dn > 0.0
    th1 = follow_slope(touch, y, yc, scale, k_e, inv_R, dc)
    dst = fsqrt(ds * ds + dt * dt)
    f_n, k_n, k_sec, dF_dst, dF_dn, xs, stick, inv_dst = paper_law_selects(touch, dn, dst, R_j, c_hertz, lam, mu)
    es, et = ds * inv_dst, dt * inv_dst
    extra = dF_dst - k_sec
    f_s, f_t = k_sec * ds, k_sec * dt
    J10, J20 = dF_dn * es, dF_dn * et
    J11, J12, J22 = k_sec + extra * es * es, extra * es * et, k_sec + extra * et * et
    n0, n1, n2 = ct, st * cp, st * sp
    s0, s1, s2 = -st, ct * cp, ct * sp
    t1, t2 = -sp, cp
    vals[V_G * BLOCK + i] = f_n * n0 + f_s * s0
    vals[(V_G + 1) * BLOCK + i] = f_n * n1 + f_s * s1 + f_t * t1
    vals[(V_G + 2) * BLOCK + i] = f_n * n2 + f_s * s2 + f_t * t2
    k00, k10 = n0 + ds * th1, s0 - dn * th1
    A00, A01, A02 = k_n * k00, k_n * n1, k_n * n2
    A10 = J10 * k00 + J11 * k10
    A11 = J10 * n1 + J11 * s1 + J12 * t1
    A12 = J10 * n2 + J11 * s2 + J12 * t2
    A20 = J20 * k00 + J12 * k10
    A21 = J20 * n1 + J12 * s1 + J22 * t1
    A22 = J20 * n2 + J12 * s2 + J22 * t2
    vals[V_T * BLOCK + i] = n0 * A00 + s0 * A10 + (f_n * s0 - f_s * n0) * th1
    vals[(V_T + 1) * BLOCK + i] = n0 * A01 + s0 * A11
    vals[(V_T + 2) * BLOCK + i] = n0 * A02 + s0 * A12
    vals[(V_T + 3) * BLOCK + i] = n1 * A00 + s1 * A10 + t1 * A20 + (f_n * s1 - f_s * n1) * th1
    vals[(V_T + 4) * BLOCK + i] = n1 * A01 + s1 * A11 + t1 * A21
    vals[(V_T + 5) * BLOCK + i] = n1 * A02 + s1 * A12 + t1 * A22
    vals[(V_T + 6) * BLOCK + i] = n2 * A00 + s2 * A10 + t2 * A20 + (f_n * s2 - f_s * n2) * th1
    vals[(V_T + 7) * BLOCK + i] = n2 * A01 + s2 * A11 + t2 * A21
    vals[(V_T + 8) * BLOCK + i] = n2 * A02 + s2 * A12 + t2 * A22
    store_counts(vals, i, touch, xs, stick, dst, th)


@numba.njit(cache=True, inline="always", error_model="numpy")
def closure_values(vals, i, x, cp, sp, R_j, u_j, closure, dc, k_e, c_hertz, lam, mu):
    """:func:`follow_values` at Delta_2 = Delta_3 = 0 (normal closure), the same bits with less work.

    Without shear delta_t = 0 and delta_s = -sin(theta) x, so delta_st = |delta_s| (exactly
    sqrt(delta_s²) in IEEE arithmetic), the shear force has no t component and the terms of
    :func:`follow_values` that carry delta_t are exact zeros, left out here.
    """
    th, st, ct, inv_R, y, yc, scale = follow_angle(R_j, u_j, closure, k_e)
    dn = ct * x
    ds = -st * x
    touch = dn > 0.0
    th1 = follow_slope(touch, y, yc, scale, k_e, inv_R, dc)
    dst = -ds if ds < 0.0 else ds
    f_n, k_n, k_sec, dF_dst, dF_dn, xs, stick, inv_dst = paper_law_selects(touch, dn, dst, R_j, c_hertz, lam, mu)
    es = ds * inv_dst
    extra = dF_dst - k_sec
    f_s = k_sec * ds
    J10 = dF_dn * es
    J11 = k_sec + extra * es * es
    n0, n1, n2 = ct, st * cp, st * sp
    s0, s1, s2 = -st, ct * cp, ct * sp
    t1, t2 = -sp, cp
    vals[V_G * BLOCK + i] = f_n * n0 + f_s * s0
    vals[(V_G + 1) * BLOCK + i] = f_n * n1 + f_s * s1
    vals[(V_G + 2) * BLOCK + i] = f_n * n2 + f_s * s2
    k00, k10 = n0 + ds * th1, s0 - dn * th1
    A00, A01, A02 = k_n * k00, k_n * n1, k_n * n2
    A10 = J10 * k00 + J11 * k10
    A11 = J10 * n1 + J11 * s1
    A12 = J10 * n2 + J11 * s2
    vals[V_T * BLOCK + i] = n0 * A00 + s0 * A10 + (f_n * s0 - f_s * n0) * th1
    vals[(V_T + 1) * BLOCK + i] = n0 * A01 + s0 * A11
    vals[(V_T + 2) * BLOCK + i] = n0 * A02 + s0 * A12
    vals[(V_T + 3) * BLOCK + i] = n1 * A00 + s1 * A10 + (f_n * s1 - f_s * n1) * th1
    vals[(V_T + 4) * BLOCK + i] = n1 * A01 + s1 * A11 + t1 * (k_sec * t1)
    vals[(V_T + 5) * BLOCK + i] = n1 * A02 + s1 * A12 + t1 * (k_sec * t2)
    vals[(V_T + 6) * BLOCK + i] = n2 * A00 + s2 * A10 + (f_n * s2 - f_s * n2) * th1
    vals[(V_T + 7) * BLOCK + i] = n2 * A01 + s2 * A11 + t2 * (k_sec * t1)
    vals[(V_T + 8) * BLOCK + i] = n2 * A02 + s2 * A12 + t2 * (k_sec * t2)
    store_counts(vals, i, touch, xs, stick, dst, th)


@numba.njit(cache=True, inline="always", error_model="numpy")
def may_touch_follow(x, shear_ph, y, scale, tan_max):
    """False when the asperity cannot touch under policy follow, tested without trigonometry or branches.

    ``x`` = Delta_1 - r, ``shear_ph`` = cos(phi) Delta_2 + sin(phi) Delta_3, ``y`` =
    cos(theta_m(c, R_j)) = 1 - k_e c / R_j (Eq. 9, before clipping), ``scale`` = 2 u_j / pi, so
    theta = scale theta_m, and ``tan_max`` bounds tan theta of every asperity (:func:`cannot_touch`).
    Above the closure (x <= 0) contact needs shear_ph > 0 and tan(theta) > -x / shear_ph.  tan
    is convex on [0, pi/2) with tan 0 = 0, hence tan(theta) <= scale tan(theta_m): contact is
    impossible when scale² (1 - y²) shear_ph² < x² y² (0 < y < 1; y >= 1 means theta_m = 0 and
    y <= 0 gives no bound).  The relative margin 1e-9 keeps both tests on the safe side of round-off.
    """
    sh2 = shear_ph * shear_ph
    by_angle = ~(-x > shear_ph * tan_max * (1.0 + 1e-9))
    by_own = (y <= 0.0) | ((y < 1.0) & ~(scale * scale * (1.0 - y * y) * sh2 * (1.0 + 1e-9) < x * x * y * y))
    return (x > 0.0) | ((shear_ph > 0.0) & by_angle & by_own)


@numba.njit(cache=True, error_model="numpy")
def paper_chunk_follow(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, E_star, lam, mu,
                       tan_max, partial):
    """Row ic of ``partial`` under policy follow: :func:`paper_local` + :func:`accumulate`, vectorised.

    Per block of BLOCK asperities: unless the whole block lies below the closure, a loop that
    LLVM vectorises marks the asperities :func:`may_touch_follow` keeps (no trigonometry, no
    branch), a scalar pass lists their positions and their inputs are copied, contiguous, into
    ``inp`` (a single scalar loop that tested, stored and compacted at once cost about 1.7 times
    more per asperity: in sheared states most asperities of a block are dropped here);
    :func:`follow_values` (:func:`closure_values` for whole blocks without shear) fills ``vals``
    in a loop that LLVM vectorises; the columns are summed in order.  No fastmath anywhere, so
    vector and scalar code give the same bits and the sums do not depend on how LLVM
    vectorised: the result is the same in every process, compiled or loaded from the cache.
    """
    lo, hi = ic * CHUNK, min(n_active, (ic + 1) * CHUNK)
    vals = np.empty(N_VAL * BLOCK)
    inp = np.empty(N_IN * BLOCK)
    kept = np.empty(BLOCK, dtype=np.int64)
    at = np.empty(BLOCK, dtype=np.int64)
    c_hertz = (4.0 / 3.0) * E_star
    zero_shear = d2 == 0.0 and d3 == 0.0  # normal closure: closure_values, the same bits with less work
    F0 = F1 = F2 = P00 = P11 = P22 = P01 = P02 = P12 = 0.0
    T0 = T1 = T2 = T3 = T4 = T5 = T6 = T7 = T8 = 0.0
    n_c = n_s = n_p = th_sum = 0.0
    for b0 in range(lo, hi, BLOCK):
        b1 = min(hi, b0 + BLOCK)
        if d1 > r[b1 - 1]:  # the whole block lies below the closure: every asperity may touch
            m = b1 - b0
            if zero_shear:
                for i in range(m):
                    closure_values(vals, i, d1 - r[b0 + i], cos_phi[b0 + i], sin_phi[b0 + i], R[b0 + i],
                                   u[b0 + i], closure, dc, k_e, c_hertz, lam, mu)
            else:
                for i in range(m):
                    follow_values(vals, i, d1 - r[b0 + i], cos_phi[b0 + i], sin_phi[b0 + i], R[b0 + i], u[b0 + i],
                                  d2, d3, closure, dc, k_e, c_hertz, lam, mu)
        else:
            for j in range(b0, b1):  # vectorised: which asperities may touch
                cp, sp = cos_phi[j], sin_phi[j]
                keep = may_touch_follow(d1 - r[j], cp * d2 + sp * d3, 1.0 - k_e * closure / R[j],
                                        u[j] * (2.0 / math.pi), tan_max)
                kept[j - b0] = 1 if keep else 0
            m = 0
            for i in range(b1 - b0):  # their positions, contiguous
                at[m] = b0 + i
                m += kept[i]
            for i in range(m):  # their inputs, contiguous
                j = at[i]
                inp[X_X * BLOCK + i] = d1 - r[j]
                inp[X_CP * BLOCK + i] = cos_phi[j]
                inp[X_SP * BLOCK + i] = sin_phi[j]
                inp[X_R * BLOCK + i] = R[j]
                inp[X_U * BLOCK + i] = u[j]
            for i in range(m):  # without shear only the block at the closure comes here: no closure_values copy
                follow_values(vals, i, inp[X_X * BLOCK + i], inp[X_CP * BLOCK + i], inp[X_SP * BLOCK + i],
                              inp[X_R * BLOCK + i], inp[X_U * BLOCK + i], d2, d3, closure, dc, k_e, c_hertz, lam, mu)
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
    row = partial[ic]
    row[I_F], row[I_F + 1], row[I_F + 2] = F0, F1, F2
    row[I_FF], row[I_FF + 1], row[I_FF + 2], row[I_FF + 3], row[I_FF + 4], row[I_FF + 5] = P00, P11, P22, P01, P02, P12
    row[I_T], row[I_T + 1], row[I_T + 2], row[I_T + 3], row[I_T + 4] = T0, T1, T2, T3, T4
    row[I_T + 5], row[I_T + 6], row[I_T + 7], row[I_T + 8] = T5, T6, T7, T8
    row[I_NC], row[I_NS], row[I_NP], row[I_TH] = n_c, n_s, n_p, th_sum


@numba.njit(cache=True, inline="always")
def paper_chunk(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, E_star, lam, mu,
                theta_birth, has_birth, tan_max, partial):
    """Row ic of ``partial`` for the ``paper`` law, by policy."""
    if has_birth:
        paper_chunk_birth(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, E_star, lam, mu,
                          theta_birth, tan_max, partial)
    else:
        paper_chunk_follow(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, E_star, lam, mu,
                           tan_max, partial)


@numba.njit(cache=True, parallel=True)
def assemble_paper(r, R, u, cos_phi, sin_phi, n_active, delta, r_o, k_e, E_star, lam, mu, theta_birth, tan_max,
                   partial):
    """Partial sums of forces, force products, tangents and counts for the ``paper`` law.

    ``theta_birth`` is empty (policy follow) or holds, per asperity, the frozen angle of a
    committed contact and NaN elsewhere (policy birth).  ``tan_max`` is tan of an upper
    bound of every angle in use (:func:`~asperity_sim.population.reach`): an asperity above the closure that
    cannot touch at that angle is skipped before any trigonometry (:func:`cannot_touch`;
    under policy follow also by :func:`may_touch_follow`, per asperity).  ``partial`` has
    shape (n_chunks, N_ACC) with n_chunks >= ceil(n_active / CHUNK); rows are overwritten.
    Chunks are handed to the threads in the order of :func:`chunk_stride`.
    """
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, dc = closure_and_slope(r_o, d1)
    has_birth = theta_birth.size > 0
    n_chunks = (n_active + CHUNK - 1) // CHUNK
    stride = chunk_stride(n_chunks)
    for k in numba.prange(n_chunks):
        paper_chunk((k * stride) % n_chunks, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e,
                    E_star, lam, mu, theta_birth, has_birth, tan_max, partial)


@numba.njit(cache=True)
def assemble_paper_serial(r, R, u, cos_phi, sin_phi, R_min, deltas, r_o, k_e, E_star, lam, mu, beta, theta_birth, n,
                          scale, partial, out):
    """The flat result (:func:`finish`) at every row of ``deltas`` (m, 3), on the calling thread.

    Row i of ``out`` (m, N_OUT) is what :func:`paper_bounds`, :func:`assemble_paper` and
    :func:`finish` give at ``deltas[i]`` (same rows of partial sums, so the same bits).  For
    small workloads: a parallel region costs tens of microseconds on an idle machine and
    milliseconds when other processes hold the cores, and under a path-independent law the
    increments of a displacement-controlled stage are independent, so a small population
    need not pay a round trip through Python for each of them.  One kernel serves one
    evaluation (m = 1) and such batches: a second serial kernel would compile the chunk loops
    again.
    """
    has_birth = theta_birth.size > 0
    for i in range(deltas.shape[0]):
        d1, d2, d3 = deltas[i, 0], deltas[i, 1], deltas[i, 2]
        n_active, tan_max = paper_bounds(r, R_min, r_o, k_e, beta, deltas[i], theta_birth)
        closure, dc = closure_and_slope(r_o, d1)
        n_chunks = (n_active + CHUNK - 1) // CHUNK
        for ic in range(n_chunks):
            paper_chunk(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, E_star, lam, mu,
                        theta_birth, has_birth, tan_max, partial)
        finish(partial, n_chunks, n, scale, out[i])
        out[i, O_NA] = n_active


# layout of the flat result of :func:`finish` (one float array per evaluation)
O_STRESS, O_TANGENT, O_COV, O_SE, O_NC, O_NS, O_NP, O_TH, O_NA = 0, 3, 12, 21, 24, 25, 26, 27, 28
N_OUT = 29


@numba.njit(cache=True)
def finish(partial, n_chunks, n, scale, out):
    """Stress, tangent, covariance, standard error and counts from the partial sums (SPEC §6).

    sigma = N w sum f; the covariance of the mean of n iid draws scaled to stress,
    (N w n)² C_f / n = (N w)² n C_f, multiplied in this order so that 0 stays 0 when (N w)²
    overflows; the standard error is its square root on the diagonal (NaN stays NaN).
    """
    s = np.zeros(N_ACC)
    for ic in range(n_chunks):  # row after row, in order, as numpy's sum over axis 0
        for a in range(N_ACC):
            s[a] += partial[ic, a]
    for i in range(3):
        out[O_STRESS + i] = scale * s[I_F + i]
    for i in range(9):
        out[O_TANGENT + i] = scale * s[I_T + i]
    for m in range(6):
        i, j = _FF_PAIRS[m]
        c = (s[I_FF + m] - s[I_F + i] * s[I_F + j] / n) / (n - 1) * scale * scale * n if n > 1 else 0.0
        out[O_COV + 3 * i + j] = c
        out[O_COV + 3 * j + i] = c
    for i in range(3):
        c = out[O_COV + 4 * i]
        out[O_SE + i] = math.sqrt(c) if c > 0.0 or c != c else 0.0
    n_contact = round(s[I_NC])
    out[O_NC] = n_contact
    out[O_NS] = round(s[I_NS])
    out[O_NP] = round(s[I_NP])
    out[O_TH] = s[I_TH] / n_contact if n_contact else 0.0


@numba.njit(cache=True)
def paper_bounds(r, R_min, r_o, k_e, beta, delta, theta_birth):
    """(n_active, tan_max) of the kernels at delta: :func:`~asperity_sim.population.reach` and tan of its angle.

    ``theta_birth`` as in :func:`assemble_paper` (its largest frozen angle raises the bound).
    The kernels themselves are called from Python: calling them from here would compile the
    serial and the parallel kernel into this function too (twice the first-run JIT time).
    """
    theta_max = 0.0
    for tb in theta_birth:
        if tb > theta_max:  # NaN (no committed contact) never is
            theta_max = tb
    n_active, theta = reach(r, R_min, r_o, k_e, beta, delta[0], delta[1], delta[2], theta_max)
    return n_active, math.inf if theta >= 0.5 * math.pi - 1e-9 else math.tan(theta)


@numba.njit(cache=True, inline="always")
def fresh_spacing(r_j, R_j, dn_cap, k):
    """Spring spacing of an asperity without history: covers delta_n up to 2 max(dn_cap - r, dn_cap/10)."""
    return math.sqrt(2.0 * R_j * max(dn_cap - r_j, 0.1 * dn_cap)) / k


@numba.njit(cache=True, inline="always")
def committed_overlap(j, r, u, inv_R, cp, sp, delta_c, r_o, k_e):
    """delta_n of asperity j at the committed displacement, at its follow angle (no history)."""
    closure_c, _ = closure_and_slope(r_o, delta_c[0])
    th_c, _ = asperity_theta(u[j], inv_R, closure_c, k_e, 0.0)
    dn_c, _, _ = local_displacement(delta_c[0] - r[j], delta_c[1], delta_c[2],
                                    math.cos(th_c), math.sin(th_c), cp, sp)
    return dn_c


@numba.njit(cache=True, inline="always")
def mdr_history(j, slot, w, h_slot, dn_c_slot, r, R, u, inv_R, cp, sp, delta_c, r_o, k_e, dn_cap, k):
    """(slot index or -1, n_hist, h, committed overlap) of asperity j."""
    sl = slot[j]
    if sl >= 0:
        dn_c = dn_c_slot[sl]
        return sl, (k if dn_c > 0.0 else 0), h_slot[sl], dn_c
    return -1, 0, fresh_spacing(r[j], R[j], dn_cap, k), committed_overlap(j, r, u, inv_R, cp, sp, delta_c, r_o, k_e)


@numba.njit(cache=True, parallel=True)
def assemble_mdr(r, R, u, cos_phi, sin_phi, n_active, delta, delta_c, r_o, k_e, E_star, lam, mu, theta_birth,
                 slot, w, h_slot, dn_c_slot, dn_cap, partial):
    """Partial sums for the ``mdr`` law: trial springs from the committed history, never written.

    ``slot[j]`` indexes the history arrays (w (m, k, 2), h_slot, dn_c_slot) of asperity j
    or is -1 (no history: a fresh contact with spacing :func:`fresh_spacing`).
    """
    d1, d2, d3 = delta[0], delta[1], delta[2]
    D0, D1, D2 = d1 - delta_c[0], d2 - delta_c[1], d3 - delta_c[2]
    closure, dc = closure_and_slope(r_o, d1)
    has_birth = theta_birth.size > 0
    k = w.shape[1]
    no_write = np.empty((0, 2))
    n_chunks = (n_active + CHUNK - 1) // CHUNK
    for ic in numba.prange(n_chunks):
        acc = np.zeros(N_ACC)
        J = np.zeros((3, 3))
        for j in range(ic * CHUNK, min(n_active, (ic + 1) * CHUNK)):
            cp, sp = cos_phi[j], sin_phi[j]
            inv_R = 1.0 / R[j]
            th, th1 = contact_angle(j, r, u, inv_R, cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth, has_birth)
            ct, st = math.cos(th), math.sin(th)
            dn, ds, dt = local_displacement(d1 - r[j], d2, d3, ct, st, cp, sp)
            if dn <= 0.0:
                continue
            rho, dds, ddt = local_displacement(D0, D1, D2, ct, st, cp, sp)
            sl, n_hist, h, dn_c = mdr_history(j, slot, w, h_slot, dn_c_slot, r, R, u, inv_R, cp, sp,
                                              delta_c, r_o, k_e, dn_cap, k)
            w_c = w[sl] if sl >= 0 else w[0]
            f_n, f_s, f_t, _, _, state, _, _, _ = mdr_springs(
                dn, dds, ddt, dn_c, w_c, n_hist, h, R[j], E_star, lam, mu, J, no_write)
            accumulate(acc, ct, st, cp, sp, f_n, f_s, f_t, J, ds, rho, th1, state)
            acc[20] += th
        partial[ic, :] = acc


@numba.njit(cache=True, parallel=True)
def birth_angles(r, R, u, cos_phi, sin_phi, n_active, delta, r_o, k_e, theta_birth):
    """Commit the birth angles at delta (policy ``birth``, SPEC §3), in place.

    A committed contact that stays in contact keeps its angle; one that leaves contact is
    released (NaN) and, like every asperity without an angle, is born at its current
    ``follow`` angle if it touches there.  Asperities beyond n_active are out of contact.
    """
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure = max(r_o + d1, 0.0)
    for j in numba.prange(theta_birth.size):
        if j >= n_active:
            theta_birth[j] = np.nan
            continue
        shear = cos_phi[j] * d2 + sin_phi[j] * d3
        tb = theta_birth[j]
        if not math.isnan(tb) and math.cos(tb) * (d1 - r[j]) + math.sin(tb) * shear > 0.0:
            continue
        th, _ = asperity_theta(u[j], 1.0 / R[j], closure, k_e, 0.0)
        if math.cos(th) * (d1 - r[j]) + math.sin(th) * shear > 0.0:
            theta_birth[j] = th
        else:
            theta_birth[j] = np.nan


@dataclass(frozen=True)
class Evaluation:
    """Interface response at one displacement (SPEC §6).

    stress (3,) [Pa], stderr (3,) [Pa] (Monte Carlo standard error of each component),
    covariance (3, 3) [Pa²] (Monte Carlo covariance of the stress estimate), tangent (3, 3) [Pa/m] (d sigma_i / d Delta_k), n_contact and n_slip (asperity counts),
    mean_theta [rad] (mean orientation of the contacts; 0 when none), n_active (asperities
    that could touch and were visited).
    """

    delta: np.ndarray
    stress: np.ndarray
    stderr: np.ndarray
    covariance: np.ndarray
    tangent: np.ndarray
    n_contact: int
    n_slip: int
    n_partial: int
    mean_theta: float
    n_active: int


def check_delta(delta) -> np.ndarray:
    d = np.asarray(delta, dtype=float)
    if d.shape != (3,):
        raise ValueError(f"delta = {delta!r} must have shape (3,) [m], got shape {d.shape}")
    if not all(map(math.isfinite, d.tolist())):
        raise ValueError(f"delta = {d!r} [m] is not finite (valid range: finite reals)")
    return d


def check_choice(name, value, valid):
    if value not in valid:
        raise ValueError(f"{name} = {value!r} is not known (valid: {', '.join(valid)})")


class Workspace:
    """Preallocated partial-sum buffer for one population (a Newton iteration allocates nothing)."""

    def __init__(self, n):
        self.partial = np.zeros(((n + CHUNK - 1) // CHUNK, N_ACC))


_EMPTY = np.empty(0)


def evaluate(pop, delta, law="paper", policy="follow", theta_birth=None, workspace=None,
             history=None) -> Evaluation:
    """Evaluate Eq. (23) and its tangent over a population at interface displacement delta [m].

    Under policy ``birth`` the committed birth angles ``theta_birth`` (NaN where not in
    contact) are used; without them every contact is born now, which equals ``follow``.
    Law ``mdr`` reads the committed springs of ``history`` (a :class:`~asperity_sim.state.MDRHistory`;
    default: a virgin interface at Delta = 0) and never changes them.
    """
    if not isinstance(pop, Population):
        raise ValueError(f"pop = {pop!r} is not a Population")
    d = check_delta(delta)
    check_choice("law", law, LAWS)
    check_choice("policy", policy, POLICIES)
    if workspace is not None and (not isinstance(workspace, Workspace)
                                  or workspace.partial.shape[0] * CHUNK < pop.n):
        raise ValueError(f"workspace = {workspace!r} is not a Workspace for {pop.n} asperities (use Workspace(pop.n))")
    tb = None
    if policy == "birth" and theta_birth is not None:
        tb = np.asarray(theta_birth, dtype=float)
        if tb.shape != (pop.n,):
            raise ValueError(f"theta_birth has shape {tb.shape}, expected ({pop.n},)")
    ws = workspace if workspace is not None else Workspace(pop.n)
    return evaluate_unchecked(pop, d, law, tb, ws, history)


def evaluate_unchecked(pop, d, law, theta_birth, workspace, history) -> Evaluation:
    """:func:`evaluate` on arguments already checked (for a solver that calls it many times).

    ``d`` a finite float array (3,), ``law`` valid, ``theta_birth`` None (every contact born
    now) or a float array (n,), ``workspace`` a :class:`Workspace` for ``pop``.
    """
    tb = _EMPTY if theta_birth is None else theta_birth
    out = np.empty(N_OUT)
    r_o, k_e, E_star, lam, mu, beta, scale = pop.kernel_constants
    serial = law == "paper" and pop.n <= SERIAL_CHUNKS * CHUNK  # then n_active is small too: no bounds needed here
    if not serial:
        n_active, tan_max = paper_bounds(pop.r, pop.R_min, r_o, k_e, beta, d, tb)
        serial = law == "paper" and n_active <= SERIAL_CHUNKS * CHUNK
    if serial:  # the serial kernel finds its own bounds
        assemble_paper_serial(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, pop.R_min, _row(d), r_o, k_e,
                              E_star, lam, mu, beta, tb, pop.n, scale, workspace.partial, out.reshape(1, N_OUT))
        return evaluation_from(d, out)
    if law == "paper":
        assemble_paper(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, n_active, d, r_o, k_e, E_star, lam, mu, tb,
                       tan_max, workspace.partial)
    else:
        if history is None:
            from .state import MDRHistory

            history = MDRHistory.virgin(pop, dn_cap=max(d[0], beta))
        hs = history
        assemble_mdr(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, n_active, d, hs.delta_c,
                     r_o, k_e, E_star, lam, mu, tb, hs.slot, hs.w, hs.h, hs.dn_c, hs.dn_cap,
                     workspace.partial)
    finish(workspace.partial, (n_active + CHUNK - 1) // CHUNK, pop.n, scale, out)
    out[O_NA] = n_active
    return evaluation_from(d, out)


def _row(d):
    """d (3,) as a C-contiguous (1, 3) view or copy: the one array layout the serial kernel is compiled for."""
    return np.ascontiguousarray(d).reshape(1, 3)


def evaluate_steps(pop, deltas, workspace) -> np.ndarray:
    """Flat results (m, N_OUT) of the ``paper`` law under policy follow at each row of ``deltas`` (m, 3) [m].

    One call of the serial kernel (:func:`assemble_paper_serial`) for all rows, each
    bit-identical to :func:`evaluate` there; meant for small populations, where the per-call
    overhead of :func:`evaluate` exceeds the kernel time.  Read a row with
    :func:`evaluation_from`.  ``deltas`` finite and C-contiguous, ``workspace`` a
    :class:`Workspace` for ``pop``.
    """
    r_o, k_e, E_star, lam, mu, beta, scale = pop.kernel_constants
    out = np.empty((deltas.shape[0], N_OUT))
    assemble_paper_serial(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, pop.R_min, deltas, r_o, k_e, E_star, lam,
                          mu, beta, _EMPTY, pop.n, scale, workspace.partial, out)
    return out


def evaluation_from(d, out) -> Evaluation:
    """The :class:`Evaluation` at ``d`` from one flat result row ``out`` (N_OUT,) of :func:`finish`."""
    return Evaluation(
        delta=d,
        stress=out[O_STRESS:O_STRESS + 3],
        stderr=out[O_SE:O_SE + 3],
        covariance=out[O_COV:O_COV + 9].reshape(3, 3),
        tangent=out[O_TANGENT:O_TANGENT + 9].reshape(3, 3),
        n_contact=int(out[O_NC]),
        n_slip=int(out[O_NS]),
        n_partial=int(out[O_NP]),
        mean_theta=float(out[O_TH]),
        n_active=int(out[O_NA]),
    )


def sqrt_nonneg(x: float) -> float:
    """sqrt(max(x, 0)) as numpy computes it: NaN stays NaN, -0.0 gives 0.0."""
    return math.sqrt(x) if x > 0.0 or x != x else 0.0


@numba.njit(cache=True, parallel=True)
def asperity_snapshot(r, R, u, cos_phi, sin_phi, delta, r_o, k_e, E_star, lam, mu, theta_birth,
                      delta_n_out, theta_out, force_out, state_out):
    """Per-asperity overlap, orientation, global force and state code (0 out, 1 stick, 2 partial, 3 slip)."""
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure = max(r_o + d1, 0.0)
    has_birth = theta_birth.size > 0
    for j in numba.prange(r.size):
        cp, sp = cos_phi[j], sin_phi[j]
        th, _ = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, 0.0, theta_birth, has_birth)
        ct, st = math.cos(th), math.sin(th)
        dn, ds, dt = local_displacement(d1 - r[j], d2, d3, ct, st, cp, sp)
        delta_n_out[j] = dn
        theta_out[j] = th
        if dn <= 0.0:
            force_out[j, 0] = 0.0
            force_out[j, 1] = 0.0
            force_out[j, 2] = 0.0
            state_out[j] = 0
            continue
        f_n, f_s, f_t, _, _, _, _, slip = paper_local(dn, ds, dt, math.sqrt(R[j]), E_star, lam, mu)
        force_out[j, 0] = f_n * ct - f_s * st
        force_out[j, 1] = f_n * st * cp + f_s * ct * cp - f_t * sp
        force_out[j, 2] = f_n * st * sp + f_s * ct * sp + f_t * cp
        if slip:
            state_out[j] = 3
        elif ds == 0.0 and dt == 0.0:
            state_out[j] = 1
        else:
            state_out[j] = 2


def snapshot(pop, delta, policy="follow", theta_birth=None):
    """Per-asperity arrays at delta: dict of delta_n [m], theta [rad], force (n, 3) [N], state code."""
    d = check_delta(delta)
    p = pop.params
    tb = np.asarray(theta_birth, dtype=float) if (policy == "birth" and theta_birth is not None) else _EMPTY
    out = {
        "delta_n": np.empty(pop.n), "theta": np.empty(pop.n),
        "force": np.empty((pop.n, 3)), "state": np.empty(pop.n, dtype=np.int8),
    }
    asperity_snapshot(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, d, p.r_o, p.k_e, p.E_star, p.lam, p.mu,
                      tb, out["delta_n"], out["theta"], out["force"], out["state"])
    return out
