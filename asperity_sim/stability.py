"""The stability study's cases: extreme parameters and load paths, hostile inputs and checkpoints.

Owns the definition of the stability matrix run by ``studies/stability.py`` (and, at tiny
size, by ``tests/test_stability.py``): what each case is, what it must end with, how one case
is run and judged, and the tables written from the records.  Two tables:

* the **matrix** (:data:`CASES`): each case changes the R1 (or S1) set of Table 1 towards an
  edge of the parameter space, alone and combined, and runs load paths (:data:`PATHS`,
  :func:`build_path`) for the laws ``paper`` and ``mdr``; a run must finish with finite
  results or stop with the named exception of :func:`expected`;
* the **hostile inputs** (:data:`HOSTILE`): output paths that cannot be written, seeds the
  output cannot store, damaged and forged checkpoints (:mod:`asperity_sim.testing`), a
  checkpoint of another run, a kill during a checkpoint write.  Each states its expected
  outcome: the name of the exception that must refuse it before any work, or ``same bits``
  (the run resumes bit-identically to an uninterrupted one).

Every case runs in a worker process (:class:`Worker`) killed at a hard time limit, so a hang
or a crash inside a kernel is recorded as an outcome too.  Nothing here is compared with a
reference: the physics is tested elsewhere; this is about robustness.
"""

from __future__ import annotations

import contextlib
import io
import math
import multiprocessing as mp
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

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
    from . import presets

    return presets.TABLE1[case.base].replace(**case.changes)


def closure_scale(p):
    """d [m]: the larger of the 15 % height quantile and 0.6 mean heights (SPEC §2)."""
    from scipy import stats

    return max(float(stats.gamma.ppf(0.15, p.alpha + 1.0, scale=p.beta)), 0.6 * (p.alpha + 1.0) * p.beta)


def normal_stress(p, case, d):
    """sigma_n [Pa] of the stress-controlled paths, from a 20 000-asperity paper-law population."""
    from .kernels.evaluate import evaluate
    from .sampling.population import Population

    if isinstance(case.sigma_n, (int, float)):
        return float(case.sigma_n)
    pop = Population.sample(p, 20_000, seed=12345)
    if case.sigma_n == "pi/2":
        # theta_m(c, R_m) = pi/2 at c = R_m / k_e (Eq. 9); the closure is Delta_1 = c - r_o
        d = max(p.R_m / p.k_e - p.r_o, d) if p.k_e > 0 else 10.0 * d
    return float(evaluate(pop, [d, 0.0, 0.0]).stress[0])


def build_path(kind, p, d, sigma_n, inc):
    from . import paths

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


# --------------------------------------------------------------------------- worker with a hard time limit


def _worker(conn):
    import asperity_sim  # noqa: F401 - imports (and numba's cache) load before the first job's clock starts

    conn.send("ready")
    while True:
        job = conn.recv()
        if job is None:
            return
        try:
            function, *args = job
            conn.send(function(*args))
        except BaseException as err:  # noqa: B036 - reported to the parent, never lost
            conn.send({"outcome": type(err).__name__, "message": str(err)})


class Worker:
    """One spawned process running jobs; killed (SIGKILL) and replaced when a job exceeds its limit."""

    def __init__(self):
        self.ctx = mp.get_context("spawn")
        self.proc = None
        self._start()

    def _start(self):
        self.conn, child = self.ctx.Pipe()
        self.proc = self.ctx.Process(target=_worker, args=(child,), daemon=True)
        self.proc.start()
        if not (self.conn.poll(300) and self.conn.recv() == "ready"):
            raise RuntimeError("the stability worker process did not start")

    def run(self, job, hard_limit):
        """``job[0](*job[1:])`` in the worker (a module-level function and its arguments): its record, or
        ``{"outcome", "message"}`` when the worker was killed or died."""
        self.conn.send(job)
        if self.conn.poll(hard_limit):
            try:
                return self.conn.recv()
            except EOFError:  # the worker died (e.g. killed by the system, or a crash in compiled code)
                self.proc.join(5)
                failure = {"outcome": "WorkerDied", "message": f"worker process died (exit code {self.proc.exitcode})"}
        else:
            failure = {"outcome": "HardTimeLimit", "message": f"worker killed after {hard_limit:.0f} s"}
        self.proc.kill()
        self.proc.join()
        self._start()
        return failure

    def close(self):
        try:
            self.conn.send(None)
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(5)
        if self.proc.is_alive():
            self.proc.kill()


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


