"""The law protocol (:mod:`asperity_sim.laws`): a law registered here runs through `simulate`, and every
registered law meets the generic properties (Taylor test of the tangent, energy balance, trials never
change committed state, the same bits on 1 and 2 threads)."""

import numba
import numpy as np
import pytest

from asperity_sim import laws, paths, Population, presets, simulate
from asperity_sim.kernels.evaluate import evaluate
from asperity_sim.laws.hertz import hertz
from asperity_sim.kernels.state import ContactState

um = 1e-6
R1 = presets.R1


@numba.njit(cache=True, inline="always", error_model="numpy")
def frictionless_values(dn, ds, dt, R, consts):
    """Hertz normal force, no tangential force: every contact slides freely."""
    f_n, k_n = hertz(dn, R, consts[0])
    return (f_n, 0.0, 0.0, k_n, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 3.0)


FRICTIONLESS = laws.Law(name="test_frictionless_hertz", summary="Hertz without friction (test law)",
                        constants=lambda params, k: (params.E_star,), local=frictionless_values)


@pytest.fixture(autouse=True, scope="module")
def registered():
    """The test law is in the registry while this module's tests run, and only then."""
    laws.register(FRICTIONLESS)
    yield
    laws.LAWS.pop(FRICTIONLESS.name)


def test_a_law_registered_here_runs_through_simulate_and_equals_the_paper_law_without_friction():
    """Frictionless Hertz is the paper law at mu = 0: the same stresses along the 3-step path."""
    path = paths.three_step(6 * um, increments=6)
    ours = simulate(R1, path, n=4000, seed=2, law=FRICTIONLESS.name)
    paper = simulate(R1.replace(mu=0.0), path, n=4000, seed=2, law="paper")
    assert ours.attrs["law"] == FRICTIONLESS.name
    scale = np.abs(paper.stress.values).max()
    np.testing.assert_allclose(ours.stress.values, paper.stress.values, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(ours.tangent.values, paper.tangent.values, rtol=0,
                               atol=1e-12 * np.abs(paper.tangent.values).max())
    assert np.array_equal(ours.n_contact.values, paper.n_contact.values)
    assert ours.n_contact.values[-1] > 0


def test_a_history_law_without_block_kernels_is_run_contact_by_contact_with_the_same_result():
    """mdr registered again without its ``trial_block`` and ``commit_block``: the generic reductions call its
    ``trial`` and ``commit`` per contact, and a cyclic path gives the stresses, tangents and energies of mdr
    with its block kernels."""
    import dataclasses

    mdr = laws.get("mdr")
    plain = dataclasses.replace(mdr, name="test_mdr_per_contact",
                                history=dataclasses.replace(mdr.history, trial_block=None, commit_block=None))
    laws.register(plain)
    try:
        st = [paths.Stage((paths.STRESS, paths.DISPLACEMENT, paths.DISPLACEMENT), (100e6, 0, 0), 4)]
        for a in (1.5, -1.5, 0.0):
            st.append(paths.Stage((paths.STRESS, paths.DISPLACEMENT, paths.DISPLACEMENT), (100e6, a * um, 0.3 * a * um),
                                  6))
        path = paths.LoadPath(tuple(st))
        block = simulate(R1, path, n=3000, seed=5, law="mdr", k=8)
        each = simulate(R1, path, n=3000, seed=5, law=plain.name, k=8)
    finally:
        laws.LAWS.pop(plain.name)
    for name in ("stress", "tangent", "dissipation", "elastic_energy", "external_work"):
        a, b = block[name].values, each[name].values
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12 * np.abs(a).max(), err_msg=name)
    assert np.abs(block.stress.values[:, 1]).max() > 0


def test_registry_rejects_unknown_names_and_malformed_laws():
    with pytest.raises(ValueError, match=r"not known \(valid: paper, mdr"):
        laws.get("coulomb")
    with pytest.raises(ValueError, match="exactly one"):
        laws.Law(name="x", summary="", constants=lambda p, k: ())
    with pytest.raises(ValueError, match="law = 'coulomb' is not known"):
        simulate(R1, paths.three_step(1 * um, increments=2), n=100, law="coulomb")


def test_no_module_tests_a_law_by_name():
    """Laws are selected through the registry and their declared properties, never by name."""
    import pathlib
    import re

    root = pathlib.Path(laws.__file__).parent.parent
    pattern = re.compile(r"""law\w*\s*(==|!=)\s*["'](paper|mdr)["']|["'](paper|mdr)["']\s*(==|!=)\s*law""")
    offenders = [f"{path.name}:{i + 1}" for path in root.rglob("*.py")
                 for i, line in enumerate(path.read_text().splitlines()) if pattern.search(line)]
    assert offenders == []


