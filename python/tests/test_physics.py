# SPDX-License-Identifier: BSD-3-Clause
"""Runs of the real kumo program through the package, against answers known exactly.

Each Monte Carlo estimate must lie within K_SIGMA of its own standard error from the exact
value (plus round-off where kumo's estimate is exact in every batch).
"""

import re
import warnings

import numpy as np
import pytest
import xarray as xr

import kumo
from cases import assert_within, small_case


def test_transparent_atmosphere_over_lambert_surface(exe, tmp_path):
    """No extinction: every photon reaches the surface and what it reflects leaves at the top,
    so R = albedo, T = 1 and the surface absorbs 1 - albedo, at any sun angle."""
    albedo = 0.3
    ds = kumo.run(small_case(surface={"albedo": albedo}, source={"sza_deg": 40.0}), tmp_path,
                  exe=exe)
    assert isinstance(ds, xr.Dataset)
    for name, exact in (("reflectance", albedo), ("transmittance", 1.0),
                        ("absorptance_surface", 1.0 - albedo), ("absorptance_atmosphere", 0.0)):
        mean, err = kumo.value(ds, name)
        assert_within(mean, exact, err, name)
    assert ds["reflectance"].attrs["ancillary_variables"] == "reflectance_stderr"
    assert "kumo_log" in ds.attrs


def test_pure_absorber_beer_lambert(exe, tmp_path):
    """A purely absorbing layer of optical depth tau over a black surface: the direct beam
    transmittance is exp(-tau/mu0) (Beer-Lambert), nothing is reflected or scattered."""
    tau, sza = 0.7, 60.0
    mu0 = np.cos(np.radians(sza))
    case = small_case(atmosphere={"nz": 1, "z_levels": [0.0, 1000.0], "ext1d": [[tau / 1000.0]],
                                  "ssa1d": [[0.0]]},
                      source={"sza_deg": sza})
    ds = kumo.run(case, tmp_path, exe=exe)
    exact = np.exp(-tau / mu0)
    for name, value in (("transmittance", exact), ("transmittance_direct", exact),
                        ("transmittance_diffuse", 0.0), ("reflectance", 0.0),
                        ("absorptance_atmosphere", 1.0 - exact)):
        mean, err = kumo.value(ds, name)
        assert_within(mean, value, err, name)
    flux, err = kumo.value(ds, "flux_down_direct")          # per level, bottom first
    assert_within(flux.values, [exact, 1.0], err.values, "flux_down_direct")


def test_scene_file_columns_beer_lambert(exe, tmp_path):
    """A 3-D region of purely absorbing columns, sun at the zenith: each column's direct
    transmittance at the surface is exp(-ext * dz) of that column. Extinctions differ along x
    and along y, so a transposed or mirrored scene file fails. The scene is given as an xarray
    DataArray in (x, y, z) order, which write_scene must transpose."""
    nx, ny, dz = 3, 2, 500.0
    tau = np.array([[0.1, 0.4, 0.8],             # tau[y, x]
                    [1.2, 0.0, 2.0]])
    ext = xr.DataArray((tau / dz).T[:, :, np.newaxis], dims=("x", "y", "z"))
    kumo.write_scene(tmp_path / "scene.nc", ext, xr.zeros_like(ext))
    case = small_case(atmosphere={"nz": 1, "z_levels": [0.0, dz], "lx": 3000.0, "ly": 2000.0,
                                  "scene_file": "scene.nc", "k3d_bottom": 1, "nx": nx, "ny": ny,
                                  "nz3": 1})
    ds = kumo.run(case, tmp_path, exe=exe)
    level_dim = ds["flux_down_direct_map"].dims[0]
    surface = ds["flux_down_direct_map"].isel({level_dim: 0})        # (y, x)
    err = ds["flux_down_direct_map_stderr"].isel({level_dim: 0})
    assert surface.shape == (ny, nx)
    assert_within(surface.values, np.exp(-tau), err.values, "direct transmittance per column")
    # the coordinates are the column centres
    assert np.allclose(ds["x"].values, [500.0, 1500.0, 2500.0])
    assert np.allclose(ds["y"].values, [500.0, 1500.0])


