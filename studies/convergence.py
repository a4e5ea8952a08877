"""Error against run time: Monte Carlo, randomised QMC, height-band pruning and the paper's grid.

Physical question: how many asperities (and how much wall time) does a given accuracy of
the interface response cost, and which way of choosing the asperities is cheapest?  For
each scene the error of every method is measured against the converged quadrature of
Eq. (23) (``asperity_sim.reference``, ``paper`` law, policy follow, ~1e-8 relative), as a
function of the sample size n and of the wall time, with replicas (different seeds), so
that an error is the RMS over replicas, not one draw.

Scenes (the paper's figures, fixed resolution of the recorded curves):
  fig13_R1, fig13_S1  shear at 500 MPa (Fig. 13): sigma_1 to 500 MPa in 20 increments, then
                      Delta_2 to 10 um (20 increments) and to 50 um (20 increments), sigma_1 held;
                      scenarios/constant_normal_shear.shear_path(500e6, 50e-6, 20).
  fig11_R1            the 3-step path of R1 (Fig. 11): Delta = 15 um along 1, then 2, then 3,
                      10 increments per step (paths.three_step(15e-6, 10)).
  closure_R1          the normal loading alone (stage 1 of Fig. 13: sigma_1 to 500 MPa in 20
                      increments), where height-band pruning pays.
Quantities (relative errors, |x - x_ref| / |x_ref|):
  curve          max over the curve: fig13 the shear resistance sigma_2/sigma_1 over the shear
                 stages (40 points); fig11 |sigma_shear|/sigma_1 over steps 2 and 3 (20 points);
                 closure Delta_1 over the 20 load points.
  fig13: delta1_500MPa (Delta_1 at 500 MPa, end of stage 1), sigma2_10um, sigma2_50um (sigma_2 at
  Delta_2 = 10 and 50 um), delta1_curve (max over the shear stages of the Delta_1 error).
  fig11: sigma1_p1 (end of step 1), sigma1_p2, sigma2_p2 (end of step 2), sigma1_p3, sigma2_p3,
  sigma3_p3 (end of step 3).   closure: delta1_500MPa.
Under stress control sigma_1 is prescribed (its error is the solver tolerance), so its Monte
Carlo error shows up in Delta_1, which is reported instead.

Methods (all in one run, same machine, same number of threads):
  mc           plain Monte Carlo (Population.sample, sampler "random") + asperity_sim.simulate
  rqmc         scrambled Sobol' points (randomised QMC), n = 2^m; its error comes from replicas
  pruned       height-band pruning + scrambled Sobol' (asperity_sim.solve.pruning.simulate_pruned): the
               heights are drawn from the band the scene can reach (provable bound, including
               shear-induced contacts of inclined asperities), weight P(band)/n; a 4096-point
               pilot run gives Delta_1 for stress-controlled paths, the run is checked against
               the bound afterwards and redone with a wider band if it left it (detect and
               correct); pilot and checks are included in the wall time
  pruned_mc    the same band with plain Monte Carlo (shows the variance gain of the band alone)
  grid         the paper's grid method, Steps 1-5 as published (asperity_sim.analysis.gridmethod: Simpson,
               Delta_r = 0.01 r90 s, Delta_R = 0.01 R_sigma s, (20/s) x (40/s) in theta, phi, the
               tangent of Eq. 27 by forward differences with step 0.01 r90 at every iterate, Newton),
               s = 1 is the published resolution; deterministic, one replica; its "n" is the number
               of grid points of one stress evaluation.  Like the Monte Carlo runs it records a
               tangent at every increment.
  grid_forces  the same grid with a lighter Step 4 that is not the paper's (full_tangent=False):
               difference columns only for the stress-controlled components and only while
               iterating, no tangent recorded.  Identical stresses; on the displacement-controlled
               Fig. 11 path one stress evaluation per increment instead of four.  Speed-ups are
               reported against both.
Wall time: sampling + simulate (or the whole grid run), warm numba cache (every kernel is
run once before timing), 2 threads; the reference quadrature is not timed.  A run shorter than
0.2 s, of any method, is run three times and its median time kept (the runs are deterministic):
one timing of a 5-50 ms run varies about 2x on this shared machine.
Settings: Newton tolerance rtol = 1e-9 (relative residual of the prescribed stress) for both
Monte Carlo (SolverSettings) and the grid; OMP_WAIT_POLICY=PASSIVE (set below unless already
set: with the default spinning policy a small parallel region took ~10 ms instead of ~0.1 ms
whenever other processes shared the cores).

Sizes and replicas: n = 2^10 ... 2^22 (--n-max) in factors of 4, 4 replicas (--replicas) up to
2^20 and 3 at 2^22; grid scales s = 4, 2, 1 for Fig. 13 (the published run takes minutes there:
grid_forces ~10 and grid ~20 stress evaluations per increment; halving s costs ~15x), 4, 2,
1.4, 1, 0.7 for the displacement-controlled Fig. 11 (four evaluations per increment with grid,
one with grid_forces) and 4, 2, 1.4, 1 for the closure (s = 0.7 would take ~10-20 min there:
1e9 points per evaluation).

Run:   python studies/convergence.py              (full study: 30 min on this 2-core machine at load
                                                   average 1.5-2, half of it the grid runs at s = 1)
       python studies/convergence.py --quick      (smoke run, about 25 s)
Writes outputs/convergence.nc (dims method, n, replica, quantity; wall_time over method, n,
replica, scene), outputs/convergence.png (log-log error of the curve against wall time, one
line per method, one panel per scene) and outputs/convergence.md (table for the README:
error reached at 1 s and 10 s, time to reach 1 % and 0.1 %, speed-up against the grid; shown in
docs/performance.md).
"""

