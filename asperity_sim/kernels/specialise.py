"""The reduction kernels of one law: templates compiled with the law's kernels bound in.

Owns :func:`kernels` (law -> its compiled reductions, built once per law) and
:func:`specialise`, which copies each template with the law's kernels bound to its free names
and compiles it under a name that carries the law and a fingerprint of its source, so numba's
on-disk cache keeps each law's kernels apart (a function passed to a kernel as an argument, or
captured in a closure, would defeat that cache).
"""

from __future__ import annotations

import functools
import types

from .. import laws
from ..laws import Law


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

    namespaces = {}  # one per template module: the templates of a module call only each other
    tag = f"{law.name}-{law.fingerprint}"
    out = {}
    for name, f in templates.items():
        namespace = namespaces.setdefault(f.__module__, {**f.__globals__, **bindings})
        copy = types.FunctionType(f.__code__, namespace, f.__name__, f.__defaults__, f.__closure__)
        copy.__qualname__ = f"{f.__qualname__}[{tag}]"
        copy.__module__ = f.__module__
        copy.__doc__ = f.__doc__
        out[name] = numba.njit(**jit[name])(copy)
    for namespace in namespaces.values():
        namespace.update(out)
        for name, template in (aliases or {}).items():  # a binding that is one of the templates' own copies
            namespace[name] = out[template]
    return out


_PATH_INDEPENDENT = {"values_follow": dict(cache=True, inline="always", error_model="numpy"),
                     "chunk_follow": dict(cache=True, error_model="numpy"),
                     "chunk_birth": dict(cache=True, inline="always", error_model="numpy"),
                     "chunk_any": dict(cache=True, inline="always", error_model="numpy"),
                     "reduce_parallel": dict(cache=True, parallel=True, error_model="numpy"),
                     "reduce_serial": dict(cache=True, error_model="numpy"),
                     "snapshot_local": dict(cache=True, parallel=True, error_model="numpy")}
_HISTORY = {"slot_pass": dict(cache=True, parallel=True, error_model="numpy"),
            "fresh_pass": dict(cache=True, parallel=True, error_model="numpy"),
            "commit_slots": dict(cache=True, parallel=True, error_model="numpy"),
            "commit_fresh": dict(cache=True, parallel=True, error_model="numpy"),
            "snapshot_slots": dict(cache=True, parallel=True, error_model="numpy"),
            "each_contact": dict(cache=True, error_model="numpy"),
            "each_commit": dict(cache=True, error_model="numpy")}


@functools.lru_cache(maxsize=None)
def _kernels_of(law: laws.Law) -> dict:
    templates = _PATH_INDEPENDENT if law.path_independent else _HISTORY
    from . import commit, history, reductions

    g = {**vars(reductions), **vars(history), **vars(commit)}
    aliases = {}
    if law.path_independent:
        bindings = {"local": law.local}
    else:
        bindings = {"trial": law.history.trial, "commit_law": law.history.commit}
        for name, default, given in (("trial_block", "each_contact", law.history.trial_block),
                                     ("commit_block", "each_commit", law.history.commit_block)):
            if given is None:
                aliases[name] = default
            else:
                bindings[name] = given
    return specialise({name: g[name] for name in templates}, law, bindings, templates, aliases)


def kernels(law) -> dict:
    """The generic kernels compiled for ``law`` (name -> numba dispatcher), built once per law."""
    return _kernels_of(laws.get(law))
