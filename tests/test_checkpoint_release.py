"""The checkpoint version guard against a real release: a checkpoint resumed by another version.

A checkpoint is written by this code; then a release is made the way a release makes it, by
editing the sources of a copy of the package (``__version__`` in ``asperity_sim/version.py``,
and for a release that changes the file layout also ``FORMAT`` in ``asperity_sim/output/checkpoint.py``),
and the copy is asked, in its own Python process, to resume the checkpoint through the Python
API and through the command line.  The policy (docs/robustness.md): only the version that wrote a
checkpoint resumes it, also across a patch release, and the refusal names both versions.
The control: the unchanged package resumes the same file to the bits of an uninterrupted run.
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import asperity_sim as asim
from asperity_sim.output import checkpoint as ckpt
from asperity_sim import presets, simulate
from asperity_sim.ui import cli, exits
from asperity_sim.output.netcdf import read_netcdf
from asperity_sim.paths import LoadPath, Stage

PACKAGE = Path(asim.__file__).resolve().parent
RUN = dict(n=400, seed=2, law="paper")


def _path():
    S, D = "s", "d"
    return LoadPath((Stage((S, D, D), (200e6, 0, 0), 3, name="normal"),
                     Stage((S, D, D), (200e6, 3e-6, 0), 3, name="shear")), name="release")


class _Stop(Exception):
    pass


def _stop_at(step_to_stop):
    def progress(stage, n_stages, fraction, step, iterations):
        if step == step_to_stop:
            raise _Stop
    return progress


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """A checkpoint of this version after 4 of 6 increments, and the uninterrupted run."""
    folder = tmp_path_factory.mktemp("release")
    ck = folder / "run.npz"
    with pytest.raises(_Stop):
        simulate(presets.S1, _path(), checkpoint=ck, checkpoint_every=1, progress=_stop_at(5), **RUN)
    assert ckpt.load(ck, asim.__version__)[0]["version"] == asim.__version__
    return ck, simulate(presets.S1, _path(), **RUN)


def _bump(version, part):
    major, minor, patch = (int(v) for v in re.match(r"^(\d+)\.(\d+)\.(\d+)", version).groups())
    return {"patch": f"{major}.{minor}.{patch + 1}", "minor": f"{major}.{minor + 1}.0"}[part]


def _released(tmp_path, version, new_format=None):
    """A copy of the package with its sources edited as a release edits them."""
    root = tmp_path / "released"
    shutil.copytree(PACKAGE, root / "asperity_sim", ignore=shutil.ignore_patterns("__pycache__"))
    home = root / "asperity_sim" / "version.py"
    text, count = re.subn(r'^__version__ = "[^"]*"$', f'__version__ = "{version}"', home.read_text(), flags=re.M)
    assert count == 1
    home.write_text(text)
    if new_format is not None:
        module = root / "asperity_sim" / "output" / "checkpoint.py"
        text, count = re.subn(r"^FORMAT = \d+$", f"FORMAT = {new_format}", module.read_text(), flags=re.M)
        assert count == 1
        module.write_text(text)
    return root


def _in(root, *args):
    """Run Python with the released copy first on the path (the copy, not this worktree, is imported)."""
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=300, cwd=root,
                          env={**os.environ, "PYTHONPATH": str(root), "NUMBA_NUM_THREADS": "1"})


@pytest.mark.slow  # two fresh Python processes per release
@pytest.mark.parametrize("part, format_change", [("patch", False), ("minor", True)],
                         ids=["patch release", "minor release with a new checkpoint format"])
def test_another_release_refuses_the_checkpoint_naming_both_versions(written, tmp_path, part, format_change):
    ck, _ = written
    old, new = asim.__version__, _bump(asim.__version__, part)
    new_format = ckpt.FORMAT + 1 if format_change else None
    root = _released(tmp_path, new, new_format)
    api = _in(root, "-c", "import sys, asperity_sim as a\n"
                          "print(a.__file__, a.__version__, a.checkpoint.FORMAT)\n"
                          "try:\n"
                          f"    a.resume({str(ck)!r})\n"
                          "except a.CheckpointError as err:\n"
                          "    print('refused:', err)\n"
                          "    sys.exit(0)\n"
                          "sys.exit('resumed')")
    assert api.returncode == 0, api.stdout + api.stderr
    where, version, fmt = api.stdout.splitlines()[0].split()
    assert where == str(root / "asperity_sim" / "__init__.py") and version == new  # the release was imported
    assert int(fmt) == (new_format or ckpt.FORMAT)
    refusal = api.stdout.splitlines()[1]
    assert f"written by asperity_sim {old!r}" in refusal and f"{new!r}" in refusal
    if format_change:
        assert f"has format {ckpt.FORMAT}" in refusal and f"reads format {new_format} only" in refusal
    command = _in(root, "-m", "asperity_sim", "run", "--resume", str(ck), "-o", str(tmp_path / "out.nc"))
    assert command.returncode == exits.EXIT_INPUT, command.stderr
    line = command.stderr.strip()
    assert "\n" not in line and line.startswith("asperity-sim: error: ")
    assert f"written by asperity_sim {old!r}" in line and f"{new!r}" in line
    assert not (tmp_path / "out.nc").exists()


def test_the_version_that_wrote_the_checkpoint_resumes_it(written, tmp_path):
    ck, full = written
    out = tmp_path / "resumed.nc"
    assert cli.main(["run", "--resume", str(ck), "-o", str(out)]) == 0
    resumed = read_netcdf(out)
    for name in ("stress", "displacement", "stress_stderr", "iterations"):
        assert np.array_equal(resumed[name].values, full[name].values), name
