"""The paper's 3-step path (Fig. 10/11) on the rough R1 and smooth S1 interfaces.

Physical question: how strongly does shear couple to the normal stress, and does the
shear traction plateau (S1) or harden above sigma_1 (R1)?  Step 1: Delta_1 from 0 to
d_max (15 um for R1, 6 um for S1) with Delta_2 = Delta_3 = 0; step 2: Delta_2 from 0 to
d_max; step 3: Delta_3 from 0 to d_max (SPEC §7).  The isotropy check: sigma_2 at the
end of step 2 equals sigma_3 at the end of step 3.

Relations: Eq. (23) as a Monte Carlo mean over a sampled population, `paper` law
(Eqs. 16–22), policy `follow`; the quadrature of Eq. (23) as the dashed reference.

The scenes (parameters, path, n, seed) are the scene files scenarios/three_step_R1.toml
and three_step_S1.toml, which `asperity-sim run` takes too; options here override them.

Run:   python scenarios/three_step.py [--n 200000] [--seed 2024]
Writes outputs/three_step_R1.nc, outputs/three_step_S1.nc, outputs/three_step.png.
Expected run time: about 10 s with a warm numba cache (n = 200000, 30 increments per step).
"""

from __future__ import annotations

import sys
from pathlib import Path

from _common import Timer, add_reference, fmt, parse_args

from asperity_sim.output.netcdf import read_netcdf, write_netcdf
from asperity_sim.output.plotting import plot_three_step
from asperity_sim.runs.scene import load_scene, scale_increments

SCENES = {name: Path(__file__).resolve().parent / f"three_step_{name}.toml" for name in ("R1", "S1")}


def main(argv=None):
    scenes = {name: load_scene(f) for name, f in SCENES.items()}
    args = parse_args(__doc__.splitlines()[0], n_default=scenes["R1"].n, argv=argv,
                      extra=lambda p: p.set_defaults(seed=scenes["R1"].seed, sampler=scenes["R1"].sampler))
    args.outdir.mkdir(parents=True, exist_ok=True)
    files = {}
    for name, scene in scenes.items():
        params = scene.params
        if args.increments or args.quick:
            scene = scene.replace(path=scale_increments(scene.path, args.increments or 4))
        with Timer() as t:
            ds = scene.replace(n=args.n, seed=args.seed, sampler=args.sampler).simulate()
        ds.attrs["wall_time_simulate_call_s"] = t.seconds  # the whole simulate() call
        if not args.no_reference:
            ds = add_reference(ds, params, level="fast" if args.quick else "default")
        files[name] = write_netcdf(ds, args.outdir / f"three_step_{name}.nc")
        end = {k: int(ds.step[ds.stage == k][-1]) for k in (1, 2, 3)}
        s, se = ds["stress"].values, ds["stress_stderr"].values
        print(f"{name}: n = {args.n}, {ds.sizes['step'] - 1} increments, {t.seconds:.2f} s")
        print(f"  end of step 1: sigma_1 = {fmt(s[end[1], 0], se[end[1], 0], 1e-6, 'MPa')}")
        print(f"  end of step 2: sigma_1 = {fmt(s[end[2], 0], se[end[2], 0], 1e-6, 'MPa')}, "
              f"sigma_2 = {fmt(s[end[2], 1], se[end[2], 1], 1e-6, 'MPa')}")
        print(f"  end of step 3: sigma_2 = {fmt(s[end[3], 1], se[end[3], 1], 1e-6, 'MPa')}, "
              f"sigma_3 = {fmt(s[end[3], 2], se[end[3], 2], 1e-6, 'MPa')}")
        if "reference_stress" in ds:
            ref = ds["reference_stress"].values
            print(f"  quadrature: sigma_1(1) = {ref[end[1], 0] / 1e6:.4g}, sigma_2(2) = {ref[end[2], 1] / 1e6:.4g}, "
                  f"sigma_3(3) = {ref[end[3], 2] / 1e6:.4g} MPa")
    fig = plot_three_step({name: read_netcdf(f) for name, f in files.items()})
    fig.savefig(args.outdir / "three_step.png", dpi=130)
    print(f"wrote {', '.join(str(f) for f in files.values())}, {args.outdir / 'three_step.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
