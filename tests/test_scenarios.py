"""Every scenario runs at tiny size, so none can silently rot."""

import importlib
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
sys.path.insert(0, str(SCENARIOS))

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
def test_scenario_runs_and_writes_its_outputs(name, tmp_path, capsys):
    module = importlib.import_module(name)
    assert module.main(["--quick", "--n", "800", "--outdir", str(tmp_path)]) == 0
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
    assert "wrote" in capsys.readouterr().out


def test_scenario_rejects_bad_options(capsys):
    module = importlib.import_module("three_step")
    with pytest.raises(SystemExit) as err:
        module.main(["--n", "0"])
    assert err.value.code != 0
    assert "--n = 0" in capsys.readouterr().err


@pytest.mark.slow
def test_convergence_study_quick_run(tmp_path, capsys):
    """The error-against-time study (issue 5) at smoke size: every method, every scene, its three outputs."""
    module = importlib.import_module("convergence")
    assert module.main(["--quick", "--outdir", str(tmp_path)]) == 0
    ds = xr.open_dataset(tmp_path / "convergence.nc", engine="netcdf4")
    assert set(ds["error"].dims) == {"method", "n", "replica", "quantity"}
    assert set(ds.method.values) == {"mc", "rqmc", "pruned", "pruned_mc", "grid", "grid_forces"}
    # the two grid variants differ only in Step 4: same errors, the published one costs more
    for v in ("grid", "grid_forces"):
        assert np.isfinite(ds["rms_error"].sel(method=v)).any()
    np.testing.assert_array_equal(ds["error"].sel(method="grid").values, ds["error"].sel(method="grid_forces").values)
    for var in ("error", "wall_time", "rms_error", "mean_wall_time"):
        assert ds[var].attrs["units"] and ds[var].attrs["long_name"]
    for m in ds.method.values:
        e = ds["rms_error"].sel({"method": m}).values
        assert np.all(e[np.isfinite(e)] >= 0.0) and np.isfinite(e).any()
    # randomised QMC on a smooth scene: 4x the points must cut the RMS curve error
    e = ds["rms_error"].sel({"method": "rqmc", "quantity": "fig13_S1/curve"}).values
    e = e[np.isfinite(e)]
    assert e[-1] < e[0]
    ds.close()
    table = (tmp_path / "convergence.md").read_text()
    assert "| fig13_R1 | rqmc |" in table and "Speed-up against the paper's grid method" in table
    assert "| fig11_R1 | 1e-02 |" in table and "grid_forces time" in table
    assert (tmp_path / "convergence.png").stat().st_size > 0


def test_convergence_timing_repeats_only_short_runs():
    """A short run is timed REPEATS times and its median kept; a long one once; the result is the first run's."""
    module = importlib.import_module("convergence")
    times = iter([0.05, 0.30, 0.01, 0.50])
    calls = []

    def run():
        calls.append(1)
        return len(calls), next(times)

    result, seconds = module.timed(run)
    assert (result, seconds, len(calls)) == (1, float(np.median([0.05, 0.30, 0.01])), module.REPEATS)
    result, seconds = module.timed(run)
    assert (result, seconds, len(calls)) == (4, 0.50, module.REPEATS + 1)
