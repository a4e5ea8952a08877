"""Committed per-contact state of a run, and its one ``commit``.

Owns what a contact remembers between increments:

- policy ``birth``: the frozen angle of every committed contact (SPEC §3), per asperity;
- a history law (:mod:`asperity_sim.laws`): the contacts in committed contact, in *slots*
  (struct-of-arrays over slots: the asperity index ``asp`` (-1 for a free slot), the committed
  overlap ``dn_c`` and state code ``code``, and the law's own arrays, e.g. springs), a one-byte
  flag per asperity (1: holds a slot) and the committed interface displacement ``delta_c``.
  Asperities that never touch get nothing: the slot arrays are reserved for as many slots as
  asperities (:mod:`asperity_sim.memory`), and only the slots in use take memory.  A contact
  that is lost frees its slot and its memory is erased (SPEC: contact loss erases history).

A path-independent law under policy follow keeps nothing.  Trial evaluations
(:func:`asperity_sim.kernels.evaluate.evaluate`) only read this state; :meth:`ContactState.commit` is
the one place that writes it, and the driver calls it only after an increment converged.

Commit of a history law (each step a numba kernel over the slots or the population, no
Python work per asperity): the committed contacts are committed by the law at the new
displacement (energies, state transitions, lost contacts freed), the asperities that touch
for the first time (as the last trial at this displacement listed them, or found by a search)
are given slots (free slots first, in asperity order) and committed from no history; then,
under policy birth, the birth angles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import laws
from ..checks import check_choice
from ..geometry import POLICIES
from ..memory import reserve
from ..threads import chunks_of, run_calls, run_chunks, uneven
from .ahead import wait_for
from .commit import assign_slots, birth_angles, find_fresh
from .layout import (
    BLOCK,
    BLOCKS_PER_CHUNK,
    C_DISS,
    C_EVENTS,
    C_STORED,
    C_TR,
    C_WORK,
    CHUNK,
    EMPTY,
    EMPTY_BY_SLOT,
    EMPTY_COUNTS,
    N_BY_SLOT,
    N_COMMIT,
    OFFSET,
)
from .reach import bounds
from .specialise import kernels


@dataclass
class CommitResult:
    """Energies [J per unit nominal area: J m-2] and bookkeeping of one commit (history laws)."""

    work: float          # external work of the increment
    stored: float        # stored elastic energy after the increment
    dissipation: float   # frictional dissipation of the increment
    events: int          # law events in this increment (mdr: contacts coarsened)
    transitions: np.ndarray  # (4, 4) asperity counts from state (row) to state (column)


def by_blocks(n: int) -> bool:
    """True if a commit of n contacts goes by blocks: at least two blocks' worth, in chunks that split unevenly over
    the threads (:func:`asperity_sim.threads.uneven`; the same sums, :func:`~.commit.commit_slots`)."""
    return n >= 2 * BLOCK and uneven(n, CHUNK)


class ContactState:
    """The committed per-contact state of a population under one law and policy (module docstring)."""

    def __init__(self, pop, law="paper", policy="follow", options=None, **law_options):
        """``options``: the law's options object (:attr:`Law.options`), or ``law_options`` as keywords
        (:func:`asperity_sim.laws.options_of`: those of other laws ignored, unknown names refused)."""
        self.law = laws.get(law)
        check_choice("policy", policy, POLICIES)
        if options is None:
            options = laws.options_of(self.law, law_options)
        elif not isinstance(options, self.law.options) or law_options:
            raise ValueError(f"options = {options!r} is not a {self.law.options.__name__} of law {self.law.name!r} "
                             "(give either the options object or keywords)")
        self.options = options
        self.pop, self.policy = pop, policy
        self.consts = tuple(float(c) for c in self.law.constants(pop.params, options))
        self.theta_birth = np.full(pop.n, np.nan) if policy == "birth" else None
        self.delta_c = np.zeros(3)
        self.serial = 0  # commits and restores so far: a trial's leftovers are valid for this state only
        self.reference = np.zeros(3)  # where fresh contacts are expected to go: their springs fit it
        self.n_slots = 0
        if self.law.history is not None:
            self.flag = np.zeros(pop.n, dtype=np.uint8)
            self._allocate_slots(pop.n)
            self._fresh = self._n_fresh = None  # the fresh contacts of a commit without a trial to list them
            self._partial = np.zeros((0, N_COMMIT))
            self._by_slot_cols = None
            self._new_slots = None  # the slots given to the contacts born in a compiled commit (span_scratch)

    def _allocate_slots(self, n):
        """The slot arrays: reserved for as many slots as asperities (:func:`asperity_sim.memory.reserve`: only
        slots in use cost memory, and nothing moves as contacts come; slots from ``n_slots`` on are never
        read), or, where that much memory cannot be had, 1024 slots that grow."""
        shapes = [((), np.int32), ((), np.float64), ((), np.int8)]
        shapes += [(a.shape[1:], a.dtype) for a in self.law.history.arrays(1, self.options)]
        try:
            self.asp, self.dn_c, self.code, *law_arrays = (reserve((max(n, 1),) + s, t) for s, t in shapes)
        except MemoryError:
            self.asp, self.dn_c, self.code, *law_arrays = (np.zeros((1024,) + s, t) for s, t in shapes)
            self.asp[:] = -1
        self.arrays = tuple(law_arrays)

    @property
    def has_history(self) -> bool:
        return self.law.history is not None

    @property
    def n_stored(self) -> int:
        """Springs per slot (the last axis of the law's first array)."""
        return self.arrays[0].shape[-1] if self.has_history else 0

    @property
    def n_contacts(self) -> int:
        """Committed contacts holding a slot."""
        return int(np.count_nonzero(self.asp[:self.n_slots] >= 0)) if self.has_history else 0

    @property
    def nbytes(self) -> int:
        """Bytes in use: birth angles, flags and the slots in use (reserved slots beyond are not memory)."""
        total = 0 if self.theta_birth is None else self.theta_birth.nbytes
        if self.has_history:
            m = self.n_slots
            total += self.flag.nbytes + sum(a[:m].nbytes for a in (self.asp, self.dn_c, self.code, *self.arrays))
        return total

    # -- commit -----------------------------------------------------------------------------------

    def commit(self, delta, n_active=None, workspace=None) -> CommitResult | None:
        """Make the state at the converged displacement ``delta`` [m] the committed one.

        Returns the energies of the increment for a history law, else None.  ``n_active``
        (asperities below the height bound, from the trial) is recomputed when not given.
        ``workspace``: the :class:`~asperity_sim.kernels.evaluate.Workspace` of the trials; if the last
        one was made at ``delta``, the search for contacts born in this increment looks only
        where it found them.
        """
        pop, p = self.pop, self.pop.params
        delta = np.asarray(delta, dtype=float)
        tb = EMPTY if self.theta_birth is None else self.theta_birth
        result = None
        if self.has_history:
            n_active_h, tan_max = bounds(pop.r, pop.R_min, p.r_o, p.k_e, p.beta, delta, EMPTY)
            listed = None if workspace is None else workspace.fresh_contacts(delta, self)
            result = self._commit_history(delta, n_active_h, tan_max, tb, listed)
            self.serial += 1
        if self.theta_birth is not None:
            if n_active is None:
                n_active = bounds(pop.r, pop.R_min, p.r_o, p.k_e, p.beta, delta, tb)[0]
            birth_angles(*pop.arrays, n_active, delta, p.r_o, p.k_e, self.theta_birth)
        self.delta_c = delta.copy()
        return result

    def _commit_history(self, delta, n_active, tan_max, tb, listed) -> CommitResult:
        pop, p = self.pop, self.pop.params
        kern = kernels(self.law, birth=tb.size > 0)
        n_slot_chunks = chunks_of(self.n_slots, CHUNK)
        n_pop_chunks = chunks_of(n_active, CHUNK)
        if self._partial.shape[0] < n_slot_chunks + 1:
            self._partial = np.zeros((2 * n_slot_chunks + 16, N_COMMIT))
        sums = np.zeros(N_COMMIT)
        if self.n_slots:
            wait_for(kern["commit_slots"])  # a first run: the helper may be compiling it (kernels.ahead)
            pieces, by_slot, done = self._pieces(self.n_slots)
            run_calls((kern["commit_slots"], pieces, (self.asp, self.n_slots, self.dn_c, self.code, self.flag,
                       *pop.arrays, delta, self.delta_c, p.r_o, p.k_e, self.consts, self.arrays, tb, self.n_stored,
                       self._partial, by_slot, done), True))
            sums += self._partial[:n_slot_chunks].sum(axis=0)
        if listed is not None and int(listed[1][:n_pop_chunks].max(initial=0)) > listed[0].shape[1]:
            listed = None  # a chunk had more contacts born than its row of the list holds
        if listed is None:  # no trial here to list the contacts born, or not all of them: look for them
            listed = self._fresh_rows(n_pop_chunks)
            run_chunks(find_fresh, n_pop_chunks, self.flag, n_active, *pop.arrays, delta, p.r_o, p.k_e, tan_max,
                       *listed)
        fresh, n_fresh = listed[0], listed[1][:n_pop_chunks]
        n_new = int(n_fresh.sum())
        if n_new:
            need = self.n_slots + n_new
            if need > self.asp.size:  # free slots are taken first: only the new contacts beyond them need room
                need = self.n_slots + max(0, n_new - (self.n_slots - self.n_contacts))
            self._reserve(need)
            new_slots = np.empty(n_new, dtype=np.int64)
            self.n_slots = int(assign_slots(self.flag, fresh, n_fresh, self.asp, self.n_slots, new_slots))
            n_new_chunks = chunks_of(n_new, CHUNK)
            if self._partial.shape[0] < n_new_chunks:
                self._partial = np.zeros((n_new_chunks + 16, N_COMMIT))
            wait_for(kern["commit_fresh"])
            pieces, by_slot, done = self._pieces(n_new)
            run_calls((kern["commit_fresh"], pieces, (new_slots, self.asp, self.dn_c, self.code, *pop.arrays, delta,
                       self.delta_c, self.reference, p.r_o, p.k_e, self.consts, self.arrays, self.n_stored,
                       self._partial, by_slot, done), True))
            sums += self._partial[:n_new_chunks].sum(axis=0)
        scale = p.N * pop.weight
        transitions = np.rint(sums[C_TR:C_TR + 16]).astype(np.int64).reshape(4, 4)
        transitions[0, 0] = pop.n - transitions.sum()  # out of contact before and after
        return CommitResult(work=scale * sums[C_WORK], stored=scale * sums[C_STORED], dissipation=scale * sums[C_DISS],
                            events=int(round(sums[C_EVENTS])), transitions=transitions)

    def _fresh_rows(self, n_chunks):
        """(fresh, n_fresh) of :func:`~.commit.find_fresh` for n_chunks chunks: reserved for every chunk of the
        population (only the rows written cost memory), or, where that cannot be had, for n_chunks."""
        if self._fresh is None or self._fresh.shape[0] < n_chunks:
            try:
                self._fresh = reserve((chunks_of(self.pop.n, CHUNK), CHUNK), OFFSET)
            except MemoryError:
                self._fresh = np.zeros((n_chunks, CHUNK), dtype=OFFSET)
            self._n_fresh = np.zeros(self._fresh.shape[0], dtype=np.int64)
        return self._fresh, self._n_fresh

    def _pieces(self, n):
        """How a commit of n contacts is handed to the threads: (pieces, by_slot, done) of
        :func:`~asperity_sim.kernels.commit.commit_slots`, by blocks where :func:`by_blocks` says so, else chunk by
        chunk (the same sums either way)."""
        n_chunks = chunks_of(n, CHUNK)
        if by_blocks(n):
            return n_chunks * BLOCKS_PER_CHUNK, self._by_slot(n), np.zeros(n_chunks, dtype=np.int64)
        return n_chunks, EMPTY_BY_SLOT, EMPTY_COUNTS

    def _by_slot(self, n):
        """Columns for n contacts of a commit by blocks (N_BY_SLOT, >= n): reserved for as many as the slot arrays
        hold (only the columns written cost memory, and only commits of few chunks write them), or, where that
        cannot be had, twice n."""
        if self._by_slot_cols is None or self._by_slot_cols.shape[1] < n:
            try:
                self._by_slot_cols = reserve((N_BY_SLOT, max(n, self.asp.size)))
            except MemoryError:
                self._by_slot_cols = np.empty((N_BY_SLOT, 2 * n))
        return self._by_slot_cols

    def _reserve(self, needed):
        """Room for ``needed`` slots: grows the arrays of 1024 slots made when reserving was refused (reserved
        arrays hold a slot for every asperity, as many as there can be contacts, and never grow)."""
        cap = self.asp.size
        if needed <= cap:
            return
        new = max(needed, int(cap * 1.25) + 1)
        for a in (self.asp, self.dn_c, self.code, *self.arrays):
            _grow_in_place(a, new)
        self.asp[cap:] = -1

    def span_scratch(self):
        """(cpartial, by_slot, new_slots, found, n_found): the commit's scratch sized for every slot, for the compiled
        increments (:mod:`asperity_sim.kernels.loop_history`), which cannot grow it (nor the slot arrays: they
        must hold a slot for every asperity)."""
        n_chunks = chunks_of(self.asp.size, CHUNK)
        if self._partial.shape[0] < n_chunks + 1:
            self._partial = np.zeros((2 * n_chunks + 16, N_COMMIT))
        if self._new_slots is None:
            self._new_slots = reserve(self.asp.size, np.int64)  # only the pages written cost memory
        return (self._partial, self._by_slot(self.asp.size), self._new_slots,
                *self._fresh_rows(chunks_of(self.pop.n, CHUNK)))

    # -- snapshots and checkpoints ----------------------------------------------------------------

    def snapshot(self, delta):
        """Per-asperity arrays at the committed displacement ``delta`` (call right after commit)."""
        pop, p = self.pop, self.pop.params
        out = {"delta_n": np.empty(pop.n), "theta": np.empty(pop.n), "force": np.empty((pop.n, 3)),
               "state": np.empty(pop.n, dtype=np.int8)}
        tb = EMPTY if self.theta_birth is None else self.theta_birth
        d = np.asarray(delta, dtype=float)
        if not self.has_history:
            run_chunks(kernels(self.law, birth=tb.size > 0)["snapshot_local"], chunks_of(pop.n, CHUNK), *pop.arrays,
                       d, p.r_o, p.k_e, self.consts, tb, out["delta_n"], out["theta"], out["force"], out["state"])
            return out
        slot_of = np.full(pop.n, -1, dtype=np.int64)
        live = np.flatnonzero(self.asp[:self.n_slots] >= 0)
        slot_of[self.asp[live]] = live
        run_chunks(kernels(self.law, birth=tb.size > 0)["snapshot_slots"], chunks_of(pop.n, CHUNK), slot_of,
                   self.dn_c, self.code, *pop.arrays, d, p.r_o, p.k_e, self.consts, self.arrays, tb, out["delta_n"],
                   out["theta"], out["force"], out["state"])
        return out

    def state_arrays(self) -> dict:
        """The committed state as plain arrays (checkpoints); spare capacity is not exported."""
        out = {"delta_c": self.delta_c.copy()}
        if self.theta_birth is not None:
            out["theta_birth"] = self.theta_birth.copy()
        if self.has_history:
            m = self.n_slots
            out.update({"flag": self.flag.copy(), "asp": self.asp[:m].copy(), "dn_c": self.dn_c[:m].copy(),
                        "code": self.code[:m].copy()})
            out.update({f"law{i}": a[:m].copy() for i, a in enumerate(self.arrays)})
        return out

    def restore(self, arrays):
        """Set the state from :meth:`state_arrays` of the same configuration (checked: ValueError if malformed)."""
        pop = self.pop
        delta_c = _checked(arrays, "delta_c", (3,), np.float64)
        if self.theta_birth is not None:
            self.theta_birth = _checked(arrays, "theta_birth", (pop.n,), np.float64, finite=False).copy()
        if self.has_history:
            asp = arrays["asp"]
            m = asp.shape[0] if asp.ndim == 1 else -1
            flag = _checked(arrays, "flag", (pop.n,), np.uint8)
            asp = _checked(arrays, "asp", (m,), np.int32)
            if m > max(pop.n, 1):
                raise ValueError(f"slot map holds {m} slots for {pop.n} asperities")
            if m and (asp.max() >= pop.n or asp.min() < -1):
                raise ValueError(f"slot map holds asperity indices outside [-1, {pop.n - 1}]")
            live = asp[asp >= 0]
            if np.unique(live).size != live.size or np.count_nonzero(flag) != live.size or not np.all(flag[live] == 1):
                raise ValueError("slot map and contact flags disagree")
            dn_c = _checked(arrays, "dn_c", (m,), np.float64)
            code = _checked(arrays, "code", (m,), np.int8)
            if np.any((code < 0) | (code > 3)):
                raise ValueError("contact state codes outside [0, 3]")
            if np.any(dn_c[asp >= 0] <= 0.0):
                raise ValueError("a committed contact has a committed overlap <= 0")
            law_arrays = []
            for i, a in enumerate(self.arrays):
                law_arrays.append(_checked(arrays, f"law{i}", (m,) + a.shape[1:], a.dtype, finite=False))
            if self.law.history.validate is not None:
                self.law.history.validate(tuple(law_arrays), np.flatnonzero(asp >= 0))
            self._reserve(max(m, 1))
            self.flag[:] = flag
            self.asp[:m], self.dn_c[:m], self.code[:m] = asp, dn_c, code
            for a, b in zip(self.arrays, law_arrays):
                a[:m] = b
            self.n_slots = m
        self.delta_c = delta_c.copy()
        self.serial += 1


def _grow_in_place(a, new):
    """Grow ``a`` along its first axis to ``new`` rows, in place (new rows zero).

    ``ndarray.resize`` reallocates the buffer (``realloc``, which moves large blocks by remapping
    pages): the peak memory of a growing spring store stays near its new size, where a copy into a
    new array would hold both.  The state's arrays are never shared with a view.
    """
    a.resize((new,) + a.shape[1:], refcheck=False)


def _checked(arrays, name, shape, dtype, finite=True):
    try:
        a = arrays[name]
    except KeyError:
        raise ValueError(f"state array {name} is missing") from None
    if a.shape != shape or a.dtype != np.dtype(dtype):
        raise ValueError(f"state array {name} has shape {a.shape} and dtype {a.dtype}, expected {shape} {np.dtype(dtype)}")
    if finite and a.dtype.kind == "f" and not np.all(np.isfinite(a)):
        raise ValueError(f"state array {name} holds non-finite values")
    return a
