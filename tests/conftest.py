"""Shared test fixtures.  Scripts under scenarios/ and studies/ are run as programs (``run_script``);
a test that needs a study's own code (its cases, its bookkeeping) imports that module by name
through ``support.study`` (tests/support.py), the one way tests reach studies/."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

if "PYTEST_XDIST_WORKER" in os.environ:
    # The suite runs in two worker processes (pyproject.toml: -n 2) on a 2-core machine.  An idle thread
    # of the package polls for work for a while before it sleeps (asperity_sim.threads); here it would poll
    # on the core the other process needs, so the workers' threads sleep at once (set before the package
    # is imported; the scripts the tests start inherit it).  The polling itself is tested in a process of
    # its own (tests/test_threads.py).
    os.environ.setdefault("ASPERITY_SIM_SPIN_US", "0")


@pytest.fixture
def run_script(tmp_path):
    """``run_script("scenarios/x.py", "--quick", ...)``: run a script of the repository as a program.

    It runs in a fresh Python process in ``tmp_path`` with this checkout's package first on the
    path, and returns the ``subprocess.CompletedProcess`` (text stdout and stderr captured).
    """
    def run(script, *args, timeout=900):
        path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
        return subprocess.run([sys.executable, str(ROOT / script), *(str(a) for a in args)], cwd=tmp_path,
                              env={**os.environ, "PYTHONPATH": path}, capture_output=True, text=True,
                              timeout=timeout)

    return run
