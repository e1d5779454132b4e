#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Install the tools kumo needs to build and test (Debian/Ubuntu packages):
# gfortran, OpenMPI, netCDF-Fortran, CMake, pkg-config, make.
# Does nothing when every tool is already on PATH, so it is safe to run often.
#
#   bash scripts/install-deps.sh            build tools
#   bash scripts/install-deps.sh --python   only the Python modules of the example and benchmark
#                                           scripts and of the Python package in python/ and its
#                                           tests (numpy, netCDF4, xarray, f90nml, matplotlib,
#                                           pytest, compliance-checker) for the Python in
#                                           $PYTHON (default python3), with pip (user site
#                                           when not root)
set -euo pipefail

if [[ ${1:-} == --python ]]; then
  python="${PYTHON:-python3}"
  if "$python" -c 'import numpy, netCDF4, xarray, f90nml, matplotlib, pytest, compliance_checker' \
    2>/dev/null; then
    echo "install-deps: Python modules present"
    exit 0
  fi
  echo "install-deps: installing numpy, netCDF4, xarray, f90nml, matplotlib, pytest," \
    "compliance-checker for $python (pip)"
  pip_args=(--quiet)
  [[ $(id -u) -ne 0 ]] && pip_args+=(--user)
  if ! "$python" -m pip install "${pip_args[@]}" numpy netCDF4 xarray f90nml matplotlib pytest \
    compliance-checker; then
    echo "install-deps: pip failed; on Debian/Ubuntu install python3-numpy python3-netcdf4" \
      "python3-xarray python3-f90nml python3-matplotlib python3-pytest and use" \
      "PYTHON=/usr/bin/python3" >&2
    exit 1
  fi
  exit 0
elif [[ $# -gt 0 ]]; then
  echo "install-deps: unknown argument $1 (only --python)" >&2
  exit 2
fi

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
