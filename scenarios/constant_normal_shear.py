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

The scenes (parameters, path, n, seed) are the scene files
scenarios/constant_normal_shear_R1.toml and constant_normal_shear_S1.toml, which
`asperity-sim run` takes too; options here override them.

Run:   python scenarios/constant_normal_shear.py [--n 200000] [--sigma-n 500e6]
Writes outputs/constant_normal_shear_R1.nc, ..._S1.nc, outputs/constant_normal_shear.png.
Expected run time: about 30 s with a warm numba cache (mostly the quadrature reference).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
from _common import Timer, add_reference, check_positive, fmt, parse_args

from asperity_sim import paths
from asperity_sim.output.netcdf import read_netcdf, write_netcdf
from asperity_sim.runs.scene import load_scene

SCENES = {name: Path(__file__).resolve().parent / f"constant_normal_shear_{name}.toml" for name in ("R1", "S1")}


def _extra(p, scene):
    p.set_defaults(seed=scene.seed, sampler=scene.sampler)  # defaults from the scene file
    p.add_argument("--sigma-n", type=float, default=None, help="normal stress [Pa] (default: the scene files', 500e6)")
    p.add_argument("--d2-max", type=float, default=None,
                   help="final shear displacement [m] (default: the scene files', 50e-6)")


def adjust_path(path, sigma_n=None, d2_max=None, inc=None):
    """The scene's path with another normal stress [Pa], final Delta_2 [m] or increments per stage.

    Delta_2 targets are capped at d2_max and the last stage ends there; a stage that no
    longer moves (same targets as the one before) is dropped.
    """
    stages = []
    for st in path.stages:
        t = list(st.target)
        t[0] = t[0] if sigma_n is None else sigma_n
        t[1] = t[1] if d2_max is None else min(t[1], d2_max)
        stages.append(dataclasses.replace(st, target=tuple(t), increments=inc or st.increments))
    if d2_max is not None:
        stages[-1] = dataclasses.replace(stages[-1], target=(stages[-1].target[0], d2_max, stages[-1].target[2]))
    kept = [st for i, st in enumerate(stages)
            if i == 0 or (st.target, st.control) != (stages[i - 1].target, stages[i - 1].control)]
    return paths.LoadPath(tuple(kept), name=path.name)


def shear_path(sigma_n, d2_max, inc):
    """The Fig. 13 path of the R1 scene file at normal stress sigma_n [Pa], to Delta_2 = d2_max [m]."""
    return adjust_path(load_scene(SCENES["R1"]).path, sigma_n, d2_max, inc)


def main(argv=None):
    # matplotlib here, not at module level: importing this script for shear_path stays light
    from asperity_sim.output.plotting import plot_constant_normal_shear, shear_stage

    scenes = {name: load_scene(f) for name, f in SCENES.items()}
    args = parse_args(__doc__.splitlines()[0], n_default=scenes["R1"].n, argv=argv,
                      extra=lambda p: _extra(p, scenes["R1"]))
    sigma_n = None if args.sigma_n is None else check_positive("--sigma-n [Pa]", args.sigma_n)
    d2_max = None if args.d2_max is None else check_positive("--d2-max [m]", args.d2_max)
    inc = args.increments or (4 if args.quick else None)
    args.outdir.mkdir(parents=True, exist_ok=True)
    files = {}
    for name, scene in scenes.items():
        params = scene.params
        path = adjust_path(scene.path, sigma_n, d2_max, inc)
        with Timer() as t:
            ds = scene.replace(path=path, n=args.n, seed=args.seed, sampler=args.sampler).simulate()
        ds.attrs["wall_time_simulate_call_s"] = t.seconds  # the whole simulate() call
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
