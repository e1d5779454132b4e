# SPDX-License-Identifier: BSD-3-Clause
"""kumo's output against the CF conventions (CF-1.8), checked offline by the IOOS compliance
checker, and the CF features users select and plot with: numeric attributes, auxiliary
direction coordinates without repeated values, the wavelength as a scalar coordinate, the
standard errors linked as ancillary variables."""

import json

import numpy as np
import pytest

import kumo
from cases import small_case

from compliance_checker.runner import CheckSuite, ComplianceChecker  # scripts/install-deps.sh --python


def cf_case(tmp_path):
    """A small 3-D cloud with column maps and voxel outputs, radiances in four directions that
    share mu (two azimuths each), a camera, fluxes in W m-2 and a wavelength."""
    ext = np.zeros((2, 2, 3))
    ext[0] = [[0.01, 0.02, 0.0], [0.01, 0.03, 0.0]]
    ext[1] = [[0.002, 0.0, 0.015], [0.0, 0.005, 0.02]]
    kumo.write_scene(tmp_path / "scene.nc", ext, np.full_like(ext, 0.99))
    return small_case(
        atmosphere={"nz": 3, "z_levels": [0.0, 200.0, 700.0, 1200.0], "lx": 600.0, "ly": 400.0,
                    "scene_file": "scene.nc", "k3d_bottom": 2, "nz3": 2, "nx": 3, "ny": 2},
        phase={"n_phase": 1, "phase_kind": "hg", "phase_g": 0.7},
        surface={"albedo": 0.2},
        source={"sza_deg": 40.0, "solar_flux": 1000.0, "wavelength_um": 0.67},
        radiance={"rad_mu": [1.0, 0.5, 0.5, -0.5], "rad_phi_deg": [0.0, 0.0, 180.0, 0.0]},
        camera={"n_cameras": 1, "cam_z": 3000.0, "cam_fov_deg": 20.0, "cam_npx": 4,
                "cam_npy": 3},
        output={"file": "cf.nc"})


def test_output_passes_cf_checker(exe, tmp_path):
    """Every high-priority (required) CF-1.8 check passes on a file with every kind of product;
    the checker's medium-priority advice (the T, Z, Y, X order it recommends for dimensions
    ahead of kumo's direction dimension) is not counted."""
    kumo.run(cf_case(tmp_path), tmp_path, exe=exe)
    CheckSuite.load_all_available_checkers()
    report = tmp_path / "cf_report.json"
    _, errors = ComplianceChecker.run_checker(
        str(tmp_path / "cf.nc"), ["cf:1.8"], verbose=0, criteria="lenient",
        output_filename=str(report), output_format="json")
    assert not errors, "the compliance checker failed to run"
    result = json.loads(report.read_text())["cf:1.8"]
    failed = [check for check in result["high_priorities"] if check["msgs"]]
    assert result["high_count"] == 0 and not failed, \
        f"required CF-1.8 checks failed: {json.dumps(failed, indent=1)[:4000]}"
    assert result["scored_points"] > 0


def test_cf_features_in_xarray(exe, tmp_path):
    ds = kumo.run(cf_case(tmp_path), tmp_path, exe=exe)
    # numbers are numbers
    assert ds.attrs["n_photons"] * 2 == 2 * 2000 * 10
    assert isinstance(ds.attrs["solar_zenith_angle_deg"], (float, np.floating))
    # directions: numbered, mu and phi as auxiliary coordinates, no repeated coordinate values
    rad = ds["radiance"]
    assert "direction_mu" in rad.coords and "direction_phi" in rad.coords
    assert list(rad["direction_mu"].values) == [1.0, 0.5, 0.5, -0.5]
    one = rad.where((rad.direction_mu == 0.5) & (rad.direction_phi == 180.0), drop=True)
    assert one.sizes["direction"] == 1
    # the wavelength is a scalar coordinate of every result
    assert float(ds["reflectance"].coords["wavelength"]) == pytest.approx(0.67)
    # standard errors are linked, with the CF modifier where there is a standard name
    assert ds["flux_up_wm2"].attrs["standard_name"] == "upwelling_shortwave_flux_in_air"
    assert ds["flux_up_wm2"].attrs["ancillary_variables"] == "flux_up_wm2_stderr"
    assert ds["flux_up_wm2_stderr"].attrs["standard_name"] == \
        "upwelling_shortwave_flux_in_air standard_error"
    assert ds["level"].attrs["standard_name"] == "height"
    # camera pixels have coordinates
    assert list(ds["camera1_x"].values) == [1, 2, 3, 4]
