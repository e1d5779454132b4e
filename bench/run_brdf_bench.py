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
(bash scripts/build.sh Release). The namelists and the scene file are written, and kumo is run,
with the kumo Python package of this tree (python/; needs f90nml and xarray:
bash scripts/install-deps.sh --python).
"""
import argparse
import csv
import os
import subprocess
import sys
import time

import numpy as np
from netCDF4 import Dataset

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, 'python', 'src'))   # the kumo package of this tree
import kumo  # noqa: E402

SURFACES = {
    'black': {'brdf': 'black'},
    'lambert': {'albedo': 0.5},
    'lsrt': {'brdf': 'lsrt', 'brdf_param': [0.3, 0.07, 0.03]},
    'rpv': {'brdf': 'rpv', 'brdf_param': [0.3, 0.8, -0.1, 0.2]},
    'dsm': {'brdf': 'dsm', 'brdf_param': [0.3, 0.5, 1.334, 0.0, 0.02]},
}


def timed_run(exe, nml, cwd):
    """Run kumo on the namelist file nml in cwd: (wall time [s], log)."""
    t0 = time.perf_counter()
    try:
        done = kumo.run_kumo(nml, cwd, exe=exe)
    except kumo.KumoError as error:
        sys.exit(f'run_brdf_bench: kumo failed on {nml}:\n{error}')
    return time.perf_counter() - t0, done.stdout


def event_nml(surface, n, path):
    kumo.write_namelist({
        'control': {'n_photons_per_batch': n, 'n_batches': 2, 'seed': 3, 'verbose': 0},
        'atmosphere': {'nz': 1, 'z_levels': [0.0, 1000.0]},
        'surface': SURFACES[surface],
        'source': {'sza_deg': 40.0},
        'vr': {'rr_threshold': 0.01},
        'output': {'file': os.path.basename(path)[:-4] + '.nc'},
    }, path)


def instructions(exe, nml, cwd):
    out = nml[:-4] + '.cg'
    p = subprocess.run(['valgrind', '--tool=callgrind', f'--callgrind-out-file={out}', exe,
                        os.path.basename(nml)], cwd=cwd, capture_output=True, text=True,
                       check=False)
    if p.returncode != 0:
        sys.exit(f'run_brdf_bench: callgrind failed on {nml}:\n{p.stderr}')
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


def image_nml(path, n, photons, batches, rayleigh, preset):
    lx = 30.0 * n
    atm = {'nz': 1, 'z_levels': [0.0, 1000.0]}
    case = {}
    if rayleigh:
        # a Rayleigh layer of optical depth 0.05 above the (empty) 3-D region
        atm = {'nz': 2, 'z_levels': [0.0, 1000.0, 9000.0], 'ext1d': [[0.0], [0.05 / 8000.0]],
               'ssa1d': [[1.0], [1.0]], 'phase1d': [[1], [1]]}
        case['phase'] = {'phase_kind': ['rayleigh']}
    atm.update({'lx': lx, 'ly': lx, 'scene_file': f'empty_{n}.nc', 'nx': n, 'ny': n, 'nz3': 1,
                'k3d_bottom': 1, 'n_components_3d': 1})
    case.update({
        'control': {'n_photons_per_batch': photons, 'n_batches': batches, 'seed': 5,
                    'verbose': 0},
        'atmosphere': atm,
        'surface': {'brdf': 'lsrt', 'brdf_file': f'lsrt_map_{n}.nc'},
        'source': {'sza_deg': 30.0},
        'radiance': {'rad_mu': [1.0], 'rad_phi_deg': [0.0]},
        'vr': {'vr_preset': preset},
        'output': {'file': os.path.basename(path)[:-4] + '.nc', 'column_fluxes': False,
                   'voxel_absorption': False},
    })
    kumo.write_namelist(case, path)


def part_image(args, raw):
    n = 256
    write_map(os.path.join(raw, f'lsrt_map_{n}.nc'), n)
    kumo.write_scene(os.path.join(raw, f'empty_{n}.nc'), np.zeros((1, n, n)),
                     np.ones((1, n, n)))
    rows = []
    for rayleigh, preset in ((False, 'analog'), (False, 'unbiased'), (True, 'analog'),
                             (True, 'unbiased')):
        # set-up alone: a run with the fewest photons the driver accepts
        nml0 = os.path.join(raw, f'image_setup_{int(rayleigh)}.nml')
        image_nml(nml0, n, 1, 2, rayleigh, preset)
        t_setup, _ = timed_run(args.kumo, nml0, raw)
        nml = os.path.join(raw, f'image_{int(rayleigh)}_{preset}.nml')
        image_nml(nml, n, args.photons, args.batches, rayleigh, preset)
        t_run, _ = timed_run(args.kumo, nml, raw)
        ds = kumo.open_results(os.path.join(raw, os.path.basename(nml)[:-4] + '.nc'))
        # (direction, rad_level, y, x): nadir, the top level
        m = ds['radiance_map'][0, -1].values.ravel()
        e = ds['radiance_map_stderr'][0, -1].values.ravel()
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
