# SPDX-License-Identifier: BSD-3-Clause
"""kumo.broadband_total: a shortwave and a longwave run of one scene added, errors in
quadrature (the two runs are independent)."""

import numpy as np
import pytest
import xarray as xr

import kumo


def _run(kind, up, dn, heat, err):
    lev = xr.DataArray([0.0, 1000.0, 2000.0], dims="level")
    lay = xr.DataArray([500.0, 1500.0], dims="layer")
    ds = xr.Dataset(coords={"level": lev, "layer": lay},
                    attrs={"broadband": f"{kind}, Monte Carlo integration over the g-points"})
    for name, values, dim in (("flux_up_wm2", up, "level"), ("flux_down_wm2", dn, "level"),
                              ("flux_net_wm2", np.subtract(dn, up), "level"),
                              ("heating_rate_layer", heat, "layer")):
        ds[name] = xr.DataArray(np.asarray(values, float), dims=dim, attrs={"units": "W m-2"})
        ds[name + "_stderr"] = xr.DataArray(np.full(len(values), err), dims=dim)
    return ds


def test_sums_and_errors_in_quadrature():
    sw = _run("shortwave", [100.0, 110.0, 120.0], [500.0, 600.0, 680.0], [1.0, 2.0], 3.0)
    lw = _run("longwave", [390.0, 370.0, 240.0], [330.0, 300.0, 0.0], [-2.0, -1.5], 4.0)
    tot = kumo.broadband_total(sw, lw)
    np.testing.assert_allclose(tot["flux_net_wm2"], [340.0, 420.0, 320.0])
    np.testing.assert_allclose(tot["heating_rate_layer"], [-1.0, 0.5])
    np.testing.assert_allclose(tot["flux_up_wm2_stderr"], 5.0)      # sqrt(3^2 + 4^2)
    assert tot["flux_up_wm2"].attrs["ancillary_variables"] == "flux_up_wm2_stderr"


def test_refuses_wrong_kinds_and_grids():
    sw = _run("shortwave", [1.0, 1.0, 1.0], [2.0, 2.0, 2.0], [0.0, 0.0], 0.1)
    lw = _run("longwave", [1.0, 1.0, 1.0], [2.0, 2.0, 2.0], [0.0, 0.0], 0.1)
    with pytest.raises(ValueError, match="not a broadband longwave run"):
        kumo.broadband_total(sw, sw)
    with pytest.raises(ValueError, match="not a broadband shortwave run"):
        kumo.broadband_total(lw, lw)
    moved = lw.assign_coords(level=[0.0, 1000.0, 2500.0])
    with pytest.raises(ValueError, match="coordinate level differs"):
        kumo.broadband_total(sw, moved)
