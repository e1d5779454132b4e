! SPDX-License-Identifier: BSD-3-Clause
!> Cameras for the local estimate: pinhole (perspective) and orthographic projection of a
!> scattering event onto a pixel, and the periodic image shifts the tracer loops over.
!>
!> Geometry and conventions (all lengths in metres, angles in degrees at the interface):
!>
!> * Look direction L = (sin t cos p, sin t sin p, cos t) with t = `look_zenith_deg` (angle
!>   from the upward vertical: 180 looks straight down, 0 straight up) and p =
!>   `look_azimuth_deg` (from +x toward +y).
!> * Image axes before roll: "up" U0 is the projection of +z on the plane normal to L; "right"
!>   is R0 = L x U0 (what a viewer looking along L with head toward U0 has on the right hand).
!>   When L is vertical (sin t < 1e-10) the azimuth is ignored and U0 = +y; then R0 = +x when
!>   looking down and R0 = -x when looking up. (R, U, -L) is always right-handed.
!>   Note: a camera tilted slightly off nadir at azimuth p has U0 close to (cos p, sin p, 0),
!>   so the image turns when L passes the vertical; set roll for the orientation you want.
!> * Roll r turns the image axes about L, positive counter-clockwise as seen by the camera:
!>   R = cos r R0 + sin r U0, U = -sin r R0 + cos r U0 (the scene appears turned clockwise).
!> * Pixel (i, j), i = 1..npx along R, j = 1..npy along U, flat index ipix = i + (j-1)*npx.
!>   Pixels are square. Pixel cells are half-open: [lower edge, upper edge).
!> * Pinhole at C: image plane at unit distance along L, spanning a in [-tx, tx) along R and
!>   b in [-ty, ty) along U with tx = tan(fov_deg/2), ty = tx*npy/npx. A point r is seen when
!>   (r - C).L > 0 and its central projection falls in the image; the light travels along
!>   u = (C - r)/|C - r| for dist = |C - r| and factor = 1/(dist**2 * solid angle of the pixel).
!>   The pixel solid angle is exact: Omega = F(a2,b2) - F(a1,b2) - F(a2,b1) + F(a1,b1) with
!>   F(a,b) = atan(a b / sqrt(1 + a**2 + b**2)).
!> * Orthographic: image rectangle of width `width` along R and height width*npy/npx along U,
!>   centred on C in the plane through C normal to L. A point is seen when (r - C).L > 0 and
!>   its projection along L falls in the rectangle; u = -L, dist = (r - C).L (distance to the
!>   image plane) and factor = 1/pixel_area, pixel_area = (width/npx)**2.
!>
!> The mean radiance of pixel ipix is the sum over events and image shifts of
!> w * p(u) * T(u, dist) * factor, with p the phase function (or BRDF) density per steradian
!> of the light leaving the event toward u and T the transmittance over dist along u.
!>
!> Periodic images: the tracer calls `camera_project` for r0 + (mx lx, my ly, 0) with
!> mx = mx_lo..mx_hi and my = my_lo..my_hi. `camera_init` takes the vertices of the convex
!> region seen by the camera inside the slab 0 <= z <= ztop (and within MAX_CAMERA_OFFSET
!> domain lengths of the camera), and converts their x-y bounding box into shift ranges, so
!> every image of the box [0,lx) x [0,ly) x [0,ztop] that can reach the image is included
!> (points within 1e-9 domain lengths of the edge of the view may be dropped). A range longer
!> than 2*MAX_IMAGE_SHIFTS + 1 (a view reaching the horizon, or a very wide footprint) is cut to
!> the MAX_IMAGE_SHIFTS shifts on either side of the shift nearest to the camera position, and
!> `capped` is set: the image then misses the far-away periodic copies. When the camera sees no
!> part of the slab (e.g. a camera above ztop looking up) the ranges are empty (hi < lo).
module kumo_camera
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_constants, only: DEG2RAD
  use kumo_error, only: error_t, set_error, str
  implicit none
  private
  public :: camera_t, camera_init, camera_project, camera_pixel_direction, camera_half_angle
  public :: CAMERA_PINHOLE, CAMERA_ORTHOGRAPHIC, MAX_IMAGE_SHIFTS, MAX_CAMERA_OFFSET

  integer, parameter :: CAMERA_PINHOLE = 1       !! perspective camera at a point
  integer, parameter :: CAMERA_ORTHOGRAPHIC = 2  !! parallel projection onto a rectangle
  !> Most image shifts on either side of the camera's own shift, per horizontal axis.
  integer, parameter :: MAX_IMAGE_SHIFTS = 50
  !> Largest horizontal distance of the camera from the domain origin, in domain lengths
  !> (|pos(1)| <= MAX_CAMERA_OFFSET*lx, same for y); it also bounds the view searched for the
  !> shift ranges. Keeps the shift indices far from integer overflow.
  real(wp), parameter :: MAX_CAMERA_OFFSET = 1.0e6_wp

  !> |sin(look zenith)| below which the look direction is taken as exactly vertical.
  real(wp), parameter :: VERTICAL_TOL = 1.0e-10_wp
  !> Shift ranges ignore the outermost 1e-9 domain lengths of the view (round-off margin).
  real(wp), parameter :: SHIFT_TOL = 1.0e-9_wp
  !> Most half-spaces bounding the seen region: 5 (orthographic) + 2 (slab) + 4 (search box).
  integer, parameter :: MAX_PLANES = 11

  !> A camera. Set it up with `camera_init`; a default-initialised camera is not usable.
  type :: camera_t
    integer :: kind = CAMERA_PINHOLE  !! CAMERA_PINHOLE or CAMERA_ORTHOGRAPHIC
    integer :: npx = 1, npy = 1       !! pixels along the image x (right) and y (up) axes
    !> periodic image shifts to loop over (in units of lx and ly); empty when hi < lo
    integer :: mx_lo = 0, mx_hi = 0, my_lo = 0, my_hi = 0
    logical :: capped = .false.       !! the shift ranges were cut (view reaches the horizon)
    real(wp) :: pos(3) = 0.0_wp       !! pinhole: the pinhole; orthographic: image centre [m]
    real(wp) :: look(3) = [0.0_wp, 0.0_wp, -1.0_wp]  !! L, unit viewing direction
    real(wp) :: right(3) = [1.0_wp, 0.0_wp, 0.0_wp]  !! R, unit image x axis (i increasing)
    real(wp) :: up(3) = [0.0_wp, 1.0_wp, 0.0_wp]     !! U, unit image y axis (j increasing)
    !> half extent of the image along R and U: pinhole tan of the half field of view
    !> (image plane at unit distance), orthographic half-width and half-height [m]
    real(wp) :: half_x = 1.0_wp, half_y = 1.0_wp
    real(wp) :: pixel_size = 2.0_wp   !! pixel side in the same units as half_x
    real(wp) :: pixel_area = 4.0_wp   !! orthographic: pixel area [m2]
    real(wp) :: inv_pixel_area = 0.25_wp  !! orthographic: 1/pixel_area [m-2]
    real(wp), allocatable :: inv_solid_angle(:)  !! pinhole: 1/solid angle per pixel [sr-1]
  end type camera_t

