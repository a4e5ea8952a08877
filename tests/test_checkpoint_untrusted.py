"""Untrusted checkpoints (issue 24, item 3): every malformed file raises CheckpointError naming it.

A checkpoint is hostile input.  Whatever the damage -- bit flips, truncation, members forged
with a valid zip checksum, impossible headers, compressed or encrypted members, bad JSON --
:func:`asperity_sim.output.checkpoint.load` and :func:`asperity_sim.resume` raise a
:class:`~asperity_sim.CheckpointError` that names the file, never ``NotImplementedError``,
``TokenError``, ``RuntimeError``, ``LZMAError``, ``MemoryError``, a raw ``KeyError`` or a
segfault; a harmless flip (in a part of the zip nobody reads) resumes to the same bits.
:func:`~asperity_sim.output.checkpoint.require` is the check the driver calls on every array before a
kernel sees it.  No temporary file survives a failed or killed write.

The property tests build one real checkpoint per law (``simulate(..., checkpoint=)``, n = 200)
and corrupt it by the thousand.  The forged-array cases resume in a child process (a forged
array that reached a kernel could crash the interpreter); they rely on
:mod:`asperity_sim.solve.run_checkpoint` calling :func:`require` on every array before any kernel sees it.
"""

import io
import json
import os
import signal
import subprocess
import sys
import textwrap
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support import forge, study

import asperity_sim as asim
from asperity_sim import CheckpointError, presets, simulate
from asperity_sim.output import checkpoint as ckpt
from asperity_sim.solve import run_checkpoint
from asperity_sim.paths import LoadPath, Stage

# the byte-level tools of damaged files, shared with the stability study's hostile inputs (studies/)
_files = study("damaged_checkpoints")
members, meta_bytes, npy_bytes, same_run, write_zip = (_files.members, _files.meta_bytes, _files.npy_bytes,
                                                       _files.same_run, _files.write_zip)

N = 200


def tiny_path():
    S, D = "s", "d"
    return LoadPath((Stage((S, D, D), (300e6, 0, 0), 3, name="normal"),
                     Stage((S, D, D), (300e6, 4e-6, 0), 3, name="shear"),
                     Stage((S, D, D), (300e6, -2e-6, 1e-6), 4, adaptive=True, max_fraction=0.5, name="reverse")),
                    name="tiny")


def run_kw(law):
    return dict(n=N, seed=4, law=law, k=4, snapshots=[0, 4])


class Stop(Exception):
    pass


def stop_at(step_to_stop):
    def progress(stage, n_stages, fraction, step, iterations):
        if step == step_to_stop:
            raise Stop(step)
    return progress


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """{law: (checkpoint bytes, uninterrupted dataset)} from a tiny run stopped at step 5."""
    out = {}
    folder = tmp_path_factory.mktemp("untrusted")
    for law in ("paper", "mdr"):
        ck = folder / f"{law}.npz"
        with pytest.raises(Stop):
            simulate(presets.S1, tiny_path(), checkpoint=ck, checkpoint_every=1, progress=stop_at(5), **run_kw(law))
        full = simulate(presets.S1, tiny_path(), **run_kw(law))
        assert same_run(full, asim.resume(_copy(ck, folder / f"{law}-check.npz")))  # the intact file resumes
        out[law] = (ck.read_bytes(), full)
    return out


def _copy(src, dst):
    dst.write_bytes(src.read_bytes())
    return dst


def good_meta(config=None):
    cfg = config or {"params": presets.S1.as_dict(), "n": 3, "seed": 0, "sampler": "random", "law": "paper",
                     "policy": "follow", "law_options": {}, "path": {"name": "x", "stages": [{}]}, "settings": {},
                     "snapshots": []}
    return {"format": ckpt.FORMAT, "version": asim.__version__, "config": cfg}


