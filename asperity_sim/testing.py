"""Helpers for tests and studies: damaged and forged checkpoint files, the comparison of two runs,
and runs on one numba thread.

Used by ``tests/test_checkpoint_untrusted.py`` and the stability study
(:mod:`asperity_sim.stability`, ``studies/stability.py``) to make the hostile checkpoints a
user could meet: truncated files, flipped bits, and arrays rewritten inside a zip whose
checksums are valid (a forgery that the container's CRC-32 cannot see).  Nothing in the
simulator imports this module.
"""

from __future__ import annotations

import contextlib
import io
import json
import zipfile

import numba
import numpy as np

VOLATILE = {"wall_time_s", "wall_time_increment_loop_s", "history", "date_created"}  # attributes that differ between two runs of the same bits

HOWS = ("nan", "inf", "huge", "negative", "reverse", "shorter", "longer", "flat", "float32", "to_int", "to_float",
        "scalar", "drop")


def same_run(a, b) -> bool:
    """Whether two run datasets hold the same bits (every variable, dtype and attribute but :data:`VOLATILE`)."""
    if set(a.variables) != set(b.variables) or set(a.attrs) != set(b.attrs):
        return False
    for name in a.variables:
        if a[name].dtype != b[name].dtype or not np.array_equal(a[name].values, b[name].values,
                                                                equal_nan=a[name].dtype.kind == "f"):
            return False
    return all(np.array_equal(np.asarray(a.attrs[k]), np.asarray(b.attrs[k])) for k in set(a.attrs) - VOLATILE)


@contextlib.contextmanager
def single_thread():
    """Run numba kernels on one thread inside the block (pure speed: no barrier waits on a busy machine)."""
    old = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(old)


def members(data: bytes):
    """({member name: raw bytes}, [ZipInfo]) of a zip held in memory."""
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        return {info.filename: z.read(info) for info in z.infolist()}, z.infolist()


def arrays_of(data: bytes) -> dict:
    """{name: ndarray} of every ``.npy`` member of a checkpoint held in memory (``meta`` included)."""
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        return {i.filename[:-4]: np.load(io.BytesIO(z.read(i)), allow_pickle=False) for i in z.infolist()}


def write_zip(path, parts: dict, compression=zipfile.ZIP_STORED):
    """A zip with the given (name -> bytes) members and valid CRCs."""
    with zipfile.ZipFile(path, "w", compression=compression) as z:
        for name, raw in parts.items():
            z.writestr(name, raw)
    return path


def npy_bytes(a) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()


def meta_bytes(doc) -> bytes:
    return npy_bytes(np.array(json.dumps(doc)))


def write_checkpoint(path, arrays: dict, changes: dict | None = None):
    """Write ``arrays`` (name -> ndarray, ``meta`` included) as a checkpoint with valid checksums.

    ``changes``: name -> replacement array, or None to leave the array out.
    """
    changes = changes or {}
    parts = {}
    for name, a in arrays.items():
        if name in changes:
            a = changes[name]
            if a is None:
                continue
        parts[f"{name}.npy"] = npy_bytes(a)
    return write_zip(path, parts)


def flip_bit(data: bytes, offset: int, bit: int = 0) -> bytes:
    """``data`` with one bit flipped at byte ``offset``."""
    buf = bytearray(data)
    buf[offset] ^= 1 << bit
    return bytes(buf)


def member_data_offset(data: bytes, name: str) -> int:
    """Offset of the first byte of member ``name``'s data in a stored (uncompressed) zip."""
    _, infos = members(data)
    info = next(i for i in infos if i.filename == name)
    local = info.header_offset
    name_len = int.from_bytes(data[local + 26:local + 28], "little")
    extra_len = int.from_bytes(data[local + 28:local + 30], "little")
    return local + 30 + name_len + extra_len


def forge(arrays, name, how, rng):
    """A damaged copy of one array (``how``, one of :data:`HOWS`); None: drop it; False: does not apply."""
    a = arrays[name]
    if how == "nan" and a.dtype.kind == "f" and a.size:
        a = a.copy()
        a.flat[rng.integers(a.size)] = np.nan
    elif how == "inf" and a.dtype.kind == "f" and a.size:
        a = a.copy()
        a.flat[rng.integers(a.size)] = -np.inf
    elif how == "huge" and a.size:
        a = a.copy()
        a.flat[rng.integers(a.size)] = np.iinfo(a.dtype).max if a.dtype.kind in "iu" else 1e300
    elif how == "negative" and a.size and a.dtype.kind in "if":
        a = a.copy()
        a.flat[rng.integers(a.size)] = -7
    elif how == "reverse" and a.ndim and a.shape[0] > 1:
        a = a[::-1].copy()
    elif how == "shorter" and a.ndim and a.shape[0] > 0:
        a = a[:-1].copy()
    elif how == "longer" and a.ndim:
        a = np.concatenate([a, a[:1]])
    elif how == "flat" and a.ndim > 1:
        a = a.ravel().copy()
    elif how == "float32" and a.dtype.kind == "f":
        a = a.astype(np.float32)
    elif how == "to_int" and a.dtype.kind in "fb":
        a = np.nan_to_num(a).astype(np.int64)
    elif how == "to_float" and a.dtype.kind in "iub":
        a = a.astype(np.float64)
    elif how == "scalar":
        a = np.array(a.ravel()[0] if a.size else 0)
    elif how == "drop":
        return None
    else:
        return False  # this forgery does not apply to this array
    return a
