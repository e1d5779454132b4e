# SPDX-License-Identifier: BSD-3-Clause
"""kumo output files as xarray Datasets, with their standard errors.

Every Monte Carlo product ``<name>`` of an output file has a companion ``<name>_stderr``: the
standard error (1 sigma) of the batch mean (docs/output.md). :func:`open_results` links the two
through the CF attribute ``ancillary_variables`` where the file does not already.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

STDERR_SUFFIX = "_stderr"


def open_results(path) -> xr.Dataset:
    """Read a kumo output file into memory (the file is closed again) as an xarray Dataset."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"kumo output file {path} not found")
    with xr.open_dataset(path) as ds:
        ds = ds.load()
    for name in products(ds):
        ds[name].attrs.setdefault("ancillary_variables", name + STDERR_SUFFIX)
    ds.attrs.setdefault("source_file", str(path))
    return ds


def products(ds: xr.Dataset) -> list:
    """The names of the variables that have a standard error (``<name>_stderr``)."""
    return [name for name in ds.data_vars
            if not str(name).endswith(STDERR_SUFFIX) and f"{name}{STDERR_SUFFIX}" in ds]


def stderr(ds: xr.Dataset, name: str) -> xr.DataArray:
    """The standard error of product ``name``."""
    key = name + STDERR_SUFFIX
    if key not in ds:
        raise KeyError(f"{name} has no standard error ({key} is not in the dataset)")
    return ds[key]


def value(ds: xr.Dataset, name: str):
    """``(mean, standard error)`` of product ``name``: floats for a scalar, else DataArrays."""
    mean, err = ds[name], stderr(ds, name)
    if mean.ndim == 0:
        return float(mean), float(err)
    return mean, err


def relative_error(ds: xr.Dataset, name: str) -> xr.DataArray:
    """stderr / |mean| of product ``name`` (NaN where the mean is 0)."""
    mean = ds[name]
    return stderr(ds, name) / abs(mean).where(mean != 0, np.nan)
