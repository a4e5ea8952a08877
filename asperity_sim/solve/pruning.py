"""Height-band pruning: sample only the heights a scene can reach (issue 5).

Owns :func:`simulate_pruned`, which samples the height band a path can reach
(the bound, the band and its check are in :mod:`asperity_sim.sampling.band`) (``Population.sample(..., r_max=)``),
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
:func:`asperity_sim.kernels.evaluate.evaluate` (weight p / n; see tests/test_pruning.py).

Stress-controlled components are not known before the run.  :func:`simulate_pruned` takes
them from a small pilot run (or from ``delta_bound``), widens the band by a margin, and
after the run checks the recorded path; a violation (or a failed run) widens the band to
what the path needed and runs again.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import SimulationError
from ..params import InterfaceParams
from ..paths import LoadPath
from ..sampling.band import band_for_path, check_band, reach_along
from ..sampling.distributions import band_probability
from ..sampling.population import Population
from .driver import simulate


def _pilot_path(path: LoadPath, increments: int = 5) -> LoadPath:
    """The same stages with at most ``increments`` increments each (for a pilot run)."""
    import dataclasses

    return LoadPath(tuple(dataclasses.replace(st, increments=min(st.increments, increments)) for st in path.stages),
                    name=path.name + "_pilot")


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
