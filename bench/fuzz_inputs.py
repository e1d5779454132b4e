#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Random valid cases: kumo must end every one cleanly and give numbers that hold together.

Each case is a namelist drawn at random within the documented ranges, many of them at their
edges: 1 to 5 layers of 1 m to 5 km, optical depths from 0 to 1000 per layer, albedos 0 and 1,
Henyey-Greenstein g from -0.99 to 0.9999, the sun from the zenith to 89.99 degrees, a 3-D
region from a scene file (extinction 0 to 50 m-1) or none, thermal emission with or without
the sun, Lambert or RPV surfaces, radiances, a camera, every preset and 3-D mode. For each case:

* the run ends with status 0, or with status 1 and one ``kumo error:`` message (no crash, no
  STOP line); a run beyond ``--timeout`` seconds is listed with the warnings kumo gave for it;
* every output variable is finite, the energy closure is 1 to 1e-9, and (runs of 10 batches
  or more) the reflectance and absorptances lie in [0, 1] within 5 standard errors (the
  transmittance counts light that a
  reflecting surface sends up and the atmosphere back down, so it may exceed 1);
* weight lost at a loop cap comes with a warning on standard error;
* with ``--mpi N``, the run on N ranks gives the same results to 1e-9 relative (the sums over
  ranks are added in another order); a standard error, formed from the sums of x and x^2,
  within the rounding of those sums as well (1e-15 mean^2 / stderr).

    python3 bench/fuzz_inputs.py --kumo build/kumo --cases 300 --seed 1 [--mpi 2] [--clouds]

With ``--clouds`` the cases are LES cloud files (liquid water 0 to 3 g m-3, effective radii 0 to
60 um, inside and outside the Mie tables) at wavelengths from 0.55 to 10.8 um, over the same
checks.

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


def draw_case(rng):
    """A namelist text and the voxel fields of its scene file (None without a 3-D region)."""
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
    scene = None
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
        scene = (ext, ssa)
    lines.append("&kumo_atmosphere " + ", ".join(atm) + " /")
    thermal = rng.random() < 0.3
    sun = rng.random() < 0.5
    if thermal:
        t_levels = ", ".join(fmt(rng.choice([200.0, 250.0, 300.0])) for _ in range(nz + 1))
        lines.append(f"&kumo_thermal thermal = .true., t_levels = {t_levels}, "
                     f"t_surface = {fmt(rng.choice([0.0, 250.0, 310.0]))}, "
                     "wavenumber_lo = 800.0, wavenumber_hi = 1250.0, "
                     f"include_sun = {'.true.' if sun else '.false.'} /")
    if rng.random() < 0.6:
        lines.append(f"&kumo_surface albedo = {fmt(rng.choice([0.0, 0.3, 1.0]))} /")
    else:
        lines.append(f"&kumo_surface brdf = 'rpv', brdf_param = {fmt(rng.choice([0.05, 0.3]))}, "
                     f"{fmt(rng.choice([0.5, 1.0]))}, {fmt(rng.choice([-0.3, 0.0]))}, 1.0, 0.0 /")
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
    return "\n".join(lines) + "\n", scene


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
    return "\n".join(lines) + "\n", fields


def write_cloud(path, fields):
    with netCDF4.Dataset(path, "w") as f:
        nz, ny, nx = fields["lwc"].shape
        for name, size in (("x", nx), ("y", ny), ("z", nz), ("z_edges", nz + 1)):
            f.createDimension(name, size)
        for name, dims, units in (("x", ("x",), "m"), ("y", ("y",), "m"),
                                  ("z_edges", ("z_edges",), "m"), ("lwc", ("z", "y", "x"), "g m-3"),
                                  ("reff", ("z", "y", "x"), "um")):
            v = f.createVariable(name, "f8" if len(dims) == 1 else "f4", dims)
            v.units = units
            v[:] = fields[name]


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


def check_output(out, stderr, n_batches):
    problems = [f"{k} not finite" for k, v in out.items() if not np.all(np.isfinite(v))]
    closure = float(out["energy_closure"])
    if abs(closure - 1.0) > 1e-9:
        problems.append(f"energy_closure = {closure}")
    # error bars from fewer than 10 batches are too uncertain to bound by (the run warns)
    for name in ("reflectance", "absorptance_atmosphere", "absorptance_surface") \
            if n_batches >= 10 else ():
        x, e = float(out[name]), float(out[name + "_stderr"])
        if x < -5 * e - 1e-12 or x > 1 + 5 * e + 1e-9:
            problems.append(f"{name} = {x} +- {e}")
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
    ap.add_argument("--clouds", action="store_true",
                    help="cases over LES cloud files (kumo's Mie optics) instead of layers and scene files")
    args = ap.parse_args()
    kumo = os.path.abspath(args.kumo)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    failed = refused = slow = 0
    for i in range(args.cases):
        seed = args.seed + i
        case_dir = os.path.join(args.workdir, f"case{seed}")
        os.makedirs(case_dir, exist_ok=True)
        if args.clouds:
            text, fields = draw_cloud_case(random.Random(seed))
            write_cloud(os.path.join(case_dir, "cloud.nc"), fields)
        else:
            text, scene = draw_case(random.Random(seed))
            if scene is not None:
                write_scene(os.path.join(case_dir, "scene.nc"), scene)
        with open(os.path.join(case_dir, "case.nml"), "w") as f:
            f.write(text)
        done = run([kumo, "case.nml"], case_dir, args.timeout)
        if done is None:
            slow += 1
            check = run([kumo, "--check", "case.nml"], case_dir, args.timeout)
            warned = [] if check is None else [
                line[15:95] for line in check.stderr.splitlines() if line.startswith("kumo: warning:")]
            print(f"slow {case_dir}: beyond {args.timeout:g} s; set-up warnings: {warned or 'none'}")
            continue
        if done.returncode != 0:
            if done.returncode == 1 and done.stderr.count("kumo error") == 1 \
                    and "STOP" not in done.stderr:
                refused += 1
            else:
                failed += 1
                print(f"FAIL {case_dir}: exit {done.returncode}: {done.stderr[-300:]}")
            continue
        out = read_outputs(os.path.join(case_dir, "out.nc"))
        problems = check_output(out, done.stderr,
                                int(re.search(r"n_batches = (\d+)", text).group(1)))
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
    print(f"fuzz_inputs: {args.cases} cases from seed {args.seed}: "
          f"{args.cases - failed - refused - slow} ran and passed, {refused} refused with a "
          f"message, {slow} slower than {args.timeout:g} s, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
