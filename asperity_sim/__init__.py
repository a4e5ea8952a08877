"""asperity_sim: Monte Carlo simulator of rough interfaces (Misra & Huang, SPEC.md)."""

__version__ = "0.1.0"

from . import presets
from .params import InterfaceParams

__all__ = ["InterfaceParams", "presets", "__version__"]
