"""How far is the asperity model from exact contact mechanics, in closure, contact area and shear? (BEM)

Physical question: for two families of rough surfaces that differ in Hurst exponent and bandwidth,
with several independent surface pairs each, how close are the asperity model's mean gap and
contact area to the exact (boundary-element) contact of the same surfaces from 0.1 % to 10 %
contact area, which model variant comes closest, and how does the model's shear (the ``mdr`` law,
contacts normal to the plane) compare with the exact frictional contact at a constant mean pressure?

Surfaces: pairs of periodic self-affine Gaussian surfaces (SurfaceTopography's Fourier synthesis),
rms height 0.5 um each, pixel 1.953 um; family A: H = 0.8, short cutoff 32 px, long cutoff 128 px
(bandwidth 4, 1024², 2 mm); family B: H = 0.5, short cutoff 8 px, long cutoff 128 px (bandwidth 16,
512², 1 mm).  Each surface is synthesised at twice the resolution and the base grid takes every
other point: the spectrum stops at the short cutoff, far below both Nyquist limits, so the two
grids sample the same continuous surfaces and the doubled grid bounds the BEM's own error.

Relations.  BEM (asperity_sim.analysis.surfaces.bem_contact, tamaas Polonsky-Keer, periodic): the
composite h = h1 + h2 against a flat with the contact modulus E* = G/(1 - nu) (preset R1,
114 GPa); mean gap = mean(u - h), area fraction = share of pixels with positive pressure.  Model:
the composite is fitted (surfaces.fit; the rest of the parameters from R1, e = 0: contacts normal
to the plane as in BEM), and each variant of asperity_sim.analysis.surfaces.variants answers at
the same mean pressures: closure Delta_1 ± its Monte Carlo standard error, mean gap
max(h) - mean(h) - Delta_1, area fraction N E[pi R_area delta].  Loads: pressures from Persson's
estimate A/A0 = 2 p/(E* h'_rms) for 0.07 % .. 10 %, the same for every pair of a family.
Shear (asperity_sim.analysis.surfaces.tangential and .shear): at two mean pressures, mean shear
tractions Q = f mu p (f from 0.05 to 0.9; mu = 1 from R1): BEM = tamaas' normal pressure, then the
Cattaneo problem (Coulomb friction, two identical bodies G, nu); model = the mdr law run by
simulate with sigma_1 and sigma_2 stress controlled.  Compared: the mean tangential displacement,
the stick-area fraction and the initial (Mindlin) tangential stiffness.

Run:   python scenarios/exact_contact.py [--pairs 3] [--loads 8] [--double 1] [--shear-pairs 3] [--quick]
       python scenarios/exact_contact.py --report outputs/exact_contact.nc   (figures and tables only)
       python scenarios/exact_contact.py --family A --outdir outputs/A & python scenarios/exact_contact.py
           --family B --outdir outputs/B; python scenarios/exact_contact.py --merge outputs/A/exact_contact.nc
           outputs/B/exact_contact.nc        (the families in two processes, one core each, then joined)
Writes outputs/exact_contact.nc, outputs/exact_contact_normal.png, outputs/exact_contact_shear.png
and prints the tables of docs/surfaces.md (from the netCDF file alone).
Expected run time: about 90 min on 2 shared cores at the defaults (the doubled 2048² BEM of family A
and the 1024² shear solves take most of it); --quick (256², one pair, 4 loads): about 1 min.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from _exact_report import plot_normal, plot_shear, tables

from asperity_sim.checks import check_real
from asperity_sim.output.netcdf import read_netcdf, write_netcdf
from asperity_sim.sampling.population import Population

OUTPUTS = Path(__file__).resolve().parent.parent / "outputs"
PIXEL = 1e-3 / 512  # [m]
RMS_HEIGHT = 0.5e-6  # [m] each surface
SHEAR_FRACTIONS = (0.05, 0.2, 0.4, 0.6, 0.8, 0.9)
SHEAR_LOADS = (5e-3, 5e-2)  # Persson targets of the two shear pressures (about 0.6 % and 6 % area)
SHEAR_MODELS = ("parametric", "empirical")


@dataclass(frozen=True)
class Family:
    name: str
    hurst: float
    short_px: int
    long_px: int
    pixels: int

    @property
    def label(self):
        return (f"{self.name}: H = {self.hurst:g}, cutoffs {self.short_px}/{self.long_px} px "
                f"(bandwidth {self.long_px // self.short_px}), {self.pixels}²")


FAMILIES = (Family("A", 0.8, 32, 128, 1024), Family("B", 0.5, 8, 128, 512))
QUICK = (Family("A", 0.8, 16, 64, 256), Family("B", 0.5, 8, 128, 256))


def parse(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=3, help="independent surface pairs per family (default 3)")
    p.add_argument("--loads", type=int, default=8, help="mean pressures per family (default 8)")
    p.add_argument("--double", type=int, default=1, help="pairs per family also solved at twice the resolution "
                                                         "(default 1)")
    p.add_argument("--shear-pairs", type=int, default=3, help="pairs per family with the shear comparison (default 3)")
    p.add_argument("--n", type=int, default=200_000, help="asperities per model population (default 200000)")
    p.add_argument("--shear-n", type=int, default=100_000, help="asperities of the mdr runs (default 100000)")
    p.add_argument("--seed", type=int, default=1, help="seed of the first surface of the first pair (default 1)")
    p.add_argument("--tolerance", type=float, default=1e-10, help="tamaas solver tolerance (default 1e-10)")
    p.add_argument("--outdir", type=Path, default=OUTPUTS, help="folder for .nc and .png (default outputs/)")
    p.add_argument("--quick", action="store_true", help="256², one pair, 4 loads, shear at one pressure, n = 20000")
    p.add_argument("--family", action="append", choices=[f.name for f in FAMILIES], default=None,
                   help="only this family (repeatable; default all): families can run in separate processes, "
                        "and --merge joins their files")
    p.add_argument("--merge", type=Path, nargs="+", default=None, metavar="FILE",
                   help="join the exact_contact.nc files of separate families into <outdir>/exact_contact.nc, then "
                        "draw and print as --report")
    p.add_argument("--report", type=Path, default=None, metavar="FILE",
                   help="draw the figures and print the tables of an existing exact_contact.nc (no solve)")
    args = p.parse_args(argv)
    if args.report is not None and not args.report.is_file():
        p.error(f"--report {args.report}: no such file (valid: an exact_contact.nc written by this script)")
    args.families = QUICK if args.quick else FAMILIES
    if args.family:
        args.families = tuple(f for f in args.families if f.name in args.family)
    for f in args.merge or ():
        if not f.is_file():
            p.error(f"--merge {f}: no such file (valid: exact_contact.nc files written by this script)")
    args.shear_loads = SHEAR_LOADS[1:] if args.quick else SHEAR_LOADS
    args.fractions = (0.05, 0.5, 0.9) if args.quick else SHEAR_FRACTIONS
    if args.quick:
        args.pairs, args.loads, args.double, args.shear_pairs = 1, 4, 0, 1
        args.n, args.shear_n = min(args.n, 20_000), min(args.shear_n, 20_000)
    for name, lo in (("pairs", 1), ("loads", 2), ("double", 0), ("shear_pairs", 0), ("n", 100), ("shear_n", 100),
                     ("seed", 0)):
        if getattr(args, name) < lo:
            p.error(f"--{name.replace('_', '-')} = {getattr(args, name)} is out of range (valid range: integer >= {lo})")
    if args.double > args.pairs or args.shear_pairs > args.pairs:
        p.error(f"--double and --shear-pairs are out of range (valid range: 0 .. --pairs = {args.pairs})")
    check_real("--tolerance", args.tolerance, 0.0, 1e-4, lo_open=True)
    return args


def pair_surfaces(fam: Family, seed: int):
    """The two surfaces of a pair at twice the family's resolution (Surface, periodic, metres)."""
    from asperity_sim.analysis import surfaces as sf

    kw = dict(hurst=fam.hurst, rms_height=RMS_HEIGHT, short_cutoff=fam.short_px * PIXEL,
              long_cutoff=fam.long_px * PIXEL)
    size = fam.pixels * PIXEL
    return [sf.synthetic(2 * fam.pixels, size, seed=seed + i, **kw) for i in (0, 1)]


