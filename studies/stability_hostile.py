"""The stability study's hostile inputs: unwritable outputs, bad seeds, damaged and forged checkpoints.

Owns the table :data:`HOSTILE` run by ``studies/stability.py`` (its quick subset by
``tests/test_stability.py``): output paths that cannot be written, seeds the output cannot
store, damaged and forged checkpoints (made with ``damaged_checkpoints.py``), a checkpoint of
another run, a kill during a checkpoint write.  Each states its expected outcome: the name of
the exception that must refuse it before any work, or ``same bits`` (:data:`SAME`: the run
resumes bit-identically to an uninterrupted one).  Each case runs in a fresh folder
(:func:`run_hostile`), in the worker process of ``stability_worker.py`` unless asked otherwise.

A study module beside ``studies/stability.py`` (moved out of ``asperity_sim.stability`` in
0.4), importing its siblings by name.  The kill probe starts a child Python (``-c``) that
imports this module: it is given this folder and the package's on ``PYTHONPATH``.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from damaged_checkpoints import arrays_of, flip_bit, member_data_offset, same_run, write_checkpoint
from stability_cases import LAWS
from stability_worker import Worker

HERE = os.path.dirname(os.path.abspath(__file__))  # studies/: the kill probe's child imports this module from here

SAME = "same bits"  # the run resumes bit-identically to an uninterrupted one
SKIPPED = "skipped"


@dataclass(frozen=True)
class Hostile:
    """One hostile input: what is done (:data:`PROBES`), with which law, and what it must end with."""

    name: str
    probe: str                      # key of PROBES
    law: str = "paper"
    expected: str = "ValueError"    # exception class name, or SAME
    quick: bool = True              # part of the tests' fast subset
    note: str = ""


def _tiny_path():
    from asperity_sim.paths import LoadPath, Stage

    S, D = "s", "d"
    return LoadPath((Stage((S, D, D), (300e6, 0, 0), 3, name="normal"),
                     Stage((S, D, D), (300e6, 4e-6, 0), 3, name="shear"),
                     Stage((S, D, D), (300e6, -2e-6, 1e-6), 4, adaptive=True, max_fraction=0.5, name="reverse")),
                    name="tiny")


def _run_kw(law):
    return dict(n=200, seed=4, law=law, k=4, snapshots=[0, 4])


class _Stop(Exception):
    pass


def _stop_at(step_to_stop):
    def progress(stage, n_stages, fraction, step, iterations):
        if step == step_to_stop:
            raise _Stop(step)
    return progress


_BASE = {}


def base_run(law, folder):
    """(checkpoint bytes at step 5, uninterrupted dataset) of a tiny S1 run (n = 200), cached per process."""
    import asperity_sim as asim

    if law not in _BASE:
        ck = Path(folder) / f"base-{law}.npz"
        try:
            asim.simulate(asim.presets.S1, _tiny_path(), checkpoint=ck, checkpoint_every=1, progress=_stop_at(5),
                          **_run_kw(law))
        except _Stop:
            pass
        _BASE[law] = (ck.read_bytes(), asim.simulate(asim.presets.S1, _tiny_path(), **_run_kw(law)))
        ck.unlink()
    return _BASE[law]


def _tiny(folder, **kw):
    """A tiny run whose progress callback fails the probe if any increment is computed."""
    import asperity_sim as asim

    def no_work(*args):
        raise AssertionError("an increment was computed before the input was refused")

    return asim.simulate(asim.presets.S1, _tiny_path(), **{**_run_kw("paper"), "progress": no_work, **kw})


def _resumed(law, folder, path, **kw):
    """SAME if resuming ``path`` gives the uninterrupted run's bits, else what differs."""
    import asperity_sim as asim

    ds = asim.resume(path, checkpoint_every=None, **kw)
    return SAME if same_run(base_run(law, folder)[1], ds) else "resumed to different bits"


