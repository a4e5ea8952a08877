"""Error against run time for the history law ``mdr`` on a cyclic path, jointly in n and k (issue 23, item 6).

Physical question: how many asperities n and how many springs per contact k does a given
accuracy of a cyclic response of the history law cost, in wall time?  Unlike the ``paper``
law (studies/convergence.py) there is no quadrature for a history law, so the reference
is a much larger run, and the error has two parts: the Monte Carlo (sampling) error, which
falls with n, and the spring discretisation error of the MDR law, which falls with k.

Scene (R1 preset, law "mdr", policy follow, sampler "sobol": scrambled Sobol' points, n = 2^m):
  stage 1         sigma_1 to 300 MPa in 10 increments (stress control, held afterwards);
  stages 2-4      first cycle  Delta_2: 0 -> +2 um (16 increments) -> -2 um (32) -> 0 (16);
  stages 5-7      second cycle, the same (the stable Masing loop).
Quantities:
  peak_resistance     max over the first loading branch (stage 2) of sigma_2 / sigma_1 [1];
  cycle_dissipation   increase of the recorded ``dissipation`` over the last cycle [J m-2]
                      (from the last step before stage 5 to the end of stage 7).
Error of a run: (x - x_ref) / x_ref; the error of an (n, k) point is the RMS over replicas
(different seeds), so it is measured, not guessed.  It is split into
  k_error   (x(n, k) - x(n, k_ref)) / x_ref with the same population (same seed), mean over
            replicas: the spring discretisation error alone;
  mc_error  (x(n, k_ref) - x_ref) / x_ref, RMS over replicas: the sampling error alone.
Reference: the mean of ``--ref-replicas`` (4) independent runs at n_ref = 2^20 and k_ref = 64
(seeds disjoint from the grid's); its uncertainty is the standard error of that mean (replica
spread / sqrt(replicas)); its own spring error is estimated from the grid as
|x(k=32) - x(k=64)| / 3 at the largest n (second order in k: see outputs/mdr_k_convergence.md).
The recorded iid standard error (``stress_stderr``) of the reference peak is kept too, as an
indicator: for Sobol' points it overstates the actual error.

Grid: n = 2^10 ... 2^18 (every power of two, --n-max), k = 2, 4, 8, 16, 32 and k_ref = 64;
replicas 8 up to n = 2^14, 6 at 2^15, 4 at 2^16 and 2^17, 3 at 2^18 (--replicas scales the 8).
Cheapest (n, k) reaching a relative error e*: the (n, k) of smallest mean wall time whose RMS
error is <= e* and stays <= e* at every larger n with the same k (so a lucky draw of few
replicas does not count); the table also gives the choice by the 90 % upper confidence bound
of the RMS (chi-squared with r replicas), since an RMS from 8 replicas is itself uncertain by ~25 %.
Wall time: Population.sample + simulate, warm numba cache (every kernel is run once before
timing), ONE numba thread (--threads, default 1; numba.set_num_threads), OMP_WAIT_POLICY=PASSIVE;
a run shorter than 0.2 s is run three times and its median time kept (runs are
deterministic), as in studies/convergence.py.  The reference runs are timed but are not
part of the grid.

Run:   python studies/mdr_convergence.py            (full study: 14.6 min on one core of this
                                                    shared 2-core machine at load average 2.8-4.6;
                                                    the 4 reference runs, ~110 s each, are half of it)
       python studies/mdr_convergence.py --quick    (smoke run: n = 2^10, 2^11, k = 2, 4, 8,
                                                    short path; a few seconds with a warm cache)
       python studies/mdr_convergence.py --replot   (figure and table again from the netCDF file)
Writes outputs/mdr_convergence.nc (dims n, k, replica, quantity, ref_replica),
outputs/mdr_convergence.png (log-log error against wall time, one line per k and per n;
error split into Monte Carlo and spring parts) and outputs/mdr_convergence.md (cheapest
(n, k) for 1 % and 0.1 % per quantity, with run times, and the sentences for the README).
"""

from __future__ import annotations

import os

# idle OpenMP threads sleep instead of spinning (see studies/convergence.py)
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse
import math
import sys
import time
import warnings
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numba
import numpy as np
import xarray as xr

from timing import REPEAT_BELOW, REPEATS, timed  # studies/timing.py, beside this script

from asperity_sim import __version__, paths, Population, presets, simulate

OUTPUTS = Path(__file__).resolve().parent.parent / "outputs"
S, D = paths.STRESS, paths.DISPLACEMENT
QUANTITIES = ("peak_resistance", "cycle_dissipation")
LONG_NAMES = {"peak_resistance": "peak shear resistance max(sigma_2/sigma_1) over the first loading branch",
              "cycle_dissipation": "energy dissipated over the last shear cycle"}
