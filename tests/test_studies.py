"""The studies under studies/ run at tiny size as programs, and their bookkeeping is right.

The quick runs start the scripts as programs (``python studies/x.py --quick``).  The tests of
the mdr study's own bookkeeping (which runs it reads, the cheapest (n, k)) and of the studies'
timing rule (``studies/timing.py``) import those modules by name through ``support.study``
(``studies/`` on ``sys.path``, as when the scripts run): those functions exist only there.
"""

import math
import warnings

import numpy as np
import pytest
import xarray as xr
from support import study


@pytest.fixture(scope="module")
def mdr_convergence():
    return study("mdr_convergence")


@pytest.mark.slow
def test_mdr_convergence_quick_run(tmp_path, run_script):
    """The study at smoke size writes its three outputs; every variable has units and a long name."""
    done = run_script("studies/mdr_convergence.py", "--quick", "--outdir", tmp_path)
    assert done.returncode == 0, done.stderr
    assert "wrote" in done.stdout
    ds = xr.open_dataset(tmp_path / "mdr_convergence.nc", engine="netcdf4")
    for name in list(ds.data_vars) + ["n", "k"]:
        assert ds[name].attrs.get("units") and ds[name].attrs.get("long_name"), name
    assert ds["cycle_dissipation"].attrs["units"] == "J m-2" and ds["wall_time"].attrs["units"] == "s"
    assert set(ds["error"].dims) == {"quantity", "n", "k", "replica"}
    assert ds.attrs["numba_threads"] == 1
    # every (n, k, replica) that was run has finite values, positive times and a closed energy balance
    run = ds["seed"].values >= 0  # (n, replica)
    for var in ("peak_resistance", "cycle_dissipation", "wall_time", "energy_balance"):
        v = ds[var].transpose("n", "replica", "k").values[run]
        assert np.all(np.isfinite(v)), var
    assert np.all(ds["wall_time"].values[np.isfinite(ds["wall_time"].values)] > 0.0)
    assert float(np.nanmax(ds["energy_balance"].values)) <= 1e-9
    assert np.all(np.isfinite(ds["rms_error"].values))
    # the RMS over replicas is that of the recorded per-replica errors, and mc_error is its k_ref column
    err = ds["error"].transpose("quantity", "n", "k", "replica").values
    np.testing.assert_allclose(ds["rms_error"].transpose("quantity", "n", "k").values,
                               np.sqrt(np.nanmean(err**2, axis=-1)), rtol=1e-12)
    np.testing.assert_allclose(ds["mc_error"].transpose("quantity", "n").values,
                               ds["rms_error"].sel(k=ds.attrs["k_ref"]).transpose("quantity", "n").values, rtol=1e-12)
    assert np.all(np.isfinite(ds["mc_error"].values))
    # the k error is measured against the same population: zero at k_ref by construction
    np.testing.assert_array_equal(ds["k_error"].sel(k=ds.attrs["k_ref"]).values, 0.0)
    # the quantities are physical: a positive peak resistance below mu-like values, positive loop energy
    assert 0.0 < float(ds["reference_value_peak_resistance"]) < 2.0
    assert float(ds["reference_value_cycle_dissipation"]) > 0.0
    assert np.all(np.isfinite(ds["reference_rel_stderr"].values))
    ds.close()
    table = (tmp_path / "mdr_convergence.md").read_text()
    assert "## For the README" in table
    assert "| peak shear resistance | 1 % |" in table and "| dissipation per cycle | 0.1 % |" in table
    assert (tmp_path / "mdr_convergence.png").stat().st_size > 0


@pytest.mark.slow
def test_convergence_study_quick_run(tmp_path, run_script):
    """The error-against-time study (issue 5) at smoke size: every method, every scene, its three outputs."""
    done = run_script("studies/convergence.py", "--quick", "--outdir", tmp_path)
    assert done.returncode == 0, done.stderr
    ds = xr.open_dataset(tmp_path / "convergence.nc", engine="netcdf4")
    assert set(ds["error"].dims) == {"method", "n", "replica", "quantity"}
    assert set(ds.method.values) == {"mc", "rqmc", "pruned", "pruned_mc", "grid", "grid_forces"}
    # the two grid variants differ only in Step 4: same errors, the published one costs more
    for v in ("grid", "grid_forces"):
        assert np.isfinite(ds["rms_error"].sel(method=v)).any()
    np.testing.assert_array_equal(ds["error"].sel(method="grid").values, ds["error"].sel(method="grid_forces").values)
    for var in ("error", "wall_time", "rms_error", "mean_wall_time"):
        assert ds[var].attrs["units"] and ds[var].attrs["long_name"]
    # the RMS over replicas is that of the recorded per-replica errors (NaN where a (method, n) was not run)
    err = ds["error"].transpose("method", "n", "quantity", "replica").values
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN slices: (method, n) pairs not run
        rms = np.sqrt(np.nanmean(err**2, axis=-1))
    np.testing.assert_allclose(ds["rms_error"].transpose("method", "n", "quantity").values, rms, rtol=1e-12)
    for m in ds.method.values:
        assert np.isfinite(ds["rms_error"].sel({"method": m}).values).any(), m
    # randomised QMC on a smooth scene: 4x the points must cut the RMS curve error
    e = ds["rms_error"].sel({"method": "rqmc", "quantity": "fig13_S1/curve"}).values
    e = e[np.isfinite(e)]
    assert e[-1] < e[0]
    assert ds.attrs["source"].endswith("studies/convergence.py")
    ds.close()
    table = (tmp_path / "convergence.md").read_text()
    assert "| fig13_R1 | rqmc |" in table and "Speed-up against the paper's grid method" in table
    assert "| fig11_R1 | 1e-02 |" in table and "grid_forces time" in table
    assert (tmp_path / "convergence.png").stat().st_size > 0


