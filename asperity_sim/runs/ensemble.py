"""The dataset of a sweep: runs on a grid of points and replicas, and their ensemble statistics.

Owns how the results of a sweep's runs become one ``xarray.Dataset`` (dims: the grid, replica,
step), with the replica mean and standard error of each output and the sweep's attributes.
"""

from __future__ import annotations

import datetime as _dt
import math

import numpy as np
import xarray as xr

from .. import paths
from ..params import InterfaceParams
from ..units import format_quantity
from ..version import __version__
from .sweep import PATH_QUANTITIES, Sweep, run_quantities

ALIGNED = ("displacement", "stress", "stress_stderr", "displacement_stderr", "tangent", "n_contact", "n_slip",
           "n_partial", "theta_am", "mean_theta", "external_work", "elastic_energy", "dissipation")
"""Per-step outputs carried into a sweep (those a run holds)."""

STATISTICS = ("displacement", "stress", "tangent", "n_contact", "n_slip", "n_partial", "theta_am", "mean_theta",
              "external_work", "elastic_energy", "dissipation")
"""Outputs that get an ensemble mean and standard error over the replicas."""


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


# -- the gathered dataset ------------------------------------------------------------

def sweep_dataset(sweep: Sweep, results: list, engine: str = "", wall_time: float = float("nan")) -> xr.Dataset:
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
    run = run_quantities()
    if name in PATH_QUANTITIES or name in run:
        unit, long_name = {**PATH_QUANTITIES, **run}[name]
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
        "history": f"{now} asperity_sim.runs.engine.run_sweep({sweep.source}) on {engine}",
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
