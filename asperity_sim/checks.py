"""Checks of inputs: the one home of the validators every entry point uses.

Each check returns the value in its canonical type (float, int, array) or raises ``ValueError``
(or the ``error`` class given, such as :class:`~asperity_sim.errors.SceneError` for a scene
file) with one message shape: ``name = value`` what is wrong ``(valid range: ...)`` or
``(valid: ...)``.  Python's own API, scene and sweep files, checkpoints and law options all
check through these, so the same bad value reads the same wherever it comes from.
"""

from __future__ import annotations

import math
import numbers
import os
import re

import numpy as np

__all__ = ["check_real", "check_int", "check_choice", "check_delta", "check_file", "check_writable", "range_text"]


def range_text(lo, hi, lo_open=False, hi_open=False) -> str:
    """The valid range of a real in words: ``> 0``, ``[0, 1]``, ``any finite real``."""
    if lo is None and hi is None:
        return "any finite real"
    if hi is None:
        return f"{'>' if lo_open else '>='} {lo:g}"
    if lo is None:
        return f"{'<' if hi_open else '<='} {hi:g}"
    return f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"


def check_real(name: str, value, lo=None, hi=None, lo_open=False, hi_open=False, allow_inf=False,
               error=ValueError) -> float:
    """``value`` as a float in the range given (open or closed ends; None: unbounded)."""
    rng = range_text(lo, hi, lo_open, hi_open)
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise error(f"{name} = {value!r} is not a real number (valid range: {rng})")
    v = float(value)
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise error(f"{name} = {v!r} is not finite (valid range: {rng})")
    bad_lo = lo is not None and (v <= lo if lo_open else v < lo)
    bad_hi = hi is not None and (v >= hi if hi_open else v > hi)
    if bad_lo or bad_hi:
        raise error(f"{name} = {v!r} is out of range (valid range: {rng})")
    return v


def check_int(name: str, value, lo, hi=None, error=ValueError) -> int:
    """``value`` as an int in [lo, hi] (``hi`` None: no upper bound).

    A string, float or bool is "not an integer" (a quoted integer, as a TOML file may hold,
    says to drop the quotes); an integer outside the bounds is "out of range".
    """
    rng = f"integer >= {lo}" if hi is None else f"integer in [{lo}, {hi}]"
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        hint = f": write {value.strip()} without quotes" if isinstance(value, str) \
            and re.fullmatch(r"\s*[+-]?\d+\s*", value) else ""
        raise error(f"{name} = {value!r} is not an integer{hint} (valid range: {rng})")
    if value < lo or (hi is not None and value > hi):
        raise error(f"{name} = {value!r} is out of range (valid range: {rng})")
    return int(value)


def check_choice(name: str, value, valid, error=ValueError):
    """``value`` if it is one of ``valid``."""
    try:
        known = value in valid
    except TypeError:  # an unhashable value
        known = False
    if not known:
        raise error(f"{name} = {value!r} is not known (valid: {', '.join(map(str, valid))})")
    return value


def check_delta(delta) -> np.ndarray:
    """An interface displacement Delta as a finite float array (3,) [m]."""
    d = np.asarray(delta, dtype=float)
    if d.shape != (3,):
        raise ValueError(f"delta = {delta!r} must have shape (3,) [m], got shape {d.shape}")
    if not all(map(math.isfinite, d.tolist())):
        raise ValueError(f"delta = {d!r} [m] is not finite (valid range: finite reals)")
    return d


def check_file(name: str, value):
    """A file path (str or os.PathLike, not empty), or None."""
    if value is None:
        return None
    if not isinstance(value, (str, os.PathLike)) or not os.fspath(value):
        raise ValueError(f"{name} = {value!r} is not a file path (valid: str or os.PathLike, or None)")
    return value


def check_writable(name: str, value):
    """A file path that can be written, checked before any work: not a folder, and its folder exists and is
    writable or can be created (the nearest existing ancestor is a writable folder, not a file)."""
    if value is None:
        return None
    path = os.path.abspath(os.fspath(value))
    valid = "valid: a file path in a writable folder"
    if os.path.isdir(path):
        raise ValueError(f"{name} = {os.fspath(value)!r} is a folder ({valid})")
    ancestor = os.path.dirname(path)
    while not os.path.exists(ancestor):
        ancestor = os.path.dirname(ancestor)
    if not os.path.isdir(ancestor):
        raise ValueError(f"{name} = {os.fspath(value)!r} lies under {ancestor!r}, which is a file ({valid})")
    if not os.access(ancestor, os.W_OK):
        raise ValueError(f"{name} = {os.fspath(value)!r}: the folder {ancestor!r} is not writable ({valid})")
    return value