from __future__ import annotations

import os

# idle OpenMP threads sleep instead of spinning: with other processes on the cores a spinning
# thread steals the time its partner needs, and small parallel regions then take milliseconds
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse
import math
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numba
import numpy as np
import xarray as xr
from scipy import optimize

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scenarios"))  # the Fig. 13 path of its scene
from constant_normal_shear import shear_path  # noqa: E402
from timing import REPEAT_BELOW, REPEATS, timed  # noqa: E402 - studies/timing.py, beside this script

from asperity_sim import __version__, paths, Population, presets, reference, simulate, SolverSettings
from asperity_sim.analysis import gridmethod
from asperity_sim.solve.pruning import simulate_pruned  # noqa: E402

OUTPUTS = Path(__file__).resolve().parent.parent / "outputs"
SETTINGS = SolverSettings(rtol=1e-9)
S, D = paths.STRESS, paths.DISPLACEMENT


@dataclass
class Scene:
    params: object
    path: paths.LoadPath
    kind: str  # "fig13", "fig11" or "closure"
    grid_scales: tuple
    quantities: tuple = field(default=())


def scenes(quick=False):
    inc13, inc11 = (4, 3) if quick else (20, 10)
    coarse = (4.0, 3.0) if quick else (4.0, 2.0)  # a smoke run's grids: two sizes, a sixth of the points of s = 2
    big = () if quick else (1.4, 1.0)
    fine = () if quick else (0.7, 0.5)
    out = {
        "fig13_R1": Scene(presets.R1, shear_path(500e6, 50e-6, inc13), "fig13", coarse + big[1:]),
        "fig13_S1": Scene(presets.S1, shear_path(500e6, 50e-6, inc13), "fig13", coarse + big[1:]),
        "fig11_R1": Scene(presets.R1, paths.three_step(15e-6, inc11), "fig11", coarse + big + fine[:1]),
        "closure_R1": Scene(presets.R1, paths.LoadPath((paths.Stage((S, D, D), (500e6, 0.0, 0.0), inc13,
                                                                    name="normal loading"),), name="closure"),
                            "closure", coarse + big),
    }
    q = {"fig13": ("curve", "delta1_500MPa", "sigma2_10um", "sigma2_50um", "delta1_curve"),
         "fig11": ("curve", "sigma1_p1", "sigma1_p2", "sigma2_p2", "sigma1_p3", "sigma2_p3", "sigma3_p3"),
         "closure": ("curve", "delta1_500MPa")}
    for sc in out.values():
        sc.quantities = q[sc.kind]
    return out


# ------------------------------------------------------------------------------------------
# reference along the nominal steps of a path (quadrature; stress-controlled Delta_1 by Brent)
# ------------------------------------------------------------------------------------------


