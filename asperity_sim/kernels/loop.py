"""The increments of a stage compiled whole: predictors, Newton, commit and what each step records (a template).

Owns :func:`span`, the run's increment loop (:meth:`asperity_sim.solve.run.Run.go`) for stages
with at most one stress-controlled component, as one compiled call handed to the threads once
(:func:`asperity_sim.threads.run_calls`, one part per thread): the calling thread steps through
the increments; every other thread waits in compiled code for the parallel work of each
evaluation and commit (its law family's ``serve``), so that neither costs Python nor the GIL.
The same arithmetic in the same order as the Python loop, so the same bits:

- the predictors of :mod:`asperity_sim.solve.stepping` (tangent; cubic for a path-independent
  law, the extrapolation through four points for a history law);
- the bracketed Newton of one component of :mod:`asperity_sim.solve.solver`;
- the law family's evaluation (``evaluate_at``) and commit (``commit_at``), templates of
  :mod:`~asperity_sim.kernels.loop_path_independent` or :mod:`~asperity_sim.kernels.loop_history`;
- the stage's stiffness, the standard errors under the step's control, the law's domain flags
  (path-independent laws) and the size of the next increment.

An increment it cannot complete the ordinary way (no convergence at once, a cut-back, a solution
accepted at the resolution of Delta, a non-finite result, the stage's budget spent) it leaves
to the Python loop, which takes it up from the last converged one.
"""

from __future__ import annotations

import math

import numpy as np

from ..atomics import cpu_pause, cpu_yield, load_acquire, store_release
from ..jit import kernel, template
from .domain import domain_step
from .layout import N_OUT, O_AREA_COV, O_AREA_GRAD, O_AREA_VAR, O_COV, O_SE, O_STRESS, O_TANGENT

# ---- the family's kernels: placeholders, bound by kernels.specialise ----


def evaluate_at(flags, law_args, x, ref, out, shared):
    """The flat result (kernels.layout) at ``x`` into ``out``; ``ref`` where fresh contacts are expected to go."""
    raise NotImplementedError


def commit_at(flags, law_args, x, ref, out, extra, shared):
    """Commit the state at the converged ``x``; what the step records of it besides the evaluation into ``extra``."""
    raise NotImplementedError


def serve(flags, law_args, t):
    """Thread t: the parallel parts of the evaluations and commits the calling thread posts, until STOP."""
    raise NotImplementedError


# ---- the hand-off: flags (int64), each on a cache line of its own ----
MAIL, KIND, EPOCH, CLAIMS, CLAIMS2, DONE = 0, 8, 16, 24, 32, 40  # DONE + 8 t: thread t's last part done
STOP = -1


def n_flags(threads: int) -> int:
    """Length of the flags of a span on ``threads`` threads."""
    return DONE + 8 * max(threads, 1)


@kernel(inline="always")
def post(flags, kind):
    """Hand the other threads a part of kind ``kind`` (their arguments already written): its epoch."""
    epoch = flags[EPOCH] + 1
    flags[EPOCH] = epoch
    flags[CLAIMS] = 0
    flags[CLAIMS2] = 0
    flags[KIND] = kind
    store_release(flags, MAIL, epoch)
    return epoch


@kernel(inline="always")
def idle(k):
    """The k-th poll of a wait: a pause, and every 32nd the core to any other thread ready to run on it (where
    threads outnumber the cores, the one with work runs; :func:`asperity_sim.atomics.wait_while`)."""
    if k % 32 == 31:
        cpu_yield()
    else:
        cpu_pause()


@kernel(inline="always")
def next_post(flags, seen):
    """A serving thread's wait for the next part after part ``seen``: its epoch, or STOP."""
    k = 0
    while True:
        v = load_acquire(flags, MAIL)
        if v != seen:
            return v
        idle(k)
        k += 1


@kernel(inline="always")
def said_done(flags, t, epoch):
    """Thread t has done part ``epoch``."""
    store_release(flags, DONE + 8 * t, epoch)


@kernel(inline="always")
def wait_all(flags, epoch, threads):
    """Until every other thread has done part ``epoch``."""
    for t in range(1, threads):
        k = 0
        while load_acquire(flags, DONE + 8 * t) != epoch:
            idle(k)
            k += 1


