"""Measured and synthetic topographies: reading, missing data, detrending, the composite of two surfaces.

Owns :class:`Surface` (heights on a regular grid, SI units, with the mask of the pixels the
instrument did not measure) and how one is obtained: read from an instrument file through
SurfaceTopography (an optional dependency), built from arrays, synthesised as a self-affine
random surface, detrended, and the composite (sum) of two surfaces in contact.  Missing data are
filled by SurfaceTopography's harmonic interpolation (so detrending and filtering see a complete
map) and kept in ``Surface.mask``, so that no summit is taken on or beside a filled pixel.
A one-dimensional profile is refused: the model needs areal data.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...checks import check_choice, check_int, check_real
from ...errors import SurfaceError

INSTALL_HINT = 'pip install "asperity-sim[surfaces]" (or pip install SurfaceTopography)'


SIZE_RTOL = 1e-6  # physical sizes of two files agree to this (netCDF stores them as float32, 6e-8)
DETRENDS = ("plane", "mean", "none")
_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "μm": 1e-6, "nm": 1e-9, "Å": 1e-10,
          "A": 1e-10, "pm": 1e-12}


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
    """A height map in SI: heights (nx, ny) [m] on a grid of physical size (Lx, Ly) [m].

    mask : bool (nx, ny) or None, True where the heights are not measured data at this
        surface's scale: missing in the file (filled by harmonic interpolation), and after a
        cutoff (:func:`~asperity_sim.analysis.surfaces.scale.s_filter`) also within its reach of
        such pixels or of the edge of a non-periodic map.  Summits are never taken there.
    """

    heights: np.ndarray
    physical_sizes: tuple[float, float]
    periodic: bool = False
    source: str = "<array>"
    slopes: tuple | None = None  # (d h1/dx, d h1/dy) [1] of the first surface of a composite
    mask: np.ndarray | None = None

    @property
    def nb_grid_pts(self):
        return self.heights.shape

    @property
    def pixel_size(self):
        return tuple(L / n for L, n in zip(self.physical_sizes, self.heights.shape))

    @property
    def area(self) -> float:
        return self.physical_sizes[0] * self.physical_sizes[1]

    @property
    def missing_fraction(self) -> float:
        """Fraction of the pixels that are not measured data (see ``mask``) [1]."""
        return 0.0 if self.mask is None else float(np.mean(self.mask))


def profile_error(where, shape) -> SurfaceError:
    """The error for one-dimensional data: the asperity model needs an areal height map."""
    pts = " x ".join(str(n) for n in shape)
    return SurfaceError(f"{where}is a one-dimensional profile (a line scan, {pts} points): the asperity model "
                        "needs areal data, a 2-D height map with at least 3 points along each axis (an areal scan "
                        "of an atomic-force, interferometric, confocal or stylus instrument)")


def fill_missing(heights, mask, physical_sizes, periodic=False, where="") -> np.ndarray:
    """Heights with the pixels of ``mask`` filled by harmonic interpolation (SurfaceTopography).

    A harmonic function has no maximum inside the region it fills, so the filling creates no
    summit of its own; the summit finder excludes the filled pixels and their neighbours anyway.
    """
    mask = np.asarray(mask, dtype=bool)
    if mask.all():
        raise SurfaceError(f"{where}every pixel is missing data: there is no height to fit")
    from SurfaceTopography import Topography

    topo = Topography(np.ma.masked_array(np.where(mask, 0.0, heights), mask=mask), tuple(physical_sizes),
                      periodic=periodic)
    filled = np.ma.getdata(topo.interpolate_undefined_data().heights()).astype(float)
    if not np.all(np.isfinite(filled)):
        raise SurfaceError(f"{where}heights contain NaN or inf after filling the missing data")
    return filled


def with_missing_filled(s: Surface) -> Surface:
    """``s`` itself, or, when heights are NaN or inf, a copy with them masked and filled."""
    bad = ~np.isfinite(s.heights)
    if not bad.any():
        return s
    _st()
    mask = bad if s.mask is None else (bad | s.mask)
    h = fill_missing(s.heights, mask, s.physical_sizes, s.periodic, f"{s.source}: ")
    return Surface(h, s.physical_sizes, s.periodic, s.source, s.slopes, mask)


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
        raise profile_error(where, tuple(ch.nb_grid_pts or ()) or ("?",))
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
    return from_topography(topo, str(path))


def from_topography(topo, source="<topography>") -> Surface:
    """A :class:`Surface` in metres from a SurfaceTopography ``Topography`` (missing data masked and filled)."""
    where = f"{source}: "
    if getattr(topo, "dim", 2) != 2 or min(topo.nb_grid_pts) < 3:
        raise profile_error(where, tuple(topo.nb_grid_pts))
    f = _unit_factor(topo.unit or "m", where)
    sizes = tuple(float(s) * f for s in topo.physical_sizes)
    if not all(math.isfinite(s) and s > 0 for s in sizes):
        raise SurfaceError(f"{where}physical size {sizes} m is not positive and finite")
    raw = topo.heights()
    h = np.asarray(np.ma.getdata(raw), dtype=float) * f
    mask = np.ma.getmaskarray(raw) | ~np.isfinite(h)
    periodic = bool(topo.is_periodic)
    if not mask.any():
        return Surface(h, sizes, periodic, source)
    return Surface(fill_missing(h, mask, sizes, periodic, where), sizes, periodic, source, mask=mask)


def as_surface(s) -> Surface:
    """A :class:`Surface` from a Surface (NaN heights masked and filled), a Topography or a file name."""
    if isinstance(s, Surface):
        if s.heights.ndim != 2 or min(s.heights.shape) < 3:
            raise profile_error(f"{s.source}: ", s.heights.shape)
        return with_missing_filled(s)
    if isinstance(s, (str, Path)):
        return read(s)
    if hasattr(s, "heights") and hasattr(s, "physical_sizes"):
        return from_topography(s)
    raise SurfaceError(f"{s!r} is not a Surface, a SurfaceTopography Topography or a file name")


def detrend(h: np.ndarray, mode: str = "plane", mask=None) -> np.ndarray:
    """Heights with the least-squares plane (``plane``), the mean (``mean``) or nothing (``none``) removed.

    With a ``mask`` (True: not measured) the plane or mean is that of the measured pixels only.
    """
    check_choice("detrend", mode, DETRENDS, error=SurfaceError)
    if mode == "none":
        return h
    if mask is not None and np.any(mask):
        good = ~np.asarray(mask, dtype=bool)
        if mode == "mean":
            return h - h[good].mean()
        i, j = np.nonzero(good)
        a = np.column_stack([np.ones(i.size), i, j]).astype(float)
        c = np.linalg.lstsq(a, h[good], rcond=None)[0]
        return h - c[0] - c[1] * np.arange(h.shape[0])[:, None] - c[2] * np.arange(h.shape[1])[None, :]
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
    a = as_surface(surface)
    if detrend_mode == "plane" and a.periodic and (other is None or as_surface(other).periodic):
        detrend_mode = "mean"  # a periodic map has no plane trend; removing one would put a step at its edge
    ha = detrend(a.heights, detrend_mode, a.mask)
    if other is None:
        return Surface(ha, a.physical_sizes, a.periodic, a.source, mask=a.mask)
    b = as_surface(other)
    if a.heights.shape != b.heights.shape:
        raise SurfaceError(f"grids differ: {a.source} has {a.heights.shape[0]} x {a.heights.shape[1]} points, "
                           f"{b.source} {b.heights.shape[0]} x {b.heights.shape[1]} "
                           "(the composite needs the same grid)")
    if not np.allclose(a.physical_sizes, b.physical_sizes, rtol=SIZE_RTOL, atol=0.0):
        raise SurfaceError(f"physical sizes differ: {a.source} is "
                           f"{a.physical_sizes[0]:.6g} x {a.physical_sizes[1]:.6g} m, "
                           f"{b.source} {b.physical_sizes[0]:.6g} x {b.physical_sizes[1]:.6g} m "
                           f"(relative tolerance {SIZE_RTOL:g})")
    hb = detrend(b.heights, detrend_mode, b.mask)
    periodic = a.periodic and b.periodic
    dx, dy = a.pixel_size
    mask = a.mask if b.mask is None else b.mask if a.mask is None else (a.mask | b.mask)
    return Surface(ha + hb, a.physical_sizes, periodic, f"{a.source} + {b.source}",
                   slopes=_gradient(ha, dx, dy, periodic), mask=mask)


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
    seed = check_int("seed", seed, 0, error=SurfaceError)
    topo = fourier_synthesis(n, L, hurst=hurst, unit="m", rng=np.random.default_rng(int(seed)), **kw)
    return Surface(np.asarray(topo.heights(), dtype=float), L, True, f"synthetic(H={hurst:g}, seed={seed})")
