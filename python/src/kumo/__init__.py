# SPDX-License-Identifier: BSD-3-Clause
"""Python interface of kumo, a forward Monte Carlo 3-D radiative transfer code.

* :func:`write_namelist` -- a namelist file from a dict of groups (f90nml);
* :func:`write_scene`, :func:`write_albedo_map`, :func:`write_cloud` -- input netCDF files
  from NumPy/xarray arrays;
* :func:`run` -- run the kumo program (serial or MPI) and get the output as an xarray Dataset;
  :func:`check` -- ``kumo --check``; errors raise :class:`KumoError` with kumo's message,
  warnings are issued as :class:`KumoWarning`;
* :func:`open_results`, :func:`value`, :func:`relative_error` -- results with standard errors;
  :func:`broadband_total` -- shortwave + longwave runs of one scene, with standard errors;
* :func:`quicklook` -- the standard plots (also the ``kumo-quicklook`` command).

See docs/python.md in the kumo source tree.
"""

from .namelist import GROUPS, read_namelist, to_namelist, write_namelist
from .quicklook import quicklook
from .results import broadband_total, open_results, products, relative_error, stderr, value
from .run import (KumoError, KumoWarning, check, find_executable, kumo_warnings, mpi_command,
                  output_path, run, run_kumo, version_info)
from .scene import write_albedo_map, write_cloud, write_scene

__version__ = "0.1.0"

__all__ = [
    "GROUPS", "KumoError", "KumoWarning", "broadband_total", "check", "find_executable",
    "kumo_warnings", "mpi_command", "open_results", "output_path", "products", "quicklook",
    "read_namelist", "relative_error", "run", "run_kumo", "stderr", "to_namelist", "value",
    "version_info", "write_albedo_map", "write_cloud", "write_namelist", "write_scene",
]