def _forged(law, folder, change):
    """Resume a copy of the base checkpoint with arrays rewritten by ``change(arrays)`` (valid checksums)."""
    raw, _ = base_run(law, folder)
    arrays = arrays_of(raw)
    path = write_checkpoint(folder / "forged.npz", arrays, change(arrays))
    return _resumed(law, folder, path)


def _with_nan(a, index=0):
    a = a.astype(np.float64 if a.dtype.kind != "f" else a.dtype, copy=True)
    a.flat[index] = np.nan
    return a


def probe_output_folder(law, folder):
    (folder / "a folder.nc").mkdir()
    return _tiny(folder, output=folder / "a folder.nc", law=law)


def probe_output_under_file(law, folder):
    (folder / "plain").write_text("a file")
    return _tiny(folder, output=folder / "plain" / "out.nc", law=law)


def probe_output_unwritable(law, folder):
    ro = folder / "read-only"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        if os.access(ro, os.W_OK):  # root (or a file system without permissions) writes anyway
            return SKIPPED, "the folder stays writable for this user (running as root): nothing to refuse"
        return _tiny(folder, output=ro / "out.nc", law=law)
    finally:
        ro.chmod(0o755)


def probe_output_is_checkpoint(law, folder):
    return _tiny(folder, output=folder / "same.npz", checkpoint=folder / "same.npz", law=law)


def probe_resume_output_is_checkpoint(law, folder):
    import asperity_sim as asim

    raw, _ = base_run(law, folder)
    ck = folder / "ck.npz"
    ck.write_bytes(raw)
    asim.resume(ck, output=ck)
    return "resumed over its own checkpoint"


def probe_existing_output(law, folder):
    """``asperity-sim run`` onto an existing file without ``--overwrite``: exit 1, the file untouched."""
    from asperity_sim.ui import cli

    scene = folder / "small.toml"
    scene.write_text(f'title = "hostile"\n[parameters]\npreset = "S1"\n[run]\nn = 200\nseed = 3\nlaw = "{law}"\n'
                     '[[path.stages]]\nincrements = 2\nDelta_1 = "2 um"\nDelta_2 = "0 um"\nDelta_3 = "0 um"\n')
    out = folder / "existing.nc"
    out.write_bytes(b"an earlier result")
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = cli.main(["run", str(scene), "-o", str(out), "--quiet"])
    kept = out.read_bytes() == b"an earlier result"
    return f"exit {code}, file {'unchanged' if kept else 'overwritten'}", err.getvalue().strip()


def probe_seed_huge(law, folder):
    return _tiny(folder, seed=2**63, law=law)


def probe_seed_negative(law, folder):
    return _tiny(folder, seed=-1, law=law)


