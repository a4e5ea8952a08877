"""InterfaceParams and the Table 1 presets against SPEC §1, §3 and §5."""

import dataclasses
import math
import re

import numpy as np
import pytest

from asperity_sim import presets
from asperity_sim.params import InterfaceParams

# A valid, generic parameter set (SI) used as the base for single-field changes.
BASE = dict(N=1.0e8, alpha=2.5, beta=2.0e-6, R_m=40e-6, R_sigma=5e-6, mu=0.6, G=30e9, nu=0.25,
            e=0.5, r_o=1e-6, b=0.1, c=0.05, d=-0.05, summit_offset=0.5e-6, interaction=0.5)

ALL_FIELDS = {"N", "alpha", "beta", "R_m", "R_sigma", "e", "r_o", "mu", "G", "nu", "b", "c", "d", "summit_offset", "interaction"}


def make(**changes):
    kw = dict(BASE)
    kw.update(changes)
    return InterfaceParams(**kw)


def names_param(msg, name):
    """The message mentions ``name`` as a separate token (not inside a word or a number like 1e-9)."""
    return re.search(rf"(?<![A-Za-z0-9_.]){re.escape(name)}(?![A-Za-z0-9_])", msg) is not None


def value_texts(value):
    out = {repr(value), str(value)}
    if isinstance(value, float):
        out |= {repr(float(value))}
    return out


def assert_rejected(name, value, **changes):
    with pytest.raises(ValueError) as info:
        make(**{name: value}, **changes)
    msg = str(info.value)
    assert names_param(msg, name), msg
    assert any(t in msg for t in value_texts(value)), msg


# --------------------------------------------------------------------------- Table 1

# SPEC §1, Table 1 in SI, typed here from SPEC (not from presets.py).
TABLE1_SPEC = {
    "R1": dict(N=200e6, R_m=50e-6, R_sigma=15e-6, mu=1.0, G=80e9, nu=0.3, r_o=0.0, alpha=6.14, beta=3.52e-6),
    "S1": dict(N=200e6, R_m=75e-6, R_sigma=10e-6, mu=1.0, G=80e9, nu=0.3, r_o=0.0, alpha=3.82, beta=1.15e-6),
    "R2": dict(N=0.2240e6, R_m=8.82e-3, R_sigma=0.30e-3, mu=1.0, G=31.8e9, nu=0.152, r_o=0.10e-3,
               alpha=7.20, beta=0.05e-3),
    "S2": dict(N=0.2034e6, R_m=8.18e-3, R_sigma=0.20e-3, mu=1.0, G=31.8e9, nu=0.152, r_o=0.12e-3,
               alpha=6.77, beta=0.03e-3),
}


@pytest.mark.parametrize("name", sorted(TABLE1_SPEC))
def test_table1_preset_values(name):
    p = getattr(presets, name)
    assert isinstance(p, InterfaceParams)
    for field, expected in TABLE1_SPEC[name].items():
        assert getattr(p, field) == pytest.approx(expected, rel=1e-12, abs=0.0), field
    # SPEC §1: e is not given in the paper; e = 1 and b = c = d = 0
    assert p.e == 1.0
    assert (p.b, p.c, p.d) == (0.0, 0.0, 0.0)
    assert p.isotropic


def test_table1_dict():
    assert set(presets.TABLE1) == {"R1", "S1", "R2", "S2"}
    for name, p in presets.TABLE1.items():
        assert p is getattr(presets, name)


def test_presets_are_distinct_sets():
    # the rough/smooth pairs differ in the roughness parameters of SPEC Table 1
    assert presets.R1.R_m < presets.S1.R_m and presets.R1.alpha > presets.S1.alpha
    assert presets.R2.beta > presets.S2.beta


# --------------------------------------------------------------------------- replace / immutability

def test_replace_returns_validated_copy():
    p = make()
    q = p.replace(mu=0.3, nu=0.5)
    assert q is not p
    assert (q.mu, q.nu) == (0.3, 0.5)
    assert (p.mu, p.nu) == (BASE["mu"], BASE["nu"])  # original unchanged
    for f in ALL_FIELDS - {"mu", "nu"}:
        assert getattr(q, f) == getattr(p, f)
    q2 = p.replace(alpha=3)  # an int is stored as a float
    assert type(q2.alpha) is float and q2.alpha == 3.0


@pytest.mark.parametrize("change", [dict(mu=-0.1), dict(nu=0.6), dict(G=0.0), dict(e=1.5),
                                    dict(beta=float("nan")), dict(b=1.0, c=0.3)])
def test_replace_rejects_invalid_value(change):
    p = make()
    with pytest.raises(ValueError) as info:
        p.replace(**change)
    name = next(iter(change))
    assert names_param(str(info.value), name)


