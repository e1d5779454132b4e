#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# A bad voxel temperature in a thermal run on 2 ranks (one scene per node: only the node's
# first rank holds the temperatures and forms their Planck radiances) is every rank's error:
# the job ends (well inside the time limit: a hang fails the test), every rank with the exit
# status of the run on 1 rank, printing its `kumo error:` line, and no rank reports a message of
# its own (`kumo error on rank ...`: a different message, or a rank failing alone). Two inputs: a scene file with a
# voxel at 0 K, which its reader lets through (>= 0) and the node's first rank refuses as it
# forms the Planck radiances (kumo_scene_setup voxel_planck, whose verdict rank 0 gives every
# rank), and an LES water file with a voxel at 0 K, refused by the reader on rank 0.
#
#   thermal_bad_ranks.sh KUMO SCENE_CDL -- MPIEXEC [MPIEXEC FLAGS...]
# SCENE_CDL is tests/mpi/node_scene.cdl (its first temperature is replaced here).
set -uo pipefail
kumo=$1 scene_cdl=$2
shift 2
[[ "${1:-}" == "--" ]] && shift
work=thermal_bad_ranks_work
rm -rf "$work"
mkdir -p "$work"
cd "$work" || exit 1
fail=0

# the scene file: the first voxel temperature (285.0 K) becomes 0 K, which the file's reader
# lets through (>= 0) and the Planck radiances refuse (> 0)
sed -E '/^ temperature =/{n;s/^ 285\.0,/ 0.0,/}' "$scene_cdl" > scene_bad.cdl
grep -q '^ 0.0,' scene_bad.cdl || { echo "FAIL: could not put 0 K into the scene file"; exit 1; }
ncgen -o node_scene.nc scene_bad.cdl || exit 1
cat > scene.nml <<'NML'
&kumo_control n_photons_per_batch = 1000, n_batches = 2, seed = 5 /
&kumo_atmosphere nz = 4, z_levels = 0.0, 300.0, 600.0, 900.0, 3000.0, lx = 800.0, ly = 600.0,
  scene_file = 'node_scene.nc', k3d_bottom = 1, nz3 = 3, nx = 4, ny = 3, n_components_3d = 2,
  ext1d(4,1) = 0.00003, ssa1d(4,1) = 0.0 /
&kumo_phase n_phase = 3, phase_kind = 'hg', 'hg', 'hg', phase_g = 0.85, 0.6, 0.7 /
&kumo_surface albedo = 0.05 /
&kumo_thermal t_levels = 288.0, 286.0, 284.0, 282.0, 260.0, t_surface = 289.0,
  wavenumber_lo = 800.0, wavenumber_hi = 1250.0 /
&kumo_output file = 'out.nc' /
NML

# an LES water file with a voxel at 0 K
cat > les_bad.cdl <<'CDL'
netcdf les_bad {
dimensions:
	x = 3 ;
	y = 2 ;
	z = 2 ;
	z_edges = 3 ;
variables:
	double x(x) ;
		x:units = "m" ;
	double y(y) ;
		y:units = "m" ;
	double z_edges(z_edges) ;
		z_edges:units = "m" ;
	float lwc(z, y, x) ;
		lwc:units = "g m-3" ;
	float reff(z, y, x) ;
		reff:units = "um" ;
	float temperature(z, y, x) ;
		temperature:units = "K" ;
data:
 x = 50, 150, 250 ;
 y = 50, 150 ;
 z_edges = 1000, 1100, 1250 ;
 lwc = 0.1, 0.4, 0, 0.2, 0.3, 0.5, 0.05, 0.1, 0, 0, 0.2, 0.1 ;
 reff = 8, 12, 0, 9, 11, 14, 6, 7, 0, 0, 10, 9 ;
 temperature = 285, 285, 285, 285, 0, 285, 283, 283, 283, 283, 283, 283 ;
}
CDL
ncgen -o les_bad.nc les_bad.cdl || exit 1
cat > les.nml <<'NML'
&kumo_control n_photons_per_batch = 1000, n_batches = 2, seed = 5 /
&kumo_source wavelength_um = 10.5 /
&kumo_atmosphere nz = 4, z_levels = 0.0, 1000.0, 1100.0, 1250.0, 3000.0 /
&kumo_surface albedo = 0.05 /
&kumo_thermal t_levels = 288.0, 284.0, 283.0, 282.0, 270.0, t_surface = 289.0 /
&kumo_cloud cloud_file = 'les_bad.nc' /
&kumo_output file = 'out.nc' /
NML

# case_ NAME NML REGEX LAUNCH...: the run on 1 rank and the run LAUNCH (2 ranks) fail alike,
# with a message matching REGEX. On 2 ranks each rank runs kumo under a shell that records its
# exit status (NAME.rankR.rc, R from the launcher's environment) and then exits 0: a rank that
# did not end in kumo's own failure (ended by MPI_Abort, killed, or still waiting in a
# collective operation when the others stopped) leaves no status, or another one.
case_() {
  local name=$1 nml=$2 regex=$3 rc1 rc2 line1 line2 r
  shift 3
  timeout -s KILL 30 "$kumo" "$nml" > "$name.np1.out" 2> "$name.np1.err"
  rc1=$?
  SECONDS=0
  # shellcheck disable=SC2016
  timeout -s KILL 30 "$@" sh -c '"$0" "$1"; echo $? > "$2.rank${OMPI_COMM_WORLD_RANK:-${PMI_RANK:-${PMIX_RANK:-unknown}}}.rc"' \
    "$kumo" "$nml" "$name" > "$name.np2.out" 2> "$name.np2.err"
  rc2=$?
  line1=$(grep '^kumo error: ' "$name.np1.err")
  line2=$(grep '^kumo error' "$name.np2.err")
  if [[ $rc1 == 0 || $rc1 == 137 ]]; then
    echo "FAIL ($name): the run on 1 rank did not fail with kumo's error (status $rc1):"
    cat "$name.np1.err"
    fail=1
    return
  fi
  if ! grep -E -q "$regex" <<< "$line1"; then
    echo "FAIL ($name): the run on 1 rank does not say /$regex/:"
    cat "$name.np1.err"
    fail=1
  fi
  if [[ $rc2 == 137 ]]; then
    echo "FAIL ($name): the run on 2 ranks hung (killed after 30 s)"
    cat "$name.np2.err"
    fail=1
  fi
  for r in 0 1; do
    if [[ ! -e "$name.rank$r.rc" ]]; then
      echo "FAIL ($name): rank $r of 2 did not end in kumo's own failure (no exit status)"
      cat "$name.np2.err"
      fail=1
    elif [[ $(< "$name.rank$r.rc") != "$rc1" ]]; then
      echo "FAIL ($name): rank $r of 2 ended with status $(< "$name.rank$r.rc"), 1 rank with $rc1"
      fail=1
    fi
  done
  if [[ "$line2" != "$line1" ]]; then
    echo "FAIL ($name): the 2-rank run's error lines differ from the 1-rank run's"
    echo "  1 rank:  $line1"
    echo "  2 ranks: $line2"
    fail=1
  fi
  [[ $fail == 0 ]] && echo "$name: 1 and 2 ranks fail alike in ${SECONDS} s (status $rc1 on" \
    "each rank): $line2"
}
case_ scene scene.nml 'voxel \(1,1,1\) has 0.* K; temperatures must be > 0' "$@" -n 2
case_ les les.nml 'les_bad.nc:temperature\): value 0 at \(x,y,z\) = \(2,2,1\) must be > 0' "$@" -n 2
exit $fail
