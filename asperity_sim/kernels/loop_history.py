"""A history law's part of the compiled increments (:mod:`asperity_sim.kernels.loop`): templates.

Owns the trial at one displacement as :func:`asperity_sim.kernels.evaluate.at_contacts` makes it
(``evaluate_at``: the index of asperities near the path of
:meth:`~asperity_sim.kernels.workspace.Workspace.fresh_index`, then ``slot_pass`` and ``fresh_pass``
with their chunks claimed by every thread), the commit as
:meth:`~asperity_sim.kernels.state.ContactState.commit` makes it (``commit_at``: ``commit_slots``,
the contacts born, ``assign_slots`` and ``commit_fresh``, and the energies of the increment), and
the other threads' loop (``serve``).  The slot arrays must hold a slot for every asperity (they
never grow here).

``law_args`` (:func:`asperity_sim.solve.span_args.law_args`): the population's arrays (r, R, u,
cos_phi, sin_phi), R_min, the law's constants and number of asperities n; the committed state
(asp, dn_c, code, flag, the law's arrays, delta_c); the workspace's rows, fresh contacts and index
(partial, fresh, n_fresh, listed, n_listed, box); the commit's scratch (cpartial, by_slot, done,
new_slots, found, n_found); ``hints`` and ``hreals`` (H_*, HR_*); what the calling thread writes for
the others before each post (``post_i``, ``post_r``, ``d``, ``ref``).
"""

from __future__ import annotations


import numpy as np

from ..jit import kernel, template
from .commit import assign_slots, find_fresh
from .history import scan_chunks
from .layout import BLOCK, BLOCKS_PER_CHUNK, C_DISS, C_EVENTS, C_STORED, C_TR, C_WORK, CHUNK, N_COMMIT, O_NA, finish
from .loop import CLAIMS, CLAIMS2, KIND, STOP, next_post, post, said_done, wait_all
from .reach import bounds

# hints (int64): slots in use, threads, index on, box valid, n_box, trials by index (3), springs per slot, commits
H_NSLOTS, H_THREADS, H_INDEX, H_BOXOK, H_NBOX, H_TRIALS, H_NSTORE, H_COMMITS, N_HINTS = 0, 1, 2, 3, 4, 5, 8, 9, 10
HR_RO, HR_KE, HR_BETA, HR_SCALE, HR_TANBOX, N_HREALS = range(6)  # HR_SCALE: N w, of stresses and energies
# post_i: n_active, pop chunks, slot chunks, index, scan chunks, pieces, blocks (1: by blocks), n_new, slots
PI_NACTIVE, PI_NPOP, PI_NSLOTCH, PI_INDEX, PI_NSCAN, PI_PIECES, PI_BLOCKS, PI_NNEW, PI_NSLOTS, N_POSTI = range(10)
TRIAL, COMMIT_SLOTS, FIND_FRESH, COMMIT_FRESH = 1, 2, 3, 4  # kinds of part posted
AHEAD = 8.0  # Workspace.AHEAD


def slot_pass(asp, n_slots, dn_c, r, R, u, cos_phi, sin_phi, delta, delta_c, r_o, k_e, consts, arrays,
              theta_birth, partial, claims, kk_lo, kk_hi):
    """Placeholder: the law's copy (:mod:`asperity_sim.kernels.history`)."""
    raise NotImplementedError


def fresh_pass(flag, n_active, r, R, u, cos_phi, sin_phi, delta, delta_c, delta_ref, r_o, k_e, consts, arrays, tan_max,
               partial, fresh, n_fresh, index, listed, n_listed, box, n_box, tan_box, claims, kk_lo, kk_hi):
    """Placeholder: the law's copy (:mod:`asperity_sim.kernels.history`)."""
    raise NotImplementedError


def commit_slots(asp, n_slots, dn_c, code, flag, r, R, u, cos_phi, sin_phi, delta, delta_c, r_o, k_e, consts, arrays,
                 theta_birth, n_store, partial, by_slot, done, claims, kk_lo, kk_hi):
    """Placeholder: the law's copy (:mod:`asperity_sim.kernels.commit`)."""
    raise NotImplementedError


