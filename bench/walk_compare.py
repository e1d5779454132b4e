#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Two kumo programs side by side on LES scenes, every output with a standard error compared.

For a change of the 3-D walk that must leave results identical in expectation (photon paths
change at round-off level): each case runs program A with one seed and program B with another,
and every element of every output variable that has a `_stderr` companion (flux profiles, flux
maps, voxel and layer absorption, radiances, net-flux tallies of thermal runs) gives
z = (a - b) / sqrt(sa^2 + sb^2). With the right answer on both sides z is about standard normal:
the mean of z^2 is near 1 and |z| > 3 for about 0.3 % of the elements. B is also run with A's
seed: then the largest |a - b| / sa shows how far the photon paths drift apart.

    python3 bench/walk_compare.py --old A/kumo --new B/kumo [--photons 1000000]
        [--cases stcu_maps,stcu_track,stcu_tentative,stcu_unbiased_rad,stcu_thermal,les05]

Cases (inputs from examples/data): the I3RC LES stratocumulus at 2.13 um, SZA 60, albedo 0.2,
column flux maps at every level and voxel absorption, with the collision, track and tentative
absorption estimators and with the unbiased preset's radiances (DDIS); the same cloud in the
10.7 um window with thermal emission (bench/thermal/run_thermal_bench.py); the MCARaTS LES05
scene at SZA 60 (examples/mcarats_les05). Prints one line per case and a summary per variable.
"""
import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from netCDF4 import Dataset

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "bench" / "thermal"))

STCU = """&kumo_control n_photons_per_batch = {npb}, n_batches = {nb}, seed = {seed}, verbose = 0 /
&kumo_cloud cloud_file = '{lwc}', cloud_format = 'lwc',
  size_distribution = 'gamma', v_eff = 0.1, reff_min_um = 2.0, reff_max_um = 30.0, n_reff = 8,
  mie_cache = 'mie_213.nc' /
