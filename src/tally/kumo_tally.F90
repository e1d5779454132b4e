! SPDX-License-Identifier: BSD-3-Clause
!> Tallies of one batch and the batch statistics built from them.
!>
!> All accumulators of a batch live in one contiguous real(dp) buffer, so merging is one array
!> add and the MPI reduction is one call. The layout records where each quantity sits. After a
!> batch, its normalised tallies x_b enter the running sums S1 = sum x_b and S2 = sum x_b**2,
!> from which the mean and the standard error of the mean follow (batch method, as in the I3RC
!> community model).
!>
!> The photon code scores through the named `score_*` procedures below (a level crossing, an
!> absorption, a radiance sample, ...), never through buffer positions: only this module knows
!> the layout. They are small and in the kernel library, so the compiler inlines them into the
!> photon loop (link-time optimisation across modules).
module kumo_tally
  use kumo_kinds, only: dp, i8
  implicit none
  private
  public :: tally_layout_t, tally_t, stats_t, layout_init, tally_reset, stats_init, &
            stats_add_batch, stats_mean, stats_stderr, batch_budget, tally_flush, &
            tally_free
  public :: score_flux, score_flux_map, score_layer_abs, score_voxel_abs, score_surface_abs, &
            score_roulette, score_lost, score_source, score_net_layer, score_net_surface, &
            score_net_voxel, score_radiance, score_radiance_map, score_camera
  public :: score_radiance_map_block, radiance_maps_integrate
  public :: ANOM_UZ_NUDGED, ANOM_EVENT_CAP, ANOM_STEP_CAP, ANOM_POSITION_REPAIR, &
            ANOM_BRDF_ENVELOPE, N_ANOMALIES, ANOMALY_NAMES

  integer, parameter :: ANOM_UZ_NUDGED = 1       !! direction nudged away from the horizontal
  integer, parameter :: ANOM_EVENT_CAP = 2       !! photon stopped at the event cap (weight lost)
  integer, parameter :: ANOM_STEP_CAP = 3        !! photon stopped at the step cap (weight lost)
  integer, parameter :: ANOM_POSITION_REPAIR = 4 !! position clamped back into its cell
  !> BRDF direction drawn where the sampling envelope was below the target density (a slight
  !> bias near that direction; kumo_brdf)
  integer, parameter :: ANOM_BRDF_ENVELOPE = 5
  integer, parameter :: N_ANOMALIES = 5
  character(len=24), parameter :: ANOMALY_NAMES(N_ANOMALIES) = &
    [character(len=24) :: 'uz_nudged', 'event_cap', 'step_cap', 'position_repair', &
     'brdf_envelope']

  !> Where each quantity sits in the buffer. Offsets are 0-based: the quantity for level k is
  !> buf(i_up + k + 1) etc.; see the accessor comments.
  type :: tally_layout_t
    integer :: nz = 0          !! layers
    integer :: ncol = 1        !! columns of the 3-D region (nx*ny)
    integer :: n3 = 0          !! layers of the 3-D region
    integer :: n_map = 0       !! number of levels with per-column flux maps
    logical :: do_maps = .false.
    logical :: do_voxel = .false.
    logical :: log_voxel = .false.  !! the voxel absorption scores go through the log (tally_t)
    logical :: log_maps = .false.   !! flux-map scores go through the log (tally_t)
    integer, allocatable :: map_slot(:)  !! (0:nz) slot of each level in the maps, 0 = none
    integer :: i_up = 0        !! up flux at level k: buf(i_up + k + 1), k = 0..nz
    integer :: i_dir = 0       !! direct down flux at level k
    integer :: i_dif = 0       !! diffuse down flux at level k
    integer :: i_abs = 0       !! absorbed in layer k: buf(i_abs + k), k = 1..nz
    integer :: i_sfc = 0       !! absorbed by the surface: buf(i_sfc + 1)
    integer :: i_rr = 0        !! net weight created by Russian roulette: buf(i_rr + 1)
    integer :: i_lost = 0      !! weight lost at loop caps: buf(i_lost + 1)
    integer :: i_dn = 0        !! derived per batch: total down flux at level k (direct + diffuse)
    integer :: i_atm = 0       !! derived per batch: absorbed by the whole atmosphere
    integer :: i_closure = 0   !! derived per batch: R + A_atm + A_sfc - roulette + lost (= 1)
    integer :: i_fnet = 0      !! derived per batch: net downward flux (down - up) at level k
    ! Thermal emission (sizes 0 without it): launched weight, net power (absorbed - emitted)
    ! of the layers, of the surface and of the voxels, by net exchange (kumo_emission)
    logical :: thermal = .false.
    !> photons launched with weights whose sum varies from batch to batch (broadband runs): the
    !> energy closure is relative to the weight that entered at the top
    logical :: weighted = .false.
    integer :: i_src = 0       !! weight launched: buf(i_src + 1)
    integer :: i_net = 0       !! net power of layer k: buf(i_net + k), k = 1..nz
    integer :: i_snet = 0      !! net power of the surface: buf(i_snet + 1)
    integer :: i_vnet = 0      !! net power per voxel: buf(i_vnet + (kr-1)*ncol + icol)
    integer :: i_map_up = 0    !! map: buf(i_map_up + (slot-1)*ncol + icol)
    integer :: i_map_dir = 0
    integer :: i_map_dif = 0
    integer :: i_vox = 0       !! voxel absorption: buf(i_vox + (kr-1)*ncol + icol)
    integer :: n_rad_dir = 0   !! radiance directions
    integer :: n_rad_lev = 0   !! radiance levels
    integer, allocatable :: rad_slot(:) !! (0:nz) slot of each level in the radiance list, 0 = none
    integer :: i_rad = 0       !! domain-mean radiance: buf(i_rad + (idir-1)*n_rad_lev + slot)
    logical :: do_rad_maps = .false.
    integer :: i_rad_map = 0   !! radiance map: buf(i_rad_map + ((idir-1)*n_rad_lev + slot-1)*ncol
                               !! + icol)
    !> Numerical diffusion spreads each radiance-map sample evenly over a block of columns.
    !> With `rad_map_blocks`, a batch adds each block to the maps as the four corners of its
    !> 2-D difference (score_radiance_map_block), whatever its size, and
    !> `radiance_maps_integrate` turns the differences into the maps' values at the end of the
    !> batch. The columns of a map are rows of `map_nx` (icol = (iy - 1) map_nx + ix).
    logical :: rad_map_blocks = .false.
    integer :: map_nx = 1
    integer :: i_cam0 = 0      !! entries after this one are camera pixels (domain scaling)
    integer, allocatable :: i_cam(:)  !! camera c, pixel p: buf(i_cam(c) + p)
    ! Column budget of the 3-D region, derived per batch from the maps and voxels: needs maps at
    ! the region's bottom and top levels and voxel absorption.
    logical :: do_budget = .false.
    integer :: budget_slot(2) = 0  !! map slots of the region's bottom and top levels
    integer :: i_col_abs = 0   !! absorbed in the column's 3-D region: buf(i_col_abs + icol)
    integer :: i_htr = 0       !! net power leaving the column's 3-D region sideways
    integer :: i_map_dn = 0    !! total downward flux maps (direct + diffuse, formed per batch)
    integer :: n = 0           !! buffer length
  end type tally_layout_t

  !> Entries of the scatter-add log (see tally_t).
  integer, parameter :: LOG_LEN = 4096
  !> Voxels from which on the collision scores go through the log: 4 MiB of voxel tallies, half
  !> the last-level cache a process gets on the machine where it was measured
  !> (docs/performance.md, cost of doubling the horizontal resolution). Below, the voxels
  !> stay in the cache and the log would only add instructions.
  integer(i8), parameter :: LOG_MIN_VOXELS = 524288_i8
  !> Map entries (levels times columns) from which on the flux-map scores go through the log:
  !> 1 MiB per map, 3 MiB for the three a photon scores in (measured: a 64 x 64 field with maps
  !> at 54 levels gains from the log; 2 levels of a 128 x 128 field fit the cache).
  integer(i8), parameter :: LOG_MIN_MAP = 131072_i8

  !> The accumulators of one batch.
  !>
  !> The voxel absorption scored in a large 3-D region (lay%log_voxel), and the
  !> level crossings of large flux maps (lay%log_maps), are not added to `buf` at once but
  !> appended to a short log, which `tally_flush` adds to `buf` in the order of scoring (so
  !> every entry receives the same additions in the same order, and the sums are the same to
  !> the last bit). On fine grids, and with maps at many levels, the entries a photon scores
  !> lie far apart in memory and most scores would wait for a cache line from memory in the
  !> middle of the photon's path; in the flush loop the reads do not depend on each other and
  !> overlap. `buf` is complete only after `tally_flush`: trace_batch flushes before it
  !> returns.
  type :: tally_t
    real(dp), allocatable :: buf(:)
    integer :: n_log = 0                 !! entries in the log
    integer, allocatable :: log_at(:)    !! (LOG_LEN) position in buf of each logged score
    real(dp), allocatable :: log_w(:)    !! (LOG_LEN) the score
    integer(i8) :: anomalies(N_ANOMALIES) = 0_i8
    integer(i8) :: work(2) = 0_i8   !! flight steps (incl. null collisions, face crossings), events
  end type tally_t

  !> Running batch statistics, same layout as the tally buffer.
  type :: stats_t
    real(dp), allocatable :: s1(:)      !! sum over batches of the per-photon batch means
    real(dp), allocatable :: s2(:)      !! sum over batches of their squares
    integer(i8) :: n_batches = 0_i8
    integer(i8) :: n_photons = 0_i8
    integer(i8) :: anomalies(N_ANOMALIES) = 0_i8
    integer(i8) :: work(2) = 0_i8
  end type stats_t

