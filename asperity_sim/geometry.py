"""Contact orientation and local frames (SPEC §3–§4).

Owns the geometry of one asperity: the orientation extent theta_m of Eq. (9), the
physical meridional angle of a sampled asperity, and the local frame (n, s, t).
Scalar functions are numba kernels (called from the assembly kernels); the
``*_array`` helpers are their numpy twins for Python-side use.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils

HALF_PI = 0.5 * math.pi

# Taylor coefficients of the libm-free trigonometry below (for kernels that LLVM vectorises:
# a loop with a libm call does not vectorise).  Truncation errors: sin, cos on [0, pi/2] below
# 1e-18 (next terms (pi/2)^23/23!, (pi/2)^24/24!); asin on [0, 1/2] below 1e-18 (next term
# about 0.25^26 / (sqrt(26 pi) 53)).  Each is zero-padded to a multiple of 4 terms for
# :func:`poly4`.  No fastmath: vector and scalar code give the same bits.


def _padded(c):
    return np.concatenate([c, np.zeros(-len(c) % 4)])


SIN_SERIES = _padded([(-1) ** k / math.factorial(2 * k + 1) for k in range(11)])
COS_SERIES = _padded([(-1) ** k / math.factorial(2 * k) for k in range(12)])
ASIN_SERIES = _padded([math.factorial(2 * k) / (4 ** k * math.factorial(k) ** 2 * (2 * k + 1)) for k in range(26)])


@numba.extending.intrinsic
def fsqrt(typingctx, x):
    """Square root as the LLVM intrinsic: the same correctly rounded value as ``math.sqrt``.

    numba lowers ``math.sqrt`` and ``np.sqrt`` to libm's ``sqrt``, which may set errno, so a
    loop with it is neither if-converted nor vectorised; the intrinsic has no side effect.
    """
    if x != numba.types.float64:
        return None

    def codegen(context, builder, signature, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.DoubleType(), [ir.DoubleType()]),
                                            "llvm.sqrt.f64")
        return builder.call(fn, args)

    return numba.types.float64(numba.types.float64), codegen


@numba.njit(cache=True, inline="always", error_model="numpy")
def poly4(coef, z):
    """sum_k coef[k] z^k (coef.size a multiple of 4) as four interleaved Horner chains in z^4.

    One Horner chain is a serial multiply-add chain; four independent ones cut the latency
    of the vectorised kernel by about four.  LLVM unrolls the loop for a constant ``coef``.
    """
    z2 = z * z
    z4 = z2 * z2
    q0 = q1 = q2 = q3 = 0.0
    for i in range(coef.size - 4, -1, -4):
        q0 = q0 * z4 + coef[i]
        q1 = q1 * z4 + coef[i + 1]
        q2 = q2 * z4 + coef[i + 2]
        q3 = q3 * z4 + coef[i + 3]
    return (q0 + z * q1) + z2 * (q2 + z * q3)


@numba.njit(cache=True, inline="always", error_model="numpy")
def sin_cos_quarter(x):
    """(sin x, cos x) for x in [0, pi/2] without a libm call; error a few 1e-16."""
    z = x * x
    return x * poly4(SIN_SERIES, z), poly4(COS_SERIES, z)


@numba.njit(cache=True, inline="always", error_model="numpy")
def acos_unit(y):
    """arccos y for y in [0, 1] without a libm call; error a few 1e-16.

    y <= 1/2: pi/2 - asin y; y > 1/2: 2 asin sqrt((1 - y)/2) (1 - y is exact there), so the
    series is needed on [0, 1/2] only and both cases share one polynomial evaluation.
    """
    low = y <= 0.5
    z = y if low else fsqrt(0.5 * (1.0 - y))
    a = z * poly4(ASIN_SERIES, z * z)
    return HALF_PI - a if low else 2.0 * a


@numba.njit(cache=True, inline="always")
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


@numba.njit(cache=True, inline="always")
def local_displacement(d1, d2, d3, cos_th, sin_th, cos_ph, sin_ph):
    """(delta_n, delta_s, delta_t) = (n.d, s.d, t.d), SPEC §4, with d = (Delta_1 - r, Delta_2, Delta_3)."""
    shear_ph = cos_ph * d2 + sin_ph * d3
    delta_n = cos_th * d1 + sin_th * shear_ph
    delta_s = -sin_th * d1 + cos_th * shear_ph
    delta_t = -sin_ph * d2 + cos_ph * d3
    return delta_n, delta_s, delta_t


def closure(params, delta_1):
    """Closure for the orientation extent, c = max(0, r_o + Delta_1) [m] (SPEC §3)."""
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
