# SPDX-License-Identifier: BSD-3-Clause
# kumo_ncgen(<cdl>...): turn each netCDF file in CDL text into <name>.nc in the working
# directory with ncgen; included by the -P scripts of the regression tests.
function(kumo_ncgen)
  foreach(cdl IN LISTS ARGN)
    get_filename_component(stem ${cdl} NAME_WE)
    execute_process(COMMAND ncgen -o ${stem}.nc ${cdl} RESULT_VARIABLE rc_gen)
    if(NOT rc_gen EQUAL 0)
      message(FATAL_ERROR "ncgen failed on ${cdl}")
    endif()
  endforeach()
endfunction()
