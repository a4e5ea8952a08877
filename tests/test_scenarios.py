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


@pytest.mark.slow  # a fresh Python process that imports the package
def test_scenario_rejects_bad_options(run_script):
    done = run_script("scenarios/three_step.py", "--n", "0")
    assert done.returncode == 2  # argparse's usage error
    assert "--n = 0" in done.stderr and "Traceback" not in done.stderr
