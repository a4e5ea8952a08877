"""Numerical stability on stiff and extreme cases (issue 6, items 1-2).

The fast part of the stability study (``studies/stability.py --quick``, cases in
``studies/stability_cases.py`` and ``studies/stability_hostile.py``, imported by name through
``support.study``) runs here at tiny size: every run either completes or stops with
the expected named exception, and no output is NaN or inf; every hostile input of the quick
subset (unwritable outputs, bad seeds, damaged and forged checkpoints) is refused by the named
exception or resumes to the same bits.  Around it, the solver behaviours the matrix relies on, each with a closed
form or an exact symmetry:

* e = 0, mu = 0: contacts are frictionless and normal to the plane (SPEC §3, §5), so
  sigma_2 = sigma_3 = 0 at every Delta.  Prescribed shear displacements must run (the
  singular shear tangent is never inverted); a prescribed non-zero shear stress must stop
  at once with a StressNotReachableError that says so.
* Scaling: stress is proportional to N G/(1 - nu) at fixed displacements (Eqs. 16-23), so
  the same path with sigma_n scaled by the same factor must take the same Newton iterations
  and reach the same displacements, from G = 1e6 to 1e13 Pa and N = 1 to 1e12 m-2.
* Stress above the strength: with e = 0, sigma_2 <= mu sigma_1 (SPEC §5); a larger
  prescribed sigma_2 stops with StressNotReachableError, also when two components are
  stress controlled.
* Floating-point resolution: at 1 Pa on a stiff interface the load is carried by overlaps
  of 1e-11 m at Delta ~ 1e-6 m, where one ulp of Delta moves sigma_1 by more than rtol; the
  run must complete (residual recorded) instead of failing on a collapsed bracket.
"""

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support import study

import asperity_sim as asim
from asperity_sim import paths, Population, presets, simulate, SolverSettings, StressNotReachableError
from asperity_sim.paths import LoadPath, Stage
from asperity_sim.solve.solver import SolveResult

STUDY = Path(__file__).resolve().parent.parent / "studies" / "stability.py"
matrix = study("stability_cases")  # the study's modules (studies/), imported by name as the script imports them
hostile = study("stability_hostile")


def all_finite(ds):
    return not matrix.nonfinite_outputs(ds)


# --------------------------------------------------------------------------- the fast matrix


@pytest.mark.slow
def test_fast_stability_matrix_passes():
    runs = matrix.select_runs(quick=True, big=False)
    assert len(runs) >= 150
    records = matrix.run_matrix(runs, n=300, seed=7, inc=2, soft_limit=60.0, hard_limit=120.0, in_process=True,
                                log=lambda *a: None)
    cap = SolverSettings().max_iter * 3 + SolverSettings().max_expansions
    bad = [(r["case"], r["path"], r["law"], matrix.verdict(r, cap), r["message"][:200]) for r in records
           if matrix.verdict(r, cap) != "pass"]
    assert not bad, bad
    assert sum(r["outcome"] == "complete" for r in records) >= 0.8 * len(records)
    assert max(r["wall_time_s"] for r in records) < 30.0


def test_cases_that_turn_over_every_contact_pass_at_the_matrix_size():
    """Cyclic shear where nearly every contact is lost or born in one increment, at the matrix's n = 2000 (where the
    history law's slot arrays are reserved for every asperity, not grown): until 2026-11-28 these stopped with
    'cannot resize this array' (the fast matrix above, at n = 300, has ordinary arrays that grow)."""
    cases = {c.name: c for c in matrix.CASES}
    for name in ("sigma_n at theta_m=pi/2", "soft: G=1e6, N=1, sigma_n=1 Pa"):
        rec = matrix.run_one(cases[name], "cyclic", "mdr", 2000, 7, 6, 60.0)
        assert rec["outcome"] == "complete", (name, rec["message"][:300])
        assert rec["steps"] > 0 and not rec["nonfinite"]


