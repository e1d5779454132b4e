#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Are kumo's standard errors consistent with the scatter between seeds?

Runs one case of examples/mcarats_les05 (the MCARaTS LES scene, SZA 60 by default) with seeds
1 .. N, one run at a time, and compares the seed-to-seed scatter of the domain means with the
standard errors kumo reports (the standard error of the mean over the batches of one run):

  chi2      sum over seeds of ((x_s - m) / sigma_s)^2, m the weighted mean, with N - 1 degrees of
            freedom, and its upper tail probability (a chi-square one: with sigma_s estimated
            from B batches each term has the mean (B - 1)/(B - 3), 1.12 for 20 batches, so this
            p is somewhat small; F below is the sharper test)
  ratio     standard deviation of the seed means over the rms of the reported sigmas (1 when
            the sigmas are right; its own 1-sigma spread is about 1 / sqrt(2 (N - 1)))
  sigma sd  relative standard deviation of the reported sigmas, against 1 / sqrt(2 (B - 1)) for
            B batches of normally distributed batch values
  F         one-way analysis of variance of all N x B batch values (the output's
            batch_reflectance, batch_transmittance, batch_absorptance): the variance between
            seeds (B times the variance of the seed means) over the pooled variance within seeds;
            F ~ 1 when the batches are independent, > 1 when batches of one run share something
  max |z|   the largest |x_s - m| / sigma_s, with its seed

Variants (--variants, comma-separated): `strat` (the example as it is: stratified entry, photons
per batch not a multiple of the 3600 columns, so the last photons of a batch enter on the
lattice), `strat_mult` (stratified, photons per batch rounded to a multiple of the columns: no
lattice), `plain` (`&kumo_vr stratify_source = .false.`: independent entry points).

Usage:
  python3 bench/seed_scatter.py [--kumo build/kumo] [--seeds 10] [--photons 100000]
      [--batches 20] [--sza 60] [--variants strat,strat_mult,plain] [--first-seed 1]
      [--halves] [--out DIR]
Takes about 12 CPU-s per run at the defaults (30 runs: 6 minutes). The namelists are those of
examples/mcarats_les05/run_mcarats_les05.sh (written by it with KUMO=true, which runs nothing),
with the seed, the photons per batch and the output file changed. Writes <out>/seed_scatter.csv
(one line per run) and prints the summary; the netCDF files stay in <out>/ (default
bench/results/raw/seed_scatter, not kept in git; the measured table is kept in
bench/results/seed_scatter.csv). Build kumo in Release first.
"""
import argparse
import csv
import math
import os
import re
import shutil
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
N_COLUMNS = 3600                       # 60 x 60 columns of the 3-D region
PRODUCTS = (('R', 'reflectance', 'batch_reflectance'),
            ('T', 'transmittance', 'batch_transmittance'),
            ('A', 'absorptance_atmosphere', 'batch_absorptance'))


def gamma_q(a, x):
    """Regularised upper incomplete gamma function Q(a, x) (series or continued fraction)."""
    if x <= 0.0:
        return 1.0
    lg = math.lgamma(a)
    if x < a + 1.0:
        term = total = 1.0 / a
        n = a
        while abs(term) > 1e-15 * abs(total):
            n += 1.0
            term *= x / n
            total += term
        return 1.0 - total * math.exp(-x + a * math.log(x) - lg)
    b, c, d = x + 1.0 - a, 1e300, 1.0 / (x + 1.0 - a)
    h = d
    for i in range(1, 1000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = 1e-300 if abs(d) < 1e-300 else d
        c = b + an / c
        c = 1e-300 if abs(c) < 1e-300 else c
        d = 1.0 / d
        h *= d * c
        if abs(d * c - 1.0) < 1e-15:
            break
    return math.exp(-x + a * math.log(x) - lg) * h


def write_namelists(out, kumo_true):
    """The example's namelists (both SZAs) in `out`, written by its own script."""
    env = dict(os.environ, KUMO=kumo_true, KUMO_RUN_DIR=out)
    subprocess.run(['bash', os.path.join(REPO, 'examples', 'mcarats_les05',
                                         'run_mcarats_les05.sh')],
                   env=env, check=True, stdout=subprocess.DEVNULL)


