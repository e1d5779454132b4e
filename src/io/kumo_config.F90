! SPDX-License-Identifier: BSD-3-Clause
!> Namelist configuration: one group per area, parsed and validated into `*_cfg_t` types.
!>
!> Groups: &kumo_control (photon budget, seed, stopping rule, solver mode), &kumo_atmosphere
!> (levels, 1-D layers, 3-D region, Rayleigh layers), &kumo_cloud (model output and other codes'
!> cloud files), &kumo_phase (phase functions), &kumo_surface (Lambert, BRDF, maps),
!> &kumo_source, &kumo_output, &kumo_vr (variance reduction and tracer fast paths),
!> &kumo_radiance, &kumo_camera, &kumo_thermal, &kumo_spectral. Every variable, its default,
!> units and range is listed in namelists/reference.nml. The groups are found by kumo's own
!> scanner (kumo_nml_text), which names unknown, misspelt and repeated groups; namelist
!> variables are local variables copied into the types, so the file syntax does not depend on
!> component names. A run reads the namelist file once, on rank 0, and every rank parses and
!> validates that same text (the `text` argument of read_config), so all ranks fail the same
!> way.
!>
!> This module opens no file but the namelist. The one fact of another file that validation
!> needs, the grid of a &kumo_cloud file (its levels set or check z_levels, lx, ly, nx, ny,
!> nz3) and, for rayleigh_profile = 'cloud_file', its pressure profile, comes from the
!> `read_grid` procedure the caller passes (kumo_scene_setup's `load_config` reads it on rank 0
!> and broadcasts it); the fields of the inputs are read when the scene is built.
module kumo_config
  use, intrinsic :: iso_fortran_env, only: iostat_end
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp, i8
  use kumo_error, only: error_t, set_error, add_context, str, to_lower, join
  use kumo_phase, only: phase_kind_from_name, PHASE_TABLE
  use kumo_math, only: within
  use kumo_brdf, only: brdf_params_t, brdf_params, brdf_kind_from_name, brdf_validate, &
                       cox_munk_slope_variance, BRDF_BLACK, BRDF_LAMBERT, BRDF_DSM, BRDF_NPAR
  use kumo_mie, only: dist_kind_from_name, size_dist_validate
  use kumo_std_atmosphere, only: std_atmosphere_kind_from_name, STD_ATMOSPHERE_NAMES
  use kumo_les_netcdf, only: LES_NAME_LEN
  use kumo_cloud_input, only: cloud_input_t, cloud_request_t, cloud_format_check, CLOUD_OPTICS, &
                              CLOUD_MCARATS
  use kumo_mcarats_files, only: is_ctl_path, mcarats_request_t
  use kumo_nml_text, only: nml_group_t, nml_scan, nml_diagnose, closest_name, nml_probe_i, &
                           nml_find_nan, nml_find_long_string
  use kumo_textio, only: read_line
  use kumo_vr, only: ABS_ESTIMATOR_NAMES, absorption_estimator_code
  implicit none
  private
  public :: config_t, control_cfg_t, atmosphere_cfg_t, phase_cfg_t, surface_cfg_t, &
            source_cfg_t, output_cfg_t, vr_cfg_t, radiance_cfg_t, camera_cfg_t, cloud_cfg_t, &
            thermal_cfg_t, spectral_cfg_t, &
            read_config, config_echo, resolve_path, input_file_t, config_inputs, cloud_grid_reader
  public :: MAX_LAYERS, MAX_COMP, MAX_PHASE, MAX_DIR, MAX_CAMERAS, TARGET_NAMES, PRESET_NAMES, &
            MODE_NAMES
  public :: RAYLEIGH_LEVELS, RAYLEIGH_CLOUD_FILE

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
  character(len=16), parameter :: TARGET_NAMES(3) = &
    [character(len=16) :: 'reflectance', 'transmittance', 'absorptance']
  !> Transport modes: full 3-D, independent columns, 3-D for the first scattering orders.
  character(len=8), parameter :: MODE_NAMES(3) = [character(len=8) :: 'f3d', 'ica', 'p3d']
  character(len=16), parameter :: GROUP_NAMES(12) = &
    [character(len=16) :: 'kumo_control', 'kumo_atmosphere', 'kumo_phase', 'kumo_surface', &
     'kumo_source', 'kumo_output', 'kumo_vr', 'kumo_radiance', 'kumo_camera', 'kumo_cloud', &
     'kumo_thermal', 'kumo_spectral']
  !> Total solar irradiance of broadband runs by default [W m-2]: 1360.8 +- 0.5 W m-2 at the
  !> 2008 solar minimum (Kopp and Lean 2011, Geophys. Res. Lett. 38, L01706,
  !> doi:10.1029/2010GL045777).
  real(wp), parameter :: TSI_KOPP_LEAN = 1360.8_wp
  !> Pressure profiles of the Rayleigh layers besides the named standard atmospheres: the
  !> namelist's sounding (pressure_levels_hpa) and the pressure of the &kumo_cloud LES file.
  character(len=*), parameter :: RAYLEIGH_LEVELS = 'levels'
  character(len=*), parameter :: RAYLEIGH_CLOUD_FILE = 'cloud_file'
  !> Variance-reduction presets, from none to the most aggressive (see read_vr).
  character(len=16), parameter :: PRESET_NAMES(4) = &
    [character(len=16) :: 'analog', 'unbiased', 'standard', 'quick']
  ! Preset values, in the order of PRESET_NAMES (MCARaTS ladder, state-of-the-art C1, B2, B6).
  real(wp), parameter :: PRESET_ZETA(4) = [0.0_wp, 0.3_wp, 0.3_wp, 0.3_wp]
  real(wp), parameter :: PRESET_TRUNC_DEG(4) = [0.0_wp, 0.0_wp, 30.0_wp, 40.0_wp]
  integer, parameter :: PRESET_TRUNC_LEVELS(4) = [1, 1, 4, 3]
  real(wp), parameter :: PRESET_CF_TAU(4) = [0.0_wp, 1.0_wp, 2.0_wp, 3.0_wp]
  real(wp), parameter :: PRESET_DIFF(4) = [0.0_wp, 0.0_wp, 60.0_wp, 150.0_wp]
  real(wp), parameter :: PRESET_DDIS(4) = [0.0_wp, 0.1_wp, 0.1_wp, 0.1_wp]

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
    logical :: voxel_absorption = .true.           !! absorption/heating per voxel (3-D scenes)
    integer :: deflate_level = 0                   !! netCDF deflate level of the results (0: off)
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

  !> Read and validate every group of the namelist file `path`. With `text` (the file's
  !> content, read once on rank 0 and broadcast by kumo_driver, so that every rank parses the
  !> same text) the file is not opened: the text is parsed from a scratch copy; `path` still
  !> locates the relative file names it gives. A namelist with a &kumo_cloud file needs
  !> `read_grid`, which gives the file's grid (kumo_scene_setup's `load_config` passes one).
  subroutine read_config(path, cfg, error, text, read_grid)
    character(len=*), intent(in) :: path
    type(config_t), intent(out) :: cfg
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: text
    procedure(cloud_grid_reader), optional :: read_grid
    integer :: unit, ios
    character(len=512) :: msg
    logical :: present_groups(size(GROUP_NAMES))
    cfg%path = path
    if (present(text)) then
      call open_text(text, unit, error)
      if (allocated(error)) return
    else
      open (newunit=unit, file=path, status='old', action='read', iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call set_error(error, 'cannot open namelist file "'//trim(path)//'": '//trim(msg))
        return
      end if
    end if
    call scan_groups(unit, present_groups, error)
    if (.not. allocated(error)) call read_control(unit, present_groups(1), cfg%control, error)
    if (.not. allocated(error)) call read_cloud(unit, present_groups(10), path, cfg%cloud, error, &
                                                read_grid)
    if (.not. allocated(error)) call read_atmosphere(unit, present_groups(2), cfg%cloud, &
                                                     cfg%atm, error, read_grid)
    if (.not. allocated(error)) call read_phase(unit, present_groups(3), cfg%phase, error)
    if (.not. allocated(error)) call read_surface(unit, present_groups(4), cfg%surface, error)
    if (.not. allocated(error)) call read_source(unit, present_groups(5), cfg%source, error)
    if (.not. allocated(error)) call read_output(unit, present_groups(6), cfg%atm%nz, &
                                                 cfg%output, error)
    if (.not. allocated(error)) call read_vr(unit, present_groups(7), cfg%vr, error)
    if (.not. allocated(error)) call read_radiance(unit, present_groups(8), cfg%atm%nz, &
                                                   cfg%rad, error)
    if (.not. allocated(error)) call read_camera(unit, present_groups(9), cfg%atm, cfg%cam, &
                                                 error)
    if (.not. allocated(error)) call read_thermal(unit, present_groups(11), cfg%atm%nz, &
                                                  cfg%thermal, error)
    if (.not. allocated(error)) call read_spectral(unit, present_groups(12), path, cfg%atm%nz, &
                                                   cfg%spectral, error)
    close (unit)
    if (.not. allocated(error)) call consolidate(cfg, error)
  end subroutine read_config

  !> A scratch file holding `text` (lines separated by line ends), open for reading on `unit`.
  subroutine open_text(text, unit, error)
    character(len=*), intent(in) :: text
    integer, intent(out) :: unit
    type(error_t), allocatable, intent(out) :: error
    integer :: ios, i0, i1
    character(len=512) :: msg
    open (newunit=unit, status='scratch', action='readwrite', iostat=ios, iomsg=msg)
    i0 = 1
    do while (ios == 0 .and. i0 <= len(text))
      i1 = index(text(i0:), new_line('a'))
      if (i1 == 0) then
        i1 = len(text) + 1
      else
        i1 = i0 + i1 - 1
      end if
      write (unit, '(a)', iostat=ios, iomsg=msg) text(i0:i1 - 1)
      i0 = i1 + 1
    end do
    if (ios == 0) rewind (unit, iostat=ios, iomsg=msg)
    if (ios /= 0) call set_error(error, 'cannot make a scratch copy of the namelist text: '// &
                                 trim(msg))
  end subroutine open_text

  !> Find which groups are present (kumo_nml_text reads the layouts gfortran reads: &group ... /,
  !> $group ... $end, tabs, several groups on a line). Unknown group names are errors with the
  !> closest known name; a group given twice is an error naming both lines.
  subroutine scan_groups(unit, present_groups, error)
    integer, intent(in) :: unit
    logical, intent(out) :: present_groups(:)
    type(error_t), allocatable, intent(out) :: error
    type(nml_group_t), allocatable :: groups(:)
    character(len=:), allocatable :: text, hint
    integer :: i, k, first_line(size(GROUP_NAMES))
    present_groups = .false.
    first_line = 0
    text = unit_text(unit)
    call nml_scan(text, groups, error)
    if (allocated(error)) return
    do i = 1, size(groups)
      k = findloc(GROUP_NAMES, groups(i)%name, 1)
      if (k == 0) then
        hint = closest_name(groups(i)%name, GROUP_NAMES)
        if (len(hint) > 0) then
          hint = '; did you mean &'//hint//'?'
        else
          hint = '; known groups: '//join(GROUP_NAMES)
        end if
        call set_error(error, 'unknown namelist group &'//groups(i)%name//' (line '// &
                       str(groups(i)%line)//')'//hint)
        return
      end if
      if (present_groups(k)) then
        call set_error(error, 'namelist group &'//groups(i)%name//' appears more than once '// &
                       '(lines '//str(first_line(k))//' and '//str(groups(i)%line)// &
                       '); give each group once')
        return
      end if
      present_groups(k) = .true.
      first_line(k) = groups(i)%line
    end do
    rewind (unit)
  end subroutine scan_groups

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

  subroutine read_control(unit, present, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(control_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    integer(i8) :: n_photons_per_batch, seed, max_photons, max_events
    integer :: n_batches, verbose, ios, p3d_orders
    real(wp) :: target_rel_error, checkpoint_interval
    character(len=16) :: target_output
    character(len=8) :: mode_3d
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_control: '
    namelist /kumo_control/ n_photons_per_batch, n_batches, seed, target_rel_error, &
      target_output, max_photons, max_events, verbose, mode_3d, p3d_orders, checkpoint_interval
    n_photons_per_batch = cfg%n_photons_per_batch
    n_batches = cfg%n_batches
    seed = cfg%seed
    target_rel_error = cfg%target_rel_error
    target_output = cfg%target_output
    max_photons = cfg%max_photons
    max_events = cfg%max_events
    verbose = cfg%verbose
    mode_3d = cfg%mode_3d
    p3d_orders = cfg%p3d_orders
    checkpoint_interval = cfg%checkpoint_interval
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_control, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_control', present, ios, msg, error, probe)
    if (allocated(error)) return
    cfg%n_photons_per_batch = n_photons_per_batch
    cfg%n_batches = n_batches
    cfg%seed = seed
    cfg%target_rel_error = target_rel_error
    cfg%target_output = to_lower(target_output)
    cfg%max_photons = max_photons
    cfg%max_events = max_events
    cfg%verbose = verbose
    cfg%mode_3d = to_lower(mode_3d)
    cfg%p3d_orders = p3d_orders
    cfg%checkpoint_interval = checkpoint_interval
    call require(n_photons_per_batch >= 1, CTX, 'n_photons_per_batch', n_photons_per_batch, &
                 'must be >= 1', error)
    call require(n_batches >= 2, CTX, 'n_batches', n_batches, &
                 'must be >= 2 (batches give the standard error)', error)
    call require(seed >= 0, CTX, 'seed', seed, 'must be >= 0', error)
    call require(within(target_rel_error, 0.0_wp, BIG), CTX, 'target_rel_error', &
                 target_rel_error, 'must be >= 0 (0 = fixed photon budget)', error)
    call require(findloc(TARGET_NAMES, cfg%target_output, 1) > 0, CTX, 'target_output', &
                 target_output, 'must be one of '//join(TARGET_NAMES), error)
    call require(max_photons >= 1, CTX, 'max_photons', max_photons, 'must be >= 1', error)
    if (.not. allocated(error)) then
      call require(n_photons_per_batch <= MAX_TOTAL_PHOTONS/n_batches, CTX, &
                   'n_photons_per_batch', n_photons_per_batch, 'times n_batches = '// &
                   str(n_batches)//' must be <= 2^53 = '//str(MAX_TOTAL_PHOTONS)// &
                   ' photons (beyond, counts overflow or lose exactness in the tallies)', error)
      call require(max_photons <= MAX_TOTAL_PHOTONS, CTX, 'max_photons', max_photons, &
                   'must be <= 2^53 = '//str(MAX_TOTAL_PHOTONS), error)
    end if
    call require(max_events >= 1, CTX, 'max_events', max_events, 'must be >= 1', error)
    call require(findloc(MODE_NAMES, cfg%mode_3d, 1) > 0, CTX, 'mode_3d', mode_3d, &
                 'must be one of '//join(MODE_NAMES), error)
    call require(p3d_orders >= 0, CTX, 'p3d_orders', p3d_orders, 'must be >= 0', error)
    call require(within(checkpoint_interval, 0.0_wp, BIG), CTX, 'checkpoint_interval', &
                 checkpoint_interval, 'must be >= 0 s (0 = no checkpoints)', error)
  contains
    !> Read one assignment of &kumo_control (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_control, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_control, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_control

  subroutine read_atmosphere(unit, present, cloud, cfg, error, read_grid)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(cloud_cfg_t), intent(in) :: cloud
    type(atmosphere_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    procedure(cloud_grid_reader), optional :: read_grid   !! present whenever cloud%enabled
    integer :: nz, n_components, k3d_bottom, nx, ny, nz3, n_components_3d, ios, k, ic
    real(wp) :: lx, ly, cp_air, co2_ppm, latitude_deg, rayleigh_depol
    logical :: rayleigh
    character(len=16) :: rayleigh_profile
    real(wp) :: z_levels(0:MAX_LAYERS), ext1d(MAX_LAYERS, MAX_COMP), ssa1d(MAX_LAYERS, MAX_COMP)
    real(wp) :: air_density(MAX_LAYERS), pressure_levels_hpa(0:MAX_LAYERS)
    integer :: phase1d(MAX_LAYERS, MAX_COMP), phase3d(MAX_COMP)
    character(len=PATH_LEN) :: scene_file
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_atmosphere: '
    namelist /kumo_atmosphere/ nz, z_levels, lx, ly, n_components, ext1d, ssa1d, phase1d, &
      scene_file, k3d_bottom, nx, ny, nz3, n_components_3d, phase3d, air_density, cp_air, &
      rayleigh, rayleigh_profile, co2_ppm, latitude_deg, rayleigh_depol, pressure_levels_hpa
    if (.not. present .and. .not. cloud%enabled) then
      call set_error(error, 'namelist group &kumo_atmosphere is required (levels and layers) '// &
                     'unless &kumo_cloud gives a cloud file')
      return
    end if
    nz = 0
    z_levels = UNSET
    lx = UNSET
    ly = UNSET
    rayleigh = cfg%rayleigh
    rayleigh_profile = cfg%rayleigh_profile
    co2_ppm = cfg%co2_ppm
    latitude_deg = cfg%latitude_deg
    rayleigh_depol = cfg%rayleigh_depol
    pressure_levels_hpa = UNSET
    n_components = cfg%n_components
    ext1d = UNSET
    ssa1d = UNSET
    phase1d = IUNSET
    scene_file = ''
    k3d_bottom = 0
    nx = IUNSET     ! (1, 1, 0 when not given; unset is told apart for MCARaTS files)
    ny = IUNSET
    nz3 = IUNSET
    n_components_3d = 1
    phase3d = 1
    air_density = UNSET
    cp_air = cfg%cp_air
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_atmosphere, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_atmosphere', present, ios, msg, error, probe)
    if (allocated(error)) return
    if (rayleigh) then
      call rayleigh_profile_check(rayleigh_profile, error)
      if (allocated(error)) return
      call require(within(co2_ppm, 0.0_wp, 2000.0_wp) .and. within(latitude_deg, -90.0_wp, &
                                                                   90.0_wp), CTX, 'co2_ppm', &
                   co2_ppm, 'must be within [0, 2000] and latitude_deg = '//str(latitude_deg)// &
                   ' within [-90, 90]', error)
      call require(rayleigh_depol < 6.0_wp/7.0_wp .and. ieee_is_finite(rayleigh_depol), CTX, &
                   'rayleigh_depol', rayleigh_depol, &
                   'must be < 6/7 (a value < 0 takes the Bodhaine et al. value)', error)
      if (allocated(error)) return
    end if
    cfg%rayleigh = rayleigh
    cfg%rayleigh_profile = to_lower(adjustl(rayleigh_profile))
    cfg%co2_ppm = co2_ppm
    cfg%latitude_deg = latitude_deg
    cfg%rayleigh_depol = rayleigh_depol
    if (cloud%enabled .and. cloud%req%format == 'mcarats') then
      call mcarats_region_sizes(cloud, lx, ly, scene_file, nx, ny, nz3, error)
      if (allocated(error)) return
    else
      if (nx == IUNSET) nx = 1
      if (ny == IUNSET) ny = 1
      if (nz3 == IUNSET) nz3 = 0
    end if
    if (cloud%enabled .and. cloud%req%format /= 'mcarats') then
      call levels_with_cloud(cloud, nz, z_levels, lx, ly, scene_file, k3d_bottom, nz3, ext1d, &
                             ssa1d, phase1d, error)
      if (allocated(error)) return
      nx = cloud%grid%nx
      ny = cloud%grid%ny
      n_components_3d = 1
      cfg%levels_from_cloud = .true.
    end if
    if (lx == UNSET) lx = cfg%lx
    if (ly == UNSET) ly = cfg%ly
    call require(nz >= 1 .and. nz <= MAX_LAYERS, CTX, 'nz', nz, &
                 'must be within 1..'//str(MAX_LAYERS), error)
    call require(n_components >= 1 .and. n_components <= MAX_COMP, CTX, 'n_components', &
                 n_components, 'must be within 1..'//str(MAX_COMP), error)
    if (allocated(error)) return
    call require(all(z_levels(0:nz) /= UNSET), CTX, 'z_levels', rule='needs nz + 1 = '// &
                 str(nz + 1)//' values (levels 0..nz, bottom first) [m]', error=error)
    call require(all(z_levels(nz + 1:) == UNSET), CTX, 'z_levels', rule='has more than '// &
                 'nz + 1 = '//str(nz + 1)//' values', error=error)
    if (allocated(error)) return
    do k = 0, nz
      if (.not. ieee_is_finite(z_levels(k))) then
        call set_error(error, CTX//'z_levels('//str(k)//') is not finite')
        return
      end if
      if (k > 0) then
        if (.not. z_levels(k) > z_levels(k - 1)) then
          call set_error(error, CTX//'z_levels must increase strictly, but z_levels('// &
                         str(k)//') = '//str(z_levels(k))//' <= z_levels('//str(k - 1)//') = '// &
                         str(z_levels(k - 1)))
          return
        end if
      end if
    end do
    call require(within(lx, SMALL, BIG) .and. within(ly, SMALL, BIG), CTX, 'lx', lx, &
                 'and ly = '//str(ly)//' must be > 0 [m]', error)
    if (allocated(error)) return
    ! Rayleigh layers are set from pressures over real heights: a top below KM_HINT looks like
    ! kilometres given where metres are expected.
    if (rayleigh .and. z_levels(nz) < KM_HINT) then
      call set_error(error, CTX//'z_levels top = '//str(z_levels(nz))//' m with rayleigh = '// &
                     '.true.: heights are in metres; '//str(z_levels(nz))//' km would be '// &
                     str(1000.0_wp*z_levels(nz))//' m (the top must be >= '//str(KM_HINT)//' m)')
      return
    end if
    if (any(ext1d(nz + 1:, :) /= UNSET) .or. any(ext1d(:, n_components + 1:) /= UNSET) .or. &
        any(ssa1d(nz + 1:, :) /= UNSET) .or. any(ssa1d(:, n_components + 1:) /= UNSET) .or. &
        any(phase1d(nz + 1:, :) /= IUNSET) .or. any(phase1d(:, n_components + 1:) /= IUNSET)) then
      call set_error(error, '&kumo_atmosphere: ext1d/ssa1d/phase1d have values beyond '// &
                     'layer nz = '//str(nz)//' or component n_components = '//str(n_components))
      return
    end if
    do ic = 1, n_components
      do k = 1, nz
        if (ext1d(k, ic) == UNSET) ext1d(k, ic) = 0.0_wp
        if (ssa1d(k, ic) == UNSET) ssa1d(k, ic) = 1.0_wp
        if (phase1d(k, ic) == IUNSET) phase1d(k, ic) = 1
        call require(within(ext1d(k, ic), 0.0_wp, BIG), CTX, 'ext1d('//str(k)//','//str(ic)//')', &
                     ext1d(k, ic), 'must be finite and >= 0 [m-1]', error)
        call require(within(ssa1d(k, ic), 0.0_wp, 1.0_wp), CTX, 'ssa1d('//str(k)//','//str(ic)// &
                     ')', ssa1d(k, ic), 'must be within [0, 1]', error)
        if (allocated(error)) return
      end do
    end do
    if (len_trim(scene_file) > 0) then
      if (k3d_bottom < 1 .or. nz3 < 1 .or. k3d_bottom + nz3 - 1 > nz) then
        call set_error(error, '&kumo_atmosphere: with scene_file, the 3-D region k3d_bottom = '// &
                       str(k3d_bottom)//' .. k3d_bottom + nz3 - 1 = '//str(k3d_bottom + nz3 - 1)// &
                       ' must lie within layers 1..nz = '//str(nz))
        return
      end if
      call require(nx >= 1 .and. ny >= 1, CTX, 'nx', nx, 'and ny = '//str(ny)//' must be >= 1', &
                   error)
      if (allocated(error)) return
    else if (cloud%enabled .and. cloud%req%format == 'mcarats') then
      if (k3d_bottom < 1 .or. k3d_bottom + nz3 - 1 > nz) then
        call set_error(error, '&kumo_atmosphere: the 3-D region of the MCARaTS file, layers '// &
                       'k3d_bottom = '//str(k3d_bottom)//' .. k3d_bottom + nz3 - 1 = '// &
                       str(k3d_bottom + nz3 - 1)//', must lie within layers 1..nz = '//str(nz)// &
                       ' (k3d_bottom is MCARaTS''s Atm_iz3l)')
        return
      end if
    else if ((k3d_bottom /= 0 .or. nz3 /= 0) .and. .not. cloud%enabled) then
      call set_error(error, '&kumo_atmosphere: k3d_bottom/nz3 are set but scene_file is empty')
      return
    end if
    ! checked with or without a scene file: phase3d(1:n_components_3d) is kept below
    call require(n_components_3d >= 1 .and. n_components_3d <= MAX_COMP, CTX, &
                 'n_components_3d', n_components_3d, 'must be within 1..'//str(MAX_COMP), error)
    call require(within(cp_air, SMALL, BIG), CTX, 'cp_air', cp_air, 'must be > 0', error)
    if (allocated(error)) return
    if (any(air_density(1:nz) /= UNSET)) then
      call require(all(air_density(1:nz) /= UNSET) .and. all(air_density(nz + 1:) == UNSET), &
                   CTX, 'air_density', rule='needs exactly nz = '//str(nz)//' values [kg m-3]', &
                   error=error)
      call require(all(within(air_density(1:nz), SMALL, BIG)), CTX, 'air_density values', &
                   rule='must be finite and > 0', error=error)
      if (allocated(error)) return
      cfg%air_density = air_density(1:nz)
    end if
    cfg%nz = nz
    cfg%z = z_levels(0:nz)
    cfg%lx = lx
    cfg%ly = ly
    cfg%n_components = n_components
    cfg%ext1d = ext1d(1:nz, 1:n_components)
    cfg%ssa1d = ssa1d(1:nz, 1:n_components)
    cfg%phase1d = phase1d(1:nz, 1:n_components)
    cfg%scene_file = scene_file
    cfg%k3d_bottom = k3d_bottom
    cfg%nx = nx
    cfg%ny = ny
    cfg%nz3 = nz3
    cfg%n_components_3d = n_components_3d
    cfg%phase3d = phase3d(1:n_components_3d)
    cfg%cp_air = cp_air
    call rayleigh_pressure(pressure_levels_hpa, cloud, cfg, error, read_grid)
  contains
    !> Read one assignment of &kumo_atmosphere (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_atmosphere, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_atmosphere, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_atmosphere

  !> The 3-D region of an MCARaTS atmosphere (cloud_format = 'mcarats'). As in MCARaTS, the
  !> levels, the region's first layer and the domain come from the namelist (z_levels,
  !> k3d_bottom, lx, ly: the binary file has no grid). Its sizes come from the `.ctl`, where
  !> nx, ny, nz3 given in the namelist must agree with it, or, for a binary file, from nx, ny,
  !> nz3, which are then required.
  subroutine mcarats_region_sizes(cloud, lx, ly, scene_file, nx, ny, nz3, error)
    type(cloud_cfg_t), intent(in) :: cloud
    real(wp), intent(in) :: lx, ly
    character(len=*), intent(in) :: scene_file
    integer, intent(inout) :: nx, ny, nz3
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: CTX = '&kumo_atmosphere with an MCARaTS cloud file: '
    if (len_trim(scene_file) > 0) then
      call set_error(error, CTX//'scene_file must not be set: the 3-D region is the MCARaTS file')
    else if (lx == UNSET .or. ly == UNSET) then
      call set_error(error, CTX//'lx and ly are required: the MCARaTS file has no horizontal '// &
                     'grid (lx = nx Atm_dx, ly = ny Atm_dy)')
    else if (cloud%grid%nx > 0) then
      call agree('nx', nx, cloud%grid%nx, 'XDEF')
      call agree('ny', ny, cloud%grid%ny, 'YDEF')
      call agree('nz3', nz3, cloud%grid%nz, 'levels of extp3d')
    else if (nx == IUNSET .or. ny == IUNSET .or. nz3 == IUNSET) then
      call set_error(error, CTX//'nx, ny and nz3 are required with a binary MCARaTS file '// &
                     '(its sizes Atm_nx, Atm_ny, Atm_nz3), or name its .ctl in cloud_file')
    else if (nx < 1 .or. ny < 1 .or. nz3 < 1) then
      call set_error(error, CTX//'nx = '//str(nx)//', ny = '//str(ny)//' and nz3 = '//str(nz3)// &
                     ' must be >= 1')
    end if
  contains
    subroutine agree(name, given, found, what)
      character(len=*), intent(in) :: name, what
      integer, intent(inout) :: given
      integer, intent(in) :: found
      if (allocated(error)) return
      if (given /= IUNSET .and. given /= found) then
        call set_error(error, CTX//name//' = '//str(given)//' disagrees with '//cloud%req%path// &
                       ' ('//what//' '//str(found)//'); leave it out to take the file''s')
      end if
      given = found
    end subroutine agree
  end subroutine mcarats_region_sizes

  !> A Rayleigh profile name: a named standard atmosphere, RAYLEIGH_LEVELS or RAYLEIGH_CLOUD_FILE.
  subroutine rayleigh_profile_check(name, error)
    character(len=*), intent(in) :: name
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: lname
    integer :: kind
    lname = trim(adjustl(to_lower(name)))
    if (lname == RAYLEIGH_LEVELS .or. lname == RAYLEIGH_CLOUD_FILE) return
    call std_atmosphere_kind_from_name(lname, kind, error)
    if (.not. allocated(error)) return
    error%message = '&kumo_atmosphere: rayleigh_profile = '''//trim(name)//''' must be one '// &
                    'of '//join(STD_ATMOSPHERE_NAMES)//' (standard atmospheres), '// &
                    RAYLEIGH_LEVELS//' (the sounding pressure_levels_hpa) or '// &
                    RAYLEIGH_CLOUD_FILE//' (the pressure of the &kumo_cloud LES file)'
  end subroutine rayleigh_profile_check

  !> The pressure of the Rayleigh layers when it does not come from a standard atmosphere:
  !> `pressure_levels_hpa` for RAYLEIGH_LEVELS, or the layer pressures of the &kumo_cloud LES
  !> file for RAYLEIGH_CLOUD_FILE, from `read_grid` (grid and a pressure profile only, no 3-D
  !> field). Runs after the levels are set (cfg%nz, cfg%z).
  subroutine rayleigh_pressure(pressure_levels_hpa, cloud, cfg, error, read_grid)
    real(wp), intent(in) :: pressure_levels_hpa(0:)  !! the namelist array, UNSET where not given
    type(cloud_cfg_t), intent(in) :: cloud
    type(atmosphere_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    procedure(cloud_grid_reader), optional :: read_grid   !! present whenever cloud%enabled
    character(len=*), parameter :: CTX = '&kumo_atmosphere: '
    character(len=:), allocatable :: ctx_cloud
    type(cloud_request_t) :: req
    type(cloud_input_t) :: c
    integer :: nz, n_given, k

    if (.not. cfg%rayleigh) return   ! every Rayleigh setting is unused
    nz = cfg%nz
    n_given = count(pressure_levels_hpa /= UNSET)
    if (n_given > 0 .and. cfg%rayleigh_profile /= RAYLEIGH_LEVELS) then
      call set_error(error, CTX//'pressure_levels_hpa is given but rayleigh_profile = '''// &
                     trim(cfg%rayleigh_profile)//'''; the sounding is used only with '// &
                     'rayleigh_profile = '''//RAYLEIGH_LEVELS//'''')
      return
    end if
    select case (trim(cfg%rayleigh_profile))
    case (RAYLEIGH_LEVELS)
      if (n_given == 0) then
        call set_error(error, CTX//'rayleigh_profile = '''//RAYLEIGH_LEVELS//''' needs '// &
                       'pressure_levels_hpa, the pressure at each of the nz + 1 = '// &
                       str(nz + 1)//' entries of z_levels [hPa]')
        return
      end if
      if (any(pressure_levels_hpa(0:nz) == UNSET) .or. &
          any(pressure_levels_hpa(nz + 1:) /= UNSET)) then
        call set_error(error, CTX//'pressure_levels_hpa has '//str(n_given)//' values but '// &
                       'needs nz + 1 = '//str(nz + 1)//', one per entry of z_levels '// &
                       '(levels 0..nz, bottom first) [hPa]')
        return
      end if
      do k = 0, nz
        if (.not. within(pressure_levels_hpa(k), SMALL, BIG)) then
          call set_error(error, CTX//'pressure_levels_hpa('//str(k)//') = '// &
                         str(pressure_levels_hpa(k))//' must be finite and > 0 [hPa]')
          return
        end if
      end do
      do k = 1, nz
        if (.not. pressure_levels_hpa(k) < pressure_levels_hpa(k - 1)) then
          call set_error(error, CTX//'pressure_levels_hpa('//str(k)//') = '// &
                         str(pressure_levels_hpa(k))//' must be < pressure_levels_hpa('// &
                         str(k - 1)//') = '//str(pressure_levels_hpa(k - 1))// &
                         ': pressure falls with height (levels bottom first)')
          return
        end if
      end do
      cfg%p_levels = 100.0_wp*pressure_levels_hpa(0:nz)
    case (RAYLEIGH_CLOUD_FILE)
      ctx_cloud = CTX//'rayleigh_profile = '''//RAYLEIGH_CLOUD_FILE//''': '
      if (.not. cloud%enabled) then
        call set_error(error, ctx_cloud//'needs a cloud file (&kumo_cloud cloud_file) '// &
                       'whose pressure gives the profile; there is none')
        return
      end if
      if (trim(cloud%req%format) /= 'les') then
        call set_error(error, ctx_cloud//'only LES netCDF files (cloud_format = ''les'') '// &
                       'have a pressure variable; the cloud file '//cloud%req%path// &
                       ' has cloud_format = '''//trim(cloud%req%format)//'''. Use '// &
                       'rayleigh_profile = '''//RAYLEIGH_LEVELS//''' with pressure_levels_hpa'// &
                       ' or a standard atmosphere')
        return
      end if
      req = cloud%req
      req%pressure_profile = .true.
      call grid_of(req, c, error, read_grid)
      if (allocated(error)) then
        error%message = ctx_cloud//error%message
        return
      end if
      if (.not. allocated(c%pressure)) then
        call set_error(error, ctx_cloud//cloud%req%path//': no pressure was read')
        return
      end if
      if (size(c%pressure) /= cloud%grid%nz) then
        call set_error(error, ctx_cloud//cloud%req%path//': '//str(size(c%pressure))// &
                       ' pressure values for '//str(cloud%grid%nz)//' layers')
        return
      end if
      associate (p => c%pressure)
        do k = 2, size(p)
          if (.not. p(k) < p(k - 1)) then
            call set_error(error, ctx_cloud//'the pressure of the cloud file ('// &
                           c%pressure_source//') must fall with height, but layer '// &
                           str(k)//' (z = '//str(cloud%grid%z(k - 1))//' to '// &
                           str(cloud%grid%z(k))//' m) has '//str(p(k))//' Pa >= '// &
                           str(p(k - 1))//' Pa of layer '//str(k - 1)//' below it')
            return
          end if
        end do
      end associate
      call move_alloc(c%pressure, cfg%p_cloud)
      cfg%p_cloud_source = c%pressure_source
    case default
      continue   ! a standard atmosphere: nothing to read
    end select
  end subroutine rayleigh_pressure

  !> Levels with a cloud file: the file's layer edges, below them a layer from the ground if
  !> the file starts above 0; or, when z_levels is given, z_levels must hold the file's edges
  !> as consecutive levels (to 1 mm), and the 3-D region is put there.
  subroutine levels_with_cloud(cloud, nz, z_levels, lx, ly, scene_file, k3d_bottom, nz3, &
                               ext1d, ssa1d, phase1d, error)
    type(cloud_cfg_t), intent(in) :: cloud
    integer, intent(inout) :: nz, k3d_bottom, nz3
    real(wp), intent(inout) :: z_levels(0:), lx, ly, ext1d(:, :), ssa1d(:, :)
    integer, intent(inout) :: phase1d(:, :)
    character(len=*), intent(in) :: scene_file
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: TOL = 1.0e-3_wp   ! [m]
    integer :: nzc, k, j
    real(wp) :: lxc, lyc
    character(len=*), parameter :: CTX = '&kumo_atmosphere with &kumo_cloud: '
    nzc = cloud%grid%nz
    lxc = cloud%grid%nx*cloud%grid%dx
    lyc = cloud%grid%ny*cloud%grid%dy
    if (len_trim(scene_file) > 0 .or. k3d_bottom /= 0 .or. nz3 /= 0) then
      call set_error(error, CTX//'scene_file, k3d_bottom and nz3 must not be set: the 3-D '// &
                     'region is the cloud file''s grid')
      return
    end if
    if ((lx /= UNSET .and. abs(lx - lxc) > TOL) .or. (ly /= UNSET .and. abs(ly - lyc) > TOL)) then
      call set_error(error, CTX//'lx, ly = '//str(lx)//', '//str(ly)//' differ from the '// &
                     'cloud file''s domain '//str(lxc)//' x '//str(lyc)//' m; leave them out')
      return
    end if
    lx = lxc
    ly = lyc
    if (nz == 0 .and. all(z_levels == UNSET)) then
      if (any(ext1d /= UNSET) .or. any(ssa1d /= UNSET) .or. any(phase1d /= IUNSET)) then
        call set_error(error, CTX//'ext1d, ssa1d or phase1d need z_levels (and nz): give the '// &
                       'levels of the whole column, the cloud file''s edges among them')
        return
      end if
      k = 0
      if (cloud%grid%z(0) > 0.0_wp) then
        z_levels(0) = 0.0_wp
        k = 1
      end if
      if (k + nzc > MAX_LAYERS) then
        call set_error(error, CTX//'the cloud file has '//str(nzc)//' layers; at most '// &
                       str(MAX_LAYERS)//' are possible')
        return
      end if
      z_levels(k:k + nzc) = cloud%grid%z
      nz = k + nzc
      k3d_bottom = k + 1
    else
      k3d_bottom = -1
      do k = 0, nz - nzc
        if (all(abs(z_levels(k:k + nzc) - cloud%grid%z) <= TOL)) then
          k3d_bottom = k + 1
          exit
        end if
      end do
      if (k3d_bottom < 0) then
        call set_error(error, CTX//'z_levels must contain the cloud file''s '//str(nzc + 1)// &
                       ' layer edges '//str(cloud%grid%z(0))//' ... '//str(cloud%grid%z(nzc))// &
                       ' m as consecutive levels (to 1 mm); or leave z_levels out to use them')
        return
      end if
      j = k3d_bottom - 1
      z_levels(j:j + nzc) = cloud%grid%z
    end if
    nz3 = nzc
  end subroutine levels_with_cloud

  !> &kumo_cloud: the cloud file, what it lacks, and how kumo computes its optics. The file's
  !> grid comes from `read_grid` here, so that the levels are known to the other groups.
  subroutine read_cloud(unit, present, nml_path, cfg, error, read_grid)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    character(len=*), intent(in) :: nml_path
    type(cloud_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    procedure(cloud_grid_reader), optional :: read_grid
    character(len=PATH_LEN) :: cloud_file, mie_cache, ice_optics_file, mcarats_phase_file
    character(len=16) :: cloud_format, size_distribution
    character(len=LES_NAME_LEN) :: les_lwc, les_reff, les_number, les_iwc, les_reff_ice, &
                                   les_temperature, les_pressure, les_air_density, les_x, les_y, &
                                   les_z, les_x_edges, les_y_edges, les_z_edges, les_vapour
    integer :: les_time_index, n_reff, ios, dist
    integer :: mcarats_np3d, mcarats_nkd, mcarats_mtprof, mcarats_idread, mcarats_ikd, &
               mcarats_nang, mcarats_npf
    real(wp) :: les_k_factor, droplet_number_cm3, v_eff, reff_min_um, reff_max_um
    logical :: les_z_edges_from_midpoints
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_cloud: '
    namelist /kumo_cloud/ cloud_file, cloud_format, les_time_index, les_lwc, les_reff, &
      les_number, les_iwc, les_reff_ice, les_temperature, les_pressure, les_air_density, &
      les_vapour, les_x, les_y, les_z, les_x_edges, les_y_edges, les_z_edges, les_k_factor, &
      les_z_edges_from_midpoints, droplet_number_cm3, size_distribution, v_eff, reff_min_um, &
      reff_max_um, n_reff, mie_cache, ice_optics_file, mcarats_np3d, mcarats_nkd, mcarats_mtprof, &
      mcarats_idread, mcarats_ikd, mcarats_phase_file, mcarats_nang, mcarats_npf
    if (.not. present) return
    cloud_file = ''
    cloud_format = 'les'
    les_time_index = -1
    les_lwc = ''
    les_reff = ''
    les_number = ''
    les_iwc = ''
    les_reff_ice = ''
    les_temperature = ''
    les_pressure = ''
    les_air_density = ''
    les_vapour = ''
    les_x = ''
    les_y = ''
    les_z = ''
    les_x_edges = ''
    les_y_edges = ''
    les_z_edges = ''
    les_k_factor = cfg%req%k_factor
    les_z_edges_from_midpoints = .false.
    droplet_number_cm3 = 0.0_wp
    size_distribution = cfg%size_distribution
    v_eff = cfg%v_eff
    reff_min_um = cfg%reff_min_um
    reff_max_um = cfg%reff_max_um
    n_reff = cfg%n_reff
    mie_cache = ''
    ice_optics_file = ''
    ! MCARaTS sizes: 0 (mtprof: -1) = not given, i.e. from the .ctl or MCARaTS's default
    mcarats_np3d = 0
    mcarats_nkd = 0
    mcarats_mtprof = -1
    mcarats_idread = 1
    mcarats_ikd = 1
    mcarats_phase_file = ''
    mcarats_nang = 0
    mcarats_npf = 0
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_cloud, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_cloud', present, ios, msg, error, probe)
    if (allocated(error)) return
    call cloud_format_check(cloud_format, cfg%req%format, error)
    if (allocated(error)) then
      error%message = '&kumo_cloud: '//error%message
      return
    end if
    call require(les_time_index >= 1 .or. les_time_index == -1, CTX, 'les_time_index', &
                 les_time_index, 'must be >= 1, or -1 for a file without a time dimension', error)
    call require(les_k_factor > 0.0_wp .and. les_k_factor <= 1.0_wp, CTX, 'les_k_factor', &
                 les_k_factor, 'must satisfy 0 < les_k_factor <= 1', error)
    call require(within(droplet_number_cm3, 0.0_wp, BIG), CTX, 'droplet_number_cm3', &
                 droplet_number_cm3, 'must be finite and >= 0 (0 = not given)', error)
    call require(n_reff >= 2 .and. n_reff <= 1000, CTX, 'n_reff', n_reff, &
                 'must be within 2..1000', error)
    call require(within(reff_min_um, 0.01_wp, 1000.0_wp) .and. &
                 within(reff_max_um, 0.01_wp, 1000.0_wp) .and. reff_max_um > reff_min_um, CTX, &
                 'reff_min_um', reff_min_um, 'and reff_max_um = '//str(reff_max_um)// &
                 ' must satisfy 0.01 <= reff_min_um < reff_max_um <= 1000 [um]', error)
    if (allocated(error)) return
    call dist_kind_from_name(size_distribution, dist, error)
    if (.not. allocated(error)) call size_dist_validate(dist, reff_min_um, v_eff, error)
    if (allocated(error)) then
      error%message = '&kumo_cloud: '//error%message
      return
    end if
    call mcarats_cloud_settings(cfg%req%format, cloud_file, mcarats_np3d, mcarats_nkd, &
                                mcarats_mtprof, mcarats_idread, mcarats_ikd, mcarats_phase_file, &
                                mcarats_nang, mcarats_npf, nml_path, cfg%req%mcarats, error)
    if (allocated(error)) return
    cfg%mcarats_phase_file = mcarats_phase_file
    if (len_trim(cloud_file) == 0) return   ! no cloud file: the group's settings are unused
    cfg%enabled = .true.
    cfg%file = cloud_file
    cfg%req%path = resolve_path(cloud_file, nml_path)
    cfg%req%time_index = les_time_index
    cfg%req%names%lwc = les_lwc
    cfg%req%names%reff = les_reff
    cfg%req%names%number = les_number
    cfg%req%names%iwc = les_iwc
    cfg%req%names%reff_ice = les_reff_ice
    cfg%req%names%temperature = les_temperature
    cfg%req%names%pressure = les_pressure
    cfg%req%names%air_density = les_air_density
    cfg%req%names%vapour = les_vapour
    cfg%req%names%x = les_x
    cfg%req%names%y = les_y
    cfg%req%names%z = les_z
    cfg%req%names%x_edges = les_x_edges
    cfg%req%names%y_edges = les_y_edges
    cfg%req%names%z_edges = les_z_edges
    cfg%req%k_factor = les_k_factor
    cfg%req%z_edges_from_midpoints = les_z_edges_from_midpoints
    cfg%req%droplet_number_cm3 = droplet_number_cm3
    cfg%size_distribution = to_lower(size_distribution)
    cfg%v_eff = v_eff
    cfg%reff_min_um = reff_min_um
    cfg%reff_max_um = reff_max_um
    cfg%n_reff = n_reff
    cfg%mie_cache = ''
    if (len_trim(mie_cache) > 0) cfg%mie_cache = resolve_path(mie_cache, nml_path)
    cfg%ice_optics_file = ''
    if (len_trim(ice_optics_file) > 0) cfg%ice_optics_file = resolve_path(ice_optics_file, &
                                                                          nml_path)
    call grid_of(cfg%req, cfg%grid, error, read_grid)
    if (allocated(error)) error%message = '&kumo_cloud: '//error%message
  contains
    !> Read one assignment of &kumo_cloud (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_cloud, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_cloud, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_cloud

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

  !> &kumo_cloud mcarats_*: checks, and the request for `from_mcarats`. They apply to
  !> cloud_format = 'mcarats' only. A binary atmosphere file takes the sizes not given from
  !> MCARaTS's defaults (Atm_np3d = 1, Atm_nkd = 1, Atm_mtprof = 0), as MCARaTS itself does; a
  !> `.ctl` gives them (sizes given must agree, checked when it is read). A binary phase file
  !> needs mcarats_nang and mcarats_npf; there is no default to fall back on.
  subroutine mcarats_cloud_settings(fmt, cloud_file, np3d, nkd, mtprof, idread, ikd, phase_file, &
                                    nang, npf, nml_path, req, error)
    character(len=*), intent(in) :: fmt, cloud_file, phase_file, nml_path
    integer, intent(in) :: np3d, nkd, mtprof, idread, ikd, nang, npf
    type(mcarats_request_t), intent(inout) :: req
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: CTX = '&kumo_cloud: '
    logical :: atm_ctl, phase_ctl
    if (trim(fmt) /= 'mcarats') then
      if (np3d /= 0 .or. nkd /= 0 .or. mtprof /= -1 .or. idread /= 1 .or. ikd /= 1 .or. &
          len_trim(phase_file) > 0 .or. nang /= 0 .or. npf /= 0) then
        call set_error(error, CTX//'the mcarats_* settings apply to cloud_format = '// &
                       '''mcarats'' only (cloud_format is '''//trim(fmt)//''')')
      end if
      return
    end if
    if (np3d < 0 .or. nkd < 0 .or. npf < 0 .or. nang < 0) then
      call set_error(error, CTX//'mcarats_np3d = '//str(np3d)//', mcarats_nkd = '//str(nkd)// &
                     ', mcarats_nang = '//str(nang)//' and mcarats_npf = '//str(npf)// &
                     ' must be >= 0 (0 = not given)')
      return
    end if
    call require(mtprof >= -1 .and. mtprof <= 1, CTX, 'mcarats_mtprof', mtprof, &
                 'must be 0 (temperatures per layer), 1 (per level) or -1 (not given)', error)
    call require(idread >= 1, CTX, 'mcarats_idread', idread, 'must be >= 1', error)
    call require(ikd >= 1, CTX, 'mcarats_ikd', ikd, 'must be >= 1', error)
    call require(nang /= 1, CTX, 'mcarats_nang', nang, &
                 'must be >= 2 (angles per phase function)', error)
    if (allocated(error)) return
    atm_ctl = is_ctl_path(cloud_file)
    phase_ctl = is_ctl_path(phase_file)
    req%np3d = merge(np3d, -1, np3d > 0)
    req%nkd = merge(nkd, -1, nkd > 0)
    req%mtprof = mtprof
    req%nang = merge(nang, -1, nang > 0)
    req%npf = merge(npf, -1, npf > 0)
    if (.not. atm_ctl) then
      ! a binary file: MCARaTS's defaults for the sizes not given
      if (req%np3d < 0) req%np3d = 1
      if (req%nkd < 0) req%nkd = 1
      if (req%mtprof < 0) req%mtprof = 0
      if (ikd > req%nkd) then
        call set_error(error, CTX//'mcarats_ikd = '//str(ikd)//' must be within 1..'// &
                       'mcarats_nkd = '//str(req%nkd))
        return
      end if
    end if
    if (len_trim(phase_file) == 0) then
      if (nang /= 0 .or. npf /= 0) then
        call set_error(error, CTX//'mcarats_nang and mcarats_npf describe mcarats_phase_file, '// &
                       'which is not given')
        return
      end if
    else if (.not. phase_ctl .and. (nang == 0 .or. npf == 0)) then
      call set_error(error, CTX//'mcarats_phase_file '''//trim(phase_file)//''' is a binary '// &
                     'file: give its sizes mcarats_nang (angles, Sca_nangi) and mcarats_npf '// &
                     '(tables, Sca_npf), or name its .ctl')
      return
    end if
    req%idread = idread
    req%ikd = ikd
    req%phase_path = ''
    if (len_trim(phase_file) > 0) req%phase_path = resolve_path(phase_file, nml_path)
  end subroutine mcarats_cloud_settings

  !> Every input file the configuration `cfg` (read from `nml_path`) names, the namelist
  !> first; the Mie cache is not among them (the run may write it).
  function config_inputs(cfg, nml_path) result(inputs)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: nml_path
    type(input_file_t), allocatable :: inputs(:)
    integer :: i
    allocate (inputs(0))
    call add('namelist', nml_path)
    do i = 1, cfg%phase%n_phase
      if (cfg%phase%kind(i) == PHASE_TABLE) &
        call add('&kumo_phase phase_file('//str(i)//')', resolve_path(cfg%phase%file(i), nml_path))
    end do
    if (len_trim(cfg%atm%scene_file) > 0) &
      call add('&kumo_atmosphere scene_file', resolve_path(cfg%atm%scene_file, nml_path))
    if (len_trim(cfg%surface%albedo_file) > 0) &
      call add('&kumo_surface albedo_file', resolve_path(cfg%surface%albedo_file, nml_path))
    if (len_trim(cfg%surface%brdf_file) > 0) &
      call add('&kumo_surface brdf_file', resolve_path(cfg%surface%brdf_file, nml_path))
    if (len_trim(cfg%surface%surface_file) > 0) &
      call add('&kumo_surface surface_file', resolve_path(cfg%surface%surface_file, nml_path))
    if (cfg%thermal%enabled .and. len_trim(cfg%thermal%t_surface_file) > 0) &
      call add('&kumo_thermal t_surface_file', resolve_path(cfg%thermal%t_surface_file, nml_path))
    if (cfg%spectral%enabled .and. allocated(cfg%spectral%kdist_path)) &
      call add('&kumo_spectral kdist_file', cfg%spectral%kdist_path)
    if (cfg%spectral%enabled .and. cfg%cloud%enabled .and. &
        allocated(cfg%spectral%cloud_optics_path)) &
      call add('&kumo_spectral cloud_optics_file', cfg%spectral%cloud_optics_path)
    if (.not. cfg%cloud%enabled) return
    if (allocated(cfg%cloud%req%path)) call add('&kumo_cloud cloud_file', cfg%cloud%req%path)
    if (allocated(cfg%cloud%req%mcarats%phase_path)) then
      if (len_trim(cfg%cloud%req%mcarats%phase_path) > 0) &
        call add('&kumo_cloud mcarats_phase_file', cfg%cloud%req%mcarats%phase_path)
    end if
    if (len_trim(cfg%cloud%ice_optics_file) > 0) &
      call add('&kumo_cloud ice_optics_file', trim(cfg%cloud%ice_optics_file))
  contains
    subroutine add(label, path)
      character(len=*), intent(in) :: label, path
      type(input_file_t), allocatable :: more(:)
      integer :: n
      n = size(inputs)
      allocate (more(n + 1))
      more(1:n) = inputs
      more(n + 1)%label = label
      more(n + 1)%path = path
      call move_alloc(more, inputs)
    end subroutine add
  end function config_inputs

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

  subroutine read_phase(unit, present, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(phase_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    integer :: n_phase, n_table, ios, i
    character(len=16) :: phase_kind(MAX_PHASE)
    real(wp) :: phase_g(MAX_PHASE)
    character(len=PATH_LEN) :: phase_file(MAX_PHASE)
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_phase: '
    namelist /kumo_phase/ n_phase, phase_kind, phase_g, phase_file, n_table
    n_phase = 1
    phase_kind = 'isotropic'
    phase_g = 0.0_wp
    phase_file = ''
    n_table = cfg%n_table
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_phase, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_phase', present, ios, msg, error, probe)
    if (allocated(error)) return
    call require(n_phase >= 1 .and. n_phase <= MAX_PHASE, CTX, 'n_phase', n_phase, &
                 'must be within 1..'//str(MAX_PHASE), error)
    call require(n_table >= 100, CTX, 'n_table', n_table, 'must be >= 100', error)
    if (allocated(error)) return
    allocate (cfg%kind(n_phase))
    do i = 1, n_phase
      call phase_kind_from_name(phase_kind(i), cfg%kind(i), error)
      if (allocated(error)) then
        error%message = '&kumo_phase: phase_kind('//str(i)//'): '//error%message
        return
      end if
      call require(within(phase_g(i), nearest(-1.0_wp, 1.0_wp), nearest(1.0_wp, -1.0_wp)), CTX, &
                   'phase_g('//str(i)//')', phase_g(i), 'must satisfy |g| < 1', error)
      call require(trim(to_lower(phase_kind(i))) /= 'table' .or. len_trim(phase_file(i)) > 0, &
                   CTX, 'phase_file('//str(i)//')', rule='is needed for a table', error=error)
      if (allocated(error)) return
    end do
    cfg%n_phase = n_phase
    cfg%kind_name = phase_kind(1:n_phase)
    cfg%g = phase_g(1:n_phase)
    cfg%file = phase_file(1:n_phase)
    cfg%n_table = n_table
  contains
    !> Read one assignment of &kumo_phase (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_phase, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_phase, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_phase

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

  subroutine read_output(unit, present, nz, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    integer, intent(in) :: nz
    type(output_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    character(len=PATH_LEN) :: file
    integer :: flux_levels(MAX_LAYERS + 1), ios, i, deflate_level
    logical :: column_fluxes, voxel_absorption
    character(len=512) :: msg
    namelist /kumo_output/ file, flux_levels, column_fluxes, voxel_absorption, deflate_level
    file = cfg%file
    deflate_level = cfg%deflate_level
    flux_levels = IUNSET
    column_fluxes = cfg%column_fluxes
    voxel_absorption = cfg%voxel_absorption
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_output, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_output', present, ios, msg, error, probe)
    if (allocated(error)) return
    call require(len_trim(file) > 0, '&kumo_output: ', 'file', rule='must not be empty', &
                 error=error)
    if (allocated(error)) return
    call level_list('kumo_output', 'flux_levels', flux_levels, nz, [(i, i=0, nz)], &
                    cfg%flux_levels, error)
    if (allocated(error)) return
    call require(deflate_level >= 0 .and. deflate_level <= 9, '&kumo_output: ', 'deflate_level', &
                 deflate_level, 'must be within 0..9 (0: no compression)', error)
    if (allocated(error)) return
    cfg%deflate_level = deflate_level
    cfg%file = file
    cfg%column_fluxes = column_fluxes
    cfg%voxel_absorption = voxel_absorption
  contains
    !> Read one assignment of &kumo_output (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_output, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_output, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_output

  subroutine read_vr(unit, present, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(vr_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: rr_threshold, rr_weight, sv_fsupg, sv_fsupi
    integer :: sv_max_layers, ios, ip
    logical :: use_supervoxels, use_1d_layers, use_absorbing_layers, stratify_source, &
               use_exact_thermal
    character(len=16) :: vr_preset, absorption_estimator
    real(wp) :: zeta_min, trunc_theta_max_deg, trunc_peak, cf_tau_min, diffusion, ddis_eps
    integer :: trunc_levels, diffusion_max
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_vr: '
    namelist /kumo_vr/ rr_threshold, rr_weight, use_supervoxels, sv_fsupg, sv_fsupi, &
      sv_max_layers, use_1d_layers, use_absorbing_layers, use_exact_thermal, vr_preset, zeta_min, &
      trunc_theta_max_deg, trunc_levels, trunc_peak, cf_tau_min, diffusion, diffusion_max, &
      ddis_eps, stratify_source, absorption_estimator
    rr_threshold = cfg%rr_threshold
    rr_weight = cfg%rr_weight
    use_supervoxels = cfg%use_supervoxels
    sv_fsupg = cfg%sv_fsupg
    sv_fsupi = cfg%sv_fsupi
    sv_max_layers = cfg%sv_max_layers
    use_1d_layers = cfg%use_1d_layers
    use_absorbing_layers = cfg%use_absorbing_layers
    use_exact_thermal = cfg%use_exact_thermal
    stratify_source = cfg%stratify_source
    vr_preset = cfg%preset
    zeta_min = UNSET
    trunc_theta_max_deg = UNSET
    trunc_levels = IUNSET
    trunc_peak = cfg%trunc_peak
    cf_tau_min = UNSET
    diffusion = UNSET
    diffusion_max = cfg%diffusion_max
    ddis_eps = UNSET
    absorption_estimator = cfg%absorption_estimator
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_vr, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_vr', present, ios, msg, error, probe)
    if (allocated(error)) return
    ! The preset gives every technique a value; a variable set in the namelist overrides it.
    ip = findloc(PRESET_NAMES, to_lower(adjustl(vr_preset)), 1)
    call require(ip > 0, CTX, 'vr_preset', vr_preset, 'must be one of '//join(PRESET_NAMES), error)
    if (allocated(error)) return
    cfg%preset = PRESET_NAMES(ip)
    if (zeta_min == UNSET) zeta_min = PRESET_ZETA(ip)
    if (trunc_theta_max_deg == UNSET) trunc_theta_max_deg = PRESET_TRUNC_DEG(ip)
    if (trunc_levels == IUNSET) trunc_levels = PRESET_TRUNC_LEVELS(ip)
    if (cf_tau_min == UNSET) cf_tau_min = PRESET_CF_TAU(ip)
    if (diffusion == UNSET) diffusion = PRESET_DIFF(ip)
    if (ddis_eps == UNSET) ddis_eps = PRESET_DDIS(ip)
    call require(within(zeta_min, 0.0_wp, BIG), CTX, 'zeta_min', zeta_min, &
                 'must be >= 0 (0 = off)', error)
    call require(within(trunc_theta_max_deg, 0.0_wp, 89.0_wp), CTX, 'trunc_theta_max_deg', &
                 trunc_theta_max_deg, 'must be within [0, 89] (0 = no truncation)', error)
    call require(trunc_levels >= 1 .and. trunc_levels <= 16, CTX, 'trunc_levels', trunc_levels, &
                 'must be within 1..16 (1 = no truncation)', error)
    call require(within(trunc_peak, SMALL, BIG), CTX, 'trunc_peak', trunc_peak, 'must be > 0', &
                 error)
    call require(within(cf_tau_min, 0.0_wp, 1.0e6_wp), CTX, 'cf_tau_min', cf_tau_min, &
                 'must be within [0, 1e6] (0 = no collision forcing)', error)
    call require(within(diffusion, 0.0_wp, 1.0e6_wp), CTX, 'diffusion', diffusion, &
                 'must be within [0, 1e6] (0 = no numerical diffusion)', error)
    call require(within(ddis_eps, 0.0_wp, 0.9_wp), CTX, 'ddis_eps', ddis_eps, &
                 'must be within [0, 0.9] (0 = no directional importance sampling)', error)
    call require(diffusion_max >= 0 .and. diffusion_max <= 1000, CTX, 'diffusion_max', &
                 diffusion_max, 'must be within 0..1000 [columns]', error)
    if (allocated(error)) return
    if (trunc_levels == 1 .or. trunc_theta_max_deg == 0.0_wp) then
      trunc_levels = 1
      trunc_theta_max_deg = 0.0_wp
    end if
    cfg%zeta_min = zeta_min
    cfg%trunc_theta_max_deg = trunc_theta_max_deg
    cfg%trunc_levels = trunc_levels
    cfg%trunc_peak = trunc_peak
    cfg%cf_tau_min = cf_tau_min
    cfg%diffusion = diffusion
    cfg%diffusion_max = diffusion_max
    cfg%ddis_eps = ddis_eps
    call require(within(rr_weight, SMALL, BIG), CTX, 'rr_weight', rr_weight, 'must be > 0', error)
    call require(within(rr_threshold, 0.0_wp, rr_weight), CTX, 'rr_threshold', rr_threshold, &
                 'must be within [0, rr_weight = '//str(rr_weight)//']', error)
    if (.not. allocated(error) .and. rr_threshold > 0.0_wp) then
      call require(rr_weight <= RR_RATIO_MAX*rr_threshold, CTX, 'rr_weight', rr_weight, &
                   'must be <= '//str(RR_RATIO_MAX)//' x rr_threshold = '//str(rr_threshold)// &
                   ': a photon below rr_threshold survives the roulette with probability '// &
                   'at most rr_threshold/rr_weight = '//str(rr_threshold/rr_weight)// &
                   ', so nearly every photon is killed and the few survivors, of weight '// &
                   'rr_weight, dominate the result (set rr_threshold = 0 for no roulette)', error)
    end if
    call require(within(sv_fsupg, SMALL, BIG) .and. within(sv_fsupi, SMALL, BIG), CTX, &
                 'sv_fsupg and sv_fsupi', rule='must be > 0', error=error)
    call require(sv_max_layers >= 1, CTX, 'sv_max_layers', sv_max_layers, 'must be >= 1', error)
    cfg%rr_threshold = rr_threshold
    cfg%rr_weight = rr_weight
    cfg%use_supervoxels = use_supervoxels
    cfg%sv_fsupg = sv_fsupg
    cfg%sv_fsupi = sv_fsupi
    cfg%sv_max_layers = sv_max_layers
    cfg%use_1d_layers = use_1d_layers
    cfg%use_absorbing_layers = use_absorbing_layers
    cfg%use_exact_thermal = use_exact_thermal
    cfg%stratify_source = stratify_source
    ip = absorption_estimator_code(absorption_estimator)
    call require(ip >= 0, CTX, 'absorption_estimator', absorption_estimator, 'must be one of '// &
                 join(ABS_ESTIMATOR_NAMES), error)
    if (ip >= 0) cfg%absorption_estimator = ABS_ESTIMATOR_NAMES(ip)
  contains
    !> Read one assignment of &kumo_vr (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_vr, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_vr, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_vr

  subroutine read_radiance(unit, present, nz, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    integer, intent(in) :: nz
    type(radiance_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: rad_mu(MAX_DIR), rad_phi_deg(MAX_DIR)
    integer :: rad_levels(MAX_LAYERS + 1), ios, n, i
    logical :: radiance_maps
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_radiance: '
    namelist /kumo_radiance/ rad_mu, rad_phi_deg, rad_levels, radiance_maps
    rad_mu = UNSET
    rad_phi_deg = UNSET
    rad_levels = IUNSET
    radiance_maps = cfg%maps
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_radiance, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_radiance', present, ios, msg, error, probe)
    if (allocated(error)) return
    n = count(rad_mu /= UNSET)
    call require(all(rad_mu(n + 1:) == UNSET), CTX, 'rad_mu', rule='must be a list without gaps', &
                 error=error)
    call require(all(rad_phi_deg(n + 1:) == UNSET), CTX, 'rad_phi_deg', &
                 rule='has more entries than rad_mu ('//str(n)//')', error=error)
    if (allocated(error)) return
    do i = 1, n
      call require(within(abs(rad_mu(i)), 1.0e-6_wp, 1.0_wp), CTX, 'rad_mu('//str(i)//')', &
                   rad_mu(i), 'must satisfy 1e-6 <= |rad_mu| <= 1 (> 0: upward, < 0: downward)', &
                   error)
      if (allocated(error)) return
      if (rad_phi_deg(i) == UNSET) rad_phi_deg(i) = 0.0_wp
      call require(ieee_is_finite(rad_phi_deg(i)), CTX, 'rad_phi_deg('//str(i)//')', &
                   rule='must be finite', error=error)
      if (allocated(error)) return
    end do
    call level_list('kumo_radiance', 'rad_levels', rad_levels, nz, [0, nz], cfg%levels, error)
    if (allocated(error)) return
    cfg%mu = rad_mu(1:n)
    cfg%phi_deg = rad_phi_deg(1:n)
    cfg%maps = radiance_maps
  contains
    !> Read one assignment of &kumo_radiance (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_radiance, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_radiance, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_radiance

  subroutine read_camera(unit, present, atm, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(atmosphere_cfg_t), intent(in) :: atm
    type(camera_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: M = MAX_CAMERAS
    integer :: n_cameras, cam_npx(M), cam_npy(M), ios, i, n
    character(len=16) :: cam_kind(M)
    real(wp) :: cam_x(M), cam_y(M), cam_z(M), cam_look_zenith_deg(M), cam_look_azimuth_deg(M)
    real(wp) :: cam_roll_deg(M), cam_fov_deg(M), cam_width(M)
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_camera: '
    namelist /kumo_camera/ n_cameras, cam_kind, cam_x, cam_y, cam_z, cam_look_zenith_deg, &
      cam_look_azimuth_deg, cam_roll_deg, cam_fov_deg, cam_width, cam_npx, cam_npy
    n_cameras = 0
    cam_kind = 'pinhole'
    cam_x = 0.5_wp*atm%lx
    cam_y = 0.5_wp*atm%ly
    cam_z = UNSET
    cam_look_zenith_deg = 180.0_wp
    cam_look_azimuth_deg = 0.0_wp
    cam_roll_deg = 0.0_wp
    cam_fov_deg = 30.0_wp
    cam_width = atm%lx
    cam_npx = 64
    cam_npy = 64
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_camera, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_camera', present, ios, msg, error, probe)
    if (allocated(error)) return
    call require(n_cameras >= 0 .and. n_cameras <= M, CTX, 'n_cameras', n_cameras, &
                 'must be within 0..'//str(M), error)
    if (allocated(error)) return
    do i = 1, n_cameras
      cam_kind(i) = to_lower(adjustl(cam_kind(i)))
      call require(cam_kind(i) == 'pinhole' .or. cam_kind(i) == 'orthographic', CTX, &
                   'cam_kind('//str(i)//')', cam_kind(i), 'must be "pinhole" or "orthographic"', &
                   error)
      call require(cam_z(i) /= UNSET, CTX, 'cam_z('//str(i)//')', rule='must be given [m]', &
                   error=error)
      if (allocated(error)) return
      if (cam_npx(i) < 1 .or. cam_npy(i) < 1 .or. &
          int(cam_npx(i), i8)*cam_npy(i) > 16777216_i8) then
        call set_error(error, CTX//'cam_npx('//str(i)//') and cam_npy('//str(i)// &
                       ') must be >= 1, with at most 16777216 pixels')
        return
      end if
    end do
    n = n_cameras
    cfg%n = n
    cfg%kind = cam_kind(1:n)
    allocate (cfg%pos(3, n))
    cfg%pos(1, :) = cam_x(1:n)
    cfg%pos(2, :) = cam_y(1:n)
    cfg%pos(3, :) = cam_z(1:n)
    cfg%look_zenith_deg = cam_look_zenith_deg(1:n)
    cfg%look_azimuth_deg = cam_look_azimuth_deg(1:n)
    cfg%roll_deg = cam_roll_deg(1:n)
    cfg%fov_deg = cam_fov_deg(1:n)
    cfg%width = cam_width(1:n)
    cfg%npx = cam_npx(1:n)
    cfg%npy = cam_npy(1:n)
  contains
    !> Read one assignment of &kumo_camera (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_camera, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_camera, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_camera

  !> Cross-group checks.
  subroutine consolidate(cfg, error)
    type(config_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    integer :: np
    if (cfg%cloud%enabled .and. cfg%cloud%req%format == 'mcarats') then
      call complete_mcarats(cfg%atm, cfg%cloud)
    end if
    np = cfg%phase%n_phase
    call require(all(cfg%atm%phase1d >= 1 .and. cfg%atm%phase1d <= np), '&kumo_atmosphere: ', &
                 'phase1d values', rule='must be within 1..n_phase = '//str(np)//' (&kumo_phase)', &
                 error=error)
    call require(all(cfg%atm%phase3d >= 1 .and. cfg%atm%phase3d <= np), '&kumo_atmosphere: ', &
                 'phase3d values', rule='must be within 1..n_phase = '//str(np)//' (&kumo_phase)', &
                 error=error)
    if (allocated(error)) return
    if (cfg%spectral%enabled) then
      call spectral_checks(cfg, error)
      if (allocated(error)) return
    end if
    call require(.not. cfg%thermal%enabled .or. cfg%vr%absorption_estimator == 'collision', &
                 '&kumo_vr: ', 'absorption_estimator', cfg%vr%absorption_estimator, 'is for '// &
                 'solar runs only: with &kumo_thermal the net-exchange tallies score absorption '// &
                 'at collisions; set absorption_estimator = ''collision'' (the default)', error)
    if (allocated(error)) return
    if (cfg%thermal%enabled .and. cfg%thermal%include_sun .and. &
        cfg%source%solar_flux <= 0.0_wp) then
      call set_error(error, '&kumo_thermal: include_sun = .true. needs &kumo_source: '// &
                     'solar_flux > 0 [W m-2] (thermal results are in absolute units)')
    else if (cfg%thermal%enabled .and. cfg%thermal%wavenumber_lo < 0.0_wp .and. &
             cfg%thermal%wavelength_um <= 0.0_wp .and. &
             .not. allocated(cfg%thermal%planck_levels) .and. &
             cfg%source%wavelength_um <= 0.0_wp) then
      call set_error(error, '&kumo_thermal: no spectral interval: give wavenumber_lo and '// &
                     'wavenumber_hi [cm-1], or wavelength_um (here or in &kumo_source), or the '// &
                     'Planck radiances themselves (planck_levels, planck_surface)')
    else if (allocated(cfg%atm%air_density) .and. cfg%source%solar_flux <= 0.0_wp .and. &
             .not. cfg%thermal%enabled .and. .not. cfg%spectral%enabled) then
      call set_error(error, '&kumo_atmosphere: air_density is given but &kumo_source: '// &
                     'solar_flux is not; heating rates in K/day need both')
    else if (cfg%atm%rayleigh .and. cfg%source%wavelength_um <= 0.0_wp) then
      call set_error(error, '&kumo_atmosphere: rayleigh = .true. needs the wavelength '// &
                     '(&kumo_source wavelength_um)')
    else if (cfg%cloud%enabled .and. cfg%source%wavelength_um <= 0.0_wp .and. &
             .not. cfg%spectral%enabled .and. cfg%cloud%grid%content /= CLOUD_OPTICS .and. &
             cfg%cloud%grid%content /= CLOUD_MCARATS) then
      call set_error(error, '&kumo_cloud: the cloud file ('//trim(cfg%cloud%req%format)// &
                     ') gives no optical properties; kumo computes them for the wavelength '// &
                     'in &kumo_source wavelength_um, which is not given')
    end if
  end subroutine consolidate

  !> Broadband runs: what they do not combine with (yet), and F0 = the total solar irradiance
  !> (the results are then in W m-2 with the usual normalisation by mu0 F0).
  subroutine spectral_checks(cfg, error)
    type(config_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), parameter :: CTX = '&kumo_spectral: '
    call require(.not. cfg%thermal%enabled, CTX, 'spectral', rule='= .true. cannot be '// &
                 'combined with &kumo_thermal: a longwave k-distribution file makes the run '// &
                 'thermal, with t_surface here and the temperatures of the gas profile', error=error)
    call require(.not. cfg%atm%rayleigh, CTX, 'spectral', rule='= .true. takes Rayleigh '// &
                 'scattering from the k-distribution: set &kumo_atmosphere rayleigh = .false.', &
                 error=error)
    call require(cfg%source%solar_flux <= 0.0_wp, CTX, 'spectral', rule='= .true. takes the '// &
                 'solar flux from tsi: leave &kumo_source solar_flux unset (it is '// &
                 str(cfg%source%solar_flux)//' W m-2)', error=error)
    call require(cfg%source%wavelength_um <= 0.0_wp, CTX, 'spectral', rule='= .true. is '// &
                 'broadband: leave &kumo_source wavelength_um unset (it is '// &
                 str(cfg%source%wavelength_um)//' um)', error=error)
    call require(cfg%vr%use_1d_layers, CTX, 'spectral', rule='= .true. needs &kumo_vr '// &
                 'use_1d_layers = .true.', error=error)
    call require(cfg%cam%n == 0, CTX, 'spectral', rule='= .true.: cameras are not available '// &
                 'in broadband runs yet', error=error)
    if (allocated(cfg%rad%mu)) call require(size(cfg%rad%mu) == 0, CTX, 'spectral', &
                                            rule='= .true.: radiances are not available in '// &
                                            'broadband runs yet', error=error)
    if (allocated(error)) return
    cfg%source%solar_flux = cfg%spectral%tsi
  end subroutine spectral_checks

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

  !> &kumo_spectral: broadband runs, shortwave or longwave as the k-distribution file is. The group's presence switches them on (spectral =
  !> .false. keeps them off). The gas profile is a standard atmosphere at the levels of
  !> &kumo_atmosphere (`profile`) or level pressures and temperatures given here; water vapour
  !> per layer is always given; ozone per layer optionally.
  subroutine read_spectral(unit, present, nml_path, nz, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    character(len=*), intent(in) :: nml_path
    integer, intent(in) :: nz
    type(spectral_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: p_levels(MAX_LAYERS + 1), t_levels(MAX_LAYERS + 1), p_layers(MAX_LAYERS), &
                t_layers(MAX_LAYERS), h2o_vmr(MAX_LAYERS), o3_vmr(MAX_LAYERS)
    real(wp) :: tsi, floor_share, t_surface
    character(len=PATH_LEN) :: kdist_file, cloud_optics_file
    character(len=16) :: profile
    character(len=8) :: liquid_optics, ice_roughness
    character(len=16) :: gas_state
    integer :: gpoint
    logical :: spectral
    integer :: ios, kind, i
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_spectral: '
    type(error_t), allocatable :: err
    namelist /kumo_spectral/ spectral, kdist_file, profile, p_levels, t_levels, p_layers, &
      t_layers, h2o_vmr, o3_vmr, tsi, floor_share, t_surface, liquid_optics, cloud_optics_file, &
      ice_roughness, gas_state, gpoint
    spectral = present
    kdist_file = cfg%kdist_file
    profile = cfg%profile
    p_levels = UNSET
    t_levels = UNSET
    p_layers = UNSET
    t_layers = UNSET
    h2o_vmr = UNSET
    o3_vmr = UNSET
    tsi = cfg%tsi
    floor_share = cfg%floor_share
    t_surface = cfg%t_surface
    liquid_optics = cfg%liquid_optics
    cloud_optics_file = cfg%cloud_optics_file
    ice_roughness = cfg%ice_roughness
    gas_state = cfg%gas_state
    gpoint = cfg%gpoint
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_spectral, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_spectral', present, ios, msg, error, probe)
    if (allocated(error)) return
    cfg%enabled = spectral
    if (.not. spectral) return
    call require(len_trim(kdist_file) > 0, CTX, 'kdist_file', &
                 rule='is needed: an RRTMGP k-distribution, shortwave (rrtmgp-gas-sw-g112.nc or '// &
                 'rrtmgp-gas-sw-g224.nc) or longwave (rrtmgp-gas-lw-g128.nc or '// &
                 'rrtmgp-gas-lw-g256.nc); scripts/fetch-rrtmgp.sh fetches them', error=error)
    if (t_surface /= cfg%t_surface) call require(within(t_surface, SMALL, BIG), CTX, &
                                                 't_surface', t_surface, 'must be finite and '// &
                                                 '> 0 [K] (surface temperature, longwave)', error)
    call require(within(tsi, SMALL, BIG), CTX, 'tsi', tsi, &
                 'must be finite and > 0 [W m-2] (total solar irradiance)', error)
    call require(within(floor_share, 0.0_wp, nearest(1.0_wp, -1.0_wp)), CTX, 'floor_share', &
                 floor_share, 'must satisfy 0 <= floor_share < 1', error)
    call require(liquid_optics == 'mie' .or. liquid_optics == 'rrtmgp', CTX, 'liquid_optics', &
                 liquid_optics, 'must be ''mie'' (kumo''s band-averaged Mie tables) or '// &
                 '''rrtmgp'' (RRTMGP''s cloud-optics table)', error)
    call require(ice_roughness == 'smooth' .or. ice_roughness == 'medium' .or. &
                 ice_roughness == 'rough', CTX, 'ice_roughness', ice_roughness, 'must be '// &
                 '''smooth'', ''medium'' or ''rough'' (the ice-crystal surfaces of RRTMGP''s '// &
                 'ice optics)', error)
    call require(gas_state == 'cloud_file' .or. gas_state == 'profile', CTX, 'gas_state', &
                 gas_state, 'must be ''cloud_file'' (temperature, pressure and water vapour of '// &
                 'the &kumo_cloud file in its layers, where it has them) or ''profile''', error)
    call require(gpoint >= 0, CTX, 'gpoint', gpoint, 'must be 0 (every g-point) or the '// &
                 'index of one g-point of the k-distribution', error)
    if (allocated(error)) return
    if (len_trim(profile) > 0) then
      call std_atmosphere_kind_from_name(profile, kind, err)
      if (allocated(err)) then
        call set_error(error, CTX//'profile: '//err%message)
        return
      end if
      call require(count(p_levels /= UNSET) + count(t_levels /= UNSET) + &
                   count(p_layers /= UNSET) + count(t_layers /= UNSET) == 0, CTX, 'profile', &
                   profile, 'cannot be given with p_levels, t_levels, p_layers or t_layers: '// &
                   'a standard atmosphere or a sounding', error)
    else
      call level_values('p_levels', p_levels, nz + 1, 'pressures [Pa] (levels 0..nz)', &
                        SMALL, cfg%p_levels)
      call level_values('t_levels', t_levels, nz + 1, 'temperatures [K] (levels 0..nz)', &
                        SMALL, cfg%t_levels)
      if (allocated(error)) return
      do i = 2, nz + 1
        call require(cfg%p_levels(i) < cfg%p_levels(i - 1), CTX, 'p_levels('//str(i)//')', &
                     cfg%p_levels(i), 'must be below p_levels('//str(i - 1)//') = '// &
                     str(cfg%p_levels(i - 1))//' Pa: pressure falls from the surface up', error)
      end do
      if (count(p_layers /= UNSET) > 0) call level_values('p_layers', p_layers, nz, &
                                                         'pressures [Pa] (layers 1..nz)', SMALL, cfg%p_layers)
      if (count(t_layers /= UNSET) > 0) call level_values('t_layers', t_layers, nz, &
                                                         'temperatures [K] (layers 1..nz)', SMALL, cfg%t_layers)
      if (allocated(error)) return
      if (allocated(cfg%p_layers)) then
        do i = 1, nz
          call require(cfg%p_layers(i) <= cfg%p_levels(i) .and. &
                       cfg%p_layers(i) >= cfg%p_levels(i + 1), CTX, 'p_layers('//str(i)//')', &
                       cfg%p_layers(i), 'must lie between its levels '// &
                       str(cfg%p_levels(i))//' and '//str(cfg%p_levels(i + 1))//' Pa', error)
        end do
      end if
    end if
    call require(count(h2o_vmr /= UNSET) > 0, CTX, 'h2o_vmr', rule='is needed: the water '// &
                 'vapour of each layer 1..nz [mol/mol of dry air] (0 for a dry atmosphere)', &
                 error=error)
    if (allocated(error)) return
    call level_values('h2o_vmr', h2o_vmr, nz, 'volume mixing ratios (layers 1..nz)', 0.0_wp, &
                      cfg%h2o_vmr)
    if (count(o3_vmr /= UNSET) > 0) call level_values('o3_vmr', o3_vmr, nz, &
                                                     'volume mixing ratios (layers 1..nz)', 0.0_wp, cfg%o3_vmr)
    if (allocated(error)) return
    cfg%kdist_file = kdist_file
    cfg%kdist_path = resolve_path(kdist_file, nml_path)
    cfg%profile = profile
    cfg%tsi = tsi
    cfg%floor_share = floor_share
    cfg%t_surface = t_surface
    cfg%liquid_optics = liquid_optics
    cfg%ice_roughness = ice_roughness
    cfg%gas_state = gas_state
    cfg%gpoint = gpoint
    cfg%cloud_optics_file = cloud_optics_file
    if (len_trim(cloud_optics_file) > 0) cfg%cloud_optics_path = resolve_path(cloud_optics_file, &
                                                                             nml_path)
  contains
    !> n values of `name`, without gaps, each finite and >= lo.
    subroutine level_values(name, given, n, what, lo, out)
      character(len=*), intent(in) :: name, what
      real(wp), intent(in) :: given(:)
      integer, intent(in) :: n
      real(wp), intent(in) :: lo
      real(wp), allocatable, intent(out) :: out(:)
      integer :: m, j
      if (allocated(error)) return
      m = count(given /= UNSET)
      if (m == n .and. any(given(n + 1:) /= UNSET)) then
        ! as many values as needed, but not at positions 1..n (e.g. a comment right after
        ! "name =" reads as an empty first value)
        call require(.false., CTX, name, rule='needs '//str(n)//' '//what//' at positions '// &
                     '1..'//str(n)//'; '//str(m)//' are given, the last at position '// &
                     str(findloc(given /= UNSET, .true., back=.true., dim=1))//' (an empty '// &
                     'value, e.g. a comment right after "'//name//' =", takes position 1)', &
                     error=error)
      else
        call require(m == n .and. all(given(n + 1:) == UNSET), CTX, name, rule='needs '// &
                     str(n)//' '//what//', '//str(m)//' given', error=error)
      end if
      do j = 1, min(m, n)
        call require(within(given(j), lo, BIG), CTX, name//'('//str(j)//')', given(j), &
                     'must be finite and >= '//str(lo), error)
      end do
      if (.not. allocated(error)) out = given(1:n)
    end subroutine level_values
    !> Read one assignment of &kumo_spectral (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_spectral, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_spectral, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_spectral

  !> The grid of an MCARaTS 3-D region, which the binary file lacks, from &kumo_atmosphere:
  !> column widths lx/nx, ly/ny, the layer edges of layers k3d_bottom .. k3d_bottom + nz3 - 1,
  !> and the absorption of the 1-D components there (the gas absorption the file's perturbation
  !> is added to).
  subroutine complete_mcarats(atm, cloud)
    type(atmosphere_cfg_t), intent(in) :: atm
    type(cloud_cfg_t), intent(inout) :: cloud
    integer :: k0, k
    k0 = atm%k3d_bottom
    associate (m => cloud%req%mcarats)
      m%nx = atm%nx
      m%ny = atm%ny
      m%nz3 = atm%nz3
      m%dx = atm%lx/atm%nx
      m%dy = atm%ly/atm%ny
      m%k3d_bottom = k0
      ! atm%z(1:nz+1) holds levels 0..nz
      if (allocated(m%z)) deallocate (m%z)
      allocate (m%z(0:atm%nz3))
      m%z(:) = atm%z(k0:k0 + atm%nz3)
      if (allocated(m%abs1d)) deallocate (m%abs1d)
      allocate (m%abs1d(atm%nz3))
      do k = 1, atm%nz3
        m%abs1d(k) = sum(atm%ext1d(k0 + k - 1, :)*(1.0_wp - atm%ssa1d(k0 + k - 1, :)))
      end do
      cloud%grid%nx = m%nx
      cloud%grid%ny = m%ny
      cloud%grid%nz = m%nz3
      cloud%grid%dx = m%dx
      cloud%grid%dy = m%dy
      if (allocated(cloud%grid%z)) deallocate (cloud%grid%z)
      allocate (cloud%grid%z(0:m%nz3))
      cloud%grid%z(:) = m%z
    end associate
  end subroutine complete_mcarats

  !> The effective configuration as 'group.name = value' lines, for the log and the output file.
  function config_echo(cfg) result(text)
    type(config_t), intent(in) :: cfg
    character(len=:), allocatable :: text
    character(len=1), parameter :: nl = new_line('a')
    integer :: i
    text = 'kumo_control.n_photons_per_batch = '//str(cfg%control%n_photons_per_batch)//nl// &
           'kumo_control.n_batches = '//str(cfg%control%n_batches)//nl// &
           'kumo_control.seed = '//str(cfg%control%seed)//nl// &
           'kumo_control.target_rel_error = '//str(cfg%control%target_rel_error)//nl// &
           'kumo_control.target_output = '//trim(cfg%control%target_output)//nl// &
           'kumo_control.max_photons = '//str(cfg%control%max_photons)//nl// &
           'kumo_control.max_events = '//str(cfg%control%max_events)//nl// &
           'kumo_control.mode_3d = '//trim(cfg%control%mode_3d)//nl// &
           'kumo_control.p3d_orders = '//str(cfg%control%p3d_orders)//nl
    if (cfg%control%checkpoint_interval > 0.0_wp) text = text// &
      'kumo_control.checkpoint_interval = '//str(cfg%control%checkpoint_interval)//nl
    text = text//'kumo_atmosphere.nz = '//str(cfg%atm%nz)//nl// &
           'kumo_atmosphere.z_levels = '//join(cfg%atm%z)//nl// &
           'kumo_atmosphere.lx = '//str(cfg%atm%lx)//nl// &
           'kumo_atmosphere.ly = '//str(cfg%atm%ly)//nl// &
           'kumo_atmosphere.n_components = '//str(cfg%atm%n_components)//nl
    do i = 1, cfg%atm%n_components
      text = text//'kumo_atmosphere.ext1d(:,'//str(i)//') = '//join(cfg%atm%ext1d(:, i))//nl// &
             'kumo_atmosphere.ssa1d(:,'//str(i)//') = '//join(cfg%atm%ssa1d(:, i))//nl// &
             'kumo_atmosphere.phase1d(:,'//str(i)//') = '//join(cfg%atm%phase1d(:, i))//nl
    end do
    text = text//'kumo_atmosphere.scene_file = '//trim(cfg%atm%scene_file)//nl// &
           'kumo_atmosphere.k3d_bottom = '//str(cfg%atm%k3d_bottom)//nl// &
           'kumo_atmosphere.nx = '//str(cfg%atm%nx)//nl// &
           'kumo_atmosphere.ny = '//str(cfg%atm%ny)//nl// &
           'kumo_atmosphere.nz3 = '//str(cfg%atm%nz3)//nl// &
           'kumo_atmosphere.n_components_3d = '//str(cfg%atm%n_components_3d)//nl// &
           'kumo_atmosphere.phase3d = '//join(cfg%atm%phase3d)//nl
    if (allocated(cfg%atm%air_density)) text = text//'kumo_atmosphere.air_density = '// &
                                               join(cfg%atm%air_density)//nl
    text = text//'kumo_atmosphere.rayleigh = '//merge('T', 'F', cfg%atm%rayleigh)//nl
    if (cfg%atm%rayleigh) text = text// &
      'kumo_atmosphere.rayleigh_profile = '//trim(cfg%atm%rayleigh_profile)//nl// &
      'kumo_atmosphere.co2_ppm = '//str(cfg%atm%co2_ppm)//nl// &
      'kumo_atmosphere.latitude_deg = '//str(cfg%atm%latitude_deg)//nl// &
      'kumo_atmosphere.rayleigh_depol = '//str(cfg%atm%rayleigh_depol)//nl
    if (allocated(cfg%atm%p_levels)) text = text//'kumo_atmosphere.pressure_levels_hpa = '// &
                                            join(0.01_wp*cfg%atm%p_levels)//nl
    if (cfg%cloud%enabled) text = text// &
      'kumo_cloud.cloud_file = '//trim(cfg%cloud%file)//nl// &
      'kumo_cloud.cloud_format = '//trim(cfg%cloud%req%format)//nl// &
      'kumo_cloud.grid = '//str(cfg%cloud%grid%nx)//' x '//str(cfg%cloud%grid%ny)//' x '// &
      str(cfg%cloud%grid%nz)//' voxels of '//str(cfg%cloud%grid%dx)//' x '// &
      str(cfg%cloud%grid%dy)//' m, levels '//str(cfg%atm%k3d_bottom - 1)//'..'// &
      str(cfg%atm%k3d_bottom - 1 + cfg%atm%nz3)//nl// &
      'kumo_cloud.les_time_index = '//str(cfg%cloud%req%time_index)//nl// &
      'kumo_cloud.droplet_number_cm3 = '//str(cfg%cloud%req%droplet_number_cm3)//nl// &
      'kumo_cloud.size_distribution = '//trim(cfg%cloud%size_distribution)//nl// &
      'kumo_cloud.v_eff = '//str(cfg%cloud%v_eff)//nl// &
      'kumo_cloud.reff_min_um = '//str(cfg%cloud%reff_min_um)//nl// &
      'kumo_cloud.reff_max_um = '//str(cfg%cloud%reff_max_um)//nl// &
      'kumo_cloud.n_reff = '//str(cfg%cloud%n_reff)//nl// &
      'kumo_cloud.mie_cache = '//trim(cfg%cloud%mie_cache)//nl// &
      'kumo_cloud.ice_optics_file = '//trim(cfg%cloud%ice_optics_file)//nl
    if (cfg%cloud%enabled .and. cfg%cloud%req%format == 'mcarats') then
      associate (m => cfg%cloud%req%mcarats)
        text = text//'kumo_cloud.mcarats_np3d = '//given(m%np3d, 0)//nl// &
               'kumo_cloud.mcarats_nkd = '//given(m%nkd, 0)//nl// &
               'kumo_cloud.mcarats_mtprof = '//given(m%mtprof, -1)//nl// &
               'kumo_cloud.mcarats_idread = '//str(m%idread)//nl// &
               'kumo_cloud.mcarats_ikd = '//str(m%ikd)//nl// &
               'kumo_cloud.mcarats_phase_file = '//trim(cfg%cloud%mcarats_phase_file)//nl// &
               'kumo_cloud.mcarats_nang = '//given(m%nang, 0)//nl// &
               'kumo_cloud.mcarats_npf = '//given(m%npf, 0)//nl
      end associate
    end if
    text = text//'kumo_atmosphere.cp_air = '//str(cfg%atm%cp_air)//nl// &
           'kumo_phase.n_phase = '//str(cfg%phase%n_phase)//nl
    do i = 1, cfg%phase%n_phase
      text = text//'kumo_phase('//str(i)//') = '//trim(cfg%phase%kind_name(i))// &
             ' g='//str(cfg%phase%g(i))
      if (len_trim(cfg%phase%file(i)) > 0) text = text//' file='//trim(cfg%phase%file(i))
      text = text//nl
    end do
    text = text//'kumo_phase.n_table = '//str(cfg%phase%n_table)//nl// &
           'kumo_surface.albedo = '//str(cfg%surface%albedo)//nl// &
           'kumo_surface.albedo_file = '//trim(cfg%surface%albedo_file)//nl// &
           'kumo_surface.albedo_var = '//trim(cfg%surface%albedo_var)//nl// &
           'kumo_surface.brdf_file = '//trim(cfg%surface%brdf_file)//nl// &
           'kumo_surface.brdf = '//trim(cfg%surface%brdf)//nl// &
           'kumo_surface.brdf_param = '//str(cfg%surface%brdf_param(1))//', '// &
           str(cfg%surface%brdf_param(2))//', '//str(cfg%surface%brdf_param(3))//', '// &
           str(cfg%surface%brdf_param(4))//', '//str(cfg%surface%brdf_param(5))//nl// &
           'kumo_surface.wind_speed = '//str(cfg%surface%wind_speed)//nl// &
           'kumo_surface.surface_file = '//trim(cfg%surface%surface_file)//nl// &
           'kumo_surface.surface_format = '//trim(cfg%surface%surface_format)//nl// &
           'kumo_surface.surface_nxb = '//str(cfg%surface%surface_nxb)//nl// &
           'kumo_surface.surface_nyb = '//str(cfg%surface%surface_nyb)//nl// &
           'kumo_surface.surface_mbrdf = '//join(cfg%surface%surface_mbrdf)//nl// &
           'kumo_surface.surface_idread = '//str(cfg%surface%surface_idread)//nl// &
           'kumo_source.sza_deg = '//str(cfg%source%sza_deg)//nl// &
           'kumo_source.phi0_deg = '//str(cfg%source%phi0_deg)//nl// &
           'kumo_source.solar_flux = '//str(cfg%source%solar_flux)//nl// &
           'kumo_source.wavelength_um = '//str(cfg%source%wavelength_um)//nl// &
           'kumo_output.file = '//trim(cfg%output%file)//nl// &
           'kumo_output.flux_levels = '//join(cfg%output%flux_levels)//nl// &
           'kumo_output.column_fluxes = '//merge('T', 'F', cfg%output%column_fluxes)//nl// &
           'kumo_output.voxel_absorption = '//merge('T', 'F', cfg%output%voxel_absorption)//nl// &
           'kumo_output.deflate_level = '//str(cfg%output%deflate_level)//nl// &
           'kumo_vr.rr_threshold = '//str(cfg%vr%rr_threshold)//nl// &
           'kumo_vr.rr_weight = '//str(cfg%vr%rr_weight)//nl// &
           'kumo_vr.use_supervoxels = '//merge('T', 'F', cfg%vr%use_supervoxels)//nl// &
           'kumo_vr.stratify_source = '//merge('T', 'F', cfg%vr%stratify_source)//nl// &
           'kumo_vr.sv_fsupg = '//str(cfg%vr%sv_fsupg)//nl// &
           'kumo_vr.sv_fsupi = '//str(cfg%vr%sv_fsupi)//nl// &
           'kumo_vr.sv_max_layers = '//str(cfg%vr%sv_max_layers)//nl// &
           'kumo_vr.use_1d_layers = '//merge('T', 'F', cfg%vr%use_1d_layers)//nl// &
           'kumo_vr.use_absorbing_layers = '//merge('T', 'F', cfg%vr%use_absorbing_layers)//nl// &
           'kumo_vr.vr_preset = '//trim(cfg%vr%preset)//nl// &
           'kumo_vr.zeta_min = '//str(cfg%vr%zeta_min)//nl// &
           'kumo_vr.trunc_theta_max_deg = '//str(cfg%vr%trunc_theta_max_deg)//nl// &
           'kumo_vr.trunc_levels = '//str(cfg%vr%trunc_levels)//nl// &
           'kumo_vr.trunc_peak = '//str(cfg%vr%trunc_peak)//nl// &
           'kumo_vr.cf_tau_min = '//str(cfg%vr%cf_tau_min)//nl// &
           'kumo_vr.diffusion = '//str(cfg%vr%diffusion)//nl// &
           'kumo_vr.diffusion_max = '//str(cfg%vr%diffusion_max)//nl// &
           'kumo_vr.ddis_eps = '//str(cfg%vr%ddis_eps)//nl
    ! echoed only when changed, so that the configuration attribute of other runs stays as it was
    if (.not. cfg%vr%use_exact_thermal) text = text//'kumo_vr.use_exact_thermal = F'//nl
    if (cfg%vr%absorption_estimator /= 'collision') text = text// &
      'kumo_vr.absorption_estimator = '//trim(cfg%vr%absorption_estimator)//nl
    if (allocated(cfg%rad%mu)) text = text// &
      'kumo_radiance.rad_mu = '//join(cfg%rad%mu)//nl// &
      'kumo_radiance.rad_phi_deg = '//join(cfg%rad%phi_deg)//nl// &
      'kumo_radiance.rad_levels = '//join(cfg%rad%levels)//nl// &
      'kumo_radiance.radiance_maps = '//merge('T', 'F', cfg%rad%maps)//nl
    text = text//'kumo_camera.n_cameras = '//str(cfg%cam%n)//nl
    do i = 1, cfg%cam%n
      text = text//'kumo_camera('//str(i)//') = '//trim(cfg%cam%kind(i))//' at '// &
             join(cfg%cam%pos(:, i))//' look '//str(cfg%cam%look_zenith_deg(i))//' '// &
             str(cfg%cam%look_azimuth_deg(i))//' roll '//str(cfg%cam%roll_deg(i))//' fov '// &
             str(cfg%cam%fov_deg(i))//' width '//str(cfg%cam%width(i))//' pixels '// &
             str(cfg%cam%npx(i))//' x '//str(cfg%cam%npy(i))//nl
    end do
    if (cfg%spectral%enabled) then
      text = text//'kumo_spectral.spectral = T'//nl// &
             'kumo_spectral.kdist_file = '//trim(cfg%spectral%kdist_file)//nl// &
             'kumo_spectral.tsi = '//str(cfg%spectral%tsi)//nl// &
             'kumo_spectral.floor_share = '//str(cfg%spectral%floor_share)//nl
      if (cfg%cloud%enabled) text = text// &
        'kumo_spectral.liquid_optics = '//trim(cfg%spectral%liquid_optics)//nl// &
        'kumo_spectral.ice_roughness = '//trim(cfg%spectral%ice_roughness)//nl// &
        'kumo_spectral.gas_state = '//trim(cfg%spectral%gas_state)//nl// &
        'kumo_spectral.gpoint = '//str(cfg%spectral%gpoint)//nl
      if (len_trim(cfg%spectral%cloud_optics_file) > 0) text = text// &
        'kumo_spectral.cloud_optics_file = '//trim(cfg%spectral%cloud_optics_file)//nl
      if (len_trim(cfg%spectral%profile) > 0) text = text// &
        'kumo_spectral.profile = '//trim(cfg%spectral%profile)//nl
      if (allocated(cfg%spectral%p_levels)) text = text// &
        'kumo_spectral.p_levels = '//join(cfg%spectral%p_levels)//nl// &
        'kumo_spectral.t_levels = '//join(cfg%spectral%t_levels)//nl
      if (allocated(cfg%spectral%p_layers)) text = text// &
        'kumo_spectral.p_layers = '//join(cfg%spectral%p_layers)//nl
      if (allocated(cfg%spectral%t_layers)) text = text// &
        'kumo_spectral.t_layers = '//join(cfg%spectral%t_layers)//nl
      text = text//'kumo_spectral.h2o_vmr = '//join(cfg%spectral%h2o_vmr)//nl
      if (allocated(cfg%spectral%o3_vmr)) text = text// &
        'kumo_spectral.o3_vmr = '//join(cfg%spectral%o3_vmr)//nl
    end if
    if (cfg%thermal%enabled) then
      text = text//'kumo_thermal.thermal = T'//nl
      if (allocated(cfg%thermal%t_levels)) text = text// &
        'kumo_thermal.t_levels = '//join(cfg%thermal%t_levels)//nl// &
        'kumo_thermal.t_surface = '//str(cfg%thermal%t_surface)//nl// &
        'kumo_thermal.t_top = '//str(cfg%thermal%t_top)//nl
      if (len_trim(cfg%thermal%t_surface_file) > 0) text = text// &
        'kumo_thermal.t_surface_file = '//trim(cfg%thermal%t_surface_file)//nl// &
        'kumo_thermal.t_surface_var = '//trim(cfg%thermal%t_surface_var)//nl
      if (allocated(cfg%thermal%planck_levels)) text = text// &
        'kumo_thermal.planck_levels = '//join(cfg%thermal%planck_levels)//nl// &
        'kumo_thermal.planck_surface = '//str(cfg%thermal%planck_surface)//nl// &
        'kumo_thermal.planck_top = '//str(cfg%thermal%planck_top)//nl
      if (cfg%thermal%wavenumber_lo >= 0.0_wp) text = text// &
        'kumo_thermal.wavenumber_lo = '//str(cfg%thermal%wavenumber_lo)//nl// &
        'kumo_thermal.wavenumber_hi = '//str(cfg%thermal%wavenumber_hi)//nl
      text = text//'kumo_thermal.wavelength_um = '//str(cfg%thermal%wavelength_um)//nl// &
             'kumo_thermal.include_sun = '//merge('T', 'F', cfg%thermal%include_sun)//nl// &
             'kumo_thermal.emission_floor = '//str(cfg%thermal%emission_floor)//nl
    end if
  end function config_echo

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
end module kumo_config
