"""Checkpoints of a running :func:`~asperity_sim.simulate`: the full state, written atomically.

Owns the checkpoint file format: the container, its untrusted reading and
the checks of what is read (:func:`require`, :func:`guard`).  Which arrays hold which part of
a run, and how a run is saved to them and restored from them, is
:mod:`asperity_sim.solve.run_checkpoint`'s.  A checkpoint holds everything the loop needs to continue
as if it had never stopped, so a resumed run is bit-identical to an uninterrupted one:

- the run's configuration (parameters, n, seed, sampler, law, policy, the law's options, load path,
  solver settings, snapshot request) and the package version and checkpoint format;
- the population arrays (r, R, u, cos phi, sin phi), not only its seed: a population drawn
  with ``seed=None`` or passed in by the caller cannot be drawn again;
- the committed per-contact state (:class:`~asperity_sim.kernels.state.ContactState`: slots and law
  arrays of a history law, birth angles under policy ``birth``);
- the recorder buffers (every converged increment so far), the snapshots taken, the running
  energy sums, the last converged evaluation (stress, covariance, tangent, counts: the
  predictor of the next increment reads them) and the position of the loop (stage, fraction
  of the stage, next increment size, stage start, reference stiffness).

Format: one numpy ``.npz`` archive (uncompressed zip of ``.npy`` arrays) plus a JSON
document in the array ``meta``.  Why not netCDF: the state is a handful of arrays of
unrelated shapes and dtypes (int32 slot map, (slots, k, 2) springs, int8 states, a list of
snapshot dictionaries) that need no named dimensions, must round-trip bit for bit, and are
read back only by this module; ``.npy`` stores them exactly, needs no extra dependency and
reads without pickle (``allow_pickle=False``), and the zip's CRC-32 per member detects a
damaged file.  It is written through :func:`asperity_sim.output.atomic.write_atomically`
(temporary name in the same folder, fsync, rename), so a crash or SIGKILL never leaves a
truncated checkpoint behind under the final name.

A checkpoint is read back only by the same package version (``asperity_sim.__version__``,
exactly: a patch release may change a result in its last bit, and a resumed run promises the
bits of an uninterrupted run of one version) and the same format (:data:`FORMAT`, raised by a
release that changes the layout); either refusal is a :class:`CheckpointError` naming both
versions.  A checkpoint of another parameter set, path, law, ... than the run it is asked to
continue is refused with a :class:`CheckpointError` naming the differences.

Untrusted input (issue 24).  A checkpoint file is treated as hostile: a CRC-32 only detects
accidents, and a forged file with valid checksums is easy to make.  :func:`load` reads the zip
itself (no ``np.load``): every member must be a stored (uncompressed) ``.npy`` of format 1.0
or 2.0 with a plain numeric, boolean or unicode dtype (never object), and a header whose shape
accounts for exactly the member's bytes (so a forged header cannot ask for terabytes); any
exception while reading or decoding, whatever its type, becomes a :class:`CheckpointError`
naming the file.  The meta record must be a JSON object with a well-formed ``config``
(:func:`check_config`).  What the arrays *mean* is :mod:`asperity_sim.solve.run_checkpoint`'s
business: before any kernel sees an array it calls :func:`require` (dtype, shape, finite,
bounds, sorted), and wraps its own mapping in :func:`guard`, which turns any ``KeyError``,
``IndexError``, ``TypeError``, ``ValueError`` (e.g. from ``Population.__post_init__``) into a
:class:`CheckpointError`.
"""

from __future__ import annotations

import contextlib
import json
import numbers
import os
import zipfile
from pathlib import Path

import numpy as np

from ..errors import CheckpointError
from .atomic import write_atomically

# 3: mdr springs stored (slot, component, spring), one contiguous row per component; predictor points pos_older
# 4: the law's options in config['law_options'] (3: config['k'] and config['spring_dtype'])
FORMAT = 4
SUFFIX = ".npz"
MAX_MEMBERS = 100_000  # more arrays than any run writes (snapshots add a handful each)
_DTYPE_KINDS = "biufU"  # bool, integers, floats, the unicode meta record; never object or structured


