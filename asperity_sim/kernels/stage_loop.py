"""The increments of a stage of a path-independent law, compiled whole (a template per law).

Owns :func:`span`: the run's increment loop (:meth:`asperity_sim.solve.run.Run.go`) for a
path-independent law under policy follow, without elastic interaction, with at most one
stress-controlled component, as one compiled call handed to the threads once: the predictors
(:mod:`asperity_sim.solve.stepping`), the bracketed Newton of one component
(:mod:`asperity_sim.solve.solver`), the evaluations (:func:`bounds`, ``reduce_parallel`` or
``reduce_serial``, :func:`finish`, as :func:`asperity_sim.kernels.evaluate.at_contacts`), the
stiffness of the stage, the standard errors of each step under its control and the size of the
next increment.  The same arithmetic in the same order as the Python loop, so the same bits.  An
increment it cannot complete the ordinary way (no convergence, a cut-back, a solution accepted at
the resolution of Delta, a non-finite result, the stage's budget spent) is left to the Python loop,
which takes it up from the last converged one.  The calling thread runs the loop; the other waits
in compiled code for each parallel evaluation (``serve``), so no evaluation costs Python or a GIL.
"""

from __future__ import annotations

import math

import numpy as np

from ..atomics import cpu_pause, load_acquire, store_release
from ..jit import kernel, template
from .domain import domain_step
from .layout import CHUNK, N_OUT, O_AREA_COV, O_AREA_GRAD, O_AREA_VAR, O_COV, O_NA, O_SE, O_STRESS, O_TANGENT, \
    SERIAL_ACTIVE_CHUNKS, SERIAL_CHUNKS, finish
from .reach import bounds

# placeholders, bound to the law's copies by kernels.specialise (templates of kernels.reductions)


def reduce_parallel(r, R, u, cos_phi, sin_phi, n_active, delta, r_o, k_e, consts, theta_birth, tan_max, partial,
                    claims, kk_lo, kk_hi):
    raise NotImplementedError


def reduce_serial(r, R, u, cos_phi, sin_phi, R_min, deltas, r_o, k_e, consts, beta, theta_birth, n, scale, partial,
                  out):
    raise NotImplementedError


MAIL, DONE, CLAIMS, STOP = 0, 8, 16, -1  # flags: a post, its done, the chunk counter (cache lines apart)
# reals: the run's constants, then the loop position (updated in place)
(R_RO, R_KE, R_BETA, R_SCALE, R_L, R_RTOL, R_RESTOL, R_FLOOR, R_MAXSTEP, R_MAXSEARCH, R_NOMINAL, R_SMALLEST,
 R_MAXFRAC, R_COSTOL, R_NORMALRTOL, R_LOOPRTOL, R_S, R_DS, R_KREF, R_PREVS, N_REALS) = range(21)
# ints: constants, then counters (updated in place)
I_K, I_MAXITER, I_MAXEXP, I_ADAPTIVE, I_MMAX, I_BUDGET, I_SERIALPOP, I_STEP0, I_M, I_STATUS, I_EPOCH, N_INTS = range(12)
# vecs rows: start_delta, end, start_stress, delta (the last converged), prev_delta, prev_slope
V_START, V_END, V_SSTART, V_DELTA, V_PREVD, V_PREVSLOPE = range(6)
# per step: iterations, residual, s at its start, slope (3), stress_stderr (3), displacement_stderr (3), area stderr,
# Delta (3), the law's domain flags
S_IT, S_RES, S_S, S_SLOPE, S_SSE, S_DSE, S_ASE, S_X, S_FLAGS, N_STEP = 0, 1, 2, 3, 6, 9, 12, 13, 16, 17
DONE_STAGE, LIMIT, PYTHON = 0, 1, 2  # why span stopped: the stage ended, m_max increments, an increment for Python
RESOLUTION_ULPS = 64.0


@kernel(inline="always")
def sqrt_nonneg(x):
    """sqrt(max(x, 0)) as :func:`asperity_sim.solve.stepping.sqrt_nonneg`: NaN stays NaN."""
    return math.sqrt(x) if x > 0.0 or x != x else 0.0


@kernel(inline="always")
def py_max(a, b):
    """Python's max(a, b): ``a`` unless ``b > a`` (NaN never wins against a number)."""
    return b if b > a else a


@kernel(inline="always")
def ulp(x):
    """math.ulp of a finite x >= 0."""
    return np.nextafter(x, math.inf) - x


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
    """:func:`~asperity_sim.solve.stepping.solution_stderr` and :func:`~asperity_sim.solve.stepping.area_stderr` of
    one component k under stress control (k < 0: none): out[0:3] stress, out[3:6] displacement, out[6] area."""
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
    var = var - 2.0 * (h * row[O_AREA_COV + k]) + h * row[O_COV + 3 * k + k] * h
    out[6] = sqrt_nonneg(var)


