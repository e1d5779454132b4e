! SPDX-License-Identifier: BSD-3-Clause
!> Radiances by local estimation, cameras and the variance reduction that serves them.
!>
!> * Unbiased techniques on vs off give the same radiances within k sigma of the combined
!>   standard error (k = 4): local-estimate roulette (zeta_min), collision forcing (thick and thin
!>   slab), and a horizontally uniform 3-D region vs the same 1-D layer; the per-column radiance
!>   map averages to the domain-mean radiance to round-off.
!> * Truncation (biased) stays within a documented bound: max(4 sigma, 1 %) for radiances,
!>   max(4 sigma, 0.5 %) for fluxes, on a tau 10, omega 0.999, HG g = 0.85 slab.
!> * A Lambert surface under a transparent atmosphere: every camera pixel and every upward
!>   level radiance is the albedo (pi I/(mu0 F0) of a Lambert surface lit by mu0 F0).
!> * Grazing sun, grazing detector directions, near-transparent and very thick layers: every
!>   radiance finite, the budget closed, the anomaly counters reported.
!> * The forward-peak warning appears exactly when roulette and truncation are both off.
!>
!> Fixed seeds; standard errors from the batch spread (20 batches, 40 for truncation, 50 for the
!> 192 camera pixels so that a 4-sigma miss by chance stays unlikely); 0.2 to 2 million photons
!> per run, about 10 s CPU in all (Release). The measured differences, error ratios and anomaly
!> counts are printed for the record.
module test_radiance_suite
  use, intrinsic :: iso_fortran_env, only: output_unit
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp, dp, i8
  use kumo_error, only: str
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_sigma
  use kumo_config, only: config_t
  use kumo_results, only: result_set_t
  use kumo_driver, only: run_summary_t
  use kumo_netcdf, only: write_scene_3d
  use kumo_test_scenes, only: slab_config, set_phases, run_config, run_pair, get_scalar, &
                              get_array, attach_scene
  implicit none
  private
  public :: collect_radiance

  real(dp), parameter :: K = 4.0_dp
  integer, parameter :: NB = 20
  !> Six directions of propagation: nadir view (mu = 1), 60 deg up-going light in and against
  !> the sun's azimuth, zenith view from below (mu = -1) and 60 deg down-going light. The sun's
  !> beam travels towards phi = 0 at mu = -cos(30 deg).
  real(wp), parameter :: DIR_MU(6) = [1.0_wp, 0.5_wp, 0.5_wp, -1.0_wp, -0.5_wp, -0.5_wp]
  real(wp), parameter :: DIR_PHI(6) = [0.0_wp, 0.0_wp, 180.0_wp, 0.0_wp, 0.0_wp, 180.0_wp]

