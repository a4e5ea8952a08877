"""The asperity-sim command line: every command on the shipped scene files, errors and exit codes."""

import io
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from asperity_sim.ui import cli, exits
from asperity_sim.output.netcdf import read_netcdf

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


def test_presets_print_every_parameter_with_its_unit(capsys):
    import dataclasses
    import re

    from asperity_sim.params import InterfaceParams

    assert cli.main(["presets"]) == 0
    out = capsys.readouterr().out
    blocks = out.split("\n\n")[1:]
    assert [b.splitlines()[0].split(":")[0] for b in blocks] == ["R1", "S1", "R2", "S2"]
    fields = [f.name for f in dataclasses.fields(InterfaceParams)]
    for block in blocks:
        quantities = dict(re.findall(r"^  (\w+) += (\S+ \S+)", block, re.M))
        assert list(quantities) == fields + ["k_e", "E_star", "lam", "mean_plane_depth"]
        assert all(q.split()[1] in ("m", "Pa", "m-2", "[-]") for q in quantities.values()), quantities
    r1 = blocks[0]
    assert "  beta     = 3.52e-06 m       (3.52 um)" in r1 and "  alpha    = 6.14 [-]" in r1
    assert "  N        = 2e+08 m-2" in r1 and "  G        = 8e+10 Pa         (80 GPa)" in r1
    assert f"  E_star   = {80e9 / (1 - 0.3):.6g} Pa" in r1  # G/(1-nu) of R1
    assert cli.main(["presets", "S2"]) == 0
    only = capsys.readouterr().out
    assert "S2: smooth marble interface" in only and "R1:" not in only and "  nu       = 0.152 [-]" in only
    assert cli.main(["presets", "R7"]) == exits.EXIT_INPUT
    assert "preset = 'R7' is not known (valid: R1, S1, R2, S2)" in _one_error_line(capsys.readouterr().err, 1)


class _Terminal(io.StringIO):
    """A text stream that says it is a terminal, to see what the progress bar draws."""

    def isatty(self):
        return True


def test_run_progress_draws_stage_names_and_increments_on_a_terminal_only():
    from asperity_sim import simulate
    from asperity_sim.ui.progress import RunProgress
    from asperity_sim.runs.scene import scene_from_dict, tomllib

    scene = scene_from_dict(tomllib.loads(SMALL))
    term, pipe = _Terminal(), io.StringIO()
    with RunProgress(scene.path, term) as bar, RunProgress(scene.path, pipe) as quiet:
        def both(*args):  # simulate's progress(stage, n_stages, fraction, step, iterations), unchanged
            bar(*args)
            quiet(*args)
        simulate(scene.params, scene.path, n=300, seed=1, progress=both)
        assert bar.bar.n == bar.total == 6
    text = term.getvalue()
    assert "stage 1/2 closure" in text and "stage 2/2 shear" in text and "6/6" in text and "Newton" in text
    assert pipe.getvalue() == ""


def test_count_progress_counts_runs_on_a_terminal_only():
    from asperity_sim.ui.progress import CountProgress

    term, pipe = _Terminal(), io.StringIO()
    for stream in (term, pipe):
        with CountProgress("sweep", stream) as bar:
            for done in (1, 2, 4):
                bar(done, 4)
    assert "sweep" in term.getvalue() and "4/4" in term.getvalue() and pipe.getvalue() == ""


@pytest.mark.slow
def test_piped_run_has_no_progress_and_a_terminal_has_the_bar(tmp_path):
    import pty

    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parent.parent)}
    command = [sys.executable, "-m", "asperity_sim", "run", str(scene)]
    piped = subprocess.run(command + ["-o", str(tmp_path / "piped.nc")], capture_output=True, text=True, env=env,
                           timeout=300)
    assert piped.returncode == 0, piped.stderr
    assert "stage" not in piped.stderr and "\r" not in piped.stderr and "it/s" not in piped.stderr
    master, slave = pty.openpty()
    try:
        tty = subprocess.run(command + ["-o", str(tmp_path / "tty.nc")], stdout=subprocess.PIPE, stderr=slave,
                             env=env, timeout=300)
    finally:
        os.close(slave)
    chunks = []
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # EIO: the terminal's other end is closed and everything was read
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(master)
    drawn = b"".join(chunks).decode("utf-8", "replace")
    assert tty.returncode == 0
    assert "stage 2/2 shear" in drawn and "6/6" in drawn


