! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_brdf: parameter handling and validation, the models against independent
!> implementations written here (Fresnel in Liou's real form, Lucht's trigonometric kernel
!> form, RPV with the tangent distance G, DSM from explicit facet vectors, Smith's shadowing
!> by direct integration), reciprocity, azimuth conventions, published LSRT kernel integrals,
!> directional albedos against brute-force midpoint rules and published numbers, and the
!> albedo tables of the photon loop (interpolation, clamping, scaling).
module test_kumo_brdf
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use kumo_kinds, only: wp, i8
  use kumo_constants, only: PI, DEG2RAD
  use kumo_math, only: gauss_legendre01
  use kumo_rng, only: rng_t, rng_init, rng_uniform
  use kumo_brdf, only: BRDF_BLACK, BRDF_LAMBERT, BRDF_DSM, BRDF_RPV, BRDF_LSRT, BRDF_NAMES, &
                       BRDF_NPAR, brdf_params_t, brdf_table_t, brdf_params, &
                       brdf_kind_from_name, brdf_validate, brdf_eval, brdf_eval_dir, &
                       brdf_albedo_quad, brdf_table_init, brdf_albedo, brdf_table_eval, &
                       brdf_table_eval_dir, cox_munk_slope_variance, fresnel_reflectance, &
                       dsm_shadowing, ross_thick_kernel, li_sparse_r_kernel, &
                       lsrt_kernel_albedos, lsrt_grid_t, lsrt_grid_init, brdf_table_init_grid, BRDF_NALB, &
                       lsrt_negative_fraction
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  use kumo_error, only: str
  implicit none
  private
  public :: collect_brdf

  integer(i8), parameter :: SEED = 20250311_i8
  integer, parameter :: N_SET = 7   !! size of model_set()

