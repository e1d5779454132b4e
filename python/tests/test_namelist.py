# SPDX-License-Identifier: BSD-3-Clause
"""Namelists from dicts: group names, array orientation, and kumo reading them as meant."""

import f90nml
import numpy as np
import pytest

import kumo
from cases import small_case


def test_group_names():
    assert kumo.namelist.group_name("control") == "kumo_control"
    assert kumo.namelist.group_name("KUMO_Surface") == "kumo_surface"
    with pytest.raises(ValueError, match="unknown namelist group 'sun'"):
        kumo.namelist.group_name("sun")
    with pytest.raises(ValueError, match="is required"):
        kumo.to_namelist({"control": {"seed": 1}})
    # with a cloud file the levels may come from the file alone (docs/namelist.md)
    nml = kumo.to_namelist({"cloud": {"cloud_file": "les.nc"}})
    assert "kumo_atmosphere" not in nml and nml["kumo_cloud"]["cloud_file"] == "les.nc"


def test_array_index_order(tmp_path):
    # ext1d[k, ic] of the NumPy array is ext1d(k+1, ic+1) in the file
    ext = np.array([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0]])      # 3 layers, 2 components
    path = kumo.write_namelist({"atmosphere": {"nz": 3, "ext1d": ext, "flag": np.bool_(True),
                                               "n": np.int64(4)}}, tmp_path / "a.nml")
    group = f90nml.read(str(path))["kumo_atmosphere"]
    assert group["ext1d"] == [[1.0, 2.0, 3.0], [10.0, 20.0, 30.0]]   # f90nml: (:, ic) lists
    assert group["flag"] is True and group["n"] == 4
    back = kumo.read_namelist(path)["atmosphere"]
    assert np.array_equal(np.asarray(back["ext1d"]).T, ext)


def test_kumo_reads_the_arrays_as_written(exe, tmp_path):
    """kumo --check echoes the namelist as it understood it: layer 2 of component 1 and
    layer 1 of component 2 must come out where the NumPy indices put them."""
    ext = np.array([[1e-4, 5e-4], [2e-4, 6e-4]])
    ssa = np.array([[1.0, 0.5], [0.9, 0.25]])
    case = small_case(atmosphere={"nz": 2, "z_levels": [0.0, 500.0, 1000.0], "n_components": 2,
                                  "ext1d": ext, "ssa1d": ssa},
                      surface={"albedo": 0.25}, source={"sza_deg": 30.0})
    echo = kumo.check(case, tmp_path, exe=exe)
    assert "kumo_atmosphere.ext1d(:,1) = 0.0001, 0.0002" in echo
    assert "kumo_atmosphere.ext1d(:,2) = 0.0005, 0.0006" in echo
    assert "kumo_atmosphere.ssa1d(:,2) = 0.5, 0.25" in echo
    assert "kumo_surface.albedo = 0.25" in echo
    # the scene set up: (1e-4 + 5e-4) * 500 m + (2e-4 + 6e-4) * 500 m
    assert "vertical optical depth: 0.7\n" in echo
    assert not (tmp_path / "out.nc").exists()      # --check runs nothing