def refused(path, *words):
    with pytest.raises(CheckpointError) as exc:
        ckpt.load(path, asim.__version__)
    text = str(exc.value)
    assert repr(str(path)) in text, text  # names the file
    for w in words:
        assert w in text, text
    return text


# --------------------------------------------------------------------------- load: hand-made damage


def test_compressed_members_are_refused_not_decompressed(tmp_path):
    """A forged member claiming LZMA, bzip2 or deflate (valid CRC) raised LZMAError & co. before."""
    parts = {"meta.npy": meta_bytes(good_meta()), "a.npy": npy_bytes(np.zeros(1000))}
    for method in (zipfile.ZIP_DEFLATED, zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA):
        refused(write_zip(tmp_path / f"c{method}.npz", parts, method), "compressed")


def test_unknown_compression_method_and_corrupt_lzma_stream(tmp_path):
    good = write_zip(tmp_path / "lz.npz", {"meta.npy": meta_bytes(good_meta()), "a.npy": npy_bytes(np.arange(99.))},
                     zipfile.ZIP_LZMA)
    raw = bytearray(good.read_bytes())
    # method field of every local header and central record -> 99 (unsupported: NotImplementedError in zipfile)
    for sig, off in ((b"PK\x03\x04", 8), (b"PK\x01\x02", 10)):
        i = raw.find(sig)
        while i >= 0:
            raw[i + off:i + off + 2] = (99).to_bytes(2, "little")
            i = raw.find(sig, i + 4)
    bad = tmp_path / "m99.npz"
    bad.write_bytes(bytes(raw))
    refused(bad)


def test_header_asking_for_terabytes_is_refused_without_allocating(tmp_path):
    header = npy_bytes(np.zeros(3))
    forged = header.replace(b"(3,)", b"(10000000000000,)")
    refused(write_zip(tmp_path / "huge.npz", {"meta.npy": meta_bytes(good_meta()), "a.npy": forged}), "bytes")


BAD_NPY = {
    "object dtype": b"\x93NUMPY\x01\x00v\x00{'descr': '|O', 'fortran_order': False, 'shape': (2,), }" + b" " * 54
                    + b"\n" + b"\0" * 16,
    "structured dtype": npy_bytes(np.zeros(2, dtype=[("a", "f8"), ("b", "i4")])),
    "complex dtype": npy_bytes(np.zeros(2, dtype=complex)),
    "unterminated header": b"\x93NUMPY\x01\x00\x46\x00{'descr': '<f8', 'fortran_order': False, 'shape': (3,\n",
    "header of garbage": b"\x93NUMPY\x01\x00\x10\x00((((((((((((((((\n",
    "not npy": b"hello world, not an array",
    "format 9": b"\x93NUMPY\x09\x00" + npy_bytes(np.zeros(1))[8:],
    "short data": npy_bytes(np.zeros(10))[:-8],
    "long data": npy_bytes(np.zeros(10)) + b"\0" * 8,
    "negative shape": npy_bytes(np.zeros(3)).replace(b"(3,)", b"(-3,)"),
}


@pytest.mark.parametrize("what", sorted(BAD_NPY))
def test_malformed_npy_members_are_refused(tmp_path, what):
    path = write_zip(tmp_path / "bad.npz", {"meta.npy": meta_bytes(good_meta()), "x.npy": BAD_NPY[what]})
    refused(path)


BAD_META = {
    "deep nesting (RecursionError)": "[" * 200_000,
    "not json": "{'format': 1",
    "a list": "[1, 2, 3]",
    "no config": json.dumps({"format": ckpt.FORMAT, "version": asim.__version__}),
    "config not a dict": json.dumps({**good_meta(), "config": [1]}),
    "config lacks keys": json.dumps({**good_meta(), "config": {"n": 3}}),
    "config n a string": json.dumps({**good_meta(), "config": {**good_meta()["config"], "n": "3"}}),
    "params not numbers": json.dumps({**good_meta(), "config": {**good_meta()["config"], "params": {"N": "x"}}}),
    "no stages": json.dumps({**good_meta(), "config": {**good_meta()["config"], "path": {"stages": 5}}}),
}