def differences(saved: dict, wanted: dict, prefix="") -> list[str]:
    """Human-readable differences between two configurations (nested dicts and lists)."""
    out = []
    for key in sorted(set(saved) | set(wanted)):
        a, b = saved.get(key, "<missing>"), wanted.get(key, "<missing>")
        name = f"{prefix}{key}"
        if isinstance(a, dict) and isinstance(b, dict):
            out += differences(a, b, name + ".")
        elif a != b:
            out.append(f"{name}: checkpoint {a!r}, this run {b!r}")
    return out


def save(path, *, meta: dict, arrays: dict) -> Path:
    """Write ``arrays`` (name -> ndarray) and ``meta`` (JSON-able) to ``path`` atomically."""
    doc = {"format": FORMAT, **meta}
    payload = {"meta": np.array(json.dumps(doc, allow_nan=True))}
    for name, a in arrays.items():
        if name == "meta":
            raise ValueError("'meta' is reserved in a checkpoint")
        payload[name] = np.ascontiguousarray(a)

    def write(tmp):
        with open(tmp, "wb") as fh:
            np.savez(fh, **payload)

    write_atomically(path, write)
    return Path(path)


class Arrays(dict):
    """The arrays of a checkpoint (name -> ndarray) and the file they came from (``.path``)."""

    def __init__(self, path, items=()):
        super().__init__(items)
        self.path = str(path)


