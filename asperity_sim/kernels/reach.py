"""Which asperities a kernel may skip before any trigonometry.

Owns the cheap tests that an asperity cannot touch: at one displacement (:func:`cannot_touch`,
:func:`may_touch_follow`), anywhere in a box of displacements (:func:`may_touch_within`), and
the height and angle bounds of a reduction (:func:`bounds`).  Each errs on the side of
visiting: a skipped asperity is one the exact test also finds out of contact.
"""

from __future__ import annotations

import math

from ..jit import kernel
from ..sampling.reach import reach


@kernel(inline="always")
def cannot_touch(x, shear_ph, tan_max):
    """True when delta_n = cos(theta) x + sin(theta) shear_ph <= 0 for every theta in [0, theta_max].

    ``x`` = Delta_1 - r, ``shear_ph`` = cos(phi) Delta_2 + sin(phi) Delta_3 and ``tan_max`` =
    tan(theta_max) (inf for theta_max = pi/2).  Above the closure (x <= 0) contact needs
    shear_ph > 0 and tan(theta) > -x / shear_ph; the relative margin 1e-9 keeps the test on the
    safe side of round-off, so a skipped asperity is one the exact test also finds out of contact.
    """
    if x > 0.0:
        return False
    if shear_ph <= 0.0:
        return True
    return -x > shear_ph * tan_max * (1.0 + 1e-9)


@kernel(inline="always", error_model="numpy")
def may_touch_within(x_hi, s_hi, y_lo, y_hi, scale, tan_max):
    """False when the asperity cannot touch anywhere in a box of displacements, tested without trigonometry.

    delta_n = cos(theta) x + sin(theta) s grows with x = Delta_1 - r and with s = cos(phi) Delta_2
    + sin(phi) Delta_3 (theta in [0, pi/2]), and theta = scale theta_m grows with the closure, so
    over the box delta_n <= cos(theta) x_hi + sin(theta) s_hi with theta between its values at
    the box's smallest and largest closure, where y = cos(theta_m) = 1 - k_e c / R_j (Eq. 9,
    before clipping) is ``y_lo`` and ``y_hi``.  ``tan_max`` bounds tan theta of every asperity
    at the largest closure (:func:`cannot_touch`).

    - x_hi <= 0: contact needs s_hi > 0 and tan(theta) > -x_hi / s_hi.  tan is convex on
      [0, pi/2) with tan 0 = 0, hence tan(theta) <= scale tan(theta_m): contact is impossible
      when scale² (1 - y²) s_hi² < x_hi² y² at y = y_hi (0 < y < 1; y >= 1 means theta_m = 0
      and y <= 0 gives no bound).
    - x_hi > 0: a shear away from the asperity (s_hi < 0) lifts it off when tan(theta) >= x_hi /
      -s_hi at the least angle.  acos y = 2 asin sqrt((1 - y)/2) >= sqrt(2 (1 - y)) and tan t >= t,
      so tan(theta) >= scale sqrt(2 (1 - y)) at y = y_lo clipped to [0, 1]: contact is
      impossible when 2 scale² (1 - y_lo) s_hi² > x_hi².

    The relative margins 1e-9 keep the tests on the safe side of round-off.
    """
    sh2 = s_hi * s_hi
    by_angle = ~(-x_hi > s_hi * tan_max * (1.0 + 1e-9))
    by_own = (y_hi <= 0.0) | ((y_hi < 1.0) & ~(scale * scale * (1.0 - y_hi * y_hi) * sh2 * (1.0 + 1e-9)
                                              < x_hi * x_hi * y_hi * y_hi))
    yc = 0.0 if y_lo < 0.0 else (1.0 if y_lo > 1.0 else y_lo)
    lifted = (s_hi < 0.0) & (2.0 * scale * scale * (1.0 - yc) * sh2 > x_hi * x_hi * (1.0 + 1e-9))
    return ((x_hi > 0.0) & ~lifted) | ((s_hi > 0.0) & by_angle & by_own)


@kernel(inline="always", error_model="numpy")
def may_touch_follow(x, shear_ph, y, scale, tan_max):
    """False when the asperity cannot touch at one displacement under policy follow (no trigonometry, no branch).

    :func:`may_touch_within` for a box that is a point: ``x`` = Delta_1 - r, ``shear_ph`` =
    cos(phi) Delta_2 + sin(phi) Delta_3, ``y`` = cos(theta_m(c, R_j)) = 1 - k_e c / R_j,
    ``scale`` = 2 u_j / pi, so theta = scale theta_m in [0, pi/2].
    """
    return may_touch_within(x, shear_ph, y, y, scale, tan_max)


@kernel()
def bounds(r, R_min, r_o, k_e, beta, delta, theta_birth):
    """(n_active, tan_max): :func:`~asperity_sim.sampling.reach.reach` at delta and tan of its angle bound.

    ``theta_birth`` (empty under policy follow) raises the bound by its largest frozen angle.
    """
    theta_max = 0.0
    for tb in theta_birth:
        if tb > theta_max:  # NaN (no committed contact) never is
            theta_max = tb
    n_active, theta = reach(r, R_min, r_o, k_e, beta, delta[0], delta[1], delta[2], theta_max)
    return n_active, math.inf if theta >= 0.5 * math.pi - 1e-9 else math.tan(theta)
