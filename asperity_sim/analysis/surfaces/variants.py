"""Asperity-model variants answering the normal contact of a fitted surface, for the comparison with BEM.

Owns what the model predicts for the exact-contact comparison (``scenarios/exact_contact.py``):
the per-summit geometry a variant may use (:func:`summit_geometry`), populations of Hertzian
asperities with vertical contact normals (e = 0, the small-slope assumption of the
boundary-element solution), the closure and contact-area fraction at given mean pressures with
their Monte Carlo standard errors (:func:`answer`), and the registry :data:`VARIANTS`.

A variant is one function ``solve(fitted, pressures, n, seed) -> Answer``; most build an
asperity population and call :func:`answer`, and a variant that runs the package's solver
instead (``simulate`` with a stress-controlled sigma_1) returns the same :class:`Answer`.

Relations (SPEC §2, §5, §6 with e = 0, so every contact is normal and its overlap is
delta_j = Delta_1 - r_j):  sigma_1 = N E[(4/3) E* sqrt(R_j) delta_j^(3/2)], contact-area fraction
A = N E[pi R_area,j delta_j] (Hertz a² = R delta; R_area = R for a sphere).  At a prescribed
pressure p the closure solves sigma_1(Delta_1) = p (Brent); its standard error is
se(sigma_1)/sigma_1' and the area's, at fixed p, is N sd(a_j - s f_j)/sqrt(n) with
s = A'/sigma_1' (first-order delta method over the n equally weighted independent asperities).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy import optimize

from ... import paths
from ...checks import check_int
from ...errors import SurfaceError
from ...kernels import interaction
from ...sampling.population import Population
from ...solve.driver import simulate
from . import contact_scale, elliptic
from .fitting import FitResult


@dataclass(frozen=True)
class Answer:
    """The model at prescribed mean pressures: closure Delta_1 [m] and contact-area fraction [1], each ± its
    Monte Carlo standard error (arrays over the pressures)."""

    closure: np.ndarray
    closure_se: np.ndarray
    area: np.ndarray
    area_se: np.ndarray


@dataclass(frozen=True)
class SummitGeometry:
    """What a variant may use of each summit (sorted as ``result.summits``, highest first).

    k_max, k_min [1/m]: principal curvatures from the 3 x 3 Hessian; rho [m] (k,): disc radii,
    the first the pixel (stencil values); scale_k_max, scale_k_min [1/m] and scale_depth [m] (n, k):
    the paraboloid fitted over each disc (:mod:`.contact_scale`), its apex as a depth below the
    highest summit.
    """

    k_max: np.ndarray
    k_min: np.ndarray
    rho: np.ndarray
    scale_k_max: np.ndarray
    scale_k_min: np.ndarray
    scale_depth: np.ndarray


@dataclass(frozen=True)
class Fitted:
    """A fitted surface as the variants see it: the fit (its params with e = 0) and its summit geometry."""

    result: FitResult
    geometry: SummitGeometry

    @property
    def params(self):
        return self.result.params.replace(e=0.0)


def summit_geometry(result: FitResult) -> SummitGeometry:
    """Principal curvatures at the pixel and at growing scales for every summit of a fit."""
    s = result.summits
    k_max, k_min = elliptic.principal_curvatures(result.surface, s)
    rho, kM, km, apex = contact_scale.curvature_at_scales(result.surface, s)
    pixel = math.sqrt(s.pixel_size[0] * s.pixel_size[1])
    top = s.height[0]
    return SummitGeometry(k_max, k_min, np.concatenate([[pixel], rho]),
                          np.column_stack([k_max, kM]), np.column_stack([k_min, km]),
                          np.column_stack([s.depth, top - apex]))


def fitted(result: FitResult) -> Fitted:
    return Fitted(result, summit_geometry(result))


# -- populations and their answer ----------------------------------------------------------

@dataclass(frozen=True)
class Hertzian:
    """n equally weighted asperities, N per unit area: depth r [m], Hertz force radius R [m], area radius
    R_area [m] (contact area pi R_area delta), composite modulus E_star [Pa]."""

    r: np.ndarray
    R: np.ndarray
    R_area: np.ndarray
    N: float
    E_star: float

    def terms(self, d):
        """Per-asperity normal force [N] and contact area [m²] at closure d [m]."""
        delta = np.maximum(d - self.r, 0.0)
        return (4.0 / 3.0) * self.E_star * np.sqrt(self.R) * delta**1.5, math.pi * self.R_area * delta


@dataclass(frozen=True)
class AtContactScale:
    """Resampled summits whose paraboloid is the one fitted over a disc of their own contact radius.

    Per summit: depth_table, curvature_table (n_s, k) at the disc radii rho (k,) [m] (the depth of
    the fitted apex below the highest summit, the mean curvature kappa = (k_max + k_min)/2) and
    rho_cap (n_s,) [m], half the distance to the nearest other summit; ``pick`` (n,) the summit of
    each asperity.  At closure d each summit's scale solves rho = a = sqrt(R delta), capped at rho_cap,
    by fixed-point iteration (``iterations``), with R = 1/kappa(rho) and delta = d - depth(rho).
    """

    rho: np.ndarray
    depth_table: np.ndarray
    curvature_table: np.ndarray
    rho_cap: np.ndarray
    pick: np.ndarray
    N: float
    E_star: float
    iterations: int = 8

    @property
    def r(self):
        return self.depth_table[self.pick, 0]

    def terms(self, d):
        a = np.full(self.rho_cap.shape, self.rho[0])
        for _ in range(self.iterations):
            R, delta = self._at(a, d)
            a = np.minimum(np.sqrt(R * delta), self.rho_cap)
        R, delta = self._at(a, d)
        f, area = (4.0 / 3.0) * self.E_star * np.sqrt(R) * delta**1.5, math.pi * R * delta
        return f[self.pick], area[self.pick]

    def _at(self, a, d):
        kappa = contact_scale.radii_at(self.rho, self.curvature_table, a)
        return 1.0 / kappa, np.maximum(d - contact_scale.radii_at(self.rho, self.depth_table, a), 0.0)


def _means(model, d):
    f, a = model.terms(d)
    return model.N * f.mean(), model.N * a.mean()


def closure_at(model, pressure: float) -> float:
    """Closure Delta_1 [m] at which N E[f] equals ``pressure`` [Pa] (Brent)."""
    g = lambda d: _means(model, d)[0] - pressure  # noqa: E731
    hi = max(float(np.partition(model.r, min(10, model.r.size - 1))[min(10, model.r.size - 1)]), 1e-12)
    for _ in range(200):
        if g(hi) > 0.0:
            break
        hi *= 2.0
    return optimize.brentq(g, 0.0, hi, xtol=1e-15, rtol=1e-12)


def answer(model, pressures) -> Answer:
    """Closure and area fraction at each pressure [Pa], with first-order (delta method) standard errors."""
    p = np.atleast_1d(np.asarray(pressures, dtype=float))
    out = np.empty((4, p.size))
    for k, pk in enumerate(p):
        d = closure_at(model, pk)
        f, a = model.terms(d)
        n = f.size
        h = 1e-6 * d
        (s_hi, a_hi), (s_lo, a_lo) = _means(model, d + h), _means(model, d - h)
        ds, da = (s_hi - s_lo) / (2 * h), (a_hi - a_lo) / (2 * h)
        slope = da / ds
        out[:, k] = (d, model.N * f.std(ddof=1) / math.sqrt(n) / ds, model.N * a.mean(),
                     model.N * (a - slope * f).std(ddof=1) / math.sqrt(n))
    return Answer(*out)


# -- the variants --------------------------------------------------------------------------

def _resample(fit: Fitted, n, seed, joint=True):
    s = fit.result.summits
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, s.n, size=n)
    return pick, (pick if joint else rng.integers(0, s.n, size=n))


def _hertzian(fit: Fitted, r, R, R_area):
    p = fit.params
    return Hertzian(np.asarray(r, float), np.asarray(R, float), np.asarray(R_area, float), p.N, p.E_star)


def parametric(fit: Fitted, n, seed):
    """The fitted model as ``asperity-sim fit`` writes it: gamma depths, truncated-Gaussian radii 1/kappa."""
    pop = Population.sample(fit.params, n, seed=seed)
    return _hertzian(fit, pop.r, pop.R, pop.R)


def empirical(fit: Fitted, n, seed):
    """The summits resampled jointly (depth and mean-curvature radius 1/kappa together)."""
    i, _ = _resample(fit, n, seed)
    s = fit.result.summits
    return _hertzian(fit, s.depth[i], s.radius[i], s.radius[i])


def independent(fit: Fitted, n, seed):
    """Depth and radius 1/kappa of the summits resampled independently (SPEC §2's independence)."""
    i, j = _resample(fit, n, seed, joint=False)
    s = fit.result.summits
    return _hertzian(fit, s.depth[i], s.radius[j], s.radius[j])


def elliptic_summits(fit: Fitted, n, seed):
    """The summits resampled jointly, each an elliptic paraboloid: Hertz force and area radii from both
    principal curvatures (:func:`.elliptic.equivalent_radii`)."""
    i, _ = _resample(fit, n, seed)
    g = fit.geometry
    Rf, Ra = elliptic.equivalent_radii(g.k_max[i], g.k_min[i])
    return _hertzian(fit, fit.result.summits.depth[i], Rf, Ra)


def curvature_ratio_fit(k_max, k_min):
    """Beta(a, b) [1] fitted by moments to lambda = k_min / k_max in (0, 1] (k_min <= 0 clipped)."""
    lam = np.clip(k_min / k_max, 1.0 / elliptic.RATIO_CAP, 1.0)
    m, v = lam.mean(), lam.var(ddof=1)
    common = m * (1.0 - m) / v - 1.0
    if not (v > 0 and common > 0):
        raise SurfaceError(f"curvature ratios k_min/k_max (mean {m:.3g}, variance {v:.3g}) cannot be fitted by a "
                           "beta distribution (valid: 0 < variance < mean (1 - mean))")
    return m * common, (1.0 - m) * common


def elliptic_parametric(fit: Fitted, n, seed):
    """Parametric elliptic summits: gamma depths (the fit's), truncated-Gaussian Hertz force radii (moments of
    the summits' R_force), and each asperity's curvature ratio drawn from a beta fitted to the summits',
    independently (R_area = R_force times the ratio's R_area/R_force)."""
    g = fit.geometry
    Rf, _ = elliptic.equivalent_radii(g.k_max, g.k_min)
    params = fit.params.replace(R_m=float(Rf.mean()), R_sigma=float(Rf.std(ddof=1)))
    pop = Population.sample(params, n, seed=seed)
    a, b = curvature_ratio_fit(g.k_max, g.k_min)
    lam = np.random.default_rng([seed, 1]).beta(a, b, size=n)
    rf, ra = elliptic.hertz_elliptic(1.0 / lam)
    return Hertzian(pop.r, pop.R, pop.R * ra / rf, params.N, params.E_star)


def contact_scale_summits(fit: Fitted, n, seed):
    """The summits resampled jointly, each a paraboloid fitted over a disc of its contact radius
    (:class:`AtContactScale`; mean curvature, scale capped at half the distance to the next summit)."""
    i, _ = _resample(fit, n, seed)
    g, p, s = fit.geometry, fit.params, fit.result.summits
    kappa = 0.5 * (g.scale_k_max + g.scale_k_min)
    cap = 0.5 * contact_scale.neighbour_distance(s, fit.result.surface.physical_sizes
                                                 if fit.result.surface.periodic else None)
    # a disc whose paraboloid is no longer convex has left the summit: the scale stops before it
    first_bad = np.argmax(np.column_stack([kappa <= 0.0, np.ones(s.n, bool)]), axis=1)
    cap = np.minimum(cap, g.rho[np.maximum(first_bad - 1, 0)])
    return AtContactScale(g.rho, g.scale_depth, np.maximum(kappa, 1e-300), np.maximum(cap, g.rho[0]), i, p.N,
                          p.E_star)


def with_interaction(solve):
    """``solve`` with the mean-field elastic interaction between contacts (interaction = 1,
    :mod:`asperity_sim.kernels.interaction`): the contacts overlap by Delta_1 + kappa sigma_1, so at a
    pressure p they carry it at the overlaps of ``solve`` and the interface closes kappa p less."""

    def solved(fit: Fitted, pressures, n, seed):
        a = solve(fit, pressures, n, seed)
        shift = interaction.kappa(fit.params.replace(interaction=1.0)) * np.atleast_1d(np.asarray(pressures, float))
        return Answer(a.closure - shift, a.closure_se, a.area, a.area_se)

    return solved


def solver_interaction(fit: Fitted, pressures, n, seed, increments=4):
    """The fitted model with interaction = 1 run through :func:`~asperity_sim.solve.driver.simulate` (paper law,
    e = 0, sigma_1 stress-controlled to each pressure in turn): the package's own Newton solution of the
    interaction, where :func:`with_interaction` applies its closed form to :func:`parametric`."""
    params = fit.params.replace(interaction=1.0)
    p = np.atleast_1d(np.asarray(pressures, float))
    order = np.argsort(p)
    control = (paths.STRESS, paths.DISPLACEMENT, paths.DISPLACEMENT)
    path = paths.LoadPath(tuple(paths.Stage(control, (float(pk), 0.0, 0.0), increments) for pk in p[order]))
    ds = simulate(params, path, population=Population.sample(params, check_int("n", n, 2), seed=seed), law="paper")
    ends = np.searchsorted(ds.stage.values, np.arange(1, p.size + 1), side="right") - 1
    out = np.empty((4, p.size))
    out[:, order] = (ds.displacement.values[ends, 0], ds.displacement_stderr.values[ends, 0],
                     ds.contact_area_fraction.values[ends], ds.contact_area_fraction_stderr.values[ends])
    return Answer(*out)


@dataclass(frozen=True)
class Variant:
    """A model variant: its description and ``solve(fitted, pressures, n, seed) -> Answer``."""

    description: str
    solve: Callable


def _population(build):
    return lambda fit, pressures, n, seed: answer(build(fit, check_int("n", n, 2), seed), pressures)


VARIANTS = {
    "parametric": Variant("the fitted model: gamma depths, truncated-Gaussian radii 1/kappa", _population(parametric)),
    "empirical": Variant("summits resampled jointly (radius 1/kappa)", _population(empirical)),
    "independent": Variant("summit depths and radii resampled independently", _population(independent)),
    "elliptic": Variant("summits resampled jointly, elliptic Hertz (both principal curvatures)",
                        _population(elliptic_summits)),
    "elliptic_parametric": Variant("parametric with elliptic Hertz radii and a beta curvature ratio",
                                   _population(elliptic_parametric)),
    "contact_scale": Variant("summits resampled jointly, paraboloids fitted over discs of the contact radius",
                             _population(contact_scale_summits)),
    "interaction": Variant("the fitted model with the mean-field elastic interaction (simulate, interaction = 1)",
                           solver_interaction),
    "elliptic_interaction": Variant("elliptic summits resampled jointly, with the mean-field elastic interaction",
                                    with_interaction(_population(elliptic_summits))),
}
"""The model variants of the exact-contact comparison, by name (each measured on its own)."""
