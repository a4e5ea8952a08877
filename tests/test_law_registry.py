"""A law is one module: two laws declared here (one path independent, one with history and an option of its
own) run through ``simulate``, a scene file, a sweep, a checkpoint and the command line without any change to
the package, which learns their names, options, variables and cost from the registry."""

import dataclasses
import importlib.util
from pathlib import Path

import numba
import numpy as np
import pytest

from asperity_sim import laws, paths, presets, resume, simulate
from asperity_sim.laws.hertz import hertz, hertz_energy
from asperity_sim.output.variables import Var
from asperity_sim.runs.engine import choose_engine, run_sweep
from asperity_sim.runs.scene import load_scene
from asperity_sim.runs.sweep import Sweep
from asperity_sim.ui import cli, parser

um = 1e-6


# ---- a path-independent law: Hertz without friction (the paper law at mu = 0) ----

@numba.njit(cache=True, inline="always", error_model="numpy")
def sliding_values(dn, ds, dt, R, consts):
    f_n, k_n = hertz(dn, R, consts[0])
    return (f_n, 0.0, 0.0, k_n, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 3.0)


SLIDING = laws.Law(name="test_sliding", summary="Hertz, every contact sliding freely (test law)",
                   constants=lambda params, options: (params.E_star,), local=sliding_values)


# ---- a history law with an option: `gain` times Hertz, remembering each contact's largest overlap ----

@dataclasses.dataclass(frozen=True)
class GainOptions(laws.Options):
    gain: int = laws.option(1, "multiple of the Hertz force", valid=(1, 8))


@numba.njit(cache=True, inline="always", error_model="numpy")
def gain_trial(dn, dds, ddt, dn_c, dn_ref, R, consts, arrays, sl, fresh):
    f_n, k_n = hertz(dn, R, consts[0])
    g = consts[1]
    return (g * f_n, 0.0, 0.0, g * k_n, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 3.0)


@numba.njit(cache=True, inline="always", error_model="numpy")
def gain_commit(dn, dds, ddt, dn_c, dn_ref, R, consts, arrays, sl, fresh, scratch):
    g = consts[1]
    deepest = arrays[0]
    grew = fresh or dn > deepest[sl]
    if dn <= 0.0:
        deepest[sl] = 0.0  # contact lost: memory erased
    elif grew:
        deepest[sl] = dn
    stored = g * hertz_energy(dn, R, consts[0])
    before = 0.0 if fresh else g * hertz_energy(dn_c, R, consts[0])
    return 3 if dn > 0.0 else 0, stored - before, stored, 0.0, 1 if grew and dn > 0.0 else 0


GAIN = laws.Law(
    name="test_gain", summary="gain x Hertz without friction, remembering the deepest overlap (test law)",
    constants=lambda params, options: (params.E_star, float(options.gain)),
    history=laws.History(arrays=lambda capacity, options: (np.zeros(capacity),), trial=gain_trial,
                         commit=gain_commit, events="deepenings", bytes_per_contact=lambda options: 8),
    options=GainOptions, cost=laws.Cost(per_increment=1e-3, per_asperity_increment=1e-7, scale_by="gain"),
    variables={"deepenings": Var(("step",), "i8", "1", "contacts whose overlap passed its largest so far")},
)


@pytest.fixture(autouse=True, scope="module")
def registered():
    """Both laws are in the registry while this module's tests run, and only then."""
    for law in (SLIDING, GAIN):
        laws.register(law)
    yield
    for law in (SLIDING, GAIN):
        laws.LAWS.pop(law.name)


def displacement_path():
    """Closure, shear and partial release, every component displacement controlled."""
    d = paths.DISPLACEMENT
    return paths.LoadPath((paths.Stage((d, d, d), (10 * um, 0.0, 0.0), 4),
                           paths.Stage((d, d, d), (10 * um, 3 * um, 1 * um), 4),
                           paths.Stage((d, d, d), (6 * um, 3 * um, 1 * um), 3)), name="closure, shear, release")


def test_the_laws_run_through_simulate_with_their_option():
    path = displacement_path()
    paper = simulate(presets.R1.replace(mu=0.0), path, n=3000, seed=2, law="paper")
    sliding = simulate(presets.R1, path, n=3000, seed=2, law="test_sliding")
    np.testing.assert_allclose(sliding.stress.values, paper.stress.values, rtol=0,
                               atol=1e-12 * np.abs(paper.stress.values).max())  # the paper law at mu = 0
    one = simulate(presets.R1, path, n=3000, seed=2, law="test_gain")
    three = simulate(presets.R1, path, n=3000, seed=2, law="test_gain", gain=3)
    # the same forces, summed in another order (committed contacts first)
    np.testing.assert_allclose(one.stress.values, sliding.stress.values, rtol=0,
                               atol=1e-12 * np.abs(sliding.stress.values).max())
    np.testing.assert_allclose(three.stress.values, 3.0 * one.stress.values, rtol=1e-14, atol=0)
    assert three.attrs["gain"] == 3 and "springs_per_contact" not in three.attrs  # the law's own attributes
    assert three["deepenings"].attrs["long_name"] == GAIN.variables["deepenings"].long_name
    closing = three.stage.values == 1
    assert np.all(three.deepenings.values[closing] == three.n_contact.values[closing])  # every contact deepens
    assert np.all(three.deepenings.values[three.stage.values == 3] == 0)  # release: none does
    work = three.external_work.values - three.elastic_energy.values - three.dissipation.values
    assert np.abs(work).max() <= 1e-12 * np.abs(three.external_work.values).max()  # conservative: no loss
    with pytest.raises(ValueError, match=r"gain = 9 is out of range \(valid range: integer in \[1, 8\]\)"):
        simulate(presets.R1, path, n=100, law="test_gain", gain=9)
    with pytest.raises(ValueError, match=r"gian = 2 is not an option of any law .*gain \(law test_gain\)"):
        simulate(presets.R1, path, n=100, law="test_gain", gian=2)
    # an option of another law is accepted and ignored, so one call can loop over laws
    np.testing.assert_array_equal(simulate(presets.R1, path, n=3000, seed=2, law="test_sliding", gain=3).stress,
                                  sliding.stress)