def test_matrix_covers_the_issue_cases():
    names = " | ".join(c.name for c in matrix.CASES)
    for word in ("e=0", "theta_m=pi/2", "alpha=-0.999", "alpha=1e4", "R_sigma=0", "R_sigma=R_m", "mu=0", "mu=10",
                 "nu=0", "nu=0.5", "nu=-0.9", "G=1e6", "G=1e13", "N=1", "N=1e12", "n=1", "n=1e7", "sigma_n=1 Pa",
                 "sigma_n at theta_m=pi/2", "zero load", "above strength", "b=-1, c=0.5", "b=2"):
        assert word in names, word
    kinds = {k for c in matrix.CASES for k in c.paths}
    assert {"three_step", "cns", "cyclic", "zero_load", "above_strength"} <= kinds
    assert any(len(c.changes) >= 2 for c in matrix.CASES)  # combined cases


def test_theta_m_case_really_reaches_pi_over_2():
    case = next(c for c in matrix.CASES if c.name == "theta_m=pi/2")
    p = matrix.params_of(case)
    d = matrix.closure_scale(p)
    assert p.k_e * (p.r_o + d) / p.R_bounds[1] > 1.0  # cos theta_m clipped for every radius sampled


def test_verdict_flags_what_the_issue_forbids():
    ok = {"outcome": "complete", "expected": "complete", "message": "", "nonfinite": "", "iter_max": 5}
    assert matrix.verdict(ok, 100) == "pass"
    assert matrix.verdict({**ok, "nonfinite": "stress"}, 100).startswith("FAIL")
    assert matrix.verdict({**ok, "outcome": "ConvergenceError", "message": "why"}, 100).startswith("FAIL")
    assert matrix.verdict({**ok, "iter_max": 101}, 100).startswith("FAIL")
    named = {**ok, "outcome": "StressNotReachableError", "expected": "StressNotReachableError"}
    assert matrix.verdict({**named, "message": "sigma_2 cannot be reached"}, 100) == "pass"
    assert matrix.verdict(named, 100).startswith("FAIL")  # a failure must say why


def run_study(*argv):
    """The study as a program, importing this checkout's package (not an installed one)."""
    root = str(STUDY.parent.parent)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}
    return subprocess.run([sys.executable, str(STUDY), *argv], capture_output=True, text=True, timeout=600, env=env)


@pytest.mark.parametrize("argv, word", [
    (["--soft-limit", "0"], "soft-limit"), (["--hard-limit", "-1"], "hard-limit"),
    # rejected only after the study has imported the package (~1 s)
    pytest.param(["--only", "no such case"], "selects no case", marks=pytest.mark.slow), (["--n", "0"], "--n = 0")])
def test_study_rejects_bad_options(argv, word, tmp_path):
    done = run_study(*argv, "--outdir", str(tmp_path))
    assert done.returncode == 2, done.stderr
    assert word in done.stderr
    assert not list(tmp_path.iterdir())  # nothing ran, nothing written


def test_study_says_what_it_measures_takes_and_writes():
    doc = STUDY.read_text().split('"""')[1]
    for words in ("What it measures", "Takes:", "minute", "Writes outputs/stability.nc", "hostile"):
        assert words in doc, words


@pytest.mark.slow
def test_study_writes_netcdf_and_markdown(tmp_path):
    """The study as a program, its runs in worker processes as by default: the spawned worker imports the
    study's modules (studies/stability_cases.py, stability_hostile.py) from the script's folder."""
    done = run_study("--quick", "--n", "200", "--increments", "2", "--only", "mu=0", "--only", "forged",
                     "--outdir", str(tmp_path))
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    from asperity_sim.output.netcdf import read_netcdf

    ds = read_netcdf(tmp_path / "stability.nc")
    assert ds.sizes["run"] >= 10 and ds.sizes["hostile"] == 6
    assert set(ds["verdict"].values) == {"pass"} and set(ds["hostile_verdict"].values) == {"pass"}
    for name in ("iter_max", "iter_mean", "residual_final", "wall_time_s", "hostile_wall_time_s"):
        assert ds[name].attrs["long_name"] and np.all(np.isfinite(ds[name].values))
    md = (tmp_path / "stability.md").read_text()
    assert md.count("\n| ") > ds.sizes["run"] + ds.sizes["hostile"] and "NaN/inf" in md and "Hostile inputs" in md
    assert "wrote" in done.stdout


