"""Tests of the scale of a fit (issue 36, item 5): measured files as they come from instruments.

What is tested, and against what:
* the height step of heights rounded to a known step is recovered (and continuous heights,
  even stored in float32, have none);
* the Gaussian S-filter's summit density and mean curvature on white noise against the closed
  forms of Nayak's theory for a Gaussian-filtered white noise (derived below), so "with a cutoff
  the summit density falls as expected" has an independent reference;
* the warnings fire on a synthetic atomic-force-like scan (pixel noise, scan-line offsets,
  quantised heights) and on white noise, and not on a clean band-limited surface; the automatic
  cutoff recovers the clean surface's summits from the noisy scan;
* files in five formats SurfaceTopography reads (plain-text matrix, its netCDF, NumPy .npy,
  X3P and Gwyddion .gwy): missing-data masks, non-square pixels (an analytic lattice of
  paraboloids whose radii must come out exactly), one-dimensional profiles (a clear error),
  files without a physical size or unit (errors naming --size and --unit).

Closed forms for white noise of variance s² per pixel (area dx²) filtered by a Gaussian of
standard deviation sig (the S-filter: sig = 0.1874 cutoff): the filtered field has spectral
density s² dx² exp(-q² sig²), so its profile moments are m2 = s² dx² / (8 pi sig^4) and
m4 = 3 s² dx² / (16 pi sig^6), and Nayak's summit density m4 / (6 pi sqrt(3) m2) is
1 / (4 sqrt(3) pi sig²) (independent of s), the mean summit curvature (8/3) sqrt(m4 / pi) is
2 sqrt(3) s dx / (3 pi sig³).
"""

from __future__ import annotations

import importlib.util
import math
import warnings

import numpy as np
import pytest

from asperity_sim.analysis import surfaces as sf
from asperity_sim.analysis.surfaces import diagnosis, scale
from asperity_sim.errors import SurfaceError, SurfaceScaleWarning

pytestmark = pytest.mark.skipif(importlib.util.find_spec("SurfaceTopography") is None,
                                reason='needs SurfaceTopography: pip install "asperity-sim[surfaces]"')

NM = 1e-9
FORMATS = ("txt", "nc", "npy", "x3p", "gwy")


