"""The springs of one ``mdr`` contact: spacing, one spring's step, rows of springs, release.

Owns the per-spring mechanics of the vector MDR law (:mod:`asperity_sim.laws.mdr`): the
spacing h of a contact's springs, the radial return of one spring onto its Coulomb circle
(:func:`spring_step`), a row of springs entering, continuing in and leaving contact within an
increment, and the state code of a contact from its spring counts.  Numba kernels, inlined
into the law's trial and commit.
"""

from __future__ import annotations

import math

from ...jit import kernel
from ...vectormath import fsqrt
from ..hertz import hertz_roots
from ..registry import FULL_SLIP, PARTIAL, STICK

FLOOR_FRACTION = 1e-5  # dn_floor / ((alpha + 1) beta)


@kernel(inline="always")
def spacing(fresh, dn, dn_ref, R, k, dn_floor, h_slot):
    """(h, scaled): the committed spacing, or for a fresh contact sqrt(R max(dn, dn_ref, dn_floor))/k
    and whether it scales with dn (then x_i²/R is proportional to dn)."""
    if not fresh:
        return h_slot, False
    fixed = max(dn_ref, dn_floor)
    scaled = dn > fixed
    return math.sqrt(R * (dn if scaled else fixed)) / k, scaled


FAST = {"reassoc", "contract"}  # sums over springs may be reordered (the loops vectorise), products fused
LANES = 8  # doubles per vector register (AVX-512): spring loops are padded to whole vectors


@kernel(inline="always", error_model="numpy")
def spring_x2(c, i):
    """x_i²/R = c (i + 1/2)² of spring i, written once so that every loop takes the same stick/slip decisions."""
    y = i + 0.5
    return c * (y * y)


@kernel(inline="always", error_model="numpy")
def spring_step(wcs, wct, memory, u, u_c, g, gap, dds, ddt, lm_r, dlim, can_stick):
    """One spring's new vector and its share of the force and Jacobian, branch-free.

    ``memory``: the spring continues from its committed vector (wcs, wct); else it enters and
    takes the part a = u / gap of the increment after its entry (a = 1 if it overlapped
    already, u_c > 0), with da/d dn = ((1 - g) gap - u) / gap².  Returns (ws, wt, stick, a,
    F_s, F_t, J10, J11, J12, J20, J22) with J21 = J12.
    """
    enter = ~memory & (u_c <= 0.0)
    a = u / gap if enter else 1.0
    da = ((1.0 - g) * gap - u) / (gap * gap) if enter else 0.0
    ws, wt = wcs + a * dds, wct + a * ddt
    limit = lm_r * u
    m2 = ws * ws + wt * wt
    stick = can_stick & (m2 <= limit * limit)
    mm = fsqrt(m2)
    inv_m = 1.0 / mm if mm > 0.0 else 0.0
    es, et = ws * inv_m, wt * inv_m
    ratio = limit * inv_m
    # slip: w = limit e; d(limit e)/d(w*) = ratio (I - e e^T), d limit / d dn = dlim
    P00, P01, P11 = ratio * (1.0 - es * es), -ratio * es * et, ratio * (1.0 - et * et)
    bs, bt = da * dds, da * ddt
    return (ws if stick else limit * es, wt if stick else limit * et, stick, a,
            ws if stick else limit * es, wt if stick else limit * et,
            bs if stick else P00 * bs + P01 * bt + dlim * es,
            a if stick else a * P00,
            0.0 if stick else a * P01,
            bt if stick else P01 * bs + P11 * bt + dlim * et,
            a if stick else a * P11)


