"""Nothing lost: atomic outputs, checkpoints, and bit-identical resumption (issue 6, item 4).

A run killed with SIGKILL in a real subprocess and resumed from its last checkpoint must
finish with exactly the data of an uninterrupted run (every data variable equal bit for
bit, and every attribute but the wall time and the history line).  A checkpoint of another
run, another package version or format, or a damaged file is refused with a
``CheckpointError`` (a ``ValueError``) that says why.  A crash while writing never leaves a
truncated file under the final name.
"""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
import zipfile

import numpy as np
import pytest
import xarray as xr

import asperity_sim as asim
from asperity_sim import CheckpointError, paths, Population, presets, simulate
from asperity_sim.output import checkpoint as ckpt
from asperity_sim.output.netcdf import read_netcdf, write_netcdf
from asperity_sim.paths import LoadPath, Stage

VOLATILE = {"wall_time_s", "wall_time_increment_loop_s", "history", "date_created"}  # differ between any two runs


def mixed_path(inc=4):
    """Stress control from zero load, shear at constant sigma_1, an adaptive reversal: every kind of state."""
    S, D = "s", "d"
    return LoadPath((Stage((S, D, D), (300e6, 0, 0), inc, name="normal"),
                     Stage((S, D, D), (300e6, 4e-6, 0), inc, name="shear"),
                     Stage((S, D, D), (300e6, -2e-6, 1e-6), 2 * inc, adaptive=True, max_fraction=0.4,
                           name="reverse")), name="mixed")


def assert_same_run(a, b):
    assert set(a.variables) == set(b.variables)
    for name in a.variables:
        assert a[name].dtype == b[name].dtype, name
        assert np.array_equal(a[name].values, b[name].values, equal_nan=a[name].dtype.kind == "f"), name
    assert set(a.attrs) == set(b.attrs)
    for key in set(a.attrs) - VOLATILE:
        assert np.array_equal(np.asarray(a.attrs[key]), np.asarray(b.attrs[key])), key


class Stop(Exception):
    pass


def stop_at(step_to_stop):
    def progress(stage, n_stages, fraction, step, iterations):
        if step == step_to_stop:
            raise Stop(f"stopped at step {step}")
    return progress


# --------------------------------------------------------------------------- in-process resume


@pytest.mark.parametrize("law, policy", [("paper", "follow"), ("mdr", "follow"), ("paper", "birth"), ("mdr", "birth")])
def test_interrupted_run_resumes_bit_identically(tmp_path, law, policy):
    kw = dict(n=1500, seed=3, law=law, policy=policy, k=8, snapshots=[0, 3, 9])
    full = simulate(presets.S1, mixed_path(), **kw)
    ck = tmp_path / "run.ckpt.npz"
    with pytest.raises(Stop):
        simulate(presets.S1, mixed_path(), checkpoint=ck, checkpoint_every=5, progress=stop_at(7), **kw)
    meta, _ = ckpt.load(ck, asim.__version__)
    assert meta["steps_recorded"] == 8  # the interruption wrote the state after step 7
    out = tmp_path / "resumed.nc"
    resumed = asim.resume(ck, output=out)
    assert_same_run(full, resumed)
    assert_same_run(full, read_netcdf(out))
    assert "resumed from checkpoint" in resumed.attrs["history"]
    # the same through simulate(..., resume=) with the original arguments
    again = simulate(presets.S1, mixed_path(), resume=ck, **kw)
    assert_same_run(full, again)


def test_periodic_checkpoints_resume_from_any_of_them(tmp_path):
    """Every periodic checkpoint of a run (copied aside as it is written) resumes to the same result."""
    kw = dict(n=1200, seed=5, law="mdr", k=6)
    ck = tmp_path / "every.npz"
    copies = {}

    def keep(stage, n_stages, fraction, step, iterations):
        if ck.exists():
            copies[step] = tmp_path / f"copy{step}.npz"
            copies[step].write_bytes(ck.read_bytes())

    full = simulate(presets.R1, mixed_path(3), checkpoint=ck, checkpoint_every=2, progress=keep, **kw)
    assert sorted(copies) == list(range(2, full.sizes["step"]))
    for step in (2, 3, 5, 8):
        meta, _ = ckpt.load(copies[step], asim.__version__)
        assert meta["steps_recorded"] == step - step % 2 + 1  # the last even step (and the initial state)
        assert_same_run(full, asim.resume(copies[step], checkpoint_every=None))


def test_checkpoint_at_stage_ends_by_default(tmp_path):
    ck = tmp_path / "c.npz"
    seen = []

    def progress(stage, n_stages, fraction, step, iterations):
        if ck.exists():
            seen.append(ckpt.load(ck, asim.__version__)[0]["steps_recorded"])

    ds = simulate(presets.S1, mixed_path(2), n=500, seed=1, checkpoint=ck, progress=progress)
    stage = ds.stage.values
    ends = [int(np.flatnonzero(stage == i)[-1]) for i in (1, 2, 3)]
    assert sorted(set(seen)) == [e + 1 for e in ends]  # written after the last step of each stage


