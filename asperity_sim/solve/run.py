"""One run in progress: the loop over stages and increments, cut-backs, commit and record.

Owns :class:`Run`, the whole state of a run (population, committed contacts, recorder, loop
position) and its loop, inside ``try/finally`` so that what converged is always kept: for each
increment a Newton solve (:mod:`asperity_sim.solve.solver`) from a predicted guess
(:mod:`asperity_sim.solve.stepping`), the commit of the contact state after convergence, the
record of the step, snapshots and checkpoints.  :func:`asperity_sim.solve.driver.simulate`
checks the inputs and builds it.
"""

from __future__ import annotations

import math
import os
import time
import warnings

import numpy as np

from .. import laws
from ..checks import check_delta
from ..errors import ConvergenceError, Deadline, LawDomainWarning, OutputWriteError, WallTimeExceededError
from ..geometry import closure
from ..kernels import ahead
from ..kernels.evaluate import Workspace, evaluate_steps, evaluate_unchecked
from ..kernels.layout import fits_serial
from ..kernels.state import ContactState
from ..output.recorder import LATE_IMPORTS, WALL_TIME_DESCRIPTION, Recorder, run_attributes
from ..output.variables import run_variables
from ..sampling.population import Population
from ..version import __version__
from . import run_checkpoint
from .domain import DomainMonitor
from .records import record_step, stderr_attributes, theta_am_at, utc_now
from .span import can_span, span
from .solver import solve_increment
from .stepping import (
    TRUST,
    Position,
    cubic_predictor,
    effective_stiffness,
    extrapolated_predictor,
    increment_failure,
    length_scale,
    next_step,
    ramped_components,
    tangent_predictor,
    unreachable_by_symmetry,
)

BATCH = 64  # displacement-controlled increments per kernel call (the wall-time limit is checked between calls)


