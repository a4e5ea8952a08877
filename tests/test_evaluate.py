"""Assembly of Eq. (23) over a population: exact tangent, standard error, statistics (SPEC §6)."""

import math

import numba
import numpy as np
from pathlib import Path
import pytest

from asperity_sim import Population, presets, reference
from asperity_sim.kernels.commit import birth_angles
from asperity_sim.kernels.evaluate import evaluate, evaluate_steps, evaluation_from, snapshot, Workspace
from asperity_sim.kernels.reach import may_touch_follow, may_touch_within

um = 1e-6
R1, S1 = presets.R1, presets.S1


def fd_tangent(pop, delta, h, **kw):
    T = np.empty((3, 3))
    for k in range(3):
        dp, dm = np.array(delta, float), np.array(delta, float)
        dp[k] += h
        dm[k] -= h
        T[:, k] = (evaluate(pop, dp, **kw).stress - evaluate(pop, dm, **kw).stress) / (2 * h)
    return T


def one_asperity(params, r, R, u, phi):
    return Population.from_arrays(params, [r], [R], [u], [phi])


# one asperity in each state: (delta, expected state), for R1 and r = 2 um, R = 40 um
STATES = {
    "stick": ([6 * um, 0.0, 0.0], 1),
    "partial_slip": ([6 * um, 0.8 * um, 0.3 * um], 2),
    "full_slip": ([6 * um, 9 * um, -4 * um], 3),
}


@pytest.mark.parametrize("state", STATES)
@pytest.mark.parametrize("u", [0.0, 0.4, 1.3])
def test_tangent_single_asperity_each_state(state, u):
    pop = one_asperity(R1, 2 * um, 40 * um, u, 0.9)
    delta, code = STATES[state]
    ev = evaluate(pop, delta)
    assert ev.n_contact == 1
    if u == 0.0:  # theta = 0: the local state is exactly the one intended
        assert snapshot(pop, delta)["state"][0] == code
    T_fd = fd_tangent(pop, delta, 1e-7 * um)
    assert np.allclose(ev.tangent, T_fd, rtol=1e-6, atol=1e-6 * np.abs(T_fd).max())


def test_tangent_includes_theta_change_with_closure():
    """Under `follow`, theta = (2/pi) u theta_m(c, R) moves with Delta_1 (SPEC §3, §6)."""
    pop = one_asperity(R1, 1 * um, 30 * um, 1.2, 0.3)
    delta = [10 * um, 2 * um, 1 * um]
    ev = evaluate(pop, delta)
    T_fd = fd_tangent(pop, delta, 1e-7 * um)
    assert np.allclose(ev.tangent, T_fd, rtol=1e-6, atol=1e-7 * np.abs(T_fd).max())
    # birth policy with the angle frozen: the theta term vanishes, and FD at frozen angle agrees
    tb = np.full(1, np.nan)
    birth_angles(pop.r, pop.R, pop.u, pop.cos_phi, pop.sin_phi, 1, np.array(delta), R1.r_o, R1.k_e, tb)
    assert np.isfinite(tb[0])
    ev_b = evaluate(pop, delta, policy="birth", theta_birth=tb)
    assert np.allclose(ev_b.stress, ev.stress, rtol=1e-14)
    T_fd_b = fd_tangent(pop, delta, 1e-7 * um, policy="birth", theta_birth=tb)
    assert np.allclose(ev_b.tangent, T_fd_b, rtol=1e-6, atol=1e-7 * np.abs(T_fd_b).max())
    assert np.abs(ev_b.tangent[:, 0] - ev.tangent[:, 0]).max() > 1e-3 * np.abs(ev.tangent).max()


@pytest.mark.parametrize("delta_um", [(15, 3, 1), (15, 15, 0), (15, 15, 15), (6, 0.5, -0.2), (10, -4, 6)])
def test_tangent_population_against_finite_differences(delta_um):
    pop = Population.sample(R1, 4000, seed=11)
    delta = np.array(delta_um) * um
    ev = evaluate(pop, delta)
    assert ev.n_contact > 0
    T_fd = fd_tangent(pop, delta, 1e-6 * um)
    assert np.allclose(ev.tangent, T_fd, rtol=1e-6, atol=1e-6 * np.abs(T_fd).max())


