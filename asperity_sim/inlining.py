"""numba's inlining of ``inline="always"`` kernels, without its copies of an IR built for one call site.

Owns :func:`install`, which :mod:`asperity_sim.jit` calls when it is imported.

numba inlines a function marked ``inline="always"`` at each of its call sites (the
``InlineInlinables`` pass): ``InlineWorker.inline_function`` builds the callee's IR afresh for
that site (``run_untyped_passes``) and hands it to ``InlineWorker.inline_ir``, which deep-copies
it twice, one copy to splice into the caller and one to return untouched, before it splices.
Neither copy guards anything on this path: the IR was built for this site alone, and numba's one
caller of ``inline_function`` throws the returned copy away.  Yet ``copy.deepcopy`` of numba's IR
is slow (numba issue 8989), and the package's kernels nest their inlined functions deeply (the
springs of a contact, the series trigonometry of its angle): the copies were most of the time
numba spent inlining, and a large part of a first run's compile.

:func:`install` gives ``InlineWorker`` an ``inline_function`` that runs ``inline_ir`` with each
"copy" the object itself.  Only the copies go: the IR spliced into the caller is the one numba
would have spliced, so the compiled code is the same (``tests/test_inlining.py`` compares the
LLVM IR of a nest of inlined functions compiled both ways).  ``inline_ir`` itself, which numba
also calls on IR it keeps (typed inlining of overloads), is untouched.  Installed only for the
numba versions it was checked with (:data:`CHECKED`); ``ASPERITY_SIM_FAST_INLINE=0`` leaves numba
as it is.
"""

from __future__ import annotations

import copy
import os

import numba
from numba.core import inline_closurecall

__all__ = ["install", "installed", "CHECKED", "ENV"]

ENV = "ASPERITY_SIM_FAST_INLINE"
"""Environment variable: ``0`` leaves numba's inlining as it is."""
CHECKED = ("0.68",)
"""The numba releases (major.minor) whose ``InlineWorker`` this was checked against."""

_NUMBA_INLINE_FUNCTION = inline_closurecall.InlineWorker.inline_function


class _ByReference:
    """Stands in for the ``copy`` module inside ``inline_ir`` while it inlines a freshly built IR."""

    @staticmethod
    def deepcopy(x, memo=None):
        return x


def _inline_function(self, caller_ir, block, i, function, arg_typs=None):
    """``InlineWorker.inline_function`` without the copies of the IR it builds for this call site (module docstring)."""
    callee_ir = self.run_untyped_passes(function)
    inline_closurecall.copy = _ByReference
    try:
        return self.inline_ir(caller_ir, block, i, callee_ir, function.__code__.co_freevars, arg_typs=arg_typs)
    finally:
        inline_closurecall.copy = copy


def installed() -> bool:
    """True if numba's inlining runs without the copies in this process."""
    return inline_closurecall.InlineWorker.inline_function is _inline_function


def install() -> bool:
    """Give numba's ``InlineWorker`` the copy-free ``inline_function`` (module docstring); True if it has it."""
    version = ".".join(numba.__version__.split(".")[:2])
    if (os.environ.get(ENV, "1") == "0" or version not in CHECKED or inline_closurecall.copy is not copy
            or inline_closurecall.InlineWorker.inline_function is not _NUMBA_INLINE_FUNCTION):
        return installed()
    inline_closurecall.InlineWorker.inline_function = _inline_function
    return True
