#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Broadband 1-D references of a cloudy column, shortwave and longwave, for kumo's broadband
runs (tests/bench/test_broadband_run.F90).

The column is the U.S. Standard Atmosphere 1976 of make_gpoint_reference.py (35 layers up to
80 km, Manabe-Wetherald water vapour, RCEMIP ozone), with a gray cloud layer (layer 3, 2-3 km)
whose optical properties are the same at every g-point:

* shortwave: optical depth 10, single-scattering albedo 0.999, Henyey-Greenstein g = 0.85; sun
  at mu0 = 0.5 with TSI 1361 W m-2, Lambert surface of albedo 0.2 (the clear-sky set-up);
* longwave: optical depth 10, single-scattering albedo 0.4, Henyey-Greenstein g = 0.85; Lambert
  surface of emissivity 0.98 at 288.15 K, nothing from above.

For every g-point the gas optics of jax-rrtmgp (the functions of make_gpoint_reference.py) are
mixed with the cloud as kumo mixes the components of a layer: optical depths add, the scattering
optical depths add (Rayleigh in the shortwave, the cloud), the phase function is the
scattering-weighted mean of the components' Legendre moments, and in the longwave a layer emits
(1 - ssa) times its Planck source (Kirchhoff; PythonicDISORT applies the factor itself). Each
g-point is solved by PythonicDISORT (D. J. Ho 2024, J. Open Source Softw. 9, 6442) with delta-M
scaling; shortwave with 32 streams (16 for the error estimate), longwave with 64 (32). Written:
the broadband fluxes at every level and the heating rate of every layer, with the difference of
the two stream numbers as the reference's own error, in the format of sw_gpoint_reference.txt
and lw_gpoint_reference.txt (without the per-g-point blocks), plus a line
    cloud <layer> <optical depth> <single-scattering albedo> <g>.

Usage (about five minutes on one core; same environment as make_gpoint_reference.py):
    /tmp/venv/bin/python bench/broadband/make_cloudy_reference.py [output folder]
"""

import os
import sys
import time
import warnings
from importlib import metadata

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import make_gpoint_reference as gp  # noqa: E402  (imports jax-rrtmgp, sets float64)

from PythonicDISORT import pydisort  # noqa: E402

CLOUD_LAYER = 3                      # 1-based, from the surface
SW_CLOUD = (10.0, 0.999, 0.85)       # optical depth, ssa, g
LW_CLOUD = (10.0, 0.4, 0.85)
NQ_SW, NQ_SW_CHECK = 32, 16
NQ_LW, NQ_LW_CHECK = 64, 32


def hg_moments(g, n):
    return g ** np.arange(n)


def solve_sw(tau_gas, ray, flux, nquad, cloud=SW_CLOUD):
    """Broadband-ready fluxes (up, diffuse down, direct down at levels 0..nz) of one g-point;
    `cloud`: the cloud layer's optical depth, single-scattering albedo and HG g there."""
    nz = len(tau_gas)
    nleg = nquad + 1
    ct, cs, cg = cloud
    tau_c = np.zeros(nz)
    tau_c[CLOUD_LAYER - 1] = ct
    sca_c = tau_c * cs
    dtau = tau_gas + ray + tau_c
    sca = ray + sca_c
    ssa = np.minimum(np.where(dtau > 0, sca / np.where(dtau > 0, dtau, 1.0), 0.0), gp.SSA_MAX)
    leg = np.zeros((nz, nleg))
    ray_leg = np.zeros(nleg)
    ray_leg[:3] = gp.RAYLEIGH_CHI
    hg = hg_moments(cg, nleg)
    for k in range(nz):
        if sca[k] > 0:
            leg[k] = (ray[k] * ray_leg + sca_c[k] * hg) / sca[k]
        else:
            leg[k, 0] = 1.0
    leg, ssa, dtau = leg[::-1], ssa[::-1], dtau[::-1]     # top to bottom
    tau_lower = np.cumsum(dtau)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = pydisort(tau_lower, ssa, nquad, leg, gp.MU0, flux, 0.0, NLeg=nquad,
                       f_arr=leg[:, nquad], only_flux=True, BDRF_Fourier_modes=[gp.ALBEDO])
    t_lev = np.concatenate([[0.0], tau_lower])[::-1]
    up = np.atleast_1d(out[1](t_lev))
    down, direct = out[2](t_lev)
    return up, np.atleast_1d(down), np.broadcast_to(direct, up.shape)


