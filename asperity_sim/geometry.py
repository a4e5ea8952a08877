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
# about 0.25^26 / (sqrt(26 pi) 53)).  Each is zero-padded to a multiple of 16 terms for
# :func:`estrin16`.  No fastmath: vector and scalar code give the same bits.


def _padded(c):
    return np.concatenate([c, np.zeros(-len(c) % 16)])


SIN_SERIES = _padded([(-1) ** k / math.factorial(2 * k + 1) for k in range(11)])
COS_SERIES = _padded([(-1) ** k / math.factorial(2 * k) for k in range(12)])
ASIN_SERIES = _padded([math.factorial(2 * k) / (4 ** k * math.factorial(k) ** 2 * (2 * k + 1)) for k in range(26)])
if (SIN_SERIES.size, COS_SERIES.size, ASIN_SERIES.size) != (16, 16, 32):  # the estrin16 calls below assume these
    raise ImportError("series lengths changed: update sin_cos_quarter and acos_unit, which evaluate 16, 16, 32 terms")


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
def estrin16(coef, k, z, z2, z4, z8):
    """sum_i coef[k + i] z^i over i < 16 by Estrin's scheme (z2, z4, z8 the powers of z).

    Four levels of independent multiply-adds instead of a serial Horner chain: the vectorised
    kernel is bound by the latency of its longest dependency chain, which this shortens.
    """
    a0 = coef[k] + coef[k + 1] * z
    a1 = coef[k + 2] + coef[k + 3] * z
    a2 = coef[k + 4] + coef[k + 5] * z
    a3 = coef[k + 6] + coef[k + 7] * z
    a4 = coef[k + 8] + coef[k + 9] * z
    a5 = coef[k + 10] + coef[k + 11] * z
    a6 = coef[k + 12] + coef[k + 13] * z
    a7 = coef[k + 14] + coef[k + 15] * z
    b0, b1, b2, b3 = a0 + a1 * z2, a2 + a3 * z2, a4 + a5 * z2, a6 + a7 * z2
    return (b0 + b1 * z4) + (b2 + b3 * z4) * z8


@numba.njit(cache=True, inline="always", error_model="numpy")
def sin_cos_quarter(x):
    """(sin x, cos x) for x in [0, pi/2] without a libm call; error a few 1e-16."""
    z = x * x
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    return x * estrin16(SIN_SERIES, 0, z, z2, z4, z8), estrin16(COS_SERIES, 0, z, z2, z4, z8)


@numba.njit(cache=True, inline="always", error_model="numpy")
def acos_unit(y):
    """arccos y for y in [0, 1] without a libm call; error a few 1e-16.

    y <= 1/2: pi/2 - asin y; y > 1/2: 2 asin sqrt((1 - y)/2) (1 - y is exact there), so the
    series is needed on [0, 1/2] only and both cases share one polynomial evaluation.
    """
    low = y <= 0.5
    z = y if low else fsqrt(0.5 * (1.0 - y))
    w = z * z
    w2 = w * w
    w4 = w2 * w2
    w8 = w4 * w4
    a = z * (estrin16(ASIN_SERIES, 0, w, w2, w4, w8) + (w8 * w8) * estrin16(ASIN_SERIES, 16, w, w2, w4, w8))
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
