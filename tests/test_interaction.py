"""Elastic interaction between contacts in the mean field (asperity_sim/kernels/interaction.py).

The contacts see Delta_c = Delta + kappa sigma_1 e_1, solved at every evaluation; the response at
Delta has the exact tangent of that fixed point, for both laws, and a run with it is a run of the
same contacts whose mean level (and so the mean gap) is kappa sigma_1 further away.
"""

import math

import numpy as np
import pytest

from asperity_sim import Population, evaluate, paths, presets, simulate
from asperity_sim.kernels import interaction
from asperity_sim.kernels.state import ContactState
from asperity_sim.runs.scene import scene_from_dict

um = 1e-6


def test_kappa_is_twice_the_exclusion_radius_over_the_contact_modulus():
    p = presets.R1.replace(interaction=1.0)
    assert interaction.kappa(p) == pytest.approx(2.0 / (math.sqrt(math.pi * p.N) * p.E_star), rel=1e-15)
    assert interaction.kappa(p.replace(interaction=0.5)) == pytest.approx(0.5 * interaction.kappa(p), rel=1e-15)
    assert interaction.kappa(presets.R1) == 0.0


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_the_contacts_see_the_closure_shifted_by_kappa_sigma_1(law):
    p = presets.R1.replace(interaction=1.0)
    pop = Population.sample(p, 20_000, seed=2)
    d = np.array([14 * um, 2 * um, -1 * um])
    ev = evaluate(pop, d, law=law)
    k = interaction.kappa(p)
    assert ev.delta_contact[0] - d[0] == pytest.approx(k * ev.stress[0], rel=1e-12)
    np.testing.assert_array_equal(ev.delta_contact[1:], d[1:])
    plain = evaluate(Population(params=presets.R1, r=pop.r, R=pop.R, u=pop.u, cos_phi=pop.cos_phi,
                                sin_phi=pop.sin_phi, weight=pop.weight, seed=pop.seed, sampler=pop.sampler),
                     ev.delta_contact, law=law)
    np.testing.assert_array_equal(ev.stress, plain.stress)  # the same contacts at Delta_c
    assert ev.contact_area == plain.contact_area


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_tangent_and_area_gradient_of_the_fixed_point_are_exact(law):
    """First-order Taylor remainders fall with slope 2 in the step: the tangent is the derivative."""
    p = presets.R1.replace(interaction=1.0)
    pop = Population.sample(p, 20_000, seed=4)
    d = np.array([15 * um, 3 * um, 1 * um])
    state = ContactState(pop, law)
    ev = evaluate(pop, d, law=law, state=state)
    direction = np.array([0.6, -0.5, 0.3]) * um
    hs = np.array([1e-3, 5e-4, 2.5e-4])
    rem = []
    for h in hs:
        e = evaluate(pop, d + h * direction, law=law, state=state)
        rem.append(np.linalg.norm(e.stress - ev.stress - h * ev.tangent @ direction))
        area = abs(e.contact_area - ev.contact_area - h * ev.contact_area_grad @ direction)
        assert area < 1e-2 * abs(h * ev.contact_area_grad @ direction)
    slope = np.polyfit(np.log(hs), np.log(rem), 1)[0]
    assert 1.8 < slope < 2.2, slope


def test_interaction_zero_is_the_model_without_it_bit_for_bit():
    path = paths.constant_normal_shear(200e6, 4e-6, increments=6)
    a = simulate(presets.R1, path, n=3000, seed=5)
    b = simulate(presets.R1.replace(interaction=0.0), path, n=3000, seed=5)
    for name in ("stress", "displacement", "tangent", "contact_area_fraction", "mean_gap"):
        np.testing.assert_array_equal(a[name].values, b[name].values)


@pytest.mark.parametrize("law", ["paper", "mdr"])
def test_a_run_at_a_prescribed_pressure_moves_only_the_mean_level(law):
    """sigma_1 prescribed: the contacts carry the same load at the same Delta_c, so the area is the
    same and the mean level (Delta_1, the mean gap) moves by kappa sigma_1."""
    path = paths.LoadPath((paths.Stage(("s", "d", "d"), (150e6, 0.0, 0.0), 5),))
    p = presets.R1.replace(interaction=1.0)
    pop = Population.sample(presets.R1, 4000, seed=6)
    plain = simulate(presets.R1, path, population=pop, law=law)
    pop_i = Population(params=p, r=pop.r, R=pop.R, u=pop.u, cos_phi=pop.cos_phi, sin_phi=pop.sin_phi,
                       weight=pop.weight, seed=pop.seed, sampler=pop.sampler)
    inter = simulate(p, path, population=pop_i, law=law)
    shift = interaction.kappa(p) * 150e6
    assert inter.displacement.values[-1, 0] == pytest.approx(plain.displacement.values[-1, 0] - shift, abs=1e-6 * shift)
    assert inter.mean_gap.values[-1] == pytest.approx(plain.mean_gap.values[-1] + shift, abs=1e-6 * shift)
    assert inter.contact_area_fraction.values[-1] == pytest.approx(plain.contact_area_fraction.values[-1], rel=1e-9)