UNITS = {"peak_resistance": "1", "cycle_dissipation": "J m-2"}
TARGETS = (1e-2, 1e-3)
CONFIDENCE = 0.9  # of the upper bound of an RMS error in the stricter choice of the cheapest point


@dataclass(frozen=True)
class Scene:
    """The cyclic scene: normal loading under stress control, then symmetric shear cycles."""

    sigma_n: float = 300e6  # [Pa]
    amplitude: float = 2e-6  # [m]
    inc_normal: int = 10
    inc_quarter: int = 16  # increments per quarter cycle
    cycles: int = 2

    @property
    def path(self) -> paths.LoadPath:
        stages = [paths.Stage((S, D, D), (self.sigma_n, 0.0, 0.0), self.inc_normal, name="normal loading")]
        q, a = self.inc_quarter, self.amplitude
        for c in range(1, self.cycles + 1):
            stages += [paths.Stage((S, D, D), (self.sigma_n, a, 0.0), q, name=f"cycle {c}: +A"),
                       paths.Stage((S, D, D), (self.sigma_n, -a, 0.0), 2 * q, name=f"cycle {c}: -A"),
                       paths.Stage((S, D, D), (self.sigma_n, 0.0, 0.0), q, name=f"cycle {c}: 0")]
        return paths.LoadPath(tuple(stages), name="mdr_convergence_cycles")


def quantities(ds, cycles):
    """(peak_resistance, its iid standard error, cycle_dissipation [J m-2], energy balance) of one run.

    Stage 2 is the first loading branch; the last cycle is stages 3c-1 .. 3c+1 (c = cycles).
    The standard error is the recorded ``stress_stderr`` of sigma_2 at the peak over sigma_1.
    """
    stage, sig, se = ds["stage"].values, ds["stress"].values, ds["stress_stderr"].values
    branch = np.flatnonzero(stage == 2)
    ratio = sig[branch, 1] / sig[branch, 0]
    i = int(branch[np.argmax(ratio)])
    first, last = 3 * cycles - 1, 3 * cycles + 1
    start = int(np.flatnonzero(stage == first)[0]) - 1
    end = int(np.flatnonzero(stage == last)[-1])
    dis = ds["dissipation"].values
    work = ds["external_work"].values
    bal = np.abs(work - ds["elastic_energy"].values - dis).max() / np.abs(work).max()
    return float(ratio.max()), float(se[i, 1] / sig[i, 0]), float(dis[end] - dis[start]), float(bal)


def run_once(scene, n, k, seed):
    """(dataset, wall time [s]) of sampling and simulating one (n, k, seed)."""
    t0 = time.perf_counter()
    pop = Population.sample(presets.R1, n, seed=seed, sampler="sobol")
    ds = simulate(presets.R1, scene.path, population=pop, law="mdr", k=k)
    return ds, time.perf_counter() - t0



def replicas_for(n, replicas):
    """Replicas at sample size n: ``replicas`` up to 2^14, then fewer (3/4, 1/2, 1/2, 3/8 of it), at least 2."""
    scale = {2**15: 0.75, 2**16: 0.5, 2**17: 0.5}.get(n, 1.0 if n <= 2**14 else 0.375)
    return max(2, int(round(replicas * scale)))


def grid_seed(rep):
    return 1000 * rep + 17


def reference_seed(rep):
    return 10**6 + 7919 * rep


def warm_up(scene, ks, n_large):
    """Compile or load every kernel once (not timed), also the parallel sampler used above 4096 points."""
    short = Scene(scene.sigma_n, scene.amplitude, 2, 2, 2)
    for n in (1024, n_large):
        for k in (min(ks), max(ks)):
            run_once(short, n, k, 1)


def load_average():
    try:
        return os.getloadavg()
    except OSError:
        return (math.nan,) * 3


