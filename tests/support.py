"""Test support shared by several test modules (the fixtures are in ``conftest.py``).

* :func:`study`: a module of ``studies/`` (``stability_cases``, ``timing``, ...), imported by its
  name with ``studies/`` on ``sys.path``, as it is imported when the study scripts run as
  programs (``python3 studies/x.py`` puts ``studies/`` first on the path).  This is the one way
  tests reach the studies' code: by name, never loaded from a file under another name, so that
  a worker process spawned by the stability study (``multiprocessing`` "spawn", which hands the
  child the parent's ``sys.path``) unpickles its jobs from the same modules.
* :func:`single_thread`: numba kernels on one thread inside a block.
* :func:`forge` and :data:`HOWS`: damaged copies of one array of a checkpoint, for the property
  tests of ``test_checkpoint_untrusted.py``.

The byte-level tools for damaged and forged checkpoint files (zip members, ``.npy`` bytes,
flipped bits, the comparison of two runs' bits) are in ``studies/damaged_checkpoints.py``,
because the stability study's hostile inputs use them too and a program under ``studies/``
must not depend on the test tree; tests take them from there through :func:`study`.  Nothing
here is part of the package (this moved out of ``asperity_sim.testing`` in 0.4).
"""

from __future__ import annotations

import contextlib
import importlib
import sys
from pathlib import Path

import numba
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
STUDIES = ROOT / "studies"


def study(name: str):
    """The module ``studies/<name>.py``, imported by its name (``studies/`` put first on ``sys.path`` once)."""
    folder = str(STUDIES)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    module = importlib.import_module(name)
    if Path(module.__file__).resolve().parent != STUDIES:  # another module of that name came first
        raise ImportError(f"study module {name!r} was imported from {module.__file__}, not from {STUDIES}")
    return module


@contextlib.contextmanager
def single_thread():
    """Run numba kernels on one thread inside the block (pure speed: no barrier waits on a busy machine)."""
    old = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(old)


HOWS = ("nan", "inf", "huge", "negative", "reverse", "shorter", "longer", "flat", "float32", "to_int", "to_float",
        "scalar", "drop")


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
