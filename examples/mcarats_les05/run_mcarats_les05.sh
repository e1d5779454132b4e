#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The MCARaTS example LES scene (les05_0213.atm + .sca, 2.13 um) read from MCARaTS's own files,
# with the 1-D profiles of its flux case conf_hr0213 translated into kumo's namelist: fluxes at
# the surface and the top and the absorption of every layer, for the sun at 0 and 60 degrees
# over a Lambert surface of albedo 0.2 (see examples/mcarats_les05/README.md).
#
#   bash examples/mcarats_les05/run_mcarats_les05.sh [photons per batch, default 100000]
#
# Input: examples/data/mcarats_les05/ (in the repository; source and licence in its README).
# Environment: KUMO (the kumo program, default build/kumo), KUMO_RUN_DIR (the folder for the
# namelists and outputs, default examples/mcarats_les05/run/).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
kumo="${KUMO:-$repo/build/kumo}"
data="$repo/examples/data/mcarats_les05"
if [[ ! -x $kumo ]]; then
  echo "run_mcarats_les05: $kumo not found or not executable; build kumo first:" \
    "bash scripts/build.sh" >&2
  exit 1
fi
for f in les05_0213.atm les05_0213.atm.ctl les05_0213.sca les05_0213.sca.ctl; do
  if [[ ! -f $data/$f ]]; then
    echo "run_mcarats_les05: input file $data/$f not found; this checkout lacks examples/data" >&2
    exit 1
  fi
done
photons="${1:-100000}"
run_dir="${KUMO_RUN_DIR:-$here/run}"
mkdir -p "$run_dir"
cd "$run_dir"

# The 1-D aerosol of conf_hr0213 has Atm_apf1d = 2: table 2 of the phase-function file. kumo's
# 1-D layers take phase functions from &kumo_phase, so table 2 is written as a two-column text
# table (angle, value; the records are 203 native float32 values: angles, then the tables).
od -An -v -t f4 -w812 "$data/les05_0213.sca" |
  awk 'NR == 1 { n = split($0, ang) } NR == 3 { split($0, p); for (i = 1; i <= n; i++) print ang[i], p[i] }' \
  > les05_table2.txt

# conf_hr0213, &mcarAtm_nml_job: Atm_zgrd0 (42 levels), Atm_ext1d(:,1) (molecules, Atm_omg1d 1,
# Atm_apf1d -1: Rayleigh), Atm_ext1d(:,2) (aerosol, Atm_omg1d 0.884494066, table 2) and
# Atm_abs1d(:,1) (gas absorption of the one k-term, Atm_wkd0 = 1), bottom layer first.
levels="0.0, 30.0, 60.0, 90.0, 120.0, 150.0, 180.0, 210.0, 230.0, 250.0, 260.0, 270.0, 280.0,
  290.0, 300.0, 310.0, 320.0, 330.0, 340.0, 350.0, 360.0, 370.0, 380.0, 390.0, 400.0, 410.0,
  420.0, 430.0, 440.0, 450.0, 460.0, 600.0, 1000.0, 2000.0, 3000.0, 4000.0, 6000.0, 8000.0,
  10000.0, 15000.0, 20000.0, 30000.0"
ext_mol="4.88233E-08, 4.87134E-08, 4.85933E-08, 4.84715E-08, 4.83495E-08, 4.82266E-08,
  4.81034E-08, 4.80002E-08, 4.79180E-08, 4.78560E-08, 4.78141E-08, 4.77712E-08, 4.77271E-08,
  4.76820E-08, 4.76364E-08, 4.75903E-08, 4.75439E-08, 4.74974E-08, 4.74509E-08, 4.74042E-08,
  4.73577E-08, 4.73110E-08, 4.72629E-08, 4.72103E-08, 4.71476E-08, 4.70638E-08, 4.69514E-08,
  4.68219E-08, 4.66976E-08, 4.65964E-08, 4.61354E-08, 4.46182E-08, 4.13907E-08, 3.74059E-08,
  3.38196E-08, 2.89990E-08, 2.34198E-08, 1.87465E-08, 1.20946E-08, 5.80646E-09, 1.91461E-09"
