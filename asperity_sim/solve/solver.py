"""Newton–Raphson for the stress-controlled components of one increment (SPEC §6).

Owns the solution of T_ff dDelta_f = sigma_target_f - sigma_f(Delta) (Eqs. 24–28) for the
free (stress-controlled) components f, the others being prescribed.  It returns a small
result object and never raises for a non-converged increment: the driver decides
(cut the increment, or stop with a named error).

Safeguards:
- residuals are scaled by a stress scale and steps by a length scale, so tolerances
  mean the same from 1 Pa to 1e12 Pa and from 1 nm to 1 mm;
- floating-point resolution: when Delta_f - r of the few contacts that carry the load is
  far below Delta_f itself (a stress of 1 Pa on a stiff interface: overlaps of 1e-11 m at
  Delta ~ 1e-6 m), the stress is quantised along Delta_f: one ulp of Delta_f moves it by
  more than ``rtol``, and no representable Delta_f meets it.  The solution counts as
  pinned when the Newton step is within ``RESOLUTION_ULPS`` ulps of Delta_f or a sign
  change of the residual is bracketed within about 4 ulps; it is then accepted if its
  residual is below ``resolution_rtol`` (1e-4 by default; the driver records the residual
  of every increment and counts those accepted this way), and anything larger there is a
  discontinuity and fails by name;
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
from dataclasses import dataclass

import numpy as np

from ..checks import check_int, check_real
from ..errors import InteractionRunawayError


@dataclass(frozen=True)
class SolverSettings:
    """Software settings of the Newton solver (not physics).

    rtol : converged when max_f |sigma_f - target_f| <= rtol * sigma_scale
    sigma_floor : [Pa] smallest stress scale, so that a zero target converges absolutely
    max_iter : Newton iterations per increment
    max_expansions : doublings of the bracket search before a target is declared unreachable
    max_step : largest Newton step, in length scales
    max_cutbacks : increment halvings before the driver stops
    max_search : farthest a search for contact or for a bracket goes from its start, in length
        scales; a target not met within it is unreachable (bounds the cost of a trial
        evaluation, which grows with the overlap for history laws)
    resolution_rtol : largest scaled residual accepted when the solution is pinned to within
        the floating-point resolution of Delta (see the module docstring; never below rtol;
        set it to rtol to accept nothing beyond rtol)
    """

    rtol: float = 1e-10
    sigma_floor: float = 1e-9
    max_iter: int = 40
    max_expansions: int = 60
    max_step: float = 2.0
    max_cutbacks: int = 12
    resolution_rtol: float = 1e-4
    max_search: float = 1e4

    def __post_init__(self):
        check_real("rtol", self.rtol, 0.0, 1e-2, lo_open=True)
        check_real("resolution_rtol", self.resolution_rtol, 0.0, 1e-2, lo_open=True)
        check_real("sigma_floor", self.sigma_floor, 0.0, None, lo_open=True)
        check_real("max_step", self.max_step, 0.0, None, lo_open=True)
        check_real("max_search", self.max_search, 0.0, None, lo_open=True)
        for name, lo in (("max_iter", 1), ("max_expansions", 1), ("max_cutbacks", 0)):
            check_int(name, getattr(self, name), lo)


_NONFINITE = "non-finite stress at Delta = {} m: the interface response is beyond the floating-point range"
RESOLUTION_ULPS = 64.0  # a Newton step this many ulps of Delta or less is below its resolution


def _below_resolution(x, step):
    """True when every component of ``step`` [m] is within RESOLUTION_ULPS ulps of ``x`` [m] (lists of floats)."""
    if not all(map(math.isfinite, step)):
        return False
    return all(abs(s) <= RESOLUTION_ULPS * math.ulp(max(abs(xi), abs(xi + s))) for xi, s in zip(x, step))


def _max_abs(values):
    """max |v| over a few floats, 0 for none and NaN if any is NaN (as np.max, without its call overhead)."""
    m = 0.0
    for v in values:
        a = abs(v)
        if a > m or a != a:
            m = a
    return m


@dataclass
class SolveResult:
    """Outcome of one increment, like scipy's OdeResult (``evaluation`` None: the guess could not be evaluated)."""

    converged: bool
    iterations: int
    residual: float
    rate: float
    message: str
    evaluation: object
    unreachable: bool = False


def _stress_scale(ev, free, target, settings):
    """Scale [Pa] of the residuals: the largest |target_f|, |sigma_i| and sigma_floor."""
    return max(_max_abs(target[free].tolist()), _max_abs(ev.stress.tolist()), settings.sigma_floor)


