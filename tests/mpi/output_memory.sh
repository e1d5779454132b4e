#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Rank 0's memory at output: a run whose tallies dwarf its scene (120 x 120 columns with flux
# maps at all 41 levels, a clear 3-D region of one layer) on 2 ranks. The run log's memory line
# (verbose = 2) gives rank 0's peak resident set after the batches and after the output file is
# written, and the bytes of the sums of the tallies. The fold of the ranks' sums, the forming of
# the products and the writing must add less than a quarter of the sums to the peak: rank 0
# receives the other rank's sums piece by piece, and the flux maps and voxel products are formed
# from the sums as they are written, never held beside them (holding them alone adds about half
# the sums here, the fold's former second copy of the sums half of them).
#
#   output_memory.sh KUMO MPIEXEC [MPIEXEC FLAGS...]
set -euo pipefail
kumo=$1
shift
work=output_memory
rm -rf "$work"
mkdir -p "$work"
cd "$work"
nx=120 nz=40
# an MCARaTS 3-D atmosphere of zeros (temperatures, absorption, extinction, albedo, phase code
# of one component, float32): the 3-D region is clear, only its columns count
head -c $((5 * nx * nx * 4)) /dev/zero > zero.atm
cat > run.nml <<NML
&kumo_control n_photons_per_batch = 2000, n_batches = 2, seed = 5, verbose = 2 /
&kumo_atmosphere nz = $nz, z_levels = $(seq -s ', ' 0 100 $((nz * 100))),
  lx = $((nx * 50)).0, ly = $((nx * 50)).0, k3d_bottom = 1, nz3 = 1, nx = $nx, ny = $nx,
  ext1d(1:$nz,1) = $nz*2.0e-5 /
&kumo_cloud cloud_file = 'zero.atm', cloud_format = 'mcarats', mcarats_np3d = 1,
  mcarats_nkd = 1, mcarats_mtprof = 0, mcarats_ikd = 1 /
&kumo_surface albedo = 0.3 /
&kumo_source sza_deg = 30.0, solar_flux = 1.0 /
&kumo_output file = 'out.nc' /
NML
"$@" -n 2 "$kumo" run.nml > np2.log 2>&1 || { cat np2.log; exit 1; }
ncdump -h out.nc > header.cdl
grep -q 'double flux_up_map(level, y, x)' header.cdl || {
  echo "output_memory: out.nc has no flux_up_map(level, y, x)"
  exit 1
}
line=$(grep '^memory of rank 0: ' np2.log) || {
  echo "output_memory: no memory line in the run log"
  cat np2.log
  exit 1
}
pattern='.* set ([0-9]+) bytes after the batches, ([0-9]+) bytes after the output; '
pattern+='sums of the tallies ([0-9]+) bytes'
read -r before after sums < <(sed -E "s/$pattern/\\1 \\2 \\3/" <<< "$line")
growth=$((after - before))
limit=$((sums / 4))
echo "output_memory: rank 0's peak resident set grew by $growth bytes at output (sums of the" \
     "tallies $sums bytes, limit $limit)"
if ((growth > limit)); then
  echo "output_memory: FAILED: the output stage added more than a quarter of the sums to" \
       "rank 0's peak"
  exit 1
fi
