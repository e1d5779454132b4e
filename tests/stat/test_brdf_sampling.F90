! SPDX-License-Identifier: BSD-3-Clause
!> Statistical tests of kumo_brdf: chi-square tests of `brdf_sample` against the density
!> R mu_out/alpha(mu_in) of every model, and the envelope-violation counter.
!>
!> Each case draws N = 200,000 reflected directions for one incident direction (fixed seed, one
!> stream per case) and counts them in 20 x 36 bins of (mu_out, relative azimuth), the azimuth
!> measured from the incident photon's horizontal heading (0 = forward/specular side). The
!> expected bin probabilities are integrals of mu_out R over each bin computed here by 8 x 8
!> Gauss-Legendre points from `brdf_eval` (the model itself, independent of the samplers'
!> envelopes and of the albedo tables), normalised by their sum. Bins expecting fewer than 5
!> samples are pooled into one. The test passes when the chi-square p-value (regularised upper
!> incomplete gamma function, computed here) is at least 1e-3, and when no envelope violation
!> was counted.
module test_kumo_brdf_sampling
  use, intrinsic :: iso_fortran_env, only: output_unit
  use kumo_kinds, only: wp, i8
  use kumo_constants, only: PI, DEG2RAD
  use kumo_math, only: gauss_legendre01
  use kumo_rng, only: rng_t, rng_init
  use kumo_brdf, only: BRDF_LAMBERT, BRDF_DSM, BRDF_RPV, BRDF_LSRT, brdf_params_t, brdf_table_t, &
                       brdf_params, brdf_table_init, brdf_sample, brdf_eval, &
                       cox_munk_slope_variance, lsrt_grid_t, lsrt_grid_init, &
                       brdf_table_init_grid
  use kumo_testing, only: error_t, unittest_t, new_unittest, check
  implicit none
  private
  public :: collect_brdf_sampling

  integer(i8), parameter :: SEED = 20250312_i8   !! fixed; never changed to make a test pass
  integer, parameter :: N_SAMPLES = 200000
  integer, parameter :: N_MU = 20, N_PHI = 36
  integer, parameter :: N_GAUSS = 8
  real(wp), parameter :: MIN_EXPECTED = 5.0_wp
  real(wp), parameter :: P_MIN = 1.0e-3_wp
  real(wp), parameter :: PHI0 = 30.0_wp*DEG2RAD   !! azimuth of the incident photon's heading

