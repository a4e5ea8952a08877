"""simulate(): a load path stepped through increments under mixed control (SPEC §6–§7).

Owns the loop: for each stage, increments with cut-backs; for each increment, a Newton
solve (:mod:`asperity_sim.solver`), then commit (birth angles under policy ``birth``) and
record.  The loop runs inside ``try/finally`` so what converged is always kept: on
failure the exception carries the partial dataset (and it is written if an output
file was asked for).
"""

from __future__ import annotations

import numbers
import os
import time

import numpy as np

from . import __version__
from .assemble import LAWS, POLICIES, Workspace, birth_angles, check_choice, evaluate, snapshot
from .params import InterfaceParams
from .paths import LoadPath
from .population import SAMPLERS, Population
from .recorder import Recorder, run_attributes
from .solver import SolverSettings, solve_increment
from .state import MDRHistory
from .variables import HISTORY_VARIABLES, STEP_VARIABLES


class SimulationError(RuntimeError):
    """A run stopped before the end of its path; ``.dataset`` holds every converged increment."""

    def __init__(self, message, dataset=None):
        super().__init__(message)
        self.dataset = dataset


class StressNotReachableError(SimulationError):
    """A prescribed stress cannot be carried by the interface (e.g. shear above its strength)."""


class ConvergenceError(SimulationError):
    """An increment did not converge even after the largest number of cut-backs."""


def _theta_am(params, closure):
    from .reference import theta_am

    return float(theta_am(params, closure))


