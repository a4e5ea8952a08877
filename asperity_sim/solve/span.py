"""Increments of a stage in one compiled call, and what the run keeps of them.

Owns :func:`can_span` (whether a stage's coming increments may run compiled whole) and
:func:`span` (runs them with :func:`asperity_sim.kernels.stage_loop.span`, then records them and
moves the run's position on exactly as the Python loop of :meth:`asperity_sim.solve.run.Run.go`
would have).
"""

from __future__ import annotations

import numpy as np

from ..geometry import closure
from ..kernels import stage_loop as sl
from ..kernels.evaluate import evaluation_from
from ..kernels.layout import (
    N_OUT,
    O_AREA,
    O_NC,
    O_NP,
    O_NS,
    O_STRESS,
    O_SE,
    O_TANGENT,
    O_TH,
    fits_serial,
)
from ..kernels.specialise import kernels
from ..threads import run_calls
from .records import theta_am_at
from .stepping import TRUST


def can_span(run, free, progress, max_wall_time, checkpoint) -> bool:
    """True when the stage's increments may run compiled: a path-independent law under policy follow, no elastic
    interaction, at most one stress-controlled component, and nobody who must see each increment (a progress
    callback, snapshots, checkpoints, a wall-time limit)."""
    return (run.law.path_independent and run.state.theta_birth is None and run.params.interaction == 0.0
            and int(np.count_nonzero(free)) <= 1 and progress is None and max_wall_time is None
            and checkpoint is None and not run.snap_stage_ends and not any(s >= run.rec.size for s in run.snap_steps))


def span(run, stage, i_stage, free, end, nominal, smallest, done_in_stage) -> tuple:
    """Run the stage's coming increments compiled (:func:`can_span` true); (increments done, why it stopped)."""
    pos, settings, pop = run.pos, run.settings, run.pop
    m_max = stage.budget - done_in_stage
    if m_max <= 0:
        return 0, sl.PYTHON
    k = int(np.flatnonzero(free)[0]) if free.any() else -1
    r_o, k_e, _, _, _, beta, scale = pop.kernel_constants
    reals = np.zeros(sl.N_REALS)
    domain = run.domain
    reals[[sl.R_RO, sl.R_KE, sl.R_BETA, sl.R_SCALE, sl.R_L, sl.R_RTOL, sl.R_RESTOL, sl.R_FLOOR, sl.R_MAXSTEP,
           sl.R_MAXSEARCH, sl.R_NOMINAL, sl.R_SMALLEST, sl.R_MAXFRAC, sl.R_COSTOL, sl.R_NORMALRTOL, sl.R_LOOPRTOL,
           sl.R_S, sl.R_DS, sl.R_KREF, sl.R_PREVS]] = (
        r_o, k_e, beta, scale, TRUST * run.length, settings.rtol, max(settings.resolution_rtol, settings.rtol),
        settings.sigma_floor, settings.max_step, settings.max_search, nominal, smallest, stage.max_fraction,
        domain.cos_tol, domain.normal_rtol, domain.loop_rtol, pos.s, pos.ds, pos.k_ref, pos.prev_s)
    ints = np.zeros(sl.N_INTS, dtype=np.int64)
    ints[[sl.I_K, sl.I_MAXITER, sl.I_MAXEXP, sl.I_ADAPTIVE, sl.I_MMAX, sl.I_BUDGET, sl.I_SERIALPOP, sl.I_STEP0]] = (
        k, settings.max_iter, settings.max_expansions, int(stage.adaptive), m_max, m_max, int(fits_serial(pop.n)),
        run.rec.size)
    domain.room(m_max)
    first = domain.first_step
    vecs = np.array([pos.start_delta, end, pos.start_stress, run.delta, pos.prev_delta, pos.prev_slope], dtype=float)
    ev = np.empty(N_OUT)
    ev[:] = _row_of(run.ev)
    rows, steps = np.empty((m_max, N_OUT)), np.empty((m_max, sl.N_STEP))
    flags = np.zeros(3 * 8, dtype=np.int64)
    kern = kernels(run.law)
    run_calls((kern["span"], 2, (flags, *pop.arrays, pop.R_min, run.state.consts, run.ws.partial, pop.n, ints, reals,
                                 vecs, ev, np.zeros(2, dtype=np.int64), np.zeros(3), np.zeros(1), rows, steps, domain.track,
                                 domain.last, domain.counts)))
    m, status = int(ints[sl.I_M]), int(ints[sl.I_STATUS])
    if m:
        _keep(run, i_stage, free, end, rows[:m], steps[:m], reals)
        if first < 0 <= domain.first_step:
            run.domain_left(domain.first_step, stacklevel=5)
    return m, status


