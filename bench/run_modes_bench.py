#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Solver modes on the I3RC Phase 1 cases: time to a given error, and the cost of a photon.

Parts
  time      every case and experiment of examples/i3rc (the I3RC product set: flux maps, column
            budget and four radiance maps) in each mode (F3D, ICA, P3D with 1 order), at the
            example's photon budget. From the measured standard errors, the wall time that
            reaches 0.1 % on the domain means and 1 % per pixel: t * (rel_err / target)^2
            (the figure of merit 1/(sigma^2 t) is constant once the batch error is resolved).
            Per pixel the median and the 90th percentile over the pixels with a non-zero value
            (an exact zero, e.g. R of a clear column under ICA over a black surface, has no
            error to reach).
  target    Landsat case 3 experiment 1, fluxes only (no radiances), in target-error mode until
            the domain-mean reflectance has 0.1 % relative standard error: the photons and wall
            time actually needed, F3D and ICA, run one after the other.
  p3d       step cloud experiment 4 in P3D with 0, 1, 2, 3, 5, 10, 20, 50 orders and in F3D:
            how the domain-mean R, T, A approach F3D as more orders move in 3-D.
  callgrind instructions per photon of the photon loop, F3D against ICA, on the Landsat scene
            (experiments 1 and 4, fluxes only), from the difference of two photon counts.

Usage:
  python3 bench/run_modes_bench.py [--kumo build/kumo] [--out bench/results]
      [--parts time,target,p3d,callgrind] [--cases 1,2,3] [--batches 40] [--scale 1.0]