def make_variant(template, name, seed, photons, batches, stratify):
    text = re.sub(r'&kumo_control[^/]*/',
                  f'&kumo_control n_photons_per_batch = {photons}, n_batches = {batches}, '
                  f'seed = {seed} /', template, count=1)
    text = re.sub(r"file = '[^']*\.nc'", f"file = '{name}.nc'", text, count=1)
    if not stratify:
        text += '&kumo_vr stratify_source = .false. /\n'
    return text


def run(kumo, out, name, text):
    path = os.path.join(out, name + '.nml')
    with open(path, 'w') as f:
        f.write(text)
    done = subprocess.run([kumo, name + '.nml'], cwd=out, capture_output=True, text=True,
                          check=False)
    if done.returncode != 0:
        sys.exit(f'seed_scatter: kumo failed on {path}:\n{done.stderr}')
    cpu = re.search(r'cpu ([0-9.eE+-]+) s', done.stdout)
    from netCDF4 import Dataset
    with Dataset(os.path.join(out, name + '.nc')) as nc:
        row = {'run': name, 'cpu_s': float(cpu[1]) if cpu else float('nan')}
        batches = {}
        for p, var, bvar in PRODUCTS:
            row[p] = float(nc[var][...])
            row[p + '_stderr'] = float(nc[var + '_stderr'][...])
            batches[p] = np.asarray(nc[bvar][...], dtype=float)
    return row, batches


def analyse(rows, batches, p):
    x = np.array([r[p] for r in rows])
    s = np.array([r[p + '_stderr'] for r in rows])
    n = len(x)
    w = 1.0 / s ** 2
    m = float(np.sum(w * x) / np.sum(w))
    z = (x - m) / s
    chi2 = float(np.sum(z ** 2))
    b = np.array([bb[p] for bb in batches])           # seeds x batches
    nb = b.shape[1]
    within = float(np.mean(np.var(b, axis=1, ddof=1)))
    between = float(nb * np.var(b.mean(axis=1), ddof=1))
    kurt = float(np.mean((b - b.mean(axis=1, keepdims=True)) ** 4) /
                 np.mean((b - b.mean(axis=1, keepdims=True)) ** 2) ** 2)
    imax = int(np.argmax(np.abs(z)))
    return {'n': n, 'mean': m, 'sd_seeds': float(np.std(x, ddof=1)),
            'rms_sigma': float(np.sqrt(np.mean(s ** 2))),
            'ratio': float(np.std(x, ddof=1) / np.sqrt(np.mean(s ** 2))),
            'sigma_rel_sd': float(np.std(s, ddof=1) / np.mean(s)),
            'sigma_rel_sd_expected': 1.0 / math.sqrt(2.0 * (nb - 1)),
            'chi2': chi2, 'p': gamma_q(0.5 * (n - 1), 0.5 * chi2),
            'F': between / within, 'p_F': f_upper(between / within, n - 1, n * (nb - 1)),
            'kurtosis': kurt, 'zmax': float(z[imax]), 'seed_zmax': rows[imax]['seed']}


