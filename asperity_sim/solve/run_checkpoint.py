"""What a checkpoint of a run holds: a running :func:`~asperity_sim.simulate` to arrays and back.

Owns the mapping between the state of a run (:class:`~asperity_sim.solve.run.Run`) and the
arrays and meta entries of its checkpoint file; :mod:`asperity_sim.output.checkpoint` owns the
file itself (the container, the untrusted reading and the checks
:func:`~asperity_sim.output.checkpoint.require` and :func:`~asperity_sim.output.checkpoint.guard`).
The run and the driver only call :func:`save` (a run to
a file) and :func:`restore` (a file to the state a run continues from), plus :func:`read`,
:func:`run_arguments` and :func:`check_same_run` for :func:`~asperity_sim.resume`.

The layout (format :data:`~asperity_sim.output.checkpoint.FORMAT`; n asperities, T recorded steps):

- meta ``config``: the run's identity (:func:`config_of`): parameters, n, seed, sampler, law,
  policy, the law's options, load path, solver settings, snapshot request;
- meta ``attrs``: the output attributes built so far (provenance, counters); ``population``:
  weight, seed and sampler; ``steps_recorded`` (T) and ``snapshot_steps``;
  ``checkpoint_every`` and ``wall_time_s`` (the run's wall time so far [s]);
- ``pop_r``, ``pop_R``, ``pop_u``, ``pop_cos_phi``, ``pop_sin_phi``: the population (n,) (a
  population drawn with ``seed=None`` or passed in cannot be drawn again);
- ``delta``: the committed displacement (3,) [m]; ``ev_*``: the last converged evaluation
  (stress, standard errors, covariance, tangent, counts, mean angle, contact area with its
  variance, covariance and gradient), which the predictor reads;
- ``pos_*``: the loop position (:class:`~asperity_sim.solve.stepping.Position`);
- ``state_*``: :meth:`ContactState.state_arrays <asperity_sim.kernels.state.ContactState.state_arrays>`;
- ``energy_*``: running energy sums, event count and transitions (history laws);
- ``rec_<name>``: the T recorded rows of every output variable;
- ``snap<i>_<key>``: the per-asperity arrays of the i-th snapshot.

Every array is checked (:func:`check_run_arrays` and the checks in :func:`restore`) before
any kernel sees it, and any error of the mapping becomes a
:class:`~asperity_sim.errors.CheckpointError` naming the file (docs/robustness.md).
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from .. import laws
from ..errors import CheckpointError
from ..kernels.evaluate import Evaluation
from ..kernels.state import ContactState
from ..output import checkpoint as ckpt
from ..output.checkpoint import require
from ..params import InterfaceParams
from ..paths import LoadPath, Stage
from ..sampling.population import Population
from ..version import __version__
from .solver import SolverSettings
from .stepping import Position


def config_of(params, path, *, n, seed, sampler, law, policy, options, settings, snapshots):
    """The run's identity as JSON-able values; a checkpoint continues only the same configuration."""
    snaps = sorted(snapshots[0]) if not snapshots[1] else "stage_ends"
    return {
        "params": params.as_dict(),
        "n": int(n),
        "seed": None if seed is None else int(seed),
        "sampler": sampler,
        "law": law,
        "policy": policy,
        "law_options": options.as_dict(),
        "path": {"name": path.name,
                 "stages": [{"control": list(s.control), "target": [float(t) for t in s.target],
                             "increments": s.increments, "adaptive": s.adaptive,
                             "max_fraction": s.max_fraction, "name": s.name} for s in path.stages]},
        "settings": dataclasses.asdict(settings),
        "snapshots": snaps,
    }


class Saved(os.PathLike):
    """A checkpoint read back (``meta``, ``arrays``) and the path it came from (so a file is read once)."""

    def __init__(self, path, meta, arrays):
        self.path, self.meta, self.arrays = os.fspath(path), meta, arrays

    def __fspath__(self):
        return self.path

    @property
    def config(self) -> dict:
        return self.meta["config"]


def read(path) -> Saved:
    """Read a checkpoint of this package version (:func:`asperity_sim.output.checkpoint.load`); a :class:`Saved`
    passes unchanged."""
    if isinstance(path, Saved):
        return path
    meta, arrays = ckpt.load(path, __version__)
    return Saved(path, meta, arrays)


