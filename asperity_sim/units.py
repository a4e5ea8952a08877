"""Quantities with units: reading and writing the values of scene and sweep files.

Owns the translation between strings such as ``"50 um"`` or ``"1 GPa"`` and SI floats
(:func:`parse_quantity`, read by :mod:`pint`: any unit of the right dimension works) and
back (:func:`format_quantity`).  A value that cannot be read raises
:class:`~asperity_sim.errors.SceneError` naming the key, the value and the unit expected.
"""

from __future__ import annotations

import functools
import math
import numbers
import re
from decimal import Decimal

from .errors import SceneError

# -- units ------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def unit_registry():
    """The package's :class:`pint.UnitRegistry`, created on first use (pint costs ~0.5 s to import and set up).

    Its numbers are :class:`decimal.Decimal`, so a conversion is exact in decimal arithmetic and
    rounded once to a float: ``"15 um"`` is the float ``15e-6`` (not ``15 * 1e-6``).
    """
    import pint

    return pint.UnitRegistry(non_int_type=Decimal)


_KINDS = {  # SI unit (UDUNITS spelling) -> (what it is, pint spelling, examples of accepted units, example)
    "m": ("a length", "m", "nm, um (µm), mm, cm, m", "um"),
    "Pa": ("a stress", "Pa", "Pa, kPa, MPa, GPa", "MPa"),
    "m-2": ("an areal density", "m**-2", "1/mm2, 1/um2, mm-2, 1/mm^2", "1/mm2"),
    "1": ("a dimensionless number", "dimensionless", "a plain number or %", ""),
    "rad": ("an angle", "radian", "deg, rad", "deg"),
}
"""The quantities of scene files, by SI unit.  pint reads any unit of the right dimension."""
_ANGLE_UNITS = ("radian", "degree", "arcminute", "arcsecond", "turn", "gradian")
_QUANTITY = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*(.*?)\s*$")
_SUPERSCRIPTS = str.maketrans("⁻⁰¹²³⁴⁵⁶⁷⁸⁹", "-0123456789")


def _pint_units(text: str) -> str:
    """A unit written as in the scene files (UDUNITS ``m-2``, ``mm2``, ``/mm2``, ``mm^2``, ``mm²``) in pint's syntax."""
    text = text.strip()
    if text.startswith("/"):
        text = "1" + text
    text = re.sub(r"([⁻]?[⁰¹²³⁴⁵⁶⁷⁸⁹]+)", lambda m: "**" + m.group(1).translate(_SUPERSCRIPTS), text)
    text = text.replace("^", "**")
    # an exponent written straight after a unit name: m-2, mm2 (pint would read "m-2" as m minus 2)
    return re.sub(r"(?<=[^\W\d])([+-]?\d+)", r"**\1", text)


def _dimension_name(dimensionality) -> str:
    """``a length``, ``a stress``, ... for a pint dimensionality (its own text for others)."""
    ureg = unit_registry()
    for si, (kind, spelling, *_) in _KINDS.items():
        if si != "rad" and ureg.parse_units(spelling).dimensionality == dimensionality:
            return kind
    return f"a quantity of dimension {dimensionality}"


def parse_quantity(value, si_unit: str, name: str = "value") -> float:
    """A TOML value as a float in SI, read with :mod:`pint`.

    value : a plain number (already in SI) or a string ``"<number> <unit>"`` (``"50 um"``,
        ``"500 MPa"``, ``"200 /mm2"``, ``"30 deg"``); any unit pint knows of the right dimension
    si_unit : ``"m"``, ``"Pa"``, ``"m-2"``, ``"1"`` (dimensionless: a plain number, or a string
        such as ``"0.6"`` or ``"60 %"``) or ``"rad"`` (a string needs its unit)
    name : the key, as it starts the error message

    Raises :class:`SceneError` naming the key, the value and the expected dimension, e.g.
    ``sigma_n = '3 m': expected a stress (Pa), got a length``.
    """
    if isinstance(value, bool):
        raise SceneError(f"{name} = {value!r} is not a number")
    if isinstance(value, numbers.Real):
        v = float(value)
        if not math.isfinite(v):
            raise SceneError(f"{name} = {value!r} is not finite")
        return v
    if not isinstance(value, str):
        raise SceneError(f"{name} = {value!r} is not a number or a quantity string such as \"50 um\"")
    kind, spelling, shown, example = _KINDS[si_unit]
    expected = f"expected {kind} ({si_unit})"
    m = _QUANTITY.match(value)
    if not m:
        raise SceneError(f"{name} = {value!r} is not a quantity (write \"<number> <unit>\"; {expected}: {shown})")
    number, unit = m.groups()
    if not unit and si_unit != "1":
        raise SceneError(f"{name} = {value!r} has no unit (write e.g. \"{number} {example}\", "
                         f"or a plain number in {si_unit}); {expected}")
    ureg = unit_registry()
    try:
        units = ureg.parse_units(_pint_units(unit)) if unit else ureg.dimensionless
    except Exception as err:  # noqa: BLE001 - pint's UndefinedUnitError and its syntax errors
        names = getattr(err, "unit_names", None) or (unit,)
        names = (names,) if isinstance(names, str) else tuple(names)
        raise SceneError(f"{name} = {value!r}: unknown unit {names[0]!r}; {expected} such as {shown}") from None
    target = ureg.parse_units(spelling)
    if units.dimensionality != target.dimensionality or (si_unit == "rad" and str(units) not in _ANGLE_UNITS):
        raise SceneError(f"{name} = {value!r}: {expected}, got {_dimension_name(units.dimensionality)} "
                         f"({unit}); valid: {shown}")
    v = float(ureg.Quantity(Decimal(number), units).to(target).magnitude)
    if not math.isfinite(v):
        raise SceneError(f"{name} = {value!r} is not finite")
    return v


def format_quantity(value: float, si_unit: str) -> str:
    """A readable quantity string that :func:`parse_quantity` reads back (e.g. ``"50 um"``)."""
    choices = {"m": (("nm", 1e-9), ("um", 1e-6), ("mm", 1e-3), ("m", 1.0)),
               "Pa": (("Pa", 1.0), ("kPa", 1e3), ("MPa", 1e6), ("GPa", 1e9)),
               "m-2": (("1/m2", 1.0), ("1/mm2", 1e6), ("1/um2", 1e12))}.get(si_unit)
    if choices is None:
        return f"{value:.6g}"
    name, f = choices[0]
    for cand, cf in choices:
        if abs(value) >= cf:
            name, f = cand, cf
    return f"{value / f:.6g} {name}"