def simulate(params: InterfaceParams, path: LoadPath, n: int = 100_000, seed: int | None = 0,
             sampler: str = "random", law: str = "paper", policy: str = "follow", *, k: int = 16,
             snapshots=None, output=None, settings: SolverSettings | None = None,
             population: Population | None = None, progress=None):
    """Run ``path`` on a population sampled from ``params`` and return an ``xarray.Dataset``.

    Parameters
    ----------
    params : InterfaceParams
    path : LoadPath
    n : int, number of sampled asperities
    seed : int or None; sampler : "random" or "sobol"
    law : "paper" (path independent, SPEC §5) or "mdr" (history per contact, :mod:`asperity_sim.laws.mdr`)
    policy : "follow" or "birth" (SPEC §3)
    k : int, tangential springs per contact (law "mdr")
    snapshots : None, "stage_ends", or a sequence of step numbers: per-asperity arrays to record
    output : path of a netCDF file to write (atomically), also when the run fails
    settings : SolverSettings
    population : a Population to reuse instead of sampling (params, n, seed, sampler then come from it)
    progress : callable(stage, n_stages, fraction, step, iterations) called after each increment

    Returns
    -------
    xarray.Dataset with dimension ``step`` (see :mod:`asperity_sim.variables`).
    """
    if not isinstance(params, InterfaceParams):
        raise ValueError(f"params = {params!r} is not an InterfaceParams")
    if not isinstance(path, LoadPath):
        raise ValueError(f"path = {path!r} is not a LoadPath (see asperity_sim.paths)")
    check_choice("law", law, LAWS)
    check_choice("policy", policy, POLICIES)
    check_choice("sampler", sampler, SAMPLERS)
    settings = SolverSettings() if settings is None else settings
    if not isinstance(settings, SolverSettings):
        raise ValueError(f"settings = {settings!r} is not a SolverSettings")
    if population is not None and not isinstance(population, Population):
        raise ValueError(f"population = {population!r} is not a Population")
    if output is not None and not isinstance(output, (str, os.PathLike)):
        raise ValueError(f"output = {output!r} is not a file path")
    snap_steps, snap_stage_ends = _check_snapshots(snapshots)
    if progress is not None and not callable(progress):
        raise ValueError(f"progress = {progress!r} must be callable or None")
    if population is None:
        population = Population.sample(params, n, seed=seed, sampler=sampler)
    elif population.params != params:
        raise ValueError("population was sampled from other parameters than params")
    pop = population
    call = (f"asperity_sim.simulate(path={path.name}, n={pop.n}, seed={pop.seed}, sampler={pop.sampler!r}, "
            f"law={law!r}, policy={policy!r})")
    attrs = run_attributes(params, n=pop.n, seed=pop.seed, sampler=pop.sampler, law=law, policy=policy,
                           path=path, version=__version__, call=call)
    ws = Workspace(pop.n)
    theta_birth = np.full(pop.n, np.nan) if policy == "birth" else None
    length = (params.alpha + 1.0) * params.beta  # mean height: the natural displacement scale
    history = MDRHistory(pop, k=k, dn_cap=_closure_cap(pop, path, ws)) if law == "mdr" else None
    if history is not None:
        attrs["springs_per_contact"] = history.k

    def evaluate_at(delta):
        return evaluate(pop, delta, law=law, policy=policy, theta_birth=theta_birth, workspace=ws,
                        history=history)

    def take_snapshot(step, delta):
        if history is None:
            rec.add_snapshot(step, snapshot(pop, delta, policy, theta_birth))
        else:
            rec.add_snapshot(step, history.snapshot(delta, theta_birth))

    total = sum(s.increments for s in path.stages)
    rec = Recorder(total + 1, STEP_VARIABLES if history is None else {**STEP_VARIABLES, **HISTORY_VARIABLES})
    delta = np.zeros(3)
    ev = evaluate_at(delta)
    energy = {"external_work": 0.0, "elastic_energy": 0.0, "dissipation": 0.0, "coarsenings": 0,
              "transitions": np.zeros((4, 4), dtype=np.int64)} if history is not None else {}
    _record(rec, params, ev, stage=0, control=np.zeros(3, bool), iterations=0, residual=0.0, cutbacks=0,
            **energy)
    if 0 in snap_steps:
        take_snapshot(0, delta)
    failure = None
    interrupted = None
    t0 = time.perf_counter()
    try:
        for i_stage, stage in enumerate(path.stages, 1):
            free = stage.stress_controlled
            start_delta, start_stress = delta.copy(), ev.stress.copy()
            end = np.asarray(stage.target, dtype=float)
            k_start = None  # stiffness of the ramped stress directions after the first increment
            nominal = 1.0 / stage.increments
            smallest = nominal * 0.5 ** settings.max_cutbacks
            s, ds, cuts = 0.0, nominal, 0
            while s < 1.0 - 1e-12:
                ds = min(ds, 1.0 - s)
                s_new = 1.0 if s + ds > 1.0 - 1e-12 else s + ds
                target_delta = np.where(free, delta, start_delta + s_new * (end - start_delta))
                target_stress = np.where(free, start_stress + s_new * (end - start_stress), 0.0)
                guess = _predict(ev, delta, target_delta, target_stress, free)
                result = solve_increment(evaluate_at, guess, free, target_stress, length, settings)
                if not result.converged:
                    cuts += 1
                    if result.unreachable or cuts > settings.max_cutbacks or ds * 0.5 < smallest:
                        failure = _failure(result, ev, free, start_stress, end, target_stress, i_stage, stage, s,
                                           cuts, k_start)
                        raise failure
                    ds *= 0.5
                    continue
                ev = result.evaluation
                delta = ev.delta.copy()
                if history is not None:  # commit the springs first: they were evaluated with the old angles
                    c = history.commit(delta, ev.n_active, theta_birth)
                    energy = {"external_work": energy["external_work"] + c.work, "elastic_energy": c.stored,
                              "dissipation": energy["dissipation"] + c.dissipation,
                              "coarsenings": c.coarsenings, "transitions": c.transitions}
                if theta_birth is not None:
                    birth_angles(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, ev.n_active, delta,
                                 params.r_o, params.k_e, theta_birth)
                s = s_new
                if k_start is None and free.any():
                    k_start = effective_stiffness(ev, free, _ramped(free, start_stress, end))
                _record(rec, params, ev, stage=i_stage, control=free, iterations=result.iterations,
                        residual=result.residual, cutbacks=cuts, **energy)
                step = rec.size - 1
                if step in snap_steps or (snap_stage_ends and s >= 1.0 - 1e-12):
                    take_snapshot(step, delta)
                if progress is not None:
                    progress(i_stage, len(path.stages), s, step, result.iterations)
                if stage.adaptive:
                    ds = min(ds * (1.5 if result.iterations <= 3 else 1.0), stage.max_fraction)
                    if result.iterations > 8:
                        ds *= 0.5
                else:
                    ds = min(2.0 * ds, nominal) if cuts else nominal
                cuts = 0
    except BaseException as err:  # noqa: B036 - recorded, then re-raised
        interrupted = err
        raise
    finally:
        attrs["wall_time_s"] = time.perf_counter() - t0
        if failure is not None:
            attrs["status"] = f"failed: {failure}"
        elif interrupted is not None:
            attrs["status"] = f"interrupted: {type(interrupted).__name__}: {interrupted}"
        else:
            attrs["status"] = "complete"
        ds_out = rec.to_dataset(attrs, population=pop)
        if output is not None:
            from .io import write_netcdf

            write_netcdf(ds_out, output)
        if failure is not None:
            failure.dataset = ds_out
    return ds_out


