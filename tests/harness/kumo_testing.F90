! SPDX-License-Identifier: BSD-3-Clause
!> In-house unit-test harness: named test procedures that report failure through an `error_t`.
!>
!> A test is a module procedure `subroutine t(error)` with `type(error_t), allocatable,
!> intent(out) :: error`; it passes when it returns with `error` unallocated. The `check*`
!> routines allocate `error` on failure and keep the first failure: once `error` is allocated
!> they do nothing, so a test may return right after a failed check or run on. Each test file
!> has a suite module with `collect_<module>()` and a short program:
!>
!>     call run_unittests('kumo_error', collect_error(), n_failed)
!>     if (n_failed > 0) error stop 1
module kumo_testing
  use, intrinsic :: iso_fortran_env, only: output_unit
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan, ieee_is_finite
  use kumo_kinds, only: sp, dp
  use kumo_error, only: error_t, set_error
  implicit none
  private
  public :: error_t, test_proc, unittest_t, new_unittest, run_unittests
  public :: check, check_close, check_sigma, check_error_words

  !> Interface of a test procedure.
  abstract interface
    subroutine test_proc(error)
      import :: error_t
      implicit none
      type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    end subroutine test_proc
  end interface

  !> A named test.
  type :: unittest_t
    character(len=:), allocatable :: name                 !! name printed in the report
    procedure(test_proc), pointer, nopass :: run => null() !! the test procedure
  end type unittest_t

  !> Compare reals: pass when |actual - expected| <= max(abs_tol, rel_tol*|expected|).
  interface check_close
    module procedure check_close_dp, check_close_sp
  end interface check_close

  !> Compare a Monte Carlo estimate with a reference: pass when
  !> |actual - expected| <= k*sigma + abs_floor.
  interface check_sigma
    module procedure check_sigma_dp, check_sigma_sp
  end interface check_sigma

  character(len=*), parameter :: REAL_FMT = 'es24.16e3'

