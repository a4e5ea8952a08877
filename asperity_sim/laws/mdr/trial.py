"""The trial of an ``mdr`` contact: force and exact Jacobian from its committed springs (read only).

Owns :func:`mdr_trial`, the law's ``trial`` kernel, and what it is built from: the sums over
a contact's springs for a fresh contact (spacing that follows the trial overlap) and for a
committed one (the scalars of the contact once, then the spring loop).
"""

from __future__ import annotations

import math

from ...jit import kernel
from ...vectormath import fsqrt
from ..hertz import hertz, hertz_energy_roots
from .springs import (
    FAST,
    LANES,
    continuing_trial,
    coulomb_scale,
    entering_tail,
    release,
    spacing,
    spring_range,
    spring_step,
    spring_x2,
    springs_below,
    state_code,
)


@kernel(inline="always", error_model="numpy")
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


@kernel(inline="always", error_model="numpy")
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


@kernel(error_model="numpy", fastmath=FAST)
def committed_springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h):
    """:func:`springs` of a committed contact in a trial, without energy or scratch: the hot loop of a run.

    Returns (F_s, F_t, J10, J11, J12, J20, J21, J22, n_springs, n_slip, f_n, k_n) (Hertz: :func:`coulomb_scale`).
    """
    c, q, f_n, k_n, n_in, rho, drho, n_c, _, _ = contact_scales(dn, dn_c, R, h, E_star, lam)
    return committed_springs_scaled(dn, dds, ddt, dn_c, lam, mu, w, c, q, f_n, k_n, n_in, rho, drho, n_c)


@kernel(inline="always", error_model="numpy")
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


@kernel(error_model="numpy", fastmath=FAST)
def fresh_springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled):
    """:func:`springs` of a contact without history in a trial (``w`` any spring row, unused)."""
    Fs, Ft, J10, J11, J12, J20, J21, J22, n_springs, n_slip, _, _, _ = springs(
        dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, True, w, False)
    return Fs, Ft, J10, J11, J12, J20, J21, J22, n_springs, n_slip


@kernel(inline="always")
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
