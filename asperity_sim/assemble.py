"""Generic reductions over asperities: stress, standard error, tangent and counts (SPEC §6).

Owns the assembly of Eq. (23) as a Monte Carlo sum, sigma_i = N w sum_j f_ij, and of its
exact tangent T_ik = d sigma_i / d Delta_k, for any registered law (:mod:`asperity_sim.laws`):
orientations, local frames, which asperities may touch, the sums and their statistics live
here; the contact physics comes from the law's kernels.  The kernels loop over fixed-size
chunks under ``prange`` and each chunk writes its partial sums to its own row of a
caller-owned array, summed in order by :func:`finish`, so a result does not depend on the
number of threads.

Which asperities are visited.  The population is sorted by height: only the first
``n_active`` (:func:`bounds`) can touch.  Among them, under policy follow, the asperities
that cannot touch at their own largest angle are dropped by :func:`may_touch_follow` before
any trigonometry.

- A path-independent law under policy follow: a branch-free block loop that LLVM vectorises
  (:func:`values_follow`: series trigonometry and the law's branch-free kernel); small
  workloads run on the calling thread (``reduce_serial``, also for a batch of displacements).
  Policy birth: a scalar loop with the frozen angles (``chunk_birth``).
- A history law: one pass over the committed contacts (their slots, streamed in slot order,
  ``slot_pass``) and one for contacts that are new in this trial (``fresh_pass``, which skips
  committed contacts by their flag).  The second tests only the asperities that the
  :class:`Workspace` lists as able to touch somewhere in a box of displacements around the
  path (:func:`may_touch_within`; the list is made by the first trial outside the box), so an
  asperity out of reach costs nothing per trial.  The commit (:mod:`asperity_sim.state`)
  makes the same two passes, writing, and takes from the workspace what the trial at its
  displacement found: where the new contacts are and the geometry of the committed ones.

Each law gets its own compiled copy of these kernels (:func:`kernels`,
:func:`asperity_sim.laws.specialise`).  No fastmath anywhere: vector and scalar code give the
same bits, and a result is the same whether its kernels were compiled or loaded from cache.

Tangent of one contact (:func:`accumulate`), with Q = [n; s; t] (rows), the law's local
Jacobian J and theta_1 = d theta / d Delta_1 (policy follow only; SPEC §3):

    d f / d Delta = Q^T J K + (f_n s - f_s n) theta_1 e_1^T

where K = d(delta_n, a_s, a_t)/d Delta has rows n + delta_s theta_1 e_1, s - rho theta_1 e_1
and t, (a_s, a_t) the law's tangential variables (totals, rho = delta_n; or increments since
the committed state, rho = n.dDelta), using dn/dtheta = s, ds/dtheta = -n, dt/dtheta = 0.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numba
import numpy as np

from . import laws
from .geometry import acos_unit, fsqrt, local_displacement, sin_cos_quarter, theta_m_and_slope
from .population import Population, reach

CHUNK = 2048
SERIAL_CHUNKS = 16  # up to this many chunks (32768 asperities that can touch) a path-independent law runs serially
# layout of one row of partial sums: forces (3), products f_i f_j (11, 22, 33, 12, 13, 23),
# tangent (9), contact and full-slip counts, sum of theta over contacts, partial-slip count
I_F, I_FF, I_T, I_NC, I_NS, I_TH, I_NP = 0, 3, 9, 18, 19, 20, 21
N_ACC = 22
_FF_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))  # (i, j) of the products f_i f_j, in their order
POLICIES = ("follow", "birth")


@numba.njit(cache=True, inline="always")
def asperity_theta(u_j, inv_R, closure, k_e, dclosure_d1):
    """Physical meridional angle theta = (2/pi) u theta_m(c, R) and d theta/d Delta_1 (SPEC §3)."""
    th_m, slope = theta_m_and_slope(closure, inv_R, k_e)
    scale = u_j / (0.5 * math.pi)
    return scale * th_m, scale * slope * dclosure_d1


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
def accumulate(acc, ct, st, cp, sp, out, ds_tot, rho, th1):
    """Add one contact's global force, force products, tangent and counts to ``acc``."""
    g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8 = global_force_tangent(ct, st, cp, sp, out, ds_tot, rho, th1)
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
def may_touch_within(x_hi, s_hi, y_lo, y_hi, scale, tan_max):
    """False when the asperity cannot touch anywhere in a box of displacements, tested without trigonometry.

    delta_n = cos(theta) x + sin(theta) s grows with x = Delta_1 - r and with s = cos(phi) Delta_2
    + sin(phi) Delta_3 (theta in [0, pi/2]), and theta = scale theta_m grows with the closure, so
    over the box delta_n <= cos(theta) x_hi + sin(theta) s_hi with theta between its values at
    the box's smallest and largest closure, where y = cos(theta_m) = 1 - k_e c / R_j (Eq. 9,
    before clipping) is ``y_lo`` and ``y_hi``.  ``tan_max`` bounds tan theta of every asperity
    at the largest closure (:func:`cannot_touch`).

    - x_hi <= 0: contact needs s_hi > 0 and tan(theta) > -x_hi / s_hi.  tan is convex on
      [0, pi/2) with tan 0 = 0, hence tan(theta) <= scale tan(theta_m): contact is impossible
      when scale² (1 - y²) s_hi² < x_hi² y² at y = y_hi (0 < y < 1; y >= 1 means theta_m = 0
      and y <= 0 gives no bound).
    - x_hi > 0: a shear away from the asperity (s_hi < 0) lifts it off when tan(theta) >= x_hi /
      -s_hi at the least angle.  acos y = 2 asin sqrt((1 - y)/2) >= sqrt(2 (1 - y)) and tan t >= t,
      so tan(theta) >= scale sqrt(2 (1 - y)) at y = y_lo clipped to [0, 1]: contact is
      impossible when 2 scale² (1 - y_lo) s_hi² > x_hi².

    The relative margins 1e-9 keep the tests on the safe side of round-off.
    """
    sh2 = s_hi * s_hi
    by_angle = ~(-x_hi > s_hi * tan_max * (1.0 + 1e-9))
    by_own = (y_hi <= 0.0) | ((y_hi < 1.0) & ~(scale * scale * (1.0 - y_hi * y_hi) * sh2 * (1.0 + 1e-9)
                                              < x_hi * x_hi * y_hi * y_hi))
    yc = 0.0 if y_lo < 0.0 else (1.0 if y_lo > 1.0 else y_lo)
    lifted = (s_hi < 0.0) & (2.0 * scale * scale * (1.0 - yc) * sh2 > x_hi * x_hi * (1.0 + 1e-9))
    return ((x_hi > 0.0) & ~lifted) | ((s_hi > 0.0) & by_angle & by_own)


