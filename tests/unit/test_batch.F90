! SPDX-License-Identifier: BSD-3-Clause
!> Whole batches on scenes built in code with the kernel library alone (no namelist, MPI or
!> netCDF): scene_t, the solar source and trace_batch, checked against exact answers, DISORT and
!> the rule that stratified entry points never cost variance.
module test_batch_suite
  use kumo_kinds, only: wp, dp, i8
  use kumo_error, only: str
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_sigma
  use kumo_rng, only: rng_t, rng_init
  use kumo_phase, only: phase_t, new_phase_hg, new_phase_isotropic
  use kumo_atmosphere, only: atmosphere_options_t, atmosphere_init
  use kumo_surface, only: surface_init
  use kumo_camera, only: camera_t
  use kumo_local_estimate, only: detectors_init
  use kumo_tally, only: tally_layout_t, tally_t, layout_init, tally_reset
  use kumo_source, only: solar_source, source_stratify
  use kumo_scene, only: scene_t
  use kumo_transport, only: trace_batch
  implicit none
  private
  public :: collect_batch

contains

  function collect_batch() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('transparent_lambert_exact', test_transparent), &
             new_unittest('absorbing_layer_exact', test_absorbing), &
             new_unittest('hg_slab_vs_disort', test_hg_slab), &
             new_unittest('stratified_entry_never_costs_variance', test_stratified)]
  end function collect_batch

  !> A plane-parallel scene: layers of extinction `ext` and albedo `omega` (bottom first, 1000 m
  !> each) with phase function `ph`, over a Lambert surface, sun at `sza_deg`.
  subroutine plane_scene(ext, omega, ph, albedo, sza_deg, scn, error)
    real(wp), intent(in) :: ext(:), omega(:), albedo, sza_deg
    type(phase_t), intent(in) :: ph
    type(scene_t), intent(out) :: scn
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_options_t) :: aopts
    type(camera_t) :: cams(0)
    integer :: k, nz
    nz = size(ext)
    call atmosphere_init(scn%atm, [(1000.0_wp*k, k=0, nz)], 1000.0_wp, 1000.0_wp, &
                         reshape(ext, [nz, 1]), reshape(omega, [nz, 1]), &
                         reshape([(1, k=1, nz)], [nz, 1]), [ph], aopts, error)
    if (allocated(error)) return
    call surface_init(scn%sfc, reshape([albedo], [1, 1]), 1000.0_wp, 1000.0_wp, error)
    if (allocated(error)) return
    call finish_scene(scn, sza_deg, cams)
  end subroutine plane_scene

  subroutine finish_scene(scn, sza_deg, cams)
    type(scene_t), intent(inout) :: scn
    real(wp), intent(in) :: sza_deg
    type(camera_t), intent(in) :: cams(:)
    scn%src = solar_source(sza_deg, 0.0_wp)
    scn%mu0 = -scn%src%uz
    call detectors_init(scn%det, [real(wp) ::], [real(wp) ::], [integer ::], cams, 0.0_wp, &
                        scn%atm%lx, scn%atm%ly)
  end subroutine finish_scene

  !> Reflectance (upward flux at the top) and transmittance of `nb` batches of `n` photons:
  !> per-batch values.
  subroutine run_batches(scn, n, nb, seed, r, t)
    type(scene_t), intent(in) :: scn
    integer(i8), intent(in) :: n
    integer, intent(in) :: nb
    integer(i8), intent(in) :: seed
    real(dp), intent(out) :: r(nb), t(nb)
    type(tally_layout_t) :: lay
    type(tally_t) :: tal
    type(rng_t) :: rng
    integer :: ib
    call layout_init(lay, scn%atm%nz, scn%atm%nx*scn%atm%ny, scn%atm%n3, [integer ::], .false.)
    do ib = 1, nb
      call rng_init(rng, seed, int(ib, i8))
      call tally_reset(tal, lay)
      call trace_batch(scn, lay, rng, n, tal)
      r(ib) = tal%buf(lay%i_up + lay%nz + 1)/real(n, dp)
      t(ib) = (tal%buf(lay%i_dir + 1) + tal%buf(lay%i_dif + 1))/real(n, dp)
    end do
  end subroutine run_batches

  pure real(dp) function mean(x)
    real(dp), intent(in) :: x(:)
    mean = sum(x)/size(x)
  end function mean

  !> Variance of the values (n - 1 in the denominator).
  pure real(dp) function variance(x)
    real(dp), intent(in) :: x(:)
    variance = sum((x - mean(x))**2)/(size(x) - 1)
  end function variance

  !> Nothing between the sun and a Lambert surface of albedo 0.3: every photon comes back with
  !> weight 0.3 (above the roulette threshold), so R = 0.3 and T = 1 in every batch, exactly.
  subroutine test_transparent(error)
    type(error_t), allocatable, intent(out) :: error
    type(scene_t) :: scn
    real(dp) :: r(3), t(3)
    call plane_scene([0.0_wp], [1.0_wp], new_phase_isotropic(), 0.3_wp, 40.0_wp, scn, error)
    if (allocated(error)) return
    call run_batches(scn, 1000_i8, 3, 5_i8, r, t)
    call check_close(error, maxval(abs(r - 0.3_dp)), 0.0_wp, 1.0e-14_wp, 0.0_wp, 'R')
    if (allocated(error)) return
    call check_close(error, maxval(abs(t - 1.0_dp)), 0.0_wp, 1.0e-14_wp, 0.0_wp, 'T')
  end subroutine test_transparent

  !> A purely absorbing layer (optical depth 0.7) over a black surface: it is crossed
  !> analytically, so T = exp(-tau/mu0) and R = 0 in every batch, to round-off.
  subroutine test_absorbing(error)
    type(error_t), allocatable, intent(out) :: error
    type(scene_t) :: scn
    real(dp) :: r(2), t(2)
    real(wp), parameter :: SZA = 60.0_wp
    call plane_scene([0.7e-3_wp], [0.0_wp], new_phase_isotropic(), 0.0_wp, SZA, scn, error)
    if (allocated(error)) return
    call run_batches(scn, 500_i8, 2, 9_i8, r, t)
    call check_close(error, maxval(abs(t - exp(-0.7_dp/scn%mu0))), 0.0_wp, 1.0e-14_wp, &
                     0.0_wp, 'T - exp(-tau/mu0)')
    if (allocated(error)) return
    call check(error, maxval(r) <= 0.0_dp, 'R must be 0 over a black surface')
  end subroutine test_absorbing

  !> HG g = 0.85, tau = 10, omega = 0.999, SZA 30, black surface: DISORT gives R = 0.45939,
  !> T = 0.52002 (case hg0.85_w0.999_tau10_sza30_alb0 of the plane-parallel reference table,
  !> the example examples/hg_slab); within 4 standard errors.
  subroutine test_hg_slab(error)
    type(error_t), allocatable, intent(out) :: error
    type(scene_t) :: scn
    integer, parameter :: NB = 10
    real(dp) :: r(NB), t(NB)
    type(phase_t) :: hg
    hg = new_phase_hg(0.85_wp, error)
    if (allocated(error)) return
    call plane_scene([0.01_wp], [0.999_wp], hg, 0.0_wp, 30.0_wp, scn, error)
    if (allocated(error)) return
    call run_batches(scn, 20000_i8, NB, 3_i8, r, t)
    call check_sigma(error, mean(r), 0.45939_wp, sqrt(variance(r)/NB), &
                     4.0_wp, 'R')
    if (allocated(error)) return
    call check_sigma(error, mean(t), 0.52002_wp, sqrt(variance(t)/NB), &
                     4.0_wp, 'T')
  end subroutine test_hg_slab

  !> A 3-D field of 16 x 16 columns, thick cloud (tau 20) in the rows y < ly/2, clear air in
  !> the others. The domain reflectance of a batch depends on how many photons enter above the
  !> cloud, so entry points that cover the domain unevenly show up as batch-to-batch variance.
  !> Whatever the batch size (a multiple of the 256 entry cells, one and a half times, or less
  !> than one), the stratified source must vary less between batches than independent entry
  !> points; leftover photons given to one band of rows made it vary several times more.
  subroutine test_stratified(error)
    type(error_t), allocatable, intent(out) :: error
    type(scene_t) :: plain, strat
    type(atmosphere_options_t) :: aopts
    type(camera_t) :: cams(0)
    real(wp) :: ext3(16, 16, 1, 1), ssa3(16, 16, 1, 1)
    integer, parameter :: NB = 60
    integer(i8), parameter :: SIZES(3) = [512_i8, 384_i8, 200_i8]
    real(dp) :: r0(NB), t0(NB), r1(NB), t1(NB), ratio
    integer :: i
    type(phase_t) :: hg
    hg = new_phase_hg(0.85_wp, error)
    if (allocated(error)) return
    ext3 = 0.0_wp
    ext3(:, 1:8, 1, 1) = 0.02_wp
    ssa3 = 1.0_wp
    call atmosphere_init(plain%atm, [0.0_wp, 1000.0_wp], 1600.0_wp, 1600.0_wp, &
                         reshape([0.0_wp], [1, 1]), reshape([1.0_wp], [1, 1]), &
                         reshape([1], [1, 1]), [hg], aopts, error, 1, ext3, ssa3)
    if (allocated(error)) return
    call surface_init(plain%sfc, reshape([0.0_wp], [1, 1]), 1600.0_wp, 1600.0_wp, error)
    if (allocated(error)) return
    call finish_scene(plain, 0.0_wp, cams)
    strat = plain
    call source_stratify(strat%src, 16, 16, 1000.0_wp)
    do i = 1, size(SIZES)
      call run_batches(plain, SIZES(i), NB, 21_i8, r0, t0)
      call run_batches(strat, SIZES(i), NB, 21_i8, r1, t1)
      ! independent entry points: the cloud fraction seen by a batch is binomial, so the
      ! batch variance of R is far above what the stratified batches should show
      ratio = variance(r1)/variance(r0)
      call check(error, ratio < 1.0_dp, 'stratified / independent batch variance of R = '// &
                 str(ratio)//' for '//str(SIZES(i))//' photons per batch')
      if (allocated(error)) return
      ! and the estimates agree (both unbiased)
      call check_sigma(error, mean(r1), mean(r0), &
                       sqrt((variance(r0) + variance(r1))/NB), 4.0_wp, 'R')
      if (allocated(error)) return
    end do
  end subroutine test_stratified

end module test_batch_suite

program test_batch
  use kumo_testing, only: run_unittests
  use test_batch_suite, only: collect_batch
  implicit none
  integer :: n_failed
  call run_unittests('batch', collect_batch(), n_failed)
  if (n_failed > 0) error stop 1
end program test_batch
