"""Regenerate the reference results and figures the documentation shows, into ``docs/results/``.

The documentation (README.md, docs/*.md) shows figures and quotes numbers from result files.
Those files are kept, tracked by git, in ``docs/results/``; everything the scripts write goes
to ``outputs/``, which git ignores.  This script is the one command that rebuilds the kept
files: it runs each producing script into a work folder under ``outputs/``
(``--outdir outputs/reference_results/<task>``), saves its console output as a log, and copies
the files the documentation uses (the ``keep`` list of each task below) into ``docs/results/``.
Files the scripts write that the documentation does not use stay in the work folder.

Tasks, with their run time on the 2 shared cores of the development machine (warm numba cache):

- ``paper``: ``scenarios/paper_figures.py``, the paper's Figs. 11-13 (about 1 min);
- ``history``: the four history-law scenarios, ``cyclic_shear``, ``rotating_shear``,
  ``history_vs_paper``, ``unload_reload_shear`` (about 3 min);
- ``bem``: ``scenarios/bem_closure.py``, against a boundary-element solution (about 1 min; needs tamaas);
- ``joint``: ``scenarios/joint_properties.py``, strength envelopes and cyclic properties (about 1 min);
- ``stability``: ``studies/stability.py``, the stability matrix and hostile inputs (cases in
  ``stability_cases.py`` and ``stability_hostile.py`` beside it; about 1-5 min);
- ``convergence`` (about 30 min) and ``mdr_convergence`` (about 15 min): the two error-against-time
  studies, and ``exact`` (``scenarios/exact_contact.py``, the model against exact contact mechanics on two
  surface families, about 90 min; needs tamaas), run only when named (``--only``) or with ``--all``.

The default (the first five) takes about 8-12 minutes; ``--all`` about 2.5 hours.  Not regenerated
here: the benchmark records (``speed.json``, ``memory.json``, ...: measurements of a machine,
rerun each benchmark and copy its file from ``outputs/``) and ``convergence_repeat.md`` (a second
run of the convergence study, kept as a record).

Run:   python3 studies/reference_results.py                 # the default tasks -> docs/results/
       python3 studies/reference_results.py --only paper    # one task (repeat --only for more)
       python3 studies/reference_results.py --all           # every task, the long studies included
       python3 studies/reference_results.py --quick         # every default task at smoke size (about
                                                            # 2 min) -> outputs/reference_results_quick/;
                                                            # docs/results/ is left alone
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS_RESULTS = ROOT / "docs" / "results"
WORK = ROOT / "outputs" / "reference_results"
QUICK_DEST = ROOT / "outputs" / "reference_results_quick"


@dataclass(frozen=True)
class Task:
    scripts: tuple  # script names (without .py), found in studies/ or scenarios/
    log: str  # console output of the scripts, written next to their files
    keep: tuple  # files copied to docs/results/ (the log included when listed)
    default: bool = True
    args: tuple = ()  # extra options of a full run


TASKS = {
    "paper": Task(("paper_figures",), "paper_figures.log", (
        "three_step_R1.nc", "three_step_S1.nc", "three_step.png",
        "normal_closure_R2.nc", "normal_closure_S2.nc", "normal_closure.png",
        "constant_normal_shear_R1.nc", "constant_normal_shear_S1.nc", "constant_normal_shear.png",
        "paper_figures.log")),
    "history": Task(("cyclic_shear", "rotating_shear", "history_vs_paper", "unload_reload_shear"),
                    "history_scenarios.log", ("cyclic_shear.png", "history_vs_paper.png", "history_scenarios.log")),
    "bem": Task(("bem_closure",), "bem_closure.log", ("bem_closure.nc", "bem_closure.png")),
    "joint": Task(("joint_properties",), "joint_properties.log", (
        "joint_properties.json", "joint_properties.png", "joint_envelope_R1_paper.png", "joint_cyclic_S1_mdr.png",
        *(f"joint_{kind}_{s}_{law}.csv" for kind in ("envelope", "cyclic") for s in ("R1", "S1")
          for law in ("paper", "mdr")))),
    "stability": Task(("stability",), "stability.log", ("stability.nc", "stability.md")),
    "convergence": Task(("convergence",), "convergence.log",
                        ("convergence.nc", "convergence.md", "convergence.png", "convergence.log"), default=False),
    "mdr_convergence": Task(("mdr_convergence",), "mdr_convergence.log",
                            ("mdr_convergence.nc", "mdr_convergence.md", "mdr_convergence.log"), default=False),
    "exact": Task(("exact_contact",), "exact_contact.log", ("exact_contact.nc", "exact_contact_normal.png",
                                                            "exact_contact_shear.png", "exact_contact.log"),
                  default=False),
}

# kept in docs/results/ but written by hand from a benchmark run or a repeated study, not by a task here
RECORDS = ("speed.json", "speed.log", "benchmark_kernel.json", "history_law.json", "history_law_k8.json",
           "history_law_scale.json", "history_law_baseline.json", "memory.json", "sweep_speedup.json", "sweep_auto.json",
           "mdr_k_convergence.json", "mdr_k_convergence.md", "convergence_repeat.md", "same_numbers.md",
           "same_numbers.json", "history_law_against_0.3.json", "cold_start.json", "whole_run.json",
           "same_numbers_first_run.md", "same_numbers_first_run.json", "cold_start_ed6517e.json",
           "same_numbers_threads.md", "same_numbers_threads.json", "same_numbers_reserve.md",
           "same_numbers_reserve.json", "whole_run_3c1d6f0.json", "same_numbers_stderr.md",
           "same_numbers_stderr.json", "cold_start_ahead.json", "same_numbers_ahead.md", "same_numbers_ahead.json",
           "whole_run_3a6b298.json", "cold_start_reference.json", "whole_run_against_5a9c208.json",
           "same_numbers_handoff.md", "same_numbers_handoff.json", "cold_start_8b35572.json",
           "whole_run_against_f609918.json", "same_numbers_borrowed.md", "same_numbers_borrowed.json",
           "whole_run_1b758b9.json", "cold_start_1b758b9.json", "cold_start_against_f609918.json",
           "whole_run_one_thread.json", "whole_run_against_89a13e8.json", "whole_run_d5d7191.json",
           "cold_start_891b0d2.json", "same_numbers_threads_awake.md", "same_numbers_threads_awake.json",
           "crowded_a53ef35.json", "whole_run_against_18b1b3a.json", "whole_run_f0044eb.json",
           "same_numbers_blocks.md", "same_numbers_blocks.json", "cold_start_f0044eb.json",
           "whole_run_against_acd6ca3.json", "whole_run_against_7d2a8ea.json",
           "whole_run_against_acd6ca3_7111d38.json", "cold_start_7111d38.json", "whole_run_798b67c.json",
           "whole_run_against_7d2a8ea_798b67c.json", "same_numbers_lists.md", "same_numbers_lists.json",
           "same_numbers_lists_exact.md", "same_numbers_lists_exact.json", "whole_run_against_059efc5.json",
           "whole_run_against_bfd2ea4.json", "whole_run_52ef0e9.json", "spring_rows.json", "same_numbers_calls.md",
           "same_numbers_calls.json",
           "same_numbers_calls_exact.md", "same_numbers_calls_exact.json", "whole_run_4893ca5.json",
           "whole_run_e4b0a47.json", "cold_start_c3671cb.json", "cold_start_c3671cb_2.json",
           "whole_run_907c481.json", "cold_start_cb5a3fa.json", "cold_start_cb5a3fa_2.json",
           "cold_start_1ecc267.json", "cold_start_dc5d572.json", "cold_start_against_46a8cec.json",
           "cold_start_against_46a8cec_mdr.json", "cold_start_against_1ecc267.json",
           "cold_start_against_1ecc267_paper.json", "same_numbers_inlining.md", "same_numbers_inlining.json",
           "whole_run_split_fd564ad.json", "whole_run_18a3582.json", "whole_run_against_f1d9e88.json",
           "same_numbers_geometry.md", "same_numbers_geometry.json", "same_numbers_geometry_exact.md",
           "same_numbers_geometry_exact.json", "whole_run_ec61720.json", "spring_gather.json",
           "whole_run_against_ec61720.json", "whole_run_55581aa.json", "cold_start_against_f1d9e88.json",
           "same_numbers_1cf19ed.md", "same_numbers_1cf19ed.json", "same_numbers_1cf19ed_exact.md",
           "same_numbers_1cf19ed_exact.json", "whole_run_734612d.json", "whole_run_split_734612d.json",
           "compiled_loop.json", "whole_run_b716641.json", "cold_start_b716641.json", "cold_start_28430ac.json",
           "same_numbers_compiled_loop.md", "same_numbers_compiled_loop.json", "same_numbers_compiled_loop_exact.md", "same_numbers_compiled_loop_exact.json")


def script_path(name: str) -> Path:
    """The script ``name``.py, in studies/ or scenarios/ (studies move from one to the other)."""
    for folder in ("studies", "scenarios"):
        path = ROOT / folder / f"{name}.py"
        if path.is_file():
            return path
    raise FileNotFoundError(f"no script {name}.py in studies/ or scenarios/")


def run_task(name: str, task: Task, workdir: Path, dest: Path, quick: bool) -> float:
    """Run the scripts of ``task`` into ``workdir``, write its log there, copy its kept files to ``dest``."""
    workdir.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
               MPLBACKEND="Agg")
    t0 = time.perf_counter()
    log = []
    for script in task.scripts:
        cmd = [sys.executable, str(script_path(script)), "--outdir", str(workdir)]
        cmd += ["--quick"] if quick else list(task.args)
        print(f"[{name}] {' '.join(Path(c).name if c.endswith('.py') else c for c in cmd[1:])}", flush=True)
        proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
        log.append(f"== {script}\n{proc.stdout}")
        if proc.returncode != 0:
            (workdir / task.log).write_text("".join(log) + proc.stderr)
            raise RuntimeError(f"{script}.py stopped with exit status {proc.returncode}:\n{proc.stderr[-3000:]}")
    (workdir / task.log).write_text("".join(log))
    missing = [f for f in task.keep if not (workdir / f).is_file()]
    if missing:
        raise RuntimeError(f"task {name} wrote no {', '.join(missing)} in {workdir}")
    dest.mkdir(parents=True, exist_ok=True)
    for f in task.keep:
        shutil.copy2(workdir / f, dest / f)
    seconds = time.perf_counter() - t0
    print(f"[{name}] {len(task.keep)} files -> {dest} ({seconds:.0f} s)", flush=True)
    return seconds


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", action="append", choices=tuple(TASKS), help="run this task (repeatable)")
    p.add_argument("--all", action="store_true", help="every task, the long studies included (about 2.5 hours)")
    p.add_argument("--quick", action="store_true",
                   help=f"smoke size, into {QUICK_DEST.relative_to(ROOT)}/ (docs/results/ is left alone)")
    p.add_argument("--dest", type=Path, default=None,
                   help="where the kept files go (default docs/results/, with --quick outputs/reference_results_quick/)")
    args = p.parse_args(argv)
    names = args.only or [n for n, t in TASKS.items() if args.all or t.default]
    dest = args.dest or (QUICK_DEST if args.quick else DOCS_RESULTS)
    work = WORK.with_name(WORK.name + "_quick") / "work" if args.quick else WORK
    t0 = time.perf_counter()
    for name in names:
        run_task(name, TASKS[name], work / name, dest, args.quick)
    print(f"{len(names)} task(s) done in {time.perf_counter() - t0:.0f} s; files in {dest}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