def test_taylor_remainder_orders():
    """First-order remainder falls like h, second-order like h² (contacts entering and leaving)."""
    pop = Population.sample(R1, 3000, seed=5)
    delta = np.array([12, 5, -2]) * um
    direction = np.array([0.6, -0.5, 0.62]) * um
    ev = evaluate(pop, delta)
    hs = np.array([1e-1, 5e-2, 2.5e-2, 1.25e-2, 6.25e-3])
    r0, r1 = [], []
    for h in hs:
        s = evaluate(pop, delta + h * direction).stress
        r0.append(np.linalg.norm(s - ev.stress))
        r1.append(np.linalg.norm(s - ev.stress - h * ev.tangent @ direction))
    slope0 = np.polyfit(np.log(hs), np.log(r0), 1)[0]
    slope1 = np.polyfit(np.log(hs), np.log(r1), 1)[0]
    assert slope0 == pytest.approx(1.0, abs=0.1)
    assert slope1 == pytest.approx(2.0, abs=0.25)


def test_thread_count_does_not_change_the_answer():
    pop = Population.sample(S1, 50_000, seed=2)
    delta = np.array([6, 2, 1]) * um
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        a = evaluate(pop, delta)
        numba.set_num_threads(before)
        b = evaluate(pop, delta)
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(a.stress, b.stress) and np.array_equal(a.tangent, b.tangent)


@pytest.mark.parametrize("delta_um", [(15, 3, 1), (18, 50, 0), (5, -30, 20), (30, 0, 0), (0, 40, 0)])
def test_skipped_asperities_are_out_of_contact(delta_um):
    """Asperities beyond the height bound are never in contact, steep ones under large shear included."""
    pop = Population.sample(R1.replace(R_sigma=20e-6), 20_000, seed=3)
    delta = np.array(delta_um) * um
    snap = snapshot(pop, delta)
    ev = evaluate(pop, delta)
    assert np.all(snap["delta_n"][ev.n_active:] <= 0.0)
    assert (snap["delta_n"] > 0).sum() == ev.n_contact
    assert (snap["state"] == 3).sum() == ev.n_slip
    assert np.allclose(R1.N * pop.weight * snap["force"].sum(axis=0), ev.stress, rtol=1e-12)


def test_touch_screen_never_drops_a_contact_and_drops_lifted_asperities():
    """may_touch_follow is False only where the exact overlap cos(theta) x + sin(theta) shear <= 0, theta =
    (2u/pi) acos(clip(y)) with libm; near-zero overlaps included.  Below the closure (x > 0), a shear
    that lifts the asperity off is recognised (most such asperities are dropped before any trigonometry)."""
    may_touch = numba.njit(lambda x, s, y, sc, t: may_touch_follow(x, s, y, sc, t))
    rng = np.random.default_rng(7)
    n = 200_000
    y = rng.choice([-0.5, 0.0, 1.0, 1.5], n) * (rng.random(n) < 0.1) + rng.random(n) * (rng.random(n) >= 0.1)
    scale = rng.random(n)
    theta = scale * np.arccos(np.clip(y, 0.0, 1.0))
    shear = rng.normal(0.0, 1.0, n) * 10.0 ** rng.uniform(-3, 1, n)
    # x near the root of the overlap: cos(theta) x + sin(theta) shear = eps
    eps = rng.normal(0.0, 1.0, n) * 10.0 ** rng.uniform(-16, -1, n)
    x = np.where(rng.random(n) < 0.5, (eps - np.sin(theta) * shear) / np.maximum(np.cos(theta), 1e-300),
                 rng.normal(0.0, 1.0, n))
    dn = np.cos(theta) * x + np.sin(theta) * shear
    keep = np.array([may_touch(a, b, c, d, np.inf) for a, b, c, d in zip(x, shear, y, scale)])
    assert not np.any(~keep & (dn > 0.0))
    lifted = (x > 0.0) & (shear < 0.0) & (dn < -1e-3 * x)
    assert lifted.sum() > 1000 and (~keep[lifted]).mean() > 0.5


