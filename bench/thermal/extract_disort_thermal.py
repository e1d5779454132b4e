#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Write tests/data/thermal/disort_thermal_problems.csv: the inputs and the published answers of
DISORT's thermal test problems 6 (a-h), 7 (a-e) and 9c in one compact file, so that tests need no
other source.

Answers: the DISOTEST "correct answers" (DISORT v2.0 beta, DISOTEST.f, BLOCK DATA CHEKDO: DISORT
run in double precision; Stamnes, Tsay, Wiscombe and Jayaweera 1988, Appl. Opt. 27, 2502), read
from data/disort/disotest_v2.0beta_correct_answers.csv of the shared data directory.
Inputs: transcribed from the problem set-up in the same DISOTEST.f (test problems 6, 7 and 9),
written out here as numbers. The band Planck radiances that DISORT used are added (its PLKAVG
with sigma = 5.67032e-8 W m-2 K-4 and c2 = 1.438786 cm K, which differ from CODATA 2018 by
1.9e-5 relative), computed by adaptive quadrature (make_thermal_reference.band_planck).

Usage: python3 bench/thermal/extract_disort_thermal.py --shared-dir <KUMO_SHARED_DIR> [--output F]
(needs numpy and scipy).
"""
import argparse
import os
from math import pi

from make_thermal_reference import C2_DISORT, SIGMA_DISORT, band_planck


def problems():
    """Inputs of DISOTEST problems 6a-h, 7a-e and 9c in DISORT's conventions (layers and levels
    numbered from the top, level 0 = top; UMU > 0 upward; PHI relative to the beam's PHI0)."""
    out = []
    base6 = dict(nstr=16, nmom=16, nlyr=1, ssalb=[0.0], phase=[0], g=[0.0], wvnmlo=0.0, wvnmhi=50000.0,
                 umu=[-1.0, -0.1, 0.1, 1.0], phi=[90.0], fbeam=200.0, umu0=0.5, phi0=0.0, fisot=0.0, temis=1.0,
                 onlyfl=0, albedo=0.0, btemp=0.0, ttemp=0.0, temper=[0.0, 0.0], plank=0)
    for case in 'abcdefgh':
        p = dict(base6, problem=6, case=case)
        p['dtauc'] = [0.0 if case == 'a' else (10.0 if case == 'h' else 1.0)]
        p['utau'] = [0.0, 0.0] if case == 'a' else ([0.0, 1.0, 10.0] if case == 'h' else [0.0, 0.5, 1.0])
        p['lamber'] = 1 if case in 'abc' else 0
        p['albedo'] = 0.5 if case == 'c' else 0.0
        if case in 'efgh':
            p['plank'] = 1
            p['btemp'] = 300.0
        if case in 'fgh':
            p['ttemp'] = 250.0
        if case in 'fgh':                  # set in 6f and kept by DISOTEST for 6g, 6h
            p['fisot'] = 100.0 / pi
        if case in 'gh':
            p['temper'] = [250.0, 300.0]
        out.append(p)
    out.append(dict(problem=7, case='a', nstr=16, nmom=16, nlyr=1, dtauc=[1.0], ssalb=[0.1], phase=[1], g=[0.05],
                    temper=[200.0, 300.0], wvnmlo=300.0, wvnmhi=800.0, utau=[0.0, 1.0], umu=[-1.0, 1.0], phi=[0.0],
                    fbeam=0.0, umu0=1.0, phi0=0.0, fisot=0.0, lamber=1, albedo=0.0, plank=1, btemp=0.0, ttemp=0.0,
                    temis=1.0, onlyfl=1))
    out.append(dict(out[-1], case='b', dtauc=[100.0], ssalb=[0.95], g=[0.75], wvnmlo=2702.99, wvnmhi=2703.01,
                    utau=[0.0, 100.0], onlyfl=0))
    base7c = dict(problem=7, case='c', nstr=12, nmom=12, nlyr=1, dtauc=[1.0], ssalb=[0.5], phase=[1], g=[0.8],
                  temper=[300.0, 200.0], wvnmlo=0.0, wvnmhi=50000.0, utau=[0.0, 0.5, 1.0],
                  umu=[-1.0, -0.1, 0.1, 1.0], phi=[0.0, 90.0], fbeam=200.0, umu0=0.5, phi0=0.0, fisot=100.0,
                  lamber=1, albedo=0.0, plank=1, btemp=320.0, ttemp=100.0, temis=1.0, onlyfl=0)
    out.append(base7c)
    out.append(dict(base7c, case='d', albedo=1.0))
    out.append(dict(base7c, case='e', lamber=0))
    out.append(dict(problem=9, case='c', nstr=8, nmom=8, nlyr=6, dtauc=[float(lc) for lc in range(1, 7)],
                    ssalb=[0.6 + lc * 0.05 for lc in range(1, 7)], phase=[1] * 6, g=[lc / 7.0 for lc in range(1, 7)],
                    temper=[600.0 + lc * 10.0 for lc in range(0, 7)], wvnmlo=999.0, wvnmhi=1000.0,
                    utau=[0.0, 1.05, 2.1, 6.0, 21.0], umu=[-1.0, -0.2, 0.2, 1.0], phi=[60.0, 120.0, 180.0],
                    fbeam=pi, umu0=0.5, phi0=0.0, fisot=1.0, lamber=1, albedo=0.5, plank=1, btemp=700.0,
                    ttemp=550.0, temis=1.0, onlyfl=0))
    return out


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--shared-dir', default=os.environ.get('KUMO_SHARED_DIR', '../shared'))
    parser.add_argument('--output', default=os.path.join(here, '..', '..', 'tests', 'data', 'thermal',
                                                         'disort_thermal_problems.csv'))
    args = parser.parse_args()
    answers = []
    with open(os.path.join(args.shared_dir, 'data', 'disort', 'disotest_v2.0beta_correct_answers.csv')) as f:
        for line in f:
            if line.startswith('#') or line.startswith('problem') or not line.strip():
                continue
            fields = line.strip().split(',')
            answers.append(fields)
    lines = [
        '# disort_thermal_problems.csv: DISORT test problems 6a-h, 7a-e and 9c (thermal emission):',
        '# inputs and the DISOTEST "correct answers" (see README.md here for the sources).',
        "# DISORT's conventions: layers lc = 1..nlyr and levels 0..nlyr numbered from the TOP (level 0 =",
        '# top); utau = optical depth from the top; umu > 0 upward-travelling; phi in degrees relative',
        '# to the beam azimuth phi0. Radiances in W m-2 sr-1, fluxes in W m-2 (band-integrated over',
        '# [wvnmlo, wvnmhi] cm-1 when plank = 1; problems 6a-d have no thermal source and their units',
        '# are those of fbeam).',
        '# Columns: problem,case,quantity,i,j,k,value',
        '#  inputs (i = layer lc, level, or position in a list; j, k empty):',
        '#   nstr, nmom (streams and moments DISORT used), nlyr, dtauc(lc), ssalb(lc),',
        '#   phase(lc) (0 isotropic, 1 Henyey-Greenstein), hg_g(lc), plank (1 = thermal sources on),',
        '#   temper(level) [K], wvnmlo, wvnmhi [cm-1], btemp, ttemp [K], temis (top emissivity),',
        '#   fbeam (beam flux normal to the beam), umu0, phi0, fisot (isotropic top radiance, added to',
        '#   temis*B(ttemp)), lamber (1 Lambert with albedo; 0 Hapke BRDF, see README), albedo,',
        '#   onlyfl (1 = no intensities), utau(i), umu(i), phi(i) [deg];',
        "#   planck_temper(level), planck_btemp, planck_ttemp: band Planck radiances with DISORT's",
        '#   constants (sigma 5.67032e-8, c2 1.438786 cm K) as DISORT used them (only when plank = 1).',
        '#  answers: FIR direct flux (RFLDIR), FDN diffuse down flux (RFLDN), FUP up flux (FLUP),',
        '#   DFD flux divergence DFDT = d(net flux)/d(tau) (> 0 where absorbed; DISOTEST values),',
        '#   with i = itau; UU intensity with i = itau, j = imu, k = iphi (indices into utau, umu, phi).',
        'problem,case,quantity,i,j,k,value',
    ]

    def fmt(v):
        return str(v) if isinstance(v, int) else f'{v:.12g}'

    for p in problems():
        pre = f"{p['problem']},{p['case']}"

        def put(name, value, i=0):
            lines.append(f'{pre},{name},{i},,,{fmt(value)}')

        for key in ('nstr', 'nmom', 'nlyr'):
            put(key, p[key])
        for lc in range(p['nlyr']):
            put('dtauc', p['dtauc'][lc], lc + 1)
            put('ssalb', p['ssalb'][lc], lc + 1)
            put('phase', p['phase'][lc], lc + 1)
            put('hg_g', p['g'][lc], lc + 1)
        put('plank', p['plank'])
        for lev, t in enumerate(p['temper']):
            put('temper', t, lev)
        for key in ('wvnmlo', 'wvnmhi', 'btemp', 'ttemp', 'temis', 'fbeam', 'umu0', 'phi0', 'fisot', 'lamber',
                    'albedo', 'onlyfl'):
            put(key, p[key])
        for key in ('utau', 'umu', 'phi'):
            for i, v in enumerate(p[key]):
                put(key, v, i + 1)
        if p['plank']:
            def b(t):
                return band_planck(p['wvnmlo'], p['wvnmhi'], t, SIGMA_DISORT, C2_DISORT)
            for lev, t in enumerate(p['temper']):
                put('planck_temper', b(t), lev)
            put('planck_btemp', b(p['btemp']))
            put('planck_ttemp', b(p['ttemp']))
        n = 0
        for a in answers:
            if int(a[0]) == p['problem'] and a[1] == p['case']:
                lines.append(f"{pre},{a[2]},{a[3]},{a[4]},{a[5]},{a[6]}")
                n += 1
        if n == 0:
            raise SystemExit(f"no answers for {p['problem']}{p['case']}")
        print(f"{p['problem']}{p['case']}: {n} answers")
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    with open(args.output, 'w') as f:
        f.write('\n'.join(lines) + '\n')
    print('wrote', os.path.relpath(args.output))


if __name__ == '__main__':
    main()
