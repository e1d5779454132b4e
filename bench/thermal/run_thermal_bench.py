#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Thermal benchmarks of kumo: longwave cooling rates of two LES clouds (docs/performance.md,
section "Thermal emission: cooling rates of LES clouds").

  python3 bench/thermal/run_thermal_bench.py stcu  [--photons N] [--batches B]
  python3 bench/thermal/run_thermal_bench.py les05 --mcarats-dir DIR [--photons N] [--batches B]

stcu:  the I3RC LES stratocumulus (examples/data/i3rc_les/i3rc_les_stcu.lwc) in the window band
       900-960 cm-1 (droplet optics at 10.7 um), voxel temperatures from the LWC file's profile,
       a gray gas for the water-vapour continuum (see GAS_STCU), black-body surface at 288 K.
les05: the MCARaTS LES05 scene at 11 um (les05_1100.atm/.sca and the 1-D profiles of its
       namelist conf_hr1100), voxel temperatures t_levels + tmpa3d; DIR (or the environment
       variable KUMO_MCARATS_DIR) is the folder of those files.

Each runs kumo once (nice -n 5), measures its CPU time (of the child process), reads the output
and prints: the domain-mean cooling-rate profile with its standard error, the per-voxel
relative errors, time per photon, and the CPU time to reach a target error from the 1/sqrt(N)
scaling of the standard error. With --plot, PNG figures go to the run folder.
Environment: KUMO (default build/kumo), KUMO_RUN_DIR (default bench/thermal/run/).
"""
import argparse
import os
import pathlib
import resource
import subprocess
import sys

import numpy as np
from netCDF4 import Dataset

REPO = pathlib.Path(__file__).resolve().parents[2]

# The window-band gas of the stratocumulus: a gray absorber for the water-vapour continuum,
# whose absorption coefficient near 11 um in a moist boundary layer is of the order of 1e-4 m-1
# (the LES05 profile of MCARaTS at 11 um, conf_hr1100 Atm_abs1d: 1.6e-4 m-1 at the ground,
# 1.0e-4 m-1 at 500 m, 3.7e-5 m-1 at 2 km): 1.5e-4 m-1 up to the inversion, then decreasing.
GAS_STCU = {'below_cloud': 1.5e-4, 'cloud': 1.5e-4, 'to_1500': 1.0e-4, 'to_3000': 4.0e-5,
            'to_10000': 5.0e-6}


def run_kumo(nml_path, log_path):
    kumo = os.path.abspath(os.environ.get('KUMO', str(REPO / 'build' / 'kumo')))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with open(log_path, 'w') as log:
        subprocess.run(['nice', '-n', '5', kumo, str(nml_path)], check=True, stdout=log,
                       stderr=subprocess.STDOUT, cwd=nml_path.parent)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def fmt_list(values, per_line=8, f='{:.6g}'):
    items = [f.format(v) for v in values]
    return ',\n  '.join(', '.join(items[i:i + per_line]) for i in range(0, len(items), per_line))


def us1976_density(z_edges):
    """Layer air density (p_bottom - p_top)/(g0 dz) of the US 1976 atmosphere below 11 km."""
    zm = np.asarray(z_edges, float)
    h = 6356766.0 * zm / (6356766.0 + zm)
    p = 101325.0 * (1.0 - 0.0065 * h / 288.15) ** 5.255877
    return (p[:-1] - p[1:]) / (9.80665 * np.diff(zm))


def stcu_case(run_dir, photons, batches):
    lwc = REPO / 'examples' / 'data' / 'i3rc_les' / 'i3rc_les_stcu.lwc'
    lines = lwc.read_text().splitlines()
    z_file = [1000.0 * float(v) for v in lines[3].split()]
    t_file = [float(v) for v in lines[4].split()]
    # levels: the ground, the file's 17 edges, then 1.5, 3 and 10 km
    z = [0.0] + z_file + [1500.0, 3000.0, 10000.0]
    # temperatures: 288 K at the ground (dry adiabat to the cloud base), the file's profile,
    # then 6.5 K/km above the inversion top
    t_top_file = t_file[-1]
    t = [288.0] + t_file + [t_top_file - 6.5e-3 * (zz - z_file[-1]) for zz in z[-3:]]
    nz = len(z) - 1
    gas = []
    for k in range(nz):
        ztop = z[k + 1]
        if ztop <= z_file[-1]:
            gas.append(GAS_STCU['cloud'])
        elif ztop <= 1500.0:
            gas.append(GAS_STCU['to_1500'])
        elif ztop <= 3000.0:
            gas.append(GAS_STCU['to_3000'])
        else:
            gas.append(GAS_STCU['to_10000'])
    rho = us1976_density(z)
    nml = f"""! I3RC LES stratocumulus, thermal window band 900-960 cm-1 (bench/thermal/run_thermal_bench.py)
&kumo_control n_photons_per_batch = {photons}, n_batches = {batches}, seed = 1 /
&kumo_atmosphere nz = {nz}, z_levels = {fmt_list(z)},
  n_components = 1, ext1d(:,1) = {fmt_list(gas)},
  ssa1d(:,1) = {nz}*0.0, phase1d(:,1) = {nz}*1,
  air_density = {fmt_list(rho)} /
