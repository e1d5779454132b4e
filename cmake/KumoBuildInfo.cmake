# SPDX-License-Identifier: BSD-3-Clause
#[=======================================================================[.rst:
KumoBuildInfo
-------------

Script (``cmake -P``) run at every build of ``kumo``: writes the Fortran module
``kumo_build_info`` that ``kumo --version`` prints. The file is rewritten only
when its content changes, so an unchanged commit recompiles nothing.

Variables: ``SOURCE_DIR`` (kumo's source tree), ``TEMPLATE`` (the ``.F90.in``),
``OUTPUT`` (the generated ``.F90``), ``BUILD_TYPE``,
optional ``GIT_EXECUTABLE`` and ``GIT_COMMIT`` (given: used as is, e.g. for a
source archive whose commit is known).

The commit is ``unknown`` when git is missing or the source tree is not the top
of a git checkout (an unpacked archive inside another repository does not take
that repository's commit). Uncommitted changes to tracked files add
``(modified)``.
#]=======================================================================]

set(KUMO_GIT_COMMIT "unknown")
if(GIT_COMMIT)
  set(KUMO_GIT_COMMIT "${GIT_COMMIT}")
elseif(GIT_EXECUTABLE AND EXISTS "${GIT_EXECUTABLE}")
  execute_process(COMMAND "${GIT_EXECUTABLE}" -C "${SOURCE_DIR}" rev-parse --show-toplevel
                  RESULT_VARIABLE rc_top OUTPUT_VARIABLE top ERROR_QUIET
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  if(rc_top EQUAL 0)
    get_filename_component(top "${top}" REALPATH)
    get_filename_component(src "${SOURCE_DIR}" REALPATH)
  endif()
  if(rc_top EQUAL 0 AND top STREQUAL src)
    execute_process(COMMAND "${GIT_EXECUTABLE}" -C "${SOURCE_DIR}" rev-parse --short=12 HEAD
                    RESULT_VARIABLE rc_head OUTPUT_VARIABLE head ERROR_QUIET
                    OUTPUT_STRIP_TRAILING_WHITESPACE)
    if(rc_head EQUAL 0 AND head MATCHES "^[0-9a-f]+$")
      set(KUMO_GIT_COMMIT "${head}")
      execute_process(COMMAND "${GIT_EXECUTABLE}" -C "${SOURCE_DIR}" status --porcelain
                              --untracked-files=no
                      RESULT_VARIABLE rc_status OUTPUT_VARIABLE changes ERROR_QUIET)
      if(rc_status EQUAL 0 AND NOT changes STREQUAL "")
        string(APPEND KUMO_GIT_COMMIT " (modified)")
      endif()
    endif()
  endif()
endif()
# a Fortran string between single quotes: no quotes or line breaks from outside
string(REGEX REPLACE "['\n\r]" "" KUMO_GIT_COMMIT "${KUMO_GIT_COMMIT}")
string(SUBSTRING "${KUMO_GIT_COMMIT}" 0 60 KUMO_GIT_COMMIT)   # keeps the source line short
set(KUMO_BUILD_TYPE "${BUILD_TYPE}")
if(NOT KUMO_BUILD_TYPE)
  set(KUMO_BUILD_TYPE "unspecified")
endif()
configure_file("${TEMPLATE}" "${OUTPUT}" @ONLY)