def test_box_screen_never_drops_a_contact_anywhere_in_its_box():
    """may_touch_within over a box of displacements is False only where the exact overlap (follow angle at
    the closure max(0, r_o + Delta_1), libm) is <= 0 at every displacement of the box: checked at random
    points of random boxes, half of them placed at the root of the overlap.  Boxes that are points give
    may_touch_follow; far from contact most asperities are dropped."""
    may_touch = numba.njit(lambda x, s, ylo, yhi, sc, t: may_touch_within(x, s, ylo, yhi, sc, t))
    rng = np.random.default_rng(11)
    n, r_o, k_e = 100_000, 1.0, 1.3
    R = 10.0 ** rng.uniform(-0.5, 1.0, n)
    scale = rng.random(n)
    phi = rng.uniform(0, 2 * np.pi, n)
    cp, sp = np.cos(phi), np.sin(phi)
    centre = rng.normal(0.0, 1.0, (n, 3)) * np.array([1.0, 2.0, 2.0])
    half = np.abs(rng.normal(0.0, 1.0, (n, 3))) * 10.0 ** rng.uniform(-4, 0, (n, 1))
    half[rng.random(n) < 0.1] = 0.0  # points
    lo, hi = centre - half, centre + half
    d = lo + rng.random((n, 3)) * (hi - lo)
    corner = rng.random(n) < 0.2
    d[corner] = hi[corner]  # the corner of largest Delta_1 and shear (for cos, sin phi > 0)

    def theta(d1):
        return scale * np.arccos(np.clip(1.0 - k_e * np.maximum(0.0, r_o + d1) / R, 0.0, 1.0))

    th = theta(d[:, 0])
    shear = cp * d[:, 1] + sp * d[:, 2]
    eps = rng.normal(0.0, 1.0, n) * 10.0 ** rng.uniform(-15, -1, n)
    x = np.where(rng.random(n) < 0.5, (eps - np.sin(th) * shear) / np.maximum(np.cos(th), 1e-300),
                 rng.normal(0.0, 3.0, n))
    r = d[:, 0] - x
    x = d[:, 0] - r  # as the kernels see it
    dn = np.cos(th) * x + np.sin(th) * shear
    s_hi = np.maximum(cp * lo[:, 1], cp * hi[:, 1]) + np.maximum(sp * lo[:, 2], sp * hi[:, 2])
    y = [1.0 - k_e * np.maximum(0.0, r_o + e) / R for e in (lo[:, 0], hi[:, 0])]
    keep = np.array([may_touch(*a, np.inf) for a in zip(hi[:, 0] - r, s_hi, y[0], y[1], scale)])
    assert np.count_nonzero(dn > 0.0) > 10_000
    assert not np.any(~keep & (dn > 0.0))
    far = x < -1.0  # well above the closure
    assert (~keep[far]).mean() > 0.5
    point = np.all(half == 0.0, axis=1)
    follow = numba.njit(lambda x, s, y, sc, t: may_touch_follow(x, s, y, sc, t))
    same = [follow(a, b, c, e, np.inf) for a, b, c, e in zip((hi[:, 0] - r)[point], s_hi[point], y[1][point],
                                                            scale[point])]
    assert np.array_equal(same, keep[point])


