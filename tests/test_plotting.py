"""The figures (asperity_sim.output.plotting) say what their bands are, mark computed points and draw
only the run's physics; checked on the Figure objects (matplotlib Agg)."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

from asperity_sim import paths, Population, presets, simulate
from asperity_sim.output import plotting  # noqa: E402
from asperity_sim.paths import LoadPath, Stage  # noqa: E402

SE_STATEMENT = "±2 SE"  # the documented convention: bands are ± 2 standard errors


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def runs():
    pop = Population.sample(presets.R1, 1500, seed=3)
    S, D = "stress", "displacement"
    closure_stress = LoadPath((Stage((S, D, D), (100e6, 0.0, 0.0), 6, name="normal loading"),), name="closure")
    closure_disp = LoadPath((Stage((D, D, D), (16e-6, 0.0, 0.0), 6, name="closure"),), name="closure")
    return {
        "closure_stress": simulate(presets.R1, closure_stress, population=pop),
        "closure_displacement": simulate(presets.R1, closure_disp, population=pop),
        "shear": simulate(presets.R1, paths.constant_normal_shear(100e6, 5e-6, increments=6), population=pop),
    }


def _data_lines(ax):
    """Lines that draw computed points (not guides, not empty legend proxies)."""
    return [ln for ln in ax.get_lines() if ln.get_gid() != "guide" and len(ln.get_xdata()) > 1]


def check_honest(fig):
    """Every axes with a shaded band states the band in its legend; every computed curve has markers."""
    banded = 0
    for ax in fig.axes:
        lines = _data_lines(ax)
        for ln in lines:
            assert ln.get_marker() not in (None, "", " ", "None", "none"), (ax.get_ylabel(), ln.get_label())
        if any(isinstance(c, PolyCollection) for c in ax.collections):
            banded += 1
            legend = ax.get_legend()
            assert legend is not None, ax.get_ylabel()
            assert any(SE_STATEMENT in t.get_text() for t in legend.get_texts()), \
                [t.get_text() for t in legend.get_texts()]
    return banded


@pytest.mark.parametrize("which", ["closure_stress", "closure_displacement"])
def test_plot_of_a_closure_run_is_normal_stress_against_closure_without_shear(runs, which):
    ds = runs[which]
    fig = plotting.plot_run(ds)
    assert check_honest(fig) >= 1
    labels = " ".join(ax.get_ylabel() + ax.get_xlabel() + ax.get_title() for ax in fig.axes).lower()
    assert "shear" not in labels  # no Monte Carlo noise drawn as a shear resistance
    assert "path length" not in labels
    stress_axes = [ax for ax in fig.axes if "normal stress" in ax.get_ylabel()]
    assert len(stress_axes) == 1
    (curve,) = _data_lines(stress_axes[0])
    np.testing.assert_array_equal(curve.get_xdata(), ds["displacement"].sel(axis=1).values * 1e6)
    np.testing.assert_array_equal(curve.get_ydata(), ds["stress"].sel(axis=1).values * 1e-6)
    assert np.ptp(curve.get_xdata()) > 0 and not np.allclose(curve.get_xdata(), curve.get_ydata())
    for ax in fig.axes:  # every curve of this figure runs along the closure
        for ln in _data_lines(ax):
            np.testing.assert_array_equal(ln.get_xdata(), ds["displacement"].sel(axis=1).values * 1e6)


def test_plot_of_a_shear_run_draws_the_sheared_axis_only(runs):
    ds = runs["shear"]
    fig = plotting.plot_run(ds)
    assert check_honest(fig) >= 2
    ylabels = [ax.get_ylabel() for ax in fig.axes]
    assert any("shear resistance" in y for y in ylabels)
    legend_texts = {t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()}
    assert r"$\sigma_2$" in legend_texts and r"$\sigma_3$" not in legend_texts  # axis 3 was never moved
    (ratio_ax,) = [ax for ax in fig.axes if "shear resistance" in ax.get_ylabel()]
    (ratio,) = _data_lines(ratio_ax)
    first_shear = int(np.flatnonzero(ds["stage"].values == 2)[0])
    assert np.all(np.isnan(ratio.get_ydata()[:first_shear]))  # nothing drawn before the shear starts
    assert np.all(np.isfinite(ratio.get_ydata()[first_shear:]))


def test_shear_axes_are_the_moved_or_loaded_ones(runs):
    assert plotting.shear_axes(runs["closure_stress"]) == []
    assert plotting.shear_axes(runs["shear"]) == [2]


def test_scenario_figures_state_their_bands_and_mark_their_points(runs):
    closure = {"R1": runs["closure_stress"]}
    shear = {"R1": runs["shear"], "R1 again": runs["shear"]}
    for fig in (plotting.plot_normal_closure(closure), plotting.plot_constant_normal_shear(shear),
                plotting.plot_three_step({"R1": runs["shear"]})):
        assert check_honest(fig) >= 1


def test_the_check_fails_on_an_unlabelled_band_and_a_bare_line():
    fig, ax = plt.subplots()
    ax.plot([0, 1, 2], [0, 1, 4], label="y")
    ax.fill_between([0, 1, 2], [0, 0, 3], [0, 2, 5])
    ax.legend()
    with pytest.raises(AssertionError):
        check_honest(fig)
    fig, ax = plt.subplots()
    plotting._band(ax, np.arange(3.0), np.arange(3.0), np.ones(3), "k", label="y")
    ax.legend()  # markers, but the band is not stated
    with pytest.raises(AssertionError):
        check_honest(fig)
    plotting.band_legend(ax)
    assert check_honest(fig) == 1
