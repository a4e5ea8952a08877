"""Test support shared by several test modules (the fixtures are in ``conftest.py``).

* :func:`study`: a module of ``studies/`` (``timing``, ``mdr_convergence``, ...), imported by its
  name with ``studies/`` on ``sys.path``, as it is imported when the study scripts run as
  programs (``python3 studies/x.py`` puts ``studies/`` first on the path).  This is the one way
  tests reach the studies' code: by name, never loaded from a file under another name.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

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

