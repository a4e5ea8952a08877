"""simulate(): a load path stepped through increments under mixed control (SPEC §6–§7).

Owns the entry points of a run: :func:`simulate` checks every input before any work (the
law's options through the law), and builds the :class:`~asperity_sim.solve.run.Run`, which
owns the loop (increments, cut-backs, commit, record, inside ``try/finally``);
:func:`resume` continues a run from its checkpoint alone.  How the next increment is sized and
predicted, and the named failure of one that cannot be completed, live in
:mod:`asperity_sim.solve.stepping`; the errors in :mod:`asperity_sim.errors`; what a
checkpoint holds of a run in :mod:`asperity_sim.solve.run_checkpoint` (the file format in
:mod:`asperity_sim.output.checkpoint`).  A run stops only with a named
:class:`SimulationError` that says why (a stress the interface cannot carry, an increment
that does not converge after every cut-back, the wall-time limit), never with NaN.  The
whole state of a run (:class:`Run`) can be checkpointed at chosen steps and resumed
bit-identically (:func:`asperity_sim.solve.run_checkpoint.save` and
:func:`~asperity_sim.solve.run_checkpoint.restore`, :func:`resume`).
"""

from __future__ import annotations

import numbers
import os

from .. import laws
from ..checks import check_choice, check_file, check_int, check_real, check_writable
from ..geometry import POLICIES
from ..params import InterfaceParams
from ..paths import LoadPath
from ..sampling.population import N_MAX, SAMPLERS, Population
from . import run_checkpoint
from .run import Run
from .solver import SolverSettings

SEED_MAX = 2**63 - 1  # a seed is stored as a 64-bit integer attribute


def simulate(params: InterfaceParams, path: LoadPath, n: int = 100_000, seed: int | None = 0,
             sampler: str = "random", law: str = "paper", policy: str = "follow", *, snapshots=None, output=None,
             settings: SolverSettings | None = None, population: Population | None = None, progress=None,
             max_wall_time: float | None = None, checkpoint=None, checkpoint_every: int | None = None, resume=None,
             **law_options):
    """Run ``path`` on a population sampled from ``params`` and return an ``xarray.Dataset``.

    Parameters
    ----------
    params : InterfaceParams
    path : LoadPath
    n : int, number of sampled asperities, in [1, 2**31 - 1]
    seed : int >= 0 or None; sampler : "random" or "sobol"
    law : a registered law (:mod:`asperity_sim.laws`): "paper" (path independent, SPEC §5) or
        "mdr" (history per contact, :mod:`asperity_sim.laws.mdr`)
    policy : "follow" or "birth" (SPEC §3)
    snapshots : None, "stage_ends", or a sequence of step numbers: per-asperity arrays to record
    output : path of a netCDF file to write (atomically), also when the run fails
    settings : SolverSettings
    population : a Population to reuse instead of sampling (params, n, seed, sampler then come from it)
    progress : callable(stage, n_stages, fraction, step, iterations) called after each increment
    max_wall_time : float > 0 [s] or None; past it the run stops with :class:`WallTimeExceededError`
        (checked before every increment and cut-back)
    checkpoint : path of a checkpoint file (:mod:`asperity_sim.output.checkpoint`) written atomically every
        ``checkpoint_every`` converged increments (None: at the end of every stage), and when the
        run is interrupted by an exception that is not a :class:`SimulationError`
    checkpoint_every : int >= 1 or None
    resume : path of a checkpoint of this same run (same parameters, path, n, seed, sampler, law,
        policy, law options, settings, snapshots and package version; anything else raises
        :class:`~asperity_sim.errors.CheckpointError`, a ``ValueError``): the run continues
        from it and its results are bit-identical to an uninterrupted run.  :func:`resume`
        does the same from the file alone.
    **law_options : the law's options (:attr:`Law.options <asperity_sim.laws.Law>`; ``mdr``: ``k``,
        springs a contact has at least at its largest extent, and ``spring_dtype``), each checked by
        the law; an option of another registered law is accepted and ignored, any other name refused

    Returns
    -------
    xarray.Dataset with dimension ``step`` (see :mod:`asperity_sim.output.variables`).

    Raises
    ------
    ValueError for invalid input (before any work); :class:`StressNotReachableError`,
    :class:`ConvergenceError`, :class:`WallTimeExceededError` (all :class:`SimulationError`,
    with ``.dataset``) when the run stops early.
    """
    if not isinstance(params, InterfaceParams):
        raise ValueError(f"params = {params!r} is not an InterfaceParams")
    if not isinstance(path, LoadPath):
        raise ValueError(f"path = {path!r} is not a LoadPath (see asperity_sim.paths)")
    law = laws.get(law).name
    options = laws.options_of(law, law_options)
    check_choice("policy", policy, POLICIES)
    check_choice("sampler", sampler, SAMPLERS)
    n = check_int("n", n, 1, N_MAX)
    if seed is not None:
        seed = check_int("seed", seed, 0, SEED_MAX)
    settings = SolverSettings() if settings is None else settings
    if not isinstance(settings, SolverSettings):
        raise ValueError(f"settings = {settings!r} is not a SolverSettings")
    if population is not None and not isinstance(population, Population):
        raise ValueError(f"population = {population!r} is not a Population")
    if population is not None and population.params != params:
        raise ValueError("population was sampled from other parameters than params")
    output = check_writable("output", check_file("output", output))
    snaps = _check_snapshots(snapshots)
    if progress is not None and not callable(progress):
        raise ValueError(f"progress = {progress!r} must be callable or None")
    if max_wall_time is not None:
        max_wall_time = check_real("max_wall_time [s]", max_wall_time, 0.0, None, lo_open=True)
    checkpoint = check_writable("checkpoint", check_file("checkpoint", checkpoint))
    if output is not None and checkpoint is not None and os.path.abspath(output) == os.path.abspath(checkpoint):
        raise ValueError(f"output and checkpoint are the same file {os.fspath(output)!r}: give two different paths")
    if checkpoint_every is not None:
        checkpoint_every = check_int("checkpoint_every (steps)", checkpoint_every, 1, None)
        if checkpoint is None:
            raise ValueError(f"checkpoint_every = {checkpoint_every} needs a checkpoint file (checkpoint = None)")
    resume = check_file("resume", resume)
    saved = None
    if resume is not None:
        saved = run_checkpoint.read(resume)
        if population is not None:
            n, seed, sampler = population.n, population.seed, population.sampler
        run_checkpoint.check_same_run(saved, run_checkpoint.config_of(
            params, path, n=n, seed=seed, sampler=sampler, law=law, policy=policy, options=options,
            settings=settings, snapshots=snaps))
    run = Run(params, path, n=n, seed=seed, sampler=sampler, law=law, policy=policy, options=options, snaps=snaps,
              settings=settings, population=population, saved=saved)
    return run.go(output=output, progress=progress, max_wall_time=max_wall_time, checkpoint=checkpoint,
                  checkpoint_every=checkpoint_every)


