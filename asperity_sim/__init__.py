"""asperity_sim: Monte Carlo simulator of rough interfaces (Misra & Huang 2012; see docs/model.md).

Public API: parameters (``InterfaceParams``, ``presets``), a sampled ``Population`` with
``evaluate``, load ``paths``, ``simulate`` (and ``resume`` from a checkpoint) and the quadrature
``reference``.
"""

__version__ = "0.3.0"

import os as _os

# Idle OpenMP threads of numba's parallel kernels spin by default and steal the cores from
# other processes (sweep workers, other jobs); sleeping costs microseconds per kernel call.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from . import paths, presets, reference
from .params import InterfaceParams
from .population import Population
from .driver import (ConvergenceError, OutputWriteError, SimulationError, StressNotReachableError,
                     WallTimeExceededError, resume, simulate)
from .checkpoint import CheckpointError
from .solver import SolverSettings
from .single import single_contact
from .domain import LawDomainWarning
from . import laws

__all__ = [
    "InterfaceParams", "presets", "Population", "paths", "simulate", "resume", "single_contact", "reference",
    "SolverSettings",
    "SimulationError", "StressNotReachableError", "ConvergenceError", "WallTimeExceededError", "OutputWriteError",
    "CheckpointError", "LawDomainWarning", "laws",
    "__version__",
]
