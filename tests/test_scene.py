"""Scene files: unit parsing, the shipped scenes, and broken files giving one clear error."""

import math
from fractions import Fraction
from pathlib import Path

import pytest

from asperity_sim import paths, presets
from asperity_sim.errors import SceneError
from asperity_sim.runs.scene import load_scene, scale_increments, scene_from_dict
from asperity_sim.units import format_quantity, parse_quantity

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
SHIPPED = sorted(p for p in SCENARIOS.glob("*.toml") if not p.name.startswith("sweep_"))


@pytest.mark.parametrize("text, unit, expected", [
    ("50 um", "m", 50e-6), ("50um", "m", 50e-6), ("50 µm", "m", 50e-6), ("50 μm", "m", 50e-6),
    ("15 um", "m", 15e-6), ("3.52 um", "m", 3.52e-6), ("0.1 mm", "m", 0.1e-3), ("2 cm", "m", 0.02),
    ("1.5e3 nm", "m", 1.5e-6), ("-3 um", "m", -3e-6), ("1 m", "m", 1.0), (" 8.82 mm ", "m", 8.82e-3),
    ("500 MPa", "Pa", 500e6), ("80 GPa", "Pa", 80e9), ("0.5 kPa", "Pa", 500.0), ("12 Pa", "Pa", 12.0),
    ("1 mPa", "Pa", 1e-3),
    ("200 /mm2", "m-2", 200e6), ("200 1/mm^2", "m-2", 200e6), ("2e8 m-2", "m-2", 2e8), ("0.2 1/um2", "m-2", 0.2e12),
    ("200 1/mm²", "m-2", 200e6), ("200 mm⁻²", "m-2", 200e6), ("200 mm-2", "m-2", 200e6), ("200 mm**-2", "m-2", 200e6),
    (15e-6, "m", 15e-6), (500000000, "Pa", 5e8), (0.6, "1", 0.6), (1, "1", 1.0), ("0.6", "1", 0.6), ("60 %", "1", 0.6),
    # units beyond the SI prefixes come from pint: 1 inch = 25.4 mm, 1 psi = 1 lbf / inch² (exact definitions)
    ("2 inch", "m", 0.0508), ("1 psi", "Pa", float(Fraction(45359237, 10**8) * Fraction(980665, 10**5)
                                                  / Fraction(254, 10**4) ** 2)),
    ("0.5 rad", "rad", 0.5), (0.5, "rad", 0.5),
])
def test_valid_quantities_are_exact_in_si(text, unit, expected):
    assert parse_quantity(text, unit, "x") == expected  # exact: "15 um" is the float 15e-6


def test_angles_in_degrees():
    assert parse_quantity("30 deg", "rad", "x") == pytest.approx(math.pi / 6, rel=1e-15)
    assert parse_quantity("90 °", "rad", "x") == pytest.approx(math.pi / 2, rel=1e-15)


@pytest.mark.parametrize("value, unit, message", [
    ("3 m", "Pa", "x = '3 m': expected a stress (Pa), got a length (m)"),
    ("500 MPA", "Pa", "x = '500 MPA': unknown unit 'MPA'; expected a stress (Pa) such as Pa, kPa, MPa, GPa"),
    ("10 MPa", "m", "expected a length (m), got a stress (MPa)"),
    ("10 um", "Pa", "expected a stress (Pa), got a length (um)"),
    ("2 um", "m-2", "expected an areal density (m-2), got a length (um)"),
    ("2 J", "m", "expected a length (m), got a quantity of dimension [mass] * [length] ** 2 / [time] ** 2 (J)"),
    ("15 flurbs", "m", "unknown unit 'flurbs'; expected a length (m)"),
    ("5 um//2", "m", "unknown unit 'um//2'"),
    ("15", "m", "x = '15' has no unit (write e.g. \"15 um\", or a plain number in m)"),
    ("30", "rad", "has no unit (write e.g. \"30 deg\""),
    ("30 percent", "rad", "expected an angle (rad), got a dimensionless number (percent)"),
    ("fifteen um", "m", "is not a quantity"),
    ("2*3 um", "m", "unknown unit '*3 um'"),  # pint reads units here, never arithmetic
    ("0.6 MPa", "1", "expected a dimensionless number (1), got a stress (MPa)"),
    (True, "m", "is not a number"),
    ([1, 2], "m", "is not a number or a quantity string"),
    (float("nan"), "m", "is not finite"),
    ("1e400 um", "m", "is not finite"),
])
def test_invalid_quantities_name_value_and_expected_dimension(value, unit, message):
    with pytest.raises(SceneError, match="^x = ") as err:
        parse_quantity(value, unit, "x")
    assert message in str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("value, unit", [(50e-6, "m"), (3.52e-6, "m"), (8.82e-3, "m"), (500e6, "Pa"), (80e9, "Pa"),
                                         (200e6, "m-2")])