@kernel(inline="always", error_model="numpy")
def continuing_trial(w, n_cont, n_pad, c, dn, dds, ddt, lm_r, dlim0, dlim1, can_stick):
    """Sums of the springs 0 <= i < n_cont that continue from their committed vectors (u_i^c > 0) in a trial.

    The physics of :func:`spring_step` with a = 1, da = 0, arranged for few operations per
    spring: with p = limit / |w|³ and g = dlim / |w| of a slipping spring, its Jacobian is
    ratio (I - e e^T) = p (wt², -ws wt; -ws wt, ws²) and dlim e = g w (no cancellation: 1 - es²
    is written et²), and a sticking spring adds the identity.  The loop runs to n_pad (whole
    vectors); springs n_cont.. add nothing.  Returns (F_s, F_t, J10, J11, J12, J20, J22, n_stick)
    per unit q.
    """
    Fs = Ft = A = B = C = Gs = Gt = n_stick = 0.0
    for i in range(n_pad):
        u = dn - spring_x2(c, i)
        ws, wt = float(w[0, i]) + dds, float(w[1, i]) + ddt
        limit = lm_r * u
        ws2, wt2 = ws * ws, wt * wt
        m2 = ws2 + wt2
        stick = can_stick & (m2 <= limit * limit)
        mm = fsqrt(m2)
        inv_m = 1.0 / mm if mm > 0.0 else 0.0
        inc = i < n_cont
        slip = inc & ~stick
        r = (1.0 if stick else limit * inv_m) if inc else 0.0
        p = r * inv_m * inv_m if slip else 0.0
        g = (dlim0 + u * dlim1) * inv_m if slip else 0.0
        Fs += r * ws
        Ft += r * wt
        n_stick += 1.0 if inc & stick else 0.0
        A += p * wt2
        B += p * (ws * wt)
        C += p * ws2
        Gs += g * ws
        Gt += g * wt
    return Fs, Ft, Gs, n_stick + A, -B, Gt, n_stick + C, n_stick


@kernel(inline="always", error_model="numpy")
def continuing_commit(w, n_cont, n_pad, c, dn, dds, ddt, lm_r, can_stick):
    """:func:`continuing_trial` of a commit: the new vectors of springs 0 <= i < n_cont written over ``w``.

    Energies per unit q as :func:`add_spring` with a = 1.  The loop runs to n_pad (whole
    vectors) and writes springs n_cont.. back unchanged.  Returns (n_stick, work, dissipation,
    sum |w|² of the new vectors).
    """
    n_stick = work = dissipation = stored = 0.0
    for i in range(n_pad):
        u = dn - spring_x2(c, i)
        wcs, wct = float(w[0, i]), float(w[1, i])
        ws, wt = wcs + dds, wct + ddt
        limit = lm_r * u
        m2 = ws * ws + wt * wt
        stick = can_stick & (m2 <= limit * limit)
        mm = fsqrt(m2)
        ratio = limit * (1.0 / mm) if mm > 0.0 else 0.0
        ns, nt = (ws, wt) if stick else (ratio * ws, ratio * wt)
        inc = i < n_cont
        w[0, i] = ns if inc else wcs
        w[1, i] = nt if inc else wct
        n2 = ns * ns + nt * nt
        de = 0.5 * (n2 - (wcs * wcs + wct * wct))
        # a sticking spring is linear: its work is its change of energy; a slipping one slips by ws - ns
        wk = de if stick else ns * dds + nt * ddt
        dd = 0.0 if stick else ns * (ws - ns) + nt * (wt - nt) + 0.5 * ((ns - wcs) ** 2 + (nt - wct) ** 2)
        n_stick += 1.0 if inc & stick else 0.0
        work += wk if inc else 0.0
        dissipation += dd if inc else 0.0
        stored += n2 if inc else 0.0
    return n_stick, work, dissipation, stored


