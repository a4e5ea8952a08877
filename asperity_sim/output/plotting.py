"""Figures drawn from run files alone (netCDF written by :func:`asperity_sim.simulate`).

Owns the figures of runs and their conventions (figures of sweeps and envelopes follow them,
:mod:`asperity_sim.runs.figures`): every function takes datasets (as read back from disk)
and returns a matplotlib Figure, and :func:`save_figure` writes one atomically.  Conventions of every figure:

- Monte Carlo standard errors are drawn as shaded bands of ±2 standard errors (``BAND``), and
  every legend of an axes with bands says so (``BAND_LABEL``);
- every computed point (a recorded step) carries a marker, so a large increment shows as a
  straight segment between two markers; guide lines (stage boundaries, zero lines, slopes) carry
  none and have the gid ``"guide"``;
- a quadrature reference, when the file holds one (``reference_stress``), is a dashed line;
- only what the run computed is drawn: a run without shear gets no shear panel, and a
  closure curve is normal stress against closure.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from .atomic import write_atomically  # noqa: E402

MPA, UM = 1e-6, 1e6
BAND = 2.0  # half-width of the error bands, in standard errors
BAND_LABEL = f"shaded: ±{BAND:g} SE (Monte Carlo standard error)"
COLORS = {1: "tab:blue", 2: "tab:red", 3: "tab:green"}
MARK = {"marker": "o", "ms": 2.5}  # every recorded step is a marker
GUIDE = {"color": "0.6", "lw": 0.8, "gid": "guide"}  # lines that are not computed points


def save_figure(fig, path, **kw) -> Path:
    """Write ``fig`` to ``path`` (format from its suffix) atomically (:mod:`asperity_sim.output.atomic`)."""
    path = Path(path)
    return write_atomically(path, lambda tmp: fig.savefig(tmp, format=path.suffix.lstrip(".") or "png", **kw))


def path_length(ds) -> np.ndarray:
    """Cumulative length of the displacement path [m], the abscissa of multi-stage plots."""
    d = ds["displacement"].values
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(d, axis=0), axis=1))])


def _band(ax, x, y, se, color, label=None, **kw):
    """A computed curve with markers and its ±BAND standard-error band (vertical)."""
    ax.plot(x, y, color=color, label=label, **{**MARK, **kw})
    ax.fill_between(x, y - BAND * se, y + BAND * se, color=color, alpha=0.25, lw=0)


def _band_x(ax, x, y, se_x, color, label=None, **kw):
    """A computed curve with markers and its ±BAND standard-error band along x (a solved abscissa)."""
    ax.plot(x, y, color=color, label=label, **{**MARK, **kw})
    ax.fill_betweenx(y, x - BAND * se_x, x + BAND * se_x, color=color, alpha=0.25, lw=0)


def band_legend(ax, handles=None, labels=None, **kw):
    """The legend of an axes with standard-error bands: its entries and one that states the band."""
    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    patch = Patch(facecolor="0.5", alpha=0.35, lw=0)
    kw.setdefault("fontsize", 8)
    return ax.legend(list(handles) + [patch], list(labels) + [BAND_LABEL], **kw)


def _stage_marks(ax, ds, x):
    stage = ds["stage"].values
    for i in np.flatnonzero(np.diff(stage) != 0)[1:]:
        ax.axvline(x[i], ls=":", **GUIDE)


def shear_axes(ds) -> list:
    """The shear components (2, 3) the run moved or loaded: displacement controlled with a nonzero
    Delta_k, or stress controlled with a nonzero sigma_k target, at some step."""
    control = ds["control"].values.astype(bool)
    d, s = ds["displacement"].values, ds["stress"].values
    return [k for k in (2, 3)
            if np.any((~control[:, k - 1] & (d[:, k - 1] != 0.0)) | (control[:, k - 1] & (s[:, k - 1] != 0.0)))]


def plot_three_step(runs: dict):
    """Fig. 11: sigma_1, sigma_2, sigma_3 and theta_am along the 3-step path, one panel per interface."""
    fig, axes = plt.subplots(1, len(runs), figsize=(5.5 * len(runs), 4.2), squeeze=False)
    for ax, (name, ds) in zip(axes[0], runs.items()):
        x = path_length(ds) * UM
        for k in (1, 2, 3):
            s = ds["stress"].sel(axis=k).values * MPA
            se = ds["stress_stderr"].sel(axis=k).values * MPA
            _band(ax, x, s, se, COLORS[k], label=rf"$\sigma_{k}$")
            if "reference_stress" in ds:
                ax.plot(x, ds["reference_stress"].sel(axis=k).values * MPA, "k--", lw=0.9,
                        label="quadrature" if k == 1 else None, marker="x", ms=2.5)
        _stage_marks(ax, ds, x)
        ax.set_xlabel(r"path length $\int|d\Delta|$ [µm] (steps 1 | 2 | 3)")
        ax.set_ylabel("interface stress [MPa]")
        ax.set_title(f"{name}: 3-step path, n = {ds.attrs.get('n_asperities')}")
        ax2 = ax.twinx()
        ax2.plot(x, np.degrees(ds["theta_am"].values), color="0.35", lw=1.2, ls="-.", label=r"$\theta_{am}$", **MARK)
        ax2.set_ylabel(r"orientation extent $\theta_{am}$ [deg]")
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        band_legend(ax, h1 + h2, l1 + l2, loc="upper left")
    fig.tight_layout()
    return fig


def plot_normal_closure(runs: dict):
    """Fig. 12: sigma_1 and theta_am against Delta_1 for each interface."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for (name, ds), color in zip(runs.items(), ("tab:red", "tab:blue", "tab:green", "tab:orange")):
        d1 = ds["displacement"].sel(axis=1).values
        se_d1 = ds["displacement_stderr"].sel(axis=1).values
        s1 = ds["stress"].sel(axis=1).values * MPA
        _band_x(a1, d1 * 1e3, s1, se_d1 * 1e3, color, label=f"{name} (Monte Carlo)")
        if "reference_displacement" in ds:
            a1.plot(ds["reference_displacement"].sel(axis=1).values * 1e3, s1, "k--", lw=0.9, marker="x", ms=2.5)
        a2.plot(d1 * 1e3, np.degrees(ds["theta_am"].values), color=color, label=name, **MARK)
    a1.plot([], [], "k--", lw=0.9, marker="x", ms=2.5, label="quadrature")
    a1.set_xlabel(r"closure $\Delta_1$ [mm]")
    a1.set_ylabel(r"normal stress $\sigma_1$ [MPa]")
    band_legend(a1)
    a1.set_title("normal closure")
    a2.set_xlabel(r"closure $\Delta_1$ [mm]")
    a2.set_ylabel(r"average orientation extent $\theta_{am}$ [deg]")
    a2.legend(fontsize=8)
    a2.set_title(r"orientation extent (Eq. 29)")
    fig.tight_layout()
    return fig


