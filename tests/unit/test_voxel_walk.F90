! SPDX-License-Identifier: BSD-3-Clause
!> The voxel walk (kumo_voxel_walk): the segments of a straight path cover it exactly, each lies
!> in the voxel column the walk names (checked at its midpoint, computed independently of the
!> walk), across the periodic boundaries, for oblique and axis-parallel directions.
module test_voxel_walk_suite
  use kumo_kinds, only: wp
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  use kumo_atmosphere, only: atmosphere_t
  use kumo_voxel_walk, only: voxel_walk_t, walk_begin, walk_segment, walk_next, walk_extend
  implicit none
  private
  public :: collect_voxel_walk

contains

  function collect_voxel_walk() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('oblique_path_across_boundaries', test_oblique), &
             new_unittest('backward_path', test_backward), &
             new_unittest('axis_parallel_path', test_axis), &
             new_unittest('path_inside_one_voxel', test_short), &
             new_unittest('long_path_keeps_its_voxels', test_long), &
             new_unittest('path_goes_on_through_layers', test_layers)]
  end function collect_voxel_walk

  !> A 3 x 2 grid of 100 m x 50 m voxels (lx = 300 m, ly = 100 m).
  function grid() result(atm)
    type(atmosphere_t) :: atm
    atm%nx = 3
    atm%ny = 2
    atm%lx = 300.0_wp
    atm%ly = 100.0_wp
    atm%dx = 100.0_wp
    atm%dy = 50.0_wp
    atm%inv_dx = 0.01_wp
    atm%inv_dy = 0.02_wp
  end function grid

  !> Walk s metres from (x0, y0) along (vx, vy) and check every segment; n_seg is the count.
  !> With `pieces`, the path is walked as consecutive pieces of these lengths (layers; they
  !> add up to s), each after the first by walk_extend.
  subroutine check_walk(error, x0, y0, vx, vy, s, n_seg, pieces)
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in) :: x0, y0, vx, vy, s
    integer, intent(out) :: n_seg
    real(wp), intent(in), optional :: pieces(:)
    type(atmosphere_t) :: atm
    type(voxel_walk_t) :: wk
    real(wp) :: t, tm, xm, ym
    logical :: last
    integer :: ix, iy, ip
    atm = grid()
    ip = 1
    if (present(pieces)) then
      call walk_begin(wk, atm, x0, y0, vx, vy, pieces(1))
    else
      call walk_begin(wk, atm, x0, y0, vx, vy, s)
    end if
    t = 0.0_wp
    n_seg = 0
    do
      call walk_segment(wk, last)
      n_seg = n_seg + 1
      call check(error, wk%step > 0.0_wp, 'segment of positive length')
      if (allocated(error)) return
      ! the midpoint of the segment, from the start point and the distance travelled
      tm = t + 0.5_wp*wk%step
      xm = modulo(x0 + vx*tm, atm%lx)
      ym = modulo(y0 + vy*tm, atm%ly)
      ix = int(xm/atm%dx) + 1
      iy = int(ym/atm%dy) + 1
      call check(error, wk%ix == ix .and. wk%iy == iy, 'segment lies in the voxel the walk names')
      if (allocated(error)) return
      t = t + wk%step
      if (last) then
        if (.not. present(pieces)) exit
        if (ip == size(pieces)) exit
        ip = ip + 1
        call walk_extend(wk, pieces(ip))
        cycle
      end if
      call walk_next(wk, atm)
      call check(error, n_seg < 100000, 'walk ends')
      if (allocated(error)) return
    end do
    call check_close(error, t, s, 1.0e-9_wp, 1.0e-12_wp, 'segments add up to the path')
  end subroutine check_walk

  subroutine test_oblique(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: n
    ! 0.6 x and 0.8 y per metre over 1000 m: 600 m in x (six x faces), 800 m in y (16 y faces)
    call check_walk(error, 30.0_wp, 20.0_wp, 0.6_wp, 0.8_wp, 1000.0_wp, n)
    if (allocated(error)) return
    call check(error, n == 1 + 6 + 16, 'one segment per voxel entered')
  end subroutine test_oblique

  subroutine test_backward(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: n
    ! -0.28 x and -0.96 y per metre over 500 m: x from 250 to 110 (one x face), y 26 to -454
    ! (faces at 0, -50, ..., -450: ten)
    call check_walk(error, 250.0_wp, 26.0_wp, -0.28_wp, -0.96_wp, 500.0_wp, n)
    if (allocated(error)) return
    call check(error, n == 1 + 1 + 10, 'one segment per voxel entered')
  end subroutine test_backward

  subroutine test_axis(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: n
    ! along x only (vy = 0): from 10 to 760, faces at 100, 200, ..., 700
    call check_walk(error, 10.0_wp, 70.0_wp, 1.0_wp, 0.0_wp, 750.0_wp, n)
    if (allocated(error)) return
    call check(error, n == 8, 'seven x faces crossed')
  end subroutine test_axis

  subroutine test_short(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: n
    call check_walk(error, 120.0_wp, 60.0_wp, 0.6_wp, -0.8_wp, 10.0_wp, n)
    if (allocated(error)) return
    call check(error, n == 1, 'one segment')
  end subroutine test_short

  !> A long path (the face distances are carried from segment to segment, not recomputed from
  !> positions): 60 km at 0.6 x and -0.8 y per metre cross 360 x faces and 960 y faces, and every
  !> segment's midpoint must still lie in the voxel the walk names.
  subroutine test_long(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: n
    call check_walk(error, 37.3_wp, 12.9_wp, 0.6_wp, -0.8_wp, 60000.0_wp, n)
    if (allocated(error)) return
    call check(error, n == 1 + 360 + 960, 'one segment per voxel entered')
  end subroutine test_long

  !> A line of sight through several layers: the walk of the first goes on through the others
  !> (walk_extend) and names the same voxels as one walk of the whole path, with one more
  !> segment at each layer boundary (none of which lies on a face here).
  subroutine test_layers(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: n
    real(wp), parameter :: PIECES(7) = [101.3_wp, 77.7_wp, 211.9_wp, 3.1_wp, 150.5_wp, &
                                        298.6_wp, 156.9_wp]
    call check_walk(error, 30.0_wp, 20.0_wp, 0.6_wp, 0.8_wp, sum(PIECES), n, PIECES)
    if (allocated(error)) return
    call check(error, n == 1 + 6 + 16 + 6, 'one segment per voxel entered and per boundary')
  end subroutine test_layers
end module test_voxel_walk_suite

program test_voxel_walk
  use kumo_testing, only: run_unittests
  use test_voxel_walk_suite, only: collect_voxel_walk
  implicit none
  integer :: n_failed
  call run_unittests('voxel_walk', collect_voxel_walk(), n_failed)
  if (n_failed > 0) error stop 1
end program test_voxel_walk
