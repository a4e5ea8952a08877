"""Reductions of a path-independent law over the population (templates, compiled once per law).

Owns the sums of Eq. (23) for a law without history: under policy follow a branch-free block
loop that LLVM vectorises (:func:`values_follow`, :func:`chunk_follow`), under policy birth a
scalar loop with the frozen angles (:func:`chunk_birth`); parallel over chunks
(:func:`reduce_parallel`) or on the calling thread for small workloads and batches of
displacements (:func:`reduce_serial`); and the per-asperity snapshot.  ``local`` is the law's
kernel, bound per law by :mod:`asperity_sim.kernels.specialise`.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import closure_and_slope, local_displacement
from ..jit import template
from ..threads import claim
from ..vectormath import borrowed, copy_into
from .contact import (
    accumulate,
    add_values,
    contact_angle,
    contact_area,
    follow_angle,
    follow_slope,
    global_force_tangent,
    store_values,
)
from .layout import (BIRTH, BLOCK, CHUNK, I_TH, N_ACC, N_IN, N_VAL, O_NA, X_CP, X_R, X_SP, X_U, X_X, chunk_stride,
                     finish)
from .reach import bounds, cannot_touch, may_touch_follow

# ---- the law's kernel: a placeholder, bound to the law's own by kernels.specialise ----


def local(dn, ds, dt, R, consts):
    """The path-independent law's kernel (``Law.local``): 13 values, force, Jacobian, state code.

    A placeholder: each law's copy of the templates below calls that law's kernel here.
    """
    raise NotImplementedError("a template calls its law's kernel: compile it with kernels.specialise")


# ---- templates: each compiled once per law (kernels.specialise) with the options of its decorator ----


@template(inline="always", error_model="numpy")
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
    a, a0, a1, a2 = contact_area(R_j, dn, ct, st, cp, sp, ds, th1)
    store_values(vals, i, touch, code, th, g0, g1, g2, T0, T1, T2, T3, T4, T5, T6, T7, T8, a, a0, a1, a2)


@template(error_model="numpy")
def chunk_follow(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, tan_max, partial):
    """Row ic of ``partial`` under policy follow: :func:`values_follow` over the asperities that may touch.

    Per block of BLOCK asperities: unless the whole block lies below the closure, a loop that
    LLVM vectorises marks the asperities :func:`may_touch_follow` keeps (no trigonometry, no
    branch) and a scalar pass lists them; their inputs are copied, contiguous, into ``inp`` and
    :func:`values_follow` fills ``vals`` in a loop that LLVM vectorises; the columns are summed in
    order (no fastmath: the same bits however LLVM vectorised).  One call site of
    :func:`values_follow`, for both kinds of block: numba inlines a copy of it per call site, and
    the copy is most of the kernel's compile time.
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
                at[i] = b0 + i
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
    copy_into(partial[ic], acc)


@template(inline="always", error_model="numpy")
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
        accumulate(acc, ct, st, cp, sp, local(dn, ds, dt, R[j], consts), ds, dn, th1, dn, R[j])
        acc[I_TH] += th
    copy_into(partial[ic], acc)


@template(inline="always", error_model="numpy")
def chunk_any(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, theta_birth, tan_max,
              partial):
    """Row ic of ``partial`` under the copy's policy (``BIRTH``, a constant: the other branch is pruned before
    numba inlines it)."""
    if BIRTH:
        chunk_birth(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, theta_birth,
                    tan_max, partial)
    else:
        chunk_follow(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, tan_max, partial)


@template(nogil=True, error_model="numpy")
def reduce_parallel(r, R, u, cos_phi, sin_phi, n_active, delta, r_o, k_e, consts, theta_birth, tan_max, partial,
                    claims, kk_lo, kk_hi):
    """Partial sums of a path-independent law over the first n_active asperities, chunks kk_lo .. kk_hi.

    Chunks go to the threads as they claim them (:func:`asperity_sim.threads.claim`) in the strided
    order of :func:`chunk_stride`, so both threads get low (in contact, costly) and high (cheap)
    heights; rows are overwritten.
    """
    r, R, u, cos_phi, sin_phi, theta_birth, partial = borrowed(
        (r, R, u, cos_phi, sin_phi, theta_birth, partial))  # no reference counts (vectormath.borrowed)
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, dc = closure_and_slope(r_o, d1)
    n_chunks = (n_active + CHUNK - 1) // CHUNK
    stride = chunk_stride(n_chunks)
    for kk0 in range(kk_lo, kk_hi):
        kk = claim(claims, kk0)
        if kk >= kk_hi:
            break
        chunk_any((kk * stride) % n_chunks, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts,
                  theta_birth, tan_max, partial)


@template(error_model="numpy")
def reduce_serial(r, R, u, cos_phi, sin_phi, R_min, deltas, r_o, k_e, consts, beta, theta_birth, n, scale, partial,
                  out):
    """The flat result (:func:`finish`) at every row of ``deltas`` (m, 3), on the calling thread.

    The same rows of partial sums as :func:`bounds` + ``reduce_parallel`` + :func:`finish`, so
    the same bits.  For small workloads: a parallel region costs tens of microseconds on an
    idle machine and milliseconds on a loaded one, and the increments of a
    displacement-controlled stage of a path-independent law are independent, so a small
    population need not pay a round trip through Python for each of them.
    """
    r, R, u, cos_phi, sin_phi, theta_birth, partial = borrowed(
        (r, R, u, cos_phi, sin_phi, theta_birth, partial))  # no reference counts (vectormath.borrowed)
    for i in range(deltas.shape[0]):
        d1, d2, d3 = deltas[i, 0], deltas[i, 1], deltas[i, 2]
        n_active, tan_max = bounds(r, R_min, r_o, k_e, beta, deltas[i], theta_birth)
        closure, dc = closure_and_slope(r_o, d1)
        n_chunks = (n_active + CHUNK - 1) // CHUNK
        for ic in range(n_chunks):
            chunk_any(ic, r, R, u, cos_phi, sin_phi, n_active, d1, d2, d3, closure, dc, k_e, consts, theta_birth,
                      tan_max, partial)
        finish(partial, n_chunks, n, scale, out[i])
        out[i, O_NA] = n_active


@template(nogil=True, error_model="numpy")
def snapshot_local(r, R, u, cos_phi, sin_phi, delta, r_o, k_e, consts, theta_birth, delta_n_out, theta_out,
                   force_out, state_out, kk_lo, kk_hi):
    """Per-asperity overlap, orientation, global force and state code of a path-independent law (chunks kk_lo ..
    kk_hi of asperities)."""
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, _ = closure_and_slope(r_o, d1)
    for j in range(kk_lo * CHUNK, min(r.size, kk_hi * CHUNK)):
        cp, sp = cos_phi[j], sin_phi[j]
        th, _ = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, 0.0, theta_birth, BIRTH)
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