def shear_stage(ds):
    """The steps after the first stage (the shear of a constant-normal-stress test), with its start."""
    start = int(np.flatnonzero(ds["stage"].values >= 2)[0]) - 1
    return ds.isel(step=slice(start, None))


def plot_constant_normal_shear(runs: dict):
    """Fig. 13: shear resistance sigma_2/sigma_1 and change of Delta_1 against Delta_2."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for (name, ds), color in zip(runs.items(), ("tab:red", "tab:blue", "tab:green", "tab:orange")):
        sh = shear_stage(ds)
        d2 = sh["displacement"].sel(axis=2).values * UM
        s1 = sh["stress"].sel(axis=1).values
        ratio = sh["stress"].sel(axis=2).values / s1
        se_ratio = sh["stress_stderr"].sel(axis=2).values / s1
        _band(a1, d2, ratio, se_ratio, color, label=f"{name}")
        d1 = sh["displacement"].sel(axis=1).values
        change = (d1 - d1[0]) * UM
        se_d1 = sh["displacement_stderr"].sel(axis=1).values * UM
        _band(a2, d2, change, se_d1, color, label=f"{name}")
        if "reference_stress" in sh:
            ref = sh["reference_stress"]
            a1.plot(d2, ref.sel(axis=2).values / ref.sel(axis=1).values, "k--", lw=0.9, marker="x", ms=2.5)
            rd1 = sh["reference_displacement"].sel(axis=1).values
            a2.plot(d2, (rd1 - rd1[0]) * UM, "k--", lw=0.9, marker="x", ms=2.5)
    sigma_n = float(np.median(shear_stage(next(iter(runs.values())))["stress"].sel(axis=1).values)) * MPA
    a1.plot([], [], "k--", lw=0.9, marker="x", ms=2.5, label="quadrature")
    a1.axhline(float(next(iter(runs.values())).attrs.get("param_mu", 1.0)), ls=":", **GUIDE)
    a1.set_xlabel(r"shear displacement $\Delta_2$ [µm]")
    a1.set_ylabel(r"shear resistance $\sigma_2/\sigma_1$ [1]")
    a1.set_title(rf"shear at constant $\sigma_1$ = {sigma_n:.0f} MPa")
    band_legend(a1)
    a2.set_xlabel(r"shear displacement $\Delta_2$ [µm]")
    a2.set_ylabel(r"change of closure $\Delta_1 - \Delta_1^0$ [µm] (> 0: compaction)")
    a2.axhline(0.0, **GUIDE)
    band_legend(a2)
    a2.set_title("normal displacement during shear")
    fig.tight_layout()
    return fig


def _closure_curve(ax, ds):
    """Normal stress sigma_1 against closure Delta_1, with the band of whichever was computed."""
    d1 = ds["displacement"].sel(axis=1).values * UM
    s1 = ds["stress"].sel(axis=1).values * MPA
    se_d1 = ds["displacement_stderr"].sel(axis=1).values * UM
    se_s1 = ds["stress_stderr"].sel(axis=1).values * MPA
    if np.any(se_d1 > 0.0):  # stress controlled somewhere: the closure was solved, its error is along x
        _band_x(ax, d1, s1, se_d1, COLORS[1], label=r"$\sigma_1$ (closure solved)")
    else:
        _band(ax, d1, s1, se_s1, COLORS[1], label=r"$\sigma_1$")
    ax.set_xlabel(r"closure $\Delta_1$ [µm]")
    ax.set_ylabel(r"normal stress $\sigma_1$ [MPa]")
    band_legend(ax)


def plot_run(ds):
    """Standard figure of any run, with the panels its physics fills.

    Without shear (no shear displacement or shear stress target at any step): normal stress
    and the fraction of asperities in contact against closure Delta_1.  With shear: the
    stresses, the shear resistance and the contact and slip fractions against the path
    length, and normal stress against closure; only the shear axes the run moved or loaded.
    """
    shear = shear_axes(ds)
    n = float(ds.attrs.get("n_asperities", 1))
    if not shear:
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.4))
        _closure_curve(a1, ds)
        d1 = ds["displacement"].sel(axis=1).values * UM
        a2.plot(d1, ds["n_contact"].values / n, color="k", label="in contact", **MARK)
        a2.set_xlabel(r"closure $\Delta_1$ [µm]")
        a2.set_ylabel("fraction of the population in contact [1]")
        fig.suptitle(ds.attrs.get("title", "asperity_sim run") + " (no shear)")
        fig.tight_layout()
        return fig
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    x = path_length(ds) * UM
    ax = axes[0, 0]
    for k in (1, *shear):
        _band(ax, x, ds["stress"].sel(axis=k).values * MPA, ds["stress_stderr"].sel(axis=k).values * MPA,
              COLORS[k], label=rf"$\sigma_{k}$")
    ax.set_ylabel("interface stress [MPa]")
    band_legend(ax)
    ax = axes[0, 1]
    s1 = ds["stress"].sel(axis=1).values
    control = ds["control"].values.astype(bool)
    d, s = ds["displacement"].values, ds["stress"].values
    sheared = np.any((~control[:, 1:] & (d[:, 1:] != 0.0)) | (control[:, 1:] & (s[:, 1:] != 0.0)), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.hypot(s[:, 1], s[:, 2])
        ratio = np.where((s1 > 0) & sheared, tau / s1, np.nan)  # before any shear: Monte Carlo noise, not drawn
    ax.plot(x, ratio, color="k", **MARK)
    ax.set_ylabel(r"shear resistance $|\sigma_{23}|/\sigma_1$ [1]")
    ax = axes[1, 1]
    ax.plot(x, ds["n_contact"].values / n, label="in contact", **MARK)
    ax.plot(x, ds["n_slip"].values / n, label="in full slip", **MARK)
    ax.set_ylabel("fraction of the population [1]")
    ax.legend(fontsize=8)
    for ax in (axes[0, 0], axes[0, 1], axes[1, 1]):
        ax.set_xlabel(r"path length $\int|d\Delta|$ [µm]")
        _stage_marks(ax, ds, x)
    _closure_curve(axes[1, 0], ds)
    fig.suptitle(ds.attrs.get("title", "asperity_sim run"))
    fig.tight_layout()
    return fig


def plot_cyclic_shear(runs: dict):
    """Hysteresis loops (sigma_2 against Delta_2) and loop dissipation against amplitude (log-log)."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.4))
    for (name, ds), color in zip(runs.items(), ("tab:red", "tab:blue", "tab:green", "tab:orange")):
        sh = shear_stage(ds)
        a1.plot(sh["displacement"].sel(axis=2).values * UM, sh["stress"].sel(axis=2).values * MPA, color=color,
                lw=0.9, label=name, marker="o", ms=1.5)
        amp, W = ds["loop_amplitude"].values, ds["loop_dissipation"].values
        a2.loglog(amp * UM, W, "o-", color=color, label=name)
    a = ds["loop_amplitude"].values * UM
    ref = W[0] * (a / a[0]) ** 3
    a2.loglog(a, ref, "k:", lw=0.9, label=r"$\propto A^3$", gid="guide")
    a1.set_xlabel(r"shear displacement $\Delta_2$ [µm]")
    a1.set_ylabel(r"shear stress $\sigma_2$ [MPa]")
    a1.set_title("hysteresis loops at constant normal stress (law mdr)")
    a1.legend(fontsize=8)
    a2.set_xlabel(r"cycle amplitude $A$ [µm]")
    a2.set_ylabel(r"dissipation per cycle [J m$^{-2}$]")
    a2.set_title("energy dissipated per stable cycle")
    a2.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_rotating_shear(runs: dict, turn_deg):
    """Shear stress path in the (sigma_2, sigma_3) plane and non-coaxiality after the turn."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.6))
    colors = {"R1": "tab:red", "S1": "tab:blue"}
    for (name, law), ds in runs.items():
        style = "-" if "dissipation" in ds else "--"  # a history law records its energies
        tau = ds["stress"].sel(axis=[2, 3]).values * MPA
        a1.plot(tau[:, 0], tau[:, 1], style, color=colors.get(name, "k"), label=f"{name}, {law}", **MARK)
        turned = ds["stage"].values == ds["stage"].values.max()
        d2 = ds["displacement"].sel(axis=[2, 3]).values
        start = d2[np.flatnonzero(turned)[0] - 1]
        travelled = np.linalg.norm(d2[turned] - start, axis=1) * UM
        a2.plot(travelled, np.degrees(ds["non_coaxiality"].values[turned]), style, color=colors.get(name, "k"),
                label=f"{name}, {law}", **MARK)
    a1.set_xlabel(r"$\sigma_2$ [MPa]")
    a1.set_ylabel(r"$\sigma_3$ [MPa]")
    a1.set_aspect("equal", adjustable="datalim")
    a1.set_title(f"shear stress path (shear turns by {turn_deg:g}°)")
    a1.legend(fontsize=8)
    a2.set_xlabel("shear displacement after the turn [µm]")
    a2.set_ylabel("angle between shear stress and displacement increment [deg]")
    a2.set_title("non-coaxiality")
    a2.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_history_vs_paper(runs: dict):
    """Fig. 13 curves with the `paper` and the `mdr` law, and their difference."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.4))
    colors = {"R1": "tab:red", "S1": "tab:blue"}
    names = sorted({name for name, _ in runs})
    for name in names:
        curves = {}
        for law, style in (("paper", "--"), ("mdr", "-")):
            sh = shear_stage(runs[(name, law)])
            d2 = sh["displacement"].sel(axis=2).values * UM
            ratio = sh["stress"].sel(axis=2).values / sh["stress"].sel(axis=1).values
            se = sh["stress_stderr"].sel(axis=2).values / sh["stress"].sel(axis=1).values
            curves[law] = (d2, ratio, se)
            a1.plot(d2, ratio, style, color=colors.get(name, "k"), label=f"{name}, {law}", **MARK)
        d2, rm, se = curves["mdr"]
        _band(a2, d2, rm - curves["paper"][1], se, colors.get(name, "k"), label=f"{name}: mdr - paper")
    a1.set_xlabel(r"shear displacement $\Delta_2$ [µm]")
    a1.set_ylabel(r"shear resistance $\sigma_2/\sigma_1$ [1]")
    a1.set_title("Fig. 13 path: history law against the paper's law")
    a1.legend(fontsize=8)
    a2.axhline(0.0, **GUIDE)
    a2.set_xlabel(r"shear displacement $\Delta_2$ [µm]")
    a2.set_ylabel("mdr − paper, shear resistance [1]")
    a2.text(0.98, 0.02, "band: the standard error of one curve (the common-sample difference is known better)",
             transform=a2.transAxes, ha="right", va="bottom", fontsize=7, color="0.4")
    a2.set_title("history effect")
    band_legend(a2)
    fig.tight_layout()
    return fig