def run_arguments(saved: Saved) -> dict:
    """The arguments of :func:`~asperity_sim.simulate` that made the saved run (the inverse of :func:`config_of`).

    Keys: params, path, n, seed, sampler, law, policy, snapshots, settings and the law's options.
    """
    cfg = saved.config
    with ckpt.guard(saved, "holds an invalid configuration"):
        params = InterfaceParams(**cfg["params"])
        path = LoadPath(tuple(Stage(tuple(s["control"]), tuple(s["target"]), s["increments"], s["adaptive"],
                                    s["max_fraction"], s["name"]) for s in cfg["path"]["stages"]),
                        name=cfg["path"]["name"])
        settings = SolverSettings(**cfg["settings"])
        options = laws.get(cfg["law"]).options(**cfg["law_options"])  # the law's own options only, checked
    return dict(params=params, path=path, n=cfg["n"], seed=cfg["seed"], sampler=cfg["sampler"], law=cfg["law"],
                policy=cfg["policy"], snapshots=cfg["snapshots"] if cfg["snapshots"] != [] else None, settings=settings,
                **options.as_dict())


def check_same_run(saved: Saved, wanted: dict) -> None:
    """Refuse a checkpoint of another run than ``wanted`` (a :func:`config_of`), naming the differences."""
    diff = ckpt.differences(saved.config, wanted)
    if diff:
        raise CheckpointError(f"checkpoint {saved.path!r} belongs to another run: " + "; ".join(diff))


def check_run_arrays(arrays, *, n: int, n_stages: int, birth: bool = False) -> None:
    """The checks of docs/robustness.md for the arrays whose layout has been kept since format 1.

    Population (``pop_*``), the current and last evaluated displacement and stress (``delta``,
    ``ev_*``), the loop position (``pos_*``) and the birth angles (``theta_birth``, policy birth).
    History (``state_*`` of a history law), energy, recorder (``rec_*``) and snapshot arrays are
    checked by :func:`restore`.  Raises :class:`CheckpointError` naming the file, array, value and range.
    """
    half_pi = 0.5 * np.pi
    f8, i8 = np.float64, np.int64
    require(arrays, "pop_r", shape=(n,), dtype=f8, lo=0.0, sorted=True)
    require(arrays, "pop_R", shape=(n,), dtype=f8, lo=0.0, lo_open=True)
    require(arrays, "pop_u", shape=(n,), dtype=f8, lo=0.0, hi=half_pi)
    for name in ("pop_cos_phi", "pop_sin_phi"):
        require(arrays, name, shape=(n,), dtype=f8, lo=-1.0, hi=1.0)
    for name in ("delta", "ev_delta", "ev_delta_contact", "ev_stress", "ev_stderr", "pos_start_delta",
                 "pos_start_stress"):
        require(arrays, name, shape=(3,), dtype=f8)
    for name in ("ev_covariance", "ev_tangent"):
        require(arrays, name, shape=(3, 3), dtype=f8)
    require(arrays, "ev_ints", shape=(4,), dtype=i8, lo=0, hi=n)
    require(arrays, "ev_mean_theta", shape=(1,), dtype=f8, lo=0.0, hi=half_pi)
    require(arrays, "ev_area", shape=(8,), dtype=f8)  # area, its variance, covariance (3), gradient (3)
    if not (arrays["ev_area"][0] >= 0.0 and arrays["ev_area"][1] >= 0.0):
        raise CheckpointError(f"checkpoint {getattr(arrays, 'path', '<unknown>')!r}: array ev_area = "
                              f"{arrays['ev_area'][:2].tolist()}... (valid range: contact area and its variance >= 0)")
    pos_i = require(arrays, "pos_i", shape=(2,), dtype=i8, lo=0)
    where = f"checkpoint {getattr(arrays, 'path', '<unknown>')!r}"
    if pos_i[0] > n_stages or pos_i[1] > 1:
        raise CheckpointError(f"{where}: array pos_i = {pos_i.tolist()} (valid range: stage index in [0, "
                              f"{n_stages}] ({n_stages}: the path is done), started flag in [0, 1])")
    pos_f = require(arrays, "pos_f", shape=(3,), dtype=f8)
    if not (0.0 <= pos_f[0] <= 1.0 and 0.0 <= pos_f[1] <= 1.0 and (pos_f[1] > 0.0 or pos_i[1] == 0)
            and pos_f[2] >= 0.0):
        raise CheckpointError(f"{where}: array pos_f = {pos_f.tolist()} (valid range: s in [0, 1], ds in (0, 1] "
                              "(0 before the stage starts), k_ref >= 0)")
    prev = require(arrays, "pos_prev", shape=(7,), dtype=f8, finite=False)
    if not np.isnan(prev[0]) and not (np.all(np.isfinite(prev)) and 0.0 <= prev[0] <= 1.0):
        raise CheckpointError(f"{where}: array pos_prev = {prev.tolist()} (valid: NaN first (no previous point) or "
                              "s in [0, 1] and a finite Delta and slope)")
    older = require(arrays, "pos_older", shape=(2, 4), dtype=f8, finite=False)
    for row in older:
        if not np.isnan(row[0]) and not (np.all(np.isfinite(row)) and 0.0 <= row[0] <= 1.0):
            raise CheckpointError(f"{where}: array pos_older = {older.tolist()} (valid: rows (s, Delta) with NaN s "
                                  "(no point) or s in [0, 1] and a finite Delta)")
    if birth:
        require(arrays, "state_theta_birth", shape=(n,), dtype=f8, finite=False, lo=0.0, hi=half_pi)
        if np.isinf(arrays["state_theta_birth"]).any():
            raise CheckpointError(f"{where}: array state_theta_birth holds inf (valid: NaN (not born) or [0, pi/2])")


