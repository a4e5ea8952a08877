"""Strength envelopes and cyclic stiffness/damping curves of a joint, from sweeps over the load path.

Owns the joint-element products of issue 26: :func:`envelope` runs a scene at several
normal stresses (a sweep over ``sigma_n``, :mod:`asperity_sim.runs.sweep`) and gathers the shear
properties of :mod:`asperity_sim.analysis.properties` against sigma_n, with a Mohr-Coulomb envelope
``tau = c + sigma_n tan(phi)`` and a power-law envelope ``tau = A (sigma_n / sigma_ref)^B``
(sigma_ref = 1 MPa, so A is the shear strength at 1 MPa) fitted to the peak and residual
shear stresses, each with confidence intervals; :func:`cyclic` runs symmetric shear cycles
``0 -> +a -> -a -> 0`` at several amplitudes and gathers the secant stiffness (and its
ratio to the initial shear stiffness, G/Gmax), loop energy and damping ratio.
:func:`write_products` writes the dataset (netCDF), a CSV table and a figure with error bars.

Fits: weighted least squares with weights 1/se^2 (se: the standard error of each point's
mean, :func:`asperity_sim.analysis.properties.replica_statistics`; unweighted when a point has none),
parameter covariance scaled by the reduced chi-square (the scatter about the fit counts,
as ``scipy.optimize.curve_fit(absolute_sigma=False)``), two-sided Student-t intervals with
m - 2 degrees of freedom.  The friction angle's interval is atan of the slope's interval;
the power law is fitted as log tau = log A + B log(sigma_n / sigma_ref) with se(log tau) =
se / tau, and A's interval is exp of the interval of log A.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import xarray as xr

from .. import paths
from ..analysis import properties as P
from ..checks import check_choice
from ..errors import SceneError
from ..output.atomic import write_atomically
from ..output.variables import PROPERTY_VARIABLES
from ..units import parse_quantity
from .engine import run_sweep
from .scene import Scene
from .sweep import Sweep

SIGMA_REF = 1e6
"""Reference normal stress of the power-law envelope [Pa]."""
MAX_POINTS = 200

_RANGE = re.compile(r"^([^:]+):([^:]+):([^:]+):([^:]+)$")


def parse_range(text: str, si_unit: str, key: str) -> np.ndarray:
    """``"start:stop:count:log|lin"`` (quantities with units, :func:`asperity_sim.units.parse_quantity`) as an array.

    A single quantity (``"100 MPa"``) is one point.  Raises :class:`SceneError` naming ``key``
    and the allowed range: 0 < start < stop, count an integer in [2, 200], spacing log or lin.
    """
    if not isinstance(text, str):
        raise SceneError(f"{key} = {text!r} must be a string \"start:stop:count:log|lin\" or one quantity")
    m = _RANGE.match(text.strip())
    if not m:
        if ":" in text:
            raise SceneError(f"{key} = {text!r} is not a range (write \"start:stop:count:log\" or "
                             f"\"start:stop:count:lin\", e.g. \"1 MPa:1 GPa:12:log\")")
        v = parse_quantity(text, si_unit, key)
        if not v > 0.0:
            raise SceneError(f"{key} = {text!r} is out of range (valid range: > 0)")
        return np.array([v])
    start, stop, count, spacing = (g.strip() for g in m.groups())
    lo = parse_quantity(start, si_unit, f"{key} start")
    hi = parse_quantity(stop, si_unit, f"{key} stop")
    try:
        n = int(count)
    except ValueError:
        n = -1
    if str(n) != count or not 2 <= n <= MAX_POINTS:
        raise SceneError(f"{key} count = {count!r} is out of range (valid range: integer in [2, {MAX_POINTS}])")
    check_choice(f"{key} spacing", spacing, ("log", "lin"), error=SceneError)
    if not 0.0 < lo < hi:
        raise SceneError(f"{key} = {text!r}: start and stop are out of range (valid range: 0 < start < stop)")
    values = np.geomspace(lo, hi, n) if spacing == "log" else np.linspace(lo, hi, n)
    values[0], values[-1] = lo, hi  # the ends exactly as written
    return values


def cyclic_path(normal: paths.Stage, amplitude: float, cycles: int = 2, increments: int = 8) -> paths.LoadPath:
    """The stage ``normal`` (its end state held), then ``cycles`` cycles Delta_2: 0 -> +a -> -a -> 0.

    Each quarter cycle takes ``increments`` increments (the half cycle +a -> -a twice as many);
    the normal component keeps the control and target of ``normal``, Delta_3 = 0.
    """
    a = float(amplitude)
    if not (math.isfinite(a) and a > 0.0):
        raise ValueError(f"amplitude = {amplitude!r} is out of range (valid range: > 0 m)")
    if isinstance(cycles, bool) or not isinstance(cycles, int) or not 1 <= cycles <= 1000:
        raise ValueError(f"cycles = {cycles!r} is out of range (valid range: integer in [1, 1000])")
    c1, t1 = normal.control[0], normal.target[0]
    D = paths.DISPLACEMENT
    first = dataclasses.replace(normal, control=(c1, D, D), target=(t1, 0.0, 0.0), name=normal.name or "normal")
    stages = [first]
    for c in range(1, cycles + 1):
        stages += [paths.Stage((c1, D, D), (t1, a, 0.0), increments, name=f"cycle {c}: 0 -> +a"),
                   paths.Stage((c1, D, D), (t1, -a, 0.0), 2 * increments, name=f"cycle {c}: +a -> -a"),
                   paths.Stage((c1, D, D), (t1, 0.0, 0.0), increments, name=f"cycle {c}: -a -> 0")]
    return paths.LoadPath(tuple(stages), name="cyclic_shear")


# -- fits ---------------------------------------------------------------------------

def weighted_line(x, y, se=None, level: float = 0.95) -> dict:
    """Weighted least-squares line y = a + b x; returns estimates, covariance and ``level`` intervals.

    se : standard errors of y (weights 1/se^2); None, or any non-finite or non-positive, gives
    an unweighted fit.  Points with non-finite x or y are dropped.  Intervals need >= 3 points.
    """
    from scipy import stats

    if not 0.0 < level < 1.0:
        raise ValueError(f"level = {level!r} is out of range (valid range: 0 < level < 1)")
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    weighted = se is not None and np.all(np.isfinite(np.asarray(se, float)[ok])) and \
        np.all(np.asarray(se, float)[ok] > 0.0)
    w = 1.0 / np.asarray(se, float)[ok] ** 2 if weighted else np.ones_like(x)
    m = x.size
    if m < 2 or np.ptp(x) == 0.0:
        raise ValueError(f"a line needs 2 or more points with distinct abscissae (got {m})")
    X = np.column_stack([np.ones(m), x])
    XtW = X.T * w
    cov0 = np.linalg.inv(XtW @ X)
    coef = cov0 @ (XtW @ y)
    dof = m - 2
    resid = y - X @ coef
    chi2 = float(np.sum(w * resid**2))
    if dof > 0:
        cov = cov0 * (chi2 / dof)
        t = float(stats.t.ppf(0.5 + level / 2.0, dof))
    else:
        cov, t = np.full((2, 2), np.nan), math.nan
    half = t * np.sqrt(np.diag(cov))
    return {"a": coef[0], "b": coef[1], "cov": cov, "a_ci": (coef[0] - half[0], coef[0] + half[0]),
            "b_ci": (coef[1] - half[1], coef[1] + half[1]), "points": m, "dof": dof,
            "reduced_chi2": chi2 / dof if dof > 0 else math.nan, "weighted": bool(weighted), "t": t}


def fit_mohr_coulomb(sigma_n, tau, se=None, level: float = 0.95) -> dict:
    """tau = c + sigma_n tan(phi): cohesion c [Pa] and friction angle phi [rad] with ``level`` intervals."""
    f = weighted_line(sigma_n, tau, se, level)
    return {"cohesion": f["a"], "cohesion_ci": f["a_ci"], "friction_angle": math.atan(f["b"]),
            "friction_angle_ci": tuple(math.atan(v) for v in f["b_ci"]), "fit": f}


def fit_power_law(sigma_n, tau, se=None, level: float = 0.95, sigma_ref: float = SIGMA_REF) -> dict:
    """tau = A (sigma_n / sigma_ref)^B: A [Pa] and B [1] with ``level`` intervals (fitted in log space; tau > 0 only)."""
    sigma_n, tau = np.asarray(sigma_n, float), np.asarray(tau, float)
    keep = (tau > 0.0) & (sigma_n > 0.0)
    se_log = None if se is None else np.asarray(se, float)[keep] / tau[keep]
    f = weighted_line(np.log(sigma_n[keep] / sigma_ref), np.log(tau[keep]), se_log, level)
    return {"A": math.exp(f["a"]), "A_ci": tuple(math.exp(v) for v in f["a_ci"]), "B": f["b"], "B_ci": f["b_ci"],
            "sigma_ref": sigma_ref, "fit": f}


# -- the sweeps -------------------------------------------------------------------------

def _seeds(scene, replicas, seeds):
    if seeds is not None:
        return tuple(seeds)
    if isinstance(replicas, bool) or not isinstance(replicas, int) or not 1 <= replicas <= 10_000:
        raise ValueError(f"replicas = {replicas!r} is out of range (valid range: integer in [1, 10000])")
    return tuple(scene.seed + i for i in range(replicas))


def _fit_variables(props, level):
    """Mohr-Coulomb and power-law fits of the peak and residual shear stresses (dimension ``strength``)."""
    rows = {k: [] for k in ("mc_cohesion", "mc_friction_angle", "power_law_A", "power_law_B")}
    bounds = {k: ([], []) for k in rows}
    notes = []
    sigma = props["sigma_n"].values
    for which in ("peak", "residual"):
        mean = props[f"{which}_shear_stress_mean"].values
        se = props[f"{which}_shear_stress_sem"].values
        try:
            mc = fit_mohr_coulomb(sigma, mean, se, level)
            pl = fit_power_law(sigma, mean, se, level)
        except ValueError as err:
            notes.append(f"{which}: {err}")
            for k in rows:
                rows[k].append(math.nan)
                bounds[k][0].append(math.nan)
                bounds[k][1].append(math.nan)
            continue
        for k, est, ci in (("mc_cohesion", mc["cohesion"], mc["cohesion_ci"]),
                           ("mc_friction_angle", mc["friction_angle"], mc["friction_angle_ci"]),
                           ("power_law_A", pl["A"], pl["A_ci"]), ("power_law_B", pl["B"], pl["B_ci"])):
            rows[k].append(est)
            bounds[k][0].append(ci[0])
            bounds[k][1].append(ci[1])
        notes.append(f"{which}: Mohr-Coulomb on {mc['fit']['points']} points "
                     f"({'weighted 1/se^2' if mc['fit']['weighted'] else 'unweighted'}, reduced chi2 "
                     f"{mc['fit']['reduced_chi2']:.3g}); power law on {pl['fit']['points']} points (reduced chi2 "
                     f"{pl['fit']['reduced_chi2']:.3g})")
    out = xr.Dataset(coords={"strength": ("strength", np.array(["peak", "residual"]),
                                          {"long_name": "shear strength fitted: peak or residual"})})
    pct = f"{100 * level:g} %"
    for k in rows:
        var = PROPERTY_VARIABLES[k]
        out[k] = ("strength", np.array(rows[k]), {"units": var.units, "long_name": var.long_name})
        out[f"{k}_low"] = ("strength", np.array(bounds[k][0]),
                           {"units": var.units, "long_name": f"lower end of the {pct} confidence interval: {var.long_name}"})
        out[f"{k}_high"] = ("strength", np.array(bounds[k][1]),
                            {"units": var.units, "long_name": f"upper end of the {pct} confidence interval: {var.long_name}"})
    out.attrs = {"fit_confidence_level": level, "power_law_sigma_ref_Pa": SIGMA_REF, "fit_notes": "; ".join(notes),
                 "fit_method": "weighted least squares (weights 1/se^2 of the replica means, covariance scaled by the "
                               "reduced chi-square), Student-t intervals with m - 2 degrees of freedom; power law "
                               "in log space"}
    return out


def _product(sweep_ds, props, kind, extra_attrs):
    ds = xr.merge([sweep_ds, props.drop_vars([c for c in props.coords if c in sweep_ds.coords])],
                  combine_attrs="override")
    ds.attrs = {**sweep_ds.attrs, **props.attrs, **extra_attrs, "product": kind}
    ds.attrs["history"] = f"{sweep_ds.attrs.get('history', '')}\nasperity_sim.runs.envelope.{kind}".strip()
    return ds


def envelope(scene: Scene, sigma_n, replicas: int = 3, seeds=None, scheduler=None, workers: int = 2,
             shear_stages=None, level: float = 0.95, progress=None, note=None) -> xr.Dataset:
    """Shear properties of ``scene`` against normal stress, with fitted envelopes (see the module docstring).

    sigma_n : normal stresses [Pa] (the largest stress-controlled sigma_1 of the path is set to each)
    replicas / seeds : replicas per normal stress (seeds scene.seed, +1, ...) or explicit seeds
    scheduler, workers, progress, note : as :func:`asperity_sim.runs.engine.run_sweep` (None: automatic choice)
    shear_stages : stages of the shear segment (default: every stage after the first)
    """
    values = tuple(float(v) for v in np.atleast_1d(np.asarray(sigma_n, float)))
    sweep = Sweep(scene=scene, grid={"sigma_n": values}, seeds=_seeds(scene, replicas, seeds),
                  title=f"strength envelope: {scene.title or scene.name}", source=scene.source)
    runs = run_sweep(sweep, scheduler=scheduler, workers=workers, progress=progress, note=note)
    props = P.replica_statistics(P.shear_properties(runs, shear_stages))
    fits = _fit_variables(props, level) if len(values) >= 2 else xr.Dataset()
    props = xr.merge([props, fits], combine_attrs="drop_conflicts")
    props.attrs = fits.attrs
    return _product(runs, props, "envelope", {"shear_stages": "all after the first" if shear_stages is None
                                              else " ".join(map(str, shear_stages))})


def cyclic(scene: Scene, amplitudes, cycles: int = 2, increments: int = 8, sigma_n=None, replicas: int = 3,
           seeds=None, scheduler=None, workers: int = 2, progress=None, note=None) -> xr.Dataset:
    """Secant stiffness, G/Gmax, loop energy and damping of the last of ``cycles`` cycles against amplitude.

    The path: the first stage of ``scene`` (normal loading, its sigma_1 set to ``sigma_n`` [Pa]
    if given), then :func:`cyclic_path` cycles at each amplitude [m].
    """
    base = cyclic_path(scene.path.stages[0], 1e-6, cycles, increments)
    scene = scene.replace(path=base)
    if sigma_n is not None:
        from .sweep import apply_path

        try:
            scene = scene.replace(path=apply_path(base, sigma_n=float(sigma_n)))
        except ValueError as err:
            raise SceneError(f"sigma_n: {err}") from None
    values = tuple(float(v) for v in np.atleast_1d(np.asarray(amplitudes, float)))
    sweep = Sweep(scene=scene, grid={"amplitude": values}, seeds=_seeds(scene, replicas, seeds),
                  title=f"cyclic shear: {scene.title or scene.name}", source=scene.source)
    runs = run_sweep(sweep, scheduler=scheduler, workers=workers, progress=progress, note=note)
    props = P.replica_statistics(P.cycle_properties(runs, cycle=-1))
    props = xr.merge([props, P.every_cycle(runs).drop_vars([c for c in props.coords if c != "cycle"],
                                                            errors="ignore")], combine_attrs="drop_conflicts")
    return _product(runs, props, "cyclic", {"cycles": cycles, "cycle_evaluated": "the last",
                                            "increments_per_quarter_cycle": increments})


# -- files ---------------------------------------------------------------------------------

_COLUMN_UNITS = {"Pa m-1": "Pa_per_m", "J m-2": "J_per_m2"}
"""CF units as they appear in CSV column names (no spaces)."""


def write_csv(ds: xr.Dataset, path) -> Path:
    """A plain CSV table (``#`` comment header) of the properties against the swept quantity, with standard errors."""
    path = Path(path)
    kind = ds.attrs.get("product")
    x_name, names = ("sigma_n", P.SHEAR_PROPERTIES) if kind == "envelope" else ("amplitude", P.CYCLE_PROPERTIES)
    x_unit = "Pa" if x_name == "sigma_n" else "m"
    lines = [f"# asperity_sim {kind} table: {ds.attrs.get('title', '')}",
             f"# law {ds.attrs.get('law')}, n = {ds.attrs.get('n_asperities')} asperities, "
             f"{ds.attrs.get('replicas')} replica(s) per point (seeds {ds.attrs.get('seeds')})",
             "# <name>: ensemble mean over replicas; <name>_se: its standard error (replica s.d./sqrt(m) for m >= 2, "
             "else the Monte Carlo standard error of the one run where defined, else empty)",
             "# units in the column names (SI); see docs/joint_properties.md for definitions"]
    if kind == "envelope" and "mc_cohesion" in ds:
        level = 100 * float(ds.attrs.get("fit_confidence_level", 0.95))
        for which in ("peak", "residual"):
            f = ds.sel(strength=which)
            lines.append(f"# {which} Mohr-Coulomb: c = {float(f.mc_cohesion):.6g} Pa "
                         f"[{float(f.mc_cohesion_low):.6g}, {float(f.mc_cohesion_high):.6g}] ({level:g} % CI), "
                         f"phi = {math.degrees(float(f.mc_friction_angle)):.4f} deg "
                         f"[{math.degrees(float(f.mc_friction_angle_low)):.4f}, "
                         f"{math.degrees(float(f.mc_friction_angle_high)):.4f}]")
            lines.append(f"# {which} power law tau = A (sigma_n / {SIGMA_REF:g} Pa)^B: A = {float(f.power_law_A):.6g} Pa "
                         f"[{float(f.power_law_A_low):.6g}, {float(f.power_law_A_high):.6g}], "
                         f"B = {float(f.power_law_B):.5f} [{float(f.power_law_B_low):.5f}, "
                         f"{float(f.power_law_B_high):.5f}]")
    header = [f"{x_name}_{x_unit}", "replicas_complete"]
    for k in names:
        u = _COLUMN_UNITS.get(PROPERTY_VARIABLES[k].units, PROPERTY_VARIABLES[k].units)
        header += [f"{k}_{u}", f"{k}_se_{u}"]
    status = ds["status"].values
    complete = (status == "complete").sum(axis=-1)

    def write(tmp):
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            fh.write("\n".join(lines) + "\n")
            w = csv.writer(fh)
            w.writerow(header)
            for i, x in enumerate(ds[x_name].values):
                row = [f"{x:.10g}", int(complete[i])]
                for k in names:
                    for v in (ds[f"{k}_mean"].values[i], ds[f"{k}_sem"].values[i]):
                        row.append(f"{v:.10g}" if np.isfinite(v) else "")
                w.writerow(row)

    return write_atomically(path, write)
