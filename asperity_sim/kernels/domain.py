"""The per-step test of a path-independent law's domain, compiled (the rules: :mod:`asperity_sim.solve.domain`).

Owns :func:`domain_step`, called by :class:`asperity_sim.solve.domain.DomainMonitor` for each
recorded step and by the compiled increments of a stage (:mod:`asperity_sim.kernels.stage_loop`).
Its state is arrays: ``track`` (steps, 5): each recorded Delta [m], the external work to it and
the work of its absolute increments [J/m²]; ``last`` (5,): the last stress (3) [Pa], the normal
stress when shear began (NaN: not sheared) [Pa] and the work of the closed loop last flagged;
``counts`` (4,): steps recorded, first step flagged (-1: none), its flags, every flag seen.
The work and the cosine are sums in index order: numpy's ``@`` (its BLAS) may fuse the products and
so differ in the last bit, which can change a flag only where the test sits on its threshold to
that bit (the flags of every scenario are the same, studies/same_numbers.py); ``np.dot`` would
match it, at the cost of seconds of compile in a first run.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import kernel

SHEAR_TURN, NORMAL_CHANGE, LOOP_WORK = 1, 2, 4
T_WORK, T_ABS, N_TRACK = 3, 4, 5
L_SIGMA_REF, L_LOOP_WORK, N_LAST = 3, 4, 5
C_STEPS, C_FIRST, C_FIRST_FLAGS, C_ANY, N_COUNTS = 0, 1, 2, 3, 4


@kernel(inline="always")
def _py_max(a, b):
    """Python's max(a, b)."""
    return b if b > a else a


@kernel()
def domain_step(track, last, counts, step, delta, stress, cos_tol, normal_rtol, loop_rtol):
    """Flags of recorded ``step`` at ``delta`` [m] and ``stress`` [Pa], the state updated (call in step order).

    SHEAR_TURN: the shear increment turns from the accumulated shear by more than the angle whose
    cosine is ``cos_tol``; NORMAL_CHANGE: sigma_1 moved by more than ``normal_rtol`` since shear
    began; LOOP_WORK: back at an earlier Delta with the work of the loop below -``loop_rtol`` of
    the work along it (looked for once any flag was raised).
    """
    n = counts[C_STEPS]
    if n == 0:
        for j in range(3):
            track[0, j] = delta[j]
            last[j] = stress[j]
        track[0, T_WORK] = track[0, T_ABS] = 0.0
        counts[C_STEPS] = 1
        return 0
    flags = 0
    prev = track[n - 1]
    dW = 0.0
    for j in range(3):
        dW += (0.5 * (last[j] + stress[j])) * (delta[j] - prev[j])
    track[n, T_WORK] = track[n - 1, T_WORK] + dW
    track[n, T_ABS] = track[n - 1, T_ABS] + abs(dW)
    ds1, ds2 = delta[1] - prev[1], delta[2] - prev[2]
    n_prev, n_ds = np.hypot(prev[1], prev[2]), np.hypot(ds1, ds2)
    if n_prev * n_ds > 0.0:
        cos = (prev[1] * ds1 + prev[2] * ds2) / (n_prev * n_ds)  # both norms > 0 (may underflow to 0 in the product)
        if not cos >= cos_tol:
            flags |= SHEAR_TURN
    sheared = np.hypot(delta[1], delta[2]) > 0.0
    if sheared and math.isnan(last[L_SIGMA_REF]):
        last[L_SIGMA_REF] = last[0]
    if not sheared:
        last[L_SIGMA_REF] = math.nan
    elif abs(stress[0] - last[L_SIGMA_REF]) > normal_rtol * _py_max(abs(last[L_SIGMA_REF]), abs(stress[0])):
        flags |= NORMAL_CHANGE
    for j in range(3):
        track[n, j] = delta[j]
        last[j] = stress[j]
    counts[C_STEPS] = n + 1
    if counts[C_ANY] or flags:
        flags |= _loop(track, last, n, delta, loop_rtol)
    if flags and counts[C_FIRST] < 0:
        counts[C_FIRST], counts[C_FIRST_FLAGS] = step, flags
    counts[C_ANY] |= flags
    return flags


@kernel(inline="always")
def _loop(track, last, n, delta, loop_rtol):
    """LOOP_WORK when ``delta`` (step n) is back at a step before n - 1 and the work since it is negative."""
    if n < 2:
        return 0
    scale = 0.0
    for i in range(n + 1):
        for j in range(3):
            scale = _py_max(scale, abs(track[i, j]))
    scale = _py_max(scale, 1e-300)
    for i in range(n - 2, -1, -1):
        far = 0.0
        for j in range(3):
            far = _py_max(far, abs(track[i, j] - delta[j]))
        if far <= 1e-9 * scale:
            w = track[n, T_WORK] - track[i, T_WORK]
            along = track[n, T_ABS] - track[i, T_ABS]
            if along > 0.0 and w < -loop_rtol * along:
                last[L_LOOP_WORK] = w
                return LOOP_WORK
    return 0
