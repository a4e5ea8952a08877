"""Interface parameters (SPEC §1): one frozen, validated dataclass.

This module owns the physical parameters of a rough interface and nothing else.
Every field carries its unit and long name in the dataclass field metadata; the
recorder copies them into netCDF attributes from there.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from .checks import check_real


def _f(units: str, long_name: str, **kw):
    return field(metadata={"units": units, "long_name": long_name}, **kw)


class derived(property):
    """A derived quantity of the parameters: a read-only property carrying its unit and long name.

    The derived counterpart of a field's metadata, so the unit of ``E_star`` is written once,
    where ``E_star`` is defined; :meth:`InterfaceParams.derived_units` collects them.
    """

    def __init__(self, fget, units: str = "1", long_name: str = ""):
        super().__init__(fget, doc=fget.__doc__)
        self.units, self.long_name = units, long_name

    @staticmethod
    def of(units: str, long_name: str):
        """Decorator: ``@derived.of("Pa", "contact modulus")`` over the getter."""
        return lambda fget: derived(fget, units, long_name)


# (lo, hi, lo_open, hi_open) per field, from SPEC §1.
_RANGES = {
    "N": (0.0, None, True, False),
    "alpha": (-1.0, None, True, False),
    "beta": (0.0, None, True, False),
    "R_m": (0.0, None, True, False),
    "R_sigma": (0.0, None, False, False),
    "e": (0.0, 1.0, False, False),
    "r_o": (0.0, None, False, False),
    "mu": (0.0, None, False, False),
    "G": (0.0, None, True, False),
    "nu": (-1.0, 0.5, True, False),
    "b": (-1.0, 2.0, False, False),
    "c": (None, None, False, False),  # bounded jointly with b and d below
    "d": (None, None, False, False),
    "summit_offset": (0.0, None, False, False),
    "interaction": (0.0, None, False, False),
}


@dataclass(frozen=True)
class InterfaceParams:
    """Statistical and elastic description of a rough interface (SPEC §1).

    Parameters
    ----------
    N : float [1/m²]      asperity contacts per unit nominal area
    alpha : float [1]     gamma shape minus one of the height density, Eq. (1)
    beta : float [m]      gamma scale of the height density, Eq. (1)
    R_m, R_sigma : float [m]  mean and s.d. of the relative radius, Eq. (5)
    mu : float [1]        asperity friction coefficient
    G : float [Pa]        shear modulus
    nu : float [1]        Poisson's ratio
    e : float [1]         curvature ratio R1/R2 (Eq. 4); default 1
    r_o : float [m]       initial closure, widens the orientation extent only (SPEC §3)
    b, c, d : float [1]   shape of the orientation density, Eq. (10) corrected
    summit_offset : float [m]  height of the summits' mean plane above the surface's mean plane;
                          only the mean gap reads it (default 0: the gap from the summits' mean plane)
    interaction : float [1]  strength of the mean-field elastic interaction between contacts
                          (:mod:`asperity_sim.kernels.interaction`; default 0: none, 1: the mean-field estimate)
    """

    N: float = _f("m-2", "asperity contacts per unit nominal area")
    alpha: float = _f("1", "height distribution shape parameter alpha")
    beta: float = _f("m", "height distribution scale parameter beta")
    R_m: float = _f("m", "mean relative radius of curvature")
    R_sigma: float = _f("m", "standard deviation of relative radius of curvature")
    mu: float = _f("1", "asperity friction coefficient")
    G: float = _f("Pa", "shear modulus")
    nu: float = _f("1", "Poisson's ratio")
    e: float = _f("1", "curvature ratio R1/R2 at a contact", default=1.0)
    r_o: float = _f("m", "initial closure", default=0.0)
    b: float = _f("1", "orientation density coefficient b (P2 term)", default=0.0)
    c: float = _f("1", "orientation density coefficient c (cos 2 phi term)", default=0.0)
    d: float = _f("1", "orientation density coefficient d (sin 2 phi term)", default=0.0)
    summit_offset: float = _f("m", "height of the summits' mean plane above the surface's mean plane", default=0.0)
    interaction: float = _f("1", "strength of the mean-field elastic interaction between contacts (0: none)",
                            default=0.0)

    def __post_init__(self):
        for name, (lo, hi, lo_open, hi_open) in _RANGES.items():
            v = check_real(name, getattr(self, name), lo, hi, lo_open, hi_open)
            object.__setattr__(self, name, v)
        rho = math.hypot(self.c, self.d)
        if self.b / 2.0 + 3.0 * rho > 1.0 + 1e-12:
            raise ValueError(
                f"orientation density goes negative: b/2 + 3 sqrt(c² + d²) = "
                f"{self.b / 2.0 + 3.0 * rho:.6g} with b = {self.b!r}, c = {self.c!r}, d = {self.d!r} "
                "(valid range: b >= -1 and b/2 + 3 sqrt(c² + d²) <= 1, SPEC §3)"
            )

    # -- derived quantities (SPEC §3, §5) ----------------------------------
    @derived.of("1", "curvature factor e/(1+e)^2")
    def k_e(self) -> float:
        """Curvature factor e/(1+e)² of Eq. (9)."""
        return self.e / (1.0 + self.e) ** 2

    @derived.of("Pa", "contact modulus G/(1-nu)")
    def E_star(self) -> float:
        """Contact modulus G/(1-nu) [Pa], SPEC §5."""
        return self.G / (1.0 - self.nu)

    @derived.of("1", "lambda = (2-nu)/(2(1-nu)): full slip at delta_s = lambda mu delta_n")
    def lam(self) -> float:
        """lambda = (2-nu)/(2(1-nu)) of Eq. (17)."""
        return (2.0 - self.nu) / (2.0 * (1.0 - self.nu))

    @derived.of("m", "depth of the surface's mean plane below its highest summit, (alpha+1) beta + summit_offset")
    def mean_plane_depth(self) -> float:
        """Depth [m] of the surface's mean plane below the highest summit: the mean summit depth
        (alpha+1) beta (SPEC §2) plus ``summit_offset``; the mean gap is this less Delta_1."""
        return (self.alpha + 1.0) * self.beta + self.summit_offset

    @property
    def R_bounds(self) -> tuple[float, float]:
        """Support of the truncated radius density [m] (SPEC §2)."""
        return max(self.R_m - 3.0 * self.R_sigma, 0.0), self.R_m + 3.0 * self.R_sigma

    @property
    def isotropic(self) -> bool:
        return self.b == 0.0 and self.c == 0.0 and self.d == 0.0

    def replace(self, **changes) -> "InterfaceParams":
        """A validated copy with some fields changed, e.g. ``params.replace(mu=0.3)``."""
        unknown = set(changes) - set(_RANGES)
        if unknown:
            raise ValueError(f"unknown parameter(s) {sorted(unknown)} (valid: {sorted(_RANGES)})")
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict[str, float]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    @staticmethod
    def units() -> dict[str, str]:
        return {f.name: f.metadata["units"] for f in dataclasses.fields(InterfaceParams)}

    @staticmethod
    def long_names() -> dict[str, str]:
        return {f.name: f.metadata["long_name"] for f in dataclasses.fields(InterfaceParams)}

    @staticmethod
    def derived_units() -> dict[str, tuple[str, str]]:
        """Derived scalar quantities: name -> (unit, long name), from their definitions."""
        return {name: (q.units, q.long_name) for name, q in vars(InterfaceParams).items() if isinstance(q, derived)}
