"""Hertz normal contact, shared by every law (SPEC §5, Eq. 16).

f_n = (4/3) E* sqrt(R) delta_n^(3/2), its stiffness d f_n / d delta_n = 2 E* sqrt(R delta_n)
and its elastic energy (8/15) E* sqrt(R) delta_n^(5/2).
"""

from __future__ import annotations

from ..jit import kernel
from ..vectormath import fsqrt


@kernel(inline="always", error_model="numpy")
def hertz(dn, R, E_star):
    """(f_n [N], k_n [N/m]) of an overlap dn > 0 [m] on relative radius R [m]."""
    return hertz_roots(dn, fsqrt(R), fsqrt(dn), E_star)


@kernel(inline="always", error_model="numpy")
def hertz_roots(dn, sqrt_R, sqrt_dn, E_star):
    """:func:`hertz` given sqrt(R) and sqrt(dn) (for a caller that needs the roots too)."""
    C = (4.0 / 3.0) * E_star * sqrt_R
    return C * dn * sqrt_dn, 1.5 * C * sqrt_dn


@kernel(inline="always", error_model="numpy")
def hertz_energy(dn, R, E_star):
    """Elastic energy of the normal contact [J]; 0 out of contact."""
    if dn <= 0.0:
        return 0.0
    return hertz_energy_roots(dn, fsqrt(R), fsqrt(dn), E_star)


@kernel(inline="always", error_model="numpy")
def hertz_energy_roots(dn, sqrt_R, sqrt_dn, E_star):
    """:func:`hertz_energy` of an overlap dn > 0 given sqrt(R) and sqrt(dn)."""
    return (8.0 / 15.0) * E_star * sqrt_R * dn * dn * sqrt_dn