def to_dataset(records, attrs):
    import xarray as xr

    cols = {k: [r[k] for r in records] for k in records[0]}
    units = {"n": "1", "all_converged": "1", "steps": "1", "iter_max": "1", "iter_mean": "1", "residual_max": "1", "residual_final": "1",
             "cutbacks": "1", "wall_time_s": "s", "sigma_n": "Pa", "d": "m"}
    long = {"case": "case name", "path": "load path", "law": "asperity law", "n": "asperities sampled",
            "expected": "expected outcome", "outcome": "outcome (complete or exception class)",
            "message": "exception message", "steps": "converged increments",
            "all_converged": "1 when every increment of the path converged",
            "iter_max": "largest Newton iterations of an increment", "iter_mean": "mean Newton iterations",
            "residual_max": "largest final scaled residual of an increment",
            "residual_final": "final scaled residual of the last increment", "cutbacks": "increment halvings",
            "nonfinite": "outputs holding NaN or inf (empty: none)", "wall_time_s": "wall time",
            "sigma_n": "normal stress of the stress-controlled paths", "d": "closure of the 3-step path",
            "verdict": "pass, or why not"}
    data = {}
    for k, v in cols.items():
        a = np.array(v, dtype=object if isinstance(v[0], str) else None)
        if a.dtype == object:
            a = a.astype(str)
        data[k] = ("run", a, {"long_name": long[k], **({"units": units[k]} if k in units else {})})
    return xr.Dataset(data, coords={"run": np.arange(len(records))}, attrs=attrs)


def _cell(recs):
    if not recs:
        return ""
    r = recs[0]
    mark = "ok" if r["verdict"] == "pass" else "**FAIL**"
    if r["outcome"] == "complete":
        return f"{mark} {r['iter_max']}/{r['iter_mean']:.1f}"
    return f"{mark} {r['outcome'].replace('Error', '')}"


