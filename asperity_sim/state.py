"""Committed per-contact history of the ``mdr`` law, and its commit.

Owns history: the spring vectors of every asperity that has touched (struct-of-arrays
over *slots*: asperities that never touch get none), their spacing h, the committed
overlap delta_n and state code, and the committed interface displacement.  Trial
evaluations (:func:`asperity_sim.assemble.evaluate`) only read it; :meth:`MDRHistory.commit`
is the one place that writes it, and the driver calls it only after an increment
converged.

Commit, per asperity that touches at the new displacement or holds history:
1. springs are recomputed at the converged displacement by the same kernel as the
   trial (:func:`asperity_sim.laws.mdr.mdr_springs`, commit mode), with energy terms;
2. a contact wider than its k springs is coarsened (neighbours merged, h doubled) until
   it fits, so no contact area is dropped; the events are counted and the stored
   energy lost to averaging is counted as dissipation;
3. a contact that is lost has its memory erased (SPEC: contact loss erases history).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from .assemble import CHUNK, closure_and_slope, contact_angle, local_displacement, mdr_history
from .laws.mdr import hertz_energy, mdr_springs, merge_pairs, release_springs

# per-chunk commit sums: work, stored energy (absolute), dissipation, coarsenings, transitions (4x4)
N_COMMIT = 4 + 16


@numba.njit(cache=True, parallel=True)
def _contacts(r, R, u, cos_phi, sin_phi, n_upper, delta, r_o, k_e, theta_birth, out):
    """out[j] = 1 where asperity j is in contact at delta (j < n_upper)."""
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, dc = closure_and_slope(r_o, d1)
    has_birth = theta_birth.size > 0
    for j in numba.prange(n_upper):
        cp, sp = cos_phi[j], sin_phi[j]
        th, _ = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth, has_birth)
        dn, _, _ = local_displacement(d1 - r[j], d2, d3, math.cos(th), math.sin(th), cp, sp)
        out[j] = 1 if dn > 0.0 else 0


@numba.njit(cache=True, parallel=True)
def _commit(r, R, u, cos_phi, sin_phi, n_upper, delta, delta_c, r_o, k_e, E_star, lam, mu, theta_birth,
            slot, w, h_slot, dn_c, state_c, dn_cap, partial):
    """Write the springs at delta for every slotted asperity j < n_upper; sums into ``partial``."""
    d1, d2, d3 = delta[0], delta[1], delta[2]
    D0, D1, D2 = d1 - delta_c[0], d2 - delta_c[1], d3 - delta_c[2]
    closure, dc = closure_and_slope(r_o, d1)
    has_birth = theta_birth.size > 0
    k = w.shape[1]
    n_chunks = (n_upper + CHUNK - 1) // CHUNK
    q_unit = 2.0 * E_star / lam
    for ic in numba.prange(n_chunks):
        acc = np.zeros(N_COMMIT)
        J = np.zeros((3, 3))
        chunk_scratch = np.zeros((4 * k, 2))
        for j in range(ic * CHUNK, min(n_upper, (ic + 1) * CHUNK)):
            sl = slot[j]
            if sl < 0:
                continue
            cp, sp = cos_phi[j], sin_phi[j]
            inv_R = 1.0 / R[j]
            th, _ = contact_angle(j, r, u, inv_R, cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth, has_birth)
            ct, st = math.cos(th), math.sin(th)
            dn, _, _ = local_displacement(d1 - r[j], d2, d3, ct, st, cp, sp)
            _, n_hist, h, dn_old = mdr_history(j, slot, w, h_slot, dn_c, r, R, u, inv_R, cp, sp,
                                               delta_c, r_o, k_e, dn_cap, k)
            old_state = state_c[sl] if dn_old > 0.0 else 0
            e_old_n = hertz_energy(dn_old, R[j], E_star)
            if dn <= 0.0:
                # contact lost: normal energy returned, springs released, memory erased
                _, dds, ddt = local_displacement(D0, D1, D2, ct, st, cp, sp)
                wk, _, dd = release_springs(w[sl], 0, n_hist, dn, dn_old, h, inv_R, dds, ddt, q_unit * h)
                for i in range(n_hist):
                    w[sl, i, 0] = 0.0
                    w[sl, i, 1] = 0.0
                acc[0] += wk - e_old_n
                acc[2] += dd
                dn_c[sl] = dn
                state_c[sl] = 0
                new_state = 0
            else:
                _, dds, ddt = local_displacement(D0, D1, D2, ct, st, cp, sp)
                n_need = int(math.ceil(math.sqrt(R[j] * dn) / h - 0.5)) + 1
                scratch = chunk_scratch if n_need <= 4 * k else np.zeros((n_need, 2))
                _, _, _, n_springs, _, new_state, work, d_stored, diss = mdr_springs(
                    dn, dds, ddt, dn_old, w[sl], n_hist, h, R[j], E_star, lam, mu, J, scratch)
                while n_springs > k:  # coarsen: contact wider than its springs
                    lost = merge_pairs(scratch, n_springs)
                    diss += q_unit * h * lost
                    h *= 2.0
                    n_springs = (n_springs + 1) // 2
                    acc[3] += 1.0
                stored = 0.0
                for i in range(k):
                    w[sl, i, 0] = scratch[i, 0]
                    w[sl, i, 1] = scratch[i, 1]
                    stored += scratch[i, 0] ** 2 + scratch[i, 1] ** 2
                e_new_n = hertz_energy(dn, R[j], E_star)
                acc[0] += work + e_new_n - e_old_n
                acc[1] += 0.5 * q_unit * h * stored + e_new_n
                acc[2] += diss
                h_slot[sl] = h
                dn_c[sl] = dn
                state_c[sl] = new_state
            acc[4 + 4 * old_state + new_state] += 1.0
        partial[ic, :] = acc


@numba.njit(cache=True, parallel=True)
def _snapshot(r, R, u, cos_phi, sin_phi, delta, r_o, k_e, E_star, lam, theta_birth, slot, w, h_slot, dn_c,
              state_c, delta_n_out, theta_out, force_out, state_out):
    """Per-asperity overlap, angle, global force (committed springs) and state code at the committed delta."""
    d1, d2, d3 = delta[0], delta[1], delta[2]
    closure, dc = closure_and_slope(r_o, d1)
    has_birth = theta_birth.size > 0
    q_unit = 2.0 * E_star / lam
    for j in numba.prange(r.size):
        cp, sp = cos_phi[j], sin_phi[j]
        th, _ = contact_angle(j, r, u, 1.0 / R[j], cp, sp, d1, d2, d3, closure, k_e, dc, theta_birth, has_birth)
        ct, st = math.cos(th), math.sin(th)
        dn, _, _ = local_displacement(d1 - r[j], d2, d3, ct, st, cp, sp)
        delta_n_out[j] = dn
        theta_out[j] = th
        sl = slot[j]
        f_n = f_s = f_t = 0.0
        code = 0
        if sl >= 0 and dn_c[sl] > 0.0:
            f_n = (4.0 / 3.0) * E_star * math.sqrt(R[j]) * dn_c[sl] ** 1.5
            for i in range(w.shape[1]):
                f_s += w[sl, i, 0]
                f_t += w[sl, i, 1]
            f_s *= q_unit * h_slot[sl]
            f_t *= q_unit * h_slot[sl]
            code = state_c[sl]
        force_out[j, 0] = f_n * ct - f_s * st
        force_out[j, 1] = f_n * st * cp + f_s * ct * cp - f_t * sp
        force_out[j, 2] = f_n * st * sp + f_s * ct * sp + f_t * cp
        state_out[j] = code


@dataclass
class CommitResult:
    """Energies [J per unit nominal area: J m-2] and bookkeeping of one commit."""

    work: float          # external work of the increment
    stored: float        # stored elastic energy after the increment (springs + Hertz)
    dissipation: float   # frictional dissipation of the increment
    coarsenings: int     # contacts coarsened in this increment
    transitions: np.ndarray  # (4, 4) asperity counts from state (row) to state (column)


class MDRHistory:
    """Committed springs of the asperities that have touched (slots), see module docstring."""

    def __init__(self, pop, k=16, dn_cap=None, capacity=1024):
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= 4096:
            raise ValueError(f"k = {k!r} is not a valid spring count (valid range: integer in [1, 4096])")
        self.k = int(k)
        self.n = pop.n
        self.slot = np.full(pop.n, -1, dtype=np.int32)
        cap = max(int(capacity), 1)
        self.w = np.zeros((cap, self.k, 2))
        self.h = np.zeros(cap)
        self.dn_c = np.zeros(cap)
        self.state_c = np.zeros(cap, dtype=np.int8)
        self.n_slots = 0
        self.n_upper = 0  # every slotted asperity has index < n_upper
        self.delta_c = np.zeros(3)
        beta = pop.params.beta
        self.dn_cap = float(dn_cap) if dn_cap is not None and dn_cap > 0 else beta
        self.coarsenings = 0
        self._pop = pop
        self._contact = np.zeros(0, dtype=np.int8)
        self._partial = np.zeros(((pop.n + CHUNK - 1) // CHUNK, N_COMMIT))

    @classmethod
    def virgin(cls, pop, k=16, dn_cap=None):
        return cls(pop, k=k, dn_cap=dn_cap, capacity=1)

    def state_arrays(self) -> dict:
        """The committed history as plain arrays (checkpoints): slot map, used slots, scalars.

        Spare capacity is not exported: it holds no history and its size does not change any
        result.  :meth:`from_state_arrays` rebuilds an equivalent history.
        """
        m = self.n_slots
        return {"slot": self.slot.copy(), "w": self.w[:m].copy(), "h": self.h[:m].copy(),
                "dn_c": self.dn_c[:m].copy(), "state_c": self.state_c[:m].copy(), "delta_c": self.delta_c.copy(),
                "counts": np.array([self.k, self.n_slots, self.n_upper, self.coarsenings], dtype=np.int64),
                "dn_cap": np.array([self.dn_cap])}

    @classmethod
    def from_state_arrays(cls, pop, arrays) -> "MDRHistory":
        """A history equal to the one that exported ``arrays`` (see :meth:`state_arrays`)."""
        k, n_slots, n_upper, coarsenings = (int(v) for v in arrays["counts"])
        hist = cls(pop, k=k, dn_cap=float(arrays["dn_cap"][0]), capacity=max(n_slots, 1))
        expected = {"slot": (pop.n,), "w": (n_slots, k, 2), "h": (n_slots,), "dn_c": (n_slots,),
                    "state_c": (n_slots,), "delta_c": (3,)}
        for name, shape in expected.items():
            a = arrays[name]
            if a.shape != shape:
                raise ValueError(f"history array {name} has shape {a.shape}, expected {shape}")
        if np.any(arrays["slot"] >= n_slots) or (n_slots and int(arrays["slot"].max()) != n_slots - 1):
            raise ValueError("history slot map does not match its slot count")
        hist.slot[:] = arrays["slot"]
        hist.w[:n_slots] = arrays["w"]
        hist.h[:n_slots] = arrays["h"]
        hist.dn_c[:n_slots] = arrays["dn_c"]
        hist.state_c[:n_slots] = arrays["state_c"]
        hist.delta_c = np.array(arrays["delta_c"], dtype=float)
        hist.n_slots, hist.n_upper, hist.coarsenings = n_slots, n_upper, coarsenings
        return hist

    @property
    def nbytes(self) -> int:
        """Bytes held: slot map (n) plus springs, spacing, overlap and state of each slot."""
        per_slot = self.k * 2 * 8 + 8 + 8 + 1
        return self.slot.nbytes + self.n_slots * per_slot

    def snapshot(self, delta, theta_birth=None):
        """Per-asperity arrays at the committed displacement ``delta`` (call right after commit)."""
        pop, p = self._pop, self._pop.params
        tb = theta_birth if theta_birth is not None else np.empty(0)
        out = {"delta_n": np.empty(pop.n), "theta": np.empty(pop.n), "force": np.empty((pop.n, 3)),
               "state": np.empty(pop.n, dtype=np.int8)}
        _snapshot(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, np.asarray(delta, float), p.r_o, p.k_e,
                  p.E_star, p.lam, tb, self.slot, self.w, self.h, self.dn_c, self.state_c,
                  out["delta_n"], out["theta"], out["force"], out["state"])
        return out

    def _grow(self, needed):
        cap = self.w.shape[0]
        if needed <= cap:
            return
        new = max(needed, int(cap * 1.5) + 1)
        for name in ("w", "h", "dn_c", "state_c"):
            a = getattr(self, name)
            b = np.zeros((new,) + a.shape[1:], dtype=a.dtype)
            b[:cap] = a
            setattr(self, name, b)

    def commit(self, delta, n_active, theta_birth=None) -> CommitResult:
        """Make the springs at the converged displacement ``delta`` [m] the committed history."""
        pop, p = self._pop, self._pop.params
        delta = np.asarray(delta, dtype=float)
        tb = theta_birth if theta_birth is not None else np.empty(0)
        # slots for asperities that touch for the first time
        if self._contact.size < n_active:
            self._contact = np.zeros(max(n_active, 2 * self._contact.size), dtype=np.int8)
        _contacts(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, n_active, delta, p.r_o, p.k_e, tb,
                  self._contact)
        new = np.flatnonzero((self._contact[:n_active] == 1) & (self.slot[:n_active] < 0))
        if new.size:
            self._grow(self.n_slots + new.size)
            slots = np.arange(self.n_slots, self.n_slots + new.size, dtype=np.int32)
            self.slot[new] = slots
            # same spacing as the trial gave these fresh contacts (assemble.fresh_spacing)
            self.h[slots] = np.sqrt(2.0 * pop.R[new] * np.maximum(self.dn_cap - pop.r[new], 0.1 * self.dn_cap)) / self.k
            # committed overlap at the previous displacement (the trial used the same)
            self.dn_c[slots] = _overlap_at(pop, new, self.delta_c)
            self.state_c[slots] = 0
            self.n_slots += new.size
            self.n_upper = max(self.n_upper, int(new.max()) + 1)
        n_upper = max(self.n_upper, 0)
        n_chunks = (n_upper + CHUNK - 1) // CHUNK
        _commit(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, n_upper, delta, self.delta_c, p.r_o, p.k_e,
                p.E_star, p.lam, p.mu, tb, self.slot, self.w, self.h, self.dn_c, self.state_c, self.dn_cap,
                self._partial)
        s = self._partial[:n_chunks].sum(axis=0)
        self.delta_c = delta.copy()
        scale = p.N * pop.weight
        coarse = int(round(s[3]))
        self.coarsenings += coarse
        return CommitResult(work=scale * s[0], stored=scale * s[1], dissipation=scale * s[2],
                            coarsenings=coarse, transitions=np.rint(s[4:]).astype(np.int64).reshape(4, 4))


def _overlap_at(pop, idx, delta_c):
    """delta_n at delta_c of asperities idx at their follow angle (fresh contacts, SPEC §3–§4)."""
    p = pop.params
    closure = max(0.0, p.r_o + delta_c[0])
    y = 1.0 - p.k_e * closure / pop.R[idx]
    theta = pop.u[idx] / (0.5 * math.pi) * np.arccos(np.clip(y, 0.0, 1.0))
    shear = pop.cos_phi[idx] * delta_c[1] + pop.sin_phi[idx] * delta_c[2]
    return np.cos(theta) * (delta_c[0] - pop.r[idx]) + np.sin(theta) * shear
