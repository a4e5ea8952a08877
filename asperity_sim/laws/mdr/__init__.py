"""The ``mdr`` asperity law: Hertz normal force and a vector MDR tangential law with memory.

Method of dimensionality reduction (Popov & Heß) in vector form: a contact is a row of
tangential spring-sliders at x_i = (i + 1/2) h on a line (i = 0, 1, ...).

- normal: local overlap of spring i, u_i = delta_n - x_i²/R (in contact where u_i > 0);
  the normal force stays Hertz (:mod:`asperity_sim.laws.hertz`);
- tangential: spring i holds a 2-vector w_i (local s, t components).  In contact it follows
  the tangential displacement increment of the asperity and is returned radially onto the
  circle |w_i| <= lam mu u_i (Coulomb per spring, the MDR image of mu p);
- force: (f_s, f_t) = (2 E*/lam) h sum_i w_i.

Exact (up to the spring count) for any tangential history with varying normal force:
Cattaneo–Mindlin, Mindlin–Deresiewicz, Masing unloading and reloading with nested memory
and erasure; it never creates energy and reduces to the ``paper`` law under monotonic
shear at constant normal force.

Springs that fit the contact.  A contact is born with k springs across the larger of its
radius at birth and the radius it is expected to reach (``dn_ref``: its overlap at the end
of the current stage, where the path prescribes it), h = sqrt(R max(delta_n, dn_ref,
dn_floor))/k, whatever the interface statistics; each slot stores 2k springs, and a contact
that grows beyond them is coarsened (neighbours merged, h doubled), so a contact at its
largest extent has at least k springs in contact.  While a fresh contact is being solved
for and its overlap exceeds dn_ref, h follows its trial overlap, and the Jacobian includes
dh/d delta_n.  dn_floor (a 1e-5 fraction of the interface's height scale) only bounds the
spring count of a contact born with a vanishing overlap.  Coarsening keeps the force and
counts the stored energy the merge averages away as dissipation (a small artefact of the
discretisation; none when the expected extent was right).

Within an increment delta_n and the tangential displacement vary linearly, so a spring
that enters contact (u_i^c <= 0 < u_i) carries the part of the increment after its entry,
frac = u_i / (u_i - u_i^c): proportional loading below slip stays exactly elastic.  A
spring that leaves contact holds zero; a contact that is lost has its memory erased.

Energy of one increment, per spring (q = 2 E* h / lam): stored ½ q |w|²; work
½ q (w^c + w).dδ_i while it sticks, q w.dδ_i when it slips (end-point rule of the radial
return); dissipation q w.p + ½ q |w - w^c|² >= 0 for a slipping spring (p: its slip).
Work = change of stored energy + dissipation then holds per spring to round-off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...output.variables import Var
from ..options import Cost, Options, option
from ..registry import History, Law, register
from .blocks import mdr_commit_block, mdr_trial_block
from .commit import mdr_commit
from .springs import FLOOR_FRACTION
from .trial import mdr_trial

K_MAX = 4096
"""Most springs a contact may have at its largest extent (``k``)."""


@dataclass(frozen=True)
class MdrOptions(Options):
    """The options of the ``mdr`` law."""

    k: int = option(16, "least number of tangential springs of a contact at its largest extent", valid=(1, K_MAX),
                    attribute="springs_per_contact")
    spring_dtype: str = option("float64", "storage of the springs", valid=("float64", "float32"))


def arrays(capacity, options):
    """Per-slot state: springs w (capacity, 2, 2k) of ``spring_dtype`` (the s row, then the t row: each
    contiguous, so the spring loops vectorise) and spacing h (capacity,) [m]."""
    return np.zeros((capacity, 2, 2 * options.k), dtype=np.dtype(options.spring_dtype)), np.zeros(capacity)


def validate(arrays, live):
    """Springs finite, and a positive spacing for every committed contact (a zero spacing never ends a loop)."""
    w, h = arrays
    if not np.all(np.isfinite(w)):
        raise ValueError("spring array holds non-finite values")
    hl = h[live]
    if not np.all(np.isfinite(hl) & (hl > 0.0)):
        raise ValueError("a committed contact has a spring spacing that is not finite and > 0 [m]")


def bytes_per_contact(options):
    return 2 * options.k * 2 * np.dtype(options.spring_dtype).itemsize + 8


def constants(params, options):
    return (params.E_star, params.lam, params.mu, float(options.k),
            FLOOR_FRACTION * (params.alpha + 1.0) * params.beta)


def attributes(options, arrays):
    """Output attributes: the spring count, the springs each slot stores (2k) and their storage."""
    return {"springs_per_contact": options.k, "springs_stored_per_contact": arrays[0].shape[-1],
            "spring_dtype": options.spring_dtype}


MDR = register(Law(
    name="mdr",
    summary="Hertz + vector MDR springs per contact: loading, unloading, reloading, turning (history)",
    constants=constants,
    history=History(arrays=arrays, trial=mdr_trial, commit=mdr_commit, trial_block=mdr_trial_block,
                    commit_block=mdr_commit_block, events="coarsenings", bytes_per_contact=bytes_per_contact,
                    validate=validate),
    domain="any path",
    options=MdrOptions,
    # fitted to serial runs of the 120-increment constant-normal-shear path on 2 shared cores (2 numba
    # threads): 0.33 s at n = 5000 and 1.06 s at n = 20 000 with k = 8 (kernel time per spring)
    cost=Cost(per_increment=7.2e-4, per_asperity_increment=1.0e-7, scale_by="k"),
    variables={"coarsenings": Var(("step",), "i8", "1", "contacts whose springs were coarsened in the increment")},
    attributes=attributes,
))