# --------------------------------------------------------------------------- a run to a file


def save(run, path, *, every, wall_time) -> None:
    """Write the whole state of ``run`` (a ``driver._Run`` after a converged increment) to ``path`` atomically.

    ``every``: the run's checkpoint interval (steps, or None: stage ends), kept for :func:`~asperity_sim.resume`;
    ``wall_time`` [s]: the run's wall time so far.
    """
    pop, ev, pos = run.pop, run.ev, run.pos
    arrays = {"pop_r": pop.r, "pop_R": pop.R, "pop_u": pop.u, "pop_cos_phi": pop.cos_phi,
              "pop_sin_phi": pop.sin_phi, "delta": run.delta,
              "ev_delta": ev.delta, "ev_delta_contact": ev.at_contacts(), "ev_stress": ev.stress, "ev_stderr": ev.stderr,
              "ev_covariance": ev.covariance, "ev_tangent": ev.tangent,
              "ev_ints": np.array([ev.n_contact, ev.n_slip, ev.n_partial, ev.n_active], dtype=np.int64),
              "ev_mean_theta": np.array([ev.mean_theta]),
              "ev_area": np.concatenate([[ev.contact_area, ev.contact_area_var], ev.contact_area_cov,
                                         ev.contact_area_grad]),
              "pos_i": np.array([pos.i_stage, int(pos.started)], dtype=np.int64),
              "pos_f": np.array([pos.s, pos.ds, pos.k_ref]),
              "pos_start_delta": pos.start_delta, "pos_start_stress": pos.start_stress,
              "pos_prev": np.concatenate([[pos.prev_s], pos.prev_delta, pos.prev_slope]), "pos_older": pos.older}
    arrays.update({f"state_{k}": v for k, v in run.state.state_arrays().items()})
    history = run.law.history
    if history is not None:
        e = run.energy
        arrays["energy_f"] = np.array([e["external_work"], e["elastic_energy"], e["dissipation"]])
        arrays["energy_events"] = np.array([e[history.events]], dtype=np.int64)
        arrays["energy_transitions"] = np.asarray(e["transitions"], dtype=np.int64)
    recorded = run.rec.to_dataset({})
    for name in run.variables:
        arrays[f"rec_{name}"] = recorded[name].values
    for i, (_, snap) in enumerate(run.rec.snapshots):
        arrays.update({f"snap{i}_{key}": v for key, v in snap.items()})
    meta = {"version": __version__, "config": run.config, "attrs": run.attrs,
            "population": {"weight": pop.weight, "seed": pop.seed, "sampler": pop.sampler},
            "steps_recorded": run.rec.size, "snapshot_steps": [int(s) for s, _ in run.rec.snapshots],
            "checkpoint_every": every, "wall_time_s": wall_time}
    ckpt.save(path, meta=meta, arrays=arrays)


# --------------------------------------------------------------------------- a file to the state a run continues from


@dataclasses.dataclass
class Restored:
    """The state a run continues from, every part checked: what :func:`restore` returns."""

    pop: Population
    contact: ContactState          # committed per-contact state
    attrs: dict                    # output attributes so far
    wall_time: float               # wall time of the run so far [s]
    delta: np.ndarray              # committed displacement [m]
    ev: Evaluation                 # last converged evaluation
    energy: dict                   # running energy sums (history laws; empty otherwise)
    pos: Position                 # loop position
    rows: dict                     # output variable -> its recorded rows (steps_recorded of them)
    steps_recorded: int
    snapshots: list                # [(step, {key: array})]


