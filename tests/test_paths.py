"""Load paths (SPEC §6–§7): Stage / LoadPath validation and the paper's two paths.

Expected stages are written out from SPEC §7, not read back from the code.
"""

import math

import numpy as np
import pytest

from asperity_sim import paths
from asperity_sim.paths import DISPLACEMENT, LoadPath, Stage, STRESS

D, S = DISPLACEMENT, STRESS


# --------------------------------------------------------------------------- Stage: control


@pytest.mark.parametrize("given, expected", [
    (("displacement", "displacement", "displacement"), (D, D, D)),
    (("d", "d", "d"), (D, D, D)),
    (("s", "d", "d"), (S, D, D)),
    (("stress", "d", "s"), (S, D, S)),
    (["s", "s", "s"], (S, S, S)),
])
def test_stage_control_names_and_aliases(given, expected):
    st = Stage(given, (1.0, 2.0, 3.0), 5)
    assert st.control == expected
    assert st.stress_controlled.dtype == bool
    assert st.stress_controlled.tolist() == [c == S for c in expected]


def test_stage_defaults_are_displacement_controlled_zero_target():
    st = Stage()
    assert st.control == (D, D, D)
    assert st.target == (0.0, 0.0, 0.0)
    assert not st.stress_controlled.any()


@pytest.mark.parametrize("bad, shown", [
    (("d", "x", "d"), "'x'"),
    (("d", "d", "Stress"), "'Stress'"),
    (("d", "d", None), "None"),
    (("d", "d"), "('d', 'd')"),
    (("d", "d", "d", "d"), "('d', 'd', 'd', 'd')"),
    ("dds", "'dds'"),  # a string is not 3 component names
])
def test_stage_bad_control_raises_naming_the_value(bad, shown):
    with pytest.raises(ValueError) as exc:
        Stage(bad, (0.0, 0.0, 0.0), 1)
    assert shown in str(exc.value)
    assert "control" in str(exc.value)


def test_stage_scalar_control_raises_value_error():
    with pytest.raises(ValueError, match="control"):
        Stage(5, (0.0, 0.0, 0.0), 1)


# --------------------------------------------------------------------------- Stage: target


def test_stage_target_is_converted_to_floats():
    st = Stage(("s", "d", "d"), np.array([5e8, 1e-6, 0]), 3)
    assert st.target == (5e8, 1e-6, 0.0)
    assert all(type(t) is float for t in st.target)
    st2 = Stage(("d", "d", "d"), [1, 2, 3], 3)  # integers are reals
    assert st2.target == (1.0, 2.0, 3.0)


@pytest.mark.parametrize("bad, shown", [
    ((1.0, 2.0), "(1.0, 2.0)"),
    ((1.0, 2.0, 3.0, 4.0), "(1.0, 2.0, 3.0, 4.0)"),
    ((), "()"),
    ("abc", "'abc'"),
])
def test_stage_target_wrong_length_raises_naming_the_value(bad, shown):
    with pytest.raises(ValueError) as exc:
        Stage(("d", "d", "d"), bad, 1)
    assert "target" in str(exc.value)
    assert shown in str(exc.value)


@pytest.mark.parametrize("bad, shown", [
    (math.nan, "nan"), (math.inf, "inf"), (-math.inf, "-inf"), ("1e-6", "'1e-6'"), (None, "None"),
    (True, "True"), (1 + 0j, "(1+0j)"),
])
@pytest.mark.parametrize("k", [0, 1, 2])
def test_stage_target_not_finite_real_raises_naming_component_and_value(bad, shown, k):
    target = [1e-6, 2e-6, 3e-6]
    target[k] = bad
    with pytest.raises(ValueError) as exc:
        Stage(("d", "s", "d"), tuple(target), 1)
    msg = str(exc.value)
    assert f"target[{k + 1}]" in msg
    assert shown in msg


def test_stage_target_unit_follows_control_in_message():
    with pytest.raises(ValueError, match=r"target\[1\] \[Pa\]"):
        Stage(("s", "d", "d"), (math.nan, 0.0, 0.0), 1)
    with pytest.raises(ValueError, match=r"target\[1\] \[m\]"):
        Stage(("d", "d", "d"), (math.nan, 0.0, 0.0), 1)


def test_stage_negative_and_zero_targets_are_allowed():
    # unloading and tension targets are a physics question for the solver, not an input error
    st = Stage(("s", "d", "d"), (-1e6, -2e-6, 0.0), 1)
    assert st.target == (-1e6, -2e-6, 0.0)


