! SPDX-License-Identifier: BSD-3-Clause
!> The configuration's types, limits and the helpers its namelist groups share (reading a
!> group and explaining a failed read, validation rules, level lists, the grid of a cloud
!> file from the caller's reader). kumo_config, the module programs use, exports the types;
!> the groups are read by one module each (kumo_config_<group>).
module kumo_config_base
  use, intrinsic :: iso_fortran_env, only: iostat_end
  use kumo_kinds, only: wp, i8
  use kumo_error, only: error_t, set_error, str
  use kumo_math, only: within
  use kumo_brdf, only: brdf_params_t, BRDF_NPAR
  use kumo_cloud_input, only: cloud_input_t, cloud_request_t
  use kumo_nml_text, only: nml_diagnose, nml_probe_i, nml_find_nan, nml_find_long_string
  use kumo_textio, only: read_line
  implicit none
  private
  public :: MAX_LAYERS, MAX_COMP, MAX_PHASE, MAX_DIR, MAX_CAMERAS, PATH_LEN, KM_HINT, &
            MAX_TOTAL_PHOTONS, RR_RATIO_MAX, UNSET, BIG, SMALL, IUNSET, TSI_KOPP_LEAN, &
            RAYLEIGH_LEVELS, RAYLEIGH_CLOUD_FILE, input_file_t, control_cfg_t, atmosphere_cfg_t, &
            cloud_cfg_t, phase_cfg_t, surface_cfg_t, source_cfg_t, output_cfg_t, vr_cfg_t, &
            radiance_cfg_t, camera_cfg_t, thermal_cfg_t, spectral_cfg_t, config_t, &
            cloud_grid_reader, unit_text, check_read, grid_of, resolve_path, require, level_list, &
            given

  integer, parameter :: MAX_LAYERS = 2000   !! most layers a namelist can describe
  integer, parameter :: MAX_COMP = 8        !! most components per layer
  integer, parameter :: MAX_PHASE = 64      !! most phase functions
  integer, parameter :: MAX_DIR = 64        !! most radiance directions
  integer, parameter :: MAX_CAMERAS = 8     !! most cameras
  integer, parameter :: PATH_LEN = 4096  !! longest path a namelist can give
  !> A Rayleigh atmosphere whose top is lower than this [m] was given in kilometres.
  real(wp), parameter :: KM_HINT = 100.0_wp
  !> Photon totals beyond 2^53 lose exactness in the double-precision tallies.
  integer(i8), parameter :: MAX_TOTAL_PHOTONS = 2_i8**53
  !> Largest rr_weight/rr_threshold: beyond it the roulette kills nearly every photon.
  real(wp), parameter :: RR_RATIO_MAX = 1000.0_wp
  real(wp), parameter :: UNSET = -huge(1.0_wp)
  real(wp), parameter :: BIG = huge(1.0_wp)      !! largest finite value
  real(wp), parameter :: SMALL = tiny(1.0_wp)    !! smallest positive value
  integer, parameter :: IUNSET = -huge(1)
  !> Total solar irradiance of broadband runs by default [W m-2]: 1360.8 +- 0.5 W m-2 at the
  !> 2008 solar minimum (Kopp and Lean 2011, Geophys. Res. Lett. 38, L01706,
  !> doi:10.1029/2010GL045777).
  real(wp), parameter :: TSI_KOPP_LEAN = 1360.8_wp
  !> Pressure profiles of the Rayleigh layers besides the named standard atmospheres: the
  !> namelist's sounding (pressure_levels_hpa) and the pressure of the &kumo_cloud LES file.
  character(len=*), parameter :: RAYLEIGH_LEVELS = 'levels'
  character(len=*), parameter :: RAYLEIGH_CLOUD_FILE = 'cloud_file'

  !> How read_config learns the grid of a cloud file: `grid` gets the file's columns, widths and
  !> layer edges (nx, ny, nz, dx, dy, z) and the kind of content, plus the layer pressures
  !> (`pressure`, `pressure_source`) when `req%pressure_profile` is set; no field data. Every
  !> rank that parses the namelist calls it at the same points with the same request.
  abstract interface
    subroutine cloud_grid_reader(req, grid, error)
      import :: cloud_request_t, cloud_input_t, error_t
      implicit none
      type(cloud_request_t), intent(in) :: req
      type(cloud_input_t), intent(out) :: grid
      type(error_t), allocatable, intent(out) :: error
    end subroutine cloud_grid_reader
  end interface

  !> An input file a configuration names, and the namelist entry that names it.
  type :: input_file_t
    character(len=:), allocatable :: label   !! e.g. '&kumo_atmosphere scene_file'
    character(len=:), allocatable :: path    !! as kumo opens it (relative to the namelist)
  end type input_file_t

  !> &kumo_control: photon budget, seeding and stopping rule.
  type :: control_cfg_t
    integer(i8) :: n_photons_per_batch = 100000_i8 !! photons traced per batch
    integer :: n_batches = 20                      !! batches (>= 2 for a standard error)
    integer(i8) :: seed = 1_i8                     !! global seed; stream = batch index
    real(wp) :: target_rel_error = 0.0_wp          !! > 0: add rounds of n_batches until reached
    character(len=16) :: target_output = 'reflectance' !! one of TARGET_NAMES
    integer(i8) :: max_photons = 1000000000_i8     !! photon cap of the target-error mode
    integer(i8) :: max_events = 100000000_i8       !! collisions + reflections per photon
    integer :: verbose = 1                         !! 0 quiet, 1 summary, 2 per round
    character(len=8) :: mode_3d = 'f3d'            !! one of MODE_NAMES: f3d, ica, p3d
    integer :: p3d_orders = 1                      !! p3d: scatterings placed by 3-D transport
    real(wp) :: checkpoint_interval = 0.0_wp       !! [s] between checkpoints; 0 = none
    !> several ranks: the ranks of a node share one copy of the scene (.false.: a copy each)
    logical :: one_scene_per_node = .true.
  end type control_cfg_t

  !> &kumo_atmosphere: levels, 1-D layers and the 3-D region.
  type :: atmosphere_cfg_t
    integer :: nz = 0                              !! number of layers
    real(wp), allocatable :: z(:)                  !! levels 0..nz stored as z(1:nz+1) [m]
    real(wp) :: lx = 1000.0_wp, ly = 1000.0_wp     !! periodic domain size [m]
    integer :: n_components = 1                    !! components of the 1-D layers
    real(wp), allocatable :: ext1d(:, :)           !! (nz, n_components) extinction [m-1]
    real(wp), allocatable :: ssa1d(:, :)           !! single-scattering albedo
    integer, allocatable :: phase1d(:, :)          !! phase-function index
    character(len=PATH_LEN) :: scene_file = ''     !! netCDF file of the 3-D region
    integer :: k3d_bottom = 0                      !! lowest layer of the 3-D region (0 = none)
    integer :: nx = 1, ny = 1, nz3 = 0             !! 3-D region size (checked against the file)
    integer :: n_components_3d = 1                 !! components in the scene file
    integer, allocatable :: phase3d(:)             !! phase index per 3-D component
    real(wp), allocatable :: air_density(:)        !! (nz) [kg m-3], for heating rates in K/day
    real(wp) :: cp_air = 1004.64_wp                !! specific heat [J kg-1 K-1]
    logical :: levels_from_cloud = .false.         !! levels taken from the &kumo_cloud file
    ! Molecular (Rayleigh) scattering added to every layer as one more component
    logical :: rayleigh = .false.                  !! add Rayleigh scattering of dry air
    !> pressure profile: a standard atmosphere (STD_ATMOSPHERE_NAMES), RAYLEIGH_LEVELS or
    !> RAYLEIGH_CLOUD_FILE
    character(len=16) :: rayleigh_profile = 'us1976'
    real(wp), allocatable :: p_levels(:)           !! 'levels': pressure at levels 0..nz [Pa]
    !> 'cloud_file': pressure of each layer of the &kumo_cloud file [Pa], bottom first
    real(wp), allocatable :: p_cloud(:)
    character(len=:), allocatable :: p_cloud_source !! 'cloud_file': where p_cloud came from
    real(wp) :: co2_ppm = 400.0_wp                 !! CO2 volume mixing ratio [ppm]
    real(wp) :: latitude_deg = 45.0_wp             !! latitude for gravity [deg]
    real(wp) :: rayleigh_depol = -1.0_wp           !! depolarisation ratio; < 0: Bodhaine value
  end type atmosphere_cfg_t

  !> &kumo_cloud: the 3-D region from a model-output or cloud file, optics computed by kumo.
  type :: cloud_cfg_t
    logical :: enabled = .false.                   !! a cloud file is given
    type(cloud_request_t) :: req                   !! format, resolved path, LES names, ...
    character(len=PATH_LEN) :: file = ''           !! the file as written in the namelist
    character(len=16) :: size_distribution = 'gamma' !! droplet size distribution
    real(wp) :: v_eff = 0.1_wp                     !! effective variance
    real(wp) :: reff_min_um = 1.0_wp               !! smallest table radius [um]
    real(wp) :: reff_max_um = 40.0_wp              !! largest table radius [um]
    integer :: n_reff = 40                         !! table radii (geometric spacing)
    character(len=PATH_LEN) :: mie_cache = ''      !! netCDF Mie-table cache ('' = none)
    character(len=PATH_LEN) :: ice_optics_file = '' !! ice optics table (Mie-table layout)
    !> MCARaTS phase-function file as written in the namelist (resolved: req%mcarats)
    character(len=PATH_LEN) :: mcarats_phase_file = ''
    type(cloud_input_t) :: grid                    !! the file's grid (no field data)
  end type cloud_cfg_t

  !> &kumo_phase: the phase functions, referenced by index from layers and voxels.
  type :: phase_cfg_t
    integer :: n_phase = 1
    integer, allocatable :: kind(:)                !! PHASE_* code
    character(len=16), allocatable :: kind_name(:)
    real(wp), allocatable :: g(:)                  !! HG asymmetry parameter
    character(len=PATH_LEN), allocatable :: file(:)!! table file (angle [deg], value)
    integer :: n_table = 20000                     !! inverse-CDF table size
  end type phase_cfg_t

  !> &kumo_surface: Lambert surface (uniform or a map) or a BRDF (uniform or a map).
  type :: surface_cfg_t
    real(wp) :: albedo = 0.0_wp                    !! uniform albedo
    character(len=PATH_LEN) :: albedo_file = ''    !! netCDF 2-D albedo map (overrides albedo)
    character(len=64) :: albedo_var = 'albedo'     !! variable name in albedo_file
    character(len=8) :: brdf = 'lambert'           !! lambert, dsm, rpv, lsrt or black
    character(len=PATH_LEN) :: brdf_file = ''      !! netCDF 2-D BRDF map
    real(wp) :: brdf_param(BRDF_NPAR) = 0.0_wp     !! BRDF parameters in the MCARaTS order
    real(wp) :: wind_speed = -1.0_wp               !! DSM: sets the slope variance (< 0: unused)
    character(len=PATH_LEN) :: surface_file = ''   !! surface file of another code (kinds, params)
    character(len=16) :: surface_format = 'mcarats' !! its format: 'mcarats' (binary Sfc_inpfile)
    integer :: surface_nxb = 0, surface_nyb = 0    !! its pixels (Sfc_nxb, Sfc_nyb); 0: not given
    integer :: surface_mbrdf(4) = 1                !! models that may appear (Sfc_mbrdf)
    integer :: surface_idread = 1                  !! dataset read (Sfc_idread)
    type(brdf_params_t) :: model                   !! the BRDF after validation
  end type surface_cfg_t

  !> &kumo_source: the solar beam.
  type :: source_cfg_t
    real(wp) :: sza_deg = 0.0_wp                   !! solar zenith angle [deg], 0 <= sza < 90
    real(wp) :: phi0_deg = 0.0_wp                  !! azimuth the beam travels towards [deg]
    real(wp) :: solar_flux = 0.0_wp                !! F0 normal to the beam [W m-2]; 0 = unknown
    real(wp) :: wavelength_um = 0.0_wp             !! vacuum wavelength [um]; 0 = not given
  end type source_cfg_t

  !> &kumo_output: what to write and where.
  type :: output_cfg_t
    character(len=PATH_LEN) :: file = 'kumo_out.nc'!! output netCDF file
    integer, allocatable :: flux_levels(:)         !! levels (0..nz) written; default all
    logical :: column_fluxes = .true.              !! per-column flux maps (3-D scenes)
    integer, allocatable :: map_levels(:)          !! levels (0..nz) of the maps; default flux_levels
    logical :: voxel_absorption = .true.           !! absorption/heating per voxel (3-D scenes)
    integer :: deflate_level = 0                   !! netCDF deflate level of the results (0: off)
  contains
    procedure :: map_level_list
  end type output_cfg_t

  !> &kumo_vr: Russian roulette and the tracer's fast paths.
  type :: vr_cfg_t
    real(wp) :: rr_threshold = 0.25_wp             !! roulette below this weight
    real(wp) :: rr_weight = 0.5_wp                 !! survivors' weight
    logical :: use_supervoxels = .true.            !! .false.: one majorant for the 3-D region
    real(wp) :: sv_fsupg = 2.0_wp                  !! merge rule: optical size factor
    real(wp) :: sv_fsupi = 1.3_wp                  !! merge rule: real/majorant factor
    integer :: sv_max_layers = 50                  !! most layers per super-layer
    logical :: use_1d_layers = .true.              !! analytic 1-D layers (else 3-D tracer)
    logical :: use_absorbing_layers = .true.       !! absorbing layers without collisions
    logical :: stratify_source = .true.            !! stratified entry points per batch
    character(len=16) :: preset = 'unbiased'       !! one of PRESET_NAMES
    real(wp) :: zeta_min = 0.3_wp                  !! local-estimate roulette threshold (BRF)
    real(wp) :: trunc_theta_max_deg = 0.0_wp       !! largest truncation angle (0 = off)
    integer :: trunc_levels = 1                    !! truncation levels (1 = off)
    real(wp) :: trunc_peak = 30.0_wp               !! P >= this is a scattering into the peak
    real(wp) :: cf_tau_min = 1.0_wp                !! collision forcing: least column depth
    real(wp) :: diffusion = 0.0_wp                 !! numerical diffusion of radiance maps
    integer :: diffusion_max = 30                  !! largest spread half-width [columns]
    real(wp) :: ddis_eps = 0.1_wp                  !! detector directional importance sampling
    logical :: use_exact_thermal = .true.          !! non-scattering thermal columns solved exactly
    character(len=16) :: absorption_estimator = 'collision'  !! one of ABS_ESTIMATOR_NAMES (kumo_vr)
    !> similarity-scaled truncation of forward peaks for fluxes and absorption [deg] (0 = off)
    real(wp) :: similarity_theta_deg = 0.0_wp
  end type vr_cfg_t

  !> &kumo_radiance: radiances by local estimation at levels, in chosen directions.
  type :: radiance_cfg_t
    real(wp), allocatable :: mu(:)                 !! cosine of the propagation direction
    real(wp), allocatable :: phi_deg(:)            !! azimuth of the propagation direction [deg]
    integer, allocatable :: levels(:)              !! levels (0..nz) with radiance detectors
    logical :: maps = .true.                       !! per-column radiance maps (3-D scenes)
  end type radiance_cfg_t

  !> &kumo_camera: perspective (pinhole) and orthographic cameras.
  type :: camera_cfg_t
    integer :: n = 0                               !! number of cameras
    character(len=16), allocatable :: kind(:)      !! 'pinhole' or 'orthographic'
    real(wp), allocatable :: pos(:, :)             !! (3, n) position [m]
    real(wp), allocatable :: look_zenith_deg(:)    !! zenith angle of the viewing direction
    real(wp), allocatable :: look_azimuth_deg(:)   !! azimuth of the viewing direction
    real(wp), allocatable :: roll_deg(:)           !! rotation of the image about the view axis
    real(wp), allocatable :: fov_deg(:)            !! pinhole: full field of view along x
    real(wp), allocatable :: width(:)              !! orthographic: image width [m]
    integer, allocatable :: npx(:), npy(:)         !! pixels along the image x and y axes
  end type camera_cfg_t

  !> &kumo_thermal: thermal emission by the atmosphere, the surface and the top.
  type :: thermal_cfg_t
    logical :: enabled = .false.                   !! thermal emission is a source
    real(wp), allocatable :: t_levels(:)           !! (nz + 1) temperature at levels 0..nz [K]
    real(wp) :: t_surface = -1.0_wp                !! surface temperature [K]
    character(len=PATH_LEN) :: t_surface_file = '' !! netCDF 2-D surface temperature map
    character(len=64) :: t_surface_var = 't_surface' !! its variable
    real(wp) :: t_top = 0.0_wp                     !! brightness temperature of the isotropic
                                                   !! downward radiance at the top [K]; 0: none
    real(wp) :: wavenumber_lo = -1.0_wp            !! band [cm-1] (both or neither)
    real(wp) :: wavenumber_hi = -1.0_wp
    real(wp) :: wavelength_um = 0.0_wp             !! single wavelength [um] (0: band or source's)
    real(wp), allocatable :: planck_levels(:)      !! (nz + 1) Planck radiances given directly
    real(wp) :: planck_surface = -1.0_wp           !! (with planck_levels)
    real(wp) :: planck_top = 0.0_wp                !! (with planck_levels)
    logical :: include_sun = .false.               !! the solar beam of &kumo_source too
    real(wp) :: emission_floor = 0.1_wp            !! share of photons spread by capacity
  end type thermal_cfg_t

  !> &kumo_spectral: broadband runs over the g-points of an RRTMGP k-distribution (shortwave
  !> or longwave, as the file is).
  type :: spectral_cfg_t
    logical :: enabled = .false.                   !! the run is broadband
    character(len=PATH_LEN) :: kdist_file = ''     !! k-distribution as written in the namelist
    character(len=:), allocatable :: kdist_path    !! resolved (relative to the namelist)
    character(len=16) :: profile = ''              !! standard atmosphere at z_levels, or ''
    real(wp), allocatable :: p_levels(:)           !! (nz + 1) level pressure [Pa] ('' profile)
    real(wp), allocatable :: t_levels(:)           !! (nz + 1) level temperature [K]
    real(wp), allocatable :: p_layers(:)           !! (nz) layer pressure [Pa] (optional)
    real(wp), allocatable :: t_layers(:)           !! (nz) layer temperature [K] (optional)
    real(wp), allocatable :: h2o_vmr(:)            !! (nz) water vapour [mol/mol of dry air]
    real(wp), allocatable :: o3_vmr(:)             !! (nz) ozone; not allocated: RCEMIP profile
    !> other gases of the k-distribution at a constant volume mixing ratio [mol/mol of dry air],
    !> instead of kumo's present-day defaults (e.g. 'co2' for a CO2 experiment)
    character(len=16), allocatable :: gas_names(:)
    real(wp), allocatable :: gas_vmr(:)
    real(wp) :: tsi = TSI_KOPP_LEAN                !! total solar irradiance [W m-2]
    real(wp) :: floor_share = 0.2_wp               !! share of photons spread evenly over g-points
    real(wp) :: t_surface = -1.0_wp                !! longwave: surface temperature [K] (< 0:
                                                   !! the lowest level's)
    !> cloud files: liquid optics per band, 'mie' (kumo's band-averaged Mie tables with their
    !> phase functions) or 'rrtmgp' (RRTMGP's look-up table, Henyey-Greenstein phase functions)
    character(len=8) :: liquid_optics = 'mie'
    !> RRTMGP cloud-optics file (ice, and liquid with 'rrtmgp'); '' = cloudysky_sw.nc or
    !> cloudysky_lw.nc beside the k-distribution or in the folder of scripts/fetch-rrtmgp.sh
    character(len=PATH_LEN) :: cloud_optics_file = ''
    character(len=:), allocatable :: cloud_optics_path  !! resolved (relative to the namelist)
    character(len=8) :: ice_roughness = 'medium'   !! smooth, medium or rough (RRTMGP ice)
    !> the gas state in the layers of an LES/CRM cloud file: 'cloud_file' (the file's
    !> temperature, pressure and water vapour, column means per layer, where it has them) or
    !> 'profile' (the profile of this group everywhere)
    character(len=16) :: gas_state = 'cloud_file'
    !> 0: every g-point (broadband); g > 0: g-point g alone (its own share of the fluxes and
    !> heating rates, e.g. to compare with a monochromatic code or to time one g-point)
    integer :: gpoint = 0
  end type spectral_cfg_t

  type :: config_t
    character(len=:), allocatable :: path          !! namelist file
    type(control_cfg_t) :: control
    type(atmosphere_cfg_t) :: atm
    type(phase_cfg_t) :: phase
    type(surface_cfg_t) :: surface
    type(source_cfg_t) :: source
    type(output_cfg_t) :: output
    type(vr_cfg_t) :: vr
    type(radiance_cfg_t) :: rad
    type(camera_cfg_t) :: cam
    type(cloud_cfg_t) :: cloud
    type(thermal_cfg_t) :: thermal
    type(spectral_cfg_t) :: spectral
  end type config_t

contains

  !> The levels of the per-column flux maps: `map_levels`, or the flux levels when it is not set
  !> (a configuration built in code may set only those).
  pure function map_level_list(out) result(levels)
    class(output_cfg_t), intent(in) :: out
    integer, allocatable :: levels(:)
    if (allocated(out%map_levels)) then
      levels = out%map_levels
    else
      levels = out%flux_levels
    end if
  end function map_level_list

  !> The whole text of the file open on `unit`, lines joined with line ends.
  function unit_text(unit) result(text)
    integer, intent(in) :: unit
    character(len=:), allocatable :: text, line
    integer :: ios
    text = ''
    rewind (unit)
    do
      call read_line(unit, line, ios)
      if (ios /= 0) exit
      text = text//line//new_line('a')
    end do
    rewind (unit)
  end function unit_text

  !> Turn the iostat of a namelist read into an error (or nothing). A value NaN is refused
  !> wherever it is written (even where another form of the same setting would win). A failed
  !> read is explained
  !> by re-reading the group's assignments one at a time (`probe`): the message names the
  !> group, the line, the variable and what it takes.
  subroutine check_read(unit, group, present, ios, msg, error, probe)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: group, msg
    logical, intent(in) :: present
    integer, intent(in) :: ios
    type(error_t), allocatable, intent(out) :: error
    procedure(nml_probe_i) :: probe
    character(len=:), allocatable :: nan_message
    if (ios == 0) then
      if (present) then
        nan_message = nml_find_nan(group, unit_text(unit))
        if (len(nan_message) == 0) nan_message = nml_find_long_string(group, unit_text(unit), &
                                                                      probe)
        if (len(nan_message) > 0) call set_error(error, nan_message)
      end if
      return
    end if
    if (ios == iostat_end .and. .not. present) return
    if (ios == iostat_end) then
      call set_error(error, 'namelist &'//group//' is malformed: a value could not be read '// &
                     '(check numbers, quotes and the closing /)')
    else
      call set_error(error, nml_diagnose(group, unit_text(unit), probe, msg))
    end if
  end subroutine check_read

  !> The grid of the cloud file `req%path` from the caller's reader (see read_config).
  subroutine grid_of(req, grid, error, read_grid)
    type(cloud_request_t), intent(in) :: req
    type(cloud_input_t), intent(out) :: grid
    type(error_t), allocatable, intent(out) :: error
    procedure(cloud_grid_reader), optional :: read_grid
    if (present(read_grid)) then
      call read_grid(req, grid, error)
    else
      call set_error(error, 'cloud_file '//req%path//': its grid is needed to check the '// &
                     'levels, but read_config was given no reader of cloud-file grids '// &
                     '(load_config of kumo_scene_setup passes one)')
    end if
  end subroutine grid_of

  !> A path from the namelist: relative paths are relative to the namelist's folder.
  function resolve_path(path, nml_path) result(full)
    character(len=*), intent(in) :: path, nml_path
    character(len=:), allocatable :: full
    integer :: i
    full = trim(path)
    if (len(full) == 0) return
    if (full(1:1) == '/') return
    i = index(nml_path, '/', back=.true.)
    if (i > 0) full = nml_path(1:i)//full
  end function resolve_path

  !> One validation rule of a namelist variable. Unless an earlier check has failed (`error`
  !> allocated), `ok` false gives the error "<ctx><name> = <value> <rule>", or
  !> "<ctx><name> <rule>" without a value; a character value is shown in double quotes.
  !> Checks written as a sequence of calls report the first rule broken, as an if/else chain.
  subroutine require(ok, ctx, name, value, rule, error)
    logical, intent(in) :: ok
    character(len=*), intent(in) :: ctx    !! group prefix, e.g. '&kumo_vr: '
    character(len=*), intent(in) :: name   !! the variable, e.g. 'phase_g(2)'
    class(*), intent(in), optional :: value
    character(len=*), intent(in) :: rule   !! e.g. 'must be >= 1'
    type(error_t), allocatable, intent(inout) :: error
    character(len=:), allocatable :: shown
    if (allocated(error) .or. ok) return
    shown = ' '
    if (present(value)) then
      select type (value)
      type is (integer)
        shown = ' = '//str(value)//' '
      type is (integer(i8))
        shown = ' = '//str(value)//' '
      type is (real(wp))
        shown = ' = '//str(value)//' '
      type is (character(len=*))
        shown = ' = "'//trim(value)//'" '
      end select
    end if
    call set_error(error, ctx//name//shown//rule)
  end subroutine require

  !> A list of levels from the namelist (`given`, IUNSET where not set): `default` when no
  !> value is given, else the values given, which must stand without gaps, lie within 0..nz
  !> and increase strictly.
  subroutine level_list(group, name, given, nz, default, levels, error)
    character(len=*), intent(in) :: group, name  !! e.g. 'kumo_output', 'flux_levels'
    integer, intent(in) :: given(:), nz, default(:)
    integer, allocatable, intent(out) :: levels(:)
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: ctx
    integer :: n, i
    ctx = '&'//group//': '
    n = count(given /= IUNSET)
    call require(all(given(n + 1:) == IUNSET), ctx, name, rule='must be a list without gaps', &
                 error=error)
    if (allocated(error)) return
    if (n == 0) then
      levels = default
      return
    end if
    levels = given(1:n)
    do i = 1, n
      call require(levels(i) >= 0 .and. levels(i) <= nz, ctx, name//'('//str(i)//')', &
                   levels(i), 'must be within 0..nz = '//str(nz), error)
      if (i > 1) call require(levels(i) > levels(i - 1), ctx, name, &
                              rule='must increase strictly', error=error)
      if (allocated(error)) return
    end do
  end subroutine level_list

  !> A size of the MCARaTS request as the namelist writes it, or `unset` and "from the .ctl"
  !> when it was not given (the request keeps -1 then).
  pure function given(n, unset) result(s)
    integer, intent(in) :: n, unset
    character(len=:), allocatable :: s
    if (n < 0) then
      s = str(unset)//' (from the .ctl)'
    else
      s = str(n)
    end if
  end function given
end module kumo_config_base
