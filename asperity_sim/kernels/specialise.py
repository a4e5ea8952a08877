"""The reduction kernels of one law: templates compiled with the law's kernels bound in.

Owns :func:`kernels` (a law and an angle policy -> its compiled reductions, built once each) and
:func:`specialise`, which builds them.

A template (``@template(...)``, :mod:`asperity_sim.jit`) is a plain function of
:mod:`~asperity_sim.kernels.reductions` (path-independent laws), :mod:`~asperity_sim.kernels.history`
or :mod:`~asperity_sim.kernels.commit` (history laws) that calls the law through placeholders
defined at the top of its module: ``local``; ``trial`` and ``trial_block``; ``commit_law`` and
``commit_block``.  For each law every template of its family is copied with globals in which
the placeholders are that law's kernels (a law without block kernels gets :func:`each_contact`
and :func:`each_commit`, which call its per-contact kernels), ``BIRTH`` is the angle policy
(a constant: the other policy's branches are pruned before numba types them, so a scene
compiles only its own) and every template name is the law's own copy, then compiled with the
options of its decorator under the name ``<template>__<law>_<policy>_<fingerprint>``.  A
closure over the law's kernels, or kernels passed as arguments, would defeat numba's on-disk
cache; named copies of plain functions keep it, each law cached apart.  The fingerprint (:func:`law_fingerprint`) covers every kernel source of the
package and the law's own files, so no edit in a copy's call graph leaves it stale.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import types
from pathlib import Path

import numba

from .. import laws
from ..jit import PACKAGE, source_fingerprint, tag
from . import commit, history, loop, loop_history, loop_path_independent, reductions

FAMILIES = {"path_independent": (reductions, loop, loop_path_independent),
            "history": (history, commit, loop, loop_history)}
"""The template modules of each kind of law."""


def templates_of(module) -> dict:
    """The templates defined in ``module`` (name -> plain function with its ``jit_options``)."""
    return {name: f for name, f in vars(module).items()
            if callable(f) and hasattr(f, "jit_options") and f.__module__ == module.__name__}


def law_kernels(law: laws.Law) -> dict:
    """What the placeholders of the law's templates become (name -> kernel, or the name of a template)."""
    if law.path_independent:
        return {"local": law.local}
    h = law.history
    return {"trial": h.trial, "commit_law": h.commit,
            "trial_block": h.trial_block if h.trial_block is not None else "each_contact",
            "commit_block": h.commit_block if h.commit_block is not None else "each_commit"}


def law_fingerprint(law: laws.Law) -> str:
    """Short hash of what the law's copies are compiled from: the package's kernel sources and the law's files.

    A law defined outside the package (a test module, say) adds the files of its own kernels.
    """
    h = hashlib.sha256(f"{law.name}:{source_fingerprint()}".encode())
    for f in law_kernels(law).values():
        if callable(f):
            path = Path(inspect.getsourcefile(getattr(f, "py_func", f))).resolve()
            if PACKAGE not in path.parents:
                h.update(path.read_bytes())
    return h.hexdigest()[:12]


def specialise(modules, law: laws.Law, birth: bool = False) -> dict:
    """The templates of ``modules`` compiled for ``law`` under policy birth or follow (name -> numba dispatcher)."""
    bindings = law_kernels(law)
    label = f"{law.name}-{'birth' if birth else 'follow'}-{law_fingerprint(law)}"
    namespaces, out = [], {}
    for module in modules:
        namespace = {**vars(module), **{k: v for k, v in bindings.items() if callable(v)}, "BIRTH": bool(birth)}
        namespaces.append(namespace)
        for name, f in templates_of(module).items():
            copy = types.FunctionType(f.__code__, namespace, f.__name__, f.__defaults__, f.__closure__)
            copy.__qualname__, copy.__module__, copy.__doc__ = f.__qualname__, f.__module__, f.__doc__
            out[name] = numba.njit(**f.jit_options)(tag(copy, label))
    for namespace in namespaces:  # each template name, and a default the law does not replace, is the law's copy
        namespace.update(out)
        namespace.update({k: out[v] for k, v in bindings.items() if isinstance(v, str)})
    return out


@functools.lru_cache(maxsize=None)
def _compiled(law: laws.Law, birth: bool) -> dict:
    return specialise(FAMILIES["path_independent" if law.path_independent else "history"], law, birth)


def kernels(law, birth: bool = False) -> dict:
    """The reductions compiled for ``law`` (a registered name or a :class:`~asperity_sim.laws.Law`) under policy
    birth (``birth``) or follow, built once.  Each runs only on the angles of its policy: ``theta_birth`` of
    size n under birth, empty under follow."""
    return _compiled(laws.get(law), bool(birth))
