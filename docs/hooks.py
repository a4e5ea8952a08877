"""MkDocs hook: the figures of the documentation are the files in ``outputs/``.

Pages link to figures as ``../outputs/NAME.png`` (so they also show on the repository's web
view); the site copies each figure to ``figures/NAME.png`` and rewrites the links.

Docstrings give units in brackets (``r : ndarray [m]``, ``E[sqrt R] [m^0.5]``); Markdown reads
``[a] [m]`` as a reference link and mkdocs-autorefs warns that it cannot find the target ``m``.
Those warnings, and only those (a target that is a unit, not a Python name), are dropped, so
that ``mkdocs build --strict`` still fails on every other warning.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

from mkdocs.structure.files import File

_LINK = re.compile(r"\]\(\.\./outputs/([^)\s]+\.(?:png|svg|jpg))\)")
_ROOT = Path(__file__).resolve().parent.parent
_UNIT = r"(?:[a-zA-Zµ]{1,3}(?:\^?-?[0-9.]+)?|1)"
_UNIT_TARGET = re.compile(rf"Could not find cross-reference target '{_UNIT}(?:[ /*]{_UNIT})*'")


class _UnitBrackets(logging.Filter):
    def filter(self, record):
        return not _UNIT_TARGET.search(record.getMessage())


def on_config(config):
    for handler in logging.getLogger("mkdocs").handlers:
        if not any(isinstance(f, _UnitBrackets) for f in handler.filters):
            handler.addFilter(_UnitBrackets())
    return config


def on_files(files, config):
    for fig in sorted((_ROOT / "outputs").glob("*.png")):
        files.append(File.generated(config, f"figures/{fig.name}", abs_src_path=str(fig)))
    return files


def on_page_markdown(markdown, page, config, files):
    depth = page.file.src_uri.count("/")
    prefix = "../" * depth
    return _LINK.sub(lambda m: f"]({prefix}figures/{m.group(1)})", markdown)