class Run:
    """The state of one run: population, committed history, recorder, loop position."""

    def __init__(self, params, path, *, n, seed, sampler, law, policy, options, snaps, settings, population, saved):
        self.params, self.path, self.policy, self.settings = params, path, policy, settings
        self.law = laws.get(law)
        self.snap_steps, self.snap_stage_ends = snaps
        self.resumed_from = None
        self.variables = run_variables(self.law)
        self.domain = DomainMonitor() if self.law.path_independent else None
        self.compiled_loop = None  # whether the compiled increments run (solve.span), once it is decided
        # a first run: a helper compiles the kernels this run needs last while it compiles the first (kernels.ahead)
        ahead.expect(self.law.name, policy == "birth", fits_serial(population.n if population is not None else n),
                     imports=LATE_IMPORTS)
        restored = None
        if saved is not None:  # every array is checked before any kernel sees it
            restored = run_checkpoint.restore(saved, params=params, n_stages=len(path.stages), law=self.law,
                                              policy=policy, options=options, variables=self.variables,
                                              population=population)
            pop = restored.pop
        elif population is not None:
            pop = population
        else:
            pop = Population.sample(params, n, seed=seed, sampler=sampler)
        self.pop = pop
        self.config = run_checkpoint.config_of(params, path, n=pop.n, seed=pop.seed, sampler=pop.sampler, law=law,
                                               policy=policy, options=options, settings=settings, snapshots=snaps)
        self.ws = Workspace(pop.n)
        self.length = length_scale(params, path)
        total = sum(s.increments for s in path.stages)
        self.rec = Recorder(total + 1, self.variables)
        self.wall_before = 0.0
        self.deadline = math.inf  # set by go() from max_wall_time; evaluations check it
        if restored is None:
            self.state = ContactState(pop, self.law, policy, options=options)
            self._fresh()
        else:
            self.state = restored.contact
            self._continue(restored, saved.path)
        ahead.expect(None)  # set up: a kernel compiled later in this process is not this run's start

    # -- set-up ---------------------------------------------------------------------------------

    def _fresh(self):
        pop, params, path, law = self.pop, self.params, self.path, self.law
        call = (f"asperity_sim.simulate(path={path.name}, n={pop.n}, seed={pop.seed}, sampler={pop.sampler!r}, "
                f"law={law.name!r}, policy={self.policy!r})")
        self.attrs = run_attributes(params, n=pop.n, seed=pop.seed, sampler=pop.sampler, law=law.name,
                                    policy=self.policy, path=path, version=__version__, call=call)
        self.attrs["law_summary"] = law.summary
        self.attrs["law_domain"] = law.domain
        self.attrs.update(law.run_attributes(self.state.options, getattr(self.state, "arrays", ())))
        stderr_attributes(self.attrs, pop.n)
        self.attrs["increments_at_resolution"] = 0  # residual above rtol, accepted at the resolution of Delta
        self.attrs["increments_at_resolution_note"] = (
            "increments whose stress target no representable Delta meets to rtol (contact overlaps far below "
            "Delta); accepted at the floating-point resolution of Delta, their residual is recorded")
        self.delta = np.zeros(3)
        self.ev = self.evaluate_at(self.delta)
        self.energy = ({"external_work": 0.0, "elastic_energy": 0.0, "dissipation": 0.0, self.law.history.events: 0,
                        "transitions": np.zeros((4, 4), dtype=np.int64)} if self.law.history is not None else {})
        self.pos = Position()
        record_step(self.rec, params, self.ev, stage=0, control=np.zeros(3, bool), iterations=0, residual=0.0,
                    cutbacks=0, **self.energy, **self.domain_flags(0, self.ev.delta, self.ev.stress))
        if 0 in self.snap_steps:
            self.take_snapshot(0)

    def _continue(self, restored, source):
        """Take up the state of a checkpoint (:func:`asperity_sim.solve.run_checkpoint.restore`)."""
        self.attrs, self.wall_before = restored.attrs, restored.wall_time
        self.delta, self.ev, self.energy, self.pos = restored.delta, restored.ev, restored.energy, restored.pos
        rows = restored.rows
        for i in range(restored.steps_recorded):
            self.rec.append(**{name: rows[name][i] for name in self.variables})
            if self.domain is not None:  # its state is a function of the recorded steps: replayed
                self.domain.step(i, rows["displacement"][i], rows["stress"][i])
        for step, snap in restored.snapshots:
            self.rec.add_snapshot(step, snap)
        self.resumed_from = (source, self.rec.size - 1)

    # -- the law's domain (path-independent laws) -------------------------------------------------

    def domain_flags(self, step, delta, stress) -> dict:
        """{"law_domain": flags} of a recorded step (empty for history laws); warns at the first flag."""
        if self.domain is None:
            return {}
        first = self.domain.first_step
        flags = self.domain.step(step, delta, stress)
        if flags and first < 0:
            self.domain_left(step, stacklevel=5)
        return {"law_domain": flags}

    def domain_left(self, step, stacklevel):
        """Note in the attributes, and warn, that the run left the law's domain at ``step`` (once)."""
        self.attrs["law_domain_first_step"] = step
        self.attrs["law_domain_note"] = self.domain.message(self.law.name, step)
        warnings.warn(self.domain.message(self.law.name, step), LawDomainWarning, stacklevel=stacklevel)

    def domain_flags_of(self, first_step, deltas, stresses) -> dict:
        """:meth:`domain_flags` of consecutive recorded steps, as one column."""
        if self.domain is None:
            return {}
        return {"law_domain": np.array([self.domain_flags(first_step + i, d, s)["law_domain"]
                                        for i, (d, s) in enumerate(zip(deltas, stresses))], dtype="i1")}

    # -- evaluation, snapshots, checkpoints -----------------------------------------------------

    def evaluate_at(self, delta):
        # the run's own arguments were checked once; only the solver's delta is new
        if time.perf_counter() > self.deadline:
            raise Deadline
        return evaluate_unchecked(self.pop, check_delta(delta), self.state, self.ws)

    def take_snapshot(self, step):
        self.rec.add_snapshot(step, self.state.snapshot(self.ev.at_contacts()))

    def save_checkpoint(self, target, every, wall):
        run_checkpoint.save(self, target, every=every, wall_time=wall)

    # -- displacement-controlled increments in batches --------------------------------------------

    def prescribed_batch(self, stage, i_stage, end, nominal, smallest, checkpoint_every) -> bool:
        """Run up to BATCH coming increments of a displacement-controlled stage in one kernel call; True if any.

        Under the path-independent ``paper`` law and policy follow, with no history to commit,
        such an increment is one evaluation at a known Delta, with no Newton solve: a small
        population (serial kernels) evaluates them in one call
        (:func:`~asperity_sim.kernels.evaluate.evaluate_steps`), bit-identical to the loop, instead of
        paying a round trip through Python for each (the driver does this only when no
        progress callback watches each increment).  Stops before the increment that ends the
        stage, takes a snapshot or a checkpoint (the loop does those) and at a non-finite
        result (the loop cuts it back); the loop goes on from the position left here.
        """
        pos, rec, params = self.pos, self.rec, self.params
        plan, ds, s, step = [], pos.ds, pos.s, rec.size
        while len(plan) < BATCH:  # the loop's own increments, each converging at once (0 iterations)
            ds = min(ds, 1.0 - s)
            s = 1.0 if s + ds > 1.0 - 1e-12 else s + ds
            if (s >= 1.0 - 1e-12 or step in self.snap_steps
                    or (checkpoint_every is not None and step % checkpoint_every == 0)):
                break
            plan.append((s, ds))
            ds = next_step(stage, ds, 0, 0, nominal, smallest)
            step += 1
        if not plan:
            return False
        fractions = np.array([f for f, _ in plan])
        start = pos.start_delta
        deltas = start + fractions[:, None] * (end - start)  # the loop's targets, row by row
        steps = evaluate_steps(self.pop, deltas, self.ws, self.law)
        finite = steps.finite  # as the solver checks an evaluation
        m = len(plan) if finite.all() else int(np.argmin(finite))
        if m == 0:
            return False
        rec.extend(displacement=deltas[:m], stress=steps.stress[:m], stress_stderr=steps.stderr[:m],
                   displacement_stderr=0.0, tangent=steps.tangent[:m], n_contact=steps.n_contact[:m],
                   n_slip=steps.n_slip[:m], n_partial=steps.n_partial[:m],
                   theta_am=[theta_am_at(params, float(closure(params, d1))) for d1 in deltas[:m, 0]],
                   mean_theta=steps.mean_theta[:m], contact_area_fraction=steps.contact_area[:m],
                   contact_area_fraction_stderr=steps.contact_area_stderr[:m],
                   mean_gap=params.mean_plane_depth - deltas[:m, 0], mean_gap_stderr=0.0,
                   stage=i_stage, control=0, iterations=0, residual=0.0, cutbacks=0,
                   **self.domain_flags_of(rec.size, deltas[:m], steps.stress[:m]))
        # the loop's position after the last of them (the points before it feed the predictors), as the loop
        # would leave it: each point before an increment becomes the previous one in turn
        before, s_before = (self.delta, pos.s) if m == 1 else (deltas[m - 2], plan[m - 2][0])
        s_last, ds_last = plan[m - 1]
        for i in range(m - 1):
            pos.advance(pos.s if i == 0 else plan[i - 1][0], self.delta if i == 0 else deltas[i - 1], pos.prev_slope)
        self.ev = steps.evaluation(m - 1)
        self.delta = deltas[m - 1].copy()
        self.state.commit(self.delta)  # a path-independent law under policy follow: only delta_c moves
        pos.advance(s_before, before, (self.delta - before) / (s_last - s_before))
        pos.s, pos.ds = s_last, next_step(stage, ds_last, 0, 0, nominal, smallest)
        return True

    # -- the loop ---------------------------------------------------------------------------------

    def go(self, *, output, progress, max_wall_time, checkpoint, checkpoint_every):
        params, path, settings, rec, pos = self.params, self.path, self.settings, self.rec, self.pos
        attrs = self.attrs
        if self.resumed_from is not None:
            attrs["history"] = (f"{attrs.get('history', '')}\n{utc_now()} resumed from checkpoint "
                                f"{self.resumed_from[0]} at step {self.resumed_from[1]}").lstrip("\n")
        failure = None
        interrupted = None
        consistent = True  # the state is that of the last converged increment (safe to checkpoint)
        n_stages = len(path.stages)
        t0 = time.perf_counter()
        self.deadline = math.inf if max_wall_time is None else t0 + max_wall_time
        try:
            while pos.i_stage < n_stages:
                stage = path.stages[pos.i_stage]
                i_stage = pos.i_stage + 1
                free = stage.stress_controlled
                end = np.asarray(stage.target, dtype=float)
                nominal = 1.0 / stage.increments
                smallest = nominal * 0.5 ** settings.max_cutbacks
                if not pos.started:
                    failure = unreachable_by_symmetry(params, stage, i_stage, free, end)
                    if failure is not None:
                        raise failure
                    pos.start_delta, pos.start_stress = self.delta.copy(), self.ev.stress.copy()
                    pos.s, pos.ds = 0.0, nominal
                    pos.forget()
                    pos.k_ref = (effective_stiffness(self.ev, free, ramped_components(free, pos.start_stress, end))
                                 if free.any() else 0.0)
                    pos.started = True
                ramped = ramped_components(free, pos.start_stress, end)  # stage constant
                done_in_stage = rec.count("stage", i_stage)  # bounded: at most stage.budget increments
                # increments that are one evaluation each, on serial kernels, with nobody watching each one
                batches = (not free.any() and self.law.path_independent and self.state.theta_birth is None
                           and fits_serial(self.pop.n) and progress is None and params.interaction == 0.0)
                spans = not batches and can_span(self, free, max_wall_time)
                ds, cuts = pos.ds, 0
                while pos.s < 1.0 - 1e-12:
                    if spans and cuts == 0:  # as many increments as it can, compiled (solve.span)
                        consistent = False
                        m, stage_done = span(self, stage, i_stage, free, end, nominal, smallest, done_in_stage,
                                             (progress, checkpoint, checkpoint_every, t0, n_stages))
                        consistent, spans = True, self.compiled_loop
                        ds, done_in_stage = pos.ds, done_in_stage + m
                        if stage_done:
                            break
                    if batches and cuts == 0 and not (max_wall_time is not None
                                                      and time.perf_counter() - t0 > max_wall_time):
                        consistent = False
                        if self.prescribed_batch(stage, i_stage, end, nominal, smallest, checkpoint_every):
                            ds = pos.ds
                            done_in_stage = rec.count("stage", i_stage)
                        consistent = True
                    s = pos.s
                    if done_in_stage >= stage.budget:
                        failure = ConvergenceError(
                            f"stage {i_stage} ({stage.name or 'unnamed'}) took {done_in_stage} increments, its budget "
                            f"({stage.budget} = 4 x its nominal count + 64), and stopped at {s:.4g} of the stage: "
                            "its increments stayed too small (raise max_fraction or increments)")
                        raise failure
                    if max_wall_time is not None and time.perf_counter() - t0 > max_wall_time:
                        failure = WallTimeExceededError(
                            f"wall-time limit max_wall_time = {max_wall_time:g} s exceeded: stage {i_stage} "
                            f"({stage.name or 'unnamed'}) stopped at {s:.4g} of the stage after "
                            f"{rec.size - 1} converged increments")
                        raise failure
                    ds = min(ds, 1.0 - s)
                    s_new = 1.0 if s + ds > 1.0 - 1e-12 else s + ds
                    target_delta = np.where(free, self.delta, pos.start_delta + s_new * (end - pos.start_delta))
                    target_stress = np.where(free, pos.start_stress + s_new * (end - pos.start_stress), 0.0)
                    guess = tangent_predictor(self.ev, self.delta, target_delta, target_stress, free, TRUST * self.length)
                    slope = (guess - self.delta) / (s_new - s)  # d Delta / d s at s (free components)
                    if free.any() and not math.isnan(pos.prev_s):
                        guess = (cubic_predictor(guess, self.delta, slope, pos, s, s_new, free) if self.law.path_independent
                                 else extrapolated_predictor(guess, self.delta, pos, s, s_new, free))
                    # fresh contacts get springs that fit their overlap at the stage's end point
                    self.state.reference = np.where(free, self.delta, end)
                    # under elastic interaction every increment's first evaluation starts from the offset of the
                    # last converged one (so a resumed run repeats the same iterations)
                    self.ws.interaction_offset = float(self.ev.at_contacts()[0] - self.ev.delta[0])
                    try:
                        result = solve_increment(self.evaluate_at, guess, free, target_stress, self.length, settings)
                    except Deadline:
                        failure = WallTimeExceededError(
                            f"wall-time limit max_wall_time = {max_wall_time:g} s exceeded during an increment of "
                            f"stage {i_stage} ({stage.name or 'unnamed'}) at {s:.4g} of the stage, after "
                            f"{rec.size - 1} converged increments")
                        raise failure from None
                    if not result.converged:
                        cuts += 1
                        if result.unreachable or cuts > settings.max_cutbacks or ds * 0.5 < smallest:
                            failure = increment_failure(result, self.ev, free, pos.start_stress, end, target_stress, i_stage,
                                               stage, s, cuts, pos.k_ref)
                            raise failure
                        ds *= 0.5
                        continue
                    consistent = False
                    pos.advance(s, self.delta, slope)
                    ev = self.ev = result.evaluation
                    self.delta = ev.delta.copy()
                    c = self.state.commit(ev.at_contacts(), ev.n_active, self.ws)
                    if c is not None:
                        e = self.energy
                        self.energy = {"external_work": e["external_work"] + c.work, "elastic_energy": c.stored,
                                       "dissipation": e["dissipation"] + c.dissipation,
                                       self.law.history.events: c.events, "transitions": c.transitions}
                    if free.any():
                        pos.k_ref = max(pos.k_ref, effective_stiffness(ev, free, ramped))
                    done_in_stage += 1
                    record_step(rec, params, ev, stage=i_stage, control=free, iterations=result.iterations,
                                residual=result.residual, cutbacks=cuts, **self.energy,
                                **self.domain_flags(rec.size, ev.delta, ev.stress))
                    if result.residual > settings.rtol:  # accepted at the floating-point resolution of Delta
                        attrs["increments_at_resolution"] = attrs.get("increments_at_resolution", 0) + 1
                    step = rec.size - 1
                    if step in self.snap_steps or (self.snap_stage_ends and s_new >= 1.0 - 1e-12):
                        self.take_snapshot(step)
                    ds, cuts = next_step(stage, ds, result.iterations, cuts, nominal, smallest), 0
                    pos.s, pos.ds = s_new, ds
                    stage_done = s_new >= 1.0 - 1e-12
                    if stage_done:
                        pos.i_stage, pos.started = pos.i_stage + 1, False
                    consistent = True
                    if checkpoint is not None and (step % checkpoint_every == 0 if checkpoint_every else stage_done):
                        self.save_checkpoint(checkpoint, checkpoint_every,
                                             self.wall_before + time.perf_counter() - t0)
                    if progress is not None:
                        progress(i_stage, n_stages, s_new, step, result.iterations)
                    if stage_done:
                        break
        except BaseException as err:  # noqa: B036 - recorded, then re-raised
            interrupted = err
            raise
        finally:
            wall = self.wall_before + time.perf_counter() - t0
            attrs.pop("wall_time_s", None)  # its earlier, ambiguous name (carried by older checkpoints)
            attrs["wall_time_increment_loop_s"] = wall
            attrs["wall_time_increment_loop_s_description"] = WALL_TIME_DESCRIPTION
            if failure is not None:
                attrs["status"] = f"failed: {type(failure).__name__}: {failure}"
            elif interrupted is not None:
                attrs["status"] = f"interrupted: {type(interrupted).__name__}: {interrupted}"
            else:
                attrs["status"] = "complete"
            if failure is None and interrupted is not None and checkpoint is not None and consistent:
                try:
                    self.save_checkpoint(checkpoint, checkpoint_every, wall)
                except Exception as err:  # noqa: BLE001 - never hide the interruption itself
                    warnings.warn(f"could not write the checkpoint of the interrupted run: {err}", stacklevel=2)
            ds_out = rec.to_dataset(attrs, population=self.pop, stage_names=[s.name for s in path.stages])
            if failure is not None:
                failure.dataset = ds_out
            if output is not None:
                from ..output.netcdf import write_netcdf

                try:
                    write_netcdf(ds_out, output)
                except Exception as err:  # noqa: BLE001 - the result is kept, the run's own error is never masked
                    note = f"the result could not be written to {os.fspath(output)!r} ({type(err).__name__}: {err})"
                    if interrupted is not None:
                        interrupted.add_note(note + "; it is on this exception as .dataset")
                        if not hasattr(interrupted, "dataset"):
                            interrupted.dataset = ds_out
                    else:
                        raise OutputWriteError(note + "; the complete result is on this exception as .dataset",
                                               ds_out) from err
        return ds_out

