"""Compiling a law's last-needed kernels ahead in a helper process (asperity_sim/kernels/ahead.py).

The helper compiles exactly the kernels a run calls (the run then loads them from the cache and
compiles none of them itself): a history law's commit kernels, the evaluation kernel of a law
without history; a first run with the helper gives the bits of the same run in the test process
(its kernels from the test process's own cache), a helper that
fails leaves the run to compile the kernels itself, and the helper starts once, at the first
compile of the run a driver announced.
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
import json, sys
import asperity_sim as asim
from asperity_sim import paths, presets
from asperity_sim.kernels.specialise import kernels
law = sys.argv[1]
ds = asim.simulate(presets.R1, paths.constant_normal_shear(300e6, 10e-6, increments=12), n=1500, seed=2, law=law)
compiled = sorted(name for name, k in kernels(law).items()
                  for cres in k.overloads.values() if "compiler_lock" in (cres.metadata or {}).get("timers", {}))
energy = ds.elastic_energy.values.tolist() if "elastic_energy" in ds else None
print(json.dumps({"stress": ds.stress.values.tolist(), "energy": energy, "compiled_here": compiled}))
"""


def _run(cache, compile_ahead, law="mdr"):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "NUMBA_NUM_THREADS": "2", ahead.ENV: compile_ahead,
           "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", RUN, law], env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def _here(law):
    """The run of RUN in this process (kernels compiled here or loaded from this process's cache)."""
    import asperity_sim as asim
    from asperity_sim import paths, presets

    return asim.simulate(presets.R1, paths.constant_normal_shear(300e6, 10e-6, increments=12), n=1500, seed=2, law=law)


@pytest.mark.slow  # a first run of mdr with an empty numba cache
@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="the helper needs a second core")
def test_a_first_run_loads_the_helpers_commit_kernels_and_gives_the_same_bits(tmp_path):
    helped = _run(tmp_path / "helped", "1")
    assert not set(ahead.COMMIT_KERNELS) & set(helped["compiled_here"])  # loaded: the helper compiled them
    assert {"fresh_pass", "slot_pass"} <= set(helped["compiled_here"])  # and the run its trial meanwhile
    here = _here("mdr")
    assert helped["stress"] == here.stress.values.tolist() and helped["energy"] == here.elastic_energy.values.tolist()


@pytest.mark.slow  # a first run of paper with an empty numba cache
@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="the helper needs a second core")
def test_a_first_paper_run_loads_the_helpers_evaluation_kernel_and_gives_the_same_bits(tmp_path):
    helped = _run(tmp_path / "helped", "1", law="paper")  # its cache is empty: every kernel compiles or loads
    assert "reduce_serial" not in helped["compiled_here"]  # loaded: the helper compiled it
    assert helped["stress"] == _here("paper").stress.values.tolist()  # the bits of a run whose kernels are ours


MEANWHILE = """
import sys
import numpy as np
from asperity_sim import presets
from asperity_sim.kernels import ahead, evaluate as ev
from asperity_sim.sampling.population import Population
p = presets.R1
pop = Population.from_arrays(p, [0.0, 0.1 * p.beta], [p.R_m] * 2, [0.3, 0.6], [0.0, 1.0])
assert ahead.start("paper", False, helper="asperity_sim.no_such_module", serial=True)
def stop(dispatcher):  # the run would now wait for the helper: what it compiled meanwhile is in the cache
    sys.exit(0)
ev.wait_for = stop
ev.evaluate(pop, np.array([p.beta, 0.0, 0.0]))
sys.exit(1)
"""

HELPER = """
import json
from numba.core import event
from asperity_sim.kernels import ahead_helper
compiled = []
class Listener(event.Listener):
    def on_start(self, ev):
        compiled.append(ev.data["dispatcher"].py_func.__qualname__.split("__")[0])
    def on_end(self, ev):
        pass
event.register("numba:compile", Listener())
ahead_helper.main(["paper", "follow", "serial"])
print(json.dumps(compiled))
"""


