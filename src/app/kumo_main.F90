! SPDX-License-Identifier: BSD-3-Clause
!> kumo: forward Monte Carlo 3-D radiative transfer. Usage: `kumo CASE.nml`.
program kumo_main
  use, intrinsic :: iso_fortran_env, only: error_unit
  use kumo_error, only: error_t
  use kumo_driver, only: run_case
  use kumo_parallel, only: par_init, par_finalize, par_is_root, par_abort
  implicit none
  type(error_t), allocatable :: error
  character(len=4096) :: path

  call par_init()
  if (command_argument_count() /= 1) then
    if (par_is_root()) write (error_unit, '(a)') 'usage: kumo CASE.nml'
    call par_abort(2)
  end if
  call get_command_argument(1, path)
  call run_case(trim(path), error)
  if (allocated(error)) then
    if (par_is_root()) write (error_unit, '(a)') 'kumo error: '//error%message
    call par_abort(1)
  end if
  call par_finalize()
end program kumo_main
