#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Golden-output check: run kumo on one of the cases in this folder and compare every variable
# and attribute of the output, to the last bit, with the fingerprints recorded in <case>.sha
# (<case>.np<N>.sha for a run on N ranks: per-batch results are the same for any rank count,
# but the sums over ranks are added in another order).
#
#   golden.sh KUMO CASE_DIR CASE SHARED_DIR NP [MPIEXEC...]
#
# CASE_DIR/CASE.nml is run in a fresh working folder (./golden_CASE_npNP) on NP ranks (NP = 1:
# the program alone). Inputs it names are made there: every CASE_DIR/*.cdl becomes a netCDF
# file (ncgen), and the I3RC LES field is linked from SHARED_DIR, so that the namelist stored in
# the output holds no path of the machine. The output is dumped with ncdump at 17 digits; the
# attributes that change from run to run (times, history, rank count) are left out; each
# variable's data and the header get a SHA-256. Any difference names the variables that differ.
#
# The fingerprints pin the photon paths: a change that keeps every random number and every
# floating-point operation in order keeps them. A change that is meant to alter results
# (physics, the order in which random numbers are drawn) records new ones with
# KUMO_UPDATE_GOLDEN=1 and says why in its commit.
set -euo pipefail
kumo=$1 case_dir=$2 case=$3 shared=$4 np=$5
shift 5
work="golden_${case}_np${np}"
rm -rf "$work"
mkdir -p "$work"
cd "$work"
cp "$case_dir/$case.nml" .
for cdl in "$case_dir"/*.cdl; do
  [[ -e $cdl ]] && ncgen -o "$(basename "${cdl%.cdl}").nc" "$cdl"
done
ln -sf "$shared/data/i3rc/les_examples/i3rc_les_stcu.lwc" i3rc_les_stcu.lwc
if ((np == 1)); then
  "$kumo" "$case.nml" > run.log 2>&1 || { cat run.log; exit 1; }
else
  "$@" -n "$np" "$kumo" "$case.nml" > run.log 2>&1 || { cat run.log; exit 1; }
fi
out=$(sed -n "/&kumo_output/ s/.*[ ,]file *= *'\([^']*\)'.*/\1/p" "$case.nml" | head -n 1)
ncdump -p 17,17 "$out" |
  grep -v -E ':(history|n_ranks|parallel|wall_time_s|cpu_time_s|setup_time_s) =' > dump.cdl
# one fingerprint for the header (dimensions, variables, attributes), one per variable's data
awk -v OFS=' ' '
  /^data:/ { part = "data"; next }
  part != "data" { print > "part_header"; next }
  /^ [A-Za-z_][A-Za-z0-9_]* =/ { name = $1 }
  name != "" { print > ("part_var_" name) }
' dump.cdl
{
  for f in part_header part_var_*; do
    printf '%s %s\n' "${f#part_}" "$(sha256sum "$f" | cut -d' ' -f1)"
  done
} | sort > fingerprints.txt
golden="$case_dir/$case.sha"
# the sums over ranks are formed in another order: a run on NP > 1 ranks has its own record
((np > 1)) && golden="$case_dir/$case.np$np.sha"
if [[ ${KUMO_UPDATE_GOLDEN:-0} == 1 ]]; then
  cp fingerprints.txt "$golden"
  echo "golden: recorded $(wc -l < fingerprints.txt) fingerprints in $golden"
  exit 0
fi
if [[ ! -f $golden ]]; then
  echo "golden: no fingerprints recorded for $case ($golden)" >&2
  exit 1
fi
if ! diff_out=$(diff "$golden" fingerprints.txt); then
  echo "golden: $case on $np rank(s) differs from its recorded output in:" >&2
  echo "$diff_out" | sed -n 's/^> \([^ ]*\) .*/  \1/p' >&2
  echo "(dump: $PWD/dump.cdl)" >&2
  exit 1
fi
echo "golden: $case on $np rank(s) matches all $(wc -l < fingerprints.txt) fingerprints"
