"""Derived joint properties (asperity_sim.analysis.properties) and envelopes (asperity_sim.runs.envelope).

Synthetic datasets whose answers are known in closed form: an elastic / softening shear
curve with a quadratic normal displacement (peak, residual, dilation exact), rotated
shear directions, an elliptic hysteresis loop (area pi a c, secant stiffness k, damping
c / (2 k a)), and Mohr-Coulomb / power-law data with known noise (estimates and the
coverage of the confidence intervals).  Then small real runs: the path-independent paper
law dissipates nothing per cycle, and for the history law mdr the loop area matches the
recorded dissipation.
"""

import math

import numpy as np
import pytest
import xarray as xr

from asperity_sim.analysis import properties as P
from asperity_sim.output.variables import PROPERTY_VARIABLES


# -- synthetic datasets ------------------------------------------------------------------

def _dataset(stage, disp, stress, stderr=None, tangent=None, control_1=1, dissipation=None, status="complete"):
    m = len(stage)
    control = np.zeros((m, 3), dtype="i1")
    control[:, 0] = control_1
    stderr = np.zeros((m, 3)) if stderr is None else stderr
    tangent = np.zeros((m, 3, 3)) if tangent is None else tangent
    ds = xr.Dataset({"displacement": (("step", "axis"), disp), "stress": (("step", "axis"), stress),
                     "stress_stderr": (("step", "axis"), stderr), "tangent": (("step", "axis", "axis_k"), tangent),
                     "stage": (("step",), np.asarray(stage)), "control": (("step", "axis"), control)})
    if dissipation is not None:
        ds["dissipation"] = ("step", dissipation)
    ds.attrs["status"] = status
    return ds


K, TAU_Y, H, SIGMA_N = 1e14, 300e6, 5e13, 500e6  # Pa/m, Pa, Pa/m, Pa
P1, Q1 = 0.2, 5e4  # Delta_1 = D0 + P1 s - Q1 s^2: compress, then dilate


