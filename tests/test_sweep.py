"""Sweeps: grid x replicas, alignment on the nominal schedule, ensemble statistics, Dask = serial bit for bit."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from asperity_sim import paths, presets
from asperity_sim.ui import cli
from asperity_sim.output.netcdf import read_netcdf
from asperity_sim.errors import SceneError
from asperity_sim.runs.scene import load_scene, scale_increments, Scene
from asperity_sim.runs.engine import run_one, run_sweep
from asperity_sim.runs.ensemble import align_run, ensemble_statistics, nominal_schedule
from asperity_sim.runs.sweep import load_sweep, Sweep

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
COMPARED = ("displacement", "stress", "stress_stderr", "displacement_stderr", "tangent", "n_contact", "theta_am",
            "stress_mean", "stress_sem", "displacement_mean", "status", "n_steps", "total_iterations")


def _small_sweep(n=1500, seeds=(1, 2), grid=None):
    scene = load_scene(SCENARIOS / "constant_normal_shear_R1.toml")
    scene = scene.replace(n=n, path=scale_increments(scene.path, 4))
    return Sweep(scene=scene, grid=grid if grid is not None else {"mu": (0.5, 1.0)}, seeds=seeds)


def _same(a, b):
    for v in COMPARED:
        x, y = a[v].values, b[v].values
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), v


@pytest.fixture(scope="module")
def serial():
    return run_sweep(_small_sweep(), scheduler="serial")


def test_sweep_dataset_layout(serial):
    ds = serial
    assert ds["stress"].dims == ("mu", "replica", "step", "axis")
    assert ds.sizes["step"] == 13 and list(ds["seed"].values) == [1, 2] and list(ds["mu"].values) == [0.5, 1.0]
    assert ds["mu"].attrs["units"] == "1" and ds["stress"].attrs["units"] == "Pa"
    assert ds["stress_mean"].dims == ("mu", "step", "axis") and ds["stress_sem"].attrs["units"] == "Pa"
    assert (ds["status"].values == "complete").all() and (ds["aligned_exactly"].values == 1).all()
    assert list(ds["stage"].values[:6]) == [0, 1, 1, 1, 1, 2]
    assert ds.attrs["kind"] == "sweep" and ds.attrs["swept_parameters"] == "mu" and ds.attrs["runs"] == 4
    for name, var in ds.data_vars.items():
        assert "long_name" in var.attrs, name


def test_each_run_is_the_plain_simulation(serial):
    sweep = _small_sweep()
    one = sweep.scene.replace(params=presets.R1.replace(mu=0.5), seed=2).simulate()
    assert np.array_equal(serial["stress"].sel(mu=0.5, replica=1).values, one["stress"].values)
    assert np.array_equal(serial["n_contact"].sel(mu=0.5, replica=1).values, one["n_contact"].values)


def test_ensemble_mean_and_standard_error(serial):
    x = serial["stress"].sel(mu=1.0).values
    assert np.array_equal(serial["stress_mean"].sel(mu=1.0).values, x.mean(axis=0))
    np.testing.assert_allclose(serial["stress_sem"].sel(mu=1.0).values, x.std(axis=0, ddof=1) / np.sqrt(2),
                               rtol=1e-12, atol=1e-6)


@pytest.mark.slow  # starts a cluster of 2 worker processes
def test_local_cluster_of_2_workers_matches_serial_bit_for_bit(serial):
    pytest.importorskip("dask.distributed")
    on_dask = run_sweep(_small_sweep(), scheduler="local", workers=2)
    assert on_dask.attrs["engine"].startswith("dask LocalCluster (2 workers")
    _same(serial, on_dask)


def test_without_dask_runs_serially_with_a_note(monkeypatch, serial):
    import asperity_sim.runs.engine as sweep_module

    monkeypatch.setattr(sweep_module, "dask_available", lambda: False)
    notes = []
    ds = run_sweep(_small_sweep(), scheduler=None, note=notes.append)
    assert len(notes) == 1 and "dask.distributed is not installed: running the sweep serially" in notes[0]
    assert ds.attrs["engine"].startswith("serial")
    _same(serial, ds)
    with pytest.raises(ValueError, match="needs dask.distributed"):
        run_sweep(_small_sweep(), scheduler="tcp://127.0.0.1:1")


def test_alignment_interpolates_adaptive_runs_and_pads_stopped_runs():
    S, D = paths.STRESS, paths.DISPLACEMENT
    nominal = paths.LoadPath((paths.Stage((D, D, D), (3e-6, 0, 0), 6),
                              paths.Stage((S, D, D), (50e6, 1e-6, 0), 6)), name="t")
    scene = Scene(params=presets.S1, path=nominal, n=800, seed=4)
    ds = scene.simulate()
    exact, is_exact = align_run(ds, nominal)
    assert is_exact and np.array_equal(exact["stress"], ds["stress"].values)
    # the same path with an adaptive second stage takes other steps: interpolated onto the nominal ones
    adaptive = paths.LoadPath((nominal.stages[0], dataclasses.replace(nominal.stages[1], increments=2,
                                                                      adaptive=True, max_fraction=0.6)), name="t")
    other = scene.replace(path=adaptive).simulate()
    assert other.sizes["step"] != ds.sizes["step"]
    aligned, is_exact = align_run(other, nominal)
    assert not is_exact
    stage, frac = nominal_schedule(nominal)
    d2 = aligned["displacement"][stage == 2, 1]
    np.testing.assert_allclose(d2, frac[stage == 2] * 1e-6, rtol=1e-12)  # controlled: exactly interpolated
    np.testing.assert_allclose(aligned["stress"][:, 0], exact["stress"][:, 0], rtol=1e-6, atol=1.0)
    # a run that stopped early: NaN beyond its last converged step
    stopped, _ = align_run(ds.isel(step=slice(0, 9)), nominal)
    assert np.isfinite(stopped["stress"][:9]).all() and np.isnan(stopped["stress"][9:]).all()


def test_statistics_skip_missing_replicas():
    import xarray as xr

    x = np.array([[1.0, 2.0], [3.0, np.nan], [5.0, np.nan]])
    ds = xr.Dataset({"stress": (("replica", "step"), x, {"units": "Pa"})})
    out = ensemble_statistics(ds)
    np.testing.assert_allclose(out["stress_mean"].values, [3.0, 2.0])
    assert out["stress_sem"].values[0] == pytest.approx(2.0 / np.sqrt(3)) and np.isnan(out["stress_sem"].values[1])


def test_run_one_returns_summary():
    res = run_one(_small_sweep(seeds=(3,)).scenes()[0])
    assert res["status"] == "complete" and res["exact"] and res["n_steps"] == 13 and res["total_iterations"] > 0


def _write(tmp_path, text, name="sw.toml"):
    f = tmp_path / name
    f.write_text(text)
    return f


BASE = f'scene = "{(SCENARIOS / "constant_normal_shear_R1.toml").as_posix()}"\n'


def test_sweep_file_merges_the_base_scene(tmp_path):
    f = _write(tmp_path, BASE + '[run]\nn = 5000\nseed = 7\n[sweep]\nreplicas = 3\n'
                                '[sweep.grid]\nR_m = ["40 um", "50 um"]\nmu = [0.5]\n')
    sw = load_sweep(f)
    assert sw.grid == {"R_m": (40e-6, 50e-6), "mu": (0.5,)} and sw.seeds == (7, 8, 9)
    assert sw.scene.n == 5000 and sw.scene.policy == "follow" and sw.scene.path.name == "constant_normal_shear"
    assert sw.shape == (2, 1, 3) and len(sw.scenes()) == 6 and sw.default_output() == Path("sw.nc")
    assert load_sweep(SCENARIOS / "sweep_friction_R1.toml").shape == (2, 4)


@pytest.mark.parametrize("text, message", [
    ("[run]\nn = 10\n", "missing [sweep] table"),
    ("[sweep]\nreplica = 3\n", "[sweep] unknown key 'replica'"),
    ("[sweep]\nreplicas = 0\n", "replicas = 0 is out of range"),
    ("[sweep]\nreplicas = 2\nseeds = [1, 2]\n", "give replicas or seeds, not both"),
    ("[sweep]\nseeds = [1, 1]\n", "repeat a seed"),
    ("[sweep.grid]\nRm = [1e-6]\n", "[sweep.grid] unknown key 'Rm'"),
    ("[sweep.grid]\nmu = 0.5\n", "must be a non-empty list"),
    ("[sweep.grid]\nmu = [0.5, 0.5]\n", "repeats a value"),
    ("[sweep.grid]\nR_m = [\"40 MPa\"]\n", "[sweep.grid] R_m = '40 MPa': expected a length (m), got a stress (MPa)"),
    ("[sweep]\nreplicas = \"3\"\n", "replicas = '3' is not an integer"),
    ("[sweep.grid]\nnu = [0.3, 0.7]\n", "sweep grid point {'nu': 0.7}: nu = 0.7 is out of range"),
])
def test_broken_sweep_files(tmp_path, text, message):
    with pytest.raises(SceneError) as err:
        load_sweep(_write(tmp_path, BASE + text))
    assert message in str(err.value) and "\n" not in str(err.value)


def test_sweep_command_serial_info_and_plot(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    base = tmp_path / "base.toml"
    base.write_text((SCENARIOS / "three_step_S1.toml").read_text().replace("increments = 30", "increments = 2"))
    _write(tmp_path, 'scene = "base.toml"\n[run]\nn = 600\n[sweep]\nseeds = [5, 6]\n[sweep.grid]\nmu = [0.4, 0.8]\n'
                     '[output]\nfile = "out/sweep.nc"\n')
    assert cli.main(["sweep", "sw.toml", "--serial", "--n", "500"]) == 0
    out = capsys.readouterr().out
    assert "wrote out/sweep.nc: 4 runs (4 complete), dims mu = 2, replica = 2" in out
    ds = read_netcdf(tmp_path / "out" / "sweep.nc")
    assert ds.attrs["n_asperities"] == 500 and list(ds["seed"].values) == [5, 6]
    assert cli.main(["info", "out/sweep.nc"]) == 0
    info = capsys.readouterr().out
    assert "sweep of 4 runs on serial" in info and "runs complete: 4 of 4" in info and "swept" in info
    assert cli.main(["plot", "out/sweep.nc"]) == 0
    assert (tmp_path / "out" / "sweep.png").stat().st_size > 10_000
