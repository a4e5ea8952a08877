"""Asperity laws: the protocol every law follows, and the registry that maps names to laws.

A law is the physics of one asperity contact in its local frame (n, s, t), given its local
displacement: the contact force (f_n, f_s, f_t) and its exact Jacobian.  Everything else
(orientations, frames, which asperities may touch, the sums over the population, the
standard errors, the per-contact bookkeeping) is generic and lives in
:mod:`asperity_sim.kernels.evaluate` (reductions) and :mod:`asperity_sim.kernels.state` (committed state).

A law is one module that defines its kernels and a :class:`Law` object, and calls
:func:`register`; the Law declares, besides its kernels, its options (a frozen dataclass of
:func:`option` fields, :class:`Options`), its cost model (:class:`Cost`, for sweeps), its own
per-step output variables and its run attributes.  The rest of the package (``simulate``,
scene files, checkpoints, sweeps, the command line, the documentation) takes all of these from
the registry.  Two kinds:

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

``consts`` is the tuple of floats ``law.constants(params, options)`` (built once per run, so
kernels never see Python objects).  Kernels are free functions compiled with
``@kernel(inline="always")`` (:mod:`asperity_sim.jit`; ``numba.njit(cache=True, inline="always")``
in a module outside the package); the generic reductions are compiled once per law
(:mod:`asperity_sim.kernels.specialise`), because a function passed to a numba kernel as an
argument, or captured in a closure, defeats numba's on-disk cache.
"""

from .options import Cost, Options, option
from .registry import (
           FULL_SLIP,
           LAWS,
           OUT,
           PARTIAL,
           STICK,
           History,
           Law,
           NoOptions,
           get,
           option_names,
           options_of,
           register,
)

# isort: split
# the built-in laws register themselves, in this order
from . import paper  # noqa: E402,I001
from . import mdr  # noqa: E402,I001

__all__ = ["Law", "History", "Options", "NoOptions", "option", "Cost", "LAWS", "register", "get", "options_of",
           "option_names", "OUT", "STICK", "PARTIAL", "FULL_SLIP"]
