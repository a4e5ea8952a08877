"""Load paths under mixed force/displacement control (SPEC §6–§7).

Owns the description of a loading programme: a path is a sequence of stages; in each
stage every component k = 1, 2, 3 is either displacement controlled (Delta_k goes
linearly to a target [m]) or stress controlled (sigma_k goes linearly to a target
[Pa]) from its value at the start of the stage, over a number of increments.

Bounded work (issue 24, item 4): a stage is refused up front when it would make the driver's
adaptive loop unbounded.  The largest increment of an adaptive stage is ``max_fraction`` of
the stage, so a stage takes at least 1/max_fraction increments: ``max_fraction`` must be at
least :data:`MIN_FRACTION` (1e-6, i.e. at most a million increments at full size; 1e-12 made
a stage that never ended and grew memory).  :attr:`Stage.budget` is the most converged
increments a stage may take, cut-backs and shrinking included (:data:`BUDGET_FACTOR` times
its nominal count, plus :data:`BUDGET_SLACK`); the driver stops a stage that exceeds it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .checks import check_int, check_real

MIN_FRACTION = 1e-6
"""Smallest ``max_fraction`` of a stage: at most 1e6 increments of the largest size."""
BUDGET_FACTOR = 4
"""A stage may take this many times its nominal increment count (see :attr:`Stage.budget`) ..."""
BUDGET_SLACK = 64
"""... plus this many, for the cut-backs of a short stage."""

DISPLACEMENT = "displacement"
STRESS = "stress"
_ALIASES = {"displacement": DISPLACEMENT, "d": DISPLACEMENT, "stress": STRESS, "s": STRESS}


def _as_tuple(value):
    """tuple(value) for a non-string iterable, else None."""
    if isinstance(value, (str, bytes)):
        return None
    try:
        return tuple(value)
    except TypeError:
        return None


@dataclass(frozen=True)
class Stage:
    """One stage of a load path.

    Parameters
    ----------
    control : 3 strings, each ``"displacement"`` (``"d"``) or ``"stress"`` (``"s"``)
    target : 3 floats, Delta_k [m] or sigma_k [Pa] reached at the end of the stage
    increments : int, number of equal increments (the driver halves one that fails)
    adaptive : bool, let the increment grow after easy convergence, up to
        ``max_fraction`` of the stage, and shrink after hard convergence
    max_fraction : float in [1e-6, 1], largest increment as a fraction of the stage (adaptive
        only; :data:`MIN_FRACTION` bounds the number of increments, see the module docstring)
    name : str, label recorded in the output
    """

    control: tuple = (DISPLACEMENT, DISPLACEMENT, DISPLACEMENT)
    target: tuple = (0.0, 0.0, 0.0)
    increments: int = 50
    adaptive: bool = False
    max_fraction: float = 0.1
    name: str = ""

    def __post_init__(self):
        control = _as_tuple(self.control)
        if control is None or len(control) != 3:
            raise ValueError(f"control = {self.control!r} must name 3 components, each 'displacement' or 'stress'")
        mapped = []
        for k, c in enumerate(control, 1):
            if c not in _ALIASES:
                raise ValueError(f"control[{k}] = {c!r} is not known (valid: 'displacement'/'d', 'stress'/'s')")
            mapped.append(_ALIASES[c])
        object.__setattr__(self, "control", tuple(mapped))
        target = _as_tuple(self.target)
        if target is None or len(target) != 3:
            raise ValueError(f"target = {self.target!r} must have 3 components ([m] or [Pa])")
        units = {DISPLACEMENT: "m", STRESS: "Pa"}
        object.__setattr__(self, "target", tuple(
            check_real(f"target[{k}] [{units[c]}]", t) for k, (c, t) in enumerate(zip(mapped, target), 1)))
        object.__setattr__(self, "increments", check_int("increments", self.increments, 1, 10**7))
        if not isinstance(self.adaptive, bool):
            raise ValueError(f"adaptive = {self.adaptive!r} must be True or False")
        try:
            mf = check_real("max_fraction", self.max_fraction, MIN_FRACTION, 1.0)
        except ValueError as err:
            raise ValueError(f"{err}; a stage takes at least 1/max_fraction increments, so a smaller fraction "
                             "would make an adaptive stage practically unbounded (issue 24)") from None
        object.__setattr__(self, "max_fraction", mf)
        if not isinstance(self.name, str):
            raise ValueError(f"name = {self.name!r} must be a string")

    @property
    def nominal_increments(self) -> int:
        """Increments the stage takes when nothing is cut back: ``increments``, or for an adaptive
        stage at least 1/max_fraction (its increments never grow beyond max_fraction)."""
        if self.adaptive:
            return max(self.increments, math.ceil(1.0 / self.max_fraction - 1e-9))
        return self.increments

    @property
    def budget(self) -> int:
        """Most converged increments this stage may take before the driver must stop it.

        ``BUDGET_FACTOR * nominal_increments + BUDGET_SLACK`` (4 n + 64): room for the cut-backs
        of a hard stretch (each halving costs one more increment, later ones grow back), never
        an unbounded loop. At most 4e7 + 64 (``increments`` <= 1e7, ``max_fraction`` >= 1e-6).
        """
        return BUDGET_FACTOR * self.nominal_increments + BUDGET_SLACK

    @property
    def stress_controlled(self) -> np.ndarray:
        """Boolean mask (3,) of the stress-controlled components."""
        return np.array([c == STRESS for c in self.control])


@dataclass(frozen=True)
class LoadPath:
    """A sequence of stages, applied from zero displacement and zero stress."""

    stages: tuple = field(default_factory=tuple)
    name: str = "custom"

    def __post_init__(self):
        stages = _as_tuple(self.stages)
        if not stages or not all(isinstance(s, Stage) for s in stages):
            raise ValueError(f"stages = {self.stages!r} must be a non-empty sequence of Stage")
        object.__setattr__(self, "stages", stages)

    def __len__(self):
        return len(self.stages)

    def describe(self) -> str:
        lines = []
        for i, s in enumerate(self.stages, 1):
            parts = [f"{'sigma' if c == STRESS else 'Delta'}_{k} -> {t:.4g} {'Pa' if c == STRESS else 'm'}"
                     for k, (c, t) in enumerate(zip(s.control, s.target), 1)]
            lines.append(f"stage {i} ({s.name or 'unnamed'}, {s.increments} increments): " + ", ".join(parts))
        return "\n".join(lines)


def three_step(d_max: float, increments: int = 30) -> LoadPath:
    """The paper's 3-step path (SPEC §7, Fig. 10): Delta_1, then Delta_2, then Delta_3 to d_max [m]."""
    d = check_real("d_max [m]", d_max, 0.0, None, lo_open=True)
    D = DISPLACEMENT
    return LoadPath((
        Stage((D, D, D), (d, 0.0, 0.0), increments, name="step 1: normal closure"),
        Stage((D, D, D), (d, d, 0.0), increments, name="step 2: shear along 2"),
        Stage((D, D, D), (d, d, d), increments, name="step 3: shear along 3"),
    ), name="three_step")


def constant_normal_shear(sigma_n: float, d2_max: float, increments: int = 40,
                          normal_increments: int | None = None) -> LoadPath:
    """Shear at constant normal stress (SPEC §7, Fig. 13).

    Stage 1: sigma_1 from 0 to sigma_n [Pa] with Delta_2 = Delta_3 = 0; stage 2: sigma_1
    held, Delta_2 from 0 to d2_max [m], Delta_3 = 0.
    """
    s_n = check_real("sigma_n [Pa]", sigma_n, 0.0, None, lo_open=True)
    d2 = check_real("d2_max [m]", d2_max, 0.0, None, lo_open=True)
    n1 = increments if normal_increments is None else normal_increments
    S, D = STRESS, DISPLACEMENT
    return LoadPath((
        Stage((S, D, D), (s_n, 0.0, 0.0), n1, name="normal loading"),
        Stage((S, D, D), (s_n, d2, 0.0), increments, name="shear at constant normal stress"),
    ), name="constant_normal_shear")
