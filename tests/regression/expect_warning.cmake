# SPDX-License-Identifier: BSD-3-Clause
# Run kumo on a valid namelist that must succeed, and check its warnings: with WARN=1 the
# standard error and the output's global attribute `warnings` must both match REGEX; with
# WARN=0 neither may match it.
# Variables: KUMO (program), NML (namelist), REGEX, OUT (output file the namelist writes), WARN,
# optional CDL (netCDF files in CDL text, turned into <name>.nc with ncgen before the run).
include(${CMAKE_CURRENT_LIST_DIR}/ncgen.cmake)
file(REMOVE ${OUT})
kumo_ncgen(${CDL})
get_filename_component(name ${NML} NAME)
configure_file(${NML} ${name} COPYONLY)
execute_process(COMMAND ${KUMO} ${name} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "kumo failed on ${NML} (exit ${rc}):\n${err}")
endif()
execute_process(COMMAND ncdump -h ${OUT} RESULT_VARIABLE rc_dump OUTPUT_VARIABLE header)
if(NOT rc_dump EQUAL 0)
  message(FATAL_ERROR "ncdump -h ${OUT} failed")
endif()
string(REGEX MATCH ":warnings = [^\n]*" attr "${header}")
if(WARN)
  if(NOT err MATCHES "kumo: warning: [^\n]*${REGEX}")
    message(FATAL_ERROR "no warning matching '${REGEX}' on standard error:\n${err}")
  endif()
  if(NOT attr MATCHES "${REGEX}")
    message(FATAL_ERROR "the global attribute warnings does not match '${REGEX}':\n${attr}")
  endif()
  message(STATUS "warned as expected: ${err}")
else()
  if(err MATCHES "${REGEX}" OR attr MATCHES "${REGEX}")
    message(FATAL_ERROR "unexpected warning matching '${REGEX}':\n${err}\n${attr}")
  endif()
  message(STATUS "no warning, as expected")
endif()
