#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# A rank that fails alone speaks and the job ends: with the test hook KUMO_TEST_FAIL_RANK=1,
# rank 1 of 2 fails after the scene set-up as if an input it reads could not be read, while
# rank 0 traces its batches and then waits for rank 1's sums. The job must end (well inside
# the time limit: a hang fails the test) with a non-zero exit status, print kumo's message
# naming rank 1 and the cause, and write no output. The same with rank 0 failing alone, and an
# error every rank finds (an invalid namelist) is printed once.
#   failing_rank.sh KUMO MPIEXEC [MPIEXEC_PREFLAGS...]
set -uo pipefail
kumo=$1
shift
work=failing_rank_work
rm -rf "$work"
mkdir -p "$work"
cd "$work" || exit 1
cat > case.nml <<'NML'
&kumo_control n_photons_per_batch = 20000, n_batches = 8, verbose = 0 /
&kumo_atmosphere nz = 1, z_levels = 0.0, 1000.0, ext1d(1,1) = 0.001, ssa1d(1,1) = 0.9 /
&kumo_output file = 'out.nc' /
NML
fail=0
# run NAME LIMIT_S ENV...: run kumo on 2 ranks with a time limit, output in NAME.out/.err
run() {
  local name=$1 limit=$2
  shift 2
  env "$@" timeout -s KILL "$limit" "${launch[@]}" "$kumo" case.nml > "$name.out" 2> "$name.err"
  rc=$?
}
expect() {   # expect NAME DESCRIPTION REGEX: stderr of NAME matches REGEX
  if ! grep -E -q "$3" "$1.err"; then
    echo "FAIL ($1): stderr does not $2 (/$3/):"
    cat "$1.err"
    fail=1
  fi
}
launch=("$@" -n 2)

# rank 1 fails alone: it must say so, and the job must end (no hang) with a failure status
SECONDS=0
run rank1 60 KUMO_TEST_FAIL_RANK=1
t=$SECONDS
echo "rank 1 failing: exit status $rc after $t s"
if ((rc == 0 || rc == 137)); then
  echo "FAIL (rank1): exit status $rc (0: success reported; 137: killed at the time limit, a hang)"
  fail=1
fi
expect rank1 "name rank 1 of 2" '^kumo error on rank 1 of 2: '
expect rank1 "name the cause" 'cannot read case\.nml: input unreadable on this rank'
[[ -e out.nc ]] && { echo "FAIL (rank1): out.nc was written"; fail=1; }

# rank 0 fails alone: its message, without a rank, and the job ends
run rank0 60 KUMO_TEST_FAIL_RANK=0
echo "rank 0 failing: exit status $rc"
((rc == 0 || rc == 137)) && { echo "FAIL (rank0): exit status $rc"; fail=1; }
expect rank0 "give rank 0's message" '^kumo error: cannot read case\.nml: input unreadable'

# every rank finds the error: one message, no abort
sed -i 's/n_batches = 8/n_batches = 1/' case.nml
run shared 60
echo "shared error: exit status $rc"
((rc == 0 || rc == 137)) && { echo "FAIL (shared): exit status $rc"; fail=1; }
expect shared "give the error" '^kumo error: &kumo_control: n_batches = 1 must be >= 2'
n=$(grep -c 'kumo error' shared.err)
((n == 1)) || { echo "FAIL (shared): $n error lines, expected 1:"; cat shared.err; fail=1; }
grep -q MPI_ABORT shared.err && { echo "FAIL (shared): MPI_Abort for an error all ranks found"; fail=1; }

((fail == 0)) && echo "failing ranks: every failure printed and the job ended"
exit "$fail"
