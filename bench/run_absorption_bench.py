#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Per-voxel absorption of the MCARaTS LES05 scene by kumo's absorption estimators, run on demand.

The scene of examples/mcarats_les05 (60 x 60 x 21 voxels of 30 x 30 x 10 m, 2.13 um, gas and
aerosol everywhere, cloud in half of the voxels), its namelists written by
examples/mcarats_les05/run_mcarats_les05.sh, is run with &kumo_vr absorption_estimator =
'collision' (the default), 'track' and 'tentative', interleaved (A B C C B A ... so that a drift
of the machine's load falls on all alike), each run B batches of N photons. Per run:

* cloudy voxels (the file's cloud extinction extp3d > 1e-6 m-1): the CPU time to a 10 %
  standard error on the median cloudy voxel, t (e_med / 0.1)^2 with e_med the median over the
  cloudy voxels of stderr/mean of absorptance_voxel and t the tracing CPU time (cpu_time_s);
* clear voxels: the fraction whose tally is zero in every batch (mean exactly 0), and the time
  to 10 % on the median clear voxel where it is defined;
* the domain absorption (absorptance_atmosphere) and the absorption of the 3-D region: relative
  standard error and figure of merit 1/(sigma_rel^2 t).

The ratios old/new of the times (and new/old of the figures of merit) are formed per pair of
runs with the same seed and reported as median and range.

    python3 bench/run_absorption_bench.py [--kumo build/kumo] [--kumo-old OLD] [--sza 0]
        [--photons 20000] [--batches 100] [--rounds 2] [--estimators collision,track,tentative]
        [--out DIR]

With --kumo-old, a kumo built before the switch existed runs the same cases (labelled 'old'),
so that the default path's cost can be compared with it.

Writes DIR/absorption_bench_sza<SZA>.md and .csv (default bench/results/).
"""
import argparse
import csv
import os
import re
import statistics
import subprocess
import sys

import numpy as np
from netCDF4 import Dataset

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
DATA = os.path.join(REPO, "examples", "data", "mcarats_les05")
ESTIMATORS = ["collision", "track", "tentative"]


def cloud_mask():
    """Cloudy voxels (z3d, y, x) from the MCARaTS atmosphere file (native float32 records:
    tmpa3d on 22 levels, then abst3d, extp3d, omgp3d, apfp3d on 21 layers of 60 x 60)."""
    a = np.fromfile(os.path.join(DATA, "les05_0213.atm"), "<f4")
    n = 60 * 60
    ext = a[(22 + 21) * n:(22 + 42) * n].reshape(21, 60, 60)
    return ext > 1.0e-6


def namelists(kumo, run_dir):
    """Let the example script write its namelists (and the aerosol table) with a tiny run."""
    env = dict(os.environ, KUMO=kumo, KUMO_RUN_DIR=run_dir)
    subprocess.run(["bash", os.path.join(REPO, "examples", "mcarats_les05",
                                         "run_mcarats_les05.sh"), "1000"],
                   env=env, check=True, capture_output=True)


def make_case(run_dir, sza, est, photons, batches, seed):
    text = open(os.path.join(run_dir, f"les05_sza{sza}.nml")).read()
    text = re.sub(r"&kumo_control[^/]*/",
                  f"&kumo_control n_photons_per_batch = {photons}, n_batches = {batches}, "
                  f"seed = {seed} /", text)
    text = re.sub(r"(&kumo_output\s+file = ')[^']*'", rf"\g<1>absb_{est}_{seed}.nc'", text)
    if est != "old":
        text += f"&kumo_vr absorption_estimator = '{est}' /\n"
    path = os.path.join(run_dir, f"absb_{est}_{seed}.nml")
    with open(path, "w") as f:
        f.write(text)
    return path, os.path.join(run_dir, f"absb_{est}_{seed}.nc")


def measure(kumo, run_dir, nml, out, cloudy):
    subprocess.run([kumo, nml], cwd=run_dir, check=True, capture_output=True)
    with Dataset(out) as nc:
        t = float(nc.getncattr("cpu_time_s"))
        m = np.array(nc["absorptance_voxel"][:], dtype=float)
        e = np.array(nc["absorptance_voxel_stderr"][:], dtype=float)
        a = float(nc["absorptance_atmosphere"][:])
        ea = float(nc["absorptance_atmosphere_stderr"][:])
        al = np.array(nc["absorptance_layer"][:], dtype=float)
    os.remove(out)
    clear = ~cloudy
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(m > 0, e / m, np.inf)
    r_cloud = float(np.median(rel[cloudy]))
    r_clear = float(np.median(rel[clear]))
    return {
        "cpu_s": t,
        "cloudy_rel_median": r_cloud,
        "t10_cloudy_s": t * (r_cloud / 0.1) ** 2,
        "clear_zero_frac": float(np.mean(m[clear] == 0.0)),
        "clear_rel_median": r_clear,
        "t10_clear_s": t * (r_clear / 0.1) ** 2 if np.isfinite(r_clear) else float("inf"),
        "A_atm": a,
        "A_atm_rel": ea / a,
        "fom_A_atm": 1.0 / ((ea / a) ** 2 * t),
        "A_3d": float(np.sum(m) / (60 * 60)),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kumo", default=os.path.join(REPO, "build", "kumo"))
    ap.add_argument("--sza", type=int, default=0, choices=[0, 60])
    ap.add_argument("--photons", type=int, default=20000)
    ap.add_argument("--batches", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--estimators", default=",".join(ESTIMATORS))
    ap.add_argument("--kumo-old", default="",
                    help="a kumo built without the absorption_estimator switch: its runs are "
                         "labelled 'old' and interleaved with the others")
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    args = ap.parse_args()
    kumo = os.path.abspath(args.kumo)
    ests = args.estimators.split(",")
    if args.kumo_old:
        ests = ["old"] + ests
    run_dir = os.path.join(REPO, "examples", "mcarats_les05", "run")
    os.makedirs(run_dir, exist_ok=True)
    namelists(kumo, run_dir)
    cloudy = cloud_mask()
    rows = []
    for r in range(args.rounds):
        seed = 11 + r
        order = ests if r % 2 == 0 else ests[::-1]
        for est in order + order[::-1]:
            nml, out = make_case(run_dir, args.sza, est, args.photons, args.batches, seed)
            exe = os.path.abspath(args.kumo_old) if est == "old" else kumo
            res = measure(exe, run_dir, nml, out, cloudy)
            res.update(estimator=est, seed=seed, sza=args.sza)
            rows.append(res)
            print(f"{est:10s} seed {seed}: cpu {res['cpu_s']:.1f} s, cloudy median rel "
                  f"{res['cloudy_rel_median']:.4f} (t10 {res['t10_cloudy_s']:.1f} s), clear zero "
                  f"{res['clear_zero_frac']:.3f}, clear rel {res['clear_rel_median']:.4f}, "
                  f"A_atm {res['A_atm']:.5f} +- {res['A_atm_rel'] * res['A_atm']:.5f}",
                  flush=True)
            os.remove(nml)
    os.makedirs(args.out, exist_ok=True)
    keys = ["estimator", "sza", "seed", "cpu_s", "cloudy_rel_median", "t10_cloudy_s",
            "clear_zero_frac", "clear_rel_median", "t10_clear_s", "A_atm", "A_atm_rel",
            "fom_A_atm", "A_3d"]
    csv_path = os.path.join(args.out, f"absorption_bench_sza{args.sza}.csv")
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for row in rows:
            w.writerow({k: row[k] for k in keys})
    # ratios to the collision estimator, run by run in the order A B C C B A (each new run is
    # paired with the collision run of the same seed and half-round)
    lines = [f"# Absorption estimators on MCARaTS LES05, SZA {args.sza}",
             "", f"{args.batches} batches of {args.photons} photons per run, {args.rounds} "
             "rounds; cloudy = extp3d > 1e-6 m-1 "
             f"({int(cloudy.sum())} voxels), clear = the other {int((~cloudy).sum())}.", "",
             "| estimator | CPU s | cloudy: median rel. err. | t(10 %) cloudy [s] | "
             "clear: zero tallies | clear: median rel. err. | A_atm rel. err. | "
             "FOM A_atm [1/s] |", "|---|---|---|---|---|---|---|---|"]
    for est in ests:
        sel = [r for r in rows if r["estimator"] == est]
        def med(k):
            return statistics.median(r[k] for r in sel)
        lines.append(f"| {est} | {med('cpu_s'):.1f} | {med('cloudy_rel_median'):.4f} | "
                     f"{med('t10_cloudy_s'):.1f} | {med('clear_zero_frac'):.3f} | "
                     f"{med('clear_rel_median'):.4f} | {med('A_atm_rel'):.2e} | "
                     f"{med('fom_A_atm'):.3g} |")
    lines += ["", "Ratios to the collision estimator (pairs of the same seed; median, range):", "",
              "| estimator | t(10 %) cloudy: old/new | CPU per photon: new/old | "
              "FOM A_atm: new/old |", "|---|---|---|---|"]
    for est in ests:
        if est == "collision":
            continue
        # 'old' is compared with 'collision' too: the cost of the switch on the default path
        rt, rc, rf = [], [], []
        for r in rows:
            if r["estimator"] != est:
                continue
            base = [b for b in rows if b["estimator"] == "collision" and b["seed"] == r["seed"]]
            for b in base:
                rt.append(b["t10_cloudy_s"] / r["t10_cloudy_s"])
                rc.append(r["cpu_s"] / b["cpu_s"])
                rf.append(r["fom_A_atm"] / b["fom_A_atm"])
        if rt:
            lines.append(f"| {est} | {statistics.median(rt):.2f} ({min(rt):.2f}-{max(rt):.2f}) | "
                         f"{statistics.median(rc):.2f} ({min(rc):.2f}-{max(rc):.2f}) | "
                         f"{statistics.median(rf):.2f} ({min(rf):.2f}-{max(rf):.2f}) |")
    with open(os.path.join(args.out, f"absorption_bench_sza{args.sza}.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())