def test_a_scene_file_turns_it_on_and_too_strong_an_interaction_is_refused():
    scene = scene_from_dict({"parameters": {"preset": "R1", "interaction": 1.0}, "run": {"n": 2000},
                             "path": {"stages": [{"increments": 3, "sigma_1": "100 MPa", "Delta_2": "0 um",
                                                  "Delta_3": "0 um"}]}})
    assert scene.params.interaction == 1.0
    ds = scene.simulate()
    assert ds.attrs["param_interaction"] == 1.0 and ds.attrs["status"] == "complete"
    pop = Population.sample(presets.R1.replace(interaction=1e6), 2000, seed=1)
    with pytest.raises(ValueError, match="kappa T_11 = .* >= 1"):
        evaluate(pop, [20 * um, 0.0, 0.0])
    with pytest.raises(ValueError, match="interaction = -1"):
        presets.R1.replace(interaction=-1.0)


def test_a_run_with_interaction_resumes_from_its_checkpoint_to_the_same_bits(tmp_path):
    p = presets.R1.replace(interaction=1.0)
    path = paths.LoadPath((paths.Stage(("s", "d", "d"), (120e6, 0.0, 0.0), 3),
                           paths.Stage(("s", "d", "d"), (120e6, 2 * um, 0.0), 4),
                           paths.Stage(("s", "d", "d"), (120e6, -1 * um, 0.0), 4)))

    class Stop(Exception):
        pass

    def stop_at_6(stage, n_stages, fraction, step, iterations):
        if step == 6:
            raise Stop

    ck = tmp_path / "run.npz"
    with pytest.raises(Stop):
        simulate(p, path, n=3000, seed=7, law="mdr", k=8, checkpoint=ck, checkpoint_every=1, progress=stop_at_6)
    from asperity_sim import resume

    resumed, full = resume(ck), simulate(p, path, n=3000, seed=7, law="mdr", k=8)
    for name in ("stress", "displacement", "tangent", "contact_area_fraction", "mean_gap", "dissipation"):
        np.testing.assert_array_equal(resumed[name].values, full[name].values, err_msg=name)


def test_a_first_guess_beyond_the_fold_restarts_from_the_left_and_no_root_is_a_named_runaway():
    """g(c) = c - Delta_1 - kappa sigma_1(c) is concave with a fold where kappa T_11 = 1: a first guess beyond
    it (a stale offset) must still find the root on the rising branch (checked by bisection on g), and a
    Delta_1 beyond the top of g has no root: InteractionRunawayError."""
    from asperity_sim.errors import InteractionRunawayError

    pop = Population.sample(presets.R1, 4000, seed=3)

    def plain(c):
        return evaluate(pop, c)

    def g(c1, d1, k):
        return c1 - d1 - k * plain([c1, 0.0, 0.0]).stress[0]

    d1 = 6 * um
    T11 = plain([d1, 0.0, 0.0]).tangent[0, 0]
    k = 0.3 / T11  # kappa T_11 = 0.3 at c = Delta_1: the root lies on the rising branch
    fold = d1
    while 1.0 - k * plain([fold, 0.0, 0.0]).tangent[0, 0] > 0.0:
        fold += 0.5 * um
    lo, hi = d1, fold  # g(lo) <= 0 < g(hi) (checked), bisection to the root
    assert g(lo, d1, k) <= 0.0 < g(hi - 0.5 * um, d1, k)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if g(mid, d1, k) < 0.0 else (lo, mid)
    ev = interaction.solve(plain, np.array([d1, 0.0, 0.0]), k, offset=2.0 * (fold - d1))
    assert ev.at_contacts()[0] == pytest.approx(lo, rel=1e-9)
    assert ev.at_contacts()[0] < fold
    with pytest.raises(InteractionRunawayError, match="kappa T_11"):
        interaction.solve(plain, np.array([fold + 50 * um, 0.0, 0.0]), k)
