#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Two kumo programs (or one program with two sets of &kumo_vr settings) side by side on the
LES workloads: CPU time to a given standard error, run interleaved A B B A.

Workloads (each run is one kumo run; its CPU time is the tracing time cpu_time_s):

  stcu_flux  the I3RC LES stratocumulus at 2.13 um from its SHDOM property file
             (les_stcu_w213.prp), SZA 60, black surface, default preset (unbiased): domain R
             (upward flux at the top) and T (downward flux at the surface) to 0.1 %, and the
             atmosphere's absorptance A to 0.1 %.
  les05_flux the MCARaTS LES05 scene (examples/mcarats_les05, namelists written by its script),
             default preset: domain R, T and A to 0.1 %, and the absorption of the median cloudy
             voxel (extp3d > 1e-6 m-1) to 10 %: t (e_med / 0.1)^2, e_med the median over the
             cloudy voxels of stderr/mean of absorptance_voxel.
  stcu_rad_standard, stcu_rad_unbiased
             the stratocumulus with domain-mean radiances at the top: nadir (mu 1), 60 degrees
             forward (mu 0.5, phi 0) and the exact backscatter direction (mu 0.5, phi 180 =
             the hot spot at SZA 60), with vr_preset 'standard' and 'unbiased': time to 1 %.
             The standard preset's bias against the unbiased preset in every direction is
             given in sigma, from all runs of each program pooled.
  les05_rad_standard, les05_rad_unbiased
             the same directions on LES05 (fluxes as in les05_flux, not scored), to 1 %; at
             SZA 0 nadir is the exact backscatter direction (optional: not in the default list,
             so that one default comparison stays within about 10 minutes on a loaded machine).

For every workload and metric, the time to the target error is t (sigma_rel / target)^2 (the
inverse of the figure of merit 1/(sigma^2 t), scaled), and the ratio new/old is formed per pair
of runs with the same seed (median and range over pairs; below 1 = new is faster). Each round
runs old, new, new, old (then the reverse order in the next round) so that a drift of the
machine's load falls on both alike; the 1-minute load average is logged with every run.

    python3 bench/les_speed/run_les_speed.py --old OLD_KUMO --new NEW_KUMO
        [--old-vr 'key=value,...'] [--new-vr 'key=value,...'] [--rounds 3]
        [--scale 1.0] [--workloads stcu_flux,les05_flux,stcu_rad_standard,stcu_rad_unbiased]
        [--shared DIR] [--label NAME] [--out DIR] [--no-rad-maps]

--no-rad-maps writes radiance_maps = .false. in &kumo_radiance of both sides' radiance runs
(domain-mean radiances only; per-column maps keep the fixed roulette threshold zeta_min).
--old-vr / --new-vr add settings to &kumo_vr of that side's runs (after the preset, so they
override it), e.g. --new-vr "sv_fsupg=4,sv_fsupi=1.5" with --new the same program as --old.
Values are written as given, except that a bare word is quoted (absorption_estimator=track
becomes absorption_estimator = 'track'). --scale multiplies
every photon count. --shared is the folder holding data/i3rc/les_examples/les_stcu_w213.prp
(default: the folder 'shared' next to the repository).