def study(ns, ks, k_ref, replicas, n_ref, ref_replicas, scene=Scene(), log=print):
    """Run the grid and the reference; return the results as an ``xarray.Dataset`` (see module docstring).

    ns : sample sizes (powers of two); ks : springs per contact, k_ref must be the last;
    replicas : replicas at the smallest sizes (replicas_for); n_ref, ref_replicas : reference runs.
    """
    ks = list(ks)
    if ks[-1] != k_ref or sorted(ks) != ks:
        raise ValueError(f"ks = {ks} must be increasing and end with k_ref = {k_ref}")
    n_rep = max(replicas_for(n, replicas) for n in ns)
    shape = (len(ns), len(ks), n_rep)
    peak, peak_se, dis, bal, wall = (np.full(shape, np.nan) for _ in range(5))
    seeds = np.full((len(ns), n_rep), -1, dtype=np.int64)
    t_start = time.perf_counter()
    load_start = load_average()
    warm_up(scene, ks, max(min(max(ns), 2**15), 8192))
    log(f"warm-up done ({time.perf_counter() - t_start:.1f} s); {numba.get_num_threads()} numba thread(s)")

    ref = np.full((ref_replicas, 5), np.nan)  # peak, peak stderr, dissipation, balance, wall time
    for r in range(ref_replicas):
        ds, seconds = run_once(scene, n_ref, k_ref, reference_seed(r))
        ref[r] = (*quantities(ds, scene.cycles), seconds)
        log(f"reference {r}: n = {n_ref}, k = {k_ref}: peak {ref[r, 0]:.7f}, cycle dissipation "
            f"{ref[r, 2]:.6f} J/m2, {seconds:.1f} s")

    for i_n, n in enumerate(ns):
        for rep in range(replicas_for(n, replicas)):
            seeds[i_n, rep] = grid_seed(rep)
            for i_k, k in enumerate(ks):
                ds, seconds = timed(lambda: run_once(scene, n, k, grid_seed(rep)))
                peak[i_n, i_k, rep], peak_se[i_n, i_k, rep], dis[i_n, i_k, rep], bal[i_n, i_k, rep] = \
                    quantities(ds, scene.cycles)
                wall[i_n, i_k, rep] = seconds
        log(f"n = {n:<7d} {replicas_for(n, replicas)} replicas, mean wall time per k: "
            + " ".join(f"{np.nanmean(wall[i_n, i_k]):.3g}" for i_k in range(len(ks))) + " s")
    total = time.perf_counter() - t_start
    load_end = load_average()
    return assemble(ns, ks, k_ref, n_ref, scene, peak, peak_se, dis, bal, wall, seeds, ref,
                    total=total, load=(load_start, load_end))


