"""Every exception and warning type the package raises of its own.

A run stops only with a named :class:`SimulationError` that says why (each carries the
converged part of the run as ``.dataset``), never with NaN; an input that cannot be used is a
``ValueError`` naming the value and the valid range, or one of its subclasses naming where it
came from (:class:`CheckpointError`, :class:`SceneError`, :class:`SurfaceError`); a
path-independent law driven outside its domain warns with :class:`LawDomainWarning`, and a fit
of a topography whose summits describe the instrument rather than the surface (pixel-scale
summits, quantised heights, scan-line artefacts, non-square pixels, missing data) warns with
:class:`SurfaceScaleWarning`.
"""

from __future__ import annotations


class Deadline(Exception):
    """The wall-time limit passed during an increment (turned into WallTimeExceededError by the loop)."""


class SimulationError(RuntimeError):
    """A run stopped before the end of its path; ``.dataset`` holds every converged increment."""

    def __init__(self, message, dataset=None):
        super().__init__(message)
        self.dataset = dataset


class StressNotReachableError(SimulationError):
    """A prescribed stress cannot be carried by the interface (e.g. shear above its strength)."""


class ConvergenceError(SimulationError):
    """An increment did not converge even after the largest number of cut-backs."""


class OutputWriteError(SimulationError):
    """A run completed but its output file could not be written; ``.dataset`` holds the complete result."""


class WallTimeExceededError(SimulationError):
    """The run took longer than its ``max_wall_time``; ``.dataset`` holds every converged increment."""


class CheckpointError(ValueError):
    """A checkpoint cannot be used: unreadable, another version or format, or another run."""


class InteractionRunawayError(ValueError):
    """No closure of the contacts carries the interface displacement under the mean-field elastic interaction
    (kappa T_11 would reach 1: the contacts' load runs away).  Within a stress-controlled solve this marks a
    trial displacement beyond the load's reach, and the solver steps back (:mod:`asperity_sim.solve.solver`)."""


class LawDomainWarning(UserWarning):
    """A path-independent law was driven along a path outside its domain (see :mod:`asperity_sim.solve.domain`)."""


class SurfaceError(ValueError):
    """A topography that cannot be used; the message names the file or value and what is allowed."""


class SurfaceScaleWarning(UserWarning):
    """A fit's summits may describe the instrument rather than the surface (see
    :mod:`asperity_sim.analysis.surfaces.diagnosis`): the message says what was measured, the
    threshold it passed and what to do (usually ``--cutoff``)."""


class SceneError(ValueError):
    """A scene or sweep file that cannot be used; the message says where, what and what is allowed."""