@numba.njit(cache=True, inline="always", error_model="numpy")
def may_touch_follow(x, shear_ph, y, scale, tan_max):
    """False when the asperity cannot touch at one displacement under policy follow (no trigonometry, no branch).

    :func:`may_touch_within` for a box that is a point: ``x`` = Delta_1 - r, ``shear_ph`` =
    cos(phi) Delta_2 + sin(phi) Delta_3, ``y`` = cos(theta_m(c, R_j)) = 1 - k_e c / R_j,
    ``scale`` = 2 u_j / pi, so theta = scale theta_m in [0, pi/2].
    """
    return may_touch_within(x, shear_ph, y, y, scale, tan_max)


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



# layout of the flat result of :func:`finish` (one float array per evaluation)
O_STRESS, O_TANGENT, O_COV, O_SE, O_NC, O_NS, O_NP, O_TH, O_NA = 0, 3, 12, 21, 24, 25, 26, 27, 28
N_OUT = 29

@numba.njit(cache=True, inline="always")
def committed_overlap(j, r, u, inv_R, cp, sp, delta_c, r_o, k_e):
    """delta_n of asperity j at displacement ``delta_c`` (the committed one, or a reference), at its follow angle."""
    closure_c, _ = closure_and_slope(r_o, delta_c[0])
    th_c, _ = asperity_theta(u[j], inv_R, closure_c, k_e, 0.0)
    dn_c, _, _ = local_displacement(delta_c[0] - r[j], delta_c[1], delta_c[2], math.cos(th_c), math.sin(th_c), cp, sp)
    return dn_c


@numba.njit(cache=True)
def bounds(r, R_min, r_o, k_e, beta, delta, theta_birth):
    """(n_active, tan_max): :func:`~asperity_sim.population.reach` at delta and tan of its angle bound.

    ``theta_birth`` (empty under policy follow) raises the bound by its largest frozen angle.
    """
    theta_max = 0.0
    for tb in theta_birth:
        if tb > theta_max:  # NaN (no committed contact) never is
            theta_max = tb
    n_active, theta = reach(r, R_min, r_o, k_e, beta, delta[0], delta[1], delta[2], theta_max)
    return n_active, math.inf if theta >= 0.5 * math.pi - 1e-9 else math.tan(theta)


# per-asperity values of the vectorised follow loop, one row of BLOCK each: global force (3), tangent
# (9, row-major), contact, full slip, partial slip (0 or 1) and theta of a contact
V_G, V_T, V_NC, V_NS, V_NP, V_TH = 0, 3, 12, 13, 14, 15
N_VAL = 16
BLOCK = 256  # asperities per block (16 x 256 doubles of values = 32 KiB)
# inputs of one block, one row of BLOCK each: Delta_1 - r, cos phi, sin phi, R, u
X_X, X_CP, X_SP, X_R, X_U = 0, 1, 2, 3, 4
N_IN = 5


# per-slot geometry of a block of committed contacts, one row of BLOCK each: inputs (Delta_1 - r, cos phi,
# sin phi, R, u), then delta_n, delta_s, the local increment (normal, s, t), cos/sin theta, theta, d theta/d Delta_1
G_X, G_CP, G_SP, G_R, G_U, G_DN, G_DS, G_RHO, G_DDS, G_DDT, G_CT, G_ST, G_TH, G_TH1 = range(14)
N_GEO = 14
# what a commit needs of that geometry, left by the trial per slot: delta_n, the increment (s, t), R
SLOT_GEO_ROWS = (G_DN, G_DDS, G_DDT, G_R)
N_SLOT_GEO = len(SLOT_GEO_ROWS)


@numba.njit(cache=True, inline="always")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
def store_values(vals, i, touch, code, th, g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8):
    """Column i of ``vals``: global force, tangent, counts and angle of one asperity; zeros out of contact
    (selects, so that the loop stays vectorised)."""
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


@numba.njit(cache=True, inline="always", error_model="numpy")
def slot_values(vals, i, geo, out):
    """Column i of ``vals`` (as :func:`values_follow`) from the law's values ``out`` of a committed contact."""
    touch = geo[G_DN, i] > 0.0
    o = (out[0, i], out[1, i], out[2, i], out[3, i], out[4, i], out[5, i], out[6, i], out[7, i], out[8, i],
         out[9, i], out[10, i], out[11, i], out[12, i])
    g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8 = global_force_tangent(
        geo[G_CT, i], geo[G_ST, i], geo[G_CP, i], geo[G_SP, i], o, geo[G_DS, i], geo[G_RHO, i], geo[G_TH1, i])
    code = out[12, i]
    store_values(vals, i, touch, code, geo[G_TH, i], g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8)


@numba.njit(cache=True, inline="always")
def add_values(vals, m, acc):
    """Add columns 0..m of ``vals`` to the sums ``acc`` (N_ACC), in order."""
    F0, F1, F2 = acc[I_F], acc[I_F + 1], acc[I_F + 2]
    P00, P11, P22, P01, P02, P12 = acc[I_FF], acc[I_FF + 1], acc[I_FF + 2], acc[I_FF + 3], acc[I_FF + 4], acc[I_FF + 5]
    T0, T1, T2, T3, T4 = acc[I_T], acc[I_T + 1], acc[I_T + 2], acc[I_T + 3], acc[I_T + 4]
    T5, T6, T7, T8 = acc[I_T + 5], acc[I_T + 6], acc[I_T + 7], acc[I_T + 8]
    n_c, n_s, n_p, th_sum = acc[I_NC], acc[I_NS], acc[I_NP], acc[I_TH]
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
    acc[I_F], acc[I_F + 1], acc[I_F + 2] = F0, F1, F2
    acc[I_FF], acc[I_FF + 1], acc[I_FF + 2], acc[I_FF + 3], acc[I_FF + 4], acc[I_FF + 5] = P00, P11, P22, P01, P02, P12
    acc[I_T], acc[I_T + 1], acc[I_T + 2], acc[I_T + 3], acc[I_T + 4] = T0, T1, T2, T3, T4
    acc[I_T + 5], acc[I_T + 6], acc[I_T + 7], acc[I_T + 8] = T5, T6, T7, T8
    acc[I_NC], acc[I_NS], acc[I_NP], acc[I_TH] = n_c, n_s, n_p, th_sum


