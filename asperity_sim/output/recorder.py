"""Per-step recording into preallocated buffers, and the xarray Dataset built from them.

Owns the shape of the output: variables come only from :mod:`asperity_sim.output.variables`,
so each carries ``units`` and ``long_name``; a value with a standard error names it in
``ancillary_variables`` (CF), and ``stage_name`` labels each step with its stage's name.  Global attributes record every parameter,
the sampling, the law, the policy, the load path and the package version.
"""

from __future__ import annotations

import datetime as _dt
import functools
from typing import TYPE_CHECKING

import numpy as np

from .variables import (
    ASPERITY_VARIABLES,
    COORDS,
    INITIAL_STAGE_NAME,
    LABEL_VARIABLES,
    SNAPSHOT_VARIABLES,
    STEP_VARIABLES,
    standard_error_links,
)

if TYPE_CHECKING:
    import xarray as xr

LATE_IMPORTS = ("xarray",)
"""What building the Dataset imports (at its first build, not at this module's import: see :func:`_build`)."""

PAPER = ("Misra, A. and Huang, S.: Micromechanical stress-displacement model for rough interfaces: "
         "effect of asperity contact orientation on closure and shear behavior")


WALL_TIME_DESCRIPTION = (
    "wall-clock time [s] of the increment loop of simulate (solving, committing and recording the increments), "
    "summed over the parts of a resumed run; sampling the population and writing the file are not included")

_SIZES = {"axis": 3, "axis_k": 3, "from_state": 4, "to_state": 4}


class Recorder:
    """Growable per-step buffers; ``append`` one converged increment, or ``extend`` several."""

    def __init__(self, capacity: int, variables=STEP_VARIABLES):
        self.size = 0
        self._buf = {}
        self._vars = dict(variables)
        self._capacity = max(int(capacity), 1)
        for name, var in self._vars.items():
            shape = (self._capacity,) + tuple(_SIZES[d] for d in var.dims[1:])
            self._buf[name] = np.zeros(shape, dtype=var.dtype)
        self.snapshots = []

    def append(self, **values):
        self._reserve(1)
        if not values.keys() >= self._buf.keys():
            raise KeyError(f"record is missing {sorted(self._buf.keys() - values.keys())}")
        for name, v in values.items():
            self._buf[name][self.size] = v
        self.size += 1

    def extend(self, **columns):
        """Append m increments at once: each value holds m rows, or one value for all of them."""
        m = len(columns["stress"])
        self._reserve(m)
        if not columns.keys() >= self._buf.keys():
            raise KeyError(f"record is missing {sorted(self._buf.keys() - columns.keys())}")
        for name, v in columns.items():
            self._buf[name][self.size:self.size + m] = v
        self.size += m

    def _reserve(self, m):
        if self.size + m > self._capacity:
            self._capacity = max(2 * self._capacity, self.size + m)
            for name, a in self._buf.items():
                grown = np.zeros((self._capacity,) + a.shape[1:], dtype=a.dtype)
                grown[: self.size] = a[: self.size]
                self._buf[name] = grown

    def count(self, name, value) -> int:
        """Recorded steps whose ``name`` equals ``value`` (e.g. the increments of a stage)."""
        return int(np.count_nonzero(self._buf[name][: self.size] == value))

    def add_snapshot(self, step, arrays):
        self.snapshots.append((step, arrays))

    def to_dataset(self, attrs: dict, population=None, stage_names=None) -> xr.Dataset:
        """The Dataset of the recorded steps; ``stage_names`` (the names of the path's stages, in
        order) adds ``stage_name``, each step's stage name."""
        n = self.size
        data = {name: self._buf[name][:n].copy() for name in self._vars}
        names = None if stage_names is None else stage_name_values(data["stage"], stage_names)
        if self.snapshots and population is not None:
            ds = _build(self._vars, data, _snapshot_vars(self.snapshots, population))
            if names is not None:
                _add_stage_name(ds, names)
        else:  # the common case: a copy of the cached empty Dataset of this shape, with the data swapped in
            if names is not None:
                data["stage_name"] = names
            ds = _template(tuple(self._vars.items()), n, names is not None).copy(deep=False, data=data)
        ds.attrs = attrs
        return ds


def stage_name_values(stage, stage_names) -> np.ndarray:
    """``stage_name`` (step): the name of each step's stage (``stage`` 0: the initial state)."""
    names = np.array([INITIAL_STAGE_NAME, *(str(s) for s in stage_names)], dtype=object)
    if stage.size and (stage.min() < 0 or stage.max() >= names.size):
        raise ValueError(f"stage index {int(stage.max())} is out of range (valid range: 0 to {names.size - 1})")
    return names[stage].astype(str)


