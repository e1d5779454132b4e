#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Bars of the cloud-file input (&kumo_cloud), run on demand.

1. Setup of a 256 x 256 x 100 LES field with two species: liquid water and ice (lwc, reff,
   iwc, reff_ice as float32, 105 MB), optics from cached tables, super-voxels built. The water
   table is kumo's Mie table (cache warmed by a first run); the ice table is a stand-in in the
   same layout (water spheres of 10-60 um, written by kumo), since kumo has no ice optics of
   its own: the setup work is the same. Measured: the setup time kumo reports (setup_time_s)
   and the peak resident memory of the whole run (/usr/bin/time), with 2 x 10 photons.
2. The I3RC LES stratocumulus at 2.13 um from its SHDOM property file (les_stcu_w213.prp),
   SZA 60, black surface, domain fluxes only: CPU time to a 0.1 % standard error of the
   reflectance, t (sigma/R / 0.001)^2 from runs of 100 batches of 1e4 photons: five seeds,
   pooled as the mean variance per photon times the mean CPU time per photon (100 batches pin
   one run's sigma^2 to about 14 %), with the range of the single runs. After each of these runs a
   plane-parallel slab with the scene's mean optical depth, albedo and asymmetry parameter
   is traced on kumo's 1-D path, as the floor a 3-D walk cannot go below: the ratio of CPU
   time per photon is measured side by side.

    python3 bench/run_les_bench.py [--kumo build/kumo] [--shared ../shared] [--out DIR]

Writes DIR/les_bench.md (default bench/results/les_bench.md).
"""
import argparse
import os
import re
import statistics
import subprocess
import sys

import numpy as np
from netCDF4 import Dataset

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "python", "src"))   # the kumo package of this tree
import kumo  # noqa: E402


def make_les(path, nx=256, ny=256, nz=100, seed=1):
    """A stratocumulus-like field: cloud between layers 30 and 60, ice between 70 and 95."""
    rng = np.random.default_rng(seed)
    z_edges = np.linspace(0.0, 2500.0, nz + 1)
    x = (np.arange(nx) + 0.5) * 50.0
    y = (np.arange(ny) + 0.5) * 50.0
    base = rng.random((ny, nx)).astype(np.float32)
    lwc = np.zeros((nz, ny, nx), np.float32)
    reff = np.zeros((nz, ny, nx), np.float32)
    iwc = np.zeros((nz, ny, nx), np.float32)
    rei = np.zeros((nz, ny, nx), np.float32)
    for k in range(30, 60):
        w = np.clip(base - 0.3, 0.0, None) * (k - 29) / 30.0
        lwc[k] = 0.5 * w
        reff[k] = np.where(w > 0, 4.0 + 12.0 * w, 0.0)
    for k in range(70, 95):
        w = np.clip(rng.random((ny, nx)) - 0.5, 0.0, None).astype(np.float32)
        iwc[k] = 0.02 * w
        rei[k] = np.where(w > 0, 20.0 + 40.0 * w, 0.0)
    with Dataset(path, "w") as nc:
        nc.createDimension("x", nx)
        nc.createDimension("y", ny)
        nc.createDimension("z", nz)
        nc.createDimension("z_edges", nz + 1)
        for name, dims, data, units in [("x", ("x",), x, "m"), ("y", ("y",), y, "m"),
                                        ("z_edges", ("z_edges",), z_edges, "m")]:
            v = nc.createVariable(name, "f8", dims)
            v.units = units
            v[:] = data
        for name, data, units in [("lwc", lwc, "g m-3"), ("reff", reff, "um"),
                                  ("iwc", iwc, "g m-3"), ("reff_ice", rei, "um")]:
            v = nc.createVariable(name, "f4", ("z", "y", "x"))
            v.units = units
            v[:] = data
    return 4 * lwc.nbytes


def run(kumo_exe, nml, cwd):
    """Run kumo under /usr/bin/time; return (log, peak RSS in MB)."""
    p = subprocess.run(["/usr/bin/time", "-f", "MAXRSS %M", kumo_exe, nml], cwd=cwd,
                       capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"kumo failed on {nml}:\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
    rss = float(re.search(r"MAXRSS (\d+)", p.stderr).group(1)) / 1024.0
    return p.stdout, rss


def attr(path, name):
    with Dataset(path) as nc:
        return float(getattr(nc, name))


def setup_bar(kumo_exe, work):
    les = os.path.join(work, "les_256.nc")
    nbytes = make_les(les)
    def case(out, cloud):
        return {"control": {"n_photons_per_batch": 10, "n_batches": 2, "verbose": 0},
                "source": {"sza_deg": 30.0, "wavelength_um": 0.67},
                "output": {"file": out, "column_fluxes": False, "voxel_absorption": False},
                "cloud": {"cloud_file": "les_256.nc", **cloud}}

    # the ice stand-in table, then warm the water cache
    kumo.write_namelist(case("ice_out.nc", {"les_iwc": "none", "mie_cache": "ice_standin.nc",
                                            "reff_min_um": 10.0, "reff_max_um": 60.0,
                                            "n_reff": 20}),
                        os.path.join(work, "ice.nml"))
    run(kumo_exe, "ice.nml", work)
    kumo.write_namelist(case("les_out.nc", {"mie_cache": "water.nc", "reff_min_um": 2.0,
                                            "reff_max_um": 30.0, "n_reff": 30,
                                            "ice_optics_file": "ice_standin.nc"}),
                        os.path.join(work, "les.nml"))
    run(kumo_exe, "les.nml", work)          # computes the water table
    times, rss = [], []
    for _ in range(3):
        log, r = run(kumo_exe, "les.nml", work)
        times.append(attr(os.path.join(work, "les_out.nc"), "setup_time_s"))
        rss.append(r)
    return nbytes / 1e6, statistics.median(times), statistics.median(rss)


def prp_means(prp):
    """Domain-mean optical depth, and the extinction-weighted single-scattering albedo and
    scattering-weighted asymmetry parameter of an SHDOM tabulated property file (the first
    Legendre coefficient of each table is 3 g)."""
    with open(prp) as f:
        lines = f.read().split("\n")
    z = np.array(lines[2].split()[3:], float)
    nph = int(lines[3])
    start = next(i for i in range(4, len(lines)) if len(lines[i].split()) == 7)
    tok = " ".join(lines[4:start]).split()
    g, p = [], 0
    for _ in range(nph):
        n = int(tok[p])
        g.append(float(tok[p + 1]) / 3.0 if n > 0 else 0.0)
        p += 1 + n
    a = np.loadtxt(lines[start:], usecols=(0, 1, 2, 4, 5, 6))
    nx, ny, nz = (int(v) for v in lines[1].split())
    ext = np.zeros((nx, ny, nz))
    ix, iy, iz = (a[:, i].astype(int) - 1 for i in range(3))
    ext[ix, iy, iz] = a[:, 3]
    tau = ((ext[:, :, :-1] + ext[:, :, 1:]) / 2 * np.diff(z)).sum(axis=2).mean()
    omega = (a[:, 3] * a[:, 4]).sum() / a[:, 3].sum()
    gbar = (a[:, 3] * a[:, 4] * np.array(g)[a[:, 5].astype(int) - 1]).sum() / \
        (a[:, 3] * a[:, 4]).sum()
    return tau, omega, gbar


def cpu_and_r(log):
    cpu = float(re.search(r"cpu ([0-9.eE+-]+) s", log).group(1))
    m = re.search(r"reflectance\s+([0-9.]+) \+-\s+([0-9.eE+-]+)", log)
    return cpu, float(m.group(1)), float(m.group(2))


def flux_bar(kumo_exe, shared, work):
    """t01 of the 3-D scene, and side by side with each run, a plane-parallel slab with the
    scene's mean optical depth, albedo and asymmetry (Henyey-Greenstein) traced by kumo's 1-D
    path: the ratio of CPU time per photon, and the slab's own t01."""
    prp = os.path.join(shared, "data", "i3rc", "les_examples", "les_stcu_w213.prp")
    n_ph = 1e6
    control = {"n_photons_per_batch": 10000, "n_batches": 100, "verbose": 1}
    nml = {"control": control,
           "cloud": {"cloud_file": prp, "cloud_format": "prp"},
           "source": {"sza_deg": 60.0},
           "output": {"file": "prp_out.nc", "column_fluxes": False, "voxel_absorption": False}}
    tau, omega, g = prp_means(prp)
    # the slab's optical properties as the run log reports them (7, 7 and 4 digits)
    slab = {"control": control,
            "atmosphere": {"nz": 1, "z_levels": [0.0, 1000.0],
                           "ext1d": [[float(f"{tau / 1000.0:.6e}")]],
                           "ssa1d": [[float(f"{omega:.6f}")]], "phase1d": [[1]]},
            "phase": {"n_phase": 1, "phase_kind": "hg", "phase_g": float(f"{g:.4f}")},
            "source": {"sza_deg": 60.0},
            "output": {"file": "slab_out.nc"}}
    t01, relvar, ratio, t01_slab = [], [], [], []
    cpus = []
    for seed in (1, 2, 3, 4, 5):
        control["seed"] = seed
        kumo.write_namelist(nml, os.path.join(work, "prp.nml"))
        kumo.write_namelist(slab, os.path.join(work, "slab.nml"))
        cpu, r, s = cpu_and_r(run(kumo_exe, "prp.nml", work)[0])
        cpu1, r1, s1 = cpu_and_r(run(kumo_exe, "slab.nml", work)[0])
        t01.append(cpu * (s / r / 0.001) ** 2)
        cpus.append(cpu)
        relvar.append((s / r) ** 2 * n_ph)
        ratio.append(cpu / cpu1)
        t01_slab.append(cpu1 * (s1 / r1 / 0.001) ** 2)
    # pooled: the mean variance per photon times the mean CPU time per photon (steadier than
    # the median of the single runs, whose sigma^2 is uncertain by 14 % each)
    return {"r": r, "t01": statistics.mean(relvar) * statistics.mean(cpus) / n_ph * 1e6,
            "lo": min(t01), "hi": max(t01),
            "relvar": statistics.mean(relvar), "ratio": statistics.median(ratio),
            "t01_slab": statistics.median(t01_slab), "tau": tau, "omega": omega, "g": g}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kumo", default=os.path.join(REPO, "build", "kumo"))
    ap.add_argument("--shared", default=os.path.join(REPO, "..", "shared"))
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    a = ap.parse_args()
    kumo_exe = os.path.abspath(a.kumo)
    work = os.path.join(a.out, "les_bench_work")
    os.makedirs(work, exist_ok=True)
    mb, t_setup, rss = setup_bar(kumo_exe, work)
    fb = flux_bar(kumo_exe, os.path.abspath(a.shared), work)
    text = (
        "# Cloud-file bars (bench/run_les_bench.py)\n\n"
        "| bar | required | measured | met |\n|---|---|---|---|\n"
        f"| 256 x 256 x 100 LES, liquid + ice, setup time (cached tables) | < 10 s | "
        f"{t_setup:.2f} s | {'yes' if t_setup < 10 else 'no'} |\n"
        f"| the same, peak memory of the run / input fields ({mb:.0f} MB float32) | < 3 | "
        f"{rss:.0f} MB = {rss / mb:.2f} | {'yes' if rss < 3 * mb else 'no'} |\n"
        f"| les_stcu_w213.prp, SZA 60, reflectance R = {fb['r']:.4f} to 0.1 %, CPU-s | <= 1 | "
        f"{fb['t01']:.2f} (single runs {fb['lo']:.2f} - {fb['hi']:.2f}) | "
        f"{'yes' if fb['t01'] <= 1 else 'no'} |\n\n"
        "What the flux time is made of (same runs):\n\n"
        f"- relative variance of a photon's score for R: {fb['relvar']:.2f} (mean of the seeds)\n"
        f"- a plane-parallel slab with the scene's mean optics (tau {fb['tau']:.2f}, "
        f"omega {fb['omega']:.4f}, HG g {fb['g']:.3f}), run after each 3-D run: the 3-D scene "
        f"costs {fb['ratio']:.2f} times its CPU time per photon; the slab itself reaches 0.1 % "
        f"in {fb['t01_slab']:.2f} CPU-s\n")
    with open(os.path.join(a.out, "les_bench.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
