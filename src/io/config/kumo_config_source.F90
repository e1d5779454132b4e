! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_source: the solar source.
!>
!> The parsing and validation of this namelist group (read_source), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_source
  use kumo_config_base
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_error, only: error_t
  use kumo_math, only: within
  implicit none
  private
  public :: read_source

contains

  subroutine read_source(unit, present, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(source_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: sza_deg, phi0_deg, solar_flux, wavelength_um
    integer :: ios
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_source: '
    namelist /kumo_source/ sza_deg, phi0_deg, solar_flux, wavelength_um
    wavelength_um = cfg%wavelength_um
    sza_deg = cfg%sza_deg
    phi0_deg = cfg%phi0_deg
    solar_flux = cfg%solar_flux
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_source, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_source', present, ios, msg, error, probe)
    if (allocated(error)) return
    call require(within(sza_deg, 0.0_wp, nearest(90.0_wp, -1.0_wp)), CTX, 'sza_deg', sza_deg, &
                 'must satisfy 0 <= sza_deg < 90', error)
    call require(ieee_is_finite(phi0_deg), CTX, 'phi0_deg', phi0_deg, 'must be finite', error)
    call require(within(solar_flux, 0.0_wp, BIG), CTX, 'solar_flux', solar_flux, &
                 'must be >= 0 [W m-2] (0 = normalised output only)', error)
    call require(within(wavelength_um, 0.0_wp, BIG), CTX, 'wavelength_um', wavelength_um, &
                 'must be finite and >= 0 [um] (0 = not given)', error)
    cfg%wavelength_um = wavelength_um
    cfg%sza_deg = sza_deg
    cfg%phi0_deg = phi0_deg
    cfg%solar_flux = solar_flux
  contains
    !> Read one assignment of &kumo_source (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_source, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_source, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_source
end module kumo_config_source