def test_fresh_contact_index_gives_the_bits_of_a_full_search():
    """A history-law trial that tests only the asperities listed for a box (Workspace index) finds the same
    fresh contacts, in the same order, as one that tests every asperity: equal results at every trial of
    a path that loads, shears, turns back and unloads, with the index built more than once and used."""
    from asperity_sim.kernels.state import ContactState

    pop = Population.sample(R1, 20_000, seed=5)
    listed, full = Workspace(pop.n), Workspace(pop.n, index=False)
    a, b = ContactState(pop, "mdr", k=8), ContactState(pop, "mdr", k=8)
    path = [np.array([x, y, 0.3 * y]) * um for x, y in
            [(2, 0), (4, 0), (6, 0), (6, 1), (6.1, 2), (6.2, 3), (6.2, 4), (6.1, 3), (6, 1), (6, -1), (5, -2), (3, -2)]]
    for dc in path:
        for frac in (1.0, 0.97, 1.0):  # a predictor, a correction and the converged trial, as Newton makes them
            d = a.delta_c + frac * (dc - a.delta_c)
            e1, e2 = evaluate(pop, d, law="mdr", state=a, workspace=listed), evaluate(pop, d, law="mdr", state=b,
                                                                                      workspace=full)
            assert np.array_equal(e1.stress, e2.stress) and np.array_equal(e1.tangent, e2.tangent)
            assert e1.n_contact == e2.n_contact
        a.commit(d, workspace=listed)
        b.commit(d, workspace=full)
        assert np.array_equal(a.asp[:a.n_slots], b.asp[:b.n_slots])
    assert listed.trials_by_index[1] >= 2 and listed.trials_by_index[2] >= 10
    assert full.trials_by_index == [3 * len(path), 0, 0]


@pytest.mark.statistical
def test_standard_error_matches_spread_of_replicas():
    """The per-run standard error agrees with the scatter of independent replicas."""
    delta = np.array([15, 3, 1]) * um
    runs = [evaluate(Population.sample(R1, 2000, seed=100 + i), delta) for i in range(60)]
    stress = np.array([e.stress for e in runs])
    se = np.array([e.stderr for e in runs]).mean(axis=0)
    sd = stress.std(axis=0, ddof=1)
    # the sample s.d. of 60 replicas has relative s.e. ~ 1/sqrt(2*59) ~ 0.09: allow 4 of those
    assert np.all(np.abs(sd / se - 1.0) < 4 * math.sqrt(1 / (2 * 59)))


@pytest.mark.statistical
def test_isotropy_sigma2_equals_sigma3():
    pop = Population.sample(R1, 200_000, seed=8)
    a = evaluate(pop, np.array([15, 6, 0]) * um)
    b = evaluate(pop, np.array([15, 0, 6]) * um)
    assert abs(a.stress[1] - b.stress[2]) < 4 * math.hypot(a.stderr[1], b.stderr[2])
    assert abs(a.stress[0] - b.stress[0]) < 4 * math.hypot(a.stderr[0], b.stderr[0])


# a dozen points of the Table 1 sets, anisotropic cases included
REFERENCE_POINTS = [
    ("R1", {}, (5, 0, 0)), ("R1", {}, (15, 0, 0)), ("R1", {}, (15, 3, 1)), ("R1", {}, (15, 15, 0)),
    ("R1", {}, (15, 15, 15)), ("S1", {}, (6, 0, 0)), ("S1", {}, (6, 6, 0)), ("S1", {}, (3, 1, 2)),
    ("R2", {}, (100, 0, 0)), ("S2", {}, (150, 20, -10)),
    ("R1", {"b": 0.8, "c": 0.1, "d": -0.05}, (15, 3, 1)), ("S1", {"b": -0.6, "c": 0.2, "d": 0.2}, (6, 2, -3)),
    ("R1", {"e": 0.3}, (12, 5, 5)),
]


@pytest.mark.statistical
@pytest.mark.parametrize("name,changes,delta_um", REFERENCE_POINTS)
def test_monte_carlo_within_four_standard_errors_of_quadrature(name, changes, delta_um):
    params = presets.TABLE1[name].replace(**changes)
    delta = np.array(delta_um) * um
    pop = Population.sample(params, 100_000, seed=21)
    ev = evaluate(pop, delta)
    ref = reference.stress(params, delta)
    for i in range(3):
        if ev.stderr[i] == 0.0:  # no shear displacement: every shear force is exactly zero... by symmetry only
            assert abs(ref[i]) <= 1e-9 * abs(ref[0])
            continue
        assert abs(ev.stress[i] - ref[i]) < 4 * ev.stderr[i], (i, ev.stress[i], ref[i], ev.stderr[i])


