"""Output variable registry and the metadata of written datasets (CF conventions).

Every variable (registry and dataset) must carry non-empty ``units`` and ``long_name``; units
must be UDUNITS-2 strings (checked by a small UDUNITS grammar written here: products of SI
symbols with optional prefixes and integer exponents, an optional single division, or "1"), and
the units of the quantities SPEC §1–§6 defines must be the physically right ones.
"""

import re

import numpy as np
import pytest

from asperity_sim import InterfaceParams, paths, Population, presets, simulate
from asperity_sim.output import variables as V

# --------------------------------------------------------------------------- a UDUNITS-2 subset

_SYMBOLS = ("m", "g", "s", "K", "A", "mol", "cd", "N", "Pa", "J", "W", "Hz", "rad", "sr", "C", "V", "degree",
            "bar", "percent")
_PREFIXES = ("", "Y", "Z", "E", "P", "T", "G", "M", "k", "h", "da", "d", "c", "m", "u", "n", "p", "f", "a")
_TERM = re.compile(r"^(?P<unit>[A-Za-z]+)(?:\^?(?P<exp>[-+]?\d+))?$")


def _is_symbol(word):
    return any(word == p + s for p in _PREFIXES for s in _SYMBOLS)


def is_udunits(text):
    """True for "1" and for products like "Pa m-1", "m-2", "kg.m/s2", "N"."""
    if not isinstance(text, str) or text != text.strip() or not text:
        return False
    if text == "1":
        return True
    parts = text.split("/")
    if len(parts) > 2:
        return False
    for part in parts:
        terms = re.split(r"[ .]", part)
        if not terms or any(t == "" for t in terms):
            return False
        for t in terms:
            m = _TERM.match(t)
            if not m or not _is_symbol(m.group("unit")):
                return False
            if m.group("exp") is not None and int(m.group("exp")) == 0:
                return False
    return True


@pytest.mark.parametrize("good", ["1", "m", "Pa", "Pa m-1", "m-2", "N", "rad", "m2", "kg.m.s-2", "Pa/m",
                                  "m^-2", "um", "MPa"])
def test_udunits_checker_accepts(good):
    assert is_udunits(good)


@pytest.mark.parametrize("bad", ["", " m", "Pa/m/s", "meters", "1/m²", "Pa·m-1", "m**2", "m-0", "dimensionless",
                                 "mm mm /", None, 1, "rad s- 1", "MPa per m"])
def test_udunits_checker_rejects(bad):
    assert not is_udunits(bad)


# --------------------------------------------------------------------------- the registry

# every table of Var in the module (new tables are picked up), except the union ALL_VARIABLES
REGISTRIES = {name: obj for name, obj in vars(V).items()
              if isinstance(obj, dict) and obj and name != "ALL_VARIABLES"
              and all(isinstance(v, V.Var) for v in obj.values())}

# what SPEC §1–§6 fixes (units every implementation must use for these quantities)
EXPECTED_UNITS = {
    "displacement": "m", "stress": "Pa", "stress_stderr": "Pa", "displacement_stderr": "m",
    "tangent": "Pa m-1", "n_contact": "1", "n_slip": "1", "theta_am": "rad", "mean_theta": "rad",
    "stage": "1", "control": "1", "iterations": "1", "residual": "1", "cutbacks": "1",
    "r": "m", "R": "m", "u": "rad", "phi": "rad",
    "asperity_delta_n": "m", "asperity_theta": "rad", "asperity_force": "N", "n_partial": "1",
    "external_work": "J m-2", "elastic_energy": "J m-2", "dissipation": "J m-2",
}
_EQUIVALENT = {"Pa m-1": {"Pa m-1", "Pa/m", "Pa.m-1", "N m-3", "N.m-3"},
               "J m-2": {"J m-2", "J/m2", "J.m-2", "N m-1", "N/m", "Pa m", "Pa.m"}}


def _same_unit(a, b):
    return a == b or a in _EQUIVALENT.get(b, ())


def all_registry_items():
    for reg_name, reg in REGISTRIES.items():
        for name, var in reg.items():
            yield reg_name, name, var


@pytest.mark.parametrize("reg_name, name, var", list(all_registry_items()),
                         ids=[f"{r}.{n}" for r, n, _ in all_registry_items()])
def test_registry_entry_has_cf_units_and_long_name(reg_name, name, var):
    assert isinstance(var.units, str) and var.units.strip(), name
    assert is_udunits(var.units), (name, var.units)
    assert isinstance(var.long_name, str) and len(var.long_name.strip()) >= 3, name
    assert isinstance(var.dims, tuple) and var.dims and all(isinstance(d, str) for d in var.dims)
    np.dtype(var.dtype)  # a valid numpy dtype
    if name in EXPECTED_UNITS:
        assert _same_unit(var.units, EXPECTED_UNITS[name]), (name, var.units)


