! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_truncation (delta-flat truncation by level): the digest values for
!> Henyey-Greenstein g = 0.85, normalisation and first-moment conservation by quadrature that is
!> independent of the module (composite Simpson in angle), the cases left untruncated, the level
!> angles, chi-square tests of the sampler, trunc_eval, mu_peak and argument validation.
!>
!> The tabulated phase function is built here from Henyey-Greenstein g = 0.97 on a 0.1 deg grid
!> (P(0) ~ 2200, a forward peak as sharp as the Deirmendjian C.1 cloud's), so no data file is
!> needed.
module test_truncation_suite
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_finite
  use kumo_kinds, only: wp, i8
  use kumo_constants, only: DEG2RAD, RAD2DEG
  use kumo_rng, only: rng_t, rng_init, rng_uniform
  use kumo_phase, only: phase_t, new_phase_isotropic, new_phase_rayleigh, new_phase_hg, &
                        phase_from_table, phase_eval, phase_sample_mu, hg_eval
  use kumo_truncation, only: truncation_t, truncation_init, trunc_sample_mu, trunc_eval
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  implicit none
  private
  public :: collect_truncation

  integer(i8), parameter :: SEED = 20240923_i8   !! fixed; never changed to make a test pass
  !> Simpson step of the independent quadrature [deg] (table angles are multiples of 2 steps).
  real(wp), parameter :: SIMPSON_STEP_DEG = 0.005_wp
  integer, parameter :: N_SAMPLES = 100000
  integer, parameter :: N_BODY_BINS = 40   !! equal bins in mu on [-1, u_t]
  integer, parameter :: N_CONE_BINS = 10   !! equal bins in mu on [u_t, 1]
  !> 0.9999 quantile of chi^2 with 49 degrees of freedom (50 bins): root of
  !> P(49/2, x/2) = 0.9999, P the regularised lower incomplete gamma function (mpmath).
  real(wp), parameter :: CHI2_9999_DF49 = 94.597_wp

contains

  !> All tests of this suite.
  function collect_truncation() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('hg_085_digest_values', test_hg_digest), &
             new_unittest('normalisation_hg', test_norm_hg), &
             new_unittest('normalisation_table', test_norm_table), &
             new_unittest('table_body_matches_sampler', test_table_body), &
             new_unittest('untruncated_cases', test_untruncated), &
             new_unittest('negative_f_not_truncated', test_negative_f), &
             new_unittest('level_angles', test_level_angles), &
             new_unittest('eval_body_and_cone', test_eval), &
             new_unittest('sampler_edges', test_sampler_edges), &
             new_unittest('chi2_hg_085_level3of4', test_chi2_hg), &
             new_unittest('chi2_table_level2of4', test_chi2_table), &
             new_unittest('mu_peak', test_mu_peak), &
             new_unittest('bad_arguments_rejected', test_bad_arguments)]
  end function collect_truncation

  ! ------------------------------------------------------------------------------------------
  ! Helpers
  ! ------------------------------------------------------------------------------------------

  !> Henyey-Greenstein phase function (stops the test program on a bad g: test set-up only).
  function hg(g) result(ph)
    real(wp), intent(in) :: g
    type(phase_t) :: ph
    type(error_t), allocatable :: err
    ph = new_phase_hg(g, err)
    if (allocated(err)) error stop 'new_phase_hg failed in the test set-up'
  end function hg

  !> Table of Henyey-Greenstein g on 0, 0.1, ..., 180 deg, converted by phase_from_table.
  function hg_table(g) result(ph)
    real(wp), intent(in) :: g
    type(phase_t) :: ph
    type(error_t), allocatable :: err
    real(wp) :: angle(1801)
    integer :: j
    angle = [(0.1_wp*j, j=0, 1800)]
    angle(1801) = 180.0_wp
    ph = phase_from_table(angle, hg_eval(g, cos(angle*DEG2RAD)), error=err)
    if (allocated(err)) error stop 'phase_from_table failed in the test set-up'
  end function hg_table

  !> (1/2) Int P_trunc sin(t) cos(t)^moment dt over [t_a, t_b] [deg], composite Simpson with
  !> steps of at most SIMPSON_STEP_DEG. `side` = 0: body (mu <= u_t), 1: cone (mu > u_t); the
  !> end points are evaluated on the stated side of u_t.
  function simpson(tr, ph, iph, lev, t_a, t_b, moment, side) result(s)
    type(truncation_t), intent(in) :: tr
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: iph, lev, moment, side
    real(wp), intent(in) :: t_a, t_b
    real(wp) :: s
    real(wp) :: h, t, mu, fx, u_t
    integer :: n, k
    s = 0.0_wp
    if (t_b <= t_a) return
    u_t = tr%u_t(lev, iph)
    n = 2*max(1, ceiling((t_b - t_a)/(2.0_wp*SIMPSON_STEP_DEG)))
    h = (t_b - t_a)/n*DEG2RAD
    do k = 0, n
      t = t_a*DEG2RAD + k*h
      if (k == n) t = t_b*DEG2RAD
      mu = cos(t)
      if (side == 0) then
        mu = min(mu, u_t)
      else
        mu = max(mu, nearest(u_t, 1.0_wp))
      end if
      fx = 0.5_wp*trunc_eval(tr, ph, iph, lev, mu)*sin(t)
      if (moment == 1) fx = fx*cos(t)
      if (k == 0 .or. k == n) then
        s = s + fx
      else if (mod(k, 2) == 1) then
        s = s + 4.0_wp*fx
      else
        s = s + 2.0_wp*fx
      end if
    end do
    s = s*h/3.0_wp
  end function simpson

  !> Zeroth and first moments of P_trunc, (1/2) Int P_trunc mu^m dmu, m = 0, 1.
  subroutine trunc_moments(tr, ph, iph, lev, m0, m1)
    type(truncation_t), intent(in) :: tr
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: iph, lev
    real(wp), intent(out) :: m0, m1
    real(wp) :: t_t
    t_t = acos(tr%u_t(lev, iph))*RAD2DEG
    m0 = simpson(tr, ph, iph, lev, 0.0_wp, t_t, 0, 1) + &
         simpson(tr, ph, iph, lev, t_t, 180.0_wp, 0, 0)
    m1 = simpson(tr, ph, iph, lev, 0.0_wp, t_t, 1, 1) + &
         simpson(tr, ph, iph, lev, t_t, 180.0_wp, 1, 0)
  end subroutine trunc_moments

  !> Exact equality of two reals (written without == to keep -Wcompare-reals quiet).
  elemental logical function same(a, b)
    real(wp), intent(in) :: a, b
    same = .not. (a < b .or. a > b)
  end function same

  !> True when level lev of phase iph is left untruncated.
  logical function untouched(tr, iph, lev)
    type(truncation_t), intent(in) :: tr
    integer, intent(in) :: iph, lev
    untouched = same(tr%f(lev, iph), 0.0_wp) .and. same(tr%u_t(lev, iph), 1.0_wp) .and. &
                same(tr%body(lev, iph), 1.0_wp) .and. same(tr%p_flat(lev, iph), 0.0_wp)
  end function untouched

  !> Normalisation of P^ (to 1e-8) and first-moment conservation g = f + (1/2) Int P_trunc mu
  !> (to g_tol) at every level, by the independent quadrature.
  subroutine check_moments(error, tr, ph, iph, g_tol, what)
    type(error_t), allocatable, intent(inout) :: error
    type(truncation_t), intent(in) :: tr
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: iph
    real(wp), intent(in) :: g_tol
    character(len=*), intent(in) :: what
    real(wp) :: m0, m1
    integer :: lev
    character(len=8) :: buf
    do lev = 1, tr%n_levels
      write (buf, '(i0)') lev
      call trunc_moments(tr, ph, iph, lev, m0, m1)
      call check_close(error, m0/(1.0_wp - tr%f(lev, iph)), 1.0_wp, abs_tol=1.0e-8_wp, &
                       label=what//' level '//trim(buf)//': (1/2) Int P^ dmu')
      call check_close(error, tr%f(lev, iph) + m1, ph%g, abs_tol=g_tol, &
                       label=what//' level '//trim(buf)//': f + (1/2) Int P_trunc mu dmu = g')
    end do
  end subroutine check_moments

  !> Chi-square test of trunc_sample_mu against P^ = trunc_eval/(1 - f): N_SAMPLES deviates of
  !> the stream (SEED, stream), N_BODY_BINS equal bins in mu on the body and N_CONE_BINS on the
  !> cone; expected counts by Simpson quadrature of trunc_eval. Passes when chi^2 is below the
  !> 0.9999 quantile for 49 degrees of freedom.
  subroutine chi2_trunc(error, tr, ph, iph, lev, stream)
    type(error_t), allocatable, intent(inout) :: error
    type(truncation_t), intent(in) :: tr
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: iph, lev
    integer(i8), intent(in) :: stream
    integer, parameter :: NB = N_BODY_BINS + N_CONE_BINS
    type(rng_t) :: rng
    real(wp) :: edge(0:NB), prob(NB), u_t, one_f, mu, chi2, expected
    integer :: counts(NB), k, i, ibin
    character(len=100) :: msg

    if (allocated(error)) return
    u_t = tr%u_t(lev, iph)
    one_f = 1.0_wp - tr%f(lev, iph)
    call check(error, u_t < 1.0_wp .and. tr%f(lev, iph) > 0.0_wp, 'level is not truncated')
    if (allocated(error)) return
    do k = 0, N_BODY_BINS
      edge(k) = -1.0_wp + (u_t + 1.0_wp)*k/N_BODY_BINS
    end do
    do k = 1, N_CONE_BINS
      edge(N_BODY_BINS + k) = u_t + (1.0_wp - u_t)*k/N_CONE_BINS
    end do
    edge(N_BODY_BINS) = u_t
    edge(NB) = 1.0_wp
    do k = 1, N_BODY_BINS
      prob(k) = simpson(tr, ph, iph, lev, acos(edge(k))*RAD2DEG, acos(edge(k - 1))*RAD2DEG, &
                        0, 0)/one_f
    end do
    do k = N_BODY_BINS + 1, NB
      prob(k) = 0.5_wp*trunc_eval(tr, ph, iph, lev, 0.5_wp*(edge(k - 1) + edge(k)))* &
                (edge(k) - edge(k - 1))/one_f
    end do
    call check_close(error, sum(prob), 1.0_wp, abs_tol=1.0e-8_wp, label='sum of bin probabilities')
    call check(error, minval(prob)*N_SAMPLES >= 5.0_wp, 'fewer than 5 expected counts in a bin')
    if (allocated(error)) return

    call rng_init(rng, SEED, stream)
    counts = 0
    do i = 1, N_SAMPLES
      mu = trunc_sample_mu(tr, ph, iph, lev, rng_uniform(rng))
      call check(error, mu >= -1.0_wp .and. mu <= 1.0_wp, 'sample outside [-1, 1]')
      if (allocated(error)) return
      if (mu <= u_t) then
        ibin = min(N_BODY_BINS, int((mu + 1.0_wp)/(u_t + 1.0_wp)*N_BODY_BINS) + 1)
      else
        ibin = N_BODY_BINS + min(N_CONE_BINS, int((mu - u_t)/(1.0_wp - u_t)*N_CONE_BINS) + 1)
      end if
      counts(ibin) = counts(ibin) + 1
    end do
    chi2 = 0.0_wp
    do k = 1, NB
      expected = N_SAMPLES*prob(k)
      chi2 = chi2 + (counts(k) - expected)**2/expected
    end do
    write (msg, '(a, f0.2, a, f0.3, a)') 'chi2 = ', chi2, ' >= ', CHI2_9999_DF49, &
      ' (49 degrees of freedom, p = 1e-4)'
    call check(error, chi2 < CHI2_9999_DF49, trim(msg))
  end subroutine chi2_trunc

  ! ------------------------------------------------------------------------------------------
  ! Tests
  ! ------------------------------------------------------------------------------------------

  !> Digest section 19.3: HG g = 0.85 at 5/10/20 deg gives f = 0.008/0.065/0.253 and
  !> g^ = 0.849/0.840/0.799 (printed digits: tolerance half a unit of the last digit); g^ by
  !> independent quadrature of P^, and g = f + (1 - f) g^ to 1e-10.
  subroutine test_hg_digest(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: F_REF(3) = [0.008_wp, 0.065_wp, 0.253_wp]
    real(wp), parameter :: G_REF(3) = [0.849_wp, 0.840_wp, 0.799_wp]
    integer, parameter :: LEVS(3) = [2, 3, 5]      ! 5, 10, 20 deg with 5 levels up to 20 deg
    type(truncation_t) :: tr
    real(wp) :: m0, m1, g_hat, f
    integer :: i
    call truncation_init(tr, [hg(0.85_wp)], 20.0_wp, 5, 30.0_wp, error)
    if (allocated(error)) return
    do i = 1, 3
      f = tr%f(LEVS(i), 1)
      call check_close(error, acos(tr%u_t(LEVS(i), 1))*RAD2DEG, 5.0_wp*(LEVS(i) - 1), &
                       abs_tol=1.0e-9_wp, label='Theta_t [deg]')
      call check_close(error, f, F_REF(i), abs_tol=5.0e-4_wp, label='f')
      call trunc_moments(tr, hg(0.85_wp), 1, LEVS(i), m0, m1)
      g_hat = m1/m0                     ! mean cosine of P^ = P_trunc/(1 - f)
      call check_close(error, g_hat, G_REF(i), abs_tol=5.0e-4_wp, label='g^')
      call check_close(error, f + (1.0_wp - f)*g_hat, 0.85_wp, abs_tol=1.0e-10_wp, &
                       label='f + (1 - f) g^ = g')
      if (allocated(error)) return
    end do
  end subroutine test_hg_digest

  !> (1/2) Int P^ dmu = 1 and conservation of g at every level for HG g = 0.85 and 0.5.
  subroutine test_norm_hg(error)
    type(error_t), allocatable, intent(out) :: error
    type(truncation_t) :: tr
    type(phase_t) :: phases(2)
    phases = [hg(0.85_wp), hg(0.5_wp)]
    call truncation_init(tr, phases, 30.0_wp, 4, 30.0_wp, error)
    if (allocated(error)) return
    call check(error, all(tr%f(2:, :) > 0.0_wp), 'HG g > 0 not truncated at some level')
    call check_moments(error, tr, phases(1), 1, 1.0e-10_wp, 'HG 0.85')
    call check_moments(error, tr, phases(2), 2, 1.0e-10_wp, 'HG 0.5')
  end subroutine test_norm_hg

  !> The same for the sharp table (cone integrals by quadrature in the module); g of the table
  !> comes from phase_from_table's own quadrature, hence 1e-9.
  subroutine test_norm_table(error)
    type(error_t), allocatable, intent(out) :: error
    type(truncation_t) :: tr
    type(phase_t) :: phases(1)
    phases(1) = hg_table(0.97_wp)
    call truncation_init(tr, phases, 30.0_wp, 4, 30.0_wp, error)
    if (allocated(error)) return
    call check(error, all(tr%f(2:, 1) > 0.0_wp), 'table not truncated at some level')
    call check_moments(error, tr, phases(1), 1, 1.0e-9_wp, 'HG 0.97 table')
    ! the table is close to HG 0.97, whose f has a closed form: f = 0.5937 at 10 deg
    call check_close(error, tr%f(2, 1), 0.5937_wp, abs_tol=2.0e-3_wp, label='f of the table')
  end subroutine test_norm_table

  !> The body probability 1 - s0 agrees with the table's inverse CDF: mu_s = phase_sample_mu(ph,
  !> body) is u_t up to the linear interpolation of the inverse-CDF table (module header). In
  !> probability the mismatch (P(u_t)/2)|mu_s - u_t| is at most (1/n_inv)^2/4 |P'|/P^2 <= 6e-8
  !> for a tabulated HG 0.97 (|P'|/P^2 <= 3g/(1 - g) = 97, n_inv = 20,000): checked to 1e-7 at
  !> every 5 deg up to 60 deg. Analytic HG is exact to rounding.
  subroutine test_table_body(error)
    type(error_t), allocatable, intent(out) :: error
    type(truncation_t) :: tr
    type(phase_t) :: phases(2)
    real(wp) :: mu_s, u_t
    integer :: lev
    phases = [hg_table(0.97_wp), hg(0.85_wp)]
    call truncation_init(tr, phases, 60.0_wp, 13, 30.0_wp, error)
    if (allocated(error)) return
    do lev = 2, tr%n_levels
      u_t = tr%u_t(lev, 1)
      mu_s = phase_sample_mu(phases(1), tr%body(lev, 1))
      call check_close(error, 0.5_wp*phase_eval(phases(1), u_t)*(mu_s - u_t), 0.0_wp, &
                       abs_tol=1.0e-7_wp, label='table: (P(u_t)/2) (phase_sample_mu(body) - u_t)')
      call check_close(error, mu_s, u_t, abs_tol=1.0e-5_wp, &
                       label='table: phase_sample_mu(body) = u_t')
      call check_close(error, phase_sample_mu(phases(2), tr%body(lev, 2)), tr%u_t(lev, 2), &
                       abs_tol=1.0e-12_wp, label='HG: phase_sample_mu(body) = u_t')
    end do
  end subroutine test_table_body

  !> Isotropic (f = 0), Rayleigh (g = 0), HG with g < 0, level 1, theta_max_deg = 0 and
  !> n_levels = 1 leave the phase functions untouched.
  subroutine test_untruncated(error)
    type(error_t), allocatable, intent(out) :: error
    type(truncation_t) :: tr
    type(phase_t) :: phases(4)
    integer :: iph, lev
    phases = [new_phase_isotropic(), new_phase_rayleigh(), hg(-0.5_wp), hg(0.85_wp)]
    call truncation_init(tr, phases, 30.0_wp, 4, 30.0_wp, error)
    if (allocated(error)) return
    call check(error, tr%n_levels == 4 .and. tr%n_phases == 4, 'n_levels, n_phases')
    call check(error, all(shape(tr%f) == [4, 4]) .and. size(tr%mu_peak) == 4, 'array shapes')
    if (allocated(error)) return
    do lev = 1, 4
      do iph = 1, 3
        call check(error, untouched(tr, iph, lev), 'isotropic, Rayleigh or HG g < 0 truncated')
      end do
    end do
    call check(error, untouched(tr, 4, 1), 'level 1 truncated')
    call check(error, .not. untouched(tr, 4, 2), 'HG 0.85 not truncated at level 2')
    ! off switches
    if (allocated(error)) return   ! the next call resets error (intent(out))
    call truncation_init(tr, phases, 0.0_wp, 3, 30.0_wp, error)
    if (allocated(error)) return
    call check(error, all(same(tr%f, 0.0_wp)) .and. all(same(tr%u_t, 1.0_wp)) .and. &
               all(same(tr%body, 1.0_wp)) .and. all(same(tr%p_flat, 0.0_wp)), &
               'theta_max_deg = 0 truncates')
    if (allocated(error)) return   ! the next call resets error (intent(out))
    call truncation_init(tr, phases, 30.0_wp, 1, 30.0_wp, error)
    if (allocated(error)) return
    call check(error, all(shape(tr%f) == [1, 4]), 'shape with one level')
    call check(error, all(same(tr%f, 0.0_wp)) .and. all(same(tr%u_t, 1.0_wp)) .and. &
               all(same(tr%body, 1.0_wp)) .and. all(same(tr%p_flat, 0.0_wp)), &
               'n_levels = 1 truncates')
    ! untruncated: the sampler is phase_sample_mu, trunc_eval is phase_eval
    if (allocated(error)) return   ! the next call resets error (intent(out))
    call truncation_init(tr, phases, 30.0_wp, 4, 30.0_wp, error)
    if (allocated(error)) return
    call check(error, same(trunc_sample_mu(tr, phases(4), 4, 1, 0.9_wp), &
                           phase_sample_mu(phases(4), 0.9_wp)), &
               'level 1 sampler differs from phase_sample_mu')
    call check(error, same(trunc_eval(tr, phases(2), 2, 4, 1.0_wp), 1.5_wp), &
               'Rayleigh trunc_eval(1) /= 1.5')
  end subroutine test_untruncated

  !> A table with g > 0 whose P rises away from the forward direction (a bump at 20 deg) gives
  !> f < 0 for a 10 deg cone (not truncated) and f > 0 once the cone holds the bump (40 deg).
  subroutine test_negative_f(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(truncation_t) :: tr
    type(phase_t) :: phases(1)
    real(wp) :: angle(1801)
    integer :: j
    angle = [(0.1_wp*j, j=0, 1800)]
    angle(1801) = 180.0_wp
    phases(1) = phase_from_table(angle, 1.0_wp + 50.0_wp*exp(-((angle - 20.0_wp)/8.0_wp)**2), &
                                 error=err)
    call check(error, .not. allocated(err), 'phase_from_table failed')
    call check(error, phases(1)%g > 0.0_wp, 'g of the bump table is not > 0')
    if (allocated(error)) return
    call truncation_init(tr, phases, 40.0_wp, 5, 30.0_wp, error)
    if (allocated(error)) return
    call check(error, untouched(tr, 1, 2), '10 deg cone with f < 0 truncated')
    call check(error, tr%f(5, 1) > 0.0_wp .and. tr%u_t(5, 1) < 1.0_wp, &
               '40 deg cone holding the bump not truncated')
    call check_moments(error, tr, phases(1), 1, 1.0e-9_wp, 'bump table')
  end subroutine test_negative_f

  !> Level l truncates at theta_max (l - 1)/(n_levels - 1): 0, 10, 20, 30 deg.
  subroutine test_level_angles(error)
    type(error_t), allocatable, intent(out) :: error
    type(truncation_t) :: tr
    integer :: lev
    call truncation_init(tr, [hg(0.85_wp), hg_table(0.9_wp)], 30.0_wp, 4, 30.0_wp, error)
    if (allocated(error)) return
    call check(error, same(tr%theta_max_deg, 30.0_wp) .and. same(tr%pf_peak, 30.0_wp), &
               'stored arguments')
    do lev = 1, 4
      call check_close(error, acos(tr%u_t(lev, 1))*RAD2DEG, 10.0_wp*(lev - 1), &
                       abs_tol=1.0e-9_wp, label='HG level angle [deg]')
      call check_close(error, acos(tr%u_t(lev, 2))*RAD2DEG, 10.0_wp*(lev - 1), &
                       abs_tol=1.0e-9_wp, label='table level angle [deg]')
      ! body = 1 - s0 decreases and f increases with the level
      if (lev > 1) then
        call check(error, tr%f(lev, 1) > tr%f(lev - 1, 1) .and. &
                   tr%body(lev, 1) < tr%body(lev - 1, 1), 'f or body not monotone in level')
      end if
    end do
  end subroutine test_level_angles

  !> trunc_eval is phase_eval on the body (including mu = u_t) and p_flat on the cone.
  subroutine test_eval(error)
    type(error_t), allocatable, intent(out) :: error
    type(truncation_t) :: tr
    type(phase_t) :: phases(2)
    real(wp) :: u_t, mu
    integer :: iph, k
    phases = [hg(0.85_wp), hg_table(0.97_wp)]
    call truncation_init(tr, phases, 30.0_wp, 4, 30.0_wp, error)
    if (allocated(error)) return
    do iph = 1, 2
      u_t = tr%u_t(3, iph)
      call check(error, tr%p_flat(3, iph) > 0.0_wp, 'p_flat not positive')
      call check(error, tr%p_flat(3, iph) < phase_eval(phases(iph), 1.0_wp), &
                 'p_flat not below the peak value')
      do k = 0, 20
        mu = -1.0_wp + (u_t + 1.0_wp)*k/20.0_wp
        if (k == 20) mu = u_t
        call check(error, same(trunc_eval(tr, phases(iph), iph, 3, mu), &
                               phase_eval(phases(iph), mu)), &
                   'trunc_eval /= phase_eval on the body')
        mu = u_t + (1.0_wp - u_t)*(k + 1)/21.0_wp
        if (k == 0) mu = nearest(u_t, 1.0_wp)
        call check(error, same(trunc_eval(tr, phases(iph), iph, 3, mu), tr%p_flat(3, iph)), &
                   'trunc_eval /= p_flat on the cone')
      end do
    end do
  end subroutine test_eval

  !> u = 0 gives -1; mu is non-decreasing in u and stays in [-1, 1]; the body ends at u_t where
  !> u (1 - f) = body, also when body exceeds the table's own F(u_t); the cone branch survives a
  !> zero flat part (no division by zero: the Debug build traps it).
  subroutine test_sampler_edges(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: N = 20000
    type(truncation_t) :: tr, tr0
    type(phase_t) :: phases(2)
    real(wp) :: mu, mu_prev, u_b
    integer :: iph, i
    phases = [hg(0.85_wp), hg_table(0.97_wp)]
    call truncation_init(tr, phases, 30.0_wp, 4, 30.0_wp, error)
    if (allocated(error)) return
    do iph = 1, 2
      call check_close(error, trunc_sample_mu(tr, phases(iph), iph, 3, 0.0_wp), -1.0_wp, &
                       abs_tol=1.0e-12_wp, label='mu(u = 0)')
      mu_prev = -1.0_wp
      do i = 1, N
        mu = trunc_sample_mu(tr, phases(iph), iph, 3, (i - 0.5_wp)/N)
        call check(error, mu >= mu_prev .and. mu <= 1.0_wp, 'mu decreasing in u or above 1')
        if (allocated(error)) return
        mu_prev = mu
      end do
      u_b = tr%body(3, iph)/(1.0_wp - tr%f(3, iph))
      call check(error, trunc_sample_mu(tr, phases(iph), iph, 3, nearest(u_b, -1.0_wp)) <= &
                 tr%u_t(3, iph), 'body branch leaks into the cone')
      call check_close(error, trunc_sample_mu(tr, phases(iph), iph, 3, u_b), tr%u_t(3, iph), &
                       abs_tol=1.0e-7_wp, label='mu at the body/cone boundary')
      call check_close(error, trunc_sample_mu(tr, phases(iph), iph, 3, nearest(1.0_wp, -1.0_wp)), &
                       1.0_wp, abs_tol=1.0e-12_wp, label='mu(u -> 1)')
    end do
    ! a body probability above the table's F(u_t) must not push body samples into the cone
    tr%body(3, 2) = tr%body(3, 2) + 1.0e-4_wp
    u_b = tr%body(3, 2)/(1.0_wp - tr%f(3, 2))
    call check(error, trunc_sample_mu(tr, phases(2), 2, 3, nearest(u_b, -1.0_wp)) <= &
               tr%u_t(3, 2), 'body branch returns mu > u_t')
    ! hand-made tables: no flat part (1 - f - body = 0), u = 1 reaches the cone branch
    tr0%n_levels = 1
    tr0%n_phases = 1
    allocate (tr0%f(1, 1), tr0%u_t(1, 1), tr0%body(1, 1), tr0%p_flat(1, 1), tr0%mu_peak(1))
    tr0%f = 0.0_wp
    tr0%u_t = 0.9_wp
    tr0%body = 1.0_wp
    tr0%p_flat = 0.0_wp
    tr0%mu_peak = 2.0_wp
    mu = trunc_sample_mu(tr0, phases(1), 1, 1, 1.0_wp)
    call check(error, ieee_is_finite(mu), 'zero flat part: mu not finite')
    call check_close(error, mu, 0.9_wp, abs_tol=1.0e-15_wp, label='zero flat part: mu = u_t')
  end subroutine test_sampler_edges

  !> Chi-square test, HG 0.85 at level 3 of 4 up to 30 deg (Theta_t = 20 deg).
  subroutine test_chi2_hg(error)
    type(error_t), allocatable, intent(out) :: error
    type(truncation_t) :: tr
    type(phase_t) :: phases(1)
    phases(1) = hg(0.85_wp)
    call truncation_init(tr, phases, 30.0_wp, 4, 30.0_wp, error)
    if (allocated(error)) return
    call chi2_trunc(error, tr, phases(1), 1, 3, 1_i8)
  end subroutine test_chi2_hg

  !> Chi-square test, HG 0.97 table at level 2 of 4 up to 30 deg (Theta_t = 10 deg), as the
  !> second phase function of the set.
  subroutine test_chi2_table(error)
    type(error_t), allocatable, intent(out) :: error
    type(truncation_t) :: tr
    type(phase_t) :: phases(2)
    phases = [hg(0.5_wp), hg_table(0.97_wp)]
    call truncation_init(tr, phases, 30.0_wp, 4, 30.0_wp, error)
    if (allocated(error)) return
    call chi2_trunc(error, tr, phases(2), 2, 2, 2_i8)
  end subroutine test_chi2_table

  !> mu_peak: P(mu_peak) = pf_peak on the forward side (HG 0.85 with pf_peak = 30, closed form
  !> 1 - mu = (((1 - g^2)/30)^(2/3) - (1 - g)^2)/(2 g)); 2 when P(1) = 82.2 < pf_peak = 100;
  !> -1 when P >= pf_peak everywhere; a table's crossing lies on its own interpolant.
  subroutine test_mu_peak(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: G = 0.85_wp
    type(truncation_t) :: tr
    type(phase_t) :: phases(3)
    real(wp) :: mu_ref, mu
    integer :: k
    phases = [hg(G), hg_table(G), new_phase_isotropic()]
    call truncation_init(tr, phases, 10.0_wp, 2, 30.0_wp, error)
    if (allocated(error)) return
    mu_ref = 1.0_wp - (((1.0_wp - G*G)/30.0_wp)**(2.0_wp/3.0_wp) - (1.0_wp - G)**2)/(2.0_wp*G)
    call check_close(error, tr%mu_peak(1), mu_ref, abs_tol=1.0e-12_wp, label='HG mu_peak')
    call check_close(error, phase_eval(phases(1), tr%mu_peak(1)), 30.0_wp, rel_tol=1.0e-9_wp, &
                     label='HG P(mu_peak)')
    call check_close(error, phase_eval(phases(2), tr%mu_peak(2)), 30.0_wp, rel_tol=1.0e-9_wp, &
                     label='table P(mu_peak)')
    call check_close(error, tr%mu_peak(2), mu_ref, abs_tol=1.0e-4_wp, label='table mu_peak')
    do k = 1, 50
      mu = tr%mu_peak(2) + (1.0_wp - tr%mu_peak(2))*k/50.0_wp
      call check(error, phase_eval(phases(2), mu) >= 30.0_wp, 'table P < pf_peak above mu_peak')
    end do
    call check(error, same(tr%mu_peak(3), 2.0_wp), 'isotropic mu_peak /= 2 for pf_peak = 30')
    if (allocated(error)) return   ! the next call resets error (intent(out))
    call truncation_init(tr, phases, 10.0_wp, 2, 100.0_wp, error)
    if (allocated(error)) return
    call check(error, all(same(tr%mu_peak, 2.0_wp)), 'mu_peak /= 2 for pf_peak = 100 > P(1)')
    if (allocated(error)) return   ! the next call resets error (intent(out))
    call truncation_init(tr, phases, 10.0_wp, 2, 0.01_wp, error)
    if (allocated(error)) return
    call check(error, all(same(tr%mu_peak, -1.0_wp)), 'mu_peak /= -1 for pf_peak below min P')
  end subroutine test_mu_peak

  !> Out-of-range arguments give an error naming the argument.
  subroutine test_bad_arguments(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(truncation_t) :: tr
    type(phase_t) :: phases(1)
    real(wp) :: nan
    nan = ieee_value(1.0_wp, ieee_quiet_nan)
    phases(1) = hg(0.85_wp)
    call truncation_init(tr, phases, 30.0_wp, 0, 30.0_wp, err)
    call expect(error, err, 'n_levels')
    call truncation_init(tr, phases, -1.0_wp, 2, 30.0_wp, err)
    call expect(error, err, 'theta_max_deg')
    call truncation_init(tr, phases, 90.0_wp, 2, 30.0_wp, err)
    call expect(error, err, 'theta_max_deg')
    call truncation_init(tr, phases, nan, 2, 30.0_wp, err)
    call expect(error, err, 'theta_max_deg')
    call truncation_init(tr, phases, 30.0_wp, 2, 0.0_wp, err)
    call expect(error, err, 'pf_peak')
    call truncation_init(tr, phases, 30.0_wp, 2, -5.0_wp, err)
    call expect(error, err, 'pf_peak')
    call truncation_init(tr, phases, 30.0_wp, 2, nan, err)
    call expect(error, err, 'pf_peak')
    ! the edges of the valid ranges are accepted
    call truncation_init(tr, phases, 89.9_wp, 1, 1.0e-9_wp, err)
    call check(error, .not. allocated(err), 'valid arguments rejected')
  end subroutine test_bad_arguments

  !> Fail unless `err` is set and its message names `arg`.
  subroutine expect(error, err, arg)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: arg
    call check(error, allocated(err), 'bad '//arg//' accepted')
    if (allocated(error)) return
    call check(error, index(err%message, arg) > 0, "message '"//err%message// &
               "' does not name "//arg)
  end subroutine expect

end module test_truncation_suite

program test_truncation
  use kumo_testing, only: run_unittests
  use test_truncation_suite, only: collect_truncation
  implicit none
  integer :: n_failed
  call run_unittests('truncation', collect_truncation(), n_failed)
  if (n_failed > 0) error stop 1
end program test_truncation