def test_replace_rejects_unknown_name():
    with pytest.raises(ValueError, match="not_a_field"):
        make().replace(not_a_field=1.0)
    with pytest.raises(ValueError, match="Mu"):
        presets.R1.replace(Mu=0.5)


@pytest.mark.parametrize("field", sorted(ALL_FIELDS))
def test_frozen(field):
    p = make()
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(p, field, 1.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(presets.R1, field, 1.0)
    assert getattr(p, field) == BASE[field]


def test_field_set_and_units():
    assert {f.name for f in dataclasses.fields(InterfaceParams)} == ALL_FIELDS
    units = InterfaceParams.units()
    assert units["N"] == "m-2" and units["G"] == "Pa"
    for f in ("beta", "R_m", "R_sigma", "r_o", "summit_offset"):
        assert units[f] == "m"
    for f in ("alpha", "e", "mu", "nu", "b", "c", "d", "interaction"):
        assert units[f] == "1"
    assert set(InterfaceParams.long_names()) == ALL_FIELDS


def test_numpy_scalars_accepted_and_stored_as_float():
    p = make(alpha=np.float32(2.5), N=np.int64(1000), mu=np.float64(0.25))
    for f in ("alpha", "N", "mu"):
        assert type(getattr(p, f)) is float
    assert p.alpha == 2.5 and p.N == 1000.0 and p.mu == 0.25


# --------------------------------------------------------------------------- validation of every field

BAD_TYPES = [float("nan"), float("inf"), float("-inf"), "1.0", "abc", None, True, False, 1 + 0j, 0.5 + 1j,
             np.nan, np.True_, [1.0]]


@pytest.mark.parametrize("field", sorted(ALL_FIELDS))
@pytest.mark.parametrize("value", BAD_TYPES, ids=repr)
def test_every_field_rejects_non_finite_and_non_real(field, value):
    assert_rejected(field, value)


def _up(x):
    return float(np.nextafter(x, math.inf))


def _down(x):
    return float(np.nextafter(x, -math.inf))


# (field, value) pairs at and just beyond each bound of SPEC §1 that must be rejected.
OUT_OF_RANGE = [
    ("N", 0.0), ("N", _down(0.0)), ("N", -1.0),
    ("alpha", -1.0), ("alpha", _down(-1.0)), ("alpha", -2.0),
    ("beta", 0.0), ("beta", _down(0.0)), ("beta", -1e-6),
    ("R_m", 0.0), ("R_m", _down(0.0)), ("R_m", -1e-6),
    ("R_sigma", _down(0.0)), ("R_sigma", -1e-6),
    ("e", _down(0.0)), ("e", _up(1.0)), ("e", -0.5), ("e", 2.0),
    ("r_o", _down(0.0)), ("r_o", -1e-6),
    ("mu", _down(0.0)), ("mu", -0.1),
    ("G", 0.0), ("G", _down(0.0)), ("G", -1e9),
    ("nu", -1.0), ("nu", _down(-1.0)), ("nu", _up(0.5)), ("nu", 0.6), ("nu", -1.5),
]

# (field, value) pairs at or just inside each bound that must be accepted.
IN_RANGE = [
    ("N", _up(0.0)), ("N", 1e30),
    ("alpha", _up(-1.0)), ("alpha", 0.0), ("alpha", 50.0),
    ("beta", _up(0.0)),
    ("R_m", _up(0.0)),
    ("R_sigma", 0.0), ("R_sigma", 1.0),  # R_sigma > R_m/3 is allowed (truncation at R > 0, SPEC §2)
    ("e", 0.0), ("e", 1.0),
    ("r_o", 0.0),
    ("mu", 0.0), ("mu", 10.0),
    ("G", _up(0.0)),
    ("nu", _up(-1.0)), ("nu", 0.5), ("nu", 0.0),
]


@pytest.mark.parametrize("field,value", OUT_OF_RANGE, ids=lambda v: repr(v))
def test_out_of_range_rejected(field, value):
    assert_rejected(field, value)


@pytest.mark.parametrize("field,value", IN_RANGE, ids=lambda v: repr(v))
def test_in_range_accepted(field, value):
    p = make(**{field: value})
    assert getattr(p, field) == value


# --------------------------------------------------------------------------- orientation density rule (SPEC §3)

def xi_min(b, c, d):
    """Minimum over (u, phi) of 2 pi xi (SPEC §3): for fixed x = cos u the minimum over phi of
    c cos 2phi + d sin 2phi is -sqrt(c² + d²); the remaining function of x is then scanned on a grid
    that contains both ends x = 0 and x = 1."""
    x = np.linspace(0.0, 1.0, 1001)
    rho = math.hypot(c, d)
    return float(np.min(1 + b * (3 * x**2 - 1) / 2 - 3 * (1 - x**2) * rho))


EDGE_ACCEPTED = [
    pytest.param(2.0, 0.0, 0.0, id="b=2"),
    pytest.param(-1.0, 0.0, 0.0, id="b=-1"),
    pytest.param(0.0, 1 / 3, 0.0, id="c=1/3"),
    pytest.param(0.0, 0.0, -1 / 3, id="d=-1/3"),
    pytest.param(0.0, -0.2, math.sqrt(1 / 9 - 0.04), id="rho=1/3"),
    pytest.param(0.5, 0.15, 0.2, id="b=0.5,rho=0.25"),
    pytest.param(-1.0, 0.2, -0.25, id="b=-1,interior"),
    pytest.param(-1.0, 0.5, 0.0, id="b=-1,c=1/2"),
    pytest.param(-1.0, 0.3, 0.4, id="b=-1,rho=1/2"),
    pytest.param(-0.4, 0.0, -0.4, id="b=-0.4,d=-0.4"),
    pytest.param(-1.0, 0.4, 0.0, id="b=-1,c=0.4-interior"),
]


@pytest.mark.parametrize("b,c,d", EDGE_ACCEPTED)
def test_orientation_edge_and_valid_accepted(b, c, d):
    assert xi_min(b, c, d) >= -1e-9  # the test's own premise: the density is non-negative
    p = make(b=b, c=c, d=d)
    assert (p.b, p.c, p.d) == (b, c, d)


EPS = 1e-9
BEYOND = [
    pytest.param(_down(-1.0), 0.0, 0.0, id="b<-1"),
    pytest.param(2.0 + EPS, 0.0, 0.0, id="b>2"),
    pytest.param(0.0, 1 / 3 + EPS, 0.0, id="c>1/3"),
    pytest.param(0.0, 0.0, -1 / 3 - EPS, id="d<-1/3"),
    pytest.param(0.0, -0.2 - EPS, math.sqrt(1 / 9 - 0.04), id="rho>1/3"),
    pytest.param(0.5, 0.15 + EPS, 0.2, id="b=0.5,rho>0.25"),
    pytest.param(0.5 + EPS, 0.15, 0.2, id="b>0.5,rho=0.25"),
    pytest.param(-1.0, 0.5 + EPS, 0.0, id="b=-1,c>1/2"),
    pytest.param(-1.0 - EPS, 0.0, 0.5, id="b<-1,d=1/2"),
    pytest.param(1.0, 0.2, 0.0, id="b=1,c=0.2"),
]


@pytest.mark.parametrize("b,c,d", BEYOND)
def test_orientation_beyond_edge_rejected(b, c, d):
    assert xi_min(b, c, d) < 0.0  # the test's own premise: the density goes negative
    with pytest.raises(ValueError) as info:
        make(b=b, c=c, d=d)
    msg = str(info.value)
    assert any(names_param(msg, k) for k in ("b", "c", "d")), msg


# --------------------------------------------------------------------------- derived quantities

@pytest.mark.parametrize("e", [0.0, 0.1, 0.5, 1.0])
def test_k_e(e):
    p = make(e=e)
    assert p.k_e == pytest.approx(e / (1 + e) ** 2, rel=1e-15, abs=0)


def test_k_e_limits():
    assert make(e=0.0).k_e == 0.0  # flat against rough (SPEC §3)
    assert make(e=1.0).k_e == 0.25


@pytest.mark.parametrize("nu", [_up(-1.0) + 1e-6, -0.5, 0.0, 0.152, 0.3, 0.5])
@pytest.mark.parametrize("G", [1e6, 31.8e9, 80e9])
def test_elastic_derived(nu, G):
    p = make(G=G, nu=nu)
    assert p.E_star == pytest.approx(G / (1 - nu), rel=1e-14)
    assert p.lam == pytest.approx((2 - nu) / (2 * (1 - nu)), rel=1e-14)
    for R in (5e-6, 50e-6, 8.82e-3):
        K = 8 * G * math.sqrt(R) / (3 * (2 - nu))
        assert (4 / 3) * p.E_star * math.sqrt(R) == pytest.approx(p.lam * K, rel=1e-13)


def test_elastic_limits():
    # nu = 0.5: E* = 2G, lambda = 3/2; nu = 0: E* = G, lambda = 1
    p = make(nu=0.5, G=2.0)
    assert (p.E_star, p.lam) == (pytest.approx(4.0), pytest.approx(1.5))
    p = make(nu=0.0, G=3.0)
    assert (p.E_star, p.lam) == (pytest.approx(3.0), pytest.approx(1.0))


@pytest.mark.parametrize("R_m,R_sigma,lo,hi", [(50e-6, 15e-6, 5e-6, 95e-6), (10e-6, 5e-6, 0.0, 25e-6),
                                               (1.0, 0.0, 1.0, 1.0)])
def test_R_bounds(R_m, R_sigma, lo, hi):
    a, b = make(R_m=R_m, R_sigma=R_sigma).R_bounds
    assert a == pytest.approx(lo, abs=1e-18) and b == pytest.approx(hi, rel=1e-14)