# ---- layout of the loop's arrays ----
I_K, I_MAXITER, I_MAXEXP, I_ADAPTIVE, I_MMAX, I_STEP0, I_HISTORY, I_THREADS, I_M, N_INTS = range(10)
(R_L, R_RTOL, R_RESTOL, R_FLOOR, R_MAXSTEP, R_MAXSEARCH, R_NOMINAL, R_SMALLEST, R_MAXFRAC, R_COSTOL, R_NORMALRTOL,
 R_LOOPRTOL, R_S, R_DS, R_KREF, R_PREVS, N_REALS) = range(17)
V_START, V_END, V_SSTART, V_DELTA, V_PREVD, V_PREVSLOPE, N_VECS = range(7)  # rows of vecs (3 columns)
# per step: iterations, residual, s at its start, slope (3), stress_stderr (3), displacement_stderr (3), area stderr,
# Delta (3), the law's domain flags, what the commit records (N_EXTRA)
S_IT, S_RES, S_S, S_SLOPE, S_SSE, S_DSE, S_ASE, S_X, S_FLAGS, S_EXTRA = 0, 1, 2, 3, 6, 9, 12, 13, 16, 17
N_EXTRA = 20
N_STEP = S_EXTRA + N_EXTRA
RESOLUTION_ULPS = 64.0


@kernel(inline="always")
def sqrt_nonneg(x):
    """sqrt(max(x, 0)) as :func:`asperity_sim.solve.stepping.sqrt_nonneg`: NaN stays NaN."""
    return math.sqrt(x) if x > 0.0 or x != x else 0.0


@kernel(inline="always")
def py_max(a, b):
    """Python's max(a, b): ``a`` unless ``b > a``."""
    return b if b > a else a


@kernel()
def next_step(adaptive, ds, iterations, nominal, smallest, max_fraction):
    """:func:`asperity_sim.solve.stepping.next_step` after an increment with no cut-back."""
    if adaptive:
        ds = min(ds * (1.5 if iterations <= 3 else 1.0), max_fraction)
        if iterations > 8:
            ds = max(0.5 * ds, smallest)
        return ds
    return nominal


@kernel()
def stderr_of(row, k, out):
    """:func:`~asperity_sim.solve.stepping.solution_stderr` and :func:`~asperity_sim.solve.stepping.area_stderr` under
    stress control of component k alone (k < 0: none): out[0:3] stress, out[3:6] displacement, out[6] area."""
    if k < 0:
        for i in range(3):
            out[i] = row[O_SE + i]
            out[3 + i] = 0.0
        out[6] = sqrt_nonneg(row[O_AREA_VAR])
        return
    t_kk = row[O_TANGENT + 3 * k + k]
    inv = 1.0 / t_kk
    a = inv if t_kk != 0.0 and math.isfinite(inv) else 0.0
    c_kk = row[O_COV + 3 * k + k]
    for i in range(3):
        g = row[O_TANGENT + 3 * i + k] * a
        v = row[O_COV + 3 * i + i] - 2.0 * g * row[O_COV + 3 * i + k] + g * g * c_kk
        out[i] = 0.0 if i == k else sqrt_nonneg(v)
        out[3 + i] = sqrt_nonneg(a * a * c_kk) if i == k else 0.0
    var = row[O_AREA_VAR]
    h = (1.0 / t_kk if t_kk != 0.0 else 0.0) * row[O_AREA_GRAD + k]
    out[6] = sqrt_nonneg(var - 2.0 * (h * row[O_AREA_COV + k]) + h * row[O_COV + 3 * k + k] * h)


