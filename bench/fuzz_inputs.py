#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Random valid cases: kumo must end every one cleanly and give numbers that hold together.

Each case is a namelist drawn at random within the documented ranges, many of them at their
edges: 1 to 5 layers of 1 m to 5 km, optical depths from 0 to 1000 per layer, albedos 0 and 1,
Henyey-Greenstein g from -0.99 to 0.9999, the sun from the zenith to 89.99 degrees, a 3-D
region from a scene file (extinction 0 to 50 m-1) or none, thermal emission with or without
the sun, Lambert or RPV surfaces, radiances, a camera, every preset and 3-D mode. For each case:

* the run ends with status 0, or with status 1 and one ``kumo error:`` message (no crash, no
  STOP line, and not the output writer refusing a number that is not finite); a run beyond
  ``--timeout`` seconds is listed with the warnings kumo gave for it;
* every output variable is finite, the energy closure is 1 to 1e-9, and (runs of 10 batches
  or more) the reflectance and absorptances lie in [0, 1] within 5 standard errors (the
  transmittance counts light that a
  reflecting surface sends up and the atmosphere back down, so it may exceed 1);
* no upward or downward flux is negative (they count the positive weights that cross a level);
* weight lost at a loop cap comes with a warning on standard error;
* with ``--mpi N``, the run on N ranks gives the same results to 1e-9 relative (the sums over
  ranks are added in another order); a standard error, formed from the sums of x and x^2,
  within the rounding of those sums as well (1e-15 mean^2 / stderr).

    python3 bench/fuzz_inputs.py --kumo build/kumo --cases 300 --seed 1 [--mpi 2] [--mode M]

``--mode`` chooses what the cases draw (``layers``, the above, by default):

* ``clouds`` (or ``--clouds``): LES cloud files (liquid water 0 to 3 g m-3, effective radii 0 to
  60 um, inside and outside the Mie tables) at wavelengths from 0.55 to 10.8 um;
* ``broadband``: &kumo_spectral runs, shortwave and longwave (RRTMGP g112, g128, now and then
  g224, g256; ``scripts/fetch-rrtmgp.sh`` fetches them), over 1-5 layers up to 86 km and
  beyond: the U.S. Standard profile or a sounding (50 to 1200 hPa at the ground, 160 to 400 K,
  layer pressures at their levels), water vapour and ozone 0 to 1 mol/mol, CO2 0 to 1e-2, TSI
  1e-3 to 1e4 W m-2, floor shares 0 to 0.9, one g-point alone; gray layers, a scene file of
  gray voxels or an LES cloud file (liquid and ice, RRTMGP optics, the file's temperature,
  pressure and water vapour); uniform, mapped or DSM surfaces; radiances in 1-3 directions
  and a pinhole or orthographic camera now and then;
