# SPDX-License-Identifier: BSD-3-Clause
"""Input files of kumo from NumPy or xarray arrays.

Arrays are in the order NumPy, netCDF4 and ``ncdump`` use (slowest index first):
``(component, z, y, x)`` for scene files, ``(ys, xs)`` for surface maps, ``(z, y, x)`` for
cloud fields; ``z`` runs from the bottom up. An xarray DataArray whose dimensions carry these
names is transposed to that order first. The formats are specified in docs/input-netcdf.md
(scene, albedo map) and docs/les-input.md (cloud fields).

Every writer checks the values with the rules kumo applies when it reads them, so a file
written here is not rejected for its values. Missing folders of the path are created.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from netCDF4 import Dataset


def _array(value, dims, name):
    """A float or int array with the dimensions ``dims`` (ncdump order)."""
    if hasattr(value, "dims") and hasattr(value, "transpose"):   # xarray.DataArray
        if set(value.dims) == set(dims):
            value = value.transpose(*dims)
        elif len(value.dims) == len(dims) and set(value.dims) != set(dims):
            raise ValueError(f"{name}: dimensions {value.dims} are not {dims} (in any order)")
        value = value.values
    array = np.asarray(value)
    if array.ndim != len(dims):
        raise ValueError(f"{name}: {array.ndim}-D array, expected {len(dims)}-D {dims}")
    return array


def _new_file(path) -> Path:
    """``path`` as a Path, its folder created if missing."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _check_range(array, name, low=None, high=None):
    if not np.all(np.isfinite(array)):
        index = tuple(int(i) for i in np.argwhere(~np.isfinite(array))[0])
        raise ValueError(f"{name}: value {array[index]} at index {index} is not finite")
    if low is not None and np.any(array < low):
        index = tuple(int(i) for i in np.argwhere(array < low)[0])
        raise ValueError(f"{name}: value {array[index]} at index {index} must be >= {low}")
    if high is not None and np.any(array > high):
        index = tuple(int(i) for i in np.argwhere(array > high)[0])
        raise ValueError(f"{name}: value {array[index]} at index {index} must be <= {high}")


def write_scene(path, extinction, ssa, phase_index=None, ext_units: str = "m-1") -> Path:
    """Write the optical properties of the 3-D region (``&kumo_atmosphere scene_file``).

    ``extinction``, ``ssa`` and the optional ``phase_index`` (1-based indices into
    ``&kumo_phase``) are ``(component, z, y, x)`` arrays, or ``(z, y, x)`` for one component.
    ``ext_units`` is ``"m-1"`` or ``"km-1"``. The namelist must give the same sizes (``nx``,
    ``ny``, ``nz3``, ``n_components_3d``). Returns the path.
    """
    if ext_units not in ("m-1", "km-1"):
        raise ValueError(f"ext_units = {ext_units!r}: kumo reads 'm-1' or 'km-1'")
    dims = ("component", "z", "y", "x")

    def four_d(value, name):
        ndim = value.ndim if hasattr(value, "ndim") else np.ndim(value)
        if ndim == 3:
            if hasattr(value, "dims"):
                value = value.expand_dims("component")
            else:
                value = np.asarray(value)[np.newaxis]
        return _array(value, dims, name)

    ext = four_d(extinction, "extinction").astype(float)
    alb = four_d(ssa, "ssa").astype(float)
    if alb.shape != ext.shape:
        raise ValueError(f"ssa has shape {alb.shape}, extinction {ext.shape}")
    _check_range(ext, "extinction", low=0.0)
    _check_range(alb, "ssa", low=0.0, high=1.0)
    iph = None
    if phase_index is not None:
        iph = four_d(phase_index, "phase_index")
        if iph.shape != ext.shape:
            raise ValueError(f"phase_index has shape {iph.shape}, extinction {ext.shape}")
        if not np.issubdtype(iph.dtype, np.integer):
            if not np.all(iph == np.round(iph)):
                raise ValueError("phase_index: values must be whole numbers")
            iph = np.round(iph)
        _check_range(iph, "phase_index", low=1)
        iph = iph.astype(np.int32)

    path = _new_file(path)
    with Dataset(path, "w", format="NETCDF4_CLASSIC") as nc:
        for name, size in zip(dims, ext.shape):
            nc.createDimension(name, size)
        v = nc.createVariable("extinction", "f8", dims)
        v.long_name = "volume extinction coefficient"
        v.units = ext_units
        v[:] = ext
        v = nc.createVariable("ssa", "f8", dims)
        v.long_name = "single-scattering albedo"
        v.units = "1"
        v[:] = alb
        if iph is not None:
            v = nc.createVariable("phase_index", "i4", dims)
            v.long_name = "index of the phase function in the namelist list (1-based)"
            v[:] = iph
        nc.Conventions = "CF-1.8"
        nc.title = "kumo 3-D scene optical properties"
    return path


