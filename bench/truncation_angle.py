#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Bias of truncated radiances against the truncation angle, on plane-parallel DISORT cases.

kumo's `standard` and `quick` presets truncate forward peaks within `trunc_theta_max_deg`
(30 and 40 degrees). The namelist allows up to 89. This study runs the `standard` preset with
several largest truncation angles (and the `unbiased` preset as a control) on the Henyey-
Greenstein g = 0.85 cases of `reference/disort_pp.csv` (a reference kumo did not produce:
cdisort through pydisort, radiances accurate to 6e-6) and reports, per angle, the bias of every
radiance at the top (upward, mu 0.2-1) and at the surface (downward) in units of its own
standard error and in per cent.

Usage:
  python3 bench/truncation_angle.py SHARED [--kumo build/kumo] [--out DIR]
         [--angles 30,40,60,75,89] [--presets unbiased] [--photons 20000] [--batches 20]
         [--seeds 1] [--mus 0.3,0.35,0.4]
(`--angles ''` runs the presets only; a preset's own truncation angle is 30 degrees for
`standard` and 40 for `quick`.)
SHARED is the folder that holds reference/disort_pp.csv. Writes DIR/truncation_angle.csv (one
line per radiance and run) and DIR/truncation_angle.md (the summary; `--name` changes the stem);
runs go to DIR/raw/.
"""
import argparse
import csv
import os
import subprocess
import sys

import netCDF4
import numpy as np

CASES = ['hg0.85_w1_tau1_sza30_alb0', 'hg0.85_w1_tau1_sza60_alb0',
         'hg0.85_w1_tau10_sza30_alb0', 'hg0.85_w1_tau10_sza60_alb0',
         'hg0.85_w1_tau50_sza30_alb0', 'hg0.85_w1_tau50_sza60_alb0',
         'hg0.85_w0.999_tau10_sza0_alb0.3']
MUS = [0.2, 0.5, 0.8, 1.0]
PHIS = [0.0, 90.0, 180.0]


def load_reference(path):
    """{case: {'tau':, 'omega':, 'sza':, 'albedo':, 'rad': {(level, mu, phi): value}}}"""
    cases = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            cid = row['case_id']
            if cid not in CASES:
                continue
            c = cases.setdefault(cid, {'rad': {}})
            spec = dict(kv.split('=') for kv in row['layer_spec'].split(':')[1:])
            c['tau'] = float(spec['tau'])
            c['omega'] = float(spec['omega'])
            c['sza'] = float(row['sza_deg'])
            c['albedo'] = float(row['albedo'])
            if row['quantity'] != 'pi_I_over_mu0F0':
                continue
            c['rad'][(row['level'], float(row['mu']), float(row['phi_rel_deg']))] = \
                float(row['value'])
    return cases


def disort_references(cases, mus):
    """References at view cosines the table lacks, from PythonicDISORT (pip install
    PythonicDISORT): 128 streams, 64 azimuthal modes and the Henyey-Greenstein moments g^l up
    to l = 127 (below 1e-8, so no delta-M scaling), omega = 1 taken as 1 - 1e-6 (the solver
    excludes 1; more nines make it unstable), black surfaces only; radiances
    interpolated in mu between the streams. Checked against the table at |mu| 0.2 and 0.5
    (the largest relative difference is printed and written to the summary)."""
    from PythonicDISORT import pydisort
    from PythonicDISORT.subroutines import interpolate
    worst = 0.0
    for cid, c in cases.items():
        nq = 128
        leg = np.array([[0.85**l for l in range(nq)]])
        mu0 = np.cos(np.radians(c['sza']))
        u = interpolate(pydisort(np.array([c['tau']]), np.array([min(c['omega'], 1.0 - 1e-6)]),
                                 nq, leg, mu0, 1.0, 0.0, NFourier=64)[-1])

        def value(mu, phi):
            tau = 0.0 if mu > 0 else c['tau']
            return float(np.pi*u(mu, tau, np.radians(phi))/mu0)
        for (lev, mu, phi), v in c['rad'].items():
            if abs(mu) in (0.2, 0.5) and ((lev == 'TOA') == (mu > 0)) and v > 1e-4:
                worst = max(worst, abs(value(mu, phi)/v - 1.0))
        c['rad'] = {}
        for m in mus:
            for sign, lev in ((1.0, 'TOA'), (-1.0, 'BOA')):
                for phi in PHIS:
                    c['rad'][(lev, sign*m, phi)] = value(sign*m, phi)
    return worst


def directions():
    """Upward directions (scored at the top) and downward ones (at the surface)."""
    dirs = []
    for sign in (1.0, -1.0):
        for mu in MUS:
            for phi in (PHIS if mu < 1.0 else [0.0]):
                dirs.append((sign*mu, phi))
    return dirs


def namelist(case, angle, preset, nphot, nb, seed, out):
    dirs = directions()
    if angle > 0.0:
        vr = "vr_preset = '%s', trunc_theta_max_deg = %g" % (preset, angle)
    else:   # the preset as it is
        vr = "vr_preset = '%s'" % preset
    return '\n'.join([
        '&kumo_control n_photons_per_batch = %d, n_batches = %d, seed = %d, verbose = 0 /'
        % (nphot, nb, seed),
        '&kumo_atmosphere nz = 1, z_levels = 0.0, 1000.0, ext1d(1,1) = %r, ssa1d(1,1) = %r, '
        'phase1d(1,1) = 1 /' % (case['tau']/1000.0, case['omega']),
        "&kumo_phase n_phase = 1, phase_kind = 'hg', phase_g = 0.85 /",
        '&kumo_source sza_deg = %g, phi0_deg = 0 /' % case['sza'],
        '&kumo_surface albedo = %g /' % case['albedo'],
        '&kumo_radiance rad_mu = %s, rad_phi_deg = %s, rad_levels = 0, 1 /'
        % (', '.join('%g' % d[0] for d in dirs), ', '.join('%g' % d[1] for d in dirs)),
        '&kumo_vr %s /' % vr,
        "&kumo_output file = '%s' /" % out, ''])


def run(kumo, raw, cid, case, angle, preset, nphot, nb, seed):
    tag = '%s_%s_%g_s%d' % (cid, preset, angle, seed)
    nml = os.path.join(raw, tag + '.nml')
    out = os.path.join(raw, tag + '.nc')
    with open(nml, 'w') as f:
        f.write(namelist(case, angle, preset, nphot, nb, seed, out))
    subprocess.run([kumo, nml], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    with netCDF4.Dataset(out) as ds:
        r = np.array(ds['radiance'][:])            # (direction, rad_level): level 0 BOA, 1 TOA
        e = np.array(ds['radiance_stderr'][:])
        cpu = float(ds.getncattr('cpu_time_s'))
    rows = []
    for d, (mu, phi) in enumerate(directions()):
        lev, il = ('TOA', 1) if mu > 0 else ('BOA', 0)
        ref = case['rad'][(lev, mu, phi)]
        rows.append({'case': cid, 'preset': preset, 'angle': angle, 'seed': seed, 'level': lev,
                     'mu': mu, 'phi_rel': phi, 'kumo': r[d, il], 'stderr': e[d, il],
                     'ref': ref, 'cpu_s': cpu})
    return rows


def pool(rows):
    """One row per radiance: the mean over seeds (equal photons per seed) and its error."""
    groups = {}
    for r in rows:
        groups.setdefault((r['case'], r['level'], r['mu'], r['phi_rel']), []).append(r)
    out = []
    for g in groups.values():
        n = len(g)
        r = dict(g[0])
        r['kumo'] = sum(x['kumo'] for x in g)/n
        r['stderr'] = np.sqrt(sum(x['stderr']**2 for x in g))/n
        r['cpu_s'] = float(np.median([x['cpu_s'] for x in g]))
        out.append(r)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('shared')
    ap.add_argument('--kumo', default='build/kumo')
    ap.add_argument('--out', default='bench/results')
    ap.add_argument('--angles', default='30,40,60,75,89',
                    help='largest truncation angles run with the standard preset')
    ap.add_argument('--presets', default='unbiased',
                    help='presets also run with their own settings (e.g. unbiased,standard,quick)')
    ap.add_argument('--photons', type=int, default=20000)
    ap.add_argument('--batches', type=int, default=20)
    ap.add_argument('--seeds', type=int, default=1)
    ap.add_argument('--name', default='truncation_angle', help='stem of the result files')
    ap.add_argument('--mus', default='',
                    help='view cosines to use instead of the table\'s (e.g. 0.3,0.35,0.4): '
                         'references from PythonicDISORT, black-surface slabs only')
    a = ap.parse_args()
    global MUS, CASES
    cases = load_reference(os.path.join(a.shared, 'reference', 'disort_pp.csv'))
    missing = [c for c in CASES if c not in cases]
    if missing:
        sys.exit('truncation_angle: not in disort_pp.csv: ' + ', '.join(missing))
    check = ''
    if a.mus:
        MUS = [float(x) for x in a.mus.split(',')]
        CASES = [c for c in CASES if cases[c]['albedo'] == 0.0]
        cases = {c: cases[c] for c in CASES}
        worst = disort_references(cases, MUS)
        check = ('References from PythonicDISORT (128 streams, 64 azimuthal modes); against the '
                 'table at |mu| 0.2 '
                 'and 0.5 they differ by at most %.3f %%.' % (100.0*worst))
        print(check)
    angles = [float(x) for x in a.angles.split(',') if x]
    raw = os.path.join(a.out, 'raw', 'truncation_angle')
    os.makedirs(raw, exist_ok=True)
    rows = []
    runs = [(p, 0.0) for p in a.presets.split(',') if p] + [('standard', t) for t in angles]
    for seed in range(1, a.seeds + 1):
        for cid in CASES:
            for preset, angle in runs:
                rows += run(a.kumo, raw, cid, cases[cid], angle, preset, a.photons,
                            a.batches, seed)
    with open(os.path.join(a.out, a.name + '.csv'), 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    # summary: per run setting, over all radiances of all cases (pooled over seeds)
    lines = ['# Truncated radiances against DISORT, by largest truncation angle', '',
             'HG g = 0.85 cases of `reference/disort_pp.csv` (%s); %d x %d photons per run, '
             '%d seed(s), pooled; radiances at the top (upward) and at the surface (downward) in %d '
             'directions each; z = (kumo - DISORT)/stderr.' %
             (', '.join(CASES), a.batches, a.photons, a.seeds, len(directions())//2), '',
             check, '',
             '| setting | radiances | rms z | max abs z | beyond 4 sigma | largest bias '
             '(%) where beyond 3 sigma | median abs bias (%) | CPU s per run |',
             '|---|---|---|---|---|---|---|---|']
    for preset, angle in runs:
        sel = pool([r for r in rows if r['preset'] == preset and r['angle'] == angle
                    and r['ref'] > 1e-4])
        z = np.array([(r['kumo'] - r['ref'])/max(r['stderr'], 1e-300) for r in sel])
        rel = np.array([100.0*(r['kumo'] - r['ref'])/r['ref'] for r in sel])
        big = [(abs(rel[i]), sel[i]) for i in range(len(sel)) if abs(z[i]) > 3.0]
        worst = max(big, key=lambda t: t[0]) if big else None
        wtxt = ('%+.2f (%s %s mu %g phi %g)' % (rel[sel.index(worst[1])], worst[1]['case'],
                                                worst[1]['level'], worst[1]['mu'],
                                                worst[1]['phi_rel'])) if worst else '-'
        cpu = np.median([r['cpu_s'] for r in sel])
        name = preset if angle == 0.0 else 'standard, %g deg' % angle
        lines.append('| %s | %d | %.2f | %.1f | %d | %s | %.2f | %.2f |' %
                     (name, len(sel), np.sqrt(np.mean(z*z)), np.max(np.abs(z)),
                      int(np.sum(np.abs(z) > 4.0)), wtxt, np.median(np.abs(rel)), cpu))
    text = '\n'.join(lines) + '\n'
    with open(os.path.join(a.out, a.name + '.md'), 'w') as f:
        f.write(text)
    print(text)


if __name__ == '__main__':
    main()
