"""Same numbers: does a refactoring leave every result of the scenarios and the stability study unchanged?

Question.  Two checkouts of asperity_sim, an old one (``--base``) and a new one (``--new``),
should compute the same thing.  This script runs every scenario script (``scenarios/*.py``
but ``_common.py``) and the stability study (``studies/stability.py``) in both, each task in a
fresh subprocess whose PYTHONPATH starts with that checkout and whose working directory is a
fresh temporary folder (each checkout's own scripts with its own package; base and new take turns
going first, task by task; one subprocess at a time), then compares what they wrote:

* every ``.nc`` file: the same set of files; in each, the same dimensions (and sizes),
  variables, coordinate variables, dtypes, dimensions of each variable and attributes, and every
  stored value bit for bit (the raw bytes as stored, no masking or scaling: NaN equals NaN at the
  same place with the same bits).  Volatile items are not compared (listed in the report):
  attributes whose name contains one of ``VOLATILE_ATTRIBUTES`` (creation date and time,
  history, wall times such as ``wall_time_s`` or ``fit_seconds``) or is one of
  ``VERSION_ATTRIBUTES`` (the package version); the values (not the dtype and dimensions) of
  variables whose name contains one of ``VOLATILE_VARIABLES`` (``wall_time_s``, ``bem_seconds``);
  and, in every string, the paths of the checkout, of the run's output folder and of its working
  folder (replaced by ``<checkout>``, ``<outdir>`` and ``<cwd>`` before comparing);
* the stability study's ``stability.md``, without its timing: the ``wall [s]`` columns, the
  ``N s on this machine`` of its headers and the package version in them.

The ``.png`` figures and the ``.csv``/``.json`` side products are not compared (they are drawn
or printed from the same numbers).  Numba runs with the same thread count on both sides
(``NUMBA_NUM_THREADS`` and ``OMP_NUM_THREADS``, ``--threads``), and each side has its own numba
cache folder under ``<outdir>/numba_cache`` (nothing is written into the checkouts but Python's
own ``__pycache__``).

Run:   python3 studies/same_numbers.py [--base /work/base] [--new DIR] [--outdir DIR] [--quick]
                                      [--only NAME ...] [--n N] [--threads T]
       e.g. ``python3 studies/same_numbers.py --quick`` (old checkout in /work/base, new: this one)
Writes <outdir>/same_numbers.md (the table printed), <outdir>/same_numbers.json (commits of both
checkouts and whether their trees are dirty, the settings, every run and every comparison) and
keeps each run's files and log in <outdir>/runs/{base,new}/<task>/.
Exit status 0 only if every task ran (exit status 0 on both sides) and everything compared is
identical; 1 otherwise; 2 for a bad command line.
Takes (measured on the shared 2-core machine, base against itself, 2 threads): ``--quick`` about
1.5 minutes with warm numba caches under <outdir>, about 4.5 minutes cold (every kernel is compiled
once per side on the first runs); a full run (the scripts' default sizes, stability with
``--no-big``) about 4.5 minutes warm, some 7-8 minutes cold.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import netCDF4
import numpy as np

REPO = Path(__file__).resolve().parent.parent
SIDES = ("base", "new")
STABILITY = "stability"
VOLATILE_ATTRIBUTES = ("history", "date_created", "wall_time", "seconds")  # not compared: names containing these
VERSION_ATTRIBUTES = ("source", "asperity_sim_version")  # not compared: these names (they hold the package version)
VOLATILE_VARIABLES = ("wall_time", "seconds")  # values not compared: names containing these
STABILITY_MD = "stability.md"


# --------------------------------------------------------------------------- command line and tasks

def parse_args(argv=None):
    p = argparse.ArgumentParser(prog="same_numbers.py", description=__doc__.splitlines()[0])
    p.add_argument("--base", type=Path, default=Path("/work/base"),
                   help="checkout of the old code (default /work/base)")
    p.add_argument("--new", type=Path, default=REPO, help=f"checkout of the new code (default {REPO})")
    p.add_argument("--outdir", type=Path, default=REPO / "outputs" / "same_numbers",
                   help="folder for the report and the runs (default outputs/same_numbers of this repository)")
    p.add_argument("--quick", action="store_true", help="smoke size: every task with --quick")
    p.add_argument("--only", action="append", default=None, metavar="NAME",
                   help="run only this task (a scenario name such as three_step, or stability); repeatable")
    p.add_argument("--n", type=int, default=None, help="pass --n N to every task (default: each task's own)")
    p.add_argument("--renamed", action="append", default=[], metavar="OLD=NEW",
                   help="a text the new code writes renamed (e.g. a module path that moved): OLD in the base's "
                        "strings reads as NEW before comparing; repeatable, listed in the report")
    p.add_argument("--threads", type=int, default=None,
                   help="numba and OpenMP threads of every run (default: $NUMBA_NUM_THREADS, else the core count)")
    args = p.parse_args(argv)
    for name in ("base", "new"):
        path = getattr(args, name).resolve()
        if not (path / "scenarios").is_dir() or not (path / "studies" / "stability.py").is_file():
            p.error(f"--{name} {path} is not a checkout of asperity_sim (no scenarios/ or studies/stability.py)")
        setattr(args, name, path)
    if args.n is not None and args.n < 1:
        p.error(f"--n = {args.n} is out of range (valid range: integer >= 1)")
    args.threads = args.threads or int(os.environ.get("NUMBA_NUM_THREADS") or os.cpu_count() or 1)
    if args.threads < 1:
        p.error(f"--threads = {args.threads} is out of range (valid range: integer >= 1)")
    try:
        args.renamed = [tuple(r.split("=", 1)) for r in args.renamed if r.index("=")]
    except ValueError:
        p.error(f"--renamed {args.renamed}: each must be OLD=NEW")
    args.outdir = args.outdir.resolve()
    args.tasks = all_tasks(args.base, args.new)
    unknown = sorted(set(args.only or ()) - set(args.tasks))
    if unknown:
        p.error(f"--only {', '.join(unknown)}: no such task (tasks: {', '.join(args.tasks)})")
    args.tasks = [t for t in args.tasks if not args.only or t in args.only]
    return args


def scenario_names(checkout: Path) -> set:
    return {f.stem for f in (checkout / "scenarios").glob("*.py") if not f.name.startswith("_")}


def all_tasks(base: Path, new: Path) -> list:
    """The scenario names of either checkout, sorted, then ``stability``."""
    return sorted(scenario_names(base) | scenario_names(new)) + [STABILITY]


def task_command(checkout: Path, task: str, outdir: Path, quick: bool, n) -> list:
    """The command line of one task in one checkout (its own script, run by this Python)."""
    if task == STABILITY:
        cmd = [sys.executable, str(checkout / "studies" / "stability.py"), "--outdir", str(outdir)]
        cmd += ["--quick"] if quick else ["--no-big"]
    else:
        cmd = [sys.executable, str(checkout / "scenarios" / f"{task}.py"), "--outdir", str(outdir)]
        cmd += ["--quick"] if quick else []
    return cmd + (["--n", str(n)] if n is not None else [])


# --------------------------------------------------------------------------- running

def side_env(checkout: Path, cache: Path, threads: int) -> dict:
    """The environment of a run: the checkout first on PYTHONPATH, fixed thread counts, its own numba cache."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(checkout)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    env.update(NUMBA_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads), NUMBA_CACHE_DIR=str(cache),
               MPLBACKEND="Agg")
    return env


