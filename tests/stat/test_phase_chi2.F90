! SPDX-License-Identifier: BSD-3-Clause
!> Statistical tests of kumo_phase: chi-square tests of every sampler against its own density.
!>
!> Each test draws N = 200,000 samples of mu with `phase_sample_mu` and the kumo_rng generator
!> (fixed seed, one stream per test), maps them through the exact CDF F(mu) and counts them in
!> 100 bins of equal expected probability (F in [(k-1)/100, k/100)). The exact CDFs are the
!> closed forms for the analytic kinds (for the depolarised Rayleigh function written out here
!> from Chandrasekhar's P = a + b mu^2, F = (1 + a mu + b mu^3/3)/2) and for Henyey-Greenstein
!> built from its Legendre moments g^l; for the C.1 table (path given as the first command-line
!> argument) the source table is integrated here, independently of kumo_phase, with composite
!> Simpson rules on a 0.005 deg grid of the same interpolant (log P linear in angle). The test
!> passes when chi^2 < 148.230, the 0.999 quantile of the chi-square distribution with 99
!> degrees of freedom.
module test_kumo_phase_chi2
  use kumo_test_text, only: read_table
  use kumo_kinds, only: wp, i8
  use kumo_constants, only: DEG2RAD
  use kumo_rng, only: rng_t, rng_init, rng_uniform
  use kumo_phase, only: phase_t, new_phase_isotropic, new_phase_rayleigh, new_phase_hg, &
                        new_phase_rayleigh_depol, phase_from_table, phase_from_legendre, &
                        phase_sample_mu, PHASE_N_INV_DEFAULT
  use kumo_testing, only: error_t, unittest_t, new_unittest, check
  implicit none
  private
  public :: collect_phase_chi2

  integer(i8), parameter :: SEED = 20240917_i8   !! fixed; never changed to make a test pass
  integer, parameter :: N_SAMPLES = 200000
  integer, parameter :: N_BINS = 100
  !> 0.999 quantile of chi^2 with 99 degrees of freedom: the root x of P(99/2, x/2) = 0.999,
  !> P the regularised lower incomplete gamma function (series / continued fraction, solved by
  !> bisection); the Wilson-Hilferty approximation gives 148.29.
  real(wp), parameter :: CHI2_999_DF99 = 148.230_wp

  integer, parameter :: CDF_ISOTROPIC = 1, CDF_RAYLEIGH = 2, CDF_HG = 3, CDF_TABLE = 4
  integer, parameter :: CDF_RAYLEIGH_DEPOL = 5

  !> Exact CDF used for the binning.
  type :: cdf_t
    integer :: kind = CDF_ISOTROPIC
    real(wp) :: g = 0.0_wp
    real(wp) :: a = 0.0_wp, b = 0.0_wp     !! depolarised Rayleigh: P = a + b mu^2
    real(wp) :: h = 0.0_wp                 !! angular step of the tabulated CDF [rad]
    real(wp), allocatable :: c(:)          !! c(k) = F(cos(k h)), k = 0 ... n
  end type cdf_t

contains

  !> All tests of this suite.
  function collect_phase_chi2() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('chi2_isotropic', test_isotropic), &
             new_unittest('chi2_rayleigh', test_rayleigh), &
             new_unittest('chi2_hg_g0.85', test_hg_085), &
             new_unittest('chi2_hg_g0.3', test_hg_03), &
             new_unittest('chi2_hg_g-0.5', test_hg_m05), &
             new_unittest('chi2_table_c1', test_table_c1), &
             new_unittest('chi2_rayleigh_depol_0.0279', test_rayleigh_depol_0279), &
             new_unittest('chi2_rayleigh_depol_0.5', test_rayleigh_depol_05), &
             new_unittest('chi2_legendre_hg_g0.85', test_legendre_hg)]
  end function collect_phase_chi2

  subroutine test_isotropic(error)
    type(error_t), allocatable, intent(out) :: error
    type(cdf_t) :: cdf
    cdf%kind = CDF_ISOTROPIC
    call chi2_test(error, new_phase_isotropic(), cdf, 1_i8)
  end subroutine test_isotropic

  subroutine test_rayleigh(error)
    type(error_t), allocatable, intent(out) :: error
    type(cdf_t) :: cdf
    cdf%kind = CDF_RAYLEIGH
    call chi2_test(error, new_phase_rayleigh(), cdf, 2_i8)
  end subroutine test_rayleigh

  subroutine test_hg_085(error)
    type(error_t), allocatable, intent(out) :: error
    call hg_case(error, 0.85_wp, 3_i8)
  end subroutine test_hg_085

  subroutine test_hg_03(error)
    type(error_t), allocatable, intent(out) :: error
    call hg_case(error, 0.3_wp, 4_i8)
  end subroutine test_hg_03

  subroutine test_hg_m05(error)
    type(error_t), allocatable, intent(out) :: error
    call hg_case(error, -0.5_wp, 5_i8)
  end subroutine test_hg_m05

  subroutine hg_case(error, g, stream)
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(in) :: g
    integer(i8), intent(in) :: stream
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    type(cdf_t) :: cdf
    ph = new_phase_hg(g, err)
    call check(error, .not. allocated(err), 'new_phase_hg failed')
    if (allocated(error)) return
    cdf%kind = CDF_HG
    cdf%g = g
    call chi2_test(error, ph, cdf, stream)
  end subroutine hg_case

  subroutine test_rayleigh_depol_0279(error)
    type(error_t), allocatable, intent(out) :: error
    call rayleigh_depol_case(error, 0.0279_wp, 7_i8)
  end subroutine test_rayleigh_depol_0279

  !> rho = 0.5: far from 3/4 (1 + mu^2) (P(0)/P(1) = 0.75 instead of 0.5), so sampling the
  !> plain Rayleigh function fails this case; rho = 0.0279 differs too little for that.
  subroutine test_rayleigh_depol_05(error)
    type(error_t), allocatable, intent(out) :: error
    call rayleigh_depol_case(error, 0.5_wp, 8_i8)
  end subroutine test_rayleigh_depol_05

  !> Depolarised Rayleigh phase_t sampled by phase_sample_mu; CDF from Chandrasekhar's
  !> coefficients a = 3 (1 + 3 gamma)/(4 (1 + 2 gamma)), b = 3 (1 - gamma)/(4 (1 + 2 gamma)),
  !> gamma = rho/(2 - rho).
  subroutine rayleigh_depol_case(error, rho, stream)
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(in) :: rho
    integer(i8), intent(in) :: stream
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    type(cdf_t) :: cdf
    real(wp) :: gam
    ph = new_phase_rayleigh_depol(rho, err)
    call check(error, .not. allocated(err), 'new_phase_rayleigh_depol failed')
    if (allocated(error)) return
    gam = rho/(2.0_wp - rho)
    cdf%kind = CDF_RAYLEIGH_DEPOL
    cdf%a = 3.0_wp*(1.0_wp + 3.0_wp*gam)/(4.0_wp*(1.0_wp + 2.0_wp*gam))
    cdf%b = 3.0_wp*(1.0_wp - gam)/(4.0_wp*(1.0_wp + 2.0_wp*gam))
    call chi2_test(error, ph, cdf, stream)
  end subroutine rayleigh_depol_case

  !> Henyey-Greenstein g = 0.85 from its Legendre moments chi_l = g^l (l <= 400) through
  !> phase_from_legendre, against the closed-form HG CDF: the table's CDF differs from it by
  !> < 1e-5 (test_phase), i.e. < 2 of the 2000 expected counts per bin, far below the
  !> sampling noise of 45.
  subroutine test_legendre_hg(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: g = 0.85_wp
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    type(cdf_t) :: cdf
    integer :: l
    ph = phase_from_legendre([(g**l, l=0, 400)], PHASE_N_INV_DEFAULT, err)
    call check(error, .not. allocated(err), 'phase_from_legendre failed')
    if (allocated(error)) return
    cdf%kind = CDF_HG
    cdf%g = g
    call chi2_test(error, ph, cdf, 9_i8)
  end subroutine test_legendre_hg

  !> Deirmendjian C.1 cloud table (I3RC C.1_PF) with the default inverse-CDF resolution.
  subroutine test_table_c1(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: n_sub = 20   ! Simpson steps per 0.1 deg table interval
    type(error_t), allocatable :: err
    character(len=4096) :: path
    integer :: length, stat, j
    real(wp), allocatable :: angle(:), value(:)
    type(phase_t) :: ph
    type(cdf_t) :: cdf

    call get_command_argument(1, path, length, stat)
    call check(error, stat == 0 .and. length > 0, 'no path of C.1_PF on the command line '// &
               '(CTest passes ${KUMO_SHARED_DIR}/data/i3rc/phase1_inputs/C.1_PF)')
    if (allocated(error)) return
    call read_table(path(1:length), angle, value, error)
    if (allocated(error)) return
    ph = phase_from_table(angle, value, error=err)
    call check(error, .not. allocated(err), 'phase_from_table failed on C.1_PF')
    if (allocated(error)) return
    call check(error, all(abs(angle - [(0.1_wp*j, j=0, size(angle) - 1)]) < 1.0e-9_wp), &
               'C.1_PF is not on a 0.1 deg grid')
    if (allocated(error)) return
    call table_cdf(value, n_sub, cdf)
    call chi2_test(error, ph, cdf, 6_i8)
  end subroutine test_table_c1

  !> CDF of a table on 0, 0.1, ..., 180 deg, interpolated with log P linear in angle (linear
  !> in P where a neighbour is 0), integrated with Simpson's rule on n_sub steps per table
  !> interval, from 180 deg (mu = -1) to each grid angle, normalised to F(mu = 1) = 1.
  subroutine table_cdf(value, n_sub, cdf)
    real(wp), intent(in) :: value(:)
    integer, intent(in) :: n_sub
    type(cdf_t), intent(out) :: cdf
    integer :: n, k, i
    real(wp) :: h, t0, t1, simpson
    n = (size(value) - 1)*n_sub
    h = 0.1_wp*DEG2RAD/n_sub
    cdf%kind = CDF_TABLE
    cdf%h = h
    allocate (cdf%c(0:n))
    cdf%c(n) = 0.0_wp
    do k = n - 1, 0, -1
      i = k/n_sub + 1            ! table interval [value(i), value(i+1)]
      t0 = k*h
      t1 = (k + 1)*h
      simpson = half_p_sin(value, i, t0) + 4.0_wp*half_p_sin(value, i, 0.5_wp*(t0 + t1)) &
                + half_p_sin(value, i, t1)
      cdf%c(k) = cdf%c(k + 1) + (t1 - t0)/6.0_wp*simpson
    end do
    cdf%c = cdf%c/cdf%c(0)
  end subroutine table_cdf

  !> (1/2) P(t) sin t for t in the interval i of a table on 0, 0.1, ..., 180 deg.
  pure function half_p_sin(value, i, t) result(f)
    real(wp), intent(in) :: value(:)
    integer, intent(in) :: i
    real(wp), intent(in) :: t   !! scattering angle [rad]
    real(wp) :: f
    real(wp) :: w, pa, pb, p
    w = (t - (i - 1)*0.1_wp*DEG2RAD)/(0.1_wp*DEG2RAD)
    pa = value(i)
    pb = value(i + 1)
    if (pa > 0.0_wp .and. pb > 0.0_wp) then
      p = exp((1.0_wp - w)*log(pa) + w*log(pb))
    else
      p = (1.0_wp - w)*pa + w*pb
    end if
    f = 0.5_wp*p*sin(t)
  end function half_p_sin

  !> Exact CDF F(mu) = (1/2) Int_{-1}^{mu} P dmu'.
  function cdf_eval(cdf, mu) result(f)
    type(cdf_t), intent(in) :: cdf
    real(wp), intent(in) :: mu
    real(wp) :: f
    real(wp) :: g, t, w
    integer :: k
    select case (cdf%kind)
    case (CDF_RAYLEIGH)
      f = (mu**3 + 3.0_wp*mu + 4.0_wp)/8.0_wp
    case (CDF_RAYLEIGH_DEPOL)
      f = 0.5_wp*(1.0_wp + cdf%a*mu + cdf%b*mu**3/3.0_wp)
    case (CDF_HG)
      g = cdf%g
      f = (1.0_wp - g*g)/(2.0_wp*g)*(1.0_wp/sqrt(1.0_wp + g*g - 2.0_wp*g*mu) - 1.0_wp/(1.0_wp + g))
    case (CDF_TABLE)
      ! linear in angle between the 0.005 deg nodes (P sin t is nearly constant across one)
      t = acos(min(1.0_wp, max(-1.0_wp, mu)))
      k = min(int(t/cdf%h), size(cdf%c) - 2)
      w = t/cdf%h - k
      f = (1.0_wp - w)*cdf%c(k) + w*cdf%c(k + 1)
    case default
      f = 0.5_wp*(1.0_wp + mu)
    end select
  end function cdf_eval

  !> Sample N_SAMPLES values from `ph` with the stream (SEED, stream), bin F(mu) in N_BINS
  !> equal bins and compare chi^2 with the 0.999 quantile.
  subroutine chi2_test(error, ph, cdf, stream)
    type(error_t), allocatable, intent(inout) :: error
    type(phase_t), intent(in) :: ph
    type(cdf_t), intent(in) :: cdf
    integer(i8), intent(in) :: stream
    type(rng_t) :: rng
    integer :: counts(N_BINS), i, ibin
    real(wp) :: mu, f, expected, chi2
    character(len=80) :: msg
    if (allocated(error)) return
    call rng_init(rng, SEED, stream)
    counts = 0
    do i = 1, N_SAMPLES
      mu = phase_sample_mu(ph, rng_uniform(rng))
      call check(error, mu >= -1.0_wp .and. mu <= 1.0_wp, 'sample outside [-1, 1]')
      if (allocated(error)) return
      f = cdf_eval(cdf, mu)
      ibin = min(max(int(f*N_BINS) + 1, 1), N_BINS)
      counts(ibin) = counts(ibin) + 1
    end do
    expected = real(N_SAMPLES, wp)/N_BINS
    chi2 = sum((counts - expected)**2)/expected
    write (msg, '(a, f0.2, a, f0.3, a)') 'chi2 = ', chi2, ' >= ', CHI2_999_DF99, &
      ' (99 degrees of freedom, p = 0.001)'
    call check(error, chi2 < CHI2_999_DF99, trim(msg))
  end subroutine chi2_test

end module test_kumo_phase_chi2

program test_phase_chi2
  use test_kumo_phase_chi2, only: collect_phase_chi2
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_phase (chi-square)', collect_phase_chi2(), n_failed)
  if (n_failed > 0) error stop 1
end program test_phase_chi2