@kernel()
def predict(ints, reals, vecs, older, ev, s, s_new, guess, slope):
    """The guess of the increment from s to s_new (its prescribed components already in ``guess``) and the slope of
    the tangent predictor: :func:`~asperity_sim.solve.stepping.tangent_predictor`, then the cubic (path-independent
    law) or the extrapolation through four points (history law) where it is kept."""
    k, delta = ints[I_K], vecs[V_DELTA]
    end, sstart = vecs[V_END], vecs[V_SSTART]
    if k >= 0:
        target_k = sstart[k] + s_new * (end[k] - sstart[k])
        held = 0.0  # the sum first, as Python's sum
        for j in range(3):
            if j != k:
                held += ev[O_TANGENT + 3 * k + j] * (guess[j] - delta[j])
        rhs = (target_k - ev[O_STRESS + k]) - held
        t_kk = ev[O_TANGENT + 3 * k + k]
        if t_kk != 0.0 and math.isfinite(t_kk):
            step = rhs / t_kk
            if math.isfinite(step):
                limit = reals[R_L]
                guess[k] = delta[k] + max(-limit, min(limit, step))
    for a in range(3):
        slope[a] = (guess[a] - delta[a]) / (s_new - s)
    prev_s = reals[R_PREVS]
    if k < 0 or math.isnan(prev_s):
        return
    h0 = s - prev_s
    if not 0.0 < s_new - s <= 2.0 * h0:
        return
    lin = guess[k]
    if ints[I_HISTORY] == 1:  # extrapolated_predictor
        if math.isnan(older[1, 0]):
            return
        nodes_s = (older[1, 0], older[0, 0], prev_s, s)
        nodes_x = (older[1, 1 + k], older[0, 1 + k], vecs[V_PREVD, k], delta[k])
        poly = 0.0
        for a in range(4):
            w = 1.0
            for b in range(4):
                if b != a:
                    w *= (s_new - nodes_s[b]) / (nodes_s[a] - nodes_s[b])
            poly += w * nodes_x[a]
        if abs(poly - lin) <= abs(lin - delta[k]):
            guess[k] = poly
        return
    t = 1.0 + (s_new - s) / h0  # cubic_predictor
    t2, t3 = t * t, t * t * t
    b0, b1, b2, b3 = 2.0 * t3 - 3.0 * t2 + 1.0, (t3 - 2.0 * t2 + t) * h0, 3.0 * t2 - 2.0 * t3, (t3 - t2) * h0
    cubic = b0 * vecs[V_PREVD, k] + b1 * vecs[V_PREVSLOPE, k] + b2 * delta[k] + b3 * slope[k]
    if abs(cubic - lin) <= abs(lin - delta[k]):
        guess[k] = cubic


@template(nogil=True, error_model="numpy")
def newton(flags, law_args, ints, reals, x, ref, target_k, out, shared):
    """:func:`asperity_sim.solve.solver._solve_scalar` from the evaluation in ``out`` at ``x``: (iterations, residual)
    when it converges to rtol, else iterations -1 (the Python solver takes the increment up)."""
    k, L = ints[I_K], reals[R_L]
    rtol, res_tol, floor = reals[R_RTOL], reals[R_RESTOL], reals[R_FLOOR]
    has_lo = has_hi = False
    lo = hi = 0.0
    search = L / 64.0
    x0 = xk = x[k]
    expansions, stalled = 0, 0
    best_search = math.inf
    for it in range(1, ints[I_MAXITER] + ints[I_MAXEXP] + 1):
        m = 0.0
        for i in range(3):
            v = abs(out[O_STRESS + i])
            if v > m or v != v:
                m = v
        scale = py_max(py_max(abs(target_k), m), floor)
        rk = (out[O_STRESS + k] - target_k) / scale
        if not math.isfinite(rk):
            return -1, 0.0
        if abs(rk) <= rtol:
            return it - 1, abs(rk)
        if rk < 0.0:
            has_lo, lo = True, xk
        else:
            has_hi, hi = True, xk
        T = out[O_TANGENT + 3 * k + k] / scale
        x_new = xk - rk / T if T > 0.0 and math.isfinite(T) else math.nan
        if abs(rk) <= res_tol and math.isfinite(x_new):
            step = x_new - xk
            at = py_max(abs(xk), abs(xk + step))
            if abs(step) <= RESOLUTION_ULPS * (np.nextafter(at, math.inf) - at):
                return -1, 0.0  # at the resolution of Delta: the Python solver says so
        if has_lo and has_hi:
            a, b = min(lo, hi), max(lo, hi)
            if not (a < x_new < b):
                x_new = 0.5 * (a + b)
            if b - a <= 1e-15 * py_max(py_max(abs(a), abs(b)), L):
                return -1, 0.0
        else:
            direction = 1.0 if rk < 0.0 else -1.0
            if not math.isfinite(x_new) or abs(x_new - xk) > reals[R_MAXSTEP] * L:
                x_new = xk + direction * search
                search *= 2.0
                expansions += 1
                if abs(rk) < best_search * (1.0 - 1e-9):
                    best_search, stalled = abs(rk), 0
                else:
                    stalled += 1
                if expansions > ints[I_MAXEXP] or stalled >= 8 or abs(x_new - x0) > reals[R_MAXSEARCH] * L:
                    return -1, 0.0
        if not math.isfinite(x_new):
            return -1, 0.0
        x[k] = x_new
        evaluate_at(flags, law_args, x, ref, out, shared)
        xk = x_new
    return -1, 0.0