# --------------------------------------------------------------------------- hostile inputs and checkpoints


def test_quick_hostile_inputs_end_as_expected(tmp_path):
    selected = hostile.select_hostile(quick=True)
    assert len(selected) >= 18
    records = hostile.run_hostile_table(selected, hard_limit=120.0, in_process=True, log=lambda *a: None)
    bad = [(r["case"], r["law"], r["outcome"], r["verdict"], r["message"][:300]) for r in records
           if r["verdict"] not in ("pass", "skipped")]
    assert not bad, bad
    skipped = [r for r in records if r["verdict"] == "skipped"]
    assert all(r["case"].startswith("output in a folder without write permission") for r in skipped), skipped
    assert sum(r["outcome"] == "CheckpointError" for r in records) >= 10
    assert sum(r["outcome"] == hostile.SAME for r in records) == 2  # the intact controls of both laws


def test_hostile_table_covers_the_issue_cases():
    names = " | ".join(h.name for h in hostile.HOSTILE)
    for words in ("existing folder", "under a regular file", "without write permission", "equal to the checkpoint",
                  "without --overwrite", "2^63", "seed = -1", "truncated", "flipped bit", "NaN", "unsorted",
                  "out of range", "another law", "another load path", "killed during a checkpoint write"):
        assert words in names, words
    assert {h.law for h in hostile.HOSTILE if "checkpoint" in h.name} == {"paper", "mdr"}


def test_hostile_verdict_flags_what_the_issue_forbids():
    ok = {"outcome": "CheckpointError", "expected": "CheckpointError", "message": "checkpoint '/x.npz' is damaged"}
    assert hostile.hostile_verdict(ok) == "pass"
    assert hostile.hostile_verdict({**ok, "message": "damaged"}).startswith("FAIL")  # names no file
    assert hostile.hostile_verdict({**ok, "outcome": "KeyError"}).startswith("FAIL")
    assert hostile.hostile_verdict({**ok, "outcome": "complete"}).startswith("FAIL")
    assert hostile.hostile_verdict({**ok, "outcome": "skipped", "message": ""}).startswith("FAIL")  # say why
    assert hostile.hostile_verdict({**ok, "outcome": "skipped", "message": "root"}) == "skipped"
    same = {"outcome": "same bits", "expected": "same bits", "message": ""}
    assert hostile.hostile_verdict(same) == "pass"
    assert hostile.hostile_verdict({**same, "outcome": "resumed to different bits"}).startswith("FAIL")


@pytest.mark.slow
def test_kill_during_a_checkpoint_write_is_cleaned_up_and_resumes_to_the_same_bits():
    for law in ("paper", "mdr"):
        case = next(h for h in hostile.HOSTILE if h.probe == "killed_write" and h.law == law)
        rec = hostile.run_hostile(case)
        assert rec["outcome"] == hostile.SAME and hostile.hostile_verdict(rec) == "pass", rec
        assert ".tmp" in rec["message"] and "removed" in rec["message"]


@pytest.mark.slow
def test_hard_time_limit_kills_a_run_and_the_matrix_goes_on():
    huge = matrix.Case("huge", n=50_000_000, paths=("three_step",), laws=("paper",))
    small = matrix.Case("small", paths=("three_step",), laws=("paper",))
    # the small case first in this process, so that its kernels are in numba's cache: the worker that runs it
    # after the kill must not compile them within the 4 s limit (the tests run in parallel, in any order)
    assert matrix.run_one(small, "three_step", "paper", 200, 1, 1, 60.0)["outcome"] == "complete"
    records = matrix.run_matrix([(huge, "three_step", "paper"), (small, "three_step", "paper")], n=200, seed=1,
                                inc=1, soft_limit=60.0, hard_limit=4.0, log=lambda *a: None)
    assert records[0]["outcome"] == "HardTimeLimit" and "killed" in records[0]["message"]
    assert records[1]["outcome"] == "complete"


