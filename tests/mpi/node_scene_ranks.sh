#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# One copy of the scene per node, for an input path other than the LES water files of
# cloud_ice_ranks (a scene file, an optics or MCARaTS cloud file, ...): the namelist NML is run
# on 1 and on 2 ranks. On 2 ranks the voxel arrays must live in the node's shared window, which
# rank 0 (the node's first rank) allocates and fills, the second rank holding no voxel array
# of its own (the bytes of the run log's "voxel arrays:" line), and every batch must equal
# those of 1 rank, bit for bit. The run on 1 rank must keep its voxel arrays as before.
#
#   node_scene_ranks.sh NAME KUMO NML OUT [INPUT...] -- MPIEXEC [MPIEXEC FLAGS...]
# OUT is the output file the namelist writes; an INPUT ending in .cdl is made into the .nc of
# the same name, any other is copied next to the namelist.
set -euo pipefail
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
if grep -q 'voxel arrays: one copy per node' np1.log; then
  fail "a run on 1 rank must keep its voxel arrays as before (no shared window)"
fi
line=$(grep 'voxel arrays: one copy per node in shared memory' np2.log) ||
  fail "the 2-rank run does not report a shared window"
# "... bytes allocated per rank (own, shared window): rank 0 O0 W0; rank 1 O1 W1;"
read -r o0 w0 o1 w1 < <(sed -E 's/.*rank 0 ([0-9]+) ([0-9]+); rank 1 ([0-9]+) ([0-9]+);.*/\1 \2 \3 \4/' <<< "$line")
[[ "$o0" == 0 && "$o1" == 0 ]] || fail "a rank allocated voxel arrays of its own ($o0, $o1 bytes)"
[[ "$w0" -gt 0 ]] || fail "rank 0 allocated no shared window"
[[ "$w1" == 0 ]] || fail "rank 1 allocated $w1 bytes of window: the scene is not one copy"
vars=batch_reflectance,batch_transmittance,batch_absorptance
for f in np1 np2; do
  ncdump -v "$vars" "$f.nc" | sed -n '/^data:/,$p' > "$f.txt"
done
if ! diff np1.txt np2.txt > /dev/null; then
  echo "$name: the batches of 1 and 2 ranks differ"
  diff np1.txt np2.txt | head -20
  exit 1
fi
echo "$name: window of $w0 bytes on rank 0, none on rank 1; $(grep -c , np1.txt)" \
  "lines of batch results identical on 1 and 2 ranks"
