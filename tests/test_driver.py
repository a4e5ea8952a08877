"""simulate(): recording, control, the paper's paths (SPEC §6–§7), output and input checks.

Expected values come from ``Population.evaluate`` at the recorded displacement, from the
quadrature ``reference`` module, from an independent numpy implementation of SPEC §3–§5
written here (``twin_*``), from closed forms and from the paper's qualitative statements
(SPEC §7).  Monte Carlo comparisons use 4 standard errors; differences between two states
of the same population use the standard error of the per-asperity difference (from
snapshots), which accounts for their correlation.

How a stage is stepped (increment sizes, predictors, named failures: asperity_sim/stepping.py)
is tested in test_stepping.py.
"""

import math

import numpy as np
import pytest
import xarray as xr
from scipy import integrate, special
from support import single_thread

import asperity_sim
import asperity_sim.reference as reference
from asperity_sim import evaluate, paths, Population, presets, simulate, SolverSettings
from asperity_sim.output.netcdf import params_from_attrs, read_netcdf, write_netcdf
from asperity_sim.paths import LoadPath, Stage
from asperity_sim.output.variables import ASPERITY_VARIABLES, SNAPSHOT_VARIABLES, STEP_VARIABLES

N_POP = 20_000
RTOL = SolverSettings().rtol
Z = 4.0  # standard errors allowed in Monte Carlo comparisons


# --------------------------------------------------------------------------- independent twin of SPEC §3–§5


def twin_theta_follow(params, pop, d1):
    """theta = (2/pi) u theta_m(c, R), c = max(0, r_o + Delta_1) (SPEC §3)."""
    c = max(0.0, params.r_o + d1)
    k_e = params.e / (1.0 + params.e) ** 2
    theta_m = np.arccos(np.clip(1.0 - k_e * c / pop.R, 0.0, 1.0))
    return (2.0 / np.pi) * pop.u * theta_m


def twin_delta_n(pop, delta, theta):
    cp, sp = pop.cos_phi, pop.sin_phi
    return np.cos(theta) * (delta[0] - pop.r) + np.sin(theta) * (cp * delta[1] + sp * delta[2])


def twin_forces(params, pop, delta, theta):
    """Global asperity forces (n, 3) [N] from SPEC §4–§5, and the contact / full-slip masks."""
    ct, st = np.cos(theta), np.sin(theta)
    cp, sp = pop.cos_phi, pop.sin_phi
    n_vec = np.stack([ct, st * cp, st * sp], axis=1)
    s_vec = np.stack([-st, ct * cp, ct * sp], axis=1)
    t_vec = np.stack([np.zeros_like(ct), -sp, cp], axis=1)
    d = np.stack([delta[0] - pop.r, np.full_like(ct, delta[1]), np.full_like(ct, delta[2])], axis=1)
    dn = np.einsum("ij,ij->i", n_vec, d)
    ds = np.einsum("ij,ij->i", s_vec, d)
    dt = np.einsum("ij,ij->i", t_vec, d)
    contact = dn > 0.0
    dnc = np.where(contact, dn, 0.0)
    E_star = params.G / (1.0 - params.nu)
    lam = (2.0 - params.nu) / (2.0 * (1.0 - params.nu))
    fn = (4.0 / 3.0) * E_star * np.sqrt(pop.R) * dnc ** 1.5
    dst = np.hypot(ds, dt)
    dslip = lam * params.mu * dnc
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(dslip > 0, dst / dslip, np.inf)
        stick = contact & (x < 1.0)
        F = params.mu * fn * np.where(stick, 1.0 - (1.0 - np.minimum(x, 1.0)) ** 1.5, 1.0)
        fs = np.where(dst > 0, F * ds / dst, 0.0)
        ft = np.where(dst > 0, F * dt / dst, 0.0)
    f = fn[:, None] * n_vec + fs[:, None] * s_vec + ft[:, None] * t_vec
    f[~contact] = 0.0
    return f, dn, contact, contact & ~stick


def twin_stress(params, pop, delta, theta):
    f, _, contact, slip = twin_forces(params, pop, delta, theta)
    return params.N * f.sum(axis=0) / pop.n, contact, slip


def twin_theta_am(params, closure):
    """Eq. (29) by adaptive quadrature over the truncated Gaussian radius (SPEC §2–§3)."""
    k_e = params.e / (1.0 + params.e) ** 2
    lo, hi = max(params.R_m - 3 * params.R_sigma, 0.0), params.R_m + 3 * params.R_sigma
    Zn = special.ndtr((hi - params.R_m) / params.R_sigma) - special.ndtr((lo - params.R_m) / params.R_sigma)

    def f(R):
        pdf = math.exp(-0.5 * ((R - params.R_m) / params.R_sigma) ** 2) / (math.sqrt(2 * math.pi) * params.R_sigma)
        return math.acos(min(max(1.0 - k_e * closure / R, 0.0), 1.0)) * pdf / Zn

    kink = [k_e * closure] if lo < k_e * closure < hi else None
    val, _ = integrate.quad(f, lo, hi, points=kink, epsabs=1e-13, epsrel=1e-11, limit=200)
    return val


# --------------------------------------------------------------------------- shared runs


@pytest.fixture(scope="module")
def pops():
    return {name: Population.sample(presets.TABLE1[name], N_POP, seed=11) for name in ("R1", "S1")}


D3STEP = {"R1": 15e-6, "S1": 6e-6}       # SPEC §7
D2_CNS = {"R1": 40e-6, "S1": 15e-6}      # shear until the resistance no longer grows much
INC_CNS = {"R1": 40, "S1": 30}


@pytest.fixture(scope="module")
def three(pops):
    out = {}
    for name, pop in pops.items():
        out[name] = simulate(pop.params, paths.three_step(D3STEP[name], increments=10), population=pop,
                             snapshots="stage_ends")
    return out


@pytest.fixture(scope="module")
def cns(pops):
    out = {}
    for name, pop in pops.items():
        path = paths.constant_normal_shear(500e6, D2_CNS[name], increments=INC_CNS[name], normal_increments=10)
        out[name] = simulate(pop.params, path, population=pop)
    return out


def snap(ds, step):
    """Per-asperity forces (n, 3) of the snapshot taken at ``step``."""
    k = int(np.flatnonzero(ds.snapshot_step.values == step)[0])
    return ds.asperity_force.values[k]