def test_albedo_map_per_column(exe, tmp_path):
    """Transparent 3-D region over an albedo map on the same 3 x 2 grid, sun at the zenith:
    the upward flux leaving the surface in each column is that pixel's albedo."""
    albedo = np.array([[0.1, 0.5, 0.9],            # albedo[ys, xs]
                       [0.0, 0.3, 0.7]])
    kumo.write_albedo_map(tmp_path / "albedo.nc", albedo)
    kumo.write_scene(tmp_path / "scene.nc", np.zeros((2, 2, 3)), np.ones((2, 2, 3)))   # (z, y, x)
    case = small_case(atmosphere={"nz": 2, "z_levels": [0.0, 500.0, 1000.0], "lx": 3000.0,
                                  "ly": 2000.0, "scene_file": "scene.nc", "k3d_bottom": 1,
                                  "nx": 3, "ny": 2, "nz3": 2},
                      surface={"albedo_file": "albedo.nc"})
    ds = kumo.run(case, tmp_path, exe=exe)
    level_dim = ds["flux_up_map"].dims[0]
    up, err = (ds[name].isel({level_dim: 0}).values
               for name in ("flux_up_map", "flux_up_map_stderr"))
    assert_within(up, albedo, err, "upward flux at the surface per column")
    mean, err = kumo.value(ds, "reflectance")
    assert_within(mean, albedo.mean(), err, "reflectance")


def test_errors_carry_kumos_message(exe, tmp_path):
    with pytest.raises(kumo.KumoError, match=r"n_batches = 1 must be >= 2") as info:
        kumo.run(small_case(control={"n_batches": 1}), tmp_path, exe=exe)
    assert info.value.returncode == 1
    assert "STOP" not in info.value.stderr
    # --check lists every unreadable input file
    case = small_case(atmosphere={"nz": 1, "z_levels": [0.0, 1000.0], "scene_file": "none.nc",
                                  "k3d_bottom": 1, "nx": 2, "ny": 2, "nz3": 1},
                      phase={"n_phase": 1, "phase_kind": ["table"], "phase_file": ["none.txt"]})
    with pytest.raises(kumo.KumoError, match=r"(?s)2 problems.*none.txt: no such file.*"
                                             r"none.nc: no such file"):
        kumo.check(case, tmp_path, exe=exe)
    with pytest.raises(kumo.KumoError, match="not an executable file"):
        kumo.run(small_case(), tmp_path, exe=tmp_path / "no_kumo")


def test_warnings_reach_python(exe, tmp_path):
    """kumo's warnings (its standard error and the output's warnings attribute) are issued as
    KumoWarning: a run of 4 batches warns that its error bars are uncertain; 10 do not."""
    with pytest.warns(kumo.KumoWarning, match=r"standard errors rest on 4 batches") as record:
        ds = kumo.run(small_case(control={"n_photons_per_batch": 500, "n_batches": 4}),
                      tmp_path / "four", exe=exe)
    assert str(record[0].message) in ds.attrs["warnings"]
    assert record[0].filename == __file__          # reported where the caller called run
    with warnings.catch_warnings():
        warnings.simplefilter("error", kumo.KumoWarning)
        ds = kumo.run(small_case(control={"n_photons_per_batch": 200, "n_batches": 10}),
                      tmp_path / "ten", exe=exe)
    assert "warnings" not in ds.attrs