def committed_state(law, policy, n=2000, seed=4):
    """A state of ``law`` after a short mixed path (normal, shear, turn)."""
    pop = Population.sample(R1, n, seed=seed)
    state = ContactState(pop, law, policy, k=8)
    steps = ([np.array([x, 0.0, 0.0]) for x in np.linspace(0, 14, 5)[1:] * um]
             + [np.array([14, y, 0.5 * y]) * um for y in np.linspace(0, 4, 5)[1:]]
             + [np.array([13.5, 4 - z, 2 + z]) * um for z in np.linspace(0, 2, 3)[1:]])
    for d in steps:
        ev = evaluate(pop, d, law=law, policy=policy, state=state)
        state.commit(d, ev.n_active)
    return pop, state


LAW_NAMES = [*laws.LAWS, FRICTIONLESS.name]


@pytest.mark.parametrize("policy", ["follow", "birth"])
@pytest.mark.parametrize("law", LAW_NAMES)
def test_tangent_taylor_remainders(law, policy):
    """First-order remainder falls with slope 1, second-order with slope 2 (exact tangent)."""
    pop, state = committed_state(law, policy)
    d = state.delta_c + np.array([0.2, -0.3, 0.4]) * um
    direction = np.array([0.5, -0.6, 0.4]) * um
    ev = evaluate(pop, d, law=law, policy=policy, state=state)
    assert ev.n_contact > 0
    hs = np.array([0.08, 0.04, 0.02, 0.01, 0.005])
    r0, r1 = [], []
    for h in hs:
        s = evaluate(pop, d + h * direction, law=law, policy=policy, state=state).stress
        r0.append(np.linalg.norm(s - ev.stress))
        r1.append(np.linalg.norm(s - ev.stress - h * ev.tangent @ direction))
    assert np.polyfit(np.log(hs), np.log(r0), 1)[0] == pytest.approx(1.0, abs=0.1)
    assert np.polyfit(np.log(hs), np.log(r1), 1)[0] == pytest.approx(2.0, abs=0.3)


@pytest.mark.parametrize("law", LAW_NAMES)
def test_trial_evaluations_never_change_committed_state(law):
    pop, state = committed_state(law, "birth")
    before = {k: v.copy() for k, v in state.state_arrays().items()}
    rng = np.random.default_rng(1)
    for _ in range(20):
        evaluate(pop, state.delta_c + rng.normal(0, 2, 3) * um, law=law, policy="birth", state=state)
    after = state.state_arrays()
    assert before.keys() == after.keys()
    for k, v in before.items():
        np.testing.assert_array_equal(after[k], v, err_msg=k)


@pytest.mark.parametrize("law", LAW_NAMES)
def test_same_bits_on_one_and_two_threads(law):
    pop, state = committed_state(law, "follow", n=20000)
    d = state.delta_c + np.array([0.3, 0.5, -0.2]) * um
    results = []
    old = numba.get_num_threads()
    try:
        for threads in (1, 2):
            numba.set_num_threads(threads)
            ev = evaluate(pop, d, law=law, state=state)
            results.append(np.concatenate([ev.stress, ev.covariance.ravel(), ev.tangent.ravel()]))
    finally:
        numba.set_num_threads(old)
    np.testing.assert_array_equal(results[0], results[1])


@pytest.mark.parametrize("law", LAW_NAMES)
def test_energy_balance_closes(law):
    """History laws: external work = stored energy + dissipation on a cyclic path, dissipation never decreases."""
    if laws.get(law).history is None:
        pytest.skip("a path-independent law keeps no energy account (its domain is checked by asperity_sim.solve.domain)")
    S, D = paths.STRESS, paths.DISPLACEMENT
    path = paths.LoadPath((paths.Stage((S, D, D), (300e6, 0, 0), 6), paths.Stage((S, D, D), (300e6, 3 * um, 0), 6),
                           paths.Stage((S, D, D), (300e6, -3 * um, 1 * um), 8)), name="cycle")
    ds = simulate(R1, path, n=3000, seed=3, law=law, k=8)
    W, E, Dd = ds.external_work.values, ds.elastic_energy.values, ds.dissipation.values
    assert np.abs(W - E - Dd).max() <= 1e-10 * np.abs(W).max()
    assert np.all(np.diff(Dd) >= 0.0) and Dd[-1] > 0.0
