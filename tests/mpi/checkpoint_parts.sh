#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Checkpoints written per rank: a manifest out.nc.ckpt and one part out.nc.ckpt.<g>.<r> per
# writing rank. A case killed (SIGKILL) after its second checkpoint on 3 ranks and resumed on 2
# gives the output of an uninterrupted run to the last bit, and leaves no checkpoint file behind.
# A missing part, a part cut short, a part of another generation and a part of the same
# generation written by another job (another stamp) are each refused with a message naming the
# part and the manifest, on whichever rank reads it. A job killed with every
# part in place but before the manifest (test hook KUMO_TEST_KILL_BEFORE_MANIFEST) leaves the
# previous checkpoint usable, and the next resume removes what the cut write left.
#   checkpoint_parts.sh KUMO MPIEXEC [MPIEXEC_PREFLAGS...]
set -uo pipefail
kumo=$1
shift
launcher=("$@")
work=checkpoint_parts
rm -rf "$work"
mkdir -p "$work"
cd "$work" || exit 1
cat > case.nml <<'NML'
&kumo_control n_photons_per_batch = 3000, n_batches = 12, verbose = 1,
  checkpoint_interval = 1.0e-9 /
&kumo_atmosphere nz = 2, z_levels = 0.0, 500.0, 1000.0, ext1d(1:2,1) = 0.001, 0.002,
  ssa1d(1:2,1) = 0.9, 1.0 /
&kumo_phase phase_g(1) = 0.7 /
&kumo_surface albedo = 0.3 /
&kumo_radiance rad_mu = 1.0, 0.5, rad_phi_deg = 0.0, 30.0 /
&kumo_output file = 'out.nc' /
NML
fail=0
kumo_on() {
  local np=$1
  shift
  "${launcher[@]}" -n "$np" "$kumo" "$@"
}
dump() {
  ncdump -p 17,17 "$1" | tail -n +2 |
    grep -v -E ':(history|n_ranks|parallel|wall_time_s|cpu_time_s|setup_time_s) ='
}
# no_leftovers WHAT: no checkpoint file of any kind is left
no_leftovers() {
  local left
  left=$(ls out.nc.ckpt* 2> /dev/null)
  [[ -z $left ]] || { echo "FAIL: $1 left checkpoint files behind: $left"; fail=1; }
}
restore() {
  rm -f out.nc out.nc.ckpt*
  cp saved/* .
}
# refused LOG PATTERN WHAT: the resumed run failed with a message matching PATTERN
refused() {
  local log=$1 pattern=$2 what=$3
  if grep -q -- "$pattern" "$log"; then
    echo "refused: $what"
  else
    cat "$log"
    echo "FAIL: $what was not refused with a message naming the file"
    fail=1
  fi
}

kumo_on 3 case.nml > full.log 2>&1 || { cat full.log; echo "FAIL: the full run failed"; exit 1; }
mv out.nc full.nc
no_leftovers "the full run"

# a part of generation 1 (kept for the foreign-part check below)
KUMO_TEST_KILL_AFTER_CHECKPOINT=1 kumo_on 3 case.nml > gen1.log 2>&1
[[ -e out.nc.ckpt.1.1 ]] || { cat gen1.log; echo "FAIL: no part out.nc.ckpt.1.1"; exit 1; }
cp out.nc.ckpt.1.1 gen1_part1
rm -f out.nc.ckpt*

KUMO_TEST_KILL_AFTER_CHECKPOINT=2 kumo_on 3 case.nml > killed.log 2>&1
(($? != 0)) || { echo "FAIL: the run to be killed ended normally"; exit 1; }
expected="out.nc.ckpt out.nc.ckpt.2.0 out.nc.ckpt.2.1 out.nc.ckpt.2.2"
files=$(echo $(ls out.nc.ckpt*))
[[ $files == "$expected" ]] || { cat killed.log; echo "FAIL: checkpoint files '$files', expected '$expected'"; exit 1; }
mkdir saved
cp out.nc.ckpt* saved/
# the same generation written by another job (another stamp)
rm -f out.nc.ckpt*
KUMO_TEST_KILL_AFTER_CHECKPOINT=2 kumo_on 3 case.nml > other_job.log 2>&1
cp out.nc.ckpt.2.0 other_job_part0

kumo_on 2 --resume case.nml > resumed.log 2>&1 || { cat resumed.log; echo "FAIL: the resumed run failed"; exit 1; }
if diff <(dump full.nc) <(dump out.nc) > diff.txt; then
  echo "written on 3 ranks, resumed on 2: output identical to the full run"
else
  echo "FAIL: the resumed output differs from the uninterrupted run:"
  head -20 diff.txt
  fail=1
fi
no_leftovers "the resumed run"

# a missing part (slot 1: read by rank 1 of 2), a part cut short (slot 2: read by rank 0), a
# part of another generation: each refused, naming the part and the manifest
restore
rm out.nc.ckpt.2.1
kumo_on 2 --resume case.nml > missing.log 2>&1 && { echo "FAIL: a checkpoint without a part resumed"; fail=1; }
refused missing.log 'the checkpoint out.nc.ckpt cannot be resumed: its part out.nc.ckpt.2.1 is missing' \
  "a missing part"
restore
head -c $(($(wc -c < out.nc.ckpt.2.2) - 20)) saved/out.nc.ckpt.2.2 > out.nc.ckpt.2.2
kumo_on 2 --resume case.nml > cut.log 2>&1 && { echo "FAIL: a cut part resumed"; fail=1; }
refused cut.log 'its part out.nc.ckpt.2.2 is cut short or damaged (520 bytes, the checkpoint implies 540)' \
  "a part cut short"
restore
cp gen1_part1 out.nc.ckpt.2.1
kumo_on 2 --resume case.nml > foreign.log 2>&1 && { echo "FAIL: a part of another generation resumed"; fail=1; }
refused foreign.log 'its part out.nc.ckpt.2.1 belongs to another checkpoint (it is part 1 of generation 1' \
  "a part of another generation"
restore
cp other_job_part0 out.nc.ckpt.2.0
kumo_on 2 --resume case.nml > stamp.log 2>&1 && { echo "FAIL: a part of another job resumed"; fail=1; }
refused stamp.log 'its part out.nc.ckpt.2.0 belongs to another checkpoint (it is part 0 of generation 2' \
  "a part of the same generation written by another job"

# killed with its parts in place but no manifest: the previous checkpoint stays usable
restore
KUMO_TEST_KILL_BEFORE_MANIFEST=1 kumo_on 2 --resume case.nml > cut_write.log 2>&1
(($? != 0)) || { echo "FAIL: the run to be killed before its manifest ended normally"; fail=1; }
cmp -s out.nc.ckpt saved/out.nc.ckpt || { echo "FAIL: the manifest changed"; fail=1; }
[[ -e out.nc.ckpt.3.0 && -e out.nc.ckpt.3.1 && -e out.nc.ckpt.pending ]] || {
  cat cut_write.log; echo "FAIL: the cut write did not leave its parts and marker"; fail=1; }
kumo_on 3 --resume case.nml > after_cut.log 2>&1 || { cat after_cut.log; echo "FAIL: no resume after a cut write"; fail=1; }
if diff <(dump full.nc) <(dump out.nc) > diff2.txt; then
  echo "a write killed before its manifest: resumed from the previous checkpoint, output identical"
else
  echo "FAIL: the output after a cut write differs from the uninterrupted run:"
  head -20 diff2.txt
  fail=1
fi
no_leftovers "the run resumed after a cut write"
exit "$fail"
