#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Write kumo scenes and namelists for the I3RC Phase 1 cases (Cahalan et al. 2005).

The three Phase 1 clouds of the Intercomparison of 3-D Radiation Codes (Cahalan et al. 2005,
BAMS 86, 1275, doi:10.1175/BAMS-86-9-1275), with the inputs in examples/data/i3rc_phase1 (their
README gives the source and the licence; `--data DIR` reads them from elsewhere):

  case 1  step cloud: 32 columns of 15.625 m (period 0.5 km), columns 1-16 optical depth 2,
          17-32 optical depth 18, cloud from 0 to 0.25 km, uniform extinction, infinite in y
  case 2  ARM MMCR cloud (Lamont, 8 Feb 1998): 640 x 54 cells of 50 m x 45 m (x by z), optical
          depth per cell from `mmcr_tau_32km_020898` (first line = top layer), grid from the
          ground to 2.43 km, infinite in y
  case 3  Landsat cloud (scene 43): 128 x 128 columns of 30 m, cloud base flat at 0.2 km,
          column optical depth and geometric thickness from `scene43.tau/dz.128x128`, uniform
          extinction in each column; 80 equal layers from the base to the highest top (30 m
          thick), so that the voxels the cloud tops cut hold little of any column

No atmosphere besides the cloud, periodic boundaries, one wavelength, solar flux 1, sun in the
x-z plane with the photons travelling towards +x (`phi0_deg = 0`). Experiments (EXPERIMENTS
below): Henyey-Greenstein g = 0.85 or the tabulated Deirmendjian C.1 phase function, single-
scattering albedo 1 or 0.99, solar zenith angle 0 or 60 deg, black or Lambert (0.4) surface.

For each selected case this writes into the run folder (default `examples/i3rc/run`):

  case<c>_ssa<w>.nc               the cloud as a kumo scene file, one per single-scattering
                                  albedo (the scene file carries the albedo); besides
                                  `extinction` and `ssa` it holds `dz(z)`, the layer thickness
  C.1_PF                          copy of the C.1 phase-function table (case 2, exps 6 and 7)
  case<c>_exp<e>_<mode>.nml       one namelist per experiment and transport mode; the output
                                  file it names (`case<c>_exp<e>_<mode>.nc`) is relative to the
                                  working directory, so run kumo inside the run folder

Modes (`mode_3d` in `&kumo_control`): `f3d` (full 3-D), `ica` (independent columns), `p3d`
with `--p3d-orders N` (photons move horizontally during the direct beam and after scatterings
1 .. N-1, and stay in their column afterwards; files `..._p3d<N>.nml`). The namelists (written
with the kumo Python package of python/, a comment header on top) ask for the I3RC products:
flux maps at the ground and the top (R, T), absorption per column (A) and net horizontal
transport (H) of the 3-D region, which spans the whole atmosphere, and radiance maps (Iu, Id,
I601, I602); plot_i3rc.py extracts them. As in the I3RC definitions (and the consensus files),
the transmittance T and the zenith radiance Id are taken at the cloud base: 630 m in case 2
(the lowest 14 layers of the MMCR field are clear), 200 m in case 3, the ground in case 1. The
namelists therefore put flux and radiance detectors at the ground, the cloud base and the top.

`--check` reads the scene files back and verifies their column optical depths against the
published statistics (case 1: exactly 2 and 18; case 2: mean 19.509, min 6.480, max 51.525;
case 3: mean 10.064, max 42.11); it exits with status 1 on a mismatch.

The Landsat functions (read_landsat_field, levels_km, voxel_extinction, write_scene) are also
used by bench/make_landsat_scene.py.

Usage:
  python3 examples/i3rc/i3rc_cases.py [--case {1,2,3}] [--exp N] [--mode {f3d,ica,p3d}]
      [--p3d-orders N] [--photons N] [--batches N] [--seed N] [--data DIR] [--run-dir DIR]
      [--check] [--list]