def test_resume_of_a_complete_run_returns_it(tmp_path):
    ck = tmp_path / "c.npz"
    full = simulate(presets.S1, mixed_path(2), n=500, seed=1, checkpoint=ck, checkpoint_every=1)
    assert_same_run(full, asim.resume(ck))


# --------------------------------------------------------------------------- SIGKILL in a real subprocess

CHILD = textwrap.dedent("""
    import sys, time
    import asperity_sim as asim
    from asperity_sim import presets
    sys.path.insert(0, {here!r})
    from test_checkpoint import mixed_path

    def slow(*args):
        time.sleep(0.15)

    asim.simulate(presets.R1, mixed_path(6), n=2000, seed=9, law={law!r}, k=8, checkpoint={ck!r},
                  checkpoint_every=2, output={out!r}, progress=slow)
""")


@pytest.mark.slow
@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_sigkill_then_resume_is_bit_identical(tmp_path, law):
    ck, out = tmp_path / "kill.npz", tmp_path / "kill.nc"
    code = CHILD.format(here=os.path.dirname(__file__), law=law, ck=str(ck), out=str(out))
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        steps = 0
        while time.monotonic() < deadline and child.poll() is None:
            if ck.exists():
                steps = ckpt.load(ck, asim.__version__)[0]["steps_recorded"]
                if steps >= 7:
                    break
            time.sleep(0.05)
        assert child.poll() is None, child.communicate()  # still running: the kill interrupts real work
        os.kill(child.pid, signal.SIGKILL)
        child.wait(30)
    finally:
        if child.poll() is None:
            child.kill()
    assert child.returncode == -signal.SIGKILL
    assert steps >= 7
    assert not out.exists()  # the run never finished
    resumed = asim.resume(ck, output=out)
    full = simulate(presets.R1, mixed_path(6), n=2000, seed=9, law=law, k=8)
    assert ckpt.load(ck, asim.__version__)[0]["steps_recorded"] > steps  # the resumed run kept checkpointing
    assert_same_run(full, resumed)
    assert_same_run(full, read_netcdf(out))
    assert not list(tmp_path.glob(".kill.nc.*"))


# --------------------------------------------------------------------------- refusing checkpoints


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    ck = tmp_path_factory.mktemp("ck") / "saved.npz"
    with pytest.raises(Stop):
        simulate(presets.S1, mixed_path(2), n=400, seed=2, law="mdr", k=4, checkpoint=ck, checkpoint_every=1,
                 progress=stop_at(3))
    return ck


@pytest.mark.parametrize("change, word", [
    ({"params": presets.S1.replace(mu=0.5)}, "params.mu"),
    ({"params": presets.R1}, "params."),
    ({"n": 401}, "n:"), ({"seed": 3}, "seed"), ({"sampler": "sobol"}, "sampler"),
    ({"law": "paper"}, "law"), ({"policy": "birth"}, "policy"), ({"k": 5}, "k:"),
    ({"path": mixed_path(3)}, "path."), ({"settings": asim.SolverSettings(rtol=1e-9)}, "settings.rtol"),
    ({"snapshots": "stage_ends"}, "snapshots"),
])
def test_checkpoint_of_another_run_is_refused(saved, change, word):
    args = dict(params=presets.S1, path=mixed_path(2), n=400, seed=2, law="mdr", k=4)
    args.update(change)
    with pytest.raises(CheckpointError) as exc:
        simulate(args.pop("params"), args.pop("path"), resume=saved, **args)
    assert isinstance(exc.value, ValueError)
    assert "another run" in str(exc.value) and word in str(exc.value)


def test_checkpoint_with_another_population_is_refused(saved):
    pop = Population.sample(presets.S1, 400, seed=2)
    pop.r[0] += 1e-12  # same size, seed and sampler, but not the checkpoint's asperities
    with pytest.raises(CheckpointError, match="another population"):
        simulate(presets.S1, mixed_path(2), law="mdr", k=4, population=pop, resume=saved)


def rewrite_meta(src, dst, **changes):
    with np.load(src, allow_pickle=False) as z:
        arrays = {name: z[name] for name in z.files}
    meta = json.loads(str(arrays.pop("meta")))
    meta.update(changes)
    np.savez(dst, meta=np.array(json.dumps(meta)), **arrays)


@pytest.mark.parametrize("field, value, word", [("version", "0.0.1", "written by asperity_sim '0.0.1'"),
                                                 ("format", 99, "format 99")])
