"""The increments of a stage compiled whole (asperity_sim.solve.span) give the bits of the Python loop.

Each case runs ``simulate`` twice on one population, once with the compiled span and once with the
Python loop alone (``can_span`` patched to refuse), and compares every output variable and attribute
but the wall time.  The cases reach every way out of the compiled loop: the stage's end, an increment
left to the Python loop (a cut-back, a solution at the resolution of Delta), displacement control
without a Newton solve, stress control of a shear component, adaptive increments, and a population
on the serial kernel.
"""

import os
import subprocess
import sys

import numpy as np
import pytest

from asperity_sim import Population, paths, presets, resume, simulate
from asperity_sim.solve import run as run_module
from asperity_sim.solve import span as span_module
from asperity_sim.threads import SPIN_ENV

S, D = paths.STRESS, paths.DISPLACEMENT


def _both(monkeypatch, pop, path, law="paper", **kw):
    monkeypatch.setattr(span_module, "MODE", "always")
    spans = []
    real = span_module.span

    def counting(*args):
        m, status = real(*args)
        spans.append(m)
        return m, status

    monkeypatch.setattr(run_module, "span", counting)
    kw = {"law": law, **({"k": 8} if law == "mdr" else {}), **kw}
    compiled = simulate(pop.params, path, population=pop, **kw)
    monkeypatch.setattr(run_module, "can_span", lambda *a: False)
    python = simulate(pop.params, path, population=pop, **kw)
    return compiled, python, sum(spans)


def _same(a, b):
    assert set(a.data_vars) == set(b.data_vars)
    for name in a.data_vars:
        assert np.array_equal(a[name].values, b[name].values), name
    skip = {"wall_time_increment_loop_s", "history", "date_created"}
    assert {k: str(v) for k, v in a.attrs.items() if k not in skip} == \
        {k: str(v) for k, v in b.attrs.items() if k not in skip}


CASES = {
    "constant normal stress": lambda: paths.constant_normal_shear(500e6, 30e-6, increments=30),
    "normal then shear": lambda: paths.LoadPath((paths.Stage((S, D, D), (300e6, 0, 0), 10),
                                                 paths.Stage((S, D, D), (300e6, 10e-6, 0), 20))),
    "shear stress control": lambda: paths.LoadPath((paths.Stage((D, D, D), (2e-6, 0, 0), 5),
                                                    paths.Stage((D, S, D), (2e-6, 5e6, 0), 20))),
    "displacement only": lambda: paths.three_step(3e-6, increments=8),
    "adaptive": lambda: paths.LoadPath((paths.Stage((S, D, D), (200e6, 0, 0), 10, adaptive=True,
                                                    max_fraction=0.3),
                                        paths.Stage((S, D, D), (200e6, 20e-6, 0), 10, adaptive=True,
                                                    max_fraction=0.2))),
}