def _scaled_residual(ev, free, target, settings, scale=None):
    if scale is None:
        scale = _stress_scale(ev, free, target, settings)
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
    return _checked(_solve(evaluate, delta_guess, free, target, length_scale, settings))


def _solve(evaluate, delta_guess, free, target, length_scale, settings):
    free = np.asarray(free, dtype=bool)
    mask = free.tolist()
    x = np.array(delta_guess, dtype=float)
    try:
        ev = evaluate(x)
    except InteractionRunawayError as err:  # the guess is beyond the load's reach: no evaluation, the caller cuts back
        return SolveResult(False, 0, math.inf, 0.0, str(err), None)
    if not any(mask):
        return SolveResult(True, 0, 0.0, 0.0, "displacement controlled", ev)
    if sum(mask) == 1:
        return _solve_scalar(evaluate, x, ev, mask.index(True), free, target, length_scale, settings)
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


def _checked(result):
    """A 'converged' evaluation with a non-finite stress, covariance or tangent is no solution.

    This happens only when the parameters put the stress beyond the floating-point range
    (e.g. N G sqrt(R) Delta^1.5 > 1e308); the driver then cuts the increment and stops with
    a named error, and nothing non-finite is ever recorded.
    """
    ev = result.evaluation
    if result.converged and not all(all(map(math.isfinite, a.ravel().tolist()))
                                    for a in (ev.stress, ev.covariance, ev.tangent)):
        result.converged = False
        result.message = (f"the stress, its covariance or its tangent at Delta = {ev.delta} m is not finite: the "
                          "parameters put the interface response beyond the floating-point range")
    return result


def _solve_scalar(evaluate, x, ev, k, free, target, L, settings):
    """Safeguarded Newton with bracketing for one stress-controlled component k."""
    lo = hi = None  # displacements where the residual is < 0 and > 0
    r_prev = None
    search = L / 64.0
    x0 = xk = float(x[k])  # x[k] as a Python float: the loop below is scalar arithmetic
    target_k = float(target[k])
    expansions = 0
    best_search = math.inf
    best_r, best = math.inf, (0, ev)  # smallest |residual| seen, with (iterations, evaluation)
    res_tol = max(settings.resolution_rtol, settings.rtol)
    stalled = 0
    rate = 0.0
    for it in range(1, settings.max_iter + settings.max_expansions + 1):
        stress = ev.stress.tolist()
        scale = max(abs(target_k), _max_abs(stress), settings.sigma_floor)  # _stress_scale, one component
        r = (stress[k] - target_k) / scale  # the one component of _scaled_residual
        if not math.isfinite(r):
            return SolveResult(False, it - 1, r, rate, _NONFINITE.format(x), ev)
        if abs(r) <= settings.rtol:
            return SolveResult(True, it - 1, abs(r), rate, "converged", ev)
        if r_prev is not None and r_prev != 0.0:
            rate = abs(r / r_prev)
        r_prev = r
        if abs(r) < best_r:
            best_r, best = abs(r), (it - 1, ev)
        if r < 0.0:
            lo = xk
        else:
            hi = xk
        T = ev.tangent.item(k, k) / scale
        x_new = xk - r / T if T > 0.0 and math.isfinite(T) else math.nan
        if abs(r) <= res_tol and math.isfinite(x_new) and _below_resolution([xk], [x_new - xk]):
            return SolveResult(True, it - 1, abs(r), rate, f"converged to the floating-point resolution of "
                               f"Delta_{k + 1} (residual {abs(r):.3g})", ev)
        if lo is not None and hi is not None:
            a, b = min(lo, hi), max(lo, hi)
            if not (a < x_new < b):
                x_new = 0.5 * (a + b)
            if b - a <= 1e-15 * max(abs(a), abs(b), L):
                if best_r <= res_tol:  # pinned to a few ulps: the stress is quantised
                    return SolveResult(True, best[0], best_r, rate,
                                       f"converged to the floating-point resolution of Delta_{k + 1} "
                                       f"(residual {best_r:.3g})", best[1])
                ulps = (b - a) / math.ulp(max(abs(a), abs(b)))
                return SolveResult(False, it, abs(r), rate,
                                   f"bracket on Delta_{k + 1} collapsed to {b - a:.3g} m ({ulps:.0f} ulps) at "
                                   f"{xk:.6g} m with a scaled residual still {best_r:.3g} > {res_tol:.3g}: the "
                                   f"stress is discontinuous there, or changes by more than that between neighbouring "
                                   f"floating-point values of Delta_{k + 1} (contact overlaps far below Delta)", ev)
        else:
            direction = 1.0 if r < 0.0 else -1.0  # the response is stiffening: sigma_k grows with Delta_k
            if not math.isfinite(x_new) or abs(x_new - xk) > settings.max_step * L:
                x_new = xk + direction * search
                search *= 2.0
                expansions += 1
                if abs(r) < best_search * (1.0 - 1e-9):
                    best_search, stalled = abs(r), 0
                else:
                    stalled += 1
                if expansions > settings.max_expansions or stalled >= 8:
                    return SolveResult(False, it, abs(r), rate,
                                       f"sigma_{k + 1} = {target[k]:.6g} Pa cannot be reached: along Delta_{k + 1} the "
                                       f"stress saturates at about {ev.stress[k]:.6g} Pa "
                                       f"(Delta_{k + 1} = {xk:.6g} m)", ev, unreachable=True)
                if abs(x_new - x0) > settings.max_search * L:
                    return SolveResult(False, it, abs(r), rate,
                                       f"sigma_{k + 1} = {target[k]:.6g} Pa cannot be reached within |Delta_{k + 1} "
                                       f"- {x0:.6g} m| <= max_search = {settings.max_search:g} length scales "
                                       f"({settings.max_search * L:.3g} m): the stress there is only "
                                       f"{ev.stress[k]:.6g} Pa", ev, unreachable=True)
        x[k] = xk_new = x_new
        ev = None
        for _ in range(64):
            try:
                ev = evaluate(x)
                break
            except InteractionRunawayError:  # beyond the load's reach (mean-field interaction): step back halfway
                x[k] = xk_new = xk + 0.5 * (xk_new - xk)
        if ev is None:
            return SolveResult(False, it, abs(r), rate, f"Delta_{k + 1} = {xk:.6g} m is at the edge of the mean-field "
                               "interaction's reach: no closure of the contacts carries a step beyond it", best[1])
        xk = xk_new
    r, _ = _scaled_residual(ev, free, target, settings)
    return SolveResult(False, settings.max_iter, float(abs(r[0])), rate,
                       f"no convergence on sigma_{k + 1} in {settings.max_iter} iterations", ev)