"""
import argparse
import os
import shutil
import sys
from dataclasses import dataclass

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, 'python', 'src'))   # the kumo package of this tree
import kumo

# ------------------------------------------------------------------------------------------------
# Input data
# ------------------------------------------------------------------------------------------------

BASE_KM = 0.2          # flat cloud base of the Landsat scene [km]
DX_M = 30.0            # column size of the Landsat field [m]
N_FIELD = 128          # columns per side of the Landsat field
#: Equal layers from the cloud base to the highest cloud top (2.38 km above it). With 20 layers
#: of 119 m the voxels the cloud tops cut spread their optical depth over the whole voxel, which
#: lowers R by 0.27 % and the nadir radiance by 0.6 % against the same cloud on 80 layers.
LANDSAT_LAYERS = 80

MMCR_FILE = 'mmcr_tau_32km_020898'
MMCR_SHAPE = (54, 640)  # lines (layers, top first) x values (columns)
MMCR_DX_M = 50.0
MMCR_DZ_M = 45.0

STEP_NX = 32
STEP_LX_M = 500.0
STEP_TOP_M = 250.0
STEP_TAU = (2.0, 18.0)  # columns 1-16, 17-32

C1_FILE = 'C.1_PF'


def default_data_dir():
    """The I3RC Phase 1 inputs shipped with the repository: examples/data/i3rc_phase1."""
    return os.path.join(REPO, 'examples', 'data', 'i3rc_phase1')


def _input_path(data_dir, name):
    path = os.path.join(data_dir, name)
    if not os.path.isfile(path):
        raise ValueError(f'input file {path} not found (the repository holds it in '
                         'examples/data/i3rc_phase1; --data DIR reads it from DIR)')
    return path


def read_landsat_field(data_dir):
    """Case 3: column optical depth and geometric thickness [km] as (ny, nx) arrays (line = y)."""
    tau = np.loadtxt(_input_path(data_dir, 'scene43.tau.128x128'))
    dz = np.loadtxt(_input_path(data_dir, 'scene43.dz.128x128'))
    if tau.shape != (N_FIELD, N_FIELD) or dz.shape != (N_FIELD, N_FIELD):
        raise ValueError(f'expected {N_FIELD} x {N_FIELD} values, got tau {tau.shape} and dz '
                         f'{dz.shape}')
    if np.any(tau < 0) or np.any(dz < 0) or np.any((tau > 0) & (dz <= 0)):
        raise ValueError('negative values, or optical depth in a column of zero thickness')
    return tau, dz


def levels_km(dz, n_layers):
    """Levels [km]: ground, cloud base, then n_layers equal layers up to the highest top."""
    top = BASE_KM + float(dz.max())
    return np.concatenate(([0.0], BASE_KM + (top - BASE_KM) * np.arange(n_layers + 1) / n_layers))


def voxel_extinction(tau, dz, z_km):
    """Extinction [m-1] of the layers above the cloud base (layers 2..), shape (nz3, ny, nx).

    Each column is filled from the base up to base + dz(column) with extinction tau/dz; a voxel
    the cloud top cuts gets the extinction times the covered fraction, so the column optical
    depth of every column is exact."""
    zb = z_km[1:-1] - BASE_KM            # bottoms of the 3-D layers above the base [km]
    zt = z_km[2:] - BASE_KM              # tops
    thick = (zt - zb)[:, None, None]
    covered = np.clip(np.minimum(zt[:, None, None], dz[None]) - zb[:, None, None], 0.0, None)
    ext_km = np.where(dz > 0, tau / np.where(dz > 0, dz, 1.0), 0.0)[None]  # [km-1]
    ext = ext_km * covered / thick * 1.0e-3                                # layer mean [m-1]
    # exact column optical depth (round-off only)
    col = (ext * thick * 1.0e3).sum(axis=0)
    err = np.max(np.abs(col - tau))
    if err > 1.0e-9 * max(1.0, tau.max()):
        raise ValueError(f'column optical depth off by {err}')
    return ext


def read_mmcr_field(data_dir):
    """Case 2: optical depth per cell as an (nz, nx) array, bottom layer first."""
    tau = np.loadtxt(_input_path(data_dir, MMCR_FILE))
    if tau.shape != MMCR_SHAPE:
        raise ValueError(f'{MMCR_FILE}: expected {MMCR_SHAPE[0]} lines of {MMCR_SHAPE[1]} '
                         f'values, got {tau.shape}')
    if np.any(tau < 0) or not np.all(np.isfinite(tau)):
        raise ValueError(f'{MMCR_FILE}: negative or invalid optical depths')
    return tau[::-1].copy()              # the file's first line is the top layer


def write_scene(path, ext, ssa, title, source, dz_m=None):
    """Write a one-component kumo scene file (kumo.write_scene): extinction (nz3, ny, nx)
    [m-1], a uniform single-scattering albedo, and optionally the layer thicknesses dz(z) [m]
    (ignored by kumo, used by --check). Written to `path`.tmp first, then renamed."""
    from netCDF4 import Dataset
    tmp = path + '.tmp'
    kumo.write_scene(tmp, ext, np.full(ext.shape, ssa))
    with Dataset(tmp, 'a') as nc:
        nc.title = title
        nc.source = source
        if dz_m is not None:
            v = nc.createVariable('dz', 'f8', ('z',))
            v.long_name = 'layer thickness'
            v.units = 'm'
            v[:] = dz_m
    os.replace(tmp, path)


# ------------------------------------------------------------------------------------------------
# Cases and experiments
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Experiment:
    phase: str        # 'hg' (g = 0.85) or 'c1' (tabulated C.1)
    ssa: float
    sza: float        # deg
    albedo: float     # Lambert surface albedo

    def describe(self):
        ph = 'HG g 0.85' if self.phase == 'hg' else 'C.1 phase function (table)'
        sfc = 'black surface' if self.albedo == 0 else f'Lambert surface albedo {self.albedo:g}'
        return f'{ph}, SSA {self.ssa:g}, SZA {self.sza:g}, {sfc}'


_HG = [Experiment('hg', 1.00, 0.0, 0.0), Experiment('hg', 1.00, 60.0, 0.0),
       Experiment('hg', 0.99, 0.0, 0.0), Experiment('hg', 0.99, 60.0, 0.0)]

#: I3RC Phase 1 experiments per case (shared data README, section 1; Cahalan et al. 2005).
EXPERIMENTS = {
    1: dict(enumerate(_HG, start=1)),
    2: dict(enumerate(_HG + [Experiment('hg', 1.00, 60.0, 0.4),
                             Experiment('c1', 1.00, 0.0, 0.0),
                             Experiment('c1', 1.00, 60.0, 0.0)], start=1)),
    3: dict(enumerate(_HG, start=1)),
}

CASE_TITLES = {1: 'step cloud', 2: 'MMCR cloud', 3: 'Landsat cloud'}

#: Default photons per run: on one core each run takes about 5 to 45 s. The tabulated C.1
#: phase function makes the radiances about 3 times as costly, so those runs get half.
DEFAULT_PHOTONS = {1: 2_000_000, 2: 1_000_000, 3: 2_000_000}
DEFAULT_BATCHES = 10


def default_photons(case, exp_no):
    """Default photons of one run."""
    n = DEFAULT_PHOTONS[case]
    return n // 2 if EXPERIMENTS[case][exp_no].phase == 'c1' else n

#: Published column optical depth statistics: (mean, min, max); None = not checked.
TAU_CHECK = {1: None, 2: (19.509, 6.480, 51.525), 3: (10.064, None, 42.11)}


@dataclass
class Scene:
    """A case's cloud on kumo's grid: extinction (nz, ny, nx) [m-1] with layer 1 at the ground,
    level heights [m] and the domain size [m]. The 3-D region covers every layer."""
    case: int
    ext: np.ndarray
    z_m: np.ndarray
    lx: float
    ly: float

    @property
    def shape(self):
        return self.ext.shape

    @property
    def base_level(self):
        """The cloud base: the level below the lowest layer holding any cloud (0 = ground)."""
        cloudy = np.flatnonzero((self.ext > 0).any(axis=(1, 2)))
        return int(cloudy[0]) if cloudy.size else 0

    @property
    def detector_levels(self):
        """Levels of the flux and radiance detectors: ground, cloud base (if above it), top."""
        return sorted({0, self.base_level, self.shape[0]})


def build_scene(case, data_dir):
    """The cloud of `case` (1, 2, 3) as a Scene."""
    if case == 1:
        tau = np.repeat(np.array(STEP_TAU), STEP_NX // 2)
        ext = (tau / STEP_TOP_M)[None, None, :]
        return Scene(1, ext, np.array([0.0, STEP_TOP_M]), STEP_LX_M, STEP_LX_M)
    if case == 2:
        tau = read_mmcr_field(data_dir)
        nz, nx = tau.shape
        ext = (tau / MMCR_DZ_M)[:, None, :]
        lx = nx * MMCR_DX_M
        return Scene(2, ext, MMCR_DZ_M * np.arange(nz + 1), lx, lx)
    if case == 3:
        tau, dz = read_landsat_field(data_dir)
        z_km = levels_km(dz, LANDSAT_LAYERS)
        ext = voxel_extinction(tau, dz, z_km)
        # the clear layer below the cloud base joins the 3-D region (extinction 0), so that the
        # region's bottom is the ground and H is the net horizontal transport of the whole column
        ext = np.concatenate((np.zeros((1,) + ext.shape[1:]), ext), axis=0)
        lx = N_FIELD * DX_M
        return Scene(3, ext, 1000.0 * z_km, lx, lx)
    raise ValueError(f'unknown case {case} (1, 2 or 3)')


def scene_file_name(case, ssa):
    return f'case{case}_ssa{ssa:g}.nc'


def mode_tag(mode, p3d_orders):
    return f'p3d{p3d_orders}' if mode == 'p3d' else mode


def namelist_groups(scene, scene_file, case, exp_no, exp, mode, p3d_orders, photons, batches,
                    seed):
    """The kumo namelist groups (kumo.write_namelist) of one case, experiment and mode."""
    nz3, ny, nx = scene.shape
    levels = scene.detector_levels
    control = {'n_photons_per_batch': max(1, photons // batches), 'n_batches': batches,
               'seed': seed, 'mode_3d': mode}
    if mode == 'p3d':
        control['p3d_orders'] = p3d_orders
    if exp.phase == 'hg':
        phase = {'n_phase': 1, 'phase_kind': 'hg', 'phase_g': 0.85}
    else:
        phase = {'n_phase': 1, 'phase_kind': 'table', 'phase_file': C1_FILE}
    return {
        'control': control,
        'atmosphere': {'nz': nz3, 'z_levels': np.round(scene.z_m, 6),
                       'lx': round(scene.lx, 3), 'ly': round(scene.ly, 3),
                       'scene_file': scene_file, 'k3d_bottom': 1, 'nx': nx, 'ny': ny,
                       'nz3': nz3, 'n_components_3d': 1, 'phase3d': 1},
        'phase': phase,
        'surface': {'albedo': exp.albedo},
        'source': {'sza_deg': exp.sza, 'phi0_deg': 0.0, 'solar_flux': 1.0},
        'output': {'file': f'case{case}_exp{exp_no}_{mode_tag(mode, p3d_orders)}.nc',
                   'flux_levels': levels},
        'radiance': {'rad_mu': [1.0, -1.0, 0.5, 0.5], 'rad_phi_deg': [0.0, 0.0, 0.0, 180.0],
                     'rad_levels': levels},
    }


def namelist_header(scene, case, exp_no, exp, mode, p3d_orders):
    """Comment lines that open the namelist file: what the case is and what the detectors are."""
    base = scene.base_level
    base_text = (f'level {base} = {scene.z_m[base]:g} m' if base > 0 else
                 'level 0, the ground: the cloud starts there')
    return (
        f'! I3RC Phase 1 case {case} ({CASE_TITLES[case]}), experiment {exp_no}: '
        f'{exp.describe()}.\n'
        f'! Transport mode {mode_tag(mode, p3d_orders)}. Written by i3rc_cases.py; run kumo in '
        'this folder.\n'
        '! Sun: phi0_deg = 0, the photons travel towards +x (sun at low x).\n'
        f'! kumo_output: R is the flux map at the top; T at the cloud base ({base_text}), as\n'
        '! I3RC defines it; the ground level closes the budget. A, H: absorptance_column and\n'
        '! horizontal_transport_map (the 3-D region spans levels 0..nz).\n'
        '! kumo_radiance: Iu is mu 1 at the top; Id mu -1 at the cloud base; I601, I602 mu 0.5\n'
        '! at the top, light travelling towards +x (phi 0, forward side) and -x (phi 180).\n')


def write_case(case, exps, modes, photons, batches, seed, data_dir, run_dir):
    """Write the scene files and namelists of one case; returns the namelist paths. `photons`
    None gives each experiment its default."""
    scene = build_scene(case, data_dir)
    written = []
    for ssa in sorted({EXPERIMENTS[case][e].ssa for e in exps}):
        name = scene_file_name(case, ssa)
        write_scene(os.path.join(run_dir, name), scene.ext, ssa,
                    f'I3RC Phase 1 case {case} ({CASE_TITLES[case]}) as a kumo scene',
                    'examples/i3rc/i3rc_cases.py from the I3RC Phase 1 inputs',
                    dz_m=np.diff(scene.z_m))
    if any(EXPERIMENTS[case][e].phase == 'c1' for e in exps):
        shutil.copyfile(_input_path(data_dir, C1_FILE), os.path.join(run_dir, C1_FILE))
    for e in exps:
        exp = EXPERIMENTS[case][e]
        for mode, orders in modes:
            groups = namelist_groups(scene, scene_file_name(case, exp.ssa), case, e, exp, mode,
                                     orders, photons or default_photons(case, e), batches, seed)
            path = os.path.join(run_dir, f'case{case}_exp{e}_{mode_tag(mode, orders)}.nml')
            with open(path, 'w') as f:
                f.write(namelist_header(scene, case, e, exp, mode, orders))
                kumo.to_namelist(groups).write(f)
            written.append(path)
    return written


def check_scene_file(path, case):
    """Column optical depths of a written scene file against the published values; returns a
    list of problems (empty when it agrees)."""
    from netCDF4 import Dataset
    with Dataset(path) as nc:
        ext = np.asarray(nc['extinction'][0], dtype=float)
        dz = np.asarray(nc['dz'][:], dtype=float)
    tau = (ext * dz[:, None, None]).sum(axis=0)
    print(f'{os.path.basename(path)}: column optical depth mean {tau.mean():.4f}, min '
          f'{tau.min():.4f}, max {tau.max():.4f}')
    problems = []
    if case == 1:
        want = np.repeat(np.array(STEP_TAU), STEP_NX // 2)[None, :]
        err = np.max(np.abs(tau - want))
        if tau.shape != want.shape or err > 1e-9:
            problems.append(f'columns 1-16 must have optical depth 2 and 17-32 optical depth 18 '
                            f'(largest difference {err:.3g})')
        return problems
    mean, lo, hi = TAU_CHECK[case]
    for label, value, ref, tol in (('mean', tau.mean(), mean, 5e-4), ('min', tau.min(), lo, 5e-4),
                                   ('max', tau.max(), hi, 5e-3)):
        if ref is not None and abs(value - ref) > tol:
            problems.append(f'{label} column optical depth {value:.4f}, published {ref}')
    return problems


# ------------------------------------------------------------------------------------------------
# Command line
# ------------------------------------------------------------------------------------------------

def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog='See examples/i3rc/README.md.')
    ap.add_argument('--case', type=int, choices=(1, 2, 3), default=None,
                    help='case (default: all three)')
    ap.add_argument('--exp', type=int, default=None,
                    help='experiment number (default: all of the case; needs --case)')
    ap.add_argument('--mode', choices=('f3d', 'ica', 'p3d'), default='f3d',
                    help='transport mode (default f3d)')
    ap.add_argument('--p3d-orders', type=int, default=1,
                    help='scattering orders traced in 3-D with --mode p3d (default 1)')
    ap.add_argument('--photons', type=int, default=None,
                    help='photons per run (default: case 1 and 3: 2e6; case 2: 1e6, with the '
                    'C.1 phase function 5e5)')
    ap.add_argument('--batches', type=int, default=DEFAULT_BATCHES,
                    help=f'batches per run (default {DEFAULT_BATCHES})')
    ap.add_argument('--seed', type=int, default=1, help='random seed (default 1)')
    ap.add_argument('--data', default=None, help='folder with the I3RC Phase 1 input files '
                    '(default examples/data/i3rc_phase1)')
    ap.add_argument('--run-dir', default=os.path.join(HERE, 'run'),
                    help='folder for the scenes and namelists (default examples/i3rc/run)')
    ap.add_argument('--check', action='store_true',
                    help='verify the column optical depths of the written scene files')
    ap.add_argument('--list', action='store_true',
                    help='print only the names of the namelists that would be written')
    a = ap.parse_args(argv)

    prog = 'i3rc_cases'
    cases = [a.case] if a.case else [1, 2, 3]
    if a.exp is not None:
        if a.case is None:
            ap.error('--exp needs --case')
        if a.exp not in EXPERIMENTS[a.case]:
            ap.error(f'case {a.case} has experiments {min(EXPERIMENTS[a.case])}..'
                     f'{max(EXPERIMENTS[a.case])}, not {a.exp}')
    if a.mode == 'p3d' and a.p3d_orders < 0:
        ap.error('--p3d-orders must be >= 0')
    if a.batches < 2:
        ap.error('--batches must be >= 2 (the standard errors come from the batches)')
    if a.photons is not None and a.photons < a.batches:
        ap.error('--photons must be at least --batches')
    modes = [(a.mode, a.p3d_orders)]
    data_dir = a.data or default_data_dir()

    if a.list:
        for c in cases:
            for e in ([a.exp] if a.exp else sorted(EXPERIMENTS[c])):
                print(f'case{c}_exp{e}_{mode_tag(a.mode, a.p3d_orders)}.nml')
        return 0

    os.makedirs(a.run_dir, exist_ok=True)
    failed = False
    for c in cases:
        exps = [a.exp] if a.exp else sorted(EXPERIMENTS[c])
        try:
            paths = write_case(c, exps, modes, a.photons, a.batches, a.seed, data_dir, a.run_dir)
        except (ValueError, OSError) as err:
            sys.exit(f'{prog}: case {c}: {err}')
        for p in paths:
            print(f'wrote {os.path.relpath(p)}')
        if a.check:
            for ssa in sorted({EXPERIMENTS[c][e].ssa for e in exps}):
                path = os.path.join(a.run_dir, scene_file_name(c, ssa))
                for problem in check_scene_file(path, c):
                    print(f'{prog}: check failed: {os.path.basename(path)}: {problem}',
                          file=sys.stderr)
                    failed = True
    if a.check:
        print(f'{prog}: check {"FAILED" if failed else "passed"}')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
