#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Install what is missing, then build and run the test suite in three configurations:
# Release (build/) and Debug (build-debug/, run-time checks and FP traps) run the whole
# suite; the serial build without MPI (build-serial/) runs all but the `bench` label (its
# physics is the Release build's; what differs is the parallel layer, which the other
# labels and the batch-by-batch comparison of the serial and MPI builds that follows
# cover). All runs always happen; the script exits non-zero if any fails. The last line
# is the total over all runs, "N passed, N failed". A configuration that does not build
# counts as one failed test.
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

bash scripts/install-deps.sh || exit 1
# RRTMGP k-distribution files for the gas-optics tests (cache outside the source tree); without
# them test_gas_optics fails and says so, the other tests still run.
bash scripts/fetch-rrtmgp.sh || echo "test.sh: RRTMGP files not fetched; test_gas_optics will fail"

total_passed=0
total_failed=0
status=0
summaries=()

# run_suite <build type> <build dir> [extra ctest arguments...]
run_suite() {
  local build_type=$1 build_dir=$2 log line failed total
  shift 2   # the rest: extra ctest arguments
  echo "=== ${build_type}: build ==="
  if ! bash scripts/build.sh "$build_type"; then
    echo "=== ${build_type}: build FAILED ==="
    summaries+=("${build_type}: build failed")
    total_failed=$((total_failed + 1))
    status=1
    return
  fi

  echo "=== ${build_type}: ctest ==="
  log=$(mktemp)
  (cd "$build_dir" && ctest --output-on-failure --no-tests=error -j "${KUMO_TEST_JOBS:-2}" "$@") 2>&1 | tee "$log"
  if ((PIPESTATUS[0] != 0)); then
    status=1
  fi

  # ctest's summary: "92% tests passed, 1 tests failed out of 12"
  line=$(grep -E 'tests passed, [0-9]+ tests? failed out of [0-9]+' "$log" | tail -n 1)
  rm -f "$log"
  if [[ $line =~ ([0-9]+)\ tests?\ failed\ out\ of\ ([0-9]+) ]]; then
    failed=${BASH_REMATCH[1]}
    total=${BASH_REMATCH[2]}
    total_passed=$((total_passed + total - failed))
    total_failed=$((total_failed + failed))
    summaries+=("${build_type}: $((total - failed)) passed, ${failed} failed")
  else
    echo "=== ${build_type}: no ctest summary found ==="
    summaries+=("${build_type}: ctest did not report a summary")
    total_failed=$((total_failed + 1))
    status=1
  fi
}

run_suite Release build
run_suite Debug build-debug
run_suite Serial build-serial -LE bench

# The serial build and the MPI build must give the same per-batch results for the same case.
echo "=== serial vs MPI build ==="
cmp_dir=$(mktemp -d)
if [[ -x build/kumo && -x build-serial/kumo ]] &&
  (cd "$cmp_dir" && cp "$OLDPWD/tests/regression/data/compare_builds.nml" . &&
    "$OLDPWD/build/kumo" compare_builds.nml > /dev/null &&
    mv compare_builds.nc mpi.nc &&
    "$OLDPWD/build-serial/kumo" compare_builds.nml > /dev/null &&
    ncdump -v batch_reflectance,batch_transmittance,batch_absorptance mpi.nc | sed 1d | grep -v -E 'wall_time|cpu_time|setup_time|history|:parallel' > a.txt &&
    ncdump -v batch_reflectance,batch_transmittance,batch_absorptance compare_builds.nc | sed 1d | grep -v -E 'wall_time|cpu_time|setup_time|history|:parallel' > b.txt &&
    diff a.txt b.txt > /dev/null); then
  echo "serial and MPI builds agree batch by batch"
  summaries+=("serial vs MPI: 1 passed, 0 failed")
  total_passed=$((total_passed + 1))
else
  echo "serial and MPI builds DIFFER (or did not run)"
  summaries+=("serial vs MPI: 0 passed, 1 failed")
  total_failed=$((total_failed + 1))
  status=1
fi
rm -rf "$cmp_dir"

echo "=== summary ==="
for s in "${summaries[@]}"; do
  echo "$s"
done
if ((total_failed > 0)); then
  status=1
fi
echo "${total_passed} passed, ${total_failed} failed"
exit "$status"
