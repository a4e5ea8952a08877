"""How a function becomes a compiled kernel: its compile options, and an on-disk cache that cannot go stale.

Owns the two decorators every kernel of the package is written with:

- :func:`kernel` (``@kernel(parallel=True)``): compiled as written, ``numba.njit(cache=True, ...)``;
- :func:`template` (``@template(parallel=True)``): a generic reduction whose law kernels are
  placeholders, compiled once per law by :mod:`asperity_sim.kernels.specialise` with the
  options given here.

The first compile of each group of kernels in a process (a law's reductions, the other kernels)
says so once on a terminal (:class:`CompileNotice`): a first run after an install or an upgrade
waits for the compiler, and the user should know why.  Importing it also makes numba inline the
``inline="always"`` kernels without copying their IR (:mod:`asperity_sim.inlining`).

Why a fingerprint.  numba caches a compiled kernel on disk and reuses it as long as the
kernel's own source file is unchanged; it does not notice an edit in a function the kernel
calls from another file, and would go on running the old code.  A kernel can only call
compiled code, and every compiled function of the package is written with one of these
decorators or with numba itself (intrinsics), so :func:`source_fingerprint` hashes every
source file that holds one (:data:`COMPILED`), and every cached kernel is
compiled under a name that carries the fingerprint (``hertz__3f2a...``): an edit anywhere in a
kernel's call graph gives every kernel a new name, hence a fresh compile, never a stale one.
"""

from __future__ import annotations

import functools
import hashlib
import re
import sys
from pathlib import Path

import numba
from numba.core import event

from . import inlining

__all__ = ["kernel", "template", "kernel_sources", "source_fingerprint", "tag", "group_of", "CompileNotice"]

PACKAGE = Path(__file__).resolve().parent
COMPILED = re.compile(rb"^@(kernel|template)\(|^\s*(import|from) numba\b", flags=re.M)
"""What marks a source file that holds compiled code: a decorator of this module, or an import of numba."""


def kernel_sources() -> list:
    """The source files of the package that hold compiled code, sorted."""
    return sorted(p for p in PACKAGE.rglob("*.py") if COMPILED.search(p.read_bytes()))


@functools.cache
def source_fingerprint() -> str:
    """Short hash of every source file of the package that holds compiled code (paths and contents)."""
    h = hashlib.sha256()
    for path in kernel_sources():
        h.update(path.relative_to(PACKAGE).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:12]


def tag(f, label: str):
    """``f`` with ``label`` appended to its qualified name, which names its entries in numba's cache.

    Only identifier characters: numba builds variable names from the names of the functions a
    parallel loop calls.
    """
    f.__qualname__ = f"{f.__qualname__}__{re.sub(r'[^0-9A-Za-z_]', '_', label)}"
    return f


def kernel(**options):
    """Decorator: compile ``f`` with ``numba.njit(cache=True, **options)`` under the source fingerprint."""
    def compile_(f):
        return numba.njit(cache=True, **options)(tag(f, source_fingerprint()))

    return compile_


def ready(dispatcher, args) -> bool:
    """True if ``dispatcher`` has machine code for ``args`` in this process or in numba's on-disk cache (then loaded):
    a call with them compiles nothing."""
    sig = tuple(numba.typeof(a) for a in args)
    if sig in dispatcher.overloads:
        return True
    if dispatcher._cache.load_overload(sig, dispatcher.targetctx) is None:  # the key numba's own compile uses
        return False
    dispatcher.compile(sig)  # loads what the cache holds
    return True


def template(**options):
    """Decorator: mark ``f`` as a reduction template compiled per law with ``numba.njit(cache=True, **options)``.

    ``f`` stays a plain Python function; :func:`asperity_sim.kernels.specialise.specialise`
    compiles a copy of it for each law, with the law's kernels bound to its placeholders.
    """
    def mark(f):
        f.jit_options = {"cache": True, **options}
        return f

    return mark


def group_of(f):
    """The compile group of a function: ``<law>_<policy>`` for a law's reductions
    (``slot_pass__mdr_follow_<fingerprint>``), "shared" for the package's other kernels, None outside the package."""
    if not f.__module__.startswith(PACKAGE.name + "."):
        return None
    name = f.__qualname__
    group = name.split("__", 1)[1].rpartition("_")[0] if name.count("__") and "_" in name.split("__", 1)[1] else ""
    return group or "shared"


class CompileNotice(event.Listener):
    """Says once per group, on a terminal, that the package's kernels are being compiled.

    numba announces every compile that its on-disk cache could not serve (``numba:compile``);
    a kernel of the package compiled for the first time in this process starts its group's line:
    the law and angle policy of the reductions specialised for them
    (``slot_pass__mdr_follow_<fingerprint>``), "shared" for the others.  Nothing is said when
    stderr is not a terminal (``isatty``).
    """

    def __init__(self, stream=None, isatty=None):
        self.stream, self.isatty, self.said = stream, isatty, set()

    def on_start(self, ev):
        f = getattr((ev.data or {}).get("dispatcher"), "py_func", None)
        group = None if f is None else group_of(f)
        if group is None:
            return
        stream = self.stream or sys.stderr
        if group in self.said or not (self.isatty or stream.isatty)():
            return
        self.said.add(group)
        law, _, policy = group.rpartition("_")
        what = "the shared kernels" if group == "shared" else f"the {law} law's kernels (policy {policy})"
        print(f"asperity_sim: compiling {what} (first run after an install or an upgrade only: later runs load "
              "them from numba's cache; `asperity-sim warmup` compiles them ahead)", file=stream, flush=True)

    def on_end(self, ev):
        pass


NOTICE = CompileNotice()
event.register("numba:compile", NOTICE)
inlining.install()  # before any kernel compiles: numba's inlining without its copies (asperity_sim.inlining)
