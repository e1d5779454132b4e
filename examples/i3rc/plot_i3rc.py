#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Extract the I3RC products from kumo output files, tabulate their domain means and plot them.

For each kumo output file written from a namelist of i3rc_cases.py (the 3-D region spans the
whole atmosphere; flux and radiance levels at the ground, the cloud base when it is above the
ground, and the top), the per-pixel I3RC products and their standard errors are

  R     flux_up_map at the top                              (reflectance)
  T     flux_down_map at the cloud base                     (transmittance, direct + diffuse)
  A     absorptance_column                                  (absorptance)
  H     horizontal_transport_map                            (net horizontal transport)
  Iu    radiance_map, mu  1.0, top                          (nadir reflectivity)
  Id    radiance_map, mu -1.0, cloud base                   (zenith transmissivity, diffuse)
  I601  radiance_map, mu  0.5, phi   0, top                 (60 deg, light towards +x)
  I602  radiance_map, mu  0.5, phi 180, top                 (60 deg, light towards -x)

The cloud base is the lowest level above the ground when the file has three or more levels
(i3rc_cases.py writes 0, base, top for cases 2 and 3), else the ground (case 1, whose cloud
starts at the ground); the I3RC consensus files give T and Id there. All are normalised by the
incident flux mu0 F0 (radiances as pi I / (mu0 F0)), each with kumo's own
per-pixel standard error. Domain means
of R, T, A and the radiances are kumo's domain products (reflectance, transmittance,
absorptance_atmosphere, radiance) with their standard errors. The domain mean of H is the mean
of its map; over the periodic domain the sideways transport cancels and what is left is the
weight changed by Russian roulette (and DDIS) inside the 3-D region, so its standard error is
taken from roulette_weight_balance_stderr: exact over a black surface, an overestimate when
roulette also acts on photons reflected by the surface.

Written next to each input file (or into --out-dir):

  <name>_summary.txt   domain means +- standard errors, pixel ranges, the closure
                       R + T_net + A + H = 1 (T_net = T minus the upward flux at the ground,
                       which is T itself over a black surface) over the domain and per column
                       (where it equals the incident flux of the column), and for ICA runs the
                       largest |H| of a column
  <name>.png           2-D cases (ny = 1): the products against x with +-1 standard error bands;
                       3-D cases: images

`--compare OTHER.nc` (one input file) adds the other run to the table (difference +- combined
standard error, the runs taken as independent) and writes `<name>_vs_<other>.png`: overlays and
differences for 2-D cases, difference images for 3-D cases (e.g. F3D - ICA).
`--markdown FILE` appends one table row per input file (domain means and wall time).

Usage:
  python3 examples/i3rc/plot_i3rc.py RUN.nc [RUN2.nc ...] [--compare OTHER.nc] [--out-dir DIR]
      [--markdown TABLE.md] [--no-plot]