def test_registry_tables_found():
    assert {"STEP_VARIABLES", "ASPERITY_VARIABLES", "SNAPSHOT_VARIABLES", "COORDS"} <= set(REGISTRIES)


def test_registry_covers_spec_quantities_and_is_consistent():
    all_vars = V.ALL_VARIABLES
    for name in ("displacement", "stress", "stress_stderr", "tangent", "n_contact", "n_slip", "theta_am"):
        assert name in V.STEP_VARIABLES, name
    assert V.STEP_VARIABLES["tangent"].dims == ("step", "axis", "axis_k")
    for name in V.STEP_VARIABLES.values():
        assert name.dims[0] == "step"
    for name in V.ASPERITY_VARIABLES.values():
        assert name.dims == ("asperity",)
    for name in V.SNAPSHOT_VARIABLES.values():
        assert name.dims[0] == "snapshot"
    # ALL_VARIABLES is the union, without a name defined twice differently
    total = sum(len(r) for r in REGISTRIES.values())
    assert len(all_vars) == total
    for reg in REGISTRIES.values():
        for name, var in reg.items():
            assert all_vars[name] == var
    # long names are distinct (each describes its own quantity)
    long_names = [v.long_name for v in all_vars.values()]
    assert len(set(long_names)) == len(long_names)


# --------------------------------------------------------------------------- written datasets


@pytest.fixture(scope="module")
def runs():
    pop = Population.sample(presets.S1, 2000, seed=1)
    a = simulate(presets.S1, paths.three_step(6e-6, increments=2), population=pop, snapshots=[0, 3])
    b = simulate(presets.S1, paths.constant_normal_shear(100e6, 2e-6, increments=2), population=pop)
    return {"three_step": a, "constant_normal_shear": b}


@pytest.mark.parametrize("which", ["three_step", "constant_normal_shear"])
def test_every_dataset_variable_has_cf_units_and_long_name(runs, which):
    ds = runs[which]
    for name in ds.variables:  # data variables and coordinates
        attrs = ds[name].attrs
        assert "units" in attrs and "long_name" in attrs, name
        units, long_name = attrs["units"], attrs["long_name"]
        assert isinstance(units, str) and is_udunits(units), (name, units)
        assert isinstance(long_name, str) and long_name.strip(), name
        if name in V.ALL_VARIABLES:
            reg = V.ALL_VARIABLES[name]
            assert units == reg.units and long_name == reg.long_name, name
            assert ds[name].dims == reg.dims, name
            if reg.dtype == "U":  # a string as long as its longest value
                assert ds[name].dtype.kind == "U", name
            else:
                assert ds[name].dtype == np.dtype(reg.dtype), name
        if name in EXPECTED_UNITS:
            assert _same_unit(units, EXPECTED_UNITS[name]), (name, units)
    # every step variable of the registry is written
    assert set(V.STEP_VARIABLES) <= set(ds.data_vars)
    # and nothing is written that the registry does not describe (apart from the step index)
    assert set(ds.variables) - set(V.ALL_VARIABLES) <= {"step"}


def test_snapshot_variables_present_with_metadata(runs):
    ds = runs["three_step"]
    for name in {**V.ASPERITY_VARIABLES, **V.SNAPSHOT_VARIABLES}:
        assert name in ds.variables, name
        assert ds[name].attrs["units"] == V.ALL_VARIABLES[name].units
    assert "asperity" not in runs["constant_normal_shear"].sizes


@pytest.mark.parametrize("which", ["three_step", "constant_normal_shear"])
def test_flag_variables_are_consistent(runs, which):
    ds = runs[which]
    flags = ["control"] + (["asperity_state"] if "asperity_state" in ds else [])
    for name in flags:
        attrs = ds[name].attrs
        values = np.asarray(attrs["flag_values"])
        meanings = attrs["flag_meanings"].split()
        assert len(values) == len(meanings) and len(set(values.tolist())) == len(values), name
        assert set(np.unique(ds[name].values)) <= set(values.tolist()), name
    c = dict(zip(np.asarray(ds.control.attrs["flag_values"]).tolist(), ds.control.attrs["flag_meanings"].split()))
    assert c == {0: "displacement", 1: "stress"}


