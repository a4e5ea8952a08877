"""Atomic memory operations and polling without the GIL: what threads that wait awake are built from.

Owns the intrinsics :func:`load_acquire`, :func:`store_release` and :func:`fetch_add` (one
int64 element of a 1-D array, as an atomic load, store, or add), :func:`cpu_pause` and
:func:`cpu_yield`, and the two polling kernels :func:`wait_while` and :func:`post_then_wait` that
:mod:`asperity_sim.threads` runs while a thread waits for another.  numba has no atomics of its
own, and a plain load in a polling loop may be hoisted out of it by LLVM.
"""

from __future__ import annotations

import platform

import llvmlite.binding
import numba
from llvmlite import ir
from numba.core import cgutils

from .jit import kernel

__all__ = ["load_acquire", "store_release", "fetch_add", "cpu_pause", "cpu_yield", "wait_while", "post_then_wait"]


def _int64_vector(flags) -> bool:
    return isinstance(flags, numba.types.Array) and flags.dtype == numba.types.int64 and flags.ndim == 1


def _element(context, builder, signature, args):
    """The pointer to ``flags[i]`` (the first two arguments of an intrinsic below)."""
    aryty = signature.args[0]
    ary = context.make_array(aryty)(context, builder, args[0])
    index = context.cast(builder, args[1], signature.args[1], numba.types.intp)
    return cgutils.get_item_pointer(context, builder, aryty, ary, [index])


def _int64(context, builder, signature, args, k):
    """Argument k of an intrinsic as an int64."""
    return context.cast(builder, args[k], signature.args[k], numba.types.int64)


@numba.extending.intrinsic
def load_acquire(typingctx, flags, i):
    """``flags[i]`` (a 1-D int64 array) read as an atomic load: a loop that polls it sees another thread's writes."""
    if not _int64_vector(flags):
        return None

    def codegen(context, builder, signature, args):
        return builder.load_atomic(_element(context, builder, signature, args), "acquire", 8)

    return numba.types.int64(flags, i), codegen


@numba.extending.intrinsic
def store_release(typingctx, flags, i, value):
    """``flags[i] = value`` as an atomic store: what the thread wrote before is visible to a reader that sees it."""
    if not _int64_vector(flags):
        return None

    def codegen(context, builder, signature, args):
        builder.store_atomic(_int64(context, builder, signature, args, 2), _element(context, builder, signature, args),
                             "release", 8)
        return context.get_dummy_value()

    return numba.types.void(flags, i, value), codegen


def _atomic_add(flags, i, value, ordering):
    """The typing and codegen of an atomic ``flags[i] += value`` with memory ordering ``ordering``."""
    if not _int64_vector(flags):
        return None

    def codegen(context, builder, signature, args):
        return builder.atomic_rmw("add", _element(context, builder, signature, args),
                                  _int64(context, builder, signature, args, 2), ordering)

    return numba.types.int64(flags, i, value), codegen


@numba.extending.intrinsic
def fetch_add(typingctx, flags, i, value):
    """``flags[i] += value`` as one atomic step (``lock xadd``): the value before."""
    return _atomic_add(flags, i, value, "monotonic")


@numba.extending.intrinsic
def fetch_add_acq_rel(typingctx, flags, i, value):
    """:func:`fetch_add` that also orders memory: what a thread wrote before it is visible to a thread that
    adds after it (the last of several threads to finish a piece of work reads what the others wrote)."""
    return _atomic_add(flags, i, value, "acq_rel")


_PAUSE = "llvm.x86.sse2.pause" if platform.machine().lower() in ("x86_64", "amd64", "i686", "i386") else None


@numba.extending.intrinsic
def cpu_pause(typingctx):
    """The x86 ``pause`` of a polling loop (leaves the core's resources to its sibling); nothing elsewhere."""
    def codegen(context, builder, signature, args):
        if _PAUSE:
            fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), []), _PAUSE)
            builder.call(fn, [])
        return context.get_dummy_value()

    return numba.types.void(), codegen


def _yield_symbol():
    """``sched_yield`` of the C library made known to LLVM's linker (None where there is none)."""
    import ctypes

    try:
        fn = ctypes.CDLL(None).sched_yield
    except (AttributeError, OSError, TypeError):
        return None
    llvmlite.binding.add_symbol("sched_yield", ctypes.cast(fn, ctypes.c_void_p).value)
    return "sched_yield"


_YIELD = _yield_symbol()


@numba.extending.intrinsic
def cpu_yield(typingctx):
    """``sched_yield()``: the core goes to another thread that is ready to run on it, if any."""
    def codegen(context, builder, signature, args):
        if _YIELD:
            fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(32), []), _YIELD)
            builder.call(fn, [])
        return context.get_dummy_value()

    return numba.types.void(), codegen


@kernel(nogil=True)
def wait_while(flags, i, seen, polls):
    """Poll ``flags[i]`` at most ``polls`` times while it equals ``seen``, without the GIL: its value at the end.

    Every 32nd poll yields the core: where threads outnumber the cores, one with work runs."""
    for k in range(polls):
        v = load_acquire(flags, i)
        if v != seen:
            return v
        if k % 32 == 31:
            cpu_yield()
        else:
            cpu_pause()
    return seen


@kernel(nogil=True)
def post_then_wait(flags, i_post, value, i_wait, seen, polls):
    """``flags[i_post] = value``, then :func:`wait_while` on ``flags[i_wait]``: a worker says it is done with the GIL
    already given up, so the caller that sees it never waits for the GIL."""
    store_release(flags, i_post, value)
    return wait_while(flags, i_wait, seen, polls)


@kernel(nogil=True)
def post_each_then_wait(flags, slots, values, watched, seen, polls):
    """``flags[slots[k]] = values[k]`` for each k, then :func:`wait_while` on ``watched[0]``: the posts are made with
    the GIL given up, so a worker that sees its post takes the GIL at once instead of sleeping until it is free."""
    for k in range(slots.size):
        store_release(flags, slots[k], values[k])
    return wait_while(watched, 0, seen, polls)
