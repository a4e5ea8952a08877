"""asperity_sim.analysis.surfaces.shear: the mdr law at a mean pressure and mean shear tractions (e = 0).

The run's displacements against the closed forms of Hertz and Cattaneo–Mindlin solved independently (Brent),
the initial stiffness against the kernels' tangent, and the stick-area standard error against the spread over
independent populations."""

import math

import numpy as np
import pytest
from scipy import optimize

from asperity_sim import evaluate, presets
from asperity_sim.analysis.surfaces import shear
from asperity_sim.sampling.population import Population

PARAMS = presets.R1.replace(e=0.0, mu=0.6)
P = 100e6


def _closed_forms(pop, pressure, traction):
    """Delta_1 and Delta_2 solving N E[Hertz] = pressure and N E[Cattaneo–Mindlin] = traction (Brent)."""
    p = pop.params
    fn = lambda d1: (4 / 3) * p.E_star * np.sqrt(pop.R) * np.maximum(d1 - pop.r, 0) ** 1.5  # noqa: E731
    d1 = optimize.brentq(lambda d: p.N * pop.weight * fn(d).sum() - pressure, 0, 1e-4, xtol=1e-16, rtol=1e-13)
    slip = p.lam * p.mu * np.maximum(d1 - pop.r, 0)

    def fs(d2):
        x = np.minimum(d2 / np.where(slip > 0, slip, 1), 1)
        return p.mu * fn(d1) * (1 - (1 - x) ** 1.5)

    d2 = optimize.brentq(lambda d: p.N * pop.weight * fs(d).sum() - traction, 0, slip.max(), xtol=1e-18, rtol=1e-13)
    return d1, d2


def test_mdr_run_equals_the_closed_forms_and_stick_area_is_cattaneo():
    """The mdr springs converge to Cattaneo–Mindlin as 1/k² (docs/results/mdr_k_convergence.md): Delta_2 within
    3e-5 at k = 64 (measured 7e-6; 7e-4 at k = 16, the default of the comparison)."""
    pop = Population.sample(PARAMS, 3000, seed=4)
    q = np.array([0.1, 0.5, 0.9]) * PARAMS.mu * P
    out, coarse = shear.model_shear(pop, P, q, k=64), shear.model_shear(pop, P, q, k=16)
    for i, qi in enumerate(q):
        d1, d2 = _closed_forms(pop, P, qi)
        assert out["closure"][i] == pytest.approx(d1, rel=1e-8)
        assert out["delta"][i] == pytest.approx(d2, rel=3e-5)
        assert abs(coarse["delta"][i] / d2 - 1) < 2e-3
        assert out["traction"][i] == pytest.approx(qi, rel=1e-8)
        stick = math.pi * pop.R * np.maximum(d1 - pop.r - d2 / (PARAMS.lam * PARAMS.mu), 0)
        assert out["stick"][i] == pytest.approx(PARAMS.N * stick.mean(), rel=1e-4)
    assert np.all(np.diff(out["stick"]) < 0) and out["stick"][0] < out["contact"]
    d1 = _closed_forms(pop, P, q[0])[0]
    assert out["stiffness"] == pytest.approx(evaluate(pop, (d1, 0.0, 0.0)).tangent[1, 1], rel=1e-6)


@pytest.mark.statistical
def test_stick_and_stiffness_standard_errors_match_the_spread():
    """30 populations of 1000: the variance of the stick fraction and of the initial stiffness over the
    populations against the mean delta-method standard error, within the 99.9 % band of chi² with 29 degrees of
    freedom ([0.37, 2.0])."""
    q = [0.5 * PARAMS.mu * P]
    runs = [shear.model_shear(Population.sample(PARAMS, 1000, seed=200 + s), P, q, k=8) for s in range(30)]
    for name in ("stick", "stiffness", "delta"):
        values = np.array([np.atleast_1d(r[name])[0] for r in runs])
        se = np.mean([np.atleast_1d(r[f"{name}_se"])[0] for r in runs])
        ratio = values.var(ddof=1) / se**2
        assert 0.37 < ratio < 2.0, (name, ratio)


def test_contacts_must_be_normal_to_the_plane():
    pop = Population.sample(presets.R1, 100, seed=1)
    with pytest.raises(ValueError, match="valid: e = 0"):
        shear.model_shear(pop, P, [1e6])
