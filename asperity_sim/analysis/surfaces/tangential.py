"""The exact frictional contact of a composite surface under a mean shear traction (boundary elements).

Owns :func:`solve_tangential` (the Cattaneo problem on a periodic grid: Coulomb friction under a
given contact pressure, the rigid tangential shift prescribed) and :func:`bem_shear` (tamaas'
normal solution at a mean pressure, then the tangential one at prescribed mean shear tractions,
with the tangential displacement and the stick area), which the ``mdr`` law is compared with in
``scenarios/exact_contact.py``.

The problem.  Two identical elastic bodies (G, nu) meet along a composite rough surface with slopes
small enough that every contact is normal to the nominal plane.  For identical bodies the normal
and tangential problems are uncoupled (Dundurs' beta = 0; Johnson, *Contact Mechanics*, §5.2 and
§7.2): the pressure p(x) is that of frictionless contact (tamaas ``PolonskyKeerRey`` with the
contact modulus E* = G/(1 - nu)), and the shear traction q(x) solves

    minimise (1/2) q . C q - delta . sum_i q_i   subject to |q_i| <= mu p_i,

whose optimality conditions are Coulomb's law: stick (|q_i| < mu p_i) where the relative
tangential displacement (C q)_i equals the rigid shift delta, slip (|q_i| = mu p_i) where the slip
delta - (C q)_i is parallel to q_i.  C is the relative surface compliance of the two bodies, on a
periodic cell the Fourier multiplier (2 / (G |k|)) (I - nu k k^T / |k|²) (twice Cerruti's single
body; its k = 0 term is dropped, as tamaas drops it in the normal problem, so delta is the shift
relative to the mean surface displacement, the tangential twin of the mean-gap closure).  Under a
tangential load that grows monotonically in one direction at constant normal load the stick
zones only shrink and the slip keeps its direction, so this one-shot solution is the end of the
incremental loading path (Cattaneo 1938; Mindlin 1949) that the model's path also follows.

Solver: accelerated projected gradient (FISTA, Beck & Teboulle 2009) with adaptive restart
(O'Donoghue & Candès 2015); the projection onto the discs is exact, the step 1/L with L the
largest eigenvalue of C.  Converged when the projected-gradient residual, in displacement units,
is below ``tol`` times |delta| at every point.  The mean shear traction Q(delta) is monotone; a
target Q is reached by the secant method on delta.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np


def compliance(shape, size, G, nu):
    """Fourier multipliers (C_xx, C_xy, C_yy) [m/Pa] of the relative tangential compliance on an rfft2 grid."""
    nx, ny = shape
    Lx, Ly = size
    kx = 2 * np.pi * np.fft.fftfreq(nx, Lx / nx)[:, None]
    ky = 2 * np.pi * np.fft.rfftfreq(ny, Ly / ny)[None, :]
    k = np.hypot(kx, ky)
    k[0, 0] = 1.0
    base = 2.0 / (G * k)
    cxx, cxy, cyy = base * (1 - nu * kx**2 / k**2), -base * nu * kx * ky / k**2, base * (1 - nu * ky**2 / k**2)
    for c in (cxx, cxy, cyy):
        c[0, 0] = 0.0
    return cxx, cxy, cyy


def _apply(C, q):
    """Relative tangential displacement (2, nx, ny) [m] of the traction q (2, nx, ny) [Pa]."""
    cxx, cxy, cyy = C
    fx, fy = np.fft.rfft2(q[0]), np.fft.rfft2(q[1])
    s = q.shape[1:]
    return np.stack([np.fft.irfft2(cxx * fx + cxy * fy, s=s), np.fft.irfft2(cxy * fx + cyy * fy, s=s)])


def _project(q, bound):
    """Each q_i radially onto the disc |q_i| <= bound_i."""
    norm = np.hypot(q[0], q[1])
    scale = np.where(norm > bound, bound / np.maximum(norm, 1e-300), 1.0)
    return q * scale


@dataclass(frozen=True)
class TangentialSolution:
    """q (2, nx, ny) [Pa]; delta (2,) [m]; Q (2,) [Pa] mean traction; stick, contact [1] area fractions;
    iterations; residual [1] (projected-gradient residual / |delta|)."""

    q: np.ndarray
    delta: np.ndarray
    Q: np.ndarray
    stick: float
    contact: float
    iterations: int
    residual: float


def solve_tangential(pressure, size, G, nu, mu, delta, q0=None, tol=1e-6, max_iter=50_000, C=None):
    """Shear tractions of the Cattaneo problem at a prescribed rigid tangential shift (module docstring).

    pressure (nx, ny) [Pa]: contact pressure;  size (Lx, Ly) [m];  G [Pa], nu [1] of each body;
    mu [1];  delta (2,) [m] rigid shift;  q0 (2, nx, ny) [Pa] start (warm start), default 0;
    tol [1]: residual / |delta|;  C: :func:`compliance` of this grid, to reuse.
    """
    p = np.asarray(pressure, dtype=float)
    bound = mu * np.maximum(p, 0.0)
    C = compliance(p.shape, size, G, nu) if C is None else C
    lipschitz = 2.0 * max(size) / (2 * np.pi * G)  # the largest multiplier, at |k| = 2 pi / max(L)
    step = 1.0 / lipschitz
    d = np.asarray(delta, dtype=float).reshape(2, 1, 1)
    scale = max(float(np.hypot(*d.ravel())), 1e-300)
    q = np.zeros((2,) + p.shape) if q0 is None else _project(np.array(q0, dtype=float), bound)
    y, t, resid, it = q.copy(), 1.0, math.inf, 0
    for it in range(1, max_iter + 1):
        grad = _apply(C, y) - d
        q_new = _project(y - step * grad, bound)
        if it % 10 == 0 or it == max_iter:  # residual in displacement units, at y
            resid = float(np.abs(y - q_new).max()) / step / scale
            if resid < tol:
                q = q_new
                break
        if np.sum(grad * (q_new - q)) > 0.0:  # restart: the momentum points uphill
            t = 1.0
        t_new = 0.5 * (1.0 + math.sqrt(1.0 + 4.0 * t * t))
        y = q_new + ((t - 1.0) / t_new) * (q_new - q)
        q, t = q_new, t_new
    contact = bound > 0.0
    stick = contact & (np.hypot(q[0], q[1]) < bound * (1.0 - 1e-9))
    return TangentialSolution(q, d.ravel().copy(), q.reshape(2, -1).mean(axis=1), float(stick.mean()),
                              float(contact.mean()), it, resid)


def shear_at(pressure, size, G, nu, mu, target, delta_guess, q0=None, rtol=2e-3, tol=1e-6, C=None, max_solves=30):
    """The solution whose mean traction Q_x is ``target`` [Pa] to ``rtol`` of mu p̄ (secant on delta_x, delta_y = 0).

    delta_guess [m]: a first shift (e.g. the model's); returns (solution, solves).
    """
    C = compliance(np.shape(pressure), size, G, nu) if C is None else C
    cap = mu * float(np.mean(pressure))
    if not 0.0 < target < cap:
        raise ValueError(f"target = {target!r} Pa is out of range (valid range: 0 < target < mu p = {cap!r} Pa)")
    pts, sol = [], None
    x = float(delta_guess)
    for solves in range(1, max_solves + 1):
        sol = solve_tangential(pressure, size, G, nu, mu, (x, 0.0), q0=q0, tol=tol, C=C)
        q0 = sol.q
        pts.append((x, float(sol.Q[0])))
        if abs(sol.Q[0] - target) <= rtol * cap:
            return sol, solves
        below = [pt for pt in pts if pt[1] < target]
        above = [pt for pt in pts if pt[1] > target]
        if below and above:  # secant inside the bracket (regula falsi on the closest points)
            (x0, y0), (x1, y1) = max(below, key=lambda v: v[1]), min(above, key=lambda v: v[1])
            x = x0 + (target - y0) * (x1 - x0) / (y1 - y0)
        elif len(pts) >= 2:  # secant from the last two, never more than doubling
            (x0, y0), (x1, y1) = pts[-2], pts[-1]
            slope = (y1 - y0) / (x1 - x0) if x1 != x0 else 0.0
            x = x1 + (target - y1) / slope if slope > 0 else 2.0 * x1
            x = min(max(x, 0.5 * x1), 2.0 * x1)
        else:  # the chord through the origin (Q is concave in delta: it under-shoots)
            x = x * min(max(target / max(float(sol.Q[0]), 1e-300), 0.5), 2.0)
    raise RuntimeError(f"mean shear traction {target:.4g} Pa not reached in {max_solves} solves "
                       f"(last {pts[-1][1]:.4g} Pa at delta {pts[-1][0]:.4g} m)")


def bem_shear(h, size, G, nu, mu, pressure, fractions, delta_guesses, tolerance=1e-10, tol=1e-6, rtol=5e-3):
    """Frictional contact of the composite surface h at a mean pressure and mean shear tractions.

    h (nx, ny) [m]; size (Lx, Ly) [m]; G [Pa], nu [1] of each of the two bodies; mu [1];
    pressure [Pa]: mean contact pressure (tamaas ``PolonskyKeerRey``, E* = G/(1 - nu));
    fractions: increasing mean shear tractions as fractions of mu p (each in (0, 1)), each reached to
    ``rtol`` of mu p; delta_guesses [m]: a shift for each (e.g. the model's tangential displacement
    there), used as the shape of the curve: the first guess of each level is its delta_guess times
    the ratio found at the level before (the first level starts from the full-stick stiffness).

    Returns a dict of arrays over the fractions: ``traction`` [Pa] (Q_x reached), ``delta`` [m]
    (tangential displacement), ``stick`` and ``contact`` [1] (area fractions), ``solves`` and
    ``seconds``; and ``stiffness`` [Pa/m], the full-stick (Mindlin) tangential stiffness Q/delta of
    the same contact area (every contact point stuck).
    """
    import tamaas as tm

    tm.initialize(1)
    tm.set_log_level(tm.LogLevel.error)
    E_star = G / (1.0 - nu)
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, list(size), list(h.shape))
    model.E, model.nu = E_star, 0.0
    tm.PolonskyKeerRey(model, np.ascontiguousarray(h), tolerance).solve(float(pressure))
    p = np.array(model.traction)
    C = compliance(p.shape, size, G, nu)
    probe = 1e-3 * float(delta_guesses[0])
    stuck = solve_tangential(np.where(p > 0, np.inf, 0.0), size, G, nu, 1.0, (probe, 0.0), tol=tol, C=C)
    stiffness = float(stuck.Q[0] / probe)
    keys = ("traction", "delta", "stick", "contact", "solves", "seconds")
    out = {k: np.empty(len(fractions)) for k in keys}
    q0, ratio = None, None
    for k, (f, guess) in enumerate(zip(fractions, delta_guesses)):
        t0 = time.perf_counter()
        target = f * mu * float(p.mean())
        first = target / stiffness if ratio is None else ratio * float(guess)
        sol, solves = shear_at(p, size, G, nu, mu, target, first, q0=q0, tol=tol, C=C, rtol=rtol)
        q0, ratio = sol.q, sol.delta[0] / float(guess)
        row = (sol.Q[0], sol.delta[0], sol.stick, sol.contact, solves, time.perf_counter() - t0)
        for key, v in zip(keys, row):
            out[key][k] = v
    out["stiffness"] = stiffness
    out["pressure"] = float(p.mean())
    return out
