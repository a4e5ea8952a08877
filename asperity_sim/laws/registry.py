"""The law protocol (:class:`Law`, :class:`History`) and the registry of laws (:func:`register`, :func:`get`).

See :mod:`asperity_sim.laws` for what a law gives.  The registry is the one list of laws the
rest of the package asks; a law module registers itself when it is imported.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

OUT, STICK, PARTIAL, FULL_SLIP = 0, 1, 2, 3  # contact state codes


@dataclass(frozen=True)
class History:
    """What a history law keeps per contact, and its two kernels.

    arrays : (capacity, k, dtype) -> tuple of zeroed arrays whose first axis is the slot
    trial, commit : numba kernels (see the module docstring)
    events : name of the per-step count that ``commit`` returns as ``events`` (e.g. coarsenings)
    events_long_name : its long name in the output
    bytes_per_contact : (k, dtype) -> bytes of the arrays per slot
    validate : (arrays, live slots) -> None, raising ValueError for a state the kernels cannot use
        (read from a checkpoint, say)
    trial_block, commit_block : optional numba kernels, the trial and the commit of the committed
        contacts of a block of slots (see the module docstring); without them, one by one
    """

    arrays: Callable
    trial: Callable
    commit: Callable
    events: str
    events_long_name: str
    bytes_per_contact: Callable
    validate: Callable | None = None  # (arrays, live slots) -> None, ValueError if the state cannot be used
    trial_block: Callable | None = None  # the trial of a block of committed contacts (module docstring)
    commit_block: Callable | None = None  # the commit of a block of committed contacts (module docstring)


@dataclass(frozen=True)
class Law:
    """An asperity law (see the module docstring).

    name : registry key (``simulate(..., law=name)``)
    summary : one line for listings and output attributes
    constants : (params, k) -> tuple of floats passed to every kernel call
    local : path-independent kernel, or None for a history law
    history : :class:`History`, or None for a path-independent law
    domain : the load paths on which the law is valid, in words (output attributes, warnings)
    """

    name: str
    summary: str
    constants: Callable
    local: Callable | None = None
    history: History | None = None
    domain: str = "any path"
    spring_dtypes: tuple = field(default=("float64",))

    def __post_init__(self):
        if (self.local is None) == (self.history is None):
            raise ValueError(f"law {self.name!r}: give exactly one of local (path independent) or history")

    @property
    def path_independent(self) -> bool:
        return self.history is None


LAWS: dict[str, Law] = {}


def register(law: Law) -> Law:
    """Add ``law`` to the registry (replacing a law of the same name) and return it."""
    if not isinstance(law, Law):
        raise ValueError(f"law = {law!r} is not a Law")
    LAWS[law.name] = law
    return law


def get(name) -> Law:
    """The registered law called ``name``; a ValueError lists the valid names otherwise."""
    if isinstance(name, Law):
        return name
    try:
        return LAWS[name]
    except (KeyError, TypeError):
        raise ValueError(f"law = {name!r} is not known (valid: {', '.join(LAWS)})") from None

