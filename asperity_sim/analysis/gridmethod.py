"""The paper's deterministic grid method (Misra & Huang, Section 3.4, Steps 1–5), ``paper`` law.

Owns a faithful re-implementation of the numerical scheme the paper used, so that the
Monte Carlo estimator can be compared with it side by side (issue 5).  It is not the
package's reference: :mod:`asperity_sim.reference` is (~1e-6 relative); this module
reproduces the paper's own discretisation, with its own discretisation error.

Step 1 (quadrature of Eq. 23, SPEC §6):
    heights r on [0, r_top] with spacing Delta_r = 0.01 r90 (r90: 90th percentile of the
    gamma height density, SPEC §2; r_top: the gamma quantile 1 - 1e-15, rounded up to a
    whole even number of intervals), relative radii R on the truncated support
    [R_m - 3 R_sigma, R_m + 3 R_sigma] (SPEC §2) with Delta_R = 0.01 R_sigma, and a
    20 x 40 grid in theta and phi: theta in [0, theta_m(c, R)] (Eq. 9, so the theta grid
    moves with the closure), i.e. u = (pi/2) theta / theta_m uniform in [0, pi/2], and phi
    in [0, 2 pi].  Every axis is integrated with the composite Simpson rule (weights 1, 4,
    2, ..., 4, 1 times h/3), the densities (gamma H(r), truncated Gaussian p(R), the
    orientation density xi(u, phi) sin u of Eq. 10, corrected) multiplied into the weights;
    no weight is renormalised (as in the paper).
Steps 2–3: the force of every grid point (an "asperity") from Eqs. (12)–(21), summed.
Step 4: the tangent T_ik = d sigma_i / d Delta_k (Eq. 27) by forward differences with step
    dDelta = 0.01 r90, in all three components, at every iterate (three extra stress
    evaluations; the Dataset records it at each converged increment, as the Monte Carlo run
    records its analytic tangent).  ``full_tangent=False`` is a lighter variant that is not
    the paper's: only the columns of the stress-controlled components, only while the
    residual is above the tolerance, nothing recorded (a displacement-controlled increment
    then costs one evaluation instead of four).
Step 5: Newton update dDelta_f = T_ff^-1 (sigma_target_f - sigma_f) until
    |residual| <= rtol * max(|sigma_target|, |sigma|).

``GridResolution(dr, dR, n_theta, n_phi)`` holds the four resolutions (``PAPER`` is the
published one); ``GridResolution.scaled(s)`` multiplies the two spacings by s and divides
the two interval counts by s (rounded to even counts), so s = 2 is coarser and s = 0.5 finer.

Cost: only grid points in contact are visited.  For fixed (R, theta, phi), delta_n is
affine and decreasing in r (SPEC §4), so the height loop stops at the end of contact; this
skips exactly the points whose force is zero and does not change the sum.  The loop over
R nodes is parallel (prange), each node writing its own row, so the result does not depend
on the number of threads.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numba
import numpy as np
import xarray as xr
from scipy import special

from .. import geometry
from ..geometry import theta_m_and_slope
from ..jit import kernel
from ..kernels.layout import chunk_stride
from ..laws.paper import paper_local
from ..params import InterfaceParams
from ..paths import LoadPath
from .gridnewton import fd_tangent, grid_newton

HALF_PI = 0.5 * math.pi


@dataclass(frozen=True)
class GridResolution:
    """Resolution of the paper's grid (Step 1).

    dr : float [1]      height spacing as a fraction of r90
    dR : float [1]      radius spacing as a fraction of R_sigma
    n_theta : int       Simpson intervals in theta over [0, theta_m] (even)
    n_phi : int         Simpson intervals in phi over [0, 2 pi] (even)
    fd_step : float [1] finite-difference step of Step 4 as a fraction of r90
    """

    dr: float = 0.01
    dR: float = 0.01
    n_theta: int = 20
    n_phi: int = 40
    fd_step: float = 0.01

    def __post_init__(self):
        for name in ("dr", "dR", "fd_step"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 0.0 < v <= 1.0):
                raise ValueError(f"{name} = {v!r} is out of range (valid range: (0, 1])")
        for name in ("n_theta", "n_phi"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 2 or v % 2:
                raise ValueError(f"{name} = {v!r} is not valid (valid range: even integer >= 2)")

    @classmethod
    def scaled(cls, s: float) -> "GridResolution":
        """The published resolution with spacings times s and interval counts divided by s."""
        if not (math.isfinite(s) and s > 0):
            raise ValueError(f"s = {s!r} must be a finite number > 0")

        def even(k):
            return max(2, 2 * int(round(k / (2.0 * s))))

        return cls(dr=0.01 * s, dR=0.01 * s, n_theta=even(20), n_phi=even(40), fd_step=0.01)

    def label(self) -> str:
        return f"dr={self.dr:g} r90, dR={self.dR:g} R_sigma, {self.n_theta}x{self.n_phi}"


PAPER = GridResolution()


def r_percentile(params: InterfaceParams, q: float = 0.9) -> float:
    """Height percentile [m] of the gamma density of SPEC §2 (r90 for q = 0.9)."""
    return float(special.gammaincinv(params.alpha + 1.0, q) * params.beta)


def simpson_weights(m: int, h: float) -> np.ndarray:
    """Composite Simpson weights for m (even) intervals of width h: (h/3)(1, 4, 2, ..., 4, 1)."""
    w = np.full(m + 1, 2.0)
    w[1::2] = 4.0
    w[0] = w[-1] = 1.0
    return w * (h / 3.0)


@dataclass(frozen=True)
class GridRule:
    """Nodes and weights of Step 1 that do not depend on the displacement.

    r, w_r : height nodes [m] and Simpson weights times H(r) [1]
    R, w_R : radius nodes [m] and Simpson weights times p(R) [1]
    t_u, w_u : u / (pi/2) in [0, 1] and Simpson weights on [0, pi/2] times sin u [1]
    phi, w_phi : azimuth nodes [rad] and Simpson weights on [0, 2 pi] [rad]
    """

    resolution: GridResolution
    r90: float
    r: np.ndarray
    w_r: np.ndarray
    R: np.ndarray
    w_R: np.ndarray
    t_u: np.ndarray
    w_u: np.ndarray
    phi: np.ndarray
    w_phi: np.ndarray

    @property
    def n_points(self) -> int:
        """Grid points (asperities) of the full tensor grid."""
        return self.r.size * self.R.size * self.t_u.size * self.phi.size


def grid_rule(params: InterfaceParams, resolution: GridResolution = PAPER) -> GridRule:
    """Build the Step 1 grid for ``params`` (SPEC §2–§3 densities, Simpson weights)."""
    if not isinstance(params, InterfaceParams):
        raise ValueError(f"params = {params!r} is not an InterfaceParams")
    res = resolution
    a1 = params.alpha + 1.0
    r90 = r_percentile(params, 0.9)
    h_r = res.dr * r90
    r_top = params.beta * float(special.gammainccinv(a1, 1e-15))
    m_r = 2 * int(math.ceil(r_top / (2.0 * h_r)))
    r = h_r * np.arange(m_r + 1)
    with np.errstate(divide="ignore"):
        log_H = special.xlogy(params.alpha, r) - r / params.beta - special.gammaln(a1) - a1 * math.log(params.beta)
    H = np.exp(log_H)
    if params.alpha == 0.0:
        H[0] = 1.0 / params.beta
    elif params.alpha < 0.0:
        H[0] = 0.0  # integrable singularity at r = 0: the Simpson rule cannot use the end point
    w_r = simpson_weights(m_r, h_r) * H
    if params.R_sigma == 0.0:
        R = np.array([params.R_m])
        w_R = np.array([1.0])
    else:
        lo, hi = params.R_bounds
        m_R = max(2, 2 * int(round((hi - lo) / (2.0 * res.dR * params.R_sigma))))
        R = np.linspace(lo, hi, m_R + 1)
        z_lo, z_hi = (lo - params.R_m) / params.R_sigma, (hi - params.R_m) / params.R_sigma
        Z = special.ndtr(z_hi) - special.ndtr(z_lo)
        pdf = np.exp(-0.5 * ((R - params.R_m) / params.R_sigma) ** 2) / (math.sqrt(2 * math.pi) * params.R_sigma * Z)
        w_R = simpson_weights(m_R, (hi - lo) / m_R) * pdf
        R = np.maximum(R, np.nextafter(0.0, 1.0))
    t_u = np.linspace(0.0, 1.0, res.n_theta + 1)
    w_u = simpson_weights(res.n_theta, HALF_PI / res.n_theta) * np.sin(HALF_PI * t_u)
    phi = np.linspace(0.0, 2.0 * math.pi, res.n_phi + 1)
    w_phi = simpson_weights(res.n_phi, 2.0 * math.pi / res.n_phi)
    return GridRule(res, r90, r, w_r, R, w_R, t_u, w_u, phi, w_phi)


@kernel(parallel=True)
def _grid_kernel(d1, d2, d3, closure, k_e, E_star, lam, mu, b, c, d,
                 r, w_r, R, w_R, t_u, w_u, phi, w_phi, rows, visited):
    """rows[iR] = w_R sum over (u, phi, r) of the weighted global force E[f] / N (Steps 2–3)."""
    n_r = r.size
    stride = chunk_stride(R.size)
    for i_par in numba.prange(R.size):
        iR = (i_par * stride) % R.size  # spread the radii over the threads (the cost varies with R)
        R_i = R[iR]
        th_m, _ = theta_m_and_slope(closure, 1.0 / R_i, k_e)
        sqrt_R = math.sqrt(R_i)
        s1 = 0.0
        s2 = 0.0
        s3 = 0.0
        count = 0
        for iu in range(t_u.size):
            if w_u[iu] == 0.0:
                continue
            u = HALF_PI * t_u[iu]
            th = t_u[iu] * th_m
            ct = math.cos(th)
            st = math.sin(th)
            cu = math.cos(u)
            iso = 1.0 + b * 0.5 * (3.0 * cu * cu - 1.0)
            su2 = 1.0 - cu * cu
            for ip in range(phi.size):
                cp = math.cos(phi[ip])
                sp = math.sin(phi[ip])
                xi = (iso + 3.0 * su2 * (c * (cp * cp - sp * sp) + d * 2.0 * sp * cp)) / (2.0 * math.pi)
                w = w_u[iu] * w_phi[ip] * xi
                if w == 0.0:
                    continue
                sh = cp * d2 + sp * d3
                a_n = ct * d1 + st * sh  # delta_n at r = 0; delta_n = a_n - ct r
                if a_n <= 0.0:
                    continue
                a_s = -st * d1 + ct * sh  # delta_s = a_s + st r
                d_t = -sp * d2 + cp * d3
                i_n = 0.0
                i_s = 0.0
                i_t = 0.0
                for k in range(n_r):
                    dn = a_n - ct * r[k]
                    if dn <= 0.0:
                        break
                    if w_r[k] == 0.0:
                        continue
                    f_n, f_s, f_t, _, _, _, _, _ = paper_local(dn, a_s + st * r[k], d_t, sqrt_R, E_star, lam, mu)
                    i_n += w_r[k] * f_n
                    i_s += w_r[k] * f_s
                    i_t += w_r[k] * f_t
                    count += 1
                s1 += w * (ct * i_n - st * i_s)
                s2 += w * (st * cp * i_n + ct * cp * i_s - sp * i_t)
                s3 += w * (st * sp * i_n + ct * sp * i_s + cp * i_t)
        rows[iR, 0] = w_R[iR] * s1
        rows[iR, 1] = w_R[iR] * s2
        rows[iR, 2] = w_R[iR] * s3
        visited[iR] = count


class GridEvaluator:
    """Interface stress of the grid (Steps 1–3) at any displacement; counts its work."""

    def __init__(self, params, rule):
        self.p = params
        self.rule = rule
        self.rows = np.zeros((rule.R.size, 3))
        self.visited = np.zeros(rule.R.size, dtype=np.int64)
        self.calls = 0
        self.points = 0

    def __call__(self, delta):
        p, g = self.p, self.rule
        d = np.asarray(delta, dtype=float)
        closure = float(geometry.closure(p, d[0]))
        _grid_kernel(float(d[0]), float(d[1]), float(d[2]), closure, p.k_e, p.E_star, p.lam, p.mu,
                     p.b, p.c, p.d, g.r, g.w_r, g.R, g.w_R, g.t_u, g.w_u, g.phi, g.w_phi,
                     self.rows, self.visited)
        self.calls += 1
        self.points += int(self.visited.sum())
        return p.N * self.rows.sum(axis=0)


def stress(params: InterfaceParams, delta, resolution: GridResolution = PAPER, rule: GridRule | None = None):
    """Interface stress sigma [Pa] (3,) at displacement delta [m] by the paper's grid (Step 1)."""
    rule = grid_rule(params, resolution) if rule is None else rule
    d = np.asarray(delta, dtype=float)
    if d.shape != (3,) or not np.all(np.isfinite(d)):
        raise ValueError(f"delta = {delta!r} must be 3 finite numbers [m]")
    return GridEvaluator(params, rule)(d)


