"""One asperity driven through a path of local displacements (validation and single-contact studies).

Owns nothing new: the contact is a population of one flat-on-flat asperity (e = 0, so
theta = 0 and the local frame is the global one: n = e1, s = e2, t = e3) with N = 1 and
weight 1, evaluated and committed by exactly the kernels of an interface run.  Its
"stress" is then the contact force in newtons.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from .. import laws
from ..checks import check_real
from ..kernels.evaluate import Workspace, evaluate
from ..kernels.state import ContactState
from ..params import InterfaceParams
from ..sampling.population import Population
from ..version import __version__

COMPONENTS = ["n", "s", "t"]


def single_contact(path, R, G, nu, mu, law: str = "mdr", **law_options) -> xr.Dataset:
    """Force and energy of one asperity along a path of local displacements.

    Parameters
    ----------
    path : array_like (m, 3) [m]
        Local displacements (delta_n, delta_s, delta_t), reached in this order from a virgin
        contact at zero; each row is one increment.
    R : float [m], relative radius;  G : float [Pa];  nu : float [1];  mu : float [1]
    law : a registered law: "mdr" (history, default) or "paper" (path independent, SPEC §5)
    **law_options : the law's options (``mdr``: ``k``, ``spring_dtype``), as in :func:`~asperity_sim.simulate`

    Returns
    -------
    xarray.Dataset over ``point`` with ``displacement`` and ``force`` (point, component) [m, N]
    (components n, s, t), ``tangent`` (point, component, component_k) [N m-1], and for a
    history law the cumulative ``external_work`` and ``dissipation`` [J], the stored
    ``elastic_energy`` [J], the contact ``state`` (0 out, 1 stick, 2 partial slip, 3 full
    slip) and the law's event count (``mdr``: ``coarsenings``); the law's options as attributes.
    """
    lw = laws.get(law)
    d = np.asarray(path, dtype=float)
    if d.ndim != 2 or d.shape[1] != 3 or d.shape[0] < 1:
        raise ValueError(f"path must have shape (m, 3) [m] with m >= 1, got shape {d.shape}")
    if not np.all(np.isfinite(d)):
        raise ValueError("path holds non-finite displacements (valid range: finite reals [m])")
    R = check_real("R [m]", R, 0.0, None, lo_open=True)
    dn_max = float(max(d[:, 0].max(), 0.0))
    params = InterfaceParams(N=1.0, alpha=0.0, beta=max(dn_max, R * 1e-9), R_m=R, R_sigma=0.0, mu=mu, G=G,
                             nu=nu, e=0.0)
    pop = Population.from_arrays(params, [0.0], [R], [0.0], [0.0])
    ws = Workspace(1)
    state = ContactState(pop, lw, **law_options)
    state.reference = np.array([dn_max, 0.0, 0.0])  # a fresh contact's springs fit the path's largest overlap
    history = state if state.has_history else None
    m = d.shape[0]
    force = np.zeros((m, 3))
    tangent = np.zeros((m, 3, 3))
    work = np.zeros(m)
    stored = np.zeros(m)
    diss = np.zeros(m)
    codes = np.zeros(m, dtype=np.int8)
    coarse = np.zeros(m, dtype=np.int64)
    w_sum = d_sum = 0.0
    for i in range(m):
        ev = evaluate(pop, d[i], law=lw, workspace=ws, state=state)
        force[i] = ev.stress
        tangent[i] = ev.tangent
        c = state.commit(d[i], ev.n_active, ws)
        if history is not None:
            w_sum += c.work
            d_sum += c.dissipation
            work[i], stored[i], diss[i], coarse[i] = w_sum, c.stored, d_sum, c.events
            codes[i] = state.code[0] if state.flag[0] else 0
    coords = {"point": np.arange(m), "component": COMPONENTS, "component_k": COMPONENTS}
    ds = xr.Dataset(
        {
            "displacement": (("point", "component"), d, {"units": "m", "long_name": "local displacement"}),
            "force": (("point", "component"), force, {"units": "N", "long_name": "contact force (f_n, f_s, f_t)"}),
            "tangent": (("point", "component", "component_k"), tangent,
                        {"units": "N m-1", "long_name": "tangent stiffness d f / d delta"}),
        },
        coords=coords,
        attrs={"law": lw.name, "R": R, "G": params.G, "nu": params.nu, "mu": params.mu,
               "source": f"asperity_sim {__version__}", "Conventions": "CF-1.8"},
    )
    ds.attrs.update(lw.run_attributes(state.options, getattr(state, "arrays", ())))
    if history is not None:
        ds["external_work"] = ("point", work, {"units": "J", "long_name": "cumulative external work"})
        ds["elastic_energy"] = ("point", stored, {"units": "J", "long_name": "stored elastic energy"})
        ds["dissipation"] = ("point", diss, {"units": "J", "long_name": "cumulative frictional dissipation"})
        ds["state"] = ("point", codes, {"units": "1", "long_name": "contact state (0 out, 1 stick, 2 partial, 3 slip)"})
        events = lw.variables[lw.history.events]
        ds[lw.history.events] = ("point", coarse, {"units": events.units, "long_name": events.long_name})
    return ds
