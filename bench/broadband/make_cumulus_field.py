#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""A synthetic trade-wind cumulus field with its moist atmosphere, as an LES netCDF file.

kumo's broadband benchmark (bench/broadband/run_les_broadband_bench.py) needs a cumulus field
whose file carries the model state (temperature, pressure, water vapour) besides the cloud
water, the way LES output does. No such field is distributed with kumo, so this script builds
one from a published case:

* The atmosphere is the initial state of the BOMEX intercomparison (Siebesma et al. 2003,
  J. Atmos. Sci. 60, 1201-1219, Appendix: piecewise-linear profiles of the liquid-water
  potential temperature theta_l and total water q_t; surface pressure 1015 hPa):

      z [m]      0      520    1480   2000   3000
      theta_l K  298.7  298.7  302.4  308.2  311.85
      q_t g/kg   17.0   16.3   10.7   4.2    3.0

* Pressure is integrated hydrostatically from 1015 hPa with the virtual temperature
  (R_d = 287.04 J kg-1 K-1, c_p = 1004.64 J kg-1 K-1, g = 9.80665 m s-2;
  T_v = T (1 + 0.608 q_v - q_l)).
* Clouds: `n_clouds` cumulus towers at random positions (seeded), each a vertical cylinder of
  radius 150-450 m from the base at 600 m (near the BOMEX lifting condensation level) to a top
  between 900 and 1800 m. Inside, the liquid water mixing ratio is a fraction f of the
  adiabatic value, q_l = f Gamma_l (z - z_base) (1 - (r/R)^2) with Gamma_l = 2.0 g/kg per km
  (about the moist-adiabatic rate at 290 K; e.g. Wood 2012, Mon. Weather Rev. 140, 2373) and
  f = 0.6 (sub-adiabatic cumulus cores). Water vapour is q_t - q_l in cloud, q_t outside;
  temperature T = (theta_l + L q_l / (c_p Pi)) Pi with Pi = (p/p0)^(R_d/c_p), p0 = 1000 hPa,
  L = 2.5e6 J/kg.
* Effective radius from a droplet number of 70 cm-3 (maritime) and k = 0.8 (Martin et al.
  1994, J. Atmos. Sci. 51, 1823): r_e = (3 LWC / (4 pi rho_w k N))^(1/3).

The file has the variables kumo's LES reader looks for by default (docs/les-input.md): x, y,
z (centres, m), z_edges, lwc (g m-3), reff (um), temperature (K), p (Pa) and qv (a specific
humidity, kg/kg, with standard_name = "specific_humidity").

Usage:  python3 bench/broadband/make_cumulus_field.py out.nc [--nx 64 --dx 100 --dz 40
        --top 3000 --n-clouds 20 --seed 1]
