"""A path-independent law's part of the compiled increments (:mod:`asperity_sim.kernels.loop`): templates.

Owns the evaluation at one displacement as :func:`asperity_sim.kernels.evaluate.at_contacts` makes
it (``evaluate_at``: on the calling thread when the population or the asperities that can touch
fit the serial kernel, else ``reduce_parallel`` with its chunks claimed by every thread), the
other threads' loop (``serve``) and the commit, which keeps nothing (``commit_at``).

``law_args``: (r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, serial, reals, counts, d):
the population's arrays, the law's constants, the workspace's rows of partial sums, the number of
asperities, 1 if the population fits the serial kernel, ``reals`` (r_o, k_e, beta, scale, tan_max),
and what the calling thread writes for the others before each post: ``counts`` (n_active,
chunks) and ``d``, the displacement.
"""

from __future__ import annotations

import numpy as np

from ..jit import template
from .layout import CHUNK, N_OUT, O_NA, SERIAL_ACTIVE_CHUNKS, finish
from .loop import CLAIMS, DONE, STOP, next_post, post, said_done, wait_all
from .reach import bounds

P_RO, P_KE, P_BETA, P_SCALE, P_TANMAX, N_PREALS = range(6)
EVALUATE = 1  # the one kind of part posted


def reduce_parallel(r, R, u, cos_phi, sin_phi, n_active, delta, r_o, k_e, consts, theta_birth, tan_max, partial,
                    claims, kk_lo, kk_hi):
    """Placeholder: the law's copy (:mod:`asperity_sim.kernels.reductions`)."""
    raise NotImplementedError


def reduce_serial(r, R, u, cos_phi, sin_phi, R_min, deltas, r_o, k_e, consts, beta, theta_birth, n, scale, partial,
                  out):
    """Placeholder: the law's copy (:mod:`asperity_sim.kernels.reductions`)."""
    raise NotImplementedError


@template(nogil=True, error_model="numpy")
def evaluate_at(flags, law_args, x, ref, out, shared):
    """``out``: the flat result at ``x`` (``ref`` unused: no history)."""
    r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, serial, reals, counts, d = law_args
    r_o, k_e, beta, scale = reals[P_RO], reals[P_KE], reals[P_BETA], reals[P_SCALE]
    empty = np.empty(0)
    d[:] = x
    n_active, tan_max = 0, 0.0
    on_caller = serial == 1
    if not on_caller:
        n_active, tan_max = bounds(r, R_min, r_o, k_e, beta, d, empty)
        on_caller = n_active <= SERIAL_ACTIVE_CHUNKS * CHUNK
    if on_caller:
        reduce_serial(r, R, u, cos_phi, sin_phi, R_min, d.reshape(1, 3), r_o, k_e, consts, beta, empty, n, scale,
                      partial, out.reshape(1, N_OUT))
        return
    n_chunks = (n_active + CHUNK - 1) // CHUNK
    if shared:
        counts[0], counts[1], reals[P_TANMAX] = n_active, n_chunks, tan_max
        epoch = post(flags, EVALUATE)
        reduce_parallel(r, R, u, cos_phi, sin_phi, n_active, d, r_o, k_e, consts, empty, tan_max, partial,
                        flags[CLAIMS:CLAIMS + 1], 0, n_chunks)
        wait_all(flags, epoch, (flags.size - DONE) // 8)
    else:
        reduce_parallel(r, R, u, cos_phi, sin_phi, n_active, d, r_o, k_e, consts, empty, tan_max, partial,
                        flags[0:0], 0, n_chunks)
    finish(partial, n_chunks, n, scale, out)
    out[O_NA] = n_active


@template(nogil=True, error_model="numpy")
def commit_at(flags, law_args, x, ref, out, extra, shared):
    """Nothing to commit: the state is the displacement, which the run keeps."""
    return


@template(nogil=True, error_model="numpy")
def serve(flags, law_args, t):
    """Thread t: each posted evaluation's claimed chunks, until STOP."""
    r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, serial, reals, counts, d = law_args
    empty = np.empty(0)
    seen = 0
    while True:
        seen = next_post(flags, seen)
        if seen == STOP:
            return
        reduce_parallel(r, R, u, cos_phi, sin_phi, counts[0], d, reals[P_RO], reals[P_KE], consts, empty,
                        reals[P_TANMAX], partial, flags[CLAIMS:CLAIMS + 1], 0, counts[1])
        said_done(flags, t, seen)