def link_standard_errors(ds) -> xr.Dataset:
    """Set the CF attribute ``ancillary_variables`` of each value that has a standard error in ``ds``
    (``x`` -> ``x_stderr``, ``x_mean`` -> ``x_sem``); returns ``ds``."""
    for value, stderr in standard_error_links(ds.data_vars).items():
        ds[value].attrs["ancillary_variables"] = stderr
    return ds


def _build(variables, data, extra=None) -> xr.Dataset:
    """The Dataset of the step variables (data: name -> array) and of ``extra`` (name -> (dims, array, attrs))."""
    import xarray as xr  # here, not at the top: a first run would pay its import (0.4 s) before it starts compiling,
    # while now it imports it as it waits on a compile-ahead helper (LATE_IMPORTS, kernels.ahead.expect)

    data_vars = {name: (var.dims, data[name], _attrs(var)) for name, var in variables.items()}
    data_vars.update(extra or {})
    n = len(next(iter(data.values())))
    coords = {
        "step": ("step", np.arange(n), {"long_name": "converged increment", "units": "1"}),
        "axis": ("axis", np.array([1, 2, 3], dtype="i4"), _attrs(COORDS["axis"])),
        "axis_k": ("axis_k", np.array([1, 2, 3], dtype="i4"), _attrs(COORDS["axis_k"])),
    }
    if "transitions" in variables:
        for dim in ("from_state", "to_state"):
            coords[dim] = (dim, np.arange(4, dtype="i4"), _attrs(COORDS[dim]))
    ds = link_standard_errors(xr.Dataset(data_vars, coords=coords))
    ds["control"].attrs.update(flag_values=np.array([0, 1], dtype="i1"), flag_meanings="displacement stress")
    return ds


@functools.lru_cache(maxsize=32)
def _template(variables: tuple, n: int, labelled: bool) -> xr.Dataset:
    """A Dataset of ``n`` steps to copy with new data (``labelled``: with ``stage_name``): the constructor's checks
    and index building cost about 1 ms, several times a small run's own work.  Never handed out itself; a
    shallow copy has its own attribute dicts (global and per variable), so what a caller changes stays in its
    copy."""
    variables = dict(variables)
    ds = _build(variables, {name: np.zeros((n,) + tuple(_SIZES[d] for d in var.dims[1:]), dtype=var.dtype)
                            for name, var in variables.items()})
    if labelled:
        _add_stage_name(ds, np.zeros(n, dtype="U1"))
    return ds


def _add_stage_name(ds, names) -> None:
    """``stage_name`` as the last variable of ``ds`` (after the coordinates, where files have always had it)."""
    var = LABEL_VARIABLES["stage_name"]
    ds["stage_name"] = (var.dims, names, _attrs(var))


def _attrs(var):
    return {"units": var.units, "long_name": var.long_name}


def _snapshot_vars(snapshots, pop):
    steps = np.array([s for s, _ in snapshots], dtype="i8")
    stacked = {k: np.stack([a[k] for _, a in snapshots]) for k in snapshots[0][1]}
    static = {"r": pop.r, "R": pop.R, "u": pop.u, "phi": pop.phi}
    out = {name: (var.dims, static[name], _attrs(var)) for name, var in ASPERITY_VARIABLES.items()}
    per_step = {"snapshot_step": steps, "asperity_delta_n": stacked["delta_n"],
                "asperity_theta": stacked["theta"], "asperity_force": stacked["force"],
                "asperity_state": stacked["state"]}
    for name, var in SNAPSHOT_VARIABLES.items():
        out[name] = (var.dims, per_step[name], _attrs(var))
    out["asperity_state"][2].update(flag_values=np.array([0, 1, 2, 3], dtype="i1"),
                                    flag_meanings="out_of_contact stick partial_slip full_slip")
    return out


def run_attributes(params, *, n, seed, sampler, law, policy, path, version, call) -> dict:
    """Global attributes of a run (CF conventions; every parameter with its unit)."""
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    attrs = {
        "Conventions": "CF-1.8",
        "title": f"asperity_sim run: {path.name} path, law {law}, policy {policy}",
        "source": f"asperity_sim {version}",
        "history": f"{now} {call}",
        "date_created": now,
        "references": PAPER,
        "law": law,
        "policy": policy,
        "sampler": sampler,
        "n_asperities": int(n),
        "seed": int(seed) if seed is not None else -1,
        "seed_note": ("-1 means unseeded (not reproducible)" if seed is None
                      else "seed of numpy PCG64 (random) or of the Sobol' scramble (asperity_sim.sampling.sobol)"),
        "load_path": path.describe(),
        "asperity_sim_version": version,
    }
    units = params.units()
    for name, value in params.as_dict().items():
        attrs[f"param_{name}"] = float(value)
        attrs[f"param_{name}_units"] = units[name]
    return attrs
