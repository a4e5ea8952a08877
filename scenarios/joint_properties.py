"""Joint properties of R1 and S1 under both laws: strength envelopes, stiffness and damping tables.

Physical question: what would a joint element built from this model look like?  For the
rough (R1) and smooth (S1) interfaces of the paper's Table 1 and both asperity laws
(``paper``, path independent; ``mdr``, with contact history), this scenario

1. runs the constant-normal-stress shear path of Fig. 13 (scenarios/constant_normal_shear_*.toml:
   sigma_1 raised, then held while Delta_2 goes to 50 um) at several normal stresses and
   writes the strength envelope (peak and residual shear stress, friction coefficients,
   dilation angle at peak, normal and shear stiffness at the start of shear), with fitted
   Mohr-Coulomb and power-law envelopes (:func:`asperity_sim.runs.envelope.envelope`);
2. runs two symmetric shear cycles 0 -> +a -> -a -> 0 at several amplitudes a after
   sigma_1 = 300 MPa, and writes the secant stiffness ratio (G/Gmax) and the equivalent
   damping ratio of the second cycle (:func:`asperity_sim.runs.envelope.cyclic`);
3. checks the paper's qualitative findings at 500 MPa (SPEC §7): S1 stiffer at small shear
   and yielding sharply just above mu, R1 hardening to a higher resistance, both
   compressing then dilating.

Relations: Eq. (23) with the paper law (SPEC §5) or the vector MDR law; definitions of the
properties in asperity_sim/properties.py and docs/joint_properties.md.

Run:   python scenarios/joint_properties.py [--n 5000] [--replicas 3] [--quick] [--outdir outputs]
Writes <outdir>/joint_envelope_{R1,S1}_{paper,mdr}.{nc,csv,png},
<outdir>/joint_cyclic_{R1,S1}_{paper,mdr}.{nc,csv,png}, <outdir>/joint_properties.png and
<outdir>/joint_properties.json (the summary printed).  Expected run time: about 1-3 minutes
with a warm numba cache at the defaults (n = 5000, k = 8, 3 replicas); --quick: seconds.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
from _common import Timer, parse_args

from asperity_sim.runs import envelope as E
from asperity_sim.runs import figures as F
from asperity_sim.output.netcdf import read_netcdf
from asperity_sim.runs.scene import load_scene, scale_increments

HERE = Path(__file__).resolve().parent
SIGMA_N = np.array([10e6, 30e6, 100e6, 300e6, 500e6, 1000e6])
AMPLITUDES = np.array([0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0]) * 1e-6
LAWS = ("paper", "mdr")


def _extra(p):
    p.add_argument("--replicas", type=int, default=3, help="replicas (seeds) per point (default 3)")
    p.add_argument("--k", type=int, default=8, help="springs per contact, law mdr (default 8)")


def findings(env: dict) -> dict:
    """The paper's qualitative findings at sigma_n = 500 MPa, from the envelope datasets {(name, law): ds}."""
    out = {}
    for (name, law), ds in env.items():
        p = ds.sel(sigma_n=500e6)
        stage = ds["stage"].values
        d1 = p["displacement_mean"].values[:, 0]
        start = int(np.flatnonzero(stage >= 2)[0]) - 1
        shear = d1[start:]
        out[f"{name} {law}"] = {
            "shear_stiffness_MPa_per_um": float(p["shear_stiffness_mean"]) * 1e-12,
            "peak_friction": float(p["peak_friction_mean"]), "peak_friction_se": float(p["peak_friction_sem"]),
            "residual_friction": float(p["residual_friction_mean"]),
            "peak_shear_displacement_um": float(p["peak_shear_displacement_mean"]) * 1e6,
            "compaction_during_shear_um": float(np.nanmax(shear) - shear[0]) * 1e6,
            "dilation_after_max_closure_um": float(np.nanmax(shear) - shear[-1]) * 1e6,
            "dilation_angle_peak_deg": math.degrees(float(p["dilation_angle_peak_mean"])),
            "shear_displacement_to_95_percent_of_peak_um": float(_to_fraction_of_peak(p, stage, 0.95)) * 1e6,
        }
    for law in {law for _, law in env}:
        r, s = (_resistance(env[(name, law)].sel(sigma_n=500e6)) for name in ("R1", "S1"))
        d2, above = r[0], r[1] > s[1]
        out[f"crossing {law}"] = {"R1_above_S1_from_um": float(d2[np.argmax(above)]) * 1e6 if above.any() else None,
                                  "S1_above_R1_first": bool(s[1][1] > r[1][1])}
    return out