@kernel(inline="always", error_model="numpy")
def coulomb_scale(dn, dn_c, R, E_star, h, c, scaled):
    """(f_n, k_n, n_in, rho, drho, sqrt R, sqrt dn): Hertz force and stiffness, springs in contact, Coulomb scale.

    The Coulomb limit of spring i is lam mu rho u_i, with rho = f_n / (2 E* h sum u_i) the ratio
    of the Hertz force to the springs' own normal force (1 up to the discretisation), so that a
    contact in full slip carries exactly mu f_n, as the paper law; drho = d rho / d dn (zero when
    h follows the overlap: both forces then grow as dn^(3/2)).  Hertz as :func:`hertz`, with the
    roots shared: sqrt(dn / c) = sqrt(dn) sqrt(R) / h.
    """
    sR, sdn = fsqrt(R), fsqrt(dn)
    f_n, k_n = hertz_roots(dn, sR, sdn, E_star)
    n_in, sum_u, _ = tail_sums(0, springs_below(dn, c, sdn * sR / h), dn, dn_c, c)
    some = sum_u > 0.0  # selects, not branches: a loop over contacts vectorises
    rho = f_n / (2.0 * E_star * h * sum_u) if some else 1.0
    drho = rho * (1.5 / dn - n_in / sum_u) if some & ~scaled else 0.0
    return f_n, k_n, n_in, rho, drho, sR, sdn


@kernel(inline="always", error_model="numpy")
def add_spring(i, wcs, wct, held, c, dn, dn_c, inv_dn, scaled, gap, dds, ddt, lm, rho, drho, lm_r, can_stick, q,
               w_out, write):
    """Spring i (committed vector (wcs, wct) if ``held``): its share (F_s, F_t, J10, J11, J12, J20, J22, sticks,
    work, change of stored energy, dissipation); the energies, and the new vector in ``w_out``, only if ``write``
    (a constant at every call: a conditional store would keep the loop from vectorising)."""
    wcs, wct = float(wcs), float(wct)
    x2 = spring_x2(c, i)
    u, u_c = dn - x2, dn_c - x2
    g = x2 * inv_dn if scaled else 0.0  # d x_i²/R / d dn: positions scale with a fresh contact
    memory = held & ((u_c > 0.0) | (wcs != 0.0) | (wct != 0.0))
    dlim = lm * (rho * (1.0 - g) + u * drho)
    ws, wt, stick, a, fs, ft, j10, j11, j12, j20, j22 = spring_step(wcs, wct, memory, u, u_c, g, gap, dds, ddt,
                                                                   lm_r, dlim, can_stick)
    work = de = dd = 0.0
    if write:  # a commit: the new springs and the energy of the increment
        w_out[0, i] = ws
        w_out[1, i] = wt
        dis, dit = a * dds, a * ddt  # displacement this spring took while in contact
        de = 0.5 * q * (ws * ws + wt * wt - wcs * wcs - wct * wct)
        ps, pt = wcs + dis - ws, wct + dit - wt  # its slip (zero when it sticks)
        # a sticking spring is linear: its work is its change of energy
        work = de if stick else q * (ws * dis + wt * dit)
        dd = 0.0 if stick else q * (ws * ps + wt * pt) + 0.5 * q * ((ws - wcs) ** 2 + (wt - wct) ** 2)
    return fs, ft, j10, j11, j12, j20, j22, 1.0 if stick else 0.0, work, de, dd


@kernel(inline="always", error_model="numpy")
def spring_range(i0, i1, i_end, w, held, c, dn, dn_c, inv_dn, scaled, gap, dds, ddt, lm, rho, drho, lm_r,
                 can_stick, q, w_out, write):
    """Sums of :func:`add_spring` over springs i0 <= i < i1 (their committed vectors from ``w`` if ``held``).

    The loop runs to i_end >= i1 (whole vectors, no scalar remainder); springs i1.. add nothing
    (with ``write`` their slots in ``w_out`` get values to be discarded).
    """
    Fs = Ft = J10 = J11 = J12 = J20 = J22 = n_stick = work = stored_change = dissipation = 0.0
    for i in range(i0, i_end):
        fs, ft, j10, j11, j12, j20, j22, st, wk, de, dd = add_spring(
            i, w[0, i] if held else 0.0, w[1, i] if held else 0.0, held, c, dn, dn_c, inv_dn, scaled, gap, dds, ddt,
            lm, rho, drho, lm_r, can_stick, q, w_out, write)
        inc = i < i1
        Fs += fs if inc else 0.0
        Ft += ft if inc else 0.0
        J10 += j10 if inc else 0.0
        J11 += j11 if inc else 0.0
        J12 += j12 if inc else 0.0
        J20 += j20 if inc else 0.0
        J22 += j22 if inc else 0.0
        n_stick += st if inc else 0.0
        work += wk if inc else 0.0
        stored_change += de if inc else 0.0
        dissipation += dd if inc else 0.0
    return Fs, Ft, J10, J11, J12, J20, J22, n_stick, work, stored_change, dissipation


