# SPDX-License-Identifier: BSD-3-Clause
# Run kumo with command-line arguments and check the exit status and the output: the command
# line tests (--help, --version, --check, unknown options). No run may print a STOP line.
# Variables: KUMO (program), ARGS (arguments, separated by |), RC (expected exit status),
# optional OUT_REGEX / ERR_REGEX (must match stdout / stderr), NML (copied into the working
# directory first), CDL (netCDF in CDL text, made into <name>.nc there with ncgen), ABSENT (a
# file that must not exist afterwards), LAUNCH (a launcher and its arguments, separated by |,
# e.g. mpiexec|-n|2).
string(REPLACE "|" ";" ARGS "${ARGS}")
string(REPLACE "|" ";" LAUNCH "${LAUNCH}")
if(NML)
  get_filename_component(name ${NML} NAME)
  configure_file(${NML} ${name} COPYONLY)
endif()
include(${CMAKE_CURRENT_LIST_DIR}/ncgen.cmake)
kumo_ncgen(${CDL})
if(ABSENT)
  file(REMOVE ${ABSENT})
endif()
execute_process(COMMAND ${LAUNCH} ${KUMO} ${ARGS} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
set(shown "stdout:\n${out}\nstderr:\n${err}")
if(NOT rc STREQUAL "${RC}")
  message(FATAL_ERROR "kumo ${ARGS}: exit status ${rc}, expected ${RC}\n${shown}")
endif()
if(OUT_REGEX AND NOT out MATCHES "${OUT_REGEX}")
  message(FATAL_ERROR "kumo ${ARGS}: stdout does not match '${OUT_REGEX}'\n${shown}")
endif()
if(ERR_REGEX AND NOT err MATCHES "${ERR_REGEX}")
  message(FATAL_ERROR "kumo ${ARGS}: stderr does not match '${ERR_REGEX}'\n${shown}")
endif()
if("${out}${err}" MATCHES "(^|\n)(ERROR )?STOP")
  message(FATAL_ERROR "kumo ${ARGS}: a STOP line was printed\n${shown}")
endif()
if(ABSENT AND EXISTS ${ABSENT})
  message(FATAL_ERROR "kumo ${ARGS}: ${ABSENT} was written\n${shown}")
endif()
message(STATUS "kumo ${ARGS}: exit status ${rc} as expected\n${shown}")