def _fit(*surfaces, **kw):
    """fit() and the scale warnings it issued (their messages)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SurfaceScaleWarning)
        res = sf.fit(*surfaces, bootstrap=20, **kw)
    return res, [str(w.message) for w in caught if issubclass(w.category, SurfaceScaleWarning)]


def _has(messages, text):
    return any(text in m for m in messages)


def afm_like(n=512, seed=0, noise=0.1 * NM, line=0.1 * NM, step=0.1 * NM, short=32):
    """A synthetic atomic-force scan: 1 nm pixels; a self-affine surface (rms 2 nm, H = 0.8) with a
    short cutoff of ``short`` nm (long cutoff 4 times that), plus white pixel noise, an offset per scan
    line (scan lines along x) and heights rounded to ``step``.  Returns (scan, clean), both non-periodic."""
    L = n * NM
    clean = sf.synthetic(n, L, hurst=0.8, rms_height=2 * NM, short_cutoff=short * NM, long_cutoff=4 * short * NM,
                         seed=seed)
    rng = np.random.default_rng(seed + 100)
    h = clean.heights + noise * rng.standard_normal((n, n)) + line * rng.standard_normal((1, n))
    if step:
        h = step * np.round(h / step)
    return sf.Surface(h, (L, L), False, "afm-like"), sf.Surface(clean.heights, (L, L), False, "clean")


def write(path, heights, sizes, fmt, unit="nm", mask=None):
    """Write heights [m] on a map of physical sizes [m] as ``fmt``; returns read()'s extra arguments (npy:
    the size and unit, which the format cannot hold)."""
    from SurfaceTopography import Topography

    f = {"nm": 1e-9, "um": 1e-6}[unit]
    h = heights / f
    data = h if mask is None else np.ma.masked_array(h, mask=mask)
    topo = Topography(data, tuple(s / f for s in sizes), unit=unit)
    if fmt == "npy":
        np.save(path, np.where(mask, np.nan, h) if mask is not None else h)
        return {"physical_sizes": tuple(s / f for s in sizes), "unit": unit}
    {"txt": topo.to_matrix, "nc": topo.to_netcdf, "x3p": topo.to_x3p, "gwy": topo.to_gwy}[fmt](str(path))
    return {}


# -- the height step ---------------------------------------------------------------------

def test_height_step_recovers_a_known_step():
    rng = np.random.default_rng(0)
    h = rng.standard_normal((200, 200)) * 3 * NM
    for q in (0.1 * NM, 0.37 * NM, 20 * NM / 65536):  # the last: a 16-bit converter over 20 nm
        r = q * np.round(h / q) + 1.234 * NM
        assert scale.height_step(r) == pytest.approx(q, rel=1e-6)
        assert scale.height_step(r.astype(np.float32).astype(float)) == pytest.approx(q, rel=1e-3)
    assert scale.height_step(h) is None  # continuous
    assert scale.height_step(h.astype(np.float32).astype(float)) is None  # continuous, stored in float32
    assert scale.height_step(np.zeros((10, 10))) is None
    # filled (continuous) values of missing pixels do not hide the step of the measured ones
    r = 0.2 * NM * np.round(h / (0.2 * NM))
    mask = np.zeros(r.shape, dtype=bool)
    mask[50:60, 50:90] = True
    r[mask] = rng.random(mask.sum()) * NM
    assert scale.height_step(r) is None and scale.height_step(r, mask) == pytest.approx(0.2 * NM, rel=1e-9)


# -- the filter against closed forms -------------------------------------------------------

@pytest.mark.parametrize("cutoff_px", [16, 24])
def test_cutoff_on_white_noise_gives_nayaks_density_and_curvature(cutoff_px):
    """The S-filtered white noise has Nayak's closed-form summit density and mean curvature (module
    docstring); the density falls as cutoff^-2.  Tolerance: 3 standard errors (Poisson for the density,
    the spread of the curvatures for their mean) plus 3 % for the 5-point finder's O((q dx)²) bias."""
    n, dx, s = 512, 1e-6, 1e-9
    h = s * np.random.default_rng(cutoff_px).standard_normal((n, n))
    f = scale.s_filter(sf.Surface(h, (n * dx, n * dx), True), cutoff_px * dx)
    sm = sf.find_summits(f)
    sig = scale.SIGMA_PER_CUTOFF * cutoff_px * dx
    density = 1.0 / (4 * math.sqrt(3) * math.pi * sig**2)
    curvature = 2 * math.sqrt(3) * s * dx / (3 * math.pi * sig**3)
    assert sm.density / density == pytest.approx(1.0, abs=0.03 + 3 / math.sqrt(sm.n))
    se = sm.curvature.std(ddof=1) / math.sqrt(sm.n) / curvature
    assert sm.curvature.mean() / curvature == pytest.approx(1.0, abs=0.03 + 3 * se)


def test_filter_transmits_half_at_the_cutoff_and_keeps_a_long_wave():
    n, dx = 256, 1e-6
    x = np.arange(n) * dx
    for wavelength, expected in ((32 * dx, 0.5), (128 * dx, 0.5 ** (1 / 16))):
        h = np.cos(2 * np.pi * x / wavelength)[:, None] * np.ones((1, n))
        f = scale.s_filter(sf.Surface(h, (n * dx, n * dx), True), 32 * dx)
        assert f.heights.max() == pytest.approx(expected, rel=2e-3)


