#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Install what is missing, build kumo (Release) and run the shipped example:
#   build/kumo examples/hg_slab/hg_slab.nml
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

namelist=examples/hg_slab/hg_slab.nml
if [[ ! -f $namelist ]]; then
  echo "run-example: $namelist not found; this checkout does not contain the example" >&2
  exit 1
fi

bash scripts/install-deps.sh
bash scripts/build.sh Release
echo "=== build/kumo $namelist ==="
build/kumo "$namelist"
