"""Tests of asperity_sim.analysis.surfaces: reading, composite, summits against Nayak's closed forms, fit, population.

The closed forms (Nayak 1971, isotropic Gaussian surface, profile spectral moments m0, m2, m4):
    summit density  n_s = m4 / (6 pi sqrt(3) m2)        [1/m²]
    mean summit curvature  E[-(k1 + k2)/2] = (8/3) sqrt(m4 / pi)   [1/m]
The second holds for every bandwidth alpha = m0 m4 / m2², not only as alpha -> inf: gradient
and Hessian of a stationary Gaussian field are independent, and the height (the only variable
correlated with the Hessian) is integrated out.  The moments are computed from the synthetic
heights by exact Fourier derivatives (surfaces.spectral_moments), independent of the summit finder.

Tolerances.  An 8-neighbour finder on a grid of spacing dx converges to the continuum values
with an error O((q_s dx)²) (q_s = 2 pi / short cutoff); with the short cutoff at 16 pixels,
(q_s dx)²/12 = 1.3 % is the scale of the truncation error of a second difference at the
shortest wavelength, and we allow 1.5 % bias plus three standard errors across seeds.  The
convergence itself is tested: halving the cutoff in pixels (8 px) must give a larger error.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import importlib.util

from asperity_sim import presets
from asperity_sim.analysis import surfaces as sf
from asperity_sim.analysis.surfaces import topography
from asperity_sim.sampling.population import Population

# tests that read files or generate surfaces need the optional SurfaceTopography ([surfaces] extra)
needs_st = pytest.mark.skipif(importlib.util.find_spec("SurfaceTopography") is None,
                              reason='needs SurfaceTopography: pip install "asperity-sim[surfaces]"')

L = 1e-3  # [m]


def _band(n, cutoff_px, seed):
    """A band-limited self-affine surface: short cutoff cutoff_px pixels, long cutoff 4x that."""
    dx = L / n
    return sf.synthetic(n, L, hurst=0.8, rms_height=1e-6, short_cutoff=cutoff_px * dx,
                        long_cutoff=4 * cutoff_px * dx, seed=seed)


def _ratios(n, cutoff_px, seeds):
    dens, curv = [], []
    for seed in seeds:
        s = _band(n, cutoff_px, seed)
        ref = sf.nayak(*sf.spectral_moments(s))
        sm = sf.find_summits(s)
        dens.append(sm.density / ref["summit_density"])
        curv.append(sm.curvature.mean() / ref["mean_curvature"])
    return np.array(dens), np.array(curv)


@pytest.fixture(scope="module")
def fine_ratios():
    pytest.importorskip("SurfaceTopography")
    return _ratios(1024, 16, range(4))


@pytest.mark.statistical
@needs_st
def test_summit_density_and_curvature_match_nayak(fine_ratios):
    for name, r in zip(("summit density", "mean curvature"), fine_ratios):
        se = r.std(ddof=1) / math.sqrt(r.size)
        assert abs(r.mean() - 1.0) < 0.015 + 3 * se, f"{name}: finder / Nayak = {r.mean():.4f} ± {se:.4f}"


@needs_st
def test_finder_converges_with_sampling(fine_ratios):
    coarse = _ratios(1024, 8, range(2))
    for c, f in zip(coarse, fine_ratios):
        assert abs(c.mean() - 1.0) > abs(f.mean() - 1.0)


@needs_st
def test_fit_density_is_nayak_and_stderr_is_calibrated():
    """N is the Nayak density; bootstrap stderr of alpha and R_m agrees with the spread across surfaces."""
    fits = [sf.fit(_band(512, 8, seed), bootstrap=100, seed=seed) for seed in range(8)]
    ref = sf.nayak(*sf.spectral_moments(_band(512, 8, 0)))
    N = np.array([f.params.N for f in fits])
    assert abs(N.mean() / ref["summit_density"] - 1) < 0.05  # 8 px: about 2 % below, see the module docstring
    for name in ("alpha", "R_m"):
        spread = np.std([getattr(f.params, name) for f in fits], ddof=1)
        boot = np.mean([f.stderr[name] for f in fits])
        # the sample s.d. of 8 values is within a factor 2 of the truth with probability > 0.95
        assert 0.5 < boot / spread < 2.0, f"{name}: bootstrap {boot:.3g} vs spread across surfaces {spread:.3g}"


@needs_st
def test_fit_result_fields_and_not_identified():
    s = _band(256, 8, 3)
    res = sf.fit(s, base="S1")
    p = res.params
    for name in sf.NOT_IDENTIFIED:
        assert getattr(p, name) == getattr(presets.S1, name)
        assert "not identified" in res.source_of(name) and "S1" in res.source_of(name)
    for name in sf.IDENTIFIED:
        assert res.stderr[name] > 0 and "fitted" in res.source_of(name)
    d = res.summits.depth
    assert d[0] == 0 and np.all(d >= 0)
    assert math.isclose((p.alpha + 1) * p.beta, d.mean(), rel_tol=1e-12)  # Eq. (2) mean
    assert math.isclose((p.alpha + 1) * p.beta**2, d.var(ddof=1), rel_tol=1e-12)  # Eq. (2) variance
    assert 0 < res.goodness["heights"] < 1 and 0 < res.goodness["radii"] < 1
    assert res.goodness["n"] == res.summits.n
    assert math.isclose(p.N, res.summits.n / L**2)


@needs_st
def test_ks_statistic_detects_a_wrong_distribution():
    """The KS statistic of the fit is small for gamma-like depths and large for a two-level surface."""
    s = _band(256, 8, 1)
    good = sf.fit(s).goodness["heights"]
    h = s.heights.copy()
    h += np.where(np.arange(256)[:, None] < 128, 0.0, 20 * h.std())  # two plateaus: bimodal summit depths
    bad = sf.fit(sf.Surface(h, s.physical_sizes, True), detrend_mode="mean").goodness["heights"]
    assert good < 0.1 < 0.25 < bad


def test_summit_definition_on_a_known_map():
    h = np.zeros((6, 6))
    h[0, 0] = 1.0  # corner: a summit only when the map wraps around
    h[3, 3] = 2.0
    h[3, 2] = 1.9  # neighbour of (3, 3): not a summit
    per = sf.find_summits(sf.Surface(h, (6e-6, 6e-6), periodic=True))
    assert per.n == 2 and per.height[0] == 2.0 and per.x[0] == pytest.approx(3e-6)
    assert per.curvature[0] == pytest.approx(-0.5 * ((-4.0) + (1.9 - 4.0)) / 1e-12)
    assert per.prominence[0] == pytest.approx(0.1)
    flat = sf.find_summits(sf.Surface(h, (6e-6, 6e-6), periodic=False))
    assert flat.n == 1 and flat.area == pytest.approx(16e-12)
    assert sf.find_summits(sf.Surface(h, (6e-6, 6e-6), True), min_prominence=0.5).n == 1


@needs_st
def test_plane_detrend_removes_a_tilt():
    s = _band(128, 8, 0)
    x = np.arange(128)[:, None] * 1e-8 + np.arange(128)[None, :] * 2e-8 + 3e-6
    h = topography.detrend(s.heights + x, "plane")
    assert np.allclose(h, topography.detrend(s.heights, "plane"), atol=1e-18)
    with pytest.raises(ValueError, match="detrend = 'cubic'"):
        topography.detrend(h, "cubic")


@needs_st
def test_two_surfaces_sum_and_slope():
    a, b = _band(128, 8, 0), _band(128, 8, 1)
    c = sf.composite(a, b)
    assert np.allclose(c.heights, topography.detrend(a.heights, "mean") + topography.detrend(b.heights, "mean"))
    sm = sf.find_summits(c)
    gx, gy = c.slopes
    i, j = np.rint(sm.x / c.pixel_size[0]).astype(int), np.rint(sm.y / c.pixel_size[1]).astype(int)
    assert np.allclose(sm.slope, np.hypot(gx[i, j], gy[i, j])) and np.all(sm.slope > 0)
    # periodic maps: plane detrend is the mean only (no step at the wrap-around edge)
    assert sf.composite(a).heights.mean() == pytest.approx(0, abs=1e-20)
    assert np.allclose(sf.composite(a).heights, a.heights - a.heights.mean())
    with pytest.raises(ValueError, match="grids differ"):
        sf.composite(a, _band(64, 8, 1))
    with pytest.raises(ValueError, match="physical sizes differ"):
        sf.composite(a, sf.Surface(b.heights, (L, 1.01 * L), True))


def test_too_few_summits_is_an_error():
    x = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    h = np.sin(x)[:, None] * np.sin(x)[None, :]  # 2 summits
    with pytest.raises(ValueError, match="too few to fit"):
        sf.fit(sf.Surface(h * 1e-6, (L, L), True))


@needs_st
def test_read_files_units_and_errors(tmp_path):
    s = _band(64, 8, 0)
    txt = tmp_path / "map.txt"
    np.savetxt(txt, s.heights * 1e6)  # heights in um
    with pytest.raises(ValueError, match="no physical size.*--size"):
        sf.read(txt)
    with pytest.raises(ValueError, match="no length unit.*--unit"):
        sf.read(txt, physical_sizes=(1.0, 1.0))
    r = sf.read(txt, physical_sizes=(1000.0, 1000.0), unit="um")
    assert r.physical_sizes == pytest.approx((L, L)) and np.allclose(r.heights.T, s.heights, rtol=1e-6, atol=1e-15)
    # (SurfaceTopography's axis 0 is x: a text matrix has one line per y)
    with pytest.raises(ValueError, match="no such file"):
        sf.read(tmp_path / "missing.nc")
    junk = tmp_path / "junk.dat"
    junk.write_text("hello\n")
    with pytest.raises(ValueError, match="not a topography file"):
        sf.read(junk)


@needs_st
def test_netcdf_float32_sizes_compose(tmp_path):
    """SurfaceTopography's netCDF stores sizes in float32: two such files still compose."""
    from SurfaceTopography.Generation import fourier_synthesis

    files = []
    for seed in (0, 1):
        t = fourier_synthesis((64, 64), (0.3, 0.3), hurst=0.8, rms_height=1e-3, short_cutoff=0.03, unit="mm", rng=seed)
        files.append(tmp_path / f"s{seed}.nc")
        t.to_netcdf(str(files[-1]))
    a, b = sf.read(files[0]), sf.read(files[1])
    assert a.physical_sizes[0] != 0.3e-3 and a.physical_sizes == pytest.approx((0.3e-3, 0.3e-3))
    assert sf.composite(a, b).heights.shape == (64, 64)


