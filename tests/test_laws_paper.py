"""The `paper` asperity law (SPEC §5, Eqs. 16–22) against its closed forms."""

import math

import numpy as np
import pytest

from asperity_sim import presets
from asperity_sim.laws.paper import paper_force, paper_local

P = presets.R1
R = 40e-6
E_STAR, LAM, MU = P.E_star, P.lam, P.mu


def force(dn, ds, dt, mu=MU):
    return np.array(paper_force(dn, ds, dt, R, E_STAR, LAM, mu))


def test_hertz_normal_force_matches_paper_form():
    # Eq. (16)-(17): f_n = lambda K delta_n^(3/2), K = 8 G sqrt(R) / (3 (2 - nu))
    G, nu = P.G, P.nu
    lam = (2 - nu) / (2 * (1 - nu))
    K = 8 * G * math.sqrt(R) / (3 * (2 - nu))
    for dn in (1e-9, 3e-7, 2e-6):
        assert force(dn, 0.0, 0.0)[0] == pytest.approx(lam * K * dn**1.5, rel=1e-13)


def test_no_force_out_of_contact():
    assert np.all(force(0.0, 1e-6, 1e-6) == 0.0)
    assert np.all(force(-1e-7, 1e-6, 0.0) == 0.0)


def test_mindlin_initial_tangential_stiffness():
    dn = 1e-6
    k0 = 4 * P.G * math.sqrt(R * dn) / (2 - P.nu)  # Mindlin, SPEC §5
    h = 1e-16
    assert force(dn, h, 0.0)[1] / h == pytest.approx(k0, rel=1e-9)
    # secant stiffness at zero shear displacement (returned by the kernel)
    assert paper_local(dn, 0.0, 0.0, math.sqrt(R), E_STAR, LAM, MU)[4] == pytest.approx(k0, rel=1e-12)


@pytest.mark.parametrize("x", [1e-9, 0.1, 0.5, 0.9, 0.999999])
def test_stick_branch_closed_form(x):
    dn = 2e-6
    d_slip = LAM * MU * dn
    dst = x * d_slip
    fn = (4 / 3) * E_STAR * math.sqrt(R) * dn**1.5
    F = MU * fn * (1 - (1 - x) ** 1.5)
    ang = 0.7
    f = force(dn, dst * math.cos(ang), dst * math.sin(ang))
    assert f[1] == pytest.approx(F * math.cos(ang), rel=1e-9)
    assert f[2] == pytest.approx(F * math.sin(ang), rel=1e-9)


def test_full_slip_is_coulomb_and_coaxial():
    dn = 1e-6
    f = force(dn, -3e-6, 4e-6)
    assert math.hypot(f[1], f[2]) == pytest.approx(MU * f[0], rel=1e-14)
    assert f[1] / f[2] == pytest.approx(-3 / 4, rel=1e-14)


def test_continuity_at_stick_slip_boundary():
    dn = 1e-6
    d_slip = LAM * MU * dn
    eps = 1e-10
    below = force(dn, d_slip * (1 - eps), 0.0)
    above = force(dn, d_slip * (1 + eps), 0.0)
    assert below[1] == pytest.approx(above[1], rel=1e-12)
    # the tangential stiffness dF/d delta_st tends to zero from the stick side
    loc_b = paper_local(dn, d_slip * (1 - eps), 0.0, math.sqrt(R), E_STAR, LAM, MU)
    loc_a = paper_local(dn, d_slip * (1 + eps), 0.0, math.sqrt(R), E_STAR, LAM, MU)
    assert not loc_b[7] and loc_a[7]
    assert loc_b[5] < 1e-4 * loc_b[4] and loc_a[5] == 0.0
    assert loc_b[6] == pytest.approx(loc_a[6], rel=1e-4)


def test_local_jacobian_against_finite_differences():
    sq = math.sqrt(R)
    for dn, ds, dt in [(1e-6, 2e-7, -1e-7), (1e-6, 0.9e-6, 0.5e-6), (2e-6, 3e-6, 1e-6)]:
        f_n, f_s, f_t, k_n, k_sec, dF_dst, dF_dn, slip = paper_local(dn, ds, dt, sq, E_STAR, LAM, MU)
        dst = math.hypot(ds, dt)
        h = 1e-13
        F = lambda a, b: math.hypot(*force(a, b, 0.0)[1:])  # noqa: E731
        assert dF_dn == pytest.approx((F(dn + h, dst) - F(dn - h, dst)) / (2 * h), rel=1e-6)
        if not slip:
            assert dF_dst == pytest.approx((F(dn, dst + h) - F(dn, dst - h)) / (2 * h), rel=1e-6)
        assert k_n == pytest.approx((force(dn + h, 0, 0)[0] - force(dn - h, 0, 0)[0]) / (2 * h), rel=1e-7)


def test_zero_friction_has_no_shear_force():
    f = force(1e-6, 1e-6, 0.0, mu=0.0)
    assert f[0] > 0 and f[1] == 0.0 and f[2] == 0.0
    f = force(1e-6, 0.0, 0.0, mu=0.0)
    assert np.all(np.isfinite(f))
