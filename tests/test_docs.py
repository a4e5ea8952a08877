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
    from asperity_sim.scene import load_scene

    (toml,) = _blocks(README, "toml")
    scene_file = tmp_path / "my_scene.toml"
    scene_file.write_text(toml, encoding="utf-8")
    scene = load_scene(scene_file)
    assert len(scene.path.stages) == 2


def test_version_is_the_same_everywhere_and_in_the_changelog():
    import asperity_sim
    from asperity_sim.scene import tomllib  # the standard library's, or tomli on Python 3.10

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert project["version"] == asperity_sim.__version__
    assert f"## {asperity_sim.__version__} " in (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
