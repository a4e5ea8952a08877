"""Scene files: one run described in TOML, with quantities written with their units.

Owns the translation of a scene file into the objects :func:`asperity_sim.simulate`
takes (``InterfaceParams``, ``LoadPath``, run settings).  Read with the standard library
(``tomllib``).  Every value is checked before anything runs; a bad one raises
:class:`SceneError` (a ``ValueError``) naming the file, the key, the value and what is
allowed.  The layout (``scenarios/*.toml`` are complete examples)::

    title = "free text"                      # optional
    [parameters]                             # a Table 1 preset plus overrides (SPEC §1)
    preset = "R1"                            # R1, S1, R2, S2; without it give every field
    mu = 0.6                                 # dimensionless: a plain number
    R_m = "50 um"                            # length: nm, um (µm), mm, cm, m
    G = "80 GPa"                             # stress: Pa, kPa, MPa, GPa
    N = "200 /mm2"                           # areal density: 1/m2, 1/mm2, 1/um2 (also m-2, ...)
    [run]                                    # optional; defaults shown
    n = 100000                               # sampled asperities
    seed = 0
    sampler = "random"                       # random, sobol
    law = "paper"                            # a registered law: paper, mdr
    policy = "follow"                        # follow, birth
    k = 16                                   # the laws' options (mdr: k, spring_dtype); an option
                                             # applies to the laws that declare it
    [output]                                 # optional
    file = "run.nc"                          # inside the scene's folder (no absolute path, no '..');
                                             # default <scene>.nc in the current directory
    snapshots = "stage_ends"                 # or a list of step numbers
    [path]
    name = "constant_normal_shear"           # optional label
    [[path.stages]]                          # one table per stage (SPEC §6): each component k is
    name = "normal loading"                  # displacement controlled (Delta_k = length) or
    increments = 40                          # stress controlled (sigma_k = stress), never both
    sigma_1 = "500 MPa"
    Delta_2 = "0 um"
    Delta_3 = "0 um"
    # adaptive = false, max_fraction = 0.1   (optional, see asperity_sim.paths.Stage)

A plain TOML number is taken in SI units (m, Pa, 1/m²).  Strings with units are read by
:mod:`pint` (:func:`parse_quantity`): any unit of the right dimension works (``"0.5 mm"``,
``"1 psi"``), and exponents may be written ``mm-2``, ``mm2``, ``mm^2``, ``mm²`` or ``mm**2``.
"""

from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from .. import paths, presets
from ..checks import check_choice, check_int
from ..errors import SceneError
from ..params import InterfaceParams
from ..units import parse_quantity

# -- structure checks ----------------------------------------------------------

def check_keys(table: dict, allowed, where: str):
    """Raise for a key of ``table`` not in ``allowed``, suggesting the closest valid one."""
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, list(allowed), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise SceneError(f"{where}unknown key {key!r} (valid: {', '.join(allowed)}){hint}")


def _table(data: dict, key: str, where: str, required=False) -> dict:
    if key not in data:
        if required:
            raise SceneError(f"{where}missing [{key}] table")
        return {}
    value = data[key]
    if not isinstance(value, dict):
        raise SceneError(f"{where}{key} must be a table [{key}], got {value!r}")
    return value


def _string(value, name):
    if not isinstance(value, str):
        raise SceneError(f"{name} = {value!r} must be a string")
    return value


