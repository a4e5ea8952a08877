"""asperity_sim: Monte Carlo simulator of rough interfaces (Misra & Huang 2012; see docs/model.md).

Public API: parameters (``InterfaceParams``, ``presets``), a sampled ``Population`` and its
response at one displacement (``evaluate``), load ``paths``, ``simulate`` (and ``resume`` from a
checkpoint), one contact (``single_contact``), the asperity ``laws`` and the quadrature
``reference``.  The subpackages follow the data flow (docs/architecture.md): ``sampling`` →
``laws`` → ``kernels`` → ``solve`` → ``output``, with ``reference``, ``analysis``, ``runs`` and
``ui`` beside them.
"""

import importlib as _importlib
import os as _os

# Idle OpenMP threads of numba's parallel kernels spin by default and steal the cores from
# other processes (sweep workers, other jobs); sleeping costs microseconds per kernel call.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from typing import TYPE_CHECKING  # noqa: E402

from . import deprecated as _deprecated  # noqa: E402
from .errors import (  # noqa: E402
    CheckpointError,
    ConvergenceError,
    LawDomainWarning,
    OutputWriteError,
    SimulationError,
    StressNotReachableError,
    WallTimeExceededError,
)
from .version import __version__  # noqa: E402

# The rest of the public API is imported at its first use (PEP 562): what it imports (xarray,
# pandas, the reference's scipy) takes about half a second, which a first run would pay before it
# starts compiling, and so would the compile-ahead helper (asperity_sim.kernels.ahead), a fresh
# process that needs none of it.
_LAZY = {
    "InterfaceParams": "params",
    "Population": "sampling.population",
    "evaluate": "kernels.evaluate",
    "simulate": "solve.driver",
    "resume": "solve.driver",
    "single_contact": "solve.single",
    "SolverSettings": "solve.solver",
}
_SUBPACKAGES = ("laws", "paths", "presets", "reference")

if TYPE_CHECKING:  # what the names are, for type checkers and documentation tools
    from . import laws, paths, presets, reference
    from .kernels.evaluate import evaluate
    from .params import InterfaceParams
    from .sampling.population import Population
    from .solve.driver import resume, simulate
    from .solve.single import single_contact
    from .solve.solver import SolverSettings

_deprecated.install()

__all__ = [
    "InterfaceParams", "presets", "Population", "evaluate", "paths", "simulate", "resume", "single_contact",
    "reference", "SolverSettings",
    "SimulationError", "StressNotReachableError", "ConvergenceError", "WallTimeExceededError", "OutputWriteError",
    "CheckpointError", "LawDomainWarning", "laws",
    "__version__",
]


def __getattr__(name):
    """The public names imported at their first use (``_LAZY``, the subpackages), then 0.3's module paths
    (``asperity_sim.assemble``, ...), deprecated: see :mod:`asperity_sim.deprecated`."""
    if name in _LAZY:
        value = getattr(_importlib.import_module(f".{_LAZY[name]}", __name__), name)
    elif name in _SUBPACKAGES:
        value = _importlib.import_module(f".{name}", __name__)
    else:
        return _deprecated.moved_module(name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