def f_upper(f, d1, d2):
    """Upper tail of the F distribution by the regularised incomplete beta function, from a
    midpoint sum of its density in the variable t = d1 f / (d1 f + d2) (accurate to ~1e-6)."""
    x = d1 * f / (d1 * f + d2)
    a, b = 0.5 * d1, 0.5 * d2
    ln_beta = math.lgamma(a) + math.lgamma(b) - math.lgamma(a + b)
    n = 200000
    h = (1.0 - x) / n
    total = 0.0
    for i in range(n):
        t = x + (i + 0.5) * h
        total += math.exp((a - 1) * math.log(t) + (b - 1) * math.log1p(-t) - ln_beta)
    return total * h


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--kumo', default=os.path.join(REPO, 'build', 'kumo'))
    ap.add_argument('--seeds', type=int, default=10)
    ap.add_argument('--photons', type=int, default=100000)
    ap.add_argument('--batches', type=int, default=20)
    ap.add_argument('--sza', type=int, default=60, choices=(0, 60))
    ap.add_argument('--variants', default='strat,strat_mult,plain')
    ap.add_argument('--first-seed', type=int, default=1)
    ap.add_argument('--halves', action='store_true',
                    help='also print the means of the first and the second half of the batches')
    ap.add_argument('--out', default=os.path.join(HERE, 'results', 'raw', 'seed_scatter'))
    args = ap.parse_args(argv)
    kumo = os.path.abspath(args.kumo)
    if not os.access(kumo, os.X_OK):
        sys.exit(f'seed_scatter: {kumo} not found; build kumo first (bash scripts/build.sh)')
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    write_namelists(out, shutil.which('true'))
    with open(os.path.join(out, f'les05_sza{args.sza}.nml')) as f:
        template = f.read()
    mult = max(1, round(args.photons / N_COLUMNS)) * N_COLUMNS
    setups = {'strat': (args.photons, True), 'strat_mult': (mult, True),
              'plain': (args.photons, False)}
    rows_all = []
    for variant in args.variants.split(','):
        photons, stratify = setups[variant]
        rows, batches = [], []
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            name = f'sza{args.sza}_{variant}_seed{seed}'
            row, b = run(kumo, out, name,
                         make_variant(template, name, seed, photons, args.batches, stratify))
            row.update(variant=variant, seed=seed, photons_per_batch=photons)
            rows.append(row)
            batches.append(b)
            print(f'{name}: R {row["R"]:.5f} ± {row["R_stderr"]:.5f}, T {row["T"]:.5f} ± '
                  f'{row["T_stderr"]:.5f}, A {row["A"]:.5f} ± {row["A_stderr"]:.5f}, '
                  f'cpu {row["cpu_s"]:.1f} s', flush=True)
            if args.halves:
                for p, _, _ in PRODUCTS:
                    h = np.array_split(b[p], 2)
                    print('   ' + p + ': batches 1-' + str(len(h[0])) + ' ' + ', then '.join(
                        f'{x.mean():.5f} ± {x.std(ddof=1) / np.sqrt(len(x)):.5f}' for x in h))
        rows_all += rows
        print(f'== {variant}: {args.seeds} seeds x {args.batches} batches of {photons} photons '
              f'(stratified entry {"on" if stratify else "off"})')
        for p, _, _ in PRODUCTS if len(rows) > 1 else ():
            a = analyse(rows, batches, p)
            print(f'  {p}: mean {a["mean"]:.5f}, sd of the seed means {a["sd_seeds"]:.2e}, rms '
                  f'sigma {a["rms_sigma"]:.2e}, ratio {a["ratio"]:.2f}; chi2 {a["chi2"]:.1f} '
                  f'on {a["n"] - 1} dof (p {a["p"]:.3f}); sigma rel. sd {a["sigma_rel_sd"]:.2f} '
                  f'(expected {a["sigma_rel_sd_expected"]:.2f}); F {a["F"]:.2f} (p '
                  f'{a["p_F"]:.3f}); batch kurtosis {a["kurtosis"]:.2f}; max |z| '
                  f'{abs(a["zmax"]):.1f} (seed {a["seed_zmax"]})', flush=True)
    fields = ['variant', 'seed', 'photons_per_batch', 'cpu_s'] + \
        [k for p, _, _ in PRODUCTS for k in (p, p + '_stderr')]
    with open(os.path.join(out, 'seed_scatter.csv'), 'w', newline='') as f:
        wr = csv.DictWriter(f, fieldnames=fields, extrasaction='ignore')
        wr.writeheader()
        wr.writerows(rows_all)
    print(f'wrote {os.path.join(out, "seed_scatter.csv")}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