@pytest.mark.parametrize("what", sorted(BAD_META))
def test_malformed_meta_is_refused(tmp_path, what):
    path = write_zip(tmp_path / "meta.npz", {"meta.npy": npy_bytes(np.array(BAD_META[what]))})
    refused(path)


def test_meta_of_the_wrong_type_and_other_oddities(tmp_path):
    refused(write_zip(tmp_path / "m1.npz", {"meta.npy": npy_bytes(np.zeros(3))}), "meta")
    refused(write_zip(tmp_path / "m2.npz", {"a.npy": npy_bytes(np.zeros(3))}), "no 'meta' record")
    refused(write_zip(tmp_path / "m3.npz", {"meta.npy": meta_bytes(good_meta()), "notes.txt": b"hi"}), "not a .npy")
    dup = tmp_path / "dup.npz"
    with pytest.warns(UserWarning):  # zipfile warns about the duplicate name
        with zipfile.ZipFile(dup, "w") as z:
            z.writestr("meta.npy", meta_bytes(good_meta()))
            z.writestr("a.npy", npy_bytes(np.zeros(2)))
            z.writestr("a.npy", npy_bytes(np.ones(2)))
    refused(dup, "twice")
    (tmp_path / "empty.npz").write_bytes(b"")
    refused(tmp_path / "empty.npz", "not a readable")
    (tmp_path / "text.npz").write_bytes(b"PK\x05\x06" + b"\0" * 18)  # an empty zip
    refused(tmp_path / "text.npz", "no 'meta' record")


def test_a_valid_hand_made_checkpoint_loads(tmp_path):
    path = write_zip(tmp_path / "ok.npz", {"meta.npy": meta_bytes(good_meta()), "a.npy": npy_bytes(np.arange(4.0)),
                                           "f.npy": npy_bytes(np.asfortranarray(np.arange(6.0).reshape(2, 3)))})
    meta, arrays = ckpt.load(path, asim.__version__)
    assert meta["config"]["n"] == 3
    assert np.array_equal(arrays["a"], np.arange(4.0)) and arrays["a"].flags.writeable
    assert np.array_equal(arrays["f"], np.arange(6.0).reshape(2, 3))
    assert arrays.path == str(path)


# --------------------------------------------------------------------------- require and guard


def test_require_accepts_and_returns_a_valid_array():
    arrays = ckpt.Arrays("run.npz", {"r": np.array([0.0, 1e-6, 2e-6]), "i": np.array([0, 3, 1], dtype=np.int32),
                                     "t": np.array([np.nan, 0.2])})
    assert ckpt.require(arrays, "r", shape=(3,), dtype=np.float64, lo=0.0, sorted=True) is arrays["r"]
    assert ckpt.require(arrays, "i", shape=(None,), dtype=np.int32, lo=0, hi=3) is arrays["i"]
    assert ckpt.require(arrays, "t", shape=(2,), finite=False, lo=0.0, hi=np.pi / 2) is arrays["t"]


