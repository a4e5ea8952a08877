"""Compiling a history law's commit kernels ahead in a helper process (asperity_sim/kernels/ahead.py).

The helper compiles exactly the kernels a run calls (the run then loads them from the cache and
compiles none of them itself), a first run with the helper gives the bits of one without it, and
a helper that fails leaves the run to compile the kernels itself.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numba
import pytest

from asperity_sim.kernels import ahead
from asperity_sim.kernels.specialise import kernels

ROOT = Path(__file__).resolve().parent.parent

RUN = """
import json
import asperity_sim as asim
from asperity_sim import paths, presets
from asperity_sim.kernels.specialise import kernels
ds = asim.simulate(presets.R1, paths.constant_normal_shear(300e6, 10e-6, increments=12), n=1500, seed=2, law="mdr")
compiled = sorted(name for name, k in kernels("mdr").items()
                  for cres in k.overloads.values() if "compiler_lock" in (cres.metadata or {}).get("timers", {}))
print(json.dumps({"stress": ds.stress.values.tolist(), "energy": ds.elastic_energy.values.tolist(),
                  "compiled_here": compiled}))
"""


def _run(cache, compile_ahead):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "NUMBA_NUM_THREADS": "2", ahead.ENV: compile_ahead,
           "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", RUN], env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # two first runs of mdr, each with an empty numba cache
@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="the helper needs a second core")
def test_a_first_run_loads_the_helpers_commit_kernels_and_gives_the_same_bits(tmp_path):
    alone = _run(tmp_path / "alone", "0")
    helped = _run(tmp_path / "helped", "1")
    assert helped["stress"] == alone["stress"] and helped["energy"] == alone["energy"]
    assert set(ahead.COMMIT_KERNELS) <= set(alone["compiled_here"])  # without a helper the run compiles them
    assert not set(ahead.COMMIT_KERNELS) & set(helped["compiled_here"])  # with one it loads them
    assert {"fresh_pass", "slot_pass"} <= set(helped["compiled_here"])  # and compiles its trial meanwhile


def test_wait_for_returns_at_once_for_a_kernel_no_helper_compiles():
    ahead.wait_for(kernels("mdr")["commit_slots"])  # nothing pending in this process: no wait, no error


def test_a_helper_that_fails_releases_its_kernels():
    """A helper that cannot run exits at once; waiting for its kernels returns and forgets them."""
    assert ahead.start("mdr", True, helper="asperity_sim.no_such_module")
    commit_fresh = kernels("mdr", birth=True)["commit_fresh"]
    assert commit_fresh.py_func.__qualname__ in ahead.pending()
    ahead.wait_for(commit_fresh)
    assert not ahead.pending()


def test_only_the_laws_a_fresh_process_knows_and_that_commit_get_a_helper():
    assert {"paper", "mdr"} <= ahead.BUILT_IN
    assert not ahead.start("paper", False)  # no history: nothing to commit
    assert not ahead.pending()
