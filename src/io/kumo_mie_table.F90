! SPDX-License-Identifier: BSD-3-Clause
!> Mie tables of water clouds on disk: netCDF write and read, and a cache that reuses a file
!> whose metadata match the request exactly.
!>
!> File (netCDF-4 classic model, CF-1.8; `ncdump` order of dimensions):
!>
!>     dimensions: radius = nr ; angle = nang ;
!>     double r_eff(radius)           effective radius, units "um"
!>     double ext_per_lwc(radius)     extinction per liquid water content, units "m2 g-1"
!>                                    (extinction [m-1] = ext_per_lwc * LWC [g m-3])
!>     double ssa(radius)             single-scattering albedo, units "1"
!>     double asymmetry(radius)       asymmetry parameter g, units "1"
!>     double angle(angle)            scattering angle, units "degree"
!>     double phase_function(radius, angle)   units "1", (1/2) Int P dcos = 1
!>     global: Conventions, title, kumo_mie_table_version, wavelength_um,
!>             refractive_index_real, refractive_index_imag, refractive_index_source,
!>             size_distribution ("gamma" or "lognormal"), effective_variance, dlnr_phase,
!>             water_density_g_m3
!>
!> Files are written to `<path>.tmp` and renamed to `<path>` after a successful close, so a
!> reader never sees a partial table.
module kumo_mie_table
  use, intrinsic :: iso_c_binding, only: c_null_char
  use netcdf, only: nf90_create, nf90_open, nf90_close, nf90_enddef, nf90_def_dim, &
                    nf90_put_att, nf90_get_att, nf90_put_var, NF90_NOWRITE, NF90_NOCLOBBER, &
                    NF90_NETCDF4, NF90_CLASSIC_MODEL, NF90_GLOBAL
  use kumo_kinds, only: wp, i8
  use kumo_error, only: error_t, set_error, str
  use kumo_file_check, only: check_netcdf_complete
  use kumo_mie, only: mie_table_t, mie_table_build, DIST_NAMES, DLNR_DEFAULT, RHO_WATER_G_M3
  use kumo_water_index, only: water_index, WATER_INDEX_SOURCE
  use kumo_netcdf, only: c_rename, c_remove, explain_write_failure, reserve_space
  use kumo_nc_table, only: nc_check, nc_def_double, nc_put_global, nc_get_global, nc_dim_len, &
                           nc_get_values
  implicit none
  private
  public :: write_mie_table, read_mie_table, mie_table_cached, MIE_TABLE_VERSION

  !> Version of the file layout and of the computation; a file of another version is rebuilt.
  integer, parameter :: MIE_TABLE_VERSION = 1
  !> Created exclusively after a stale `<path>.tmp` is removed: a link there is never followed.
  integer, parameter :: CREATE_MODE = ior(NF90_NOCLOBBER, ior(NF90_NETCDF4, NF90_CLASSIC_MODEL))