def markdown(records, header):
    kinds = [k for k in PATHS if any(r["path"] == k for r in records)]
    cols = [(k, law) for k in kinds for law in LAWS if any(r["path"] == k and r["law"] == law for r in records)]
    lines = [header, "",
             "Cells: verdict, then Newton iterations per increment (max/mean) of a run that completed, "
             "or the exception that stopped it (expected for `above_strength` and `tension` only, unless a case says "
             "otherwise).", "",
             "| case | " + " | ".join(f"{k} {law}" for k, law in cols) + " |",
             "|---|" + "---|" * len(cols)]
    for name in dict.fromkeys(r["case"] for r in records):
        cells = [_cell([r for r in records if r["case"] == name and r["path"] == k and r["law"] == law])
                 for k, law in cols]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", "### The cases", ""]
    for case in CASES:
        if any(r["case"] == case.name for r in records):
            what = ("with " + ", ".join(f"{k} = {v:.6g}" for k, v in case.changes.items())) if case.changes else "as is"
            extra = [f"n = {case.n:g}" if case.n else "", f"policy {case.policy}" if case.policy != "follow" else "",
                     f"sigma_n = {case.sigma_n}" if case.sigma_n is not None else ""]
            extra = "; ".join(e for e in extra if e)
            lines.append(f"- **{case.name}**: {case.base} {what}{'; ' + extra if extra else ''}"
                         f"{'. ' + case.note if case.note else ''}")
    lines += ["", "### Every run", "",
              "| case | path | law | n | outcome | expected | iters max/mean | residual final (max) | cut-backs "
              "| NaN/inf | wall [s] |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in records:
        lines.append(f"| {r['case']} | {r['path']} | {r['law']} | {r['n']:g} | {r['outcome']} | {r['expected']} | "
                     f"{r['iter_max']}/{r['iter_mean']:.2f} | {r['residual_final']:.1e} ({r['residual_max']:.1e}) | "
                     f"{r['cutbacks']} | {r['nonfinite'] or 'none'} | {r['wall_time_s']:.2f} |")
    msgs = [r for r in records if r["outcome"] != "complete"]
    if msgs:
        lines += ["", "### Why the runs that stopped stopped", ""]
        for r in msgs:
            lines.append(f"- {r['case']}, {r['path']}, {r['law']}: `{r['outcome']}`: {r['message'][:400]}")
    return "\n".join(lines) + "\n"




# --------------------------------------------------------------------------- hostile inputs and checkpoints

SAME = "same bits"  # the run resumes bit-identically to an uninterrupted one
SKIPPED = "skipped"


@dataclass(frozen=True)
class Hostile:
    """One hostile input: what is done (:data:`PROBES`), with which law, and what it must end with."""

    name: str
    probe: str                      # key of PROBES
    law: str = "paper"
    expected: str = "ValueError"    # exception class name, or SAME
    quick: bool = True              # part of the tests' fast subset
    note: str = ""


def _tiny_path():
    from .paths import LoadPath, Stage

    S, D = "s", "d"
    return LoadPath((Stage((S, D, D), (300e6, 0, 0), 3, name="normal"),
                     Stage((S, D, D), (300e6, 4e-6, 0), 3, name="shear"),
                     Stage((S, D, D), (300e6, -2e-6, 1e-6), 4, adaptive=True, max_fraction=0.5, name="reverse")),
                    name="tiny")


def _run_kw(law):
    return dict(n=200, seed=4, law=law, k=4, snapshots=[0, 4])


class _Stop(Exception):
    pass


def _stop_at(step_to_stop):
    def progress(stage, n_stages, fraction, step, iterations):
        if step == step_to_stop:
            raise _Stop(step)
    return progress


_BASE = {}


def base_run(law, folder):
    """(checkpoint bytes at step 5, uninterrupted dataset) of a tiny S1 run (n = 200), cached per process."""
    import asperity_sim as asim

    if law not in _BASE:
        ck = Path(folder) / f"base-{law}.npz"
        try:
            asim.simulate(asim.presets.S1, _tiny_path(), checkpoint=ck, checkpoint_every=1, progress=_stop_at(5),
                          **_run_kw(law))
        except _Stop:
            pass
        _BASE[law] = (ck.read_bytes(), asim.simulate(asim.presets.S1, _tiny_path(), **_run_kw(law)))
        ck.unlink()
    return _BASE[law]


def _tiny(folder, **kw):
    """A tiny run whose progress callback fails the probe if any increment is computed."""
    import asperity_sim as asim

    def no_work(*args):
        raise AssertionError("an increment was computed before the input was refused")

    return asim.simulate(asim.presets.S1, _tiny_path(), **{**_run_kw("paper"), "progress": no_work, **kw})


def _resumed(law, folder, path, **kw):
    """SAME if resuming ``path`` gives the uninterrupted run's bits, else what differs."""
    import asperity_sim as asim

    from .testing import same_run

    ds = asim.resume(path, checkpoint_every=None, **kw)
    return SAME if same_run(base_run(law, folder)[1], ds) else "resumed to different bits"


def _forged(law, folder, change):
    """Resume a copy of the base checkpoint with arrays rewritten by ``change(arrays)`` (valid checksums)."""
    from .testing import arrays_of, write_checkpoint

    raw, _ = base_run(law, folder)
    arrays = arrays_of(raw)
    path = write_checkpoint(folder / "forged.npz", arrays, change(arrays))
    return _resumed(law, folder, path)


def _with_nan(a, index=0):
    a = a.astype(np.float64 if a.dtype.kind != "f" else a.dtype, copy=True)
    a.flat[index] = np.nan
    return a


def probe_output_folder(law, folder):
    (folder / "a folder.nc").mkdir()
    return _tiny(folder, output=folder / "a folder.nc", law=law)


def probe_output_under_file(law, folder):
    (folder / "plain").write_text("a file")
    return _tiny(folder, output=folder / "plain" / "out.nc", law=law)


def probe_output_unwritable(law, folder):
    ro = folder / "read-only"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        if os.access(ro, os.W_OK):  # root (or a file system without permissions) writes anyway
            return SKIPPED, "the folder stays writable for this user (running as root): nothing to refuse"
        return _tiny(folder, output=ro / "out.nc", law=law)
    finally:
        ro.chmod(0o755)


def probe_output_is_checkpoint(law, folder):
    return _tiny(folder, output=folder / "same.npz", checkpoint=folder / "same.npz", law=law)


def probe_resume_output_is_checkpoint(law, folder):
    import asperity_sim as asim

    raw, _ = base_run(law, folder)
    ck = folder / "ck.npz"
    ck.write_bytes(raw)
    asim.resume(ck, output=ck)
    return "resumed over its own checkpoint"


def probe_existing_output(law, folder):
    """``asperity-sim run`` onto an existing file without ``--overwrite``: exit 1, the file untouched."""
    from .ui import cli

    scene = folder / "small.toml"
    scene.write_text(f'title = "hostile"\n[parameters]\npreset = "S1"\n[run]\nn = 200\nseed = 3\nlaw = "{law}"\n'
                     '[[path.stages]]\nincrements = 2\nDelta_1 = "2 um"\nDelta_2 = "0 um"\nDelta_3 = "0 um"\n')
    out = folder / "existing.nc"
    out.write_bytes(b"an earlier result")
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = cli.main(["run", str(scene), "-o", str(out), "--quiet"])
    kept = out.read_bytes() == b"an earlier result"
    return f"exit {code}, file {'unchanged' if kept else 'overwritten'}", err.getvalue().strip()


def probe_seed_huge(law, folder):
    return _tiny(folder, seed=2**63, law=law)


def probe_seed_negative(law, folder):
    return _tiny(folder, seed=-1, law=law)


def probe_truncated(law, folder):
    raw, _ = base_run(law, folder)
    path = folder / "truncated.npz"
    path.write_bytes(raw[: len(raw) // 2])
    return _resumed(law, folder, path)


def probe_bit_flip(law, folder):
    from .testing import flip_bit, member_data_offset

    raw, _ = base_run(law, folder)
    path = folder / "flipped.npz"
    path.write_bytes(flip_bit(raw, member_data_offset(raw, "pop_R.npy") + 200, 3))  # inside the radii: bad CRC
    return _resumed(law, folder, path)


def probe_intact(law, folder):
    raw, _ = base_run(law, folder)
    path = folder / "intact.npz"
    path.write_bytes(raw)
    return _resumed(law, folder, path)


def probe_nan_state(law, folder):
    def change(a):
        if "state_law0" in a:  # history law: a spring of the first contact
            return {"state_law0": _with_nan(a["state_law0"])}
        return {"state_delta_c": _with_nan(a["state_delta_c"])}  # path-independent law: the committed Delta
    return _forged(law, folder, change)


def probe_unsorted_heights(law, folder):
    return _forged(law, folder, lambda a: {"pop_r": a["pop_r"][::-1].copy()})


def probe_slot_index(law, folder):
    def change(a):
        if "state_asp" in a:  # history law: a slot pointing past the last asperity
            asp = a["state_asp"].copy()
            asp[0] = a["pop_r"].size
            return {"state_asp": asp}
        return {"pos_i": np.array([99, 1], dtype=np.int64)}  # path-independent law: a stage index past the path
    return _forged(law, folder, change)


def probe_other_law(law, folder):
    import asperity_sim as asim

    raw, _ = base_run(law, folder)
    ck = folder / "ck.npz"
    ck.write_bytes(raw)
    other = next(name for name in LAWS if name != law)
    asim.simulate(asim.presets.S1, _tiny_path(), resume=ck, **{**_run_kw(law), "law": other})
    return "resumed under another law"


def probe_other_path(law, folder):
    import asperity_sim as asim

    from . import paths

    raw, _ = base_run(law, folder)
    ck = folder / "ck.npz"
    ck.write_bytes(raw)
    asim.simulate(asim.presets.S1, paths.three_step(10e-6, increments=3), resume=ck, **_run_kw(law))
    return "resumed on another path"


KILLED_WRITER = """
import os, signal, sys
import asperity_sim as asim
from asperity_sim import checkpoint
from asperity_sim.stability import _run_kw, _tiny_path
real, calls = os.replace, []
def replace(src, dst):
    calls.append(src)
    if len(calls) == 3:
        os.kill(os.getpid(), signal.SIGKILL)  # the third checkpoint is written in full, then killed before its rename
    real(src, dst)
checkpoint.os.replace = replace
asim.simulate(asim.presets.S1, _tiny_path(), checkpoint=sys.argv[1], checkpoint_every=1, **_run_kw(sys.argv[2]))
"""


def probe_killed_write(law, folder):
    """SIGKILL between a checkpoint's write and its rename: the next run removes the stale temporary and resumes."""
    import asperity_sim

    ck = folder / "killed.npz"
    package_root = os.path.dirname(os.path.dirname(asperity_sim.__file__))  # the child imports this same package
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [package_root, os.environ.get("PYTHONPATH")]))}
    child = subprocess.run([sys.executable, "-c", KILLED_WRITER, str(ck), law], capture_output=True, text=True,
                           timeout=300, env=env)
    if child.returncode != -signal.SIGKILL:
        return f"the writer was not killed (exit {child.returncode})", child.stderr[-400:]
    stale = [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]
    if not stale:
        return "no temporary was left by the kill (nothing tested)", ""
    outcome = _resumed(law, folder, ck)
    left = [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]
    if left:
        return f"{outcome}, but temporaries remain: {left}", ""
    return outcome, (f"the kill left {len(stale)} temporary file (.{ck.name}.<pid>.<random>.tmp) next to the intact "
                     "checkpoint; the resumed run removed it and finished")


