#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# A longwave broadband run over a cloud file (the I3RC LES example of examples/broadband, few
# photons) whose ranks share one copy of the voxels per node: the node's first rank forms them
# at every g-point switch and the others switch with it. Each g-point's emission table draws
# the voxels layer by layer: every rank forms its own, of one entry per layer.
# * 1, 2 and 3 ranks give the same batches, bit for bit;
# * the run log shows that only rank 0 allocated the voxels (in the node's window), and no rank
#   allocated any of its own; every rank's emission table is its own and small (no window, at
#   most a fiftieth of the voxels' bytes);
# * with one_scene_per_node = .false. every rank keeps its own copy, with the same batches;
# * a run killed after its first checkpoint on 3 ranks and resumed on 2 (three slots on two
#   ranks: one rank traces two batches per window while the other joins the switches without a
#   batch) gives the output of the uninterrupted run on 3 ranks to the last bit.
#
#   broadband_node_ranks.sh KUMO NML MPIEXEC [MPIEXEC FLAGS...]
set -uo pipefail
kumo=$1 nml=$2
shift 2
launcher=("$@")
work=broadband_node_ranks
rm -rf "$work"
mkdir -p "$work"
cd "$work" || exit 1
fail=0
sed -e 's/n_photons_per_batch = [0-9]*/n_photons_per_batch = 2000/' \
  -e 's/n_batches = [0-9]*/n_batches = 7/' -e "s/file = 'les_stcu_lw.nc'/file = 'out.nc'/" \
  -e 's/^&kumo_control/\&kumo_control verbose = 1, checkpoint_interval = 1.0e-9,/' "$nml" > case.nml
grep -q 'checkpoint_interval' case.nml || { echo "FAIL: could not edit $nml"; exit 1; }
kumo_on() {
  local np=$1
  shift
  "${launcher[@]}" -n "$np" "$kumo" "$@"
}
batches() {
  ncdump -v batch_reflectance,batch_transmittance,batch_absorptance "$1" | sed -n '/^data:/,$p'
}
dump() {
  ncdump -p 17,17 "$1" | tail -n +2 |
    grep -v -E ':(history|n_ranks|parallel|wall_time_s|cpu_time_s|setup_time_s) ='
}
"$kumo" case.nml > np1.log 2>&1 || { cat np1.log; echo "FAIL: the run on 1 rank failed"; exit 1; }
mv out.nc np1.nc
for np in 2 3; do
  kumo_on "$np" case.nml > "np$np.log" 2>&1 || { cat "np$np.log"; echo "FAIL: the run on $np ranks failed"; exit 1; }
  mv out.nc "np$np.nc"
  if diff <(batches np1.nc) <(batches "np$np.nc") > /dev/null; then
    echo "batches identical on 1 and $np ranks"
  else
    echo "FAIL: the batches of 1 and $np ranks differ"
    fail=1
  fi
  # "... bytes allocated per rank (own, shared window): rank 0 O0 W0; rank 1 O1 W1; ..."
  for what in 'voxel arrays'; do
    line=$(grep "^$what: one copy per node" "np$np.log")
    [[ -n $line ]] || { echo "FAIL: no line on the $what in the log of $np ranks"; fail=1; continue; }
    read -r -a f <<< "${line##*(own, shared window):}"
    w0=${f[3]%;}
    others=""
    for ((r = 0; r < np; r++)); do
      own=${f[$((4 * r + 2))]}
      win=${f[$((4 * r + 3))]%;}
      [[ $own == 0 ]] || others="$others rank $r allocated $own bytes of its own;"
      ((r == 0)) || [[ $win == 0 ]] || others="$others rank $r allocated $win bytes of window;"
    done
    if [[ -z $others && $w0 -gt 0 ]]; then
      echo "$np ranks: one copy of the $what ($w0 bytes, in rank 0's window)"
    else
      echo "FAIL: $np ranks, $what:$others (rank 0's window $w0 bytes)"
      fail=1
    fi
  done
  # "emission table: one per rank, voxels drawn layer by layer (B bytes); ... rank 0 O0 W0; ..."
  line=$(grep '^emission table: one per rank, voxels drawn layer by layer' "np$np.log")
  [[ -n $line ]] || { echo "FAIL: no line on the emission table in the log of $np ranks"; fail=1; continue; }
  read -r -a f <<< "${line##*(own, shared window):}"
  bad=""
  for ((r = 0; r < np; r++)); do
    own=${f[$((4 * r + 2))]}
    win=${f[$((4 * r + 3))]%;}
    [[ $win == 0 ]] || bad="$bad rank $r has $win bytes of window;"
    ((own > 0 && own * 50 <= w0)) || bad="$bad rank $r has $own bytes of its own;"
  done
  if [[ -z $bad ]]; then
    echo "$np ranks: every rank's emission table is its own and small (${f[2]} bytes on rank 0)"
  else
    echo "FAIL: $np ranks, emission table:$bad (voxel arrays $w0 bytes)"
    fail=1
  fi
done
# with one_scene_per_node = .false. every rank keeps its own copy and switches g-points on its
# own: the same batches, and no window
sed -e 's/^&kumo_control /\&kumo_control one_scene_per_node = .false., /' case.nml > own.nml
kumo_on 2 own.nml > own.log 2>&1 || { cat own.log; echo "FAIL: the run on 2 ranks with a copy each failed"; exit 1; }
mv out.nc own.nc
if diff <(batches np1.nc) <(batches own.nc) > /dev/null; then
  echo "batches identical on 1 rank and on 2 ranks with a copy each"
else
  echo "FAIL: the batches of 2 ranks with a copy each differ from 1 rank's"
  fail=1
fi
if grep -q 'one copy per node' own.log; then
  echo "FAIL: one_scene_per_node = .false. still shared the scene"
  fail=1
fi
# the uninterrupted run on 3 ranks wrote checkpoints and removed them
ls out.nc.ckpt* > /dev/null 2>&1 && { echo "FAIL: the run on 3 ranks left checkpoint files"; fail=1; }
KUMO_TEST_KILL_AFTER_CHECKPOINT=1 kumo_on 3 case.nml > killed.log 2>&1
(($? != 0)) || { echo "FAIL: the run to be killed ended normally"; exit 1; }
[[ -e out.nc.ckpt ]] || { cat killed.log; echo "FAIL: no checkpoint out.nc.ckpt"; exit 1; }
kumo_on 2 --resume case.nml > resumed.log 2>&1 || { cat resumed.log; echo "FAIL: the resumed run failed"; exit 1; }
if diff <(dump np3.nc) <(dump out.nc) > diff.txt; then
  echo "killed on 3 ranks, resumed on 2: output identical to the uninterrupted run"
else
  echo "FAIL: the resumed output differs from the uninterrupted run on 3 ranks:"
  head -20 diff.txt
  fail=1
fi
exit $fail