@pytest.mark.parametrize("law", ["paper", "mdr"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_span_gives_the_bits_of_the_python_loop(monkeypatch, case, law):
    pop = Population.sample(presets.R1, 40_000, seed=3)
    compiled, python, spanned = _both(monkeypatch, pop, CASES[case](), law)
    _same(compiled, python)
    assert spanned > 0  # the compiled span did run increments


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_span_on_a_small_population(monkeypatch, law):
    pop = Population.sample(presets.R1, 3_000, seed=4)
    compiled, python, spanned = _both(monkeypatch, pop, CASES["constant normal stress"](), law)
    _same(compiled, python)
    assert spanned > 0


def test_span_of_a_history_law_through_unloading_and_reversal(monkeypatch):
    """Contacts lost and born again, springs reversed: every kind of commit (mdr)."""
    pop = Population.sample(presets.R1, 30_000, seed=8)
    path = paths.LoadPath((paths.Stage((S, D, D), (300e6, 0, 0), 8), paths.Stage((S, D, D), (300e6, 8e-6, 0), 12),
                           paths.Stage((S, D, D), (300e6, -8e-6, 0), 16), paths.Stage((S, D, D), (20e6, -8e-6, 0), 8),
                           paths.Stage((S, D, D), (300e6, -8e-6, 4e-6), 8)))
    compiled, python, spanned = _both(monkeypatch, pop, path, "mdr")
    _same(compiled, python)
    assert spanned > 0


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_span_leaves_hard_increments_to_python(monkeypatch, law):
    """A stress target reached from no contact (bracket search) and a tiny stress on a stiff interface (solutions at
    the resolution of Delta): the Python loop takes up what the span leaves, with the same bits."""
    pop = Population.sample(presets.R1, 20_000, seed=5)
    path = paths.LoadPath((paths.Stage((S, D, D), (1.0, 0, 0), 6), paths.Stage((S, D, D), (1.0, 1e-9, 0), 6)))
    compiled, python, _ = _both(monkeypatch, pop, path, law)
    _same(compiled, python)


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_span_stops_for_snapshots_checkpoints_and_progress(monkeypatch, tmp_path, law):
    """Snapshots, checkpoints and the progress callback see the same steps, states and calls from both loops."""
    pop = Population.sample(presets.R1, 30_000, seed=9)
    path = CASES["constant normal stress"]()
    seen = {}

    def run(label, **kw):
        calls = seen.setdefault(label, [])
        return simulate(pop.params, path, population=pop, law=law, snapshots=[5, 33], progress=lambda *a: calls.append(a),
                        checkpoint=tmp_path / f"{label}.ckpt", checkpoint_every=7, **kw)

    monkeypatch.setattr(span_module, "MODE", "always")
    compiled = run("compiled")
    monkeypatch.setattr(run_module, "can_span", lambda *a: False)
    python = run("python")
    _same(compiled, python)
    assert seen["compiled"] == seen["python"] and len(seen["python"]) == 60
    assert compiled.sizes.get("snapshot", 0) == 2  # both snapshots taken (compared with the rest above)
    _same(resume(tmp_path / "compiled.ckpt"), resume(tmp_path / "python.ckpt"))  # the last checkpoints hold the same


def test_span_refuses_what_it_does_not_cover():
    pop = Population.sample(presets.R1, 3_000, seed=6)
    path = paths.constant_normal_shear(100e6, 5e-6, increments=4)
    two = paths.LoadPath((paths.Stage((S, S, D), (100e6, 1e6, 0), 4),))
    params = pop.params
    cases = [(path, {"law": "paper", "policy": "birth"}), (path, {"law": "mdr", "policy": "birth"}),
             (two, {"law": "paper"}), (path, {"law": "mdr", "max_wall_time": 1e3})]
    for path_, kw in cases:
        seen = []
        real = run_module.can_span

        def spy(run, *a):
            ok = real(run, *a)
            seen.append(ok)
            return ok

        run_module.can_span = spy
        try:
            simulate(params, path_, population=pop, **kw)
        finally:
            run_module.can_span = real
        assert seen and not any(seen), kw


ON_TWO_THREADS = """
import numpy as np
from asperity_sim import Population, paths, presets, simulate
from asperity_sim.solve import run as run_module, span
assert span.SPIN_US > 0
pop = Population.sample(presets.R1, 60_000, seed=11)
path = paths.LoadPath((paths.Stage(("s", "d", "d"), (300e6, 0, 0), 8), paths.Stage(("s", "d", "d"), (300e6, 8e-6, 0), 12),
                       paths.Stage(("s", "d", "d"), (300e6, -4e-6, 0), 12)))
real, done = run_module.span, []


def counting(*args):
    m, stage_done = real(*args)
    done.append(m)
    return m, stage_done


run_module.span = counting
for law in ("paper", "mdr"):
    span.MODE = "always"
    compiled = simulate(pop.params, path, population=pop, law=law, k=8)
    span.MODE = "never"
    python = simulate(pop.params, path, population=pop, law=law, k=8)
    assert all(np.array_equal(compiled[v].values, python[v].values) for v in compiled.data_vars), law
assert sum(done) > 0
print("same bits")
"""


@pytest.mark.slow  # a process of its own: two threads that poll (the suite's worker processes run the span alone)
def test_span_on_two_threads_gives_the_bits_of_the_python_loop():
    """The threads that serve the span's parallel parts (posts, claims, waits) give the same bits as the Python
    loop, on two threads with the default polling (tests/conftest.py turns polling off in the suite's workers, and
    the span then runs on the calling thread alone)."""
    env = {k: v for k, v in os.environ.items() if k != SPIN_ENV} | {"NUMBA_NUM_THREADS": "2"}
    run = subprocess.run([sys.executable, "-c", ON_TWO_THREADS], env=env, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    assert run.stdout.strip().endswith("same bits")