def check_import(checkout: Path, env: dict) -> None:
    """Refuse to go on if ``import asperity_sim`` with ``env`` does not load the package of ``checkout``."""
    with tempfile.TemporaryDirectory(prefix="same_numbers-") as cwd:
        out = subprocess.run([sys.executable, "-c", "import asperity_sim; print(asperity_sim.__file__)"],
                             cwd=cwd, env=env, capture_output=True, text=True)
    where = Path(out.stdout.strip() or "?").resolve()
    if out.returncode != 0 or checkout not in where.parents:
        raise SystemExit(f"same_numbers.py: error: with PYTHONPATH={env['PYTHONPATH']}, asperity_sim comes from "
                         f"{where} (not from {checkout}): {out.stderr.strip()[-500:]}")


def run_task(cmd: list, env: dict, outdir: Path) -> dict:
    """Run ``cmd`` in a fresh temporary working folder, output and log in ``outdir`` (emptied first).

    The return code is None if the checkout has no such script.
    """
    if outdir.exists():
        shutil.rmtree(outdir)
    outdir.mkdir(parents=True)
    log = outdir.parent / f"{outdir.name}.log"
    with tempfile.TemporaryDirectory(prefix="same_numbers-") as cwd, open(log, "w") as fh:
        t0 = time.perf_counter()
        if Path(cmd[1]).is_file():
            rc = subprocess.run(cmd, cwd=cwd, env=env, stdout=fh, stderr=subprocess.STDOUT).returncode
        else:
            rc = None
            fh.write(f"no such script: {cmd[1]}\n")
        seconds = time.perf_counter() - t0
    return {"command": cmd, "returncode": rc, "seconds": round(seconds, 2), "log": str(log), "cwd": cwd,
            "outdir": str(outdir)}


