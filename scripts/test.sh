#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Install what is missing, then build and run the test suite in three configurations:
# Release (build/) runs the whole suite; Debug (build-debug/, run-time checks and FP traps)
# and the serial build without MPI (build-serial/) run all but the `bench` label (the serial
# build's physics is the Release build's; what differs is the parallel layer, which the other
# labels and the batch-by-batch comparison of the serial and MPI builds that follows cover).
# Then the Python package's pytest tests run against the Release build. All runs always
# happen; the script exits non-zero if any fails. The last line is the total over all runs,
# "N passed, N failed". A configuration that does not build counts as one failed test.
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
# The Debug build is there for its run-time checks and floating-point traps, not to repeat the
# long accuracy studies of the bench label at -O0 (some took minutes and ran past their
# timeouts on a loaded machine): it runs the unit, stat, mpi and regression labels, which trace
# whole batches too (test_batch, the examples and command-line runs, the bad inputs).
run_suite Debug build-debug -LE bench
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

# The Python package (python/): install it where it cannot disturb the user's Python
# (build/python-site, with pip as `pip install ./python` would), then run its pytest tests
# against the Release build. Each test counts; pytest exiting without a summary (no tests
# collected: exit status 5, or a crash) counts as one failure.
echo "=== Python package: pytest ==="
python="${PYTHON:-python3}"
repo=$PWD
site="$repo/build/python-site"
log=$(mktemp)
if bash scripts/install-deps.sh --python &&
  rm -rf "$site" &&
  PIP_ROOT_USER_ACTION=ignore "$python" -m pip install --quiet --no-deps --target "$site" ./python; then
  (cd python && PYTHONPATH="$site" KUMO_EXE="$repo/build/kumo" \
    "$python" -m pytest -p no:cacheprovider -q -rs tests) 2>&1 | tee "$log"
  rc=${PIPESTATUS[0]}
else
  echo "=== Python package: installation FAILED ==="
  rc=-1
fi
line=$(grep -E '^=*[ ]*[0-9]+ (passed|failed|error)' "$log" | tail -n 1)
rm -f "$log"
py_passed=0
py_failed=0
[[ $line =~ ([0-9]+)\ passed ]] && py_passed=${BASH_REMATCH[1]}
[[ $line =~ ([0-9]+)\ failed ]] && py_failed=${BASH_REMATCH[1]}
[[ $line =~ ([0-9]+)\ errors? ]] && py_failed=$((py_failed + BASH_REMATCH[1]))
if ((rc != 0 && py_failed == 0)); then
  py_failed=1   # no tests run, or pytest or the installation broke down
fi
summaries+=("pytest: ${py_passed} passed, ${py_failed} failed")
total_passed=$((total_passed + py_passed))
total_failed=$((total_failed + py_failed))
((rc != 0)) && status=1

echo "=== summary ==="
for s in "${summaries[@]}"; do
  echo "$s"
done
if ((total_failed > 0)); then
  status=1
fi
echo "${total_passed} passed, ${total_failed} failed"
exit "$status"
