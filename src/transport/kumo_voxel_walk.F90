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
!>       call walk_segment(wk, last)        ! voxel (wk%ix, wk%iy), length wk%step
!>       ... use the segment ...
!>       if (last) exit                     ! the end of the piece lies in this voxel
!>       call walk_next(wk, atm)            ! cross into the next voxel
!>     end do
!>     call walk_extend(wk, s2)             ! the same path on through the next layer
!>
!> The walk is a digital differential analyser in path length: it keeps the distances to the
!> next x and y faces, and after each segment takes the segment from both and sets the one it
!> crossed to a whole voxel's width (dx/|vx| or dy/|vy|), so a step needs no division, no
!> position and no search for the cell; the periodic boundaries only wrap the cell index. The
!> null-collision flight itself (`fly_3d`) does not use this walk: it steps through the
!> super-voxel blocks of the majorant grid (kumo_supervoxel), in three dimensions (see
!> docs/design.md).
module kumo_voxel_walk
  use kumo_kinds, only: wp
  use kumo_atmosphere, only: atmosphere_t, column_xy
  implicit none
  private
  public :: voxel_walk_t, walk_begin, walk_segment, walk_next, walk_extend, walk_layer

  !> State of a walk through the voxel columns of one layer (set by walk_begin; no default
  !> values, so that starting a walk costs nothing beyond what it sets).
  type :: voxel_walk_t
    integer :: ix, iy          !! voxel column of the current segment
    integer :: sx, sy          !! step of ix, iy at an x, y face (+1, -1; 0 along no face)
    real(wp) :: tx, ty         !! path from the start of the current segment to the next x, y face [m]
    real(wp) :: tdx, tdy       !! path across one voxel from x face to x face, y face to y face [m]
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
    call first_face(wk%ix, x, vx, atm%dx, wk%sx, wk%tx, wk%tdx)
    call first_face(wk%iy, y, vy, atm%dy, wk%sy, wk%ty, wk%tdy)
    wk%rem = s
  end subroutine walk_begin

  !> The segment inside voxel column (wk%ix, wk%iy): its length wk%step, and `last` when the
  !> walk ends inside this voxel (then wk%step = wk%rem).
  pure subroutine walk_segment(wk, last)
    type(voxel_walk_t), intent(inout) :: wk
    logical, intent(out) :: last
    wk%step = min(wk%tx, wk%ty, wk%rem)
    wk%x_face = wk%tx <= wk%ty
    last = wk%step >= wk%rem
  end subroutine walk_segment

  !> Move to the start of the next segment: across the face that ends the current one.
  pure subroutine walk_next(wk, atm)
    type(voxel_walk_t), intent(inout) :: wk
    type(atmosphere_t), intent(in) :: atm
    wk%rem = wk%rem - wk%step
    if (wk%x_face) then
      wk%ty = wk%ty - wk%step
      wk%tx = wk%tdx
      wk%ix = wk%ix + wk%sx
      if (wk%ix > atm%nx) wk%ix = 1
      if (wk%ix < 1) wk%ix = atm%nx
    else
      wk%tx = wk%tx - wk%step
      wk%ty = wk%tdy
      wk%iy = wk%iy + wk%sy
      if (wk%iy > atm%ny) wk%iy = 1
      if (wk%iy < 1) wk%iy = atm%ny
    end if
  end subroutine walk_next

  !> Go on along the same straight path into the next layer, for the path length s there. The
  !> walk's last segment ended in the current voxel column on the boundary between the layers,
  !> so the column stays and the paths to the faces ahead shrink by that segment: a line of
  !> sight crosses the layers of the 3-D region without starting a walk (two divisions per
  !> axis) in each.
  pure subroutine walk_extend(wk, s)
    type(voxel_walk_t), intent(inout) :: wk
    real(wp), intent(in) :: s
    wk%tx = wk%tx - wk%step
    wk%ty = wk%ty - wk%step
    wk%rem = s
  end subroutine walk_extend

  !> A walk of length s through one layer: on from the walk of the layer before when that
  !> ended here (`walking`), else a new one from (x, y); `walking` is true on return.
  pure subroutine walk_layer(wk, atm, x, y, vx, vy, s, walking)
    type(voxel_walk_t), intent(inout) :: wk
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(in) :: x, y, vx, vy, s
    logical, intent(inout) :: walking
    if (walking) then
      call walk_extend(wk, s)
    else
      call walk_begin(wk, atm, x, y, vx, vy, s)
    end if
    walking = .true.
  end subroutine walk_layer

  !> Along one axis, for cell i (width d) holding coordinate x and direction cosine v: the step
  !> of i at a face (the sign of v), the path to the face ahead and the path across one cell
  !> (both huge for v = 0).
  pure subroutine first_face(i, x, v, d, si, t, td)
    integer, intent(in) :: i
    real(wp), intent(in) :: x, v, d
    integer, intent(out) :: si
    real(wp), intent(out) :: t, td
    if (v > 0.0_wp) then
      si = 1
      t = max(0.0_wp, (i*d - x)/v)
      td = d/v
    else if (v < 0.0_wp) then
      si = -1
      t = max(0.0_wp, ((i - 1)*d - x)/v)
      td = -d/v
    else
      si = 0
      t = huge(1.0_wp)
      td = huge(1.0_wp)
    end if
  end subroutine first_face
end module kumo_voxel_walk
