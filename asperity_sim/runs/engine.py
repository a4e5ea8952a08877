"""Running the scenes of a sweep: serially or on Dask, with a cost model to choose.

Owns how the runs of a sweep are executed: one run with its per-step outputs aligned on the
nominal schedule of its path (:func:`run_one`, :func:`align_run`), the engines (serial, a local
Dask cluster, or a scheduler), the cost model that picks one (:func:`estimate_run_seconds`,
:func:`choose_engine`) and the worker environment.
"""

from __future__ import annotations

import logging
import math
import os
import time

import xarray as xr

from .ensemble import align_run, sweep_dataset
from .scene import Scene
from .sweep import Sweep


def _set_threads(threads):
    if threads:
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))


def run_one(scene: Scene, threads: int | None = None) -> dict:
    """Run one scene (a task of a sweep) and return its aligned outputs and run summary.

    A run that stops early (``SimulationError``) returns what converged; ``threads`` sets
    numba's thread count in this process (results do not depend on it).
    """
    from ..errors import SimulationError

    _set_threads(threads)
    t0 = time.perf_counter()
    try:
        ds = scene.simulate(output=None)
    except SimulationError as err:
        ds = err.dataset
        if ds is None:
            return _failed(f"failed: {type(err).__name__}: {err}", time.perf_counter() - t0)
    except (ValueError, ArithmeticError) as err:  # a point the run itself rejects: recorded, the others go on
        return _failed(f"error: {type(err).__name__}: {' '.join(str(err).split())}", time.perf_counter() - t0)
    wall = time.perf_counter() - t0
    aligned, exact = align_run(ds, scene.path)
    return {
        "aligned": aligned,
        "exact": exact,
        "status": str(ds.attrs.get("status", "unknown")),
        "n_steps": int(ds.sizes["step"]),
        "total_iterations": int(ds["iterations"].values.sum()),
        "max_iterations": int(ds["iterations"].values.max()),
        "total_cutbacks": int(ds["cutbacks"].values.sum()),
        "wall_time": wall,
        "attrs": {v: dict(ds[v].attrs) for v in aligned},
    }


def _failed(status, wall):
    """The result of a run that produced no dataset: NaN everywhere, its error in ``status``."""
    return {"aligned": {}, "exact": False, "status": status, "n_steps": 0, "total_iterations": 0,
            "max_iterations": 0, "total_cutbacks": 0, "wall_time": wall, "attrs": {}}


# -- execution -----------------------------------------------------------------

CLUSTER_START = 8.0
"""Start of a 2-worker LocalCluster and its first tasks [s] (worker processes import asperity_sim and load
the numba cache): 8.7-11.4 s for a whole small sweep on it in benchmarks/sweep_auto.py (2 shared cores)."""


def estimate_run_seconds(scene: Scene, threads: int = 1) -> float | None:
    """Wall time of one run [s] on ``threads`` numba threads from its law's cost model (rough, for choosing);
    None when the law declares none.  Kernels are taken to scale perfectly over the threads."""
    from .. import laws

    cost = laws.get(scene.law).cost
    if cost is None:
        return None
    return cost.seconds(sum(s.increments for s in scene.path.stages), scene.n, scene.options(), threads)


