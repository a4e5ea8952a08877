"""The boundary-element solution of a surface pair (tamaas), and the figure of a fit.

Owns :func:`bem_contact`, the exact elastic contact of a composite surface at given mean
pressures (tamaas, an optional dependency), which the asperity model is compared with, and
:func:`plot_fit`.
"""

from __future__ import annotations

import numpy as np
from scipy import special, stats

from .fitting import FitResult


def bem_contact(h, size, E_star, pressures, tolerance=1e-10):
    """Exact (boundary-element) frictionless contact of a rigid surface h on an elastic half-space.

    The reference the asperity model is compared with (``scenarios/bem_closure.py``); needs
    tamaas (``pip install "asperity-sim[bem]"``).  tamaas' Polonsky-Keer solver on a periodic
    grid, with E = E_star and nu = 0, so its contact modulus E/(1 - nu²) is E_star.

    h : ndarray (nx, ny) [m]      composite surface heights
    size : (Lx, Ly) [m]           physical size of the periodic cell
    E_star : float [Pa]           contact modulus
    pressures : sequence [Pa]     mean pressures to solve at
    tolerance : float [1]         tamaas solver tolerance

    Returns an array (4, len(pressures)): closure max(h) - mean(u) [m], mean separation
    mean(u - h) [m], area fraction [1] (traction > 0) and wall time [s] of each solve.
    """
    import time

    import tamaas as tm

    tm.initialize(1)
    tm.set_log_level(tm.LogLevel.error)
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, list(size), list(h.shape))
    model.E, model.nu = E_star, 0.0  # tamaas' contact modulus E/(1 - nu²) = E*
    solver = tm.PolonskyKeerRey(model, np.ascontiguousarray(h), tolerance)
    out = np.empty((4, len(pressures)))
    for k, p in enumerate(pressures):
        t0 = time.perf_counter()
        solver.solve(float(p))
        seconds = time.perf_counter() - t0
        t, u = np.array(model.traction), np.array(model.displacement)
        out[:, k] = h.max() - u.mean(), (u - h).mean(), (t > 0).mean(), seconds
    return out


def plot_fit(result: FitResult):
    """Figure of a fit: summit map, QQ plots of depths (gamma) and radii (truncated Gaussian), histogram."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    p, sm = result.params, result.summits
    fig, ax = plt.subplots(2, 2, figsize=(10, 8.5))
    surf = result.surface
    if surf is not None:
        Lx, Ly = surf.physical_sizes
        im = ax[0, 0].imshow(surf.heights.T * 1e6, origin="lower", extent=(0, Lx * 1e3, 0, Ly * 1e3), cmap="gray")
        fig.colorbar(im, ax=ax[0, 0], label="composite height [um]")
    ax[0, 0].plot(sm.x * 1e3, sm.y * 1e3, ".", ms=2, color="tab:red")
    k = 2 * result.settings.get("window", 1) + 1
    ax[0, 0].set(xlabel="x [mm]", ylabel="y [mm]", title=f"{sm.n} summits (maxima of {k}x{k} pixel squares)")
    prob = (np.arange(1, sm.n + 1) - 0.5) / sm.n
    d = np.sort(sm.depth)
    q = stats.gamma.ppf(prob, p.alpha + 1.0, scale=p.beta)
    ax[0, 1].plot(q * 1e6, d * 1e6, ".", ms=3)
    ax[0, 1].plot([0, d.max() * 1e6], [0, d.max() * 1e6], "k--", lw=1)
    ax[0, 1].set(xlabel="gamma quantile [um]", ylabel="summit depth [um]",
                 title=f"QQ depth: alpha = {p.alpha:.3g}, beta = {p.beta * 1e6:.3g} um, "
                       f"KS = {result.goodness['heights']:.3f}")
    rad = np.sort(sm.radius)
    lo, hi = p.R_bounds
    a, b = special.ndtr((lo - p.R_m) / p.R_sigma), special.ndtr((hi - p.R_m) / p.R_sigma)
    qr = p.R_m + p.R_sigma * special.ndtri(a + prob * (b - a))
    ax[1, 0].plot(qr * 1e6, rad * 1e6, ".", ms=3)
    ax[1, 0].plot([qr.min() * 1e6, qr.max() * 1e6], [qr.min() * 1e6, qr.max() * 1e6], "k--", lw=1)
    ax[1, 0].set(xlabel="truncated Gaussian quantile [um]", ylabel="summit radius 1/kappa [um]",
                 title=f"QQ radius: R_m = {p.R_m * 1e6:.3g} um, R_sigma = {p.R_sigma * 1e6:.3g} um, "
                       f"KS = {result.goodness['radii']:.3f}")
    ax[1, 1].hist(sm.depth * 1e6, bins=40, density=True, alpha=0.6, label="summits")
    x = np.linspace(0, sm.depth.max(), 200)
    ax[1, 1].plot(x * 1e6, stats.gamma.pdf(x, p.alpha + 1.0, scale=p.beta) * 1e-6, label="fitted gamma, Eq. (1)")
    ax[1, 1].set(xlabel="depth below the highest summit r [um]", ylabel="density [1/um]",
                 title=f"N = {p.N * 1e-6:.4g} /mm2")
    ax[1, 1].legend()
    for a_ in ax.flat:
        a_.title.set_fontsize(9)
    fig.tight_layout()
    return fig
