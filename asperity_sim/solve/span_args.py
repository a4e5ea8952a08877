"""What a law family's part of the compiled increments takes and gives back (:mod:`asperity_sim.solve.span`).

Owns :func:`supported` (whether the run's state can be handed to the compiled loop),
:func:`law_args` (the tuple of arrays of ``evaluate_at``, ``commit_at`` and ``serve``, with what to
do once the loop returned) and :func:`recorded` (the law's own per-step variables from what the
commits wrote).
"""

from __future__ import annotations

import numpy as np

from ..kernels import loop_history as lh
from ..kernels import loop_path_independent as lpi
from ..kernels.layout import CHUNK, EMPTY_COUNTS, EMPTY_INDEX, fits_serial
from ..threads import chunks_of


def supported(run) -> bool:
    """True if the run's law family has a part in the compiled loop, and its state can be handed to it."""
    return run.law.path_independent or run.state.asp.size >= run.pop.n


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
    return _history(run, threads)


def _history(run, threads):
    """(law_args, after) of :mod:`asperity_sim.kernels.loop_history`; ``after`` hands back to the state and the
    workspace what the loop changed in its own arrays."""
    pop, st, ws = run.pop, run.state, run.ws
    ws.allocate_index(pop)
    partial = ws.rows(chunks_of(pop.n, CHUNK) + chunks_of(st.asp.size, CHUNK))
    cpartial, by_slot, new_slots, found, n_found = st.span_scratch()
    hints = np.zeros(lh.N_HINTS, dtype=np.int64)
    hints[[lh.H_NSLOTS, lh.H_THREADS, lh.H_INDEX, lh.H_BOXOK, lh.H_NBOX, lh.H_NSTORE]] = (
        st.n_slots, threads, int(ws.index), int(ws.box_pop is pop), ws.n_box, st.n_stored)
    r_o, k_e, _, _, _, beta, scale = pop.kernel_constants
    hreals = np.zeros(lh.N_HREALS)
    hreals[[lh.HR_RO, lh.HR_KE, lh.HR_BETA, lh.HR_SCALE, lh.HR_TANBOX]] = r_o, k_e, beta, scale, ws.tan_box
    delta_c = st.delta_c.copy()
    listed, n_listed = (ws.listed, ws.n_listed) if ws.index else (EMPTY_INDEX, EMPTY_COUNTS)
    args = (*pop.arrays, pop.R_min, st.consts, pop.n, st.asp, st.dn_c, st.code, st.flag, st.arrays, delta_c, partial,
            ws.fresh, ws.n_fresh, listed, n_listed, ws.box, cpartial, by_slot,
            np.zeros(chunks_of(st.asp.size, CHUNK), dtype=np.int64), new_slots, found, n_found, hints, hreals,
            np.zeros(lh.N_POSTI, dtype=np.int64), np.zeros(1), np.zeros(3), np.zeros(3))

    def after(m):
        st.n_slots = int(hints[lh.H_NSLOTS])
        st.serial += int(hints[lh.H_COMMITS])
        st.delta_c = delta_c.copy()
        for i in range(3):
            ws.trials_by_index[i] += int(hints[lh.H_TRIALS + i])
        ws.n_box, ws.tan_box = int(hints[lh.H_NBOX]), float(hreals[lh.HR_TANBOX])
        ws.box_pop = pop if hints[lh.H_BOXOK] else None
        ws.fresh_key = None  # the last trial's contacts born are not handed to a commit outside the loop

    return args, after


def recorded(run, extra) -> dict:
    """The law's per-step variables of the steps whose commits wrote ``extra`` (rows)."""
    if run.law.path_independent:
        return {}
    e, events = run.energy, run.law.history.events
    columns = {"external_work": [], "elastic_energy": [], "dissipation": [], events: [], "transitions": []}
    for row in extra:
        work, stored, dissipation = row[0], row[1], row[2]
        e = {"external_work": e["external_work"] + work, "elastic_energy": stored,
             "dissipation": e["dissipation"] + dissipation, events: int(row[3]),
             "transitions": row[4:20].astype(np.int64).reshape(4, 4)}
        for name, value in e.items():
            columns[name].append(value)
    run.energy = e
    return columns
