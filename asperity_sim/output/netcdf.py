"""Writing and reading run files (netCDF4).  With the recorder, the only module that writes files.

Files are written atomically: to a temporary file in the target folder, then renamed,
so a crash never leaves a truncated file under the final name.  The temporary is named
``.<name>.<pid>.<random>.tmp``; a failed write removes it, and the next write of the same file
removes those of killed processes (:func:`asperity_sim.output.checkpoint.remove_stale_temporaries`).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import xarray as xr

from ..params import InterfaceParams


def write_netcdf(ds: xr.Dataset, path) -> Path:
    """Write ``ds`` to ``path`` with engine netcdf4 and compression, atomically.

    Each value with a standard error in ``ds`` (``x`` and ``x_stderr``, ``x_mean`` and ``x_sem``)
    names it in its CF attribute ``ancillary_variables`` in the file (``ds`` itself is not changed).
    """
    from .recorder import link_standard_errors

    ds = link_standard_errors(ds.copy(deep=False))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    encoding = {name: {"zlib": True, "complevel": 4} for name in ds.data_vars}
    from .checkpoint import remove_stale_temporaries

    remove_stale_temporaries(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; give the file the usual permissions
    try:
        ds.to_netcdf(tmp, engine="netcdf4", encoding=encoding)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def read_netcdf(path) -> xr.Dataset:
    """Open a run file fully into memory."""
    with xr.open_dataset(path, engine="netcdf4") as ds:
        return ds.load()


def params_from_attrs(attrs) -> InterfaceParams:
    """The InterfaceParams recorded in a run file's global attributes."""
    names = InterfaceParams.units().keys()
    return InterfaceParams(**{n: float(attrs[f"param_{n}"]) for n in names})
