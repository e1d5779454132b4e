#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Time walk_interleave.f90 with one and with two photons in flight, side by side (A B B A, three
# rounds) on fields of 128^2, 256^2 and 512^2 columns x 20 layers (1.3, 5.2 and 21 MB of
# extinction), and print the median time per photon and the median ratio two/one per grid.
#
#   bash bench/interleave/run_interleave.sh [PHOTONS]     (default 300000 per run)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
n_phot=${1:-300000}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
gfortran -O3 -funroll-loops -march=x86-64-v2 "$here/walk_interleave.f90" -o "$work/wi" -J "$work"
for round in 1 2 3; do
  for n in 128 256 512; do
    for k in 1 2 2 1; do
      "$work/wi" "$n" "$k" "$n_phot"
    done
  done
done > "$work/runs.txt"
python3 - "$work/runs.txt" <<'PY'
import re, statistics, sys
runs = {}
order = []
for line in open(sys.argv[1]):
    m = re.match(r"N\s+(\d+) K\s+(\d+) ns/photon\s+([\d.]+)", line)
    key = (int(m[1]), int(m[2]))
    runs.setdefault(key, []).append(float(m[3]))
print("| columns | one photon [ns/photon] | two in turn [ns/photon] | two / one: median (range) |")
print("|---|---|---|---|")
for n in (128, 256, 512):
    a, b = runs[(n, 1)], runs[(n, 2)]
    r = [y / x for x, y in zip(a, b)]
    print(f"| {n}^2 | {statistics.median(a):.0f} | {statistics.median(b):.0f} | "
          f"{statistics.median(r):.3f} ({min(r):.3f}-{max(r):.3f}) |")
PY
