"""Compiled kernels and their on-disk cache (asperity_sim/jit.py, asperity_sim/kernels/specialise.py).

numba reuses a cached kernel as long as the kernel's own file is unchanged; the package's
fingerprint makes an edit anywhere in a kernel's call graph compile the kernel anew.  The slow
test edits callees in a copy of the package, in other files than their callers, and checks that
a second process with the same cache folder runs the edited code.
"""

import ast
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numba
import numpy as np
import pytest

from asperity_sim import jit, laws
from asperity_sim.kernels import commit, history, loop, loop_history, loop_path_independent, reductions, specialise

PACKAGE = Path(jit.__file__).resolve().parent


def _compiles(path) -> bool:
    """True if the file defines a function decorated by kernel, template or anything of numba."""
    for node in ast.walk(ast.parse(path.read_text())):
        for d in getattr(node, "decorator_list", []):
            text = ast.unparse(d)
            if re.match(r"(kernel|template)\(|numba\.", text):
                return True
    return False


def test_every_file_with_compiled_code_is_in_the_fingerprint():
    """Every file that compiles something (a kernel, a template, a numba intrinsic) is hashed."""
    hashed = set(jit.kernel_sources())
    compiling = {path for path in PACKAGE.rglob("*.py") if _compiles(path)}
    assert len(compiling) > 20 and compiling <= hashed, compiling - hashed
    assert {PACKAGE / "laws" / "hertz.py", PACKAGE / "sampling" / "reach.py", PACKAGE / "vectormath.py"} <= hashed
    assert PACKAGE / "ui" / "cli.py" not in hashed  # a file without compiled code does not invalidate them


def test_templates_carry_their_options_and_placeholders_are_module_names():
    for module, placeholders in ((reductions, {"local"}), (history, {"trial", "trial_block"}),
                                 (commit, {"commit_law", "commit_block"})):
        found = specialise.templates_of(module)
        assert found and all(f.jit_options["cache"] for f in found.values())
        for name in placeholders:  # defined in the module, never compiled as written
            with pytest.raises(NotImplementedError):
                getattr(module, name)(*([None] * getattr(module, name).__code__.co_argcount))
    assert specialise.templates_of(reductions)["reduce_parallel"].jit_options["nogil"] is True


def test_each_law_gets_its_own_compiled_copies_named_by_law_and_fingerprint():
    paper, mdr = specialise.kernels("paper"), specialise.kernels("mdr")
    birth = specialise.kernels("paper", birth=True)
    assert set(paper) == set(specialise.templates_of(reductions)) | set(specialise.templates_of(loop)) | set(
        specialise.templates_of(loop_path_independent))
    assert set(mdr) == (set(specialise.templates_of(history)) | set(specialise.templates_of(commit))
                        | set(specialise.templates_of(loop)) | set(specialise.templates_of(loop_history)))
    assert paper["reduce_parallel"].py_func.__qualname__ == (
        f"reduce_parallel__paper_follow_{specialise.law_fingerprint(laws.get('paper'))}")
    assert birth["reduce_parallel"].py_func.__qualname__.startswith("reduce_parallel__paper_birth_")
    assert specialise.kernels("paper") is paper and specialise.kernels("paper", birth=True) is birth  # built once


EDITS = {  # file in the copy: (text, replacement) -- each a callee in another file than its callers
    "laws/paper.py": ("C = (4.0 / 3.0) * E_star * sqrt_R", "C = (8.0 / 3.0) * E_star * sqrt_R"),
    "sampling/reach.py": ("r_max += 1e-12 * max(abs(r_max), beta)", "r_max += 0.5 * beta"),
}