Writes DIR/les_speed[_LABEL].md (table of ratios) and DIR/les_speed[_LABEL].csv (one row per
run and metric); default DIR bench/results. Namelists and outputs go to a scratch folder.
"""
import argparse
import csv
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from netCDF4 import Dataset

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
LES05 = os.path.join(REPO, "examples", "data", "mcarats_les05")
WORKLOADS = ["stcu_flux", "les05_flux", "stcu_rad_standard", "stcu_rad_unbiased"]
# photons per batch and batches of one run at --scale 1 (1.5-3 CPU-s per run on one core of
# the benchmark machine; one round of two programs on all four workloads takes about 40 CPU-s).
# Batches are multiples of the column count (64 x 64, 60 x 60), so that stratified entry gives
# every column the same number of photons; 100 batches pin a run's sigma^2 to about 14 %.
SIZES = {"stcu_flux": (4096, 100), "les05_flux": (3600, 100),
         "stcu_rad_standard": (4096, 50), "stcu_rad_unbiased": (4096, 50),
         "les05_rad_standard": (3600, 40), "les05_rad_unbiased": (3600, 40)}
DIRS = [("nadir", 1.0, 0.0), ("fwd60", 0.5, 0.0), ("hotspot", 0.5, 180.0)]


def load1():
    with open("/proc/loadavg") as f:
        return float(f.read().split()[0])


def vr_text(preset, extra):
    """&kumo_vr group: the preset first, then the extra settings (which override it)."""
    items = []
    if preset:
        items.append(f"vr_preset = '{preset}'")
    items += [quote_word(kv.strip()) for kv in extra.split(",") if kv.strip()] if extra else []
    return f"&kumo_vr {', '.join(items)} /\n" if items else ""


def quote_word(kv):
    """'key=value' with a bare word as value (track) quoted for the namelist ('track');
    numbers, logicals and quoted strings are left as they are."""
    key, sep, value = kv.partition("=")
    v = value.strip()
    if not sep or not v or v[0] in "'\"" or v.lower() in (".true.", ".false.", "t", "f"):
        return kv
    try:
        float(v.replace("d", "e").replace("D", "e"))
        return kv
    except ValueError:
        return f"{key.strip()} = '{v}'"


def stcu_namelist(prp, npb, nb, seed, out, preset, extra, radiance, rad_extra=""):
    text = (f"&kumo_control n_photons_per_batch = {npb}, n_batches = {nb}, seed = {seed}, "
            "verbose = 0 /\n"
            f"&kumo_cloud cloud_file = '{prp}', cloud_format = 'prp' /\n"
            "&kumo_source sza_deg = 60.0, phi0_deg = 0.0 /\n"
            "&kumo_surface albedo = 0.0 /\n"
            f"&kumo_output file = '{out}', column_fluxes = .false., "
            "voxel_absorption = .false. /\n")
    if radiance:
        mus = ", ".join(f"{d[1]}" for d in DIRS)
        phis = ", ".join(f"{d[2]}" for d in DIRS)
        text += f"&kumo_radiance rad_mu = {mus}, rad_phi_deg = {phis}{rad_extra} /\n"
    return text + vr_text(preset, extra)


def les05_namelist(base_text, npb, nb, seed, out, extra, preset="", rad_extra=""):
    text = re.sub(r"&kumo_control[^/]*/",
                  f"&kumo_control n_photons_per_batch = {npb}, n_batches = {nb}, "
                  f"seed = {seed}, verbose = 0 /", base_text)
    text = re.sub(r"(&kumo_output\s+file = ')[^']*'", rf"\g<1>{out}'", text)
    if preset:
        mus = ", ".join(f"{d[1]}" for d in DIRS)
        phis = ", ".join(f"{d[2]}" for d in DIRS)
        text += f"&kumo_radiance rad_mu = {mus}, rad_phi_deg = {phis}{rad_extra} /\n"
    return text + vr_text(preset, extra)


def les05_cloud_mask():
    """Cloudy voxels (z3d, y, x) from the MCARaTS atmosphere file (native float32 records:
    tmpa3d on 22 levels, then abst3d, extp3d, omgp3d, apfp3d on 21 layers of 60 x 60)."""
    a = np.fromfile(os.path.join(LES05, "les05_0213.atm"), "<f4")
    n = 60 * 60
    return a[(22 + 21) * n:(22 + 42) * n].reshape(21, 60, 60) > 1.0e-6


def scalar(nc, name):
    return float(nc[name][:]), float(nc[name + "_stderr"][:])


def metrics(workload, path, cloudy):
    """{metric: (value, stderr, target relative error)} and the CPU time of one output file."""
    res = {}
    with Dataset(path) as nc:
        cpu = float(nc.getncattr("cpu_time_s"))
        work = {"steps_per_photon": float(nc.getncattr("flight_steps_per_photon")),
                "events_per_photon": float(nc.getncattr("events_per_photon"))}
        if workload.endswith("flux"):
            res["R"] = scalar(nc, "reflectance") + (1e-3,)
            res["T"] = scalar(nc, "transmittance") + (1e-3,)
            res["A"] = scalar(nc, "absorptance_atmosphere") + (1e-3,)
        if workload == "les05_flux":
            m = np.array(nc["absorptance_voxel"][:], dtype=float)
            e = np.array(nc["absorptance_voxel_stderr"][:], dtype=float)
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = np.where(m > 0, e / m, np.inf)
            # reported as value 1 with the median relative error as its stderr
            res["abs_cloudy_median"] = (1.0, float(np.median(rel[cloudy])), 0.1)
        if "_rad_" in workload:
            lev = int(np.argmax(np.array(nc["rad_level"][:])))
            r = np.array(nc["radiance"][:], dtype=float)
            s = np.array(nc["radiance_stderr"][:], dtype=float)
            for i, (name, _, _) in enumerate(DIRS):
                res[f"I_{name}"] = (float(r[i, lev]), float(s[i, lev]), 1e-2)
    return cpu, res, work


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--old", required=True, help="kumo program A (today's kumo)")
    ap.add_argument("--new", required=True, help="kumo program B (may be the same as --old)")
    ap.add_argument("--old-vr", default="", help="extra &kumo_vr settings of A: 'k=v,k=v'")
    ap.add_argument("--new-vr", default="", help="extra &kumo_vr settings of B: 'k=v,k=v'")
    ap.add_argument("--rounds", type=int, default=3, help="rounds of A B B A (or B A A B)")
    ap.add_argument("--scale", type=float, default=1.0, help="factor on every photon count")
    ap.add_argument("--workloads", default=",".join(WORKLOADS))
    ap.add_argument("--shared", default=os.path.join(os.path.dirname(REPO), "shared"))
    ap.add_argument("--label", default="", help="suffix of the output files")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(HERE), "results"))
    ap.add_argument("--les05-sza", type=int, default=0, choices=[0, 60])
    ap.add_argument("--no-rad-maps", action="store_true",
                    help="radiance workloads without per-column radiance maps (domain means only)")
    ap.add_argument("--keep", default="", help="keep the scratch folder here")
    a = ap.parse_args()
    # extra &kumo_radiance settings of both sides
    rad_extra = ", radiance_maps = .false." if a.no_rad_maps else ""
    exe = {"old": os.path.abspath(a.old), "new": os.path.abspath(a.new)}
    vr = {"old": a.old_vr, "new": a.new_vr}
    workloads = [w.strip() for w in a.workloads.split(",") if w.strip()]
    for w in workloads:
        if w not in SIZES:
            sys.exit(f"run_les_speed: unknown workload {w!r} (known: {', '.join(SIZES)})")
    prp = os.path.join(os.path.abspath(a.shared), "data", "i3rc", "les_examples",
                       "les_stcu_w213.prp")
    if any(w.startswith("stcu") for w in workloads) and not os.path.isfile(prp):
        sys.exit(f"run_les_speed: {prp} not found (set --shared)")
    work = a.keep or tempfile.mkdtemp(prefix="les_speed_")
    os.makedirs(work, exist_ok=True)
    cloudy = les05_cloud_mask()
    les05_base = ""
    if any(w.startswith("les05") for w in workloads):
        env = dict(os.environ, KUMO=exe["old"], KUMO_RUN_DIR=work)
        subprocess.run(["bash", os.path.join(REPO, "examples", "mcarats_les05",
                                             "run_mcarats_les05.sh"), "1000"],
                       env=env, check=True, capture_output=True)
        with open(os.path.join(work, f"les05_sza{a.les05_sza}.nml")) as f:
            les05_base = f.read()

    rows = []
    t_start = time.time()
    for r in range(a.rounds):
        seed = 101 + r
        order = ["old", "new", "new", "old"] if r % 2 == 0 else ["new", "old", "old", "new"]
        for half, side in enumerate(order):
            # the two runs of a pair (one per side) share a seed
            s = seed * 10 + (0 if half < 2 else 1)
            for w in workloads:
                npb, nb = SIZES[w]
                npb = max(100, int(round(npb * a.scale)))
                out = f"{w}_{side}_{s}.nc"
                preset = w.split("_")[-1] if "_rad_" in w else ""
                if w.startswith("les05"):
                    text = les05_namelist(les05_base, npb, nb, s, out, vr[side], preset,
                                          rad_extra)
                else:
                    text = stcu_namelist(prp, npb, nb, s, out, preset, vr[side], "_rad_" in w,
                                         rad_extra)
                nml = os.path.join(work, f"{w}_{side}_{s}.nml")
                with open(nml, "w") as f:
                    f.write(text)
                ld = load1()
                p = subprocess.run([exe[side], nml], cwd=work, capture_output=True, text=True)
                if p.returncode != 0:
                    sys.exit(f"run_les_speed: {exe[side]} failed on {nml}:\n{p.stdout[-3000:]}"
                             f"\n{p.stderr[-3000:]}")
                cpu, res, wk = metrics(w, os.path.join(work, out), cloudy)
                os.remove(os.path.join(work, out))
                for m, (val, err, target) in res.items():
                    rel = err / val if m != "abs_cloudy_median" else err
                    rows.append(dict(workload=w, metric=m, side=side, round=r, seed=s,
                                     photons=npb * nb, cpu_s=cpu, value=val, stderr=err,
                                     rel_err=rel, target=target,
                                     t_target_s=cpu * (rel / target) ** 2, load1=ld, **wk))
                print(f"{w:18s} {side} seed {s}: cpu {cpu:6.2f} s, load {ld:4.2f}, " +
                      ", ".join(f"{m} {res[m][0]:.5f} +- {res[m][1]:.5f}" for m in res),
                      flush=True)
    elapsed = time.time() - t_start
    if not a.keep:
        shutil.rmtree(work, ignore_errors=True)
    write_results(a, rows, workloads, elapsed)


def pooled(rows):
    """Mean of the runs' values and its standard error (independent runs)."""
    v = [r["value"] for r in rows]
    e = [r["stderr"] for r in rows]
    return statistics.mean(v), (sum(x * x for x in e)) ** 0.5 / len(e)