def test_stage_scalar_target_raises_value_error():
    with pytest.raises(ValueError, match="target"):
        Stage(("d", "d", "d"), 1e-6, 1)


# --------------------------------------------------------------------------- Stage: increments etc.


@pytest.mark.parametrize("good", [1, 2, 50, np.int64(7), 10**7])
def test_stage_increments_valid(good):
    st = Stage(("d", "d", "d"), (0.0, 0.0, 0.0), good)
    assert st.increments == int(good)
    assert type(st.increments) is int


@pytest.mark.parametrize("bad, shown", [
    (0, "0"), (-3, "-3"), (2.0, "2.0"), (2.5, "2.5"), (True, "True"), ("10", "'10'"), (None, "None"),
    (math.nan, "nan"), (10**7 + 1, str(10**7 + 1)),
])
def test_stage_increments_invalid_raise_naming_value(bad, shown):
    with pytest.raises(ValueError) as exc:
        Stage(("d", "d", "d"), (0.0, 0.0, 0.0), bad)
    assert "increments" in str(exc.value)
    assert shown in str(exc.value)


@pytest.mark.parametrize("kw, name", [
    ({"adaptive": 1}, "adaptive"), ({"adaptive": "yes"}, "adaptive"),
    ({"max_fraction": 0.0}, "max_fraction"), ({"max_fraction": 1.5}, "max_fraction"),
    ({"max_fraction": math.nan}, "max_fraction"), ({"name": 3}, "name"),
])
def test_stage_other_fields_validated(kw, name):
    with pytest.raises(ValueError, match=name):
        Stage(("d", "d", "d"), (0.0, 0.0, 0.0), 1, **kw)


def test_stage_is_frozen():
    st = Stage(("d", "d", "d"), (0.0, 0.0, 0.0), 1)
    with pytest.raises(Exception):
        st.increments = 3


# --------------------------------------------------------------------------- LoadPath


def test_loadpath_accepts_sequence_of_stages_and_reports_length():
    a = Stage(("d", "d", "d"), (1e-6, 0.0, 0.0), 2)
    b = Stage(("s", "d", "d"), (1e6, 0.0, 0.0), 3)
    lp = LoadPath([a, b], name="x")
    assert lp.stages == (a, b)
    assert len(lp) == 2
    text = lp.describe()
    assert "stage 1" in text and "stage 2" in text and "sigma_1" in text and "Delta_1" in text


@pytest.mark.parametrize("bad", [(), [], (Stage(), "stage"), ("abc",), [None], "abc"])
def test_loadpath_rejects_empty_or_non_stage(bad):
    with pytest.raises(ValueError, match="Stage"):
        LoadPath(bad)


@pytest.mark.parametrize("bad", [Stage(), None])
def test_loadpath_rejects_non_iterable_with_value_error(bad):
    with pytest.raises(ValueError):
        LoadPath(bad)


# --------------------------------------------------------------------------- the paper's paths (SPEC §7)


@pytest.mark.parametrize("d_max", [15e-6, 6e-6, 1, np.float64(2.5e-6)])
def test_three_step_matches_spec(d_max):
    d = float(d_max)
    lp = paths.three_step(d_max)
    assert isinstance(lp, LoadPath)
    assert len(lp) == 3
    # SPEC §7: step 1 Delta_1 -> d; step 2 Delta_1 held, Delta_2 -> d; step 3 both held, Delta_3 -> d
    expected = [(d, 0.0, 0.0), (d, d, 0.0), (d, d, d)]
    for st, tgt in zip(lp.stages, expected):
        assert st.control == (D, D, D)
        assert st.target == tgt
        assert st.increments >= 1
    lp5 = paths.three_step(d_max, increments=5)
    assert [s.increments for s in lp5.stages] == [5, 5, 5]