# ---- templates: compiled once per law by :func:`kernels` (the names ``local``, ``trial`` and
# ``commit_law`` are the law's kernels there; each template name is its own compiled copy) ----

def values_follow(vals, i, x, cp, sp, R_j, u_j, d2, d3, closure, dc, k_e, consts):
    """Column i of ``vals``: force, tangent and counts of one asperity under policy follow, branch-free.

    ``x`` = Delta_1 - r.  :func:`accumulate` for a path-independent law, written with selects
    instead of branches and series trigonometry instead of libm, so that the loop vectorises.
    An asperity out of contact gets zeros.
    """
    shear_ph = cp * d2 + sp * d3
    dt = -sp * d2 + cp * d3
    th, st, ct, inv_R, y, yc, scale = follow_angle(R_j, u_j, closure, k_e)
    dn = ct * x + st * shear_ph
    ds = -st * x + ct * shear_ph
    touch = dn > 0.0
    th1 = follow_slope(touch, y, yc, scale, k_e, inv_R, dc)
    out = local(dn if touch else 1.0, ds, dt, R_j, consts)
    code = out[12]
    g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8 = global_force_tangent(ct, st, cp, sp, out, ds, dn, th1)
    store_values(vals, i, touch, code, th, g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8)


def chunk_follow(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, tan_max, partial):
    """Row ic of ``partial`` under policy follow: :func:`values_follow` over the asperities that may touch.

    Per block of BLOCK asperities: unless the whole block lies below the closure, a loop that
    LLVM vectorises marks the asperities :func:`may_touch_follow` keeps (no trigonometry, no
    branch), a scalar pass lists them and copies their inputs, contiguous, into ``inp``;
    :func:`values_follow` fills ``vals`` in a loop that LLVM vectorises; the columns are
    summed in order (no fastmath: the same bits however LLVM vectorised).
    """
    lo, hi = ic * CHUNK, min(n_active, (ic + 1) * CHUNK)
    vals = np.empty(N_VAL * BLOCK)
    inp = np.empty(N_IN * BLOCK)
    kept = np.empty(BLOCK, dtype=np.int64)
    at = np.empty(BLOCK, dtype=np.int64)
    acc = np.zeros(N_ACC)
    for b0 in range(lo, hi, BLOCK):
        b1 = min(hi, b0 + BLOCK)
        if d1 > r[b1 - 1]:  # the whole block lies below the closure: every asperity may touch
            m = b1 - b0
            for i in range(m):
                values_follow(vals, i, d1 - r[b0 + i], cos_phi[b0 + i], sin_phi[b0 + i], R[b0 + i], u[b0 + i],
                              d2, d3, closure, dc, k_e, consts)
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
            for i in range(m):
                values_follow(vals, i, inp[X_X * BLOCK + i], inp[X_CP * BLOCK + i], inp[X_SP * BLOCK + i],
                              inp[X_R * BLOCK + i], inp[X_U * BLOCK + i], d2, d3, closure, dc, k_e, consts)
        add_values(vals, m, acc)
    partial[ic, :] = acc


def chunk_birth(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, theta_birth, tan_max,
                partial):
    """Row ic of ``partial`` under policy birth: frozen angles where a committed contact lasts, scalar libm loop."""
    acc = np.zeros(N_ACC)
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
        accumulate(acc, ct, st, cp, sp, local(dn, ds, dt, R[j], consts), ds, dn, th1)
        acc[I_TH] += th
    partial[ic, :] = acc


def chunk_any(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, theta_birth, has_birth,
              tan_max, partial):
    """Row ic of ``partial`` for a path-independent law, by policy."""
    if has_birth:
        chunk_birth(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, theta_birth,
                    tan_max, partial)
    else:
        chunk_follow(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, tan_max, partial)


def reduce_parallel(r, R, u, cos_phi, sin_phi, n_active, delta, r_o, k_e, consts, theta_birth, tan_max, partial):
    """Partial sums of a path-independent law over the first n_active asperities, chunks in parallel.

    Chunks go to the threads in the strided order of :func:`chunk_stride`, so both threads
    get low (in contact, costly) and high (cheap) heights; rows are overwritten.
    """
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, dc = closure_and_slope(r_o, d1)
    has_birth = theta_birth.size > 0
    n_chunks = (n_active + CHUNK - 1) // CHUNK
    stride = chunk_stride(n_chunks)
    for kk in numba.prange(n_chunks):
        chunk_any((kk * stride) % n_chunks, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts,
                  theta_birth, has_birth, tan_max, partial)


def reduce_serial(r, R, u, cos_phi, sin_phi, R_min, deltas, r_o, k_e, consts, beta, theta_birth, n, scale, partial,
                  out):
    """The flat result (:func:`finish`) at every row of ``deltas`` (m, 3), on the calling thread.

    The same rows of partial sums as :func:`bounds` + ``reduce_parallel`` + :func:`finish`, so
    the same bits.  For small workloads: a parallel region costs tens of microseconds on an
    idle machine and milliseconds on a loaded one, and the increments of a
    displacement-controlled stage of a path-independent law are independent, so a small
    population need not pay a round trip through Python for each of them.
    """
    has_birth = theta_birth.size > 0
    for i in range(deltas.shape[0]):
        d1, d2, d3 = deltas[i, 0], deltas[i, 1], deltas[i, 2]
        n_active, tan_max = bounds(r, R_min, r_o, k_e, beta, deltas[i], theta_birth)
        closure, dc = closure_and_slope(r_o, d1)
        n_chunks = (n_active + CHUNK - 1) // CHUNK
        for ic in range(n_chunks):
            chunk_any(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, theta_birth,
                      has_birth, tan_max, partial)
        finish(partial, n_chunks, n, scale, out[i])
        out[i, O_NA] = n_active


def snapshot_local(r, R, u, cos_phi, sin_phi, delta, r_o, k_e, consts, theta_birth, delta_n_out, theta_out,
                   force_out, state_out):
    """Per-asperity overlap, orientation, global force and state code of a path-independent law."""
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
        f_n = f_s = f_t = 0.0
        code = 0
        if dn > 0.0:
            out = local(dn, ds, dt, R[j], consts)
            f_n, f_s, f_t, code = out[0], out[1], out[2], int(out[12])
        force_out[j, 0] = f_n * ct - f_s * st
        force_out[j, 1] = f_n * st * cp + f_s * ct * cp - f_t * sp
        force_out[j, 2] = f_n * st * sp + f_s * ct * sp + f_t * cp
        state_out[j] = code


