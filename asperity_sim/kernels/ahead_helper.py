"""The helper process of :mod:`asperity_sim.kernels.ahead`: compile a law's last-needed kernels into the cache.

Run as ``python -m asperity_sim.kernels.ahead_helper <law> <follow|birth> [serial|parallel]``,
with populations given as arrays (no sampling kernels):

- a history law: three asperities committed twice, at displacements where all three touch,
  which compiles the commit of contacts born (``commit_fresh``) and then of committed contacts
  (``commit_slots``) with the argument types of any run;
- a law without history: one evaluation where every asperity touches, of three asperities
  (``serial``: the serial kernel) or of one more than the serial kernel takes (``parallel``),
  after a call of its loop over a chunk (``chunk_follow``, most of its compile) on its own, so
  that the run, waiting, compiles the serial kernel's other callees for it to load.

Each kernel's name is printed as soon as numba has written it to its cache.
"""

from __future__ import annotations

import sys

import numpy as np

from .. import laws, presets
from ..sampling.population import Population
from .ahead import kernel_names
from .evaluate import evaluate
from .layout import CHUNK, SERIAL_CHUNKS
from .specialise import kernels
from .state import ContactState
from .workspace import Workspace


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    law, policy = args[:2]
    serial = (args[2] if len(args) > 2 else "serial") == "serial"
    birth = policy == "birth"
    p, lw = presets.R1, laws.get(law)
    names = kernel_names(lw, birth, serial)
    if lw.history is not None:
        pop = Population.from_arrays(p, [0.0, 0.1 * p.beta, 0.2 * p.beta], [p.R_m] * 3, [0.3, 0.6, 0.9],
                                     [0.0, 1.0, 2.0])
        state = ContactState(pop, law=law, policy=policy)
        for name, d2 in zip(names, (0.0, 0.1 * p.beta)):
            state.commit(np.array([p.beta, d2, 0.0]))
            print(name, flush=True)
        return 0
    n = 3 if serial else SERIAL_CHUNKS * CHUNK + 1
    pop = Population.from_arrays(p, np.linspace(0.0, 0.2 * p.beta, n), np.full(n, p.R_m), np.linspace(0.3, 0.9, n),
                                 np.linspace(0.0, 2.0, n))
    # the loop over a chunk first (most of the kernel's compile), with the argument types the kernel gives it: the
    # kernel's other callees (bounds, finish) the waiting run compiles meanwhile (kernels.evaluate.at_contacts)
    state, (_, k_e, *_) = ContactState(pop, law, policy), pop.kernel_constants
    kernels(lw)["chunk_follow"](0, *pop.arrays, n, p.beta, 0.0, 0.0, 0.0, 0.0, k_e, state.consts, 0.0,
                                Workspace(n).partial)
    evaluate(pop, np.array([p.beta, 0.0, 0.0]), law=law, policy=policy)
    print(names[0], flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
