! SPDX-License-Identifier: BSD-3-Clause
!> Levels inside the super-layers of the 3-D walk (`fly_3d` in kumo_transport): the walk does not
!> stop at them, and tallies the levels a straight piece of flight has passed afterwards.
!>
!> * A conservative 3-D field over a black surface (no absorption, no roulette: every photon
!>   keeps weight 1): a photon that ends at the surface has crossed every level once more
!>   downward than upward, one that escapes as often each way, so the net downward flux is the
!>   transmittance at every level, to round-off. Checked with one majorant for the whole region
!>   (every level inside one super-layer) and with the default grid, together with the flux
!>   maps (their mean over the columns is the domain flux at every level: each crossing falls in
!>   a column of the domain).
!> * An isotropic absorbing layer (DISORT case iso_w0.9_tau1_sza60_alb0.2) as four voxel layers
!>   under one majorant: R, T and the absorption against `reference/disort_pp.csv` within 4
!>   sigma with the collision, track and tentative absorption estimators (the track estimator
!>   scores the flight piece by piece between the levels it passes), and the four layers'
!>   absorption of the track estimator against the collision estimator of another seed.
!> The path of the shared data folder is the first command-line argument.
module test_walk_levels_suite
  use kumo_kinds, only: wp, dp, i8
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_sigma
  use kumo_error, only: str
  use kumo_config, only: config_t
  use kumo_results, only: result_set_t
  use kumo_test_text, only: disort_value
  use kumo_test_scenes, only: slab_config, run_config, get_scalar, get_array, attach_scene
  implicit none
  private
  public :: collect_walk_levels

  real(dp), parameter :: K = 4.0_dp

