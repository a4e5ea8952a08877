"""What a run records of one converged step, and the run attributes that go with it.

Owns :func:`record_step` (the values of an :class:`~asperity_sim.kernels.evaluate.Evaluation`
appended to the :class:`~asperity_sim.output.recorder.Recorder`: stress, displacement and
their standard errors under the step's control, tangent, counts, the largest contact angle,
contact area and mean gap), :func:`theta_am_at` (its largest angle, cached) and the
attributes that flag an undefined standard error.
"""

from __future__ import annotations

import datetime as _dt
import functools

from ..geometry import closure
from ..reference.rules import theta_am
from .stepping import area_stderr, solution_stderr


@functools.lru_cache(maxsize=256)
def theta_am_at(params, c):
    """theta_am(c) [rad], cached: paths often hold the closure (shear at a prescribed Delta_1)."""
    return float(theta_am(params, c))


def stderr_attributes(attrs, n):
    """n = 1: the Monte Carlo standard error is undefined; it is reported as 0 and flagged here."""
    attrs["stderr_defined"] = int(n > 1)
    if n < 2:
        attrs["stderr_note"] = ("n = 1: the Monte Carlo standard error of one sample is undefined; stress_stderr "
                                "and displacement_stderr are written as 0 and are not error bars")


def utc_now():
    """The time now, UTC, as the ISO 8601 text of a history attribute."""
    return _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def record_step(rec, params, ev, *, stage, control, iterations, residual, cutbacks, **extra):
    """Append the converged evaluation ``ev`` of one step to the recorder ``rec`` (``control``: stress-controlled
    components, which decide the standard errors; ``extra``: the law's own per-step variables)."""
    stress_se, disp_se = solution_stderr(ev, control)
    rec.append(
        displacement=ev.delta, stress=ev.stress, stress_stderr=stress_se, displacement_stderr=disp_se,
        tangent=ev.tangent,
        n_contact=ev.n_contact, n_slip=ev.n_slip, n_partial=ev.n_partial,
        theta_am=theta_am_at(params, float(closure(params, ev.delta[0]))), mean_theta=ev.mean_theta,
        contact_area_fraction=ev.contact_area, contact_area_fraction_stderr=area_stderr(ev, control),
        mean_gap=params.mean_plane_depth - ev.delta[0], mean_gap_stderr=disp_se[0],
        stage=stage, control=control.astype("i1"), iterations=iterations, residual=residual,
        cutbacks=cutbacks, **extra,
    )
