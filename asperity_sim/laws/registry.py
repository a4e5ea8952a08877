"""The law protocol (:class:`Law`, :class:`History`) and the registry of laws (:func:`register`, :func:`get`).

See :mod:`asperity_sim.laws` for what a law gives.  The registry is the one list of laws the
rest of the package asks (the command line's choices, the keys of scene files, the fields of
checkpoints, the cost model of sweeps, the documentation); a law module registers itself
when it is imported.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from ..output.variables import Var
from .options import Cost, Options

OUT, STICK, PARTIAL, FULL_SLIP = 0, 1, 2, 3  # contact state codes


@dataclass(frozen=True)
class NoOptions(Options):
    """The options of a law that has none."""


@dataclass(frozen=True)
class History:
    """What a history law keeps per contact, and its two kernels.

    arrays : (capacity, options) -> tuple of zeroed arrays whose first axis is the slot (the committed
        state takes their shapes and dtypes and reserves zeroed arrays of them for every slot)
    trial, commit : numba kernels (see the module docstring)
    events : name of the per-step count that ``commit`` returns as ``events`` (e.g. coarsenings),
        one of the law's ``variables``
    bytes_per_contact : (options) -> bytes of the arrays per slot
    validate : (arrays, live slots) -> None, raising ValueError for a state the kernels cannot use
        (read from a checkpoint, say)
    trial_block, commit_block : optional numba kernels, the trial and the commit of the committed
        contacts of a block of slots (see the module docstring); without them, one by one
    """

    arrays: Callable
    trial: Callable
    commit: Callable
    events: str
    bytes_per_contact: Callable
    validate: Callable | None = None  # (arrays, live slots) -> None, ValueError if the state cannot be used
    trial_block: Callable | None = None  # the trial of a block of committed contacts (module docstring)
    commit_block: Callable | None = None  # the commit of a block of committed contacts (module docstring)


@dataclass(frozen=True)
class Law:
    """An asperity law (see the module docstring).

    name : registry key (``simulate(..., law=name)``)
    summary : one line for listings and output attributes
    constants : (params, options) -> tuple of floats passed to every kernel call
    local : path-independent kernel, or None for a history law
    history : :class:`History`, or None for a path-independent law
    domain : the load paths on which the law is valid, in words (output attributes, warnings)
    options : its options, a frozen dataclass derived from :class:`~asperity_sim.laws.options.Options`
    cost : its run-time model (:class:`~asperity_sim.laws.options.Cost`), or None (a sweep then says it
        cannot estimate and runs serially)
    variables : the law's own per-step output variables (name -> Var): a history law's event count
        (``History.events``), none for a path-independent law
    attributes : (options, state arrays) -> output attributes of a run (default: the options)
    """

    name: str
    summary: str
    constants: Callable
    local: Callable | None = None
    history: History | None = None
    domain: str = "any path"
    options: type = NoOptions
    cost: Cost | None = None
    variables: dict = field(default_factory=dict)
    attributes: Callable | None = None
    def __post_init__(self):
        if (self.local is None) == (self.history is None):
            raise ValueError(f"law {self.name!r}: give exactly one of local (path independent) or history")
        if not (isinstance(self.options, type) and issubclass(self.options, Options)):
            raise ValueError(f"law {self.name!r}: options = {self.options!r} is not an Options dataclass")
        if not all(isinstance(v, Var) for v in self.variables.values()):
            raise ValueError(f"law {self.name!r}: every variable must be a Var (dims, dtype, units, long name)")
        recorded = {self.history.events} if self.history is not None else set()
        if set(self.variables) != recorded:  # what a run can fill: a history law's event count
            raise ValueError(f"law {self.name!r}: variables {sorted(self.variables)} must be "
                             f"{sorted(recorded) or 'none'} (a history law declares its event count, History.events)")

    def __hash__(self):  # the variables are a dict: a law is identified by its name and kernels
        return hash((self.name, self.local, self.history))

    def run_attributes(self, options, arrays=()) -> dict:
        """Output attributes of a run with these options (and, for a history law, its state arrays)."""
        return self.attributes(options, arrays) if self.attributes is not None else options.attributes()

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


def option_names() -> dict:
    """option name -> the registered laws that declare it (in registry order)."""
    out = {}
    for law in LAWS.values():
        for name in law.options.names():
            out.setdefault(name, []).append(law.name)
    return out


def options_of(law, given: dict | None = None):
    """The options of ``law`` from keyword values ``given`` (name -> value), checked.

    The law's own options are taken and checked by its :class:`~asperity_sim.laws.options.Options`;
    an option that only other registered laws declare is accepted and ignored (one call can loop
    over laws), after the first law that declares it has checked its value; a name no registered law
    declares raises ``ValueError`` listing every option.
    """
    law = get(law)
    given = dict(given or {})
    own = {k: v for k, v in given.items() if k in law.options.names()}
    known = option_names()
    for name, value in given.items():
        if name in own:
            continue
        if name not in known:
            listing = "; ".join(f"{n} (law {', '.join(ls)})" for n, ls in known.items()) or "none"
            raise ValueError(f"{name} = {value!r} is not an option of any law (options: {listing})")
        other = LAWS[known[name][0]]
        other.options(**{name: value})  # checked, then ignored by this law
    return law.options(**own)


def get(name) -> Law:
    """The registered law called ``name``; a ValueError lists the valid names otherwise."""
    if isinstance(name, Law):
        return name
    try:
        return LAWS[name]
    except (KeyError, TypeError):
        raise ValueError(f"law = {name!r} is not known (valid: {', '.join(LAWS)})") from None