def run_both(task: str, index: int, args, envs: dict) -> dict:
    """Run ``task`` on both sides, base first for even ``index``, new first for odd."""
    order = SIDES if index % 2 == 0 else SIDES[::-1]
    runs = {}
    for side in order:
        checkout = getattr(args, side)
        out = args.outdir / "runs" / side / task
        print(f"[{task}] {side}: running", flush=True)
        runs[side] = run_task(task_command(checkout, task, out, args.quick, args.n), envs[side], out)
        print(f"[{task}] {side}: exit status {runs[side]['returncode']}, {runs[side]['seconds']:.1f} s", flush=True)
    return runs


# --------------------------------------------------------------------------- comparing netCDF files

def is_volatile(name: str, patterns, exact=()) -> bool:
    return name in exact or any(p in name for p in patterns)


def normalizer(checkout: str, outdir: str, cwd: str, renamed=()):
    """A function replacing the run's own paths in a string by placeholders (longest first), and the
    texts ``renamed`` (old, new) by their new form."""
    pairs = sorted(((checkout, "<checkout>"), (outdir, "<outdir>"), (cwd, "<cwd>"),
                    (os.path.realpath(cwd), "<cwd>"), *renamed), key=lambda kv: -len(kv[0]))

    def norm(text: str) -> str:
        for path, tag in pairs:
            text = text.replace(path, tag)
        return text

    return norm


def same_attr(a, b, norm_a, norm_b) -> bool:
    if isinstance(a, str) and isinstance(b, str):
        return norm_a(a) == norm_b(b)
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def attr_differences(where: str, a: dict, b: dict, norm_a, norm_b, ignored: set):
    """Yield the differences of two attribute dicts, volatile names skipped (and noted in ``ignored``)."""
    if set(a) != set(b):
        yield "attribute", f"{where}: attributes only in base {sorted(set(a) - set(b))}, only in new " \
                           f"{sorted(set(b) - set(a))}"
    for key in a.keys() & b.keys():
        if is_volatile(key, VOLATILE_ATTRIBUTES, VERSION_ATTRIBUTES):
            ignored.add(key)
        elif not same_attr(a[key], b[key], norm_a, norm_b):
            yield "attribute", f"{where}: attribute {key!r}: base {a[key]!r:.200} != new {b[key]!r:.200}"


def raw(var) -> np.ndarray:
    """The values of a netCDF4 variable as stored (no mask, no scaling, char arrays as chars)."""
    var.set_auto_maskandscale(False)
    var.set_auto_chartostring(False)
    return np.asarray(var[...])


def value_difference(name: str, a: np.ndarray, b: np.ndarray, norm_a, norm_b):
    """None if ``a`` and ``b`` hold the same bits (strings: the same text up to the run's paths), else what differs."""
    if a.dtype == object or a.dtype.kind in "US":
        fa = [norm_a(str(x)) for x in a.ravel()]
        fb = [norm_b(str(x)) for x in b.ravel()]
        bad = [i for i, (x, y) in enumerate(zip(fa, fb)) if x != y]
        return None if not bad else (f"variable {name!r}: {len(bad)} of {len(fa)} strings differ, first at "
                                     f"flat index {bad[0]}: base {fa[bad[0]]!r:.120} != new {fb[bad[0]]!r:.120}")
    if a.tobytes() == b.tobytes():
        return None
    return f"variable {name!r}: " + numeric_difference(a, b)