BROKEN = {
    "unknown unit": ('R_m = "50 uum"', "[parameters] R_m = '50 uum': unknown unit 'uum'; expected a length (m)"),
    "negative value": ('R_sigma = "-1 um"', "[parameters] R_sigma = -1e-06 is out of range (valid range: >= 0)"),
    "unknown key": ("Rsigma = 1e-6", "[parameters] unknown key 'Rsigma'"),
    "stress for a length": ('beta = "3 MPa"', "[parameters] beta = '3 MPa': expected a length (m), got a stress (MPa)"),
}


@pytest.mark.parametrize("case", BROKEN)
def test_broken_scene_one_line_exit_1_and_nothing_lost(case, tmp_path, capsys):
    line, message = BROKEN[case]
    scene = tmp_path / "broken.toml"
    scene.write_text(SMALL.replace('preset = "S1"', f'preset = "S1"\n{line}'))
    out = tmp_path / "result.nc"
    out.write_bytes(b"previous results")
    assert cli.main(["run", str(scene), "-o", str(out)]) == exits.EXIT_INPUT
    err = _one_error_line(capsys.readouterr().err, 1)
    assert message in err and str(scene) in err
    assert out.read_bytes() == b"previous results"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.toml", "result.nc"]


def test_quoted_integer_is_not_an_integer(tmp_path, capsys):
    scene = tmp_path / "quoted.toml"
    scene.write_text(SMALL.replace("n = 400", 'n = "400"'))
    assert cli.main(["run", str(scene)]) == exits.EXIT_INPUT
    line = _one_error_line(capsys.readouterr().err, 1)
    assert line.endswith(f"{scene}: [run] n = '400' is not an integer: write 400 without quotes "
                         "(valid range: integer in [1, 2147483647])")


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
    (["run", "{scene}", "--interaction", "-0.5"], 2, "argument --interaction: -0.5 is out of range (valid range: finite"),
    (["run", "{scene}", "--interaction", "nan"], 2, "argument --interaction: nan is out of range"),
    (["run", "{scene}", "--interaction", "strong"], 2, "argument --interaction: 'strong' is not a number"),
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
    assert code == exits.EXIT_FAILED
    assert "run stopped: sigma_2" in line and "cannot be reached" in line and f"written to {out}" in line
    ds = read_netcdf(out)
    assert ds.attrs["status"].startswith("failed") and ds.sizes["step"] >= 4
    assert ds.attrs["scene_file"] == str(scene.resolve())


def test_debug_shows_the_traceback(tmp_path):
    with pytest.raises(ValueError, match="no such file"):
        cli.main(["run", str(tmp_path / "absent.toml"), "--debug"])


@pytest.mark.slow  # a fresh Python process that imports the package
def test_console_entry_point_in_a_subprocess(tmp_path):
    scene = tmp_path / "broken.toml"
    scene.write_text(SMALL.replace("n = 400", "n = -400"))
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    bad = subprocess.run([sys.executable, "-m", "asperity_sim", "run", str(scene)], capture_output=True, text=True,
                         cwd=tmp_path, env=env, timeout=120)
    assert bad.returncode == 1 and bad.stdout == ""
    assert bad.stderr.strip() == f"asperity-sim: error: {scene}: [run] n = -400 is out of range " \
                                 "(valid range: integer in [1, 2147483647])"


# --------------------------------------------------------------------------- issue 24, item 5

VOLATILE = {"wall_time_s", "wall_time_increment_loop_s", "history", "date_created", "scene_file", "scene"}


