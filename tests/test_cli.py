"""The asperity-sim command line: every command on the shipped scene files, errors and exit codes."""

import io
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from asperity_sim import cli
from asperity_sim.io import read_netcdf

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
SHIPPED = sorted(p for p in SCENARIOS.glob("*.toml") if not p.name.startswith("sweep_"))
SMALL = """
title = "small test scene"
[parameters]
preset = "S1"
[run]
n = 400
seed = 3
[[path.stages]]
name = "closure"
increments = 3
Delta_1 = "2 um"
Delta_2 = "0 um"
Delta_3 = "0 um"
[[path.stages]]
name = "shear"
increments = 3
Delta_1 = "2 um"
Delta_2 = "1 um"
Delta_3 = "0 um"
"""


def _one_error_line(err, code):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("asperity-sim")
    assert "Traceback" not in err
    return lines[0]


@pytest.mark.parametrize("scene", SHIPPED, ids=lambda p: p.stem)
def test_run_info_plot_on_every_shipped_scene(scene, tmp_path, capsys):
    out = tmp_path / f"{scene.stem}.nc"
    assert cli.main(["run", str(scene), "--n", "300", "--seed", "5", "-o", str(out)]) == 0
    stdout, stderr = capsys.readouterr()
    assert f"wrote {out}" in stdout and "status complete" in stdout
    assert "stage 1/" not in stderr  # no progress bar when stderr is not a terminal
    ds = read_netcdf(out)
    assert ds.attrs["status"] == "complete" and ds.attrs["n_asperities"] == 300 and ds.attrs["seed"] == 5
    assert ds.attrs["scene_file"] == str(scene.resolve()) and "[parameters]" in ds.attrs["scene"]
    assert np.all(np.isfinite(ds["stress"].values))
    assert cli.main(["info", str(out)]) == 0
    info = capsys.readouterr().out
    assert "status: complete" in info and "n = 300" in info and "convergence: Newton iterations" in info
    assert cli.main(["plot", str(out)]) == 0
    assert out.with_suffix(".png").stat().st_size > 10_000