@pytest.mark.parametrize("array, kw, words", [
    (np.array([0.0, 2.0, 1.0]), dict(sorted=True), ["array x", "not sorted", "element (2,) = 1.0 < element (1,) = 2.0"]),
    (np.array([0.0, np.nan]), dict(), ["array x", "nan at index (1,)", "finite"]),
    (np.array([0.0, np.inf]), dict(), ["inf at index (1,)"]),
    (np.array([-1.0, 1.0]), dict(lo=0.0), ["-1.0 at index (0,)", "valid range: [0.0, inf)"]),
    (np.array([0.0, 1.0]), dict(lo=0.0, lo_open=True), ["0.0 at index (0,)", "valid range: (0.0, inf)"]),
    (np.array([0, 7], dtype=np.int32), dict(lo=0, hi=4), ["7 at index (1,)", "valid range: [0, 4]"]),
    (np.zeros(3), dict(shape=(4,)), ["shape (3,), expected (4,)"]),
    (np.zeros((3, 2)), dict(shape=(None, 3)), ["shape (3, 2), expected (any, 3)"]),
    (np.zeros(3, dtype=np.float32), dict(dtype=np.float64), ["dtype <f4, expected <f8"]),
    (np.zeros(3, dtype=">f8"), dict(dtype=np.float64), ["dtype >f8"]),
    (np.array(["a"]), dict(lo=0), ["numeric"]),
])
def test_require_names_file_array_value_and_range(array, kw, words):
    with pytest.raises(CheckpointError) as exc:
        ckpt.require(ckpt.Arrays("/tmp/run.npz", {"x": array}), "x", **kw)
    text = str(exc.value)
    assert text.startswith("checkpoint '/tmp/run.npz': array x"), text
    for w in words:
        assert w in text, text


def test_require_missing_array_and_plain_dict():
    with pytest.raises(CheckpointError, match="'f.npz': array y is missing"):
        ckpt.require({"x": np.zeros(1)}, "y", path="f.npz")


def test_guard_turns_mapping_errors_into_checkpoint_errors():
    from asperity_sim import Population

    for exc in (KeyError("pop_r"), IndexError("3"), TypeError("x"), ValueError("bad")):
        with pytest.raises(CheckpointError, match="'c.npz' is incomplete or damaged"):
            with ckpt.guard("c.npz"):
                raise exc
    pop = Population.sample(presets.S1, 10, seed=1)
    with pytest.raises(CheckpointError, match="not sorted"):
        with ckpt.guard("c.npz"):
            Population(params=pop.params, r=pop.r[::-1].copy(), R=pop.R, u=pop.u, cos_phi=pop.cos_phi,
                       sin_phi=pop.sin_phi, weight=pop.weight, seed=None, sampler="given")


# --------------------------------------------------------------------------- temporaries


KILLED_WRITER = textwrap.dedent("""
    import os, signal, numpy as np
    from asperity_sim import checkpoint as ckpt
    def die(*a, **k):
        os.kill(os.getpid(), signal.SIGKILL)  # killed between the full write and the rename
    ckpt.os.replace = die
    ckpt.save({path!r}, meta={{"version": "x"}}, arrays={{"a": np.zeros(1000)}})
""")