def assemble(ns, ks, k_ref, n_ref, scene, peak, peak_se, dis, bal, wall, seeds, ref, total, load):
    """Errors, their split and the reference, as a Dataset with units and long names on every variable."""
    n_ref_rep = ref.shape[0]
    ref_mean = {"peak_resistance": ref[:, 0].mean(), "cycle_dissipation": ref[:, 2].mean()}
    ref_se = {q: (np.std(ref[:, j], ddof=1) / math.sqrt(n_ref_rep) if n_ref_rep > 1 else math.nan)
              for q, j in (("peak_resistance", 0), ("cycle_dissipation", 2))}
    values = {"peak_resistance": peak, "cycle_dissipation": dis}
    err = np.stack([(values[q] - ref_mean[q]) / ref_mean[q] for q in QUANTITIES])  # (quantity, n, k, replica)
    i_ref = ks.index(k_ref)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # replicas not run are NaN
        rms = np.sqrt(np.nanmean(err**2, axis=-1))
        k_err = np.nanmean(err - err[:, :, i_ref:i_ref + 1, :], axis=-1)
        mc_err = np.sqrt(np.nanmean(err[:, :, i_ref, :] ** 2, axis=-1))
        mean_wall = np.nanmean(wall, axis=-1)
    # spring error of the reference itself: |x(k_prev) - x(k_ref)| / (2^2 - 1) at the largest n
    # (second order in k, k_prev = k_ref / 2), when the grid holds k_ref / 2
    if len(ks) > 1 and ks[i_ref - 1] * 2 == k_ref:
        ref_k_err = np.abs(k_err[:, -1, i_ref - 1]) / 3.0
    else:
        ref_k_err = np.full(len(QUANTITIES), np.nan)
    rel_se = np.array([ref_se[q] / abs(ref_mean[q]) for q in QUANTITIES])
    count = np.sum(np.isfinite(wall[:, 0, :]), axis=-1)

    def a(units, long_name, **extra):
        return {"units": units, "long_name": long_name, **extra}

    dims = ("n", "k", "replica")
    res = xr.Dataset(
        {
            "peak_resistance": (dims, peak, a("1", LONG_NAMES["peak_resistance"])),
            "peak_resistance_stderr": (dims, peak_se, a("1", "recorded iid Monte Carlo standard error of sigma_2 "
                                                              "at the peak step over sigma_1 (indicator)")),
            "cycle_dissipation": (dims, dis, a("J m-2", LONG_NAMES["cycle_dissipation"])),
            "energy_balance": (dims, bal, a("1", "max over steps of |external work - elastic energy - dissipation| "
                                                 "/ max external work")),
            "wall_time": (dims, wall, a("s", "wall time of the run (sampling and simulation), one numba thread",
                                        note=f"median of {REPEATS} timings of the same run when shorter "
                                             f"than {REPEAT_BELOW} s")),
            "seed": (("n", "replica"), seeds, a("1", "seed of the population (same population at every k)")),
            "replicas": (("n",), count.astype("i4"), a("1", "replicas run")),
            "error": (("quantity",) + dims, err, a("1", "relative error (x - x_ref) / x_ref")),
            "rms_error": (("quantity", "n", "k"), rms, a("1", "RMS over replicas of the relative error")),
            "k_error": (("quantity", "n", "k"), k_err,
                        a("1", "spring discretisation error: mean over replicas of (x(k) - x(k_ref)) / x_ref, "
                               "same population")),
            "mc_error": (("quantity", "n"), mc_err,
                         a("1", "Monte Carlo error: RMS over replicas of (x(k_ref) - x_ref) / x_ref")),
            "mean_wall_time": (("n", "k"), mean_wall, a("s", "mean wall time over replicas, one numba thread")),
            **{f"reference_value_{q}": ((), ref_mean[q], a(UNITS[q], "reference value x_ref of the "
                                                             + LONG_NAMES[q] + ": mean of the reference runs"))
               for q in QUANTITIES},
            "reference_rel_stderr": (("quantity",), rel_se,
                                     a("1", "standard error of the reference mean over its value "
                                            "(replica spread / sqrt(replicas))")),
            "reference_rel_k_error": (("quantity",), ref_k_err,
                                      a("1", "estimated spring error of the reference: |x(k_ref/2) - x(k_ref)| / 3 "
                                             "/ x_ref at the largest grid n (second order in k)")),
            "reference_peak_resistance": (("ref_replica",), ref[:, 0], a("1", LONG_NAMES["peak_resistance"]
                                                                         + ", reference runs")),
            "reference_peak_resistance_stderr": (("ref_replica",), ref[:, 1],
                                                 a("1", "recorded iid Monte Carlo standard error of the reference "
                                                        "peak (indicator, overstates the Sobol' error)")),
            "reference_cycle_dissipation": (("ref_replica",), ref[:, 2], a("J m-2", LONG_NAMES["cycle_dissipation"]
                                                                           + ", reference runs")),
            "reference_energy_balance": (("ref_replica",), ref[:, 3], a("1", "energy balance of the reference runs")),
            "reference_wall_time": (("ref_replica",), ref[:, 4], a("s", "wall time of the reference runs, "
                                                                        "one numba thread")),
        },
        coords={"n": ("n", np.array(ns, dtype=np.int64), a("1", "asperities sampled (scrambled Sobol' points)")),
                "k": ("k", np.array(ks, dtype=np.int64), a("1", "springs per contact at its largest extent")),
                "replica": ("replica", np.arange(peak.shape[-1]), a("1", "replica (seed) index")),
                "ref_replica": ("ref_replica", np.arange(n_ref_rep), a("1", "reference run index")),
                "quantity": ("quantity", list(QUANTITIES), {"long_name": "quantity of the error"})},
        attrs={
            "title": "Error against run time for the history law mdr on a cyclic path (issue 23, item 6)",
            "source": f"asperity_sim {__version__}, studies/mdr_convergence.py",
            "history": f"{datetime.now(timezone.utc).isoformat(timespec='seconds')} python studies/mdr_convergence.py "
                       + " ".join(sys.argv[1:]),
            "Conventions": "CF-1.8",
            "params": "R1 (asperity_sim.presets.R1)",
            "law": "mdr", "policy": "follow", "sampler": "sobol",
            "path": scene.path.describe(),
            "scene": f"sigma_1 to {scene.sigma_n / 1e6:g} MPa in {scene.inc_normal} increments (stress control, "
                     f"held), then {scene.cycles} cycles Delta_2 = 0 -> +{scene.amplitude * 1e6:g} um -> "
                     f"-{scene.amplitude * 1e6:g} um -> 0, {scene.inc_quarter} increments per quarter cycle",
            "sigma_n_Pa": scene.sigma_n, "amplitude_m": scene.amplitude, "cycles": scene.cycles,
            "inc_normal": scene.inc_normal, "inc_quarter": scene.inc_quarter,
            "k_ref": k_ref, "n_ref": n_ref,
            "reference_definition": f"mean of {n_ref_rep} runs at n = {n_ref}, k = {k_ref}, sampler sobol, "
                                    f"seeds {', '.join(str(reference_seed(r)) for r in range(n_ref_rep))}",
            "numba_threads": numba.get_num_threads(),
            "timing": "Population.sample + simulate, warm numba cache, one numba thread, OMP_WAIT_POLICY="
                      + os.environ.get("OMP_WAIT_POLICY", ""),
            "load_average_start": list(load[0]), "load_average_end": list(load[1]),
            "total_wall_time_s": total,
        },
    )
    return res


# ------------------------------------------------------------------------------------------
# summaries: cheapest point, table, figure (read only the dataset)
# ------------------------------------------------------------------------------------------