def solution_stderr(ev, free):
    """Standard errors of the recorded stress and displacement under mixed control.

    The Monte Carlo error dsigma of the estimate moves the solved displacements:
    dDelta_f = -T_ff^-1 dsigma_f, and the reported stresses of the displacement-controlled
    components by dsigma_d - T_df T_ff^-1 dsigma_f (delta method, first order, using the
    covariance of the estimate).  Returns (stress_stderr [Pa], displacement_stderr [m]).
    """
    free = np.asarray(free, dtype=bool)
    if not free.any():
        return ev.stderr, np.zeros(3)
    fixed = ~free
    A = np.linalg.pinv(ev.tangent[np.ix_(free, free)], rcond=1e-12)
    M_stress = np.zeros((3, 3))
    M_stress[np.ix_(fixed, fixed)] = np.eye(int(fixed.sum()))
    M_stress[np.ix_(fixed, free)] = -ev.tangent[np.ix_(fixed, free)] @ A
    M_disp = np.zeros((3, 3))
    M_disp[np.ix_(free, free)] = -A
    var_s = np.einsum("ij,jk,ik->i", M_stress, ev.covariance, M_stress)
    var_d = np.einsum("ij,jk,ik->i", M_disp, ev.covariance, M_disp)
    return np.sqrt(np.maximum(var_s, 0.0)), np.sqrt(np.maximum(var_d, 0.0))


def _record(rec, params, ev, *, stage, control, iterations, residual, cutbacks, **extra):
    stress_se, disp_se = solution_stderr(ev, control)
    rec.append(
        displacement=ev.delta, stress=ev.stress, stress_stderr=stress_se, displacement_stderr=disp_se,
        tangent=ev.tangent,
        n_contact=ev.n_contact, n_slip=ev.n_slip, n_partial=ev.n_partial,
        theta_am=_theta_am(params, max(0.0, params.r_o + ev.delta[0])), mean_theta=ev.mean_theta,
        stage=stage, control=control.astype("i1"), iterations=iterations, residual=residual,
        cutbacks=cutbacks, **extra,
    )


def _closure_cap(pop, path, ws):
    """Largest closure Delta_1 [m] the path is expected to reach (sets the springs' spacing).

    Displacement-controlled normal targets are read off the path; a normal stress target is
    converted by bisection on the ``paper`` law at zero shear (the springs coarsen if a
    contact grows beyond this estimate, so it need not be exact).
    """
    cap = pop.params.beta
    for stage in path.stages:
        if stage.control[0] == "displacement":
            cap = max(cap, stage.target[0])
            continue
        target = stage.target[0]
        lo, hi = 0.0, pop.params.beta
        while evaluate(pop, [hi, 0.0, 0.0], workspace=ws).stress[0] < target and hi < 1e3:
            lo, hi = hi, 2.0 * hi
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if evaluate(pop, [mid, 0.0, 0.0], workspace=ws).stress[0] < target:
                lo = mid
            else:
                hi = mid
        cap = max(cap, hi)
    return cap