def nominal_steps(path):
    """(stage, prescribed mask, displacement targets, stress targets) of every nominal step.

    Stress targets of a stage start from the stress reached at its start, which for the paths
    here is the previous stage's target (0 at the start)."""
    steps = [(0, np.zeros(3, bool), np.zeros(3), np.zeros(3))]
    x, s = np.zeros(3), np.zeros(3)
    for i_st, st in enumerate(path.stages, 1):
        free = st.stress_controlled
        end = np.asarray(st.target, dtype=float)
        x0, s0 = x.copy(), s.copy()
        for i in range(1, st.increments + 1):
            f = i / st.increments
            x = np.where(free, x, x0 + f * (end - x0))
            s = np.where(free, s0 + f * (end - s0), 0.0)
            steps.append((i_st, free.copy(), x.copy(), s.copy()))
    return steps


def reference_path(params, path):
    """Quadrature displacement and stress (steps, 3) at the nominal steps of ``path``."""
    disp, stress = [], []
    guess = 0.0
    for _, free, x, s in nominal_steps(path):
        d = x.copy()
        if free[0] and s[0] != 0.0:
            target = s[0]

            def resid(v, d=d):
                dd = d.copy()
                dd[0] = v
                return reference.stress(params, dd)[0] - target

            lo, hi = guess * 0.9, max(guess * 1.1, params.beta)
            while resid(lo) > 0.0:
                lo *= 0.5
            while resid(hi) < 0.0:
                hi *= 1.5
            d[0] = optimize.brentq(resid, lo, hi, xtol=1e-16, rtol=1e-13)
            guess = d[0]
        disp.append(d)
        stress.append(reference.stress(params, d))
    return np.array(disp), np.array(stress)


def match_steps(ds, path):
    """Indices of the recorded steps at the nominal steps (cut-backs add steps in between)."""
    stage = ds["stage"].values
    disp, sig = ds["displacement"].values, ds["stress"].values
    idx = []
    for i_st, free, x, s in nominal_steps(path):
        cand = np.flatnonzero(stage == i_st)
        scale_x = max(np.abs(x).max(), 1e-9)
        scale_s = max(np.abs(s).max(), 1.0)
        mis = [max(np.max(np.abs(disp[j][~free] - x[~free]), initial=0.0) / scale_x,
                   np.max(np.abs(sig[j][free] - s[free]), initial=0.0) / scale_s) for j in cand]
        j = int(cand[int(np.argmin(mis))])
        if min(mis) > 1e-6:
            raise RuntimeError(f"no recorded step matches nominal step of stage {i_st} (mismatch {min(mis):.3g})")
        idx.append(j)
    return np.array(idx)


def errors(kind, disp, sig, ref_disp, ref_sig, stage):
    """Relative errors of the scene's quantities (dict), from values at the nominal steps."""

    def rel(a, b):
        return abs(a - b) / abs(b)

    out = {}
    if kind == "fig13":
        shear = stage >= 2
        i1, i10, i50 = int(np.flatnonzero(stage == 1)[-1]), int(np.flatnonzero(stage == 2)[-1]), len(stage) - 1
        res, res_ref = sig[shear, 1] / sig[shear, 0], ref_sig[shear, 1] / ref_sig[shear, 0]
        out["curve"] = float(np.max(np.abs(res - res_ref) / np.abs(res_ref)))
        out["delta1_500MPa"] = rel(disp[i1, 0], ref_disp[i1, 0])
        out["sigma2_10um"] = rel(sig[i10, 1], ref_sig[i10, 1])
        out["sigma2_50um"] = rel(sig[i50, 1], ref_sig[i50, 1])
        out["delta1_curve"] = float(np.max(np.abs(disp[shear, 0] - ref_disp[shear, 0]) / np.abs(ref_disp[shear, 0])))
    elif kind == "fig11":
        ends = [int(np.flatnonzero(stage == k)[-1]) for k in (1, 2, 3)]
        shear = stage >= 2
        res = np.hypot(sig[shear, 1], sig[shear, 2]) / sig[shear, 0]
        res_ref = np.hypot(ref_sig[shear, 1], ref_sig[shear, 2]) / ref_sig[shear, 0]
        out["curve"] = float(np.max(np.abs(res - res_ref) / np.abs(res_ref)))
        out["sigma1_p1"] = rel(sig[ends[0], 0], ref_sig[ends[0], 0])
        out["sigma1_p2"] = rel(sig[ends[1], 0], ref_sig[ends[1], 0])
        out["sigma2_p2"] = rel(sig[ends[1], 1], ref_sig[ends[1], 1])
        out["sigma1_p3"] = rel(sig[ends[2], 0], ref_sig[ends[2], 0])
        out["sigma2_p3"] = rel(sig[ends[2], 1], ref_sig[ends[2], 1])
        out["sigma3_p3"] = rel(sig[ends[2], 2], ref_sig[ends[2], 2])
    else:
        load = stage >= 1
        out["curve"] = float(np.max(np.abs(disp[load, 0] - ref_disp[load, 0]) / np.abs(ref_disp[load, 0])))
        out["delta1_500MPa"] = rel(disp[-1, 0], ref_disp[-1, 0])
    return out