def numeric_difference(a: np.ndarray, b: np.ndarray) -> str:
    """How much two numeric arrays of one shape and dtype differ: count, NaN places, max abs and rel."""
    a, b = a.ravel(), b.ravel()
    differ = a.view(np.uint8).reshape(a.size, -1) != b.view(np.uint8).reshape(b.size, -1)
    text = f"{int(np.any(differ, axis=1).sum())} of {a.size} values differ"
    if a.dtype.kind in "fc":
        nan_a, nan_b = np.isnan(a), np.isnan(b)
        if np.any(nan_a != nan_b):
            text += f", NaN at {int(np.sum(nan_a != nan_b))} places on one side only"
        a, b = a[~nan_a & ~nan_b], b[~nan_a & ~nan_b]
    if a.dtype.kind in "biufc" and a.size:
        with np.errstate(all="ignore"):
            d = np.abs(a.astype(np.complex128 if a.dtype.kind == "c" else np.float64) - b)
            rel = np.where(d > 0, d / np.maximum(np.abs(a), np.abs(b)).astype(np.float64), 0.0)
        text += f"; max abs difference {np.nanmax(d):.3g}, max rel difference {np.nanmax(rel):.3g}"
    return text


def variable_differences(name: str, va, vb, norm_a, norm_b, ignored: set):
    """Yield what differs in one variable: dtype or dims (then nothing more), attributes, values."""
    if va.dtype != vb.dtype:
        yield "structure", f"variable {name!r}: dtype base {va.dtype} != new {vb.dtype}"
        return
    if va.dimensions != vb.dimensions or va.shape != vb.shape:
        yield "structure", f"variable {name!r}: dims base {va.dimensions}{va.shape} != new {vb.dimensions}{vb.shape}"
        return
    yield from attr_differences(f"variable {name!r}", {k: va.getncattr(k) for k in va.ncattrs()},
                                {k: vb.getncattr(k) for k in vb.ncattrs()}, norm_a, norm_b, ignored)
    if is_volatile(name, VOLATILE_VARIABLES):
        ignored.add(f"values of variable {name}")
        return
    diff = value_difference(name, raw(va), raw(vb), norm_a, norm_b)
    if diff:
        yield "values", diff


def group_differences(ga, gb, norm_a, norm_b, ignored: set, where="/"):
    """Yield (kind, text) for every difference between two netCDF4 groups, recursively."""
    dims_a = {k: (len(d), d.isunlimited()) for k, d in ga.dimensions.items()}
    dims_b = {k: (len(d), d.isunlimited()) for k, d in gb.dimensions.items()}
    if dims_a != dims_b:
        yield "structure", f"{where}: dimensions base {dims_a} != new {dims_b}"
    names_a, names_b = list(ga.variables), list(gb.variables)
    if names_a != names_b:
        yield "structure", (f"{where}: variables only in base {sorted(set(names_a) - set(names_b))}, only in new "
                            f"{sorted(set(names_b) - set(names_a))}" + (" (order only)" if set(names_a) == set(names_b)
                                                                        else ""))
    yield from attr_differences(f"{where} global", {k: ga.getncattr(k) for k in ga.ncattrs()},
                                {k: gb.getncattr(k) for k in gb.ncattrs()}, norm_a, norm_b, ignored)
    for name in (n for n in names_a if n in gb.variables):
        yield from variable_differences(name, ga.variables[name], gb.variables[name], norm_a, norm_b, ignored)
    if list(ga.groups) != list(gb.groups):
        yield "structure", f"{where}: groups base {list(ga.groups)} != new {list(gb.groups)}"
    for name in (n for n in ga.groups if n in gb.groups):
        yield from group_differences(ga.groups[name], gb.groups[name], norm_a, norm_b, ignored, f"{where}{name}/")


def compare_nc(path_a: Path, path_b: Path, norm_a, norm_b, ignored: set):
    """(verdict, every difference, coordinate variables) of two netCDF files.

    The verdict names the first difference of the values if any (else the first of the structure, else of the
    attributes) and how many there are in all.
    """
    with netCDF4.Dataset(path_a) as a, netCDF4.Dataset(path_b) as b:
        coords = [v for v in a.variables if v in a.dimensions]
        diffs = list(group_differences(a, b, norm_a, norm_b, ignored))
    if not diffs:
        return "identical", [], coords
    first = next(text for kind in ("values", "structure", "attribute") for k, text in diffs if k == kind)
    more = f" (and {len(diffs) - 1} more difference{'s' * (len(diffs) > 2)}: see the JSON)" if len(diffs) > 1 else ""
    return f"DIFFERENT: {first}{more}", [f"{k}: {t}" for k, t in diffs], coords


