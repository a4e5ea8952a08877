"""Runs that never lose work (driver side): wall time inside increments, output checks first, a failed write
keeps the result.  The bounded predictor and the named failures are tested in test_stepping.py."""

import os
import time

import numpy as np
import pytest

import asperity_sim as asim
from asperity_sim import paths, presets, simulate

S, D = paths.STRESS, paths.DISPLACEMENT


def test_wall_time_is_honoured_inside_an_increment(monkeypatch):
    from asperity_sim.solve import run as driver

    real = driver.evaluate_unchecked
    path = paths.constant_normal_shear(100e6, 5e-6, increments=4)
    simulate(presets.R1, path, n=500)  # the kernels compiled (or loaded) first: the time below is the run's own

    def slow(*a, **k):
        time.sleep(0.05)
        return real(*a, **k)

    monkeypatch.setattr(driver, "evaluate_unchecked", slow)
    t = time.perf_counter()
    with pytest.raises(asim.WallTimeExceededError, match="during an increment") as exc:
        simulate(presets.R1, path, n=500, max_wall_time=0.12)
    assert time.perf_counter() - t < 5.0
    assert exc.value.dataset.attrs["status"].startswith("failed: WallTimeExceededError")  # the partial result


@pytest.mark.parametrize("where", ["folder", "under_a_file"])
def test_output_paths_are_checked_before_any_work(tmp_path, where, monkeypatch):
    from asperity_sim.solve import run as driver

    monkeypatch.setattr(driver, "evaluate_unchecked", lambda *a, **k: pytest.fail("work started"))
    if where == "folder":
        target = tmp_path
    else:
        (tmp_path / "file").write_text("x")
        target = tmp_path / "file" / "out.nc"
    with pytest.raises(ValueError, match="output"):
        simulate(presets.R1, paths.three_step(1e-6, increments=1), n=100, output=target)


def test_seed_beyond_64_bits_is_refused_up_front():
    with pytest.raises(ValueError, match="seed"):
        simulate(presets.R1, paths.three_step(1e-6, increments=1), n=100, seed=2**64)


def test_a_failed_write_keeps_the_result_and_names_the_path(tmp_path, monkeypatch):
    from asperity_sim.output import netcdf as io

    def broken(ds, path):
        raise OSError("disk full")

    monkeypatch.setattr(io, "write_netcdf", broken)
    out = tmp_path / "run.nc"
    with pytest.raises(asim.OutputWriteError, match="run.nc") as exc:
        simulate(presets.R1, paths.three_step(1e-6, increments=2), n=200, output=out)
    assert exc.value.dataset.attrs["status"] == "complete"
    assert exc.value.dataset.sizes["step"] == 7
    assert not any(p.name.endswith(".tmp") for p in tmp_path.iterdir())


def test_a_stopped_run_keeps_its_own_error_when_the_write_fails(tmp_path, monkeypatch):
    from asperity_sim.output import netcdf as io

    monkeypatch.setattr(io, "write_netcdf", lambda ds, path: (_ for _ in ()).throw(OSError("disk full")))
    path = paths.LoadPath((paths.Stage((S, D, D), (100e6, 0, 0), 2), paths.Stage((S, S, D), (100e6, 1e12, 0), 2)))
    with pytest.raises(asim.SimulationError) as exc:  # shear far above the strength: the run stops
        simulate(presets.R1, path, n=500, output=tmp_path / "run.nc")
    ds = exc.value.dataset  # the converged part: the start and the normal stage at least
    assert ds.sizes["step"] >= 3 and ds.attrs["status"].startswith(f"failed: {type(exc.value).__name__}")
    assert any("could not be written" in n for n in getattr(exc.value, "__notes__", []))
    assert os.listdir(tmp_path) == []