def test_checkpoint_of_another_version_or_format_is_refused(saved, tmp_path, field, value, word):
    bad = tmp_path / "other.npz"
    rewrite_meta(saved, bad, **{field: value})
    with pytest.raises(CheckpointError, match=word):
        asim.resume(bad)
    with pytest.raises(CheckpointError, match=word):
        simulate(presets.S1, mixed_path(2), n=400, seed=2, law="mdr", k=4, resume=bad)


def test_damaged_or_missing_checkpoint_is_refused(saved, tmp_path):
    data = saved.read_bytes()
    cut = tmp_path / "cut.npz"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(CheckpointError, match="not a readable"):
        asim.resume(cut)
    with pytest.raises(CheckpointError, match="does not exist"):
        asim.resume(tmp_path / "nothing.npz")
    flipped = tmp_path / "flipped.npz"
    with zipfile.ZipFile(saved) as z:
        info = z.getinfo("state_law0.npy")
    raw = bytearray(data)
    raw[info.header_offset + 200] ^= 0xFF  # inside the spring array: the member's CRC no longer matches
    flipped.write_bytes(bytes(raw))
    with pytest.raises(CheckpointError):
        asim.resume(flipped)
    no_meta = tmp_path / "plain.npz"
    np.savez(no_meta, a=np.zeros(3))
    with pytest.raises(CheckpointError, match="not an asperity_sim checkpoint"):
        asim.resume(no_meta)


@pytest.mark.parametrize("kw, word", [
    ({"checkpoint_every": 0}, "checkpoint_every"), ({"checkpoint_every": 2.5}, "checkpoint_every"),
    ({"checkpoint_every": True}, "checkpoint_every"), ({"checkpoint_every": 3}, "needs a checkpoint file"),
    ({"checkpoint": 5}, "checkpoint"), ({"checkpoint": ""}, "checkpoint"), ({"resume": 1.0}, "resume"),
    ({"max_wall_time": 0.0}, "max_wall_time"), ({"max_wall_time": float("nan")}, "max_wall_time"),
    ({"max_wall_time": "1"}, "max_wall_time"),
])
def test_bad_checkpoint_arguments_raise_value_error(kw, word):
    with pytest.raises(ValueError, match=word):
        simulate(presets.S1, mixed_path(2), n=100, **kw)


# --------------------------------------------------------------------------- atomic writes


def test_failed_checkpoint_write_keeps_the_previous_one(saved, tmp_path, monkeypatch):
    ck = tmp_path / "keep.npz"
    ck.write_bytes(saved.read_bytes())
    before = ck.read_bytes()

    def broken(fh, **arrays):
        fh.write(b"PK\x03\x04 half a checkpoint")
        raise OSError("disk full")

    monkeypatch.setattr(ckpt.np, "savez", broken)
    with pytest.raises(OSError, match="disk full"):
        ckpt.save(ck, meta={"version": "x"}, arrays={"a": np.zeros(2)})
    assert ck.read_bytes() == before
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_failed_netcdf_write_leaves_no_file_under_the_final_name(tmp_path, monkeypatch):
    ds = simulate(presets.S1, paths.three_step(6e-6, increments=2), n=300, seed=1)
    out = tmp_path / "out.nc"

    def broken(self, path, *a, **k):
        with open(path, "wb") as fh:
            fh.write(b"\x89HDF\r\n\x1a\n truncated")
        raise OSError("killed mid-write")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", broken)
    with pytest.raises(OSError, match="mid-write"):
        write_netcdf(ds, out)
    assert not out.exists()
    assert not list(tmp_path.iterdir())
    # over an existing complete file: the old file survives intact
    monkeypatch.undo()
    write_netcdf(ds, out)
    good = out.read_bytes()
    monkeypatch.setattr(xr.Dataset, "to_netcdf", broken)
    with pytest.raises(OSError):
        write_netcdf(ds, out)
    assert out.read_bytes() == good


WRITER = textwrap.dedent("""
    import numpy as np, xarray as xr
    from asperity_sim.output.netcdf import write_netcdf
    ds = xr.Dataset({{"x": (("a", "b"), np.arange(3_000_000, dtype="f8").reshape(3000, 1000) % 977.0)}})
    print("ready", flush=True)
    while True:
        write_netcdf(ds, {out!r})
""")


@pytest.mark.slow
def test_sigkill_during_netcdf_writes_never_leaves_a_truncated_final_file(tmp_path):
    out = tmp_path / "big.nc"
    expected = np.arange(3_000_000, dtype="f8").reshape(3000, 1000) % 977.0
    for delay in (0.3, 0.9, 1.7):
        child = subprocess.Popen([sys.executable, "-c", WRITER.format(out=str(out))], stdout=subprocess.PIPE)
        assert child.stdout.readline().strip() == b"ready"
        time.sleep(delay)
        os.kill(child.pid, signal.SIGKILL)
        child.wait(30)
        if out.exists():  # either absent or complete, never truncated
            with xr.open_dataset(out, engine="netcdf4") as back:
                assert np.array_equal(back["x"].values, expected)
