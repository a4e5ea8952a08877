"""What two measured surfaces tell beyond heights: the curvature ratio e at the contacts and the contact slopes.

Owns :func:`pair_statistics`.  With two surfaces h1 and h2 (each measured outward from its own body,
summed into the composite), every composite summit is a contact point of the two bodies, and at it

- the mean curvatures of the two surfaces, kappa_1 = -(h1_xx + h1_yy)/2 and kappa_2 = kappa - kappa_1
  (5-point stencil, the composite's kappa from the summit finder), give the curvature ratio of the
  model (SPEC §1, §3): e = R1/R2 = min(kappa_1, kappa_2)/max(kappa_1, kappa_2) in [0, 1] when both
  surfaces are convex there; where one is flat or concave the contact is a rough surface against
  a flat or a socket, and e = 0 (k_e = 0: Eq. 9 then gives no tilt);
- the slope |grad h1| (= |grad h2|, since grad(h1 + h2) = 0 at a summit) is the tilt theta of the
  tangent plane the bodies share: the contact orientation, theta = arctan |grad h1|.

The model takes one e for the interface, and e enters Eq. (9) only through k_e = e/(1 + e)², so the
fitted e is the one whose k_e is the mean of k_e over the summits in contact at the closure
(e = (1 - 2k - sqrt(1 - 4k))/(2k), the root in [0, 1]).  The measured slopes of the same summits are
set against the model's orientation density at that closure: theta = (2/pi) u theta_m(c, R)
(SPEC §3, Eqs. 9-10) over the model's contacts (heights r < Delta_1).  Standard errors: bootstrap
over the summits in contact (data), Monte Carlo (model).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from ...geometry import theta_m_array
from ...params import InterfaceParams
from ...sampling.population import Population
from .summits import Summits
from .topography import Surface


def e_from_k(k):
    """The curvature ratio e in [0, 1] with e/(1 + e)² = k, k in [0, 1/4]."""
    k = np.clip(np.asarray(k, dtype=float), 0.0, 0.25)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = (1.0 - 2.0 * k - np.sqrt(np.maximum(1.0 - 4.0 * k, 0.0))) / (2.0 * k)
    return np.where(k > 0, e, 0.0)


def curvature_ratio(first: Surface, summits: Summits):
    """(kappa_1, kappa_2, e) per summit: mean curvatures [1/m] of the first surface and of the second
    (composite minus first) at the summit, and their ratio (module docstring; 0 where one is <= 0)."""
    h = first.heights
    nx, ny = h.shape
    dx, dy = first.pixel_size
    ii, jj = summits.pixel_indices(first.pixel_size)
    z = h[ii, jj]
    hxx = (h[(ii + 1) % nx, jj] - 2 * z + h[(ii - 1) % nx, jj]) / dx**2
    hyy = (h[ii, (jj + 1) % ny] - 2 * z + h[ii, (jj - 1) % ny]) / dy**2
    k1 = -0.5 * (hxx + hyy)
    k2 = summits.curvature - k1
    lo, hi = np.minimum(k1, k2), np.maximum(k1, k2)
    return k1, k2, np.where(lo > 0, lo / np.where(hi > 0, hi, 1.0), 0.0)


def model_angles(params: InterfaceParams, closure: float, n: int = 200_000, seed: int = 0):
    """Contact angles theta [rad] of the model's asperities in contact at Delta_1 = closure (Eqs. 9-10)."""
    pop = Population.sample(params, n, seed=seed)
    k = int(np.searchsorted(pop.r, closure))
    c = max(0.0, params.r_o + closure)
    return (2.0 / math.pi) * pop.u[:k] * theta_m_array(params, c, pop.R[:k])


