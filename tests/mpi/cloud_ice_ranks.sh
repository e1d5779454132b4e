#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# A monochromatic run over an LES file with liquid and ice water on 1 and on 2 ranks: the
# fields and the ice optics table are read on rank 0 and shared (kumo_cloud_share), and every
# batch must come out the same, bit for bit. The ice optics table is a Mie table of water that
# a first run writes as its cache: the test checks the sharing, not ice optics.
# One copy of the scene per node: on 2 ranks the voxel arrays live in an MPI-3 shared-memory
# window that the node's first rank allocates and fills (kumo_parallel par_node_storage), and
# the second rank holds no voxel array of its own: the run log lists the bytes each rank
# allocated.
#
#   cloud_ice_ranks.sh KUMO CDL MPIEXEC [MPIEXEC FLAGS...]
set -euo pipefail
source "$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/one_copy_checks.sh"
kumo=$1 cdl=$2
shift 2
work=cloud_ice_ranks
rm -rf "$work"
mkdir -p "$work"
cd "$work"
ncgen -o cloud_ice.nc "$cdl"
common="&kumo_control n_photons_per_batch = 3000, n_batches = 4, seed = 11 /
&kumo_source sza_deg = 40.0, wavelength_um = 0.86, solar_flux = 1.0 /
&kumo_surface albedo = 0.1 /
&kumo_output file = 'out.nc' /"
cloud="cloud_file = 'cloud_ice.nc', cloud_format = 'les', size_distribution = 'gamma',
  v_eff = 0.1, reff_min_um = 4.0, reff_max_um = 32.0, n_reff = 6"
# the table: liquid water only, its Mie table kept in ice_table.nc
printf '%s\n&kumo_cloud %s, les_iwc = %s, mie_cache = %s /\n' "$common" "$cloud" "'none'" \
  "'ice_table.nc'" > table.nml
"$kumo" table.nml > table.log 2>&1 || { cat table.log; exit 1; }
printf '%s\n&kumo_cloud %s, ice_optics_file = %s, mie_cache = %s /\n' "$common" "$cloud" \
  "'ice_table.nc'" "'mie.nc'" > ice.nml
"$kumo" ice.nml > np1.log 2>&1 || { cat np1.log; exit 1; }
mv out.nc np1.nc
"$@" -n 2 "$kumo" ice.nml > np2.log 2>&1 || { cat np2.log; exit 1; }
mv out.nc np2.nc
if ! grep -q 'ice optics table ice_table.nc' np2.log; then
  echo "cloud_ice_ranks: the run did not use the ice optics table"
  cat np2.log
  exit 1
fi
check_one_copy cloud_ice_ranks
