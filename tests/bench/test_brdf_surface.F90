! SPDX-License-Identifier: BSD-3-Clause
!> BRDF surfaces in whole runs (&kumo_surface brdf, brdf_param, wind_speed).
!>
!> * Under a transparent atmosphere every photon reflects once: the reflectance equals the
!>   directional albedo (to the albedo table's interpolation error and k sigma of the roulette
!>   that follows the reflection), and the radiance
!>   pi I/(mu0 F0) in any direction equals pi R(mu0, mu, dphi) exactly in expectation (k sigma;
!>   the local-estimate roulette makes it noisy). For RPV the reference is the published formula
!>   (Rahman et al. 1993, with the hot-spot sharpness h of MCARaTS) written out here; for DSM and
!>   LSRT it is kumo_brdf's evaluation, which test_brdf checks against independent forms.
!> * A cloud over each BRDF: energy closure 1 in every batch, and the reflectance lies between
!>   those over a black and a white Lambert surface.
!> * BRDF maps (&kumo_surface brdf_file): a map of eight pixels of five kinds under a
!>   transparent atmosphere reflects in each pixel its own directional albedo (the upward flux
!>   per column at the surface, with the 3-D region's columns on the pixels; entry points are
!>   stratified, so every pixel receives the same number of photons), and the domain-mean
!>   radiance is the pixels' mean pi R; a uniform LSRT map gives the answer of the uniform
!>   namelist surface under a cloud (k sigma of the difference), and a uniform Lambert map the
!>   answer of the uniform albedo exactly.
module test_brdf_surface_suite
  use kumo_kinds, only: wp, dp, i8
  use kumo_constants, only: PI, DEG2RAD
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_sigma
  use kumo_config, only: config_t
  use kumo_results, only: result_set_t
  use kumo_test_scenes, only: slab_config, run_config, get_scalar, get_array
  use kumo_brdf, only: brdf_params_t, brdf_params, brdf_eval, brdf_albedo_quad, &
                       cox_munk_slope_variance, BRDF_BLACK, BRDF_LAMBERT, BRDF_DSM, BRDF_RPV, &
                       BRDF_LSRT, BRDF_NPAR
  use kumo_netcdf, only: BRDF_MAP_VARS
  use kumo_test_scenes, only: attach_scene
  use netcdf, only: nf90_create, nf90_def_dim, nf90_def_var, nf90_enddef, nf90_put_var, &
                    nf90_close, nf90_clobber, nf90_int, nf90_double, NF90_NOERR
  use kumo_error, only: str
  implicit none
  private
  public :: collect_brdf_surface

  real(dp), parameter :: K = 4.0_dp
  real(wp), parameter :: SZA = 40.0_wp
  !> detector directions (propagation; upward) and their azimuths relative to the beam
  real(wp), parameter :: MUS(5) = [1.0_wp, 0.5_wp, 0.5_wp, 0.8_wp, 0.3_wp]
  real(wp), parameter :: PHIS(5) = [0.0_wp, 0.0_wp, 180.0_wp, 90.0_wp, 30.0_wp]

