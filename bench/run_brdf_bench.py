#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""BRDF surfaces: the cost of a reflection event and a clear-sky BRF image over an LSRT map.

Parts
  events    instructions per reflection event (valgrind callgrind, repeatable): a transparent
            1 km layer over a uniform surface, sun at 40 deg, roulette threshold 0.01 so that
            every photon reflects exactly once and leaves. Instructions per photon come from
            the difference of two photon counts (2 x 20,000 and 2 x 40,000, which removes the
            set-up); the event cost is a surface's cost per photon minus a black surface's
            (which ends the photon at the surface without any reflection work), and the ratio
            is taken to the Lambert event.
  image     a 256 x 256 pixel LSRT map with distinct kernel weights in every pixel (uniform
            random k_iso in [0.05, 0.35], k_vol in [0, 0.25], k_geo in [0, 0.06], a MODIS-like
            range), under an empty 3-D region of 256 x 256 columns of 30 m (the BRF image is the
            nadir radiance map at the top, whose columns lie over the pixels), sun at 30 deg;
            runs without atmosphere and under a Rayleigh layer of optical depth 0.05 above the
            region, each with the 'analog' preset (every local estimate kept) and the default
            'unbiased' one (local-estimate roulette below a BRF of 0.3). Reported: set-up time (map tables), wall time of the whole run on
            one core, and the median, 99th percentile and largest relative standard error of the
            pixels; from these, the time to 1 % per pixel.

Usage:
  python3 bench/run_brdf_bench.py [--kumo build/kumo] [--out bench/results]
      [--parts events,image] [--batches 10] [--photons 65536]
Writes <out>/brdf_events.csv, <out>/brdf_image.csv and <out>/brdf_summary.md; namelists and
netCDF files go to <out>/raw/brdf/ (not kept in git). Build kumo in Release first
(bash scripts/build.sh Release).
"""
import argparse
import csv
import os
import re
import subprocess
import sys
import time

import numpy as np
from netCDF4 import Dataset

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SURFACES = {
    'black': "brdf = 'black'",
    'lambert': 'albedo = 0.5',
    'lsrt': "brdf = 'lsrt', brdf_param = 0.3, 0.07, 0.03",
    'rpv': "brdf = 'rpv', brdf_param = 0.3, 0.8, -0.1, 0.2",
    'dsm': "brdf = 'dsm', brdf_param = 0.3, 0.5, 1.334, 0.0, 0.02",
}


def run_kumo(cmd, cwd):
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f'run_brdf_bench: {" ".join(cmd)} failed:\n{p.stderr}')
    return time.perf_counter() - t0, p.stdout


def event_nml(surface, n, path):
    with open(path, 'w') as f:
        f.write(f"""&kumo_control
  n_photons_per_batch = {n}, n_batches = 2, seed = 3, verbose = 0
/
&kumo_atmosphere
  nz = 1
  z_levels = 0.0, 1000.0
/
&kumo_surface
  {SURFACES[surface]}
/
&kumo_source
  sza_deg = 40.0
/
&kumo_vr
  rr_threshold = 0.01
/
&kumo_output
  file = '{os.path.basename(path)[:-4]}.nc'
/
""")


def instructions(kumo, nml, cwd):
    out = nml[:-4] + '.cg'
    run_kumo(['valgrind', '--tool=callgrind', f'--callgrind-out-file={out}', kumo,
              os.path.basename(nml)], cwd)
    with open(os.path.join(cwd, out)) as f:
        for line in f:
            if line.startswith('summary:') or line.startswith('totals:'):
                return int(line.split()[1])
    sys.exit(f'run_brdf_bench: no instruction count in {out}')


def part_events(args, raw):
    rows = []
    per_photon = {}
    for s in SURFACES:
        counts = []
        for n in (20000, 40000):
            nml = os.path.join(raw, f'event_{s}_{n}.nml')
            event_nml(s, n, nml)
            counts.append(instructions(args.kumo, nml, raw))
        per_photon[s] = (counts[1] - counts[0]) / 40000.0
    lam = per_photon['lambert'] - per_photon['black']
    for s in SURFACES:
        ev = per_photon[s] - per_photon['black']
        rows.append({'surface': s, 'instructions_per_photon': round(per_photon[s]),
                     'instructions_per_event': round(ev),
                     'ratio_to_lambert': '' if s == 'black' else f'{ev / lam:.2f}'})
    return rows


def write_map(path, n, seed=1):
    rng = np.random.default_rng(seed)
    with Dataset(path, 'w', format='NETCDF4_CLASSIC') as nc:
        nc.createDimension('xs', n)
        nc.createDimension('ys', n)
        for name, lo, hi in (('k_iso', 0.05, 0.35), ('k_vol', 0.0, 0.25), ('k_geo', 0.0, 0.06)):
            v = nc.createVariable(name, 'f8', ('ys', 'xs'))
            v.units = '1'
            v[:] = lo + (hi - lo) * rng.random((n, n))


def write_empty_scene(path, n):
    with Dataset(path, 'w', format='NETCDF4_CLASSIC') as nc:
        for name in ('x', 'y'):
            nc.createDimension(name, n)
        nc.createDimension('z', 1)
        nc.createDimension('component', 1)
        dims = ('component', 'z', 'y', 'x')
        v = nc.createVariable('extinction', 'f8', dims)
        v.units = 'm-1'
        v[:] = 0.0
        v = nc.createVariable('ssa', 'f8', dims)
        v.units = '1'
        v[:] = 1.0


def image_nml(path, n, photons, batches, rayleigh, preset):
    lx = 30.0 * n
    if rayleigh:
        atm = f"""  nz = 2
  z_levels = 0.0, 1000.0, 9000.0
  ext1d(2,1) = {0.05 / 8000.0}, ssa1d(2,1) = 1.0
  phase1d(2,1) = 1"""
        phase = "&kumo_phase\n  phase_kind = 'rayleigh'\n/\n"
    else:
        atm = """  nz = 1
  z_levels = 0.0, 1000.0"""
        phase = ''
    with open(path, 'w') as f:
        f.write(f"""&kumo_control
  n_photons_per_batch = {photons}, n_batches = {batches}, seed = 5, verbose = 0