&kumo_source sza_deg = 60.0, phi0_deg = 20.0, wavelength_um = 2.13, solar_flux = 1.0 /
&kumo_surface albedo = 0.2 /
&kumo_output file = '{out}', column_fluxes = .true., voxel_absorption = .true. /
"""
RAD = "&kumo_radiance rad_mu = 1.0, 0.5, 0.5, rad_phi_deg = 0.0, 0.0, 180.0 /\n"


def namelist(case, work, npb, nb, seed, out):
    lwc = REPO / "examples" / "data" / "i3rc_les" / "i3rc_les_stcu.lwc"
    if case.startswith("stcu") and case != "stcu_thermal":
        text = STCU.format(npb=npb, nb=nb, seed=seed, lwc=lwc, out=out)
        if case == "stcu_track":
            text += "&kumo_vr absorption_estimator = 'track' /\n"
        elif case == "stcu_tentative":
            text += "&kumo_vr absorption_estimator = 'tentative' /\n"
        elif case == "stcu_unbiased_rad":
            text += RAD + "&kumo_vr vr_preset = 'unbiased' /\n"
        return text
    if case == "stcu_thermal":
        import run_thermal_bench as rtb
        path, _, _ = rtb.stcu_case(Path(work), npb, nb)
        text = path.read_text()
        text = text.replace("seed = 1 /", f"seed = {seed} /")
        return text.replace("file = 'stcu_thermal.nc'", f"file = '{out}'")
    if case == "les05":
        import re
        base = (Path(work) / "les05_sza60.nml").read_text()
        text = re.sub(r"&kumo_control[^/]*/", f"&kumo_control n_photons_per_batch = {npb}, "
                      f"n_batches = {nb}, seed = {seed}, verbose = 0 /", base)
        return re.sub(r"(&kumo_output\s+file = ')[^']*'", rf"\g<1>{out}'", text)
    sys.exit(f"walk_compare: unknown case {case}")


def run(exe, case, work, npb, nb, seed, tag):
    out = f"{case}_{tag}.nc"
    nml = Path(work) / f"{case}_{tag}.nml"
    nml.write_text(namelist(case, work, npb, nb, seed, out))
    p = subprocess.run([exe, str(nml)], cwd=work, capture_output=True, text=True, check=False)
    if p.returncode != 0:
        sys.exit(f"walk_compare: {exe} failed on {nml}:\n{p.stdout[-2000:]}{p.stderr[-2000:]}")
    return Path(work) / out


def arrays(path):
    res = {}
    with Dataset(path) as nc:
        steps = float(nc.getncattr("flight_steps_per_photon"))
        for v in nc.variables:
            if v.endswith("_stderr") or v + "_stderr" not in nc.variables:
                continue
            a = np.ma.filled(nc[v][:].astype(float), np.nan)
            s = np.ma.filled(nc[v + "_stderr"][:].astype(float), np.nan)
            res[v] = (np.atleast_1d(a), np.atleast_1d(s))
    return res, steps


def compare(ra, rb):
    """Per variable: (n, mean z^2, max |z|, n |z| > 3)."""
    out = {}
    for v, (a, sa) in ra.items():
        if v not in rb:
            continue
        b, sb = rb[v]
        den = np.sqrt(sa**2 + sb**2)
        ok = np.isfinite(a) & np.isfinite(b) & (den > 0)
        if not ok.any():
            continue
        z = (a[ok] - b[ok]) / den[ok]
        out[v] = (z.size, float(np.mean(z**2)), float(np.max(np.abs(z))), int(np.sum(abs(z) > 3)))
    return out


def drift(ra, rb):
    """Largest |a - b| / sa over all elements with sa > 0 (same seed on both sides)."""
    m = 0.0
    for v, (a, sa) in ra.items():
        if v not in rb:
            continue
        b = rb[v][0]
        ok = np.isfinite(a) & np.isfinite(b) & (sa > 0)
        if ok.any():
            m = max(m, float(np.max(np.abs(a[ok] - b[ok]) / sa[ok])))
    return m


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--old", required=True)
    ap.add_argument("--new", required=True)
    ap.add_argument("--photons", type=int, default=1000000, help="photons per run")
    ap.add_argument("--batches", type=int, default=40)
    ap.add_argument("--cases", default="stcu_maps,stcu_track,stcu_tentative,stcu_unbiased_rad,"
                    "stcu_thermal,les05")
    ap.add_argument("--verbose", action="store_true", help="one line per variable")
    a = ap.parse_args()
    old, new = os.path.abspath(a.old), os.path.abspath(a.new)
    cases = [c.strip() for c in a.cases.split(",") if c.strip()]
    work = tempfile.mkdtemp(prefix="walk_compare_")
    if "les05" in cases:
        env = dict(os.environ, KUMO=old, KUMO_RUN_DIR=work)
        subprocess.run(["bash", str(REPO / "examples" / "mcarats_les05" / "run_mcarats_les05.sh"),
                        "1000"], env=env, check=True, capture_output=True)
    npb = max(1, a.photons // a.batches)
    total_n = total_big = 0
    total_z2 = 0.0
    print(f"{'case':18s} {'elements':>9s} {'mean z^2':>9s} {'max|z|':>7s} {'|z|>3':>6s} "
          f"{'same-seed max|d|/s':>19s} {'steps A':>8s} {'steps B':>8s}")
    for c in cases:
        pa = run(old, c, work, npb, a.batches, 101, "old")
        pb = run(new, c, work, npb, a.batches, 202, "new")
        ps = run(new, c, work, npb, a.batches, 101, "same")
        ra, sta = arrays(pa)
        rb, stb = arrays(pb)
        rs, _ = arrays(ps)
        cmp = compare(ra, rb)
        n = sum(x[0] for x in cmp.values())
        z2 = sum(x[0] * x[1] for x in cmp.values())
        zmax = max(x[2] for x in cmp.values())
        big = sum(x[3] for x in cmp.values())
        total_n += n
        total_z2 += z2
        total_big += big
        print(f"{c:18s} {n:9d} {z2 / n:9.3f} {zmax:7.2f} {big:6d} {drift(ra, rs):19.2e} "
              f"{sta:8.2f} {stb:8.2f}")
        if a.verbose:
            for v, (nv, mz2, mz, nb3) in sorted(cmp.items()):
                print(f"    {v:40s} {nv:7d} {mz2:7.3f} {mz:6.2f} {nb3:5d}")
    print(f"{'all':18s} {total_n:9d} {total_z2 / total_n:9.3f} {'':7s} {total_big:6d} "
          f"(expected fraction |z|>3: 0.0027, here {total_big / total_n:.4f})")


if __name__ == "__main__":
    main()