def write_albedo_map(path, albedo, var: str = "albedo") -> Path:
    """Write a Lambert albedo map ``albedo(ys, xs)`` (``&kumo_surface albedo_file``).

    The pixels divide the periodic domain evenly, independent of the atmosphere's columns.
    ``var`` is the variable name (``&kumo_surface albedo_var``). Returns the path.
    """
    alb = _array(albedo, ("ys", "xs"), var).astype(float)
    _check_range(alb, var, low=0.0, high=1.0)
    path = _new_file(path)
    with Dataset(path, "w", format="NETCDF4_CLASSIC") as nc:
        nc.createDimension("xs", alb.shape[1])
        nc.createDimension("ys", alb.shape[0])
        v = nc.createVariable(var, "f8", ("ys", "xs"))
        v.long_name = "surface albedo"
        v.units = "1"
        v[:] = alb
        nc.Conventions = "CF-1.8"
        nc.title = "kumo surface albedo map"
    return path


def write_cloud(path, lwc, reff, z_edges, dx: float, dy: float) -> Path:
    """Write a liquid-water cloud field in the LES layout kumo reads (``&kumo_cloud``).

    ``lwc`` [g m-3] and ``reff`` [um] are ``(z, y, x)`` arrays; ``z_edges`` [m] are the nz + 1
    layer edges, bottom first and increasing (they may be stretched); ``dx``, ``dy`` [m] are the
    column widths. kumo computes the droplet optics at ``&kumo_source wavelength_um``
    (docs/mie.md); the namelist needs ``&kumo_cloud cloud_file = path`` (format ``les``, the
    default). Returns the path.
    """
    dims = ("z", "y", "x")
    water = _array(lwc, dims, "lwc").astype(float)
    radius = _array(reff, dims, "reff").astype(float)
    if radius.shape != water.shape:
        raise ValueError(f"reff has shape {radius.shape}, lwc {water.shape}")
    _check_range(water, "lwc", low=0.0)
    _check_range(radius, "reff", low=0.0)
    edges = np.asarray(z_edges, dtype=float)
    nz, ny, nx = water.shape
    if edges.shape != (nz + 1,):
        raise ValueError(f"z_edges: {edges.size} values, expected nz + 1 = {nz + 1}")
    if np.any(np.diff(edges) <= 0):
        raise ValueError("z_edges must increase strictly (bottom first)")
    if not (dx > 0 and dy > 0):
        raise ValueError(f"dx = {dx}, dy = {dy}: column widths must be > 0")

    path = _new_file(path)
    with Dataset(path, "w", format="NETCDF4_CLASSIC") as nc:
        nc.createDimension("x", nx)
        nc.createDimension("y", ny)
        nc.createDimension("z", nz)
        nc.createDimension("x_edges", nx + 1)
        nc.createDimension("y_edges", ny + 1)
        nc.createDimension("z_edges", nz + 1)
        for axis, n, step in (("x", nx, dx), ("y", ny, dy)):
            v = nc.createVariable(axis, "f8", (axis,))
            v.units = "m"
            v[:] = (np.arange(n) + 0.5) * step
            v = nc.createVariable(axis + "_edges", "f8", (axis + "_edges",))
            v.units = "m"
            v[:] = np.arange(n + 1) * step
        v = nc.createVariable("z", "f8", ("z",))
        v.units = "m"
        v[:] = 0.5 * (edges[1:] + edges[:-1])
        v = nc.createVariable("z_edges", "f8", ("z_edges",))
        v.units = "m"
        v[:] = edges
        v = nc.createVariable("lwc", "f8", dims)
        v.long_name = "liquid water content"
        v.units = "g m-3"
        v[:] = water
        v = nc.createVariable("reff", "f8", dims)
        v.long_name = "droplet effective radius"
        v.units = "um"
        v[:] = radius
        nc.Conventions = "CF-1.8"
        nc.title = "cloud field for kumo"
    return path
