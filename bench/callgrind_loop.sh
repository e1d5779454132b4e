#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Instructions spent in the photon loop (trace_batch and everything it calls; setup and output
# excluded) for four cases, counted by valgrind's callgrind: repeatable whatever else the machine
# does, so two builds can be compared without timing noise.
#
#   bash bench/callgrind_loop.sh [KUMO ...]     (default: build/kumo)
#
# Cases: the HG slab with fluxes only and with four radiances (2e4 photons), the I3RC Landsat
# cloud on 20 layers (1e4 photons, fluxes), the I3RC LES stratocumulus at 2.13 um with nadir and
# 60-degree radiances and the standard preset (4e3 photons), the same stratocumulus with fluxes
# only (les_flux: SZA 60, black surface, default preset, 8192 photons) and the MCARaTS LES05
# scene at SZA 0 with fluxes and voxel absorption (les05_flux, 7200 photons, namelist written by
# examples/mcarats_les05/run_mcarats_les05.sh). Inputs come from examples/data.
# Prints one line per build and case: the build, the case, the instruction count.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
(($# > 0)) || set -- "$repo/build/kumo"
command -v valgrind > /dev/null || { echo "callgrind_loop: valgrind is needed" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"

slab='&kumo_atmosphere nz = 1, z_levels = 0.0, 1000.0, lx = 1000.0, ly = 1000.0,
  ext1d(1,1) = 0.01, ssa1d(1,1) = 0.999, phase1d(1,1) = 1 /
&kumo_phase n_phase = 1, phase_kind = '"'hg'"', phase_g = 0.85 /
&kumo_surface albedo = 0.0 /
&kumo_source sza_deg = 30.0 /'
printf '%s\n%s\n%s\n' '&kumo_control n_photons_per_batch = 10000, n_batches = 2, seed = 1 /' \
  "$slab" "&kumo_output file = 'slab_flux.nc' /" > slab_flux.nml
printf '%s\n%s\n%s\n%s\n' '&kumo_control n_photons_per_batch = 10000, n_batches = 2, seed = 1 /' \
  "$slab" "&kumo_output file = 'slab_rad.nc' /" \
  '&kumo_radiance rad_mu = 1.0, 0.5, 0.5, -0.5, rad_phi_deg = 0.0, 0.0, 180.0, 0.0 /' \
  > slab_rad.nml

python3 "$repo/bench/make_landsat_scene.py" --data "$repo/examples/data/i3rc_phase1" \
  --out landsat.nc --atm-group atm.txt > /dev/null
{
  echo '&kumo_control n_photons_per_batch = 5000, n_batches = 2, seed = 1 /'
  cat atm.txt
  echo "&kumo_phase n_phase = 1, phase_kind = 'hg', phase_g = 0.85 /"
  echo '&kumo_surface albedo = 0.0 /'
  echo '&kumo_source sza_deg = 60.0 /'
  echo "&kumo_output file = 'landsat_out.nc' /"
} > landsat.nml

ln -s "$repo/examples/data/i3rc_les/i3rc_les_stcu.lwc" .
cat > les_rad.nml <<'NML'
&kumo_control n_photons_per_batch = 2000, n_batches = 2, seed = 3 /
&kumo_cloud cloud_file = 'i3rc_les_stcu.lwc', cloud_format = 'lwc',
  size_distribution = 'gamma', v_eff = 0.1, reff_min_um = 2.0, reff_max_um = 30.0, n_reff = 8,
  mie_cache = 'mie_213.nc' /
&kumo_source sza_deg = 60.0, phi0_deg = 20.0, wavelength_um = 2.13, solar_flux = 1.0 /
&kumo_surface albedo = 0.05 /
&kumo_output file = 'les_rad.nc' /
&kumo_radiance rad_mu = 1.0, 0.5, rad_phi_deg = 0.0, 200.0 /
&kumo_vr vr_preset = 'standard' /
NML

cat > les_flux.nml <<'NML'
&kumo_control n_photons_per_batch = 4096, n_batches = 2, seed = 7 /
&kumo_cloud cloud_file = 'i3rc_les_stcu.lwc', cloud_format = 'lwc',
  size_distribution = 'gamma', v_eff = 0.1, reff_min_um = 2.0, reff_max_um = 30.0, n_reff = 8,
  mie_cache = 'mie_213.nc' /
&kumo_source sza_deg = 60.0, wavelength_um = 2.13, solar_flux = 1.0 /
&kumo_surface albedo = 0.0 /
&kumo_output file = 'les_flux.nc', column_fluxes = .false., voxel_absorption = .false. /
NML

KUMO="$1" KUMO_RUN_DIR="$work" bash "$repo/examples/mcarats_les05/run_mcarats_les05.sh" 1000 \
  > /dev/null 2>&1
sed -e 's|&kumo_control[^/]*/|\&kumo_control n_photons_per_batch = 3600, n_batches = 2, seed = 5 /|' \
  -e "s|\(&kumo_output *file = '\)[^']*'|\1les05_flux.nc'|" les05_sza0.nml > les05_flux.nml

for kumo in "$@"; do
  "$kumo" les_rad.nml > /dev/null   # the Mie cache, so that no run below computes it
  for c in slab_flux slab_rad landsat les_rad les_flux les05_flux; do
    valgrind --tool=callgrind --callgrind-out-file="cg.$c" --toggle-collect='*trace_batch*' \
      "$kumo" "$c.nml" > /dev/null 2> "cg.$c.log"
    echo "$kumo $c $(sed -n 's/^\(summary\|totals\): *//p' "cg.$c" | head -n 1)"
  done
done
