! SPDX-License-Identifier: BSD-3-Clause
!> netCDF input and output: the 3-D scene, surface albedo and BRDF maps, 1-D variables, and the
!> result file (any result set of kumo_results, with its CF attributes).
!>
!> The LES reader (kumo_les_netcdf), the Mie-table cache (kumo_mie_table) and the RRTMGP reader
!> (kumo_rrtmgp_file) use the netCDF library too, through the helpers here. Every library call
!> is checked; a failure
!> returns an `error_t` whose message reads `<routine>(<file>:<variable>): <netCDF message>`, and
!> nothing here stops the program.
!>
!> Dimension order: the netCDF Fortran API lists dimensions with the fastest-varying first, the
!> reverse of what `ncdump` shows. A Fortran array `ext(nx, ny, nz, ncomp)` is the file variable
!> `extinction(component, z, y, x)`. The file formats are described in `docs/input-netcdf.md`.
!>
!> Files are written atomically: the data go to `<path>.tmp` in the same directory, which is
!> renamed to `<path>` only after it was closed without error, and removed on any error. A failed
!> write therefore never leaves a partial file behind, and an older file at `<path>` stays intact.
!> The temporary file is created exclusively after a stale one is removed (a link there is never
!> followed). Files read are first checked for data cut short (kumo_file_check). A write that
!> fails because the file system takes no more data (full disk, quota, file size limit) is
!> reported as such, not as the netCDF library's "NetCDF: HDF error" (`explain_write_failure`).
module kumo_netcdf
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_null_char, c_funptr, c_intptr_t, &
                                         c_null_funptr
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
  use netcdf, only: nf90_create, nf90_open, nf90_close, nf90_enddef, nf90_def_dim, nf90_def_var, &
                    nf90_put_att, nf90_get_att, nf90_put_var, nf90_get_var, nf90_inq_dimid, &
                    nf90_inq_varid, nf90_inquire_dimension, nf90_inquire_variable, &
                    nf90_inquire_attribute, nf90_strerror, NF90_NOERR, NF90_ENOTATT, &
                    NF90_NOWRITE, NF90_NOCLOBBER, NF90_NETCDF4, NF90_CLASSIC_MODEL, NF90_GLOBAL, &
                    NF90_DOUBLE, NF90_FLOAT, NF90_INT, NF90_SHORT, NF90_BYTE, NF90_CHAR, &
                    NF90_FILL_DOUBLE, NF90_FILL_FLOAT, NF90_FILL_INT, NF90_FILL_SHORT, &
                    NF90_FILL_BYTE, NF90_MAX_VAR_DIMS, NF90_MAX_NAME
  use kumo_kinds, only: wp, dp, i8
  use kumo_error, only: error_t, set_error, join, str, to_lower
  use kumo_file_check, only: check_netcdf_complete
  use kumo_results, only: result_set_t, var_size, var_has_stderr, var_values
  use kumo_brdf, only: BRDF_NPAR, BRDF_NAMES, BRDF_DSM, cox_munk_slope_variance
  implicit none
  private
  public :: write_results, check_writable
  public :: read_scene_3d, write_scene_3d, read_albedo_map, read_brdf_map, &
            read_scene_temperature, read_temperature_map
  public :: BRDF_MAP_VARS
  public :: c_rename, c_remove, explain_write_failure, ignore_file_size_signal, reserve_space
  public :: read_var_1d, read_text_attr

  !> netCDF-4 file restricted to the classic data model (readable by every netCDF-4 tool).
  !> Output files are created exclusively (after removing a stale temporary file, which
  !> unlinks a symbolic link instead of following it), so a link planted at <file>.tmp can never
  !> make kumo write elsewhere.
  integer, parameter :: CREATE_MODE = ior(NF90_NOCLOBBER, ior(NF90_NETCDF4, NF90_CLASSIC_MODEL))
  character(len=*), parameter :: CONVENTIONS = 'CF-1.8'
  character(len=*), parameter :: TMP_SUFFIX = '.tmp'
  !> Bytes appended to a file whose write failed, to ask the file system why (more than the few
  !> bytes a full file system may still have in a partly used block).
  integer, parameter :: PROBE_BYTES = 1048576
  !> SIGXFSZ (POSIX: Linux, the BSDs and macOS all use 25), raised by a write beyond the
  !> process's file size limit; ignored, the write fails with EFBIG and is reported instead.
  integer(c_int), parameter :: SIGNAL_XFSZ = 25_c_int
  character(len=*), parameter :: DEFAULT_ALBEDO_NAME = 'albedo'
  !> Conversion of an extinction coefficient from km-1 to m-1.
  real(wp), parameter :: PER_KM_TO_PER_M = 1.0e-3_wp

  !> Scene file: dimension names in Fortran order (first varies fastest), and as ncdump shows them.
  character(len=*), parameter :: SCENE_DIM_NAMES(4) = &
                                 [character(len=9) :: 'x', 'y', 'z', 'component']
  character(len=*), parameter :: SCENE_INDEX = '(x,y,z,component)'
  character(len=*), parameter :: SCENE_CDL_DIMS = '(component, z, y, x)'
  !> BRDF map: the variable of each parameter slot c(1:5) per kind (blank: unused). DSM's
  !> slope variance may be given instead as `wind_speed` [m s-1] (Cox-Munk).
  character(len=21), parameter :: BRDF_MAP_VARS(BRDF_NPAR, 0:4) = reshape([ &
    character(len=21) :: '', '', '', '', '', &
    'albedo', '', '', '', '', &
    'diffuse_albedo', 'diffuse_fraction', 'refractive_index_real', 'refractive_index_imag', &
    'slope_variance', &
    'rho0', 'k', 'theta', 'hotspot', '', &
    'k_iso', 'k_geo', 'k_vol', '', ''], [BRDF_NPAR, 5])
  !> Albedo map: dimension names in Fortran order, and as ncdump shows them.
  character(len=*), parameter :: MAP_DIM_NAMES(2) = [character(len=2) :: 'xs', 'ys']
  character(len=*), parameter :: MAP_INDEX = '(xs,ys)'
  character(len=*), parameter :: MAP_CDL_DIMS = '(ys, xs)'

  ! Assumed-size character dummies are how Fortran 2008 passes a C string (`char *`); assumed shape
  ! is not interoperable before Fortran 2018.
  ! allow(C071)
  interface
    !> C `rename` (stdio.h): atomic replacement of `newpath` on POSIX file systems.
    function c_rename(oldpath, newpath) bind(C, name='rename') result(status)
      import :: c_char, c_int
      implicit none
      character(kind=c_char), intent(in) :: oldpath(*)
      character(kind=c_char), intent(in) :: newpath(*)
      integer(c_int) :: status
    end function c_rename

    !> C `signal` (signal.h): set the action of a signal; returns the previous one.
    function c_signal(signum, handler) bind(C, name='signal') result(previous)
      import :: c_int, c_funptr
      implicit none
      integer(c_int), value :: signum
      type(c_funptr), value :: handler
      type(c_funptr) :: previous
    end function c_signal

    !> C `remove` (stdio.h): delete a file.
    function c_remove(path) bind(C, name='remove') result(status)
      import :: c_char, c_int
      implicit none
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: status
    end function c_remove
  end interface

