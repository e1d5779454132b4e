#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Convert the I3RC Phase 1 Landsat cloud (case 3) into a kumo scene file.

Input: the two I3RC files `scene43.tau.128x128` (column optical depth) and
`scene43.dz.128x128` (geometric thickness in km), 128 lines (y) x 128 values (x), 30 m columns,
cloud base flat at 0.2 km, uniform extinction inside each column, Henyey-Greenstein g = 0.85.

Vertical grid: level 0 at the ground, level 1 at the cloud base (0.2 km), then `--layers` equal
layers up to the highest cloud top (0.2 km + max dz = 2.58 km). Layer 1 (0 - 0.2 km) is clear
and stays a 1-D layer; layers 2 .. 1 + `--layers` form the 3-D region (`k3d_bottom = 2`).
Each column is filled from the base up to base + dz(column) with extinction tau/dz; a voxel the
cloud top cuts gets the extinction times the covered fraction, so the column optical depth of
every column is exact.

`--refine 2` writes the same field on a grid twice as fine horizontally (256 x 256 columns of
15 m): every column is split into 2 x 2 identical columns, so the optical statistics (and, with
one majorant, every photon path) are those of the 128 x 128 field.

The field reader and the grid and extinction functions are those of
examples/i3rc/i3rc_cases.py (imported from there).

Besides the scene file, `--atm-group FILE` writes the matching `&kumo_atmosphere` namelist group
(levels, domain size, 3-D region) so that a case namelist can include it verbatim.

Usage:
  python3 bench/make_landsat_scene.py --data DIR --out scene.nc [--refine 2] [--layers 20]
      [--ssa 0.99] [--atm-group atm.nml]
DIR defaults to examples/data/i3rc_phase1, the copy of the I3RC inputs in the repository.
"""
import argparse
import os
import sys

import numpy as np

# The Landsat field reader, vertical grid, extinction and scene writer are shared with the I3RC
# examples: examples/i3rc/i3rc_cases.py.
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, 'examples', 'i3rc'))
sys.path.insert(0, os.path.join(REPO, 'python', 'src'))   # the kumo package of this tree
import kumo  # noqa: E402
from i3rc_cases import (DX_M, N_FIELD, default_data_dir, levels_km,  # noqa: E402
                        read_landsat_field, voxel_extinction, write_scene)


def atm_group(z_km, nx, ny, lx_m, ly_m, scene):
    """The &kumo_atmosphere group for the scene (layer 1 clear, layers 2.. the 3-D region), as
    a dict for kumo.write_namelist."""
    nz = len(z_km) - 1
    return {'nz': nz, 'z_levels': np.round(1000.0 * np.asarray(z_km), 6),
            'lx': round(lx_m, 1), 'ly': round(ly_m, 1), 'scene_file': scene, 'k3d_bottom': 2,
            'nx': nx, 'ny': ny, 'nz3': nz - 1, 'n_components_3d': 1, 'phase3d': 1}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--data', default=None, help='folder with the scene43.* files')
    ap.add_argument('--out', required=True, help='scene file to write (netCDF)')
    ap.add_argument('--refine', type=int, default=1, help='split each column into r x r (1, 2)')
    ap.add_argument('--layers', type=int, default=20, help='layers of the 3-D region')
    ap.add_argument('--ssa', type=float, default=0.99, help='single-scattering albedo')
    ap.add_argument('--atm-group', default=None, help='also write the &kumo_atmosphere group')
    a = ap.parse_args()
    if a.refine < 1 or a.layers < 1 or not 0.0 <= a.ssa <= 1.0:
        sys.exit('make_landsat_scene: need refine >= 1, layers >= 1, 0 <= ssa <= 1')
    try:
        tau, dz = read_landsat_field(a.data or default_data_dir())
        z_km = levels_km(dz, a.layers)
        ext = voxel_extinction(tau, dz, z_km)
    except (ValueError, OSError) as err:
        sys.exit(f'make_landsat_scene: {err}')
    if a.refine > 1:
        ext = np.repeat(np.repeat(ext, a.refine, axis=1), a.refine, axis=2)
    write_scene(a.out, ext, a.ssa, 'I3RC Phase 1 Landsat cloud (case 3) as a kumo scene',
                'bench/make_landsat_scene.py from scene43.tau.128x128, scene43.dz.128x128')
    ny, nx = ext.shape[1:]
    if a.atm_group:
        kumo.write_namelist({'atmosphere': atm_group(z_km, nx, ny, N_FIELD * DX_M, N_FIELD * DX_M,
                                                     os.path.basename(a.out))}, a.atm_group)
    print(f'{a.out}: {nx} x {ny} x {ext.shape[0]} voxels, mean column optical depth '
          f'{tau.mean():.4f}, max extinction {ext.max():.6g} m-1')


if __name__ == '__main__':
    main()