def softening_run(m_normal=5, m_shear=60, s_max=6e-6, direction=0.0, tangent_start=None):
    """sigma_n held; tau = K s up to s_y = TAU_Y / K, then TAU_Y - H (s - s_y); shear along angle ``direction``."""
    s = np.linspace(0.0, s_max, m_shear + 1)
    s_y = TAU_Y / K
    tau = np.where(s <= s_y, K * s, TAU_Y - H * (s - s_y))
    d1_0 = 3e-6
    d1 = d1_0 + P1 * s - Q1 * s**2
    c, sn = math.cos(direction), math.sin(direction)
    normal = np.linspace(0, 1, m_normal + 1)
    disp = np.zeros((m_normal + 1 + m_shear, 3))
    stress = np.zeros_like(disp)
    disp[: m_normal + 1, 0] = d1_0 * normal
    stress[: m_normal + 1, 0] = SIGMA_N * normal
    disp[m_normal + 1:, 0] = d1[1:]
    disp[m_normal + 1:, 1], disp[m_normal + 1:, 2] = c * s[1:], sn * s[1:]
    stress[m_normal + 1:, 0] = SIGMA_N
    stress[m_normal + 1:, 1], stress[m_normal + 1:, 2] = c * tau[1:], sn * tau[1:]
    stderr = np.full_like(disp, 1e6)
    stderr[:, 0] = 0.0
    tangent = np.zeros((disp.shape[0], 3, 3))
    tangent[m_normal] = tangent_start if tangent_start is not None else np.diag([5e13, K, K])
    stage = np.array([0] + [1] * m_normal + [2] * (m_shear // 2) + [3] * (m_shear - m_shear // 2))
    return _dataset(stage, disp, stress, stderr, tangent), s, tau, s_y


def test_peak_residual_friction_dilation_of_a_softening_curve():
    ds, s, tau, s_y = softening_run()
    assert np.isclose(s, s_y).any()  # the yield point is a recorded step
    props = P.shear_properties(ds)
    assert props["peak_shear_stress"].item() == pytest.approx(TAU_Y, rel=1e-12)
    assert props["peak_shear_displacement"].item() == pytest.approx(s_y, rel=1e-9)
    assert props["peak_friction"].item() == pytest.approx(TAU_Y / SIGMA_N, rel=1e-12)
    assert props["residual_shear_stress"].item() == pytest.approx(tau[-1], rel=1e-12)
    assert props["residual_friction"].item() == pytest.approx(tau[-1] / SIGMA_N, rel=1e-12)
    # central differences are exact for the quadratic Delta_1(s): atan(-(P1 - 2 Q1 s_y))
    assert props["dilation_angle_peak"].item() == pytest.approx(math.atan(-(P1 - 2 * Q1 * s_y)), rel=1e-9)
    assert props["normal_stiffness"].item() == 5e13 and props["shear_stiffness"].item() == K
    assert props["normal_stress_start"].item() == SIGMA_N
    # one-run standard errors: stress_stderr at that step; friction: sigma_1 is stress controlled (no error)
    assert props["peak_shear_stress_stderr"].item() == pytest.approx(1e6)
    assert props["peak_friction_stderr"].item() == pytest.approx(1e6 / SIGMA_N)


def test_dilation_sign_compression_then_opening():
    """Delta_1 first rises (compression: negative angle), then falls (dilation: positive angle)."""
    s = np.linspace(0, 4e-6, 11)
    d1 = 1e-6 + P1 * s - Q1 * s**2  # maximum at s = P1 / (2 Q1) = 2 um
    assert P.dilation_angle(s, d1, 1) < 0.0 < P.dilation_angle(s, d1, 9)
    assert P.dilation_angle(s, d1, 10) == pytest.approx(math.atan(-(P1 - 2 * Q1 * s[10])), rel=1e-9)  # one-sided, exact
    assert math.isnan(P.dilation_angle(np.zeros(11), d1, 3))  # no shear displacement: undefined


def test_elastic_perfectly_plastic_peak_is_the_first_yield_step_and_residual_the_plateau():
    s = np.linspace(0, 6e-6, 61)
    tau = np.minimum(K * s, TAU_Y)
    assert P.peak(tau) == int(np.argmax(s >= TAU_Y / K - 1e-18)) and tau[P.residual(tau)] == TAU_Y


@pytest.mark.parametrize("angle", [0.0, math.pi / 6, math.pi / 2, 2.0])
def test_shear_direction_is_recovered(angle):
    t = np.diag([5e13, 1e12, 3e12])
    t[1, 2] = t[2, 1] = 5e11
    ds, s, tau, s_y = softening_run(direction=angle, tangent_start=t)
    props = P.shear_properties(ds)
    e = np.array([math.cos(angle), math.sin(angle)])
    assert props["peak_shear_stress"].item() == pytest.approx(TAU_Y, rel=1e-12)
    assert props["shear_stiffness"].item() == pytest.approx(e @ t[1:, 1:] @ e, rel=1e-12)
    assert props["dilation_angle_peak"].item() == pytest.approx(math.atan(-(P1 - 2 * Q1 * s_y)), rel=1e-9)
    assert props["peak_shear_stress_stderr"].item() == pytest.approx(1e6 * math.hypot(*e), rel=1e-12)


def ellipse_run(cycles=((2e-6, 1e13), (1e-6, 3e13)), c=8e6, per_quarter=100, dissipation=None):
    """Cycles (a_i, k_i): s = a_i sin t, tau = k_i s + c cos t, t in [0, 2 pi] (closed loops, all through (0, c)).

    Loop area pi a_i c, secant stiffness k_i, damping ratio c / (2 k_i a_i).
    """
    stage, s_all, tau_all = [0, 1], [0.0, 0.0], [0.0, c]
    for i, (a, k) in enumerate(cycles):
        t = np.linspace(0, 2 * np.pi, 4 * per_quarter + 1)[1:]
        q = np.arange(1, t.size + 1)
        stage += list(2 + 3 * i + np.where(q <= per_quarter, 0, np.where(q <= 3 * per_quarter, 1, 2)))
        s_all += list(a * np.sin(t))
        tau_all += list(k * a * np.sin(t) + c * np.cos(t))
    m = len(stage)
    disp, stress = np.zeros((m, 3)), np.zeros((m, 3))
    disp[1:, 0], stress[1:, 0] = 1e-6, 100e6
    disp[:, 1], stress[:, 1] = s_all, tau_all
    tangent = np.zeros((m, 3, 3))
    tangent[1] = np.diag([1e14, 6e13, 6e13])
    return _dataset(np.array(stage), disp, stress, tangent=tangent, dissipation=dissipation)


def test_ellipse_loop_area_secant_stiffness_and_damping():
    cycles, c = ((2e-6, 1e13), (1e-6, 3e13)), 8e6
    ds = ellipse_run(cycles, c)
    for cycle, (a, k) in ((0, cycles[0]), (1, cycles[1]), (-1, cycles[1])):
        props = P.cycle_properties(ds, cycle=cycle)
        # trapezoid in s over 400 points per cycle: O(h^2) with h = 2 pi / 400, relative error ~ 1e-4
        assert props["loop_dissipation"].item() == pytest.approx(np.pi * a * c, rel=1e-3)
        assert props["secant_shear_stiffness"].item() == pytest.approx(k, rel=1e-12)  # cos t = 0 at s = +-a
        assert props["cycle_amplitude"].item() == pytest.approx(a, rel=1e-12)
        assert props["damping_ratio"].item() == pytest.approx(c / (2 * k * a), rel=1e-3)
        assert props["secant_stiffness_ratio"].item() == pytest.approx(k / 6e13, rel=1e-12)
        assert np.isnan(props["cycle_dissipation"].item())  # no dissipation variable (path-independent law)
    with pytest.raises(ValueError, match="cycle = 2 is out of range"):
        P.cycle_run(P.run_arrays(ds, {}), cycle=2)


def test_cycle_dissipation_is_the_increase_of_the_recorded_dissipation():
    ds = ellipse_run()
    diss = np.cumsum(np.full(ds.sizes["step"], 0.5))
    ds = ellipse_run(dissipation=diss)
    props = P.cycle_properties(ds)
    assert props["cycle_dissipation"].item() == pytest.approx(0.5 * 400)  # 400 increments in the last cycle


def test_loop_of_a_path_independent_curve_has_no_area():
    s = np.concatenate([np.linspace(0, 1, 11), np.linspace(1, -1, 21)[1:], np.linspace(-1, 0, 11)[1:]]) * 1e-6
    tau = 3e12 * s - 1e18 * s**2 * np.sign(s)
    assert abs(P.loop_energy(s, tau)) < 1e-12 * P.damping_ratio(1.0, 3e12, 1e-6)
    assert P.loop_energy(s, tau) == pytest.approx(0.0, abs=1e-15)


def test_replica_statistics_sem_and_single_run_fallback():
    runs = [softening_run(s_max=s_max)[0] for s_max in (6e-6, 6.5e-6, 7e-6)]
    ds = xr.concat(runs, dim="replica")
    ds["stage"] = runs[0]["stage"]
    ds["control"] = runs[0]["control"]
    ds.attrs["status"] = "complete"
    props = P.replica_statistics(P.shear_properties(ds))
    x = props["residual_shear_stress"].values
    assert props["residual_shear_stress_mean"].item() == pytest.approx(x.mean())
    assert props["residual_shear_stress_sem"].item() == pytest.approx(x.std(ddof=1) / np.sqrt(3))
    one = P.replica_statistics(P.shear_properties(runs[0]))
    assert one["peak_shear_stress_sem"].item() == pytest.approx(1e6)  # stderr of the one run
    assert np.isnan(one["dilation_angle_peak_sem"].item())  # replicas only


def test_failed_run_gives_nan_and_its_status():
    ds, *_ = softening_run()
    ds.attrs["status"] = "failed: StressNotReachableError: sigma_2 cannot be reached"
    props = P.shear_properties(ds)
    assert np.isnan(props["peak_shear_stress"].item())
    assert "StressNotReachableError" in str(props["property_note"].values)


def test_no_shear_stage_is_a_clear_error():
    ds, *_ = softening_run()
    with pytest.raises(ValueError, match=r"no recorded step in the shear stage\(s\) \[7\]"):
        P.shear_run(P.run_arrays(ds, {}), shear_stages=(7,))


def test_every_property_is_registered_with_units():
    for name in P.SHEAR_PROPERTIES + P.CYCLE_PROPERTIES:
        assert name in PROPERTY_VARIABLES and PROPERTY_VARIABLES[name].units
    ds, *_ = softening_run()
    props = P.replica_statistics(P.shear_properties(ds))
    for name, var in props.data_vars.items():
        assert var.attrs.get("long_name"), name
        assert name == "property_note" or var.attrs.get("units"), name


# -- sweeps over the load path (asperity_sim.runs.sweep) ---------------------------------------

from pathlib import Path  # noqa: E402

from asperity_sim import laws, paths, presets  # noqa: E402
from asperity_sim.errors import SceneError  # noqa: E402
from asperity_sim.runs.scene import Scene  # noqa: E402
from asperity_sim.runs import engine as EN  # noqa: E402
from asperity_sim.runs import sweep as SW  # noqa: E402

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
S_, D_ = paths.STRESS, paths.DISPLACEMENT


def _cns(sigma=500e6, d2=10e-6, inc=4):
    return paths.LoadPath((paths.Stage((S_, D_, D_), (sigma, 0, 0), inc, name="normal"),
                           paths.Stage((S_, D_, D_), (sigma, d2 / 2, 0), inc, name="shear 1"),
                           paths.Stage((S_, D_, D_), (sigma, d2, 0), inc, name="shear 2")), name="cns")


def test_apply_path_sets_normal_stress_amplitude_direction_and_cycles():
    base = _cns()
    p = SW.apply_path(base, sigma_n=20e6, amplitude=3e-6, direction=math.pi / 2, cycles=2)
    assert len(p.stages) == 5 and [s.name for s in p.stages] == ["normal", "shear 1", "shear 2", "shear 1", "shear 2"]
    assert all(s.target[0] == pytest.approx(20e6) for s in p.stages)
    assert p.stages[2].target[1] == pytest.approx(0.0, abs=1e-21) and p.stages[2].target[2] == pytest.approx(3e-6)
    assert p.stages[1].target[2] == pytest.approx(1.5e-6)
    assert SW.apply_path(base) == base
    with pytest.raises(ValueError, match="no stress-controlled sigma_1"):
        SW.apply_path(paths.three_step(5e-6), sigma_n=1e6)
    with pytest.raises(ValueError, match="no displacement-controlled shear"):
        SW.apply_path(paths.LoadPath((base.stages[0],)), amplitude=1e-6)


def test_sweep_file_with_path_quantities_units_and_errors(tmp_path):
    base = f'scene = "{(SCENARIOS / "constant_normal_shear_R1.toml").as_posix()}"\n[run]\nn = 300\n'
    f = tmp_path / "sw.toml"
    f.write_text(base + '[sweep]\nreplicas = 2\n[sweep.grid]\nsigma_n = ["10 MPa", "0.1 GPa"]\n'
                        'amplitude = ["2 um"]\ndirection = ["30 deg"]\ncycles = [1]\nlaw = ["paper", "mdr"]\n'
                        'n = [200]\n')
    sw = SW.load_sweep(f)
    assert sw.grid["sigma_n"] == (10e6, 100e6) and sw.grid["direction"] == (pytest.approx(math.pi / 6),)
    assert sw.grid["law"] == ("paper", "mdr") and sw.shape == (2, 1, 1, 1, 2, 1, 2)
    sc = sw.scene_at({"sigma_n": 10e6, "amplitude": 2e-6, "law": "mdr", "n": 200})
    assert sc.law == "mdr" and sc.n == 200 and sc.path.stages[-1].target[:2] == pytest.approx((10e6, 2e-6))
    for text, message in [
        ('sigma_n = ["-1 MPa"]', "sigma_n = -1000000.0 is out of range (valid range: > 0 Pa)"),
        ('sigma_n = ["1 um"]', "sigma_n = '1 um': expected a stress (Pa), got a length (um)"),
        ('direction = ["30 um"]', "direction = '30 um': expected an angle (rad), got a length (um)"),
        ('direction = ["30"]', "direction = '30' has no unit"),
        ('cycles = [0]', "cycles = 0 is out of range (valid range: integer in [1, 1000])"),
        ('law = ["elastic"]', "law = 'elastic' is not known (valid: paper, mdr)"),
        ('n = [1.5]', "n = 1.5 is not an integer"),
        ('n = ["100"]', "n = '100' is not an integer"),
        ('sigman = ["1 MPa"]', "unknown key 'sigman'"),
    ]:
        f.write_text(base + f"[sweep]\nreplicas = 1\n[sweep.grid]\n{text}\n")
        with pytest.raises(SceneError) as err:
            SW.load_sweep(f)
        assert message in str(err.value) and "\n" not in str(err.value), (text, str(err.value))
    # a path quantity the path cannot take: named with the grid point before anything runs
    three = tmp_path / "three.toml"
    three.write_text((SCENARIOS / "three_step_S1.toml").read_text())
    f.write_text('scene = "three.toml"\n[sweep]\nreplicas = 1\n[sweep.grid]\nsigma_n = ["1 MPa"]\n')
    with pytest.raises(SceneError, match="sweep grid point {'sigma_n': 1000000.0}: sigma_n = 1e\\+06 Pa: the path"):
        SW.load_sweep(f)


def test_path_sweep_runs_pads_shorter_paths_and_keeps_failed_points():
    scene = Scene(params=presets.S1, path=_cns(inc=2), n=300, seed=1)
    # sigma_2 prescribed above what the interface can carry at 1 MPa: that point fails, the others complete
    unreachable = paths.LoadPath((paths.Stage((S_, D_, D_), (1e6, 0, 0), 2, name="normal"),
                                  paths.Stage((S_, S_, D_), (1e6, 5e6, 0), 2, name="shear")), name="too much")
    sw = SW.Sweep(scene=scene, grid={"cycles": (1, 2), "sigma_n": (1e6, 50e6)}, seeds=(1,))
    ds = EN.run_sweep(sw, scheduler="serial")
    assert ds.sizes["step"] == 2 + 2 * 2 * 2 + 1 and ds["stress"].dims[:3] == ("cycles", "sigma_n", "replica")
    assert np.isnan(ds["stress"].sel(cycles=1).values[:, :, 7:]).all()
    assert np.isfinite(ds["stress"].sel(cycles=2).values).all()
    bad = EN.run_sweep(SW.Sweep(scene=scene.replace(path=unreachable), grid={"sigma_n": (1e6, 500e6)}, seeds=(1,)),
                       scheduler="serial")
    status = bad["status"].values[:, 0]
    assert status[0].startswith("failed: StressNotReachableError") and status[1] == "complete"
    props = P.shear_properties(bad)
    assert np.isnan(props["peak_shear_stress"].values[0, 0]) and np.isfinite(props["peak_shear_stress"].values[1, 0])
    assert "StressNotReachableError" in props["property_note"].values[0, 0]


def test_auto_engine_picks_serial_for_small_and_cluster_for_large_sweeps():
    scene = Scene(params=presets.R1, path=_cns(inc=40), n=1000, seed=1)
    small = [scene] * 4
    big_runs = [scene.replace(n=200_000, law="mdr", k=16)] * 8  # kernels use both cores serially already
    many_small = [scene.replace(n=500, law="mdr", k=8)] * 400  # Python-side work side by side pays the start
    assert EN.choose_engine(small, workers=2, cpus=2)[0] == "serial"
    assert EN.choose_engine(big_runs, workers=2, cpus=2)[0] == "serial"
    choice, reason = EN.choose_engine(many_small, workers=2, cpus=2)
    assert choice == "local" and reason.startswith("auto: estimated")
    assert EN.choose_engine(many_small, workers=2, cpus=1)[0] == "serial"  # one core: nothing to share
    assert EN.choose_engine(many_small[:1], workers=2, cpus=2)[0] == "serial"  # one run is one task
    # the model: serial = sum of runs on all threads; cluster = start + runs on cpus // workers threads, shared
    one = EN.estimate_run_seconds(many_small[0], 2)
    cost = laws.get("mdr").cost
    assert one == pytest.approx(120 * (cost.per_increment + 8 * cost.per_asperity_increment * 250))
    ds = EN.run_sweep(SW.Sweep(scene=scene.replace(path=_cns(inc=2), n=200), seeds=(1, 2)), scheduler=None)
    assert ds.attrs["engine"].startswith("serial") and "auto: estimated" in ds.attrs["engine"]


# -- envelopes and cycles (asperity_sim.runs.envelope) ----------------------------------------

from asperity_sim.runs import envelope as E  # noqa: E402
from asperity_sim.runs import figures as F  # noqa: E402
from asperity_sim.ui import cli, exits  # noqa: E402
from asperity_sim.output.netcdf import read_netcdf  # noqa: E402


def test_mohr_coulomb_fit_recovers_c_and_phi_and_its_intervals_cover_the_truth():
    c, phi = 2e6, math.radians(35.0)
    sigma = np.linspace(5e6, 100e6, 8)
    se = 0.5e6 + 0.02 * sigma  # heteroscedastic, known
    rng = np.random.default_rng(7)
    tau = c + sigma * math.tan(phi) + rng.normal(0.0, se)
    mc = E.fit_mohr_coulomb(sigma, tau, se, level=0.95)
    assert mc["cohesion_ci"][0] < c < mc["cohesion_ci"][1]
    assert mc["friction_angle_ci"][0] < phi < mc["friction_angle_ci"][1]
    assert mc["cohesion"] == pytest.approx(c, abs=3e6) and math.degrees(mc["friction_angle"]) == pytest.approx(35, abs=2)
    exact = E.fit_mohr_coulomb(sigma, c + sigma * math.tan(phi), se)  # no noise: exact, zero-width intervals
    assert exact["cohesion"] == pytest.approx(c, rel=1e-9) and exact["friction_angle"] == pytest.approx(phi, rel=1e-12)
    # coverage over 400 noisy data sets: 95 % intervals cover about 95 % of the time
    # (binomial s.d. 1.1 %: [0.92, 0.98] is about +-2.7 s.d.)
    hits_c = hits_phi = 0
    for _ in range(400):
        t = c + sigma * math.tan(phi) + rng.normal(0.0, se)
        f = E.fit_mohr_coulomb(sigma, t, se)
        hits_c += f["cohesion_ci"][0] < c < f["cohesion_ci"][1]
        hits_phi += f["friction_angle_ci"][0] < phi < f["friction_angle_ci"][1]
    assert 0.92 <= hits_c / 400 <= 0.98 and 0.92 <= hits_phi / 400 <= 0.98


def test_power_law_fit_recovers_A_and_B():
    A, B = 3e6, 0.8
    sigma = np.geomspace(1e6, 1e9, 10)
    rng = np.random.default_rng(3)
    rel = 0.03
    tau = A * (sigma / E.SIGMA_REF) ** B * np.exp(rng.normal(0.0, rel, sigma.size))
    pl = E.fit_power_law(sigma, tau, rel * tau)
    assert pl["A_ci"][0] < A < pl["A_ci"][1] and pl["B_ci"][0] < B < pl["B_ci"][1]
    exact = E.fit_power_law(sigma, A * (sigma / E.SIGMA_REF) ** B)
    assert exact["A"] == pytest.approx(A, rel=1e-9) and exact["B"] == pytest.approx(B, rel=1e-9)
    with pytest.raises(ValueError, match="2 or more points"):
        E.weighted_line([1.0], [2.0])


@pytest.mark.parametrize("text, message", [
    ("1 MPa:1 GPa:12:log", None),
    ("1 MPa:1 GPa:1:log", "--sigma-n count = '1' is out of range (valid range: integer in [2, 200])"),
    ("1 MPa:1 GPa:x:log", "count = 'x' is out of range"),
    ("1 MPa:1 GPa:4:cubic", "spacing = 'cubic' is not known (valid: log, lin)"),
    ("1 GPa:1 MPa:4:log", "start and stop are out of range (valid range: 0 < start < stop)"),
    ("1 um:1 GPa:4:log", "--sigma-n start = '1 um': expected a stress (Pa), got a length (um)"),
    ("1 MPa:1 GPa", "is not a range"),
    ("-5 MPa", "is out of range (valid range: > 0)"),
])
def test_range_syntax(text, message):
    if message is None:
        v = E.parse_range(text, "Pa", "--sigma-n")
        assert v.size == 12 and v[0] == 1e6 and v[-1] == 1e9 and np.allclose(np.diff(np.log(v)), np.log(10) / 3.6667,
                                                                              rtol=1e-3)
        assert list(E.parse_range("1 um:3 um:3:lin", "m", "a")) == pytest.approx([1e-6, 2e-6, 3e-6])
        assert list(E.parse_range("100 MPa", "Pa", "s")) == [100e6]
        return
    with pytest.raises(SceneError) as err:
        E.parse_range(text, "Pa", "--sigma-n")
    assert message in str(err.value)


def _cyclic_run(law, inc, n=2000):
    from asperity_sim import simulate

    path = E.cyclic_path(paths.Stage((S_, D_, D_), (100e6, 0, 0), 6), 0.5e-6, cycles=2, increments=inc)
    return simulate(presets.S1, path, n=n, seed=3, law=law, k=8)


def test_paper_law_dissipates_nothing_per_cycle():
    """The paper law is path independent: the loop retraces itself, W_d = 0 to round-off, damping 0."""
    props = P.cycle_properties(_cyclic_run("paper", 4))
    w_s = 0.5 * props["secant_shear_stiffness"].item() * props["cycle_amplitude"].item() ** 2
    assert abs(props["loop_dissipation"].item()) < 1e-9 * w_s and abs(props["damping_ratio"].item()) < 1e-9


def test_mdr_loop_area_converges_to_the_recorded_dissipation():
    """Loop area (trapezoid of tau ds at the interface) against the increase of ``dissipation`` (per contact):
    both are second-order in the increment, so their gap must shrink ~4x per halving (measured 3.5x, 3.3x)."""
    gaps = []
    for inc in (6, 12, 24):
        props = P.cycle_properties(_cyclic_run("mdr", inc))
        w, d = props["loop_dissipation"].item(), props["cycle_dissipation"].item()
        assert w > 0 and d > 0
        gaps.append(abs(w - d) / d)
    assert gaps[0] / gaps[1] > 2.5 and gaps[1] / gaps[2] > 2.5
    assert gaps[2] < 0.005


def test_envelope_function_dataset_csv_and_figure(tmp_path):
    scene = Scene(params=presets.R1, path=_cns(sigma=100e6, d2=20e-6, inc=5), n=800, seed=1)
    ds = E.envelope(scene, [20e6, 60e6, 200e6], replicas=2, scheduler="serial")
    assert ds["peak_shear_stress"].dims == ("sigma_n", "replica") and ds["peak_shear_stress_mean"].dims == ("sigma_n",)
    assert (ds["status"].values == "complete").all()
    np.testing.assert_allclose(ds["peak_normal_stress_mean"].values, [20e6, 60e6, 200e6], rtol=1e-6)
    assert ds["mc_friction_angle"].dims == ("strength",) and ds["mc_cohesion_low"].attrs["units"] == "Pa"
    f = ds.sel(strength="peak")
    assert f.mc_friction_angle_low <= f.mc_friction_angle <= f.mc_friction_angle_high
    for name, var in ds.data_vars.items():
        assert var.attrs.get("long_name"), name
    files = F.write_products(ds, tmp_path / "env.nc")
    back = read_netcdf(files["netcdf"])
    assert back.attrs["product"] == "envelope" and back["peak_shear_stress_mean"].attrs["units"] == "Pa"
    rows = [r for r in files["csv"].read_text().splitlines() if not r.startswith("#")]
    assert rows[0].startswith("sigma_n_Pa,replicas_complete,peak_shear_stress_Pa,peak_shear_stress_se_Pa")
    assert len(rows) == 4 and rows[1].startswith("20000000,2,")
    assert files["figure"].stat().st_size > 20_000


def test_envelope_and_cyclic_commands(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "cns.toml"
    scene.write_text((SCENARIOS / "constant_normal_shear_S1.toml").read_text().replace("increments = 40",
                                                                                       "increments = 4"))
    assert cli.main(["envelope", "cns.toml", "--sigma-n", "10 MPa:100 MPa:3:log", "--n", "500", "--replicas", "2",
                     "--serial"]) == 0
    out = capsys.readouterr().out
    assert "wrote cns_envelope.nc, cns_envelope.csv, cns_envelope.png: 6 runs (6 complete)" in out
    assert cli.main(["cyclic", "cns.toml", "--amplitude", "0.1 um:1 um:2:log", "--n", "400", "--replicas", "2",
                     "--law", "mdr", "--sigma-n", "50 MPa", "--increments", "3", "-o", "c/cyc.nc"]) == 0
    out = capsys.readouterr().out
    assert "wrote c/cyc.nc, c/cyc.csv, c/cyc.png: 4 runs (4 complete)" in out and "auto: estimated" in out
    cyc = read_netcdf(tmp_path / "c" / "cyc.nc")
    assert cyc.attrs["product"] == "cyclic" and (cyc["damping_ratio_mean"].values > 0).all()
    assert np.all(np.diff(cyc["secant_stiffness_ratio_mean"].values) < 0)  # stiffness falls with amplitude
    for argv, message in [
        (["envelope", "cns.toml", "--sigma-n", "1 MPa:1 GPa:0:log"], "--sigma-n count = '0' is out of range"),
        (["envelope", "cns.toml", "--sigma-n", "1 MPa", "--shear-stages", "9"], "--shear-stages = '9' is out of range"),
        (["envelope", "cns.toml", "--sigma-n", "1 MPa", "--level", "1.5"], "--level = 1.5 is out of range"),
        (["cyclic", "cns.toml", "--amplitude", "1 MPa"], "--amplitude = '1 MPa': expected a length (m), got a stress"),
        (["cyclic", "cns.toml", "--amplitude", "1 um", "--sigma-n", "-3 MPa"], "--sigma-n = '-3 MPa' is out of range"),
    ]:
        assert cli.main(argv) == exits.EXIT_INPUT
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err, err


@pytest.mark.slow
def test_joint_properties_scenario_quick(tmp_path, run_script):
    done = run_script("scenarios/joint_properties.py", "--quick", "--n", "600", "--outdir", tmp_path)
    assert done.returncode == 0, done.stderr
    for name in ("R1", "S1"):
        for law in ("paper", "mdr"):
            for kind in ("envelope", "cyclic"):
                for ext in ("nc", "csv", "png"):
                    assert (tmp_path / f"joint_{kind}_{name}_{law}.{ext}").stat().st_size > 0
    assert (tmp_path / "joint_properties.png").stat().st_size > 20_000
    out = done.stdout
    assert "R1 paper   at 500 MPa: k_s =" in out and "crossing mdr: S1 above R1 at first" in out


@pytest.mark.statistical
def test_sweep_command_over_law_n_and_direction_then_info_and_plot(tmp_path, monkeypatch, capsys):
    """An isotropic interface (b = c = d = 0) resists shear the same in every direction (within Monte Carlo error)."""
    monkeypatch.chdir(tmp_path)
    base = tmp_path / "base.toml"
    base.write_text((SCENARIOS / "constant_normal_shear_S1.toml").read_text().replace("increments = 40",
                                                                                      "increments = 3"))
    (tmp_path / "sw.toml").write_text('scene = "base.toml"\n[run]\nn = 800\n[sweep]\nseeds = [4]\n[sweep.grid]\n'
                                      'direction = ["0 deg", "90 deg"]\nlaw = ["paper", "mdr"]\nn = [600, 900]\n')
    assert cli.main(["sweep", "sw.toml", "--serial"]) == 0
    assert "8 runs (8 complete), dims direction = 2, law = 2, n = 2, replica = 1" in capsys.readouterr().out
    ds = read_netcdf(tmp_path / "sw.nc")
    assert list(ds["law"].values) == ["paper", "mdr"] and ds["direction"].attrs["units"] == "rad"
    d = ds["displacement"].sel(direction=ds["direction"].values[1]).values
    assert np.allclose(d[..., -1, 1], 0.0, atol=1e-18) and np.allclose(d[..., -1, 2], 50e-6)  # sheared along axis 3
    props = P.shear_properties(ds)
    tau, se = props["peak_shear_stress"].values, props["peak_shear_stress_stderr"].values
    z = (tau[0] - tau[1]) / np.hypot(se[0], se[1])
    assert np.all(np.abs(z) < 4.0) and np.all(np.abs(tau[0] - tau[1]) > 0), z  # different samples, same law
    assert cli.main(["info", "sw.nc"]) == 0 and "direction = [0 deg, 90 deg]" in capsys.readouterr().out
    assert cli.main(["plot", "sw.nc"]) == 0 and (tmp_path / "sw.png").stat().st_size > 10_000


def test_fits_skip_failed_points():
    sigma = np.array([10e6, 20e6, 40e6, 80e6, 160e6])
    tau = 1e6 + 0.7 * sigma
    tau_failed = tau.copy()
    tau_failed[2] = np.nan
    se = np.full(5, 1e5)
    f = E.fit_mohr_coulomb(sigma, tau_failed, se)
    assert f["fit"]["points"] == 4 and f["cohesion"] == pytest.approx(1e6, rel=1e-9)
    assert math.tan(f["friction_angle"]) == pytest.approx(0.7, rel=1e-12)


@pytest.mark.slow
def test_path_sweep_with_a_failing_point_gives_the_same_bits_on_a_local_cluster():
    pytest.importorskip("dask.distributed")
    unreachable = paths.LoadPath((paths.Stage((S_, D_, D_), (1e6, 0, 0), 2, name="normal"),
                                  paths.Stage((S_, S_, D_), (1e6, 5e6, 0), 2, name="shear")), name="too much")
    scene = Scene(params=presets.S1, path=unreachable, n=300, seed=1)
    sw = SW.Sweep(scene=scene, grid={"sigma_n": (1e6, 500e6), "cycles": (1, 2)}, seeds=(1, 2))
    serial = EN.run_sweep(sw, scheduler="serial")
    dask = EN.run_sweep(sw, scheduler="local", workers=2)
    assert dask.attrs["engine"].startswith("dask LocalCluster")
    assert np.array_equal(serial["status"].values, dask["status"].values)
    assert (serial["status"].sel(sigma_n=1e6).values != "complete").all()
    for v in ("stress", "displacement", "tangent"):
        assert np.array_equal(serial[v].values, dask[v].values, equal_nan=True), v


def test_python_api_errors_name_the_key():
    scene = Scene(params=presets.S1, path=_cns(inc=2), n=300, seed=1)
    with pytest.raises(SceneError, match="sweep grid: sigma_n = '10 MPa' is not a number in Pa"):
        SW.Sweep(scene=scene, grid={"sigma_n": ("10 MPa",)})
    with pytest.raises(SceneError, match=r"sweep grid: amplitude = 0.0 is out of range \(valid range: > 0 m\)"):
        SW.Sweep(scene=scene, grid={"amplitude": (0.0,)})
    with pytest.raises(ValueError, match=r"replicas = 0 is out of range \(valid range: integer in \[1, 10000\]\)"):
        E.envelope(scene, [1e6], replicas=0)
    with pytest.raises(ValueError, match=r"cycles = 0 is out of range"):
        E.cyclic_path(scene.path.stages[0], 1e-6, cycles=0)
    with pytest.raises(ValueError, match=r"level = 1.2 is out of range"):
        E.weighted_line([1, 2, 3], [1, 2, 3], level=1.2)


FAILING_SCENE = """
title = "shear stress prescribed: too much at low normal stress"
[parameters]
preset = "S1"
[run]
n = 400
seed = 2
[[path.stages]]
name = "normal"
increments = 3
sigma_1 = "100 MPa"
Delta_2 = "0 um"
Delta_3 = "0 um"
[[path.stages]]
name = "shear"
increments = 3
sigma_1 = "100 MPa"
sigma_2 = "5 MPa"
Delta_3 = "0 um"
"""


def test_envelope_command_with_a_failing_point_writes_the_others_and_exits_3(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "f.toml").write_text(FAILING_SCENE)
    code = cli.main(["envelope", "f.toml", "--sigma-n", "1 MPa:100 MPa:3:log", "--replicas", "2", "--serial"])
    out, err = capsys.readouterr()
    assert code == exits.EXIT_FAILED and "wrote f_envelope.nc" in out
    assert "2 of 6 runs did not complete" in err and "StressNotReachableError" in err and len(err.splitlines()) == 1
    ds = read_netcdf(tmp_path / "f_envelope.nc")
    assert np.isnan(ds["peak_shear_stress"].values[0]).all() and np.isfinite(ds["peak_shear_stress"].values[1:]).all()
    assert ds["peak_shear_stress_mean"].values[1:] == pytest.approx([5e6, 5e6])  # the prescribed shear stress
    rows = [r for r in (tmp_path / "f_envelope.csv").read_text().splitlines() if not r.startswith("#")]
    assert rows[1].startswith("1000000,0,,")  # no complete replica: empty fields, not numbers


def test_every_cycle_gives_each_cycle_in_closed_form():
    cycles, c = ((2e-6, 1e13), (1e-6, 3e13), (1.5e-6, 2e13)), 8e6
    by = P.every_cycle(ellipse_run(cycles, c))
    assert list(by["cycle"].values) == [1, 2, 3]
    np.testing.assert_allclose(by["secant_shear_stiffness_by_cycle"].values, [k for _, k in cycles], rtol=1e-12)
    np.testing.assert_allclose(by["loop_dissipation_by_cycle"].values, [np.pi * a * c for a, _ in cycles], rtol=1e-3)
    np.testing.assert_allclose(by["damping_ratio_by_cycle"].values, [c / (2 * k * a) for a, k in cycles], rtol=1e-3)
    assert by["loop_dissipation_by_cycle"].attrs["units"] == "J m-2"


def test_shipped_path_sweep_file():
    sw = SW.load_sweep(SCENARIOS / "sweep_path_R1.toml")
    assert sw.shape == (3, 2, 3) and sw.grid["sigma_n"] == (10e6, 100e6, 1e9) and sw.scene.law_options == {"k": 8}
    assert sw.scenes()[-1].law == "mdr" and sw.scenes()[-1].path.stages[-1].target[0] == pytest.approx(1e9)