def test_run_default_output_is_scene_name_in_cwd(tmp_path, monkeypatch, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    monkeypatch.chdir(tmp_path)
    assert cli.main(["run", "small.toml", "--quiet"]) == 0
    assert (tmp_path / "small.nc").exists()
    assert cli.main(["plot", "small.nc", "-o", "figs/small.pdf"]) == 0
    assert (tmp_path / "figs" / "small.pdf").stat().st_size > 0


def test_presets_lists_table1_with_units(capsys):
    assert cli.main(["presets"]) == 0
    out = capsys.readouterr().out
    for name in ("R1", "S1", "R2", "S2"):
        assert name in out
    assert "R_m        m" in out and "G          Pa" in out and "N          m-2" in out


def test_progress_line_and_bar():
    line = cli.progress_line([10, 30], 2, 2, 0.5, 25, 3, 1.5, width=10)
    assert line.startswith("stage 2/2 [######....]  62%") and "step 25" in line and "Newton  3" in line
    buf = io.StringIO()
    from asperity_sim.scene import load_scene

    bar = cli.ProgressBar(load_scene(SHIPPED[0]).path, buf)
    bar(1, 3, 1.0, 40, 2)
    bar.close()
    assert buf.getvalue().startswith("\rstage 1/3") and buf.getvalue().endswith("\n")


BROKEN = {
    "unknown unit": ('R_m = "50 uum"', "[parameters] R_m = '50 uum': unknown unit 'uum'; a length is needed"),
    "negative value": ('R_sigma = "-1 um"', "[parameters] R_sigma = -1e-06 is out of range (valid range: >= 0)"),
    "unknown key": ("Rsigma = 1e-6", "[parameters] unknown key 'Rsigma'"),
    "stress for a length": ('beta = "3 MPa"', "'MPa' is a stress unit; a length is needed"),
}


@pytest.mark.parametrize("case", BROKEN)
def test_broken_scene_one_line_exit_1_and_nothing_lost(case, tmp_path, capsys):
    line, message = BROKEN[case]
    scene = tmp_path / "broken.toml"
    scene.write_text(SMALL.replace('preset = "S1"', f'preset = "S1"\n{line}'))
    out = tmp_path / "result.nc"
    out.write_bytes(b"previous results")
    assert cli.main(["run", str(scene), "-o", str(out)]) == cli.EXIT_INPUT
    err = _one_error_line(capsys.readouterr().err, 1)
    assert message in err and str(scene) in err
    assert out.read_bytes() == b"previous results"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.toml", "result.nc"]


def test_missing_fields(tmp_path, capsys):
    scene = tmp_path / "broken.toml"
    scene.write_text(SMALL.replace('Delta_3 = "0 um"\n[[path', '[[path').replace("increments = 3\nDelta_1 = \"2 um\"\n"
                                                                                  "Delta_2 = \"1 um\"", "Delta_1 = 0"))
    assert cli.main(["run", str(scene)]) == 1
    assert "stage 1: component 3 is missing" in _one_error_line(capsys.readouterr().err, 1)
    scene.write_text(SMALL.replace('preset = "S1"', ""))
    assert cli.main(["run", str(scene)]) == 1
    assert "missing preset" in _one_error_line(capsys.readouterr().err, 1)
    assert not (tmp_path / "broken.nc").exists()


@pytest.mark.parametrize("argv, code, message", [
    (["run", "absent.toml"], 1, "absent.toml: no such file"),
    (["run", "{scene}", "--n", "0"], 2, "argument --n: 0 is out of range (valid range: integer >= 1)"),
    (["run", "{scene}", "--seed", "-3"], 2, "argument --seed: -3 is out of range"),
    (["run", "{scene}", "--n", "many"], 2, "argument --n: 'many' is not an integer"),
    (["run", "{scene}", "-o", "{scene}"], 1, "must end in .nc"),
    (["run", "{scene}", "-o", "result.png"], 1, "output 'result.png' must end in .nc or .nc4"),
    (["info", "absent.nc"], 1, "absent.nc: no such file"),
    (["info", "{scene}"], 1, "not a netCDF file"),
    (["plot", "absent.nc", "-o", "fig.xyz"], 1, "unknown format '.xyz'"),
    (["frobnicate"], 2, "invalid choice: 'frobnicate'"),
    ([], 2, "the following arguments are required: COMMAND"),
    (["sweep", "{scene}", "--serial"], 1, "missing [sweep] table"),
    (["sweep", "{scene}", "--serial", "--scheduler", "tcp://x:1"], 2, "not allowed with argument"),
])
def test_errors_are_one_line_with_exit_code(argv, code, message, tmp_path, monkeypatch, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    monkeypatch.chdir(tmp_path)
    assert cli.main([a.format(scene=scene) for a in argv]) == code
    assert message in _one_error_line(capsys.readouterr().err, code)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small.toml"]


def test_simulation_failure_exit_3_keeps_converged_steps(tmp_path, capsys):
    # stage 2 opens the interface (Delta_1 -> 0) while asking for a shear stress: at Delta_1 = 0 no
    # asperity can touch (theta_m = 0 for r_o = 0, SPEC §3), so sigma_2 = 1 MPa cannot be reached
    scene = tmp_path / "unreachable.toml"
    scene.write_text(SMALL.replace('Delta_1 = "2 um"\nDelta_2 = "1 um"', 'Delta_1 = "0 um"\nsigma_2 = "1 MPa"'))
    out = tmp_path / "run.nc"
    code = cli.main(["run", str(scene), "-o", str(out)])
    line = _one_error_line(capsys.readouterr().err, code)
    assert code == cli.EXIT_FAILED
    assert "run stopped: sigma_2" in line and "cannot be reached" in line and f"written to {out}" in line
    ds = read_netcdf(out)
    assert ds.attrs["status"].startswith("failed") and ds.sizes["step"] >= 4
    assert ds.attrs["scene_file"] == str(scene.resolve())


def test_debug_shows_the_traceback(tmp_path):
    with pytest.raises(ValueError, match="no such file"):
        cli.main(["run", str(tmp_path / "absent.toml"), "--debug"])


def test_console_entry_point_in_a_subprocess(tmp_path):
    scene = tmp_path / "broken.toml"
    scene.write_text(SMALL.replace("n = 400", "n = -400"))
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    bad = subprocess.run([sys.executable, "-m", "asperity_sim", "run", str(scene)], capture_output=True, text=True,
                         cwd=tmp_path, env=env, timeout=120)
    assert bad.returncode == 1 and bad.stdout == ""
    assert bad.stderr.strip() == f"asperity-sim: error: {scene}: [run] n = -400 is out of range " \
                                 "(valid range: integer in [1, 2147483647])"
