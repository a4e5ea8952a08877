"""The stability study's tables: markdown for docs/stability.md and a netCDF dataset, from the records.

The records are those of ``stability_cases.run_matrix`` (one per run) and
``stability_hostile.run_hostile_table`` (one per hostile case); ``studies/stability.py`` writes
both tables to ``outputs/stability.md`` and ``outputs/stability.nc``.  A study module beside the
script (moved out of ``asperity_sim.stability`` in 0.4).
"""

from __future__ import annotations

import numpy as np
from stability_cases import CASES, LAWS, PATHS
from stability_hostile import SAME


def to_dataset(records, attrs):
    import xarray as xr

    cols = {k: [r[k] for r in records] for k in records[0]}
    units = {"n": "1", "all_converged": "1", "steps": "1", "iter_max": "1", "iter_mean": "1", "residual_max": "1", "residual_final": "1",
             "cutbacks": "1", "wall_time_s": "s", "sigma_n": "Pa", "d": "m"}
    long = {"case": "case name", "path": "load path", "law": "asperity law", "n": "asperities sampled",
            "expected": "expected outcome", "outcome": "outcome (complete or exception class)",
            "message": "exception message", "steps": "converged increments",
            "all_converged": "1 when every increment of the path converged",
            "iter_max": "largest Newton iterations of an increment", "iter_mean": "mean Newton iterations",
            "residual_max": "largest final scaled residual of an increment",
            "residual_final": "final scaled residual of the last increment", "cutbacks": "increment halvings",
            "nonfinite": "outputs holding NaN or inf (empty: none)", "wall_time_s": "wall time",
            "sigma_n": "normal stress of the stress-controlled paths", "d": "closure of the 3-step path",
            "verdict": "pass, or why not"}
    data = {}
    for k, v in cols.items():
        a = np.array(v, dtype=object if isinstance(v[0], str) else None)
        if a.dtype == object:
            a = a.astype(str)
        data[k] = ("run", a, {"long_name": long[k], **({"units": units[k]} if k in units else {})})
    return xr.Dataset(data, coords={"run": np.arange(len(records))}, attrs=attrs)



def _cell(recs):
    if not recs:
        return ""
    r = recs[0]
    mark = "ok" if r["verdict"] == "pass" else "**FAIL**"
    if r["outcome"] == "complete":
        return f"{mark} {r['iter_max']}/{r['iter_mean']:.1f}"
    return f"{mark} {r['outcome'].replace('Error', '')}"


def markdown(records, header):
    kinds = [k for k in PATHS if any(r["path"] == k for r in records)]
    cols = [(k, law) for k in kinds for law in LAWS if any(r["path"] == k and r["law"] == law for r in records)]
    lines = [header, "",
             "Cells: verdict, then Newton iterations per increment (max/mean) of a run that completed, "
             "or the exception that stopped it (expected for `above_strength` and `tension` only, unless a case says "
             "otherwise).", "",
             "| case | " + " | ".join(f"{k} {law}" for k, law in cols) + " |",
             "|---|" + "---|" * len(cols)]
    for name in dict.fromkeys(r["case"] for r in records):
        cells = [_cell([r for r in records if r["case"] == name and r["path"] == k and r["law"] == law])
                 for k, law in cols]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", "### The cases", ""]
    for case in CASES:
        if any(r["case"] == case.name for r in records):
            what = ("with " + ", ".join(f"{k} = {v:.6g}" for k, v in case.changes.items())) if case.changes else "as is"
            extra = [f"n = {case.n:g}" if case.n else "", f"policy {case.policy}" if case.policy != "follow" else "",
                     f"sigma_n = {case.sigma_n}" if case.sigma_n is not None else ""]
            extra = "; ".join(e for e in extra if e)
            lines.append(f"- **{case.name}**: {case.base} {what}{'; ' + extra if extra else ''}"
                         f"{'. ' + case.note if case.note else ''}")
    lines += ["", "### Every run", "",
              "| case | path | law | n | outcome | expected | iters max/mean | residual final (max) | cut-backs "
              "| NaN/inf | wall [s] |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in records:
        lines.append(f"| {r['case']} | {r['path']} | {r['law']} | {r['n']:g} | {r['outcome']} | {r['expected']} | "
                     f"{r['iter_max']}/{r['iter_mean']:.2f} | {r['residual_final']:.1e} ({r['residual_max']:.1e}) | "
                     f"{r['cutbacks']} | {r['nonfinite'] or 'none'} | {r['wall_time_s']:.2f} |")
    msgs = [r for r in records if r["outcome"] != "complete"]
    if msgs:
        lines += ["", "### Why the runs that stopped stopped", ""]
        for r in msgs:
            lines.append(f"- {r['case']}, {r['path']}, {r['law']}: `{r['outcome']}`: {r['message'][:400]}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- hostile inputs


def hostile_markdown(records, header):
    lines = [header, "",
             "Expected: the exception that must refuse the input (before any work for the output and seed rows), "
             f"or `{SAME}` (resumed bit-identically to an uninterrupted run).", "",
             "| case | law | expected | outcome | verdict | wall [s] |", "|---|---|---|---|---|---|"]
    for r in records:
        lines.append(f"| {r['case']} | {r['law']} | {r['expected']} | {r['outcome']} | {r['verdict']} | "
                     f"{r['wall_time_s']:.2f} |")
    lines += ["", "Messages:", ""]
    for r in records:
        if r["message"]:
            lines.append(f"- {r['case']}, {r['law']}: {r['message'][:300]}")
    return "\n".join(lines) + "\n"


def hostile_dataset(records):
    import xarray as xr

    long = {"case": "hostile input", "law": "asperity law", "expected": "expected outcome",
            "outcome": "outcome (exception class, same bits, ...)", "message": "message of the outcome",
            "wall_time_s": "wall time", "verdict": "pass, skipped (and why), or why not"}
    data = {}
    for k, name in long.items():
        v = [r[k] for r in records]
        attrs = {"long_name": name, **({"units": "s"} if k == "wall_time_s" else {})}
        data[f"hostile_{k}"] = ("hostile", np.array(v, dtype=float if k == "wall_time_s" else str), attrs)
    return xr.Dataset(data, coords={"hostile": np.arange(len(records))})
