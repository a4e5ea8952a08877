"""Shared plumbing of the scenario scripts: command line, reference curves, summaries."""

from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numba
import numpy as np
from scipy import optimize

from asperity_sim import reference
from asperity_sim.checks import check_real

OUTPUTS = Path(__file__).resolve().parent.parent / "outputs"


def parse_args(description, n_default, argv=None, extra=None):
    """Common options: --n, --seed, --increments, --outdir, --no-reference, --quick."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--n", type=int, default=n_default, help=f"asperities sampled per interface (default {n_default})")
    p.add_argument("--seed", type=int, default=2024, help="random seed (default 2024)")
    p.add_argument("--sampler", default="random", choices=("random", "sobol"))
    p.add_argument("--increments", type=int, default=None, help="increments per stage")
    p.add_argument("--outdir", type=Path, default=OUTPUTS, help="folder for .nc and .png (default outputs/)")
    p.add_argument("--no-reference", action="store_true", help="skip the quadrature reference curves")
    p.add_argument("--quick", action="store_true", help="tiny run for smoke tests")
    if extra:
        extra(p)
    args = p.parse_args(argv)
    try:
        if args.n < 1:
            raise ValueError(f"--n = {args.n} is out of range (valid range: integer >= 1)")
        if args.seed < 0:
            raise ValueError(f"--seed = {args.seed} is out of range (valid range: integer >= 0)")
        if args.increments is not None and args.increments < 1:
            raise ValueError(f"--increments = {args.increments} is out of range (valid range: integer >= 1)")
    except ValueError as err:
        p.error(str(err))
    if args.quick:
        args.n = min(args.n, 2000)
    return args


def _attrs(units, long_name):
    return {"units": units, "long_name": long_name}


def add_reference(ds, params, level="default", threads=None):
    """Add the quadrature solution of the same path (``paper`` law, policy ``follow``).

    At every recorded step the displacement-controlled components are taken as recorded
    and each stress-controlled component is solved (one at most, by Brent's method) so
    that the quadrature stress equals the recorded target.  Adds ``reference_stress``
    (step, axis) [Pa] and ``reference_displacement`` (step, axis) [m].

    The steps are independent, so they are solved ``threads`` at a time (default: numba's
    thread count; the quadrature kernel releases the GIL), and within a step no displacement is
    integrated twice (Brent's method starts from the bracket's ends, and its root is one of the
    points it evaluated): the same numbers as one step after the other, in less time.
    """
    disp = ds["displacement"].values
    control = ds["control"].values.astype(bool)
    sig = ds["stress"].values
    if (control.sum(axis=1) > 1).any():
        raise ValueError("the reference handles one stress-controlled component at a time")
    threads = numba.get_num_threads() if threads is None else threads
    with ThreadPoolExecutor(max_workers=max(1, threads)) as pool:
        steps = list(pool.map(lambda i: _reference_step(params, disp[i], control[i], sig[i], level),
                              range(disp.shape[0])))
    ref_s = np.array([s for s, _ in steps]).reshape(sig.shape)
    ref_d = np.array([d for _, d in steps]).reshape(disp.shape)
    ds["reference_stress"] = (("step", "axis"), ref_s,
                              _attrs("Pa", "quadrature reference stress (paper law, policy follow)"))
    ds["reference_displacement"] = (("step", "axis"), ref_d,
                                    _attrs("m", "quadrature reference displacement (paper law, policy follow)"))
    return ds


def _reference_step(params, disp, control, sig, level):
    """(stress, displacement) of the quadrature at one step of :func:`add_reference`."""
    d = disp.copy()
    free = np.flatnonzero(control)
    if free.size == 0 or sig[free[0]] == 0.0:
        return reference.stress(params, d, level=level), d
    k, target = int(free[0]), sig[free[0]]
    known = {}  # stress at each displacement integrated, by the value (sign of zero included) of d[k]

    def stress_at(x):
        key = (x, math.copysign(1.0, x))
        if key not in known:
            dd = d.copy()
            dd[k] = x
            known[key] = reference.stress(params, dd, level=level)
        return known[key]

    def resid(x):
        return stress_at(x)[k] - target

    # bracket around the Monte Carlo solution, widening until the sign changes
    width = max(abs(d[k]) * 0.05, params.beta)
    lo, hi = d[k] - width, d[k] + width
    for _ in range(60):
        if resid(lo) < 0.0 < resid(hi):
            break
        lo, hi = lo - width, hi + width
        width *= 2.0
    d[k] = optimize.brentq(resid, lo, hi, xtol=1e-15, rtol=1e-13)
    return stress_at(float(d[k])).copy(), d


def z_scores(ds):
    """(Monte Carlo - reference) / standard error for stresses and displacements, per step and axis."""
    with np.errstate(divide="ignore", invalid="ignore"):
        zs = (ds["stress"] - ds["reference_stress"]) / ds["stress_stderr"]
        zd = (ds["displacement"] - ds["reference_displacement"]) / ds["displacement_stderr"]
    return zs.where(ds["stress_stderr"] > 0), zd.where(ds["displacement_stderr"] > 0)


class Timer:
    def __enter__(self):
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.seconds = time.perf_counter() - self.t0


def fmt(value, se, scale, unit):
    if se == 0 or not math.isfinite(se):
        return f"{value * scale:10.4g} {unit}"
    return f"{value * scale:10.4g} ± {se * scale:.2g} {unit}"


def check_positive(name, value):
    return check_real(name, value, 0.0, None, lo_open=True)
