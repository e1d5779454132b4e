! SPDX-License-Identifier: BSD-3-Clause
!> Cloud fields from LES / cloud-resolving-model netCDF output.
!>
!> `read_les_field` reads liquid water content and droplet effective radius (or droplet number,
!> from which the effective radius is computed), optionally ice water content and ice effective
!> radius, temperature and pressure, and the grid, from one time step of a model output file.
!> Units come from each variable's `units` attribute (module `kumo_units`); a missing or unknown
!> unit is an error. The conventions, defaults and messages are described in docs/les-input.md.
!>
!> Dimension order: a 3-D field is `(x, y, z)` in Fortran order, i.e. `(z, y, x)` or
!> `(time, z, y, x)` as ncdump shows it. Any other order is an error showing the order found and
!> the order expected; nothing is transposed.
!>
!> Memory: every variable is read once, only the chosen time step (start/count), straight into
!> its array of the result; the netCDF library converts float to double while reading. The only
!> full-size temporary is the air density when a density variable is needed for mixing ratios.
module kumo_les_netcdf
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use netcdf, only: nf90_open, nf90_close, nf90_get_att, nf90_get_var, nf90_inq_dimid, &
                    nf90_inq_varid, nf90_inquire_dimension, nf90_inquire_variable, &
                    nf90_inquire_attribute, nf90_strerror, NF90_NOERR, NF90_ENOTATT, &
                    NF90_NOWRITE, NF90_DOUBLE, NF90_FLOAT, NF90_CHAR, NF90_FILL_DOUBLE, &
                    NF90_FILL_FLOAT, NF90_MAX_VAR_DIMS, NF90_MAX_NAME
  use kumo_kinds, only: wp, sp, dp, vp
  use kumo_constants, only: PI
  use kumo_error, only: error_t, set_error, str, join
  use kumo_file_check, only: check_netcdf_complete
  use kumo_units, only: unit_factor, QTY_WATER_CONTENT, QTY_LENGTH, QTY_RADIUS, QTY_NUMBER, &
                        QTY_TEMPERATURE, QTY_PRESSURE, QTY_AIR_DENSITY, QTY_HUMIDITY
  implicit none
  private
  public :: les_names_t, les_field_t, read_les_field
  public :: LES_NAME_LEN, LES_NONE, K_MARITIME, K_CONTINENTAL, R_DRY_AIR, RHO_LIQUID_WATER
  public :: DEFAULT_LWC, DEFAULT_REFF, DEFAULT_NUMBER, DEFAULT_IWC, DEFAULT_REFF_ICE, &
            DEFAULT_TEMPERATURE, DEFAULT_POTENTIAL_TEMPERATURE, DEFAULT_PRESSURE, DEFAULT_AIR_DENSITY, DEFAULT_X, DEFAULT_Y, &
            DEFAULT_Z, DEFAULT_X_EDGES, DEFAULT_Y_EDGES, DEFAULT_Z_EDGES

  integer, parameter :: LES_NAME_LEN = 64   !! longest variable name in les_names_t
  !> A name of `'none'` switches an optional variable off even if the file has it.
  character(len=*), parameter :: LES_NONE = 'none'

  !> Ratio k = (r_v / r_e)^3 of volume-mean to effective radius cubed for stratocumulus droplet
  !> spectra: 0.80 +- 0.07 maritime, 0.67 +- 0.07 continental (Martin, Johnson and Spice 1994,
  !> J. Atmos. Sci. 51, 1823-1842).
  real(wp), parameter :: K_MARITIME = 0.80_wp
  real(wp), parameter :: K_CONTINENTAL = 0.67_wp
  !> Density of liquid water [g m-3] used with Martin et al. (1994): 1000 kg m-3.
  real(wp), parameter :: RHO_LIQUID_WATER = 1.0e6_wp
  !> Gas constant of dry air [J kg-1 K-1], 287.047: R / M_a with R = 8.314462618 J mol-1 K-1
  !> (CODATA 2018) and M_a = 28.96546e-3 kg mol-1 (Picard et al. 2008, Metrologia 45, 149-155).
  real(wp), parameter :: R_DRY_AIR = 8.314462618_wp/28.96546e-3_wp
  !> Reference pressure of potential temperature [Pa] (1000 hPa).
  real(wp), parameter :: P_REFERENCE = 1.0e5_wp
  !> Exponent R_d/c_pd of the Exner function (p/p0)^kappa: dry air as an ideal diatomic gas,
  !> c_pd = 7/2 R_d = 1004.7 J kg-1 K-1 (e.g. Bohren and Albrecht 1998, Atmospheric
  !> Thermodynamics, ch. 3).
  real(wp), parameter :: KAPPA_DRY_AIR = 2.0_wp/7.0_wp

  !> Default names, tried in order when a name is left blank; the first one in the file is used.
  !> Names whose meaning differs between models in a way units cannot tell are left out (WRF's
  !> `T` is a perturbation potential temperature in K, its `P` a perturbation pressure in Pa).
  character(len=*), parameter :: DEFAULT_LWC(8) = [character(len=8) :: &
                                                   'lwc', 'LWC', 'ql', 'qc', 'QC', 'qcl', &
                                                   'QCLOUD', 'clw']
  character(len=*), parameter :: DEFAULT_REFF(7) = [character(len=8) :: &
                                                    'reff', 'r_eff', 'Reff', 're', 'rel', 'REL', &
                                                    'reff_liq']
  character(len=*), parameter :: DEFAULT_NUMBER(7) = [character(len=8) :: &
                                                      'nc', 'Nc', 'NC', 'nd', 'Nd', 'cdnc', &
                                                      'QNCLOUD']
  character(len=*), parameter :: DEFAULT_IWC(6) = [character(len=8) :: &
                                                   'iwc', 'IWC', 'qi', 'QI', 'QICE', 'cli']
  character(len=*), parameter :: DEFAULT_REFF_ICE(6) = [character(len=9) :: &
                                                        'reff_ice', 'r_eff_ice', 'Reff_ice', &
                                                        'rei', 'REI', 're_ice']
  character(len=*), parameter :: DEFAULT_TEMPERATURE(5) = [character(len=11) :: &
                                                           'temperature', 'temp', 'TABS', 'tabs', &
                                                           'ta']
  !> Potential temperature, used for thermal emission when the file has no temperature (then it
  !> needs the pressure). Liquid-water potential temperatures (thl) are not potential
  !> temperatures and are not on the list.
  character(len=*), parameter :: DEFAULT_POTENTIAL_TEMPERATURE(4) = [character(len=21) :: &
                                                                     'theta', 'THETA', 'th', &
                                                                     'potential_temperature']
  character(len=*), parameter :: DEFAULT_PRESSURE(4) = [character(len=8) :: &
                                                        'pressure', 'pres', 'p', 'PRES']
  !> Water vapour (broadband gas state): specific humidities and mixing ratios. Total-water
  !> variables (qt, q of several models) hold the condensate too and are not on the list.
  character(len=*), parameter :: DEFAULT_VAPOUR(7) = [character(len=21) :: &
                                                      'qv', 'QV', 'QVAPOR', 'qvapor', 'hus', &
                                                      'specific_humidity', 'humidity_mixing_ratio']
  !> Molar masses of dry air and water [kg mol-1] (U.S. Standard Atmosphere 1976; CRC).
  real(wp), parameter :: M_DRY_AIR = 28.9644e-3_wp, M_WATER = 18.0153e-3_wp
  character(len=*), parameter :: DEFAULT_AIR_DENSITY(5) = [character(len=11) :: &
                                                           'rho', 'rho_air', 'rhoa', 'RHO', &
                                                           'air_density']
  !> Coordinates: dimension names of the cell centres, and edge variables (n + 1 values).
  character(len=*), parameter :: DEFAULT_X(3) = [character(len=2) :: 'x', 'xt', 'xc']
  character(len=*), parameter :: DEFAULT_Y(3) = [character(len=2) :: 'y', 'yt', 'yc']
  character(len=*), parameter :: DEFAULT_Z(3) = [character(len=2) :: 'z', 'zt', 'zc']
  character(len=*), parameter :: DEFAULT_X_EDGES(2) = [character(len=7) :: 'x_edges', 'xedges']
  character(len=*), parameter :: DEFAULT_Y_EDGES(2) = [character(len=7) :: 'y_edges', 'yedges']
  character(len=*), parameter :: DEFAULT_Z_EDGES(3) = &
                                 [character(len=7) :: 'z_edges', 'zedges', 'zh']

  !> Names of the variables to read. Blank: try the DEFAULT_* list; `'none'`: do not read an
  !> optional variable. A name that is given must exist in the file.
  type :: les_names_t
    character(len=LES_NAME_LEN) :: lwc = ''          !! liquid water content or mixing ratio
    character(len=LES_NAME_LEN) :: reff = ''         !! droplet effective radius
    character(len=LES_NAME_LEN) :: number = ''       !! droplet number (used when reff is absent)
    character(len=LES_NAME_LEN) :: iwc = ''          !! ice water content or mixing ratio
    character(len=LES_NAME_LEN) :: reff_ice = ''     !! ice effective radius
    character(len=LES_NAME_LEN) :: temperature = ''  !! temperature
    !> potential temperature (thermal runs, when the file has no temperature)
    character(len=LES_NAME_LEN) :: potential_temperature = ''
    character(len=LES_NAME_LEN) :: pressure = ''     !! pressure
    character(len=LES_NAME_LEN) :: air_density = ''  !! air density (for mixing ratios)
    character(len=LES_NAME_LEN) :: vapour = ''       !! water vapour (broadband gas state)
    character(len=LES_NAME_LEN) :: x = ''            !! x dimension (centres)
    character(len=LES_NAME_LEN) :: y = ''            !! y dimension (centres)
    character(len=LES_NAME_LEN) :: z = ''            !! z dimension (centres)
    character(len=LES_NAME_LEN) :: x_edges = ''      !! x cell edges (nx + 1 values)
    character(len=LES_NAME_LEN) :: y_edges = ''      !! y cell edges (ny + 1 values)
    character(len=LES_NAME_LEN) :: z_edges = ''      !! z layer edges (nz + 1 values)
  end type les_names_t

  !> A cloud field on a grid with uniform horizontal spacing, in kumo's units.
  type :: les_field_t
    integer :: nx = 0                                 !! columns along x
    integer :: ny = 0                                 !! columns along y
    integer :: nz = 0                                 !! layers
    real(wp) :: dx = 0.0_wp                           !! column width along x [m]
    real(wp) :: dy = 0.0_wp                           !! column width along y [m]
    real(wp), allocatable :: z_edges(:)               !! layer edges (nz + 1), bottom first [m]
    real(vp), allocatable :: lwc(:, :, :)             !! liquid water content (nx, ny, nz) [g m-3]
    real(vp), allocatable :: reff(:, :, :)            !! droplet effective radius [um]
    logical :: reff_computed = .false.                !! reff computed from lwc and droplet number
    real(wp) :: k_factor = 0.0_wp                     !! k used when reff_computed
    logical :: has_ice = .false.                      !! iwc and reff_ice present
    real(vp), allocatable :: iwc(:, :, :)             !! ice water content (nx, ny, nz) [g m-3]
    real(vp), allocatable :: reff_ice(:, :, :)        !! ice effective radius [um]
    logical :: has_temperature = .false.              !! temperature read (needed and present)
    !> the temperature was computed from a potential temperature and the pressure
    logical :: temperature_from_theta = .false.
    !> temperature [K]: shape (nx, ny, nz), or (1, 1, nz) for a profile
    real(vp), allocatable :: temperature(:, :, :)
    logical :: has_pressure = .false.                 !! pressure read (needed and present)
    !> pressure [Pa]: shape (nx, ny, nz), or (1, 1, nz) for a profile
    real(vp), allocatable :: pressure(:, :, :)
    !> grid-only reads with `pressure_profile`: the pressure of each layer [Pa] in double
    !> precision, the horizontal mean of a 3-D variable (`pressure_averaged`)
    real(wp), allocatable :: pressure_profile(:)
    logical :: pressure_averaged = .false.
    !> grid-only reads with `state_profile`: per layer, the mean over the columns of the
    !> temperature [K] (`t_profile`) and of the water vapour's volume mixing ratio relative to
    !> dry air [mol mol-1] (`h2o_profile`), each allocated when the file has it, and the
    !> pressure in `pressure_profile` when the file has one
    real(wp), allocatable :: t_profile(:), h2o_profile(:)
    type(les_names_t) :: used                         !! names actually read (blank: not read)
    character(len=:), allocatable :: notes            !! one line per variable: name, unit, origin
  end type les_field_t

  !> An open file and the grid dimensions found in it.
  type :: les_file_t
    character(len=:), allocatable :: path
    integer :: ncid = -1
    integer :: dimids(3) = -1      !! netCDF ids of the x, y, z dimensions
    integer :: n(3) = 0            !! nx, ny, nz
    integer :: tdim = -1           !! id of the time dimension, -1 if none
    integer :: nt = 0              !! its length
    integer :: itime = -1          !! chosen time step, -1 for none
    character(len=NF90_MAX_NAME) :: names(3) = ''  !! names of the x, y, z dimensions
    character(len=NF90_MAX_NAME) :: tname = ''     !! name of the time dimension
  end type les_file_t

  !> A variable read one layer at a time (read_state_profile).
  type :: layer_var_t
    integer :: id = -1, ndims = 0
    character(len=:), allocatable :: name, at, units
    logical :: profile = .false., positive = .false., has_missing = .false.
    real(wp) :: factor = 1.0_wp, fill = 0.0_wp, missing = 0.0_wp
  end type layer_var_t

  character(len=*), parameter :: PROC = 'read_les_field'
  character(len=*), parameter :: AXES(3) = ['x', 'y', 'z']
  character(len=*), parameter :: NL = new_line('a')