PROBES = {name.removeprefix("probe_"): f for name, f in dict(globals()).items() if name.startswith("probe_")}

HOSTILE = (
    Hostile("output is an existing folder", "output_folder", note="refused before any work"),
    Hostile("output under a regular file", "output_under_file"),
    Hostile("output in a folder without write permission", "output_unwritable",
            note="skipped where the user can write anyway (root)"),
    Hostile("output equal to the checkpoint", "output_is_checkpoint"),
    Hostile("resume with output equal to its checkpoint", "resume_output_is_checkpoint"),
    Hostile("existing output without --overwrite (asperity-sim run)", "existing_output",
            expected="exit 1, file unchanged"),
    Hostile("seed = 2^63", "seed_huge", note="the output stores a signed 64-bit seed"),
    Hostile("seed = -1", "seed_negative"),
    *(h for law, first in zip(LAWS, (True, False)) for h in (
        Hostile("intact checkpoint (control)", "intact", law, SAME),
        Hostile("checkpoint truncated to half", "truncated", law, "CheckpointError"),
        Hostile("checkpoint with a flipped bit (CRC-32 fails)", "bit_flip", law, "CheckpointError"),
        Hostile("forged: NaN in the committed state, valid checksum", "nan_state", law, "CheckpointError"),
        Hostile("forged: heights unsorted, valid checksum", "unsorted_heights", law, "CheckpointError"),
        Hostile("forged: index out of range, valid checksum", "slot_index", law, "CheckpointError",
                note="mdr: a contact slot naming asperity n; paper: stage index 99"),
        Hostile("resume under another law", "other_law", law, "CheckpointError", quick=first),
        Hostile("resume on another load path", "other_path", law, "CheckpointError", quick=first),
        Hostile("killed during a checkpoint write, then resumed", "killed_write", law, SAME, quick=False,
                note="SIGKILL between the write and the rename of the third checkpoint"),
    )),
)


