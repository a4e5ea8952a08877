"""Run files: datasets written to netCDF4 (compressed, atomically) and read back.

Owns the netCDF form of a run's dataset: the engine and compression, the CF links between a
value and its standard error (``ancillary_variables``), and the parameters read back from the
attributes.  The file is written through :func:`asperity_sim.output.atomic.write_atomically`.
"""

from __future__ import annotations

from pathlib import Path

import xarray as xr

from ..params import InterfaceParams
from .atomic import write_atomically


def write_netcdf(ds: xr.Dataset, path) -> Path:
    """Write ``ds`` to ``path`` with engine netcdf4 and compression, atomically.

    Each value with a standard error in ``ds`` (``x`` and ``x_stderr``, ``x_mean`` and ``x_sem``)
    names it in its CF attribute ``ancillary_variables`` in the file (``ds`` itself is not changed).
    """
    from .recorder import link_standard_errors

    ds = link_standard_errors(ds.copy(deep=False))
    encoding = {name: {"zlib": True, "complevel": 4} for name in ds.data_vars}
    return write_atomically(path, lambda tmp: ds.to_netcdf(tmp, engine="netcdf4", encoding=encoding))


def read_netcdf(path) -> xr.Dataset:
    """Open a run file fully into memory."""
    with xr.open_dataset(path, engine="netcdf4") as ds:
        return ds.load()


def params_from_attrs(attrs) -> InterfaceParams:
    """The InterfaceParams recorded in a run file's global attributes."""
    names = InterfaceParams.units().keys()
    return InterfaceParams(**{n: float(attrs[f"param_{n}"]) for n in names})