def solve_lw(tau_gas, bot, top, sfc, nquad, cloud=LW_CLOUD):
    nz = len(tau_gas)
    nleg = nquad + 1
    ct, cs, cg = cloud
    tau_c = np.zeros(nz)
    tau_c[CLOUD_LAYER - 1] = ct
    dtau = np.maximum(tau_gas + tau_c, gp.TAU_MIN)
    thin = (tau_gas + tau_c) < gp.TAU_MIN
    ssa = np.where(dtau > 0, tau_c * cs / dtau, 0.0)
    leg = np.zeros((nz, nleg))
    leg[:, 0] = 1.0
    leg[CLOUD_LAYER - 1] = hg_moments(cg, nleg)
    # top to bottom; Planck radiance linear in optical depth from bot to top of each layer
    leg, ssa, dtau, thin = leg[::-1], ssa[::-1], dtau[::-1], thin[::-1]
    tau_lower = np.cumsum(dtau)
    tau_upper = tau_lower - dtau
    b_upper, b_lower = top[::-1], bot[::-1]
    slope = np.where(thin, 0.0, (b_lower - b_upper) / dtau)
    b_upper = np.where(thin, 0.5 * (b_upper + b_lower), b_upper)
    s_poly = np.column_stack([b_upper - slope * tau_upper, slope])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = pydisort(tau_lower, ssa, nquad, leg, 0.5, 0.0, 0.0, NLeg=nquad,
                       f_arr=leg[:, nquad], only_flux=True, b_pos=gp.EMISSIVITY * sfc, b_neg=0.0,
                       BDRF_Fourier_modes=[1.0 - gp.EMISSIVITY], s_poly_coeffs=s_poly)
    t_lev = np.concatenate([[0.0], tau_lower])[::-1]
    up = np.atleast_1d(out[1](t_lev))
    down, _ = out[2](t_lev)
    return up, np.atleast_1d(down)


def heating(col, net):
    dp = col["p_lev"][:-1] - col["p_lev"][1:]
    return gp.gref.G0 / gp.CP * (net[1:] - net[:-1]) / dp * gp.SECONDS_PER_DAY


def write_results(out, col, rows, net, netc):
    """The broadband lines (one row of fluxes and their errors per level), the heating rates of
    `net` with the difference from `netc` as their error, and the end of the block."""
    for i, bb in enumerate(rows):
        out.write(f"broadband {i} " + " ".join(f"{v:.10e}" for v in bb) + "\n")
    h, hc = heating(col, net), heating(col, netc)
    for l in range(len(h)):
        out.write(f"heating {l + 1} {h[l]:.10e} {abs(h[l] - hc[l]):.3e}\n")
    out.write("end\n")
    return h, hc


def write_head(out, col, names, vmr, cd, kdist, nq, nqc, setup):
    nl = len(col["p_lay"])
    out.write(f"case {col['name']}_cloud {kdist} {nl} {len(names)} 0\n")
    out.write("gases " + " ".join(names) + "\n")
    out.write("setup " + " ".join(f"{v:.17g}" for v in setup) + f" {nq} {nqc}\n")
    for i in range(nl + 1):
        out.write(f"level {i} {col['p_lev'][i]:.17g} {col['t_lev'][i]:.17g}\n")
    for l in range(nl):
        row = [col["p_lay"][l], col["t_lay"][l], cd[l]] + [vmr[g][l] for g in names]
        out.write(f"layer {l + 1} " + " ".join(f"{v:.17g}" for v in row) + "\n")


def run_sw(col, out):
    t0 = time.time()
    names, vmr, cd, tau, ray, solar = gp.sw_optics(col)
    nl, ng = tau.shape
    res = {}
    for nq in (NQ_SW, NQ_SW_CHECK):
        s = np.zeros((3, nl + 1))
        for g in range(ng):
            s += np.array(solve_sw(tau[:, g], ray[:, g], solar[g], nq))
        res[nq] = s
    up, dn, dr = res[NQ_SW]
    upc, dnc, drc = res[NQ_SW_CHECK]
    # checks: the direct beam below the cloud is the clear one times exp(-tau_c/mu0); energy
    tau_above = np.concatenate([np.cumsum((tau + ray)[::-1], axis=0)[::-1], np.zeros((1, ng))])
    beer = (solar * gp.MU0 * np.exp(-tau_above / gp.MU0)).sum(1)
    beer[:CLOUD_LAYER] *= np.exp(-SW_CLOUD[0] / gp.MU0)
    assert np.max(np.abs(dr - beer)) < 1e-8 * solar.sum(), np.max(np.abs(dr - beer))
    net = dn + dr - up
    assert np.all(np.diff(net) >= -1e-6 * solar.sum())
    write_head(out, col, names, vmr, cd, gp.KDIST, NQ_SW, NQ_SW_CHECK,
               [gp.MU0, gp.ALBEDO, col["tsi"]])
    out.write("cloud {} {:.17g} {:.17g} {:.17g}\n".format(CLOUD_LAYER, *SW_CLOUD))
    rows = [[up[i], dn[i], dr[i], abs(up[i] - upc[i]), abs(dn[i] - dnc[i])] for i in range(nl + 1)]
    h, hc = write_results(out, col, rows, net, dnc + drc - upc)
    print(f"{col['name']} cloudy shortwave: {time.time() - t0:.0f} s; TOA up {up[-1]:.4f}, "
          f"surface down {dn[0] + dr[0]:.4f} W m-2; {NQ_SW_CHECK} vs {NQ_SW} streams: up "
          f"{np.max(np.abs(up - upc)):.2e}, down {np.max(np.abs(dn - dnc)):.2e}, heating "
          f"{np.max(np.abs(h - hc)):.2e} K/day", flush=True)