@pytest.mark.slow  # a helper's compile of the serial evaluation kernel (its loop) in an empty numba cache
def test_the_run_compiles_the_serial_kernels_other_callees_while_it_waits_and_the_helper_loads_them(tmp_path):
    """A first run that would wait for the helper's serial kernel compiles the kernel's other callees (bounds,
    finish) meanwhile, with the argument types the kernel gives them: the helper then loads them from the cache,
    and compiles only the loop (which it compiles first, once) and the kernel."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "PYTHONPATH": str(ROOT), ahead.ENV: "0"}
    run = subprocess.run([sys.executable, "-c", MEANWHILE], env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    helper = subprocess.run([sys.executable, "-c", HELPER], env=env, capture_output=True, text=True, timeout=600)
    assert helper.returncode == 0, helper.stderr
    compiled = json.loads(helper.stdout.strip().splitlines()[-1])
    assert compiled.count("chunk_follow") == 1 and "reduce_serial" in compiled
    assert "bounds" not in compiled and "finish" not in compiled


def test_wait_for_returns_at_once_for_a_kernel_no_helper_compiles():
    ahead.wait_for(kernels("mdr")["commit_slots"])  # nothing pending in this process: no wait, no error


def test_a_helper_that_fails_releases_its_kernels():
    """A helper that cannot run exits at once; waiting for its kernels returns and forgets them."""
    assert ahead.start("mdr", True, helper="asperity_sim.no_such_module")
    commit_fresh = kernels("mdr", birth=True)["commit_fresh"]
    assert commit_fresh.py_func.__qualname__ in ahead.pending()
    ahead.wait_for(commit_fresh)
    assert not ahead.pending()


def test_a_law_without_history_gets_a_helper_for_its_evaluation_kernel_under_policy_follow_only():
    assert {"paper", "mdr"} <= ahead.BUILT_IN
    assert not ahead.start("paper", True)  # policy birth: none
    assert not ahead.pending()
    for serial in (True, False):
        assert ahead.start("paper", False, helper="asperity_sim.no_such_module", serial=serial)
        kern = kernels("paper")[ahead.evaluation_kernel(serial)]
        assert ahead.pending() == {kern.py_func.__qualname__}
        ahead.wait_for(kern)
        assert not ahead.pending()


def test_the_announced_imports_are_made_while_waiting_on_a_helper_and_only_then(monkeypatch):
    """A run's later imports (its output's) are made as it would wait on the helper, once; no wait, no import."""
    monkeypatch.setattr(ahead, "_IDLE", [])
    monkeypatch.delitem(sys.modules, "colorsys", raising=False)  # a small standard module, imported by no test
    ahead.expect("mdr", True, imports=("colorsys",))
    ahead.expect(None)  # the end of the set-up keeps them for the run's first wait
    commit_fresh = kernels("mdr", birth=True)["commit_fresh"]
    ahead.wait_for(commit_fresh)  # nothing pending: no wait, so nothing imported
    assert "colorsys" not in sys.modules
    assert ahead.start("mdr", True, helper="asperity_sim.no_such_module")
    ahead.wait_for(commit_fresh)
    assert "colorsys" in sys.modules and ahead._IDLE == []


def test_a_run_announces_the_imports_of_its_output(monkeypatch):
    from asperity_sim import paths, presets, simulate
    from asperity_sim.output.recorder import LATE_IMPORTS

    seen = []
    real = ahead.expect
    monkeypatch.setattr(ahead, "expect", lambda *a, **k: (seen.append(k.get("imports")), real(*a, **k)))
    simulate(presets.R1, paths.constant_normal_shear(300e6, 1e-6, increments=2), n=200, seed=1)
    assert seen[0] == LATE_IMPORTS and "xarray" in LATE_IMPORTS


class _Event:
    def __init__(self, dispatcher):
        self.data = {"dispatcher": dispatcher}


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="the helper needs a second core")
def test_the_helper_of_an_announced_run_starts_once_at_the_first_compile_of_any_package_kernel(monkeypatch):
    from asperity_sim.kernels.reach import bounds

    monkeypatch.setenv(ahead.ENV, "1")
    started = []
    monkeypatch.setattr(ahead, "start", lambda law, birth, serial=True: started.append((law, birth, serial)))
    monkeypatch.setattr(ahead, "_EXPECTED", [])
    listener = ahead._FirstCompile()
    ahead.expect("paper", False, False)  # more asperities than the serial kernel takes
    listener.on_start(_Event(bounds))  # a shared kernel (sampling, bounds) is the first compile
    listener.on_start(_Event(bounds))
    assert started == [("paper", False, False)]
    # a run whose first compile is the helper's own kernel compiles it itself: no helper
    started.clear()
    listener = ahead._FirstCompile()
    ahead.expect("paper", False, True)
    listener.on_start(_Event(kernels("paper")["reduce_serial"]))
    assert started == []


@pytest.mark.parametrize("mode", ["serial", "parallel"])
def test_the_helper_says_the_evaluation_kernel_it_compiled(mode, capsys):
    from asperity_sim import laws
    from asperity_sim.kernels import ahead_helper

    assert ahead_helper.main(["paper", "follow", mode]) == 0
    said = capsys.readouterr().out.split()
    assert said == ahead.kernel_names(laws.get("paper"), False, mode == "serial")
    kern = kernels("paper")[ahead.evaluation_kernel(mode == "serial")]
    assert kern.signatures  # the helper's evaluation went through the kernel it names
    assert len(kernels("paper")["chunk_follow"].signatures) == 1  # its loop, called first, with the kernel's types


def test_a_run_announces_itself_only_while_it_is_set_up(monkeypatch):
    from asperity_sim import paths, presets, simulate

    seen = []
    real = ahead.expect
    monkeypatch.setattr(ahead, "expect", lambda *a, **k: (seen.append(a[0]), real(*a, **k)))
    simulate(presets.R1, paths.constant_normal_shear(300e6, 1e-6, increments=2), n=200, seed=1)
    assert seen == ["paper", None]
    assert ahead._EXPECTED == []  # a kernel compiled after the set-up starts no helper for it
