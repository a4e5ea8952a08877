"""The ``mdr`` asperity law: Hertz normal force and a vector MDR tangential law with memory.

Method of dimensionality reduction (Popov & Heß) in vector form: a contact is a row of
tangential spring-sliders at x_i = (i + 1/2) h on a line (i = 0, 1, ...).

- normal: local overlap of spring i, u_i = delta_n - x_i²/R (in contact where u_i > 0);
  the normal force stays Hertz (:mod:`asperity_sim.laws.hertz`);
- tangential: spring i holds a 2-vector w_i (local s, t components).  In contact it follows
  the tangential displacement increment of the asperity and is returned radially onto the
  circle |w_i| <= lam mu u_i (Coulomb per spring, the MDR image of mu p);
- force: (f_s, f_t) = (2 E*/lam) h sum_i w_i.

Exact (up to the spring count) for any tangential history with varying normal force:
Cattaneo–Mindlin, Mindlin–Deresiewicz, Masing unloading and reloading with nested memory
and erasure; it never creates energy and reduces to the ``paper`` law under monotonic
shear at constant normal force.

Springs that fit the contact.  A contact is born with k springs across the larger of its
radius at birth and the radius it is expected to reach (``dn_ref``: its overlap at the end
of the current stage, where the path prescribes it), h = sqrt(R max(delta_n, dn_ref,
dn_floor))/k, whatever the interface statistics; each slot stores 2k springs, and a contact
that grows beyond them is coarsened (neighbours merged, h doubled), so a contact at its
largest extent has at least k springs in contact.  While a fresh contact is being solved
for and its overlap exceeds dn_ref, h follows its trial overlap, and the Jacobian includes
dh/d delta_n.  dn_floor (a 1e-5 fraction of the interface's height scale) only bounds the
spring count of a contact born with a vanishing overlap.  Coarsening keeps the force and
counts the stored energy the merge averages away as dissipation (a small artefact of the
discretisation; none when the expected extent was right).

Within an increment delta_n and the tangential displacement vary linearly, so a spring
that enters contact (u_i^c <= 0 < u_i) carries the part of the increment after its entry,
frac = u_i / (u_i - u_i^c): proportional loading below slip stays exactly elastic.  A
spring that leaves contact holds zero; a contact that is lost has its memory erased.

Energy of one increment, per spring (q = 2 E* h / lam): stored ½ q |w|²; work
½ q (w^c + w).dδ_i while it sticks, q w.dδ_i when it slips (end-point rule of the radial
return); dissipation q w.p + ½ q |w - w^c|² >= 0 for a slipping spring (p: its slip).
Work = change of stored energy + dissipation then holds per spring to round-off.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from . import FULL_SLIP, PARTIAL, STICK, History, Law, register
from ..geometry import fsqrt
from ..prefetch import prefetch
from .hertz import hertz, hertz_energy, hertz_energy_roots, hertz_roots

FLOOR_FRACTION = 1e-5  # dn_floor / ((alpha + 1) beta)
AHEAD = 4  # a block kernel asks for the springs of the contact this many slots ahead (asperity_sim.prefetch)


@numba.njit(cache=True, inline="always")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
def spring_x2(c, i):
    """x_i²/R = c (i + 1/2)² of spring i, written once so that every loop takes the same stick/slip decisions."""
    y = i + 0.5
    return c * (y * y)


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
def springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, fresh, w_out, write):
    """Tangential force, its Jacobian, counts and (commit) energy of one contact's springs.

    For a commit and for a fresh contact in a trial (a committed contact in a trial goes through
    :func:`committed_springs`, the same physics without energies, with the springs beyond the
    stored ones summed in closed form).  ``w`` (2, >= stored): committed springs (ignored when
    ``fresh``); ``w_out`` (2, >= springs in contact): the new springs (``write``: a commit, else the
    energies are 0).  Compiled through :func:`commit_springs` and :func:`fresh_springs`.  Returns
    (F_s, F_t, J10, J11, J12, J20, J21, J22, n_springs, n_slip, work, d_stored, dissipation),
    J = d(F_s, F_t)/d(dn, dds, ddt).
    """
    c = h * h / R
    q = 2.0 * E_star * h / lam
    lm = lam * mu
    f_n, k_n, n_in, rho, drho, _, _ = coulomb_scale(dn, dn_c, R, E_star, h, c, scaled)
    lm_r = lm * rho
    can_stick = lm != 0.0
    gap = dn - dn_c
    inv_dn = 1.0 / dn
    n_mem = 0 if fresh else min(n_in, w.shape[1])
    # two branch-free loops that LLVM vectorises: stored springs, then springs without memory
    # (a stored spring with u_c <= 0 has memory only after coarsening, merged across the edge: it keeps it)
    # released first: the loops may write over the stored springs beyond those in contact
    work = stored_change = dissipation = 0.0
    if write and not fresh:
        work, stored_change, dissipation = release(w, n_in, w.shape[1], dn, dn_c, c, dds, ddt, q)
    n_pad = min((n_mem + LANES - 1) // LANES * LANES, w.shape[1], w_out.shape[1] if write else w.shape[1])
    Fs, Ft, J10, J11, J12, J20, J22, n_stick, wk, de, dd = spring_range(
        0, n_mem, max(n_pad, n_mem), w, True, c, dn, dn_c, inv_dn, scaled, gap, dds, ddt, lm, rho, drho, lm_r,
        can_stick, q, w_out, write)
    work, stored_change, dissipation = work + wk, stored_change + de, dissipation + dd
    fs, ft, j10, j11, j12, j20, j22, st, wk, de, dd = spring_range(
        n_mem, n_in, n_in, w, False, c, dn, dn_c, inv_dn, scaled, gap, dds, ddt, lm, rho, drho, lm_r, can_stick, q,
        w_out, write)
    Fs, Ft, J10, J11, J12, J20, J22 = Fs + fs, Ft + ft, J10 + j10, J11 + j11, J12 + j12, J20 + j20, J22 + j22
    n_stick, work, stored_change, dissipation = n_stick + st, work + wk, stored_change + de, dissipation + dd
    Fs *= q
    Ft *= q
    J10, J11, J12, J20, J22 = q * J10, q * J11, q * J12, q * J20, q * J22
    if scaled:  # q and the positions follow the overlap of a fresh contact: dq/d dn = q/(2 dn)
        J10 += 0.5 * Fs * inv_dn
        J20 += 0.5 * Ft * inv_dn
    return Fs, Ft, J10, J11, J12, J20, J12, J22, n_in, n_in - int(n_stick), work, stored_change, dissipation


@numba.njit(cache=True, inline="always", error_model="numpy")
def contact_scales(dn, dn_c, R, h, E_star, lam):
    """(c, q, f_n, k_n, n_in, rho, drho, n_c, e, e_c) of a committed contact at overlap dn > 0: c = h²/R,
    q = 2 E* h / lam, Hertz, springs in contact, Coulomb scale (:func:`coulomb_scale`), the springs in
    contact at dn_c, and the Hertz energies at dn and dn_c [J] (one set of square roots for all).

    Branch-free, so that a loop over the contacts of a block vectorises (:func:`mdr_trial_block`).
    """
    c = h * h / R
    f_n, k_n, n_in, rho, drho, sR, sdn = coulomb_scale(dn, dn_c, R, E_star, h, c, False)
    sdc = fsqrt(dn_c)
    return (c, 2.0 * E_star * h / lam, f_n, k_n, n_in, rho, drho, springs_below(dn_c, c, sdc * sR / h),
            hertz_energy_roots(dn, sR, sdn, E_star), hertz_energy_roots(dn_c, sR, sdc, E_star))


@numba.njit(cache=True, error_model="numpy", fastmath=FAST)
def committed_springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h):
    """:func:`springs` of a committed contact in a trial, without energy or scratch: the hot loop of a run.

    Returns (F_s, F_t, J10, J11, J12, J20, J21, J22, n_springs, n_slip, f_n, k_n) (Hertz: :func:`coulomb_scale`).
    """
    c, q, f_n, k_n, n_in, rho, drho, n_c, _, _ = contact_scales(dn, dn_c, R, h, E_star, lam)
    return committed_springs_scaled(dn, dds, ddt, dn_c, lam, mu, w, c, q, f_n, k_n, n_in, rho, drho, n_c)


@numba.njit(cache=True, inline="always", error_model="numpy")
def committed_springs_scaled(dn, dds, ddt, dn_c, lam, mu, w, c, q, f_n, k_n, n_in, rho, drho, n_c):
    """:func:`committed_springs` given the contact's :func:`contact_scales`.

    The stored springs in contact are visited once, in storage order (w: (2, stored), one
    contiguous row per component, so the loop vectorises); those beyond the stored ones enter
    in this increment and are summed in closed form.
    """
    lm = lam * mu
    lm_r = lm * rho
    can_stick = lm != 0.0
    gap = dn - dn_c
    n_store = w.shape[1]
    dlim0, dlim1 = lm * rho, lm * drho
    n_held = min(n_in, n_store)
    # springs in contact at the committed overlap (u_c > 0) continue from their vectors: the lean loop
    n_cont = min(n_c, n_held)
    n_pad = min((n_cont + LANES - 1) // LANES * LANES, n_store)  # whole vectors: no scalar remainder
    Fs, Ft, J10, J11, J12, J20, J22, stuck = continuing_trial(w, n_cont, n_pad, c, dn, dds, ddt, lm_r, dlim0, dlim1,
                                                             can_stick)
    n_stick = int(stuck)
    for i in range(n_cont, n_held):  # entering this increment, or kept memory across the edge (coarsening)
        x2 = spring_x2(c, i)
        u, u_c = dn - x2, dn_c - x2
        wcs, wct = float(w[0, i]), float(w[1, i])
        memory = (u_c > 0.0) | (wcs != 0.0) | (wct != 0.0)
        _, _, stick, _, fs, ft, j10, j11, j12, j20, j22 = spring_step(wcs, wct, memory, u, u_c, 0.0, gap, dds, ddt,
                                                                      lm_r, dlim0 + u * dlim1, can_stick)
        Fs += fs
        Ft += ft
        J10 += j10
        J11 += j11
        J12 += j12
        J20 += j20
        J22 += j22
        n_stick += 1 if stick else 0
    n_slip = min(n_in, n_store) - n_stick
    m = n_in - n_store
    if m > 0:  # every entering spring takes u_i / gap of the increment: all stick or all slip together
        _, tail_u, tail_uc = entering_tail(n_store, dn, dn_c, c)
        if can_stick and dds * dds + ddt * ddt <= (lm_r * gap) ** 2:
            Fs += tail_u / gap * dds
            Ft += tail_u / gap * ddt
            J10 += tail_uc / (gap * gap) * dds
            J20 += tail_uc / (gap * gap) * ddt
            J11 += tail_u / gap
            J22 += tail_u / gap
        else:
            n_slip += m
            dd = math.sqrt(dds * dds + ddt * ddt)
            es, et = (dds / dd, ddt / dd) if dd > 0.0 else (0.0, 0.0)
            ratio = lm_r * gap / dd if dd > 0.0 else 0.0
            P00, P01, P11 = ratio * (1.0 - es * es), -ratio * es * et, ratio * (1.0 - et * et)
            bs, bt = tail_uc / (gap * gap) * dds, tail_uc / (gap * gap) * ddt
            dlim_sum = lm * (rho * m + drho * tail_u)
            J10 += P00 * bs + P01 * bt + dlim_sum * es
            J20 += P01 * bs + P11 * bt + dlim_sum * et
            J11 += tail_u / gap * P00
            J12 += tail_u / gap * P01
            J22 += tail_u / gap * P11
            Fs += lm_r * tail_u * es
            Ft += lm_r * tail_u * et
    return q * Fs, q * Ft, q * J10, q * J11, q * J12, q * J20, q * J12, q * J22, n_in, n_slip, f_n, k_n


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always", error_model="numpy")
def tail_sums(i0, N, dn, dn_c, c):
    """(m, sum u_i, sum -u_i^c) over the springs i0 <= i < N, u_i = dn - c (i + 1/2)², in closed form (branch-free)."""
    N = N if N > i0 else i0
    m = N - i0
    sq = (N * (4.0 * N * N - 1.0) - i0 * (4.0 * i0 * i0 - 1.0)) / 12.0  # sum_{i0 <= i < N} (i + 1/2)²
    return m, m * dn - c * sq, c * sq - m * dn_c


@numba.njit(cache=True, inline="always", error_model="numpy")
def entering_tail(i0, dn, dn_c, c):
    """(m, sum u_i, sum -u_i^c) over the springs i >= i0 in contact, u_i = dn - c (i + 1/2)², in closed form.

    Springs beyond the stored ones enter contact in this increment: each takes the same part
    u_i / (dn - dn_c) of it and they all stick or all slip together, so their sums need only
    these three numbers (the cost of a trial does not grow with the overlap).  The count is
    :func:`springs_below`, the number of springs the loops find in contact.
    """
    return tail_sums(i0, springs_below(dn, c, fsqrt(dn / c)), dn, dn_c, c)


@numba.njit(cache=True, inline="always", error_model="numpy")
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


@numba.njit(cache=True, inline="always")
def state_code(n_springs, n_slip):
    if n_slip == 0:
        return STICK
    return FULL_SLIP if n_slip == n_springs else PARTIAL


@numba.njit(cache=True, error_model="numpy", fastmath=FAST)
def fresh_springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled):
    """:func:`springs` of a contact without history in a trial (``w`` any spring row, unused)."""
    Fs, Ft, J10, J11, J12, J20, J21, J22, n_springs, n_slip, _, _, _ = springs(
        dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, True, w, False)
    return Fs, Ft, J10, J11, J12, J20, J21, J22, n_springs, n_slip


@numba.njit(cache=True, inline="always")
def mdr_trial(dn, dds, ddt, dn_c, dn_ref, R, consts, arrays, sl, fresh):
    """Force, Jacobian and state code of one contact (dn > 0) from its committed springs; reads only."""
    E_star, lam, mu, k, dn_floor = consts
    w_all, h_all = arrays
    row = 0 if fresh else sl
    h, scaled = spacing(fresh, dn, dn_ref, R, k, dn_floor, h_all[row])
    if fresh:  # a call, not inlined: the hot loop over committed contacts stays small
        f_n, k_n = hertz(dn, R, E_star)
        Fs, Ft, J10, J11, J12, J20, J21, J22, n_springs, n_slip = fresh_springs(
            dn, dds, ddt, dn_c, R, E_star, lam, mu, w_all[row], h, scaled)
    else:
        Fs, Ft, J10, J11, J12, J20, J21, J22, n_springs, n_slip, f_n, k_n = committed_springs(
            dn, dds, ddt, dn_c, R, E_star, lam, mu, w_all[sl], h)
    return (f_n, Fs, Ft, k_n, 0.0, 0.0, J10, J11, J12, J20, J21, J22, float(state_code(n_springs, n_slip)))


@numba.njit(cache=True, inline="always")
def prefetch_springs(w_all, sl, n):
    """Ask for the cache lines of the first n springs (both components) of slot ``sl``, to be read soon."""
    per_line = max(1, 64 // w_all.itemsize)
    last = min(n, w_all.shape[2]) - 1
    for a in range(2):
        for i in range(0, last, per_line):
            prefetch(w_all, sl, a, i)
        prefetch(w_all, sl, a, max(last, 0))


# columns of a block's table of contact scales (:func:`block_scales`)
S_C, S_Q, S_FN, S_KN, S_NIN, S_RHO, S_DRHO, S_NC, S_E, S_EC = range(10)
N_SCALES = 10


@numba.njit(cache=True, inline="always", error_model="numpy")
def block_scales(dn, dn_c, R, h_all, b0, m, E_star, lam):
    """A block's table of contact scales (N_SCALES, m): column i :func:`contact_scales` of slot b0 + i (its
    overlap dn[i], radius R[i], committed overlap and spacing from ``dn_c`` and ``h_all``) if in contact
    (dn > 0 and a spacing h > 0), finite values to be discarded otherwise.

    One loop, branch-free, one contiguous row per quantity: LLVM vectorises it (it does not when
    the loop body calls an inlined function that writes the table).
    """
    sc = np.empty((N_SCALES, m))
    dn_cb, h = dn_c[b0:b0 + m], h_all[b0:b0 + m]  # slices: the loop reads them at i, a vector load
    for i in range(m):
        go = (dn[i] > 0.0) & (h[i] > 0.0)
        x, xc, hh = (dn[i], dn_cb[i], h[i]) if go else (1.0, 0.5, 1.0)
        (sc[S_C, i], sc[S_Q, i], sc[S_FN, i], sc[S_KN, i], n_in, sc[S_RHO, i], sc[S_DRHO, i], n_c, sc[S_E, i],
         sc[S_EC, i]) = contact_scales(x, xc, R[i], hh, E_star, lam)
        sc[S_NIN, i], sc[S_NC, i] = n_in, n_c
    return sc


@numba.njit(cache=True, inline="always")
def prefetch_ahead(w_all, sc, b0, i, m):
    """Prefetch the springs in contact, and those entering, of the contact AHEAD rows after row i of a block."""
    if i + AHEAD < m:
        prefetch_springs(w_all, b0 + i + AHEAD, max(int(sc[S_NIN, i + AHEAD]), int(sc[S_NC, i + AHEAD])) + LANES)


@numba.njit(cache=True, error_model="numpy", fastmath=FAST)
def mdr_trial_block(dn, dds, ddt, R, dn_c, b0, m, consts, arrays, out):
    """:func:`mdr_trial` of the committed contacts in slots b0 .. b0 + m (dn[i] > 0; zeros in ``out`` elsewhere).

    First :func:`contact_scales` of every contact in one loop (LLVM vectorises it, and no
    contact's square roots and divisions wait behind another's springs), then the springs
    contact by contact.  The same values as :func:`mdr_trial` contact by contact.
    """
    E_star, lam, mu, k, dn_floor = consts
    w_all, h_all = arrays
    sc = block_scales(dn, dn_c, R, h_all, b0, m, E_star, lam)
    for i in range(m):
        prefetch_ahead(w_all, sc, b0, i, m)
        if dn[i] <= 0.0:
            for a in range(13):
                out[a, i] = 0.0
            continue
        Fs, Ft, J10, J11, J12, J20, J21, J22, n_springs, n_slip, f_n, k_n = committed_springs_scaled(
            dn[i], dds[i], ddt[i], dn_c[b0 + i], lam, mu, w_all[b0 + i], sc[S_C, i], sc[S_Q, i], sc[S_FN, i],
            sc[S_KN, i], int(sc[S_NIN, i]), sc[S_RHO, i], sc[S_DRHO, i], int(sc[S_NC, i]))
        out[0, i], out[1, i], out[2, i], out[3, i], out[4, i], out[5, i] = f_n, Fs, Ft, k_n, 0.0, 0.0
        out[6, i], out[7, i], out[8, i], out[9, i], out[10, i], out[11, i] = J10, J11, J12, J20, J21, J22
        out[12, i] = float(state_code(n_springs, n_slip))


@numba.njit(cache=True, error_model="numpy", fastmath=FAST)
def commit_springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, fresh, w_out):
    """:func:`springs` of a commit: writes the new springs to ``w_out``; (n_springs, n_slip, work, d_stored,
    dissipation) (no force or Jacobian: LLVM drops their arithmetic)."""
    out = springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, fresh, w_out, True)
    return out[8], out[9], out[10], out[11], out[12]


@numba.njit(cache=True, error_model="numpy", fastmath=FAST)
def commit_springs_in_place(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, fresh):
    """:func:`commit_springs` writing the new springs over the committed ones ``w`` (they must fit).

    One array for both, so that LLVM sees each spring read before it is written and vectorises.
    """
    out = springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, fresh, w, True)
    return out[8], out[9], out[10], out[11], out[12]


@numba.njit(cache=True, error_model="numpy", fastmath=FAST)
def committed_commit(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h):
    """:func:`springs` of a commit of a committed contact (dn > 0) whose springs fit, in place.

    Returns (fits, code, work, stored, dissipation) [J] (:func:`committed_commit_scaled`).
    """
    c, q, f_n, k_n, n_in, rho, drho, n_c, e, e_c = contact_scales(dn, dn_c, R, h, E_star, lam)
    return committed_commit_scaled(dn, dds, ddt, dn_c, lam, mu, w, c, q, n_in, rho, drho, n_c, e, e_c)


@numba.njit(cache=True, inline="always", error_model="numpy")
def committed_commit_scaled(dn, dds, ddt, dn_c, lam, mu, w, c, q, n_in, rho, drho, n_c, e, e_c):
    """:func:`committed_commit` given the contact's :func:`contact_scales`.

    The springs leaving contact are released, those continuing go through the lean loop, the
    few entering (or holding memory across the edge after coarsening) through the general
    step; springs beyond those in contact are zeroed.  Returns :func:`mdr_commit`'s code, work,
    stored energy and dissipation [J], Hertz included; nothing is written when the springs in
    contact do not fit in the store (fits False).
    """
    if n_in > w.shape[1]:
        return False, 0, 0.0, 0.0, 0.0
    lm = lam * mu
    lm_r = lm * rho
    can_stick = lm != 0.0
    n_cont = min(n_c, n_in)
    # a commit zeroes the springs beyond those in contact (a coarsening may leave one more, across the
    # edge), so only springs n_in .. n_c + 1 can hold a vector to release
    n_held = min(w.shape[1], max(n_in, n_c + 1))
    work, _, dissipation = release(w, n_in, n_held, dn, dn_c, c, dds, ddt, q)
    n_pad = min((n_cont + LANES - 1) // LANES * LANES, w.shape[1])
    st, wk, dd, stored = continuing_commit(w, n_cont, n_pad, c, dn, dds, ddt, lm_r, can_stick)
    _, _, _, _, _, _, _, st2, wk2, _, dd2 = spring_range(
        n_cont, n_in, n_in, w, True, c, dn, dn_c, 1.0 / dn, False, dn - dn_c, dds, ddt, lm, rho, drho, lm_r, can_stick,
        q, w, True)
    for i in range(n_cont, n_in):
        stored += float(w[0, i]) ** 2 + float(w[1, i]) ** 2
    for i in range(n_in, n_held):
        w[0, i] = 0.0
        w[1, i] = 0.0
    return (True, state_code(n_in, n_in - int(st + st2)), work + q * wk + wk2 + e - e_c, 0.5 * q * stored + e,
            dissipation + q * dd + dd2)


@numba.njit(cache=True, error_model="numpy", fastmath=FAST)
def mdr_commit_block(dn, dds, ddt, R, dn_c, b0, m, live, consts, arrays, scratch, res):
    """:func:`mdr_commit` of the committed contacts in slots b0 .. b0 + m where ``live`` (res[:, i] = its 5 values).

    As :func:`mdr_trial_block`: the scales of every contact in contact first, in one loop that
    vectorises, then the springs contact by contact; a contact that is lost or outgrew its
    springs goes through :func:`mdr_commit`.  The same values as :func:`mdr_commit`.
    """
    E_star, lam, mu, k, dn_floor = consts
    w_all, h_all = arrays
    sc = block_scales(dn, dn_c, R, h_all, b0, m, E_star, lam)
    for i in range(m):
        prefetch_ahead(w_all, sc, b0, i, m)
        if not live[i]:
            continue
        sl = b0 + i
        if dn[i] > 0.0:
            fits, code, work, stored, diss = committed_commit_scaled(
                dn[i], dds[i], ddt[i], dn_c[sl], lam, mu, w_all[sl], sc[S_C, i], sc[S_Q, i], int(sc[S_NIN, i]),
                sc[S_RHO, i], sc[S_DRHO, i], int(sc[S_NC, i]), sc[S_E, i], sc[S_EC, i])
            if fits:
                res[0, i], res[1, i], res[2, i], res[3, i], res[4, i] = code, work, stored, diss, 0.0
                continue
        code, work, stored, diss, events = mdr_commit(dn[i], dds[i], ddt[i], dn_c[sl], 0.0, R[i], consts, arrays, sl,
                                                      False, scratch)
        res[0, i], res[1, i], res[2, i], res[3, i], res[4, i] = code, work, stored, diss, events


@numba.njit(cache=True)
def merge_pairs(w, n):
    """Coarsen n springs to ceil(n/2) by merging neighbours (spacing doubles), in place; w: (2, >= n).

    The merged vector is the mean of the pair, so the force (2E*/lam)(2h) sum w is kept;
    returns the stored energy lost per unit q, ½ sum |w_a - w_b|² / 2 (counted as dissipation).
    """
    lost = 0.0
    m = (n + 1) // 2
    for j in range(m):
        a0, a1 = w[0, 2 * j], w[1, 2 * j]
        if 2 * j + 1 < n:
            b0, b1 = w[0, 2 * j + 1], w[1, 2 * j + 1]
        else:
            b0 = b1 = 0.0
        lost += 0.25 * ((a0 - b0) ** 2 + (a1 - b1) ** 2)
        w[0, j] = 0.5 * (a0 + b0)
        w[1, j] = 0.5 * (a1 + b1)
    for j in range(m, n):
        w[0, j] = 0.0
        w[1, j] = 0.0
    return lost


@numba.njit(cache=True)
def mdr_commit(dn, dds, ddt, dn_c, dn_ref, R, consts, arrays, sl, fresh, scratch):
    """Write the springs of slot ``sl`` at the converged displacement; (code, work, stored, dissipation, coarsenings).

    dn <= 0: the contact is lost, its springs are released and its memory erased.  Energies
    [J] include the Hertz normal spring; ``stored`` is the contact's energy after the increment.
    ``scratch``: (2, 2 stored) floats for the new springs (a larger buffer is made when needed).
    """
    E_star, lam, mu, k, dn_floor = consts
    w_all, h_all = arrays
    w = w_all[sl]
    n_store = w.shape[1]
    q_unit = 2.0 * E_star / lam
    if dn > 0.0 and not fresh:  # the common case: springs that fit, written over the committed ones
        fits, code, work, stored, diss = committed_commit(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h_all[sl])
        if fits:
            return code, work, stored, diss, 0
    e_old = 0.0 if fresh else hertz_energy(dn_c, R, E_star)
    if dn <= 0.0:
        h = h_all[sl]
        wk, _, dd = release(w, 0, n_store, dn, dn_c, h * h / R, dds, ddt, q_unit * h)
        w[:, :] = 0.0
        h_all[sl] = 0.0
        return 0, wk - e_old, 0.0, dd, 0
    h, scaled = spacing(fresh, dn, dn_ref, R, k, dn_floor, h_all[sl])
    n_need = entering_tail(0, dn, dn_c, h * h / R)[0]
    coarsenings = 0
    stored = 0.0
    if n_need <= n_store:  # a fresh contact that fits
        n_springs, n_slip, work, _, diss = commit_springs_in_place(
            dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, fresh)
        code = state_code(n_springs, n_slip)
        for i in range(n_springs):
            stored += float(w[0, i]) ** 2 + float(w[1, i]) ** 2
        w[:, n_springs:] = 0.0
    else:
        buf = scratch if n_need <= scratch.shape[1] else np.zeros((2, n_need))
        n_springs, n_slip, work, _, diss = commit_springs(
            dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, fresh, buf)
        code = state_code(n_springs, n_slip)  # of the springs as computed, before any coarsening
        while n_springs > n_store:  # coarsen: the contact outgrew its springs
            diss += q_unit * h * merge_pairs(buf, n_springs)
            h *= 2.0
            n_springs = (n_springs + 1) // 2
            coarsenings += 1
        for i in range(n_store):
            a, b = (buf[0, i], buf[1, i]) if i < n_springs else (0.0, 0.0)
            w[0, i] = a
            w[1, i] = b
            stored += a * a + b * b
    h_all[sl] = h
    e_new = hertz_energy(dn, R, E_star)
    return code, work + e_new - e_old, 0.5 * q_unit * h * stored + e_new, diss, 1 if coarsenings else 0


def arrays(capacity, k, dtype):
    """Per-slot state: springs w (capacity, 2, 2k) of ``dtype`` (the s row, then the t row: each contiguous,
    so the spring loops vectorise) and spacing h (capacity,) [m]."""
    return np.zeros((capacity, 2, 2 * k), dtype=dtype), np.zeros(capacity)


def validate(arrays, live):
    """Springs finite, and a positive spacing for every committed contact (a zero spacing never ends a loop)."""
    w, h = arrays
    if not np.all(np.isfinite(w)):
        raise ValueError("spring array holds non-finite values")
    hl = h[live]
    if not np.all(np.isfinite(hl) & (hl > 0.0)):
        raise ValueError("a committed contact has a spring spacing that is not finite and > 0 [m]")


def bytes_per_contact(k, dtype):
    return 2 * k * 2 * np.dtype(dtype).itemsize + 8


def constants(params, k):
    return (params.E_star, params.lam, params.mu, float(k), FLOOR_FRACTION * (params.alpha + 1.0) * params.beta)


MDR = register(Law(
    name="mdr",
    summary="Hertz + vector MDR springs per contact: loading, unloading, reloading, turning (history)",
    constants=constants,
    history=History(arrays=arrays, trial=mdr_trial, commit=mdr_commit, trial_block=mdr_trial_block,
                    commit_block=mdr_commit_block, events="coarsenings",
                    events_long_name="contacts whose springs were coarsened in the increment",
                    bytes_per_contact=bytes_per_contact, validate=validate),
    domain="any path",
    spring_dtypes=("float64", "float32"),
))
