"""Asperity laws: the protocol every law follows, and the registry that maps names to laws.

A law is the physics of one asperity contact in its local frame (n, s, t), given its local
displacement: the contact force (f_n, f_s, f_t) and its exact Jacobian.  Everything else
(orientations, frames, which asperities may touch, the sums over the population, the
standard errors, the per-contact bookkeeping) is generic and lives in
:mod:`asperity_sim.assemble` (reductions) and :mod:`asperity_sim.state` (committed state).

A law is one module that defines numba kernels and a :class:`Law` object, and calls
:func:`register`.  Two kinds:

- **path independent** (``history=None``): ``local(dn, ds, dt, R, consts)`` with the total
  local displacements returns ``(f_n, f_s, f_t, J00, J01, J02, J10, J11, J12, J20, J21, J22,
  code)``, J = d(f_n, f_s, f_t)/d(dn, ds, dt), code 1 stick, 2 partial slip, 3 full slip.
  It is called with any dn (the caller keeps only dn > 0), so it must return finite values
  for any input; written without branches (selects instead), the population loop vectorises.
- **history** (``history=History(...)``): the law keeps per-contact arrays (first axis: the
  contact's slot).  ``trial(dn, dds, ddt, dn_c, dn_ref, R, consts, arrays, sl, fresh)`` gives
  the same 13 values from the committed state of slot ``sl`` plus the local increment (dds,
  ddt) since the committed displacement (``fresh``: no committed contact, ``sl`` unused;
  ``dn_ref``: the overlap a fresh contact is expected to reach, 0 if unknown) and never
  writes; ``commit(..., scratch)`` writes the state at the converged displacement (dn <= 0:
  the contact is lost and its memory erased) and returns ``(code, work, stored,
  dissipation, events)`` [J] for the energy balance.  Optionally ``trial_block(dn, dds, ddt, R,
  dn_c, b0, m, consts, arrays, out)`` gives ``out[:, i]`` = the trial of the committed contact
  in slot b0 + i (i < m) from block rows of its overlap, increment and radius where dn[i] > 0,
  zeros elsewhere, and ``commit_block(dn, dds, ddt, R, dn_c, b0, m, live, consts, arrays,
  scratch, res)`` gives ``res[:, i]`` = the 5 values of ``commit`` of slot b0 + i where
  ``live[i]``: a law may then arrange the work over a block (vectorised per-contact scalars,
  say); without them the generic reductions call ``trial`` and ``commit`` contact by contact.

``consts`` is the tuple of floats ``law.constants(params, k)`` (built once per run, so
kernels never see Python objects).  Kernels must be ``@numba.njit(cache=True,
inline="always")`` free functions; the generic reductions are compiled once per law
(:func:`specialise`), because a function passed to a numba kernel as an argument, or
captured in a closure, defeats numba's on-disk cache.
"""

from __future__ import annotations

import hashlib
import inspect
import types
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

__all__ = ["Law", "History", "LAWS", "register", "get", "specialise", "STICK", "PARTIAL", "FULL_SLIP"]

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

    @property
    def fingerprint(self) -> str:
        """Short hash of the source the law's kernels are built from: compiled reductions are cached under it.

        numba invalidates a cached kernel only when its own file changes, not when a function it
        calls does; the hash covers the files that define the law's kernels, the shared Hertz
        contact, the geometry and the prefetch, so a change in any of them compiles anew (a law
        whose kernels call helpers from other files should keep them in its own file).
        """
        h = self.history
        funcs = [self.local] if h is None else [h.trial, h.commit, h.trial_block, h.commit_block]
        files = {Path(inspect.getsourcefile(getattr(f, "py_func", f))) for f in funcs if f is not None}
        here = Path(__file__).parent
        files |= {here / "hertz.py", here.parent / "geometry.py", here.parent / "prefetch.py"}
        h = hashlib.sha256(self.name.encode())
        for path in sorted(files):
            h.update(path.read_bytes())
        return h.hexdigest()[:12]


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


def specialise(templates: dict, law: Law, bindings: dict, jit: dict, aliases: dict | None = None) -> dict:
    """numba kernels of the generic ``templates`` (name -> plain function) bound to one law.

    Each template is copied with globals where the names in ``bindings`` (e.g. ``local``)
    refer to the law's kernels and each template name refers to its own bound copy, and
    compiled with the options ``jit[name]``.  The copies get the qualified name
    ``<template>[<law name>-<fingerprint>]``, so numba caches each law's kernels on disk
    under their own name, and a changed law compiles anew.  ``aliases`` (name -> template name)
    bind further names to the bound copies (a default for a kernel the law does not give).
    """
    import numba

    first = next(iter(templates.values()))
    namespace = dict(first.__globals__)
    namespace.update(bindings)
    tag = f"{law.name}-{law.fingerprint}"
    out = {}
    for name, f in templates.items():
        copy = types.FunctionType(f.__code__, namespace, f.__name__, f.__defaults__, f.__closure__)
        copy.__qualname__ = f"{f.__qualname__}[{tag}]"
        copy.__module__ = f.__module__
        copy.__doc__ = f.__doc__
        out[name] = numba.njit(**jit[name])(copy)
    namespace.update(out)
    for name, template in (aliases or {}).items():  # a binding that is one of the templates' own copies
        namespace[name] = out[template]
    return out


from . import paper  # noqa: E402,I001  (the built-in laws register themselves, in this order)
from . import mdr  # noqa: E402
