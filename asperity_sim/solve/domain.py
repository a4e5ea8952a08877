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

SHEAR_TURN, NORMAL_CHANGE, LOOP_WORK = 1, 2, 4
REASONS = {SHEAR_TURN: "the shear direction reversed or turned",
           NORMAL_CHANGE: "the normal stress changed during shear",
           LOOP_WORK: "the external work over a closed loop is negative (energy returned)"}


class DomainMonitor:
    """Flags the steps of a run where a path-independent law leaves its domain (module docstring)."""

    def __init__(self, angle_tol=1e-6, normal_rtol=1e-2, loop_rtol=1e-3):
        self.angle_tol, self.normal_rtol, self.loop_rtol = angle_tol, normal_rtol, loop_rtol
        self.deltas, self.work, self.abs_work = [], [], []
        self.sigma_ref = None  # normal stress when shear began
        self.first_step, self.first_flags, self.any_flags = -1, 0, 0
        self.loop_work = math.nan

    def step(self, step, delta, stress) -> int:
        """Flags of recorded ``step`` at displacement ``delta`` [m] and stress [Pa] (call in step order)."""
        delta, stress = np.asarray(delta, float), np.asarray(stress, float)
        flags = 0
        if not self.deltas:
            self.deltas.append(delta.copy())
            self.work.append(0.0)
            self.abs_work.append(0.0)
            self._stress = stress.copy()
            return 0
        prev = self.deltas[-1]
        dW = float(0.5 * (self._stress + stress) @ (delta - prev))
        self.work.append(self.work[-1] + dW)
        self.abs_work.append(self.abs_work[-1] + abs(dW))
        s_prev, s_new = prev[1:], delta[1:]
        ds = s_new - s_prev
        n_prev, n_ds = float(np.hypot(*s_prev)), float(np.hypot(*ds))
        if n_prev * n_ds > 0.0:
            cos = float(s_prev @ ds) / (n_prev * n_ds)  # both norms > 0 (may underflow to 0 in the product)
            if not cos >= math.cos(self.angle_tol):
                flags |= SHEAR_TURN
        sheared = float(np.hypot(*s_new)) > 0.0
        if sheared and self.sigma_ref is None:
            self.sigma_ref = float(self._stress[0])
        if not sheared:
            self.sigma_ref = None
        elif abs(stress[0] - self.sigma_ref) > self.normal_rtol * max(abs(self.sigma_ref), abs(stress[0])):
            flags |= NORMAL_CHANGE
        self.deltas.append(delta.copy())
        self._stress = stress.copy()
        if self.any_flags or flags:
            flags |= self._loop(delta)
        if flags and self.first_step < 0:
            self.first_step, self.first_flags = step, flags
        self.any_flags |= flags
        return flags

    def _loop(self, delta) -> int:
        """LOOP_WORK when delta closes a loop (returns to an earlier displacement) with negative work."""
        past = np.asarray(self.deltas[:-2])
        if past.size == 0:
            return 0
        scale = max(float(np.abs(np.asarray(self.deltas)).max()), 1e-300)
        close = np.flatnonzero(np.abs(past - delta).max(axis=1) <= 1e-9 * scale)
        for i in close[::-1]:
            w = self.work[-1] - self.work[i]
            along = self.abs_work[-1] - self.abs_work[i]
            if along > 0.0 and w < -self.loop_rtol * along:
                self.loop_work = w
                return LOOP_WORK
        return 0

    def message(self, law_name, n_steps) -> str:
        reasons = "; ".join(text for bit, text in REASONS.items() if self.first_flags & bit)
        return (f"law {law_name!r} is path independent (valid for monotonic shear in a fixed direction at constant "
                f"normal force) and this path leaves that domain from step {self.first_step} of {n_steps}: "
                f"{reasons}. Its forces there are not those of a contact with memory; use law 'mdr' for such paths "
                "(the per-step flags are in the variable law_domain)")