def paired_se(ds, fa, fb, ia, ib):
    """Standard error of sigma_ia(a) - sigma_ib(b) from the per-asperity differences."""
    n = fa.shape[0]
    return ds.attrs["param_N"] * np.std(fa[:, ia] - fb[:, ib], ddof=1) / math.sqrt(n)


def stage_end(ds, stage):
    return int(np.flatnonzero(ds.stage.values == stage)[-1])


# --------------------------------------------------------------------------- dataset structure


def test_dataset_has_registry_variables_and_dims(cns):
    ds = cns["R1"]
    assert isinstance(ds, xr.Dataset)
    assert {"step", "axis", "axis_k"} <= set(ds.sizes)
    assert ds.sizes["axis"] == 3 and ds.sizes["axis_k"] == 3
    assert ds.axis.values.tolist() == [1, 2, 3] and ds.axis_k.values.tolist() == [1, 2, 3]
    for name, var in STEP_VARIABLES.items():
        assert name in ds.data_vars, name
        assert ds[name].dims == var.dims, name
        assert ds[name].dtype == np.dtype(var.dtype), name
    # no snapshots unless asked
    assert "asperity" not in ds.sizes and "snapshot" not in ds.sizes
    for name in {**ASPERITY_VARIABLES, **SNAPSHOT_VARIABLES}:
        assert name not in ds.variables
    # one record for the initial state plus one per increment (no cut-backs on this path)
    assert ds.sizes["step"] == 1 + 10 + INC_CNS["R1"]
    assert ds.step.values.tolist() == list(range(ds.sizes["step"]))
    assert ds.stage.values.tolist() == [0] + [1] * 10 + [2] * INC_CNS["R1"]
    assert np.all(ds.control.values[1:] == np.array([1, 0, 0]))
    assert np.all(ds.control.values[0] == 0)
    assert ds.attrs["status"] == "complete"
    # initial state: zero displacement, zero stress, no contact
    assert np.all(ds.displacement.values[0] == 0) and np.all(ds.stress.values[0] == 0)
    assert ds.n_contact.values[0] == 0


# --------------------------------------------------------------------------- recording = evaluate


@pytest.mark.parametrize("name", ["R1", "S1"])
def test_displacement_path_records_linear_ramp_and_evaluate(pops, three, name):
    pop, ds = pops[name], three[name]
    d = D3STEP[name]
    disp = ds.displacement.values
    # SPEC §7 ramps, 10 increments per step
    k = np.arange(1, 11) / 10
    expected = np.concatenate([
        np.stack([k * d, 0 * k, 0 * k], 1), np.stack([0 * k + d, k * d, 0 * k], 1),
        np.stack([0 * k + d, 0 * k + d, k * d], 1)])
    np.testing.assert_allclose(disp[1:], expected, rtol=1e-14, atol=1e-20)
    for i in range(ds.sizes["step"]):
        ev = evaluate(pop, disp[i])
        scale = max(np.abs(ev.stress).max(), 1.0)
        np.testing.assert_allclose(ds.stress.values[i], ev.stress, rtol=1e-12, atol=1e-12 * scale)
        np.testing.assert_allclose(ds.stress_stderr.values[i], ev.stderr, rtol=1e-9, atol=1e-12 * scale)
        np.testing.assert_allclose(ds.tangent.values[i], ev.tangent, rtol=1e-12,
                                   atol=1e-12 * max(np.abs(ev.tangent).max(), 1.0))
        assert ds.n_contact.values[i] == ev.n_contact
        assert ds.n_slip.values[i] == ev.n_slip
    assert np.all(ds.iterations.values == 0)  # nothing to solve under displacement control


@pytest.mark.parametrize("name", ["R1", "S1"])
def test_stress_controlled_stage_follows_linear_ramp(pops, cns, name):
    pop, ds = pops[name], cns[name]
    s_n = 500e6
    st = ds.stage.values
    s1 = ds.stress.values[:, 0]
    ramp = np.arange(1, 11) / 10 * s_n
    # |sigma_1 - target| <= rtol * max(|target|, max_i |sigma_i|) (the solver's stress scale), a hair of slack
    smax = np.abs(ds.stress.values).max(axis=1)
    np.testing.assert_array_less(np.abs(s1[st == 1] - ramp), 1.0001 * RTOL * np.maximum(ramp, smax[st == 1]))
    np.testing.assert_array_less(np.abs(s1[st == 2] - s_n), 1.0001 * RTOL * np.maximum(s_n, smax[st == 2]))
    # and in absolute terms far below anything physical: 1e-9 of sigma_n
    assert np.all(np.abs(s1[st == 2] - s_n) < 1e-9 * s_n)
    assert np.all(ds.residual.values <= RTOL)
    # prescribed components follow their own ramps exactly
    disp = ds.displacement.values
    assert np.all(disp[st == 1][:, 1:] == 0.0)
    k = np.arange(1, INC_CNS[name] + 1) / INC_CNS[name]
    np.testing.assert_allclose(disp[st == 2][:, 1], k * D2_CNS[name], rtol=1e-14)
    assert np.all(disp[st == 2][:, 2] == 0.0)
    # and the recorded stress is the evaluation at the recorded displacement
    for i in range(0, ds.sizes["step"], 7):
        ev = evaluate(pop, disp[i])
        np.testing.assert_allclose(ds.stress.values[i], ev.stress, rtol=1e-12, atol=1e-3)


