"""Closed forms for e = 0 and no shear: the Greenwood–Williamson limit (independent checks).

Owns the one-dimensional forms the tests set against the quadrature and the Monte Carlo:
the mean of sqrt(R) over the radius density and the normal stress of normal asperities
(Greenwood–Williamson) as a one-dimensional height integral.
"""

from __future__ import annotations

import math

from scipy import special

from ..params import InterfaceParams


def mean_sqrt_R(params: InterfaceParams) -> float:
    """E[sqrt(R)] [m^0.5] over the truncated Gaussian of SPEC §2 (scipy quad)."""
    if params.R_sigma == 0.0:
        return math.sqrt(params.R_m)
    lo, hi = params.R_bounds
    s = params.R_sigma
    Z = special.ndtr((hi - params.R_m) / s) - special.ndtr((lo - params.R_m) / s)
    norm = math.sqrt(2.0 * math.pi) * s * Z

    def integrand(R):
        return math.sqrt(R) * math.exp(-0.5 * ((R - params.R_m) / s) ** 2) / norm

    from scipy import integrate  # here, not at module level: ~0.2 s of every start-up

    return integrate.quad(integrand, lo, hi, epsabs=0.0, epsrel=1e-13, limit=200)[0]


def sigma_gw(params: InterfaceParams, delta_1: float, shear: float = 0.0):
    """(sigma_1, sigma_shear) [Pa] for e = 0 (flat on rough), by scipy quad; independent check.

    With e = 0, k_e = 0 and every contact has theta = 0 (Eq. 9), so Eq. (23) reduces to
    1-D integrals over the gamma heights (SPEC §2, §5):
    sigma_1 = N (4/3) E* E[sqrt R] int_0^Delta_1 (Delta_1 - r)^(3/2) H(r) dr, and the shear
    stress along a shear displacement of magnitude ``shear`` [m] is
    N mu (4/3) E* E[sqrt R] int_0^Delta_1 (Delta_1 - r)^(3/2) g(x) H(r) dr,
    x = shear / (lam mu (Delta_1 - r)), g = 1 - (1-x)^(3/2) for x < 1, else 1.
    ``params.e`` is ignored: the result is the model's stress for ``params.replace(e=0)``
    (for any e it is the theta = 0 approximation; it ignores the orientation density too).

    Parameters
    ----------
    delta_1 : float [m]   normal displacement Delta_1
    shear : float [m]     magnitude of (Delta_2, Delta_3)
    """
    delta_1 = float(delta_1)
    shear = abs(float(shear))
    if not (math.isfinite(delta_1) and math.isfinite(shear)):
        raise ValueError(f"delta_1 = {delta_1!r}, shear = {shear!r} must be finite [m]")
    p = params
    if delta_1 <= 0.0:
        return 0.0, 0.0
    a = p.alpha
    # H(r) dr with r = delta_1 s: s^alpha (quad's 'alg' weight) times the rest
    scale = math.exp((a + 1.0) * math.log(delta_1) - special.gammaln(a + 1.0)
                     - (a + 1.0) * math.log(p.beta))
    C = p.N * (4.0 / 3.0) * p.E_star * mean_sqrt_R(p) * scale
    opts = dict(epsabs=0.0, epsrel=1e-13, limit=200)
    from scipy import integrate  # here, not at module level: ~0.2 s of every start-up

    def f_n(s):
        return (delta_1 * (1.0 - s)) ** 1.5 * math.exp(-delta_1 * s / p.beta)

    s1, _ = integrate.quad(f_n, 0.0, 1.0, weight="alg", wvar=(a, 0.0), **opts)
    if shear == 0.0 or p.mu == 0.0:
        return C * s1, 0.0
    m = p.lam * p.mu

    def f_t(s):
        dn = delta_1 * (1.0 - s)
        x = shear / (m * dn) if dn > 0.0 else math.inf
        g = 1.0 - (1.0 - x) ** 1.5 if x < 1.0 else 1.0
        return p.mu * dn ** 1.5 * g * math.exp(-delta_1 * s / p.beta)

    s_slip = 1.0 - shear / (m * delta_1)  # x = 1 here; stick for s < s_slip
    if 0.0 < s_slip < 1.0:
        s2a, _ = integrate.quad(f_t, 0.0, s_slip, weight="alg", wvar=(a, 0.0), **opts)
        s2b, _ = integrate.quad(lambda s: f_t(s) * s ** a, s_slip, 1.0, **opts)
        s2 = s2a + s2b
    else:
        s2, _ = integrate.quad(f_t, 0.0, 1.0, weight="alg", wvar=(a, 0.0), **opts)
    return C * s1, C * s2


def sigma_1_gw(params: InterfaceParams, delta_1: float) -> float:
    """sigma_1 [Pa] for e = 0, Eq. (23) reduced to 1-D (see :func:`sigma_gw`)."""
    return sigma_gw(params, delta_1)[0]