def pair_statistics(first: Surface, summits: Summits, params: InterfaceParams, closure: float,
                    bootstrap: int = 200, seed: int = 0, n_model: int = 200_000) -> dict:
    """e and the contact slopes of the summits in contact at ``closure`` [m] (depth below the highest summit),
    and the model's contact angles there with the fitted e (the rest of ``params`` as given).

    first : the first surface of the pair, detrended as in the composite (its heights h1)
    Returns a dict: n_contacts; e, e_stderr, k_e, k_e_stderr, concave (fraction of those summits with one
    surface flat or concave); theta_mean, theta_mean_stderr, theta_median, theta_p90 [rad] of the data and
    model_theta_mean, model_theta_mean_stderr, model_theta_median, model_theta_p90 [rad] of the model;
    ks (Kolmogorov–Smirnov distance of the two angle distributions); and e_all, k_e_all over every summit.
    """
    k1, k2, e = curvature_ratio(first, summits)
    ke = e / (1.0 + e) ** 2
    touching = np.flatnonzero(summits.depth <= closure)
    if touching.size < 2:
        touching = np.arange(min(2, summits.n))
    rng = np.random.default_rng(seed)
    boot = rng.integers(0, touching.size, size=(int(bootstrap), touching.size))
    ke_t = ke[touching]
    theta = np.arctan(summits.slope[touching])
    k_mean, k_se = float(ke_t.mean()), float(ke_t[boot].mean(axis=1).std(ddof=1))
    e_fit = float(e_from_k(k_mean))
    # e is a smooth function of k: its standard error by the bootstrap of k, mapped
    e_boot = e_from_k(ke_t[boot].mean(axis=1))
    model = model_angles(params.replace(e=e_fit), closure, n_model, seed)
    out = {"closure": float(closure), "n_contacts": int(touching.size), "e": e_fit, "e_stderr": float(e_boot.std(ddof=1)),
           "k_e": k_mean, "k_e_stderr": k_se, "concave": float(np.mean((k1[touching] <= 0) | (k2[touching] <= 0))),
           "e_all": float(e_from_k(ke.mean())), "k_e_all": float(ke.mean()),
           "theta_mean": float(theta.mean()), "theta_mean_stderr": float(theta[boot].mean(axis=1).std(ddof=1)),
           "theta_median": float(np.median(theta)), "theta_p90": float(np.quantile(theta, 0.9))}
    if model.size > 1:
        out.update(model_theta_mean=float(model.mean()),
                   model_theta_mean_stderr=float(model.std(ddof=1) / math.sqrt(model.size)),
                   model_theta_median=float(np.median(model)), model_theta_p90=float(np.quantile(model, 0.9)),
                   ks=float(stats.ks_2samp(theta, model).statistic), model_contacts=int(model.size))
    else:
        out.update(model_theta_mean=math.nan, model_theta_mean_stderr=math.nan, model_theta_median=math.nan,
                   model_theta_p90=math.nan, ks=math.nan, model_contacts=int(model.size))
    return out


def scene_comments(pair: dict) -> list:
    """Comment lines of a scene file that report :func:`pair_statistics`."""
    d = pair
    deg = 180.0 / math.pi
    return [
        f"# Two surfaces: at the {d['n_contacts']} summits in contact at the closure {d['closure'] * 1e6:.3g} um, "
        f"curvature ratio e = {d['e']:.3g} ± {d['e_stderr']:.2g} (the e of the mean k_e = e/(1+e)^2 = "
        f"{d['k_e']:.3g} ± {d['k_e_stderr']:.2g}, bootstrap; {100 * d['concave']:.0f} % with one surface flat or "
        f"concave there, e = 0; over all summits e = {d['e_all']:.3g})",
        f"# Contact slopes theta = arctan|grad h1| at those summits: mean {d['theta_mean'] * deg:.3g} ± "
        f"{d['theta_mean_stderr'] * deg:.2g} deg, median {d['theta_median'] * deg:.3g} deg, 90 % "
        f"{d['theta_p90'] * deg:.3g} deg; the model at that closure (Eqs. 9-10, this e and b, c, d): mean "
        f"{d['model_theta_mean'] * deg:.3g} ± {d['model_theta_mean_stderr'] * deg:.2g} deg, median "
        f"{d['model_theta_median'] * deg:.3g} deg, 90 % {d['model_theta_p90'] * deg:.3g} deg "
        f"(Kolmogorov–Smirnov distance {d['ks']:.2f})",
    ]
