"""The model's answer to a mean shear traction at a mean pressure, for the comparison with the exact solution.

Owns :func:`model_shear`: the ``mdr`` law run by :func:`~asperity_sim.solve.driver.simulate` on a
population with e = 0 (every contact normal to the nominal plane, the small-slope assumption of the
boundary-element solution, :mod:`.tangential`), sigma_1 then sigma_2 stress controlled
(:mod:`asperity_sim.paths`), and what the comparison needs that a run does not record: the stick
area and the interface's initial (Mindlin) tangential stiffness, with their standard errors.

Relations (SPEC §5 with e = 0: delta_n = Delta_1 - r, delta_s = Delta_2).  Under monotonic shear at
constant normal force the ``mdr`` law is Cattaneo–Mindlin (it reduces to the ``paper`` law), whose
stick zone has radius c = a (1 - Q/(mu P))^(1/3) = a sqrt(1 - delta_s/delta_slip), so the stick area
of a contact is pi R (delta_n - Delta_2 / (lam mu))^+ (delta_slip = lam mu delta_n); the initial
tangential stiffness of a contact is 4 G sqrt(R delta_n)/(2 - nu).  Standard errors: first-order
delta method over the n equally weighted asperities, at the prescribed stresses (sigma_1, sigma_2).
"""

from __future__ import annotations

import math

import numpy as np

from ... import paths
from ...sampling.population import Population
from ...solve.driver import simulate


def shear_path(pressure: float, tractions, increments: int = 4) -> paths.LoadPath:
    """sigma_1 to ``pressure`` [Pa] (Delta_2 = Delta_3 = 0), then sigma_2 to each traction [Pa] in turn (Delta_3 = 0)."""
    S, D = paths.STRESS, paths.DISPLACEMENT
    stages = [paths.Stage((S, D, D), (pressure, 0.0, 0.0), 2 * increments, name="normal loading")]
    stages += [paths.Stage((S, S, D), (pressure, float(q), 0.0), increments, name=f"shear to {float(q):.4g} Pa")
               for q in tractions]
    return paths.LoadPath(tuple(stages), name="shear_at_constant_pressure")


def _per_asperity(pop: Population, d1, d2):
    """Normal and tangential forces [N], stick area [m²] and initial tangential stiffness [N/m] of each asperity
    (paper law at e = 0, equal to mdr under monotonic shear)."""
    p = pop.params
    dn = np.maximum(d1 - pop.r, 0.0)
    fn = (4.0 / 3.0) * p.E_star * np.sqrt(pop.R) * dn**1.5
    slip = p.lam * p.mu * dn
    x = np.where(slip > 0, np.minimum(d2 / np.where(slip > 0, slip, 1.0), 1.0), 1.0)
    fs = p.mu * fn * (1.0 - (1.0 - x) ** 1.5)
    stick = math.pi * pop.R * np.maximum(dn - d2 / (p.lam * p.mu), 0.0)
    k0 = 4.0 * p.G * np.sqrt(pop.R * dn) / (2.0 - p.nu)
    return fn, fs, stick, k0


def _fixed_stress_se(pop, d1, d2, value):
    """Standard error of N mean(value_j(d1, d2)) at the stresses, not the displacements, of (d1, d2)."""
    n, N = pop.r.size, pop.params.N

    def means(a, b):
        fn, fs, st, k0 = _per_asperity(pop, a, b)
        return N * np.array([fn.mean(), fs.mean(), value(fn, fs, st, k0).mean()])

    h1, h2 = 1e-6 * max(d1, 1e-12), 1e-6 * max(d2, d1 * 1e-3)
    J = np.column_stack([(means(d1 + h1, d2) - means(d1 - h1, d2)) / (2 * h1),
                         (means(d1, d2 + h2) - means(d1, max(d2 - h2, 0.0))) / (h2 + min(h2, d2))])
    # value's sensitivity to the stresses through the displacements: g = J[2] T^-1, T = J[:2]
    g = np.linalg.solve(J[:2].T, J[2])
    fn, fs, st, k0 = _per_asperity(pop, d1, d2)
    lin = value(fn, fs, st, k0) - g[0] * fn - g[1] * fs
    return N * lin.std(ddof=1) / math.sqrt(n)


def model_shear(pop: Population, pressure: float, tractions, increments: int = 4, k: int = 16) -> dict:
    """The ``mdr`` law at a mean pressure [Pa] and mean shear tractions [Pa] (module docstring).

    pop : a Population whose params have e = 0 (checked)
    Returns a dict of arrays over the tractions: ``delta`` and ``delta_se`` [m] (Delta_2 ± its Monte Carlo
    standard error, from the run), ``closure`` [m] (Delta_1), ``stick`` and ``stick_se`` [1] (stick-area
    fraction), ``traction`` [Pa] (sigma_2 reached); and ``stiffness``, ``stiffness_se`` [Pa/m] (the initial
    tangential stiffness N E[4 G sqrt(R delta_n)/(2 - nu)] at the pressure), ``contact`` [1] (contact-area
    fraction at the pressure), ``seconds``.
    """
    import time

    if pop.params.e != 0.0:
        raise ValueError(f"pop.params.e = {pop.params.e!r}: the comparison needs contacts normal to the plane "
                         "(valid: e = 0)")
    t0 = time.perf_counter()
    tractions = np.atleast_1d(np.asarray(tractions, dtype=float))
    ds = simulate(pop.params, shear_path(pressure, tractions, increments), population=pop, law="mdr", k=k)
    stage = ds["stage"].values
    # stage 0 is the initial state, stage 1 the normal loading, stage 1 + k the k-th traction
    last = np.array([np.flatnonzero(stage == s)[-1] for s in range(2, len(tractions) + 2)])
    disp, se, stress = ds["displacement"].values, ds["displacement_stderr"].values, ds["stress"].values
    d0 = float(disp[np.flatnonzero(stage == 1)[-1], 0])
    N = pop.params.N
    out = {"delta": disp[last, 1], "delta_se": se[last, 1], "closure": disp[last, 0], "traction": stress[last, 1]}
    frac = lambda fn, fs, st, k0: st  # noqa: E731
    out["stick"] = np.array([N * _per_asperity(pop, disp[i, 0], disp[i, 1])[2].mean() for i in last])
    out["stick_se"] = np.array([_fixed_stress_se(pop, disp[i, 0], disp[i, 1], frac) for i in last])
    fn, _, area0, k0 = _per_asperity(pop, d0, 0.0)
    out["contact"] = N * area0.mean()
    out["stiffness"] = N * k0.mean()
    # at Delta_2 = 0 the stiffness depends on sigma_1 alone: delta method in one dimension
    h = 1e-6 * d0
    dk = N * (_per_asperity(pop, d0 + h, 0.0)[3].mean() - _per_asperity(pop, d0 - h, 0.0)[3].mean()) / (2 * h)
    dsig = N * (_per_asperity(pop, d0 + h, 0.0)[0].mean() - _per_asperity(pop, d0 - h, 0.0)[0].mean()) / (2 * h)
    out["stiffness_se"] = N * (k0 - dk / dsig * fn).std(ddof=1) / math.sqrt(pop.r.size)
    out["seconds"] = time.perf_counter() - t0
    return out