def run_hostile(case, folder=None):
    """Run one hostile case in a fresh folder; its record (case, law, expected, outcome, message, wall time)."""
    rec = {"case": case.name, "law": case.law, "expected": case.expected, "outcome": "", "message": "",
           "wall_time_s": 0.0}
    folder = Path(tempfile.mkdtemp(prefix="hostile-", dir=folder))
    t0 = time.perf_counter()
    try:
        base_run(case.law, folder)  # not timed as part of the case
        t0 = time.perf_counter()
        result = PROBES[case.probe](case.law, folder)
        rec["outcome"], rec["message"] = result if isinstance(result, tuple) else (result, "")
        if not isinstance(rec["outcome"], str):  # a probe that returned a dataset: the input was accepted
            rec["outcome"], rec["message"] = "complete", "the input was accepted and the run completed"
    except Exception as err:  # noqa: BLE001 - the outcome is the exception's name
        rec["outcome"], rec["message"] = type(err).__name__, str(err)
        if isinstance(err, AssertionError):
            rec["message"] += " | " + traceback.format_exc(limit=3)
    finally:
        rec["wall_time_s"] = time.perf_counter() - t0
        shutil.rmtree(folder, ignore_errors=True)
    rec["message"] = rec["message"].replace(str(folder), "<folder>")  # the same text on every run
    return rec


