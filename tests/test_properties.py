"""Property-based checks of every public entry point (issue 6, items 1 and 3), with hypothesis.

* Valid configurations -- parameters anywhere in their SPEC §1 ranges (log-uniform over
  N 1..1e12 m-2, G 1e6..1e13 Pa, beta 1e-9..1e-3 m, R_m 1e-7..1e-2 m; alpha from -1 + 1e-9
  to 1e3; R_sigma from 0 to 1.5 R_m; e, mu, nu, r_o and the orientation density up to the
  edges of their ranges), a small random load path (1-3 stages, each component displacement
  or stress controlled, targets around the interface's own scales, including zero, negative
  and unreachable ones), n from 1 to 40, both laws, both policies -- must either complete or
  stop with a named :class:`SimulationError` that says why; in both cases every number
  written (data variables and numeric attributes) is finite.
* Invalid configurations -- one bad value at a time, at every entry point (InterfaceParams,
  Stage, LoadPath, the paper's path constructors, simulate, resume, Population.sample,
  evaluate, single_contact) -- must raise ``ValueError`` naming the offending argument,
  before any work (sampling and evaluation are patched to fail if reached).

Examples are derandomised (the same ones on every run, no example database), so CI is
reproducible; ``HYPOTHESIS_SEED`` style exploration can be done by editing ``SETTINGS``.
"""

import math
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import asperity_sim as asim
import asperity_sim.solve.driver as driver
import asperity_sim.solve.run as run_module
from asperity_sim import InterfaceParams, paths, Population, presets, simulate, SolverSettings
from asperity_sim.kernels.evaluate import evaluate
from asperity_sim.paths import LoadPath, Stage