def resume(checkpoint, *, output=None, progress=None, max_wall_time: float | None = None, checkpoint_every="saved"):
    """Continue the run saved in ``checkpoint`` from the file alone; return its complete dataset.

    Parameters, load path, population, solver settings and state all come from the
    checkpoint; the run goes on checkpointing to the same file every ``checkpoint_every``
    steps (default: as the interrupted run did; None: at stage ends).  ``output``,
    ``progress`` and ``max_wall_time`` as in :func:`simulate`.  The result is bit-identical
    to an uninterrupted run (only the wall time and the history attribute differ).
    """
    checkpoint = check_file("checkpoint", checkpoint)
    if checkpoint is None:
        raise ValueError("checkpoint = None is not valid: name the checkpoint file to resume from (str or os.PathLike)")
    saved = run_checkpoint.read(checkpoint)
    every = saved.meta.get("checkpoint_every") if checkpoint_every == "saved" else checkpoint_every
    return simulate(**run_checkpoint.run_arguments(saved), output=output, progress=progress,
                    max_wall_time=max_wall_time, checkpoint=checkpoint, checkpoint_every=every, resume=saved)


def _check_snapshots(snapshots):
    if snapshots is None:
        return set(), False
    if isinstance(snapshots, str):
        if snapshots == "stage_ends":
            return set(), True
        raise ValueError(f"snapshots = {snapshots!r} must be None, 'stage_ends' or a sequence of step numbers")
    try:
        steps = set(snapshots)
    except TypeError:
        raise ValueError(f"snapshots = {snapshots!r} must be None, 'stage_ends' or a sequence of step numbers")
    for s in steps:
        if isinstance(s, bool) or not isinstance(s, numbers.Integral) or s < 0:
            raise ValueError(f"snapshot step {s!r} is not valid (valid range: integer >= 0)")
    return {int(s) for s in steps}, False