@needs_st
def test_synthetic_validates_and_hits_rms():
    s = sf.synthetic(128, L, hurst=0.7, rms_height=2e-6, seed=5)
    assert 0.5 < s.heights.std() / 2e-6 < 1.5  # the rms of the expected PSD, not of one realisation
    with pytest.raises(ValueError, match="hurst"):
        sf.synthetic(64, L, hurst=1.5)
    with pytest.raises(ValueError, match="nb_grid_pts"):
        sf.synthetic(4, L)
    with pytest.raises(ValueError, match="seed"):
        sf.synthetic(64, L, seed=-1)


@needs_st
def test_empirical_population_resamples_summits_jointly():
    a, b = _band(256, 8, 0), _band(256, 8, 1)
    res = sf.fit(a, b)
    pop = sf.empirical_population(res, 5000, seed=1)
    assert isinstance(pop, Population) and pop.n == 5000
    pairs = set(zip(res.summits.depth.round(18), res.summits.radius.round(12)))
    assert all((r, R) in pairs for r, R in zip(pop.r.round(18), pop.R.round(12)))
    # steeper summits get larger u: rank correlation of slope and u is +1 per summit
    by_r = {round(r, 18): u for r, u in zip(pop.r, pop.u)}
    s = res.summits
    us = np.array([by_r.get(round(d, 18), np.nan) for d in s.depth])
    ok = np.isfinite(us)
    assert np.all(np.diff(us[ok][np.argsort(s.slope[ok])]) >= -1e-12)
    # joint=False: depth and radius from independent draws (same marginals)
    ind = sf.empirical_population(res, 20000, seed=1, joint=False)
    assert set(ind.r.round(18)) <= set(res.summits.depth.round(18))
    assert set(ind.R.round(12)) <= set(res.summits.radius.round(12))
    from scipy import stats as st_

    rho_joint = st_.spearmanr(sf.empirical_population(res, 20000, seed=1).r, sf.empirical_population(res, 20000,
                                                                                                 seed=1).R).statistic
    rho_ind = st_.spearmanr(ind.r, ind.R).statistic
    assert abs(rho_ind) < 4 / math.sqrt(20000) < rho_joint
    # one surface: orientations independent of the summits, cos u uniform (isotropic base)
    pop1 = sf.empirical_population(sf.fit(a), 20000, seed=2)
    assert abs(np.cos(pop1.u).mean() - 0.5) < 4 * math.sqrt(1 / 12 / 20000)