def commit_fresh(new_slots, asp, dn_c, code, r, R, u, cos_phi, sin_phi, delta, delta_c, delta_ref, r_o, k_e, consts,
                 arrays, n_store, partial, by_slot, done, claims, kk_lo, kk_hi):
    """Placeholder: the law's copy (:mod:`asperity_sim.kernels.commit`)."""
    raise NotImplementedError


@kernel(inline="always")
def chunks(n):
    return (n + CHUNK - 1) // CHUNK


@kernel()
def by_blocks(n, threads):
    """:func:`asperity_sim.kernels.state.by_blocks` on ``threads`` threads (:func:`asperity_sim.threads.uneven`)."""
    if n < 2 * BLOCK:
        return False
    full, rest = divmod(n, CHUNK)
    rounds, extra = divmod(full, threads)
    busiest = CHUNK * (rounds + 1) if extra else CHUNK * rounds + rest
    return threads > 1 and busiest > 1.05 * n / threads


@kernel()
def fresh_index(hints, hreals, box, r, R_min, d, delta_c, n_active):
    """:meth:`~asperity_sim.kernels.workspace.Workspace.fresh_index` (its list already allocated)."""
    if hints[H_INDEX] == 0:
        return 0
    if hints[H_BOXOK] == 1 and n_active <= hints[H_NBOX]:
        if (box[0, 0] <= d[0] <= box[1, 0] and box[0, 1] <= d[1] <= box[1, 1]
                and box[0, 2] <= d[2] <= box[1, 2]):
            return 2
    pad = 0.0
    for a in range(3):
        v = abs(d[a] - delta_c[a])
        if v > pad or v != v:
            pad = v
    if not pad > 0.0:
        return 0
    for a in range(3):
        ahead = delta_c[a] + AHEAD * (d[a] - delta_c[a])
        box[0, a] = min(delta_c[a], ahead) - pad
        box[1, a] = max(delta_c[a], ahead) + pad
    corner = np.array([box[1, 0], max(abs(box[0, 1]), abs(box[1, 1])), max(abs(box[0, 2]), abs(box[1, 2]))])
    n_box, tan_box = bounds(r, R_min, hreals[HR_RO], hreals[HR_KE], hreals[HR_BETA], corner, np.empty(0))
    hints[H_NBOX], hreals[HR_TANBOX] = n_box, tan_box
    hints[H_BOXOK] = 0
    return 1


@template(nogil=True, error_model="numpy")
def trial_part(law_args, claims_s, claims_f):
    """A thread's part of a trial: its claims of the slot pass, then of the fresh pass."""
    (r, R, u, cos_phi, sin_phi, R_min, consts, n, asp, dn_c, code, flag, arrays, delta_c, partial, fresh, n_fresh,
     listed, n_listed, box, cpartial, by_slot, done, new_slots, found, n_found, hints, hreals, post_i, post_r, d,
     ref) = law_args
    index, n_pop = post_i[PI_INDEX], post_i[PI_NPOP]
    if post_i[PI_NSLOTCH]:
        slot_pass(asp, hints[H_NSLOTS], dn_c, r, R, u, cos_phi, sin_phi, d, delta_c, hreals[HR_RO], hreals[HR_KE],
                  consts, arrays, np.empty(0), partial[n_pop:], claims_s, 0, post_i[PI_NSLOTCH])
    fresh_pass(flag, post_i[PI_NACTIVE], r, R, u, cos_phi, sin_phi, d, delta_c, ref, hreals[HR_RO], hreals[HR_KE],
               consts, arrays, post_r[0], partial, fresh, n_fresh, index, listed if index else listed[:0],
               n_listed if index else n_listed[:0], box, hints[H_NBOX], hreals[HR_TANBOX], claims_f, 0,
               post_i[PI_NSCAN])


