! SPDX-License-Identifier: BSD-3-Clause
!> Camera geometry: pixel lookup and image axes, exact pixel solid angles, roll and azimuth
!> conventions, orthographic tiling, periodic image shift ranges, the radiance normalisation
!> of the local-estimate factor (Monte Carlo, Lambert surface) and input validation.
module test_camera_suite
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use kumo_kinds, only: wp, i8
  use kumo_constants, only: PI, DEG2RAD
  use kumo_rng, only: rng_t, rng_init, rng_uniform
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_sigma
  use kumo_camera, only: camera_t, camera_init, camera_project, camera_pixel_direction, &
                         CAMERA_PINHOLE, CAMERA_ORTHOGRAPHIC, MAX_IMAGE_SHIFTS
  implicit none
  private
  public :: collect_camera

contains

  function collect_camera() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('nadir_pinhole_centre_and_axes', test_nadir_pinhole), &
             new_unittest('pixel_solid_angles_exact', test_solid_angles), &
             new_unittest('pixel_directions_project_back', test_pixel_roundtrip), &
             new_unittest('roll_and_azimuth_conventions', test_roll_azimuth), &
             new_unittest('orthographic_nadir_tiles_domain', test_ortho_tiling), &
             new_unittest('shift_range_of_nadir_pinhole', test_nadir_range), &
             new_unittest('shift_ranges_cover_every_hit', test_range_coverage), &
             new_unittest('horizon_view_is_capped', test_horizon_capped), &
             new_unittest('lambert_surface_radiance_mc', test_lambert_mc), &
             new_unittest('invalid_inputs_rejected', test_invalid)]
  end function collect_camera

  !> camera_init with defaults for everything not given; a failure is reported in `error`.
  subroutine make_camera(cam, error, kind, pos, zen, azi, roll, fov, width, npx, npy, lx, ly, &
                         ztop)
    type(camera_t), intent(out) :: cam
    type(error_t), allocatable, intent(out) :: error
    integer, intent(in), optional :: kind, npx, npy
    real(wp), intent(in), optional :: pos(3), zen, azi, roll, fov, width, lx, ly, ztop
    integer :: k, nx, ny
    real(wp) :: p(3), t, a, r, f, w, dx, dy, h
    k = CAMERA_PINHOLE
    p = [500.0_wp, 500.0_wp, 3000.0_wp]
    t = 180.0_wp
    a = 0.0_wp
    r = 0.0_wp
    f = 40.0_wp
    w = 1000.0_wp
    nx = 5
    ny = 5
    dx = 1000.0_wp
    dy = 1000.0_wp
    h = 2000.0_wp
    if (present(kind)) k = kind
    if (present(pos)) p = pos
    if (present(zen)) t = zen
    if (present(azi)) a = azi
    if (present(roll)) r = roll
    if (present(fov)) f = fov
    if (present(width)) w = width
    if (present(npx)) nx = npx
    if (present(npy)) ny = npy
    if (present(lx)) dx = lx
    if (present(ly)) dy = ly
    if (present(ztop)) h = ztop
    call camera_init(cam, k, p, t, a, r, f, w, nx, ny, dx, dy, h, error)
  end subroutine make_camera

  !> Pixel indices (i, j) of a flat index.
  pure subroutine pixel_ij(cam, ipix, i, j)
    type(camera_t), intent(in) :: cam
    integer, intent(in) :: ipix
    integer, intent(out) :: i, j
    i = mod(ipix - 1, cam%npx) + 1
    j = (ipix - 1)/cam%npx + 1
  end subroutine pixel_ij

  subroutine test_nadir_pinhole(error)
    type(error_t), allocatable, intent(out) :: error
    type(camera_t) :: cam
    integer :: ipix, i, j
    real(wp) :: dist, ux, uy, uz, factor
    logical :: hit
    call make_camera(cam, error, pos=[420.0_wp, 610.0_wp, 3000.0_wp])
    if (allocated(error)) return
    ! straight below the camera: central pixel (3, 3) of 5 x 5, light going straight up
    call camera_project(cam, 420.0_wp, 610.0_wp, 1200.0_wp, ipix, dist, ux, uy, uz, factor, hit)
    call check(error, hit, 'point below a nadir camera is seen')
    call check(error, ipix == 3 + 2*5, 'point below the camera is in the central pixel')
    call check_close(error, dist, 1800.0_wp, label='dist = height difference')
    call check_close(error, uz, 1.0_wp, label='uz')
    call check_close(error, ux, 0.0_wp, abs_tol=1.0e-15_wp, label='ux')
    call check_close(error, uy, 0.0_wp, abs_tol=1.0e-15_wp, label='uy')
    call check_close(error, factor, cam%inv_solid_angle(13)/1800.0_wp**2, label='factor')
    if (allocated(error)) return
    ! +x is the image x axis (i increasing), +y the image y axis (j increasing)
    call camera_project(cam, 700.0_wp, 610.0_wp, 1200.0_wp, ipix, dist, ux, uy, uz, factor, hit)
    call pixel_ij(cam, ipix, i, j)
    call check(error, hit .and. i > 3 .and. j == 3, 'a point toward +x has a larger i')
    call check(error, ux < 0.0_wp .and. uz > 0.0_wp, 'light from +x travels back toward -x')
    call camera_project(cam, 420.0_wp, 900.0_wp, 1200.0_wp, ipix, dist, ux, uy, uz, factor, hit)
    call pixel_ij(cam, ipix, i, j)
    call check(error, hit .and. i == 3 .and. j > 3, 'a point toward +y has a larger j')
    call camera_project(cam, 100.0_wp, 610.0_wp, 1200.0_wp, ipix, dist, ux, uy, uz, factor, hit)
    call pixel_ij(cam, ipix, i, j)
    call check(error, hit .and. i < 3 .and. j == 3, 'a point toward -x has a smaller i')
    ! outside the 40 degree field of view, and above the camera
    call camera_project(cam, 420.0_wp + 1800.0_wp*tan(21.0_wp*DEG2RAD), 610.0_wp, 1200.0_wp, &
                        ipix, dist, ux, uy, uz, factor, hit)
    call check(error, .not. hit .and. ipix == 0, 'a point outside the field of view is missed')
    call camera_project(cam, 420.0_wp, 610.0_wp, 3500.0_wp, ipix, dist, ux, uy, uz, factor, hit)
    call check(error, .not. hit, 'a point behind the camera is missed')
  end subroutine test_nadir_pinhole

  subroutine test_solid_angles(error)
    type(error_t), allocatable, intent(out) :: error
    type(camera_t) :: cam
    integer, parameter :: nq = 400
    real(wp) :: total, tx, ty, quad, a, b, h
    integer :: i, j
    ! 90 degree square field of view: one face of a cube seen from its centre, 4 pi / 6
    call make_camera(cam, error, fov=90.0_wp, npx=8, npy=8)
    if (allocated(error)) return
    call check_close(error, sum(1.0_wp/cam%inv_solid_angle), 4.0_wp*PI/6.0_wp, rel_tol=1.0e-12_wp, &
                     label='solid angle of a cube face')
    ! rectangular field: total = 4 atan(tx ty / sqrt(1 + tx^2 + ty^2))
    call make_camera(cam, error, fov=65.0_wp, npx=7, npy=4, zen=120.0_wp, roll=30.0_wp)
    if (allocated(error)) return
    tx = tan(32.5_wp*DEG2RAD)
    ty = tx*4.0_wp/7.0_wp
    total = 4.0_wp*atan(tx*ty/sqrt(1.0_wp + tx*tx + ty*ty))
    call check_close(error, sum(1.0_wp/cam%inv_solid_angle), total, rel_tol=1.0e-12_wp, &
                     label='sum of the pixel solid angles')
    ! corner pixel (1, 1) against the midpoint rule for int int (1 + a^2 + b^2)^(-3/2) da db
    h = 2.0_wp*tx/7.0_wp/nq
    quad = 0.0_wp
    do j = 1, nq
      b = -ty + (j - 0.5_wp)*h
      do i = 1, nq
        a = -tx + (i - 0.5_wp)*h
        quad = quad + h*h/(1.0_wp + a*a + b*b)**1.5_wp
      end do
    end do
    call check_close(error, 1.0_wp/cam%inv_solid_angle(1), quad, rel_tol=1.0e-5_wp, &
                     label='corner pixel solid angle vs quadrature')
    call check(error, cam%inv_solid_angle(1) > cam%inv_solid_angle(4 + 7), &
               'a corner pixel subtends less than a central one')
  end subroutine test_solid_angles

  subroutine test_pixel_roundtrip(error)
    type(error_t), allocatable, intent(out) :: error
    type(camera_t) :: cam
    integer :: i, j, ipix, icam
    real(wp) :: vx, vy, vz, dist, ux, uy, uz, factor, s
    logical :: hit
    do icam = 1, 2
      if (icam == 1) then
        call make_camera(cam, error, fov=50.0_wp, npx=7, npy=5, zen=120.0_wp, azi=200.0_wp, &
                         roll=17.0_wp, pos=[100.0_wp, -40.0_wp, 500.0_wp])
      else
        call make_camera(cam, error, fov=170.0_wp, npx=6, npy=9, zen=180.0_wp, roll=-75.0_wp)
      end if
      if (allocated(error)) return
      s = 137.0_wp
      do j = 1, cam%npy
        do i = 1, cam%npx
          call camera_pixel_direction(cam, i, j, vx, vy, vz)
          call check_close(error, vx*vx + vy*vy + vz*vz, 1.0_wp, label='unit pixel direction')
          call camera_project(cam, cam%pos(1) + s*vx, cam%pos(2) + s*vy, cam%pos(3) + s*vz, &
                              ipix, dist, ux, uy, uz, factor, hit)
          call check(error, hit .and. ipix == i + (j - 1)*cam%npx, &
                     'point along the pixel direction lands in that pixel')
          if (allocated(error)) return
          call check_close(error, dist, s, rel_tol=1.0e-12_wp, label='dist along pixel direction')
          call check(error, abs(ux + vx) + abs(uy + vy) + abs(uz + vz) < 1.0e-12_wp, &
                     'light direction is opposite to the viewing direction')
          call check_close(error, factor, cam%inv_solid_angle(ipix)/s**2, rel_tol=1.0e-12_wp, &
                           label='factor = 1/(dist^2 solid angle)')
          if (allocated(error)) return
        end do
      end do
    end do
  end subroutine test_pixel_roundtrip

  subroutine test_roll_azimuth(error)
    type(error_t), allocatable, intent(out) :: error
    type(camera_t) :: cam
    real(wp), parameter :: c(3) = [0.0_wp, 0.0_wp, 500.0_wp]
    ! horizontal camera looking along +x: up = +z, right = -y
    call make_camera(cam, error, zen=90.0_wp, azi=0.0_wp, npx=9, npy=9, pos=c)
    if (allocated(error)) return
    call check(error, norm2(cam%up - [0.0_wp, 0.0_wp, 1.0_wp]) < 1.0e-12_wp, 'image up is +z')
    call check(error, norm2(cam%right - [0.0_wp, -1.0_wp, 0.0_wp]) < 1.0e-12_wp, &
               'image right is -y looking along +x')
    call expect_pixel(error, cam, [100.0_wp, 0.0_wp, 500.0_wp], 0, 0, 'on the axis')
    call expect_pixel(error, cam, [100.0_wp, 0.0_wp, 530.0_wp], 0, 1, 'above the axis, roll 0')
    call expect_pixel(error, cam, [100.0_wp, -30.0_wp, 500.0_wp], 1, 0, '-y side, roll 0')
    ! roll 90 (counter-clockwise as seen by the camera): image x turns onto the old up
    call make_camera(cam, error, zen=90.0_wp, azi=0.0_wp, roll=90.0_wp, npx=9, npy=9, pos=c)
    if (allocated(error)) return
    call expect_pixel(error, cam, [100.0_wp, 0.0_wp, 530.0_wp], 1, 0, 'above the axis, roll 90')
    call expect_pixel(error, cam, [100.0_wp, -30.0_wp, 500.0_wp], 0, -1, '-y side, roll 90')
    ! azimuth 90: looking along +y, right = +x
    call make_camera(cam, error, zen=90.0_wp, azi=90.0_wp, npx=9, npy=9, pos=c)
    if (allocated(error)) return
    call expect_pixel(error, cam, [0.0_wp, 100.0_wp, 500.0_wp], 0, 0, 'looking along +y')
    call expect_pixel(error, cam, [30.0_wp, 100.0_wp, 500.0_wp], 1, 0, '+x side, azimuth 90')
    ! oblique view down toward azimuth 45: the far side (along the azimuth) is image up
    call make_camera(cam, error, zen=135.0_wp, azi=45.0_wp, npx=9, npy=9, pos=c)
    if (allocated(error)) return
    call expect_pixel(error, cam, [500.0_wp*sqrt(0.5_wp), 500.0_wp*sqrt(0.5_wp), 0.0_wp], 0, 0, &
                      'oblique centre')
    call expect_pixel(error, cam, [400.0_wp, 400.0_wp, 0.0_wp], 0, 1, 'oblique far side')
    ! nadir: azimuth is ignored; roll 90 puts image x along +y
    call make_camera(cam, error, zen=180.0_wp, azi=70.0_wp, npx=9, npy=9, pos=c)
    if (allocated(error)) return
    call expect_pixel(error, cam, [30.0_wp, 0.0_wp, 100.0_wp], 1, 0, 'nadir, azimuth ignored')
    call make_camera(cam, error, zen=180.0_wp, roll=90.0_wp, npx=9, npy=9, pos=c)
    if (allocated(error)) return
    call expect_pixel(error, cam, [0.0_wp, 30.0_wp, 100.0_wp], 1, 0, 'nadir, roll 90')
    call expect_pixel(error, cam, [30.0_wp, 0.0_wp, 100.0_wp], 0, -1, 'nadir, roll 90, +x')
    ! zenith camera (looking up): up = +y, right = -x
    call make_camera(cam, error, zen=0.0_wp, npx=9, npy=9, pos=c)
    if (allocated(error)) return
    call expect_pixel(error, cam, [0.0_wp, 30.0_wp, 900.0_wp], 0, 1, 'zenith camera, +y')
    call expect_pixel(error, cam, [-30.0_wp, 0.0_wp, 900.0_wp], 1, 0, 'zenith camera, -x')
  end subroutine test_roll_azimuth

  !> The point is seen in the pixel offset from the central one (of an odd-sized image) by
  !> the signs (si, sj) of (i - centre, j - centre).
  subroutine expect_pixel(error, cam, r, si, sj, what)
    type(error_t), allocatable, intent(inout) :: error
    type(camera_t), intent(in) :: cam
    real(wp), intent(in) :: r(3)
    integer, intent(in) :: si, sj
    character(len=*), intent(in) :: what
    integer :: ipix, i, j
    real(wp) :: dist, ux, uy, uz, factor
    logical :: hit
    call camera_project(cam, r(1), r(2), r(3), ipix, dist, ux, uy, uz, factor, hit)
    call check(error, hit, what//': point not seen')
    if (allocated(error)) return
    call pixel_ij(cam, ipix, i, j)
    call check(error, sign_of(i - (cam%npx + 1)/2) == si .and. sign_of(j - (cam%npy + 1)/2) == sj, &
               what//': point in the wrong pixel')
  end subroutine expect_pixel

  pure integer function sign_of(k)
    integer, intent(in) :: k
    sign_of = merge(1, merge(-1, 0, k < 0), k > 0)
  end function sign_of

  subroutine test_ortho_tiling(error)
    type(error_t), allocatable, intent(out) :: error
    type(camera_t) :: cam
    real(wp), parameter :: l = 1200.0_wp, zt = 800.0_wp
    integer, parameter :: n = 21
    real(wp) :: x, y, z, dist, ux, uy, uz, factor
    integer :: ix, iy, iz, mx, my, ipix, nhit, mx_hit, my_hit, ipix_hit
    logical :: hit
    call make_camera(cam, error, kind=CAMERA_ORTHOGRAPHIC, &
                     pos=[0.5_wp*l, 0.5_wp*l, zt + 100.0_wp], width=l, npx=8, npy=8, lx=l, &
                     ly=l, ztop=zt)
    if (allocated(error)) return
    call check_close(error, cam%pixel_area, (l/8)**2, label='pixel area')
    call check(error, cam%mx_lo <= 0 .and. cam%mx_hi >= 0 .and. cam%mx_hi - cam%mx_lo <= 1, &
               'x shift range covers 0, at most one neighbour')
    call check(error, cam%my_lo <= 0 .and. cam%my_hi >= 0 .and. cam%my_hi - cam%my_lo <= 1, &
               'y shift range covers 0, at most one neighbour')
    call check(error, .not. cam%capped, 'nadir orthographic range is not capped')
    if (allocated(error)) return
    do iz = 0, 2
      z = iz*0.5_wp*zt
      do iy = 0, n - 1
        y = iy*l/n
        do ix = 0, n - 1
          x = ix*l/n
          nhit = 0
          mx_hit = -99
          my_hit = -99
          ipix_hit = 0
          do my = cam%my_lo - 1, cam%my_hi + 1
            do mx = cam%mx_lo - 1, cam%mx_hi + 1
              call camera_project(cam, x + mx*l, y + my*l, z, ipix, dist, ux, uy, uz, factor, hit)
              if (hit) then
                nhit = nhit + 1
                mx_hit = mx
                my_hit = my
                ipix_hit = ipix
                call check_close(error, dist, zt + 100.0_wp - z, rel_tol=1.0e-12_wp, &
                                 label='distance to the image plane')
                call check_close(error, factor, (8/l)**2, label='factor = 1/pixel area')
                call check(error, abs(ux) + abs(uy) + abs(uz - 1.0_wp) < 1.0e-15_wp, &
                           'light goes straight up')
              end if
            end do
          end do
          call check(error, nhit == 1 .and. mx_hit == 0 .and. my_hit == 0, &
                     'each point is seen exactly once, through shift (0, 0)')
          call check(error, ipix_hit == int(8*x/l) + 1 + int(8*y/l)*8, 'pixel of the point')
          if (allocated(error)) return
        end do
      end do
    end do
    ! a point above the image plane is behind the camera
    call camera_project(cam, 0.5_wp*l, 0.5_wp*l, zt + 150.0_wp, ipix, dist, ux, uy, uz, factor, &
                        hit)
    call check(error, .not. hit, 'point behind the orthographic image plane is missed')
  end subroutine test_ortho_tiling

  subroutine test_nadir_range(error)
    type(error_t), allocatable, intent(out) :: error
    type(camera_t) :: cam
    ! footprint on z = 0: 300 +- 2000 tan 30 = [-854.7, 1454.7] -> shifts -1..1 of lx = 1000;
    ! 700 +- 1154.7 = [-454.7, 1854.7] -> shifts -1..3 of ly = 600
    call make_camera(cam, error, pos=[300.0_wp, 700.0_wp, 2000.0_wp], fov=60.0_wp, npx=4, &
                     npy=4, lx=1000.0_wp, ly=600.0_wp, ztop=1000.0_wp)
    if (allocated(error)) return
    call check(error, cam%mx_lo == -1 .and. cam%mx_hi == 1, 'x shifts of the nadir footprint')
    call check(error, cam%my_lo == -1 .and. cam%my_hi == 3, 'y shifts of the nadir footprint')
    call check(error, .not. cam%capped, 'bounded footprint is not capped')
    ! above the atmosphere looking up: nothing to see, empty ranges
    call make_camera(cam, error, pos=[300.0_wp, 700.0_wp, 2000.0_wp], zen=10.0_wp, &
                     lx=1000.0_wp, ly=600.0_wp, ztop=1000.0_wp)
    if (allocated(error)) return
    call check(error, cam%mx_hi < cam%mx_lo .and. cam%my_hi < cam%my_lo, &
               'camera above the atmosphere looking up sees no image')
  end subroutine test_nadir_range

  subroutine test_range_coverage(error)
    type(error_t), allocatable, intent(out) :: error
    type(camera_t) :: cam
    real(wp), parameter :: lx = 1000.0_wp, ly = 700.0_wp, zt = 1500.0_wp
    integer, parameter :: ncam = 5, n = 9, margin = 3
    real(wp) :: x, y, z, dist, ux, uy, uz, factor
    integer :: icam, ix, iy, iz, mx, my, ipix, nhit
    logical :: hit
    do icam = 1, ncam
      select case (icam)
      case (1)  ! oblique pinhole above the atmosphere
        call make_camera(cam, error, pos=[-200.0_wp, 300.0_wp, 4000.0_wp], zen=150.0_wp, &
                         azi=35.0_wp, roll=10.0_wp, fov=50.0_wp, npx=6, npy=4, lx=lx, ly=ly, &
                         ztop=zt)
      case (2)  ! pinhole inside the atmosphere looking obliquely down
        call make_camera(cam, error, pos=[400.0_wp, 100.0_wp, 900.0_wp], zen=135.0_wp, &
                         azi=-120.0_wp, fov=40.0_wp, npx=5, npy=5, lx=lx, ly=ly, ztop=zt)
      case (3)  ! oblique orthographic camera above the atmosphere
        call make_camera(cam, error, kind=CAMERA_ORTHOGRAPHIC, pos=[100.0_wp, 0.0_wp, 2500.0_wp], &
                         zen=140.0_wp, azi=250.0_wp, roll=-30.0_wp, width=1700.0_wp, npx=4, &
                         npy=6, lx=lx, ly=ly, ztop=zt)
      case (4)  ! orthographic image plane inside the atmosphere, looking down
        call make_camera(cam, error, kind=CAMERA_ORTHOGRAPHIC, pos=[100.0_wp, 0.0_wp, 700.0_wp], &
                         zen=160.0_wp, azi=10.0_wp, width=900.0_wp, npx=3, npy=3, lx=lx, &
                         ly=ly, ztop=zt)
      case (5)  ! pinhole at the surface looking up
        call make_camera(cam, error, pos=[10.0_wp, 20.0_wp, 0.0_wp], zen=20.0_wp, &
                         fov=90.0_wp, npx=4, npy=3, lx=lx, ly=ly, ztop=zt)
      case default
        call check(error, .false., 'no camera defined for this case')
        return
      end select
      if (allocated(error)) return
      call check(error, .not. cam%capped, 'bounded view is not capped')
      call check(error, cam%mx_lo <= cam%mx_hi .and. cam%my_lo <= cam%my_hi, 'range not empty')
      nhit = 0
      do iz = 0, n - 1
        z = iz*zt/(n - 1)
        do iy = 0, n - 1
          y = (iy + 0.37_wp)*ly/n
          do ix = 0, n - 1
            x = (ix + 0.61_wp)*lx/n
            do my = cam%my_lo - margin, cam%my_hi + margin
              do mx = cam%mx_lo - margin, cam%mx_hi + margin
                call camera_project(cam, x + mx*lx, y + my*ly, z, ipix, dist, ux, uy, uz, &
                                    factor, hit)
                if (.not. hit) cycle
                nhit = nhit + 1
                call check(error, mx >= cam%mx_lo .and. mx <= cam%mx_hi .and. &
                           my >= cam%my_lo .and. my <= cam%my_hi, &
                           'a point is seen through a shift outside the range (camera '// &
                           achar(iachar('0') + icam)//')')
                if (allocated(error)) return
              end do
            end do
          end do
        end do
      end do
      call check(error, nhit > 50, 'the camera sees the atmosphere')
      ! few spare shifts: these views span at most a few domain lengths (a loose bound; the
      ! exact range of a nadir footprint is checked in shift_range_of_nadir_pinhole)
      call check(error, cam%mx_hi - cam%mx_lo <= 12 .and. cam%my_hi - cam%my_lo <= 12, &
                 'shift range is not much wider than the view')
    end do
  end subroutine test_range_coverage

  subroutine test_horizon_capped(error)
    type(error_t), allocatable, intent(out) :: error
    type(camera_t) :: cam
    ! pinhole inside the atmosphere looking horizontally along +x: the view never leaves the
    ! slab toward +x, so the x range is cut to MAX_IMAGE_SHIFTS past the camera's own shift
    call make_camera(cam, error, pos=[2500.0_wp, 300.0_wp, 500.0_wp], zen=90.0_wp, &
                     fov=30.0_wp, npx=8, npy=4, lx=1000.0_wp, ly=1000.0_wp, ztop=1000.0_wp)
    if (allocated(error)) return
    call check(error, cam%capped, 'horizon view is capped')
    call check(error, cam%mx_lo == 2 .and. cam%mx_hi == 2 + MAX_IMAGE_SHIFTS, &
               'x range runs from the camera shift to MAX_IMAGE_SHIFTS beyond it')
    call check(error, cam%my_lo <= 0 .and. cam%my_hi >= 0, 'y range covers the camera shift')
    call check(error, cam%my_hi - cam%my_lo == 2*MAX_IMAGE_SHIFTS, 'y range capped both ways')
    ! nadir views are bounded
    call make_camera(cam, error, lx=1000.0_wp, ly=1000.0_wp, ztop=1000.0_wp)
    if (allocated(error)) return
    call check(error, .not. cam%capped, 'nadir view is not capped')
  end subroutine test_horizon_capped

  !> Lambert surface at z = 0 with albedo a under a horizontal irradiance of 1: its radiance is
  !> a/pi in every direction. N points are drawn uniformly on the base domain [0,lx) x [0,ly);
  !> each carries the reflected power w = a lx ly / N, leaves toward the camera with the
  !> density p = cos(theta)/pi per steradian (theta from the vertical, cos(theta) = uz) and
  !> T = 1. Summing over the camera's image shifts is the same as drawing N/(lx ly) points per
  !> unit area over the whole plane, so for a pinhole the expected pixel sum is
  !>   E = (a/pi) (1/Omega_pix) int_{footprint} cos(theta)/dist^2 dA = a/pi,
  !> because cos(theta) dA/dist^2 is the solid angle at the camera of the surface element and
  !> every ray of a downward-looking pixel meets the surface. For an orthographic camera with
  !> look direction at angle theta from the nadir the pixel footprint has area
  !> pixel_area/cos(theta), and E = (a/pi) cos(theta) (pixel_area/cos(theta)) / pixel_area =
  !> a/pi as well. Each pixel sum is compared with a/pi within 4 of its own standard errors
  !> (estimated from the per-point contributions), N = 200000, seed 12345.
  subroutine test_lambert_mc(error)
    type(error_t), allocatable, intent(out) :: error
    type(camera_t) :: cam
    type(rng_t) :: rng
    real(wp), parameter :: lx = 1000.0_wp, ly = 600.0_wp, albedo = 0.3_wp
    integer, parameter :: n = 200000, ncam = 3
    real(wp), allocatable :: s1(:), s2(:), xs(:)
    real(wp) :: x, y, w, dist, ux, uy, uz, factor, sigma
    integer :: icam, k, mx, my, ipix
    logical :: hit
    character(len=64) :: label
    do icam = 1, ncam
      select case (icam)
      case (1)  ! nadir pinhole, footprint over several images
        call make_camera(cam, error, pos=[300.0_wp, 700.0_wp, 2000.0_wp], fov=60.0_wp, &
                         npx=4, npy=3, lx=lx, ly=ly, ztop=1000.0_wp)
      case (2)  ! oblique rolled pinhole
        call make_camera(cam, error, pos=[-50.0_wp, 80.0_wp, 1500.0_wp], zen=160.0_wp, &
                         azi=30.0_wp, roll=20.0_wp, fov=40.0_wp, npx=3, npy=3, lx=lx, ly=ly, &
                         ztop=1000.0_wp)
      case (3)  ! oblique orthographic camera
        call make_camera(cam, error, kind=CAMERA_ORTHOGRAPHIC, pos=[200.0_wp, 0.0_wp, 1200.0_wp], &
                         zen=150.0_wp, azi=40.0_wp, width=1500.0_wp, npx=3, npy=2, lx=lx, &
                         ly=ly, ztop=1000.0_wp)
      case default
        call check(error, .false., 'no camera defined for this case')
        return
      end select
      if (allocated(error)) return
      allocate (s1(cam%npx*cam%npy), s2(cam%npx*cam%npy), xs(cam%npx*cam%npy))
      s1 = 0.0_wp
      s2 = 0.0_wp
      w = albedo*lx*ly/n
      call rng_init(rng, 12345_i8, int(icam, i8))
      do k = 1, n
        x = lx*rng_uniform(rng)
        y = ly*rng_uniform(rng)
        xs = 0.0_wp
        do my = cam%my_lo, cam%my_hi
          do mx = cam%mx_lo, cam%mx_hi
            call camera_project(cam, x + mx*lx, y + my*ly, 0.0_wp, ipix, dist, ux, uy, uz, &
                                factor, hit)
            if (hit) xs(ipix) = xs(ipix) + w*(uz/PI)*factor
          end do
        end do
        s1 = s1 + xs
        s2 = s2 + xs*xs
      end do
      do ipix = 1, cam%npx*cam%npy
        sigma = sqrt(max(0.0_wp, s2(ipix) - s1(ipix)**2/n))
        write (label, '(a,i0,a,i0)') 'radiance of camera ', icam, ', pixel ', ipix
        call check(error, sigma < 0.01_wp*albedo/PI, trim(label)//': too few samples')
        call check_sigma(error, s1(ipix), albedo/PI, sigma, k=4.0_wp, label=trim(label))
      end do
      deallocate (s1, s2, xs)
      if (allocated(error)) return
    end do
  end subroutine test_lambert_mc

  subroutine test_invalid(error)
    type(error_t), allocatable, intent(out) :: error
    type(camera_t) :: cam
    type(error_t), allocatable :: err
    real(wp) :: nan
    nan = ieee_value(nan, ieee_quiet_nan)
    call make_camera(cam, err)
    call check(error, .not. allocated(err), 'default pinhole is valid')
    call make_camera(cam, err, kind=CAMERA_ORTHOGRAPHIC, pos=[0.0_wp, 0.0_wp, -50.0_wp], &
                     zen=0.0_wp, fov=0.0_wp)
    call check(error, .not. allocated(err), &
               'orthographic camera below the surface looking up is valid (fov unused)')
    call make_camera(cam, err, width=-1.0_wp)
    call check(error, .not. allocated(err), 'width is not used by a pinhole')
    if (allocated(error)) return

    call make_camera(cam, err, kind=3)
    call expect(error, err, 'kind = 3')
    call make_camera(cam, err, npx=0)
    call expect(error, err, 'npx = 0')
    call make_camera(cam, err, npy=-2)
    call expect(error, err, 'npy = -2')
    call make_camera(cam, err, fov=0.0_wp)
    call expect(error, err, 'fov_deg = 0')
    call make_camera(cam, err, fov=180.0_wp)
    call expect(error, err, 'fov_deg = 180')
    call make_camera(cam, err, fov=nan)
    call expect(error, err, 'fov_deg = NaN')
    call make_camera(cam, err, kind=CAMERA_ORTHOGRAPHIC, width=0.0_wp)
    call expect(error, err, 'width = 0')
    call make_camera(cam, err, kind=CAMERA_ORTHOGRAPHIC, width=nan)
    call expect(error, err, 'width = NaN')
    call make_camera(cam, err, lx=0.0_wp)
    call expect(error, err, 'lx = 0')
    call make_camera(cam, err, ly=-10.0_wp)
    call expect(error, err, 'ly = -10')
    call make_camera(cam, err, ztop=nan)
    call expect(error, err, 'ztop = NaN')
    call make_camera(cam, err, pos=[0.0_wp, nan, 10.0_wp])
    call expect(error, err, 'pos(2) = NaN')
    call make_camera(cam, err, pos=[0.0_wp, 0.0_wp, -1.0_wp])
    call expect(error, err, 'pos(3) = -1')
    call make_camera(cam, err, pos=[1.0e10_wp, 0.0_wp, 10.0_wp])
    call expect(error, err, 'pos(1) =')
    call make_camera(cam, err, zen=nan)
    call expect(error, err, 'look_zenith_deg = NaN')
    call make_camera(cam, err, zen=190.0_wp)
    call expect(error, err, 'look_zenith_deg = 190')
    call make_camera(cam, err, azi=nan)
    call expect(error, err, 'look_azimuth_deg = NaN')
    call make_camera(cam, err, roll=nan)
    call expect(error, err, 'roll_deg = NaN')
  end subroutine test_invalid

  !> `err` (from camera_init) must be a message starting with 'camera_init: '//fragment;
  !> otherwise a failure is recorded in `error` (the first one is kept).
  subroutine expect(error, err, fragment)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: fragment
    if (.not. allocated(err)) then
      call check(error, .false., 'not rejected: '//fragment)
      return
    end if
    call check(error, index(err%message, 'camera_init: '//fragment) == 1, &
               'wrong message "'//err%message//'", expected "'//fragment//'"')
  end subroutine expect
end module test_camera_suite

program test_camera
  use kumo_testing, only: run_unittests
  use test_camera_suite, only: collect_camera
  implicit none
  integer :: n_failed
  call run_unittests('camera', collect_camera(), n_failed)
  if (n_failed > 0) error stop 1
end program test_camera
