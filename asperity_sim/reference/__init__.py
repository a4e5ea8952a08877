"""The deterministic reference of the Monte Carlo results, for the ``paper`` law under policy follow.

The interface stress of Eq. (23) as a nested quadrature (:mod:`~asperity_sim.reference.quadrature`,
its integrand in :mod:`~asperity_sim.reference.integrand`), the rules over the model's densities and
theta_am of Eq. (29) (:mod:`~asperity_sim.reference.rules`), and closed forms for e = 0
(:mod:`~asperity_sim.reference.closed_forms`).  The tests and studies compare Monte Carlo with it.
"""

from .closed_forms import mean_sqrt_R, sigma_1_gw, sigma_gw
from .quadrature import LEVELS, stress, stress_and_tangent, tangent
from .rules import orientation_density, orientation_rule, radius_rule, theta_am

__all__ = ["LEVELS", "stress", "tangent", "stress_and_tangent", "theta_am", "orientation_density", "radius_rule",
           "orientation_rule", "mean_sqrt_R", "sigma_gw", "sigma_1_gw"]
