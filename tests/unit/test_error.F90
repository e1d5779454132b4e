! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_error: creating errors and adding context.
module test_kumo_error
  use kumo_error, only: error_t, set_error, add_context, str, to_lower
  use kumo_kinds, only: dp
  use kumo_testing, only: unittest_t, new_unittest, check
  implicit none
  private
  public :: collect_error

contains

  !> All tests of this suite.
  function collect_error() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('set_error_stores_message', test_set_error), &
             new_unittest('set_error_replaces_previous', test_set_error_replaces), &
             new_unittest('set_error_empty_message', test_set_error_empty), &
             new_unittest('add_context_prefixes', test_add_context), &
             new_unittest('add_context_nests', test_add_context_nested), &
             new_unittest('add_context_without_error', test_add_context_no_error), &
             new_unittest('numbers_and_case_in_messages', test_str)]
  end function collect_error

  subroutine test_set_error(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    call set_error(err, '&kumo_control: n_batches = 1 must be >= 2')
    call check(error, allocated(err), 'set_error left the error unallocated')
    if (allocated(error)) return
    call check(error, err%message == '&kumo_control: n_batches = 1 must be >= 2', &
               'unexpected message "'//err%message//'"')
  end subroutine test_set_error

  subroutine test_set_error_replaces(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    call set_error(err, 'first')
    call set_error(err, 'second')
    call check(error, allocated(err), 'error unallocated after second set_error')
    if (allocated(error)) return
    call check(error, err%message == 'second', 'expected "second", got "'//err%message//'"')
  end subroutine test_set_error_replaces

  subroutine test_set_error_empty(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    call set_error(err, '')
    call check(error, allocated(err), 'an empty message must still signal an error')
    if (allocated(error)) return
    call check(error, len(err%message) == 0, 'expected an empty message')
  end subroutine test_set_error_empty

  subroutine test_add_context(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    call set_error(err, 'file not found')
    call add_context(err, 'kumo_netcdf: read_scene')
    call check(error, allocated(err), 'add_context removed the error')
    if (allocated(error)) return
    call check(error, err%message == 'kumo_netcdf: read_scene: file not found', &
               'unexpected message "'//err%message//'"')
  end subroutine test_add_context

  subroutine test_add_context_nested(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    call set_error(err, 'bad value')
    call add_context(err, 'inner')
    call add_context(err, 'outer')
    call check(error, err%message == 'outer: inner: bad value', &
               'unexpected message "'//err%message//'"')
  end subroutine test_add_context_nested

  subroutine test_add_context_no_error(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    call add_context(err, 'kumo_config')
    call check(error, .not. allocated(err), 'add_context created an error where there was none')
  end subroutine test_add_context_no_error

  !> Numbers in messages print plainly, so users and tests can read them.
  subroutine test_str(error)
    type(error_t), allocatable, intent(out) :: error
    call check(error, str(0.01_dp) == '0.01', 'str(0.01) = "'//str(0.01_dp)//'"')
    call check(error, str(1000.0_dp) == '1000', 'str(1000.) = "'//str(1000.0_dp)//'"')
    call check(error, str(-1.5_dp) == '-1.5', 'str(-1.5) = "'//str(-1.5_dp)//'"')
    call check(error, str(2.5e-7_dp) == '2.5E-07', 'str(2.5e-7) = "'//str(2.5e-7_dp)//'"')
    call check(error, str(0.0_dp) == '0', 'str(0.) = "'//str(0.0_dp)//'"')
    call check(error, str(1.0_dp/3.0_dp) == '0.3333333333', 'str(1/3) = "'//str(1.0_dp/3.0_dp)//'"')
    call check(error, str(-42) == '-42', 'str(-42)')
    call check(error, to_lower('HG Table') == 'hg table', 'to_lower')
  end subroutine test_str
end module test_kumo_error

program test_error
  use test_kumo_error, only: collect_error
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_error', collect_error(), n_failed)
  if (n_failed > 0) error stop 1
end program test_error
