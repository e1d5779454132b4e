#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Convert the I3RC LES stratocumulus at 2.13 um (a tabulated phase function property file)
into a kumo case: scene file, phase function tables and namelist.

Input: `les_stcu_w213.prp` (64 x 64 columns of 0.055 km, from the I3RC community Monte Carlo
model, Tools/Examples) and, optionally, the molecular absorption profile `molec_abs_w213.dat`.

Property file format ("T" = tabulated phase functions; SHDOM's format and the I3RC community
model's variant of it, read by its Tools/OpticalPropertiesToDomain.f95):
    T...                                  (a header line starting with T)
    NX NY NZ
    DELX DELY Z(1) ... Z(NZ) or Z(NZ+1)   (km)
    NUMPHASE
    NLEG CHI(1) ... CHI(NLEG)             (one per phase function; may run over several lines)
    IX IY IZ TEMP EXTINCT ALBEDO IPHASE   (one per grid point or cell; TEMP is not used)
* The Legendre coefficients start at l = 1 and include the factor 2l + 1: CHI(l) = (2l+1) chi_l
  with chi_0 = 1 not listed, so CHI(1) = 3 g (Henyey-Greenstein: CHI(l) = (2l+1) g^l). NLEG = 0 is
  the isotropic function; `2  0.0 0.5` is Rayleigh.
* EXTINCT is in the inverse of the grid spacing unit, km-1; ALBEDO is the single-scattering albedo;
  IPHASE (1..NUMPHASE) selects a phase function of the header.
* Vertical grid: with NZ + 1 heights (the I3RC variant; les_stcu_w213.prp has 18 cells and 19
  heights 0, 0.425, 0.45, ..., 0.825, 1.0 km) the values are CELL values: cell IZ lies between
  Z(IZ) and Z(IZ+1), and becomes kumo layer IZ unchanged. With NZ heights (SHDOM proper, e.g.
  les2y21w16.prp) the values live on GRID POINTS and SHDOM interpolates linearly between them:
  the kumo layer between heights Z(k) and Z(k+1) gets the mean of the two planes' extinction
  (exact column optical depth of the linear profile), the scattering-weighted mean albedo and the
  phase function of the plane with the larger scattering coefficient (tables are not blended).
  Horizontally each value is the value of its column, x column IX covers [(IX-1) DELX, IX DELX).
* kumo levels: the heights of the file, in metres, preceded by a clear layer from the ground if
  the lowest height is above 0. Layers whose extinction is 0 everywhere at the bottom and the top
  stay 1-D layers; the 3-D region is the rest (for les_stcu_w213.prp: layers 2..17, 0.425 -
  0.825 km, nz3 = 16, k3d_bottom = 2). Where the extinction is 0 the phase index is set to 1.

Phase functions: each one is summed from its Legendre series, P(mu) = 1 + sum_l CHI(l) P_l(mu)
(kumo's normalisation, (1/2) Int P dmu = 1), on scattering angles in steps of `--fine-step`
(0.1 deg) below `--fine-limit` (10 deg, forward peak) and above `--back-limit` (170 deg, glory),
of `--mid-step` (0.25 deg) up to `--mid-limit` (30 deg) and of `--coarse-step` (0.5 deg) between
(561 angles; kumo's log-linear interpolation of the table then stays within 0.25 % of the series
for les_stcu_w213.prp), and written as a two-column table `angle_deg  P` (kumo phase_kind =
'table'). Values that are negative by round-off of the truncated series would be set to a small
positive value and counted (les_stcu_w213.prp has none). NLEG = 0 becomes phase_kind =
'isotropic' (no file). The kumo phase function list keeps the order of the file, so
phase_index = IPHASE.

Molecular absorption (`molec_abs_w213.dat`, the I3RC community model's molecular absorption
file: NZ / Zlevels(1:NZ+1) in km / absorption coefficient in km-1 of each of the NZ cells) is
added as the 1-D component 1 (ssa1d = 0) of every kumo layer: each layer gets the
thickness-weighted mean of the piecewise constant profile, so the column absorption optical depth
is kept. Its levels need not match the property file's. `--no-molecules` leaves it out.

Outputs in `--out-dir`: NAME.nc (scene, extinction in km-1), NAME_phase/pfNN.txt (tables), and
the namelist NAME.nml (or `--nml FILE`), whose file names are relative to the namelist's folder.
The namelist sets the sun (`--sza`, `--phi0`), a black surface, `--batches` x `--photons` and
requests upward nadir radiances at the top level (&kumo_radiance) with vr_preset = 'standard'.

Usage:
  python3 bench/make_les_scene.py --out-dir bench/les
      [--prp FILE] [--molec FILE | --no-molecules] [--name les_stcu_w213] [--nml FILE]
      [--sza 60] [--phi0 0] [--batches 20] [--photons 100000]
      [--fine-limit 10] [--fine-step 0.1] [--mid-limit 30] [--mid-step 0.25] [--coarse-step 0.5]
      [--back-limit 170]
The input files default to $KUMO_SHARED_DIR/data/i3rc/les_examples/les_stcu_w213.prp and
molec_abs_w213.dat (KUMO_SHARED_DIR defaults to the folder `shared` next to the repository).
"""
import argparse
import os
import sys

import numpy as np
from numpy.polynomial import legendre

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                'python', 'src'))   # the kumo package of this tree
import kumo  # noqa: E402

NEG_TOL = 1.0e-4      # |P| below this (P averages 1 over the sphere) counts as round-off
P_FLOOR = 1.0e-6      # value given to such (tiny negative) entries


def die(msg):
    sys.exit(f'make_les_scene: {msg}')


def default_data_dir():
    shared = os.environ.get('KUMO_SHARED_DIR')
    if not shared:
        repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        shared = os.path.join(os.path.dirname(repo), 'shared')
    return os.path.join(shared, 'data', 'i3rc', 'les_examples')


# ------------------------------------------------------------------------------------------------
# Property file
# ------------------------------------------------------------------------------------------------
def read_prp(path):
    """Read a tabulated phase function property file (see the module docstring)."""
    with open(path) as f:
        lines = f.read().splitlines()
    if len(lines) < 5 or not lines[0].lstrip().startswith('T'):
        die(f'{path}: not a tabulated phase function property file (first line must start '
            'with T)')
    try:
        nx, ny, nz = (int(v) for v in lines[1].split()[:3])
        hdr = [float(v) for v in lines[2].split()]
    except ValueError:
        die(f'{path}: cannot read the grid size and spacing lines')
    dx, dy, heights = hdr[0], hdr[1], np.array(hdr[2:])
    if len(heights) == nz + 1:
        kind = 'cells'
    elif len(heights) == nz:
        kind = 'points'
    else:
        die(f'{path}: {len(heights)} heights for NZ = {nz}: expected NZ (grid points) or '
            'NZ + 1 (cell boundaries)')
    if min(nx, ny, nz) < 1 or dx <= 0 or dy <= 0 or np.any(np.diff(heights) <= 0) \
            or heights[0] < 0:
        die(f'{path}: bad grid: sizes {nx} {ny} {nz}, spacing {dx} {dy}, heights must be '
            '>= 0 and strictly increasing')
    tok = ' '.join(lines[3:]).split()
    p = 0
    nphase = int(tok[p]); p += 1
    chis = []
    for i in range(nphase):
        nleg = int(tok[p]); p += 1
        chis.append(np.array(tok[p:p + nleg], dtype=float)); p += nleg
        if len(chis[-1]) != nleg:
            die(f'{path}: phase function {i + 1} is cut short')
    rest = np.array(tok[p:], dtype=float)
    if rest.size % 7:
        die(f'{path}: the property lines do not have 7 values each')
    rest = rest.reshape(-1, 7)
    ix, iy, iz = (rest[:, c].astype(int) for c in range(3))
    ip = rest[:, 6].astype(int)
    if ix.min() < 1 or ix.max() > nx or iy.min() < 1 or iy.max() > ny or iz.min() < 1 \
            or iz.max() > nz or ip.min() < 1 or ip.max() > nphase:
        die(f'{path}: grid or phase function index out of range')
    ext = np.zeros((nz, ny, nx)); ssa = np.zeros((nz, ny, nx))
    iph = np.ones((nz, ny, nx), dtype=np.int32)
    seen = np.zeros((nz, ny, nx), dtype=bool)
    ext[iz - 1, iy - 1, ix - 1] = rest[:, 4]
    ssa[iz - 1, iy - 1, ix - 1] = rest[:, 5]
    iph[iz - 1, iy - 1, ix - 1] = ip
    seen[iz - 1, iy - 1, ix - 1] = True
    if len(rest) != nx * ny * nz or not seen.all():
        die(f'{path}: {len(rest)} property lines cover {seen.sum()} of {nx * ny * nz} '
            'grid points (duplicates or gaps)')
    if ext.min() < 0 or ssa.min() < 0 or ssa.max() > 1:
        die(f'{path}: extinction < 0 or albedo outside [0, 1]')
    return dict(nx=nx, ny=ny, nz=nz, dx=dx, dy=dy, heights=heights, kind=kind, chis=chis,
                ext=ext, ssa=ssa, iph=iph)


def to_layers(prp):
    """Levels [km] and layer properties (nl, ny, nx) from cell or grid-point values."""
    z, ext, ssa, iph = prp['heights'], prp['ext'], prp['ssa'], prp['iph']
    if prp['kind'] == 'points':
        sca = ext * ssa
        e = 0.5 * (ext[:-1] + ext[1:])
        s = 0.5 * (sca[:-1] + sca[1:])
        ssa = np.where(e > 0, s / np.where(e > 0, e, 1.0), 0.0).clip(0.0, 1.0)
        iph = np.where(sca[1:] > sca[:-1], iph[1:], iph[:-1])
        ext = e
    iph = np.where(ext > 0, iph, 1).astype(np.int32)
    if z[0] > 0:   # clear layer from the ground to the lowest height of the file
        z = np.concatenate(([0.0], z))
        ext = np.concatenate((np.zeros_like(ext[:1]), ext))
        ssa = np.concatenate((np.zeros_like(ssa[:1]), ssa))
        iph = np.concatenate((np.ones_like(iph[:1]), iph))
    return z, ext, ssa, iph


# ------------------------------------------------------------------------------------------------
# Phase functions
# ------------------------------------------------------------------------------------------------
def angle_grid(a):
    parts = [np.arange(0.0, a.fine_limit, a.fine_step),
             np.arange(a.fine_limit, a.mid_limit, a.mid_step),
             np.arange(a.mid_limit, a.back_limit, a.coarse_step),
             np.arange(a.back_limit, 180.0, a.fine_step), [180.0]]
    return np.unique(np.round(np.concatenate(parts), 9))


def series(chi, mu):
    """P(mu) = 1 + sum_l CHI(l) P_l(mu), CHI as listed in the file (l = 1..NLEG)."""
    return legendre.legval(mu, np.concatenate(([1.0], chi)))


def table_moments(theta_deg, p, sub=40):
    """(1/2) Int P dmu and g of the table under kumo's interpolation (linear in log P)."""
    t = np.radians(theta_deg)
    f = np.linspace(0.0, 1.0, sub + 1)[:-1] + 0.5 / sub             # midpoints in each interval
    tt = t[:-1, None] + f[None] * np.diff(t)[:, None]
    lp = np.log(np.maximum(p, 1e-300))
    pp = np.exp(lp[:-1, None] + f[None] * np.diff(lp)[:, None])
    w = np.sin(tt) * (np.diff(t)[:, None] / sub)
    norm = 0.5 * np.sum(pp * w)
    return norm, 0.5 * np.sum(pp * np.cos(tt) * w) / norm, (tt, pp)


def make_tables(chis, theta, out_dir, tag, src_name):
    """Write one table per phase function with NLEG > 0; return kinds, files and a report."""
    mu = np.cos(np.radians(theta))
    os.makedirs(out_dir, exist_ok=True)
    kinds, files, rows = [], [], []
    for i, chi in enumerate(chis, start=1):
        if len(chi) == 0:
            kinds.append('isotropic'); files.append(None)
            rows.append((i, 0, 0.0, 0.0, 1.0, 1.0, 0, 1.0, 0.0)); continue
        p = series(chi, mu)
        neg, pmin = p < 0, p.min()
        if np.any(p < -NEG_TOL):
            die(f'phase function {i}: value {p.min():.3e} < -{NEG_TOL} (series not usable)')
        p = np.where(p < P_FLOOR, P_FLOOR, p)
        g = chi[0] / 3.0
        norm, g_tab, (tt, pp) = table_moments(theta, p)
        # accuracy of the table against the series between the nodes
        exact = series(chi, np.cos(tt))
        rel = np.abs(pp - exact) / np.maximum(np.abs(exact), 1e-3)
        name = f'pf{i:02d}.txt'
        with open(os.path.join(out_dir, name), 'w') as f:
            f.write(f'# phase function {i} of {src_name}: Legendre series of {len(chi)} terms\n'
                    f'# g = CHI(1)/3 = {g:.6f}; {int(neg.sum())} negative values set to '
                    f'{P_FLOOR:g}\n# angle_deg  P   (normalised: (1/2) Int P dmu = 1)\n')
            for a, v in zip(theta, p):
                f.write(f'{a:9.4f}  {v:.7e}\n')
        kinds.append('table'); files.append(os.path.join(tag, name))
        rows.append((i, len(chi), g, g_tab, norm, p.max(), int(neg.sum()), pmin, rel.max()))
    return kinds, files, rows


# ------------------------------------------------------------------------------------------------
# Molecular absorption
# ------------------------------------------------------------------------------------------------
def read_molec(path):
    tok = open(path).read().split()
    try:
        n = int(tok[0])
        zl = np.array(tok[1:n + 2], dtype=float)
        k = np.array(tok[n + 2:2 * n + 2], dtype=float)
    except (ValueError, IndexError):
        die(f'{path}: cannot read NZ / Zlevels(NZ+1) / absorption(NZ)')
    if len(tok) != 2 * n + 2 or len(zl) != n + 1 or len(k) != n or np.any(np.diff(zl) <= 0) \
            or np.any(k < 0):
        die(f'{path}: expected NZ, NZ+1 increasing levels [km] and NZ values >= 0 [km-1]')
    return zl, k


def layer_means(zl, k, z):
    """Thickness-weighted mean over the layers [z(i), z(i+1)] of the cell profile (zl, k)."""
    lo = np.maximum(z[:-1, None], zl[None, :-1])
    hi = np.minimum(z[1:, None], zl[None, 1:])
    return (np.clip(hi - lo, 0.0, None) * k[None]).sum(axis=1) / np.diff(z)


# ------------------------------------------------------------------------------------------------
# Output
# ------------------------------------------------------------------------------------------------
def write_scene(path, ext, ssa, iph, dx_m, dy_m, z3_m, src_name):
    """The scene file (kumo.write_scene, extinction in km-1) with coordinates x, y, z [m]."""
    from netCDF4 import Dataset
    nz3, ny, nx = ext.shape
    tmp = path + '.tmp'
    kumo.write_scene(tmp, ext, ssa, iph, ext_units='km-1')
    with Dataset(tmp, 'a') as nc:
        nc.title = 'I3RC LES stratocumulus at 2.13 um as a kumo scene'
        nc.source = f'bench/make_les_scene.py from {src_name}'
        for name, vals, ln in (('x', (np.arange(nx) + 0.5) * dx_m, 'column centre along x'),
                               ('y', (np.arange(ny) + 0.5) * dy_m, 'column centre along y'),
                               ('z', 0.5 * (z3_m[:-1] + z3_m[1:]), 'layer mid-height')):
            v = nc.createVariable(name, 'f8', (name,))
            v.units, v.long_name = 'm', ln
            v[:] = vals
    os.replace(tmp, path)


def fmt(x):
    s = f'{x:.10g}'
    return s if any(c in s for c in '.en') else s + '.0'


def num(x, spec='.10g'):
    """x rounded to the digits the namelist keeps."""
    return float(format(x, spec))


NAMELIST_HEADER = """! kumo case: I3RC LES stratocumulus at 2.13 um (les_stcu_w213.prp).
! Generated by bench/make_les_scene.py (see its docstring for the format and the
! mapping); file names are relative to the folder of this namelist.
! kumo_atmosphere: component 1 is the molecular absorption [m-1] (molec_abs_w213.dat), no
! scattering (left out with --no-molecules).
! kumo_radiance: rad_mu is the cosine of the propagation direction: 1 = upward nadir radiance
! (what a downward-looking sensor sees).
"""


def namelist(a, z_m, lx, ly, nx, ny, k3d, nz3, scene_rel, kinds, files, mol_ext_m):
    """The case's namelist groups (kumo.write_namelist)."""
    nz = len(z_m) - 1
    atm = {'nz': nz, 'z_levels': [num(z) for z in z_m], 'lx': num(lx), 'ly': num(ly),
           'n_components': 1}
    if mol_ext_m is not None:
        atm['ext1d'] = np.array([[num(e, '.6e')] for e in mol_ext_m])
        atm['ssa1d'] = np.zeros((nz, 1))
    atm.update(scene_file=scene_rel, k3d_bottom=k3d, nx=nx, ny=ny, nz3=nz3, n_components_3d=1)
    phase = {'n_phase': len(kinds), 'phase_kind': list(kinds)}
    if any(files):
        phase['phase_file'] = list(files)
    return {
        'control': {'n_photons_per_batch': a.photons, 'n_batches': a.batches, 'seed': 1},
        'atmosphere': atm,
        'phase': phase,
        'surface': {'albedo': 0.0},
        'source': {'sza_deg': num(a.sza), 'phi0_deg': num(a.phi0)},
        'output': {'file': f'{a.name}_out.nc'},
        'radiance': {'rad_mu': 1.0, 'rad_phi_deg': 0.0, 'rad_levels': nz,
                     'radiance_maps': True},
        'vr': {'vr_preset': 'standard'},
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--prp', default=None, help='property file (default: shared data)')
    ap.add_argument('--molec', default=None, help='molecular absorption file (default: shared)')
    ap.add_argument('--no-molecules', action='store_true', help='leave molecular absorption out')
    ap.add_argument('--out-dir', required=True, help='folder for the scene, tables and namelist')
    ap.add_argument('--name', default='les_stcu_w213', help='case name (file name stem)')
    ap.add_argument('--nml', default=None, help='namelist to write (default OUT_DIR/NAME.nml)')
    ap.add_argument('--sza', type=float, default=60.0, help='solar zenith angle [deg]')
    ap.add_argument('--phi0', type=float, default=0.0, help='beam propagation azimuth [deg]')
    ap.add_argument('--batches', type=int, default=20)
    ap.add_argument('--photons', type=int, default=100000, help='photons per batch')
    ap.add_argument('--fine-limit', type=float, default=10.0)
    ap.add_argument('--fine-step', type=float, default=0.1)
    ap.add_argument('--mid-limit', type=float, default=30.0)
    ap.add_argument('--mid-step', type=float, default=0.25)
    ap.add_argument('--coarse-step', type=float, default=0.5)
    ap.add_argument('--back-limit', type=float, default=170.0,
                    help='fine steps again from here to 180 deg (glory)')
    a = ap.parse_args()
    if not (0 < a.fine_limit <= a.mid_limit <= a.back_limit <= 180
            and min(a.fine_step, a.mid_step, a.coarse_step) > 0):
        die('need 0 < fine-limit <= mid-limit <= back-limit <= 180 and positive steps')
    data = default_data_dir()
    prp_path = a.prp or os.path.join(data, 'les_stcu_w213.prp')
    prp = read_prp(prp_path)
    src_name = os.path.basename(prp_path)
    if len(prp['chis']) > 64:
        die(f"{len(prp['chis'])} phase functions: kumo takes at most 64")

    z_km, ext, ssa, iph = to_layers(prp)
    nl = len(z_km) - 1
    cloudy = np.flatnonzero(ext.max(axis=(1, 2)) > 0)
    if cloudy.size == 0:
        die('no extinction anywhere')
    k0, k1 = cloudy[0], cloudy[-1]            # 0-based first and last layers of the 3-D region
    ext3, ssa3, iph3 = ext[k0:k1 + 1], ssa[k0:k1 + 1], iph[k0:k1 + 1]
    nz3, ny, nx = ext3.shape
    z_m = np.round(z_km * 1000.0, 6)
    lx, ly = round(nx * prp['dx'] * 1000.0, 6), round(ny * prp['dy'] * 1000.0, 6)

    os.makedirs(a.out_dir, exist_ok=True)
    nml_path = a.nml or os.path.join(a.out_dir, a.name + '.nml')
    nml_dir = os.path.dirname(os.path.abspath(nml_path))
    scene_path = os.path.join(a.out_dir, a.name + '.nc')
    tab_dir = os.path.join(a.out_dir, a.name + '_phase')
    tab_rel = os.path.relpath(os.path.abspath(tab_dir), nml_dir)
    write_scene(scene_path, ext3, ssa3, iph3, prp['dx'] * 1000.0, prp['dy'] * 1000.0,
                z_m[k0:k1 + 2], src_name)
    theta = angle_grid(a)
    kinds, files, rows = make_tables(prp['chis'], theta, tab_dir, tab_rel, src_name)

    mol = None
    if not a.no_molecules:
        mpath = a.molec or os.path.join(data, 'molec_abs_w213.dat')
        zl, kabs = read_molec(mpath)
        if zl[0] > z_km[0] + 1e-9 or zl[-1] < z_km[-1] - 1e-9:
            print(f'warning: {os.path.basename(mpath)} covers {zl[0]}-{zl[-1]} km only; '
                  'no molecular absorption outside', file=sys.stderr)
        mol_km = layer_means(zl, kabs, z_km)
        mol = mol_km * 1.0e-3
        print(f'molecular absorption: column optical depth {np.sum(mol_km * np.diff(z_km)):.5f} '
              f'(file {np.sum(kabs * np.diff(zl)):.5f})')

    groups = namelist(a, z_m, lx, ly, nx, ny, k0 + 1, nz3,
                      os.path.relpath(os.path.abspath(scene_path), nml_dir), kinds, files, mol)
    with open(nml_path, 'w') as f:
        f.write(NAMELIST_HEADER)
        kumo.to_namelist(groups).write(f)

    # report
    tau = (ext * np.diff(z_km)[:, None, None]).sum(axis=0)
    used = np.unique(iph3[ext3 > 0])
    print(f'{src_name}: {prp["kind"]} values, {prp["nx"]} x {prp["ny"]} x {prp["nz"]}, '
          f'{len(prp["chis"])} phase functions')
    print(f'kumo: nz = {nl} layers, levels {", ".join(f"{z:g}" for z in z_m)} m')
    print(f'      domain {fmt(lx)} x {fmt(ly)} m, 3-D region layers {k0 + 1}..{k1 + 1} '
          f'(nz3 = {nz3}, {nx} x {ny} columns)')
    print(f'column optical depth: mean {tau.mean():.4f}, min {tau.min():.4f}, max '
          f'{tau.max():.4f}, cloudy columns {np.mean(tau > 0):.3f}; max extinction '
          f'{ext.max():.4g} km-1; ssa {ssa3[ext3 > 0].min():.4f}..{ssa3[ext3 > 0].max():.4f}')
    print(f'phase functions used in cloudy voxels: {", ".join(str(i) for i in used)}')
    print(f'angle grid: {len(theta)} angles')
    print('  i  nleg   g=CHI1/3  g(table)   norm(table)  max P     #neg  min P(raw)  '
          'max rel.err(interp)')
    for r in rows:
        print(f'{r[0]:3d} {r[1]:5d}  {r[2]:9.6f}  {r[3]:9.6f}  {r[4]:.6f}  {r[5]:9.4g}  '
              f'{r[6]:4d}  {r[7]:10.3e}  {r[8]:.2e}')
    gs = [r[2] for r in rows if r[1] > 0 and r[0] in used]
    if gs:
        print(f'g of the cloud phase functions in use: {min(gs):.4f} .. {max(gs):.4f}')
    print(f'wrote {scene_path}, {len(files) - files.count(None)} tables in {tab_dir}, '
          f'{nml_path}')


if __name__ == '__main__':
    main()
