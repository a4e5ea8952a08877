"""Figures of sweeps, strength envelopes and cyclic curves, and the files an envelope or cyclic run writes.

Owns the plots of a sweep's dataset and of the joint-property curves, and
:func:`write_products` (netCDF, CSV and PNG of an envelope or cyclic run).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import xarray as xr

from ..output.plotting import save_figure
from .envelope import SIGMA_REF, write_csv

# -- figure ---------------------------------------------------------------------------

def plot_sweep(ds: xr.Dataset):
    """Ensemble means ±2 standard errors of every grid point: stresses, shear resistance, displacements, contacts.

    Abscissa: path length of the mean displacement [um]; one colour per grid point.
    (Lives here rather than in :mod:`asperity_sim.output.plotting`, which does not know sweeps yet.)
    """
    from ..output.plotting import BAND, MARK, MPA, UM, band_legend, plt

    grid = [d for d in ds["stress"].dims if d not in ("replica", "step", "axis")]
    stacked = ds.stack(point=grid) if grid else ds.expand_dims(point=[0])
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    styles = {1: "-", 2: "--", 3: ":"}
    for j in range(stacked.sizes["point"]):
        p = stacked.isel(point=j)
        n = float(p["n"]) if "n" in grid else float(ds.attrs.get("n_asperities", 1))  # n may be swept
        label = ", ".join(f"{g} = {p[g].item():.4g}" if ds[g].dtype.kind in "fiu" else f"{g} = {p[g].item()}"
                          for g in grid) or "ensemble"
        color = colors[j % len(colors)]
        d = p["displacement_mean"].values
        ok = np.all(np.isfinite(d), axis=1)
        x = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(np.where(ok[:, None], d, 0.0), axis=0),
                                                            axis=1))]) * UM
        x = np.where(ok, x, np.nan)
        for k in (1, 2, 3):
            s = p["stress_mean"].sel(axis=k).values
            if np.nanmax(np.abs(s), initial=0.0) == 0.0:
                continue
            se = np.nan_to_num(p["stress_sem"].sel(axis=k).values)
            axes[0, 0].plot(x, s * MPA, styles[k], color=color, label=rf"$\sigma_{k}$, {label}", **MARK)
            axes[0, 0].fill_between(x, (s - BAND * se) * MPA, (s + BAND * se) * MPA, color=color, alpha=0.2, lw=0)
            dk = p["displacement_mean"].sel(axis=k).values
            dse = np.nan_to_num(p["displacement_sem"].sel(axis=k).values)
            axes[1, 0].plot(x, dk * UM, styles[k], color=color, label=rf"$\Delta_{k}$, {label}", **MARK)
            axes[1, 0].fill_between(x, (dk - BAND * dse) * UM, (dk + BAND * dse) * UM, color=color, alpha=0.2, lw=0)
        s = p["stress_mean"].values
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(s[:, 0] > 0, np.hypot(s[:, 1], s[:, 2]) / s[:, 0], np.nan)
        axes[0, 1].plot(x, ratio, color=color, label=label, **MARK)
        axes[1, 1].plot(x, p["n_contact_mean"].values / n, "-", color=color, label=f"in contact, {label}", **MARK)
        axes[1, 1].plot(x, p["n_slip_mean"].values / n, "--", color=color, label=f"full slip, {label}", **MARK)
    axes[0, 0].set_ylabel("interface stress [MPa] (ensemble mean ± 2 s.e.)")
    axes[0, 1].set_ylabel(r"shear resistance $|\sigma_{23}|/\sigma_1$ [1]")
    axes[1, 0].set_ylabel("interface displacement [µm] (ensemble mean ± 2 s.e.)")
    axes[1, 1].set_ylabel("fraction of the population [1]")
    for ax in axes.ravel():
        ax.set_xlabel(r"path length of the mean displacement $\int|d\Delta|$ [µm]")
        if ax in (axes[0, 0], axes[1, 0]):
            band_legend(ax, fontsize=7)
        else:
            ax.legend(fontsize=7)
    fig.suptitle(f"{ds.attrs.get('title', 'asperity_sim sweep')}\n{ds.attrs.get('replicas')} replica(s) per point; "
                 "bands: ±2 standard errors of the ensemble mean")
    fig.tight_layout()
    return fig


def write_products(ds: xr.Dataset, output) -> dict:
    """Write ``ds`` to ``output`` (.nc), the table next to it (.csv) and the figure (.png); returns the paths."""
    import matplotlib.pyplot as plt

    from ..output.netcdf import write_netcdf

    output = Path(output)
    out = {"netcdf": write_netcdf(ds, output), "csv": write_csv(ds, output.with_suffix(".csv"))}
    fig = plot_envelope(ds) if ds.attrs.get("product") == "envelope" else plot_cyclic(ds)
    out["figure"] = output.with_suffix(".png")
    save_figure(fig, out["figure"], dpi=130)
    plt.close(fig)
    return out


# -- figures (from the dataset alone) --------------------------------------------------------

def _errorbar(ax, x, ds, name, scale, label, **kw):
    y = ds[f"{name}_mean"].values * scale
    se = np.nan_to_num(ds[f"{name}_sem"].values) * scale
    return ax.errorbar(x, y, yerr=2 * se, fmt="o-", capsize=3, ms=4, label=f"{label} (bars ±2 SE)", **kw)


def plot_envelope(ds: xr.Dataset):
    """Shear strength, friction and dilation, stiffnesses against sigma_n (mean ± 2 s.e.), fitted envelopes."""
    from ..output.plotting import MPA, UM, plt

    sig = ds["sigma_n"].values
    x = sig * MPA
    log = sig.size > 1 and sig.max() / sig.min() > 20
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5))
    ax = axes[0, 0]
    _errorbar(ax, x, ds, "peak_shear_stress", MPA, "peak", color="tab:red")
    _errorbar(ax, x, ds, "residual_shear_stress", MPA, "residual", color="tab:blue")
    if "mc_cohesion" in ds:
        xs = np.geomspace(sig.min(), sig.max(), 100) if log else np.linspace(sig.min(), sig.max(), 100)
        for which, color in (("peak", "tab:red"), ("residual", "tab:blue")):
            f = ds.sel(strength=which)
            c, phi = float(f.mc_cohesion), float(f.mc_friction_angle)
            ax.plot(xs * MPA, (c + xs * math.tan(phi)) * MPA, "--", color=color, lw=1,
                    label=f"{which} Mohr-Coulomb: c = {c * MPA:.3g} MPa, phi = {math.degrees(phi):.1f} deg")
            A, B = float(f.power_law_A), float(f.power_law_B)
            ax.plot(xs * MPA, A * (xs / SIGMA_REF) ** B * MPA, ":", color=color, lw=1.3,
                    label=f"{which} power law: A = {A * MPA:.3g} MPa, B = {B:.3f}")
    ax.set_ylabel("shear stress [MPa] (mean ± 2 s.e.)")
    ax.set_title("strength envelope")
    ax = axes[0, 1]
    _errorbar(ax, x, ds, "peak_friction", 1.0, r"peak $\tau/\sigma_1$", color="tab:red")
    _errorbar(ax, x, ds, "residual_friction", 1.0, r"residual $\tau/\sigma_1$", color="tab:blue")
    ax.set_ylabel(r"friction coefficient $\tau/\sigma_1$ [1]")
    ax2 = ax.twinx()
    _errorbar(ax2, x, ds, "dilation_angle_peak", 180 / math.pi, "dilation angle at peak", color="0.3")
    ax2.set_ylabel("dilation angle at peak [deg] (positive: opening)")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=7)
    ax = axes[1, 0]
    _errorbar(ax, x, ds, "normal_stiffness", 1e-12, r"normal $d\sigma_1/d\Delta_1$", color="tab:green")
    _errorbar(ax, x, ds, "shear_stiffness", 1e-12, r"shear $d\tau/ds$", color="tab:purple")
    ax.set_ylabel("stiffness at the start of shear [MPa/µm] (mean ± 2 s.e.)")
    ax = axes[1, 1]
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    stage = ds["stage"].values
    shear = stage >= 2
    for i, s in enumerate(sig):
        d2 = ds["displacement_mean"].isel(sigma_n=i).values[:, 1]
        t2 = ds["stress_mean"].isel(sigma_n=i).values[:, 1]
        s1 = ds["stress_mean"].isel(sigma_n=i).values[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            ax.plot(d2[shear] * UM, (t2 / s1)[shear], color=colors[i % len(colors)],
                    label=rf"$\sigma_n$ = {s * MPA:.3g} MPa")
    ax.set_xlabel(r"shear displacement $\Delta_2$ [µm]")
    ax.set_ylabel(r"shear resistance $\sigma_2/\sigma_1$ [1] (ensemble mean)")
    ax.legend(fontsize=6, ncol=2)
    for a in (axes[0, 0], axes[0, 1], axes[1, 0]):
        a.set_xlabel(r"normal stress $\sigma_n$ [MPa]")
        if log:
            a.set_xscale("log")
    if log:
        axes[0, 0].set_yscale("log")
        axes[1, 0].set_yscale("log")
    axes[0, 0].legend(fontsize=6)
    axes[1, 0].legend(fontsize=7)
    fig.suptitle(f"{ds.attrs.get('title', '')}\nlaw {ds.attrs.get('law')}, n = {ds.attrs.get('n_asperities')}, "
                 f"{ds.attrs.get('replicas')} replica(s); error bars ±2 s.e.; fits: "
                 f"{100 * float(ds.attrs.get('fit_confidence_level', 0.95)):g} % CIs in the CSV", fontsize=9)
    fig.tight_layout()
    return fig


def plot_cyclic(ds: xr.Dataset):
    """G/Gmax, damping ratio, loop energy against amplitude (mean ± 2 s.e.), and the last loops."""
    from ..output.plotting import MPA, UM, plt

    a = ds["amplitude"].values * UM
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5))
    _errorbar(axes[0, 0], a, ds, "secant_stiffness_ratio", 1.0, r"$k_{sec}/k_0$", color="tab:blue")
    axes[0, 0].set_ylabel(r"secant shear stiffness / initial ($G/G_{max}$) [1]")
    _errorbar(axes[0, 1], a, ds, "damping_ratio", 100.0, r"$W_d / (4\pi W_s)$", color="tab:red")
    axes[0, 1].set_ylabel("equivalent damping ratio [%]")
    _errorbar(axes[1, 0], a, ds, "loop_dissipation", 1.0, r"loop area $\oint\tau\,ds$", color="tab:purple")
    if np.isfinite(ds["cycle_dissipation_mean"].values).any():
        _errorbar(axes[1, 0], a, ds, "cycle_dissipation", 1.0, "recorded dissipation", color="0.4")
    axes[1, 0].set_ylabel(r"energy dissipated per cycle [J/m$^2$]")
    ax = axes[1, 1]
    stage = ds["stage"].values
    last = int(stage.max())
    cycle = (stage > last - 3) | (np.r_[stage[1:], -1] == last - 2)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, amp in enumerate(ds["amplitude"].values):
        d2 = ds["displacement_mean"].isel(amplitude=i).values[:, 1]
        t2 = ds["stress_mean"].isel(amplitude=i).values[:, 1]
        ax.plot(d2[cycle] / amp, t2[cycle] * MPA, color=colors[i % len(colors)], label=f"a = {amp * UM:.3g} µm")
    ax.set_xlabel(r"$\Delta_2 / a$ [1] (last cycle)")
    ax.set_ylabel(r"shear stress $\sigma_2$ [MPa] (ensemble mean)")
    ax.legend(fontsize=6)
    for ax in (axes[0, 0], axes[0, 1], axes[1, 0]):
        ax.set_xscale("log")
        ax.set_xlabel("shear amplitude a [µm]")
        ax.legend(fontsize=7)
    if (ds["loop_dissipation_mean"].values > 0).all():
        axes[1, 0].set_yscale("log")
    fig.suptitle(f"{ds.attrs.get('title', '')}\nlaw {ds.attrs.get('law')}, n = {ds.attrs.get('n_asperities')}, "
                 f"{ds.attrs.get('replicas')} replica(s), last of {ds.attrs.get('cycles')} cycles; "
                 "error bars ±2 s.e.", fontsize=9)
    fig.tight_layout()
    return fig