@needs_st
def test_fit_1024_under_10_s():
    import time

    s = sf.synthetic(1024, L, hurst=0.8, rms_height=1e-6, short_cutoff=8 * L / 1024, seed=0)
    t0 = time.perf_counter()
    sf.fit(s)
    assert time.perf_counter() - t0 < 10.0


# -- command line -----------------------------------------------------------------------

def _write_pair(tmp_path, n=256):
    from SurfaceTopography.Generation import fourier_synthesis

    files = []
    for seed in (1, 2):
        t = fourier_synthesis((n, n), (0.5, 0.5), hurst=0.8, rms_height=1e-3, short_cutoff=8 * 0.5 / n,
                              unit="mm", rng=seed)
        files.append(tmp_path / f"s{seed}.nc")
        t.to_netcdf(str(files[-1]))
    return files


@needs_st
def test_cli_fit_writes_a_valid_scene_and_figure(tmp_path, capsys):
    from asperity_sim.ui.cli import main
    from asperity_sim.runs.scene import load_scene

    a, b = _write_pair(tmp_path)
    out, fig = tmp_path / "fit.toml", tmp_path / "fit.png"
    assert main(["fit", str(a), str(b), "-o", str(out), "--plot", str(fig), "--preset", "S1"]) == 0
    assert fig.stat().st_size > 10_000
    scene = load_scene(out)
    res = sf.fit(sf.read(a), sf.read(b), base="S1")
    for name in sf.IDENTIFIED:  # the scene keeps 6 significant digits
        assert getattr(scene.params, name) == pytest.approx(getattr(res.params, name), rel=1e-5)
    assert scene.params.G == presets.S1.G and scene.params.nu == presets.S1.nu
    text = out.read_text()
    # two surfaces identify e too (analysis/surfaces/pair.py): the rest comes from the preset
    assert text.count("not identified from topography: preset S1") == len(sf.NOT_IDENTIFIED) - 1
    assert "e = " in text and "fitted from the two surfaces" in text and "# Contact slopes theta" in text
    assert scene.params.e == pytest.approx(res.params.e, rel=1e-9) and res.stderr["e"] > 0
    assert 'R_m = "' in text and ' um"' in text  # quantities carry units
    printed = capsys.readouterr().out
    assert "summits" in printed and "two surfaces" in printed and "Contact slopes" in printed