def subsample(s):
    from asperity_sim.analysis import surfaces as sf

    return sf.Surface(s.heights[::2, ::2].copy(), s.physical_sizes, s.periodic, s.source + "[::2]")


def normal_comparison(res, pressures, args, variants):
    """BEM and every variant at the pressures for one fitted composite."""
    from asperity_sim.analysis.surfaces import bem_contact
    from asperity_sim.analysis.surfaces.variants import VARIANTS, fitted

    surf = res.surface
    h = surf.heights
    bem = bem_contact(h, surf.physical_sizes, res.params.E_star, pressures, args.tolerance)
    fit = fitted(res)
    top = h.max() - h.mean()
    model = np.empty((len(variants), 4, len(pressures)))
    for i, v in enumerate(variants):
        a = VARIANTS[v].solve(fit, pressures, args.n, args.seed)
        model[i] = top - a.closure, a.closure_se, a.area, a.area_se
    return bem, model


def shear_comparison(res, pressure, args):
    """BEM and the mdr law (parametric and empirical populations) at one pressure and the shear fractions."""
    from asperity_sim.analysis.surfaces.shear import model_shear
    from asperity_sim.analysis.surfaces.tangential import bem_shear

    p = res.params.replace(e=0.0)
    s = res.summits
    pick = np.random.default_rng(args.seed).integers(0, s.n, size=args.shear_n)
    pops = {"parametric": Population.sample(p, args.shear_n, seed=args.seed),
            "empirical": Population.from_arrays(p, s.depth[pick], s.radius[pick], np.zeros(args.shear_n),
                                                np.zeros(args.shear_n))}
    q = np.asarray(args.fractions) * p.mu * pressure
    models = {k: model_shear(pop, pressure, q) for k, pop in pops.items()}
    bem = bem_shear(res.surface.heights, res.surface.physical_sizes, p.G, p.nu, p.mu, pressure, args.fractions,
                    models["empirical"]["delta"], args.tolerance)
    return bem, models


