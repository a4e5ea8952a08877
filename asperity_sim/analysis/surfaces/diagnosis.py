"""The scale diagnosis of a fit: what the summits resolve, and the warnings when they describe the instrument.

Owns :class:`ScaleReport` (pixel sizes, height step, summit radius in pixels, pixel-scale
summits, curvature error from quantised heights, alignment of the summits with the scan axes,
missing data, the cutoff and why), :func:`scale_report` that measures it on the surface a fit's
summits were found on, and the thresholds above which a fit warns
(:class:`~asperity_sim.errors.SurfaceScaleWarning`); docs/surfaces.md justifies each.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...units import format_quantity
from .scale import transfer
from .summits import Summits, eligible
from .topography import Surface

PIXEL_SCALE_RHO = 0.5
"""A summit is at the pixel scale when its curvature over 2 pixels is less than half its curvature
over 1 pixel (rho = kappa_2 / kappa_1 < 0.5): a cosine of wavelength lambda has rho = cos²(pi dx /
lambda), below 0.5 for wavelengths below 4 pixels; white noise gives rho near 0.2."""
PIXEL_SCALE_MAX = 0.10
"""Warn when more than 10 % of the summits are at the pixel scale: N and R_m are then off by more
than the 10 % that issue 36 asks of the model."""
CURVATURE_BIAS_MAX = 0.05
"""Warn when the discretisation error of the summit curvatures, (median rho - 1) / 3 (the O(dx²)
term of a second difference, from the curvatures over 1 and 2 pixels: Richardson), exceeds 5 % in
magnitude: a cosine's curvature over 1 px is 5 % low at a wavelength of 8 pixels."""
QUANTISATION_MAX = 0.10
"""Warn when rounding the heights to their step makes a summit curvature uncertain by more than
10 % of the mean curvature (one standard deviation, rounding errors taken independent and uniform)."""
ALIGNMENT_MAX = 0.10
"""Warn when the mean axis anisotropy of the summit curvatures, A = <(kappa_y - kappa_x) / (kappa_x
+ kappa_y)>, exceeds 0.1 in magnitude (summits 22 % sharper across one axis than along it) ..."""
ALIGNMENT_SIGMAS = 4.0
"""... and 4 standard errors (false alarms 6e-5 on an isotropic surface; A of one summit has a
standard deviation of about 0.3, from its random elliptic orientation)."""
ASPECT_MAX = 1.10
"""Warn when the pixels' aspect ratio exceeds 1.1 (a scanner's axes are calibrated to a few %),
unless the cutoff spans at least ASPECT_CUTOFF_PX of the larger pixels."""
ASPECT_CUTOFF_PX = 8.0
"""From this many larger pixels per cutoff the summit finder's discretisation error is about 2 %
(docs/surfaces.md, tests against Nayak) along both axes, so the grid no longer sets the summits."""


def _len(value) -> str:
    """A length with 3 significant digits in a readable unit (``0.0972 nm``)."""
    number, unit = format_quantity(value, "m").split()
    return f"{float(number):.3g} {unit}"


@dataclass(frozen=True)
class ScaleReport:
    """At which scale a fit describes the surface (SI units; fractions in [0, 1]).

    pixel_size : (dx, dy) [m];  pixel_aspect : max/min [1]
    height_step : quantisation step of the heights as read [m], None when continuous (the largest
        of two surfaces)
    quantisation_error : s.d. of a summit curvature due to that rounding / mean summit curvature [1]
    summit_relief : mean height of a summit above the mean of its 4 neighbours [m]
    summit_radius_px : mean summit radius / sqrt(dx dy) [1]
    pixel_scale_fraction : summits whose curvature over 2 pixels is < 0.5 x that over 1 pixel
    curvature_bias : (median kappa_2/kappa_1 - 1) / 3, discretisation error of the curvatures [1]
    alignment, alignment_se : mean of (kappa_y - kappa_x)/(kappa_x + kappa_y) over summits and its
        standard error (> 0: summits elongated along x, lined up with x-scan lines)
    missing_fraction : pixels without data;  searched_fraction : of the map where summits may be
    cutoff : [m] or None;  cutoff_choice : "none", "given" or "auto";  cutoff_note : why
    ladder : ((cutoff, summits, density, mean curvature), ...) of the automatic choice
    warnings : one message per threshold passed
    """

    pixel_size: tuple
    pixel_aspect: float
    height_step: float | None
    quantisation_error: float
    summit_relief: float
    summit_radius_px: float
    pixel_scale_fraction: float
    curvature_bias: float
    alignment: float
    alignment_se: float
    missing_fraction: float
    searched_fraction: float
    cutoff: float | None = None
    cutoff_choice: str = "none"
    cutoff_note: str = ""
    ladder: tuple = ()
    warnings: tuple = ()

    def lines(self) -> list:
        """The report in a few lines of text (the command line's output and the scene's comments)."""
        dx, dy = self.pixel_size
        step = "continuous heights" if self.height_step is None else \
            f"heights quantised in steps of {_len(self.height_step)}"
        scale = f"cutoff {_len(self.cutoff)} ({self.cutoff / max(dx, dy):.3g} px, {self.cutoff_choice})" \
            if self.cutoff is not None else "no cutoff (the pixels set the smallest scale)"
        out = [f"scale: pixels {_len(dx)} x {_len(dy)} (aspect {self.pixel_aspect:.3g}); "
               f"{step}; {scale}",
               f"summits: mean radius {self.summit_radius_px:.3g} px; {self.pixel_scale_fraction:.0%} at the pixel "
               f"scale; "
               f"curvature discretisation error {self.curvature_bias:+.1%}; from quantisation "
               f"{self.quantisation_error:.1%}; summit relief {_len(self.summit_relief)}; "
               f"axis anisotropy A = {self.alignment:+.3f} ± {self.alignment_se:.3f}; missing data "
               f"{self.missing_fraction:.2%}, searched {self.searched_fraction:.1%} of the map"]
        if self.cutoff_note:
            out.append(f"cutoff: {self.cutoff_note}")
        return out


