# SPDX-License-Identifier: BSD-3-Clause
#[=======================================================================[.rst:
KumoCompilerFlags
-----------------

Defines the INTERFACE target ``kumo_options`` that carries kumo's compiler
flags. Every kumo target links it ``PRIVATE``, so the flags never leak into
code that merely uses kumo, and ``CMAKE_Fortran_FLAGS`` stays free for the
user.

* all builds: ``-std=f2008 -fimplicit-none -Wall -Wextra -Wimplicit-interface``
* Debug: run-time checks, floating-point traps, signalling-NaN reals, backtrace
* Release: ``-O3 -funroll-loops`` with raised inlining limits and, on x86-64,
  ``-march=x86-64-v2`` (a portable baseline; never ``-march=native``, the CI
  machine may differ). The inlining limits keep the small helpers of the photon
  loop (azimuth, rotation, phase sampling, the generator) inlined into it now
  that the radiance code calls them too: with gcc's defaults the HG slab's
  photon loop needed 9 % more instructions and time per photon (callgrind and
  side-by-side timing against the build before radiances). The photon loop
  is written as event procedures (fly, reflect, collide, scatter) that gcc
  inlines into one function; ``large-function-insns`` is raised so that this
  function still takes the small helpers inline (with the default, the HG
  slab's flux loop needed 3 % more instructions per photon, callgrind).

With ``KUMO_ENABLE_LTO`` (default ON) link-time optimisation is switched on
for Release builds of every target defined after this file is included, but
only if a test project with LTO compiles and links; ``KUMO_LTO_ACTIVE``
tells the outcome.

Linking a test executable with LTO costs as much as linking ``kumo`` itself
(up to 40 s of CPU each for the tests that link the driver), and there are
about fifty of them: with ``KUMO_TEST_LTO`` OFF (the default) the libraries
are compiled into fat LTO objects (intermediate language and machine code)
and the test executables link their machine code without LTO, so the whole
suite builds in a fraction of the time. ``kumo`` and the other installed
programs always link with LTO; their results are what the golden-output tests
pin. Switch ``KUMO_TEST_LTO`` on to build the tests exactly like ``kumo``.
#]=======================================================================]

include_guard(GLOBAL)
include(CheckFortranCompilerFlag)

add_library(kumo_options INTERFACE)

if(CMAKE_Fortran_COMPILER_ID STREQUAL "GNU")
  set(_kumo_release_flags -O3 -funroll-loops --param=max-inline-insns-auto=100
      --param=large-function-growth=400 --param=inline-unit-growth=200
      --param=large-function-insns=6000)
  if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
    check_fortran_compiler_flag(-march=x86-64-v2 KUMO_HAVE_MARCH_X86_64_V2)
    if(KUMO_HAVE_MARCH_X86_64_V2)
      list(APPEND _kumo_release_flags -march=x86-64-v2)
    endif()
  endif()

  set(_kumo_debug_flags -g -fcheck=all -ffpe-trap=invalid,zero,overflow -finit-real=snan -fbacktrace)

  target_compile_options(kumo_options INTERFACE
    -std=f2008 -fimplicit-none -Wall -Wextra -Wimplicit-interface
    "$<$<CONFIG:Debug>:${_kumo_debug_flags}>"
    "$<$<CONFIG:Release>:${_kumo_release_flags}>")
  # With link-time optimisation the code is generated at link time: pass the
  # optimisation flags there too.
  target_link_options(kumo_options INTERFACE "$<$<CONFIG:Release>:${_kumo_release_flags}>")
  unset(_kumo_debug_flags)
  unset(_kumo_release_flags)
else()
  message(WARNING "kumo is developed with gfortran; no project flags are set for "
                  "${CMAKE_Fortran_COMPILER_ID}")
endif()

# Link-time optimisation (Release only). CMake's IPO support also switches the
# static-library archiver to gcc-ar, which plain -flto flags would not.
set(KUMO_LTO_ACTIVE OFF)
if(KUMO_ENABLE_LTO)
  include(CheckIPOSupported)
  check_ipo_supported(RESULT _kumo_ipo_ok OUTPUT _kumo_ipo_log LANGUAGES Fortran)
  if(_kumo_ipo_ok)
    set(CMAKE_INTERPROCEDURAL_OPTIMIZATION_RELEASE ON)
    if(NOT KUMO_TEST_LTO AND CMAKE_Fortran_COMPILER_ID STREQUAL "GNU")
      # fat objects: machine code beside the LTO intermediate language, so that the tests
      # can link without LTO (kumo_add_test)
      set(CMAKE_Fortran_COMPILE_OPTIONS_IPO -flto=auto -ffat-lto-objects)
    endif()
    if(CMAKE_BUILD_TYPE STREQUAL "Release" OR CMAKE_CONFIGURATION_TYPES)
      set(KUMO_LTO_ACTIVE ON)
    endif()
  else()
    message(STATUS "kumo: link-time optimisation not available, building without it")
    message(VERBOSE "${_kumo_ipo_log}")
  endif()
  unset(_kumo_ipo_ok)
  unset(_kumo_ipo_log)
endif()