ext_aer="7.94029438E-06, 7.82210282E-06, 7.70562747E-06, 7.59089971E-06, 7.47788954E-06,
  7.3665642E-06, 7.25689142E-06, 7.16672093E-06, 7.09538608E-06, 7.04231434E-06,
  7.00731471E-06, 6.97221913E-06, 6.93750553E-06, 6.90288743E-06, 6.86855492E-06,
  6.83422286E-06, 6.80008088E-06, 6.7662254E-06, 6.73246541E-06, 6.69889641E-06,
  6.66551705E-06, 6.63223409E-06, 6.59914167E-06, 6.56623979E-06, 6.53352936E-06,
  6.50091306E-06, 6.46848866E-06, 6.4362539E-06, 6.40411554E-06, 6.37216726E-06,
  6.13890506E-06, 5.37150254E-06, 3.81842028E-06, 2.3159896E-06, 1.40471798E-06,
  6.84385952E-07, 2.51771411E-07, 9.2621562E-08, 1.97915657E-08, 1.62458957E-09,
  7.21504592E-11"
abs_gas="1.59819E-05, 1.57612E-05, 1.56240E-05, 1.55167E-05, 1.54074E-05, 1.53020E-05,
  1.52026E-05, 1.51240E-05, 1.50600E-05, 1.50106E-05, 1.49763E-05, 1.49368E-05, 1.48906E-05,
  1.48397E-05, 1.47850E-05, 1.47272E-05, 1.46663E-05, 1.46038E-05, 1.45397E-05, 1.44738E-05,
  1.44052E-05, 1.43323E-05, 1.42521E-05, 1.41541E-05, 1.40073E-05, 1.37460E-05, 1.33383E-05,
  1.28653E-05, 1.24490E-05, 1.21707E-05, 1.15858E-05, 1.18120E-05, 9.49417E-06, 5.11318E-06,
  2.58936E-06, 1.02930E-06, 2.84544E-07, 8.73284E-08, 1.66185E-08, 2.02657E-09, 1.43051E-10"

# conf_hr0213, &mcarSrc_nml_job: two solar sources, Src_the = 180 and 120 (propagation zenith
# angles: SZA 0 and 60), Src_flx = 1 and 2 (normal to the beam: 1 W m-2 on the horizontal).
for case in "0 1.0" "60 2.0"; do
  set -- $case
  sza="$1"
  flx="$2"
  cat > "les05_sza${sza}.nml" <<NML
! MCARaTS example les05_0213 (conf_hr0213) at SZA ${sza}: fluxes and layer absorption.
&kumo_control n_photons_per_batch = ${photons}, n_batches = 20, seed = 1 /
&kumo_atmosphere
  nz = 41
  z_levels = ${levels}
  k3d_bottom = 10          ! Atm_iz3l; nx, ny, nz3 come from the .ctl
  lx = 1800.0, ly = 1800.0 ! Atm_nx x Atm_dx, Atm_ny x Atm_dy
  n_components = 3
  ext1d(1:41,1) = ${ext_mol}
  phase1d(1:41,1) = 41*1
  ext1d(1:41,2) = ${ext_aer}
  ssa1d(1:41,2) = 41*0.884494066
  phase1d(1:41,2) = 41*2
  ext1d(1:41,3) = ${abs_gas}
  ssa1d(1:41,3) = 41*0.0
/
&kumo_phase n_phase = 2, phase_kind = 'rayleigh', 'table', phase_file(2) = 'les05_table2.txt' /
&kumo_cloud
  cloud_file = '${data}/les05_0213.atm.ctl'
  cloud_format = 'mcarats'
  mcarats_phase_file = '${data}/les05_0213.sca.ctl'
/
&kumo_surface albedo = 0.2 /
&kumo_source sza_deg = ${sza}.0, solar_flux = ${flx} /
&kumo_output file = 'les05_sza${sza}.nc', flux_levels = 0, 41 /
NML
  echo "== les05_sza${sza}.nml"
  "$kumo" "les05_sza${sza}.nml" | sed -n '/^cloud file/,$p'
done
