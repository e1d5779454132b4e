! SPDX-License-Identifier: BSD-3-Clause
!> The voxel atmosphere: levels, 1-D layers, the 3-D region, components and their optics.
!>
!> Layers are numbered 1..nz from the bottom; layer k lies between levels z(k-1) and z(k). The
!> 3-D region covers layers k3_lo..k3_hi with nx x ny columns over the periodic domain
!> [0, lx) x [0, ly). Each cell holds several components (extinction, single-scattering albedo,
!> phase function). Cells store what the photon loop needs: the total extinction, the mixture
!> single-scattering albedo, and the cumulative scattering fractions with which the scattering
!> component is chosen (seed text section 3.4.3, method b: weight times the mixture albedo, then
!> the scatterer drawn by its scattering coefficient).
!>
!> Each 1-D layer gets a class at setup so the photon loop does only the work it needs: clear
!> layers are crossed, purely absorbing layers attenuate the weight along the path, scattering
!> layers are traced analytically (their extinction is uniform, no null collisions), and 3-D
!> layers use the super-voxel majorant grid.
module kumo_atmosphere
  use, intrinsic :: iso_c_binding, only: c_ptr, c_f_pointer, c_loc
  use kumo_kinds, only: wp, vp, i8
  use, intrinsic :: iso_fortran_env, only: i1 => int8
  use kumo_error, only: error_t, set_error, str, add_context
  use kumo_phase, only: phase_t
  use kumo_truncation, only: truncation_t, truncation_init
  use kumo_supervoxel, only: supervoxel_grid_t, supervoxel_options_t, build_supervoxels, &
                             supervoxel_majorants, supervoxel_copy_layout
  implicit none
  private
  public :: atmosphere_t, atmosphere_options_t, atmosphere_init, atmosphere_set_truncation
  public :: atmosphere_refresh_truncation
  public :: similarity_blend_weight, similarity_tables, similarity_scale_1d
  public :: atmosphere_begin, atmosphere_put_layer, atmosphere_end, atmosphere_swap_background
  public :: EXT_MAX
  public :: column_of, column_xy, sigma_trunc_3d, voxel_ext, voxel_omg, voxel_layer, VOXEL_CLEAR
  public :: atmosphere_release, voxel_storage_i, voxel_sync_i, atmosphere_column_tau
  public :: LAYER_CLEAR, LAYER_ABSORBING, LAYER_SCATTERING, LAYER_3D, LAYER_CLASS_NAMES

  integer, parameter :: LAYER_CLEAR = 0, LAYER_ABSORBING = 1, LAYER_SCATTERING = 2, LAYER_3D = 3
  character(len=10), parameter :: LAYER_CLASS_NAMES(0:3) = &
                                  ['clear     ', 'absorbing ', 'scattering', '3-D       ']
  !> What ext3 and omg3 hold in a voxel without voxel components after a background swap: the
  !> voxel's extinction and albedo are then its layer's (clear3), which voxel_ext and voxel_omg
  !> return; every reader of the two arrays goes through them.
  real(vp), parameter :: VOXEL_CLEAR = -1.0_vp
  !> Similarity-scaled truncation has one level: no scattering counts as "into the peak"
  real(wp), parameter :: SIM_PF_PEAK = huge(1.0_wp)

  abstract interface
    !> Storage for the voxel arrays of an atmosphere, handed in by the caller (atmosphere_begin's
    !> `storage`): `base` receives the address of `nbytes` bytes (aligned for reals and integers)
    !> that stay valid as long as the atmosphere is used, and that the caller frees. `writer` is
    !> .true. on the one process that fills the values; the others see them after `sync`. The
    !> parallel layer gives one copy per node this way (kumo_parallel par_node_storage).
    subroutine voxel_storage_i(nbytes, base, writer)
      import :: c_ptr, i8
      implicit none
      integer(i8), intent(in) :: nbytes
      type(c_ptr), intent(out) :: base
      logical, intent(out) :: writer
    end subroutine voxel_storage_i
    !> Returns when the writer's values are visible to every process sharing the storage.
    subroutine voxel_sync_i()
      implicit none
    end subroutine voxel_sync_i
  end interface

  !> Setup choices; each fast path can be switched off to test that it changes nothing.
  type :: atmosphere_options_t
    logical :: use_1d_layers = .true.        !! .false.: every layer goes through the 3-D tracer
    logical :: use_absorbing_layers = .true. !! .false.: absorbing layers collide like others
    type(supervoxel_options_t) :: sv
    !> > 0: similarity-scaled truncation of forward peaks at this angle [deg] (see
    !> atmosphere_begin); 0: the optics as given
    real(wp) :: similarity_deg = 0.0_wp
  end type atmosphere_options_t

  type :: atmosphere_t
    integer :: nz = 0                        !! number of layers
    integer :: nx = 1, ny = 1                !! columns of the 3-D region
    integer :: k3_lo = 1, k3_hi = 0          !! layers of the 3-D region (empty if k3_hi < k3_lo)
    integer :: n3 = 0                        !! number of 3-D layers
    integer :: ncomp1 = 0                    !! components per 1-D layer
    integer :: ncomp = 0                     !! components per 3-D voxel (the 1-D ones present
                                             !! in the region first, then the scene file's)
    integer :: nc3 = 0                       !! components given per voxel
    integer :: kf_lo = 1, kf_hi = 0          !! layers whose voxels are given
    integer, allocatable :: act1(:)          !! 1-D components present in the 3-D region
    real(wp) :: lx = 1.0_wp, ly = 1.0_wp     !! domain size [m]
    real(wp) :: dx = 1.0_wp, dy = 1.0_wp     !! column size of the 3-D region [m]
    real(wp) :: inv_dx = 1.0_wp, inv_dy = 1.0_wp
    real(wp), allocatable :: z(:)            !! levels z(0:nz) [m]
    integer, allocatable :: layer_class(:)   !! LAYER_* per layer
    real(wp), allocatable :: ext1(:)         !! 1-D layers: total extinction [m-1]
    real(wp), allocatable :: omg1(:)         !! 1-D layers: mixture single-scattering albedo
    real(wp), allocatable :: csca1(:, :)     !! (ncomp1, nz) cumulative scattering fraction
    integer, allocatable :: iph1(:, :)       !! (ncomp1, nz) phase function per component
    ! The voxel arrays are pointers: to storage this atmosphere allocated and owns, or to
    ! storage handed in by the caller through atmosphere_begin's `storage` (e.g. one copy shared
    ! by the processes of a node), which the caller frees (see voxel_storage_i).
    real(vp), pointer, contiguous :: ext3(:, :, :) => null()  !! (nx, ny, n3) total extinction [m-1]
    real(vp), pointer, contiguous :: omg3(:, :, :) => null()  !! (nx, ny, n3) mixture albedo
    !> (ncomp - 1, nx, ny, n3) cumulative scattering fractions of components 1 .. ncomp - 1
    !> (the last ends at 1); associated only when ncomp > 1
    real(vp), pointer, contiguous :: csca3(:, :, :, :) => null()
    !> (ncomp, nx, ny, n3) phase function index; associated only when it varies between voxels
    integer, pointer, contiguous :: iph3(:, :, :, :) => null()
    !> (ncomp, nx, ny, n3) weight w of table iph + 1: the phase function is
    !> (1 - w) P(iph) + w P(iph + 1) (MCARaTS's fractional index); associated only when used
    real(vp), pointer, contiguous :: wph3(:, :, :, :) => null()
    logical :: voxels_borrowed = .false.     !! the voxel arrays live in the caller's storage
    logical :: voxel_writer = .true.         !! this process fills the voxel values (else it
                                             !! only reads what another process wrote)
    integer(i8) :: voxel_bytes_own = 0_i8    !! bytes of voxel arrays this process allocated
    integer(i8) :: voxel_bytes_borrowed = 0_i8  !! bytes of voxel arrays in the caller's storage
    integer, allocatable :: iph3_const(:)    !! (ncomp) phase index when it is the same everywhere
    type(phase_t), allocatable :: phases(:)  !! phase functions referenced by index
    type(supervoxel_grid_t) :: sv            !! majorant grid of the 3-D region
    logical, allocatable :: uniform3(:)      !! (n3) every voxel of the 3-D layer is the same
    !> The voxels with voxel components of each layer kr, as runs of consecutive columns
    !> (ix_first, ix_last, iy) in cloud_run(:, cloud_ptr(kr) + 1 : cloud_ptr(kr + 1)), found by
    !> the first atmosphere_swap_background after a build or at a new band (cloud_ptr not
    !> allocated), for every layer by every process: later swaps form only these, and the
    !> majorants take the others as one value per layer (clear3). clear_all (per block of the
    !> majorant grid): every layer of the block has a voxel without components; clear_part
    !> (2, n): (block, layer) where a block that is not clear_all has some. Both are found with
    !> the list.
    integer, allocatable :: cloud_ptr(:), cloud_run(:, :)
    !> (2 ncomp3, n) the listed voxels' components, extinction then albedo, in the order of the
    !> list, gathered from the band's arrays at its first swap (cloud_c not allocated), so that
    !> the swaps of its g-points read them side by side; run j starts at cloud_first(j). Only
    !> the layers this process forms (voxels shared by several processes).
    real(wp), allocatable :: cloud_c(:, :)
    integer, allocatable :: cloud_first(:)
    logical, allocatable :: clear_all(:)
    integer, allocatable :: clear_part(:, :)
    !> (2, n3) extinction and albedo of the voxels without components of each layer, where
    !> ext3 and omg3 hold VOXEL_CLEAR (allocated with the voxel arrays, 0 before a swap)
    real(vp), allocatable :: clear3(:, :)
    !> (ncomp - 1, n3) the scattering fractions of the voxels without components of each layer
    !> as this process's last swap wrote them, where clear_known: a swap writes only those that
    !> changed; where clear_known the voxels without components hold VOXEL_CLEAR
    real(vp), allocatable :: clear_last(:, :)
    logical, allocatable :: clear_known(:)
    !> Similarity-scaled truncation (atmosphere_options_t%similarity_deg): the optics are
    !> those of the truncated medium, and photons scatter with the normalised truncated phase
    !> functions of level 2 of `sim`
    logical :: similar = .false.
    type(truncation_t) :: sim
    !> what `sim` was formed from (similarity_key): a new build over the same phase functions
    !> and angle takes it over instead of forming it again (broadband runs rebuild per g-point)
    real(wp), allocatable :: sim_key(:)
    ! Truncation of forward peaks (set by atmosphere_set_truncation; off by default)
    logical :: truncated = .false.           !! truncation levels > 1 exist
    type(truncation_t) :: trunc              !! delta fractions per level and phase function
    real(wp), allocatable :: ext1_lev(:, :)  !! (nz, n_levels) truncated extinction of 1-D layers
  end type atmosphere_t

  !> Largest extinction accepted [m-1]: a mean free path of 1 um. No atmosphere is that dense,
  !> and far denser media (1e13 m-1 over a 1 km column) make free paths shorter than the
  !> spacing of double-precision heights, so photons would stop moving: refused, not traced.
  real(wp), parameter :: EXT_MAX = 1.0e6_wp

contains

  !> Build the atmosphere from per-component optics.
  !>
  !> `ext1d`, `ssa1d`, `iph1d` are (nz, ncomp1) and describe every layer; inside the 3-D region
  !> they are added to the voxel components `ext3d`, `ssa3d`, `iph3d` (nx, ny, n3, ncomp3), as a
  !> background (e.g. molecules around a cloud). This is `atmosphere_begin`, one
  !> `atmosphere_put_layer` per component and layer, and `atmosphere_end`. With `storage` and
  !> `sync` the voxel arrays lie in the caller's storage, which only its writer fills: the
  !> other processes pass the fields' shape `n3d` instead of the fields.
  subroutine atmosphere_init(atm, z, lx, ly, ext1d, ssa1d, iph1d, phases, opts, error, &
                             k3_lo, ext3d, ssa3d, iph3d, iph3_const, n3d, storage, sync)
    type(atmosphere_t), intent(inout) :: atm   !! built anew (its old voxel arrays released)
    real(wp), intent(in) :: z(0:)              !! levels [m], strictly increasing
    real(wp), intent(in) :: lx, ly             !! domain size [m]
    real(wp), intent(in) :: ext1d(:, :)        !! (nz, ncomp1) extinction [m-1]
    real(wp), intent(in) :: ssa1d(:, :)        !! (nz, ncomp1) single-scattering albedo
    integer, intent(in) :: iph1d(:, :)         !! (nz, ncomp1) phase-function index
    type(phase_t), intent(in) :: phases(:)     !! the phase functions
    type(atmosphere_options_t), intent(in) :: opts
    type(error_t), allocatable, intent(out) :: error
    integer, intent(in), optional :: k3_lo     !! lowest layer of the 3-D region
    real(wp), intent(in), optional :: ext3d(:, :, :, :)  !! (nx, ny, n3, ncomp3) [m-1]
    real(wp), intent(in), optional :: ssa3d(:, :, :, :)
    integer, intent(in), optional :: iph3d(:, :, :, :)
    !> (ncomp3) without iph3d: the phase index of every voxel of each component (default 1)
    integer, intent(in), optional :: iph3_const(:)
    !> the shape of the 3-D fields, for a process that does not hold them: with `storage`, one
    !> that is not the storage's writer (it only takes part in building the scene)
    integer, intent(in), optional :: n3d(4)
    procedure(voxel_storage_i), optional :: storage  !! the caller's storage (atmosphere_begin)
    procedure(voxel_sync_i), optional :: sync        !! with `storage` (atmosphere_end)
    type(phase_t), allocatable :: ph(:)
    integer :: ic, kf, shp(4)
    integer, allocatable :: one(:, :)

    ph = phases
    if (present(k3_lo) .and. (present(n3d) .or. (present(ext3d) .and. present(ssa3d)))) then
      if (present(n3d)) then
        shp = n3d
      else
        shp = shape(ext3d)
      end if
      call atmosphere_begin(atm, z, lx, ly, ext1d, ssa1d, iph1d, ph, opts, error, k3_lo, &
                            shp(1), shp(2), shp(3), shp(4), storage=storage)
      if (allocated(error)) return
      if (atm%voxel_writer) then
        if (.not. present(iph3d)) allocate (one(shp(1), shp(2)), source=1)
        do ic = 1, shp(4)
          if (.not. present(iph3d) .and. present(iph3_const)) one = iph3_const(ic)
          do kf = 1, shp(3)
            if (present(iph3d)) then
              call atmosphere_put_layer(atm, ic, kf, ext3d(:, :, kf, ic), ssa3d(:, :, kf, ic), &
                                        iph3d(:, :, kf, ic))
            else
              call atmosphere_put_layer(atm, ic, kf, ext3d(:, :, kf, ic), ssa3d(:, :, kf, ic), one)
            end if
          end do
        end do
      end if
    else
      call atmosphere_begin(atm, z, lx, ly, ext1d, ssa1d, iph1d, ph, opts, error)
      if (allocated(error)) return
    end if
    call atmosphere_end(atm, opts, error, sync=sync)
  end subroutine atmosphere_init

  !> First step of building an atmosphere whose voxels are given layer by layer: the levels, the
  !> 1-D layers and their classes, and the voxel arrays of the 3-D region, holding the 1-D
  !> components present there (the background). The 3-D region has `n3f` layers from `k3_lo`
  !> with `nc3` components on nx x ny columns; `blend` reserves a per-voxel weight for phase
  !> functions that blend two consecutive tables. `phases` is moved into the atmosphere.
  !> Then `atmosphere_put_layer` for every component and layer, then `atmosphere_end`.
  !> With `storage` the voxel arrays are placed in the caller's storage (voxel_storage_i): only
  !> its writer fills them (background, put_layer, atmosphere_end's values), and every process
  !> passes atmosphere_end the `sync` that makes the writer's values visible to it.
  subroutine atmosphere_begin(atm, z, lx, ly, ext1d, ssa1d, iph1d, phases, opts, error, &
                              k3_lo, nx, ny, n3f, nc3, blend, storage)
    type(atmosphere_t), intent(inout) :: atm   !! built anew (its old voxel arrays released)
    real(wp), intent(in) :: z(0:)              !! levels [m], strictly increasing
    real(wp), intent(in) :: lx, ly             !! domain size [m]
    real(wp), intent(in) :: ext1d(:, :)        !! (nz, ncomp1) extinction [m-1]
    real(wp), intent(in) :: ssa1d(:, :)        !! (nz, ncomp1) single-scattering albedo
    integer, intent(in) :: iph1d(:, :)         !! (nz, ncomp1) phase-function index
    type(phase_t), allocatable, intent(inout) :: phases(:)  !! the phase functions (moved)
    type(atmosphere_options_t), intent(in) :: opts
    type(error_t), allocatable, intent(out) :: error
    integer, intent(in), optional :: k3_lo     !! lowest layer of the 3-D region
    integer, intent(in), optional :: nx, ny    !! columns of the 3-D region
    integer, intent(in), optional :: n3f, nc3  !! layers and components given per voxel
    logical, intent(in), optional :: blend     !! some voxels blend two phase tables
    procedure(voxel_storage_i), optional :: storage  !! the caller's storage for the voxels
    integer :: nz, k, ic, nc1, klo, khi, ncomp, na1, kr
    real(wp) :: e, s
    real(wp), allocatable :: x1(:, :), a1(:, :)
    real(vp), allocatable :: bg_sca(:)
    integer, allocatable :: bg_iph(:)
    logical :: with_blend, reuse
    type(atmosphere_t) :: fresh
    type(truncation_t) :: prev_sim
    real(wp), allocatable :: prev_key(:), key(:)

    if (atm%similar .and. allocated(atm%sim_key)) then
      prev_sim = atm%sim
      prev_key = atm%sim_key
    end if
    call atmosphere_release(atm)
    atm = fresh
    nz = size(z) - 1
    nc1 = size(ext1d, 2)
    if (nz < 1) then
      call set_error(error, 'atmosphere: at least one layer is needed')
      return
    end if
    do k = 1, nz
      if (.not. (z(k) > z(k - 1))) then
        call set_error(error, 'atmosphere: levels must increase strictly (z_levels('// &
                       str(k)//') <= z_levels('//str(k - 1)//'))')
        return
      end if
    end do
    if (any(iph1d < 1) .or. any(iph1d > size(phases))) then
      call set_error(error, 'atmosphere: a 1-D phase-function index is outside 1..'// &
                     str(size(phases)))
      return
    end if
    atm%nz = nz
    atm%z = z
    atm%lx = lx
    atm%ly = ly
    atm%ncomp1 = nc1
    call move_alloc(phases, atm%phases)
    x1 = ext1d
    a1 = ssa1d
    if (opts%similarity_deg > 0.0_wp) then
      ! Similarity-scaled truncation: the delta part f of each phase function's forward peak
      ! (delta-flat within similarity_deg) leaves the extinction, tau' = tau (1 - omega f),
      ! omega' = omega (1 - f)/(1 - omega f), and photons scatter with the normalised rest
      key = similarity_key(atm%phases, opts%similarity_deg)
      reuse = .false.
      if (allocated(prev_key)) then
        if (size(prev_key) == size(key)) reuse = all(prev_key == key)
      end if
      if (reuse) then
        atm%sim = prev_sim
      else
        call similarity_tables(atm%phases, opts%similarity_deg, atm%sim, error)
        if (allocated(error)) return
      end if
      call move_alloc(key, atm%sim_key)
      atm%similar = .true.
      call similarity_scale_1d(atm%sim, iph1d, x1, a1)
    end if

    ! 1-D layers: totals and cumulative scattering fractions
    allocate (atm%ext1(nz), atm%omg1(nz), atm%csca1(max(nc1, 1), nz), atm%iph1(max(nc1, 1), nz))
    atm%iph1 = 1
    do k = 1, nz
      call mix(x1(k, :), a1(k, :), atm%ext1(k), atm%omg1(k), atm%csca1(1:nc1, k))
      atm%iph1(1:nc1, k) = iph1d(k, :)
      if (atm%ext1(k) > EXT_MAX) then
        call set_error(error, 'atmosphere: layer '//str(k)//' has an extinction of '// &
                       str(atm%ext1(k))//too_dense())
        return
      end if
    end do

    atm%nc3 = 0
    atm%kf_lo = 1     ! layers whose voxels are given (none if kf_hi < kf_lo)
    atm%kf_hi = 0
    if (present(k3_lo) .and. present(nx) .and. present(ny) .and. present(n3f) .and. &
        present(nc3)) then
      klo = k3_lo
      khi = k3_lo + n3f - 1
      atm%kf_lo = klo
      atm%kf_hi = khi
      atm%nx = nx
      atm%ny = ny
      atm%nc3 = nc3
      if (klo < 1 .or. khi > nz) then
        call set_error(error, 'atmosphere: the 3-D region (layers '//str(klo)//'..'// &
                       str(khi)//') must lie within layers 1..'//str(nz))
        return
      end if
    else
      klo = 1
      khi = 0
    end if
    if (.not. opts%use_1d_layers) then
      ! Every layer goes through the 3-D tracer: the region is widened to the whole column.
      klo = 1
      khi = nz
    end if
    atm%k3_lo = klo
    atm%k3_hi = khi
    atm%n3 = max(0, khi - klo + 1)
    atm%dx = lx/atm%nx
    atm%dy = ly/atm%ny
    atm%inv_dx = atm%nx/lx
    atm%inv_dy = atm%ny/ly

    allocate (atm%layer_class(nz))
    do k = 1, nz
      atm%layer_class(k) = class_of_layer(atm, k, opts)
    end do
    if (atm%n3 == 0) return

    ! 1-D components that are empty throughout the region (e.g. no molecules given in cloud
    ! layers) are left out of the voxels: no choice of scatterer, no storage for them.
    atm%act1 = pack([(ic, ic=1, nc1)], [(any(x1(klo:khi, ic) > 0.0_wp), ic=1, nc1)])
    na1 = size(atm%act1)
    ncomp = na1 + atm%nc3
    atm%ncomp = ncomp
    ! While the layers are put, ext3 sums the extinction, omg3 the scattering coefficient and
    ! csca3 holds each component's scattering coefficient (the last component's is the rest);
    ! atmosphere_end turns them into the albedo and the cumulative fractions.
    with_blend = .false.
    if (present(blend)) with_blend = blend
    call voxel_arrays(atm, with_blend, storage)
    if (.not. atm%voxel_writer) return
    if (with_blend) atm%wph3 = 0.0_vp
    ! the background is the same in every voxel of a layer: its values once per layer
    allocate (bg_sca(max(ncomp - 1, 1)), bg_iph(ncomp))
    do kr = 1, atm%n3
      k = klo + kr - 1
      e = 0.0_wp
      s = 0.0_wp
      bg_sca = 0.0_vp
      bg_iph = 1
      do ic = 1, na1
        e = e + x1(k, atm%act1(ic))
        s = s + x1(k, atm%act1(ic))*a1(k, atm%act1(ic))
        if (ic < ncomp) bg_sca(ic) = real(x1(k, atm%act1(ic))*a1(k, atm%act1(ic)), vp)
        bg_iph(ic) = iph1d(k, atm%act1(ic))
      end do
      atm%ext3(:, :, kr) = real(e, vp)
      atm%omg3(:, :, kr) = real(s, vp)
      ! by component (a loop over the few components inside would become a call of memcpy)
      do ic = 1, ncomp
        atm%iph3(ic, :, :, kr) = bg_iph(ic)
      end do
      do ic = 1, ncomp - 1
        atm%csca3(ic, :, :, kr) = bg_sca(ic)
      end do
    end do
  end subroutine atmosphere_begin

  !> Put layer `kf` (1..n3f of atmosphere_begin) of 3-D component `ic` (1..nc3): extinction
  !> [m-1], single-scattering albedo and phase-function index per column, and optionally the
  !> weight w of table iph + 1 in the blend P = (1 - w) P(iph) + w P(iph + 1).
  subroutine atmosphere_put_layer(atm, ic, kf, ext, ssa, iph, wph)
    type(atmosphere_t), intent(inout) :: atm
    integer, intent(in) :: ic, kf
    real(wp), intent(in) :: ext(:, :), ssa(:, :)   !! (nx, ny)
    integer, intent(in) :: iph(:, :)               !! (nx, ny)
    real(wp), intent(in), optional :: wph(:, :)    !! (nx, ny) in [0, 1]
    integer :: kr, icc, ix, iy
    real(wp) :: sca, e, a, w
    if (.not. atm%voxel_writer) return
    kr = atm%kf_lo + kf - 1 - atm%k3_lo + 1
    icc = size(atm%act1) + ic
    do iy = 1, atm%ny
      do ix = 1, atm%nx
        e = ext(ix, iy)
        a = ssa(ix, iy)
        if (atm%similar) then
          w = 0.0_wp
          if (present(wph)) w = wph(ix, iy)
          call similarity_scale(similarity_f(atm%sim, iph(ix, iy), w), e, a)
        end if
        sca = e*a
        atm%ext3(ix, iy, kr) = real(atm%ext3(ix, iy, kr) + e, vp)
        atm%omg3(ix, iy, kr) = real(atm%omg3(ix, iy, kr) + sca, vp)
        if (icc < atm%ncomp) atm%csca3(icc, ix, iy, kr) = real(sca, vp)
        atm%iph3(icc, ix, iy, kr) = iph(ix, iy)
      end do
    end do
    if (present(wph) .and. associated(atm%wph3)) atm%wph3(icc, :, :, kr) = real(wph, vp)
  end subroutine atmosphere_put_layer

  !> Last step: albedo and cumulative scattering fractions from the sums, checks of the phase
  !> indices, storage dropped where nothing varies, the super-voxel grid.
  !> With `sv_layout` (the super-voxel grid of an earlier atmosphere of the same region) the
  !> grid keeps those blocks and only takes the new majorants (supervoxel_majorants).
  !> Voxels in the caller's storage: its writer forms the values, then every process calls
  !> `sync` and derives the rest (checks, super-voxel grid) from the same values.
  subroutine atmosphere_end(atm, opts, error, sv_layout, sync)
    type(atmosphere_t), intent(inout) :: atm
    type(atmosphere_options_t), intent(in) :: opts
    type(error_t), allocatable, intent(out) :: error
    type(supervoxel_grid_t), intent(in), optional :: sv_layout
    procedure(voxel_sync_i), optional :: sync   !! needed with atmosphere_begin's `storage`
    integer :: ic, kr, nc, np, klo, khi
    real(vp) :: no_csca(1, 1, 1)
    logical :: varies, bad_index, bad_weight, bad_blend, blended

    if (atm%n3 == 0) return
    nc = atm%ncomp
    np = size(atm%phases)
    ! the values first (they read neither the phase indices nor the blend weights)
    if (atm%voxel_writer) then
      do kr = 1, atm%n3
        if (nc > 1) then
          call normalise_layer(atm%ext3(:, :, kr), atm%omg3(:, :, kr), atm%csca3(:, :, :, kr))
        else
          call normalise_layer(atm%ext3(:, :, kr), atm%omg3(:, :, kr), no_csca)
        end if
      end do
    end if
    if (present(sync)) call sync()
    ! the indices and blend weights, in one pass
    call index_checks(atm%iph3, atm%wph3, np, bad_index, bad_weight, bad_blend, blended)
    if (bad_index) then
      call set_error(error, 'atmosphere: a 3-D phase-function index is outside 1..'//str(np))
      return
    end if
    if (associated(atm%wph3)) then
      if (bad_weight) then
        call set_error(error, 'atmosphere: a phase-function blend weight is outside 0..1 or NaN')
        return
      end if
      if (bad_blend) then
        call set_error(error, 'atmosphere: a phase-function blend needs table iph + 1 > '// &
                       str(np))
        return
      end if
      if (.not. blended) call drop_real(atm%voxels_borrowed, atm%wph3)
    end if
    ! A phase index that is the same in every voxel is stored once.
    atm%iph3_const = atm%iph3(:, 1, 1, 1)
    varies = associated(atm%wph3)
    do ic = 1, nc
      if (any(atm%iph3(ic, :, :, :) /= atm%iph3_const(ic))) varies = .true.
    end do
    if (.not. varies) call drop_int(atm%voxels_borrowed, atm%iph3)

    klo = atm%k3_lo
    khi = atm%k3_hi
    if (present(sv_layout)) then
      call supervoxel_majorants(atm%ext3, sv_layout, atm%sv)
    else
      call build_supervoxels(atm%ext3, atm%dx, atm%dy, atm%z(klo:khi) - atm%z(klo - 1:khi - 1), &
                             opts%sv, atm%sv)
    end if
    if (size(atm%sv%maj) > 0) then
      if (maxval(atm%sv%maj) > EXT_MAX) then
        call set_error(error, 'atmosphere: a voxel has an extinction of '// &
                       str(maxval(atm%sv%maj))//too_dense())
        return
      end if
    end if
    call set_uniform3(atm)

  contains

    !> The albedo and cumulative scattering fractions of the voxels of layer kr from their
    !> summed extinction, scattering and per-component scattering (the layer's arrays as
    !> dummies, so that the compiler keeps their addresses in registers).
    subroutine normalise_layer(ext_l, omg_l, csca_l)
      real(vp), intent(in) :: ext_l(:, :)
      real(vp), intent(inout) :: omg_l(:, :)
      real(vp), intent(inout) :: csca_l(:, :, :)   !! (nc - 1, nx, ny); not touched if nc = 1
      integer :: ix, iy, ic
      real(wp) :: ext_tot, sca_tot, acc
      do iy = 1, size(ext_l, 2)
        do ix = 1, size(ext_l, 1)
          ext_tot = ext_l(ix, iy)
          sca_tot = omg_l(ix, iy)
          if (ext_tot > 0.0_wp) then
            omg_l(ix, iy) = real(min(1.0_wp, sca_tot/ext_tot), vp)
          else
            omg_l(ix, iy) = 1.0_vp
          end if
          acc = 0.0_wp
          do ic = 1, nc - 1
            acc = acc + csca_l(ic, ix, iy)
            if (sca_tot > 0.0_wp) then
              csca_l(ic, ix, iy) = real(min(1.0_wp, acc/sca_tot), vp)
            else
              csca_l(ic, ix, iy) = real(real(ic, wp)/nc, vp)
            end if
          end do
        end do
      end do
    end subroutine normalise_layer
  end subroutine atmosphere_end

  !> Give an atmosphere built by atmosphere_begin, atmosphere_put_layer and atmosphere_end a new
  !> background: the 1-D components `ext1d`, `ssa1d` (nz, ncomp1) with the phase functions they
  !> had, and the voxel components as they were put (`cext`, `cssa`: (nx, ny, n3f, nc3),
  !> extinction [m-1] and albedo; their phase indices and blends stay). Every number is formed
  !> as the build would form it, in the same order, so the result is the atmosphere that
  !> begin/put/end would give (with the super-voxel blocks of `sv_layout` and new majorants),
  !> without allocating or checking anything again: broadband runs switch the gas of a
  !> g-point this way. `done` is .false. (and nothing changed) when a 1-D component that the
  !> build left out of the 3-D region, being empty there, is not empty now: build it anew.
  !> Voxels in the caller's storage (atmosphere_begin's `storage`) need `sync`, `part` and
  !> `nparts`: the `nparts` processes sharing them call this with the same arguments once none
  !> of them reads the old values, process `part` (0 .. nparts - 1) forms the layers
  !> kr = part + 1 + j nparts, and every process takes its 1-D layers and majorants after `sync`.
  !>
  !> With `new_band`, the voxel components are those of another band, with their own phase
  !> indices and blend weights (`ciph`, `cwph`, (nx, ny, n3f, nc3) as put by
  !> atmosphere_put_layer; with shared voxels every process reads them, and `sync` first makes
  !> the writer's new components visible). The phase functions of the atmosphere must hold every band's tables. The
  !> indices and weights are checked as atmosphere_end checks them, and the layers that are the
  !> same in every voxel are found again. `done` is .false. when a build would store the voxels
  !> otherwise (no blend weights, or a phase index that does not vary) or would fail: then
  !> build anew (the voxel values are no longer those of either band). A caller that switches
  !> to the same band and g-point again may pass what the first switch found: `checked` (the
  !> band's indices and weights passed), `uniform3` with `uniform3_known` (the uniform layers
  !> after that switch); the voxels are then the same and these checks are not repeated.
  !> `same_clear` says that the voxels whose components are all absent are those of the last
  !> swap, with the same phase indices and blend weights (a cloud file's voxels without water
  !> in every band): a new band then keeps the list of the others and writes only theirs.
  !> A voxel beyond EXT_MAX also gives `done` .false., so that the build refuses it.
  subroutine atmosphere_swap_background(atm, ext1d, ssa1d, cext, cssa, opts, sv_layout, done, &
                                        sync, part, nparts, new_band, ciph, cwph, checked, &
                                        uniform3, uniform3_known, same_clear)
    type(atmosphere_t), intent(inout) :: atm
    real(wp), intent(in) :: ext1d(:, :), ssa1d(:, :)
    real(wp), intent(in) :: cext(:, :, :, :), cssa(:, :, :, :)
    type(atmosphere_options_t), intent(in) :: opts
    type(supervoxel_grid_t), intent(in) :: sv_layout
    logical, intent(out) :: done
    procedure(voxel_sync_i), optional :: sync
    integer, intent(in), optional :: part, nparts
    logical, intent(in), optional :: new_band
    integer, intent(in), optional :: ciph(:, :, :, :)
    real(vp), intent(in), optional :: cwph(:, :, :, :)
    logical, intent(in), optional :: checked, uniform3(:), uniform3_known, same_clear
    integer :: k, ic, kr, kf, na1, nc, nc1, nf
    real(wp) :: e, s
    real(vp) :: clr_e, clr_w, no_csca(1, 1, 1)
    real(vp), allocatable :: bg_sca(:), clr_c(:)
    real(wp), allocatable :: acc_bg(:), x1(:, :), a1(:, :)
    logical :: band, bad_index, bad_weight, bad_blend, blended
    done = .false.
    nc1 = atm%ncomp1
    band = .false.
    if (present(new_band)) band = new_band
    ! voxels in shared storage: formed by all the processes sharing them, seen after sync
    if (atm%voxels_borrowed .and. .not. (present(sync) .and. present(part) .and. &
                                         present(nparts))) return
    if (size(ext1d, 1) /= atm%nz .or. size(ext1d, 2) /= nc1) return
    if (atm%n3 > 0) then
      do ic = 1, nc1
        if (any(atm%act1 == ic)) cycle
        if (any(ext1d(atm%k3_lo:atm%k3_hi, ic) > 0.0_wp)) return
      end do
    end if
    if (band .and. atm%n3 > 0) then
      ! a build keeps the phase indices and blend weights per voxel only when blends occur
      if (.not. (associated(atm%iph3) .and. associated(atm%wph3))) return
      if (.not. (present(ciph) .and. present(cwph))) return
    end if
    done = .true.
    ! the 1-D components as atmosphere_begin takes them (similarity-scaled if the build was)
    x1 = ext1d
    a1 = ssa1d
    if (atm%similar) call similarity_scale_1d(atm%sim, transpose(atm%iph1(1:nc1, :)), x1, a1)
    do k = 1, atm%nz
      call mix(x1(k, :), a1(k, :), atm%ext1(k), atm%omg1(k), atm%csca1(1:nc1, k))
      atm%layer_class(k) = class_of_layer(atm, k, opts)
    end do
    if (atm%n3 == 0) return
    ! another band: other components, gathered again
    if (band .and. allocated(atm%cloud_c)) deallocate (atm%cloud_c)
    if (band .and. .not. present_and_true(same_clear)) then
      ! another band: other voxels may hold components
      if (allocated(atm%cloud_ptr)) deallocate (atm%cloud_ptr)
      if (allocated(atm%clear_known)) atm%clear_known = .false.
    end if
    if (band .and. atm%voxels_borrowed) then
      ! the writer's components of the band, seen by all, who then form a share of the layers
      call sync()
      call form_voxels(part, nparts)
    else if (atm%voxels_borrowed) then
      call form_voxels(part, nparts)
    else
      call form_voxels(0, 1)
    end if
    if (present(sync)) call sync()
    if (band) then
      ! what atmosphere_end finds of the indices and weights (every process, the same values)
      bad_index = .false.
      bad_weight = .false.
      bad_blend = .false.
      blended = .true.
      if (.not. present_and_true(checked)) &
        call band_checks(bad_index, bad_weight, bad_blend, blended)
      if (bad_index .or. bad_weight .or. bad_blend .or. .not. blended) then
        done = .false.
        return
      end if
      atm%iph3_const = atm%iph3(:, 1, 1, 1)
      if (present_and_true(uniform3_known) .and. present(uniform3)) then
        atm%uniform3 = uniform3
      else if (present_and_true(same_clear) .and. allocated(atm%uniform3)) then
        call set_uniform3(atm, keep=atm%cloud_ptr(2:atm%n3 + 1) == atm%cloud_ptr(1:atm%n3))
      else
        call set_uniform3(atm)
      end if
    end if
    call swap_majorants()
    ! a voxel denser than a build accepts (another band's cloud under the gas): the build
    ! that the caller then makes refuses it with atmosphere_end's message
    if (size(atm%sv%maj) > 0) then
      if (maxval(atm%sv%maj) > EXT_MAX) done = .false.
    end if

  contains

    !> index_checks of the layers with voxel components (the other layers' indices and
    !> weights are those of the last build, which checked them)
    subroutine band_checks(bad_index, bad_weight, bad_blend, blended)
      logical, intent(out) :: bad_index, bad_weight, bad_blend, blended
      integer :: klo, khi
      integer, pointer, contiguous :: ip(:, :, :, :)
      real(vp), pointer, contiguous :: wv(:, :, :, :)
      klo = max(1, atm%kf_lo - atm%k3_lo + 1)
      khi = min(atm%n3, atm%kf_hi - atm%k3_lo + 1)
      ip => atm%iph3(:, :, :, klo:khi)
      wv => atm%wph3(:, :, :, klo:khi)
      call index_checks(ip, wv, size(atm%phases), bad_index, bad_weight, bad_blend, blended)
    end subroutine band_checks

    !> The voxels of layers kr = p + 1, p + 1 + np, ... of the region; the clear values
    !> (clear3) and, once per band, the list of voxels with components, of every layer.
    subroutine form_voxels(p, np)
      integer, intent(in) :: p, np
      if (.not. allocated(atm%clear_known)) then
        allocate (atm%clear_last(atm%ncomp - 1, atm%n3), atm%clear_known(atm%n3))
        atm%clear_known = .false.
      end if
      na1 = size(atm%act1)
      nc = atm%ncomp
      nf = atm%kf_hi - atm%kf_lo + 1
      if (.not. allocated(atm%cloud_ptr)) call list_cloudy()
      if (.not. allocated(atm%cloud_c)) call gather_cloudy(p, np)
      allocate (bg_sca(max(nc - 1, 1)), acc_bg(0:na1), clr_c(max(nc - 1, 1)))
      do kr = 1, atm%n3
        k = atm%k3_lo + kr - 1
        kf = k - atm%kf_lo + 1          ! the layer of the voxel components, if any
        e = 0.0_wp
        s = 0.0_wp
        bg_sca = 0.0_vp
        do ic = 1, na1
          e = e + x1(k, atm%act1(ic))
          s = s + x1(k, atm%act1(ic))*a1(k, atm%act1(ic))
          if (ic < nc) bg_sca(ic) = real(x1(k, atm%act1(ic))*a1(k, atm%act1(ic)), vp)
        end do
        ! the running sums of the background's scattering, the same in every voxel of the layer
        acc_bg(0) = 0.0_wp
        do ic = 1, na1
          acc_bg(ic) = acc_bg(ic - 1)
          if (ic < nc) acc_bg(ic) = acc_bg(ic) + bg_sca(ic)
        end do
        ! A voxel without voxel components takes the layer's own values (as formed below with no
        ! components, identical to the last bit), which most voxels of a cloud field do: they
        ! are formed once per layer and kept in clear3, the voxels hold VOXEL_CLEAR, and only the
        ! voxels with components are formed one by one. A component counts as absent when its
        ! extinction is 0 and its albedo finite (then it adds exactly nothing).
        call form_voxel(0, .false., clr_e, clr_w, clr_c)
        atm%clear3(1, kr) = clr_e
        atm%clear3(2, kr) = clr_w
        if (mod(kr - 1, np) /= p) cycle
        if (nc > 1) then
          call form_layer(atm%ext3(:, :, kr), atm%omg3(:, :, kr), atm%csca3(:, :, :, kr))
        else
          call form_layer(atm%ext3(:, :, kr), atm%omg3(:, :, kr), no_csca)
        end if
      end do
    end subroutine form_voxels

    !> The voxels with voxel components of every layer (cloud_ptr, cloud_run): those where the
    !> sum of |extinction| + 0 x albedo over the components is not 0 (0 exactly when every
    !> extinction is 0 and every albedo finite; 0 times an infinite or NaN albedo is NaN).
    subroutine list_cloudy()
      integer :: kr, kf, ix, iy, j, n, lo
      integer, allocatable :: grown(:, :)
      real(wp) :: t(atm%nx + 1)
      if (allocated(atm%clear_all)) deallocate (atm%clear_all, atm%clear_part)
      if (allocated(atm%cloud_c)) deallocate (atm%cloud_c)
      if (.not. allocated(atm%cloud_run)) allocate (atm%cloud_run(3, max(256, atm%ny)))
      allocate (atm%cloud_ptr(atm%n3 + 1))
      n = 0
      atm%cloud_ptr(1) = 0
      t(atm%nx + 1) = 0.0_wp            ! ends the last run of a row
      do kr = 1, atm%n3
        kf = atm%k3_lo + kr - 1 - atm%kf_lo + 1
        if (kf >= 1 .and. kf <= nf) then
          do iy = 1, atm%ny
            ! a sum, so that the compiler vectorises it
            t(1:atm%nx) = 0.0_wp
            do j = 1, size(cext, 4)
              do ix = 1, atm%nx
                t(ix) = t(ix) + (abs(cext(ix, iy, kf, j)) + 0.0_wp*cssa(ix, iy, kf, j))
              end do
            end do
            lo = 0
            do ix = 1, atm%nx + 1
              if (t(ix) /= 0.0_wp) then
                if (lo == 0) lo = ix
              else if (lo > 0) then
                if (n == size(atm%cloud_run, 2)) then
                  allocate (grown(3, 2*n))
                  grown(:, 1:n) = atm%cloud_run(:, 1:n)
                  call move_alloc(grown, atm%cloud_run)
                end if
                n = n + 1
                atm%cloud_run(:, n) = [lo, ix - 1, iy]
                lo = 0
              end if
            end do
          end do
        end if
        atm%cloud_ptr(kr + 1) = n
      end do
    end subroutine list_cloudy

    !> cloud_c and cloud_first: the components of the listed voxels side by side, of the layers
    !> this process forms (kr = p + 1, p + 1 + np, ...: the processes sharing the voxels hold
    !> one copy between them)
    subroutine gather_cloudy(p, np)
      integer, intent(in) :: p, np
      integer :: kr, kf, j, ix, iy, n, nr
      nr = atm%cloud_ptr(atm%n3 + 1)
      if (allocated(atm%cloud_first)) deallocate (atm%cloud_first)
      allocate (atm%cloud_first(nr))
      atm%cloud_first = 0
      n = 0
      do kr = 1, atm%n3
        if (mod(kr - 1, np) /= p) cycle
        do j = atm%cloud_ptr(kr) + 1, atm%cloud_ptr(kr + 1)
          atm%cloud_first(j) = n + 1
          n = n + atm%cloud_run(2, j) - atm%cloud_run(1, j) + 1
        end do
      end do
      allocate (atm%cloud_c(2*atm%nc3, n))
      n = 0
      do kr = 1, atm%n3
        if (mod(kr - 1, np) /= p) cycle
        kf = atm%k3_lo + kr - 1 - atm%kf_lo + 1
        do j = atm%cloud_ptr(kr) + 1, atm%cloud_ptr(kr + 1)
          iy = atm%cloud_run(3, j)
          do ix = atm%cloud_run(1, j), atm%cloud_run(2, j)
            n = n + 1
            atm%cloud_c(1:atm%nc3, n) = cext(ix, iy, kf, :)
            atm%cloud_c(atm%nc3 + 1:2*atm%nc3, n) = cssa(ix, iy, kf, :)
            if (atm%similar) call scale_cloudy(ix, iy, kf, kr, n)
          end do
        end do
      end do
    end subroutine gather_cloudy

    !> Similarity-scaled truncation of the components of listed voxel n, (ix, iy) of layer kr,
    !> as atmosphere_put_layer scales them: with the band's phase indices and blend weights at
    !> a new band, else with those the voxels hold.
    subroutine scale_cloudy(ix, iy, kf, kr, n)
      integer, intent(in) :: ix, iy, kf, kr, n
      integer :: j, ip
      real(wp) :: w
      do j = 1, atm%nc3
        if (band) then
          ip = ciph(ix, iy, kf, j)
          w = cwph(ix, iy, kf, j)
        else
          if (associated(atm%iph3)) then
            ip = atm%iph3(na1 + j, ix, iy, kr)
          else
            ip = atm%iph3_const(na1 + j)
          end if
          w = 0.0_wp
          if (associated(atm%wph3)) w = atm%wph3(na1 + j, ix, iy, kr)
        end if
        call similarity_scale(similarity_f(atm%sim, ip, w), atm%cloud_c(j, n), &
                              atm%cloud_c(atm%nc3 + j, n))
      end do
    end subroutine scale_cloudy

    !> The voxels of layer kr (its arrays as dummies, so that the compiler keeps their
    !> addresses in registers instead of reloading them after every store): VOXEL_CLEAR and the
    !> layer's scattering fractions everywhere, then the voxels with components formed anew.
    !> Within a band the voxels with components stay the same ones, so the others still hold
    !> what the last swap wrote them (clear_known): a value that has not changed is not
    !> written again.
    subroutine form_layer(ext_l, omg_l, csca_l)
      real(vp), intent(inout) :: ext_l(:, :), omg_l(:, :)
      real(vp), intent(inout) :: csca_l(:, :, :)   !! (nc - 1, nx, ny); not touched if nc = 1
      integer :: ic, j, ix, iy, iv
      logical :: known
      known = atm%clear_known(kr)
      if (.not. known) then
        ext_l = VOXEL_CLEAR
        omg_l = VOXEL_CLEAR
      end if
      ! by component (a loop over the few components inside would become a call of memcpy)
      do ic = 1, nc - 1
        if (.not. (known .and. same_bits(clr_c(ic), atm%clear_last(ic, kr)))) &
          csca_l(ic, :, :) = clr_c(ic)
      end do
      atm%clear_last(:, kr) = clr_c(1:nc - 1)
      atm%clear_known(kr) = .true.
      if (kf < 1 .or. kf > nf) return
      do j = atm%cloud_ptr(kr) + 1, atm%cloud_ptr(kr + 1)
        iy = atm%cloud_run(3, j)
        iv = atm%cloud_first(j)
        do ix = atm%cloud_run(1, j), atm%cloud_run(2, j)
          call form_cloudy(ix, iy, iv, ext_l, omg_l, csca_l)
          iv = iv + 1
        end do
      end do
      if (.not. band) return
      ! the band's phase indices and blends of the voxel components, as put_layer puts them
      ! (with same_clear, those of the voxels without components stay what they are)
      if (present_and_true(same_clear)) then
        do j = atm%cloud_ptr(kr) + 1, atm%cloud_ptr(kr + 1)
          iy = atm%cloud_run(3, j)
          do ix = atm%cloud_run(1, j), atm%cloud_run(2, j)
            atm%iph3(na1 + 1:na1 + atm%nc3, ix, iy, kr) = ciph(ix, iy, kf, :)
            atm%wph3(na1 + 1:na1 + atm%nc3, ix, iy, kr) = cwph(ix, iy, kf, :)
          end do
        end do
        return
      end if
      do ic = 1, atm%nc3
        atm%iph3(na1 + ic, :, :, kr) = ciph(:, :, kf, ic)
        atm%wph3(na1 + ic, :, :, kr) = cwph(:, :, kf, ic)
      end do
    end subroutine form_layer

    !> The majorant of each block of sv_layout: the largest extinction of its voxels with
    !> components (the list) and of its layers' voxels without (clear3, in every layer of its
    !> super-layer where clear_all says so, else in the layers clear_part lists). These are the
    !> values a sweep over every voxel takes the maximum of, so the majorants are the same to
    !> the last bit, without reading every voxel.
    subroutine swap_majorants()
      integer :: sl, kl, b, nb, j, ix, ie, o
      real(vp), allocatable :: m(:)
      real(vp) :: c
      call supervoxel_copy_layout(sv_layout, atm%sv)
      if (.not. allocated(atm%clear_all)) call find_clear_blocks()
      allocate (m(size(atm%sv%maj)))
      do sl = 1, atm%sv%ns
        nb = atm%sv%nbx(sl)*atm%sv%nby(sl)
        o = atm%sv%off(sl)
        c = maxval(atm%clear3(1, atm%sv%kb(sl):atm%sv%kt(sl)))
        do b = o + 1, o + nb
          m(b) = merge(c, -huge(1.0_vp), atm%clear_all(b))
        end do
      end do
      do j = 1, size(atm%clear_part, 2)
        b = atm%clear_part(1, j)
        m(b) = max(m(b), atm%clear3(1, atm%clear_part(2, j)))
      end do
      do kl = 1, atm%n3
        if (atm%cloud_ptr(kl + 1) - atm%cloud_ptr(kl) > atm%ny) then
          ! many runs: a sweep over the layer (its clear voxels come in again, which does not
          ! change a maximum)
          call sweep_layer(kl, m)
          cycle
        end if
        do j = atm%cloud_ptr(kl) + 1, atm%cloud_ptr(kl + 1)
          ix = atm%cloud_run(1, j)
          do while (ix <= atm%cloud_run(2, j))
            call run_piece(kl, j, ix, ie, b)
            m(b) = max(m(b), maxval(atm%ext3(ix:ie, atm%cloud_run(3, j), kl)))
            ix = ie + 1
          end do
        end do
      end do
      atm%sv%maj = real(m, wp)
    end subroutine swap_majorants

    !> The largest extinction of each block in layer kl taken into m: for each row of blocks
    !> the maximum over its rows column by column (a streaming, vectorisable sweep), then over
    !> each block's columns.
    subroutine sweep_layer(kl, m)
      integer, intent(in) :: kl
      real(vp), intent(inout) :: m(:)
      real(vp) :: col(atm%nx), c
      integer :: sl, bx, by, jx, jy, ix, iy, b
      sl = atm%sv%sl_of_layer(kl)
      bx = atm%sv%bx(sl)
      by = atm%sv%by(sl)
      c = atm%clear3(1, kl)
      do jy = 1, atm%sv%nby(sl)
        col = -huge(1.0_vp)
        do iy = (jy - 1)*by + 1, min(atm%ny, jy*by)
          do ix = 1, atm%nx
            col(ix) = max(col(ix), merge(c, atm%ext3(ix, iy, kl), atm%ext3(ix, iy, kl) < 0.0_vp))
          end do
        end do
        b = atm%sv%off(sl) + (jy - 1)*atm%sv%nbx(sl)
        if (bx == 1) then
          do ix = 1, atm%nx
            m(b + ix) = max(m(b + ix), col(ix))
          end do
        else
          do ix = 1, atm%nx
            jx = (ix - 1)/bx + 1
            m(b + jx) = max(m(b + jx), col(ix))
          end do
        end if
      end do
    end subroutine sweep_layer

    !> The piece ix .. ie of run j of layer kl that lies in one block, b (global index).
    subroutine run_piece(kl, j, ix, ie, b)
      integer, intent(in) :: kl, j, ix
      integer, intent(out) :: ie, b
      integer :: sl, jx
      sl = atm%sv%sl_of_layer(kl)
      jx = (ix - 1)/atm%sv%bx(sl)
      ie = min(atm%cloud_run(2, j), (jx + 1)*atm%sv%bx(sl))
      b = atm%sv%off(sl) + ((atm%cloud_run(3, j) - 1)/atm%sv%by(sl))*atm%sv%nbx(sl) + jx + 1
    end subroutine run_piece

    !> clear_all and clear_part: which blocks have a voxel without components in which layer of
    !> their super-layer (fewer voxels with components than the block holds).
    subroutine find_clear_blocks()
      integer :: sl, kl, b, nb, j, ix, ie, jx, jy, n, o, pass
      integer, allocatable :: cnt(:), area(:)
      allocate (atm%clear_all(size(atm%sv%maj)), area(size(atm%sv%maj)))
      do sl = 1, atm%sv%ns
        o = atm%sv%off(sl)
        do jy = 1, atm%sv%nby(sl)
          do jx = 1, atm%sv%nbx(sl)
            area(o + (jy - 1)*atm%sv%nbx(sl) + jx) = &
              (min(atm%nx, jx*atm%sv%bx(sl)) - (jx - 1)*atm%sv%bx(sl))* &
              (min(atm%ny, jy*atm%sv%by(sl)) - (jy - 1)*atm%sv%by(sl))
          end do
        end do
      end do
      ! a block is not clear_all when one of its layers is full of voxels with components; the
      ! layers where such a block has voxels without components go to clear_part
      atm%clear_all = .true.
      allocate (cnt(size(atm%sv%maj)), atm%clear_part(2, 0))
      do pass = 1, 2
        n = 0
        do kl = 1, atm%n3
          sl = atm%sv%sl_of_layer(kl)
          o = atm%sv%off(sl)
          nb = atm%sv%nbx(sl)*atm%sv%nby(sl)
          cnt(o + 1:o + nb) = 0
          do j = atm%cloud_ptr(kl) + 1, atm%cloud_ptr(kl + 1)
            ix = atm%cloud_run(1, j)
            do while (ix <= atm%cloud_run(2, j))
              call run_piece(kl, j, ix, ie, b)
              cnt(b) = cnt(b) + (ie - ix + 1)
              ix = ie + 1
            end do
          end do
          do b = o + 1, o + nb
            if (pass == 1) then
              if (cnt(b) == area(b)) atm%clear_all(b) = .false.
            else if (.not. atm%clear_all(b) .and. cnt(b) < area(b)) then
              n = n + 1
              if (n > size(atm%clear_part, 2)) call grow_part()
              atm%clear_part(:, n) = [b, kl]
            end if
          end do
        end do
        if (all(atm%clear_all)) exit
      end do
      atm%clear_part = atm%clear_part(:, 1:n)
    end subroutine find_clear_blocks

    subroutine grow_part()
      integer, allocatable :: g(:, :)
      allocate (g(2, max(64, 2*size(atm%clear_part, 2))))
      g(:, 1:size(atm%clear_part, 2)) = atm%clear_part
      call move_alloc(g, atm%clear_part)
    end subroutine grow_part

    !> Voxel (ix, iy) of the layer's arrays, with its components (cloud_c(:, iv)).
    subroutine form_cloudy(ix, iy, iv, ext_l, omg_l, csca_l)
      integer, intent(in) :: ix, iy, iv
      real(vp), intent(inout) :: ext_l(:, :), omg_l(:, :)
      real(vp), intent(inout) :: csca_l(:, :, :)
      if (nc > 1) then
        call form_voxel(iv, .true., ext_l(ix, iy), omg_l(ix, iy), csca_l(:, ix, iy))
      else
        call form_voxel(iv, .true., ext_l(ix, iy), omg_l(ix, iy), clr_c)
      end if
    end subroutine form_cloudy

    !> The totals, albedo and cumulative scattering fractions of a voxel of layer kr (host's
    !> k, e, s, acc_bg), with the voxel components cloud_c(:, iv) if `cloud`, else with none.
    subroutine form_voxel(iv, cloud, ext_v, omg_v, csca_v)
      integer, intent(in) :: iv
      logical, intent(in) :: cloud
      real(vp), intent(out) :: ext_v, omg_v
      real(vp), intent(out) :: csca_v(:)
      real(wp) :: sca, ext_tot, sca_tot, acc
      real(vp) :: et, st
      integer :: j, ic, icc
      et = real(e, vp)
      st = real(s, vp)
      if (cloud) then
        do j = 1, atm%nc3
          sca = atm%cloud_c(j, iv)*atm%cloud_c(atm%nc3 + j, iv)
          et = real(et + atm%cloud_c(j, iv), vp)
          st = real(st + sca, vp)
        end do
      end if
      ext_v = et
      ext_tot = et
      sca_tot = st
      if (ext_tot > 0.0_wp) then
        omg_v = real(min(1.0_wp, sca_tot/ext_tot), vp)
      else
        omg_v = 1.0_vp
      end if
      do ic = 1, min(na1, nc - 1)
        if (sca_tot > 0.0_wp) then
          csca_v(ic) = real(min(1.0_wp, acc_bg(ic)/sca_tot), vp)
        else
          csca_v(ic) = real(real(ic, wp)/nc, vp)
        end if
      end do
      acc = acc_bg(na1)
      do icc = na1 + 1, nc - 1
        sca = 0.0_wp
        if (cloud) sca = real(real(atm%cloud_c(icc - na1, iv)* &
                                   atm%cloud_c(atm%nc3 + icc - na1, iv), vp), wp)
        acc = acc + sca
        if (sca_tot > 0.0_wp) then
          csca_v(icc) = real(min(1.0_wp, acc/sca_tot), vp)
        else
          csca_v(icc) = real(real(icc, wp)/nc, vp)
        end if
      end do
    end subroutine form_voxel
  end subroutine atmosphere_swap_background

  !> The voxel arrays of the 3-D region (nx, ny, n3 and ncomp set): allocated here and owned,
  !> or placed one after the other in one block of the caller's `storage` (borrowed). A new
  !> per-voxel array takes its place in both branches and in atmosphere_release.
  subroutine voxel_arrays(atm, blend, storage)
    type(atmosphere_t), intent(inout) :: atm
    logical, intent(in) :: blend
    procedure(voxel_storage_i), optional :: storage
    !> bytes of one value; reals of kind vp and default integers have the same size
    integer(i8), parameter :: WORD = storage_size(1.0_vp)/8
    integer(i8) :: nv, nw, o
    integer :: nx, ny, n3, nc
    real(vp), pointer, contiguous :: words(:)
    integer, pointer, contiguous :: iwords(:)
    type(c_ptr) :: base
    nx = atm%nx
    ny = atm%ny
    n3 = atm%n3
    nc = atm%ncomp
    nv = int(nx, i8)*ny*n3
    nw = nv*(2 + (nc - 1) + nc + merge(nc, 0, blend))
    ! no voxel holds VOXEL_CLEAR before a swap
    allocate (atm%clear3(2, n3), source=0.0_vp)
    if (.not. present(storage)) then
      allocate (atm%ext3(nx, ny, n3), atm%omg3(nx, ny, n3))
      if (nc > 1) allocate (atm%csca3(nc - 1, nx, ny, n3))
      allocate (atm%iph3(nc, nx, ny, n3))
      if (blend) allocate (atm%wph3(nc, nx, ny, n3))
      atm%voxel_bytes_own = nw*WORD
      return
    end if
    call storage(nw*WORD, base, atm%voxel_writer)
    atm%voxels_borrowed = .true.
    atm%voxel_bytes_borrowed = nw*WORD
    call c_f_pointer(base, words, [nw])
    o = 0
    atm%ext3(1:nx, 1:ny, 1:n3) => words(o + 1:o + nv)
    o = o + nv
    atm%omg3(1:nx, 1:ny, 1:n3) => words(o + 1:o + nv)
    o = o + nv
    if (nc > 1) then
      atm%csca3(1:nc - 1, 1:nx, 1:ny, 1:n3) => words(o + 1:o + (nc - 1)*nv)
      o = o + (nc - 1)*nv
    end if
    if (blend) then
      atm%wph3(1:nc, 1:nx, 1:ny, 1:n3) => words(o + 1:o + nc*nv)
      o = o + nc*nv
    end if
    call c_f_pointer(c_loc(words(o + 1)), iwords, [nc*nv])
    atm%iph3(1:nc, 1:nx, 1:ny, 1:n3) => iwords
  end subroutine voxel_arrays

  !> Free the voxel arrays this atmosphere owns (borrowed ones are only let go: their storage
  !> belongs to the caller). The atmosphere has no voxel arrays afterwards.
  subroutine atmosphere_release(atm)
    type(atmosphere_t), intent(inout) :: atm
    if (.not. atm%voxels_borrowed) then
      if (associated(atm%ext3)) deallocate (atm%ext3)
      if (associated(atm%omg3)) deallocate (atm%omg3)
      if (associated(atm%csca3)) deallocate (atm%csca3)
      if (associated(atm%iph3)) deallocate (atm%iph3)
      if (associated(atm%wph3)) deallocate (atm%wph3)
    end if
    nullify (atm%ext3, atm%omg3, atm%csca3, atm%iph3, atm%wph3)
    atm%voxels_borrowed = .false.
    atm%voxel_writer = .true.
    atm%voxel_bytes_own = 0_i8
    atm%voxel_bytes_borrowed = 0_i8
  end subroutine atmosphere_release

  !> Let go of a voxel array that is not needed (freed when owned).
  subroutine drop_real(borrowed, a)
    logical, intent(in) :: borrowed
    real(vp), pointer, contiguous, intent(inout) :: a(:, :, :, :)
    if (borrowed) then
      nullify (a)
    else
      deallocate (a)
    end if
  end subroutine drop_real

  subroutine drop_int(borrowed, a)
    logical, intent(in) :: borrowed
    integer, pointer, contiguous, intent(inout) :: a(:, :, :, :)
    if (borrowed) then
      nullify (a)
    else
      deallocate (a)
    end if
  end subroutine drop_int

  !> How the photon loop treats layer k (LAYER_*): in the 3-D region, or by its 1-D mixture.
  pure integer function class_of_layer(atm, k, opts) result(cls)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: k
    type(atmosphere_options_t), intent(in) :: opts
    if (k >= atm%k3_lo .and. k <= atm%k3_hi) then
      cls = LAYER_3D
    else if (atm%ext1(k) <= 0.0_wp) then
      cls = LAYER_CLEAR
    else if (atm%omg1(k) <= 0.0_wp .and. opts%use_absorbing_layers) then
      cls = LAYER_ABSORBING
    else
      cls = LAYER_SCATTERING
    end if
  end function class_of_layer

  pure logical function present_and_true(flag)
    logical, intent(in), optional :: flag
    present_and_true = .false.
    if (present(flag)) present_and_true = flag
  end function present_and_true

  !> a and b have the same bits (unlike ==, which takes -0 for 0 and no NaN for itself)
  pure logical function same_bits(a, b)
    real(vp), intent(in) :: a, b
    same_bits = all(transfer(a, [0_i1]) == transfer(b, [0_i1]))
  end function same_bits

  !> Which layers of the 3-D region hold the same values in every voxel (uniform3): extinction,
  !> albedo, scattering fractions, phase indices and blend weights, as far as they are stored.
  !> Each layer's test stops at its first voxel that differs. Layers with `keep` set keep the
  !> answer they have (a band switch with same_clear: a layer without voxel components holds
  !> its layer's optics everywhere and the indices and weights of the last switch, so its
  !> answer is that of the last test).
  subroutine set_uniform3(atm, keep)
    type(atmosphere_t), intent(inout) :: atm
    logical, intent(in), optional :: keep(:)
    integer :: kr, ncol
    if (.not. present(keep)) then
      if (allocated(atm%uniform3)) deallocate (atm%uniform3)
      allocate (atm%uniform3(atm%n3))
    end if
    ncol = atm%nx*atm%ny
    do kr = 1, atm%n3
      if (present(keep)) then
        if (keep(kr)) cycle
      end if
      atm%uniform3(kr) = same_voxel(ncol, atm%ext3(:, :, kr), atm%clear3(1, kr))
      if (atm%uniform3(kr)) &
        atm%uniform3(kr) = same_voxel(ncol, atm%omg3(:, :, kr), atm%clear3(2, kr))
      if (atm%uniform3(kr) .and. associated(atm%csca3)) &
        atm%uniform3(kr) = same_real(size(atm%csca3, 1), ncol, atm%csca3(:, :, :, kr))
      if (atm%uniform3(kr) .and. associated(atm%iph3)) &
        atm%uniform3(kr) = same_int(size(atm%iph3, 1), ncol, atm%iph3(:, :, :, kr))
      if (atm%uniform3(kr) .and. associated(atm%wph3)) &
        atm%uniform3(kr) = same_real(size(atm%wph3, 1), ncol, atm%wph3(:, :, :, kr))
    end do
  contains
    !> a(:, j) == a(:, 1) for every column j (the layer's contiguous values as dummies)
    pure logical function same_real(m, n, a) result(same)
      integer, intent(in) :: m, n
      real(vp), intent(in) :: a(m, n)
      integer :: i, j
      same = .false.
      do j = 1, n
        do i = 1, m
          if (.not. (a(i, j) == a(i, 1))) return
        end do
      end do
      same = .true.
    end function same_real
    !> The same for the voxel values of a layer's extinction or albedo, c where they hold
    !> VOXEL_CLEAR
    pure logical function same_voxel(n, a, c) result(same)
      integer, intent(in) :: n
      real(vp), intent(in) :: a(n), c
      real(vp) :: a1, v
      integer :: j
      same = .false.
      a1 = a(1)
      if (a1 < 0.0_vp) a1 = c
      do j = 1, n
        v = a(j)
        if (v < 0.0_vp) v = c
        if (.not. (v == a1)) return
      end do
      same = .true.
    end function same_voxel
    pure logical function same_int(m, n, a) result(same)
      integer, intent(in) :: m, n
      integer, intent(in) :: a(m, n)
      integer :: i, j
      same = .false.
      do j = 1, n
        do i = 1, m
          if (a(i, j) /= a(i, 1)) return
        end do
      end do
      same = .true.
    end function same_int
  end subroutine set_uniform3

  !> Switch truncation on: store the delta fractions and the truncated extinction of the 1-D
  !> layers per level (sigma_a + sum_i (1 - f_i) sigma_s,i, seed text eq. 4.2.20 per component).
  !> The photon loop keeps the original extinction and turns the delta part into forward
  !> scatterings; local estimates use the truncated extinction (see kumo_transport).
  subroutine atmosphere_set_truncation(atm, tr)
    type(atmosphere_t), intent(inout) :: atm
    type(truncation_t), intent(in) :: tr
    atm%trunc = tr
    atm%truncated = tr%n_levels > 1
    if (allocated(atm%ext1_lev)) deallocate (atm%ext1_lev)
    allocate (atm%ext1_lev(atm%nz, tr%n_levels))
    call atmosphere_refresh_truncation(atm)
  end subroutine atmosphere_set_truncation

  !> The truncated extinction of the 1-D layers again, after their optics changed (a broadband
  !> run's switch to another g-point keeps the delta fractions, which belong to the phase
  !> functions, but not the layers' mix of them).
  subroutine atmosphere_refresh_truncation(atm)
    type(atmosphere_t), intent(inout) :: atm
    integer :: k, l, ic, nc
    real(wp) :: fbar, prev
    nc = atm%ncomp1
    do l = 1, atm%trunc%n_levels
      do k = 1, atm%nz
        fbar = 0.0_wp
        prev = 0.0_wp
        do ic = 1, nc
          fbar = fbar + (atm%csca1(ic, k) - prev)*atm%trunc%f(l, atm%iph1(ic, k))
          prev = atm%csca1(ic, k)
        end do
        atm%ext1_lev(k, l) = atm%ext1(k)*(1.0_wp - atm%omg1(k)*fbar)
      end do
    end do
  end subroutine atmosphere_refresh_truncation

  !> Extinction of voxel (ix, iy) of 3-D layer kr [m-1]: its own, or its layer's where the voxel
  !> holds VOXEL_CLEAR (a voxel without voxel components after a background swap).
  pure real(vp) function voxel_ext(atm, ix, iy, kr) result(e)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: ix, iy, kr
    e = atm%ext3(ix, iy, kr)
    e = merge(atm%clear3(1, kr), e, e < 0.0_vp)
  end function voxel_ext

  !> Extinction [m-1] and albedo of every voxel of 3-D layer kr, as voxel_ext and voxel_omg.
  pure subroutine voxel_layer(atm, kr, e, w)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: kr
    real(vp), intent(out) :: e(:, :), w(:, :)   !! (nx, ny)
    real(vp) :: ce, cw
    ce = atm%clear3(1, kr)
    cw = atm%clear3(2, kr)
    e = merge(ce, atm%ext3(:, :, kr), atm%ext3(:, :, kr) < 0.0_vp)
    w = merge(cw, atm%omg3(:, :, kr), atm%omg3(:, :, kr) < 0.0_vp)
  end subroutine voxel_layer

  !> Single-scattering albedo of voxel (ix, iy) of 3-D layer kr, as voxel_ext.
  pure real(vp) function voxel_omg(atm, ix, iy, kr) result(w)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: ix, iy, kr
    w = atm%omg3(ix, iy, kr)
    w = merge(atm%clear3(2, kr), w, w < 0.0_vp)
  end function voxel_omg

  !> Vertical optical depth (total extinction from the surface to the top) of the columns of the
  !> 3-D region, or of the one column of a 1-D atmosphere: the smallest, the mean and the largest,
  !> and the column (ix_max, iy_max) of the largest. Untruncated, as ext1 and ext3 hold it.
  subroutine atmosphere_column_tau(atm, tau_min, tau_mean, tau_max, ix_max, iy_max)
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(out) :: tau_min, tau_mean, tau_max
    integer, intent(out) :: ix_max, iy_max
    real(wp), allocatable :: tau(:, :)
    real(vp), allocatable :: e(:, :), w(:, :)
    real(wp) :: tau1
    integer :: k, kr, loc(2)

    tau1 = 0.0_wp   ! the 1-D layers, the same in every column
    do k = 1, atm%nz
      if (atm%n3 > 0 .and. k >= atm%k3_lo .and. k <= atm%k3_hi) cycle
      tau1 = tau1 + atm%ext1(k)*(atm%z(k) - atm%z(k - 1))
    end do
    if (atm%n3 <= 0) then
      tau_min = tau1
      tau_mean = tau1
      tau_max = tau1
      ix_max = 1
      iy_max = 1
      return
    end if
    allocate (tau(atm%nx, atm%ny), e(atm%nx, atm%ny), w(atm%nx, atm%ny))
    tau = tau1
    do kr = 1, atm%n3
      k = atm%k3_lo + kr - 1
      call voxel_layer(atm, kr, e, w)
      tau = tau + real(e, wp)*(atm%z(k) - atm%z(k - 1))
    end do
    tau_min = minval(tau)
    tau_max = maxval(tau)
    tau_mean = sum(tau)/real(size(tau), wp)
    loc = maxloc(tau)
    ix_max = loc(1)
    iy_max = loc(2)
  end subroutine atmosphere_column_tau

  !> Truncated extinction of voxel (ix, iy, kr) at truncation level `lev` [m-1].
  pure function sigma_trunc_3d(atm, ix, iy, kr, lev) result(sig)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: ix, iy, kr, lev
    real(wp) :: sig
    real(wp) :: fbar, prev, c
    integer :: ic
    sig = voxel_ext(atm, ix, iy, kr)
    if (lev <= 1 .or. sig <= 0.0_wp) return
    fbar = 0.0_wp
    prev = 0.0_wp
    do ic = 1, atm%ncomp
      if (ic < atm%ncomp) then
        c = atm%csca3(ic, ix, iy, kr)
      else
        c = 1.0_wp
      end if
      fbar = fbar + (c - prev)*delta_fraction(atm, ic, ix, iy, kr, lev)
      prev = c
    end do
    sig = sig*(1.0_wp - voxel_omg(atm, ix, iy, kr)*fbar)
  end function sigma_trunc_3d

  !> Truncated (delta) fraction of component ic of a voxel at level lev, blends included.
  pure real(wp) function delta_fraction(atm, ic, ix, iy, kr, lev) result(f)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: ic, ix, iy, kr, lev
    integer :: iph
    real(wp) :: w
    if (associated(atm%iph3)) then
      iph = atm%iph3(ic, ix, iy, kr)
    else
      iph = atm%iph3_const(ic)
    end if
    f = atm%trunc%f(lev, iph)
    if (associated(atm%wph3)) then
      w = atm%wph3(ic, ix, iy, kr)
      if (w > 0.0_wp) f = (1.0_wp - w)*f + w*atm%trunc%f(lev, iph + 1)
    end if
  end function delta_fraction

  !> Column (1..nx*ny) of the 3-D grid under (x, y).
  pure integer function column_of(atm, x, y) result(icol)
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(in) :: x, y
    integer :: ix, iy
    call column_xy(atm, x, y, ix, iy)
    icol = ix + (iy - 1)*atm%nx
  end function column_of

  !> Column indices (ix, iy) of the point (x, y), clamped to the grid against round-off.
  pure subroutine column_xy(atm, x, y, ix, iy)
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(in) :: x, y
    integer, intent(out) :: ix, iy
    ix = min(atm%nx, max(1, int(x*atm%inv_dx) + 1))
    iy = min(atm%ny, max(1, int(y*atm%inv_dy) + 1))
  end subroutine column_xy

  !> Total extinction, mixture albedo and cumulative scattering fractions of one cell.
  !> In one pass over the voxels: is a phase index outside 1..np (`bad_index`), a blend weight
  !> outside 0..1 or NaN (`bad_weight`), a weight > 0 on an index without a next table
  !> (`bad_blend`), any weight > 0 (`blended`)? Without blend weights (`wph` not associated)
  !> only the indices are checked.
  subroutine index_checks(iph, wph, np, bad_index, bad_weight, bad_blend, blended)
    integer, pointer, contiguous, intent(in) :: iph(:, :, :, :)
    real(vp), pointer, contiguous, intent(in) :: wph(:, :, :, :)
    integer, intent(in) :: np
    logical, intent(out) :: bad_index, bad_weight, bad_blend, blended
    integer :: imin, imax
    bad_blend = .false.
    if (associated(wph)) then
      call scan_blend(size(iph), iph, wph, imin, imax, bad_weight, blended, bad_blend)
    else
      imin = minval(iph)
      imax = maxval(iph)
      bad_weight = .false.
      blended = .false.
    end if
    bad_index = imin < 1 .or. imax > np
  contains
    subroutine scan_blend(n, ip, w, imin, imax, bad_w, any_w, late)
      integer, intent(in) :: n
      integer, intent(in) :: ip(n)    !! the indices, as one sequence
      real(vp), intent(in) :: w(n)    !! the weights, as one sequence
      integer, intent(out) :: imin, imax
      logical, intent(out) :: bad_w   !! a weight outside 0..1 (or NaN)
      logical, intent(out) :: any_w   !! a weight > 0
      logical, intent(out) :: late    !! a weight > 0 on index np (or above)
      integer :: i, n_bad, n_pos, n_late
      ! loops without branches, each of one kind of value, so that the compiler vectorises them
      imin = huge(1)
      imax = -huge(1)
      do i = 1, n
        imin = min(imin, ip(i))
        imax = max(imax, ip(i))
      end do
      n_bad = 0
      n_pos = 0
      do i = 1, n
        n_bad = n_bad + merge(0, 1, w(i) >= 0.0_vp .and. w(i) <= 1.0_vp)
        n_pos = n_pos + merge(1, 0, w(i) > 0.0_vp)
      end do
      n_late = 0
      if (n_pos > 0 .and. imax >= np) then
        do i = 1, n
          n_late = n_late + merge(1, 0, w(i) > 0.0_vp .and. ip(i) >= np)
        end do
      end if
      bad_w = n_bad > 0
      any_w = n_pos > 0
      late = n_late > 0
    end subroutine scan_blend
  end subroutine index_checks

  !> The truncation tables of similarity-scaled truncation at theta_deg: one truncated level
  !> (level 2), at which no scattering counts as "into the peak".
  subroutine similarity_tables(phases, theta_deg, sim, error)
    type(phase_t), intent(in) :: phases(:)
    real(wp), intent(in) :: theta_deg
    type(truncation_t), intent(out) :: sim
    type(error_t), allocatable, intent(out) :: error
    call truncation_init(sim, phases, theta_deg, 2, SIM_PF_PEAK, error)
    if (allocated(error)) call add_context(error, 'similarity_theta_deg')
  end subroutine similarity_tables

  !> The 1-D components ext, ssa (nz, ncomp1; phase indices iph alike) similarity-scaled in
  !> place with the tables `sim`, as every build and switch of g-point takes them.
  pure subroutine similarity_scale_1d(sim, iph, ext, ssa)
    type(truncation_t), intent(in) :: sim
    integer, intent(in) :: iph(:, :)
    real(wp), intent(inout) :: ext(:, :), ssa(:, :)
    integer :: k, ic
    do ic = 1, size(ext, 2)
      do k = 1, size(ext, 1)
        call similarity_scale(similarity_f(sim, iph(k, ic), 0.0_wp), ext(k, ic), ssa(k, ic))
      end do
    end do
  end subroutine similarity_scale_1d

  !> What the truncation tables of similarity-scaled truncation depend on: the angle and, per
  !> phase function, its kind, asymmetry parameter, normalisation, table size and forward value.
  pure function similarity_key(phases, theta_deg) result(key)
    type(phase_t), intent(in) :: phases(:)
    real(wp), intent(in) :: theta_deg
    real(wp) :: key(1 + 5*size(phases))
    integer :: i, j
    key(1) = theta_deg
    do i = 1, size(phases)
      j = 1 + 5*(i - 1)
      key(j + 1) = real(phases(i)%kind, wp)
      key(j + 2) = phases(i)%g
      key(j + 3) = phases(i)%norm_factor
      key(j + 4) = 0.0_wp
      key(j + 5) = 0.0_wp
      if (allocated(phases(i)%p_tab)) then
        key(j + 4) = real(size(phases(i)%p_tab), wp)
        if (size(phases(i)%p_tab) > 0) key(j + 5) = phases(i)%p_tab(size(phases(i)%p_tab))
      end if
    end do
  end function similarity_key

  !> Delta fraction of phase function iph at the one level of similarity-scaled truncation
  !> `sim`, or of the blend (1 - w) P(iph) + w P(iph + 1): the weighted sum of its tables'. An
  !> index or weight that atmosphere_end will reject gives 0.
  pure real(wp) function similarity_f(sim, iph, w) result(f)
    type(truncation_t), intent(in) :: sim
    integer, intent(in) :: iph
    real(wp), intent(in) :: w
    integer :: np
    np = size(sim%f, 2)
    f = 0.0_wp
    if (iph < 1 .or. iph > np) return
    f = sim%f(2, iph)
    if (w > 0.0_wp .and. w <= 1.0_wp .and. iph < np) f = (1.0_wp - w)*f + w*sim%f(2, iph + 1)
  end function similarity_f

  !> The weight of table iph + 1 in the normalised rest of a scaled blend with weight w:
  !> w (1 - f(iph + 1))/(1 - f), f the blend's delta fraction (the voxels keep w).
  pure real(wp) function similarity_blend_weight(sim, iph, w) result(ws)
    type(truncation_t), intent(in) :: sim
    integer, intent(in) :: iph
    real(wp), intent(in) :: w
    ws = w*(1.0_wp - sim%f(2, iph + 1))/(1.0_wp - similarity_f(sim, iph, w))
  end function similarity_blend_weight

  !> Similarity transform of one component's optics for a delta fraction f of its phase
  !> function: extinction e (1 - a f), albedo a (1 - f)/(1 - a f). Absorption e (1 - a) is kept.
  pure subroutine similarity_scale(f, e, a)
    real(wp), intent(in) :: f
    real(wp), intent(inout) :: e, a
    real(wp) :: r
    if (f <= 0.0_wp .or. e <= 0.0_wp) return
    r = 1.0_wp - a*f
    e = e*r
    a = a*(1.0_wp - f)/r
  end subroutine similarity_scale

  pure subroutine mix(ext, ssa, ext_tot, omega, csca)
    real(wp), intent(in) :: ext(:), ssa(:)
    real(wp), intent(out) :: ext_tot, omega, csca(:)
    real(wp) :: sca_tot, acc
    integer :: i
    ext_tot = sum(ext)
    sca_tot = sum(ext*ssa)
    if (ext_tot > 0.0_wp) then
      omega = min(1.0_wp, sca_tot/ext_tot)
    else
      omega = 1.0_wp
    end if
    acc = 0.0_wp
    do i = 1, size(ext)
      acc = acc + ext(i)*ssa(i)
      if (sca_tot > 0.0_wp) then
        csca(i) = acc/sca_tot
      else
        csca(i) = real(i, wp)/size(ext)
      end if
    end do
    if (size(csca) > 0) csca(size(csca)) = 1.0_wp
  end subroutine mix

  !> The end of the message for an extinction beyond EXT_MAX.
  pure function too_dense() result(msg)
    character(len=:), allocatable :: msg
    msg = ' m-1, more than '//str(EXT_MAX)//' m-1 (a mean free path below 1 um): no atmosphere'// &
          ' is that dense, and photon positions could not resolve such steps; check the units'// &
          ' of the extinction (m-1)'
  end function too_dense

end module kumo_atmosphere
