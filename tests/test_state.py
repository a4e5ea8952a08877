"""Committed per-contact state (law `mdr`): trial vs committed, exact tangent, energy, slots, population checks."""

import math

import numpy as np
import pytest

from asperity_sim import paths, Population, presets, reference, simulate
from asperity_sim.kernels.evaluate import evaluate, Workspace
from asperity_sim.kernels import state as state_module
from asperity_sim.kernels.state import ContactState

um = 1e-6
R1, S1 = presets.R1, presets.S1


def loaded_history(params=R1, n=3000, seed=1, k=16, policy="follow"):
    """A state built by committing a short mixed path (normal, shear, turn, partial unloading)."""
    pop = Population.sample(params, n, seed=seed)
    hist = ContactState(pop, "mdr", policy, k=k)
    steps = ([np.array([x, 0, 0]) for x in np.linspace(0, 15, 6)[1:] * um]
             + [np.array([15, y, 0.4 * y]) * um for y in np.linspace(0, 5, 6)[1:]]
             + [np.array([14, 5 - z, 2 + z]) * um for z in np.linspace(0, 3, 4)[1:]])
    for d in steps:
        ev = evaluate(pop, d, law="mdr", policy=policy, state=hist)
        hist.commit(d, ev.n_active)
    return pop, hist


def fd_tangent(pop, d, h=1e-7 * um, **kw):
    """Central finite differences of the stress at displacement d [m], trial evaluations only."""
    T = np.empty((3, 3))
    for k in range(3):
        dp, dm = d.copy(), d.copy()
        dp[k] += h
        dm[k] -= h
        T[:, k] = (evaluate(pop, dp, **kw).stress - evaluate(pop, dm, **kw).stress) / (2 * h)
    return T


def test_trial_evaluation_never_changes_committed_history():
    pop, hist = loaded_history()
    before = {name: a.copy() for name, a in hist.state_arrays().items()}
    rng = np.random.default_rng(0)
    for _ in range(50):
        d = hist.delta_c + rng.normal(0, 2, 3) * um
        evaluate(pop, d, law="mdr", state=hist)
    after = hist.state_arrays()
    assert before.keys() == after.keys()
    for name, a in before.items():
        assert np.array_equal(after[name], a), name


def test_commit_after_a_trial_there_finds_the_same_fresh_contacts_as_a_full_search():
    """A commit given the workspace of a trial at its displacement searches only where that trial found
    fresh contacts: the committed state is the same as after a search of every asperity; a trial
    elsewhere, or on another committed state, is not used."""
    pop, full = loaded_history(n=20000)
    guided = ContactState(pop, "mdr", k=16)
    guided.restore(full.state_arrays())
    ws = Workspace(pop.n)
    rng = np.random.default_rng(3)
    born = 0
    for _ in range(12):
        d = full.delta_c + rng.normal([0.4, 0.3, 0.2], 0.3) * um
        evaluate(pop, d + 1e-3 * um, law="mdr", state=guided, workspace=ws)  # not where the commit goes
        assert ws.fresh_contacts(d, guided) is None
        evaluate(pop, d, law="mdr", state=guided, workspace=ws)
        assert ws.fresh_contacts(d, guided) is not None
        before = full.n_contacts
        a, b = full.commit(d), guided.commit(d, workspace=ws)
        born += full.n_contacts - before
        assert ws.fresh_contacts(d, guided) is None  # committed since
        assert (a.work, a.stored, a.dissipation) == (b.work, b.stored, b.dissipation)
        assert np.array_equal(a.transitions, b.transitions)
        for name, x in full.state_arrays().items():
            assert np.array_equal(guided.state_arrays()[name], x), name
    assert born > 0  # contacts were born along the way


