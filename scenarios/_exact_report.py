"""Figures and Markdown tables of scenarios/exact_contact.py, read from its netCDF file alone."""

from __future__ import annotations

import numpy as np

STYLE = {"parametric": ("tab:blue", "-"), "empirical": ("tab:orange", "-"), "independent": ("tab:green", ":"),
         "elliptic": ("tab:red", "--"), "elliptic_parametric": ("tab:purple", "--"),
         "contact_scale": ("tab:brown", "-."), "interaction": ("tab:cyan", "-"),
         "elliptic_interaction": ("tab:pink", "-")}
WITHIN = 0.10  # the goal: within 10 % of BEM


def ratios(ds, what, variant, family):
    """model / BEM per pair and load (pair, load) for ``what`` in ("mean_gap", "area_fraction")."""
    m = ds[f"model_{what}"].sel(family=family, variant=variant).values
    return m / ds[f"bem_{what}"].sel(family=family).values


def _cell(r):
    """'mean (min–max)' over the pairs of a column of ratios; bold when the mean is more than 10 % off."""
    r = r[np.isfinite(r)]
    text = f"{r.mean():.3f}" + (f" ({r.min():.2f}–{r.max():.2f})" if r.size > 1 else "")
    return f"**{text}**" if abs(r.mean() - 1.0) > WITHIN else text


def _pm(values, scale, digits=3):
    v = values[np.isfinite(values)] * scale
    return f"{v.mean():.{digits}g} ± {v.std(ddof=1):.2g}" if v.size > 1 else f"{v.mean():.{digits}g}"


def normal_tables(ds) -> str:
    out = []
    variants = [str(v) for v in ds.variant.values]
    for fam in ds.family.values:
        f = ds.sel(family=fam)
        label = [s for s in ds.attrs["families"].split("; ") if s.startswith(f"{fam}:")][0]
        npairs = int(np.isfinite(f.bem_mean_gap.values[:, 0]).sum())
        out.append(f"\nFamily {label}, {npairs} pairs; ratios model / BEM at the same mean pressure, mean over the "
                   f"pairs (range); bold: mean more than 10 % from 1.")
        for what, name in (("mean_gap", "mean gap"), ("area_fraction", "contact area")):
            head = "| p [MPa] | BEM area [%] | BEM mean gap [um] | " + " | ".join(variants) + " |"
            lines = [f"\n{name} ratio, family {fam}:\n", head, "|" + "---|" * (3 + len(variants))]
            for k in range(ds.sizes["load"]):
                cells = [_cell(ratios(ds, what, v, fam)[:, k]) for v in variants]
                lines.append(f"| {float(f.pressure[k]) / 1e6:.3g} | {_pm(f.bem_area_fraction.values[:, k], 100)} | "
                             f"{_pm(f.bem_mean_gap.values[:, k], 1e6)} | " + " | ".join(cells) + " |")
            out += lines
        se_gap = float(np.nanmax(f.model_mean_gap_stderr.values / f.model_mean_gap.values))
        se_area = float(np.nanmax(f.model_area_fraction_stderr.values / f.model_area_fraction.values))
        out.append(f"\nLargest Monte Carlo standard error, family {fam}: {100 * se_gap:.2f} % of a mean gap, "
                   f"{100 * se_area:.2f} % of an area fraction.")
    return "\n".join(out)


def summary_table(ds) -> str:
    """Per family and variant: loads at which the mean ratio is within 10 %, for gap, area and both."""
    variants = [str(v) for v in ds.variant.values]
    lines = ["\n| family | variant | gap within 10 % | area within 10 % | both | worst gap ratio | worst area ratio |",
             "|---|---|---|---|---|---|---|"]
    for fam in ds.family.values:
        for v in variants:
            g, a = np.nanmean(ratios(ds, "mean_gap", v, fam), 0), np.nanmean(ratios(ds, "area_fraction", v, fam), 0)
            ok_g, ok_a = np.abs(g - 1) <= WITHIN, np.abs(a - 1) <= WITHIN
            L = g.size
            lines.append(f"| {fam} | {v} | {ok_g.sum()}/{L} | {ok_a.sum()}/{L} | {(ok_g & ok_a).sum()}/{L} | "
                         f"{g[np.argmax(np.abs(g - 1))]:.3f} | {a[np.argmax(np.abs(a - 1))]:.3f} |")
    return "\n".join(lines)


