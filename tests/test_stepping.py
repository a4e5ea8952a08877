"""Stepping a stage (asperity_sim/stepping.py): increment sizes, predictors within a trust region, named
failures, and the standard errors of a solution under mixed control.

Through ``simulate`` where the behaviour is the loop's (an adaptive stage grows its increments and still
ends on its target; a predictor step stays within the interface's length scale, so a reload from zero
load is reached; a stress that cannot be reached stops with a named error and the partial dataset), and
on the functions themselves where there is a closed form to compare with (the cubic predictor's order).
Expected values come from closed forms (e = 0 bounds the shear stress by mu sigma_1 exactly), from the
paper's Fig. 13 (R1 resists about 1.7 sigma_1) and from the scatter of replicas.
"""

import math

import numpy as np
import pytest
import xarray as xr
from support import single_thread

import asperity_sim as asim
from asperity_sim import evaluate, paths, Population, presets, simulate, SolverSettings, StressNotReachableError
from asperity_sim.output.netcdf import read_netcdf
from asperity_sim.paths import LoadPath, Stage
from asperity_sim.output.variables import STEP_VARIABLES

S, D = paths.STRESS, paths.DISPLACEMENT
RTOL = SolverSettings().rtol


# --------------------------------------------------------------------------- increment sizes


def test_adaptive_stage_ends_exactly_on_target():
    pop = Population.sample(presets.S1, 2000, seed=1)
    st = Stage(("s", "d", "d"), (200e6, 0, 0), 20, adaptive=True, max_fraction=0.25)
    ds = simulate(presets.S1, LoadPath((st, Stage(("s", "d", "d"), (200e6, 3e-6, 0), 10, adaptive=True,
                                                   max_fraction=0.5))), population=pop)
    s = ds.stress.values
    stg = ds.stage.values
    i1 = int(np.flatnonzero(stg == 1)[-1])  # end of stage 1
    assert abs(s[i1, 0] - 200e6) <= 2 * RTOL * 200e6
    assert ds.displacement.values[-1, 1] == 3e-6
    # easy increments grew: fewer records than nominal increments, none larger than max_fraction
    assert (stg == 2).sum() < 10
    d2 = ds.displacement.values[stg == 2, 1]
    assert np.all(np.diff(np.concatenate([[0.0], d2])) <= 0.5 * 3e-6 * (1 + 1e-12))
    assert np.all(np.diff(s[stg == 1, 0]) > 0) and (stg == 1).sum() < 20


# --------------------------------------------------------------------------- predictors and the trust region


def test_cubic_predictor_is_third_order_on_a_smooth_path_and_falls_back_at_a_kink():
    """The Hermite extrapolation from two converged points (values and exact slopes) has an
    error O(h^4), far below the tangent predictor's O(h^2); at a slope jump it keeps the tangent."""
    from asperity_sim.solve.stepping import cubic_predictor as _cubic_predict, Position as _Position

    def x(s):
        return np.array([np.exp(s), 0.0, np.sin(3.0 * s)])

    def dx(s):
        return np.array([np.exp(s), 0.0, 3.0 * np.cos(3.0 * s)])

    free = np.array([True, False, True])
    errors = []
    for h in (0.1, 0.05):
        s0, s1, s2 = 0.3 - h, 0.3, 0.3 + h
        pos = _Position(prev_s=s0, prev_delta=x(s0), prev_slope=dx(s0))
        linear = x(s1) + h * dx(s1)
        guess = _cubic_predict(linear, x(s1), dx(s1), pos, s1, s2, free)
        err_lin, err_cub = np.abs(linear - x(s2))[free], np.abs(guess - x(s2))[free]
        assert np.all(err_cub < 0.05 * err_lin)
        assert guess[1] == linear[1]  # prescribed components are left alone
        errors.append(err_cub)
    assert np.all(errors[0] / errors[1] > 2.0**4 * 0.8)  # fourth-order local error
    # a kink: the previous slope points the other way, so the cubic would overshoot
    pos = _Position(prev_s=0.2, prev_delta=x(0.3) + 0.1 * dx(0.3), prev_slope=dx(0.3))
    linear = x(0.3) + 0.1 * dx(0.3)
    np.testing.assert_array_equal(_cubic_predict(linear, x(0.3), dx(0.3), pos, 0.3, 0.4, free), linear)