contains

  !> Read one time step of an LES / CRM output file into a cloud field in kumo's units.
  !>
  !> * `lwc` [g m-3] from a mass concentration or, with the air density, a mixing ratio;
  !> * `reff` [um], or computed from `lwc` and droplet number N as
  !>   r_e = (3 LWC / (4 pi rho_w k N))^(1/3) (Martin et al. 1994, eq. 11, with k = `k_factor`,
  !>   default K_MARITIME) where N is read instead; `reff` is 0 where LWC = 0;
  !> * `iwc`, `reff_ice` if the file has an ice water variable (then `reff_ice` is required);
  !> * air density for mixing ratios from a density variable, else from p and T by the ideal gas
  !>   law rho = p / (R_d T), else an error saying what is missing; temperature [K] and pressure
  !>   [Pa] (3-D fields or profiles over z) are read only then, and kept;
  !> * with `temperature` (thermal runs), the temperature [K] in any case if the file has it;
  !>   else, if it has a potential temperature theta and the pressure p, T = theta (p/p0)^kappa
  !>   (p0 = 1000 hPa, kappa = R_d/c_pd = 2/7), noted in `notes`. A file with neither leaves
  !>   `has_temperature` false (the caller decides what that means).
  !>
  !> Coordinates: the x, y, z dimensions are found by name (names%x or DEFAULT_X, ...). Each axis
  !> is taken from an edges variable with n + 1 values if there is one (names%x_edges or
  !> DEFAULT_X_EDGES, ...), else from the coordinate variable of the dimension (cell centres).
  !> Units m or km. x and y must be uniformly spaced. z may be stretched when edges are given;
  !> from centres the edges are the midpoints between centres (the outer edges half a spacing
  !> beyond the outer centres), which is exact for uniform centres and is used for stretched
  !> centres only when `z_edges_from_midpoints` is true, since it is one convention among several.
  subroutine read_les_field(path, names, time_index, field, error, k_factor, &
                            z_edges_from_midpoints, grid_only, part, pressure_profile, &
                            temperature, state_profile)
    character(len=*), intent(in) :: path               !! netCDF file
    type(les_names_t), intent(in) :: names             !! variable names (blank: defaults)
    integer, intent(in) :: time_index                  !! time step (1-based), or -1: no time dim
    type(les_field_t), intent(out) :: field            !! the field, in kumo's units
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: k_factor         !! Martin et al. k (default K_MARITIME)
    !> accept edges from midpoints of stretched z centres (default false)
    logical, intent(in), optional :: z_edges_from_midpoints
    !> read only the grid (nx, ny, nz, dx, dy, z_edges) and check the liquid water variable's
    !> layout and time step; no field is read (default false)
    logical, intent(in), optional :: grid_only
    !> 'liquid': liquid water and its radius only (`has_ice` still tells whether the file has
    !> ice water); 'ice': ice water and its radius only; default: both. Reading the species one
    !> at a time halves the memory of a large field.
    character(len=*), intent(in), optional :: part
    !> with `grid_only`: also read the pressure, which is then required, into
    !> `pressure_profile` (one value per layer, a 3-D variable averaged over the columns of
    !> each layer and read one layer at a time, so that no 3-D array is held; default false)
    logical, intent(in), optional :: pressure_profile
    !> also read the temperature, or a potential temperature and the pressure, when the file
    !> has them (thermal emission; default false)
    logical, intent(in), optional :: temperature
    !> with `grid_only`: also the gas state of every layer, the column means of temperature,
    !> pressure and water vapour where the file has them (`t_profile`, `pressure_profile`,
    !> `h2o_profile`), read one layer at a time (default false)
    logical, intent(in), optional :: state_profile
    type(les_file_t) :: f
    type(error_t), allocatable :: close_error
    logical :: liquid, ice
    integer :: status
    real(wp) :: k
    logical :: midpoints

    k = K_MARITIME
    if (present(k_factor)) k = k_factor
    midpoints = .false.
    if (present(z_edges_from_midpoints)) midpoints = z_edges_from_midpoints
    if (.not. (k > 0.0_wp .and. k <= 1.0_wp)) then
      call set_error(error, PROC//': k_factor = '//str(k)//' must satisfy 0 < k_factor <= 1')
      return
    end if
    if (time_index == 0 .or. time_index < -1) then
      call set_error(error, PROC//'('//trim(path)//'): time index '//str(time_index)// &
                     ' must be >= 1, or -1 for a file without a time dimension')
      return
    end if
    liquid = .true.
    ice = .true.
    if (present(part)) then
      select case (part)
      case ('liquid')
        ice = .false.
      case ('ice')
        liquid = .false.
      case default
        call set_error(error, PROC//': part = "'//part//'" must be liquid or ice')
        return
      end select
    end if
    f%path = trim(path)
    f%itime = time_index
    call check_netcdf_complete(PROC//'('//f%path//')', f%path, error)
    if (allocated(error)) return
    call nc_check(nf90_open(f%path, NF90_NOWRITE, f%ncid), PROC//'('//f%path//')', error)
    if (allocated(error)) return
    field%notes = ''
    call read_body(f, names, k, midpoints, liquid, ice, field, error, grid_only, &
                   pressure_profile, temperature, state_profile)
    status = nf90_close(f%ncid)
    if (.not. allocated(error)) then
      call nc_check(status, PROC//'('//f%path//')', close_error)
      if (allocated(close_error)) call move_alloc(close_error, error)
    end if
    if (allocated(error)) call clear_field(field)
  end subroutine read_les_field

  ! ------------------------------------------------------------------------------------------------

  subroutine read_body(f, names, k, midpoints, liquid, ice, field, error, grid_only, &
                       pressure_profile, want_temperature, state_profile)
    type(les_file_t), intent(inout) :: f
    type(les_names_t), intent(in) :: names
    real(wp), intent(in) :: k
    logical, intent(in) :: midpoints
    logical, intent(in) :: liquid, ice     !! read these species
    type(les_field_t), intent(inout) :: field
    type(error_t), allocatable, intent(out) :: error
    logical, intent(in), optional :: grid_only, pressure_profile, want_temperature, state_profile
    integer :: lwc_id, reff_id, num_id, iwc_id, rei_id, t_id, p_id, rho_id
    character(len=:), allocatable :: lwc_name, reff_name, num_name, iwc_name, rei_name
    character(len=:), allocatable :: t_name, p_name, rho_name, text
    real(wp), allocatable :: edges(:)
    real(vp), allocatable :: rho(:, :, :)
    real(wp) :: spacing
    logical :: lwc_per_air, num_per_air, iwc_per_air, ice_per_air, reff_per_air, dummy

    ! Grid dimensions and coordinates.
    call find_axis_dim(f, 1, names%x, DEFAULT_X, error)
    if (allocated(error)) return
    call find_axis_dim(f, 2, names%y, DEFAULT_Y, error)
    if (allocated(error)) return
    call find_axis_dim(f, 3, names%z, DEFAULT_Z, error)
    if (allocated(error)) return
    field%nx = f%n(1)
    field%ny = f%n(2)
    field%nz = f%n(3)
    call read_axis(f, 1, names%x_edges, DEFAULT_X_EDGES, midpoints, edges, field%dx, field, &
                   error)
    if (allocated(error)) return
    call read_axis(f, 2, names%y_edges, DEFAULT_Y_EDGES, midpoints, edges, field%dy, field, &
                   error)
    if (allocated(error)) return
    call read_axis(f, 3, names%z_edges, DEFAULT_Z_EDGES, midpoints, edges, spacing, field, &
                   error)
    if (allocated(error)) return
    call move_alloc(edges, field%z_edges)

    ! Liquid water defines the time dimension; every other field must agree with it.
    call find_var(f, 'liquid water', names%lwc, DEFAULT_LWC, .true., lwc_id, lwc_name, error)
    if (allocated(error)) return
    call find_time(f, lwc_id, lwc_name, error)
    if (allocated(error)) return
    if (present(grid_only)) then
      if (grid_only) then
        if (present(pressure_profile)) then
          if (pressure_profile) call read_pressure_profile(f, names, field, error)
        end if
        if (allocated(error)) return
        if (present(state_profile)) then
          if (state_profile) call read_state_profile(f, names, field, error)
        end if
        return
      end if
    end if

    ! Temperature and pressure (optional): found here, read only for mixing ratios without a
    ! density variable (below), so that a model's T and p cost no memory otherwise.
    call find_var(f, 'temperature', names%temperature, DEFAULT_TEMPERATURE, .false., t_id, &
                  t_name, error)
    if (allocated(error)) return
    call find_var(f, 'pressure', names%pressure, DEFAULT_PRESSURE, .false., p_id, p_name, error)
    if (allocated(error)) return

    ! Liquid water and its effective radius, or droplet number.
    lwc_per_air = .false.
    num_per_air = .false.
    if (liquid) then
      call read_field(f, lwc_id, lwc_name, QTY_WATER_CONTENT, .false., .false., field%lwc, &
                      lwc_per_air, field%notes, error)
      if (allocated(error)) return
      field%used%lwc = lwc_name
      call find_var(f, 'droplet effective radius', names%reff, DEFAULT_REFF, .false., reff_id, &
                    reff_name, error)
      if (allocated(error)) return
      if (reff_id >= 0) then
        call read_field(f, reff_id, reff_name, QTY_RADIUS, .false., .false., field%reff, &
                        reff_per_air, field%notes, error)
        if (allocated(error)) return
        field%used%reff = reff_name
      else
        call find_var(f, 'droplet number', names%number, DEFAULT_NUMBER, .false., num_id, &
                      num_name, error)
        if (allocated(error)) return
        if (num_id < 0) then
          call set_error(error, PROC//'('//f%path//'): neither a droplet effective radius '// &
                         '(tried '//tried(names%reff, DEFAULT_REFF)//') nor a droplet number '// &
                         '(tried '//tried(names%number, DEFAULT_NUMBER)//') is in the file')
          return
        end if
        ! The number goes into the reff array and is turned into a radius below (no temporary).
        call read_field(f, num_id, num_name, QTY_NUMBER, .false., .false., field%reff, &
                        num_per_air, field%notes, error)
        if (allocated(error)) return
        field%used%number = num_name
        field%reff_computed = .true.
        field%k_factor = k
      end if
    end if

    ! Ice (optional): water content and then a required effective radius.
    call find_var(f, 'ice water', names%iwc, DEFAULT_IWC, .false., iwc_id, iwc_name, error)
    if (allocated(error)) return
    iwc_per_air = .false.
    if (iwc_id >= 0) then
      call find_var(f, 'ice effective radius', names%reff_ice, DEFAULT_REFF_ICE, .false., &
                    rei_id, rei_name, error)
      if (allocated(error)) return
      if (rei_id < 0) then
        call set_error(error, PROC//'('//f%path//'): ice water "'//iwc_name//'" needs an ice '// &
                       'effective radius; tried '//tried(names%reff_ice, DEFAULT_REFF_ICE)// &
                       ' (name it, or set the ice water name to "none" to skip ice)')
        return
      end if
      field%has_ice = .true.
      field%used%iwc = iwc_name
      field%used%reff_ice = rei_name
      if (ice) then
        call read_field(f, iwc_id, iwc_name, QTY_WATER_CONTENT, .false., .false., field%iwc, &
                        iwc_per_air, field%notes, error)
        if (allocated(error)) return
        call read_field(f, rei_id, rei_name, QTY_RADIUS, .false., .false., field%reff_ice, &
                        ice_per_air, field%notes, error)
        if (allocated(error)) return
      end if
    end if

    ! Quantities per mass of air: multiply by the air density.
    if (lwc_per_air .or. num_per_air .or. iwc_per_air) then
      call find_var(f, 'air density', names%air_density, DEFAULT_AIR_DENSITY, .false., rho_id, &
                    rho_name, error)
      if (allocated(error)) return
      if (rho_id >= 0) then
        call read_field(f, rho_id, rho_name, QTY_AIR_DENSITY, .true., .true., rho, dummy, &
                        field%notes, error)
        if (allocated(error)) return
        field%used%air_density = rho_name
        if (lwc_per_air) call scale_by(field%lwc, rho)
        if (num_per_air) call scale_by(field%reff, rho)
        if (iwc_per_air) call scale_by(field%iwc, rho)
        deallocate (rho)
        field%notes = field%notes//'mixing ratios times air density "'//rho_name//'"'//NL
      else if (t_id >= 0 .and. p_id >= 0) then
        call read_field(f, t_id, t_name, QTY_TEMPERATURE, .true., .true., field%temperature, &
                        dummy, field%notes, error)
        if (allocated(error)) return
        field%has_temperature = .true.
        field%used%temperature = t_name
        call read_field(f, p_id, p_name, QTY_PRESSURE, .true., .true., field%pressure, dummy, &
                        field%notes, error)
        if (allocated(error)) return
        field%has_pressure = .true.
        field%used%pressure = p_name
        if (lwc_per_air) call scale_by_ideal_gas(field%lwc, field%pressure, field%temperature)
        if (num_per_air) call scale_by_ideal_gas(field%reff, field%pressure, field%temperature)
        if (iwc_per_air) call scale_by_ideal_gas(field%iwc, field%pressure, field%temperature)
        field%notes = field%notes//'mixing ratios times air density p / (R_d T) from "'// &
                      trim(field%used%pressure)//'" and "'//trim(field%used%temperature)// &
                      '", R_d = '//str(R_DRY_AIR)//' J kg-1 K-1'//NL
      else
        text = per_air_list(lwc_per_air, num_per_air, iwc_per_air, lwc_name, &
                            field%used%number, field%used%iwc)
        call set_error(error, PROC//'('//f%path//'): '//text// &
                       ' the air density: no density variable (tried '// &
                       tried(names%air_density, DEFAULT_AIR_DENSITY)//')'// &
                       missing_pt(p_id >= 0, t_id >= 0, names))
        return
      end if
    end if

    if (field%reff_computed) then
      call reff_from_number(f, lwc_name, field%used%number, k, field%lwc, field%reff, error)
      if (allocated(error)) return
      field%notes = field%notes//'reff computed from "'//lwc_name//'" and "'// &
                    trim(field%used%number)//'": r_e = (3 LWC / (4 pi rho_w k N))^(1/3), k = '// &
                    str(k)//' (Martin et al. 1994)'//NL
    end if

    if (present(want_temperature)) then
      if (want_temperature .and. .not. field%has_temperature) then
        call read_temperature(f, names, t_id, t_name, p_id, p_name, field, error)
        if (allocated(error)) return
      end if
    end if
  end subroutine read_body

  !> The temperature for thermal emission: the temperature variable if there is one, else a
  !> potential temperature converted with the pressure, T = theta (p/p0)^kappa; neither:
  !> `has_temperature` stays false and `notes` says what was tried.
  subroutine read_temperature(f, names, t_id, t_name, p_id, p_name, field, error)
    type(les_file_t), intent(in) :: f
    type(les_names_t), intent(in) :: names
    integer, intent(in) :: t_id, p_id
    character(len=*), intent(in) :: t_name, p_name
    type(les_field_t), intent(inout) :: field
    type(error_t), allocatable, intent(out) :: error
    integer :: th_id, ix, iy, iz, nx, ny
    character(len=:), allocatable :: th_name
    real(vp), allocatable :: theta(:, :, :)
    logical :: dummy
    real(wp) :: p

    if (t_id >= 0) then
      call read_field(f, t_id, t_name, QTY_TEMPERATURE, .true., .true., field%temperature, &
                      dummy, field%notes, error)
      if (allocated(error)) return
      field%has_temperature = .true.
      field%used%temperature = t_name
      return
    end if
    call find_var(f, 'potential temperature', names%potential_temperature, &
                  DEFAULT_POTENTIAL_TEMPERATURE, .false., th_id, th_name, error)
    if (allocated(error)) return
    if (th_id < 0) then
      field%notes = field%notes//'no temperature (tried '// &
                    tried(names%temperature, DEFAULT_TEMPERATURE)//') and no potential '// &
                    'temperature (tried '//tried(names%potential_temperature, &
                                                 DEFAULT_POTENTIAL_TEMPERATURE)//')'//NL
      return
    end if
    if (p_id < 0) then
      field%notes = field%notes//'potential temperature "'//th_name//'" not used: no '// &
                    'pressure to convert it (tried '//tried(names%pressure, DEFAULT_PRESSURE)// &
                    ')'//NL
      return
    end if
    call read_field(f, th_id, th_name, QTY_TEMPERATURE, .true., .true., theta, dummy, &
                    field%notes, error)
    if (allocated(error)) return
    if (.not. field%has_pressure) then
      call read_field(f, p_id, p_name, QTY_PRESSURE, .true., .true., field%pressure, dummy, &
                      field%notes, error)
      if (allocated(error)) return
      field%has_pressure = .true.
      field%used%pressure = p_name
    end if
    ! a 3-D result if either field is 3-D
    nx = max(size(theta, 1), size(field%pressure, 1))
    ny = max(size(theta, 2), size(field%pressure, 2))
    allocate (field%temperature(nx, ny, size(theta, 3)))
    do iz = 1, size(theta, 3)
      do iy = 1, ny
        do ix = 1, nx
          p = real(field%pressure(min(ix, size(field%pressure, 1)), &
                                  min(iy, size(field%pressure, 2)), iz), wp)
          field%temperature(ix, iy, iz) = real(theta(min(ix, size(theta, 1)), &
                                                     min(iy, size(theta, 2)), iz)* &
                                               (p/P_REFERENCE)**KAPPA_DRY_AIR, vp)
        end do
      end do
    end do
    field%has_temperature = .true.
    field%temperature_from_theta = .true.
    field%used%potential_temperature = th_name
    field%notes = field%notes//'temperature T = theta (p/p0)^kappa from "'//th_name// &
                  '" and "'//trim(field%used%pressure)//'", p0 = 1000 hPa, kappa = R_d/c_pd = 2/7'//NL
  end subroutine read_temperature

  ! ------------------------------------------------------------------------------------------------
  ! Grid
  ! ------------------------------------------------------------------------------------------------

  !> The dimension of axis `iaxis`: the given name or the first default that is a dimension.
  subroutine find_axis_dim(f, iaxis, given, defaults, error)
    type(les_file_t), intent(inout) :: f
    integer, intent(in) :: iaxis
    character(len=*), intent(in) :: given
    character(len=*), intent(in) :: defaults(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: i, dimid

    if (len_trim(given) > 0) then
      if (nf90_inq_dimid(f%ncid, trim(given), dimid) /= NF90_NOERR) then
        call set_error(error, PROC//'('//f%path//'): no '//AXES(iaxis)//' dimension "'// &
                       trim(given)//'" in the file')
        return
      end if
      call set_axis_dim(f, iaxis, given, dimid, error)
      return
    end if
    do i = 1, size(defaults)
      if (nf90_inq_dimid(f%ncid, trim(defaults(i)), dimid) /= NF90_NOERR) cycle
      call set_axis_dim(f, iaxis, defaults(i), dimid, error)
      return
    end do
    call set_error(error, PROC//'('//f%path//'): no '//AXES(iaxis)//' dimension; tried '// &
                   join(defaults))
  end subroutine find_axis_dim

  subroutine set_axis_dim(f, iaxis, name, dimid, error)
    type(les_file_t), intent(inout) :: f
    integer, intent(in) :: iaxis, dimid
    character(len=*), intent(in) :: name
    type(error_t), allocatable, intent(out) :: error
    f%dimids(iaxis) = dimid
    f%names(iaxis) = trim(name)
    call nc_check(nf90_inquire_dimension(f%ncid, dimid, len=f%n(iaxis)), at_text(f, name), error)
  end subroutine set_axis_dim

  !> Read the coordinate of one axis: edges (n + 1) if present, else centres. Returns the edges
  !> (vertical) or the uniform spacing (horizontal).
  subroutine read_axis(f, iaxis, given_edges, edge_defaults, midpoints, edges, spacing, field, &
                       error)
    type(les_file_t), intent(in) :: f
    integer, intent(in) :: iaxis
    character(len=*), intent(in) :: given_edges
    character(len=*), intent(in) :: edge_defaults(:)
    logical, intent(in) :: midpoints
    real(wp), allocatable, intent(out) :: edges(:)
    real(wp), intent(out) :: spacing
    type(les_field_t), intent(inout) :: field
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: c(:)
    integer :: varid, n, i, xtype
    character(len=:), allocatable :: ename, cname, at
    real(wp) :: tol
    logical :: vertical

    n = f%n(iaxis)
    vertical = iaxis == 3
    spacing = 0.0_wp
    call find_var(f, AXES(iaxis)//' edges', given_edges, edge_defaults, .false., varid, ename, &
                  error)
    if (allocated(error)) return

    if (varid >= 0) then
      at = at_text(f, ename)
      call read_coordinate(f, varid, ename, n + 1, edges, xtype, error)
      if (allocated(error)) return
      call check_increasing(at, edges, error)
      if (allocated(error)) return
      field%notes = field%notes//AXES(iaxis)//' from edges "'//ename//'"'//NL
      if (vertical) return
      spacing = (edges(n + 1) - edges(1))/n
      call check_uniform(at, edges, spacing, coordinate_tol(edges, xtype, spacing), .false., error)
      return
    end if

    ! Centres: the coordinate variable of the dimension.
    cname = trim(f%names(iaxis))
    at = at_text(f, cname)
    if (nf90_inq_varid(f%ncid, cname, varid) /= NF90_NOERR) then
      call set_error(error, at//': no coordinate for '//AXES(iaxis)//': neither a coordinate '// &
                     'variable "'//cname//'" (cell centres) nor an edges variable (tried '// &
                     tried(given_edges, edge_defaults)//')')
      return
    end if
    call read_coordinate(f, varid, cname, n, c, xtype, error)
    if (allocated(error)) return
    call check_increasing(at, c, error)
    if (allocated(error)) return
    if (n < 2) then
      call set_error(error, at//': one cell centre does not give the cell size; give the '// &
                     AXES(iaxis)//' edges (tried '//tried(given_edges, edge_defaults)//')')
      return
    end if
    spacing = (c(n) - c(1))/(n - 1)
    tol = coordinate_tol(c, xtype, spacing)
    if (.not. vertical) then
      call check_uniform(at, c, spacing, tol, vertical, error)
      if (allocated(error)) return
      field%notes = field%notes//AXES(iaxis)//' from centres "'//cname//'"'//NL
      return
    end if
    if (.not. midpoints) then
      call check_uniform(at, c, spacing, tol, vertical, error)
      if (allocated(error)) then
        error%message = error%message//'; the layer edges of stretched centres are a matter '// &
                        'of convention: give z edges (nz + 1 values; tried '// &
                        tried(given_edges, DEFAULT_Z_EDGES)//') or accept edges midway '// &
                        'between centres explicitly'
        return
      end if
    end if
    allocate (edges(n + 1))
    edges(1) = c(1) - 0.5_wp*(c(2) - c(1))
    do i = 2, n
      edges(i) = 0.5_wp*(c(i - 1) + c(i))
    end do
    edges(n + 1) = c(n) + 0.5_wp*(c(n) - c(n - 1))
    field%notes = field%notes//'z edges midway between centres "'//cname//'"'//NL
  end subroutine read_axis

  !> A 1-D coordinate variable with `n` values in m or km, converted to m.
  subroutine read_coordinate(f, varid, name, n, values, xtype, error)
    type(les_file_t), intent(in) :: f
    integer, intent(in) :: varid
    character(len=*), intent(in) :: name
    integer, intent(in) :: n
    real(wp), allocatable, intent(out) :: values(:)
    integer, intent(out) :: xtype
    type(error_t), allocatable, intent(out) :: error
    integer :: ndims, dimids(NF90_MAX_VAR_DIMS), length, i
    real(wp) :: factor, fill, missing
    logical :: per_air, has_missing
    character(len=:), allocatable :: at

    at = at_text(f, name)
    call nc_check(nf90_inquire_variable(f%ncid, varid, xtype=xtype, ndims=ndims, dimids=dimids), &
                  at, error)
    if (allocated(error)) return
    if (ndims /= 1) then
      call set_error(error, at//': a coordinate must have one dimension, found '//str(ndims))
      return
    end if
    call nc_check(nf90_inquire_dimension(f%ncid, dimids(1), len=length), at, error)
    if (allocated(error)) return
    if (length /= n) then
      call set_error(error, at//': '//str(length)//' values, expected '//str(n))
      return
    end if
    call real_var_attrs(f, varid, name, xtype, QTY_LENGTH, factor, per_air, fill, has_missing, &
                        missing, error)
    if (allocated(error)) return
    allocate (values(n))
    call nc_check(nf90_get_var(f%ncid, varid, values), at, error)
    if (allocated(error)) return
    do i = 1, n
      if (.not. ieee_is_finite(values(i))) then
        call set_error(error, at//': value '//str(values(i))//' at index '//str(i)// &
                       ' is not finite')
        return
      end if
      if (same(values(i), fill) .or. (has_missing .and. same(values(i), missing))) then
        call set_error(error, at//': value at index '//str(i)//' is the fill value (missing data)')
        return
      end if
    end do
    values = values*factor
  end subroutine read_coordinate

  subroutine check_increasing(at, c, error)
    character(len=*), intent(in) :: at
    real(wp), intent(in) :: c(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    do i = 2, size(c)
      if (c(i) > c(i - 1)) cycle
      call set_error(error, at//': values must increase (bottom / first cell first): value '// &
                     str(c(i))//' m at index '//str(i)//' follows '//str(c(i - 1))//' m')
      return
    end do
  end subroutine check_increasing

  !> Every step c(i) - c(i-1) must equal `spacing` within `tol` [m].
  subroutine check_uniform(at, c, spacing, tol, vertical, error)
    character(len=*), intent(in) :: at
    real(wp), intent(in) :: c(:), spacing, tol
    logical, intent(in) :: vertical
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    do i = 2, size(c)
      if (abs(c(i) - c(i - 1) - spacing) <= tol) cycle
      call set_error(error, at//': spacing is not uniform: step '//str(i - 1)//' to '//str(i)// &
                     ' is '//str(c(i) - c(i - 1))//' m, the mean step is '//str(spacing)//' m')
      if (.not. vertical) error%message = error%message//'; kumo needs uniform horizontal spacing'
      return
    end do
  end subroutine check_uniform

  !> Tolerance for "uniform": 1e-6 of the spacing plus the rounding of the stored coordinates
  !> (4 epsilon of the file's type times the largest magnitude), so float32 km coordinates of a
  !> regular grid pass and a real stretch does not.
  pure real(wp) function coordinate_tol(c, xtype, spacing) result(tol)
    real(wp), intent(in) :: c(:)
    integer, intent(in) :: xtype
    real(wp), intent(in) :: spacing
    real(wp) :: eps
    if (xtype == NF90_FLOAT) then
      eps = real(epsilon(1.0_sp), wp)
    else
      eps = real(epsilon(1.0_dp), wp)
    end if
    tol = 1.0e-6_wp*abs(spacing) + 4.0_wp*eps*maxval(abs(c))
  end function coordinate_tol

  ! ------------------------------------------------------------------------------------------------
  ! Fields
  ! ------------------------------------------------------------------------------------------------

  !> Time dimension from the liquid water variable: (x, y, z) or (x, y, z, time), Fortran order.
  subroutine find_time(f, varid, name, error)
    type(les_file_t), intent(inout) :: f
    integer, intent(in) :: varid
    character(len=*), intent(in) :: name
    type(error_t), allocatable, intent(out) :: error
    integer :: ndims, dimids(NF90_MAX_VAR_DIMS), i
    character(len=:), allocatable :: at

    at = at_text(f, name)
    call nc_check(nf90_inquire_variable(f%ncid, varid, ndims=ndims, dimids=dimids), at, error)
    if (allocated(error)) return
    if (ndims == 4) then
      do i = 1, 4
        if (all(dimids(i) /= f%dimids)) then
          f%tdim = dimids(i)
          exit
        end if
      end do
    end if
    if (f%tdim >= 0) then
      call nc_check(nf90_inquire_dimension(f%ncid, f%tdim, name=f%tname, len=f%nt), at, error)
      if (allocated(error)) return
    end if
    ! Layout first, so a transposed file is reported as such.
    call check_layout(f, varid, name, .false., error)
    if (allocated(error)) return
    if (f%tdim < 0 .and. f%itime /= -1) then
      call set_error(error, at//': time index '//str(f%itime)//' requested but the variable '// &
                     'has no time dimension; use -1')
    else if (f%tdim >= 0 .and. f%itime == -1) then
      call set_error(error, at//': the variable has a time dimension "'//trim(f%tname)// &
                     '" of length '//str(f%nt)//'; choose a time index from 1 to '//str(f%nt))
    else if (f%tdim >= 0 .and. f%itime > f%nt) then
      call set_error(error, at//': time index '//str(f%itime)//' is outside 1 to '//str(f%nt)// &
                     ' (length of dimension "'//trim(f%tname)//'")')
    end if
  end subroutine find_time

  !> Dimensions must be (x, y, z[, time]) in Fortran order, or (z[, time]) for a profile.
  !> Returns whether the variable is a profile.
  subroutine check_layout(f, varid, name, allow_profile, error, is_profile)
    type(les_file_t), intent(in) :: f
    integer, intent(in) :: varid
    character(len=*), intent(in) :: name
    logical, intent(in) :: allow_profile
    type(error_t), allocatable, intent(out) :: error
    logical, intent(out), optional :: is_profile
    integer :: ndims, dimids(NF90_MAX_VAR_DIMS), i
    character(len=NF90_MAX_NAME), allocatable :: dnames(:)
    character(len=:), allocatable :: found, expected, at
    logical :: ok, profile

    at = at_text(f, name)
    call nc_check(nf90_inquire_variable(f%ncid, varid, ndims=ndims, dimids=dimids), at, error)
    if (allocated(error)) return
    profile = .false.
    if (f%tdim >= 0) then
      ok = ndims == 4
      if (ok) ok = all(dimids(1:4) == [f%dimids, f%tdim])
      if (.not. ok .and. allow_profile) then
        profile = ndims == 2
        if (profile) profile = all(dimids(1:2) == [f%dimids(3), f%tdim])
        if (.not. profile) then
          profile = ndims == 1
          if (profile) profile = dimids(1) == f%dimids(3)
        end if
        ok = profile
      end if
    else
      ok = ndims == 3
      if (ok) ok = all(dimids(1:3) == f%dimids)
      if (.not. ok .and. allow_profile) then
        profile = ndims == 1
        if (profile) profile = dimids(1) == f%dimids(3)
        ok = profile
      end if
    end if
    if (present(is_profile)) is_profile = profile
    if (ok) return

    allocate (dnames(ndims))
    do i = 1, ndims                         ! ncdump order: slowest-varying first
      call nc_check(nf90_inquire_dimension(f%ncid, dimids(ndims + 1 - i), name=dnames(i)), at, &
                    error)
      if (allocated(error)) return
    end do
    found = join(dnames, ', ', '()')
    expected = '('//trim(f%names(3))//', '//trim(f%names(2))//', '//trim(f%names(1))//')'
    if (f%tdim >= 0) expected = '('//trim(f%tname)//', '//expected(2:)
    if (allow_profile) then
      if (f%tdim >= 0) then
        expected = expected//', ('//trim(f%tname)//', '//trim(f%names(3))//') or ('// &
                   trim(f%names(3))//')'
      else
        expected = expected//' or ('//trim(f%names(3))//')'
      end if
    end if
    call set_error(error, at//': dimensions are '//found//' in ncdump order; expected '// &
                   expected//' (Fortran order x, y, z, time); kumo does not transpose')
  end subroutine check_layout

  !> Read one field of the chosen time step in kumo's unit. 3-D fields get shape (nx, ny, nz),
  !> profiles (1, 1, nz). Values must be finite, not the fill value, and >= 0 (> 0 if
  !> `positive`). `per_air` reports a quantity per mass of air (not yet multiplied by density).
  subroutine read_field(f, varid, name, quantity, allow_profile, positive, values, per_air, &
                        notes, error)
    type(les_file_t), intent(in) :: f
    integer, intent(in) :: varid
    character(len=*), intent(in) :: name
    integer, intent(in) :: quantity
    logical, intent(in) :: allow_profile, positive
    real(vp), allocatable, intent(out) :: values(:, :, :)
    logical, intent(out) :: per_air
    character(len=:), allocatable, intent(inout) :: notes
    type(error_t), allocatable, intent(out) :: error
    integer :: xtype, ndims, iz
    real(wp) :: factor, fill, missing
    real(wp), allocatable :: slab(:, :, :)
    logical :: profile, has_missing
    character(len=:), allocatable :: at, units
    logical :: found

    at = at_text(f, name)
    per_air = .false.
    call check_layout(f, varid, name, allow_profile, error, profile)
    if (allocated(error)) return
    call nc_check(nf90_inquire_variable(f%ncid, varid, xtype=xtype, ndims=ndims), at, error)
    if (allocated(error)) return
    call real_var_attrs(f, varid, name, xtype, quantity, factor, per_air, fill, has_missing, &
                        missing, error)
    if (allocated(error)) return

    ! Read and check in double precision one layer at a time, keep the field in the voxel
    ! precision: a large field never exists in double precision.
    if (profile) then
      allocate (slab(1, 1, f%n(3)), values(1, 1, f%n(3)))
      if (ndims == 2) then
        call nc_check(nf90_get_var(f%ncid, varid, slab, start=[1, f%itime], &
                                   count=[f%n(3), 1]), at, error)
      else
        call nc_check(nf90_get_var(f%ncid, varid, slab, start=[1], count=[f%n(3)]), at, error)
      end if
      if (allocated(error)) return
      call check_values(f, at, slab, 0, fill, has_missing, missing, positive, error)
      if (allocated(error)) return
      values = real(slab*factor, vp)
    else
      allocate (slab(f%n(1), f%n(2), 1), values(f%n(1), f%n(2), f%n(3)))
      do iz = 1, f%n(3)
        call get_layer(f, varid, iz, slab, at, error)
        if (allocated(error)) return
        call check_values(f, at, slab, iz - 1, fill, has_missing, missing, positive, error)
        if (allocated(error)) return
        values(:, :, iz) = real(slab(:, :, 1)*factor, vp)
      end do
    end if

    call get_text_att(f, varid, name, 'units', units, found, error)
    if (allocated(error)) return
    notes = notes//'"'//name//'" ['//units//']'
    if (profile) notes = notes//' profile'
    if (f%tdim >= 0) notes = notes//', '//trim(f%tname)//' '//str(f%itime)//' of '//str(f%nt)
    notes = notes//NL
  end subroutine read_field

  !> The pressure variable (required) as a layer profile in field%pressure_profile(1:nz) [Pa],
  !> in double precision. A profile variable is read as it is; a 3-D variable is read one layer
  !> at a time and each layer replaced by its arithmetic mean over the columns, so the largest
  !> array held is one layer. Every value is checked as in `read_field` (finite, not missing,
  !> > 0).
  subroutine read_pressure_profile(f, names, field, error)
    type(les_file_t), intent(in) :: f
    type(les_names_t), intent(in) :: names
    type(les_field_t), intent(inout) :: field
    type(error_t), allocatable, intent(out) :: error
    type(layer_var_t) :: v
    integer :: p_id, iz
    real(wp), allocatable :: slab(:, :, :)
    character(len=:), allocatable :: p_name

    call find_var(f, 'pressure', names%pressure, DEFAULT_PRESSURE, .true., p_id, p_name, error)
    if (allocated(error)) return
    call open_layer_var(f, p_id, p_name, QTY_PRESSURE, .true., v, error)
    if (allocated(error)) return
    allocate (field%pressure_profile(f%n(3)))
    do iz = 1, f%n(3)
      call layer_values(f, v, iz, slab, error)
      if (allocated(error)) return
      field%pressure_profile(iz) = sum(slab)/real(size(slab), wp)
    end do
    field%pressure_averaged = .not. v%profile
    field%notes = field%notes//'"'//p_name//'" ['//v%units//']'
    if (v%profile) then
      field%notes = field%notes//' profile'
    else
      field%notes = field%notes//' 3-D, averaged over the columns of each layer'
    end if
    if (f%tdim >= 0) field%notes = field%notes//', '//trim(f%tname)//' '//str(f%itime)// &
                                   ' of '//str(f%nt)
    field%notes = field%notes//NL
    field%used%pressure = p_name
  end subroutine read_pressure_profile

  !> The gas state of the layers for broadband runs (`state_profile`): the mean over the columns
  !> of each layer of the temperature, or of theta (p/p0)^kappa from a potential temperature
  !> and the pressure; of the pressure (unless `read_pressure_profile` read it); and of the
  !> water vapour's volume mixing ratio relative to dry air, r M_d/M_w with the mass mixing
  !> ratio r, or q/(1 - q) from a specific humidity q. Each variable may be a profile over z or
  !> 3-D and is read one layer at a time. What the file lacks stays unallocated and `notes`
  !> says what was tried.
  subroutine read_state_profile(f, names, field, error)
    type(les_file_t), intent(in) :: f
    type(les_names_t), intent(in) :: names
    type(les_field_t), intent(inout) :: field
    type(error_t), allocatable, intent(out) :: error
    type(layer_var_t) :: vt, vp_, vq
    integer :: t_id, p_id, q_id, iz, nz
    character(len=:), allocatable :: t_name, p_name, q_name, sname
    real(wp), allocatable :: t(:, :, :), p(:, :, :), q(:, :, :), tt(:, :, :)
    integer :: ix, iy
    logical :: theta, specific, found

    nz = f%n(3)
    theta = .false.
    call find_var(f, 'temperature', names%temperature, DEFAULT_TEMPERATURE, .false., t_id, &
                  t_name, error)
    if (allocated(error)) return
    if (t_id < 0) then
      call find_var(f, 'potential temperature', names%potential_temperature, &
                    DEFAULT_POTENTIAL_TEMPERATURE, .false., t_id, t_name, error)
      if (allocated(error)) return
      theta = t_id >= 0
    end if
    call find_var(f, 'pressure', names%pressure, DEFAULT_PRESSURE, .false., p_id, p_name, error)
    if (allocated(error)) return
    call find_var(f, 'water vapour', names%vapour, DEFAULT_VAPOUR, .false., q_id, q_name, error)
    if (allocated(error)) return
    if (theta .and. p_id < 0) then
      field%notes = field%notes//'potential temperature "'//t_name//'" not used: no pressure '// &
                    'to convert it (tried '//tried(names%pressure, DEFAULT_PRESSURE)//')'//NL
      t_id = -1
    end if
    if (t_id >= 0) call open_layer_var(f, t_id, t_name, QTY_TEMPERATURE, .true., vt, error)
    if (allocated(error)) return
    if (p_id >= 0) call open_layer_var(f, p_id, p_name, QTY_PRESSURE, .true., vp_, error)
    if (allocated(error)) return
    specific = .false.
    if (q_id >= 0) then
      call open_layer_var(f, q_id, q_name, QTY_HUMIDITY, .false., vq, error)
      if (allocated(error)) return
      call get_text_att(f, q_id, q_name, 'standard_name', sname, found, error)
      if (allocated(error)) return
      if (found) then
        specific = trim(sname) == 'specific_humidity'
      else
        specific = q_name == 'hus' .or. q_name == 'specific_humidity'
      end if
    end if

    if (t_id >= 0) allocate (field%t_profile(nz))
    if (q_id >= 0) allocate (field%h2o_profile(nz))
    if (p_id >= 0 .and. .not. allocated(field%pressure_profile)) then
      allocate (field%pressure_profile(nz))
      field%pressure_averaged = .not. vp_%profile
    end if
    do iz = 1, nz
      if (p_id >= 0) then
        call layer_values(f, vp_, iz, p, error)
        if (allocated(error)) return
        field%pressure_profile(iz) = sum(p)/real(size(p), wp)
      end if
      if (t_id >= 0) then
        call layer_values(f, vt, iz, t, error)
        if (allocated(error)) return
        if (theta) then
          ! T = theta (p/p0)^kappa voxel by voxel; either may be a profile
          allocate (tt(max(size(t, 1), size(p, 1)), max(size(t, 2), size(p, 2)), 1))
          do iy = 1, size(tt, 2)
            do ix = 1, size(tt, 1)
              tt(ix, iy, 1) = t(min(ix, size(t, 1)), min(iy, size(t, 2)), 1)* &
                              (p(min(ix, size(p, 1)), min(iy, size(p, 2)), 1)/P_REFERENCE)**KAPPA_DRY_AIR
            end do
          end do
          call move_alloc(tt, t)
        end if
        field%t_profile(iz) = sum(t)/real(size(t), wp)
      end if
      if (q_id >= 0) then
        call layer_values(f, vq, iz, q, error)
        if (allocated(error)) return
        if (specific) then
          if (any(q >= 1.0_wp)) then
            call set_error(error, at_text(f, q_name)//': a specific humidity of '// &
                           str(maxval(q))//' kg/kg in layer '//str(iz)//' is not below 1')
            return
          end if
          q = q/(1.0_wp - q)
        end if
        field%h2o_profile(iz) = (M_DRY_AIR/M_WATER)*sum(q)/real(size(q), wp)
      end if
    end do

    if (t_id >= 0) then
      if (theta) then
        field%notes = field%notes//'gas state: temperature theta (p/p0)^kappa from "'//t_name// &
                      '" and "'//p_name//'" (p0 = 1000 hPa, kappa = 2/7), '//vt%units
      else
        field%notes = field%notes//'gas state: temperature "'//t_name//'" ['//vt%units//']'
      end if
      field%notes = field%notes//', mean over the columns of each layer'//NL
      field%used%temperature = t_name
    else
      field%notes = field%notes//'gas state: no temperature (tried '// &
                    tried(names%temperature, DEFAULT_TEMPERATURE)//' and the potential '// &
                    'temperatures '//tried(names%potential_temperature, &
                                           DEFAULT_POTENTIAL_TEMPERATURE)//')'//NL
    end if
    if (p_id >= 0) then
      if (len_trim(field%used%pressure) == 0) field%notes = field%notes//'gas state: pressure "'// &
          p_name//'" ['//vp_%units//'], mean over the columns of each layer'//NL
      field%used%pressure = p_name
    else
      field%notes = field%notes//'gas state: no pressure (tried '// &
                    tried(names%pressure, DEFAULT_PRESSURE)//')'//NL
    end if
    if (q_id >= 0) then
      field%notes = field%notes//'gas state: water vapour "'//q_name//'" ['//vq%units//'], '
      if (specific) then
        field%notes = field%notes//'a specific humidity q (standard_name or name): '// &
                      'vmr = q/(1 - q) M_d/M_w'
      else
        field%notes = field%notes//'taken as a mass mixing ratio r (vmr = r M_d/M_w; '// &
                      'give it standard_name = "specific_humidity" if it is one, which would '// &
                      'raise the vmr by 1/(1 - q))'
      end if
      field%notes = field%notes//', M_d/M_w = '//str(M_DRY_AIR/M_WATER)// &
                    ', mean over the columns of each layer'//NL
      field%used%vapour = q_name
    else
      field%notes = field%notes//'gas state: no water vapour (tried '// &
                    tried(names%vapour, DEFAULT_VAPOUR)//')'//NL
    end if
  end subroutine read_state_profile

  !> Open a variable for reading one layer at a time: layout (3-D or profile), unit factor,
  !> fill and missing values.
  subroutine open_layer_var(f, varid, name, quantity, positive, v, error)
    type(les_file_t), intent(in) :: f
    integer, intent(in) :: varid, quantity
    character(len=*), intent(in) :: name
    logical, intent(in) :: positive
    type(layer_var_t), intent(out) :: v
    type(error_t), allocatable, intent(out) :: error
    integer :: xtype
    logical :: per_air, found
    v%id = varid
    v%name = name
    v%positive = positive
    v%at = at_text(f, name)
    call check_layout(f, varid, name, .true., error, v%profile)
    if (allocated(error)) return
    call nc_check(nf90_inquire_variable(f%ncid, varid, xtype=xtype, ndims=v%ndims), v%at, error)
    if (allocated(error)) return
    call real_var_attrs(f, varid, name, xtype, quantity, v%factor, per_air, v%fill, &
                        v%has_missing, v%missing, error)
    if (allocated(error)) return
    call get_text_att(f, varid, name, 'units', v%units, found, error)
  end subroutine open_layer_var

  !> Layer iz of a variable opened by open_layer_var, checked and in kumo's unit: shape
  !> (nx, ny, 1), or (1, 1, 1) for a profile.
  subroutine layer_values(f, v, iz, slab, error)
    type(les_file_t), intent(in) :: f
    type(layer_var_t), intent(in) :: v
    integer, intent(in) :: iz
    real(wp), allocatable, intent(inout) :: slab(:, :, :)
    type(error_t), allocatable, intent(out) :: error
    if (allocated(slab)) deallocate (slab)
    if (v%profile) then
      allocate (slab(1, 1, 1))
      if (v%ndims == 2) then
        call nc_check(nf90_get_var(f%ncid, v%id, slab, start=[iz, f%itime], count=[1, 1]), &
                      v%at, error)
      else
        call nc_check(nf90_get_var(f%ncid, v%id, slab, start=[iz], count=[1]), v%at, error)
      end if
    else
      allocate (slab(f%n(1), f%n(2), 1))
      call get_layer(f, v%id, iz, slab, v%at, error)
    end if
    if (allocated(error)) return
    call check_values(f, v%at, slab, iz - 1, v%fill, v%has_missing, v%missing, v%positive, error)
    if (allocated(error)) return
    slab = v%factor*slab
  end subroutine layer_values

  !> Layer iz of a 3-D variable (of the chosen time step, if it has a time dimension).
  subroutine get_layer(f, varid, iz, slab, at, error)
    type(les_file_t), intent(in) :: f
    integer, intent(in) :: varid, iz
    real(wp), intent(out) :: slab(:, :, :)
    character(len=*), intent(in) :: at
    type(error_t), allocatable, intent(out) :: error
    if (f%tdim >= 0) then
      call nc_check(nf90_get_var(f%ncid, varid, slab, start=[1, 1, iz, f%itime], &
                                 count=[f%n(1), f%n(2), 1, 1]), at, error)
    else
      call nc_check(nf90_get_var(f%ncid, varid, slab, start=[1, 1, iz], &
                                 count=[f%n(1), f%n(2), 1]), at, error)
    end if
  end subroutine get_layer

  !> Type, packing, units (factor to kumo's unit), fill and missing values of a real variable.
  subroutine real_var_attrs(f, varid, name, xtype, quantity, factor, per_air, fill, has_missing, &
                            missing, error)
    type(les_file_t), intent(in) :: f
    integer, intent(in) :: varid
    character(len=*), intent(in) :: name
    integer, intent(in) :: xtype, quantity
    real(wp), intent(out) :: factor, fill, missing
    logical, intent(out) :: per_air, has_missing
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: at, units
    logical :: found

    at = at_text(f, name)
    factor = 1.0_wp
    per_air = .false.
    fill = 0.0_wp
    missing = 0.0_wp
    has_missing = .false.
    if (xtype /= NF90_DOUBLE .and. xtype /= NF90_FLOAT) then
      call set_error(error, at//': variable type must be double or float')
      return
    end if
    ! nf90_get_var does not unpack, so scale_factor/add_offset would give wrong numbers silently.
    if (nf90_inquire_attribute(f%ncid, varid, 'scale_factor') == NF90_NOERR .or. &
        nf90_inquire_attribute(f%ncid, varid, 'add_offset') == NF90_NOERR) then
      call set_error(error, at//': packed variables (scale_factor/add_offset) are not '// &
                     'supported; store the unpacked values')
      return
    end if
    call get_text_att(f, varid, name, 'units', units, found, error)
    if (allocated(error)) return
    if (.not. found) then
      call unit_factor('', quantity, factor, per_air, error)
      units = error%message(index(error%message, 'accepted'):)
      error%message = at//': units attribute missing; '//units
      return
    end if
    call unit_factor(units, quantity, factor, per_air, error)
    if (allocated(error)) then
      error%message = at//': '//error%message
      return
    end if
    if (nf90_inquire_attribute(f%ncid, varid, '_FillValue') == NF90_NOERR) then
      call nc_check(nf90_get_att(f%ncid, varid, '_FillValue', fill), at//'/_FillValue', error)
      if (allocated(error)) return
    else if (xtype == NF90_DOUBLE) then
      fill = real(NF90_FILL_DOUBLE, wp)
    else
      fill = real(NF90_FILL_FLOAT, wp)
    end if
    if (nf90_inquire_attribute(f%ncid, varid, 'missing_value') == NF90_NOERR) then
      call nc_check(nf90_get_att(f%ncid, varid, 'missing_value', missing), &
                    at//'/missing_value', error)
      if (allocated(error)) return
      has_missing = .true.
    end if
  end subroutine real_var_attrs

  !> Finite, not the fill or missing value, >= 0 (> 0 if `positive`); the error names the index.
  subroutine check_values(f, at, values, k0, fill, has_missing, missing, positive, error)
    type(les_file_t), intent(in) :: f
    character(len=*), intent(in) :: at
    real(wp), intent(in) :: values(:, :, :)
    integer, intent(in) :: k0                 !! layers of the field before values(:, :, 1)
    real(wp), intent(in) :: fill, missing
    logical, intent(in) :: has_missing, positive
    type(error_t), allocatable, intent(out) :: error
    integer :: ix, iy, iz
    real(wp) :: v
    character(len=:), allocatable :: problem, place

    do iz = 1, size(values, 3)
      do iy = 1, size(values, 2)
        do ix = 1, size(values, 1)
          v = values(ix, iy, iz)
          if (ieee_is_finite(v)) then       ! tested first: no ordered comparison with NaN
            if (.not. (same(v, fill) .or. (has_missing .and. same(v, missing)))) then
              if (v > 0.0_wp) cycle
              if (v >= 0.0_wp .and. .not. positive) cycle
            end if
          end if
          if (.not. ieee_is_finite(v)) then
            problem = 'is not finite'
          else if (same(v, fill)) then
            problem = 'is the fill value (missing data)'
          else if (has_missing .and. same(v, missing)) then
            problem = 'is the missing_value (missing data)'
          else if (positive) then
            problem = 'must be > 0'
          else
            problem = 'must be >= 0'
          end if
          if (size(values, 1) == 1 .and. size(values, 2) == 1 .and. &
              (f%n(1) /= 1 .or. f%n(2) /= 1)) then
            place = ' at (z) = ('//str(k0 + iz)//')'
          else
            place = ' at (x,y,z) = ('//str(ix)//','//str(iy)//','//str(k0 + iz)//')'
          end if
          if (f%tdim >= 0) place = place//', time step '//str(f%itime)
          call set_error(error, at//': value '//str(v)//place//' '//problem)
          return
        end do
      end do
    end do
  end subroutine check_values

  !> values(i, j, k) *= rho(i or 1, j or 1, k) for a 3-D or profile density.
  subroutine scale_by(values, rho)
    real(vp), intent(inout) :: values(:, :, :)
    real(vp), intent(in) :: rho(:, :, :)
    integer :: ix, iy, iz
    do iz = 1, size(values, 3)
      do iy = 1, size(values, 2)
        do ix = 1, size(values, 1)
          values(ix, iy, iz) = real(real(values(ix, iy, iz), wp)* &
                                    rho(min(ix, size(rho, 1)), min(iy, size(rho, 2)), iz), vp)
        end do
      end do
    end do
  end subroutine scale_by

  !> values *= p / (R_d T), the ideal-gas density of dry air [kg m-3]; p and T 3-D or profiles.
  subroutine scale_by_ideal_gas(values, p, t)
    real(vp), intent(inout) :: values(:, :, :)
    real(vp), intent(in) :: p(:, :, :), t(:, :, :)
    real(wp) :: rho
    integer :: ix, iy, iz
    do iz = 1, size(values, 3)
      do iy = 1, size(values, 2)
        do ix = 1, size(values, 1)
          rho = real(p(min(ix, size(p, 1)), min(iy, size(p, 2)), iz), wp)/ &
                (R_DRY_AIR*t(min(ix, size(t, 1)), min(iy, size(t, 2)), iz))
          values(ix, iy, iz) = real(values(ix, iy, iz)*rho, vp)
        end do
      end do
    end do
  end subroutine scale_by_ideal_gas

  !> On entry `reff` holds the droplet number [m-3]; on exit the effective radius [um]
  !> r_e = (3 LWC / (4 pi rho_w k N))^(1/3) (Martin et al. 1994), 0 where LWC = 0.
  subroutine reff_from_number(f, lwc_name, num_name, k, lwc, reff, error)
    type(les_file_t), intent(in) :: f
    character(len=*), intent(in) :: lwc_name, num_name
    real(wp), intent(in) :: k
    real(vp), intent(in) :: lwc(:, :, :)
    real(vp), intent(inout) :: reff(:, :, :)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: M_TO_UM = 1.0e6_wp
    real(wp) :: c
    integer :: ix, iy, iz

    c = 3.0_wp/(4.0_wp*PI*RHO_LIQUID_WATER*k)
    do iz = 1, size(lwc, 3)
      do iy = 1, size(lwc, 2)
        do ix = 1, size(lwc, 1)
          if (lwc(ix, iy, iz) > 0.0_wp) then
            if (reff(ix, iy, iz) > 0.0_wp) then
              reff(ix, iy, iz) = real(M_TO_UM*(c*real(lwc(ix, iy, iz), wp)/ &
                                               reff(ix, iy, iz))**(1.0_wp/3.0_wp), vp)
            else
              call set_error(error, at_text(f, num_name)//': droplet number is 0 at (x,y,z) = ('// &
                             str(ix)//','//str(iy)//','//str(iz)//') where "'//lwc_name// &
                             '" = '//str(real(lwc(ix, iy, iz), wp))//' g m-3 > 0: '// &
                             'no effective radius')
              return
            end if
          else
            reff(ix, iy, iz) = 0.0_vp
          end if
        end do
      end do
    end do
  end subroutine reff_from_number

  ! ------------------------------------------------------------------------------------------------
  ! Names
  ! ------------------------------------------------------------------------------------------------

  !> Find a variable: the given name (must exist), 'none' (not read), or the first default present.
  !> `varid` is -1 when an optional variable is not found; a required one is an error that lists
  !> the names tried.
  subroutine find_var(f, what, given, defaults, required, varid, name, error)
    type(les_file_t), intent(in) :: f
    character(len=*), intent(in) :: what, given
    character(len=*), intent(in) :: defaults(:)
    logical, intent(in) :: required
    integer, intent(out) :: varid
    character(len=:), allocatable, intent(out) :: name
    type(error_t), allocatable, intent(out) :: error
    integer :: i

    varid = -1
    name = ''
    if (trim(given) == LES_NONE) then
      if (required) call set_error(error, PROC//'('//f%path//'): '//what//' is required; '// &
                                   'its name cannot be "none"')
      return
    end if
    if (len_trim(given) > 0) then
      if (nf90_inq_varid(f%ncid, trim(given), varid) /= NF90_NOERR) then
        varid = -1
        call set_error(error, PROC//'('//f%path//'): '//what//' variable "'//trim(given)// &
                       '" not found in the file')
        return
      end if
      name = trim(given)
      return
    end if
    do i = 1, size(defaults)
      if (nf90_inq_varid(f%ncid, trim(defaults(i)), varid) == NF90_NOERR) then
        name = trim(defaults(i))
        return
      end if
    end do
    varid = -1
    if (required) then
      call set_error(error, PROC//'('//f%path//'): no '//what//' variable; tried '// &
                     join(defaults)//'; name it explicitly')
    end if
  end subroutine find_var

  !> The names that were tried: the given one, or the defaults.
  pure function tried(given, defaults) result(text)
    character(len=*), intent(in) :: given
    character(len=*), intent(in) :: defaults(:)
    character(len=:), allocatable :: text
    if (len_trim(given) > 0) then
      text = trim(given)
    else
      text = join(defaults)
    end if
  end function tried

  function per_air_list(lwc, num, iwc, lwc_name, num_name, iwc_name) result(text)
    logical, intent(in) :: lwc, num, iwc
    character(len=*), intent(in) :: lwc_name, num_name, iwc_name
    character(len=:), allocatable :: text
    text = ''
    if (lwc) text = '"'//trim(lwc_name)//'"'
    if (num) then
      if (len(text) > 0) text = text//' and '
      text = text//'"'//trim(num_name)//'"'
    end if
    if (iwc) then
      if (len(text) > 0) text = text//' and '
      text = text//'"'//trim(iwc_name)//'"'
    end if
    if (count([lwc, num, iwc]) > 1) then
      text = text//' are given per mass of air and need'
    else
      text = text//' is given per mass of air and needs'
    end if
  end function per_air_list

  function missing_pt(has_p, has_t, names) result(text)
    logical, intent(in) :: has_p, has_t
    type(les_names_t), intent(in) :: names
    character(len=:), allocatable :: text
    text = ''
    if (.not. has_p) text = text//', no pressure (tried '// &
                            tried(names%pressure, DEFAULT_PRESSURE)//')'
    if (.not. has_t) text = text//', no temperature (tried '// &
                            tried(names%temperature, DEFAULT_TEMPERATURE)//')'
  end function missing_pt

  ! ------------------------------------------------------------------------------------------------
  ! Helpers
  ! ------------------------------------------------------------------------------------------------

  subroutine clear_field(field)
    type(les_field_t), intent(inout) :: field
    if (allocated(field%z_edges)) deallocate (field%z_edges)
    if (allocated(field%lwc)) deallocate (field%lwc)
    if (allocated(field%reff)) deallocate (field%reff)
    if (allocated(field%iwc)) deallocate (field%iwc)
    if (allocated(field%reff_ice)) deallocate (field%reff_ice)
    if (allocated(field%temperature)) deallocate (field%temperature)
    if (allocated(field%pressure)) deallocate (field%pressure)
    field%has_ice = .false.
    field%has_temperature = .false.
    field%temperature_from_theta = .false.
    field%has_pressure = .false.
    if (allocated(field%pressure_profile)) deallocate (field%pressure_profile)
    if (allocated(field%t_profile)) deallocate (field%t_profile)
    if (allocated(field%h2o_profile)) deallocate (field%h2o_profile)
    field%pressure_averaged = .false.
    field%reff_computed = .false.
  end subroutine clear_field

  !> Exact equality (for fill values), spelt without == to keep -Wcompare-reals quiet.
  pure logical function same(x, y)
    real(wp), intent(in) :: x, y
    same = x >= y .and. x <= y
  end function same

  !> "read_les_field(file:name)"
  pure function at_text(f, name) result(at)
    type(les_file_t), intent(in) :: f
    character(len=*), intent(in) :: name
    character(len=:), allocatable :: at
    at = PROC//'('//f%path//':'//trim(name)//')'
  end function at_text

  subroutine nc_check(status, at, error)
    integer, intent(in) :: status
    character(len=*), intent(in) :: at
    type(error_t), allocatable, intent(out) :: error
    if (status == NF90_NOERR) return
    call set_error(error, at//': '//trim(nf90_strerror(status)))
  end subroutine nc_check

  !> A text attribute; `found` is false if it is absent.
  subroutine get_text_att(f, varid, name, att, value, found, error)
    type(les_file_t), intent(in) :: f
    integer, intent(in) :: varid
    character(len=*), intent(in) :: name, att
    character(len=:), allocatable, intent(out) :: value
    logical, intent(out) :: found
    type(error_t), allocatable, intent(out) :: error
    integer :: status, xtype, length
    character(len=:), allocatable :: at

    found = .false.
    value = ''
    at = at_text(f, trim(name)//'/'//att)
    status = nf90_inquire_attribute(f%ncid, varid, att, xtype=xtype, len=length)
    if (status == NF90_ENOTATT) return
    call nc_check(status, at, error)
    if (allocated(error)) return
    if (xtype /= NF90_CHAR) then
      call set_error(error, at//': attribute is not text')
      return
    end if
    found = .true.
    deallocate (value)
    allocate (character(len=length) :: value)
    if (length > 0) then
      call nc_check(nf90_get_att(f%ncid, varid, att, value), at, error)
      if (allocated(error)) return
    end if
    do while (len(value) > 0)
      if (value(len(value):len(value)) /= achar(0)) exit
      value = value(1:len(value) - 1)
    end do
  end subroutine get_text_att
end module kumo_les_netcdf