@pytest.mark.slow  # a writer killed in a fresh Python process
def test_temporaries_of_a_killed_write_are_removed_by_the_next_save(tmp_path):
    target = tmp_path / "run.npz"
    ckpt.save(target, meta={"version": "x"}, arrays={"a": np.ones(3)})
    before = target.read_bytes()
    child = subprocess.run([sys.executable, "-c", KILLED_WRITER.format(path=str(target))], capture_output=True)
    assert child.returncode == -signal.SIGKILL, child.stderr
    stale = [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
    assert len(stale) == 1 and stale[0].name.startswith(".run.npz.")  # the kill left its temporary ...
    assert target.read_bytes() == before  # ... and the checkpoint intact
    # another live process's temporary of the same checkpoint, and an unrelated file, are left alone
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        other = tmp_path / f".run.npz.{live.pid}.abcd1234.tmp"
        other.write_bytes(b"in progress")
        unrelated = tmp_path / ".other.npz.1.x.tmp"
        unrelated.write_bytes(b"x")
        ckpt.save(target, meta={"version": "x"}, arrays={"a": np.full(3, 2.0)})
        left = sorted(p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp"))
        assert left == sorted([other.name, unrelated.name])
    finally:
        live.kill()
        live.wait()
    ckpt.save(target, meta={"version": "x"}, arrays={"a": np.full(3, 3.0)})  # the writer is gone now
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")) == [unrelated.name]
    with np.load(target) as z:
        assert np.array_equal(z["a"], np.full(3, 3.0))


def test_failed_write_leaves_no_temporary_and_keeps_the_old_file(tmp_path, monkeypatch):
    target = tmp_path / "run.npz"
    ckpt.save(target, meta={"version": "x"}, arrays={"a": np.ones(3)})
    before = target.read_bytes()
    for exc in (OSError("disk full"), KeyboardInterrupt()):
        def broken(fh, **arrays):
            fh.write(b"PK\x03\x04 half")
            raise exc
        monkeypatch.setattr(ckpt.np, "savez", broken)
        with pytest.raises(type(exc)):
            ckpt.save(target, meta={"version": "x"}, arrays={"a": np.zeros(2)})
        assert target.read_bytes() == before
        assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


# --------------------------------------------------------------------------- property tests on real checkpoints


def resume_outcome(path, full):
    """'error' (CheckpointError naming the file), 'same' (the uninterrupted run's bits) or a failure text."""
    try:
        ds = asim.resume(path, checkpoint_every=None)
    except CheckpointError as err:
        return "error" if repr(str(path)) in str(err) else f"CheckpointError without the file name: {err}"
    except Exception as err:  # noqa: BLE001 - the property: nothing else may escape
        return f"{type(err).__name__}: {err}"
    return "same" if same_run(full, ds) else "resumed to a different result"


@pytest.mark.slow
@pytest.mark.parametrize("law", ["paper", "mdr"])
@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                   HealthCheck.too_slow])
@given(data=st.data())
def test_bit_flips_raise_checkpoint_error_or_resume_identically(saved, tmp_path, law, data):
    raw, full = saved[law]
    buf = bytearray(raw)
    for _ in range(data.draw(st.integers(1, 4), label="flips")):
        pos = data.draw(st.integers(0, len(buf) - 1), label="byte")
        buf[pos] ^= 1 << data.draw(st.integers(0, 7), label="bit")
    path = tmp_path / "flipped.npz"
    path.write_bytes(bytes(buf))
    assert resume_outcome(path, full) in ("error", "same")


@pytest.mark.slow
@pytest.mark.parametrize("law", ["paper", "mdr"])
@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                   HealthCheck.too_slow])
@given(data=st.data())
def test_truncations_raise_checkpoint_error(saved, tmp_path, law, data):
    raw, full = saved[law]
    cut = data.draw(st.integers(0, len(raw) - 1), label="length")
    path = tmp_path / "cut.npz"
    path.write_bytes(raw[:cut])
    assert resume_outcome(path, full) == "error"


def test_some_single_flips_resume_identically_and_most_are_refused(saved, tmp_path):
    """Not a vacuous property: flips in unread zip fields (timestamps) resume to the same bits."""
    raw, full = saved["paper"]
    _, infos = members(raw)
    path = tmp_path / "f.npz"
    info = infos[1]
    buf = bytearray(raw)
    buf[info.header_offset + 10] ^= 0x01  # local header: modification time
    path.write_bytes(bytes(buf))
    assert resume_outcome(path, full) == "same"
    buf = bytearray(raw)
    buf[info.header_offset + 30 + len(info.filename) + 200] ^= 0x10  # member data: CRC mismatch
    path.write_bytes(bytes(buf))
    assert resume_outcome(path, full) == "error"


# forged arrays with a valid zip (support.forge): the same member names, rewritten contents ----

CASE_TIMEOUT = 10.0  # s per forged file: an intact run of this size resumes in well under a second
CHILD = textwrap.dedent("""
    import faulthandler, json, pickle, sys
    faulthandler.enable()
    sys.path.insert(0, {here!r})
    import asperity_sim as asim
    from test_checkpoint_untrusted import resume_outcome
    full = pickle.loads(open({full!r}, "rb").read())
    for line in sys.stdin:
        path = line.strip()
        print(json.dumps([path, resume_outcome(path, full)]), flush=True)
""")