* ``maps``: the layers above over an albedo map or a BRDF map (1-7 x 1-5 pixels of every kind,
  black, Lambert, DSM, RPV, LSRT, each pixel's parameters at the edges of their ranges, a
  wind speed for the slope variance, the other kinds' values missing or out of range), and in
  thermal runs a surface temperature map at times;
* ``dsm``: the layers above over a uniform diffuse-specular mixture (ocean) surface: diffuse
  albedo and fraction 0 to 1, refractive index 1 to 100 + 0 to 100 i, slope variance 1e-6 to
  100 or a wind speed of 0 to 50 m s-1;
* ``thermal-clouds``: &kumo_thermal over LES cloud files (kumo's Mie optics at 3.7 to 12 um), a
  band or the wavelength alone, level temperatures 0 to 330 K, voxel temperatures from the file
  (temperature, or potential temperature and pressure) or the levels, a surface temperature
  or its map, a top radiance, emission floors 0 to 0.99, with or without the sun.

Broadband shortwave batches let in the share of mu0 TSI that their g-points carry: all of it
when every g-point with solar energy has an expected photon (n >= n_gpt / floor_share), else
all of it in expectation (checked within 5 standard errors), and a g-point's own share with
``gpoint``; the energy closure is relative to that share (the downward flux at the top), so it
is 1 to 1e-9 as in every other run.

Needs numpy and netCDF4. The cases and outputs stay in ``--workdir`` (default
``fuzz_runs/``); the last line counts the cases that failed a check. Results: docs/verification.md.
"""
import argparse
import os
import random
import re
import subprocess
import sys

import netCDF4
import numpy as np


def fmt(x):
    return repr(float(x))


def draw_case(rng, surface=None):
    """A namelist text and its input files ({name: (writer, data)}). ``surface(rng, lx, ly,
    thermal)``, if given, draws the ``&kumo_surface`` line and its files instead of a uniform
    Lambert or RPV surface, and may return a ``t_surface`` or ``t_surface_file`` setting."""
    nz = rng.randint(1, 5)
    dz = [rng.choice([1.0, 10.0, 100.0, 1000.0, 5000.0]) for _ in range(nz)]
    z = [0.0]
    for d in dz:
        z.append(z[-1] + d)
    lines = [f"&kumo_control n_photons_per_batch = {rng.choice([50, 200, 1000])}, "
             f"n_batches = {rng.choice([2, 3, 10])}, seed = {rng.randint(1, 99)}, "
             f"mode_3d = '{rng.choice(['f3d', 'ica', 'p3d'])}' /"]
    nph = rng.randint(1, 3)
    kinds = [rng.choice(["hg", "isotropic", "rayleigh"]) for _ in range(nph)]
    gs = [rng.choice([-0.99, -0.5, 0.0, 0.5, 0.85, 0.99, 0.9999]) for _ in range(nph)]
    lines.append(f"&kumo_phase n_phase = {nph}, phase_kind = "
                 + ", ".join(f"'{k}'" for k in kinds)
                 + ", phase_g = " + ", ".join(fmt(g) for g in gs) + " /")
    ncomp = rng.randint(1, 2)
    lx = rng.choice([1.0, 100.0, 1000.0, 1e5])
    atm = [f"nz = {nz}", "z_levels = " + ", ".join(fmt(v) for v in z),
           f"n_components = {ncomp}", f"lx = {fmt(lx)}",
           f"ly = {fmt(lx * rng.choice([1.0, 0.5, 2.0]))}"]
    for k in range(1, nz + 1):
        for c in range(1, ncomp + 1):
            tau = rng.choice([0.0, 1e-8, 1e-3, 0.1, 1.0, 10.0, 100.0, 1000.0])
            atm += [f"ext1d({k},{c}) = {fmt(tau / dz[k - 1])}",
                    f"ssa1d({k},{c}) = {fmt(rng.choice([0.0, 0.3, 0.9, 0.999999, 1.0]))}",
                    f"phase1d({k},{c}) = {rng.randint(1, nph)}"]
    files = {}
    if rng.random() < 0.5:
        nx, ny = rng.choice([1, 2, 5]), rng.choice([1, 3])
        k3 = rng.randint(1, nz)
        n3 = rng.randint(1, nz - k3 + 1)
        atm.append(f"scene_file = 'scene.nc', k3d_bottom = {k3}, nz3 = {n3}, nx = {nx}, "
                   f"ny = {ny}")
        shape = (1, n3, ny, nx)
        ext = np.array([rng.choice([0.0, 1e-9, 1e-4, 0.01, 1.0, 50.0])
                        for _ in range(n3 * ny * nx)]).reshape(shape)
        ssa = np.array([rng.choice([0.0, 0.5, 1.0]) for _ in range(n3 * ny * nx)]).reshape(shape)
        files["scene.nc"] = (write_scene, (ext, ssa))
    lines.append("&kumo_atmosphere " + ", ".join(atm) + " /")
    thermal = rng.random() < 0.3
    sun = rng.random() < 0.5
    if thermal:
        t_levels = ", ".join(fmt(rng.choice([200.0, 250.0, 300.0])) for _ in range(nz + 1))
        t_surface = f"t_surface = {fmt(rng.choice([0.0, 250.0, 310.0]))}"
    if surface is not None:
        surface_line, surface_files, t_map = surface(rng, thermal)
        files.update(surface_files)
        t_surface = t_map or (t_surface if thermal else None)
    elif rng.random() < 0.6:
        surface_line = f"&kumo_surface albedo = {fmt(rng.choice([0.0, 0.3, 1.0]))} /"
    else:
        surface_line = (f"&kumo_surface brdf = 'rpv', brdf_param = {fmt(rng.choice([0.05, 0.3]))}, "
                        f"{fmt(rng.choice([0.5, 1.0]))}, {fmt(rng.choice([-0.3, 0.0]))}, 1.0, 0.0 /")
    if thermal:
        lines.append(f"&kumo_thermal thermal = .true., t_levels = {t_levels}, {t_surface}, "
                     "wavenumber_lo = 800.0, wavenumber_hi = 1250.0, "
                     f"include_sun = {'.true.' if sun else '.false.'} /")
    lines.append(surface_line)
    source = (f"&kumo_source sza_deg = {fmt(rng.choice([0.0, 30.0, 60.0, 85.0, 89.0, 89.99]))}, "
              f"phi0_deg = {fmt(rng.choice([0.0, 45.0, 270.0]))}")
    lines.append(source + (", solar_flux = 20.0" if thermal and sun else "") + " /")
    if rng.random() < 0.6:
        n_dir = rng.randint(1, 3)
        mus = [rng.choice([1.0, 0.5, -0.5, -1.0, 0.2, -0.2]) for _ in range(n_dir)]
        phis = [rng.choice([0.0, 90.0, 180.0]) for _ in range(n_dir)]
        lines.append("&kumo_radiance rad_mu = " + ", ".join(fmt(m) for m in mus)
                     + ", rad_phi_deg = " + ", ".join(fmt(p) for p in phis) + " /")
    if rng.random() < 0.4:
        lines.append(
            f"&kumo_camera n_cameras = 1, cam_kind(1) = "
            f"'{rng.choice(['pinhole', 'orthographic'])}', cam_x(1) = {fmt(rng.uniform(0, lx))}, "
            f"cam_y(1) = 0.0, cam_z(1) = {fmt(rng.choice([z[-1] + 10.0, 3 * z[-1], 0.5 * z[-1]]))}, "
            f"cam_look_zenith_deg(1) = {fmt(rng.choice([180.0, 120.0, 90.0, 0.0, 60.0]))}, "
            f"cam_look_azimuth_deg(1) = {fmt(rng.choice([0.0, 33.0]))}, "
            f"cam_fov_deg(1) = {fmt(rng.choice([1.0, 30.0, 120.0, 170.0]))}, "
            f"cam_width(1) = {fmt(rng.choice([1.0, lx]))}, cam_npx(1) = {rng.choice([1, 7])}, "
            f"cam_npy(1) = {rng.choice([1, 5])} /")
    lines.append(f"&kumo_vr vr_preset = '{rng.choice(['analog', 'unbiased', 'standard', 'quick'])}' /")
    lines.append("&kumo_output file = 'out.nc' /")
    return "\n".join(lines) + "\n", files


def draw_cloud_case(rng):
    """A namelist over an LES cloud file and the file's fields: 2-4 x 2-3 columns of 1 m to
    1 km, 1-5 layers of 5-500 m from 0-500 m up, liquid water 0 to 3 g m-3 and effective radii
    0 to 60 um (outside the Mie tables at both ends), wavelengths 0.55 to 10.8 um."""
    nx, ny, nz = rng.choice([2, 4]), rng.choice([2, 3]), rng.choice([1, 2, 5])
    dx = rng.choice([1.0, 50.0, 1000.0])
    z0, dz = rng.choice([0.0, 10.0, 500.0]), rng.choice([5.0, 50.0, 500.0])
    shape = (nz, ny, nx)
    n = nz * ny * nx
    fields = {
        "x": dx * (np.arange(nx) + 0.5), "y": dx * (np.arange(ny) + 0.5),
        "z_edges": z0 + dz * np.arange(nz + 1),
        "lwc": np.array([rng.choice([0.0, 0.0, 1e-6, 0.1, 1.0, 3.0]) for _ in range(n)]).reshape(shape),
        "reff": np.array([rng.choice([0.0, 1.0, 5.0, 12.0, 30.0, 60.0]) for _ in range(n)]).reshape(shape)}
    lines = [f"&kumo_control n_photons_per_batch = {rng.choice([100, 1000])}, n_batches = 10, "
             f"seed = {rng.randint(1, 99)}, mode_3d = '{rng.choice(['f3d', 'ica'])}' /",
             f"&kumo_cloud cloud_file = 'cloud.nc', cloud_format = 'les', "
             f"n_reff = {rng.choice([2, 4, 10])}, reff_min_um = {fmt(rng.choice([2.0, 5.0]))}, "
             f"reff_max_um = {fmt(rng.choice([20.0, 30.0]))} /",
             f"&kumo_surface albedo = {fmt(rng.choice([0.0, 0.2, 1.0]))} /",
             f"&kumo_source sza_deg = {fmt(rng.choice([0.0, 60.0, 85.0]))}, solar_flux = 1.0, "
             f"wavelength_um = {fmt(rng.choice([0.55, 0.86, 1.6, 2.13, 3.7, 10.8]))} /"]
    if rng.random() < 0.5:
        lines.append("&kumo_radiance rad_mu = 1.0, 0.5 /")
        lines.append(f"&kumo_vr vr_preset = '{rng.choice(['unbiased', 'standard'])}' /")
    lines.append("&kumo_output file = 'out.nc' /")
    return "\n".join(lines) + "\n", {"cloud.nc": (write_cloud, fields)}


# BRDF parameters at the edges of their documented ranges, per kind, in the names of a BRDF map
BRDF_PARAMS = {
    "lambert": {"albedo": [0.0, 0.5, 1.0]},
    "dsm": {"diffuse_albedo": [0.0, 0.3, 1.0], "diffuse_fraction": [0.0, 0.5, 1.0],
            "refractive_index_real": [1.0, 1.000001, 1.33, 100.0],
            "refractive_index_imag": [0.0, 1e-9, 100.0],
            "slope_variance": [1e-6, 0.003, 0.5, 100.0]},
    "rpv": {"rho0": [0.0, 0.05, 1.0], "k": [1e-3, 0.8, 2.0], "theta": [-0.99, 0.0, 0.99],
            "hotspot": [1e-3, 1.0, 100.0]},
    "lsrt": {"k_iso": None, "k_geo": None, "k_vol": None},   # drawn together: LSRT_WEIGHTS
    "black": {}}
# LSRT weights (k_iso, k_geo, k_vol): a kernel sum negative for more than a quarter of the
# direction pairs is refused (docs/user-guide.md), as the last two are
LSRT_WEIGHTS = [(0.0, 0.0, 0.0), (0.2, 0.05, 0.3), (1.0, 0.0, 0.0), (1.0, 0.1, 2.0),
                (0.05, 0.0, 0.02), (0.0, 0.0, 0.3), (0.2, 1.0, 0.0)]
KINDS = ["black", "lambert", "dsm", "rpv", "lsrt"]      # brdf_kind codes 0..4


def draw_map_surface(rng, thermal):
    """An albedo map or a BRDF map of 1-7 x 1-5 pixels (every kind, pixels of each at the
    edges of their ranges, parameters of other kinds' pixels left missing), and in thermal
    runs a surface temperature map at times."""
    nxs, nys = rng.choice([1, 2, 7]), rng.choice([1, 3, 5])
    files, t_map = {}, None
    if rng.random() < 0.4:
        albedo = np.array([[rng.choice([0.0, 1e-6, 0.5, 1.0]) for _ in range(nxs)]
                           for _ in range(nys)])
        files["albedo.nc"] = (write_map, ({"albedo": albedo}, rng.choice(["f4", "f8"])))
        line = "&kumo_surface albedo_file = 'albedo.nc' /"
    else:
        pool = rng.sample(KINDS, rng.randint(1, 3))
        kind = np.array([[KINDS.index(rng.choice(pool)) for _ in range(nxs)] for _ in range(nys)])
        wind = rng.random() < 0.3
        fields = {}
        lsrt = [rng.randrange(len(LSRT_WEIGHTS)) for _ in range(int(np.sum(kind == 4)))]
        for code in sorted(set(kind.ravel())):
            for name, values in BRDF_PARAMS[KINDS[code]].items():
                if name == "slope_variance" and wind:
                    name, values = "wind_speed", [0.0, 5.0, 50.0]
                v = np.ma.masked_array(np.zeros((nys, nxs)), mask=True)
                if KINDS[code] == "lsrt":
                    v[kind == code] = [LSRT_WEIGHTS[i][("k_iso", "k_geo", "k_vol").index(name)]
                                       for i in lsrt]
                else:
                    v[kind == code] = [rng.choice(values)
                                       for _ in range(int(np.sum(kind == code)))]
                if rng.random() < 0.5:      # the other pixels' values: anything
                    v[kind != code] = rng.choice([0.0, -7.0, 1e30])
                fields[name] = v
        if len(set(kind.ravel())) == 1 and fields and rng.random() < 0.5:
            line = f"&kumo_surface brdf = '{KINDS[kind[0, 0]]}', brdf_file = 'brdf.nc' /"
        else:
            fields["brdf_kind"] = kind
            line = "&kumo_surface brdf_file = 'brdf.nc' /"
        files["brdf.nc"] = (write_map, (fields, rng.choice(["f4", "f8"])))
    if thermal and rng.random() < 0.5:
        ntx, nty = rng.choice([1, 4]), rng.choice([1, 2])
        t = np.array([[rng.choice([0.0, 200.0, 330.0]) for _ in range(ntx)] for _ in range(nty)])
        files["tsfc.nc"] = (write_map, ({"t_surface": t}, "f8"))
        t_map = "t_surface_file = 'tsfc.nc'"
    return line, files, t_map


def draw_dsm_surface(rng, thermal):
    """A uniform diffuse-specular mixture (ocean) surface: diffuse albedo and fraction 0 to 1,
    refractive index 1 to 100 + 0 to 100 i, slope variance 1e-6 to 100 or a wind speed of
    0 to 50 m s-1."""
    p = BRDF_PARAMS["dsm"]
    par = [rng.choice(p[k]) for k in ("diffuse_albedo", "diffuse_fraction",
                                      "refractive_index_real", "refractive_index_imag")]
    if rng.random() < 0.3:
        return (f"&kumo_surface brdf = 'dsm', brdf_param = {', '.join(fmt(x) for x in par)}, "
                f"wind_speed = {fmt(rng.choice([0.0, 0.1, 10.0, 50.0]))} /"), {}, None
    par.append(rng.choice(p["slope_variance"]))
    return f"&kumo_surface brdf = 'dsm', brdf_param = {', '.join(fmt(x) for x in par)} /", {}, None


def draw_les_fields(rng, nx, ny, nz, dx, z0, dz, extra=()):
    """LES cloud-file fields: liquid water 0 to 3 g m-3 and radii 0 to 60 um, and of ``extra``
    ice water and radius, temperature, potential temperature, pressure and water vapour."""
    shape, n = (nz, ny, nx), nz * ny * nx

    def field(values):
        return np.array([rng.choice(values) for _ in range(n)]).reshape(shape)

    f = {"x": dx * (np.arange(nx) + 0.5), "y": dx * (np.arange(ny) + 0.5),
         "z_edges": z0 + dz * np.arange(nz + 1),
         "lwc": field([0.0, 0.0, 1e-6, 0.1, 1.0, 3.0]),
         "reff": field([0.0, 1.0, 5.0, 12.0, 30.0, 60.0])}
    zc = (f["z_edges"][:-1] + f["z_edges"][1:])[:, None, None] / 2 * np.ones(shape)
    p = 101325.0 * np.exp(-zc / 8000.0)
    if "ice" in extra:
        f["iwc"] = field([0.0, 0.0, 0.01, 1.0])
        f["reff_ice"] = field([0.0, 5.0, 50.0, 200.0])
    if "temperature" in extra:
        f["temperature"] = field([160.0, 250.0, 290.0, 355.0])
    if "theta" in extra:
        f["theta"] = field([250.0, 300.0, 400.0])
    if "pressure" in extra:
        f["pressure"] = p * field([1.0, 1.0, 0.99, 1.01])
    if "qv" in extra:
        f["qv"] = field([0.0, 1e-4, 0.01, 0.04])
    return f


def draw_broadband_case(rng):
    """A broadband namelist (&kumo_spectral) over 1-5 layers up to 86 km or beyond: shortwave or
    longwave k-distribution, the U.S. Standard profile or a sounding (50 to 1200 hPa at the
    ground, 160 to 400 K), water vapour and ozone 0 to 1 mol/mol, CO2 0 to 1e-2, TSI 1e-3 to
    1e4 W m-2, floor shares 0 to 0.9, one g-point alone; gray cloud layers, a scene file of gray
    voxels or an LES cloud file (liquid and ice, RRTMGP optics, the file's gas state)."""
    kdist = rng.choice(["sw-g112"] * 9 + ["lw-g128"] * 9 + ["sw-g224", "lw-g256"])
    sw = kdist.startswith("sw")
    n_gpt = int(kdist[4:])
    lines = [f"&kumo_control n_photons_per_batch = {rng.choice([50, 200, 1000])}, "
             f"n_batches = {rng.choice([2, 3, 10])}, seed = {rng.randint(1, 99)}, "
             f"mode_3d = '{rng.choice(['f3d', 'ica', 'p3d'])}' /"]
    cloud = rng.random() < 0.3
    files = {}
    if cloud:
        nx, ny, nzf = rng.choice([2, 3]), rng.choice([2, 3]), rng.choice([1, 2, 3])
        z0, dzf = rng.choice([10.0, 500.0]), rng.choice([5.0, 50.0, 500.0])
        fields = draw_les_fields(rng, nx, ny, nzf, rng.choice([1.0, 100.0]), z0, dzf,
                                 [e for e in ("ice", "temperature", "theta", "pressure", "qv")
                                  if rng.random() < 0.4])
        files["cloud.nc"] = (write_cloud, fields)
        z = [0.0] + list(fields["z_edges"]) + [rng.choice([5000.0, 20000.0]),
                                               rng.choice([60000.0, 86000.0])]
    else:
        z = [0.0]
        for _ in range(rng.randint(1, 5)):
            z.append(z[-1] + rng.choice([1.0, 100.0, 2000.0, 20000.0, 40000.0]))
    nz = len(z) - 1
    atm = [f"nz = {nz}", "z_levels = " + ", ".join(fmt(v) for v in z)]
    nph = 1
    atm.append("n_components = 1")
    for k in range(1, nz + 1):
        if rng.random() < 0.5:
            tau = rng.choice([1e-8, 0.1, 10.0, 1000.0])
            atm += [f"ext1d({k},1) = {fmt(tau / (z[k] - z[k - 1]))}",
                    f"ssa1d({k},1) = {fmt(rng.choice([0.0, 0.5, 0.999999, 1.0]))}"]
        else:
            atm.append(f"ext1d({k},1) = 0.0")
    if not cloud and rng.random() < 0.3:
        nx, ny = rng.choice([1, 2, 5]), rng.choice([1, 3])
        k3 = rng.randint(1, nz)
        atm.append(f"scene_file = 'scene.nc', k3d_bottom = {k3}, nz3 = 1, nx = {nx}, ny = {ny}")
        shape = (1, 1, ny, nx)
        ext = np.array([rng.choice([0.0, 1e-9, 1e-4, 0.01, 1.0, 50.0])
                        for _ in range(ny * nx)]).reshape(shape)
        ssa = np.array([rng.choice([0.0, 0.5, 1.0]) for _ in range(ny * nx)]).reshape(shape)
        files["scene.nc"] = (write_scene, (ext, ssa))
    lines.append("&kumo_atmosphere " + ", ".join(atm) + " /")
    lines.append(f"&kumo_phase n_phase = {nph}, phase_kind = "
                 f"'{rng.choice(['hg', 'isotropic', 'rayleigh'])}', "
                 f"phase_g = {fmt(rng.choice([-0.99, 0.0, 0.85, 0.9999]))} /")
    if cloud:
        lines.append(f"&kumo_cloud cloud_file = 'cloud.nc', cloud_format = 'les' /")
    spec = [f"kdist_file = 'rrtmgp-gas-{kdist}.nc'"]
    if rng.random() < 0.6:
        spec.append("profile = 'us1976'")
    else:
        p = [rng.choice([5000.0, 101325.0, 109600.0, 120000.0])]
        for _ in range(nz):
            p.append(p[-1] * rng.choice([0.999, 0.5, 0.01, 1.0 if rng.random() < 0.05 else 0.9]))
        spec.append("p_levels = " + ", ".join(fmt(v) for v in p))
        spec.append("t_levels = " + ", ".join(fmt(rng.choice([160.0, 220.0, 288.0, 355.0, 400.0]))
                                              for _ in range(nz + 1)))
        if rng.random() < 0.3:
            w = [rng.choice([0.0, 0.5, 1.0]) for _ in range(nz)]
            spec.append("p_layers = " + ", ".join(fmt(p[k] ** (1 - w[k]) * p[k + 1] ** w[k])
                                                  for k in range(nz)))
            spec.append("t_layers = " + ", ".join(fmt(rng.choice([160.0, 300.0]))
                                                  for _ in range(nz)))
    spec.append("h2o_vmr = " + ", ".join(fmt(rng.choice([0.0, 1e-6, 1e-3, 0.03, 1.0]))
                                         for _ in range(nz)))
    if rng.random() < 0.3:
        spec.append("o3_vmr = " + ", ".join(fmt(rng.choice([0.0, 1e-7, 1e-5, 0.1]))
                                            for _ in range(nz)))
    if rng.random() < 0.2:
        spec.append(f"gas_names = 'co2', gas_vmr = {fmt(rng.choice([0.0, 4e-4, 1e-2]))}")
    if sw:
        spec.append(f"tsi = {fmt(rng.choice([1e-3, 1360.8, 1e4]))}")
    elif rng.random() < 0.7:
        spec.append(f"t_surface = {fmt(rng.choice([160.0, 288.15, 355.0, 400.0]))}")
    spec.append(f"floor_share = {fmt(rng.choice([0.0, 0.2, 0.9]))}")
    if rng.random() < 0.1:
        spec.append(f"gpoint = {rng.choice([1, n_gpt // 2, n_gpt])}")
    if cloud:
        spec.append("liquid_optics = 'rrtmgp', "
                    f"ice_roughness = '{rng.choice(['smooth', 'medium', 'rough'])}', "
                    f"gas_state = '{rng.choice(['cloud_file', 'profile'])}'")
    lines.append("&kumo_spectral " + ", ".join(spec) + " /")
    r = rng.random()
    if r < 0.6:
        lines.append(f"&kumo_surface albedo = {fmt(rng.choice([0.0, 0.02, 0.3, 1.0]))} /")
    elif r < 0.8:
        line, more, _ = draw_map_surface(rng, False)
        lines.append(line)
        files.update(more)
    else:
        lines.append(draw_dsm_surface(rng, False)[0])
    lines.append(f"&kumo_source sza_deg = {fmt(rng.choice([0.0, 60.0, 89.0, 89.99]))}, "
                 f"phi0_deg = {fmt(rng.choice([0.0, 270.0]))} /")
    if rng.random() < 0.4:
        n_dir = rng.randint(1, 3)
        lines.append("&kumo_radiance rad_mu = "
                     + ", ".join(fmt(rng.choice([1.0, 0.5, 0.2, -0.5, -1.0])) for _ in range(n_dir))
                     + ", rad_phi_deg = "
                     + ", ".join(fmt(rng.choice([0.0, 90.0, 180.0])) for _ in range(n_dir)) + " /")
    if rng.random() < 0.2:
        lines.append(
            "&kumo_camera n_cameras = 1, "
            f"cam_kind(1) = '{rng.choice(['pinhole', 'orthographic'])}', cam_x(1) = 500.0, "
            f"cam_y(1) = 500.0, cam_z(1) = {fmt(rng.choice([z[-1] + 10.0, 0.5 * z[-1]]))}, "
            f"cam_look_zenith_deg(1) = {fmt(rng.choice([180.0, 120.0, 0.0]))}, "
            f"cam_fov_deg(1) = {fmt(rng.choice([1.0, 60.0]))}, cam_width(1) = 1000.0, "
            f"cam_npx(1) = {rng.choice([1, 4])}, cam_npy(1) = {rng.choice([1, 3])} /")
    lines.append(f"&kumo_vr vr_preset = '{rng.choice(['analog', 'unbiased', 'standard', 'quick'])}' /")
    lines.append("&kumo_output file = 'out.nc' /")
    return "\n".join(lines) + "\n", files


def draw_thermal_cloud_case(rng):
    """Thermal emission (&kumo_thermal) over an LES cloud file, kumo's Mie optics at 3.7 to 12 um:
    a band or the wavelength alone, level temperatures 0 to 330 K, voxel temperatures from the
    file (temperature, or potential temperature and pressure) or from the levels, a surface
    temperature or its map, emission floors 0 to 0.99, with or without the sun."""
    nx, ny, nzf = rng.choice([2, 4]), rng.choice([2, 3]), rng.choice([1, 2, 5])
    z0, dz = rng.choice([0.0, 10.0, 500.0]), rng.choice([5.0, 50.0, 500.0])
    fields = draw_les_fields(rng, nx, ny, nzf, rng.choice([1.0, 50.0, 1000.0]), z0, dz,
                             rng.choice([(), ("temperature",), ("theta", "pressure")]))
    files = {"cloud.nc": (write_cloud, fields)}
    z = ([0.0] if z0 > 0 else []) + list(fields["z_edges"])
    if rng.random() < 0.5:
        z.append(z[-1] + rng.choice([100.0, 10000.0]))
    nz = len(z) - 1
    sun = rng.random() < 0.3
    wl = rng.choice([3.7, 10.8, 12.0])
    lines = [f"&kumo_control n_photons_per_batch = {rng.choice([100, 1000])}, n_batches = 10, "
             f"seed = {rng.randint(1, 99)}, mode_3d = '{rng.choice(['f3d', 'ica'])}' /"]
    atm = [f"nz = {nz}", "z_levels = " + ", ".join(fmt(v) for v in z)]
    if rng.random() < 0.3:
        atm.append("ext1d = " + ", ".join(fmt(rng.choice([0.0, 1e-4, 0.1])) for _ in range(nz))
                   + ", ssa1d = " + ", ".join(fmt(rng.choice([0.0, 1.0])) for _ in range(nz)))
    if rng.random() < 0.4:
        atm.append("air_density = " + ", ".join(fmt(rng.choice([0.01, 1.2])) for _ in range(nz)))
    lines.append("&kumo_atmosphere " + ", ".join(atm) + " /")
    lines.append(f"&kumo_cloud cloud_file = 'cloud.nc', cloud_format = 'les', "
                 f"n_reff = {rng.choice([2, 4, 10])}, reff_min_um = {fmt(rng.choice([2.0, 5.0]))}, "
                 f"reff_max_um = {fmt(rng.choice([20.0, 30.0]))} /")
    th = ["t_levels = " + ", ".join(fmt(rng.choice([0.0, 200.0, 250.0, 300.0, 330.0]))
                                    for _ in range(nz + 1))]
    band = rng.choice([None, (800.0, 1250.0), (10.0, 3000.0), (2500.0, 2800.0)])
    if band:
        th.append(f"wavenumber_lo = {fmt(band[0])}, wavenumber_hi = {fmt(band[1])}")
    th.append(f"t_top = {fmt(rng.choice([0.0, 0.0, 3.0, 300.0]))}, "
              f"emission_floor = {fmt(rng.choice([0.0, 0.1, 0.99]))}, "
              f"include_sun = {'.true.' if sun else '.false.'}")
    surface_line, more, t_map = draw_map_surface(rng, True) if rng.random() < 0.3 else (
        f"&kumo_surface albedo = {fmt(rng.choice([0.0, 0.02, 1.0]))} /", {}, None)
    files.update(more)
    th.append(t_map or f"t_surface = {fmt(rng.choice([0.0, 250.0, 310.0]))}")
    lines.append("&kumo_thermal " + ", ".join(th) + " /")
    lines.append(surface_line)
    lines.append(f"&kumo_source sza_deg = {fmt(rng.choice([0.0, 60.0, 85.0]))}, "
                 f"wavelength_um = {fmt(wl)}" + (", solar_flux = 10.0" if sun else "") + " /")
    if rng.random() < 0.4:
        lines.append("&kumo_radiance rad_mu = 1.0, -1.0, 0.5 /")
    if rng.random() < 0.5:
        lines.append(f"&kumo_vr vr_preset = '{rng.choice(['unbiased', 'standard', 'quick'])}' /")
    lines.append("&kumo_output file = 'out.nc' /")
    return "\n".join(lines) + "\n", files


DRAWS = {
    "layers": draw_case,
    "clouds": lambda rng: draw_cloud_case(rng),
    "broadband": draw_broadband_case,
    "maps": lambda rng: draw_case(rng, draw_map_surface),
    "dsm": lambda rng: draw_case(rng, draw_dsm_surface),
    "thermal-clouds": draw_thermal_cloud_case}


CLOUD_UNITS = {"lwc": "g m-3", "reff": "um", "iwc": "g m-3", "reff_ice": "um", "temperature": "K",
               "theta": "K", "pressure": "Pa", "qv": "kg kg-1"}


def write_cloud(path, fields):
    with netCDF4.Dataset(path, "w") as f:
        nz, ny, nx = fields["lwc"].shape
        for name, size in (("x", nx), ("y", ny), ("z", nz), ("z_edges", nz + 1)):
            f.createDimension(name, size)
        for name in ("x", "y", "z_edges"):
            v = f.createVariable(name, "f8", (name,))
            v.units = "m"
            v[:] = fields[name]
        for name, units in CLOUD_UNITS.items():
            if name in fields:
                v = f.createVariable(name, "f4", ("z", "y", "x"))
                v.units = units
                v[:] = fields[name]


def write_map(path, data):
    """A surface map on (ys, xs): albedo, BRDF parameters and kinds, or surface temperature."""
    fields, dtype = data
    with netCDF4.Dataset(path, "w") as f:
        nys, nxs = next(iter(fields.values())).shape
        f.createDimension("xs", nxs)
        f.createDimension("ys", nys)
        for name, values in fields.items():
            kind = name == "brdf_kind"
            v = f.createVariable(name, "i1" if kind else dtype, ("ys", "xs"))
            if not kind:
                v.units = {"wind_speed": "m s-1", "t_surface": "K"}.get(name, "1")
            v[:] = values


def write_scene(path, scene):
    ext, ssa = scene
    with netCDF4.Dataset(path, "w") as f:
        for name, n in zip(("component", "z", "y", "x"), ext.shape):
            f.createDimension(name, n)
        for name, values, units in (("extinction", ext, "m-1"), ("ssa", ssa, "1")):
            v = f.createVariable(name, "f8", ("component", "z", "y", "x"))
            v.units = units
            v[:] = values


def read_outputs(path):
    with netCDF4.Dataset(path) as f:
        return {k: np.asarray(v[:], dtype=float) for k, v in f.variables.items()
                if v.dtype.kind in "fi"}


def shortwave_plan(text):
    """How much light a broadband shortwave batch lets in (as a fraction of mu0 TSI, the
    normalisation): exactly 1 when every g-point with energy has an expected photon (a floor
    share a and n_gpt / a photons or more; docs/broadband.md), else 1 in expectation; with
    ``gpoint`` that g-point's share. None for other runs, which let in exactly 1 (in thermal
    runs the closure is relative to the weight launched)."""
    kdist = re.search(r"rrtmgp-gas-sw-g(\d+)", text)
    if kdist is None:
        return None
    if re.search(r"gpoint = [1-9]", text):
        return "share"
    n = int(re.search(r"n_photons_per_batch = (\d+)", text).group(1))
    share = float(re.search(r"floor_share = ([0-9.e+-]+)", text).group(1))
    return "exact" if share > 0 and n * share >= int(kdist.group(1)) else "expectation"


def check_output(out, stderr, n_batches, sw_plan=None):
    problems = [f"{k} not finite" for k, v in out.items() if not np.all(np.isfinite(v))]
    incident = 1.0
    if sw_plan is not None:    # what came in: the downward flux at the top level
        incident, e = float(out["flux_down"][-1]), float(out["flux_down_stderr"][-1])
        if (sw_plan == "exact" and abs(incident - 1.0) > 1e-9
                or sw_plan == "expectation" and n_batches >= 10
                and abs(incident - 1.0) > 5 * e + 1e-9
                or sw_plan == "share" and not 0.0 < incident <= 1.0 + 1e-9):
            problems.append(f"incident flux at the top = {incident} +- {e} ({sw_plan})")
    closure = float(out["energy_closure"])
    if abs(closure - 1.0) > 1e-9:
        problems.append(f"energy_closure = {closure}, incident {incident}")
    # error bars from fewer than 10 batches are too uncertain to bound by (the run warns)
    for name in ("reflectance", "absorptance_atmosphere", "absorptance_surface") \
            if n_batches >= 10 else ():
        x, e = float(out[name]), float(out[name + "_stderr"])
        if x < -5 * e - 1e-12 or x > 1 + 5 * e + 1e-9:
            problems.append(f"{name} = {x} +- {e}")
    # fluxes count the positive weights of photons crossing a level
    for name, v in out.items():
        if name.startswith(("flux_up", "flux_down")) and not name.endswith("_stderr") \
                and np.any(v < -1e-12 * max(1.0, float(np.max(np.abs(v))))):
            problems.append(f"{name} negative: {float(np.min(v))}")
    if float(out["weight_lost"]) > 0 and "stopped at a loop cap" not in stderr:
        problems.append("weight lost without a warning")
    return problems


def run(cmd, cwd, timeout, env=None):
    try:
        return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout,
                              env=env)
    except subprocess.TimeoutExpired:
        return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kumo", default="build/kumo")
    ap.add_argument("--cases", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workdir", default="fuzz_runs")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per run")
    ap.add_argument("--mpi", type=int, default=0, help="also run on this many ranks, compare")
    ap.add_argument("--mode", choices=sorted(DRAWS), default="layers",
                    help="what the cases draw: layers and scene files, LES cloud files (kumo's Mie "
                         "optics), broadband runs, surface maps, DSM surfaces, thermal emission "
                         "over LES cloud files")
    ap.add_argument("--clouds", action="store_const", dest="mode", const="clouds",
                    help="the same as --mode clouds")
    args = ap.parse_args()
    kumo = os.path.abspath(args.kumo)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    failed = refused = slow = 0
    for i in range(args.cases):
        seed = args.seed + i
        case_dir = os.path.join(args.workdir, f"case{seed}")
        os.makedirs(case_dir, exist_ok=True)
        text, files = DRAWS[args.mode](random.Random(seed))
        for name, (write, data) in files.items():
            write(os.path.join(case_dir, name), data)
        with open(os.path.join(case_dir, "case.nml"), "w") as f:
            f.write(text)
        done = run([kumo, "case.nml"], case_dir, args.timeout)
        if done is None:
            slow += 1
            check = run([kumo, "--check", "case.nml"], case_dir, args.timeout)
            warned = [] if check is None else [
                line[15:95] for line in check.stderr.splitlines() if line.startswith("kumo: warning:")]
            # kumo joins its set-up warnings on one line: say whether one of them foretold this
            foretold = check is not None and "the run will be slow" in check.stderr
            print(f"slow {case_dir}: beyond {args.timeout:g} s; set-up warnings: {warned or 'none'}"
                  + ("; a warning says the run will be slow" if foretold else ""))
            continue
        if done.returncode != 0:
            # the output writer refuses numbers that are not finite: a result, not the input
            if done.returncode == 1 and done.stderr.count("kumo error") == 1 \
                    and "STOP" not in done.stderr and "write_results" not in done.stderr:
                refused += 1
            else:
                failed += 1
                print(f"FAIL {case_dir}: exit {done.returncode}: {done.stderr[-300:]}")
            continue
        out = read_outputs(os.path.join(case_dir, "out.nc"))
        problems = check_output(out, done.stderr,
                                int(re.search(r"n_batches = (\d+)", text).group(1)),
                                shortwave_plan(text))
        if args.mpi > 1 and not problems:
            os.replace(os.path.join(case_dir, "out.nc"), os.path.join(case_dir, "out_np1.nc"))
            par = run(["mpirun", "--oversubscribe", "-np", str(args.mpi), kumo, "case.nml"],
                      case_dir, 3 * args.timeout, env)
            if par is None or par.returncode != 0:
                problems.append(f"{args.mpi} ranks: failed or too slow")
            else:
                out_p = read_outputs(os.path.join(case_dir, "out.nc"))
                for k, v in out.items():
                    tol = 1e-9 * np.abs(v) + 1e-13
                    mean = out.get(k[:-len("_stderr")]) if k.endswith("_stderr") else None
                    if mean is not None and mean.shape == v.shape:
                        # a standard error comes from the sums of x and x^2: their rounding
                        # (1e-16 of mean^2) shows in it as 1e-16 mean^2 / stderr
                        tol = tol + 1e-15 * mean**2 / np.maximum(v, 1e-300)
                    if np.any(np.abs(v - out_p[k]) > tol):
                        problems.append(f"{k} differs on {args.mpi} ranks")
        if problems:
            failed += 1
            print(f"FAIL {case_dir}: " + "; ".join(problems[:5]))
    print(f"fuzz_inputs --mode {args.mode}: {args.cases} cases from seed {args.seed}: "
          f"{args.cases - failed - refused - slow} ran and passed, {refused} refused with a "
          f"message, {slow} slower than {args.timeout:g} s, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
