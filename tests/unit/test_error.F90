! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_error: creating errors, adding context, numbers and lists in messages.
module test_kumo_error
  use kumo_error, only: error_t, set_error, add_context, str, to_lower, join
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
             new_unittest('numbers_and_case_in_messages', test_str), &
             new_unittest('join_names', test_join_names), &
             new_unittest('join_numbers', test_join_numbers), &
             new_unittest('join_empty_and_single', test_join_short), &
             new_unittest('join_components', test_join_components)]
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
    call check(error, str(1.5e-300_dp) == '1.5E-300', 'str(1.5e-300) = "'//str(1.5e-300_dp)//'"')
    call check(error, str(-2.0e120_dp) == '-2E+120', 'str(-2e120) = "'//str(-2.0e120_dp)//'"')
    call check(error, str(3.0e99_dp) == '3E+99', 'str(3e99) = "'//str(3.0e99_dp)//'"')
    call check(error, str(0.0_dp) == '0', 'str(0.) = "'//str(0.0_dp)//'"')
    call check(error, str(1.0_dp/3.0_dp) == '0.3333333333', 'str(1/3) = "'//str(1.0_dp/3.0_dp)//'"')
    ! rounded to a number of significant digits, for logs
    call check(error, str(27.3456_dp, 3) == '27.3', 'str(27.3456, 3) = "'//str(27.3456_dp, 3)//'"')
    call check(error, str(0.0040825769_dp, 4) == '0.004083', &
               'str(0.0040825769, 4) = "'//str(0.0040825769_dp, 4)//'"')
    call check(error, str(43.20000076_dp, 4) == '43.2', 'str(43.20000076, 4) = "'//str(43.20000076_dp, 4)//'"')
    call check(error, str(12345678.0_dp, 2) == '12000000', 'str(12345678, 2) = "'//str(12345678.0_dp, 2)//'"')
    call check(error, str(-9.9996e-7_dp, 4) == '-1E-06', 'str(-9.9996e-7, 4) = "'//str(-9.9996e-7_dp, 4)//'"')
    call check(error, str(0.0_dp, 4) == '0', 'str(0, 4) = "'//str(0.0_dp, 4)//'"')
    call check(error, str(-42) == '-42', 'str(-42)')
    call check(error, to_lower('HG Table') == 'hg table', 'to_lower')
  end subroutine test_str

  !> Names: trailing blanks dropped, leading ones kept; separator and brackets as asked.
  subroutine test_join_names(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=5), parameter :: names(3) = [character(len=5) :: 'x', ' yy', 'zzz']
    call expect(error, join(names), 'x,  yy, zzz', 'default separator')
    call expect(error, join(names, ','), 'x, yy,zzz', 'separator ","')
    call expect(error, join(names, ',', '()'), '(x, yy,zzz)', 'separator "," in ()')
    call expect(error, join(names, ' or ', '[]'), '[x or  yy or zzz]', 'separator " or " in []')
  end subroutine test_join_names

  !> Numbers are written as `str` writes them.
  subroutine test_join_numbers(error)
    type(error_t), allocatable, intent(out) :: error
    call expect(error, join([2, -1, 30]), '2, -1, 30', 'integers')
    call expect(error, join([-2147483647, 0]), '-2147483647, 0', 'widest integer')
    call expect(error, join([2, 1, 3], ',', '()'), '(2,1,3)', 'integers in ()')
    call expect(error, join([0.5_dp, 2.5e-7_dp, 1000.0_dp]), '0.5, 2.5E-07, 1000', 'reals')
    call expect(error, join([-1.5_dp, 0.01_dp], ' ', '[]'), '[-1.5 0.01]', 'reals in []')
    call expect(error, join([-1.234567891e-99_dp]), '-1.234567891E-99', 'long real')
  end subroutine test_join_numbers

  !> An empty list gives nothing (or only the brackets); one item has no separator.
  subroutine test_join_short(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=4), parameter :: none(0) = [character(len=4) ::]
    integer, parameter :: no_ints(0) = [integer ::]
    real(dp), parameter :: no_reals(0) = [real(dp) ::]
    call expect(error, join(none), '', 'no names')
    call expect(error, join(none, ',', '()'), '()', 'no names in ()')
    call expect(error, join(no_ints), '', 'no integers')
    call expect(error, join(no_ints, ',', '()'), '()', 'no integers in ()')
    call expect(error, join(no_reals, ', ', '[]'), '[]', 'no reals in []')
    call expect(error, join(['only  ']), 'only', 'one name')
    call expect(error, join([7], ',', '()'), '(7)', 'one integer in ()')
    call expect(error, join([0.25_dp]), '0.25', 'one real')
  end subroutine test_join_short

  !> A component of an array of derived type is a strided array: each item must still be read.
  !> (An unlimited polymorphic `items` argument misreads such arrays with gfortran 12. A Debug
  !> build notes the array temporaries made for these calls at run time.)
  subroutine test_join_components(error)
    type(error_t), allocatable, intent(out) :: error
    type :: entry_t
      character(len=6) :: name
      real(dp) :: factor
      integer :: code
    end type entry_t
    type(entry_t) :: table(3)
    table = [entry_t('g m-3', 1.0_dp, 7), entry_t('kg m-3', 1000.0_dp, -1), &
             entry_t('g kg-1', 0.5_dp, 12)]
    call expect(error, join(table%name), 'g m-3, kg m-3, g kg-1', 'names')
    call expect(error, join(table%factor, ' ', '[]'), '[1 1000 0.5]', 'reals')
    call expect(error, join(table%code, ',', '()'), '(7,-1,12)', 'integers')
  end subroutine test_join_components

  !> Compare texts exactly, both shown between quotes on failure.
  subroutine expect(error, actual, expected, what)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: actual, expected, what
    call check(error, actual == expected .and. len(actual) == len(expected), &
               what//': got "'//actual//'", expected "'//expected//'"')
  end subroutine expect
end module test_kumo_error

program test_error
  use test_kumo_error, only: collect_error
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_error', collect_error(), n_failed)
  if (n_failed > 0) error stop 1
end program test_error