@needs_st
def test_cli_fit_scene_supplies_the_rest(tmp_path):
    from asperity_sim.ui.cli import main
    from asperity_sim.runs.scene import load_scene

    a, _ = _write_pair(tmp_path, 128)
    base = tmp_path / "base.toml"
    base.write_text('[parameters]\npreset = "R2"\nmu = 0.4\n[path]\n[[path.stages]]\nincrements = 1\n'
                    'Delta_1 = "1 um"\nDelta_2 = "0 um"\nDelta_3 = "0 um"\n')
    out = tmp_path / "fit.toml"
    assert main(["fit", str(a), "-o", str(out), "--scene", str(base)]) == 0
    p = load_scene(out).params
    assert p.mu == 0.4 and p.G == presets.R2.G and p.r_o == pytest.approx(presets.R2.r_o)
    assert f"scene {base}" in out.read_text()


@needs_st
@pytest.mark.parametrize("extra, message", [
    (["missing.nc"], "no such file"),
    (["junk.dat"], "not a topography file"),
    (["plain.txt"], "no physical size.*--size"),
    (["plain.txt", "--size", "0.5"], "no length unit.*--unit"),
    (["s1.nc", "plain.txt", "--size", "0.5,0.6", "--unit", "mm"], "physical sizes differ"),
    (["s1.nc", "small.txt", "--size", "0.5", "--unit", "mm"], "grids differ"),
    (["flat.txt", "--size", "0.5", "--unit", "mm"], "too few to fit"),
    (["s1.nc", "--min-prominence", "5 GPa"], "min-prominence"),
])
def test_cli_fit_bad_input_exits_1(tmp_path, capsys, extra, message):
    from asperity_sim.ui.cli import main

    _write_pair(tmp_path, 64)
    (tmp_path / "junk.dat").write_text("hello\n")
    np.savetxt(tmp_path / "plain.txt", np.random.default_rng(0).random((64, 64)))
    np.savetxt(tmp_path / "small.txt", np.random.default_rng(0).random((32, 32)))
    np.savetxt(tmp_path / "flat.txt", np.outer(np.sin(np.linspace(0, 6.28, 64)), np.sin(np.linspace(0, 6.28, 64))))
    args = ["fit"] + [str(tmp_path / e) if e.endswith((".nc", ".txt", ".dat")) else e for e in extra]
    assert main(args + ["-o", str(tmp_path / "out.toml")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and __import__("re").search(message, err), err
    assert not (tmp_path / "out.toml").exists()


@needs_st
@pytest.mark.slow
def test_cli_fit_scene_runs(tmp_path):
    from asperity_sim.ui.cli import main

    a, b = _write_pair(tmp_path, 128)
    out = tmp_path / "fit.toml"
    assert main(["fit", str(a), str(b), "-o", str(out)]) == 0
    assert main(["run", str(out), "--n", "500", "-q", "-o", str(tmp_path / "run.nc")]) == 0


# -- BEM scenario -----------------------------------------------------------------------

@pytest.mark.slow
@needs_st
def test_bem_scenario_quick(tmp_path, run_script):
    """scenarios/bem_closure.py at tiny size: outputs with units, BEM on the intended area range."""
    pytest.importorskip("tamaas")
    import xarray as xr

    done = run_script("scenarios/bem_closure.py", "--quick", "--outdir", tmp_path)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "bem_closure.png").stat().st_size > 10_000
    ds = xr.open_dataset(tmp_path / "bem_closure.nc", engine="netcdf4")
    for v in list(ds.data_vars) + list(ds.coords):
        assert ds[v].attrs.get("units") and ds[v].attrs.get("long_name"), v
    a = ds.bem_area_fraction.values
    assert np.all(np.diff(a) > 0) and 5e-4 < a[0] < 5e-3 and 0.03 < a[-1] < 0.3  # 0.1 % .. 10 % (Persson estimate)
    assert np.all(np.diff(ds.bem_closure.values) > 0)
    # the models answer at the BEM pressures: sigma_1 at the model closure is the BEM pressure
    assert np.all(np.isfinite(ds.closure_ratio.values)) and np.all(ds.model_closure.values > 0)
    assert "| p [MPa] |" in done.stdout


def test_bem_hertz_sanity():
    """The tamaas call used by the scenario (surfaces.bem_contact) reproduces Hertz for one sphere."""
    pytest.importorskip("tamaas")
    n, size, R, E_star = 256, 1e-3, 5e-3, 100e9
    x = (np.arange(n) + 0.5) * size / n - size / 2
    h = -(x[:, None] ** 2 + x[None, :] ** 2) / (2 * R)
    p = 2e5  # mean pressure [Pa] over the cell
    closure, _, area, _ = sf.bem_contact(h, (size, size), E_star, [p], 1e-12)[:, 0]
    a = (3 * p * size**2 * R / (4 * E_star)) ** (1 / 3)  # Hertz contact radius
    assert area * size**2 == pytest.approx(math.pi * a**2, rel=0.05)
    # periodic images add a uniform compliance, so the closure is only near Hertz's a²/R
    assert closure == pytest.approx(a**2 / R, rel=0.15)


@needs_st
def test_depth_radius_dependence_is_detected():
    """Nayak: higher summits are sharper, so depth and radius are positively rank-correlated on a
    Gaussian surface, against the independence SPEC §2 assumes; the fit reports it."""
    rhos = [sf.fit(_band(512, 8, seed)).goodness["spearman_depth_radius"] for seed in range(3)]
    assert all(r > 0.1 for r in rhos), rhos


def test_missing_surfacetopography_says_how_to_install(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "SurfaceTopography", None)
    with pytest.raises(ValueError, match=r"pip install \"asperity-sim\[surfaces\]\""):
        sf.read("anything.nc")
    with pytest.raises(ValueError, match="needs SurfaceTopography"):
        sf.synthetic(64, L)


@needs_st
def test_read_fills_undefined_data_and_rejects_line_scans(tmp_path):
    h = np.random.default_rng(0).random((64, 64))
    h[10:12, 20:25] = np.nan
    np.savetxt(tmp_path / "holes.txt", h)
    s = sf.read(tmp_path / "holes.txt", physical_sizes=(1, 1), unit="mm")
    assert np.all(np.isfinite(s.heights)) and s.heights.max() <= 1e-3
    np.savetxt(tmp_path / "line.txt", h[0])
    with pytest.raises(ValueError, match="line scan"):
        sf.read(tmp_path / "line.txt", physical_sizes=(1,), unit="mm")


@needs_st
def test_window_removes_noise_summits():
    """White noise of 1 % of the rms height adds one-pixel maxima near the smooth summits; a 7x7
    window (3 pixels, well below the 16-pixel cutoff) brings the count back near the clean surface's."""
    s = _band(512, 16, 0)
    noisy = sf.Surface(s.heights + 0.01 * s.heights.std() * np.random.default_rng(1).standard_normal(s.heights.shape),
                       s.physical_sizes, True)
    clean, raw = sf.find_summits(s).n, sf.find_summits(noisy).n
    kept, clean3 = sf.find_summits(noisy, window=3).n, sf.find_summits(s, window=3).n
    assert raw > 1.5 * clean and abs(kept - clean3) < 0.05 * clean3 and abs(clean3 - clean) < 0.1 * clean, \
        (clean, raw, kept, clean3)
    with pytest.raises(ValueError, match="window"):
        sf.find_summits(s, window=0)


def test_window_border_and_prominence():
    h = np.zeros((9, 9))
    h[4, 4], h[4, 6] = 2.0, 1.5  # two maxima 2 pixels apart
    surf = sf.Surface(h, (9e-6, 9e-6), periodic=False)
    assert sf.find_summits(surf).n == 2
    one = sf.find_summits(surf, window=2)
    assert one.n == 1 and one.prominence[0] == pytest.approx(0.5) and one.area == pytest.approx(25e-12)


def test_curvature_exact_on_a_paraboloid_with_rectangular_pixels():
    """The 5-point Laplacian is exact for a quadratic: a paraboloid cap of radius R on a 96 x 64 grid
    with dx != dy gives kappa = 1/R and radius R at its apex."""
    nx, ny, Lx, Ly, R = 96, 64, 3e-4, 1e-4, 2e-3
    x = (np.arange(nx) - 40) * Lx / nx
    y = (np.arange(ny) - 30) * Ly / ny
    h = -(x[:, None] ** 2 + y[None, :] ** 2) / (2 * R)
    sm = sf.find_summits(sf.Surface(h, (Lx, Ly), periodic=False))
    assert sm.n == 1 and sm.radius[0] == pytest.approx(R, rel=1e-9)
    assert (sm.x[0], sm.y[0]) == pytest.approx((40 * Lx / nx, 30 * Ly / ny))


def test_cli_fit_without_surfacetopography_exits_1(tmp_path, capsys, monkeypatch):
    import sys

    from asperity_sim.ui.cli import main

    monkeypatch.setitem(sys.modules, "SurfaceTopography", None)
    np.savetxt(tmp_path / "m.txt", np.zeros((8, 8)))
    assert main(["fit", str(tmp_path / "m.txt"), "-o", str(tmp_path / "o.toml")]) == 1
    assert 'pip install "asperity-sim[surfaces]"' in capsys.readouterr().err