def plot_unload_reload(runs: dict):
    """Shear stress and contact fraction along a path with normal unloading and reloading."""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.4))
    colors = {"R1": "tab:red", "S1": "tab:blue"}
    for (name, law), ds in runs.items():
        style = "-" if "dissipation" in ds else "--"  # a history law records its energies
        x = path_length(ds) * UM
        a1.plot(x, ds["stress"].sel(axis=2).values * MPA, style, color=colors.get(name, "k"), label=f"{name}, {law}",
                **MARK)
        n = float(ds.attrs.get("n_asperities", 1))
        a2.plot(x, ds["n_contact"].values / n, style, color=colors.get(name, "k"), label=f"{name}, {law}", **MARK)
        _stage_marks(a1, ds, x)
        _stage_marks(a2, ds, x)
    a1.set_xlabel(r"path length $\int|d\Delta|$ [µm] (closure | shear | unload | reload | shear)")
    a1.set_ylabel(r"shear stress $\sigma_2$ [MPa]")
    a1.set_title("shear with normal unloading and reloading")
    a1.legend(fontsize=8)
    a2.set_xlabel(r"path length $\int|d\Delta|$ [µm]")
    a2.set_ylabel("fraction of asperities in contact [1]")
    a2.legend(fontsize=8)
    fig.tight_layout()
    return fig
