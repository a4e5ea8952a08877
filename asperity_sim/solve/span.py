"""Increments of a stage in one compiled call, and what the run keeps of them.

Owns :func:`can_span` (whether a stage's coming increments may run compiled whole) and
:func:`span` (runs them with :func:`asperity_sim.kernels.loop.span`, then records them and moves
the run's position and energies on exactly as the Python loop of
:meth:`asperity_sim.solve.run.Run.go` would have).
"""

from __future__ import annotations

import os
import time

import numba
import numpy as np

from .. import jit
from ..geometry import closure
from ..kernels import loop as lp
from ..kernels.evaluate import evaluation_from
from ..kernels.layout import N_OUT, O_AREA, O_NC, O_NP, O_NS, O_STRESS, O_TANGENT, O_TH
from ..kernels.specialise import kernels
from ..threads import SPIN_US, run_calls
from . import span_args
from .records import theta_am_at
from .stepping import TRUST


MODE_ENV = "ASPERITY_SIM_COMPILED_LOOP"
"""Environment variable: when runs use the compiled increments (:data:`MODE`)."""
MODE = os.environ.get(MODE_ENV, "cached")
"""``cached`` (default): where they cover a stage and their code is compiled already (in this process or numba's
on-disk cache, where ``asperity-sim warmup`` puts it): a first run compiles nothing more than the Python loop
needs; ``always``: compiled at their first use (a minute for both laws); ``never``: the Python loop alone."""


def can_span(run, free, max_wall_time) -> bool:
    """True when the stage's increments may run compiled: policy follow, no elastic interaction, at most one
    stress-controlled component, no wall-time limit (checked at every evaluation) and the law's state in arrays
    that never grow (:func:`.span_args.supported`)."""
    return (run.compiled_loop is not False and MODE != "never" and run.state.theta_birth is None
            and run.params.interaction == 0.0 and int(np.count_nonzero(free)) <= 1 and max_wall_time is None
            and span_args.supported(run))


def span(run, stage, i_stage, free, end, nominal, smallest, done_in_stage, watch) -> tuple:
    """Run the stage's coming increments compiled (:func:`can_span` true), then what the Python loop does after
    each: (increments done, whether the stage ended).

    ``watch`` (progress, checkpoint, checkpoint_every, t0, n_stages): the loop stops after the increment of
    a snapshot or checkpoint step, and after every increment when a progress callback watches them.
    """
    progress, checkpoint, checkpoint_every, t0, n_stages = watch
    step0 = run.rec.size
    m_max = stage.budget - done_in_stage
    if progress is not None:
        m_max = min(m_max, 1)
    snaps = [s for s in run.snap_steps if s >= step0]
    if snaps:
        m_max = min(m_max, min(snaps) - step0 + 1)
    if checkpoint is not None and checkpoint_every:
        m_max = min(m_max, -step0 % checkpoint_every + 1)
    m, iterations = _run(run, stage, i_stage, free, end, nominal, smallest, m_max)
    if not m:
        return 0, False
    stage_done = run.pos.s >= 1.0 - 1e-12
    step = run.rec.size - 1
    if step in run.snap_steps or (run.snap_stage_ends and stage_done):
        run.take_snapshot(step)
    if stage_done:
        run.pos.i_stage, run.pos.started = run.pos.i_stage + 1, False
    if checkpoint is not None and (step % checkpoint_every == 0 if checkpoint_every else stage_done):
        run.save_checkpoint(checkpoint, checkpoint_every, run.wall_before + time.perf_counter() - t0)
    if progress is not None:
        progress(i_stage, n_stages, run.pos.s, step, iterations)
    return m, stage_done


