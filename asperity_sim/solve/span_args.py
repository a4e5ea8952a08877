"""What a law family's part of the compiled increments takes and gives back (:mod:`asperity_sim.solve.span`).

Owns :func:`supported` (whether the run's state can be handed to the compiled loop),
:func:`law_args` (the tuple of arrays of ``evaluate_at``, ``commit_at`` and ``serve``, with what to
do once the loop returned) and :func:`recorded` (the law's own per-step variables from what the
commits wrote).
"""

from __future__ import annotations

import numpy as np

from ..kernels import loop_path_independent as lpi
from ..kernels.layout import fits_serial


def supported(run) -> bool:
    """True if the run's law family has a part in the compiled loop, and its state can be handed to it."""
    if run.law.path_independent:
        return True
    return run.state.span_ready(run.ws)


def law_args(run, threads):
    """(law_args, after): the family's arrays for the loop, and ``after(m)``, called with the increments it made."""
    pop = run.pop
    if run.law.path_independent:
        r_o, k_e, _, _, _, beta, scale = pop.kernel_constants
        reals = np.zeros(lpi.N_PREALS)
        reals[[lpi.P_RO, lpi.P_KE, lpi.P_BETA, lpi.P_SCALE]] = r_o, k_e, beta, scale
        args = (*pop.arrays, pop.R_min, run.state.consts, run.ws.partial, pop.n, int(fits_serial(pop.n)), reals,
                np.zeros(2, dtype=np.int64), np.zeros(3))
        return args, lambda m: None
    return run.state.span_args(run.ws, threads)


def recorded(run, extra) -> dict:
    """The law's per-step variables of the steps whose commits wrote ``extra`` (rows)."""
    if run.law.path_independent:
        return {}
    return run.state.span_recorded(run, extra)