PROBE = """
import json, numpy as np
import asperity_sim as asim
from asperity_sim import presets
from asperity_sim.kernels.reach import bounds
p = presets.R1.replace(mu=0.0)
n = 60  # heights from 0 to Delta_1 + beta, from arrays: no sampling kernel to compile twice
pop = asim.Population.from_arrays(p, np.linspace(0.0, 12e-6 + p.beta, n), np.full(n, p.R_m),
                                  np.linspace(0.1, 0.9, n), np.linspace(0.0, 6.0, n))
d = np.array([12e-6, 0.0, 0.0])
ev = asim.evaluate(pop, d)
n_active, _ = bounds(pop.r, pop.R_min, p.r_o, p.k_e, p.beta, d, np.empty(0))
print(json.dumps({"file": asim.__file__, "stress": ev.stress.tolist(), "n_active": int(n_active)}))
"""


def _probe(root, cache):
    env = {**os.environ, "PYTHONPATH": str(root), "NUMBA_CACHE_DIR": str(cache), "NUMBA_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", PROBE], env=env, cwd=root, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # two fresh processes compile the paper law's kernels
def test_editing_a_callee_in_another_file_compiles_anew(tmp_path):
    root = tmp_path / "copy"
    shutil.copytree(PACKAGE, root / "asperity_sim", ignore=shutil.ignore_patterns("__pycache__"))
    cache = tmp_path / "numba_cache"
    before = _probe(root, cache)
    assert before["file"] == str(root / "asperity_sim" / "__init__.py")
    for name, (old, new) in EDITS.items():
        path = root / "asperity_sim" / name
        text = path.read_text()
        assert text.count(old) == 1, name
        path.write_text(text.replace(old, new))
    after = _probe(root, cache)  # same cache folder: a stale kernel would give the numbers of before
    # mu = 0: no tangential force, so doubling the Hertz constant doubles the normal stress exactly
    assert after["stress"][0] == 2.0 * before["stress"][0] > 0.0
    # the wider height margin of reach() reaches asperities that the bound of before excluded
    assert after["n_active"] > before["n_active"]


def test_a_first_compile_says_so_once_per_group_on_a_terminal():
    import io

    from numba.core import event

    class Event:
        def __init__(self, f):
            self.data = {"dispatcher": type("D", (), {"py_func": f})()}

    def fake(module, qualname):
        def f():
            pass
        f.__module__, f.__qualname__ = module, qualname
        return f

    out = io.StringIO()
    notice = jit.CompileNotice(stream=out, isatty=lambda: True)
    for module, name in (("asperity_sim.kernels.history", "slot_pass__mdr_follow_0123456789ab"),
                         ("asperity_sim.kernels.commit", "commit_slots__mdr_follow_0123456789ab"),
                         ("asperity_sim.sampling.draws", "inverse_cdfs__0123456789ab"),
                         ("asperity_sim.kernels.history", "slot_pass__test_gain_birth_0123456789ab"),
                         ("numpy_user_module", "other__0123456789ab")):
        notice.on_start(Event(fake(module, name)))
    lines = out.getvalue().splitlines()
    assert [line.split(" (")[0] for line in lines] == [
        "asperity_sim: compiling the mdr law's kernels", "asperity_sim: compiling the shared kernels",
        "asperity_sim: compiling the test_gain law's kernels"]
    assert "(policy follow)" in lines[0] and "(policy birth)" in lines[2]
    quiet = io.StringIO()
    silent = jit.CompileNotice(stream=quiet, isatty=lambda: False)
    silent.on_start(Event(fake("asperity_sim.kernels.history", "slot_pass__mdr_follow_0123456789ab")))
    assert quiet.getvalue() == ""
    assert isinstance(jit.NOTICE, event.Listener)


def test_ready_says_whether_a_call_would_compile():
    """jit.ready: False for argument types with no machine code in this process or the cache, True once compiled."""
    f = numba.njit(lambda x: x + 1.0)  # no on-disk cache: nothing to load
    assert not jit.ready(f, (1.0,))
    assert f(1.0) == 2.0
    assert jit.ready(f, (1.0,)) and not jit.ready(f, (np.zeros(2),))
