"""Fitting the model to a surface: InterfaceParams and populations from measured summits.

Owns :func:`fit` (heights, radii and their densities from the summits of a composite surface,
by moments, at the scale of a chosen or automatic cutoff, with its scale diagnosis and warnings),
:func:`empirical_population` (a population resampled from the measured summits) and the scene
file written for a fit.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import special, stats

from ...checks import check_choice, check_int, check_real
from ...errors import SurfaceError, SurfaceScaleWarning
from ...params import InterfaceParams
from .diagnosis import ScaleReport, scale_report
from .scale import auto_cutoff, height_step, s_filter
from .summits import IDENTIFIED, MIN_SUMMITS, NOT_IDENTIFIED, Summits, find_summits
from .topography import Surface, as_surface, composite

# -- fit ----------------------------------------------------------------------------------

def _moments_fit(depth, radius):
    """(alpha, beta, R_m, R_sigma) of samples of depths [m] and radii [m] (method of moments)."""
    m, v = depth.mean(axis=-1), depth.var(axis=-1, ddof=1)
    return m * m / v - 1.0, v / m, radius.mean(axis=-1), radius.std(axis=-1, ddof=1)


def _truncnorm_cdf(x, R_m, R_sigma):
    lo, hi = max(R_m - 3 * R_sigma, 0.0), R_m + 3 * R_sigma
    a, b = special.ndtr((lo - R_m) / R_sigma), special.ndtr((hi - R_m) / R_sigma)
    return np.clip((special.ndtr((x - R_m) / R_sigma) - a) / (b - a), 0.0, 1.0)


@dataclass(frozen=True)
class FitResult:
    """The fit of a composite topography.

    params : InterfaceParams (identified fields fitted, others from ``source_of_rest``)
    stderr : {field: standard error} for the identified fields [units of the field]
    goodness : {"heights": KS statistic of depths vs gamma, "radii": KS of radii vs truncated Gaussian,
               "n": summits, "spearman_depth_radius": rank correlation of depth and radius, 0 if
               independent as SPEC §2 assumes} [1]
    summits : Summits
    identified, not_identified : field names; source_of_rest : e.g. "preset R1"
    surface : the composite Surface at the fit's scale (filtered at the cutoff, if any)
    settings : detrend, min_prominence, window, cutoff, bootstrap size, seed
    scale : ScaleReport, at which scale the fit describes the surface, and its warnings
    pair : with two surfaces, :func:`.pair.pair_statistics` at the scene's closure (e and the contact
           slopes with their standard errors; e is then fitted), else None
    """

    params: InterfaceParams
    stderr: dict
    goodness: dict
    summits: Summits
    identified: tuple = IDENTIFIED
    not_identified: tuple = NOT_IDENTIFIED
    source_of_rest: str = "preset R1"
    surface: Surface | None = None
    settings: dict = field(default_factory=dict)
    scale: ScaleReport | None = None
    pair: dict | None = None

    def source_of(self, name: str) -> str:
        """Where the value of parameter ``name`` came from (one line, for scene comments)."""
        s = self.settings
        k = 2 * s.get("window", 1) + 1
        how = {"N": f"summits ({k}x{k}-window maxima) per unit area",
               "alpha": "gamma fit of summit depths below the highest summit (method of moments)",
               "beta": "gamma fit of summit depths below the highest summit (method of moments)",
               "R_m": "mean of summit radii 1/kappa, kappa = -(h_xx + h_yy)/2",
               "R_sigma": "s.d. of summit radii 1/kappa, kappa = -(h_xx + h_yy)/2",
               "summit_offset": "mean summit height above the mean height of the surface"}
        if name in how:
            from ...units import format_quantity

            unit = InterfaceParams.units()[name]
            se = format_quantity(self.stderr[name], unit) if unit != "1" else f"{self.stderr[name]:.3g}"
            how_se = "Poisson, sqrt(n)/area" if name == "N" else f"bootstrap, {s.get('bootstrap')} resamples"
            return f"fitted: {how[name]}; stderr {se} ({how_se})"
        if name == "e" and self.pair is not None:
            return (f"fitted from the two surfaces: ratio of their mean curvatures at the {self.pair['n_contacts']} "
                    f"summits in contact at {self.pair['closure'] * 1e6:.3g} um (the e of the mean k_e); stderr "
                    f"{self.pair['e_stderr']:.2g} (bootstrap, {s.get('bootstrap')} resamples)")
        return f"not identified from topography: {self.source_of_rest}"


def _scaled(surf, cutoff, window, min_prominence):
    """(surface at the fit's scale, cutoff [m] or None, choice, note, ladder) for ``cutoff`` None, "auto" or a
    length [m] (a number, or a string such as "50 nm")."""
    if cutoff is None:
        return surf, None, "none", "", ()
    if isinstance(cutoff, str) and cutoff.strip().lower() == "auto":
        c, ladder, note = auto_cutoff(surf, window, min_prominence)
        return s_filter(surf, c), c, "auto", note, ladder
    if isinstance(cutoff, str):
        from ...units import parse_quantity

        try:
            cutoff = parse_quantity(cutoff, "m", "cutoff")
        except ValueError as err:
            raise SurfaceError(f"{err} (or auto)") from None
    c = check_real("cutoff [m]", cutoff, 0.0, None, lo_open=True, error=SurfaceError)
    note = "given: Gaussian S-filter (ISO 16610-61), 50 % transmission at the cutoff"
    return s_filter(surf, c), c, "given", note, ()


def fit(topography, other=None, *, base: InterfaceParams | str = "R1", detrend_mode: str = "plane",
        min_prominence: float = 0.0, window: int = 1, bootstrap: int = 200, seed: int = 0,
        base_label: str | None = None, cutoff: float | str | None = None,
        closure: float | None = None) -> FitResult:
    """Fit N, alpha, beta, R_m, R_sigma to the summits of a topography (or of two, summed), and
    summit_offset (the height of the summits' mean plane above the surface's) to its heights.

    topography, other : Surface, SurfaceTopography Topography or file name
    base : preset name or InterfaceParams giving the parameters topography does not identify
    base_label : where ``base`` came from, for the report (e.g. "scene my.toml")
    min_prominence [m], window [pixels] : summit definition (:func:`find_summits`)
    cutoff : short-wavelength cutoff [m] of the Gaussian S-filter applied to the composite before
        the summits are found (:func:`~asperity_sim.analysis.surfaces.scale.s_filter`), "auto"
        (:func:`~asperity_sim.analysis.surfaces.scale.auto_cutoff`) or None (the raw map)
    bootstrap : resamples of the summits for the standard errors (>= 10)
    closure [m] : with two surfaces, the closure at which e and the contact slopes are measured (default:
        the scene's, :func:`default_closure`); e is then fitted (:mod:`.pair`)

    The result's ``scale`` says at which scale the fit describes the surface; each threshold it
    passes is also issued as a :class:`~asperity_sim.errors.SurfaceScaleWarning`.
    """
    from ... import presets

    if isinstance(base, str):
        check_choice("preset", base, tuple(presets.TABLE1), error=SurfaceError)
        rest, source = presets.TABLE1[base], f"preset {base}"
    elif isinstance(base, InterfaceParams):
        rest, source = base, base_label or "given parameters"
    else:
        raise SurfaceError(f"base = {base!r} is not a preset name or InterfaceParams")
    bootstrap = check_int("bootstrap", bootstrap, 10, error=SurfaceError)
    inputs = [as_surface(s) for s in (topography, other) if s is not None]
    raw = composite(inputs[0], inputs[1] if len(inputs) > 1 else None, detrend_mode)
    surf, cut, choice, note, ladder = _scaled(raw, cutoff, window, min_prominence)
    summits = find_summits(surf, min_prominence, window)
    if summits.n < MIN_SUMMITS:
        raise SurfaceError(f"{surf.source}: {summits.n} summits found, too few to fit "
                           f"(valid range: at least {MIN_SUMMITS}; lower --min-prominence, --window or --cutoff, "
                           f"or use a larger map)")
    depth, radius = summits.depth, summits.radius
    if not np.var(depth) > 0:
        raise SurfaceError(f"{surf.source}: all summits at the same height: the height distribution cannot be fitted")
    alpha, beta, R_m, R_sigma = _moments_fit(depth, radius)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, summits.n, size=(int(bootstrap), summits.n))
    # the depth reference is the highest summit of each resample
    bd = summits.height[idx].max(axis=1, keepdims=True) - summits.height[idx]
    ba, bb, bm, bs = _moments_fit(bd, radius[idx])
    # the surface's mean plane lies max(summit heights) - mean(h) below the highest summit: the mean
    # summit depth (alpha+1) beta plus the summits' offset above that plane
    below_top = summits.height.max() - float(np.nanmean(surf.heights))
    offset = max(below_top - (alpha + 1.0) * beta, 0.0)
    b_offset = summits.height[idx].max(axis=1) - float(np.nanmean(surf.heights)) - (ba + 1.0) * bb
    stderr = {"N": math.sqrt(summits.n) / summits.area, "alpha": float(ba.std(ddof=1)), "beta": float(bb.std(ddof=1)),
              "R_m": float(bm.std(ddof=1)), "R_sigma": float(bs.std(ddof=1)),
              "summit_offset": float(np.std(b_offset, ddof=1))}
    try:
        params = rest.replace(N=summits.density, alpha=float(alpha), beta=float(beta), R_m=float(R_m),
                              R_sigma=float(R_sigma), summit_offset=float(offset))
    except ValueError as err:
        raise SurfaceError(f"{surf.source}: fitted parameters are not valid: {err}") from None
    ks_h = stats.kstest(depth, stats.gamma(params.alpha + 1.0, scale=params.beta).cdf).statistic
    ks_r = stats.kstest(radius, lambda x: _truncnorm_cdf(x, params.R_m, params.R_sigma)).statistic \
        if params.R_sigma > 0 else float("nan")
    # SPEC §2 takes heights and radii independent: their rank correlation over the summits tests that
    rho = stats.spearmanr(depth, radius).statistic
    goodness = {"heights": float(ks_h), "radii": float(ks_r), "n": summits.n, "spearman_depth_radius": float(rho)}
    settings = {"detrend": detrend_mode, "min_prominence": float(min_prominence), "window": int(window),
                "cutoff": cut, "bootstrap": int(bootstrap), "seed": int(seed), "source": surf.source}
    report = scale_report(surf, summits, raw=raw, steps=[height_step(s.heights, s.mask) for s in inputs],
                          window=window, cutoff=cut, cutoff_choice=choice, cutoff_note=note, ladder=ladder)
    for message in report.warnings:
        warnings.warn(f"{surf.source}: {message}", SurfaceScaleWarning, stacklevel=2)
    pair = None
    if len(inputs) > 1:  # two surfaces: e and the contact slopes (only second differences of h1 are used,
        from .pair import pair_statistics  # so its detrending, plane or mean, does not matter)

        at = default_closure(params) if closure is None else check_real("closure [m]", closure, 0.0, None, lo_open=True)
        first = composite(inputs[0], None, detrend_mode)
        first = first if cut is None else s_filter(first, cut)  # at the fit's scale, as the summits
        pair = pair_statistics(first, summits, params, at, bootstrap, seed)
        params, stderr = params.replace(e=pair["e"]), {**stderr, "e": pair["e_stderr"]}
    return FitResult(params, stderr, goodness, summits, source_of_rest=source, surface=surf, settings=settings,
                     scale=report, pair=pair)


# -- empirical population --------------------------------------------------------------

def empirical_population(result: FitResult, n: int, seed: int = 0, joint: bool = True):
    """A Population that resamples the identified summits jointly (height, radius and slope together).

    Each of the n asperities is one summit drawn with replacement: r its depth [m], R its radius [m].
    ``joint=False`` draws the depth, the radius and the slope of each asperity from three
    independent draws instead: the data's marginals under the model's independence assumption
    (SPEC §2), so comparing the two isolates the effect of that assumption.
    Orientation: with two surfaces, u = (pi/2) F^-1(slope rank), the model's marginal of u
    (Eq. 10 with the base b, c, d) at the mid-rank of the summit's slope, and phi the azimuth
    of grad h1, so u keeps the data's dependence on r and R; with one surface (all slopes 0)
    u and phi are drawn from the model's density independently, as in the parametric model.
    """
    from ...sampling.distributions import orientation_from_uniform
    from ...sampling.population import Population

    n = check_int("n", n, 1, error=SurfaceError)
    s = result.summits
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, s.n, size=int(n))
    pick_R, pick_u = (pick, pick) if joint else (rng.integers(0, s.n, size=int(n)), rng.integers(0, s.n, size=int(n)))
    p = result.params
    if np.any(s.slope > 0):
        rank = (stats.rankdata(s.slope) - 0.5) / s.n
        u, _ = orientation_from_uniform(p, 1.0 - rank[pick_u], np.zeros(n))  # steeper: larger u
        phi = s.azimuth[pick_u]
    else:
        u, phi = orientation_from_uniform(p, rng.random(n), rng.random(n))
    return Population.from_arrays(p, s.depth[pick], s.radius[pick_R], u, phi)


# -- scene and figure -------------------------------------------------------------------

def _toml_string(text: str) -> str:
    return '"' + str(text).replace("\\", "\\\\").replace('"', '\\"') + '"'


def default_closure(params: InterfaceParams, fraction: float = 0.1) -> float:
    """Closure [m] at which the fraction ``fraction`` of the summits (the highest) has been reached:
    the gamma quantile of the depths (SPEC §2)."""
    return float(stats.gamma.ppf(fraction, params.alpha + 1.0, scale=params.beta))


def scene_text(result: FitResult, *, closure: float | None = None, increments: int = 20, n: int = 100_000,
               seed: int = 0, command: str = "") -> str:
    """A scene file (TOML, units on every quantity, a comment on where each value came from).

    The path is a normal closure under displacement control, Delta_1 from 0 to ``closure`` [m]
    (default: the depth of the highest 10 % of the summits, :func:`default_closure`).
    """
    from ...units import format_quantity
    from .pair import scene_comments as pair_comments

    p = result.params
    closure = default_closure(p) if closure is None else check_real("closure [m]", closure, 0.0, None, lo_open=True)
    units = InterfaceParams.units()
    s, g = result.settings, result.goodness
    lines = [f"# Scene fitted by asperity_sim.analysis.surfaces from {s.get('source', '?')}",
             f"# {command}" if command else "#",
             f"# {g['n']} summits (maxima of {2 * s.get('window', 1) + 1}x{2 * s.get('window', 1) + 1} windows, "
             f"min prominence {s.get('min_prominence', 0):.3g} m, "
             f"detrend {s.get('detrend')}); KS statistic of depths vs gamma {g['heights']:.3f}, "
             f"of radii vs truncated Gaussian {g['radii']:.3f}; rank correlation of depth and radius "
             f"{g['spearman_depth_radius']:.3f} (the model takes them independent)",
             *(f"# {line}" for line in (result.scale.lines() if result.scale is not None else ())),
             *(f"# WARNING: {w}" for w in (result.scale.warnings if result.scale is not None else ())),
             *(pair_comments(result.pair) if result.pair is not None else []),
             f"# Parameters not identified by a topography come from {result.source_of_rest}.",
             "# Run:  asperity-sim run THIS_FILE.toml",
             f"title = {_toml_string('normal closure of the fitted interface (' + str(s.get('source', '?')) + ')')}",
             "", "[parameters]"]
    for name, unit in units.items():
        v = getattr(p, name)
        value = _toml_string(format_quantity(v, unit)) if unit != "1" else repr(float(v))
        lines.append(f"{name} = {value}  # {result.source_of(name)}")
    lines += ["", "[run]", f"n = {int(n)}", f"seed = {int(seed)}", 'sampler = "random"', 'law = "paper"',
              'policy = "follow"', "", "[path]", 'name = "normal_closure"', "", "[[path.stages]]",
              'name = "normal closure"', f"increments = {int(increments)}",
              f"Delta_1 = {_toml_string(format_quantity(closure, 'm'))}  # depth reached by 10 % of the summits",
              'Delta_2 = "0 um"', 'Delta_3 = "0 um"', ""]
    return "\n".join(lines)
