! SPDX-License-Identifier: BSD-3-Clause
!> Band-averaged Mie tables of liquid clouds (kumo_band_mie) on disk: netCDF write and read, and
!> a cache that reuses a file whose metadata match the request exactly. A table for all bands of
!> a shortwave k-distribution takes minutes to compute (docs/cloud-optics-bands.md), so runs
!> keep it in a file.
!>
!> File (netCDF-4 classic model, CF-1.8; `ncdump` order of dimensions):
!>
!>     dimensions: band = nb ; radius = nr ; angle = nang ;
!>     double wavenumber_lower(band), wavenumber_upper(band)      band limits, "cm-1"
!>     double wavenumber_lower_used(band), wavenumber_upper_used(band)  averaged part, "cm-1"
!>     int    nodes(band)                         wavenumber nodes of each band's average
!>     double r_eff(radius)                       effective radius, "um"
!>     double ext_per_lwc(band, radius)           "m2 g-1"
!>     double ssa(band, radius), asymmetry(band, radius)        "1"
!>     double angle(angle)                        "degree"
!>     double phase_function(band, radius, angle) "1", (1/2) Int P dcos = 1
!>     global: Conventions, title, kumo_band_mie_version, source_temperature_K (0: flat),
!>             nodes_per_band (requested minimum), size_distribution, effective_variance, dlnr_phase,
!>             refractive_index_source
!>
!> Files are written to `<path>.tmp` and renamed to `<path>` after a successful close.
module kumo_band_mie_file
  use, intrinsic :: iso_c_binding, only: c_null_char
  use netcdf, only: nf90_create, nf90_open, nf90_close, nf90_enddef, nf90_def_dim, &
                    nf90_def_var, nf90_put_att, nf90_get_att, nf90_put_var, nf90_get_var, &
                    nf90_inq_varid, NF90_NOWRITE, NF90_NOCLOBBER, NF90_NETCDF4, &
                    NF90_CLASSIC_MODEL, NF90_GLOBAL, NF90_INT
  use kumo_kinds, only: wp, i8
  use kumo_error, only: error_t, set_error, str
  use kumo_file_check, only: check_netcdf_complete
  use kumo_mie, only: DIST_NAMES, DLNR_DEFAULT
  use kumo_water_index, only: WATER_INDEX_SOURCE
  use kumo_band_mie, only: band_mie_t, band_mie_build
  use kumo_netcdf, only: c_rename, c_remove, explain_write_failure, reserve_space
  use kumo_nc_table, only: nc_check, nc_def_double, nc_put_global, nc_get_global, nc_dim_len, &
                           nc_get_values
  implicit none
  private
  public :: write_band_mie, read_band_mie, band_mie_cached, BAND_MIE_VERSION

  !> Version of the file layout and of the computation; a file of another version is rebuilt.
  integer, parameter :: BAND_MIE_VERSION = 1
  integer, parameter :: CREATE_MODE = ior(NF90_NOCLOBBER, ior(NF90_NETCDF4, NF90_CLASSIC_MODEL))

