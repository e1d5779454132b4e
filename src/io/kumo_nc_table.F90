! SPDX-License-Identifier: BSD-3-Clause
!> Small netCDF steps shared by kumo's table files (the Mie tables of kumo_mie_table and the
!> band-averaged ones of kumo_band_mie_file): each takes the file's id, the text that names the
!> file in messages (`at`) and the run's error, does nothing when the error is already set, and
!> names the attribute, dimension or variable when the library fails.
module kumo_nc_table
  use netcdf, only: nf90_def_var, nf90_put_att, nf90_get_att, nf90_get_var, nf90_inq_dimid, &
                    nf90_inq_varid, nf90_inquire_dimension, nf90_inquire_attribute, &
                    nf90_strerror, NF90_NOERR, NF90_GLOBAL, NF90_DOUBLE
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error
  implicit none
  private
  public :: nc_check, nc_def_double, nc_put_global, nc_get_global, nc_dim_len, nc_get_values

  !> A global attribute, text or real.
  interface nc_put_global
    module procedure put_global_text, put_global_real
  end interface nc_put_global

  !> A global attribute read back, text (any length) or real.
  interface nc_get_global
    module procedure get_global_text, get_global_real
  end interface nc_get_global

  !> A double-precision variable read into an array of its shape.
  interface nc_get_values
    module procedure get_values_1d, get_values_2d, get_values_3d
  end interface nc_get_values

contains

  !> The library's message, after `at`, unless the call succeeded or an error is already set.
  subroutine nc_check(status, at, error)
    integer, intent(in) :: status
    character(len=*), intent(in) :: at
    type(error_t), allocatable, intent(inout) :: error
    if (status == NF90_NOERR .or. allocated(error)) return
    call set_error(error, at//': '//trim(nf90_strerror(status)))
  end subroutine nc_check

  !> Define a double variable on dimensions `dims` with its long_name and units.
  subroutine nc_def_double(ncid, at, error, name, dims, long_name, units, varid)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: at, name, long_name, units
    type(error_t), allocatable, intent(inout) :: error
    integer, intent(in) :: dims(:)
    integer, intent(out) :: varid
    varid = 0
    if (allocated(error)) return
    call nc_check(nf90_def_var(ncid, name, NF90_DOUBLE, dims, varid), at//':'//name, error)
    if (allocated(error)) return
    call nc_check(nf90_put_att(ncid, varid, 'long_name', long_name), at//':'//name, error)
    if (allocated(error)) return
    call nc_check(nf90_put_att(ncid, varid, 'units', units), at//':'//name, error)
  end subroutine nc_def_double

  subroutine put_global_text(ncid, at, error, name, value)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: at, name, value
    type(error_t), allocatable, intent(inout) :: error
    if (allocated(error)) return
    call nc_check(nf90_put_att(ncid, NF90_GLOBAL, name, value), at//':'//name, error)
  end subroutine put_global_text

  subroutine put_global_real(ncid, at, error, name, value)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: at, name
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(in) :: value
    if (allocated(error)) return
    call nc_check(nf90_put_att(ncid, NF90_GLOBAL, name, value), at//':'//name, error)
  end subroutine put_global_real

  subroutine get_global_real(ncid, at, error, name, value)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: at, name
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(out) :: value
    value = 0.0_wp
    if (allocated(error)) return
    call nc_check(nf90_get_att(ncid, NF90_GLOBAL, name, value), at//':'//name, error)
  end subroutine get_global_real

  subroutine get_global_text(ncid, at, error, name, value)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: at, name
    type(error_t), allocatable, intent(inout) :: error
    character(len=:), allocatable, intent(out) :: value
    integer :: n
    value = ''
    if (allocated(error)) return
    call nc_check(nf90_inquire_attribute(ncid, NF90_GLOBAL, name, len=n), at//':'//name, error)
    if (allocated(error)) return
    deallocate (value)
    allocate (character(len=n) :: value)
    call nc_check(nf90_get_att(ncid, NF90_GLOBAL, name, value), at//':'//name, error)
  end subroutine get_global_text

  !> Length of dimension `name`.
  subroutine nc_dim_len(ncid, at, error, name, n)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: at, name
    type(error_t), allocatable, intent(inout) :: error
    integer, intent(out) :: n
    integer :: dimid
    n = 0
    if (allocated(error)) return
    call nc_check(nf90_inq_dimid(ncid, name, dimid), at//':'//name, error)
    if (allocated(error)) return
    call nc_check(nf90_inquire_dimension(ncid, dimid, len=n), at//':'//name, error)
  end subroutine nc_dim_len

  !> Id of variable `name` (0 and the error set if it is missing).
  integer function var_id(ncid, at, error, name) result(varid)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: at, name
    type(error_t), allocatable, intent(inout) :: error
    varid = 0
    if (allocated(error)) return
    call nc_check(nf90_inq_varid(ncid, name, varid), at//':'//name, error)
  end function var_id

  subroutine get_values_1d(ncid, at, error, name, values)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: at, name
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(out) :: values(:)
    integer :: varid
    values = 0.0_wp
    varid = var_id(ncid, at, error, name)
    if (allocated(error)) return
    call nc_check(nf90_get_var(ncid, varid, values), at//':'//name, error)
  end subroutine get_values_1d

  subroutine get_values_2d(ncid, at, error, name, values)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: at, name
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(out) :: values(:, :)
    integer :: varid
    values = 0.0_wp
    varid = var_id(ncid, at, error, name)
    if (allocated(error)) return
    call nc_check(nf90_get_var(ncid, varid, values), at//':'//name, error)
  end subroutine get_values_2d

  subroutine get_values_3d(ncid, at, error, name, values)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: at, name
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(out) :: values(:, :, :)
    integer :: varid
    values = 0.0_wp
    varid = var_id(ncid, at, error, name)
    if (allocated(error)) return
    call nc_check(nf90_get_var(ncid, varid, values), at//':'//name, error)
  end subroutine get_values_3d

end module kumo_nc_table
