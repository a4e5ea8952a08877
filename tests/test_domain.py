"""The paper law's domain (asperity_sim.solve.domain): a run that leaves it warns once and records where."""

import warnings

import numpy as np
import pytest

from asperity_sim import LawDomainWarning, paths, presets, simulate
from asperity_sim.solve.domain import LOOP_WORK, NORMAL_CHANGE, SHEAR_TURN

um = 1e-6
S, D = paths.STRESS, paths.DISPLACEMENT


def rectangle(d1=12 * um, a=3 * um, b=5 * um, inc=6):
    """A closed loop in (Delta_1, Delta_2): +b along 2, +a along 1, -b along 2, -a along 1."""
    st = [paths.Stage((D, D, D), (d1, 0, 0), inc, name="close")]
    for target in ((d1, b, 0), (d1 + a, b, 0), (d1 + a, 0, 0), (d1, 0, 0)):
        st.append(paths.Stage((D, D, D), target, inc))
    return paths.LoadPath(tuple(st), name="rectangle")


def loop_work(ds, first):
    """External work [J m-2] from step ``first`` to the end, trapezoid rule on the recorded stresses."""
    d, s = ds.displacement.values[first:], ds.stress.values[first:]
    return float(np.sum(0.5 * (s[1:] + s[:-1]) * np.diff(d, axis=0)))


def test_monotonic_shear_at_constant_normal_stress_stays_in_the_domain():
    with warnings.catch_warnings():
        warnings.simplefilter("error", LawDomainWarning)
        ds = simulate(presets.R1, paths.constant_normal_shear(300e6, 10e-6, increments=10), n=3000, seed=1)
    assert np.all(ds.law_domain.values == 0)
    assert "law_domain_first_step" not in ds.attrs


def test_a_closed_loop_warns_once_at_its_first_step_outside_and_flags_the_energy_returned():
    with pytest.warns(LawDomainWarning) as record:
        ds = simulate(presets.R1, rectangle(), n=4000, seed=1)
    assert len([w for w in record if issubclass(w.category, LawDomainWarning)]) == 1
    flags = ds.law_domain.values
    first = int(np.flatnonzero(flags)[0])
    assert ds.attrs["law_domain_first_step"] == first
    assert "step %d" % first in str(record[0].message)
    assert flags[first] & NORMAL_CHANGE  # Delta_1 rises while sheared: sigma_1 moves
    assert np.any(flags & SHEAR_TURN)  # the shear reverses on the way back
    start = 6  # end of the closing stage: the loop starts and ends here
    w = loop_work(ds, start)
    assert w < 0.0  # the path-independent law returns energy on this loop (independent trapezoid sum)
    assert flags[-1] & LOOP_WORK


def test_the_history_law_needs_no_domain_and_dissipates_on_the_same_loop():
    with warnings.catch_warnings():
        warnings.simplefilter("error", LawDomainWarning)
        ds = simulate(presets.R1, rectangle(), n=4000, seed=1, law="mdr", k=8)
    assert "law_domain" not in ds
    W = ds.external_work.values
    assert W[-1] - W[6] > 0.0  # positive net work over the closed loop: dissipation
    np.testing.assert_allclose(W[-1] - W[6], ds.dissipation.values[-1] - ds.dissipation.values[6]
                               + ds.elastic_energy.values[-1] - ds.elastic_energy.values[6], rtol=1e-9)
