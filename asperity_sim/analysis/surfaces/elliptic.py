"""Elliptic summits: principal curvatures at the summits and the Hertz contact of an elliptic paraboloid.

Owns :func:`principal_curvatures` (both principal curvatures of the composite gap at each
summit, from the discrete Hessian) and :func:`hertz_elliptic`, the exact Hertz relations of an
elliptic paraboloid against a flat written as two equivalent spheres, which the model's Hertz
law (SPEC §5: f = (4/3) E* sqrt(R) delta^(3/2), contact area pi R delta) can use unchanged.

The relations (Johnson, *Contact Mechanics*, 1985, §3.5 and §4.2; Hertz 1882).  A gap
h = A x² + B y² (0 < A <= B; A = k_min/2, B = k_max/2 with k the principal curvatures) pressed
by an approach delta has an elliptic contact of semi-axes a >= b, eccentricity e² = m = 1 - b²/a²,
with K = K(m), E = E(m) the complete elliptic integrals of parameter m:

    B/A = (E/(1 - m) - K) / (K - E)           (fixes m from the shape alone)
    delta = A m a² K / (K - E)                 (approach)
    P = (2/3) pi E* A m a³ / (K - E)           (load; p0 = E* A m a² / (b (K - E)))

so that the load and the contact area pi a b are those of two spheres:

    P = (4/3) E* sqrt(R_force) delta^(3/2),    R_force = (pi²/4) (K - E) / (A m K³)
    pi a b = pi R_area delta,                  R_area  = (K - E) sqrt(1 - m) / (A m K)

Both tend to the sphere's R = 1/(2A) as B/A -> 1.  Greenwood (1997, Tribol. Int. 30, 235)
showed that the Hertz load-approach and area relations of an elliptic contact are close to those
of a sphere of the geometric-mean radius R_e = sqrt(R' R'') = 1/sqrt(k_max k_min); the exact
factors R_force/R_e and R_area/R_e (Johnson's correction factors F_2^-3 and F_1²/F_2) are
returned here and stay within a few per cent of 1 for the curvature ratios of random
surfaces (median about 2).  The model's current radius, 1/kappa with kappa the mean
curvature (k_max + k_min)/2, is the harmonic mean of the principal radii, smaller than R_e.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

from .summits import Summits
from .topography import as_surface

RATIO_MAX = 1.0e4
"""Largest curvature ratio k_max/k_min the tables cover."""
RATIO_CAP = 20.0
"""Largest curvature ratio :func:`equivalent_radii` uses: a summit more elongated than this (or with
k_min <= 0) is a ridge rather than a paraboloid, whose Hertz contact would grow without bound
along it; it is given the radii of the ratio RATIO_CAP (about 1 % of the summits of a Gaussian
surface on the 3 x 3 stencil)."""
_K_GRID = np.geomspace(1.0e-4, 1.0, 4001)[::-1]  # b/a, from the circle to a long ellipse


def _exact(k):
    """(B/A, R_force A, R_area A) of contacts with axis ratio k = b/a in (0, 1), exact (elliptic integrals)."""
    m1 = k * k  # 1 - m, the complementary parameter: accurate near the long-ellipse end
    m = 1.0 - m1
    K, E = special.ellipkm1(m1), special.ellipe(m)
    kme = K - E
    ratio = (E / m1 - K) / kme
    return ratio, (math.pi**2 / 4.0) * kme / (m * K**3), kme * np.sqrt(m1) / (m * K)


def _table():
    k = _K_GRID[1:]  # k = 1 (the circle) is the limit, set exactly
    ratio, rf, ra = _exact(k)
    return np.concatenate([[0.0], np.log(ratio)]), np.concatenate([[math.log(0.5)], np.log(rf)]), \
        np.concatenate([[math.log(0.5)], np.log(ra)])


_LOG_RATIO, _LOG_RF, _LOG_RA = _table()


def hertz_elliptic(ratio):
    """Equivalent sphere radii of an elliptic paraboloid, in units of its geometric-mean radius.

    ratio : array [1], k_max / k_min >= 1 of the principal curvatures (clipped to [1, RATIO_MAX])

    Returns (R_force / R_e, R_area / R_e) [1]: the sphere radius that gives the same Hertz load at
    the same approach, and the one whose pi R delta is the same contact area (module docstring),
    both divided by R_e = 1/sqrt(k_max k_min).  Interpolated in log-log from a table of the exact
    relations (relative error below 1e-6 of the exact value).
    """
    x = np.log(np.clip(np.asarray(ratio, dtype=float), 1.0, RATIO_MAX))
    # the table holds R A; R_e = 1 / (2 A sqrt(B/A)), so R / R_e = 2 (R A) sqrt(B/A)
    scale = math.log(2.0) + 0.5 * x
    return np.exp(np.interp(x, _LOG_RATIO, _LOG_RF) + scale), np.exp(np.interp(x, _LOG_RATIO, _LOG_RA) + scale)


def hertz_elliptic_exact(ratio: float):
    """(R_force / R_e, R_area / R_e, b / a) for one curvature ratio, solved exactly (Brent on m); for tests."""
    from scipy import optimize

    ratio = float(ratio)
    if ratio == 1.0:
        return 1.0, 1.0, 1.0
    f = lambda lk: math.log(_exact(np.array([math.exp(lk)]))[0][0]) - math.log(ratio)  # noqa: E731
    lk = optimize.brentq(f, math.log(1e-6), math.log(1.0 - 1e-9), xtol=1e-14)
    k = math.exp(lk)
    _, rf, ra = _exact(np.array([k]))
    s = 2.0 * math.sqrt(ratio)
    return float(rf[0]) * s, float(ra[0]) * s, k


def principal_curvatures(surface, summits: Summits):
    """(k_max, k_min) [1/m] of the composite gap at each summit: eigenvalues of minus the discrete Hessian.

    h_xx, h_yy from the 3-point second differences (as :func:`~.summits.find_summits`, so
    (k_max + k_min)/2 is its curvature kappa), h_xy from the 4 diagonal neighbours.  k_min <= 0 (a
    saddle-like summit on the 3 x 3 stencil) is possible and returned as it is.
    """
    s = as_surface(surface)
    h = s.heights
    nx, ny = h.shape
    dx, dy = s.pixel_size
    ii, jj = summits.pixel_indices(s.pixel_size)
    ip, im, jp, jm = (ii + 1) % nx, (ii - 1) % nx, (jj + 1) % ny, (jj - 1) % ny
    z = h[ii, jj]
    hxx = (h[ip, jj] - 2 * z + h[im, jj]) / dx**2
    hyy = (h[ii, jp] - 2 * z + h[ii, jm]) / dy**2
    hxy = (h[ip, jp] - h[ip, jm] - h[im, jp] + h[im, jm]) / (4 * dx * dy)
    kappa = -0.5 * (hxx + hyy)
    d = np.hypot(0.5 * (hxx - hyy), hxy)
    return kappa + d, kappa - d


def equivalent_radii(k_max, k_min):
    """(R_force, R_area) [m] per summit (:func:`hertz_elliptic`); k_min is raised to at least k_max / RATIO_CAP."""
    k_max = np.asarray(k_max, dtype=float)
    k_min = np.maximum(np.asarray(k_min, dtype=float), k_max / RATIO_CAP)
    rf, ra = hertz_elliptic(k_max / k_min)
    R_e = 1.0 / np.sqrt(k_max * k_min)
    return rf * R_e, ra * R_e
