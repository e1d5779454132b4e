#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Broadband heating rates of LES fields: cost against error, broadband against one g-point.

Issue bar (docs/performance.md, "Broadband heating rates of LES fields"): a broadband run
reaches a given error on the domain-mean heating-rate profile in at most 3 times the CPU time
of a single-g-point run of the same scene.

Scenes:
* `stcu`: the I3RC LES stratocumulus (examples/data/i3rc_les, 64 x 64 x 16 voxels of 55 x 55 x
  25 m) in the U.S. Standard Atmosphere, as the examples/broadband namelists run it;
* `cumulus`: a synthetic trade-wind cumulus field on the BOMEX initial state with its own
  temperature, pressure and water vapour (bench/broadband/make_cumulus_field.py, 64 x 64 x 75
  voxels of 100 x 100 x 40 m; the gas state of its layers is the file's, above 3 km the U.S.
  Standard Atmosphere).
Cases: shortwave at solar zenith angles 30 and 60 degrees (rrtmgp-gas-sw-g112, surface albedo
0.05) and longwave (rrtmgp-gas-lw-g128, emissivity 0.98). Liquid optics from RRTMGP's table.

For each scene and case, runs are interleaved A B B A (A: broadband, B: `gpoint` alone: the
most energetic shortwave g-point 72, or in the longwave the g-point that the broadband run
draws most, as its log says), each with its own seed, and the CPU time is kumo's own
(`cpu_time_s` of the output). From each run:
* e = rms over the field's layers of the standard error of the domain-mean heating rate,
  divided by the rms of the heating rate itself (a relative error of the profile, so that the
  broadband profile and the one g-point's share compare on the same footing);
* the CPU time to reach a given e is t e^2 (errors fall as 1/sqrt(photons)); the ratio of the
  broadband run's to the g-point's is the figure of the bar (geometric mean over the pairs);
* the CPU time to 0.1 K/day on every layer of the domain mean, t (max_k sigma_k / 0.1)^2, over
  the field's layers and over the whole column;
* the median standard error of the voxel heating rates in cloudy voxels after 60 s of CPU,
  sigma sqrt(t / 60) (a cloudy voxel without any tally counts as unresolved, +inf).

Usage:
    python3 bench/broadband/run_les_broadband_bench.py --kumo build/kumo [--out DIR]
        [--photons 50000 --batches 20 --pairs 1 --scenes stcu,cumulus --cases sw30,sw60,lw]
Needs numpy and netCDF4, and the k-distributions of scripts/fetch-rrtmgp.sh.
"""

import argparse
import json
import math
import os
import re
import statistics
import subprocess
import sys

import netCDF4
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
GPOINT = {"sw": 72, "lw": None}   # lw: the g-point the broadband run draws most (its log)


def example_profile():
    """z_levels and h2o_vmr of examples/broadband/les_stcu_sw.nml (U.S. Standard humidity)."""
    text = open(os.path.join(ROOT, "examples", "broadband", "les_stcu_sw.nml")).read()
    text = re.sub(r"!.*", "", text)

    def values(name):
        # the numbers after "name =" up to the next assignment or the end of the group
        tail = text[text.index(name):].split("=", 1)[1]
        tail = re.split(r"\n\s*[a-z_0-9]+\s*=|/", tail)[0]
        return np.array([float(v) for v in tail.replace(",", " ").split()])

    return values("z_levels"), values("h2o_vmr")


def nml_list(values, fmt="{:g}", per_line=10):
    items = [fmt.format(v) for v in values]
    lines = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
    return ",\n    ".join(lines)


def scene_setup(scene, out):
    """z_levels, h2o_vmr, &kumo_cloud lines, and the cloudy-voxel mask (z, y, x) of a scene."""
    z_ex, h_ex = example_profile()
    if scene == "stcu":
        path = os.path.join(ROOT, "examples", "data", "i3rc_les", "i3rc_les_stcu.lwc")
        cloud = (f"  cloud_file = '{path}'\n  cloud_format = 'lwc'\n")
        # the LWC file: header of 5 lines, then ix iy iz lwc reff
        with open(path) as f:
            lines = f.read().split("\n")
        nx, ny, nz = (int(v) for v in lines[1].split()[:3])
        mask = np.zeros((nz, ny, nx), bool)
        for line in lines[5:]:
            w = line.split()
            if len(w) >= 4 and float(w[3]) > 0:
                mask[int(w[2]) - 1, int(w[1]) - 1, int(w[0]) - 1] = True
        return z_ex, h_ex, cloud, mask
    path = os.path.join(out, "cumulus_bomex.nc")
    if not os.path.exists(path):
        subprocess.run([sys.executable, os.path.join(HERE, "make_cumulus_field.py"), path], check=True)
    with netCDF4.Dataset(path) as f:
        ze = np.array(f["z_edges"][:])
        mask = np.array(f["lwc"][:]) > 0
    above = z_ex[z_ex > ze[-1] + 1.0]
    z = np.concatenate([ze, above])
    zmid = 0.5 * (z[1:] + z[:-1])
    zmid_ex = 0.5 * (z_ex[1:] + z_ex[:-1])
    h = np.exp(np.interp(zmid, zmid_ex, np.log(h_ex)))     # inside the field: replaced by qv
    cloud = f"  cloud_file = '{path}'\n  reff_min_um = 2.0\n  reff_max_um = 30.0\n"
    return z, h, cloud, mask


def write_namelist(path, scene_data, case, photons, batches, seed, gpoint, out_nc):
    z, h, cloud, _ = scene_data
    lw = case == "lw"
    src = "" if lw else f"&kumo_source\n  sza_deg = {case[2:]}.0\n/\n"
    surf = "  albedo = 0.02\n" if lw else "  albedo = 0.05\n"
    kd = "rrtmgp-gas-lw-g128.nc" if lw else "rrtmgp-gas-sw-g112.nc"
    # surface temperature: the U.S. Standard 288.15 K under the stratocumulus, the BOMEX sea
    # surface 300.4 K (Siebesma et al. 2003) under the cumulus
    tsfc = 300.4 if "cumulus" in cloud else 288.15
    extra = f"  t_surface = {tsfc}\n" if lw else ""
    text = (f"&kumo_control\n  n_photons_per_batch = {photons}\n  n_batches = {batches}\n"
            f"  seed = {seed}\n  verbose = 1\n/\n"
            f"&kumo_atmosphere\n  nz = {len(z) - 1}\n  z_levels =\n    {nml_list(z)}\n/\n"
            f"&kumo_cloud\n{cloud}/\n&kumo_surface\n{surf}/\n{src}"
            f"&kumo_output\n  file = '{out_nc}'\n/\n"
            f"&kumo_spectral\n  kdist_file = '{kd}'\n  profile = 'us1976'\n{extra}"
            f"  h2o_vmr =\n    {nml_list(h, '{:.4g}')}\n  floor_share = 0.2\n"
            f"  liquid_optics = 'rrtmgp'\n  gpoint = {gpoint}\n/\n")
    with open(path, "w") as f:
        f.write(text)


def measure(nc_path, mask):
    with netCDF4.Dataset(nc_path) as f:
        cpu = float(f.getncattr("cpu_time_s"))
        hr = np.array(f["heating_rate_layer"][:])
        sd = np.array(f["heating_rate_layer_stderr"][:])
        zl = np.array(f["layer"][:])
        z3 = np.array(f["z3d"][:])
        sv = np.array(f["heating_rate_voxel_stderr"][:])
    field = np.isin(np.round(zl, 6), np.round(z3, 6))
    e = math.sqrt(np.mean(sd[field] ** 2)) / math.sqrt(np.mean(hr[field] ** 2))
    return {
        "cpu": cpu,
        "e": e,
        "t01_field": cpu * (sd[field].max() / 0.1) ** 2,
        "t01_column": cpu * (sd.max() / 0.1) ** 2,
        # a cloudy voxel that no photon touched has no error bar: counted as unresolved (+inf)
        "voxel60": float(np.median(np.where(sv[mask] > 0, sv[mask], np.inf))) * math.sqrt(cpu / 60.0),
        "unresolved": float(np.mean(sv[mask] == 0)),
        "hr_field": hr[field].tolist(),
        "sd_field": sd[field].tolist(),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kumo", required=True)
    ap.add_argument("--out", default="bench_les_broadband")
    ap.add_argument("--photons", type=int, default=50000)
    ap.add_argument("--batches", type=int, default=20)
    ap.add_argument("--pairs", type=int, default=1, help="A B B A blocks per scene and case")
    ap.add_argument("--scenes", default="stcu,cumulus")
    ap.add_argument("--cases", default="sw30,sw60,lw")
    a = ap.parse_args()
    for scene in a.scenes.split(","):
        if scene not in ("stcu", "cumulus"):
            ap.error(f"--scenes: unknown scene {scene!r} (stcu, cumulus)")
    for case in a.cases.split(","):
        if case != "lw" and not re.fullmatch(r"sw[0-9]+", case):
            ap.error(f"--cases: unknown case {case!r} (swNN with the solar zenith angle, lw)")
    os.makedirs(a.out, exist_ok=True)
    kumo = os.path.abspath(a.kumo)
    results = {}
    seed = 1
    for scene in a.scenes.split(","):
        data = scene_setup(scene, os.path.abspath(a.out))
        for case in a.cases.split(","):
            kind = "lw" if case == "lw" else "sw"
            runs = {"broadband": [], "gpoint": []}
            gsingle = GPOINT[kind]
            for _ in range(a.pairs):
                for which in ("broadband", "gpoint", "gpoint", "broadband"):
                    g = 0 if which == "broadband" else gsingle
                    stem = os.path.join(os.path.abspath(a.out), f"{scene}_{case}_{which}_{seed}")
                    write_namelist(stem + ".nml", data, case, a.photons, a.batches, seed, g,
                                   stem + ".nc")
                    with open(stem + ".log", "w") as log:
                        subprocess.run([kumo, stem + ".nml"], check=True, stdout=log,
                                       stderr=subprocess.STDOUT)
                    if gsingle is None:
                        m = re.search(r"largest share [0-9.eE+-]+ to g-point (\d+)",
                                      open(stem + ".log").read())
                        gsingle = int(m.group(1))
                    runs[which].append(measure(stem + ".nc", data[3]))
                    seed += 1
            bb, gp = runs["broadband"], runs["gpoint"]
            ratios = [(b["cpu"] * b["e"] ** 2) / (q["cpu"] * q["e"] ** 2) for b, q in zip(bb, gp)]
            res = {
                "ratio": math.exp(statistics.mean(math.log(r) for r in ratios)),
                "ratios": ratios,
                "gpoint": gsingle,
                "cpu_broadband": statistics.mean(r["cpu"] for r in bb),
                "cpu_gpoint": statistics.mean(r["cpu"] for r in gp),
                "e_broadband": statistics.mean(r["e"] for r in bb),
                "e_gpoint": statistics.mean(r["e"] for r in gp),
                "t01_field": statistics.mean(r["t01_field"] for r in bb),
                "t01_column": statistics.mean(r["t01_column"] for r in bb),
                "voxel60": statistics.mean(r["voxel60"] for r in bb),
                "unresolved": statistics.mean(r["unresolved"] for r in bb),
                "hr_field": bb[0]["hr_field"],
                "sd_field": bb[0]["sd_field"],
            }
            results[f"{scene}/{case}"] = res
            print(f"{scene:8s} {case:5s} g-point {gsingle} ratio {res['ratio']:.2f} "
                  f"(cpu {res['cpu_broadband']:.1f} s vs {res['cpu_gpoint']:.1f} s, "
                  f"e {res['e_broadband']:.2e} vs {res['e_gpoint']:.2e}); "
                  f"0.1 K/day: field {res['t01_field']:.0f} s, column {res['t01_column']:.0f} s; "
                  f"cloudy voxel sigma after 60 s {res['voxel60']:.2f} K/day "
                  f"({100 * res['unresolved']:.1f} % of them without a tally)", flush=True)
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump({"photons": a.photons, "batches": a.batches, "results": results}, f, indent=1)
    print("\n| scene | case | g-point | CPU broadband / one g-point | relative error e, broadband / g-point "
          "| ratio of CPU to the same e | CPU to 0.1 K/day, field layers | whole column "
          "| cloudy-voxel sigma after 60 s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for key, r in results.items():
        s, c = key.split("/")
        print(f"| {s} | {c} | {r['gpoint']} | {r['cpu_broadband']:.1f} / {r['cpu_gpoint']:.1f} s "
              f"| {r['e_broadband']:.2e} / {r['e_gpoint']:.2e} | {r['ratio']:.2f} "
              f"| {r['t01_field']:.0f} s | {r['t01_column']:.0f} s | {r['voxel60']:.2f} K/day |")


if __name__ == "__main__":
    main()