contains

  !> Lay out the buffer. `map_levels` lists the levels (0..nz) that get per-column maps.
  !> Radiances (optional): `n_rad_dir` directions at the levels `rad_levels` (0..nz), with
  !> per-column maps if `rad_maps`, and cameras with `cam_npix(c)` pixels. `region_levels`
  !> (the levels below and above the 3-D region) give the column budget when both have maps
  !> and voxel absorption is on.
  subroutine layout_init(lay, nz, ncol, n3, map_levels, do_voxel, n_rad_dir, rad_levels, &
                         rad_maps, cam_npix, region_levels, thermal, map_nx, rad_map_blocks, &
                         weighted)
    type(tally_layout_t), intent(out) :: lay
    integer, intent(in) :: nz, ncol, n3
    integer, intent(in) :: map_levels(:)
    logical, intent(in) :: do_voxel
    integer, intent(in), optional :: n_rad_dir, rad_levels(:)
    logical, intent(in), optional :: rad_maps
    integer, intent(in), optional :: cam_npix(:)
    integer, intent(in), optional :: region_levels(2)
    logical, intent(in), optional :: thermal   !! thermal emission: net-exchange tallies
    !> columns per row of the maps (ncol = map_nx * rows), and whether radiance-map samples
    !> come as blocks of columns (numerical diffusion): see tally_layout_t
    integer, intent(in), optional :: map_nx
    logical, intent(in), optional :: rad_map_blocks
    logical, intent(in), optional :: weighted  !! see tally_layout_t%weighted
    integer :: i, pos
    lay%nz = nz
    lay%ncol = ncol
    lay%n3 = n3
    allocate (lay%map_slot(0:nz))
    lay%map_slot = 0
    do i = 1, size(map_levels)
      lay%map_slot(map_levels(i)) = i
    end do
    lay%n_map = size(map_levels)
    lay%do_maps = lay%n_map > 0
    lay%do_voxel = do_voxel .and. n3 > 0
    lay%log_voxel = lay%do_voxel .and. int(n3, i8)*ncol >= LOG_MIN_VOXELS
    lay%log_maps = lay%do_maps .and. int(lay%n_map, i8)*ncol >= LOG_MIN_MAP
    pos = 0
    lay%i_up = pos
    pos = pos + nz + 1
    lay%i_dir = pos
    pos = pos + nz + 1
    lay%i_dif = pos
    pos = pos + nz + 1
    lay%i_abs = pos
    pos = pos + nz
    lay%i_sfc = pos
    pos = pos + 1
    lay%i_rr = pos
    pos = pos + 1
    lay%i_lost = pos
    pos = pos + 1
    lay%i_dn = pos
    pos = pos + nz + 1
    lay%i_atm = pos
    pos = pos + 1
    lay%i_closure = pos
    pos = pos + 1
    lay%i_fnet = pos
    pos = pos + nz + 1
    if (present(thermal)) lay%thermal = thermal
    if (present(weighted)) lay%weighted = weighted
    lay%i_src = pos
    lay%i_net = pos
    lay%i_snet = pos
    if (lay%thermal) then
      lay%i_net = pos + 1
      lay%i_snet = lay%i_net + nz
      pos = lay%i_snet + 1
    end if
    allocate (lay%rad_slot(0:nz))
    lay%rad_slot = 0
    if (present(n_rad_dir) .and. present(rad_levels)) then
      if (n_rad_dir > 0) then
        lay%n_rad_dir = n_rad_dir
        lay%n_rad_lev = size(rad_levels)
        do i = 1, size(rad_levels)
          lay%rad_slot(rad_levels(i)) = i
        end do
      end if
    end if
    lay%i_rad = pos
    pos = pos + lay%n_rad_dir*lay%n_rad_lev
    lay%i_map_up = pos
    pos = pos + lay%n_map*ncol
    lay%i_map_dir = pos
    pos = pos + lay%n_map*ncol
    lay%i_map_dif = pos
    pos = pos + lay%n_map*ncol
    lay%i_vox = pos
    if (lay%do_voxel) pos = pos + n3*ncol
    lay%i_vnet = pos
    if (lay%do_voxel .and. lay%thermal) pos = pos + n3*ncol
    lay%i_rad_map = pos
    if (present(rad_maps)) lay%do_rad_maps = rad_maps .and. lay%n_rad_dir > 0
    if (lay%do_rad_maps) pos = pos + lay%n_rad_dir*lay%n_rad_lev*ncol
    if (present(map_nx)) lay%map_nx = map_nx
    if (present(rad_map_blocks)) lay%rad_map_blocks = rad_map_blocks .and. lay%do_rad_maps
    if (lay%rad_map_blocks) then
      if (lay%map_nx < 1 .or. mod(ncol, lay%map_nx) /= 0) error stop &
        'layout_init: the map rows (map_nx) must divide the columns'
    end if
    lay%i_cam0 = pos
    if (present(cam_npix)) then
      allocate (lay%i_cam(size(cam_npix)))
      do i = 1, size(cam_npix)
        lay%i_cam(i) = pos
        pos = pos + cam_npix(i)
      end do
    else
      allocate (lay%i_cam(0))
    end if
    lay%i_col_abs = pos
    lay%i_htr = pos
    if (present(region_levels) .and. lay%do_maps .and. lay%do_voxel) then
      lay%budget_slot = lay%map_slot(region_levels)
      lay%do_budget = all(lay%budget_slot > 0)
    end if
    if (lay%do_budget) then
      lay%i_htr = pos + ncol
      pos = pos + 2*ncol
    end if
    lay%i_map_dn = pos
    if (lay%do_maps) pos = pos + lay%n_map*ncol
    lay%n = pos
  end subroutine layout_init

  !> Zero a tally (allocating it for the layout if needed).
  subroutine tally_reset(tal, lay)
    type(tally_t), intent(inout) :: tal
    type(tally_layout_t), intent(in) :: lay
    if (.not. allocated(tal%buf)) allocate (tal%buf(lay%n))
    if ((lay%log_voxel .or. lay%log_maps) .and. .not. allocated(tal%log_at)) &
      allocate (tal%log_at(LOG_LEN), tal%log_w(LOG_LEN))
    tal%buf = 0.0_dp
    tal%n_log = 0
    tal%anomalies = 0_i8
    tal%work = 0_i8
  end subroutine tally_reset

  !> Give back the arrays of a tally (the next tally_reset allocates them again).
  subroutine tally_free(tal)
    type(tally_t), intent(inout) :: tal
    if (allocated(tal%buf)) deallocate (tal%buf)
    if (allocated(tal%log_at)) deallocate (tal%log_at)
    if (allocated(tal%log_w)) deallocate (tal%log_w)
    tal%n_log = 0
  end subroutine tally_free

  !> Add the logged scores to the buffer, in the order they were scored, and empty the log.
  pure subroutine tally_flush(tal)
    type(tally_t), intent(inout) :: tal
    integer :: j
    do j = 1, tal%n_log
      tal%buf(tal%log_at(j)) = tal%buf(tal%log_at(j)) + tal%log_w(j)
    end do
    tal%n_log = 0
  end subroutine tally_flush

  !> Log score `w` for buf(i), flushing the log when it is full.
  pure subroutine log_score(tal, i, w)
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: i
    real(dp), intent(in) :: w
    if (tal%n_log == LOG_LEN) call tally_flush(tal)
    tal%n_log = tal%n_log + 1
    tal%log_at(tal%n_log) = i
    tal%log_w(tal%n_log) = w
  end subroutine log_score

  subroutine stats_init(st, lay)
    type(stats_t), intent(out) :: st
    type(tally_layout_t), intent(in) :: lay
    allocate (st%s1(lay%n), st%s2(lay%n))
    st%s1 = 0.0_dp
    st%s2 = 0.0_dp
  end subroutine stats_init

  !> Add one finished batch of `n_photons` photons. Per-column quantities are scaled by the number
  !> of columns so that they are fluxes per unit column area normalised like the domain means;
  !> camera pixels carry their own normalisation and are divided by the photons only.
  subroutine stats_add_batch(st, lay, tal, n_photons)
    type(stats_t), intent(inout) :: st
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(in) :: tal
    integer(i8), intent(in) :: n_photons
    real(dp) :: scale_dom, scale_col
    real(dp), allocatable :: xd(:), a(:), h(:)
    integer :: nz, c, kr, ib, it, n, o
    nz = lay%nz
    scale_dom = 1.0_dp/real(n_photons, dp)
    scale_col = real(lay%ncol, dp)/real(n_photons, dp)
    xd = tal%buf(1:lay%i_map_up)*scale_dom
    ! derived quantities, formed per batch so that their standard errors include correlations
    xd(lay%i_dn + 1:lay%i_dn + nz + 1) = xd(lay%i_dir + 1:lay%i_dir + nz + 1) + &
                                         xd(lay%i_dif + 1:lay%i_dif + nz + 1)
    xd(lay%i_atm + 1) = sum(xd(lay%i_abs + 1:lay%i_abs + nz))
    xd(lay%i_closure + 1) = xd(lay%i_up + nz + 1) + xd(lay%i_atm + 1) + xd(lay%i_sfc + 1) &
                            - xd(lay%i_rr + 1) + xd(lay%i_lost + 1)
    ! with emission, photons carry unequal launch weights: the closure is relative to them
    if (lay%thermal) then
      xd(lay%i_closure + 1) = xd(lay%i_closure + 1)/xd(lay%i_src + 1)
    else if (lay%weighted) then
      ! broadband shortwave: a batch lets in mu0 TSI on average (with gpoint, the g-point's
      ! share), exactly only when every g-point is drawn its expected number of times
      xd(lay%i_closure + 1) = xd(lay%i_closure + 1)/xd(lay%i_dn + nz + 1)
    end if
    xd(lay%i_fnet + 1:lay%i_fnet + nz + 1) = xd(lay%i_dn + 1:lay%i_dn + nz + 1) - &
                                             xd(lay%i_up + 1:lay%i_up + nz + 1)
    st%s1(1:lay%i_map_up) = st%s1(1:lay%i_map_up) + xd
    st%s2(1:lay%i_map_up) = st%s2(1:lay%i_map_up) + xd*xd
    n = lay%i_cam0 - lay%i_map_up
    call add_moments(n, st%s1(lay%i_map_up + 1:), st%s2(lay%i_map_up + 1:), &
                     tal%buf(lay%i_map_up + 1:), scale_col)
    n = lay%i_col_abs - lay%i_cam0
    call add_moments(n, st%s1(lay%i_cam0 + 1:), st%s2(lay%i_cam0 + 1:), &
                     tal%buf(lay%i_cam0 + 1:), scale_dom)
    if (lay%do_budget) then
      ! per column: A = sum of its voxels; H = net flux in at the top - net flux out at the
      ! bottom - A (zero in every column when nothing moves sideways and no roulette acts).
      ! The voxels are summed layer by layer into a(:), each column's in the order kr = 1, 2, ...
      ib = (lay%budget_slot(1) - 1)*lay%ncol
      it = (lay%budget_slot(2) - 1)*lay%ncol
      allocate (a(lay%ncol), h(lay%ncol))
      a = 0.0_dp
      do kr = 1, lay%n3
        o = lay%i_vox + (kr - 1)*lay%ncol
        a = a + tal%buf(o + 1:o + lay%ncol)
      end do
      do c = 1, lay%ncol
        h(c) = tal%buf(lay%i_map_dir + it + c) + tal%buf(lay%i_map_dif + it + c) &
               - tal%buf(lay%i_map_up + it + c) &
               - (tal%buf(lay%i_map_dir + ib + c) + tal%buf(lay%i_map_dif + ib + c) &
                  - tal%buf(lay%i_map_up + ib + c)) - a(c)
      end do
      call add_moments(lay%ncol, st%s1(lay%i_col_abs + 1:), st%s2(lay%i_col_abs + 1:), a, &
                       scale_col)
      call add_moments(lay%ncol, st%s1(lay%i_htr + 1:), st%s2(lay%i_htr + 1:), h, scale_col)
    end if
    if (lay%do_maps) then
      ! total downward flux per column, per batch, so that its standard error is exact
      n = lay%n_map*lay%ncol
      call add_moments_sum(n, st%s1(lay%i_map_dn + 1:), st%s2(lay%i_map_dn + 1:), &
                           tal%buf(lay%i_map_dir + 1:), tal%buf(lay%i_map_dif + 1:), scale_col)
    end if
    st%n_batches = st%n_batches + 1_i8
    st%n_photons = st%n_photons + n_photons
    st%anomalies = st%anomalies + tal%anomalies
    st%work = st%work + tal%work
  end subroutine stats_add_batch

  !> s1 += x, s2 += x*x with x = b*scale, for n values (separate dummies: the compiler knows
  !> they do not overlap and may work on several values at once; each value is formed as in
  !> a loop over one)
  pure subroutine add_moments(n, s1, s2, b, scale)
    integer, intent(in) :: n
    real(dp), intent(inout) :: s1(n), s2(n)
    real(dp), intent(in) :: b(n), scale
    real(dp) :: x
    integer :: i
    do i = 1, n
      x = b(i)*scale
      s1(i) = s1(i) + x
      s2(i) = s2(i) + x*x
    end do
  end subroutine add_moments

  !> The same with x = (b(i) + c(i))*scale.
  pure subroutine add_moments_sum(n, s1, s2, b, c, scale)
    integer, intent(in) :: n
    real(dp), intent(inout) :: s1(n), s2(n)
    real(dp), intent(in) :: b(n), c(n), scale
    real(dp) :: x
    integer :: i
    do i = 1, n
      x = (b(i) + c(i))*scale
      s1(i) = s1(i) + x
      s2(i) = s2(i) + x*x
    end do
  end subroutine add_moments_sum

  !> The energy budget of one batch's tally, summed over its photons: reflected (up at the top),
  !> transmitted (down at the surface, direct + diffuse) and absorbed in the atmosphere.
  pure function batch_budget(lay, tal) result(b)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(in) :: tal
    real(dp) :: b(3)
    b(1) = tal%buf(lay%i_up + lay%nz + 1)
    b(2) = tal%buf(lay%i_dir + 1) + tal%buf(lay%i_dif + 1)
    b(3) = sum(tal%buf(lay%i_abs + 1:lay%i_abs + lay%nz))
  end function batch_budget

  !> Mean over batches of entries lo..hi (1-based buffer positions).
  pure function stats_mean(st, lo, hi) result(m)
    type(stats_t), intent(in) :: st
    integer, intent(in) :: lo, hi
    real(dp) :: m(hi - lo + 1)
    m = st%s1(lo:hi)/real(max(1_i8, st%n_batches), dp)
  end function stats_mean

  !> Standard error of the mean over batches: sqrt((<x^2> - <x>^2)/(B - 1)).
  !>
  !> The difference <x^2> - <x>^2 is resolved only to a few units of epsilon * <x>^2; below
  !> 16 epsilon <x>^2 (a relative batch spread under 6e-8, far below any Monte Carlo noise
  !> here) it is round-off of a quantity that is the same in every batch, such as the energy
  !> closure or the incident flux, and its standard error is 0.
  pure function stats_stderr(st, lo, hi) result(e)
    type(stats_t), intent(in) :: st
    integer, intent(in) :: lo, hi
    real(dp) :: e(hi - lo + 1)
    real(dp) :: b, m, v
    integer :: i
    b = real(st%n_batches, dp)
    if (st%n_batches < 2_i8) then
      e = 0.0_dp
      return
    end if
    ! without a branch, so that several values are formed at once (abs keeps the root's
    ! argument >= 0 where its value is not taken, and a NaN a NaN)
    do i = lo, hi
      m = st%s1(i)/b
      v = st%s2(i)/b - m*m
      e(i - lo + 1) = merge(0.0_dp, sqrt(abs(v)/(b - 1.0_dp)), &
                            v <= 16.0_dp*epsilon(1.0_dp)*m*m)
    end do
  end function stats_stderr
  ! ---- Scoring: one procedure per kind of score. Weights are in units of the photon weight;
  ! ---- positions of columns are icol = ix + (iy - 1) nx, of voxels (kr - 1) ncol + icol.

  !> Weight `w` crossing level k (0..nz): upward if `up`, else downward, direct when `order`
  !> is 0 and diffuse otherwise (domain mean; see score_flux_map for the per-column maps).
  pure subroutine score_flux(lay, tal, k, up, order, w)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: k, order
    logical, intent(in) :: up
    real(dp), intent(in) :: w
    integer :: i
    if (up) then
      i = lay%i_up + k + 1
    else if (order == 0) then
      i = lay%i_dir + k + 1
    else
      i = lay%i_dif + k + 1
    end if
    tal%buf(i) = tal%buf(i) + w
  end subroutine score_flux

  !> The same crossing in the flux map of column icol; `slot` = lay%map_slot(k) > 0 (levels
  !> with maps only). Large maps are scored through the log (see tally_t).
  pure subroutine score_flux_map(lay, tal, slot, up, order, icol, w)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: slot, order, icol
    logical, intent(in) :: up
    real(dp), intent(in) :: w
    integer :: i
    if (up) then
      i = lay%i_map_up
    else if (order == 0) then
      i = lay%i_map_dir
    else
      i = lay%i_map_dif
    end if
    i = i + (slot - 1)*lay%ncol + icol
    if (lay%log_maps) then
      call log_score(tal, i, w)
    else
      tal%buf(i) = tal%buf(i) + w
    end if
  end subroutine score_flux_map

  !> Weight `a` absorbed in layer k (1..nz).
  pure subroutine score_layer_abs(lay, tal, k, a)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: k
    real(dp), intent(in) :: a
    tal%buf(lay%i_abs + k) = tal%buf(lay%i_abs + k) + a
  end subroutine score_layer_abs

  !> Weight `a` absorbed in voxel (kr, icol) of the 3-D region; nothing without voxel tallies.
  !> In a large region (lay%log_voxel) every voxel score, at collisions and along paths alike,
  !> goes through the log (tally_t), so each voxel still receives its additions in the order
  !> they were scored.
  pure subroutine score_voxel_abs(lay, tal, kr, icol, a)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: kr, icol
    real(dp), intent(in) :: a
    integer :: i
    if (.not. lay%do_voxel) return
    i = lay%i_vox + (kr - 1)*lay%ncol + icol
    if (lay%log_voxel) then
      call log_score(tal, i, a)
    else
      tal%buf(i) = tal%buf(i) + a
    end if
  end subroutine score_voxel_abs

  !> Weight `a` absorbed by the surface.
  pure subroutine score_surface_abs(lay, tal, a)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    real(dp), intent(in) :: a
    tal%buf(lay%i_sfc + 1) = tal%buf(lay%i_sfc + 1) + a
  end subroutine score_surface_abs

  !> Net weight `dw` created (negative: destroyed) by Russian roulette, a DDIS split, or the
  !> balance of expected-value absorption scores against the weight lost at collisions: the
  !> term of the energy closure that is zero in expectation.
  pure subroutine score_roulette(lay, tal, dw)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    real(dp), intent(in) :: dw
    tal%buf(lay%i_rr + 1) = tal%buf(lay%i_rr + 1) + dw
  end subroutine score_roulette

  !> Weight `w` of a photon stopped at a loop cap (counted, never silently dropped).
  pure subroutine score_lost(lay, tal, w)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    real(dp), intent(in) :: w
    tal%buf(lay%i_lost + 1) = tal%buf(lay%i_lost + 1) + w
  end subroutine score_lost

  !> Launch weight `w` of a photon (thermal emission: photons start with unequal weights).
  pure subroutine score_source(lay, tal, w)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    real(dp), intent(in) :: w
    tal%buf(lay%i_src + 1) = tal%buf(lay%i_src + 1) + w
  end subroutine score_source

  !> Net power `x` (absorbed - emitted, kumo_emission) of layer k (1..nz).
  pure subroutine score_net_layer(lay, tal, k, x)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: k
    real(dp), intent(in) :: x
    tal%buf(lay%i_net + k) = tal%buf(lay%i_net + k) + x
  end subroutine score_net_layer

  !> Net power `x` of the surface.
  pure subroutine score_net_surface(lay, tal, x)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    real(dp), intent(in) :: x
    tal%buf(lay%i_snet + 1) = tal%buf(lay%i_snet + 1) + x
  end subroutine score_net_surface

  !> Net power `x` of voxel iv = (kr - 1) ncol + icol; nothing without voxel tallies.
  pure subroutine score_net_voxel(lay, tal, iv, x)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: iv
    real(dp), intent(in) :: x
    if (.not. lay%do_voxel) return
    tal%buf(lay%i_vnet + iv) = tal%buf(lay%i_vnet + iv) + x
  end subroutine score_net_voxel

  !> Radiance sample `v` (pi I per unit incident flux) in direction d at the radiance level of
  !> `slot` (= lay%rad_slot(k) > 0), domain mean.
  pure subroutine score_radiance(lay, tal, d, slot, v)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: d, slot
    real(dp), intent(in) :: v
    integer :: i
    i = lay%i_rad + (d - 1)*lay%n_rad_lev + slot
    tal%buf(i) = tal%buf(i) + v
  end subroutine score_radiance

  !> The same sample in the radiance map of column icol (when lay%do_rad_maps).
  pure subroutine score_radiance_map(lay, tal, d, slot, icol, v)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: d, slot, icol
    real(dp), intent(in) :: v
    integer :: i
    i = lay%i_rad_map + ((d - 1)*lay%n_rad_lev + slot - 1)*lay%ncol + icol
    tal%buf(i) = tal%buf(i) + v
  end subroutine score_radiance_map

  !> Sample `v` in every column of the block ix1..ix2 x iy1..iy2 of the radiance map of
  !> direction d at `slot` (1 <= ix1 <= ix2 <= map_nx, 1 <= iy1 <= iy2 <= rows; a block that
  !> wraps around the periodic edges comes as up to four blocks), for lay%rad_map_blocks: as
  !> the corners of its 2-D difference, +v at (ix1, iy1), -v at (ix2+1, iy1) and (ix1, iy2+1),
  !> +v at (ix2+1, iy2+1), those beyond the map's last column or row left out (the running
  !> sums of radiance_maps_integrate end there). Four additions whatever the block's size.
  pure subroutine score_radiance_map_block(lay, tal, d, slot, ix1, ix2, iy1, iy2, v)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: d, slot, ix1, ix2, iy1, iy2
    real(dp), intent(in) :: v
    integer :: i, nx
    logical :: right, below
    nx = lay%map_nx
    i = lay%i_rad_map + ((d - 1)*lay%n_rad_lev + slot - 1)*lay%ncol + (iy1 - 1)*nx + ix1
    right = ix2 < nx
    below = iy2*nx < lay%ncol
    tal%buf(i) = tal%buf(i) + v
    if (right) tal%buf(i + ix2 + 1 - ix1) = tal%buf(i + ix2 + 1 - ix1) - v
    if (below) then
      i = i + (iy2 + 1 - iy1)*nx
      tal%buf(i) = tal%buf(i) - v
      if (right) tal%buf(i + ix2 + 1 - ix1) = tal%buf(i + ix2 + 1 - ix1) + v
    end if
  end subroutine score_radiance_map_block

  !> End of a batch with lay%rad_map_blocks: every radiance map, scored as 2-D differences
  !> (score_radiance_map_block), becomes its values: running sums along each row, then down
  !> each column. Each value is the sum of the blocks over it, to round-off (sums of a few
  !> hundred terms of either sign); a column no block covered may keep a round-off residue
  !> instead of an exact zero.
  pure subroutine radiance_maps_integrate(lay, tal)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer :: m, i0, nx, ny, iy, i
    if (.not. lay%rad_map_blocks) return
    nx = lay%map_nx
    ny = lay%ncol/nx
    do m = 1, lay%n_rad_dir*lay%n_rad_lev
      i0 = lay%i_rad_map + (m - 1)*lay%ncol
      do iy = 1, ny
        i = i0 + (iy - 1)*nx
        call running_sum(tal%buf(i + 1:i + nx))
      end do
      do iy = 2, ny
        i = i0 + (iy - 1)*nx
        tal%buf(i + 1:i + nx) = tal%buf(i + 1:i + nx) + tal%buf(i + 1 - nx:i)
      end do
    end do
  contains
    pure subroutine running_sum(a)
      real(dp), intent(inout) :: a(:)
      integer :: j
      do j = 2, size(a)
        a(j) = a(j) + a(j - 1)
      end do
    end subroutine running_sum
  end subroutine radiance_maps_integrate

  !> Sample `v` of pixel ipix (1-based) of camera c.
  pure subroutine score_camera(lay, tal, c, ipix, v)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: c, ipix
    real(dp), intent(in) :: v
    tal%buf(lay%i_cam(c) + ipix) = tal%buf(lay%i_cam(c) + ipix) + v
  end subroutine score_camera
end module kumo_tally
