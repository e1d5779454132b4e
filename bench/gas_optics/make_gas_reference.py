#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Reference gas optics from jax-rrtmgp for kumo's test tests/unit/test_gas_optics.F90.

jax-rrtmgp (PyPI `jax-rrtmgp==0.5.0`, run on the CPU with `jax[cpu]` in double precision) is an
independent implementation of the RRTMGP gas optics (Pincus, Mlawer and Delamere 2019, JAMES 11,
3074, doi:10.1029/2019MS001621). This script evaluates it on a few columns and writes, for a
subset of their layers and every g-point, the absorption optical depth (major + minor), the
Rayleigh optical depth (shortwave), the Planck sources (longwave: layer, bottom and top of the
layer, surface) and the solar source per g-point, with the inputs that produced them, to
tests/data/gas_optics/reference.txt.

Columns:
* three RFMIP clear-sky sites (present-day experiment, expt 0) of the file `clearsky_as.nc`
  shipped in the same wheel (RFMIP atmospheric states: Pincus, Forster and Stevens 2016, GMD 9,
  3447, doi:10.5194/gmd-9-3447-2016);
* the U.S. Standard Atmosphere 1976 (temperature and pressure from its definition, NOAA-S/T
  76-1562) with the relative humidity of Manabe and Wetherald (1967, J. Atmos. Sci. 24, 241)
  RH = 0.77 (p/ps - 0.02)/0.98 (saturation vapour pressure over water of Bolton 1980, MWR 108,
  1046) and the RCEMIP ozone profile (Wing et al. 2018, GMD 11, 793, doi:10.5194/gmd-11-793-2018);
* a moist tropical column: the RCEMIP analytic sounding for SST 300 K (Wing et al. 2018) with
  the same ozone profile.
* three layers outside the tables (very high and low pressure and temperature), where both codes
  extend the tables linearly and floor the results at zero.
The well-mixed gases of the last three columns are the RFMIP present-day global means.

The dry-air column of a layer is N_A dp / (g (M_d + M_w r_w)) with g = 9.80665 m s-2,
M_d = 28.9644e-3 and M_w = 18.0153e-3 kg/mol and r_w the water-vapour volume mixing ratio
(relative to dry air); it is written with the other inputs, so the test does not depend on it.

