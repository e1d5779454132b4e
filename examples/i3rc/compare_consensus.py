#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Compare kumo's I3RC runs with the I3RC consensus files.

The I3RC consensus results (file sets consensus_result_case<c>.tar of the I3RC web site; copies
in the public repository tamarloeub/MitsubaGradient, mitsuba/notebooks/i3rc/case<c>/
consensus_results/) are per-pixel values without uncertainties; they are not shipped with kumo.
For every consensus file I3RC_cons_res_case<c>_exp<e>_<product>.txt found under DIR (searched
recursively) whose kumo output case<c>_exp<e>_f3d.nc is in the run folder, this prints one
Markdown table row: the consensus domain mean (the average over its pixels), kumo's domain mean
+- standard error (as plot_i3rc.py extracts them), their difference in units of kumo's standard
error, and, pixel by pixel, the rms of (kumo - consensus) / kumo's pixel standard error over the
pixels where that error is not 0 (in clear columns over a black surface kumo's R, A and Iu are
exactly 0, without error; the largest consensus value there is printed to stderr).
Case 3 files hold 128 lines (y) of 128 values (x); cases 1 and 2 one value (x) per line.

Usage:
  python3 examples/i3rc/compare_consensus.py DIR [--run-dir examples/i3rc/run] [--mode f3d]
"""
import argparse
import glob
import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_i3rc import Run

NAME = re.compile(r'I3RC_cons_res_case(\d)_exp(\d)_(R|T|A|H|Iu|Id|I601|I602)\.txt$')
ORDER = ('R', 'T', 'A', 'H', 'Iu', 'Id', 'I601', 'I602')


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('consensus_dir')
    ap.add_argument('--run-dir', default=os.path.join(os.path.dirname(__file__), 'run'))
    ap.add_argument('--mode', default='f3d')
    args = ap.parse_args(argv)
    files = {}
    for path in glob.glob(os.path.join(args.consensus_dir, '**', '*.txt'), recursive=True):
        m = NAME.search(os.path.basename(path))
        if m:
            files[(int(m[1]), int(m[2]), ORDER.index(m[3]))] = path
    if not files:
        print(f'compare_consensus: no I3RC_cons_res_*.txt file under {args.consensus_dir}',
              file=sys.stderr)
        return 1
    print('| case | exp | product | consensus | kumo | difference / σ | '
          'pixels: rms of (kumo − consensus) / σ |')
    print('|---|---|---|---|---|---|---|')
    runs = {}
    for (c, e, ip), path in sorted(files.items()):
        nc = os.path.join(args.run_dir, f'case{c}_exp{e}_{args.mode}.nc')
        if not os.path.exists(nc):
            continue
        if nc not in runs:
            runs[nc] = Run(nc)
        run, p = runs[nc], ORDER[ip]
        cons = np.loadtxt(path).reshape(run.maps[p].shape)
        ok = run.maps_se[p] > 0   # clear columns: R, Iu, A exactly 0 in kumo, no error
        if not ok.all():
            print(f'case {c} exp {e} {p}: {np.sum(~ok)} pixels with kumo value '
                  f'{np.abs(run.maps[p][~ok]).max():.1e} and no error, consensus up to '
                  f'{np.abs(cons[~ok]).max():.1e}', file=sys.stderr)
        m, s = run.mean[p], run.mean_se[p]
        z = (run.maps[p][ok] - cons[ok]) / run.maps_se[p][ok]
        print(f'| {c} | {e} | {p} | {cons.mean():.4f} | {m:.4f} ± {s:.4f} | '
              f'{(m - cons.mean()) / s:+.1f} | {np.sqrt(np.mean(z ** 2)):.2f} |'
              .replace('-', '−').replace('+0.0 |', '0.0 |'))
    return 0


if __name__ == '__main__':
    sys.exit(main())