Needs numpy and netCDF4.
"""

import argparse
import math

import netCDF4
import numpy as np

R_D = 287.04
CP = 1004.64
G0 = 9.80665
LV = 2.5e6
P0 = 1.0e5
RHO_W = 1000.0

Z_NODES = [0.0, 520.0, 1480.0, 2000.0, 3000.0]
THETA_L = [298.7, 298.7, 302.4, 308.2, 311.85]
QT_GKG = [17.0, 16.3, 10.7, 4.2, 3.0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--nx", type=int, default=64, help="columns along x and y")
    ap.add_argument("--dx", type=float, default=100.0, help="column width [m]")
    ap.add_argument("--dz", type=float, default=40.0, help="layer thickness [m]")
    ap.add_argument("--top", type=float, default=3000.0, help="top of the field [m]")
    ap.add_argument("--n-clouds", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()

    nz = int(round(a.top / a.dz))
    ze = np.arange(nz + 1) * a.dz
    zc = 0.5 * (ze[1:] + ze[:-1])
    x = (np.arange(a.nx) + 0.5) * a.dx
    thl = np.interp(zc, Z_NODES, THETA_L)
    qt = 1.0e-3 * np.interp(zc, Z_NODES, QT_GKG)

    # clouds: liquid water mixing ratio [kg/kg] on (z, y, x)
    rng = np.random.default_rng(a.seed)
    ql = np.zeros((nz, a.nx, a.nx))
    xx, yy = np.meshgrid(x, x, indexing="xy")   # (y, x)
    size = a.nx * a.dx
    for _ in range(a.n_clouds):
        cx, cy = rng.uniform(0.0, size, 2)
        radius = rng.uniform(150.0, 450.0)
        top = rng.uniform(900.0, 1800.0)
        base = 600.0
        # periodic distance
        dxp = np.abs(xx - cx)
        dxp = np.minimum(dxp, size - dxp)
        dyp = np.abs(yy - cy)
        dyp = np.minimum(dyp, size - dyp)
        r2 = (dxp**2 + dyp**2) / radius**2
        shape = np.clip(1.0 - r2, 0.0, None)
        for k in range(nz):
            if base <= zc[k] <= top:
                q = 0.6 * 2.0e-6 * (zc[k] - base) * shape
                ql[k] = np.maximum(ql[k], q)
    ql = np.minimum(ql, 0.9 * qt[:, None, None])

    # hydrostatic pressure with the layer-mean virtual temperature (iterated twice)
    p_edge = np.empty(nz + 1)
    p_edge[0] = 101500.0
    for k in range(nz):
        p_edge[k + 1] = p_edge[k]
        for _ in range(3):
            pm = math.sqrt(p_edge[k] * p_edge[k + 1])
            exner = (pm / P0) ** (R_D / CP)
            qlm = ql[k].mean()
            t = (thl[k] + LV * qlm / (CP * exner)) * exner
            qv = qt[k] - qlm
            tv = t * (1.0 + 0.608 * qv - qlm)
            p_edge[k + 1] = p_edge[k] * math.exp(-G0 * a.dz / (R_D * tv))
    p_layer = np.sqrt(p_edge[:-1] * p_edge[1:])
    exner = (p_layer / P0) ** (R_D / CP)
    temp = (thl[:, None, None] + LV * ql / (CP * exner[:, None, None])) * exner[:, None, None]
    qv = qt[:, None, None] - ql
    tv = temp * (1.0 + 0.608 * qv - ql)
    rho = p_layer[:, None, None] / (R_D * tv)
    lwc = 1.0e3 * ql * rho                          # g m-3
    n_drop = 70.0e6                                 # m-3
    reff = np.where(lwc > 0.0, 1.0e6 * np.cbrt(3.0 * 1.0e-3 * lwc / (4.0 * math.pi * RHO_W * 0.8 * n_drop)), 0.0)

    with netCDF4.Dataset(a.out, "w") as f:
        f.title = "synthetic trade-wind cumulus on the BOMEX initial state (make_cumulus_field.py)"
        f.createDimension("x", a.nx)
        f.createDimension("y", a.nx)
        f.createDimension("z", nz)
        f.createDimension("z_edge", nz + 1)
        for name, dim, val in (("x", "x", x), ("y", "y", x), ("z", "z", zc), ("z_edges", "z_edge", ze)):
            v = f.createVariable(name, "f8", (dim,))
            v.units = "m"
            v[:] = val
        def field(name, units, val, std=None):
            v = f.createVariable(name, "f4", ("z", "y", "x"))
            v.units = units
            if std:
                v.standard_name = std
            v[:] = val
        field("lwc", "g m-3", lwc)
        field("reff", "um", reff)
        field("temperature", "K", temp, "air_temperature")
        field("qv", "kg kg-1", qv, "specific_humidity")
        v = f.createVariable("p", "f8", ("z",))
        v.units = "Pa"
        v.standard_name = "air_pressure"
        v[:] = p_layer
    cloudy = lwc > 0
    print(f"{a.out}: {a.nx} x {a.nx} x {nz} voxels of {a.dx:g} x {a.dx:g} x {a.dz:g} m; "
          f"cloud cover {cloudy.any(axis=0).mean():.3f}, cloudy voxels {cloudy.mean():.4f}, "
          f"max LWC {lwc.max():.3f} g m-3, reff {reff[cloudy].min():.1f}-{reff.max():.1f} um, "
          f"surface pressure {p_edge[0]/100:.1f} hPa, top {p_edge[-1]/100:.1f} hPa")


if __name__ == "__main__":
    main()