def _same_data(a, b, skip=()):
    assert set(a.variables) == set(b.variables)
    for name in a.variables:
        assert np.array_equal(a[name].values, b[name].values, equal_nan=a[name].dtype.kind == "f"), name
    for key in set(a.attrs) - VOLATILE - set(skip):
        assert np.array_equal(np.asarray(a.attrs[key]), np.asarray(b.attrs[key])), key


def test_version(capsys):
    import asperity_sim

    assert cli.main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"asperity-sim {asperity_sim.__version__}"


@pytest.mark.parametrize("file, word", [("../escape.nc", "inside the scene's folder"),
                                        ("sub/../../escape.nc", "without '..'"),
                                        ("/tmp/absolute.nc", "inside the scene's folder")])
def test_scene_output_may_not_leave_the_scene_folder(tmp_path, monkeypatch, capsys, file, word):
    folder = tmp_path / "scenes"
    folder.mkdir()
    scene = folder / "small.toml"
    scene.write_text(SMALL + f'[output]\nfile = "{file}"\n')
    monkeypatch.chdir(tmp_path)
    assert cli.main(["run", str(scene), "--quiet"]) == exits.EXIT_INPUT
    line = _one_error_line(capsys.readouterr().err, 1)
    assert word in line and repr(file) in line and str(scene) in line and "-o" in line
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["scenes", "small.toml"]


def test_scene_output_through_a_symlink_out_of_the_folder_is_refused(tmp_path, capsys):
    folder = tmp_path / "scenes"
    (tmp_path / "elsewhere").mkdir()
    folder.mkdir()
    (folder / "link").symlink_to(tmp_path / "elsewhere")
    scene = folder / "small.toml"
    scene.write_text(SMALL + '[output]\nfile = "link/run.nc"\n')
    assert cli.main(["run", str(scene), "--quiet"]) == exits.EXIT_INPUT
    assert "symbolic link" in _one_error_line(capsys.readouterr().err, 1)
    assert not list((tmp_path / "elsewhere").iterdir())


def test_scene_output_is_resolved_in_the_scene_folder_and_o_goes_anywhere(tmp_path, monkeypatch, capsys):
    folder = tmp_path / "scenes"
    folder.mkdir()
    scene = folder / "small.toml"
    scene.write_text(SMALL + '[output]\nfile = "results/run.nc"\n')
    monkeypatch.chdir(tmp_path)  # not the scene's folder
    assert cli.main(["run", str(scene), "--quiet"]) == 0
    assert (folder / "results" / "run.nc").exists() and not (tmp_path / "results").exists()
    assert cli.main(["run", str(scene), "--quiet", "-o", str(tmp_path / "other" / "x.nc")]) == 0
    assert (tmp_path / "other" / "x.nc").exists()