def test_recorded_standard_errors_under_mixed_control(pops, cns, three):
    """One stress-controlled component (sigma_1): the Monte Carlo error e of the estimate moves
    the solved Delta_1 by -e_1/T_11 and sigma_2 by e_2 - (T_21/T_11) e_1 (first order).  So the
    recorded stress_stderr is 0 on sigma_1, displacement_stderr is sqrt(C_11)/|T_11| on Delta_1
    and 0 on the prescribed Delta_2, Delta_3.  Under pure displacement control the stress errors
    are the raw ones and no displacement error is recorded."""
    pop, ds = pops["R1"], cns["R1"]
    for i in (5, stage_end(ds, 1), stage_end(ds, 1) + 5, ds.sizes["step"] - 1):
        ev = evaluate(pop, ds.displacement.values[i])
        C, T = ev.covariance, ev.tangent
        np.testing.assert_allclose(np.diag(C), ev.stderr ** 2, rtol=1e-12)
        g = T[1, 0] / T[0, 0]
        h = T[2, 0] / T[0, 0]
        se = ds.stress_stderr.values[i]
        dse = ds.displacement_stderr.values[i]
        assert se[0] == 0.0
        assert se[1] == pytest.approx(math.sqrt(C[1, 1] - 2 * g * C[0, 1] + g * g * C[0, 0]), rel=1e-8)
        assert se[2] == pytest.approx(math.sqrt(C[2, 2] - 2 * h * C[0, 2] + h * h * C[0, 0]), rel=1e-8)
        assert dse[0] == pytest.approx(math.sqrt(C[0, 0]) / abs(T[0, 0]), rel=1e-8)
        assert dse[1] == 0.0 and dse[2] == 0.0
    d3 = three["R1"]
    for i in (10, 20, 30):
        ev = evaluate(pops["R1"], d3.displacement.values[i])
        np.testing.assert_allclose(d3.stress_stderr.values[i], ev.stderr, rtol=1e-9)
        assert np.all(d3.displacement_stderr.values[i] == 0.0)


def test_theta_am_and_mean_theta_recorded(pops, three):
    """theta_am against an independent quadrature of Eq. (29); mean_theta against the twin."""
    pop, ds = pops["R1"], three["R1"]
    p = pop.params
    for i in (0, 3, 10, 20, 30):
        d = ds.displacement.values[i]
        assert ds.theta_am.values[i] == pytest.approx(twin_theta_am(p, max(0.0, p.r_o + d[0])), rel=1e-7, abs=1e-12)
        th = twin_theta_follow(p, pop, d[0])
        contact = twin_delta_n(pop, d, th) > 0
        expected = th[contact].mean() if contact.any() else 0.0
        assert ds.mean_theta.values[i] == pytest.approx(expected, rel=1e-10, abs=1e-14)
    # theta_am grows with closure (Eq. 9 is increasing in c) and stays below pi/2
    th_am = ds.theta_am.values[:11]
    assert np.all(np.diff(th_am) > 0) and th_am[-1] < math.pi / 2


def test_theta_am_with_initial_closure():
    """R2 has r_o > 0: theta_am uses c = r_o + Delta_1 (SPEC §3), non-zero already at Delta = 0."""
    p = presets.R2
    ds = simulate(p, LoadPath((Stage(("d", "d", "d"), (0.1e-3, 0, 0), 2),)), n=2000, seed=1)
    for i in range(3):
        c = p.r_o + ds.displacement.values[i, 0]
        assert ds.theta_am.values[i] == pytest.approx(twin_theta_am(p, c), rel=1e-7)
    assert ds.theta_am.values[0] > 0


# --------------------------------------------------------------------------- snapshots


