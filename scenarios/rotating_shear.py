"""Shear that turns by 120°: the interface version of the paper's Fig. 9 (law `mdr` against `paper`).

Physical question: when the shear direction changes, does the shear stress follow the new
direction at once (coaxial), or does the contact memory keep it pointing elsewhere?  After
sigma_1 reaches sigma_n (stress control, held), the interface is sheared along axis 2 by
d_a, then along a direction at 120° to it by d_b (Delta_3 = 0 at first, then
Delta_2, Delta_3 move along (cos 120°, sin 120°)).  The angle between the shear stress
(sigma_2, sigma_3) and the direction of the shear displacement increment measures the
non-coaxiality; with the path-independent `paper` law the stress is a function of the
current displacement only, with `mdr` it carries the history of each contact.

Run:   python scenarios/rotating_shear.py [--n 50000] [--sigma-n 300e6] [--turn 120]
Writes outputs/rotating_shear_<law>_<set>.nc and outputs/rotating_shear.png.
Expected run time: about 30 s with a warm numba cache.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from _common import Timer, check_positive, parse_args

from asperity_sim import paths, presets, simulate
from asperity_sim.output.netcdf import read_netcdf, write_netcdf
from asperity_sim.output.plotting import plot_rotating_shear


def _extra(p):
    p.add_argument("--sigma-n", type=float, default=300e6, help="normal stress [Pa] (default 300e6)")
    p.add_argument("--d-a", type=float, default=2e-6, help="first shear leg along axis 2 [m] (default 2e-6)")
    p.add_argument("--d-b", type=float, default=4e-6, help="second shear leg [m] (default 4e-6)")
    p.add_argument("--turn", type=float, default=120.0, help="turn of the shear direction [deg] (default 120)")
    p.add_argument("--k", type=int, default=16, help="springs per contact (default 16)")


def turning_path(sigma_n, d_a, d_b, turn_deg, inc):
    S, D = paths.STRESS, paths.DISPLACEMENT
    a = math.radians(turn_deg)
    end = (d_a + d_b * math.cos(a), d_b * math.sin(a))
    return paths.LoadPath((
        paths.Stage((S, D, D), (sigma_n, 0.0, 0.0), inc, name="normal loading"),
        paths.Stage((S, D, D), (sigma_n, d_a, 0.0), inc, name="shear along 2"),
        paths.Stage((S, D, D), (sigma_n, end[0], end[1]), 2 * inc, name=f"shear turned by {turn_deg:g} deg"),
    ), name="rotating_shear")


def non_coaxiality(ds):
    """Angle [rad] between the shear stress and the shear displacement increment, per step."""
    tau = ds["stress"].sel(axis=[2, 3]).values
    dd = np.diff(ds["displacement"].sel(axis=[2, 3]).values, axis=0, prepend=np.zeros((1, 2)))
    cross = tau[:, 0] * dd[:, 1] - tau[:, 1] * dd[:, 0]
    dot = (tau * dd).sum(axis=1)
    ang = np.abs(np.arctan2(cross, dot))
    return np.where(np.hypot(*dd.T) > 0, ang, 0.0)


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], n_default=50_000, argv=argv, extra=_extra)
    sigma_n = check_positive("--sigma-n [Pa]", args.sigma_n)
    d_a, d_b = check_positive("--d-a [m]", args.d_a), check_positive("--d-b [m]", args.d_b)
    inc = args.increments or (3 if args.quick else 20)
    path = turning_path(sigma_n, d_a, d_b, args.turn, inc)
    args.outdir.mkdir(parents=True, exist_ok=True)
    files = {}
    for name in ("R1", "S1"):
        for law in ("mdr", "paper"):
            with Timer() as t:
                ds = simulate(presets.TABLE1[name], path, n=args.n, seed=args.seed, sampler=args.sampler, law=law,
                              k=args.k)
            ds.attrs["wall_time_simulate_call_s"] = t.seconds  # the whole simulate() call
            ds["non_coaxiality"] = ("step", non_coaxiality(ds), {
                "units": "rad", "long_name": "angle between shear stress and shear displacement increment"})
            files[(name, law)] = write_netcdf(ds, args.outdir / f"rotating_shear_{law}_{name}.nc")
            turned = ds.isel(step=ds.stage.values == 3)
            ang = np.degrees(turned.non_coaxiality.values)
            print(f"{name} {law:5s}: {t.seconds:5.1f} s; after the turn the stress is {ang[0]:.1f}° off the new "
                  f"direction, {ang[len(ang) // 4]:.1f}° a quarter of the way, {ang[-1]:.1f}° at the end")
    fig = plot_rotating_shear({key: read_netcdf(f) for key, f in files.items()}, args.turn)
    fig.savefig(args.outdir / "rotating_shear.png", dpi=130)
    print(f"wrote {len(files)} files and {args.outdir / 'rotating_shear.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