@pytest.mark.parametrize("index", [False, True])
def test_a_trial_lists_the_fresh_contacts_a_search_finds(index):
    """The fresh contacts a trial lists for its commit (with or without the workspace's index, from a new box
    and from a box it made before) are those :func:`find_fresh` finds at the same displacement, in order."""
    from asperity_sim.kernels.commit import find_fresh
    from asperity_sim.kernels.layout import CHUNK, OFFSET
    from asperity_sim.threads import chunks_of

    pop, hist = loaded_history(n=20000)
    p = pop.params
    ws = Workspace(pop.n, index=index)
    rng = np.random.default_rng(5)
    found = 0
    for _ in range(6):
        d = hist.delta_c + rng.normal([0.4, 0.3, 0.2], 0.3) * um
        for dd in (d + 0.1 * um, d):  # the second trial in the box the first one made (with the index)
            evaluate(pop, dd, law="mdr", state=hist, workspace=ws)
        fresh, n_fresh = ws.fresh_contacts(d, hist)
        n_active, tan_max = state_module.bounds(pop.r, pop.R_min, p.r_o, p.k_e, p.beta, d, np.empty(0))
        m = chunks_of(n_active, CHUNK)
        want, n_want = np.zeros((m, CHUNK), OFFSET), np.zeros(m, np.int64)
        find_fresh(hist.flag, n_active, *pop.arrays, d, p.r_o, p.k_e, tan_max, want, n_want, 0, m)
        assert np.array_equal(n_fresh[:m], n_want)
        for ic in range(m):
            k = min(n_want[ic], fresh.shape[1])  # a row holds the first FRESH_ROW (the count says if there were more)
            got = fresh[ic, :k]
            assert np.array_equal(got, want[ic, :k]) and np.all(np.diff(got) > 0), ic
        found += int(n_want.sum())
        hist.commit(d, workspace=ws)
    assert found > 0  # contacts were born
    assert ws.trials_by_index[2 if index else 0] > 0


def test_a_list_too_short_for_its_chunk_makes_the_commit_search():
    """Where a trial found more contacts born in a chunk than its row of the list holds, the commit searches
    for them: the same committed state as a commit that searches every asperity, bit for bit."""
    from asperity_sim.kernels.layout import OFFSET

    pop, full = loaded_history(n=20000)
    short = ContactState(pop, "mdr", k=16)
    short.restore(full.state_arrays())
    ws = Workspace(pop.n)
    ws.fresh = np.zeros((ws.fresh.shape[0], 2), dtype=OFFSET)  # rows of 2
    rng = np.random.default_rng(7)
    overflowed = 0
    for _ in range(6):
        d = full.delta_c + rng.normal([0.4, 0.3, 0.2], 0.3) * um
        evaluate(pop, d, law="mdr", state=short, workspace=ws)
        overflowed += int((ws.n_fresh > 2).sum())
        a, b = full.commit(d), short.commit(d, workspace=ws)
        assert (a.work, a.stored, a.dissipation) == (b.work, b.stored, b.dissipation)
        for name, x in full.state_arrays().items():
            assert np.array_equal(short.state_arrays()[name], x), name
    assert overflowed > 0


@pytest.mark.parametrize("trial_um", [(14.3, 3.5, 2.5), (13, 5, 3.1), (15, 6, 3), (12, 1, 6)])
def test_mdr_tangent_against_finite_differences(trial_um):
    pop, hist = loaded_history()
    d = np.array(trial_um) * um
    ev = evaluate(pop, d, law="mdr", state=hist)
    assert ev.n_contact > 0
    T_fd = fd_tangent(pop, d, law="mdr", state=hist)
    assert np.allclose(ev.tangent, T_fd, rtol=1e-6, atol=1e-6 * np.abs(T_fd).max())


def test_mdr_taylor_remainder_orders():
    pop, hist = loaded_history()
    d = hist.delta_c + np.array([0.3, -0.4, 0.5]) * um
    direction = np.array([0.5, -0.6, 0.4]) * um
    ev = evaluate(pop, d, law="mdr", state=hist)
    hs = np.array([0.1, 0.05, 0.025, 0.0125, 0.00625])
    r0, r1 = [], []
    for h in hs:
        s = evaluate(pop, d + h * direction, law="mdr", state=hist).stress
        r0.append(np.linalg.norm(s - ev.stress))
        r1.append(np.linalg.norm(s - ev.stress - h * ev.tangent @ direction))
    assert np.polyfit(np.log(hs), np.log(r0), 1)[0] == pytest.approx(1.0, abs=0.1)
    assert np.polyfit(np.log(hs), np.log(r1), 1)[0] == pytest.approx(2.0, abs=0.3)


