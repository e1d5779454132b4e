# SPDX-License-Identifier: BSD-3-Clause
"""Input writers (values checked before writing; kumo reads what they write) and the
quick-look plots."""

import numpy as np
import pytest
import xarray as xr

import kumo
from kumo.quicklook import main as quicklook_main
from cases import small_case


def test_writers_reject_what_kumo_rejects(tmp_path):
    with pytest.raises(ValueError, match=r"ssa: value 1.5 at index \(0, 0, 1, 0\) must be <= 1"):
        kumo.write_scene(tmp_path / "s.nc", np.ones((1, 1, 2, 1)), [[[[0.5], [1.5]]]])
    with pytest.raises(ValueError, match="extinction: value nan"):
        kumo.write_scene(tmp_path / "s.nc", np.full((1, 1, 1), np.nan), np.ones((1, 1, 1)))
    with pytest.raises(ValueError, match="ext_units"):
        kumo.write_scene(tmp_path / "s.nc", np.ones((1, 1, 1)), np.ones((1, 1, 1)),
                         ext_units="1/km")
    with pytest.raises(ValueError, match=r"phase_index: value 0 .* must be >= 1"):
        kumo.write_scene(tmp_path / "s.nc", np.ones((1, 1, 1)), np.ones((1, 1, 1)),
                         phase_index=np.zeros((1, 1, 1), dtype=int))
    with pytest.raises(ValueError, match="must be <= 1"):
        kumo.write_albedo_map(tmp_path / "a.nc", [[0.5, 1.2]])
    with pytest.raises(ValueError, match="z_edges must increase"):
        kumo.write_cloud(tmp_path / "c.nc", np.zeros((2, 1, 1)), np.zeros((2, 1, 1)),
                         [0.0, 300.0, 200.0], 100.0, 100.0)
    with pytest.raises(ValueError, match=r"dimensions \('a', 'b'\)"):
        kumo.write_albedo_map(tmp_path / "a.nc", xr.DataArray([[0.5]], dims=("a", "b")))


def test_cloud_file_grid(exe, tmp_path):
    """kumo reads the grid of a cloud file written by write_cloud: columns, widths and the
    stretched layer edges, which must then appear among the namelist levels."""
    lwc = np.zeros((3, 2, 4))
    lwc[1] = 0.3
    kumo.write_cloud(tmp_path / "cloud.nc", lwc, np.where(lwc > 0, 10.0, 0.0),
                     [0.0, 200.0, 400.0, 700.0], dx=100.0, dy=50.0)
    case = small_case(atmosphere={"nz": 4, "z_levels": [0.0, 200.0, 400.0, 700.0, 2000.0]},
                      cloud={"cloud_file": "cloud.nc"}, source={"wavelength_um": 0.67})
    echo = kumo.check(case, tmp_path, exe=exe)
    assert "kumo_cloud.grid = 4 x 2 x 3 voxels of 100 x 50 m" in echo
    assert "kumo_atmosphere.lx = 400" in echo and "kumo_atmosphere.ly = 100" in echo
    case["atmosphere"]["z_levels"] = [0.0, 200.0, 450.0, 700.0, 2000.0]
    with pytest.raises(kumo.KumoError, match="cloud file's 4 layer edges"):
        kumo.check(case, tmp_path, exe=exe)


def test_quicklook(exe, tmp_path):
    """The quick look of a 3-D run with radiances and a camera has the flux profiles, the
    column maps, the radiance maps and the camera image, each image with its error panel."""
    rng = np.random.default_rng(3)
    ext = rng.uniform(0.0, 0.01, (1, 2, 3))                        # (z, y, x)
    kumo.write_scene(tmp_path / "scene.nc", ext, np.full_like(ext, 0.99))
    case = small_case(
        atmosphere={"nz": 2, "z_levels": [0.0, 500.0, 1000.0], "scene_file": "scene.nc",
                    "k3d_bottom": 1, "nx": 3, "ny": 2, "nz3": 1, "air_density": [1.2, 1.1]},
        surface={"albedo": 0.1}, source={"sza_deg": 20.0, "solar_flux": 1000.0},
        radiance={"rad_mu": [1.0], "rad_phi_deg": [0.0]},
        camera={"n_cameras": 1, "cam_kind": ["orthographic"], "cam_x": [500.0],
                "cam_y": [500.0], "cam_z": [2000.0], "cam_width": [1000.0], "cam_npx": [6],
                "cam_npy": [4]})
    kumo.run(case, tmp_path, exe=exe)
    fig = kumo.quicklook(tmp_path / "out.nc", tmp_path / "out.png")
    titles = [ax.get_title() for ax in fig.axes]
    for expected in ("fluxes (+-2 s.e.)", "heating_rate_layer (+-2 s.e.)",
                     "radiances (+-2 s.e.)", "flux_up_map (top)", "flux_down_map (surface)",
                     "absorptance_column", "camera1_radiance"):
        assert expected in titles, f"no panel {expected!r} in {titles}"
    assert any(t.startswith("radiance_map") for t in titles)
    n_images = sum(1 for t in titles if t == "relative standard error")
    assert n_images >= 5
    assert (tmp_path / "out.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the command: writes the image, exit status 0; a file that is not kumo output: status 1
    assert quicklook_main([str(tmp_path / "out.nc"), "-o", str(tmp_path / "cmd.png")]) == 0
    assert (tmp_path / "cmd.png").stat().st_size > 0
    xr.Dataset({"a": ("t", [1.0])}).to_netcdf(tmp_path / "other.nc")
    assert quicklook_main([str(tmp_path / "other.nc"), "-o", str(tmp_path / "x.png")]) == 1
