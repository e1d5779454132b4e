#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The examples must run from the repository alone. This checks, for the examples in
# examples/ (label regression):
#   1. no example file refers to data outside the repository (`shared/`, KUMO_SHARED_DIR);
#   2. every input file listed in examples/data/SHA256SUMS is there with its checksum;
#   3. `files`: every `examples/data/...` path named in the examples, README.md and docs/ exists;
#   4. `les_stcu`, `mcarats_les05`: the example script runs end to end with 10 photons per batch
#      (its namelists parse, its input files are found and read, kumo writes the outputs);
#   5. `i3rc`: i3rc_cases.py writes every case and experiment (column optical depths checked
#      against the published values) and kumo runs every namelist with 20 photons. Needs numpy,
#      netCDF4, xarray and f90nml for python3 (i3rc_cases.py uses the kumo package in python/);
#      without them the test is skipped (exit 77).
#
#   check_examples.sh REPO KUMO WORKDIR files|les_stcu|mcarats_les05|i3rc
set -euo pipefail
if (($# != 4)); then
  echo "usage: check_examples.sh REPO KUMO WORKDIR files|les_stcu|mcarats_les05|i3rc" >&2
  exit 2
fi
repo=$1
kumo=$2
work=$3
what=$4
fail() {
  echo "check_examples: $*" >&2
  exit 1
}

case $what in
  files)
    # 1. nothing under examples/ (outside the generated run/ folders) points at ../shared
    hits=$(grep -rIl --exclude-dir=run -e 'shared/' -e 'KUMO_SHARED_DIR' "$repo/examples" || true)
    [[ -z $hits ]] || fail "these example files refer to data outside the repository:"$'\n'"$hits"
    # 2. the shipped data and their checksums
    (cd "$repo/examples/data" && sha256sum --quiet -c SHA256SUMS) ||
      fail "examples/data does not match examples/data/SHA256SUMS"
    n=$(wc -l <"$repo/examples/data/SHA256SUMS")
    ((n > 0)) || fail "examples/data/SHA256SUMS lists no file"
    # 3. every examples/data path named in the examples and docs exists
    missing=0
    while IFS= read -r path; do
      path=${path%.}
      if [[ ! -e $repo/$path ]]; then
        echo "check_examples: $path is named but does not exist" >&2
        missing=1
      fi
    done < <(grep -rhoI --exclude-dir=run -E 'examples/data/[A-Za-z0-9_./-]+' \
      "$repo/examples" "$repo/README.md" "$repo/docs" | sort -u)
    ((missing == 0)) || exit 1
    echo "check_examples: no reference to shared data; $n data files match their checksums"
    ;;
  les_stcu | mcarats_les05)
    rm -rf "$work" && mkdir -p "$work"
    KUMO=$kumo KUMO_RUN_DIR=$work bash "$repo/examples/$what/run_$what.sh" 10 ||
      fail "examples/$what/run_$what.sh failed"
    shopt -s nullglob
    outs=("$work"/*.nc)
    nmls=("$work"/*.nml)
    ((${#nmls[@]} > 0)) || fail "$what wrote no namelist"
    for nml in "${nmls[@]}"; do
      out=$(sed -n "s/.*&kumo_output *file *= *'\([^']*\)'.*/\1/p" "$nml")
      [[ -n $out && -s $work/$out ]] || fail "$nml: output file '$out' not written"
    done
    echo "check_examples: $what ran ${#nmls[@]} namelists, ${#outs[@]} netCDF files in $work"
    ;;
  i3rc)
    if ! python3 -c 'import numpy, netCDF4, xarray, f90nml' 2>/dev/null; then
      echo "check_examples: python3 lacks numpy, netCDF4, xarray or f90nml; i3rc example not" \
        "checked" >&2
      exit 77
    fi
    rm -rf "$work" && mkdir -p "$work"
    python3 "$repo/examples/i3rc/i3rc_cases.py" --run-dir "$work" --photons 20 --batches 2 \
      --check || fail "i3rc_cases.py failed"
    mapfile -t nmls < <(python3 "$repo/examples/i3rc/i3rc_cases.py" --list)
    ((${#nmls[@]} == 15)) || fail "expected 15 I3RC namelists, got ${#nmls[@]}"
    cd "$work"
    for nml in "${nmls[@]}"; do
      "$kumo" "$nml" >"${nml%.nml}.log" 2>&1 || {
        tail -n 5 "${nml%.nml}.log" >&2
        fail "kumo failed on $nml"
      }
      [[ -s ${nml%.nml}.nc ]] || fail "$nml: no output"
    done
    # kumo --check reports the column optical depths of the I3RC step cloud as published
    # (case 2: min 6.480, mean 19.509, max 51.525; examples/i3rc/README.md)
    "$kumo" --check case2_exp1_f3d.nml >check_case2.log 2>&1 || fail "kumo --check failed on case 2"
    grep -q "optical depth of the columns: smallest 6.48, mean 19.51, largest 51.53" \
      check_case2.log || fail "kumo --check: case 2 column optical depths not as published: \
$(grep -A1 '^scene:' check_case2.log)"
    # the I3RC products (T and Id at the cloud base) can be extracted from every output
    python3 "$repo/examples/i3rc/plot_i3rc.py" --quiet --no-plot "${nmls[@]/%.nml/.nc}" ||
      fail "plot_i3rc.py could not extract the I3RC products"
    echo "check_examples: i3rc: ${#nmls[@]} namelists ran"
    ;;
  *)
    fail "unknown check $what (files, les_stcu, mcarats_les05, i3rc)"
    ;;
esac
