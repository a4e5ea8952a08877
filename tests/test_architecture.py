"""The house rules of the package layout (docs/architecture.md), read from the source.

Imports flow one way between the subpackages, no module imports itself back through a cycle
(lazy imports inside functions count), no private name crosses a module boundary, no module
grows far beyond 400 lines, the module paths of 0.3 still work, with a warning, and the package's
public names, imported at their first use, are what their modules define.
"""

import ast
import importlib
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import asperity_sim

PACKAGE = Path(asperity_sim.__file__).resolve().parent
ORDER = ("foundation", "output", "sampling", "laws", "reference", "kernels", "solve", "analysis", "runs", "ui", "top")
"""Subpackages from the bottom up: a module imports only from its own layer and those before it.
``foundation`` is the top-level modules (inputs, numerics, checks, errors); ``top`` the package itself."""
MAX_LINES = 430


def _modules() -> dict:
    """module name -> (path, is a package)."""
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = (path, path.name == "__init__.py")
    return out


MODULES = _modules()


def _imports(name) -> list:
    """(imported module, imported names) of every import in the module, at any depth."""
    path, is_pkg = MODULES[name]
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_pkg else name.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] == "asperity_sim":
                found.append((target, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            found += [(a.name, []) for a in node.names if a.name.split(".")[0] == "asperity_sim"]
    return found


def _targets(name) -> set:
    """The package modules ``name`` imports (a name imported from a package counts as its submodule if it is one)."""
    out = set()
    for target, names in _imports(name):
        subs = {f"{target}.{n}" for n in names} & set(MODULES)
        out |= subs or {target}
    out.discard(name)
    return out & set(MODULES)


def _layer(name) -> str:
    parts = name.split(".")
    if len(parts) == 1 or parts[1] in ("deprecated", "__main__"):
        return "top"
    if len(parts) == 2 and not MODULES[name][1]:
        return "foundation"
    return parts[1]


def test_every_module_has_a_layer():
    assert {_layer(m) for m in MODULES} <= set(ORDER)


def test_imports_flow_one_way_between_subpackages():
    upward = sorted((m, t) for m in MODULES for t in _targets(m) if ORDER.index(_layer(t)) > ORDER.index(_layer(m)))
    assert upward == []


def test_no_import_cycle():
    graph = {m: _targets(m) for m in MODULES}
    state, cycles = {}, []

    def visit(m, stack):
        state[m] = "open"
        for t in sorted(graph[m]):
            if state.get(t) == "open":
                cycles.append(stack[stack.index(t):] + [t])
            elif t not in state:
                visit(t, stack + [t])
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert cycles == []


def test_no_private_name_crosses_a_module():
    crossing = sorted((m, t, n) for m in MODULES for t, names in _imports(m) for n in names
                      if n.startswith("_") and not n.startswith("__"))
    assert crossing == []


def test_no_module_far_beyond_400_lines():
    long = {m: n for m, (p, _) in MODULES.items() if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert long == {}


@pytest.mark.parametrize("old, name", [("assemble", "evaluate"), ("state", "ContactState"), ("driver", "simulate"),
                                       ("surfaces", "fit"), ("scene", "parse_quantity"), ("io", "write_netcdf")])
def test_the_paths_of_0_3_still_work_with_a_deprecation_warning(old, name):
    import asperity_sim.deprecated as deprecated

    deprecated._warned.discard(old)
    sys.modules.pop(f"asperity_sim.{old}", None)  # a stand-in made by an earlier test would not warn again
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(f"asperity_sim.{old}")
        value = getattr(module, name)
    assert callable(value)
    assert any(issubclass(w.category, DeprecationWarning) and f"asperity_sim.{old} moved" in str(w.message)
               for w in caught)
    assert getattr(importlib.import_module(f"asperity_sim.{deprecated.MOVED[old][0]}"), name, value) is value


def test_every_public_name_is_the_one_its_module_defines():
    """The package imports its public names at their first use: each is there, and is the object itself."""
    for name in asperity_sim.__all__:
        assert name in dir(asperity_sim)
        assert getattr(asperity_sim, name) is not None
    assert asperity_sim.simulate is importlib.import_module("asperity_sim.solve.driver").simulate
    assert asperity_sim.Population is importlib.import_module("asperity_sim.sampling.population").Population
    assert asperity_sim.laws is importlib.import_module("asperity_sim.laws")
    with pytest.raises(AttributeError, match="no_such_name"):
        asperity_sim.no_such_name  # noqa: B018


def test_a_run_and_the_compile_ahead_helper_start_without_the_output_libraries():
    """``simulate``, and the helper that compiles ahead in a fresh process, are reached without importing xarray
    or pandas (half a second that a first run would spend before it starts compiling)."""
    code = ("import sys, asperity_sim, asperity_sim.kernels.ahead_helper; asperity_sim.simulate; "
            "print(sorted(m for m in ('xarray', 'pandas') if m in sys.modules))")
    env = {**os.environ, "PYTHONPATH": str(PACKAGE.parent)}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert done.stdout.strip() == "[]"
