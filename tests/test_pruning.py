"""Height-band pruning: safe bound, unbiased band estimator, right standard error, detect and correct."""

import math

import numpy as np
import pytest
from scipy import optimize, stats

from asperity_sim import paths, Population, presets, reference, simulate
from asperity_sim.kernels.commit import birth_angles
from asperity_sim.kernels.evaluate import evaluate, snapshot
from asperity_sim.sampling.distributions import band_probability
from asperity_sim.sampling.band import band_for_path, check_band, reach_along, reach_height, theta_bound
from asperity_sim.solve.pruning import simulate_pruned

um = 1e-6
R1, S1, R2 = presets.R1, presets.S1, presets.R2
S, D = paths.STRESS, paths.DISPLACEMENT


# ---------------------------------------------------------------------------------------------
# band sampling and the estimator
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("sampler", ["random", "sobol"])
def test_band_heights_follow_the_truncated_gamma(sampler):
    r_max = 20 * um
    pop = Population.sample(R1, 4096, seed=3, sampler=sampler, r_max=r_max)
    p = band_probability(R1, r_max)
    assert pop.r.max() <= r_max and pop.r_band == r_max
    assert pop.weight == pytest.approx(p / pop.n, rel=1e-15)
    cdf = lambda x: stats.gamma.cdf(x, R1.alpha + 1, scale=R1.beta) / p  # noqa: E731
    assert stats.kstest(pop.r, cdf).pvalue > 1e-3


def test_no_band_is_the_full_population():
    a = Population.sample(S1, 1000, seed=4)
    b = Population.sample(S1, 1000, seed=4, r_max=math.inf)
    assert np.array_equal(a.r, b.r) and a.weight == b.weight and b.r_band == math.inf


def test_band_validation():
    with pytest.raises(ValueError, match="r_max"):
        Population.sample(R1, 10, r_max=-1.0)
    with pytest.raises(ValueError, match="too narrow"):
        Population.sample(R1, 10, r_max=1e-300)


def test_standard_error_formula_with_band_weights():
    """assemble.finish with weight p/n: sigma = N p mean(f), se = N p sd(f)/sqrt(n), from per-asperity forces."""
    d = np.array([6.0, 2.0, -1.0]) * um
    band = reach_height(S1, d[0], math.hypot(d[1], d[2]))
    pop = Population.sample(S1, 3000, seed=5, r_max=band)
    ev = evaluate(pop, d)
    f = snapshot(pop, d)["force"]
    p = pop.weight * pop.n
    assert p < 0.95
    assert np.allclose(ev.stress, S1.N * p * f.mean(axis=0), rtol=1e-12)
    assert np.allclose(ev.stderr, S1.N * p * f.std(axis=0, ddof=1) / math.sqrt(pop.n), rtol=1e-9)
    assert np.allclose(ev.covariance, S1.N**2 * p**2 * np.cov(f.T) / pop.n, rtol=1e-9, atol=1e-12 * ev.stderr.max()**2)


def test_band_standard_error_matches_replica_scatter():
    d = np.array([18.0, 0.0, 0.0]) * um
    est, se = [], []
    for seed in range(80):
        ev = evaluate(Population.sample(R1, 1500, seed=seed, r_max=d[0]), d)
        est.append(ev.stress[0])
        se.append(ev.stderr[0])
    ratio = np.std(est, ddof=1) / np.mean(se)
    assert 0.8 < ratio < 1.25


@pytest.mark.parametrize("params, delta_um", [(R1, (18.0, 0.0, 0.0)), (S1, (6.0, 2.0, 0.0)),
                                              (S1, (5.8, 10.0, -3.0)), (R2, (150.0, 20.0, 0.0))])
@pytest.mark.statistical
def test_band_estimate_is_unbiased(params, delta_um):
    d = np.array(delta_um) * um
    band = reach_height(params, d[0], math.hypot(d[1], d[2]))
    assert math.isfinite(band) and band_probability(params, band) < 0.999
    pop = Population.sample(params, 40000, seed=11, r_max=band)
    ev = evaluate(pop, d)
    ref = reference.stress(params, d)
    z = (ev.stress - ref) / np.where(ev.stderr > 0, ev.stderr, np.inf)
    assert np.all(np.abs(z) < 4), z


# ---------------------------------------------------------------------------------------------
# safety of the bound, checked with full populations
# ---------------------------------------------------------------------------------------------


def test_bound_is_sharp_for_the_steepest_asperity():
    """At R = R_lo, u = pi/2, phi along the shear: touches just below the bound, not above."""
    d1, s = 10 * um, 4 * um
    bound = reach_height(R1, d1, s)
    R_lo = R1.R_bounds[0]
    pop = Population.from_arrays(R1, [bound * (1 - 1e-6), bound * (1 + 1e-6)], [R_lo, R_lo],
                                 [0.5 * math.pi] * 2, [0.0, 0.0])
    dn = snapshot(pop, [d1, s, 0.0])["delta_n"]
    assert dn[0] > 0 and dn[1] < 0
    assert theta_bound(R1, d1) == pytest.approx(math.acos(1 - R1.k_e * d1 / R_lo))