N_VALID = 300
N_INVALID = 700  # 1000 configurations in all
SETTINGS = dict(derandomize=True, database=None, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
FAST = SolverSettings(max_cutbacks=4)  # valid settings; a failing run stops sooner


def log_uniform(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda x: 10.0 ** x)


def edge_or(strategy, *edges):
    """Mostly ``strategy``, sometimes exactly an edge of the range."""
    return st.one_of(st.sampled_from(edges), strategy, strategy, strategy)


@st.composite
def valid_params(draw):
    R_m = draw(log_uniform(1e-7, 1e-2))
    alpha = draw(edge_or(st.floats(-0.999, 30.0), -1.0 + 1e-9, -0.999, 0.0, 1e3))
    b = draw(edge_or(st.floats(-1.0, 2.0), -1.0, 0.0, 2.0))
    rho_max = max(0.0, (1.0 - b / 2.0) / 3.0)
    rho = rho_max * draw(edge_or(st.floats(0.0, 1.0), 0.0, 1.0))
    angle = draw(st.floats(0.0, 2.0 * math.pi))
    return InterfaceParams(
        N=draw(log_uniform(1.0, 1e12)), alpha=alpha, beta=draw(log_uniform(1e-9, 1e-3)), R_m=R_m,
        R_sigma=R_m * draw(edge_or(st.floats(0.0, 1.5), 0.0, 1.0 / 3.0, 1.5)),
        mu=draw(edge_or(st.floats(0.0, 10.0), 0.0, 10.0)), G=draw(log_uniform(1e6, 1e13)),
        nu=draw(edge_or(st.floats(-0.999, 0.5), -0.999, 0.0, 0.5)), e=draw(edge_or(st.floats(0.0, 1.0), 0.0, 1.0)),
        r_o=draw(edge_or(log_uniform(1e-9, 1e-2), 0.0)), b=b, c=rho * math.cos(angle), d=rho * math.sin(angle))


def scales(p):
    """Displacement scale (mean height) [m] and a stress scale [Pa] of the interface."""
    L = (p.alpha + 1.0) * p.beta
    L = max(L, 1e-3 * p.beta)
    return L, p.N * (4.0 / 3.0) * p.E_star * math.sqrt(p.R_m) * L ** 1.5


@st.composite
def valid_path(draw, p):
    L, sig = scales(p)
    stages = []
    for _ in range(draw(st.integers(1, 3))):
        control = tuple(draw(st.sampled_from(("d", "s"))) for _ in range(3))
        target = []
        for k, c in enumerate(control):
            if c == "d":
                target.append(L * draw(edge_or(st.floats(-0.5, 3.0), 0.0)))
            else:
                mag = sig * 10.0 ** draw(st.floats(-6.0, 1.0))
                sign = draw(st.sampled_from((1.0, 1.0, 1.0, -1.0))) if k == 0 else draw(st.sampled_from((1.0, -1.0)))
                target.append(draw(st.sampled_from((0.0, sign * mag, sign * mag, sign * mag))))
        stages.append(Stage(control, tuple(target), draw(st.integers(1, 2)),
                            adaptive=draw(st.booleans()), max_fraction=draw(st.sampled_from((0.5, 1.0)))))
    return LoadPath(tuple(stages), name="hypothesis")


def nonfinite(ds):
    bad = [name for name, v in ds.data_vars.items()
           if np.issubdtype(v.dtype, np.number) and not np.all(np.isfinite(v.values))]
    bad += [key for key, v in ds.attrs.items()
            if np.issubdtype(np.asarray(v).dtype, np.number) and not np.all(np.isfinite(np.asarray(v)))]
    return bad


@pytest.mark.slow
@settings(max_examples=N_VALID, **SETTINGS)
@given(data=st.data())
def test_valid_configurations_run_without_nan_or_inf(data):
    p = data.draw(valid_params(), label="params")
    path = data.draw(valid_path(p), label="path")
    n = data.draw(st.sampled_from((1, 2, 3, 7, 20, 40)), label="n")
    law = data.draw(st.sampled_from(("paper", "mdr")), label="law")
    policy = data.draw(st.sampled_from(("follow", "follow", "birth")), label="policy")
    k = data.draw(st.integers(1, 8), label="k")
    sampler = data.draw(st.sampled_from(("random", "sobol")), label="sampler")
    try:
        ds = simulate(p, path, n=n, seed=data.draw(st.integers(0, 2**32), label="seed"), sampler=sampler, law=law,
                      policy=policy, k=k, settings=FAST, max_wall_time=20.0)
        assert ds.attrs["status"] == "complete"
    except asim.SimulationError as err:
        ds = err.dataset
        assert len(str(err)) > 20 and ds.attrs["status"].startswith("failed: " + type(err).__name__)
        assert not isinstance(err, asim.WallTimeExceededError), str(err)
    assert not nonfinite(ds), nonfinite(ds)
    assert ds.sizes["step"] >= 1 and ds.attrs["n_asperities"] == n


# --------------------------------------------------------------------------- invalid configurations

GOOD = dict(N=200e6, alpha=6.14, beta=3.52e-6, R_m=50e-6, R_sigma=15e-6, mu=1.0, G=80e9, nu=0.3, e=1.0, r_o=0.0,
            b=0.0, c=0.0, d=0.0)
NON_REALS = st.sampled_from((math.nan, math.inf, -math.inf, "1.0", None, True, [1.0], complex(1, 0)))
NEG = st.floats(max_value=0.0, exclude_max=True)
NONPOS = st.floats(max_value=0.0)
BAD_PARAM_VALUES = {
    "N": NONPOS, "alpha": st.floats(max_value=-1.0), "beta": NONPOS, "R_m": NONPOS, "R_sigma": NEG, "mu": NEG,
    "G": NONPOS, "nu": st.floats(max_value=-1.0) | st.floats(min_value=0.5, exclude_min=True),
    "e": NEG | st.floats(min_value=1.0, exclude_min=True), "r_o": NEG,
    "b": st.floats(max_value=-1.0, exclude_max=True) | st.floats(min_value=2.0, exclude_min=True),
}


@st.composite
def invalid_params_call(draw):
    """Valid parameters anywhere in their ranges with one field made invalid."""
    good = draw(valid_params()).as_dict()
    name = draw(st.sampled_from(sorted(GOOD)))
    if name in ("c", "d"):  # bounded jointly with b: push b/2 + 3 sqrt(c² + d²) above 1
        limit = (1.0 - good["b"] / 2.0) / 3.0
        value = draw(st.one_of(NON_REALS, st.floats(limit + 1e-6, 1e6).map(lambda v: v * draw(
            st.sampled_from((1.0, -1.0))))))
        good["c" if name == "d" else "d"] = 0.0
    else:
        value = draw(st.one_of(NON_REALS, BAD_PARAM_VALUES[name]))
    good[name] = value
    return f"InterfaceParams({name}={value!r})", (lambda: InterfaceParams(**good)), name


BAD_STAGE = [
    ("control", ("d", "d")), ("control", ("x", "d", "d")), ("control", "dds"), ("control", None),
    ("target", (1e-6, 0.0)), ("target", (math.nan, 0.0, 0.0)), ("target", (0.0, math.inf, 0.0)),
    ("target", (0.0, 0.0, "1")), ("target", 1e-6), ("increments", 0), ("increments", -3), ("increments", 2.5),
    ("increments", True), ("increments", 10**8), ("adaptive", 1), ("max_fraction", 0.0), ("max_fraction", 1.5),
    ("max_fraction", math.nan), ("name", 3),
]


@st.composite
def invalid_path_call(draw):
    kw = dict(control=tuple(draw(st.sampled_from(("d", "s", "displacement", "stress"))) for _ in range(3)),
              target=tuple(draw(st.floats(-1e9, 1e9)) for _ in range(3)), increments=draw(st.integers(1, 10**7)))
    field, value = draw(st.one_of(
        st.sampled_from(BAD_STAGE),
        st.tuples(st.just("increments"), st.integers(max_value=0) | st.integers(min_value=10**7 + 1)),
        st.tuples(st.just("max_fraction"), NONPOS | st.floats(min_value=1.0, exclude_min=True)),
        st.tuples(st.just("target"), st.lists(st.floats(allow_nan=False), min_size=3, max_size=3).flatmap(
            lambda t: st.integers(0, 2).map(lambda i: tuple(t[:i] + [draw(st.sampled_from(
                (math.nan, math.inf, -math.inf)))] + t[i + 1:])))),
    ))
    kw[field] = value
    return f"Stage({field}={value!r})", (lambda: Stage(**kw)), field


BAD_CONSTRUCTORS = [
    ("three_step d_max", lambda v: paths.three_step(v), "d_max", (0.0, -1e-6, math.nan, math.inf, "1e-6", None)),
    ("three_step increments", lambda v: paths.three_step(1e-6, increments=v), "increments", (0, -1, 1.5, True)),
    ("constant_normal_shear sigma_n", lambda v: paths.constant_normal_shear(v, 1e-6), "sigma_n",
     (0.0, -1.0, math.nan, math.inf, None)),
    ("constant_normal_shear d2_max", lambda v: paths.constant_normal_shear(1e6, v), "d2_max", (0.0, -1e-6, math.nan)),
    ("LoadPath stages", lambda v: LoadPath(v), "stages", ((), [], None, (1, 2), "stage")),
]


@st.composite
def invalid_constructor_call(draw):
    label, f, word, values = draw(st.sampled_from(BAD_CONSTRUCTORS))
    value = draw(st.sampled_from(values))
    return f"{label}={value!r}", (lambda: f(value)), word


PATH = paths.three_step(1e-6, increments=1)
BAD_SIMULATE = {
    "n": (0, -1, 2.5, True, "100", None, 2**31), "seed": (-1, 1.5, "a", True), "law": ("x", None, "Paper"),
    "policy": ("x", None), "sampler": ("x", None), "k": (0, 4097, 2.5, True, "16"),
    "snapshots": ("ends", [-1], 3, [1.5]), "settings": ("x", {}), "output": (3, b"x".decode() * 0),
    "progress": (3, "f"), "max_wall_time": (0.0, -1.0, math.nan, math.inf, "10"),
    "checkpoint": (3, ""), "checkpoint_every": (0, -1, 2.5, True), "resume": (3, 1.0, ""),
    "population": ("x", 3), "params": (None, {"N": 1.0}, presets), "path": (None, PATH.stages[0], list(PATH.stages)),
}


CONTINUOUS_SIMULATE = {
    "n": st.integers(max_value=0) | st.integers(min_value=2**31), "seed": st.integers(max_value=-1),
    "k": st.integers(max_value=0) | st.integers(min_value=4097), "max_wall_time": NONPOS,
    "checkpoint_every": st.integers(max_value=0),
}


@st.composite
def invalid_simulate_call(draw):
    name = draw(st.sampled_from(sorted(BAD_SIMULATE)))
    values = st.sampled_from(BAD_SIMULATE[name])
    value = draw(values | CONTINUOUS_SIMULATE[name] if name in CONTINUOUS_SIMULATE else values)
    args = dict(params=presets.S1, path=PATH, n=50)
    if name == "checkpoint_every":
        args["checkpoint"] = "/nonexistent/never-written.npz"
    args[name] = value
    word = "snapshot" if name == "snapshots" else name
    return f"simulate({name}={value!r})", (lambda: simulate(args.pop("params"), args.pop("path"), **args)), word


POP = Population.sample(presets.S1, 20, seed=1)
BAD_OTHER = [
    ("Population.sample n", lambda v: Population.sample(presets.S1, v), "n", (0, -1, 1.5, True, None)),
    ("Population.sample seed", lambda v: Population.sample(presets.S1, 5, seed=v), "seed", (-1, 1.5, "x")),
    ("Population.sample sampler", lambda v: Population.sample(presets.S1, 5, sampler=v), "sampler", ("x", None)),
    ("Population.sample params", lambda v: Population.sample(v, 5), "params", (None, {"N": 1.0})),
    ("evaluate delta", lambda v: evaluate(POP, v), "delta",
     ([0.0, 0.0], [math.nan, 0.0, 0.0], [0.0, math.inf, 0.0], np.zeros((3, 1)))),
    ("evaluate law", lambda v: evaluate(POP, np.zeros(3), law=v), "law", ("x", None)),
    ("evaluate policy", lambda v: evaluate(POP, np.zeros(3), policy=v), "policy", ("x", None)),
    ("evaluate theta_birth", lambda v: evaluate(POP, np.zeros(3), policy="birth", theta_birth=v), "theta_birth",
     (np.zeros(3), np.zeros(21))),
    ("single_contact path", lambda v: asim.single_contact(v, 1e-4, 80e9, 0.3, 0.5), "path",
     (np.zeros((0, 3)), np.zeros((2, 2)), [[math.nan, 0, 0]], [[0, math.inf, 0]])),
    ("single_contact R", lambda v: asim.single_contact([[1e-7, 0, 0]], v, 80e9, 0.3, 0.5), "R",
     (0.0, -1e-4, math.nan, None)),
    ("single_contact G", lambda v: asim.single_contact([[1e-7, 0, 0]], 1e-4, v, 0.3, 0.5), "G", (0.0, -1.0, math.inf)),
    ("single_contact nu", lambda v: asim.single_contact([[1e-7, 0, 0]], 1e-4, 80e9, v, 0.5), "nu", (-1.0, 0.6)),
    ("single_contact mu", lambda v: asim.single_contact([[1e-7, 0, 0]], 1e-4, 80e9, 0.3, v), "mu", (-0.1, math.nan)),
    ("single_contact law", lambda v: asim.single_contact([[1e-7, 0, 0]], 1e-4, 80e9, 0.3, 0.5, law=v), "law", ("x",)),
    ("single_contact k", lambda v: asim.single_contact([[1e-7, 0, 0]], 1e-4, 80e9, 0.3, 0.5, k=v), "k", (0, 1.5)),
    ("resume checkpoint", lambda v: asim.resume(v), "checkpoint", (None, 3, "/nonexistent/ck.npz")),
    ("SolverSettings", lambda v: SolverSettings(**{v[0]: v[1]}), "",
     (("rtol", 0.0), ("max_iter", 0), ("resolution_rtol", -1.0), ("max_step", math.nan), ("max_search", 0.0))),
]


@st.composite
def invalid_other_call(draw):
    label, f, word, values = draw(st.sampled_from(BAD_OTHER))
    value = draw(st.sampled_from(values))
    return f"{label}={value!r}", (lambda: f(value)), word


def _no_work(*args, **kwargs):
    raise AssertionError("work started before the input was rejected")


@settings(max_examples=N_INVALID, **SETTINGS)
@given(call=st.one_of(invalid_params_call(), invalid_path_call(), invalid_constructor_call(), invalid_simulate_call(),
                      invalid_other_call()))
def test_invalid_configurations_raise_value_error_naming_the_value(call):
    label, f, word = call
    no_sampling = label.startswith("simulate")
    with mock.patch.object(run_module, "evaluate_unchecked", _no_work), \
            mock.patch.object(driver.Population, "sample", _no_work if no_sampling else Population.sample):
        with pytest.raises(ValueError) as exc:
            f()
    msg = str(exc.value)
    assert word == "" or word in msg, (label, msg)
    assert any(w in msg for w in ("valid", "must", "not", "expected", "another")), (label, msg)