&kumo_cloud cloud_file = '{lwc}', cloud_format = 'lwc', size_distribution = 'gamma', v_eff = 0.1,
  reff_min_um = 2.0, reff_max_um = 30.0, n_reff = 30, mie_cache = 'mie_107.nc' /
&kumo_source wavelength_um = 10.7 /
&kumo_surface albedo = 0.0 /
&kumo_thermal t_levels = {fmt_list(t, f='{:.2f}')}, t_surface = 288.0, t_top = 0.0,
  wavenumber_lo = 900.0, wavenumber_hi = 960.0 /
&kumo_output file = 'stcu_thermal.nc' /
"""
    path = run_dir / 'stcu_thermal.nml'
    path.write_text(nml)
    return path, 'stcu_thermal.nc', (2, 2 + 16)


def les05_case(run_dir, photons, batches, mdir):
    conf = (mdir / 'conf_hr1100').read_text()

    def values(name):
        start = conf.index(name)
        text = conf[start:].split('=', 1)[1]
        out = []
        for line in text.splitlines():
            line = line.split('!')[0].strip()
            if not line:
                if out:
                    break
                continue
            if line.startswith('Atm_') or line.startswith('/'):
                break
            out += [float(v) for v in line.replace(',', ' ').split()]
        return out
    z = values('Atm_zgrd0')
    tmp = values('Atm_tmp1d')
    ext_mol = values('Atm_ext1d(1:, 1)')
    abs_gas = values('Atm_abs1d(1: 41,1)')
    nz = len(z) - 1
    assert len(tmp) == nz + 1 and len(ext_mol) == nz and len(abs_gas) == nz
    # US 1976 pressure: troposphere, the isothermal 11-20 km layer, the 20-32 km gradient
    def p76(zz):
        h = 6356766.0 * zz / (6356766.0 + zz)
        if h <= 11000.0:
            return 101325.0 * (1.0 - 0.0065 * h / 288.15) ** 5.255877
        p11 = 22632.06
        if h <= 20000.0:
            return p11 * np.exp(-9.80665 * 0.0289644 * (h - 11000.0) / (8.3144598 * 216.65))
        p20 = 5474.889
        return p20 * (1.0 + 0.001 * (h - 20000.0) / 216.65) ** (-34.1632)
    p = [p76(zz) for zz in z]
    rho = [(p[k] - p[k + 1]) / (9.80665 * (z[k + 1] - z[k])) for k in range(nz)]
    atm = mdir / 'les05_1100.atm.ctl'
    sca = mdir / 'les05_1100.sca.ctl'
    nml = f"""! MCARaTS LES05 at 11 um (conf_hr1100), thermal (bench/thermal/run_thermal_bench.py)
&kumo_control n_photons_per_batch = {photons}, n_batches = {batches}, seed = 1 /
&kumo_atmosphere nz = {nz}, z_levels = {fmt_list(z)},
  k3d_bottom = 10, lx = 1800.0, ly = 1800.0, n_components = 2,
  ext1d(:,1) = {fmt_list(ext_mol)}, phase1d(:,1) = {nz}*1,
  ext1d(:,2) = {fmt_list(abs_gas)}, ssa1d(:,2) = {nz}*0.0, phase1d(:,2) = {nz}*1,
  air_density = {fmt_list(rho)} /
