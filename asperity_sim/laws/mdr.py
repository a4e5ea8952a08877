"""The ``mdr`` asperity law: Hertz normal force and a vector MDR tangential law with memory.

Method of dimensionality reduction (Popov & Heß) in vector form (issue 4): each contact
is a row of k independent tangential spring-sliders at x_i = (i - 1/2) h on a line.

- normal: local overlap of spring i, u_i = delta_n - x_i²/R (in contact where u_i > 0);
  the normal force stays Hertz, f_n = (4/3) E* sqrt(R) delta_n^(3/2) (SPEC §5);
- tangential: spring i holds a 2-vector w_i (local s, t components).  In contact it
  follows the tangential displacement increment of the asperity and is returned radially
  onto the circle |w_i| <= lam mu u_i (Coulomb per spring, the MDR image of mu p);
- force: (f_s, f_t) = (2 E*/lam) h sum_i w_i  (tangential spring stiffness G* = E*/lam).

Within an increment delta_n and the tangential displacement are taken to vary linearly,
so a spring that enters contact (u_i^c <= 0 < u_i) carries the part of the increment
after its entry, frac = u_i / (u_i - u_i^c): proportional loading below slip stays
exactly elastic.  A spring that leaves contact holds zero.

Everything here is a scalar numba function of one asperity; the history (committed w,
committed delta_n) is read, never written, except by :func:`mdr_springs` in commit mode,
which writes the new springs into a caller-owned scratch array.

Energy of one increment, per spring (q = 2 E* h / lam):
stored ½ q |w|²; work q ½(w^c + w).dδ_i while it sticks (exact for a linear spring: the
change of its energy), q w.dδ_i when it slips (end-point rule of the radial return), where
dδ_i is the displacement it took while in contact; dissipation q w.p + ½ q |w - w^c|² >= 0
for a slipping spring (p: its slip), 0 for a sticking one.  Work = change of stored
energy + dissipation then holds per spring (to round-off), and dissipation never
decreases.  A spring that leaves contact follows the increment elastically until its exit
and then slides to zero as its limit vanishes (:func:`release_springs`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

STICK, PARTIAL, FULL_SLIP = 1, 2, 3


@numba.njit(cache=True)
def mdr_springs(dn, dds, ddt, dn_c, w_c, n_hist, h, R, E_star, lam, mu, J, w_out):
    """Local force, Jacobian and energy of one contact with delta_n = dn > 0.

    Parameters
    ----------
    dn : trial normal overlap [m]
    dds, ddt : trial tangential increment (s, t) since the committed state [m]
    dn_c : committed normal overlap [m] (<= 0: no committed contact)
    w_c : (>= n_hist, 2) committed spring vectors [m]; only the first n_hist are read
    n_hist : number of springs with history (0 for a fresh contact)
    h : spring spacing [m]
    J : (3, 3) output, d(f_n, f_s, f_t) / d(delta_n, dds, ddt)
    w_out : (m, 2) scratch written with the new springs when m > 0 (commit mode)

    Returns
    -------
    f_n, f_s, f_t [N], n_springs (in contact), n_slipping, state code,
    work, delta_stored, dissipation [J] (meaningful in commit mode only)
    """
    C = (4.0 / 3.0) * E_star * math.sqrt(R)
    sq = math.sqrt(dn)
    f_n = C * dn * sq
    inv_R = 1.0 / R
    q = 2.0 * E_star * h / lam
    lm = lam * mu
    write = w_out.shape[0] > 0
    Fs = Ft = 0.0
    J10 = J11 = J12 = J20 = J21 = J22 = 0.0
    n_springs = 0
    n_slip = 0
    work = stored_change = dissipation = 0.0
    i = 0
    while True:
        x = (i + 0.5) * h
        x2 = x * x * inv_R
        u = dn - x2
        if u <= 0.0:
            break
        u_c = dn_c - x2
        # continuing spring: committed vector plus the increment.  A spring with memory but
        # u_c <= 0 exists only after coarsening (merged across the contact edge): it keeps it.
        if i < n_hist and (u_c > 0.0 or w_c[i, 0] != 0.0 or w_c[i, 1] != 0.0):
            wcs, wct = w_c[i, 0], w_c[i, 1]
            a = 1.0
            bs = bt = 0.0
        else:  # entering: in contact for the last fraction of the increment
            wcs = wct = 0.0
            if u_c > 0.0:  # no stored history (fresh contact already overlapping): whole increment
                a = 1.0
                da = 0.0
            else:
                a = u / (u - u_c)
                da = -u_c / ((u - u_c) * (u - u_c))
            bs, bt = da * dds, da * ddt
        ws = wcs + a * dds
        wt = wct + a * ddt
        limit = lm * u
        m2 = ws * ws + wt * wt
        # mu = 0: the stick region is empty, every spring slides (zero force and zero tangent,
        # also at a zero tangential increment, where the stick branch would give a spurious q a)
        slipping = m2 > limit * limit or lm == 0.0
        if not slipping:
            Fs += ws
            Ft += wt
            J10 += bs
            J20 += bt
            J11 += a
            J22 += a
        else:
            n_slip += 1
            m = math.sqrt(m2)
            if m > 0.0:
                es, et = ws / m, wt / m
            else:
                es = et = 0.0
            ratio = limit / m if m > 0.0 else 0.0
            # d(limit e)/d(w*) = ratio (I - e e^T); d limit/d delta_n = lm
            P00, P01, P11 = ratio * (1.0 - es * es), -ratio * es * et, ratio * (1.0 - et * et)
            J10 += P00 * bs + P01 * bt + lm * es
            J20 += P01 * bs + P11 * bt + lm * et
            J11 += a * P00
            J12 += a * P01
            J21 += a * P01
            J22 += a * P11
            ws, wt = limit * es, limit * et
            Fs += ws
            Ft += wt
        if write:
            if i < w_out.shape[0]:
                w_out[i, 0] = ws
                w_out[i, 1] = wt
            # displacement this spring took while in contact: a (dds, ddt)
            dis, dit = a * dds, a * ddt
            de = 0.5 * q * (ws * ws + wt * wt - wcs * wcs - wct * wct)
            if slipping:  # end-point work; dissipation q w.p + ½ q |w - w_c|² >= 0, p the slip
                wk = q * (ws * dis + wt * dit)
                ps, pt = wcs + dis - ws, wct + dit - wt
                dissipation += q * (ws * ps + wt * pt) + 0.5 * q * ((ws - wcs) ** 2 + (wt - wct) ** 2)
            else:  # a linear spring: its work is its change of energy
                wk = de
            work += wk
            stored_change += de
        n_springs += 1
        i += 1
    if write:
        wk, de, dd = release_springs(w_c, i, n_hist, dn, dn_c, h, inv_R, dds, ddt, q)
        work += wk
        stored_change += de
        dissipation += dd
        for jj in range(i, w_out.shape[0]):
            w_out[jj, 0] = 0.0
            w_out[jj, 1] = 0.0
    J[0, 0] = 1.5 * C * sq
    J[0, 1] = J[0, 2] = 0.0
    J[1, 0], J[1, 1], J[1, 2] = q * J10, q * J11, q * J12
    J[2, 0], J[2, 1], J[2, 2] = q * J20, q * J21, q * J22
    if n_slip == 0:
        state = STICK
    elif n_slip == n_springs:
        state = FULL_SLIP
    else:
        state = PARTIAL
    return f_n, q * Fs, q * Ft, n_springs, n_slip, state, work, stored_change, dissipation


@numba.njit(cache=True, inline="always")
def release_springs(w_c, start, n_hist, dn, dn_c, h, inv_R, dds, ddt, q):
    """Work, change of stored energy and dissipation of springs start..n_hist-1 leaving contact.

    A spring in contact for the first fraction f = u^c/(u^c - u) of the increment follows
    it elastically to w* = w^c + f dδ (work ½ q (w^c + w*).f dδ); as its limit vanishes at
    the exit it slides to zero, dissipating ½ q |w*|².  Under proportional unloading w* = 0.
    """
    work = stored_change = dissipation = 0.0
    for jj in range(start, n_hist):
        wcs, wct = w_c[jj, 0], w_c[jj, 1]
        if wcs == 0.0 and wct == 0.0:
            continue
        x2 = ((jj + 0.5) * h) ** 2 * inv_R
        u_c, u = dn_c - x2, dn - x2
        f = u_c / (u_c - u) if u_c > 0.0 and u < u_c else 0.0
        es, et = wcs + f * dds, wct + f * ddt
        work += 0.5 * q * ((wcs + es) * f * dds + (wct + et) * f * ddt)
        stored_change -= 0.5 * q * (wcs * wcs + wct * wct)
        dissipation += 0.5 * q * (es * es + et * et)
    return work, stored_change, dissipation


@numba.njit(cache=True)
def hertz_energy(dn, R, E_star):
    """Elastic energy of the Hertz normal spring, (8/15) E* sqrt(R) delta_n^(5/2) [J]."""
    if dn <= 0.0:
        return 0.0
    return (8.0 / 15.0) * E_star * math.sqrt(R) * dn * dn * math.sqrt(dn)


@numba.njit(cache=True)
def merge_pairs(w, n):
    """Coarsen n springs to ceil(n/2) by merging neighbours (spacing doubles), in place.

    The merged vector is the mean of the pair, so the force (2E*/lam)(2h) sum w is kept;
    returns the stored energy lost per unit q, ½ sum |w_a - w_b|² / 2 (counted as dissipation).
    """
    lost = 0.0
    m = (n + 1) // 2
    for j in range(m):
        a0, a1 = w[2 * j, 0], w[2 * j, 1]
        if 2 * j + 1 < n:
            b0, b1 = w[2 * j + 1, 0], w[2 * j + 1, 1]
        else:
            b0 = b1 = 0.0
        lost += 0.25 * ((a0 - b0) ** 2 + (a1 - b1) ** 2)
        w[j, 0] = 0.5 * (a0 + b0)
        w[j, 1] = 0.5 * (a1 + b1)
    for j in range(m, n):
        w[j, 0] = 0.0
        w[j, 1] = 0.0
    return lost


def spring_spacing_guess(R, dn_cap, k):
    """Spacing h = sqrt(R dn_cap)/k [m] that covers a contact of overlap dn_cap with k springs."""
    return np.sqrt(R * np.maximum(dn_cap, 0.0)) / k
