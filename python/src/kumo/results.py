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


#: The products that add up from a shortwave and a longwave run of the same scene.
BROADBAND_SUMS = ("flux_up_wm2", "flux_down_wm2", "flux_net_wm2", "heating_rate_layer",
                  "heating_rate_voxel")


def broadband_total(sw: xr.Dataset, lw: xr.Dataset) -> xr.Dataset:
    """Shortwave + longwave: the sums of a broadband shortwave and a broadband longwave run of
    the same scene (``&kumo_spectral``), with standard errors.

    Fluxes in W m-2 (``flux_up_wm2``, ``flux_down_wm2``, ``flux_net_wm2``) and heating rates in
    K/day (``heating_rate_layer``, ``heating_rate_voxel``) are added (the per-column maps are
    fractions of each run's own normalisation and are left out). The two runs are independent
    (their own photons), so the standard error of a sum is sqrt(sigma_sw^2 + sigma_lw^2). The coordinates (levels,
    layers, columns) must be the same; a dataset that is not a broadband run of the right kind
    is refused.
    """
    for ds, kind in ((sw, "shortwave"), (lw, "longwave")):
        text = str(ds.attrs.get("broadband", ""))
        if not text.startswith(kind):
            raise ValueError(f"broadband_total: the {kind} dataset is not a broadband {kind} run "
                             f"(its 'broadband' attribute is {text!r})")
    out = xr.Dataset(attrs={"title": "kumo: shortwave + longwave",
                            "shortwave_source": str(sw.attrs.get("source_file", "")),
                            "longwave_source": str(lw.attrs.get("source_file", ""))})
    for name in BROADBAND_SUMS:
        if name not in sw or name not in lw:
            continue
        a, b = sw[name], lw[name]
        for dim in a.dims:
            if (dim in sw.coords and dim in lw.coords
                    and not np.array_equal(sw[dim].values, lw[dim].values)):
                raise ValueError(f"broadband_total: {name}: the coordinate {dim} differs between "
                                 "the shortwave and the longwave run")
        if a.shape != b.shape:
            raise ValueError(f"broadband_total: {name} has shape {a.shape} in the shortwave run "
                             f"and {b.shape} in the longwave run")
        total = a + b
        total.attrs = {"long_name": f"{a.attrs.get('long_name', name)}, shortwave + longwave",
                       "units": a.attrs.get("units", "")}
        err = np.sqrt(stderr(sw, name) ** 2 + stderr(lw, name) ** 2)
        err.attrs = {"long_name": f"standard error of {total.attrs.get('long_name', name)}",
                     "units": a.attrs.get("units", "")}
        total.attrs["ancillary_variables"] = name + STDERR_SUFFIX
        out[name] = total
        out[name + STDERR_SUFFIX] = err
    if not out.data_vars:
        raise ValueError("broadband_total: the two runs share no product to add")
    return out