# --------------------------------------------------------------------------- mu = 0: singular shear tangent


FLAT_FRICTIONLESS = presets.R1.replace(e=0.0, mu=0.0)


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_mu0_e0_prescribed_shear_displacement_runs(law):
    ds = simulate(FLAT_FRICTIONLESS, paths.constant_normal_shear(200e6, 20e-6, increments=3, normal_increments=3),
                  n=500, seed=1, law=law)
    assert ds.attrs["status"] == "complete" and all_finite(ds)
    assert np.all(ds.stress.values[:, 1:] == 0.0)  # no shear stress at all (SPEC §3, §5)
    st = ds.stage.values == 2
    np.testing.assert_allclose(ds.stress.values[st, 0], 200e6, rtol=1e-9)
    # the closure does not change under shear: nothing couples it (theta = 0, no friction)
    assert np.ptp(ds.displacement.values[st, 0]) <= 1e-12 * ds.displacement.values[-1, 0]
    assert np.all(ds.tangent.values[:, 1:, 1:] == 0.0)  # the singular block the solver must not invert


@pytest.mark.parametrize("law", ["paper", "mdr"])
@pytest.mark.parametrize("control", [("s", "s", "d"), ("d", "s", "d"), ("s", "d", "s")])
def test_mu0_e0_prescribed_shear_stress_fails_at_once_and_says_why(law, control):
    k = control.index("s", 1)
    target = [200e6 if control[0] == "s" else 10e-6, 0.0, 0.0]
    target[k] = 1e6
    path = LoadPath((Stage(("s", "d", "d"), (200e6, 0, 0), 2, name="normal"),
                     Stage(control, tuple(target), 2, name="shear by stress")))
    calls = []
    with pytest.raises(StressNotReachableError) as exc:
        simulate(FLAT_FRICTIONLESS, path, n=400, seed=1, law=law, progress=lambda *a: calls.append(a))
    msg = str(exc.value)
    assert f"sigma_{k + 1} = 1e+06 Pa" in msg and "mu = 0 and e = 0" in msg and "no shear stress" in msg
    assert len(calls) == 2  # stopped before the first increment of the shear stage
    ds = exc.value.dataset
    assert ds.sizes["step"] == 3 and all_finite(ds)
    assert ds.attrs["status"].startswith("failed: StressNotReachableError")


def test_mu0_e0_zero_shear_stress_target_is_met_by_symmetry():
    path = LoadPath((Stage(("s", "s", "s"), (200e6, 0.0, 0.0), 3),))
    ds = simulate(FLAT_FRICTIONLESS, path, n=400, seed=2)
    assert ds.attrs["status"] == "complete" and all_finite(ds)
    np.testing.assert_allclose(ds.stress.values[1:, 0], np.arange(1, 4) / 3 * 200e6, rtol=1e-9)


def test_mu0_with_inclined_contacts_carries_shear_up_to_a_strength():
    """mu = 0, e = 1: inclined frictionless contacts still resist shear (their normal forces
    lean), so a small shear stress is reachable and a large one is not."""
    p = presets.R1.replace(mu=0.0)
    pop = Population.sample(p, 1500, seed=3)
    ok = LoadPath((Stage(("s", "d", "d"), (200e6, 0, 0), 3), Stage(("s", "s", "d"), (200e6, 5e6, 0), 3)))
    ds = simulate(p, ok, population=pop)
    assert ds.attrs["status"] == "complete" and all_finite(ds)
    assert ds.stress.values[-1, 1] == pytest.approx(5e6, rel=1e-9)
    too_much = LoadPath((Stage(("s", "d", "d"), (200e6, 0, 0), 3), Stage(("s", "s", "d"), (200e6, 400e6, 0), 3)))
    with pytest.raises(StressNotReachableError, match="sigma_2"):
        simulate(p, too_much, population=pop)


