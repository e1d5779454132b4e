! SPDX-License-Identifier: BSD-3-Clause
!> The lower boundary: a Lambert surface with a uniform albedo or a 2-D albedo map on its own grid,
!> or a uniform BRDF surface (kumo_brdf: DSM, RPV, LSRT).
module kumo_surface
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str
  use kumo_math, only: within
  use kumo_brdf, only: brdf_params_t, brdf_table_t, brdf_table_init, BRDF_BLACK, BRDF_LAMBERT
  implicit none
  private
  public :: surface_t, surface_init, surface_init_brdf

  !> Lambert surface. The map covers the periodic domain [0, lx) x [0, ly) with nxs x nys pixels
  !> that are independent of the atmosphere's grid.
  type :: surface_t
    integer :: nxs = 1                      !! pixels along x
    integer :: nys = 1                      !! pixels along y
    real(wp) :: lx = 1.0_wp                 !! domain size along x [m]
    real(wp) :: ly = 1.0_wp                 !! domain size along y [m]
    real(wp) :: inv_dxs = 1.0_wp            !! pixels per metre along x
    real(wp) :: inv_dys = 1.0_wp            !! pixels per metre along y
    logical :: uniform = .true.             !! one albedo everywhere
    logical :: black = .true.               !! albedo 0 everywhere: no reflection work at all
    real(wp), allocatable :: albedo(:, :)   !! Lambert albedo per pixel, (nxs, nys)
    !> a BRDF other than Lambert: reflection weights, directions and local estimates come from
    !> `tab` (albedo(:, :) is then unused)
    logical :: use_brdf = .false.
    type(brdf_table_t) :: tab
  contains
    procedure :: albedo_at
  end type surface_t

contains

  !> Build the surface from an albedo map (a 1 x 1 map is a uniform surface).
  subroutine surface_init(sfc, albedo, lx, ly, error)
    type(surface_t), intent(out) :: sfc
    real(wp), intent(in) :: albedo(:, :)   !! albedo per pixel, (nxs, nys)
    real(wp), intent(in) :: lx, ly          !! domain size [m]
    type(error_t), allocatable, intent(out) :: error
    integer :: i, j
    do j = 1, size(albedo, 2)
      do i = 1, size(albedo, 1)
        if (.not. within(albedo(i, j), 0.0_wp, 1.0_wp)) then
          call set_error(error, 'surface albedo at pixel ('//str(i)//','//str(j)// &
                         ') must be within [0, 1]')
          return
        end if
      end do
    end do
    sfc%nxs = size(albedo, 1)
    sfc%nys = size(albedo, 2)
    sfc%lx = lx
    sfc%ly = ly
    sfc%inv_dxs = sfc%nxs/lx
    sfc%inv_dys = sfc%nys/ly
    sfc%albedo = albedo
    sfc%uniform = all(albedo == albedo(1, 1))
    sfc%black = all(albedo == 0.0_wp)
  end subroutine surface_init

  !> A uniform BRDF surface over the domain [0, lx) x [0, ly). A Lambert or black model gives
  !> the ordinary Lambert surface.
  subroutine surface_init_brdf(sfc, model, lx, ly, error)
    type(surface_t), intent(out) :: sfc
    type(brdf_params_t), intent(in) :: model
    real(wp), intent(in) :: lx, ly          !! domain size [m]
    type(error_t), allocatable, intent(out) :: error
    select case (model%kind)
    case (BRDF_BLACK)
      call surface_init(sfc, reshape([0.0_wp], [1, 1]), lx, ly, error)
    case (BRDF_LAMBERT)
      call surface_init(sfc, reshape([model%c(1)], [1, 1]), lx, ly, error)
    case default
      call surface_init(sfc, reshape([1.0_wp], [1, 1]), lx, ly, error)
      if (allocated(error)) return
      call brdf_table_init(sfc%tab, model, error)
      sfc%use_brdf = .true.
    end select
  end subroutine surface_init_brdf

  !> Albedo under the point (x, y), with x in [0, lx) and y in [0, ly).
  pure real(wp) function albedo_at(sfc, x, y) result(a)
    class(surface_t), intent(in) :: sfc
    real(wp), intent(in) :: x, y  !! position [m]
    integer :: i, j
    if (sfc%uniform) then
      a = sfc%albedo(1, 1)
    else
      i = min(sfc%nxs, max(1, int(x*sfc%inv_dxs) + 1))
      j = min(sfc%nys, max(1, int(y*sfc%inv_dys) + 1))
      a = sfc%albedo(i, j)
    end if
  end function albedo_at

end module kumo_surface