def write_results(a, rows, workloads, elapsed):
    os.makedirs(a.out, exist_ok=True)
    stem = "les_speed" + (f"_{a.label}" if a.label else "")
    keys = ["workload", "metric", "side", "round", "seed", "photons", "cpu_s", "value", "stderr",
            "rel_err", "target", "t_target_s", "load1", "steps_per_photon", "events_per_photon"]
    with open(os.path.join(a.out, stem + ".csv"), "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=keys)
        wr.writeheader()
        for row in rows:
            wr.writerow({k: row[k] for k in keys})
    loads = [r["load1"] for r in rows]
    lines = [f"# LES speed: new / old ({stem})", "",
             f"old: `{os.path.basename(a.old)}` {a.old_vr or '(defaults)'}; "
             f"new: `{os.path.basename(a.new)}` {a.new_vr or '(defaults)'}; "
             f"{a.rounds} rounds of A B B A, photon scale {a.scale}, {elapsed / 60:.1f} min; "
             f"1-minute load average {min(loads):.2f}-{max(loads):.2f} "
             f"(median {statistics.median(loads):.2f}) on a 2-core machine.", "",
             "Time to error = CPU-s of the tracing x (relative standard error / target)^2; "
             "ratio new/old per pair of runs with the same seed, median (range); below 1 means "
             "new is faster.", "",
             "| workload | metric | target | old: time to target [CPU-s] | new: time [CPU-s] | "
             "ratio new/old | old CPU/photon [us] | CPU/photon new/old | steps/photon old, new |",
             "|---|---|---|---|---|---|---|---|---|"]
    for w in workloads:
        for m in dict.fromkeys(r["metric"] for r in rows if r["workload"] == w):
            sel = {side: [r for r in rows if r["workload"] == w and r["metric"] == m
                          and r["side"] == side] for side in ("old", "new")}
            ratios, cpur = [], []
            for rn in sel["new"]:
                for ro in sel["old"]:
                    if ro["seed"] == rn["seed"]:
                        ratios.append(rn["t_target_s"] / ro["t_target_s"])
                        cpur.append((rn["cpu_s"] / rn["photons"]) / (ro["cpu_s"] / ro["photons"]))
            t_old = statistics.median(r["t_target_s"] for r in sel["old"])
            t_new = statistics.median(r["t_target_s"] for r in sel["new"])
            us = statistics.median(r["cpu_s"] / r["photons"] for r in sel["old"]) * 1e6
            st = (statistics.median(r["steps_per_photon"] for r in sel["old"]),
                  statistics.median(r["steps_per_photon"] for r in sel["new"]))
            target = sel["old"][0]["target"]
            lines.append(f"| {w} | {m} | {target * 100:g} % | {t_old:.3g} | {t_new:.3g} | "
                         f"{statistics.median(ratios):.2f} ({min(ratios):.2f}-{max(ratios):.2f})"
                         f" | {us:.2f} | {statistics.median(cpur):.2f} | "
                         f"{st[0]:.1f}, {st[1]:.1f} |")
    for scene in ("stcu", "les05"):
        std, unb = f"{scene}_rad_standard", f"{scene}_rad_unbiased"
        if std not in workloads or unb not in workloads:
            continue
        lines += ["", f"{scene}: standard preset against the unbiased preset (all runs of each side "
                  "pooled; bias in % of the unbiased value and in its combined standard error):",
                  "", "| direction | side | standard | unbiased | bias [%] | bias [sigma] |",
                  "|---|---|---|---|---|---|"]
        for name, _, _ in DIRS:
            for side in ("old", "new"):
                st = pooled([r for r in rows if r["workload"] == std
                             and r["metric"] == f"I_{name}" and r["side"] == side])
                ub = pooled([r for r in rows if r["workload"] == unb
                             and r["metric"] == f"I_{name}" and r["side"] == side])
                d = st[0] - ub[0]
                sig = (st[1] ** 2 + ub[1] ** 2) ** 0.5
                lines.append(f"| {name} | {side} | {st[0]:.5f} +- {st[1]:.5f} | "
                             f"{ub[0]:.5f} +- {ub[1]:.5f} | {100 * d / ub[0]:+.2f} | "
                             f"{d / sig:+.1f} |")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(a.out, stem + ".md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
