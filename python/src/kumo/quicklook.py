# SPDX-License-Identifier: BSD-3-Clause
"""Quick-look plots of a kumo output file: ``kumo-quicklook out.nc -o out.png``.

One figure with what the file contains (docs/output.md):

* flux profiles (up, down, direct, diffuse) against height, with error bars;
* the absorption profile: heating rate if the file has it, else absorbed power density, else
  layer absorptance, with error bars;
* per-column maps (reflectance at the top, transmittance at the surface, column absorptance),
  domain-mean radiances against height, radiance maps and camera images; every image comes
  with a panel of its relative standard error (colour scale capped at its 98th percentile, so
  a few near-zero means do not wash it out).

Error bars are +-2 standard errors (about 95 %).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from .results import STDERR_SUFFIX, open_results

K_SIGMA = 2.0          #: error bars are +- K_SIGMA standard errors
MAX_IMAGES = 8         #: most image panels (each with its error panel) in one figure


def _err(ds, name):
    key = name + STDERR_SUFFIX
    return ds[key].values if key in ds else None


def _height_coord(da):
    """The height coordinate [m] of a 1-D profile and its name, or (None, None)."""
    dim = da.dims[0]
    if dim in da.coords:
        return da.coords[dim].values, dim
    return None, None


def _profile_panels(ds):
    """Functions that draw the 1-D profiles, one per panel."""
    panels = []
    flux_names = [n for n in ("flux_up", "flux_down", "flux_down_direct", "flux_down_diffuse")
                  if n in ds and ds[n].ndim == 1]
    if flux_names:
        def draw_fluxes(ax):
            for name in flux_names:
                z, _ = _height_coord(ds[name])
                if z is None:
                    z = np.arange(ds[name].size)
                err = _err(ds, name)
                ax.errorbar(ds[name].values, z / 1000.0,
                            xerr=None if err is None else K_SIGMA * err,
                            marker=".", capsize=2, label=name)
            unit = ds[flux_names[0]].attrs.get("units", "1")
            ax.set_xlabel("flux / (mu0 F0)" if unit == "1" else f"flux [{unit}]")
            ax.set_ylabel("height [km]")
            ax.set_title(f"fluxes (+-{K_SIGMA:g} s.e.)")
            ax.legend(fontsize="small")
        panels.append(draw_fluxes)

    for name in ("heating_rate_layer", "absorbed_power_density_layer", "absorptance_layer"):
        if name in ds and ds[name].ndim == 1:
            def draw_absorption(ax, name=name):
                da = ds[name]
                z, _ = _height_coord(da)
                if z is None:
                    z = np.arange(da.size)
                err = _err(ds, name)
                ax.errorbar(da.values, z / 1000.0, xerr=None if err is None else K_SIGMA * err,
                            marker=".", capsize=2, color="C3")
                ax.set_xlabel(f"[{da.attrs.get('units', '1')}]")
                ax.set_ylabel("height [km]")
                ax.set_title(f"{name} (+-{K_SIGMA:g} s.e.)")
            panels.append(draw_absorption)
            break

    if "radiance" in ds and ds["radiance"].ndim == 2:
        def draw_radiance(ax):
            da = ds["radiance"]
            direction_dim, level_dim = _radiance_dims(da)
            da = da.transpose(direction_dim, level_dim)
            err = ds.get("radiance" + STDERR_SUFFIX)
            err = None if err is None else err.transpose(direction_dim, level_dim).values
            z = (da.coords[level_dim].values if level_dim in da.coords
                 else np.arange(da.sizes[level_dim]))
            for i in range(da.sizes[direction_dim]):
                ax.errorbar(da.isel({direction_dim: i}).values, z / 1000.0,
                            xerr=None if err is None else K_SIGMA * err[i],
                            marker="o", capsize=2, label=_direction_label(ds, da, i))
            ax.set_xlabel("radiance pi I / (mu0 F0)")
            ax.set_ylabel("height [km]")
            ax.set_title(f"radiances (+-{K_SIGMA:g} s.e.)")
            ax.legend(fontsize="x-small")
        panels.append(draw_radiance)
    return panels


def _radiance_dims(da):
    """(direction dim, level dim) of a radiance variable: by name, else the first two."""
    direction = next((d for d in da.dims if "direction" in d), da.dims[0])
    level = next((d for d in da.dims if "level" in d and d != direction),
                 next(d for d in da.dims if d != direction))
    return direction, level


def _direction_label(ds, da, i):
    """'mu=0.5 phi=90' for direction i of a radiance variable: from the coordinates or
    variables along the direction dimension whose names mention mu and phi (the direction
    coordinate itself holds mu when nothing else does)."""
    dim = _radiance_dims(da)[0]
    along = {str(n): v for n, v in {**dict(ds.variables), **dict(da.coords)}.items()
             if v.dims == (dim,)}
    parts = []
    for key in ("mu", "phi"):
        names = [n for n in along if key in n.lower()]
        if key == "mu" and not names and dim in along:
            names = [dim]
        if names:
            parts.append(f"{key}={float(along[names[0]].values[i]):.3g}")
    return " ".join(parts) if parts else f"{dim} {i + 1}"


def _extent(da):
    """imshow extent [km] from the x and y coordinates of a map, or None (pixel indices)."""
    if da.ndim != 2 or da.dims != ("y", "x") or "x" not in da.coords or "y" not in da.coords:
        return None
    ydim, xdim = da.dims
    edges = []
    for dim in (xdim, ydim):
        c = np.asarray(da.coords[dim].values, dtype=float)
        step = c[1] - c[0] if c.size > 1 else 2.0 * c[0]
        edges += [(c[0] - step / 2) / 1000.0, (c[-1] + step / 2) / 1000.0]
    return edges


def _images(ds):
    """(title, values, relative error, extent) of the 2-D images the file holds, the most
    telling first: column maps at the top and the surface, column absorptance, camera images,
    radiance maps, then the direct-beam and horizontal-transport maps."""
    images = []

    def add(title, da, err):
        values = np.asarray(da, dtype=float)
        rel = None
        if err is not None:
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = np.where(values != 0, np.asarray(err, dtype=float) / np.abs(values), np.nan)
        images.append((title, values, rel, _extent(da)))

    def level_map(name, pick, label):
        if name in ds and ds[name].ndim == 3:
            level_dim = ds[name].dims[0]
            err = ds.get(name + STDERR_SUFFIX)
            add(f"{name} ({label})", ds[name].isel({level_dim: pick}),
                None if err is None else err.isel({level_dim: pick}))

    level_map("flux_up_map", -1, "top")
    level_map("flux_down_map", 0, "surface")
    if "absorptance_column" in ds and ds["absorptance_column"].ndim == 2:
        add("absorptance_column", ds["absorptance_column"], _err(ds, "absorptance_column"))
    for name in sorted(str(n) for n in ds.data_vars):
        if name.startswith("camera") and name.endswith("_radiance") and ds[name].ndim == 2:
            add(name, ds[name], _err(ds, name))
    if "radiance_map" in ds and ds["radiance_map"].ndim == 4:
        da = ds["radiance_map"]
        err = ds.get("radiance_map" + STDERR_SUFFIX)
        direction_dim, level_dim = _radiance_dims(da)
        for k in reversed(range(da.sizes[level_dim])):      # top level first
            for i in range(da.sizes[direction_dim]):
                sel = {direction_dim: i, level_dim: k}
                z = (f" z={float(da.coords[level_dim].values[k]):g} m"
                     if level_dim in da.coords else "")
                add(f"radiance_map {_direction_label(ds, da, i)}{z}", da.isel(sel),
                    None if err is None else err.isel(sel))
    level_map("flux_down_direct_map", 0, "surface")
    if "horizontal_transport_map" in ds and ds["horizontal_transport_map"].ndim == 2:
        add("horizontal_transport_map", ds["horizontal_transport_map"],
            _err(ds, "horizontal_transport_map"))
    return images


def quicklook(path, output=None, dpi: int = 120):
    """Draw the quick look of output file ``path``; save it to ``output`` (any format
    matplotlib writes, by its suffix) if given. Returns the matplotlib Figure."""
    import matplotlib
    if output is not None:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ds = open_results(path)
    profiles = _profile_panels(ds)
    images = _images(ds)
    n_skipped = max(0, len(images) - MAX_IMAGES)
    images = images[:MAX_IMAGES]
    if not profiles and not images:
        raise ValueError(f"{path}: nothing to plot (no kumo fluxes, maps or images found)")

    ncols = 4
    # profiles fill the first row(s); each image takes two neighbouring slots (value, error)
    nrows = math.ceil(len(profiles) / ncols) + math.ceil(len(images) / (ncols // 2))
    # fixed spacing: a constrained layout takes twice as long to draw for little gain
    fig = plt.figure(figsize=(4.4 * ncols, 3.6 * nrows))
    grid = fig.add_gridspec(nrows, ncols, left=0.05, right=0.97, bottom=0.35 / nrows,
                            top=1.0 - 0.45 / nrows, wspace=0.45, hspace=0.45)
    slot = 0
    for draw in profiles:
        draw(fig.add_subplot(grid[slot // ncols, slot % ncols]))
        slot += 1
    slot = math.ceil(slot / ncols) * ncols
    for title, values, rel, extent in images:
        row, col = slot // ncols, slot % ncols
        for offset, data, cmap, label, name in ((0, values, "viridis", None, title),
                                                (1, rel, "magma", "%", "relative standard error")):
            ax = fig.add_subplot(grid[row, col + offset])
            if data is None:
                ax.set_axis_off()
                continue
            shown = data if offset == 0 else 100.0 * data
            # relative errors: a few near-zero means must not wash out the colour scale
            vmax = None
            if offset == 1 and np.any(np.isfinite(shown)):
                vmax = float(np.nanpercentile(shown, 98.0))
            im = ax.imshow(shown, origin="lower", cmap=cmap, aspect="auto", extent=extent,
                           interpolation="nearest", vmax=vmax)
            fig.colorbar(im, ax=ax, shrink=0.85, label=label)
            ax.set_title(name, fontsize="small")
            ax.set_xlabel("x [km]" if extent else "pixel")
            ax.set_ylabel("y [km]" if extent else "pixel")
        slot += 2
    title = Path(str(path)).name
    for attr in ("reflectance", "transmittance"):
        if attr in ds and ds[attr].ndim == 0:
            err = _err(ds, attr)
            title += f"   {attr[0].upper()} = {float(ds[attr]):.5f}"
            if err is not None:
                title += f" +- {float(err):.5f}"
    if n_skipped:
        title += f"   ({n_skipped} more images not shown)"
    fig.suptitle(title)
    if output is not None:
        fig.savefig(output, dpi=dpi)
    return fig


def main(argv=None) -> int:
    """The ``kumo-quicklook`` command."""
    parser = argparse.ArgumentParser(
        prog="kumo-quicklook",
        description="Quick-look plots of a kumo output file: flux and heating-rate profiles "
                    "with error bars, per-column maps, radiance and camera images with their "
                    "relative standard error.")
    parser.add_argument("file", help="kumo output file (netCDF)")
    parser.add_argument("-o", "--output",
                        help="image file to write (e.g. out.png, out.pdf); default: the output "
                             "file name with .png")
    parser.add_argument("--dpi", type=int, default=120, help="resolution of raster images")
    args = parser.parse_args(argv)
    output = args.output or str(Path(args.file).with_suffix(".png"))
    try:
        quicklook(args.file, output, dpi=args.dpi)
    except (OSError, ValueError, KeyError) as error:
        print(f"kumo-quicklook: {error}", file=sys.stderr)
        return 1
    print(output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
