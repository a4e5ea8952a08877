"""The commit kernels: committed contacts, contacts born, slots and birth angles.

Owns the kernels that write committed state (called only by
:meth:`asperity_sim.kernels.state.ContactState.commit`): the commit of every committed contact
(contacts lost are released and their slots freed), the search for contacts born in the
increment, their slots (lowest free first, in asperity order) and commit from no history,
and the birth angles of policy ``birth``.  ``commit_law`` and ``commit_block`` are the law's
kernels, bound per law by :mod:`asperity_sim.kernels.specialise`.
"""

from __future__ import annotations

import math

import numpy as np

from ..atomics import fetch_add_acq_rel
from ..geometry import closure_and_slope, local_displacement
from ..jit import kernel, template
from ..threads import chunks_of, claim, run_chunks
from ..vectormath import borrowed, copy_into
from .contact import asperity_theta, committed_overlap, contact_angle, gather_slots, slot_geometry
from .layout import (
    BIRTH,
    BLOCK,
    B_DISS,
    B_EVENTS,
    B_STORED,
    B_TR,
    B_WORK,
    BLOCKS_PER_CHUNK,
    C_DISS,
    C_EVENTS,
    C_STORED,
    C_TR,
    C_WORK,
    CHUNK,
    G_DDS,
    G_DDT,
    G_DN,
    G_R,
    N_COMMIT,
    N_GEO,
    chunk_stride,
)
from .reach import may_touch_follow

# ---- the law's kernels: placeholders, bound to the law's own by kernels.specialise ----


def commit_law(dn, dds, ddt, dn_c, dn_ref, R, consts, arrays, sl, fresh, scratch):
    """The history law's commit of one contact (``History.commit``): writes its state, returns the energies.

    A placeholder: each law's copy of the templates below calls that law's kernel here.
    """
    raise NotImplementedError("a template calls its law's kernel: compile it with kernels.specialise")


def commit_block(dn, dds, ddt, R, dn_c, b0, m, live, consts, arrays, scratch, res):
    """The law's commit of a block of committed contacts (``History.commit_block``, or :func:`each_commit`).

    A placeholder: each law's copy of the templates below calls that law's kernel here.
    """
    raise NotImplementedError("a template calls its law's kernel: compile it with kernels.specialise")


# ---- templates: each compiled once per law (kernels.specialise) with the options of its decorator ----


@template(error_model="numpy")
def each_commit(dn, dds, ddt, R, dn_c, b0, m, live, consts, arrays, scratch, res):
    """The law's ``commit_block`` for a law without one: ``commit`` of each live committed contact."""
    for i in range(m):
        if live[i]:
            code, work, stored, diss, events = commit_law(dn[i], dds[i], ddt[i], dn_c[b0 + i], 0.0, R[i], consts,
                                                          arrays, b0 + i, m < 0, scratch)  # False, run time
            res[0, i], res[1, i], res[2, i], res[3, i], res[4, i] = code, work, stored, diss, events