contains

  ! ------------------------------------------------------------------------------------------------
  ! Output
  ! ------------------------------------------------------------------------------------------------

  !> Write a result set as a CF-1.8 netCDF-4 (classic model) file, atomically.
  !>
  !> Each dimension is written; a dimension with `coord` allocated also gets a coordinate variable.
  !> Each result variable becomes a double variable `<name>` (the mean) and, if its standard error
  !> is allocated, `<name>_stderr`. The set is validated first (dimensions exist, sizes agree,
  !> values finite, standard errors >= 0): an invalid set creates no file at all.
  subroutine write_results(path, set, error)
    character(len=*), intent(in) :: path                !! output file
    type(result_set_t), intent(in) :: set               !! dimensions, variables, global attributes
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'write_results'
    integer :: ncid
    integer(i8) :: nb_min, nb_max

    call validate_result_set(PROC, trim(path), set, error)
    if (allocated(error)) return
    call result_set_bytes(set, nb_min, nb_max)
    call reserve_space(trim(path)//TMP_SUFFIX, nb_min, nb_max, error)
    if (allocated(error)) return
    call create_temp(PROC, trim(path), ncid, error)
    if (allocated(error)) return
    call write_results_body(PROC, trim(path), ncid, set, error)
    call commit_temp(PROC, trim(path), ncid, error)
  end subroutine write_results

  !> Check, before a run starts, that the output file can be created: a probe file `<path>.tmp`
  !> is created, closed and deleted. The error message names the path.
  subroutine check_writable(path, error)
    character(len=*), intent(in) :: path                !! output file the run will write
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'check_writable'
    character(len=512) :: msg
    character(len=:), allocatable :: fname, at
    integer :: unit, ios
    logical :: is_dir

    fname = trim(path)
    at = where_text(PROC, fname, '')
    if (len(fname) == 0) then
      call set_error(error, at//': output path is empty')
      return
    end if
    ! A directory "exists" with "/." appended; a regular file does not.
    inquire (file=fname//'/.', exist=is_dir)
    if (is_dir) then
      call set_error(error, at//': output path is a directory')
      return
    end if
    ! a stale probe or temporary file (or a link of that name) goes first; the probe is then
    ! created exclusively, so a link is never followed
    call remove_file(fname//TMP_SUFFIX)
    open (newunit=unit, file=fname//TMP_SUFFIX, status='new', action='write', iostat=ios, &
          iomsg=msg)
    if (ios /= 0) then
      call set_error(error, at//': cannot create the output file: '//trim(msg))
      return
    end if
    close (unit, status='delete', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call set_error(error, at//': cannot delete the probe file '//fname//TMP_SUFFIX//': '// &
                     trim(msg))
    end if
  end subroutine check_writable

  !> Write a 3-D scene file in the format read by `read_scene_3d`, atomically.
  !>
  !> The arrays are validated with the reader's rules first, so a file written here always reads
  !> back. `ext_units` selects the units stored in the file ("m-1", the default, or "km-1"); the
  !> values passed in are always in m-1.
  subroutine write_scene_3d(path, ext, ssa, phase_index, error, ext_units, temperature)
    character(len=*), intent(in) :: path                !! output file
    real(wp), intent(in) :: ext(:, :, :, :)             !! extinction (nx, ny, nz3, ncomp) [m-1]
    real(wp), intent(in) :: ssa(:, :, :, :)             !! single-scattering albedo, same shape [1]
    integer, intent(in), optional :: phase_index(:, :, :, :) !! 1-based phase function index
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: ext_units !! "m-1" (default) or "km-1"
    real(wp), intent(in), optional :: temperature(:, :, :) !! voxel temperatures (nx, ny, nz3) [K]
    character(len=*), parameter :: PROC = 'write_scene_3d'
    real(wp), parameter :: FILL = real(NF90_FILL_DOUBLE, wp)
    character(len=:), allocatable :: fname, units, at_ext, at_ssa, at_phase
    integer :: ncid

    fname = trim(path)
    at_ext = where_text(PROC, fname, 'extinction')
    at_ssa = where_text(PROC, fname, 'ssa')
    at_phase = where_text(PROC, fname, 'phase_index')
    units = 'm-1'
    if (present(ext_units)) units = trim(ext_units)
    if (units /= 'm-1' .and. units /= 'km-1') then
      call set_error(error, at_ext//': ext_units = "'//units// &
                     '" not allowed; allowed units are "m-1" and "km-1"')
      return
    end if
    if (any(shape(ssa) /= shape(ext))) then
      call set_error(error, at_ssa//': shape '//join(shape(ssa), ',', '()')// &
                     ' differs from the shape of extinction '//join(shape(ext), ',', '()'))
      return
    end if
    if (present(phase_index)) then
      if (any(shape(phase_index) /= shape(ext))) then
        call set_error(error, at_phase//': shape '//join(shape(phase_index), ',', '()')// &
                       ' differs from the shape of extinction '//join(shape(ext), ',', '()'))
        return
      end if
    end if
    if (size(ext) == 0) then
      call set_error(error, at_ext//': every dimension must be >= 1, shape is '// &
                     join(shape(ext), ',', '()'))
      return
    end if
    call check_real_4d(at_ext, ext, FILL, .false., error)
    if (allocated(error)) return
    call check_real_4d(at_ssa, ssa, FILL, .true., error)
    if (allocated(error)) return
    if (present(phase_index)) then
      call check_index_4d(at_phase, phase_index, NF90_FILL_INT, error)
      if (allocated(error)) return
    end if

    call create_temp(PROC, fname, ncid, error)
    if (allocated(error)) return
    if (present(temperature)) then
      if (any(shape(temperature) /= shape(ext(:, :, :, 1)))) then
        call set_error(error, where_text(PROC, fname, 'temperature')//': shape '// &
                       join(shape(temperature), ',', '()')//' differs from the grid '// &
                       join(shape(ext(:, :, :, 1)), ',', '()'))
        return
      end if
    end if
    call write_scene_body(PROC, fname, ncid, ext, units, ssa, phase_index, error, temperature)
    call commit_temp(PROC, fname, ncid, error)
  end subroutine write_scene_3d

  ! ------------------------------------------------------------------------------------------------
  ! Input
  ! ------------------------------------------------------------------------------------------------

  !> Read the optical properties of the 3-D region from a scene file (see docs/input-netcdf.md).
  !>
  !> The dimensions `x`, `y`, `z`, `component` must have the expected sizes. Extinction in "km-1"
  !> is converted to m-1. Values are validated: extinction finite and >= 0, ssa finite in [0, 1],
  !> phase_index >= 1; fill values (missing data) and packed variables are rejected. On error all
  !> outputs are deallocated.
  subroutine read_scene_3d(path, nx, ny, nz3, ncomp, ext, ssa, phase_index, has_phase_index, error)
    character(len=*), intent(in) :: path                !! scene file
    integer, intent(in) :: nx                           !! expected size of dimension x
    integer, intent(in) :: ny                           !! expected size of dimension y
    integer, intent(in) :: nz3                          !! expected layers of the 3-D region (z)
    integer, intent(in) :: ncomp                        !! expected number of components
    real(wp), allocatable, intent(out) :: ext(:, :, :, :) !! extinction (nx, ny, nz3, ncomp) [m-1]
    real(wp), allocatable, intent(out) :: ssa(:, :, :, :) !! single-scattering albedo [1]
    integer, allocatable, intent(out) :: phase_index(:, :, :, :) !! allocated if present in the file
    logical, intent(out) :: has_phase_index             !! whether the file has phase_index
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'read_scene_3d'
    integer :: ncid

    has_phase_index = .false.
    call open_read(PROC, trim(path), ncid, error)
    if (allocated(error)) return
    call read_scene_body(PROC, trim(path), ncid, [nx, ny, nz3, ncomp], ext, ssa, phase_index, &
                         has_phase_index, error)
    call close_read(PROC, trim(path), ncid, error)
    if (allocated(error)) then
      if (allocated(ext)) deallocate (ext)
      if (allocated(ssa)) deallocate (ssa)
      if (allocated(phase_index)) deallocate (phase_index)
      has_phase_index = .false.
    end if
  end subroutine read_scene_3d

  !> Read the optional voxel temperatures of a scene file: variable `temperature` (z, y, x) in
  !> ncdump order, units "K", finite and >= 0; `found` is false when the file has no such
  !> variable. Its dimensions must be the scene's x, y and z of the expected sizes.
  subroutine read_scene_temperature(path, nx, ny, nz3, t, found, error)
    character(len=*), intent(in) :: path
    integer, intent(in) :: nx, ny, nz3
    real(wp), allocatable, intent(out) :: t(:, :, :)   !! (nx, ny, nz3) [K]
    logical, intent(out) :: found
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'read_scene_temperature'
    integer :: ncid, varid, dimids(3), i, length, status
    integer :: expected(3)
    real(wp) :: fill
    real(wp), allocatable :: t4(:, :, :, :)
    character(len=:), allocatable :: at, units
    logical :: has_units

    found = .false.
    expected = [nx, ny, nz3]
    call open_read(PROC, trim(path), ncid, error)
    if (allocated(error)) return
    at = where_text(PROC, trim(path), 'temperature')
    status = nf90_inq_varid(ncid, 'temperature', varid)
    if (status /= NF90_NOERR) then
      call close_read(PROC, trim(path), ncid, error)
      return
    end if
    found = .true.
    do i = 1, 3
      call nc_check(nf90_inq_dimid(ncid, trim(SCENE_DIM_NAMES(i)), dimids(i)), at, error)
      if (allocated(error)) exit
      call nc_check(nf90_inquire_dimension(ncid, dimids(i), len=length), at, error)
      if (allocated(error)) exit
      if (length /= expected(i)) then
        call set_error(error, at//': dimension '//trim(SCENE_DIM_NAMES(i))//' has size '// &
                       str(length)//', the 3-D region '//str(expected(i)))
        exit
      end if
    end do
    if (.not. allocated(error)) call check_real_var(at, ncid, varid, dimids, '(z, y, x)', fill, &
                                                    error)
    if (.not. allocated(error)) then
      call get_text_att(PROC, trim(path), ncid, varid, 'units', units, has_units, error)
      if (.not. allocated(error) .and. (.not. has_units .or. units /= 'K')) &
        call set_error(error, at//': units must be "K"')
    end if
    if (.not. allocated(error)) then
      allocate (t(nx, ny, nz3))
      call nc_check(nf90_get_var(ncid, varid, t), at, error)
    end if
    if (.not. allocated(error)) then
      t4 = reshape(t, [nx, ny, nz3, 1])
      call check_real_4d(at, t4, fill, .false., error)
    end if
    if (allocated(error)) then
      status = nf90_close(ncid)
      if (allocated(t)) deallocate (t)
      return
    end if
    call close_read(PROC, trim(path), ncid, error)
  end subroutine read_scene_temperature

  !> Read a 2-D surface albedo map `albedo(ys, xs)` (ncdump order) on its own grid.
  !>
  !> The sizes come from the file. Values must be finite and within [0, 1].
  subroutine read_albedo_map(path, varname, nxs, nys, albedo, error)
    character(len=*), intent(in) :: path                !! map file
    character(len=*), intent(in) :: varname             !! variable name; blank means "albedo"
    integer, intent(out) :: nxs                         !! size of dimension xs
    integer, intent(out) :: nys                         !! size of dimension ys
    real(wp), allocatable, intent(out) :: albedo(:, :)  !! albedo (nxs, nys) [1]
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'read_albedo_map'
    character(len=:), allocatable :: name
    integer :: ncid

    nxs = 0
    nys = 0
    name = trim(varname)
    if (len(name) == 0) name = DEFAULT_ALBEDO_NAME
    call open_read(PROC, trim(path), ncid, error)
    if (allocated(error)) return
    call read_albedo_body(PROC, trim(path), ncid, name, nxs, nys, albedo, error)
    call close_read(PROC, trim(path), ncid, error)
    if (allocated(error)) then
      if (allocated(albedo)) deallocate (albedo)
      nxs = 0
      nys = 0
    end if
  end subroutine read_albedo_map

  !> Read a 2-D surface temperature map `t(ys, xs)` (ncdump order, units "K", finite, >= 0) on
  !> its own grid over the domain, like the albedo map.
  subroutine read_temperature_map(path, varname, nxs, nys, t, error)
    character(len=*), intent(in) :: path, varname
    integer, intent(out) :: nxs, nys
    real(wp), allocatable, intent(out) :: t(:, :)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'read_temperature_map'
    integer :: ncid
    nxs = 0
    nys = 0
    call open_read(PROC, trim(path), ncid, error)
    if (allocated(error)) return
    call read_albedo_body(PROC, trim(path), ncid, trim(varname), nxs, nys, t, error, &
                          temperature=.true.)
    call close_read(PROC, trim(path), ncid, error)
    if (allocated(error)) then
      if (allocated(t)) deallocate (t)
      nxs = 0
      nys = 0
    end if
  end subroutine read_temperature_map

  !> Read a BRDF map: dimensions `xs`, `ys`; optional integer `brdf_kind(ys, xs)` with the kind
  !> code of each pixel (0 black, 1 Lambert, 2 DSM, 3 RPV, 4 LSRT; without it every pixel has
  !> `default_kind`), and for each kind present its parameter variables (ys, xs), named in
  !> BRDF_MAP_VARS (DSM: `wind_speed` [m s-1] in place of `slope_variance` is converted by
  !> Cox-Munk). Parameters are read, and must be finite and not missing, only at the pixels of
  !> their kind; they are returned in the MCARaTS slot order c(1:5). Their ranges are checked
  !> by the caller (brdf_validate, per pixel).
  subroutine read_brdf_map(path, default_kind, nxs, nys, kind, c, error)
    character(len=*), intent(in) :: path                 !! map file
    integer, intent(in) :: default_kind                  !! kind of every pixel without brdf_kind
    integer, intent(out) :: nxs, nys                     !! sizes of dimensions xs and ys
    integer, allocatable, intent(out) :: kind(:, :)      !! kind code per pixel (nxs, nys)
    real(wp), allocatable, intent(out) :: c(:, :, :)     !! parameters (BRDF_NPAR, nxs, nys)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'read_brdf_map'
    integer :: ncid
    nxs = 0
    nys = 0
    call open_read(PROC, trim(path), ncid, error)
    if (allocated(error)) return
    call read_brdf_body(PROC, trim(path), ncid, default_kind, kind, c, error)
    call close_read(PROC, trim(path), ncid, error)
    if (allocated(error)) then
      if (allocated(kind)) deallocate (kind)
      if (allocated(c)) deallocate (c)
    else
      nxs = size(kind, 1)
      nys = size(kind, 2)
    end if
  end subroutine read_brdf_map

  subroutine read_brdf_body(routine, path, ncid, default_kind, kind, c, error)
    character(len=*), intent(in) :: routine, path
    integer, intent(in) :: ncid, default_kind
    integer, allocatable, intent(out) :: kind(:, :)
    real(wp), allocatable, intent(out) :: c(:, :, :)
    type(error_t), allocatable, intent(out) :: error
    integer :: dimids(2), lengths(2), varid, i, k, ix, iy, ifill, status
    real(wp) :: fill
    real(wp), allocatable :: v(:, :)
    character(len=:), allocatable :: at, name, units
    logical :: found, wind

    do i = 1, 2
      at = where_text(routine, path, trim(MAP_DIM_NAMES(i)))
      call nc_check(nf90_inq_dimid(ncid, trim(MAP_DIM_NAMES(i)), dimids(i)), at, error)
      if (allocated(error)) return
      call nc_check(nf90_inquire_dimension(ncid, dimids(i), len=lengths(i)), at, error)
      if (allocated(error)) return
    end do
    allocate (kind(lengths(1), lengths(2)), c(BRDF_NPAR, lengths(1), lengths(2)))
    c = 0.0_wp
    at = where_text(routine, path, 'brdf_kind')
    if (nf90_inq_varid(ncid, 'brdf_kind', varid) == NF90_NOERR) then
      call check_layout(at, ncid, varid, dimids, MAP_CDL_DIMS, error)
      if (allocated(error)) return
      call integer_fill(at, ncid, varid, ifill, error)
      if (allocated(error)) return
      call nc_check(nf90_get_var(ncid, varid, kind), at, error)
      if (allocated(error)) return
      do iy = 1, lengths(2)
        do ix = 1, lengths(1)
          if (kind(ix, iy) == ifill) then
            call set_error(error, at//': value '//str(kind(ix, iy))//' at '//MAP_INDEX// &
                           ' = '//join([ix, iy], ',', '()')//' is the fill value (missing data)')
            return
          else if (kind(ix, iy) < 0 .or. kind(ix, iy) > 4) then
            call set_error(error, at//': value '//str(kind(ix, iy))//' at '//MAP_INDEX// &
                           ' = '//join([ix, iy], ',', '()')//' must be 0 (black), 1 (Lambert), '// &
                           '2 (DSM), 3 (RPV) or 4 (LSRT)')
            return
          end if
        end do
      end do
    else
      kind = default_kind
    end if

    allocate (v(lengths(1), lengths(2)))
    do k = 1, 4
      if (.not. any(kind == k)) cycle
      do i = 1, BRDF_NPAR
        name = trim(BRDF_MAP_VARS(i, k))
        if (len(name) == 0) cycle
        wind = .false.
        status = nf90_inq_varid(ncid, name, varid)
        if (status /= NF90_NOERR .and. name == 'slope_variance') then
          wind = nf90_inq_varid(ncid, 'wind_speed', varid) == NF90_NOERR
          if (wind) name = 'wind_speed'
        else if (name == 'slope_variance') then
          if (nf90_inq_varid(ncid, 'wind_speed', ifill) == NF90_NOERR) then
            call set_error(error, where_text(routine, path, 'wind_speed')// &
                           ': give either slope_variance or wind_speed, not both')
            return
          end if
        end if
        at = where_text(routine, path, name)
        if (status /= NF90_NOERR .and. .not. wind) then
          call set_error(error, at//': variable not found; the map has '// &
                         trim(BRDF_NAMES(k))//' pixels, which need '//kind_vars(k))
          return
        end if
        call check_real_var(at, ncid, varid, dimids, MAP_CDL_DIMS, fill, error)
        if (allocated(error)) return
        if (wind) then
          call get_text_att(routine, path, ncid, varid, 'units', units, found, error)
          if (allocated(error)) return
          if (.not. found) units = '(none)'
          if (units /= 'm s-1' .and. units /= 'm/s') then
            call set_error(error, at//': units "'//units//'" not allowed; wind_speed must be'// &
                           ' in "m s-1"')
            return
          end if
        else
          call check_dimensionless(routine, path, at, ncid, varid, error)
          if (allocated(error)) return
        end if
        call nc_check(nf90_get_var(ncid, varid, v), at, error)
        if (allocated(error)) return
        do iy = 1, lengths(2)
          do ix = 1, lengths(1)
            if (kind(ix, iy) /= k) cycle
            if (.not. ieee_is_finite(v(ix, iy)) .or. is_fill(v(ix, iy), fill) .or. &
                (wind .and. v(ix, iy) < 0.0_wp)) then
              call set_error(error, at//': value '//real_text(v(ix, iy))//' at '//MAP_INDEX// &
                             ' = '//join([ix, iy], ',', '()')//' '// &
                             value_problem(v(ix, iy), fill, .false.))
              return
            end if
            c(i, ix, iy) = v(ix, iy)
            if (wind) c(i, ix, iy) = cox_munk_slope_variance(v(ix, iy))
          end do
        end do
      end do
    end do
  contains
    !> The variables a kind needs, as a list for messages.
    function kind_vars(kk) result(text)
      integer, intent(in) :: kk
      character(len=:), allocatable :: text
      text = join(pack(BRDF_MAP_VARS(:, kk), len_trim(BRDF_MAP_VARS(:, kk)) > 0))
      if (kk == BRDF_DSM) text = text//' (or wind_speed)'
    end function kind_vars
  end subroutine read_brdf_body

  !> Read a numeric variable of any rank as doubles, flattened in Fortran order.
  subroutine read_var_1d(path, varname, values, error)
    character(len=*), intent(in) :: path                !! netCDF file
    character(len=*), intent(in) :: varname            !! variable name
    real(dp), allocatable, intent(out) :: values(:)    !! values, first file dimension fastest
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'read_var_1d'
    integer :: ncid

    call open_read(PROC, trim(path), ncid, error)
    if (allocated(error)) return
    call read_var_body(PROC, trim(path), ncid, trim(varname), values, error)
    call close_read(PROC, trim(path), ncid, error)
    if (allocated(error) .and. allocated(values)) deallocate (values)
  end subroutine read_var_1d

  !> Read a global text attribute. Trailing NUL characters written by some C tools are dropped.
  subroutine read_text_attr(path, attname, value, error)
    character(len=*), intent(in) :: path                !! netCDF file
    character(len=*), intent(in) :: attname             !! global attribute name
    character(len=:), allocatable, intent(out) :: value !! attribute text
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PROC = 'read_text_attr'
    integer :: ncid
    logical :: found

    call open_read(PROC, trim(path), ncid, error)
    if (allocated(error)) return
    call get_text_att(PROC, trim(path), ncid, NF90_GLOBAL, trim(attname), value, found, error)
    if (.not. allocated(error) .and. .not. found) then
      call set_error(error, where_text(PROC, trim(path), trim(attname))// &
                     ': global attribute not found')
    end if
    call close_read(PROC, trim(path), ncid, error)
    if (allocated(error) .and. allocated(value)) deallocate (value)
  end subroutine read_text_attr

  ! ------------------------------------------------------------------------------------------------
  ! Bodies (the file is open; the caller closes it)
  ! ------------------------------------------------------------------------------------------------

  subroutine write_results_body(routine, path, ncid, set, error)
    character(len=*), intent(in) :: routine, path
    integer, intent(in) :: ncid
    type(result_set_t), intent(in) :: set
    type(error_t), allocatable, intent(out) :: error
    integer, allocatable :: dimids(:), coord_ids(:), mean_ids(:), stderr_ids(:)
    integer :: vdims(4), counts(4)
    integer :: ndim, nvar, i, k, nd
    character(len=:), allocatable :: name, at, long_name

    ndim = 0
    nvar = 0
    if (allocated(set%dims)) ndim = size(set%dims)
    if (allocated(set%vars)) nvar = size(set%vars)
    allocate (dimids(ndim), coord_ids(ndim), mean_ids(nvar), stderr_ids(nvar))
    coord_ids = -1
    stderr_ids = -1

    ! Global attributes: the convention first, then the set's own attributes in order.
    at = where_text(routine, path, 'Conventions')
    call nc_check(nf90_put_att(ncid, NF90_GLOBAL, 'Conventions', CONVENTIONS), at, error)
    if (allocated(error)) return
    if (allocated(set%attrs)) then
      do i = 1, size(set%attrs)
        name = trim(set%attrs(i)%name)
        at = where_text(routine, path, name)
        if (allocated(set%attrs(i)%num)) then
          call nc_check(nf90_put_att(ncid, NF90_GLOBAL, name, set%attrs(i)%num), at, error)
        else if (allocated(set%attrs(i)%value)) then
          call nc_check(nf90_put_att(ncid, NF90_GLOBAL, name, set%attrs(i)%value), at, error)
        else
          call nc_check(nf90_put_att(ncid, NF90_GLOBAL, name, ''), at, error)
        end if
        if (allocated(error)) return
      end do
    end if

    ! Dimensions and coordinate variables.
    do i = 1, ndim
      name = trim(set%dims(i)%name)
      at = where_text(routine, path, name)
      call nc_check(nf90_def_dim(ncid, name, set%dims(i)%size, dimids(i)), at, error)
      if (allocated(error)) return
      if (.not. allocated(set%dims(i)%coord)) cycle
      call nc_check(nf90_def_var(ncid, name, NF90_DOUBLE, [dimids(i)], coord_ids(i)), at, error)
      if (allocated(error)) return
      call put_text_att_if_set(at, ncid, coord_ids(i), 'units', set%dims(i)%units, error)
      if (allocated(error)) return
      call put_text_att_if_set(at, ncid, coord_ids(i), 'long_name', set%dims(i)%long_name, error)
      if (allocated(error)) return
      if (allocated(set%dims(i)%standard_name)) then
        call put_text_att_if_set(at, ncid, coord_ids(i), 'standard_name', &
                                 set%dims(i)%standard_name, error)
        if (allocated(error)) return
      end if
      if (set%dims(i)%axis /= ' ') then
        call put_text_att_if_set(at, ncid, coord_ids(i), 'axis', set%dims(i)%axis, error)
        if (allocated(error)) return
        ! kumo's vertical coordinates are heights
        if (set%dims(i)%axis == 'Z') call put_text_att_if_set(at, ncid, coord_ids(i), &
                                                              'positive', 'up', error)
        if (allocated(error)) return
      end if
    end do

    ! Result variables: <name> and <name>_stderr, dimensions in Fortran order.
    do k = 1, nvar
      associate (v => set%vars(k))
        nd = v%ndims
        do i = 1, nd
          vdims(i) = dimids(dim_position(set, v%dim_names(i)))
        end do
        name = trim(v%name)
        long_name = name
        if (allocated(v%long_name)) then
          if (len_trim(v%long_name) > 0) long_name = trim(v%long_name)
        end if
        at = where_text(routine, path, name)
        call def_result_var(name, mean_ids(k))
        if (allocated(error)) return
        call put_text_att_if_set(at, ncid, mean_ids(k), 'long_name', long_name, error)
        if (allocated(error)) return
        call put_text_att_if_set(at, ncid, mean_ids(k), 'units', v%units, error)
        if (allocated(error)) return
        if (allocated(v%standard_name)) then
          call put_text_att_if_set(at, ncid, mean_ids(k), 'standard_name', v%standard_name, error)
          if (allocated(error)) return
        end if
        if (allocated(v%coordinates)) then
          call put_text_att_if_set(at, ncid, mean_ids(k), 'coordinates', v%coordinates, error)
          if (allocated(error)) return
        end if
        if (var_has_stderr(v)) then
          ! CF: the standard error is an ancillary variable of the value
          call put_text_att_if_set(at, ncid, mean_ids(k), 'ancillary_variables', name//'_stderr', &
                                   error)
          if (allocated(error)) return
          at = where_text(routine, path, name//'_stderr')
          call def_result_var(name//'_stderr', stderr_ids(k))
          if (allocated(error)) return
          call put_text_att_if_set(at, ncid, stderr_ids(k), 'long_name', &
                                   'standard error of '//long_name, error)
          if (allocated(error)) return
          call put_text_att_if_set(at, ncid, stderr_ids(k), 'units', v%units, error)
          if (allocated(error)) return
          if (allocated(v%standard_name)) then
            call put_text_att_if_set(at, ncid, stderr_ids(k), 'standard_name', &
                                     v%standard_name//' standard_error', error)
            if (allocated(error)) return
          end if
          if (allocated(v%coordinates)) then
            call put_text_att_if_set(at, ncid, stderr_ids(k), 'coordinates', v%coordinates, error)
            if (allocated(error)) return
          end if
        end if
      end associate
    end do

    call nc_check(nf90_enddef(ncid), where_text(routine, path, ''), error)
    if (allocated(error)) return

    do i = 1, ndim
      if (coord_ids(i) < 0) cycle
      at = where_text(routine, path, trim(set%dims(i)%name))
      call nc_check(nf90_put_var(ncid, coord_ids(i), set%dims(i)%coord), at, error)
      if (allocated(error)) return
    end do
    do k = 1, nvar
      associate (v => set%vars(k))
        nd = v%ndims
        do i = 1, nd
          counts(i) = set%dims(dim_position(set, v%dim_names(i)))%size
        end do
        at = where_text(routine, path, trim(v%name))
        if (v%src_lo >= 0) then
          ! deferred (kumo_results): formed and written slab by slab
          call put_deferred(ncid, mean_ids(k), stderr_ids(k), set, k, nd, counts, &
                            where_text(routine, path, trim(v%name)//'_stderr'), at, error)
          if (allocated(error)) return
          cycle
        end if
        call put_flat(ncid, mean_ids(k), nd, counts, v%mean, at, error)
        if (allocated(error)) return
        if (stderr_ids(k) >= 0) then
          at = where_text(routine, path, trim(v%name)//'_stderr')
          call put_flat(ncid, stderr_ids(k), nd, counts, v%stderr, at, error)
          if (allocated(error)) return
        end if
      end associate
    end do

  contains

    !> Define a result variable on the dimensions vdims(1:nd), deflated when the set asks.
    subroutine def_result_var(vname, id)
      character(len=*), intent(in) :: vname
      integer, intent(out) :: id
      if (set%deflate > 0 .and. nd > 0) then
        call nc_check(nf90_def_var(ncid, vname, NF90_DOUBLE, vdims(1:nd), id, shuffle=.true., &
                                   deflate_level=set%deflate), at, error)
      else
        call nc_check(nf90_def_var(ncid, vname, NF90_DOUBLE, vdims(1:nd), id), at, error)
      end if
    end subroutine def_result_var
  end subroutine write_results_body

  subroutine write_scene_body(routine, path, ncid, ext, units, ssa, phase_index, error, &
                              temperature)
    character(len=*), intent(in) :: routine, path
    integer, intent(in) :: ncid
    real(wp), intent(in) :: ext(:, :, :, :)
    character(len=*), intent(in) :: units                !! "m-1" or "km-1"
    real(wp), intent(in) :: ssa(:, :, :, :)
    integer, intent(in), optional :: phase_index(:, :, :, :)
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: temperature(:, :, :)
    integer :: dimids(4), shp(4), ext_id, ssa_id, pi_id, i, t_id
    logical :: in_km

    shp = shape(ext)
    in_km = units == 'km-1'
    call nc_check(nf90_put_att(ncid, NF90_GLOBAL, 'Conventions', CONVENTIONS), &
                  where_text(routine, path, 'Conventions'), error)
    if (allocated(error)) return
    call nc_check(nf90_put_att(ncid, NF90_GLOBAL, 'title', 'kumo 3-D scene optical properties'), &
                  where_text(routine, path, 'title'), error)
    if (allocated(error)) return
    do i = 1, 4
      call nc_check(nf90_def_dim(ncid, trim(SCENE_DIM_NAMES(i)), shp(i), dimids(i)), &
                    where_text(routine, path, trim(SCENE_DIM_NAMES(i))), error)
      if (allocated(error)) return
    end do

    call def_scene_var('extinction', NF90_DOUBLE, 'volume extinction coefficient', units, ext_id)
    if (allocated(error)) return
    call def_scene_var('ssa', NF90_DOUBLE, 'single-scattering albedo', '1', ssa_id)
    if (allocated(error)) return
    if (present(phase_index)) then
      call def_scene_var('phase_index', NF90_INT, &
                         'index of the phase function in the namelist list (1-based)', '', pi_id)
      if (allocated(error)) return
    end if
    if (present(temperature)) then
      call nc_check(nf90_def_var(ncid, 'temperature', NF90_DOUBLE, dimids(1:3), t_id), &
                    where_text(routine, path, 'temperature'), error)
      if (allocated(error)) return
      call put_text_att_if_set(where_text(routine, path, 'temperature'), ncid, t_id, &
                               'long_name', 'air temperature (thermal emission)', error)
      if (allocated(error)) return
      call put_text_att_if_set(where_text(routine, path, 'temperature'), ncid, t_id, 'units', &
                               'K', error)
      if (allocated(error)) return
    end if
    call nc_check(nf90_enddef(ncid), where_text(routine, path, ''), error)
    if (allocated(error)) return
    if (present(temperature)) then
      call nc_check(nf90_put_var(ncid, t_id, temperature), &
                    where_text(routine, path, 'temperature'), error)
      if (allocated(error)) return
    end if

    if (in_km) then
      call nc_check(nf90_put_var(ncid, ext_id, ext/PER_KM_TO_PER_M), &
                    where_text(routine, path, 'extinction'), error)
    else
      call nc_check(nf90_put_var(ncid, ext_id, ext), where_text(routine, path, 'extinction'), error)
    end if
    if (allocated(error)) return
    call nc_check(nf90_put_var(ncid, ssa_id, ssa), where_text(routine, path, 'ssa'), error)
    if (allocated(error)) return
    if (present(phase_index)) then
      call nc_check(nf90_put_var(ncid, pi_id, phase_index), &
                    where_text(routine, path, 'phase_index'), error)
    end if

  contains

    subroutine def_scene_var(name, xtype, long_name, var_units, varid)
      character(len=*), intent(in) :: name, long_name, var_units
      integer, intent(in) :: xtype
      integer, intent(out) :: varid
      character(len=:), allocatable :: at
      at = where_text(routine, path, name)
      call nc_check(nf90_def_var(ncid, name, xtype, dimids, varid), at, error)
      if (allocated(error)) return
      call put_text_att_if_set(at, ncid, varid, 'long_name', long_name, error)
      if (allocated(error)) return
      call put_text_att_if_set(at, ncid, varid, 'units', var_units, error)
    end subroutine def_scene_var
  end subroutine write_scene_body

  subroutine read_scene_body(routine, path, ncid, expected, ext, ssa, phase_index, &
                             has_phase_index, error)
    character(len=*), intent(in) :: routine, path
    integer, intent(in) :: ncid
    integer, intent(in) :: expected(4)
    real(wp), allocatable, intent(out) :: ext(:, :, :, :), ssa(:, :, :, :)
    integer, allocatable, intent(out) :: phase_index(:, :, :, :)
    logical, intent(inout) :: has_phase_index
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: EXPECTED_NAMES(4) = &
                                   [character(len=5) :: 'nx', 'ny', 'nz3', 'ncomp']
    integer :: dimids(4), length, varid, status, i
    real(wp) :: fill
    integer :: ifill
    character(len=:), allocatable :: units, at
    logical :: found, in_km

    ! Dimensions: present and of the expected size, checked before anything is read.
    do i = 1, 4
      at = where_text(routine, path, trim(SCENE_DIM_NAMES(i)))
      call nc_check(nf90_inq_dimid(ncid, trim(SCENE_DIM_NAMES(i)), dimids(i)), at, error)
      if (allocated(error)) return
      call nc_check(nf90_inquire_dimension(ncid, dimids(i), len=length), at, error)
      if (allocated(error)) return
      if (length /= expected(i)) then
        call set_error(error, at//': dimension size '//str(length)// &
                       ' in the file does not match the expected size '// &
                       trim(EXPECTED_NAMES(i))//' = '//str(expected(i)))
        return
      end if
    end do

    ! Extinction: layout, units, values.
    at = where_text(routine, path, 'extinction')
    call nc_check(nf90_inq_varid(ncid, 'extinction', varid), at, error)
    if (allocated(error)) return
    call check_real_var(at, ncid, varid, dimids, SCENE_CDL_DIMS, fill, error)
    if (allocated(error)) return
    call get_text_att(routine, path, ncid, varid, 'units', units, found, error)
    if (allocated(error)) return
    if (.not. found) then
      call set_error(error, at//': units attribute missing; allowed units are "m-1" and "km-1"')
      return
    end if
    if (units /= 'm-1' .and. units /= 'km-1') then
      call set_error(error, at//': units "'//units// &
                     '" not allowed; allowed units are "m-1" and "km-1"')
      return
    end if
    in_km = units == 'km-1'
    allocate (ext(expected(1), expected(2), expected(3), expected(4)))
    call nc_check(nf90_get_var(ncid, varid, ext), at, error)
    if (allocated(error)) return
    call check_real_4d(at, ext, fill, .false., error)
    if (allocated(error)) return
    if (in_km) ext = ext*PER_KM_TO_PER_M

    ! Single-scattering albedo: dimensionless.
    at = where_text(routine, path, 'ssa')
    call nc_check(nf90_inq_varid(ncid, 'ssa', varid), at, error)
    if (allocated(error)) return
    call check_real_var(at, ncid, varid, dimids, SCENE_CDL_DIMS, fill, error)
    if (allocated(error)) return
    call check_dimensionless(routine, path, at, ncid, varid, error)
    if (allocated(error)) return
    allocate (ssa(expected(1), expected(2), expected(3), expected(4)))
    call nc_check(nf90_get_var(ncid, varid, ssa), at, error)
    if (allocated(error)) return
    call check_real_4d(at, ssa, fill, .true., error)
    if (allocated(error)) return

    ! Optional phase-function index.
    at = where_text(routine, path, 'phase_index')
    status = nf90_inq_varid(ncid, 'phase_index', varid)
    if (status /= NF90_NOERR) return        ! absent: every component uses its own phase function
    call check_layout(at, ncid, varid, dimids, SCENE_CDL_DIMS, error)
    if (allocated(error)) return
    call integer_fill(at, ncid, varid, ifill, error)
    if (allocated(error)) return
    allocate (phase_index(expected(1), expected(2), expected(3), expected(4)))
    call nc_check(nf90_get_var(ncid, varid, phase_index), at, error)
    if (allocated(error)) return
    call check_index_4d(at, phase_index, ifill, error)
    if (allocated(error)) return
    has_phase_index = .true.
  end subroutine read_scene_body

  subroutine read_albedo_body(routine, path, ncid, name, nxs, nys, albedo, error, temperature)
    character(len=*), intent(in) :: routine, path, name
    integer, intent(in) :: ncid
    integer, intent(inout) :: nxs, nys
    real(wp), allocatable, intent(out) :: albedo(:, :)
    type(error_t), allocatable, intent(out) :: error
    !> a temperature map instead: units "K", values >= 0 (not within [0, 1])
    logical, intent(in), optional :: temperature
    integer :: dimids(2), lengths(2), varid, i, ix, iy
    real(wp) :: fill
    character(len=:), allocatable :: at, units
    logical :: unit_interval, found

    do i = 1, 2
      at = where_text(routine, path, trim(MAP_DIM_NAMES(i)))
      call nc_check(nf90_inq_dimid(ncid, trim(MAP_DIM_NAMES(i)), dimids(i)), at, error)
      if (allocated(error)) return
      call nc_check(nf90_inquire_dimension(ncid, dimids(i), len=lengths(i)), at, error)
      if (allocated(error)) return
    end do
    at = where_text(routine, path, name)
    call nc_check(nf90_inq_varid(ncid, name, varid), at, error)
    if (allocated(error)) return
    call check_real_var(at, ncid, varid, dimids, MAP_CDL_DIMS, fill, error)
    if (allocated(error)) return
    unit_interval = .true.
    if (present(temperature)) unit_interval = .not. temperature
    if (unit_interval) then
      call check_dimensionless(routine, path, at, ncid, varid, error)
    else
      call get_text_att(routine, path, ncid, varid, 'units', units, found, error)
      if (.not. allocated(error) .and. (.not. found .or. units /= 'K')) &
        call set_error(error, at//': units must be "K"')
    end if
    if (allocated(error)) return
    allocate (albedo(lengths(1), lengths(2)))
    call nc_check(nf90_get_var(ncid, varid, albedo), at, error)
    if (allocated(error)) return
    do iy = 1, lengths(2)
      do ix = 1, lengths(1)
        if (.not. value_ok(albedo(ix, iy), fill, unit_interval)) then
          call set_error(error, at//': value '//real_text(albedo(ix, iy))//' at '//MAP_INDEX// &
                         ' = '//join([ix, iy], ',', '()')//' '// &
                         value_problem(albedo(ix, iy), fill, unit_interval))
          return
        end if
      end do
    end do
    nxs = lengths(1)
    nys = lengths(2)
  end subroutine read_albedo_body

  subroutine read_var_body(routine, path, ncid, name, values, error)
    character(len=*), intent(in) :: routine, path, name
    integer, intent(in) :: ncid
    real(dp), allocatable, intent(out) :: values(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: varid, xtype, ndims, i
    integer :: dimids(NF90_MAX_VAR_DIMS)
    integer, allocatable :: counts(:)
    character(len=:), allocatable :: at

    at = where_text(routine, path, name)
    call nc_check(nf90_inq_varid(ncid, name, varid), at, error)
    if (allocated(error)) return
    call nc_check(nf90_inquire_variable(ncid, varid, xtype=xtype, ndims=ndims, dimids=dimids), &
                  at, error)
    if (allocated(error)) return
    if (xtype == NF90_CHAR) then
      call set_error(error, at//': variable holds text, not numbers')
      return
    end if
    allocate (counts(ndims))
    do i = 1, ndims
      call nc_check(nf90_inquire_dimension(ncid, dimids(i), len=counts(i)), at, error)
      if (allocated(error)) return
    end do
    allocate (values(product(counts)))
    if (ndims == 0) then
      call nc_check(nf90_get_var(ncid, varid, values(1)), at, error)
    else if (size(values) > 0) then
      call nc_check(nf90_get_var(ncid, varid, values, start=spread(1, 1, ndims), count=counts), &
                    at, error)
    end if
  end subroutine read_var_body

  ! ------------------------------------------------------------------------------------------------
  ! Validation
  ! ------------------------------------------------------------------------------------------------

  !> Check a result set before any file is created.
  subroutine validate_result_set(routine, path, set, error)
    character(len=*), intent(in) :: routine, path
    type(result_set_t), intent(in) :: set
    type(error_t), allocatable, intent(out) :: error
    integer :: i, j, n, expected_size
    integer :: counts(4)
    character(len=:), allocatable :: at

    if (allocated(set%attrs)) then
      do i = 1, size(set%attrs)
        at = where_text(routine, path, trim(set%attrs(i)%name))
        if (len_trim(set%attrs(i)%name) == 0) then
          call set_error(error, at//': global attribute '//str(i)//' has no name')
          return
        end if
        if (trim(set%attrs(i)%name) == 'Conventions') then
          call set_error(error, at//': the Conventions attribute is set by the writer ("'// &
                         CONVENTIONS//'") and must not be in the result set')
          return
        end if
      end do
    end if

    if (allocated(set%dims)) then
      do i = 1, size(set%dims)
        at = where_text(routine, path, trim(set%dims(i)%name))
        if (len_trim(set%dims(i)%name) == 0) then
          call set_error(error, at//': dimension '//str(i)//' has no name')
          return
        end if
        if (dim_position(set, set%dims(i)%name) /= i) then
          call set_error(error, at//': dimension defined twice')
          return
        end if
        if (set%dims(i)%size < 1) then
          call set_error(error, at//': dimension size '//str(set%dims(i)%size)// &
                         ' must be >= 1')
          return
        end if
        if (allocated(set%dims(i)%coord)) then
          if (size(set%dims(i)%coord) /= set%dims(i)%size) then
            call set_error(error, at//': coordinate has '//str(size(set%dims(i)%coord))// &
                           ' values, dimension size is '//str(set%dims(i)%size))
            return
          end if
          call check_finite_flat(at, set%dims(i)%coord, 1, [set%dims(i)%size], &
                                 '('//trim(set%dims(i)%name)//')', .false., error)
          if (allocated(error)) return
        end if
      end do
    end if

    if (.not. allocated(set%vars)) return
    do i = 1, size(set%vars)
      associate (v => set%vars(i))
        at = where_text(routine, path, trim(v%name))
        if (len_trim(v%name) == 0) then
          call set_error(error, at//': variable '//str(i)//' has no name')
          return
        end if
        n = v%ndims
        if (n < 0 .or. n > size(v%dim_names)) then
          call set_error(error, at//': ndims = '//str(n)//' must be in [0, '// &
                         str(size(v%dim_names))//']')
          return
        end if
        do j = 1, n
          if (dim_position(set, v%dim_names(j)) == 0) then
            call set_error(error, at//': dimension "'//trim(v%dim_names(j))// &
                           '" is not defined in the result set')
            return
          end if
          counts(j) = set%dims(dim_position(set, v%dim_names(j)))%size
        end do
        expected_size = product(counts(1:n))
        if (v%src_lo >= 0) then
          call check_deferred(at, where_text(routine, path, trim(v%name)//'_stderr'), set, i, &
                              counts(1:n), expected_size, error)
          if (allocated(error)) return
          cycle
        end if
        if (.not. allocated(v%mean)) then
          call set_error(error, at//': mean values not allocated')
          return
        end if
        if (size(v%mean) /= expected_size) then
          call set_error(error, at//': '//str(size(v%mean))//' mean values, expected '// &
                         str(expected_size)//' from its dimensions')
          return
        end if
        call check_finite_flat(at, v%mean, n, counts(1:n), join(v%dim_names(1:n), ',', '()'), &
                               .false., error)
        if (allocated(error)) return
        if (allocated(v%stderr)) then
          at = where_text(routine, path, trim(v%name)//'_stderr')
          if (size(v%stderr) /= expected_size) then
            call set_error(error, at//': '//str(size(v%stderr))// &
                           ' standard errors, expected '//str(expected_size)// &
                           ' from its dimensions')
            return
          end if
          call check_finite_flat(at, v%stderr, n, counts(1:n), join(v%dim_names(1:n), ',', '()'), &
                                 .true., error)
          if (allocated(error)) return
        end if
      end associate
    end do
  end subroutine validate_result_set

  !> A deferred variable iv (kumo_results): `expected` values, finite (standard errors >= 0),
  !> checked slab by slab as put_deferred writes them.
  subroutine check_deferred(at, at_err, set, iv, counts, expected, error)
    character(len=*), intent(in) :: at, at_err
    type(result_set_t), intent(in) :: set
    integer, intent(in) :: iv, expected
    integer, intent(in) :: counts(:)
    type(error_t), allocatable, intent(out) :: error
    real(dp), allocatable :: m(:), e(:)
    integer :: n, slab, j0, nd
    character(len=:), allocatable :: names
    n = var_size(set%vars(iv))
    if (n /= expected) then
      call set_error(error, at//': '//str(n)//' mean values, expected '//str(expected)// &
                     ' from its dimensions')
      return
    end if
    nd = size(counts)
    names = join(set%vars(iv)%dim_names(1:nd), ',', '()')
    slab = slab_size(counts, n)
    allocate (m(slab), e(slab))
    do j0 = 0, n - 1, slab
      call var_values(set, iv, j0, m, e)
      call check_finite_flat(at, m, nd, counts, names, .false., error, j0)
      if (allocated(error)) return
      call check_finite_flat(at_err, e, nd, counts, names, .true., error, j0)
      if (allocated(error)) return
    end do
  end subroutine check_deferred

  !> Entries of one slab of a variable: all but its last (slowest) dimension.
  pure integer function slab_size(counts, n) result(slab)
    integer, intent(in) :: counts(:), n
    slab = n
    if (size(counts) > 1) slab = product(counts(1:size(counts) - 1))
  end function slab_size

  !> Write a deferred variable iv (kumo_results) and its standard error one slab (index of its
  !> last dimension) at a time, formed just before: no array of the whole variable is needed.
  subroutine put_deferred(ncid, mean_id, stderr_id, set, iv, ndims, counts, at_err, at, error)
    integer, intent(in) :: ncid, mean_id, stderr_id, iv, ndims
    type(result_set_t), intent(in) :: set
    integer, intent(in) :: counts(:)
    character(len=*), intent(in) :: at_err, at
    type(error_t), allocatable, intent(out) :: error
    real(dp), allocatable :: x(:)
    integer :: n, slab, j0, start(4), cnt(4), part
    n = var_size(set%vars(iv))
    slab = slab_size(counts(1:ndims), n)
    allocate (x(slab))
    start = 1
    cnt(1:ndims) = counts(1:ndims)
    if (ndims > 1) cnt(ndims) = 1
    ! the means, then the standard errors
    do part = 1, 2
      do j0 = 0, n - 1, slab
        if (ndims > 1) start(ndims) = j0/slab + 1
        if (part == 1) then
          call var_values(set, iv, j0, mean=x)
          call nc_check(nf90_put_var(ncid, mean_id, x, start=start(1:ndims), &
                                     count=cnt(1:ndims)), at, error)
        else
          call var_values(set, iv, j0, stderr=x)
          call nc_check(nf90_put_var(ncid, stderr_id, x, start=start(1:ndims), &
                                     count=cnt(1:ndims)), at_err, error)
        end if
        if (allocated(error)) return
      end do
    end do
  end subroutine put_deferred

  !> Flattened values must be finite (and >= 0 if `nonnegative`); the message gives the index
  !> (of values(k) at position offset + k of the variable when `offset` is given).
  subroutine check_finite_flat(at, values, ndims, counts, index_names, nonnegative, error, offset)
    character(len=*), intent(in) :: at
    real(dp), intent(in) :: values(:)
    integer, intent(in) :: ndims
    integer, intent(in) :: counts(:)
    character(len=*), intent(in) :: index_names
    logical, intent(in) :: nonnegative
    type(error_t), allocatable, intent(out) :: error
    integer, intent(in), optional :: offset
    integer :: k, j, rest, idx(4)
    character(len=:), allocatable :: problem, place

    do k = 1, size(values)
      if (ieee_is_finite(values(k))) then  ! fast path first; no ordered comparison with NaN
        if (.not. nonnegative) cycle
        if (values(k) >= 0.0_dp) cycle
        problem = 'must be >= 0'
      else
        problem = 'is not finite'
      end if
      if (ndims == 0) then
        place = ''
      else
        rest = k - 1
        if (present(offset)) rest = rest + offset
        do j = 1, ndims
          idx(j) = mod(rest, counts(j)) + 1
          rest = rest/counts(j)
        end do
        place = ' at '//index_names//' = '//join(idx(1:ndims), ',', '()')
      end if
      call set_error(error, at//': value '//real_text(values(k))//place//' '//problem)
      return
    end do
  end subroutine check_finite_flat

  !> Finite, not the fill value, >= 0 and, if `unit_interval`, <= 1.
  subroutine check_real_4d(at, values, fill, unit_interval, error)
    character(len=*), intent(in) :: at
    real(wp), intent(in) :: values(:, :, :, :)
    real(wp), intent(in) :: fill
    logical, intent(in) :: unit_interval
    type(error_t), allocatable, intent(out) :: error
    integer :: ix, iy, iz, ic

    do ic = 1, size(values, 4)
      do iz = 1, size(values, 3)
        do iy = 1, size(values, 2)
          do ix = 1, size(values, 1)
            if (value_ok(values(ix, iy, iz, ic), fill, unit_interval)) cycle
            call set_error(error, at//': value '//real_text(values(ix, iy, iz, ic))//' at '// &
                           SCENE_INDEX//' = '//join([ix, iy, iz, ic], ',', '()')//' '// &
                           value_problem(values(ix, iy, iz, ic), fill, unit_interval))
            return
          end do
        end do
      end do
    end do
  end subroutine check_real_4d

  !> Phase-function indices are 1-based; the fill value marks missing data.
  subroutine check_index_4d(at, values, fill, error)
    character(len=*), intent(in) :: at
    integer, intent(in) :: values(:, :, :, :)
    integer, intent(in) :: fill
    type(error_t), allocatable, intent(out) :: error
    integer :: ix, iy, iz, ic
    character(len=:), allocatable :: problem

    do ic = 1, size(values, 4)
      do iz = 1, size(values, 3)
        do iy = 1, size(values, 2)
          do ix = 1, size(values, 1)
            if (values(ix, iy, iz, ic) >= 1 .and. values(ix, iy, iz, ic) /= fill) cycle
            if (values(ix, iy, iz, ic) == fill) then
              problem = 'is the fill value (missing data)'
            else
              problem = 'must be >= 1'
            end if
            call set_error(error, at//': value '//str(values(ix, iy, iz, ic))//' at '// &
                           SCENE_INDEX//' = '//join([ix, iy, iz, ic], ',', '()')//' '//problem)
            return
          end do
        end do
      end do
    end do
  end subroutine check_index_4d

  !> Exact match with the fill value (spelt without == to keep -Wcompare-reals quiet).
  pure logical function is_fill(x, fill)
    real(wp), intent(in) :: x, fill
    is_fill = x >= fill .and. x <= fill
  end function is_fill

  !> Cheap test used in the loops; `value_problem` explains a failure.
  pure logical function value_ok(x, fill, unit_interval)
    real(wp), intent(in) :: x, fill
    logical, intent(in) :: unit_interval
    value_ok = .false.
    if (.not. ieee_is_finite(x)) return      ! tested first: no ordered comparison with NaN
    if (is_fill(x, fill)) return
    if (x < 0.0_wp) return
    if (unit_interval) then
      if (x > 1.0_wp) return
    end if
    value_ok = .true.
  end function value_ok

  function value_problem(x, fill, unit_interval) result(problem)
    real(wp), intent(in) :: x, fill
    logical, intent(in) :: unit_interval
    character(len=:), allocatable :: problem
    if (.not. ieee_is_finite(x)) then
      problem = 'is not finite'
    else if (is_fill(x, fill)) then
      problem = 'is the fill value (missing data)'
    else if (x < 0.0_wp) then
      problem = 'must be >= 0'
    else if (unit_interval .and. x > 1.0_wp) then
      problem = 'must be <= 1'
    else
      problem = 'is valid'
    end if
  end function value_problem

  !> A floating-point variable with the expected dimensions, not packed; returns its fill value.
  subroutine check_real_var(at, ncid, varid, expected_dimids, expected_cdl, fill, error)
    character(len=*), intent(in) :: at
    integer, intent(in) :: ncid, varid
    integer, intent(in) :: expected_dimids(:)
    character(len=*), intent(in) :: expected_cdl
    real(wp), intent(out) :: fill
    type(error_t), allocatable, intent(out) :: error
    integer :: xtype, status

    fill = 0.0_wp
    call nc_check(nf90_inquire_variable(ncid, varid, xtype=xtype), at, error)
    if (allocated(error)) return
    if (xtype /= NF90_DOUBLE .and. xtype /= NF90_FLOAT) then
      call set_error(error, at//': variable type must be double or float')
      return
    end if
    call check_layout(at, ncid, varid, expected_dimids, expected_cdl, error)
    if (allocated(error)) return
    call check_not_packed(at, ncid, varid, error)
    if (allocated(error)) return
    status = nf90_inquire_attribute(ncid, varid, '_FillValue')
    if (status == NF90_NOERR) then
      call nc_check(nf90_get_att(ncid, varid, '_FillValue', fill), at//'/_FillValue', error)
    else if (xtype == NF90_DOUBLE) then
      fill = real(NF90_FILL_DOUBLE, wp)
    else
      fill = real(NF90_FILL_FLOAT, wp)
    end if
  end subroutine check_real_var

  !> The fill value of an integer variable (its _FillValue or the netCDF default for its type).
  subroutine integer_fill(at, ncid, varid, fill, error)
    character(len=*), intent(in) :: at
    integer, intent(in) :: ncid, varid
    integer, intent(out) :: fill
    type(error_t), allocatable, intent(out) :: error
    integer :: xtype, status

    fill = 0
    call nc_check(nf90_inquire_variable(ncid, varid, xtype=xtype), at, error)
    if (allocated(error)) return
    select case (xtype)
    case (NF90_BYTE)
      fill = int(NF90_FILL_BYTE)
    case (NF90_SHORT)
      fill = int(NF90_FILL_SHORT)
    case (NF90_INT)
      fill = int(NF90_FILL_INT)
    case default
      call set_error(error, at//': variable type must be an integer type (byte, short or int)')
      return
    end select
    call check_not_packed(at, ncid, varid, error)
    if (allocated(error)) return
    status = nf90_inquire_attribute(ncid, varid, '_FillValue')
    if (status == NF90_NOERR) then
      call nc_check(nf90_get_att(ncid, varid, '_FillValue', fill), at//'/_FillValue', error)
    end if
  end subroutine integer_fill

  !> The variable's dimensions must be exactly `expected_dimids` (Fortran order).
  subroutine check_layout(at, ncid, varid, expected_dimids, expected_cdl, error)
    character(len=*), intent(in) :: at
    integer, intent(in) :: ncid, varid
    integer, intent(in) :: expected_dimids(:)
    character(len=*), intent(in) :: expected_cdl
    type(error_t), allocatable, intent(out) :: error
    integer :: ndims, i
    integer :: dimids(NF90_MAX_VAR_DIMS)
    character(len=NF90_MAX_NAME), allocatable :: dnames(:)
    logical :: same

    call nc_check(nf90_inquire_variable(ncid, varid, ndims=ndims, dimids=dimids), at, error)
    if (allocated(error)) return
    same = ndims == size(expected_dimids)
    if (same) same = all(dimids(1:ndims) == expected_dimids)
    if (same) return
    allocate (dnames(ndims))
    do i = 1, ndims                         ! ncdump (C) order: slowest-varying first
      call nc_check(nf90_inquire_dimension(ncid, dimids(ndims + 1 - i), name=dnames(i)), at, error)
      if (allocated(error)) return
    end do
    call set_error(error, at//': dimensions are '//join(dnames, ', ', '()')// &
                   ' in ncdump order; expected '//expected_cdl)
  end subroutine check_layout

  !> nf90_get_var does not unpack, so scale_factor/add_offset would give wrong numbers silently.
  subroutine check_not_packed(at, ncid, varid, error)
    character(len=*), intent(in) :: at
    integer, intent(in) :: ncid, varid
    type(error_t), allocatable, intent(out) :: error
    if (nf90_inquire_attribute(ncid, varid, 'scale_factor') == NF90_NOERR .or. &
        nf90_inquire_attribute(ncid, varid, 'add_offset') == NF90_NOERR) then
      call set_error(error, at//': packed variables (scale_factor/add_offset) are not '// &
                     'supported; store the unpacked values')
    end if
  end subroutine check_not_packed

  !> A dimensionless variable has units "1" or no units attribute.
  subroutine check_dimensionless(routine, path, at, ncid, varid, error)
    character(len=*), intent(in) :: routine, path, at
    integer, intent(in) :: ncid, varid
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: units
    logical :: found

    call get_text_att(routine, path, ncid, varid, 'units', units, found, error)
    if (allocated(error)) return
    if (.not. found) return
    if (units /= '1') then
      call set_error(error, at//': units "'//units// &
                     '" not allowed; the variable is dimensionless: units must be "1" or absent')
    end if
  end subroutine check_dimensionless

  ! ------------------------------------------------------------------------------------------------
  ! netCDF helpers
  ! ------------------------------------------------------------------------------------------------

  !> Turn a netCDF status into an error located at `at` ("routine(file:name)").
  subroutine nc_check(status, at, error)
    integer, intent(in) :: status
    character(len=*), intent(in) :: at
    type(error_t), allocatable, intent(out) :: error
    if (status == NF90_NOERR) return
    call set_error(error, at//': '//trim(nf90_strerror(status)))
  end subroutine nc_check

  !> "routine(file:name)", or "routine(file)" for an empty name.
  pure function where_text(routine, path, name) result(at)
    character(len=*), intent(in) :: routine, path, name
    character(len=:), allocatable :: at
    if (len(name) == 0) then
      at = routine//'('//path//')'
    else
      at = routine//'('//path//':'//name//')'
    end if
  end function where_text

  subroutine open_read(routine, path, ncid, error)
    character(len=*), intent(in) :: routine, path
    integer, intent(out) :: ncid
    type(error_t), allocatable, intent(out) :: error
    ncid = -1
    call check_netcdf_complete(where_text(routine, path, ''), path, error)
    if (allocated(error)) return
    call nc_check(nf90_open(path, NF90_NOWRITE, ncid), where_text(routine, path, ''), error)
  end subroutine open_read

  !> Close a file opened for reading; an earlier error is kept and the close status ignored.
  subroutine close_read(routine, path, ncid, error)
    character(len=*), intent(in) :: routine, path
    integer, intent(in) :: ncid
    type(error_t), allocatable, intent(inout) :: error
    integer :: status
    status = nf90_close(ncid)
    if (allocated(error)) return
    call nc_check(status, where_text(routine, path, ''), error)
  end subroutine close_read

  !> Create `<path>.tmp` (replacing a stale one from an interrupted run).
  subroutine create_temp(routine, path, ncid, error)
    character(len=*), intent(in) :: routine, path
    integer, intent(out) :: ncid
    type(error_t), allocatable, intent(out) :: error
    integer :: status, slash
    logical :: dir_exists, explained

    ncid = -1
    call ignore_file_size_signal()
    call remove_file(path//TMP_SUFFIX)   ! left by a run that was killed while writing
    status = nf90_create(path//TMP_SUFFIX, CREATE_MODE, ncid)
    if (status == NF90_NOERR) return
    call set_error(error, where_text(routine, path//TMP_SUFFIX, '')//': '// &
                   trim(nf90_strerror(status))//' (cannot create the temporary file)')
    call explain_write_failure(path//TMP_SUFFIX, error, explained)   ! a full disk
    call remove_file(path//TMP_SUFFIX)
    if (explained) return
    ! HDF5 reports a missing directory as "Permission denied": say what is wrong.
    slash = index(path, '/', back=.true.)
    dir_exists = .true.
    if (slash > 1) inquire (file=path(1:slash - 1)//'/.', exist=dir_exists)
    if (.not. dir_exists) then
      call set_error(error, where_text(routine, path//TMP_SUFFIX, '')//': '// &
                     trim(nf90_strerror(status))//' (directory '//path(1:slash - 1)// &
                     ' does not exist)')
    end if
  end subroutine create_temp

  !> Close `<path>.tmp` and rename it to `<path>`; on any error (earlier or here) remove it.
  subroutine commit_temp(routine, path, ncid, error)
    character(len=*), intent(in) :: routine, path
    integer, intent(in) :: ncid
    type(error_t), allocatable, intent(inout) :: error
    integer :: status

    status = nf90_close(ncid)
    if (.not. allocated(error)) then
      call nc_check(status, where_text(routine, path//TMP_SUFFIX, ''), error)
    end if
    if (allocated(error)) then
      call explain_write_failure(path//TMP_SUFFIX, error)
      call remove_file(path//TMP_SUFFIX)
      return
    end if
    if (c_rename(path//TMP_SUFFIX//c_null_char, path//c_null_char) /= 0) then
      call set_error(error, where_text(routine, path, '')//': cannot rename '//path//TMP_SUFFIX// &
                     ' to '//path)
      call remove_file(path//TMP_SUFFIX)
    end if
  end subroutine commit_temp

  !> After a write, create or close of `path` failed with `error`: if the file system takes no more
  !> data there, replace the message by one that says so. netCDF-4 reports a full disk, an
  !> exceeded quota and the process's file size limit (ulimit -f) alike as "NetCDF: HDF error";
  !> the operating system's reason is found by appending PROBE_BYTES to the file (which is
  !> removed afterwards anyway): if that fails too, its message (the system's own, e.g. "No space
  !> left on device") is the cause. Anything else (the file is missing, the append works) keeps
  !> the original message. The file is left for the caller to remove.
  subroutine explain_write_failure(path, error, explained)
    character(len=*), intent(in) :: path    !! the file whose write failed
    type(error_t), allocatable, intent(inout) :: error  !! the failure (unallocated: nothing done)
    logical, intent(out), optional :: explained  !! true if the message now names the cause
    character(len=512) :: msg
    character(len=1), allocatable :: filler(:)
    integer :: unit, ios, ios_close
    logical :: exists

    if (present(explained)) explained = .false.
    if (.not. allocated(error)) return
    inquire (file=path, exist=exists)
    if (.not. exists) return
    open (newunit=unit, file=path, access='stream', form='unformatted', status='old', &
          position='append', action='write', iostat=ios)
    if (ios /= 0) return
    allocate (filler(PROBE_BYTES))
    filler = c_null_char
    write (unit, iostat=ios, iomsg=msg) filler
    if (ios == 0) flush (unit, iostat=ios, iomsg=msg)
    close (unit, iostat=ios_close)
    if (ios == 0) return
    call probe_message(path, msg, error)
    if (present(explained)) explained = .true.
  end subroutine explain_write_failure

  !> Replace the message of `error` by one naming the cause of a write to `path` that the file
  !> system refused, from the system's message `msg` (iomsg of the failed write).
  subroutine probe_message(path, msg, error)
    character(len=*), intent(in) :: path, msg
    type(error_t), allocatable, intent(inout) :: error
    character(len=:), allocatable :: cause, advice, low
    low = to_lower(trim(msg))
    if (index(low, 'no space') > 0) then
      cause = 'no space left on device'
      advice = 'the file system is full: free space there or write the output elsewhere'
    else if (index(low, 'quota') > 0) then
      cause = 'disk quota exceeded'
      advice = 'free space within the quota or write the output elsewhere'
    else if (index(low, 'too large') > 0) then
      cause = 'file size limit exceeded'
      advice = 'the process may not write files this large (ulimit -f): raise the limit'
    else
      cause = trim(msg)
      advice = 'the file system refuses more data'
    end if
    error%message = cause//' while writing '//path//': '//advice//' (reported: '// &
                    error%message//')'
  end subroutine probe_message

  !> Make sure the output fits before the netCDF library writes it: up to `nbytes_max` bytes
  !> are written to `path` (created exclusively after a stale file is removed) and the file is
  !> deleted again. If the file system takes fewer than `nbytes_min` bytes (the data alone), the
  !> write cannot succeed and the error names the operating system's reason (a full disk, an
  !> exceeded quota, the file size limit: `probe_message`) before HDF5 has a file open: after a
  !> failed HDF5 write the library's clean-up at program exit can crash, and the message it
  !> gives is only "NetCDF: HDF error". Between the two bounds the real write is tried. The cost
  !> is writing the output's size once more.
  subroutine reserve_space(path, nbytes_min, nbytes_max, error)
    character(len=*), intent(in) :: path          !! the temporary file the output will be
    integer(i8), intent(in) :: nbytes_min         !! a lower bound of the file's size
    integer(i8), intent(in) :: nbytes_max         !! an upper bound of the file's size
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: CHUNK = 1048576
    character(len=1), allocatable :: zeros(:)
    character(len=512) :: msg
    integer(i8) :: left, written
    integer :: unit, ios, ios_close

    call ignore_file_size_signal()
    call remove_file(path)
    open (newunit=unit, file=path, access='stream', form='unformatted', status='new', &
          action='write', iostat=ios, iomsg=msg)
    if (ios /= 0) return       ! cannot be created: the caller's create says why, in its words
    allocate (zeros(int(min(nbytes_max, int(CHUNK, i8)))))
    zeros = c_null_char
    left = nbytes_max
    do while (left > 0_i8 .and. ios == 0)
      write (unit, iostat=ios, iomsg=msg) zeros(1:int(min(left, int(size(zeros), i8))))
      left = left - size(zeros)
    end do
    if (ios == 0) flush (unit, iostat=ios, iomsg=msg)
    written = -1_i8
    if (ios /= 0) inquire (unit=unit, size=written)
    close (unit, status='delete', iostat=ios_close)
    if (ios == 0) return
    call remove_file(path)
    if (written >= nbytes_min) return     ! the file may fit: the real write decides
    call set_error(error, 'reserve_space('//path//'): '//trim(msg)//' (the file needs '// &
                   str(nbytes_min)//' to '//str(nbytes_max)//' bytes)')
    call probe_message(path, msg, error)
  end subroutine reserve_space

  !> Bounds of the size of the netCDF-4 file of a result set: the values (mean and standard
  !> error) and coordinates as doubles and the attribute texts, plus HDF5 object headers per
  !> dimension and variable (measured: about 1.1 KiB each in kumo's outputs) and the file's own
  !> structures: at least 512 bytes per object and 2 KiB (with compression the values do not
  !> count), at most 4 KiB per object and 64 KiB.
  pure subroutine result_set_bytes(set, nbytes_min, nbytes_max)
    type(result_set_t), intent(in) :: set
    integer(i8), intent(out) :: nbytes_min, nbytes_max
    integer :: i
    integer(i8) :: n_objects, n_text
    nbytes_min = 0_i8
    n_objects = 0_i8
    n_text = 0_i8
    if (allocated(set%dims)) then
      do i = 1, size(set%dims)
        n_objects = n_objects + 1_i8
        if (allocated(set%dims(i)%coord)) nbytes_min = nbytes_min + &
                                                       8_i8*size(set%dims(i)%coord, kind=i8)
      end do
    end if
    if (allocated(set%vars)) then
      do i = 1, size(set%vars)
        n_objects = n_objects + 2_i8
        nbytes_min = nbytes_min + 8_i8*var_size(set%vars(i))
        if (var_has_stderr(set%vars(i))) nbytes_min = nbytes_min + 8_i8*var_size(set%vars(i))
      end do
    end if
    if (allocated(set%attrs)) then
      do i = 1, size(set%attrs)
        if (allocated(set%attrs(i)%value)) n_text = n_text + len(set%attrs(i)%value, kind=i8)
      end do
    end if
    nbytes_min = nbytes_min + n_text
    nbytes_max = nbytes_min + 4096_i8*n_objects + 65536_i8
    if (set%deflate > 0) nbytes_min = n_text     ! compressed values: only the text is sure
    nbytes_min = nbytes_min + 512_i8*n_objects + 2048_i8
  end subroutine result_set_bytes

  !> Ignore SIGXFSZ, so that a write beyond the file size limit (`ulimit -f`) fails with an
  !> error kumo reports ("file size limit exceeded", the file named, the temporary file removed)
  !> instead of ending the process with a backtrace and a partial `<output>.tmp`. The Fortran
  !> runtime installs its own handler for this signal at start-up, so an inherited "ignore" is
  !> not enough. Called before each output file is created.
  subroutine ignore_file_size_signal()
    type(c_funptr) :: previous
    previous = c_signal(SIGNAL_XFSZ, transfer(1_c_intptr_t, c_null_funptr))   ! SIG_IGN
  end subroutine ignore_file_size_signal

  !> Delete a file if it exists; failures are ignored (used only while cleaning up).
  subroutine remove_file(path)
    character(len=*), intent(in) :: path
    integer(c_int) :: status
    status = c_remove(path//c_null_char)
  end subroutine remove_file

  !> Read a text attribute of a variable (or NF90_GLOBAL); `found` is false if it is absent.
  subroutine get_text_att(routine, path, ncid, varid, name, value, found, error)
    character(len=*), intent(in) :: routine, path
    integer, intent(in) :: ncid, varid
    character(len=*), intent(in) :: name
    character(len=:), allocatable, intent(out) :: value
    logical, intent(out) :: found
    type(error_t), allocatable, intent(out) :: error
    character(len=NF90_MAX_NAME) :: vname
    character(len=:), allocatable :: at
    integer :: status, xtype, length

    found = .false.
    if (varid == NF90_GLOBAL) then
      at = where_text(routine, path, name)
    else
      call nc_check(nf90_inquire_variable(ncid, varid, name=vname), &
                    where_text(routine, path, name), error)
      if (allocated(error)) return
      at = where_text(routine, path, trim(vname)//'/'//name)
    end if
    status = nf90_inquire_attribute(ncid, varid, name, xtype=xtype, len=length)
    if (status == NF90_ENOTATT) return
    call nc_check(status, at, error)
    if (allocated(error)) return
    if (xtype /= NF90_CHAR) then
      call set_error(error, at//': attribute is not text')
      return
    end if
    found = .true.
    allocate (character(len=length) :: value)
    if (length > 0) then
      call nc_check(nf90_get_att(ncid, varid, name, value), at, error)
      if (allocated(error)) return
    end if
    do while (len(value) > 0)
      if (value(len(value):len(value)) /= c_null_char) exit
      value = value(1:len(value) - 1)
    end do
  end subroutine get_text_att

  !> Write a text attribute unless the text is absent or blank. An unallocated allocatable actual
  !> argument counts as absent (Fortran 2008).
  subroutine put_text_att_if_set(at, ncid, varid, name, text, error)
    character(len=*), intent(in) :: at
    integer, intent(in) :: ncid, varid
    character(len=*), intent(in) :: name
    character(len=*), intent(in), optional :: text
    type(error_t), allocatable, intent(out) :: error
    if (.not. present(text)) return
    if (len_trim(text) == 0) return
    call nc_check(nf90_put_att(ncid, varid, name, trim(text)), at//'/'//name, error)
  end subroutine put_text_att_if_set

  !> Write flattened values into a variable of `ndims` dimensions with the given counts.
  subroutine put_flat(ncid, varid, ndims, counts, values, at, error)
    integer, intent(in) :: ncid, varid, ndims
    integer, intent(in) :: counts(:)
    real(dp), intent(in) :: values(:)
    character(len=*), intent(in) :: at
    type(error_t), allocatable, intent(out) :: error
    if (ndims == 0) then
      call nc_check(nf90_put_var(ncid, varid, values(1)), at, error)
    else
      call nc_check(nf90_put_var(ncid, varid, values, start=spread(1, 1, ndims), &
                                 count=counts(1:ndims)), at, error)
    end if
  end subroutine put_flat

  !> Position of the named dimension in the set, 0 if absent.
  pure integer function dim_position(set, name) result(pos)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: name
    integer :: i
    pos = 0
    if (.not. allocated(set%dims)) return
    do i = 1, size(set%dims)
      if (trim(set%dims(i)%name) == trim(name)) then
        pos = i
        return
      end if
    end do
  end function dim_position

  ! ------------------------------------------------------------------------------------------------
  ! Text formatting
  ! ------------------------------------------------------------------------------------------------

  !> A real value in messages, with nine significant digits; NaN and infinities spelt out.
  function real_text(x) result(text)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: text
    character(len=32) :: buffer
    if (ieee_is_nan(x)) then
      text = 'NaN'
    else if (.not. ieee_is_finite(x)) then
      if (x > 0.0_wp) then
        text = '+Infinity'
      else
        text = '-Infinity'
      end if
    else
      write (buffer, '(es16.8)') x
      text = trim(adjustl(buffer))
    end if
  end function real_text
end module kumo_netcdf