def cyclic_path(sigma_n, amp, cycles=2, inc=8):
    S, D = paths.STRESS, paths.DISPLACEMENT
    stages = [paths.Stage((S, D, D), (sigma_n, 0, 0), inc, name="normal")]
    for _ in range(cycles):
        stages += [paths.Stage((S, D, D), (sigma_n, amp, 0), inc), paths.Stage((S, D, D), (sigma_n, -amp, 0), 2 * inc),
                   paths.Stage((S, D, D), (sigma_n, 0, 0), inc)]
    return paths.LoadPath(tuple(stages), name="cyclic")


def random_path(seed, stages=8):
    rng = np.random.default_rng(seed)
    D = paths.DISPLACEMENT
    out = [paths.Stage((D, D, D), (12 * um, 0, 0), 6)]
    for _ in range(stages):
        target = (rng.uniform(6, 16) * um, rng.uniform(-4, 4) * um, rng.uniform(-4, 4) * um)
        out.append(paths.Stage((D, D, D), target, 5))
    return paths.LoadPath(tuple(out), name="random")


@pytest.mark.slow
@pytest.mark.parametrize("path", [cyclic_path(300e6, 3 * um), random_path(1), random_path(2)], ids=["cyclic", "random1", "random2"])
def test_energy_balance_closes_and_dissipation_never_decreases(path):
    ds = simulate(R1, path, n=5000, seed=3, law="mdr", k=16)
    W, E, D = ds.external_work.values, ds.elastic_energy.values, ds.dissipation.values
    assert np.abs(W - E - D).max() <= 1e-10 * np.abs(W).max()
    assert np.all(np.diff(D) >= 0.0)
    assert D[-1] > 0.0
    counts = ds.n_contact.values
    assert np.all(ds.n_slip.values + ds.n_partial.values <= counts)
    # transitions: every contact counted once, consistent with the recorded counts
    tr = ds.transitions.values
    assert np.array_equal(tr[1:, 1:, :].sum(axis=(1, 2)), counts[:-1])  # from: contacts before
    assert np.array_equal(tr[1:, :, 1:].sum(axis=(1, 2)), counts[1:])  # to: contacts after
    assert np.array_equal(tr[1:, :, 3].sum(axis=1), ds.n_slip.values[1:])
    assert np.array_equal(tr[1:, :, 2].sum(axis=1), ds.n_partial.values[1:])


def test_slots_grow_the_same_where_reserving_them_is_refused(monkeypatch):
    """The slot arrays are reserved for as many slots as asperities; where that memory cannot be had, 1024
    slots grow as contacts come, and the committed state is the same, bit for bit."""
    pop, reserved = loaded_history(n=20000)
    assert reserved.asp.size == pop.n

    def refuse(shape, dtype=np.float64):
        raise MemoryError("refused (test)")

    monkeypatch.setattr(state_module, "reserve", refuse)
    _, grown = loaded_history(n=20000)
    assert 1024 < grown.n_slots <= grown.asp.size < pop.n
    a, b = reserved.state_arrays(), grown.state_arrays()
    assert a.keys() == b.keys()
    for name in a:
        assert np.array_equal(a[name], b[name]), name


