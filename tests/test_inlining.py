"""numba's inlining without copies of an IR built for one call site (asperity_sim/inlining.py).

The compiled code is that of numba's own inlining: a nest of ``inline="always"`` functions,
each called at several sites, compiled both ways gives the same LLVM IR (up to the
process-wide counters numba numbers its functions and blocks with) and the same bits; the copy-free path
is the one taken, and it leaves numba's module as it found it.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import numba
import numpy as np
import pytest
from numba.core import inline_closurecall

from asperity_sim import inlining

ROOT = Path(__file__).resolve().parent.parent
CHECKED = ".".join(numba.__version__.split(".")[:2]) in inlining.CHECKED


@numba.njit(inline="always")
def _leaf(x, k):
    y = x * k
    return y * y - x if y > 0.0 else x + k


@numba.njit(inline="always")
def _middle(x, k):
    a = _leaf(x, k)
    b = _leaf(a, k + 1.0)
    return a + b if a < b else a - b


def _top(v, k):
    s = 0.0
    for i in range(v.size):
        s += _middle(v[i], k) + _leaf(v[i], 0.5 * k)
    return s


def _compiled(fast, monkeypatch):
    """_top compiled (a fresh dispatcher) with the copy-free inlining or numba's: (LLVM IR, value, copies skipped)."""
    skipped = []
    with monkeypatch.context() as m:
        if fast:
            m.setattr(inlining._ByReference, "deepcopy", staticmethod(lambda x, memo=None: skipped.append(1) or x))
        else:
            m.setattr(inline_closurecall.InlineWorker, "inline_function", inlining._NUMBA_INLINE_FUNCTION)
        f = numba.njit(_top)
        v = np.linspace(-2.0, 3.0, 101)
        value = f(v, 0.7)
    llvm = "".join(f.inspect_llvm().values())
    # numba numbers the functions and the blocks it compiles in a process: the numbers in names may differ
    # (and so the padding of the comments after a block's name, and the length of the strings that hold a name)
    return re.sub(r'B\d+v\d+B|_v\d+_|\bB\d+|\s*;.*|\[\d+ x i8\] c"[^"]*"', "#", llvm), value, len(skipped)


@pytest.mark.skipif(not CHECKED, reason=f"numba {numba.__version__} is not one the copy-free inlining was checked with")
def test_the_package_installs_it_and_numba_inlines_to_the_same_code_without_the_copies(monkeypatch):
    assert inlining.installed()
    fast_ir, fast_value, skipped = _compiled(True, monkeypatch)
    slow_ir, slow_value, _ = _compiled(False, monkeypatch)
    assert skipped > 0  # the copy-free path inlined them
    assert fast_ir == slow_ir
    assert fast_value == slow_value  # the same bits
    assert inline_closurecall.copy.deepcopy is __import__("copy").deepcopy  # numba's module as it was


def test_the_environment_variable_leaves_numba_as_it_is():
    env = {**os.environ, inlining.ENV: "0", "PYTHONPATH": str(ROOT)}
    code = "import asperity_sim.jit, asperity_sim.inlining as i; print(i.installed())"
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False"]