contains

  !> Write a table to `path` (atomically, through `path.tmp`).
  subroutine write_mie_table(path, table, error)
    character(len=*), intent(in) :: path              !! netCDF file to write
    type(mie_table_t), intent(in) :: table            !! the table
    type(error_t), allocatable, intent(out) :: error  !! set if writing failed
    character(len=*), parameter :: PROC = 'write_mie_table'
    character(len=:), allocatable :: tmp, at
    integer :: ncid, dr, da, v_r, v_e, v_s, v_g, v_a, v_p, status
    type(error_t), allocatable :: close_error
    integer(i8) :: n_data

    tmp = trim(path)//'.tmp'
    at = PROC//'('//trim(path)//')'
    if (.not. allocated(table%r_eff_um) .or. .not. allocated(table%phase)) then
      call set_error(error, at//': the table is empty')
      return
    end if
    ! a full disk is reported before the netCDF library writes (kumo_netcdf); the values as
    ! doubles, 4 KiB of object headers per variable and 64 KiB for the file's structures
    n_data = 8_i8*(4_i8*size(table%r_eff_um, kind=i8) + size(table%angle_deg, kind=i8) + &
                   size(table%phase, kind=i8))
    call reserve_space(tmp, n_data, n_data + 65536_i8 + 6_i8*4096_i8, error)
    if (allocated(error)) return
    status = c_remove(tmp//c_null_char)   ! a stale one (or a link of that name) goes first
    call nc_check(nf90_create(tmp, CREATE_MODE, ncid), PROC//'('//tmp//')', error)
    if (allocated(error)) then
      call explain_write_failure(tmp, error)
      status = c_remove(tmp//c_null_char)
      return
    end if
    call define()
    if (.not. allocated(error)) call nc_check(nf90_enddef(ncid), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v_r, table%r_eff_um), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v_e, table%ext_per_lwc), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v_s, table%ssa), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v_g, table%g), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v_a, table%angle_deg), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v_p, table%phase), at, error)
    call nc_check(nf90_close(ncid), at, close_error)
    if (.not. allocated(error) .and. allocated(close_error)) call move_alloc(close_error, error)
    if (allocated(error)) then
      call explain_write_failure(tmp, error)   ! a full disk says so
      status = c_remove(tmp//c_null_char)
      return
    end if
    if (c_rename(tmp//c_null_char, trim(path)//c_null_char) /= 0) then
      status = c_remove(tmp//c_null_char)
      call set_error(error, at//': cannot rename '//tmp//' to '//trim(path))
    end if
  contains
    subroutine define()
      call nc_check(nf90_def_dim(ncid, 'radius', size(table%r_eff_um), dr), at, error)
      if (allocated(error)) return
      call nc_check(nf90_def_dim(ncid, 'angle', size(table%angle_deg), da), at, error)
      if (allocated(error)) return
      call nc_def_double(ncid, at, error, 'r_eff', [dr], 'effective radius of the size distribution', 'um', v_r)
      call nc_def_double(ncid, at, error, 'ext_per_lwc', [dr], &
                   'extinction coefficient per unit liquid water content', 'm2 g-1', v_e)
      call nc_def_double(ncid, at, error, 'ssa', [dr], 'single-scattering albedo', '1', v_s)
      call nc_def_double(ncid, at, error, 'asymmetry', [dr], 'asymmetry parameter', '1', v_g)
      call nc_def_double(ncid, at, error, 'angle', [da], 'scattering angle', 'degree', v_a)
      call nc_def_double(ncid, at, error, 'phase_function', [da, dr], &
                   'phase function, (1/2) integral over cos(angle) = 1', '1', v_p)
      if (allocated(error)) return
      call nc_put_global(ncid, at, error, 'Conventions', 'CF-1.8')
      call nc_put_global(ncid, at, error, 'title', 'kumo Mie table of liquid water clouds')
      call nc_put_global(ncid, at, error, 'size_distribution', trim(DIST_NAMES(table%dist)))
      call nc_put_global(ncid, at, error, 'refractive_index_source', WATER_INDEX_SOURCE)
      call nc_put_global(ncid, at, error, 'refractive_index_convention', 'm = n + i k, k > 0 absorbing')
      if (allocated(error)) return
      call nc_check(nf90_put_att(ncid, NF90_GLOBAL, 'kumo_mie_table_version', &
                                 MIE_TABLE_VERSION), at, error)
      call nc_put_global(ncid, at, error, 'wavelength_um', table%wavelength_um)
      call nc_put_global(ncid, at, error, 'refractive_index_real', real(table%m, wp))
      call nc_put_global(ncid, at, error, 'refractive_index_imag', aimag(table%m))
      call nc_put_global(ncid, at, error, 'effective_variance', table%v_eff)
      call nc_put_global(ncid, at, error, 'dlnr_phase', table%dlnr)
      call nc_put_global(ncid, at, error, 'water_density_g_m3', RHO_WATER_G_M3)
    end subroutine define
  end subroutine write_mie_table

  !> Read a table written by `write_mie_table`.
  subroutine read_mie_table(path, table, error)
    character(len=*), intent(in) :: path              !! netCDF file
    type(mie_table_t), intent(out) :: table           !! the table
    type(error_t), allocatable, intent(out) :: error  !! set if the file is missing or invalid
    character(len=*), parameter :: PROC = 'read_mie_table'
    character(len=:), allocatable :: at, dist_name
    type(error_t), allocatable :: close_error
    integer :: ncid, nr, nang, version, i
    real(wp) :: m_re, m_im

    at = PROC//'('//trim(path)//')'
    call check_netcdf_complete(at, trim(path), error)
    if (allocated(error)) return
    call nc_check(nf90_open(trim(path), NF90_NOWRITE, ncid), at, error)
    if (allocated(error)) return
    call body()
    call nc_check(nf90_close(ncid), at, close_error)
    if (.not. allocated(error) .and. allocated(close_error)) call move_alloc(close_error, error)
  contains
    subroutine body()
      call nc_check(nf90_get_att(ncid, NF90_GLOBAL, 'kumo_mie_table_version', version), &
                    at//':kumo_mie_table_version', error)
      if (allocated(error)) return
      if (version /= MIE_TABLE_VERSION) then
        call set_error(error, at//': kumo_mie_table_version = '//str(version)// &
                       ' but this kumo reads version '//str(MIE_TABLE_VERSION))
        return
      end if
      call nc_get_global(ncid, at, error, 'wavelength_um', table%wavelength_um)
      call nc_get_global(ncid, at, error, 'refractive_index_real', m_re)
      call nc_get_global(ncid, at, error, 'refractive_index_imag', m_im)
      call nc_get_global(ncid, at, error, 'effective_variance', table%v_eff)
      call nc_get_global(ncid, at, error, 'dlnr_phase', table%dlnr)
      if (allocated(error)) return
      table%m = cmplx(m_re, m_im, kind=wp)
      call nc_get_global(ncid, at, error, 'size_distribution', dist_name)
      if (allocated(error)) return
      table%dist = 0
      do i = 1, size(DIST_NAMES)
        if (dist_name == trim(DIST_NAMES(i))) table%dist = i
      end do
      if (table%dist == 0) then
        call set_error(error, at//': size_distribution = "'//dist_name// &
                       '" must be gamma or lognormal')
        return
      end if
      call nc_dim_len(ncid, at, error, 'radius', nr)
      call nc_dim_len(ncid, at, error, 'angle', nang)
      if (allocated(error)) return
      allocate (table%r_eff_um(nr), table%ext_per_lwc(nr), table%ssa(nr), table%g(nr), &
                table%angle_deg(nang), table%phase(nang, nr))
      call nc_get_values(ncid, at, error, 'r_eff', table%r_eff_um)
      call nc_get_values(ncid, at, error, 'ext_per_lwc', table%ext_per_lwc)
      call nc_get_values(ncid, at, error, 'ssa', table%ssa)
      call nc_get_values(ncid, at, error, 'asymmetry', table%g)
      call nc_get_values(ncid, at, error, 'angle', table%angle_deg)
      if (allocated(error)) return
      call nc_get_values(ncid, at, error, 'phase_function', table%phase)
    end subroutine body
  end subroutine read_mie_table

  !> The Mie table of liquid water (index from `water_index`) for the request: read from
  !> `path` if that file exists and its version, wavelength, refractive index, distribution,
  !> effective variance, phase-function step and radii all equal the request exactly;
  !> otherwise computed and written to `path` (atomically). `action` says which happened and,
  !> for a recomputation, why (e.g. "computed: wavelength_um in file 0.67 differs from 0.86").
  subroutine mie_table_cached(path, wavelength_um, dist, v_eff, r_eff_um, table, action, error)
    character(len=*), intent(in) :: path          !! cache file
    real(wp), intent(in) :: wavelength_um         !! wavelength [um], 0.2 ... 200
    integer, intent(in) :: dist                   !! DIST_GAMMA or DIST_LOGNORMAL
    real(wp), intent(in) :: v_eff                 !! effective variance
    real(wp), intent(in) :: r_eff_um(:)           !! effective radii [um], increasing
    type(mie_table_t), intent(out) :: table       !! the table
    character(len=:), allocatable, intent(out) :: action  !! "read" or "computed: <reason>"
    type(error_t), allocatable, intent(out) :: error  !! set for invalid input or I/O failure
    complex(wp) :: m
    logical :: exists
    type(error_t), allocatable :: read_error
    type(mie_table_t) :: old

    call water_index(wavelength_um, m, error)
    if (allocated(error)) then
      error%message = 'mie_table_cached: '//error%message
      return
    end if
    inquire (file=trim(path), exist=exists)
    if (exists) then
      call read_mie_table(path, old, read_error)
      if (allocated(read_error)) then
        action = 'computed: existing file unreadable ('//read_error%message//')'
      else
        action = mismatch(old)
        if (len(action) == 0) then
          action = 'read'
          call move_table(old, table)
          return
        end if
        action = 'computed: '//action
      end if
    else
      action = 'computed: no file'
    end if
    call mie_table_build(wavelength_um, m, dist, v_eff, r_eff_um, table, error)
    if (allocated(error)) then
      error%message = 'mie_table_cached: '//error%message
      return
    end if
    call write_mie_table(path, table, error)
  contains
    function mismatch(t) result(why)
      type(mie_table_t), intent(in) :: t
      character(len=:), allocatable :: why
      why = ''
      if (t%wavelength_um /= wavelength_um) then
        why = 'wavelength_um in file '//str(t%wavelength_um)//' differs from '// &
              str(wavelength_um)
      else if (t%m /= m) then
        why = 'refractive index in file differs'
      else if (t%dist /= dist) then
        why = 'size_distribution in file differs'
      else if (t%v_eff /= v_eff) then
        why = 'effective_variance in file '//str(t%v_eff)//' differs from '//str(v_eff)
      else if (t%dlnr /= DLNR_DEFAULT) then
        why = 'dlnr_phase in file differs'
      else if (size(t%r_eff_um) /= size(r_eff_um)) then
        why = 'number of radii in file '//str(size(t%r_eff_um))//' differs from '// &
              str(size(r_eff_um))
      else if (any(t%r_eff_um /= r_eff_um)) then
        why = 'effective radii in file differ'
      end if
    end function mismatch
  end subroutine mie_table_cached

  subroutine move_table(from, to)
    type(mie_table_t), intent(inout) :: from
    type(mie_table_t), intent(out) :: to
    to%wavelength_um = from%wavelength_um
    to%m = from%m
    to%dist = from%dist
    to%v_eff = from%v_eff
    to%dlnr = from%dlnr
    call move_alloc(from%r_eff_um, to%r_eff_um)
    call move_alloc(from%ext_per_lwc, to%ext_per_lwc)
    call move_alloc(from%ssa, to%ssa)
    call move_alloc(from%g, to%g)
    call move_alloc(from%angle_deg, to%angle_deg)
    call move_alloc(from%phase, to%phase)
  end subroutine move_table

end module kumo_mie_table
