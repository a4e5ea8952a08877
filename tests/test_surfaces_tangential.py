"""asperity_sim.analysis.surfaces.tangential: the frictional (Cattaneo) boundary-element solution.

Checked against Cattaneo–Mindlin for a sphere (with the exact compliance of the periodic images) and against
tamaas' own tangential solver (PolonskyKeerTan) where its single elastic body equals the two identical bodies
of the model (nu = 0.5: no normal-tangential coupling)."""

import math

import numpy as np
import pytest

from asperity_sim.analysis.surfaces import tangential as T

tamaas = pytest.importorskip("tamaas")

LATTICE = 3.9002649200019  # -(zero-mean periodic sum of 1/r on the unit square lattice) = -4 zeta(1/2) beta(1/2)


def _hertz_pressure(n, L, R, E_star, P):
    from asperity_sim.analysis.surfaces import bem_contact  # noqa: F401  (initialises tamaas the same way)

    x = (np.arange(n) + 0.5) * L / n - L / 2
    h = -(x[:, None] ** 2 + x[None, :] ** 2) / (2 * R)
    model = tamaas.ModelFactory.createModel(tamaas.model_type.basic_2d, [L, L], [n, n])
    model.E, model.nu = E_star, 0.0
    tamaas.PolonskyKeerRey(model, np.ascontiguousarray(h), 1e-12).solve(P)
    return h, np.array(model.traction)


def test_sphere_follows_cattaneo_mindlin_with_periodic_images():
    """A Hertz contact (radius 6.8 pixels, a/L = 0.053) under Q = f mu P, two identical bodies G, nu = 0.3.

    Periodic images add a compliance Q_total (2 - nu) 3.90026 / (2 pi G L) (the zero-mean lattice sum of the
    Cerruti kernel), so the BEM shift is Cattaneo–Mindlin's 3 mu P/(16 G* a) [1 - (1 - f)^(2/3)] minus that;
    the full-stick stiffness is 1/(1/(8 G* a) - that compliance).  Measured at 128²: stiffness 1.2 %, shift
    0.2 % (f >= 0.3), stick area 5 % (stick zones of 3 to 6 pixels); the bounds are about twice that."""
    n, L, R, G, nu, mu = 128, 1.0, 1.0, 1.0, 0.3, 0.5
    E_star, Gs = G / (1 - nu), G / (2 * (2 - nu))
    P = 2e-4 * E_star
    F = P * L * L
    a = (3 * F * R / (4 * E_star)) ** (1 / 3)
    _, p = _hertz_pressure(n, L, R, E_star, P)
    C = T.compliance(p.shape, (L, L), G, nu)
    images = LATTICE * (2 - nu) / (2 * math.pi * G * L)
    stuck = T.solve_tangential(np.where(p > 0, np.inf, 0.0), (L, L), G, nu, 1.0, (1e-6, 0.0), C=C)
    assert stuck.Q[0] * L * L / 1e-6 == pytest.approx(1 / (1 / (8 * Gs * a) - images), rel=0.025)
    q0 = None
    for f in (0.3, 0.6, 0.9):
        sol, _ = T.shear_at(p, (L, L), G, nu, mu, f * mu * P, f * mu * F / (8 * Gs * a), q0=q0, C=C, rtol=2e-3)
        q0 = sol.q
        ff = sol.Q[0] / (mu * P)
        assert ff == pytest.approx(f, abs=2e-3)
        cm = 3 * mu * F / (16 * Gs * a) * (1 - (1 - ff) ** (2 / 3)) - images * sol.Q[0] * L * L
        assert sol.delta[0] == pytest.approx(cm, rel=0.005)
        assert sol.stick * L * L == pytest.approx(math.pi * (a * (1 - ff) ** (1 / 3)) ** 2, rel=0.1)
        assert sol.residual < 1e-6 and abs(sol.Q[1]) < 1e-6 * sol.Q[0]


def test_matches_tamaas_polonsky_keer_tan_without_coupling():
    """tamaas' PolonskyKeerTan solves one elastic body (E', nu') against a rigid one with the full coupled kernel;
    at nu' = 0.5 it is uncoupled and equals two identical bodies with G = 2 G'.  Same pressure, same mean traction:
    the same shift (stick-zone displacement in tamaas) and the same stick zone, to 1e-4."""
    n, L, R, Ep, nu, mu, P = 128, 1.0, 1.0, 1.0, 0.5, 0.5, 2e-4
    x = (np.arange(n) + 0.5) * L / n - L / 2
    h = -(x[:, None] ** 2 + x[None, :] ** 2) / (2 * R)
    tamaas.initialize(1)
    tamaas.set_log_level(tamaas.LogLevel.error)
    model = tamaas.ModelFactory.createModel(tamaas.model_type.surface_2d, [L, L], [n, n])
    model.E, model.nu = Ep, nu
    tamaas.PolonskyKeerTan(model, np.ascontiguousarray(h), 1e-12, mu).solve([0.3 * mu * P, 0.0, P])
    t, u = np.array(model.traction), np.array(model.displacement)
    p = t[..., 2]
    stick = (p > 0) & (np.hypot(t[..., 0], t[..., 1]) < (1 - 1e-6) * mu * p)
    sol, _ = T.shear_at(p, (L, L), 2 * Ep / (2 * (1 + nu)), nu, mu, t[..., 0].mean(), 1e-4, rtol=1e-5)
    assert sol.delta[0] == pytest.approx(u[..., 0][stick].mean(), rel=1e-4)
    assert sol.stick == stick.mean()


def test_shear_at_refuses_a_traction_beyond_friction():
    p = np.zeros((16, 16))
    p[7:9, 7:9] = 1.0
    with pytest.raises(ValueError, match="valid range: 0 < target < mu p"):
        T.shear_at(p, (1.0, 1.0), 1.0, 0.3, 0.5, 0.5 * p.mean(), 1e-3)
