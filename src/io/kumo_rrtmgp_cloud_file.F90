! SPDX-License-Identifier: BSD-3-Clause
!> Reader of the RRTMGP cloud-optics look-up tables (`cloudysky_sw.nc`, `cloudysky_lw.nc`;
!> Pincus, Mlawer and Delamere 2019, JAMES 11, 3074, doi:10.1029/2019MS001621) into kumo's
!> `band_cloud_t` (module kumo_band_cloud). docs/cloud-optics-bands.md describes the data.
!>
!> Read (ncdump order; Fortran order is the reverse):
!>
!> | variable | dimensions | units |
!> |---|---|---|
!> | `bnd_limits_wavenumber` | (nband, pair) | cm-1 |
!> | `radliq_lwr`, `radliq_upr` | scalars | um (effective radius) |
!> | `radice_lwr`, `radice_upr` | scalars | um (generalised effective diameter, see kumo_band_cloud) |
!> | `radliq_fac`, `radice_fac` | scalars | index factors of RRTMG's tables (checked, not used) |
!> | `lut_extliq`, `lut_ssaliq`, `lut_asyliq` | (nband, nsize_liq) | m2 g-1, 1, 1 |
!> | `lut_extice`, `lut_ssaice`, `lut_asyice` | (nrghice, nband, nsize_ice) | m2 g-1, 1, 1 |
!>
!> The size grids are uniform from the lower to the upper bound. The index factors encode the
!> same grids in RRTMG's indexing (liquid: offset, lower bound - factor = step; ice: factor =
!> 1/step); the reader checks that, so a file whose grid means something else is refused. The
!> Pade coefficients the files also hold are not read. Shortwave tables stored in RRTMG's band
!> order are put into RRTMGP's order (band_cloud_sw_reorder; `bc%reordered` tells).
module kumo_rrtmgp_cloud_file
  use netcdf, only: nf90_open, nf90_close, nf90_strerror, NF90_NOWRITE, NF90_NOERR
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str
  use kumo_band_cloud, only: band_cloud_t, band_cloud_init, band_cloud_sw_reorder
  use kumo_rrtmgp_file, only: rrtmgp_dim_len, rrtmgp_get_real
  implicit none
  private

  public :: read_rrtmgp_cloud_optics

  !> Relative tolerance of the check of the index factors against the grid (the factors are
  !> stored in single precision in some files: radice_fac = 0.100000001490116).
  real(wp), parameter :: FAC_TOL = 1.0e-6_wp
  character(len=*), parameter :: KIND = 'RRTMGP cloud file'