def test_snapshots_reproduce_recorded_stress_and_twin(pops, three):
    pop, ds = pops["R1"], three["R1"]
    p = pop.params
    assert {"asperity", "snapshot"} <= set(ds.sizes)
    assert ds.sizes["asperity"] == pop.n
    assert ds.snapshot_step.values.tolist() == [10, 20, 30]  # 'stage_ends'
    for name in ASPERITY_VARIABLES:
        assert ds[name].dims == ("asperity",)
    np.testing.assert_array_equal(ds.r.values, pop.r)
    np.testing.assert_array_equal(ds.R.values, pop.R)
    np.testing.assert_array_equal(ds.u.values, pop.u)
    np.testing.assert_allclose(np.cos(ds.phi.values), pop.cos_phi, atol=1e-14)
    np.testing.assert_allclose(np.sin(ds.phi.values), pop.sin_phi, atol=1e-14)
    weight = 1.0 / ds.attrs["n_asperities"]
    for k, step in enumerate(ds.snapshot_step.values):
        f = ds.asperity_force.values[k]
        stress = ds.stress.values[step]
        scale = np.abs(stress).max()
        np.testing.assert_allclose(ds.attrs["param_N"] * weight * f.sum(axis=0), stress, rtol=1e-10,
                                   atol=1e-10 * scale)
        d = ds.displacement.values[step]
        th = twin_theta_follow(p, pop, d[0])
        ft, dn, contact, slip = twin_forces(p, pop, d, th)
        np.testing.assert_allclose(ds.asperity_theta.values[k], th, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(ds.asperity_delta_n.values[k], dn, rtol=1e-10, atol=1e-18)
        np.testing.assert_allclose(f, ft, rtol=1e-8, atol=1e-9 * np.abs(ft).max())
        assert ds.n_contact.values[step] == contact.sum() == (ds.asperity_state.values[k] > 0).sum()
        assert ds.n_slip.values[step] == slip.sum() == (ds.asperity_state.values[k] == 3).sum()
        # the twin's stress is the recorded one as well
        np.testing.assert_allclose(p.N * ft.sum(0) / pop.n, stress, rtol=1e-8, atol=1e-8 * scale)


def test_snapshots_at_requested_steps_only(pops):
    pop = pops["S1"]
    path = paths.three_step(6e-6, increments=3)
    ds = simulate(pop.params, path, population=pop, snapshots=[0, 4])
    assert ds.snapshot_step.values.tolist() == [0, 4]
    assert ds.asperity_force.shape == (2, pop.n, 3)
    assert np.all(ds.asperity_force.values[0] == 0.0)  # no contact at Delta = 0
    f = ds.asperity_force.values[1]
    np.testing.assert_allclose(pop.params.N * f.sum(0) / pop.n, ds.stress.values[4], rtol=1e-10,
                               atol=1e-10 * np.abs(ds.stress.values[4]).max())
    with pytest.raises(ValueError, match="snapshot"):
        simulate(pop.params, path, population=pop, snapshots=[-1])
    with pytest.raises(ValueError, match="snapshot"):
        simulate(pop.params, path, population=pop, snapshots=[1.5])


# --------------------------------------------------------------------------- reference and symmetry (statistical)


@pytest.mark.statistical
@pytest.mark.parametrize("name", ["R1", "S1"])
def test_three_step_matches_reference_quadrature(three, name):
    ds = three[name]
    p = presets.TABLE1[name]
    for step in (10, 20, 30):
        d = ds.displacement.values[step]
        ref = reference.stress(p, d)
        mc, se = ds.stress.values[step], ds.stress_stderr.values[step]
        assert np.all(np.abs(mc - ref) <= Z * se + 1e-5 * np.abs(ref).max()), (step, mc, ref, se)


@pytest.mark.statistical
@pytest.mark.parametrize("name", ["R1", "S1"])
def test_isotropy_sigma2_equals_sigma3_at_end_of_step3(three, name):
    """SPEC §7 / paper: at Delta = (d, d, d) sigma_2 = sigma_3 (swap of axes 2, 3 is a symmetry)."""
    ds = three[name]
    f = snap(ds, 30)
    s = ds.stress.values[30]
    se = paired_se(ds, f, f, 1, 2)
    assert abs(s[1] - s[2]) <= Z * se, (s, se)
    assert se < 0.05 * abs(s[1])  # the comparison has power


@pytest.mark.statistical
@pytest.mark.parametrize("name", ["R1", "S1"])
def test_isotropy_shear_along_3_equals_shear_along_2(pops, three, name):
    """sigma at (d, 0, d) is sigma at (d, d, 0) with axes 2 and 3 swapped (isotropic density)."""
    pop, d = pops[name], D3STEP[name]
    path = LoadPath((Stage(("d", "d", "d"), (d, 0, 0), 2), Stage(("d", "d", "d"), (d, 0, d), 2)))
    alt = simulate(pop.params, path, population=pop)
    a = alt.stress.values[-1]
    sa = alt.stress_stderr.values[-1]
    b = three[name].stress.values[20]
    sb = three[name].stress_stderr.values[20]
    for i, j in ((0, 0), (2, 1), (1, 2)):
        assert abs(a[i] - b[j]) <= Z * (sa[i] + sb[j]), (i, a, b)


@pytest.mark.statistical
def test_sigma2_end_of_step2_is_not_sigma3_end_of_step3_for_S1(three):
    """(d, d, 0) and (d, d, d) are different states: for S1 the quadrature gives sigma_2 = 563 MPa
    vs sigma_3 = 419 MPa.  Guards the isotropy check above against a trivially relabelled step 3."""
    ds = three["S1"]
    p = presets.S1
    a, b = ds.stress.values[20, 1], ds.stress.values[30, 2]
    ra, rb = reference.stress(p, ds.displacement.values[20])[1], reference.stress(p, ds.displacement.values[30])[2]
    assert ra - rb > 0.1 * ra  # the physics says they differ
    se = paired_se(ds, snap(ds, 20), snap(ds, 30), 1, 2)
    assert a - b > Z * se


# --------------------------------------------------------------------------- SPEC §7 (a): 3-step path


@pytest.mark.statistical
def test_three_step_coupling_R1_strong_S1_weak(three):
    rel = {}
    for name, ds in three.items():
        s1a, s1b = ds.stress.values[10, 0], ds.stress.values[20, 0]
        se = paired_se(ds, snap(ds, 20), snap(ds, 10), 0, 0)
        rel[name] = ((s1b - s1a) / s1a, se / s1a)
        print(f"{name}: sigma_1 {s1a / 1e6:.1f} -> {s1b / 1e6:.1f} MPa during step 2 "
              f"(relative change {rel[name][0]:+.4f} +- {rel[name][1]:.4f})")
    # R1: sigma_1 increases during shear (strong coupling), beyond Monte Carlo error
    assert rel["R1"][0] > Z * rel["R1"][1]
    assert rel["R1"][0] > 0.05
    # S1: little coupling: its relative change is much smaller than R1's (quadrature: -1.3 % vs +16 %)
    assert abs(rel["S1"][0]) < 0.2 * rel["R1"][0]
    assert abs(rel["S1"][0]) + Z * rel["S1"][1] < 0.5 * (rel["R1"][0] - Z * rel["R1"][1])


@pytest.mark.statistical
def test_three_step_R1_hardens_above_sigma1_S1_plateaus(three):
    ds = three["R1"]
    f = snap(ds, 20)
    s = ds.stress.values[20]
    assert s[1] - s[0] > Z * paired_se(ds, f, f, 1, 0)  # sigma_2 > sigma_1 at the end of step 2
    assert s[1] > 1.2 * s[0]
    # hardening vs plateau: growth of sigma_2 over the last 30 % of step 2
    growth = {n: (d.stress.values[20, 1] - d.stress.values[17, 1]) / d.stress.values[20, 1] for n, d in three.items()}
    print("sigma_2 growth over the last 30% of step 2:", growth)
    assert growth["R1"] > 0.15
    assert growth["S1"] < 0.5 * growth["R1"]


# --------------------------------------------------------------------------- SPEC §7 (b): constant normal stress


def _ratio(ds, pop):
    """Shear resistance sigma_2/sigma_1 in stage 2 and its standard error.  sigma_1 is exact
    (stress controlled); the error of sigma_2 is the recorded delta-method one, which includes the
    error of the solved Delta_1 and the correlation of the two components (checked against the
    covariance in test_recorded_standard_errors_under_mixed_control)."""
    m = np.flatnonzero(ds.stage.values == 2)
    s = ds.stress.values[m]
    ratio = s[:, 1] / s[:, 0]
    err = ds.stress_stderr.values[m, 1] / s[:, 0]
    # sanity: the correlation-aware error is not larger than the crude bound e2 + |T21/T11| e1
    for k in (0, len(m) - 1):
        ev = evaluate(pop, ds.displacement.values[m[k]])
        crude = (ev.stderr[1] + abs(ev.tangent[1, 0] / ev.tangent[0, 0]) * ev.stderr[0]) / s[k, 0]
        assert 0 < err[k] <= crude * (1 + 1e-9)
    return ds.displacement.values[m, 1], ratio, err


@pytest.mark.statistical
def test_constant_normal_shear_S1_yields_just_above_mu(pops, cns):
    d2, ratio, err = _ratio(cns["S1"], pops["S1"])
    mu = presets.S1.mu
    print("S1 sigma_2/sigma_1:", np.round(ratio, 3).tolist())
    assert ratio[-1] - Z * err[-1] > mu
    assert ratio[-1] + Z * err[-1] < 1.2 * mu
    # sharp yield: the last third of the shear stage adds little compared with the first third
    n = len(ratio)
    first = ratio[n // 3 - 1]
    last = ratio[-1] - ratio[2 * n // 3 - 1]
    assert last < 0.1 * first


@pytest.mark.statistical
def test_constant_normal_shear_curves_cross(pops, cns):
    d2r, rr, er = _ratio(cns["R1"], pops["R1"])
    d2s, rs, es = _ratio(cns["S1"], pops["S1"])
    print("R1 sigma_2/sigma_1:", np.round(rr, 3).tolist())

    def at(d2, r, e, x):
        i = int(np.argmin(np.abs(d2 - x)))
        assert abs(d2[i] - x) < 1e-12
        return r[i], e[i]

    # small Delta_2: S1 stiffer (above R1)
    (a, ea), (b, eb) = at(d2s, rs, es, 1e-6), at(d2r, rr, er, 1e-6)
    assert a - b > Z * (ea + eb), (a, b)
    # large Delta_2: R1 above S1, at the same Delta_2 and at the end of each run
    (a, ea), (b, eb) = at(d2s, rs, es, 15e-6), at(d2r, rr, er, 15e-6)
    assert b - a > Z * (ea + eb), (a, b)
    assert rr[-1] - rs[-1] > Z * (er[-1] + es[-1])
    # R1 reaches a resistance well above mu (hardening), S1 does not
    assert rr.max() > 1.5 * presets.R1.mu


@pytest.mark.parametrize("name", ["R1", "S1"])
def test_constant_normal_shear_compresses_then_dilates(cns, name):
    ds = cns[name]
    d1 = ds.displacement.values[:, 0]
    i0 = stage_end(ds, 1)
    shear = d1[i0 + 1:]
    top = int(np.argmax(shear))
    print(f"{name}: Delta_1 at sigma_n {d1[i0] * 1e6:.4f} um, max in shear {shear[top] * 1e6:.4f} um "
          f"at step {top + 1}, final {shear[-1] * 1e6:.4f} um")
    assert shear[top] > d1[i0] * (1 + 1e-4)          # compression first
    assert 0 < top < len(shear) - 1                  # then ...
    assert shear[-1] < d1[i0] * (1 - 1e-3)           # ... dilation below the starting closure
    assert np.all(np.diff(shear[top:]) < 0)          # monotone dilation after the peak


@pytest.mark.statistical
@pytest.mark.parametrize("name", ["R1", "S1"])
def test_constant_normal_shear_matches_reference(pops, cns, name):
    """At the recorded (solved) displacement the estimate is an ordinary Monte Carlo sum: compare it
    with the quadrature using the raw standard error of the estimate there."""
    ds = cns[name]
    p = presets.TABLE1[name]
    for i in (stage_end(ds, 1), stage_end(ds, 1) + 2, ds.sizes["step"] // 2 + 5, ds.sizes["step"] - 1):
        ref = reference.stress(p, ds.displacement.values[i])
        mc, se = ds.stress.values[i], evaluate(pops[name], ds.displacement.values[i]).stderr
        assert np.all(np.abs(mc - ref) <= Z * se + 1e-5 * np.abs(ref).max()), (i, mc, ref, se)


@pytest.mark.parametrize("name", ["R1", "S1"])
def test_newton_iterations_on_paper_paths(cns, three, name):
    ds = cns[name]
    it, st = ds.iterations.values, ds.stage.values
    normal, shear = it[st == 1], it[st == 2]
    print(f"{name} constant_normal_shear Newton iterations: normal stage {normal.tolist()}, "
          f"shear stage {shear.tolist()} (max {shear.max()}, mean {shear.mean():.2f})")
    assert np.all(ds.cutbacks.values == 0)
    assert normal[0] <= 20                 # first contact from zero load (zero tangent)
    assert normal[1:].max() <= 10 and normal[1:].mean() <= 4
    assert shear.max() <= 10 and shear.mean() <= 4
    assert np.all(three[name].iterations.values == 0)


# --------------------------------------------------------------------------- interrupted runs


def test_interrupted_run_is_not_recorded_as_complete(tmp_path):
    pop = Population.sample(presets.S1, 1000, seed=1)
    out = tmp_path / "run.nc"

    def progress(stage, n_stages, fraction, step, iterations):
        if step == 2:
            raise RuntimeError("stop")

    with pytest.raises(RuntimeError, match="stop"):
        simulate(pop.params, paths.three_step(6e-6, increments=3), population=pop, output=out, progress=progress)
    assert read_netcdf(out).attrs["status"] != "complete"


# --------------------------------------------------------------------------- netCDF


def test_netcdf_round_trip(three, tmp_path):
    ds = three["R1"]  # with snapshots: every kind of variable
    path = write_netcdf(ds, tmp_path / "run.nc")
    with xr.open_dataset(path, engine="netcdf4") as back:
        back = back.load()
    assert set(back.variables) == set(ds.variables)
    for name in ds.variables:
        assert np.array_equal(back[name].values, ds[name].values), name
        assert back[name].dims == ds[name].dims
        assert back[name].attrs.keys() >= {"units", "long_name"}
        for key, val in ds[name].attrs.items():
            assert np.array_equal(np.asarray(back[name].attrs[key]), np.asarray(val)), (name, key)
    assert back.attrs.keys() == ds.attrs.keys()
    for key, val in ds.attrs.items():
        assert np.array_equal(np.asarray(back.attrs[key]), np.asarray(val)), key
    # what the run was: parameters, sample, law, policy, version
    p = presets.R1
    for name, value in p.as_dict().items():
        assert back.attrs[f"param_{name}"] == value
        assert back.attrs[f"param_{name}_units"] == p.units()[name]
    assert params_from_attrs(back.attrs) == p
    assert back.attrs["n_asperities"] == N_POP
    assert back.attrs["seed"] == 11
    assert back.attrs["sampler"] == "random"
    assert back.attrs["law"] == "paper" and back.attrs["policy"] == "follow"
    assert back.attrs["asperity_sim_version"] == asperity_sim.__version__


def test_output_argument_writes_the_returned_dataset(tmp_path):
    out = tmp_path / "ok.nc"
    ds = simulate(presets.S1, paths.three_step(6e-6, increments=2), n=1000, seed=3, output=out)
    back = read_netcdf(out)
    for name in ds.variables:
        assert np.array_equal(back[name].values, ds[name].values), name
    assert back.attrs["status"] == "complete"


# --------------------------------------------------------------------------- reproducibility


def test_same_seed_identical_other_seed_different():
    path = paths.constant_normal_shear(200e6, 5e-6, increments=3, normal_increments=3)
    a = simulate(presets.S1, path, n=3000, seed=7)
    b = simulate(presets.S1, path, n=3000, seed=7)
    c = simulate(presets.S1, path, n=3000, seed=8)
    for name in STEP_VARIABLES:
        assert np.array_equal(a[name].values, b[name].values), name
    volatile = {"history", "date_created", "wall_time_s", "wall_time_increment_loop_s"}
    assert {k: v for k, v in a.attrs.items() if k not in volatile} == \
           {k: v for k, v in b.attrs.items() if k not in volatile}
    assert not np.array_equal(a.displacement.values, c.displacement.values)


def test_sobol_sampler_recorded_and_reproducible():
    path = paths.three_step(6e-6, increments=2)
    a = simulate(presets.S1, path, n=1024, seed=3, sampler="sobol")
    b = simulate(presets.S1, path, n=1024, seed=3, sampler="sobol")
    c = simulate(presets.S1, path, n=1024, seed=3, sampler="random")
    assert a.attrs["sampler"] == "sobol" and c.attrs["sampler"] == "random"
    assert np.array_equal(a.stress.values, b.stress.values)
    assert not np.array_equal(a.stress.values, c.stress.values)


def test_result_does_not_depend_on_thread_count():
    path = paths.constant_normal_shear(200e6, 5e-6, increments=3, normal_increments=3)
    pop = Population.sample(presets.R1, 9000, seed=7)  # several assembly chunks
    a = simulate(presets.R1, path, population=pop)
    with single_thread():
        b = simulate(presets.R1, path, population=pop)
    for name in STEP_VARIABLES:
        assert np.array_equal(a[name].values, b[name].values), name


# --------------------------------------------------------------------------- policy birth (SPEC §3)


def test_policy_birth_freezes_angles_at_contact_birth():
    """Pure normal closure from zero, r_o = 0.  SPEC §3: under 'birth' an asperity keeps the angle
    it had when it entered contact, under 'follow' its angle follows theta_m(Delta_1), which grows
    with closure.  So the two agree at the first increment (every contact is new) and differ after;
    both are reproduced by the independent twin."""
    p = presets.R1
    pop = Population.sample(p, 5000, seed=9)
    path = LoadPath((Stage(("d", "d", "d"), (15e-6, 0, 0), 5),))
    fol = simulate(p, path, population=pop, policy="follow")
    bir = simulate(p, path, population=pop, policy="birth")
    assert bir.attrs["policy"] == "birth"
    np.testing.assert_array_equal(bir.displacement.values, fol.displacement.values)
    # step 1: identical
    np.testing.assert_allclose(bir.stress.values[1], fol.stress.values[1], rtol=1e-13)
    assert bir.mean_theta.values[1] == pytest.approx(fol.mean_theta.values[1], rel=1e-13)

    tb = np.full(pop.n, np.nan)
    frozen = 0
    for i in range(1, fol.sizes["step"]):
        d = fol.displacement.values[i]
        th_f = twin_theta_follow(p, pop, d[0])
        s_f, c_f, _ = twin_stress(p, pop, d, th_f)
        keep = ~np.isnan(tb) & (twin_delta_n(pop, d, np.nan_to_num(tb)) > 0)
        th_b = np.where(keep, tb, th_f)
        s_b, c_b, _ = twin_stress(p, pop, d, th_b)
        scale = abs(s_f[0])
        np.testing.assert_allclose(fol.stress.values[i], s_f, rtol=1e-9, atol=1e-9 * scale)
        np.testing.assert_allclose(bir.stress.values[i], s_b, rtol=1e-9, atol=1e-9 * scale)
        assert bir.mean_theta.values[i] == pytest.approx(th_b[c_b].mean() if c_b.any() else 0.0, rel=1e-9)
        assert bir.n_contact.values[i] == c_b.sum()
        if i >= 2 and bir.n_contact.values[i - 1] > 0:
            frozen += 1
            # frozen angles are smaller than the current extent allows
            assert bir.mean_theta.values[i] < fol.mean_theta.values[i] * (1 - 1e-3)
            assert not np.allclose(bir.stress.values[i], fol.stress.values[i], rtol=1e-9, atol=0)
        # commit (entering contact freezes, leaving contact releases)
        born = ~keep & (twin_delta_n(pop, d, th_f) > 0)
        tb = np.where(keep, tb, np.where(born, th_f, np.nan))
    assert frozen >= 3  # the comparison of frozen and following angles really happened


def test_policy_birth_releases_angles_on_leaving_contact():
    """Load to 15 um, unload to 5 um, reload to 15 um (R1).  'follow' is path independent (same
    Delta, same stress, to round-off); under 'birth' the contacts lost on unloading are released and
    reborn on reloading at the larger current angle (SPEC §3), so the state at 15 um differs from
    the first visit.  Every step is checked against the twin's bookkeeping."""
    p = presets.R1
    pop = Population.sample(p, 4000, seed=12)
    D = "d"
    path = LoadPath((Stage((D, D, D), (15e-6, 0, 0), 5), Stage((D, D, D), (5e-6, 0, 0), 2),
                     Stage((D, D, D), (15e-6, 0, 0), 2)))
    fol = simulate(p, path, population=pop, policy="follow")
    bir = simulate(p, path, population=pop, policy="birth")
    first, last = 5, bir.sizes["step"] - 1
    assert fol.displacement.values[first, 0] == fol.displacement.values[last, 0] == 15e-6
    np.testing.assert_allclose(fol.stress.values[last], fol.stress.values[first], rtol=1e-12, atol=1e-6)
    assert bir.mean_theta.values[last] > bir.mean_theta.values[first] * (1 + 1e-3)
    assert abs(bir.stress.values[last, 0] - bir.stress.values[first, 0]) > 1e-8 * bir.stress.values[first, 0]
    tb = np.full(pop.n, np.nan)
    for i in range(1, bir.sizes["step"]):
        d = bir.displacement.values[i]
        th_f = twin_theta_follow(p, pop, d[0])
        keep = ~np.isnan(tb) & (twin_delta_n(pop, d, np.nan_to_num(tb)) > 0)
        th_b = np.where(keep, tb, th_f)
        s_b, c_b, _ = twin_stress(p, pop, d, th_b)
        np.testing.assert_allclose(bir.stress.values[i], s_b, rtol=1e-9, atol=1e-9 * abs(s_b[0]))
        assert bir.n_contact.values[i] == c_b.sum()
        born = ~keep & (twin_delta_n(pop, d, th_f) > 0)
        tb = np.where(keep, tb, np.where(born, th_f, np.nan))


def test_policy_birth_runs_under_mixed_control():
    pop = Population.sample(presets.S1, 3000, seed=2)
    path = paths.constant_normal_shear(300e6, 4e-6, increments=4, normal_increments=4)
    ds = simulate(presets.S1, path, population=pop, policy="birth")
    assert ds.attrs["policy"] == "birth" and ds.attrs["status"] == "complete"
    st = ds.stage.values
    np.testing.assert_allclose(ds.stress.values[st == 1, 0], np.arange(1, 5) / 4 * 300e6, rtol=2 * RTOL)
    np.testing.assert_allclose(ds.stress.values[st == 2, 0], 300e6, rtol=2 * RTOL)
    assert np.all(ds.stress.values[st == 2, 1] > 0)


# --------------------------------------------------------------------------- bad inputs


@pytest.fixture
def no_work(monkeypatch):
    """Make any evaluation an error, so a ValueError proves the input was rejected first."""
    import asperity_sim.solve.run as drv

    def boom(*a, **k):
        raise AssertionError("simulate started working before rejecting its input")

    monkeypatch.setattr(drv, "evaluate_unchecked", boom)


GOOD_PATH = paths.three_step(1e-6, increments=1)


@pytest.mark.parametrize("kw, word", [
    ({"n": 0}, "n"), ({"n": -5}, "n"), ({"n": 2.5}, "n"), ({"n": True}, "n"), ({"n": "100"}, "n"),
    ({"law": "x"}, "law"), ({"law": None}, "law"),
    ({"policy": "x"}, "policy"), ({"policy": "Follow"}, "policy"),
    ({"sampler": "x"}, "sampler"),
    ({"seed": -1}, "seed"), ({"seed": "a"}, "seed"),
    ({"params": {"N": 1.0}}, "params"), ({"params": None}, "params"), ({"params": presets}, "params"),
    ({"path": GOOD_PATH.stages[0]}, "path"), ({"path": list(GOOD_PATH.stages)}, "path"),
    ({"path": paths.three_step}, "path"),
    ({"snapshots": "ends"}, "snapshot"), ({"snapshots": [-1]}, "snapshot"), ({"snapshots": 3}, "snapshot"),
    ({"progress": 3}, "progress"),
    ({"population": Population.sample(presets.S1, 10, seed=0)}, "population"),
])
def test_bad_inputs_raise_value_error_before_any_work(no_work, kw, word):
    args = {"params": presets.R1, "path": GOOD_PATH, "n": 100, "seed": 0}
    args.update(kw)
    with pytest.raises(ValueError, match=word):
        simulate(args.pop("params"), args.pop("path"), **args)


@pytest.mark.parametrize("kw", [{"settings": "x"}, {"population": "x"}, {"output": 3}])
def test_bad_settings_or_population_type_raise_value_error(no_work, kw):
    with pytest.raises(ValueError):
        simulate(presets.R1, GOOD_PATH, n=100, **kw)


# --------------------------------------------------------------------------- displacement-controlled increments in batches


def run_both(monkeypatch, params, path, n, **kw):
    """(batched run, stepwise run, rows evaluated in batches) of the same population and arguments."""
    from asperity_sim.solve import run as driver

    pop = Population.sample(params, n, seed=4, sampler="sobol")
    rows = []
    real = driver.evaluate_steps

    def counted(pop, deltas, ws, law):
        rows.append(len(deltas))
        return real(pop, deltas, ws, law)

    monkeypatch.setattr(driver, "evaluate_steps", counted)
    batched = simulate(params, path, population=pop, **kw)
    monkeypatch.setattr(driver, "BATCH", 0)  # no batches: every increment through the Newton loop
    stepwise = simulate(params, path, population=pop, **kw)
    return batched, stepwise, rows


def assert_same_records(a, b):
    assert set(a.data_vars) == set(b.data_vars)
    for name in a.data_vars:
        assert a[name].dtype == b[name].dtype, name
        assert np.array_equal(a[name].values, b[name].values), name


@pytest.mark.parametrize("snapshots", [None, [0, 5, 17, 18], "stage_ends"])
def test_batched_displacement_increments_are_bit_identical_to_the_loop(monkeypatch, snapshots):
    """The 3-step path of a small population: all but the stage-ending and snapshot increments go through
    batches, and every recorded variable (snapshots included) has the bits of the Newton loop's."""
    path = paths.three_step(15e-6, 10)
    batched, stepwise, rows = run_both(monkeypatch, presets.R1, path, 2**10, snapshots=snapshots)
    assert_same_records(batched, stepwise)
    taken = set() if snapshots in (None, "stage_ends") else set(snapshots) - {0}
    loop_steps = {10, 20, 30} | taken  # stage ends and snapshot steps are the loop's
    assert sum(rows) == 30 - len(loop_steps) and len(rows) >= 3


def test_batches_follow_adaptive_increments_and_leave_stress_control_to_the_loop(monkeypatch):
    S, D = "s", "d"
    path = LoadPath((Stage((D, D, D), (8e-6, 0.0, 0.0), 12, adaptive=True, max_fraction=0.3),
                     Stage((S, D, D), (80e6, 0.0, 0.0), 4),
                     Stage((D, D, D), (12e-6, 6e-6, -2e-6), 9)))
    batched, stepwise, rows = run_both(monkeypatch, presets.S1, path, 3000)
    assert_same_records(batched, stepwise)
    stage = batched.stage.values
    assert (stage == 1).sum() < 12  # the adaptive stage grew its increments, in batches too
    assert sum(rows) == (stage == 1).sum() - 1 + (stage == 3).sum() - 1


def test_batches_stop_before_checkpoints_and_the_checkpoints_match(monkeypatch, tmp_path):
    from asperity_sim.output import checkpoint as ckpt

    path = paths.three_step(15e-6, 7)
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    batched, stepwise, rows = run_both(monkeypatch, presets.R1, path, 2**9, checkpoint=a, checkpoint_every=4)
    assert rows and max(rows) <= 3
    simulate(presets.R1, path, population=Population.sample(presets.R1, 2**9, seed=4, sampler="sobol"),
             checkpoint=b, checkpoint_every=4)  # BATCH is still 0 here: stepwise
    assert_same_records(batched, stepwise)
    (meta_a, arr_a), (meta_b, arr_b) = ckpt.load(a, asperity_sim.__version__), ckpt.load(b, asperity_sim.__version__)
    assert meta_a["steps_recorded"] == meta_b["steps_recorded"] == 21
    assert arr_a.keys() == arr_b.keys()
    for key in arr_a:
        assert np.array_equal(arr_a[key], arr_b[key], equal_nan=True), key


def test_a_non_finite_batch_row_is_left_to_the_loop(monkeypatch):
    """A batch keeps the rows before the first non-finite one; the loop redoes that increment itself."""
    from asperity_sim.solve import run as driver

    real = driver.evaluate_steps

    def poisoned(pop, deltas, ws, law):
        steps = real(pop, deltas, ws, law)
        steps.rows[len(deltas) // 2:, 0] = np.nan  # the first stress component of the later rows
        return steps

    path = paths.three_step(15e-6, 10)
    pop = Population.sample(presets.R1, 2**10, seed=4, sampler="sobol")
    expected = simulate(presets.R1, path, population=pop)
    monkeypatch.setattr(driver, "evaluate_steps", poisoned)
    got = simulate(presets.R1, path, population=pop)
    assert_same_records(got, expected)
    assert np.all(np.isfinite(got.stress.values))


def test_no_batches_with_a_progress_callback_or_a_large_population(monkeypatch):
    """Each increment reaches the callback in order; populations beyond the serial kernels run the loop."""
    from asperity_sim.solve import run as driver
    from asperity_sim.kernels.layout import CHUNK, SERIAL_CHUNKS

    monkeypatch.setattr(driver, "evaluate_steps", lambda *a: pytest.fail("batch used"))
    seen = []
    simulate(presets.R1, paths.three_step(15e-6, 3), n=256, progress=lambda *a: seen.append(a[3]))
    assert seen == list(range(1, 10))
    simulate(presets.R1, paths.three_step(15e-6, 1), n=SERIAL_CHUNKS * CHUNK + 1)


def test_an_interruption_after_a_batch_checkpoints_the_loops_state(monkeypatch, tmp_path):
    """Interrupted right after the first batch (steps 1-9), the run saves the state the loop has after
    step 9 (its position and cubic-predictor point included), and resumes to the uninterrupted result."""
    from asperity_sim.output import checkpoint as ckpt
    from asperity_sim.solve import run as driver

    class Stop(Exception):
        pass

    path = paths.three_step(15e-6, 10)
    pop = Population.sample(presets.R1, 2**10, seed=4, sampler="sobol")
    full = simulate(presets.R1, path, population=pop)
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    def stop(*args):
        raise Stop

    with monkeypatch.context() as patch:
        patch.setattr(driver, "solve_increment", stop)  # at the loop's first increment, step 10
        with pytest.raises(Stop):
            simulate(presets.R1, path, population=pop, checkpoint=a)

    def stop_at_9(stage, n_stages, fraction, step, iterations):
        if step == 9:
            raise Stop

    monkeypatch.setattr(driver, "BATCH", 0)
    with pytest.raises(Stop):
        simulate(presets.R1, path, population=pop, checkpoint=b, progress=stop_at_9)
    (meta_a, arr_a), (meta_b, arr_b) = ckpt.load(a, asperity_sim.__version__), ckpt.load(b, asperity_sim.__version__)
    assert meta_a["steps_recorded"] == meta_b["steps_recorded"] == 10
    assert arr_a.keys() == arr_b.keys()
    for key in arr_a:
        assert np.array_equal(arr_a[key], arr_b[key], equal_nan=True), key
    assert_same_records(asperity_sim.resume(a), full)


# ---- contact area fraction and mean gap (per-step outputs of every run) ----

def test_mean_gap_is_the_mean_plane_depth_less_the_closure():
    p = presets.R1.replace(summit_offset=2e-6)
    ds = simulate(p, paths.constant_normal_shear(100e6, 3e-6, increments=5), n=2000, seed=3)
    np.testing.assert_array_equal(ds.mean_gap.values, p.mean_plane_depth - ds.displacement.values[:, 0])
    assert p.mean_plane_depth == (p.alpha + 1.0) * p.beta + 2e-6
    np.testing.assert_array_equal(ds.mean_gap_stderr.values, ds.displacement_stderr.values[:, 0])
    assert ds.mean_gap_stderr.values[-1] > 0.0  # sigma_1 controlled: Delta_1 carries the Monte Carlo error
    assert ds.mean_gap.attrs["units"] == "m" and ds.contact_area_fraction.attrs["units"] == "1"
    assert np.all(np.diff(ds.contact_area_fraction.values[:6]) > 0.0)  # closing adds area


@pytest.mark.statistical
def test_contact_area_stderr_under_stress_control_is_the_spread_over_populations():
    """At a prescribed sigma_1 the area estimate's error comes mostly through the solved closure; the
    recorded standard error (delta method) matches the spread of the area over 60 independent
    populations (ratio within the 99.99 % chi interval of 59 degrees of freedom), where the area's own
    standard error at the solved closure would overstate it several times."""
    from scipy import stats

    path = LoadPath((Stage(("s", "d", "d"), (50e6, 0.0, 0.0), 3),))
    area, se = [], []
    for s in range(60):
        ds = simulate(presets.R1, path, n=2000, seed=100 + s)
        area.append(ds.contact_area_fraction.values[-1])
        se.append(ds.contact_area_fraction_stderr.values[-1])
    ratio = np.std(area, ddof=1) / np.sqrt(np.mean(np.square(se)))
    lo, hi = np.sqrt(stats.chi2.ppf([5e-5, 1.0 - 5e-5], 59) / 59)
    assert lo < ratio < hi, ratio
    pop = Population.sample(presets.R1, 2000, seed=100)
    own = np.sqrt(evaluate(pop, simulate(presets.R1, path, population=pop).displacement.values[-1]).contact_area_var)
    assert own > 2.0 * se[0]