def _curvatures(s: Surface, ii, jj, step: int):
    """(kappa_x, kappa_y, valid) [1/m]: minus the second differences over ``step`` pixels at (ii, jj)."""
    h = s.heights
    nx, ny = h.shape
    dx, dy = s.pixel_size
    z = h[ii, jj]
    ip, im, jp, jm = ii + step, ii - step, jj + step, jj - step
    valid = np.ones(ii.size, dtype=bool)
    if not s.periodic:
        valid = (im >= 0) & (ip < nx) & (jm >= 0) & (jp < ny)
    ip, im, jp, jm = ip % nx, im % nx, jp % ny, jm % ny
    if s.mask is not None:
        m = s.mask
        valid &= ~(m[ip, jj] | m[im, jj] | m[ii, jp] | m[ii, jm])
    kx = -(h[ip, jj] - 2 * z + h[im, jj]) / (step * dx) ** 2
    ky = -(h[ii, jp] - 2 * z + h[ii, jm]) / (step * dy) ** 2
    return kx, ky, valid


def quantisation_noise(s: Surface, cutoff, steps) -> float:
    """S.d. [1/m] of a summit curvature -(h_xx + h_yy)/2 when the heights carry independent uniform rounding
    errors of the ``steps`` (variance sum q²/12), passed through the cutoff's filter and the 5-point stencil."""
    var = sum(q * q for q in steps if q) / 12.0
    if var == 0.0:
        return 0.0
    nx, ny = s.heights.shape
    dx, dy = s.pixel_size
    qx = 2 * np.pi * np.fft.fftfreq(nx, dx)[:, None]
    qy = 2 * np.pi * np.fft.fftfreq(ny, dy)[None, :]
    lap = (2 * np.cos(qx * dx) - 2) / dx**2 + (2 * np.cos(qy * dy) - 2) / dy**2
    gain = (transfer(cutoff, qx, qy) * lap / 2.0) ** 2
    return math.sqrt(var * float(gain.mean()))


def scale_report(scaled: Surface, summits: Summits, *, raw: Surface, steps=(), window: int = 1,
                 cutoff=None, cutoff_choice="none", cutoff_note="", ladder=()) -> ScaleReport:
    """Measure the scale of a fit: ``summits`` were found on ``scaled`` (``raw`` filtered at ``cutoff``).

    raw : the composite before the cutoff (its mask is the missing data)
    steps : quantisation steps [m] (or None) of the surfaces as read
    """
    dx, dy = scaled.pixel_size
    ii, jj = summits.pixel_indices(scaled.pixel_size)
    kx, ky, _ = _curvatures(scaled, ii, jj, 1)
    kx2, ky2, ok2 = _curvatures(scaled, ii, jj, 2)
    k1 = 0.5 * (kx + ky)
    rho = (0.5 * (kx2 + ky2) / k1)[ok2]
    relief = (kx * dx**2 + ky * dy**2) / 4.0  # h - mean of the 4 neighbours
    a = (ky - kx) / (kx + ky)
    steps = tuple(q for q in steps if q)
    kmean = float(np.mean(k1)) if k1.size else float("nan")
    report = ScaleReport(
        pixel_size=(dx, dy), pixel_aspect=max(dx, dy) / min(dx, dy),
        height_step=max(steps) if steps else None,
        quantisation_error=quantisation_noise(scaled, cutoff, steps) / kmean if steps else 0.0,
        summit_relief=float(np.mean(relief)) if summits.n else float("nan"),
        summit_radius_px=float(np.mean(summits.radius)) / math.sqrt(dx * dy) if summits.n else float("nan"),
        pixel_scale_fraction=float(np.mean(rho < PIXEL_SCALE_RHO)) if rho.size else 0.0,
        curvature_bias=(float(np.median(rho)) - 1.0) / 3.0 if rho.size else 0.0,
        alignment=float(a.mean()) if a.size else 0.0,
        alignment_se=float(a.std(ddof=1) / math.sqrt(a.size)) if a.size > 1 else float("inf"),
        missing_fraction=raw.missing_fraction,
        searched_fraction=float(np.mean(eligible(scaled, window))),
        cutoff=cutoff, cutoff_choice=cutoff_choice, cutoff_note=cutoff_note, ladder=tuple(ladder))
    return replace(report, warnings=tuple(scale_warnings(report, window)))


