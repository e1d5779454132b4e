#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The I3RC LES stratocumulus (i3rc_les_stcu.lwc) straight from its LWC file, with kumo's Mie
# optics, at 0.67 and 2.13 um: fluxes, heating rates and a nadir radiance image
# (see examples/les_stcu/README.md).
#
#   bash examples/les_stcu/run_les_stcu.sh [photons per batch, default 100000]
#
# Environment: KUMO (the kumo program, default build/kumo), KUMO_SHARED_DIR (the shared data
# folder, default: `shared` next to the repository). Output goes to examples/les_stcu/run/.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
kumo="${KUMO:-$repo/build/kumo}"
shared="${KUMO_SHARED_DIR:-$repo/../shared}"
lwc="$(cd "$shared/data/i3rc/les_examples" && pwd)/i3rc_les_stcu.lwc"
photons="${1:-100000}"
mkdir -p "$here/run"
cd "$here/run"

for wl in 0.67 2.13; do
  tag="${wl/./}"
  # Rayleigh scattering is defined for 0.23-1.69 um; at 2.13 um its optical depth over the
  # lowest kilometre is below 1e-4 and is left out.
  rayleigh=".true."
  [ "$wl" = "2.13" ] && rayleigh=".false."
  cat > "les_stcu_${tag}.nml" <<NML
! I3RC LES stratocumulus at ${wl} um, optics computed by kumo from LWC and r_eff.
&kumo_control n_photons_per_batch = ${photons}, n_batches = 20 /
&kumo_atmosphere rayleigh = ${rayleigh} /
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
&kumo_output file = 'les_stcu_${tag}.nc' /
NML
  echo "== les_stcu_${tag}.nml"
  "$kumo" "les_stcu_${tag}.nml" | sed -n '/^Rayleigh\|^cloud file\|^the file\|^Mie\|^photons/,$p'
done