@pytest.mark.parametrize("policy", ["follow", "birth"])
def test_a_commit_by_blocks_has_the_bits_of_a_commit_by_chunks(monkeypatch, policy):
    """Where a few chunks of slots would spread unevenly over the threads, the threads claim blocks of slots and
    the thread that ends a chunk sums its contacts in slot order: the committed state and every sum of every
    commit are those of the commit chunk by chunk, bit for bit (with contacts lost, so slots freed, on the way)."""
    def refuse(shape, dtype=np.float64):
        raise MemoryError("refused (test)")

    runs = {}
    for blocks in (True, False, "refused"):  # "refused": by blocks where reserving memory is refused
        if blocks == "refused":
            monkeypatch.setattr(state_module, "reserve", refuse)
        monkeypatch.setattr(state_module, "by_blocks", lambda n, blocks=blocks: bool(blocks))
        pop = Population.sample(R1, 30000, seed=5)
        hist = ContactState(pop, "mdr", policy, k=8)
        sums = []
        for d in ([np.array([x, 0, 0]) * um for x in (6.0, 12.0, 16.0)]
                  + [np.array([16.0, y, -0.5 * y]) * um for y in (2.0, 4.0)] + [np.array([13.0, 3.0, -2.0]) * um]):
            ws = Workspace(pop.n)
            evaluate(pop, d, law="mdr", policy=policy, state=hist, workspace=ws)
            r = hist.commit(d, workspace=ws)
            sums.append([r.work, r.stored, r.dissipation, r.events, *r.transitions.ravel()])
        assert (hist._by_slot_cols is not None) == bool(blocks) and hist.n_slots > 2 * 2048  # several chunks
        runs[blocks] = hist.state_arrays(), np.array(sums)
    b, sb = runs[False]
    assert sb[-1, 4 + 4 * 1 + 0] > 0  # some contacts in stick were lost in the last commit
    for blocks in (True, "refused"):
        a, sa = runs[blocks]
        assert np.array_equal(sa, sb), blocks
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k], equal_nan=True) for k in a), blocks


def test_reserved_slots_hold_a_turnover_of_nearly_every_asperity():
    """Contacts lost and born in one increment reuse the freed slots first, so the reserved slots (one per
    asperity) never need to grow, even when the slots in use plus the contacts born exceed the asperities (a
    commit once tried to grow the reserved arrays there, which cannot be done, and stopped the run)."""
    c = R1.R_m / R1.k_e - R1.r_o  # theta_m(c, R_m) = pi/2: nearly every asperity in contact, turning over in shear
    pop = Population.sample(R1, 2000, seed=1)
    state = ContactState(pop, "mdr", "follow", k=16)
    steps = ([np.array([c * f, 0.0, 0.0]) for f in (0.5, 1.0)] + [np.array([c, c * f / 6, 0.0]) for f in (1, 2, 3)]
             + [np.array([c, c * (0.5 - f / 6), 0.0]) for f in range(1, 7)])
    turned = False
    for d in steps:
        ev = evaluate(pop, d, law="mdr", state=state)
        slots, before = state.n_slots, state.flag != 0
        state.commit(d, ev.n_active)
        born = int(np.count_nonzero((state.flag != 0) & ~before))
        turned |= slots + born > pop.n
        assert state.asp.size == pop.n and state.n_contacts <= state.n_slots <= pop.n
    assert turned  # the turnover that needs the freed slots happened
    D = paths.DISPLACEMENT
    path = paths.LoadPath((paths.Stage((D, D, D), (c, 0.0, 0.0), 2, name="close"),
                           paths.Stage((D, D, D), (c, 0.5 * c, 0.0), 3, name="+A"),
                           paths.Stage((D, D, D), (c, -0.5 * c, 0.0), 6, name="-A")), name="turnover")
    ds = simulate(R1, path, population=pop, law="mdr", k=16)
    assert ds.sizes["step"] == 12 and 0 < ds.n_contact.values.max() <= pop.n


def test_contact_loss_erases_memory():
    pop, hist = loaded_history()
    d = np.array([-1.0, 0.0, 0.0]) * um  # opening: every contact lost
    ev = evaluate(pop, d, law="mdr", state=hist)
    assert ev.n_contact == 0
    c = hist.commit(d, ev.n_active)
    assert c.stored == 0.0
    assert hist.n_contacts == 0 and not hist.flag.any()
    assert np.all(hist.arrays[0] == 0.0)  # every spring erased
    # reloading: identical to a virgin interface loaded the same way
    d2 = np.array([10, 1, 0]) * um
    a = evaluate(pop, d2, law="mdr", state=hist)
    virgin = ContactState(pop, "mdr", options=hist.options)
    virgin.delta_c = d.copy()
    b = evaluate(pop, d2, law="mdr", state=virgin)
    assert np.array_equal(a.stress, b.stress)