def choose_engine(scenes, workers: int = 2, cpus: int | None = None) -> tuple[str, str]:
    """("serial" or "local", reason): the engine estimated faster for these runs.

    Serial: every run on all ``cpus`` numba threads (also when a law declares no cost model).  Local cluster: :data:`CLUSTER_START`, then
    the runs shared by min(workers, cpus, runs) processes with cpus // workers threads each.
    The kernels use every core either way, so a cluster gains only the Python-side work it
    runs side by side (many small runs) and must win back its start.
    """
    cpus = (os.cpu_count() or 1) if cpus is None else cpus
    unknown = sorted({sc.law for sc in scenes if estimate_run_seconds(sc) is None})
    if unknown:
        return "serial", f"auto: serial (law {', '.join(unknown)} declares no cost model to estimate a cluster by)"
    serial = sum(estimate_run_seconds(sc, cpus) for sc in scenes)
    share = max(1, min(workers, cpus, len(scenes)))
    per_worker = max(1, cpus // workers)
    cluster = CLUSTER_START + sum(estimate_run_seconds(sc, per_worker) for sc in scenes) / share \
        if share > 1 else math.inf
    choice = "local" if cluster < serial else "serial"
    reason = (f"auto: estimated {serial:.1f} s serial, {cluster:.1f} s on a {workers}-worker local cluster "
              f"({cpus} cores)")
    return choice, reason


def worker_env() -> dict:
    """Environment of local worker processes: idle OpenMP threads sleep (``OMP_WAIT_POLICY=PASSIVE``).

    With numba's OpenMP layer, threads that spin between the parallel reductions of a
    Newton iteration slow every process on a shared machine (measured: a small run took
    2.5 s spinning against 0.06 s sleeping on 2 loaded cores); an explicit setting wins.
    """
    return {"OMP_WAIT_POLICY": os.environ.get("OMP_WAIT_POLICY", "PASSIVE")}


def dask_available() -> bool:
    try:
        import dask.distributed  # noqa: F401
    except ImportError:
        return False
    return True


def run_sweep(sweep: Sweep, scheduler=None, workers: int = 2, progress=None, note=None,
              threads: int | None = None) -> xr.Dataset:
    """Run every point of ``sweep`` and gather one Dataset (see the module docstring).

    scheduler : None or "auto" (serial or a local cluster, whichever :func:`choose_engine` estimates
        faster), "local" (a ``dask.distributed.LocalCluster`` of ``workers`` processes), "serial",
        an address such as ``"tcp://host:8786"``, or a ``dask.distributed.Client``; None, "auto"
        and "local" run serially, with a note, when dask is not installed
    progress : callable(done, total) after each finished run
    note : callable(str) for messages to the user (default: ``logging.warning``)
    threads : numba threads per run on Dask workers (default: cores // workers on a local
        cluster, the workers' own setting elsewhere); a software setting, results do not depend on it
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers = {workers!r} is out of range (valid range: integer >= 1)")
    note = note or logging.getLogger(__name__).warning
    scenes = sweep.scenes()
    t0 = time.perf_counter()
    results, engine = _execute(scenes, scheduler, workers, progress, note, threads)
    return sweep_dataset(sweep, results, engine=engine, wall_time=time.perf_counter() - t0)


def _execute(scenes, scheduler, workers, progress, note, threads=None):
    total = len(scenes)
    why = ""
    if scheduler in (None, "auto", "local"):
        if not dask_available():
            note("dask.distributed is not installed: running the sweep serially "
                 "(pip install 'asperity-sim[distributed]' to run it on a local cluster)")
            scheduler = "serial"
        elif scheduler != "local":
            scheduler, why = choose_engine(scenes, workers)
            why = f"; {why}"
    if scheduler == "serial":
        import numba

        before = numba.get_num_threads()
        results = []
        try:
            for i, scene in enumerate(scenes, 1):
                results.append(run_one(scene, threads))
                if progress:
                    progress(i, total)
        finally:
            numba.set_num_threads(before)
        return results, f"serial ({numba.get_num_threads() if threads is None else threads} numba threads{why})"
    if isinstance(scheduler, str) and scheduler != "local" and not dask_available():
        raise ValueError(f"scheduler = {scheduler!r} needs dask.distributed, which is not installed "
                         "(pip install 'asperity-sim[distributed]')")
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = client = None
    try:
        if scheduler is None or scheduler == "local":
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR, env=worker_env())
            client = Client(cluster)
            threads = threads or max(1, (os.cpu_count() or 1) // workers)
            engine = f"dask LocalCluster ({workers} workers, 1 task and {threads} numba threads each{why})"
        elif isinstance(scheduler, str):
            try:
                client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError) as err:
                raise ValueError(f"cannot connect to the Dask scheduler at {scheduler!r}: {err}") from None
            engine = f"dask scheduler {scheduler}"
        else:
            client = scheduler
            engine = f"dask client {getattr(scheduler, 'scheduler', scheduler)}"
        futures = client.map(run_one, scenes, threads=threads, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        results = [None] * total
        for done, fut in enumerate(as_completed(futures), 1):
            results[index[fut.key]] = fut.result()
            if progress:
                progress(done, total)
        return results, engine
    finally:
        if client is not None and client is not scheduler:
            client.close()
        if cluster is not None:
            cluster.close()