def forged_outcomes(saved, folder, law, cases):
    """Write every forged file, resume each in one child process; {case: outcome} (a crash is an outcome too)."""
    import pickle

    raw, full = saved[law]
    with zipfile.ZipFile(io.BytesIO(raw)) as z:
        arrays = {info.filename[:-4]: np.load(io.BytesIO(z.read(info)), allow_pickle=False) for info in z.infolist()}
    files = {}
    for k, (name, how, seed) in enumerate(cases):
        forged = forge(arrays, name, how, np.random.default_rng(seed))
        if forged is False:
            continue
        parts = {f"{n}.npy": npy_bytes(forged if n == name else a) for n, a in arrays.items()
                 if not (n == name and forged is None)}
        files[str(write_zip(folder / f"forged{k}.npz", parts))] = (name, how)
    (folder / "full.pkl").write_bytes(pickle.dumps(full))
    return _resume_each(files, folder / "full.pkl")


def _resume_each(files, full_pickle, per_file=CASE_TIMEOUT):
    """Resume every file in a child process, one at a time; a crash or a hang (> per_file s) is an outcome too."""
    import select

    todo, out = list(files), {}
    code = CHILD.format(here=os.path.dirname(__file__), full=str(full_pickle))
    child = None
    try:
        while todo:
            if child is None or child.poll() is not None:
                child = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                         stderr=subprocess.DEVNULL, text=True, bufsize=1)
                first = True
            path = todo.pop(0)
            child.stdin.write(path + "\n")
            child.stdin.flush()
            # the first file of a child waits for its start-up (imports, numba cache) as well
            ready, _, _ = select.select([child.stdout], [], [], per_file + (60 if first else 0))
            first = False
            line = child.stdout.readline() if ready else ""
            if line.startswith("["):
                out[files[path]] = json.loads(line)[1]
                continue
            if not ready:
                child.kill()
                out[files[path]] = f"hang: no answer within {per_file} s"
            else:
                child.wait(30)
                out[files[path]] = f"child process died (return code {child.returncode})"
            child = None
    finally:
        if child is not None:
            child.stdin.close()
            child.kill()
            child.wait(30)
    return out


# Forgeries that break an invariant whatever the array means: shape, dtype, a missing array, and
# non-finite values where the genuine file has none; plus range forgeries where the range is known
# (docs/robustness.md).  A forgery that stays valid (a finite array reversed, say) cannot be told from
# the file alone -- there is no secret to sign it with -- and is not asked for here.
ALWAYS = ("shorter", "longer", "flat", "float32", "to_int", "to_float", "scalar", "drop")
RANGE = {"pop_r": ("reverse", "negative"), "pop_R": ("negative",), "pop_u": ("huge", "negative"),
         "pop_cos_phi": ("huge",), "pop_sin_phi": ("huge",), "ev_ints": ("negative", "huge"),
         "pos_i": ("negative", "huge"), "energy_coarsenings": ("negative",), "energy_transitions": ("negative",)}
NAN_MEANS_UNSET = {"pos_prev", "pos_older", "state_theta_birth"}  # NaN is a legal value there ("no previous point", "not born")


def invalid_forgeries(arrays):
    """(name, how) pairs that every correct reader must refuse."""
    out = []
    for name, a in arrays.items():
        hows = list(ALWAYS) + list(RANGE.get(name, ()))
        if a.dtype.kind == "f" and np.all(np.isfinite(a)) and name not in NAN_MEANS_UNSET:
            hows += ["nan", "inf"]
        out += [(name, how) for how in hows]
    return out


