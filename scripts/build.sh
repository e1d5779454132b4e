#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Configure and build kumo.
#   scripts/build.sh [Release|Debug] [extra cmake options...]
# Release builds into build/, Debug into build-debug/. Example:
#   scripts/build.sh Debug -DKUMO_ENABLE_MPI=OFF
# KUMO_BUILD_JOBS sets the number of parallel build jobs (default 2).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

build_type=${1:-Release}
if (($# > 0)); then shift; fi
case $build_type in
  Release) build_dir=build ;;
  Debug) build_dir=build-debug ;;
  Serial)
    # Release without MPI: kumo_parallel is the serial stub
    build_type=Release
    build_dir=build-serial
    set -- -DKUMO_ENABLE_MPI=OFF "$@"
    ;;
  *)
    echo "usage: scripts/build.sh [Release|Debug|Serial] [cmake options...]" >&2
    exit 2
    ;;
esac

cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE="$build_type" "$@"
cmake --build "$build_dir" -j "${KUMO_BUILD_JOBS:-2}"
