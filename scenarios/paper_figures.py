"""Regenerate the paper's three scenarios (Figs. 11, 12, 13) in one run.

Runs scenarios/three_step.py, normal_closure.py and constant_normal_shear.py with their
defaults (options are passed on to each, so only the options the three share: --n, --seed,
--sampler, --increments, --outdir, --no-reference, --quick), writing outputs/*.nc and
outputs/*.png.  tests/test_scenarios.py runs it with --quick --n 2000.

Run:   python scenarios/paper_figures.py [--n 200000] [--seed 2024] [--quick] [--outdir DIR]
Expected run time: about 15 s with a warm numba cache on 2 cores (the quadrature reference curves, solved on
the threads, are most of it).
"""

from __future__ import annotations

import sys
import time

import constant_normal_shear
import normal_closure
import three_step


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    t0 = time.perf_counter()
    for module in (three_step, normal_closure, constant_normal_shear):
        print(f"== {module.__name__} ==")
        t = time.perf_counter()
        module.main(argv)
        print(f"   ({time.perf_counter() - t:.1f} s)\n")
    print(f"all scenarios done in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
