"""The text reports of ``asperity-sim``: ``info`` on a run or sweep file, and ``presets``.
"""

from __future__ import annotations

import numpy as np

# -- plot ----------------------------------------------------------------------

RUN_VARIABLES = ("stress", "displacement", "stress_stderr", "displacement_stderr", "stage", "iterations",
                 "cutbacks", "residual", "n_contact", "n_slip")
SWEEP_VARIABLES = ("stress", "displacement", "status", "aligned_exactly", "total_iterations", "max_iterations",
                   "total_cutbacks")


def _run_wall_time(attrs):
    """Wall-clock seconds of a run's increment loop: ``wall_time_increment_loop_s``, or ``wall_time_s`` in older files."""
    for key in ("wall_time_increment_loop_s", "wall_time_s"):
        if key in attrs:
            return float(attrs[key])
    return None


def _params_lines(attrs):
    from ..params import InterfaceParams
    from ..units import format_quantity

    lines = []
    longs = InterfaceParams.long_names()
    for name, unit in InterfaceParams.units().items():
        key = f"param_{name}"
        if key in attrs:
            v = float(attrs[key])
            readable = format_quantity(v, unit) if unit != "1" else f"{v:.6g}"
            if f"{key}_note" in attrs:
                lines.append(f"  {name:8s} = {'swept':>14s}   [see grid]  {longs[name]}")
            else:
                lines.append(f"  {name:8s} = {readable:>14s}   [{v:.6g} {unit}]  {longs[name]}")
    return lines


def info_text(ds, path) -> str:
    """A plain-text summary of a run or sweep file."""
    a = ds.attrs
    lines = [f"{path}: {a.get('title', '')}", f"  {a.get('source', '?')}, created {a.get('date_created', '?')}"]
    if a.get("kind") == "sweep":
        return "\n".join(lines + _sweep_info(ds))
    if "scene_file" in a:
        lines.append(f"scene: {a['scene_file']}")
    lines.append(f"status: {a.get('status', '?')}")
    lines.append(f"law {a.get('law')}, policy {a.get('policy')}, sampler {a.get('sampler')}, "
                 f"n = {a.get('n_asperities')}, seed = {a.get('seed')}")
    lines.append("parameters:")
    lines += _params_lines(a)
    lines.append("load path:")
    lines += ["  " + line for line in str(a.get("load_path", "?")).splitlines()]
    it, cuts, res = ds["iterations"].values[1:], ds["cutbacks"].values[1:], ds["residual"].values[1:]
    steps = ds.sizes["step"] - 1
    lines.append(f"steps: {steps} converged increments over {int(ds['stage'].values.max())} stage(s)"
                 + (f", wall time {wall:.2f} s (increment loop)" if (wall := _run_wall_time(a)) is not None else ""))
    if steps:
        lines.append(f"convergence: Newton iterations total {int(it.sum())}, mean {it.mean():.2f}, max {int(it.max())};"
                     f" cut-backs {int(cuts.sum())}; largest final residual {res.max():.2g}")
        last = ds.isel(step=-1)
        d, s = last["displacement"].values, last["stress"].values
        sd, ss = last["displacement_stderr"].values, last["stress_stderr"].values
        lines.append("final state:")
        for k in range(3):
            lines.append(f"  Delta_{k + 1} = {d[k] * 1e6:10.4g} ± {sd[k] * 1e6:.2g} um   "
                         f"sigma_{k + 1} = {s[k] * 1e-6:10.4g} ± {ss[k] * 1e-6:.2g} MPa")
        n = max(int(a.get("n_asperities", 1)), 1)
        lines.append(f"  in contact {int(last['n_contact'])} ({100 * int(last['n_contact']) / n:.3g} %), "
                     f"full slip {int(last['n_slip'])}")
    return "\n".join(lines)


def _sweep_info(ds):
    a = ds.attrs
    status = ds["status"].values.ravel()
    complete = int(np.sum(status == "complete"))
    lines = [f"sweep of {a.get('runs')} runs on {a.get('engine')}, {float(a.get('wall_time_s', np.nan)):.1f} s",
             f"grid: {a.get('grid')}",
             f"replicas: {a.get('replicas')} (seeds {a.get('seeds')})",
             f"law {a.get('law')}, policy {a.get('policy')}, sampler {a.get('sampler')}, n = {a.get('n_asperities')}",
             "parameters (base values):"]
    lines += _params_lines(a)
    lines.append("load path:")
    lines += ["  " + line for line in str(a.get("load_path", "?")).splitlines()]
    lines.append(f"runs complete: {complete} of {status.size}; interpolated onto the nominal steps: "
                 f"{int(np.sum(ds['aligned_exactly'].values == 0))}")
    for s in sorted(set(status) - {"complete"}):
        lines.append(f"  {int(np.sum(status == s))} run(s): {s}")
    lines.append(f"convergence: Newton iterations total {int(ds['total_iterations'].sum())}, max per increment "
                 f"{int(ds['max_iterations'].max())}; cut-backs {int(ds['total_cutbacks'].sum())}")
    return lines


# -- presets -----------------------------------------------------------------------

def presets_text(names=None) -> str:
    """The Table 1 parameter sets: every parameter and derived quantity with its unit.

    One block per preset, one line per quantity: ``beta = 3.52e-06 m  (3.52 um)``; a
    dimensionless one is marked ``[-]``.  Units and long names come from the definitions in
    :class:`asperity_sim.params.InterfaceParams` (field metadata and derived properties).
    """
    from ..params import InterfaceParams
    from ..presets import TABLE1, TITLES
    from ..units import format_quantity

    units, longs = InterfaceParams.units(), InterfaceParams.long_names()
    rows = [(name, units[name], longs[name]) for name in units]
    derived = [(name, unit, long) for name, (unit, long) in InterfaceParams.derived_units().items()]

    def line(params, name, unit, long):
        v = getattr(params, name)
        si = f"{v:.6g} {'[-]' if unit == '1' else unit}"
        readable = format_quantity(v, unit) if unit in ("m", "Pa", "m-2") and v != 0.0 else ""
        readable = f"({readable})" if readable and readable != si else ""
        return f"  {name:8s} = {si:16s} {readable:16s} {long}"

    lines = ["Parameter sets that ship (the paper's Table 1), in SI units; [-] is dimensionless.",
             "Use in a scene file: [parameters] preset = \"R1\", plus overrides such as R_m = \"50 um\"."]
    for preset in names or TABLE1:
        params = TABLE1[preset]
        lines += ["", f"{preset}: {TITLES.get(preset, '')}"]
        lines += [line(params, *row) for row in rows]
        lines.append("  derived:")
        lines += [line(params, *row) for row in derived]
    return "\n".join(lines)