def _attrs(units, long_name):
    return {"units": units, "long_name": long_name}


def report(path: Path, outdir: Path):
    """Figures and tables of a written exact_contact.nc, from the file alone."""
    back = read_netcdf(path)
    outdir.mkdir(parents=True, exist_ok=True)
    plot_normal(back).savefig(outdir / "exact_contact_normal.png", dpi=130)
    plot_shear(back).savefig(outdir / "exact_contact_shear.png", dpi=130)
    print(tables(back))
    print(f"figures: {outdir / 'exact_contact_normal.png'}, {outdir / 'exact_contact_shear.png'}")


def merge(files, outdir: Path) -> Path:
    """One exact_contact.nc from files of separate families (same settings), joined along ``family``."""
    parts = [read_netcdf(f) for f in files]
    keep = ("families", "seconds_total", "history")
    for ds in parts[1:]:
        differ = [k for k in parts[0].attrs if not k.startswith(("seconds_family_",) + keep)
                  and ds.attrs.get(k, parts[0].attrs[k]) != parts[0].attrs[k]]
        if differ:
            raise SystemExit(f"--merge: the files differ in {differ}: they are not parts of one run")
    joined = xr.concat(parts, dim="family", data_vars="minimal", coords="minimal", compat="equals",
                       combine_attrs="override")
    joined.attrs.update({
        "families": "; ".join(ds.attrs["families"] for ds in parts),
        "seconds_total": float(sum(ds.attrs["seconds_total"] for ds in parts)),
        "history": " | ".join(ds.attrs["history"] for ds in parts) + " | merged: exact_contact.py --merge "
                   + " ".join(str(f) for f in files),
        **{k: v for ds in parts for k, v in ds.attrs.items() if k.startswith("seconds_family_")}})
    outdir.mkdir(parents=True, exist_ok=True)
    return write_netcdf(joined, outdir / "exact_contact.nc")


