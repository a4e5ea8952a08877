"""Shear at constant normal stress on R1 and S1 (the paper's Fig. 13).

Physical question: how does the shear resistance sigma_2/sigma_1 of a rough and a
smooth interface evolve with shear displacement at 500 MPa, and how does the closure
change (compaction, then dilation)?  Stage 1: sigma_1 from 0 to 500 MPa (stress
control, Delta_2 = Delta_3 = 0); then sigma_1 held while Delta_2 grows, finely to
10 um and coarser to 50 um, past the peak of the resistance: the interface has failed
in shear when sigma_2/sigma_1 no longer grows (SPEC §7).

Relations: Eq. (23) (Monte Carlo), `paper` law, Newton on sigma_1 at every increment;
error bars by the delta method (the Monte Carlo error of sigma_1 moves the solved
Delta_1); the quadrature reference solves the same path with Brent's method.

Run:   python scenarios/constant_normal_shear.py [--n 200000] [--sigma-n 500e6]
Writes outputs/constant_normal_shear_R1.nc, ..._S1.nc, outputs/constant_normal_shear.png.
Expected run time: about 30 s with a warm numba cache (mostly the quadrature reference).
"""

from __future__ import annotations

import sys

import numpy as np
from _common import Timer, add_reference, check_positive, fmt, parse_args

from asperity_sim import paths, presets, simulate
from asperity_sim.io import read_netcdf, write_netcdf
from asperity_sim.plotting import plot_constant_normal_shear, shear_stage


def _extra(p):
    p.add_argument("--sigma-n", type=float, default=500e6, help="normal stress [Pa] (default 500e6)")
    p.add_argument("--d2-max", type=float, default=50e-6, help="final shear displacement [m] (default 50e-6)")


def shear_path(sigma_n, d2_max, inc):
    S, D = paths.STRESS, paths.DISPLACEMENT
    d2_fine = min(10e-6, d2_max)
    stages = [paths.Stage((S, D, D), (sigma_n, 0.0, 0.0), inc, name="normal loading"),
              paths.Stage((S, D, D), (sigma_n, d2_fine, 0.0), inc, name="shear (fine increments)")]
    if d2_max > d2_fine:
        stages.append(paths.Stage((S, D, D), (sigma_n, d2_max, 0.0), inc, name="shear (coarse increments)"))
    return paths.LoadPath(tuple(stages), name="constant_normal_shear")


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], n_default=200_000, argv=argv, extra=_extra)
    sigma_n = check_positive("--sigma-n [Pa]", args.sigma_n)
    d2_max = check_positive("--d2-max [m]", args.d2_max)
    inc = args.increments or (4 if args.quick else 40)
    args.outdir.mkdir(parents=True, exist_ok=True)
    path = shear_path(sigma_n, d2_max, inc)
    files = {}
    for name in ("R1", "S1"):
        params = presets.TABLE1[name]
        with Timer() as t:
            ds = simulate(params, path, n=args.n, seed=args.seed, sampler=args.sampler)
        ds.attrs["wall_time_s"] = t.seconds
        if not args.no_reference:
            ds = add_reference(ds, params, level="fast" if args.quick else "default")
        files[name] = write_netcdf(ds, args.outdir / f"constant_normal_shear_{name}.nc")
        sh = shear_stage(ds)
        d2 = sh.displacement.sel(axis=2).values
        ratio = (sh.stress.sel(axis=2) / sh.stress.sel(axis=1)).values
        se_ratio = (sh.stress_stderr.sel(axis=2) / sh.stress.sel(axis=1)).values
        d1 = sh.displacement.sel(axis=1).values
        i_pk, i_d1 = int(np.argmax(ratio)), int(np.argmax(d1))
        iters = sh.iterations.values[1:]
        print(f"{name}: n = {args.n}, {ds.sizes['step'] - 1} increments, {t.seconds:.2f} s, Newton iterations "
              f"on the shear stages: max {iters.max()}, mean {iters.mean():.2f}")
        print(f"  peak resistance {fmt(ratio[i_pk], se_ratio[i_pk], 1, '')} at Delta_2 = {d2[i_pk] * 1e6:.3g} um; "
              f"final {ratio[-1]:.4f} at {d2[-1] * 1e6:.3g} um")
        print(f"  Delta_1: {d1[0] * 1e6:.4f} um at the start of shear, max {d1[i_d1] * 1e6:.4f} um at "
              f"Delta_2 = {d2[i_d1] * 1e6:.3g} um (compaction), {d1[-1] * 1e6:.4f} um at the end (dilation)")
        if "reference_stress" in sh:
            ref = sh.reference_stress
            ref_ratio = (ref.sel(axis=2) / ref.sel(axis=1)).values
            print(f"  quadrature: peak resistance {ref_ratio.max():.4f}, final {ref_ratio[-1]:.4f}")
    fig = plot_constant_normal_shear({name: read_netcdf(f) for name, f in files.items()})
    fig.savefig(args.outdir / "constant_normal_shear.png", dpi=130)
    print(f"wrote {', '.join(str(f) for f in files.values())}, {args.outdir / 'constant_normal_shear.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