def test_filter_uses_both_pixel_sizes():
    """The same physical wave on square and on 2:1 pixels is filtered alike: sigma is in metres, and the
    transmission is the Gaussian's, exp(-sigma² (kx² + ky²) / 2)."""
    n, L, cutoff = 256, 256e-6, 24e-6
    x, y2 = np.arange(n) * L / n, np.arange(n // 2) * L / (n // 2)
    kx, ky = 2 * np.pi * 4 / L, 2 * np.pi * 8 / L
    wave = lambda x, y: np.cos(kx * x)[:, None] * np.cos(ky * y)[None, :]
    sig = scale.SIGMA_PER_CUTOFF * cutoff
    for y in (x, y2):
        f = scale.s_filter(sf.Surface(wave(x, y), (L, L), True), cutoff).heights
        assert f[0, 0] == pytest.approx(math.exp(-0.5 * sig**2 * (kx**2 + ky**2)), rel=1e-3)  # sampled kernel


# -- the warnings ------------------------------------------------------------------------

@pytest.mark.parametrize("wavelength_px", [3, 6, 8, 16])
def test_curvature_over_two_pixels_of_a_cosine_lattice(wavelength_px):
    """On h = cos(kx) cos(ky) the curvatures over 1 and 2 px at a summit are in the ratio rho = cos²(pi / lambda)
    (second differences of a cosine), so the pixel-scale fraction is 1 below 4 px and 0 above, and the
    discretisation error reported is (rho - 1) / 3."""
    n = 48
    k = 2 * np.pi / wavelength_px
    i = np.arange(n)
    s = sf.Surface(np.cos(k * i)[:, None] * np.cos(k * i)[None, :] * NM, (n * NM, n * NM), True)
    sm = sf.find_summits(s)
    r = diagnosis.scale_report(s, sm, raw=s)
    rho = math.cos(math.pi / wavelength_px) ** 2
    assert sm.n == (n // wavelength_px) ** 2 * (2 if wavelength_px % 2 == 0 else 1)  # + (lambda/2, lambda/2)
    assert r.pixel_scale_fraction == (1.0 if rho < 0.5 else 0.0)
    assert r.curvature_bias == pytest.approx((rho - 1) / 3, abs=1e-12)
    assert r.alignment == pytest.approx(0.0, abs=1e-12)
    assert r.summit_radius_px == pytest.approx(1 / (2 - 2 * math.cos(k)), rel=1e-9)  # h_xx = -(2 - 2 cos k) h / dx²


def test_pixel_scale_warning_fires_on_white_noise_and_not_on_a_smooth_surface():
    n = 256
    noise = sf.Surface(np.random.default_rng(1).standard_normal((n, n)) * NM, (n * NM, n * NM), True, "noise")
    res, msgs = _fit(noise)
    assert res.scale.pixel_scale_fraction > 0.9 and _has(msgs, "pixel scale")
    smooth = sf.synthetic(n, n * NM, hurst=0.8, rms_height=2 * NM, short_cutoff=16 * NM, long_cutoff=64 * NM, seed=1)
    res, msgs = _fit(smooth)
    assert msgs == [] and res.scale.pixel_scale_fraction < 0.01 and res.scale.height_step is None
    assert -0.02 < res.scale.curvature_bias < 0 and res.scale.summit_radius_px > 10
    # the same smooth surface with its heights rounded at the scale of its summits' relief: the curvature error
    # of independent uniform rounding errors is 0.645 step / dx² (s.d. of -(h_xx + h_yy)/2 over 5 points)
    kappa = res.summits.curvature.mean()
    step = 0.5 * kappa * NM**2
    q = sf.Surface(step * np.round(smooth.heights / step), smooth.physical_sizes, True, "rounded")
    res, msgs = _fit(q)
    assert res.scale.height_step == pytest.approx(step) and _has(msgs, "quantised")
    assert res.scale.quantisation_error == pytest.approx(math.sqrt(5 / 12) * step / NM**2
                                                         / res.summits.curvature.mean(), rel=1e-9)
    # ... and rounded far below it: the step is reported, no warning
    fine = sf.Surface(0.01 * step * np.round(smooth.heights / (0.01 * step)), smooth.physical_sizes, True)
    res, msgs = _fit(fine)
    assert res.scale.height_step == pytest.approx(0.01 * step, rel=1e-6) and msgs == []


def test_scan_line_offsets_make_summits_align_with_the_fast_axis():
    scan, clean = afm_like(n=256, noise=0.0, step=0.0, line=0.3 * NM, short=16)
    res, msgs = _fit(scan)
    assert res.scale.alignment > 0.1 and _has(msgs, "align with the x axis")
    t = sf.Surface(scan.heights.T.copy(), scan.physical_sizes, False, "transposed")
    res, msgs = _fit(t)
    assert res.scale.alignment < -0.1 and _has(msgs, "align with the y axis")
    res, msgs = _fit(clean)
    assert not _has(msgs, "align")


def test_afm_like_scan_warns_and_auto_cutoff_recovers_the_clean_summits():
    scan, clean = afm_like()
    raw, msgs = _fit(scan)
    s = raw.scale
    assert s.pixel_size == pytest.approx((NM, NM)) and s.height_step == pytest.approx(0.1 * NM, rel=1e-6)
    assert s.summit_radius_px < 4 and s.pixel_scale_fraction > 0.9
    for text in ("pixel scale", "quantised", "align with the x axis"):
        assert _has(msgs, text), (text, msgs)
    assert raw.summits.n > 10 * sf.fit(clean, bootstrap=20).summits.n
    auto, msgs = _fit(scan, cutoff="auto")
    assert msgs == [] and auto.scale.cutoff_choice == "auto" and "px" in auto.scale.cutoff_note
    assert 8 * NM <= auto.scale.cutoff <= 32 * NM
    ref = sf.fit(clean, cutoff=auto.scale.cutoff, bootstrap=20)
    assert auto.params.N == pytest.approx(ref.params.N, rel=0.15)
    assert auto.params.R_m == pytest.approx(ref.params.R_m, rel=0.15)


def test_auto_cutoff_refuses_noise_and_keeps_a_clean_surface_near_its_pixels():
    n = 256
    noise = sf.Surface(np.random.default_rng(2).standard_normal((n, n)) * NM, (n * NM, n * NM), True, "noise")
    with pytest.raises(SurfaceError, match="no scale at which.*--cutoff LENGTH"):
        sf.fit(noise, cutoff="auto")
    smooth = sf.synthetic(n, n * NM, hurst=0.8, rms_height=2 * NM, short_cutoff=16 * NM, long_cutoff=64 * NM, seed=3)
    res, msgs = _fit(smooth, cutoff="auto")
    assert res.scale.cutoff <= 4 * NM and msgs == []
    assert res.params.N == pytest.approx(sf.fit(smooth, bootstrap=20).params.N, rel=0.05)
    with pytest.raises(ValueError, match="cutoff"):
        sf.fit(smooth, cutoff="fine")
    with pytest.raises(ValueError, match="cutoff.*expected a length"):
        sf.fit(smooth, cutoff="5 GPa")
    assert _fit(smooth, cutoff="8 nm")[0].scale.cutoff == pytest.approx(8 * NM)
    with pytest.raises(ValueError, match="cutoff"):
        sf.fit(smooth, cutoff=-1e-9)


def test_cutoff_lowers_the_summit_density():
    scan, _ = afm_like(n=256, short=16)
    counts = [_fit(scan, cutoff=c * NM)[0].summits.n for c in (4, 8, 16)]
    assert counts[0] > counts[1] > counts[2]


def test_non_square_pixels_warn_unless_the_cutoff_spans_them():
    s = sf.synthetic((256, 128), (256 * NM, 256 * NM), hurst=0.8, rms_height=2 * NM, short_cutoff=32 * NM,
                     long_cutoff=128 * NM, seed=4)
    res, msgs = _fit(s)
    assert res.scale.pixel_aspect == pytest.approx(2.0) and _has(msgs, "not square")
    res, msgs = _fit(s, cutoff=16 * NM)
    assert not _has(msgs, "not square")
    nearly = sf.Surface(s.heights, (256 * NM, 128 * 1.05 * NM), True)  # aspect 1.05
    assert not _has(_fit(nearly)[1], "not square")


# -- files: masks, non-square pixels, profiles, sizes and units ------------------------------

@pytest.mark.parametrize("fmt", FORMATS)
def test_missing_data_is_masked_filled_and_kept_away_from_summits(tmp_path, fmt):
    n = 128
    smooth = sf.synthetic(n, n * NM, hurst=0.8, rms_height=2 * NM, short_cutoff=8 * NM, long_cutoff=32 * NM, seed=5)
    mask = np.zeros((n, n), dtype=bool)
    mask[20:30, 40:52] = True
    mask[:, 100] = True  # a dropped column, as confocal and interferometric scans have
    path = tmp_path / f"holes.{fmt}"
    s = sf.read(path, **write(path, smooth.heights, smooth.physical_sizes, fmt, mask=mask))
    assert np.array_equal(s.mask, mask) and np.all(np.isfinite(s.heights))
    assert np.allclose(s.heights[~mask], smooth.heights[~mask], rtol=1e-6, atol=1e-15)
    res, msgs = _fit(s)
    assert _has(msgs, "missing data") and res.scale.missing_fraction == pytest.approx(mask.mean())
    i = np.rint(res.summits.x / NM).astype(int)
    j = np.rint(res.summits.y / NM).astype(int)
    near = np.zeros_like(mask)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            near |= np.roll(np.roll(mask, di, 0), dj, 1)
    assert not near[i, j].any() and np.all(np.isfinite(res.summits.curvature))
    # the density is per searched area: the full map's summits outside the holes' reach, on that area
    full = sf.find_summits(sf.composite(sf.Surface(smooth.heights, smooth.physical_sizes, False)))
    fi, fj = np.rint(full.x / NM).astype(int), np.rint(full.y / NM).astype(int)
    keep = ~near[fi, fj]
    assert res.summits.n == keep.sum() or abs(res.summits.n - keep.sum()) <= 2  # the detrend differs slightly
    assert res.summits.area == pytest.approx((n - 2) ** 2 * NM**2 - near[1:-1, 1:-1].sum() * NM**2)


def test_nan_heights_of_a_surface_built_in_python_are_masked():
    smooth = sf.synthetic(128, 128 * NM, hurst=0.8, rms_height=2 * NM, short_cutoff=8 * NM, seed=6)
    h = smooth.heights.copy()
    h[10:14, 10:14] = np.nan
    res, msgs = _fit(sf.Surface(h, smooth.physical_sizes, True))
    assert _has(msgs, "missing data") and np.all(np.isfinite(res.summits.height))


def test_two_surfaces_combine_masks_and_height_steps():
    """The composite's mask is the union of the two; the quantisation error adds the two rounding variances."""
    a = sf.synthetic(128, 128 * NM, hurst=0.8, rms_height=2 * NM, short_cutoff=8 * NM, seed=10)
    b = sf.synthetic(128, 128 * NM, hurst=0.8, rms_height=2 * NM, short_cutoff=8 * NM, seed=11)
    q = 0.05 * NM
    ha, hb = q * np.round(a.heights / q), b.heights.copy()
    ha[5:9, 5:9], hb[60:64, 70:80] = np.nan, np.nan
    res, msgs = _fit(sf.Surface(ha, a.physical_sizes, True), sf.Surface(hb, b.physical_sizes, True))
    assert res.scale.height_step == pytest.approx(q) and res.scale.missing_fraction == pytest.approx(56 / 128**2)
    kappa = res.summits.curvature.mean()
    assert res.scale.quantisation_error == pytest.approx(math.sqrt(5 / 12) * q / NM**2 / kappa, rel=1e-9)
    assert _has(msgs, "missing data")


def test_masked_detrend_uses_the_measured_pixels_only():
    from asperity_sim.analysis.surfaces.topography import detrend

    i, j = np.meshgrid(np.arange(50), np.arange(40), indexing="ij")
    h = 3e-9 * i - 2e-9 * j + 7e-9
    mask = np.zeros(h.shape, dtype=bool)
    mask[5:20, 5:20] = True
    h_bad = np.where(mask, 1e-6, h)  # garbage where nothing was measured
    assert np.allclose(detrend(h_bad, "plane", mask)[~mask], 0.0, atol=1e-20)
    assert np.allclose(detrend(h_bad, "mean", mask)[~mask], (h - h[~mask].mean())[~mask], atol=1e-20)


def _paraboloid_lattice(cells=(8, 8), px=(16, 8), pixel=(1e-6, 2e-6), seed=7):
    """Paraboloid caps, one per cell of px pixels (physically square cells on a 1:2 grid), each with its
    own apex height and radius; returns (heights [m], physical sizes [m], radii [m] by cell)."""
    rng = np.random.default_rng(seed)
    nx, ny = cells[0] * px[0], cells[1] * px[1]
    R = rng.uniform(50e-6, 150e-6, cells)
    z = rng.uniform(0, 1e-6, cells)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    ci, cj = i // px[0], j // px[1]
    x = (i % px[0] - px[0] // 2) * pixel[0]
    y = (j % px[1] - px[1] // 2) * pixel[1]
    h = z[ci, cj] - (x**2 + y**2) / (2 * R[ci, cj])
    return h, (nx * pixel[0], ny * pixel[1]), R


@pytest.mark.parametrize("fmt", FORMATS)
def test_non_square_pixels_give_the_paraboloids_curvature(tmp_path, fmt):
    """Each summit's radius is its paraboloid's exactly (5-point stencil on a quadratic), which needs both
    pixel sizes from the file: with dx for both, the radii would come out 1.6 times too small."""
    h, sizes, R = _paraboloid_lattice()
    path = tmp_path / f"lattice.{fmt}"
    s = sf.read(path, **write(path, h, sizes, fmt, unit="um"))
    assert s.pixel_size == pytest.approx((1e-6, 2e-6), rel=1e-6)
    res, msgs = _fit(s, detrend_mode="none")
    assert res.summits.n == R.size and _has(msgs, "not square")
    assert np.sort(res.summits.radius) == pytest.approx(np.sort(R.ravel()), rel=1e-6)
    nx, ny = h.shape
    assert res.params.N == pytest.approx(R.size / ((nx - 2) * (ny - 2) * 2e-12), rel=1e-6)


@pytest.mark.parametrize("fmt", ["txt-column", "txt-row", "nc", "npy"])
def test_profiles_are_refused_with_a_clear_error(tmp_path, fmt):
    from SurfaceTopography import UniformLineScan

    z = np.random.default_rng(8).standard_normal(200) * NM
    path = tmp_path / f"profile.{fmt.split('-')[0]}"
    kw = {}
    if fmt == "txt-column":
        np.savetxt(path, z / NM)
        kw = {"physical_sizes": (200.0,), "unit": "nm"}
    elif fmt == "txt-row":  # one line of 200 values: read as a 200 x 1 map
        np.savetxt(path, z[None, :] / NM)
        kw = {"physical_sizes": (200.0, 1.0), "unit": "nm"}
    elif fmt == "nc":
        UniformLineScan(z / NM, 200.0, unit="nm").to_netcdf(str(path))
    else:
        np.save(path, z / NM)
        kw = {"physical_sizes": (200.0,), "unit": "nm"}
    with pytest.raises(SurfaceError, match="one-dimensional profile.*needs areal data"):
        sf.read(path, **kw)
    with pytest.raises(SurfaceError, match="one-dimensional profile"):
        sf.fit(sf.Surface(z[:, None], (200 * NM, NM)))


@pytest.mark.parametrize("fmt", ["txt", "npy", "nc"])
def test_files_without_size_or_unit_name_the_options(tmp_path, fmt):
    import netCDF4
    from SurfaceTopography import Topography

    h = np.random.default_rng(9).random((32, 24))
    bare, unitless = tmp_path / f"bare.{fmt}", tmp_path / f"unitless.{fmt}"
    if fmt == "txt":
        np.savetxt(bare, h.T)  # one line per y
        Topography(h, (3.0, 2.0)).to_matrix(str(unitless))  # sizes, no unit
    elif fmt == "npy":
        np.save(bare, h)
        unitless = None  # .npy holds neither
    else:
        with netCDF4.Dataset(bare, "w") as ds:
            ds.createDimension("x", 32)
            ds.createDimension("y", 24)
            ds.createVariable("heights", "f8", ("x", "y"))[:] = h
        Topography(h, (3.0, 2.0)).to_netcdf(str(unitless))
    with pytest.raises(SurfaceError, match="no physical size.*--size"):
        sf.read(bare)
    with pytest.raises(SurfaceError, match="no length unit.*--unit"):
        sf.read(bare, physical_sizes=(3.0, 2.0))
    s = sf.read(bare, physical_sizes=(3.0, 2.0), unit="um")
    assert s.physical_sizes == pytest.approx((3e-6, 2e-6)) and np.allclose(s.heights, h * 1e-6)
    if unitless is not None:
        with pytest.raises(SurfaceError, match="no length unit.*--unit"):
            sf.read(unitless)
        assert sf.read(unitless, unit="mm").physical_sizes == pytest.approx((3e-3, 2e-3))


@pytest.mark.parametrize("fmt", FORMATS)
def test_afm_like_files_warn_and_a_clean_file_does_not(tmp_path, fmt):
    scan, clean = afm_like(n=256, short=16)
    path, cpath = tmp_path / f"scan.{fmt}", tmp_path / f"clean.{fmt}"
    s = sf.read(path, **write(path, scan.heights, scan.physical_sizes, fmt))
    assert s.pixel_size == pytest.approx((NM, NM), rel=1e-6)
    res, msgs = _fit(s)
    assert res.scale.height_step == pytest.approx(0.1 * NM, rel=1e-3)
    assert _has(msgs, "pixel scale") and _has(msgs, "quantised")
    c = sf.read(cpath, **write(cpath, clean.heights, clean.physical_sizes, fmt))
    assert _fit(c)[1] == []


@pytest.mark.slow
def test_afm_like_512_scan_as_in_the_issue(tmp_path):
    """The issue's case at its size: a 512² scan with 1 nm pixels, through a file; every seed warns
    raw and, at the automatic cutoff, is within 15 % of the clean surface at the same cutoff."""
    for seed in range(3):
        scan, clean = afm_like(n=512, seed=seed)
        path = tmp_path / f"scan{seed}.x3p"
        write(path, scan.heights, scan.physical_sizes, "x3p")
        s = sf.read(path)
        raw, msgs = _fit(s)
        assert len(msgs) == 3 and raw.scale.summit_radius_px < 4, msgs
        auto, msgs = _fit(s, cutoff="auto")
        ref = sf.fit(clean, cutoff=auto.scale.cutoff, bootstrap=20)
        assert msgs == [] and auto.params.N == pytest.approx(ref.params.N, rel=0.15), seed
        assert auto.params.R_m == pytest.approx(ref.params.R_m, rel=0.15), seed


def test_report_lines_and_thresholds_are_consistent():
    """Each threshold is a module constant the warnings quote."""
    r = diagnosis.ScaleReport(pixel_size=(1e-9, 1e-9), pixel_aspect=1.0, height_step=None, quantisation_error=0.0,
                              summit_relief=1e-10, summit_radius_px=50.0, pixel_scale_fraction=0.11,
                              curvature_bias=0.0, alignment=0.0, alignment_se=0.01, missing_fraction=0.0,
                              searched_fraction=1.0)
    assert [w.split(":")[0] for w in diagnosis.scale_warnings(r)] == ["summits at the pixel scale"]
    from dataclasses import replace

    assert diagnosis.scale_warnings(replace(r, pixel_scale_fraction=0.09)) == []
    assert diagnosis.scale_warnings(replace(r, pixel_scale_fraction=0.0, curvature_bias=-0.06))
    assert diagnosis.scale_warnings(replace(r, pixel_scale_fraction=0.0, alignment=0.12, alignment_se=0.02))
    assert not diagnosis.scale_warnings(replace(r, pixel_scale_fraction=0.0, alignment=0.12, alignment_se=0.04))
    assert len(r.lines()) == 2 and "50 px" not in r.lines()[0]


# -- command line ------------------------------------------------------------------------

def test_cli_fit_reports_the_scale_warns_and_fits_at_a_cutoff(tmp_path, capsys):
    from asperity_sim.runs.scene import load_scene
    from asperity_sim.ui.cli import main

    scan, _ = afm_like()
    path = tmp_path / "scan.nc"
    write(path, scan.heights, scan.physical_sizes, "nc")
    out = tmp_path / "raw.toml"
    assert main(["fit", str(path), "-o", str(out)]) == 0
    cap = capsys.readouterr()
    warned = [line for line in cap.err.splitlines() if line.startswith("asperity-sim: warning:")]
    assert len(warned) == len(cap.err.splitlines()) == 3
    assert "pixels 1 nm x 1 nm" in cap.out and "quantised in steps of 0.1 nm" in cap.out
    text = out.read_text()
    assert text.count("# WARNING:") == 3 and "no cutoff" in text
    out = tmp_path / "cut.toml"
    assert main(["fit", str(path), "-o", str(out), "--cutoff", "20 nm"]) == 0
    cap = capsys.readouterr()
    assert cap.err == "" and "cutoff 20 nm (20 px, given)" in cap.out
    assert "--cutoff '20 nm'" in out.read_text() and load_scene(out).params.N > 0
    out = tmp_path / "auto.toml"
    assert main(["fit", str(path), "-o", str(out), "--cutoff", "auto"]) == 0
    assert "auto" in capsys.readouterr().out and "summits per cutoff" in out.read_text()


@pytest.mark.parametrize("value, message", [("5 GPa", "--cutoff"), ("0 nm", "out of range"), ("-3 nm", "--cutoff"),
                                            ("soon", "--cutoff")])
def test_cli_fit_bad_cutoff_exits_1(tmp_path, capsys, value, message):
    from asperity_sim.ui.cli import main

    _, clean = afm_like(n=64, short=8)
    path = tmp_path / "s.nc"
    write(path, clean.heights, clean.physical_sizes, "nc")
    assert main(["fit", str(path), "-o", str(tmp_path / "o.toml"), "--cutoff", value]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


def test_cli_fit_profile_exits_1(tmp_path, capsys):
    from asperity_sim.ui.cli import main

    np.savetxt(tmp_path / "p.txt", np.random.default_rng(0).random(100))
    assert main(["fit", str(tmp_path / "p.txt"), "--size", "1", "--unit", "um", "-o", str(tmp_path / "o.toml")]) == 1
    assert "needs areal data" in capsys.readouterr().err
