"""Stepping a stage: increment sizes, predictors, the solver's length scale and named failures.

Owns how the driver moves along a stage: the loop position (:class:`Position`, saved in
checkpoints), the size of the next increment (:func:`next_step`), the tangent and cubic
predictors within a trust region (:func:`tangent_predictor`, :func:`cubic_predictor`), the length
scale of the solver (:func:`length_scale`), the standard errors of a solution under mixed
control (:func:`solution_stderr`) and the named error of an increment that cannot be
completed (:func:`increment_failure`).  Pure functions of the last converged state; the driver
(:mod:`asperity_sim.solve.driver`) calls them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConvergenceError, StressNotReachableError


def sqrt_nonneg(x: float) -> float:
    """sqrt(max(x, 0)) as numpy computes it: NaN stays NaN, -0.0 gives 0.0."""
    return math.sqrt(x) if x > 0.0 or x != x else 0.0


TRUST = 1.0  # largest predictor step, in length scales of the interface (length_scale)


@dataclass
class Position:
    """Where the loop is, after the last converged increment (saved in checkpoints)."""

    i_stage: int = 0          # index of the current stage (0-based)
    started: bool = False     # stage start (start_delta, start_stress, ds, k_ref) set up
    s: float = 0.0            # fraction of the stage done
    ds: float = 0.0           # size of the next increment, fraction of the stage
    k_ref: float = 0.0        # largest stiffness of the ramped stress directions seen in the stage [Pa/m]
    start_delta: np.ndarray = field(default_factory=lambda: np.zeros(3))
    start_stress: np.ndarray = field(default_factory=lambda: np.zeros(3))
    # the converged point before the last one in this stage, for the cubic predictor (prev_s NaN: none)
    prev_s: float = math.nan  # its fraction of the stage
    prev_delta: np.ndarray = field(default_factory=lambda: np.zeros(3))  # its Delta [m]
    prev_slope: np.ndarray = field(default_factory=lambda: np.zeros(3))  # its d Delta / d s [m]
    # the two converged points before that one, rows (s, Delta_1, Delta_2, Delta_3) (s NaN: none), for the
    # path extrapolation of a history law (:func:`extrapolated_predictor`)
    older: np.ndarray = field(default_factory=lambda: np.full((2, 4), np.nan))

    def advance(self, s, delta, slope):
        """The point (s, delta) with its slope becomes the previous one; the older ones shift back."""
        if not math.isnan(self.prev_s):
            self.older[1] = self.older[0]
            self.older[0, 0], self.older[0, 1:] = self.prev_s, self.prev_delta
        self.prev_s, self.prev_delta, self.prev_slope = s, delta, slope

    def forget(self):
        """No previous point (a stage starts)."""
        self.prev_s = math.nan
        self.older = np.full((2, 4), np.nan)


def next_step(stage, ds, iterations, cuts, nominal, smallest):
    """Size of the next increment (fraction of the stage) after one that converged in ``iterations``."""
    if stage.adaptive:
        ds = min(ds * (1.5 if iterations <= 3 else 1.0), stage.max_fraction)
        if iterations > 8:
            ds = max(0.5 * ds, smallest)  # never below the smallest increment: no Zeno stall
        return ds
    return min(2.0 * ds, nominal) if cuts else nominal


def length_scale(params, path) -> float:
    """Displacement scale [m] of the solver: steps, searches and their limits are counted in it.

    The mean height (alpha + 1) beta (SPEC §2), or, if larger, the Hertz closure that would
    carry the largest prescribed stress with every asperity in contact,
    (sigma_max / (N (4/3) E* sqrt(R_m)))^(2/3): heights piled at r = 0 (alpha -> -1) have a
    vanishing mean, yet a stress target still needs that much closure.
    """
    sigma_max = max((abs(t) for s in path.stages for t, c in zip(s.target, s.control) if c == "stress"),
                    default=0.0)
    hertz = (sigma_max / (params.N * (4.0 / 3.0) * params.E_star * np.sqrt(params.R_m))) ** (2.0 / 3.0)
    length = max((params.alpha + 1.0) * params.beta, float(hertz))
    return length if np.isfinite(length) and length > 0.0 else params.beta


def unreachable_by_symmetry(params, stage, i_stage, free, end):
    """mu = 0 and e = 0: every contact is frictionless and normal to the plane, so sigma_2 = sigma_3 = 0
    identically (SPEC §3, §5) and the shear tangent is zero; a non-zero shear stress target cannot be met."""
    if params.mu != 0.0 or params.k_e != 0.0:
        return None
    bad = [k for k in (1, 2) if free[k] and end[k] != 0.0]
    if not bad:
        return None
    names = ", ".join(f"sigma_{k + 1} = {end[k]:.6g} Pa" for k in bad)
    return StressNotReachableError(
        f"{names} cannot be reached in stage {i_stage} ({stage.name or 'unnamed'}): with mu = 0 and e = 0 every "
        "contact is frictionless and normal to the nominal plane (theta_m = 0, SPEC §3, §5), so the interface "
        "carries no shear stress at any displacement (its shear tangent is zero); prescribe the shear "
        "displacement instead")


def solution_stderr(ev, free):
    """Standard errors of the recorded stress and displacement under mixed control.

    The Monte Carlo error dsigma of the estimate moves the solved displacements:
    dDelta_f = -T_ff^-1 dsigma_f, and the reported stresses of the displacement-controlled
    components by dsigma_d - T_df T_ff^-1 dsigma_f (delta method, first order, using the
    covariance of the estimate).  Returns (stress_stderr [Pa], displacement_stderr [m]).
    """
    free = np.asarray(free, dtype=bool)
    mask = free.tolist()
    if not any(mask):
        return ev.stderr, np.zeros(3)
    if sum(mask) == 1:  # the common case, in closed form (same formulas, no pinv), on Python floats
        k = mask.index(True)
        T, C = ev.tangent.tolist(), ev.covariance.tolist()
        t_kk = T[k][k]
        a = 1.0 / t_kk if t_kk != 0.0 and math.isfinite(1.0 / t_kk) else 0.0
        g = [T[i][k] * a for i in range(3)]  # dsigma_i = dsigma_i - g_i dsigma_k for the fixed i
        var_s = [C[i][i] - 2.0 * g[i] * C[i][k] + g[i] * g[i] * C[k][k] for i in range(3)]
        var_s[k] = 0.0
        var_d = [0.0] * 3
        var_d[k] = a * a * C[k][k]
        return np.array([sqrt_nonneg(v) for v in var_s]), np.array([sqrt_nonneg(v) for v in var_d])
    fixed = ~free
    A = np.linalg.pinv(ev.tangent[np.ix_(free, free)], rcond=1e-12)
    M_stress = np.zeros((3, 3))
    M_stress[np.ix_(fixed, fixed)] = np.eye(int(fixed.sum()))
    M_stress[np.ix_(fixed, free)] = -ev.tangent[np.ix_(fixed, free)] @ A
    M_disp = np.zeros((3, 3))
    M_disp[np.ix_(free, free)] = -A
    var_s = np.einsum("ij,jk,ik->i", M_stress, ev.covariance, M_stress)
    var_d = np.einsum("ij,jk,ik->i", M_disp, ev.covariance, M_disp)
    return np.sqrt(np.maximum(var_s, 0.0)), np.sqrt(np.maximum(var_d, 0.0))


def area_stderr(ev, free) -> float:
    """Standard error of the recorded contact area fraction under mixed control [1].

    As :func:`solution_stderr`: the Monte Carlo error of the stress estimate moves the solved
    displacements by dDelta_f = -T_ff^-1 dsigma_f, which moves the area by g . dDelta_f, g the
    area's gradient; the area's own error is correlated with dsigma.  Var = Var(a) - 2 h . Cov(a,
    sigma_f) + h C_ff h, h = T_ff^-T g_f (delta method, first order).
    """
    var = ev.contact_area_var
    free = np.asarray(free, dtype=bool)
    mask = free.tolist()
    if sum(mask) == 1:  # the common case on Python floats: the pseudo-inverse of t_kk is 1/t_kk (0 if t_kk = 0)
        k = mask.index(True)
        t_kk = ev.tangent.item(k, k)
        if math.isfinite(t_kk):
            h = (1.0 / t_kk if t_kk != 0.0 else 0.0) * ev.contact_area_grad.item(k)
            var = var - 2.0 * (h * ev.contact_area_cov.item(k)) + h * ev.covariance.item(k, k) * h
            return sqrt_nonneg(var)
    if free.any():
        A = np.linalg.pinv(ev.tangent[np.ix_(free, free)], rcond=1e-12)
        h = A.T @ ev.contact_area_grad[free]
        C = ev.covariance[np.ix_(free, free)]
        var = var - 2.0 * float(h @ ev.contact_area_cov[free]) + float(h @ C @ h)
    return sqrt_nonneg(var)


def tangent_predictor(ev, delta, target_delta, target_stress, free, limit=math.inf):
    """Tangent predictor for the free components from the last converged state.

    The step is kept within ``limit`` [m] (a trust region of the interface's length scale): near
    zero stiffness (an unloaded interface, first contact) the tangent step is unbounded, and the
    solver's own bracket search finds the way from a point within reach instead.
    """
    guess = target_delta.copy()
    mask = free.tolist()
    if not any(mask):
        return guess
    fixed = ~free
    if sum(mask) == 1:  # the common case, on Python floats, without the SVD of cond
        k = mask.index(True)
        row, change = ev.tangent[k].tolist(), (target_delta - delta).tolist()
        rhs = float(target_stress[k] - ev.stress[k]) - sum(row[j] * change[j] for j in range(3) if not mask[j])
        t_kk = row[k]
        if t_kk != 0.0 and math.isfinite(t_kk):
            step = rhs / t_kk
            if math.isfinite(step):
                guess[k] = delta[k] + max(-limit, min(limit, step))
        return guess
    rhs = (target_stress - ev.stress)[free] - ev.tangent[np.ix_(free, fixed)] @ (target_delta - delta)[fixed]
    T = ev.tangent[np.ix_(free, free)]
    try:
        if np.linalg.cond(T) < 1e12:
            step = np.linalg.solve(T, rhs)
            if np.all(np.isfinite(step)):
                norm = float(np.linalg.norm(step))
                guess[free] = delta[free] + (step if norm <= limit else step * (limit / norm))
    except np.linalg.LinAlgError:
        pass
    return guess


def cubic_predictor(linear, delta, slope, pos, s, s_new, free):
    """Free components of the guess from the cubic through the last two converged points.

    The tangent predictor ``linear`` is first order in the increment; the cubic Hermite
    through (prev_s, prev_delta, prev_slope) and (s, delta, slope), extrapolated to s_new,
    is third order on a smooth path.  Kept only where the extrapolation is mild (the new
    increment at most twice the previous one) and its correction smaller than the tangent
    step itself; otherwise ``linear`` (near kinks: contact onset, stick-slip changes).
    """
    h0 = s - pos.prev_s
    if not 0.0 < s_new - s <= 2.0 * h0:
        return linear
    t = 1.0 + (s_new - s) / h0
    t2, t3 = t * t, t * t * t
    # Hermite basis at t (0 at prev_s, 1 at s), on Python floats: three components, no numpy overhead
    b0, b1, b2, b3 = 2.0 * t3 - 3.0 * t2 + 1.0, (t3 - 2.0 * t2 + t) * h0, 3.0 * t2 - 2.0 * t3, (t3 - t2) * h0
    guess = linear.copy()
    x0, m0, x1, m1, lin = (a.tolist() for a in (pos.prev_delta, pos.prev_slope, delta, slope, linear))
    for k in np.flatnonzero(free).tolist():
        cubic = b0 * x0[k] + b1 * m0[k] + b2 * x1[k] + b3 * m1[k]
        if abs(cubic - lin[k]) <= abs(lin[k] - x1[k]):  # False for NaN
            guess[k] = cubic
    return guess


def extrapolated_predictor(linear, delta, pos, s, s_new, free):
    """Free components of the guess from the cubic through the last four converged points (history laws).

    A history law's tangent at the end of an increment is that of the increment (springs that
    entered during it, slips that began), not the one the next increment starts with, so the
    tangent-based predictors are first order at best; the path Delta(s) itself is smooth between
    stick-slip events, and its Lagrange extrapolation through the points (older, prev, now) is
    third order.  Kept under the same conditions as :func:`cubic_predictor` (the new increment at
    most twice the last one, and the correction smaller than the tangent step); otherwise ``linear``.
    """
    if math.isnan(pos.prev_s) or math.isnan(pos.older[1, 0]):
        return linear
    h0 = s - pos.prev_s
    if not 0.0 < s_new - s <= 2.0 * h0:
        return linear
    nodes = [(float(pos.older[1, 0]), pos.older[1, 1:].tolist()), (float(pos.older[0, 0]), pos.older[0, 1:].tolist()),
             (pos.prev_s, pos.prev_delta.tolist()), (s, delta.tolist())]
    weights = []
    for a, (sa, _) in enumerate(nodes):
        w = 1.0
        for b, (sb, _) in enumerate(nodes):
            if b != a:
                w *= (s_new - sb) / (sa - sb)
        weights.append(w)
    guess = linear.copy()
    lin, x1 = linear.tolist(), delta.tolist()
    for k in np.flatnonzero(free).tolist():
        poly = sum(w * x[k] for w, (_, x) in zip(weights, nodes))
        if abs(poly - lin[k]) <= abs(lin[k] - x1[k]):  # False for NaN
            guess[k] = poly
    return guess


def ramped_components(free, start_stress, end):
    """Stress-controlled components whose target changes over the stage (all of them if none does)."""
    idx, s, e = np.flatnonzero(free).tolist(), start_stress.tolist(), end.tolist()
    moving = [k for k in idx if abs(e[k] - s[k]) > 1e-6 * max(abs(e[k]), abs(s[k]))]
    return moving or idx


def effective_stiffness(ev, free, ramped):
    """Stiffness [Pa/m] of the ramped stress components with the other stress-controlled ones held.

    The inverse of the ramped block of the compliance T_ff^-1; 0 where T_ff is singular.
    """
    idx = np.flatnonzero(free)
    if idx.size == 1:  # one stress-controlled component: its own stiffness
        t_kk = float(ev.tangent[idx[0], idx[0]])
        return t_kk if math.isfinite(t_kk) else 0.0
    pos = [int(np.flatnonzero(idx == k)[0]) for k in ramped]
    try:
        C = np.linalg.inv(ev.tangent[np.ix_(idx, idx)])
        K = np.linalg.inv(C[np.ix_(pos, pos)])
    except np.linalg.LinAlgError:
        return 0.0
    return float(np.min(np.linalg.eigvalsh(0.5 * (K + K.T))))


def increment_failure(result, ev, free, start_stress, end, target_stress, i_stage, stage, s, cuts, k_ref=None):
    """The named exception for an increment that cannot be completed.

    The driver calls this only once the increment has been cut to its smallest size (or the
    solver saw the target saturate).  The prescribed stress is then declared unreachable when
    the solver saw it saturate, when the tangent block of the stress-controlled components is
    (almost) singular at the last converged state or at the solver's last iterate (contacts
    present: e.g. every contact sliding on a flat interface), or when the stiffness of the
    interface in the ramped stress directions (the others held) has fallen below 10 % of
    ``k_ref``, the largest value seen in the stage (its start included): the target lies
    beyond a peak or a plateau.  Anything else is a :class:`ConvergenceError`.
    """
    where = f"stage {i_stage} ({stage.name or 'unnamed'}) stopped at {s:.4g} of the stage after {cuts - 1} cut-backs"
    if not free.any():
        return ConvergenceError(f"{where}: {result.message}")
    if free[0] and target_stress[0] < 0.0 and ev.n_contact == 0:
        return StressNotReachableError(
            f"sigma_1 = {target_stress[0]:.6g} Pa (tension) cannot be reached: {where}; the interface has no contact "
            "(sigma = 0): opening it further keeps the surfaces apart, closing it makes sigma_1 compressive")
    ramped = ramped_components(free, start_stress, end)
    names = ", ".join(f"sigma_{k + 1} = {target_stress[k]:.6g} Pa" for k in ramped)
    reached = ", ".join(f"sigma_{k + 1} = {ev.stress[k]:.6g} Pa" for k in ramped)
    k_now = effective_stiffness(ev, free, ramped)
    softened = k_ref is not None and k_ref > 0 and k_now < 0.1 * k_ref
    if result.unreachable or softened or _saturated(ev, free) or (result.evaluation is not None
                                                                  and _saturated(result.evaluation, free)):
        return StressNotReachableError(
            f"{names} cannot be reached: {where}; the interface carried at most {reached} "
            f"(at Delta = {np.array2string(ev.delta, precision=4)} m) and its stiffness in the stress-controlled "
            f"directions is exhausted ({result.message})")
    return ConvergenceError(f"{names} not reached: {where}; last converged {reached} ({result.message})")


def _saturated(ev, free):
    """True when the tangent block of the free components has (almost) no stiffness left.

    Only a state with contacts can have used up its stiffness: at zero load the tangent is
    zero too, and a failure there says nothing about the target.
    """
    if ev.n_contact == 0:
        return False
    T = ev.tangent[np.ix_(free, free)]
    sv = np.linalg.svd(T, compute_uv=False)
    return bool(sv[-1] <= 1e-6 * max(np.abs(ev.tangent).max(), 1e-300))
