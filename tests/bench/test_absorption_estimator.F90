! SPDX-License-Identifier: BSD-3-Clause
!> The expected-value absorption estimators (&kumo_vr absorption_estimator = 'track' and
!> 'tentative', kumo_vr and kumo_transport) against discrete ordinates and against the collision
!> estimator:
!>
!> * an isotropic absorbing layer (omega 0.9, tau 1, SZA 60, albedo 0.2) as a 3-D region, and
!>   the two-layer case of the table (Rayleigh over HG 0.85, omega 0.9999) with its Rayleigh
!>   layer in the 3-D region under one majorant (sv off: 99 % of its tentative collisions are
!>   null), against `reference/disort_pp.csv` within 4 sigma: layer absorption, R and T; and a
!>   thin absorbing layer (tau 0.1) with a radiance detector, so that collision forcing is on;
!> * a 3-D field with clear (gas-absorbing) and cloudy voxels: every voxel's absorptance by
!>   'track' and 'tentative' against the collision estimator of a run with another seed, within
!>   5 sigma of the difference per voxel, with the RMS of the normalised differences near 1 and
!>   the track estimator's error bars smaller in the clear voxels;
!> * with the same seed the photons follow the same paths: reflectance, transmittance and
!>   surface absorption are bit-identical to the collision run's ('track_voxels': its layer
!>   absorption and weight balance are the collision run's, its voxels the track run's, to the
!>   last bit); the energy budget closes to
!>   round-off, and the weight balance (collision losses against the expected-value scores) is
!>   zero within 4 sigma;
!> * a thermal run refuses the expected-value estimators (regression bad input
!>   `absorption_estimator_thermal`).
!> The path of the shared data folder is the first command-line argument.
module test_absorption_estimator_suite
  use kumo_kinds, only: wp, dp, i8
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_sigma
  use kumo_error, only: str
  use kumo_config, only: config_t
  use kumo_results, only: result_set_t
  use kumo_test_text, only: disort_value
  use kumo_test_scenes, only: slab_config, set_layers, run_config, get_scalar, get_array, &
                              attach_scene
  implicit none
  private
  public :: collect_absorption_estimator

  real(dp), parameter :: K = 4.0_dp
  character(len=12), parameter :: EXPECTED(3) = [character(len=12) :: 'track', 'tentative', &
                                                   'track_voxels']
  !> The first N_LAYERS of EXPECTED score the layers along the flights ('track_voxels' scores
  !> them at collisions, to the last bit as 'collision': test_same_paths)
  integer, parameter :: N_LAYERS = 2

