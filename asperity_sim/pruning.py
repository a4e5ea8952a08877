"""Height-band pruning: sample only the heights a scene can reach (issue 5).

Owns the bound on the heights that can touch along a load path, the choice of a height
band for a scene, the check that a finished run stayed inside its band, and
:func:`simulate_pruned`, which samples the band (``Population.sample(..., r_max=)``),
runs the path, checks it and re-runs with a wider band if the check fails
(detect and correct).  An asperity above the band is never stored.

The bound (SPEC §3–§4).  An asperity of height r, angle theta and azimuth phi has
delta_n = cos(theta) (Delta_1 - r) + sin(theta) (cos(phi) Delta_2 + sin(phi) Delta_3)
        <= cos(theta) (Delta_1 - r) + sin(theta) |Delta_s|,   |Delta_s| = hypot(Delta_2, Delta_3),
so it can touch only if r < Delta_1 + |Delta_s| tan(theta) (for theta < pi/2).  Every angle
in use is at most theta_m(c, R_lo), R_lo = max(R_m - 3 R_sigma, 0) the lower end of the
radius support (Eq. 9 grows as R falls and as the closure c grows): under policy follow
theta = (2/pi) u theta_m(c, R) <= theta_m(c, R_lo), and a frozen (``birth``) angle was
theta_m at an earlier closure, so the running maximum of c covers it.  This includes the
shear-induced contacts of inclined asperities above the closure.  It holds for every
population drawn from the parameters, not only the one sampled.

Along a straight segment between two recorded displacements, Delta_1 is linear and
|Delta_s| convex, so both are at most their larger end value; with the running maximum of
the closure this gives a bound for the whole segment (:func:`reach_along`).  So a run whose
band edge is at least the bound of every segment of its recorded path could not have
touched any asperity above the band, at the recorded steps or between them: the band
estimate N (p / n) sum f, p = P(r <= r_band), is then the full Monte Carlo estimator of
Eq. (23) restricted to samples that can contribute, unbiased, with the standard error of
:func:`asperity_sim.assemble.evaluate` (weight p / n; see tests/test_pruning.py).

Stress-controlled components are not known before the run.  :func:`simulate_pruned` takes
them from a small pilot run (or from ``delta_bound``), widens the band by a margin, and
after the run checks the recorded path; a violation (or a failed run) widens the band to
what the path needed and runs again.
"""

from __future__ import annotations

import math

import numpy as np

from .driver import SimulationError, simulate
from .params import InterfaceParams
from .paths import LoadPath
from .population import Population, band_probability

__all__ = ["theta_bound", "reach_height", "reach_along", "band_for_path", "check_band", "simulate_pruned"]


def _R_low(params: InterfaceParams) -> float:
    """Smallest relative radius the truncated Gaussian of SPEC §2 can produce [m]."""
    lo, _ = params.R_bounds
    return lo if params.R_sigma > 0.0 else params.R_m


def theta_bound(params: InterfaceParams, closure: float) -> float:
    """Largest contact angle [rad] at closure c [m]: theta_m(c, R_lo) of Eq. (9)."""
    R_lo = _R_low(params)
    if R_lo <= 0.0:
        return 0.5 * math.pi
    y = 1.0 - params.k_e * max(closure, 0.0) / R_lo
    return math.acos(min(max(y, 0.0), 1.0))


def reach_height(params: InterfaceParams, delta_1: float, shear: float, closure_max: float | None = None) -> float:
    """Height bound [m]: no asperity with r >= bound touches at (Delta_1, |Delta_s| = shear).

    ``closure_max`` [m] (default c of Delta_1) is the largest closure met so far on the
    path (covers frozen birth angles).  inf when the angle bound reaches pi/2 under shear.
    """
    c = max(0.0, params.r_o + delta_1)
    if closure_max is not None:
        c = max(c, closure_max)
    shear = abs(shear)
    if shear == 0.0:
        return delta_1
    th = theta_bound(params, c)
    if th >= 0.5 * math.pi - 1e-12:
        return math.inf
    return delta_1 + shear * math.tan(th)


def reach_along(params: InterfaceParams, displacements) -> float:
    """Height bound [m] for a piecewise-linear path through ``displacements`` (m, 3) [m], from 0.

    Segment by segment: max Delta_1 of its ends + max |Delta_s| of its ends times
    tan(theta_m(c_max, R_lo)), c_max the running maximum of the closure.
    """
    d = np.atleast_2d(np.asarray(displacements, dtype=float))
    d = np.vstack([np.zeros((1, 3)), d])
    shear = np.hypot(d[:, 1], d[:, 2])
    c_run = np.maximum.accumulate(np.maximum(0.0, params.r_o + d[:, 0]))
    bound = 0.0
    for i in range(1, d.shape[0]):
        d1 = max(d[i - 1, 0], d[i, 0])
        s = max(shear[i - 1], shear[i])
        bound = max(bound, reach_height(params, d1, s, closure_max=c_run[i]))
        if math.isinf(bound):
            return bound
    return bound