"""
import argparse
import os
import sys

import numpy as np

PRODUCTS = ('R', 'T', 'A', 'H', 'Iu', 'Id', 'I601', 'I602')
FLUXES = ('R', 'T', 'A', 'H')
RADIANCES = ('Iu', 'Id', 'I601', 'I602')
LONG = {'R': 'reflectance', 'T': 'transmittance', 'A': 'absorptance',
        'H': 'net horizontal transport', 'Iu': 'nadir reflectivity (mu 1, top)',
        'Id': 'zenith transmissivity (mu -1, cloud base)',
        'I601': 'reflectivity mu 0.5 phi 0 (top)', 'I602': 'reflectivity mu 0.5 phi 180 (top)'}
#: the radiance products: (mu, phi [deg], level 'top' or 'base' (the cloud base))
RAD_DIRS = {'Iu': (1.0, None, 'top'), 'Id': (-1.0, None, 'base'),
            'I601': (0.5, 0.0, 'top'), 'I602': (0.5, 180.0, 'top')}


def base_index(heights):
    """Index of the cloud-base level among `heights`: the lowest above the ground when there are
    three or more levels, else the ground."""
    order = np.argsort(heights)
    return int(order[1]) if len(heights) > 2 else int(order[0])


class ProductError(Exception):
    """The file lacks something the I3RC products need."""


class Run:
    """The I3RC products of one kumo output file.

    maps[p], maps_se[p]: (ny, nx) arrays; mean[p], mean_se[p]: domain means and their standard
    errors; x, y: column centres [m]; plus run metadata and closure diagnostics."""

    def __init__(self, path):
        from netCDF4 import Dataset
        self.path = path
        self.name = os.path.splitext(os.path.basename(path))[0]
        self.maps, self.maps_se, self.mean, self.mean_se = {}, {}, {}, {}
        with Dataset(path) as nc:
            self._read(nc)

    @staticmethod
    def _var(nc, name):
        if name not in nc.variables:
            raise ProductError(f'variable {name} not found; the I3RC products need flux maps at '
                               'the bottom and top of the 3-D region (flux_levels), voxel '
                               'absorption and &kumo_radiance with radiance maps')
        return np.asarray(nc[name][...], dtype=float)

    def _read(self, nc):
        def var(name):
            return self._var(nc, name)

        def attr(name, default=''):
            return nc.getncattr(name) if name in nc.ncattrs() else default

        self.mode = attr('mode_3d', 'f3d')
        if self.mode == 'p3d':
            self.mode += str(int(float(attr('p3d_orders', '0'))))
        self.photons = int(float(attr('n_photons', '0')))
        self.batches = int(float(attr('n_batches', '0')))
        self.wall = float(attr('wall_time_s', 'nan'))
        self.sza = float(attr('solar_zenith_angle_deg', 'nan'))
        self.config = dict(line.split(' = ', 1) for line in attr('configuration').splitlines()
                           if ' = ' in line)
        self.x, self.y = var('x'), var('y')
        levels = var('level')
        top, bot = int(np.argmax(levels)), int(np.argmin(levels))
        if len(levels) < 2 or levels[bot] != 0.0:
            raise ProductError('flux_levels must include level 0 (the ground) and the top')

        def pick(name, k):
            return var(name)[k], var(name + '_stderr')[k]

        # per-pixel products
        self.maps['R'], self.maps_se['R'] = pick('flux_up_map', top)
        base = base_index(levels)
        self.base_height = float(levels[base])
        self.maps['T'], self.maps_se['T'] = pick('flux_down_map', base)
        t_ground = var('flux_down_map')[bot]
        self.maps['A'], self.maps_se['A'] = var('absorptance_column'), \
            var('absorptance_column_stderr')
        self.maps['H'], self.maps_se['H'] = var('horizontal_transport_map'), \
            var('horizontal_transport_map_stderr')
        up_bot = var('flux_up_map')[bot]
        self.incident = var('flux_down_direct_map')[top]

        mu, phi = var('direction_mu'), var('direction_phi')
        rlev = var('rad_level')
        rad, rad_se = var('radiance'), var('radiance_stderr')
        rmap, rmap_se = var('radiance_map'), var('radiance_map_stderr')
        for p, (m, ph, where) in RAD_DIRS.items():
            k = int(np.argmax(rlev)) if where == 'top' else base_index(rlev)
            hit = np.isclose(mu, m, atol=1e-6)
            if ph is not None:
                hit &= np.isclose(np.mod(phi - ph + 180.0, 360.0) - 180.0, 0.0, atol=1e-6)
            if not hit.any():
                raise ProductError(f'no radiance direction mu {m}' +
                                   (f' phi {ph}' if ph is not None else '') + ' in the file')
            d = int(np.flatnonzero(hit)[0])
            self.maps[p], self.maps_se[p] = rmap[d, k], rmap_se[d, k]
            self.mean[p], self.mean_se[p] = rad[d, k], rad_se[d, k]

        # domain means: kumo's scalars where they exist (their standard errors are exact)
        for p, name in (('R', 'reflectance'), ('T', 'transmittance'),
                        ('A', 'absorptance_atmosphere')):
            self.mean[p], self.mean_se[p] = float(var(name)), float(var(name + '_stderr'))
        if abs(self.mean['A'] - self.maps['A'].mean()) > 1e-9:
            # the 3-D region does not cover every absorbing layer: use the map
            self.mean['A'] = self.maps['A'].mean()
            self.mean_se['A'] = np.sqrt((self.maps_se['A'] ** 2).sum()) / self.maps['A'].size
        # Over the periodic domain the sideways transport cancels: batch by batch the mean of H
        # is weight_lost minus the roulette balance inside the 3-D region, which is all of
        # roulette_weight_balance over a black surface (an overestimate of the error otherwise).
        self.mean['H'] = self.maps['H'].mean()
        self.mean_se['H'] = float(np.hypot(var('roulette_weight_balance_stderr'),
                                           var('weight_lost_stderr')))
        self.up_ground = float(var('flux_up')[bot])

        # closure: R + (T - F_up,ground) + A + H = incident flux, domain-wide and per column
        self.closure = (self.mean['R'] + self.mean['T'] - self.up_ground + self.mean['A'] +
                        self.mean['H'])
        col = self.maps['R'] + t_ground - up_bot + self.maps['A'] + self.maps['H']
        self.closure_col_err = float(np.max(np.abs(col - self.incident)))
        self.incident_rms = float(np.sqrt(np.mean((self.incident - 1.0) ** 2)))
        self.max_abs_h = float(np.max(np.abs(self.maps['H'])))

    @property
    def is_2d(self):
        return self.maps['R'].shape[0] == 1

    def header(self):
        albedo = self.config.get('kumo_surface.albedo', '?')
        return (f'{self.name}: mode {self.mode}, {self.photons} photons in {self.batches} '
                f'batches, wall time {self.wall:.1f} s, SZA {self.sza:g}, surface albedo '
                f'{albedo}, {self.maps["R"].shape[1]} x {self.maps["R"].shape[0]} columns')


def summary_text(run, other=None):
    """The text table of domain means (and the comparison with `other`)."""
    lines = [f'# I3RC products of {run.header()}',
             '# domain means +- standard errors; radiances as pi I / (mu0 F0)']
    if other is not None:
        lines.append(f'# compared with {other.header()}')
        lines.append(f'{"":5s} {"mean":>10s} {"stderr":>9s}   {"other":>10s} {"stderr":>9s}   '
                     f'{"difference":>10s} {"stderr":>9s}')
    else:
        lines.append(f'{"":5s} {"mean":>10s} {"stderr":>9s}   {"pixel min":>10s} '
                     f'{"pixel max":>10s} {"median pixel stderr":>20s}')
    for p in PRODUCTS:
        m, s = run.mean[p], run.mean_se[p]
        if other is None:
            lines.append(f'{p:5s} {m:10.6f} {s:9.6f}   {run.maps[p].min():10.5f} '
                         f'{run.maps[p].max():10.5f} {np.median(run.maps_se[p]):20.5f}')
        else:
            mo, so = other.mean[p], other.mean_se[p]
            lines.append(f'{p:5s} {m:10.6f} {s:9.6f}   {mo:10.6f} {so:9.6f}   {m - mo:10.6f} '
                         f'{np.hypot(s, so):9.6f}')
    lines.append(f'closure R + T_net + A + H over the domain: {run.closure:.10f}'
                 f'   (T_net = T - upward flux at the ground = T - {run.up_ground:.6f})')
    lines.append('closure per column: largest |R + T_net + A + H - incident flux of the column| '
                 f'= {run.closure_col_err:.2e}; incident flux per column 1 +- '
                 f'{run.incident_rms:.4f} (rms; photons enter at random points)')
    if run.mean['A'] == 0.0:
        lines.append('A = 0: no absorption (single-scattering albedo 1)')
    if run.mode == 'ica':
        h, s = run.maps['H'], run.maps_se['H']
        off = np.abs(h) > 1e-9
        text = f'ICA: largest |H| of a column = {run.max_abs_h:.3e}'
        if not off.any():
            text += ': H = 0 in every column (to round-off)'
        else:
            z = h[off] / np.where(s[off] > 0, s[off], np.inf)
            text += (f'; {off.sum()} of {h.size} columns have |H| > 1e-9, with rms H/stderr '
                     f'{np.sqrt(np.mean(z ** 2)):.2f} (weight changes by Russian roulette or '
                     'DDIS: zero on average)')
        lines.append(text)
    return '\n'.join(lines) + '\n'


def markdown_row(run):
    cells = [run.name, run.mode, f'{run.photons:.2g}']
    for p in FLUXES + RADIANCES:
        cells.append(f'{run.mean[p]:.4f} ± {run.mean_se[p]:.4f}')
    cells.append(f'{run.wall:.1f}')
    return '| ' + ' | '.join(cells) + ' |\n'


MARKDOWN_HEADER = ('| run | mode | photons | R | T | A | H | Iu | Id | I601 | I602 | wall [s] |\n'
                   '|---|---|---|---|---|---|---|---|---|---|---|---|\n')


def _band(ax, x, y, s, label, style='-', color=None):
    line, = ax.plot(x, y, style, label=label, color=color, lw=1.2)
    ax.fill_between(x, y - s, y + s, color=line.get_color(), alpha=0.25, lw=0)


def plot_run(run, path, other=None):
    """Line plots (2-D case) or images (3-D case) of the products, or with `other` the
    comparison."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    if run.is_2d:
        x = run.x / 1000.0
        rows = 2 if other is None else 3
        fig, axes = plt.subplots(rows, 1, figsize=(9, 3.2 * rows), sharex=True)
        for ax, group in zip(axes[:2], (FLUXES, RADIANCES)):
            for p in group:
                _band(ax, x, run.maps[p][0], run.maps_se[p][0], f'{p} {run.mode}')
                if other is not None:
                    _band(ax, x, other.maps[p][0], other.maps_se[p][0], f'{p} {other.mode}',
                          style='--', color=ax.lines[-1].get_color())
            ax.set_ylabel('fluxes / (mu0 F0)' if group is FLUXES else 'pi I / (mu0 F0)')
            ax.axhline(0.0, color='0.6', lw=0.5)
            ax.legend(fontsize=7, ncol=4 if other is None else 8, loc='best')
            ax.grid(alpha=0.3)
        if other is not None:
            ax = axes[2]
            for p in PRODUCTS:
                _band(ax, x, run.maps[p][0] - other.maps[p][0],
                      np.hypot(run.maps_se[p][0], other.maps_se[p][0]), p)
            ax.axhline(0.0, color='0.6', lw=0.5)
            ax.set_ylabel(f'{run.mode} - {other.mode}')
            ax.legend(fontsize=7, ncol=8, loc='best')
            ax.grid(alpha=0.3)
        axes[-1].set_xlabel('x [km]')
        title = run.name if other is None else f'{run.name} vs {other.name}'
        axes[0].set_title(f'{title}: +-1 standard error bands')
    else:
        fig, axes = plt.subplots(2, 4, figsize=(16, 7.5))
        ext = [0.0, (run.x[-1] + run.x[0]) / 1000.0, 0.0, (run.y[-1] + run.y[0]) / 1000.0]
        for ax, p in zip(axes.flat, PRODUCTS):
            if other is None:
                data, cmap = run.maps[p], ('RdBu_r' if p == 'H' else 'viridis')
                lim = np.max(np.abs(data)) if p == 'H' else None
                vmin, vmax = (-lim, lim) if lim else (None, None)
                ax.set_title(f'{p} ({run.mean[p]:.4f})', fontsize=9)
            else:
                data, cmap = run.maps[p] - other.maps[p], 'RdBu_r'
                lim = max(np.max(np.abs(data)), 1e-12)
                vmin, vmax = -lim, lim
                ax.set_title(f'{p}: {run.mode} - {other.mode} '
                             f'({run.mean[p] - other.mean[p]:+.4f})', fontsize=9)
            im = ax.imshow(data, origin='lower', extent=ext, cmap=cmap, vmin=vmin, vmax=vmax)
            fig.colorbar(im, ax=ax, shrink=0.8)
            ax.set_xlabel('x [km]', fontsize=8)
            ax.set_ylabel('y [km]', fontsize=8)
        fig.suptitle(run.name if other is None else f'{run.name} vs {other.name}')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('files', nargs='+', help='kumo output files')
    ap.add_argument('--compare', default=None,
                    help='another run of the same case to compare with (one input file only)')
    ap.add_argument('--out-dir', default=None, help='folder for the outputs (default: next to '
                    'each input file)')
    ap.add_argument('--markdown', default=None,
                    help='append one markdown table row per input file to this file')
    ap.add_argument('--no-plot', action='store_true', help='write only the text tables')
    ap.add_argument('--quiet', action='store_true', help='do not print the tables')
    a = ap.parse_args(argv)
    if a.compare and len(a.files) != 1:
        ap.error('--compare needs exactly one input file')
    try:
        other = Run(a.compare) if a.compare else None
        for f in a.files:
            run = Run(f)
            if other is not None and run.maps['R'].shape != other.maps['R'].shape:
                raise ProductError(f'{f} and {a.compare} have different column grids')
            out_dir = a.out_dir or os.path.dirname(os.path.abspath(f))
            os.makedirs(out_dir, exist_ok=True)
            stem = run.name if other is None else f'{run.name}_vs_{other.name}'
            text = summary_text(run, other)
            with open(os.path.join(out_dir, stem + '_summary.txt'), 'w') as fh:
                fh.write(text)
            if not a.quiet:
                print(text, end='')
            if not a.no_plot:
                png = os.path.join(out_dir, stem + '.png')
                plot_run(run, png, other)
                if not a.quiet:
                    print(f'wrote {os.path.relpath(png)}')
            if a.markdown:
                new = not os.path.exists(a.markdown)
                with open(a.markdown, 'a') as fh:
                    fh.write((MARKDOWN_HEADER if new else '') + markdown_row(run))
    except (OSError, ProductError, KeyError) as err:
        sys.exit(f'plot_i3rc: {err}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
