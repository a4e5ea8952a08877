"""Software prefetch for the kernels that walk the spring store contact by contact.

The hardware prefetchers follow a stream, but a loop over committed contacts visits a few
cache lines per contact and then does tens of nanoseconds of arithmetic: when the store
does not fit in the cache (millions of contacts), each contact's springs arrive from memory
while the core waits.  Asking for the lines of a contact a few contacts ahead overlaps the
two.  A prefetch is a hint: it changes no value, only when a line arrives.
"""

from __future__ import annotations

import llvmlite.binding
import numba
from llvmlite import ir
from numba.core import cgutils

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
