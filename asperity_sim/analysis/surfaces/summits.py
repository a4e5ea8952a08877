"""Summits of a topography: identification, curvatures, and the spectral moments (Nayak).

Owns :func:`find_summits` (local maxima on the 8-neighbour grid with their heights and mean
curvature radii), where a summit may be (:func:`eligible`: not on the border of a non-periodic
map, not within the window of a pixel without data) and the random-process description of a
surface (spectral moments m0, m2, m4 and Nayak's bandwidth parameter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...checks import check_int, check_real
from ...errors import SurfaceError
from .topography import as_surface

IDENTIFIED = ("N", "alpha", "beta", "R_m", "R_sigma", "summit_offset")
NOT_IDENTIFIED = ("mu", "G", "nu", "e", "r_o", "b", "c", "d", "interaction")
MIN_SUMMITS = 20


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

    def pixel_indices(self, pixel_size=None):
        """(i, j): the grid indices of the summits on a map of ``pixel_size`` (dx, dy) [m] (default: their own)."""
        dx, dy = self.pixel_size if pixel_size is None else pixel_size
        return np.rint(self.x / dx).astype(int), np.rint(self.y / dy).astype(int)

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


def eligible(surface, window: int = 1) -> np.ndarray:
    """Pixels that may be summits (bool (nx, ny)): their whole (2 window + 1)² square is measured data.

    On a non-periodic map the ``window`` border rows and columns never qualify (their square is
    not complete); nor does any pixel within ``window`` pixels of one of ``surface.mask`` (missing
    data, filled).  The nominal area of the summit density is the area of these pixels.
    """
    from scipy import ndimage

    s = surface
    K = int(window)
    nx, ny = s.heights.shape
    ok = np.ones((nx, ny), dtype=bool)
    if not s.periodic:
        ok[:K], ok[-K:], ok[:, :K], ok[:, -K:] = False, False, False, False
    if s.mask is not None and np.any(s.mask):
        near = ndimage.maximum_filter(np.asarray(s.mask, dtype=np.uint8), size=2 * K + 1,
                                      mode="wrap" if s.periodic else "constant").astype(bool)
        ok &= ~near
    return ok


def find_summits(surface, min_prominence: float = 0.0, window: int = 1) -> Summits:
    """Summits of a composite :class:`Surface` (see the module docstring).

    A summit is strictly higher than every other pixel of the (2 window + 1)² square around it
    (window = 1: the 8 neighbours) and at least ``min_prominence`` [m] higher than the highest of
    them, and it is :func:`eligible` (no missing data in its square, not on a border).
    """
    from scipy import ndimage

    s = as_surface(surface)
    min_prominence = check_real("min_prominence [m]", min_prominence, 0.0)
    K = check_int("window [pixels]", window, 1, 64, error=SurfaceError)
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
    ok = eligible(s, K)
    mask = (prom > 0.0) & ok
    if min_prominence > 0.0:
        mask &= prom >= min_prominence
    area = float(ok.sum()) * dx * dy
    if area <= 0.0:
        raise SurfaceError(f"{s.source}: no pixel has its whole {2 * K + 1}x{2 * K + 1} window in measured data")
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
    s = as_surface(surface)
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
