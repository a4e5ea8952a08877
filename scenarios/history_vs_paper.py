"""How large is the history effect on the paper's own monotonic test? (Fig. 13 path, `mdr` against `paper`)

Physical question: the paper argues that for monotonic shear after normal loading the
loading history of individual contacts matters little, and uses a path-independent law.
Here the same population (common random numbers) runs the Fig. 13 path (sigma_1 to 500
MPa, then Delta_2 to 50 um at constant sigma_1) with the path-independent `paper` law and
with the history law `mdr` (each contact remembers the tangential loading it took during
closure, the direction change when shear starts, and its partial unloading).  The
difference of the shear resistance and of Delta_1 measures the history effect; the Monte
Carlo standard error shows which part of it is resolved.

Run:   python scenarios/history_vs_paper.py [--n 100000] [--k 16]
Writes outputs/history_vs_paper_<law>_<set>.nc and outputs/history_vs_paper.png.
Expected run time: about 1–2 minutes with a warm numba cache.
"""

from __future__ import annotations

import sys

import numpy as np
from _common import Timer, check_positive, parse_args
from constant_normal_shear import shear_path

from asperity_sim import Population, presets, simulate
from asperity_sim.output.netcdf import read_netcdf, write_netcdf
from asperity_sim.output.plotting import plot_history_vs_paper, shear_stage


def _extra(p):
    p.add_argument("--sigma-n", type=float, default=500e6, help="normal stress [Pa] (default 500e6)")
    p.add_argument("--d2-max", type=float, default=50e-6, help="final shear displacement [m] (default 50e-6)")
    p.add_argument("--k", type=int, default=16, help="springs per contact (default 16)")


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], n_default=100_000, argv=argv, extra=_extra)
    sigma_n = check_positive("--sigma-n [Pa]", args.sigma_n)
    d2_max = check_positive("--d2-max [m]", args.d2_max)
    inc = args.increments or (4 if args.quick else 40)
    path = shear_path(sigma_n, d2_max, inc)
    args.outdir.mkdir(parents=True, exist_ok=True)
    files = {}
    for name in ("R1", "S1"):
        params = presets.TABLE1[name]
        pop = Population.sample(params, args.n, seed=args.seed, sampler=args.sampler)
        runs = {}
        for law in ("paper", "mdr"):
            with Timer() as t:
                ds = simulate(params, path, population=pop, law=law, k=args.k)
            ds.attrs["wall_time_simulate_call_s"] = t.seconds  # the whole simulate() call
            files[(name, law)] = write_netcdf(ds, args.outdir / f"history_vs_paper_{law}_{name}.nc")
            runs[law] = shear_stage(ds)
            print(f"{name} {law:5s}: {t.seconds:5.1f} s, {ds.sizes['step'] - 1} increments")
        a, b = runs["paper"], runs["mdr"]
        ra = (a.stress.sel(axis=2) / a.stress.sel(axis=1)).values
        rb = (b.stress.sel(axis=2) / b.stress.sel(axis=1)).values
        se = (b.stress_stderr.sel(axis=2) / b.stress.sel(axis=1)).values
        diff = rb - ra
        i = int(np.argmax(np.abs(diff)))
        d2 = b.displacement.sel(axis=2).values * 1e6
        dd1 = (b.displacement.sel(axis=1) - a.displacement.sel(axis=1)).values * 1e6
        print(f"  shear resistance: largest difference mdr - paper = {diff[i]:+.4f} at Delta_2 = {d2[i]:.3g} um "
              f"({100 * diff[i] / ra[i]:+.2f} %; Monte Carlo s.e. of one curve {se[i]:.4f}); "
              f"peak {ra.max():.4f} (paper) vs {rb.max():.4f} (mdr)")
        print(f"  Delta_1: largest difference {dd1[np.argmax(np.abs(dd1))]:+.4f} um "
              f"(start of shear: {dd1[0]:+.4f} um, from the closure stage)")
    fig = plot_history_vs_paper({key: read_netcdf(f) for key, f in files.items()})
    fig.savefig(args.outdir / "history_vs_paper.png", dpi=130)
    print(f"wrote {len(files)} files and {args.outdir / 'history_vs_paper.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