def _resistance(p):
    """(Delta_2, sigma_2 / sigma_1) of the ensemble mean over the shear stages."""
    shear = p["stage"].values >= 2
    d, sig = p["displacement_mean"].values[shear], p["stress_mean"].values[shear]
    return d[:, 1], sig[:, 1] / sig[:, 0]


def _to_fraction_of_peak(p, stage, fraction):
    """Shear displacement [m] at which the mean shear stress first reaches ``fraction`` of its peak."""
    d2, ratio = _resistance(p)
    return d2[int(np.argmax(ratio >= fraction * np.nanmax(ratio)))]


def plot_summary(env_files: dict, cyc_files: dict):
    """R1 against S1, both laws: peak friction, shear stiffness against sigma_n; G/Gmax, damping against a."""
    from asperity_sim.output.plotting import plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5))
    colors = {"R1": "tab:red", "S1": "tab:blue"}
    styles = {"paper": "o-", "mdr": "s--"}
    for (name, law), f in env_files.items():
        ds = read_netcdf(f)
        x = ds["sigma_n"].values * 1e-6
        for ax, var, scale in ((axes[0, 0], "peak_friction", 1.0), (axes[0, 1], "shear_stiffness", 1e-12)):
            ax.errorbar(x, ds[f"{var}_mean"].values * scale, yerr=2 * np.nan_to_num(ds[f"{var}_sem"].values) * scale,
                        fmt=styles[law], color=colors[name], capsize=3, ms=4, label=f"{name}, {law}")
    for (name, law), f in cyc_files.items():
        ds = read_netcdf(f)
        x = ds["amplitude"].values * 1e6
        for ax, var, scale in ((axes[1, 0], "secant_stiffness_ratio", 1.0), (axes[1, 1], "damping_ratio", 100.0)):
            ax.errorbar(x, ds[f"{var}_mean"].values * scale, yerr=2 * np.nan_to_num(ds[f"{var}_sem"].values) * scale,
                        fmt=styles[law], color=colors[name], capsize=3, ms=4, label=f"{name}, {law}")
    axes[0, 0].axhline(1.0, color="0.5", lw=0.8, ls=":")
    axes[0, 0].set_ylabel(r"peak friction coefficient $\tau_p/\sigma_n$ [1] (asperity $\mu$ = 1 dotted)")
    axes[0, 1].set_ylabel("shear stiffness at the start of shear [MPa/µm]")
    axes[0, 1].set_yscale("log")
    axes[1, 0].set_ylabel(r"secant stiffness ratio $k_{sec}/k_0$ ($G/G_{max}$) [1]")
    axes[1, 1].set_ylabel("equivalent damping ratio [%]")
    for ax in axes[0]:
        ax.set_xlabel(r"normal stress $\sigma_n$ [MPa]")
        ax.set_xscale("log")
    for ax in axes[1]:
        ax.set_xlabel("shear amplitude a [µm] (sigma_n = 300 MPa, second cycle)")
        ax.set_xscale("log")
    for ax in axes.ravel():
        ax.legend(fontsize=7, title="bars: ±2 SE over replicas", title_fontsize=7)
    fig.suptitle("joint properties of R1 and S1, laws paper and mdr (mean ± 2 s.e. over replicas)", fontsize=10)
    fig.tight_layout()
    return fig


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], n_default=5000, argv=argv, extra=_extra)
    if not 1 <= args.replicas <= 100:
        raise SystemExit(f"--replicas = {args.replicas} is out of range (valid range: integer in [1, 100])")
    sigma = SIGMA_N[[1, 4]] if args.quick else SIGMA_N
    amps = AMPLITUDES[[1, 4]] if args.quick else AMPLITUDES
    replicas = min(args.replicas, 2) if args.quick else args.replicas
    inc = args.increments or (4 if args.quick else 20)
    args.outdir.mkdir(parents=True, exist_ok=True)
    env_files, cyc_files, env = {}, {}, {}
    for name in ("R1", "S1"):
        base = load_scene(HERE / f"constant_normal_shear_{name}.toml")
        for law in LAWS:
            scene = base.replace(n=args.n, seed=args.seed, sampler=args.sampler, law=law, k=args.k,
                                 path=scale_increments(base.path, inc))
            with Timer() as t:
                ds = E.envelope(scene, sigma, replicas=replicas, scheduler=None)
            files = F.write_products(ds, args.outdir / f"joint_envelope_{name}_{law}.nc")
            env_files[(name, law)], env[(name, law)] = files["netcdf"], ds
            f = ds.sel(strength="peak")
            print(f"{name} {law}: envelope at {len(sigma)} normal stresses x {replicas} replicas, n = {args.n}, "
                  f"{t.seconds:.1f} s on {ds.attrs['engine'].split(';')[0]}; peak Mohr-Coulomb c = "
                  f"{float(f.mc_cohesion) * 1e-6:.3g} MPa [{float(f.mc_cohesion_low) * 1e-6:.3g}, "
                  f"{float(f.mc_cohesion_high) * 1e-6:.3g}], phi = {math.degrees(float(f.mc_friction_angle)):.2f} deg "
                  f"[{math.degrees(float(f.mc_friction_angle_low)):.2f}, "
                  f"{math.degrees(float(f.mc_friction_angle_high)):.2f}]; power law B = {float(f.power_law_B):.3f}")
            with Timer() as t:
                cy = E.cyclic(scene, amps, cycles=2, increments=max(2, inc // 3), sigma_n=300e6, replicas=replicas)
            files = F.write_products(cy, args.outdir / f"joint_cyclic_{name}_{law}.nc")
            cyc_files[(name, law)] = files["netcdf"]
            print(f"  cyclic at {len(amps)} amplitudes, {t.seconds:.1f} s: G/Gmax "
                  + ", ".join(f"{v:.3f}" for v in cy["secant_stiffness_ratio_mean"].values) + "; damping ratio "
                  + ", ".join(f"{100 * v:.2f} %" for v in cy["damping_ratio_mean"].values))
    summary = {"sigma_n_Pa": 500e6, "n": args.n, "replicas": replicas, "at_500_MPa": findings(env)}
    for key, v in summary["at_500_MPa"].items():
        if key.startswith("crossing"):
            print(f"{key}: S1 above R1 at first: {v['S1_above_R1_first']}; R1 above S1 from "
                  f"{v['R1_above_S1_from_um']} um")
            continue
        print(f"{key:10s} at 500 MPa: k_s = {v['shear_stiffness_MPa_per_um']:.4g} MPa/um, peak friction "
              f"{v['peak_friction']:.4f} ± {v['peak_friction_se']:.2g} at {v['peak_shear_displacement_um']:.3g} um, "
              f"residual {v['residual_friction']:.4f}; compaction {v['compaction_during_shear_um']:.3g} um then "
              f"dilation {v['dilation_after_max_closure_um']:.3g} um; dilation angle at peak "
              f"{v['dilation_angle_peak_deg']:.2f} deg; 95 % of peak at "
              f"{v['shear_displacement_to_95_percent_of_peak_um']:.3g} um")
    (args.outdir / "joint_properties.json").write_text(json.dumps(summary, indent=2) + "\n")
    fig = plot_summary(env_files, cyc_files)
    fig.savefig(args.outdir / "joint_properties.png", dpi=130)
    print(f"wrote {len(env_files) + len(cyc_files)} datasets with tables and figures, "
          f"{args.outdir / 'joint_properties.png'}, {args.outdir / 'joint_properties.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