@pytest.mark.statistical
def test_flat_on_rough_against_greenwood_williamson():
    """e = 0: every contact is normal to the plane, sigma_1 is a 1-D GW integral (SPEC §3)."""
    params = R1.replace(e=0.0)
    pop = Population.sample(params, 100_000, seed=4)
    for d1 in (10 * um, 20 * um):
        ev = evaluate(pop, [d1, 0.0, 0.0])
        gw = reference.sigma_1_gw(params, d1)
        assert abs(ev.stress[0] - gw) < 4 * ev.stderr[0]
        assert ev.mean_theta == 0.0



def test_evaluate_rejects_wrong_population_and_workspace():
    from asperity_sim.kernels.evaluate import Workspace

    pop = Population.sample(R1, 5000, seed=1)
    with pytest.raises(ValueError, match="not a Population"):
        evaluate({"r": pop.r}, [1e-6, 0.0, 0.0])
    with pytest.raises(ValueError, match="Workspace"):
        evaluate(pop, [1e-6, 0.0, 0.0], workspace=np.zeros((3, 22)))
    with pytest.raises(ValueError, match="Workspace"):
        evaluate(pop, [1e-6, 0.0, 0.0], workspace=Workspace(10))
    # a workspace of the right size is taken and changes nothing; with no shear, the asperities that may
    # touch are exactly those whose height r lies below Delta_1 (SPEC §3: delta_n = Delta_1 - r)
    d1 = 25e-6  # about the mean height of R1: roughly half of the asperities
    ev = evaluate(pop, [d1, 0.0, 0.0], workspace=Workspace(pop.n))
    assert 0 < ev.n_active == int(np.count_nonzero(pop.r <= d1)) < pop.n
    assert ev.n_contact == ev.n_active  # no shear: every asperity below the closure touches
    plain = evaluate(pop, [d1, 0.0, 0.0])
    assert plain.n_active == ev.n_active and np.array_equal(plain.stress, ev.stress)


@pytest.mark.parametrize("params", [R1, S1], ids=["R1", "S1"])
@pytest.mark.parametrize("delta_um", [(18.0, 0.0, 0.0), (15.0, 3.0, 1.0), (13.0, 50.0, 0.0), (15.0, 15.0, 15.0),
                                      (5.0, -2.0, 7.0), (3.0, 0.0, 40.0), (4.0, 30.0, -20.0)])