contains

  function collect_radiance() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('le_roulette_on_equals_off', test_roulette), &
             new_unittest('collision_forcing_on_equals_off', test_forcing), &
             new_unittest('collision_forcing_thin_slab', test_forcing_thin), &
             new_unittest('radiance_3d_equals_1d_and_map_mean', test_3d_vs_1d), &
             new_unittest('truncation_bias_within_bound', test_truncation), &
             new_unittest('diffusion_keeps_domain_means', test_diffusion), &
             new_unittest('cameras_see_lambert_albedo', test_camera_lambert), &
             new_unittest('radiance_stress_stays_finite', test_stress), &
             new_unittest('forward_peak_warning', test_warning)]
  end function collect_radiance

  ! ------------------------------------------------------------------------------------------
  ! scenes and helpers

  !> Variance reduction set explicitly (a configuration built in code has no preset). Detector
  !> directional importance sampling stays off, so that each test isolates one technique.
  subroutine set_vr(cfg, zeta_min, cf_tau_min, trunc_theta_max_deg, trunc_levels)
    type(config_t), intent(inout) :: cfg
    real(wp), intent(in) :: zeta_min, cf_tau_min, trunc_theta_max_deg
    integer, intent(in) :: trunc_levels
    cfg%vr%zeta_min = zeta_min
    cfg%vr%cf_tau_min = cf_tau_min
    cfg%vr%trunc_theta_max_deg = trunc_theta_max_deg
    cfg%vr%trunc_levels = trunc_levels
    cfg%vr%trunc_peak = 30.0_wp
    cfg%vr%ddis_eps = 0.0_wp
  end subroutine set_vr

  subroutine set_radiance(cfg, mu, phi_deg, levels)
    type(config_t), intent(inout) :: cfg
    real(wp), intent(in) :: mu(:), phi_deg(:)
    integer, intent(in) :: levels(:)
    cfg%rad%mu = mu
    cfg%rad%phi_deg = phi_deg
    cfg%rad%levels = levels
    cfg%rad%maps = .true.
  end subroutine set_radiance

  !> The HG g = 0.85 slab (omega 0.99, sza 30, Lambert albedo 0.2) with radiances at the surface
  !> and the top in DIR_MU/DIR_PHI, every variance reduction off.
  function hg_slab(tau, n_photons) result(cfg)
    real(wp), intent(in) :: tau
    integer(i8), intent(in) :: n_photons
    type(config_t) :: cfg
    cfg = slab_config(tau, 0.99_wp, 'hg', 0.85_wp, 30.0_wp, 0.2_wp, n_photons, NB)
    call set_vr(cfg, 0.0_wp, 0.0_wp, 0.0_wp, 1)
    call set_radiance(cfg, DIR_MU, DIR_PHI, [0, 1])
  end function hg_slab

  !> Append a camera looking at azimuth 0 without roll.
  subroutine add_camera(cfg, kind, pos, look_zenith_deg, fov_deg, width, npx, npy)
    type(config_t), intent(inout) :: cfg
    character(len=*), intent(in) :: kind
    real(wp), intent(in) :: pos(3), look_zenith_deg, fov_deg, width
    integer, intent(in) :: npx, npy
    real(wp), allocatable :: p(:, :)
    integer :: n
    n = cfg%cam%n
    if (.not. allocated(cfg%cam%pos)) then
      allocate (cfg%cam%kind(0), cfg%cam%pos(3, 0), cfg%cam%look_zenith_deg(0), &
                cfg%cam%look_azimuth_deg(0), cfg%cam%roll_deg(0), cfg%cam%fov_deg(0), &
                cfg%cam%width(0), cfg%cam%npx(0), cfg%cam%npy(0))
    end if
    allocate (p(3, n + 1))
    p(:, 1:n) = cfg%cam%pos
    p(:, n + 1) = pos
    call move_alloc(p, cfg%cam%pos)
    cfg%cam%kind = [character(len=16) :: cfg%cam%kind, kind]
    cfg%cam%look_zenith_deg = [cfg%cam%look_zenith_deg, look_zenith_deg]
    cfg%cam%look_azimuth_deg = [cfg%cam%look_azimuth_deg, 0.0_wp]
    cfg%cam%roll_deg = [cfg%cam%roll_deg, 0.0_wp]
    cfg%cam%fov_deg = [cfg%cam%fov_deg, fov_deg]
    cfg%cam%width = [cfg%cam%width, width]
    cfg%cam%npx = [cfg%cam%npx, npx]
    cfg%cam%npy = [cfg%cam%npy, npy]
    cfg%cam%n = n + 1
  end subroutine add_camera

  !> A global attribute of a result set; `found` is false when it is missing.
  subroutine get_attr(set, name, value, found)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: name
    character(len=:), allocatable, intent(out) :: value
    logical, intent(out) :: found
    integer :: i
    value = ''
    found = .false.
    if (.not. allocated(set%attrs)) return
    do i = 1, size(set%attrs)
      if (trim(set%attrs(i)%name) == name) then
        found = .true.
        if (allocated(set%attrs(i)%value)) value = set%attrs(i)%value
        return
      end if
    end do
  end subroutine get_attr

  !> A numeric global attribute.
  subroutine get_attr_real(set, name, value, error)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: name
    real(dp), intent(out) :: value
    type(error_t), allocatable, intent(inout) :: error
    character(len=:), allocatable :: text
    logical :: found
    integer :: ios
    value = 0.0_dp
    call get_attr(set, name, text, found)
    call check(error, found, 'attribute '//name//' is missing')
    if (allocated(error)) return
    read (text, *, iostat=ios) value
    call check(error, ios == 0, 'attribute '//name//' = "'//text//'" is not a number')
  end subroutine get_attr_real

  !> Every entry of output `name` of two runs agrees within k sigma of the combined error;
  !> `max_dev` is the largest deviation in combined sigmas.
  subroutine compare_outputs(a, b, name, label, error, max_dev)
    type(result_set_t), intent(in) :: a, b
    character(len=*), intent(in) :: name, label
    type(error_t), allocatable, intent(inout) :: error
    real(dp), intent(out), optional :: max_dev
    real(dp), allocatable :: ma(:), ea(:), mb(:), eb(:)
    real(dp) :: s, dev
    integer :: i
    dev = 0.0_dp
    call get_array(a, name, ma, ea, error)
    call get_array(b, name, mb, eb, error)
    if (allocated(error)) return
    call check(error, size(ma) == size(mb) .and. size(ma) > 0, label//': '//name// &
               ' has different or zero sizes')
    if (allocated(error)) return
    do i = 1, size(ma)
      s = sqrt(ea(i)**2 + eb(i)**2)
      if (s > 0.0_dp) dev = max(dev, abs(ma(i) - mb(i))/s)
      call check_sigma(error, ma(i), mb(i), s, K, label//': '//name//'('//str(i)//')', &
                       abs_floor=1.0e-12_dp)
    end do
    if (present(max_dev)) max_dev = dev
  end subroutine compare_outputs

  subroutine note(text)
    character(len=*), intent(in) :: text
    write (output_unit, '(a)') '  '//text
    flush (output_unit)
  end subroutine note

  !> Every mean and standard error of a result set is finite.
  subroutine check_all_finite(set, label, error)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: label
    type(error_t), allocatable, intent(inout) :: error
    integer :: i
    do i = 1, size(set%vars)
      call check(error, all(ieee_is_finite(set%vars(i)%mean)), label//': non-finite mean in '// &
                 trim(set%vars(i)%name))
      if (allocated(set%vars(i)%stderr)) call check(error, &
        all(ieee_is_finite(set%vars(i)%stderr)), label//': non-finite stderr in '// &
        trim(set%vars(i)%name))
    end do
  end subroutine check_all_finite

  ! ------------------------------------------------------------------------------------------
  ! 1. unbiased techniques on vs off

  !> (a) Local-estimate roulette zeta_min = 0.3 vs off: same radiances, fluxes untouched.
  subroutine test_roulette(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: off, on
    type(result_set_t) :: r_off, r_on
    real(dp) :: dev
    off = hg_slab(2.0_wp, 10000_i8)
    on = off
    on%vr%zeta_min = 0.3_wp
    on%control%seed = 101_i8
    call run_pair(off, r_off, on, r_on, error)
    if (allocated(error)) return
    call compare_outputs(r_off, r_on, 'radiance', 'zeta_min 0 vs 0.3', error, dev)
    call note('zeta_min 0 vs 0.3: largest radiance deviation '//str(dev)//' sigma')
    call compare_outputs(r_off, r_on, 'reflectance', 'zeta_min 0 vs 0.3', error)
    call compare_outputs(r_off, r_on, 'transmittance', 'zeta_min 0 vs 0.3', error)
  end subroutine test_roulette

  !> (b) Collision forcing cf_tau_min = 20 on the tau = 2 slab vs off: the forcing factor is
  !> cf_tau_min / (tau/mu0) = 10 mu0 (the slant column along the sun's path, sza 30).
  subroutine test_forcing(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: off, on
    type(result_set_t) :: r_off, r_on
    real(dp) :: dev, f
    off = hg_slab(2.0_wp, 10000_i8)
    off%vr%zeta_min = 0.3_wp
    on = off
    on%vr%cf_tau_min = 20.0_wp
    on%control%seed = 202_i8
    call run_pair(off, r_off, on, r_on, error)
    if (allocated(error)) return
    call get_attr_real(r_off, 'collision_forcing_factor', f, error)
    call check_close(error, f, 1.0_dp, label='collision_forcing_factor without forcing')
    call get_attr_real(r_on, 'collision_forcing_factor', f, error)
    call check_close(error, f, 10.0_dp*cos(30.0_dp*acos(-1.0_dp)/180.0_dp), rel_tol=1.0e-9_dp, &
                     label='collision_forcing_factor')
    call compare_outputs(r_off, r_on, 'radiance', 'forcing off vs x10', error, dev)
    call note('collision forcing off vs x10: largest radiance deviation '//str(dev)//' sigma')
    call compare_outputs(r_off, r_on, 'reflectance', 'forcing off vs x10', error)
    call compare_outputs(r_off, r_on, 'transmittance', 'forcing off vs x10', error)
    call compare_outputs(r_off, r_on, 'absorptance_atmosphere', 'forcing off vs x10', error)
    call compare_outputs(r_off, r_on, 'transmittance_direct', 'forcing off vs x10', error)
  end subroutine test_forcing

  !> (c) A thin slab (tau = 0.05): forcing (cf_tau_min = 1, factor 20) gives the same radiances
  !> and, without local-estimate roulette, a smaller standard error (most photons now scatter in
  !> the layer instead of 6 %). With roulette (zeta_min = 0.3) the weak forced contributions are
  !> mostly rouletted away; that error ratio is only printed.
  subroutine test_forcing_thin(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: off, on
    type(result_set_t) :: r_off, r_on
    real(dp), allocatable :: m1(:), e1(:), m2(:), e2(:)
    real(dp) :: dev, f, ratio
    integer :: iz
    real(wp), parameter :: ZETA(2) = [0.0_wp, 0.3_wp]
    do iz = 1, 2
      off = hg_slab(0.05_wp, 4000_i8)
      off%vr%zeta_min = ZETA(iz)
      on = off
      on%vr%cf_tau_min = 1.0_wp
      on%control%seed = 303_i8
      call run_pair(off, r_off, on, r_on, error)
      if (allocated(error)) return
      call get_attr_real(r_on, 'collision_forcing_factor', f, error)
      ! cf_tau_min / (tau/mu0) with tau 0.05, sza 30
      call check_close(error, f, 20.0_dp*cos(30.0_dp*acos(-1.0_dp)/180.0_dp), &
                       rel_tol=1.0e-9_dp, label='collision_forcing_factor')
      call compare_outputs(r_off, r_on, 'radiance', 'thin slab forcing off vs on', error, dev)
      call compare_outputs(r_off, r_on, 'reflectance', 'thin slab forcing off vs on', error)
      call compare_outputs(r_off, r_on, 'transmittance', 'thin slab forcing off vs on', error)
      call compare_outputs(r_off, r_on, 'transmittance_direct', 'thin slab forcing off vs on', &
                           error)
      call get_array(r_off, 'radiance', m1, e1, error)
      call get_array(r_on, 'radiance', m2, e2, error)
      if (allocated(error)) return
      ! root of the summed variances of all radiances, forcing on / off (same photon count)
      ratio = sqrt(sum(e2**2)/sum(e1**2))
      call note('thin slab, zeta_min '//str(ZETA(iz))//': largest radiance deviation '// &
                str(dev)//' sigma; standard error ratio forcing on/off '//str(ratio))
      if (iz == 1) call check(error, ratio < 0.7_dp, 'collision forcing must reduce the '// &
                              'radiance error on a thin slab: ratio on/off = '//str(ratio))
      if (allocated(error)) return
    end do
  end subroutine test_forcing_thin

  !> (d) A horizontally uniform 3-D region gives the radiances of the same 1-D layer; the
  !> per-column radiance map averages to the domain-mean radiance to round-off. Two regions:
  !> identical voxels (lines of sight cross the layer in one step), and a checkerboard of two
  !> identical HG phase functions (the same optics, but lines of sight go voxel by voxel).
  subroutine test_3d_vs_1d(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: NX = 4, NY = 3
    character(len=*), parameter :: VARIANT(2) = [character(len=24) :: 'identical voxels', &
                                                 'phase checkerboard']
    type(config_t) :: c1, c3
    type(result_set_t) :: r1, r3
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    real(dp), allocatable :: mmap(:), emap(:), m(:), e(:)
    real(dp) :: dev, worst, avg
    integer :: iph(NX, NY, 1, 1), i, j, ncol, iv
    c1 = hg_slab(2.0_wp, 10000_i8)
    c1%vr%zeta_min = 0.3_wp
    call run_config(c1, r1, error)
    if (allocated(error)) return
    allocate (ext(NX, NY, 1), ssa(NX, NY, 1))
    ext = c1%atm%ext1d(1, 1)
    ssa = 0.99_wp
    do iv = 1, 2
      c3 = c1
      c3%atm%ext1d = 0.0_wp
      c3%control%seed = 404_i8 + iv
      if (iv == 1) then
        call attach_scene(c3, 'radiance_homog.nc', 1, ext, ssa, 1, error)
      else
        deallocate (c3%phase%kind, c3%phase%kind_name, c3%phase%g, c3%phase%file)
        call set_phases(c3, [character(len=8) :: 'hg', 'hg'], [0.85_wp, 0.85_wp])
        do j = 1, NY
          do i = 1, NX
            iph(i, j, 1, 1) = 1 + mod(i + j, 2)
          end do
        end do
        call write_scene_3d('radiance_checker.nc', reshape(ext, [NX, NY, 1, 1]), &
                            reshape(ssa, [NX, NY, 1, 1]), iph, error)
        if (allocated(error)) return
        call attach_scene(c3, 'radiance_checker.nc', 1, ext, ssa, 1, error, write_file=.false.)
      end if
      if (allocated(error)) return
      call run_config(c3, r3, error)
      if (allocated(error)) return
      call compare_outputs(r1, r3, 'radiance', '1-D vs 3-D '//trim(VARIANT(iv)), error, dev)
      call note('1-D vs 3-D, '//trim(VARIANT(iv))//': largest radiance deviation '//str(dev)// &
                ' sigma')
      call compare_outputs(r1, r3, 'reflectance', '1-D vs 3-D '//trim(VARIANT(iv)), error)
      call get_array(r3, 'radiance_map', mmap, emap, error)
      call get_array(r3, 'radiance', m, e, error)
      if (allocated(error)) return
      ncol = NX*NY
      call check(error, size(mmap) == ncol*size(m), 'radiance_map has '//str(size(mmap))// &
                 ' entries, expected '//str(ncol*size(m)))
      if (allocated(error)) return
      worst = 0.0_dp
      do i = 1, size(m)   ! (rad_level, direction) flattened, as the map's last two dimensions
        avg = sum(mmap((i - 1)*ncol + 1:i*ncol))/ncol
        worst = max(worst, abs(avg - m(i)))
        call check_close(error, avg, m(i), abs_tol=1.0e-13_dp, rel_tol=1.0e-12_dp, &
                         label='radiance_map column mean vs radiance('//str(i)//')')
      end do
      call note('  radiance_map column mean vs domain mean: largest |difference| '//str(worst))
      if (allocated(error)) return
    end do
  end subroutine test_3d_vs_1d

  !> Numerical diffusion spreads map samples over neighbouring columns only: with the same seed
  !> the domain-mean radiances are bit for bit those without it (its documented bias on domain
  !> means is zero), the mean of each smoothed map equals the domain mean to round-off, and the
  !> per-pixel standard errors fall (the point of it). A striped 16 x 16 cloud so that the map
  !> has structure to blur.
  subroutine test_diffusion(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: NX = 16, NY = 16
    type(config_t) :: c0, c1
    type(result_set_t) :: r0, r1
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    real(dp), allocatable :: m0(:), e0(:), m1(:), e1(:), map0(:), emap0(:), map1(:), emap1(:)
    real(dp) :: n0, n1
    integer :: i, ncol
    c0 = hg_slab(2.0_wp, 5000_i8)
    c0%vr%zeta_min = 0.3_wp
    allocate (ext(NX, NY, 1), ssa(NX, NY, 1))
    do i = 1, NX
      ext(i, :, 1) = c0%atm%ext1d(1, 1)*merge(0.3_wp, 1.7_wp, mod(i, 4) < 2)
    end do
    ssa = 0.99_wp
    c0%atm%ext1d = 0.0_wp
    call attach_scene(c0, 'radiance_stripes.nc', 1, ext, ssa, 1, error)
    if (allocated(error)) return
    c1 = c0
    c1%vr%diffusion = 60.0_wp
    c1%vr%diffusion_max = 30
    call run_pair(c0, r0, c1, r1, error)
    if (allocated(error)) return
    call get_array(r0, 'radiance', m0, e0, error)
    if (.not. allocated(error)) call get_array(r1, 'radiance', m1, e1, error)
    if (.not. allocated(error)) call get_array(r0, 'radiance_map', map0, emap0, error)
    if (.not. allocated(error)) call get_array(r1, 'radiance_map', map1, emap1, error)
    if (allocated(error)) return
    call check(error, all(m0 == m1) .and. all(e0 == e1), &
               'numerical diffusion changed a domain-mean radiance')
    ncol = NX*NY
    do i = 1, size(m1)
      call check_close(error, sum(map1((i - 1)*ncol + 1:i*ncol))/ncol, m1(i), &
                       abs_tol=1.0e-13_dp, rel_tol=1.0e-12_dp, &
                       label='smoothed radiance_map mean vs radiance('//str(i)//')')
    end do
    ! nadir radiance at the top: direction 1, level slot 2
    n0 = sqrt(sum(emap0((2 - 1)*ncol + 1:2*ncol)**2)/ncol)
    n1 = sqrt(sum(emap1((2 - 1)*ncol + 1:2*ncol)**2)/ncol)
    call note('  numerical diffusion 60: RMS per-pixel standard error of the TOA nadir '// &
              'radiance '//str(n1)//' against '//str(n0)//' without')
    call check(error, n1 < 0.8_dp*n0, 'numerical diffusion did not lower the per-pixel noise: '// &
               str(n1)//' against '//str(n0))
  end subroutine test_diffusion

  ! ------------------------------------------------------------------------------------------
  ! 2. truncation: biased, within a documented bound

  !> Standard truncation (30 deg, 4 levels, peak 30) vs none on a tau = 10, omega = 0.999,
  !> HG 0.85 slab (sza 30): TOA radiances at nadir and 60 deg within max(4 sigma, 1 %), the
  !> reflectance and transmittance within max(4 sigma, 0.5 %).
  subroutine test_truncation(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: off, on
    type(result_set_t) :: r_off, r_on
    real(dp), allocatable :: m1(:), e1(:), m2(:), e2(:)
    real(dp) :: s, nlev
    integer :: i
    character(len=16), parameter :: FLUXES(2) = [character(len=16) :: 'reflectance', &
                                                 'transmittance']
    character(len=*), parameter :: DIRS(3) = [character(len=14) :: 'nadir', '60 deg phi 0', &
                                              '60 deg phi 180']
    off = slab_config(10.0_wp, 0.999_wp, 'hg', 0.85_wp, 30.0_wp, 0.2_wp, 25000_i8, 40)
    call set_vr(off, 0.3_wp, 0.0_wp, 0.0_wp, 1)
    call set_radiance(off, [1.0_wp, 0.5_wp, 0.5_wp], [0.0_wp, 0.0_wp, 180.0_wp], [1])
    on = off
    call set_vr(on, 0.3_wp, 0.0_wp, 30.0_wp, 4)
    on%control%seed = 505_i8
    ! the untruncated run is the noisier one: twice the photons
    off%control%n_photons_per_batch = 50000_i8
    call run_pair(off, r_off, on, r_on, error)
    if (allocated(error)) return
    call get_attr_real(r_on, 'truncation_levels', nlev, error)
    call check_close(error, nlev, 4.0_dp, label='truncation_levels with truncation')
    call get_attr_real(r_off, 'truncation_levels', nlev, error)
    call check_close(error, nlev, 1.0_dp, label='truncation_levels without truncation')
    call get_array(r_off, 'radiance', m1, e1, error)
    call get_array(r_on, 'radiance', m2, e2, error)
    if (allocated(error)) return
    do i = 1, size(m1)
      s = sqrt(e1(i)**2 + e2(i)**2)
      call note('truncation bias, TOA radiance '//trim(DIRS(i))//': '// &
                str(100.0_dp*(m2(i) - m1(i))/m1(i))//' % (4 sigma = '// &
                str(400.0_dp*s/m1(i))//' %; '//str(m1(i))//' vs '//str(m2(i))//')')
      call check_close(error, m2(i), m1(i), abs_tol=K*s, rel_tol=0.01_dp, &
                       label='truncated TOA radiance, '//trim(DIRS(i)))
    end do
    do i = 1, size(FLUXES)
      call get_array(r_off, trim(FLUXES(i)), m1, e1, error)
      call get_array(r_on, trim(FLUXES(i)), m2, e2, error)
      if (allocated(error)) return
      s = sqrt(e1(1)**2 + e2(1)**2)
      call note('truncation bias, '//trim(FLUXES(i))//': '// &
                str(100.0_dp*(m2(1) - m1(1))/m1(1))//' % (4 sigma = '// &
                str(400.0_dp*s/m1(1))//' %)')
      call check_close(error, m2(1), m1(1), abs_tol=K*s, rel_tol=0.005_dp, &
                       label='truncated '//trim(FLUXES(i)))
    end do
  end subroutine test_truncation

  ! ------------------------------------------------------------------------------------------
  ! 3. cameras

  !> A Lambert surface (albedo 0.3) under a transparent layer, sun at 40 deg: the pixels of a
  !> nadir pinhole above the top, an orthographic nadir camera and a tilted pinhole, and the
  !> up-going radiances at the top in mu = 1 and 0.5, all equal the albedo.
  subroutine test_camera_lambert(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp), parameter :: ALBEDO = 0.3_dp
    type(config_t) :: cfg
    type(result_set_t) :: res
    real(dp), allocatable :: m(:), e(:)
    real(dp) :: dev, chi2
    integer :: c, i
    cfg = slab_config(0.0_wp, 1.0_wp, 'iso', 0.0_wp, 40.0_wp, ALBEDO, 8000_i8, 50)
    call set_vr(cfg, 0.3_wp, 1.0_wp, 0.0_wp, 1)
    call set_radiance(cfg, [1.0_wp, 0.5_wp], [0.0_wp, 90.0_wp], [1])
    ! nadir pinhole 1 km above the top (it sees 1.5 lx: periodic images), orthographic nadir
    ! of width lx, pinhole tilted 30 deg off nadir
    call add_camera(cfg, 'pinhole', [500.0_wp, 500.0_wp, 2000.0_wp], 180.0_wp, 40.0_wp, &
                    0.0_wp, 8, 8)
    call add_camera(cfg, 'orthographic', [500.0_wp, 500.0_wp, 1500.0_wp], 180.0_wp, 0.0_wp, &
                    cfg%atm%lx, 8, 8)
    call add_camera(cfg, 'pinhole', [300.0_wp, 700.0_wp, 1500.0_wp], 150.0_wp, 40.0_wp, &
                    0.0_wp, 8, 8)
    call run_config(cfg, res, error)
    if (allocated(error)) return
    do c = 1, 3
      call get_array(res, 'camera'//str(c)//'_radiance', m, e, error)
      if (allocated(error)) return
      call check(error, size(m) == 64, 'camera'//str(c)//' must have 8 x 8 pixels')
      if (allocated(error)) return
      dev = 0.0_dp
      chi2 = 0.0_dp
      do i = 1, size(m)
        call check(error, e(i) > 0.0_dp, 'camera'//str(c)//' pixel '//str(i)//' has no error')
        if (allocated(error)) return
        dev = max(dev, abs(m(i) - ALBEDO)/e(i))
        chi2 = chi2 + ((m(i) - ALBEDO)/e(i))**2
        call check_sigma(error, m(i), ALBEDO, e(i), K, 'camera'//str(c)//' pixel '//str(i))
      end do
      call note('camera'//str(c)//': mean pixel '//str(sum(m)/size(m))//', largest deviation '// &
                str(dev)//' sigma, chi2/n '//str(chi2/size(m)))
      ! the whole image: the mean of the pixels within k sigma of its own error
      call check_sigma(error, sum(m)/size(m), ALBEDO, sqrt(sum(e**2))/size(m), K, &
                       'camera'//str(c)//' image mean')
    end do
    call get_array(res, 'radiance', m, e, error)
    if (allocated(error)) return
    do i = 1, size(m)
      call check_sigma(error, m(i), ALBEDO, e(i), K, 'TOA radiance('//str(i)//')', &
                       abs_floor=1.0e-12_dp)
    end do
    call note('TOA radiance mu = 1, 0.5: '//str(m(1))//' +- '//str(e(1))//', '//str(m(2))// &
              ' +- '//str(e(2)))
  end subroutine test_camera_lambert

  ! ------------------------------------------------------------------------------------------
  ! 4. stability

  !> Detector directions at |mu| = 1e-6 and 1e-3, sun at 89.9 deg, over a nearly transparent
  !> layer (tau 1e-6, collision forcing factor 1e6) and a very thick one (tau 1e4, omega 0.999,
  !> truncation on), each with cameras: the runs end in reasonable time, every output is
  !> finite, the energy budget closes, the anomaly counters are reported.
  subroutine test_stress(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: MU(6) = [1.0e-6_wp, -1.0e-6_wp, 1.0e-3_wp, -1.0e-3_wp, 1.0_wp, &
                                    -1.0_wp]
    real(wp), parameter :: PHI(6) = [0.0_wp, 90.0_wp, 180.0_wp, 270.0_wp, 0.0_wp, 0.0_wp]
    character(len=*), parameter :: ANOM(4) = [character(len=15) :: 'uz_nudged', 'event_cap', &
                                              'step_cap', 'position_repair']
    type(config_t) :: cfg
    type(result_set_t) :: res
    type(run_summary_t) :: summary
    real(dp) :: m, e, f, t
    real(dp), allocatable :: rm(:), re(:)
    character(len=:), allocatable :: text, line
    logical :: found
    integer :: icase, i
    do icase = 1, 3
      select case (icase)
      case (1)   ! nearly transparent layer: every photon is forced to collide (factor 1e6),
        ! ~570 times along its grazing path
        cfg = slab_config(1.0e-6_wp, 1.0_wp, 'hg', 0.85_wp, 89.9_wp, 0.3_wp, 250_i8, 4)
        call set_vr(cfg, 0.3_wp, 1.0_wp, 0.0_wp, 1)
      case (2)   ! very thick layer, few photons, truncation on
        cfg = slab_config(1.0e4_wp, 0.999_wp, 'hg', 0.85_wp, 89.9_wp, 0.3_wp, 50_i8, 4)
        call set_vr(cfg, 0.3_wp, 1.0_wp, 30.0_wp, 4)
        call add_camera(cfg, 'pinhole', [500.0_wp, 500.0_wp, 0.0_wp], 0.0_wp, 40.0_wp, &
                        0.0_wp, 4, 4)
      case default   ! the thin layer without forcing or roulette, and a camera inside the
        ! layer looking at the horizon: its view reaches infinity, its periodic images are
        ! capped (about 5000 image shifts per event)
        cfg = slab_config(1.0e-6_wp, 1.0_wp, 'hg', 0.85_wp, 89.9_wp, 0.3_wp, 250_i8, 4)
        call set_vr(cfg, 0.0_wp, 0.0_wp, 0.0_wp, 1)
        call add_camera(cfg, 'pinhole', [500.0_wp, 500.0_wp, 500.0_wp], 90.0_wp, 40.0_wp, &
                        0.0_wp, 4, 4)
      end select
      call set_radiance(cfg, MU, PHI, [0, 1])
      call add_camera(cfg, 'pinhole', [500.0_wp, 500.0_wp, 1500.0_wp], 180.0_wp, 40.0_wp, &
                      0.0_wp, 4, 4)
      call add_camera(cfg, 'orthographic', [500.0_wp, 500.0_wp, 2000.0_wp], 179.9_wp, 0.0_wp, &
                      cfg%atm%lx, 4, 4)
      call run_config(cfg, res, error, summary)
      if (allocated(error)) return
      call check_all_finite(res, 'stress case '//str(icase), error)
      call get_scalar(res, 'energy_closure', m, e, error)
      call check_close(error, m, 1.0_dp, abs_tol=1.0e-10_dp, rel_tol=0.0_dp, &
                       label='energy_closure (stress case '//str(icase)//')')
      call check(error, summary%wall_time < 60.0_dp, 'stress case '//str(icase)// &
                 ' took '//str(summary%wall_time)//' s')
      call get_attr_real(res, 'collision_forcing_factor', f, error)
      line = 'stress case '//str(icase)//': wall '//str(summary%wall_time)//' s, events/photon '// &
             str(real(summary%events, dp)/real(summary%n_photons, dp))//', forcing factor '// &
             str(f)//', closure - 1 = '//str(m - 1.0_dp)//'; anomalies:'
      do i = 1, size(ANOM)
        call get_attr(res, 'anomaly_'//trim(ANOM(i)), text, found)
        call check(error, found, 'attribute anomaly_'//trim(ANOM(i))//' is missing')
        line = line//' '//trim(ANOM(i))//' '//text
      end do
      call note(line)
      ! radiance is (rad_level, direction): level 0 of direction d at 1 + 2 (d - 1)
      call get_array(res, 'radiance', rm, re, error)
      call get_scalar(res, 'transmittance', t, e, error)
      if (allocated(error)) return
      call note('  up-going radiance at the surface, mu = 1e-6, 1e-3, 1: '//str(rm(1))//' +- '// &
                str(re(1))//', '//str(rm(5))//' +- '//str(re(5))//', '//str(rm(9))//' +- '// &
                str(re(9))//' (albedo x transmittance = '//str(0.3_dp*t)//'); at the top, '// &
                'mu = 1e-6: '//str(rm(2))//' +- '//str(re(2)))
      if (icase == 3) then
        ! without roulette every surface reflection adds its reflected weight to every up-going
        ! direction: the radiance at the surface is albedo x transmittance, to round-off
        do i = 1, 5, 2
          call check_close(error, rm(1 + 2*(i - 1)), 0.3_dp*t, rel_tol=1.0e-12_dp, &
                           label='up-going radiance at the surface, mu = '//str(MU(i)))
        end do
      end if
      call get_scalar(res, 'weight_lost', m, e, error)
      call check(error, m <= 0.0_dp, 'weight lost in stress case '//str(icase))
      if (allocated(error)) return
    end do
  end subroutine test_stress

  ! ------------------------------------------------------------------------------------------
  ! 5. warning

  !> HG 0.85 (P(0) = 82 > 50) with radiances, roulette and truncation off: a warning naming the
  !> forward peak; with roulette on (or truncation on) no warning.
  subroutine test_warning(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: res
    character(len=:), allocatable :: text
    logical :: found
    cfg = hg_slab(2.0_wp, 100_i8)
    cfg%control%n_batches = 10   ! fewer batches would warn of their error bars
    call run_config(cfg, res, error)
    if (allocated(error)) return
    call get_attr(res, 'warnings', text, found)
    call check(error, found, 'no warnings attribute with roulette and truncation off')
    call check(error, len_trim(text) > 0, 'empty warnings attribute')
    call check(error, index(text, 'forward peak') > 0, 'the warning does not mention the '// &
               'forward peak: "'//text//'"')
    if (allocated(error)) return
    call note('warning: '//text)
    cfg%vr%zeta_min = 0.3_wp
    call run_config(cfg, res, error)
    if (allocated(error)) return
    call get_attr(res, 'warnings', text, found)
    call check(error, len_trim(text) == 0, 'warning with zeta_min = 0.3: "'//text//'"')
    cfg%vr%zeta_min = 0.0_wp
    call set_vr(cfg, 0.0_wp, 0.0_wp, 30.0_wp, 4)
    call run_config(cfg, res, error)
    if (allocated(error)) return
    call get_attr(res, 'warnings', text, found)
    call check(error, len_trim(text) == 0, 'warning with truncation on: "'//text//'"')
  end subroutine test_warning
end module test_radiance_suite

program test_radiance
  use kumo_test_text, only: run_suite
  use test_radiance_suite, only: collect_radiance
  implicit none
  call run_suite('radiance', collect_radiance())
end program test_radiance
