! SPDX-License-Identifier: BSD-3-Clause
!> kumo: forward Monte Carlo 3-D radiative transfer. Usage: `kumo [options] CASE.nml`
!> (`kumo --help`).
!>
!> Exit status: 0 success, 1 invalid case or failed run, 2 wrong command line. Errors are one
!> `kumo error: ...` message on standard error, without a STOP line; an error found on a rank
!> other than 0 alone is printed as `kumo error on rank R of N: ...` before the job ends
!> (`par_fail`).
program kumo_main
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
  use kumo_error, only: error_t
  use kumo_driver, only: run_case, check_setup
  use kumo_parallel, only: par_init, par_finalize, par_is_root, par_fail, par_stop, &
                           par_bcast_int
  use kumo_cli, only: cli_t, parse_command_line, help_text, version_text, check_case, &
                      CLI_HELP, CLI_VERSION, CLI_CHECK
  implicit none
  type(error_t), allocatable :: error
  type(cli_t) :: cli
  character(len=:), allocatable :: report
  integer :: status(1)

  call par_init()
  call parse_command_line(cli, error)
  if (allocated(error)) then
    if (par_is_root()) write (error_unit, '(a)') 'kumo: '//error%message//new_line('a')// &
                                                 'usage: kumo [options] CASE.nml (kumo --help)'
    call par_stop(2)   ! every rank parsed the same command line
  end if

  select case (cli%action)
  case (CLI_HELP)
    if (par_is_root()) write (output_unit, '(a)') help_text()
  case (CLI_VERSION)
    if (par_is_root()) write (output_unit, '(a)') version_text()
  case (CLI_CHECK)
    ! rank 0 checks; the others learn the outcome, so that every rank ends with the same status
    status = 0
    if (par_is_root()) then
      call check_case(cli%path, report, error)
      if (len(report) > 0) write (output_unit, '(a)') report
      if (allocated(error)) then
        write (error_unit, '(a)') 'kumo error: '//error%message
        status = 1
      end if
    end if
    call par_bcast_int(status)
    if (status(1) /= 0) call par_stop(1)
    ! the files are there: set the scene up as a run would, on every rank, and trace nothing
    call check_setup(cli%path, error)
    if (allocated(error)) call par_fail(error%message, 1)
    if (par_is_root()) write (output_unit, '(a)') 'kumo --check: '//cli%path// &
      ' is valid; its scene was set up, nothing was traced'
  case default   ! CLI_RUN
    call run_case(cli%path, error, resume=cli%resume)
    ! possibly found on one rank only: par_fail prints it and ends every rank
    if (allocated(error)) call par_fail(error%message, 1)
  end select
  call par_finalize()
end program kumo_main
