#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Namelist knobs of &kumo_vr on the LES workloads: each setting against the defaults of the same
kumo program, with run_les_speed.py (interleaved A B B A), on the workloads it can change.

    python3 bench/les_speed/run_knobs.py --kumo KUMO [--rounds 2] [--only LABEL,...]
        [--shared DIR] [--out DIR] [--append]

Writes DIR/les_speed_knobs.md (one line per setting and metric: time to the target error,
ratio setting/default, median and range over pairs of runs) and DIR/les_speed_knobs.csv (every
run); default DIR bench/results.
"""
import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
FLUX = "stcu_flux,les05_flux"
RAD = "stcu_rad_unbiased"
# label, workloads, &kumo_vr settings of the 'new' side (the 'old' side keeps the defaults)
KNOBS = [
    ("fsupg1", FLUX, "sv_fsupg=1.0"),
    ("fsupg4", FLUX, "sv_fsupg=4.0"),
    ("fsupi1.1", FLUX, "sv_fsupi=1.1"),
    ("fsupi2", FLUX, "sv_fsupi=2.0"),
    ("svmaxlay1", FLUX, "sv_max_layers=1"),
    ("svmaxlay2", FLUX, "sv_max_layers=2"),
    ("svmaxlay1_fsupg4", FLUX, "sv_max_layers=1,sv_fsupg=4.0"),
    ("svmaxlay1_fsupi1.1", FLUX, "sv_max_layers=1,sv_fsupi=1.1"),
    ("no_sv", FLUX, "use_supervoxels=.false."),
    ("rr_off", FLUX, "rr_threshold=0.0"),
    ("rr_0.1_0.2", FLUX, "rr_threshold=0.1,rr_weight=0.2"),
    ("rr_0.5_1", FLUX, "rr_threshold=0.5,rr_weight=1.0"),
    ("abs_track", "les05_flux", "absorption_estimator='track'"),
    ("abs_tentative", "les05_flux", "absorption_estimator='tentative'"),
    ("ddis0", RAD, "ddis_eps=0.0"),
    ("ddis0.3", RAD, "ddis_eps=0.3"),
    ("zeta0.1", RAD, "zeta_min=0.1"),
    ("zeta1", RAD, "zeta_min=1.0"),
    ("cf3", RAD, "cf_tau_min=3.0"),
]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kumo", required=True)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--only", default="", help="comma-separated labels of KNOBS to run")
    ap.add_argument("--shared", default=os.path.join(os.path.dirname(REPO), "shared"))
    ap.add_argument("--out", default=os.path.join(os.path.dirname(HERE), "results"))
    ap.add_argument("--append", action="store_true",
                    help="keep the runs of les_speed_knobs.csv in DIR (other settings) and add")
    a = ap.parse_args()
    only = [s for s in a.only.split(",") if s]
    scratch = tempfile.mkdtemp(prefix="les_knobs_")
    rows = []
    csv_path = os.path.join(a.out, "les_speed_knobs.csv")
    if a.append and os.path.isfile(csv_path):
        with open(csv_path) as f:
            rows = [r for r in csv.DictReader(f) if not only or r["knob"] not in only]
    for label, workloads, vr in KNOBS:
        if only and label not in only:
            continue
        subprocess.run([sys.executable, os.path.join(HERE, "run_les_speed.py"),
                        "--old", a.kumo, "--new", a.kumo, "--new-vr", vr,
                        "--rounds", str(a.rounds), "--workloads", workloads,
                        "--shared", a.shared, "--label", label, "--out", scratch], check=True)
        with open(os.path.join(scratch, f"les_speed_{label}.csv")) as f:
            for r in csv.DictReader(f):
                r.update(knob=label, setting=vr)
                rows.append(r)
    os.makedirs(a.out, exist_ok=True)
    keys = ["knob", "setting"] + [k for k in rows[0] if k not in ("knob", "setting")]
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    loads = [float(r["load1"]) for r in rows]
    lines = ["# &kumo_vr knobs on the LES workloads (bench/les_speed/run_knobs.py)", "",
             f"Each setting against the defaults of the same program, {a.rounds} rounds of "
             "A B B A; time to target = CPU-s x (relative standard error / target)^2; ratio "
             "setting/default per pair of runs with the same seed, median (range): below 1 the "
             f"setting is faster. 1-minute load average {min(loads):.2f}-{max(loads):.2f} on a "
             "2-core machine.", "",
             "| setting | workload | metric | default: time [CPU-s] | setting: time [CPU-s] | "
             "ratio | CPU/photon ratio | steps/photon default, setting |",
             "|---|---|---|---|---|---|---|---|"]
    for label, _, vr in KNOBS:
        sel = [r for r in rows if r["knob"] == label]
        if not sel:
            continue
        for wl, m in dict.fromkeys((r["workload"], r["metric"]) for r in sel):
            s = {side: [r for r in sel if r["workload"] == wl and r["metric"] == m
                        and r["side"] == side] for side in ("old", "new")}
            ratio, cpur = [], []
            for rn in s["new"]:
                for ro in s["old"]:
                    if ro["seed"] == rn["seed"]:
                        ratio.append(float(rn["t_target_s"]) / float(ro["t_target_s"]))
                        cpur.append(float(rn["cpu_s"]) / float(ro["cpu_s"]))
            t = {k: statistics.median(float(r["t_target_s"]) for r in v) for k, v in s.items()}
            st = {k: statistics.median(float(r["steps_per_photon"]) for r in v)
                  for k, v in s.items()}
            lines.append(f"| {vr} | {wl} | {m} | {t['old']:.3g} | {t['new']:.3g} | "
                         f"{statistics.median(ratio):.2f} ({min(ratio):.2f}-{max(ratio):.2f}) | "
                         f"{statistics.median(cpur):.2f} | {st['old']:.1f}, {st['new']:.1f} |")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(a.out, "les_speed_knobs.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
