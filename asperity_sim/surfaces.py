"""Measured and synthetic surfaces: read topographies, identify summits, fit InterfaceParams.

Owns the route from a topography file (profilometer, AFM, plain-text matrix, netCDF) to the
interface parameters of SPEC §1, and the empirical population that resamples the identified
summits.  Reading and synthetic surfaces use the optional ``SurfaceTopography`` package
(``pip install "asperity-sim[surfaces]"``); everything after reading is numpy.

Definitions (also in docs/surfaces.md)
--------------------------------------
Composite topography
    One surface: its heights.  Two surfaces: the sum h = h1 + h2 of their heights, each
    measured outward from its own body (as a profilometer sees it), on the same grid and
    physical size (SPEC §2: the composite topography).  All lengths are converted to metres.
Detrending
    ``"plane"`` (default) removes the least-squares plane, ``"mean"`` the mean height only,
    ``"none"`` nothing.  Detrending is applied to each surface before the sum.  A periodic
    map (synthetic surfaces) has no plane trend: ``"plane"`` removes its mean only, since
    a tilt removed from it would put a step at its edges.
Summit
    A pixel strictly higher than every other pixel of the (2 window + 1)² square around it
    (``window = 1``, the default: its 8 neighbours; periodic surfaces wrap around, otherwise
    the ``window`` border rows and columns are never summits), whose *local prominence*
    (height minus the highest other pixel of the square) is at least ``min_prominence`` [m]
    (default 0).  A larger window suppresses the one-pixel maxima of instrument noise.
Summit curvature and radius
    kappa = -(h_xx + h_yy)/2 [1/m], the mean of the two principal curvatures, from the
    5-point discrete Laplacian at the summit; radius R = 1/kappa [m].
Summit slope
    With two surfaces, |grad h1| [1] at the composite summit (central differences).  There
    grad h1 = -grad h2, so this is the tilt of the common tangent plane of the two bodies,
    the model's contact orientation theta = arctan(slope); its azimuth phi is the direction
    of grad h1.  With one surface (against a flat) every contact normal is vertical: slope 0.
Model mapping (SPEC §2)
    r = depth of a summit below the highest summit [m]: gamma with shape alpha + 1 and scale
    beta, fitted by the method of moments, beta = var(r)/mean(r), alpha = mean(r)²/var(r) - 1;
    N = summits per unit nominal area [1/m²]; R_m, R_sigma = mean and s.d. of the summit radii.
    Standard errors: bootstrap over summits (N: Poisson, sqrt(n)/A).  Goodness of fit: the
    Kolmogorov–Smirnov statistic of the depths against the fitted gamma and of the radii
    against the fitted truncated Gaussian (parameters estimated from the same data, so the
    usual KS p-value is too large; the statistic is reported, not a test decision).
Not identified
    e, r_o, mu, G, nu, b, c, d cannot be identified from heights alone; they are taken from
    a named preset (default R1) or a given InterfaceParams and reported as such.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import special, stats

from .params import InterfaceParams, check_real

__all__ = ["SurfaceError", "bem_contact", "Summits", "FitResult", "read", "composite", "synthetic", "find_summits", "fit",
           "empirical_population", "spectral_moments", "nayak", "IDENTIFIED", "NOT_IDENTIFIED", "INSTALL_HINT"]

INSTALL_HINT = 'pip install "asperity-sim[surfaces]" (or pip install SurfaceTopography)'
IDENTIFIED = ("N", "alpha", "beta", "R_m", "R_sigma")
NOT_IDENTIFIED = ("mu", "G", "nu", "e", "r_o", "b", "c", "d")
MIN_SUMMITS = 20
SIZE_RTOL = 1e-6  # physical sizes of two files agree to this (netCDF stores them as float32, 6e-8)
DETRENDS = ("plane", "mean", "none")
_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "μm": 1e-6, "nm": 1e-9, "Å": 1e-10,
          "A": 1e-10, "pm": 1e-12}


class SurfaceError(ValueError):
    """A topography that cannot be used; the message names the file or value and what is allowed."""


def _st():
    try:
        import SurfaceTopography
    except ModuleNotFoundError:
        raise SurfaceError(f"reading and generating topographies needs SurfaceTopography: {INSTALL_HINT}") from None
    return SurfaceTopography


def _unit_factor(unit, where) -> float:
    if unit in _UNITS:
        return _UNITS[unit]
    try:
        from SurfaceTopography.Support.UnitConversion import get_unit_conversion_factor

        return float(get_unit_conversion_factor(unit, "m"))
    except Exception:  # noqa: BLE001 - any failure is an unknown unit
        raise SurfaceError(f"{where}unit {unit!r} is not a known length unit (valid: {', '.join(_UNITS)})") from None


@dataclass(frozen=True)
class Surface:
    """A height map in SI: heights (nx, ny) [m] on a grid of physical size (Lx, Ly) [m]."""

    heights: np.ndarray
    physical_sizes: tuple[float, float]
    periodic: bool = False
    source: str = "<array>"
    slopes: tuple | None = None  # (d h1/dx, d h1/dy) [1] of the first surface of a composite

    @property
    def nb_grid_pts(self):
        return self.heights.shape

    @property
    def pixel_size(self):
        return tuple(L / n for L, n in zip(self.physical_sizes, self.heights.shape))

    @property
    def area(self) -> float:
        return self.physical_sizes[0] * self.physical_sizes[1]


def read(path, *, physical_sizes=None, unit=None, channel=None) -> Surface:
    """Read a topography file (any format SurfaceTopography reads) as a :class:`Surface` in metres.

    physical_sizes : (Lx, Ly) in ``unit``, needed when the file does not give them
    unit : length unit of heights and sizes (m, mm, um, nm, ...), needed when the file does not give it
    """
    st = _st()
    path = Path(path)
    where = f"{path}: "
    if not path.exists():
        raise SurfaceError(f"{where}no such file")
    if path.is_dir():
        raise SurfaceError(f"{where}is a folder, not a topography file")
    try:
        reader = st.open_topography(str(path))
    except Exception as err:  # noqa: BLE001 - the reader raises many kinds
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise SurfaceError(f"{where}not a topography file SurfaceTopography can read ({first})") from None
    ch = reader.default_channel if channel is None else reader.channels[channel]
    if ch.dim != 2:
        raise SurfaceError(f"{where}is a line scan (dim = {ch.dim}); fitting needs a 2-D height map")
    kwargs = {}
    if ch.physical_sizes is None:
        if physical_sizes is None:
            raise SurfaceError(f"{where}the file gives no physical size: give it with --size LX[,LY] "
                               f"(Python: physical_sizes=(Lx, Ly)) and --unit")
        kwargs["physical_sizes"] = tuple(float(s) for s in physical_sizes)
    if ch.unit is None:
        if unit is None:
            raise SurfaceError(f"{where}the file gives no length unit: give it with --unit (e.g. --unit um; "
                               f"Python: unit='um')")
        kwargs["unit"] = unit
    try:
        topo = reader.topography(channel_index=ch.index, **kwargs)
    except Exception as err:  # noqa: BLE001
        raise SurfaceError(f"{where}cannot read the height map: {' '.join(str(err).split())}") from None
    if topo.has_undefined_data:
        topo = topo.interpolate_undefined_data()
    f = _unit_factor(topo.unit, where)
    h = np.asarray(topo.heights(), dtype=float) * f
    sizes = tuple(float(s) * f for s in topo.physical_sizes)
    if not all(math.isfinite(s) and s > 0 for s in sizes):
        raise SurfaceError(f"{where}physical size {sizes} m is not positive and finite")
    if not np.all(np.isfinite(h)):
        raise SurfaceError(f"{where}heights contain NaN or inf after filling undefined data")
    return Surface(h, sizes, bool(topo.is_periodic), str(path))


def from_topography(topo, source="<topography>") -> Surface:
    """A :class:`Surface` in metres from a SurfaceTopography ``Topography``."""
    f = _unit_factor(topo.unit or "m", f"{source}: ")
    return Surface(np.asarray(topo.heights(), dtype=float) * f, tuple(float(s) * f for s in topo.physical_sizes),
                   bool(topo.is_periodic), source)


def _as_surface(s) -> Surface:
    if isinstance(s, Surface):
        return s
    if isinstance(s, (str, Path)):
        return read(s)
    if hasattr(s, "heights") and hasattr(s, "physical_sizes"):
        return from_topography(s)
    raise SurfaceError(f"{s!r} is not a Surface, a SurfaceTopography Topography or a file name")


def detrend(h: np.ndarray, mode: str = "plane") -> np.ndarray:
    """Heights with the least-squares plane (``plane``), the mean (``mean``) or nothing (``none``) removed."""
    if mode not in DETRENDS:
        raise SurfaceError(f"detrend = {mode!r} is not known (valid: {', '.join(DETRENDS)})")
    if mode == "none":
        return h
    h = h - h.mean()
    if mode == "plane":
        nx, ny = h.shape
        x = np.arange(nx) - 0.5 * (nx - 1)
        y = np.arange(ny) - 0.5 * (ny - 1)
        # the centred x and y columns are orthogonal on a full grid: two projections, no lstsq
        ax = (h.sum(axis=1) @ x) / (ny * (x @ x)) if nx > 1 else 0.0
        ay = (h.sum(axis=0) @ y) / (nx * (y @ y)) if ny > 1 else 0.0
        h = h - ax * x[:, None] - ay * y[None, :]
    return h


def _gradient(h, dx, dy, periodic):
    """Central-difference gradient (h_x, h_y) [1] (one-sided at the border of a non-periodic map)."""
    if periodic:
        gx = (np.roll(h, -1, 0) - np.roll(h, 1, 0)) / (2 * dx)
        gy = (np.roll(h, -1, 1) - np.roll(h, 1, 1)) / (2 * dy)
        return gx, gy
    return np.gradient(h, dx, axis=0), np.gradient(h, dy, axis=1)


def composite(surface, other=None, detrend_mode: str = "plane") -> Surface:
    """The composite topography: one surface detrended, or the sum of two on the same grid.

    Two surfaces must have the same grid points and, in metres, the same physical size to
    a relative ``SIZE_RTOL``; otherwise a one-line :class:`SurfaceError`.
    """
    a = _as_surface(surface)
    if detrend_mode == "plane" and a.periodic and (other is None or _as_surface(other).periodic):
        detrend_mode = "mean"  # a periodic map has no plane trend; removing one would put a step at its edge
    ha = detrend(a.heights, detrend_mode)
    if other is None:
        return Surface(ha, a.physical_sizes, a.periodic, a.source)
    b = _as_surface(other)
    if a.heights.shape != b.heights.shape:
        raise SurfaceError(f"grids differ: {a.source} has {a.heights.shape[0]} x {a.heights.shape[1]} points, "
                           f"{b.source} {b.heights.shape[0]} x {b.heights.shape[1]} "
                           "(the composite needs the same grid)")
    if not np.allclose(a.physical_sizes, b.physical_sizes, rtol=SIZE_RTOL, atol=0.0):
        raise SurfaceError(f"physical sizes differ: {a.source} is "
                           f"{a.physical_sizes[0]:.6g} x {a.physical_sizes[1]:.6g} m, "
                           f"{b.source} {b.physical_sizes[0]:.6g} x {b.physical_sizes[1]:.6g} m "
                           f"(relative tolerance {SIZE_RTOL:g})")
    hb = detrend(b.heights, detrend_mode)
    periodic = a.periodic and b.periodic
    dx, dy = a.pixel_size
    return Surface(ha + hb, a.physical_sizes, periodic, f"{a.source} + {b.source}",
                   slopes=_gradient(ha, dx, dy, periodic))


def synthetic(nb_grid_pts=512, physical_size=1e-3, *, hurst=0.8, rms_height=None, rms_slope=None,
              short_cutoff=None, long_cutoff=None, seed=0) -> Surface:
    """A periodic self-affine Gaussian surface (SurfaceTopography's Fourier synthesis), in metres.

    nb_grid_pts : int or (nx, ny)    pixels
    physical_size : float or (Lx, Ly) [m]
    hurst : float [1] in (0, 1]      Hurst exponent H, PSD C(q) ~ q^(-2-2H)
    rms_height [m] or rms_slope [1]  amplitude (one of them; default rms_height = 1e-3 physical_size)
    short_cutoff, long_cutoff [m]    wavelengths below / above which the PSD is cut / flat
    seed : int >= 0
    """
    _st()
    from SurfaceTopography.Generation import fourier_synthesis

    n = (nb_grid_pts, nb_grid_pts) if isinstance(nb_grid_pts, numbers.Integral) else tuple(nb_grid_pts)
    if len(n) != 2 or not all(isinstance(k, numbers.Integral) and not isinstance(k, bool) and k >= 8 for k in n):
        raise SurfaceError(f"nb_grid_pts = {nb_grid_pts!r} is out of range "
                           "(valid range: integer or pair of integers >= 8)")
    L = (physical_size, physical_size) if isinstance(physical_size, numbers.Real) else tuple(physical_size)
    L = tuple(check_real("physical_size [m]", v, 0.0, None, lo_open=True) for v in L)
    hurst = check_real("hurst", hurst, 0.0, 1.0, lo_open=True)
    if rms_height is not None and rms_slope is not None:
        raise SurfaceError("give rms_height [m] or rms_slope [1], not both")
    if rms_height is None and rms_slope is None:
        rms_height = 1e-3 * L[0]
    kw = {}
    if rms_height is not None:
        kw["rms_height"] = check_real("rms_height [m]", rms_height, 0.0, None, lo_open=True)
    else:
        kw["rms_slope"] = check_real("rms_slope [1]", rms_slope, 0.0, None, lo_open=True)
    pix = max(L[0] / n[0], L[1] / n[1])
    if short_cutoff is not None:
        kw["short_cutoff"] = check_real("short_cutoff [m]", short_cutoff, 2 * pix, max(L))
    if long_cutoff is not None:
        kw["long_cutoff"] = check_real("long_cutoff [m]", long_cutoff, 2 * pix, None)
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise SurfaceError(f"seed = {seed!r} is out of range (valid range: integer >= 0)")
    topo = fourier_synthesis(n, L, hurst=hurst, unit="m", rng=np.random.default_rng(int(seed)), **kw)
    return Surface(np.asarray(topo.heights(), dtype=float), L, True, f"synthetic(H={hurst:g}, seed={seed})")


# -- summits --------------------------------------------------------------------------

@dataclass(frozen=True)
class Summits:
    """Identified summits of a composite topography (one entry per summit, sorted by height, highest first).

    x, y : [m] position;  height : [m] above the mean plane;  depth : [m] below the highest summit
    curvature : [1/m] kappa = -(h_xx + h_yy)/2;  radius : [m] 1/kappa
    slope : [1] |grad h1| at the summit (0 for one surface);  azimuth : [rad] direction of grad h1
    prominence : [m] height above the highest of the 8 neighbours
    area : [m²] nominal area searched;  pixel_size : (dx, dy) [m]
    """

    x: np.ndarray
    y: np.ndarray
    height: np.ndarray
    curvature: np.ndarray
    slope: np.ndarray
    azimuth: np.ndarray
    prominence: np.ndarray
    area: float
    pixel_size: tuple

    @property
    def n(self) -> int:
        return self.height.size

    @property
    def depth(self) -> np.ndarray:
        return self.height[0] - self.height

    @property
    def radius(self) -> np.ndarray:
        return 1.0 / self.curvature

    @property
    def density(self) -> float:
        """Summits per unit nominal area [1/m²]."""
        return self.n / self.area


def find_summits(surface, min_prominence: float = 0.0, window: int = 1) -> Summits:
    """Summits of a composite :class:`Surface` (see the module docstring).

    A summit is strictly higher than every other pixel of the (2 window + 1)² square around it
    (window = 1: the 8 neighbours) and at least ``min_prominence`` [m] higher than the highest of them.
    """
    from scipy import ndimage

    s = _as_surface(surface)
    min_prominence = check_real("min_prominence [m]", min_prominence, 0.0)
    if isinstance(window, bool) or not isinstance(window, numbers.Integral) or not 1 <= window <= 64:
        raise SurfaceError(f"window = {window!r} is out of range (valid range: integer in [1, 64] pixels)")
    K = int(window)
    h = s.heights
    nx, ny = h.shape
    dx, dy = s.pixel_size
    if not s.periodic and (nx <= 2 * K or ny <= 2 * K):
        raise SurfaceError(f"{s.source}: grid {nx} x {ny} is too small for window {K} "
                           f"(valid range: more than {2 * K} x {2 * K} points)")
    footprint = np.ones((2 * K + 1, 2 * K + 1), dtype=bool)
    footprint[K, K] = False
    # highest other pixel of the window (C loop of scipy.ndimage, no Python loop over pixels)
    top = ndimage.maximum_filter(h, footprint=footprint, mode="wrap" if s.periodic else "nearest")
    prom = h - top
    mask = prom > 0.0
    if min_prominence > 0.0:
        mask &= prom >= min_prominence
    if s.periodic:
        area = s.area
    else:  # the border pixels never qualify: their window is not complete
        mask[:K], mask[-K:], mask[:, :K], mask[:, -K:] = False, False, False, False
        area = (nx - 2 * K) * dx * (ny - 2 * K) * dy
    ii, jj = np.nonzero(mask)
    z = h[ii, jj]
    ip, im = (ii + 1) % nx, (ii - 1) % nx  # inside the border for a non-periodic map
    jp, jm = (jj + 1) % ny, (jj - 1) % ny
    hxx = (h[ip, jj] - 2 * z + h[im, jj]) / dx**2
    hyy = (h[ii, jp] - 2 * z + h[ii, jm]) / dy**2
    kappa = -0.5 * (hxx + hyy)
    if s.slopes is not None:
        gx, gy = s.slopes[0][ii, jj], s.slopes[1][ii, jj]
        slope, azimuth = np.hypot(gx, gy), np.mod(np.arctan2(gy, gx), 2 * np.pi)
    else:
        slope, azimuth = np.zeros(z.size), np.zeros(z.size)
    order = np.argsort(-z, kind="stable")
    return Summits(x=(ii[order] + 0.0) * dx, y=(jj[order] + 0.0) * dy, height=z[order], curvature=kappa[order],
                   slope=slope[order], azimuth=azimuth[order], prominence=prom[ii, jj][order], area=area,
                   pixel_size=(dx, dy))


# -- closed forms of Nayak (1971) ---------------------------------------------------------

def spectral_moments(surface) -> tuple[float, float, float]:
    """Profile spectral moments (m0 [m²], m2 [1], m4 [1/m²]) of a periodic surface, isotropic average.

    m0 = <h²>, m2 = <(h_x² + h_y²)/2>, m4 = <(h_xx² + h_yy²)/2>, derivatives taken exactly in
    Fourier space (independent of any summit finder).
    """
    s = _as_surface(surface)
    h = s.heights - s.heights.mean()
    nx, ny = h.shape
    qx = 2 * np.pi * np.fft.fftfreq(nx, s.pixel_size[0])[:, None]
    qy = 2 * np.pi * np.fft.rfftfreq(ny, s.pixel_size[1])[None, :]
    H = np.fft.rfft2(h)
    w = np.full(H.shape, 2.0)  # each rfft column stands for itself and its conjugate
    w[:, 0] = 1.0
    if ny % 2 == 0:
        w[:, -1] = 1.0
    p = w * np.abs(H) ** 2 / (nx * ny) ** 2
    m0 = p.sum()
    m2 = 0.5 * (p * (qx**2 + qy**2)).sum()
    m4 = 0.5 * (p * (qx**4 + qy**4)).sum()
    return float(m0), float(m2), float(m4)


def nayak(m0, m2, m4) -> dict:
    """Nayak's (1971) closed forms for an isotropic Gaussian surface from its profile moments.

    summit_density = m4 / (6 pi sqrt(3) m2) [1/m²];  mean_curvature = (8/3) sqrt(m4/pi) [1/m]
    (mean of -(k1+k2)/2 over all summits); bandwidth alpha = m0 m4 / m2² [1].
    """
    return {"summit_density": m4 / (6 * math.pi * math.sqrt(3) * m2),
            "mean_curvature": 8.0 / 3.0 * math.sqrt(m4 / math.pi),
            "bandwidth": m0 * m4 / m2**2}


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
    surface : the composite Surface;  settings : detrend, min_prominence, bootstrap size, seed
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

    def source_of(self, name: str) -> str:
        """Where the value of parameter ``name`` came from (one line, for scene comments)."""
        s = self.settings
        k = 2 * s.get("window", 1) + 1
        how = {"N": f"summits ({k}x{k}-window maxima) per unit area",
               "alpha": "gamma fit of summit depths below the highest summit (method of moments)",
               "beta": "gamma fit of summit depths below the highest summit (method of moments)",
               "R_m": "mean of summit radii 1/kappa, kappa = -(h_xx + h_yy)/2",
               "R_sigma": "s.d. of summit radii 1/kappa, kappa = -(h_xx + h_yy)/2"}
        if name in how:
            from .scene import format_quantity

            unit = InterfaceParams.units()[name]
            se = format_quantity(self.stderr[name], unit) if unit != "1" else f"{self.stderr[name]:.3g}"
            how_se = "Poisson, sqrt(n)/area" if name == "N" else f"bootstrap, {s.get('bootstrap')} resamples"
            return f"fitted: {how[name]}; stderr {se} ({how_se})"
        return f"not identified from topography: {self.source_of_rest}"


def fit(topography, other=None, *, base: InterfaceParams | str = "R1", detrend_mode: str = "plane",
        min_prominence: float = 0.0, window: int = 1, bootstrap: int = 200, seed: int = 0,
        base_label: str | None = None) -> FitResult:
    """Fit N, alpha, beta, R_m, R_sigma to the summits of a topography (or of two, summed).

    topography, other : Surface, SurfaceTopography Topography or file name
    base : preset name or InterfaceParams giving the parameters topography does not identify
    base_label : where ``base`` came from, for the report (e.g. "scene my.toml")
    min_prominence [m], window [pixels] : summit definition (:func:`find_summits`)
    bootstrap : resamples of the summits for the standard errors (>= 10)
    """
    from . import presets

    if isinstance(base, str):
        if base not in presets.TABLE1:
            raise SurfaceError(f"preset = {base!r} is not known (valid: {', '.join(presets.TABLE1)})")
        rest, source = presets.TABLE1[base], f"preset {base}"
    elif isinstance(base, InterfaceParams):
        rest, source = base, base_label or "given parameters"
    else:
        raise SurfaceError(f"base = {base!r} is not a preset name or InterfaceParams")
    if isinstance(bootstrap, bool) or not isinstance(bootstrap, numbers.Integral) or bootstrap < 10:
        raise SurfaceError(f"bootstrap = {bootstrap!r} is out of range (valid range: integer >= 10)")
    surf = composite(topography, other, detrend_mode)
    summits = find_summits(surf, min_prominence, window)
    if summits.n < MIN_SUMMITS:
        raise SurfaceError(f"{surf.source}: {summits.n} summits found, too few to fit "
                           f"(valid range: at least {MIN_SUMMITS}; lower --min-prominence or --window, or use a "
                           f"larger map)")
    depth, radius = summits.depth, summits.radius
    if not np.var(depth) > 0:
        raise SurfaceError(f"{surf.source}: all summits at the same height: the height distribution cannot be fitted")
    alpha, beta, R_m, R_sigma = _moments_fit(depth, radius)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, summits.n, size=(int(bootstrap), summits.n))
    # the depth reference is the highest summit of each resample
    bd = summits.height[idx].max(axis=1, keepdims=True) - summits.height[idx]
    ba, bb, bm, bs = _moments_fit(bd, radius[idx])
    stderr = {"N": math.sqrt(summits.n) / summits.area, "alpha": float(ba.std(ddof=1)), "beta": float(bb.std(ddof=1)),
              "R_m": float(bm.std(ddof=1)), "R_sigma": float(bs.std(ddof=1))}
    try:
        params = rest.replace(N=summits.density, alpha=float(alpha), beta=float(beta), R_m=float(R_m),
                              R_sigma=float(R_sigma))
    except ValueError as err:
        raise SurfaceError(f"{surf.source}: fitted parameters are not valid: {err}") from None
    ks_h = stats.kstest(depth, stats.gamma(params.alpha + 1.0, scale=params.beta).cdf).statistic
    ks_r = stats.kstest(radius, lambda x: _truncnorm_cdf(x, params.R_m, params.R_sigma)).statistic \
        if params.R_sigma > 0 else float("nan")
    # SPEC §2 takes heights and radii independent: their rank correlation over the summits tests that
    rho = stats.spearmanr(depth, radius).statistic
    goodness = {"heights": float(ks_h), "radii": float(ks_r), "n": summits.n, "spearman_depth_radius": float(rho)}
    settings = {"detrend": detrend_mode, "min_prominence": float(min_prominence), "window": int(window),
                "bootstrap": int(bootstrap),
                "seed": int(seed), "source": surf.source}
    return FitResult(params, stderr, goodness, summits, source_of_rest=source, surface=surf, settings=settings)


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
    from .population import Population, orientation_from_uniform

    if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 1:
        raise SurfaceError(f"n = {n!r} is out of range (valid range: integer >= 1)")
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
    from .scene import format_quantity

    p = result.params
    closure = default_closure(p) if closure is None else check_real("closure [m]", closure, 0.0, None, lo_open=True)
    units = InterfaceParams.units()
    s, g = result.settings, result.goodness
    lines = [f"# Scene fitted by asperity_sim.surfaces from {s.get('source', '?')}",
             f"# {command}" if command else "#",
             f"# {g['n']} summits (maxima of {2 * s.get('window', 1) + 1}x{2 * s.get('window', 1) + 1} windows, "
             f"min prominence {s.get('min_prominence', 0):.3g} m, "
             f"detrend {s.get('detrend')}); KS statistic of depths vs gamma {g['heights']:.3f}, "
             f"of radii vs truncated Gaussian {g['radii']:.3f}; rank correlation of depth and radius "
             f"{g['spearman_depth_radius']:.3f} (the model takes them independent)",
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


def bem_contact(h, size, E_star, pressures, tolerance=1e-10):
    """Exact (boundary-element) frictionless contact of a rigid surface h on an elastic half-space.

    The reference the asperity model is compared with (``scenarios/bem_closure.py``); needs
    tamaas (``pip install "asperity-sim[bem]"``).  tamaas' Polonsky-Keer solver on a periodic
    grid, with E = E_star and nu = 0, so its contact modulus E/(1 - nu²) is E_star.

    h : ndarray (nx, ny) [m]      composite surface heights
    size : (Lx, Ly) [m]           physical size of the periodic cell
    E_star : float [Pa]           contact modulus
    pressures : sequence [Pa]     mean pressures to solve at
    tolerance : float [1]         tamaas solver tolerance

    Returns an array (4, len(pressures)): closure max(h) - mean(u) [m], mean separation
    mean(u - h) [m], area fraction [1] (traction > 0) and wall time [s] of each solve.
    """
    import time

    import tamaas as tm

    tm.initialize(1)
    tm.set_log_level(tm.LogLevel.error)
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, list(size), list(h.shape))
    model.E, model.nu = E_star, 0.0  # tamaas' contact modulus E/(1 - nu²) = E*
    solver = tm.PolonskyKeerRey(model, np.ascontiguousarray(h), tolerance)
    out = np.empty((4, len(pressures)))
    for k, p in enumerate(pressures):
        t0 = time.perf_counter()
        solver.solve(float(p))
        seconds = time.perf_counter() - t0
        t, u = np.array(model.traction), np.array(model.displacement)
        out[:, k] = h.max() - u.mean(), (u - h).mean(), (t > 0).mean(), seconds
    return out


def plot_fit(result: FitResult):
    """Figure of a fit: summit map, QQ plots of depths (gamma) and radii (truncated Gaussian), histogram."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    p, sm = result.params, result.summits
    fig, ax = plt.subplots(2, 2, figsize=(10, 8.5))
    surf = result.surface
    if surf is not None:
        Lx, Ly = surf.physical_sizes
        im = ax[0, 0].imshow(surf.heights.T * 1e6, origin="lower", extent=(0, Lx * 1e3, 0, Ly * 1e3), cmap="gray")
        fig.colorbar(im, ax=ax[0, 0], label="composite height [um]")
    ax[0, 0].plot(sm.x * 1e3, sm.y * 1e3, ".", ms=2, color="tab:red")
    k = 2 * result.settings.get("window", 1) + 1
    ax[0, 0].set(xlabel="x [mm]", ylabel="y [mm]", title=f"{sm.n} summits (maxima of {k}x{k} pixel squares)")
    prob = (np.arange(1, sm.n + 1) - 0.5) / sm.n
    d = np.sort(sm.depth)
    q = stats.gamma.ppf(prob, p.alpha + 1.0, scale=p.beta)
    ax[0, 1].plot(q * 1e6, d * 1e6, ".", ms=3)
    ax[0, 1].plot([0, d.max() * 1e6], [0, d.max() * 1e6], "k--", lw=1)
    ax[0, 1].set(xlabel="gamma quantile [um]", ylabel="summit depth [um]",
                 title=f"QQ depth: alpha = {p.alpha:.3g}, beta = {p.beta * 1e6:.3g} um, "
                       f"KS = {result.goodness['heights']:.3f}")
    rad = np.sort(sm.radius)
    lo, hi = p.R_bounds
    a, b = special.ndtr((lo - p.R_m) / p.R_sigma), special.ndtr((hi - p.R_m) / p.R_sigma)
    qr = p.R_m + p.R_sigma * special.ndtri(a + prob * (b - a))
    ax[1, 0].plot(qr * 1e6, rad * 1e6, ".", ms=3)
    ax[1, 0].plot([qr.min() * 1e6, qr.max() * 1e6], [qr.min() * 1e6, qr.max() * 1e6], "k--", lw=1)
    ax[1, 0].set(xlabel="truncated Gaussian quantile [um]", ylabel="summit radius 1/kappa [um]",
                 title=f"QQ radius: R_m = {p.R_m * 1e6:.3g} um, R_sigma = {p.R_sigma * 1e6:.3g} um, "
                       f"KS = {result.goodness['radii']:.3f}")
    ax[1, 1].hist(sm.depth * 1e6, bins=40, density=True, alpha=0.6, label="summits")
    x = np.linspace(0, sm.depth.max(), 200)
    ax[1, 1].plot(x * 1e6, stats.gamma.pdf(x, p.alpha + 1.0, scale=p.beta) * 1e-6, label="fitted gamma, Eq. (1)")
    ax[1, 1].set(xlabel="depth below the highest summit r [um]", ylabel="density [1/um]",
                 title=f"N = {p.N * 1e-6:.4g} /mm2")
    ax[1, 1].legend()
    for a_ in ax.flat:
        a_.title.set_fontsize(9)
    fig.tight_layout()
    return fig