# ---- history laws: committed contacts live in slots (asp[sl] = asperity index, -1 a free slot) ----

def slot_pass(asp, n_slots, dn_c, r, R, u, cos_phi, sin_phi, delta, delta_c, r_o, k_e, consts, arrays,
              theta_birth, partial, slot_geo):
    """Rows 0.. of ``partial``: the committed contacts at the trial displacement, from their history (read only).

    Under policy follow, per block of BLOCK slots: their inputs gathered contiguous, their
    geometry in a loop that LLVM vectorises (:func:`slot_geometry`), the law's trial per contact,
    then their global force and tangent in a vectorised loop and the sums in slot order.  The
    geometry the law needs (delta_n, the increment, R) is left in ``slot_geo`` (N_SLOT_GEO, >=
    n_slots), for a commit at this displacement (:func:`commit_slots`).
    """
    d1, d2, d3 = delta[0], delta[1], delta[2]
    D0, D1, D2 = d1 - delta_c[0], d2 - delta_c[1], d3 - delta_c[2]
    closure, dc = closure_and_slope(r_o, d1)
    has_birth = theta_birth.size > 0
    n_chunks = (n_slots + CHUNK - 1) // CHUNK
    stride = chunk_stride(n_chunks)  # slots follow the heights: spread the large contacts over the threads
    for kk in numba.prange(n_chunks):
        ic = (kk * stride) % n_chunks
        acc = np.zeros(N_ACC)
        lo, hi = ic * CHUNK, min(n_slots, (ic + 1) * CHUNK)
        if has_birth:
            for sl in range(lo, hi):
                j = asp[sl]
                if j < 0:
                    continue
                cp, sp = cos_phi[j], sin_phi[j]
                th, th1 = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth,
                                        has_birth)
                ct, st = math.cos(th), math.sin(th)
                dn, ds, dt = local_displacement(d1 - r[j], d2, d3, ct, st, cp, sp)
                if dn <= 0.0:
                    continue
                rho, dds, ddt = local_displacement(D0, D1, D2, ct, st, cp, sp)
                accumulate(acc, ct, st, cp, sp, trial(dn, dds, ddt, dn_c[sl], 0.0, R[j], consts, arrays, sl, False),
                           ds, rho, th1)
                acc[I_TH] += th
            partial[ic, :] = acc
            continue
        geo = np.empty((N_GEO, BLOCK))
        out = np.empty((13, BLOCK))
        vals = np.empty(N_VAL * BLOCK)
        for b0 in range(lo, hi, BLOCK):
            m = min(hi, b0 + BLOCK) - b0
            gather_slots(geo, asp, b0, m, d1, r, R, u, cos_phi, sin_phi)
            for i in range(m):  # vectorised
                slot_geometry(geo, i, d2, d3, D0, D1, D2, closure, dc, k_e)
            for a in range(N_SLOT_GEO):
                for i in range(m):
                    slot_geo[a, b0 + i] = geo[SLOT_GEO_ROWS[a], i]
            trial_block(geo[G_DN], geo[G_DDS], geo[G_DDT], geo[G_R], dn_c, b0, m, consts, arrays, out)  # the law
            for i in range(m):  # vectorised
                slot_values(vals, i, geo, out)
            add_values(vals, m, acc)
        partial[ic, :] = acc


def each_contact(dn, dds, ddt, R, dn_c, b0, m, consts, arrays, out):
    """The law's ``trial_block`` for a law without one: ``trial`` of each committed contact in contact."""
    for i in range(m):
        if dn[i] > 0.0:
            o = trial(dn[i], dds[i], ddt[i], dn_c[b0 + i], 0.0, R[i], consts, arrays, b0 + i, False)
            for a in range(13):
                out[a, i] = o[a]
        else:
            for a in range(13):
                out[a, i] = 0.0


def each_commit(dn, dds, ddt, R, dn_c, b0, m, live, consts, arrays, scratch, res):
    """The law's ``commit_block`` for a law without one: ``commit`` of each live committed contact."""
    for i in range(m):
        if live[i]:
            code, work, stored, diss, events = commit_law(dn[i], dds[i], ddt[i], dn_c[b0 + i], 0.0, R[i], consts,
                                                          arrays, b0 + i, False, scratch)
            res[0, i], res[1, i], res[2, i], res[3, i], res[4, i] = code, work, stored, diss, events


