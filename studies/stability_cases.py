"""The stability study's matrix: extreme parameters and load paths, each with its expected outcome.

Owns the cases run by ``studies/stability.py`` (and, at tiny size, by ``tests/test_stability.py``):
each case (:data:`CASES`) changes the R1 (or S1) set of Table 1 towards an edge of the
parameter space, alone and combined, and runs load paths (:data:`PATHS`, :func:`build_path`)
for the laws ``paper`` and ``mdr``; a run must finish with finite results or stop with the
named exception of :func:`expected`.  Here too: how one run is made and judged
(:func:`run_one`, :func:`verdict`) and the loop over the matrix (:func:`run_matrix`), each run
in a worker process killed at a hard time limit (``stability_worker.py``), so a hang or a crash
inside a kernel is recorded as an outcome too.  Nothing here is compared with a reference: the
physics is tested elsewhere; this is about robustness.

The hostile inputs are in ``stability_hostile.py``, the tables written from the records in
``stability_tables.py``.  These modules are the study's, not the package's (they moved out of
``asperity_sim.stability`` in 0.4): they sit beside ``studies/stability.py`` and import each
other by name, as the script imports them (its folder is on ``sys.path``); tests import them
through ``tests/support.py``'s ``study(...)``.
"""

from __future__ import annotations

import math
import time
import traceback
from dataclasses import dataclass, field

import numpy as np
from stability_worker import Worker

LAWS = ("paper", "mdr")
PATHS = ("three_step", "cns", "cyclic", "zero_load", "stress_shear", "above_strength", "tension", "reload",
         "seat_load")
DEFAULT_PATHS = ("three_step", "cns", "cyclic")
SQ = 1.0 / (3.0 * math.sqrt(2.0))  # c = d = SQ puts b/2 + 3 sqrt(c² + d²) exactly at 1 with b = 0
R1_MEAN = (6.14 + 1.0) * 3.52e-6   # mean height of R1 [m]


@dataclass(frozen=True)
class Case:
    """One corner of the parameter space: changes to a Table 1 set, sample size, paths and laws."""

    name: str
    changes: dict = field(default_factory=dict)
    base: str = "R1"
    n: int | None = None            # None: the --n of the run
    paths: tuple = DEFAULT_PATHS
    laws: tuple = LAWS
    sigma_n: object = None          # None (stress at d), a stress [Pa], or "pi/2"
    policy: str = "follow"
    inc: int | None = None          # increments per stage (None: the run's)
    expect: dict = field(default_factory=dict)  # path kind -> expected outcome, overriding EXPECTED
    big: bool = False               # skipped by --no-big and --quick
    quick: bool = True              # part of --quick (and of the tests' fast matrix)
    note: str = ""