&kumo_phase n_phase = 1, phase_kind = 'rayleigh' /
&kumo_cloud cloud_file = '{atm}', cloud_format = 'mcarats', mcarats_phase_file = '{sca}' /
&kumo_source wavelength_um = 11.0 /
&kumo_surface albedo = 0.0 /
&kumo_thermal t_levels = {fmt_list(tmp, f='{:.4f}')}, t_surface = 288.62, t_top = 0.0 /
&kumo_output file = 'les05_thermal.nc' /
"""
    path = run_dir / 'les05_thermal.nml'
    path.write_text(nml)
    return path, 'les05_thermal.nc', (10, 10 + 21)


def analyse(out, cpu, setup, photons, batches, k_range, target_kday, plot, tag):
    """Print the profile and the error figures. `cpu` is the CPU time of the run, `setup` that
    of a run of 100 photons (reading, optics, tables); the photon loop takes cpu - setup, and
    every time-to-error below is setup + loop time scaled by (error now/target)^2."""
    ds = Dataset(out)
    hr = np.array(ds['heating_rate_layer'][:], float)
    hr_e = np.array(ds['heating_rate_layer_stderr'][:], float)
    z = None
    for name in ('z_levels', 'level', 'z'):
        if name in ds.variables:
            z = np.array(ds[name][:], float)
            break
    hv = np.array(ds['heating_rate_voxel'][:], float)
    hv_e = np.array(ds['heating_rate_voxel_stderr'][:], float)
    n = photons * batches
    loop = max(cpu - setup, 1e-9)
    print(f'# {tag}: {n:.3g} photons, CPU {cpu:.1f} s (set-up {setup:.1f} s, photons {loop:.1f} s),'
          f' {n / loop:.4g} photons per CPU-s, {1e6 * loop / n:.3g} us per photon')
    print(f'# source_power {float(ds["source_power"][:].ravel()[0]):.6g} W m-2')
    print('layer  heating rate [K/day]  stderr   (3-D layers marked *)')
    lo, hi = k_range
    for k in range(len(hr)):
        mark = '*' if lo <= k + 1 < hi else ' '
        print(f'{k + 1:4d}{mark} {hr[k]:12.4f} {hr_e[k]:10.4f}')
    region = slice(lo - 1, hi - 1)
    worst = np.max(hr_e[region])
    t_target = setup + loop * (worst / target_kday) ** 2
    print(f'largest stderr of a 3-D layer {worst:.4g} K/day: CPU time to {target_kday} K/day '
          f'on every 3-D layer {t_target:.3g} s')
    peak = np.max(np.abs(hr[region]))
    t_peak = setup + loop * (worst / (0.01 * peak)) ** 2
    print(f'largest cooling rate {peak:.4g} K/day: CPU time to 1 % of it on every 3-D layer '
          f'{t_peak:.3g} s')
    strong = np.abs(hr[region]) > 0.1 * peak
    rel = np.abs(hr_e[region][strong] / hr[region][strong])
    t_1pc = setup + loop * (np.max(rel) / 0.01) ** 2
    print(f'{np.count_nonzero(strong)} 3-D layers cool by more than 10 % of it: largest '
          f'relative stderr {np.max(rel):.4g}, CPU time to 1 % on each {t_1pc:.3g} s')
    nz3 = hv.shape[0]
    print(f'voxels: {hv.size} ({nz3} layers)')
    for label, sel in (('all voxels with a heating rate', np.abs(hv) > 0),
                       ('voxels with |heating rate| > 1 K/day', np.abs(hv) > 1.0)):
        relv = np.abs(hv_e[sel] / hv[sel])
        if relv.size == 0:
            continue
        med = np.median(relv)
        print(f'  {label} ({relv.size}): median relative stderr {med:.4g} after {cpu:.1f} '
              f'CPU-s; {med * np.sqrt(loop / 60.0):.4g} after 60 CPU-s of photons')
    if plot:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(1, 3, figsize=(13, 4))
        kk = np.arange(lo, hi)
        ax[0].errorbar(hr[region], kk, xerr=hr_e[region], fmt='o-', ms=3)
        ax[0].set_xlabel('domain-mean heating rate [K/day]')
        ax[0].set_ylabel('layer')
        # voxel maps: arrays (z, y, x) in ncdump order
        kmin = int(np.argmin(hr[region]))
        im = ax[1].imshow(hv[kmin], origin='lower', cmap='RdBu', vmin=-np.max(np.abs(hv[kmin])),
                          vmax=np.max(np.abs(hv[kmin])))
        ax[1].set_title(f'heating rate, layer {lo + kmin} [K/day]')
        fig.colorbar(im, ax=ax[1])
        im = ax[2].imshow(hv_e[kmin], origin='lower')
        ax[2].set_title('its standard error [K/day]')
        fig.colorbar(im, ax=ax[2])
        fig.tight_layout()
        fig.savefig(out.with_suffix('.png'), dpi=80)
        print('figure', os.path.relpath(out.with_suffix('.png'), REPO))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('case', choices=['stcu', 'les05'])
    ap.add_argument('--photons', type=int, default=20000)
    ap.add_argument('--batches', type=int, default=20)
    ap.add_argument('--mcarats-dir', default=os.environ.get('KUMO_MCARATS_DIR', ''))
    ap.add_argument('--plot', action='store_true')
    a = ap.parse_args()
    run_dir = pathlib.Path(os.environ.get('KUMO_RUN_DIR', REPO / 'bench' / 'thermal' / 'run'))
    run_dir.mkdir(parents=True, exist_ok=True)
    if a.case == 'stcu':
        nml, out, k_range = stcu_case(run_dir, a.photons, a.batches)
        target = 0.1
    else:
        if not a.mcarats_dir:
            sys.exit('les05: give --mcarats-dir DIR or KUMO_MCARATS_DIR (folder of les05_1100.* '
                     'and conf_hr1100)')
        nml, out, k_range = les05_case(run_dir, a.photons, a.batches, pathlib.Path(a.mcarats_dir))
        target = 0.1
    # the set-up cost (files, optics, tables): the same run with 100 photons
    text = nml.read_text()
    small = nml.with_name(nml.stem + '_setup.nml')
    small.write_text(text.replace(f'n_photons_per_batch = {a.photons}, n_batches = {a.batches}',
                                  'n_photons_per_batch = 50, n_batches = 2')
                     .replace(f"file = '{out}'", f"file = 'setup_{out}'"))
    setup = run_kumo(small, run_dir / (small.stem + '.log'))
    cpu = run_kumo(nml, run_dir / (nml.stem + '.log'))
    analyse(run_dir / out, cpu, setup, a.photons, a.batches, k_range, target, a.plot, a.case)


if __name__ == '__main__':
    main()
