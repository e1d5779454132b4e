#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# A broadband run over a cloud file (the I3RC LES example of examples/broadband, fewer photons)
# on 1 and on 2 ranks: the cloud's fields are read and its optics per band made on rank 0 and
# shared, and every batch must come out the same, bit for bit.
#
#   broadband_ranks.sh KUMO NML MPIEXEC [MPIEXEC FLAGS...]
set -euo pipefail
kumo=$1 nml=$2
shift 2
work=broadband_ranks
rm -rf "$work"
mkdir -p "$work"
cd "$work"
sed -e 's/n_photons_per_batch = 100000/n_photons_per_batch = 5000/' \
  -e 's/n_batches = 20/n_batches = 4/' -e "s/file = 'les_stcu_sw.nc'/file = 'out.nc'/" "$nml" > np1.nml
"$kumo" np1.nml > np1.log 2>&1 || { cat np1.log; exit 1; }
mv out.nc np1.nc
"$@" -n 2 "$kumo" np1.nml > np2.log 2>&1 || { cat np2.log; exit 1; }
mv out.nc np2.nc
for f in np1 np2; do
  ncdump -v batch_reflectance,batch_transmittance,batch_absorptance "$f.nc" | sed -n '/^data:/,$p' > "$f.txt"
done
if ! diff np1.txt np2.txt > /dev/null; then
  echo "broadband_ranks: the batches of 1 and 2 ranks differ"
  diff np1.txt np2.txt | head -20
  exit 1
fi
echo "broadband_ranks: $(grep -c , np1.txt) lines of batch results identical on 1 and 2 ranks"