def resolution_table(ds) -> str:
    """Twice the resolution: how BEM and the model (fitted again) change, on the pairs solved twice."""
    lines = ["\n| family | p [MPa] | BEM area 2x/1x | BEM gap 2x/1x | empirical gap ratio 1x → 2x | "
             "empirical area ratio 1x → 2x | parametric area ratio 1x → 2x |", "|---|---|---|---|---|---|---|"]
    for fam in ds.family.values:
        f = ds.sel(family=fam)
        have = np.isfinite(f.bem2_mean_gap.values[:, 0])
        if not have.any():
            continue
        for k in range(ds.sizes["load"]):
            sel = lambda v: v[have, k]  # noqa: E731
            b1g, b2g = sel(f.bem_mean_gap.values), sel(f.bem2_mean_gap.values)
            b1a, b2a = sel(f.bem_area_fraction.values), sel(f.bem2_area_fraction.values)

            def m(var, v):
                return sel(f[f"model{var}"].sel(variant=v).values)

            lines.append(
                f"| {fam} | {float(f.pressure[k]) / 1e6:.3g} | {np.mean(b2a / b1a):.3f} | {np.mean(b2g / b1g):.4f} | "
                f"{np.mean(m('_mean_gap', 'empirical') / b1g):.3f} → {np.mean(m('2_mean_gap', 'empirical') / b2g):.3f} | "
                f"{np.mean(m('_area_fraction', 'empirical') / b1a):.3f} → "
                f"{np.mean(m('2_area_fraction', 'empirical') / b2a):.3f} | "
                f"{np.mean(m('_area_fraction', 'parametric') / b1a):.3f} → "
                f"{np.mean(m('2_area_fraction', 'parametric') / b2a):.3f} |")
    return "\n".join(lines)


def shear_runs(ds, fam):
    """(j, the family's data at shear load j, the pairs that have it) for each shear load with a BEM solution."""
    f = ds.sel(family=fam)
    for j in range(ds.sizes["shear_load"]):
        g = f.sel(shear_load=j)
        have = np.isfinite(g.bem_shear_stiffness.values)
        if have.any():
            yield j, g, have


def shear_tables(ds) -> str:
    out = []
    models = [str(m) for m in ds.shear_model.values]
    for fam in ds.family.values:
        for j, g, have in shear_runs(ds, fam):
            c = g.bem_shear_contact_fraction.values[have, 0]
            out.append(f"\nShear, family {fam}, p = {float(g.shear_pressure) / 1e6:.3g} MPa (BEM contact "
                       f"{100 * c.mean():.3g} %), {int(have.sum())} pairs; ratios model / BEM, mean (range):\n")
            out.append("| Q / mu p (BEM) | BEM displacement [nm] | BEM stick / contact | "
                       + " | ".join(f"delta ratio {m} | stick ratio {m}" for m in models) + " |")
            out.append("|" + "---|" * (3 + 2 * len(models)))
            bq = g.bem_shear_traction.values[have] / (float(ds.attrs["mu"]) * float(g.shear_pressure))
            bd, bs = g.bem_shear_displacement.values[have], g.bem_stick_fraction.values[have]
            for i in range(ds.sizes["level"]):
                cells = []
                for m in models:
                    gm = g.sel(shear_model=m)
                    cells += [_cell(gm.model_shear_displacement.values[have, i] / bd[:, i]),
                              _cell(gm.model_stick_fraction.values[have, i] / bs[:, i])]
                out.append(f"| {bq[:, i].mean():.3f} | {_pm(bd[:, i], 1e9)} | {np.mean(bs[:, i] / c):.3f} | "
                           + " | ".join(cells) + " |")
            k_cells = [_cell(g.sel(shear_model=m).model_shear_stiffness.values[have] / g.bem_shear_stiffness.values[have])
                       for m in models]
            out.append(f"| initial stiffness (full stick) | {_pm(g.bem_shear_stiffness.values[have], 1e-12)} MPa/um | | "
                       + " | ".join(f"{k} | " for k in k_cells) + "")
    return "\n".join(out)


