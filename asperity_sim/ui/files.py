"""The files a command reads and writes: output paths checked before any work, run files read.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .exits import PROG
from .reports import RUN_VARIABLES, SWEEP_VARIABLES

# -- run ---------------------------------------------------------------------

def check_output(path: Path, inputs=(), suffixes=(".nc", ".nc4"), overwrite=False, what="output") -> Path:
    """Refuse, before any work, an output that cannot or must not be written; create its folder.

    Not the input, not a folder, an existing file only with ``--overwrite``, a folder that
    exists (or can be created) and is writable.
    """
    if path.suffix not in suffixes:
        raise ValueError(f"{what} {str(path)!r} must end in {' or '.join(suffixes)}")
    for p in inputs:
        if p is not None and path.exists() and p.exists() and os.path.samefile(path, p):
            raise ValueError(f"{what} {str(path)!r} is the input file {str(p)!r}; choose another name")
    if path.is_dir():
        raise ValueError(f"{what} {str(path)!r} is a folder; give a file name")
    if path.exists() and not overwrite:
        raise ValueError(f"{what} {str(path)!r} exists; give --overwrite to replace it, or another name with -o")
    folder = path.parent
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"{what} folder {str(folder)!r} cannot be created: {str(existing)!r} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{what} folder {str(existing)!r} is not writable")
    folder.mkdir(parents=True, exist_ok=True)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{what} folder {str(folder)!r} is not writable")
    return path


def check_checkpoint(path: Path, *, resume: bool, others=(), overwrite=False) -> Path:
    """The checkpoint file: ends in .npz, is neither the scene nor the run file, its folder writable."""
    from ..output.checkpoint import SUFFIX

    if path.suffix != SUFFIX:
        raise ValueError(f"checkpoint {str(path)!r} must end in {SUFFIX}")
    for p in others:
        if p is not None and (path.resolve() == p.resolve()
                              or (path.exists() and p.exists() and os.path.samefile(path, p))):
            raise ValueError(f"checkpoint {str(path)!r} is also the file {str(p)!r}; choose another name")
    if path.is_dir():
        raise ValueError(f"checkpoint {str(path)!r} is a folder; give a file name")
    if resume:
        if not path.is_file():
            raise ValueError(f"checkpoint {str(path)!r}: no such file (nothing to resume)")
        if not os.access(path.parent, os.W_OK | os.X_OK):
            raise ValueError(f"checkpoint folder {str(path.parent)!r} is not writable (a resumed run goes on "
                             "checkpointing there)")
        return path
    if path.exists() and not overwrite:
        raise ValueError(f"checkpoint {str(path)!r} exists (a killed run?); give --resume {path} to continue it, "
                         "or --overwrite to start afresh")
    return check_output(path, suffixes=(SUFFIX,), overwrite=True, what="checkpoint")


def write_with_scene(ds, out, scene, scene_file, note=""):
    """Rewrite the run file with the scene's title, file name and text (provenance), atomically."""
    from ..output.netcdf import write_netcdf

    if scene.title:
        ds.attrs["title"] = scene.title
    ds.attrs["scene_file"] = str(Path(scene_file).resolve())
    ds.attrs["scene"] = Path(scene_file).read_text(encoding="utf-8")
    ds.attrs["history"] = (f"{ds.attrs.get('history', '')}\n"
                           f"{PROG} run {scene_file} (n = {scene.n}, seed = {scene.seed}) -> {out}"
                           + (f": {note}" if note else "")).strip()
    write_netcdf(ds, out)


def read_run(path: Path):
    """(dataset, kind) of a run or sweep file; one-line ValueError naming the file and what is wrong."""
    from ..output.netcdf import read_netcdf

    if not path.exists():
        raise ValueError(f"{path}: no such file")
    if path.is_dir():
        raise ValueError(f"{path}: is a folder, not a run file")
    try:
        ds = read_netcdf(path)
    except Exception as err:  # noqa: BLE001 - OSError, RuntimeError (HDF5), ValueError, ... of a damaged file
        raise ValueError(f"{path}: not a netCDF file, or a damaged one ({type(err).__name__}: {' '.join(str(err).split())}; "
                         f"asperity-sim plot and info read run files written by asperity-sim run or sweep)") from None
    kind = ds.attrs.get("kind", "run")
    if "stress" not in ds or "displacement" not in ds:
        raise ValueError(f"{path}: not an asperity_sim run or sweep file (no stress and displacement variables)")
    needed = SWEEP_VARIABLES if kind == "sweep" else RUN_VARIABLES
    missing = [v for v in needed if v not in ds]
    if "axis" not in ds.coords or sorted(np.asarray(ds["axis"].values).tolist()) != [1, 2, 3]:
        missing.append("coordinate axis = 1, 2, 3")
    if kind != "sweep" and ("step" not in ds.dims or ds.sizes["step"] < 1):
        missing.append("dimension step")
    if missing:
        raise ValueError(f"{path}: damaged or foreign {kind} file: missing {', '.join(missing)}")
    return ds, kind


def damaged_file_error(path, kind, err):
    return ValueError(f"{path}: damaged {kind} file ({type(err).__name__}: {' '.join(str(err).split())})")
