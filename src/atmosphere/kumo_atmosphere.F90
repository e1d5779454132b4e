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
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str
  use kumo_phase, only: phase_t
  use kumo_truncation, only: truncation_t
  use kumo_supervoxel, only: supervoxel_grid_t, supervoxel_options_t, build_supervoxels
  implicit none
  private
  public :: atmosphere_t, atmosphere_options_t, atmosphere_init, atmosphere_set_truncation
  public :: column_of, column_xy, sigma_trunc_3d
  public :: LAYER_CLEAR, LAYER_ABSORBING, LAYER_SCATTERING, LAYER_3D, LAYER_CLASS_NAMES

  integer, parameter :: LAYER_CLEAR = 0, LAYER_ABSORBING = 1, LAYER_SCATTERING = 2, LAYER_3D = 3
  character(len=10), parameter :: LAYER_CLASS_NAMES(0:3) = &
                                  ['clear     ', 'absorbing ', 'scattering', '3-D       ']

  !> Setup choices; each fast path can be switched off to test that it changes nothing.
  type :: atmosphere_options_t
    logical :: use_1d_layers = .true.        !! .false.: every layer goes through the 3-D tracer
    logical :: use_absorbing_layers = .true. !! .false.: absorbing layers collide like others
    type(supervoxel_options_t) :: sv
  end type atmosphere_options_t

  type :: atmosphere_t
    integer :: nz = 0                        !! number of layers
    integer :: nx = 1, ny = 1                !! columns of the 3-D region
    integer :: k3_lo = 1, k3_hi = 0          !! layers of the 3-D region (empty if k3_hi < k3_lo)
    integer :: n3 = 0                        !! number of 3-D layers
    integer :: ncomp1 = 0                    !! components per 1-D layer
    integer :: ncomp = 0                     !! components per 3-D voxel (the 1-D ones present
                                             !! in the region first, then the scene file's)
    real(wp) :: lx = 1.0_wp, ly = 1.0_wp     !! domain size [m]
    real(wp) :: dx = 1.0_wp, dy = 1.0_wp     !! column size of the 3-D region [m]
    real(wp) :: inv_dx = 1.0_wp, inv_dy = 1.0_wp
    real(wp), allocatable :: z(:)            !! levels z(0:nz) [m]
    integer, allocatable :: layer_class(:)   !! LAYER_* per layer
    real(wp), allocatable :: ext1(:)         !! 1-D layers: total extinction [m-1]
    real(wp), allocatable :: omg1(:)         !! 1-D layers: mixture single-scattering albedo
    real(wp), allocatable :: csca1(:, :)     !! (ncomp1, nz) cumulative scattering fraction
    integer, allocatable :: iph1(:, :)       !! (ncomp1, nz) phase function per component
    real(wp), allocatable :: ext3(:, :, :)   !! (nx, ny, n3) total extinction [m-1]
    real(wp), allocatable :: omg3(:, :, :)   !! (nx, ny, n3) mixture single-scattering albedo
    real(wp), allocatable :: csca3(:, :, :, :) !! (ncomp, nx, ny, n3) cumulative fractions;
                                               !! allocated only when ncomp > 1
    integer, allocatable :: iph3(:, :, :, :) !! (ncomp, nx, ny, n3) phase function index;
                                             !! allocated only when it varies between voxels
    integer, allocatable :: iph3_const(:)    !! (ncomp) phase index when it is the same everywhere
    type(phase_t), allocatable :: phases(:)  !! phase functions referenced by index
    type(supervoxel_grid_t) :: sv            !! majorant grid of the 3-D region
    logical, allocatable :: uniform3(:)      !! (n3) every voxel of the 3-D layer is the same
    ! Truncation of forward peaks (set by atmosphere_set_truncation; off by default)
    logical :: truncated = .false.           !! truncation levels > 1 exist
    type(truncation_t) :: trunc              !! delta fractions per level and phase function
    real(wp), allocatable :: ext1_lev(:, :)  !! (nz, n_levels) truncated extinction of 1-D layers
  end type atmosphere_t

contains

  !> Build the atmosphere from per-component optics.
  !>
  !> `ext1d`, `ssa1d`, `iph1d` are (nz, ncomp1) and describe every layer; inside the 3-D region
  !> they are added to the voxel components `ext3d`, `ssa3d`, `iph3d` (nx, ny, n3, ncomp3), as a
  !> background (e.g. molecules around a cloud).
  subroutine atmosphere_init(atm, z, lx, ly, ext1d, ssa1d, iph1d, phases, opts, error, &
                             k3_lo, ext3d, ssa3d, iph3d)
    type(atmosphere_t), intent(out) :: atm
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
    integer :: nz, k, ic, nc1, nc3, ix, iy, kr, klo, khi, ncomp, kf_lo, kf_hi, na1
    integer, allocatable :: act1(:)
    real(wp), allocatable :: e(:), s(:), csca(:)
    integer, allocatable :: p(:)
    logical :: has3d, phase_varies

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
    atm%phases = phases

    ! 1-D layers: totals and cumulative scattering fractions
    allocate (atm%ext1(nz), atm%omg1(nz), atm%csca1(max(nc1, 1), nz), atm%iph1(max(nc1, 1), nz))
    atm%iph1 = 1
    do k = 1, nz
      call mix(ext1d(k, :), ssa1d(k, :), atm%ext1(k), atm%omg1(k), atm%csca1(1:nc1, k))
      atm%iph1(1:nc1, k) = iph1d(k, :)
    end do

    has3d = present(k3_lo) .and. present(ext3d) .and. present(ssa3d)
    kf_lo = 1     ! layers whose voxels come from the scene file (none if kf_hi < kf_lo)
    kf_hi = 0
    if (has3d) then
      klo = k3_lo
      khi = k3_lo + size(ext3d, 3) - 1
      kf_lo = klo
      kf_hi = khi
      atm%nx = size(ext3d, 1)
      atm%ny = size(ext3d, 2)
      nc3 = size(ext3d, 4)
      if (klo < 1 .or. khi > nz) then
        call set_error(error, 'atmosphere: the 3-D region (layers '//str(klo)//'..'// &
                       str(khi)//') must lie within layers 1..'//str(nz))
        return
      end if
      if (present(iph3d)) then
        if (any(iph3d < 1) .or. any(iph3d > size(phases))) then
          call set_error(error, 'atmosphere: a 3-D phase-function index is outside 1..'// &
                         str(size(phases)))
          return
        end if
      end if
    else
      klo = 1
      khi = 0
      nc3 = 0
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
      if (k >= klo .and. k <= khi) then
        atm%layer_class(k) = LAYER_3D
      else if (atm%ext1(k) <= 0.0_wp) then
        atm%layer_class(k) = LAYER_CLEAR
      else if (atm%omg1(k) <= 0.0_wp .and. opts%use_absorbing_layers) then
        atm%layer_class(k) = LAYER_ABSORBING
      else
        atm%layer_class(k) = LAYER_SCATTERING
      end if
    end do

    if (atm%n3 > 0) then
      ! 1-D components that are empty throughout the region (e.g. no molecules given in cloud
      ! layers) are left out of the voxels: no choice of scatterer, no storage for them.
      act1 = pack([(ic, ic=1, nc1)], [(any(ext1d(klo:khi, ic) > 0.0_wp), ic=1, nc1)])
      na1 = size(act1)
      ncomp = na1 + nc3
      atm%ncomp = ncomp
      allocate (atm%ext3(atm%nx, atm%ny, atm%n3), atm%omg3(atm%nx, atm%ny, atm%n3))
      ! Per-voxel scattering fractions and phase indices are kept only when the photon loop
      ! needs them: one component needs no choice, and a phase index that is the same in every
      ! voxel is stored once. This keeps the voxel data of large fields in the caches.
      allocate (csca(ncomp))
      if (ncomp > 1) allocate (atm%csca3(ncomp, atm%nx, atm%ny, atm%n3))
      phase_varies = .false.
      do ic = 1, na1
        if (any(iph1d(klo:khi, act1(ic)) /= iph1d(klo, act1(ic)))) phase_varies = .true.
      end do
      if (present(iph3d) .and. nc3 > 0) then
        do ic = 1, nc3
          if (any(iph3d(:, :, :, ic) /= iph3d(1, 1, 1, ic))) phase_varies = .true.
        end do
      end if
      if (phase_varies) allocate (atm%iph3(ncomp, atm%nx, atm%ny, atm%n3))
      allocate (e(ncomp), s(ncomp), p(ncomp))
      do kr = 1, atm%n3
        k = klo + kr - 1
        do iy = 1, atm%ny
          do ix = 1, atm%nx
            e(1:na1) = ext1d(k, act1)
            s(1:na1) = ssa1d(k, act1)
            p(1:na1) = iph1d(k, act1)
            if (k >= kf_lo .and. k <= kf_hi) then
              do ic = 1, nc3
                e(na1 + ic) = ext3d(ix, iy, k - kf_lo + 1, ic)
                s(na1 + ic) = ssa3d(ix, iy, k - kf_lo + 1, ic)
                if (present(iph3d)) then
                  p(na1 + ic) = iph3d(ix, iy, k - kf_lo + 1, ic)
                else
                  p(na1 + ic) = 1
                end if
              end do
            else if (nc3 > 0) then
              e(na1 + 1:) = 0.0_wp
              s(na1 + 1:) = 0.0_wp
              p(na1 + 1:) = 1
            end if
            call mix(e, s, atm%ext3(ix, iy, kr), atm%omg3(ix, iy, kr), csca)
            if (ncomp > 1) atm%csca3(:, ix, iy, kr) = csca
            if (phase_varies) atm%iph3(:, ix, iy, kr) = p
            if (kr == 1 .and. ix == 1 .and. iy == 1) atm%iph3_const = p
          end do
        end do
      end do
      call build_supervoxels(atm%ext3, atm%dx, atm%dy, z(klo:khi) - z(klo - 1:khi - 1), &
                             opts%sv, atm%sv)
      allocate (atm%uniform3(atm%n3))
      do kr = 1, atm%n3
        atm%uniform3(kr) = all(atm%ext3(:, :, kr) == atm%ext3(1, 1, kr)) .and. &
                           all(atm%omg3(:, :, kr) == atm%omg3(1, 1, kr))
        if (allocated(atm%csca3)) then
          do ic = 1, ncomp
            atm%uniform3(kr) = atm%uniform3(kr) .and. &
                               all(atm%csca3(ic, :, :, kr) == atm%csca3(ic, 1, 1, kr))
          end do
        end if
        if (allocated(atm%iph3)) then
          do ic = 1, ncomp
            atm%uniform3(kr) = atm%uniform3(kr) .and. &
                               all(atm%iph3(ic, :, :, kr) == atm%iph3(ic, 1, 1, kr))
          end do
        end if
      end do
    end if
  end subroutine atmosphere_init

  !> Switch truncation on: store the delta fractions and the truncated extinction of the 1-D
  !> layers per level (sigma_a + sum_i (1 - f_i) sigma_s,i, seed text eq. 4.2.20 per component).
  !> The photon loop keeps the original extinction and turns the delta part into forward
  !> scatterings; local estimates use the truncated extinction (see kumo_transport).
  subroutine atmosphere_set_truncation(atm, tr)
    type(atmosphere_t), intent(inout) :: atm
    type(truncation_t), intent(in) :: tr
    integer :: k, l, ic, nc
    real(wp) :: fbar, prev
    atm%trunc = tr
    atm%truncated = tr%n_levels > 1
    allocate (atm%ext1_lev(atm%nz, tr%n_levels))
    nc = atm%ncomp1
    do l = 1, tr%n_levels
      do k = 1, atm%nz
        fbar = 0.0_wp
        prev = 0.0_wp
        do ic = 1, nc
          fbar = fbar + (atm%csca1(ic, k) - prev)*tr%f(l, atm%iph1(ic, k))
          prev = atm%csca1(ic, k)
        end do
        atm%ext1_lev(k, l) = atm%ext1(k)*(1.0_wp - atm%omg1(k)*fbar)
      end do
    end do
  end subroutine atmosphere_set_truncation

  !> Truncated extinction of voxel (ix, iy, kr) at truncation level `lev` [m-1].
  pure function sigma_trunc_3d(atm, ix, iy, kr, lev) result(sig)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: ix, iy, kr, lev
    real(wp) :: sig
    real(wp) :: fbar, prev
    integer :: ic, iph
    sig = atm%ext3(ix, iy, kr)
    if (lev <= 1 .or. sig <= 0.0_wp) return
    if (atm%ncomp == 1) then
      if (allocated(atm%iph3)) then
        iph = atm%iph3(1, ix, iy, kr)
      else
        iph = atm%iph3_const(1)
      end if
      fbar = atm%trunc%f(lev, iph)
    else
      fbar = 0.0_wp
      prev = 0.0_wp
      do ic = 1, atm%ncomp
        if (allocated(atm%iph3)) then
          iph = atm%iph3(ic, ix, iy, kr)
        else
          iph = atm%iph3_const(ic)
        end if
        fbar = fbar + (atm%csca3(ic, ix, iy, kr) - prev)*atm%trunc%f(lev, iph)
        prev = atm%csca3(ic, ix, iy, kr)
      end do
    end if
    sig = sig*(1.0_wp - atm%omg3(ix, iy, kr)*fbar)
  end function sigma_trunc_3d

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

end module kumo_atmosphere