@template(nogil=True, error_model="numpy")
def serve(flags, r, R, u, cos_phi, sin_phi, counts, d, r_o, k_e, consts, theta_birth, tan_box, partial):
    """The other thread: each posted evaluation's claimed chunks, until STOP is posted."""
    seen = 0
    while True:
        v = load_acquire(flags, MAIL)
        if v == seen:
            cpu_pause()
            continue
        if v == STOP:
            return
        seen = v
        reduce_parallel(r, R, u, cos_phi, sin_phi, counts[0], d, r_o, k_e, consts, theta_birth, tan_box[0], partial,
                        flags[CLAIMS:CLAIMS + 1], 0, counts[1])
        store_release(flags, DONE, v)


@template(nogil=True, error_model="numpy")
def evaluate_at(flags, r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, ints, reals, counts, d, tan_box, x,
                out, shared):
    """``out``: the flat result at ``x`` as :func:`asperity_sim.kernels.evaluate.at_contacts` makes it."""
    r_o, k_e, beta, scale = reals[R_RO], reals[R_KE], reals[R_BETA], reals[R_SCALE]
    empty = np.empty(0)
    for a in range(3):
        d[a] = x[a]
    n_active, tan_max = 0, 0.0
    serial = ints[I_SERIALPOP] == 1
    if not serial:
        n_active, tan_max = bounds(r, R_min, r_o, k_e, beta, d, empty)
        serial = n_active <= SERIAL_ACTIVE_CHUNKS * CHUNK
    if serial:
        reduce_serial(r, R, u, cos_phi, sin_phi, R_min, d.reshape(1, 3), r_o, k_e, consts, beta, empty, n, scale,
                      partial, out.reshape(1, N_OUT))
        return
    n_chunks = (n_active + CHUNK - 1) // CHUNK
    if shared:
        counts[0], counts[1], tan_box[0] = n_active, n_chunks, tan_max
        flags[CLAIMS] = 0
        epoch = ints[I_EPOCH] + 1
        ints[I_EPOCH] = epoch
        store_release(flags, MAIL, epoch)
        reduce_parallel(r, R, u, cos_phi, sin_phi, n_active, d, r_o, k_e, consts, empty, tan_max, partial,
                        flags[CLAIMS:CLAIMS + 1], 0, n_chunks)
        while load_acquire(flags, DONE) != epoch:
            cpu_pause()
    else:
        reduce_parallel(r, R, u, cos_phi, sin_phi, n_active, d, r_o, k_e, consts, empty, tan_max, partial,
                        flags[0:0], 0, n_chunks)
    finish(partial, n_chunks, n, scale, out)
    out[O_NA] = n_active


@template(nogil=True, error_model="numpy")
def newton(flags, r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, ints, reals, counts, d, tan_box, x,
           target_k, out, shared):
    """:func:`asperity_sim.solve.solver._solve_scalar` from the evaluation in ``out`` at ``x``: (iterations, residual)
    when it converges to rtol, else iterations -1 (the Python solver takes the increment up)."""
    k, L = ints[I_K], reals[R_L]
    rtol, res_tol, floor = reals[R_RTOL], reals[R_RESTOL], reals[R_FLOOR]
    has_lo = has_hi = has_prev = False
    lo = hi = r_prev = 0.0
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
        has_prev, r_prev = True, rk
        if rk < 0.0:
            has_lo, lo = True, xk
        else:
            has_hi, hi = True, xk
        T = out[O_TANGENT + 3 * k + k] / scale
        x_new = xk - rk / T if T > 0.0 and math.isfinite(T) else math.nan
        if abs(rk) <= res_tol and math.isfinite(x_new):
            step = x_new - xk
            if abs(step) <= RESOLUTION_ULPS * ulp(py_max(abs(xk), abs(xk + step))):
                return -1, 0.0  # converged at the resolution of Delta: the Python solver says so
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
        evaluate_at(flags, r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, ints, reals, counts, d, tan_box, x,
                    out, shared)
        xk = x_new
    return -1, 0.0