def hostile_verdict(rec):
    """'pass' (the expected outcome, with a message if refused), 'skipped' (with why), or 'FAIL: ...'."""
    if rec["outcome"] == SKIPPED:
        return "skipped" if rec["message"] else "FAIL: skipped without a reason"
    if rec["outcome"] != rec["expected"]:
        return f"FAIL: {rec['outcome']}"
    if rec["expected"].endswith("Error") and not rec["message"]:
        return "FAIL: no message"
    if rec["expected"] == "CheckpointError" and "checkpoint '" not in rec["message"]:
        return "FAIL: the message does not name the file"
    return "pass"


def select_hostile(quick=False, only=None):
    return [h for h in HOSTILE if (h.quick or not quick)
            and (not only or any(s.lower() in h.name.lower() for s in only))]


def run_hostile_table(cases, hard_limit, in_process=False, log=print):
    records = []
    worker = None if in_process else Worker()
    try:
        for i, case in enumerate(cases, 1):
            t0 = time.perf_counter()
            rec = run_hostile(case) if in_process else worker.run((run_hostile, case), hard_limit)
            if "case" not in rec:  # killed at the hard limit, or died
                rec = {"case": case.name, "law": case.law, "expected": case.expected, **rec,
                       "wall_time_s": time.perf_counter() - t0}
            rec["verdict"] = hostile_verdict(rec)
            records.append(rec)
            log(f"[{i:3d}/{len(cases)}] {case.name:58s} {case.law:5s} {rec['outcome']:24s} {rec['verdict']:8s} "
                f"{rec['wall_time_s']:6.2f} s")
    finally:
        if worker is not None:
            worker.close()
    return records


def hostile_markdown(records, header):
    lines = [header, "",
             "Expected: the exception that must refuse the input (before any work for the output and seed rows), "
             f"or `{SAME}` (resumed bit-identically to an uninterrupted run).", "",
             "| case | law | expected | outcome | verdict | wall [s] |", "|---|---|---|---|---|---|"]
    for r in records:
        lines.append(f"| {r['case']} | {r['law']} | {r['expected']} | {r['outcome']} | {r['verdict']} | "
                     f"{r['wall_time_s']:.2f} |")
    lines += ["", "Messages:", ""]
    for r in records:
        if r["message"]:
            lines.append(f"- {r['case']}, {r['law']}: {r['message'][:300]}")
    return "\n".join(lines) + "\n"


def hostile_dataset(records):
    import xarray as xr

    long = {"case": "hostile input", "law": "asperity law", "expected": "expected outcome",
            "outcome": "outcome (exception class, same bits, ...)", "message": "message of the outcome",
            "wall_time_s": "wall time", "verdict": "pass, skipped (and why), or why not"}
    data = {}
    for k, name in long.items():
        v = [r[k] for r in records]
        attrs = {"long_name": name, **({"units": "s"} if k == "wall_time_s" else {})}
        data[f"hostile_{k}"] = ("hostile", np.array(v, dtype=float if k == "wall_time_s" else str), attrs)
    return xr.Dataset(data, coords={"hostile": np.arange(len(records))})