@pytest.mark.statistical
def test_flat_on_rough_shear_follows_ciavarella_jaeger_and_masing():
    """e = 0: sigma_2 = mu [sigma_1(D) - sigma_1(D - Delta_2/(lam mu))] on loading, Masing 2 mu [...] on unloading."""
    params = R1.replace(e=0.0)
    D1, top = 20 * um, 4 * um
    lm = params.lam * params.mu
    D = paths.DISPLACEMENT
    path = paths.LoadPath((paths.Stage((D, D, D), (D1, 0, 0), 10), paths.Stage((D, D, D), (D1, top, 0), 20),
                           paths.Stage((D, D, D), (D1, -top, 0), 40)), name="flat")
    pop = Population.sample(params, 100_000, seed=9)
    ds = simulate(params, path, population=pop, law="mdr", k=32)
    d2 = ds.displacement.sel(axis=2).values
    s2, se2 = ds.stress.sel(axis=2).values, ds.stress_stderr.sel(axis=2).values
    load = slice(11, 31)
    unload = slice(31, None)

    def sigma1_pop(x):  # the same population's Hertz closure (the identity holds asperity by asperity)
        return evaluate(pop, [x, 0.0, 0.0]).stress[0]

    def sigma1_ref(x):
        return reference.sigma_1_gw(params, x) if x > 0 else 0.0

    for sigma1, tol in ((sigma1_pop, None), (sigma1_ref, "stat")):
        s_top = params.mu * (sigma1(D1) - sigma1(D1 - top / lm))
        exp_load = np.array([params.mu * (sigma1(D1) - sigma1(D1 - x / lm)) for x in d2[load]])
        exp_unload = np.array([s_top - 2 * params.mu * (sigma1(D1) - sigma1(D1 - (top - x) / (2 * lm)))
                               for x in d2[unload]])
        got = np.r_[s2[load], s2[unload]]
        exp = np.r_[exp_load, exp_unload]
        if tol is None:  # spring discretisation only (k = 32)
            assert np.abs(got - exp).max() < 1e-3 * params.mu * sigma1(D1)
        else:
            se = np.r_[se2[load], se2[unload]]
            assert np.all(np.abs(got - exp) < 4 * se + 1e-3 * params.mu * sigma1(D1))


@pytest.mark.slow
def test_mdr_with_birth_policy_closes_energy_and_differs_from_follow():
    """Policy `birth` freezes each contact's frame at its birth (SPEC §3): the springs then do not turn."""
    path = random_path(3)
    pop = Population.sample(R1, 4000, seed=5)
    a = simulate(R1, path, population=pop, law="mdr", policy="birth")
    b = simulate(R1, path, population=pop, law="mdr", policy="follow")
    W, E, D = a.external_work.values, a.elastic_energy.values, a.dissipation.values
    assert np.abs(W - E - D).max() <= 1e-10 * np.abs(W).max()
    assert np.all(np.diff(D) >= 0.0)
    assert np.abs(a.stress.values - b.stress.values).max() > 1e-3 * np.abs(b.stress.values).max()


def test_mdr_birth_tangent_against_finite_differences():
    pop = Population.sample(R1, 3000, seed=1)
    hist = ContactState(pop, "mdr", "birth", k=16)
    for d in [np.array([x, 0.3 * x, 0]) for x in np.linspace(0, 15, 6)[1:] * um]:
        ev = evaluate(pop, d, law="mdr", policy="birth", state=hist)
        hist.commit(d, ev.n_active)
    assert np.isfinite(hist.theta_birth).sum() == hist.n_contacts > 0
    d = np.array([16, 5, 1]) * um
    ev = evaluate(pop, d, law="mdr", policy="birth", state=hist)
    T_fd = fd_tangent(pop, d, law="mdr", policy="birth", state=hist)
    assert np.allclose(ev.tangent, T_fd, rtol=1e-6, atol=1e-6 * np.abs(T_fd).max())


