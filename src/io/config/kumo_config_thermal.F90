! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_thermal: thermal emission.
!>
!> The parsing and validation of this namelist group (read_thermal), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_thermal
  use kumo_config_base
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, str
  use kumo_math, only: within
  implicit none
  private
  public :: read_thermal

contains

  !> &kumo_thermal: temperatures (or Planck radiances) of the levels, the surface and the top,
  !> and the spectral interval. The group's presence switches emission on (thermal = .false.
  !> keeps it off).
  subroutine read_thermal(unit, present, nz, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    integer, intent(in) :: nz
    type(thermal_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: t_levels(MAX_LAYERS + 1), planck_levels(MAX_LAYERS + 1)
    real(wp) :: t_surface, t_top, wavenumber_lo, wavenumber_hi, wavelength_um, planck_surface, &
                planck_top, emission_floor
    character(len=PATH_LEN) :: t_surface_file
    character(len=64) :: t_surface_var
    logical :: thermal, include_sun
    integer :: ios, n, i
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_thermal: '
    namelist /kumo_thermal/ thermal, t_levels, t_surface, t_top, wavenumber_lo, wavenumber_hi, &
      wavelength_um, planck_levels, planck_surface, planck_top, include_sun, emission_floor, &
      t_surface_file, t_surface_var
    thermal = present
    t_levels = UNSET
    planck_levels = UNSET
    t_surface = UNSET
    t_top = cfg%t_top
    wavenumber_lo = UNSET
    wavenumber_hi = UNSET
    wavelength_um = cfg%wavelength_um
    planck_surface = UNSET
    planck_top = cfg%planck_top
    include_sun = cfg%include_sun
    emission_floor = cfg%emission_floor
    t_surface_file = cfg%t_surface_file
    t_surface_var = cfg%t_surface_var
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_thermal, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_thermal', present, ios, msg, error, probe)
    if (allocated(error)) return
    cfg%enabled = thermal
    if (.not. thermal) return
    n = count(planck_levels /= UNSET)
    if (n > 0) then
      call require(n == nz + 1 .and. all(planck_levels(n + 1:) == UNSET), CTX, 'planck_levels', &
                   rule='needs nz + 1 = '//str(nz + 1)//' values (levels 0..nz, from the '// &
                   'surface up), '//str(n)//' given', error=error)
      do i = 1, n
        call require(within(planck_levels(i), 0.0_wp, BIG), CTX, 'planck_levels('//str(i)//')', &
                     planck_levels(i), 'must be finite and >= 0', error)
      end do
      call require(planck_surface /= UNSET, CTX, 'planck_surface', &
                   rule='is needed with planck_levels', error=error)
      call require(within(planck_surface, 0.0_wp, BIG), CTX, 'planck_surface', planck_surface, &
                   'must be finite and >= 0', error)
      call require(within(planck_top, 0.0_wp, BIG), CTX, 'planck_top', planck_top, &
                   'must be finite and >= 0', error)
      call require(count(t_levels /= UNSET) == 0 .and. t_surface == UNSET, CTX, 't_levels', &
                   rule='and t_surface cannot be given with planck_levels: give temperatures '// &
                   'or Planck radiances', error=error)
      if (allocated(error)) return
      cfg%planck_levels = planck_levels(1:n)
      cfg%planck_surface = planck_surface
      cfg%planck_top = planck_top
    else
      n = count(t_levels /= UNSET)
      call require(n == nz + 1 .and. all(t_levels(n + 1:) == UNSET), CTX, 't_levels', &
                   rule='needs nz + 1 = '//str(nz + 1)//' temperatures [K] (levels 0..nz, from '// &
                   'the surface up), '//str(n)//' given', error=error)
      do i = 1, n
        call require(within(t_levels(i), 0.0_wp, BIG), CTX, 't_levels('//str(i)//')', &
                     t_levels(i), 'must be a temperature in K (finite, >= 0)', error)
      end do
      call require(t_surface /= UNSET .or. len_trim(t_surface_file) > 0, CTX, 't_surface', &
                   rule='is needed: the surface temperature [K] (or a map, t_surface_file)', &
                   error=error)
      call require(t_surface == UNSET .or. len_trim(t_surface_file) == 0, CTX, 't_surface', &
                   rule='and t_surface_file cannot both be given', error=error)
      if (t_surface == UNSET) t_surface = 0.0_wp
      call require(within(t_surface, 0.0_wp, BIG), CTX, 't_surface', t_surface, &
                   'must be a temperature in K (finite, >= 0)', error)
      call require(within(t_top, 0.0_wp, BIG), CTX, 't_top', t_top, &
                   'must be a temperature in K (finite, >= 0; 0: no radiance from above)', error)
      if (allocated(error)) return
      cfg%t_levels = t_levels(1:n)
      cfg%t_surface = t_surface
      cfg%t_top = t_top
    end if
    if (wavenumber_lo /= UNSET .or. wavenumber_hi /= UNSET) then
      call require(wavenumber_lo /= UNSET .and. wavenumber_hi /= UNSET, CTX, 'wavenumber_lo', &
                   rule='and wavenumber_hi go together', error=error)
      call require(within(wavenumber_lo, 0.0_wp, BIG), CTX, 'wavenumber_lo', wavenumber_lo, &
                   'must be finite and >= 0 [cm-1]', error)
      call require(wavenumber_hi > wavenumber_lo, CTX, &
                   'wavenumber_hi', wavenumber_hi, 'must be larger than wavenumber_lo = '// &
                   str(wavenumber_lo)//' [cm-1]', error)
      call require(wavelength_um <= 0.0_wp, CTX, 'wavelength_um', wavelength_um, &
                   'cannot be given with a wavenumber band', error)
      if (allocated(error)) return
      cfg%wavenumber_lo = wavenumber_lo
      cfg%wavenumber_hi = wavenumber_hi
    end if
    call require(within(wavelength_um, 0.0_wp, BIG), CTX, 'wavelength_um', wavelength_um, &
                 'must be finite and >= 0 [um]', error)
    call require(within(emission_floor, 0.0_wp, nearest(1.0_wp, -1.0_wp)), CTX, &
                 'emission_floor', emission_floor, 'must satisfy 0 <= emission_floor < 1', error)
    cfg%wavelength_um = wavelength_um
    call require(len_trim(t_surface_file) == 0 .or. .not. allocated(cfg%planck_levels), CTX, &
                 't_surface_file', rule='needs temperatures (t_levels), not planck_levels', &
                 error=error)
    cfg%include_sun = include_sun
    cfg%emission_floor = emission_floor
    cfg%t_surface_file = t_surface_file
    cfg%t_surface_var = t_surface_var
  contains
    !> Read one assignment of &kumo_thermal (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_thermal, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_thermal, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_thermal
end module kumo_config_thermal