SCENE = """
[parameters]
preset = "R1"
[run]
n = 3000
seed = 2
law = "test_gain"
gain = 2
[[path.stages]]
increments = 4
Delta_1 = "10 um"
Delta_2 = "0 um"
Delta_3 = "0 um"
[[path.stages]]
increments = 4
Delta_1 = "10 um"
Delta_2 = "3 um"
Delta_3 = "1 um"
"""


def test_a_scene_file_and_the_command_line_take_the_law_and_its_option(tmp_path):
    scene_file = tmp_path / "gain.toml"
    scene_file.write_text(SCENE)
    scene = load_scene(scene_file)
    assert scene.law == "test_gain" and scene.law_options == {"gain": 2} and scene.options().gain == 2
    direct = simulate(scene.params, scene.path, n=3000, seed=2, law="test_gain", gain=2)
    np.testing.assert_array_equal(scene.simulate().stress.values, direct.stress.values)
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENE.replace("gain = 2", "gain = 0"))
    assert cli.main(["run", str(bad), "-o", str(tmp_path / "bad.nc")]) == 1
    out = tmp_path / "gain.nc"
    assert cli.main(["run", str(scene_file), "-o", str(out)]) == 0
    import xarray as xr

    with xr.open_dataset(out) as ds:
        np.testing.assert_array_equal(ds.stress.values, direct.stress.values)
        assert ds.attrs["law"] == "test_gain" and ds.attrs["gain"] == 2
    law_choices = next(a.choices for act in parser.build_parser()._actions if act.choices and "cyclic" in act.choices
                       for a in act.choices["cyclic"]._actions if "--law" in a.option_strings)
    assert {"test_gain", "test_sliding"} <= set(law_choices)


def test_a_sweep_varies_the_option_and_knows_the_cost(tmp_path):
    scene_file = tmp_path / "gain.toml"
    scene_file.write_text(SCENE)
    scene = load_scene(scene_file).replace(n=1500)
    sweep = Sweep(scene=scene, grid={"gain": (1, 4)}, seeds=(1, 2))
    ds = run_sweep(sweep, scheduler="serial")
    assert ds.sizes["gain"] == 2 and ds["gain"].attrs["long_name"].startswith("multiple of the Hertz force")
    one, four = ds.stress.sel(gain=1).values, ds.stress.sel(gain=4).values
    np.testing.assert_allclose(four, 4.0 * one, rtol=1e-14, atol=0)
    with pytest.raises(ValueError, match=r"gain = 9 is out of range"):
        Sweep(scene=scene, grid={"gain": (1, 9)})
    engine, reason = choose_engine(sweep.scenes())
    assert engine in ("serial", "local") and "estimated" in reason  # the law's own cost model
    engine, reason = choose_engine([scene.replace(law="test_sliding")])
    assert engine == "serial" and "test_sliding declares no cost model" in reason


def test_a_checkpoint_keeps_the_option_and_resumes_to_the_same_bits(tmp_path):
    path, ck = displacement_path(), tmp_path / "gain.npz"

    class Stop(Exception):
        pass

    def stop_at_5(stage, n_stages, fraction, step, iterations):
        if step == 5:
            raise Stop

    with pytest.raises(Stop):
        simulate(presets.R1, path, n=2000, seed=4, law="test_gain", gain=5, checkpoint=ck, checkpoint_every=1,
                 progress=stop_at_5)
    resumed = resume(ck)
    full = simulate(presets.R1, path, n=2000, seed=4, law="test_gain", gain=5)
    for name in ("stress", "tangent", "external_work", "deepenings", "transitions"):
        np.testing.assert_array_equal(resumed[name].values, full[name].values, err_msg=name)
    assert resumed.attrs["gain"] == 5


def test_the_laws_page_lists_a_registered_law_with_its_options():
    docs = Path(__file__).resolve().parent.parent / "docs"
    spec = importlib.util.spec_from_file_location("make_laws", docs / "make_laws.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    page = mod.render()
    assert "## `test_gain`" in page and "| `gain` | `1` | integer in [1, 8] |" in page and "`deepenings`" in page
    assert "## `test_sliding`" in page and "cost model: none" in page


def test_a_law_must_declare_what_it_records():
    with pytest.raises(ValueError, match="deepenings"):
        dataclasses.replace(GAIN, variables={})
    with pytest.raises(ValueError, match="not an Options dataclass"):
        dataclasses.replace(SLIDING, options=dict)
