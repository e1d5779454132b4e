! SPDX-License-Identifier: BSD-3-Clause
!> Sources: where photons come from. One launch interface for every kind of source; the photon
!> loop asks the source for a photon and never looks inside it.
!>
!> Kinds today:
!> * SOURCE_SOLAR: a parallel beam entering at the top of the domain (seed text section 3.2.4),
!>   with optional stratified entry points.
!>
!> A new kind (thermal emission from cells and the surface, a point or cone source, a lidar
!> transmitter) is a new kind code, its set-up routine and its branch in `source_launch` (and in
!> `source_begin_batch` if it stratifies): the loop itself does not change. Launching is one
!> `select case` on an integer per photon, no polymorphic dispatch.
module kumo_source
  use kumo_kinds, only: wp, i8
  use kumo_constants, only: DEG2RAD
  use kumo_rng, only: rng_t, rng_uniform
  use kumo_math, only: wrap
  use kumo_atmosphere, only: atmosphere_t
  use kumo_photon, only: photon_t
  implicit none
  private
  public :: source_t, launch_plan_t, SOURCE_SOLAR, solar_source, source_stratify, &
            source_begin_batch, source_launch

  integer, parameter :: SOURCE_SOLAR = 1

  !> A source of photons.
  !>
  !> Solar beam: entry points are stratified when nsx*nsy > 1 and a batch has at least nsx*nsy
  !> photons: the photons of a batch take the cells of an nsx x nsy grid in turn, from a random
  !> first cell, each at a uniform random point of its cell, and the grid is shifted by
  !> (shift_x, shift_y) (the drift of the direct beam from the top to the surface, so that the
  !> cells fall onto the columns or surface pixels below). Every entry point is still uniform
  !> over the domain, so the estimates stay unbiased; each batch covers the domain evenly, so
  !> per-column and per-pixel results vary less between batches.
  type :: source_t
    integer :: kind = SOURCE_SOLAR
    real(wp) :: ux = 0.0_wp, uy = 0.0_wp, uz = -1.0_wp  !! propagation direction of the beam
    integer :: nsx = 1, nsy = 1                         !! grid of entry cells (1 x 1: off)
    real(wp) :: shift_x = 0.0_wp, shift_y = 0.0_wp      !! grid offset [m]
  end type source_t

  !> What a source decides once per batch (the first entry cell of a stratified beam).
  type :: launch_plan_t
    logical :: stratify = .false.
    integer :: ns = 1              !! entry cells
    integer(i8) :: s_first = 0_i8  !! cell of the batch's first photon (0-based)
  end type launch_plan_t

contains

  !> Solar beam for solar zenith angle `sza_deg` and propagation azimuth `phi0_deg` (from +x
  !> towards +y; 0 means the beam travels towards +x, i.e. the sun is at low x).
  pure function solar_source(sza_deg, phi0_deg) result(src)
    real(wp), intent(in) :: sza_deg, phi0_deg
    type(source_t) :: src
    real(wp) :: st
    src%kind = SOURCE_SOLAR
    st = sin(sza_deg*DEG2RAD)
    src%ux = st*cos(phi0_deg*DEG2RAD)
    src%uy = st*sin(phi0_deg*DEG2RAD)
    src%uz = -cos(sza_deg*DEG2RAD)
  end function solar_source

  !> Stratify the entry points of a beam on an nsx x nsy grid whose cells fall, after the
  !> beam's drift over `depth` (top of the domain to the surface), onto the columns or surface
  !> pixels below.
  pure subroutine source_stratify(src, nsx, nsy, depth)
    type(source_t), intent(inout) :: src
    integer, intent(in) :: nsx, nsy
    real(wp), intent(in) :: depth
    src%nsx = nsx
    src%nsy = nsy
    src%shift_x = src%ux/(-src%uz)*depth
    src%shift_y = src%uy/(-src%uz)*depth
  end subroutine source_stratify

  !> Start a batch of `n_photons`: the decisions the source takes once per batch.
  subroutine source_begin_batch(src, n_photons, rng, plan)
    type(source_t), intent(in) :: src
    integer(i8), intent(in) :: n_photons
    type(rng_t), intent(inout) :: rng
    type(launch_plan_t), intent(out) :: plan
    plan%ns = src%nsx*src%nsy
    plan%stratify = plan%ns > 1 .and. n_photons >= plan%ns
    plan%s_first = 0
    if (plan%stratify) plan%s_first = min(int(rng_uniform(rng)*plan%ns, i8), int(plan%ns - 1, i8))
  end subroutine source_begin_batch

  !> Launch photon `ip` (1-based) of the batch: position, direction, weight 1, no events yet.
  subroutine source_launch(src, plan, atm, rng, ip, p)
    type(source_t), intent(in) :: src
    type(launch_plan_t), intent(in) :: plan
    type(atmosphere_t), intent(in) :: atm
    type(rng_t), intent(inout) :: rng
    integer(i8), intent(in) :: ip
    type(photon_t), intent(inout) :: p
    integer :: s_cell
    ! SOURCE_SOLAR (the only kind so far): the beam enters at the top
    if (plan%stratify) then
      s_cell = int(mod(plan%s_first + ip - 1, int(plan%ns, i8)))
      p%x = (mod(s_cell, src%nsx) + rng_uniform(rng))*(atm%lx/src%nsx) - src%shift_x
      p%y = (s_cell/src%nsx + rng_uniform(rng))*(atm%ly/src%nsy) - src%shift_y
      call wrap(p%x, atm%lx)
      call wrap(p%y, atm%ly)
    else
      p%x = rng_uniform(rng)*atm%lx
      p%y = rng_uniform(rng)*atm%ly
    end if
    p%z = atm%z(atm%nz)
    p%ux = src%ux
    p%uy = src%uy
    p%uz = src%uz
    p%w = 1.0_wp
    p%order = 0
    p%lev = 1
    p%iz = atm%nz
    p%n_events = 0
    p%n_steps = 0
    p%secondary = .false.
  end subroutine source_launch

end module kumo_source
