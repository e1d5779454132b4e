#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Install the tools kumo needs to build and test (Debian/Ubuntu packages):
# gfortran, OpenMPI, netCDF-Fortran, CMake, pkg-config, make.
# Does nothing when every tool is already on PATH, so it is safe to run often.
set -euo pipefail

tools=(gfortran mpif90 mpirun nf-config ncdump cmake pkg-config make)
packages=(gfortran libopenmpi-dev openmpi-bin libnetcdff-dev netcdf-bin cmake pkg-config make)

missing=()
for tool in "${tools[@]}"; do
  command -v "$tool" >/dev/null 2>&1 || missing+=("$tool")
done
if ((${#missing[@]} == 0)); then
  echo "install-deps: all tools present"
  exit 0
fi
echo "install-deps: missing: ${missing[*]}"

if ! command -v apt-get >/dev/null 2>&1; then
  echo "install-deps: no apt-get on this system; install by hand: ${packages[*]}" >&2
  exit 1
fi

sudo=()
if [[ $(id -u) -ne 0 ]]; then
  if command -v sudo >/dev/null 2>&1; then
    sudo=(sudo)
  else
    echo "install-deps: not root and no sudo; install by hand: ${packages[*]}" >&2
    exit 1
  fi
fi

export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update
"${sudo[@]}" apt-get install -y "${packages[@]}"

for tool in "${tools[@]}"; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "install-deps: $tool still missing after installation" >&2
    exit 1
  fi
done
echo "install-deps: done"