def test_vectorised_follow_kernel_matches_scalar_libm_kernel(params, delta_um):
    """Policy follow runs the branch-free, series-trigonometry kernel; policy birth with no frozen
    angle is the same physics through the scalar libm kernel.  They must agree to round-off."""
    pop = Population.sample(params, 20000, seed=7)
    delta = np.array(delta_um) * um
    ev_f = evaluate(pop, delta, policy="follow")
    ev_b = evaluate(pop, delta, policy="birth", theta_birth=np.full(pop.n, np.nan))
    assert ev_f.n_contact == ev_b.n_contact > 0
    assert (ev_f.n_slip, ev_f.n_partial) == (ev_b.n_slip, ev_b.n_partial)
    scale = np.abs(ev_b.stress).max()
    np.testing.assert_allclose(ev_f.stress, ev_b.stress, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(ev_f.covariance, ev_b.covariance, rtol=0, atol=1e-11 * np.abs(ev_b.covariance).max())
    np.testing.assert_allclose(ev_f.tangent, ev_b.tangent, rtol=0, atol=1e-12 * np.abs(ev_b.tangent).max())
    assert ev_f.mean_theta == pytest.approx(ev_b.mean_theta, rel=1e-13)



BITS = """
import numba, numpy as np
from asperity_sim import Population, presets
from asperity_sim.kernels.evaluate import evaluate
pop = Population.sample(presets.R1, 100000, seed=5)
out = []
for th in (1, 2):
    numba.set_num_threads(th)
    for d in ((18.0, 0.0, 0.0), (15.0, 3.0, 1.0), (13.0, 50.0, 0.0)):
        ev = evaluate(pop, np.array(d) * 1e-6)
        out += [v.hex() for v in np.concatenate([ev.stress, ev.covariance.ravel(), ev.tangent.ravel()])]
print(" ".join(out))
"""


BITS_MDR = """
import numba, numpy as np
from asperity_sim import presets, simulate
from asperity_sim.paths import LoadPath, Stage
S, D = "stress", "displacement"
path = LoadPath((Stage((S, D, D), (100e6, 0, 0), 3), Stage((S, D, D), (100e6, 3e-6, 1e-6), 4),
                 Stage((S, D, D), (100e6, -1e-6, 0), 3)))
out = []
for th in (1, 2):
    numba.set_num_threads(th)
    ds = simulate(presets.R1, path, n=20000, seed=3, law="mdr", k=8)
    out += [v.hex() for v in np.concatenate([ds.stress.values.ravel(), ds.displacement.values.ravel(),
                                             ds.dissipation.values.ravel()])]
print(" ".join(out))
"""


@pytest.mark.slow
@pytest.mark.parametrize("script", [BITS, BITS_MDR], ids=["paper", "mdr"])
def test_kernel_bits_equal_in_this_process_and_one_that_loads_the_cache(script):
    """The same bits here and in a fresh process that loads the kernels from the numba cache, on 1
    and 2 threads (a kernel whose sums LLVM may reassociate differently when compiled and when loaded
    fails this); for the ``mdr`` law, whose spring loops LLVM may reassociate, along a path with history.

    On a cold cache (CI's fresh checkout) this process compiled the kernels; with a warm one both
    loaded them, and the test checks the threads only.  (A second process that compiles into its own
    cache would cost about 100 s for the ``mdr`` kernels; the fresh checkout gives that case for free.)
    """
    import contextlib
    import io
    import subprocess
    import sys

    import numba

    here = io.StringIO()
    threads = numba.get_num_threads()
    try:
        with contextlib.redirect_stdout(here):
            exec(script, {"__name__": "__bits__"})
    finally:
        numba.set_num_threads(threads)
    package = Path(__file__).resolve().parent.parent / "asperity_sim"
    assert any(package.rglob("*.nbi"))  # the kernels are cached for the other process to load
    there = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    first = here.getvalue().split()
    assert here.getvalue() == there
    assert first[:len(first) // 2] == first[len(first) // 2:]  # 1 and 2 threads


def test_evaluate_steps_gives_the_bits_of_evaluate_at_each_row():
    """One kernel call over many displacements (no contact, closure only, shear in every state)."""
    pop = Population.sample(R1, 3000, seed=2, sampler="sobol")
    rng = np.random.default_rng(1)
    deltas = np.concatenate([[[0.0, 0.0, 0.0], [-5 * um, 1 * um, 0.0], [12 * um, 0.0, 0.0]],
                             rng.uniform([0.0, -20 * um, -20 * um], [25 * um, 20 * um, 20 * um], (30, 3))])
    steps = evaluate_steps(pop, deltas, Workspace(pop.n))
    assert steps.stress.shape == (len(deltas), 3) and steps.tangent.shape == (len(deltas), 3, 3)
    for i, d in enumerate(deltas):
        got, expected = steps.evaluation(i), evaluate(pop, d)
        for name in ("stress", "stderr", "covariance", "tangent"):
            np.testing.assert_array_equal(getattr(got, name), getattr(expected, name), err_msg=name)
        for name in ("n_contact", "n_slip", "n_partial", "mean_theta", "n_active"):
            assert getattr(got, name) == getattr(expected, name), name
        np.testing.assert_array_equal(steps.stress[i], expected.stress)
        assert steps.n_contact[i] == expected.n_contact and steps.finite[i]
    assert steps.evaluation(0).n_contact == 0 < steps.evaluation(2).n_contact


# ---- the contact area fraction (per-step output of every run) ----

def _area_closed_form(p, d1):
    """Contacts normal to the plane (e = 0): N pi E[R] E[(d1 - r)+], gamma heights (SPEC §2), truncated
    Gaussian radii; E[(d1 - r)+] = d1 P(alpha+1, d1/beta) - (alpha+1) beta P(alpha+2, d1/beta)."""
    from scipy import special, stats

    lo, hi = p.R_bounds
    a, b = (lo - p.R_m) / p.R_sigma, (hi - p.R_m) / p.R_sigma
    mean_R = stats.truncnorm(a, b, loc=p.R_m, scale=p.R_sigma).mean()
    x = d1 / p.beta
    depth = d1 * special.gammainc(p.alpha + 1.0, x) - (p.alpha + 1.0) * p.beta * special.gammainc(p.alpha + 2.0, x)
    return p.N * math.pi * mean_R * depth


@pytest.mark.statistical
@pytest.mark.parametrize("shear", [0.0, 4 * um])
def test_contact_area_matches_the_closed_form_of_normal_contacts(shear):
    """e = 0: every contact normal to the plane, delta_n = Delta_1 - r whatever the shear; the Monte Carlo
    area fraction within 4 standard errors of N pi E[R] E[(Delta_1 - r)+]."""
    p = presets.R1.replace(e=0.0)
    pop = Population.sample(p, 200_000, seed=11)
    for d1 in (10 * um, 20 * um, 30 * um):
        ev = evaluate(pop, [d1, shear, 0.5 * shear])
        expected = _area_closed_form(p, d1)
        se = math.sqrt(ev.contact_area_var)
        assert 0.0 < se < 0.1 * expected
        assert abs(ev.contact_area - expected) < 4.0 * se, (d1, ev.contact_area, expected, se)


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_contact_area_gradient_is_the_derivative(law):
    """The area's gradient d a / d Delta against central differences (orientations follow the closure).

    The area has a kink wherever a contact starts (its slope jumps by pi R cos(theta) N w), so the
    step is small enough that no contact starts within it here."""
    pop = Population.sample(R1, 20_000, seed=3)
    d = np.array([15 * um, 3 * um, -2 * um])
    ev = evaluate(pop, d, law=law)
    for k in range(3):
        h = np.zeros(3)
        h[k] = 1e-12
        fd = (evaluate(pop, d + h, law=law).contact_area - evaluate(pop, d - h, law=law).contact_area) / 2e-12
        assert fd == pytest.approx(ev.contact_area_grad[k], rel=1e-5, abs=1e-6 * abs(ev.contact_area_grad[0]))
    assert ev.contact_area_grad[0] > 0.0  # closing the gap adds area


def test_contact_area_covariance_with_the_stress_is_that_of_the_samples():
    """The covariance of the area and stress estimates equals the sample covariance of the per-asperity
    area and force (snapshot), scaled as the stress: an independent computation."""
    pop = Population.sample(R1, 5000, seed=8)
    d = np.array([14 * um, 2 * um, 1 * um])
    ev = evaluate(pop, d)
    snap = snapshot(pop, d)
    p = pop.params
    theta, dn = snap["theta"], snap["delta_n"]
    a = np.where(dn > 0.0, math.pi * pop.R * dn * np.cos(theta), 0.0)
    scale = p.N * pop.weight
    assert ev.contact_area == pytest.approx(scale * a.sum(), rel=1e-12)
    var = np.var(a, ddof=1) * scale * scale * pop.n
    assert ev.contact_area_var == pytest.approx(var, rel=1e-9)
    for i in range(3):
        cov = np.cov(a, snap["force"][:, i], ddof=1)[0, 1] * scale * scale * pop.n
        assert ev.contact_area_cov[i] == pytest.approx(cov, rel=1e-9, abs=1e-12 * abs(cov) + 1e-30)
