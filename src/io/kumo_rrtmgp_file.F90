! SPDX-License-Identifier: BSD-3-Clause
!> Reader of RRTMGP k-distribution files (netCDF; Pincus, Mlawer and Delamere 2019, JAMES 11,
!> 3074, doi:10.1029/2019MS001621) into kumo's `gas_kdist_t` (module kumo_gas_optics).
!>
!> A longwave file is recognised by its Planck tables (`totplnk`, `plank_fraction`), a shortwave
!> file by its solar source and Rayleigh tables (`solar_source_quiet`, `rayl_lower`,
!> `rayl_upper`). Every variable is checked for presence, type (numbers or text) and its
!> dimension names, so a missing or reshaped variable is reported by name. Arrays keep the
!> files' layout read in Fortran order (the reverse of the order ncdump shows), e.g. `kmajor`
!> (gpt, mixing_fraction, pressure_interp, temperature).
!>
!> Minor absorbers are named in the files by an identifier (`minor_gases_lower`, e.g.
!> "h2o_frgn"), which `identifier_minor`/`gas_minor` map to the absorbing gas of `gas_names`.
module kumo_rrtmgp_file
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use netcdf, only: nf90_open, nf90_close, nf90_inq_varid, nf90_inquire_variable, &
                    nf90_inquire_dimension, nf90_inq_dimid, nf90_get_var, nf90_strerror, &
                    NF90_NOWRITE, NF90_NOERR, NF90_CHAR, NF90_MAX_VAR_DIMS, NF90_MAX_NAME
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str, to_lower, join
  use kumo_gas_optics, only: gas_kdist_t, minor_table_t, GAS_NAME_LEN, kdist_finish, gas_index
  implicit none
  private

  public :: read_rrtmgp_kdist
  ! the checked netCDF access that the RRTMGP readers share (kumo_rrtmgp_cloud_file too); `kind`
  ! names the file in messages ('RRTMGP file' unless given)
  public :: rrtmgp_dim_len, rrtmgp_get_real

