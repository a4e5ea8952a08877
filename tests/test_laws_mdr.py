"""The `mdr` history law on one contact, against closed forms (issue 4, item 6).

Expected values come from Cattaneo–Mindlin, the Masing rules (with memory erasure),
Mindlin–Deresiewicz for normal-load changes at fixed tangential displacement and energy
arguments, all written out here, never taken from the code.  The law converges with the
spring count k like 1/k² (midpoint springs): the tolerances below are the spring
discretisation error at the k used (checked to shrink with k).
"""

import math
import warnings

import numpy as np
import pytest
from scipy import integrate

from asperity_sim import single_contact

R, G, NU, MU = 1e-4, 30e9, 0.3, 0.5
E_STAR = G / (1 - NU)
LAM = (2 - NU) / (2 * (1 - NU))
DN = 1e-6
D_SLIP = LAM * MU * DN
F_N = 4 / 3 * E_STAR * math.sqrt(R) * DN**1.5
K = 32
TOL = 1e-3  # spring discretisation at k = 32, relative to mu f_n (error ~ 0.35/k²)


def f_cm(delta):
    """Cattaneo–Mindlin monotonic curve at constant normal force (odd in delta)."""
    x = np.minimum(np.abs(delta) / D_SLIP, 1.0)
    return np.sign(delta) * MU * F_N * (1 - (1 - x) ** 1.5)


def ramp(a, b, m):
    return np.linspace(a, b, m + 1)[1:]


def normal_then(tangential, dn=DN, m_normal=10):
    """Path: normal load to dn at zero shear, then the given delta_s sequence at constant dn."""
    t = np.asarray(tangential)
    return np.r_[np.c_[ramp(0, dn, m_normal), np.zeros(m_normal), np.zeros(m_normal)],
                 np.c_[np.full(t.size, dn), t, np.zeros(t.size)]]


def run(path, k=K):
    return single_contact(path, R, G, NU, MU, law="mdr", k=k)


def test_monotonic_cattaneo_mindlin_and_convergence_in_k():
    tang = ramp(0, 1.3 * D_SLIP, 52)
    errs = []
    for k in (8, 16, 32):
        ds = run(normal_then(tang), k)
        errs.append(np.abs(ds.force.values[10:, 1] - f_cm(tang)).max() / (MU * F_N))
        assert np.allclose(ds.force.values[:, 0][10:], F_N, rtol=1e-12)  # normal force stays Hertz
    assert errs[2] < TOL
    # ~ 1/k²: a contact keeps between k and 2k springs as it grows (coarsened by pairs), so the
    # count at the end of the loading is not exactly proportional to k; over two doublings of k
    # the error must still fall by more than half of the ideal factor 16
    assert errs[2] < errs[1] < errs[0] and errs[0] / errs[2] > 8


def test_proportional_ray_below_slip_is_elastic_and_returns_to_zero():
    c = 0.6 * LAM * MU  # delta_t / delta_n below the slip ratio
    s = np.r_[ramp(0, 1, 30), ramp(1, 0, 30)]
    path = np.c_[s * DN, np.zeros_like(s), c * s * DN]
    ds = run(path)
    assert np.all(ds.dissipation.values <= 1e-14 * ds.external_work.values.max())
    assert np.all(ds.state.values[ds.force.values[:, 0] > 0] != 3)
    assert np.all(np.abs(ds.force.values[-1]) == 0.0)
    # on the ray the tangential force is c times the normal-force integral: (2/3)(c/lam) E* ... i.e.
    # f_t = (2 E*/lam) sum h c u_i -> (c/lam) f_n in the continuum (MDR: f_n = 2 E* int u dx)
    peak = ds.force.values[29]
    assert peak[2] == pytest.approx(c / LAM * peak[0], rel=2 * TOL)


def expected_nested(d):
    """Hand-written Masing branches for 0 -> 0.8 -> 0.2 -> 0.6 -> 0.4 -> 1.0 (units of delta_slip)."""
    s = D_SLIP
    FA = f_cm(0.8 * s)
    FB = FA - 2 * f_cm((0.8 * s - 0.2 * s) / 2)
    FC = FB + 2 * f_cm((0.6 * s - 0.2 * s) / 2)
    FD = FC - 2 * f_cm((0.6 * s - 0.4 * s) / 2)
    table = {
        0.8: FA, 0.2: FB, 0.6: FC, 0.4: FD,
        0.5: FD + 2 * f_cm((0.5 * s - 0.4 * s) / 2),    # inner branch D -> E
        0.7: FB + 2 * f_cm((0.7 * s - 0.2 * s) / 2),    # inner loop closed at 0.6: back on C
        0.9: f_cm(0.9 * s),                             # loop closed at 0.8: back on the virgin curve
        1.0: f_cm(1.0 * s),
    }
    return table[d]