# ------------------------------------------------------------------------------------------
# methods
# ------------------------------------------------------------------------------------------


def run_mc(scene, n, seed, sampler):
    t0 = time.perf_counter()
    pop = Population.sample(scene.params, n, seed=seed, sampler=sampler)
    ds = simulate(scene.params, scene.path, population=pop, settings=SETTINGS)
    return ds, time.perf_counter() - t0


def run_pruned(scene, n, seed, sampler):
    t0 = time.perf_counter()
    ds = simulate_pruned(scene.params, scene.path, n, seed=seed, sampler=sampler, settings=SETTINGS)
    return ds, time.perf_counter() - t0


def run_grid(scene, s, full_tangent=True):
    ds = gridmethod.simulate_grid(scene.params, scene.path, gridmethod.GridResolution.scaled(s), rtol=SETTINGS.rtol,
                                  full_tangent=full_tangent)
    return ds, ds.attrs["wall_time_s"]



METHODS = {
    "mc": lambda sc, n, seed: run_mc(sc, n, seed, "random"),
    "rqmc": lambda sc, n, seed: run_mc(sc, n, seed, "sobol"),
    "pruned": lambda sc, n, seed: run_pruned(sc, n, seed, "sobol"),
    "pruned_mc": lambda sc, n, seed: run_pruned(sc, n, seed, "random"),
}
GRIDS = {"grid": True, "grid_forces": False}  # grid method -> full_tangent (True: Step 4 as published)
BASELINES = {"grid": "the paper's grid method (Steps 1-5 as published, tangent at every increment)",
             "grid_forces": "the grid with the lighter Step 4 (grid_forces: no tangent unless iterating)"}


def replicas_for(n, replicas):
    return replicas if n <= 2**20 else max(2, replicas - 1)


def warm_up():
    """Compile or load every kernel once (not timed)."""
    sc = scenes(quick=True)
    for s in sc.values():
        run_mc(s, 512, 0, "sobol")
        run_pruned(s, 512, 0, "sobol")
        gridmethod.simulate_grid(s.params, s.path, gridmethod.GridResolution.scaled(8.0), rtol=1e-6)


def load_average():
    try:
        return os.getloadavg()
    except OSError:
        return (math.nan,) * 3


# ------------------------------------------------------------------------------------------
# summaries: interpolation, table, figure
# ------------------------------------------------------------------------------------------


def frontier(t, e):
    """Points (time, error) sorted by time with the error replaced by its running minimum."""
    ok = np.isfinite(t) & np.isfinite(e) & (e > 0)
    t, e = np.asarray(t)[ok], np.asarray(e)[ok]
    o = np.argsort(t)
    return t[o], np.minimum.accumulate(e[o])


def error_at(t, e, t_star):
    """Log-log interpolated best error reached within t_star [s] (nan before the first point)."""
    t, e = frontier(t, e)
    if t.size == 0 or t_star < t[0]:
        return math.nan
    if t_star >= t[-1]:
        return float(e[-1])
    return float(np.exp(np.interp(math.log(t_star), np.log(t), np.log(e))))


def time_to(t, e, e_star):
    """Log-log interpolated wall time [s] to reach the error e_star (nan if never reached)."""
    t, e = frontier(t, e)
    if t.size == 0 or e[-1] > e_star:
        return math.nan
    k = int(np.argmax(e <= e_star))
    if k == 0:
        return float(t[0])
    # e falls from e[k-1] > e_star to e[k] <= e_star between t[k-1] and t[k]
    x = (math.log(e_star) - math.log(e[k - 1])) / (math.log(e[k]) - math.log(e[k - 1]))
    return float(math.exp(math.log(t[k - 1]) + x * (math.log(t[k]) - math.log(t[k - 1]))))