@pytest.mark.parametrize("params, path", [
    (S1, paths.LoadPath((paths.Stage((S, D, D), (500e6, 0, 0), 4), paths.Stage((S, D, D), (500e6, 20e-6, 0), 6)))),
    (R1, paths.three_step(15e-6, 4)),
    (R2, paths.LoadPath((paths.Stage((D, D, D), (0.15e-3, 0, 0), 3),
                         paths.Stage((D, D, D), (0.15e-3, 0.03e-3, 0.01e-3), 3)))),
])
def test_no_asperity_above_the_bound_touches_along_a_path(params, path):
    """Full population (no band): every contact at every recorded step lies below the bound."""
    pop = Population.sample(params, 20000, seed=2)
    ds = simulate(params, path, population=pop)
    disp = ds["displacement"].values
    for i in range(1, disp.shape[0]):
        snap = snapshot(pop, disp[i])
        touching = snap["delta_n"] > 0
        if touching.any():
            assert pop.r[touching].max() < reach_along(params, disp[: i + 1])
            assert pop.r[touching].max() < reach_height(params, disp[i, 0], math.hypot(disp[i, 1], disp[i, 2]))
    safe, need = check_band(params, disp, math.inf)
    assert safe and need > 0


def test_bound_covers_frozen_birth_angles_after_unloading():
    """Policy birth: angles frozen at a large closure stay steep after the closure falls."""
    pop = Population.sample(R1, 20000, seed=6)
    path = [np.array(x) * um for x in [(15, 0, 0), (15, 8, 0), (8, 8, 0), (5, 12, 0)]]
    tb = np.full(pop.n, np.nan)
    for i, d in enumerate(path):
        birth_angles(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, pop.n, d, R1.r_o, R1.k_e, tb)
        snap = snapshot(pop, d, policy="birth", theta_birth=tb)
        touching = snap["delta_n"] > 0
        assert pop.r[touching].max() < reach_along(R1, np.array(path[: i + 1]))
    # a steep asperity born at the large closure keeps touching above the bound of the current
    # closure: the running maximum of the closure is needed (and sufficient)
    R_lo = R1.R_bounds[0]
    one = Population.from_arrays(R1, [30 * um], [R_lo], [0.5 * math.pi], [0.0])
    tb1 = np.full(1, np.nan)
    for i, d in enumerate(path):
        birth_angles(one.r, one.R, one.u, one.cos_phi, one.sin_phi, 1, d, R1.r_o, R1.k_e, tb1)
        assert (snapshot(one, d, policy="birth", theta_birth=tb1)["delta_n"][0] > 0) == (i > 0)
    d = path[-1]
    assert one.r[0] > reach_height(R1, d[0], d[1])
    assert one.r[0] < reach_along(R1, np.array(path))


def test_band_for_displacement_path_equals_bound_of_its_targets():
    path = paths.three_step(6e-6, 5)
    b = band_for_path(S1, path)
    assert b == pytest.approx(reach_along(S1, np.array([[6e-6, 0, 0], [6e-6, 6e-6, 0], [6e-6, 6e-6, 6e-6]])))
    closure = paths.LoadPath((paths.Stage((S, D, D), (100e6, 0, 0), 3),))
    assert band_for_path(S1, closure) == math.inf  # Delta_1 unknown without a bound
    assert band_for_path(S1, closure, delta_bound=[5e-6, 0, 0]) == pytest.approx(5e-6)


# ---------------------------------------------------------------------------------------------
# simulate_pruned: pilot, band, check, correction
# ---------------------------------------------------------------------------------------------


def _reference_closure(params, sigma):
    f = lambda x: reference.stress(params, [x, 0, 0])[0] - sigma  # noqa: E731
    return optimize.brentq(f, 1e-7, 60 * params.beta, xtol=1e-16, rtol=1e-13)


@pytest.mark.statistical
def test_simulate_pruned_closure_is_unbiased():
    path = paths.LoadPath((paths.Stage((S, D, D), (300e6, 0, 0), 3),))
    ds = simulate_pruned(R1, path, 20000, seed=1, sampler="random")
    assert 0 < ds.attrs["height_band_probability"] < 0.5
    assert ds.attrs["height_band_runs"] == 1 and ds.attrs["height_band_pilot"] == 1
    assert ds.attrs["height_band_m"] >= ds.attrs["height_band_needed_m"]
    d1 = ds.displacement.values[-1, 0]
    ref = _reference_closure(R1, 300e6)
    assert abs(d1 - ref) < 4 * ds.displacement_stderr.values[-1, 0]


def test_simulate_pruned_detects_and_corrects_a_narrow_band():
    path = paths.LoadPath((paths.Stage((S, D, D), (300e6, 0, 0), 3),))
    ds = simulate_pruned(R1, path, 20000, seed=1, sampler="sobol", delta_bound=[8e-6, 0, 0])
    assert ds.attrs["height_band_runs"] >= 2
    safe, need = check_band(R1, ds.displacement.values, ds.attrs["height_band_m"])
    assert safe
    assert abs(ds.displacement.values[-1, 0] / _reference_closure(R1, 300e6) - 1) < 2e-3


def test_simulate_pruned_displacement_path_needs_no_pilot():
    ds = simulate_pruned(S1, paths.three_step(6e-6, 3), 5000, seed=2, sampler="sobol")
    assert ds.attrs["height_band_pilot"] == 0 and ds.attrs["height_band_runs"] == 1
    assert ds.attrs["height_band_probability"] < 0.95
