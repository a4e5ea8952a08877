"""Contact orientation and local frames (SPEC §3–§4).

Owns the geometry of one asperity: the orientation extent theta_m of Eq. (9) and its slope,
the local displacement (delta_n, delta_s, delta_t) in the frame (n, s, t), the closure
c = max(0, r_o + Delta_1), and their numpy twins (``*_array``, :func:`frame`) for Python-side
use.  The scalar functions are numba kernels inlined into the reductions.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import kernel

HALF_PI = 0.5 * math.pi
POLICIES = ("follow", "birth")
"""How a contact's orientation evolves (SPEC §3): it follows theta = (2/pi) u theta_m(c, R) as the closure
changes, or keeps the angle it was born with while the contact lasts."""


@kernel(inline="always")
def theta_m_and_slope(closure, inv_R, k_e):
    """theta_m(c, R) of Eq. (9) and d theta_m / d c [rad/m].

    ``closure`` is c = max(0, r_o + Delta_1) [m], ``inv_R`` = 1/R [1/m].
    The cosine is clipped to [0, 1] (SPEC §3); the slope is zero where it is clipped
    (one-sided at c = 0, where the exact slope is infinite).
    """
    y = 1.0 - k_e * closure * inv_R
    if y >= 1.0:
        return 0.0, 0.0
    if y <= 0.0:
        return HALF_PI, 0.0
    return math.acos(y), k_e * inv_R / math.sqrt((1.0 - y) * (1.0 + y))


@kernel(inline="always")
def local_displacement(d1, d2, d3, cos_th, sin_th, cos_ph, sin_ph):
    """(delta_n, delta_s, delta_t) = (n.d, s.d, t.d), SPEC §4, with d = (Delta_1 - r, Delta_2, Delta_3)."""
    shear_ph = cos_ph * d2 + sin_ph * d3
    delta_n = cos_th * d1 + sin_th * shear_ph
    delta_s = -sin_th * d1 + cos_th * shear_ph
    delta_t = -sin_ph * d2 + cos_ph * d3
    return delta_n, delta_s, delta_t


@kernel(inline="always")
def closure_and_slope(r_o, d1):
    """c = max(0, r_o + Delta_1) [m] and dc/dDelta_1 (SPEC §3): the closure the orientation extent sees.

    The one definition of the closure; :func:`closure` is its numpy twin.
    """
    closure = r_o + d1
    if closure <= 0.0:
        return 0.0, 0.0
    return closure, 1.0


def closure(params, delta_1):
    """Closure c = max(0, r_o + Delta_1) [m] (SPEC §3), numpy twin of :func:`closure_and_slope`."""
    return np.maximum(0.0, params.r_o + np.asarray(delta_1, dtype=float))


def theta_m_array(params, closure_, R):
    """Vectorised Eq. (9): theta_m [rad] for closure c [m] and relative radius R [m]."""
    R = np.asarray(R, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        y = 1.0 - params.k_e * np.asarray(closure_, dtype=float) / R
    return np.arccos(np.clip(y, 0.0, 1.0))


def frame(theta, phi):
    """Local unit vectors n, s, t (SPEC §4) as arrays of shape (..., 3)."""
    theta = np.asarray(theta, dtype=float)
    phi = np.asarray(phi, dtype=float)
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(phi), np.sin(phi)
    n = np.stack([ct, st * cp, st * sp], axis=-1)
    s = np.stack([-st, ct * cp, ct * sp], axis=-1)
    t = np.stack([np.zeros_like(ct), -sp, cp], axis=-1)
    return n, s, t