def _run(run, stage, i_stage, free, end, nominal, smallest, m_max) -> tuple:
    """The compiled call for at most ``m_max`` increments: (increments done, iterations of the last)."""
    pos, settings, history = run.pos, run.settings, not run.law.path_independent
    if m_max <= 0:
        return 0, 0
    # the other threads poll for the whole call: where idle threads must sleep at once (ASPERITY_SIM_SPIN_US=0:
    # processes share the cores), the calling thread does it alone (the same bits on any number of threads)
    threads = numba.get_num_threads() if SPIN_US > 0 else 1
    domain = run.domain
    reals = np.zeros(lp.N_REALS)
    reals[[lp.R_L, lp.R_RTOL, lp.R_RESTOL, lp.R_FLOOR, lp.R_MAXSTEP, lp.R_MAXSEARCH, lp.R_NOMINAL, lp.R_SMALLEST,
           lp.R_MAXFRAC, lp.R_S, lp.R_DS, lp.R_KREF, lp.R_PREVS]] = (
        TRUST * run.length, settings.rtol, max(settings.resolution_rtol, settings.rtol), settings.sigma_floor,
        settings.max_step, settings.max_search, nominal, smallest, stage.max_fraction, pos.s, pos.ds, pos.k_ref,
        pos.prev_s)
    if domain is not None:
        reals[[lp.R_COSTOL, lp.R_NORMALRTOL, lp.R_LOOPRTOL]] = domain.cos_tol, domain.normal_rtol, domain.loop_rtol
        domain.room(m_max)
        track, last, dcounts, first = domain.track, domain.last, domain.counts, domain.first_step
    else:
        track, last, dcounts, first = np.zeros((1, 5)), np.zeros(5), np.zeros(4, dtype=np.int64), -1
    ints = np.zeros(lp.N_INTS, dtype=np.int64)
    ints[[lp.I_K, lp.I_MAXITER, lp.I_MAXEXP, lp.I_ADAPTIVE, lp.I_MMAX, lp.I_STEP0, lp.I_HISTORY, lp.I_THREADS]] = (
        int(np.flatnonzero(free)[0]) if free.any() else -1, settings.max_iter, settings.max_expansions,
        int(stage.adaptive), m_max, run.rec.size, int(history), threads)
    vecs = np.array([pos.start_delta, end, pos.start_stress, run.delta, pos.prev_delta, pos.prev_slope], dtype=float)
    older = pos.older.copy()
    ev = row_of(run.ev)
    rows, steps = np.empty((m_max, N_OUT)), np.zeros((m_max, lp.N_STEP))
    flags = np.zeros(lp.n_flags(threads), dtype=np.int64)
    law_args, after = span_args.law_args(run, threads)
    args = (flags, law_args, ints, reals, vecs, older, ev, rows, steps, track, last, dcounts)
    kernel = kernels(run.law)["span"]
    if run.compiled_loop is None:  # decided once per run
        run.compiled_loop = MODE == "always" or (MODE == "cached" and jit.ready(kernel, (*args, 0, 1)))
    if not run.compiled_loop:
        return 0, 0
    run_calls((kernel, threads, args))
    m = int(ints[lp.I_M])
    after(m)
    if m:
        _keep(run, i_stage, free, end, rows[:m], steps[:m], reals)
        if domain is not None and first < 0 <= domain.first_step:
            run.domain_left(domain.first_step, stacklevel=6)
    return m, int(steps[m - 1, lp.S_IT]) if m else 0


def row_of(ev) -> np.ndarray:
    """The flat result row (:mod:`asperity_sim.kernels.layout`) of an Evaluation: its fields in their places."""
    from ..kernels.layout import O_AREA_COV, O_AREA_GRAD, O_AREA_VAR, O_COV, O_NA, O_SE

    row = np.empty(N_OUT)
    row[O_STRESS:O_STRESS + 3] = ev.stress
    row[O_TANGENT:O_TANGENT + 9] = ev.tangent.ravel()
    row[O_COV:O_COV + 9] = ev.covariance.ravel()
    row[O_SE:O_SE + 3] = ev.stderr
    row[[O_NC, O_NS, O_NP, O_TH, O_NA]] = ev.n_contact, ev.n_slip, ev.n_partial, ev.mean_theta, ev.n_active
    row[O_AREA], row[O_AREA_VAR] = ev.contact_area, ev.contact_area_var
    row[O_AREA_COV:O_AREA_COV + 3] = ev.contact_area_cov
    row[O_AREA_GRAD:O_AREA_GRAD + 3] = ev.contact_area_grad
    return row


def _keep(run, i_stage, free, end, rows, steps, reals):
    """Record the increments and move the run's position on, as the Python loop does after each."""
    pos, params, rec = run.pos, run.params, run.rec
    m = rows.shape[0]
    deltas = steps[:, lp.S_X:lp.S_X + 3]
    before = run.delta
    for i in range(m):
        pos.advance(float(steps[i, lp.S_S]), before, steps[i, lp.S_SLOPE:lp.S_SLOPE + 3].copy())
        before = deltas[i].copy()
    stress = rows[:, O_STRESS:O_STRESS + 3]
    disp_se = steps[:, lp.S_DSE:lp.S_DSE + 3]
    extra = span_args.recorded(run, steps[:, lp.S_EXTRA:])
    if run.domain is not None:
        extra["law_domain"] = steps[:, lp.S_FLAGS].astype("i1")
    rec.extend(displacement=deltas, stress=stress, stress_stderr=steps[:, lp.S_SSE:lp.S_SSE + 3],
               displacement_stderr=disp_se, tangent=rows[:, O_TANGENT:O_TANGENT + 9].reshape(-1, 3, 3),
               n_contact=rows[:, O_NC], n_slip=rows[:, O_NS], n_partial=rows[:, O_NP],
               theta_am=[theta_am_at(params, float(closure(params, d1))) for d1 in deltas[:, 0].tolist()],
               mean_theta=rows[:, O_TH], contact_area_fraction=rows[:, O_AREA],
               contact_area_fraction_stderr=steps[:, lp.S_ASE], mean_gap=params.mean_plane_depth - deltas[:, 0],
               mean_gap_stderr=disp_se[:, 0], stage=i_stage, control=free.astype("i1"),
               iterations=steps[:, lp.S_IT], residual=steps[:, lp.S_RES], cutbacks=0, **extra)
    prev = deltas[m - 2] if m > 1 else run.delta
    run.ev = evaluation_from(deltas[m - 1].copy(), rows[m - 1].copy())
    run.delta = run.ev.delta.copy()
    if run.law.path_independent:
        run.state.commit(run.delta)  # only delta_c moves (a history law's commits were made in the span)
    run.state.reference = np.where(free, prev, end)
    run.ws.interaction_offset = 0.0
    pos.s, pos.ds, pos.k_ref = float(reals[lp.R_S]), float(reals[lp.R_DS]), float(reals[lp.R_KREF])
