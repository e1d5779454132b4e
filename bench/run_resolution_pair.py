#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Cost of doubling the horizontal resolution, two kumo programs side by side.

The I3RC Landsat cloud on 128 x 128 columns and the same field on 256 x 256 (each column split
into 2 x 2 identical ones: the same medium on a finer grid), fluxes and voxel absorption as in
bench/run_bench.sh's resolution part. Each repetition runs the four combinations (program x
grid) in an order that rotates from one repetition to the next, so that a drift of the machine's
speed falls on all alike; ratios are formed within a repetition and summarised by their median.

    python3 bench/run_resolution_pair.py --old OLD_KUMO --new NEW_KUMO [--reps 8]
        [--photons 50000] [--batches 4] [--data examples/data/i3rc_phase1] [--out DIR]

Prints, per program, the CPU time per photon at both grids and the 256/128 ratio, and the
new/old ratio at each grid (median and range over repetitions); writes DIR/resolution_pair.csv.
"""
import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, 'python', 'src'))
sys.path.insert(0, HERE)
import kumo  # noqa: E402
from run_cases import landsat_namelist, loadavg  # noqa: E402
from netCDF4 import Dataset  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--old', required=True)
    ap.add_argument('--new', required=True)
    ap.add_argument('--reps', type=int, default=8)
    ap.add_argument('--photons', type=int, default=50000)
    ap.add_argument('--batches', type=int, default=4)
    ap.add_argument('--data', default=os.path.join(REPO, 'examples', 'data', 'i3rc_phase1'))
    ap.add_argument('--out', default=os.path.join(HERE, 'results'))
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix='kumo_res_')
    nml = {}
    for refine, n in ((1, 128), (2, 256)):
        scene = os.path.join(work, f'landsat{n}.nc')
        group = os.path.join(work, f'landsat{n}.atm.nml')
        subprocess.run([sys.executable, os.path.join(HERE, 'make_landsat_scene.py'), '--data',
                        a.data, '--out', scene, '--refine', str(refine), '--atm-group', group],
                       check=True, stdout=subprocess.DEVNULL)
        atm = kumo.read_namelist(group)['atmosphere']
        groups = landsat_namelist(atm, f'out{n}.nc', a.photons, a.batches, seed=11)
        nml[n] = os.path.join(work, f'landsat{n}.nml')
        with open(nml[n], 'w') as f:
            kumo.to_namelist(groups).write(f)
    progs = {'old': os.path.abspath(a.old), 'new': os.path.abspath(a.new)}
    combos = [('old', 128), ('new', 128), ('new', 256), ('old', 256)]
    rows = []
    for rep in range(a.reps):
        k = rep % len(combos)
        order = combos[k:] + combos[:k]
        if rep % 2:
            order = order[::-1]
        for prog, n in order:
            la = loadavg()
            subprocess.run([progs[prog], os.path.basename(nml[n])], cwd=work, check=True,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            with Dataset(os.path.join(work, f'out{n}.nc')) as ds:
                cpu = float(ds.getncattr('cpu_time_s'))
                nph = float(ds.getncattr('n_photons'))
                r = float(ds['reflectance'][...])
            rows.append(dict(rep=rep, program=prog, grid=n, cpu_s=cpu, us_per_photon=cpu/nph*1e6,
                             reflectance=r, load=la))
            print(f'rep {rep} {prog} {n}: {cpu/nph*1e6:.2f} us/photon  R {r:.6f}  load {la:.2f}',
                  flush=True)
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, 'resolution_pair.csv'), 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    t = {(r['rep'], r['program'], r['grid']): r['us_per_photon'] for r in rows}

    def summary(vals):
        return f'{statistics.median(vals):.3f} ({min(vals):.3f} .. {max(vals):.3f})'
    for prog in ('old', 'new'):
        ratios = [t[(i, prog, 256)]/t[(i, prog, 128)] for i in range(a.reps)]
        print(f'{prog}: 128 {statistics.median([t[(i, prog, 128)] for i in range(a.reps)]):.2f} '
              f'us/photon, 256 {statistics.median([t[(i, prog, 256)] for i in range(a.reps)]):.2f}'
              f' us/photon, 256/128 {summary(ratios)}')
    for n in (128, 256):
        print(f'new/old at {n}: {summary([t[(i, "new", n)]/t[(i, "old", n)] for i in range(a.reps)])}')
    loads = [r['load'] for r in rows]
    print(f'load average {min(loads):.2f} .. {max(loads):.2f}')


if __name__ == '__main__':
    main()