# --------------------------------------------------------------------------- comparing stability.md

def markdown_without_timing(text: str, norm) -> list:
    """The lines of stability.md without its wall-time columns, seconds and package version."""
    out, drop = [], None
    for line in norm(text).splitlines():
        line = re.sub(r"\d+(\.\d+)? s on this machine", "<t> s on this machine", line)
        line = re.sub(r"asperity_sim \d+\.\d+\S*,", "asperity_sim <version>,", line)
        if line.startswith("|"):
            cells = line.strip().strip("|").split("|")
            if any(c.strip() == "wall [s]" for c in cells):
                drop = [i for i, c in enumerate(cells) if c.strip() == "wall [s]"]
            if drop:
                line = "|" + "|".join(c for i, c in enumerate(cells) if i not in drop) + "|"
        else:
            drop = None
        out.append(line)
    return out


def compare_markdown(path_a: Path, path_b: Path, norm_a, norm_b) -> str:
    la = markdown_without_timing(path_a.read_text(), norm_a)
    lb = markdown_without_timing(path_b.read_text(), norm_b)
    for i, (x, y) in enumerate(zip(la, lb), 1):
        if x != y:
            return f"DIFFERENT: line {i}: base {x!r:.150} != new {y!r:.150}"
    if len(la) != len(lb):
        return f"DIFFERENT: base has {len(la)} lines, new {len(lb)}"
    return "identical"


# --------------------------------------------------------------------------- one task

def compare_task(task: str, runs: dict, args) -> list:
    """The rows (task, file, verdict) of one task: its exit codes, then every .nc file, then stability.md."""
    rows = []
    codes = {s: runs[s]["returncode"] for s in SIDES}
    if any(code != 0 for code in codes.values()):
        what = {s: "no such script" if c is None else f"exit status {c}" for s, c in codes.items()}
        rows.append({"task": task, "file": "(exit status)", "verdict": f"ERROR: base {what['base']}, "
                     f"new {what['new']} (see the logs)", "ok": False})
    dirs = {s: Path(runs[s]["outdir"]) for s in SIDES}
    norms = {s: normalizer(str(getattr(args, s)), runs[s]["outdir"], runs[s]["cwd"],
                           args.renamed if s == "base" else ()) for s in SIDES}
    files = {s: {p.relative_to(dirs[s]).as_posix() for p in dirs[s].rglob("*.nc")} for s in SIDES}
    if not files["base"] | files["new"]:
        rows.append({"task": task, "file": "(none)", "verdict": "ERROR: no .nc file written", "ok": False})
    ignored = set()
    for name in sorted(files["base"] | files["new"]):
        if name not in files["base"] or name not in files["new"]:
            only = "base" if name in files["base"] else "new"
            rows.append({"task": task, "file": name, "verdict": f"DIFFERENT: written by {only} only", "ok": False})
            continue
        verdict, diffs, coords = compare_nc(dirs["base"] / name, dirs["new"] / name, norms["base"], norms["new"],
                                            ignored)
        rows.append({"task": task, "file": name, "verdict": verdict, "ok": not diffs, "differences": diffs,
                     "coordinates": coords})
    if task == STABILITY:
        rows.append(markdown_row(task, dirs, norms))
    for row in rows:
        row["ignored"] = sorted(ignored)
    return rows


def markdown_row(task: str, dirs: dict, norms: dict) -> dict:
    paths = {s: dirs[s] / STABILITY_MD for s in SIDES}
    missing = [s for s in SIDES if not paths[s].is_file()]
    if missing:
        return {"task": task, "file": STABILITY_MD, "verdict": f"ERROR: not written by {', '.join(missing)}",
                "ok": False}
    verdict = compare_markdown(paths["base"], paths["new"], norms["base"], norms["new"])
    return {"task": task, "file": STABILITY_MD + " (no timing)", "verdict": verdict, "ok": verdict == "identical"}


# --------------------------------------------------------------------------- report