@pytest.mark.slow
@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_forged_arrays_raise_checkpoint_error_or_resume_identically(saved, tmp_path, law):
    raw, _ = saved[law]
    with zipfile.ZipFile(io.BytesIO(raw)) as z:
        arrays = {i.filename[:-4]: np.load(io.BytesIO(z.read(i)), allow_pickle=False) for i in z.infolist()
                  if i.filename != "meta.npy"}
    rng = np.random.default_rng(24)
    cases = [(name, how, int(rng.integers(2**31))) for name, how in invalid_forgeries(arrays)]
    outcomes = forged_outcomes(saved, tmp_path, law, cases)
    assert len(outcomes) > 200
    bad = {f"{name} ({how})": o for (name, how), o in outcomes.items() if o not in ("error", "same")}
    assert not bad, f"{len(bad)} of {len(outcomes)} forged files: " + "; ".join(f"{k}: {v}" for k, v in
                                                                                 sorted(bad.items())[:40])


@pytest.mark.slow
@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_forged_population_arrays_never_reach_a_kernel(saved, tmp_path, law):
    """Population.__post_init__ refuses them: unsorted heights, NaN, R <= 0, u > pi/2, (cos, sin) off the circle.

    Only forgeries that break an invariant: a valid but different population (R reversed, say) cannot be
    told from the file alone; the driver has to compare it with ``Population.sample`` of the stored seed.
    """
    invalid = {"pop_r": ("nan", "inf", "negative", "reverse", "float32", "to_int", "shorter"),
               "pop_R": ("nan", "inf", "negative", "float32", "to_int", "longer"),
               "pop_u": ("nan", "negative", "huge", "float32"),
               "pop_cos_phi": ("nan", "huge", "negative", "float32"),
               "pop_sin_phi": ("nan", "inf", "huge", "negative")}
    cases = [(name, how, 7) for name, hows in invalid.items() for how in hows]
    outcomes = forged_outcomes(saved, tmp_path, law, cases)
    crashed = {k: v for k, v in outcomes.items() if v.startswith("child process died") or v.startswith("resumed")}
    assert not crashed, crashed
    wrong = {k: v for k, v in outcomes.items() if v not in ("error", "same")}
    assert not wrong, wrong