contains

  !> Read the k-distribution file `path` into `kd` (tables filled, `kdist_finish` applied).
  subroutine read_rrtmgp_kdist(path, kd, error)
    character(len=*), intent(in) :: path
    type(gas_kdist_t), intent(out) :: kd
    type(error_t), allocatable, intent(out) :: error
    integer :: ncid, status
    type(error_t), allocatable :: close_error

    status = nf90_open(trim(path), NF90_NOWRITE, ncid)
    if (status /= NF90_NOERR) then
      call set_error(error, 'RRTMGP file ' // trim(path) // ': ' // trim(nf90_strerror(status)))
      return
    end if
    call read_body(trim(path), ncid, kd, error)
    status = nf90_close(ncid)
    if (.not. allocated(error) .and. status /= NF90_NOERR) then
      call set_error(close_error, 'RRTMGP file ' // trim(path) // ': ' // trim(nf90_strerror(status)))
      call move_alloc(close_error, error)
    end if
    if (allocated(error)) return
    call kdist_finish(kd, error)
  end subroutine read_rrtmgp_kdist

  subroutine read_body(path, ncid, kd, error)
    character(len=*), intent(in) :: path
    integer, intent(in) :: ncid
    type(gas_kdist_t), intent(inout) :: kd
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: r(:)
    integer, allocatable :: iv(:)
    character(len=GAS_NAME_LEN), allocatable :: ident(:), gas_minor(:)
    integer :: n_temp_planck, n_absorber_ext, n_pinterp

    kd%source = path
    call dim_len(path, ncid, 'absorber', kd%n_gas, error); if (allocated(error)) return
    call dim_len(path, ncid, 'bnd', kd%n_band, error); if (allocated(error)) return
    call dim_len(path, ncid, 'gpt', kd%n_gpt, error); if (allocated(error)) return
    call dim_len(path, ncid, 'temperature', kd%n_temp, error); if (allocated(error)) return
    call dim_len(path, ncid, 'pressure', kd%n_press, error); if (allocated(error)) return
    call dim_len(path, ncid, 'mixing_fraction', kd%n_eta, error); if (allocated(error)) return
    call dim_len(path, ncid, 'absorber_ext', n_absorber_ext, error); if (allocated(error)) return
    call dim_len(path, ncid, 'pressure_interp', n_pinterp, error); if (allocated(error)) return
    if (n_absorber_ext /= kd%n_gas + 1 .or. n_pinterp /= kd%n_press + 1) then
      call set_error(error, 'RRTMGP file ' // path // ': dimensions absorber_ext = ' // &
                     str(n_absorber_ext) // ' and pressure_interp = ' // str(n_pinterp) // &
                     ' must be absorber + 1 = ' // str(kd%n_gas + 1) // ' and pressure + 1 = ' // &
                     str(kd%n_press + 1))
      return
    end if

    call get_text(path, ncid, 'gas_names', 'absorber', kd%gas_names, error)
    if (allocated(error)) return
    call get_int(path, ncid, 'bnd_limits_gpt', [character(len=40) :: 'pair', 'bnd'], iv, error)
    if (allocated(error)) return
    kd%band_gpt = reshape(iv, [2, kd%n_band])
    call get_real(path, ncid, 'bnd_limits_wavenumber', [character(len=40) :: 'pair', 'bnd'], r, error)
    if (allocated(error)) return
    kd%band_wavenumber = reshape(r, [2, kd%n_band])
    call get_real(path, ncid, 'temp_ref', [character(len=40) :: 'temperature'], r, error)
    if (allocated(error)) return
    kd%temp_ref = r
    call get_real(path, ncid, 'press_ref', [character(len=40) :: 'pressure'], r, error)
    if (allocated(error)) return
    kd%press_ref = r
    call get_real(path, ncid, 'press_ref_trop', [character(len=40) ::], r, error)
    if (allocated(error)) return
    kd%press_ref_trop = r(1)
    call get_int(path, ncid, 'key_species', [character(len=40) :: 'pair', 'atmos_layer', 'bnd'], &
                 iv, error)
    if (allocated(error)) return
    kd%key_species = reshape(iv, [2, 2, kd%n_band])
    call get_real(path, ncid, 'vmr_ref', &
                  [character(len=40) :: 'atmos_layer', 'absorber_ext', 'temperature'], r, error)
    if (allocated(error)) return
    allocate(kd%vmr_ref(2, 0:kd%n_gas, kd%n_temp))
    kd%vmr_ref = reshape(r, [2, kd%n_gas + 1, kd%n_temp])
    call get_real(path, ncid, 'kmajor', [character(len=40) :: 'gpt', 'mixing_fraction', &
                  'pressure_interp', 'temperature'], r, error)
    if (allocated(error)) return
    kd%kmajor = reshape(r, [kd%n_gpt, kd%n_eta, kd%n_press + 1, kd%n_temp])

    call get_text(path, ncid, 'identifier_minor', 'minor_absorber', ident, error)
    if (allocated(error)) return
    call get_text(path, ncid, 'gas_minor', 'minor_absorber', gas_minor, error)
    if (allocated(error)) return
    call read_minor(path, ncid, kd, 'lower', ident, gas_minor, kd%minor(1), error)
    if (allocated(error)) return
    call read_minor(path, ncid, kd, 'upper', ident, gas_minor, kd%minor(2), error)
    if (allocated(error)) return

    kd%longwave = has_var(ncid, 'totplnk')
    if (kd%longwave) then
      call dim_len(path, ncid, 'temperature_Planck', n_temp_planck, error)
      if (allocated(error)) return
      call get_real(path, ncid, 'totplnk', [character(len=40) :: 'temperature_Planck', 'bnd'], r, error)
      if (allocated(error)) return
      kd%planck_band = reshape(r, [n_temp_planck, kd%n_band])
      call get_real(path, ncid, 'plank_fraction', [character(len=40) :: 'gpt', 'mixing_fraction', &
                    'pressure_interp', 'temperature'], r, error)
      if (allocated(error)) return
      kd%planck_fraction = reshape(r, [kd%n_gpt, kd%n_eta, kd%n_press + 1, kd%n_temp])
    else
      if (.not. has_var(ncid, 'solar_source_quiet')) then
        call set_error(error, 'RRTMGP file ' // path // ': neither totplnk (longwave) nor ' // &
                       'solar_source_quiet (shortwave) found; not a k-distribution file?')
        return
      end if
      call get_real(path, ncid, 'solar_source_quiet', [character(len=40) :: 'gpt'], r, error)
      if (allocated(error)) return
      kd%solar_quiet = r
      call get_real(path, ncid, 'tsi_default', [character(len=40) ::], r, error)
      if (allocated(error)) return
      kd%tsi_default = r(1)
      call get_real(path, ncid, 'solar_source_facular', [character(len=40) :: 'gpt'], r, error)
      if (allocated(error)) return
      kd%solar_facular = r
      call get_real(path, ncid, 'solar_source_sunspot', [character(len=40) :: 'gpt'], r, error)
      if (allocated(error)) return
      kd%solar_sunspot = r
      call get_real(path, ncid, 'mg_default', [character(len=40) ::], r, error)
      if (allocated(error)) return
      kd%mg_default = r(1)
      call get_real(path, ncid, 'sb_default', [character(len=40) ::], r, error)
      if (allocated(error)) return
      kd%sb_default = r(1)
      allocate(kd%rayleigh(kd%n_gpt, kd%n_eta, kd%n_temp, 2))
      call get_real(path, ncid, 'rayl_lower', [character(len=40) :: 'gpt', 'mixing_fraction', &
                    'temperature'], r, error)
      if (allocated(error)) return
      kd%rayleigh(:, :, :, 1) = reshape(r, [kd%n_gpt, kd%n_eta, kd%n_temp])
      call get_real(path, ncid, 'rayl_upper', [character(len=40) :: 'gpt', 'mixing_fraction', &
                    'temperature'], r, error)
      if (allocated(error)) return
      kd%rayleigh(:, :, :, 2) = reshape(r, [kd%n_gpt, kd%n_eta, kd%n_temp])
    end if
  end subroutine read_body

  !> The minor-absorber tables of one atmosphere part ('lower' or 'upper').
  subroutine read_minor(path, ncid, kd, part, ident, gas_minor, m, error)
    character(len=*), intent(in) :: path, part
    integer, intent(in) :: ncid
    type(gas_kdist_t), intent(in) :: kd
    character(len=*), intent(in) :: ident(:), gas_minor(:)
    type(minor_table_t), intent(out) :: m
    type(error_t), allocatable, intent(out) :: error
    character(len=40) :: dint, dcon
    character(len=GAS_NAME_LEN), allocatable :: names(:), scaling(:)
    integer, allocatable :: iv(:)
    real(wp), allocatable :: r(:)
    integer :: i, j, ncon

    dint = 'minor_absorber_intervals_' // part
    dcon = 'contributors_' // part
    call dim_len(path, ncid, trim(dint), m%n, error); if (allocated(error)) return
    call dim_len(path, ncid, trim(dcon), ncon, error); if (allocated(error)) return
    call get_text(path, ncid, 'minor_gases_' // part, trim(dint), names, error)
    if (allocated(error)) return
    call get_text(path, ncid, 'scaling_gas_' // part, trim(dint), scaling, error)
    if (allocated(error)) return
    allocate(m%gas(m%n), m%scaling_gas(m%n))
    do i = 1, m%n
      j = findloc(ident, names(i), 1)
      if (j == 0) then
        call set_error(error, 'RRTMGP file ' // path // ': minor_gases_' // part // '(' // &
                       str(i) // ') = "' // trim(names(i)) // '" is not in identifier_minor')
        return
      end if
      m%gas(i) = gas_index(kd, gas_minor(j))
      if (m%gas(i) == 0) then
        call set_error(error, 'RRTMGP file ' // path // ': minor gas "' // trim(gas_minor(j)) // &
                       '" is not in gas_names')
        return
      end if
      m%scaling_gas(i) = 0
      if (len_trim(scaling(i)) > 0) then
        m%scaling_gas(i) = gas_index(kd, scaling(i))
        if (m%scaling_gas(i) == 0) then
          call set_error(error, 'RRTMGP file ' // path // ': scaling_gas_' // part // '(' // &
                         str(i) // ') = "' // trim(scaling(i)) // '" is not in gas_names')
          return
        end if
      end if
    end do
    call get_int(path, ncid, 'minor_limits_gpt_' // part, [character(len=40) :: 'pair', dint], &
                 iv, error)
    if (allocated(error)) return
    m%gpt = reshape(iv, [2, m%n])
    call get_int(path, ncid, 'minor_scales_with_density_' // part, [dint], iv, error)
    if (allocated(error)) return
    m%scales_with_density = iv /= 0
    call get_int(path, ncid, 'scale_by_complement_' // part, [dint], iv, error)
    if (allocated(error)) return
    m%scale_by_complement = iv /= 0
    call get_int(path, ncid, 'kminor_start_' // part, [dint], iv, error)
    if (allocated(error)) return
    m%kstart = iv
    call get_real(path, ncid, 'kminor_' // part, [character(len=40) :: dcon, 'mixing_fraction', &
                  'temperature'], r, error)
    if (allocated(error)) return
    m%kminor = reshape(r, [ncon, kd%n_eta, kd%n_temp])
  end subroutine read_minor

  ! ---------------------------------------------------------------------------------------------

  logical function has_var(ncid, name)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: name
    integer :: varid
    has_var = nf90_inq_varid(ncid, name, varid) == NF90_NOERR
  end function has_var

  subroutine dim_len(path, ncid, name, n, error, kind)
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: ncid
    integer, intent(out) :: n
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: kind
    integer :: dimid
    n = 0
    if (nf90_inq_dimid(ncid, name, dimid) /= NF90_NOERR) then
      call set_error(error, label(path, kind) // ': dimension ' // name // ' missing')
      return
    end if
    if (nf90_inquire_dimension(ncid, dimid, len=n) /= NF90_NOERR) then
      call set_error(error, label(path, kind) // ': cannot read dimension ' // name)
    end if
  end subroutine dim_len

  !> 'RRTMGP file <path>' (or `kind` <path>), the start of every message.
  function label(path, kind) result(text)
    character(len=*), intent(in) :: path
    character(len=*), intent(in), optional :: kind
    character(len=:), allocatable :: text
    if (present(kind)) then
      text = kind // ' ' // path
    else
      text = 'RRTMGP file ' // path
    end if
  end function label

  !> Length of dimension `name` (public name of dim_len).
  subroutine rrtmgp_dim_len(path, ncid, name, n, error, kind)
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: ncid
    integer, intent(out) :: n
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: kind
    call dim_len(path, ncid, name, n, error, kind)
  end subroutine rrtmgp_dim_len

  !> A numeric variable with dimensions `dims` (Fortran order; none for a scalar), flattened,
  !> without NaN (public name of get_real).
  subroutine rrtmgp_get_real(path, ncid, name, dims, values, error, kind)
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: dims(:)
    real(wp), allocatable, intent(out) :: values(:)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: kind
    call get_real(path, ncid, name, dims, values, error, kind)
  end subroutine rrtmgp_get_real

  !> Variable id after checking presence, kind (text or numbers) and dimension names (Fortran
  !> order); `counts` are the dimension lengths.
  subroutine find_var(path, ncid, name, dims, text, varid, counts, error, kind)
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: dims(:)
    logical, intent(in) :: text
    integer, intent(out) :: varid
    integer, allocatable, intent(out) :: counts(:)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: kind
    integer :: xtype, ndims, dimids(NF90_MAX_VAR_DIMS), i
    character(len=NF90_MAX_NAME) :: dname
    character(len=NF90_MAX_NAME), allocatable :: found(:)

    if (nf90_inq_varid(ncid, name, varid) /= NF90_NOERR) then
      call set_error(error, label(path, kind) // ': variable ' // name // ' missing')
      return
    end if
    if (nf90_inquire_variable(ncid, varid, xtype=xtype, ndims=ndims, dimids=dimids) &
        /= NF90_NOERR) then
      call set_error(error, label(path, kind) // ': cannot inquire variable ' // name)
      return
    end if
    if ((xtype == NF90_CHAR) .neqv. text) then
      if (text) then
        call set_error(error, label(path, kind) // ': variable ' // name // ' must be text')
      else
        call set_error(error, label(path, kind) // ': variable ' // name // &
                       ' must hold numbers, not text')
      end if
      return
    end if
    allocate(counts(ndims), found(ndims))
    do i = 1, ndims
      if (nf90_inquire_dimension(ncid, dimids(i), name=dname, len=counts(i)) /= NF90_NOERR) then
        call set_error(error, label(path, kind) // ': cannot inquire the dimensions of ' // name)
        return
      end if
      found(i) = dname
    end do
    if (ndims /= size(dims)) then
      call set_error(error, label(path, kind) // ': variable ' // name // ' has dimensions (' &
                     // join(found) // '), expected (' // join(dims) // ') in Fortran order')
      return
    end if
    do i = 1, ndims
      if (trim(found(i)) /= trim(dims(i))) then
        call set_error(error, label(path, kind) // ': variable ' // name // &
                       ' has dimensions (' // join(found) // '), expected (' // join(dims) // &
                       ') in Fortran order')
        return
      end if
    end do
  end subroutine find_var

  subroutine get_real(path, ncid, name, dims, values, error, kind)
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: dims(:)
    real(wp), allocatable, intent(out) :: values(:)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: kind
    integer :: varid, status
    integer, allocatable :: counts(:)

    call find_var(path, ncid, name, dims, .false., varid, counts, error, kind)
    if (allocated(error)) return
    allocate(values(product(counts)))
    if (size(counts) == 0) then
      status = nf90_get_var(ncid, varid, values(1))
    else
      status = nf90_get_var(ncid, varid, values, start=spread(1, 1, size(counts)), count=counts)
    end if
    if (status /= NF90_NOERR) then
      call set_error(error, label(path, kind) // ': reading ' // name // ': ' // &
                     trim(nf90_strerror(status)))
      return
    end if
    if (any(ieee_is_nan(values))) then
      call set_error(error, label(path, kind) // ': variable ' // name // ' holds NaN')
    end if
  end subroutine get_real

  subroutine get_int(path, ncid, name, dims, values, error)
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: dims(:)
    integer, allocatable, intent(out) :: values(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: varid, status
    integer, allocatable :: counts(:)

    call find_var(path, ncid, name, dims, .false., varid, counts, error)
    if (allocated(error)) return
    allocate(values(product(counts)))
    status = nf90_get_var(ncid, varid, values, start=spread(1, 1, size(counts)), count=counts)
    if (status /= NF90_NOERR) then
      call set_error(error, 'RRTMGP file ' // path // ': reading ' // name // ': ' // &
                     trim(nf90_strerror(status)))
    end if
  end subroutine get_int

  !> A list of names (char variable (n, string_len) in CDL), trimmed, NULs blanked, lower case.
  subroutine get_text(path, ncid, name, dim, values, error)
    character(len=*), intent(in) :: path, name, dim
    integer, intent(in) :: ncid
    character(len=GAS_NAME_LEN), allocatable, intent(out) :: values(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: varid, status, i, j
    integer, allocatable :: counts(:)

    call find_var(path, ncid, name, [character(len=40) :: 'string_len', dim], .true., varid, counts, &
                  error)
    if (allocated(error)) return
    if (counts(1) > GAS_NAME_LEN) then
      call set_error(error, 'RRTMGP file ' // path // ': ' // name // ' has strings of ' // &
                     str(counts(1)) // ' characters, at most ' // str(GAS_NAME_LEN) // ' supported')
      return
    end if
    allocate(values(counts(2)))
    values = ''
    status = nf90_get_var(ncid, varid, values, start=[1, 1], count=[counts(1), counts(2)])
    if (status /= NF90_NOERR) then
      call set_error(error, 'RRTMGP file ' // path // ': reading ' // name // ': ' // &
                     trim(nf90_strerror(status)))
      return
    end if
    do i = 1, size(values)
      do j = 1, GAS_NAME_LEN
        if (values(i)(j:j) == achar(0)) values(i)(j:j) = ' '
      end do
      values(i) = to_lower(adjustl(values(i)))
    end do
  end subroutine get_text

end module kumo_rrtmgp_file
