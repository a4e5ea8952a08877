"""A sampled population of asperity contacts (SPEC §2–§3).

Owns :class:`Population` and its invariants; the random points come from
:mod:`asperity_sim.sampling.draws` (the only module that touches random generators), mapped
through :mod:`asperity_sim.sampling.distributions`.  A population is struct-of-arrays (no Python object per asperity): heights r, relative radii R and
fixed shifted orientation coordinates (u, phi), stored sorted by height so that a
kernel can skip every asperity that cannot touch at a given displacement.

Each draw maps one point of the unit hypercube [0, 1)^4 through the inverse CDFs of
the independent densities: gamma heights (SPEC §2, corrected normalisation), the
truncated Gaussian radius, the marginal of cos u, and the conditional of phi given u
(Eq. 10, corrected).  ``sampler="random"`` takes the points from numpy's PCG64,
``sampler="sobol"`` from scrambled Sobol' points (randomised QMC).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import special

from ..checks import check_choice, check_int
from ..jit import kernel
from ..params import InterfaceParams
from .distributions import band_probability, quantile_table, radius_constants
from .draws import (
    argsort_unit,
    clip_running_max,
    gather,
    inverse_cdfs,
    sample_net,
    unit_points,
)
from .reach import reach
from .sobol import net_directions

SAMPLERS = ("random", "sobol")


N_MAX = 2**31 - 1


UNIT_TOL = 1e-12  # largest |cos² phi + sin² phi - 1| accepted in a Population
CHECKED_IN_PYTHON = 64
"""Populations of at most this many asperities are checked by the Python of :func:`_all_valid`: compiling it
would cost half a second more than the check (the compile-ahead helper's three asperities, single contacts)."""


@kernel()
def _all_valid(r, R, u, cos_phi, sin_phi):
    """True if every asperity keeps the invariants of :func:`_first_invalid`; branch-free (vectorises)."""
    half_pi = 0.5 * math.pi
    ok = True
    prev = 0.0
    for i in range(r.shape[0]):
        ri = r[i]
        c = cos_phi[i]
        s = sin_phi[i]
        ok &= ((ri >= prev) & (ri < math.inf) & (R[i] > 0.0) & (R[i] < math.inf) & (u[i] >= 0.0)
               & (u[i] <= half_pi) & (abs(c * c + s * s - 1.0) <= UNIT_TOL))
        prev = ri
    return ok


@kernel()
def _first_invalid(r, R, u, cos_phi, sin_phi):
    """(code, i): the first asperity i that breaks an invariant the kernels rely on, code 0 if none.

    Codes: 1 r not finite or < 0; 2 r[i] < r[i-1] (heights must be sorted: the kernels stop at
    the first height out of reach); 3 R not finite or <= 0; 4 u outside [0, pi/2] (or NaN);
    5 cos phi or sin phi not finite, or |cos² + sin² - 1| > UNIT_TOL.
    """
    half_pi = 0.5 * math.pi
    prev = 0.0
    for i in range(r.shape[0]):
        ri = r[i]
        if not (0.0 <= ri < math.inf):
            return 1, i
        if ri < prev:
            return 2, i
        prev = ri
        if not (0.0 < R[i] < math.inf):
            return 3, i
        if not (0.0 <= u[i] <= half_pi):
            return 4, i
        c = cos_phi[i]
        s = sin_phi[i]
        if not abs(c * c + s * s - 1.0) <= UNIT_TOL:
            return 5, i
    return 0, -1


_ARRAYS = ("r", "R", "u", "cos_phi", "sin_phi")


@dataclass(frozen=True, eq=False)
class Population:
    """n sampled asperities as struct-of-arrays, sorted by height r.

    Attributes
    ----------
    params : InterfaceParams
    r : ndarray (n,) [m]        asperity height below the highest summit
    R : ndarray (n,) [m]        relative radius of curvature
    u : ndarray (n,) [rad]      shifted meridional coordinate in [0, pi/2]
    cos_phi, sin_phi : ndarray (n,) [1]  azimuth phi as its cosine and sine
    weight : float [1]          probability weight of each sample: P(r <= r_band) / n (1/n without a band)
    seed, sampler : how it was drawn
    r_band : float [m]          heights were drawn from the gamma density truncated to [0, r_band]
                                (inf: no band); see :meth:`sample` and :mod:`asperity_sim.solve.pruning`
    """

    params: InterfaceParams
    r: np.ndarray
    R: np.ndarray
    u: np.ndarray
    cos_phi: np.ndarray
    sin_phi: np.ndarray
    weight: float
    seed: int | None
    sampler: str
    r_band: float = math.inf

    def __post_init__(self):
        """Check every invariant the kernels rely on (SPEC §2–§3); O(n), one pass, no copies.

        A Population built directly (from a checkpoint, or by hand) with unsorted heights, NaN,
        out-of-range values or arrays of unequal length would make the kernels skip asperities,
        read out of bounds or return garbage; it is refused with a ``ValueError`` naming the array,
        the first bad element and the valid range.
        """
        if not isinstance(self.params, InterfaceParams):
            raise ValueError(f"params = {self.params!r} is not an InterfaceParams")
        n = None
        for name in _ARRAYS:
            a = getattr(self, name)
            if not isinstance(a, np.ndarray):
                raise ValueError(f"Population.{name} is a {type(a).__name__}, not a numpy array "
                                 "(valid: 1-D float64 ndarray)")
            if a.dtype != np.float64 or a.ndim != 1:
                raise ValueError(f"Population.{name} has dtype {a.dtype} and shape {a.shape} "
                                 "(valid: 1-D float64 array)")
            if n is None:
                n = a.shape[0]
                if n < 1:
                    raise ValueError("Population.r is empty (valid range: n >= 1 asperities)")
            elif a.shape[0] != n:
                raise ValueError(f"Population.{name} has length {a.shape[0]}, r has length {n} "
                                 "(valid: all five arrays of equal length)")
        all_valid = _all_valid.py_func if n <= CHECKED_IN_PYTHON else _all_valid
        if not all_valid(self.r, self.R, self.u, self.cos_phi, self.sin_phi):  # the fast pass; then find why
            code, i = _first_invalid(self.r, self.R, self.u, self.cos_phi, self.sin_phi)
            raise ValueError(self._invalid_text(code, i))
        w = self.weight
        if isinstance(w, bool) or not isinstance(w, numbers.Real) or not (0.0 < w < math.inf):
            raise ValueError(f"Population.weight = {w!r} is not valid (valid range: finite and > 0)")
        if self.seed is not None and (isinstance(self.seed, bool) or not isinstance(self.seed, numbers.Integral)
                                      or self.seed < 0):
            raise ValueError(f"Population.seed = {self.seed!r} is not valid (valid range: None or integer >= 0)")
        if not isinstance(self.sampler, str):
            raise ValueError(f"Population.sampler = {self.sampler!r} is not a string")
        rb = self.r_band
        if isinstance(rb, bool) or not isinstance(rb, numbers.Real) or not rb > 0.0:
            raise ValueError(f"Population.r_band = {rb!r} is not valid (valid range: > 0 [m], inf for no band)")

    def _invalid_text(self, code, i):
        if code == 0:  # _all_valid and _first_invalid disagree: cannot happen, but never pass silently
            return "Population arrays failed the validity check (r, R, u, cos_phi, sin_phi)"
        if code == 1:
            return f"Population.r[{i}] = {float(self.r[i])!r} is not valid (valid range: finite and >= 0 [m])"
        if code == 2:
            return (f"Population.r is not sorted: r[{i}] = {float(self.r[i])!r} < r[{i - 1}] = {float(self.r[i - 1])!r} "
                    "(valid: heights sorted non-decreasing [m]; Population.from_arrays sorts them)")
        if code == 3:
            return f"Population.R[{i}] = {float(self.R[i])!r} is not valid (valid range: finite and > 0 [m])"
        if code == 4:
            return f"Population.u[{i}] = {float(self.u[i])!r} is not valid (valid range: [0, pi/2] [rad])"
        c, s = float(self.cos_phi[i]), float(self.sin_phi[i])
        return (f"Population.cos_phi[{i}] = {c!r}, sin_phi[{i}] = {s!r} are not the cosine and sine of one angle "
                f"(valid: finite with |cos² + sin² - 1| <= {UNIT_TOL:g})")

    @classmethod
    def sample(cls, params: InterfaceParams, n: int, seed: int | None = 0, sampler: str = "random",
               r_max: float | None = None) -> "Population":
        """Draw n asperities from SPEC §2–§3; same (params, n, seed, sampler, r_max) gives identical arrays.

        With ``r_max`` [m] (a height band, see :mod:`asperity_sim.solve.pruning`) the heights are drawn
        from the gamma density truncated to [0, r_max] (inverse CDF of the band) and every sample
        carries the weight p / n, p = P(r <= r_max) exactly (regularised incomplete gamma), so
        sigma = N (p / n) sum f is unbiased for Eq. (23) whenever no asperity above r_max touches.
        ``r_max=None`` or inf is the full density (identical arrays to no band).
        """
        if not isinstance(params, InterfaceParams):
            raise ValueError(f"params = {params!r} is not an InterfaceParams")
        n = check_int("n", n, 1, N_MAX)
        seed = None if seed is None else check_int("seed", seed, 0)
        check_choice("sampler", sampler, SAMPLERS)
        p_band, r_band = band_probability(params, r_max), math.inf if r_max is None else float(r_max)
        if not p_band > 0.0:
            raise ValueError(f"r_max = {r_max!r} m holds no probability (P(r <= r_max) = {p_band!r}): band too narrow")
        # the height is monotone in its uniform, so sorting the points by it sorts by height.
        # Sobol', n = 2^m: the first coordinate is a (0, m, 1)-net (one point per cell of width
        # 1/n), so the points are generated directly in that order (no sort, no array of uniforms).
        # Otherwise an O(n) counting sort; the sorted uniforms go straight into the output arrays
        # (allocated by numpy, which asks for huge pages) and the inverse CDFs replace them in place.
        radius = params.R_sigma > 0.0
        R_const = radius_constants(params) if radius else (params.R_m, 0.0, 0.0, 1.0, params.R_m, params.R_m)
        shape = params.alpha + 1.0
        constants = (p_band, *quantile_table(shape), radius, *R_const, params.b, params.c, params.d)
        if sampler == "sobol" and n & (n - 1) == 0:
            r, R, u, cos_phi, sin_phi = (np.empty(n) for _ in range(5))
            sample_net(*net_directions(n.bit_length() - 1, seed), r, R, u, cos_phi, sin_phi, *constants)
        else:
            U = unit_points(n, seed, sampler)
            order = argsort_unit(U[:, 0])  # before the outputs exist: the sort's work arrays are freed
            r, R, u, cos_phi, sin_phi = (np.empty(n) for _ in range(5))
            gather(U, order, r, R, u, cos_phi)
            del U, order
            inverse_cdfs(r, R, u, cos_phi, sin_phi, *constants)
        tail = np.signbit(r)  # where no table is accurate: scipy's inverse
        r[tail] = special.gammaincinv(shape, -r[tail])
        r *= params.beta
        clip_running_max(r, r_band)
        return cls(
            params=params,
            r=r,
            R=R,
            u=u,
            cos_phi=cos_phi,
            sin_phi=sin_phi,
            weight=p_band / n,
            seed=seed,
            sampler=sampler,
            r_band=r_band,
        )

    @classmethod
    def from_arrays(cls, params: InterfaceParams, r, R, u, phi) -> "Population":
        """A population of given asperities (heights r [m], radii R [m], u [rad], phi [rad]), equally weighted."""
        if not isinstance(params, InterfaceParams):
            raise ValueError(f"params = {params!r} is not an InterfaceParams")
        arrays = [np.atleast_1d(np.asarray(a, dtype=float)) for a in (r, R, u, phi)]
        n = arrays[0].size
        if n == 0:
            raise ValueError("r is empty: a population needs at least one asperity (valid range: n >= 1)")
        names = ("r", "R", "u", "phi")
        for name, a in zip(names, arrays):
            if a.shape != (n,) or not np.all(np.isfinite(a)):
                raise ValueError(f"{name} must be a finite 1-D array of length {n}, got {a!r}")
        r, R, u, phi = arrays
        if np.any(r < 0) or np.any(R <= 0) or np.any((u < 0) | (u > 0.5 * math.pi)):
            raise ValueError("need r >= 0 [m], R > 0 [m] and u in [0, pi/2] [rad]")
        order = np.argsort(r, kind="stable")
        return cls(params=params, r=r[order].copy(), R=R[order].copy(), u=u[order].copy(),
                   cos_phi=np.cos(phi[order]), sin_phi=np.sin(phi[order]), weight=1.0 / n,
                   seed=None, sampler="given")

    @property
    def n(self) -> int:
        return self.r.size

    @property
    def phi(self) -> np.ndarray:
        """Azimuth phi [rad] in [0, 2 pi)."""
        phi = np.mod(np.arctan2(self.sin_phi, self.cos_phi), 2.0 * math.pi)
        return np.where(phi >= 2.0 * math.pi, 0.0, phi)  # a tiny negative angle rounds up to 2 pi

    @property
    def arrays(self) -> tuple:
        """(r, R, u, cos_phi, sin_phi): the per-asperity arrays, in the order every kernel takes them."""
        return self.r, self.R, self.u, self.cos_phi, self.sin_phi

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.arrays)

    @cached_property
    def R_min(self) -> float:
        """Smallest relative radius in the population [m] (largest orientation extent)."""
        return float(self.R.min())

    def n_reachable(self, delta, theta_max: float = 0.0) -> int:
        """Number of asperities, lowest first, that can touch at displacement delta (:func:`reach`).

        ``theta_max`` [rad] raises the angle bound for frozen (``birth``) angles.
        """
        p = self.params
        return int(reach(self.r, self.R_min, p.r_o, p.k_e, p.beta, float(delta[0]), float(delta[1]),
                         float(delta[2]), float(theta_max))[0])

    @cached_property
    def kernel_constants(self) -> tuple:
        """(r_o, k_e, E_star, lam, mu, beta, N w): the scalars every evaluation passes to the kernels."""
        p = self.params
        return p.r_o, p.k_e, p.E_star, p.lam, p.mu, p.beta, p.N * self.weight
