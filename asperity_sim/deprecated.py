"""The module paths of asperity_sim 0.3, kept working for one release with a ``DeprecationWarning``.

0.4 laid the package out as the model flows (docs/architecture.md; CHANGELOG lists what moved).
``import asperity_sim.assemble`` or ``asperity_sim.assemble.evaluate`` still work through 0.4:
the old module is a stand-in whose attributes are looked up, in order, in the modules its
contents moved to, and the first use of each old module warns once with where it went.  Nothing
in the package uses these paths.  Removed in 0.5.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings

#: old module (under asperity_sim) -> the modules its public names moved to, the main one first
MOVED = {
    "assemble": ("kernels.evaluate", "kernels.layout", "kernels.contact", "kernels.reach", "kernels.reductions",
                 "kernels.history", "kernels.commit", "kernels.specialise", "solve.stepping"),
    "state": ("kernels.state",),
    "population": ("sampling.population", "sampling.distributions", "sampling.draws", "sampling.reach"),
    "sobol": ("sampling.sobol",),
    "pruning": ("solve.pruning", "sampling.band"),
    "prefetch": ("vectormath",),
    "reference": ("reference",),
    "variables": ("output.variables",),
    "recorder": ("output.recorder",),
    "io": ("output.netcdf",),
    "checkpoint": ("output.checkpoint", "errors"),
    "plotting": ("output.plotting",),
    "solver": ("solve.solver",),
    "stepping": ("solve.stepping",),
    "domain": ("solve.domain", "errors"),
    "driver": ("solve.driver", "solve.run", "errors"),
    "run_checkpoint": ("solve.run_checkpoint",),
    "single": ("solve.single",),
    "gridmethod": ("analysis.gridmethod",),
    "properties": ("analysis.properties",),
    "surfaces": ("analysis.surfaces",),
    "scene": ("runs.scene", "units", "errors"),
    "sweep": ("runs.sweep", "runs.engine", "runs.ensemble", "runs.figures"),
    "envelope": ("runs.envelope", "runs.figures"),
    "progress": ("ui.progress",),
    "cli": ("ui.cli", "ui.parser", "ui.commands", "ui.reports", "ui.exits"),
}

_PACKAGE = __name__.rpartition(".")[0]
_warned: set = set()


def _warn(old: str, stacklevel: int) -> None:
    if old not in _warned:
        _warned.add(old)
        new = ", ".join(f"{_PACKAGE}.{m}" for m in MOVED[old])
        warnings.warn(f"{_PACKAGE}.{old} moved in 0.4 to {new}; the old path goes in 0.5", DeprecationWarning,
                      stacklevel=stacklevel)


class _Moved(types.ModuleType):
    """Stand-in for an old module: attributes come from the modules its contents moved to."""

    def __init__(self, old: str):
        super().__init__(f"{_PACKAGE}.{old}", f"moved in 0.4 to {', '.join(MOVED[old])} (deprecated path)")
        self._old = old

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        for m in MOVED[self._old]:
            module = importlib.import_module(f"{_PACKAGE}.{m}")
            if hasattr(module, name):
                return getattr(module, name)
        raise AttributeError(f"module {self.__name__!r} (moved) has no attribute {name!r}")

    def __dir__(self):
        names = set()
        for m in MOVED[self._old]:
            names.update(n for n in dir(importlib.import_module(f"{_PACKAGE}.{m}")) if not n.startswith("_"))
        return sorted(names)


class _Finder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Serves ``import asperity_sim.<old>`` with the stand-in (warning once)."""

    def find_spec(self, fullname, path=None, target=None):
        pkg, _, old = fullname.rpartition(".")
        if pkg == _PACKAGE and old in MOVED:
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec):
        old = spec.name.rpartition(".")[2]
        _warn(old, stacklevel=6)
        return _Moved(old)

    def exec_module(self, module):
        pass


def moved_module(old: str, stacklevel: int = 3):
    """The stand-in of ``asperity_sim.<old>`` (module ``__getattr__`` of the package), or AttributeError."""
    if old not in MOVED:
        raise AttributeError(f"module {_PACKAGE!r} has no attribute {old!r}")
    _warn(old, stacklevel)
    return importlib.import_module(f"{_PACKAGE}.{old}")


def _population_evaluate(self, delta, law="paper", policy="follow", theta_birth=None, workspace=None, state=None):
    """Deprecated: ``asperity_sim.evaluate(pop, delta, ...)`` (0.3's ``Population.evaluate``)."""
    warnings.warn("Population.evaluate(delta, ...) moved in 0.4 to asperity_sim.evaluate(pop, delta, ...); "
                  "the method goes in 0.5", DeprecationWarning, stacklevel=2)
    from .kernels.evaluate import evaluate

    return evaluate(self, delta, law=law, policy=policy, theta_birth=theta_birth, workspace=workspace, state=state)


def install() -> None:
    """Serve the old module paths and ``Population.evaluate`` (called once by the package's ``__init__``)."""
    from .sampling.population import Population

    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
    Population.evaluate = _population_evaluate
