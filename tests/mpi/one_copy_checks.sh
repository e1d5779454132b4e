# SPDX-License-Identifier: BSD-3-Clause
# Checks shared by the one-copy-per-node tests (cloud_ice_ranks.sh, node_scene_ranks.sh), sourced
# by them: in the current folder, np1.log/np1.nc come from a run on 1 rank and np2.log/np2.nc
# from the same run on 2 ranks.
#
#   check_one_copy NAME [thermal]
# The run on 1 rank keeps its voxel arrays as before (no shared window); on 2 ranks rank 0
# allocates the node's window and neither rank has voxel arrays of its own (the bytes of the
# run log's "voxel arrays:" line); every batch equals those of 1 rank, bit for bit. With
# `thermal` the emission table (its per-voxel arrays and cumulative table) must be one copy per
# node the same way (the run log's "emission table:" line), and the voxel temperatures and their
# Planck radiances must be held by rank 0 alone (the run log's "voxel temperatures:" line:
# bytes rank 0 held, none on rank 1).
check_one_copy() {
  local name=$1 line o0 w0 o1 w1 f what windows=''
  fail() { echo "$name: $1"; cat np2.log; exit 1; }
  for what in 'voxel arrays' 'emission table'; do
    [[ "$what" == 'emission table' && "${2:-}" != thermal ]] && continue
    if grep -q "$what: one copy per node" np1.log; then
      fail "a run on 1 rank must keep its $what as before (no shared window)"
    fi
    line=$(grep "$what: one copy per node in shared memory" np2.log) ||
      fail "the 2-rank run does not report a shared window for its $what"
    # "... bytes allocated per rank (own, shared window): rank 0 O0 W0; rank 1 O1 W1;"
    read -r o0 w0 o1 w1 < <(sed -E 's/.*rank 0 ([0-9]+) ([0-9]+); rank 1 ([0-9]+) ([0-9]+);.*/\1 \2 \3 \4/' <<< "$line")
    [[ "$o0" == 0 && "$o1" == 0 ]] || fail "a rank allocated $what of its own ($o0, $o1 bytes)"
    [[ "$w0" -gt 0 ]] || fail "rank 0 allocated no shared window for its $what"
    [[ "$w1" == 0 ]] || fail "rank 1 allocated $w1 bytes of window: the $what are not one copy"
    windows="$windows${windows:+, }$what $w0 bytes"
  done
  if [[ "${2:-}" == thermal ]]; then
    grep -q "voxel temperatures: held" np1.log &&
      fail "a run on 1 rank must form its voxel Planck radiances as before (no node's first rank)"
    line=$(grep "voxel temperatures: held and made into Planck radiances by the node's first rank alone" np2.log) ||
      fail "the 2-rank run does not report where its voxel temperatures are held"
    read -r o0 w0 o1 w1 < <(sed -E 's/.*rank 0 ([0-9]+) ([0-9]+); rank 1 ([0-9]+) ([0-9]+);.*/\1 \2 \3 \4/' <<< "$line")
    [[ "$o0" -gt 0 ]] || fail "rank 0 holds no voxel temperatures ($o0 bytes)"
    [[ "$o1" == 0 ]] || fail "rank 1 held $o1 bytes of voxel temperatures or Planck radiances"
    windows="$windows; voxel temperatures and Planck radiances $o0 bytes on rank 0, none on rank 1"
  fi
  for f in np1 np2; do
    ncdump -v batch_reflectance,batch_transmittance,batch_absorptance "$f.nc" |
      sed -n '/^data:/,$p' > "$f.txt"
  done
  if ! diff np1.txt np2.txt > /dev/null; then
    echo "$name: the batches of 1 and 2 ranks differ"
    diff np1.txt np2.txt | head -20
    exit 1
  fi
  echo "$name: windows on rank 0 ($windows), none on rank 1; $(grep -c , np1.txt)" \
    "lines of batch results identical on 1 and 2 ranks"
}
