! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_vr's roulette-balance rule: the Student t quantile it judges the balance
!> with, and when the rule warns; the names of the absorption estimators.
module test_kumo_vr
  use kumo_kinds, only: dp, i8
  use kumo_constants, only: PI
  use kumo_error, only: error_t
  use kumo_vr, only: roulette_balance_warning, student_t_quantile, RR_BALANCE_MIN, &
                     RR_BALANCE_TAIL, few_batches_warning, FEW_BATCHES, absorption_estimator_code, ABS_COLLISION, ABS_TRACK, &
                     ABS_TENTATIVE
  use kumo_testing, only: unittest_t, new_unittest, check, check_close
  implicit none
  private
  public :: collect_vr

contains

  function collect_vr() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('t_quantile_closed_forms', test_closed_forms), &
             new_unittest('t_quantile_tables', test_tables), &
             new_unittest('roulette_balance_rule', test_balance_rule), &
             new_unittest('few_batches_rule', test_few_batches), &
             new_unittest('absorption_estimator_names', test_estimator_names)]
  end function collect_vr

  !> 1 and 2 degrees of freedom have closed-form quantiles: t = cot(pi p/2) (Cauchy) and
  !> t = sqrt(2 q^2/(1 - q^2)) with q = 1 - p.
  subroutine test_closed_forms(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp) :: p, q
    integer :: i
    real(dp), parameter :: ps(3) = [0.05_dp, 1.0e-3_dp, RR_BALANCE_TAIL]
    do i = 1, size(ps)
      p = ps(i)
      call check_close(error, student_t_quantile(p, 1), 1.0_dp/tan(0.5_dp*PI*p), 0.0_dp, 1.0e-10_dp, &
                       'nu = 1')
      if (allocated(error)) return
      q = 1.0_dp - p
      call check_close(error, student_t_quantile(p, 2), sqrt(2.0_dp*q*q/(1.0_dp - q*q)), 0.0_dp, &
                       1.0e-10_dp, 'nu = 2')
      if (allocated(error)) return
    end do
  end subroutine test_closed_forms

  !> Two-sided quantiles of the t distribution from Abramowitz and Stegun (1964), table 26.10,
  !> and the normal limit: 4 standard deviations for RR_BALANCE_TAIL.
  subroutine test_tables(error)
    type(error_t), allocatable, intent(out) :: error
    call check_close(error, student_t_quantile(0.05_dp, 5), 2.571_dp, 6.0e-4_dp, 0.0_dp, 'nu 5')
    if (allocated(error)) return
    call check_close(error, student_t_quantile(0.05_dp, 10), 2.228_dp, 6.0e-4_dp, 0.0_dp, 'nu 10')
    if (allocated(error)) return
    call check_close(error, student_t_quantile(0.01_dp, 3), 5.841_dp, 6.0e-4_dp, 0.0_dp, 'nu 3')
    if (allocated(error)) return
    call check_close(error, student_t_quantile(0.01_dp, 30), 2.750_dp, 6.0e-4_dp, 0.0_dp, 'nu 30')
    if (allocated(error)) return
    ! many degrees of freedom: close to the normal quantile 4, and decreasing towards it
    call check_close(error, student_t_quantile(RR_BALANCE_TAIL, 1000), 4.0_dp, 0.0_dp, 0.01_dp, &
                     'nu 1000')
    if (allocated(error)) return
    call check(error, student_t_quantile(RR_BALANCE_TAIL, 9) > student_t_quantile(RR_BALANCE_TAIL, 99), &
               't quantile does not fall with the degrees of freedom')
  end subroutine test_tables

  !> The rule warns only for a balance that is both significant and larger than RR_BALANCE_MIN.
  subroutine test_balance_rule(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp) :: t9
    t9 = student_t_quantile(RR_BALANCE_TAIL, 9)
    ! significant and large: warns, naming the setting to change
    call check(error, index(roulette_balance_warning(-6.0e-3_dp, 1.0e-5_dp, 10_i8), 'rr_weight') > 0, &
               'no warning for a balance of -6e-3 +- 1e-5')
    if (allocated(error)) return
    ! large but not significant (the survivors were sampled: noisy, with an honest error)
    call check(error, len(roulette_balance_warning(-0.3_dp, 0.3_dp/(0.99_dp*t9), 10_i8)) == 0, &
               'warning for a balance within t standard errors')
    if (allocated(error)) return
    call check(error, len(roulette_balance_warning(-0.3_dp, 0.3_dp/(1.01_dp*t9), 10_i8)) > 0, &
               'no warning for a balance just beyond t standard errors')
    if (allocated(error)) return
    ! significant but small: a bias below RR_BALANCE_MIN is not reported
    call check(error, len(roulette_balance_warning(0.9_dp*RR_BALANCE_MIN, 1.0e-9_dp, 10_i8)) == 0, &
               'warning for a balance below RR_BALANCE_MIN')
    if (allocated(error)) return
    ! two batches: t(1) is about 1e4, so 100 standard errors are no evidence
    call check(error, len(roulette_balance_warning(-0.1_dp, 1.0e-3_dp, 2_i8)) == 0, &
               'warning from two batches at 100 standard errors')
    if (allocated(error)) return
    call check(error, len(roulette_balance_warning(-0.1_dp, 0.0_dp, 1_i8)) == 0, &
               'warning from a single batch (no standard error)')
  end subroutine test_balance_rule

  !> Fewer than FEW_BATCHES batches warn, giving the Student factor of a 95 % interval (t for
  !> 3 degrees of freedom 3.182, Abramowitz and Stegun 1964, table 26.10) and the relative
  !> uncertainty of the standard error, 1/sqrt(2 nu); FEW_BATCHES batches do not.
  subroutine test_few_batches(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: text
    text = few_batches_warning(4_i8)
    call check(error, index(text, '3.18 standard errors') > 0, 'no t factor 3.18 for 4 batches: "'// &
               text//'"')
    if (allocated(error)) return
    call check(error, index(text, 'about 41 %') > 0, 'no 41 % for 4 batches: "'//text//'"')
    if (allocated(error)) return
    call check(error, index(few_batches_warning(2_i8), '12.71 standard errors') > 0, &
               'no t factor 12.71 for 2 batches')
    if (allocated(error)) return
    call check(error, len(few_batches_warning(FEW_BATCHES - 1_i8)) > 0, &
               'no warning one batch below FEW_BATCHES')
    if (allocated(error)) return
    call check(error, len(few_batches_warning(FEW_BATCHES)) == 0, 'a warning at FEW_BATCHES batches')
    call check(error, len(few_batches_warning(1000_i8)) == 0, 'a warning at 1000 batches')
  end subroutine test_few_batches

  !> Names are read case-insensitively with leading blanks; unknown ones give -1.
  subroutine test_estimator_names(error)
    type(error_t), allocatable, intent(out) :: error
    call check(error, absorption_estimator_code('collision') == ABS_COLLISION, 'collision')
    call check(error, absorption_estimator_code('  Track') == ABS_TRACK, '  Track')
    call check(error, absorption_estimator_code('TENTATIVE') == ABS_TENTATIVE, 'TENTATIVE')
    call check(error, absorption_estimator_code('tracks') == -1, 'tracks is unknown')
    call check(error, absorption_estimator_code('') == -1, 'an empty name is unknown')
  end subroutine test_estimator_names
end module test_kumo_vr

program test_vr
  use test_kumo_vr, only: collect_vr
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_vr', collect_vr(), n_failed)
  if (n_failed > 0) error stop 1
end program test_vr