def fresh_pass(flag, n_active, r, R, u, cos_phi, sin_phi, delta, delta_c, delta_ref, r_o, k_e, consts, arrays, tan_max,
               partial, spans, index, listed, n_listed, box, n_box, tan_box):
    """Rows 0.. of ``partial``: asperities without a committed contact that touch at the trial displacement.

    They take their follow angle (SPEC §3) and start from no history; committed contacts are
    skipped by their flag, and the rest by :func:`may_touch_follow` before any trigonometry.
    ``spans`` (chunks, 2): per chunk, the asperities [first, last] + 1 found touching ((0, 0) if
    none), so that a commit at this displacement looks only there (:func:`find_fresh`).

    ``index`` 0: every asperity below n_active is tested.  1: the same, and every asperity
    below ``n_box`` that may touch somewhere in ``box`` (2, 3; :func:`may_touch_within`, with
    ``tan_box`` the angle bound there), committed or not, is listed in ``listed``: chunk ic's
    from position ic CHUNK on, in order, their count in ``n_listed[ic]``.  2: only the listed
    asperities are tested (the caller checked that the box holds delta).  The same asperities
    touch in the same order, so the sums have the same bits whatever the index.
    """
    d1, d2, d3 = delta[0], delta[1], delta[2]
    D0, D1, D2 = d1 - delta_c[0], d2 - delta_c[1], d3 - delta_c[2]
    closure, dc = closure_and_slope(r_o, d1)
    c_lo, _ = closure_and_slope(r_o, box[0, 0])
    c_hi, _ = closure_and_slope(r_o, box[1, 0])
    n_chunks = (n_active + CHUNK - 1) // CHUNK
    n_scan = (n_box + CHUNK - 1) // CHUNK if index == 1 else n_chunks
    stride = chunk_stride(n_scan)
    for kk in numba.prange(n_scan):
        ic = (kk * stride) % n_scan
        lo = ic * CHUNK
        hi = min(n_active, lo + CHUNK)
        acc = np.zeros(N_ACC)
        first, last = n_active, -1
        if index == 2:
            n_it = n_listed[ic]
        else:
            n_it = min(n_box if index == 1 else n_active, lo + CHUNK) - lo
        m = 0
        for t in range(n_it):
            j = listed[lo + t] if index == 2 else lo + t
            if index == 1:
                cp, sp = cos_phi[j], sin_phi[j]
                s_hi = max(cp * box[0, 1], cp * box[1, 1]) + max(sp * box[0, 2], sp * box[1, 2])
                inv_R = 1.0 / R[j]
                if not may_touch_within(box[1, 0] - r[j], s_hi, 1.0 - k_e * c_lo * inv_R, 1.0 - k_e * c_hi * inv_R,
                                        u[j] * (2.0 / math.pi), tan_box):
                    continue
                listed[lo + m] = j
                m += 1
            if j >= hi or flag[j]:
                continue
            cp, sp = cos_phi[j], sin_phi[j]
            x = d1 - r[j]
            inv_R = 1.0 / R[j]
            if not may_touch_follow(x, cp * d2 + sp * d3, 1.0 - k_e * closure * inv_R, u[j] * (2.0 / math.pi),
                                    tan_max):
                continue
            th, th1 = asperity_theta(u[j], inv_R, closure, k_e, dc)
            ct, st = math.cos(th), math.sin(th)
            dn, ds, dt = local_displacement(x, d2, d3, ct, st, cp, sp)
            if dn <= 0.0:
                continue
            first, last = min(first, j), j
            dn_c = committed_overlap(j, r, u, inv_R, cp, sp, delta_c, r_o, k_e)
            dn_ref = committed_overlap(j, r, u, inv_R, cp, sp, delta_ref, r_o, k_e)
            rho, dds, ddt = local_displacement(D0, D1, D2, ct, st, cp, sp)
            accumulate(acc, ct, st, cp, sp, trial(dn, dds, ddt, dn_c, dn_ref, R[j], consts, arrays, 0, True), ds, rho,
                       th1)
            acc[I_TH] += th
        if index == 1:
            n_listed[ic] = m
        if ic < n_chunks:
            partial[ic, :] = acc
            spans[ic, 0], spans[ic, 1] = (first, last + 1) if last >= 0 else (0, 0)


def commit_slots(asp, n_slots, dn_c, code, flag, r, R, u, cos_phi, sin_phi, delta, delta_c, r_o, k_e, consts, arrays,
                 theta_birth, n_store, partial, slot_geo):
    """Commit every committed contact at the converged ``delta``; sums (N_COMMIT) per chunk into ``partial``.

    A contact that is lost is released by the law, its slot freed (asp = -1) and its flag cleared.
    Under policy follow the geometry of a block of slots is computed as in :func:`slot_pass`, or
    read from ``slot_geo`` when a trial at ``delta`` on this committed state left it there (not
    empty; the same bits).
    """
    d1, d2, d3 = delta[0], delta[1], delta[2]
    D0, D1, D2 = d1 - delta_c[0], d2 - delta_c[1], d3 - delta_c[2]
    closure, dc = closure_and_slope(r_o, d1)
    has_birth = theta_birth.size > 0
    known = slot_geo.shape[1] > 0
    n_chunks = (n_slots + CHUNK - 1) // CHUNK
    stride = chunk_stride(n_chunks)  # slots follow the heights: spread the large contacts over the threads
    for kk in numba.prange(n_chunks):
        ic = (kk * stride) % n_chunks
        acc = np.zeros(N_COMMIT)
        work = stored = diss = events = 0.0
        scratch = np.zeros((2, 2 * n_store))  # the law's scratch: two rows of twice the stored springs
        geo = np.empty((N_GEO, BLOCK))
        live = np.empty(BLOCK, dtype=np.bool_)
        res = np.empty((5, BLOCK))
        lo, hi = ic * CHUNK, min(n_slots, (ic + 1) * CHUNK)
        for b0 in range(lo, hi, BLOCK):
            m = min(hi, b0 + BLOCK) - b0
            if has_birth:
                for i in range(m):
                    j = asp[b0 + i]
                    if j < 0:
                        continue
                    cp, sp = cos_phi[j], sin_phi[j]
                    th, _ = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth,
                                          has_birth)
                    ct, st = math.cos(th), math.sin(th)
                    geo[G_DN, i], _, _ = local_displacement(d1 - r[j], d2, d3, ct, st, cp, sp)
                    _, geo[G_DDS, i], geo[G_DDT, i] = local_displacement(D0, D1, D2, ct, st, cp, sp)
                    geo[G_R, i] = R[j]
            elif known:
                for a in range(N_SLOT_GEO):
                    for i in range(m):
                        geo[SLOT_GEO_ROWS[a], i] = slot_geo[a, b0 + i]
            else:
                gather_slots(geo, asp, b0, m, d1, r, R, u, cos_phi, sin_phi)
                for i in range(m):  # vectorised
                    slot_geometry(geo, i, d2, d3, D0, D1, D2, closure, dc, k_e)
            for i in range(m):
                live[i] = asp[b0 + i] >= 0
            commit_block(geo[G_DN], geo[G_DDS], geo[G_DDT], geo[G_R], dn_c, b0, m, live, consts, arrays, scratch, res)
            for i in range(m):
                sl = b0 + i
                j = asp[sl]
                if j < 0:
                    continue
                dn = geo[G_DN, i]
                new = int(res[0, i])
                work += res[1, i]
                stored += res[2, i]
                diss += res[3, i]
                events += res[4, i]
                acc[C_TR + 4 * code[sl] + new] += 1.0
                if dn <= 0.0:
                    asp[sl] = -1
                    flag[j] = 0
                    dn_c[sl] = 0.0
                    code[sl] = 0
                else:
                    dn_c[sl] = dn
                    code[sl] = new
        acc[C_WORK], acc[C_STORED], acc[C_DISS], acc[C_EVENTS] = work, stored, diss, events
        partial[ic, :] = acc


