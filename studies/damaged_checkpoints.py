"""Damaged and forged checkpoint files, and the comparison of two runs' bits.

The byte-level tools to make the hostile checkpoints a user could meet: members of a zip held
in memory, ``.npy`` bytes, a checkpoint rewritten with valid checksums (a forgery the
container's CRC-32 cannot see), a flipped bit at a known offset; and :func:`same_run`, whether
a resumed run holds the bits of an uninterrupted one.

Used by the stability study's hostile inputs (``stability_hostile.py``, run by
``studies/stability.py``) and by ``tests/test_checkpoint_untrusted.py``.  It lives beside the
study, not in the package (nothing in the simulator needs it; it moved here from
``asperity_sim.testing`` in 0.4) and not under ``tests/`` (a program under ``studies/`` does not
depend on the test tree): the study imports it as a sibling module, tests through
``tests/support.py``'s ``study("damaged_checkpoints")``.  The test-only parts of the old module
(``single_thread``, ``forge``) are in ``tests/support.py``.
"""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np

VOLATILE = {"wall_time_s", "wall_time_increment_loop_s", "history", "date_created"}  # attributes that differ between two runs of the same bits


def same_run(a, b) -> bool:
    """Whether two run datasets hold the same bits (every variable, dtype and attribute but :data:`VOLATILE`)."""
    if set(a.variables) != set(b.variables) or set(a.attrs) != set(b.attrs):
        return False
    for name in a.variables:
        if a[name].dtype != b[name].dtype or not np.array_equal(a[name].values, b[name].values,
                                                                equal_nan=a[name].dtype.kind == "f"):
            return False
    return all(np.array_equal(np.asarray(a.attrs[k]), np.asarray(b.attrs[k])) for k in set(a.attrs) - VOLATILE)


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

