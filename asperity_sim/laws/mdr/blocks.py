"""Block kernels of the ``mdr`` law: the trial and the commit of a block of committed contacts.

Owns ``trial_block`` and ``commit_block`` of the law protocol (:mod:`asperity_sim.laws`): the
scalars of every contact of a block (Hertz force, spring scale, normal increment) in one
vectorised loop (:func:`block_scales`), then each contact's springs, with the springs of the
contact ``AHEAD`` slots on asked for in advance (:func:`asperity_sim.vectormath.prefetch`).
"""

from __future__ import annotations

import numpy as np

from ...jit import kernel
from ...vectormath import borrowed, prefetch
from .commit import committed_commit_scaled, mdr_commit
from .springs import FAST, LANES, state_code
from .trial import committed_springs_scaled, contact_scales

AHEAD = 4  # a block kernel asks for the springs of the contact this many slots ahead (asperity_sim.vectormath)


@kernel(inline="always")
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


@kernel(inline="always", error_model="numpy")
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


@kernel(inline="always")
def prefetch_ahead(w_all, n_in, n_c, sl):
    """Prefetch the springs in contact (n_in), and those entering (n_c), of slot ``sl`` (the table's values as
    scalars: an array handed to an inlined function costs two atomic reference counts per contact)."""
    prefetch_springs(w_all, sl, max(int(n_in), int(n_c)) + LANES)


@kernel(error_model="numpy", fastmath=FAST)
def mdr_trial_block(dn, dds, ddt, R, dn_c, b0, m, consts, arrays, out):
    """:func:`mdr_trial` of the committed contacts in slots b0 .. b0 + m (dn[i] > 0; zeros in ``out`` elsewhere).

    First :func:`contact_scales` of every contact in one loop (LLVM vectorises it, and no
    contact's square roots and divisions wait behind another's springs), then the springs
    contact by contact.  The same values as :func:`mdr_trial` contact by contact.
    """
    E_star, lam, mu, k, dn_floor = consts
    w_all, h_all = borrowed(arrays)  # no reference counts in the loops (asperity_sim.vectormath.borrowed)
    sc = block_scales(dn, dn_c, R, h_all, b0, m, E_star, lam)
    for i in range(m):
        if i + AHEAD < m:
            prefetch_ahead(w_all, sc[S_NIN, i + AHEAD], sc[S_NC, i + AHEAD], b0 + i + AHEAD)
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


@kernel(error_model="numpy", fastmath=FAST)
def mdr_commit_block(dn, dds, ddt, R, dn_c, b0, m, live, consts, arrays, scratch, res):
    """:func:`mdr_commit` of the committed contacts in slots b0 .. b0 + m where ``live`` (res[:, i] = its 5 values).

    As :func:`mdr_trial_block`: the scales of every contact in contact first, in one loop that
    vectorises, then the springs contact by contact; a contact that is lost or outgrew its
    springs goes through :func:`mdr_commit`.  The same values as :func:`mdr_commit`.

    ``fresh`` goes to :func:`mdr_commit` as a run-time bool (``m < 0``): numba compiles a function
    once per argument type, and a literal ``False`` here and ``True`` in the fresh contacts' commit
    would compile the whole commit twice.
    """
    E_star, lam, mu, k, dn_floor = consts
    w_all, h_all = borrowed(arrays)  # no reference counts in the loops (asperity_sim.vectormath.borrowed)
    sc = block_scales(dn, dn_c, R, h_all, b0, m, E_star, lam)
    for i in range(m):
        if i + AHEAD < m:
            prefetch_ahead(w_all, sc[S_NIN, i + AHEAD], sc[S_NC, i + AHEAD], b0 + i + AHEAD)
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
                                                      m < 0, scratch)  # False, as a run-time bool (see below)
        res[0, i], res[1, i], res[2, i], res[3, i], res[4, i] = code, work, stored, diss, events