def test_nested_reversals_with_memory_erasure():
    s = D_SLIP
    legs = [(0.0, 0.8), (0.8, 0.2), (0.2, 0.6), (0.6, 0.4), (0.4, 1.0)]
    tang = np.concatenate([ramp(a * s, b * s, int(round(abs(b - a) * 100))) for a, b in legs])
    ds = run(normal_then(tang))
    F = ds.force.values[10:, 1]
    # indices of the probe points along the path
    checks = {0.8: 79, 0.2: 139, 0.6: 179, 0.4: 199, 0.5: 209, 0.7: 229, 0.9: 249, 1.0: 259}
    for d, i in checks.items():
        assert tang[i] == pytest.approx(d * s, rel=1e-9)
        assert F[i] == pytest.approx(expected_nested(d), abs=TOL * MU * F_N), d
    assert np.all(np.diff(ds.dissipation.values) >= 0)


def loop_energy_closed_form(amp):
    """Area of the Masing loop of amplitude amp at constant normal force (Mindlin–Deresiewicz)."""
    F_star = f_cm(amp)
    down = lambda d: F_star - 2 * f_cm((amp - d) / 2)  # noqa: E731
    up = lambda d: -F_star + 2 * f_cm((d + amp) / 2)  # noqa: E731
    # moving up the force exceeds the force moving down: the loop is walked clockwise
    with warnings.catch_warnings():  # tiny loops: the branches nearly cancel, 1e-9 is still far below need
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        return integrate.quad(lambda d: up(d) - down(d), -amp, amp, epsabs=0, epsrel=1e-9, limit=200)[0]


