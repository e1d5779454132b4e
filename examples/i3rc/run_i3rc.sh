#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Run the I3RC Phase 1 cases with kumo (see examples/i3rc/README.md).
#
#   bash examples/i3rc/run_i3rc.sh [--case N] [--exp N] [--mode f3d|ica|p3d] [--p3d-orders N]
#                                  [--photons N] [--batches N] [--seed N] [--data DIR]
#
# Works from any directory. The options go to i3rc_cases.py, which writes the scene files and
# namelists into examples/i3rc/run/ (default: every case and experiment, mode f3d). Then
# build/kumo runs each namelist inside run/ (one process at a time; log in <name>.log), the wall
# time of every run is appended to run/timings.txt, and plot_i3rc.py writes <name>_summary.txt
# and <name>.png for every new output, F3D-versus-ICA (or -P3D) comparisons where both outputs
# exist, and run/summary.md, a table of the domain means of every output in run/.
# Input: examples/data/i3rc_phase1 (in the repository; source and licence in its README).
# Environment: KUMO (the kumo program, default build/kumo), PYTHON (default python3).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
kumo="${KUMO:-$repo/build/kumo}"
python="${PYTHON:-python3}"
run_dir="$here/run"

for arg in "$@"; do
  case $arg in
    -h | --help)
      awk 'NR > 2 && !/^#/ { exit } NR > 2 { sub(/^# ?/, ""); print }' "${BASH_SOURCE[0]}"
      echo
      "$python" "$here/i3rc_cases.py" --help
      exit 0
      ;;
    --run-dir | --run-dir=* | --list)
      echo "run_i3rc: $arg is not supported here; the runs go to $run_dir" >&2
      exit 2
      ;;
  esac
done

if [[ ! -x $kumo ]]; then
  echo "run_i3rc: $kumo not found or not executable; build kumo first: bash scripts/build.sh" >&2
  exit 1
fi
PYTHON="$python" bash "$repo/scripts/install-deps.sh" --python

"$python" "$here/i3rc_cases.py" "$@"
mapfile -t namelists < <("$python" "$here/i3rc_cases.py" "$@" --list)

cd "$run_dir"
outputs=()
for nml in "${namelists[@]}"; do
  name="${nml%.nml}"
  echo "=== kumo $nml"
  start=$(date +%s.%N)
  if ! "$kumo" "$nml" >"$name.log" 2>&1; then
    echo "run_i3rc: kumo failed on $nml; last lines of $run_dir/$name.log:" >&2
    tail -n 5 "$name.log" >&2
    exit 1
  fi
  end=$(date +%s.%N)
  wall=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.2f", b - a }')
  photons=$(sed -n 's/^photons \([0-9]*\) .*/\1/p' "$name.log")
  printf '%s  %-22s photons %-10s wall %8s s\n' "$(date '+%Y-%m-%dT%H:%M:%S')" "$nml" \
    "$photons" "$wall" | tee -a timings.txt
  outputs+=("$name.nc")
done

echo "=== plot_i3rc.py"
"$python" "$here/plot_i3rc.py" "${outputs[@]}"

# F3D against ICA or P3D where both outputs of a case and experiment exist
for out in "${outputs[@]}"; do
  base="${out%_*}"          # case<c>_exp<e>
  mode="${out##*_}"
  mode="${mode%.nc}"
  if [[ $mode == f3d ]]; then
    others=("$base"_ica.nc)
  else
    others=("$out")
  fi
  for other in "${others[@]}"; do
    if [[ $other != "$base"_f3d.nc && -f $other && -f "$base"_f3d.nc ]]; then
      "$python" "$here/plot_i3rc.py" --quiet "$base"_f3d.nc --compare "$other"
      echo "wrote ${base}_f3d_vs_${other%.nc}.png and _summary.txt"
    fi
  done
done

# table of every output in the run folder
shopt -s nullglob
all=(case*_exp*_*.nc)
rm -f summary.md
if ((${#all[@]} > 0)); then
  "$python" "$here/plot_i3rc.py" --quiet --no-plot --markdown summary.md "${all[@]}"
  echo "wrote $run_dir/summary.md"
fi