A part left out keeps the results of its last run in the summary (`--parts none` only rewrites
the summary).
Writes <out>/modes_time.csv, <out>/modes_target.csv, <out>/modes_p3d.csv,
<out>/modes_callgrind.csv and
<out>/modes_summary.md; namelists and netCDF files go to <out>/raw/modes/ (not kept in git).
Build kumo in Release first (bash scripts/build.sh Release).
"""
import argparse
import csv
import os
import re
import shutil
import subprocess
import sys
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, 'examples', 'i3rc'))
import i3rc_cases  # noqa: E402
from plot_i3rc import Run, FLUXES, RADIANCES  # noqa: E402

sys.path.insert(0, os.path.join(REPO, 'python', 'src'))   # the kumo package of this tree
import kumo  # noqa: E402

MODES = (('f3d', 0), ('ica', 0), ('p3d', 1))


def run_kumo(kumo_exe, nml, cwd):
    """Run kumo on a namelist file in `cwd`; returns the wall time of the process and its
    standard output."""
    t0 = time.perf_counter()
    try:
        done = kumo.run_kumo(nml, cwd, exe=kumo_exe)
    except kumo.KumoError as err:
        sys.exit(f'run_modes_bench: kumo failed on {nml}:\n{err}')
    return time.perf_counter() - t0, done.stdout


def time_to(rel, t, target):
    return t * (rel / target) ** 2


def part_time(a, raw):
    rows = []
    for case in a.cases:
        exps = sorted(i3rc_cases.EXPERIMENTS[case])
        for e in exps:
            photons = int(a.scale * i3rc_cases.default_photons(case, e))
            for mode, orders in MODES:
                paths = i3rc_cases.write_case(case, [e], [(mode, orders)], photons,
                                              a.batches, 1,
                                              i3rc_cases.default_data_dir(), raw)
                wall, _ = run_kumo(a.kumo, paths[0], raw)
                nc = os.path.splitext(paths[0])[0] + '.nc'
                run = Run(nc)
                row = dict(case=case, exp=e, mode=i3rc_cases.mode_tag(mode, orders),
                           photons=run.photons, wall_s=round(run.wall, 3))
                for p in FLUXES + RADIANCES:
                    if p == 'H':
                        continue   # averages to zero: no relative error
                    m, s = run.mean[p], run.mean_se[p]
                    row[f'{p}_mean'] = m
                    row[f'{p}_t_dom'] = (time_to(s / abs(m), run.wall, 1e-3)
                                         if abs(m) > 1e-12 and s > 0 else '')
                    mp, sp = run.maps[p].ravel(), run.maps_se[p].ravel()
                    ok = (np.abs(mp) > 1e-12) & (sp > 0)
                    if ok.any():
                        rel = sp[ok] / np.abs(mp[ok])
                        row[f'{p}_t_pix50'] = time_to(np.median(rel), run.wall, 1e-2)
                        row[f'{p}_t_pix90'] = time_to(np.percentile(rel, 90), run.wall, 1e-2)
                    else:
                        row[f'{p}_t_pix50'] = row[f'{p}_t_pix90'] = ''
                rows.append(row)
                print(f"time: case {case} exp {e} {row['mode']}: {run.photons} photons "
                      f"{run.wall:.1f} s, R {run.mean['R']:.5f} +- {run.mean_se['R']:.5f}",
                      flush=True)
    write_csv(os.path.join(a.out, 'modes_time.csv'), rows)
    return rows


def flux_only(case, exp_no, mode, photons, batches, target, raw):
    """A case namelist without radiances, optionally in target-error mode."""
    path = i3rc_cases.write_case(case, [exp_no], [(mode, 0)], photons, batches, 7,
                                 i3rc_cases.default_data_dir(), raw)[0]
    with open(path) as f:   # the first two comment lines: the case, the experiment, the mode
        header = ''.join([line for line in f if line.startswith('!')][:2])
    header += '! Fluxes only (no radiances); written by bench/run_modes_bench.py.\n'
    groups = kumo.read_namelist(path)
    del groups['radiance']
    if target:
        groups['control'].update(target_rel_error=target, max_photons=100000000)
    tag = f'{os.path.splitext(path)[0]}_flux{photons}'
    groups['output']['file'] = os.path.basename(tag) + '.nc'
    with open(tag + '.nml', 'w') as f:
        f.write(header)
        kumo.to_namelist(groups).write(f)
    return tag + '.nml'


def part_target(a, raw):
    from netCDF4 import Dataset
    rows = []
    for mode in ('f3d', 'ica'):
        nml = flux_only(3, 1, mode, 200000, 10, 0.001, raw)
        wall, _ = run_kumo(a.kumo, nml, raw)
        with Dataset(os.path.splitext(nml)[0] + '.nc') as nc:
            r, s = float(nc['reflectance'][...]), float(nc['reflectance_stderr'][...])
            rows.append(dict(case=3, exp=1, mode=mode, photons=int(nc.n_photons),
                             reflectance=r, rel_err=s / r, wall_s=float(nc.wall_time_s),
                             cpu_s=float(nc.cpu_time_s), process_s=round(wall, 3)))
        print(f"target: case 3 exp 1 {mode}: R {r:.5f} +- {s / r:.2e} relative, "
              f"{rows[-1]['photons']} photons, wall {rows[-1]['wall_s']:.1f} s", flush=True)
    write_csv(os.path.join(a.out, 'modes_target.csv'), rows)
    return rows


def part_p3d(a, raw):
    rows = []
    for mode, orders in [('p3d', n) for n in (0, 1, 2, 3, 5, 10, 20, 50)] + [('f3d', 0)]:
        path = i3rc_cases.write_case(1, [4], [(mode, orders)], 1000000, 10, 11,
                                     i3rc_cases.default_data_dir(), raw)[0]
        run_kumo(a.kumo, path, raw)
        run = Run(os.path.splitext(path)[0] + '.nc')
        row = dict(case=1, exp=4, mode=i3rc_cases.mode_tag(mode, orders), photons=run.photons)
        for p in ('R', 'T', 'A'):
            row[p] = run.mean[p]
            row[p + '_se'] = run.mean_se[p]
        rows.append(row)
        print(f"p3d: case 1 exp 4 {row['mode']}: R {row['R']:.4f} T {row['T']:.4f} "
              f"A {row['A']:.4f}", flush=True)
    write_csv(os.path.join(a.out, 'modes_p3d.csv'), rows)
    return rows


def callgrind_total(path):
    out = subprocess.run(['callgrind_annotate', path], capture_output=True, text=True).stdout
    m = re.search(r'([\d,]+)\s+\(100.0%\)\s+PROGRAM TOTALS', out) or \
        re.search(r'([\d,]+)\s+PROGRAM TOTALS', out)
    return int(m.group(1).replace(',', ''))


def part_callgrind(a, raw):
    valgrind = shutil.which('valgrind')
    if not valgrind:
        print('callgrind: valgrind not found, skipped', flush=True)
        return []
    rows = []
    small = 2000
    for e in (1, 4):
        for mode in ('f3d', 'ica'):
            ir = {}
            for n in (small, 2 * small):
                nml = flux_only(3, e, mode, 2 * n, 2, 0, raw)
                cg = os.path.splitext(nml)[0] + '.callgrind'
                subprocess.run([valgrind, '--tool=callgrind', f'--callgrind-out-file={cg}',
                                a.kumo, os.path.basename(nml)], cwd=raw, capture_output=True,
                               check=True)
                ir[n] = callgrind_total(cg)
            per = (ir[2 * small] - ir[small]) / (2 * small)
            rows.append(dict(case=3, exp=e, mode=mode, instructions_per_photon=round(per)))
            print(f'callgrind: case 3 exp {e} {mode}: {per:.0f} instructions per photon',
                  flush=True)
    write_csv(os.path.join(a.out, 'modes_callgrind.csv'), rows)
    return rows


def write_csv(path, rows):
    if not rows:
        return
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


def read_csv(folder, name):
    """Rows of an earlier run (numbers as float, empty fields as '')."""
    path = os.path.join(folder, name)
    if not os.path.exists(path):
        return []
    def num(v):
        try:
            return float(v)
        except ValueError:
            return v
    with open(path, newline='') as f:
        return [{k: num(v) for k, v in r.items()} for r in csv.DictReader(f)]


def fmt_t(v):
    if v == '' or v is None:
        return '–'
    return f'{v:.2g}' if v < 10 else f'{v:.0f}'


def summary(time_rows, target_rows, cg_rows, p3d_rows=()):
    out = []
    if time_rows:
        out.append('| case | exp | mode | photons | wall [s] | R | 0.1 % fluxes [s] | '
                   '0.1 % radiances [s] | 1 % per pixel, fluxes: median / 90 % [s] | '
                   '1 % per pixel, radiances: median / 90 % [s] |\n')
        out.append('|---|---|---|---|---|---|---|---|---|---|\n')
        for r in time_rows:
            def worst(prods, key):
                v = [r[f'{p}_{key}'] for p in prods if r.get(f'{p}_{key}', '') != '']
                return max(v) if v else ''
            fl = ('R', 'T', 'A')
            out.append(f"| {int(r['case'])} | {int(r['exp'])} | {r['mode']} | {r['photons']:.2g} | "
                       f"{r['wall_s']:.1f} | {r['R_mean']:.4f} | {fmt_t(worst(fl, 't_dom'))} | "
                       f"{fmt_t(worst(RADIANCES, 't_dom'))} | "
                       f"{fmt_t(worst(fl, 't_pix50'))} / {fmt_t(worst(fl, 't_pix90'))} | "
                       f"{fmt_t(worst(RADIANCES, 't_pix50'))} / "
                       f"{fmt_t(worst(RADIANCES, 't_pix90'))} |\n")
    if target_rows:
        out.append('\n| Landsat exp 1, fluxes only | photons | R | relative error | wall [s] |\n'
                   '|---|---|---|---|---|\n')
        for r in target_rows:
            out.append(f"| {r['mode']} | {r['photons']:.3g} | {r['reflectance']:.5f} | "
                       f"{r['rel_err']:.2e} | {r['wall_s']:.1f} |\n")
    if p3d_rows:
        out.append('\n| step cloud exp 4 | R | T | A |\n|---|---|---|---|\n')
        for r in p3d_rows:
            out.append(f"| {r['mode']} | " + ' | '.join(f"{r[p]:.4f} ± {r[p + '_se']:.4f}"
                                                       for p in ('R', 'T', 'A')) + ' |\n')
    if cg_rows:
        by = {(r['exp'], r['mode']): r['instructions_per_photon'] for r in cg_rows}
        out.append('\n| Landsat, fluxes only | F3D instructions / photon | ICA | ICA / F3D |\n'
                   '|---|---|---|---|\n')
        for e in (1, 4):
            f, i = by.get((e, 'f3d')), by.get((e, 'ica'))
            if f and i:
                out.append(f'| exp {e} | {int(f)} | {int(i)} | {i / f:.2f} |\n')
    return ''.join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--kumo', default=os.path.join(REPO, 'build', 'kumo'))
    ap.add_argument('--out', default=os.path.join(REPO, 'bench', 'results'))
    ap.add_argument('--parts', default='time,target,p3d,callgrind')
    ap.add_argument('--cases', default='1,2,3')
    ap.add_argument('--batches', type=int, default=40,
                    help='batches per run of the time part (the error of sigma^2, and so of '
                         'the extrapolated times, is about sqrt(2/(batches - 1)))')
    ap.add_argument('--scale', type=float, default=1.0,
                    help='photons relative to the examples\' defaults (time part)')
    a = ap.parse_args()
    a.kumo = os.path.abspath(a.kumo)
    if not os.access(a.kumo, os.X_OK):
        sys.exit(f'run_modes_bench: {a.kumo} not found; build kumo first '
                 '(bash scripts/build.sh Release)')
    a.cases = [int(c) for c in a.cases.split(',')]
    parts = a.parts.split(',')
    raw = os.path.join(a.out, 'raw', 'modes')
    os.makedirs(raw, exist_ok=True)
    # a part that is not run keeps the rows of its last run
    t_rows = part_time(a, raw) if 'time' in parts else read_csv(a.out, 'modes_time.csv')
    g_rows = part_target(a, raw) if 'target' in parts else read_csv(a.out, 'modes_target.csv')
    p_rows = part_p3d(a, raw) if 'p3d' in parts else read_csv(a.out, 'modes_p3d.csv')
    c_rows = (part_callgrind(a, raw) if 'callgrind' in parts
              else read_csv(a.out, 'modes_callgrind.csv'))
    text = summary(t_rows, g_rows, c_rows, p_rows)
    with open(os.path.join(a.out, 'modes_summary.md'), 'w') as f:
        f.write(text)
    print(text)


if __name__ == '__main__':
    main()
