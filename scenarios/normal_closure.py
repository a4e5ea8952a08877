"""Normal closure of the marble interfaces R2 and S2 (the paper's Fig. 12).

Physical question: how does the normal stress grow with closure for a rough and a
smooth interface, and how does the orientation extent widen with closure?  The
normal stress sigma_1 is raised from 0 to 50 MPa under stress control (finer increments
below 5 MPa) (Delta_2 =
Delta_3 = 0); Delta_1 is solved by Newton at each increment.  R2 and S2 carry an
initial closure r_o, which widens the orientation cone only (SPEC §3).

Relations: Eq. (23) (Monte Carlo), Eq. (9) for theta_m, Eq. (29) for theta_am; the
quadrature reference solves the same stress targets by Brent's method.

Run:   python scenarios/normal_closure.py [--n 200000] [--sigma-max 50e6]
Writes outputs/normal_closure_R2.nc, outputs/normal_closure_S2.nc, outputs/normal_closure.png.
Expected run time: about 10 s with a warm numba cache.
"""

from __future__ import annotations

import sys

from _common import Timer, add_reference, check_positive, fmt, parse_args

from asperity_sim import paths, presets, simulate
from asperity_sim.io import read_netcdf, write_netcdf
from asperity_sim.plotting import plot_normal_closure


def _extra(p):
    p.add_argument("--sigma-max", type=float, default=50e6, help="largest normal stress [Pa] (default 50e6)")


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], n_default=200_000, argv=argv, extra=_extra)
    sigma_max = check_positive("--sigma-max [Pa]", args.sigma_max)
    inc = args.increments or (4 if args.quick else 40)
    args.outdir.mkdir(parents=True, exist_ok=True)
    S, D = paths.STRESS, paths.DISPLACEMENT
    # finer stress increments at low load, where the closure grows fastest
    stages = [paths.Stage((S, D, D), (fraction * sigma_max, 0.0, 0.0), max(1, int(share * inc)), name=label)
              for fraction, share, label in ((0.01, 0.25, "first contacts"), (0.1, 0.25, "low load"),
                                             (1.0, 1.0, "normal loading"))]
    path = paths.LoadPath(tuple(stages), name="normal_closure")
    files = {}
    for name in ("R2", "S2"):
        params = presets.TABLE1[name]
        with Timer() as t:
            ds = simulate(params, path, n=args.n, seed=args.seed, sampler=args.sampler)
        ds.attrs["wall_time_s"] = t.seconds
        if not args.no_reference:
            ds = add_reference(ds, params, level="fast" if args.quick else "default")
        files[name] = write_netcdf(ds, args.outdir / f"normal_closure_{name}.nc")
        last = ds.isel(step=-1)
        d1, se1 = float(last.displacement.sel(axis=1)), float(last.displacement_stderr.sel(axis=1))
        print(f"{name}: n = {args.n}, {ds.sizes['step'] - 1} increments, {t.seconds:.2f} s, "
              f"max Newton iterations {int(ds.iterations.max())}")
        print(f"  sigma_1 = {float(last.stress.sel(axis=1)) / 1e6:.4g} MPa at Delta_1 = {fmt(d1, se1, 1e3, 'mm')}, "
              f"theta_am = {float(last.theta_am):.4f} rad, contacts {int(last.n_contact)} of {args.n}")
        if "reference_displacement" in ds:
            print(f"  quadrature: Delta_1 = {float(last.reference_displacement.sel(axis=1)) * 1e3:.6g} mm")
    fig = plot_normal_closure({name: read_netcdf(f) for name, f in files.items()})
    fig.savefig(args.outdir / "normal_closure.png", dpi=130)
    print(f"wrote {', '.join(str(f) for f in files.values())}, {args.outdir / 'normal_closure.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
