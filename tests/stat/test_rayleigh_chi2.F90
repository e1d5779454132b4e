! SPDX-License-Identifier: BSD-3-Clause
!> Statistical test of kumo_rayleigh's depolarised Rayleigh sampler: chi-square against its
!> own density.
!>
!> For each depolarisation ratio, N = 200,000 values of mu are drawn with
!> `rayleigh_depol_sample_mu` and the kumo_rng generator (fixed seed, one stream per case),
!> mapped through the exact CDF F(mu) = (1/2) [c0 (mu + 1) + c2 (mu^3 + 1)/3] of
!> P = c0 + c2 mu^2 (integrated here in closed form, independently of the sampler) and counted
!> in 100 bins of equal expected probability. The test passes when chi^2 < 148.230, the 0.999
!> quantile of the chi-square distribution with 99 degrees of freedom (as in test_phase_chi2).
!> A second check bins the samples in 20 equal bins of mu and compares each count with the
!> probability (1/2) Int P dmu over the bin, so a sampler drawing from the wrong density (for
!> example without depolarisation) is caught even if it were consistent with a wrong CDF.
module test_kumo_rayleigh_chi2
  use kumo_kinds, only: wp, i8
  use kumo_rng, only: rng_t, rng_init, rng_uniform
  use kumo_rayleigh, only: rayleigh_depol_sample_mu
  use kumo_testing, only: error_t, unittest_t, new_unittest, check
  implicit none
  private
  public :: collect_rayleigh_chi2

  integer(i8), parameter :: SEED = 20250612_i8   !! fixed; never changed to make a test pass
  integer, parameter :: N_SAMPLES = 200000
  integer, parameter :: N_BINS = 100
  integer, parameter :: N_MU_BINS = 20
  !> 0.999 quantile of chi^2 with 99 degrees of freedom (see test_phase_chi2).
  real(wp), parameter :: CHI2_999_DF99 = 148.230_wp
  !> 0.999 quantile of chi^2 with 19 degrees of freedom (standard tables: 43.820).
  real(wp), parameter :: CHI2_999_DF19 = 43.820_wp

contains

  !> All tests of this suite.
  function collect_rayleigh_chi2() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('chi2_rho_0', test_rho0), &
             new_unittest('chi2_rho_0.0279', test_rho_air), &
             new_unittest('chi2_rho_0.5', test_rho_half)]
  end function collect_rayleigh_chi2

  subroutine test_rho0(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_test(error, 0.0_wp, 1_i8)
  end subroutine test_rho0

  !> Air in the visible (Young 1981).
  subroutine test_rho_air(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_test(error, 0.0279_wp, 2_i8)
  end subroutine test_rho_air

  !> Strong depolarisation: P is far flatter (P(0)/P(1) = 5/6), so a sampler ignoring rho fails.
  subroutine test_rho_half(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_test(error, 0.5_wp, 3_i8)
  end subroutine test_rho_half

  !> Sample, bin in F(mu) and in mu, compare both chi^2 with their 0.999 quantiles.
  subroutine chi2_test(error, rho, stream)
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(in) :: rho
    integer(i8), intent(in) :: stream
    type(rng_t) :: rng
    integer :: counts(N_BINS), mu_counts(N_MU_BINS), i, ibin
    real(wp) :: gam, c0, c2, mu, expected, chi2, prob, lo, hi
    character(len=100) :: msg
    if (allocated(error)) return
    gam = rho/(2.0_wp - rho)
    c0 = 0.75_wp*(1.0_wp + 3.0_wp*gam)/(1.0_wp + 2.0_wp*gam)
    c2 = 0.75_wp*(1.0_wp - gam)/(1.0_wp + 2.0_wp*gam)
    call rng_init(rng, SEED, stream)
    counts = 0
    mu_counts = 0
    do i = 1, N_SAMPLES
      mu = rayleigh_depol_sample_mu(rho, rng_uniform(rng))
      call check(error, mu >= -1.0_wp .and. mu <= 1.0_wp, 'sample outside [-1, 1]')
      if (allocated(error)) return
      ibin = min(max(int(cdf(mu)*N_BINS) + 1, 1), N_BINS)
      counts(ibin) = counts(ibin) + 1
      ibin = min(max(int(0.5_wp*(mu + 1.0_wp)*N_MU_BINS) + 1, 1), N_MU_BINS)
      mu_counts(ibin) = mu_counts(ibin) + 1
    end do
    expected = real(N_SAMPLES, wp)/N_BINS
    chi2 = sum((counts - expected)**2)/expected
    write (msg, '(a, f0.2, a, f0.3, a, f0.4)') 'chi2 in F = ', chi2, ' >= ', CHI2_999_DF99, &
      ' (99 dof, p = 0.001), rho = ', rho
    call check(error, chi2 < CHI2_999_DF99, trim(msg))
    if (allocated(error)) return
    chi2 = 0.0_wp
    do i = 1, N_MU_BINS
      lo = -1.0_wp + 2.0_wp*(i - 1)/N_MU_BINS
      hi = -1.0_wp + 2.0_wp*i/N_MU_BINS
      prob = 0.5_wp*(c0*(hi - lo) + c2*(hi**3 - lo**3)/3.0_wp)
      expected = N_SAMPLES*prob
      chi2 = chi2 + (mu_counts(i) - expected)**2/expected
    end do
    write (msg, '(a, f0.2, a, f0.3, a, f0.4)') 'chi2 in mu = ', chi2, ' >= ', CHI2_999_DF19, &
      ' (19 dof, p = 0.001), rho = ', rho
    call check(error, chi2 < CHI2_999_DF19, trim(msg))
  contains
    pure function cdf(m) result(f)
      real(wp), intent(in) :: m
      real(wp) :: f
      f = 0.5_wp*(c0*(m + 1.0_wp) + c2*(m**3 + 1.0_wp)/3.0_wp)
    end function cdf
  end subroutine chi2_test

end module test_kumo_rayleigh_chi2

program test_rayleigh_chi2
  use test_kumo_rayleigh_chi2, only: collect_rayleigh_chi2
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_rayleigh (chi-square)', collect_rayleigh_chi2(), n_failed)
  if (n_failed > 0) error stop 1
end program test_rayleigh_chi2
