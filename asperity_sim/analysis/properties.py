"""Joint properties derived from a run's per-step dataset (strength, dilation, stiffness, damping).

Owns the reduction of per-step outputs (``displacement``, ``stress``, ``stress_stderr``,
``tangent``, and ``dissipation`` for history laws; :mod:`asperity_sim.output.variables`) to the
numbers a joint-element user needs.  Every property is one small pure function of the
arrays of one run; :func:`shear_properties` and :func:`cycle_properties` apply them to
every run of a run or sweep dataset, and :func:`replica_statistics` adds the ensemble
mean and its standard error over the replicas.  Units and long names come from
:data:`asperity_sim.output.variables.PROPERTY_VARIABLES`.

Definitions (docs/joint_properties.md gives the same with figures)
------------------------------------------------------------------
Shear segment: the steps of the shear stages (default: every stage after the first),
preceded by the last step before them, the *start of shear*.  Shear direction ``e``: the
unit vector of the largest shear displacement (Delta_2, Delta_3) of the segment measured
from the start of shear, signed so that shear begins in +e; ``tau = sigma_23 . e`` is the
shear stress and ``s = (Delta_23 - Delta_23(start)) . e`` the shear displacement.  For a
path sheared along axis 2, tau = sigma_2 and s = Delta_2.

- peak shear stress: max tau over the segment; peak friction coefficient tau/sigma_1 there;
- residual shear stress: tau at the *last step* of the segment (not a mean over its end);
  residual friction coefficient tau/sigma_1 there;
- dilation angle at peak: atan(-dDelta_1/ds) at the peak step (closure positive, so a
  positive angle is dilation), dDelta_1/ds by second-order finite differences of the
  recorded steps (``numpy.gradient``);
- normal stiffness dsigma_1/dDelta_1 = T_11 and shear stiffness e.T_ss.e (= T_22 along
  axis 2) at the start of shear, from the recorded ``tangent``;
- per cycle (stages ``0 -> +a -> -a -> 0`` of :func:`asperity_sim.runs.envelope.cyclic_path`):
  secant stiffness k_sec = (tau(+a) - tau(-a)) / (s(+a) - s(-a)) (= (tau(+a) - tau(-a)) / 2a),
  loop energy W_d = closed integral of tau ds (trapezoid over the recorded steps), the
  increase of ``dissipation`` over the cycle (history laws), equivalent damping ratio
  xi = W_d / (4 pi W_s) with W_s = k_sec a^2 / 2, and k_sec / k_0 with k_0 the shear
  stiffness at the start of shear (the G/Gmax of geotechnical practice).

Standard errors: over replicas (``<name>_sem``, sample s.d. / sqrt(m), m >= 2).  Of one
run, the Monte Carlo standard error ``<name>_stderr`` exists only for the shear stresses
at the peak and at the end (from ``stress_stderr`` of that step, exact when e is an axis,
else combining the two shear components as independent) and for the friction
coefficients when sigma_1 is stress controlled (then exact: sigma_1 has no error).  Every
other property (derivatives, tangents, loop integrals) combines correlated stresses of
the same samples, so its error comes from replicas only.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from ..output.variables import PROPERTY_VARIABLES

SHEAR_PROPERTIES = ("peak_shear_stress", "peak_shear_displacement", "peak_normal_stress", "peak_friction",
                    "residual_shear_stress", "residual_friction", "dilation_angle_peak", "normal_stress_start",
                    "normal_stiffness", "shear_stiffness")
CYCLE_PROPERTIES = ("cycle_amplitude", "secant_shear_stiffness", "secant_stiffness_ratio", "loop_dissipation",
                    "cycle_dissipation", "damping_ratio")
WITH_STDERR = ("peak_shear_stress", "peak_friction", "residual_shear_stress", "residual_friction")
"""Properties with a Monte Carlo standard error of one run (``<name>_stderr``)."""

_DIMS = ("step", "axis", "axis_k")


# -- pure functions of one run ---------------------------------------------------------

def shear_direction(shear: np.ndarray) -> np.ndarray:
    """Unit vector e (2,) of the largest shear displacement in ``shear`` (m, 2), measured from row 0.

    Signed so that the first row that moves has a positive projection on e.
    """
    rel = np.asarray(shear, float) - shear[0]
    norm = np.hypot(rel[:, 0], rel[:, 1])
    if not np.any(norm > 0.0):
        raise ValueError("the shear segment has no shear displacement (Delta_2 = Delta_3 = const)")
    e = rel[int(np.argmax(norm))] / norm.max()
    first = rel[int(np.flatnonzero(norm > 0.0)[0])]
    return e if first @ e > 0.0 else -e


def peak(tau: np.ndarray) -> int:
    """Index of the largest shear stress of the segment (the first one on a tie)."""
    tau = np.asarray(tau, float)
    if tau.size == 0 or not np.all(np.isfinite(tau)):
        raise ValueError("the shear stress of the segment must be finite and non-empty")
    return int(np.argmax(tau))


def residual(tau: np.ndarray) -> int:
    """Index of the residual shear stress: the last step of the segment."""
    if np.asarray(tau).size == 0:
        raise ValueError("empty shear segment")
    return int(np.asarray(tau).size - 1)


def dilation_angle(s: np.ndarray, delta_1: np.ndarray, i: int) -> float:
    """atan(-dDelta_1/ds) [rad] at row ``i``; s [m] must increase strictly around ``i``.

    Second-order finite differences over 3 recorded points (one-sided at the ends); positive = dilation (opening).
    """
    s, d1 = np.asarray(s, float), np.asarray(delta_1, float)
    lo = max(0, min(i - 1, s.size - 3))
    hi = min(s.size, lo + 3)
    if hi - lo < 2 or np.any(np.diff(s[lo:hi]) <= 0.0):
        return math.nan
    slope = np.gradient(d1[lo:hi], s[lo:hi], edge_order=2 if hi - lo == 3 else 1)[i - lo]
    return float(math.atan(-slope))


def start_stiffness(tangent: np.ndarray, e: np.ndarray) -> tuple[float, float]:
    """(dsigma_1/dDelta_1, e.T_ss.e) [Pa m-1] from one tangent matrix (3, 3)."""
    t = np.asarray(tangent, float)
    return float(t[0, 0]), float(e @ t[1:, 1:] @ e)


def secant_stiffness(s: np.ndarray, tau: np.ndarray) -> tuple[float, float]:
    """(k_sec [Pa m-1], amplitude a [m]) of one cycle: (tau(s_max) - tau(s_min)) / (s_max - s_min), a = half the span."""
    s, tau = np.asarray(s, float), np.asarray(tau, float)
    i, j = int(np.argmax(s)), int(np.argmin(s))
    span = s[i] - s[j]
    if not span > 0.0:
        raise ValueError("the cycle has no shear displacement span")
    return float((tau[i] - tau[j]) / span), float(span / 2.0)


def loop_energy(s: np.ndarray, tau: np.ndarray) -> float:
    """Closed integral of tau ds [J m-2] over the recorded points (trapezoid rule), positive for a dissipative loop."""
    s, tau = np.asarray(s, float), np.asarray(tau, float)
    return float(np.sum(0.5 * (tau[1:] + tau[:-1]) * np.diff(s)))


def damping_ratio(w_d: float, k_sec: float, amplitude: float) -> float:
    """Equivalent viscous damping ratio W_d / (4 pi W_s), W_s = k_sec a^2 / 2 [1]."""
    w_s = 0.5 * k_sec * amplitude**2
    return float(w_d / (4.0 * math.pi * w_s)) if w_s > 0.0 else math.nan


# -- one run: all properties -----------------------------------------------------------

def _segment(stage, shear_stages, length):
    stage = np.asarray(stage)[:length]
    rows = np.flatnonzero(np.isin(stage, shear_stages))
    if rows.size == 0:
        raise ValueError(f"no recorded step in the shear stage(s) {list(shear_stages)} "
                         f"(stages recorded: {sorted(set(stage.tolist()))})")
    if rows[0] == 0 or np.any(np.diff(rows) != 1):
        raise ValueError(f"the shear stages {list(shear_stages)} must follow at least one stage and be consecutive")
    return np.concatenate([[rows[0] - 1], rows])


def _recorded(run):
    """Rows of a run before the NaN padding of a sweep (runs of different lengths)."""
    ok = np.isfinite(run["displacement"]).all(axis=1)
    return int(np.flatnonzero(ok)[-1]) + 1 if ok.any() else 0


def _tau_se(stderr_rows, e):
    return np.sqrt((stderr_rows[:, 1] * e[0]) ** 2 + (stderr_rows[:, 2] * e[1]) ** 2)


def shear_run(run: dict, shear_stages=None) -> tuple[dict, dict]:
    """({property: value}, {property: one-run standard error}) of :data:`SHEAR_PROPERTIES` of one run.

    run : {"displacement" (m,3), "stress" (m,3), "stress_stderr" (m,3), "tangent" (m,3,3),
        "stage" (m,), "control" (m,3) 0/1}, as from :func:`run_arrays`
    shear_stages : stage numbers of the shear segment (default: every stage after the first)
    """
    stage = np.asarray(run["stage"])
    if shear_stages is None:
        shear_stages = tuple(range(2, int(stage.max()) + 1))
    rows = _segment(stage, tuple(shear_stages), _recorded(run))
    d, sig = run["displacement"][rows], run["stress"][rows]
    e = shear_direction(d[:, 1:])
    tau, s = sig[:, 1:] @ e, (d[:, 1:] - d[0, 1:]) @ e
    se = _tau_se(run["stress_stderr"][rows], e)
    i_p, i_r = peak(tau), residual(tau)
    sigma_1_controlled = np.asarray(run["control"])[rows, 0] == 1
    out = {
        "peak_shear_stress": tau[i_p], "peak_shear_displacement": s[i_p], "peak_normal_stress": sig[i_p, 0],
        "peak_friction": tau[i_p] / sig[i_p, 0], "residual_shear_stress": tau[i_r],
        "residual_friction": tau[i_r] / sig[i_r, 0], "dilation_angle_peak": dilation_angle(s, d[:, 0], i_p),
        "normal_stress_start": sig[0, 0],
    }
    out["normal_stiffness"], out["shear_stiffness"] = start_stiffness(run["tangent"][rows[0]], e)
    err = {"peak_shear_stress": se[i_p], "residual_shear_stress": se[i_r],
           "peak_friction": se[i_p] / sig[i_p, 0] if sigma_1_controlled[i_p] else math.nan,
           "residual_friction": se[i_r] / sig[i_r, 0] if sigma_1_controlled[i_r] else math.nan}
    return {k: float(v) for k, v in out.items()}, {k: float(v) for k, v in err.items()}


def cycle_run(run: dict, cycle: int = -1, first_stage: int = 2, stages_per_cycle: int = 3) -> dict:
    """Cycle properties (:data:`CYCLE_PROPERTIES`) of cycle ``cycle`` (default: the last) of one run.

    Cycle c (0-based) is stages ``first_stage + c * stages_per_cycle`` ... ``+ stages_per_cycle - 1``
    (``0 -> +a -> -a -> 0`` with :func:`asperity_sim.runs.envelope.cyclic_path`), preceded by the step before them.
    """
    stage = np.asarray(run["stage"])
    length = _recorded(run)
    last = int(stage[:length].max()) if length else 0
    n_cycles = (last - first_stage + 1) // stages_per_cycle
    if n_cycles < 1:
        raise ValueError(f"no complete cycle recorded (stages {first_stage}.. in groups of {stages_per_cycle}; "
                         f"last stage recorded: {last})")
    c = cycle if cycle >= 0 else n_cycles + cycle
    if not 0 <= c < n_cycles:
        raise ValueError(f"cycle = {cycle} is out of range (valid range: integer in [{-n_cycles}, {n_cycles - 1}])")
    first = first_stage + c * stages_per_cycle
    rows = _segment(stage, tuple(range(first, first + stages_per_cycle)), length)
    whole = _segment(stage, tuple(range(first_stage, last + 1)), length)
    d, sig = run["displacement"], run["stress"]
    e = shear_direction(d[whole, 1:])
    tau, s = sig[rows, 1:] @ e, d[rows, 1:] @ e
    k_sec, a = secant_stiffness(s, tau)
    w_d = loop_energy(s, tau)
    k_0 = float(e @ run["tangent"][whole[0], 1:, 1:] @ e)
    diss = run.get("dissipation")
    out = {"cycle_amplitude": a, "secant_shear_stiffness": k_sec,
           "secant_stiffness_ratio": k_sec / k_0 if k_0 > 0.0 else math.nan, "loop_dissipation": w_d,
           "cycle_dissipation": float(diss[rows[-1]] - diss[rows[0]]) if diss is not None else math.nan,
           "damping_ratio": damping_ratio(w_d, k_sec, a)}
    return {k: float(v) for k, v in out.items()}


# -- every run of a dataset ----------------------------------------------------------------

def _lead_dims(ds):
    return tuple(d for d in ds["stress"].dims if d not in _DIMS)


def run_arrays(ds: xr.Dataset, index: dict) -> dict:
    """The per-step arrays of one run of a run or sweep dataset (``index``: {dim: position} of its lead dims)."""
    out = {}
    for name in ("displacement", "stress", "stress_stderr", "tangent", "dissipation"):
        if name in ds:
            out[name] = ds[name].isel(index).values.astype(float) if index else ds[name].values.astype(float)
    if "tangent" not in out:
        raise ValueError("the dataset has no tangent variable (needed for the start-of-shear stiffnesses)")
    out["stage"] = ds["stage"].values
    control = ds["control"]
    out["control"] = (control.isel({k: v for k, v in index.items() if k in control.dims}) if index else control).values
    return out


def _status_ok(ds, index):
    if "status" not in ds:
        status = str(ds.attrs.get("status", "complete"))
    else:
        status = str(ds["status"].isel({k: v for k, v in index.items() if k in ds["status"].dims}).values)
    return status == "complete", status


def _apply(ds, names, fn, with_stderr=()):
    if "stress" not in ds:
        status = sorted(set(np.atleast_1d(ds["status"].values).ravel())) if "status" in ds else ["unknown"]
        raise ValueError(f"no run recorded any step (status: {'; '.join(map(str, status))})")
    lead = _lead_dims(ds)
    shape = tuple(ds.sizes[d] for d in lead)
    values = {k: np.full(shape, np.nan) for k in names}
    errors = {k: np.full(shape, np.nan) for k in with_stderr}
    notes = np.full(shape, "", dtype=object)
    for idx in np.ndindex(*shape):
        index = dict(zip(lead, idx))
        ok, status = _status_ok(ds, index)
        if not ok:
            notes[idx] = status
            continue
        try:
            result = fn(run_arrays(ds, index))
        except ValueError as err:
            notes[idx] = f"property error: {err}"
            continue
        vals, errs = result if isinstance(result, tuple) else (result, {})
        for k in names:
            values[k][idx] = vals[k]
        for k in with_stderr:
            errors[k][idx] = errs.get(k, np.nan)
    coords = {d: ds[d] for d in lead if d in ds.coords}
    for c in ("seed",):
        if c in ds.coords and set(ds[c].dims) <= set(lead):
            coords[c] = ds[c]
    out = xr.Dataset(coords=coords)
    for k in names:
        out[k] = (lead, values[k], _attrs(k))
    for k in with_stderr:
        out[f"{k}_stderr"] = (lead, errors[k], _attrs(k, "Monte Carlo standard error of one run of the "))
    out["property_note"] = (lead, notes.astype(str), {"long_name": "why a property is NaN (run status or "
                                                                    "property error); empty when computed"})
    return out


def _attrs(name, prefix=""):
    var = PROPERTY_VARIABLES[name]
    return {"units": var.units, "long_name": prefix + var.long_name}


def shear_properties(ds: xr.Dataset, shear_stages=None) -> xr.Dataset:
    """:data:`SHEAR_PROPERTIES` (and ``<name>_stderr`` for :data:`WITH_STDERR`) of every run of ``ds``.

    ``ds`` is a run dataset (:func:`asperity_sim.simulate`) or a sweep dataset
    (:func:`asperity_sim.runs.engine.run_sweep`); the result has its grid and replica dimensions.
    A run that did not complete gets NaN and its status in ``property_note``.
    """
    return _apply(ds, SHEAR_PROPERTIES, lambda run: shear_run(run, shear_stages), WITH_STDERR)


def cycle_properties(ds: xr.Dataset, cycle: int = -1, first_stage: int = 2, stages_per_cycle: int = 3) -> xr.Dataset:
    """:data:`CYCLE_PROPERTIES` of cycle ``cycle`` of every run of ``ds`` (see :func:`cycle_run`)."""
    return _apply(ds, CYCLE_PROPERTIES, lambda run: cycle_run(run, cycle, first_stage, stages_per_cycle))


BY_CYCLE = ("secant_shear_stiffness", "loop_dissipation", "cycle_dissipation", "damping_ratio")
"""Cycle properties also given for every cycle (``<name>_by_cycle``, dimension ``cycle``)."""


def every_cycle(ds: xr.Dataset, first_stage: int = 2, stages_per_cycle: int = 3) -> xr.Dataset:
    """``<name>_by_cycle`` for :data:`BY_CYCLE`: the cycle properties of cycles 1, 2, ... of every run.

    A run with fewer cycles than the longest (a sweep over ``cycles``) is NaN for the missing ones.
    """
    n = (int(np.nanmax(ds["stage"].values)) - first_stage + 1) // stages_per_cycle
    if n < 1:
        raise ValueError(f"no complete cycle recorded (stages {first_stage}.. in groups of {stages_per_cycle})")
    parts = [cycle_properties(ds, cycle=c, first_stage=first_stage, stages_per_cycle=stages_per_cycle)[list(BY_CYCLE)]
             for c in range(n)]
    out = xr.concat(parts, dim="cycle").assign_coords(
        cycle=("cycle", np.arange(1, n + 1), {"units": "1", "long_name": "cycle number"}))
    lead = _lead_dims(ds)
    return xr.Dataset({f"{k}_by_cycle": out[k].transpose(*lead, "cycle").assign_attrs(_attrs(f"{k}_by_cycle"))
                       for k in BY_CYCLE})


def replica_statistics(props: xr.Dataset) -> xr.Dataset:
    """Add ``<name>_mean`` and ``<name>_sem`` over ``replica`` for every property of ``props``.

    sem: sample standard deviation of the m replicas with a value / sqrt(m) when m >= 2;
    with one replica, the Monte Carlo standard error of that run where one exists
    (``<name>_stderr``), else NaN.  ``<name>_count`` is m.
    """
    out = props.copy()
    names = [k for k in props.data_vars if k in PROPERTY_VARIABLES]
    has_replica = "replica" in props.dims
    for k in names:
        da = props[k]
        if has_replica:
            count = da.notnull().sum("replica")
            mean = da.mean("replica", skipna=True)
            sem = (da.std("replica", ddof=1, skipna=True) / np.sqrt(count)).where(count >= 2)
            if f"{k}_stderr" in props:
                one = props[f"{k}_stderr"].where(da.notnull()).max("replica", skipna=True)
                sem = sem.where(count >= 2, one.where(count == 1))
        else:
            count = da.notnull().astype(int)
            mean = da
            sem = props[f"{k}_stderr"] if f"{k}_stderr" in props else xr.full_like(da, np.nan)
        units = PROPERTY_VARIABLES[k].units
        long_name = PROPERTY_VARIABLES[k].long_name
        out[f"{k}_mean"] = mean.assign_attrs(units=units, long_name=f"ensemble mean over replicas of the {long_name}")
        out[f"{k}_sem"] = sem.assign_attrs(units=units, long_name=f"standard error of the {long_name} (over "
                                           "replicas when 2 or more, else Monte Carlo standard error of the one run, "
                                           "else NaN)")
        out[f"{k}_count"] = count.assign_attrs(units="1", long_name=f"replicas with a value of the {long_name}")
    return out
