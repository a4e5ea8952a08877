"""Normal closure of the marble interfaces R2 and S2 (the paper's Fig. 12).

Physical question: how does the normal stress grow with closure for a rough and a
smooth interface, and how does the orientation extent widen with closure?  The
normal stress sigma_1 is raised from 0 to 50 MPa under stress control (finer increments
below 5 MPa) (Delta_2 =
Delta_3 = 0); Delta_1 is solved by Newton at each increment.  R2 and S2 carry an
initial closure r_o, which widens the orientation cone only (SPEC §3).

Relations: Eq. (23) (Monte Carlo), Eq. (9) for theta_m, Eq. (29) for theta_am; the
quadrature reference solves the same stress targets by Brent's method.

The scenes (parameters, path, n, seed) are the scene files scenarios/normal_closure_R2.toml
and normal_closure_S2.toml, which `asperity-sim run` takes too; options here override them.

Run:   python scenarios/normal_closure.py [--n 200000] [--sigma-max 50e6]
Writes outputs/normal_closure_R2.nc, outputs/normal_closure_S2.nc, outputs/normal_closure.png.
Expected run time: about 10 s with a warm numba cache.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from _common import Timer, add_reference, check_positive, fmt, parse_args

from asperity_sim import paths
from asperity_sim.output.netcdf import read_netcdf, write_netcdf
from asperity_sim.output.plotting import plot_normal_closure
from asperity_sim.runs.scene import load_scene, scale_increments

SCENES = {name: Path(__file__).resolve().parent / f"normal_closure_{name}.toml" for name in ("R2", "S2")}


def _extra(p, scene):
    p.set_defaults(seed=scene.seed, sampler=scene.sampler)  # defaults from the scene file
    p.add_argument("--sigma-max", type=float, default=None,
                   help="largest normal stress [Pa] (default: the scene files', 50e6)")


def scale_stress(path, sigma_max):
    """The path with its normal-stress targets scaled so that the largest is sigma_max [Pa]."""
    top = max(st.target[0] for st in path.stages)
    if sigma_max == top:
        return path
    stages = tuple(dataclasses.replace(st, target=(st.target[0] * sigma_max / top,) + st.target[1:])
                   for st in path.stages)
    return paths.LoadPath(stages, name=path.name)


def main(argv=None):
    scenes = {name: load_scene(f) for name, f in SCENES.items()}
    args = parse_args(__doc__.splitlines()[0], n_default=scenes["R2"].n, argv=argv,
                      extra=lambda p: _extra(p, scenes["R2"]))
    sigma_max = None if args.sigma_max is None else check_positive("--sigma-max [Pa]", args.sigma_max)
    args.outdir.mkdir(parents=True, exist_ok=True)
    files = {}
    for name, scene in scenes.items():
        params = scene.params
        path = scene.path if sigma_max is None else scale_stress(scene.path, sigma_max)
        if args.increments or args.quick:
            path = scale_increments(path, args.increments or 4)
        with Timer() as t:
            ds = scene.replace(path=path, n=args.n, seed=args.seed, sampler=args.sampler).simulate()
        ds.attrs["wall_time_simulate_call_s"] = t.seconds  # the whole simulate() call
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
