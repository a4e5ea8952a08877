"""Accuracy and cost of ``reference.stress`` over the parameter box, anisotropic sets included.

Draws random valid parameter sets around the Table 1 presets (b, c, d, e, r_o, mu, R_sigma,
alpha, beta all varied; mu fixed with ``--mu``, e.g. 0.3 as in issue 24) and a displacement
Delta_1 in [0.5, 2] mean heights with shears up to Delta_1 in both directions, and compares
the default level with a refined one (``--ref-level``, default "ultra").  The error measure is
the one of the module docstring: max_i |sigma_i - sigma_i^ref| / max_i |sigma_i^ref|.

Run:   python benchmarks/reference_accuracy.py [--seed 4] [--n 30] [--mu 0.3] [--level default]
Prints one line per point and a summary (worst, 90 % quantile, median error; time per call);
writes no file.  About 2 minutes with the defaults (113 s measured on one numba thread of this
2-core machine, most of it the refined "ultra" level).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from asperity_sim import reference as ref
from asperity_sim.presets import R1, R2, S1, S2


def draw(rng, mu=None):
    """One random valid (params, delta) around a random Table 1 preset."""
    base = [R1, S1, R2, S2][rng.integers(4)]
    b = rng.uniform(-1.0, 1.5)
    rho = rng.uniform(0.0, (1.0 - b / 2.0) / 3.0)  # b/2 + 3 sqrt(c² + d²) <= 1 (SPEC §3)
    ang = rng.uniform(0.0, 2.0 * math.pi)
    mu_ = mu if mu is not None else rng.choice([0.3, rng.uniform(0.05, 1.5)])
    params = base.replace(b=b, c=rho * math.cos(ang), d=rho * math.sin(ang), e=rng.uniform(0.05, 1.0),
                          r_o=rng.uniform(0.0, 3.0) * base.beta, mu=mu_,
                          R_sigma=base.R_m * rng.uniform(0.0, 0.4), alpha=rng.uniform(0.5, 9.0),
                          beta=base.beta * rng.uniform(0.5, 2.0))
    d1 = params.beta * (params.alpha + 1.0) * rng.uniform(0.5, 2.0)
    shear = d1 * rng.uniform(0.0, 1.0, 2) * rng.choice([-1.0, 1.0], 2)
    return params, np.array([d1, *shear])


def rel_err(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=4)
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--mu", type=float, default=None)
    ap.add_argument("--level", default="default")
    ap.add_argument("--ref-level", default="ultra")
    ap.add_argument("--ref-refine", type=float, default=1.0)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    ref.stress(R1, np.array([15e-6, 3e-6, 1e-6]))  # compile (or load the numba cache) untimed
    errs, times = [], []
    for i in range(args.n):
        params, delta = draw(rng, args.mu)
        t0 = time.perf_counter()
        s = ref.stress(params, delta, level=args.level)
        times.append(time.perf_counter() - t0)
        s_ref = ref.stress(params, delta, level=args.ref_level, refine=args.ref_refine)
        errs.append(rel_err(s, s_ref))
        p = params
        print(f"{i:3d} err {errs[-1]:.2e}  {times[-1] * 1e3:6.1f} ms  b={p.b:+.2f} c={p.c:+.3f} d={p.d:+.3f} "
              f"e={p.e:.2f} r_o/beta={p.r_o / p.beta:.2f} mu={p.mu:.2f} R_sigma/R_m={p.R_sigma / p.R_m:.2f} "
              f"alpha={p.alpha:.2f} Delta/beta=({', '.join(f'{x:+.2f}' for x in delta / p.beta)})", flush=True)
    e, t = np.array(errs), np.array(times)
    print(f"level {args.level} vs {args.ref_level} x{args.ref_refine}: worst {e.max():.2e}, 90% {np.quantile(e, 0.9):.2e}, "
          f"median {np.median(e):.2e}; time per call median {np.median(t) * 1e3:.1f} ms, mean {t.mean() * 1e3:.1f} ms, "
          f"max {t.max() * 1e3:.1f} ms ({args.n} points, seed {args.seed}, mu {args.mu})")
    return e


if __name__ == "__main__":
    main()