def test_existing_outputs_are_not_overwritten_without_the_flag(tmp_path, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    out = tmp_path / "run.nc"
    assert cli.main(["run", str(scene), "-o", str(out)]) == 0
    first = out.read_bytes()
    capsys.readouterr()
    assert cli.main(["run", str(scene), "-o", str(out), "--seed", "9"]) == exits.EXIT_INPUT
    line = _one_error_line(capsys.readouterr().err, 1)
    assert f"output '{out}' exists; give --overwrite" in line
    assert out.read_bytes() == first
    assert cli.main(["run", str(scene), "-o", str(out), "--seed", "9", "--overwrite"]) == 0
    assert read_netcdf(out).attrs["seed"] == 9
    fig = tmp_path / "run.png"
    assert cli.main(["plot", str(out)]) == 0
    capsys.readouterr()
    assert cli.main(["plot", str(out)]) == exits.EXIT_INPUT
    assert "figure" in _one_error_line(capsys.readouterr().err, 1)
    assert cli.main(["plot", str(out), "--overwrite"]) == 0 and fig.exists()


@pytest.mark.parametrize("target, word", [("{tmp}", "is a folder"), ("{tmp}/afile/out.nc", "is not a folder"),
                                          ("{tmp}/small.toml", "must end in .nc")])
def test_output_paths_checked_before_any_work(tmp_path, capsys, target, word):
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    (tmp_path / "afile").write_text("x")
    target = target.format(tmp=tmp_path)
    if target == str(tmp_path):
        target = str(tmp_path / "folder.nc")
        (tmp_path / "folder.nc").mkdir()
    before = sorted(p.name for p in tmp_path.rglob("*"))
    assert cli.main(["run", str(scene), "-o", target]) == exits.EXIT_INPUT
    assert word in _one_error_line(capsys.readouterr().err, 1)
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def _foreign(path):
    import xarray as xr

    xr.Dataset({"stress": (("step", "axis"), np.zeros((2, 3))),
                "displacement": (("step", "axis"), np.zeros((2, 3)))},
               coords={"axis": [1, 2, 3]}).to_netcdf(path, engine="netcdf4")
    return path


def test_info_and_plot_on_damaged_or_foreign_files_exit_1_with_one_line(tmp_path, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    good = tmp_path / "good.nc"
    assert cli.main(["run", str(scene), "-o", str(good)]) == 0
    raw = good.read_bytes()
    cut = tmp_path / "cut.nc"
    cut.write_bytes(raw[: len(raw) // 2])
    garbage = tmp_path / "garbage.nc"
    garbage.write_bytes(raw[:8] + bytes(range(256)) * 8)
    foreign = _foreign(tmp_path / "foreign.nc")
    no_stage = tmp_path / "no_stage.nc"
    read_netcdf(good).drop_vars(["stage", "n_slip"]).to_netcdf(no_stage, engine="netcdf4")
    cases = {cut: "not a netCDF file, or a damaged one", garbage: "not a netCDF file, or a damaged one",
             foreign: "missing stress_stderr, displacement_stderr, stage, iterations",
             no_stage: "missing stage, n_slip"}
    for path, word in cases.items():
        for cmd in (["info", str(path)], ["plot", str(path), "-o", str(tmp_path / "f.png")]):
            capsys.readouterr()
            assert cli.main(cmd) == exits.EXIT_INPUT, cmd
            line = _one_error_line(capsys.readouterr().err, 1)
            assert str(path) in line and word in line and "KeyError" not in line, line
    assert not (tmp_path / "f.png").exists()


def _stopped_checkpoint(scene_path, ck, step):
    """The checkpoint a run of the scene leaves when it dies after ``step`` (killed: nothing else written)."""
    from asperity_sim.runs.scene import load_scene

    class Stop(Exception):
        pass

    def progress(stage, n_stages, fraction, s, iterations):
        if s == step:
            raise Stop

    with pytest.raises(Stop):
        load_scene(scene_path).simulate(checkpoint=ck, checkpoint_every=1, progress=progress)


def test_run_checkpoint_then_resume_with_or_without_the_scene_gives_the_same_bits(tmp_path, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    full = tmp_path / "full.nc"
    ck_full = tmp_path / "full.npz"
    assert cli.main(["run", str(scene), "-o", str(full), "--checkpoint", str(ck_full), "--checkpoint-every", "2"]) == 0
    assert ck_full.exists()
    ck = tmp_path / "killed.npz"
    _stopped_checkpoint(scene, ck, 4)
    a, b = tmp_path / "a.nc", tmp_path / "b.nc"
    saved = ck.read_bytes()
    assert cli.main(["run", str(scene), "--resume", str(ck), "-o", str(a)]) == 0
    _same_data(read_netcdf(full), read_netcdf(a))
    assert "resumed from checkpoint" in read_netcdf(a).attrs["history"]
    ck.write_bytes(saved)
    capsys.readouterr()
    assert cli.main(["run", "--resume", str(ck), "-o", str(b)]) == 0
    assert f"wrote {b}: resumed from {ck}" in capsys.readouterr().out
    _same_data(read_netcdf(full), read_netcdf(b), skip=("title",))  # the scene's title is in the scene only


@pytest.mark.parametrize("argv, code, word", [
    (["run", "{scene}", "--checkpoint", "{tmp}/ck.npz", "-o", "{tmp}/o.nc"], 1, "exists (a killed run?); give --resume"),
    (["run", "{scene}", "--resume", "{tmp}/none.npz", "-o", "{tmp}/o.nc"], 1, "no such file (nothing to resume)"),
    (["run", "{scene}", "--resume", "{tmp}/bad.npz", "-o", "{tmp}/o.nc"], 1, "is not a readable asperity_sim checkpoint"),
    (["run", "--resume", "{tmp}/bad.npz", "-o", "{tmp}/o.nc"], 1, "is not a readable asperity_sim checkpoint"),
    (["run", "{scene}", "--checkpoint", "{tmp}/ck.txt"], 1, "must end in .npz"),
    (["run", "{scene}", "--checkpoint-every", "2"], 2, "--checkpoint-every needs --checkpoint"),
    (["run", "{scene}", "--checkpoint", "{tmp}/x.npz", "--checkpoint-every", "0"], 2, "out of range"),
    (["run"], 2, "SCENE.toml (or --resume CK.npz)"),
    (["run", "--resume", "{tmp}/bad.npz", "--n", "5"], 2, "--n, --seed and --interaction need the scene"),
    (["run", "--resume", "{tmp}/bad.npz", "--interaction", "1"], 2, "--n, --seed and --interaction need the scene"),
])
def test_checkpoint_options_errors(tmp_path, capsys, argv, code, word):
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    (tmp_path / "ck.npz").write_bytes(b"an older checkpoint")
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04 damaged")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert cli.main([a.format(scene=scene, tmp=tmp_path) for a in argv]) == code
    line = _one_error_line(capsys.readouterr().err, code)
    assert word in line, line
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_resume_of_another_runs_checkpoint_is_refused(tmp_path, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    ck = tmp_path / "k.npz"
    _stopped_checkpoint(scene, ck, 3)
    assert cli.main(["run", str(scene), "--resume", str(ck), "--seed", "99", "-o", str(tmp_path / "o.nc")]) == 1
    line = _one_error_line(capsys.readouterr().err, 1)
    assert "belongs to another run" in line and "seed" in line


KILLED_CLI = """
import sys, time
from asperity_sim.ui import cli
from asperity_sim.solve import run
orig = run.Run.save_checkpoint
def slow(self, *a, **k):
    orig(self, *a, **k)
    time.sleep(0.3)
run.Run.save_checkpoint = slow
sys.exit(cli.main(sys.argv[1:]))
"""


@pytest.mark.slow
def test_sigkill_of_asperity_sim_run_then_resume_gives_the_same_bits(tmp_path):
    import signal
    import time

    from asperity_sim import __version__
    from asperity_sim.output import checkpoint as ckpt

    scene = tmp_path / "small.toml"
    scene.write_text(SMALL.replace("increments = 3", "increments = 8"))
    ck, out, full = tmp_path / "k.npz", tmp_path / "k.nc", tmp_path / "full.nc"
    child = subprocess.Popen([sys.executable, "-c", KILLED_CLI, "run", str(scene), "-o", str(out), "--checkpoint",
                              str(ck), "--checkpoint-every", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        steps = 0
        while time.monotonic() < deadline and child.poll() is None and steps < 5:
            if ck.exists():
                steps = ckpt.load(ck, __version__)[0]["steps_recorded"]
            time.sleep(0.05)
        assert child.poll() is None, child.communicate()
        os.kill(child.pid, signal.SIGKILL)
        child.wait(30)
    finally:
        if child.poll() is None:
            child.kill()
    assert not out.exists()
    assert cli.main(["run", str(scene), "--resume", str(ck), "-o", str(out)]) == 0
    assert cli.main(["run", str(scene), "-o", str(full)]) == 0
    _same_data(read_netcdf(full), read_netcdf(out))


def test_ctrl_c_keeps_what_converged_with_the_scene_provenance(tmp_path, monkeypatch, capsys):
    from asperity_sim.runs.scene import Scene

    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    out, ck = tmp_path / "run.nc", tmp_path / "run.npz"
    real = Scene.simulate

    def interrupted(self, **kw):
        def progress(stage, n_stages, fraction, step, iterations):
            if step == 4:
                raise KeyboardInterrupt
        return real(self, **{**kw, "progress": progress})

    monkeypatch.setattr(Scene, "simulate", interrupted)
    assert cli.main(["run", str(scene), "-o", str(out), "--checkpoint", str(ck), "--checkpoint-every", "1"]) == 130
    line = _one_error_line(capsys.readouterr().err, 130)
    assert f"the converged increments are in {out}; resume with --resume {ck}" in line
    ds = read_netcdf(out)
    assert ds.attrs["status"].startswith("interrupted") and ds.sizes["step"] >= 4
    assert ds.attrs["scene_file"] == str(scene.resolve()) and ds.attrs["title"] == "small test scene"
    assert "interrupted (Ctrl-C)" in ds.attrs["history"]
    monkeypatch.undo()
    assert cli.main(["run", str(scene), "--resume", str(ck), "-o", str(out), "--overwrite"]) == 0
    full = tmp_path / "full.nc"
    assert cli.main(["run", str(scene), "-o", str(full)]) == 0
    _same_data(read_netcdf(full), read_netcdf(out))


def test_info_reads_the_wall_time_of_new_and_older_files(tmp_path, capsys):
    """Files written before the rename carry ``wall_time_s``; ``info`` reads both names."""
    from asperity_sim.output.netcdf import write_netcdf

    scene = Path(__file__).resolve().parent.parent / "scenarios" / "three_step_S1.toml"
    out = tmp_path / "new.nc"
    assert cli.main(["run", str(scene), "--n", "300", "-o", str(out)]) == 0
    capsys.readouterr()
    ds = read_netcdf(out)
    assert "wall_time_s" not in ds.attrs
    assert cli.main(["info", str(out)]) == 0
    new = capsys.readouterr().out
    assert f"wall time {ds.attrs['wall_time_increment_loop_s']:.2f} s" in new
    old = ds.copy()
    old.attrs = {k: v for k, v in ds.attrs.items() if not k.startswith("wall_time_increment_loop_s")}
    old.attrs["wall_time_s"] = 12.345
    write_netcdf(old, tmp_path / "old.nc")
    assert cli.main(["info", str(tmp_path / "old.nc")]) == 0
    assert "wall time 12.35 s" in capsys.readouterr().out
    assert cli.main(["plot", str(tmp_path / "old.nc")]) == 0



def test_warmup_compiles_a_law_and_says_what_it_did(capsys):
    assert cli.main(["warmup", "--law", "paper"]) == 0
    out = capsys.readouterr().out
    assert "asperity-sim: compiling the paper kernels" in out and "kernels ready for paper in" in out
    assert cli.main(["warmup", "--law", "nosuchlaw"]) == exits.EXIT_USAGE


def test_run_interaction_overrides_the_scene_as_python_would(tmp_path, capsys):
    """--interaction X is [parameters] interaction = X: the run equals simulate with that parameter, bit for bit."""
    import dataclasses

    from asperity_sim.runs.scene import load_scene

    scene = tmp_path / "small.toml"
    scene.write_text(SMALL)
    out0, out1 = tmp_path / "plain.nc", tmp_path / "mean_field.nc"
    assert cli.main(["run", str(scene), "-q", "-o", str(out0)]) == 0
    assert cli.main(["run", str(scene), "-q", "--interaction", "1", "-o", str(out1)]) == 0
    capsys.readouterr()
    plain, mean_field = read_netcdf(out0), read_netcdf(out1)
    assert plain.attrs["param_interaction"] == 0.0 and mean_field.attrs["param_interaction"] == 1.0
    s = load_scene(scene)
    expected = s.replace(params=dataclasses.replace(s.params, interaction=1.0)).simulate()
    np.testing.assert_array_equal(mean_field["stress"].values, expected["stress"].values)
    # Delta_1 is the approach of the surface's mean level, which the contacts' load pushes away from the
    # contacts: they overlap by more than Delta_1 and the same Delta_1 carries more normal stress
    loaded = plain["stress"].values[:, 0] > 0.0
    assert loaded.sum() >= 4
    assert np.all(mean_field["stress"].values[loaded, 0] > plain["stress"].values[loaded, 0])
