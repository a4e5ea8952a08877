"""The helper process of :mod:`asperity_sim.kernels.ahead`: compile a history law's commit kernels into the cache.

Run as ``python -m asperity_sim.kernels.ahead_helper <law> <follow|birth>``: a three-asperity
population (no sampling kernels) under the law and policy is committed twice, at displacements
where all three touch, which compiles the commit of contacts born (``commit_fresh``) and then of
committed contacts (``commit_slots``) with the argument types of any run; each kernel's name is
printed as soon as numba has written it to its cache.
"""

from __future__ import annotations

import sys

import numpy as np

from .. import presets
from ..sampling.population import Population
from .ahead import commit_kernel_names
from .state import ContactState


def main(argv=None) -> int:
    law, policy = (sys.argv[1:] if argv is None else argv)[:2]
    p = presets.R1
    pop = Population.from_arrays(p, [0.0, 0.1 * p.beta, 0.2 * p.beta], [p.R_m] * 3, [0.3, 0.6, 0.9], [0.0, 1.0, 2.0])
    state = ContactState(pop, law=law, policy=policy)
    for name, d2 in zip(commit_kernel_names(law, policy == "birth"), (0.0, 0.1 * p.beta)):
        state.commit(np.array([p.beta, d2, 0.0]))
        print(name, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