@numba.njit(cache=True, parallel=True)
def find_fresh(flag, n_active, r, R, u, cos_phi, sin_phi, delta, r_o, k_e, tan_max, counts, spans):
    """Flag (2) the asperities without a committed contact that touch at ``delta``; their count per chunk.

    ``spans`` (chunks, 2), if not empty: where the trial's :func:`fresh_pass` at this same
    displacement and committed state found them, per chunk; only those ranges are tested (the
    same test, so the same asperities), else every asperity below n_active.
    """
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, _ = closure_and_slope(r_o, d1)
    n_chunks = (n_active + CHUNK - 1) // CHUNK
    known = spans.shape[0] > 0
    for ic in numba.prange(n_chunks):
        c = 0
        lo, hi = ic * CHUNK, min(n_active, (ic + 1) * CHUNK)
        if known:
            lo, hi = spans[ic, 0], spans[ic, 1]
        for j in range(lo, hi):
            if flag[j]:
                continue
            cp, sp = cos_phi[j], sin_phi[j]
            x = d1 - r[j]
            inv_R = 1.0 / R[j]
            if not may_touch_follow(x, cp * d2 + sp * d3, 1.0 - k_e * closure * inv_R, u[j] * (2.0 / math.pi),
                                    tan_max):
                continue
            th, _ = asperity_theta(u[j], inv_R, closure, k_e, 0.0)
            dn, _, _ = local_displacement(x, d2, d3, math.cos(th), math.sin(th), cp, sp)
            if dn > 0.0:
                flag[j] = 2
                c += 1
        counts[ic] = c


def commit_fresh(new_slots, asp, dn_c, code, r, R, u, cos_phi, sin_phi, delta, delta_c, delta_ref, r_o, k_e, consts,
                 arrays, n_store, partial):
    """Commit the contacts born in this increment (slots ``new_slots``, assigned in asperity order)."""
    d1, d2, d3 = delta[0], delta[1], delta[2]
    D0, D1, D2 = d1 - delta_c[0], d2 - delta_c[1], d3 - delta_c[2]
    closure, _ = closure_and_slope(r_o, d1)
    m = new_slots.size
    n_chunks = (m + CHUNK - 1) // CHUNK
    for ic in numba.prange(n_chunks):
        acc = np.zeros(N_COMMIT)
        scratch = np.zeros((2, 2 * n_store))  # the law's scratch: two rows of twice the stored springs
        for ii in range(ic * CHUNK, min(m, (ic + 1) * CHUNK)):
            sl = new_slots[ii]
            j = asp[sl]
            cp, sp = cos_phi[j], sin_phi[j]
            inv_R = 1.0 / R[j]
            th, _ = asperity_theta(u[j], inv_R, closure, k_e, 0.0)
            ct, st = math.cos(th), math.sin(th)
            dn, _, _ = local_displacement(d1 - r[j], d2, d3, ct, st, cp, sp)
            dnc = committed_overlap(j, r, u, inv_R, cp, sp, delta_c, r_o, k_e)
            dn_ref = committed_overlap(j, r, u, inv_R, cp, sp, delta_ref, r_o, k_e)
            _, dds, ddt = local_displacement(D0, D1, D2, ct, st, cp, sp)
            new, work, stored, diss, events = commit_law(dn, dds, ddt, dnc, dn_ref, R[j], consts, arrays, sl, True,
                                                         scratch)
            acc[C_WORK] += work
            acc[C_STORED] += stored
            acc[C_DISS] += diss
            acc[C_EVENTS] += events
            acc[C_TR + new] += 1.0
            dn_c[sl] = dn
            code[sl] = new
        partial[ic, :] = acc


def snapshot_slots(slot_of, dn_c, code, r, R, u, cos_phi, sin_phi, delta, r_o, k_e, consts, arrays, theta_birth,
                   delta_n_out, theta_out, force_out, state_out):
    """Per-asperity overlap, angle, global force of the committed springs and state code (call right after commit)."""
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, dc = closure_and_slope(r_o, d1)
    has_birth = theta_birth.size > 0
    for j in numba.prange(r.size):
        cp, sp = cos_phi[j], sin_phi[j]
        th, _ = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth, has_birth)
        ct, st = math.cos(th), math.sin(th)
        dn, _, _ = local_displacement(d1 - r[j], d2, d3, ct, st, cp, sp)
        delta_n_out[j] = dn
        theta_out[j] = th
        sl = slot_of[j]
        f_n = f_s = f_t = 0.0
        c = 0
        if sl >= 0 and dn > 0.0:  # the committed springs: a trial with no increment
            out = trial(dn, 0.0, 0.0, dn_c[sl], 0.0, R[j], consts, arrays, sl, False)
            f_n, f_s, f_t, c = out[0], out[1], out[2], code[sl]
        force_out[j, 0] = f_n * ct - f_s * st
        force_out[j, 1] = f_n * st * cp + f_s * ct * cp - f_t * sp
        force_out[j, 2] = f_n * st * sp + f_s * ct * sp + f_t * cp
        state_out[j] = c


# layout of one row of commit sums: work, stored energy, dissipation, law events, transitions (4 x 4)
C_WORK, C_STORED, C_DISS, C_EVENTS, C_TR = 0, 1, 2, 3, 4
N_COMMIT = 4 + 16

_PATH_INDEPENDENT = {"values_follow": dict(cache=True, inline="always", error_model="numpy"),
                     "chunk_follow": dict(cache=True, error_model="numpy"),
                     "chunk_birth": dict(cache=True, inline="always", error_model="numpy"),
                     "chunk_any": dict(cache=True, inline="always", error_model="numpy"),
                     "reduce_parallel": dict(cache=True, parallel=True, error_model="numpy"),
                     "reduce_serial": dict(cache=True, error_model="numpy"),
                     "snapshot_local": dict(cache=True, parallel=True, error_model="numpy")}
_HISTORY = {"slot_pass": dict(cache=True, parallel=True, error_model="numpy"),
            "fresh_pass": dict(cache=True, parallel=True, error_model="numpy"),
            "commit_slots": dict(cache=True, parallel=True, error_model="numpy"),
            "commit_fresh": dict(cache=True, parallel=True, error_model="numpy"),
            "snapshot_slots": dict(cache=True, parallel=True, error_model="numpy"),
            "each_contact": dict(cache=True, error_model="numpy"),
            "each_commit": dict(cache=True, error_model="numpy")}


@functools.lru_cache(maxsize=None)
def _kernels_of(law: laws.Law) -> dict:
    templates = _PATH_INDEPENDENT if law.path_independent else _HISTORY
    g = globals()
    aliases = {}
    if law.path_independent:
        bindings = {"local": law.local}
    else:
        bindings = {"trial": law.history.trial, "commit_law": law.history.commit}
        for name, default, given in (("trial_block", "each_contact", law.history.trial_block),
                                     ("commit_block", "each_commit", law.history.commit_block)):
            if given is None:
                aliases[name] = default
            else:
                bindings[name] = given
    return laws.specialise({name: g[name] for name in templates}, law, bindings, templates, aliases)


