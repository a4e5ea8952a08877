"""Steps 4–5 of the paper's grid method: the tangent by forward differences, and Newton on it.

Owns :func:`fd_tangent` (Step 4, Eq. 27: T_ik = d sigma_i / d Delta_k by forward differences)
and :func:`grid_newton` (Step 5: Newton on the stress-controlled components, with the
safeguards the paper does not state), for :func:`asperity_sim.analysis.gridmethod.simulate_grid`.
``F`` is any stress function of the displacement, sigma(Delta) [Pa] of (3,) [m].
"""

from __future__ import annotations

import numpy as np


def fd_tangent(F, x, sig, h, columns):
    """Step 4: the columns k of T_ik = d sigma_i / d Delta_k [Pa/m] (Eq. 27) by forward differences
    of step h [m] from (x, sig = F(x)); the other columns are NaN."""
    T = np.full((3, 3), np.nan)
    for k in columns:
        xp = x.copy()
        xp[k] += h
        T[:, k] = (F(xp) - sig) / h
    return T


def grid_newton(F, x, sig, free, target, h, rtol, max_iter, full_tangent):
    """Steps 4–5: Newton with a forward-difference tangent (step h [m]) on the free components.

    ``full_tangent``: Step 4 as published, the whole tangent at every iterate, the converged
    one included (the paper's Step 4 comes before the convergence check of Step 5);
    otherwise only the free columns, only while iterating.
    Safeguards (not in the paper, which does not say how it started or protected Newton):
    with one free component, every iterate that brackets the root is kept and a Newton step
    leaving the bracket is replaced by bisection; a zero tangent (no contact yet) steps
    towards the target by h, doubling.  With several free components the step is halved
    until the residual falls.  Returns (Delta, sigma, iterations, scaled residual, tangent
    at Delta or None).
    """
    idx = np.flatnonzero(free)
    lo = hi = None
    search = h
    for it in range(max_iter + 1):
        T_full = fd_tangent(F, x, sig, h, range(3)) if full_tangent else None
        scale = max(np.max(np.abs(target[idx])), np.max(np.abs(sig)), 1e-9)
        res = target[idx] - sig[idx]
        norm = float(np.max(np.abs(res)) / scale)
        if norm <= rtol:
            return x, sig, it, norm, T_full
        if it == max_iter:
            break
        if idx.size == 1:  # bracket: the stress grows with the displacement along a stress control
            if res[0] > 0.0:
                lo = x[idx[0]]
            else:
                hi = x[idx[0]]
        T = (T_full if full_tangent else fd_tangent(F, x, sig, h, idx))[np.ix_(idx, idx)]
        step = np.full(idx.size, np.nan)
        if np.all(np.isfinite(T)) and abs(np.linalg.det(T)) > 0.0:
            step = np.linalg.solve(T, res)
        x_new = x.copy()
        if idx.size == 1:
            k = idx[0]
            cand = x[k] + step[0]
            if lo is not None and hi is not None:
                if not (min(lo, hi) < cand < max(lo, hi)):
                    cand = 0.5 * (lo + hi)
            elif not np.isfinite(cand) or (lo is not None and cand <= lo) or (hi is not None and cand >= hi):
                cand = x[k] + (search if res[0] > 0.0 else -search)
                search *= 2.0
            x_new[k] = cand
            x, sig = x_new, F(x_new)
            continue
        if not np.all(np.isfinite(step)):
            step = np.where(res > 0, search, -search)
            search *= 2.0
        lam = 1.0
        for _ in range(30):
            x_new = x.copy()
            x_new[idx] += lam * step
            sig_new = F(x_new)
            if np.max(np.abs(target[idx] - sig_new[idx])) / scale < norm or lam < 1e-6:
                break
            lam *= 0.5
        x, sig = x_new, sig_new
    raise RuntimeError(f"grid Newton did not converge in {max_iter} iterations at Delta = {x} m "
                       f"(scaled residual {norm:.3g})")