def load(path, version: str) -> tuple[dict, Arrays]:
    """Read a checkpoint: (meta, arrays).  Refuses another format or package version.

    Any damage (bit flips, truncation, forged members, impossible headers, bad JSON) raises a
    :class:`CheckpointError` naming the file; nothing else escapes (only ``KeyboardInterrupt``
    and other non-``Exception`` signals).
    """
    path = Path(path)
    name = str(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {name!r} does not exist")
    try:
        arrays = _read_members(path)
    except CheckpointError:
        raise
    except Exception as err:  # noqa: BLE001 - hostile input: any failure of reading is a damaged file
        raise CheckpointError(f"checkpoint {name!r} is not a readable asperity_sim checkpoint "
                              f"({type(err).__name__}: {err})") from err
    if "meta" not in arrays:
        raise CheckpointError(f"checkpoint {name!r} has no 'meta' record: not an asperity_sim checkpoint")
    record = arrays.pop("meta")
    if record.dtype.kind != "U" or record.shape != ():
        raise CheckpointError(f"checkpoint {name!r} has a damaged 'meta' record (dtype {record.dtype}, shape "
                              f"{record.shape}; expected one unicode string)")
    try:
        meta = json.loads(str(record))
    except Exception as err:  # noqa: BLE001 - ValueError, RecursionError on forged nesting, ...
        raise CheckpointError(f"checkpoint {name!r} has a damaged 'meta' record ({type(err).__name__}: {err})") \
            from err
    if not isinstance(meta, dict):
        raise CheckpointError(f"checkpoint {name!r} has a damaged 'meta' record (a JSON {type(meta).__name__}, "
                              "expected an object)")
    written = meta.get("version")
    if meta.get("format") != FORMAT:
        raise CheckpointError(f"checkpoint {name!r} has format {meta.get('format')!r} and was written by "
                              f"asperity_sim {written!r}; this is asperity_sim {version!r}, which reads format "
                              f"{FORMAT} only (finish the run with {written!r}, or start it again)")
    if written != version:
        raise CheckpointError(f"checkpoint {name!r} was written by asperity_sim {written!r}; this is {version!r} "
                              "and continues only its own checkpoints, also across a patch release (a bit-identical "
                              f"continuation needs the same code: finish the run with {written!r}, or start it "
                              "again)")
    check_config(meta.get("config"), name)
    return meta, arrays


def _read_members(path) -> Arrays:
    """Every member of the zip as an array, each checked against its own header and size."""
    size = path.stat().st_size
    out = Arrays(path)
    with zipfile.ZipFile(path) as zf:
        infos = zf.infolist()
        if len(infos) > MAX_MEMBERS:
            raise CheckpointError(f"checkpoint {str(path)!r} has {len(infos)} members (at most {MAX_MEMBERS})")
        total = sum(info.file_size for info in infos)
        if total > size:  # stored members cannot hold more than the file: overlapping (forged) entries
            raise CheckpointError(f"checkpoint {str(path)!r}: its members claim {total} bytes in a file of {size} "
                                  "bytes (overlapping entries)")
        for info in infos:
            key = info.filename[:-4] if info.filename.endswith(".npy") else None
            where = f"checkpoint {str(path)!r}: member {info.filename!r}"
            if not key:
                raise CheckpointError(f"{where} is not a .npy array")
            if key in out:
                raise CheckpointError(f"{where} appears twice")
            if info.compress_type != zipfile.ZIP_STORED:
                raise CheckpointError(f"{where} is compressed (method {info.compress_type}); asperity_sim writes "
                                      "stored members only")
            if info.flag_bits & 0x1:
                raise CheckpointError(f"{where} is encrypted")
            if not (0 <= info.file_size <= size and info.compress_size == info.file_size):
                raise CheckpointError(f"{where} claims {info.file_size} bytes in a file of {size} bytes")
            with zf.open(info) as fh:
                out[key] = _read_npy(fh, info.file_size, where)
    return out


def _read_npy(fh, member_size, where):
    fmt = np.lib.format
    major_minor = fmt.read_magic(fh)
    if major_minor == (1, 0):
        shape, fortran, dtype = fmt.read_array_header_1_0(fh)
    elif major_minor == (2, 0):
        shape, fortran, dtype = fmt.read_array_header_2_0(fh)
    else:
        raise CheckpointError(f"{where} has .npy format {major_minor} (expected 1.0 or 2.0)")
    if dtype.kind not in _DTYPE_KINDS or dtype.fields is not None or dtype.subdtype is not None \
            or dtype.hasobject:
        raise CheckpointError(f"{where} has dtype {dtype} (expected a plain bool, integer, float or unicode dtype)")
    if not all(isinstance(s, int) and s >= 0 for s in shape):
        raise CheckpointError(f"{where} has shape {shape!r}")
    count = 1
    for s in shape:
        count *= s
    nbytes = count * dtype.itemsize
    if nbytes != member_size - fh.tell():
        raise CheckpointError(f"{where}: its header (shape {shape}, dtype {dtype}) needs {nbytes} bytes, the member "
                              f"holds {member_size - fh.tell()}")
    data = bytearray(fh.read(nbytes))
    if len(data) != nbytes or fh.read(1):  # reading to the end also checks the CRC-32
        raise CheckpointError(f"{where} is truncated")
    return np.frombuffer(data, dtype=dtype).reshape(shape, order="F" if fortran else "C")


_CONFIG_TYPES = {"params": dict, "n": int, "seed": (int, type(None)), "sampler": str, "law": str, "policy": str,
                 "law_options": dict, "path": dict, "settings": dict, "snapshots": (list, str)}


def check_config(config, name="<checkpoint>") -> dict:
    """Check the shape of a configuration read back from a file (see :func:`asperity_sim.solve.run_checkpoint.config_of`)."""
    where = f"checkpoint {name!r}"
    if not isinstance(config, dict):
        raise CheckpointError(f"{where} has no valid 'config' record (got a {type(config).__name__})")
    missing = sorted(set(_CONFIG_TYPES) - set(config))
    if missing:
        raise CheckpointError(f"{where}: its 'config' record lacks {missing}")
    for key, kind in _CONFIG_TYPES.items():
        value = config[key]
        if isinstance(value, bool) or not isinstance(value, kind):
            raise CheckpointError(f"{where}: config {key} = {value!r} has type {type(value).__name__}")
    bad = [k for k, v in config["params"].items() if isinstance(v, bool) or not isinstance(v, numbers.Real)]
    if bad:
        raise CheckpointError(f"{where}: config params {bad} are not numbers")
    stages = config["path"].get("stages")
    if not isinstance(stages, list) or not stages or not all(isinstance(s, dict) for s in stages):
        raise CheckpointError(f"{where}: config path.stages = {stages!r} is not a list of stages")
    return config


def require(arrays, name, *, shape=None, dtype=None, finite=True, lo=None, hi=None, lo_open=False,
            hi_open=False, sorted=False, path=None) -> np.ndarray:  # noqa: A002 - the natural keyword
    """``arrays[name]`` after checking it; raise :class:`CheckpointError` naming the file, array and range.

    Parameters
    ----------
    arrays : Arrays or dict
        As returned by :func:`load` (its ``.path`` names the file) or any mapping.
    shape : tuple of (int or None), optional
        Expected shape; ``None`` entries match any length (``(n,)``, ``(None, 3)``).
    dtype : dtype-like, optional
        Exact dtype (``np.float64``, ``np.int32``, ``np.int8``, ``bool``); native byte order.
    finite : bool
        Floating values must be finite (NaN, inf refused).  ``False`` lets NaN through (for
        arrays where NaN means "unset", such as unborn angles); the bounds then skip NaN.
    lo, hi : float, optional
        Bounds of every element, inclusive unless ``lo_open`` / ``hi_open``.
    sorted : bool
        Non-decreasing along the last axis.
    path : str, optional
        File to name when ``arrays`` is a plain dict.
    """
    where = f"checkpoint {str(path if path is not None else getattr(arrays, 'path', '<unknown>'))!r}: array {name}"
    try:
        a = arrays[name]
    except (KeyError, TypeError):
        raise CheckpointError(f"{where} is missing") from None
    if not isinstance(a, np.ndarray):
        raise CheckpointError(f"{where} is a {type(a).__name__}, not an array")
    if dtype is not None and a.dtype != np.dtype(dtype):
        raise CheckpointError(f"{where} has dtype {a.dtype.str}, expected {np.dtype(dtype).str} ({np.dtype(dtype)})")
    if shape is not None:
        shape = tuple(shape)
        if a.ndim != len(shape) or any(want is not None and got != want for got, want in zip(a.shape, shape)):
            text = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
            raise CheckpointError(f"{where} has shape {a.shape}, expected {text}")
    if a.dtype.kind not in "biuf":
        if lo is not None or hi is not None or sorted:
            raise CheckpointError(f"{where} has dtype {a.dtype}, expected a numeric array")
        return a
    if finite and a.dtype.kind == "f":
        bad = ~np.isfinite(a)
        if bad.any():
            i = _first(bad)
            raise CheckpointError(f"{where} holds {a[i].item()!r} at index {i} (valid range: finite values)")
    rng = _range(lo, hi, lo_open, hi_open)
    if lo is not None:
        bad = a <= lo if lo_open else a < lo
        if bad.any():
            i = _first(bad)
            raise CheckpointError(f"{where} holds {a[i].item()!r} at index {i} (valid range: {rng})")
    if hi is not None:
        bad = a >= hi if hi_open else a > hi
        if bad.any():
            i = _first(bad)
            raise CheckpointError(f"{where} holds {a[i].item()!r} at index {i} (valid range: {rng})")
    if sorted and a.ndim and a.shape[-1] > 1:
        bad = a[..., 1:] < a[..., :-1]
        if bad.any():
            i = _first(bad)
            j = i[:-1] + (i[-1] + 1,)
            raise CheckpointError(f"{where} is not sorted: element {j} = {a[j].item()!r} < element {i} = "
                                  f"{a[i].item()!r} (valid: non-decreasing along the last axis)")
    return a


def _first(mask):
    return tuple(int(k) for k in np.unravel_index(int(np.argmax(mask)), mask.shape))


def _range(lo, hi, lo_open, hi_open):
    left = f"{'(' if lo_open else '['}{lo!r}" if lo is not None else "(-inf"
    right = f"{hi!r}{')' if hi_open else ']'}" if hi is not None else "inf)"
    return f"{left}, {right}"


@contextlib.contextmanager
def guard(path, what="is incomplete or damaged"):
    """Turn any error of mapping a checkpoint's content into a :class:`CheckpointError` naming ``path``.

    For the reading of meta and arrays (:mod:`asperity_sim.solve.run_checkpoint`)::

        with ckpt.guard(path):
            pop = Population(params=params, r=ckpt.require(arrays, "pop_r", ...), ...)

    ``KeyError``, ``IndexError``, ``TypeError``, ``AttributeError``, ``OverflowError`` and
    ``ValueError`` (``Population.__post_init__`` and every validated dataclass raise it) are
    re-raised as :class:`CheckpointError`; a :class:`CheckpointError` passes unchanged.
    """
    try:
        yield
    except CheckpointError:
        raise
    except (KeyError, IndexError, TypeError, AttributeError, OverflowError, ValueError) as err:
        raise CheckpointError(f"checkpoint {os.fspath(path)!r} {what} ({type(err).__name__}: {err})") from err


def read_config(path, version: str) -> dict:
    """The configuration stored in a checkpoint (see :func:`asperity_sim.solve.run_checkpoint.config_of`)."""
    return load(path, version)[0]["config"]
