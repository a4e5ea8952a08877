"""The scale at which a fit describes a surface: the S-filter, the height step, the automatic cutoff.

Owns :func:`s_filter` (the areal Gaussian low-pass filter of ISO 16610-61 / ISO 25178-3: the
short-wavelength cutoff ``cutoff`` [m] is the wavelength it transmits at 50 %),
:func:`height_step` (the quantisation step of an instrument's heights, estimated from the gaps
between their distinct values) and :func:`auto_cutoff` (the smallest cutoff of a geometric
ladder at which the summit density and mean curvature stop depending on the cutoff).
"""

from __future__ import annotations

import math

import numpy as np

from ...checks import check_real
from ...errors import SurfaceError
from .summits import MIN_SUMMITS, find_summits
from .topography import Surface

GAUSS_ALPHA = math.sqrt(math.log(2.0) / math.pi)
"""ISO 16610-61: the Gaussian weight exp(-pi (r / (alpha lambda_c))²) transmits 50 % at the cutoff lambda_c."""
SIGMA_PER_CUTOFF = GAUSS_ALPHA / math.sqrt(2.0 * math.pi)
"""Standard deviation of that Gaussian weight per unit cutoff: sigma = 0.1874 lambda_c."""
REACH_PER_CUTOFF = 0.5
"""After filtering, pixels within half a cutoff (2.7 sigma: 2.8 % of the weight lies beyond) of
missing data or of the edge of a non-periodic map are treated as missing."""
LADDER_STEP = math.sqrt(2.0)
"""Ratio of consecutive cutoffs of the automatic choice."""
LADDER_START = 2.0
"""First cutoff of the ladder, in (larger) pixels: the Nyquist wavelength."""
LADDER_END = 0.25
"""Last cutoff of the ladder, as a fraction of the smaller side of the map."""
AUTO_TOLERANCE = 0.20
"""Largest relative change of summit density and of mean curvature between consecutive cutoffs (a
factor sqrt(2)) at the automatic cutoff.  Noise and self-affine roughness sampled down to the
pixels make the density vary as cutoff^-2, 29 % or more per step (white noise: 50 %), so they
never pass; the summits of a band-limited surface drift by up to about 15 % per step under the
Gaussian filter once the cutoff nears half their shortest wavelength, and pass."""
QUANTISED_TOLERANCE = 0.05
"""Heights count as quantised when the gaps between consecutive distinct values are integer
multiples of the smallest gap, to within 5 % of it, ..."""
QUANTISED_MEDIAN_STEPS = 4
"""... and the median gap is at most 4 of those steps: quantised heights occupy most levels in the
bulk of their distribution, while continuous heights stored in float32 are all multiples of the
float spacing near zero, by factors of thousands."""
QUANTISED_OUTLIERS = 0.01
"""... allowing 1 % of the gaps to be off the grid (a few stray values in an instrument's export)."""


# -- the filter --------------------------------------------------------------------------

def s_filter(surface: Surface, cutoff: float) -> Surface:
    """The surface low-pass filtered at the short-wavelength cutoff ``cutoff`` [m].

    The areal Gaussian filter of ISO 16610-61 (the S-filter of ISO 25178-3): weight
    exp(-pi (r / (alpha cutoff))²), alpha = sqrt(ln 2 / pi), i.e. a Gaussian of standard deviation
    sigma = 0.1874 cutoff in both directions, in metres (so with sigma / dx and sigma / dy pixels on
    a grid of non-square pixels); its transmission exp(-pi (alpha cutoff / wavelength)²) is 50 % at
    the cutoff, 96 % at four times it.  Periodic maps wrap around; other maps are mirrored at the
    edge, and the pixels within half a cutoff of the edge, or of missing data, join the mask
    (their filtered heights lean on data that is not there).  Slopes of a composite are filtered
    alike.
    """
    from scipy import ndimage

    cutoff = check_real("cutoff [m]", cutoff, 0.0, None, lo_open=True, error=SurfaceError)
    dx, dy = surface.pixel_size
    sigma = SIGMA_PER_CUTOFF * cutoff
    mode = "wrap" if surface.periodic else "mirror"

    def smooth(a):
        return ndimage.gaussian_filter(a, (sigma / dx, sigma / dy), mode=mode, truncate=4.0)

    rx, ry = (int(math.ceil(REACH_PER_CUTOFF * cutoff / d - 1e-9)) for d in (dx, dy))
    mask = None
    if surface.mask is not None and np.any(surface.mask):
        mask = ndimage.maximum_filter(surface.mask.astype(np.uint8), size=(2 * rx + 1, 2 * ry + 1),
                                      mode="wrap" if surface.periodic else "constant").astype(bool)
    if not surface.periodic:
        mask = np.zeros(surface.heights.shape, dtype=bool) if mask is None else mask
        mask[:rx], mask[mask.shape[0] - rx:], mask[:, :ry], mask[:, mask.shape[1] - ry:] = True, True, True, True
    slopes = None if surface.slopes is None else tuple(smooth(g) for g in surface.slopes)
    return Surface(smooth(surface.heights), surface.physical_sizes, surface.periodic, surface.source, slopes, mask)


def transfer(cutoff: float | None, qx, qy):
    """Transmission of :func:`s_filter` at wavenumbers (qx, qy) [rad/m] (1 without a cutoff)."""
    if cutoff is None:
        return np.ones(np.broadcast_shapes(np.shape(qx), np.shape(qy)))
    sigma = SIGMA_PER_CUTOFF * cutoff
    return np.exp(-0.5 * sigma**2 * (qx**2 + qy**2))


# -- the height step -----------------------------------------------------------------------

