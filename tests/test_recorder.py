"""Recorder: per-step buffers (append one increment, extend several) and the Dataset built from them."""

import numpy as np
import pytest
import xarray as xr

from asperity_sim.output.recorder import Recorder
from asperity_sim.output.variables import STEP_VARIABLES


def rows(m, rng):
    """m increments of every step variable, with random values of its dtype and shape."""
    shapes = {"axis": 3, "axis_k": 3}
    out = []
    for _ in range(m):
        row = {}
        for name, var in STEP_VARIABLES.items():
            shape = tuple(shapes[d] for d in var.dims[1:])
            row[name] = (rng.normal(size=shape) if var.dtype == "f8" else rng.integers(0, 100, size=shape)).astype(
                var.dtype)
        out.append(row)
    return out


def test_extend_equals_appending_row_by_row_across_growth():
    rng = np.random.default_rng(0)
    data = rows(11, rng)
    one, many = Recorder(2), Recorder(2)  # both must grow
    for row in data:
        one.append(**row)
    many.append(**data[0])
    many.extend(**{k: np.stack([r[k] for r in data[1:7]]) for k in data[0]})
    many.extend(**{k: np.stack([r[k] for r in data[7:]]) for k in data[0]})
    a, b = one.to_dataset({}), many.to_dataset({})
    assert a.sizes["step"] == b.sizes["step"] == 11
    for name in STEP_VARIABLES:
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


def test_extend_broadcasts_one_value_and_names_a_missing_variable():
    rng = np.random.default_rng(1)
    data = rows(4, rng)
    rec = Recorder(4)
    columns = {k: np.stack([r[k] for r in data]) for k in data[0]}
    rec.extend(**{**columns, "stage": 2, "residual": 0.0})
    ds = rec.to_dataset({})
    assert np.all(ds["stage"].values == 2) and np.all(ds["residual"].values == 0.0)
    del columns["tangent"]
    with pytest.raises(KeyError, match="tangent"):
        rec.extend(**columns)


def test_dataset_from_the_cached_template_is_the_constructors_and_shares_nothing_mutable():
    from asperity_sim.output import recorder

    rng = np.random.default_rng(2)
    rec = Recorder(5)
    for row in rows(5, rng):
        rec.append(**row)
    first = rec.to_dataset({"title": "a"})
    data = {name: rec._buf[name][:5] for name in STEP_VARIABLES}
    xr.testing.assert_identical(first, recorder._build(STEP_VARIABLES, data).assign_attrs(title="a"))
    # whatever a caller does to one result never reaches the next one
    first["stress"].values[:] = -1.0
    first["stress"].attrs["units"] = "changed"
    first["control"].attrs["flag_meanings"] = "changed"
    first["step"].attrs["units"] = "changed"
    first.attrs["title"] = "changed"
    second = rec.to_dataset({"title": "b"})
    assert second["stress"].attrs["units"] == "Pa" and second["step"].attrs["units"] == "1"
    assert second["control"].attrs["flag_meanings"] == "displacement stress"
    assert second.attrs == {"title": "b"}
    np.testing.assert_array_equal(second["stress"].values, data["stress"])


def test_stage_names_label_each_step_and_a_stage_beyond_the_names_is_refused():
    rng = np.random.default_rng(2)
    rec = Recorder(4)
    for i, row in enumerate(rows(3, rng)):
        row["stage"] = np.array(i, dtype=STEP_VARIABLES["stage"].dtype)
        rec.append(**row)
    ds = rec.to_dataset({}, stage_names=["load", "shear"])
    assert list(ds["stage_name"].values) == ["initial state", "load", "shear"]
    assert list(ds.variables)[-1] == "stage_name"  # after the coordinates, as files have always had it
    with pytest.raises(ValueError, match=r"stage index 2 is out of range \(valid range: 0 to 1\)"):
        rec.to_dataset({}, stage_names=["load"])
