"""Where a path-independent law leaves its domain along a run.

A path-independent law (the ``paper`` law, Cattaneo–Mindlin at constant normal force) gives
each contact's force from its current displacement alone.  It is valid for monotonic shear
in a fixed direction at constant normal force; on any other path it forgets what a real
contact remembers and can even return energy on a closed loop.  :class:`DomainMonitor`
watches the recorded steps of a run and flags, per step (bits of ``law_domain``):

- ``SHEAR_TURN`` (1): the shear displacement increment is not along the accumulated shear
  displacement (a reversal or a change of direction, by more than ``angle_tol``);
- ``NORMAL_CHANGE`` (2): the normal stress moved by more than ``normal_rtol`` (relative) from
  its value when shear began, while the interface is sheared;
- ``LOOP_WORK`` (4): the path came back to a displacement it had visited and the external work
  over that closed loop (trapezoid rule on the recorded stresses) is negative by more than
  ``loop_rtol`` of the work done along it: the law returned energy.

The driver warns once (:class:`LawDomainWarning`) with the first step flagged and records the
flags as the per-step variable ``law_domain``.  History laws (``mdr``) need none of this.
"""

from __future__ import annotations

import math

import numpy as np

from ..kernels.domain import (
    C_ANY,
    C_FIRST,
    C_FIRST_FLAGS,
    L_LOOP_WORK,
    L_SIGMA_REF,
    LOOP_WORK,
    N_COUNTS,
    N_LAST,
    N_TRACK,
    NORMAL_CHANGE,
    SHEAR_TURN,
    domain_step,
)

REASONS = {SHEAR_TURN: "the shear direction reversed or turned",
           NORMAL_CHANGE: "the normal stress changed during shear",
           LOOP_WORK: "the external work over a closed loop is negative (energy returned)"}


class DomainMonitor:
    """Flags the steps of a run where a path-independent law leaves its domain (module docstring).

    Its state is that of the compiled step (:func:`asperity_sim.kernels.domain.domain_step`), in arrays
    that the compiled increments of a stage update too (:meth:`room` first)."""

    def __init__(self, angle_tol=1e-6, normal_rtol=1e-2, loop_rtol=1e-3):
        self.angle_tol, self.normal_rtol, self.loop_rtol = angle_tol, normal_rtol, loop_rtol
        self.cos_tol = math.cos(angle_tol)
        self.track = np.zeros((64, N_TRACK))
        self.last = np.zeros(N_LAST)
        self.last[L_SIGMA_REF] = math.nan  # not sheared
        self.last[L_LOOP_WORK] = math.nan
        self.counts = np.zeros(N_COUNTS, dtype=np.int64)
        self.counts[C_FIRST] = -1

    @property
    def first_step(self) -> int:
        return int(self.counts[C_FIRST])

    @property
    def first_flags(self) -> int:
        return int(self.counts[C_FIRST_FLAGS])

    @property
    def any_flags(self) -> int:
        return int(self.counts[C_ANY])

    @property
    def loop_work(self) -> float:
        return float(self.last[L_LOOP_WORK])

    def room(self, steps):
        """Room in the arrays for ``steps`` more steps."""
        need = int(self.counts[0]) + steps
        if need > self.track.shape[0]:
            grown = np.zeros((max(need, 2 * self.track.shape[0]), N_TRACK))
            grown[:self.track.shape[0]] = self.track
            self.track = grown

    def step(self, step, delta, stress) -> int:
        """Flags of recorded ``step`` at displacement ``delta`` [m] and stress [Pa] (call in step order)."""
        self.room(1)
        return int(domain_step(self.track, self.last, self.counts, step, np.asarray(delta, float),
                               np.asarray(stress, float), self.cos_tol, self.normal_rtol, self.loop_rtol))

    def message(self, law_name, n_steps) -> str:
        reasons = "; ".join(text for bit, text in REASONS.items() if self.first_flags & bit)
        return (f"law {law_name!r} is path independent (valid for monotonic shear in a fixed direction at constant "
                f"normal force) and this path leaves that domain from step {self.first_step} of {n_steps}: "
                f"{reasons}. Its forces there are not those of a contact with memory; use law 'mdr' for such paths "
                "(the per-step flags are in the variable law_domain)")