def kernels(law) -> dict:
    """The generic kernels compiled for ``law`` (name -> numba dispatcher), built once per law."""
    return _kernels_of(laws.get(law))


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


@numba.njit(cache=True)
def assign_slots(flag, counts, asp, n_slots, new_slots):
    """Give each asperity flagged 2 (a new contact) a slot, lowest free slot first, in asperity order.

    Returns the new number of slots in use (free slots have asp = -1); ``new_slots`` receives
    the slots given, in order.  Only chunks with a count are scanned.
    """
    free = 0
    m = 0
    for ic in range(counts.size):
        if counts[ic] == 0:
            continue
        for j in range(ic * CHUNK, min(flag.size, (ic + 1) * CHUNK)):
            if flag[j] != 2:
                continue
            while free < n_slots and asp[free] >= 0:
                free += 1
            sl = free
            if sl == n_slots:
                n_slots += 1
            asp[sl] = j
            flag[j] = 1
            new_slots[m] = sl
            m += 1
            free += 1
    return n_slots


@dataclass(frozen=True)
class Evaluation:
    """Interface response at one displacement (SPEC §6).

    stress (3,) [Pa], stderr (3,) [Pa] (Monte Carlo standard error of each component),
    covariance (3, 3) [Pa²] (Monte Carlo covariance of the stress estimate), tangent (3, 3)
    [Pa/m] (d sigma_i / d Delta_k), n_contact, n_slip and n_partial (asperity counts),
    mean_theta [rad] (mean orientation of the contacts; 0 when none), n_active (asperities
    below the height bound, the most that can touch).
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
    """Preallocated partial-sum rows for one population (a Newton iteration allocates nothing).

    A history law's trial also leaves here, for a commit at its displacement, where its fresh
    contacts are (``spans``), the geometry of its committed contacts (``slot_geo``, policy
    follow) and the displacement and committed state it was made at (``fresh_key``).  The
    workspace also keeps an index of the asperities that may touch in a box of displacements
    around the path (``listed``; :meth:`fresh_index`), so that a trial inside the box tests
    only those; ``index=False`` turns it off (every trial tests every asperity that can touch).
    """

    AHEAD = 8  # the index box reaches this many times the step from the committed displacement

    def __init__(self, n, index=True):
        n_chunks = (n + CHUNK - 1) // CHUNK
        self.partial = np.zeros((n_chunks, N_ACC))
        self.spans = np.zeros((n_chunks, 2), dtype=np.int64)
        self.fresh_key = None
        self.slot_geo = np.zeros((N_SLOT_GEO, 0))
        self.index = bool(index)
        self.listed = self.n_listed = None  # allocated by the first history-law trial
        self.box = np.zeros((2, 3))
        self.box_pop = None  # the population the listed asperities belong to; None: no valid list
        self.n_box, self.tan_box = 0, 0.0
        self.trials_by_index = [0, 0, 0]  # trials that tested every asperity, built the list, used it

    @staticmethod
    def trial_key(delta, state):
        """What identifies a trial: the bits of its displacement and the committed state it was made on."""
        return np.asarray(delta, dtype=float).tobytes(), id(state), state.serial

    def made_at(self, delta, state):
        """True if the last trial was made at ``delta`` on the committed state ``state``."""
        return self.fresh_key == self.trial_key(delta, state)

    def fresh_spans(self, delta, state):
        """The spans of the last trial if it was made at ``delta`` on the committed state ``state``, else empty."""
        return self.spans if self.made_at(delta, state) else _EMPTY_SPANS

    def slot_geometry(self, delta, state):
        """The slot geometry of the last trial if it was made at ``delta`` on ``state`` (policy follow), else empty."""
        return self.slot_geo if self.made_at(delta, state) and state.theta_birth is None else _EMPTY_SLOT_GEO

    def slot_rows(self, n_slots):
        """The slot geometry array, grown (by a quarter beyond the need) to hold ``n_slots`` slots."""
        if self.slot_geo.shape[1] < n_slots:
            self.slot_geo = np.zeros((N_SLOT_GEO, n_slots + n_slots // 4 + BLOCK))
        return self.slot_geo

    def fresh_index(self, pop, d, delta_c, n_active):
        """How a history-law trial at ``d`` finds its fresh contacts: ``index`` of :func:`fresh_pass` (0, 1, 2).

        2 when the listed asperities were built for ``pop`` in a box that holds ``d``.  Else 1:
        a new box, from the committed displacement ``delta_c`` to AHEAD steps d - delta_c
        beyond it, widened by the largest component of the step in every direction (Newton
        corrections, a turning path), with its own bounds (:func:`bounds` at the box corner of
        largest closure and shear).  0 without an index, or for a trial at ``delta_c``.
        """
        if not self.index:
            return 0
        if self.listed is None or self.listed.size < pop.n:
            self.listed = np.empty(self.spans.shape[0] * CHUNK, dtype=np.int32)
            self.n_listed = np.zeros(self.spans.shape[0], dtype=np.int64)
            self.box_pop = None
        if (self.box_pop is pop and n_active <= self.n_box and np.all(self.box[0] <= d)
                and np.all(d <= self.box[1])):
            return 2
        step = d - delta_c
        pad = np.abs(step).max()
        if not pad > 0.0:
            return 0
        ahead = delta_c + self.AHEAD * step
        self.box[0] = np.minimum(delta_c, ahead) - pad
        self.box[1] = np.maximum(delta_c, ahead) + pad
        corner = np.array([self.box[1, 0], np.abs(self.box[:, 1]).max(), np.abs(self.box[:, 2]).max()])
        r_o, k_e, _, _, _, beta, _ = pop.kernel_constants
        self.n_box, self.tan_box = bounds(pop.r, pop.R_min, r_o, k_e, beta, corner, _EMPTY)
        self.box_pop = None  # until the list is written
        return 1

    def rows(self, m):
        """At least m rows of partial sums (grown when a history law has more slot chunks)."""
        if self.partial.shape[0] < m:
            self.partial = np.zeros((m, N_ACC))
        return self.partial


_EMPTY = np.empty(0)
_EMPTY_SPANS = np.zeros((0, 2), dtype=np.int64)
_EMPTY_INDEX = np.zeros(0, dtype=np.int32)
_EMPTY_SLOT_GEO = np.zeros((N_SLOT_GEO, 0))
_EMPTY_COUNTS = np.zeros(0, dtype=np.int64)


def evaluate(pop, delta, law="paper", policy="follow", theta_birth=None, workspace=None, state=None) -> Evaluation:
    """Evaluate Eq. (23) and its tangent over a population at interface displacement delta [m].

    ``law`` a registered law name (:mod:`asperity_sim.laws`).  ``state`` (a
    :class:`~asperity_sim.state.ContactState`) holds the committed per-contact state: the
    springs of a history law and the birth angles of policy birth; it is read, never written.
    Without it: a virgin interface at Delta = 0 (every contact born now).  Under policy
    birth ``theta_birth`` (n,) may give the frozen angles directly (NaN where none).
    """
    if not isinstance(pop, Population):
        raise ValueError(f"pop = {pop!r} is not a Population")
    d = check_delta(delta)
    lw = laws.get(law)
    check_choice("policy", policy, POLICIES)
    if workspace is not None and (not isinstance(workspace, Workspace)
                                  or workspace.partial.shape[0] * CHUNK < pop.n):
        raise ValueError(f"workspace = {workspace!r} is not a Workspace for {pop.n} asperities (use Workspace(pop.n))")
    if state is None:
        from .state import ContactState

        state = ContactState(pop, lw, policy)
    elif state.law is not lw or state.pop is not pop:
        raise ValueError(f"state belongs to law {state.law.name!r} on another population; this is law {lw.name!r}")
    if policy == "birth" and theta_birth is not None:
        tb = np.asarray(theta_birth, dtype=float)
        if tb.shape != (pop.n,):
            raise ValueError(f"theta_birth has shape {tb.shape}, expected ({pop.n},)")
        state.theta_birth = tb
    ws = workspace if workspace is not None else Workspace(pop.n)
    return evaluate_unchecked(pop, d, state, ws)


def evaluate_unchecked(pop, d, state, workspace) -> Evaluation:
    """:func:`evaluate` on arguments already checked (for a solver that calls it many times).

    ``d`` a finite float array (3,), ``state`` a :class:`~asperity_sim.state.ContactState`
    of ``pop``, ``workspace`` a :class:`Workspace` for ``pop``.
    """
    law = state.law
    tb = _EMPTY if state.theta_birth is None else state.theta_birth
    out = np.empty(N_OUT)
    r_o, k_e, _, _, _, beta, scale = pop.kernel_constants
    kern = kernels(law)
    if law.path_independent:
        # a population that fits the serial kernel: it finds its own bounds
        serial = pop.n <= SERIAL_CHUNKS * CHUNK
        if not serial:
            n_active, tan_max = bounds(pop.r, pop.R_min, r_o, k_e, beta, d, tb)
            serial = n_active <= SERIAL_CHUNKS * CHUNK
        if serial:
            kern["reduce_serial"](pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, pop.R_min, _row(d), r_o, k_e,
                                  state.consts, beta, tb, pop.n, scale, workspace.partial, out.reshape(1, N_OUT))
            return evaluation_from(d, out)
        kern["reduce_parallel"](pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, n_active, d, r_o, k_e, state.consts,
                                tb, tan_max, workspace.partial)
        n_rows = (n_active + CHUNK - 1) // CHUNK
    else:
        n_active, tan_max = bounds(pop.r, pop.R_min, r_o, k_e, beta, d, _EMPTY)
        n_pop = (n_active + CHUNK - 1) // CHUNK
        n_slot = (state.n_slots + CHUNK - 1) // CHUNK
        partial = workspace.rows(n_pop + n_slot)
        workspace.fresh_key = None
        index = workspace.fresh_index(pop, d, state.delta_c, n_active)
        listed, n_listed = (workspace.listed, workspace.n_listed) if index else (_EMPTY_INDEX, _EMPTY_COUNTS)
        kern["fresh_pass"](state.flag, n_active, pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, d, state.delta_c,
                           state.reference, r_o, k_e, state.consts, state.arrays, tan_max, partial, workspace.spans,
                           index, listed, n_listed, workspace.box, workspace.n_box, workspace.tan_box)
        workspace.trials_by_index[index] += 1
        if index == 1:
            workspace.box_pop = pop
        if n_slot:
            kern["slot_pass"](state.asp, state.n_slots, state.dn_c, pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, d,
                              state.delta_c, r_o, k_e, state.consts, state.arrays, tb, partial[n_pop:],
                              workspace.slot_rows(state.n_slots))
        workspace.fresh_key = workspace.trial_key(d, state)
        n_rows = n_pop + n_slot
    finish(workspace.partial, n_rows, pop.n, scale, out)
    out[O_NA] = n_active
    return evaluation_from(d, out)


def _row(d):
    """d (3,) as a C-contiguous (1, 3) view or copy: the one array layout the serial kernel is compiled for."""
    return np.ascontiguousarray(d).reshape(1, 3)


def evaluate_steps(pop, deltas, workspace, law="paper") -> np.ndarray:
    """Flat results (m, N_OUT) of a path-independent law under policy follow at each row of ``deltas`` (m, 3) [m].

    One call of the serial kernel for all rows, each bit-identical to :func:`evaluate` there;
    meant for small populations, where the per-call overhead of :func:`evaluate` exceeds the
    kernel time.  Read a row with :func:`evaluation_from`.  ``deltas`` finite and
    C-contiguous, ``workspace`` a :class:`Workspace` for ``pop``.
    """
    lw = laws.get(law)
    r_o, k_e, _, _, _, beta, scale = pop.kernel_constants
    out = np.empty((deltas.shape[0], N_OUT))
    kernels(lw)["reduce_serial"](pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, pop.R_min, deltas, r_o, k_e,
                                 lw.constants(pop.params, None), beta, _EMPTY, pop.n, scale, workspace.partial, out)
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


def snapshot(pop, delta, policy="follow", theta_birth=None, law="paper"):
    """Per-asperity arrays at delta of a path-independent law: delta_n [m], theta [rad], force (n, 3) [N], state."""
    d = check_delta(delta)
    lw = laws.get(law)
    tb = np.asarray(theta_birth, dtype=float) if (policy == "birth" and theta_birth is not None) else _EMPTY
    out = {"delta_n": np.empty(pop.n), "theta": np.empty(pop.n), "force": np.empty((pop.n, 3)),
           "state": np.empty(pop.n, dtype=np.int8)}
    kernels(lw)["snapshot_local"](pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, d, pop.params.r_o, pop.params.k_e,
                                  lw.constants(pop.params, None), tb, out["delta_n"], out["theta"], out["force"],
                                  out["state"])
    return out
