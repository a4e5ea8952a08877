"""The paper's grid method (Steps 1–5) against the quadrature reference, and its convergence."""

import math

import numba
import numpy as np
import pytest

from asperity_sim import gridmethod as gm
from asperity_sim import paths, presets, reference

um = 1e-6

POINTS = {
    "R1": [(15, 0, 0), (15, 15, 0), (13, 50, 0)],
    "S1": [(6, 0, 0), (6, 6, 6), (3.7, 50, 0)],
}


def max_error(name, s):
    p = presets.TABLE1[name]
    rule = gm.grid_rule(p, gm.GridResolution.scaled(s))
    errs = []
    for d in POINTS[name]:
        d = np.array(d) * um
        ref = reference.stress(p, d)
        errs.append(np.abs(gm.stress(p, d, rule=rule) - ref).max() / np.abs(ref).max())
    return max(errs)


@pytest.mark.parametrize("name", ["R1", "S1"])
def test_published_grid_agrees_with_quadrature_and_converges(name):
    """Error at the published resolution is small, and falls under refinement (s = 4, 2, 1)."""
    e4, e2, e1 = (max_error(name, s) for s in (4.0, 2.0, 1.0))
    assert e1 < 2e-4  # measured: R1 8e-5, S1 1.1e-5 (relative to max |sigma|)
    assert e4 > e2 > e1
    assert e1 < e4 / 20


def test_simpson_weights_exact_for_cubics():
    x = np.linspace(0.0, 2.0, 11)
    w = gm.simpson_weights(10, 0.2)
    for k in range(4):
        assert np.dot(w, x**k) == pytest.approx(2.0 ** (k + 1) / (k + 1), rel=1e-13)


@pytest.mark.parametrize("name", ["R1", "S1", "R2"])
def test_rule_weights_integrate_the_densities(name):
    """Height, radius and orientation weights integrate their densities to ~1 (not renormalised)."""
    rule = gm.grid_rule(presets.TABLE1[name], gm.PAPER)
    assert rule.w_r.sum() == pytest.approx(1.0, abs=1e-6)
    assert rule.w_R.sum() == pytest.approx(1.0, abs=1e-6)
    # orientation: int sin u du dphi xi = 1 with xi = 1/(2 pi) (isotropic)
    assert rule.w_u.sum() * rule.w_phi.sum() / (2 * math.pi) == pytest.approx(1.0, abs=1e-5)
    assert rule.r[1] == pytest.approx(0.01 * gm.r_percentile(presets.TABLE1[name]), rel=1e-12)
    assert rule.R.size == 601 and rule.t_u.size == 21 and rule.phi.size == 41


def test_resolution_scaling_and_validation():
    assert gm.GridResolution.scaled(1.0) == gm.PAPER
    r2 = gm.GridResolution.scaled(2.0)
    assert (r2.dr, r2.dR, r2.n_theta, r2.n_phi) == (0.02, 0.02, 10, 20)
    with pytest.raises(ValueError, match="n_theta"):
        gm.GridResolution(n_theta=7)
    with pytest.raises(ValueError, match="dr"):
        gm.GridResolution(dr=0.0)
    with pytest.raises(ValueError, match="delta"):
        gm.stress(presets.R1, [1.0, 2.0])


def test_result_does_not_depend_on_thread_count():
    p = presets.R1
    rule = gm.grid_rule(p, gm.GridResolution.scaled(4.0))
    d = np.array([15, 4, -2]) * um
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        a = gm.stress(p, d, rule=rule)
        numba.set_num_threads(before)
        b = gm.stress(p, d, rule=rule)
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(a, b)


def test_newton_path_under_stress_control():
    """Steps 2-5 on a short Fig. 13 path: sigma_1 held to rtol, close to the quadrature solution."""
    p = presets.S1
    S, D = paths.STRESS, paths.DISPLACEMENT
    path = paths.LoadPath((paths.Stage((S, D, D), (500e6, 0.0, 0.0), 3),
                           paths.Stage((S, D, D), (500e6, 4 * um, 0.0), 2)))
    ds = gm.simulate_grid(p, path, gm.GridResolution.scaled(4.0), rtol=1e-9)
    sig = ds.stress.values
    assert np.allclose(sig[1:4, 0], [500e6 / 3, 1000e6 / 3, 500e6], rtol=1e-8)
    assert np.allclose(sig[4:, 0], 500e6, rtol=1e-8)
    assert np.all(ds.iterations.values[1:] >= 1)
    # the solved closure against the quadrature at the last step (grid error ~1e-3 at s = 4)
    d = ds.displacement.values[-1]
    ref = reference.stress(p, d)
    assert abs(ref[0] / 500e6 - 1) < 1e-2
    assert abs(sig[-1, 1] / ref[1] - 1) < 1e-2
    assert ds.attrs["stress_evaluations"] > ds.sizes["step"]