def height_step(heights, mask=None) -> float | None:
    """The quantisation step [m] of measured heights, or None when they are continuous.

    From the sorted distinct values of the measured pixels (``mask`` True: not measured; gaps
    below 1e-9 of the height range, floating-point splits of one level, are merged): the heights
    are quantised when the gaps are integer multiples k of the smallest (:data:`QUANTISED_TOLERANCE`,
    :data:`QUANTISED_OUTLIERS`) with a median k of at most :data:`QUANTISED_MEDIAN_STEPS`; the
    step is then the least-squares common step, sum(gaps) / sum(k).  Give the heights as read, not
    detrended (a plane breaks the levels).
    """
    h = np.asarray(heights, dtype=float)
    if mask is not None:
        h = h[~np.asarray(mask, dtype=bool)]
    h = h[np.isfinite(h)].ravel()
    u = np.unique(h)
    if u.size < 3:
        return None
    gaps = np.diff(u)
    gaps = gaps[gaps > 1e-9 * (u[-1] - u[0])]
    if gaps.size < 2:
        return None
    k = np.rint(gaps / gaps.min())
    if np.median(k) > QUANTISED_MEDIAN_STEPS:
        return None
    on_grid = np.abs(gaps / gaps.min() - k) <= QUANTISED_TOLERANCE
    if np.mean(~on_grid) > QUANTISED_OUTLIERS:
        return None
    return float(gaps[on_grid].sum() / k[on_grid].sum())


# -- the automatic cutoff ------------------------------------------------------------------

def cutoff_ladder(surface: Surface, window: int = 1, min_prominence: float = 0.0) -> list:
    """Summit statistics against the cutoff: [(cutoff [m], summits, density [1/m²], mean curvature [1/m])].

    Cutoffs LADDER_START larger pixels times sqrt(2)^k, up to LADDER_END of the smaller side of
    the map or until fewer than MIN_SUMMITS summits remain.
    """
    dx, dy = surface.pixel_size
    Lmin = min(surface.physical_sizes)
    out = []
    cutoff = LADDER_START * max(dx, dy)
    while cutoff <= LADDER_END * Lmin * (1 + 1e-9):
        try:
            sm = find_summits(s_filter(surface, cutoff), min_prominence, window)
        except SurfaceError:  # the filter's reach left no pixel to search
            break
        if sm.n < MIN_SUMMITS:
            break
        out.append((cutoff, sm.n, sm.density, float(sm.curvature.mean())))
        cutoff *= LADDER_STEP
    return out


def ladder_changes(ladder) -> list:
    """Change from each cutoff to the next: max(|relative change of density|, |of mean curvature|)."""
    return [max(abs(n1 / n0 - 1.0), abs(c1 / c0 - 1.0)) for (_, _, n0, c0), (_, _, n1, c1) in zip(ladder, ladder[1:])]


def stable_rung(ladder, tolerance: float = AUTO_TOLERANCE) -> int | None:
    """Index of the automatic cutoff in ``ladder``, or None.

    The first cutoff whose change to the next (:func:`ladder_changes`) is below ``tolerance`` and
    is a local minimum, not larger than the next change (the knee where the noise has gone and the
    filter has not yet started to smooth the surface's own summits); the last step needs only the
    tolerance.
    """
    ch = ladder_changes(ladder)
    for k, c in enumerate(ch):
        if c < tolerance and (k + 1 == len(ch) or c <= ch[k + 1]):
            return k
    return None


def ladder_text(ladder, pixel: float) -> str:
    """The ladder in one line: ``cutoff [px]: summits`` per rung."""
    return ", ".join(f"{c / pixel:.3g} px: {n}" for c, n, _, _ in ladder)


def auto_cutoff(surface: Surface, window: int = 1, min_prominence: float = 0.0,
                tolerance: float = AUTO_TOLERANCE):
    """The automatic cutoff: (cutoff [m], ladder, reason).

    The smallest cutoff of :func:`cutoff_ladder` at which both the summit density and the mean
    summit curvature change by less than ``tolerance`` (relative) to the next cutoff, a factor
    sqrt(2) larger, and by no more than from that one to the one after (:func:`stable_rung`): the
    scale from which the summits describe the surface rather than the sampling and the noise.
    A surface without such a scale (white noise, a self-affine surface sampled down to its
    pixels) raises :class:`SurfaceError` with the ladder: choose the cutoff (for example the size
    of the contacts) with ``cutoff=``.
    """
    ladder = cutoff_ladder(surface, window, min_prominence)
    pixel = max(surface.pixel_size)
    k = stable_rung(ladder, tolerance)
    if k is None:
        raise SurfaceError(f"{surface.source}: --cutoff auto found no scale at which the summits stop depending on "
                           f"the cutoff (density or mean curvature changes by more than {tolerance:.0%} per factor "
                           f"sqrt(2) at every cutoff; summits per cutoff: {ladder_text(ladder, pixel) or 'none'}); "
                           "noise or self-affine roughness down to the pixels has no such scale: choose the scale "
                           "with --cutoff LENGTH (e.g. the size of the contacts)")
    (c0, _, n0, k0), (c1, _, n1, k1) = ladder[k], ladder[k + 1]
    why = (f"auto: first cutoff of the ladder {LADDER_START:g} px x sqrt(2)^k at which summit density and mean "
           f"curvature change by less than {tolerance:.0%} to the next cutoff, and by no more than at the next "
           f"({n1 / n0 - 1:+.1%} and {k1 / k0 - 1:+.1%} from {c0 / pixel:.3g} to {c1 / pixel:.3g} px); "
           f"summits per cutoff: {ladder_text(ladder, pixel)}")
    return c0, tuple(ladder), why
