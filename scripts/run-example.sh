#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Install what is missing, build kumo (Release) and run one of the shipped examples:
#   bash scripts/run-example.sh [hg_slab|les_stcu|mcarats_les05|i3rc|broadband]
# hg_slab (default): build/kumo examples/hg_slab/hg_slab.nml (7 s of CPU time)
# les_stcu:          examples/les_stcu/run_les_stcu.sh (30 s)
# mcarats_les05:     examples/mcarats_les05/run_mcarats_les05.sh (27 s)
# i3rc:              examples/i3rc/run_i3rc.sh --case 1 (30 s; the other cases: see its README)
# broadband:         examples/broadband/cloudy_column_sw.nml and _lw.nml (1 s each), after
#                    scripts/fetch-rrtmgp.sh (the RRTMGP k-distributions, a 57 MB download once)
# Every other example reads only files of the repository (its inputs are in examples/data).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

example=${1:-hg_slab}
case $example in
  hg_slab) need=examples/hg_slab/hg_slab.nml ;;
  les_stcu | mcarats_les05) need=examples/$example/run_$example.sh ;;
  i3rc) need=examples/i3rc/run_i3rc.sh ;;
  broadband) need=examples/broadband/cloudy_column_sw.nml ;;
  *)
    echo "usage: bash scripts/run-example.sh [hg_slab|les_stcu|mcarats_les05|i3rc|broadband]" >&2
    exit 2
    ;;
esac
if [[ ! -f $need ]]; then
  echo "run-example: $need not found; this checkout does not contain the example" >&2
  exit 1
fi

bash scripts/install-deps.sh
bash scripts/build.sh Release
echo "=== $example"
case $example in
  hg_slab) build/kumo "$need" ;;
  i3rc) bash "$need" --case 1 ;;
  broadband)
    bash scripts/fetch-rrtmgp.sh
    build/kumo examples/broadband/cloudy_column_sw.nml
    build/kumo examples/broadband/cloudy_column_lw.nml
    ;;
  *) bash "$need" ;;
esac
