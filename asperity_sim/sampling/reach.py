"""Which asperities can touch at a displacement: the height bound the kernels stop at.

Owns :func:`reach` (SPEC §3–§4): with the population sorted by height, the first
``n_active`` asperities are the only ones that can be in contact at Delta.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import closure_and_slope
from ..jit import kernel


@kernel()
def reach(r, R_min, r_o, k_e, beta, d1, d2, d3, theta_max):
    """(n_active, theta bound): asperities, lowest first, that can touch at Delta (SPEC §3–§4).

    Under policy follow theta = (2/pi) u theta_m(c, R) <= theta_m(c, R_min); ``theta_max``
    [rad] raises the bound for frozen (``birth``) angles.  delta_n = cos(theta)(Delta_1 - r)
    + sin(theta) s with s <= |Delta_shear|, so contact needs r < Delta_1 + |Delta_shear| tan(theta).
    ``r`` is sorted.
    """
    shear = math.hypot(d2, d3)
    closure, _ = closure_and_slope(r_o, d1)
    y = 1.0 - k_e * closure / R_min
    theta = max(math.acos(min(max(y, 0.0), 1.0)), theta_max)
    if shear == 0.0:
        r_max = d1
    elif theta >= 0.5 * math.pi - 1e-9:
        return r.size, theta
    else:
        r_max = d1 + shear * math.tan(theta)
    r_max += 1e-12 * max(abs(r_max), beta)  # round-off margin at the contact edge
    return np.searchsorted(r, r_max, side="right"), theta
