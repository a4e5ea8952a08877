"""Preallocated arrays of the evaluations of one population, and what a trial leaves for its commit.

Owns :class:`Workspace`: the rows of partial sums, and, for a history law, the fresh contacts
a trial found and the index of the asperities that may touch in a box of displacements around
the path (:meth:`Workspace.fresh_index`).
"""

from __future__ import annotations

import numpy as np

from ..memory import reserve
from ..threads import chunks_of
from .layout import (
    CHUNK,
    EMPTY,
    FRESH_ROW,
    N_ACC,
    OFFSET,
)
from .reach import bounds


class Workspace:
    """Preallocated partial-sum rows for one population (a Newton iteration allocates nothing).

    A history law's trial also leaves here, for a commit at its displacement, its fresh contacts
    (``fresh``, ``n_fresh``: offsets per chunk) and the displacement and committed state it was made at
    (``fresh_key``).  The workspace also keeps an index of the asperities that may touch in a box of
    displacements around the path (``listed``; :meth:`fresh_index`), so that a trial inside the box tests
    only those; ``index=False`` turns it off (every trial tests every asperity that can touch).
    """

    AHEAD = 8  # the index box reaches this many times the step from the committed displacement

    def __init__(self, n, index=True):
        self.n_chunks = n_chunks = chunks_of(n, CHUNK)
        self.partial = np.zeros((n_chunks, N_ACC))
        self.fresh = reserve((n_chunks, FRESH_ROW), OFFSET)  # written only where contacts are born (memory.reserve)
        self.n_fresh = np.zeros(n_chunks, dtype=np.int64)
        self.fresh_key = None
        self.index = bool(index)
        self.listed = self.n_listed = None  # allocated by the first history-law trial
        self.box = np.zeros((2, 3))
        self.box_pop = None  # the population the listed asperities belong to; None: no valid list
        self.n_box, self.tan_box = 0, 0.0
        self.trials_by_index = [0, 0, 0]  # trials that tested every asperity, built the list, used it
        self.interaction_offset = 0.0  # Delta_c,1 - Delta_1 of the last evaluation under elastic interaction

    @staticmethod
    def trial_key(delta, state):
        """What identifies a trial: the bits of its displacement and the committed state it was made on."""
        return np.asarray(delta, dtype=float).tobytes(), id(state), state.serial

    def made_at(self, delta, state):
        """True if the last trial was made at ``delta`` on the committed state ``state``."""
        return self.fresh_key == self.trial_key(delta, state)

    def fresh_contacts(self, delta, state):
        """(fresh, n_fresh): the fresh contacts of the last trial if it was made at ``delta`` on ``state``, else None."""
        return (self.fresh, self.n_fresh) if self.made_at(delta, state) else None

    def fresh_index(self, pop, d, delta_c, n_active):
        """How a history-law trial at ``d`` finds its fresh contacts: ``index`` of :func:`fresh_pass` (0, 1, 2).

        2 when the listed asperities were built for ``pop`` in a box that holds ``d``.  Else 1:
        a new box, from the committed displacement ``delta_c`` to AHEAD steps d - delta_c
        beyond it, widened by the largest component of the step in every direction (Newton
        corrections, a turning path), with its own bounds (:func:`bounds` at the box corner of
        largest closure and shear).  0 without an index, or for a trial at ``delta_c``.
        """
        if not self.index:
            return 0
        self.allocate_index(pop)
        if self.box_pop is pop and n_active <= self.n_box:
            (lo1, lo2, lo3), (hi1, hi2, hi3) = self.box.tolist()
            d1, d2, d3 = d.tolist()  # Python floats: numpy costs more on 3 values, at every trial
            if lo1 <= d1 <= hi1 and lo2 <= d2 <= hi2 and lo3 <= d3 <= hi3:
                return 2
        step = d - delta_c
        pad = np.abs(step).max()
        if not pad > 0.0:
            return 0
        ahead = delta_c + self.AHEAD * step
        self.box[0] = np.minimum(delta_c, ahead) - pad
        self.box[1] = np.maximum(delta_c, ahead) + pad
        corner = np.array([self.box[1, 0], np.abs(self.box[:, 1]).max(), np.abs(self.box[:, 2]).max()])
        r_o, k_e, _, _, _, beta, _ = pop.kernel_constants
        self.n_box, self.tan_box = bounds(pop.r, pop.R_min, r_o, k_e, beta, corner, EMPTY)
        self.box_pop = None  # until the list is written
        return 1

    def allocate_index(self, pop):
        """The list of asperities near the path, allocated for ``pop`` if it is not (by the first trial)."""
        if self.index and (self.listed is None or self.listed.size < pop.n):
            self.listed = reserve(self.n_chunks * CHUNK, OFFSET)  # offsets in the chunk, written up to n_listed
            self.n_listed = np.zeros(self.n_chunks, dtype=np.int64)
            self.box_pop = None

    def rows(self, m):
        """At least m rows of partial sums (grown when a history law has more slot chunks)."""
        if self.partial.shape[0] < m:
            self.partial = np.zeros((m, N_ACC))
        return self.partial
