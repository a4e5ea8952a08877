"""Checkpoints of a running :func:`~asperity_sim.simulate`: the full state, written atomically.

Owns the checkpoint file format.  A checkpoint holds everything the loop needs to continue
as if it had never stopped, so a resumed run is bit-identical to an uninterrupted one:

- the run's configuration (parameters, n, seed, sampler, law, policy, springs k, load path,
  solver settings, snapshot request) and the package version and checkpoint format;
- the population arrays (r, R, u, cos phi, sin phi), not only its seed: a population drawn
  with ``seed=None`` or passed in by the caller cannot be drawn again;
- the committed per-contact state (:class:`~asperity_sim.state.ContactState`: slots and law
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
damaged file.  The file is written to a temporary name in the same folder, flushed to disk
(fsync) and renamed over the final name, so a crash or SIGKILL never leaves a truncated
checkpoint behind under the final name.

A checkpoint is read back only by the same package version and the same format
(:data:`FORMAT`); a checkpoint of another parameter set, path, law, ... than the run it is
asked to continue is refused with a :class:`CheckpointError` naming the differences.
"""

from __future__ import annotations

import dataclasses
import json
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

FORMAT = 2
SUFFIX = ".npz"


class CheckpointError(ValueError):
    """A checkpoint cannot be used: unreadable, another version or format, or another run."""


def config_of(params, path, *, n, seed, sampler, law, policy, k, settings, snapshots, spring_dtype="float64"):
    """The run's identity as JSON-able values; a checkpoint continues only the same configuration."""
    snaps = sorted(snapshots[0]) if not snapshots[1] else "stage_ends"
    return {
        "params": params.as_dict(),
        "n": int(n),
        "seed": None if seed is None else int(seed),
        "sampler": sampler,
        "law": law,
        "policy": policy,
        "k": int(k) if _has_history(law) else None,
        "spring_dtype": spring_dtype if _has_history(law) else None,
        "path": {"name": path.name,
                 "stages": [{"control": list(s.control), "target": [float(t) for t in s.target],
                             "increments": s.increments, "adaptive": s.adaptive,
                             "max_fraction": s.max_fraction, "name": s.name} for s in path.stages]},
        "settings": dataclasses.asdict(settings),
        "snapshots": snaps,
    }


def _has_history(law) -> bool:
    from . import laws

    return laws.get(law).history is not None


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
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"format": FORMAT, **meta}
    payload = {"meta": np.array(json.dumps(doc, allow_nan=True))}
    for name, a in arrays.items():
        if name == "meta":
            raise ValueError("'meta' is reserved in a checkpoint")
        payload[name] = np.ascontiguousarray(a)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **payload)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        _fsync_dir(path.parent)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def _fsync_dir(folder):
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def load(path, version: str) -> tuple[dict, dict]:
    """Read a checkpoint: (meta, arrays).  Refuses another format or package version."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {str(path)!r} does not exist")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
        raise CheckpointError(f"checkpoint {str(path)!r} is not a readable asperity_sim checkpoint ({err})") from err
    if "meta" not in arrays:
        raise CheckpointError(f"checkpoint {str(path)!r} has no 'meta' record: not an asperity_sim checkpoint")
    try:
        meta = json.loads(str(arrays.pop("meta")))
    except ValueError as err:
        raise CheckpointError(f"checkpoint {str(path)!r} has a damaged 'meta' record ({err})") from err
    if meta.get("format") != FORMAT:
        raise CheckpointError(f"checkpoint {str(path)!r} has format {meta.get('format')!r}; this asperity_sim "
                              f"reads format {FORMAT} only")
    if meta.get("version") != version:
        raise CheckpointError(f"checkpoint {str(path)!r} was written by asperity_sim {meta.get('version')!r}; "
                              f"this is {version!r} and continues only its own checkpoints (a bit-identical "
                              "continuation needs the same code)")
    return meta, arrays


def read_config(path, version: str) -> dict:
    """The configuration stored in a checkpoint (see :func:`config_of`)."""
    return load(path, version)[0]["config"]
