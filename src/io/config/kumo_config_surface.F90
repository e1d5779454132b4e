! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_surface: Lambert, BRDF and maps.
!>
!> The parsing and validation of this namelist group (read_surface), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_surface
  use kumo_config_base
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, add_context, str, to_lower
  use kumo_math, only: within
  use kumo_brdf, only: brdf_params, brdf_kind_from_name, brdf_validate, cox_munk_slope_variance, &
                       BRDF_BLACK, BRDF_LAMBERT, BRDF_DSM, BRDF_NPAR
  implicit none
  private
  public :: read_surface

contains

  subroutine read_surface(unit, present, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(surface_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: albedo, brdf_param(BRDF_NPAR), wind_speed
    character(len=PATH_LEN) :: albedo_file, brdf_file, surface_file
    character(len=64) :: albedo_var
    character(len=16) :: surface_format
    character(len=8) :: brdf
    integer :: ios, kind, surface_nxb, surface_nyb, surface_mbrdf(4), surface_idread
    character(len=512) :: msg
    namelist /kumo_surface/ albedo, albedo_file, albedo_var, brdf, brdf_param, wind_speed, &
      brdf_file, surface_file, surface_format, surface_nxb, surface_nyb, surface_mbrdf, &
      surface_idread
    albedo = cfg%albedo
    albedo_file = cfg%albedo_file
    brdf_file = cfg%brdf_file
    albedo_var = cfg%albedo_var
    brdf = cfg%brdf
    brdf_param = cfg%brdf_param
    wind_speed = cfg%wind_speed
    surface_file = cfg%surface_file
    surface_format = cfg%surface_format
    surface_nxb = cfg%surface_nxb
    surface_nyb = cfg%surface_nyb
    surface_mbrdf = cfg%surface_mbrdf
    surface_idread = cfg%surface_idread
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_surface, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_surface', present, ios, msg, error, probe)
    if (allocated(error)) return
    call surface_file_settings(surface_file, surface_format, surface_nxb, surface_nyb, &
                               surface_mbrdf, surface_idread, albedo, albedo_file, brdf, &
                               brdf_file, brdf_param, wind_speed, error)
    if (allocated(error)) return
    cfg%surface_file = surface_file
    cfg%surface_format = to_lower(adjustl(surface_format))
    cfg%surface_nxb = surface_nxb
    cfg%surface_nyb = surface_nyb
    cfg%surface_mbrdf = surface_mbrdf
    cfg%surface_idread = surface_idread
    call require(within(albedo, 0.0_wp, 1.0_wp), '&kumo_surface: ', 'albedo', albedo, &
                 'must be within [0, 1]', error)
    if (allocated(error)) return
    call brdf_kind_from_name(brdf, kind, error)
    call add_context(error, '&kumo_surface')
    if (allocated(error)) return
    if (len_trim(brdf_file) > 0) then
      ! a BRDF map: kinds and parameters come from the file (brdf: kind of pixels without one)
      if (len_trim(albedo_file) > 0) then
        call set_error(error, '&kumo_surface: give either albedo_file (a Lambert albedo map) '// &
                       'or brdf_file (a BRDF map), not both')
        return
      end if
      if (any(brdf_param /= 0.0_wp) .or. wind_speed >= 0.0_wp) then
        call set_error(error, '&kumo_surface: brdf_param and wind_speed do not apply with '// &
                       'brdf_file; the map file holds the parameters of every pixel')
        return
      end if
      cfg%model = brdf_params(kind, [0.0_wp])
    else if (kind == BRDF_LAMBERT .or. kind == BRDF_BLACK) then
      if (any(brdf_param /= 0.0_wp)) then
        call set_error(error, '&kumo_surface: brdf_param applies to brdf = ''dsm'', ''rpv'' '// &
                       'and ''lsrt''; a Lambert surface takes its albedo from albedo or '// &
                       'albedo_file')
        return
      end if
    end if
    if (kind /= BRDF_LAMBERT .and. len_trim(brdf_file) == 0) then
      if (len_trim(albedo_file) > 0) then
        call set_error(error, '&kumo_surface: albedo_file is a Lambert albedo map and cannot'// &
                       ' be combined with brdf = '''//trim(brdf)//'''')
        return
      end if
      if (wind_speed >= 0.0_wp) then
        if (kind /= BRDF_DSM) then
          call set_error(error, '&kumo_surface: wind_speed applies to brdf = ''dsm'' only')
          return
        end if
        ! Cox and Munk (1954): the total mean-square slope from the wind speed
        brdf_param(5) = cox_munk_slope_variance(wind_speed)
      end if
      cfg%model = brdf_params(kind, brdf_param)
      call brdf_validate(cfg%model, error)
      call add_context(error, '&kumo_surface')
      if (allocated(error)) return
    end if
    cfg%albedo = albedo
    cfg%albedo_file = albedo_file
    cfg%brdf_file = brdf_file
    cfg%albedo_var = albedo_var
    cfg%brdf = trim(to_lower(adjustl(brdf)))
    cfg%brdf_param = brdf_param
    cfg%wind_speed = wind_speed
  contains
    !> Read one assignment of &kumo_surface (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_surface, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_surface, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_surface

  !> &kumo_surface surface_file: a surface file of another code gives the kind and parameters
  !> of every pixel, so no other surface setting may be given with it; its sizes, which the
  !> binary file does not hold, must be.
  subroutine surface_file_settings(surface_file, surface_format, nxb, nyb, mbrdf, idread, &
                                   albedo, albedo_file, brdf, brdf_file, brdf_param, wind_speed, &
                                   error)
    character(len=*), intent(in) :: surface_file, surface_format, albedo_file, brdf, brdf_file
    integer, intent(in) :: nxb, nyb, mbrdf(4), idread
    real(wp), intent(in) :: albedo, brdf_param(:), wind_speed
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: CTX = '&kumo_surface: '
    call require(trim(to_lower(adjustl(surface_format))) == 'mcarats', CTX, 'surface_format', &
                 surface_format, 'must be ''mcarats'' (the MCARaTS binary surface file, '// &
                 'Sfc_inpfile)', error)
    if (allocated(error)) return
    if (len_trim(surface_file) == 0) then
      if (nxb /= 0 .or. nyb /= 0 .or. any(mbrdf /= 1) .or. idread /= 1) then
        call set_error(error, CTX//'surface_nxb, surface_nyb, surface_mbrdf and '// &
                       'surface_idread describe surface_file, which is not given')
      end if
      return
    end if
    if (len_trim(albedo_file) > 0 .or. len_trim(brdf_file) > 0 .or. albedo /= 0.0_wp .or. &
        trim(to_lower(adjustl(brdf))) /= 'lambert' .or. any(brdf_param /= 0.0_wp) .or. &
        wind_speed >= 0.0_wp) then
      call set_error(error, CTX//'surface_file gives the kind and parameters of every pixel: '// &
                     'albedo, albedo_file, brdf, brdf_file, brdf_param and wind_speed must '// &
                     'not be set with it')
    else if (nxb < 1 .or. nyb < 1) then
      call set_error(error, CTX//'surface_nxb = '//str(nxb)//' and surface_nyb = '//str(nyb)// &
                     ' must be given and >= 1: the pixels of '//trim(surface_file)// &
                     ' (MCARaTS Sfc_nxb, Sfc_nyb)')
    else if (any(mbrdf /= 0 .and. mbrdf /= 1)) then
      call set_error(error, CTX//'surface_mbrdf = '//str(mbrdf(1))//', '//str(mbrdf(2))//', '// &
                     str(mbrdf(3))//', '//str(mbrdf(4))//' must be 0 or 1 each (Lambert, DSM, '// &
                     'RPV, LSRT may appear)')
    end if
    call require(idread >= 1, CTX, 'surface_idread', idread, 'must be >= 1', error)
  end subroutine surface_file_settings
end module kumo_config_surface
