! SPDX-License-Identifier: BSD-3-Clause
!> The lower boundary: a Lambert surface with a uniform albedo or a 2-D albedo map on its own grid,
!> or a BRDF surface (kumo_brdf: black, Lambert, DSM, RPV, LSRT), uniform or a 2-D map of
!> parameter sets on its own grid.
module kumo_surface
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, add_context, str
  use kumo_math, only: within
  use kumo_brdf, only: brdf_params_t, brdf_table_t, brdf_table_init, BRDF_BLACK, BRDF_LAMBERT, &
                       BRDF_LSRT, BRDF_NPAR, lsrt_grid_t, lsrt_grid_init, brdf_table_init_grid
  implicit none
  private
  public :: surface_t, surface_init, surface_init_brdf, surface_init_brdf_map

  !> Lambert surface. The map covers the periodic domain [0, lx) x [0, ly) with nxs x nys pixels
  !> that are independent of the atmosphere's grid.
  type :: surface_t
    integer :: nxs = 1                      !! pixels along x
    integer :: nys = 1                      !! pixels along y
    real(wp) :: lx = 1.0_wp                 !! domain size along x [m]
    real(wp) :: ly = 1.0_wp                 !! domain size along y [m]
    real(wp) :: inv_dxs = 1.0_wp            !! pixels per metre along x
    real(wp) :: inv_dys = 1.0_wp            !! pixels per metre along y
    logical :: uniform = .true.             !! one albedo (one BRDF class) everywhere
    logical :: black = .true.               !! albedo 0 everywhere: no reflection work at all
    real(wp), allocatable :: albedo(:, :)   !! Lambert albedo per pixel, (nxs, nys)
    !> a BRDF other than Lambert: reflection weights, directions and local estimates come from
    !> the table of the pixel's class, tabs(class_at(x, y)) (albedo(:, :) is then unused)
    logical :: use_brdf = .false.
    type(brdf_table_t), allocatable :: tabs(:)   !! one table per distinct parameter set
    integer, allocatable :: cls(:, :)            !! class of each pixel (nxs, nys), if not uniform
  contains
    procedure :: albedo_at
    procedure :: class_at
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
  !> `mu0` (-uz of the direct beam) gets its directional albedo stored exactly.
  subroutine surface_init_brdf(sfc, model, lx, ly, error, mu0)
    type(surface_t), intent(out) :: sfc
    type(brdf_params_t), intent(in) :: model
    real(wp), intent(in) :: lx, ly          !! domain size [m]
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: mu0
    select case (model%kind)
    case (BRDF_BLACK)
      call surface_init(sfc, reshape([0.0_wp], [1, 1]), lx, ly, error)
    case (BRDF_LAMBERT)
      call surface_init(sfc, reshape([model%c(1)], [1, 1]), lx, ly, error)
    case default
      call surface_init(sfc, reshape([1.0_wp], [1, 1]), lx, ly, error)
      if (allocated(error)) return
      allocate (sfc%tabs(1))
      call brdf_table_init(sfc%tabs(1), model, error, mu0)
      sfc%use_brdf = .true.
    end select
  end subroutine surface_init_brdf

  !> A BRDF map: one parameter set per pixel of an nxs x nys grid over [0, lx) x [0, ly).
  !> Pixels with identical parameters share a class and its table; tables of DSM and RPV classes
  !> come from `brdf_table_init` (4-10 ms each), those of LSRT classes from the shared kernel
  !> grid (`brdf_table_init_grid`, about 0.1 ms each). A map of Lambert and black pixels only
  !> becomes an albedo map; a map with one class is a uniform surface.
  subroutine surface_init_brdf_map(sfc, params, lx, ly, error, n_classes, mu0)
    type(surface_t), intent(out) :: sfc
    type(brdf_params_t), intent(in) :: params(:, :)   !! parameters per pixel (nxs, nys)
    real(wp), intent(in) :: lx, ly                    !! domain size [m]
    type(error_t), allocatable, intent(out) :: error
    integer, intent(out), optional :: n_classes       !! number of distinct parameter sets
    real(wp), intent(in), optional :: mu0             !! -uz of the direct beam (exact albedo)
    integer, allocatable :: order(:), cls(:)
    real(wp), allocatable :: alb(:, :)
    type(lsrt_grid_t) :: grid
    type(brdf_params_t) :: p
    integer :: nxs, nys, n, i, k, first
    logical :: have_grid

    nxs = size(params, 1)
    nys = size(params, 2)
    n = nxs*nys
    if (present(n_classes)) n_classes = 0
    if (all(params%kind == BRDF_LAMBERT .or. params%kind == BRDF_BLACK)) then
      allocate (alb(nxs, nys))
      alb = merge(params%c(1), 0.0_wp, params%kind == BRDF_LAMBERT)
      call surface_init(sfc, alb, lx, ly, error)
      if (present(n_classes)) n_classes = 1
      return
    end if
    call surface_init(sfc, reshape([1.0_wp], [1, 1]), lx, ly, error)
    if (allocated(error)) return
    sfc%nxs = nxs
    sfc%nys = nys
    sfc%inv_dxs = nxs/lx
    sfc%inv_dys = nys/ly
    sfc%use_brdf = .true.
    sfc%black = .false.

    ! classes: runs of equal parameter sets in sorted order
    order = sorted_pixels(params)
    allocate (cls(n))
    k = 0
    first = 0
    do i = 1, n
      if (i == 1) then
        k = 1
        first = order(1)
      else if (compare_params(pixel(order(i)), pixel(first)) /= 0) then
        k = k + 1
        first = order(i)
      end if
      cls(order(i)) = k
    end do
    allocate (sfc%tabs(k))
    have_grid = .false.
    k = 0
    do i = 1, n
      if (cls(order(i)) == k) cycle
      k = cls(order(i))
      p = pixel(order(i))
      if (p%kind == BRDF_LSRT) then
        if (.not. have_grid) call lsrt_grid_init(grid)
        have_grid = .true.
        call brdf_table_init_grid(sfc%tabs(k), p, grid, error, mu0)
      else
        call brdf_table_init(sfc%tabs(k), p, error, mu0)
      end if
      if (allocated(error)) then
        call add_context(error, 'surface pixel (xs,ys) = ('//str(mod(order(i) - 1, nxs) + 1)// &
                         ','//str((order(i) - 1)/nxs + 1)//')')
        return
      end if
    end do
    sfc%cls = reshape(cls, [nxs, nys])
    sfc%uniform = size(sfc%tabs) == 1
    if (present(n_classes)) n_classes = size(sfc%tabs)
  contains
    !> Parameters of pixel i in Fortran (column-major) order.
    pure type(brdf_params_t) function pixel(i)
      integer, intent(in) :: i
      pixel = params(mod(i - 1, nxs) + 1, (i - 1)/nxs + 1)
    end function pixel
  end subroutine surface_init_brdf_map

  !> Pixel indices (column-major) sorted by parameter set (merge sort, stable).
  function sorted_pixels(params) result(order)
    type(brdf_params_t), intent(in) :: params(:, :)
    integer, allocatable :: order(:)
    integer, allocatable :: tmp(:)
    type(brdf_params_t), allocatable :: flat(:)
    integer :: n, width, lo, mid, hi, i, j, k
    flat = reshape(params, [size(params)])
    n = size(flat)
    order = [(i, i=1, n)]
    allocate (tmp(n))
    width = 1
    do while (width < n)
      do lo = 1, n, 2*width
        mid = min(lo + width - 1, n)
        hi = min(lo + 2*width - 1, n)
        i = lo
        j = mid + 1
        do k = lo, hi
          if (j > hi) then
            tmp(k) = order(i)
            i = i + 1
          else if (i > mid) then
            tmp(k) = order(j)
            j = j + 1
          else if (compare_params(flat(order(j)), flat(order(i))) < 0) then
            tmp(k) = order(j)
            j = j + 1
          else
            tmp(k) = order(i)
            i = i + 1
          end if
        end do
      end do
      order = tmp
      width = 2*width
    end do
  end function sorted_pixels

  !> Lexicographic order of parameter sets: -1, 0 or 1.
  pure integer function compare_params(a, b) result(c)
    type(brdf_params_t), intent(in) :: a, b
    integer :: i
    c = 0
    if (a%kind /= b%kind) then
      c = merge(-1, 1, a%kind < b%kind)
      return
    end if
    do i = 1, BRDF_NPAR
      if (a%c(i) /= b%c(i)) then
        c = merge(-1, 1, a%c(i) < b%c(i))
        return
      end if
    end do
  end function compare_params

  !> BRDF class (index into tabs) of the pixel under (x, y), with x in [0, lx), y in [0, ly).
  pure integer function class_at(sfc, x, y) result(k)
    class(surface_t), intent(in) :: sfc
    real(wp), intent(in) :: x, y  !! position [m]
    integer :: i, j
    if (sfc%uniform) then
      k = 1
    else
      i = min(sfc%nxs, max(1, int(x*sfc%inv_dxs) + 1))
      j = min(sfc%nys, max(1, int(y*sfc%inv_dys) + 1))
      k = sfc%cls(i, j)
    end if
  end function class_at

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
