"""The commit of an ``mdr`` contact: its springs written at the converged displacement.

Owns :func:`mdr_commit`, the law's ``commit`` kernel: springs written, a contact that outgrew
its 2k stored springs coarsened (neighbours merged, h doubled), and the energies of the
increment (work, stored energy, dissipation) returned for the balance.
"""

from __future__ import annotations

import numpy as np

from ...jit import kernel
from ..hertz import hertz_energy
from .springs import FAST, LANES, continuing_commit, entering_tail, release, spacing, spring_range, state_code
from .trial import springs


@kernel(error_model="numpy", fastmath=FAST)
def commit_springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, fresh, w_out):
    """:func:`springs` of a commit: writes the new springs to ``w_out``; (n_springs, n_slip, work, d_stored,
    dissipation) (no force or Jacobian: LLVM drops their arithmetic)."""
    out = springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, fresh, w_out, True)
    return out[8], out[9], out[10], out[11], out[12]


@kernel(inline="always", error_model="numpy")
def committed_commit_scaled(dn, dds, ddt, dn_c, lam, mu, w, c, q, n_in, rho, drho, n_c, e, e_c):
    """The commit of a committed contact (dn > 0) whose springs fit, in place, given its :func:`contact_scales`.

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


@kernel()
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


@kernel()
def mdr_commit(dn, dds, ddt, dn_c, dn_ref, R, consts, arrays, sl, fresh, scratch):
    """Write the springs of slot ``sl`` at the converged displacement; (code, work, stored, dissipation, coarsenings).

    dn <= 0: the contact is lost, its springs are released and its memory erased.  Energies
    [J] include the Hertz normal spring; ``stored`` is the contact's energy after the increment.
    ``scratch``: (2, 2 stored) floats for the new springs (a larger buffer is made when needed).

    The general step, for every case: the common one, a committed contact whose springs fit, goes
    through the lean loop of :func:`~asperity_sim.laws.mdr.blocks.mdr_commit_block` (the law's
    ``commit_block``) and comes here only when they do not.
    """
    E_star, lam, mu, k, dn_floor = consts
    w_all, h_all = arrays
    w = w_all[sl]
    n_store = w.shape[1]
    q_unit = 2.0 * E_star / lam
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
    buf = scratch if n_need <= scratch.shape[1] else np.zeros((2, n_need))
    n_springs, n_slip, work, _, diss = commit_springs(dn, dds, ddt, dn_c, R, E_star, lam, mu, w, h, scaled, fresh, buf)
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
