"""The trial of a history law over the population (templates, compiled once per law).

Owns the two passes of a trial (read only): over the committed contacts, streamed in slot
order with their geometry in a vectorised loop (:func:`slot_pass`), and over the asperities
without a committed contact that touch at the trial displacement (:func:`fresh_pass`, which
tests only the asperities the workspace lists as able to touch near the path); and the
per-asperity snapshot of the committed springs.  ``trial`` and ``trial_block`` are the law's
kernels, bound per law by :mod:`asperity_sim.kernels.specialise`.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import closure_and_slope, local_displacement
from ..jit import kernel, template
from ..threads import claim
from ..vectormath import borrowed, copy_into
from .contact import (
    accumulate,
    add_values,
    asperity_theta,
    committed_overlap,
    contact_angle,
    gather_slots,
    slot_geometry,
    slot_values,
)
from .layout import (
    BIRTH,
    BLOCK,
    CHUNK,
    G_DDS,
    G_DDT,
    G_DN,
    G_R,
    I_TH,
    N_ACC,
    N_GEO,
    N_VAL,
    chunk_stride,
)
from .reach import may_touch_follow, may_touch_within

# ---- the law's kernels: placeholders, bound to the law's own by kernels.specialise ----


def trial(dn, dds, ddt, dn_c, dn_ref, R, consts, arrays, sl, fresh):
    """The history law's trial of one contact (``History.trial``): 13 values, never writes.

    A placeholder: each law's copy of the templates below calls that law's kernel here.
    """
    raise NotImplementedError("a template calls its law's kernel: compile it with kernels.specialise")


def trial_block(dn, dds, ddt, R, dn_c, b0, m, consts, arrays, out):
    """The law's trial of a block of committed contacts (``History.trial_block``, or :func:`each_contact`).

    A placeholder: each law's copy of the templates below calls that law's kernel here.
    """
    raise NotImplementedError("a template calls its law's kernel: compile it with kernels.specialise")


# ---- templates: each compiled once per law (kernels.specialise) with the options of its decorator;
# committed contacts live in slots (asp[sl] = asperity index, -1 a free slot) ----


@template(nogil=True, error_model="numpy")
def slot_pass(asp, n_slots, dn_c, r, R, u, cos_phi, sin_phi, delta, delta_c, r_o, k_e, consts, arrays,
              theta_birth, partial, claims, kk_lo, kk_hi):
    """Rows of ``partial``: the committed contacts at the trial displacement, from their history (read only).

    Chunks kk_lo .. kk_hi of the strided order (:func:`chunk_stride`), claimed (:func:`asperity_sim.threads.claim`).

    Under policy follow, per block of BLOCK slots: their inputs gathered contiguous, their
    geometry in a loop that LLVM vectorises (:func:`slot_geometry`), the law's trial per contact,
    then their global force and tangent in a vectorised loop and the sums in slot order.
    """
    asp, dn_c, r, R, u, cos_phi, sin_phi, arrays, theta_birth, partial = borrowed(
        (asp, dn_c, r, R, u, cos_phi, sin_phi, arrays, theta_birth, partial))  # no reference counts
    d1, d2, d3 = delta[0], delta[1], delta[2]
    D0, D1, D2 = d1 - delta_c[0], d2 - delta_c[1], d3 - delta_c[2]
    closure, dc = closure_and_slope(r_o, d1)
    n_chunks = (n_slots + CHUNK - 1) // CHUNK
    stride = chunk_stride(n_chunks)  # slots follow the heights: spread the large contacts over the threads
    for kk0 in range(kk_lo, kk_hi):
        kk = claim(claims, kk0)
        if kk >= kk_hi:
            break
        ic = (kk * stride) % n_chunks
        acc = np.zeros(N_ACC)
        lo, hi = ic * CHUNK, min(n_slots, (ic + 1) * CHUNK)
        if BIRTH:
            for sl in range(lo, hi):
                j = asp[sl]
                if j < 0:
                    continue
                cp, sp = cos_phi[j], sin_phi[j]
                th, th1 = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth,
                                        BIRTH)
                ct, st = math.cos(th), math.sin(th)
                dn, ds, dt = local_displacement(d1 - r[j], d2, d3, ct, st, cp, sp)
                if dn <= 0.0:
                    continue
                rho, dds, ddt = local_displacement(D0, D1, D2, ct, st, cp, sp)
                accumulate(acc, ct, st, cp, sp, trial(dn, dds, ddt, dn_c[sl], 0.0, R[j], consts, arrays, sl, False),
                           ds, rho, th1, dn, R[j])
                acc[I_TH] += th
            copy_into(partial[ic], acc)
            continue
        geo = np.empty((N_GEO, BLOCK))
        out = np.empty((13, BLOCK))
        vals = np.empty(N_VAL * BLOCK)
        for b0 in range(lo, hi, BLOCK):
            m = min(hi, b0 + BLOCK) - b0
            gather_slots(geo, asp, b0, m, d1, r, R, u, cos_phi, sin_phi)
            for i in range(m):  # vectorised
                slot_geometry(geo, i, d2, d3, D0, D1, D2, closure, dc, k_e)
            trial_block(geo[G_DN], geo[G_DDS], geo[G_DDT], geo[G_R], dn_c, b0, m, consts, arrays, out)  # the law
            for i in range(m):  # vectorised
                slot_values(vals, i, geo, out)
            add_values(vals, m, acc)
        copy_into(partial[ic], acc)


@template(error_model="numpy")
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


@kernel(inline="always")
def scan_chunks(n_active, index, n_box):
    """The chunks :func:`fresh_pass` goes through: of the n_box asperities it indexes (``index`` 1), else of
    n_active."""
    return ((n_box if index == 1 else n_active) + CHUNK - 1) // CHUNK


@template(nogil=True, error_model="numpy")
def fresh_pass(flag, n_active, r, R, u, cos_phi, sin_phi, delta, delta_c, delta_ref, r_o, k_e, consts, arrays, tan_max,
               partial, fresh, n_fresh, index, listed, n_listed, box, n_box, tan_box, claims, kk_lo, kk_hi):
    """Rows of ``partial``: asperities without a committed contact that touch at the trial displacement.

    They take their follow angle (SPEC §3) and start from no history; committed contacts are
    skipped by their flag, and the rest by :func:`may_touch_follow` before any trigonometry.
    The asperities found touching are listed, so that a commit at this displacement need not
    look for them again: chunk ic's in ``fresh[ic]`` (offsets from ic CHUNK, ascending), their
    count in ``n_fresh[ic]`` (the layout of :func:`~.commit.find_fresh`); a chunk with more than
    its row holds lists only the first (its count says so, and a commit searches again).

    ``index`` 0: every asperity below n_active is tested.  1: the same, and every asperity
    below ``n_box`` that may touch somewhere in ``box`` (2, 3; :func:`may_touch_within`, with
    ``tan_box`` the angle bound there), committed or not, is listed in ``listed``: chunk ic's
    from position ic CHUNK on, in order, as offsets from ic CHUNK (``OFFSET``: half the memory of an
    index), their count in ``n_listed[ic]``.  2: only the listed
    asperities are tested (the caller checked that the box holds delta).  The same asperities
    touch in the same order, so the sums have the same bits whatever the index.  Chunks kk_lo .. kk_hi of
    the strided order over :func:`scan_chunks`, claimed (:func:`asperity_sim.threads.claim`).
    """
    flag, r, R, u, cos_phi, sin_phi, arrays, partial, fresh, n_fresh, listed, n_listed = borrowed(
        (flag, r, R, u, cos_phi, sin_phi, arrays, partial, fresh, n_fresh, listed, n_listed))  # no reference counts
    d1, d2, d3 = delta[0], delta[1], delta[2]
    D0, D1, D2 = d1 - delta_c[0], d2 - delta_c[1], d3 - delta_c[2]
    closure, dc = closure_and_slope(r_o, d1)
    c_lo, _ = closure_and_slope(r_o, box[0, 0])
    c_hi, _ = closure_and_slope(r_o, box[1, 0])
    n_chunks = (n_active + CHUNK - 1) // CHUNK
    n_scan = scan_chunks(n_active, index, n_box)
    stride = chunk_stride(n_scan)
    for kk0 in range(kk_lo, kk_hi):
        kk = claim(claims, kk0)
        if kk >= kk_hi:
            break
        ic = (kk * stride) % n_scan
        lo = ic * CHUNK
        hi = min(n_active, lo + CHUNK)
        acc = np.zeros(N_ACC)
        nf = 0  # fresh contacts of this chunk
        if index == 2:
            n_it = n_listed[ic]
        else:
            n_it = min(n_box if index == 1 else n_active, lo + CHUNK) - lo
        m = 0
        for t in range(n_it):
            j = lo + listed[lo + t] if index == 2 else lo + t
            if index == 1:
                cp, sp = cos_phi[j], sin_phi[j]
                s_hi = max(cp * box[0, 1], cp * box[1, 1]) + max(sp * box[0, 2], sp * box[1, 2])
                inv_R = 1.0 / R[j]
                if not may_touch_within(box[1, 0] - r[j], s_hi, 1.0 - k_e * c_lo * inv_R, 1.0 - k_e * c_hi * inv_R,
                                        u[j] * (2.0 / math.pi), tan_box):
                    continue
                listed[lo + m] = j - lo
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
            if nf < fresh.shape[1]:
                fresh[ic, nf] = j - lo
            nf += 1
            dn_c = committed_overlap(j, r, u, inv_R, cp, sp, delta_c, r_o, k_e)
            dn_ref = committed_overlap(j, r, u, inv_R, cp, sp, delta_ref, r_o, k_e)
            rho, dds, ddt = local_displacement(D0, D1, D2, ct, st, cp, sp)
            accumulate(acc, ct, st, cp, sp, trial(dn, dds, ddt, dn_c, dn_ref, R[j], consts, arrays, 0, True), ds, rho,
                       th1, dn, R[j])
            acc[I_TH] += th
        if index == 1:
            n_listed[ic] = m
        if ic < n_chunks:
            copy_into(partial[ic], acc)
            n_fresh[ic] = nf


@template(nogil=True, error_model="numpy")
def snapshot_slots(slot_of, dn_c, code, r, R, u, cos_phi, sin_phi, delta, r_o, k_e, consts, arrays, theta_birth,
                   delta_n_out, theta_out, force_out, state_out, kk_lo, kk_hi):
    """Per-asperity overlap, angle, global force of the committed springs and state code (call right after commit).

    Asperities of chunks kk_lo .. kk_hi."""
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, dc = closure_and_slope(r_o, d1)
    for j in range(kk_lo * CHUNK, min(r.size, kk_hi * CHUNK)):
        cp, sp = cos_phi[j], sin_phi[j]
        th, _ = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth, BIRTH)
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