def tables(ds) -> str:
    return "\n".join([normal_tables(ds), "\nWithin 10 % of BEM (mean ratio over the pairs):", summary_table(ds),
                      "\nTwice the resolution (same surfaces):", resolution_table(ds), shear_tables(ds)])


def _mpl():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def plot_normal(ds):
    """Mean gap and contact area against pressure, one column per family: BEM (mean ± s.d. over pairs), models."""
    plt = _mpl()
    nf = ds.sizes["family"]
    fig, ax = plt.subplots(2, nf, figsize=(5.5 * nf, 8.5), squeeze=False)
    for c, fam in enumerate(ds.family.values):
        f = ds.sel(family=fam)
        p = f.pressure.values / 1e6
        for r, (what, scale) in enumerate((("mean_gap", 1e6), ("area_fraction", 100))):
            b = f[f"bem_{what}"].values * scale
            ax[r, c].errorbar(p, np.nanmean(b, 0), yerr=np.nanstd(b, 0), fmt="ko", capsize=3, label="BEM (tamaas)",
                              zorder=5)
            for v in ds.variant.values:
                color, ls = STYLE.get(str(v), ("k", "-"))
                ax[r, c].plot(p, np.nanmean(f[f"model_{what}"].sel(variant=v).values, 0) * scale, ls, color=color,
                              label=str(v))
            ax[r, c].set_xscale("log")
            ax[r, c].grid(alpha=0.3, which="both")
        ax[1, c].set_yscale("log")
        ax[0, c].set(title=[s for s in ds.attrs["families"].split("; ") if s.startswith(f"{fam}:")][0],
                     ylabel="mean gap [um]")
        ax[1, c].set(xlabel="mean pressure [MPa]", ylabel="contact-area fraction [%]")
    ax[0, 0].legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_shear(ds):
    """Tangential displacement and stick fraction against Q / (mu p), one column per family that has shear runs."""
    plt = _mpl()
    sheared = [f for f in ds.family.values if np.isfinite(ds.bem_shear_stiffness.sel(family=f).values).any()]
    nf = max(len(sheared), 1)
    fig, ax = plt.subplots(2, nf, figsize=(5.5 * nf, 8.5), squeeze=False)
    marks = ("o", "s", "^")
    for c, fam in enumerate(sheared):
        for j, g, have in shear_runs(ds, fam):
            mp = float(ds.attrs["mu"]) * float(g.shear_pressure)
            q = g.bem_shear_traction.values[have] / mp
            contact = g.bem_shear_contact_fraction.values[have, :1]
            tag = f"p = {float(g.shear_pressure) / 1e6:.3g} MPa"
            for r, (b, scale) in enumerate(((g.bem_shear_displacement.values[have], 1e9),
                                           (g.bem_stick_fraction.values[have] / contact, 1.0))):
                ax[r, c].errorbar(q.mean(0), np.mean(b, 0) * scale, yerr=np.std(b, 0) * scale,
                                  fmt="k" + marks[j % 3], capsize=3, label=f"BEM, {tag}")
            for m in ds.shear_model.values:
                gm = g.sel(shear_model=m)
                color = STYLE.get(str(m), ("k", "-"))[0]
                qm = gm.model_shear_traction.values[have] / mp
                ax[0, c].plot(qm.mean(0), gm.model_shear_displacement.values[have].mean(0) * 1e9, "-", color=color,
                              marker=marks[j % 3], ms=3, label=f"mdr, {m}, {tag}")
                ax[1, c].plot(qm.mean(0), (gm.model_stick_fraction.values[have] / contact).mean(0), "-", color=color,
                              marker=marks[j % 3], ms=3)
        ax[0, c].set(title=[s for s in ds.attrs["families"].split("; ") if s.startswith(f"{fam}:")][0],
                     ylabel="tangential displacement [nm]", yscale="log")
        ax[1, c].set(xlabel="mean shear traction Q / (mu p)", ylabel="stick area / BEM contact area")
        for a in ax[:, c]:
            a.grid(alpha=0.3, which="both")
    ax[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return fig
