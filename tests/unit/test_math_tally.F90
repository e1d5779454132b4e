! SPDX-License-Identifier: BSD-3-Clause
!> Direction rotation, Gauss-Legendre quadrature, batch statistics and the scoring procedures.
module test_math_tally_suite
  use kumo_kinds, only: wp, dp, i8
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  use kumo_math, only: rotate_direction, gauss_legendre01, arccos, wrap
  use kumo_rng, only: rng_t, rng_init, sample_azimuth, rng_uniform
  use kumo_constants, only: PI
  use kumo_error, only: str
  use kumo_tally, only: tally_layout_t, tally_t, stats_t, layout_init, tally_reset, stats_init, &
                        stats_add_batch, stats_mean, stats_stderr, score_flux, score_flux_map, &
                        score_layer_abs, score_voxel_abs, score_surface_abs, score_roulette, &
                        score_lost, score_source, score_net_layer, score_net_surface, &
                        score_net_voxel, score_radiance, score_radiance_map, score_camera, &
                        tally_flush, tally_free, score_radiance_map_block, &
                        radiance_maps_integrate
  implicit none
  private
  public :: collect_math_tally

contains

  function collect_math_tally() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('rotation_keeps_angle_and_length', test_rotation), &
             new_unittest('rotation_of_vertical_directions', test_vertical), &
             new_unittest('batch_mean_and_standard_error', test_stats), &
             new_unittest('layout_is_contiguous', test_layout), &
             new_unittest('each_score_has_its_own_place', test_scores), &
             new_unittest('logged_scores_add_in_scoring_order', test_score_log), &
             new_unittest('map_blocks_integrate_to_their_sums', test_map_blocks), &
             new_unittest('polar_azimuth_is_uniform', test_azimuth), &
             new_unittest('gauss_legendre_is_exact_for_polynomials', test_gauss), &
             new_unittest('arccos_within_an_ulp_of_acos', test_arccos), &
             new_unittest('wrap_is_modulo_into_the_period', test_wrap)]
  end function collect_math_tally

  !> arccos against the compiler's acos: over [-1, 1] in fine steps, around the ends and the
  !> switch at |x| = 1/2 ulp by ulp, and at exact values; at most one unit in the last place.
  subroutine test_arccos(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: N = 400001
    real(wp) :: x, worst, xw, d
    integer :: i, k
    real(wp), parameter :: EDGES(5) = [-1.0_wp, -0.5_wp, 0.0_wp, 0.5_wp, 1.0_wp]
    worst = 0.0_wp
    xw = 0.0_wp
    do i = 0, N - 1
      x = -1.0_wp + 2.0_wp*real(i, wp)/real(N - 1, wp)
      call note(x)
    end do
    do k = 1, size(EDGES)
      x = EDGES(k)
      do i = 1, 64
        call note(x)
        if (x > -1.0_wp) call note(nearest(x, -1.0_wp))
        x = nearest(x, 1.0_wp)
        if (x > 1.0_wp) exit
      end do
      x = EDGES(k)
      do i = 1, 64
        if (x <= -1.0_wp) exit
        x = nearest(x, -1.0_wp)
        call note(x)
      end do
    end do
    do i = 1, 300                        ! tiny arguments and arguments near +-1 in octaves
      call note(2.0_wp**(-i))
      call note(-2.0_wp**(-i))
      if (i <= 52) call note(1.0_wp - 2.0_wp**(-i))
      if (i <= 52) call note(-1.0_wp + 2.0_wp**(-i))
    end do
    call check(error, worst <= 1.0_wp, 'arccos differs from acos by more than one ulp at x = ' &
               //str(xw))
    if (allocated(error)) return
    call check(error, arccos(1.0_wp) == 0.0_wp .and. arccos(-1.0_wp) == acos(-1.0_wp) .and. &
               arccos(0.0_wp) == acos(0.0_wp), 'arccos at -1, 0 and 1')
  contains
    subroutine note(v)
      real(wp), intent(in) :: v
      d = abs(arccos(v) - acos(v))/spacing(acos(v))
      if (acos(v) == 0.0_wp) d = abs(arccos(v))/tiny(1.0_wp)
      if (d > worst) then
        worst = d
        xw = v
      end if
    end subroutine note
  end subroutine test_arccos

  !> wrap gives what modulo does (and 0 where that rounds up to the period), within one period
  !> of the interval, at its ends and far beyond, for two periods.
  subroutine test_wrap(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: l, x, y, r, u
    real(wp) :: probes(16)
    integer :: i, il
    type(rng_t) :: rng
    call rng_init(rng, 5_i8, 0_i8)
    do il = 1, 2
      l = merge(1800.0_wp, 0.1_wp*PI, il == 1)
      probes = [-2.0_wp*l, -l, nearest(-l, 1.0_wp), nearest(-l, -1.0_wp), -1.0e-300_wp, &
                -tiny(1.0_wp), 0.0_wp, 1.0e-300_wp, nearest(l, -1.0_wp), l, nearest(l, 1.0_wp), &
                nearest(2.0_wp*l, -1.0_wp), 2.0_wp*l, 3.7_wp*l, -5.3_wp*l, 1.0e-17_wp - l]
      do i = 1, size(probes) + 20000
        if (i <= size(probes)) then
          x = probes(i)
        else
          u = rng_uniform(rng)
          x = (6.0_wp*u - 3.0_wp)*l
        end if
        r = modulo(x, l)
        if (r >= l) r = 0.0_wp
        y = x
        call wrap(y, l)
        call check(error, y == r .and. y >= 0.0_wp .and. y < l, 'wrap differs from modulo')
        if (allocated(error)) return
      end do
    end do
  end subroutine test_wrap

  subroutine test_rotation(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: ux, uy, uz, vx, vy, vz, mu, phi
    integer :: i
    do i = 1, 200
      ux = 0.3_wp
      uy = -0.4_wp
      uz = sqrt(1.0_wp - 0.25_wp)
      vx = ux
      vy = uy
      vz = uz
      mu = -1.0_wp + 2.0_wp*(i - 0.5_wp)/200
      phi = 0.37_wp*i
      call rotate_direction(vx, vy, vz, mu, cos(phi), sin(phi))
      call check_close(error, vx*vx + vy*vy + vz*vz, 1.0_wp, abs_tol=1.0e-14_wp, label='|v|^2')
      call check_close(error, vx*ux + vy*uy + vz*uz, mu, abs_tol=1.0e-13_wp, &
                       label='cosine between old and new direction')
      if (allocated(error)) return
    end do
    ! the renormalisation is one Newton step: an input 1e-6 off unit length comes out off by
    ! about 1.5e-12, an exact unit input stays within rounding
    vx = 0.3_wp*(1.0_wp + 1.0e-6_wp)
    vy = -0.4_wp*(1.0_wp + 1.0e-6_wp)
    vz = sqrt(0.75_wp)*(1.0_wp + 1.0e-6_wp)
    call rotate_direction(vx, vy, vz, 0.2_wp, cos(1.0_wp), sin(1.0_wp))
    call check_close(error, vx*vx + vy*vy + vz*vz, 1.0_wp, abs_tol=1.0e-11_wp, &
                     label='|v|^2 after turning a vector 1e-6 off unit length')
  end subroutine test_rotation

  !> A photon travelling straight down (sun at zenith) or up: the new direction must make the
  !> angle acos(mu) with the old one for backward as well as forward turns.
  subroutine test_vertical(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: ux, uy, uz, s
    integer :: i
    real(wp), parameter :: mus(4) = [0.9_wp, 0.2_wp, -0.3_wp, -0.95_wp]
    do i = 1, 4
      s = merge(-1.0_wp, 1.0_wp, mod(i, 2) == 0)
      ux = 0.0_wp
      uy = 0.0_wp
      uz = s
      call rotate_direction(ux, uy, uz, mus(i), cos(1.0_wp), sin(1.0_wp))
      call check_close(error, uz*s, mus(i), abs_tol=1.0e-14_wp, label='vertical turn, cosine')
      call check_close(error, ux*ux + uy*uy + uz*uz, 1.0_wp, abs_tol=1.0e-14_wp, label='|v|^2')
    end do
  end subroutine test_vertical

  subroutine test_stats(error)
    type(error_t), allocatable, intent(out) :: error
    type(tally_layout_t) :: lay
    type(tally_t) :: tal
    type(stats_t) :: st
    real(dp), parameter :: x(5) = [1.0_dp, 2.0_dp, 4.0_dp, 3.0_dp, 5.0_dp]
    real(dp) :: m(1), e(1), mean, var
    integer :: b
    call layout_init(lay, 1, 1, 0, [integer ::], .false.)
    call stats_init(st, lay)
    do b = 1, 5
      call tally_reset(tal, lay)
      tal%buf(lay%i_up + 2) = x(b)*10.0_dp    ! 10 photons per batch, reflectance x(b)
      call stats_add_batch(st, lay, tal, 10_i8)
    end do
    mean = sum(x)/5
    var = sum((x - mean)**2)/4       ! sample variance of the batch values
    m = stats_mean(st, lay%i_up + 2, lay%i_up + 2)
    e = stats_stderr(st, lay%i_up + 2, lay%i_up + 2)
    call check_close(error, m(1), mean, rel_tol=1.0e-14_dp, label='mean of batches')
    call check_close(error, e(1), sqrt(var/5), rel_tol=1.0e-12_dp, label='standard error')
    call check(error, st%n_photons == 50_i8 .and. st%n_batches == 5_i8, 'counters')
    ! a quantity that is 1 in every batch up to round-off has no standard error
    call stats_init(st, lay)
    do b = 1, 5
      call tally_reset(tal, lay)
      tal%buf(lay%i_up + 2) = 10.0_dp*(1.0_dp + (b - 3)*epsilon(1.0_dp))
      call stats_add_batch(st, lay, tal, 10_i8)
    end do
    e = stats_stderr(st, lay%i_up + 2, lay%i_up + 2)
    call check(error, e(1) == 0.0_dp, 'round-off spread must give a zero standard error')
  end subroutine test_stats

  subroutine test_layout(error)
    type(error_t), allocatable, intent(out) :: error
    type(tally_layout_t) :: lay
    call layout_init(lay, 3, 4, 2, [0, 3], .true.)
    call check(error, lay%i_dir == lay%i_up + 4 .and. lay%i_dif == lay%i_dir + 4, 'flux blocks')
    call check(error, lay%map_slot(0) == 1 .and. lay%map_slot(3) == 2 .and. &
               lay%map_slot(1) == 0, 'map slots')
    call check(error, lay%i_map_dn == lay%i_vox + 2*4, 'voxel block before the derived maps')
    call check(error, lay%n == lay%i_map_dn + 2*4, 'total downward maps end the buffer')
    call check(error, lay%i_map_dif == lay%i_map_dir + 2*4, 'map blocks')
  end subroutine test_layout

  !> Every scoring procedure adds its value to exactly one buffer entry, the one the layout
  !> documents, and no two kinds of score share an entry (a layout with every block: thermal,
  !> flux maps, voxels, radiances with maps, two cameras).
  subroutine test_scores(error)
    type(error_t), allocatable, intent(out) :: error
    type(tally_layout_t) :: lay
    type(tally_t) :: tal
    logical, allocatable :: used(:)
    integer, parameter :: nz = 3, ncol = 6, n3 = 2
    integer :: n_scores
    call layout_init(lay, nz, ncol, n3, [1, 3], .true., n_rad_dir=2, rad_levels=[0, 3], &
                     rad_maps=.true., cam_npix=[4, 5], region_levels=[1, 3], thermal=.true.)
    allocate (used(lay%n))
    used = .false.
    n_scores = 0
    call tally_reset(tal, lay)
    call score_flux(lay, tal, 2, .true., 3, 1.5_dp)
    call expect(lay%i_up + 3, 1.5_dp, 'score_flux up')
    call score_flux(lay, tal, 0, .false., 0, 2.5_dp)
    call expect(lay%i_dir + 1, 2.5_dp, 'score_flux direct')
    call score_flux(lay, tal, 3, .false., 2, 3.5_dp)
    call expect(lay%i_dif + 4, 3.5_dp, 'score_flux diffuse')
    call score_flux_map(lay, tal, 2, .true., 1, 5, 4.5_dp)
    call expect(lay%i_map_up + ncol + 5, 4.5_dp, 'score_flux_map up')
    call score_flux_map(lay, tal, 1, .false., 0, 2, 5.5_dp)
    call expect(lay%i_map_dir + 2, 5.5_dp, 'score_flux_map direct')
    call score_flux_map(lay, tal, 1, .false., 4, 6, 6.5_dp)
    call expect(lay%i_map_dif + 6, 6.5_dp, 'score_flux_map diffuse')
    call score_layer_abs(lay, tal, 3, 7.5_dp)
    call expect(lay%i_abs + 3, 7.5_dp, 'score_layer_abs')
    call score_voxel_abs(lay, tal, 2, 4, 8.5_dp)
    call expect(lay%i_vox + ncol + 4, 8.5_dp, 'score_voxel_abs')
    call score_surface_abs(lay, tal, 9.5_dp)
    call expect(lay%i_sfc + 1, 9.5_dp, 'score_surface_abs')
    call score_roulette(lay, tal, -10.5_dp)
    call expect(lay%i_rr + 1, -10.5_dp, 'score_roulette')
    call score_lost(lay, tal, 11.5_dp)
    call expect(lay%i_lost + 1, 11.5_dp, 'score_lost')
    call score_source(lay, tal, 12.5_dp)
    call expect(lay%i_src + 1, 12.5_dp, 'score_source')
    call score_net_layer(lay, tal, 1, -13.5_dp)
    call expect(lay%i_net + 1, -13.5_dp, 'score_net_layer')
    call score_net_surface(lay, tal, 14.5_dp)
    call expect(lay%i_snet + 1, 14.5_dp, 'score_net_surface')
    call score_net_voxel(lay, tal, ncol + 3, 15.5_dp)
    call expect(lay%i_vnet + ncol + 3, 15.5_dp, 'score_net_voxel')
    call score_radiance(lay, tal, 2, 1, 16.5_dp)
    call expect(lay%i_rad + lay%n_rad_lev + 1, 16.5_dp, 'score_radiance')
    call score_radiance_map(lay, tal, 2, 2, 3, 17.5_dp)
    call expect(lay%i_rad_map + (lay%n_rad_lev + 1)*ncol + 3, 17.5_dp, 'score_radiance_map')
    call score_camera(lay, tal, 2, 5, 18.5_dp)
    call expect(lay%i_cam(2) + 5, 18.5_dp, 'score_camera')
    call check(error, lay%i_cam(2) + 5 <= lay%i_col_abs, 'the last camera pixel is inside its block')
    if (allocated(error)) return
    ! scores add: a second score of the same kind goes to the same entry
    call score_flux(lay, tal, 2, .true., 3, 0.25_dp)
    call check(error, tal%buf(lay%i_up + 3) == 1.75_dp .and. count(tal%buf /= 0) == n_scores, &
               'a second score adds to the first')
  contains
    !> The last score added `v` at buffer entry i only, an entry no earlier score used.
    subroutine expect(i, v, label)
      integer, intent(in) :: i
      real(dp), intent(in) :: v
      character(len=*), intent(in) :: label
      if (allocated(error)) return
      call tally_flush(tal)
      n_scores = n_scores + 1
      call check(error, i >= 1 .and. i <= lay%n, label//': entry inside the buffer')
      if (allocated(error)) return
      call check(error, .not. used(i), label//': entry shared with an earlier score')
      if (allocated(error)) return
      used(i) = .true.
      call check(error, tal%buf(i) == v .and. count(tal%buf /= 0) == n_scores, &
                 label//': value not found at its entry alone')
    end subroutine expect
  end subroutine test_scores

  !> Diffused radiance-map samples are added as the corners of blocks and integrated at the end
  !> of the batch: each map column must hold the sum of the blocks over it (to round-off), for
  !> blocks anywhere on the map, up to the last row and column and over the whole map, in every
  !> map of several directions and levels, and nothing outside the maps may change. Without
  !> lay%rad_map_blocks the integration leaves the buffer alone.
  subroutine test_map_blocks(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: NX = 7, NY = 5, NCOL = NX*NY
    type(tally_layout_t) :: lay
    type(tally_t) :: tal
    type(rng_t) :: rng
    real(dp), allocatable :: expect(:), before(:)
    real(dp) :: v
    integer :: k, d, slot, ix1, ix2, iy1, iy2, i0, iy
    call layout_init(lay, 3, NCOL, 2, [0, 3], .true., n_rad_dir=2, rad_levels=[0, 3], &
                     rad_maps=.true., map_nx=NX, rad_map_blocks=.true.)
    call check(error, lay%rad_map_blocks .and. lay%map_nx == NX, 'layout keeps the map rows')
    if (allocated(error)) return
    call tally_reset(tal, lay)
    allocate (expect(lay%n))
    expect = 0.0_dp
    call rng_init(rng, 99_i8, 1_i8)
    do k = 1, 400
      d = 1 + int(2*rng_uniform(rng))
      slot = 1 + int(2*rng_uniform(rng))
      ix1 = 1 + int(NX*rng_uniform(rng))
      ix2 = ix1 + int((NX - ix1 + 1)*rng_uniform(rng))
      iy1 = 1 + int(NY*rng_uniform(rng))
      iy2 = iy1 + int((NY - iy1 + 1)*rng_uniform(rng))
      if (k <= 4) then   ! each map whole, then single corner columns
        d = 1 + mod(k - 1, 2)
        slot = 1 + (k - 1)/2
        ix1 = 1
        ix2 = NX
        iy1 = 1
        iy2 = NY
      else if (k <= 6) then
        ix1 = merge(1, NX, k == 5)
        ix2 = ix1
        iy1 = merge(1, NY, k == 5)
        iy2 = iy1
      end if
      v = 10.0_dp**(3*rng_uniform(rng) - 2)
      call score_radiance_map_block(lay, tal, d, slot, ix1, ix2, iy1, iy2, v)
      i0 = lay%i_rad_map + ((d - 1)*lay%n_rad_lev + slot - 1)*NCOL
      do iy = iy1, iy2
        expect(i0 + (iy - 1)*NX + ix1:i0 + (iy - 1)*NX + ix2) = &
          expect(i0 + (iy - 1)*NX + ix1:i0 + (iy - 1)*NX + ix2) + v
      end do
    end do
    call score_radiance(lay, tal, 1, 1, 2.5_dp)
    expect(lay%i_rad + 1) = 2.5_dp
    call radiance_maps_integrate(lay, tal)
    call check(error, all(abs(tal%buf - expect) <= 1.0e-12_dp*maxval(expect)), &
               'a map column differs from the sum of the blocks over it')
    if (allocated(error)) return
    call check(error, count(expect > 0) == 4*NCOL + 1, 'the blocks cover every map column')
    if (allocated(error)) return
    ! the same buffer under a layout without map blocks: untouched
    call layout_init(lay, 3, NCOL, 2, [0, 3], .true., n_rad_dir=2, rad_levels=[0, 3], &
                     rad_maps=.true., map_nx=NX)
    before = tal%buf
    call radiance_maps_integrate(lay, tal)
    call check(error, all(tal%buf == before), 'integrated maps without map blocks')
  end subroutine test_map_blocks

  !> Voxel absorption (at collisions and along paths alike) is logged and added at tally_flush
  !> (also when the log fills during a batch): every entry must get the same additions in the
  !> same order as if they had been added at once, so the sums agree to the last bit. Values of very different size make
  !> the sum depend on the order of the additions.
  subroutine test_score_log(error)
    type(error_t), allocatable, intent(out) :: error
    type(tally_layout_t) :: lay
    type(tally_t) :: tal
    integer, parameter :: ncol = 4, n3 = 3, n = 20000
    real(dp) :: direct(ncol*n3), v
    integer :: j, kr, icol
    ! the log is used from 2**19 voxels on
    call layout_init(lay, 3, 1024, 511, [0, 3], .true.)
    call check(error, .not. lay%log_voxel, '511 x 1024 voxels must not use the log')
    if (allocated(error)) return
    call layout_init(lay, 3, 1024, 512, [0, 3], .true.)
    call check(error, lay%log_voxel, '512 x 1024 voxels must use the log')
    if (allocated(error)) return
    call layout_init(lay, 3, ncol, n3, [0, 3], .true.)
    lay%log_voxel = .true.
    call tally_reset(tal, lay)
    direct = 0.0_dp
    do j = 1, n
      v = 1.0_dp/real(j, dp) + merge(1.0e8_dp, 0.0_dp, mod(j, 97) == 0)
      kr = 1 + mod(j, n3)
      icol = 1 + mod(j/3, ncol)
      call score_voxel_abs(lay, tal, kr, icol, v)
      direct((kr - 1)*ncol + icol) = direct((kr - 1)*ncol + icol) + v
    end do
    call tally_flush(tal)
    call check(error, all(tal%buf(lay%i_vox + 1:lay%i_vox + ncol*n3) == direct(1:ncol*n3)), &
               'voxel sums after the log differ from the sums added at once')
    if (allocated(error)) return
    ! a second flush adds nothing
    call tally_flush(tal)
    call check(error, all(tal%buf(lay%i_vox + 1:lay%i_vox + ncol*n3) == direct(1:ncol*n3)), &
               'a second flush changed the sums')
    if (allocated(error)) return
    call test_map_log()
  contains
    !> Flux maps of 2**17 entries and more go through the same log, mixed with the voxel
    !> collisions: the same sums to the last bit as scores added at once.
    subroutine test_map_log()
      integer, parameter :: nc = 65536
      real(dp), allocatable :: want(:)
      integer :: slot, i0
      logical :: up
      call layout_init(lay, 3, nc - 1, 1, [0, 3], .false.)
      call check(error, .not. lay%log_maps, '2 x 65535 map entries must not use the log')
      if (allocated(error)) return
      call layout_init(lay, 3, nc, 8, [0, 3], .true.)
      call check(error, lay%log_maps .and. lay%log_voxel, &
                 '2 x 65536 map entries and 8 x 65536 voxels must use the log')
      if (allocated(error)) return
      call tally_free(tal)
      call tally_reset(tal, lay)
      allocate (want(lay%n))
      want = 0.0_dp
      do j = 1, n
        v = 1.0_dp/real(j, dp) + merge(1.0e8_dp, 0.0_dp, mod(j, 89) == 0)
        slot = 1 + mod(j, 2)
        icol = 1 + mod(37*j, 64)
        up = mod(j, 3) == 0
        call score_flux_map(lay, tal, slot, up, mod(j, 2), icol, v)
        if (up) then
          i0 = lay%i_map_up
        else if (mod(j, 2) == 0) then
          i0 = lay%i_map_dir
        else
          i0 = lay%i_map_dif
        end if
        want(i0 + (slot - 1)*nc + icol) = want(i0 + (slot - 1)*nc + icol) + v
        if (mod(j, 5) == 0) then
          kr = 1 + mod(j, 8)
          call score_voxel_abs(lay, tal, kr, icol, 0.5_dp*v)
          want(lay%i_vox + (kr - 1)*nc + icol) = want(lay%i_vox + (kr - 1)*nc + icol) + 0.5_dp*v
        end if
      end do
      call tally_flush(tal)
      call check(error, all(tal%buf == want), &
                 'map and voxel sums after the log differ from the sums added at once')
    end subroutine test_map_log
  end subroutine test_score_log
  !> n-point Gauss-Legendre on [0, 1] integrates x^k exactly for k <= 2n - 1 (to 1/(k + 1)),
  !> and underestimates x^(2n) by the remainder term (positive for a positive 2n-th derivative).
  subroutine test_gauss(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: NS(4) = [1, 2, 7, 24]
    real(wp), allocatable :: x(:), w(:)
    integer :: i, n, k
    do i = 1, size(NS)
      n = NS(i)
      allocate (x(n), w(n))
      call gauss_legendre01(n, x, w)
      call check(error, all(x > 0.0_wp .and. x < 1.0_wp) .and. all(w > 0.0_wp), &
                 'nodes inside (0, 1), positive weights, n = '//achar(48 + mod(n, 10)))
      do k = 0, 2*n - 1
        call check_close(error, sum(w*x**k), 1.0_wp/(k + 1), abs_tol=1.0e-14_wp, &
                         label='integral of x^k')
      end do
      ! the remainder (n!)^4/((2n + 1)((2n)!)^2) is above round-off up to n = 7 (6e-9 there)
      if (n <= 7) call check(error, sum(w*x**(2*n)) < 1.0_wp/(2*n + 1) - 1.0e-10_wp, &
                             'x^(2n) must be underestimated by the remainder')
      deallocate (x, w)
      if (allocated(error)) return
    end do
  end subroutine test_gauss

  !> The polar-method azimuth: unit vector, and the angle uniform on [0, 2 pi) by a chi-square
  !> test over 36 bins (2e5 samples; 0.999 quantile of chi-square with 35 degrees of freedom is
  !> 66.62, from the inverse regularized gamma function).
  subroutine test_azimuth(error)
    type(error_t), allocatable, intent(out) :: error
    type(rng_t) :: rng
    integer, parameter :: n = 200000, nb = 36
    integer :: counts(nb), i, ib
    real(wp) :: c, s, phi, chi2, expected
    call rng_init(rng, 5_i8, 1_i8)
    counts = 0
    do i = 1, n
      call sample_azimuth(rng, c, s)
      call check_close(error, c*c + s*s, 1.0_wp, abs_tol=1.0e-14_wp, label='cos^2 + sin^2')
      if (allocated(error)) return
      phi = atan2(s, c)
      if (phi < 0.0_wp) phi = phi + 2.0_wp*PI
      ib = min(nb, int(phi/(2.0_wp*PI)*nb) + 1)
      counts(ib) = counts(ib) + 1
    end do
    expected = real(n, wp)/nb
    chi2 = sum((counts - expected)**2/expected)
    call check(error, chi2 < 66.62_wp, 'azimuth histogram fails chi-square')
  end subroutine test_azimuth
end module test_math_tally_suite

program test_math_tally
  use kumo_testing, only: run_unittests
  use test_math_tally_suite, only: collect_math_tally
  implicit none
  integer :: n_failed
  call run_unittests('math and tally', collect_math_tally(), n_failed)
  if (n_failed > 0) error stop 1
end program test_math_tally