contains

  !> Set up a camera, validate its inputs and compute its periodic image shift ranges.
  !> `fov_deg` is used by pinhole cameras only, `width` by orthographic ones only.
  subroutine camera_init(cam, kind, pos, look_zenith_deg, look_azimuth_deg, roll_deg, fov_deg, &
                         width, npx, npy, lx, ly, ztop, error)
    type(camera_t), intent(out) :: cam             !! the camera
    integer, intent(in) :: kind                    !! CAMERA_PINHOLE or CAMERA_ORTHOGRAPHIC
    integer, intent(in) :: npx, npy                !! pixels along the image x and y axes
    real(wp), intent(in) :: pos(3)                 !! pinhole / image centre (x, y, z) [m]
    real(wp), intent(in) :: look_zenith_deg        !! zenith angle of L, 0..180 [deg]
    real(wp), intent(in) :: look_azimuth_deg       !! azimuth of L from +x toward +y [deg]
    real(wp), intent(in) :: roll_deg               !! image rotation about L, ccw [deg]
    real(wp), intent(in) :: fov_deg                !! pinhole: full field of view along x [deg]
    real(wp), intent(in) :: width                  !! orthographic: image width [m]
    real(wp), intent(in) :: lx, ly                 !! periodic domain size [m]
    real(wp), intent(in) :: ztop                   !! top of the atmosphere [m]
    type(error_t), allocatable, intent(out) :: error  !! set when an input is invalid
    real(wp) :: zen, azi, rol, sin_zen, up0(3), right0(3)

    call validate(kind, pos, look_zenith_deg, look_azimuth_deg, roll_deg, fov_deg, width, &
                  npx, npy, lx, ly, ztop, error)
    if (allocated(error)) return

    cam%kind = kind
    cam%npx = npx
    cam%npy = npy
    cam%pos = pos

    zen = look_zenith_deg*DEG2RAD
    azi = look_azimuth_deg*DEG2RAD
    rol = roll_deg*DEG2RAD
    sin_zen = sin(zen)
    if (abs(sin_zen) < VERTICAL_TOL) then
      cam%look = [0.0_wp, 0.0_wp, sign(1.0_wp, cos(zen))]
      up0 = [0.0_wp, 1.0_wp, 0.0_wp]
    else
      cam%look = [sin_zen*cos(azi), sin_zen*sin(azi), cos(zen)]
      up0 = [0.0_wp, 0.0_wp, 1.0_wp] - cam%look(3)*cam%look
      up0 = up0/norm2(up0)
    end if
    right0 = cross(cam%look, up0)
    right0 = right0/norm2(right0)
    cam%right = cos(rol)*right0 + sin(rol)*up0
    cam%up = -sin(rol)*right0 + cos(rol)*up0

    if (kind == CAMERA_PINHOLE) then
      cam%half_x = tan(0.5_wp*fov_deg*DEG2RAD)
    else
      cam%half_x = 0.5_wp*width
    end if
    cam%pixel_size = 2.0_wp*cam%half_x/npx
    cam%half_y = cam%half_x*real(npy, wp)/real(npx, wp)
    cam%pixel_area = cam%pixel_size**2
    cam%inv_pixel_area = 1.0_wp/cam%pixel_area
    if (kind == CAMERA_PINHOLE) call pixel_solid_angles(cam)

    call image_shift_range(cam, lx, ly, ztop)
  end subroutine camera_init

  !> Largest angle [rad] between the look direction and the direction through any point of
  !> the image: the half diagonal of a pinhole camera's field of view, 0 for an orthographic
  !> camera (every pixel looks along L).
  pure real(wp) function camera_half_angle(cam) result(a)
    type(camera_t), intent(in) :: cam
    a = 0.0_wp
    if (cam%kind == CAMERA_PINHOLE) a = atan(sqrt(cam%half_x**2 + cam%half_y**2))
  end function camera_half_angle

  !> Input checks of `camera_init`; the message names the argument and its bound.
  subroutine validate(kind, pos, look_zenith_deg, look_azimuth_deg, roll_deg, fov_deg, width, &
                      npx, npy, lx, ly, ztop, error)
    integer, intent(in) :: kind, npx, npy
    real(wp), intent(in) :: pos(3), look_zenith_deg, look_azimuth_deg, roll_deg, fov_deg, width
    real(wp), intent(in) :: lx, ly, ztop
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: ME = 'camera_init: '
    integer :: k

    if (kind /= CAMERA_PINHOLE .and. kind /= CAMERA_ORTHOGRAPHIC) then
      call set_error(error, ME//'kind = '//str(kind)//' must be 1 (pinhole) or 2 (orthographic)')
    else if (npx < 1) then
      call set_error(error, ME//'npx = '//str(npx)//' must be >= 1')
    else if (npy < 1) then
      call set_error(error, ME//'npy = '//str(npy)//' must be >= 1')
    else if (.not. positive(lx)) then
      call set_error(error, ME//'lx = '//str(lx)//' must be > 0 and finite')
    else if (.not. positive(ly)) then
      call set_error(error, ME//'ly = '//str(ly)//' must be > 0 and finite')
    else if (.not. positive(ztop)) then
      call set_error(error, ME//'ztop = '//str(ztop)//' must be > 0 and finite')
    else if (.not. (ieee_is_finite(look_zenith_deg))) then
      call set_error(error, ME//'look_zenith_deg = '//str(look_zenith_deg)//' must be finite')
    else if (look_zenith_deg < 0.0_wp .or. look_zenith_deg > 180.0_wp) then
      call set_error(error, ME//'look_zenith_deg = '//str(look_zenith_deg)// &
                     ' must be within [0, 180]')
    else if (.not. ieee_is_finite(look_azimuth_deg)) then
      call set_error(error, ME//'look_azimuth_deg = '//str(look_azimuth_deg)//' must be finite')
    else if (.not. ieee_is_finite(roll_deg)) then
      call set_error(error, ME//'roll_deg = '//str(roll_deg)//' must be finite')
    end if
    if (allocated(error)) return

    do k = 1, 3
      if (.not. ieee_is_finite(pos(k))) then
        call set_error(error, ME//'pos('//str(k)//') = '//str(pos(k))//' must be finite')
        return
      end if
    end do
    if (abs(pos(1)) > MAX_CAMERA_OFFSET*lx) then
      call set_error(error, ME//'pos(1) = '//str(pos(1))//' must be within '// &
                     str(MAX_CAMERA_OFFSET)//' * lx of the domain')
    else if (abs(pos(2)) > MAX_CAMERA_OFFSET*ly) then
      call set_error(error, ME//'pos(2) = '//str(pos(2))//' must be within '// &
                     str(MAX_CAMERA_OFFSET)//' * ly of the domain')
    else if (kind == CAMERA_PINHOLE .and. pos(3) < 0.0_wp) then
      call set_error(error, ME//'pos(3) = '//str(pos(3))// &
                     ' must be >= 0: a pinhole camera cannot be below the surface')
    else if (kind == CAMERA_PINHOLE .and. .not. positive(fov_deg)) then
      call set_error(error, ME//'fov_deg = '//str(fov_deg)//' must be within (0, 180)')
    else if (kind == CAMERA_PINHOLE .and. .not. positive(180.0_wp - fov_deg)) then
      call set_error(error, ME//'fov_deg = '//str(fov_deg)//' must be within (0, 180)')
    else if (kind == CAMERA_ORTHOGRAPHIC .and. .not. positive(width)) then
      call set_error(error, ME//'width = '//str(width)//' must be > 0 and finite')
    end if
  end subroutine validate

  !> x > 0 and finite (false for NaN, without comparing a NaN).
  elemental logical function positive(x)
    real(wp), intent(in) :: x
    positive = .false.
    if (.not. ieee_is_finite(x)) return
    positive = x > 0.0_wp
  end function positive

  !> Exact solid angle of every pinhole pixel, stored as its inverse.
  subroutine pixel_solid_angles(cam)
    type(camera_t), intent(inout) :: cam
    real(wp) :: a1, a2, b1, b2, omega
    integer :: i, j
    allocate (cam%inv_solid_angle(cam%npx*cam%npy))
    do j = 1, cam%npy
      b1 = -cam%half_y + (j - 1)*cam%pixel_size
      b2 = -cam%half_y + j*cam%pixel_size
      do i = 1, cam%npx
        a1 = -cam%half_x + (i - 1)*cam%pixel_size
        a2 = -cam%half_x + i*cam%pixel_size
        omega = corner_f(a2, b2) - corner_f(a1, b2) - corner_f(a2, b1) + corner_f(a1, b1)
        cam%inv_solid_angle(i + (j - 1)*cam%npx) = 1.0_wp/omega
      end do
    end do
  end subroutine pixel_solid_angles

  !> Solid angle of the rectangle [0,a] x [0,b] on the plane at unit distance (signed).
  elemental real(wp) function corner_f(a, b)
    real(wp), intent(in) :: a, b
    corner_f = atan(a*b/sqrt(1.0_wp + a*a + b*b))
  end function corner_f

  !> Project the point (x, y, z) (an event, possibly shifted by a periodic image) into the
  !> camera. When `hit`, the light leaving the point along (ux, uy, uz) (unit vector toward the
  !> camera / image plane) reaches pixel `ipix` after the distance `dist`, and w*p*T*factor is
  !> its contribution to the pixel's mean radiance. When not `hit`, ipix = 0 and the other
  !> outputs are zero.
  pure subroutine camera_project(cam, x, y, z, ipix, dist, ux, uy, uz, factor, hit)
    type(camera_t), intent(in) :: cam  !! camera set up by camera_init
    real(wp), intent(in) :: x, y, z    !! point [m]
    integer, intent(out) :: ipix       !! pixel i + (j-1)*npx
    real(wp), intent(out) :: dist      !! path length to the pinhole / image plane [m]
    real(wp), intent(out) :: ux, uy, uz  !! propagation direction of the light
    !> pinhole: 1/(dist**2 solid angle) [m-2 sr-1]; orthographic: 1/pixel area [m-2]
    real(wp), intent(out) :: factor
    logical, intent(out) :: hit        !! the point is seen by a pixel
    real(wp) :: dx, dy, dz, f, sa, sb, d2
    integer :: i, j

    ipix = 0
    dist = 0.0_wp
    ux = 0.0_wp
    uy = 0.0_wp
    uz = 0.0_wp
    factor = 0.0_wp
    hit = .false.
    dx = x - cam%pos(1)
    dy = y - cam%pos(2)
    dz = z - cam%pos(3)
    f = dx*cam%look(1) + dy*cam%look(2) + dz*cam%look(3)
    if (.not. f > 0.0_wp) return
    ! offsets from the lower image edges, compared before any division
    sa = dx*cam%right(1) + dy*cam%right(2) + dz*cam%right(3)
    sb = dx*cam%up(1) + dy*cam%up(2) + dz*cam%up(3)
    if (cam%kind == CAMERA_PINHOLE) then
      sa = sa + cam%half_x*f
      sb = sb + cam%half_y*f
      if (sa < 0.0_wp .or. sa >= 2.0_wp*cam%half_x*f) return
      if (sb < 0.0_wp .or. sb >= 2.0_wp*cam%half_y*f) return
      i = min(cam%npx, int(sa/(f*cam%pixel_size)) + 1)
      j = min(cam%npy, int(sb/(f*cam%pixel_size)) + 1)
      ipix = i + (j - 1)*cam%npx
      d2 = dx*dx + dy*dy + dz*dz
      dist = sqrt(d2)
      ux = -dx/dist
      uy = -dy/dist
      uz = -dz/dist
      factor = cam%inv_solid_angle(ipix)/d2
    else
      sa = sa + cam%half_x
      sb = sb + cam%half_y
      if (sa < 0.0_wp .or. sa >= 2.0_wp*cam%half_x) return
      if (sb < 0.0_wp .or. sb >= 2.0_wp*cam%half_y) return
      i = min(cam%npx, int(sa/cam%pixel_size) + 1)
      j = min(cam%npy, int(sb/cam%pixel_size) + 1)
      ipix = i + (j - 1)*cam%npx
      dist = f
      ux = -cam%look(1)
      uy = -cam%look(2)
      uz = -cam%look(3)
      factor = cam%inv_pixel_area
    end if
    hit = .true.
  end subroutine camera_project

  !> Viewing direction through the centre of pixel (i, j), from the camera into the scene (the
  !> opposite of the light direction returned by camera_project). Orthographic: L.
  pure subroutine camera_pixel_direction(cam, i, j, ux, uy, uz)
    type(camera_t), intent(in) :: cam    !! camera set up by camera_init
    integer, intent(in) :: i, j          !! pixel indices, 1..npx and 1..npy
    real(wp), intent(out) :: ux, uy, uz  !! unit viewing direction
    real(wp) :: a, b, v(3)
    if (cam%kind == CAMERA_PINHOLE) then
      a = -cam%half_x + (i - 0.5_wp)*cam%pixel_size
      b = -cam%half_y + (j - 0.5_wp)*cam%pixel_size
      v = a*cam%right + b*cam%up + cam%look
      v = v/norm2(v)
    else
      v = cam%look
    end if
    ux = v(1)
    uy = v(2)
    uz = v(3)
  end subroutine camera_pixel_direction

  !> Periodic image shift ranges. The region the camera sees inside the slab 0 <= z <= ztop and
  !> the search box |x - pos(1)|, |y - pos(2)| <= MAX_CAMERA_OFFSET*max(lx, ly) is a convex
  !> polyhedron {d = r - pos : n_k.d >= c_k}; its x-y bounding box is that of its vertices,
  !> found by intersecting every triple of bounding planes and keeping the feasible points.
  !> In camera-relative coordinates the pinhole apex is exactly the origin.
  subroutine image_shift_range(cam, lx, ly, ztop)
    type(camera_t), intent(inout) :: cam
    real(wp), intent(in) :: lx, ly, ztop
    real(wp) :: nrm(3, MAX_PLANES), c(MAX_PLANES), v(3), det, tol, lref, rbox
    real(wp) :: xmin, xmax, ymin, ymax
    integer :: np, k1, k2, k3
    logical :: found, cap_x, cap_y

    np = 0
    if (cam%kind == CAMERA_PINHOLE) then
      call add_plane(cam%half_x*cam%look - cam%right, 0.0_wp)
      call add_plane(cam%half_x*cam%look + cam%right, 0.0_wp)
      call add_plane(cam%half_y*cam%look - cam%up, 0.0_wp)
      call add_plane(cam%half_y*cam%look + cam%up, 0.0_wp)
    else
      call add_plane(cam%look, 0.0_wp)
      call add_plane(cam%right, -cam%half_x)
      call add_plane(-cam%right, -cam%half_x)
      call add_plane(cam%up, -cam%half_y)
      call add_plane(-cam%up, -cam%half_y)
    end if
    call add_plane([0.0_wp, 0.0_wp, 1.0_wp], -cam%pos(3))
    call add_plane([0.0_wp, 0.0_wp, -1.0_wp], cam%pos(3) - ztop)
    rbox = MAX_CAMERA_OFFSET*max(lx, ly)
    call add_plane([1.0_wp, 0.0_wp, 0.0_wp], -rbox)
    call add_plane([-1.0_wp, 0.0_wp, 0.0_wp], -rbox)
    call add_plane([0.0_wp, 1.0_wp, 0.0_wp], -rbox)
    call add_plane([0.0_wp, -1.0_wp, 0.0_wp], -rbox)

    lref = max(lx, ly, ztop)
    found = .false.
    xmin = huge(1.0_wp)
    xmax = -huge(1.0_wp)
    ymin = huge(1.0_wp)
    ymax = -huge(1.0_wp)
    do k1 = 1, np - 2
      do k2 = k1 + 1, np - 1
        do k3 = k2 + 1, np
          det = dot_product(nrm(:, k1), cross(nrm(:, k2), nrm(:, k3)))
          if (abs(det) < 1.0e-12_wp) cycle
          v = (c(k1)*cross(nrm(:, k2), nrm(:, k3)) + c(k2)*cross(nrm(:, k3), nrm(:, k1)) + &
               c(k3)*cross(nrm(:, k1), nrm(:, k2)))/det
          tol = 1.0e-9_wp*(maxval(abs(v)) + lref)
          if (any(matmul(v, nrm(:, 1:np)) - c(1:np) < -tol)) cycle
          found = .true.
          xmin = min(xmin, v(1))
          xmax = max(xmax, v(1))
          ymin = min(ymin, v(2))
          ymax = max(ymax, v(2))
        end do
      end do
    end do

    if (.not. found) then
      cam%mx_lo = 0
      cam%mx_hi = -1
      cam%my_lo = 0
      cam%my_hi = -1
      cam%capped = .false.
      return
    end if
    call shift_window(cam%pos(1) + xmin, cam%pos(1) + xmax, cam%pos(1), lx, cam%mx_lo, &
                      cam%mx_hi, cap_x)
    call shift_window(cam%pos(2) + ymin, cam%pos(2) + ymax, cam%pos(2), ly, cam%my_lo, &
                      cam%my_hi, cap_y)
    cam%capped = cap_x .or. cap_y

  contains

    subroutine add_plane(n, cval)
      real(wp), intent(in) :: n(3), cval
      np = np + 1
      nrm(:, np) = n/norm2(n)
      c(np) = cval/norm2(n)
    end subroutine add_plane
  end subroutine image_shift_range

  !> Shifts m whose copy [m l, (m+1) l) of the domain meets [lo_pos, hi_pos], cut to at most
  !> MAX_IMAGE_SHIFTS either side of the shift nearest to the camera coordinate `cpos`.
  pure subroutine shift_window(lo_pos, hi_pos, cpos, length, lo, hi, capped)
    real(wp), intent(in) :: lo_pos, hi_pos  !! extent of the view along the axis [m]
    real(wp), intent(in) :: cpos            !! camera coordinate [m]
    real(wp), intent(in) :: length          !! domain length along the axis [m]
    integer, intent(out) :: lo, hi          !! shift range
    logical, intent(out) :: capped          !! the range was cut
    integer :: lo_all, hi_all, centre
    lo_all = floor(lo_pos/length + SHIFT_TOL)
    hi_all = max(lo_all, floor(hi_pos/length - SHIFT_TOL))
    centre = min(max(floor(cpos/length), lo_all), hi_all)
    lo = max(lo_all, centre - MAX_IMAGE_SHIFTS)
    hi = min(hi_all, centre + MAX_IMAGE_SHIFTS)
    capped = lo > lo_all .or. hi < hi_all
  end subroutine shift_window

  !> Cross product a x b.
  pure function cross(a, b) result(c)
    real(wp), intent(in) :: a(3), b(3)
    real(wp) :: c(3)
    c = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
  end function cross
end module kumo_camera