def test_timing_repeats_only_short_runs():
    """A short run is timed REPEATS times and its median kept; a long one once; the result is the first run's."""
    timing = study("timing")
    times = iter([0.05, 0.30, 0.01, 0.50])
    calls = []

    def run():
        calls.append(1)
        return len(calls), next(times)

    result, seconds = timing.timed(run)
    assert (result, seconds, len(calls)) == (1, float(np.median([0.05, 0.30, 0.01])), 3)
    result, seconds = timing.timed(run)
    assert (result, seconds, len(calls)) == (4, 0.50, 4)


def fake_run(stage, ratio, dissipation):
    """A dataset shaped like simulate()'s output with the given stage, sigma_2/sigma_1 and dissipation."""
    m = len(stage)
    sig = np.zeros((m, 3))
    sig[:, 0] = 3e8
    sig[:, 1] = 3e8 * np.asarray(ratio)
    se = np.full((m, 3), 1e6)
    dis = np.asarray(dissipation, dtype=float)
    return xr.Dataset({"stage": ("step", np.asarray(stage)), "stress": (("step", "axis"), sig),
                       "stress_stderr": (("step", "axis"), se), "dissipation": ("step", dis),
                       "external_work": ("step", dis + 1.0), "elastic_energy": ("step", np.ones(m))})


def test_quantities_read_the_first_branch_and_the_last_cycle(mdr_convergence):
    # steps: 0 start, stage 1 (2 steps), then two cycles of stages 2, 3, 4 (2 steps each)
    stage = [0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7]
    ratio = [0, 0, 0, .3, .4, -.2, -.3, .1, 0, .5, .45, -.3, -.4, .1, 0]  # .5 lies in stage 5, not the first branch
    dis = [0, 0, 0, 1, 2, 4, 6, 7, 8, 9, 11, 13, 15, 16, 18.5]
    peak, se, w, bal = mdr_convergence.quantities(fake_run(stage, ratio, dis), cycles=2)
    assert peak == pytest.approx(0.4)
    assert se == pytest.approx(1e6 / 3e8)
    assert w == pytest.approx(18.5 - 8.0)  # from the last step of stage 4 to the end of stage 7
    assert bal == 0.0
    _, _, w1, _ = mdr_convergence.quantities(fake_run(stage[:9], ratio[:9], dis[:9]), cycles=1)
    assert w1 == pytest.approx(8.0)


def grid(rms, t, ns=(1024, 2048, 4096), ks=(2, 4, 8)):
    return xr.Dataset({"rms_error": (("quantity", "n", "k"), np.asarray(rms, dtype=float)[None]),
                       "mean_wall_time": (("n", "k"), np.asarray(t))},
                      coords={"quantity": ["q"], "n": list(ns), "k": list(ks)})


def test_cheapest_point_stays_below_the_target_at_larger_n(mdr_convergence):
    t = [[1.0, 1.5, 2.0], [2.0, 3.0, 4.0], [4.0, 6.0, 8.0]]
    rms = [[5e-3, 2e-3, 3e-3],  # k = 2 at n = 1024 below 1e-2 by luck, above it at n = 2048
           [2e-2, 1e-3, 9e-4],
           [2e-2, 8e-4, 5e-4]]
    res = grid(rms, t)
    assert mdr_convergence.cheapest(res, "q", 1e-2) == (1024, 4, 1.5, 2e-3)
    # k = 4 and k = 8 both reach 1e-3 at n = 2048; k = 4 is cheaper there (3.0 s against 4.0 s)
    assert mdr_convergence.cheapest(res, "q", 1e-3) == (2048, 4, 3.0, 1e-3)
    assert mdr_convergence.cheapest(res, "q", 1e-4) is None
    assert mdr_convergence.best_achieved(res, "q") == (4096, 8, 8.0, 5e-4)


def test_cheapest_picks_the_smallest_time(mdr_convergence):
    t = [[1.0, 1.5], [2.0, 3.0]]
    rms = [[2e-3, 9e-4], [1e-3, 5e-4]]
    res = grid(rms, t, ns=(1024, 2048), ks=(2, 4))
    assert mdr_convergence.cheapest(res, "q", 1e-3) == (1024, 4, 1.5, 9e-4)
    assert math.isclose(mdr_convergence.cheapest(res, "q", 2e-3)[2], 1.0)


def test_confident_choice_asks_the_upper_bound_of_the_rms(mdr_convergence):
    t = [[1.0, 1.5], [2.0, 3.0]]
    rms = [[9e-4, 7e-4], [5e-4, 4e-4]]
    res = grid(rms, t, ns=(1024, 2048), ks=(2, 4))
    res["replicas"] = ("n", np.array([8, 8]))
    factor = math.sqrt(8 / 3.4895)  # chi2_8 quantile at 0.1
    np.testing.assert_allclose(mdr_convergence.rms_upper(res, "q", 0.9), np.asarray(rms) * factor, rtol=1e-4)
    assert mdr_convergence.cheapest(res, "q", 1e-3) == (1024, 2, 1.0, 9e-4)
    # 9e-4 x 1.51 and 7e-4 x 1.51 exceed 1e-3; at n = 2048, 5e-4 x 1.51 = 7.6e-4 does not
    assert mdr_convergence.cheapest(res, "q", 1e-3, confidence=0.9) == (2048, 2, 2.0, 5e-4)
