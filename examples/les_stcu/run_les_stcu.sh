#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The I3RC LES stratocumulus (i3rc_les_stcu.lwc) straight from its LWC file, with kumo's Mie
# optics, at 0.67 and 2.13 um: fluxes, heating rates and a nadir radiance image
# (see examples/les_stcu/README.md).
#
#   bash examples/les_stcu/run_les_stcu.sh [photons per batch, default 100000]
#
# Input: examples/data/i3rc_les/i3rc_les_stcu.lwc (in the repository; source and licence in its
# README). Environment: KUMO (the kumo program, default build/kumo), KUMO_RUN_DIR (the folder
# for the namelists, Mie tables and outputs, default examples/les_stcu/run/).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
kumo="${KUMO:-$repo/build/kumo}"
lwc="$repo/examples/data/i3rc_les/i3rc_les_stcu.lwc"
if [[ ! -x $kumo ]]; then
  echo "run_les_stcu: $kumo not found or not executable; build kumo first:" \
    "bash scripts/build.sh" >&2
  exit 1
fi
if [[ ! -f $lwc ]]; then
  echo "run_les_stcu: input file $lwc not found; this checkout lacks examples/data" >&2
  exit 1
fi
photons="${1:-100000}"
run_dir="${KUMO_RUN_DIR:-$here/run}"
mkdir -p "$run_dir"
cd "$run_dir"

# Air density of the 17 layers (the ground to 425 m, then the file's 16 layers), for the heating
# rates at 2.13 um, where no Rayleigh profile supplies it: (p_bottom - p_top) / (g0 dz) of the
# US 1976 standard atmosphere below 11 km, p = p0 (1 - L H / T0)^(g0 M / (R L)) with H the
# geopotential height, the values kumo takes itself from its Rayleigh profile at 0.67 um.
density=$(awk 'NR == 4 {
  n = split("0 " $0, z)
  for (k = 1; k <= n; k++) {
    zm = 1000 * z[k]; h = 6356766 * zm / (6356766 + zm)
    p[k] = 101325 * (1 - 0.0065 * h / 288.15) ^ 5.255877
  }
  for (k = 1; k < n; k++) {
    rho = (p[k] - p[k + 1]) / (9.80665 * 1000 * (z[k + 1] - z[k]))
    printf "%s%.6f", (k > 1 ? ", " : ""), rho
  }
}' "$lwc")

for wl in 0.67 2.13; do
  tag="${wl/./}"
  # Rayleigh scattering is defined for 0.23-1.69 um; at 2.13 um its optical depth over the
  # lowest kilometre is below 1e-4 and is left out, and the air density is given instead.
  atmosphere="rayleigh = .true."
  [ "$wl" = "2.13" ] && atmosphere="rayleigh = .false., air_density = ${density}"
  cat > "les_stcu_${tag}.nml" <<NML
! I3RC LES stratocumulus at ${wl} um, optics computed by kumo from LWC and r_eff.
&kumo_control n_photons_per_batch = ${photons}, n_batches = 20, seed = 1 /
&kumo_atmosphere ${atmosphere} /
&kumo_cloud
  cloud_file = '${lwc}'
  cloud_format = 'lwc'
  size_distribution = 'gamma', v_eff = 0.1
  reff_min_um = 2.0, reff_max_um = 30.0, n_reff = 30
  mie_cache = 'mie_${tag}.nc'
/
&kumo_source sza_deg = 60.0, wavelength_um = ${wl}, solar_flux = 1000.0 /
&kumo_surface albedo = 0.05 /
&kumo_radiance rad_mu = 1.0, rad_phi_deg = 0.0 /
! The nadir radiance image: with the default preset ('unbiased') the 64 x 64 map is dominated by
! noise at this photon budget; 'standard' (truncated forward peaks, collision forcing, map
! diffusion) gives a readable image at a small bias (docs/radiances.md).
&kumo_vr vr_preset = 'standard' /
&kumo_output file = 'les_stcu_${tag}.nc' /
NML
  echo "== les_stcu_${tag}.nml"
  "$kumo" "les_stcu_${tag}.nml" | sed -n '/^Rayleigh\|^cloud file\|^the file\|^Mie\|^photons/,$p'
done