def test_progress_lines_reach_python(exe, tmp_path, capsys):
    """kumo's progress lines come while it runs, from inside a batch too: to the callable given
    as ``progress``, and not at all with ``progress=False`` (the test hook
    KUMO_TEST_PROGRESS_MS gives them every 50 ms instead of after 5 s)."""
    case = small_case(control={"n_photons_per_batch": 200000, "n_batches": 2, "seed": 3,
                               "verbose": 1},
                      atmosphere={"nz": 1, "z_levels": [0.0, 1000.0], "ext1d": [[0.01]],
                                  "ssa1d": [[1.0]]})
    lines = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", kumo.KumoWarning)     # 2 batches: a warning
        done = kumo.run_kumo(case, tmp_path / "callback", exe=exe, progress=lines.append,
                             env={"KUMO_TEST_PROGRESS_MS": "50"})
        assert any(re.match(r"kumo: 0\.[1-9] of 2 batches \(\d+ %\)", line) for line in lines), lines
        assert all(line in done.stderr for line in lines)
        kumo.run_kumo(case, tmp_path / "quiet", exe=exe, progress=False,
                      env={"KUMO_TEST_PROGRESS_MS": "50"})
    assert "batches" not in capsys.readouterr().err


def test_warning_lines():
    """kumo_warnings takes every warning line of a log and nothing else."""
    log = ("kumo: warning: first one\nkumo: warning: second\nan MPI notice\n"
           "kumo error: not a warning\n")
    assert kumo.kumo_warnings(log) == ["first one", "second"]


def test_mpi_run_matches_serial(exe, tmp_path):
    """Two MPI ranks trace the same batches as one process: identical per-batch values."""
    if kumo.version_info(exe).get("parallel") != "MPI":
        pytest.skip("serial build of kumo: no MPI runs")
    case = small_case(surface={"albedo": 0.2},
                      atmosphere={"nz": 1, "z_levels": [0.0, 1000.0], "ext1d": [[5e-4]],
                                  "ssa1d": [[0.9]]})
    one = kumo.run(case, tmp_path / "np1", exe=exe)
    two = kumo.run(case, tmp_path / "np2", exe=exe, np=2)
    assert int(float(two.attrs["n_ranks"])) == 2
    for name in ("batch_reflectance", "batch_transmittance", "batch_absorptance"):
        assert np.array_equal(one[name].values, two[name].values), name


def test_map_levels_choose_the_map_levels(exe, tmp_path):
    """map_levels writes the per-column flux maps at levels of its own, on a dimension of their
    own: the same numbers as the maps of a run with maps at every level (the maps draw no
    random numbers, so both runs trace the same photons), and the same domain fluxes."""
    ext = np.zeros((3, 2, 3))                              # (z, y, x) [m-1]
    ext[1] = [[2e-3, 0.0, 8e-3], [4e-3, 1e-3, 0.0]]        # a broken layer in the middle
    kumo.write_scene(tmp_path / "scene.nc", ext, np.full_like(ext, 0.95))
    atmosphere = {"nz": 3, "z_levels": [0.0, 500.0, 1000.0, 1500.0], "lx": 3000.0,
                  "ly": 2000.0, "scene_file": str(tmp_path / "scene.nc"), "k3d_bottom": 1,
                  "nx": 3, "ny": 2, "nz3": 3}
    every = kumo.run(small_case(atmosphere=atmosphere, source={"sza_deg": 30.0}),
                     tmp_path / "every", exe=exe)
    some = kumo.run(small_case(atmosphere=atmosphere, source={"sza_deg": 30.0},
                               output={"file": "out.nc", "map_levels": [0, 3]}),
                    tmp_path / "some", exe=exe)
    assert every["flux_up_map"].dims[0] == "level"
    assert some["flux_up_map"].dims == ("map_level", "y", "x")
    assert np.array_equal(some["map_level"].values, [0.0, 1500.0])
    for name in ("flux_up_map", "flux_down_map", "flux_down_direct_map", "flux_down_diffuse_map"):
        for var in (name, name + "_stderr"):
            assert np.array_equal(some[var].values, every[var].isel(level=[0, 3]).values), var
    for name in ("flux_up", "flux_down", "reflectance", "absorptance_atmosphere"):
        assert np.array_equal(some[name].values, every[name].values), name
    # the column budget of the 3-D region needs maps at its bottom and top, which 0 and 3 are
    assert np.array_equal(some["horizontal_transport_map"].values,
                          every["horizontal_transport_map"].values)
