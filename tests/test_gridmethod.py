"""The paper's grid method (Steps 1–5) against the quadrature reference, and its convergence."""

import dataclasses
import math

import numba
import numpy as np
import pytest

from asperity_sim.analysis import gridmethod as gm
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


def test_step4_tangent_is_the_forward_difference_of_the_grid_stress():
    """Step 4 as published: at every recorded increment T[:, k] = (sigma(Delta + h e_k) - sigma(Delta)) / h,
    recomputed here from gm.stress; four stress evaluations per displacement-controlled increment."""
    p = presets.R1
    res = gm.GridResolution.scaled(4.0)
    rule = gm.grid_rule(p, res)
    path = paths.three_step(15 * um, 2)
    ds = gm.simulate_grid(p, path, res)
    h = res.fd_step * rule.r90
    assert ds["tangent"].attrs["units"] == "Pa m-1"
    for step in (2, 4, 6):
        d = ds.displacement.values[step]
        sig = gm.stress(p, d, rule=rule)
        for k in range(3):
            dk = d.copy()
            dk[k] += h
            expected = (gm.stress(p, dk, rule=rule) - sig) / h
            np.testing.assert_allclose(ds.tangent.values[step, :, k], expected, rtol=1e-12, atol=1e-3)
    assert ds.attrs["stress_evaluations"] == 4 * ds.sizes["step"]
    # the normal stiffness of the grid against the quadrature's at the end of step 1 (the forward
    # difference is first order in h: its error must shrink with the step)
    d = ds.displacement.values[2]
    ref = reference.tangent(p, d)[0, 0]
    coarse = abs(ds.tangent.values[2, 0, 0] / ref - 1)
    finer = gm.simulate_grid(p, path, dataclasses.replace(res, fd_step=res.fd_step / 4))
    assert abs(finer.tangent.values[2, 0, 0] / ref - 1) < coarse


def test_lighter_step4_gives_the_same_stresses_with_fewer_evaluations():
    """full_tangent=False: identical iterates and stresses, no tangent, one evaluation per
    displacement-controlled increment; a stress-controlled path still iterates."""
    p = presets.S1
    S, D = paths.STRESS, paths.DISPLACEMENT
    res = gm.GridResolution.scaled(4.0)
    for path in (paths.three_step(6 * um, 2),
                 paths.LoadPath((paths.Stage((S, D, D), (500e6, 0.0, 0.0), 2),
                                 paths.Stage((S, D, D), (500e6, 4 * um, 0.0), 2)))):
        full = gm.simulate_grid(p, path, res)
        light = gm.simulate_grid(p, path, res, full_tangent=False)
        np.testing.assert_array_equal(full.stress.values, light.stress.values)
        np.testing.assert_array_equal(full.iterations.values, light.iterations.values)
        assert "tangent" not in light and light.attrs["stress_evaluations"] < full.attrs["stress_evaluations"]
    assert light.attrs["stress_evaluations"] > light.sizes["step"]
    assert gm.simulate_grid(p, paths.three_step(6 * um, 2), res, full_tangent=False).attrs["stress_evaluations"] == 7
    with pytest.raises(ValueError, match="full_tangent"):
        gm.simulate_grid(p, path, res, full_tangent="yes")