CASES = (
    # -- alone ------------------------------------------------------------------------------
    Case("R1", paths=DEFAULT_PATHS + ("reload", "seat_load"),
         note="Table 1 rough set (e = 1); also unload-reload and seat-load under stress control"),
    Case("S1", base="S1", paths=DEFAULT_PATHS + ("reload", "seat_load"), note="Table 1 smooth set"),
    Case("e=0", {"e": 0.0}, paths=DEFAULT_PATHS + ("above_strength",),
         note="flat on rough: theta_m = 0, shear strength exactly mu sigma_1"),
    Case("theta_m=pi/2", {"R_m": 2e-6, "R_sigma": 0.5e-6}, quick=False,
         note="R_m small against the closure: k_e c / R > 1, cos theta_m clipped at 0"),
    Case("alpha=-0.999", {"alpha": -0.999}, note="heights piled at r = 0 (half of them exactly 0)"),
    Case("alpha=1e4", {"alpha": 1e4, "beta": R1_MEAN / (1e4 + 1.0)},
         note="narrow height band (s.d. 1 % of the mean)"),
    Case("R_sigma=0", {"R_sigma": 0.0}, note="every R = R_m"),
    Case("R_sigma=R_m", {"R_sigma": 50e-6}, quick=False, note="truncation at R > 0 bites; R down to ~0"),
    Case("mu=0", {"mu": 0.0}, paths=DEFAULT_PATHS + ("above_strength",),
         note="no tangential stiffness of a contact"),
    Case("mu=10", {"mu": 10.0}),
    Case("nu=0", {"nu": 0.0}, quick=False),
    Case("nu=0.5", {"nu": 0.5}),
    Case("nu=-0.9", {"nu": -0.9}),
    Case("nu=-0.999", {"nu": -0.999}, quick=False),
    Case("G=1e6", {"G": 1e6}),
    Case("G=1e13", {"G": 1e13}),
    Case("N=1", {"N": 1.0}),
    Case("N=1e12", {"N": 1e12}),
    Case("n=1", n=1, paths=DEFAULT_PATHS + ("zero_load",), note="one asperity: standard errors undefined (inf)"),
    Case("n=2", n=2, quick=False),
    Case("n=1e7", n=10_000_000, big=True, quick=False, note="ten million asperities (mdr: k = 4 springs)"),
    Case("sigma_n=1 Pa", sigma_n=1.0, paths=("cns", "cyclic"), note="first contact of a few asperities"),
    Case("sigma_n at theta_m=pi/2", sigma_n="pi/2", paths=("cns", "cyclic"),
         note="closure 4 R_m: theta_m(c, R_m) = pi/2 (about 0.4 TPa for R1)"),
    Case("zero load", paths=("zero_load",), note="stress control from exactly zero load"),
    Case("above strength", paths=("above_strength",), note="sigma_2 = 3 (mu + 1) sigma_1 prescribed"),
    Case("tension", paths=("tension",), note="sigma_1 < 0 prescribed: contacts only push"),
    Case("stress-controlled shear", paths=("stress_shear",),
         note="sigma_1, sigma_2 = 0.3 mu sigma_1 and sigma_3 = 0 all prescribed"),
    Case("r_o=1 mm", {"r_o": 1e-3}, note="initial closure: theta_m = pi/2 from the start"),
    Case("R2 (marble)", base="R2", quick=False, note="Table 1 marble set, r_o > 0, mm scale"),
    Case("alpha=-1+1e-9", {"alpha": -1.0 + 1e-9}, quick=False, note="all heights 0 to double precision"),
    Case("policy birth", policy="birth", paths=DEFAULT_PATHS + ("stress_shear",), note="frozen contact angles"),
    Case("b=-1, c=0.5", {"b": -1.0, "c": 0.5}, note="orientation density zero on an edge"),
    Case("b=2", {"b": 2.0}, quick=False, note="orientation density zero at u = pi/2"),
    Case("c=d=1/(3 sqrt 2)", {"c": SQ, "d": SQ}, quick=False, note="azimuthal anisotropy at its bound"),
    # -- combined ---------------------------------------------------------------------------
    Case("e=0, mu=0", {"e": 0.0, "mu": 0.0}, paths=DEFAULT_PATHS + ("above_strength", "zero_load"),
         note="singular shear tangent: displacement-driven shear works, stress-driven fails"),
    Case("stiff: G=1e13, N=1e12, nu=0.5", {"G": 1e13, "N": 1e12, "nu": 0.5}),
    Case("soft: G=1e6, N=1, sigma_n=1 Pa", {"G": 1e6, "N": 1.0}, sigma_n=1.0),
    Case("soft-dense: G=1e6, N=1e12", {"G": 1e6, "N": 1e12}, quick=False),
    Case("n=1, e=0, mu=0", {"e": 0.0, "mu": 0.0}, n=1, paths=DEFAULT_PATHS + ("above_strength",)),
    Case("n=1, alpha=-0.999, G=1e13", {"alpha": -0.999, "G": 1e13}, n=1),
    Case("alpha=-0.999, R_sigma=R_m, theta_m=pi/2", {"alpha": -0.999, "R_m": 2e-6, "R_sigma": 2e-6},
         quick=False),
    Case("alpha=1e4, R_sigma=0, e=0", {"alpha": 1e4, "beta": R1_MEAN / (1e4 + 1.0), "R_sigma": 0.0, "e": 0.0},
         quick=False),
    Case("mu=10, nu=-0.9, b=-1, c=0.5", {"mu": 10.0, "nu": -0.9, "b": -1.0, "c": 0.5}),
    Case("mu=0, theta_m=pi/2, sigma_n at pi/2", {"mu": 0.0, "R_m": 2e-6, "R_sigma": 0.5e-6}, sigma_n="pi/2",
         paths=("cns", "cyclic", "above_strength"), quick=False, expect={"above_strength": "complete"},
         note="contacts up to 90 degrees: no finite shear strength, 3 sigma_n of shear is carried"),
    Case("G=1e13, sigma_n=1 Pa, zero load", {"G": 1e13}, sigma_n=1.0, paths=("cns", "zero_load")),
    Case("sigma_n=1 mPa, G=1e13, N=1e12", {"G": 1e13, "N": 1e12}, sigma_n=1e-3, paths=("cns", "cyclic", "zero_load"),
         note="overlaps of 1e-15 m at Delta ~ 5e-6 m: sigma_1 moves by 1e-5 per ulp of Delta, so increments "
              "converge at the floating-point resolution of Delta (residual recorded)"),
    Case("e=0, alpha=-0.999, N=1e12, mu=10", {"e": 0.0, "alpha": -0.999, "N": 1e12, "mu": 10.0},
         paths=DEFAULT_PATHS + ("above_strength",), quick=False),
    Case("mu=0, e=0, stress-controlled shear", {"mu": 0.0, "e": 0.0}, paths=("stress_shear", "tension")),
    Case("birth, r_o=1 mm, mu=10", {"r_o": 1e-3, "mu": 10.0}, policy="birth", quick=False),
    Case("birth, n=1, alpha=-0.999", {"alpha": -0.999}, n=1, policy="birth", paths=DEFAULT_PATHS + ("zero_load",)),
)