def _row_of(ev):
    """The flat result row (kernels.layout) of an Evaluation."""
    from ..kernels.layout import O_AREA_COV, O_AREA_GRAD, O_AREA_VAR, O_COV, O_NA

    row = np.empty(N_OUT)
    row[O_STRESS:O_STRESS + 3] = ev.stress
    row[O_TANGENT:O_TANGENT + 9] = ev.tangent.ravel()
    row[O_COV:O_COV + 9] = ev.covariance.ravel()
    row[O_SE:O_SE + 3] = ev.stderr
    row[O_NC], row[O_NS], row[O_NP], row[O_TH], row[O_NA] = (ev.n_contact, ev.n_slip, ev.n_partial, ev.mean_theta,
                                                             ev.n_active)
    row[O_AREA], row[O_AREA_VAR] = ev.contact_area, ev.contact_area_var
    row[O_AREA_COV:O_AREA_COV + 3] = ev.contact_area_cov
    row[O_AREA_GRAD:O_AREA_GRAD + 3] = ev.contact_area_grad
    return row


def _keep(run, i_stage, free, end, rows, steps, reals):
    """Record the increments and move the run's position, as the Python loop does after each."""
    pos, params, rec = run.pos, run.params, run.rec
    m = rows.shape[0]
    deltas = steps[:, sl.S_X:sl.S_X + 3]
    before = run.delta
    for i in range(m):
        pos.advance(float(steps[i, sl.S_S]), before, steps[i, sl.S_SLOPE:sl.S_SLOPE + 3].copy())
        before = deltas[i].copy()
    stress = rows[:, O_STRESS:O_STRESS + 3]
    disp_se = steps[:, sl.S_DSE:sl.S_DSE + 3]
    rec.extend(displacement=deltas, stress=stress, stress_stderr=steps[:, sl.S_SSE:sl.S_SSE + 3],
               displacement_stderr=disp_se, tangent=rows[:, O_TANGENT:O_TANGENT + 9].reshape(-1, 3, 3),
               n_contact=rows[:, O_NC].astype(int), n_slip=rows[:, O_NS].astype(int),
               n_partial=rows[:, O_NP].astype(int),
               theta_am=[theta_am_at(params, float(closure(params, d1))) for d1 in deltas[:, 0].tolist()],
               mean_theta=rows[:, O_TH], contact_area_fraction=rows[:, O_AREA],
               contact_area_fraction_stderr=steps[:, sl.S_ASE], mean_gap=params.mean_plane_depth - deltas[:, 0],
               mean_gap_stderr=disp_se[:, 0], stage=i_stage, control=free.astype("i1"),
               iterations=steps[:, sl.S_IT].astype(int), residual=steps[:, sl.S_RES], cutbacks=0,
               law_domain=steps[:, sl.S_FLAGS].astype("i1"))
    prev = deltas[m - 2] if m > 1 else run.delta
    run.ev = evaluation_from(deltas[m - 1].copy(), rows[m - 1].copy())
    run.delta = run.ev.delta.copy()
    run.state.commit(run.delta)
    run.state.reference = np.where(free, prev, end)
    run.ws.interaction_offset = 0.0
    pos.s, pos.ds, pos.k_ref = float(reals[sl.R_S]), float(reals[sl.R_DS]), float(reals[sl.R_KREF])
