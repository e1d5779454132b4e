#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# One copy of the scene per node, for an input path other than the LES water files of
# cloud_ice_ranks (a scene file, an optics or MCARaTS cloud file, ...): the namelist NML is run
# on 1 and on 2 ranks. On 2 ranks the voxel arrays must live in the node's shared window, which
# rank 0 (the node's first rank) allocates and fills, the second rank holding no voxel array
# of its own (the bytes of the run log's "voxel arrays:" line), and every batch must equal
# those of 1 rank, bit for bit. The run on 1 rank must keep its voxel arrays as before. In a
# thermal run (a &kumo_thermal group) the same holds for the emission table.
#
#   node_scene_ranks.sh NAME KUMO NML OUT [INPUT...] -- MPIEXEC [MPIEXEC FLAGS...]
# OUT is the output file the namelist writes; an INPUT ending in .cdl is made into the .nc of
# the same name, any other is copied next to the namelist.
set -euo pipefail
source "$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/one_copy_checks.sh"
name=$1 kumo=$2 nml=$3 out=$4
shift 4
inputs=()
while [[ $# -gt 0 && "$1" != "--" ]]; do
  inputs+=("$1")
  shift
done
[[ $# -gt 0 ]] && shift
work=$name
rm -rf "$work"
mkdir -p "$work"
cd "$work"
for f in "${inputs[@]}"; do
  case "$f" in
    *.cdl) ncgen -o "$(basename "${f%.cdl}").nc" "$f" ;;
    *) cp "$f" . ;;
  esac
done
cp "$nml" run.nml
fail() { echo "$name: $1"; cat np2.log; exit 1; }
"$kumo" run.nml > np1.log 2>&1 || { cat np1.log; exit 1; }
mv "$out" np1.nc
"$@" -n 2 "$kumo" run.nml > np2.log 2>&1 || fail "the run on 2 ranks failed"
mv "$out" np2.nc
# a thermal run: its emission table must be one copy per node too
thermal=''
grep -qi '^ *&kumo_thermal' run.nml && thermal=thermal
check_one_copy "$name" $thermal
