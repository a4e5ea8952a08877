"""Stability study: does every run over the corners of the input space end well, or stop by name?

What it measures.  Two tables, defined in the study's modules beside this script
(``stability_cases.py``, ``stability_hostile.py``):

* the matrix: each case changes the R1 (or S1) set of Table 1 towards an edge of the parameter
  space (SPEC §1), alone and combined, and runs the 3-step displacement path, constant normal
  stress shear, cyclic shear and, where a case asks for them, stress control from zero load,
  stress-controlled shear, shear above the frictional strength, tension, unload-reload and
  seat-load, for the laws ``paper`` and ``mdr``.  Per run: the outcome (``complete`` or the
  exception's class) against the expected one, Newton iterations (max, mean), residuals,
  cut-backs, whether any output is NaN or inf, the message and the wall time;
* the hostile inputs: an output path that is a folder, lies under a file, is not writable or is
  the checkpoint; an existing output without ``--overwrite``; seeds of 2^63 and -1; checkpoints
  truncated, with a flipped bit, forged with valid checksums (NaN state, unsorted heights, an
  index out of range); a checkpoint of another law or load path; a kill during a checkpoint
  write.  Per case: the outcome against the expected one (the exception that must refuse the
  input, or ``same bits``: resumed bit-identically to an uninterrupted run).

Every run has a soft wall-time limit (``simulate(max_wall_time=...)``) and runs in a worker
process killed at a hard limit, so a hang or a crash inside a kernel is an outcome too.  Nothing
is compared with a reference (the physics is tested elsewhere): this is about robustness.

Run:   python3 studies/stability.py [--n 2000] [--quick] [--no-big] [--no-hostile] [--only SUBSTRING]
Takes: about 2 minutes on the shared 2-core machine (the six 1e7-asperity runs take a third of
it, the hostile table about 15 s); ``--quick`` (no 1e7 case, 3 increments per stage, the quick
subset of both tables) about 1 minute.
Writes outputs/stability.nc (one record per run, dimension ``run``, and per hostile case,
dimension ``hostile``) and outputs/stability.md (the tables for docs/stability.md: one row per
case, one row per run, one row per hostile case).  Exit status 1 if any run did not do what it
must.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

OUTPUTS = Path(__file__).resolve().parent.parent / "outputs"


def parse_args(argv=None):
    p = argparse.ArgumentParser(prog="stability.py", description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=2000, help="asperities sampled per run (default 2000)")
    p.add_argument("--seed", type=int, default=2024, help="random seed (default 2024)")
    p.add_argument("--increments", type=int, default=None, help="increments per stage (default 6, --quick 3)")
    p.add_argument("--outdir", type=Path, default=OUTPUTS, help="folder for stability.nc and .md (default outputs/)")
    p.add_argument("--quick", action="store_true", help="the quick subset of both tables, no 1e7 case")
    p.add_argument("--no-big", action="store_true", help="skip the 1e7-asperity cases")
    p.add_argument("--no-hostile", action="store_true", help="skip the table of hostile inputs")
    p.add_argument("--only", action="append", default=None, help="run only cases whose name contains this")
    p.add_argument("--soft-limit", type=float, default=60.0, help="wall-time limit per run [s] (default 60)")
    p.add_argument("--hard-limit", type=float, default=180.0,
                   help="worker killed after this many seconds per run [s] (default 180)")
    p.add_argument("--in-process", action="store_true", help="no worker process (no hard limit)")
    args = p.parse_args(argv)
    for name, value, lo in (("--n", args.n, 1), ("--seed", args.seed, 0), ("--increments", args.increments, 1)):
        if value is not None and value < lo:
            p.error(f"{name} = {value} is out of range (valid range: integer >= {lo})")
    for name, value in (("--soft-limit", args.soft_limit), ("--hard-limit", args.hard_limit)):
        if not value > 0.0:
            p.error(f"{name} [s] = {value} is out of range (valid range: (0.0, inf))")
    return args


def main(argv=None):
    args = parse_args(argv)
    import stability_cases as cases  # the study's modules, beside this script (its folder is on sys.path)
    import stability_hostile as hostile_inputs
    import stability_tables as tables

    from asperity_sim import __version__
    from asperity_sim.output.netcdf import write_netcdf
    from asperity_sim.solve.solver import SolverSettings

    inc = args.increments or (3 if args.quick else 6)
    runs = cases.select_runs(quick=args.quick, big=not args.no_big, only=args.only)
    hostile = [] if args.no_hostile else hostile_inputs.select_hostile(quick=args.quick, only=args.only)
    if not runs and not hostile:
        print(f"stability.py: error: --only {args.only} selects no case", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    records = cases.run_matrix(runs, args.n, args.seed, inc, args.soft_limit, args.hard_limit,
                                   args.in_process) if runs else []
    t_matrix = time.perf_counter() - t0
    hostile_records = hostile_inputs.run_hostile_table(hostile, args.hard_limit, args.in_process) if hostile else []
    total = time.perf_counter() - t0
    s = SolverSettings()
    cap = s.max_iter + s.max_expansions + 2 * s.max_iter  # scalar search + multi-component solve and its restart
    for r in records:
        r["verdict"] = cases.verdict(r, cap)
    n_pass = sum(r["verdict"] == "pass" for r in records)
    h_pass = sum(r["verdict"] in ("pass", "skipped") for r in hostile_records)
    h_skip = sum(r["verdict"] == "skipped" for r in hostile_records)
    attrs = {"title": "asperity_sim stability matrix", "source": f"asperity_sim {__version__}",
             "Conventions": "CF-1.8", "n_default": args.n, "seed": args.seed, "increments": inc,
             "total_wall_time_s": total, "runs_passed": n_pass, "runs": len(records),
             "hostile_passed": h_pass - h_skip, "hostile_skipped": h_skip, "hostile": len(hostile_records)}
    parts = []
    if records:
        header = (f"Stability matrix: {len(records)} runs, {n_pass} pass, n = {args.n} unless stated, "
                  f"{inc} increments per stage (asperity_sim {__version__}, {t_matrix:.0f} s on this machine)")
        parts.append(tables.markdown(records, header))
    if hostile_records:
        header = (f"### Hostile inputs and checkpoints: {len(hostile_records)} cases, {h_pass - h_skip} pass, "
                  f"{h_skip} skipped ({total - t_matrix:.0f} s on this machine)")
        parts.append(tables.hostile_markdown(hostile_records, header))
    ds = tables.to_dataset(records, attrs) if records else None
    if hostile_records:
        hds = tables.hostile_dataset(hostile_records)
        ds = hds.assign_attrs(attrs) if ds is None else ds.merge(hds).assign_attrs(attrs)
    args.outdir.mkdir(parents=True, exist_ok=True)
    nc = write_netcdf(ds, args.outdir / "stability.nc")
    md = args.outdir / "stability.md"
    text = "\n".join(parts)
    tmp = md.with_name(f".{md.name}.tmp")
    tmp.write_text(text)
    tmp.replace(md)
    print()
    print(text)
    print(f"wrote {nc}, {md}")
    return 0 if n_pass == len(records) and h_pass == len(hostile_records) else 1


if __name__ == "__main__":
    sys.exit(main())
