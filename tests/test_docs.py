"""The documentation's generated pages are up to date with the output registry and the law registry."""

import importlib.util
from pathlib import Path

from support import study

DOCS = Path(__file__).resolve().parent.parent / "docs"


def test_variables_page_is_generated_from_the_registry():
    spec = importlib.util.spec_from_file_location("make_variables", DOCS / "make_variables.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    committed = (DOCS / "variables.md").read_text(encoding="utf-8")
    assert committed == mod.render(), "docs/variables.md is stale: run python3 docs/make_variables.py"


def test_laws_page_is_generated_from_the_law_registry():
    spec = importlib.util.spec_from_file_location("make_laws", DOCS / "make_laws.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    committed = (DOCS / "laws.md").read_text(encoding="utf-8")
    assert committed == mod.render(), "docs/laws.md is stale: run python3 docs/make_laws.py"
    for name in ("paper", "mdr", "`k`", "`spring_dtype`", "coarsenings"):
        assert name in committed


ROOT = DOCS.parent
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _blocks(text, lang):
    out, inside, lines = [], False, []
    for line in text.splitlines():
        if line.startswith("```"):
            if inside:
                out.append("\n".join(lines))
                inside, lines = False, []
            elif line[3:].strip() == lang:
                inside = True
            continue
        if inside:
            lines.append(line)
    return out


def test_readme_is_a_short_front_door_with_the_ci_test_command():
    assert len(README.splitlines()) <= 150
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    command = 'python3 -m pip install -e ".[test]" && python3 -m pytest'
    assert command in ci and command in _blocks(README, "bash")


def test_readme_scene_example_is_a_valid_scene(tmp_path):
    from asperity_sim.runs.scene import load_scene

    (toml,) = _blocks(README, "toml")
    scene_file = tmp_path / "my_scene.toml"
    scene_file.write_text(toml, encoding="utf-8")
    scene = load_scene(scene_file)
    assert len(scene.path.stages) == 2


def test_version_is_the_same_everywhere_and_in_the_changelog():
    import asperity_sim
    from asperity_sim.runs.scene import tomllib  # the standard library's, or tomli on Python 3.10

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert project["version"] == asperity_sim.__version__
    assert f"## {asperity_sim.__version__} " in (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")


# --------------------------------------------------------------------------- generated files and reference results

RESULTS = DOCS / "results"


def _reference_results():
    return study("reference_results")


def test_docs_results_holds_exactly_what_the_regenerating_command_lists():
    """docs/results/ = the files the tasks of studies/reference_results.py copy there + the kept records."""
    mod = _reference_results()
    listed = {f for task in mod.TASKS.values() for f in task.keep} | set(mod.RECORDS) | {"README.md"}
    present = {p.name for p in RESULTS.iterdir()}
    assert present == listed, (f"in docs/results but not listed: {sorted(present - listed)}; "
                               f"listed but missing: {sorted(listed - present)}")
    overview = (RESULTS / "README.md").read_text(encoding="utf-8")
    for name in mod.TASKS:
        assert f"`{name}`" in overview, f"docs/results/README.md does not describe the task {name}"


def _mentions():
    """(page, target) for every link or path of the docs into docs/results/ or outputs/ (figures alike)."""
    import re

    pages = [ROOT / "README.md"] + sorted(p for p in DOCS.glob("*.md"))
    pattern = re.compile(r"\]\((?:\.\./)?((?:docs/)?results/[^)\s#]+|(?:\.\./)?outputs/[^)\s#]+)\)"
                         r"|`((?:docs/)?results/[A-Za-z0-9_.]+)`")
    for page in pages:
        for m in pattern.finditer(page.read_text(encoding="utf-8")):
            yield page, m.group(1) or m.group(2)


def test_every_reference_the_docs_make_into_docs_results_exists():
    seen = 0
    for page, target in _mentions():
        if "NAME" in target:  # a placeholder (development.md: how to link a figure)
            continue
        assert not target.lstrip("./").startswith("outputs/"), \
            f"{page.name} links {target}: outputs/ is not tracked, link docs/results/ instead"
        base = ROOT if page.name == "README.md" or target.startswith("docs/") else DOCS
        assert (base / target).is_file(), f"{page.name} refers to {target}, which does not exist"
        seen += 1
    assert seen >= 10  # the figures of the validation page alone


def test_outputs_is_ignored_by_git_except_its_readme():
    import shutil
    import subprocess

    import pytest

    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")

    def ignored(path):
        r = subprocess.run(["git", "check-ignore", "-q", "--no-index", path], cwd=ROOT)
        assert r.returncode in (0, 1), r
        return r.returncode == 0

    for generated in ("outputs/three_step_R1.nc", "outputs/convergence.png", "outputs/run.log",
                      "outputs/checkpoints/run.npz", "outputs/reference_results/paper/three_step.png"):
        assert ignored(generated), generated
    for kept in ("outputs/README.md", "docs/results/three_step.png", "docs/results/stability.md"):
        assert not ignored(kept), kept