contains

  function collect_walk_levels() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('net_flux_at_every_level_one_majorant', test_net_one), &
             new_unittest('net_flux_at_every_level_default_grid', test_net_default), &
             new_unittest('absorbing_layer_in_one_superlayer_vs_disort', test_disort)]
  end function collect_walk_levels

  subroutine test_net_one(error)
    type(error_t), allocatable, intent(out) :: error
    call net_flux(.false., error)
  end subroutine test_net_one

  subroutine test_net_default(error)
    type(error_t), allocatable, intent(out) :: error
    call net_flux(.true., error)
  end subroutine test_net_default

  !> A 12 x 10 x 6 conservative field (HG 0.85, extinction 0 to 0.06 m-1 in layers of 50 to
  !> 150 m) over clear air, SZA 50, black surface, flux maps at every level.
  subroutine net_flux(supervoxels, error)
    logical, intent(in) :: supervoxels
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: set
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    real(dp), allocatable :: fu(:), fd(:), eu(:), ed(:), mu(:), md(:), e(:)
    real(dp) :: t, tol, r, ncol
    integer :: i, j, kk, nz, nlev
    cfg = slab_config(0.0_wp, 1.0_wp, 'hg', 0.85_wp, 50.0_wp, 0.0_wp, 4000_i8, 5)
    deallocate (cfg%atm%ext1d, cfg%atm%ssa1d, cfg%atm%phase1d)
    nz = 8
    cfg%atm%nz = nz
    cfg%atm%z = [0.0_wp, 300.0_wp, 350.0_wp, 450.0_wp, 600.0_wp, 700.0_wp, 800.0_wp, 900.0_wp, &
                 2000.0_wp]
    cfg%atm%lx = 1200.0_wp
    cfg%atm%ly = 1000.0_wp
    allocate (cfg%atm%ext1d(nz, 1), cfg%atm%ssa1d(nz, 1), cfg%atm%phase1d(nz, 1))
    cfg%atm%ext1d = 0.0_wp
    cfg%atm%ssa1d = 1.0_wp
    cfg%atm%phase1d = 1
    cfg%output%flux_levels = [(i, i=0, nz)]
    cfg%output%column_fluxes = .true.
    cfg%vr%use_supervoxels = supervoxels
    cfg%control%seed = 500_i8
    allocate (ext(12, 10, 6), ssa(12, 10, 6))
    do kk = 1, 6
      do j = 1, 10
        do i = 1, 12
          ext(i, j, kk) = max(0.0_wp, 0.03_wp*(sin(0.9_wp*i + 0.4_wp*kk) + cos(0.6_wp*j) + 0.2_wp))
        end do
      end do
    end do
    ssa = 1.0_wp
    call attach_scene(cfg, 'walk_levels_field.nc', 2, ext, ssa, 1, error)
    if (allocated(error)) return
    call run_config(cfg, set, error)
    if (allocated(error)) return
    call get_array(set, 'flux_up', fu, eu, error)
    if (.not. allocated(error)) call get_array(set, 'flux_down', fd, ed, error)
    if (.not. allocated(error)) call get_scalar(set, 'transmittance', t, r, error)
    if (allocated(error)) return
    nlev = size(fu)
    call check(error, nlev == nz + 1, 'flux_up has '//str(nlev)//' levels, expected '//str(nz + 1))
    if (allocated(error)) return
    ! the weakly scattering field leaves T of order 0.5: a level crossing lost or counted twice
    ! changes the net flux there by the share of the photons that pass it, far above round-off
    call check(error, t > 0.1_dp .and. t < 0.9_dp, 'transmittance '//str(t)//' out of (0.1, 0.9)')
    if (allocated(error)) return
    tol = 1.0e-9_dp
    do i = 1, nlev
      call check(error, abs((fd(i) - fu(i)) - (fd(1) - fu(1))) <= tol, &
                 'net downward flux at level '//str(i - 1)//': '//str(fd(i) - fu(i))// &
                 ', at the surface '//str(fd(1) - fu(1))//' (conservative field, black surface)')
      if (allocated(error)) return
    end do
    call check(error, abs((fd(1) - fu(1)) - t) <= tol, 'net flux at the surface '// &
               str(fd(1) - fu(1))//' is not the transmittance '//str(t))
    if (allocated(error)) return
    ! flux maps: their mean over the columns is the domain flux at every level
    call get_array(set, 'flux_up_map', mu, e, error)
    if (.not. allocated(error)) call get_array(set, 'flux_down_map', md, e, error)
    if (allocated(error)) return
    ncol = 120.0_dp
    call check(error, size(mu) == 120*nlev, 'flux_up_map has '//str(size(mu))//' values, expected '// &
               str(120*nlev))
    if (allocated(error)) return
    do i = 1, nlev
      call check(error, abs(sum(mu((i - 1)*120 + 1:i*120))/ncol - fu(i)) <= tol .and. &
                 abs(sum(md((i - 1)*120 + 1:i*120))/ncol - fd(i)) <= tol, &
                 'flux maps at level '//str(i - 1)//': column means '// &
                 str(sum(mu((i - 1)*120 + 1:i*120))/ncol)//', '// &
                 str(sum(md((i - 1)*120 + 1:i*120))/ncol)//' against the domain fluxes '// &
                 str(fu(i))//', '//str(fd(i)))
      if (allocated(error)) return
    end do
  end subroutine net_flux

  !> DISORT case iso_w0.9_tau1_sza60_alb0.2 as a 4 x 3 x 4 region of 250 m voxel layers under one
  !> majorant (use_supervoxels off), so that the three levels inside the layer are passed
  !> without stops of the walk.
  subroutine test_disort(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: ID = 'iso_w0.9_tau1_sza60_alb0.2'
    character(len=9), parameter :: EST(3) = [character(len=9) :: 'collision', 'track', &
                                               'tentative']
    type(config_t) :: cfg, c
    type(result_set_t) :: set
    real(wp), allocatable :: ext(:, :, :), ssa(:, :, :)
    real(dp), allocatable :: m(:), e(:), m0(:), e0(:)
    real(dp) :: a_ref, r_ref, t_ref, v, s
    integer :: j, i
    a_ref = disort_value(ID, 'A_layer1', '', '', '', error)
    if (.not. allocated(error)) r_ref = disort_value(ID, 'R', '', '', '', error)
    if (.not. allocated(error)) t_ref = disort_value(ID, 'T_total', '', '', '', error)
    if (allocated(error)) return
    cfg = slab_config(0.0_wp, 1.0_wp, 'iso', 0.0_wp, 60.0_wp, 0.2_wp, 20000_i8, 20)
    deallocate (cfg%atm%ext1d, cfg%atm%ssa1d, cfg%atm%phase1d)
    cfg%atm%nz = 4
    cfg%atm%z = [0.0_wp, 250.0_wp, 500.0_wp, 750.0_wp, 1000.0_wp]
    allocate (cfg%atm%ext1d(4, 1), cfg%atm%ssa1d(4, 1), cfg%atm%phase1d(4, 1))
    cfg%atm%ext1d = 0.0_wp
    cfg%atm%ssa1d = 1.0_wp
    cfg%atm%phase1d = 1
    cfg%output%flux_levels = [0, 1, 2, 3, 4]
    cfg%vr%use_supervoxels = .false.
    allocate (ext(4, 3, 4), ssa(4, 3, 4))
    ext = 1.0_wp/1000.0_wp
    ssa = 0.9_wp
    call attach_scene(cfg, 'walk_levels_layer.nc', 1, ext, ssa, 1, error)
    if (allocated(error)) return
    do j = 1, size(EST)
      c = cfg
      c%vr%absorption_estimator = EST(j)
      c%control%seed = 600_i8 + j
      call run_config(c, set, error)
      if (allocated(error)) return
      call get_scalar(set, 'absorptance_atmosphere', v, s, error)
      if (allocated(error)) return
      call check_sigma(error, v, a_ref, s, K, trim(EST(j))//': absorptance_atmosphere')
      call get_scalar(set, 'reflectance', v, s, error)
      if (allocated(error)) return
      call check_sigma(error, v, r_ref, s, K, trim(EST(j))//': reflectance')
      call get_scalar(set, 'transmittance', v, s, error)
      if (allocated(error)) return
      call check_sigma(error, v, t_ref, s, K, trim(EST(j))//': transmittance')
      if (allocated(error)) return
      if (j == 1) then
        call get_array(set, 'absorptance_layer', m0, e0, error)
      else
        call get_array(set, 'absorptance_layer', m, e, error)
        if (allocated(error)) return
        do i = 1, size(m)
          call check_sigma(error, m(i), m0(i), sqrt(e(i)**2 + e0(i)**2), K, trim(EST(j))// &
                           ' vs collision: absorptance_layer('//str(i)//')')
          if (allocated(error)) return
        end do
      end if
      if (allocated(error)) return
    end do
  end subroutine test_disort

end module test_walk_levels_suite

program test_walk_levels
  use kumo_test_text, only: run_shared_suite
  use test_walk_levels_suite, only: collect_walk_levels
  implicit none
  call run_shared_suite('test_walk_levels', 'reference/disort_pp.csv', 'walk_levels', &
                        collect_walk_levels())
end program test_walk_levels