Usage (downloads the wheel's Python dependencies into a virtual environment of your choice):
    python3 -m venv /tmp/jaxenv && /tmp/jaxenv/bin/pip install "jax[cpu]" "jax-rrtmgp==0.5.0"
    /tmp/jaxenv/bin/python bench/gas_optics/make_gas_reference.py [output file]
"""

import math
import os
import sys
from importlib import metadata, resources

import jax

jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import netCDF4  # noqa: E402
import numpy as np  # noqa: E402
from rrtmgp.optics import gas_optics  # noqa: E402
from rrtmgp.optics import lookup_gas_optics_longwave as lw_lookup  # noqa: E402
from rrtmgp.optics import lookup_gas_optics_shortwave as sw_lookup  # noqa: E402
from rrtmgp.optics.lookup_volume_mixing_ratio import LookupVolumeMixingRatio  # noqa: E402

N_A = 6.02214076e23
G0 = 9.80665
M_DRY = 28.9644e-3  # U.S. Standard Atmosphere 1976
M_H2O = 18.0153e-3
R_DRY = 287.04  # J kg-1 K-1, RCEMIP sounding (Wing et al. 2018)

# RFMIP global-mean variable for each RRTMGP gas name (no2 is not in RFMIP: 0).
RFMIP_GM = {
    "co2": "carbon_dioxide_GM", "n2o": "nitrous_oxide_GM", "co": "carbon_monoxide_GM",
    "ch4": "methane_GM", "o2": "oxygen_GM", "n2": "nitrogen_GM",
    "ccl4": "carbon_tetrachloride_GM", "cfc11": "cfc11_GM", "cfc12": "cfc12_GM",
    "cfc22": "hcfc22_GM", "hfc143a": "hfc143a_GM", "hfc125": "hfc125_GM", "hfc23": "hfc23_GM",
    "hfc32": "hfc32_GM", "hfc134a": "hfc134a_GM", "cf4": "cf4_GM",
}
RFMIP_SITES = (0, 40, 80)
# Layers written per column besides the lowest: the nearest to these pressures (Pa), None for the
# highest. 11000 and 9000 Pa straddle the lower/upper boundary of the tables (9948 Pa).
FULL_TARGETS = (11000.0, 9000.0, None)
EXTREME_TARGETS = (50000.0, None)
SHORT_TARGETS = (9000.0,)
# Level sources are written for the first column only; the g256/g224 files are checked on the
# tropical column, lowest and highest layer.
HIGH_RES_CASE = "tropical_rcemip"


def data_dir():
    return resources.files("rrtmgp.optics") / "rrtmgp_data"


def rfmip_columns():
    path = resources.files("rrtmgp.optics") / "test_data" / "clearsky_as.nc"
    cols = []
    with netCDF4.Dataset(str(path)) as ds:
        def units_scale(name):
            u = ds[name].units
            return 1.0 if u == "1" else float(u)
        for site in RFMIP_SITES:
            # The file lists layers from the top; kumo numbers them from the bottom.
            p_lev = np.asarray(ds["pres_level"][site, :], dtype=float)[::-1]
            t_lev = np.asarray(ds["temp_level"][0, site, :], dtype=float)[::-1]
            p_lay = np.asarray(ds["pres_layer"][site, :], dtype=float)[::-1]
            t_lay = np.asarray(ds["temp_layer"][0, site, :], dtype=float)[::-1]
            vmr = {"h2o": np.asarray(ds["water_vapor"][0, site, :], dtype=float)[::-1],
                   "o3": np.asarray(ds["ozone"][0, site, :], dtype=float)[::-1]}
            for gas, var in RFMIP_GM.items():
                vmr[gas] = np.full(p_lay.shape, float(ds[var][0]) * units_scale(var))
            cols.append(dict(name=f"rfmip_site{site}", p_lev=p_lev, t_lev=t_lev, p_lay=p_lay,
                             t_lay=t_lay, vmr=vmr,
                             tsfc=float(ds["surface_temperature"][0, site]),
                             tsi=float(ds["total_solar_irradiance"][site])))
        well_mixed = {gas: float(ds[var][0]) * units_scale(var) for gas, var in RFMIP_GM.items()}
    return cols, well_mixed


def rcemip_ozone(p):
    """RCEMIP ozone (Wing et al. 2018): g1 p^g2 exp(-p/g3) ppmv, p in hPa."""
    ph = p / 100.0
    return 3.6478 * ph**0.83209 * np.exp(-ph / 11.3515) * 1e-6


def e_sat(t):
    """Saturation vapour pressure over water, Pa (Bolton 1980)."""
    return 611.2 * np.exp(17.67 * (t - 273.15) / (t - 29.65))


def us1976(z):
    """U.S. Standard Atmosphere 1976 below 86 km: p (Pa), T (K) at geometric height z (m)."""
    r0 = 6356766.0
    h = r0 * z / (r0 + z)
    hb = [0.0, 11000.0, 20000.0, 32000.0, 47000.0, 51000.0, 71000.0, 84852.0]
    lb = [-6.5e-3, 0.0, 1.0e-3, 2.8e-3, 0.0, -2.8e-3, -2.0e-3]
    gmr = 9.80665 * 28.9644 / 8.31432e3
    t, p = 288.15, 101325.0
    for i in range(7):
        top = min(h, hb[i + 1])
        dh = top - hb[i]
        if lb[i] == 0.0:
            p_new = p * math.exp(-gmr * dh / t)
        else:
            p_new = p * (t / (t + lb[i] * dh)) ** (gmr / lb[i])
        t_new = t + lb[i] * dh
        if h <= hb[i + 1]:
            return p_new, t_new
        t, p = t_new, p_new
    return p, t


def column_from_levels(name, z_lev, state, well_mixed, tsfc, tsi):
    """Layers between levels z_lev; state(z) -> (p, T, r_h2o). Layer p, T: level means."""
    p_lev, t_lev, q_lev = np.array([state(z) for z in z_lev]).T
    p_lay = np.sqrt(p_lev[:-1] * p_lev[1:])
    zl = 0.5 * (z_lev[:-1] + z_lev[1:])
    t_lay = np.array([state(z)[1] for z in zl])
    q_lay = np.array([state(z)[2] for z in zl])
    vmr = {"h2o": q_lay, "o3": rcemip_ozone(p_lay)}
    for gas, v in well_mixed.items():
        vmr[gas] = np.full(p_lay.shape, v)
    return dict(name=name, p_lev=p_lev, t_lev=t_lev, p_lay=p_lay, t_lay=t_lay, vmr=vmr,
                tsfc=tsfc, tsi=tsi)


def us1976_column(well_mixed):
    ps = 101325.0

    def state(z):
        p, t = us1976(z)
        rh = max(0.77 * (p / ps - 0.02) / 0.98, 0.0)
        e = rh * e_sat(t)
        return p, t, max(e / (p - e), 1e-6)  # volume mixing ratio relative to dry air
    z = np.concatenate([np.arange(0.0, 20000.0, 1000.0), np.arange(20000.0, 80001.0, 4000.0)])
    return column_from_levels("us1976", z, state, well_mixed, 288.15, 1361.0)


def rcemip_column(well_mixed):
    """RCEMIP initial sounding for SST 300 K (Wing et al. 2018, section 2.3)."""
    q0, zq1, zq2, zt, qt = 0.01865, 4000.0, 7500.0, 15000.0, 1e-14
    t0, gamma, p0 = 300.0, 0.0067, 101480.0
    tv0 = t0 * (1 + 0.608 * q0)
    tvt = tv0 - gamma * zt
    pt = p0 * (tvt / tv0) ** (G0 / (R_DRY * gamma))

    def state(z):
        if z <= zt:
            q = q0 * math.exp(-z / zq1) * math.exp(-(z / zq2) ** 2)
            tv = tv0 - gamma * z
            p = p0 * (tv / tv0) ** (G0 / (R_DRY * gamma))
        else:
            q, tv = qt, tvt
            p = pt * math.exp(-G0 * (z - zt) / (R_DRY * tvt))
        t = tv / (1 + 0.608 * q)
        r = q / (1 - q) * (M_DRY / M_H2O)  # specific humidity -> mixing ratio by volume
        return p, t, r
    z = np.concatenate([np.arange(0.0, 3000.0, 250.0), np.arange(3000.0, 18000.0, 750.0),
                        np.arange(18000.0, 40001.0, 2000.0)])
    return column_from_levels("tropical_rcemip", z, state, well_mixed, 300.0, 1361.0)


def extremes_column(well_mixed):
    """Three layers outside the tables: 1105 hPa and 330 K, 500 hPa and 362 K, 0.6 Pa and 150 K
    (level temperatures down to 140 K), where both codes extend the tables linearly and floor
    the results at zero (Planck fractions: held at the table edge)."""
    p_lev = np.array([111000.0, 110000.0, 1.0, 0.2])
    p_lay = np.array([110500.0, 50000.0, 0.6])
    vmr = {"h2o": np.array([0.03, 0.01, 3e-6]), "o3": rcemip_ozone(p_lay)}
    for gas, v in well_mixed.items():
        vmr[gas] = np.full(p_lay.shape, v)
    return dict(name="out_of_table", p_lev=p_lev, t_lev=np.array([335.0, 325.0, 200.0, 140.0]),
                p_lay=p_lay, t_lay=np.array([330.0, 362.0, 150.0]), vmr=vmr, tsfc=340.0,
                tsi=1361.0)


def col_dry(p_lev, r_h2o):
    dp = p_lev[:-1] - p_lev[1:]
    return N_A * dp / (G0 * (M_DRY + M_H2O * r_h2o))


def pick_layers(p_lay, targets):
    """The lowest layer, the layers nearest to the target pressures (Pa) and, for a target
    None, the highest layer."""
    idx = {0}
    for p in targets:
        idx.add(len(p_lay) - 1 if p is None else int(np.argmin(np.abs(p_lay - p))))
    return sorted(idx)


def fmt(values):
    return " ".join(f"{v:.9e}" for v in np.asarray(values, dtype=float))


def run_case(out, kind, fname, col, targets, levels=False):
    path = str(data_dir() / fname)
    lk = (lw_lookup if kind == "lw" else sw_lookup).from_nc_file(path)
    names = sorted((g for g in lk.idx_gases if g not in ("dry_air", "h2o_frgn", "h2o_self")),
                   key=lambda g: lk.idx_gases[g])
    layers = pick_layers(col["p_lay"], targets)
    p = jnp.asarray(col["p_lay"][layers])
    t = jnp.asarray(col["t_lay"][layers])
    t_bot = jnp.asarray(col["t_lev"][layers])
    t_top = jnp.asarray(col["t_lev"][[i + 1 for i in layers]])
    cd_all = col_dry(col["p_lev"], col["vmr"]["h2o"])
    cd = jnp.asarray(cd_all[layers])
    vmr = {g: np.asarray(col["vmr"].get(g, np.zeros_like(col["p_lay"])))[layers] for g in names}
    vmr_fields = {lk.idx_gases[g]: jnp.asarray(vmr[g]) for g in names}
    vmr_lib = LookupVolumeMixingRatio(global_means={"dry_air": 1.0})

    out.write(f"case {col['name']} {fname} {len(layers)} {len(names)}\n")
    out.write("gases " + " ".join(names) + "\n")
    out.write(f"surface {col['tsfc']:.17g} {col['tsi']:.17g}\n")
    for k, l in enumerate(layers):
        row = [col["p_lay"][l], col["t_lay"][l], cd_all[l], col["t_lev"][l], col["t_lev"][l + 1],
               col["p_lev"][l], col["p_lev"][l + 1]]
        row += [vmr[g][k] for g in names]
        out.write(f"layer {l + 1} " + " ".join(f"{v:.17g}" for v in row) + "\n")

    ngpt = lk.n_gpt
    t_sfc = jnp.asarray(col["tsfc"])

    @jax.jit
    def per_gpt(ig):
        """Every quantity of one g-point (jit-compiled once per case)."""
        res = {"tau": gas_optics.compute_major_optical_depth(lk, vmr_lib, cd, t, p, ig, vmr_fields)
               + gas_optics.compute_minor_optical_depth(lk, vmr_lib, cd, t, p, ig, vmr_fields)}
        if kind == "sw":
            res["tau_rayleigh"] = gas_optics.compute_rayleigh_optical_depth(
                lk, vmr_lib, cd, t, p, ig, vmr_fields)
        else:
            pf = gas_optics.compute_planck_fraction(lk, vmr_lib, p, t, ig, vmr_fields)
            res["lay_src"] = gas_optics.compute_planck_sources(lk, pf, t, ig)
            res["lev_src_bot"] = gas_optics.compute_planck_sources(lk, pf, t_bot, ig)
            res["lev_src_top"] = gas_optics.compute_planck_sources(lk, pf, t_top, ig)
            res["sfc_src"] = gas_optics.compute_planck_sources(lk, pf[0], t_sfc, ig)
        return res

    res = [per_gpt(jnp.asarray(g)) for g in range(ngpt)]
    table = {q: np.array([np.asarray(r[q]) for r in res]).T for q in res[0]}
    rows = ["tau", "tau_rayleigh", "lay_src"] + (["lev_src_bot", "lev_src_top"] if levels else [])
    for k, l in enumerate(layers):
        for q in rows:
            if q in table:
                out.write(f"{q} {l + 1} " + fmt(table[q][k]) + "\n")
    if kind == "lw" and layers[0] == 0:
        out.write("sfc_src 0 " + fmt(table["sfc_src"]) + "\n")
    if kind == "sw":
        out.write("solar_src 0 " + fmt(np.asarray(lk.solar_src_scaled) * col["tsi"]) + "\n")
    out.write("end\n")


def main():
    out_path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(__file__), "..", "..", "tests", "data", "gas_optics", "reference.txt")
    rfmip, well_mixed = rfmip_columns()
    cols = rfmip + [us1976_column(well_mixed), rcemip_column(well_mixed),
                    extremes_column(well_mixed)]
    with open(out_path, "w") as out:
        out.write("# Reference RRTMGP gas optics from jax-rrtmgp "
                  f"{metadata.version('jax-rrtmgp')} (jax {jax.__version__}, float64),\n"
                  "# written by bench/gas_optics/make_gas_reference.py (see its header for the\n"
                  "# columns and their sources). Blocks:\n"
                  "#   case <column> <k-distribution file> <n layers> <n gases>\n"
                  "#   gases <names in the order of the vmr columns>\n"
                  "#   surface <surface temperature K> <total solar irradiance W m-2>\n"
                  "#   layer <index from the bottom> p[Pa] T[K] col_dry[molecules m-2] "
                  "T_bottom[K] T_top[K]\n"
                  "#     p_bottom[Pa] p_top[Pa] vmr...\n"
                  "#   <quantity> <layer index, 0 for column quantities> <one value per g-point>\n"
                  "#     tau, tau_rayleigh: optical depth; lay_src, lev_src_bot, lev_src_top,\n"
                  "#     sfc_src: Planck source W m-2 sr-1; solar_src: W m-2\n"
                  "#   end\n")
        for i, col in enumerate(cols):
            targets = SHORT_TARGETS if col["name"] in ("rfmip_site40", "rfmip_site80") \
                else EXTREME_TARGETS if col["name"] == "out_of_table" else FULL_TARGETS
            run_case(out, "lw", "rrtmgp-gas-lw-g128.nc", col, targets, levels=(i == 0))
            run_case(out, "sw", "rrtmgp-gas-sw-g112.nc", col, targets)
        for col in cols:
            if col["name"] == HIGH_RES_CASE:
                run_case(out, "lw", "rrtmgp-gas-lw-g256.nc", col, (None,))
                run_case(out, "sw", "rrtmgp-gas-sw-g224.nc", col, (None,))
    print(f"wrote {out_path}")


if __name__ == "__main__":
    main()