@pytest.mark.parametrize("which", ["three_step", "constant_normal_shear"])
def test_parameter_attributes_carry_spec_units(runs, which):
    ds = runs[which]
    spec_units = {"N": "m-2", "alpha": "1", "beta": "m", "R_m": "m", "R_sigma": "m", "mu": "1", "G": "Pa",
                  "nu": "1", "e": "1", "r_o": "m", "b": "1", "c": "1", "d": "1", "summit_offset": "m", "interaction": "1"}
    assert set(InterfaceParams.units()) == set(spec_units)
    for name, unit in spec_units.items():
        got = ds.attrs[f"param_{name}_units"]
        assert is_udunits(got) and got == unit, (name, got)
        assert ds.attrs[f"param_{name}"] == getattr(presets.S1, name)
    assert ds.attrs["Conventions"].startswith("CF-")


# --------------------------------------------------------------------------- CF links, stage names, timing


def _stderr_partners(ds):
    return {name: f"{name}_stderr" for name in ds.data_vars if f"{name}_stderr" in ds.data_vars}


@pytest.fixture(scope="module")
def written(runs, tmp_path_factory):
    from asperity_sim.output.netcdf import read_netcdf, write_netcdf

    folder = tmp_path_factory.mktemp("written")
    return {which: read_netcdf(write_netcdf(ds, folder / f"{which}.nc")) for which, ds in runs.items()}


@pytest.mark.parametrize("where", ["memory", "file"])
@pytest.mark.parametrize("which", ["three_step", "constant_normal_shear"])
def test_every_value_with_a_standard_error_names_it_in_ancillary_variables(runs, written, which, where):
    ds = (runs if where == "memory" else written)[which]
    partners = _stderr_partners(ds)
    assert {"stress", "displacement"} <= set(partners)  # the values the recorder gives errors to
    for name, stderr in partners.items():
        assert ds[name].attrs.get("ancillary_variables") == stderr, (name, ds[name].attrs)
    for name in ds.data_vars:  # and no link points at something that is not there
        for target in ds[name].attrs.get("ancillary_variables", "").split():
            assert target in ds.data_vars, (name, target)


def test_sweep_means_name_their_standard_error_in_the_file(tmp_path):
    import xarray as xr

    from asperity_sim.output.netcdf import read_netcdf, write_netcdf

    ds = xr.Dataset({"stress_mean": ("step", [1.0, 2.0], {"units": "Pa", "long_name": "mean"}),
                     "stress_sem": ("step", [0.1, 0.2], {"units": "Pa", "long_name": "sem"}),
                     "n_mean": ("step", [1.0, 2.0], {"units": "1", "long_name": "mean without sem"})})
    back = read_netcdf(write_netcdf(ds, tmp_path / "sweep.nc"))
    assert back["stress_mean"].attrs["ancillary_variables"] == "stress_sem"
    assert "ancillary_variables" not in back["n_mean"].attrs
    assert "ancillary_variables" not in ds["stress_mean"].attrs  # the caller's dataset is not changed


@pytest.mark.parametrize("which, path", [("three_step", paths.three_step(6e-6, increments=2)),
                                         ("constant_normal_shear", paths.constant_normal_shear(100e6, 2e-6, increments=2))])
def test_stage_name_is_the_name_of_each_steps_stage_and_survives_the_file(runs, written, which, path):
    expected = ["initial state"] + [s.name for s in path.stages]
    assert all(s.name for s in path.stages)  # the constructors name their stages
    for ds in (runs[which], written[which]):
        stage = ds["stage"].values
        got = [str(v) for v in ds["stage_name"].values]
        assert got == [expected[i] for i in stage]
        assert set(got) == set(expected)  # every stage has steps
    assert written[which]["stage_name"].attrs["long_name"] == V.ALL_VARIABLES["stage_name"].long_name


def test_unnamed_stages_have_an_empty_stage_name():
    from asperity_sim.paths import LoadPath, Stage

    D = "displacement"
    path = LoadPath((Stage((D, D, D), (2e-6, 0.0, 0.0), 2), Stage((D, D, D), (2e-6, 1e-6, 0.0), 2, name="shear")))
    ds = simulate(presets.S1, path, n=500, seed=1)
    assert list(ds["stage_name"].values) == ["initial state", "", "", "shear", "shear"]


def test_wall_time_attribute_says_what_it_times(runs, written):
    for ds in (*runs.values(), *written.values()):
        assert "wall_time_s" not in ds.attrs  # the ambiguous name is gone
        assert ds.attrs["wall_time_increment_loop_s"] > 0.0
        text = ds.attrs["wall_time_increment_loop_s_description"]
        assert "increment loop" in text and "not included" in text
