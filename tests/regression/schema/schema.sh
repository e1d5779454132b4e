#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Output-schema check: run kumo on the small cases of this folder (a 1-D solar slab with
# radiances, a 3-D LES cloud with maps and a camera, a thermal column) and compare the layout
# of each output file, not its values, with the listing recorded in schema.txt: dimensions
# and their sizes, every variable with its type, dimensions and attributes (units, long_name,
# ...), and the names of the global attributes (their values are the run's: configuration,
# notes, build and times). A difference is shown as a unified diff of the listings.
#
#   schema.sh KUMO CASE_DIR DATA_DIR
#
# The cases run in ./schema_work with few photons; DATA_DIR holds the CDL of the LES cloud.
# A change to the output (a new variable, other units or attributes) records the listing anew
# with KUMO_UPDATE_SCHEMA=1 ctest -R schema, documents it in docs/output.md, and says why in
# its commit; golden fingerprints of the header change with it (tests/regression/golden).
set -euo pipefail
kumo=$1 case_dir=$2 data_dir=$3
cases=(solar_1d cloud_3d thermal)
work=schema_work
rm -rf "$work"
mkdir -p "$work"
cd "$work"
ncgen -o cloud_les_small.nc "$data_dir/cloud_les_small.cdl"
: > schema.txt
for case in "${cases[@]}"; do
  cp "$case_dir/$case.nml" .
  "$kumo" "$case.nml" > "$case.log" 2>&1 || { echo "schema: kumo failed on $case:" >&2; cat "$case.log" >&2; exit 1; }
  # one statement per line (ncdump continues long strings on further lines), then: global
  # attributes by name only, everything else as ncdump writes it
  ncdump -h "$case.nc" | awk -v name="$case" '
    NR == 1 { print "== " name " =="; next }
    /^}/ { next }
    { line = (cont ? line " " : "") $0; cont = 1 }
    line ~ / ;$/ || line ~ /^[a-z ]*:$/ || line ~ /^\/\/ / || line ~ /^$/ {
      if (line ~ /^\t\t:/) { sub(/ = .*/, "", line) }
      print line
      cont = 0
    }
  ' >> schema.txt
done
recorded="$case_dir/schema.txt"
if [[ ${KUMO_UPDATE_SCHEMA:-0} == 1 ]]; then
  cp schema.txt "$recorded"
  echo "schema: recorded the output layout of ${#cases[@]} cases in $recorded"
  exit 0
fi
if ! diff -u -F "^== " "$recorded" schema.txt > schema.diff; then
  echo "schema: the output layout differs from $recorded (- recorded, + this build):" >&2
  cat schema.diff >&2
  echo "If the change is meant: KUMO_UPDATE_SCHEMA=1 ctest -R schema, and docs/output.md." >&2
  exit 1
fi
echo "schema: the output layout of ${#cases[@]} cases matches $recorded"
