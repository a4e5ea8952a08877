"""Summit curvatures at the scale of the contacts: paraboloids fitted over discs that grow with the contact.

Owns :func:`curvature_at_scales`, the least-squares quadratic fitted to the heights within a disc
of radius rho around each summit, for a set of radii, :func:`neighbour_distance` (how far a
summit's own hill reaches) and :func:`radii_at`, a summit's value at the scale of its Hertz contact
(rho = its contact radius a).

Why: the summit finder takes curvatures from the 3 x 3 stencil at the pixel scale, while a contact
of radius a is carried by the surface over a disc of radius a; where the summit is sharper than
its shoulders the Hertz law with the pixel curvature makes the contact too small and too
compliant.  The quadratic h = c0 + c1 x + c2 y + (h_xx x² + 2 h_xy x y + h_yy y²)/2 fitted by
least squares (equal weights) to the pixels with x² + y² <= rho² gives the Hessian at scale rho;
below rho = sqrt(2) pixels (3 x 3 points) the stencil's values stand.  A disc wider than half the
distance to the nearest other summit reaches into the next asperity and describes the valley
between them, not the summit: the scale of a summit is capped there.
"""

from __future__ import annotations

import math

import numpy as np

from .summits import Summits
from .topography import as_surface

SCALES_PX = (1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0)
"""Disc radii [pixels] at which the quadratic is fitted (the first, 1.5, is the 3 x 3 square)."""


def _design(rho_px, dx, dy):
    """Pixel offsets within the disc and the pseudo-inverse of the quadratic's design matrix."""
    k = int(math.floor(rho_px))
    di, dj = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1), indexing="ij")
    inside = di**2 + dj**2 <= rho_px**2 + 1e-9
    di, dj = di[inside], dj[inside]
    x, y = di * dx, dj * dy
    X = np.stack([np.ones_like(x), x, y, 0.5 * x * x, x * y, 0.5 * y * y], axis=1)
    return di, dj, np.linalg.pinv(X)


def curvature_at_scales(surface, summits: Summits, scales_px=SCALES_PX):
    """Principal curvatures and apex heights of the paraboloids fitted around each summit.

    Returns (rho [m] (k,), k_max (n, k) [1/m], k_min (n, k) [1/m], apex (n, k) [m]): for each
    summit and disc radius rho = scales_px * pixel size, the eigenvalues of minus the fitted
    Hessian and the fitted height at the summit (c0).  Periodic maps wrap around; on other maps
    a disc reaching past the border uses the nearest edge pixel.
    """
    s = as_surface(surface)
    h = s.heights
    nx, ny = h.shape
    dx, dy = s.pixel_size
    ii, jj = summits.pixel_indices(s.pixel_size)
    shape = (summits.n, len(scales_px))
    k_max, k_min, apex = np.empty(shape), np.empty(shape), np.empty(shape)
    for c, rho in enumerate(scales_px):
        di, dj, pinv = _design(float(rho), dx, dy)
        pi, pj = ii[:, None] + di[None, :], jj[:, None] + dj[None, :]
        if s.periodic:
            pi, pj = pi % nx, pj % ny
        else:
            pi, pj = np.clip(pi, 0, nx - 1), np.clip(pj, 0, ny - 1)
        coef = h[pi, pj] @ pinv.T  # (n, 6)
        hxx, hxy, hyy = coef[:, 3], coef[:, 4], coef[:, 5]
        kappa, d = -0.5 * (hxx + hyy), np.hypot(0.5 * (hxx - hyy), hxy)
        k_max[:, c], k_min[:, c], apex[:, c] = kappa + d, kappa - d, coef[:, 0]
    rho = np.asarray(scales_px, dtype=float) * math.sqrt(dx * dy)
    return rho, k_max, k_min, apex


def neighbour_distance(summits: Summits, periodic_size=None):
    """Distance [m] from each summit to the nearest other summit (periodic when ``periodic_size`` (Lx, Ly) [m])."""
    from scipy.spatial import cKDTree

    xy = np.column_stack([summits.x, summits.y])
    if periodic_size is not None:
        xy = np.mod(xy, np.asarray(periodic_size, dtype=float))
    tree = cKDTree(xy, boxsize=None if periodic_size is None else np.asarray(periodic_size, dtype=float))
    d, _ = tree.query(xy, k=2)
    return d[:, 1]


def radii_at(rho, table, contact_radius):
    """Values of a per-summit table at each summit's own scale, interpolated in log(rho).

    rho : (k,) [m] the table's disc radii;  table : (n, k) values (e.g. a curvature)
    contact_radius : (n,) [m]; below rho[0] the first column stands, above rho[-1] the last
    """
    x = np.log(np.clip(contact_radius, rho[0], rho[-1]))
    lr = np.log(rho)
    c = np.clip(np.searchsorted(lr, x) - 1, 0, len(rho) - 2)
    t = (x - lr[c]) / (lr[c + 1] - lr[c])
    rows = np.arange(table.shape[0])
    return (1.0 - t) * table[rows, c] + t * table[rows, c + 1]
