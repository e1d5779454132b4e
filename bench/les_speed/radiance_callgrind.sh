#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Instructions per photon of the photon loop with radiances on (trace_batch and everything it
# calls; setup and output excluded), counted by valgrind's callgrind, on the radiance workloads
# of run_les_speed.py: the I3RC LES stratocumulus at 2.13 um, SZA 60, black surface, TOA
# radiances at nadir, 60 degrees forward and the hot spot, with the 'standard' and the
# 'unbiased' preset (4 batches of 4096 photons, seed 7). Also prints, per photon, the calls of
# the procedures that LTO leaves out of line (level estimates, phase-function evaluations, layer
# segments of lines of sight), which count the work of the local estimates; a procedure that a
# build inlines shows 0 calls, so compare call counts only between builds that inline alike.
#
#   bash bench/les_speed/radiance_callgrind.sh SHARED [KUMO ...]   (default: build/kumo)
#
# SHARED is the folder holding data/i3rc/les_examples/les_stcu_w213.prp.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
(($# > 0)) || { echo "usage: radiance_callgrind.sh SHARED [KUMO ...]" >&2; exit 2; }
prp="$(cd "$1" && pwd)/data/i3rc/les_examples/les_stcu_w213.prp"
shift
(($# > 0)) || set -- "$repo/build/kumo"
kumos=()
for k in "$@"; do kumos+=("$(cd "$(dirname "$k")" && pwd)/$(basename "$k")"); done
command -v valgrind > /dev/null || { echo "radiance_callgrind: valgrind is needed" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
ln -s "$prp" les.prp
n=16384
for preset in standard unbiased; do
  cat > "$preset.nml" <<NML
&kumo_control n_photons_per_batch = 4096, n_batches = 4, seed = 7, verbose = 0 /
&kumo_cloud cloud_file = 'les.prp', cloud_format = 'prp' /
&kumo_source sza_deg = 60.0, phi0_deg = 0.0 /
&kumo_surface albedo = 0.0 /
&kumo_output file = '$preset.nc', column_fluxes = .false., voxel_absorption = .false. /
&kumo_radiance rad_mu = 1.0, 0.5, 0.5, rad_phi_deg = 0.0, 0.0, 180.0 /
&kumo_vr vr_preset = '$preset' /
NML
done
for kumo in "${kumos[@]}"; do
  for preset in standard unbiased; do
    valgrind --tool=callgrind --callgrind-out-file="cg.$preset" --toggle-collect='*trace_batch*' \
      "$kumo" "$preset.nml" > /dev/null 2>&1
    python3 - "cg.$preset" "$n" "$kumo" "$preset" <<'PY'
import re, sys, collections
names, calls, total = {}, collections.Counter(), 0
for line in open(sys.argv[1]):
    m = re.match(r"^c?fn=\((\d+)\)(?: (.*))?", line)
    if m:
        if m.group(2):
            names[m.group(1)] = m.group(2)
        if line.startswith("cfn="):
            callee = names[m.group(1)]
        continue
    m = re.match(r"^calls=(\d+)", line)
    if m:
        calls[callee.split("_MOD_")[-1].split(".")[0]] += int(m.group(1))
    m = re.match(r"^summary: (\d+)", line)
    if m:
        total = int(m.group(1))
n = float(sys.argv[2])
keys = ["le_particle", "level_estimate", "layer_segment", "phase_eval", "fly_3d"]
print(f"{sys.argv[3]} {sys.argv[4]}: {total / n:.0f} instructions per photon; calls per photon: "
      + ", ".join(f"{k} {calls[k] / n:.1f}" for k in keys))
PY
  done
done
