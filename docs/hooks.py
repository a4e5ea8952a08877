"""MkDocs hook: unit brackets in docstrings are not cross-references.

(The figures of the pages are the files in ``docs/results/``, linked as ``results/NAME.png``:
they are part of the site as they are, and also show on the repository's web view.)

Docstrings give units in brackets (``r : ndarray [m]``, ``E[sqrt R] [m^0.5]``); Markdown reads
``[a] [m]`` as a reference link and mkdocs-autorefs warns that it cannot find the target ``m``.
Those warnings, and only those (a target that is a unit, not a Python name), are dropped, so
that ``mkdocs build --strict`` still fails on every other warning.
"""

from __future__ import annotations

import logging
import re

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