def probe_truncated(law, folder):
    raw, _ = base_run(law, folder)
    path = folder / "truncated.npz"
    path.write_bytes(raw[: len(raw) // 2])
    return _resumed(law, folder, path)


def probe_bit_flip(law, folder):
    raw, _ = base_run(law, folder)
    path = folder / "flipped.npz"
    path.write_bytes(flip_bit(raw, member_data_offset(raw, "pop_R.npy") + 200, 3))  # inside the radii: bad CRC
    return _resumed(law, folder, path)


def probe_intact(law, folder):
    raw, _ = base_run(law, folder)
    path = folder / "intact.npz"
    path.write_bytes(raw)
    return _resumed(law, folder, path)


def probe_nan_state(law, folder):
    def change(a):
        if "state_law0" in a:  # history law: a spring of the first contact
            return {"state_law0": _with_nan(a["state_law0"])}
        return {"state_delta_c": _with_nan(a["state_delta_c"])}  # path-independent law: the committed Delta
    return _forged(law, folder, change)


def probe_unsorted_heights(law, folder):
    return _forged(law, folder, lambda a: {"pop_r": a["pop_r"][::-1].copy()})


def probe_slot_index(law, folder):
    def change(a):
        if "state_asp" in a:  # history law: a slot pointing past the last asperity
            asp = a["state_asp"].copy()
            asp[0] = a["pop_r"].size
            return {"state_asp": asp}
        return {"pos_i": np.array([99, 1], dtype=np.int64)}  # path-independent law: a stage index past the path
    return _forged(law, folder, change)


def probe_other_law(law, folder):
    import asperity_sim as asim

    raw, _ = base_run(law, folder)
    ck = folder / "ck.npz"
    ck.write_bytes(raw)
    other = next(name for name in LAWS if name != law)
    asim.simulate(asim.presets.S1, _tiny_path(), resume=ck, **{**_run_kw(law), "law": other})
    return "resumed under another law"


def probe_other_path(law, folder):
    import asperity_sim as asim
    from asperity_sim import paths

    raw, _ = base_run(law, folder)
    ck = folder / "ck.npz"
    ck.write_bytes(raw)
    asim.simulate(asim.presets.S1, paths.three_step(10e-6, increments=3), resume=ck, **_run_kw(law))
    return "resumed on another path"


KILLED_WRITER = """
import os, signal, sys
import asperity_sim as asim
from asperity_sim.output import checkpoint
from stability_hostile import _run_kw, _tiny_path
real, calls = os.replace, []
def replace(src, dst):
    calls.append(src)
    if len(calls) == 3:
        os.kill(os.getpid(), signal.SIGKILL)  # the third checkpoint is written in full, then killed before its rename
    real(src, dst)
checkpoint.os.replace = replace
asim.simulate(asim.presets.S1, _tiny_path(), checkpoint=sys.argv[1], checkpoint_every=1, **_run_kw(sys.argv[2]))
"""


def probe_killed_write(law, folder):
    """SIGKILL between a checkpoint's write and its rename: the next run removes the stale temporary and resumes."""
    import asperity_sim

    ck = folder / "killed.npz"
    package_root = os.path.dirname(os.path.dirname(asperity_sim.__file__))  # the child imports this same package
    env = {**os.environ,
           "PYTHONPATH": os.pathsep.join(filter(None, [package_root, HERE, os.environ.get("PYTHONPATH")]))}
    child = subprocess.run([sys.executable, "-c", KILLED_WRITER, str(ck), law], capture_output=True, text=True,
                           timeout=300, env=env)
    if child.returncode != -signal.SIGKILL:
        return f"the writer was not killed (exit {child.returncode})", child.stderr[-400:]
    stale = [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]
    if not stale:
        return "no temporary was left by the kill (nothing tested)", ""
    outcome = _resumed(law, folder, ck)
    left = [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]
    if left:
        return f"{outcome}, but temporaries remain: {left}", ""
    return outcome, (f"the kill left {len(stale)} temporary file (.{ck.name}.<pid>.<random>.tmp) next to the intact "
                     "checkpoint; the resumed run removed it and finished")


PROBES = {name.removeprefix("probe_"): f for name, f in dict(globals()).items() if name.startswith("probe_")}

HOSTILE = (
    Hostile("output is an existing folder", "output_folder", note="refused before any work"),
    Hostile("output under a regular file", "output_under_file"),
    Hostile("output in a folder without write permission", "output_unwritable",
            note="skipped where the user can write anyway (root)"),
    Hostile("output equal to the checkpoint", "output_is_checkpoint"),
    Hostile("resume with output equal to its checkpoint", "resume_output_is_checkpoint"),
    Hostile("existing output without --overwrite (asperity-sim run)", "existing_output",
            expected="exit 1, file unchanged"),
    Hostile("seed = 2^63", "seed_huge", note="the output stores a signed 64-bit seed"),
    Hostile("seed = -1", "seed_negative"),
    *(h for law, first in zip(LAWS, (True, False)) for h in (
        Hostile("intact checkpoint (control)", "intact", law, SAME),
        Hostile("checkpoint truncated to half", "truncated", law, "CheckpointError"),
        Hostile("checkpoint with a flipped bit (CRC-32 fails)", "bit_flip", law, "CheckpointError"),
        Hostile("forged: NaN in the committed state, valid checksum", "nan_state", law, "CheckpointError"),
        Hostile("forged: heights unsorted, valid checksum", "unsorted_heights", law, "CheckpointError"),
        Hostile("forged: index out of range, valid checksum", "slot_index", law, "CheckpointError",
                note="mdr: a contact slot naming asperity n; paper: stage index 99"),
        Hostile("resume under another law", "other_law", law, "CheckpointError", quick=first),
        Hostile("resume on another load path", "other_path", law, "CheckpointError", quick=first),
        Hostile("killed during a checkpoint write, then resumed", "killed_write", law, SAME, quick=False,
                note="SIGKILL between the write and the rename of the third checkpoint"),
    )),
)


def run_hostile(case, folder=None):
    """Run one hostile case in a fresh folder; its record (case, law, expected, outcome, message, wall time)."""
    rec = {"case": case.name, "law": case.law, "expected": case.expected, "outcome": "", "message": "",
           "wall_time_s": 0.0}
    folder = Path(tempfile.mkdtemp(prefix="hostile-", dir=folder))
    t0 = time.perf_counter()
    try:
        base_run(case.law, folder)  # not timed as part of the case
        t0 = time.perf_counter()
        result = PROBES[case.probe](case.law, folder)
        rec["outcome"], rec["message"] = result if isinstance(result, tuple) else (result, "")
        if not isinstance(rec["outcome"], str):  # a probe that returned a dataset: the input was accepted
            rec["outcome"], rec["message"] = "complete", "the input was accepted and the run completed"
    except Exception as err:  # noqa: BLE001 - the outcome is the exception's name
        rec["outcome"], rec["message"] = type(err).__name__, str(err)
        if isinstance(err, AssertionError):
            rec["message"] += " | " + traceback.format_exc(limit=3)
    finally:
        rec["wall_time_s"] = time.perf_counter() - t0
        shutil.rmtree(folder, ignore_errors=True)
    rec["message"] = rec["message"].replace(str(folder), "<folder>")  # the same text on every run
    return rec


def hostile_verdict(rec):
    """'pass' (the expected outcome, with a message if refused), 'skipped' (with why), or 'FAIL: ...'."""
    if rec["outcome"] == SKIPPED:
        return "skipped" if rec["message"] else "FAIL: skipped without a reason"
    if rec["outcome"] != rec["expected"]:
        return f"FAIL: {rec['outcome']}"
    if rec["expected"].endswith("Error") and not rec["message"]:
        return "FAIL: no message"
    if rec["expected"] == "CheckpointError" and "checkpoint '" not in rec["message"]:
        return "FAIL: the message does not name the file"
    return "pass"


def select_hostile(quick=False, only=None):
    return [h for h in HOSTILE if (h.quick or not quick)
            and (not only or any(s.lower() in h.name.lower() for s in only))]


def run_hostile_table(cases, hard_limit, in_process=False, log=print):
    records = []
    worker = None if in_process else Worker()
    try:
        for i, case in enumerate(cases, 1):
            t0 = time.perf_counter()
            rec = run_hostile(case) if in_process else worker.run((run_hostile, case), hard_limit)
            if "case" not in rec:  # killed at the hard limit, or died
                rec = {"case": case.name, "law": case.law, "expected": case.expected, **rec,
                       "wall_time_s": time.perf_counter() - t0}
            rec["verdict"] = hostile_verdict(rec)
            records.append(rec)
            log(f"[{i:3d}/{len(cases)}] {case.name:58s} {case.law:5s} {rec['outcome']:24s} {rec['verdict']:8s} "
                f"{rec['wall_time_s']:6.2f} s")
    finally:
        if worker is not None:
            worker.close()
    return records