def fmt_e(v):
    return "—" if not math.isfinite(v) else f"{v:.1e}"


def fmt_ratio(v):
    return " — |" if not math.isfinite(v) else f" {v:.2g}x |" if v < 10 else f" {v:.0f}x |"


def fmt_t(v):
    return "—" if not math.isfinite(v) else (f"{v:.2f} s" if v < 10 else f"{v:.0f} s")


def summary_table(res, sc_names, methods):
    others = [m for m in methods if m not in GRIDS]

    def curve(m, sc):
        """(mean wall time, RMS curve error) over n of method m on scene sc."""
        return (res["mean_wall_time"].sel({"method": m, "scene": sc}).values,
                res["rms_error"].sel({"method": m, "quantity": f"{sc}/curve"}).values)

    lines = ["| scene | method | error at 1 s | error at 10 s | time to 1 % | time to 0.1 % |",
             "|---|---|---|---|---|---|"]
    for sc in sc_names:
        for m in methods:
            t, e = curve(m, sc)
            lines.append(f"| {sc} | {m} | {fmt_e(error_at(t, e, 1.0))} | {fmt_e(error_at(t, e, 10.0))} | "
                         f"{fmt_t(time_to(t, e, 1e-2))} | {fmt_t(time_to(t, e, 1e-3))} |")
    out = lines
    for grid in (g for g in GRIDS if g in methods):
        out += speedup_tables(curve, res, sc_names, others, grid)
    return "\n".join(out)


def speedup_tables(curve, res, sc_names, others, grid):
    """Speed-ups of the methods ``others`` against the grid method ``grid``, at fixed errors and at its runs."""
    speed = ["", f"Speed-up against {BASELINES[grid]} at equal error (time of the grid / time of the "
             "method, both interpolated on the error-time frontier of the curve error; — where a method "
             "does not reach the error):", "",
             f"| scene | error | {grid} time | " + " | ".join(others) + " |",
             "|---|---|---|" + "---|" * len(others)]
    for sc in sc_names:
        tg, eg = curve(grid, sc)
        for e_star in (1e-2, 1e-3, 1e-4):
            t_grid = time_to(tg, eg, e_star)
            row = [f"| {sc} | {e_star:.0e} | {fmt_t(t_grid)} |"]
            for m in others:
                tm = time_to(*curve(m, sc), e_star)
                ratio = t_grid / tm if math.isfinite(t_grid) and math.isfinite(tm) else math.nan
                row.append(fmt_ratio(ratio))
            speed.append("".join(row))
    own = ["", f"Speed-up at the error of each {grid} run (its resolution s relative to the paper's, s = 1 "
           "published; time of that grid run / time the method needs for the same curve error):", "",
           f"| scene | grid s | grid error | {grid} time | " + " | ".join(others) + " |",
           "|---|---|---|---|" + "---|" * len(others)]
    for sc in sc_names:
        tg, eg = curve(grid, sc)
        sg = res["grid_scale"].sel({"scene": sc}).values
        for i in np.flatnonzero(np.isfinite(tg) & np.isfinite(eg)):
            row = [f"| {sc} | {sg[i]:g} | {eg[i]:.1e} | {fmt_t(tg[i])} |"]
            for m in others:
                tm = time_to(*curve(m, sc), eg[i])
                ratio = tg[i] / tm if math.isfinite(tm) else math.nan
                row.append(fmt_ratio(ratio))
            own.append("".join(row))
    return speed + own