def test_format_quantity_reads_back(value, unit):
    assert parse_quantity(format_quantity(value, unit), unit) == pytest.approx(value, rel=1e-12)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_shipped_scenes_load_and_use_table1(path):
    scene = load_scene(path)
    assert scene.params == presets.TABLE1[scene.preset]
    assert scene.n == 200_000 and scene.seed == 2024 and scene.law == "paper" and scene.policy == "follow"
    assert scene.title


def test_shipped_scenes_are_the_papers_paths():
    assert load_scene(SCENARIOS / "three_step_R1.toml").path == paths.three_step(15e-6, 30)
    assert load_scene(SCENARIOS / "three_step_S1.toml").path == paths.three_step(6e-6, 30)
    shear = load_scene(SCENARIOS / "constant_normal_shear_S1.toml").path
    assert [s.control for s in shear.stages] == [("stress", "displacement", "displacement")] * 3
    assert [s.target for s in shear.stages] == [(500e6, 0.0, 0.0), (500e6, 10e-6, 0.0), (500e6, 50e-6, 0.0)]
    closure = load_scene(SCENARIOS / "normal_closure_R2.toml").path
    assert [s.target[0] for s in closure.stages] == [0.5e6, 5e6, 50e6]


def _scene(**tables):
    base = {"parameters": {"preset": "S1"},
            "path": {"stages": [{"increments": 3, "Delta_1": "2 um", "Delta_2": "0 um", "Delta_3": "0 um"}]}}
    base.update(tables)
    return base


def test_overrides_with_units_and_defaults():
    scene = scene_from_dict(_scene(parameters={"preset": "R1", "R_m": "40 um", "mu": 0.6, "G": "70 GPa",
                                               "N": "100 /mm2"}), source="t.toml")
    assert scene.params == presets.R1.replace(R_m=40e-6, mu=0.6, G=70e9, N=100e6)
    assert (scene.n, scene.seed, scene.sampler, scene.law, scene.policy, scene.law_options) == (
        100_000, 0, "random", "paper", "follow", {})
    assert scene.output is None and scene.default_output() == Path("t.nc")
    assert scene.path.name == "t"


def test_full_parameter_set_without_preset():
    table = {k: v for k, v in presets.S2.as_dict().items()}
    assert scene_from_dict(_scene(parameters=table)).params == presets.S2


