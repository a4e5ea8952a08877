"""Branch-free arithmetic for kernels that LLVM vectorises, a software prefetch, and borrowed arrays.

Owns the numerics below the physics: :func:`fsqrt` (the LLVM square root, which has no
side effect, so loops with it vectorise), the libm-free series trigonometry
(:func:`sin_cos_quarter`, :func:`acos_unit`, evaluated by Estrin's scheme in
:func:`estrin16`), :func:`prefetch` (``llvm.prefetch``) for the kernels that walk the spring
store contact by contact, and :func:`borrowed` (arrays without a reference count for their
loops).  No fastmath: vector and scalar code give the same bits.

Prefetch: the hardware prefetchers follow a stream, but a loop over committed contacts visits a
few cache lines per contact and then does tens of nanoseconds of arithmetic; when the store does
not fit in the cache, asking for the lines of a contact a few contacts ahead overlaps the two.
A prefetch is a hint: it changes no value, only when a line arrives.
"""

from __future__ import annotations

import math

import llvmlite.binding
import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils

from .geometry import HALF_PI
from .jit import kernel

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


@kernel(inline="always", error_model="numpy")
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


@kernel(inline="always", error_model="numpy")
def sin_cos_quarter(x):
    """(sin x, cos x) for x in [0, pi/2] without a libm call; error a few 1e-16."""
    z = x * x
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    return x * estrin16(SIN_SERIES, 0, z, z2, z4, z8), estrin16(COS_SERIES, 0, z, z2, z4, z8)


@kernel(inline="always", error_model="numpy")
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


# the intrinsic's name carries its pointer type: typed (i8*) before LLVM 15, opaque after
_NAME = "llvm.prefetch.p0" if llvmlite.binding.llvm_version_info[0] >= 15 else "llvm.prefetch.p0i8"


@numba.extending.intrinsic
def prefetch(typingctx, a, i, j, k):
    """Ask for the cache line holding ``a[i, j, k]`` (a C-contiguous 3-D array), to be read soon.

    ``llvm.prefetch`` (read, high locality, data cache); the index is not bounds-checked, and a
    prefetch of any address is harmless.
    """
    if not (isinstance(a, numba.types.Array) and a.ndim == 3 and a.layout == "C"):
        return None
    if not all(isinstance(x, numba.types.Integer) for x in (i, j, k)):
        return None

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        index = [context.cast(builder, v, t, numba.types.intp) for v, t in zip(args[1:], signature.args[1:])]
        ptr = builder.bitcast(cgutils.get_item_pointer(context, builder, aryty, ary, index),
                              ir.IntType(8).as_pointer())
        i32 = ir.IntType(32)
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [ir.IntType(8).as_pointer(), i32, i32, i32]), _NAME)
        builder.call(fn, [ptr, ir.Constant(i32, 0), ir.Constant(i32, 3), ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return numba.types.void(a, i, j, k), codegen


@kernel(inline="always")
def copy_into(dest, src):
    """``dest[:] = src`` for 1-D arrays of the same length, as a loop.

    numba compiles an array-to-slice assignment with a shape-mismatch error whose message it formats
    at run time (string conversion, joins): about 2 s of every first run for one line.
    """
    for i in range(src.shape[0]):
        dest[i] = src[i]


def _without_owner(context, builder, ty, value):
    """``value`` of type ``ty`` with the owner (meminfo, parent) of every array in it set to null."""
    if isinstance(ty, numba.types.Array):
        ary = context.make_array(ty)(context, builder, value)
        ary.meminfo = cgutils.get_null_value(ary.meminfo.type)
        ary.parent = cgutils.get_null_value(ary.parent.type)
        return ary._getvalue()
    if isinstance(ty, numba.types.BaseTuple):
        for k, t in enumerate(ty):
            value = builder.insert_value(value, _without_owner(context, builder, t, builder.extract_value(value, k)), k)
    return value


@numba.extending.intrinsic
def borrowed(typingctx, a):
    """``a`` (an array, or a tuple holding arrays) as views without a reference count: the same data, no owner.

    numba counts the references to an array with atomic increments and decrements, and inserts
    a pair wherever a loop body hands the array to an inlined function with branches; two
    threads doing so on the same array fight over one cache line, at every contact.  A view
    without an owner (a null ``meminfo``) turns each of those into a test of a null pointer, with
    no atomic.  Only for arrays the caller keeps alive while the view is in use (a kernel's
    arguments).
    """
    if not isinstance(a, (numba.types.Array, numba.types.BaseTuple)):
        return None

    def codegen(context, builder, signature, args):
        return _without_owner(context, builder, signature.args[0], args[0])

    return a(a), codegen