contains

  !> Read the cloud-optics file `path` into `bc`.
  subroutine read_rrtmgp_cloud_optics(path, bc, error)
    character(len=*), intent(in) :: path
    type(band_cloud_t), intent(out) :: bc
    type(error_t), allocatable, intent(out) :: error
    integer :: ncid, status
    type(error_t), allocatable :: close_error

    status = nf90_open(trim(path), NF90_NOWRITE, ncid)
    if (status /= NF90_NOERR) then
      call set_error(error, 'RRTMGP cloud file ' // trim(path) // ': ' // trim(nf90_strerror(status)))
      return
    end if
    call read_body(trim(path), ncid, bc, error)
    status = nf90_close(ncid)
    if (.not. allocated(error) .and. status /= NF90_NOERR) then
      call set_error(close_error, 'RRTMGP cloud file ' // trim(path) // ': ' // &
                     trim(nf90_strerror(status)))
      call move_alloc(close_error, error)
    end if
  end subroutine read_rrtmgp_cloud_optics

  subroutine read_body(path, ncid, bc, error)
    character(len=*), intent(in) :: path
    integer, intent(in) :: ncid
    type(band_cloud_t), intent(out) :: bc
    type(error_t), allocatable, intent(out) :: error
    integer :: nband, nliq, nice, nrgh, npair
    real(wp) :: liq(3), ice(3), step
    real(wp), allocatable :: lim(:), el(:), sl(:), al(:), ei(:), si(:), ai(:)
    character(len=*), parameter :: LIQ_DIMS(2) = [character(len=9) :: 'nsize_liq', 'nband']
    character(len=*), parameter :: ICE_DIMS(3) = [character(len=9) :: 'nsize_ice', 'nband', 'nrghice']

    call dim_len(path, ncid, 'nband', nband, error)
    if (.not. allocated(error)) call dim_len(path, ncid, 'nsize_liq', nliq, error)
    if (.not. allocated(error)) call dim_len(path, ncid, 'nsize_ice', nice, error)
    if (.not. allocated(error)) call dim_len(path, ncid, 'nrghice', nrgh, error)
    if (.not. allocated(error)) call dim_len(path, ncid, 'pair', npair, error)
    if (allocated(error)) return
    if (nrgh /= 3) then
      call set_error(error, 'RRTMGP cloud file ' // path // ': dimension nrghice = ' // str(nrgh) // &
                     ', expected 3 ice roughness classes')
      return
    end if
    if (npair /= 2) then
      call set_error(error, 'RRTMGP cloud file ' // path // ': dimension pair = ' // str(npair) // &
                     ', expected 2')
      return
    end if
    call get_scalar(path, ncid, 'radliq_lwr', liq(1), error)
    if (.not. allocated(error)) call get_scalar(path, ncid, 'radliq_upr', liq(2), error)
    if (.not. allocated(error)) call get_scalar(path, ncid, 'radliq_fac', liq(3), error)
    if (.not. allocated(error)) call get_scalar(path, ncid, 'radice_lwr', ice(1), error)
    if (.not. allocated(error)) call get_scalar(path, ncid, 'radice_upr', ice(2), error)
    if (.not. allocated(error)) call get_scalar(path, ncid, 'radice_fac', ice(3), error)
    if (allocated(error)) return
    call get_real(path, ncid, 'bnd_limits_wavenumber', [character(len=5) :: 'pair', 'nband'], lim, error)
    if (.not. allocated(error)) call get_real(path, ncid, 'lut_extliq', LIQ_DIMS, el, error)
    if (.not. allocated(error)) call get_real(path, ncid, 'lut_ssaliq', LIQ_DIMS, sl, error)
    if (.not. allocated(error)) call get_real(path, ncid, 'lut_asyliq', LIQ_DIMS, al, error)
    if (.not. allocated(error)) call get_real(path, ncid, 'lut_extice', ICE_DIMS, ei, error)
    if (.not. allocated(error)) call get_real(path, ncid, 'lut_ssaice', ICE_DIMS, si, error)
    if (.not. allocated(error)) call get_real(path, ncid, 'lut_asyice', ICE_DIMS, ai, error)
    if (allocated(error)) return

    ! The index factors must describe the same grids as the bounds.
    if (nliq >= 2) then
      step = (liq(2) - liq(1))/real(nliq - 1, wp)
      if (abs((liq(1) - liq(3)) - step) > FAC_TOL*step) then
        call set_error(error, 'RRTMGP cloud file ' // path // ': radliq_fac = ' // str(liq(3)) // &
                       ' does not match the liquid grid ' // str(liq(1)) // ' to ' // str(liq(2)) // &
                       ' um in ' // str(nliq) // ' steps (expected radliq_lwr - radliq_fac = step = ' // &
                       str(step) // ')')
        return
      end if
    end if
    if (nice >= 2) then
      step = (ice(2) - ice(1))/real(nice - 1, wp)
      if (abs(ice(3)*step - 1.0_wp) > FAC_TOL) then
        call set_error(error, 'RRTMGP cloud file ' // path // ': radice_fac = ' // str(ice(3)) // &
                       ' does not match the ice grid ' // str(ice(1)) // ' to ' // str(ice(2)) // &
                       ' um in ' // str(nice) // ' steps (expected radice_fac = 1/step = ' // &
                       str(1.0_wp/step) // ')')
        return
      end if
    end if

    call band_cloud_init(bc, lim(1:2*nband:2), lim(2:2*nband:2), liq(1:2), &
                         reshape(el, [nliq, nband]), reshape(sl, [nliq, nband]), &
                         reshape(al, [nliq, nband]), ice(1:2), reshape(ei, [nice, nband, 3]), &
                         reshape(si, [nice, nband, 3]), reshape(ai, [nice, nband, 3]), error)
    if (allocated(error)) then
      error%message = 'RRTMGP cloud file ' // path // ': ' // error%message
      return
    end if
    call band_cloud_sw_reorder(bc)
  end subroutine read_body

  ! the checked netCDF access of kumo_rrtmgp_file, with this file's name in the messages

  subroutine dim_len(path, ncid, name, n, error)
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: ncid
    integer, intent(out) :: n
    type(error_t), allocatable, intent(out) :: error
    call rrtmgp_dim_len(path, ncid, name, n, error, KIND)
  end subroutine dim_len

  subroutine get_real(path, ncid, name, dims, values, error)
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: dims(:)
    real(wp), allocatable, intent(out) :: values(:)
    type(error_t), allocatable, intent(out) :: error
    call rrtmgp_get_real(path, ncid, name, dims, values, error, KIND)
  end subroutine get_real

  subroutine get_scalar(path, ncid, name, value, error)
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: ncid
    real(wp), intent(out) :: value
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: v(:)
    character(len=1), parameter :: NO_DIMS(0) = [character(len=1) ::]
    value = 0.0_wp
    call rrtmgp_get_real(path, ncid, name, NO_DIMS, v, error, KIND)
    if (.not. allocated(error)) value = v(1)
  end subroutine get_scalar

end module kumo_rrtmgp_cloud_file