def main(argv=None):
    args = parse(argv)
    if args.merge is not None:
        path = merge(args.merge, args.outdir)
        report(path, args.outdir)
        print(f"wrote {path}")
        return 0
    if args.report is not None:
        report(args.report, args.outdir)
        return 0
    from asperity_sim.analysis import surfaces as sf
    from asperity_sim.analysis.surfaces.variants import VARIANTS

    variants = tuple(VARIANTS)
    nf, P, L, V = len(args.families), args.pairs, args.loads, len(variants)
    S, F, M = len(args.shear_loads), len(args.fractions), len(SHEAR_MODELS)
    nan = lambda *shape: np.full(shape, np.nan)  # noqa: E731
    pres, bem, bem2, model, model2 = nan(nf, L), nan(nf, P, 4, L), nan(nf, P, 4, L), nan(nf, V, P, 4, L), \
        nan(nf, V, P, 4, L)
    fitp, summits, summits2 = nan(nf, P, 5, 2), nan(nf, P), nan(nf, P)
    sh_p, sh_bem, sh_K, sh_mod, sh_modK = nan(nf, S), nan(nf, P, S, 4, F), nan(nf, P, S), nan(nf, M, P, S, 5, F), \
        nan(nf, M, P, S, 2)
    seconds = {}
    t_all = time.perf_counter()
    for fi, fam in enumerate(args.families):
        t0 = time.perf_counter()
        pairs = [pair_surfaces(fam, args.seed + 2 * k) for k in range(P)]
        fits = [sf.fit(subsample(a), subsample(b), base="R1") for a, b in pairs]
        E_star = fits[0].params.E_star
        slope = np.mean([math.sqrt(2.0 * sf.spectral_moments(r.surface)[1]) for r in fits])
        pres[fi] = np.geomspace(7e-4, 1e-1, L) * E_star * slope / 2.0
        sh_p[fi] = np.asarray(args.shear_loads) * E_star * slope / 2.0
        for k, res in enumerate(fits):
            print(f"family {fam.label}, pair {k + 1}/{P}: {res.summits.n} summits", flush=True)
            summits[fi, k] = res.summits.n
            fitp[fi, k] = [(getattr(res.params, n), res.stderr[n]) for n in ("N", "alpha", "beta", "R_m", "R_sigma")]
            bem[fi, k], model[fi, :, k] = normal_comparison(res, pres[fi], args, variants)
            print(f"  normal: BEM {np.nansum(bem[fi, k, 3]):.0f} s; areas {np.round(100 * bem[fi, k, 2], 3)} %",
                  flush=True)
            if k < args.double:
                res2 = sf.fit(*pairs[k], base="R1")
                summits2[fi, k] = res2.summits.n
                bem2[fi, k], model2[fi, :, k] = normal_comparison(res2, pres[fi], args, variants)
                print(f"  twice the resolution ({res2.summits.n} summits): BEM {np.nansum(bem2[fi, k, 3]):.0f} s; "
                      f"area 2x/1x {np.round(bem2[fi, k, 2] / bem[fi, k, 2], 3)}", flush=True)
            for j in range(S if k < args.shear_pairs else 0):
                t1 = time.perf_counter()
                try:
                    b, ms = shear_comparison(res, sh_p[fi, j], args)
                except RuntimeError as err:  # a BEM traction not reached: recorded as missing, said here
                    print(f"  shear at {sh_p[fi, j] / 1e6:.3g} MPa: not solved ({err})", flush=True)
                    continue
                print(f"  shear at {sh_p[fi, j] / 1e6:.3g} MPa: {time.perf_counter() - t1:.0f} s, BEM solves "
                      f"{b['solves'].astype(int).tolist()}", flush=True)
                sh_bem[fi, k, j] = b["traction"], b["delta"], b["stick"], b["contact"]
                sh_K[fi, k, j] = b["stiffness"]
                for m, name in enumerate(SHEAR_MODELS):
                    r = ms[name]
                    sh_mod[fi, m, k, j] = r["traction"], r["delta"], r["delta_se"], r["stick"], r["stick_se"]
                    sh_modK[fi, m, k, j] = r["stiffness"], r["stiffness_se"]
        seconds[fam.name] = time.perf_counter() - t0
    coords = {"family": ("family", [f.name for f in args.families], _attrs("1", "surface family")),
              "pair": ("pair", np.arange(P), _attrs("1", "surface pair (independent realisation)")),
              "load": ("load", np.arange(L), _attrs("1", "load index")),
              "variant": ("variant", list(variants), _attrs("1", "asperity-model variant")),
              "shear_load": ("shear_load", np.arange(S), _attrs("1", "index of the mean pressure of the shear runs")),
              "level": ("level", np.asarray(args.fractions), _attrs("1", "prescribed mean shear traction / (mu p)")),
              "shear_model": ("shear_model", list(SHEAR_MODELS), _attrs("1", "population of the mdr runs")),
              "fit_parameter": ("fit_parameter", ["N", "alpha", "beta", "R_m", "R_sigma"],
                                _attrs("1", "fitted parameter (SI units: 1/m², 1, m, m, m)"))}
    fpl, fvl = ("family", "pair", "load"), ("family", "variant", "pair", "load")
    fps, fmps = ("family", "pair", "shear_load", "level"), ("family", "shear_model", "pair", "shear_load", "level")
    data = {
        "pressure": (("family", "load"), pres, _attrs("Pa", "mean contact pressure")),
        "bem_mean_gap": (fpl, bem[:, :, 1], _attrs("m", "BEM mean gap mean(u - h)")),
        "bem_area_fraction": (fpl, bem[:, :, 2], _attrs("1", "BEM contact-area fraction (pixels with p > 0)")),
        "bem_seconds": (fpl, bem[:, :, 3], _attrs("s", "wall time of one BEM solve")),
        "bem2_mean_gap": (fpl, bem2[:, :, 1], _attrs("m", "BEM mean gap at twice the resolution")),
        "bem2_area_fraction": (fpl, bem2[:, :, 2], _attrs("1", "BEM contact-area fraction at twice the resolution")),
        "bem2_seconds": (fpl, bem2[:, :, 3], _attrs("s", "wall time of one BEM solve at twice the resolution")),
        "model_mean_gap": (fvl, model[:, :, :, 0], _attrs("m", "model mean gap max(h) - mean(h) - Delta_1")),
        "model_mean_gap_stderr": (fvl, model[:, :, :, 1], _attrs("m", "Monte Carlo standard error of the mean gap")),
        "model_area_fraction": (fvl, model[:, :, :, 2], _attrs("1", "model contact-area fraction")),
        "model_area_fraction_stderr": (fvl, model[:, :, :, 3],
                                       _attrs("1", "Monte Carlo standard error of the area fraction")),
        "model2_mean_gap": (fvl, model2[:, :, :, 0], _attrs("m", "model mean gap, fit at twice the resolution")),
        "model2_area_fraction": (fvl, model2[:, :, :, 2],
                                 _attrs("1", "model contact-area fraction, fit at twice the resolution")),
        "fit": (("family", "pair", "fit_parameter"), fitp[..., 0], _attrs("1", "fitted parameter value (SI)")),
        "fit_stderr": (("family", "pair", "fit_parameter"), fitp[..., 1], _attrs("1", "standard error of the fit")),
        "summits": (("family", "pair"), summits, _attrs("1", "summits found on the composite")),
        "summits2": (("family", "pair"), summits2, _attrs("1", "summits found at twice the resolution")),
        "shear_pressure": (("family", "shear_load"), sh_p, _attrs("Pa", "mean pressure of the shear runs")),
        "bem_shear_traction": (fps, sh_bem[:, :, :, 0], _attrs("Pa", "BEM mean shear traction reached")),
        "bem_shear_displacement": (fps, sh_bem[:, :, :, 1], _attrs("m", "BEM mean tangential displacement")),
        "bem_stick_fraction": (fps, sh_bem[:, :, :, 2], _attrs("1", "BEM stick-area fraction")),
        "bem_shear_contact_fraction": (fps, sh_bem[:, :, :, 3], _attrs("1", "BEM contact-area fraction (shear runs)")),
        "bem_shear_stiffness": (("family", "pair", "shear_load"), sh_K,
                                _attrs("Pa/m", "BEM full-stick (Mindlin) tangential stiffness")),
        "model_shear_traction": (fmps, sh_mod[:, :, :, :, 0], _attrs("Pa", "model mean shear traction sigma_2")),
        "model_shear_displacement": (fmps, sh_mod[:, :, :, :, 1], _attrs("m", "model tangential displacement Delta_2")),
        "model_shear_displacement_stderr": (fmps, sh_mod[:, :, :, :, 2],
                                            _attrs("m", "Monte Carlo standard error of Delta_2")),
        "model_stick_fraction": (fmps, sh_mod[:, :, :, :, 3], _attrs("1", "model stick-area fraction")),
        "model_stick_fraction_stderr": (fmps, sh_mod[:, :, :, :, 4],
                                        _attrs("1", "Monte Carlo standard error of the stick-area fraction")),
        "model_shear_stiffness": (("family", "shear_model", "pair", "shear_load"), sh_modK[..., 0],
                                  _attrs("Pa/m", "model initial (Mindlin) tangential stiffness")),
        "model_shear_stiffness_stderr": (("family", "shear_model", "pair", "shear_load"), sh_modK[..., 1],
                                         _attrs("Pa/m", "Monte Carlo standard error of the tangential stiffness")),
    }
    ds = xr.Dataset(data, coords=coords, attrs={
        "title": "asperity model against exact contact (BEM) on two surface families: closure, area and shear",
        "source": "asperity_sim scenarios/exact_contact.py", "Conventions": "CF-1.8",
        "history": f"{time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())} exact_contact.py "
                   f"{' '.join(argv if argv is not None else sys.argv[1:])}",
        "families": "; ".join(f.label for f in args.families), "pixel_size_m": PIXEL, "rms_height_each_m": RMS_HEIGHT,
        "E_star_Pa": float(fits[0].params.E_star), "G_Pa": float(fits[0].params.G), "nu": float(fits[0].params.nu),
        "mu": float(fits[0].params.mu), "preset": "R1", "n_asperities": args.n, "n_shear_asperities": args.shear_n,
        "seed": args.seed, "tamaas_tolerance": args.tolerance,
        **{f"variant_{v}": VARIANTS[v].description for v in variants},
        **{f"seconds_family_{k}": v for k, v in seconds.items()}, "seconds_total": time.perf_counter() - t_all})
    args.outdir.mkdir(parents=True, exist_ok=True)
    path = write_netcdf(ds, args.outdir / "exact_contact.nc")
    report(path, args.outdir)
    print(f"wrote {path} in {time.perf_counter() - t_all:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