@pytest.mark.parametrize("sigma_n, d2", [(500e6, 40e-6), (1.0, 1e-9)])
def test_constant_normal_shear_matches_spec(sigma_n, d2):
    lp = paths.constant_normal_shear(sigma_n, d2, increments=7, normal_increments=3)
    assert len(lp) == 2
    s1, s2 = lp.stages
    # SPEC §7: step 1, sigma_1 from 0 to sigma_n with Delta_2 = Delta_3 = 0
    assert s1.control == (S, D, D)
    assert s1.target == (sigma_n, 0.0, 0.0)
    assert s1.increments == 3
    # step 2, sigma_1 held, Delta_2 increased to d2_max, Delta_3 = 0
    assert s2.control == (S, D, D)
    assert s2.target == (sigma_n, d2, 0.0)
    assert s2.increments == 7
    assert s1.stress_controlled.tolist() == [True, False, False]
    # default: the normal stage uses the same number of increments
    lp2 = paths.constant_normal_shear(sigma_n, d2, increments=4)
    assert [s.increments for s in lp2.stages] == [4, 4]


BAD_POSITIVE = [0.0, -1e-6, -0.0, math.nan, math.inf, -math.inf, "1e-5", None, True, [1e-6]]


@pytest.mark.parametrize("bad", BAD_POSITIVE)
def test_three_step_rejects_bad_d_max(bad):
    with pytest.raises(ValueError, match="d_max"):
        paths.three_step(bad)


@pytest.mark.parametrize("bad", BAD_POSITIVE)
def test_constant_normal_shear_rejects_bad_sigma_n(bad):
    with pytest.raises(ValueError, match="sigma_n"):
        paths.constant_normal_shear(bad, 10e-6)


@pytest.mark.parametrize("bad", BAD_POSITIVE)
def test_constant_normal_shear_rejects_bad_d2_max(bad):
    with pytest.raises(ValueError, match="d2_max"):
        paths.constant_normal_shear(500e6, bad)


@pytest.mark.parametrize("bad", [0, -1, 1.5, True])
def test_paper_paths_reject_bad_increments(bad):
    with pytest.raises(ValueError, match="increments"):
        paths.three_step(1e-6, increments=bad)
    with pytest.raises(ValueError, match="increments"):
        paths.constant_normal_shear(1e6, 1e-6, increments=bad)
    with pytest.raises(ValueError, match="increments"):
        paths.constant_normal_shear(1e6, 1e-6, normal_increments=bad)


# --------------------------------------------------------------------------- bounded work (issue 24, item 4)

@pytest.mark.parametrize("fraction", [1e-12, 9.99e-7, 1e-300, 5e-324])
def test_tiny_max_fraction_is_refused_up_front_with_its_range(fraction):
    """max_fraction = 1e-12 made an adaptive stage that never ended and grew memory."""
    with pytest.raises(ValueError) as exc:
        Stage(("s", "d", "d"), (1e6, 0.0, 0.0), 10, adaptive=True, max_fraction=fraction)
    text = str(exc.value)
    assert f"max_fraction = {float(fraction)!r}" in text and "valid range: [1e-06, 1]" in text and "unbounded" in text


def test_smallest_allowed_fraction_and_the_budget():
    from asperity_sim.paths import BUDGET_FACTOR, BUDGET_SLACK, MIN_FRACTION

    st = Stage(("d", "d", "d"), (1e-6, 0.0, 0.0), 10, adaptive=True, max_fraction=MIN_FRACTION)
    assert st.nominal_increments == 10**6
    assert st.budget == BUDGET_FACTOR * 10**6 + BUDGET_SLACK
    assert Stage(("d", "d", "d"), (1e-6, 0, 0), 10, adaptive=True, max_fraction=0.3).nominal_increments == 10
    assert Stage(("d", "d", "d"), (1e-6, 0, 0), 10, adaptive=True, max_fraction=0.01).nominal_increments == 100
    assert Stage(("d", "d", "d"), (1e-6, 0, 0), 7, max_fraction=0.01).budget == 4 * 7 + 64  # not adaptive
    biggest = Stage(("d", "d", "d"), (1e-6, 0, 0), 10**7, adaptive=True, max_fraction=MIN_FRACTION)
    assert biggest.budget == 4 * 10**7 + 64


def test_tiny_fraction_in_a_scene_file_is_refused():
    from asperity_sim.errors import SceneError
    from asperity_sim.runs.scene import scene_from_dict

    data = {"parameters": {"preset": "S1"},
            "path": {"stages": [{"increments": 3, "Delta_1": "2 um", "Delta_2": "0 um", "Delta_3": "0 um",
                                 "adaptive": True, "max_fraction": 1e-12}]}}
    with pytest.raises(SceneError, match=r"max_fraction = 1e-12 .*valid range: \[1e-06, 1\]"):
        scene_from_dict(data, source="t.toml")