def git_state(checkout: Path) -> dict:
    """HEAD and whether the tree is dirty (tracked or untracked changes), read-only (no optional locks)."""
    def git(*a):
        r = subprocess.run(["git", "--no-optional-locks", "-C", str(checkout), *a], capture_output=True, text=True)
        return r.stdout.strip() if r.returncode == 0 else None

    status = git("status", "--porcelain")
    return {"path": str(checkout), "commit": git("rev-parse", "HEAD"),
            "dirty": None if status is None else bool(status),
            "changed_files": None if status is None else len(status.splitlines())}


def md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def markdown_report(rows: list, runs: dict, state: dict, args, seconds: float) -> str:
    ok = all(r["ok"] for r in rows)
    lines = [f"# Same numbers: {'everything identical' if ok else 'NOT identical'}", ""]
    for side in SIDES:
        s = state[side]
        lines.append(f"- {side}: {s['path']} at {s['commit']}"
                     f"{' (dirty: ' + str(s['changed_files']) + ' changed or untracked files)' if s['dirty'] else ''}")
    lines += [f"- size: {'--quick' if args.quick else 'full (stability --no-big)'}"
              f"{f', --n {args.n}' if args.n else ''}; {args.threads} numba/OpenMP threads; {seconds:.0f} s in all",
              "", "| task | file | verdict |", "|---|---|---|"]
    lines += [f"| {r['task']} | {r['file']} | {md_cell(r['verdict'])} |" for r in rows]
    lines += ["", "| task | base [s] | new [s] |", "|---|---|---|"]
    lines += [f"| {t} | {r['base']['seconds']:.1f} | {r['new']['seconds']:.1f} |" for t, r in runs.items()]
    ignored = sorted({k for r in rows for k in r.get("ignored", [])})
    lines += ["", "Not compared (volatile): attributes whose name contains "
              + ", ".join(f"`{p}`" for p in VOLATILE_ATTRIBUTES) + " or is " + ", ".join(
                  f"`{p}`" for p in VERSION_ATTRIBUTES) + " (met here: " + (", ".join(
                  f"`{k}`" for k in ignored if not k.startswith("values")) or "none") + "); values of variables "
              "whose name contains " + ", ".join(f"`{p}`" for p in VOLATILE_VARIABLES) + " (met here: "
              + (", ".join(f"`{k.split()[-1]}`" for k in ignored if k.startswith("values")) or "none")
              + "); in strings, the checkout, output and working folder paths; in stability.md the `wall [s]` "
              "columns, the `N s on this machine` and the package version of its headers; .png, .csv and .json "
              "files."]
    if args.renamed:
        lines += ["", "Renamed before comparing (base text -> new text): "
                  + "; ".join(f"`{a}` -> `{b}`" for a, b in args.renamed)]
    return "\n".join(lines) + "\n"


def main(argv=None):
    args = parse_args(argv)
    args.outdir.mkdir(parents=True, exist_ok=True)
    envs = {s: side_env(getattr(args, s), args.outdir / "numba_cache" / s, args.threads) for s in SIDES}
    for side in SIDES:
        check_import(getattr(args, side), envs[side])
    state = {s: git_state(getattr(args, s)) for s in SIDES}
    t0 = time.perf_counter()
    rows, runs = [], {}
    for i, task in enumerate(args.tasks):
        runs[task] = run_both(task, i, args, envs)
        rows += compare_task(task, runs[task], args)
    seconds = time.perf_counter() - t0
    report = markdown_report(rows, runs, state, args, seconds)
    print("\n" + report)
    (args.outdir / "same_numbers.md").write_text(report)
    record = {"identical": all(r["ok"] for r in rows), "base": state["base"], "new": state["new"],
              "quick": args.quick, "n": args.n, "threads": args.threads, "seconds": round(seconds, 1),
              "volatile_attributes": VOLATILE_ATTRIBUTES, "version_attributes": VERSION_ATTRIBUTES,
              "volatile_variables": VOLATILE_VARIABLES, "renamed": args.renamed, "python": sys.executable, "runs": runs, "comparisons": rows}
    (args.outdir / "same_numbers.json").write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {args.outdir / 'same_numbers.md'}, {args.outdir / 'same_numbers.json'}")
    return 0 if record["identical"] else 1


if __name__ == "__main__":
    sys.exit(main())
