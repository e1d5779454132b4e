# SPDX-License-Identifier: BSD-3-Clause
# Run kumo on a namelist that must be rejected: the run has to end with a non-zero exit code,
# print a message matching REGEX on standard error (and no STOP line after it), and leave no
# output file behind.
# Variables: KUMO (program), NML (namelist), REGEX, OUT (output file that must not exist),
# optional CDL_DIR (every <name>.cdl there, netCDF in CDL text, becomes <name>.nc with ncgen
# before the run; <name>_cut.cdl loses its last 8 bytes, a file cut short).
file(REMOVE ${OUT} ${OUT}.tmp)
if(CDL_DIR)
  file(GLOB cdls ${CDL_DIR}/*.cdl)
  include(${CMAKE_CURRENT_LIST_DIR}/ncgen.cmake)
  kumo_ncgen(${cdls})
  foreach(cdl IN LISTS cdls)
    get_filename_component(stem ${cdl} NAME_WE)
    # <name>_cut.cdl: a partly copied file, its last 8 bytes (inside the data) missing
    if(stem MATCHES "_cut$")
      execute_process(COMMAND truncate -s -8 ${stem}.nc RESULT_VARIABLE rc_cut)
      if(NOT rc_cut EQUAL 0)
        message(FATAL_ERROR "truncate failed on ${stem}.nc")
      endif()
    endif()
  endforeach()
endif()
# run a copy in the working directory, so that relative paths in the namelist point here
get_filename_component(name ${NML} NAME)
configure_file(${NML} ${name} COPYONLY)
execute_process(COMMAND ${KUMO} ${name} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0)
  message(FATAL_ERROR "kumo accepted ${NML} (exit 0); stdout:\n${out}")
endif()
if(NOT err MATCHES "${REGEX}")
  message(FATAL_ERROR "message does not match '${REGEX}':\n${err}")
endif()
if(err MATCHES "(^|\n)(ERROR )?STOP")
  message(FATAL_ERROR "a STOP line follows kumo's message:\n${err}")
endif()
if(EXISTS ${OUT} OR EXISTS ${OUT}.tmp)
  message(FATAL_ERROR "a (partial) output file was left behind: ${OUT}")
endif()
message(STATUS "rejected as expected: ${err}")