BROKEN = {
    "missing parameters": ({"parameters": None}, "missing [parameters] table"),
    "missing preset": ({"parameters": {"mu": 0.5}}, "missing preset (valid: R1, S1, R2, S2) or the parameters N"),
    "unknown preset": ({"parameters": {"preset": "R3"}}, "preset = 'R3' is not known (valid: R1, S1, R2, S2)"),
    "negative radius": ({"parameters": {"preset": "R1", "R_m": "-50 um"}},
                        "R_m = -5e-05 is out of range (valid range: > 0)"),
    "negative friction": ({"parameters": {"preset": "R1", "mu": -0.1}}, "mu = -0.1 is out of range (valid range: >= 0)"),
    "unknown parameter": ({"parameters": {"preset": "R1", "Rm": "50 um"}}, "unknown key 'Rm' (valid: preset, N"),
    "wrong unit": ({"parameters": {"preset": "R1", "G": "80 um"}},
                   "[parameters] G = '80 um': expected a stress (Pa), got a length (um)"),
    "sweep file": ({"sweep": {"replicas": 2}}, "it is a sweep file, run it with `asperity-sim sweep`"),
    "unknown top key": ({"stages": []}, "unknown key 'stages' (valid: title, parameters, run, output, path)"),
    "misspelt run key": ({"run": {"sede": 1}}, "did you mean 'seed'?"),
    "negative n": ({"run": {"n": -5}}, "n = -5 is out of range"),
    "float n": ({"run": {"n": 1.5}}, "n = 1.5 is not an integer (valid range: integer in [1, "),
    "quoted n": ({"run": {"n": "100"}}, "[run] n = '100' is not an integer: write 100 without quotes (valid range"),
    "quoted seed": ({"run": {"seed": "7"}}, "[run] seed = '7' is not an integer: write 7 without quotes"),
    "boolean k": ({"run": {"k": True}}, "[run] k = True is not an integer (valid range: integer in [1, 4096])"),
    "quoted increments": ({"path": {"stages": [{"increments": "3", "Delta_1": 0, "Delta_2": 0, "Delta_3": 0}]}},
                          "stage 1: increments = '3' is not an integer"),
    "quoted snapshot": ({"output": {"snapshots": ["2"]}}, "snapshots step = '2' is not an integer"),
    "negative seed": ({"run": {"seed": -1}}, "seed = -1 is out of range (valid range: integer >= 0)"),
    "unknown law": ({"run": {"law": "hertz"}}, "law = 'hertz' is not known (valid: paper, mdr)"),
    "unknown sampler": ({"run": {"sampler": "lhs"}}, "sampler = 'lhs' is not known (valid: random, sobol)"),
    "output not netcdf": ({"output": {"file": "run.txt"}}, "file = 'run.txt' must end in .nc"),
    "bad snapshots": ({"output": {"snapshots": "all"}}, "snapshots = 'all' must be \"stage_ends\" or a list"),
    "missing path": ({"path": None}, "missing [path] table"),
    "missing stages": ({"path": {"name": "x"}}, "missing stages"),
    "empty stages": ({"path": {"stages": []}}, "stages must be one or more [[path.stages]] tables"),
    "missing component": ({"path": {"stages": [{"increments": 3, "Delta_1": "2 um", "Delta_2": "0 um"}]}},
                          "stage 1: component 3 is missing: give Delta_3"),
    "both controls": ({"path": {"stages": [{"increments": 3, "Delta_1": "2 um", "sigma_1": "1 MPa", "Delta_2": 0,
                                            "Delta_3": 0}]}}, "give Delta_1 (displacement control) or sigma_1"),
    "missing increments": ({"path": {"stages": [{"Delta_1": "2 um", "Delta_2": 0, "Delta_3": 0}]}},
                           "stage 1: missing increments"),
    "zero increments": ({"path": {"stages": [{"increments": 0, "Delta_1": "2 um", "Delta_2": 0, "Delta_3": 0}]}},
                        "increments = 0 is out of range"),
    "tension": ({"path": {"stages": [{"increments": 2, "sigma_1": "-5 MPa", "Delta_2": 0, "Delta_3": 0}]}},
                "is a tension, which the interface cannot carry"),
    "stage length as stress": ({"path": {"stages": [{"increments": 2, "sigma_1": "5 um", "Delta_2": 0,
                                                     "Delta_3": 0}]}}, "stage 1: sigma_1 = '5 um': expected a stress (Pa), got a length (um)"),
    "unknown stage key": ({"path": {"stages": [{"increments": 2, "Delta_1": 0, "Delta_2": 0, "Delta_3": 0,
                                                "Delta_4": 0}]}}, "stage 1: unknown key 'Delta_4'"),
    "bad max_fraction": ({"path": {"stages": [{"increments": 2, "Delta_1": 0, "Delta_2": 0, "Delta_3": 0,
                                               "adaptive": True, "max_fraction": 2.0}]}}, "max_fraction = 2.0"),
}


@pytest.mark.parametrize("case", BROKEN)
def test_broken_scene_gives_one_line_naming_file_and_key(case):
    change, message = BROKEN[case]
    data = _scene(**change)
    data = {k: v for k, v in data.items() if v is not None}
    with pytest.raises(SceneError) as err:
        scene_from_dict(data, source="broken.toml")
    text = str(err.value)
    assert text.startswith("broken.toml: ") and message in text and "\n" not in text


def test_file_errors(tmp_path):
    with pytest.raises(SceneError, match="no such file"):
        load_scene(tmp_path / "absent.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[parameters\npreset = 'R1'\n")
    with pytest.raises(SceneError, match=r"bad.toml: not valid TOML: .*line 1"):
        load_scene(bad)


def test_scale_increments_keeps_proportions():
    path = load_scene(SCENARIOS / "normal_closure_S2.toml").path
    assert [s.increments for s in scale_increments(path, 4).stages] == [1, 1, 4]
    assert [s.increments for s in scale_increments(path, 80).stages] == [20, 20, 80]


# --------------------------------------------------------------------------- output inside the scene's folder (issue 24)

@pytest.mark.parametrize("file, word", [("../run.nc", "without '..'"), ("a/../../run.nc", "without '..'"),
                                        ("/abs/run.nc", "inside the scene's folder")])
def test_output_file_may_not_leave_the_scene_folder(tmp_path, file, word):
    src = tmp_path / "s.toml"
    src.write_text("")
    with pytest.raises(SceneError) as err:
        scene_from_dict(_scene(output={"file": file}), source=str(src))
    assert word in str(err.value) and repr(file) in str(err.value) and str(src) in str(err.value)


def test_output_file_is_resolved_in_the_scene_folder(tmp_path):
    src = tmp_path / "s.toml"
    src.write_text("")
    scene = scene_from_dict(_scene(output={"file": "out/run.nc"}), source=str(src))
    assert scene.output == tmp_path / "out" / "run.nc" and scene.default_output() == scene.output
    assert scene_from_dict(_scene(output={"file": "run.nc"}), source="t.toml").output == Path("run.nc")