contains

  !> Make a named test from a module procedure.
  function new_unittest(name, proc) result(test)
    character(len=*), intent(in) :: name  !! test name
    procedure(test_proc) :: proc          !! test procedure (a module procedure)
    type(unittest_t) :: test
    test%name = name
    test%run => proc
  end function new_unittest

  !> Run every test, print `ok <name>` or `FAIL <name>: <message>` per test and a closing line
  !> `N passed, N failed`.
  subroutine run_unittests(suite_name, tests, n_failed)
    character(len=*), intent(in) :: suite_name  !! name of the suite (printed as a header)
    type(unittest_t), intent(in) :: tests(:)    !! tests to run, in order
    integer, intent(out) :: n_failed            !! number of failed tests
    type(error_t), allocatable :: error
    integer :: i, n_passed
    character(len=16) :: buf_pass, buf_fail

    write (output_unit, '(a)') '# '//suite_name
    n_passed = 0
    n_failed = 0
    do i = 1, size(tests)
      if (.not. associated(tests(i)%run)) then
        call set_error(error, 'no test procedure')
      else
        call tests(i)%run(error)
      end if
      if (allocated(error)) then
        n_failed = n_failed + 1
        write (output_unit, '(a)') 'FAIL '//tests(i)%name//': '//error%message
        deallocate (error)
      else
        n_passed = n_passed + 1
        write (output_unit, '(a)') 'ok '//tests(i)%name
      end if
      flush (output_unit)
    end do
    write (buf_pass, '(i0)') n_passed
    write (buf_fail, '(i0)') n_failed
    write (output_unit, '(a)') trim(buf_pass)//' passed, '//trim(buf_fail)//' failed'
    flush (output_unit)
  end subroutine run_unittests

  !> Fail with `message` unless `condition` holds.
  subroutine check(error, condition, message)
    type(error_t), allocatable, intent(inout) :: error  !! set on failure, kept if already set
    logical, intent(in) :: condition                   !! what must hold
    character(len=*), intent(in), optional :: message  !! failure message
    if (allocated(error) .or. condition) return
    if (present(message)) then
      call set_error(error, message)
    else
      call set_error(error, 'condition is false')
    end if
  end subroutine check

  !> Double-precision `check_close`. Without tolerances the comparison is relative to
  !> 10 epsilon. NaN never passes; infinities pass only when equal.
  subroutine check_close_dp(error, actual, expected, abs_tol, rel_tol, label)
    type(error_t), allocatable, intent(inout) :: error  !! set on failure, kept if already set
    real(dp), intent(in) :: actual                     !! computed value
    real(dp), intent(in) :: expected                   !! reference value
    real(dp), intent(in), optional :: abs_tol          !! absolute tolerance (default 0)
    real(dp), intent(in), optional :: rel_tol          !! relative tolerance (default 10 eps)
    character(len=*), intent(in), optional :: label    !! name of the quantity in the message
    real(dp) :: tol, diff
    character(len=24) :: s_act, s_exp, s_diff, s_tol

    if (allocated(error)) return
    if (ieee_is_nan(actual) .or. ieee_is_nan(expected)) then
      call set_error(error, label_of(label)//'NaN in comparison: '//values_text(actual, expected))
      return
    end if
    if (.not. (ieee_is_finite(actual) .and. ieee_is_finite(expected))) then
      if (same_infinity(actual, expected)) return
      call set_error(error, label_of(label)//'infinite value: '//values_text(actual, expected))
      return
    end if
    tol = 0.0_dp
    if (present(abs_tol)) tol = abs_tol
    if (present(rel_tol)) then
      tol = max(tol, rel_tol*abs(expected))
    else if (.not. present(abs_tol)) then
      tol = 10.0_dp*epsilon(1.0_dp)*abs(expected)
    end if
    diff = abs(actual - expected)
    if (diff <= tol) return

    write (s_act, '('//REAL_FMT//')') actual
    write (s_exp, '('//REAL_FMT//')') expected
    write (s_diff, '('//REAL_FMT//')') diff
    write (s_tol, '('//REAL_FMT//')') tol
    call set_error(error, label_of(label)//'actual = '//trim(adjustl(s_act))// &
                   ', expected = '//trim(adjustl(s_exp))//', |diff| = '//trim(adjustl(s_diff))// &
                   ' > tolerance = '//trim(adjustl(s_tol)))
  end subroutine check_close_dp

  !> Single-precision `check_close` (compared in double precision; default relative
  !> tolerance 10 epsilon of single precision).
  subroutine check_close_sp(error, actual, expected, abs_tol, rel_tol, label)
    type(error_t), allocatable, intent(inout) :: error  !! set on failure, kept if already set
    real(sp), intent(in) :: actual                     !! computed value
    real(sp), intent(in) :: expected                   !! reference value
    real(sp), intent(in), optional :: abs_tol          !! absolute tolerance (default 0)
    real(sp), intent(in), optional :: rel_tol          !! relative tolerance (default 10 eps)
    character(len=*), intent(in), optional :: label    !! name of the quantity in the message
    real(dp) :: atol, rtol
    atol = 0.0_dp
    if (present(abs_tol)) atol = real(abs_tol, dp)
    if (present(rel_tol)) then
      rtol = real(rel_tol, dp)
    else if (present(abs_tol)) then
      rtol = 0.0_dp
    else
      rtol = 10.0_dp*real(epsilon(1.0_sp), dp)
    end if
    call check_close_dp(error, real(actual, dp), real(expected, dp), atol, rtol, label)
  end subroutine check_close_sp

  !> Double-precision `check_sigma`. `sigma` is the standard error of `actual`; `k` defaults
  !> to 4. The message gives the deviation in units of sigma.
  subroutine check_sigma_dp(error, actual, expected, sigma, k, label, abs_floor)
    type(error_t), allocatable, intent(inout) :: error  !! set on failure, kept if already set
    real(dp), intent(in) :: actual                     !! Monte Carlo estimate
    real(dp), intent(in) :: expected                   !! reference value
    real(dp), intent(in) :: sigma                      !! standard error of the estimate (>= 0)
    real(dp), intent(in), optional :: k                !! allowed deviation in sigmas (default 4)
    character(len=*), intent(in), optional :: label    !! name of the quantity in the message
    real(dp), intent(in), optional :: abs_floor        !! added to the limit (default 0)
    real(dp) :: kk, floor, diff, limit
    character(len=24) :: s_act, s_exp, s_sig, s_dev, s_k, s_floor

    if (allocated(error)) return
    kk = 4.0_dp
    if (present(k)) kk = k
    floor = 0.0_dp
    if (present(abs_floor)) floor = abs_floor
    if (ieee_is_nan(actual) .or. ieee_is_nan(expected)) then
      call set_error(error, label_of(label)//'NaN in comparison: '//values_text(actual, expected))
      return
    end if
    if (.not. ieee_is_finite(sigma)) then
      write (s_sig, '('//REAL_FMT//')') sigma
      call set_error(error, label_of(label)//'sigma = '//trim(adjustl(s_sig))//' is not finite')
      return
    end if
    if (sigma < 0.0_dp) then
      write (s_sig, '('//REAL_FMT//')') sigma
      call set_error(error, label_of(label)//'negative sigma = '//trim(adjustl(s_sig)))
      return
    end if
    if (.not. (ieee_is_finite(actual) .and. ieee_is_finite(expected))) then
      if (same_infinity(actual, expected)) return
      call set_error(error, label_of(label)//'infinite value: '//values_text(actual, expected))
      return
    end if
    diff = abs(actual - expected)
    limit = kk*sigma + floor
    if (diff <= limit) return

    write (s_act, '('//REAL_FMT//')') actual
    write (s_exp, '('//REAL_FMT//')') expected
    write (s_sig, '('//REAL_FMT//')') sigma
    write (s_k, '(f0.2)') kk
    write (s_floor, '(es10.3e2)') floor
    if (sigma > diff/huge(1.0_dp)) then   ! diff/sigma does not overflow
      if (diff/sigma < 1.0e6_dp) then
        write (s_dev, '(f0.2)') diff/sigma
      else
        write (s_dev, '(es10.3e3)') diff/sigma
      end if
    else
      s_dev = 'inf'
    end if
    call set_error(error, label_of(label)//'actual = '//trim(adjustl(s_act))// &
                   ', expected = '//trim(adjustl(s_exp))//', sigma = '//trim(adjustl(s_sig))// &
                   ': deviation '//trim(s_dev)//' sigma > '//trim(s_k)//' sigma + '// &
                   trim(adjustl(s_floor)))
  end subroutine check_sigma_dp

  !> Single-precision `check_sigma` (compared in double precision).
  subroutine check_sigma_sp(error, actual, expected, sigma, k, label, abs_floor)
    type(error_t), allocatable, intent(inout) :: error  !! set on failure, kept if already set
    real(sp), intent(in) :: actual                     !! Monte Carlo estimate
    real(sp), intent(in) :: expected                   !! reference value
    real(sp), intent(in) :: sigma                      !! standard error of the estimate (>= 0)
    real(sp), intent(in), optional :: k                !! allowed deviation in sigmas (default 4)
    character(len=*), intent(in), optional :: label    !! name of the quantity in the message
    real(sp), intent(in), optional :: abs_floor        !! added to the limit (default 0)
    real(dp) :: kk, floor
    kk = 4.0_dp
    if (present(k)) kk = real(k, dp)
    floor = 0.0_dp
    if (present(abs_floor)) floor = real(abs_floor, dp)
    call check_sigma_dp(error, real(actual, dp), real(expected, dp), real(sigma, dp), kk, label, floor)
  end subroutine check_sigma_sp

  !> True when both values are infinite with the same sign.
  pure logical function same_infinity(a, b)
    real(dp), intent(in) :: a, b
    same_infinity = .not. ieee_is_finite(a) .and. .not. ieee_is_finite(b) &
                    .and. ((a > 0.0_dp) .eqv. (b > 0.0_dp))
  end function same_infinity

  !> "actual = ..., expected = ..." for a message about NaN or infinite values.
  function values_text(actual, expected) result(text)
    real(dp), intent(in) :: actual, expected
    character(len=:), allocatable :: text
    character(len=24) :: s_act, s_exp
    write (s_act, '('//REAL_FMT//')') actual
    write (s_exp, '('//REAL_FMT//')') expected
    text = 'actual = '//trim(adjustl(s_act))//', expected = '//trim(adjustl(s_exp))
  end function values_text

  !> "label: " or "" when no label is given.
  function label_of(label) result(prefix)
    character(len=*), intent(in), optional :: label
    character(len=:), allocatable :: prefix
    prefix = ''
    if (present(label)) then
      if (len_trim(label) > 0) prefix = trim(label)//': '
    end if
  end function label_of
  !> The call under test must have failed (`err` allocated) with a message holding every one of
  !> `words`; records a failure in `error` otherwise (nothing is checked once `error` is set).
  subroutine check_error_words(error, err, words)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: words(:)
    integer :: i
    if (allocated(error)) return
    if (.not. allocated(err)) then
      call check(error, .false., 'no error; expected one with "'//trim(words(1))//'"')
      return
    end if
    do i = 1, size(words)
      call check(error, index(err%message, trim(words(i))) > 0, 'message "'//err%message// &
                 '" lacks "'//trim(words(i))//'"')
    end do
  end subroutine check_error_words

end module kumo_testing
