"""Newton–Raphson for the stress-controlled components of one increment (SPEC §6).

Owns the solution of T_ff dDelta_f = sigma_target_f - sigma_f(Delta) (Eqs. 24–28) for the
free (stress-controlled) components f, the others being prescribed.  It returns a small
result object and never raises for a non-converged increment: the driver decides
(cut the increment, or stop with a named error).

Safeguards:
- residuals are scaled by a stress scale and steps by a length scale, so tolerances
  mean the same from 1 Pa to 1e12 Pa and from 1 nm to 1 mm;
- one free component: Newton inside a sign-change bracket, bisection when Newton leaves
  it, and a doubling search for the bracket when the tangent is zero (first contact
  under stress control) or points the wrong way;
- several free components: least-squares Newton step (a singular tangent block gives
  the minimum-norm step), a contact search along components the tangent cannot move,
  step capping and backtracking line search; Newton gives up early when it stops
  contracting.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from .params import check_real


@dataclass(frozen=True)
class SolverSettings:
    """Software settings of the Newton solver (not physics).

    rtol : converged when max_f |sigma_f - target_f| <= rtol * sigma_scale
    sigma_floor : [Pa] smallest stress scale, so that a zero target converges absolutely
    max_iter : Newton iterations per increment
    max_expansions : doublings of the bracket search before a target is declared unreachable
    max_step : largest Newton step, in length scales
    max_cutbacks : increment halvings before the driver stops
    """

    rtol: float = 1e-10
    sigma_floor: float = 1e-9
    max_iter: int = 40
    max_expansions: int = 60
    max_step: float = 2.0
    max_cutbacks: int = 12

    def __post_init__(self):
        check_real("rtol", self.rtol, 0.0, 1e-2, lo_open=True)
        check_real("sigma_floor", self.sigma_floor, 0.0, None, lo_open=True)
        check_real("max_step", self.max_step, 0.0, None, lo_open=True)
        for name, lo in (("max_iter", 1), ("max_expansions", 1), ("max_cutbacks", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < lo:
                raise ValueError(f"{name} = {v!r} is not valid (valid range: integer >= {lo})")


@dataclass
class SolveResult:
    """Outcome of one increment, like scipy's OdeResult."""

    converged: bool
    iterations: int
    residual: float
    rate: float
    message: str
    evaluation: object
    unreachable: bool = False


def _scaled_residual(ev, free, target, settings, scale=None):
    if scale is None:
        scale = max(np.max(np.abs(target[free]), initial=0.0), np.max(np.abs(ev.stress)), settings.sigma_floor)
    r = (ev.stress[free] - target[free]) / scale
    return r, scale


def solve_increment(evaluate, delta_guess, free, target, length_scale, settings=SolverSettings()) -> SolveResult:
    """Find Delta with Delta_d = delta_guess_d (prescribed) and sigma_f(Delta) = target_f.

    Parameters
    ----------
    evaluate : callable, Delta (3,) [m] -> Evaluation (stress, tangent, ...)
    delta_guess : ndarray (3,) [m], prescribed components and the initial guess of the free ones
    free : bool ndarray (3,), stress-controlled components
    target : ndarray (3,) [Pa], target stresses (read on free components only)
    length_scale : float [m], typical displacement (sets step caps and search steps)
    """
    free = np.asarray(free, dtype=bool)
    x = np.array(delta_guess, dtype=float)
    ev = evaluate(x)
    if not free.any():
        return SolveResult(True, 0, 0.0, 0.0, "displacement controlled", ev)
    if free.sum() == 1:
        return _solve_scalar(evaluate, x, ev, int(np.flatnonzero(free)[0]), free, target, length_scale, settings)
    result = _solve_newton(evaluate, x, ev, free, target, length_scale, settings)
    if result.converged or not free[0]:
        return result
    # first contact under several stress controls: find sigma_1 alone (bracketed), then all together
    only_1 = np.array([True, False, False])
    first = _solve_scalar(evaluate, x.copy(), ev, 0, only_1, target, length_scale, settings)
    if not first.converged:
        return result
    again = _solve_newton(evaluate, first.evaluation.delta.copy(), first.evaluation, free, target, length_scale,
                          settings)
    again.iterations += result.iterations + first.iterations
    return again