@template(nogil=True, error_model="numpy")
def commit_part(law_args, kind, claims, t, threads):
    """One thread's part of a commit: its claims of ``commit_slots`` or ``commit_fresh``, or its range of the search
    for contacts born."""
    (r, R, u, cos_phi, sin_phi, R_min, consts, n, asp, dn_c, code, flag, arrays, delta_c, partial, fresh, n_fresh,
     listed, n_listed, box, cpartial, by_slot, done, new_slots, found, n_found, hints, hreals, post_i, post_r, d,
     ref) = law_args
    blocks = post_i[PI_BLOCKS] == 1
    if kind == COMMIT_SLOTS:
        n_ch = chunks(post_i[PI_NSLOTS])
        commit_slots(asp, post_i[PI_NSLOTS], dn_c, code, flag, r, R, u, cos_phi, sin_phi, d, delta_c, hreals[HR_RO],
                     hreals[HR_KE], consts, arrays, np.empty(0), hints[H_NSTORE], cpartial,
                     by_slot if blocks else by_slot[:, :0], done[:n_ch] if blocks else done[:0], claims, 0,
                     post_i[PI_PIECES])
    elif kind == FIND_FRESH:
        n_ch = post_i[PI_NPOP]
        find_fresh(flag, post_i[PI_NACTIVE], r, R, u, cos_phi, sin_phi, d, hreals[HR_RO], hreals[HR_KE], post_r[0],
                   found, n_found, n_ch * t // threads, n_ch * (t + 1) // threads)
    else:
        n_ch = chunks(post_i[PI_NNEW])
        commit_fresh(new_slots[:post_i[PI_NNEW]], asp, dn_c, code, r, R, u, cos_phi, sin_phi, d, delta_c, ref,
                     hreals[HR_RO], hreals[HR_KE], consts, arrays, hints[H_NSTORE], cpartial,
                     by_slot if blocks else by_slot[:, :0], done[:n_ch] if blocks else done[:0], claims, 0,
                     post_i[PI_PIECES])


@template(nogil=True, error_model="numpy")
def evaluate_at(flags, law_args, x, ref_now, out, shared):
    """``out``: the trial at ``x`` with fresh contacts' springs fitted to ``ref_now``."""
    (r, R, u, cos_phi, sin_phi, R_min, consts, n, asp, dn_c, code, flag, arrays, delta_c, partial, fresh, n_fresh,
     listed, n_listed, box, cpartial, by_slot, done, new_slots, found, n_found, hints, hreals, post_i, post_r, d,
     ref) = law_args
    d[:] = x
    ref[:] = ref_now
    n_active, tan_max = bounds(r, R_min, hreals[HR_RO], hreals[HR_KE], hreals[HR_BETA], d, np.empty(0))
    n_pop, n_slot = chunks(n_active), chunks(hints[H_NSLOTS])
    index = fresh_index(hints, hreals, box, r, R_min, d, delta_c, n_active)
    post_i[PI_NACTIVE], post_i[PI_NPOP], post_i[PI_NSLOTCH], post_i[PI_INDEX] = n_active, n_pop, n_slot, index
    post_i[PI_NSCAN] = scan_chunks(n_active, index, hints[H_NBOX])
    post_r[0] = tan_max
    if shared:
        epoch = post(flags, TRIAL)
        trial_part(law_args, flags[CLAIMS:CLAIMS + 1], flags[CLAIMS2:CLAIMS2 + 1])
        wait_all(flags, epoch, hints[H_THREADS])
    else:
        trial_part(law_args, flags[0:0], flags[0:0])
    hints[H_TRIALS + index] += 1
    if index == 1:
        hints[H_BOXOK] = 1
    finish(partial, n_pop + n_slot, n, hreals[HR_SCALE], out)
    out[O_NA] = n_active


@template(nogil=True, error_model="numpy")
def commit_step(flags, law_args, kind, shared):
    """Run one kind of commit part on every thread."""
    threads = law_args[26][H_THREADS]
    if shared:
        epoch = post(flags, kind)
        commit_part(law_args, kind, flags[CLAIMS:CLAIMS + 1], 0, threads)
        wait_all(flags, epoch, threads)
    else:
        commit_part(law_args, kind, flags[0:0], 0, 1)


@template(nogil=True, error_model="numpy")
def commit_at(flags, law_args, x, ref_now, out, extra, shared):
    """Commit the trial at ``x`` (the last one made): the contacts held, then those born; ``extra`` the increment's
    work, stored energy, dissipation, events and transitions (4 x 4, row-major) [J m-2, counts]."""
    (r, R, u, cos_phi, sin_phi, R_min, consts, n, asp, dn_c, code, flag, arrays, delta_c, partial, fresh, n_fresh,
     listed, n_listed, box, cpartial, by_slot, done, new_slots, found, n_found, hints, hreals, post_i, post_r, d,
     ref) = law_args
    d[:] = x
    n_active, tan_max = bounds(r, R_min, hreals[HR_RO], hreals[HR_KE], hreals[HR_BETA], d, np.empty(0))
    n_slots = hints[H_NSLOTS]
    n_pop_chunks = chunks(n_active)
    sums = np.zeros(N_COMMIT)
    if n_slots:
        post_i[PI_NSLOTS] = n_slots
        _commit_pieces(flags, law_args, COMMIT_SLOTS, n_slots, sums, shared)
    most = 0
    for ic in range(n_pop_chunks):
        most = max(most, n_fresh[ic])
    if most > fresh.shape[1]:  # a chunk had more contacts born than the trial's list holds: look for them
        post_i[PI_NACTIVE], post_i[PI_NPOP], post_r[0] = n_active, n_pop_chunks, tan_max
        commit_step(flags, law_args, FIND_FRESH, shared)
        born, n_born = found, n_found
    else:
        born, n_born = fresh, n_fresh
    n_new = 0
    for ic in range(n_pop_chunks):
        n_new += n_born[ic]
    if n_new:
        n_slots = assign_slots(flag, born, n_born[:n_pop_chunks], asp, n_slots, new_slots[:n_new])
        hints[H_NSLOTS], post_i[PI_NNEW] = n_slots, n_new
        _commit_pieces(flags, law_args, COMMIT_FRESH, n_new, sums, shared)
    scale = hreals[HR_SCALE]
    extra[0], extra[1], extra[2] = scale * sums[C_WORK], scale * sums[C_STORED], scale * sums[C_DISS]
    extra[3] = np.rint(sums[C_EVENTS])
    total = 0
    for i in range(16):
        v = np.rint(sums[C_TR + i])
        extra[4 + i] = v
        total += int(v)
    extra[4] = n - total  # out of contact before and after (the count of the sums included)
    hints[H_COMMITS] += 1
    delta_c[:] = x


@template(nogil=True, error_model="numpy")
def _commit_pieces(flags, law_args, kind, n, sums, shared):
    """Commit n contacts (``kind``) as :meth:`~asperity_sim.kernels.state.ContactState.commit` hands them out: by
    blocks where :func:`by_blocks` says so, else chunk by chunk; their sums added to ``sums``."""
    cpartial, done, hints, post_i = law_args[20], law_args[22], law_args[26], law_args[28]
    n_chunks = chunks(n)
    blocks = by_blocks(n, hints[H_THREADS])
    post_i[PI_BLOCKS] = int(blocks)
    post_i[PI_PIECES] = n_chunks * BLOCKS_PER_CHUNK if blocks else n_chunks
    done[:n_chunks] = 0
    commit_step(flags, law_args, kind, shared)
    _add_rows(sums, cpartial, n_chunks)


@kernel(inline="always")
def _add_rows(sums, rows, k):
    """sums += rows[:k].sum(axis=0), in numpy's order (the rows one after the other)."""
    part = rows[0].copy()
    for i in range(1, k):
        part += rows[i]
    sums += part


@template(nogil=True, error_model="numpy")
def serve(flags, law_args, t):
    """Thread t: its claims of each posted trial or commit, until STOP."""
    threads = law_args[26][H_THREADS]
    seen = 0
    while True:
        seen = next_post(flags, seen)
        if seen == STOP:
            return
        kind = flags[KIND]
        if kind == TRIAL:
            trial_part(law_args, flags[CLAIMS:CLAIMS + 1], flags[CLAIMS2:CLAIMS2 + 1])
        else:
            commit_part(law_args, kind, flags[CLAIMS:CLAIMS + 1], t, threads)
        said_done(flags, t, seen)