def simulate_grid(params: InterfaceParams, path: LoadPath, resolution: GridResolution = PAPER, *,
                  rtol: float = 1e-9, max_iter: int = 60, full_tangent: bool = True) -> xr.Dataset:
    """Run ``path`` with the paper's grid method (Steps 1–5); returns a Dataset like :func:`simulate`.

    Every stage is split into its nominal increments (no cut-backs); in each increment the
    displacement-controlled components are prescribed and the stress-controlled ones are
    solved by Newton with the forward-difference tangent of Step 4, starting from the last
    converged displacement (Step 2).  Variables: ``displacement`` (step, axis) [m],
    ``stress`` (step, axis) [Pa], ``tangent`` (step, axis, axis_k) [Pa/m] (only with
    ``full_tangent``, the paper's Step 4; see the module docstring for the variant),
    ``iterations`` (step), ``stage`` (step), ``control`` (step, axis).
    Attributes: resolution, grid points, points visited, stress evaluations and wall time.
    """
    if not isinstance(path, LoadPath):
        raise ValueError(f"path = {path!r} is not a LoadPath")
    if not isinstance(full_tangent, bool):
        raise ValueError(f"full_tangent = {full_tangent!r} must be True (Step 4 as published) or False")
    t0 = time.perf_counter()
    rule = grid_rule(params, resolution)
    F = GridEvaluator(params, rule)
    h = resolution.fd_step * rule.r90
    x = np.zeros(3)
    x_prev = x.copy()
    sig = F(x)
    T = fd_tangent(F, x, sig, h, range(3)) if full_tangent else None
    disp, stress_, iters, stages, control = [x.copy()], [sig.copy()], [0], [0], [np.zeros(3, bool)]
    tangents = [T]
    for i_stage, stage in enumerate(path.stages, 1):
        free = stage.stress_controlled
        start_x, start_s = x.copy(), sig.copy()
        end = np.asarray(stage.target, dtype=float)
        for i in range(1, stage.increments + 1):
            s = i / stage.increments
            target_x = start_x + s * (end - start_x)
            target_s = start_s + s * (end - start_s)
            guess = x + (x - x_prev) if (free.any() and i > 1) else x  # secant predictor (free components)
            x_prev = x.copy()
            x = np.where(free, guess, target_x)
            sig = F(x)
            it = 0
            if free.any():
                x, sig, it, _, T = grid_newton(F, x, sig, free, np.where(free, target_s, 0.0), h, rtol,
                                               max_iter, full_tangent)
            elif full_tangent:  # Steps 2-4 once: nothing to solve, the tangent is still evaluated
                T = fd_tangent(F, x, sig, h, range(3))
            disp.append(x.copy())
            stress_.append(sig.copy())
            tangents.append(T)
            iters.append(it)
            stages.append(i_stage)
            control.append(free.copy())
    wall = time.perf_counter() - t0
    axis = np.arange(1, 4)
    data = {
        "displacement": (("step", "axis"), np.array(disp), {"units": "m", "long_name": "interface displacement"}),
        "stress": (("step", "axis"), np.array(stress_),
                   {"units": "Pa", "long_name": "interface stress (grid method)"}),
        "iterations": ("step", np.array(iters), {"units": "1", "long_name": "Newton iterations (Steps 4-5)"}),
        "stage": ("step", np.array(stages), {"units": "1", "long_name": "load path stage"}),
        "control": (("step", "axis"), np.array(control).astype("i1"),
                    {"units": "1", "long_name": "1 where the stress is prescribed"}),
    }
    coords = {"step": np.arange(len(disp)), "axis": axis}
    if full_tangent:
        data["tangent"] = (("step", "axis", "axis_k"), np.array(tangents),
                           {"units": "Pa m-1", "long_name": "tangent d sigma_axis / d Delta_axis_k by forward "
                                                           f"differences of step {h:.4g} m (Step 4, Eq. 27)"})
        coords["axis_k"] = axis
    step4 = ("all three components at every iterate (as published)" if full_tangent else
             "stress-controlled components only, while iterating (lighter than the paper's Step 4)")
    return xr.Dataset(
        data, coords=coords,
        attrs={"method": "paper grid (Steps 1-5)", "resolution": resolution.label(), "step4_tangent": step4,
               "grid_points": rule.n_points, "points_visited": F.points, "stress_evaluations": F.calls,
               "wall_time_s": wall, "path": path.name},
    )