def rms_upper(res, quantity, confidence):
    """One-sided upper confidence bound of the RMS error (n, k) from its r replicas: RMS sqrt(r / chi2_r(1 - c)).

    Exact for errors that are normal with zero mean (the Monte Carlo part); a spring error adds a common
    bias, which narrows the spread of the squares, so the bound is then conservative."""
    from scipy import stats

    r = res["replicas"].values.astype(float)[:, None]
    return res["rms_error"].sel(quantity=quantity).values * np.sqrt(r / stats.chi2.ppf(1.0 - confidence, r))


def cheapest(res, quantity, target, confidence=None):
    """(n, k, mean wall time [s], RMS error) of the cheapest (n, k) whose RMS error is <= target and stays
    <= target at every larger n with the same k; None if no point qualifies.  With ``confidence`` (e.g. 0.9)
    the one-sided upper confidence bound of the RMS (:func:`rms_upper`) must be <= target instead."""
    rms = res["rms_error"].sel(quantity=quantity).values  # (n, k)
    e = rms if confidence is None else rms_upper(res, quantity, confidence)
    t = res["mean_wall_time"].values
    best = None
    for i_k, k in enumerate(res.k.values):
        col = e[:, i_k]
        for i_n, n in enumerate(res.n.values):
            tail = col[i_n:]
            if not (np.all(np.isfinite(tail)) and np.all(tail <= target) and math.isfinite(t[i_n, i_k])):
                continue
            if best is None or t[i_n, i_k] < best[2]:
                best = (int(n), int(k), float(t[i_n, i_k]), float(rms[i_n, i_k]))
            break  # larger n at this k only cost more
    return best


def best_achieved(res, quantity):
    """(n, k, mean wall time [s], RMS error) of the smallest RMS error of the grid."""
    e = res["rms_error"].sel(quantity=quantity).values
    i_n, i_k = np.unravel_index(np.nanargmin(e), e.shape)
    return int(res.n.values[i_n]), int(res.k.values[i_k]), float(res["mean_wall_time"].values[i_n, i_k]), \
        float(e[i_n, i_k])


def fmt_n(n):
    m = int(round(math.log2(n)))
    return f"2^{m}" if 2**m == n else str(n)


def pct(v):
    return f"{v * 100:g} %"


def fmt_t(v):
    return "—" if not math.isfinite(v) else (f"{v:.2f} s" if v < 10 else f"{v:.0f} s")


