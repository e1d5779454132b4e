#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# kumo performance benchmark: run on demand, not in CI (about 7-12 minutes on 2 cores).
#
#   bash bench/run_bench.sh                 # build (Release), run every part, analyse
#   bash bench/run_bench.sh --quick         # tiny photon counts: checks that everything runs;
#                                           # results go to bench/results/raw/quick/ only
#   bash bench/run_bench.sh --parts fom,mpi # redo some parts (fom, target, resolution,
#                                           # callgrind, cachesim, mpi); the other parts
#                                           # keep the results of the last run
#   bash bench/run_bench.sh --analyse-only  # redo tables and plots from the last run log
#
# Environment:
#   KUMO_BIN          use this kumo program instead of building one
#   KUMO_BENCH_BUILD  build folder (default: build-bench in the repository)
#   KUMO_SHARED_DIR   folder that holds data/i3rc/phase1_inputs (the I3RC Landsat field);
#                     default: the folder "shared" next to the repository
#   MPIRUN            MPI launcher without -np (default: mpirun --allow-run-as-root --oversubscribe)
#
# Results: bench/results/*.csv, bench/results/summary.md, docs/figures/fom_<case>.png.
# Namelists, outputs and the run log go to bench/results/raw/ (not kept in git).
# Timings depend on the load of the machine: the load average is recorded with every run, and
# the bars are judged on ratios of runs made side by side.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
repo=$(dirname "$here")
quick=()
dirs=()
parts=fom,target,resolution,callgrind,cachesim,mpi
analyse_only=0
while [[ $# -gt 0 ]]; do
  case $1 in
    --quick)
      quick=(--quick)
      q=$here/results/raw/quick
      dirs+=(--raw "$q") ;;
    --parts) parts=$2; dirs+=(--append); shift ;;  # replaces these parts of the last run
    --analyse-only) analyse_only=1 ;;
    -h | --help) sed -n "2,23p" "${BASH_SOURCE[0]}"; exit 0 ;;
    *) echo "run_bench.sh: unknown argument $1" >&2; exit 2 ;;
  esac
  shift
done

# Python packages of the scripts (scene writer, output reader, plots).
bash "$here/../scripts/install-deps.sh" --python

if [[ $analyse_only -eq 0 ]]; then
  if [[ -n ${KUMO_BIN:-} ]]; then
    kumo=$KUMO_BIN
  else
    build=${KUMO_BENCH_BUILD:-$repo/build-bench}
    cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF >/dev/null
    cmake --build "$build" -j 2 >/dev/null
    kumo=$build/kumo
    # the commit the program was built from ("+": src/ had local changes)
    if commit=$(git -C "$repo" rev-parse --short HEAD 2>/dev/null); then
      [[ -n $(git -C "$repo" status --porcelain --untracked-files=no src) ]] && commit+=+
      dirs+=(--commit "$commit")
    fi
  fi
  [[ -x $kumo ]] || { echo "run_bench.sh: no kumo program at $kumo" >&2; exit 1; }

  shared=${KUMO_SHARED_DIR:-$(dirname "$repo")/shared}
  data=$shared/data/i3rc/phase1_inputs
  [[ -f $data/scene43.tau.128x128 ]] || {
    echo "run_bench.sh: I3RC Landsat field not found in $data (set KUMO_SHARED_DIR)" >&2; exit 1; }

  mpi_launcher=${MPIRUN:-mpirun}
  if [[ ,$parts, == *,mpi,* ]] && ! command -v "${mpi_launcher%% *}" >/dev/null 2>&1; then
    echo "run_bench.sh: mpirun not found, the mpi part is skipped"
    parts=$(echo ",$parts," | sed 's/,mpi,/,/; s/^,//; s/,$//')
  fi

  echo "run_bench.sh: $(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | cut -d: -f2 | sed 's/^ //')," \
    "$(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null)"
  start=$(date +%s)
  python3 "$here/run_cases.py" --kumo "$kumo" --data "$data" --parts "$parts" \
    --mpirun "${MPIRUN:-mpirun --allow-run-as-root --oversubscribe}" "${quick[@]}" "${dirs[@]}"
  echo "run_bench.sh: runs took $(( $(date +%s) - start )) s"
fi

if [[ ${#quick[@]} -gt 0 ]]; then
  python3 "$here/analyse_bench.py" --raw "$q" --results "$q" --figures "$q"
  echo "run_bench.sh: quick results (not measurements) in bench/results/raw/quick/"
else
  python3 "$here/analyse_bench.py"
  echo "run_bench.sh: tables in bench/results/, summary in bench/results/summary.md," \
    "plots in docs/figures/"
fi
