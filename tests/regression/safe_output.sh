#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The temporary output file is never followed through a symbolic link: with <output>.tmp a link
# to another file (planted, or left by anything), kumo must leave that file untouched, write its
# output, and leave no temporary file behind. A stale <output>.tmp of a killed run is removed.
#   safe_output.sh KUMO
set -euo pipefail
kumo=$1
work=safe_output_work
rm -rf "$work"
mkdir -p "$work"
cd "$work"
cat > case.nml <<'NML'
&kumo_control n_photons_per_batch = 200, n_batches = 2, verbose = 0 /
&kumo_atmosphere nz = 1, z_levels = 0.0, 1000.0, ext1d(1,1) = 0.001, ssa1d(1,1) = 1.0 /
&kumo_output file = 'out.nc' /
NML
echo "precious" > victim.txt
ln -s victim.txt out.nc.tmp
"$kumo" case.nml > run.log 2>&1 || { cat run.log; echo "kumo failed"; exit 1; }
if [[ $(cat victim.txt) != precious ]]; then
  echo "FAIL: the file behind the link out.nc.tmp was changed"
  exit 1
fi
[[ -f out.nc && ! -L out.nc ]] || { echo "FAIL: out.nc was not written as a file"; exit 1; }
[[ ! -e out.nc.tmp && ! -L out.nc.tmp ]] || { echo "FAIL: out.nc.tmp left behind"; exit 1; }
# a stale temporary file (a run killed while writing) is replaced, not an error
echo "stale" > out.nc.tmp
"$kumo" case.nml > run.log 2>&1 || { cat run.log; echo "kumo failed on a stale .tmp"; exit 1; }
[[ ! -e out.nc.tmp ]] || { echo "FAIL: stale out.nc.tmp left behind"; exit 1; }
ncdump -h out.nc > /dev/null
echo "safe output: link not followed, stale temporary file replaced"