def summary(res):
    """Markdown: setting, reference, table of the cheapest (n, k), error split, sentences for the README."""
    q_title = {"peak_resistance": "peak shear resistance", "cycle_dissipation": "dissipation per cycle"}
    ls, le = res.attrs["load_average_start"], res.attrs["load_average_end"]
    lines = ["# Error against run time for the history law `mdr` (issue 23, item 6)", "",
             f"Scene: R1, law mdr, policy follow, Sobol' sampler; {res.attrs['scene']}.  Peak shear resistance = max "
             "sigma_2/sigma_1 on the first loading branch; dissipation per cycle = increase of the recorded "
             "dissipation over the last (second) cycle.  Error = RMS over replicas of (x - x_ref)/x_ref.  "
             f"Wall time: sampling + simulate, warm numba cache, **{res.attrs['numba_threads']} numba thread**, "
             f"median of {REPEATS} timings for runs under {REPEAT_BELOW} s; load average {float(ls[0]):.2f} at the "
             f"start and {float(le[0]):.2f} at the end (machine shared); study total "
             f"{res.attrs['total_wall_time_s'] / 60:.1f} min.", ""]
    lines += ["Reference: " + res.attrs["reference_definition"] + ".", "",
              "| quantity | x_ref | standard error of x_ref (relative) | spring error of x_ref (est., relative) "
              "| recorded iid stderr (relative, indicator) |", "|---|---|---|---|---|"]
    for q in QUANTITIES:
        x = float(res[f"reference_value_{q}"])
        se = float(res["reference_rel_stderr"].sel(quantity=q))
        ke = float(res["reference_rel_k_error"].sel(quantity=q))
        iid = (f"{float(np.mean(res['reference_peak_resistance_stderr'].values)) / x:.1e}"
               if q == "peak_resistance" else "—")
        lines.append(f"| {q_title[q]} | {x:.6g} {UNITS[q] if UNITS[q] != '1' else ''} | {se:.1e} | {ke:.1e} | "
                     f"{iid} |")
    lines += ["", f"The standard error of x_ref is the spread of the {res.sizes['ref_replica']} reference runs "
              "over sqrt(runs).  Its spring error is estimated as |x(k_ref/2) - x(k_ref)| / 3 at the largest grid n, "
              "i.e. assuming second order in k; where the measured spring error falls faster (table below) this "
              "overstates it.  The recorded iid standard error (from `stress_stderr`, sigma_2 at the peak over "
              "sigma_1) is what plain Monte Carlo with the same n would give; the scrambled Sobol' replicas agree "
              "far more closely, so it is only an indicator.  The reference uncertainty (standard error plus "
              "spring error, both below 2e-4) is at least 5x below the targets 1e-2 and 1e-3."
              if all(float(res["reference_rel_stderr"].sel(quantity=q))
                     + abs(float(res["reference_rel_k_error"].sel(quantity=q))) < 2e-4 for q in QUANTITIES) else
              f"The standard error of x_ref is the spread of the {res.sizes['ref_replica']} reference runs over "
              "sqrt(runs); its spring error is estimated as |x(k_ref/2) - x(k_ref)| / 3 (second order in k)."]
    lines += ["", "Cheapest (n, k) reaching the error: the smallest mean wall time among the points whose RMS "
              "error is at or below it and stays there at every larger n with the same k.  An RMS from r "
              f"replicas is itself uncertain (about ±25 % for r = 8), so the last columns ask the same of its "
              f"one-sided {CONFIDENCE * 100:g} % upper confidence bound, RMS sqrt(r / chi2_r(0.1)) (factor 1.5 for "
              "r = 8, 2.3 for r = 3):", "",
              f"| quantity | target | cheapest (n, k) | run time | RMS error there | cheapest (n, k), {CONFIDENCE * 100:g} % "
              "confidence | run time | RMS error there |", "|---|---|---|---|---|---|---|---|"]
    sentences = []
    for q in QUANTITIES:
        parts = []
        for target in TARGETS:
            c, cc = cheapest(res, q, target), cheapest(res, q, target, CONFIDENCE)
            cells = []
            for x in (c, cc):
                if x is None:
                    n, k, t, e = best_achieved(res, q)
                    cells.append(f"not reached (best: n = {fmt_n(n)}, k = {k}, {e:.1e} in {fmt_t(t)}) | — | —")
                else:
                    cells.append(f"n = {fmt_n(x[0])}, k = {x[1]} | {fmt_t(x[2])} | {x[3]:.1e}")
            lines.append(f"| {q_title[q]} | {pct(target)} | " + " | ".join(cells) + " |")
            if c is None:
                n, k, t, e = best_achieved(res, q)
                parts.append(f"{pct(target)} is not reached on the grid (best {e:.1e} at n = {fmt_n(n)}, k = {k}, "
                             f"{fmt_t(t)})")
            else:
                conf = ("the same point" if cc is not None and cc[:2] == c[:2] else
                        f"n = {fmt_n(cc[0])}, k = {cc[1]}, {fmt_t(cc[2])}" if cc is not None else "not reached")
                smallest = " (the smallest n tried)" if c[0] == int(res.n.values[0]) else ""
                parts.append(f"{pct(target)} needs n = {fmt_n(c[0])}{smallest} asperities and k = {c[1]} springs per contact "
                             f"({fmt_t(c[2])} per run; with {CONFIDENCE * 100:g} % confidence: {conf})")
        sentences.append(f"For the {q_title[q]} of the `mdr` law on a cyclic path (R1, 300 MPa, "
                         f"Delta_2 = ±{res.attrs['amplitude_m'] * 1e6:g} um, Sobol' sampler, one thread), "
                         + " and ".join(parts) + ".")
    # the split of the error
    ks, ns = res.k.values, res.n.values
    lines += ["", "Error split (relative).  Spring error: mean over replicas of (x(k) - x(k_ref))/x_ref at the "
              f"largest n = {fmt_n(int(ns[-1]))}, same populations; Monte Carlo error: RMS over replicas of "
              f"(x(k_ref) - x_ref)/x_ref:", "",
              "| quantity | " + " | ".join(f"k = {k}" for k in ks[:-1]) + " |", "|---|" + "---|" * (len(ks) - 1)]
    for q in QUANTITIES:
        lines.append(f"| {q_title[q]} (spring) | "
                     + " | ".join(f"{v:+.1e}" for v in res["k_error"].sel(quantity=q).values[-1, :-1]) + " |")
    lines += ["", "| quantity | " + " | ".join(f"n = {fmt_n(int(n))}" for n in ns) + " |", "|---|" + "---|" * len(ns)]
    for q in QUANTITIES:
        lines.append(f"| {q_title[q]} (Monte Carlo, k = {int(ks[-1])}) | "
                     + " | ".join(f"{v:.1e}" for v in res["mc_error"].sel(quantity=q).values) + " |")
    lines += ["", "RMS error (rows n, columns k) and mean wall time:", ""]
    for q in QUANTITIES:
        lines += [f"{q_title[q]}:", "", "| n | replicas | " + " | ".join(f"k = {k}" for k in ks) + " |",
                  "|---|---|" + "---|" * len(ks)]
        for i_n, n in enumerate(ns):
            cells = [f"{res['rms_error'].sel(quantity=q).values[i_n, i_k]:.1e} "
                     f"({fmt_t(res['mean_wall_time'].values[i_n, i_k])})" for i_k in range(len(ks))]
            lines.append(f"| {fmt_n(int(n))} | {int(res['replicas'].values[i_n])} | " + " | ".join(cells) + " |")
        lines.append("")
    t = res["mean_wall_time"].values
    lines += [f"Run times: at n = {fmt_n(int(ns[0]))} a run costs {fmt_t(float(t[0, 0]))} (k = {int(ks[0])}) to "
              f"{fmt_t(float(t[0, -1]))} (k = {int(ks[-1])}), much of it per-increment overhead (the same "
              f"{res.attrs['path'].count('stage')}-stage path for every run); at n = {fmt_n(int(ns[-1]))}, "
              f"k = {int(ks[-1])} costs {float(t[-1, -1] / t[-1, 0]):.1f}x k = {int(ks[0])}.  All on one numba thread "
              "of a 2-core machine shared with other jobs (load average above): the times are as measured under "
              "that load.", ""]
    lines += ["## For the README", ""] + sentences
    return "\n".join(lines) + "\n"