@template(nogil=True, error_model="numpy")
def increments(flags, law_args, ints, reals, vecs, older, ev, rows, steps, track, last, dcounts, shared):
    """The increments of the stage from the position in ``reals``, ``vecs`` and ``older`` (module docstring): row i of
    ``rows`` the evaluation of increment i, of ``steps`` the rest of its record; ``ints[I_M]`` how many."""
    k = ints[I_K]
    x, slope, ref = np.empty(3), np.empty(3), np.empty(3)
    out = np.empty(N_OUT)
    m = 0
    start, end, delta = vecs[V_START], vecs[V_END], vecs[V_DELTA]
    while reals[R_S] < 1.0 - 1e-12:
        if m >= ints[I_MMAX]:
            ints[I_M] = m
            return
        s, ds = reals[R_S], reals[R_DS]
        ds = min(ds, 1.0 - s)
        s_new = 1.0 if s + ds > 1.0 - 1e-12 else s + ds
        for a in range(3):
            x[a] = delta[a] if a == k else start[a] + s_new * (end[a] - start[a])
            ref[a] = delta[a] if a == k else end[a]  # fresh contacts get springs that fit the stage's end point
        predict(ints, reals, vecs, older, ev, s, s_new, x, slope)
        evaluate_at(flags, law_args, x, ref, out, shared)
        iterations, residual = 0, 0.0
        if k >= 0:
            target_k = vecs[V_SSTART, k] + s_new * (end[k] - vecs[V_SSTART, k])
            iterations, residual = newton(flags, law_args, ints, reals, x, ref, target_k, out, shared)
            if iterations < 0:
                break
        finite = True
        for i in range(O_SE):  # stress, tangent, covariance (solver._checked)
            if not math.isfinite(out[i]):
                finite = False
        if not finite:
            break
        # converged: Position.advance, then the commit
        if not math.isnan(reals[R_PREVS]):
            older[1, :] = older[0, :]
            older[0, 0] = reals[R_PREVS]
            older[0, 1:] = vecs[V_PREVD]
        reals[R_PREVS] = s
        for a in range(3):
            vecs[V_PREVD, a] = delta[a]
            vecs[V_PREVSLOPE, a] = slope[a]
            delta[a] = x[a]
            steps[m, S_X + a] = x[a]
            steps[m, S_SLOPE + a] = slope[a]
        ev[:] = out
        rows[m, :] = out
        commit_at(flags, law_args, x, ref, out, steps[m, S_EXTRA:], shared)
        if k >= 0:
            t_kk = out[O_TANGENT + 3 * k + k]
            reals[R_KREF] = py_max(reals[R_KREF], t_kk if math.isfinite(t_kk) else 0.0)
        steps[m, S_IT], steps[m, S_RES], steps[m, S_S] = iterations, residual, s
        stderr_of(out, k, steps[m, S_SSE:])
        steps[m, S_FLAGS] = 0.0
        if track.shape[0] > 1:  # a path-independent law: its domain
            steps[m, S_FLAGS] = domain_step(track, last, dcounts, ints[I_STEP0] + m, x, out[O_STRESS:O_STRESS + 3],
                                            reals[R_COSTOL], reals[R_NORMALRTOL], reals[R_LOOPRTOL])
        reals[R_DS] = next_step(ints[I_ADAPTIVE] == 1, ds, iterations, reals[R_NOMINAL], reals[R_SMALLEST],
                                reals[R_MAXFRAC])
        reals[R_S] = s_new
        m += 1
    ints[I_M] = m


@template(nogil=True, error_model="numpy")
def span(flags, law_args, ints, reals, vecs, older, ev, rows, steps, track, last, dcounts, lo, hi):
    """Part ``lo`` of :func:`asperity_sim.threads.run_calls` over ``ints[I_THREADS]`` parts: 0 the increments, then
    STOP to the others; t > 0 serves their parallel work."""
    if lo > 0:
        serve(flags, law_args, lo)
        return
    shared = ints[I_THREADS] > 1
    increments(flags, law_args, ints, reals, vecs, older, ev, rows, steps, track, last, dcounts, shared)
    if shared:
        store_release(flags, MAIL, STOP)
