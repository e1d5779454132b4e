# SPDX-License-Identifier: BSD-3-Clause
"""kumo namelist files from Python dictionaries, written with f90nml.

A run is described by a mapping of namelist groups to their variables::

    groups = {
        "control": {"n_photons_per_batch": 10000, "n_batches": 20},
        "atmosphere": {"nz": 2, "z_levels": [0.0, 500.0, 1000.0],
                       "ext1d": np.array([[1e-3], [2e-3]])},   # ext1d(k, ic)
        "surface": {"albedo": 0.2},
    }

Group names may be given with or without the ``kumo_`` prefix. Arrays keep Fortran's index
order: element ``a[i, j]`` of a NumPy array (or nested list) is ``a(i, j)`` in the namelist,
whatever the memory layout, so ``ext1d[k - 1, ic - 1]`` is the extinction of layer k and
component ic. The variables themselves are documented in docs/namelist.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import f90nml
import numpy as np

#: The namelist groups kumo reads, in the order of docs/namelist.md.
GROUPS = ("control", "atmosphere", "cloud", "phase", "surface", "source", "output", "vr",
          "radiance", "camera")


def group_name(name: str) -> str:
    """The full group name (``kumo_control``) of ``control`` or ``kumo_control``."""
    short = name.lower()
    if short.startswith("kumo_"):
        short = short[len("kumo_"):]
    if short not in GROUPS:
        raise ValueError(f"unknown namelist group {name!r}; kumo reads "
                         + ", ".join(GROUPS) + " (with or without the kumo_ prefix)")
    return "kumo_" + short


def _fortran_value(value):
    """A value in the form f90nml writes: native Python types, arrays in Fortran order."""
    if hasattr(value, "values") and hasattr(value, "dims"):   # xarray.DataArray
        value = value.values
    if isinstance(value, (str, bytes, bool)) or value is None:
        return value.decode() if isinstance(value, bytes) else value
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (list, tuple, np.ndarray)):
        array = np.asarray(value)
        if array.dtype == object:
            return [_fortran_value(v) for v in value]
        if array.ndim <= 1:
            return array.tolist() if array.ndim == 1 else array.item()
        # f90nml's nested lists run over the first Fortran index innermost: reverse the axes
        return array.transpose().tolist()
    return value


def to_namelist(groups: Mapping[str, Mapping]) -> f90nml.Namelist:
    """An f90nml Namelist of kumo's groups from a mapping of group name -> variables."""
    nml = f90nml.Namelist()
    for name, variables in groups.items():
        full = group_name(name)
        if full in nml:
            raise ValueError(f"namelist group {full} given twice")
        if variables is None:
            variables = {}
        nml[full] = f90nml.Namelist({key.lower(): _fortran_value(value)
                                     for key, value in variables.items()})
    if "kumo_atmosphere" not in nml and "kumo_cloud" not in nml:
        raise ValueError("the namelist group 'atmosphere' (kumo_atmosphere) is required "
                         "(it may be left out only with a cloud file, group 'cloud')")
    return nml


def write_namelist(groups: Mapping[str, Mapping], path) -> Path:
    """Write the groups as a kumo namelist file at ``path`` (replaced if it exists; missing
    folders are created)."""
    path = Path(path)
    nml = to_namelist(groups)
    path.parent.mkdir(parents=True, exist_ok=True)
    nml.write(path, force=True)
    return path


def read_namelist(path) -> dict:
    """Read a kumo namelist file into a dict of group name (without the prefix) -> variables.

    Arrays come back as f90nml gives them (nested lists, first Fortran index innermost); use
    ``numpy.asarray(v).T`` to index them as ``a[i, j]`` = ``a(i, j)``.
    """
    nml = f90nml.read(str(path))
    return {name[len("kumo_"):] if name.startswith("kumo_") else name: dict(group)
            for name, group in nml.items()}