def plot(res, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    q_title = {"peak_resistance": "peak shear resistance", "cycle_dissipation": "dissipation per cycle"}
    ks, ns = res.k.values, res.n.values
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.6))
    cmap = plt.get_cmap("viridis")
    t = res["mean_wall_time"].values
    for j, q in enumerate(QUANTITIES):
        ax = axes[0, j]
        e = res["rms_error"].sel(quantity=q).values
        for i_n in range(len(ns)):  # one thin grey line per n, through k
            ok = np.isfinite(e[i_n]) & (e[i_n] > 0)
            ax.loglog(t[i_n, ok], e[i_n, ok], "-", color="0.75", lw=0.7, zorder=1)
            if ok.any():
                ax.annotate(f"n={fmt_n(int(ns[i_n]))}", (t[i_n, ok][-1], e[i_n, ok][-1]), fontsize=6, color="0.45",
                            xytext=(2, -6), textcoords="offset points")
        for i_k, k in enumerate(ks):  # one line per k, through n
            ok = np.isfinite(e[:, i_k]) & (e[:, i_k] > 0)
            ax.loglog(t[ok, i_k], e[ok, i_k], "o-", ms=3.5, color=cmap(i_k / max(1, len(ks) - 1)), label=f"k = {k}",
                      zorder=2)
        floor = 2 * float(res["reference_rel_stderr"].sel(quantity=q))
        if math.isfinite(floor) and floor > 0:
            low = min(float(np.nanmin(np.where(e > 0, e, np.nan))), floor) / 3
            ax.axhspan(low / 1e3, floor, color="C3", alpha=0.12, zorder=0, label="reference uncertainty (2 s.e.)")
            ax.set_ylim(bottom=low)
        for lvl, name in ((1e-2, "1 %"), (1e-3, "0.1 %")):
            ax.axhline(lvl, color="0.5", lw=0.8, ls="--", zorder=0)
            ax.annotate(name, (1, lvl), xycoords=("axes fraction", "data"), xytext=(-22, 2),
                        textcoords="offset points", fontsize=8, color="0.35")
        for target, mk in zip(TARGETS, ("*", "P")):
            c = cheapest(res, q, target)
            if c is not None:
                ax.plot(c[2], c[3], mk, ms=13, mfc="none", mec="C3", mew=1.3, zorder=3,
                        label=f"cheapest for {pct(target)}: n={fmt_n(c[0])}, k={c[1]}")
        ax.set_title(f"{q_title[q]}: error against run time")
        ax.set_xlabel("mean wall time per run [s] (one numba thread)")
        ax.set_ylabel("relative error (RMS over replicas)")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    ax = axes[1, 0]
    for j, q in enumerate(QUANTITIES):
        ax.loglog(ns, res["mc_error"].sel(quantity=q).values, "os"[j] + "-", color=f"C{j}",
                  label=f"{q_title[q]} (k = {int(ks[-1])})")
        se = float(res["reference_rel_stderr"].sel(quantity=q))
        if math.isfinite(se) and se > 0:
            ax.axhline(se, color=f"C{j}", ls=":", lw=0.9, label=f"{q_title[q]}: reference s.e.")
    e0 = float(res["mc_error"].sel(quantity=QUANTITIES[0]).values[0])
    ax.loglog(ns, e0 * (ns / ns[0]) ** -0.5, color="0.6", lw=0.8, ls="--", label="slope n^-1/2")
    ax.loglog(ns, e0 * (ns / ns[0]) ** -1.0, color="0.6", lw=0.8, ls="-.", label="slope n^-1")
    ax.set_xscale("log", base=2)
    ax.set_title(f"Monte Carlo part at k = k_ref = {int(ks[-1])}", fontsize=10)
    ax.set_xlabel("n (asperities)")
    ax.set_ylabel("relative error (RMS over replicas)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    for j, q in enumerate(QUANTITIES):
        v = res["k_error"].sel(quantity=q).values[-1, :-1]
        ax.loglog(ks[:-1], np.abs(v), "os"[j] + "-", color=f"C{j}", label=q_title[q])
        neg = v < 0
        ax.loglog(ks[:-1][neg], np.abs(v[neg]), "os"[j], color="w", mec=f"C{j}", ms=4)
    v0 = abs(float(res["k_error"].sel(quantity=QUANTITIES[0]).values[-1, 0]))
    ax.loglog(ks[:-1], v0 * (ks[:-1] / ks[0]) ** -2.0, color="0.6", lw=0.8, ls="--", label="slope k^-2")
    ax.set_xscale("log", base=2)
    ax.set_title(f"spring part at n = {fmt_n(int(ns[-1]))} (open marker: x(k) < x(k_ref))", fontsize=10)
    ax.set_xlabel("k (springs per contact)")
    ax.set_ylabel(f"|x(k) - x(k = {int(ks[-1])})| / x_ref (mean over replicas)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=7)
    fig.suptitle("mdr law, R1, cyclic shear at 300 MPa: error against run time, jointly in n and k", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    plt.close(fig)


# ------------------------------------------------------------------------------------------
# main
# ------------------------------------------------------------------------------------------


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny smoke run (n = 2^10, 2^11; k = 2, 4, 8; short path)")
    ap.add_argument("--n-max", type=int, default=2**18, help="largest grid sample size (default 2^18)")
    ap.add_argument("--replicas", type=int, default=8, help="replicas at the small sizes (default 8)")
    ap.add_argument("--n-ref", type=int, default=2**20, help="sample size of the reference runs (default 2^20)")
    ap.add_argument("--ref-replicas", type=int, default=4, help="reference runs (default 4)")
    ap.add_argument("--threads", type=int, default=1, help="numba threads (default 1)")
    ap.add_argument("--outdir", type=Path, default=OUTPUTS)
    ap.add_argument("--replot", action="store_true",
                    help="only redraw the figure and rewrite the table from the existing mdr_convergence.nc")
    args = ap.parse_args(argv)
    if args.replot:
        return write_summaries(args.outdir)
    if args.replicas < 2 or args.ref_replicas < 2:
        ap.error("--replicas and --ref-replicas must be >= 2 (an RMS and a standard error need two)")
    if args.n_max < 2**10 or args.n_ref < args.n_max:
        ap.error("--n-max must be >= 1024 and --n-ref >= --n-max")
    if not 1 <= args.threads <= numba.config.NUMBA_NUM_THREADS:
        ap.error(f"--threads must be in [1, {numba.config.NUMBA_NUM_THREADS}]")
    numba.set_num_threads(args.threads)
    if args.quick:
        scene = Scene(inc_normal=4, inc_quarter=4)
        ns, ks, k_ref = [2**10, 2**11], [2, 4, 8], 8
        replicas, n_ref, ref_replicas = 2, 2**12, 2
    else:
        scene = Scene()
        ns = [2**m for m in range(10, 31) if 2**m <= args.n_max]
        ks, k_ref = [2, 4, 8, 16, 32, 64], 64
        replicas, n_ref, ref_replicas = args.replicas, args.n_ref, args.ref_replicas
    args.outdir.mkdir(parents=True, exist_ok=True)
    res = study(ns, ks, k_ref, replicas, n_ref, ref_replicas, scene=scene, log=lambda s: print(s, flush=True))
    res.attrs["history"] = (f"{datetime.now(timezone.utc).isoformat(timespec='seconds')} python "
                            "studies/mdr_convergence.py " + " ".join(argv if argv is not None else sys.argv[1:]))
    nc = args.outdir / "mdr_convergence.nc"
    enc = {v: {"zlib": True, "complevel": 4} for v in res.data_vars}
    res.to_netcdf(nc, engine="netcdf4", encoding=enc)
    write_summaries(args.outdir)
    print(f"wrote {nc} in {res.attrs['total_wall_time_s'] / 60:.1f} min")
    return 0


def write_summaries(outdir):
    """Figure and table from ``outdir/mdr_convergence.nc`` alone (so both can be redrawn from saved results)."""
    nc, png, md = (outdir / f"mdr_convergence.{ext}" for ext in ("nc", "png", "md"))
    with xr.open_dataset(nc, engine="netcdf4") as saved:
        saved.load()
    plot(saved, png)
    text = summary(saved)
    md.write_text(text)
    print(text)
    print(f"wrote {png}, {md}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