def scale_warnings(r: ScaleReport, window: int = 1) -> list:
    """The warnings of a report, one line each (empty when every threshold holds)."""
    dx, dy = r.pixel_size
    big = max(dx, dy)
    fix = (f"fit at a larger scale: --cutoff auto, or --cutoff LENGTH (e.g. \"{_len(8 * big)}\"; Python: cutoff=...)")
    out = []
    if r.pixel_scale_fraction > PIXEL_SCALE_MAX:
        out.append(f"summits at the pixel scale: {r.pixel_scale_fraction:.0%} of the summits are set by wavelengths "
                   f"below about 4 pixels (curvature over 2 px below half that over 1 px; threshold "
                   f"{PIXEL_SCALE_MAX:.0%}), mean "
                   f"radius {r.summit_radius_px:.3g} px: the fit describes the sampling or the instrument noise, not "
                   f"the surface; {fix}")
    elif -r.curvature_bias > CURVATURE_BIAS_MAX:
        out.append(f"summits resolved by few pixels: their curvature over 1 px is about {-r.curvature_bias:.0%} "
                   f"below the continuum value (from the curvatures over 1 and 2 px; threshold "
                   f"{CURVATURE_BIAS_MAX:.0%}), mean radius {r.summit_radius_px:.3g} px; {fix}")
    if r.quantisation_error > QUANTISATION_MAX:
        out.append(f"heights are quantised at the scale of the summits: steps of {_len(r.height_step)} against a "
                   f"mean summit relief (height above its 4 neighbours) of {_len(r.summit_relief)} "
                   f"({r.summit_relief / r.height_step:.2g} steps); rounding alone makes a summit curvature "
                   f"uncertain by {r.quantisation_error:.0%} of the mean (threshold {QUANTISATION_MAX:.0%}); {fix}")
    if abs(r.alignment) > ALIGNMENT_MAX and abs(r.alignment) > ALIGNMENT_SIGMAS * r.alignment_se:
        along, across = ("x", "y") if r.alignment > 0 else ("y", "x")
        out.append(f"summits align with the {along} axis: they are sharper across it than along it, axis anisotropy "
                   f"A = {r.alignment:+.3f} ± {r.alignment_se:.3f} (threshold {ALIGNMENT_MAX:g} and "
                   f"{ALIGNMENT_SIGMAS:g} standard errors); if {along} is the fast scan axis these are scan-line "
                   f"artefacts (line offsets, feedback noise), else non-square pixels or a lay of the surface; the "
                   f"model's summits are isotropic; level the scan lines or {fix}")
    if r.pixel_aspect > ASPECT_MAX and (r.cutoff is None or r.cutoff < ASPECT_CUTOFF_PX * big):
        out.append(f"pixels are not square: {_len(dx)} x {_len(dy)} (aspect "
                   f"{r.pixel_aspect:.3g}, threshold {ASPECT_MAX:g}); curvature and density use both sizes, but the "
                   f"summit window and the resolution differ between the axes; fit with a cutoff of at least "
                   f"{ASPECT_CUTOFF_PX:g} larger pixels (--cutoff \"{_len(ASPECT_CUTOFF_PX * big)}\")")
    if r.missing_fraction > 0.0:
        out.append(f"missing data: {r.missing_fraction:.2%} of the pixels have no height; they were filled by harmonic "
                   f"interpolation for detrending and filtering, and no summit was taken within {window} px of them "
                   "(or within half the cutoff after filtering): summits were searched on "
                   f"{r.searched_fraction:.1%} of the map, and the density uses that area")
    return out
