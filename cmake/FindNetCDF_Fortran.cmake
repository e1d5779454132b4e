# SPDX-License-Identifier: BSD-3-Clause
#[=======================================================================[.rst:
FindNetCDF_Fortran
------------------

Finds the netCDF-Fortran library and its ``netcdf`` module. Distribution
packages (Debian's ``libnetcdff-dev``) ship ``netcdf-fortran.pc`` and
``nf-config`` but no CMake package configuration file, so this module asks
pkg-config first, then ``nf-config``, then searches the usual places.
Set ``NetCDF_Fortran_ROOT`` (or the cache entries below) to point it at a
particular installation.

Imported target
^^^^^^^^^^^^^^^

``NetCDF_Fortran::NetCDF_Fortran``

Result variables
^^^^^^^^^^^^^^^^

``NetCDF_Fortran_FOUND``, ``NetCDF_Fortran_VERSION``,
``NetCDF_Fortran_LIBRARIES``, ``NetCDF_Fortran_INCLUDE_DIRS``

Cache variables
^^^^^^^^^^^^^^^

``NetCDF_Fortran_LIBRARY`` (``libnetcdff``),
``NetCDF_Fortran_INCLUDE_DIR`` (directory holding ``netcdf.mod``)
#]=======================================================================]

set(_nf_lib_hints)
set(_nf_inc_hints)

find_package(PkgConfig QUIET)
if(PkgConfig_FOUND)
  pkg_check_modules(PC_NetCDF_Fortran QUIET netcdf-fortran)
  if(PC_NetCDF_Fortran_FOUND)
    list(APPEND _nf_lib_hints ${PC_NetCDF_Fortran_LIBRARY_DIRS} ${PC_NetCDF_Fortran_LIBDIR})
    list(APPEND _nf_inc_hints ${PC_NetCDF_Fortran_INCLUDE_DIRS} ${PC_NetCDF_Fortran_INCLUDEDIR})
    set(_nf_version "${PC_NetCDF_Fortran_VERSION}")
  endif()
endif()

find_program(NetCDF_Fortran_CONFIG_EXECUTABLE NAMES nf-config)
mark_as_advanced(NetCDF_Fortran_CONFIG_EXECUTABLE)
if(NetCDF_Fortran_CONFIG_EXECUTABLE)
  execute_process(COMMAND ${NetCDF_Fortran_CONFIG_EXECUTABLE} --prefix
                  OUTPUT_VARIABLE _nf_prefix OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
  execute_process(COMMAND ${NetCDF_Fortran_CONFIG_EXECUTABLE} --includedir
                  OUTPUT_VARIABLE _nf_includedir OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
  if(_nf_prefix)
    list(APPEND _nf_lib_hints ${_nf_prefix}/lib ${_nf_prefix}/lib64)
    list(APPEND _nf_inc_hints ${_nf_prefix}/include)
  endif()
  if(_nf_includedir)
    list(APPEND _nf_inc_hints ${_nf_includedir})
  endif()
  if(NOT _nf_version)
    execute_process(COMMAND ${NetCDF_Fortran_CONFIG_EXECUTABLE} --version
                    OUTPUT_VARIABLE _nf_version_text OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
    if(_nf_version_text MATCHES "([0-9]+\\.[0-9]+(\\.[0-9]+)?)")
      set(_nf_version "${CMAKE_MATCH_1}")
    endif()
  endif()
endif()

find_library(NetCDF_Fortran_LIBRARY NAMES netcdff HINTS ${_nf_lib_hints})
find_path(NetCDF_Fortran_INCLUDE_DIR NAMES netcdf.mod HINTS ${_nf_inc_hints}
          PATH_SUFFIXES netcdf netcdf-fortran)
mark_as_advanced(NetCDF_Fortran_LIBRARY NetCDF_Fortran_INCLUDE_DIR)

set(NetCDF_Fortran_VERSION "${_nf_version}")

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(NetCDF_Fortran
  REQUIRED_VARS NetCDF_Fortran_LIBRARY NetCDF_Fortran_INCLUDE_DIR
  VERSION_VAR NetCDF_Fortran_VERSION)

if(NetCDF_Fortran_FOUND)
  set(NetCDF_Fortran_LIBRARIES "${NetCDF_Fortran_LIBRARY}")
  set(NetCDF_Fortran_INCLUDE_DIRS "${NetCDF_Fortran_INCLUDE_DIR}")
  if(NOT TARGET NetCDF_Fortran::NetCDF_Fortran)
    add_library(NetCDF_Fortran::NetCDF_Fortran UNKNOWN IMPORTED)
    set_target_properties(NetCDF_Fortran::NetCDF_Fortran PROPERTIES
      IMPORTED_LOCATION "${NetCDF_Fortran_LIBRARY}"
      INTERFACE_INCLUDE_DIRECTORIES "${NetCDF_Fortran_INCLUDE_DIR}")
  endif()
endif()

unset(_nf_lib_hints)
unset(_nf_inc_hints)
unset(_nf_prefix)
unset(_nf_includedir)
unset(_nf_version)
unset(_nf_version_text)