contains

  function collect_absorption_estimator() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('absorbing_layer_3d_vs_disort', test_absorbing_layer), &
             new_unittest('forced_collisions_vs_disort', test_forced), &
             new_unittest('two_layer_null_collisions_vs_disort', test_two_layer), &
             new_unittest('voxels_vs_collision_estimator', test_voxels), &
             new_unittest('same_paths_and_closure', test_same_paths)]
  end function collect_absorption_estimator

  !> kumo's value of `name` (element i) within K sigma of the DISORT value.
  subroutine against(set, name, i, ref, label, error)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: name, label
    integer, intent(in) :: i
    real(dp), intent(in) :: ref
    type(error_t), allocatable, intent(inout) :: error
    real(dp), allocatable :: m(:), e(:)
    if (allocated(error)) return
    call get_array(set, name, m, e, error)
    if (allocated(error)) return
    call check_sigma(error, m(i), ref, e(i), K, label//': '//name//'('//str(i)//')', &
                     abs_floor=1.0e-12_dp)
  end subroutine against

  !> DISORT case iso_w0.9_tau1_sza60_alb0.2 as a 4 x 3 x 2 region (the layer in two voxel
  !> layers of 500 m) with voxel output.
  subroutine test_absorbing_layer(error)
    type(error_t), allocatable, intent(out) :: error
    call absorbing_layer('iso_w0.9_tau1_sza60_alb0.2', 1.0_wp, 60.0_wp, 0.2_wp, .false., error)
  end subroutine test_absorbing_layer

  !> DISORT case iso_w0.9_tau0.1_sza0_alb0 the same way, with a radiance detector at the top:
  !> collision forcing raises the extinction tenfold (cf_tau_min 1), which the tentative
  !> collisions' score must divide out.
  subroutine test_forced(error)
    type(error_t), allocatable, intent(out) :: error
    call absorbing_layer('iso_w0.9_tau0.1_sza0_alb0', 0.1_wp, 0.0_wp, 0.0_wp, .true., error)
  end subroutine test_forced

  subroutine absorbing_layer(id, tau, sza, albedo, radiance, error)
    character(len=*), intent(in) :: id
    real(wp), intent(in) :: tau, sza, albedo
    logical, intent(in) :: radiance
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg, c
    type(result_set_t) :: set
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    real(dp) :: a_ref, r_ref, t_ref
    integer :: j
    a_ref = disort_value(id, 'A_layer1', '', '', '', error)
    r_ref = disort_value(id, 'R', '', '', '', error)
    t_ref = disort_value(id, 'T_total', '', '', '', error)
    if (allocated(error)) return
    cfg = slab_config(0.0_wp, 1.0_wp, 'iso', 0.0_wp, sza, albedo, 20000_i8, 20)
    cfg%atm%nz = 2
    cfg%atm%z = [0.0_wp, 500.0_wp, 1000.0_wp]
    deallocate (cfg%atm%ext1d, cfg%atm%ssa1d, cfg%atm%phase1d)
    allocate (cfg%atm%ext1d(2, 1), cfg%atm%ssa1d(2, 1), cfg%atm%phase1d(2, 1))
    cfg%atm%ext1d = 0.0_wp
    cfg%atm%ssa1d = 1.0_wp
    cfg%atm%phase1d = 1
    cfg%output%flux_levels = [0, 1, 2]
    if (radiance) then
      cfg%rad%mu = [1.0_wp]
      cfg%rad%phi_deg = [0.0_wp]
      cfg%rad%levels = [2]
      cfg%rad%maps = .false.
    end if
    allocate (ext(4, 3, 2), ssa(4, 3, 2))
    ext = tau/1000.0_wp
    ssa = 0.9_wp
    call attach_scene(cfg, 'absest_layer.nc', 1, ext, ssa, 1, error)
    if (allocated(error)) return
    do j = 1, N_LAYERS
      c = cfg
      c%vr%absorption_estimator = EXPECTED(j)
      c%control%seed = 100_i8 + j
      call run_config(c, set, error)
      if (allocated(error)) return
      call against(set, 'absorptance_atmosphere', 1, a_ref, trim(EXPECTED(j)), error)
      call against(set, 'reflectance', 1, r_ref, trim(EXPECTED(j)), error)
      call against(set, 'transmittance', 1, t_ref, trim(EXPECTED(j)), error)
      if (allocated(error)) return
    end do
  end subroutine absorbing_layer

  !> DISORT case twolayer_sza60_alb0.2: Rayleigh tau 0.1 over HG 0.85 tau 10 omega 0.9999. Both
  !> layers form the 3-D region (the HG layer as the voxel component, the Rayleigh layer as the
  !> 1-D background added to the voxels) under one majorant, so the walk through the Rayleigh
  !> layer is nearly all null collisions.
  subroutine test_two_layer(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: ID = 'twolayer_sza60_alb0.2'
    type(config_t) :: cfg, c
    type(result_set_t) :: set
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    real(dp) :: a_ref, r_ref
    integer :: j
    a_ref = disort_value(ID, 'A_layer2', '', '', '', error)
    r_ref = disort_value(ID, 'R', '', '', '', error)
    if (allocated(error)) return
    call set_layers(cfg, [0.1_wp, 10.0_wp], [1.0_wp, 0.9999_wp], &
                    [character(len=8) :: 'rayleigh', 'hg'], [0.0_wp, 0.85_wp])
    cfg%atm%ext1d(1, 1) = 0.0_wp     ! the HG layer comes from the 3-D region
    cfg%path = 'test.nml'
    cfg%source%sza_deg = 60.0_wp
    cfg%surface%albedo = 0.2_wp
    cfg%output%flux_levels = [0, 1, 2]
    cfg%control%n_photons_per_batch = 5000_i8
    cfg%control%n_batches = 20
    cfg%control%verbose = 0
    cfg%vr%use_supervoxels = .false.
    allocate (ext(3, 2, 2), ssa(3, 2, 2))
    ext(:, :, 1) = 10.0_wp/1000.0_wp
    ext(:, :, 2) = 0.0_wp
    ssa = 0.9999_wp
    call attach_scene(cfg, 'absest_two_layer.nc', 1, ext, ssa, 2, error)
    if (allocated(error)) return
    do j = 1, N_LAYERS
      c = cfg
      c%vr%absorption_estimator = EXPECTED(j)
      c%control%seed = 200_i8 + j
      call run_config(c, set, error)
      if (allocated(error)) return
      call against(set, 'absorptance_layer', 1, a_ref, trim(EXPECTED(j)), error)
      call against(set, 'reflectance', 1, r_ref, trim(EXPECTED(j)), error)
      if (allocated(error)) return
    end do
  end subroutine test_two_layer

  !> A 10 x 8 x 3 field of 100 m voxels: cloudy voxels (extinction up to 0.05 m-1, omega 0.99)
  !> beside clear ones, over a gas that absorbs everywhere (3e-4 m-1), with voxel output.
  subroutine field_config(cfg, error)
    type(config_t), intent(out) :: cfg
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    integer :: i, j, kk
    cfg = slab_config(0.0_wp, 1.0_wp, 'hg', 0.85_wp, 30.0_wp, 0.1_wp, 4000_i8, 40)
    deallocate (cfg%atm%ext1d, cfg%atm%ssa1d, cfg%atm%phase1d)
    cfg%atm%nz = 5
    cfg%atm%z = [0.0_wp, 200.0_wp, 300.0_wp, 400.0_wp, 500.0_wp, 2000.0_wp]
    cfg%atm%lx = 1000.0_wp
    cfg%atm%ly = 800.0_wp
    allocate (cfg%atm%ext1d(5, 1), cfg%atm%ssa1d(5, 1), cfg%atm%phase1d(5, 1))
    cfg%atm%ext1d = 3.0e-4_wp
    cfg%atm%ssa1d = 0.0_wp
    cfg%atm%phase1d = 1
    cfg%output%flux_levels = [0, 1, 2, 3, 4, 5]
    allocate (ext(10, 8, 3), ssa(10, 8, 3))
    do kk = 1, 3
      do j = 1, 8
        do i = 1, 10
          ext(i, j, kk) = max(0.0_wp, 0.02_wp*(sin(1.3_wp*i) + cos(0.7_wp*j) + 0.3_wp*kk - 0.6_wp))
        end do
      end do
    end do
    ssa = 0.99_wp
    call attach_scene(cfg, 'absest_field.nc', 2, ext, ssa, 1, error)
  end subroutine field_config

  subroutine test_voxels(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg, c
    type(result_set_t) :: ref, set
    real(dp), allocatable :: m0(:), e0(:), m(:), e(:)
    real(dp) :: d, rms
    integer :: i, j, n, n_better
    call field_config(cfg, error)
    if (allocated(error)) return
    cfg%control%seed = 300_i8
    call run_config(cfg, ref, error)
    if (allocated(error)) return
    call get_array(ref, 'absorptance_voxel', m0, e0, error)
    if (allocated(error)) return
    do j = 1, size(EXPECTED)
      c = cfg
      c%vr%absorption_estimator = EXPECTED(j)
      c%control%seed = 300_i8 + j
      call run_config(c, set, error)
      if (allocated(error)) return
      call get_array(set, 'absorptance_voxel', m, e, error)
      if (allocated(error)) return
      rms = 0.0_dp
      n = 0
      do i = 1, size(m)
        call check_sigma(error, m(i), m0(i), sqrt(e(i)**2 + e0(i)**2), 5.0_dp, &
                         trim(EXPECTED(j))//' vs collision: absorptance_voxel('//str(i)//')')
        if (allocated(error)) return
        d = (m(i) - m0(i))/sqrt(e(i)**2 + e0(i)**2)
        rms = rms + d*d
        n = n + 1
      end do
      rms = sqrt(rms/n)
      call check(error, rms > 0.8_dp .and. rms < 1.25_dp, trim(EXPECTED(j))// &
                 ': RMS of the normalised voxel differences '//str(rms)//' not within [0.8, 1.25]')
      if (allocated(error)) return
      if (EXPECTED(j) == 'track') then
        ! scored along every path, the weakly absorbing voxels get far smaller error bars
        n_better = count(e < 0.5_dp*e0)
        call check(error, n_better > size(m)/4, 'track: only '//str(n_better)//' of '// &
                   str(size(m))//' voxels have less than half the collision estimator''s '// &
                   'standard error')
        if (allocated(error)) return
      end if
    end do
  end subroutine test_voxels

  !> Same seed, same photon paths: fluxes bit-identical, closure to round-off, balance zero;
  !> in F3D and in ICA (columns flown by fly_column).
  subroutine test_same_paths(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg, c
    type(result_set_t) :: ref, set, track
    real(dp) :: m0, e0, m, e
    integer :: j, i, im
    character(len=24), parameter :: SAME(3) = [character(len=24) :: 'reflectance', &
      'transmittance', 'absorptance_surface']
    character(len=3), parameter :: MODES(2) = ['f3d', 'ica']
    call field_config(cfg, error)
    if (allocated(error)) return
    cfg%control%seed = 400_i8
    cfg%control%n_batches = 10
    do im = 1, size(MODES)
      cfg%control%mode_3d = MODES(im)
      call run_config(cfg, ref, error)
      if (allocated(error)) return
      do j = 1, size(EXPECTED)
        c = cfg
        c%vr%absorption_estimator = EXPECTED(j)
        call run_config(c, set, error)
        if (allocated(error)) return
        do i = 1, size(SAME)
          call get_scalar(ref, trim(SAME(i)), m0, e0, error)
          call get_scalar(set, trim(SAME(i)), m, e, error)
          if (allocated(error)) return
          call check(error, m == m0 .and. e == e0, MODES(im)//', '//trim(EXPECTED(j))//': '// &
                     trim(SAME(i))//' differs from the collision run with the same seed')
          if (allocated(error)) return
        end do
        if (EXPECTED(j) == 'track_voxels') then
          ! the layers and the budget as the collision run's, the voxels as the track run's
          call same_array(ref, set, 'absorptance_layer', MODES(im)//', track_voxels vs collision', &
                          error)
          call same_array(ref, set, 'roulette_weight_balance', MODES(im)// &
                          ', track_voxels vs collision', error)
          call same_array(track, set, 'absorptance_voxel', MODES(im)//', track_voxels vs track', &
                          error)
          if (allocated(error)) return
        end if
        if (EXPECTED(j) == 'track') track = set
        call get_scalar(set, 'energy_closure', m, e, error)
        if (allocated(error)) return
        call check_close(error, m, 1.0_dp, abs_tol=1.0e-12_dp, rel_tol=0.0_dp, &
                         label=trim(EXPECTED(j))//': energy_closure')
        call get_scalar(set, 'roulette_weight_balance', m, e, error)
        if (allocated(error)) return
        call check(error, e > 0.0_dp, trim(EXPECTED(j))//': the weight balance has no spread')
        call check_sigma(error, m, 0.0_dp, e, K, MODES(im)//', '//trim(EXPECTED(j))// &
                         ': roulette_weight_balance')
        if (allocated(error)) return
      end do
    end do
  end subroutine test_same_paths

  !> Output `name` of `b` equal to that of `a` to the last bit (values and standard errors).
  subroutine same_array(a, b, name, label, error)
    type(result_set_t), intent(in) :: a, b
    character(len=*), intent(in) :: name, label
    type(error_t), allocatable, intent(inout) :: error
    real(dp), allocatable :: ma(:), ea(:), mb(:), eb(:)
    if (allocated(error)) return
    call get_array(a, name, ma, ea, error)
    if (allocated(error)) return
    call get_array(b, name, mb, eb, error)
    if (allocated(error)) return
    call check(error, size(ma) == size(mb), label//': '//name//' has another size')
    if (allocated(error)) return
    call check(error, all(ma == mb) .and. all(ea == eb), label//': '//name//' differs')
  end subroutine same_array
end module test_absorption_estimator_suite

program test_absorption_estimator
  use kumo_test_text, only: run_shared_suite
  use test_absorption_estimator_suite, only: collect_absorption_estimator
  implicit none
  call run_shared_suite('test_absorption_estimator', 'reference/disort_pp.csv', &
                        'absorption_estimator', collect_absorption_estimator())
end program test_absorption_estimator