@kernel(inline="always", error_model="numpy")
def springs_below(dn, c, root):
    """N: springs i < N have u_i = dn - c (i + 1/2)² > 0, from root ~ sqrt(dn / c) (0 if not positive).

    The rounded root is corrected by one either way with the test the loops make
    (:func:`spring_x2`), so the count is exactly the number of springs they find in contact;
    branch-free.
    """
    N = int(root + 0.5) if root > 0.0 else 0
    N += 1 if dn - spring_x2(c, N) > 0.0 else 0
    N -= 1 if (N > 0) & (dn - spring_x2(c, N - 1) <= 0.0) else 0
    return N


@kernel(inline="always", error_model="numpy")
def tail_sums(i0, N, dn, dn_c, c):
    """(m, sum u_i, sum -u_i^c) over the springs i0 <= i < N, u_i = dn - c (i + 1/2)², in closed form (branch-free)."""
    N = N if N > i0 else i0
    m = N - i0
    sq = (N * (4.0 * N * N - 1.0) - i0 * (4.0 * i0 * i0 - 1.0)) / 12.0  # sum_{i0 <= i < N} (i + 1/2)²
    return m, m * dn - c * sq, c * sq - m * dn_c


@kernel(inline="always", error_model="numpy")
def entering_tail(i0, dn, dn_c, c):
    """(m, sum u_i, sum -u_i^c) over the springs i >= i0 in contact, u_i = dn - c (i + 1/2)², in closed form.

    Springs beyond the stored ones enter contact in this increment: each takes the same part
    u_i / (dn - dn_c) of it and they all stick or all slip together, so their sums need only
    these three numbers (the cost of a trial does not grow with the overlap).  The count is
    :func:`springs_below`, the number of springs the loops find in contact.
    """
    return tail_sums(i0, springs_below(dn, c, fsqrt(dn / c)), dn, dn_c, c)


@kernel(inline="always", error_model="numpy")
def release(w, start, end, dn, dn_c, c, dds, ddt, q):
    """Work, change of stored energy and dissipation of the stored springs start <= i < end leaving contact.

    A spring in contact for the first fraction f = u^c/(u^c - u) of the increment follows it
    elastically to w* = w^c + f dδ; as its limit vanishes at the exit it slides to zero,
    dissipating ½ q |w*|².  Under proportional unloading w* = 0.  (Springs without memory add 0.)
    """
    work = stored_change = dissipation = 0.0
    for jj in range(start, end):
        wcs, wct = float(w[0, jj]), float(w[1, jj])
        x2 = spring_x2(c, jj)
        u_c, u = dn_c - x2, dn - x2
        f = u_c / (u_c - u) if (u_c > 0.0) & (u < u_c) else 0.0
        es, et = wcs + f * dds, wct + f * ddt
        held = (wcs != 0.0) | (wct != 0.0)
        work += 0.5 * q * ((wcs + es) * f * dds + (wct + et) * f * ddt) if held else 0.0
        stored_change -= 0.5 * q * (wcs * wcs + wct * wct)
        dissipation += 0.5 * q * (es * es + et * et) if held else 0.0
    return work, stored_change, dissipation


@kernel(inline="always")
def state_code(n_springs, n_slip):
    if n_slip == 0:
        return STICK
    return FULL_SLIP if n_slip == n_springs else PARTIAL