def _predict(ev, delta, target_delta, target_stress, free):
    """Tangent predictor for the free components from the last converged state."""
    guess = target_delta.copy()
    if not free.any():
        return guess
    fixed = ~free
    rhs = (target_stress - ev.stress)[free] - ev.tangent[np.ix_(free, fixed)] @ (target_delta - delta)[fixed]
    T = ev.tangent[np.ix_(free, free)]
    try:
        if np.linalg.cond(T) < 1e12:
            step = np.linalg.solve(T, rhs)
            if np.all(np.isfinite(step)):
                guess[free] = delta[free] + step
    except np.linalg.LinAlgError:
        pass
    return guess


def _ramped(free, start_stress, end):
    """Stress-controlled components whose target changes over the stage (all of them if none does)."""
    moving = [k for k in np.flatnonzero(free)
              if abs(end[k] - start_stress[k]) > 1e-6 * max(abs(end[k]), abs(start_stress[k]))]
    return moving or list(np.flatnonzero(free))


def effective_stiffness(ev, free, ramped):
    """Stiffness [Pa/m] of the ramped stress components with the other stress-controlled ones held.

    The inverse of the ramped block of the compliance T_ff^-1; 0 where T_ff is singular.
    """
    idx = np.flatnonzero(free)
    pos = [int(np.flatnonzero(idx == k)[0]) for k in ramped]
    try:
        C = np.linalg.inv(ev.tangent[np.ix_(idx, idx)])
        K = np.linalg.inv(C[np.ix_(pos, pos)])
    except np.linalg.LinAlgError:
        return 0.0
    return float(np.min(np.linalg.eigvalsh(0.5 * (K + K.T))))


def _failure(result, ev, free, start_stress, end, target_stress, i_stage, stage, s, cuts, k_start=None):
    """The named exception for an increment that cannot be completed.

    A prescribed stress is declared unreachable when the solver saw it saturate, or when the
    stiffness of the interface in the ramped stress directions (the others held) has fallen
    below 2 % of its value at the start of the stage: the target lies beyond a peak or a plateau.
    """
    where = f"stage {i_stage} ({stage.name or 'unnamed'}) stopped at {s:.4g} of the stage after {cuts - 1} cut-backs"
    if not free.any():
        return ConvergenceError(f"{where}: {result.message}")
    ramped = _ramped(free, start_stress, end)
    names = ", ".join(f"sigma_{k + 1} = {target_stress[k]:.6g} Pa" for k in ramped)
    reached = ", ".join(f"sigma_{k + 1} = {ev.stress[k]:.6g} Pa" for k in ramped)
    k_now = effective_stiffness(ev, free, ramped)
    softened = k_start is not None and k_start > 0 and k_now < 0.02 * k_start
    if result.unreachable or softened or _saturated(ev, free):
        return StressNotReachableError(
            f"{names} cannot be reached: {where}; the interface carried at most {reached} "
            f"(at Delta = {np.array2string(ev.delta, precision=4)} m) and its stiffness in the stress-controlled "
            f"directions is exhausted ({result.message})")
    return ConvergenceError(f"{names} not reached: {where}; last converged {reached} ({result.message})")


def _saturated(ev, free):
    """True when the tangent block of the free components has (almost) no stiffness left."""
    T = ev.tangent[np.ix_(free, free)]
    sv = np.linalg.svd(T, compute_uv=False)
    return bool(sv[-1] <= 1e-6 * max(np.abs(ev.tangent).max(), 1e-300))


def _check_snapshots(snapshots):
    if snapshots is None:
        return set(), False
    if snapshots == "stage_ends":
        return set(), True
    try:
        steps = set(snapshots)
    except TypeError:
        raise ValueError(f"snapshots = {snapshots!r} must be None, 'stage_ends' or a sequence of step numbers")
    for s in steps:
        if isinstance(s, bool) or not isinstance(s, numbers.Integral) or s < 0:
            raise ValueError(f"snapshot step {s!r} is not valid (valid range: integer >= 0)")
    return {int(s) for s in steps}, False
