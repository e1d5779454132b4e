! SPDX-License-Identifier: BSD-3-Clause
!> kumo's driver library used from another program: read a namelist, run it with simulate and
!> look at the results in memory, without writing a file. Usage: driver_demo CASE.nml
!> (transparent.nml: no atmosphere over a Lambert surface, so reflectance = albedo exactly).
!> par_init must come first: in an MPI build it starts MPI, which simulate uses to share the
!> batches among ranks; in a serial build it does nothing. Exit status 0 when the check holds.
program driver_demo
  use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
  use kumo_kinds, only: dp
  use kumo_error, only: error_t
  use kumo_config, only: config_t
  use kumo_scene_setup, only: load_config
  use kumo_results, only: result_set_t, find_var
  use kumo_parallel, only: par_init, par_finalize, par_is_root, par_size
  use kumo_driver, only: simulate, run_summary_t
  implicit none
  type(error_t), allocatable :: error
  type(config_t) :: cfg
  type(result_set_t) :: set
  type(run_summary_t) :: summary
  character(len=1024) :: path
  real(dp) :: r, t, albedo
  integer :: ir, it
  logical :: ok

  call par_init()
  if (command_argument_count() /= 1) then
    write (error_unit, '(a)') 'usage: driver_demo CASE.nml'
    error stop 2
  end if
  call get_command_argument(1, path)
  call load_config(trim(path), cfg, error)
  if (allocated(error)) call fail(error%message)
  call simulate(cfg, set, summary, error)
  if (allocated(error)) call fail(error%message)

  ok = .true.
  if (par_is_root()) then   ! the results are gathered on rank 0
    ir = find_var(set, 'reflectance')
    it = find_var(set, 'transmittance')
    if (ir == 0 .or. it == 0) call fail('reflectance or transmittance missing from the results')
    r = set%vars(ir)%mean(1)
    t = set%vars(it)%mean(1)
    albedo = real(cfg%surface%albedo, dp)
    write (output_unit, '(a,i0,a)') 'driver_demo: ', par_size(), ' rank(s)'
    write (output_unit, '(a,es23.16,a,es23.16)') 'reflectance   ', r, '  surface albedo ', albedo
    write (output_unit, '(a,es23.16)') 'transmittance ', t
    ok = abs(r - albedo) <= 1.0e-13_dp .and. abs(t - 1.0_dp) <= 1.0e-13_dp
    if (ok) write (output_unit, '(a)') 'driver_demo: reflectance = albedo, transmittance = 1'
  end if
  call par_finalize()
  if (.not. ok) then
    write (error_unit, '(a)') 'driver_demo: results differ from the exact answer'
    error stop 1
  end if

contains

  subroutine fail(message)
    character(len=*), intent(in) :: message
    write (error_unit, '(a)') 'driver_demo: '//message
    error stop 1
  end subroutine fail

end program driver_demo