# --------------------------------------------------------------------------- shear stress above the strength


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_shear_stress_above_flat_strength_with_two_stress_controls(law):
    """e = 0: sigma_2 <= mu sigma_1 (SPEC §5).  sigma_1 held by stress, sigma_2 ramped to 3 mu sigma_1: the
    run must stop with StressNotReachableError (a ConvergenceError before issue 6), keeping the increments
    that converged, every one of them below the strength."""
    p = presets.R1.replace(e=0.0)
    path = LoadPath((Stage(("s", "d", "d"), (100e6, 0, 0), 2), Stage(("s", "s", "d"), (100e6, 300e6, 0), 3)))
    with pytest.raises(StressNotReachableError) as exc:
        simulate(p, path, n=800, seed=4, law=law)
    ds = exc.value.dataset
    assert all_finite(ds)
    s = ds.stress.values
    assert np.all(s[:, 1] <= p.mu * s[:, 0] * (1 + 1e-9))
    assert "sigma_2" in str(exc.value) and "cannot be reached" in str(exc.value)


# --------------------------------------------------------------------------- scaling of stresses and displacements


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_solver_is_invariant_to_the_stress_scale(law):
    """sigma is proportional to N G (Eqs. 16-23): scaling N G by F and sigma_n by F gives the same displacements
    and the same Newton iterations, from 1 Pa to 1e12 Pa of normal stress."""
    base = presets.S1
    out = {}
    for N, G in ((1.0, 1e6), (200e6, 80e9), (1e12, 1e13)):
        p = base.replace(N=N, G=G)
        F = (N * G) / (base.N * base.G)
        path = paths.constant_normal_shear(300e6 * F, 3e-6, increments=3, normal_increments=3)
        out[(N, G)] = simulate(p, path, n=600, seed=8, law=law)
    ref = out[(200e6, 80e9)]
    for key, ds in out.items():
        assert ds.attrs["status"] == "complete" and all_finite(ds), key
        np.testing.assert_array_equal(ds.iterations.values, ref.iterations.values)
        np.testing.assert_allclose(ds.displacement.values, ref.displacement.values, rtol=1e-8, atol=1e-16)
    assert out[(1.0, 1e6)].stress.values[-1, 0] == pytest.approx(300e6 * 1e6 / (200e6 * 80e9), rel=1e-9)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_solver_is_invariant_to_the_length_scale(scale):
    """Heights, radii and displacements all scaled by s: forces scale by s² (Hertz: sqrt(R) dn^1.5), so with
    N / s² the stresses are unchanged and the solved displacements scale by s (displacements from 1e-9 to 1e-3 m)."""
    base = presets.S1
    p = base.replace(beta=base.beta * scale, R_m=base.R_m * scale, R_sigma=base.R_sigma * scale,
                     N=base.N / scale ** 2)
    path = paths.constant_normal_shear(300e6, 3e-6 * scale, increments=3, normal_increments=3)
    ds = simulate(p, path, n=600, seed=8)
    ref = simulate(base, paths.constant_normal_shear(300e6, 3e-6, increments=3, normal_increments=3), n=600, seed=8)
    assert ds.attrs["status"] == "complete" and all_finite(ds)
    np.testing.assert_allclose(ds.displacement.values, ref.displacement.values * scale, rtol=1e-8,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(ds.stress.values, ref.stress.values, rtol=1e-8, atol=1e-6)
    assert np.all(np.abs(ds.iterations.values - ref.iterations.values) <= 1)


# --------------------------------------------------------------------------- floating-point resolution


def test_one_pascal_on_a_stiff_interface_converges_at_the_resolution_of_delta():
    """G = 1e13 Pa, sigma_1 = 1 Pa, law mdr: before issue 6 this stopped with 'bracket collapsed'."""
    p = presets.R1.replace(G=1e13)
    path = paths.constant_normal_shear(1.0, 31.4e-6, increments=6, normal_increments=3)
    ds = simulate(p, path, n=2000, seed=2024, law="mdr")
    assert ds.attrs["status"] == "complete" and all_finite(ds)
    s = SolverSettings()
    assert np.all(ds.residual.values <= s.resolution_rtol)
    at_resolution = int((ds.residual.values > s.rtol).sum())
    assert at_resolution > 0 and ds.attrs["increments_at_resolution"] == at_resolution  # counted, not silent
    assert ds.n_contact.values[-1] <= 3  # a handful of contacts carry 1 Pa
    np.testing.assert_allclose(ds.stress.values[1:, 0][ds.stage.values[1:] == 2], 1.0, rtol=s.resolution_rtol)


class Quantised:
    """sigma_1(Delta_1) = T (Delta_1 - x0) plus a sawtooth of amplitude A over 8 ulps of Delta_1: a stress
    that is only defined to A between neighbouring floating-point values of Delta_1 (what a contact
    overlap of 1e-11 m at Delta_1 ~ 2e-6 m gives), with no exact root."""

    def __init__(self, x0=2.3e-6, T=1e11, A=3e-8):
        self.x0, self.T, self.A, self.calls = x0, T, A, 0

    def __call__(self, delta):
        from asperity_sim.kernels.evaluate import Evaluation

        self.calls += 1
        x = float(delta[0])
        saw = ((x / np.spacing(x)) % 8.0 - 3.5) / 3.5 if x > 0 else 0.0
        s1 = self.T * (x - self.x0) + self.A * saw
        z = np.zeros((3, 3))
        tangent = z.copy()
        tangent[0, 0] = self.T
        return Evaluation(delta=np.array(delta, float), stress=np.array([s1, 0.0, 0.0]), stderr=np.zeros(3),
                          covariance=z, tangent=tangent, n_contact=1, n_slip=0, n_partial=0, mean_theta=0.0,
                          n_active=1)


def test_quantised_stress_converges_at_the_resolution_of_delta():
    from asperity_sim.solve.solver import solve_increment

    f = Quantised()
    free, target = np.array([True, False, False]), np.array([1.0, 0.0, 0.0])
    res = solve_increment(f, np.array([2.0e-6, 0, 0]), free, target, 25e-6)
    assert res.converged and "floating-point resolution" in res.message
    assert SolverSettings().rtol < res.residual <= SolverSettings().resolution_rtol
    assert res.iterations <= 60 and f.calls <= 200
    # the solution is pinned to within a few ulps of the root of the smooth part
    root = f.x0 + 1.0 / f.T
    assert abs(res.evaluation.delta[0] - root) <= 2e4 * np.spacing(root)


def test_quantised_stress_fails_by_name_when_resolution_is_not_accepted():
    from asperity_sim.solve.solver import solve_increment

    f = Quantised()
    free, target = np.array([True, False, False]), np.array([1.0, 0.0, 0.0])
    strict = SolverSettings(resolution_rtol=1e-10)
    res = solve_increment(f, np.array([2.0e-6, 0, 0]), free, target, 25e-6, strict)
    assert not res.converged and not res.unreachable
    assert "floating-point values of Delta_1" in res.message and "ulps" in res.message
    # several stress-controlled components: the same acceptance through the least-squares Newton
    both = np.array([True, False, True])
    res2 = solve_increment(f, np.array([2.0e-6, 0, 0]), both, target, 25e-6)
    assert res2.converged and res2.residual <= SolverSettings().resolution_rtol


# --------------------------------------------------------------------------- n = 1, wall time, adaptive stall


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_one_asperity_reports_zero_stderr_with_a_flag(law):
    ds = simulate(presets.R1, paths.constant_normal_shear(1e6, 10e-6, increments=2, normal_increments=2), n=1,
                  seed=3, law=law)
    assert ds.attrs["status"] == "complete" and all_finite(ds)
    assert ds.attrs["stderr_defined"] == 0 and "undefined" in ds.attrs["stderr_note"]
    assert np.all(ds.stress_stderr.values == 0.0) and np.all(ds.displacement_stderr.values == 0.0)
    two = simulate(presets.R1, paths.three_step(30e-6, increments=1), n=2, seed=3)
    assert two.attrs["stderr_defined"] == 1 and "stderr_note" not in two.attrs


def test_wall_time_limit_stops_with_a_named_error_and_keeps_results(tmp_path):
    out = tmp_path / "w.nc"
    with pytest.raises(asim.WallTimeExceededError) as exc:
        simulate(presets.R1, paths.three_step(15e-6, increments=5), n=500, max_wall_time=1e-9, output=out)
    assert "max_wall_time" in str(exc.value)
    assert exc.value.dataset.sizes["step"] >= 1 and out.exists()
    assert exc.value.dataset.attrs["status"].startswith("failed: WallTimeExceededError")


def test_adaptive_stage_never_shrinks_below_the_smallest_increment(monkeypatch):
    """An adaptive stage whose increments all converge slowly (> 8 iterations) halves its increment each time;
    it must stop halving at the smallest increment, so the stage ends in a bounded number of steps."""
    import asperity_sim.solve.run as drv

    def slow_but_converged(evaluate, guess, free, target, L, settings):
        return SolveResult(True, 20, 0.0, 0.5, "converged", evaluate(guess))

    monkeypatch.setattr(drv, "solve_increment", slow_but_converged)
    path = LoadPath((Stage(("d", "d", "d"), (10e-6, 0, 0), 1, adaptive=True, max_fraction=1.0),))
    ds = simulate(presets.R1, path, n=100, settings=SolverSettings(max_cutbacks=4))
    assert ds.attrs["status"] == "complete"
    assert ds.sizes["step"] - 1 <= 2 ** 4 + 2
    assert ds.displacement.values[-1, 0] == 10e-6


# --------------------------------------------------------------------------- extremes that must stay finite


@pytest.mark.parametrize("changes", [
    {"alpha": -1.0 + 1e-9}, {"alpha": 1e6, "beta": 25e-12}, {"R_sigma": 50e-6, "R_m": 50e-6},
    {"nu": -0.999}, {"nu": 0.5, "mu": 100.0}, {"r_o": 1.0}, {"e": 1e-12}, {"b": -1.0, "d": 0.5},
    {"N": 1e-6}, {"G": 1e-3}, {"G": 1e20, "N": 1e15},
])
@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_extreme_parameters_run_or_stop_by_name_without_nan(changes, law):
    p = presets.R1.replace(**changes)
    d = matrix.closure_scale(p)
    sn = matrix.normal_stress(p, matrix.Case("x"), d)
    for kind in ("three_step", "cyclic"):
        path = matrix.build_path(kind, p, d, sn, 2)
        try:
            ds = simulate(p, path, n=300, seed=5, law=law, max_wall_time=30.0)
        except asim.SimulationError as err:
            ds = err.dataset
            assert str(err)
        assert all_finite(ds), (changes, kind, matrix.nonfinite_outputs(ds))
        assert math.isfinite(float(ds.stress.values.max()))


# --------------------------------------------------------------------------- mdr at mu = 0 (fix in laws/mdr.py)


def test_mdr_frictionless_contact_has_no_tangential_stiffness():
    """mu = 0: the Coulomb limit of every spring is 0, so the tangential force is 0 for every
    displacement and so is its derivative.  Before issue 6 the law took a zero tangential increment
    for 'stick' and reported a tangential stiffness q a > 0 (e.g. under pure normal loading),
    inconsistent with its own (zero) force: a spurious stiffness that hides the singular shear
    tangent from the solver.  Checked against finite differences of the force."""
    path = np.array([[1e-6, 0, 0], [2e-6, 0, 0], [2e-6, 1e-7, 0], [1.5e-6, -1e-7, 2e-8]])
    ds = asim.single_contact(path, R=1e-4, G=80e9, nu=0.3, mu=0.0, law="mdr", k=8)
    assert np.all(ds.force.values[:, 1:] == 0.0)
    assert np.all(ds.tangent.values[:, 1:, :] == 0.0)
    assert np.all(ds.dissipation.values == 0.0)
    assert np.all(ds.state.values == 3)  # frictionless contacts always slide
    paper = asim.single_contact(path, R=1e-4, G=80e9, nu=0.3, mu=0.0, law="paper")
    np.testing.assert_array_equal(ds.tangent.values[:, 1:, :], paper.tangent.values[:, 1:, :])