@template(nogil=True, error_model="numpy")
def commit_slots(asp, n_slots, dn_c, code, flag, r, R, u, cos_phi, sin_phi, delta, delta_c, r_o, k_e, consts, arrays,
                 theta_birth, n_store, partial, by_slot, done, claims, kk_lo, kk_hi):
    """Commit the committed contacts of chunks kk_lo .. kk_hi (strided order, claimed) at the converged ``delta``; sums
    (N_COMMIT) per chunk into ``partial``.

    A contact that is lost is released by the law, its slot freed (asp = -1) and its flag cleared.
    Under policy follow the geometry of a block of slots is computed as in :func:`slot_pass` (the same
    bits as the trial at ``delta``; a trial keeps none of it for the commit: 32 B per contact).

    By blocks (``done`` not empty: a chunk count per chunk): the pieces claimed are the blocks of
    BLOCK slots of each chunk in turn (BLOCKS_PER_CHUNK, the last maybe empty), so that a few
    chunks still spread evenly over the threads.  Each contact's sums go to its column of
    ``by_slot`` (:func:`slot_sums`), and the thread that finishes a chunk's last block adds them up
    in slot order: the same sums, the same bits, as chunk by chunk.
    """
    asp, dn_c, code, flag, r, R, u, cos_phi, sin_phi, arrays, theta_birth, partial, by_slot = borrowed(
        (asp, dn_c, code, flag, r, R, u, cos_phi, sin_phi, arrays, theta_birth, partial, by_slot))
    d1, d2, d3 = delta[0], delta[1], delta[2]
    D0, D1, D2 = d1 - delta_c[0], d2 - delta_c[1], d3 - delta_c[2]
    closure, dc = closure_and_slope(r_o, d1)
    n_chunks = (n_slots + CHUNK - 1) // CHUNK
    stride = chunk_stride(n_chunks)  # slots follow the heights: spread the large contacts over the threads
    blocks = done.size > 0
    scratch = np.zeros((2, 2 * n_store))  # the law's scratch: two rows of twice the stored springs
    geo = np.empty((N_GEO, BLOCK))
    live = np.empty(BLOCK, dtype=np.bool_)
    res = np.empty((5, BLOCK))
    for kk0 in range(kk_lo, kk_hi):
        kk = claim(claims, kk0)
        if kk >= kk_hi:
            break
        ic, lo, hi = piece(kk, blocks, stride, n_chunks, n_slots)
        acc = np.zeros(N_COMMIT)
        work = stored = diss = events = 0.0
        for b0 in range(lo, hi, BLOCK):
            m = min(hi, b0 + BLOCK) - b0
            if BIRTH:
                for i in range(m):
                    j = asp[b0 + i]
                    if j < 0:
                        continue
                    cp, sp = cos_phi[j], sin_phi[j]
                    th, _ = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth,
                                          BIRTH)
                    ct, st = math.cos(th), math.sin(th)
                    geo[G_DN, i], _, _ = local_displacement(d1 - r[j], d2, d3, ct, st, cp, sp)
                    _, geo[G_DDS, i], geo[G_DDT, i] = local_displacement(D0, D1, D2, ct, st, cp, sp)
                    geo[G_R, i] = R[j]
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
                    if blocks:
                        by_slot[B_TR, sl] = -1.0
                    continue
                dn = geo[G_DN, i]
                new = int(res[0, i])
                if blocks:
                    by_slot[B_WORK, sl], by_slot[B_STORED, sl], by_slot[B_DISS, sl] = res[1, i], res[2, i], res[3, i]
                    by_slot[B_EVENTS, sl], by_slot[B_TR, sl] = res[4, i], float(4 * code[sl] + new)
                else:
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
        if not blocks:
            acc[C_WORK], acc[C_STORED], acc[C_DISS], acc[C_EVENTS] = work, stored, diss, events
            copy_into(partial[ic], acc)
        elif last_block(done, ic):
            slot_sums(by_slot, ic * CHUNK, min(n_slots, (ic + 1) * CHUNK), partial[ic])


