#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Where the time of a kumo run goes, by the clock: `perf record -e cpu-clock` samples the
# program (no hardware counters needed, so it works in virtual machines), and the report lists
# the procedures and the source lines that hold the most samples. Instruction counts
# (callgrind_loop.sh) miss time spent waiting for memory: a random read of a table that does
# not fit the cache costs one instruction and may cost a hundred cycles
# (docs/performance.md, sampling tabulated phase functions from the cache).
#
#   bash bench/clock_profile.sh KUMO CASE.nml [N_LINES]
#
# Build KUMO with line tables for the source lines (a Release build configured with
# -DCMAKE_Fortran_FLAGS=-g). Run it where CASE.nml's input and output paths resolve. Samples
# land on the instruction that waits, often the one after a slow read: read a line's share
# together with the lines just before it.
set -euo pipefail
(($# >= 2)) || { echo "usage: clock_profile.sh KUMO CASE.nml [N_LINES]" >&2; exit 2; }
kumo=$1 case_nml=$2 nlines=${3:-30}
command -v perf > /dev/null || { echo "clock_profile: perf is needed (Debian: linux-perf)" >&2; exit 1; }
data=$(mktemp)
trap 'rm -f "$data"' EXIT
perf record -q -e cpu-clock -F 5000 -o "$data" "$kumo" "$case_nml" > /dev/null
echo "# procedures (share of all samples)"
perf report -i "$data" --no-children --sort sym 2> /dev/null | grep -v '^#' | grep . |
  head -n 15 || true
echo "# source lines (share of all samples)"
perf report -i "$data" --no-children --sort srcline 2> /dev/null | grep -v '^#' | grep . |
  head -n "$nlines" || true
