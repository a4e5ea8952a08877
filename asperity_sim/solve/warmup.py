"""Compile ahead: the kernels a run of each law needs, before the first run needs them.

Owns :func:`warmup`, which ``asperity-sim warmup`` (an HPC job script, a Dask worker's start-up)
calls: for each law, a few tiny runs that take the paths a real run takes (sampling with both
samplers, the serial and the parallel reductions, Newton under stress control, the commit of a
history law, snapshots, both angle policies), so that their kernels are compiled and written to
numba's on-disk cache.
A kernel already in the cache is only loaded.  The runs' results are thrown away.
"""

from __future__ import annotations

import time

from .. import laws, paths, presets
from ..kernels.layout import CHUNK, SERIAL_CHUNKS
from . import span
from .driver import simulate

__all__ = ["warmup"]


def warmup(law_names=None, report=None) -> dict:
    """Compile (or load from the cache) the kernels of each law in ``law_names`` (default: every registered law).

    ``report`` : callable(str), told what is being compiled; returns {law: seconds}.
    """
    names = list(laws.LAWS) if law_names is None else [laws.get(n).name for n in law_names]
    path = paths.LoadPath((paths.Stage(("s", "d", "d"), (50e6, 0.0, 0.0), 2),
                           paths.Stage(("s", "d", "d"), (50e6, 1e-6, 0.0), 2)), name="warm-up")
    big = SERIAL_CHUNKS * CHUNK + CHUNK  # beyond the serial kernels of a path-independent law
    out = {}
    mode, span.MODE = span.MODE, "always"  # the compiled increments too (solve.span: they stop at the snapshots)
    try:
        for name in names:
            if report is not None:
                report(f"compiling the {name} kernels")
            t0 = time.perf_counter()
            for n, sampler, policy in ((500, "random", "follow"), (512, "sobol", "follow"), (big, "random", "follow"),
                                       (500, "random", "birth"), (big, "random", "birth")):
                simulate(presets.R1, path, n=n, seed=1, sampler=sampler, law=name, snapshots=[0, 2], policy=policy)
            out[name] = time.perf_counter() - t0
    finally:
        span.MODE = mode
    return out