def test_netcdf_temporaries_of_a_killed_write_are_removed_by_the_next_write(tmp_path):
    import xarray as xr

    from asperity_sim.output.netcdf import write_netcdf

    out = tmp_path / "run.nc"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = tmp_path / f".run.nc.{int(dead.stdout)}.k3j4.tmp"  # what a SIGKILL mid-write leaves
    stale.write_bytes(b"\x89HDF half a file")
    write_netcdf(xr.Dataset({"x": ("a", np.arange(3.0))}), out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.nc"]


def test_overlapping_members_cannot_multiply_the_memory(tmp_path):
    """Central-directory entries pointing at the same data (a zip bomb without compression) are refused."""
    path = write_zip(tmp_path / "one.npz", {"meta.npy": meta_bytes(good_meta()), "a.npy": npy_bytes(np.zeros(4096))})
    raw = bytearray(path.read_bytes())
    cd = raw.find(b"PK\x01\x02", raw.find(b"a.npy") + 5)  # the central record of a.npy (after its local header)
    while raw[cd + 46:cd + 51] != b"a.npy":
        cd = raw.find(b"PK\x01\x02", cd + 4)
    eocd = raw.rfind(b"PK\x05\x06")
    record = bytes(raw[cd:eocd])  # a.npy's central record
    copies = b"".join(record.replace(b"a.npy", f"{k:05d}".encode()[:5]) for k in range(50))
    n_entries = int.from_bytes(raw[eocd + 10:eocd + 12], "little") + 50
    cd_start = int.from_bytes(raw[eocd + 16:eocd + 20], "little")
    cd_size = eocd - cd_start + len(copies)
    tail = bytearray(raw[eocd:])
    tail[8:10] = n_entries.to_bytes(2, "little")
    tail[10:12] = n_entries.to_bytes(2, "little")
    tail[12:16] = cd_size.to_bytes(4, "little")
    bomb = tmp_path / "bomb.npz"
    bomb.write_bytes(bytes(raw[:eocd]) + copies + bytes(tail))
    refused(bomb, "overlapping entries")


# --------------------------------------------------------------------------- check_run_arrays (for the driver)

@pytest.mark.parametrize("law, policy", [("paper", "follow"), ("mdr", "birth")])
def test_check_run_arrays_accepts_genuine_checkpoints_and_refuses_forged_ones(tmp_path, law, policy):
    ck = tmp_path / "c.npz"
    with pytest.raises(Stop):
        simulate(presets.S1, tiny_path(), checkpoint=ck, checkpoint_every=1, progress=stop_at(5),
                 **{**run_kw(law), "policy": policy})
    meta, arrays = ckpt.load(ck, asim.__version__)
    kw = dict(n=N, n_stages=3, birth=policy == "birth")
    run_checkpoint.check_run_arrays(arrays, **kw)
    rng = np.random.default_rng(1)
    checked = ("pop_r", "pop_R", "pop_u", "pop_cos_phi", "pop_sin_phi", "delta", "ev_delta", "ev_stress",
               "ev_stderr", "ev_covariance", "ev_tangent", "ev_ints", "ev_mean_theta", "pos_i", "pos_f",
               "pos_start_delta", "pos_start_stress") + (("state_theta_birth",) if policy == "birth" else ())
    n_cases = 0
    for name in checked:
        hows = list(ALWAYS) + list(RANGE.get(name, ()))
        if np.all(np.isfinite(arrays[name])) and arrays[name].dtype.kind == "f":
            hows += ["nan", "inf"]
        for how in hows:
            forged = forge(arrays, name, how, rng)
            if forged is False:
                continue
            bad = ckpt.Arrays(ck, {**arrays})
            if forged is None:
                del bad[name]
            else:
                bad[name] = forged
            with pytest.raises(CheckpointError, match=f"checkpoint '{ck}'.*{name}") as exc:
                run_checkpoint.check_run_arrays(bad, **kw)
            assert "valid" in str(exc.value) or "missing" in str(exc.value) or "expected" in str(exc.value)
            n_cases += 1
    assert n_cases > 100
    assert arrays["pos_i"][1] == 1  # started: ds = 0 is refused
    for pos_f in ([0.5, 0.0, 1.0], [1.5, 0.1, 1.0], [0.5, 0.1, -1.0], [0.5, 1.5, 1.0]):
        with pytest.raises(CheckpointError, match="pos_f"):
            run_checkpoint.check_run_arrays(ckpt.Arrays(ck, {**arrays, "pos_f": np.array(pos_f)}), **kw)
    with pytest.raises(CheckpointError, match=r"pos_i = \[4, 1\]"):
        run_checkpoint.check_run_arrays(ckpt.Arrays(ck, {**arrays, "pos_i": np.array([4, 1])}), **kw)


@pytest.mark.parametrize("law, policy", [("paper", "follow"), ("mdr", "follow"), ("paper", "birth"), ("mdr", "birth")])
def test_check_run_arrays_accepts_every_checkpoint_of_a_run(tmp_path, law, policy):
    """At every step, at stage ends and after the last step (pos_i[0] = number of stages)."""
    ck = tmp_path / "c.npz"
    seen = []

    def keep(stage, n_stages, fraction, step, iterations):
        if ck.exists():
            seen.append(ck.read_bytes())

    simulate(presets.S1, tiny_path(), checkpoint=ck, checkpoint_every=1, progress=keep,
             **{**run_kw(law), "policy": policy})
    seen.append(ck.read_bytes())
    assert len(seen) >= 10
    for i, raw in enumerate(seen):
        path = tmp_path / f"c{i}.npz"
        path.write_bytes(raw)
        _, arrays = ckpt.load(path, asim.__version__)
        run_checkpoint.check_run_arrays(arrays, n=N, n_stages=3, birth=policy == "birth")
