"""How far is the asperity model from exact contact mechanics of the same surfaces? (BEM, tamaas)

Physical question: two synthetic self-affine surfaces are summed into a composite topography
(asperity_sim.analysis.surfaces); its normal contact against a flat elastic half-space of the model's
own composite modulus E* = G/(1 - nu) (SPEC §5) is solved exactly by the tamaas
boundary-element solver (Polonsky–Keer, periodic) at loads giving contact-area fractions from
0.1 % to about 10 %.  The same composite is fitted (N, alpha, beta, R_m, R_sigma; the rest
from preset R1) and two asperity models answer at the same mean pressures: the fitted
parametric model (Population.sample), the empirical population that resamples the
identified summits jointly (surfaces.empirical_population), and the same with depth and radius
resampled independently ("independent": the data's marginals under the model's assumption of
independence, SPEC §2), which separates the shape of the fitted densities from that assumption.

Relations.  BEM: tamaas with E = E*, nu = 0 (its E/(1 - nu²) is then E*), rigid composite
surface h; closure delta = max(h) - mean(u) (u the elastic surface, tamaas' displacement),
mean separation = mean(u - h), area fraction = fraction of pixels with positive pressure.
Model: sigma_1(Delta_1) from Eq. (23) (Population.evaluate, law paper, Delta_2 = Delta_3 = 0),
solved for Delta_1 at each BEM pressure (Brent); mean separation = max(h) - mean(h) - Delta_1
(Delta_1 is measured from first contact of the highest summit, as the BEM closure);
area fraction = N E[pi R delta_n cos(theta)] over contacts (Hertz a² = R delta_n, projected).
Ratios model/BEM at equal pressure are written for the closure and the area fraction.

Run:   python scenarios/bem_closure.py [--pixels 512] [--loads 8] [--n 200000] [--quick]
Writes outputs/bem_closure.nc and outputs/bem_closure.png; prints a Markdown table.
Expected run time: about 1 min at 512² (each BEM point a few seconds on one core); --quick 128²: a few s.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import time
from pathlib import Path

import numpy as np
import xarray as xr
from scipy import optimize

from asperity_sim import evaluate, presets
from asperity_sim.geometry import theta_m_array
from asperity_sim.output.netcdf import read_netcdf, write_netcdf
from asperity_sim.checks import check_real
from asperity_sim.sampling.population import Population
from asperity_sim.analysis.surfaces.bem import bem_contact

OUTPUTS = Path(__file__).resolve().parent.parent / "outputs"
MODELS = ("parametric", "empirical", "independent")
L = 1e-3  # [m] side of the surfaces
SURFACE = {"hurst": 0.8, "rms_height": 0.5e-6}  # each surface; cutoffs in pixels from the command line


def parse(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--pixels", type=int, default=512, help="grid points per side (default 512)")
    p.add_argument("--loads", type=int, default=8, help="BEM loads from 0.1 %% to about 10 %% area (default 8)")
    p.add_argument("--n", type=int, default=200_000, help="asperities per model population (default 200000)")
    p.add_argument("--cutoff", type=int, default=16, help="short-wavelength cutoff in pixels; long cutoff 4x "
                                                         "(default 16; --quick 8)")
    p.add_argument("--seed", type=int, default=1, help="seed of the first surface (the second: seed + 1)")
    p.add_argument("--preset", default="R1", choices=tuple(presets.TABLE1),
                   help="material (G, nu) and unidentified parameters (default R1)")
    p.add_argument("--tolerance", type=float, default=1e-10, help="tamaas solver tolerance (default 1e-10)")
    p.add_argument("--outdir", type=Path, default=OUTPUTS, help="folder for .nc and .png (default outputs/)")
    p.add_argument("--quick", action="store_true", help="tiny run for smoke tests (128², 3 loads, n = 20000)")
    args = p.parse_args(argv)
    if args.quick:
        args.pixels, args.loads, args.n = min(args.pixels, 128), min(args.loads, 3), min(args.n, 20_000)
        args.cutoff = min(args.cutoff, 8)
    for name, lo in (("pixels", 64), ("loads", 2), ("n", 100), ("cutoff", 4)):
        if getattr(args, name) < lo:
            p.error(f"--{name} = {getattr(args, name)} is out of range (valid range: integer >= {lo})")
    if args.pixels % 16:
        p.error(f"--pixels = {args.pixels} is out of range (valid range: a multiple of 16, >= 64)")
    check_real("--tolerance", args.tolerance, 0.0, 1e-4, lo_open=True)
    return args


def area_fraction(pop: Population, d1: float) -> float:
    """N E[pi R delta_n cos theta] [1] over contacts at Delta = (d1, 0, 0) (Hertz, projected; SPEC §3–§4)."""
    p = pop.params
    k = np.searchsorted(pop.r, d1)
    r, R, u = pop.r[:k], pop.R[:k], pop.u[:k]
    theta = (2.0 / math.pi) * u * theta_m_array(p, max(0.0, p.r_o + d1), R)
    dn = np.cos(theta) * (d1 - r)
    return float(p.N * pop.weight * np.sum(math.pi * R * np.maximum(dn, 0.0) * np.cos(theta)))


def closure_at(pop: Population, pressure: float) -> float:
    """Delta_1 [m] at which sigma_1 (Eq. 23, law paper, no shear) equals ``pressure`` [Pa]."""
    def f(d1):
        return evaluate(pop, (d1, 0.0, 0.0)).stress[0] - pressure

    hi = max(pop.r[min(pop.n - 1, 10)], pop.params.beta)
    while f(hi) < 0.0:
        hi *= 2.0
    return optimize.brentq(f, 0.0, hi, xtol=1e-13, rtol=1e-10)


def _attrs(units, long_name):
    return {"units": units, "long_name": long_name}


def main(argv=None):
    args = parse(argv)
    if importlib.util.find_spec("tamaas") is None:
        print('bem_closure needs tamaas: pip install "asperity-sim[bem]"', file=sys.stderr)
        return 1
    from asperity_sim.analysis import surfaces

    args.outdir.mkdir(parents=True, exist_ok=True)
    n, dx = args.pixels, L / args.pixels
    kw = dict(hurst=SURFACE["hurst"], rms_height=SURFACE["rms_height"], short_cutoff=args.cutoff * dx,
              long_cutoff=4 * args.cutoff * dx)
    a = surfaces.synthetic(n, L, seed=args.seed, **kw)
    b = surfaces.synthetic(n, L, seed=args.seed + 1, **kw)
    t0 = time.perf_counter()
    res = surfaces.fit(a, b, base=args.preset)
    fit_seconds = time.perf_counter() - t0
    h = res.surface.heights
    params = res.params
    E_star = params.E_star
    m0, m2, m4 = surfaces.spectral_moments(res.surface)
    # Persson: area fraction ~ 2 p / (E* rms slope); aim at 0.1 % .. 10 %
    rms_slope = math.sqrt(2.0 * m2)
    pressures = np.geomspace(1e-3, 1e-1, args.loads) * E_star * rms_slope / 2.0
    bem_out = bem_contact(h, res.surface.physical_sizes, E_star, pressures, args.tolerance)
    pops = {"parametric": Population.sample(params, args.n, seed=args.seed),
            "empirical": surfaces.empirical_population(res, args.n, seed=args.seed),
            "independent": surfaces.empirical_population(res, args.n, seed=args.seed, joint=False)}
    top = h.max() - h.mean()
    cl = np.empty((len(MODELS), args.loads))
    af = np.empty((len(MODELS), args.loads))
    for i, name in enumerate(MODELS):
        for k, p in enumerate(pressures):
            cl[i, k] = closure_at(pops[name], p)
            af[i, k] = area_fraction(pops[name], cl[i, k])
    grid = np.linspace(0.0, 1.2 * max(cl.max(), bem_out[0].max()), 60)
    curve_p = np.array([[evaluate(pops[m], (d, 0.0, 0.0)).stress[0] for d in grid] for m in MODELS])
    curve_a = np.array([[area_fraction(pops[m], d) for d in grid] for m in MODELS])
    ds = xr.Dataset(
        {
            "pressure": ("load", pressures, _attrs("Pa", "mean contact pressure (BEM load)")),
            "bem_closure": ("load", bem_out[0], _attrs("m", "BEM closure max(h) - mean(u)")),
            "bem_mean_separation": ("load", bem_out[1], _attrs("m", "BEM mean separation mean(u - h)")),
            "bem_area_fraction": ("load", bem_out[2], _attrs("1", "BEM contact-area fraction")),
            "bem_seconds": ("load", bem_out[3], _attrs("s", "wall time of the BEM solve at this load")),
            "model_closure": (("model", "load"), cl, _attrs("m", "model closure Delta_1 at the BEM pressure")),
            "model_mean_separation": (("model", "load"), top - cl,
                                      _attrs("m", "model mean separation max(h) - mean(h) - Delta_1")),
            "model_area_fraction": (("model", "load"), af,
                                    _attrs("1", "model contact-area fraction at the BEM pressure")),
            "closure_ratio": (("model", "load"), cl / bem_out[0], _attrs("1", "model / BEM closure at equal pressure")),
            "area_ratio": (("model", "load"), af / bem_out[2],
                           _attrs("1", "model / BEM contact-area fraction at equal pressure")),
            "curve_pressure": (("model", "closure"), curve_p, _attrs("Pa", "model mean pressure sigma_1 (Eq. 23)")),
            "curve_area_fraction": (("model", "closure"), curve_a, _attrs("1", "model contact-area fraction")),
        },
        coords={"model": ("model", list(MODELS), _attrs("1", "asperity model")),
                "load": ("load", np.arange(args.loads), _attrs("1", "load index")),
                "closure": ("closure", grid, _attrs("m", "closure Delta_1 from first contact"))},
        attrs={"title": "asperity model against BEM (tamaas, Polonsky-Keer) on the same composite surface",
               "source": "asperity_sim scenarios/bem_closure.py", "Conventions": "CF-1.8",
               "history": f"{time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())} bem_closure.py "
                          f"{' '.join(argv or sys.argv[1:])}",
               "surfaces": f"two synthetic self-affine surfaces, {n} x {n} points, {L * 1e3:g} mm, seeds {args.seed} "
                           f"and {args.seed + 1}, " + ", ".join(f"{k} = {v}" for k, v in SURFACE.items())
                           + f", short cutoff {args.cutoff} px, long cutoff {4 * args.cutoff} px",
               "E_star_Pa": E_star, "preset": args.preset, "n_asperities": args.n, "n_summits": res.summits.n,
               "fit_seconds": fit_seconds, "pixels": n, "rms_slope": rms_slope,
               "max_minus_mean_height_m": top, "tamaas_tolerance": args.tolerance,
               **{f"param_{k}": v for k, v in params.as_dict().items()},
               **{f"stderr_{k}": v for k, v in res.stderr.items()}})
    path = write_netcdf(ds, args.outdir / "bem_closure.nc")
    fig = plot(read_netcdf(path))
    fig.savefig(args.outdir / "bem_closure.png", dpi=130)
    print(f"{n} x {n}: {res.summits.n} summits (fit {fit_seconds:.2f} s); BEM {bem_out[3].sum():.1f} s for "
          f"{args.loads} loads, {bem_out[3].max():.2f} s the slowest point")
    print(table(ds))
    print(f"wrote {path}, {args.outdir / 'bem_closure.png'}")
    return 0


def table(ds) -> str:
    """Markdown table: BEM load and model/BEM ratios at each load."""
    models = [str(m) for m in ds.model.values]
    head = ("| p [MPa] | BEM area [%] | BEM closure [um] | " + " | ".join(f"closure ratio {m}" for m in models)
            + " | " + " | ".join(f"area ratio {m}" for m in models) + " | BEM time [s] |")
    lines = [head, "|" + "---|" * (4 + 2 * len(models))]
    for k in range(ds.sizes["load"]):
        cr, ar = ds.closure_ratio.isel(load=k).values, ds.area_ratio.isel(load=k).values
        lines.append(f"| {float(ds.pressure[k]) / 1e6:.3g} | {100 * float(ds.bem_area_fraction[k]):.3g} | "
                     f"{float(ds.bem_closure[k]) * 1e6:.3g} | " + " | ".join(f"{v:.3f}" for v in cr) + " | "
                     + " | ".join(f"{v:.3f}" for v in ar) + f" | {float(ds.bem_seconds[k]):.2f} |")
    return "\n".join(lines)


def plot(ds):
    """Pressure against mean separation and area fraction against pressure, from the file alone."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.5))
    top = float(ds.attrs["max_minus_mean_height_m"])
    style = {"parametric": "-", "empirical": "--", "independent": ":"}
    for m in ds.model.values:
        c = ds.sel(model=m)
        ok = c.curve_pressure.values > 0
        ax[0].semilogy((top - ds.closure.values[ok]) * 1e6, c.curve_pressure.values[ok] / 1e6, style[str(m)],
                       label=f"{m} model")
        ax[1].loglog(c.curve_pressure.values[ok] / 1e6, 100 * c.curve_area_fraction.values[ok], style[str(m)],
                     label=f"{m} model")
    ax[0].semilogy(ds.bem_mean_separation.values * 1e6, ds.pressure.values / 1e6, "ko", label="BEM (tamaas)")
    ax[1].loglog(ds.pressure.values / 1e6, 100 * ds.bem_area_fraction.values, "ko", label="BEM (tamaas)")
    p = ds.pressure.values
    ax[0].set(xlabel="mean separation [um]", ylabel="mean pressure [MPa]", ylim=(p.min() / 3 / 1e6, p.max() * 3 / 1e6),
              title="closure")
    a = ds.bem_area_fraction.values
    ax[1].set(xlabel="mean pressure [MPa]", ylabel="contact-area fraction [%]",
              xlim=(p.min() / 3 / 1e6, p.max() * 3 / 1e6),
              ylim=(100 * a.min() / 3, 100 * min(1.0, 3 * a.max())), title="contact area")
    for a in ax:
        a.legend()
        a.grid(alpha=0.3, which="both")
    fig.suptitle(f"{ds.attrs['pixels']}² composite, {ds.attrs['n_summits']} summits, E* = "
                 f"{ds.attrs['E_star_Pa'] / 1e9:.3g} GPa", fontsize=10)
    fig.tight_layout()
    return fig


if __name__ == "__main__":
    sys.exit(main())
