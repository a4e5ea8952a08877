"""The documentation's generated page is up to date with the output registry."""

import importlib.util
from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent / "docs"


def test_variables_page_is_generated_from_the_registry():
    spec = importlib.util.spec_from_file_location("make_variables", DOCS / "make_variables.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    committed = (DOCS / "variables.md").read_text(encoding="utf-8")
    assert committed == mod.render(), "docs/variables.md is stale: run python3 docs/make_variables.py"
