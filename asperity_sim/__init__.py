"""asperity_sim: Monte Carlo simulator of rough interfaces (Misra & Huang 2012; see docs/model.md).

Public API: parameters (``InterfaceParams``, ``presets``), a sampled ``Population`` and its
response at one displacement (``evaluate``), load ``paths``, ``simulate`` (and ``resume`` from a
checkpoint), one contact (``single_contact``), the asperity ``laws`` and the quadrature
``reference``.  The subpackages follow the data flow (docs/architecture.md): ``sampling`` →
``laws`` → ``kernels`` → ``solve`` → ``output``, with ``reference``, ``analysis``, ``runs`` and
``ui`` beside them.
"""

import os as _os

# Idle OpenMP threads of numba's parallel kernels spin by default and steal the cores from
# other processes (sweep workers, other jobs); sleeping costs microseconds per kernel call.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from . import deprecated as _deprecated  # noqa: E402
from . import laws, paths, presets, reference  # noqa: E402
from .errors import (  # noqa: E402
    CheckpointError,
    ConvergenceError,
    LawDomainWarning,
    OutputWriteError,
    SimulationError,
    StressNotReachableError,
    WallTimeExceededError,
)
from .kernels.evaluate import evaluate  # noqa: E402
from .params import InterfaceParams  # noqa: E402
from .sampling.population import Population  # noqa: E402
from .solve.driver import resume, simulate  # noqa: E402
from .solve.single import single_contact  # noqa: E402
from .solve.solver import SolverSettings  # noqa: E402
from .version import __version__  # noqa: E402

_deprecated.install()

__all__ = [
    "InterfaceParams", "presets", "Population", "evaluate", "paths", "simulate", "resume", "single_contact",
    "reference", "SolverSettings",
    "SimulationError", "StressNotReachableError", "ConvergenceError", "WallTimeExceededError", "OutputWriteError",
    "CheckpointError", "LawDomainWarning", "laws",
    "__version__",
]


def __getattr__(name):
    """0.3's module paths (``asperity_sim.kernels.evaluate``, ...), deprecated: see :mod:`asperity_sim.deprecated`."""
    return _deprecated.moved_module(name)
