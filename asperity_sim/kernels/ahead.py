"""Compile ahead on the other core: a history law's commit kernels, while this process compiles its trial.

Owns :func:`start`, :func:`wait_for` and the listener that starts the helper.  The first run of
a history law with an empty numba cache compiles its trial kernels, then its commit kernels, one after the
other on one core.  When numba starts compiling the first kernel of a law and policy in this
process (a cache miss: :mod:`asperity_sim.jit` names the group), a helper process
(:mod:`asperity_sim.kernels.ahead_helper`) compiles the commit kernels of that law and policy on
a tiny population into numba's on-disk cache, and says the name of each as it is done; before
this process first calls one of them (:meth:`~asperity_sim.kernels.state.ContactState.commit`),
:func:`wait_for` waits until the helper has said it, and numba loads it from the cache.

Only where it pays and cannot surprise: a law registered when the package is imported (one
registered at run time is unknown to a fresh process), more than one numba thread (a spare
core), and not inside the helper itself or with ``ASPERITY_SIM_COMPILE_AHEAD=0``.  If the helper fails, this process
compiles the kernels itself, as it would have.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import numba
from numba.core import event

from .. import jit, laws

__all__ = ["wait_for", "start", "pending", "commit_kernel_names", "ENV"]

ENV = "ASPERITY_SIM_COMPILE_AHEAD"
"""Environment variable: ``0`` turns compiling ahead off (the helper runs with it)."""
HELPER = "asperity_sim.kernels.ahead_helper"
"""The module the helper runs."""
COMMIT_KERNELS = ("commit_fresh", "commit_slots")
"""The kernels the helper compiles, in the order a run first calls them."""

BUILT_IN = frozenset(laws.LAWS)
"""The laws a fresh process knows (registered when the package is imported): the only ones a helper can compile."""
_PENDING: dict = {}  # kernel qualname -> the helper compiling it
_LOCK = threading.Lock()


def commit_kernel_names(law, birth: bool) -> list:
    """The qualified names of the law's :data:`COMMIT_KERNELS` under the policy, in order (what the helper says)."""
    from .specialise import kernels  # specialise imports the templates, which are heavy: only when needed

    return [kernels(law, birth=birth)[k].py_func.__qualname__ for k in COMMIT_KERNELS]


def pending() -> set:
    """The kernels (qualified names) a helper is compiling for this process."""
    with _LOCK:
        return set(_PENDING)


def wait_for(dispatcher) -> None:
    """Return once no helper is compiling ``dispatcher`` (at once, unless a helper was started for it)."""
    name = dispatcher.py_func.__qualname__
    with _LOCK:
        process = _PENDING.get(name)
        if process is None:
            return
        while name in _PENDING:  # the helper says each kernel as it is cached, in order
            line = process.stdout.readline()
            if not line:  # done or failed: what it did not say, this process compiles
                process.wait()
                process.stdout.close()
                for k in [k for k, h in _PENDING.items() if h is process]:
                    del _PENDING[k]
                break
            _PENDING.pop(line.strip(), None)


def start(law_name: str, birth: bool, helper: str = HELPER) -> bool:
    """Start the helper (module ``helper``) for the commit kernels of a history law under a policy; False if
    there is none to start (a law without history, or unknown to a fresh process) or it cannot be started."""
    law = laws.get(law_name)
    if law.history is None or law.name not in BUILT_IN:
        return False
    if getattr(sys, "frozen", False):  # a bundled application: sys.executable is not a Python to run -m with
        return False
    names = commit_kernel_names(law, birth)
    # this very package first on the helper's path, whatever put it on this process's
    path = os.pathsep.join(p for p in (str(jit.PACKAGE.parent), os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, ENV: "0", "PYTHONPATH": path}
    try:
        process = subprocess.Popen([sys.executable, "-m", helper, law.name, "birth" if birth else "follow"],
                                   stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL,
                                   env=env, text=True)
    except OSError:
        return False
    with _LOCK:
        for name in names:
            _PENDING[name] = process
    return True


class _FirstCompile(event.Listener):
    """Starts the helper when numba first compiles a kernel of a history law's group in this process."""

    def __init__(self):
        self.seen = set()

    def on_start(self, ev):
        f = getattr((ev.data or {}).get("dispatcher"), "py_func", None)
        if f is None or os.environ.get(ENV, "1") == "0" or numba.get_num_threads() < 2:
            return
        group = jit.group_of(f)
        if group in (None, "shared") or group in self.seen:
            return
        self.seen.add(group)
        law, _, policy = group.rpartition("_")
        if law in BUILT_IN and policy in ("follow", "birth"):
            start(law, policy == "birth")

    def on_end(self, ev):
        pass


event.register("numba:compile", _FirstCompile())