@template(nogil=True, error_model="numpy")
def increments(flags, r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, ints, reals, vecs, ev, counts, d,
               tan_box, rows, steps, track, last, dcounts, shared):
    """The increments of the stage from the position in ``reals``/``vecs`` (module docstring): row i of ``rows``
    the evaluation of increment i, of ``steps`` its solve and standard errors; ``ints[I_STATUS]`` why it stopped."""
    k = ints[I_K]
    x = np.empty(3)
    guess = np.empty(3)
    out = np.empty(N_OUT)
    m = 0
    start, end, sstart, delta = vecs[V_START], vecs[V_END], vecs[V_SSTART], vecs[V_DELTA]
    limit = reals[R_L]  # TRUST length scales
    while reals[R_S] < 1.0 - 1e-12:
        if m >= ints[I_MMAX]:
            ints[I_M], ints[I_STATUS] = m, LIMIT
            return
        if m >= ints[I_BUDGET]:
            break
        s, ds = reals[R_S], reals[R_DS]
        ds = min(ds, 1.0 - s)
        s_new = 1.0 if s + ds > 1.0 - 1e-12 else s + ds
        for a in range(3):
            guess[a] = delta[a] if a == k else start[a] + s_new * (end[a] - start[a])
        target_k = 0.0
        if k >= 0:
            target_k = sstart[k] + s_new * (end[k] - sstart[k])
            # tangent_predictor, one free component (the sum first, as Python's sum)
            held = 0.0
            for j in range(3):
                if j != k:
                    held += ev[O_TANGENT + 3 * k + j] * (guess[j] - delta[j])
            rhs = (target_k - ev[O_STRESS + k]) - held
            t_kk = ev[O_TANGENT + 3 * k + k]
            if t_kk != 0.0 and math.isfinite(t_kk):
                step = rhs / t_kk
                if math.isfinite(step):
                    guess[k] = delta[k] + max(-limit, min(limit, step))
        for a in range(3):
            steps[m, S_SLOPE + a] = (guess[a] - delta[a]) / (s_new - s)
        prev_s = reals[R_PREVS]
        if k >= 0 and not math.isnan(prev_s):  # cubic_predictor
            h0 = s - prev_s
            if 0.0 < s_new - s <= 2.0 * h0:
                t = 1.0 + (s_new - s) / h0
                t2, t3 = t * t, t * t * t
                b0, b1 = 2.0 * t3 - 3.0 * t2 + 1.0, (t3 - 2.0 * t2 + t) * h0
                b2, b3 = 3.0 * t2 - 2.0 * t3, (t3 - t2) * h0
                lin = guess[k]
                cubic = (b0 * vecs[V_PREVD, k] + b1 * vecs[V_PREVSLOPE, k] + b2 * delta[k]
                         + b3 * steps[m, S_SLOPE + k])
                if abs(cubic - lin) <= abs(lin - delta[k]):
                    guess[k] = cubic
        for a in range(3):
            x[a] = guess[a]
        evaluate_at(flags, r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, ints, reals, counts, d, tan_box, x,
                    out, shared)
        iterations, residual = 0, 0.0
        if k >= 0:
            iterations, residual = newton(flags, r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, ints, reals,
                                          counts, d, tan_box, x, target_k, out, shared)
            if iterations < 0:
                break
        finite = True
        for i in range(O_SE):  # stress, tangent, covariance (_checked)
            if not math.isfinite(out[i]):
                finite = False
        if not finite:
            break
        # converged: the position moves on (Position.advance; the caller replays it)
        reals[R_PREVS] = s
        for a in range(3):
            vecs[V_PREVD, a] = delta[a]
            vecs[V_PREVSLOPE, a] = steps[m, S_SLOPE + a]
            delta[a] = x[a]
            steps[m, S_X + a] = x[a]
        for i in range(N_OUT):
            ev[i] = out[i]
            rows[m, i] = out[i]
        if k >= 0:
            t_kk = out[O_TANGENT + 3 * k + k]
            reals[R_KREF] = py_max(reals[R_KREF], t_kk if math.isfinite(t_kk) else 0.0)
        steps[m, S_IT], steps[m, S_RES], steps[m, S_S] = iterations, residual, s
        stderr_of(out, k, steps[m, S_SSE:])
        steps[m, S_FLAGS] = domain_step(track, last, dcounts, ints[I_STEP0] + m, x, out[O_STRESS:O_STRESS + 3],
                                        reals[R_COSTOL], reals[R_NORMALRTOL], reals[R_LOOPRTOL])
        reals[R_DS] = next_step(ints[I_ADAPTIVE] == 1, ds, iterations, reals[R_NOMINAL], reals[R_SMALLEST],
                                reals[R_MAXFRAC])
        reals[R_S] = s_new
        m += 1
    ints[I_M] = m
    ints[I_STATUS] = DONE_STAGE if reals[R_S] >= 1.0 - 1e-12 else PYTHON


@template(nogil=True, error_model="numpy")
def span(flags, r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, ints, reals, vecs, ev, counts, d, tan_box,
         rows, steps, track, last, dcounts, lo, hi):
    """Part ``lo .. hi`` of :func:`asperity_sim.threads.run_calls` over 2 parts: 0 the increments, then STOP; 1 serves
    their parallel evaluations; both on one thread: the increments alone."""
    if lo == 1:
        serve(flags, r, R, u, cos_phi, sin_phi, counts, d, reals[R_RO], reals[R_KE], consts, np.empty(0), tan_box,
              partial)
    elif hi == 1:
        increments(flags, r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, ints, reals, vecs, ev, counts, d,
                   tan_box, rows, steps, track, last, dcounts, True)
        store_release(flags, MAIL, STOP)
    else:
        increments(flags, r, R, u, cos_phi, sin_phi, R_min, consts, partial, n, ints, reals, vecs, ev, counts, d,
                   tan_box, rows, steps, track, last, dcounts, False)
