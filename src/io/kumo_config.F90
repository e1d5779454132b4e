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
!> Each group is read and validated by a module of its own (src/io/config/kumo_config_<group>.F90,
!> `read_<group>`), on kumo_config_base (the types, limits and helpers the groups share); this
!> module holds read_config, the checks across groups (`consolidate`), the echo for the run
!> log and the list of input files, and exports the types.
!>
!> This module opens no file but the namelist. The one fact of another file that validation
!> needs, the grid of a &kumo_cloud file (its levels set or check z_levels, lx, ly, nx, ny,
!> nz3) and, for rayleigh_profile = 'cloud_file', its pressure profile, comes from the
!> `read_grid` procedure the caller passes (kumo_scene_setup's `load_config` reads it on rank 0
!> and broadcasts it); the fields of the inputs are read when the scene is built.
module kumo_config
  use kumo_config_base
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str, join
  use kumo_phase, only: PHASE_TABLE
  use kumo_math, only: within
  use kumo_cloud_input, only: CLOUD_OPTICS, CLOUD_MCARATS
  use kumo_nml_text, only: nml_group_t, nml_scan, closest_name
  use kumo_config_control, only: read_control, TARGET_NAMES, MODE_NAMES
  use kumo_config_atmosphere, only: read_atmosphere
  use kumo_config_cloud, only: read_cloud
  use kumo_config_phase, only: read_phase
  use kumo_config_surface, only: read_surface
  use kumo_config_source, only: read_source
  use kumo_config_output, only: read_output
  use kumo_config_vr, only: read_vr, PRESET_NAMES
  use kumo_config_radiance, only: read_radiance
  use kumo_config_camera, only: read_camera
  use kumo_config_thermal, only: read_thermal
  use kumo_config_spectral, only: read_spectral
  implicit none
  private
  public :: config_t, control_cfg_t, atmosphere_cfg_t, phase_cfg_t, surface_cfg_t, &
            source_cfg_t, output_cfg_t, vr_cfg_t, radiance_cfg_t, camera_cfg_t, cloud_cfg_t, &
            thermal_cfg_t, spectral_cfg_t, &
            read_config, config_echo, resolve_path, input_file_t, config_inputs, cloud_grid_reader
  public :: MAX_LAYERS, MAX_COMP, MAX_PHASE, MAX_DIR, MAX_CAMERAS, TARGET_NAMES, PRESET_NAMES, &
            MODE_NAMES
  public :: RAYLEIGH_LEVELS, RAYLEIGH_CLOUD_FILE

  character(len=16), parameter :: GROUP_NAMES(12) = &
    [character(len=16) :: 'kumo_control', 'kumo_atmosphere', 'kumo_phase', 'kumo_surface', &
     'kumo_source', 'kumo_output', 'kumo_vr', 'kumo_radiance', 'kumo_camera', 'kumo_cloud', &
     'kumo_thermal', 'kumo_spectral']

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
      k = findloc(GROUP_NAMES == groups(i)%name, .true., 1)
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

  !> Cross-group checks.
  subroutine consolidate(cfg, error)
    type(config_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    integer :: np, n_rad
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
    if (cfg%vr%similarity_theta_deg > 0.0_wp) then
      ! the scaled medium has the fluxes and absorption of the original one, not its radiances
      n_rad = cfg%cam%n
      if (allocated(cfg%rad%mu)) n_rad = n_rad + size(cfg%rad%mu)
      call require(n_rad == 0, '&kumo_vr: ', 'similarity_theta_deg', &
                   cfg%vr%similarity_theta_deg, 'is for fluxes and absorption: the scaled '// &
                   'medium does not give radiances; remove &kumo_radiance and the cameras or '// &
                   'set it to 0', error)
      call require(.not. cfg%thermal%enabled, '&kumo_vr: ', 'similarity_theta_deg', &
                   cfg%vr%similarity_theta_deg, 'is for solar runs only (not with '// &
                   '&kumo_thermal yet); set it to 0', error)
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

  !> Broadband runs: what they do not combine with, and F0 = the total solar irradiance
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
    if (allocated(error)) return
    cfg%source%solar_flux = cfg%spectral%tsi
  end subroutine spectral_checks

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
    if (.not. cfg%control%one_scene_per_node) text = text// &
      'kumo_control.one_scene_per_node = F'//nl
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
           'kumo_output.map_levels = '//join(cfg%output%map_level_list())//nl// &
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
    if (cfg%vr%similarity_theta_deg > 0.0_wp) text = text// &
      'kumo_vr.similarity_theta_deg = '//str(cfg%vr%similarity_theta_deg)//nl
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
      if (allocated(cfg%spectral%gas_names)) then
        if (size(cfg%spectral%gas_names) > 0) text = text// &
          'kumo_spectral.gas_names = '//join(cfg%spectral%gas_names)//nl// &
          'kumo_spectral.gas_vmr = '//join(cfg%spectral%gas_vmr)//nl
      end if
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
end module kumo_config
