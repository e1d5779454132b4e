! SPDX-License-Identifier: BSD-3-Clause
!> Rules shared by the benchmarks that compare kumo with reference values (DISORT tables,
!> published and analytic answers): the absolute floor for references near zero, the standard
!> error of a direct-beam count, the error-bar check over many comparisons, and a cache that runs
!> the cases of a suite once for all of its tests.
module kumo_test_reference
  use kumo_kinds, only: dp, i8
  use kumo_error, only: error_t, set_error, str
  use kumo_testing, only: test_proc, check
  implicit none
  private
  public :: TINY_REF, ROUNDOFF, SIGMA_EXACT
  public :: tiny_floor, direct_sigma, depth_level, check_error_bars, check_all_passed
  public :: describe_proc, run_once_t, run_once

  real(dp), parameter :: TINY_REF = 1.0e-6_dp    !! references below this get the floor
  real(dp), parameter :: REF_FLOOR = 1.0e-6_dp   !! absolute floor for those
  !> Allowance for all other references, exact ones included (F_dir_down(TOA) = 1).
  real(dp), parameter :: ROUNDOFF = 1.0e-12_dp
  !> Standard errors below this belong to exact quantities: the one-pass variance formula leaves
  !> ~1e-9 of round-off for a quantity that is the same in every batch (F_dir_down(TOA) = 1).
  real(dp), parameter :: SIGMA_EXACT = 1.0e-8_dp

  !> Text of comparison `j` of a suite, for failure messages.
  abstract interface
    function describe_proc(j) result(s)
      implicit none
      integer, intent(in) :: j
      character(len=:), allocatable :: s
    end function describe_proc
  end interface

  !> Outcome of running the cases of a suite, kept for the tests that look at it.
  type :: run_once_t
    logical :: done = .false.
    character(len=:), allocatable :: failure   !! message of a failed run
  end type run_once_t

contains

  !> Absolute floor of a comparison: REF_FLOOR for references that are zero or below what the
  !> photon budget resolves (|ref| < TINY_REF), ROUNDOFF otherwise.
  pure real(dp) function tiny_floor(ref) result(f)
    real(dp), intent(in) :: ref
    f = ROUNDOFF
    if (abs(ref) < TINY_REF) f = REF_FLOOR
  end function tiny_floor

  !> Standard error of a direct-beam quantity: the count of unscattered photons of weight 1 is
  !> binomial with the known standard error sqrt(p (1 - p)/n), which replaces a batch estimate
  !> `s` below it (a handful of expected photons gives a batch estimate of 0 or badly low).
  pure real(dp) function direct_sigma(s, p, n) result(sig)
    real(dp), intent(in) :: s, p
    integer(i8), intent(in) :: n
    sig = max(s, sqrt(max(0.0_dp, p*(1.0_dp - p))/real(n, dp)))
  end function direct_sigma

  !> kumo level (counted from the surface, 0) at optical depth `depth` below the top of layers
  !> `dtau` given top first; -1 if the depth is not a layer boundary.
  pure integer function depth_level(dtau, depth) result(lev)
    real(dp), intent(in) :: dtau(:), depth
    real(dp) :: top_depth
    integer :: nl, l
    nl = size(dtau)
    lev = -1
    if (abs(depth) <= 1.0e-9_dp) lev = nl
    top_depth = 0.0_dp
    do l = 1, nl
      top_depth = top_depth + dtau(l)
      if (abs(top_depth - depth) <= 1.0e-9_dp*max(1.0_dp, depth)) lev = nl - l
    end do
  end function depth_level

  !> Check that the error bars are honest over `n` resolved comparisons (at least `n_min`, named
  !> `what`): the RMS of (x - ref)/sigma within [0.7, 1.3] and fewer than 10 % beyond 2 sigma.
  subroutine check_error_bars(error, what, n, n_min, rms, frac2)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: what
    integer, intent(in) :: n, n_min
    real(dp), intent(in) :: rms, frac2
    call check(error, n >= n_min, 'too few resolved '//what//': '//str(n))
    call check(error, rms >= 0.7_dp .and. rms <= 1.3_dp, 'RMS of (x - ref)/sigma = '// &
               str(rms)//' outside [0.7, 1.3]: the error bars are not honest')
    call check(error, frac2 < 0.10_dp, 'fraction beyond 2 sigma = '//str(frac2)//' >= 0.10')
  end subroutine check_error_bars

  !> Fail, listing every failed comparison by `describe`, unless all of `passed` hold; `what`
  !> ends the count, e.g. 'comparisons beyond 4 sigma + floor'.
  subroutine check_all_passed(error, passed, what, describe)
    type(error_t), allocatable, intent(out) :: error
    logical, intent(in) :: passed(:)
    character(len=*), intent(in) :: what
    procedure(describe_proc) :: describe
    character(len=:), allocatable :: msg
    integer :: j, n_fail
    n_fail = count(.not. passed)
    if (n_fail == 0) return
    msg = str(n_fail)//' of '//str(size(passed))//' '//what//':'
    do j = 1, size(passed)
      if (.not. passed(j)) msg = msg//' ['//describe(j)//']'
    end do
    call set_error(error, msg)
  end subroutine check_all_passed

  !> Run the cases of a suite (`run`) the first time and return the cached outcome after: a
  !> failed run fails every test that needs it, with the run's message.
  subroutine run_once(state, run, error)
    type(run_once_t), intent(inout) :: state
    procedure(test_proc) :: run
    type(error_t), allocatable, intent(out) :: error
    if (.not. state%done) then
      state%done = .true.
      call run(error)
      if (allocated(error)) state%failure = error%message
    end if
    if (allocated(state%failure)) call set_error(error, 'running the cases failed: '// &
                                                 state%failure)
  end subroutine run_once
end module kumo_test_reference