def test_cubic_predictor_saves_newton_iterations_on_the_fig13_path():
    """Same converged curve (to the solver tolerance) with fewer iterations than the tangent predictor alone."""
    from asperity_sim.solve import run as driver

    p = presets.R1
    path = paths.constant_normal_shear(500e6, 50e-6, 20)
    pop = Population.sample(p, 2**14, seed=3, sampler="sobol")
    settings = SolverSettings(rtol=1e-9)
    cubic = simulate(p, path, population=pop, settings=settings)
    original, spans = driver.cubic_predictor, driver.can_span
    driver.cubic_predictor = lambda linear, *args: linear
    driver.can_span = lambda *args: False  # the Python loop, whose predictor is patched here
    try:
        linear = simulate(p, path, population=pop, settings=settings)
    finally:
        driver.cubic_predictor, driver.can_span = original, spans
    assert int(cubic.iterations.sum()) < 0.9 * int(linear.iterations.sum())
    np.testing.assert_allclose(cubic.stress.values, linear.stress.values, rtol=1e-8, atol=1e-6 * 500e6)
    np.testing.assert_allclose(cubic.displacement.values, linear.displacement.values, rtol=1e-7)


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_reload_from_an_unloaded_state_is_reached(law):
    """sigma_1: 100 MPa -> 0 -> 100 MPa under stress control (the tangent at zero load is zero)."""
    path = paths.LoadPath((paths.Stage((S, D, D), (100e6, 0, 0), 4), paths.Stage((S, D, D), (0.0, 0, 0), 4),
                           paths.Stage((S, D, D), (100e6, 0, 0), 4)), name="reload")
    ds = simulate(presets.R1, path, n=2000, seed=1, law=law, k=8)
    s1 = ds.stress.sel(axis=1).values
    assert ds.attrs["status"] == "complete"
    assert s1[-1] == pytest.approx(100e6, rel=1e-8)
    assert np.all(np.abs(ds.displacement.values) < 1e-3)  # no run-away predictor step


def test_seating_at_a_tiny_load_then_loading():
    path = paths.LoadPath((paths.Stage((S, D, D), (1e-3, 0, 0), 2), paths.Stage((S, D, D), (100e6, 0, 0), 4)))
    ds = simulate(presets.R1, path, n=2000, seed=1)
    assert ds.stress.sel(axis=1).values[-1] == pytest.approx(100e6, rel=1e-8)


# --------------------------------------------------------------------------- named failures


@pytest.fixture(scope="module")
def unreachable_R1():
    """sigma_1 -> 500 MPa, then sigma_1 held and sigma_2 stress controlled to 3 x 500 MPa (R1
    resists about 1.7 sigma_1, SPEC §7 / Fig. 13)."""
    pop = Population.sample(presets.R1, 4000, seed=2)
    path = LoadPath((Stage(("s", "d", "d"), (500e6, 0, 0), 5, name="normal"),
                     Stage(("s", "s", "d"), (500e6, 1500e6, 0), 5, name="shear by stress")))
    with single_thread():
        with pytest.raises(StressNotReachableError) as exc:
            simulate(pop.params, path, population=pop)
    return exc.value


@pytest.mark.slow
def test_unreachable_shear_stress_raises_with_partial_dataset(unreachable_R1):
    err = unreachable_R1
    assert isinstance(err, asim.SimulationError)
    ds = err.dataset
    assert isinstance(ds, xr.Dataset) and ds.sizes["step"] > 1
    for name in STEP_VARIABLES:
        assert np.all(np.isfinite(ds[name].values)), name
    assert ds.attrs["status"].startswith("failed")
    st = ds.stage.values
    assert (st == 2).any()
    s = ds.stress.values[st == 2]
    np.testing.assert_allclose(s[:, 0], 500e6, rtol=1e-9)
    assert s[:, 1].max() < 1500e6
    assert s[:, 1].max() > 500e6  # R1 carries more than mu sigma_1 before failing


@pytest.mark.slow
def test_unreachable_shear_stress_message_names_sigma2(unreachable_R1):
    msg = str(unreachable_R1)
    assert "sigma_2" in msg and "sigma_[1, 2]" not in msg


def _flat_contact_failure_path(pop):
    """e = 0: all contacts normal, so at fixed Delta_1 sigma_2 <= mu sigma_1 exactly (SPEC §3, §5)."""
    s1 = evaluate(pop, [10e-6, 0, 0]).stress[0]
    return LoadPath((Stage(("d", "d", "d"), (10e-6, 0, 0), 2),
                     Stage(("d", "s", "d"), (10e-6, 3 * pop.params.mu * s1, 0), 3))), s1


def test_unreachable_scalar_raises_quickly_and_writes_output(tmp_path):
    pop = Population.sample(presets.R1.replace(e=0.0), 5000, seed=4)
    path, s1 = _flat_contact_failure_path(pop)
    out = tmp_path / "sub" / "failed.nc"
    with pytest.raises(StressNotReachableError) as exc:
        simulate(pop.params, path, population=pop, output=out)
    err = exc.value
    assert "sigma_2" in str(err)
    ds = err.dataset
    assert ds.sizes["step"] >= 3  # initial state + the two normal increments at least
    assert np.all(np.isfinite(ds.stress.values))
    assert ds.stress.values[:, 1].max() <= pop.params.mu * s1 * (1 + 1e-9)
    assert out.exists()
    back = read_netcdf(out)
    assert back.attrs["status"].startswith("failed")
    for name in STEP_VARIABLES:
        assert np.array_equal(back[name].values, ds[name].values), name
    assert not list(out.parent.glob("*.tmp"))  # atomic write leaves no temporary file


