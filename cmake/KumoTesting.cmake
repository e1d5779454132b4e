# SPDX-License-Identifier: BSD-3-Clause
#[=======================================================================[.rst:
KumoTesting
-----------

Registers kumo's tests with CTest.

.. code-block:: cmake

  kumo_add_test(<name>
                SOURCES <file>...
                LABELS <label>...
                [LIBS <target>...]
                [NP <ranks>]
                [ARGS <arg>...]
                [TIMEOUT <seconds>])

Builds executable ``<name>`` from ``SOURCES``, links it with ``kumo_testing``
(which brings ``kumo_kernels``), the targets in ``LIBS`` and the project
flags, and adds the CTest test ``<name>``, run in the current binary
directory with ``ARGS`` on its command line.

``LABELS`` is required; allowed labels are ``unit``, ``stat``, ``bench``,
``mpi`` and ``regression``.

``NP <ranks>`` runs the test under ``MPIEXEC_EXECUTABLE`` with that many
ranks. With OpenMPI, ``--allow-run-as-root --oversubscribe`` are added to
``MPIEXEC_PREFLAGS`` so the tests also run as root and on machines with fewer
cores than ranks. When ``KUMO_ENABLE_MPI`` is OFF the test runs once, without
a launcher, against the serial ``kumo_parallel`` stub.

``TIMEOUT`` defaults to 300 s, so a hung test (e.g. an MPI deadlock) fails
instead of blocking the whole run.

Further properties (``WILL_FAIL``, ``PASS_REGULAR_EXPRESSION``, ...) can be
set afterwards with ``set_tests_properties(<name> ...)``.
#]=======================================================================]

include_guard(GLOBAL)

set(KUMO_TEST_LABELS unit stat bench mpi regression)

# Launcher flags for MPI tests: the user's MPIEXEC_PREFLAGS plus, for OpenMPI,
# the flags needed to run as root and with more ranks than cores.
set(KUMO_MPIEXEC_PREFLAGS ${MPIEXEC_PREFLAGS})
if(KUMO_ENABLE_MPI AND MPIEXEC_EXECUTABLE)
  execute_process(COMMAND ${MPIEXEC_EXECUTABLE} --version
                  OUTPUT_VARIABLE _kumo_mpiexec_version ERROR_VARIABLE _kumo_mpiexec_version
                  RESULT_VARIABLE _kumo_mpiexec_rc)
  if(_kumo_mpiexec_version MATCHES "Open MPI|OpenRTE|open-mpi")
    foreach(_flag IN ITEMS --allow-run-as-root --oversubscribe)
      if(NOT _flag IN_LIST KUMO_MPIEXEC_PREFLAGS)
        list(APPEND KUMO_MPIEXEC_PREFLAGS ${_flag})
      endif()
    endforeach()
  endif()
  unset(_kumo_mpiexec_version)
  unset(_kumo_mpiexec_rc)
  string(REPLACE ";" " " _kumo_preflags_text "${KUMO_MPIEXEC_PREFLAGS}")
  message(STATUS "kumo: MPI tests run as: ${MPIEXEC_EXECUTABLE} ${MPIEXEC_NUMPROC_FLAG} <np> "
                 "${_kumo_preflags_text} <test> ${MPIEXEC_POSTFLAGS}")
  unset(_kumo_preflags_text)
endif()

# kumo_test_without_lto(<target>): unless KUMO_TEST_LTO is ON, build <target> without link-time
# optimisation; it links the machine code of the fat LTO objects of kumo's libraries
# (KumoCompilerFlags), which takes about a second instead of up to 40 s of CPU.
function(kumo_test_without_lto target)
  if(KUMO_LTO_ACTIVE AND NOT KUMO_TEST_LTO)
    set_target_properties(${target} PROPERTIES INTERPROCEDURAL_OPTIMIZATION OFF
                          INTERPROCEDURAL_OPTIMIZATION_RELEASE OFF)
    if(CMAKE_Fortran_COMPILER_ID STREQUAL "GNU")
      target_link_options(${target} PRIVATE -fno-lto)
    endif()
  endif()
endfunction()

function(kumo_add_test name)
  cmake_parse_arguments(PARSE_ARGV 1 T "" "NP;TIMEOUT" "SOURCES;LIBS;LABELS;ARGS")
  if(T_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "kumo_add_test(${name}): unknown arguments: ${T_UNPARSED_ARGUMENTS}")
  endif()
  if(NOT T_SOURCES)
    message(FATAL_ERROR "kumo_add_test(${name}): SOURCES is required")
  endif()
  if(NOT T_LABELS)
    message(FATAL_ERROR "kumo_add_test(${name}): LABELS is required (one of ${KUMO_TEST_LABELS})")
  endif()
  foreach(_label IN LISTS T_LABELS)
    if(NOT _label IN_LIST KUMO_TEST_LABELS)
      message(FATAL_ERROR "kumo_add_test(${name}): unknown label '${_label}' "
                          "(allowed: ${KUMO_TEST_LABELS})")
    endif()
  endforeach()
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 300)
  endif()

  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE kumo_testing ${T_LIBS} kumo_options)
  kumo_test_without_lto(${name})

  if(T_NP AND KUMO_ENABLE_MPI)
    add_test(NAME ${name}
             COMMAND ${MPIEXEC_EXECUTABLE} ${MPIEXEC_NUMPROC_FLAG} ${T_NP} ${KUMO_MPIEXEC_PREFLAGS}
                     $<TARGET_FILE:${name}> ${MPIEXEC_POSTFLAGS} ${T_ARGS})
    set_tests_properties(${name} PROPERTIES PROCESSORS ${T_NP})
  else()
    add_test(NAME ${name} COMMAND ${name} ${T_ARGS})
  endif()
  set_tests_properties(${name} PROPERTIES
    LABELS "${T_LABELS}"
    TIMEOUT ${T_TIMEOUT}
    WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR})
endfunction()
