"""Ensembles and parameter sweeps of a scene, serially or on Dask.

Owns sweeps: a grid of interface-parameter values times a number of replicas (seeds),
one independent :func:`asperity_sim.simulate` per point, gathered into one
``xarray.Dataset`` with the swept parameters and ``replica`` as dimensions, plus the
ensemble mean and its standard error over the replicas (``<var>_mean``, ``<var>_sem``).

Runs are aligned on the *nominal* schedule of the load path (stage ``i``, fraction
``j / increments``).  A run whose stages took exactly their nominal increments is copied
step for step; a run with cut-backs or adaptive increments is interpolated linearly in the
stage fraction (recovered from its controlled components), and one that stopped early is
NaN beyond its last converged step.  Each run is a pure function of (scene, parameters,
seed) and the kernels sum in fixed chunks, so a sweep gives the same bits serially and on
any number of Dask workers.

A sweep file is a scene file (:mod:`asperity_sim.scene`) with a ``[sweep]`` table::

    scene = "constant_normal_shear_R1.toml"   # optional: take the tables not given here from
                                              # this scene ([parameters] and [run] key by key),
                                              # path relative to the sweep file
    [run]
    n = 20000
    seed = 1                                  # replica i uses seed + i (the same at every grid point)
    [sweep]
    replicas = 4                              # or seeds = [1, 7, 9]
    [sweep.grid]                              # InterfaceParams fields, values with units
    mu = [0.5, 1.0]
    R_m = ["40 um", "50 um"]
    sigma_n = ["10 MPa", "100 MPa"]           # load-path quantities (see apply_path):
    amplitude = ["1 um", "5 um"]              #   normal stress, shear amplitude,
    direction = ["0 deg", "45 deg"]           #   shear direction (deg or rad), cycles
    cycles = [1, 2]
    law = ["paper", "mdr"]                    # run settings: law, n, k
    n = [5000, 20000]
    [output]
    file = "sweep.nc"                         # default <sweep file name>.nc

Load-path quantities change the scene's path (:func:`apply_path`): ``cycles`` repeats the
stages after the first; ``sigma_n`` scales every stress-controlled sigma_1 target so that
the largest is sigma_n; ``amplitude`` scales every displacement-controlled shear target
(Delta_2, Delta_3) so that the largest magnitude is the amplitude; ``direction`` rotates
the shear targets about axis 1 by that angle.  Runs of different lengths (``cycles``) are
NaN-padded to the longest path.  A run that fails (for example
``StressNotReachableError``) keeps its error in ``status`` and NaN where it did not reach;
the other runs complete.

Engine: ``scheduler=None`` (``"auto"``) runs serially or on a local Dask cluster, whichever
:func:`choose_engine` estimates faster for the size at hand; ``"local"`` forces the
cluster, ``"serial"`` one process, an address or a ``Client`` an existing scheduler.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import itertools
import logging
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from . import __version__, paths
from .params import InterfaceParams
from .scene import (Scene, SceneError, check_int, check_keys, format_quantity, parse_quantity, read_toml,
                    scene_from_dict)

__all__ = ["Sweep", "load_sweep", "run_sweep", "run_one", "align_run", "ensemble_statistics", "dask_available",
           "apply_path", "choose_engine", "estimate_run_seconds", "ALIGNED", "STATISTICS", "PATH_QUANTITIES",
           "RUN_QUANTITIES"]

ALIGNED = ("displacement", "stress", "stress_stderr", "displacement_stderr", "tangent", "n_contact", "n_slip",
           "n_partial", "theta_am", "mean_theta", "external_work", "elastic_energy", "dissipation")
"""Per-step outputs carried into a sweep (those a run holds)."""

STATISTICS = ("displacement", "stress", "tangent", "n_contact", "n_slip", "n_partial", "theta_am", "mean_theta",
              "external_work", "elastic_energy", "dissipation")
"""Outputs that get an ensemble mean and standard error over the replicas."""


PATH_QUANTITIES = {
    "sigma_n": ("Pa", "largest prescribed normal stress sigma_1 of the path"),
    "amplitude": ("m", "largest prescribed shear displacement magnitude (shear amplitude) of the path"),
    "direction": ("rad", "shear direction: rotation of the shear targets about axis 1, from axis 2 towards 3"),
    "cycles": ("1", "number of repetitions of the stages after the first (cycles)"),
}
"""Load-path quantities a sweep grid can vary: name -> (SI unit, long name)."""

RUN_QUANTITIES = {
    "law": ("1", "asperity law"),
    "n": ("1", "sampled asperities per run"),
    "k": ("1", "tangential springs per contact (law mdr)"),
}
"""Run settings a sweep grid can vary: name -> (unit, long name)."""

def parse_angle(value, name="direction") -> float:
    """An angle [rad] from a plain number (radians) or a string with its unit (``"30 deg"``, ``"0.5 rad"``, pint)."""
    return parse_quantity(value, "rad", name)


def _check_value(name, value):
    """One grid value of a load-path or run quantity, checked (SceneError naming the key and the valid range)."""
    from .laws import LAWS
    from .population import N_MAX

    where = f"sweep grid: {name}"
    if name in ("sigma_n", "amplitude", "direction") and (isinstance(value, (bool, str))
                                                          or not isinstance(value, (int, float, np.number))):
        raise SceneError(f"{where} = {value!r} is not a number in {PATH_QUANTITIES[name][0]} (in a sweep file, "
                         "quantities with units such as \"10 MPa\" are converted before this check)")
    if name in ("sigma_n", "amplitude"):
        v = float(value)
        if not (math.isfinite(v) and v > 0.0):
            raise SceneError(f"{where} = {value!r} is out of range (valid range: > 0 {PATH_QUANTITIES[name][0]})")
        return v
    if name == "direction":
        v = float(value)
        if not math.isfinite(v):
            raise SceneError(f"{where} = {value!r} is out of range (valid range: finite angle)")
        return v
    if name == "law":
        if value not in LAWS:
            raise SceneError(f"{where} = {value!r} is not known (valid: {', '.join(LAWS)})")
        return value
    lo, hi = {"cycles": (1, 1000), "n": (1, N_MAX), "k": (1, 4096)}[name]
    return check_int(value, where, lo, hi)


def apply_path(path: paths.LoadPath, sigma_n=None, amplitude=None, direction=None, cycles=None) -> paths.LoadPath:
    """``path`` with its load-path quantities changed (see the module docstring); None leaves one as is.

    Raises ValueError when the path has nothing the quantity could change (for example
    ``sigma_n`` on a path without a stress-controlled sigma_1).
    """
    stages = list(path.stages)
    if cycles is not None:
        if len(stages) < 2:
            raise ValueError(f"cycles = {cycles}: the path has one stage; cycles repeat the stages after the first")
        stages = stages[:1] + stages[1:] * int(cycles)
    if sigma_n is not None:
        held = [st.target[0] for st in stages if st.control[0] == paths.STRESS]
        if not held or max(held) <= 0.0:
            raise ValueError(f"sigma_n = {sigma_n:.4g} Pa: the path has no stress-controlled sigma_1 > 0 to set "
                             "(give a stage with sigma_1 = \"<stress>\")")
        f = sigma_n / max(held)
        stages = [dataclasses.replace(st, target=(st.target[0] * f,) + st.target[1:]) if st.control[0] == paths.STRESS
                  else st for st in stages]
    if amplitude is not None:
        shear = [abs(t) for st in stages for c, t in zip(st.control[1:], st.target[1:]) if c == paths.DISPLACEMENT]
        largest = max(shear, default=0.0)
        if largest == 0.0:
            raise ValueError(f"amplitude = {amplitude:.4g} m: the path has no displacement-controlled shear "
                             "(Delta_2 or Delta_3) other than 0 to scale")
        f = amplitude / largest
        stages = [dataclasses.replace(st, target=(st.target[0],) + tuple(
            t * f if c == paths.DISPLACEMENT else t for c, t in zip(st.control[1:], st.target[1:])))
            for st in stages]
    if direction is not None:
        c, s = math.cos(direction), math.sin(direction)
        rotated = []
        for i, st in enumerate(stages, 1):
            t2, t3 = st.target[1:]
            if st.control[1] != st.control[2]:
                if t2 != 0.0 or t3 != 0.0:
                    raise ValueError(f"direction: stage {i} controls Delta and sigma in the shear plane; "
                                     "only a stage with both shear components of one kind can be rotated")
                rotated.append(st)
                continue
            rotated.append(dataclasses.replace(st, target=(st.target[0], c * t2 - s * t3, s * t2 + c * t3)))
        stages = rotated
    return paths.LoadPath(tuple(stages), name=path.name)


def _grid_kind(name):
    if name in PATH_QUANTITIES:
        return "path"
    if name in RUN_QUANTITIES:
        return "run"
    return "param"


@dataclass(frozen=True)
class Sweep:
    """A scene run at every point of a parameter grid, ``len(seeds)`` times each.

    grid : {name: tuple of values}, in the order of the output dimensions; a name is an
        InterfaceParams field [SI], a load-path quantity (:data:`PATH_QUANTITIES`: sigma_n [Pa],
        amplitude [m], direction [rad], cycles) or a run setting (:data:`RUN_QUANTITIES`: law, n, k)
    seeds : one seed per replica (default: scene.seed + 0, 1, ..., replicas - 1)
    """

    scene: Scene
    grid: dict = dataclasses.field(default_factory=dict)
    seeds: tuple = ()
    output: Path | None = None
    title: str = ""
    source: str = "<sweep>"

    def __post_init__(self):
        units = InterfaceParams.units()
        grid = {}
        for name, values in dict(self.grid).items():
            if name not in units and name not in PATH_QUANTITIES and name not in RUN_QUANTITIES:
                raise SceneError(f"sweep grid: unknown parameter {name!r} (valid: "
                                 f"{', '.join([*units, *PATH_QUANTITIES, *RUN_QUANTITIES])})")
            vals = tuple(float(v) if name in units else _check_value(name, v) for v in values)
            if not vals:
                raise SceneError(f"sweep grid: {name} has no values")
            if len(set(vals)) != len(vals):
                raise SceneError(f"sweep grid: {name} = {list(vals)} repeats a value")
            grid[name] = vals
        object.__setattr__(self, "grid", grid)
        seeds = tuple(self.seeds) or (self.scene.seed,)
        for s in seeds:
            if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0:
                raise SceneError(f"sweep seeds: {s!r} is not a valid seed (valid range: integer >= 0)")
        if len(set(seeds)) != len(seeds):
            raise SceneError(f"sweep seeds = {list(seeds)} repeat a seed (replicas would be identical)")
        object.__setattr__(self, "seeds", tuple(int(s) for s in seeds))
        for point in self.points():  # every grid point must be a valid run before anything runs
            try:
                self.scene_at(point)
            except ValueError as err:
                raise SceneError(f"sweep grid point {point}: {err}") from None

    @property
    def shape(self) -> tuple:
        return tuple(len(v) for v in self.grid.values()) + (len(self.seeds),)

    @property
    def dims(self) -> tuple:
        return tuple(self.grid) + ("replica",)

    def points(self) -> list[dict]:
        """Parameter overrides at every grid point, in C order."""
        names = list(self.grid)
        return [dict(zip(names, combo)) for combo in itertools.product(*self.grid.values())]

    def scene_at(self, point: dict) -> Scene:
        """The scene of one grid point (interface parameters, load path and run settings applied)."""
        kinds = {k: _grid_kind(k) for k in point}
        params = self.scene.params.replace(**{k: v for k, v in point.items() if kinds[k] == "param"})
        path = apply_path(self.scene.path, **{k: v for k, v in point.items() if kinds[k] == "path"})
        return self.scene.replace(params=params, path=path, snapshots=None,
                                  **{k: v for k, v in point.items() if kinds[k] == "run"})

    def scenes(self) -> list[Scene]:
        """One scene per run, in C order of (grid..., replica)."""
        return [self.scene_at(point).replace(seed=seed) for point in self.points() for seed in self.seeds]

    def longest_path(self) -> paths.LoadPath:
        """The path with the most nominal steps over the grid (the others are its prefixes in stage structure)."""
        return max((self.scene_at(p).path for p in self.points()), key=lambda pth: sum(s.increments for s in pth.stages))

    def default_output(self) -> Path:
        return self.output if self.output is not None else Path(f"{Path(self.source).stem}.nc")


def load_sweep(path) -> Sweep:
    """Read and check a sweep file (a scene file with a ``[sweep]`` table)."""
    path = Path(path)
    data = read_toml(path)
    where = f"{path}: "
    if "sweep" not in data:
        raise SceneError(f"{where}missing [sweep] table (replicas, seeds and/or [sweep.grid])")
    table = data["sweep"]
    if not isinstance(table, dict):
        raise SceneError(f"{where}sweep must be a table [sweep]")
    check_keys(table, ("replicas", "seeds", "grid"), f"{where}[sweep] ")
    if "scene" in data:
        base_name = data["scene"]
        if not isinstance(base_name, str):
            raise SceneError(f"{where}scene = {base_name!r} must be the path of a scene file")
        base_path = path.parent / base_name
        base = read_toml(base_path)
        if "sweep" in base or "scene" in base:
            raise SceneError(f"{where}scene = {base_name!r} is a sweep file, not a scene file")
        merged = dict(base)
        for key, value in data.items():
            if key in ("parameters", "run") and isinstance(value, dict) and isinstance(base.get(key), dict):
                merged[key] = {**base[key], **value}
            elif key not in ("scene", "sweep"):
                merged[key] = value
        merged.pop("output", None)
        if "output" in data:
            merged["output"] = data["output"]
        scene = scene_from_dict(merged, source=f"{path} (with {base_path})", name=base_path.stem, folder=path.parent)
    else:
        scene = scene_from_dict({k: v for k, v in data.items() if k != "sweep"}, source=str(path))
    seeds = _seeds(table, scene.seed, f"{where}[sweep] ")
    grid_table = table.get("grid", {})
    if not isinstance(grid_table, dict):
        raise SceneError(f"{where}[sweep] grid must be a table [sweep.grid] of parameter = [values]")
    units = InterfaceParams.units()
    check_keys(grid_table, (*units, *PATH_QUANTITIES, *RUN_QUANTITIES), f"{where}[sweep.grid] ")
    grid = {}
    for name, values in grid_table.items():
        if not isinstance(values, list) or not values:
            raise SceneError(f"{where}[sweep.grid] {name} = {values!r} must be a non-empty list of values")
        grid[name] = tuple(_grid_value(name, v, f"{where}[sweep.grid] {name}") for v in values)
    try:
        title = data.get("title") or (f"sweep of: {scene.title}" if scene.title else "")
        return Sweep(scene=scene, grid=grid, seeds=seeds, output=scene.output, title=title, source=str(path))
    except SceneError as err:
        raise SceneError(f"{where}{err}") from None


def _grid_value(name, value, where):
    units = InterfaceParams.units()
    if name in units:
        return parse_quantity(value, units[name], where)
    if name == "direction":
        return parse_angle(value, where)
    if name in ("sigma_n", "amplitude"):
        return parse_quantity(value, PATH_QUANTITIES[name][0], where)
    return value  # law, n, k, cycles: checked by Sweep


def _seeds(table, base_seed, where):
    if "seeds" in table and "replicas" in table:
        raise SceneError(f"{where}give replicas or seeds, not both")
    if "seeds" in table:
        seeds = table["seeds"]
        if not isinstance(seeds, list) or not seeds:
            raise SceneError(f"{where}seeds = {seeds!r} must be a non-empty list of integers >= 0")
        return tuple(seeds)
    replicas = table.get("replicas", 1)
    replicas = check_int(replicas, f"{where}replicas", 1, 100_000)
    return tuple(base_seed + i for i in range(replicas))


# -- one run, aligned on the nominal schedule ------------------------------------

def nominal_schedule(path: paths.LoadPath):
    """(stage, fraction) of every nominal step of ``path``, step 0 being the initial state."""
    stage, fraction = [0], [0.0]
    for i, st in enumerate(path.stages, 1):
        stage += [i] * st.increments
        fraction += [j / st.increments for j in range(1, st.increments + 1)]
    return np.array(stage, dtype="i4"), np.array(fraction)


def _stage_fraction(ds, start, rows, stage):
    """Fraction of ``stage`` reached at each recorded row, from its controlled components."""
    disp, stress = ds["displacement"].values, ds["stress"].values
    best = None
    for want in (paths.DISPLACEMENT, paths.STRESS):
        for k in range(3):
            if stage.control[k] != want:
                continue
            values = disp if want == paths.DISPLACEMENT else stress
            span = stage.target[k] - values[start, k]
            if span != 0.0 and (best is None or abs(span) > abs(best[1])):
                best = (values[rows, k] - values[start, k], span)
        if best is not None:
            s = np.clip(best[0] / best[1], 0.0, 1.0)
            nearest = np.round(s * stage.increments) / stage.increments
            s = np.where(np.abs(s - nearest) < 1e-9, nearest, s)  # round-off must not push a step off its grid point
            return np.maximum.accumulate(s)
    return np.arange(1, rows.size + 1) / stage.increments  # nothing moves: any monotone fraction will do


def align_run(ds: xr.Dataset, path: paths.LoadPath) -> tuple[dict, bool]:
    """Per-step outputs of a run on the nominal schedule of ``path``; returns ({name: array}, exact).

    ``exact`` is True when every value was copied (no cut-back, no adaptive step, run complete).
    """
    stage_nom, _ = nominal_schedule(path)
    names = [v for v in ALIGNED if v in ds]
    values = {v: ds[v].values.astype(float) for v in names}
    out = {v: np.full((stage_nom.size,) + values[v].shape[1:], np.nan) for v in names}
    for v in names:
        out[v][0] = values[v][0]
    recorded = ds["stage"].values
    cutbacks = ds["cutbacks"].values
    exact, pos = True, 1
    for i, st in enumerate(path.stages, 1):
        rows = np.flatnonzero(recorded == i)
        m = st.increments
        if rows.size == m and not st.adaptive and not cutbacks[rows].any():
            for v in names:
                out[v][pos:pos + m] = values[v][rows]
        else:
            exact = False
            if rows.size:
                start = rows[0] - 1
                xp = np.concatenate([[0.0], _stage_fraction(ds, start, rows, st)])
                x = np.arange(1, m + 1) / m
                take = np.concatenate([[start], rows])
                for v in names:
                    fp = values[v][take].reshape(take.size, -1)
                    cols = [np.interp(x, xp, fp[:, c], right=np.nan) for c in range(fp.shape[1])]
                    out[v][pos:pos + m] = np.stack(cols, axis=1).reshape((m,) + values[v].shape[1:])
        pos += m
    return out, exact


def _set_threads(threads):
    if threads:
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))


def run_one(scene: Scene, threads: int | None = None) -> dict:
    """Run one scene (a task of a sweep) and return its aligned outputs and run summary.

    A run that stops early (``SimulationError``) returns what converged; ``threads`` sets
    numba's thread count in this process (results do not depend on it).
    """
    from .driver import SimulationError

    _set_threads(threads)
    t0 = time.perf_counter()
    try:
        ds = scene.simulate(output=None)
    except SimulationError as err:
        ds = err.dataset
        if ds is None:
            return _failed(f"failed: {type(err).__name__}: {err}", time.perf_counter() - t0)
    except (ValueError, ArithmeticError) as err:  # a point the run itself rejects: recorded, the others go on
        return _failed(f"error: {type(err).__name__}: {' '.join(str(err).split())}", time.perf_counter() - t0)
    wall = time.perf_counter() - t0
    aligned, exact = align_run(ds, scene.path)
    return {
        "aligned": aligned,
        "exact": exact,
        "status": str(ds.attrs.get("status", "unknown")),
        "n_steps": int(ds.sizes["step"]),
        "total_iterations": int(ds["iterations"].values.sum()),
        "max_iterations": int(ds["iterations"].values.max()),
        "total_cutbacks": int(ds["cutbacks"].values.sum()),
        "wall_time": wall,
        "attrs": {v: dict(ds[v].attrs) for v in aligned},
    }


def _failed(status, wall):
    """The result of a run that produced no dataset: NaN everywhere, its error in ``status``."""
    return {"aligned": {}, "exact": False, "status": status, "n_steps": 0, "total_iterations": 0,
            "max_iterations": 0, "total_cutbacks": 0, "wall_time": wall, "attrs": {}}


# -- execution -----------------------------------------------------------------

COST_PER_INCREMENT = {"paper": 2.4e-4, "mdr": 7.2e-4}
"""Python-side cost of one increment [s] (Newton loop, recording): runs on one core whatever the threads."""
COST_PER_ASPERITY_INCREMENT = {"paper": 1.3e-7, "mdr": 1.0e-7}
"""Kernel cost on one thread [s]: paper law per asperity and increment; mdr per asperity, increment and spring.
Kernels run on numba's threads (taken as scaling perfectly).  Both tables were fitted to serial runs of
the 120-increment constant-normal-shear path on 2 shared cores (2 numba threads): paper 0.045 s at
n = 2000 and 0.19 s at n = 20 000; mdr (k = 8) 0.33 s at n = 5000 and 1.06 s at n = 20 000."""
CLUSTER_START = 8.0
"""Start of a 2-worker LocalCluster and its first tasks [s] (worker processes import asperity_sim and load
the numba cache): 8.7-11.4 s for a whole small sweep on it in benchmarks/sweep_auto.py (2 shared cores)."""


def estimate_run_seconds(scene: Scene, threads: int = 1) -> float:
    """Wall time of one run [s] on ``threads`` numba threads, from the cost tables (a rough model, for choosing)."""
    increments = sum(s.increments for s in scene.path.stages)
    from .laws import get

    history = get(scene.law).history is not None  # a history law's cost grows with its springs
    law = scene.law if scene.law in COST_PER_INCREMENT else ("mdr" if history else "paper")
    per = COST_PER_ASPERITY_INCREMENT[law] * (scene.k if history else 1)
    return increments * (COST_PER_INCREMENT[law] + per * scene.n / max(1, threads))


def choose_engine(scenes, workers: int = 2, cpus: int | None = None) -> tuple[str, str]:
    """("serial" or "local", reason): the engine estimated faster for these runs.

    Serial: every run on all ``cpus`` numba threads.  Local cluster: :data:`CLUSTER_START`, then
    the runs shared by min(workers, cpus, runs) processes with cpus // workers threads each.
    The kernels use every core either way, so a cluster gains only the Python-side work it
    runs side by side (many small runs) and must win back its start.
    """
    cpus = (os.cpu_count() or 1) if cpus is None else cpus
    serial = sum(estimate_run_seconds(sc, cpus) for sc in scenes)
    share = max(1, min(workers, cpus, len(scenes)))
    per_worker = max(1, cpus // workers)
    cluster = CLUSTER_START + sum(estimate_run_seconds(sc, per_worker) for sc in scenes) / share \
        if share > 1 else math.inf
    choice = "local" if cluster < serial else "serial"
    reason = (f"auto: estimated {serial:.1f} s serial, {cluster:.1f} s on a {workers}-worker local cluster "
              f"({cpus} cores)")
    return choice, reason


def worker_env() -> dict:
    """Environment of local worker processes: idle OpenMP threads sleep (``OMP_WAIT_POLICY=PASSIVE``).

    With numba's OpenMP layer, threads that spin between the parallel reductions of a
    Newton iteration slow every process on a shared machine (measured: a small run took
    2.5 s spinning against 0.06 s sleeping on 2 loaded cores); an explicit setting wins.
    """
    return {"OMP_WAIT_POLICY": os.environ.get("OMP_WAIT_POLICY", "PASSIVE")}


def dask_available() -> bool:
    try:
        import dask.distributed  # noqa: F401
    except ImportError:
        return False
    return True


def run_sweep(sweep: Sweep, scheduler=None, workers: int = 2, progress=None, note=None,
              threads: int | None = None) -> xr.Dataset:
    """Run every point of ``sweep`` and gather one Dataset (see the module docstring).

    scheduler : None or "auto" (serial or a local cluster, whichever :func:`choose_engine` estimates
        faster), "local" (a ``dask.distributed.LocalCluster`` of ``workers`` processes), "serial",
        an address such as ``"tcp://host:8786"``, or a ``dask.distributed.Client``; None, "auto"
        and "local" run serially, with a note, when dask is not installed
    progress : callable(done, total) after each finished run
    note : callable(str) for messages to the user (default: ``logging.warning``)
    threads : numba threads per run on Dask workers (default: cores // workers on a local
        cluster, the workers' own setting elsewhere); a software setting, results do not depend on it
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers = {workers!r} is out of range (valid range: integer >= 1)")
    note = note or logging.getLogger(__name__).warning
    scenes = sweep.scenes()
    t0 = time.perf_counter()
    results, engine = _execute(scenes, scheduler, workers, progress, note, threads)
    return assemble(sweep, results, engine=engine, wall_time=time.perf_counter() - t0)


def _execute(scenes, scheduler, workers, progress, note, threads=None):
    total = len(scenes)
    why = ""
    if scheduler in (None, "auto", "local"):
        if not dask_available():
            note("dask.distributed is not installed: running the sweep serially "
                 "(pip install 'asperity-sim[distributed]' to run it on a local cluster)")
            scheduler = "serial"
        elif scheduler != "local":
            scheduler, why = choose_engine(scenes, workers)
            why = f"; {why}"
    if scheduler == "serial":
        import numba

        before = numba.get_num_threads()
        results = []
        try:
            for i, scene in enumerate(scenes, 1):
                results.append(run_one(scene, threads))
                if progress:
                    progress(i, total)
        finally:
            numba.set_num_threads(before)
        return results, f"serial ({numba.get_num_threads() if threads is None else threads} numba threads{why})"
    if isinstance(scheduler, str) and scheduler != "local" and not dask_available():
        raise ValueError(f"scheduler = {scheduler!r} needs dask.distributed, which is not installed "
                         "(pip install 'asperity-sim[distributed]')")
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = client = None
    try:
        if scheduler is None or scheduler == "local":
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR, env=worker_env())
            client = Client(cluster)
            threads = threads or max(1, (os.cpu_count() or 1) // workers)
            engine = f"dask LocalCluster ({workers} workers, 1 task and {threads} numba threads each{why})"
        elif isinstance(scheduler, str):
            try:
                client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError) as err:
                raise ValueError(f"cannot connect to the Dask scheduler at {scheduler!r}: {err}") from None
            engine = f"dask scheduler {scheduler}"
        else:
            client = scheduler
            engine = f"dask client {getattr(scheduler, 'scheduler', scheduler)}"
        futures = client.map(run_one, scenes, threads=threads, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        results = [None] * total
        for done, fut in enumerate(as_completed(futures), 1):
            results[index[fut.key]] = fut.result()
            if progress:
                progress(done, total)
        return results, engine
    finally:
        if client is not None and client is not scheduler:
            client.close()
        if cluster is not None:
            cluster.close()


# -- the gathered dataset ------------------------------------------------------------

def assemble(sweep: Sweep, results: list, engine: str = "", wall_time: float = float("nan")) -> xr.Dataset:
    """One Dataset from the run results (C order of (grid..., replica)), with ensemble statistics."""
    shape, dims = sweep.shape, sweep.dims
    path = sweep.longest_path()
    stage_nom, frac_nom = nominal_schedule(path)
    coords = {name: (name, np.array(vals), _grid_attrs(name)) for name, vals in sweep.grid.items()}
    coords["replica"] = ("replica", np.arange(len(sweep.seeds)), {"units": "1", "long_name": "replica"})
    coords["seed"] = ("replica", np.array(sweep.seeds, dtype="i8"), {"units": "1", "long_name": "sampling seed"})
    coords["step"] = ("step", np.arange(stage_nom.size), {"units": "1", "long_name": "nominal step of the load path"})
    coords["stage"] = ("step", stage_nom, {"units": "1", "long_name": "stage of the load path (0: initial state)"})
    coords["stage_fraction"] = ("step", frac_nom, {"units": "1", "long_name": "fraction of the stage reached"})
    coords["axis"] = ("axis", np.array([1, 2, 3], dtype="i4"),
                      {"units": "1", "long_name": "component: 1 normal (closure), 2 and 3 shear"})
    data = {}
    for name in ALIGNED:
        have = [r for r in results if name in r["aligned"]]
        if not have:
            continue
        trailing = have[0]["aligned"][name].shape[1:]
        stacked = np.full((len(results), stage_nom.size) + trailing, np.nan)
        for i, r in enumerate(results):
            if name in r["aligned"]:
                a = r["aligned"][name]
                stacked[i, : a.shape[0]] = a  # shorter paths (fewer cycles) are NaN-padded
        extra = ("step", "axis", "axis_k")[: 1 + len(trailing)]
        data[name] = (dims + extra, stacked.reshape(shape + stacked.shape[1:]), have[0]["attrs"][name])
    if "tangent" in data:
        coords["axis_k"] = ("axis_k", np.array([1, 2, 3], dtype="i4"),
                            {"units": "1", "long_name": "displacement component of the tangent"})
    control = np.zeros((stage_nom.size, 3), dtype="i1")
    for i, st in enumerate(path.stages, 1):
        control[stage_nom == i] = st.stress_controlled.astype("i1")
    data["control"] = (("step", "axis"), control, {"units": "1", "flag_values": np.array([0, 1], dtype="i1"),
                                                   "flag_meanings": "displacement stress",
                                                   "long_name": "control of each component (0: displacement, 1: stress)"})
    per_run = {
        "status": ("", "run status (complete, or why it stopped)", str),
        "aligned_exactly": ("1", "1: every step copied; 0: interpolated (cut-backs, adaptive steps) or stopped early",
                            "i1"),
        "n_steps": ("1", "converged increments recorded by the run (with step 0)", "i8"),
        "total_iterations": ("1", "Newton iterations of the run", "i8"),
        "max_iterations": ("1", "largest number of Newton iterations of one increment", "i8"),
        "total_cutbacks": ("1", "increment halvings of the run", "i8"),
        "wall_time": ("s", "wall time of the run", "f8"),
    }
    for name, (unit, long_name, dtype) in per_run.items():
        key = "exact" if name == "aligned_exactly" else name
        vals = np.array([r[key] for r in results], dtype=object if dtype is str else dtype).reshape(shape)
        attrs = {"long_name": long_name} if dtype is str else {"units": unit, "long_name": long_name}
        data[name] = (dims, vals.astype(str) if dtype is str else vals, attrs)
    ds = xr.Dataset(data, coords=coords)
    ds = ensemble_statistics(ds)
    ds.attrs = _sweep_attributes(sweep, engine, wall_time)
    return ds


def _grid_attrs(name):
    if name in PATH_QUANTITIES or name in RUN_QUANTITIES:
        unit, long_name = {**PATH_QUANTITIES, **RUN_QUANTITIES}[name]
        return {"units": unit, "long_name": long_name + " (swept)"}
    return {"units": InterfaceParams.units()[name], "long_name": InterfaceParams.long_names()[name] + " (swept)"}


def _format_grid_value(name, value):
    if name in InterfaceParams.units():
        return format_quantity(value, InterfaceParams.units()[name])
    if name in ("sigma_n", "amplitude"):
        return format_quantity(value, PATH_QUANTITIES[name][0])
    if name == "direction":
        return f"{math.degrees(value):.6g} deg"
    return str(value)


def ensemble_statistics(ds: xr.Dataset) -> xr.Dataset:
    """Add ``<var>_mean`` and ``<var>_sem`` (standard error of the mean) over ``replica`` (NaN-aware).

    sem = s / sqrt(m), s the sample standard deviation of the m replicas that reached the
    step; NaN where m < 2.
    """
    out = ds.copy()
    for name in STATISTICS:
        if name not in ds:
            continue
        da = ds[name]
        count = da.notnull().sum("replica")
        mean = da.mean("replica", skipna=True)
        sem = (da.std("replica", ddof=1, skipna=True) / np.sqrt(count)).where(count >= 2)
        base = {"units": da.attrs.get("units", "1")}
        out[f"{name}_mean"] = mean.assign_attrs(base, long_name=f"ensemble mean over replicas of {name}")
        out[f"{name}_sem"] = sem.assign_attrs(base, long_name=f"standard error of the ensemble mean of {name}")
    return out


def _sweep_attributes(sweep: Sweep, engine: str, wall_time: float) -> dict:
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    scene = sweep.scene
    grid = "; ".join(f"{k} = [{', '.join(_format_grid_value(k, v) for v in vals)}]" for k, vals in sweep.grid.items())
    attrs = {
        "Conventions": "CF-1.8",
        "title": sweep.title or f"asperity_sim sweep: {scene.path.name} path, law {scene.law}",
        "source": f"asperity_sim {__version__}",
        "history": f"{now} asperity_sim.sweep.run_sweep({sweep.source}) on {engine}",
        "date_created": now,
        "kind": "sweep",
        "sweep_file": sweep.source,
        "swept_parameters": " ".join(sweep.grid) or "none",
        "grid": grid or "none (replicas only)",
        "replicas": len(sweep.seeds),
        "seeds": " ".join(str(s) for s in sweep.seeds),
        "runs": int(math.prod(sweep.shape)),
        "engine": engine,
        "wall_time_s": wall_time,
        "law": scene.law if "law" not in sweep.grid else "swept: see the coordinate law",
        "policy": scene.policy,
        "sampler": scene.sampler,
        "n_asperities": scene.n if "n" not in sweep.grid else "swept: see the coordinate n",
        "load_path": sweep.longest_path().describe() if any(k in PATH_QUANTITIES for k in sweep.grid)
        else scene.path.describe(),
        "load_path_note": ("load-path quantities swept (" + ", ".join(k for k in sweep.grid if k in PATH_QUANTITIES)
                           + "): see the coordinates; load_path is the path of the longest grid point")
        if any(k in PATH_QUANTITIES for k in sweep.grid) else "not swept",
        "alignment": "runs on the nominal schedule of the path; interpolated in the stage fraction where a run "
                     "took cut-backs or adaptive steps (see aligned_exactly)",
        "asperity_sim_version": __version__,
    }
    units = InterfaceParams.units()
    for name, value in scene.params.as_dict().items():
        attrs[f"param_{name}"] = float(value)
        attrs[f"param_{name}_units"] = units[name]
        if name in sweep.grid:
            attrs[f"param_{name}_note"] = "swept: see the coordinate of the same name"
    return attrs


# -- figure ---------------------------------------------------------------------------

def plot_sweep(ds: xr.Dataset):
    """Ensemble means ±2 standard errors of every grid point: stresses, shear resistance, displacements, contacts.

    Abscissa: path length of the mean displacement [um]; one colour per grid point.
    (Lives here rather than in :mod:`asperity_sim.plotting`, which does not know sweeps yet.)
    """
    from .plotting import BAND, MARK, MPA, UM, band_legend, plt

    grid = [d for d in ds["stress"].dims if d not in ("replica", "step", "axis")]
    stacked = ds.stack(point=grid) if grid else ds.expand_dims(point=[0])
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    styles = {1: "-", 2: "--", 3: ":"}
    for j in range(stacked.sizes["point"]):
        p = stacked.isel(point=j)
        n = float(p["n"]) if "n" in grid else float(ds.attrs.get("n_asperities", 1))  # n may be swept
        label = ", ".join(f"{g} = {p[g].item():.4g}" if ds[g].dtype.kind in "fiu" else f"{g} = {p[g].item()}"
                          for g in grid) or "ensemble"
        color = colors[j % len(colors)]
        d = p["displacement_mean"].values
        ok = np.all(np.isfinite(d), axis=1)
        x = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(np.where(ok[:, None], d, 0.0), axis=0),
                                                            axis=1))]) * UM
        x = np.where(ok, x, np.nan)
        for k in (1, 2, 3):
            s = p["stress_mean"].sel(axis=k).values
            if np.nanmax(np.abs(s), initial=0.0) == 0.0:
                continue
            se = np.nan_to_num(p["stress_sem"].sel(axis=k).values)
            axes[0, 0].plot(x, s * MPA, styles[k], color=color, label=rf"$\sigma_{k}$, {label}", **MARK)
            axes[0, 0].fill_between(x, (s - BAND * se) * MPA, (s + BAND * se) * MPA, color=color, alpha=0.2, lw=0)
            dk = p["displacement_mean"].sel(axis=k).values
            dse = np.nan_to_num(p["displacement_sem"].sel(axis=k).values)
            axes[1, 0].plot(x, dk * UM, styles[k], color=color, label=rf"$\Delta_{k}$, {label}", **MARK)
            axes[1, 0].fill_between(x, (dk - BAND * dse) * UM, (dk + BAND * dse) * UM, color=color, alpha=0.2, lw=0)
        s = p["stress_mean"].values
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(s[:, 0] > 0, np.hypot(s[:, 1], s[:, 2]) / s[:, 0], np.nan)
        axes[0, 1].plot(x, ratio, color=color, label=label, **MARK)
        axes[1, 1].plot(x, p["n_contact_mean"].values / n, "-", color=color, label=f"in contact, {label}", **MARK)
        axes[1, 1].plot(x, p["n_slip_mean"].values / n, "--", color=color, label=f"full slip, {label}", **MARK)
    axes[0, 0].set_ylabel("interface stress [MPa] (ensemble mean ± 2 s.e.)")
    axes[0, 1].set_ylabel(r"shear resistance $|\sigma_{23}|/\sigma_1$ [1]")
    axes[1, 0].set_ylabel("interface displacement [µm] (ensemble mean ± 2 s.e.)")
    axes[1, 1].set_ylabel("fraction of the population [1]")
    for ax in axes.ravel():
        ax.set_xlabel(r"path length of the mean displacement $\int|d\Delta|$ [µm]")
        if ax in (axes[0, 0], axes[1, 0]):
            band_legend(ax, fontsize=7)
        else:
            ax.legend(fontsize=7)
    fig.suptitle(f"{ds.attrs.get('title', 'asperity_sim sweep')}\n{ds.attrs.get('replicas')} replica(s) per point; "
                 "bands: ±2 standard errors of the ensemble mean")
    fig.tight_layout()
    return fig