def test_asymptotically_unreachable_stress_terminates():
    pop = Population.sample(presets.R1.replace(e=0.0), 2000, seed=3)
    path = LoadPath((Stage(("s", "d", "d"), (500e6, 0, 0), 5), Stage(("s", "s", "d"), (500e6, 1500e6, 0), 5)))
    count = [0]

    class Guard(Exception):
        pass

    def progress(*args):
        count[0] += 1
        if count[0] > 400:
            raise Guard(f"still running after {count[0]} increments")

    with single_thread():
        with pytest.raises(StressNotReachableError):
            simulate(pop.params, path, population=pop, progress=progress)


@pytest.mark.parametrize("control", [(S, D, D), (S, S, S)])
def test_tension_from_zero_is_named_unreachable(control):
    path = paths.LoadPath((paths.Stage(control, (-1e6, 0, 0), 3, name="tension"),))
    with pytest.raises(asim.StressNotReachableError, match="tension|cannot be reached") as exc:
        simulate(presets.R1, path, n=500)
    assert exc.value.dataset.sizes["step"] >= 1


# --------------------------------------------------------------------------- standard errors under mixed control


REPLICAS = 40


@pytest.mark.statistical
@pytest.mark.slow
def test_stderr_of_solved_closure_and_shear_stress_match_replicas():
    """Error bars under mixed control: the delta-method standard errors match replica scatter."""
    path = paths.constant_normal_shear(500e6, 4e-6, increments=2, normal_increments=3)
    finals = [simulate(presets.S1, path, n=4000, seed=1000 + i).isel(step=-1) for i in range(REPLICAS)]
    d1 = np.array([float(f.displacement.sel(axis=1)) for f in finals])
    s2 = np.array([float(f.stress.sel(axis=2)) for f in finals])
    se_d1 = np.mean([float(f.displacement_stderr.sel(axis=1)) for f in finals])
    se_s2 = np.mean([float(f.stress_stderr.sel(axis=2)) for f in finals])
    # sigma_1 is held exactly, so its error moved into Delta_1 and into sigma_2 through T_21
    assert all(float(f.stress_stderr.sel(axis=1)) == 0.0 for f in finals)
    tol = 4 * math.sqrt(1 / (2 * (REPLICAS - 1)))  # 4 s.e. of a sample standard deviation
    assert abs(d1.std(ddof=1) / se_d1 - 1) < tol
    assert abs(s2.std(ddof=1) / se_s2 - 1) < tol


# --------------------------------------------------------------------------- standard error of the area

def test_area_stderr_with_one_stress_control_is_the_pseudo_inverse_formula_bit_for_bit():
    """With one stress-controlled component the area's standard error is computed on Python floats; it is the
    delta-method formula with the pseudo-inverse of the tangent block (numpy's pinv), to the last bit, also for a
    zero tangent (pinv gives 0) and negative ones."""
    from types import SimpleNamespace

    from asperity_sim.solve.stepping import area_stderr

    rng = np.random.default_rng(7)
    for trial in range(300):
        L = rng.normal(size=(3, 3)) * 10.0 ** rng.uniform(-3, 3)
        tangent = rng.normal(size=(3, 3)) * 10.0 ** rng.uniform(9, 15)
        k = trial % 3
        if trial % 50 == 0:
            tangent[k, k] = 0.0
        own = trial % 4 == 1  # else the terms of the tangent dominate, or are all there is (var 0, no cov)
        ev = SimpleNamespace(tangent=tangent, covariance=L @ L.T,
                             contact_area_var=float(rng.uniform(0, 1e-4)) if own else 0.0,
                             contact_area_grad=rng.normal(size=3) * 1e4,
                             contact_area_cov=rng.normal(size=3) * 1e-2 * (trial % 4 != 2))
        free = np.zeros(3, dtype=bool)
        free[k] = True
        A = np.linalg.pinv(ev.tangent[np.ix_(free, free)], rcond=1e-12)
        h = A.T @ ev.contact_area_grad[free]
        C = ev.covariance[np.ix_(free, free)]
        var = ev.contact_area_var - 2.0 * float(h @ ev.contact_area_cov[free]) + float(h @ C @ h)
        want = math.sqrt(var) if var > 0.0 else 0.0
        assert area_stderr(ev, free) == want