EXPECTED = {"above_strength": "StressNotReachableError", "tension": "StressNotReachableError"}


def expected(case, kind):
    """What a run must end with: ``complete`` or the name of the exception that must stop it."""
    if kind in case.expect:
        return case.expect[kind]
    return EXPECTED.get(kind, "complete")


# --------------------------------------------------------------------------- scales and paths


def params_of(case):
    from asperity_sim import presets

    return presets.TABLE1[case.base].replace(**case.changes)


def closure_scale(p):
    """d [m]: the larger of the 15 % height quantile and 0.6 mean heights (SPEC §2)."""
    from scipy import stats

    return max(float(stats.gamma.ppf(0.15, p.alpha + 1.0, scale=p.beta)), 0.6 * (p.alpha + 1.0) * p.beta)


def normal_stress(p, case, d):
    """sigma_n [Pa] of the stress-controlled paths, from a 20 000-asperity paper-law population."""
    from asperity_sim.kernels.evaluate import evaluate
    from asperity_sim.sampling.population import Population

    if isinstance(case.sigma_n, (int, float)):
        return float(case.sigma_n)
    pop = Population.sample(p, 20_000, seed=12345)
    if case.sigma_n == "pi/2":
        # theta_m(c, R_m) = pi/2 at c = R_m / k_e (Eq. 9); the closure is Delta_1 = c - r_o
        d = max(p.R_m / p.k_e - p.r_o, d) if p.k_e > 0 else 10.0 * d
    return float(evaluate(pop, [d, 0.0, 0.0]).stress[0])


def build_path(kind, p, d, sigma_n, inc):
    from asperity_sim import paths

    S, D = paths.STRESS, paths.DISPLACEMENT
    if kind == "three_step":
        return paths.three_step(d, increments=inc)
    if kind == "cns":
        return paths.constant_normal_shear(sigma_n, 2.0 * d, increments=2 * inc, normal_increments=inc)
    if kind == "cyclic":
        a = 0.5 * d
        return paths.LoadPath((
            paths.Stage((S, D, D), (sigma_n, 0.0, 0.0), inc, name="normal loading"),
            paths.Stage((S, D, D), (sigma_n, a, 0.0), inc, name="+A"),
            paths.Stage((S, D, D), (sigma_n, -a, 0.0), 2 * inc, name="-A"),
            paths.Stage((S, D, D), (sigma_n, a, 0.0), 2 * inc, name="+A again"),
        ), name="cyclic_shear")
    if kind == "zero_load":
        return paths.LoadPath((
            paths.Stage((S, S, D), (0.0, 0.0, 0.0), 2, name="sigma_1 = sigma_2 = 0 from zero load"),
            paths.Stage((S, D, D), (0.0, d, 0.0), inc, name="shear at zero normal stress"),
            paths.Stage((S, D, D), (sigma_n, d, 0.0), inc, name="normal loading under shear"),
        ), name="zero_load")
    if kind == "stress_shear":
        return paths.LoadPath((
            paths.Stage((S, D, D), (sigma_n, 0.0, 0.0), inc, name="normal loading"),
            paths.Stage((S, S, S), (sigma_n, 0.3 * p.mu * sigma_n, 0.0), inc, name="shear by stress"),
        ), name="stress_shear")
    if kind == "reload":
        return paths.LoadPath((
            paths.Stage((S, D, D), (sigma_n, 0.0, 0.0), inc, name="normal loading"),
            paths.Stage((S, D, D), (0.0, 0.0, 0.0), inc, name="unloading to zero"),
            paths.Stage((S, D, D), (sigma_n, 0.0, 0.0), inc, name="reloading from zero"),
        ), name="reload")
    if kind == "seat_load":
        return paths.LoadPath((
            paths.Stage((S, D, D), (1e-3, 0.0, 0.0), 2, name="seating at 1 mPa"),
            paths.Stage((S, D, D), (sigma_n, 0.0, 0.0), inc, name="loading"),
        ), name="seat_load")
    if kind == "tension":
        return paths.LoadPath((
            paths.Stage((S, D, D), (-sigma_n, 0.0, 0.0), inc, name="tension"),
        ), name="tension")
    if kind == "above_strength":
        return paths.LoadPath((
            paths.Stage((S, D, D), (sigma_n, 0.0, 0.0), inc, name="normal loading"),
            paths.Stage((S, S, D), (sigma_n, 3.0 * (p.mu + 1.0) * sigma_n, 0.0), inc,
                        name="shear stress above the strength"),
        ), name="above_strength")
    raise ValueError(f"path kind {kind!r} is not known (valid: {', '.join(PATHS)})")


