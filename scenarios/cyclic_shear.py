"""Cyclic shear at constant normal stress with the history law `mdr` (R1 against S1).

Physical question: how much energy does a rough joint dissipate per shear cycle, and how
does it scale with the cycle amplitude?  After sigma_1 is raised to sigma_n (300 MPa by
default, stress control), the interface runs two symmetric cycles Delta_2 = ±A at each of
several increasing amplitudes A; the second cycle of each amplitude is the stable
(Masing) loop, whose dissipation is recorded.  Mindlin–Deresiewicz predicts a loop energy
growing as A³ while contacts are in partial slip, and about linearly once they slide.

Relations: Eq. (23) with the vector MDR law (issue 4), energy bookkeeping per increment
(external work = stored elastic energy + dissipation).

Run:   python scenarios/cyclic_shear.py [--n 50000] [--sigma-n 300e6] [--k 16]
Writes outputs/cyclic_shear_R1.nc, outputs/cyclic_shear_S1.nc, outputs/cyclic_shear.png.
Expected run time: about 1–2 minutes with a warm numba cache.
"""

from __future__ import annotations

import sys

import numpy as np
from _common import Timer, check_positive, parse_args

from asperity_sim import paths, presets, simulate
from asperity_sim.output.netcdf import read_netcdf, write_netcdf
from asperity_sim.output.plotting import plot_cyclic_shear

AMPLITUDES = np.array([0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0]) * 1e-6


def _extra(p):
    p.add_argument("--sigma-n", type=float, default=300e6, help="normal stress [Pa] (default 300e6)")
    p.add_argument("--k", type=int, default=16, help="springs per contact (default 16)")


def cyclic_path(sigma_n, amplitudes, inc):
    S, D = paths.STRESS, paths.DISPLACEMENT
    stages = [paths.Stage((S, D, D), (sigma_n, 0.0, 0.0), inc, name="normal loading")]
    for a in amplitudes:
        for c in (1, 2):
            stages += [paths.Stage((S, D, D), (sigma_n, a, 0.0), inc, name=f"A={a:.3g} m cycle {c}: +A"),
                       paths.Stage((S, D, D), (sigma_n, -a, 0.0), 2 * inc, name=f"A={a:.3g} m cycle {c}: -A"),
                       paths.Stage((S, D, D), (sigma_n, 0.0, 0.0), inc, name=f"A={a:.3g} m cycle {c}: 0")]
    return paths.LoadPath(tuple(stages), name="cyclic_shear")


def loop_dissipation(ds, n_amp):
    """Dissipation [J m-2] of the second cycle of each amplitude (3 stages per cycle after stage 1)."""
    stage, D = ds["stage"].values, ds["dissipation"].values
    out = []
    for i in range(n_amp):
        first, last = 2 + 6 * i + 3, 2 + 6 * i + 5  # stages of the second cycle
        start = np.flatnonzero(stage == first)[0] - 1
        end = np.flatnonzero(stage == last)[-1]
        out.append(D[end] - D[start])
    return np.array(out)


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], n_default=50_000, argv=argv, extra=_extra)
    sigma_n = check_positive("--sigma-n [Pa]", args.sigma_n)
    inc = args.increments or (2 if args.quick else 10)
    amps = AMPLITUDES[:3] if args.quick else AMPLITUDES
    args.outdir.mkdir(parents=True, exist_ok=True)
    files = {}
    for name in ("R1", "S1"):
        with Timer() as t:
            ds = simulate(presets.TABLE1[name], cyclic_path(sigma_n, amps, inc), n=args.n, seed=args.seed,
                          sampler=args.sampler, law="mdr", k=args.k)
        ds.attrs["wall_time_simulate_call_s"] = t.seconds  # the whole simulate() call
        W = loop_dissipation(ds, len(amps))
        ds["loop_amplitude"] = ("amplitude", amps, {"units": "m", "long_name": "shear cycle amplitude A"})
        ds["loop_dissipation"] = ("amplitude", W, {"units": "J m-2",
                                                   "long_name": "dissipation of the second cycle at each amplitude"})
        files[name] = write_netcdf(ds, args.outdir / f"cyclic_shear_{name}.nc")
        slope = np.polyfit(np.log(amps[:3]), np.log(W[:3]), 1)[0]
        bal = float(np.abs(ds.external_work - ds.elastic_energy - ds.dissipation).max() / ds.external_work.max())
        print(f"{name}: n = {args.n}, k = {args.k}, {ds.sizes['step'] - 1} increments, {t.seconds:.1f} s; "
              f"energy balance closes to {bal:.1e} (relative)")
        for a, w in zip(amps, W):
            print(f"  A = {a * 1e6:5.2f} um: loop dissipation {w:.4g} J/m²")
        print(f"  log-log slope over the three smallest amplitudes: {slope:.2f} (Mindlin–Deresiewicz: 3)")
    fig = plot_cyclic_shear({name: read_netcdf(f) for name, f in files.items()})
    fig.savefig(args.outdir / "cyclic_shear.png", dpi=130)
    print(f"wrote {', '.join(str(f) for f in files.values())}, {args.outdir / 'cyclic_shear.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
