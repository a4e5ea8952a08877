"""Wall-time measurement shared by the studies and benchmarks (``studies/``, ``benchmarks/``).

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
