"""Orientation extent (Eq. 9) and local frames (SPEC §3–§4)."""

import math

import numpy as np
import pytest

from asperity_sim import presets
from asperity_sim.geometry import closure, frame, local_displacement, theta_m_and_slope, theta_m_array

HALF_PI = 0.5 * math.pi


def eq9(k_e, c, R):
    """SPEC §3, Eq. (9): arccos of 1 - k_e c / R clipped to [0, 1]."""
    y = 1.0 - k_e * c / R
    return math.acos(min(max(y, 0.0), 1.0))


# --------------------------------------------------------------------------- theta_m

INTERIOR = [(0.25, 1e-6, 50e-6), (0.25, 15e-6, 50e-6), (0.25, 15e-6, 5e-6), (0.25, 39e-6, 10e-6),
            (0.2, 1e-4, 8.8e-3), (0.1, 3e-6, 2e-6), (0.25, 1e-12, 1e-3)]


@pytest.mark.parametrize("k_e,c,R", INTERIOR)
def test_theta_m_numba_interior(k_e, c, R):
    th, _ = theta_m_and_slope(c, 1.0 / R, k_e)
    assert 0.0 < th < HALF_PI
    assert th == pytest.approx(eq9(k_e, c, R), rel=1e-12)
    # the defining property: cos theta_m = 1 - k_e c / R
    assert math.cos(th) == pytest.approx(1.0 - k_e * c / R, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("k_e,R", [(0.25, 50e-6), (0.1, 1e-3), (0.0, 1e-6)])
def test_theta_m_zero_at_zero_closure(k_e, R):
    assert theta_m_and_slope(0.0, 1.0 / R, k_e) == (0.0, 0.0)
    assert theta_m_array(presets.R1.replace(e=1.0), 0.0, R) == 0.0


def test_theta_m_zero_when_k_e_zero():
    # e = 0 (flat against rough): k_e = 0 and no orientation spread at any closure
    p = presets.R1.replace(e=0.0)
    assert np.all(theta_m_array(p, np.array([0.0, 1e-6, 1.0]), 50e-6) == 0.0)
    assert theta_m_and_slope(1e-3, 1.0 / 50e-6, p.k_e)[0] == 0.0


@pytest.mark.parametrize("k_e,c,R", [(0.25, 40.001e-6, 10e-6), (0.25, 41e-6, 10e-6), (0.25, 1.0, 1e-6), (0.1, 5e-5, 1e-6)])
def test_theta_m_clipped_at_half_pi(k_e, c, R):
    assert k_e * c / R >= 1.0  # premise: Eq. (9) argument clipped at 0
    th, slope = theta_m_and_slope(c, 1.0 / R, k_e)
    assert th == pytest.approx(HALF_PI, rel=1e-15)
    assert slope == 0.0  # documented: zero where clipped
    p = presets.R1.replace(e=1.0 if k_e == 0.25 else 0.5 * (1 / k_e - 2 - math.sqrt((1 / k_e - 2) ** 2 - 4)))
    assert p.k_e == pytest.approx(k_e, rel=1e-12)
    assert theta_m_array(p, c, R) == pytest.approx(HALF_PI, rel=1e-15)


@pytest.mark.parametrize("k_e,c,R", INTERIOR[:-1])
def test_theta_m_slope_vs_central_difference(k_e, c, R):
    _, slope = theta_m_and_slope(c, 1.0 / R, k_e)
    # step well inside the interior on both sides; central-difference error is O(h²)
    c_clip = R / k_e
    h = 1e-4 * min(c, c_clip - c)
    fd = (eq9(k_e, c + h, R) - eq9(k_e, c - h, R)) / (2 * h)
    assert slope > 0.0
    assert slope == pytest.approx(fd, rel=1e-6)
    # and the numba kernel's own values give the same difference quotient
    fd2 = (theta_m_and_slope(c + h, 1.0 / R, k_e)[0] - theta_m_and_slope(c - h, 1.0 / R, k_e)[0]) / (2 * h)
    assert slope == pytest.approx(fd2, rel=1e-6)


def test_theta_m_array_matches_eq9_and_numba():
    rng = np.random.default_rng(7)
    for p in (presets.R1, presets.S2, presets.R1.replace(e=0.3)):
        R = rng.uniform(*p.R_bounds, size=400)
        c = rng.uniform(0.0, 1.5 * R.max() / p.k_e, size=400)  # covers interior and clipped
        got = theta_m_array(p, c, R)
        assert got.shape == (400,)
        want = np.array([eq9(p.k_e, ci, Ri) for ci, Ri in zip(c, R)])
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
        nb = np.array([theta_m_and_slope(ci, 1.0 / Ri, p.k_e)[0] for ci, Ri in zip(c, R)])
        np.testing.assert_allclose(got, nb, rtol=1e-12, atol=0)
        assert np.all((got >= 0) & (got <= HALF_PI))
    # broadcasting: closure (m, 1) against R (n,)
    out = theta_m_array(presets.R1, np.array([[0.0], [1e-6]]), np.array([5e-6, 50e-6, 95e-6]))
    assert out.shape == (2, 3)
    assert np.all(out[0] == 0.0) and np.all(np.diff(out[1]) < 0)  # decreasing in R


def test_theta_m_monotone_in_closure():
    c = np.linspace(0.0, 500e-6, 2001)
    th = theta_m_array(presets.R1, c, 50e-6)
    assert np.all(np.diff(th) >= 0)
    assert th[0] == 0.0 and th[-1] == pytest.approx(HALF_PI)


@pytest.mark.parametrize("r_o,d1,expected", [(0.0, 1e-6, 1e-6), (0.0, -1e-6, 0.0), (1e-4, -3e-5, 7e-5),
                                             (1e-4, -2e-4, 0.0)])
def test_closure(r_o, d1, expected):
    p = presets.R1.replace(r_o=r_o)
    assert closure(p, d1) == pytest.approx(expected, rel=1e-14, abs=1e-30)


# --------------------------------------------------------------------------- frame and local displacement

def random_angles(n, seed=11):
    rng = np.random.default_rng(seed)
    th = rng.uniform(0.0, HALF_PI, n)
    ph = rng.uniform(0.0, 2 * np.pi, n)
    th[:4] = [0.0, HALF_PI, 0.3, HALF_PI]
    ph[:4] = [0.0, 0.0, np.pi, 1.5 * np.pi]
    return th, ph


def test_frame_matches_spec_formulas():
    th, ph = random_angles(500)
    n, s, t = frame(th, ph)
    assert n.shape == s.shape == t.shape == (500, 3)
    ct, st, cp, sp = np.cos(th), np.sin(th), np.cos(ph), np.sin(ph)
    np.testing.assert_allclose(n, np.c_[ct, st * cp, st * sp], atol=1e-15)
    np.testing.assert_allclose(s, np.c_[-st, ct * cp, ct * sp], atol=1e-15)
    np.testing.assert_allclose(t, np.c_[np.zeros_like(ct), -sp, cp], atol=1e-15)


def test_frame_orthonormal_and_right_handed():
    th, ph = random_angles(500)
    n, s, t = frame(th, ph)
    M = np.stack([n, s, t], axis=-2)  # rows n, s, t
    np.testing.assert_allclose(M @ np.swapaxes(M, -1, -2), np.broadcast_to(np.eye(3), M.shape), atol=1e-14)
    # SPEC §4 frame: n x s = t, i.e. (n, s, t) is right-handed
    np.testing.assert_allclose(np.cross(n, s), t, atol=1e-14)
    np.testing.assert_allclose(np.cross(s, t), n, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(M), 1.0, atol=1e-14)


def test_frame_geometry():
    """n is the unit vector at polar angle theta from axis 1 and azimuth phi in the 2-3 plane;
    s = dn/dtheta and t = (dn/dphi)/sin(theta) (checked by central differences)."""
    th, ph = random_angles(200)
    th = np.clip(th, 0.05, HALF_PI - 0.05)
    n, s, t = frame(th, ph)
    np.testing.assert_allclose(n[:, 0], np.cos(th), atol=1e-15)  # angle to the interface normal
    np.testing.assert_allclose(np.arctan2(n[:, 2], n[:, 1]) % (2 * np.pi), ph % (2 * np.pi), atol=1e-12)
    h = 1e-6
    dn_dth = (frame(th + h, ph)[0] - frame(th - h, ph)[0]) / (2 * h)
    dn_dph = (frame(th, ph + h)[0] - frame(th, ph - h)[0]) / (2 * h)
    np.testing.assert_allclose(dn_dth, s, atol=1e-9)
    np.testing.assert_allclose(dn_dph / np.sin(th)[:, None], t, atol=1e-9)


def test_frame_flat_contact():
    # theta = 0: n is the interface normal e1 and s = (0, cos phi, sin phi)
    n, s, t = frame(0.0, 0.7)
    np.testing.assert_allclose(n, [1, 0, 0], atol=1e-16)
    np.testing.assert_allclose(s, [0, math.cos(0.7), math.sin(0.7)], atol=1e-16)
    np.testing.assert_allclose(t, [0, -math.sin(0.7), math.cos(0.7)], atol=1e-16)


def test_local_displacement_is_projection_on_frame():
    th, ph = random_angles(1000, seed=5)
    rng = np.random.default_rng(6)
    D = rng.normal(scale=10e-6, size=(1000, 3))
    r = rng.gamma(4.0, 3e-6, size=1000)
    n, s, t = frame(th, ph)
    d = np.c_[D[:, 0] - r, D[:, 1], D[:, 2]]  # SPEC §4: d = (Delta_1 - r, Delta_2, Delta_3)
    want = np.c_[np.einsum("ij,ij->i", n, d), np.einsum("ij,ij->i", s, d), np.einsum("ij,ij->i", t, d)]
    got = np.array([local_displacement(d[i, 0], d[i, 1], d[i, 2], math.cos(th[i]), math.sin(th[i]),
                                       math.cos(ph[i]), math.sin(ph[i])) for i in range(1000)])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-19)
    # a rotation preserves length
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), np.linalg.norm(d, axis=1), rtol=1e-12)