def cycle(amp, m=200):
    return np.r_[ramp(0, amp, m // 2), ramp(amp, -amp, m), ramp(-amp, amp, m)]


@pytest.mark.parametrize("frac", [0.3, 0.7])
def test_symmetric_cycle_masing_branch_residual_force_and_loop_energy(frac):
    amp = frac * D_SLIP
    tang = cycle(amp)
    ds = run(normal_then(tang))
    F = ds.force.values[10:, 1]
    down = slice(100, 300)
    expected = f_cm(amp) - 2 * f_cm((amp - tang[down]) / 2)
    assert np.abs(F[down] - expected).max() < TOL * MU * F_N
    # residual force at zero displacement on the unloading branch
    i0 = 100 + int(np.argmin(np.abs(tang[down])))
    assert F[i0] == pytest.approx(f_cm(amp) - 2 * f_cm(amp / 2), abs=TOL * MU * F_N)
    # the last cycle returns to the same state: its dissipation is the loop area
    W = loop_energy_closed_form(amp)
    D_cycle = ds.dissipation.values[-1] - ds.dissipation.values[10 + 99]
    work_trapz = np.sum(0.5 * (F[100:] + F[99:-1]) * np.diff(tang[99:]))
    assert work_trapz == pytest.approx(W, rel=0.02)
    assert D_cycle == pytest.approx(W, rel=0.03)


def test_small_amplitude_loop_energy_grows_as_amplitude_cubed():
    """Mindlin: W ~ amplitude³ for small amplitudes.  The springs resolve the slip annulus (width
    ~ a amp/(2 delta_slip)) only when it spans a few spacings, so the amplitudes start at 0.05."""
    amps = np.array([0.05, 0.1, 0.2]) * D_SLIP
    closed = np.array([loop_energy_closed_form(a) for a in amps])
    tiny = np.array([1e-4, 2e-4]) * D_SLIP  # the reference itself is cubic in the limit
    assert np.polyfit(np.log(tiny), np.log([loop_energy_closed_form(a) for a in tiny]), 1)[0] == \
        pytest.approx(3.0, abs=1e-3)
    energies = []
    for a in amps:
        ds = run(normal_then(cycle(a)), k=128)
        energies.append(ds.dissipation.values[-1] - ds.dissipation.values[10 + 99])
    slope = np.polyfit(np.log(amps), np.log(energies), 1)[0]
    slope_closed = np.polyfit(np.log(amps), np.log(closed), 1)[0]
    assert slope_closed == pytest.approx(3.0, abs=0.1)
    assert slope == pytest.approx(slope_closed, abs=0.1)
    assert np.allclose(energies, closed, rtol=0.1)


def test_normal_unloading_at_fixed_tangential_displacement_then_reloading():
    t0 = 0.5 * D_SLIP
    m = 40
    unload = ramp(DN, 0.4 * DN, m)
    reload = ramp(0.4 * DN, DN, m)
    path = np.r_[normal_then(ramp(0, t0, 20)),
                 np.c_[unload, np.full(m, t0), np.zeros(m)],
                 np.c_[reload, np.full(m, t0), np.zeros(m)]]
    ds = run(path)
    F = ds.force.values
    fn_un = 4 / 3 * E_STAR * math.sqrt(R) * unload**1.5
    start = 30
    ft_un = F[start:start + m, 1]
    # Mindlin–Deresiewicz: the slip annulus slides as p falls, the stick zone keeps its displacement:
    # the force is the Cattaneo–Mindlin value of the current normal load at the same displacement,
    # mu f_n [1 - (1 - t0/(lam mu delta_n))^(3/2)], and mu f_n once the whole contact slips
    x = np.minimum(t0 / (LAM * MU * unload), 1.0)
    expected = MU * fn_un * (1 - (1 - x) ** 1.5)
    assert np.abs(ft_un - expected).max() < 2 * TOL * MU * F_N
    assert np.any(x >= 1.0)  # the path does reach full slip
    assert ds.state.values[start + m - 1] == 3
    # reloading at fixed tangential displacement: new area enters unstressed, no slip, force unchanged
    ft_re = F[start + m:, 1]
    assert np.abs(ft_re - ft_un[-1]).max() < 1e-12 * MU * F_N
    d_re = ds.dissipation.values[start + m:]
    assert d_re.max() - d_re.min() <= 1e-15 * ds.external_work.values.max()


def test_normal_increase_at_fixed_tangential_displacement_does_not_slip():
    t0 = 0.6 * D_SLIP
    up = ramp(DN, 2 * DN, 30)
    path = np.r_[normal_then(ramp(0, t0, 20)), np.c_[up, np.full(30, t0), np.zeros(30)]]
    ds = run(path)
    F = ds.force.values[30:, 1]
    assert np.abs(F - f_cm(t0)).max() < TOL * MU * F_N  # tangential force unchanged
    assert np.abs(F - F[0]).max() < 1e-12 * MU * F_N
    d = ds.dissipation.values[30:]
    assert d.max() - d[0] <= 1e-15 * ds.external_work.values.max()


def test_random_closed_loops_never_produce_work():
    rng = np.random.default_rng(7)
    for _ in range(200):
        nodes = np.c_[rng.uniform(0.2, 1.5, 4) * DN, rng.uniform(-1.5, 1.5, 4) * D_SLIP]
        nodes = np.r_[nodes, nodes[:1]]
        legs = [np.c_[np.linspace(a[0], b[0], 11)[1:], np.linspace(a[1], b[1], 11)[1:]]
                for a, b in zip(nodes[:-1], nodes[1:])]
        loop = np.concatenate(legs)
        path = np.r_[np.c_[ramp(0, nodes[0, 0], 10), np.zeros(10)], loop]
        path = np.c_[path[:, 0], path[:, 1], np.zeros(len(path))]
        ds = run(path, k=16)
        F, d = ds.force.values, ds.displacement.values
        i0 = 9  # start of the loop (first node)
        work = np.sum(0.5 * (F[i0 + 1:] + F[i0:-1]) * np.diff(d[i0:], axis=0))
        recorded = ds.external_work.values[-1] - ds.external_work.values[i0]
        scale = MU * F_N * D_SLIP
        assert work >= -1e-3 * scale
        assert recorded >= -1e-12 * scale
        bal = ds.external_work.values - ds.elastic_energy.values - ds.dissipation.values
        assert np.abs(bal).max() <= 1e-9 * ds.external_work.values.max()


def turn_path(angle_deg, k):
    a = math.radians(angle_deg)
    leg1 = ramp(0, 0.6 * D_SLIP, 30)
    end = np.array([0.6 * D_SLIP, 0.0])
    direction = np.array([math.cos(a), math.sin(a)])
    leg2 = end + ramp(0, 0.8 * D_SLIP, 40)[:, None] * direction
    tang = np.r_[np.c_[leg1, np.zeros_like(leg1)], leg2]
    path = np.r_[np.c_[ramp(0, DN, 10), np.zeros((10, 2))], np.c_[np.full(len(tang), DN), tang]]
    return run(path, k)


@pytest.mark.parametrize("angle", [90, 120])
def test_direction_change_converges_in_k_and_is_non_coaxial(angle):
    forces = {k: turn_path(angle, k).force.values for k in (8, 16, 32)}
    d16 = np.abs(forces[16] - forces[32]).max()
    d8 = np.abs(forces[8] - forces[32]).max()
    assert d16 < d8 / 2 and d16 < 2 * TOL * MU * F_N
    ds = turn_path(angle, 32)
    F = ds.force.values[-1, 1:]
    D = ds.displacement.values[-1, 1:]
    a = math.radians(angle)
    increment_dir = np.array([math.cos(a), math.sin(a)])
    # after the turn the force points neither along the total displacement nor along the new direction
    cos_total = F @ D / (np.linalg.norm(F) * np.linalg.norm(D))
    cos_new = F @ increment_dir / np.linalg.norm(F)
    assert cos_total < 0.999 and cos_new < 0.999
    assert np.linalg.norm(F) <= MU * F_N * (1 + 2 * TOL)


def test_repeated_triangle_loop_shakes_down_to_a_stable_cycle():
    tri = np.array([[0.0, 0.0], [0.5, 0.0], [0.25, 0.43], [0.0, 0.0]]) * D_SLIP
    legs = [np.c_[np.linspace(a[0], b[0], 21)[1:], np.linspace(a[1], b[1], 21)[1:]] for a, b in zip(tri[:-1], tri[1:])]
    one = np.concatenate(legs)
    tang = np.concatenate([one] * 4)
    path = np.r_[np.c_[ramp(0, DN, 10), np.zeros((10, 2))], np.c_[np.full(len(tang), DN), tang]]
    ds = run(path)
    D = ds.dissipation.values[10:]
    per = [D[(i + 1) * 60 - 1] - (D[i * 60 - 1] if i else 0.0) for i in range(4)]
    assert all(p > 0 for p in per)
    assert per[3] == pytest.approx(per[2], rel=1e-3)  # stable cycle after shake-down
    F = ds.force.values[10:, 1:]
    assert np.abs(F[119] - F[179]).max() < 1e-6 * MU * F_N + 1e-3 * np.abs(F).max()


def test_block_table_of_contact_scales_is_the_per_contact_one():
    """``block_scales`` (the vectorised loop of the block kernels) gives, column by column, the values of
    ``contact_scales`` for each contact in contact (to round-off: vector code may fuse other products;
    the spring counts exactly), and finite values for a slot out of contact or free (h = 0): the
    prefetch reads the counts of every column."""
    from asperity_sim.laws.mdr import blocks, springs
    from asperity_sim.laws.mdr import trial as mdr_trial

    rng = np.random.default_rng(3)
    m = 37  # not a whole number of vectors: the loop's remainder is covered
    R_ = rng.uniform(1e-5, 1e-3, m)
    dn_c = rng.uniform(1e-8, 1e-6, m)
    dn = dn_c * rng.uniform(0.5, 1.5, m)
    h = np.sqrt(R_ * dn_c) / 16
    dn[[3, 10]] = -1e-7  # out of contact
    h[[5, 20]] = 0.0  # free slots
    dn[5] = -1e-9
    dn[20] = 1e-7  # a free slot at a positive overlap: still finite
    sc = numba_block_scales()(dn, dn_c, R_, h, 0, m, E_STAR, LAM)
    assert np.all(np.isfinite(sc))
    for i in range(m):
        if dn[i] <= 0.0 or h[i] == 0.0:
            continue
        expect = np.array(mdr_trial.contact_scales(dn[i], dn_c[i], R_[i], h[i], E_STAR, LAM), dtype=float)
        other = np.arange(blocks.N_SCALES) != blocks.S_DRHO
        np.testing.assert_allclose(sc[other, i], expect[other], rtol=1e-13, atol=0, err_msg=str(i))
        # d rho / d dn = rho (1.5 / dn - n / sum u): a difference, so round-off relative to its terms
        np.testing.assert_allclose(sc[blocks.S_DRHO, i], expect[blocks.S_DRHO], rtol=0,
                                   atol=1e-13 * abs(expect[blocks.S_RHO]) * 1.5 / dn[i], err_msg=str(i))
        assert sc[blocks.S_NIN, i] == expect[blocks.S_NIN] and sc[blocks.S_NC, i] == expect[blocks.S_NC]


def numba_block_scales():
    import numba

    from asperity_sim.laws.mdr import blocks, springs
    from asperity_sim.laws.mdr import trial as mdr_trial

    @numba.njit(error_model="numpy", fastmath=springs.FAST)
    def run(dn, dn_c, R_, h, b0, m, E_star, lam):
        return blocks.block_scales(dn, dn_c, R_, h, b0, m, E_star, lam)

    return run
