! SPDX-License-Identifier: BSD-3-Clause
!> Engine equivalences and budgets: every fast path gives the same answer as the general path
!> (within k sigma of the combined standard error, k = 4), a homogeneous 3-D region gives the 1-D
!> answer, the energy budget closes to round-off, and stress scenes stay finite.
module test_engine_suite
  use kumo_kinds, only: wp, dp, i8
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_sigma
  use kumo_config, only: config_t
  use kumo_results, only: result_set_t
  use kumo_test_scenes, only: slab_config, set_phases, run_config, run_pair, get_scalar, &
                              get_array, attach_scene
  use kumo_results, only: add_dim, add_var
  use kumo_netcdf, only: write_results
  use kumo_driver, only: run_summary_t
  implicit none
  private
  public :: collect_engine

  real(dp), parameter :: K = 4.0_dp
  character(len=24), parameter :: BUDGET(3) = [character(len=24) :: 'reflectance', &
    'transmittance', 'absorptance_atmosphere']

contains

  function collect_engine() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('homogeneous_3d_equals_1d', test_homogeneous_3d), &
             new_unittest('supervoxels_on_equals_off', test_supervoxels), &
             new_unittest('layer_fast_paths_on_equal_off', test_fast_paths), &
             new_unittest('clear_layers_change_nothing', test_clear_layers), &
             new_unittest('roulette_unbiased', test_roulette), &
             new_unittest('energy_closure_exact', test_closure), &
             new_unittest('voxel_absorption_sums_to_layers', test_voxel_sums), &
             new_unittest('stress_scenes_stay_finite', test_stress), &
             new_unittest('albedo_map_under_clear_sky', test_albedo_map), &
             new_unittest('target_error_mode_stops_when_reached', test_target_error)]
  end function collect_engine

  !> Compare the budget outputs of two runs within k sigma of their combined error.
  subroutine compare_runs(a, b, label, error, names)
    type(result_set_t), intent(in) :: a, b
    character(len=*), intent(in) :: label
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in), optional :: names(:)
    real(dp) :: ma, ea, mb, eb
    integer :: i
    character(len=24), allocatable :: list(:)
    if (present(names)) then
      list = names
    else
      list = BUDGET
    end if
    do i = 1, size(list)
      call get_scalar(a, trim(list(i)), ma, ea, error)
      call get_scalar(b, trim(list(i)), mb, eb, error)
      if (allocated(error)) return
      call check_sigma(error, ma, mb, sqrt(ea**2 + eb**2), K, label//': '//trim(list(i)), &
                       abs_floor=1.0e-12_dp)
      if (allocated(error)) return
    end do
  end subroutine compare_runs

  !> A deterministic inhomogeneous field with clear voxels and a dense core [m-1].
  function cloud_field(nx, ny, n3) result(ext)
    integer, intent(in) :: nx, ny, n3
    real(wp) :: ext(nx, ny, n3)
    integer :: i, j, kk
    do kk = 1, n3
      do j = 1, ny
        do i = 1, nx
          ext(i, j, kk) = max(0.0_wp, 0.02_wp*(sin(1.3_wp*i) + cos(0.7_wp*j) + 0.3_wp*kk - 0.4_wp))
        end do
      end do
    end do
    ext(nx/2, ny/2, :) = 0.2_wp
  end function cloud_field

  subroutine test_homogeneous_3d(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: c1, c3
    type(result_set_t) :: r1, r3
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    c1 = slab_config(5.0_wp, 0.99_wp, 'hg', 0.85_wp, 30.0_wp, 0.2_wp, 20000_i8, 10)
    c3 = c1
    allocate (ext(4, 3, 1), ssa(4, 3, 1))
    ext = c1%atm%ext1d(1, 1)
    ssa = 0.99_wp
    c3%atm%ext1d = 0.0_wp
    call attach_scene(c3, 'engine_homog.nc', 1, ext, ssa, 1, error)
    if (allocated(error)) return
    c3%control%seed = 11_i8
    call run_pair(c1, r1, c3, r3, error)
    if (allocated(error)) return
    call compare_runs(r1, r3, '1-D vs 3-D', error, [character(len=24) :: BUDGET, &
                      'transmittance_direct', 'absorptance_surface'])
  end subroutine test_homogeneous_3d

  subroutine test_supervoxels(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: on, off
    type(result_set_t) :: r_on, r_off
    type(run_summary_t) :: s_on, s_off
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    real(dp), allocatable :: m1(:), e1(:), m2(:), e2(:)
    integer :: i
    on = slab_config(0.0_wp, 1.0_wp, 'hg', 0.85_wp, 40.0_wp, 0.1_wp, 20000_i8, 10)
    deallocate (on%atm%z, on%atm%ext1d, on%atm%ssa1d, on%atm%phase1d)
    on%atm%nz = 6
    on%atm%z = [0.0_wp, 200.0_wp, 300.0_wp, 400.0_wp, 500.0_wp, 650.0_wp, 2000.0_wp]
    allocate (on%atm%ext1d(6, 1), on%atm%ssa1d(6, 1), on%atm%phase1d(6, 1))
    on%atm%ext1d = 0.0_wp
    on%atm%ssa1d = 1.0_wp
    on%atm%phase1d = 1
    on%output%flux_levels = [0, 1, 2, 3, 4, 5, 6]
    ext = cloud_field(16, 8, 4)
    allocate (ssa(16, 8, 4))
    ssa = 0.98_wp
    call attach_scene(on, 'engine_cloud.nc', 2, ext, ssa, 1, error)
    if (allocated(error)) return
    off = on
    off%vr%use_supervoxels = .false.
    off%control%seed = 99_i8
    call run_pair(on, r_on, off, r_off, error, s_on, s_off)
    if (allocated(error)) return
    call compare_runs(r_on, r_off, 'super-voxels on vs off', error)
    call check(error, s_on%flight_steps < s_off%flight_steps, &
               'super-voxels must take fewer flight steps than one global majorant')
    if (allocated(error)) return
    call get_array(r_on, 'absorptance_layer', m1, e1, error)
    call get_array(r_off, 'absorptance_layer', m2, e2, error)
    if (allocated(error)) return
    do i = 1, size(m1)
      call check_sigma(error, m1(i), m2(i), sqrt(e1(i)**2 + e2(i)**2), K, &
                       'absorptance_layer', abs_floor=1.0e-12_dp)
    end do
    call get_array(r_on, 'flux_up', m1, e1, error)
    call get_array(r_off, 'flux_up', m2, e2, error)
    if (allocated(error)) return
    do i = 1, size(m1)
      call check_sigma(error, m1(i), m2(i), sqrt(e1(i)**2 + e2(i)**2), K, 'flux_up(level)', &
                       abs_floor=1.0e-12_dp)
    end do
  end subroutine test_supervoxels

  !> A column with every layer class: clear, absorbing, Rayleigh-like, cloud.
  function layered_config() result(cfg)
    type(config_t) :: cfg
    cfg = slab_config(0.0_wp, 1.0_wp, 'hg', 0.85_wp, 50.0_wp, 0.3_wp, 20000_i8, 10)
    deallocate (cfg%atm%z, cfg%atm%ext1d, cfg%atm%ssa1d, cfg%atm%phase1d)
    cfg%atm%nz = 5
    cfg%atm%z = [0.0_wp, 500.0_wp, 1000.0_wp, 1500.0_wp, 3000.0_wp, 8000.0_wp]
    cfg%atm%n_components = 2
    allocate (cfg%atm%ext1d(5, 2), cfg%atm%ssa1d(5, 2), cfg%atm%phase1d(5, 2))
    ! component 1: molecules (Rayleigh) with an absorbing layer; component 2: cloud (HG)
    cfg%atm%ext1d(:, 1) = [2.0e-5_wp, 1.0e-3_wp, 0.0_wp, 1.0e-5_wp, 0.0_wp]
    cfg%atm%ssa1d(:, 1) = [1.0_wp, 0.0_wp, 1.0_wp, 1.0_wp, 1.0_wp]
    cfg%atm%ext1d(:, 2) = [0.0_wp, 0.0_wp, 0.0_wp, 3.0e-3_wp, 0.0_wp]
    cfg%atm%ssa1d(:, 2) = [1.0_wp, 1.0_wp, 1.0_wp, 0.999_wp, 1.0_wp]
    cfg%atm%phase1d(:, 1) = [2, 2, 2, 1, 2]   ! varies between layers: per-voxel phase indices
    cfg%atm%phase1d(:, 2) = 1                 ! when this column goes through the 3-D tracer
    deallocate (cfg%phase%kind, cfg%phase%kind_name, cfg%phase%g, cfg%phase%file)
    call set_phases(cfg, [character(len=8) :: 'hg', 'rayleigh'], [0.85_wp, 0.0_wp])
    cfg%output%flux_levels = [0, 1, 2, 3, 4, 5]
  end function layered_config

  subroutine test_fast_paths(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: base, no1d, noabs
    type(result_set_t) :: rb, r1, r2
    type(run_summary_t) :: sb, s1, s2
    real(dp) :: mt1, et1, mt2, et2
    real(dp), allocatable :: m1(:), e1(:), m2(:), e2(:)
    integer :: i
    base = layered_config()
    no1d = base
    no1d%vr%use_1d_layers = .false.
    no1d%control%seed = 21_i8
    noabs = base
    noabs%vr%use_absorbing_layers = .false.
    noabs%control%seed = 31_i8
    call run_pair(base, rb, no1d, r1, error, sb, s1)
    if (allocated(error)) return
    call run_config(noabs, r2, error, s2)
    if (allocated(error)) return
    call compare_runs(rb, r1, 'analytic 1-D layers vs 3-D tracer', error)
    call compare_runs(rb, r2, 'absorbing fast path vs collisions', error)
    if (allocated(error)) return
    call check(error, sb%flight_steps < s1%flight_steps, &
               'analytic 1-D layers must take fewer flight steps than the 3-D tracer')
    call get_array(rb, 'absorptance_layer', m1, e1, error)
    call get_array(r2, 'absorptance_layer', m2, e2, error)
    if (allocated(error)) return
    do i = 1, size(m1)
      call check_sigma(error, m1(i), m2(i), sqrt(e1(i)**2 + e2(i)**2), K, &
                       'absorptance_layer (absorbing fast path)', abs_floor=1.0e-12_dp)
    end do
    ! attenuating the weight instead of ending photons in the absorbing layer: fewer collisions,
    ! and a smaller error of what lies below it
    call check(error, sb%events < s2%events, 'absorbing fast path must need fewer events')
    call get_scalar(rb, 'transmittance', mt1, et1, error)
    call get_scalar(r2, 'transmittance', mt2, et2, error)
    call check(error, et1 < et2, 'absorbing fast path must reduce the error below the layer')
  end subroutine test_fast_paths

  subroutine test_clear_layers(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: a, b
    type(result_set_t) :: ra, rb
    a = slab_config(2.0_wp, 0.95_wp, 'iso', 0.0_wp, 60.0_wp, 0.2_wp, 20000_i8, 10)
    b = a
    deallocate (b%atm%z, b%atm%ext1d, b%atm%ssa1d, b%atm%phase1d)
    b%atm%nz = 4
    b%atm%z = [0.0_wp, 300.0_wp, 1300.0_wp, 5000.0_wp, 20000.0_wp]
    allocate (b%atm%ext1d(4, 1), b%atm%ssa1d(4, 1), b%atm%phase1d(4, 1))
    b%atm%ext1d(:, 1) = [0.0_wp, 2.0e-3_wp, 0.0_wp, 0.0_wp]
    b%atm%ssa1d = 0.95_wp
    b%atm%phase1d = 1
    b%output%flux_levels = [0, 4]
    b%control%seed = 41_i8
    call run_pair(a, ra, b, rb, error)
    if (allocated(error)) return
    call compare_runs(ra, rb, 'clear layers added', error)
  end subroutine test_clear_layers

  subroutine test_roulette(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: a, b
    type(result_set_t) :: ra, rb
    a = slab_config(4.0_wp, 0.9_wp, 'hg', 0.7_wp, 20.0_wp, 0.5_wp, 20000_i8, 10)
    b = a
    b%vr%rr_threshold = 0.05_wp
    b%vr%rr_weight = 1.0_wp
    b%control%seed = 51_i8
    call run_pair(a, ra, b, rb, error)
    if (allocated(error)) return
    call compare_runs(ra, rb, 'roulette window 0.25/0.5 vs 0.05/1', error, &
                      [character(len=24) :: BUDGET, 'absorptance_surface'])
  end subroutine test_roulette

  !> R + A_atm + A_sfc - roulette + lost = 1 per batch (round-off), and the roulette balance is
  !> zero within its own error (so R + A + A_sfc = 1 statistically).
  subroutine test_closure(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: res
    real(dp) :: m, e, rr, err_rr
    integer :: icase
    do icase = 1, 3
      select case (icase)
      case (1)
        cfg = slab_config(10.0_wp, 1.0_wp, 'hg', 0.85_wp, 0.0_wp, 0.0_wp, 20000_i8, 10)
      case (2)
        cfg = slab_config(3.0_wp, 0.8_wp, 'iso', 0.0_wp, 60.0_wp, 0.3_wp, 20000_i8, 10)
      case default
        cfg = layered_config()
      end select
      call run_config(cfg, res, error)
      if (allocated(error)) return
      call get_scalar(res, 'energy_closure', m, e, error)
      if (allocated(error)) return
      call check_close(error, m, 1.0_dp, abs_tol=1.0e-12_dp, rel_tol=0.0_dp, label='energy_closure')
      call check(error, e < 1.0e-12_dp, 'energy_closure varies between batches')
      call get_scalar(res, 'roulette_weight_balance', rr, err_rr, error)
      call check_sigma(error, rr, 0.0_dp, err_rr, K, 'roulette_weight_balance', &
                       abs_floor=1.0e-12_dp)
      call get_scalar(res, 'weight_lost', m, e, error)
      call check(error, m == 0.0_dp, 'no weight may be lost in an ordinary scene')
      if (allocated(error)) return
    end do
  end subroutine test_closure

  subroutine test_voxel_sums(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: res
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    real(dp), allocatable :: vox(:), evox(:), lay(:), elay(:), fmap(:), emap(:), fl(:), efl(:)
    integer :: kk, ncol
    cfg = slab_config(0.0_wp, 1.0_wp, 'hg', 0.85_wp, 30.0_wp, 0.0_wp, 5000_i8, 4)
    deallocate (cfg%atm%z, cfg%atm%ext1d, cfg%atm%ssa1d, cfg%atm%phase1d)
    cfg%atm%nz = 3
    cfg%atm%z = [0.0_wp, 400.0_wp, 800.0_wp, 1200.0_wp]
    allocate (cfg%atm%ext1d(3, 1), cfg%atm%ssa1d(3, 1), cfg%atm%phase1d(3, 1))
    cfg%atm%ext1d = 0.0_wp
    cfg%atm%ssa1d = 1.0_wp
    cfg%atm%phase1d = 1
    cfg%output%flux_levels = [0, 1, 2, 3]
    ext = cloud_field(8, 6, 3)
    allocate (ssa(8, 6, 3))
    ssa = 0.9_wp
    call attach_scene(cfg, 'engine_vox.nc', 1, ext, ssa, 1, error)
    if (allocated(error)) return
    call run_config(cfg, res, error)
    if (allocated(error)) return
    ncol = 8*6
    call get_array(res, 'absorptance_voxel', vox, evox, error)
    call get_array(res, 'absorptance_layer', lay, elay, error)
    if (allocated(error)) return
    ! column-area normalised voxel absorptances average to the layer absorptance exactly
    do kk = 1, 3
      call check_close(error, sum(vox((kk - 1)*ncol + 1:kk*ncol))/ncol, lay(kk), &
                       abs_tol=1.0e-13_dp, rel_tol=1.0e-12_dp, label='voxel mean vs layer')
    end do
    call get_array(res, 'flux_up_map', fmap, emap, error)
    call get_array(res, 'flux_up', fl, efl, error)
    if (allocated(error)) return
    do kk = 1, 4
      call check_close(error, sum(fmap((kk - 1)*ncol + 1:kk*ncol))/ncol, fl(kk), &
                       abs_tol=1.0e-13_dp, rel_tol=1.0e-12_dp, label='flux map mean vs domain')
    end do
  end subroutine test_voxel_sums

  !> Grazing sun, near-transparent and very thick layers, clear voxels next to thick ones:
  !> every output finite, the budget closed, nothing lost.
  subroutine test_stress(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: res
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    real(dp) :: m, e
    integer :: icase, i
    do icase = 1, 4
      select case (icase)
      case (1)   ! sun at 89.9 deg over a thin layer
        cfg = slab_config(1.0e-6_wp, 1.0_wp, 'hg', 0.85_wp, 89.9_wp, 0.3_wp, 5000_i8, 4)
      case (2)   ! very thick layer, tau = 1e4, strongly absorbing (photons end quickly)
        cfg = slab_config(1.0e4_wp, 0.5_wp, 'iso', 0.0_wp, 0.0_wp, 0.0_wp, 5000_i8, 4)
      case (3)   ! thick conservative layer, tau = 200
        cfg = slab_config(200.0_wp, 1.0_wp, 'hg', 0.85_wp, 60.0_wp, 0.5_wp, 1000_i8, 4)
      case default  ! checkerboard of clear and very thick voxels (tau 100 per voxel), sun at zenith
        cfg = slab_config(0.0_wp, 1.0_wp, 'hg', 0.85_wp, 0.0_wp, 0.2_wp, 2000_i8, 4)
        allocate (ext(8, 8, 1), ssa(8, 8, 1))
        ext = 0.0_wp
        do i = 1, 64
          if (mod(i + (i - 1)/8, 2) == 0) ext(mod(i - 1, 8) + 1, (i - 1)/8 + 1, 1) = 0.1_wp
        end do
        ssa = 0.99_wp
        call attach_scene(cfg, 'engine_checker.nc', 1, ext, ssa, 1, error)
        if (allocated(error)) return
      end select
      call run_config(cfg, res, error)
      if (allocated(error)) return
      do i = 1, size(res%vars)
        call check(error, all(abs(res%vars(i)%mean) <= huge(1.0_dp)), &
                   'non-finite value in '//trim(res%vars(i)%name))
      end do
      call get_scalar(res, 'energy_closure', m, e, error)
      call check_close(error, m, 1.0_dp, abs_tol=1.0e-12_dp, rel_tol=0.0_dp, &
                       label='energy_closure (stress)')
      call get_scalar(res, 'weight_lost', m, e, error)
      call check(error, m == 0.0_dp, 'weight lost in a stress scene')
      if (allocated(error)) return
    end do
    ! case 2: the direct beam through tau = 1e4 is exactly zero and the reflectance is the
    ! semi-infinite isotropic value for omega = 0.5, mu0 = 1: 1 - sqrt(0.5) H(1; 0.5) = 0.115254
    cfg = slab_config(1.0e4_wp, 0.5_wp, 'iso', 0.0_wp, 0.0_wp, 0.0_wp, 20000_i8, 10)
    call run_config(cfg, res, error)
    if (allocated(error)) return
    call get_scalar(res, 'reflectance', m, e, error)
    call check_sigma(error, m, 1.0_dp - sqrt(0.5_dp)*1.251260_dp, e, K, &
                     'semi-infinite reflectance omega 0.5', abs_floor=1.0e-6_dp)
    call get_scalar(res, 'transmittance', m, e, error)
    call check(error, m == 0.0_dp, 'transmittance through tau = 1e4 must be 0')
  end subroutine test_stress
  !> Under a transparent atmosphere every photon reaches the surface once: the reflectance is
  !> the map's mean albedo, and a uniform map gives bit for bit the uniform-albedo answer.
  subroutine test_albedo_map(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg, uni
    type(result_set_t) :: map_file, res, r_map, r_uni
    real(dp) :: alb(5, 3), m, e, m2, e2
    integer :: i, j
    do j = 1, 3
      do i = 1, 5
        alb(i, j) = 0.1_dp*(i - 1) + 0.05_dp*(j - 1)
      end do
    end do
    call add_dim(map_file, 'xs', 5)
    call add_dim(map_file, 'ys', 3)
    call add_var(map_file, 'albedo', 'surface albedo', '1', ['xs', 'ys'], reshape(alb, [15]))
    call write_results('engine_albedo.nc', map_file, error)
    if (allocated(error)) return
    cfg = slab_config(0.0_wp, 1.0_wp, 'iso', 0.0_wp, 30.0_wp, 0.0_wp, 20000_i8, 10)
    cfg%surface%albedo_file = 'engine_albedo.nc'
    call run_config(cfg, res, error)
    if (allocated(error)) return
    call get_scalar(res, 'reflectance', m, e, error)
    call check_sigma(error, m, sum(alb)/15, e, K, 'reflectance over an albedo map')
    call get_scalar(res, 'absorptance_surface', m, e, error)
    call check_sigma(error, m, 1.0_dp - sum(alb)/15, e, K, 'surface absorptance over the map')
    if (allocated(error)) return
    map_file%vars(1)%mean = 0.3_dp
    call write_results('engine_albedo_uniform.nc', map_file, error)
    if (allocated(error)) return
    cfg = slab_config(2.0_wp, 0.9_wp, 'hg', 0.7_wp, 30.0_wp, 0.3_wp, 5000_i8, 4)
    uni = cfg
    cfg%surface%albedo_file = 'engine_albedo_uniform.nc'
    call run_pair(cfg, r_map, uni, r_uni, error)
    if (allocated(error)) return
    do i = 1, size(BUDGET)
      call get_scalar(r_map, trim(BUDGET(i)), m, e, error)
      call get_scalar(r_uni, trim(BUDGET(i)), m2, e2, error)
      call check(error, m == m2 .and. e == e2, 'uniform map differs from uniform albedo: '// &
                 trim(BUDGET(i)))
    end do
  end subroutine test_albedo_map

  !> Batches are added in rounds until the target relative error is reached, or the photon cap.
  subroutine test_target_error(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: res
    type(run_summary_t) :: summary
    real(dp) :: m, e
    cfg = slab_config(1.0_wp, 0.9_wp, 'iso', 0.0_wp, 0.0_wp, 0.0_wp, 2000_i8, 4)
    cfg%control%target_rel_error = 0.004_wp
    cfg%control%target_output = 'reflectance'
    call run_config(cfg, res, error, summary)
    if (allocated(error)) return
    call get_scalar(res, 'reflectance', m, e, error)
    call check(error, e/m <= 0.004_dp, 'target relative error not reached')
    call check(error, summary%n_batches > 4 .and. mod(summary%n_batches, 4_i8) == 0, &
               'rounds of n_batches were added')
    cfg%control%target_rel_error = 1.0e-6_wp
    cfg%control%max_photons = 24000_i8
    call run_config(cfg, res, error, summary)
    if (allocated(error)) return
    call check(error, summary%n_photons == 24000_i8, 'the photon cap stops the run')
  end subroutine test_target_error
end module test_engine_suite

program test_engine
  use kumo_test_text, only: run_suite
  use test_engine_suite, only: collect_engine
  implicit none
  call run_suite('engine', collect_engine())
end program test_engine