contains

  !> All tests of this suite.
  function collect_brdf_sampling() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('chi2_lambert', test_lambert), &
             new_unittest('chi2_dsm_glint_u5', test_dsm_glint), &
             new_unittest('chi2_dsm_diffuse_absorbing_u10_75deg', test_dsm_mixed), &
             new_unittest('chi2_rpv_hot_spot', test_rpv_hot_spot), &
             new_unittest('chi2_rpv_forward_between_nodes', test_rpv_forward), &
             new_unittest('chi2_lsrt_clipped_alb_n98', test_lsrt_clipped), &
             new_unittest('chi2_lsrt_volume', test_lsrt_volume), &
             new_unittest('chi2_lsrt_map_table_clipped', test_lsrt_grid_clipped), &
             new_unittest('chi2_lsrt_map_table_volume', test_lsrt_grid_volume)]
  end function collect_brdf_sampling

  subroutine test_lambert(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_case(error, brdf_params(BRDF_LAMBERT, [0.3_wp]), 30.0_wp, 1_i8, 'lambert')
  end subroutine test_lambert

  !> Sun glint of a sea at U = 5 m/s (sigma^2 = 0.0286), no diffuse part, 40 deg incidence.
  subroutine test_dsm_glint(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_case(error, brdf_params(BRDF_DSM, [0.0_wp, 0.0_wp, 1.334_wp, 0.0_wp, &
                                                 cox_munk_slope_variance(5.0_wp)]), &
                   40.0_wp, 2_i8, 'dsm glint')
  end subroutine test_dsm_glint

  !> Diffuse part, absorbing index, U = 10 m/s at 75 deg (shadowing, rays lost below the
  !> horizon rejected).
  subroutine test_dsm_mixed(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_case(error, brdf_params(BRDF_DSM, [0.2_wp, 0.3_wp, 1.334_wp, 0.01_wp, &
                                                 cox_munk_slope_variance(10.0_wp)]), &
                   75.0_wp, 3_i8, 'dsm mixed')
  end subroutine test_dsm_mixed

  !> Strong backward scattering with a sharp hot spot (Theta = -0.3, h = 0.3).
  subroutine test_rpv_hot_spot(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_case(error, brdf_params(BRDF_RPV, [0.1_wp, 0.6_wp, -0.3_wp, 0.3_wp]), 50.0_wp, &
                   4_i8, 'rpv hot spot')
  end subroutine test_rpv_hot_spot

  !> Forward scattering, k > 1, incidence between table nodes.
  subroutine test_rpv_forward(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_case(error, brdf_params(BRDF_RPV, [0.2_wp, 1.3_wp, 0.2_wp, 1.0_wp]), 72.5_wp, &
                   5_i8, 'rpv forward')
  end subroutine test_rpv_forward

  !> The seed text's "alb_N98" weights, where the kernel sum is clipped at 0.
  subroutine test_lsrt_clipped(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_case(error, brdf_params(BRDF_LSRT, [0.3_wp, 0.07_wp, 0.03_wp]), 45.0_wp, 6_i8, &
                   'lsrt alb_N98')
  end subroutine test_lsrt_clipped

  !> Volume-scattering dominated LSRT near normal incidence.
  subroutine test_lsrt_volume(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_case(error, brdf_params(BRDF_LSRT, [0.1_wp, 0.02_wp, 0.6_wp]), 20.0_wp, 7_i8, &
                   'lsrt volume')
  end subroutine test_lsrt_volume

  !> The two LSRT cases above with the tables of surface maps (`brdf_table_init_grid`: albedo
  !> from shared kernel values, envelopes from the kernels' row extremes).
  subroutine test_lsrt_grid_clipped(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_case(error, brdf_params(BRDF_LSRT, [0.3_wp, 0.07_wp, 0.03_wp]), 45.0_wp, 8_i8, &
                   'lsrt alb_N98 (map table)', grid=.true.)
  end subroutine test_lsrt_grid_clipped

  subroutine test_lsrt_grid_volume(error)
    type(error_t), allocatable, intent(out) :: error
    call chi2_case(error, brdf_params(BRDF_LSRT, [0.1_wp, 0.02_wp, 0.6_wp]), 20.0_wp, 9_i8, &
                   'lsrt volume (map table)', grid=.true.)
  end subroutine test_lsrt_grid_volume

  !> Sample, bin, compare (see the module text).
  subroutine chi2_case(error, p, theta0_deg, stream, label, grid)
    type(error_t), allocatable, intent(inout) :: error
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: theta0_deg
    integer(i8), intent(in) :: stream
    character(len=*), intent(in) :: label
    logical, intent(in), optional :: grid   !! use the table of a surface map
    type(error_t), allocatable :: err
    type(lsrt_grid_t) :: lg
    type(brdf_table_t) :: tab
    type(rng_t) :: rng
    real(wp) :: u_in(3), u_out(3), mu0, expected(N_MU, N_PHI), chi2, pval, pooled_e, phi, h(2)
    integer :: counts(N_MU, N_PHI), i, im, ip, dof, pooled_n
    integer(i8) :: n_viol
    character(len=160) :: msg

    if (allocated(error)) return
    if (present(grid)) then
      call lsrt_grid_init(lg)
      call brdf_table_init_grid(tab, p, lg, err)
    else
      call brdf_table_init(tab, p, err)
    end if
    call check(error, .not. allocated(err), label//': table init failed')
    if (allocated(error)) return
    mu0 = cos(theta0_deg*DEG2RAD)
    u_in = [sin(theta0_deg*DEG2RAD)*cos(PHI0), sin(theta0_deg*DEG2RAD)*sin(PHI0), -mu0]

    call rng_init(rng, SEED, stream)
    counts = 0
    n_viol = 0_i8
    do i = 1, N_SAMPLES
      call brdf_sample(tab, u_in, rng, u_out, n_viol)
      if (.not. (u_out(3) > 0.0_wp .and. abs(norm2(u_out) - 1.0_wp) < 1.0e-12_wp)) then
        call check(error, .false., label//': sampled direction not a unit vector upward')
        return
      end if
      ! azimuth of the outgoing heading relative to the incident heading, in [0, 2 pi)
      h = [u_in(1)*u_out(1) + u_in(2)*u_out(2), u_in(1)*u_out(2) - u_in(2)*u_out(1)]
      phi = modulo(atan2(h(2), h(1)), 2.0_wp*PI)
      im = min(int(u_out(3)*N_MU), N_MU - 1) + 1
      ip = min(int(phi/(2.0_wp*PI)*N_PHI), N_PHI - 1) + 1
      counts(im, ip) = counts(im, ip) + 1
    end do

    call bin_probabilities(p, mu0, expected)
    expected = expected*N_SAMPLES
    chi2 = 0.0_wp
    dof = -1
    pooled_e = 0.0_wp
    pooled_n = 0
    do ip = 1, N_PHI
      do im = 1, N_MU
        if (expected(im, ip) < MIN_EXPECTED) then
          pooled_e = pooled_e + expected(im, ip)
          pooled_n = pooled_n + counts(im, ip)
        else
          chi2 = chi2 + (counts(im, ip) - expected(im, ip))**2/expected(im, ip)
          dof = dof + 1
        end if
      end do
    end do
    if (pooled_e > 0.0_wp) then
      chi2 = chi2 + (pooled_n - pooled_e)**2/pooled_e
      dof = dof + 1
    end if
    pval = gamma_q(0.5_wp*dof, 0.5_wp*chi2)
    write (msg, '(a, f0.1, a, i0, a, es10.2e3, a, i0)') 'chi2 = ', chi2, ', dof = ', dof, &
      ', p = ', pval, ', envelope violations = ', n_viol
    write (output_unit, '(a)') '  '//label//': '//trim(msg)
    call check(error, pval >= P_MIN, label//': '//trim(msg)//' (p < 1e-3)')
    call check(error, n_viol == 0_i8, label//': '//trim(msg))
  end subroutine chi2_case

  !> Probabilities of the (mu_out, relative azimuth) bins: Int mu R dmu dphi over each bin by
  !> N_GAUSS^2 Gauss-Legendre points, normalised by the sum over all bins.
  subroutine bin_probabilities(p, mu0, prob)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu0
    real(wp), intent(out) :: prob(N_MU, N_PHI)
    real(wp) :: x(N_GAUSS), w(N_GAUSS), cphi(N_GAUSS, N_PHI), mu, s
    integer :: im, ip, a, b
    call gauss_legendre01(N_GAUSS, x, w)
    do ip = 1, N_PHI
      do b = 1, N_GAUSS
        cphi(b, ip) = cos((ip - 1 + x(b))*2.0_wp*PI/N_PHI)
      end do
    end do
    do ip = 1, N_PHI
      do im = 1, N_MU
        s = 0.0_wp
        do a = 1, N_GAUSS
          mu = (im - 1 + x(a))/N_MU
          do b = 1, N_GAUSS
            s = s + w(a)*w(b)*mu*brdf_eval(p, mu0, mu, cphi(b, ip))
          end do
        end do
        prob(im, ip) = s
      end do
    end do
    prob = prob/sum(prob)
  end subroutine bin_probabilities

  !> Regularised upper incomplete gamma function Q(a, x) = Gamma(a, x)/Gamma(a): the power
  !> series of P for x < a + 1, otherwise the continued fraction of Q (modified Lentz).
  function gamma_q(a, x) result(q)
    real(wp), intent(in) :: a, x
    real(wp) :: q
    real(wp) :: term, total, ap, b, c, d, h, an, del, lnpre
    integer :: n
    if (x <= 0.0_wp) then
      q = 1.0_wp
      return
    end if
    lnpre = a*log(x) - x - log_gamma(a)
    if (x < a + 1.0_wp) then
      ap = a
      term = 1.0_wp/a
      total = term
      do n = 1, 10000
        ap = ap + 1.0_wp
        term = term*x/ap
        total = total + term
        if (abs(term) < abs(total)*1.0e-15_wp) exit
      end do
      q = 1.0_wp - total*exp(lnpre)
    else
      b = x + 1.0_wp - a
      c = 1.0_wp/1.0e-300_wp
      d = 1.0_wp/b
      h = d
      do n = 1, 10000
        an = -n*(n - a)
        b = b + 2.0_wp
        d = an*d + b
        if (abs(d) < 1.0e-300_wp) d = 1.0e-300_wp
        c = b + an/c
        if (abs(c) < 1.0e-300_wp) c = 1.0e-300_wp
        d = 1.0_wp/d
        del = d*c
        h = h*del
        if (abs(del - 1.0_wp) < 1.0e-15_wp) exit
      end do
      q = exp(lnpre)*h
    end if
  end function gamma_q

end module test_kumo_brdf_sampling

program test_brdf_sampling
  use test_kumo_brdf_sampling, only: collect_brdf_sampling
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_brdf (sampling, chi-square)', collect_brdf_sampling(), n_failed)
  if (n_failed > 0) error stop 1
end program test_brdf_sampling