# --------------------------------------------------------------------------- one run


def nonfinite_outputs(ds):
    """Names of data variables and numeric attributes of ``ds`` holding NaN or inf."""
    bad = [name for name, v in ds.data_vars.items()
           if np.issubdtype(v.dtype, np.number) and not np.all(np.isfinite(v.values))]
    for key, val in ds.attrs.items():
        a = np.asarray(val)
        if np.issubdtype(a.dtype, np.number) and not np.all(np.isfinite(a)):
            bad.append(f"attr {key}")
    return bad


def empty_record(case, kind, law, n):
    return {"case": case.name, "path": kind, "law": law, "n": n, "expected": expected(case, kind), "outcome": "",
            "all_converged": 0, "message": "", "steps": 0, "iter_max": 0, "iter_mean": 0.0, "residual_max": 0.0,
            "residual_final": 0.0, "cutbacks": 0, "nonfinite": "", "wall_time_s": 0.0, "sigma_n": math.nan,
            "d": math.nan}


def run_one(case, kind, law, n, seed, inc, soft_limit):
    """Run one (case, path, law) and return its record (a dict of plain values)."""
    import asperity_sim as asim

    rec = empty_record(case, kind, law, n)
    t0 = time.perf_counter()
    ds = None
    try:
        p = params_of(case)
        d = closure_scale(p)
        sigma_n = normal_stress(p, case, d)
        rec["d"], rec["sigma_n"] = d, sigma_n
        path = build_path(kind, p, d, sigma_n, inc)
        ds = asim.simulate(p, path, n=n, seed=seed, law=law, policy=case.policy, k=4 if n > 10**6 else 16,
                           max_wall_time=soft_limit)
        rec["outcome"], rec["all_converged"] = "complete", 1
    except asim.SimulationError as err:
        rec["outcome"], rec["message"] = type(err).__name__, str(err)
        ds = err.dataset
    except Exception as err:  # noqa: BLE001 - an unnamed failure is what the matrix looks for
        rec["outcome"] = type(err).__name__
        rec["message"] = f"{err} | {traceback.format_exc(limit=3)}"
    rec["wall_time_s"] = time.perf_counter() - t0
    if ds is not None:
        it = ds["iterations"].values[1:]
        res = ds["residual"].values[1:]
        rec["steps"] = int(ds.sizes["step"]) - 1
        if it.size:
            rec["iter_max"], rec["iter_mean"] = int(it.max()), float(it.mean())
            rec["residual_max"], rec["residual_final"] = float(np.max(res)), float(res[-1])
        rec["cutbacks"] = int(ds["cutbacks"].values.sum())
        rec["nonfinite"] = ", ".join(nonfinite_outputs(ds))
    return rec


def verdict(rec, iter_cap):
    """'pass' when the run did what it must: expected outcome, finite outputs, a message on failure."""
    if rec["nonfinite"]:
        return "FAIL: non-finite output"
    if rec["outcome"] != rec["expected"]:
        return f"FAIL: {rec['outcome']}"
    if rec["outcome"] != "complete" and not rec["message"]:
        return "FAIL: no message"
    if rec["iter_max"] > iter_cap:
        return "FAIL: iteration cap"
    return "pass"



# --------------------------------------------------------------------------- matrix


def select_runs(quick=False, big=True, only=None):
    runs = []
    for case in CASES:
        if (case.big and (not big or quick)) or (quick and not case.quick):
            continue
        if only and not any(s.lower() in case.name.lower() for s in only):
            continue
        for kind in case.paths:
            for law in case.laws:
                runs.append((case, kind, law))
    return runs


def run_matrix(runs, n, seed, inc, soft_limit, hard_limit, in_process=False, log=print):
    records = []
    worker = None if in_process else Worker()
    try:
        for i, (case, kind, law) in enumerate(runs, 1):
            job = (run_one, case, kind, law, case.n or n, seed, case.inc or inc, soft_limit)
            t0 = time.perf_counter()
            rec = run_one(*job[1:]) if in_process else worker.run(job, hard_limit)
            if "case" not in rec:  # killed at the hard limit, or died: record why
                rec = {**empty_record(case, kind, law, case.n or n), **rec, "wall_time_s": time.perf_counter() - t0}
            records.append(rec)
            log(f"[{i:3d}/{len(runs)}] {case.name:42s} {kind:14s} {law:5s} {rec['outcome']:26s} "
                f"it {rec['iter_max']:3d}/{rec['iter_mean']:5.2f} {rec['wall_time_s']:7.2f} s")
    finally:
        if worker is not None:
            worker.close()
    return records