def restore(saved: Saved, *, params, n_stages, law, policy, options, variables, population=None) -> Restored:
    """The checked state of the run saved in ``saved``, for a run of the same configuration.

    ``law`` is the registered law (``laws.get``), ``variables`` the run's output variables
    (name -> :class:`~asperity_sim.output.variables.Var`); ``population``, if given, must be the one
    saved.  Every array is checked before anything is built from it; any malformed content
    raises :class:`CheckpointError` naming the file.
    """
    meta, arrays, where = saved.meta, saved.arrays, saved.path
    with ckpt.guard(saved):  # every array is checked before any kernel sees it
        n = int(meta["config"]["n"])
        check_run_arrays(arrays, n=n, n_stages=n_stages, birth=policy == "birth")
        pop = _population(params, meta, arrays)
    if population is not None and not all(np.array_equal(getattr(population, a), getattr(pop, a))
                                          for a in ("r", "R", "u", "cos_phi", "sin_phi")):
        raise CheckpointError(f"checkpoint {where!r} holds another population than the one passed in")
    with ckpt.guard(saved):
        size = int(meta["steps_recorded"])
        for name, var in variables.items():
            a = require(arrays, f"rec_{name}", finite=var.dtype.startswith("f"), path=where)
            if a.shape[:1] != (size,) or a.dtype != np.dtype(var.dtype):
                raise CheckpointError(f"checkpoint {where!r}: array rec_{name} has shape {a.shape} and dtype "
                                      f"{a.dtype}, expected {size} rows of {var.dtype}")
        for i, _ in enumerate(meta["snapshot_steps"]):
            for key, shape, dtype in (("delta_n", (n,), "f8"), ("theta", (n,), "f8"), ("force", (n, 3), "f8"),
                                      ("state", (n,), "i1")):
                require(arrays, f"snap{i}_{key}", shape=shape, dtype=dtype, path=where)
        if law.history is not None:
            require(arrays, "energy_f", shape=(3,), dtype="f8", path=where)
            require(arrays, "energy_events", shape=(1,), dtype="i8", lo=0, path=where)
            require(arrays, "energy_transitions", shape=(4, 4), dtype="i8", lo=0, path=where)
        contact = ContactState(pop, law, policy, options=options)
        contact.restore({key[6:]: v for key, v in arrays.items() if key.startswith("state_")})
        ints = arrays["ev_ints"]
        ev = Evaluation(delta=arrays["ev_delta"].copy(), stress=arrays["ev_stress"].copy(),
                        stderr=arrays["ev_stderr"].copy(), covariance=arrays["ev_covariance"].copy(),
                        tangent=arrays["ev_tangent"].copy(), n_contact=int(ints[0]), n_slip=int(ints[1]),
                        n_partial=int(ints[2]), mean_theta=float(arrays["ev_mean_theta"][0]), n_active=int(ints[3]),
                        contact_area=float(arrays["ev_area"][0]), contact_area_var=float(arrays["ev_area"][1]),
                        contact_area_cov=arrays["ev_area"][2:5].copy(), contact_area_grad=arrays["ev_area"][5:8].copy(),
                        delta_contact=(None if np.array_equal(arrays["ev_delta_contact"], arrays["ev_delta"])
                                       else arrays["ev_delta_contact"].copy()))
        if law.history is not None:
            ef = arrays["energy_f"]
            energy = {"external_work": float(ef[0]), "elastic_energy": float(ef[1]), "dissipation": float(ef[2]),
                      law.history.events: int(arrays["energy_events"][0]),
                      "transitions": arrays["energy_transitions"].copy()}
        else:
            energy = {}
        pi, pf, prev = arrays["pos_i"], arrays["pos_f"], arrays["pos_prev"]
        pos = Position(i_stage=int(pi[0]), started=bool(pi[1]), s=float(pf[0]), ds=float(pf[1]), k_ref=float(pf[2]),
                        start_delta=arrays["pos_start_delta"].copy(), start_stress=arrays["pos_start_stress"].copy(),
                        prev_s=float(prev[0]), prev_delta=prev[1:4].copy(), prev_slope=prev[4:7].copy(),
                        older=arrays["pos_older"].copy())
        snapshots = []
        for i, step in enumerate(meta["snapshot_steps"]):
            prefix = f"snap{i}_"
            snapshots.append((int(step), {key[len(prefix):]: v for key, v in arrays.items() if key.startswith(prefix)}))
        return Restored(pop=pop, contact=contact, attrs=dict(meta["attrs"]),
                        wall_time=float(meta.get("wall_time_s", 0.0)), delta=arrays["delta"].copy(), ev=ev,
                        energy=energy, pos=pos, rows={name: arrays[f"rec_{name}"] for name in variables},
                        steps_recorded=size, snapshots=snapshots)


def _population(params, meta, arrays):
    info = meta["population"]
    try:
        pop = Population(params=params, r=arrays["pop_r"], R=arrays["pop_R"], u=arrays["pop_u"],
                         cos_phi=arrays["pop_cos_phi"], sin_phi=arrays["pop_sin_phi"], weight=float(info["weight"]),
                         seed=info["seed"], sampler=info["sampler"])
    except KeyError as err:
        raise CheckpointError(f"checkpoint {getattr(arrays, 'path', '<unknown>')!r} holds no population array "
                              f"{err}") from err
    if pop.n != meta["config"]["n"] or any(a.shape != (pop.n,) for a in pop.arrays):
        raise CheckpointError(f"checkpoint {getattr(arrays, 'path', '<unknown>')!r}: its population arrays do not "
                              "match its sample size")
    return pop
