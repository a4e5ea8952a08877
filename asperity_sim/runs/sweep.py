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

A sweep file is a scene file (:mod:`asperity_sim.runs.scene`) with a ``[sweep]`` table::

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
import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import paths
from ..checks import check_choice, check_int
from ..errors import SceneError
from ..params import InterfaceParams
from ..units import parse_quantity
from .scene import Scene, check_keys, read_toml, scene_from_dict

PATH_QUANTITIES = {
    "sigma_n": ("Pa", "largest prescribed normal stress sigma_1 of the path"),
    "amplitude": ("m", "largest prescribed shear displacement magnitude (shear amplitude) of the path"),
    "direction": ("rad", "shear direction: rotation of the shear targets about axis 1, from axis 2 towards 3"),
    "cycles": ("1", "number of repetitions of the stages after the first (cycles)"),
}
"""Load-path quantities a sweep grid can vary: name -> (SI unit, long name)."""

RUN_SETTINGS = {
    "law": ("1", "asperity law"),
    "n": ("1", "sampled asperities per run"),
}
"""Run settings a sweep grid can vary besides the laws' options: name -> (unit, long name)."""


def run_quantities() -> dict:
    """Run settings a sweep grid can vary: :data:`RUN_SETTINGS` and every registered law's options
    (name -> (unit, long name))."""
    from .. import laws

    out = dict(RUN_SETTINGS)
    for name, declaring in laws.option_names().items():
        _, doc, _, units = laws.get(declaring[0]).options.describe()[name]
        out[name] = (units, f"{doc} (law {', '.join(declaring)})")
    return out


def parse_angle(value, name="direction") -> float:
    """An angle [rad] from a plain number (radians) or a string with its unit (``"30 deg"``, ``"0.5 rad"``, pint)."""
    return parse_quantity(value, "rad", name)


def _check_value(name, value):
    """One grid value of a load-path or run quantity, checked (SceneError naming the key and the valid range)."""
    from .. import laws
    from ..sampling.population import N_MAX

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
        return check_choice(where, value, tuple(laws.LAWS), error=SceneError)
    if name in laws.option_names():  # checked by the first law that declares it
        try:
            return getattr(laws.get(laws.option_names()[name][0]).options(**{name: value}), name)
        except ValueError as err:
            raise SceneError(f"sweep grid: {err}") from None
    lo, hi = {"cycles": (1, 1000), "n": (1, N_MAX)}[name]
    return check_int(where, value, lo, hi, error=SceneError)


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
    if name in run_quantities():
        return "run"
    return "param"


@dataclass(frozen=True)
class Sweep:
    """A scene run at every point of a parameter grid, ``len(seeds)`` times each.

    grid : {name: tuple of values}, in the order of the output dimensions; a name is an
        InterfaceParams field [SI], a load-path quantity (:data:`PATH_QUANTITIES`: sigma_n [Pa],
        amplitude [m], direction [rad], cycles) or a run setting (:func:`run_quantities`: law, n, a law's option)
    seeds : one seed per replica (default: scene.seed + 0, 1, ..., replicas - 1)
    """

    scene: Scene
    grid: dict = dataclasses.field(default_factory=dict)
    seeds: tuple = ()
    output: Path | None = None
    title: str = ""
    source: str = "<sweep>"

    def __post_init__(self):
        units, run = InterfaceParams.units(), run_quantities()
        grid = {}
        for name, values in dict(self.grid).items():
            if name not in units and name not in PATH_QUANTITIES and name not in run:
                raise SceneError(f"sweep grid: unknown parameter {name!r} (valid: "
                                 f"{', '.join([*units, *PATH_QUANTITIES, *run])})")
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
    check_keys(grid_table, (*units, *PATH_QUANTITIES, *run_quantities()), f"{where}[sweep.grid] ")
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
    replicas = check_int(f"{where}replicas", replicas, 1, 100_000, error=SceneError)
    return tuple(base_seed + i for i in range(replicas))
