#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Analyse the run log of bench/run_cases.py: tables, figures of merit, plots and the bars.

Reads <raw>/runs.jsonl and writes
  bench/results/<case>.csv        one row per run of the figure-of-merit series
  bench/results/target_error.csv  the direct runs with target_rel_error
  bench/results/resolution.csv    128 x 128 against 256 x 256, per run
  bench/results/callgrind.csv     instructions per photon
  bench/results/mpi.csv           1 against 2 MPI ranks, per run
  bench/results/summary.md        the headline numbers and the bars (met or not)
  docs/figures/fom_<case>.png     standard error against CPU time, and FOM against photons

Definitions. For an output with batch standard error sigma (absolute) after CPU time t, the
figure of merit is FOM = 1/(sigma^2 t); with the relative error sigma/mean it is FOM_rel. Since
sigma^2 falls as 1/N and t grows as N, FOM does not depend on N; the pooled value combines all
runs of a case: per-photon variance v = mean over runs of N sigma_rel^2 (equal weights: every run
has the same number of batches, so the same degrees of freedom) and CPU time per photon
tau = sum t / sum N, FOM_rel = 1/(v tau). The CPU time to reach a relative standard error e is
then v tau / e^2 (sigma ~ 1/sqrt(N)).
"""
import argparse
import csv
import json
import math
import os
import platform
import statistics

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)

OUTPUTS = [('reflectance', 'R'), ('transmittance', 'T'), ('absorptance_atmosphere', 'A')]
CASES = ['mcpp_slab', 'hg_slab', 'landsat']
TITLES = {
    'mcpp_slab': 'isotropic slab: tau 2, omega 0.99, SZA 60, Lambert albedo 0.2',
    'hg_slab': 'HG slab: g 0.85, tau 10, omega 0.99, SZA 30, black surface',
    'landsat': 'I3RC Landsat cloud: 128 x 128 x 20, HG 0.85, omega 0.99, SZA 60',
}
#: DISORT reference (shared reference table, case iso_w0.99_tau2_sza60_alb0.2)
REFERENCE = {'mcpp_slab': {'reflectance': 0.6615915237, 'transmittance': 0.3692963247,
                           'absorptance_atmosphere': 0.04297141654}}
TARGET = 1.0e-3
QUICK_NOTE = ', QUICK mode (smoke test, not a measurement)'
BARS = dict(hg_rate=5.0e5, hg_time=2.0, resolution=1.2, mpi=0.55)


def load(path):
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]


def machine():
    model, ncpu = 'unknown', os.cpu_count()
    try:
        with open('/proc/cpuinfo') as f:
            for line in f:
                if line.startswith('model name'):
                    model = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    return f'{model}, {ncpu} cores, {platform.system()} {platform.machine()}'


def fmt(x, nd=3):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return 'n/a'
    if x == 0:
        return '0'
    if abs(x) >= 1e4 or abs(x) < 1e-3:
        return f'{x:.{nd}e}'
    return f'{x:.{nd}g}'


def write_csv(path, rows, fields):
    with open(path, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction='ignore', lineterminator='\n')
        w.writeheader()
        for r in rows:
            w.writerow({k: (f'{v:.6g}' if isinstance(v, float) else v) for k, v in r.items()})


# ------------------------------------------------------------------------------------------------

def fom_rows(runs):
    rows = []
    for r in runs:
        n, t = r['n_photons'], r['cpu_time_s']
        row = dict(n_photons=int(n), n_batches=int(r['n_batches']),
                   photons_per_batch=int(r['photons_per_batch']), cpu_s=t,
                   wall_s=r['wall_time_s'], photons_per_cpu_s=n / t,
                   load_before=r['load_before'], load_after=r['load_after'])
        for name, _ in OUTPUTS:
            m, s = r[name], r[name + '_stderr']
            row[name + '_mean'] = m
            row[name + '_sigma'] = s
            row[name + '_rel_sigma'] = s / m
            row[name + '_fom'] = 1.0 / (s * s * t)
            row[name + '_fom_rel'] = 1.0 / ((s / m) ** 2 * t)
        if 'voxel_mean_rel_stderr' in r:
            e = r['voxel_mean_rel_stderr']
            row['voxel_n_absorbing'] = r['voxel_n_absorbing']
            row['voxel_mean_rel_sigma'] = e
            row['voxel_median_rel_sigma'] = r['voxel_median_rel_stderr']
            row['voxel_fom_rel'] = 1.0 / (e * e * t)
        rows.append(row)
    rows.sort(key=lambda x: x['n_photons'])
    return rows


def pooled(rows, key_rel):
    """Per-photon relative variance v, CPU time per photon tau, FOM_rel = 1/(v tau)."""
    v = statistics.fmean(r['n_photons'] * r[key_rel] ** 2 for r in rows)
    tau = sum(r['cpu_s'] for r in rows) / sum(r['n_photons'] for r in rows)
    return v, tau, 1.0 / (v * tau)


def plot_case(case, rows, pools, target_run, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.3))
    keys = [(name, f'{label} ({name})', name + '_rel_sigma', name + '_fom_rel')
            for name, label in OUTPUTS]
    if 'voxel_mean_rel_sigma' in rows[0]:
        keys.append(('voxel', 'voxel absorption (mean over absorbing voxels)',
                     'voxel_mean_rel_sigma', 'voxel_fom_rel'))
    t = np.array([r['cpu_s'] for r in rows])
    n = np.array([r['n_photons'] for r in rows])
    tt = np.geomspace(t.min() / 2, max(t.max() * 2, 1.0), 50)
    for i, (name, label, krel, kfom) in enumerate(keys):
        c = f'C{i}'
        e = np.array([r[krel] for r in rows])
        ax[0].loglog(t, e, 'o', color=c, label=label)
        f = pools[name][2]
        ax[0].loglog(tt, 1.0 / np.sqrt(f * tt), '--', color=c, lw=0.8)
        ax[1].semilogx(n, [r[kfom] for r in rows], 'o-', color=c, label=label)
        ax[1].axhline(f, color=c, lw=0.8, ls='--')
    ax[0].axhline(TARGET, color='k', lw=0.8, ls=':')
    if target_run:
        ax[0].loglog([target_run['cpu_time_s']], [target_run['reflectance_stderr'] /
                                                   target_run['reflectance']], 'k*', ms=11,
                     label=f'direct run, target_rel_error = {target_run["target_rel_error"]:g}')
    ax[0].set_xlabel('CPU time [s]')
    ax[0].set_ylabel('relative standard error')
    ax[0].set_title('error against CPU time (dashed: pooled FOM)')
    ax[0].legend(fontsize=7)
    ax[0].grid(True, which='both', lw=0.3)
    ax[1].set_yscale('log')
    ax[1].set_xlabel('photons')
    ax[1].set_ylabel('FOM_rel = 1/(sigma_rel^2 t) [1/s]')
    ax[1].set_title('figure of merit per output (dashed: pooled)')
    ax[1].grid(True, which='both', lw=0.3)
    fig.suptitle(f'kumo {case}: {TITLES[case]}', fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description='Analyse the kumo benchmark run log.')
    ap.add_argument('--raw', default=os.path.join(HERE, 'results', 'raw'))
    ap.add_argument('--results', default=os.path.join(HERE, 'results'))
    ap.add_argument('--figures', default=os.path.join(REPO, 'docs', 'figures'))
    ap.add_argument('--no-plots', action='store_true')
    a = ap.parse_args()
    runs = load(os.path.join(a.raw, 'runs.jsonl'))
    os.makedirs(a.results, exist_ok=True)
    os.makedirs(a.figures, exist_ok=True)
    # A part rerun with `run_cases.py --append` replaces that part of earlier sessions.
    metas = [r for r in runs if r['part'] == 'meta']
    runs = [r for r in runs if r['part'] != 'meta']
    latest = {}
    for r in runs:
        latest[r['part']] = max(latest.get(r['part'], ''), r.get('session', ''))
    runs = [r for r in runs if r.get('session', '') == latest[r['part']]]
    used = {r.get('session', '') for r in runs}
    metas = [m for m in metas if m.get('session', '') in used] or metas[-1:]
    meta = metas[0] if metas else {}
    if len(metas) > 1:
        meta = dict(meta, time=', '.join(m['time'] for m in metas),
                    commit=', '.join(sorted({m['commit'] for m in metas})))
    loads = [x for r in runs for x in (r.get('load_before'), r.get('load_after'))
             if x is not None]
    md = ['# kumo performance benchmark: results', '',
          f'Machine: {machine()}. Load average (1 min) during the runs: '
          f'{min(loads):.2f} .. {max(loads):.2f} (median {statistics.median(loads):.2f}).'
          if loads else '', '',
          f'Run {meta.get("time", "?")}, kumo commit {meta.get("commit", "?")} ("+": src/ '
          f'differs from it){QUICK_NOTE if meta.get("quick") else ""}.'
          f' Caches: {meta.get("caches") or "n/a"}.', '',
          'CPU times are the `cpu_time_s` of the output file (the batch loop, summed over ranks);'
          ' ratios come from runs made side by side, interleaved, in one session.', '']
    bars = []
    summary = {}

    # --- figure-of-merit series -----------------------------------------------------------------
    targets = {r['case']: r for r in runs if r['part'] == 'target'}
    for case in CASES:
        rs = [r for r in runs if r['part'] == 'fom' and r['case'] == case]
        if not rs:
            continue
        rows = fom_rows(rs)
        fields = list(rows[0].keys())
        write_csv(os.path.join(a.results, f'{case}.csv'), rows, fields)
        pools = {name: pooled(rows, name + '_rel_sigma') for name, _ in OUTPUTS}
        if 'voxel_mean_rel_sigma' in rows[0]:
            pools['voxel'] = pooled(rows, 'voxel_mean_rel_sigma')
        rate = sum(r['n_photons'] for r in rows) / sum(r['cpu_s'] for r in rows)
        v, tau, _ = pools['reflectance']
        t_target = v * tau / TARGET ** 2
        tr = targets.get(case)
        summary[case] = dict(photons_per_cpu_s=rate, t_0p1pct_extrapolated=t_target,
                             pooled={k: dict(var_per_photon=p[0], cpu_per_photon=p[1],
                                             fom_rel=p[2]) for k, p in pools.items()})
        md += [f'## {case}: {TITLES[case]}', '',
               f'Photon histories per CPU-second (all runs): **{rate:.4g}**.', '',
               '| photons | CPU s | photons/CPU-s | output | mean | sigma | sigma/mean | FOM '
               '| FOM_rel |', '|---|---|---|---|---|---|---|---|---|']
        for r in rows:
            for name, label in OUTPUTS:
                md.append(f'| {r["n_photons"]} | {r["cpu_s"]:.3g} | {r["photons_per_cpu_s"]:.3g} '
                          f'| {label} | {r[name + "_mean"]:.6f} | {fmt(r[name + "_sigma"])} | '
                          f'{fmt(r[name + "_rel_sigma"])} | {fmt(r[name + "_fom"])} | '
                          f'{fmt(r[name + "_fom_rel"])} |')
            if 'voxel_mean_rel_sigma' in r:
                md.append(f'| {r["n_photons"]} | {r["cpu_s"]:.3g} | '
                          f'{r["photons_per_cpu_s"]:.3g} | voxel absorption | '
                          f'{r["voxel_n_absorbing"]} voxels | | mean '
                          f'{fmt(r["voxel_mean_rel_sigma"])}, median '
                          f'{fmt(r["voxel_median_rel_sigma"])} | | '
                          f'{fmt(r["voxel_fom_rel"])} |')
        md += ['', 'Pooled over the runs (FOM_rel in 1/s; CPU time for 0.1 % relative standard '
               'error = sigma_rel^2 N t / 0.001^2):', '',
               '| output | FOM_rel | CPU s for 0.1 % |', '|---|---|---|']
        for k, p in pools.items():
            md.append(f'| {k} | {fmt(p[2])} | {fmt(p[0] * p[1] / TARGET ** 2)} |')
        md.append('')
        if case in REFERENCE:
            big = rows[-1]
            ref = REFERENCE[case]
            dev = ', '.join(f'{lab} {(big[n + "_mean"] - ref[n]) / big[n + "_sigma"]:+.2f}'
                            for n, lab in OUTPUTS)
            md += [f'Check against DISORT (largest run), (mean - reference)/sigma: {dev}.', '']
        if tr:
            rel = tr['reflectance_stderr'] / tr['reflectance']
            summary[case]['target_run'] = dict(n_photons=tr['n_photons'],
                                               cpu_s=tr['cpu_time_s'], rel_stderr=rel)
            md += [f'Reflectance to 0.1 % relative standard error: extrapolated from the pooled '
                   f'FOM **{t_target:.3g} CPU-s** ({v / TARGET ** 2:.3g} photons); direct run '
                   f'with `target_rel_error = {tr["target_rel_error"]:g}`: '
                   f'**{tr["cpu_time_s"]:.3g} CPU-s**, '
                   f'{int(tr["n_photons"])} photons, reached {rel:.3e}.', '']
        if not a.no_plots:
            plot_case(case, rows, pools, tr, os.path.join(a.figures, f'fom_{case}.png'))
        if case == 'hg_slab':
            bars.append(('HG slab photon histories per CPU-second', f'>= {BARS["hg_rate"]:.0e}',
                         f'{rate:.3g}', rate >= BARS['hg_rate']))
            direct = tr is not None and abs(tr['target_rel_error'] - TARGET) < 1e-12
            worst = max(t_target, tr['cpu_time_s'] if direct else 0.0)
            bars.append(('HG slab TOA upward flux to 0.1 % standard error [CPU-s]',
                         f'<= {BARS["hg_time"]}', f'{t_target:.3g} (extrapolated)' +
                         (f', {tr["cpu_time_s"]:.3g} (direct run)' if direct else ''),
                         worst <= BARS['hg_time']))
    tgt_rows = [dict(case=r['case'], n_photons=int(r['n_photons']), cpu_s=r['cpu_time_s'],
                     wall_s=r['wall_time_s'], reflectance=r['reflectance'],
                     rel_stderr=r['reflectance_stderr'] / r['reflectance'],
                     extrapolated_cpu_s=summary.get(r['case'], {}).get('t_0p1pct_extrapolated'),
                     load_before=r['load_before'], load_after=r['load_after'])
                for r in runs if r['part'] == 'target']
    if tgt_rows:
        write_csv(os.path.join(a.results, 'target_error.csv'), tgt_rows, list(tgt_rows[0]))

    # --- resolution -----------------------------------------------------------------------------
    res = [r for r in runs if r['part'] == 'resolution']
    if res:
        rows = [dict(grid='256x256' if r['case'] == 'landsat256' else '128x128',
                     supervoxels=r['supervoxels'], rep=r['rep'], n_photons=int(r['n_photons']),
                     cpu_s=r['cpu_time_s'], cpu_us_per_photon=1e6 * r['cpu_time_s'] /
                     r['n_photons'], setup_s=r['setup_time_s'], reflectance=r['reflectance'],
                     supervoxel_grid=r['supervoxel_grid'],
                     load_before=r['load_before'], load_after=r['load_after']) for r in res]
        write_csv(os.path.join(a.results, 'resolution.csv'), rows, list(rows[0]))
        md += ['## Resolution: Landsat 128 x 128 against the same field on 256 x 256', '',
               'CPU time per photon, runs interleaved (128, 256, 128 without super-voxels, '
               '256 without), ratio per repetition; the summary is the median ratio.', '',
               '| super-voxels | rep | 128x128 us/photon | 256x256 us/photon | ratio |',
               '|---|---|---|---|---|']
        summary['resolution'] = {}
        for sv in (True, False):
            ratios = []
            for rep in sorted({r['rep'] for r in rows}):
                p = {r['grid']: r for r in rows if r['supervoxels'] == sv and r['rep'] == rep}
                if len(p) == 2:
                    q = p['256x256']['cpu_us_per_photon'] / p['128x128']['cpu_us_per_photon']
                    ratios.append(q)
                    md.append(f'| {"on" if sv else "off"} | {rep} | '
                              f'{p["128x128"]["cpu_us_per_photon"]:.3f} | '
                              f'{p["256x256"]["cpu_us_per_photon"]:.3f} | {q:.3f} |')
            if ratios:
                summary['resolution'][f'supervoxels_{"on" if sv else "off"}'] = dict(
                    median_ratio=statistics.median(ratios), ratios=ratios)
        md += ['', 'Super-voxel grids (super-voxels on): ' + '; '.join(
            f'{g}: {r["supervoxel_grid"]}' for g, r in
            {x['grid']: x for x in rows if x['supervoxels']}.items()) + '.', '']
        for sv in (True, False):
            cpus = {g: min(r['cpu_us_per_photon'] for r in rows
                           if r['grid'] == g and r['supervoxels'] == sv)
                    for g in ('128x128', '256x256')}
            key = f'supervoxels_{"on" if sv else "off"}'
            if key in summary['resolution']:
                summary['resolution'][key]['best_ratio'] = cpus['256x256'] / cpus['128x128']
                md.append(f'Super-voxels {"on" if sv else "off"}: median ratio '
                          f'**{summary["resolution"][key]["median_ratio"]:.3f}**, ratio of the '
                          f'fastest runs {cpus["256x256"] / cpus["128x128"]:.3f}.')
        md.append('')
        on = summary['resolution'].get('supervoxels_on')
        off = summary['resolution'].get('supervoxels_off')
        if on:
            bars.append(('Doubling horizontal resolution, CPU time per photon (super-voxels on)',
                         f'<= {BARS["resolution"]}', f'{on["median_ratio"]:.3f}',
                         on['median_ratio'] <= BARS['resolution']))
        if off:
            bars.append(('(contrast) the same with super-voxels off', '-',
                         f'{off["median_ratio"]:.3f}', None))

    # --- callgrind ------------------------------------------------------------------------------
    cg = [r for r in runs if r['part'] == 'callgrind']
    if cg:
        rows = [dict(case=r['case'], supervoxels=r['supervoxels'],
                     ir_per_photon=r['ir_per_photon'],
                     ir_trace_batch_per_photon=r['ir_trace_batch_per_photon'],
                     photons_small=r['photons_small'], photons_big=r['photons_big'])
                for r in cg]
        write_csv(os.path.join(a.results, 'callgrind.csv'), rows, list(rows[0]))
        md += ['## Instructions per photon (callgrind)', '',
               'Difference of two runs with 2 batches each, divided by the photon difference: '
               'the per-photon cost without setup.', '',
               '| case | super-voxels | instructions/photon | in trace_batch |',
               '|---|---|---|---|']
        for r in rows:
            md.append(f'| {r["case"]} | {"on" if r["supervoxels"] else "off"} | '
                      f'{r["ir_per_photon"]:.0f} | {r["ir_trace_batch_per_photon"]:.0f} |')
        ir = {(r['case'], r['supervoxels']): r['ir_per_photon'] for r in rows}
        for sv in (True, False):
            if ('landsat', sv) in ir and ('landsat256', sv) in ir:
                q = ir[('landsat256', sv)] / ir[('landsat', sv)]
                key = f'ratio_supervoxels_{"on" if sv else "off"}'
                summary.setdefault('callgrind', {})[key] = q
                md.append(f'\nRatio 256/128 (super-voxels {"on" if sv else "off"}): {q:.4f}')
        for case, sv in (('landsat', True), ('landsat', False), ('hg_slab', True)):
            rr = [r for r in cg if r['case'] == case and r['supervoxels'] == sv]
            if not rr or 'functions_per_photon' not in rr[0]:
                continue
            r = rr[0]
            svtext = f' (super-voxels {"on" if sv else "off"})' if case == 'landsat' else ''
            md += ['', f'Where the instructions of one photon go, {case}{svtext}'
                   ' (self cost per photon, difference of the two runs; inlined routines count '
                   'in their caller):', '', '| function | instructions/photon | share |',
                   '|---|---|---|']
            for fn, n in [x for x in r["functions_per_photon"] if x[1] >= 1.0][:10]:
                md.append(f'| `{fn}` | {n:.0f} | {100.0 * n / r["ir_per_photon"]:.1f} % |')
        md.append('')

    # --- simulated cache ------------------------------------------------------------------------
    cs = [r for r in runs if r['part'] == 'cachesim']
    if cs:
        rows = [dict(case=r['case'], ll=r['ll'], **{k: v for k, v in r['per_photon'].items()})
                for r in cs]
        write_csv(os.path.join(a.results, 'cachesim.csv'), rows, list(rows[0]))
        md += ['## Memory reads per photon (valgrind cache simulation)', '',
               f'Last-level cache simulated as {cs[0]["ll"]} (size, ways, line: the 32 MiB L3 of '
               'the benchmark machine); per photon, difference of two photon counts.', '',
               '| grid | instructions | L1 read misses | memory reads (LL read misses) |',
               '|---|---|---|---|']
        for r in cs:
            p = r['per_photon']
            md.append(f'| {"256x256" if r["case"] == "landsat256" else "128x128"} | '
                      f'{p.get("Ir", float("nan")):.0f} | {p.get("D1mr", float("nan")):.1f} | '
                      f'{p.get("DLmr", float("nan")):.2f} |')
        md.append('')

    # --- MPI ------------------------------------------------------------------------------------
    mp = [r for r in runs if r['part'] == 'mpi']
    if mp:
        rows = [dict(kind=r.get('kind', f'np{int(r["n_ranks"])}'), rep=r['rep'],
                     n_photons=int(r['n_photons']), wall_s=r['wall_time_s'],
                     external_wall_s=r['external_wall_s'], cpu_s=r['cpu_time_s'],
                     load_before=r['load_before'], load_after=r['load_after']) for r in mp]
        write_csv(os.path.join(a.results, 'mpi.csv'), rows, list(rows[0]))
        md += ['## MPI: fixed photon budget of the HG slab on 1 and 2 ranks', '',
               '`wall_s` is the `wall_time_s` of the output (setup, batches, reduction); '
               '`external` includes mpirun start-up and writing the file. Control: two serial '
               'runs of half the budget started together (no MPI): the wall time the two cores '
               'of the machine allow; its ratio to the 1-rank run is the best an MPI run can '
               'reach on this machine at that moment.', '',
               '| rep | photons | 1 rank wall s | 2 ranks wall s | ratio | ratio (external) '
               '| control: 2 halves wall s | control ratio | CPU s 1 rank / 2 ranks | load |',
               '|---|---|---|---|---|---|---|---|---|---|']
        ratios, ext, ctrl = [], [], []
        for rep in sorted({r['rep'] for r in rows}):
            p = {r['kind']: r for r in rows if r['rep'] == rep}
            if 'np1' in p and 'np2' in p:
                q = p['np2']['wall_s'] / p['np1']['wall_s']
                qe = p['np2']['external_wall_s'] / p['np1']['external_wall_s']
                ratios.append(q)
                ext.append(qe)
                c = p.get('halves')
                qc = c['wall_s'] / p['np1']['wall_s'] if c else float('nan')
                if c:
                    ctrl.append(qc)
                loads = [x[k] for x in p.values() for k in ('load_before', 'load_after')]
                md.append(f'| {rep} | {p["np1"]["n_photons"]} | {p["np1"]["wall_s"]:.3f} | '
                          f'{p["np2"]["wall_s"]:.3f} | {q:.3f} | {qe:.3f} | '
                          f'{fmt(c["wall_s"] if c else None)} | {fmt(qc)} | '
                          f'{p["np1"]["cpu_s"]:.2f} / {p["np2"]["cpu_s"]:.2f} | '
                          f'{min(loads):.2f} .. {max(loads):.2f} |')
        if ratios:
            med = statistics.median(ratios)
            summary['mpi'] = dict(median_ratio=med, ratios=ratios, external_ratios=ext,
                                  control_ratios=ctrl)
            text = (f'Median of the per-repetition ratios: **{med:.3f}** (range '
                    f'{min(ratios):.3f} .. {max(ratios):.3f})')
            if ctrl:
                mc = statistics.median(ctrl)
                summary['mpi']['median_control_ratio'] = mc
                text += (f'; the control (two serial halves at once) gives {mc:.3f}, so MPI '
                         f'reaches {mc / med:.2f} of what the two cores allowed')
            md += ['', text + '.']
            got = f'{med:.3f}' + (f' (machine control {statistics.median(ctrl):.3f})'
                                  if ctrl else '')
            bars.append(('2 ranks against 1 rank, wall time', f'<= {BARS["mpi"]}', got,
                         med <= BARS['mpi']))
        md.append('')

    # --- bars -----------------------------------------------------------------------------------
    head = ['## Bars', '', '| bar | required | measured | met |', '|---|---|---|---|']
    for name, req, got, ok in bars:
        head.append(f'| {name} | {req} | {got} | '
                    f'{"-" if ok is None else ("yes" if ok else "**no**")} |')
    head.append('')
    md = md[:8] + head + md[8:]
    with open(os.path.join(a.results, 'summary.md'), 'w') as f:
        f.write('\n'.join(md) + '\n')
    summary['bars'] = [dict(bar=b[0], required=b[1], measured=b[2], met=b[3]) for b in bars]
    with open(os.path.join(a.results, 'summary.json'), 'w') as f:
        json.dump(summary, f, indent=1)
    print('\n'.join(head))


if __name__ == '__main__':
    main()