def read_toml(path) -> dict:
    """Parse a TOML file, with a one-line error naming the file."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise SceneError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise SceneError(f"{path}: is a folder, not a TOML file") from None
    except tomllib.TOMLDecodeError as err:
        raise SceneError(f"{path}: not valid TOML: {err}") from None
    except UnicodeDecodeError:
        raise SceneError(f"{path}: not a text (UTF-8 TOML) file") from None


# -- the scene -------------------------------------------------------------------

_TOP = ("title", "parameters", "run", "output", "path")
_RUN = {"n": 100_000, "seed": 0, "sampler": "random", "law": "paper", "policy": "follow"}
"""The run settings of every scene and their defaults; the laws' options (:func:`asperity_sim.laws.option_names`)
are the other keys of ``[run]``."""
_OUTPUT = ("file", "snapshots")
_PATH = ("name", "stages")
_COMPONENTS = ("Delta_1", "Delta_2", "Delta_3", "sigma_1", "sigma_2", "sigma_3")
_STAGE = ("name", "increments", "adaptive", "max_fraction") + _COMPONENTS


@dataclass(frozen=True)
class Scene:
    """One run: parameters, load path and run settings, as read from a scene file.

    ``simulate(**overrides)`` runs it; ``run_kwargs()`` gives the keyword arguments of
    :func:`asperity_sim.simulate` other than params and path.  ``law_options`` holds the laws'
    options the scene gives (name -> value, checked); each applies to the laws that declare it.
    """

    params: InterfaceParams
    path: paths.LoadPath
    n: int = _RUN["n"]
    seed: int = _RUN["seed"]
    sampler: str = _RUN["sampler"]
    law: str = _RUN["law"]
    policy: str = _RUN["policy"]
    law_options: dict = dataclasses.field(default_factory=dict)
    output: Path | None = None
    snapshots: object = None
    title: str = ""
    preset: str | None = None
    source: str = "<scene>"

    def replace(self, **changes) -> "Scene":
        """A copy with some fields changed (``n``, ``seed``, ``params``, ``path``, a law option such as ``k``, ...)."""
        from .. import laws

        options = {k: changes.pop(k) for k in list(changes) if k in laws.option_names()}
        if options:
            changes["law_options"] = {**changes.get("law_options", self.law_options), **options}
        return dataclasses.replace(self, **changes)

    def options(self):
        """The options of the scene's law (its own options from ``law_options``, defaults for the rest)."""
        from .. import laws

        return laws.options_of(self.law, self.law_options)

    def run_kwargs(self) -> dict:
        return {"n": self.n, "seed": self.seed, "sampler": self.sampler, "law": self.law, "policy": self.policy,
                "snapshots": self.snapshots, **self.law_options}

    def simulate(self, **overrides):
        """``asperity_sim.simulate(self.params, self.path, **run_kwargs)``, with keyword overrides."""
        from ..solve.driver import simulate

        return simulate(self.params, self.path, **{**self.run_kwargs(), **overrides})

    @property
    def name(self) -> str:
        return Path(self.source).stem if self.source != "<scene>" else "scene"

    def default_output(self) -> Path:
        """``[output] file`` or ``<scene name>.nc`` in the current directory."""
        return self.output if self.output is not None else Path(f"{self.name}.nc")


def load_scene(path) -> Scene:
    """Read and check a scene file; raises :class:`SceneError` with a one-line message."""
    return scene_from_dict(read_toml(path), source=str(path))


def scene_from_dict(data: dict, source: str = "<scene>", name: str | None = None,
                    folder: str | Path | None = None) -> Scene:
    """A checked :class:`Scene` from a parsed TOML document.

    source : where the document came from (starts every error message)
    name : label of the path when ``[path] name`` is not given (default: the file name of source)
    folder : the scene's folder, where ``[output] file`` is resolved and must stay (default: the
        folder of ``source`` when it is a file, else the current directory)
    """
    where = f"{source}: "
    if "sweep" in data:
        raise SceneError(f"{where}has a [sweep] table: it is a sweep file, run it with `asperity-sim sweep`")
    check_keys(data, _TOP, where)
    title = _string(data.get("title", ""), f"{where}title")
    params, preset = parameters_from_table(_table(data, "parameters", where, required=True), f"{where}[parameters] ")
    run = _run_settings(_table(data, "run", where), f"{where}[run] ")
    if folder is None:
        folder = Path(source).parent if source != "<scene>" and Path(source).is_file() else Path(".")
    output, snapshots = _output(_table(data, "output", where), f"{where}[output] ", Path(folder))
    if name is None:
        name = Path(source).stem if source != "<scene>" else "scene"
    path = path_from_table(_table(data, "path", where, required=True), f"{where}[path] ", default_name=name)
    return Scene(params=params, path=path, output=output, snapshots=snapshots, title=title, preset=preset,
                 source=source, **run)


def parameters_from_table(table: dict, where: str = "") -> tuple[InterfaceParams, str | None]:
    """InterfaceParams from ``preset`` plus overrides with units (SPEC §1 ranges apply)."""
    units = InterfaceParams.units()
    check_keys(table, ("preset",) + tuple(units), where)
    preset = table.get("preset")
    values = {}
    for name, value in table.items():
        if name != "preset":
            values[name] = parse_quantity(value, units[name], f"{where}{name}")
    try:
        if preset is None:
            required = [f.name for f in dataclasses.fields(InterfaceParams)
                        if f.default is dataclasses.MISSING and f.name not in values]
            if required:
                raise SceneError(f"{where}missing preset (valid: {', '.join(presets.TABLE1)}) "
                                 f"or the parameters {', '.join(required)}")
            return InterfaceParams(**values), None
        check_choice(f"{where}preset", preset, tuple(presets.TABLE1), error=SceneError)
        return presets.TABLE1[preset].replace(**values), preset
    except SceneError:
        raise
    except ValueError as err:
        raise SceneError(f"{where}{err}") from None


def _run_settings(table: dict, where: str) -> dict:
    from .. import laws
    from ..geometry import POLICIES
    from ..sampling.population import N_MAX, SAMPLERS

    option_names = laws.option_names()
    check_keys(table, (*_RUN, *option_names), where)
    out = {**_RUN, **{k: v for k, v in table.items() if k in _RUN}}
    out["n"] = check_int(f"{where}n", out["n"], 1, N_MAX, error=SceneError)
    out["seed"] = check_int(f"{where}seed", out["seed"], 0, error=SceneError)
    out["sampler"] = check_choice(f"{where}sampler", out["sampler"], SAMPLERS, error=SceneError)
    out["law"] = check_choice(f"{where}law", out["law"], tuple(laws.LAWS), error=SceneError)
    out["policy"] = check_choice(f"{where}policy", out["policy"], POLICIES, error=SceneError)
    given = {k: v for k, v in table.items() if k in option_names}
    try:
        own = laws.options_of(out["law"], given).as_dict()
    except ValueError as err:
        raise SceneError(f"{where}{err}") from None
    out["law_options"] = {k: own.get(k, v) for k, v in given.items()}
    return out