def band_for_path(params: InterfaceParams, path: LoadPath, delta_bound=None, margin: float = 0.0) -> float:
    """Band edge [m] for ``path``: the bound of :func:`reach_along` over its stage ends, times 1 + margin.

    Displacement-controlled components are read off the stage targets (exact: the path is
    linear in them between stage ends).  A component that is stress controlled in any stage
    takes ``delta_bound[k]`` [m] at every stage end: an upper bound of Delta_1, or of
    |Delta_k| for a shear component, over the whole path (e.g. from a pilot run).  Without
    it the band is inf (no pruning).
    """
    free_any = np.zeros(3, bool)
    for st in path.stages:
        free_any |= st.stress_controlled
    if free_any.any():
        if delta_bound is None:
            return math.inf
        delta_bound = np.asarray(delta_bound, dtype=float)
        if delta_bound.shape != (3,) or not np.all(np.isfinite(delta_bound[free_any])):
            return math.inf
    ends = []
    cur = np.zeros(3)
    for stage in path.stages:
        cur = np.where(stage.stress_controlled, cur, np.asarray(stage.target, dtype=float))
        ends.append(np.where(free_any, delta_bound if free_any.any() else 0.0, cur))
    b = reach_along(params, np.array(ends))
    return b * (1.0 + margin)


def _pilot_path(path: LoadPath, increments: int = 5) -> LoadPath:
    """The same stages with at most ``increments`` increments each (for a pilot run)."""
    import dataclasses

    return LoadPath(tuple(dataclasses.replace(st, increments=min(st.increments, increments)) for st in path.stages),
                    name=path.name + "_pilot")


def check_band(params: InterfaceParams, displacements, r_band: float) -> tuple[bool, float]:
    """(safe, needed): is r_band >= the bound of the recorded path, and that bound [m]."""
    need = reach_along(params, displacements)
    return bool(r_band >= need), need


def simulate_pruned(params: InterfaceParams, path: LoadPath, n: int, seed: int | None = 0,
                    sampler: str = "random", *, delta_bound=None, pilot_n: int = 4096, margin: float = 0.05,
                    max_runs: int = 4, **kwargs):
    """Run ``path`` on a population sampled from the reachable height band only.

    1. Band: :func:`band_for_path` from the displacement targets and, for stress-controlled
       components, ``delta_bound`` or else a pilot run (``pilot_n`` asperities, sobol) whose
       recorded displacements are widened by ``margin``.
    2. Sample ``Population.sample(params, n, seed, sampler, r_max=band)`` (weight p/n) and run.
    3. Check the recorded path with :func:`check_band`; if the band was too narrow (or the run
       failed inside it), widen it to what the path needed times (1 + margin) and run again.
       When the bound is inf the band is the whole density (no pruning).

    Returns the Dataset of :func:`asperity_sim.simulate` with attributes ``height_band_m``,
    ``height_band_probability``, ``height_band_needed_m``, ``height_band_runs`` and
    ``height_band_pilot`` added.  ``kwargs`` go to :func:`asperity_sim.simulate`.
    """
    if not isinstance(params, InterfaceParams):
        raise ValueError(f"params = {params!r} is not an InterfaceParams")
    if not isinstance(path, LoadPath):
        raise ValueError(f"path = {path!r} is not a LoadPath")
    if not (isinstance(margin, (int, float)) and math.isfinite(margin) and margin >= 0.0):
        raise ValueError(f"margin = {margin!r} is out of range (valid range: >= 0)")
    stress_controlled = any(st.stress_controlled.any() for st in path.stages)
    pilot = False
    if stress_controlled and delta_bound is None:
        pop_p = Population.sample(params, pilot_n, seed=None if seed is None else seed + 7919, sampler="sobol")
        try:
            ds_p = simulate(params, _pilot_path(path), population=pop_p, **kwargs)
            d = ds_p["displacement"].values
            band = band_for_path(params, path, delta_bound=np.max(np.abs(d), axis=0), margin=margin)
        except SimulationError:
            band = math.inf
        pilot = True
    else:
        band = band_for_path(params, path, delta_bound=delta_bound, margin=margin)
    runs = 0
    while True:
        runs += 1
        full = not math.isfinite(band) or band_probability(params, band) >= 1.0 or runs >= max_runs
        pop = Population.sample(params, n, seed=seed, sampler=sampler, r_max=None if full else band)
        try:
            ds = simulate(params, path, population=pop, **kwargs)
        except SimulationError as err:
            if full:
                raise
            # the band may have starved the interface: widen it to what the partial run needed
            got = err.dataset["displacement"].values if err.dataset is not None else np.zeros((1, 3))
            band = max(reach_along(params, got), band) * 2.0
            continue
        safe, need = check_band(params, ds["displacement"].values, pop.r_band)
        if safe:
            break
        band = need * (1.0 + margin)
    ds.attrs.update({
        "height_band_m": float(pop.r_band),
        "height_band_probability": pop.weight * pop.n,
        "height_band_needed_m": float(need),
        "height_band_runs": runs,
        "height_band_pilot": int(pilot),
    })
    return ds