def run_lw(col, out):
    t0 = time.time()
    names, vmr, cd, tau, bot, top, sfc = gp.lw_optics(col)
    nl, ng = tau.shape
    res = {}
    for nq in (NQ_LW, NQ_LW_CHECK):
        s = np.zeros((2, nl + 1))
        for g in range(ng):
            s += np.array(solve_lw(tau[:, g], bot[:, g], top[:, g], sfc[g], nq))
        res[nq] = s
    up, dn = res[NQ_LW]
    upc, dnc = res[NQ_LW_CHECK]
    assert np.max(np.abs(dn[-1])) < 1e-9 * np.max(up)
    surf = gp.EMISSIVITY * np.pi * sfc.sum() + (1 - gp.EMISSIVITY) * dn[0]
    assert abs(up[0] - surf) < 1e-8 * up[0], up[0] - surf
    write_head(out, col, names, vmr, cd, gp.KDIST_LW, NQ_LW, NQ_LW_CHECK,
               [col["tsfc"], gp.EMISSIVITY])
    out.write("cloud {} {:.17g} {:.17g} {:.17g}\n".format(CLOUD_LAYER, *LW_CLOUD))
    rows = [[up[i], dn[i], abs(up[i] - upc[i]), abs(dn[i] - dnc[i])] for i in range(nl + 1)]
    h, hc = write_results(out, col, rows, dn - up, dnc - upc)
    print(f"{col['name']} cloudy longwave: {time.time() - t0:.0f} s; TOA up {up[-1]:.4f}, "
          f"surface down {dn[0]:.4f} W m-2; {NQ_LW_CHECK} vs {NQ_LW} streams: up "
          f"{np.max(np.abs(up - upc)):.2e}, down {np.max(np.abs(dn - dnc)):.2e}, heating "
          f"{np.max(np.abs(h - hc)):.2e} K/day", flush=True)


HEADER = """\
# Broadband {kind} reference of a cloudy column: gas optics from jax-rrtmgp {jr} (jax {jx},
# float64) with a gray cloud layer, fluxes from PythonicDISORT {pd} (delta-M, {nq} streams),
# written by bench/broadband/make_cloudy_reference.py (see its header; README.md here).
# Layers 1..nz from the bottom, levels 0..nz (0 = surface). Units: Pa, K, molecules m-2, W m-2.
# Blocks as in {like}, without the per-g-point ones, and
#   cloud <layer> <optical depth> <single-scattering albedo> <Henyey-Greenstein g>
"""


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        HERE, "..", "..", "tests", "data", "broadband")
    _, well_mixed = gp.gref.rfmip_columns()
    col = gp.gref.us1976_column(well_mixed)
    versions = dict(jr=metadata.version("jax-rrtmgp"), jx=gp.jax.__version__,
                    pd=metadata.version("PythonicDISORT"))
    path = os.path.join(out_dir, "sw_cloudy_reference.txt")
    with open(path, "w") as out:
        out.write(HEADER.format(kind="shortwave", nq=NQ_SW, like="sw_gpoint_reference.txt",
                                **versions))
        run_sw(col, out)
    print(f"wrote {os.path.relpath(path)}")
    path = os.path.join(out_dir, "lw_cloudy_reference.txt")
    with open(path, "w") as out:
        out.write(HEADER.format(kind="longwave", nq=NQ_LW, like="lw_gpoint_reference.txt",
                                **versions))
        run_lw(col, out)
    print(f"wrote {os.path.relpath(path)}")


if __name__ == "__main__":
    main()
