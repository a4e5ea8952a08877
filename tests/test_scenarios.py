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