contains

  !> All tests of this suite.
  function collect_brdf() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('kind_names_and_params', test_names), &
             new_unittest('bad_parameters_rejected', test_validation), &
             new_unittest('fresnel_against_liou_form', test_fresnel), &
             new_unittest('cox_munk_slope_variance', test_cox_munk), &
             new_unittest('shadowing_against_integral', test_shadowing), &
             new_unittest('lsrt_kernels_against_lucht_form', test_lsrt_kernels), &
             new_unittest('rpv_against_tangent_form', test_rpv_form), &
             new_unittest('dsm_against_facet_vectors', test_dsm_form), &
             new_unittest('reciprocity', test_reciprocity), &
             new_unittest('azimuth_convention', test_azimuth_convention), &
             new_unittest('lsrt_black_and_white_sky', test_lsrt_published), &
             new_unittest('albedo_against_brute_force', test_albedo_brute), &
             new_unittest('dsm_albedo_fresnel_limit', test_dsm_fresnel_limit), &
             new_unittest('lambert_and_black_albedo', test_lambert_black), &
             new_unittest('table_interpolation', test_table_interp), &
             new_unittest('table_albedo_midpoints', test_table_midpoints), &
             new_unittest('albedo_clamped_to_one', test_clamp), &
             new_unittest('map_tables_of_lsrt', test_lsrt_grid)]
  end function collect_brdf

  ! ------------------------------------------------------------------------------------------
  ! Independent reference implementations
  ! ------------------------------------------------------------------------------------------

  !> Fresnel reflectance of unpolarised light in Liou's real form (An Introduction to
  !> Atmospheric Radiation, 2002, eqs. 5.2.x; seed text eqs. 3.7.5-8): U, V from
  !> G = n^2 - k^2 - sin^2.
  pure function liou_fresnel(n, k, c) result(r)
    real(wp), intent(in) :: n, k, c
    real(wp) :: r
    real(wp) :: s2, g, root, u, v, a, rpar, rperp
    s2 = 1.0_wp - c*c
    g = n*n - k*k - s2
    root = sqrt(g*g + 4.0_wp*n*n*k*k)
    u = sqrt(0.5_wp*(root + g))
    v = sqrt(max(0.0_wp, 0.5_wp*(root - g)))
    a = n*n - k*k
    rpar = ((a*c - u)**2 + (2.0_wp*n*k*c - v)**2)/((a*c + u)**2 + (2.0_wp*n*k*c + v)**2)
    rperp = ((c - u)**2 + v*v)/((c + u)**2 + v*v)
    r = 0.5_wp*(rpar + rperp)
  end function liou_fresnel

  !> Smith's Lambda by direct integration of its definition: for a Gaussian of per-component
  !> variance sigma^2/2, Lambda = Int_a^inf (q - a) P1(q) dq / a, a = cot(theta),
  !> P1(q) = exp(-q^2/sigma^2)/(sqrt(pi) sigma) (midpoint rule to a + 12 sigma).
  pure function smith_lambda_integral(mu, sigma) result(lam)
    real(wp), intent(in) :: mu, sigma
    real(wp) :: lam
    integer, parameter :: n = 200000
    real(wp) :: a, h, q
    integer :: i
    a = mu/sqrt(1.0_wp - mu*mu)
    h = 12.0_wp*sigma/n
    lam = 0.0_wp
    do i = 1, n
      q = a + (i - 0.5_wp)*h
      lam = lam + (q - a)*exp(-q*q/(sigma*sigma))
    end do
    lam = lam*h/(sqrt(PI)*sigma)/a
  end function smith_lambda_integral

  !> Lucht et al. (2000) kernels in their trigonometric form (eqs. 38-44), b/r = 1, h/b = 2,
  !> with the relative azimuth phi measured from the hot spot (phi = pi - dphi).
  pure subroutine lucht_kernels(th0, th1, phi, kv, kg)
    real(wp), intent(in) :: th0, th1, phi
    real(wp), intent(out) :: kv, kg
    real(wp) :: cx, xi, d2, sec0, sec1, ct, t, o
    cx = cos(th0)*cos(th1) + sin(th0)*sin(th1)*cos(phi)
    xi = acos(min(1.0_wp, max(-1.0_wp, cx)))
    kv = ((0.5_wp*PI - xi)*cos(xi) + sin(xi))/(cos(th0) + cos(th1)) - 0.25_wp*PI
    d2 = tan(th0)**2 + tan(th1)**2 - 2.0_wp*tan(th0)*tan(th1)*cos(phi)
    sec0 = 1.0_wp/cos(th0)
    sec1 = 1.0_wp/cos(th1)
    ct = 2.0_wp*sqrt(d2 + (tan(th0)*tan(th1)*sin(phi))**2)/(sec0 + sec1)
    ct = min(1.0_wp, max(-1.0_wp, ct))
    t = acos(ct)
    o = (t - sin(t)*cos(t))*(sec0 + sec1)/PI
    kg = o - sec0 - sec1 + 0.5_wp*(1.0_wp + cx)*sec0*sec1
  end subroutine lucht_kernels

  !> RPV BRDF (Rahman et al. 1993) in its angular form with the tangent distance
  !> G = sqrt(tan^2 th0 + tan^2 th1 - 2 tan th0 tan th1 cos phi), phi from the hot spot.
  pure function rpv_reference(rho0, k, th, h, th0, th1, phi) result(r)
    real(wp), intent(in) :: rho0, k, th, h, th0, th1, phi
    real(wp) :: r
    real(wp) :: m0, m1, cg, f, g
    m0 = cos(th0)
    m1 = cos(th1)
    cg = m0*m1 + sin(th0)*sin(th1)*cos(phi)
    f = (1.0_wp - th*th)/(1.0_wp + th*th + 2.0_wp*th*cg)**1.5_wp
    g = sqrt(max(0.0_wp, tan(th0)**2 + tan(th1)**2 - 2.0_wp*tan(th0)*tan(th1)*cos(phi)))
    r = rho0*(m0*m1*(m0 + m1))**(k - 1.0_wp)*f*(1.0_wp + (1.0_wp - rho0)/(h + g))/PI
  end function rpv_reference

  !> DSM BRDF from the facet geometry (Cox and Munk 1954; Nakajima and Tanaka 1983): facet
  !> normal n along Omega0 + Omega1, Gaussian slope density of (zx, zy) = -(n_x, n_y)/n_z,
  !> R_s = R_F(Omega0 . n) f_s P/(4 mu0 mu1 n_z^4), plus the Lambertian part.
  pure function dsm_reference(c, u_in, u_out) result(r)
    real(wp), intent(in) :: c(5), u_in(3), u_out(3)
    real(wp) :: r
    real(wp) :: o0(3), n(3), zx, zy, pdf, fs, sigma, mu0, mu1
    o0 = -u_in
    n = (o0 + u_out)/norm2(o0 + u_out)
    zx = -n(1)/n(3)
    zy = -n(2)/n(3)
    sigma = sqrt(c(5))
    pdf = exp(-(zx*zx + zy*zy)/c(5))/(PI*c(5))
    mu0 = o0(3)
    mu1 = u_out(3)
    fs = 1.0_wp/(1.0_wp + smith_lambda_closed(mu0, sigma) + smith_lambda_closed(mu1, sigma))
    r = c(2)*c(1)/PI + (1.0_wp - c(2))*liou_fresnel(c(3), c(4), dot_product(o0, n))*fs*pdf/ &
        (4.0_wp*mu0*mu1*n(3)**4)
  end function dsm_reference

  !> Smith's Lambda in closed form (checked against the integral in test_shadowing).
  pure function smith_lambda_closed(mu, sigma) result(lam)
    real(wp), intent(in) :: mu, sigma
    real(wp) :: lam
    real(wp) :: nu
    if (mu >= 1.0_wp) then
      lam = 0.0_wp
      return
    end if
    nu = mu/(sigma*sqrt(1.0_wp - mu*mu))
    lam = 0.5_wp*(exp(-nu*nu)/(sqrt(PI)*nu) - erfc(nu))
  end function smith_lambda_closed

  !> Random unit vector with z of the given sign and |z| >= zmin.
  function random_dir(rng, up, zmin) result(u)
    type(rng_t), intent(inout) :: rng
    logical, intent(in) :: up
    real(wp), intent(in) :: zmin
    real(wp) :: u(3)
    real(wp) :: mu, phi, s
    mu = zmin + (1.0_wp - zmin)*rng_uniform(rng)
    phi = 2.0_wp*PI*rng_uniform(rng)
    s = sqrt(1.0_wp - mu*mu)
    u = [s*cos(phi), s*sin(phi), merge(mu, -mu, up)]
  end function random_dir

  !> Directional albedo by the midpoint rule on n x n cells in (mu_out, dphi in [0, pi]).
  function brute_albedo(p, mu0, n) result(s)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu0
    integer, intent(in) :: n
    real(wp) :: s
    real(wp) :: cphi(n), mu
    integer :: i, j
    do j = 1, n
      cphi(j) = cos((j - 0.5_wp)*PI/n)
    end do
    s = 0.0_wp
    do i = 1, n
      mu = (i - 0.5_wp)/n
      do j = 1, n
        s = s + mu*brdf_eval(p, mu0, mu, cphi(j))
      end do
    end do
    s = s*2.0_wp*PI/(real(n, wp)*n)
  end function brute_albedo

  !> Fail unless `err` is allocated and its message contains `part`.
  subroutine expect_error(error, err, part, what)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: part, what
    if (allocated(error)) return
    call check(error, allocated(err), what//': no error reported')
    if (allocated(error)) return
    call check(error, index(err%message, part) > 0, &
               what//': message "'//err%message//'" lacks "'//part//'"')
  end subroutine expect_error

  !> A set of valid parameters of every kind (with clipping, complex index, diffuse part).
  function model_set() result(ps)
    type(brdf_params_t) :: ps(N_SET)
    ps = [brdf_params(BRDF_LAMBERT, [0.3_wp]), &
          brdf_params(BRDF_RPV, [0.15_wp, 0.75_wp, -0.2_wp, 1.0_wp]), &
          brdf_params(BRDF_RPV, [0.05_wp, 1.4_wp, 0.25_wp, 0.3_wp]), &
          brdf_params(BRDF_LSRT, [0.3_wp, 0.07_wp, 0.03_wp]), &
          brdf_params(BRDF_LSRT, [0.1_wp, 0.02_wp, 0.6_wp]), &
          brdf_params(BRDF_DSM, [0.0_wp, 0.0_wp, 1.334_wp, 0.0_wp, 0.0286_wp]), &
          brdf_params(BRDF_DSM, [0.25_wp, 0.2_wp, 1.5_wp, 0.8_wp, 0.2_wp])]
  end function model_set

  ! ------------------------------------------------------------------------------------------
  ! Tests
  ! ------------------------------------------------------------------------------------------

  subroutine test_names(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(brdf_params_t) :: p
    integer :: kind, i
    do i = 0, 4
      call brdf_kind_from_name(BRDF_NAMES(i), kind, err)
      call check(error, kind == i .and. .not. allocated(err), 'name '//BRDF_NAMES(i))
    end do
    call brdf_kind_from_name('  LSRT ', kind, err)
    call check(error, kind == BRDF_LSRT, "'  LSRT ' is not lsrt")
    call brdf_kind_from_name('Cox-Munk', kind, err)
    call check(error, kind == -1, 'unknown name gives kind -1')
    call expect_error(error, err, "'Cox-Munk' must be one of black, lambert, dsm, rpv, lsrt", &
                      'unknown name')
    p = brdf_params(BRDF_RPV, [0.1_wp, 0.8_wp])
    call check(error, p%kind == BRDF_RPV .and. size(p%c) == BRDF_NPAR, 'brdf_params kind')
    call check(error, all(p%c == [0.1_wp, 0.8_wp, 0.0_wp, 0.0_wp, 0.0_wp]), &
               'brdf_params pads with zeros')
  end subroutine test_names

  subroutine test_validation(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(brdf_table_t) :: tab
    type(brdf_params_t) :: ps(N_SET)
    real(wp) :: nan
    integer :: i
    nan = ieee_value(nan, ieee_quiet_nan)
    ps = model_set()
    do i = 1, size(ps)
      call brdf_validate(ps(i), err)
      call check(error, .not. allocated(err), 'valid set '//BRDF_NAMES(ps(i)%kind)//' rejected')
    end do
    call brdf_validate(brdf_params(BRDF_BLACK, [-5.0_wp]), err)
    call check(error, .not. allocated(err), 'black ignores its parameters')
    call brdf_validate(brdf_params(BRDF_LAMBERT, [-0.1_wp]), err)
    call expect_error(error, err, 'brdf lambert albedo = -0.1 must be within [0, 1]', 'albedo')
    call brdf_validate(brdf_params(BRDF_LAMBERT, [nan]), err)
    call expect_error(error, err, 'lambert albedo = NaN', 'NaN albedo')
    call brdf_validate(brdf_params(BRDF_RPV, [1.2_wp, 0.7_wp, 0.0_wp, 1.0_wp]), err)
    call expect_error(error, err, 'brdf rpv rho0 = 1.2 must be within [0, 1]', 'rho0 > 1')
    call brdf_validate(brdf_params(BRDF_RPV, [-0.01_wp, 0.7_wp, 0.0_wp, 1.0_wp]), err)
    call expect_error(error, err, 'brdf rpv rho0 = -0.01 must be within [0, 1]', 'rho0 < 0')
    call brdf_validate(brdf_params(BRDF_RPV, [0.1_wp, 0.0_wp, 0.0_wp, 1.0_wp]), err)
    call expect_error(error, err, 'brdf rpv k = 0 must satisfy 0 < k <= 2', 'k = 0')
    call brdf_validate(brdf_params(BRDF_RPV, [0.1_wp, 0.7_wp, -1.0_wp, 1.0_wp]), err)
    call expect_error(error, err, 'brdf rpv Theta = -1 must satisfy |Theta| < 1', 'Theta')
    call brdf_validate(brdf_params(BRDF_RPV, [0.1_wp, 0.7_wp, 0.0_wp]), err)
    call expect_error(error, err, 'brdf rpv hot-spot parameter h = 0 must be > 0', 'h = 0')
    call brdf_validate(brdf_params(BRDF_DSM, [-0.2_wp, 0.1_wp, 1.33_wp, 0.0_wp, 0.02_wp]), err)
    call expect_error(error, err, 'brdf dsm diffuse albedo a_d = -0.2 must be within [0, 1]', 'a_d')
    call brdf_validate(brdf_params(BRDF_DSM, [0.2_wp, 1.5_wp, 1.33_wp, 0.0_wp, 0.02_wp]), err)
    call expect_error(error, err, 'brdf dsm diffuse fraction f_d = 1.5 must be within [0, 1]', &
                      'f_d')
    call brdf_validate(brdf_params(BRDF_DSM, [0.2_wp, 0.1_wp, 0.9_wp, 0.0_wp, 0.02_wp]), err)
    call expect_error(error, err, &
                      'brdf dsm refractive index real part n_r = 0.9 must be within [1, 100]', 'n_r')
    call brdf_validate(brdf_params(BRDF_DSM, [0.2_wp, 0.1_wp, 1.33_wp, -1.0e-3_wp, 0.02_wp]), err)
    call expect_error(error, err, &
                      'brdf dsm refractive index imaginary part n_i = -0.001 must be within [0, 100]', 'n_i')
    call brdf_validate(brdf_params(BRDF_DSM, [0.2_wp, 0.1_wp, 1.33_wp, 0.0_wp, 0.0_wp]), err)
    call expect_error(error, err, &
                      'brdf dsm slope variance sigma2 = 0 must satisfy 0 < sigma2 <= 100', &
                      'sigma2 = 0')
    call brdf_validate(brdf_params(BRDF_LSRT, [0.3_wp, -0.07_wp, 0.03_wp]), err)
    call expect_error(error, err, 'brdf lsrt k_geo = -0.07 must be >= 0 and finite', 'k_geo')
    call brdf_validate(brdf_params(BRDF_LSRT, [0.3_wp, 0.07_wp, nan]), err)
    call expect_error(error, err, 'brdf lsrt k_vol = NaN must be >= 0 and finite', 'k_vol')
    ! a kernel sum negative over most of the hemisphere (k_geo = k_iso) would be clamped to 0
    ! there: refused with the fraction (typical weights: 1-4 %)
    call brdf_validate(brdf_params(BRDF_LSRT, [0.1_wp, 0.1_wp, 0.05_wp]), err)
    call expect_error(error, err, 'negative for 66 % of the pairs', 'lsrt mostly negative')
    call check(error, lsrt_negative_fraction(brdf_params(BRDF_LSRT, [0.3_wp, 0.07_wp, &
               0.03_wp])) < 0.05_wp, 'alb_N98 weights: few clamped pairs')
    call brdf_validate(brdf_params(7, [0.3_wp]), err)
    call expect_error(error, err, 'brdf kind = 7 must be within [0, 4]', 'kind')
    ! the table constructor validates too
    call brdf_table_init(tab, brdf_params(BRDF_RPV, [1.2_wp, 0.7_wp, 0.0_wp, 1.0_wp]), err)
    call expect_error(error, err, 'brdf rpv rho0 = 1.2 must be within [0, 1]', 'table init')
  end subroutine test_validation

  !> Against Liou's real form at many angles and indices; closed forms at normal incidence
  !> (((n-1)^2 + k^2)/((n+1)^2 + k^2)) and at Brewster's angle (k = 0: r_p = 0, so
  !> R = r_s^2/2 with r_s = (n^2 - 1)/(n^2 + 1)); grazing incidence 1; n = 1 gives 0.
  subroutine test_fresnel(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: ns(4) = [1.0_wp, 1.334_wp, 1.5_wp, 3.0_wp]
    real(wp), parameter :: ks(4) = [0.0_wp, 1.0e-3_wp, 0.5_wp, 7.0_wp]
    real(wp) :: c, rb
    integer :: i, j, m
    do i = 1, size(ns)
      do j = 1, size(ks)
        call check_close(error, fresnel_reflectance(ns(i), ks(j), 1.0_wp), &
                         ((ns(i) - 1.0_wp)**2 + ks(j)**2)/((ns(i) + 1.0_wp)**2 + ks(j)**2), &
                         rel_tol=1.0e-13_wp, abs_tol=1.0e-16_wp, label='normal incidence')
        do m = 1, 89
          c = cos(m*DEG2RAD)
          call check_close(error, fresnel_reflectance(ns(i), ks(j), c), &
                           liou_fresnel(ns(i), ks(j), c), &
                           rel_tol=1.0e-11_wp, abs_tol=1.0e-15_wp, label='Liou form')
        end do
        call check_close(error, fresnel_reflectance(ns(i), ks(j), 0.0_wp), 1.0_wp, &
                         abs_tol=0.0_wp, label='grazing')
      end do
    end do
    call check_close(error, fresnel_reflectance(1.334_wp, 0.0_wp, 1.0_wp), 0.0204782_wp, &
                     abs_tol=1.0e-7_wp, label='water at normal incidence')
    rb = ((1.334_wp**2 - 1.0_wp)/(1.334_wp**2 + 1.0_wp))**2/2.0_wp
    call check_close(error, fresnel_reflectance(1.334_wp, 0.0_wp, cos(atan(1.334_wp))), rb, &
                     rel_tol=1.0e-12_wp, label='Brewster angle')
    call check_close(error, fresnel_reflectance(1.0_wp, 0.0_wp, 0.3_wp), 0.0_wp, &
                     abs_tol=1.0e-16_wp, label='n = 1')
  end subroutine test_fresnel

  !> sigma^2 = 0.003 + 0.00512 U (Cox and Munk 1954): U = 0, 5, 10 m/s.
  subroutine test_cox_munk(error)
    type(error_t), allocatable, intent(out) :: error
    call check_close(error, cox_munk_slope_variance(0.0_wp), 0.003_wp, rel_tol=1.0e-14_wp, &
                     label='U = 0')
    call check_close(error, cox_munk_slope_variance(5.0_wp), 0.0286_wp, rel_tol=1.0e-14_wp, &
                     label='U = 5')
    call check_close(error, cox_munk_slope_variance(10.0_wp), 0.0542_wp, rel_tol=1.0e-14_wp, &
                     label='U = 10')
    call check_close(error, cox_munk_slope_variance(-1.0_wp), 0.003_wp, rel_tol=1.0e-14_wp, &
                     label='U < 0')
  end subroutine test_cox_munk

  !> dsm_shadowing equals the defining integral of Smith's Lambda; 0 at the zenith.
  subroutine test_shadowing(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: mus(5) = [0.01_wp, 0.05_wp, 0.2_wp, 0.5_wp, 0.9_wp]
    real(wp), parameter :: sig2(3) = [0.003_wp, 0.0286_wp, 0.5_wp]
    integer :: i, j
    character(len=40) :: label
    do j = 1, size(sig2)
      do i = 1, size(mus)
        write (label, '(a, f0.3, a, f0.4)') 'Lambda mu = ', mus(i), ', sigma2 = ', sig2(j)
        call check_close(error, dsm_shadowing(mus(i), sqrt(sig2(j))), &
                         smith_lambda_integral(mus(i), sqrt(sig2(j))), rel_tol=1.0e-6_wp, &
                         abs_tol=1.0e-13_wp, label=trim(label))
      end do
    end do
    call check_close(error, dsm_shadowing(1.0_wp, 0.2_wp), 0.0_wp, abs_tol=0.0_wp, label='zenith')
  end subroutine test_shadowing

  !> Ross-Thick and Li-Sparse-R against Lucht's trigonometric form over random geometries;
  !> hot-spot values f_v = pi/(4 mu) - pi/4 and f_g = (1 - mu)/mu^2.
  subroutine test_lsrt_kernels(error)
    type(error_t), allocatable, intent(out) :: error
    type(rng_t) :: rng
    real(wp) :: th0, th1, dphi, kv, kg, mu
    integer :: i
    call rng_init(rng, SEED, 1_i8)
    do i = 1, 2000
      th0 = 0.5_wp*PI*0.98_wp*rng_uniform(rng)
      th1 = 0.5_wp*PI*0.98_wp*rng_uniform(rng)
      dphi = PI*rng_uniform(rng)
      call lucht_kernels(th0, th1, PI - dphi, kv, kg)
      call check_close(error, ross_thick_kernel(cos(th0), cos(th1), cos(dphi)), kv, &
                       abs_tol=1.0e-11_wp, rel_tol=1.0e-11_wp, label='Ross-Thick')
      call check_close(error, li_sparse_r_kernel(cos(th0), cos(th1), cos(dphi)), kg, &
                       abs_tol=1.0e-9_wp, rel_tol=1.0e-9_wp, label='Li-Sparse-R')
      if (allocated(error)) return
    end do
    do i = 1, 9
      mu = 0.1_wp*i
      call check_close(error, ross_thick_kernel(mu, mu, -1.0_wp), 0.25_wp*PI/mu - 0.25_wp*PI, &
                       rel_tol=1.0e-12_wp, abs_tol=1.0e-14_wp, label='Ross-Thick hot spot')
      call check_close(error, li_sparse_r_kernel(mu, mu, -1.0_wp), (1.0_wp - mu)/mu**2, &
                       rel_tol=1.0e-6_wp, abs_tol=1.0e-7_wp, label='Li-Sparse hot spot')
    end do
  end subroutine test_lsrt_kernels

  !> RPV against the angular form with the tangent distance G (hot spot at phi = 0).
  subroutine test_rpv_form(error)
    type(error_t), allocatable, intent(out) :: error
    type(rng_t) :: rng
    type(brdf_params_t) :: p
    real(wp) :: th0, th1, dphi, ref
    integer :: i
    call rng_init(rng, SEED, 2_i8)
    do i = 1, 2000
      p = brdf_params(BRDF_RPV, [rng_uniform(rng), 0.2_wp + 1.6_wp*rng_uniform(rng), &
                                 -0.8_wp + 1.6_wp*rng_uniform(rng), 0.1_wp + 2.0_wp*rng_uniform(rng)])
      th0 = 0.5_wp*PI*0.98_wp*rng_uniform(rng)
      th1 = 0.5_wp*PI*0.98_wp*rng_uniform(rng)
      dphi = PI*rng_uniform(rng)
      ref = rpv_reference(p%c(1), p%c(2), p%c(3), p%c(4), th0, th1, PI - dphi)
      call check_close(error, brdf_eval(p, cos(th0), cos(th1), cos(dphi)), ref, &
                       rel_tol=1.0e-9_wp, abs_tol=1.0e-14_wp, label='RPV')
      if (allocated(error)) return
    end do
  end subroutine test_rpv_form

  !> DSM against the explicit facet construction, random geometries and parameters.
  subroutine test_dsm_form(error)
    type(error_t), allocatable, intent(out) :: error
    type(rng_t) :: rng
    real(wp) :: c(5), u_in(3), u_out(3), ref
    integer :: i
    call rng_init(rng, SEED, 3_i8)
    do i = 1, 2000
      c = [rng_uniform(rng), 0.5_wp*rng_uniform(rng), 1.0_wp + rng_uniform(rng), &
           merge(0.0_wp, 2.0_wp*rng_uniform(rng), i <= 1000), 0.003_wp + 0.3_wp*rng_uniform(rng)]
      u_in = random_dir(rng, .false., 0.02_wp)
      u_out = random_dir(rng, .true., 0.02_wp)
      ref = dsm_reference(c, u_in, u_out)
      call check_close(error, brdf_eval_dir(brdf_params(BRDF_DSM, c), u_in, u_out), ref, &
                       rel_tol=1.0e-9_wp, abs_tol=1.0e-300_wp, label='DSM')
      if (allocated(error)) return
    end do
  end subroutine test_dsm_form

  !> R(u_in, u_out) = R(-u_out, -u_in) to 1e-12 for every model, random geometries; the
  !> scalar form agrees with the vector form.
  subroutine test_reciprocity(error)
    type(error_t), allocatable, intent(out) :: error
    type(brdf_params_t) :: ps(N_SET)
    type(rng_t) :: rng
    real(wp) :: u_in(3), u_out(3), r1, r2, cd, s0, s1
    integer :: k, i
    ps = model_set()
    call rng_init(rng, SEED, 4_i8)
    do k = 1, size(ps)
      do i = 1, 1000
        u_in = random_dir(rng, .false., 1.0e-3_wp)
        u_out = random_dir(rng, .true., 1.0e-3_wp)
        r1 = brdf_eval_dir(ps(k), u_in, u_out)
        r2 = brdf_eval_dir(ps(k), -u_out, -u_in)
        call check_close(error, r2, r1, rel_tol=1.0e-12_wp, abs_tol=1.0e-300_wp, &
                         label='reciprocity '//BRDF_NAMES(ps(k)%kind))
        s0 = sqrt(u_in(1)**2 + u_in(2)**2)
        s1 = sqrt(u_out(1)**2 + u_out(2)**2)
        cd = (u_in(1)*u_out(1) + u_in(2)*u_out(2))/(s0*s1)
        call check_close(error, brdf_eval(ps(k), -u_in(3), u_out(3), cd), r1, rel_tol=1.0e-9_wp, &
                         abs_tol=1.0e-300_wp, label='scalar form '//BRDF_NAMES(ps(k)%kind))
        call check_close(error, brdf_eval(ps(k), u_out(3), -u_in(3), cd), r1, rel_tol=1.0e-9_wp, &
                         abs_tol=1.0e-300_wp, label='scalar reciprocity '//BRDF_NAMES(ps(k)%kind))
        if (allocated(error)) return
      end do
    end do
  end subroutine test_reciprocity

  !> cos_dphi = +1 is the forward/specular side, -1 the hot spot: a smooth sea is brightest at
  !> the mirror direction u_out = (u_in_x, u_in_y, -u_in_z); RPV with Theta < 0 and LSRT are
  !> brighter at the hot spot u_out = -u_in than at the mirror direction.
  subroutine test_azimuth_convention(error)
    type(error_t), allocatable, intent(out) :: error
    type(brdf_params_t) :: p
    real(wp) :: u_in(3), mirror(3), back(3), best, r, mu
    integer :: i, i_best
    u_in = [sin(40.0_wp*DEG2RAD), 0.0_wp, -cos(40.0_wp*DEG2RAD)]
    mirror = [u_in(1), u_in(2), -u_in(3)]
    back = -u_in
    p = brdf_params(BRDF_DSM, [0.0_wp, 0.0_wp, 1.334_wp, 0.0_wp, 0.003_wp])
    call check(error, brdf_eval_dir(p, u_in, mirror) > 1.0e3_wp*brdf_eval_dir(p, u_in, back), &
               'DSM: glint not at the mirror direction')
    call check_close(error, brdf_eval(p, -u_in(3), mirror(3), 1.0_wp), &
                     brdf_eval_dir(p, u_in, mirror), rel_tol=1.0e-12_wp, &
                     label='DSM mirror: cos_dphi = +1')
    ! the peak over mu_out at cos_dphi = 1 lies at mu_out = mu_in, up to the shift of order
    ! sigma^2 from the factor 1/(mu_in mu_out mu_n^4): within 4 sigma^2 = 0.012
    best = 0.0_wp
    i_best = 0
    do i = 1, 999
      mu = i/1000.0_wp
      r = brdf_eval(p, -u_in(3), mu, 1.0_wp)
      if (r > best) then
        best = r
        i_best = i
      end if
    end do
    call check_close(error, i_best/1000.0_wp, -u_in(3), abs_tol=0.012_wp, label='glint mu_out')
    p = brdf_params(BRDF_RPV, [0.1_wp, 0.8_wp, -0.3_wp, 1.0_wp])
    call check(error, brdf_eval_dir(p, u_in, back) > 2.0_wp*brdf_eval_dir(p, u_in, mirror), &
               'RPV: hot spot not at the backward direction')
    ! the hot-spot term is a cone in the angles: sqrt of a rounding-level argument there
    call check_close(error, brdf_eval(p, -u_in(3), back(3), -1.0_wp), &
                     brdf_eval_dir(p, u_in, back), rel_tol=1.0e-8_wp, &
                     label='RPV hot spot: cos_dphi = -1')
    p = brdf_params(BRDF_LSRT, [0.2_wp, 0.05_wp, 0.1_wp])
    call check(error, brdf_eval_dir(p, u_in, back) > brdf_eval_dir(p, u_in, mirror), &
               'LSRT: hot spot not at the backward direction')
  end subroutine test_azimuth_convention

  !> Black-sky kernel integrals against the seed text's table (sec. 12.6: two independent
  !> quadratures, 5 decimals) to 2e-5, and white-sky integrals 2 Int A(mu) mu dmu (48-point
  !> Gauss-Legendre here) against Lucht et al. (2000): 0.189184 and -1.377622, to 1e-4.
  subroutine test_lsrt_published(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: th(7) = [0.0_wp, 15.0_wp, 30.0_wp, 45.0_wp, 60.0_wp, 75.0_wp, 85.0_wp]
    real(wp), parameter :: av_ref(7) = [-0.02108_wp, -0.00876_wp, 0.03195_wp, 0.11440_wp, &
                                        0.27048_wp, 0.58546_wp, 1.03293_wp]
    real(wp), parameter :: ag_ref(7) = [-1.28886_wp, -1.29812_wp, -1.32563_wp, -1.36984_wp, &
                                        -1.42531_wp, -1.47732_wp, -1.49731_wp]
    real(wp) :: av, ag, x(48), w(48), wv, wg
    integer :: i
    character(len=32) :: label
    do i = 1, size(th)
      call lsrt_kernel_albedos(cos(th(i)*DEG2RAD), av, ag)
      write (label, '(a, f0.0, a)') 'theta0 = ', th(i), ' deg'
      call check_close(error, av, av_ref(i), abs_tol=2.0e-5_wp, label='A_vol '//trim(label))
      call check_close(error, ag, ag_ref(i), abs_tol=2.0e-5_wp, label='A_geo '//trim(label))
    end do
    call gauss_legendre01(48, x, w)
    wv = 0.0_wp
    wg = 0.0_wp
    do i = 1, 48
      call lsrt_kernel_albedos(x(i), av, ag)
      wv = wv + 2.0_wp*w(i)*x(i)*av
      wg = wg + 2.0_wp*w(i)*x(i)*ag
    end do
    call check_close(error, wv, 0.189184_wp, abs_tol=1.0e-4_wp, label='white-sky Ross-Thick')
    call check_close(error, wg, -1.377622_wp, abs_tol=1.0e-4_wp, label='white-sky Li-Sparse-R')
  end subroutine test_lsrt_published

  !> brdf_albedo_quad against midpoint rules on 400^2 and 800^2 cells in (mu_out, dphi): the
  !> difference must lie within 4 times the Richardson error estimate of the finer rule,
  !> |I_800 - I_400|/3, plus 1e-6 relative; and against the seed text's checked values (RPV
  !> rho0 = 0.15, k = 0.75, Theta = -0.2, mu0 = 0.5: 0.30800; DSM n = 1.33, sigma^2 = 0.04,
  !> 60 deg: 0.059314; LSRT (0.3, 0.07, 0.03) at 45 deg with clipping: 0.2115).
  subroutine test_albedo_brute(error)
    type(error_t), allocatable, intent(out) :: error
    type(brdf_params_t) :: ps(7)
    real(wp) :: mus(7), q, b1, b2, est
    integer :: k
    character(len=48) :: label
    ps(1) = brdf_params(BRDF_RPV, [0.15_wp, 0.75_wp, -0.2_wp, 1.0_wp])
    mus(1) = 0.5_wp
    ps(2) = brdf_params(BRDF_DSM, [0.0_wp, 0.0_wp, 1.33_wp, 0.0_wp, 0.04_wp])
    mus(2) = 0.5_wp
    ps(3) = brdf_params(BRDF_LSRT, [0.3_wp, 0.07_wp, 0.03_wp])
    mus(3) = cos(45.0_wp*DEG2RAD)
    ps(4) = brdf_params(BRDF_RPV, [0.05_wp, 1.4_wp, 0.25_wp, 0.3_wp])
    mus(4) = 0.2_wp
    ps(5) = brdf_params(BRDF_DSM, [0.1_wp, 0.3_wp, 1.334_wp, 0.01_wp, &
                                   cox_munk_slope_variance(5.0_wp)])
    mus(5) = 0.85_wp
    ! a sharp hot spot with a backward peak, and strong clipping near an onset (mu_in ~ 0.95)
    ps(6) = brdf_params(BRDF_RPV, [0.1_wp, 0.7_wp, -0.9_wp, 0.05_wp])
    mus(6) = 0.6_wp
    ps(7) = brdf_params(BRDF_LSRT, [0.1_wp, 0.02_wp, 0.6_wp])
    mus(7) = 0.95_wp
    do k = 1, size(ps)
      q = brdf_albedo_quad(ps(k), mus(k))
      b1 = brute_albedo(ps(k), mus(k), 400)
      b2 = brute_albedo(ps(k), mus(k), 800)
      est = abs(b2 - b1)/3.0_wp
      write (label, '(a, i0, 2a, f0.3)') 'set ', k, ' '//BRDF_NAMES(ps(k)%kind), ', mu0 = ', mus(k)
      call check_close(error, q, b2, abs_tol=4.0_wp*est + 1.0e-6_wp*b2, label=trim(label))
      if (allocated(error)) return
    end do
    call check_close(error, brdf_albedo_quad(ps(1), 0.5_wp), 0.30800_wp, abs_tol=5.0e-6_wp, &
                     label='RPV published check')
    call check_close(error, brdf_albedo_quad(ps(2), 0.5_wp), 0.059314_wp, abs_tol=5.0e-7_wp, &
                     label='DSM published check')
    call check_close(error, brdf_albedo_quad(ps(3), mus(3)), 0.2115_wp, abs_tol=5.0e-5_wp, &
                     label='LSRT clipped published check')
  end subroutine test_albedo_brute

  !> A nearly calm sea (sigma^2 = 0.003, U = 0) without diffuse part reflects at normal
  !> incidence the Fresnel reflectance of its facets: alpha(1) = E[R_F(th_n) f_s], th_n the
  !> facet tilt. Shadowing is negligible there (Lambda(mu_out) < 1e-12 for tilts below
  !> 20 deg, and steeper facets have probability exp(-tan^2(20 deg)/0.003) ~ 1e-19), so
  !> |alpha(1) - R_F(0)| <= max_th |R_F(th) - R_F(0)|/tan^2(th) * E[tan^2 th_n], with
  !> E[tan^2 th_n] = sigma^2; the slope bound is taken here over 0 < th <= 20 deg.
  !> The same for a near-perfect conductor (n = 1 + 100 i) checks the slope normalisation.
  subroutine test_dsm_fresnel_limit(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: sigma2 = 0.003_wp
    type(brdf_params_t) :: p
    real(wp) :: r0, slope, th, tol
    integer :: i, j
    real(wp), parameter :: n_r(2) = [1.334_wp, 1.0_wp], n_i(2) = [0.0_wp, 100.0_wp]
    do j = 1, 2
      r0 = liou_fresnel(n_r(j), n_i(j), 1.0_wp)
      slope = 0.0_wp
      do i = 1, 200
        th = i*0.1_wp*DEG2RAD
        slope = max(slope, abs(liou_fresnel(n_r(j), n_i(j), cos(th)) - r0)/tan(th)**2)
      end do
      tol = slope*sigma2 + 1.0e-12_wp
      p = brdf_params(BRDF_DSM, [0.0_wp, 0.0_wp, n_r(j), n_i(j), sigma2])
      call check_close(error, brdf_albedo_quad(p, 1.0_wp), r0, abs_tol=tol, &
                       label='alpha(mu0 = 1) vs R_F(0)')
    end do
    call check_close(error, r0, 0.99960016_wp, abs_tol=1.0e-8_wp, label='conductor R_F(0)')
  end subroutine test_dsm_fresnel_limit

  !> A Lambert table returns its albedo at every mu, a black one 0; table eval = model.
  subroutine test_lambert_black(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(brdf_table_t) :: tab
    real(wp) :: mu, u_in(3), u_out(3)
    integer :: i
    call brdf_table_init(tab, brdf_params(BRDF_LAMBERT, [0.37_wp]), err)
    call check(error, .not. allocated(err), 'lambert table')
    do i = 1, 100
      mu = i/100.0_wp
      call check_close(error, brdf_albedo(tab, mu), 0.37_wp, abs_tol=0.0_wp, label='lambert alpha')
      call check_close(error, brdf_albedo_quad(tab%p, mu), 0.37_wp, rel_tol=1.0e-15_wp, &
                       label='lambert quadrature')
      call check_close(error, brdf_table_eval(tab, mu, 0.3_wp, 0.2_wp), 0.37_wp/PI, &
                       rel_tol=1.0e-15_wp, label='lambert R')
    end do
    u_in = [0.6_wp, 0.0_wp, -0.8_wp]
    u_out = [0.0_wp, 0.6_wp, 0.8_wp]
    call check_close(error, brdf_table_eval_dir(tab, u_in, u_out), 0.37_wp/PI, rel_tol=1.0e-15_wp, &
                     label='lambert R (vectors)')
    call brdf_table_init(tab, brdf_params(BRDF_BLACK, [0.0_wp]), err)
    call check(error, .not. allocated(err), 'black table')
    call check_close(error, brdf_albedo(tab, 0.5_wp), 0.0_wp, abs_tol=0.0_wp, label='black alpha')
    call check_close(error, brdf_eval(tab%p, 0.5_wp, 0.5_wp, 1.0_wp), 0.0_wp, abs_tol=0.0_wp, &
                     label='black R')
    ! outside the domain the BRDF is 0
    call check_close(error, brdf_eval(brdf_params(BRDF_LAMBERT, [0.5_wp]), 0.5_wp, -0.1_wp, &
                                      1.0_wp), &
                     0.0_wp, abs_tol=0.0_wp, label='mu_out < 0')
  end subroutine test_lambert_black

  !> The table albedo (cubic interpolation on 21 nodes) agrees with the quadrature at off-node
  !> mu_in in [0.05, 1] to 2e-3 relative, the error the table reports (`interp_err`, at the
  !> interval midpoints, including the grazing interval mu_in < 0.0025) is below 5e-3, and
  !> brdf_albedo <= 1 everywhere.
  subroutine test_table_interp(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(brdf_params_t) :: ps(N_SET)
    type(brdf_table_t) :: tab
    real(wp) :: mu, a, q, worst
    integer :: k, i
    character(len=64) :: label
    ps = model_set()
    do k = 1, size(ps)
      call brdf_table_init(tab, ps(k), err)
      call check(error, .not. allocated(err), 'table init')
      if (allocated(error)) return
      worst = 0.0_wp
      do i = 0, 60
        mu = 0.05_wp + 0.95_wp*(i + 0.37_wp)/61.0_wp
        a = brdf_albedo(tab, mu)
        q = min(1.0_wp, brdf_albedo_quad(ps(k), mu))
        worst = max(worst, abs(a - q)/q)
        call check(error, a <= 1.0_wp, 'alpha > 1')
      end do
      write (label, '(a, i0, a, es9.2, a, es9.2)') 'set ', k, ': max rel. error ', worst, &
        ', reported ', tab%interp_err
      call check(error, worst < 2.0e-3_wp, 'interpolation '//trim(label))
      call check(error, tab%interp_err < 5.0e-3_wp, 'reported '//trim(label))
      if (allocated(error)) return
    end do
  end subroutine test_table_interp

  !> The dense albedo table at the midpoints (in sqrt(mu_in)) between its nodes, where cubic
  !> interpolation errs most, against the quadrature `brdf_albedo_quad` (itself checked against
  !> midpoint rules in test_albedo_brute), for every kind: Lambert, RPV (including sharp hot
  !> spots: h = 0.3, and h = 0.05 with a backward peak Theta = -0.9), LSRT (including strong
  !> clipping of a negative kernel sum, whose onsets are kinks in the albedo that the table
  !> resolves with added nodes), DSM (the Cox-Munk ocean of a 5 m/s wind, and a diffuse part
  !> with an absorbing index). mu_in from 0.01 to 1; tolerance 1e-6 relative for every kind.
  !> At the solar mu_in given to the table the albedo is the quadrature value exactly.
  subroutine test_table_midpoints(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(brdf_params_t) :: ps(N_SET + 2)
    type(brdf_table_t) :: tab
    real(wp) :: mu, a, q, worst, mu0, x
    integer :: k, j, n_mid
    character(len=96) :: label
    ps(1:N_SET) = model_set()
    ps(N_SET + 1) = brdf_params(BRDF_DSM, [0.0_wp, 0.0_wp, 1.334_wp, 0.0_wp, &
                                           cox_munk_slope_variance(5.0_wp)])
    ps(N_SET + 2) = brdf_params(BRDF_RPV, [0.1_wp, 0.7_wp, -0.9_wp, 0.05_wp])
    mu0 = cos(37.3_wp*PI/180.0_wp)
    do k = 1, size(ps)
      call brdf_table_init(tab, ps(k), err, mu0=mu0)
      call check(error, .not. allocated(err), 'table init')
      if (allocated(error)) return
      worst = 0.0_wp
      n_mid = 0
      do j = 1, max(tab%n_alb, BRDF_NALB) - 1
        if (tab%n_alb >= BRDF_NALB) then      ! the nodes, adaptive ones included
          x = 0.5_wp*(tab%xa(j) + tab%xa(j + 1))
        else                                  ! Lambert: no table, the same points
          x = (j - 0.5_wp)/(BRDF_NALB - 1)
        end if
        mu = x*x
        if (mu < 0.01_wp) cycle
        n_mid = n_mid + 1
        a = brdf_albedo(tab, mu)
        q = min(1.0_wp, brdf_albedo_quad(ps(k), mu))
        worst = max(worst, abs(a - q)/q)
      end do
      write (label, '(a, i0, a, i0, a, i0, a, es9.2)') 'set ', k, ' (kind ', ps(k)%kind, ', ', &
        n_mid, ' midpoints): max rel. error ', worst
      print '(a)', '  '//trim(label)
      call check(error, n_mid >= 108, 'too few midpoints, '//trim(label))
      call check(error, worst < 1.0e-6_wp, 'dense table '//trim(label))
      call check(error, brdf_albedo(tab, mu0) == min(1.0_wp, brdf_albedo_quad(ps(k), mu0)), &
                 'exact albedo at the solar mu_in, set '//str(k))
      if (allocated(error)) return
    end do
  end subroutine test_table_midpoints

  !> RPV with small k has a model albedo above 1 at grazing incidence: the table counts the
  !> clamped nodes, brdf_albedo is 1 there and brdf_table_eval is the model BRDF divided by the
  !> model albedo (so that it integrates to 1).
  subroutine test_clamp(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(brdf_table_t) :: tab
    type(brdf_params_t) :: p
    real(wp) :: mu, q, scaled
    integer :: i
    p = brdf_params(BRDF_RPV, [0.25_wp, 0.3_wp, -0.1_wp, 1.0_wp])
    call brdf_table_init(tab, p, err)
    call check(error, .not. allocated(err), 'table init')
    if (allocated(error)) return
    call check(error, tab%n_clamped > 0 .and. tab%mu_clamped > 0.0_wp, 'no clamped nodes')
    do i = 1, 20
      mu = 0.005_wp*i
      q = brdf_albedo_quad(p, mu)
      if (q <= 1.01_wp) cycle
      call check_close(error, brdf_albedo(tab, mu), 1.0_wp, abs_tol=0.0_wp, label='clamped alpha')
      scaled = brdf_table_eval(tab, mu, 0.4_wp, 0.3_wp)
      call check_close(error, scaled*q, brdf_eval(p, mu, 0.4_wp, 0.3_wp), rel_tol=2.0e-3_wp, &
                       label='scaled BRDF')
    end do
    call check(error, tab%mu_clamped < 0.5_wp, 'clamping at moderate angles')
    call check_close(error, brdf_albedo(tab, 0.8_wp), brdf_albedo_quad(p, 0.8_wp), &
                     rel_tol=2.0e-3_wp, &
                     label='unclamped alpha')
    call check_close(error, brdf_table_eval(tab, 0.8_wp, 0.4_wp, 0.3_wp), &
                     brdf_eval(p, 0.8_wp, 0.4_wp, &
                               0.3_wp), rel_tol=1.0e-15_wp, label='unscaled BRDF')
  end subroutine test_clamp

  !> LSRT tables of surface maps (`brdf_table_init_grid`) against the accurate quadrature of
  !> `brdf_albedo_quad`, which splits its panels at the zero curve of the clipped kernel sum:
  !> without clipping (k_geo = 0, k_vol >= 0: the sum never turns negative) the grid albedo
  !> equals it at the nodes to 1e-9; with clipping the kink inside the grid's panels costs
  !> accuracy: the albedo used in the photon loop, min(1, alpha), is bounded by 5e-3 relative
  !> plus 2e-5 absolute at the nodes with mu_in >= 0.01 and between nodes for mu_in >= 0.05
  !> (interpolation included; measured worst: 1.7e-3 at the nodes for the alb_N98 weights,
  !> 4e-3 between nodes for set 5), and by 1e-2 for set 4, whose geometric kernel weight
  !> equals the isotropic one (measured 6.4e-3). The
  !> tables agree with `brdf_table_init`'s within the same bounds; that their sampling
  !> envelopes hold is checked by the chi-square tests.
  subroutine test_lsrt_grid(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(lsrt_grid_t) :: grid
    type(brdf_table_t) :: tg, ta
    type(brdf_params_t) :: ps(5)
    real(wp) :: mu, q, node_tol, worst_node, worst
    real(wp), parameter :: rel_tol(5) = [5.0e-3_wp, 5.0e-3_wp, 5.0e-3_wp, 1.0e-2_wp, 5.0e-3_wp]
    integer :: k, j
    character(len=80) :: label
    call lsrt_grid_init(grid)
    ps(1) = brdf_params(BRDF_LSRT, [0.2_wp, 0.0_wp, 0.15_wp])      ! never clipped
    ps(2) = brdf_params(BRDF_LSRT, [0.3_wp, 0.07_wp, 0.03_wp])     ! alb_N98, clipped
    ps(3) = brdf_params(BRDF_LSRT, [0.1_wp, 0.02_wp, 0.6_wp])      ! volume dominated
    ps(4) = brdf_params(BRDF_LSRT, [0.2_wp, 0.1_wp, 0.05_wp])       ! strongly clipped (21 %)
    ps(5) = brdf_params(BRDF_LSRT, [0.25_wp, 0.04_wp, 0.1_wp])     ! typical MODIS weights
    do k = 1, size(ps)
      call brdf_table_init_grid(tg, ps(k), grid, err)
      call check(error, .not. allocated(err), 'grid table init')
      call brdf_table_init(ta, ps(k), err)
      call check(error, .not. allocated(err), 'table init')
      if (allocated(error)) return
      ! worst error in units of the tolerance (k = 1: 1e-9 relative, unclipped)
      worst_node = 0.0_wp
      do j = 3, 21                       ! nodes mu_j = ((j - 1)/20)^2 >= 0.01
        mu = ((j - 1)/20.0_wp)**2
        q = brdf_albedo_quad(ps(k), mu)
        if (k == 1) then
          node_tol = 1.0e-9_wp*q
        else
          node_tol = rel_tol(k)*min(1.0_wp, q) + 2.0e-5_wp
        end if
        worst_node = max(worst_node, abs(min(1.0_wp, tg%t(j)/mu) - min(1.0_wp, q))/node_tol)
      end do
      worst = 0.0_wp
      do j = 0, 60
        mu = 0.05_wp + 0.95_wp*(j + 0.37_wp)/61.0_wp
        q = min(1.0_wp, brdf_albedo_quad(ps(k), mu))
        worst = max(worst, abs(brdf_albedo(tg, mu) - q)/(rel_tol(k)*q + 2.0e-5_wp), &
                    abs(brdf_albedo(tg, mu) - brdf_albedo(ta, mu))/(rel_tol(k)*q + 2.0e-5_wp))
      end do
      write (label, '(a, i0, 2(a, es9.2))') 'set ', k, ': nodes ', worst_node, &
        ', between nodes ', worst
      call check(error, worst_node <= 1.0_wp, 'grid albedo at the nodes (in tolerances), '// &
                 trim(label))
      call check(error, worst <= 1.0_wp, 'grid albedo between nodes (in tolerances), '// &
                 trim(label))
      call check(error, all(tg%env > 0.0_wp) .and. all(tg%a1 == tg%a1), 'envelopes set')
      if (allocated(error)) return
    end do
  end subroutine test_lsrt_grid

end module test_kumo_brdf

program test_brdf
  use test_kumo_brdf, only: collect_brdf
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_brdf', collect_brdf(), n_failed)
  if (n_failed > 0) error stop 1
end program test_brdf