def plot(res, sc_names, methods, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ncol = min(2, len(sc_names))
    nrow = (len(sc_names) + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 4.0 * nrow), squeeze=False)
    style = {"mc": "o-", "rqmc": "s-", "pruned": "^-", "pruned_mc": "v--", "grid": "D:", "grid_forces": "d:"}
    for ax in axes.flat[len(sc_names):]:
        ax.set_visible(False)
    for ax, sc in zip(axes.flat, sc_names):
        for m in methods:
            t = res["mean_wall_time"].sel({"method": m, "scene": sc}).values
            e = res["rms_error"].sel({"method": m, "quantity": f"{sc}/curve"}).values
            ok = np.isfinite(t) & np.isfinite(e) & (e > 0)
            o = np.argsort(t[ok])
            ax.loglog(t[ok][o], e[ok][o], style.get(m, "x-"), label=m, ms=4)
        for lvl in (1e-2, 1e-3):
            ax.axhline(lvl, color="0.8", lw=0.8, zorder=0)
        ax.set_title(sc)
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel("curve error (max relative, RMS)")
        ax.grid(True, which="major", alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    plt.close(fig)


# ------------------------------------------------------------------------------------------
# main
# ------------------------------------------------------------------------------------------


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny smoke run (small n, coarse grids, short paths)")
    ap.add_argument("--n-max", type=int, default=2**22, help="largest sample size (default 2^22)")
    ap.add_argument("--replicas", type=int, default=4, help="replicas (seeds) per sample size (default 4)")
    ap.add_argument("--methods", default="mc,rqmc,pruned,pruned_mc,grid,grid_forces",
                    help="comma-separated subset of mc, rqmc, pruned, pruned_mc, grid, grid_forces")
    ap.add_argument("--scenes", default="fig13_R1,fig13_S1,fig11_R1,closure_R1")
    ap.add_argument("--outdir", type=Path, default=OUTPUTS)
    args = ap.parse_args(argv)
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    for m in methods:
        if m not in METHODS and m not in GRIDS:
            ap.error(f"--methods: {m!r} is not known (valid: {', '.join(list(METHODS) + list(GRIDS))})")
    all_scenes = scenes(args.quick)
    sc_names = [s.strip() for s in args.scenes.split(",") if s.strip()]
    for s in sc_names:
        if s not in all_scenes:
            ap.error(f"--scenes: {s!r} is not known (valid: {', '.join(all_scenes)})")
    if args.replicas < 1 or args.n_max < 1024:
        ap.error("--replicas must be >= 1 and --n-max >= 1024")
    n_max = min(args.n_max, 2**12) if args.quick else args.n_max
    replicas = min(args.replicas, 2) if args.quick else args.replicas
    ns = [2**m for m in range(10, 31, 2) if 2**m <= n_max]
    args.outdir.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    load_start = load_average()
    print(f"load average at start: {load_start[0]:.2f} {load_start[1]:.2f} {load_start[2]:.2f}; "
          f"{numba.get_num_threads()} numba threads", flush=True)
    warm_up()

    # grid sizes join the n axis (number of grid points of one stress evaluation)
    grid_rows = {}
    if any(m in GRIDS for m in methods):
        for name in sc_names:
            sc = all_scenes[name]
            for s in sc.grid_scales:
                rule = gridmethod.grid_rule(sc.params, gridmethod.GridResolution.scaled(s))
                grid_rows[(name, s)] = rule.n_points
    n_axis = sorted(set(ns) | set(grid_rows.values()))
    quantities = [f"{name}/{q}" for name in sc_names for q in all_scenes[name].quantities]
    err = np.full((len(methods), len(n_axis), replicas, len(quantities)), np.nan)
    wall = np.full((len(methods), len(n_axis), replicas, len(sc_names)), np.nan)
    grid_scale = np.full((len(n_axis), len(sc_names)), np.nan)

    refs = {}
    for name in sc_names:
        sc = all_scenes[name]
        t = time.perf_counter()
        refs[name] = reference_path(sc.params, sc.path)
        print(f"reference {name}: {time.perf_counter() - t:.1f} s", flush=True)

    def record(im, i_n, rep, name, ds, seconds):
        sc = all_scenes[name]
        ref_disp, ref_sig = refs[name]
        if "stress_evaluations" in ds.attrs:  # grid: nominal steps only
            idx = np.arange(ds.sizes["step"])
        else:
            idx = match_steps(ds, sc.path)
        stage = np.array([st for st, *_ in nominal_steps(sc.path)])
        e = errors(sc.kind, ds["displacement"].values[idx], ds["stress"].values[idx], ref_disp, ref_sig, stage)
        for q, v in e.items():
            err[im, i_n, rep, quantities.index(f"{name}/{q}")] = v
        wall[im, i_n, rep, sc_names.index(name)] = seconds
        return e["curve"]

    for im, m in enumerate(methods):
        for name in sc_names:
            sc = all_scenes[name]
            if m in GRIDS:
                for s in sc.grid_scales:
                    i_n = n_axis.index(grid_rows[(name, s)])
                    ds, seconds = timed(lambda: run_grid(sc, s, GRIDS[m]))
                    c = record(im, i_n, 0, name, ds, seconds)
                    grid_scale[i_n, sc_names.index(name)] = s
                    print(f"{m:11s} {name:10s} s = {s:<4g} ({ds.attrs['grid_points']:.3g} points) "
                          f"{seconds:8.2f} s  curve error {c:.2e}", flush=True)
                continue
            for n in ns:
                i_n = n_axis.index(n)
                cs, ts = [], []
                for rep in range(replicas_for(n, replicas)):
                    ds, seconds = timed(lambda: METHODS[m](sc, n, 1000 * rep + 17))
                    cs.append(record(im, i_n, rep, name, ds, seconds))
                    ts.append(seconds)
                print(f"{m:11s} {name:10s} n = {n:<8d} {np.mean(ts):8.2f} s  curve error (RMS) "
                      f"{math.sqrt(np.mean(np.square(cs))):.2e}", flush=True)
    load_end = load_average()
    total = time.perf_counter() - t_start
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # (method, n) pairs not run are all-NaN: NaN
        rms = np.sqrt(np.nanmean(err**2, axis=2))
        mean_wall = np.nanmean(wall, axis=2)
    count = np.sum(np.isfinite(err[..., 0]), axis=2)
    q_scene = [q.split("/")[0] for q in quantities]
    res = xr.Dataset(
        {
            "error": (("method", "n", "replica", "quantity"), err,
                      {"units": "1", "long_name": "relative error against the quadrature reference"}),
            "wall_time": (("method", "n", "replica", "scene"), wall,
                          {"units": "s", "long_name": "wall time of the run (sampling and simulation)",
                           "note": f"median of {REPEATS} timings of the same run when shorter than {REPEAT_BELOW} s"}),
            "rms_error": (("method", "n", "quantity"), rms,
                          {"units": "1", "long_name": "RMS over replicas of the relative error"}),
            "mean_wall_time": (("method", "n", "scene"), mean_wall,
                               {"units": "s", "long_name": "mean wall time over replicas"}),
            "replicas": (("method", "n"), count.astype("i4"), {"units": "1", "long_name": "replicas run"}),
            "grid_scale": (("n", "scene"), grid_scale,
                           {"units": "1", "long_name": "grid spacing relative to the paper's (grid method)"}),
        },
        coords={"method": methods, "n": np.array(n_axis, dtype=np.int64), "replica": np.arange(replicas),
                "quantity": quantities, "scene": sc_names,
                "quantity_scene": ("quantity", q_scene, {"long_name": "scene of the quantity"})},
        attrs={
            "title": "Error against run time (issue 5)",
            "source": f"asperity_sim {__version__}, studies/convergence.py",
            "history": f"{datetime.now(timezone.utc).isoformat(timespec='seconds')} python studies/convergence.py "
                       + " ".join(argv if argv is not None else sys.argv[1:]),
            "Conventions": "CF-1.8",
            "numba_threads": numba.get_num_threads(),
            "load_average_start": list(load_start),
            "load_average_end": list(load_end),
            "total_wall_time_s": total,
            "newton_rtol": SETTINGS.rtol,
            "n_note": "n is the sample size (Monte Carlo) or the grid points of one evaluation (grid)",
            "paths": "; ".join(f"{k}: {v.path.describe()}" for k, v in all_scenes.items() if k in sc_names),
        },
    )
    res.to_netcdf(args.outdir / "convergence.nc")
    plot(res, sc_names, methods, args.outdir / "convergence.png")
    table = summary_table(res, sc_names, methods) if any(m in GRIDS for m in methods) else ""
    cpu = subprocess.run(["nproc"], capture_output=True, text=True).stdout.strip()
    header = (f"Study run on {cpu} cores, {numba.get_num_threads()} numba threads, load average "
              f"{load_start[0]:.2f} at the start and {load_end[0]:.2f} at the end, total {total / 60:.1f} min. "
              "Error: max over the curve of the relative error against the quadrature, RMS over replicas.\n\n")
    (args.outdir / "convergence.md").write_text(header + table + "\n")
    print(header + table)
    print(f"wrote {args.outdir / 'convergence.nc'}, {args.outdir / 'convergence.png'}, "
          f"{args.outdir / 'convergence.md'} in {total / 60:.1f} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