def _solve_scalar(evaluate, x, ev, k, free, target, L, settings):
    """Safeguarded Newton with bracketing for one stress-controlled component k."""
    lo = hi = None  # displacements where the residual is < 0 and > 0
    r_prev = None
    search = L / 64.0
    expansions = 0
    best = math.inf
    stalled = 0
    rate = 0.0
    for it in range(1, settings.max_iter + settings.max_expansions + 1):
        r, scale = _scaled_residual(ev, free, target, settings)
        r = float(r[0])
        if not math.isfinite(r):
            return SolveResult(False, it - 1, r, rate, f"non-finite stress at Delta = {x}", ev)
        if abs(r) <= settings.rtol:
            return SolveResult(True, it - 1, abs(r), rate, "converged", ev)
        if r_prev is not None and r_prev != 0.0:
            rate = abs(r / r_prev)
        r_prev = r
        if r < 0.0:
            lo = x[k]
        else:
            hi = x[k]
        T = ev.tangent[k, k] / scale
        x_new = x[k] - r / T if T > 0.0 and math.isfinite(T) else math.nan
        if lo is not None and hi is not None:
            a, b = min(lo, hi), max(lo, hi)
            if not (a < x_new < b):
                x_new = 0.5 * (a + b)
            if b - a <= 1e-15 * max(abs(a), abs(b), L):
                return SolveResult(False, it, abs(r), rate,
                                   f"bracket on Delta_{k + 1} collapsed at {x[k]:.6g} m with residual {r:.3g} "
                                   "(the stress is discontinuous here)", ev)
        else:
            direction = 1.0 if r < 0.0 else -1.0  # the response is stiffening: sigma_k grows with Delta_k
            if not math.isfinite(x_new) or abs(x_new - x[k]) > settings.max_step * L:
                x_new = x[k] + direction * search
                search *= 2.0
                expansions += 1
                if abs(r) < best * (1.0 - 1e-9):
                    best, stalled = abs(r), 0
                else:
                    stalled += 1
                if expansions > settings.max_expansions or stalled >= 8:
                    return SolveResult(False, it, abs(r), rate,
                                       f"sigma_{k + 1} = {target[k]:.6g} Pa cannot be reached: along Delta_{k + 1} the "
                                       f"stress saturates at about {ev.stress[k]:.6g} Pa (Delta_{k + 1} = {x[k]:.6g} m)",
                                       ev, unreachable=True)
        x[k] = x_new
        ev = evaluate(x)
    r, _ = _scaled_residual(ev, free, target, settings)
    return SolveResult(False, settings.max_iter, float(abs(r[0])), rate,
                       f"no convergence on sigma_{k + 1} in {settings.max_iter} iterations", ev)


def _solve_newton(evaluate, x, ev, free, target, L, settings):
    """Damped Newton with least-squares steps for several stress-controlled components."""
    idx = np.flatnonzero(free)
    r, scale = _scaled_residual(ev, free, target, settings)  # the scale stays fixed for this solve
    norm = float(np.max(np.abs(r)))
    rate, slow = 0.0, 0
    search = np.full(idx.size, L / 64.0)
    for it in range(1, settings.max_iter + 1):
        if not np.all(np.isfinite(r)):
            return SolveResult(False, it - 1, math.inf, rate, f"non-finite stress at Delta = {x}", ev)
        if norm <= settings.rtol:
            return SolveResult(True, it - 1, norm, rate, "converged", ev)
        # scaled Jacobian: d r / d (x / L)
        J = ev.tangent[np.ix_(idx, idx)] * (L / scale)
        step, *_ = np.linalg.lstsq(J, -r, rcond=1e-12)
        # components the tangent cannot move (no contact yet): search outwards, doubling
        dead = np.abs(J).sum(axis=0) <= 1e-12 * max(np.abs(J).max(initial=0.0), 1e-300)
        for i in np.flatnonzero(dead & (np.abs(r) > settings.rtol)):
            step[i] = (1.0 if r[i] < 0.0 else -1.0) * search[i] / L
            search[i] *= 2.0
        size = float(np.max(np.abs(step)))
        if size > settings.max_step:
            step *= settings.max_step / size
        lam = 1.0
        for _ in range(30):
            x_try = x.copy()
            x_try[idx] += lam * step * L
            ev_try = evaluate(x_try)
            r_try, _ = _scaled_residual(ev_try, free, target, settings, scale)
            norm_try = float(np.max(np.abs(r_try)))
            if np.all(np.isfinite(r_try)) and (norm_try < (1.0 - 1e-4 * lam) * norm or dead.any()):
                break
            lam *= 0.5
        else:
            return SolveResult(False, it, norm, rate,
                               f"line search failed on sigma_{[int(i) + 1 for i in idx]} (residual {norm:.3g})", ev)
        rate = norm_try / norm if norm > 0 else 0.0
        slow = slow + 1 if rate > 0.9 else 0
        x, ev, r, norm = x_try, ev_try, r_try, norm_try
        if slow >= 4:
            return SolveResult(False, it, norm, rate, f"Newton stopped contracting (rate {rate:.3g})", ev)
    return SolveResult(norm <= settings.rtol, settings.max_iter, norm, rate,
                       f"no convergence in {settings.max_iter} iterations", ev)
