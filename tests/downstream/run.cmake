# SPDX-License-Identifier: BSD-3-Clause
# Test install_downstream: install the build tree into a prefix inside the build tree, build the
# project in this folder against it with find_package(kumo), run its programs, then compile
# kernels_demo.F90 once more with the flags of `pkg-config --cflags --libs kumo`.
# Variables: BUILD_DIR, SOURCE_DIR (this folder), WORK_DIR, BUILD_TYPE, FC (the Fortran compiler
# kumo was built with), LIBDIR (CMAKE_INSTALL_LIBDIR), PKG_CONFIG (may be empty: step skipped
# with a message), DRIVER (ON/OFF: build and run driver_demo too).
cmake_minimum_required(VERSION 3.20)

function(run_step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err
                  WORKING_DIRECTORY ${WORK_DIR})
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} failed (${rc}):\n${ARGN}\n${out}\n${err}")
  endif()
  message(STATUS "${what}: ok")
  set(step_output "${out}" PARENT_SCOPE)
endfunction()

set(prefix ${WORK_DIR}/prefix)
file(REMOVE_RECURSE ${prefix} ${WORK_DIR}/build ${WORK_DIR}/kernels_demo_pc)
file(MAKE_DIRECTORY ${WORK_DIR})

run_step("cmake --install" ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(f IN ITEMS bin/kumo ${LIBDIR}/libkumo_kernels.a ${LIBDIR}/libkumo_io.a
                   ${LIBDIR}/libkumo_driver.a include/kumo/kumo_transport.mod
                   include/kumo/kumo_parallel.mod include/kumo/kumo_driver.mod
                   ${LIBDIR}/cmake/kumo/kumoConfig.cmake ${LIBDIR}/cmake/kumo/kumoConfigVersion.cmake
                   ${LIBDIR}/cmake/kumo/kumoTargets.cmake ${LIBDIR}/cmake/kumo/FindNetCDF_Fortran.cmake
                   ${LIBDIR}/pkgconfig/kumo.pc)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "not installed: ${f}")
  endif()
endforeach()
# Modules of the program and of the test suite stay out of the install.
file(GLOB stray ${prefix}/include/kumo/kumo_test*.mod ${prefix}/include/kumo/test_*.mod
                ${prefix}/include/kumo/kumo_cli.mod)
if(stray)
  message(FATAL_ERROR "module files that are not part of the libraries were installed: ${stray}")
endif()
run_step("installed kumo --version" ${prefix}/bin/kumo --version)

# find_package(kumo) from a separate CMake project
run_step("configure downstream project" ${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build
         -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_Fortran_COMPILER=${FC} -DCMAKE_BUILD_TYPE=${BUILD_TYPE}
         -DKUMO_DOWNSTREAM_DRIVER=${DRIVER})
run_step("build downstream project" ${CMAKE_COMMAND} --build ${WORK_DIR}/build)
run_step("kernels_demo (CMake)" ${WORK_DIR}/build/kernels_demo)
message("${step_output}")
if(DRIVER)
  run_step("driver_demo (CMake)" ${WORK_DIR}/build/driver_demo ${SOURCE_DIR}/transparent.nml)
  message("${step_output}")
else()
  message(STATUS "driver_demo not built (DRIVER=${DRIVER})")
endif()

# pkg-config
if(NOT PKG_CONFIG)
  message(STATUS "pkg-config not found: the pkg-config step is skipped")
  return()
endif()
set(ENV{PKG_CONFIG_PATH} ${prefix}/${LIBDIR}/pkgconfig)
run_step("pkg-config --cflags --libs kumo" ${PKG_CONFIG} --cflags --libs kumo)
string(STRIP "${step_output}" pc_flags)
separate_arguments(pc_flags UNIX_COMMAND "${pc_flags}")
run_step("compile kernels_demo with pkg-config flags" ${FC} ${SOURCE_DIR}/kernels_demo.F90
         -J ${WORK_DIR} ${pc_flags} -o ${WORK_DIR}/kernels_demo_pc)
run_step("kernels_demo (pkg-config)" ${WORK_DIR}/kernels_demo_pc)
message("${step_output}")