contains

  !> Write `bm` to `path` (atomically, through `path.tmp`).
  subroutine write_band_mie(path, bm, error)
    character(len=*), intent(in) :: path
    type(band_mie_t), intent(in) :: bm
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'write_band_mie'
    character(len=:), allocatable :: tmp, at
    integer :: ncid, db, dr, da, v(11), status
    type(error_t), allocatable :: close_error
    integer(i8) :: n_data

    tmp = trim(path)//'.tmp'
    at = PROC//'('//trim(path)//')'
    if (bm%nband < 1 .or. .not. allocated(bm%phase)) then
      call set_error(error, at//': the table is empty')
      return
    end if
    n_data = 8_i8*(4_i8*bm%nband + size(bm%r_eff_um) + 3_i8*size(bm%ssa, kind=i8) + &
                   size(bm%angle_deg) + size(bm%phase, kind=i8))
    call reserve_space(tmp, n_data, n_data + 65536_i8 + 11_i8*4096_i8, error)
    if (allocated(error)) return
    status = c_remove(tmp//c_null_char)
    call nc_check(nf90_create(tmp, CREATE_MODE, ncid), PROC//'('//tmp//')', error)
    if (allocated(error)) then
      call explain_write_failure(tmp, error)
      status = c_remove(tmp//c_null_char)
      return
    end if
    call define()
    if (.not. allocated(error)) call nc_check(nf90_enddef(ncid), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(1), bm%wn_lo), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(2), bm%wn_hi), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(3), bm%wn_lo_used), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(4), bm%wn_hi_used), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(5), bm%r_eff_um), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(6), bm%ext_per_lwc), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(7), bm%ssa), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(8), bm%g), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(9), bm%angle_deg), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(10), bm%phase), at, error)
    if (.not. allocated(error)) call nc_check(nf90_put_var(ncid, v(11), bm%nodes), at, error)
    call nc_check(nf90_close(ncid), at, close_error)
    if (.not. allocated(error) .and. allocated(close_error)) call move_alloc(close_error, error)
    if (allocated(error)) then
      call explain_write_failure(tmp, error)
      status = c_remove(tmp//c_null_char)
      return
    end if
    if (c_rename(tmp//c_null_char, trim(path)//c_null_char) /= 0) then
      status = c_remove(tmp//c_null_char)
      call set_error(error, at//': cannot rename '//tmp//' to '//trim(path))
    end if
  contains
    subroutine define()
      call nc_check(nf90_def_dim(ncid, 'band', bm%nband, db), at, error)
      if (.not. allocated(error)) call nc_check(nf90_def_dim(ncid, 'radius', size(bm%r_eff_um), dr), at, error)
      if (.not. allocated(error)) call nc_check(nf90_def_dim(ncid, 'angle', size(bm%angle_deg), da), at, error)
      if (allocated(error)) return
      call nc_def_double(ncid, at, error, 'wavenumber_lower', [db], 'lower limit of the band', 'cm-1', v(1))
      call nc_def_double(ncid, at, error, 'wavenumber_upper', [db], 'upper limit of the band', 'cm-1', v(2))
      call nc_def_double(ncid, at, error, 'wavenumber_lower_used', [db], 'lower limit of the averaged part of the band', &
                   'cm-1', v(3))
      call nc_def_double(ncid, at, error, 'wavenumber_upper_used', [db], 'upper limit of the averaged part of the band', &
                   'cm-1', v(4))
      if (.not. allocated(error)) then
        call nc_check(nf90_def_var(ncid, 'nodes', NF90_INT, [db], v(11)), at//':nodes', error)
      end if
      if (.not. allocated(error)) then
        call nc_check(nf90_put_att(ncid, v(11), 'long_name', 'wavenumber nodes of the band average'), &
                      at//':nodes', error)
      end if
      call nc_def_double(ncid, at, error, 'r_eff', [dr], 'effective radius of the size distribution', 'um', v(5))
      call nc_def_double(ncid, at, error, 'ext_per_lwc', [dr, db], &
                   'band-averaged extinction coefficient per unit liquid water content', 'm2 g-1', v(6))
      call nc_def_double(ncid, at, error, 'ssa', [dr, db], 'band-averaged single-scattering albedo', '1', v(7))
      call nc_def_double(ncid, at, error, 'asymmetry', [dr, db], 'band-averaged asymmetry parameter', '1', v(8))
      call nc_def_double(ncid, at, error, 'angle', [da], 'scattering angle', 'degree', v(9))
      call nc_def_double(ncid, at, error, 'phase_function', [da, dr, db], &
                   'band-averaged phase function, (1/2) integral over cos(angle) = 1', '1', v(10))
      if (allocated(error)) return
      call nc_put_global(ncid, at, error, 'Conventions', 'CF-1.8')
      call nc_put_global(ncid, at, error, 'title', 'kumo band-averaged Mie table of liquid water clouds')
      call nc_put_global(ncid, at, error, 'size_distribution', trim(DIST_NAMES(bm%dist)))
      call nc_put_global(ncid, at, error, 'refractive_index_source', WATER_INDEX_SOURCE)
      if (allocated(error)) return
      call nc_check(nf90_put_att(ncid, NF90_GLOBAL, 'kumo_band_mie_version', BAND_MIE_VERSION), at, error)
      if (.not. allocated(error)) then
        call nc_check(nf90_put_att(ncid, NF90_GLOBAL, 'nodes_per_band', bm%n_nodes), at, error)
      end if
      call nc_put_global(ncid, at, error, 'source_temperature_K', bm%t_source_k)
      call nc_put_global(ncid, at, error, 'effective_variance', bm%v_eff)
      call nc_put_global(ncid, at, error, 'dlnr_phase', bm%dlnr)
    end subroutine define
  end subroutine write_band_mie

  !> Read a table written by `write_band_mie`.
  subroutine read_band_mie(path, bm, error)
    character(len=*), intent(in) :: path
    type(band_mie_t), intent(out) :: bm
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'read_band_mie'
    character(len=:), allocatable :: at, dist_name
    type(error_t), allocatable :: close_error
    integer :: ncid, nb, nr, nang, version, i

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
      integer :: n_nodes
      call nc_check(nf90_get_att(ncid, NF90_GLOBAL, 'kumo_band_mie_version', version), &
                    at//':kumo_band_mie_version', error)
      if (allocated(error)) return
      if (version /= BAND_MIE_VERSION) then
        call set_error(error, at//': kumo_band_mie_version = '//str(version)// &
                       ' but this kumo reads version '//str(BAND_MIE_VERSION))
        return
      end if
      call nc_check(nf90_get_att(ncid, NF90_GLOBAL, 'nodes_per_band', n_nodes), &
                    at//':nodes_per_band', error)
      bm%n_nodes = n_nodes
      call nc_get_global(ncid, at, error, 'source_temperature_K', bm%t_source_k)
      call nc_get_global(ncid, at, error, 'effective_variance', bm%v_eff)
      call nc_get_global(ncid, at, error, 'dlnr_phase', bm%dlnr)
      if (allocated(error)) return
      call nc_get_global(ncid, at, error, 'size_distribution', dist_name)
      if (allocated(error)) return
      bm%dist = 0
      do i = 1, size(DIST_NAMES)
        if (dist_name == trim(DIST_NAMES(i))) bm%dist = i
      end do
      if (bm%dist == 0) then
        call set_error(error, at//': size_distribution = "'//dist_name//'" must be gamma or lognormal')
        return
      end if
      call nc_dim_len(ncid, at, error, 'band', nb)
      call nc_dim_len(ncid, at, error, 'radius', nr)
      call nc_dim_len(ncid, at, error, 'angle', nang)
      if (allocated(error)) return
      bm%nband = nb
      allocate (bm%nodes(nb))
      call nc_check(nf90_inq_varid(ncid, 'nodes', i), at//':nodes', error)
      if (allocated(error)) return
      call nc_check(nf90_get_var(ncid, i, bm%nodes), at//':nodes', error)
      if (allocated(error)) return
      allocate (bm%wn_lo(nb), bm%wn_hi(nb), bm%wn_lo_used(nb), bm%wn_hi_used(nb), bm%r_eff_um(nr), &
                bm%ext_per_lwc(nr, nb), bm%ssa(nr, nb), bm%g(nr, nb), bm%angle_deg(nang), &
                bm%phase(nang, nr, nb))
      call nc_get_values(ncid, at, error, 'wavenumber_lower', bm%wn_lo)
      call nc_get_values(ncid, at, error, 'wavenumber_upper', bm%wn_hi)
      call nc_get_values(ncid, at, error, 'wavenumber_lower_used', bm%wn_lo_used)
      call nc_get_values(ncid, at, error, 'wavenumber_upper_used', bm%wn_hi_used)
      call nc_get_values(ncid, at, error, 'r_eff', bm%r_eff_um)
      call nc_get_values(ncid, at, error, 'angle', bm%angle_deg)
      if (allocated(error)) return
      call nc_get_values(ncid, at, error, 'ext_per_lwc', bm%ext_per_lwc)
      call nc_get_values(ncid, at, error, 'ssa', bm%ssa)
      call nc_get_values(ncid, at, error, 'asymmetry', bm%g)
      if (allocated(error)) return
      call nc_get_values(ncid, at, error, 'phase_function', bm%phase)
    end subroutine body
  end subroutine read_band_mie

  !> The band-averaged Mie table for the request (arguments as band_mie_build, with the default
  !> phase-function step): read from `path` if that file exists and its version, band limits,
  !> source temperature, nodes per band, distribution, effective variance, phase step and radii
  !> all equal the request exactly; otherwise computed and written to `path` (atomically).
  !> `action` is "read" or "computed: <reason>".
  subroutine band_mie_cached(path, wn_lo, wn_hi, t_source_k, dist, v_eff, r_eff_um, n_nodes, bm, &
                             action, error)
    character(len=*), intent(in) :: path
    real(wp), intent(in) :: wn_lo(:), wn_hi(:)
    real(wp), intent(in) :: t_source_k
    integer, intent(in) :: dist
    real(wp), intent(in) :: v_eff
    real(wp), intent(in) :: r_eff_um(:)
    integer, intent(in) :: n_nodes
    type(band_mie_t), intent(out) :: bm
    character(len=:), allocatable, intent(out) :: action
    type(error_t), allocatable, intent(out) :: error
    logical :: exists
    type(error_t), allocatable :: read_error

    inquire (file=trim(path), exist=exists)
    if (exists) then
      call read_band_mie(path, bm, read_error)
      if (allocated(read_error)) then
        action = 'computed: existing file unreadable ('//read_error%message//')'
      else
        action = mismatch()
        if (len(action) == 0) then
          action = 'read'
          return
        end if
        action = 'computed: '//action
      end if
    else
      action = 'computed: no file'
    end if
    call band_mie_build(wn_lo, wn_hi, t_source_k, dist, v_eff, r_eff_um, n_nodes, bm, error)
    if (allocated(error)) then
      error%message = 'band_mie_cached: '//error%message
      return
    end if
    call write_band_mie(path, bm, error)
  contains
    function mismatch() result(why)
      character(len=:), allocatable :: why
      why = ''
      if (bm%nband /= size(wn_lo)) then
        why = 'number of bands in file '//str(bm%nband)//' differs from '//str(size(wn_lo))
      else if (any(bm%wn_lo /= wn_lo) .or. any(bm%wn_hi /= wn_hi)) then
        why = 'band limits in file differ'
      else if (bm%t_source_k /= t_source_k) then
        why = 'source_temperature_K in file '//str(bm%t_source_k)//' differs from '//str(t_source_k)
      else if (bm%n_nodes /= n_nodes) then
        why = 'nodes_per_band in file '//str(bm%n_nodes)//' differs from '//str(n_nodes)
      else if (bm%dist /= dist) then
        why = 'size_distribution in file differs'
      else if (bm%v_eff /= v_eff) then
        why = 'effective_variance in file '//str(bm%v_eff)//' differs from '//str(v_eff)
      else if (bm%dlnr /= DLNR_DEFAULT) then
        why = 'dlnr_phase in file differs'
      else if (size(bm%r_eff_um) /= size(r_eff_um)) then
        why = 'number of radii in file '//str(size(bm%r_eff_um))//' differs from '// &
              str(size(r_eff_um))
      else if (any(bm%r_eff_um /= r_eff_um)) then
        why = 'effective radii in file differ'
      end if
    end function mismatch
  end subroutine band_mie_cached

end module kumo_band_mie_file