/
&kumo_atmosphere
{atm}
  lx = {lx}, ly = {lx}
  scene_file = 'empty_{n}.nc', nx = {n}, ny = {n}, nz3 = 1, k3d_bottom = 1
  n_components_3d = 1
/
{phase}&kumo_surface
  brdf = 'lsrt', brdf_file = 'lsrt_map_{n}.nc'
/
&kumo_source
  sza_deg = 30.0
/
&kumo_radiance
  rad_mu = 1.0, rad_phi_deg = 0.0
/
&kumo_vr
  vr_preset = '{preset}'
/
&kumo_output
  file = '{os.path.basename(path)[:-4]}.nc'
  column_fluxes = .false., voxel_absorption = .false.
/
""")


def part_image(args, raw):
    n = 256
    write_map(os.path.join(raw, f'lsrt_map_{n}.nc'), n)
    write_empty_scene(os.path.join(raw, f'empty_{n}.nc'), n)
    rows = []
    for rayleigh, preset in ((False, 'analog'), (False, 'unbiased'), (True, 'analog'),
                             (True, 'unbiased')):
        # set-up alone: a run with the fewest photons the driver accepts
        nml0 = os.path.join(raw, f'image_setup_{int(rayleigh)}.nml')
        image_nml(nml0, n, 1, 2, rayleigh, preset)
        t_setup, _ = run_kumo([args.kumo, os.path.basename(nml0)], raw)
        nml = os.path.join(raw, f'image_{int(rayleigh)}_{preset}.nml')
        image_nml(nml, n, args.photons, args.batches, rayleigh, preset)
        t_run, _ = run_kumo([args.kumo, os.path.basename(nml)], raw)
        with Dataset(os.path.join(raw, os.path.basename(nml)[:-4] + '.nc')) as nc:
            # (direction, rad_level, y, x): nadir, the top level
            m = np.asarray(nc['radiance_map'][0, -1]).ravel()
            e = np.asarray(nc['radiance_map_stderr'][0, -1]).ravel()
        # pixels whose LSRT sum is clipped at nadir view have no reflected light and no error
        rel = e[m > 0] / m[m > 0]
        q50, q99, qmax = np.percentile(rel, 50), np.percentile(rel, 99), rel.max()
        t_trace = t_run - t_setup
        rows.append({'atmosphere': 'rayleigh 0.05' if rayleigh else 'none', 'vr_preset': preset,
                     'photons': args.photons * args.batches, 'setup_s': f'{t_setup:.2f}',
                     'run_s': f'{t_run:.2f}', 'rel_err_median': f'{q50:.2e}',
                     'rel_err_p99': f'{q99:.2e}', 'rel_err_max': f'{qmax:.2e}',
                     'time_to_1pct_max_s': f'{t_setup + t_trace * (qmax / 0.01) ** 2:.2f}'})
    return rows


def write_csv(path, rows):
    with open(path, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def read_csv(path):
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return list(csv.DictReader(f))


def table(rows):
    if not rows:
        return '(not run)\n'
    keys = list(rows[0])
    out = '| ' + ' | '.join(keys) + ' |\n|' + '---|' * len(keys) + '\n'
    for r in rows:
        out += '| ' + ' | '.join(str(r[k]) for k in keys) + ' |\n'
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--kumo', default=os.path.join(REPO, 'build', 'kumo'))
    ap.add_argument('--out', default=os.path.join(REPO, 'bench', 'results'))
    ap.add_argument('--parts', default='events,image')
    ap.add_argument('--batches', type=int, default=10)
    ap.add_argument('--photons', type=int, default=65536)
    args = ap.parse_args()
    args.kumo = os.path.abspath(args.kumo)
    raw = os.path.join(args.out, 'raw', 'brdf')
    os.makedirs(raw, exist_ok=True)
    parts = [p for p in args.parts.split(',') if p and p != 'none']
    ev_csv = os.path.join(args.out, 'brdf_events.csv')
    im_csv = os.path.join(args.out, 'brdf_image.csv')
    if 'events' in parts:
        write_csv(ev_csv, part_events(args, raw))
    if 'image' in parts:
        write_csv(im_csv, part_image(args, raw))
    with open(os.path.join(args.out, 'brdf_summary.md'), 'w') as f:
        f.write('# BRDF surfaces (bench/run_brdf_bench.py)\n\n')
        f.write('## Reflection event cost (callgrind instructions)\n\n')
        f.write(table(read_csv(ev_csv)))
        f.write('\n## Clear-sky BRF image over a 256 x 256 LSRT map (one core)\n\n')
        f.write(table(read_csv(im_csv)))
    print(open(os.path.join(args.out, 'brdf_summary.md')).read())


if __name__ == '__main__':
    main()