def test_local_displacement_limits():
    # flat asperity (theta = 0): normal part is the closure, tangential parts are the shear
    dn, ds, dt = local_displacement(2.0, 3.0, 4.0, 1.0, 0.0, 1.0, 0.0)
    assert (dn, ds, dt) == (2.0, 3.0, 4.0)
    # theta = pi/2, phi = pi/2: n = e3, s = -e1, t = -e2
    dn, ds, dt = local_displacement(2.0, 3.0, 4.0, 0.0, 1.0, 0.0, 1.0)
    assert (dn, ds, dt) == (4.0, -2.0, -3.0)



def test_series_trigonometry_matches_libm():
    """The libm-free sin, cos and arccos of the vectorised kernel against numpy (libm), to 4 ulp."""
    from asperity_sim.vectormath import acos_unit, sin_cos_quarter

    x = np.concatenate([np.linspace(0.0, HALF_PI, 4001), [1e-300, 1e-8, HALF_PI]])
    sc = np.array([sin_cos_quarter(v) for v in x])
    assert np.max(np.abs(sc[:, 0] - np.sin(x))) <= 4 * np.finfo(float).eps
    assert np.max(np.abs(sc[:, 1] - np.cos(x))) <= 4 * np.finfo(float).eps
    y = np.concatenate([np.linspace(0.0, 1.0, 4001), [0.5, np.nextafter(0.5, 1.0), 1.0 - 1e-12, 1e-300]])
    a = np.array([acos_unit(v) for v in y])
    assert np.max(np.abs(a - np.arccos(y))) <= 4 * np.finfo(float).eps
    assert acos_unit(1.0) == 0.0


def test_fsqrt_is_the_correctly_rounded_square_root():
    import numba

    from asperity_sim.vectormath import fsqrt

    root = numba.njit(lambda v: fsqrt(v))
    x = np.concatenate([np.geomspace(1e-300, 1e300, 2001), [0.0, 1.0, 2.0, np.nextafter(1.0, 2.0)]])
    assert all(root(v) == math.sqrt(v) for v in x)
