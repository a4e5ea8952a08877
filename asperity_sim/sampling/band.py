"""The height band a load path can reach: sample only asperities that can touch (SPEC §3–§4).

Owns the bound on the heights that can touch along a path (:func:`reach_height`,
:func:`reach_along`), the band chosen for a path and the check that a finished run stayed in
it.  :func:`asperity_sim.solve.pruning.simulate_pruned` runs a path on such a band.

The bound.  An asperity of height r, angle theta and azimuth phi has
delta_n = cos(theta) (Delta_1 - r) + sin(theta) (cos(phi) Delta_2 + sin(phi) Delta_3)
        <= cos(theta) (Delta_1 - r) + sin(theta) |Delta_s|,   |Delta_s| = hypot(Delta_2, Delta_3),
so it can touch only if r < Delta_1 + |Delta_s| tan(theta) (for theta < pi/2).  Every angle
in use is at most theta_m(c, R_lo), R_lo = max(R_m - 3 R_sigma, 0) the lower end of the
radius support: under policy follow theta = (2/pi) u theta_m(c, R) <= theta_m(c, R_lo), and a
frozen (``birth``) angle was theta_m at an earlier closure, so the running maximum of c covers
it.  Along a straight segment between two recorded displacements, Delta_1 is linear and
|Delta_s| convex, so both are at most their larger end value (:func:`reach_along`).
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import closure
from ..params import InterfaceParams
from ..paths import LoadPath


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
    c = float(closure(params, delta_1))
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
    c_run = np.maximum.accumulate(closure(params, d[:, 0]))
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


def check_band(params: InterfaceParams, displacements, r_band: float) -> tuple[bool, float]:
    """(safe, needed): is r_band >= the bound of the recorded path, and that bound [m]."""
    need = reach_along(params, displacements)
    return bool(r_band >= need), need