@pytest.mark.parametrize("changes, d1", [
    (dict(alpha=-0.95, beta=1e-3), 0.2 * um),   # heights piled at the top, closure far below beta
    (dict(alpha=20.0, beta=0.1 * um), 3.0 * um),  # narrow heights, closure far above beta
], ids=["closure_below_beta", "closure_above_beta"])
def test_springs_fit_the_contacts_whatever_beta(changes, d1):
    """e = 0 (contacts normal to the plane), Delta_1 held, monotonic Delta_2: every contact is
    Cattaneo-Mindlin at constant normal force, so mdr equals the paper law up to its spring
    discretisation, 0.35/m² of mu f_n per contact with m >= k springs in contact."""
    k = 16
    params = R1.replace(e=0.0, **changes)
    D = paths.DISPLACEMENT
    path = paths.LoadPath((paths.Stage((D, D, D), (d1, 0, 0), 5),
                           paths.Stage((D, D, D), (d1, 2.0 * params.lam * params.mu * d1, 0), 20)), name="cm")
    pop = Population.sample(params, 4000, seed=2)
    a = simulate(params, path, population=pop, law="mdr", k=k)
    b = simulate(params, path, population=pop, law="paper")
    assert a.n_contact.values[-1] > 100
    s1 = b.stress.values[-1, 0]
    err = np.abs(a.stress.values[:, 1] - b.stress.values[:, 1]).max() / (params.mu * s1)
    assert err < 0.35 / k**2
    np.testing.assert_allclose(a.stress.values[:, 0], b.stress.values[:, 0], rtol=1e-12)  # Hertz in both


def test_every_contact_has_at_least_k_springs_at_its_largest_extent():
    """A contact is born with k springs across its radius and coarsened by pairs beyond 2k."""
    k = 8
    pop = Population.sample(R1, 3000, seed=6)
    state = ContactState(pop, "mdr", k=k)
    for x in np.linspace(0, 15, 16)[1:] * um:  # monotonic closure: every contact at its largest extent
        d = np.array([x, 0.0, 0.0])
        evaluate(pop, d, law="mdr", state=state)
        state.commit(d)
    live = np.flatnonzero(state.asp[:state.n_slots] >= 0)
    R, h, dn = pop.R[state.asp[live]], state.arrays[1][live], state.dn_c[live]
    in_contact = np.ceil(np.sqrt(R * dn) / h - 0.5)
    assert live.size > 100
    assert in_contact.min() >= k and in_contact.max() <= 2 * k


def test_a_commit_leaves_no_vector_beyond_the_springs_in_contact_but_one():
    """The commit of a contact whose springs fit releases only springs up to those in contact at the
    committed overlap plus one: every other commit zeroes the springs beyond those in contact, and a
    coarsening may leave one merged spring across the edge. Checked after growth (coarsenings), shear,
    a turn and unloading."""
    k = 4
    pop = Population.sample(R1, 3000, seed=6)
    state = ContactState(pop, "mdr", k=k)
    steps = ([np.array([x, 0.0, 0.0]) for x in np.linspace(0, 15, 11)[1:] * um]
             + [np.array([15.0, y, 0.3 * y]) * um for y in np.linspace(0, 4, 6)[1:]]
             + [np.array([15.0 - z, 4.0 - z, 1.2 + z]) * um for z in np.linspace(0, 3, 7)[1:]])
    coarsened = 0
    for d in steps:
        evaluate(pop, d, law="mdr", state=state)
        coarsened += state.commit(d).events
        live = np.flatnonzero(state.asp[:state.n_slots] >= 0)
        w, h = state.arrays[0][live], state.arrays[1][live]
        c = h * h / pop.R[state.asp[live]]
        i = np.arange(w.shape[2]) + 0.5
        in_contact = (state.dn_c[live, None] - c[:, None] * i**2 > 0.0).sum(axis=1)
        beyond = np.arange(w.shape[2])[None, :] > in_contact[:, None]  # i >= in_contact + 1
        assert not np.any(w[:, 0][beyond]) and not np.any(w[:, 1][beyond])
    assert coarsened > 0 and live.size > 100
