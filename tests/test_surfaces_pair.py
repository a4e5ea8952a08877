"""asperity_sim.analysis.surfaces.pair: the curvature ratio e and the contact slopes that two surfaces give.

Exact on constructed caps; the slopes of two independent Gaussian surfaces with the same spectrum against the
closed form that follows from the independence of h1 - h2 and h1 + h2; the model's angles against Eq. (9)-(10)
in closed form; and the fit and its scene with two surfaces."""

import importlib.util
import math

import numpy as np
import pytest

from asperity_sim import presets
from asperity_sim.analysis.surfaces import Surface, find_summits, pair

needs_st = pytest.mark.skipif(importlib.util.find_spec("SurfaceTopography") is None, reason="needs SurfaceTopography")


def test_e_from_k_inverts_the_curvature_factor():
    e = np.linspace(0.0, 1.0, 11)
    assert pair.e_from_k(e / (1 + e) ** 2) == pytest.approx(e, abs=1e-7)
    assert pair.e_from_k(0.25) == pytest.approx(1.0) and pair.e_from_k(0.0) == 0.0


@pytest.mark.parametrize("k2, expected", [(1e3, 1 / 3), (3e3, 1.0), (6e3, 0.5), (0.0, 0.0), (-1e3, 0.0)])
def test_curvature_ratio_of_two_caps_is_exact(k2, expected):
    """h1 = -k1 r²/2 and h2 = -k2 r²/2 (second differences are exact on quadratics): e = min/max, 0 if one is
    flat or concave."""
    n, dx, k1 = 31, 1e-6, 3e3
    x = (np.arange(n) - n // 2) * dx
    r2 = x[:, None] ** 2 + x[None, :] ** 2
    h1 = Surface(-k1 * r2 / 2, (n * dx, n * dx), False)
    comp = Surface(-(k1 + k2) * r2 / 2, (n * dx, n * dx), False)
    sm = find_summits(comp)
    kk1, kk2, e = pair.curvature_ratio(h1, sm)
    assert kk1 == pytest.approx([k1]) and kk2 == pytest.approx([k2], abs=1e-9)
    assert e == pytest.approx([expected])


def test_model_angles_follow_eq_9_and_10():
    """One radius, isotropic orientations (cos u uniform): E[theta] = (2/pi) theta_m E[u] = (2/pi) theta_m,
    since the mean of arccos of a uniform on [0, 1] is 1."""
    params = presets.R1.replace(R_sigma=0.0, e=0.5)
    c = 3e-6
    theta = pair.model_angles(params, c, n=100_000, seed=3)
    theta_m = math.acos(1 - params.k_e * c / params.R_m)
    se = theta.std(ddof=1) / math.sqrt(theta.size)
    assert abs(theta.mean() - 2 / math.pi * theta_m) < 4 * se
    assert theta.max() <= theta_m


@needs_st
@pytest.mark.statistical
def test_contact_slopes_of_independent_surfaces_match_the_closed_form():
    """Two independent Gaussian surfaces with one spectrum: h1 - h2 is independent of h1 + h2, and at a summit of
    h1 + h2, grad h1 = grad(h1 - h2)/2.  So the slopes at the summits have the distribution of |grad(h1 - h2)|/2
    at any point: their mean is the mean of that over every pixel (same central differences), within 4 standard
    errors."""
    from asperity_sim.analysis import surfaces as sf

    dx = 1e-3 / 512
    kw = dict(hurst=0.5, rms_height=0.5e-6, short_cutoff=8 * dx, long_cutoff=128 * dx)
    a, b = (sf.synthetic(512, 1e-3, seed=s, **kw) for s in (5, 6))
    res = sf.fit(a, b, closure=1.0)  # every summit is in contact: all of them measured
    d = a.heights - b.heights
    gx = (np.roll(d, -1, 0) - np.roll(d, 1, 0)) / (2 * dx)
    gy = (np.roll(d, -1, 1) - np.roll(d, 1, 1)) / (2 * dx)
    expected = float(np.mean(np.arctan(np.hypot(gx, gy) / 2)))
    p = res.pair
    assert p["n_contacts"] == res.summits.n > 1000
    assert abs(p["theta_mean"] - expected) < 4 * p["theta_mean_stderr"], (p["theta_mean"], expected)
    # the bootstrap standard error is the textbook one, sd / sqrt(n)
    theta = np.arctan(res.summits.slope)
    assert p["theta_mean_stderr"] == pytest.approx(theta.std(ddof=1) / math.sqrt(theta.size), rel=0.2)


@needs_st
def test_fit_of_two_surfaces_fits_e_and_says_so_in_the_scene():
    from asperity_sim.analysis import surfaces as sf
    from asperity_sim.runs.scene import scene_from_dict, tomllib

    dx = 1e-3 / 256
    kw = dict(hurst=0.8, rms_height=0.5e-6, short_cutoff=8 * dx, long_cutoff=32 * dx)
    a, b = (sf.synthetic(256, 1e-3, seed=s, **kw) for s in (1, 2))
    one, two = sf.fit(a), sf.fit(a, b)
    assert one.pair is None and one.params.e == presets.R1.e and "e" not in one.stderr
    p = two.pair
    assert two.params.e == p["e"] and two.stderr["e"] == p["e_stderr"] > 0
    assert 0.0 < p["e"] < 1.0 and p["k_e"] == pytest.approx(p["e"] / (1 + p["e"]) ** 2)
    assert p["closure"] == pytest.approx(sf.fitting.default_closure(two.params))
    assert p["n_contacts"] == int(np.sum(two.summits.depth <= p["closure"]))
    text = sf.scene_text(two)
    assert "# Two surfaces: at the" in text and "# Contact slopes theta" in text
    assert "e = " in text and "fitted from the two surfaces" in text
    scene = scene_from_dict(tomllib.loads(text), source="two.toml")
    assert scene.params.e == pytest.approx(p["e"])
    assert "Two surfaces" not in sf.scene_text(one)