@kernel(inline="always")
def piece(kk, blocks, stride, n_chunks, n):
    """Piece kk of a commit of n contacts: (chunk ic, contacts lo .. hi).  Chunk by chunk, chunk kk in the strided
    order (``stride`` 1: in order); by blocks, block kk % BLOCKS_PER_CHUNK of chunk kk // BLOCKS_PER_CHUNK (maybe
    empty)."""
    per = BLOCKS_PER_CHUNK if blocks else 1
    ic = ((kk // per) * stride) % n_chunks
    lo, hi = ic * CHUNK, min(n, (ic + 1) * CHUNK)
    if blocks:
        lo = min(hi, lo + (kk % per) * BLOCK)
        hi = min(hi, lo + BLOCK)
    return ic, lo, hi


@kernel(inline="always")
def last_block(done, ic):
    """Count a block of chunk ic done; True for the chunk's last (its thread then sums the chunk, reading what the
    other threads wrote: the count orders memory)."""
    return fetch_add_acq_rel(done, ic, 1) == BLOCKS_PER_CHUNK - 1


@kernel(inline="always")
def slot_sums(by_slot, lo, hi, row):
    """``row`` (N_COMMIT): the sums of slots lo .. hi from their columns of ``by_slot``, in slot order (the order,
    and so the bits, of :func:`commit_slots` chunk by chunk)."""
    acc = np.zeros(N_COMMIT)
    work = stored = diss = events = 0.0
    for sl in range(lo, hi):
        tr = by_slot[B_TR, sl]
        if tr < 0.0:
            continue
        work += by_slot[B_WORK, sl]
        stored += by_slot[B_STORED, sl]
        diss += by_slot[B_DISS, sl]
        events += by_slot[B_EVENTS, sl]
        acc[C_TR + int(tr)] += 1.0
    acc[C_WORK], acc[C_STORED], acc[C_DISS], acc[C_EVENTS] = work, stored, diss, events
    copy_into(row, acc)


@kernel(nogil=True)
def find_fresh(flag, n_active, r, R, u, cos_phi, sin_phi, delta, r_o, k_e, tan_max, fresh, n_fresh, kk_lo, kk_hi):
    """The asperities of chunks kk_lo .. kk_hi below n_active without a committed contact that touch at ``delta``:
    chunk ic's in ``fresh[ic]`` (offsets from ic CHUNK, ascending), their count in ``n_fresh[ic]``.

    The test and the layout of the list a trial's :func:`~.history.fresh_pass` leaves: a commit
    at the displacement of its last trial takes that list and needs no search.
    """
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, _ = closure_and_slope(r_o, d1)
    for ic in range(kk_lo, kk_hi):
        nf = 0
        lo = ic * CHUNK
        for j in range(lo, min(n_active, lo + CHUNK)):
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
                fresh[ic, nf] = j - lo
                nf += 1
        n_fresh[ic] = nf


@template(nogil=True, error_model="numpy")
def commit_fresh(new_slots, asp, dn_c, code, r, R, u, cos_phi, sin_phi, delta, delta_c, delta_ref, r_o, k_e, consts,
                 arrays, n_store, partial, by_slot, done, claims, kk_lo, kk_hi):
    """Commit the contacts born in this increment (slots ``new_slots``, assigned in asperity order), chunks
    kk_lo .. kk_hi of them (claimed).  By blocks (``done`` not empty) as :func:`commit_slots`, each contact's
    sums in column ii (its place in ``new_slots``) of ``by_slot``."""
    new_slots, asp, dn_c, code, r, R, u, cos_phi, sin_phi, arrays, partial, by_slot = borrowed(
        (new_slots, asp, dn_c, code, r, R, u, cos_phi, sin_phi, arrays, partial, by_slot))  # no reference counts
    d1, d2, d3 = delta[0], delta[1], delta[2]
    D0, D1, D2 = d1 - delta_c[0], d2 - delta_c[1], d3 - delta_c[2]
    closure, _ = closure_and_slope(r_o, d1)
    m = new_slots.size
    # True as a run-time bool: with literal True here and False in the committed contacts' commit, numba would
    # compile the law's commit twice (once per argument type)
    fresh = m >= 0
    blocks = done.size > 0
    n_chunks = (m + CHUNK - 1) // CHUNK
    scratch = np.zeros((2, 2 * n_store))  # the law's scratch: two rows of twice the stored springs
    for kk0 in range(kk_lo, kk_hi):
        kk = claim(claims, kk0)
        if kk >= kk_hi:
            break
        ic, lo, hi = piece(kk, blocks, 1, n_chunks, m)
        acc = np.zeros(N_COMMIT)
        for ii in range(lo, hi):
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
            new, work, stored, diss, events = commit_law(dn, dds, ddt, dnc, dn_ref, R[j], consts, arrays, sl, fresh,
                                                         scratch)
            if blocks:
                by_slot[B_WORK, ii], by_slot[B_STORED, ii], by_slot[B_DISS, ii] = work, stored, diss
                by_slot[B_EVENTS, ii], by_slot[B_TR, ii] = events, float(new)  # born: code 0 before
            else:
                acc[C_WORK] += work
                acc[C_STORED] += stored
                acc[C_DISS] += diss
                acc[C_EVENTS] += events
                acc[C_TR + new] += 1.0
            dn_c[sl] = dn
            code[sl] = new
        if not blocks:
            copy_into(partial[ic], acc)
        elif last_block(done, ic):
            slot_sums(by_slot, ic * CHUNK, min(m, (ic + 1) * CHUNK), partial[ic])


def birth_angles(r, R, u, cos_phi, sin_phi, n_active, delta, r_o, k_e, theta_birth):
    """Commit the birth angles at delta (policy ``birth``, SPEC §3), in place (:func:`birth_angles_in` over
    every chunk)."""
    run_chunks(birth_angles_in, chunks_of(theta_birth.size, CHUNK), r, R, u, cos_phi, sin_phi, n_active, delta, r_o,
               k_e, theta_birth)


@kernel(nogil=True)
def birth_angles_in(r, R, u, cos_phi, sin_phi, n_active, delta, r_o, k_e, theta_birth, kk_lo, kk_hi):
    """Commit the birth angles at delta (policy ``birth``, SPEC §3), in place, of the asperities of chunks
    kk_lo .. kk_hi.

    A committed contact that stays in contact keeps its angle; one that leaves contact is
    released (NaN) and, like every asperity without an angle, is born at its current
    ``follow`` angle if it touches there.  Asperities beyond n_active are out of contact.
    """
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, _ = closure_and_slope(r_o, d1)
    for j in range(kk_lo * CHUNK, min(theta_birth.size, kk_hi * CHUNK)):
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


@kernel()
def assign_slots(flag, fresh, n_fresh, asp, n_slots, new_slots):
    """Give each fresh asperity (listed as :func:`find_fresh` lists them) a slot, lowest free slot first, in
    asperity order, and flag it (1).

    Returns the new number of slots in use (free slots have asp = -1); ``new_slots`` receives
    the slots given, in order.
    """
    free = 0
    m = 0
    for ic in range(n_fresh.size):
        for c in range(n_fresh[ic]):
            j = ic * CHUNK + fresh[ic, c]
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
