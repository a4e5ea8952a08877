"""Elastic interaction between contacts in the mean field: the closure the contacts see.

Owns the mean-field interaction model and its solution at one displacement, for every law.
Without it each contact's overlap follows from the interface displacement Delta alone (the
surface between contacts does not move).  With it, the surface also deforms under the load of
the other contacts.  Take the zero-mean periodic Green's function of the half-space,
G(r) ~ 1/(pi E* r): the displacement at one contact due to all others, spread as a uniform
pressure sigma_1 outside the disc r < r0 that the contact itself occupies (r0 = 1/sqrt(pi N),
one summit's share of the plane), less its mean over the plane, is -sigma_1 int_0^r0
2 pi r G(r) dr = -2 sigma_1 r0 / E*.  Measured from the mean level of the deformed surface (the
reference of Delta_1, as of a boundary-element solution's approach), every contact therefore
overlaps by

    Delta_c,1 = Delta_1 + kappa sigma_1(Delta_c),   kappa = interaction * 2 r0 / E*,

more than the rigid estimate, so that at a given load the mean level is kappa sigma_1 further
away: the mean gap is larger (`InterfaceParams.interaction`, 1: this estimate, 0: off; shear
components are not changed).  :func:`solve` finds Delta_c by Newton's method on the scalar
g(c) = c - Delta_1 - kappa sigma_1(c), g' = 1 - kappa T_11 > 0 (a larger kappa T_11 would make
the contacts' load run away: :class:`~asperity_sim.errors.InteractionRunawayError`), from the last
offset or, where that lies beyond the fold of g, from c = Delta_1, and :func:`transformed` gives the response at Delta with its exact
tangent, dDelta_c/dDelta = I + kappa e_1 t, t = T_1,:/(1 - kappa T_11), T = T_c (I + kappa e_1 t),
and the Monte Carlo covariances carried through the same fixed point
(M = I + kappa T_:,1 e_1^T / (1 - kappa T_11)).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import InteractionRunawayError

__all__ = ["kappa", "solve", "transformed"]

MAX_ITERATIONS = 50


def kappa(params) -> float:
    """The mean-field compliance kappa = interaction * 2 r0 / E* [m/Pa], r0 = 1/sqrt(pi N)."""
    return params.interaction * 2.0 / (math.sqrt(math.pi * params.N) * params.E_star)


def transformed(ev, delta, k):
    """The response at the interface displacement ``delta`` from ``ev``, the evaluation at the contacts'
    displacement Delta_c = delta + k sigma_1 e_1 (module docstring)."""
    T = ev.tangent
    denominator = 1.0 - k * T[0, 0]
    if not denominator > 0.0:
        raise InteractionRunawayError(f"elastic interaction too strong: kappa T_11 = {k * T[0, 0]:.4g} >= 1 at Delta = "
                         f"{np.asarray(delta).tolist()} m (the contacts' load would run away; lower interaction)")
    t = T[0, :] / denominator                     # d sigma_1 / d Delta
    tangent = T + k * np.outer(T[:, 0], t)
    M = np.eye(3)
    M[:, 0] += k * T[:, 0] / denominator          # d sigma_hat / d sigma_hat_contacts
    covariance = M @ ev.covariance @ M.T
    g = ev.contact_area_grad
    area_var = (ev.contact_area_var + 2.0 * k * g[0] / denominator * ev.contact_area_cov[0]
                + (k * g[0] / denominator) ** 2 * ev.covariance[0, 0])
    area_cov = M @ ev.contact_area_cov + (k * g[0] / denominator) * (M @ ev.covariance[:, 0])
    return dataclasses.replace(
        ev, delta=np.asarray(delta, dtype=float), delta_contact=ev.delta, covariance=covariance, tangent=tangent,
        stderr=np.sqrt(np.maximum(np.diag(covariance), 0.0)), contact_area_var=area_var, contact_area_cov=area_cov,
        contact_area_grad=g + k * g[0] * t)


def solve(evaluate_contacts, delta, k, offset=0.0, rtol=1e-13):
    """The response at ``delta`` [m] with the contacts at Delta_c = delta + k sigma_1 e_1 (module docstring).

    ``evaluate_contacts`` : Delta_c -> Evaluation (the kernels at the contacts' displacement);
    ``offset`` [m] : a first guess of k sigma_1 (the last one, say).  Converged when the closure
    changes by less than ``rtol`` times the offset, or by a few ulps of Delta_c.
    """
    delta = np.asarray(delta, dtype=float)
    c = delta.copy()
    c[0] += max(offset, 0.0)
    from_left = offset <= 0.0
    for _ in range(MAX_ITERATIONS):
        ev = evaluate_contacts(c)
        g = c[0] - delta[0] - k * ev.stress[0]
        slope = 1.0 - k * ev.tangent[0, 0]
        if not slope > 0.0:
            if from_left:
                return transformed(ev, delta, k)  # raises InteractionRunawayError, naming kappa T_11
            # the first guess lies beyond the fold of g: start again from c = Delta, where g <= 0; g is concave
            # (sigma_1 stiffens), so Newton from there rises to the root, if there is one, with g' > 0
            c, from_left = delta.copy(), True
            continue
        step = -g / slope
        if abs(step) <= rtol * max(abs(c[0] - delta[0]), 1e-300) or abs(step) <= 4.0 * math.ulp(abs(c[0]) + 1e-300):
            return transformed(ev, delta, k)
        c = c.copy()
        c[0] += step
    raise ValueError(f"elastic interaction: the contacts' closure did not converge in {MAX_ITERATIONS} iterations "
                     f"at Delta = {delta.tolist()} m")
