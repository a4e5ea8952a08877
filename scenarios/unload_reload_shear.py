"""Normal unloading and reloading in the middle of a shear test (law `mdr` against `paper`).

Physical question: a joint sheared under a fixed closure is partly opened and closed
again before shearing on.  Contacts that open lose their memory; when they close again
they carry no tangential load, so the shear stress drops and must be rebuilt.  The
path-independent `paper` law returns to the same stress as soon as the displacement is
the same.  Path (displacement control): Delta_1 to D (15 um for R1, 6 um for S1); Delta_2
to D/5; Delta_1 down to 0.6 D and back to D at fixed Delta_2; Delta_2 on to 2D/5.

Run:   python scenarios/unload_reload_shear.py [--n 50000] [--k 16]
Writes outputs/unload_reload_shear_<law>_<set>.nc and outputs/unload_reload_shear.png.
Expected run time: about 30 s with a warm numba cache.
"""

from __future__ import annotations

import sys

import numpy as np
from _common import Timer, parse_args

from asperity_sim import paths, Population, presets, simulate
from asperity_sim.output.netcdf import read_netcdf, write_netcdf
from asperity_sim.output.plotting import plot_unload_reload

CLOSURE = {"R1": 15e-6, "S1": 6e-6}


def _extra(p):
    p.add_argument("--k", type=int, default=16, help="springs per contact (default 16)")


def unload_reload_path(D, inc):
    d = paths.DISPLACEMENT
    c = (d, d, d)
    return paths.LoadPath((
        paths.Stage(c, (D, 0.0, 0.0), inc, name="closure"),
        paths.Stage(c, (D, D / 5, 0.0), inc, name="shear"),
        paths.Stage(c, (0.6 * D, D / 5, 0.0), inc, name="normal unloading"),
        paths.Stage(c, (D, D / 5, 0.0), inc, name="normal reloading"),
        paths.Stage(c, (D, 2 * D / 5, 0.0), inc, name="shear on"),
    ), name="unload_reload_shear")


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], n_default=50_000, argv=argv, extra=_extra)
    inc = args.increments or (3 if args.quick else 20)
    args.outdir.mkdir(parents=True, exist_ok=True)
    files = {}
    for name, D in CLOSURE.items():
        params = presets.TABLE1[name]
        pop = Population.sample(params, args.n, seed=args.seed, sampler=args.sampler)
        path = unload_reload_path(D, inc)
        runs = {}
        for law in ("paper", "mdr"):
            with Timer() as t:
                ds = simulate(params, path, population=pop, law=law, k=args.k)
            ds.attrs["wall_time_simulate_call_s"] = t.seconds  # the whole simulate() call
            files[(name, law)] = write_netcdf(ds, args.outdir / f"unload_reload_shear_{law}_{name}.nc")
            runs[law] = ds
        for law, ds in runs.items():
            st = ds.stage.values
            before = int(np.flatnonzero(st == 2)[-1])
            after = int(np.flatnonzero(st == 4)[-1])
            lowest = int(np.flatnonzero(st == 3)[-1])
            s2 = ds.stress.sel(axis=2).values / 1e6
            nc = ds.n_contact.values
            print(f"{name} {law:5s}: sigma_2 {s2[before]:.4g} MPa before unloading, {s2[after]:.4g} MPa after "
                  f"reloading to the same displacement; contacts {nc[before]} -> {nc[lowest]} -> {nc[after]}")
    fig = plot_unload_reload({key: read_netcdf(f) for key, f in files.items()})
    fig.savefig(args.outdir / "unload_reload_shear.png", dpi=130)
    print(f"wrote {len(files)} files and {args.outdir / 'unload_reload_shear.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
