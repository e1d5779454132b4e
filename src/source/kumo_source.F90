! SPDX-License-Identifier: BSD-3-Clause
!> Sources: where photons come from. One launch interface for every kind of source; the photon
!> loop asks the source for a photon and never looks inside it.
!>
!> Kinds today:
!> * SOURCE_SOLAR: a parallel beam entering at the top of the domain (seed text section 3.2.4),
!>   with optional stratified entry points.
!> * Thermal emission (kumo_emission): cells, the surface and the top, from one stratified table
!>   in which the sun, when it shines in the same run, is the first entry. Photon j of a batch of
!>   n takes the entry holding (j - 1 + U)/n, so the first n_sol photons of a batch are solar
!>   and keep the beam's own stratified entry points.
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
  use kumo_surface, only: surface_t
  use kumo_photon, only: photon_t
  use kumo_emission, only: emission_t, emission_entry, emission_launch, emission_weight, &
                           EMIT_SOLAR
  implicit none
  private
  public :: source_t, launch_plan_t, SOURCE_SOLAR, solar_source, source_stratify, &
            source_begin_batch, source_launch

  integer, parameter :: SOURCE_SOLAR = 1

  !> A source of photons.
  !>
  !> Solar beam: entry points are stratified when nsx*nsy > 1. A batch of n = q*ns + r photons
  !> (ns = nsx*nsy cells) gives q photons to every cell of an nsx x nsy grid, taken in turn from
  !> a random first cell, each at a uniform random point of its cell; the grid is shifted by
  !> (shift_x, shift_y) (the drift of the direct beam from the top to the surface, so that the
  !> cells fall onto the columns or surface pixels below). The r photons left over (all of them
  !> when n < ns) enter at the points of a randomly shifted rank-1 lattice over the whole domain
  !> (x in the k-th of r strips, y at k*g/r for a generator g coprime with r), which spreads
  !> them evenly in both directions whatever r is. The expected number of photons per unit area
  !> is uniform, so the estimates stay unbiased; each batch covers the domain evenly, so domain
  !> means and per-column and per-pixel results vary less between batches than with
  !> independent entry points, whatever the batch size.
  type :: source_t
    integer :: kind = SOURCE_SOLAR
    real(wp) :: ux = 0.0_wp, uy = 0.0_wp, uz = -1.0_wp  !! propagation direction of the beam
    integer :: nsx = 1, nsy = 1                         !! grid of entry cells (1 x 1: off)
    real(wp) :: shift_x = 0.0_wp, shift_y = 0.0_wp      !! grid offset [m]
    type(emission_t) :: em                              !! thermal emission (em%on: a source)
    !> factor on every launched weight (1: a photon carries 1/n of the source); broadband runs
    !> trace each g-point's photons with their g-point's weight w_g n / S here, into one tally
    real(wp) :: w_unit = 1.0_wp
  end type source_t

  !> What a source decides once per batch (stratified beam: the first entry cell, the photons
  !> that go to the cells, and the lattice of the photons left over).
  type :: launch_plan_t
    logical :: stratify = .false.
    integer :: ns = 1              !! entry cells
    integer(i8) :: s_first = 0_i8  !! cell of the batch's first photon (0-based)
    integer(i8) :: n_cells = 0_i8  !! photons 1 .. n_cells go to the cells (q*ns of them)
    integer(i8) :: n_left = 0_i8   !! photons after them, on the lattice (r)
    integer(i8) :: g = 0_i8        !! lattice generator, coprime with n_left
    real(wp) :: u1 = 0.0_wp, u2 = 0.0_wp  !! random shift of the lattice
    ! thermal emission: photon j takes the table entry holding (j - 1 + u_em)/n
    integer(i8) :: n = 0_i8        !! photons of the batch
    integer(i8) :: n_sol = 0_i8    !! the first n_sol of them are solar
    real(wp) :: u_em = 0.0_wp
  end type launch_plan_t

  !> The golden ratio's fractional part: lattice generators near r/phi spread points evenly.
  real(wp), parameter :: GOLDEN_FRACTION = 0.6180339887498949_wp

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
    integer(i8) :: n_beam
    plan%n = n_photons
    n_beam = n_photons
    if (src%em%on) then
      plan%u_em = rng_uniform(rng)
      plan%n_sol = 0
      if (src%em%solar_power > 0.0_wp) plan%n_sol = max(0_i8, min(n_photons, &
        int(ceiling(real(n_photons, wp)*src%em%cdf_sun - plan%u_em), i8)))
      n_beam = plan%n_sol
    end if
    plan%ns = src%nsx*src%nsy
    plan%stratify = plan%ns > 1
    plan%s_first = 0
    if (.not. plan%stratify) return
    plan%n_left = mod(n_beam, int(plan%ns, i8))
    plan%n_cells = n_beam - plan%n_left
    if (plan%n_cells > 0) &
      plan%s_first = min(int(rng_uniform(rng)*plan%ns, i8), int(plan%ns - 1, i8))
    if (plan%n_left > 0) then
      plan%u1 = rng_uniform(rng)
      plan%u2 = rng_uniform(rng)
      plan%g = max(1_i8, nint(plan%n_left*GOLDEN_FRACTION, i8))
      do while (gcd(plan%g, plan%n_left) /= 1)
        plan%g = plan%g + 1
      end do
    end if
  end subroutine source_begin_batch

  !> Greatest common divisor of two positive integers.
  pure integer(i8) function gcd(a, b)
    integer(i8), intent(in) :: a, b
    integer(i8) :: x, y, t
    x = a
    y = b
    do while (y /= 0)
      t = mod(x, y)
      x = y
      y = t
    end do
    gcd = x
  end function gcd

  !> Launch photon `ip` (1-based) of the batch: position, direction, weight (1 for the sun
  !> alone), no events yet.
  subroutine source_launch(src, plan, atm, sfc, rng, ip, p)
    type(source_t), intent(in) :: src
    type(launch_plan_t), intent(in) :: plan
    type(atmosphere_t), intent(in) :: atm
    type(surface_t), intent(in) :: sfc
    type(rng_t), intent(inout) :: rng
    integer(i8), intent(in) :: ip
    type(photon_t), intent(inout) :: p
    integer :: s_cell
    integer(i8) :: k
    real(wp) :: fy, uj
    if (src%em%on) then
      if (ip > plan%n_sol) then
        uj = (real(ip - 1, wp) + plan%u_em)/real(plan%n, wp)
        call emission_launch(src%em, atm, sfc, rng, emission_entry(src%em, uj), plan%n, &
                             plan%u_em, uj, p)
        p%w = p%w*src%w_unit
        p%w_entry = p%w_entry*src%w_unit
        return
      end if
    end if
    ! SOURCE_SOLAR: the beam enters at the top
    if (plan%stratify .and. ip > plan%n_cells) then
      ! a photon left over: point k of the shifted lattice
      k = ip - plan%n_cells - 1
      p%x = (real(k, wp) + plan%u1)/real(plan%n_left, wp)*atm%lx
      fy = real(mod(k*plan%g, plan%n_left), wp)/real(plan%n_left, wp) + plan%u2
      if (fy >= 1.0_wp) fy = fy - 1.0_wp
      p%y = fy*atm%ly
      call wrap(p%x, atm%lx)
      call wrap(p%y, atm%ly)
    else if (plan%stratify) then
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
    p%w = src%w_unit
    p%order = 0
    p%lev = 1
    p%iz = atm%nz
    p%n_events = 0
    p%n_steps = 0
    p%secondary = .false.
    if (src%em%on) then
      p%w = emission_weight(src%em, 1, plan%n, plan%u_em)*src%w_unit
      p%emitter = EMIT_SOLAR
      p%em_k = 0
      p%em_v = 0
      p%rbe = 0.0_wp
    end if
  end subroutine source_launch

end module kumo_source
