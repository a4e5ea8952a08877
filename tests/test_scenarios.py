"""Every scenario runs at tiny size as a program (``python scenarios/x.py --quick``), so none can silently rot."""

import numpy as np
import pytest
import xarray as xr

CASES = {
    "three_step": ["three_step_R1.nc", "three_step_S1.nc", "three_step.png"],
    "normal_closure": ["normal_closure_R2.nc", "normal_closure_S2.nc", "normal_closure.png"],
    "constant_normal_shear": ["constant_normal_shear_R1.nc", "constant_normal_shear_S1.nc",
                              "constant_normal_shear.png"],
    "cyclic_shear": ["cyclic_shear_R1.nc", "cyclic_shear_S1.nc", "cyclic_shear.png"],
    "rotating_shear": ["rotating_shear_mdr_R1.nc", "rotating_shear_paper_S1.nc", "rotating_shear.png"],
    "history_vs_paper": ["history_vs_paper_mdr_R1.nc", "history_vs_paper_paper_S1.nc", "history_vs_paper.png"],
    "unload_reload_shear": ["unload_reload_shear_mdr_S1.nc", "unload_reload_shear_paper_R1.nc",
                            "unload_reload_shear.png"],
}
WITH_REFERENCE = {"three_step", "normal_closure", "constant_normal_shear"}


@pytest.mark.slow
@pytest.mark.parametrize("name", CASES)
def test_scenario_runs_and_writes_its_outputs(name, tmp_path, run_script):
    done = run_script(f"scenarios/{name}.py", "--quick", "--n", "800", "--outdir", tmp_path)
    assert done.returncode == 0, done.stderr
    assert "wrote" in done.stdout
    for f in CASES[name]:
        assert (tmp_path / f).stat().st_size > 0
    for f in CASES[name]:
        if f.endswith(".nc"):
            ds = xr.open_dataset(tmp_path / f, engine="netcdf4")
            assert ds.attrs["status"] == "complete"
            names = ("stress", "displacement_stderr") + (("reference_stress",) if name in WITH_REFERENCE else ())
            for var in names:
                assert np.all(np.isfinite(ds[var].values))
            if ds.attrs["law"] == "mdr":
                bal = ds.external_work - ds.elastic_energy - ds.dissipation
                assert float(np.abs(bal).max()) <= 1e-9 * float(np.abs(ds.external_work).max())
            ds.close()


K = 5.0  # standard errors allowed between a Monte Carlo value and the quadrature (development.md: k = 3 to 6)


@pytest.mark.slow
@pytest.mark.statistical
def test_main_job_paper_figures_writes_complete_runs_that_match_the_quadrature(tmp_path, run_script):
    """The README's main job, ``python3 scenarios/paper_figures.py``, as a program at a small size (its options
    are passed on to the three scenarios: ``--quick`` = 4 increments per stage and the fast quadrature, n = 2000).

    Its nine files are written, every run is complete at the size asked for, with finite stresses, and every
    Monte Carlo stress (and, under stress control, every solved displacement) lies within K standard errors
    of the quadrature reference of the same path (Eq. 23, paper law, policy follow)."""
    n, out = 2000, tmp_path / "outputs"
    done = run_script("scenarios/paper_figures.py", "--quick", "--n", n, "--outdir", out)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("wrote ") == 3 and "all scenarios done" in done.stdout
    files = [f for name in ("three_step", "normal_closure", "constant_normal_shear") for f in CASES[name]]
    assert sorted(p.name for p in out.iterdir()) == sorted(files)
    for f in files:
        assert (out / f).stat().st_size > 0, f
    compared = {"stress": 0, "displacement": 0}
    for f in (f for f in files if f.endswith(".nc")):
        with xr.open_dataset(out / f, engine="netcdf4") as ds:
            assert ds.attrs["status"] == "complete" and ds.attrs["law"] == "paper", f
            assert int(ds.attrs["n_asperities"]) == n, f
            for var in ("stress", "stress_stderr", "displacement", "reference_stress", "reference_displacement"):
                assert np.all(np.isfinite(ds[var].values)), (f, var)
            for var in compared:
                value, ref, se = (ds[v].values for v in (var, f"reference_{var}", f"{var}_stderr"))
                has_se = se > 0.0  # zero at zero load and for a prescribed (displacement-controlled) component
                z = np.abs(value[has_se] - ref[has_se]) / se[has_se]
                assert np.all(z < K), (f, var, float(z.max()))
                compared[var] += int(has_se.sum())
    # not vacuous: every stress of every loaded step, and the closures solved under stress control
    assert compared["stress"] >= 100 and compared["displacement"] >= 20, compared


@pytest.mark.slow  # a fresh Python process that imports the package
def test_scenario_rejects_bad_options(run_script):
    done = run_script("scenarios/three_step.py", "--n", "0")
    assert done.returncode == 2  # argparse's usage error
    assert "--n = 0" in done.stderr and "Traceback" not in done.stderr


def _reference_one_step_after_the_other(ds, params, level):
    """The reference of ``scenarios/_common.add_reference`` written plainly: each step in turn, each displacement
    integrated anew whenever Brent's method or the bracket asks for it."""
    from scipy import optimize

    from asperity_sim import reference

    disp, sig = ds["displacement"].values, ds["stress"].values
    control = ds["control"].values.astype(bool)
    ref_s, ref_d = np.empty_like(sig), disp.copy()
    for i in range(disp.shape[0]):
        d = disp[i].copy()
        free = np.flatnonzero(control[i])
        if free.size == 1 and sig[i, free[0]] != 0.0:
            k, target = int(free[0]), sig[i, free[0]]

            def resid(x):
                dd = d.copy()
                dd[k] = x
                return reference.stress(params, dd, level=level)[k] - target

            width = max(abs(d[k]) * 0.05, params.beta)
            lo, hi = d[k] - width, d[k] + width
            for _ in range(60):
                if resid(lo) < 0.0 < resid(hi):
                    break
                lo, hi, width = lo - width, hi + width, 2.0 * width
            d[k] = optimize.brentq(resid, lo, hi, xtol=1e-15, rtol=1e-13)
        ref_d[i], ref_s[i] = d, reference.stress(params, d, level=level)
    return ref_s, ref_d


def test_the_reference_on_threads_has_the_bits_of_one_step_after_the_other(monkeypatch):
    """add_reference solves the steps on threads and never integrates a displacement twice; its curves are those of
    the plain loop to the last bit, on a path with a stress-controlled stage (Brent's method at every step)."""
    import sys
    from pathlib import Path

    from asperity_sim import paths, presets, simulate

    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parent.parent / "scenarios"))
    sys.modules.pop("_common", None)
    from _common import add_reference

    ds = simulate(presets.R1, paths.constant_normal_shear(300e6, 10e-6, increments=4), n=500, seed=3)
    ref_s, ref_d = _reference_one_step_after_the_other(ds, presets.R1, "fast")
    got = add_reference(ds.copy(), presets.R1, level="fast", threads=2)
    assert np.array_equal(got["reference_stress"].values, ref_s)
    assert np.array_equal(got["reference_displacement"].values, ref_d)
    assert not np.array_equal(ref_d, ds["displacement"].values)  # the closures were solved for, not copied
