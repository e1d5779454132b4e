#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# A file system that takes no more data must be named as the cause, never "NetCDF: HDF error"
# alone, and the failed run must leave neither the output nor its temporary file behind.
#   disk_full.sh KUMO ulimit   the file size limit (ulimit -f; kumo ignores SIGXFSZ so that the
#                              write fails with EFBIG): "file size limit exceeded"; needs no
#                              privileges. Open MPI's PMIx keeps its shared data in files, which
#                              the limit would stop; PMIX_MCA_gds=hash keeps them in memory.
#   disk_full.sh KUMO tmpfs    a full file system: a 16 KiB tmpfs mounted in a private mount
#                              namespace (unshare -m as root, unshare -rm otherwise): "no space
#                              left on device"; exit 77 (skipped) where no namespace can be made
set -euo pipefail
kumo=$1
mode=$2
work=disk_full_$mode
rm -rf "$work"
mkdir -p "$work"
cd "$work"
# a run whose output (about 40 KiB) exceeds the 16 KiB the file system or limit allows
write_nml() {
  cat > case.nml <<NML
&kumo_control n_photons_per_batch = 200, n_batches = 50, verbose = 0 /
&kumo_atmosphere nz = 4, z_levels = 0.0, 250.0, 500.0, 750.0, 1000.0, ext1d(1:4,1) = 4*0.001,
  ssa1d(1:4,1) = 4*1.0 /
&kumo_output file = '$1' /
NML
}

check_failure() {   # <rc> <log> <regex> <output path>
  local rc=$1 log=$2 regex=$3 out=$4
  if [[ $rc -eq 0 ]]; then
    cat "$log"; echo "FAIL: kumo succeeded although its output could not be written"; exit 1
  fi
  if ! grep -Eq "$regex" "$log"; then
    cat "$log"; echo "FAIL: the message does not match '$regex'"; exit 1
  fi
  if ! grep -q "$out" "$log"; then
    cat "$log"; echo "FAIL: the message does not name $out"; exit 1
  fi
}

case $mode in
  ulimit)
    write_nml out.nc
    set +e
    ( ulimit -f 16; export PMIX_MCA_gds=hash; exec "$kumo" case.nml ) > run.log 2>&1
    rc=$?
    set -e
    check_failure $rc run.log "file size limit exceeded while writing [^ ]*out\.nc\.tmp" out.nc
    [[ ! -e out.nc && ! -e out.nc.tmp ]] || { echo "FAIL: a partial output was left behind"; exit 1; }
    echo "file size limit: reported and cleaned up"
    ;;
  tmpfs)
    mkdir small_fs
    write_nml small_fs/out.nc
    if [[ $(id -u) -eq 0 ]]; then ns=(unshare -m); else ns=(unshare -rm); fi
    # the mount exists only inside the namespace, which ends with the run
    inner='mount -t tmpfs -o size=16k kumo_test small_fs || exit 77
           "$0" case.nml > run.log 2>&1; rc=$?
           ls -A small_fs > left.txt; exit $rc'
    set +e
    "${ns[@]}" sh -c "$inner" "$kumo" 2> ns.log
    rc=$?
    set -e
    if [[ $rc -eq 77 || ! -f run.log ]]; then
      cat ns.log; echo "SKIP: no private mount namespace with a tmpfs here"; exit 77
    fi
    check_failure $rc run.log "no space left on device while writing [^ ]*out\.nc\.tmp" small_fs/out.nc
    [[ ! -s left.txt ]] || { echo "FAIL: files left on the full file system: $(cat left.txt)"; exit 1; }
    echo "full file system: reported and cleaned up"
    ;;
  *)
    echo "unknown mode $mode"; exit 2 ;;
esac
