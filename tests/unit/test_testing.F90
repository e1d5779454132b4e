! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of the test harness itself: the pass/fail rules of check, check_close and
!> check_sigma, and the content of their messages.
module test_kumo_testing
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_positive_inf
  use kumo_kinds, only: sp, dp
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_sigma, &
                          check_error_words
  use kumo_error, only: set_error
  implicit none
  private
  public :: collect_testing

contains

  !> All tests of this suite.
  function collect_testing() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('check_pass_and_fail', test_check), &
             new_unittest('check_keeps_first_failure', test_check_first_failure), &
             new_unittest('check_close_absolute', test_close_absolute), &
             new_unittest('check_close_relative', test_close_relative), &
             new_unittest('check_close_default_tolerance', test_close_default), &
             new_unittest('check_close_message', test_close_message), &
             new_unittest('check_close_nan_and_inf', test_close_special), &
             new_unittest('check_close_single_precision', test_close_sp), &
             new_unittest('check_sigma_limits', test_sigma_limits), &
             new_unittest('check_sigma_message', test_sigma_message), &
             new_unittest('check_sigma_invalid_sigma', test_sigma_invalid), &
             new_unittest('check_error_words', test_error_words)]
  end function collect_testing

  !> Fail `error` unless `probe` holds a failure whose message contains `part`; then clear
  !> `probe` for the next probe.
  subroutine expect_failure(error, probe, part, what)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(inout) :: probe
    character(len=*), intent(in) :: part, what
    if (.not. allocated(probe)) then
      call check(error, .false., what//': expected a failure')
    else
      call check(error, index(probe%message, part) > 0, &
                 what//': message "'//probe%message//'" lacks "'//part//'"')
      deallocate (probe)
    end if
  end subroutine expect_failure

  !> Fail `error` unless `message` contains `part`.
  subroutine expect_in_message(error, message, part)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: message, part
    call check(error, index(message, part) > 0, 'message "'//message//'" lacks "'//part//'"')
  end subroutine expect_in_message

  !> Fail `error` if `probe` holds a failure.
  subroutine expect_pass(error, probe, what)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: probe
    character(len=*), intent(in) :: what
    if (allocated(error)) return
    if (allocated(probe)) call check(error, .false., what//': unexpected failure: '//probe%message)
  end subroutine expect_pass

  subroutine test_check(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    call check(probe, .true., 'must not appear')
    call expect_pass(error, probe, 'true condition')
    call check(probe, .false., 'the message')
    call expect_failure(error, probe, 'the message', 'false condition')
  end subroutine test_check

  subroutine test_check_first_failure(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    call check(probe, .false., 'first')
    call check(probe, .false., 'second')
    call check_close(probe, 1.0_dp, 2.0_dp, abs_tol=0.1_dp, label='third')
    call check(error, allocated(probe), 'expected a failure')
    if (allocated(error)) return
    call check(error, probe%message == 'first', 'expected "first", got "'//probe%message//'"')
  end subroutine test_check_first_failure

  subroutine test_close_absolute(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    ! |1.25 - 1| = 0.25 exactly: on the boundary passes, just inside the boundary fails
    call check_close(probe, 1.25_dp, 1.0_dp, abs_tol=0.25_dp, rel_tol=0.0_dp)
    call expect_pass(error, probe, 'difference equal to abs_tol')
    call check_close(probe, 1.25_dp, 1.0_dp, abs_tol=0.24_dp, rel_tol=0.0_dp)
    call expect_failure(error, probe, 'tolerance', 'difference above abs_tol')
    call check_close(probe, 1.0e-9_dp, 0.0_dp, abs_tol=1.0e-8_dp)
    call expect_pass(error, probe, 'abs_tol alone near zero')
  end subroutine test_close_absolute

  subroutine test_close_relative(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    ! tolerance is max(abs_tol, rel_tol*|expected|) = max(1e-3, 0.5*100) = 50
    call check_close(probe, 150.0_dp, 100.0_dp, abs_tol=1.0e-3_dp, rel_tol=0.5_dp)
    call expect_pass(error, probe, 'relative tolerance dominates')
    call check_close(probe, 151.0_dp, 100.0_dp, abs_tol=1.0e-3_dp, rel_tol=0.5_dp)
    call expect_failure(error, probe, 'tolerance', 'above relative tolerance')
    ! the larger of the two is used: abs_tol = 2 beats rel_tol*|e| = 0.1
    call check_close(probe, 1.0_dp, 2.0_dp, abs_tol=2.0_dp, rel_tol=0.05_dp)
    call expect_pass(error, probe, 'absolute tolerance dominates')
    ! relative to expected, not actual
    call check_close(probe, -3.0_dp, -2.0_dp, rel_tol=0.5_dp)
    call expect_pass(error, probe, 'negative values')
  end subroutine test_close_relative

  subroutine test_close_default(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    call check_close(probe, 0.1_dp + 0.2_dp, 0.3_dp)
    call expect_pass(error, probe, 'rounding-level difference')
    call check_close(probe, 0.3_dp + 1.0e-12_dp, 0.3_dp)
    call expect_failure(error, probe, 'tolerance', '1e-12 difference')
    call check_close(probe, 0.0_dp, 0.0_dp)
    call expect_pass(error, probe, 'exact zero')
  end subroutine test_close_default

  subroutine test_close_message(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    call check_close(probe, 2.5_dp, 2.0_dp, abs_tol=0.125_dp, rel_tol=0.0_dp, label='flux_up')
    call check(error, allocated(probe), 'expected a failure')
    if (allocated(error)) return
    call expect_in_message(error, probe%message, 'flux_up: ')
    call expect_in_message(error, probe%message, 'actual = 2.5')
    call expect_in_message(error, probe%message, 'expected = 2.0')
    call expect_in_message(error, probe%message, 'tolerance = 1.25')
  end subroutine test_close_message

  subroutine test_close_special(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    real(dp) :: nan, inf
    nan = ieee_value(nan, ieee_quiet_nan)
    inf = ieee_value(inf, ieee_positive_inf)
    call check_close(probe, nan, 1.0_dp, abs_tol=huge(1.0_dp))
    call expect_failure(error, probe, 'NaN', 'NaN actual')
    call check_close(probe, 1.0_dp, nan, abs_tol=huge(1.0_dp))
    call expect_failure(error, probe, 'NaN', 'NaN expected')
    call check_close(probe, inf, inf)
    call expect_pass(error, probe, 'equal infinities')
    call check_close(probe, 1.0_dp, inf, rel_tol=0.5_dp)
    call expect_failure(error, probe, 'infinite', 'finite against infinite')
  end subroutine test_close_special

  subroutine test_close_sp(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    call check_close(probe, 1.0_sp + epsilon(1.0_sp), 1.0_sp)
    call expect_pass(error, probe, 'single precision, one ulp')
    call check_close(probe, 1.001_sp, 1.0_sp, abs_tol=1.0e-4_sp)
    call expect_failure(error, probe, 'tolerance', 'single precision, above abs_tol')
  end subroutine test_close_sp

  subroutine test_sigma_limits(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    ! deviation 0.5 = 4 sigma with sigma = 0.125: on the limit
    call check_sigma(probe, 1.5_dp, 1.0_dp, 0.125_dp)
    call expect_pass(error, probe, 'deviation of 4 sigma, default k')
    call check_sigma(probe, 1.5_dp, 1.0_dp, 0.125_dp, k=3.0_dp)
    call expect_failure(error, probe, 'sigma', 'deviation of 4 sigma, k = 3')
    ! the floor is added to k*sigma: 3*0.125 + 0.125 = 0.5
    call check_sigma(probe, 1.5_dp, 1.0_dp, 0.125_dp, k=3.0_dp, abs_floor=0.125_dp)
    call expect_pass(error, probe, 'k sigma plus floor')
    ! zero sigma (an exact result) needs the floor
    call check_sigma(probe, 1.0e-10_dp, 0.0_dp, 0.0_dp, abs_floor=1.0e-9_dp)
    call expect_pass(error, probe, 'zero sigma within floor')
    call check_sigma(probe, 1.0e-10_dp, 0.0_dp, 0.0_dp)
    call expect_failure(error, probe, 'inf sigma', 'zero sigma without floor')
    call check_sigma(probe, 1.5_sp, 1.0_sp, 0.125_sp)
    call expect_pass(error, probe, 'single precision')
  end subroutine test_sigma_limits

  subroutine test_sigma_message(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    call check_sigma(probe, 2.0_dp, 1.0_dp, 0.2_dp, k=4.0_dp, label='transmittance')
    call check(error, allocated(probe), 'expected a failure')
    if (allocated(error)) return
    call expect_in_message(error, probe%message, 'transmittance: ')
    call expect_in_message(error, probe%message, 'deviation 5.00 sigma > 4.00 sigma')
    call expect_in_message(error, probe%message, 'sigma = 2.0')
  end subroutine test_sigma_message

  subroutine test_sigma_invalid(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe
    real(dp) :: nan
    nan = ieee_value(nan, ieee_quiet_nan)
    call check_sigma(probe, 1.0_dp, 1.0_dp, -1.0_dp)
    call expect_failure(error, probe, 'negative sigma', 'negative sigma')
    call check_sigma(probe, 1.0_dp, 1.0_dp, nan)
    call expect_failure(error, probe, 'not finite', 'NaN sigma')
    call check_sigma(probe, nan, 1.0_dp, 1.0_dp)
    call expect_failure(error, probe, 'NaN', 'NaN estimate')
  end subroutine test_sigma_invalid
  !> An error holding every word passes; no error, or one that lacks a word, fails and says which.
  subroutine test_error_words(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: probe, err
    call check_error_words(probe, err, ['lwc'])
    call expect_failure(error, probe, 'no error; expected one with "lwc"', 'no error')
    call set_error(err, 'file.nc: variable lwc: negative value at (1, 2, 3)')
    call check_error_words(probe, err, [character(len=8) :: 'lwc', 'negative'])
    call expect_pass(error, probe, 'all words present')
    call check_error_words(probe, err, [character(len=8) :: 'lwc', 'reff'])
    call expect_failure(error, probe, 'lacks "reff"', 'a word missing')
  end subroutine test_error_words

end module test_kumo_testing

program test_testing
  use test_kumo_testing, only: collect_testing
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_testing', collect_testing(), n_failed)
  if (n_failed > 0) error stop 1
end program test_testing
