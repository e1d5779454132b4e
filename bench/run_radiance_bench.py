#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Radiance benchmarks: time to a given error and bias of the variance-reduction presets.

Cases
  hg_slab   plane-parallel Henyey-Greenstein g 0.85 slab, tau 10, omega 0.99, SZA 30, black
            surface; nadir reflectance (pi I/(mu0 F0) at the top, mu = 1), unbiased preset.
  les       the I3RC LES stratocumulus at 2.13 um (bench/make_les_scene.py: 64 x 64 x 16 voxels
            of 55 m, tabulated Mie phase functions, SZA 60, black surface); domain-mean and
            per-pixel nadir reflectance, every preset.
  les_hg    the same voxels with every cloud phase function replaced by Henyey-Greenstein
            g 0.85 (the case where MCARaTS's standard preset is far off).

Figures
  t_1pct    CPU seconds of the photon loop to reach 1 % standard error on the domain-mean nadir
            reflectance, from the measured error at a fixed budget: t * (rel_err / 0.01)^2 (the
            figure of merit 1/(sigma^2 t) is constant once the batch error is resolved). Median
            of several runs with different seeds, interleaved.
  bias      (preset - reference) / reference, with the reference pooled (inverse-variance) from
            long analog and unbiased runs, and its 1-sigma uncertainty.
  pixel     RMS over pixels of the per-pixel standard error at 1e6 photons, relative to the
            domain mean; and the RMS per-pixel deviation from the reference map beyond what the
            noise of both explains (smoothing bias of numerical diffusion).

Usage:
  python3 bench/run_radiance_bench.py [--kumo build/kumo] [--out bench/results] [--quick]
Writes <out>/radiance.csv (one line per run) and <out>/radiance_summary.md; namelists and
netCDF files go to <out>/raw/radiance/ (not kept in git). Run `bash bench/run_bench.sh` first
or build kumo in Release (`cmake -B build -DCMAKE_BUILD_TYPE=Release && cmake --build build`).
"""
import argparse
import csv
import os
import subprocess
import sys

import f90nml
import netCDF4
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

sys.path.insert(0, os.path.join(ROOT, 'python', 'src'))   # the kumo package of this tree
import kumo


def slab_namelist(nphot, nb, seed, out, preset):
    """The Henyey-Greenstein slab case (namelist groups for kumo.write_namelist)."""
    return {
        'control': {'n_photons_per_batch': nphot, 'n_batches': nb, 'seed': seed, 'verbose': 0},
        'atmosphere': {'nz': 1, 'z_levels': [0.0, 1000.0], 'ext1d': [[0.01]],
                       'ssa1d': [[0.99]]},
        'phase': {'phase_kind': 'hg', 'phase_g': 0.85},
        'source': {'sza_deg': 30.0},
        'output': {'file': out, 'flux_levels': [0, 1]},
        'radiance': {'rad_mu': 1.0, 'rad_levels': 1},
        'vr': {'vr_preset': preset},
    }


def run(kumo_exe, nml_path):
    """Run kumo on a namelist file in its folder (kumo's message on failure)."""
    kumo.run_kumo(nml_path, os.path.dirname(nml_path), exe=kumo_exe)


def read_base(path):
    """The generated LES namelist as groups: lists start at index 1 (missing leading elements
    are None), 2-D arrays are indexed a[i, j] = a(i, j)."""
    nml = f90nml.read(path)
    groups = {}
    for name, group in nml.items():
        variables = {}
        for key, value in group.items():
            start = [1 if i is None else i for i in group.start_index.get(key, [1])]
            if isinstance(value, list) and value and isinstance(value[0], list):
                if any(i != 1 for i in start):
                    raise ValueError(f'{path}: {key} does not start at index 1')
                value = np.asarray(value).T
            elif isinstance(value, list) and start[0] > 1:
                value = [None] * (start[0] - 1) + value
            variables[key] = value
        groups[name[len('kumo_'):]] = variables
    return groups


def figures(nc_path):
    with netCDF4.Dataset(nc_path) as d:
        rad = float(np.ravel(d['radiance'][:])[-1])
        err = float(np.ravel(d['radiance_stderr'][:])[-1])
        rec = dict(radiance=rad, stderr=err, cpu=float(d.getncattr('cpu_time_s')),
                   photons=int(d.getncattr('n_photons')),
                   reflectance=float(d['reflectance'][:]),
                   reflectance_stderr=float(d['reflectance_stderr'][:]))
        if 'radiance_map' in d.variables:
            rec['map'] = np.array(d['radiance_map'][:]).reshape(-1)
            rec['map_err'] = np.array(d['radiance_map_stderr'][:]).reshape(-1)
    rec['t_1pct'] = rec['cpu'] * (rec['stderr'] / rec['radiance'] / 0.01) ** 2
    return rec


def les_namelist(base, preset, nphot, nb, seed, out, hg=False, lean=True):
    """A variant of the generated LES namelist (groups as read_base gives them)."""
    groups = {name: dict(variables) for name, variables in base.items()}
    groups['control'].update(n_photons_per_batch=nphot, n_batches=nb, seed=seed)
    groups['vr'] = {**groups.get('vr', {}), 'vr_preset': preset}
    groups['output'] = {'file': out}
    if lean:
        groups['output'].update(column_fluxes=False, voxel_absorption=False)
    if hg:
        # every tabulated cloud phase function becomes Henyey-Greenstein g 0.85
        phase = groups['phase']
        kinds = list(phase['phase_kind'])
        files = list(phase.get('phase_file') or [None] * len(kinds))
        files += [None] * (len(kinds) - len(files))
        g = list(phase.get('phase_g') or [None] * len(kinds))
        g += [None] * (len(kinds) - len(g))
        for i, kind in enumerate(kinds):
            if kind == 'table':
                kinds[i], files[i], g[i] = 'hg', None, 0.85
        phase['phase_kind'], phase['phase_g'] = kinds, g
        if any(f is not None for f in files):
            phase['phase_file'] = files
        else:
            phase.pop('phase_file', None)
    return groups


def pooled(recs):
    w = np.array([1.0 / r['stderr'] ** 2 for r in recs])
    x = np.array([r['radiance'] for r in recs])
    return float(np.sum(w * x) / np.sum(w)), float(1.0 / np.sqrt(np.sum(w)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--kumo', default=os.path.join(ROOT, 'build', 'kumo'))
    ap.add_argument('--out', default=os.path.join(HERE, 'results'))
    ap.add_argument('--quick', action='store_true', help='small budgets (a smoke test)')
    ap.add_argument('--repeats', type=int, default=3)
    args = ap.parse_args()
    kumo_exe = os.path.abspath(args.kumo)
    raw = os.path.join(args.out, 'raw', 'radiance')
    os.makedirs(raw, exist_ok=True)
    scale = 0.05 if args.quick else 1.0

    # the LES case
    subprocess.run([sys.executable, os.path.join(HERE, 'make_les_scene.py'), '--out-dir', raw],
                   check=True, stdout=subprocess.DEVNULL)
    base = read_base(os.path.join(raw, 'les_stcu_w213.nml'))

    rows = []

    def record(case, preset, kind, rec, seed):
        row = dict(case=case, preset=preset, kind=kind, seed=seed, photons=rec['photons'],
                   cpu_s=rec['cpu'], radiance=rec['radiance'], stderr=rec['stderr'],
                   t_1pct_s=rec['t_1pct'], reflectance=rec['reflectance'])
        rows.append(row)
        print(f"{case:8s} {preset:9s} {kind:6s} seed {seed}: N {rec['photons']:9d} "
              f"R_nadir {rec['radiance']:.5f} +- {rec['stderr']:.5f} cpu {rec['cpu']:.2f} s "
              f"t_1% {rec['t_1pct']:.3f} s", flush=True)

    # 1. HG slab, unbiased, time to 1 %
    for rep in range(args.repeats):
        seed = 101 + rep
        name = f'hg_slab_unbiased_{seed}'
        path = os.path.join(raw, name + '.nml')
        kumo.write_namelist(slab_namelist(int(50000 * scale), 20, seed, name + '.nc',
                                          'unbiased'), path)
        run(kumo_exe, path)
        record('hg_slab', 'unbiased', 'speed', figures(os.path.join(raw, name + '.nc')), seed)

    # 2. LES (Mie tables) and LES with HG: speed of each preset, interleaved
    results = {}
    for case, hg in (('les', False), ('les_hg', True)):
        for rep in range(args.repeats):
            for preset in ('unbiased', 'standard', 'quick'):
                seed = 201 + rep
                name = f'{case}_{preset}_speed_{seed}'
                path = os.path.join(raw, name + '.nml')
                kumo.write_namelist(les_namelist(base, preset, int(20000 * scale), 20, seed,
                                                 name + '.nc', hg=hg), path)
                run(kumo_exe, path)
                rec = figures(os.path.join(raw, name + '.nc'))
                record(case, preset, 'speed', rec, seed)
                results.setdefault((case, preset, 'speed'), []).append(rec)
        # long runs: references (analog, unbiased) and the biased presets
        for preset, nphot in (('analog', 1000000), ('unbiased', 1000000), ('standard', 500000),
                              ('quick', 500000)):
            seed = 301
            name = f'{case}_{preset}_long'
            path = os.path.join(raw, name + '.nml')
            kumo.write_namelist(les_namelist(base, preset, int(nphot * scale), 20, seed,
                                             name + '.nc', hg=hg, lean=False), path)
            run(kumo_exe, path)
            rec = figures(os.path.join(raw, name + '.nc'))
            record(case, preset, 'long', rec, seed)
            results[(case, preset, 'long')] = [rec]
        # per-pixel noise of the standard preset at 1e6 photons
        name = f'{case}_standard_1e6'
        path = os.path.join(raw, name + '.nml')
        kumo.write_namelist(les_namelist(base, 'standard', int(50000 * scale), 20, 401,
                                         name + '.nc', hg=hg), path)
        run(kumo_exe, path)
        rec = figures(os.path.join(raw, name + '.nc'))
        record(case, 'standard', 'pixel', rec, 401)
        results[(case, 'standard', 'pixel')] = [rec]

    with open(os.path.join(args.out, 'radiance.csv'), 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)

    # summary
    lines = ['# Radiance benchmark summary', '',
             'Generated by bench/run_radiance_bench.py' + (' (--quick)' if args.quick else ''),
             '', '| case | preset | t to 1 % [CPU s] (median, min-max) | bias vs reference |',
             '|---|---|---|---|']
    slab = [r['t_1pct_s'] for r in rows if r['case'] == 'hg_slab']
    lines.append(f"| hg_slab | unbiased | {np.median(slab):.3f} ({min(slab):.3f}-{max(slab):.3f})"
                 " | - |")
    for case in ('les', 'les_hg'):
        refs = results[(case, 'analog', 'long')] + results[(case, 'unbiased', 'long')]
        ref, ref_err = pooled(refs)
        for preset in ('analog', 'unbiased', 'standard', 'quick'):
            sp = results.get((case, preset, 'speed'))
            tt = ('-' if sp is None else
                  f"{np.median([r['t_1pct'] for r in sp]):.3f} "
                  f"({min(r['t_1pct'] for r in sp):.3f}-{max(r['t_1pct'] for r in sp):.3f})")
            lr = results[(case, preset, 'long')][0]
            if preset in ('standard', 'quick'):
                b = (lr['radiance'] - ref) / ref
                be = np.hypot(lr['stderr'], ref_err) / ref
                bias = f"{100 * b:+.2f} % +- {100 * be:.2f} %"
            else:
                t1 = lr['t_1pct']
                bias = f"reference member ({lr['radiance']:.5f} +- {lr['stderr']:.5f}; t_1% {t1:.2f} s)"
            lines.append(f"| {case} | {preset} | {tt} | {bias} |")
        lines.append(f"| {case} | reference | - | {ref:.5f} +- {ref_err:.5f} (pooled analog + "
                     "unbiased) |")
        px = results[(case, 'standard', 'pixel')][0]
        m = px['radiance']
        noise = np.sqrt(np.mean(px['map_err'] ** 2)) / m
        refmaps = [(r['map'], r['map_err']) for r in refs]
        wts = [1.0 / np.maximum(e, 1e-30) ** 2 for _, e in refmaps]
        refmap = sum(w * mp for (mp, _), w in zip(refmaps, wts)) / sum(wts)
        referr = 1.0 / np.sqrt(sum(wts))
        lr = results[(case, 'standard', 'long')][0]
        d2 = np.mean((lr['map'] - refmap) ** 2) - np.mean(referr ** 2) - np.mean(lr['map_err'] ** 2)
        lines.append('')
        lines.append(f"{case}: standard preset at {px['photons']} photons: per-pixel standard "
                     f"error (RMS over pixels) {100 * noise:.2f} % of the domain mean; smoothing "
                     f"(RMS per-pixel deviation of the long standard run from the reference map "
                     f"beyond noise) {100 * np.sqrt(max(d2, 0.0)) / m:.2f} % of the domain mean.")
        lines.append('')
    with open(os.path.join(args.out, 'radiance_summary.md'), 'w') as f:
        f.write('\n'.join(lines) + '\n')
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