def _output(table: dict, where: str, folder: Path = Path(".")):
    check_keys(table, _OUTPUT, where)
    output = table.get("file")
    if output is not None:
        output = Path(_string(output, f"{where}file"))
        if output.suffix not in (".nc", ".nc4"):
            raise SceneError(f"{where}file = {str(output)!r} must end in .nc (a netCDF file)")
        output = contained_output(output, folder, f"{where}file")
    snapshots = table.get("snapshots")
    if snapshots is not None and snapshots != "stage_ends":
        if not isinstance(snapshots, list):
            raise SceneError(f"{where}snapshots = {snapshots!r} must be \"stage_ends\" or a list of step numbers")
        snapshots = tuple(check_int(f"{where}snapshots step", s, 0, error=SceneError) for s in snapshots)
    return output, snapshots


def contained_output(output: Path, folder: Path, name: str = "[output] file") -> Path:
    """``folder / output`` if it stays inside ``folder``; else :class:`SceneError` (issue 24, item 5).

    A scene file may name its output only inside its own folder: no absolute path, no ``..``
    and no symbolic link leading out of it.  Anywhere else is the user's choice on the command
    line (``-o``), not the file's.
    """
    text = str(output)
    if output.is_absolute() or output.anchor or any(part == ".." for part in output.parts) or not output.name:
        raise SceneError(f"{name} = {text!r} must be a path inside the scene's folder {str(folder)!r} (a relative "
                         "path without '..'); write elsewhere with -o")
    target = folder / output
    try:
        target.resolve().relative_to(folder.resolve())
    except ValueError:
        raise SceneError(f"{name} = {text!r} leads out of the scene's folder {str(folder)!r} (through a symbolic "
                         "link); write elsewhere with -o") from None
    return target


def path_from_table(table: dict, where: str = "", default_name: str = "scene") -> paths.LoadPath:
    """A LoadPath from ``name`` and a list of stage tables (``Delta_k`` [length] or ``sigma_k`` [stress])."""
    check_keys(table, _PATH, where)
    name = _string(table.get("name", default_name), f"{where}name")
    stages = table.get("stages")
    if stages is None:
        raise SceneError(f"{where}missing stages (add one [[path.stages]] table per stage)")
    if not isinstance(stages, list) or not stages or not all(isinstance(s, dict) for s in stages):
        raise SceneError(f"{where}stages must be one or more [[path.stages]] tables")
    return paths.LoadPath(tuple(_stage(s, f"{where}stage {i}: ") for i, s in enumerate(stages, 1)), name=name)


def _stage(table: dict, where: str) -> paths.Stage:
    check_keys(table, _STAGE, where)
    control, target = [], []
    for k in (1, 2, 3):
        d, s = f"Delta_{k}", f"sigma_{k}"
        if d in table and s in table:
            raise SceneError(f"{where}give {d} (displacement control) or {s} (stress control), not both")
        if d in table:
            control.append(paths.DISPLACEMENT)
            target.append(parse_quantity(table[d], "m", f"{where}{d}"))
        elif s in table:
            control.append(paths.STRESS)
            target.append(parse_quantity(table[s], "Pa", f"{where}{s}"))
            if k == 1 and target[-1] < 0.0:
                raise SceneError(f"{where}{s} = {table[s]!r} is a tension, which the interface cannot carry "
                                 "(valid range: sigma_1 >= 0, compression positive)")
        else:
            raise SceneError(f"{where}component {k} is missing: give {d} = \"<length>\" (displacement control) "
                             f"or {s} = \"<stress>\" (stress control)")
    if "increments" not in table:
        raise SceneError(f"{where}missing increments (integer >= 1)")
    increments = check_int(f"{where}increments", table["increments"], 1, 10**7, error=SceneError)
    try:
        return paths.Stage(tuple(control), tuple(target), increments,
                           adaptive=table.get("adaptive", False), max_fraction=table.get("max_fraction", 0.1),
                           name=_string(table.get("name", ""), f"{where}name"))
    except ValueError as err:
        raise SceneError(f"{where}{err}") from None


def scale_increments(path: paths.LoadPath, increments: int) -> paths.LoadPath:
    """The path with its largest stage at ``increments`` increments and the others in proportion (at least 1)."""
    largest = max(s.increments for s in path.stages)
    stages = tuple(dataclasses.replace(s, increments=max(1, int(s.increments * increments / largest)))
                   for s in path.stages)
    return paths.LoadPath(stages, name=path.name)
