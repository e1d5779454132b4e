#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Reference fluxes and radiances of 1-D thermal-emission cases from an independent solver.

The solver is PythonicDISORT (PyPI package `PythonicDISORT`, D. J. Ho, "PythonicDISORT: a
Python reimplementation of the Discrete Ordinate Radiative Transfer package DISORT", J. Open
Source Softw. 9 (2024) 6442), a discrete-ordinates code written independently of kumo. It takes
an isotropic internal source given as a polynomial in optical depth per layer (multiplied by
1 - ssa inside, Kirchhoff's law), so the Planck source linear in optical depth between level
values (DISORT's convention, which kumo uses) is represented exactly.

Usage (needs numpy, scipy and PythonicDISORT: `pip install PythonicDISORT==1.8`, which brings
numpy and scipy; the file was made with numpy 2.4, scipy 1.17; about ten minutes on one core,
most of it in the two scattering clouds with 256-400 streams):

    python3 bench/thermal/make_thermal_reference.py --shared-dir <KUMO_SHARED_DIR> \
        [--validate-only] [--output tests/data/thermal/thermal_1d_reference.csv]

1. Validation: DISORT test problems 6 (a-c) and 7 (a-d), the cases with Lambert surfaces, are
   run with DISORT's inputs and compared with the DISOTEST "correct answers"
   (data/disort/disotest_v2.0beta_correct_answers.csv in the shared directory). The script
   prints the largest relative differences per quantity and fails if a flux differs by more
   than 1e-4 relative to the case's largest flux.
2. Reference cases (kumo's conventions: layers bottom to top, levels 0 = surface .. nz = top),
   each solved with two stream numbers; the larger one is written, and the difference between
   the two is written as the reference's own uncertainty (`solver_abs_error` rows).

Units: band Planck radiances and radiances in W m-2 sr-1, fluxes in W m-2. Band Planck values
are computed here from Planck's law with the CODATA 2018 constants of scipy.constants by
adaptive quadrature of x^3/(e^x - 1) (relative accuracy 1e-13) and written to the file, so a
test can use them directly or check its own band integral against them.
"""
import argparse
import os
import sys
import warnings
from math import pi

import numpy as np
import scipy.constants as const
import scipy.integrate as integrate
from PythonicDISORT import pydisort, subroutines

SIGMA_CODATA = const.Stefan_Boltzmann
C2_CODATA = 100.0 * const.h * const.c / const.k        # second radiation constant [cm K]
SIGMA_DISORT, C2_DISORT = 5.67032e-8, 1.438786           # the constants of DISORT's PLKAVG


def band_planck(nu1, nu2, temp, sigma=SIGMA_CODATA, c2=C2_CODATA):
    """Planck radiance integrated over [nu1, nu2] cm-1 [W m-2 sr-1]:
    (sigma/pi) T^4 (15/pi^4) Int_{x1}^{x2} x^3/(e^x - 1) dx, x = c2 nu/T."""
    if temp <= 0.0:
        return 0.0
    x1, x2 = c2 * nu1 / temp, min(c2 * nu2 / temp, 700.0)
    if x1 >= x2:
        return 0.0
    value = integrate.quad(lambda x: x**3 / np.expm1(x) if x > 0.0 else 0.0, x1, x2,
                           epsabs=0.0, epsrel=1.0e-13, limit=500)[0]
    return sigma / pi * temp**4 * 15.0 / pi**4 * value


def solve(tau, ssa, chi, b_level, emissivity, b_surface, i_top, nquad, beam=None, albedo=None):
    """Run PythonicDISORT on a column given bottom to top (kumo's order).

    tau, ssa: (nz) layer optical depths and single-scattering albedos; chi: list of nz arrays of
    normalised Legendre moments (chi_0 = 1); b_level: (nz+1) Planck radiances at levels 0..nz;
    surface Lambertian with the given emissivity (albedo 1 - emissivity unless given) and Planck
    radiance b_surface; isotropic downward radiance i_top at the top; beam = (flux normal to the
    beam, mu0) or None. Returns the solver's functions of optical depth from the top and the
    total optical depth."""
    nz = len(tau)
    tau_top = np.asarray(tau, float)[::-1]                 # top to bottom
    tau_lower = np.cumsum(tau_top)                         # optical depth of each lower boundary
    tau_upper = tau_lower - tau_top
    b_top = np.asarray(b_level, float)[::-1]               # levels from the top
    slope = np.where(tau_top > 0.0, (b_top[1:] - b_top[:-1]) / np.where(tau_top > 0, tau_top, 1.0), 0.0)
    s_poly = np.column_stack([b_top[:-1] - slope * tau_upper, slope])
    nleg_all = max(nquad + 1, max(len(c) for c in chi))
    leg = np.zeros((nz, nleg_all))
    for k, c in enumerate(chi[::-1]):
        leg[k, :len(c)] = c
    f_arr = leg[:, nquad] if nleg_all > nquad else 0.0
    if albedo is None:
        albedo = 1.0 - emissivity
    mu0, i0 = (0.5, 0.0) if beam is None else (beam[1], beam[0])
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        out = pydisort(tau_lower, np.asarray(ssa, float)[::-1], nquad, leg, mu0, i0, 0.0,
                       NLeg=nquad, f_arr=f_arr, NT_cor=beam is not None,
                       b_pos=emissivity * b_surface, b_neg=i_top,
                       BDRF_Fourier_modes=[albedo] if albedo > 0.0 else [],
                       s_poly_coeffs=s_poly)
    return out, tau_lower[-1]


def fluxes_at(out, tau_from_top):
    """Diffuse up, diffuse down and direct fluxes at optical depths from the top."""
    t = np.asarray(tau_from_top, float)
    up = np.atleast_1d(out[1](t))
    down, direct = out[2](t)
    return up, np.atleast_1d(down), np.broadcast_to(direct, up.shape)


def flux_divergence(out, t, t_lo, t_hi):
    """DISORT's DFDT = -d(net downward flux)/d(tau) (> 0 where radiation is absorbed) at t
    inside [t_lo, t_hi] (one layer), by a 4th-order centred difference or a one-sided 3rd-order
    one at the layer's edges."""
    def net(x):
        up, down, direct = fluxes_at(out, x)
        return down + direct - up
    h = 1.0e-3 * min(t_hi - t_lo, 1.0)
    if t - 2 * h >= t_lo and t + 2 * h <= t_hi:
        x = t + h * np.array([-2.0, -1.0, 1.0, 2.0])
        return -float(np.dot(net(x), [1.0, -8.0, 8.0, -1.0]) / (12.0 * h))
    sign = 1.0 if t + 3 * h <= t_hi else -1.0
    x = t + sign * h * np.arange(4.0)
    return -float(sign * np.dot(net(x), [-11.0, 18.0, -9.0, 2.0]) / (6.0 * h))


def radiances(out, col, mu, tau_from_top, n_gauss=12):
    """Radiances at directions mu (> 0 upward) and optical depths from the top by integrating
    the source function of the discrete-ordinates solution along the line of sight (as DISORT
    does for its user angles; polynomial interpolation between the nodes is not accurate
    enough). Azimuthally symmetric fields only (no beam, or no scattering).

    col: dict with tau_top, ssa_top, chi_top (top to bottom), b_top (levels from the top),
    i_top and the surface-leaving radiance function surface(mu)."""
    mu_nodes, w = subroutines.Gauss_Legendre_quad(len(out[0]) // 2)
    mu_all = np.concatenate([mu_nodes, -mu_nodes])
    w_all = np.concatenate([w, w])
    nleg = len(out[0])
    tau_lower = np.cumsum(col['tau_top'])
    tau_upper = tau_lower - col['tau_top']
    xg, wg = np.polynomial.legendre.leggauss(n_gauss)
    result = np.zeros((len(mu), len(tau_from_top)))
    for i, m in enumerate(mu):
        for j, t0 in enumerate(tau_from_top):
            total, path_end = 0.0, tau_lower[-1] if m > 0 else 0.0
            for k in range(len(tau_lower)):
                lo, hi = (max(tau_upper[k], t0), tau_lower[k]) if m > 0 else (tau_upper[k], min(tau_lower[k], t0))
                if hi <= lo:
                    continue
                # sub-intervals of at most 0.2 |mu| in optical depth, up to 40 e-foldings away
                far = t0 + 40.0 * abs(m) if m > 0 else t0 - 40.0 * abs(m)
                lo2, hi2 = (lo, min(hi, far)) if m > 0 else (max(lo, far), hi)
                if hi2 <= lo2:
                    continue
                n_sub = int(np.ceil((hi2 - lo2) / (0.2 * abs(m))))
                edges = np.linspace(lo2, hi2, n_sub + 1)
                t = (0.5 * (edges[1:] + edges[:-1])[:, None] + 0.5 * np.diff(edges)[:, None] * xg[None, :]).ravel()
                wt = (0.5 * np.diff(edges)[:, None] * wg[None, :]).ravel()
                u_nodes = np.hstack([np.atleast_2d(out[3](t[c:c + 100])) for c in range(0, len(t), 100)])
                chi = np.zeros(nleg)
                c = col['chi_top'][k][:nleg]
                chi[:len(c)] = c
                p_nodes = np.polynomial.legendre.legvander(mu_all, nleg - 1)    # (nquad, nleg)
                moments = (p_nodes * w_all[:, None]).T @ u_nodes                # (nleg, nt)
                p_mu = np.polynomial.legendre.legvander(np.array([m]), nleg - 1)[0]
                scat = 0.5 * col['ssa_top'][k] * ((2 * np.arange(nleg) + 1) * chi * p_mu) @ moments
                frac = (t - tau_upper[k]) / col['tau_top'][k]
                planck = col['b_top'][k] + (col['b_top'][k + 1] - col['b_top'][k]) * frac
                source = scat + (1.0 - col['ssa_top'][k]) * planck
                total += np.sum(wt * source * np.exp(-np.abs(t - t0) / abs(m))) / abs(m)
            boundary = col['surface'](m) if m > 0 else col['i_top']
            total += boundary * np.exp(-abs(path_end - t0) / abs(m))
            result[i, j] = total
    return result


# -------------------------------------------------------------------------------------------
# Validation against DISOTEST problems 6 and 7
# -------------------------------------------------------------------------------------------

def read_disotest(path):
    answers = {}
    with open(path) as f:
        for line in f:
            if line.startswith('#') or line.startswith('problem') or not line.strip():
                continue
            p, c, q, itau, imu, iphi, v = line.strip().split(',')
            answers[(int(p), c, q, int(itau), int(imu) if imu else 0, int(iphi) if iphi else 0)] = float(v)
    return answers


def disort_hg(g, nmom):
    return np.array([g**l for l in range(nmom + 1)])


def disotest_cases():
    """Inputs of DISOTEST problems 6a-c and 7a-d (DISOTEST.f of DISORT v2.0 beta), each as one
    layer seen from the top: (problem, case, nstr, dtau, ssa, chi, t_top, t_bottom, band, beam,
    fisot, ttemp, btemp, albedo, utau, umu, phi [deg])."""
    no_t = None
    cases = []
    umu6 = [-1.0, -0.1, 0.1, 1.0]
    for c, dtau, alb in (('a', 0.0, 0.0), ('b', 1.0, 0.0), ('c', 1.0, 0.5)):
        utau = [0.0, 0.0] if c == 'a' else [0.0, 0.5, 1.0]
        cases.append((6, c, 16, dtau, 0.0, np.array([1.0]), no_t, no_t, (0.0, 50000.0), (200.0, 0.5),
                      0.0, 0.0, 0.0, alb, utau, umu6, [90.0]))
    cases.append((7, 'a', 16, 1.0, 0.1, disort_hg(0.05, 16), 200.0, 300.0, (300.0, 800.0), None,
                  0.0, 0.0, 0.0, 0.0, [0.0, 1.0], [-1.0, 1.0], [0.0]))
    cases.append((7, 'b', 16, 100.0, 0.95, disort_hg(0.75, 16), 200.0, 300.0, (2702.99, 2703.01), None,
                  0.0, 0.0, 0.0, 0.0, [0.0, 100.0], [-1.0, 1.0], [0.0]))
    for c, alb in (('c', 0.0), ('d', 1.0)):
        cases.append((7, c, 12, 1.0, 0.5, disort_hg(0.8, 12), 300.0, 200.0, (0.0, 50000.0), (200.0, 0.5),
                      100.0, 100.0, 320.0, alb, [0.0, 0.5, 1.0], [-1.0, -0.1, 0.1, 1.0], [0.0, 90.0]))
    return cases


def validate(shared_dir):
    answers = read_disotest(os.path.join(shared_dir, 'data', 'disort', 'disotest_v2.0beta_correct_answers.csv'))
    worst_flux = 0.0
    print('Validation against DISOTEST (DISORT v2.0 beta, double precision): max |diff| / max |value of case|'
          ' (DFD: of the largest DFD, UU: of the largest intensity)')
    for (prob, case, nstr, dtau, ssa, chi, t_top, t_bot, (nu1, nu2), beam, fisot, ttemp, btemp, alb,
         utau, umu, phi) in disotest_cases():
        def b(t):
            return band_planck(nu1, nu2, t, SIGMA_DISORT, C2_DISORT) if t else 0.0
        dt = max(dtau, 1.0e-12)
        b_lev = [b(t_bot), b(t_top)]                         # bottom, top (kumo order)
        out, _ = solve([dt], [ssa], [chi], b_lev, 1.0 - alb, b(btemp), fisot + b(ttemp), nstr, beam=beam,
                       albedo=alb)
        utau = np.minimum(np.array(utau), dt)
        up, down, direct = fluxes_at(out, utau)
        mine = {}
        for i, t in enumerate(utau):
            mine[('FIR', i + 1)] = direct[i]
            mine[('FDN', i + 1)] = down[i]
            mine[('FUP', i + 1)] = up[i]
            if dtau > 0.0:
                mine[('DFD', i + 1)] = flux_divergence(out, t, 0.0, dt)
        fmax = max(abs(v) for (p, c, q, *_), v in answers.items()
                   if p == prob and c == case and q not in ('UU', 'DFD'))
        diffs = {}
        for (q, i), v in mine.items():
            ref = answers.get((prob, case, q, i, 0, 0))
            if ref is None:
                continue
            scale = fmax if q != 'DFD' else max(abs(answers[(prob, case, 'DFD', j, 0, 0)])
                                                for j in range(1, len(utau) + 1))
            diffs[q] = max(diffs.get(q, 0.0), abs(v - ref) / scale)
        worst_flux = max([worst_flux] + [d for qq, d in diffs.items() if qq in ('FIR', 'FDN', 'FUP')])
        # Intensities at DISORT's user angles: source-function integration where the field is
        # azimuthally symmetric; otherwise (7c, d: beam and scattering) PythonicDISORT's
        # polynomial interpolation, which is not accurate at user angles (reported only).
        if beam is None or ssa == 0.0:
            up_b, down_b, direct_b = fluxes_at(out, [dt])
            i_sfc = (1.0 - alb) * b(btemp) + alb * (down_b[0] + direct_b[0]) / pi
            col = dict(tau_top=np.array([dt]), ssa_top=[ssa], chi_top=[chi], b_top=b_lev[::-1],
                       i_top=fisot + b(ttemp), surface=lambda m, v=i_sfc: v)
            r = radiances(out, col, umu, utau)
            vals = {(it + 1, im + 1, ip + 1): r[im, it] for it in range(len(utau)) for im in range(len(umu))
                    for ip in range(len(phi))}
            uu_key = 'UU'
        else:
            u = subroutines.interpolate(out[4], NT_cor='eval')
            vals = {(it + 1, im + 1, ip + 1): float(u(m, t, np.deg2rad(p))) for it, t in enumerate(utau)
                    for im, m in enumerate(umu) for ip, p in enumerate(phi)}
            uu_key = 'UU(interpolated)'
        umax = max((abs(v) for (p, c, q, *_), v in answers.items() if p == prob and c == case and q == 'UU'),
                   default=0.0)
        umax = max(umax, 1.0)
        du = [abs(v - answers[(prob, case, 'UU') + k]) / umax for k, v in vals.items()
              if (prob, case, 'UU') + k in answers]
        if du:
            diffs[uu_key] = max(du)
        print(f'  {prob}{case}: ' + ', '.join(f'{q} {d:.1e}' for q, d in sorted(diffs.items())))
    print(f'  largest flux difference: {worst_flux:.1e} of the largest flux')
    if worst_flux > 1.0e-4:
        sys.exit('validation failed: PythonicDISORT does not reproduce DISOTEST fluxes to 1e-4')


# -------------------------------------------------------------------------------------------
# Reference cases
# -------------------------------------------------------------------------------------------

BAND = (800.0, 1250.0)           # cm-1: the 8-12.5 um window
MU_OUT = (1.0, 0.5, 0.2)         # radiance directions (up at the top, down at the surface)


def reference_cases(c1_chi):
    """Cases in kumo's order: z (m) and level temperatures (K) from the surface up; per layer
    tau, ssa and the normalised Legendre moments chi (None without scattering); the phase
    function's name; surface temperature (K) and emissivity; the top radiance as the band
    Planck radiance of a temperature; stream numbers (coarse, fine)."""
    hg = np.array([0.85**l for l in range(1200)])   # HG g = 0.85 (chi_l = g^l; 0.85^1200 ~ 1e-85)
    iso = np.array([1.0])
    return [
        dict(name='thin_absorbing', z=[0.0, 1000.0], t=[290.0, 283.0], tau=[0.05], ssa=[0.0], chi=[iso],
             phase=['none'], t_sfc=295.0, eps=0.9, t_top=210.0, streams=(32, 64)),
        dict(name='thick_absorbing', z=[0.0, 500.0, 1000.0, 2000.0, 4000.0], t=[293.0, 290.0, 286.0, 278.0, 263.0],
             tau=[8.0, 4.0, 2.0, 1.0], ssa=[0.0] * 4, chi=[iso] * 4, phase=['none'] * 4, t_sfc=296.0, eps=0.95,
             t_top=215.0, streams=(32, 64)),
        dict(name='inversion', z=[0.0, 300.0, 600.0, 2000.0], t=[275.0, 281.0, 284.0, 276.0],
             tau=[0.5, 1.5, 0.3], ssa=[0.0] * 3, chi=[iso] * 3, phase=['none'] * 3, t_sfc=272.0, eps=0.97,
             t_top=200.0, streams=(32, 64)),
        dict(name='cloud_hg', z=[0.0, 500.0, 800.0, 2000.0], t=[290.0, 286.0, 284.0, 277.0],
             tau=[0.3, 10.0, 0.2], ssa=[0.0, 0.5, 0.0], chi=[iso, hg, iso], phase=['none', 'hg 0.85', 'none'],
             t_sfc=292.0, eps=0.9, t_top=210.0, streams=(128, 256)),
        dict(name='cloud_c1', z=[0.0, 500.0, 800.0, 2000.0], t=[290.0, 286.0, 284.0, 277.0],
             tau=[0.3, 10.0, 0.2], ssa=[0.0, 0.5, 0.0], chi=[iso, c1_chi, iso],
             phase=['none', 'legendre C.1', 'none'], t_sfc=292.0, eps=0.9, t_top=210.0, streams=(300, 400)),
        dict(name='haze_hg', z=[0.0, 1000.0], t=[288.0, 281.0], tau=[2.0], ssa=[0.9], chi=[hg],
             phase=['hg 0.85'], t_sfc=290.0, eps=0.8, t_top=220.0, streams=(128, 256)),
    ]


def solve_case(case, nquad):
    """Fluxes at levels 0..nz and radiances (up at the top, down at the surface) of a case."""
    nu1, nu2 = BAND
    b_level = [band_planck(nu1, nu2, t) for t in case['t']]
    b_sfc = band_planck(nu1, nu2, case['t_sfc'])
    i_top = band_planck(nu1, nu2, case['t_top'])
    out, tau_total = solve(case['tau'], case['ssa'], case['chi'], b_level, case['eps'], b_sfc, i_top, nquad)
    tau_cum = np.concatenate([[0.0], np.cumsum(case['tau'])])
    t_levels = tau_total - tau_cum                            # levels 0..nz seen from the top
    up, down, _ = fluxes_at(out, t_levels)
    i_sfc = case['eps'] * b_sfc + (1.0 - case['eps']) * down[0] / pi
    col = dict(tau_top=np.asarray(case['tau'], float)[::-1], ssa_top=case['ssa'][::-1], chi_top=case['chi'][::-1],
               b_top=b_level[::-1], i_top=i_top, surface=lambda m: i_sfc)
    rad_top = radiances(out, col, MU_OUT, [0.0])[:, 0]
    rad_sfc = radiances(out, col, [-m for m in MU_OUT], [tau_total])[:, 0]
    return dict(b_level=b_level, b_sfc=b_sfc, i_top=i_top, up=up, down=down, rad_top=rad_top, rad_sfc=rad_sfc)


def write_reference(path, cases):
    lines = [
        '# thermal_1d_reference.csv: fluxes and radiances of plane-parallel thermal-emission cases',
        '# computed by bench/thermal/make_thermal_reference.py with the discrete-ordinates solver',
        '# PythonicDISORT (Ho 2024, J. Open Source Softw. 9, 6442; checked by the script against DISORT',
        '# test problems 6 and 7 to 4e-6 of the largest flux). Radiances at the given mu come from',
        '# integrating the discrete-ordinates source function along the line of sight.',
        '#',
        '# Conventions (kumo): layers k = 1..nz from the surface up, levels i = 0..nz (0 = surface).',
        '# The Planck radiance is linear in optical depth inside each layer between its level values;',
        '# the emission of a layer is (1 - ssa) times that (Kirchhoff). The surface is Lambertian:',
        '# it emits emissivity * surface_planck and reflects 1 - emissivity of the incident flux.',
        '# top_radiance is an isotropic downward radiance at the top. No solar beam.',
        '# Band Planck values: Planck radiance integrated over [band_nu1, band_nu2] cm-1 with the',
        '# CODATA 2018 constants (adaptive quadrature, relative accuracy 1e-13).',
        '#',
        '# Columns: case,quantity,index,mu,value,solver_error',
        '#   inputs (index = level i or layer k, 0 for scalars; mu empty):',
        '#     nz, streams (number of discrete ordinates, both hemispheres), band_nu1_cm-1, band_nu2_cm-1,',
        '#     z_m (level), temperature_K (level), planck (level, W m-2 sr-1), tau (layer), ssa (layer),',
        '#     phase (layer, 0 = none, 1 = Henyey-Greenstein with g = value of hg_g, 2 = Legendre moments),',
        '#     hg_g (layer), nmom (layer: number of moments listed), chi_<k> (index = l: normalised',
        '#     Legendre moment chi_l of layer k, chi_0 = 1), surface_temperature_K, surface_emissivity,',
        '#     surface_planck (W m-2 sr-1), top_temperature_K (the top radiance is the band Planck value',
        '#     of it), top_radiance (W m-2 sr-1);',
        '#   results: flux_up, flux_down (level, W m-2, diffuse = total here), radiance (level, mu > 0',
        '#     upward at the top level nz, mu < 0 downward at the surface level 0, W m-2 sr-1).',
        '#   solver_error: |value with `streams` - value with `coarse_streams`| (the convergence of',
        '#     the discrete-ordinates solution in the number of streams), an estimate of the',
        '#     reference\'s own error.',
        'case,quantity,index,mu,value,solver_error',
    ]

    def row(name, q, i, v, mu='', err=''):
        e = f'{err:.3e}' if err != '' else ''
        m = f'{mu:.6g}' if mu != '' else ''
        lines.append(f'{name},{q},{i},{m},{v:.10e},{e}' if isinstance(v, float) else f'{name},{q},{i},{m},{v},{e}')

    for case, coarse, fine in cases:
        n = case['name']
        nz = len(case['tau'])
        row(n, 'nz', 0, nz)
        row(n, 'streams', 0, case['streams'][1])
        row(n, 'coarse_streams', 0, case['streams'][0])
        row(n, 'band_nu1_cm-1', 0, float(BAND[0]))
        row(n, 'band_nu2_cm-1', 0, float(BAND[1]))
        for i in range(nz + 1):
            row(n, 'z_m', i, float(case['z'][i]))
        for i in range(nz + 1):
            row(n, 'temperature_K', i, float(case['t'][i]))
        for i in range(nz + 1):
            row(n, 'planck', i, float(fine['b_level'][i]))
        for k in range(nz):
            row(n, 'tau', k + 1, float(case['tau'][k]))
        for k in range(nz):
            row(n, 'ssa', k + 1, float(case['ssa'][k]))
        for k in range(nz):
            kind = case['phase'][k]
            row(n, 'phase', k + 1, {'none': 0, 'hg 0.85': 1, 'legendre C.1': 2}[kind])
            if kind.startswith('hg'):
                row(n, 'hg_g', k + 1, float(kind.split()[1]))
            if kind.startswith('legendre'):
                chi = case['chi'][k]
                row(n, 'nmom', k + 1, len(chi))
                for l, c in enumerate(chi):
                    row(n, f'chi_{k + 1}', l, float(c))
        row(n, 'surface_temperature_K', 0, float(case['t_sfc']))
        row(n, 'surface_emissivity', 0, float(case['eps']))
        row(n, 'surface_planck', 0, float(fine['b_sfc']))
        row(n, 'top_temperature_K', 0, float(case['t_top']))
        row(n, 'top_radiance', 0, float(fine['i_top']))
        for i in range(nz + 1):
            row(n, 'flux_up', i, float(fine['up'][i]), err=float(abs(fine['up'][i] - coarse['up'][i])))
        for i in range(nz + 1):
            row(n, 'flux_down', i, float(fine['down'][i]), err=float(abs(fine['down'][i] - coarse['down'][i])))
        for j, m in enumerate(MU_OUT):
            row(n, 'radiance', nz, float(fine['rad_top'][j]), mu=m,
                err=float(abs(fine['rad_top'][j] - coarse['rad_top'][j])))
        for j, m in enumerate(MU_OUT):
            row(n, 'radiance', 0, float(fine['rad_sfc'][j]), mu=-m,
                err=float(abs(fine['rad_sfc'][j] - coarse['rad_sfc'][j])))
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, 'w') as f:
        f.write('\n'.join(lines) + '\n')


def read_c1(shared_dir):
    """The I3RC cloud C.1 Legendre moments chi_l, l = 0..299 (one per line; Garcia and Siewert
    1985, Table 17, divided by 2l + 1)."""
    return np.loadtxt(os.path.join(shared_dir, 'data', 'i3rc', 'phase1_inputs', 'C.1_leg_coef'))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--shared-dir', default=os.environ.get('KUMO_SHARED_DIR', '../shared'))
    parser.add_argument('--validate-only', action='store_true')
    parser.add_argument('--output', default=os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..',
                                                         'tests', 'data', 'thermal', 'thermal_1d_reference.csv'))
    args = parser.parse_args()
    validate(args.shared_dir)
    if args.validate_only:
        return
    results = []
    for case in reference_cases(read_c1(args.shared_dir)):
        coarse, fine = (solve_case(case, n) for n in case['streams'])
        rel = max(np.max(np.abs(fine['up'] - coarse['up']) / fine['up']),
                  np.max(np.abs(fine['down'] - coarse['down']) / np.maximum(fine['down'], 1e-300)))
        rrel = max(np.max(np.abs(fine['rad_top'] - coarse['rad_top']) / fine['rad_top']),
                   np.max(np.abs(fine['rad_sfc'] - coarse['rad_sfc']) / fine['rad_sfc']))
        print(f"{case['name']:16s} streams {case['streams']}: flux change {rel:.1e}, "
              f"radiance change {rrel:.1e}", flush=True)
        results.append((case, coarse, fine))
    write_reference(args.output, results)
    print('wrote', os.path.relpath(args.output))


if __name__ == '__main__':
    main()
