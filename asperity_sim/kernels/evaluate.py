"""The interface response at one displacement: stress, standard error, tangent and counts (SPEC §6).

Owns the Python side of the reductions: :class:`Evaluation` (the result) and :func:`evaluate`
(into a :class:`~asperity_sim.kernels.workspace.Workspace`: preallocated partial rows and the
trial's leftovers, so a Newton iteration allocates nothing), the Monte Carlo sum of Eq. (23), sigma_i = N w sum_j f_ij, with its
exact tangent T_ik = d sigma_i / d Delta_k, for any registered law.  It picks the kernels
(:mod:`asperity_sim.kernels.specialise`) and passes them the population's arrays and the
committed state (:mod:`asperity_sim.kernels.state`), which it only reads.

Which asperities are visited.  The population is sorted by height: only the first ``n_active``
can touch (:func:`~asperity_sim.kernels.reach.bounds`).  A path-independent law sums them in one
parallel pass, or on the calling thread when they fit ``SERIAL_ACTIVE_CHUNKS`` chunks (or the
population ``SERIAL_CHUNKS``).  A history law makes two passes, handed to the threads together:
the committed contacts, from their slots, and the contacts new in this trial; the second tests
only those the workspace lists as able to touch in a box of displacements around the path (the
same asperities in the same order as a full scan, so the same bits).  No fastmath anywhere: vector
and scalar code give the same bits, and a result is the same whether compiled or from cache.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .. import laws
from ..checks import check_choice, check_delta
from ..geometry import POLICIES
from ..sampling.population import Population
from ..threads import chunks_of, run_calls, run_chunks
from .layout import (
    CHUNK,
    EMPTY,
    EMPTY_COUNTS,
    EMPTY_INDEX,
    N_OUT,
    O_COV,
    O_AREA,
    O_AREA_COV,
    O_AREA_GRAD,
    O_AREA_VAR,
    O_NA,
    O_NC,
    O_NP,
    O_NS,
    O_SE,
    O_STRESS,
    O_TANGENT,
    O_TH,
    SERIAL_ACTIVE_CHUNKS,
    fits_serial,
    finish,
)
from . import interaction
from .ahead import compiling, wait_for
from .history import scan_chunks
from .reach import bounds
from .specialise import kernels
from .state import ContactState
from .workspace import Workspace


@dataclass(frozen=True)
class Evaluation:
    """Interface response at one displacement (SPEC §6).

    stress (3,) [Pa], stderr (3,) [Pa] (Monte Carlo standard error of each component),
    covariance (3, 3) [Pa²] (Monte Carlo covariance of the stress estimate), tangent (3, 3)
    [Pa/m] (d sigma_i / d Delta_k), n_contact, n_slip and n_partial (asperity counts),
    mean_theta [rad] (mean orientation of the contacts; 0 when none), n_active (asperities
    below the height bound, the most that can touch); contact_area [1] (real contact area
    per unit nominal area: the Hertz areas pi R delta_n of the contacts, projected, N w sum),
    contact_area_var [1] (the Monte Carlo variance of that estimate), contact_area_cov (3,) [Pa]
    (its covariance with the stress estimate) and contact_area_grad (3,) [1/m] (d area / d Delta);
    delta_contact (3,) [m] the displacement the contacts see under elastic interaction
    (:mod:`asperity_sim.kernels.interaction`; None without it).
    """

    delta: np.ndarray
    stress: np.ndarray
    stderr: np.ndarray
    covariance: np.ndarray
    tangent: np.ndarray
    n_contact: int
    n_slip: int
    n_partial: int
    mean_theta: float
    n_active: int
    contact_area: float = 0.0
    contact_area_var: float = 0.0
    contact_area_cov: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    contact_area_grad: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    delta_contact: np.ndarray | None = None  # the displacement the contacts see, when it differs (interaction)

    def at_contacts(self) -> np.ndarray:
        """The displacement the contacts see [m]: ``delta`` unless elastic interaction shifts it."""
        return self.delta if self.delta_contact is None else self.delta_contact


def evaluate(pop, delta, law="paper", policy="follow", theta_birth=None, workspace=None, state=None) -> Evaluation:
    """Evaluate Eq. (23) and its tangent over a population at interface displacement delta [m].

    ``law`` a registered law name (:mod:`asperity_sim.laws`).  ``state`` (a
    :class:`~asperity_sim.kernels.state.ContactState`) holds the committed per-contact state: the
    springs of a history law and the birth angles of policy birth; it is read, never written.
    Without it: a virgin interface at Delta = 0 (every contact born now).  Under policy
    birth ``theta_birth`` (n,) may give the frozen angles directly (NaN where none).
    """
    if not isinstance(pop, Population):
        raise ValueError(f"pop = {pop!r} is not a Population")
    d = check_delta(delta)
    lw = laws.get(law)
    check_choice("policy", policy, POLICIES)
    if workspace is not None and (not isinstance(workspace, Workspace)
                                  or workspace.partial.shape[0] * CHUNK < pop.n):
        raise ValueError(f"workspace = {workspace!r} is not a Workspace for {pop.n} asperities (use Workspace(pop.n))")
    if state is None:
        state = ContactState(pop, lw, policy)
    elif state.law is not lw or state.pop is not pop:
        raise ValueError(f"state belongs to law {state.law.name!r} on another population; this is law {lw.name!r}")
    if policy == "birth" and theta_birth is not None:
        tb = np.asarray(theta_birth, dtype=float)
        if tb.shape != (pop.n,):
            raise ValueError(f"theta_birth has shape {tb.shape}, expected ({pop.n},)")
        state.theta_birth = tb
    ws = workspace if workspace is not None else Workspace(pop.n)
    return evaluate_unchecked(pop, d, state, ws)


def evaluate_unchecked(pop, d, state, workspace) -> Evaluation:
    """:func:`evaluate` on arguments already checked (for a solver that calls it many times).

    ``d`` a finite float array (3,), ``state`` a :class:`~asperity_sim.kernels.state.ContactState`
    of ``pop``, ``workspace`` a :class:`Workspace` for ``pop``.  With elastic interaction
    (``params.interaction`` > 0) the contacts' displacement is solved for first
    (:func:`~asperity_sim.kernels.interaction.solve`, from the workspace's last offset).
    """
    k = interaction.kappa(pop.params)
    if k == 0.0:
        return at_contacts(pop, d, state, workspace)
    ev = interaction.solve(lambda c: at_contacts(pop, c, state, workspace), d, k, workspace.interaction_offset)
    workspace.interaction_offset = float(ev.delta_contact[0] - d[0])
    return ev


def at_contacts(pop, d, state, workspace) -> Evaluation:
    """The sums of the kernels with the contacts at the displacement ``d`` (no interaction)."""
    law = state.law
    tb = EMPTY if state.theta_birth is None else state.theta_birth
    out = np.empty(N_OUT)
    r_o, k_e, _, _, _, beta, scale = pop.kernel_constants
    kern = kernels(law, birth=tb.size > 0)
    if law.path_independent:
        serial = fits_serial(pop.n)  # a small population: the serial kernel finds its own bounds
        if not serial:
            n_active, tan_max = bounds(pop.r, pop.R_min, r_o, k_e, beta, d, tb)
            serial = fits_serial(n_active, SERIAL_ACTIVE_CHUNKS)
        if serial:
            reduce = kern["reduce_serial"]
            if compiling(reduce):  # a first run: a helper compiles it (kernels.ahead), its loop first; its other
                # callees here meanwhile, with its argument types, for the helper to load from the cache
                bounds(pop.r, pop.R_min, r_o, k_e, beta, d, tb)
                finish(workspace.partial, 0, pop.n, scale, np.empty(N_OUT))
            wait_for(reduce)
            reduce(*pop.arrays, pop.R_min, _row(d), r_o, k_e, state.consts, beta, tb, pop.n, scale, workspace.partial,
                   out.reshape(1, N_OUT))
            return evaluation_from(d, out)
        n_rows = chunks_of(n_active, CHUNK)
        reduce = kern["reduce_parallel"]
        wait_for(reduce)
        run_calls((reduce, n_rows, (*pop.arrays, n_active, d, r_o, k_e, state.consts, tb, tan_max, workspace.partial),
                   True))
    else:
        n_active, tan_max = bounds(pop.r, pop.R_min, r_o, k_e, beta, d, EMPTY)
        n_pop = chunks_of(n_active, CHUNK)
        n_slot = chunks_of(state.n_slots, CHUNK)
        partial = workspace.rows(n_pop + n_slot)
        workspace.fresh_key = None
        index = workspace.fresh_index(pop, d, state.delta_c, n_active)
        listed, n_listed = (workspace.listed, workspace.n_listed) if index else (EMPTY_INDEX, EMPTY_COUNTS)
        calls = [(kern["fresh_pass"], scan_chunks(n_active, index, workspace.n_box),
                  (state.flag, n_active, *pop.arrays, d, state.delta_c, state.reference, r_o, k_e, state.consts,
                   state.arrays, tan_max, partial, workspace.fresh, workspace.n_fresh, index, listed, n_listed,
                   workspace.box, workspace.n_box, workspace.tan_box), True)]
        if n_slot:  # one hand-off for both passes (different rows); the costly chunks claimed first, the cheap even out
            calls.insert(0, (kern["slot_pass"], n_slot, (state.asp, state.n_slots, state.dn_c, *pop.arrays, d,
                          state.delta_c, r_o, k_e, state.consts, state.arrays, tb, partial[n_pop:]), True))
        run_calls(*calls)
        workspace.trials_by_index[index] += 1
        if index == 1:
            workspace.box_pop = pop
        workspace.fresh_key = workspace.trial_key(d, state)
        n_rows = n_pop + n_slot
    finish(workspace.partial, n_rows, pop.n, scale, out)
    out[O_NA] = n_active
    return evaluation_from(d, out)


def _row(d):
    """d (3,) as a C-contiguous (1, 3) view or copy: the one array layout the serial kernel is compiled for."""
    return np.ascontiguousarray(d).reshape(1, 3)


@dataclass(frozen=True)
class Steps:
    """Responses at a batch of displacements (:func:`evaluate_steps`): one row per displacement.

    delta (m, 3) [m]; stress, stderr (m, 3) [Pa]; tangent (m, 3, 3) [Pa/m]; n_contact, n_slip,
    n_partial (m,) counts (floats); mean_theta (m,) [rad]; finite (m,): stress, tangent and
    covariance finite (what the solver checks of an evaluation).
    """

    delta: np.ndarray
    rows: np.ndarray  # (m, N_OUT): the flat results of finish, in the layout of kernels.layout

    @property
    def stress(self):
        return self.rows[:, O_STRESS:O_STRESS + 3]

    @property
    def stderr(self):
        return self.rows[:, O_SE:O_SE + 3]

    @property
    def tangent(self):
        return self.rows[:, O_TANGENT:O_TANGENT + 9].reshape(-1, 3, 3)

    @property
    def n_contact(self):
        return self.rows[:, O_NC]

    @property
    def n_slip(self):
        return self.rows[:, O_NS]

    @property
    def n_partial(self):
        return self.rows[:, O_NP]

    @property
    def mean_theta(self):
        return self.rows[:, O_TH]

    @property
    def contact_area(self):
        return self.rows[:, O_AREA]

    @property
    def contact_area_stderr(self):
        return np.sqrt(np.maximum(self.rows[:, O_AREA_VAR], 0.0))

    @property
    def finite(self):
        return np.isfinite(self.rows[:, :O_SE]).all(axis=1)  # stress, tangent, covariance

    def evaluation(self, i) -> Evaluation:
        """The :class:`Evaluation` of row ``i``."""
        return evaluation_from(self.delta[i], self.rows[i])


def evaluate_steps(pop, deltas, workspace, law="paper") -> Steps:
    """The responses of a path-independent law under policy follow at each row of ``deltas`` (m, 3) [m].

    One call of the serial kernel for all rows, each bit-identical to :func:`evaluate` there;
    meant for small populations (:func:`~asperity_sim.kernels.layout.fits_serial`), where the per-call overhead of
    :func:`evaluate` exceeds the kernel time.  ``deltas`` finite and C-contiguous,
    ``workspace`` a :class:`Workspace` for ``pop``; no elastic interaction (``params.interaction`` 0).
    """
    if pop.params.interaction != 0.0:
        raise ValueError("evaluate_steps has no elastic interaction: evaluate each displacement (interaction > 0)")
    lw = laws.get(law)
    r_o, k_e, _, _, _, beta, scale = pop.kernel_constants
    out = np.empty((deltas.shape[0], N_OUT))
    kernels(lw)["reduce_serial"](*pop.arrays, pop.R_min, deltas, r_o, k_e, lw.constants(pop.params, lw.options()),
                                 beta, EMPTY, pop.n, scale, workspace.partial, out)
    return Steps(deltas, out)


def evaluation_from(d, out) -> Evaluation:
    """The :class:`Evaluation` at ``d`` from one flat result row ``out`` (N_OUT,) of :func:`finish`."""
    return Evaluation(
        delta=d,
        stress=out[O_STRESS:O_STRESS + 3],
        stderr=out[O_SE:O_SE + 3],
        covariance=out[O_COV:O_COV + 9].reshape(3, 3),
        tangent=out[O_TANGENT:O_TANGENT + 9].reshape(3, 3),
        n_contact=int(out[O_NC]),
        n_slip=int(out[O_NS]),
        n_partial=int(out[O_NP]),
        mean_theta=float(out[O_TH]),
        n_active=int(out[O_NA]),
        contact_area=float(out[O_AREA]),
        contact_area_var=float(out[O_AREA_VAR]),
        contact_area_cov=out[O_AREA_COV:O_AREA_COV + 3],
        contact_area_grad=out[O_AREA_GRAD:O_AREA_GRAD + 3],
    )


def snapshot(pop, delta, policy="follow", theta_birth=None, law="paper"):
    """Per-asperity arrays at delta of a path-independent law: delta_n [m], theta [rad], force (n, 3) [N], state."""
    d = check_delta(delta)
    lw = laws.get(law)
    tb = np.asarray(theta_birth, dtype=float) if (policy == "birth" and theta_birth is not None) else EMPTY
    out = {"delta_n": np.empty(pop.n), "theta": np.empty(pop.n), "force": np.empty((pop.n, 3)),
           "state": np.empty(pop.n, dtype=np.int8)}
    run_chunks(kernels(lw, birth=tb.size > 0)["snapshot_local"], chunks_of(pop.n, CHUNK), *pop.arrays, d,
               pop.params.r_o, pop.params.k_e, lw.constants(pop.params, lw.options()), tb, out["delta_n"], out["theta"],
               out["force"], out["state"])
    return out
