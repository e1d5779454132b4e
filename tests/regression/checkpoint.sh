#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Checkpoint and restart: a case run to the end, and the same case killed (SIGKILL, as a batch
# system does at the wall-time limit) after its second checkpoint and then continued with
# `kumo --resume`, must give the same output to the last bit (every variable and attribute but
# the times, the history and the rank count). The first run is on NP1 ranks, the resumed one on
# NP2 (the results are those of a run on NP1 ranks). The kill is the test hook
# KUMO_TEST_KILL_AFTER_CHECKPOINT=2. Then: the checkpoint is removed when the output is
# written; a checkpoint of another configuration (namelist text, an input file) is refused
# with a message naming what differs, and so is a checkpoint cut short; a link at the temporary
# checkpoint name is not followed; --resume without a checkpoint starts from the beginning.
#   checkpoint.sh KUMO NP1 NP2 [MPIEXEC [MPIEXEC_PREFLAGS...]]   (NP1 = NP2 = 1: no MPIEXEC)
set -uo pipefail
kumo=$1 np1=$2 np2=$3
shift 3
work="checkpoint_np${np1}_np${np2}"
rm -rf "$work"
mkdir -p "$work"
cd "$work" || exit 1
# a tabulated phase function is an input file the checkpoint's fingerprint covers
awk 'BEGIN { for (i = 0; i <= 180; i += 5) printf "%d %.6f\n", i, 1.0 + 0.9 * cos(i * 3.14159265 / 180) }' \
  > phase.txt
cat > case.nml <<'NML'
&kumo_control n_photons_per_batch = 4000, n_batches = 12, verbose = 1,
  checkpoint_interval = 1.0e-9 /
&kumo_atmosphere nz = 2, z_levels = 0.0, 500.0, 1000.0, ext1d(1:2,1) = 0.001, 0.002,
  ssa1d(1:2,1) = 0.9, 1.0, phase1d(1:2,1) = 1, 2 /
&kumo_phase n_phase = 2, phase_kind = 'hg', 'table', phase_g(1) = 0.7, phase_file(2) = 'phase.txt' /
&kumo_surface albedo = 0.3 /
&kumo_radiance rad_mu = 1.0, 0.5, rad_phi_deg = 0.0, 30.0 /
&kumo_output file = 'out.nc' /
NML
fail=0
# kumo_on NP ARGS...: run kumo on NP ranks (without a launcher: the program alone)
launcher=("$@")
kumo_on() {
  local np=$1
  shift
  if ((${#launcher[@]} == 0)); then
    "$kumo" "$@"
  else
    "${launcher[@]}" -n "$np" "$kumo" "$@"
  fi
}
# the output without what changes from run to run
dump() {
  ncdump -p 17,17 "$1" | tail -n +2 |
    grep -v -E ':(history|n_ranks|parallel|wall_time_s|cpu_time_s|setup_time_s) ='
}

kumo_on "$np1" case.nml > full.log 2>&1 || { cat full.log; echo "FAIL: the full run failed"; exit 1; }
mv out.nc full.nc
[[ -e out.nc.ckpt ]] && { echo "FAIL: the full run left its checkpoint behind"; fail=1; }

KUMO_TEST_KILL_AFTER_CHECKPOINT=2 kumo_on "$np1" case.nml > killed.log 2>&1
rc=$?
((rc != 0)) || { echo "FAIL: the run to be killed ended normally"; exit 1; }
[[ -e out.nc ]] && { echo "FAIL: the killed run wrote its output"; fail=1; }
[[ -e out.nc.ckpt ]] || { cat killed.log; echo "FAIL: no checkpoint after the kill"; exit 1; }
cp out.nc.ckpt saved.ckpt

kumo_on "$np2" --resume case.nml > resumed.log 2>&1 || {
  cat resumed.log; echo "FAIL: the resumed run failed"; exit 1; }
grep -q 'resuming from the checkpoint out.nc.ckpt: batches 1 to' resumed.log || {
  cat resumed.log; echo "FAIL: the resumed run did not say it resumed"; fail=1; }
if ! diff <(dump full.nc) <(dump out.nc) > diff.txt; then
  echo "FAIL: the resumed output differs from the uninterrupted run:"
  head -20 diff.txt
  fail=1
else
  echo "resumed on $np2 rank(s) after a kill on $np1: output identical to the full run"
fi
[[ -e out.nc.ckpt ]] && { echo "FAIL: the resumed run left its checkpoint behind"; fail=1; }

# a checkpoint of another configuration is refused, naming what differs
sed 's/albedo = 0.3/albedo = 0.31/' case.nml > other_case.nml
cp saved.ckpt out.nc.ckpt
kumo_on "$np2" --resume other_case.nml > other.log 2>&1 && { echo "FAIL: another namelist resumed"; fail=1; }
grep -q 'out.nc.ckpt was written for another configuration: the namelist text differs' other.log || {
  cat other.log; echo "FAIL: no message naming the namelist"; fail=1; }
cp phase.txt phase.orig
sed -i '1 s/ .*/ 2.0/' phase.txt   # another forward value
cp saved.ckpt out.nc.ckpt
kumo_on "$np2" --resume case.nml > input.log 2>&1 && { echo "FAIL: a changed input resumed"; fail=1; }
grep -q 'the input file &kumo_phase phase_file(2) differs' input.log || {
  cat input.log; echo "FAIL: no message naming the changed input file"; fail=1; }
mv phase.orig phase.txt

# a checkpoint cut short (a partial copy) is refused
head -c $(($(wc -c < saved.ckpt) - 20)) saved.ckpt > out.nc.ckpt
kumo_on "$np2" --resume case.nml > cut.log 2>&1 && { echo "FAIL: a cut checkpoint resumed"; fail=1; }
grep -q 'the checkpoint out.nc.ckpt is cut short or damaged' cut.log || {
  cat cut.log; echo "FAIL: no message for the cut checkpoint"; fail=1; }
rm -f out.nc.ckpt

# a link planted at the temporary checkpoint name is never followed
echo precious > victim.txt
ln -s victim.txt out.nc.ckpt.tmp
KUMO_TEST_KILL_AFTER_CHECKPOINT=1 kumo_on "$np1" case.nml > link.log 2>&1
[[ $(cat victim.txt) == precious ]] || { echo "FAIL: the file behind out.nc.ckpt.tmp was changed"; fail=1; }
[[ -f out.nc.ckpt && ! -L out.nc.ckpt ]] || { cat link.log; echo "FAIL: no checkpoint written"; fail=1; }

# --resume without a checkpoint: the run starts from the first batch
rm -f out.nc out.nc.ckpt
kumo_on "$np2" --resume case.nml > fresh.log 2>&1 || { cat fresh.log; echo "FAIL: --resume without a checkpoint"; fail=1; }
grep -q 'no checkpoint out.nc.ckpt: the run starts from the first batch' fresh.log || {
  cat fresh.log; echo "FAIL: no note that the run starts anew"; fail=1; }
exit "$fail"
