! SPDX-License-Identifier: BSD-3-Clause
!> The voxel walk: a straight piece of path inside one layer of the 3-D region, cut into the
!> segments it spends in each voxel column (a 2-D digital differential analyser on the periodic
!> nx x ny grid of `atmosphere_t`).
!>
!> Two kinds of path walk the voxel grid, and both take these steps: lines of sight, whose
!> optical depth the local estimates sum to the end (`layer_segment`, kumo_local_estimate), and
!> pieces of a photon's flight, along which the track-length absorption score deposits
!> w k_abs l in every voxel crossed (`absorb_path`, kumo_transport). The caller decides what a
!> segment adds and whether to stop early; the walk only says which voxel comes next and how
!> long the path stays in it.
!>
!>     call walk_begin(wk, atm, x, y, vx, vy, s)
!>     do
!>       call walk_segment(wk, atm, last)   ! voxel (wk%ix, wk%iy), length wk%step
!>       ... use the segment ...
!>       if (last) exit                     ! the end of the piece lies in this voxel
!>       call walk_next(wk, atm)            ! cross into the next voxel
!>     end do
!>
!> A face that is crossed sets the coordinate exactly onto it (and wraps it periodically); the
!> other coordinate is moved and its cell found again from the position. The null-collision
!> flight itself (`fly_3d`) does not use this walk: it steps through the super-voxel blocks of
!> the majorant grid (kumo_supervoxel), in three dimensions (see docs/design.md).
module kumo_voxel_walk
  use kumo_kinds, only: wp
  use kumo_math, only: wrap
  use kumo_atmosphere, only: atmosphere_t, column_xy
  implicit none
  private
  public :: voxel_walk_t, walk_begin, walk_segment, walk_next

  !> State of a walk through the voxel columns of one layer (set by walk_begin; no default
  !> values, so that starting a walk costs nothing beyond what it sets).
  type :: voxel_walk_t
    integer :: ix, iy          !! voxel column of the current segment
    real(wp) :: x, y           !! start of the current segment [m]
    real(wp) :: vx, vy         !! horizontal direction cosines
    real(wp) :: rem            !! path left from the start of the current segment [m]
    real(wp) :: step           !! length of the current segment [m]
    logical :: x_face          !! the current segment ends on an x face (else a y face)
  end type voxel_walk_t

contains

  !> Start a walk of length `s` from (x, y) along the horizontal direction cosines (vx, vy).
  pure subroutine walk_begin(wk, atm, x, y, vx, vy, s)
    type(voxel_walk_t), intent(out) :: wk
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(in) :: x, y, vx, vy, s
    call column_xy(atm, x, y, wk%ix, wk%iy)
    wk%x = x
    wk%y = y
    wk%vx = vx
    wk%vy = vy
    wk%rem = s
  end subroutine walk_begin

  !> The segment inside voxel column (wk%ix, wk%iy): its length wk%step, and `last` when the
  !> walk ends inside this voxel (then wk%step = wk%rem).
  pure subroutine walk_segment(wk, atm, last)
    type(voxel_walk_t), intent(inout) :: wk
    type(atmosphere_t), intent(in) :: atm
    logical, intent(out) :: last
    real(wp) :: tx, ty
    tx = face_distance(wk%ix, wk%x, wk%vx, atm%dx)
    ty = face_distance(wk%iy, wk%y, wk%vy, atm%dy)
    wk%step = min(tx, ty, wk%rem)
    wk%x_face = tx <= ty
    last = wk%step >= wk%rem
  end subroutine walk_segment

  !> Move to the start of the next segment: across the face that ends the current one.
  pure subroutine walk_next(wk, atm)
    type(voxel_walk_t), intent(inout) :: wk
    type(atmosphere_t), intent(in) :: atm
    wk%rem = wk%rem - wk%step
    if (wk%x_face) then
      call cross_face(wk%ix, wk%x, wk%vx, atm%nx, atm%dx, atm%lx)
      call advance(wk%iy, wk%y, wk%vy*wk%step, atm%ny, atm%ly, atm%inv_dy)
    else
      call cross_face(wk%iy, wk%y, wk%vy, atm%ny, atm%dy, atm%ly)
      call advance(wk%ix, wk%x, wk%vx*wk%step, atm%nx, atm%lx, atm%inv_dx)
    end if
  end subroutine walk_next

  !> Distance along the path to the face of cell i (width d) ahead of coordinate x, for the
  !> direction cosine v along that axis; huge for v = 0.
  pure real(wp) function face_distance(i, x, v, d) result(t)
    integer, intent(in) :: i
    real(wp), intent(in) :: x, v, d
    if (v > 0.0_wp) then
      t = max(0.0_wp, (i*d - x)/v)
    else if (v < 0.0_wp) then
      t = max(0.0_wp, ((i - 1)*d - x)/v)
    else
      t = huge(1.0_wp)
    end if
  end function face_distance

  !> Step into the next cell along one axis (direction cosine v /= 0), periodically: the
  !> coordinate is set exactly onto the face that was crossed.
  pure subroutine cross_face(i, x, v, n, d, l)
    integer, intent(inout) :: i
    real(wp), intent(inout) :: x
    real(wp), intent(in) :: v, d, l
    integer, intent(in) :: n
    if (v > 0.0_wp) then
      i = i + 1
      x = (i - 1)*d
      if (i > n) then
        i = 1
        x = 0.0_wp
      end if
    else
      i = i - 1
      x = i*d
      if (i < 1) then
        i = n
        x = l
      end if
    end if
  end subroutine cross_face

  !> Move along the other axis by dx and find its cell again (periodic).
  pure subroutine advance(i, x, dx, n, l, inv_d)
    integer, intent(out) :: i
    real(wp), intent(inout) :: x
    real(wp), intent(in) :: dx, l, inv_d
    integer, intent(in) :: n
    x = x + dx
    call wrap(x, l)
    i = min(n, max(1, int(x*inv_d) + 1))
  end subroutine advance
end module kumo_voxel_walk
