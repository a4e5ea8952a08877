"""Compile ahead on the other core: the kernels a first run needs last, while this process compiles the others.

Owns :func:`expect`, :func:`start`, :func:`compiling`, :func:`wait_for` and the listener that starts the helper.
A first run with an empty numba cache compiles its kernels one after the other on one core:
the sampling kernels, then the evaluation (for a history law its trial, then its commit). A
helper process (:mod:`asperity_sim.kernels.ahead_helper`) compiles the ones needed last on a
tiny population into numba's on-disk cache, and says the name of each as it is done:

- a history law: its commit kernels (:data:`COMMIT_KERNELS`), while this process compiles the trial;
- a law without history (policy follow): its evaluation kernel (:func:`evaluation_kernel`: the
  serial one for a population that fits it, else the parallel one), while this process compiles
  the sampling kernels.

The helper starts when numba starts compiling the first kernel of the package in this process
(a cache miss) for the run a driver announced (:func:`expect`), or, without one, the first kernel
of a history law's group. Before this process first calls a helper's kernel, :func:`wait_for`
waits until the helper has said it, and numba loads it from the cache.

Only where it pays and cannot surprise: a law registered when the package is imported (one
registered at run time is unknown to a fresh process), more than one numba thread (a spare
core), and not inside the helper itself or with ``ASPERITY_SIM_COMPILE_AHEAD=0``.  If the helper fails, this process
compiles the kernels itself, as it would have.
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import threading

import numba
from numba.core import event

from .. import jit, laws

__all__ = ["wait_for", "compiling", "start", "expect", "pending", "kernel_names", "evaluation_kernel", "ENV"]

ENV = "ASPERITY_SIM_COMPILE_AHEAD"
"""Environment variable: ``0`` turns compiling ahead off (the helper runs with it)."""
HELPER = "asperity_sim.kernels.ahead_helper"
"""The module the helper runs."""
COMMIT_KERNELS = ("commit_fresh", "commit_slots")
"""The kernels the helper compiles for a history law, in the order a run first calls them."""

BUILT_IN = frozenset(laws.LAWS)
"""The laws a fresh process knows (registered when the package is imported): the only ones a helper can compile."""
_PENDING: dict = {}  # kernel qualname -> the helper compiling it
_LOCK = threading.Lock()
_EXPECTED: list = []  # (law name, birth, serial) of the run being set up in this process (expect)
_IDLE: list = []  # modules the run imports after its kernels: imported instead while it waits on a helper (expect)


def evaluation_kernel(serial: bool) -> str:
    """The evaluation kernel of a law without history: the serial one (populations that fit it) or the parallel."""
    return "reduce_serial" if serial else "reduce_parallel"


def kernel_names(law, birth: bool, serial: bool = True) -> list:
    """The qualified names of the kernels a helper compiles for the law under the policy, in the order it says them:
    a history law's :data:`COMMIT_KERNELS`, else its :func:`evaluation_kernel`."""
    from .specialise import kernels  # specialise imports the templates, which are heavy: only when needed

    keys = COMMIT_KERNELS if law.history is not None else (evaluation_kernel(serial),)
    return [kernels(law, birth=birth)[k].py_func.__qualname__ for k in keys]


def expect(law_name, birth: bool = False, serial: bool = True, imports=()) -> None:
    """Announce the run this process sets up next (its law, policy, and whether its population fits the serial
    kernel): a helper for it starts at the first compile of any kernel of the package, before the run needs its own.
    ``imports``: modules the run imports once its kernels are compiled (its output's), imported instead while
    it would wait idle on the helper.  ``law_name`` None: no run is being set up (the announcement ends; the
    imports stay until a wait or the next announcement)."""
    _EXPECTED[:] = [] if law_name is None else [(law_name, birth, serial)]
    if law_name is not None:
        _IDLE[:] = imports


def pending() -> set:
    """The kernels (qualified names) a helper is compiling for this process."""
    with _LOCK:
        return set(_PENDING)


def compiling(dispatcher) -> bool:
    """True if a helper is compiling ``dispatcher`` for this process (what this process might do meanwhile)."""
    return bool(_PENDING) and dispatcher.py_func.__qualname__ in pending()


def wait_for(dispatcher) -> None:
    """Return once no helper is compiling ``dispatcher`` (at once, unless a helper was started for it)."""
    if not _PENDING:  # the common case, once the cache is warm: no lock
        return
    name = dispatcher.py_func.__qualname__
    with _LOCK:
        process = _PENDING.get(name)
        if process is None:
            return
        while _IDLE:  # this process would only wait: the run's later imports now, off its critical path
            importlib.import_module(_IDLE.pop(0))
        while name in _PENDING:  # the helper says each kernel as it is cached, in order
            line = process.stdout.readline()
            if not line:  # done or failed: what it did not say, this process compiles
                process.wait()
                process.stdout.close()
                for k in [k for k, h in _PENDING.items() if h is process]:
                    del _PENDING[k]
                break
            _PENDING.pop(line.strip(), None)


def start(law_name: str, birth: bool, helper: str = HELPER, serial: bool = True) -> bool:
    """Start the helper (module ``helper``) for the kernels of :func:`kernel_names`; False if there is none to start
    (a law unknown to a fresh process, a law without history under policy birth) or it cannot be started."""
    law = laws.get(law_name)
    if law.name not in BUILT_IN or (law.history is None and birth):
        return False
    if getattr(sys, "frozen", False):  # a bundled application: sys.executable is not a Python to run -m with
        return False
    names = kernel_names(law, birth, serial)
    # this very package first on the helper's path, whatever put it on this process's
    path = os.pathsep.join(p for p in (str(jit.PACKAGE.parent), os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, ENV: "0", "PYTHONPATH": path}
    args = [law.name, "birth" if birth else "follow", "serial" if serial else "parallel"]
    try:
        process = subprocess.Popen([sys.executable, "-m", helper, *args], stdout=subprocess.PIPE,
                                   stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL, env=env, text=True)
    except OSError:
        return False
    with _LOCK:
        for name in names:
            _PENDING[name] = process
    return True


class _FirstCompile(event.Listener):
    """Starts the helper when numba first compiles a kernel of the package in this process: for the run announced
    by :func:`expect`, else (at the first kernel of a history law's group) for that law."""

    def __init__(self):
        self.seen = set()  # (law name, birth) a helper was started or considered for

    def on_start(self, ev):
        f = getattr((ev.data or {}).get("dispatcher"), "py_func", None)
        if f is None or os.environ.get(ENV, "1") == "0" or numba.get_num_threads() < 2:
            return
        group = jit.group_of(f)
        if group is None:
            return
        if _EXPECTED and _EXPECTED[0][:2] not in self.seen:
            law, birth, serial = _EXPECTED[0]
            self.seen.add((law, birth))
            if f.__qualname__ not in kernel_names(laws.get(law), birth, serial):  # else this process compiles it now
                start(law, birth, serial=serial)
        law, _, policy = group.rpartition("_")
        if law in BUILT_IN and policy in ("follow", "birth") and (law, policy == "birth") not in self.seen:
            self.seen.add((law, policy == "birth"))
            if laws.get(law).history is not None:  # a law without history: its first kernel is the one to help
                start(law, policy == "birth")

    def on_end(self, ev):
        pass


event.register("numba:compile", _FirstCompile())