contains

  function collect_brdf_surface() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('clear_sky_rpv_is_the_formula', test_clear_rpv), &
             new_unittest('clear_sky_dsm_and_lsrt', test_clear_dsm_lsrt), &
             new_unittest('cloud_over_each_brdf_closes', test_cloud), &
             new_unittest('map_pixels_reflect_their_albedo', test_map_clear), &
             new_unittest('uniform_maps_give_the_uniform_answer', test_map_uniform)]
  end function collect_brdf_surface

  !> A transparent slab (optical depth 0) over the given surface model, radiances at the top.
  function clear_config(kind_name, model) result(cfg)
    character(len=*), intent(in) :: kind_name
    type(brdf_params_t), intent(in) :: model
    type(config_t) :: cfg
    cfg = slab_config(0.0_wp, 1.0_wp, 'hg', 0.0_wp, SZA, 0.0_wp, 20000_i8, 20)
    cfg%surface%brdf = kind_name
    cfg%surface%brdf_param = model%c
    cfg%surface%model = model
    cfg%rad%mu = MUS
    cfg%rad%phi_deg = PHIS
    cfg%rad%levels = [1]
  end function clear_config

  !> RPV BRF as published, pi R (Rahman et al. 1993, JGR 98, 20791, eqs. 2-5; the hot-spot term
  !> 1 + (1 - rho0)/(h + G) with MCARaTS's sharpness h): azimuth dphi from the forward direction.
  pure real(wp) function rpv_brf(c, mu0, mu, dphi_deg) result(brf)
    real(wp), intent(in) :: c(5), mu0, mu, dphi_deg
    real(wp) :: t0, t1, cp, cg, g, f
    t0 = sqrt(1.0_wp - mu0*mu0)/mu0
    t1 = sqrt(1.0_wp - mu*mu)/mu
    cp = cos((180.0_wp - dphi_deg)*DEG2RAD)        ! azimuth from the hot spot
    cg = mu0*mu + sqrt(1.0_wp - mu0*mu0)*sqrt(1.0_wp - mu*mu)*cp
    g = sqrt(max(0.0_wp, t0*t0 + t1*t1 - 2.0_wp*t0*t1*cp))
    f = (1.0_wp - c(3)**2)/(1.0_wp + c(3)**2 + 2.0_wp*c(3)*cg)**1.5_wp
    brf = c(1)*(mu0*mu*(mu0 + mu))**(c(2) - 1.0_wp)*f*(1.0_wp + (1.0_wp - c(1))/(c(4) + g))
  end function rpv_brf

  !> Run the clear-sky case and compare the reflectance with the albedo and each radiance with
  !> `ref(d)`.
  subroutine check_clear(cfg, ref, label, error)
    type(config_t), intent(in) :: cfg
    real(wp), intent(in) :: ref(:)
    character(len=*), intent(in) :: label
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: res
    real(dp) :: r, er, alpha
    real(dp), allocatable :: rad(:), erad(:)
    integer :: d
    call run_config(cfg, res, error)
    if (allocated(error)) return
    call get_scalar(res, 'reflectance', r, er, error)
    call get_array(res, 'radiance', rad, erad, error)
    if (allocated(error)) return
    alpha = brdf_albedo_quad(cfg%surface%model, cos(SZA*DEG2RAD))
    ! every photon reflects once with weight alpha(mu0) from the albedo table (interpolation
    ! error below 2e-3 relative, test_brdf), then meets the roulette (noise er)
    call check(error, abs(r - alpha) <= K*er + 2.0e-3_dp*alpha, &
               label//': reflectance '//str(r)//' +- '//str(er)//' is not the albedo '// &
               str(alpha))
    do d = 1, size(ref)
      call check_sigma(error, rad(d), real(ref(d), dp), erad(d), K, &
                       label//': radiance '//str(d), abs_floor=1.0e-12_dp)
    end do
  end subroutine check_clear

  subroutine test_clear_rpv(error)
    type(error_t), allocatable, intent(out) :: error
    type(brdf_params_t) :: p
    real(wp) :: ref(size(MUS)), mu0
    integer :: d
    p = brdf_params(BRDF_RPV, [0.1_wp, 0.8_wp, -0.1_wp, 0.2_wp, 0.0_wp])
    mu0 = cos(SZA*DEG2RAD)
    do d = 1, size(MUS)
      ref(d) = rpv_brf(p%c, mu0, MUS(d), PHIS(d))
    end do
    call check_clear(clear_config('rpv', p), ref, 'rpv', error)
  end subroutine test_clear_rpv

  subroutine test_clear_dsm_lsrt(error)
    type(error_t), allocatable, intent(out) :: error
    type(brdf_params_t) :: p(2)
    character(len=4), parameter :: NAMES(2) = ['dsm ', 'lsrt']
    real(wp) :: ref(size(MUS)), mu0
    integer :: i, d
    p(1) = brdf_params(BRDF_DSM, [0.05_wp, 0.2_wp, 1.334_wp, 0.0_wp, &
                                  cox_munk_slope_variance(5.0_wp)])
    p(2) = brdf_params(BRDF_LSRT, [0.3_wp, 0.07_wp, 0.03_wp, 0.0_wp, 0.0_wp])
    mu0 = cos(SZA*DEG2RAD)
    do i = 1, 2
      do d = 1, size(MUS)
        ref(d) = PI*brdf_eval(p(i), mu0, MUS(d), cos(PHIS(d)*DEG2RAD))
      end do
      call check_clear(clear_config(trim(NAMES(i)), p(i)), ref, trim(NAMES(i)), error)
      if (allocated(error)) return
    end do
  end subroutine test_clear_dsm_lsrt

  subroutine test_cloud(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: res
    type(brdf_params_t) :: p(3)
    character(len=4), parameter :: NAMES(3) = ['dsm ', 'rpv ', 'lsrt']
    real(dp) :: r, er, c, ec, r_lo, r_hi, e
    integer :: i
    p(1) = brdf_params(BRDF_DSM, [0.05_wp, 0.2_wp, 1.334_wp, 0.0_wp, &
                                  cox_munk_slope_variance(10.0_wp)])
    p(2) = brdf_params(BRDF_RPV, [0.25_wp, 0.7_wp, -0.2_wp, 1.0_wp, 0.0_wp])
    p(3) = brdf_params(BRDF_LSRT, [0.3_wp, 0.07_wp, 0.03_wp, 0.0_wp, 0.0_wp])
    cfg = slab_config(3.0_wp, 0.95_wp, 'hg', 0.85_wp, 50.0_wp, 0.0_wp, 20000_i8, 10)
    call run_config(cfg, res, error)
    if (allocated(error)) return
    call get_scalar(res, 'reflectance', r_lo, e, error)
    cfg%surface%albedo = 1.0_wp
    call run_config(cfg, res, error)
    if (allocated(error)) return
    call get_scalar(res, 'reflectance', r_hi, e, error)
    do i = 1, 3
      cfg = slab_config(3.0_wp, 0.95_wp, 'hg', 0.85_wp, 50.0_wp, 0.0_wp, 20000_i8, 10)
      cfg%surface%brdf = trim(NAMES(i))
      cfg%surface%brdf_param = p(i)%c
      cfg%surface%model = p(i)
      call run_config(cfg, res, error)
      if (allocated(error)) return
      call get_scalar(res, 'reflectance', r, er, error)
      call get_scalar(res, 'energy_closure', c, ec, error)
      if (allocated(error)) return
      ! closure 1 with a zero spread over the batches: 1 in every batch
      call check(error, abs(c - 1.0_dp) < 1.0e-12_dp .and. ec == 0.0_dp, &
                 trim(NAMES(i))//': energy closure '//str(c)//' +- '//str(ec))
      call check(error, r > r_lo + K*er .and. r < r_hi - K*er, trim(NAMES(i))// &
                 ': reflectance '//str(r)//' not between black '//str(r_lo)//' and white '// &
                 str(r_hi))
      if (allocated(error)) return
    end do
  end subroutine test_cloud
  !> Write a BRDF map file: brdf_kind and, for each kind present, its parameter variables.
  subroutine write_brdf_map(path, p, error)
    character(len=*), intent(in) :: path
    type(brdf_params_t), intent(in) :: p(:, :)
    type(error_t), allocatable, intent(inout) :: error
    integer :: ncid, dx, dy, vk, vid(BRDF_NPAR, 4), i, k, st
    st = nf90_create(path, nf90_clobber, ncid)
    st = st + nf90_def_dim(ncid, 'xs', size(p, 1), dx)
    st = st + nf90_def_dim(ncid, 'ys', size(p, 2), dy)
    st = st + nf90_def_var(ncid, 'brdf_kind', nf90_int, [dx, dy], vk)
    vid = 0
    do k = 1, 4
      if (.not. any(p%kind == k)) cycle
      do i = 1, BRDF_NPAR
        if (len_trim(BRDF_MAP_VARS(i, k)) == 0) cycle
        st = st + nf90_def_var(ncid, trim(BRDF_MAP_VARS(i, k)), nf90_double, [dx, dy], vid(i, k))
      end do
    end do
    st = st + nf90_enddef(ncid)
    st = st + nf90_put_var(ncid, vk, p%kind)
    do k = 1, 4
      do i = 1, BRDF_NPAR
        if (vid(i, k) /= 0) st = st + nf90_put_var(ncid, vid(i, k), p%c(i))
      end do
    end do
    st = st + nf90_close(ncid)
    call check(error, st == NF90_NOERR, 'writing '//path)
  end subroutine write_brdf_map

  !> Eight pixels of five kinds (two LSRT sets, DSM, two RPV, Lambert, black) on the 4 x 2
  !> columns of an empty 3-D region, sun at 40 deg.
  subroutine test_map_clear(error)
    type(error_t), allocatable, intent(out) :: error
    type(brdf_params_t) :: p(4, 2)
    type(config_t) :: cfg
    type(result_set_t) :: res
    real(dp), allocatable :: up(:), eup(:), rad(:), erad(:)
    real(wp) :: mu0, alpha, ref
    real(wp) :: zero(4, 2, 1)
    integer :: i, j, d, n
    p(1, 1) = brdf_params(BRDF_LSRT, [0.3_wp, 0.07_wp, 0.03_wp])
    p(2, 1) = brdf_params(BRDF_LSRT, [0.1_wp, 0.02_wp, 0.6_wp])
    p(3, 1) = brdf_params(BRDF_DSM, [0.1_wp, 0.3_wp, 1.334_wp, 0.0_wp, &
                                     cox_munk_slope_variance(7.0_wp)])
    p(4, 1) = brdf_params(BRDF_RPV, [0.1_wp, 0.8_wp, -0.1_wp, 0.2_wp])
    p(1, 2) = brdf_params(BRDF_LAMBERT, [0.4_wp])
    p(2, 2) = brdf_params(BRDF_BLACK, [0.0_wp])
    p(3, 2) = brdf_params(BRDF_RPV, [0.25_wp, 0.7_wp, -0.2_wp, 1.0_wp])
    p(4, 2) = p(1, 1)
    call write_brdf_map('brdf_map_clear.nc', p, error)
    if (allocated(error)) return
    cfg = clear_config('lambert', brdf_params(BRDF_LAMBERT, [0.0_wp]))
    cfg%surface%brdf_param = 0.0_wp
    cfg%surface%brdf_file = 'brdf_map_clear.nc'
    cfg%control%n_photons_per_batch = 8000_i8
    zero = 0.0_wp
    call attach_scene(cfg, 'brdf_map_empty.nc', 1, zero, zero + 1.0_wp, 1, error)
    if (allocated(error)) return
    call run_config(cfg, res, error)
    if (allocated(error)) return
    call get_array(res, 'flux_up_map', up, eup, error)
    call get_array(res, 'radiance', rad, erad, error)
    if (allocated(error)) return
    mu0 = cos(SZA*DEG2RAD)
    n = 0
    do j = 1, 2
      do i = 1, 4
        n = n + 1          ! flux_up_map(x, y, level): level 1 is the surface
        alpha = brdf_albedo_quad(p(i, j), mu0)
        ! table interpolation (2e-3, LSRT map tables 5e-3) and k sigma of the roulette
        call check(error, abs(up(n) - alpha) <= K*eup(n) + 5.0e-3_dp*alpha + 1.0e-12_dp, &
                   'pixel ('//str(i)//','//str(j)//'): reflected '//str(up(n))//' +- '// &
                   str(eup(n))//', albedo '//str(alpha))
      end do
    end do
    do d = 1, size(MUS)
      ref = 0.0_wp
      do j = 1, 2
        do i = 1, 4
          ref = ref + PI*brdf_eval(p(i, j), mu0, MUS(d), cos(PHIS(d)*DEG2RAD))/8.0_wp
        end do
      end do
      call check_sigma(error, rad(d), real(ref, dp), erad(d), K, 'map radiance '//str(d))
    end do
  end subroutine test_map_clear

  !> A uniform LSRT map (tables from the shared kernel grid) against the uniform namelist
  !> surface (tables by `brdf_table_init`) under a cloud of optical depth 3, and a uniform
  !> Lambert map against the uniform albedo (the same surface: identical results).
  subroutine test_map_uniform(error)
    type(error_t), allocatable, intent(out) :: error
    type(brdf_params_t) :: p(3, 2), model
    type(config_t) :: cfg
    type(result_set_t) :: res
    real(dp) :: r(2), er(2), t(2), et(2)
    integer :: m
    model = brdf_params(BRDF_LSRT, [0.25_wp, 0.04_wp, 0.1_wp])
    p = model
    call write_brdf_map('brdf_map_lsrt.nc', p, error)
    if (allocated(error)) return
    do m = 1, 2
      cfg = slab_config(3.0_wp, 0.95_wp, 'hg', 0.85_wp, 50.0_wp, 0.0_wp, 20000_i8, 10)
      if (m == 1) then
        cfg%surface%brdf = 'lsrt'
        cfg%surface%brdf_param = model%c
        cfg%surface%model = model
      else
        cfg%surface%brdf_file = 'brdf_map_lsrt.nc'
        cfg%control%seed = 8_i8
      end if
      call run_config(cfg, res, error)
      if (allocated(error)) return
      call get_scalar(res, 'reflectance', r(m), er(m), error)
      call get_scalar(res, 'transmittance', t(m), et(m), error)
    end do
    call check_sigma(error, r(2), r(1), sqrt(er(1)**2 + er(2)**2), K, 'uniform LSRT map: R')
    call check_sigma(error, t(2), t(1), sqrt(et(1)**2 + et(2)**2), K, 'uniform LSRT map: T')
    p = brdf_params(BRDF_LAMBERT, [0.35_wp])
    call write_brdf_map('brdf_map_lambert.nc', p, error)
    if (allocated(error)) return
    do m = 1, 2
      cfg = slab_config(3.0_wp, 0.95_wp, 'hg', 0.85_wp, 50.0_wp, 0.35_wp, 20000_i8, 10)
      if (m == 2) then
        cfg%surface%albedo = 0.0_wp
        cfg%surface%brdf_file = 'brdf_map_lambert.nc'
      end if
      call run_config(cfg, res, error)
      if (allocated(error)) return
      call get_scalar(res, 'reflectance', r(m), er(m), error)
    end do
    call check(error, r(1) == r(2) .and. er(1) == er(2), 'uniform Lambert map: R '// &
               str(r(2))//' differs from the uniform albedo''s '//str(r(1)))
  end subroutine test_map_uniform
end module test_brdf_surface_suite

program test_brdf_surface
  use test_brdf_surface_suite, only: collect_brdf_surface
  use kumo_test_text, only: run_suite
  implicit none
  call run_suite('BRDF surfaces in whole runs', collect_brdf_surface())
end program test_brdf_surface