def _solve_newton(evaluate, x, ev, free, target, L, settings):
    """Damped Newton with least-squares steps for several stress-controlled components."""
    idx = np.flatnonzero(free)
    r, scale = _scaled_residual(ev, free, target, settings)  # the scale stays fixed for this solve
    norm = float(np.max(np.abs(r)))
    rate, slow = 0.0, 0
    res_tol = max(settings.resolution_rtol, settings.rtol)
    search = np.full(idx.size, L / 64.0)
    for it in range(1, settings.max_iter + 1):
        if not np.all(np.isfinite(r)):
            return SolveResult(False, it - 1, math.inf, rate, _NONFINITE.format(x), ev)
        if norm <= settings.rtol:
            return SolveResult(True, it - 1, norm, rate, "converged", ev)
        # scaled Jacobian: d r / d (x / L)
        J = ev.tangent[np.ix_(idx, idx)] * (L / scale)
        step, *_ = np.linalg.lstsq(J, -r, rcond=1e-12)
        if norm <= res_tol and _below_resolution(x[idx].tolist(), (step * L).tolist()):
            return SolveResult(True, it - 1, norm, rate,
                               f"converged to the floating-point resolution of Delta (residual {norm:.3g})", ev)
        # components the tangent cannot move (no contact yet): search outwards, doubling
        dead = np.abs(J).sum(axis=0) <= 1e-12 * max(np.abs(J).max(initial=0.0), 1e-300)
        for i in np.flatnonzero(dead & (np.abs(r) > settings.rtol)):
            if search[i] > settings.max_search * L:
                return SolveResult(False, it - 1, norm, rate,
                                   f"sigma_{idx[i] + 1} = {target[idx[i]]:.6g} Pa cannot be reached: no stiffness "
                                   f"along Delta_{idx[i] + 1} within max_search = {settings.max_search:g} length "
                                   f"scales ({settings.max_search * L:.3g} m)", ev, unreachable=True)
            step[i] = (1.0 if r[i] < 0.0 else -1.0) * search[i] / L
            search[i] *= 2.0
        size = float(np.max(np.abs(step)))
        if size > settings.max_step:
            step *= settings.max_step / size
        lam = 1.0
        for _ in range(30):
            x_try = x.copy()
            x_try[idx] += lam * step * L
            try:
                ev_try = evaluate(x_try)
            except InteractionRunawayError:  # beyond the load's reach (mean-field interaction): a shorter step
                lam *= 0.5
                continue
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
