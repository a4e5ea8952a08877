"""Wall-time measurement shared by the error-against-time studies (``convergence.py``, ``mdr_convergence.py``).

A helper of the scripts in ``studies/``, not of the package (it moved here from
``asperity_sim.timing`` in 0.4).  The scripts run as programs, so their folder is on
``sys.path`` and they ``import timing``; tests import it through ``tests/support.py``'s
``study("timing")``, which puts ``studies/`` on ``sys.path`` the same way.

Owns one rule: a run shorter than :data:`REPEAT_BELOW` seconds is timed :data:`REPEATS` times
and its median kept, because one timing of a 5-50 ms run varies about 2x on a shared machine;
a longer run is timed once.  Runs are deterministic, so the result is the first run's.
"""

from __future__ import annotations

import numpy as np

REPEAT_BELOW = 0.2
"""A run shorter than this [s] is timed :data:`REPEATS` times (median)."""
REPEATS = 3


def timed(run):
    """(result, wall time [s]) of ``run() -> (result, seconds)``: the median of REPEATS timings when the
    first is shorter than REPEAT_BELOW, else the first timing; the result is always the first run's."""
    result, seconds = run()
    if seconds < REPEAT_BELOW:
        seconds = float(np.median([seconds] + [run()[1] for _ in range(REPEATS - 1)]))
    return result, seconds
