! SPDX-License-Identifier: BSD-3-Clause
!> From a namelist to a scene. `load_config` parses and validates the namelist on every rank
!> (kumo_config), with the grid of a cloud file read on rank 0 and broadcast. `setup_scene`
!> turns the configuration into the scene_t the photon loop reads: phase functions, the
!> atmosphere (namelist layers, scene file or cloud file, Rayleigh layers), the surface
!> (albedo, BRDF or MCARaTS surface maps), the source, the detectors and the variance
!> reduction that serves them. Every input file is read on rank 0 and broadcast with one
!> pack-and-broadcast (`bundle_t` of kumo_bundle), so that all ranks hold the same arrays or
!> the same error, then built into the scene without MPI; a cloud file travels whole as a
!> `cloud_input_t`, its ice optics table and its water Mie table (read from the &kumo_cloud
!> mie_cache or computed, by rank 0 alone) as `mie_table_t`s (kumo_cloud_share): no other rank
!> opens an input file.
module kumo_scene_setup
  use, intrinsic :: iso_fortran_env, only: output_unit
  use, intrinsic :: iso_c_binding, only: c_ptr
  use kumo_kinds, only: wp, dp, vp, i8
  use kumo_constants, only: DEG2RAD, PI
  use kumo_error, only: error_t, set_error, add_context, str, join
  use kumo_phase, only: phase_t, new_phase_isotropic, new_phase_rayleigh, new_phase_hg, &
                        phase_from_table, new_phase_rayleigh_depol, PHASE_ISOTROPIC, &
                        PHASE_RAYLEIGH, PHASE_HG, PHASE_TABLE
  use kumo_atmosphere, only: atmosphere_t, atmosphere_options_t, atmosphere_init, EXT_MAX, &
                             atmosphere_begin, atmosphere_end, atmosphere_swap_background, &
                             atmosphere_set_truncation, atmosphere_put_layer, LAYER_CLEAR, &
                             atmosphere_refresh_truncation, &
                             LAYER_ABSORBING, LAYER_SCATTERING, voxel_storage_i, voxel_sync_i, &
                             similarity_tables, similarity_scale_1d, voxel_layer
  use kumo_std_atmosphere, only: std_atmosphere_profile
  use kumo_gas_optics, only: gas_kdist_t, gas_default_vmr, gas_index, GRAVITY_STD, &
                             MOLAR_MASS_DRY, MOLAR_MASS_H2O
  use kumo_les_netcdf, only: R_DRY_AIR
  use kumo_rrtmgp_file, only: read_rrtmgp_kdist
  use kumo_spectral, only: spectral_column_t, spectral_sw_column, spectral_lw_column, &
                           spectral_plan_t, spectral_plan_init, spectral_batch_t
  use kumo_thermal_column, only: thermal_column_t, thermal_column_init_layers, &
                                 thermal_column_fluxes_diffusivity
  use kumo_exact_column, only: exact_thermal_possible
  use kumo_truncation, only: truncation_t, truncation_init
  use kumo_camera, only: camera_t, camera_init, CAMERA_PINHOLE, CAMERA_ORTHOGRAPHIC, &
                         MAX_IMAGE_SHIFTS, camera_half_angle
  use kumo_local_estimate, only: detectors_init
  use kumo_local_estimate, only: detectors_bounds
  use kumo_surface, only: surface_t, surface_init, surface_init_brdf, surface_init_brdf_map
  use kumo_brdf, only: brdf_params_t, BRDF_NPAR, BRDF_NAMES, brdf_albedo_quad
  use kumo_source, only: solar_source, source_stratify
  use kumo_emission, only: emission_t, emission_init, emission_bind, emission_detach, &
                           emission_voxel_power_add, voxel_abs_t, voxel_abs_init
  use kumo_planck, only: spectral_band_t, band_from_wavenumbers, band_monochromatic_wavelength, &
                         band_radiance, band_units
  use kumo_vr, only: collision_forcing, ddis_phases, spiky_without_vr, SPIKY_PEAK, DDIS_CONE_DEG, &
                    absorption_estimator_code
  use kumo_scene, only: scene_t
  use kumo_config, only: config_t, resolve_path, read_config
  use kumo_config_spectral, only: kdist_location
  use kumo_cloud_input, only: cloud_input_t, cloud_request_t, CLOUD_WATER, CLOUD_EXT_REFF, &
                              CLOUD_MCARATS
  use kumo_cloud_share, only: read_cloud_on_root, mie_table_put, mie_table_get
  use kumo_mie, only: mie_table_t
  use kumo_bundle, only: bundle_t
  use kumo_cloud_scene, only: build_cloud_atmosphere, rayleigh_layers, cloud_temperature_t, ice_table, &
                              water_table, mcarats_scan_t, mcarats_scan, take_temperature
  use kumo_spectral_cloud, only: spectral_cloud_t, spectral_cloud_init, spectral_cloud_band, &
                                 spectral_cloud_put, spectral_cloud_place
  use kumo_supervoxel, only: supervoxel_grid_t
  use kumo_gas_state, only: gas_state_merge
  use kumo_rayleigh, only: depol_from_king, king_factor_air
  use kumo_textio, only: read_two_columns
  use kumo_netcdf, only: read_scene_3d, read_albedo_map, read_brdf_map, read_scene_temperature, &
                         read_temperature_map
  use kumo_mcarats_files, only: mcarats_surface_t, read_mcarats_surface, mcarats_surface_npsfc, &
                                mcarats_surface_brdf
  use kumo_parallel, only: par_is_root, par_size, par_rank, par_node_size, par_node_storage, &
                           par_node_sync, par_gather_i8, par_node_leader, par_node_window, &
                           par_node_rank
  implicit none
  private
  public :: load_config, setup_scene, spectral_scene_t, spectral_set_gpoint

  !> Radiance directions within this angle [deg] of the exact backscatter direction get a
  !> warning when forward peaks are truncated in a 3-D scene (setup_estimators)
  real(wp), parameter :: HOTSPOT_WARN_DEG = 5.0_wp
  !> Similarity-scaled truncation beyond this angle [deg] warns: the bias of the scaled fluxes
  !> grows quickly with the angle (docs/performance.md, similarity-scaled truncation for fluxes)
  real(wp), parameter :: SIMILARITY_WARN_DEG = 30.0_wp
  !> Collision forcing to a column optical depth beyond this warns (setup_estimators)
  real(wp), parameter :: CF_WARN_TAU = 100.0_wp
  !> Truncation of forward peaks beyond this angle [deg] (the standard preset's: the quick
  !> preset's 40 is biased by up to 2.7 % in directions the standard one keeps within 0.55 %)
  !> warns, and so do
  !> truncated radiance directions with |mu| below TRUNC_GRAZING_MU: the bias of truncated
  !> radiances grows with the angle and towards the horizon (measured against DISORT on
  !> Henyey-Greenstein slabs, docs/radiances.md, bench/truncation_angle.py)
  real(wp), parameter :: TRUNC_WARN_DEG = 30.0_wp
  real(wp), parameter :: TRUNC_GRAZING_MU = 0.5_wp
  !> ... for truncation angles above this [deg]: at 15 degrees no bias was measurable
  real(wp), parameter :: TRUNC_GRAZING_DEG = 15.0_wp
  !> [K] temperatures between 0 and this warn: colder than any layer or surface of the Earth's
  !> atmosphere (its coldest, the summer polar mesopause, is near 130 K), so most likely given
  !> in degrees Celsius
  real(wp), parameter :: T_COLD = 100.0_wp
  !> [m-1] layers and voxels that scatter more than this warn: a mean free path under 10 cm,
  !> ten times the densest clouds (about 1 m-1: 2 g m-3 of 5 um droplets, 3 LWC/(2 rho reff));
  !> extinction in km-1 behind an m-1 label is 1000 times too dense, and a photon in such a
  !> conservative voxel makes about (its optical size)^2 events (dense_scattering_warning)
  real(wp), parameter :: SCAT_WARN = 10.0_wp

  !> A broadband run (&kumo_spectral): the g-point sampling plan and the optics of the 1-D
  !> layers for every g-point (setup_spectral), which spectral_set_gpoint puts into the
  !> atmosphere before the g-point's photons are traced; in the longwave also each g-point's
  !> Planck sources and emission table (setup_spectral_emission).
  type :: spectral_scene_t
    logical :: on = .false.
    integer :: n_gpt = 0, nz = 0, ncomp = 0
    real(wp) :: tsi = 0.0_wp                      !! total solar irradiance [W m-2]
    real(wp) :: mu0 = 1.0_wp
    type(spectral_plan_t) :: plan                 !! energies S_g = mu0 F_g, probabilities
    type(spectral_batch_t) :: batch               !! the current batch's counts and weights
    real(wp), allocatable :: ext1(:, :)           !! (nz, n_gpt) total extinction [m-1]
    real(wp), allocatable :: omg1(:, :)           !! (nz, n_gpt) single-scattering albedo
    real(wp), allocatable :: csca1(:, :, :)       !! (ncomp, nz, n_gpt) cumulative fractions
    integer, allocatable :: layer_class(:, :)     !! (nz, n_gpt) LAYER_*
    ! longwave
    logical :: longwave = .false.
    logical :: exact = .false.                    !! no layer scatters: exact sums, no photons
    real(wp), allocatable :: src_bot(:, :)        !! (nz, n_gpt) Planck source, layer bottom
    real(wp), allocatable :: src_top(:, :)        !! (nz, n_gpt) Planck source, layer top
    real(wp), allocatable :: src_sfc(:)           !! (n_gpt) Planck source of the surface
    type(emission_t), allocatable :: em(:)        !! (n_gpt) emission table of each g-point
    type(emission_t) :: em_sum                    !! broadband totals, for the outputs
    ! 3-D scenes (scene file): the atmosphere is rebuilt per g-point from these
    logical :: three_d = .false.
    real(wp), allocatable :: z(:)                 !! (nz + 1) levels 0..nz [m], 1-based
    real(wp) :: lx = 0.0_wp, ly = 0.0_wp
    integer :: k3d_bottom = 0
    real(wp), allocatable :: ext1d(:, :), ssa1d(:, :)  !! (nz, ncomp - 2 or - 1) namelist layers
    integer, allocatable :: phase1d(:, :)
    real(wp), allocatable :: tau_abs(:, :), tau_ray(:, :)  !! (nz, n_gpt) gas per layer
    integer :: iray = 0                           !! Rayleigh phase function (shortwave)
    integer :: gpoint = 0                         !! one g-point alone (&kumo_spectral gpoint)
    !> the power [W m-2] the tallies are fractions of, as the outputs scale them: the plan's
    !> total, or mu0 TSI when one shortwave g-point is traced alone
    real(wp) :: norm = 0.0_wp
    type(phase_t), allocatable :: phases(:)
    type(atmosphere_options_t) :: aopts
    real(wp), allocatable :: ext3(:, :, :, :), ssa3(:, :, :, :)  !! the scene file's voxels
    integer, allocatable :: iph3(:, :, :, :)
    integer :: n3d(4) = 0                         !! their shape (every rank, also without them)
    real(wp) :: floor = 0.1_wp                    !! emission floor (longwave)
    real(dp), allocatable :: exact_buf(:)         !! the exact batch tallies, once computed
    integer(i8) :: exact_n = 0_i8                 !! for this batch size
    integer :: g_setup = 0                        !! g-point of the atmosphere after set-up
    integer, allocatable :: gpt_band(:)           !! (n_gpt) band of each g-point
    real(wp), allocatable :: band_wn(:, :)        !! (2, n_band) band limits [cm-1]
    ! cloud files (&kumo_cloud): the fields and their optics per band (kumo_spectral_cloud)
    logical :: cloud_on = .false.
    type(spectral_cloud_t) :: cloud
    type(supervoxel_grid_t) :: sv_layout          !! super-voxel blocks of the set-up's g-point
    integer :: atm_band = 0                       !! band of the atmosphere's cloud voxels
    !> what a switch to a band found (spectral_set_optics): its indices and weights checked, and
    !> (n3, n_gpt) the uniform layers after a switch to g-point g (uni_known)
    logical, allocatable :: band_checked(:), uni3(:, :), uni_known(:)
    !> longwave over a cloud file: the cloud's share of the voxels' absorption in band
    !> `va_band` (row sums), from which each g-point's emission table draws the voxels layer by
    !> layer without a sweep over them (gpoint_emission)
    type(voxel_abs_t) :: va
    integer :: va_band = 0
    !> several ranks: the cloud's voxels (and, over a scene file in the longwave, each
    !> g-point's emission table) lie in storage the ranks of a node share, which its first rank
    !> alone forms at every g-point switch (node_voxels, node_table); the ranks of a node then
    !> switch together
    logical :: node = .false.
    !> radiances and cameras (setup_scene, once the detectors exist): the truncation of the
    !> forward peaks, which a switch puts back into an atmosphere built anew and refreshes in
    !> the layers; collision forcing per g-point (cf, 0 until the first switch to it, from the
    !> g-point's own column); the isotropic phase function of emission's local estimates
    logical :: truncated = .false.
    type(truncation_t) :: trunc
    logical :: forcing = .false.
    real(wp) :: cf_tau_min = 0.0_wp
    real(wp), allocatable :: cf(:)
    integer :: iph_iso = 0
  end type spectral_scene_t

contains

  !> Read and validate the namelist `path` (its `text` when given, see read_config) on every
  !> rank, with the grid of a &kumo_cloud file read on rank 0 and broadcast
  !> (`cloud_grid_on_root`): the configuration of a run. With `local` = .true. the calling
  !> process reads the grid itself and talks to no other rank (`kumo --check` on rank 0).
  subroutine load_config(path, cfg, error, text, local)
    character(len=*), intent(in) :: path
    type(config_t), intent(out) :: cfg
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: text
    logical, intent(in), optional :: local
    logical :: alone
    alone = .false.
    if (present(local)) alone = local
    if (alone) then
      call read_config(path, cfg, error, text, read_grid=cloud_grid_here)
    else
      call read_config(path, cfg, error, text, read_grid=cloud_grid_on_root)
    end if
  end subroutine load_config

  !> The grid of a cloud file for read_config (kumo_config's `cloud_grid_reader`): rank 0 reads
  !> the columns, widths and layer edges (and the layer pressures when `req%pressure_profile`
  !> is set) and every rank gets them, or rank 0's error. Every rank calls it.
  subroutine cloud_grid_on_root(req, grid, error)
    type(cloud_request_t), intent(in) :: req
    type(cloud_input_t), intent(out) :: grid
    type(error_t), allocatable, intent(out) :: error
    call read_cloud_on_root(req, grid, error, grid_only=.true.)
  end subroutine cloud_grid_on_root

  !> `cloud_grid_on_root` for one process alone.
  subroutine cloud_grid_here(req, grid, error)
    type(cloud_request_t), intent(in) :: req
    type(cloud_input_t), intent(out) :: grid
    type(error_t), allocatable, intent(out) :: error
    call read_cloud_on_root(req, grid, error, grid_only=.true., alone=.true.)
  end subroutine cloud_grid_here

  !> Build the scene (phase functions, atmosphere, surface, source) from a configuration.
  !> Every rank calls it (rank 0 reads the input files and broadcasts them). With `per_node` =
  !> .true. (a run: kumo_driver's simulate) the ranks also build the scene together: on several
  !> ranks the voxel arrays of a monochromatic run are one copy per node, in the node's
  !> shared-memory window (cloud_on_ranks, scene_on_ranks); otherwise each process builds its
  !> own, as a test that rebuilds the scene on rank 0 alone needs.
  subroutine setup_scene(cfg, scene, error, spec, per_node)
    type(config_t), intent(in) :: cfg
    type(scene_t), intent(out) :: scene
    type(error_t), allocatable, intent(out) :: error
    !> broadband runs (&kumo_spectral): the g-point plan and optics (setup_spectral)
    type(spectral_scene_t), intent(out), optional :: spec
    logical, intent(in), optional :: per_node   !! the ranks build one scene per node (.false.)
    type(phase_t), allocatable :: phases(:)
    type(atmosphere_options_t) :: aopts
    real(wp), allocatable :: ang(:), val(:), ext3(:, :, :, :), ssa3(:, :, :, :), alb(:, :)
    type(brdf_params_t), allocatable :: bmap(:, :)
    integer, allocatable :: iph3(:, :, :, :), phase1d(:, :)
    integer :: i, n_out_liq, n_out_ice
    character(len=:), allocatable :: nml_path
    real(wp), allocatable :: ext1d(:, :), ssa1d(:, :), ray_ext(:), ray_rho(:)
    character(len=:), allocatable :: ray_notes
    real(wp) :: depol
    character(len=:), allocatable :: cloud_notes, cloud_warnings
    character(len=:), allocatable :: sfc_notes
    type(cloud_temperature_t) :: cloud_t
    logical :: on_node, shared, has_iph

    shared = .false.
    if (present(per_node)) shared = per_node .and. par_size() > 1
    nml_path = ''
    if (allocated(cfg%path)) nml_path = cfg%path
    allocate (phases(cfg%phase%n_phase))
    do i = 1, cfg%phase%n_phase
      select case (cfg%phase%kind(i))
      case (PHASE_ISOTROPIC)
        phases(i) = new_phase_isotropic()
      case (PHASE_RAYLEIGH)
        phases(i) = new_phase_rayleigh()
      case (PHASE_HG)
        phases(i) = new_phase_hg(cfg%phase%g(i), error)
      case (PHASE_TABLE)
        call phase_table_on_root(resolve_path(cfg%phase%file(i), nml_path), ang, val, error)
        if (.not. allocated(error)) phases(i) = phase_from_table(ang, val, cfg%phase%n_table, error)
      case default
        call set_error(error, 'unknown phase-function kind code '//str(cfg%phase%kind(i)))
      end select
      if (allocated(error)) then
        call add_context(error, '&kumo_phase: phase function '//str(i))
        return
      end if
    end do

    scene%notes = ''
    scene%warnings = ''
    ext1d = cfg%atm%ext1d
    ssa1d = cfg%atm%ssa1d
    phase1d = cfg%atm%phase1d
    if (allocated(cfg%atm%air_density)) scene%air_density = cfg%atm%air_density
    if (cfg%atm%rayleigh) then
      ! molecules: one more 1-D component with its own phase function. The profile's arrays
      ! that are not allocated (those of the other profiles) count as absent arguments.
      call rayleigh_layers(cfg%atm%z, cfg%source%wavelength_um, cfg%atm%rayleigh_profile, &
                           cfg%atm%co2_ppm, cfg%atm%latitude_deg, ray_ext, ray_rho, ray_notes, &
                           error, p_levels=cfg%atm%p_levels, z_file=cfg%cloud%grid%z, &
                           p_file=cfg%atm%p_cloud)
      if (allocated(error)) then
        call add_context(error, '&kumo_atmosphere rayleigh_profile = '''// &
                         trim(cfg%atm%rayleigh_profile)//'''')
        return
      end if
      depol = cfg%atm%rayleigh_depol
      if (depol < 0.0_wp) depol = depol_from_king(king_factor_air(cfg%source%wavelength_um, &
                                                                  cfg%atm%co2_ppm))
      phases = [phases, new_phase_rayleigh_depol(depol, error)]
      if (allocated(error)) then
        call add_context(error, '&kumo_atmosphere rayleigh_depol')
        return
      end if
      ext1d = reshape([ext1d, ray_ext], [cfg%atm%nz, size(ext1d, 2) + 1])
      ssa1d = reshape([ssa1d, spread(1.0_wp, 1, cfg%atm%nz)], [cfg%atm%nz, size(ssa1d, 2) + 1])
      phase1d = reshape([phase1d, spread(size(phases), 1, cfg%atm%nz)], &
                        [cfg%atm%nz, size(phase1d, 2) + 1])
      if (allocated(cfg%atm%p_cloud_source)) ray_notes = cfg%atm%p_cloud_source//'; '//ray_notes
      scene%notes = scene%notes//'Rayleigh scattering (Bodhaine et al. 1999), rayleigh_profile'// &
                    ' = '''//trim(cfg%atm%rayleigh_profile)//''': optical depth '// &
                    str(sum(ray_ext*(cfg%atm%z(2:) - cfg%atm%z(:cfg%atm%nz))))// &
                    ', depolarisation ratio '//str(depol)//new_line('a')// &
                    '  pressure from '//ray_notes//new_line('a')
      if (allocated(scene%air_density)) then
        scene%notes = scene%notes//'  layer air density (heating rates): air_density of '// &
                      '&kumo_atmosphere'//new_line('a')
      else
        scene%air_density = ray_rho
        scene%notes = scene%notes//'  layer air density (heating rates): (p_bottom - p_top)/'// &
                      '(g0 dz) of the same pressure, g0 = 9.80665 m s-2'//new_line('a')
      end if
    end if
    if (cfg%spectral%enabled) then
      if (.not. present(spec)) then
        call set_error(error, 'setup_scene: a broadband configuration (&kumo_spectral) needs '// &
                       'the spec argument')
        return
      end if
      call setup_spectral(cfg, ext1d, ssa1d, phase1d, phases, scene, spec, error)
      if (allocated(error)) return
    end if
    aopts%use_1d_layers = cfg%vr%use_1d_layers
    aopts%use_absorbing_layers = cfg%vr%use_absorbing_layers
    aopts%sv%enabled = cfg%vr%use_supervoxels
    aopts%sv%fsupg = cfg%vr%sv_fsupg
    aopts%sv%fsupi = cfg%vr%sv_fsupi
    aopts%sv%max_layers = cfg%vr%sv_max_layers
    aopts%similarity_deg = cfg%vr%similarity_theta_deg
    if (aopts%similarity_deg > 0.0_wp) scene%notes = scene%notes//'similarity-scaled '// &
      'truncation of forward peaks within '//str(cfg%vr%similarity_theta_deg)//' degrees '// &
      '(&kumo_vr similarity_theta_deg): the delta part f of each phase function leaves the '// &
      'extinction, tau'' = tau (1 - omega f), omega'' = omega (1 - f)/(1 - omega f); fluxes '// &
      'and absorption carry its small bias (docs/performance.md), and the direct beam holds '// &
      'the light of the cut peaks too'//new_line('a')
    if (aopts%similarity_deg > SIMILARITY_WARN_DEG) scene%warnings = scene%warnings// &
      'similarity_theta_deg = '//str(cfg%vr%similarity_theta_deg)//' is beyond '// &
      str(nint(SIMILARITY_WARN_DEG))//' degrees, where the bias of the scaled fluxes grows '// &
      'with the angle (reflectance of cloud slabs +0.08 to +0.6 % at 40 degrees and up to '// &
      '+2 % at 60, docs/performance.md); 20 keeps it near 0.1 % or below. '
    if (cfg%cloud%enabled .and. cfg%spectral%enabled) then
      ! a broadband run: the cloud's optics per band, its atmosphere rebuilt per g-point
      spec%node = shared
      call spectral_cloud_init(cfg%cloud, cfg%spectral, cloud_optics_location(cfg, spec%longwave), &
                               band_mie_default_cache(cfg, spec%longwave), spec%band_wn, &
                               spec%longwave, cfg%phase%n_table, phases, spec%cloud, cloud_notes, &
                               cloud_warnings, error, per_node=shared)
      if (allocated(error)) return
      spec%three_d = .true.
      spec%cloud_on = .true.
      spec%aopts = aopts
      scene%notes = scene%notes//cloud_notes
      scene%warnings = scene%warnings//cloud_warnings
      if (spec%longwave) scene%notes = scene%notes//'  longwave emission of the cloud voxels: '// &
        'the Planck sources of their layers (temperatures of the &kumo_spectral profile; the '// &
        'cloud file''s temperatures are not used)'//new_line('a')
      if (spec%node) then
        ! the band's cloud optics where every rank of the node reads them (the g-points of a
        ! band are swapped by all together)
        call spectral_cloud_place(spec%cloud, node_cloud)
        call atmosphere_begin(scene%atm, cfg%atm%z, cfg%atm%lx, cfg%atm%ly, ext1d, ssa1d, &
                              phase1d, phases, aopts, error, cfg%atm%k3d_bottom, spec%cloud%nx, &
                              spec%cloud%ny, spec%cloud%nz, spec%cloud%nc3, blend=.true., &
                              storage=node_voxels)
      else
        call atmosphere_begin(scene%atm, cfg%atm%z, cfg%atm%lx, cfg%atm%ly, ext1d, ssa1d, &
                              phase1d, phases, aopts, error, cfg%atm%k3d_bottom, spec%cloud%nx, &
                              spec%cloud%ny, spec%cloud%nz, spec%cloud%nc3, blend=.true.)
      end if
      if (allocated(error)) return
      n_out_liq = 0
      n_out_ice = 0
      if (scene%atm%voxel_writer) then
        call spectral_cloud_band(spec%cloud, spec%gpt_band(spec%g_setup), n_out_liq, n_out_ice)
        call spectral_cloud_put(spec%cloud, scene%atm)
      end if
      spec%atm_band = spec%gpt_band(spec%g_setup)
      if (spec%node) then
        call atmosphere_end(scene%atm, aopts, error, sync=par_node_sync)
        if (.not. allocated(error)) call note_voxel_storage(scene%atm, cfg%control%verbose)
      else
        call atmosphere_end(scene%atm, aopts, error)
      end if
      if (allocated(error)) return
      ! the other g-points keep these super-voxel blocks, with their own majorants
      spec%sv_layout = scene%atm%sv
      ! the tables of all bands have the same radii: the counts of one band are everyone's
      if (n_out_liq > 0) scene%warnings = scene%warnings//str(n_out_liq)//' cloud voxel '// &
        'values have a droplet effective radius outside the liquid optics table ('// &
        str(spec%cloud%liq_tab(1)%r_eff_um(1))//' - '// &
        str(spec%cloud%liq_tab(1)%r_eff_um(size(spec%cloud%liq_tab(1)%r_eff_um)))// &
        ' um) and were given the nearest table radius. '
      if (n_out_ice > 0) scene%warnings = scene%warnings//str(n_out_ice)//' ice voxel values '// &
        'have an effective radius outside the ice optics table ('// &
        str(spec%cloud%ice_tab(1)%r_eff_um(1))//' - '// &
        str(spec%cloud%ice_tab(1)%r_eff_um(size(spec%cloud%ice_tab(1)%r_eff_um)))// &
        ' um) and were given the nearest table radius. '
    else if (cfg%cloud%enabled) then
      call cloud_on_ranks(cfg, ext1d, ssa1d, phase1d, phases, aopts, scene%atm, cloud_notes, &
                          cloud_warnings, error, cloud_t, shared)
      if (allocated(error)) return
      scene%notes = scene%notes//cloud_notes
      scene%warnings = scene%warnings//cloud_warnings
    else
      ! several ranks, one wavelength: one copy of the scene file's voxels per node
      on_node = len_trim(cfg%atm%scene_file) > 0 .and. shared .and. .not. cfg%spectral%enabled
      if (on_node) then
        call scene_on_ranks(cfg, resolve_path(cfg%atm%scene_file, nml_path), ext1d, ssa1d, &
                            phase1d, phases, aopts, scene%atm, error)
        if (allocated(error)) return
      else if (len_trim(cfg%atm%scene_file) > 0 .and. shared .and. cfg%spectral%enabled) then
        ! several ranks, broadband: the node's first rank keeps the fields and rebuilds the
        ! node's voxels from them at every g-point (spectral_set_optics); the ranks of the node
        ! switch together
        on_node = .true.
        spec%three_d = .true.
        spec%node = .true.
        spec%phases = phases
        spec%aopts = aopts
        call scene_fields_on_leaders(cfg, resolve_path(cfg%atm%scene_file, nml_path), spec%ext3, &
                                     spec%ssa3, spec%iph3, has_iph, spec%n3d, error)
        if (allocated(error)) return
        if (allocated(spec%ext3) .and. .not. has_iph) then
          ! the namelist's phase function of each component, as read_scene_on_root gives it
          allocate (spec%iph3(spec%n3d(1), spec%n3d(2), spec%n3d(3), spec%n3d(4)))
          do i = 1, spec%n3d(4)
            spec%iph3(:, :, :, i) = cfg%atm%phase3d(i)
          end do
        end if
        call atmosphere_init(scene%atm, cfg%atm%z, cfg%atm%lx, cfg%atm%ly, ext1d, ssa1d, &
                             phase1d, phases, aopts, error, cfg%atm%k3d_bottom, spec%ext3, &
                             spec%ssa3, spec%iph3, n3d=spec%n3d, storage=node_voxels, &
                             sync=par_node_sync)
        if (allocated(error)) return
        call note_voxel_storage(scene%atm, cfg%control%verbose)
      else if (len_trim(cfg%atm%scene_file) > 0) then
        call read_scene_on_root(cfg, resolve_path(cfg%atm%scene_file, nml_path), ext3, ssa3, &
                                iph3, error)
        if (allocated(error)) return
      end if
      if (allocated(ext3)) then
        if (present(spec)) then
          if (spec%on) then
            ! a broadband 3-D scene: its atmosphere is rebuilt per g-point from these
            spec%three_d = .true.
            spec%ext3 = ext3
            spec%ssa3 = ssa3
            if (allocated(iph3)) spec%iph3 = iph3
            spec%phases = phases
            spec%aopts = aopts
          end if
        end if
        call atmosphere_init(scene%atm, cfg%atm%z, cfg%atm%lx, cfg%atm%ly, ext1d, ssa1d, &
                             phase1d, phases, aopts, error, cfg%atm%k3d_bottom, ext3, ssa3, iph3)
      else if (.not. on_node) then
        call atmosphere_init(scene%atm, cfg%atm%z, cfg%atm%lx, cfg%atm%ly, ext1d, ssa1d, &
                             phase1d, phases, aopts, error)
      end if
      if (allocated(error)) return
    end if

    if (.not. spectral_run()) scene%warnings = scene%warnings//dense_scattering_warning(scene%atm)

    ! the beam first: BRDF tables store the albedo at its mu0 = -uz exactly (every direct-beam
    ! photon arrives at that angle, bit for bit)
    scene%src = solar_source(cfg%source%sza_deg, cfg%source%phi0_deg)
    if (len_trim(cfg%surface%albedo_file) > 0) then
      call map_on_root(resolve_path(cfg%surface%albedo_file, nml_path), &
                       trim(cfg%surface%albedo_var), .false., alb, error)
      if (allocated(error)) return
    else
      allocate (alb(1, 1))
      alb = cfg%surface%albedo
    end if
    if (len_trim(cfg%surface%surface_file) > 0) then
      call mcarats_surface_on_root(cfg, resolve_path(cfg%surface%surface_file, nml_path), bmap, &
                                   sfc_notes, error)
      if (allocated(error)) return
      call surface_init_brdf_map(scene%sfc, bmap, cfg%atm%lx, cfg%atm%ly, error, &
                                 mu0=-scene%src%uz)
      call add_context(error, trim(cfg%surface%surface_file))
      scene%notes = scene%notes//sfc_notes
    else if (len_trim(cfg%surface%brdf_file) > 0) then
      call brdf_map_on_root(resolve_path(cfg%surface%brdf_file, nml_path), cfg%surface%model%kind, &
                            bmap, error)
      if (allocated(error)) return
      call surface_init_brdf_map(scene%sfc, bmap, cfg%atm%lx, cfg%atm%ly, error, &
                                 mu0=-scene%src%uz)
      call add_context(error, trim(cfg%surface%brdf_file))
    else if (cfg%surface%brdf == 'lambert') then
      call surface_init(scene%sfc, alb, cfg%atm%lx, cfg%atm%ly, error)
    else
      call surface_init_brdf(scene%sfc, cfg%surface%model, cfg%atm%lx, cfg%atm%ly, error, &
                             mu0=-scene%src%uz)
    end if
    if (allocated(error)) return

    scene%warnings = scene%warnings//brdf_clamp_warning(scene%sfc, -scene%src%uz)

    if (cfg%vr%stratify_source) then
      ! entry cells: the 3-D region's columns, or else the surface map's pixels
      if (scene%atm%n3 > 0) then
        call source_stratify(scene%src, scene%atm%nx, scene%atm%ny, &
                             scene%atm%z(scene%atm%nz) - scene%atm%z(0))
      else if (.not. scene%sfc%uniform) then
        call source_stratify(scene%src, scene%sfc%nxs, scene%sfc%nys, &
                             scene%atm%z(scene%atm%nz) - scene%atm%z(0))
      end if
    end if
    scene%mu0 = cos(cfg%source%sza_deg*DEG2RAD)
    if (cfg%thermal%enabled) then
      call setup_thermal(cfg, scene, error, cloud_t)
      if (allocated(error)) return
    end if
    if (present(spec)) then
      if (spec%longwave) then
        if (allocated(cfg%rad%mu) .or. cfg%cam%n > 0) then
          ! emission seen by the detectors: an isotropic phase function for its local
          ! estimates, in every atmosphere a g-point switch builds
          scene%atm%phases = [scene%atm%phases, new_phase_isotropic()]
          if (allocated(spec%phases)) spec%phases = [spec%phases, new_phase_isotropic()]
          spec%iph_iso = size(scene%atm%phases)
        end if
        call setup_spectral_emission(cfg, scene, spec, error)
        if (allocated(error)) return
      end if
    end if
    scene%vr%rr_threshold = cfg%vr%rr_threshold
    scene%vr%rr_weight = cfg%vr%rr_weight
    scene%vr%abs_estimator = absorption_estimator_code(cfg%vr%absorption_estimator)
    scene%max_events = cfg%control%max_events
    select case (cfg%control%mode_3d)
    case ('ica')
      scene%n_3d = 0
    case ('p3d')
      scene%n_3d = cfg%control%p3d_orders
    case default
      scene%n_3d = huge(1)
    end select
    ! flight steps (null collisions, face crossings) per event are many but bounded: the step cap
    ! only catches a photon that no longer makes progress
    scene%max_steps = max(1000000000_i8, min(huge(1_i8)/2000_i8, cfg%control%max_events)*1000_i8)

    call setup_estimators(cfg, scene, error)
    if (allocated(error)) return
    if (present(spec)) then
      if (spec%on .and. scene%det%active) then
        ! what the detectors set up in the atmosphere of the set-up's g-point, for every other
        spec%truncated = scene%atm%truncated
        if (spec%truncated) spec%trunc = scene%atm%trunc
        spec%forcing = cfg%vr%cf_tau_min > 0.0_wp
        spec%cf_tau_min = cfg%vr%cf_tau_min
        allocate (spec%cf(spec%n_gpt))
        spec%cf = 0.0_wp
        scene%src%em%iph_iso = spec%iph_iso
      end if
      if (spec%longwave) then
        ! a longwave column that scatters at no g-point: exact sums over the g-points
        spec%exact = cfg%vr%use_exact_thermal .and. exact_thermal_possible(scene) .and. &
                     all(spec%omg1 <= 0.0_wp .or. spec%ext1 <= 0.0_wp)
        if (spec%exact) scene%notes = scene%notes//'  no layer scatters: every g-point solved '// &
          'exactly (exponential integrals), no photons traced; standard errors are 0'//new_line('a')
      end if
    end if
  contains

    logical function spectral_run()
      spectral_run = .false.
      if (present(spec)) spectral_run = spec%on
    end function spectral_run
  end subroutine setup_scene

  !> The warning for BRDF parameters whose directional albedo exceeds 1 (RPV with small k, LSRT
  !> with large kernel weights): kumo scales such a BRDF down to albedo 1 at those incidence
  !> angles, so the surface is not the model given. Said when the sun's incidence (mu0) is among
  !> them or they reach mu_in = BRDF_CLAMP_MU (isotropic diffuse light brings a fraction mu^2
  !> of its irradiance from below mu: 1 % below 0.1); empty otherwise.
  function brdf_clamp_warning(sfc, mu0) result(text)
    type(surface_t), intent(in) :: sfc
    real(wp), intent(in) :: mu0
    character(len=:), allocatable :: text
    real(wp), parameter :: BRDF_CLAMP_MU = 0.1_wp
    real(wp) :: mu_top, a_sun
    integer :: i, n
    text = ''
    if (.not. allocated(sfc%tabs)) return
    n = 0
    mu_top = 0.0_wp
    do i = 1, size(sfc%tabs)
      if (sfc%tabs(i)%n_clamped <= 0) cycle
      if (sfc%tabs(i)%mu_clamped < BRDF_CLAMP_MU .and. sfc%tabs(i)%mu_clamped < mu0) cycle
      n = n + 1
      mu_top = max(mu_top, sfc%tabs(i)%mu_clamped)
    end do
    if (n == 0) return
    if (size(sfc%tabs) == 1) then
      a_sun = brdf_albedo_quad(sfc%tabs(1)%p, mu0)
      text = 'the '//trim(BRDF_NAMES(sfc%tabs(1)%p%kind))//' BRDF''s directional albedo '// &
             'exceeds 1 for incidence cosines up to about '//str(mu_top, 4)
      if (a_sun > 1.0_wp) text = text//', the sun''s mu0 = '//str(mu0, 4)//' among them '// &
        '(albedo '//str(a_sun, 4)//')'
    else
      text = str(n)//' of the '//str(size(sfc%tabs))//' BRDF parameter sets of the surface '// &
             'map have a directional albedo above 1 for incidence cosines up to about '// &
             str(mu_top, 4)
    end if
    text = text//': a surface that reflects more than it receives; kumo scales the BRDF down '// &
           'to albedo 1 at those angles, so the surface is not the model given (check the '// &
           'parameters, docs/namelist.md). '
  end function brdf_clamp_warning

  !> The warning for layers and voxels of `atm` whose scattering coefficient (extinction times
  !> albedo) exceeds SCAT_WARN, naming how many, the largest and where; empty when none does.
  function dense_scattering_warning(atm) result(text)
    type(atmosphere_t), intent(in) :: atm
    character(len=:), allocatable :: text
    real(vp), allocatable :: e(:, :), w(:, :)
    real(wp) :: top, s
    integer(i8) :: n
    integer :: k, kr, loc(2)
    character(len=:), allocatable :: where

    text = ''
    n = 0
    top = 0.0_wp
    where = ''
    do k = 1, atm%nz
      if (atm%n3 > 0 .and. k >= atm%k3_lo .and. k <= atm%k3_hi) cycle
      s = atm%ext1(k)*atm%omg1(k)
      if (s <= SCAT_WARN) cycle
      n = n + 1
      if (s > top) then
        top = s
        where = 'layer '//str(k)
      end if
    end do
    if (atm%n3 > 0) then
      allocate (e(atm%nx, atm%ny), w(atm%nx, atm%ny))
      do kr = 1, atm%n3
        call voxel_layer(atm, kr, e, w)
        e = e*w
        n = n + count(e > real(SCAT_WARN, vp))
        s = maxval(e)
        if (s > top .and. s > SCAT_WARN) then
          top = s
          loc = maxloc(e)
          where = 'voxel ('//str(loc(1))//', '//str(loc(2))//') of layer '// &
                  str(atm%k3_lo + kr - 1)
        end if
      end do
    end if
    if (n == 0) return
    text = str(n)//' layer(s) or voxel(s) scatter more than '//str(SCAT_WARN)//' m-1 (the '// &
           'largest '//str(top, 4)//' m-1, '//where//'): a mean free path under 10 cm, ten times '// &
           'the densest clouds; check the units of the extinction (m-1; values in km-1 are '// &
           '1000 times too large), and expect a photon to make about (optical size)^2 '// &
           'scattering events in such a conservative region. '
  end function dense_scattering_warning

  !> Thermal emission: the Planck radiances of the levels, the surface and the top (from the
  !> temperatures and the spectral interval, or given), the emission table, and an isotropic
  !> phase function for the local estimates of emission by cells when radiances are wanted.
  !> The voxels emit from their own temperatures when the scene file or the cloud file gives
  !> them (`cloud_t`), else from the level temperatures.
  subroutine setup_thermal(cfg, scene, error, cloud_t)
    type(config_t), intent(in) :: cfg
    type(scene_t), intent(inout) :: scene
    type(error_t), allocatable, intent(out) :: error
    type(cloud_temperature_t), intent(inout) :: cloud_t
    real(wp), allocatable :: b_lev(:)
    real(wp) :: b_sfc, b_top, solar_power, lambda_um, scale
    type(spectral_band_t) :: band
    logical :: has_band
    character(len=24) :: units
    real(wp), allocatable :: t3(:, :, :), b3(:, :, :), tmap(:, :), bsm(:, :)
    character(len=:), allocatable :: nml_path
    character(len=:), allocatable :: what
    logical :: on_node, found
    integer(i8) :: t_bytes
    ! one scene per node: the node's first rank (the voxels' writer) alone holds the voxel
    ! temperatures and forms their Planck radiances
    on_node = scene%atm%voxels_borrowed
    associate (th => cfg%thermal)
      has_band = .not. allocated(th%planck_levels)
      if (has_band) then
        if (th%wavenumber_lo >= 0.0_wp) then
          call band_from_wavenumbers(th%wavenumber_lo, th%wavenumber_hi, band, error)
          what = 'band '//str(th%wavenumber_lo)//'-'//str(th%wavenumber_hi)//' cm-1'
        else
          lambda_um = th%wavelength_um
          if (lambda_um <= 0.0_wp) lambda_um = cfg%source%wavelength_um
          call band_monochromatic_wavelength(lambda_um*1.0e-6_wp, band, error)
          what = 'wavelength '//str(lambda_um)//' um'
        end if
        if (allocated(error)) then
          call add_context(error, '&kumo_thermal')
          return
        end if
        ! a single wavelength: radiances per um rather than per m
        scale = 1.0_wp
        units = band_units(band)
        if (units == 'W m-2 sr-1 m-1') then
          scale = 1.0e-6_wp
          units = 'W m-2 sr-1 um-1'
        end if
        b_lev = scale*band_radiance(band, th%t_levels)
        b_sfc = scale*band_radiance(band, th%t_surface)
        b_top = 0.0_wp
        if (th%t_top > 0.0_wp) b_top = scale*band_radiance(band, th%t_top)
        what = what//', Planck radiances in '//trim(units)
      else
        b_lev = th%planck_levels
        b_sfc = th%planck_surface
        b_top = th%planck_top
        what = 'Planck radiances given (planck_levels)'
      end if
    end associate
    if (has_band) call cold_warning()
    solar_power = 0.0_wp
    if (cfg%thermal%include_sun) solar_power = cfg%source%solar_flux*scene%mu0
    ! a surface temperature map: Planck radiance per pixel
    if (len_trim(cfg%thermal%t_surface_file) > 0 .and. has_band) then
      nml_path = ''
      if (allocated(cfg%path)) nml_path = cfg%path
      call map_on_root(resolve_path(cfg%thermal%t_surface_file, nml_path), &
                       trim(cfg%thermal%t_surface_var), .true., tmap, error)
      if (allocated(error)) then
        call add_context(error, '&kumo_thermal t_surface_file')
        return
      end if
      bsm = scale*band_radiance(band, tmap)
      if (any(tmap > 0.0_wp .and. tmap < T_COLD)) scene%warnings = scene%warnings// &
        'the surface temperature map '//trim(cfg%thermal%t_surface_file)//' has '// &
        str(count(tmap > 0.0_wp .and. tmap < T_COLD))//' pixel(s) between 0 and '// &
        str(nint(T_COLD))//' K (down to '//str(minval(tmap, mask=tmap > 0.0_wp))//' K): '// &
        'temperatures are in K, not degrees Celsius. '
      what = what//new_line('a')//'  surface temperature map '//trim(cfg%thermal%t_surface_file)// &
             ': '//str(size(tmap, 1))//' x '//str(size(tmap, 2))//' pixels, '// &
             str(minval(tmap))//' to '//str(maxval(tmap))//' K'
    end if
    ! voxel temperatures of the scene file, if it has them (then the voxels emit uniformly)
    if (len_trim(cfg%atm%scene_file) > 0 .and. .not. cfg%cloud%enabled .and. has_band) then
      nml_path = ''
      if (allocated(cfg%path)) nml_path = cfg%path
      call scene_temperature_on_root(resolve_path(cfg%atm%scene_file, nml_path), cfg, t3, error, &
                                     leaders=on_node, found=found)
      if (allocated(error)) return
      if (found) then
        cloud_t%found = .true.
        cloud_t%source = 'variable temperature of the scene file'
      end if
    end if
    t_bytes = 0_i8
    if (allocated(t3)) then
      t_bytes = int(size(t3), i8)*(storage_size(t3)/8)
      cloud_t%t = real(t3, vp)
      deallocate (t3)
    end if
    if (cloud_t%found .and. has_band) then
      if (allocated(cloud_t%t)) t_bytes = t_bytes + int(size(cloud_t%t), i8)*(storage_size(cloud_t%t)/8)
      if (.not. on_node .or. scene%atm%voxel_writer) &
        call voxel_planck(cloud_t, scene%atm, cfg%atm%k3d_bottom, cfg%thermal%t_levels, band, &
                          scale, b_lev, b3, what, error)
      if (on_node) call writer_verdict()
      if (allocated(error)) then
        call add_context(error, '&kumo_thermal')
        return
      end if
      if (allocated(b3)) t_bytes = t_bytes + int(size(b3), i8)*(storage_size(b3)/8)
      if (on_node) call note_rank_bytes('voxel temperatures: held and made into Planck '// &
                                        'radiances by the node''s first rank alone', t_bytes, &
                                        0_i8, cfg%control%verbose)
      ! b3 holds what the emission needs: the temperatures (one value per voxel) go first
      if (allocated(cloud_t%t)) deallocate (cloud_t%t)
      call init_table(b3, on_node)
    else
      if (cfg%cloud%enabled .and. scene%atm%n3 > 0) then
        if (.not. has_band) then
          what = what//new_line('a')//'  voxel temperatures: not used (Planck radiances given '// &
                 'directly); the voxels emit the level values'
        else
          what = what//new_line('a')//'  voxel temperatures: the cloud file has none; the '// &
                 'voxels take t_levels'
        end if
      end if
      call init_table()
    end if
    if (allocated(error)) then
      call add_context(error, '&kumo_thermal')
      return
    end if
    scene%exact_thermal = cfg%vr%use_exact_thermal
    scene%src%em%has_band = has_band
    if (has_band) then
      scene%src%em%band = band
      scene%src%em%to_band_units = 1.0_wp/scale
      scene%src%em%radiance_units = units
      scene%src%em%flux_units = 'W m-2'//units(len('W m-2 sr-1') + 1:)
    end if
    if (allocated(cfg%rad%mu) .or. cfg%cam%n > 0) then
      scene%atm%phases = [scene%atm%phases, new_phase_isotropic()]
      scene%src%em%iph_iso = size(scene%atm%phases)
    end if
    associate (em => scene%src%em)
      scene%notes = scene%notes//'thermal emission: '//what//new_line('a')// &
        '  source power per unit area '//str(em%power)//' W m-2 (atmosphere '// &
        str(sum(em%emit_layer))//', surface '//str(em%emit_sfc)//', top '//str(em%emit_top)// &
        ', sun '//str(em%solar_power)//'); surface emissivity '//str(em%eps_mean)//new_line('a')
    end associate

  contains

    !> A warning naming the temperatures of &kumo_thermal between 0 and T_COLD (0 K stays
    !> silent: it switches the emission off).
    subroutine cold_warning()
      character(len=:), allocatable :: list
      integer :: i
      list = ''
      associate (th => cfg%thermal)
        do i = 1, size(th%t_levels)
          if (th%t_levels(i) > 0.0_wp .and. th%t_levels(i) < T_COLD) &
            list = list//', t_levels('//str(i)//') = '//str(th%t_levels(i))
        end do
        if (th%t_surface > 0.0_wp .and. th%t_surface < T_COLD) &
          list = list//', t_surface = '//str(th%t_surface)
        if (th%t_top > 0.0_wp .and. th%t_top < T_COLD) list = list//', t_top = '//str(th%t_top)
      end associate
      if (len(list) > 0) scene%warnings = scene%warnings//'&kumo_thermal temperatures between '// &
        '0 and '//str(nint(T_COLD))//' K ('//list(3:)//'): colder than any layer or surface '// &
        'of the Earth''s atmosphere; temperatures are in K, not degrees Celsius. '
    end subroutine cold_warning

    !> The voxels' writer has formed their Planck radiances (or failed): rank 0's error, or its
    !> note on them (temperature range), on every rank. Every rank calls it; all node leaders
    !> hold the same temperatures, so they agree with rank 0.
    subroutine writer_verdict()
      type(bundle_t) :: bv
      if (par_is_root() .and. .not. allocated(error)) call bv%put(what)
      call bv%share(error)
      if (.not. allocated(error)) call bv%get(what)
    end subroutine writer_verdict

    !> The emission table, with its per-voxel arrays in the node's shared window when the
    !> voxels are there (one scene per node: the node's first rank forms them; with `by_writer`
    !> it alone has the voxels' Planck radiances `b3v`).
    subroutine init_table(b3v, by_writer)
      real(wp), intent(in), optional :: b3v(:, :, :)
      logical, intent(in), optional :: by_writer
      if (scene%atm%voxels_borrowed) then
        call emission_init(scene%src%em, scene%atm, scene%sfc, b_lev, b_sfc, b_top, solar_power, &
                           cfg%thermal%emission_floor, error, b3=b3v, b_sfc_map=bsm, &
                           storage=par_node_storage, sync=par_node_sync, b3_by_writer=by_writer)
        if (.not. allocated(error)) call note_table_storage(scene%src%em, cfg%control%verbose)
      else
        call emission_init(scene%src%em, scene%atm, scene%sfc, b_lev, b_sfc, b_top, solar_power, &
                           cfg%thermal%emission_floor, error, b3=b3v, b_sfc_map=bsm)
      end if
    end subroutine init_table
  end subroutine setup_thermal

  !> Planck radiances b3 of the voxels of the 3-D region from file temperatures `ft` whose
  !> first layer is layer k3_file of the atmosphere: a voxel between two planes (or levels)
  !> takes the mean of their Planck radiances; MCARaTS perturbations are added to the level
  !> temperatures t_lev (a layer's: the mean of its two levels). Layers of the region outside
  !> the file (use_1d_layers = .false. widens the region) take the mean of their level values.
  subroutine voxel_planck(ft, atm, k3_file, t_lev, band, scale, b_lev, b3, what, error)
    type(cloud_temperature_t), intent(in) :: ft
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: k3_file
    real(wp), intent(in) :: t_lev(0:), scale, b_lev(0:)
    type(spectral_band_t), intent(in) :: band
    real(wp), allocatable, intent(out) :: b3(:, :, :)
    character(len=:), allocatable, intent(inout) :: what
    type(error_t), allocatable, intent(out) :: error
    integer :: kr, k, kf, ix, iy, i, j, nf
    real(wp) :: ta, tb, tmin, tmax
    nf = size(ft%t, 3)
    if (ft%planes) nf = nf - 1
    if ((size(ft%t, 1) /= 1 .and. size(ft%t, 1) /= atm%nx) .or. &
        (size(ft%t, 2) /= 1 .and. size(ft%t, 2) /= atm%ny) .or. &
        k3_file < atm%k3_lo .or. k3_file + nf - 1 > atm%k3_hi) then
      call set_error(error, 'voxel temperatures ('//ft%source//'): '//str(size(ft%t, 1))//' x '// &
                     str(size(ft%t, 2))//' columns, '//str(nf)//' layers from layer '// &
                     str(k3_file)//'; the 3-D region has '//str(atm%nx)//' x '//str(atm%ny)// &
                     ' columns, layers '//str(atm%k3_lo)//'..'//str(atm%k3_hi))
      return
    end if
    allocate (b3(atm%nx, atm%ny, atm%n3))
    tmin = huge(1.0_wp)
    tmax = -huge(1.0_wp)
    do kr = 1, atm%n3
      k = atm%k3_lo + kr - 1
      kf = k - k3_file + 1
      if (kf < 1 .or. kf > nf) then
        b3(:, :, kr) = 0.5_wp*(b_lev(k - 1) + b_lev(k))
        cycle
      end if
      do iy = 1, atm%ny
        j = min(iy, size(ft%t, 2))
        do ix = 1, atm%nx
          i = min(ix, size(ft%t, 1))
          ta = real(ft%t(i, j, kf), wp)
          if (ft%planes) then
            tb = real(ft%t(i, j, kf + 1), wp)
            if (ft%perturbation) then
              ta = ta + t_lev(k - 1)
              tb = tb + t_lev(k)
            end if
          else
            if (ft%perturbation) ta = ta + 0.5_wp*(t_lev(k - 1) + t_lev(k))
            tb = ta
          end if
          if (.not. (min(ta, tb) > 0.0_wp)) then
            call set_error(error, 'voxel temperatures ('//ft%source//'): voxel ('//str(ix)// &
                           ','//str(iy)//','//str(kf)//') has '//str(min(ta, tb))// &
                           ' K; temperatures must be > 0')
            return
          end if
          tmin = min(tmin, ta, tb)
          tmax = max(tmax, ta, tb)
          b3(ix, iy, kr) = 0.5_wp*scale*(band_radiance(band, ta) + band_radiance(band, tb))
          if (.not. (b3(ix, iy, kr) <= huge(1.0_wp))) then
            call set_error(error, 'voxel temperatures ('//ft%source//'): voxel ('//str(ix)// &
                           ','//str(iy)//','//str(kf)//') has '//str(max(ta, tb))// &
                           ' K, whose Planck radiance is not finite')
            return
          end if
        end do
      end do
    end do
    what = what//new_line('a')//'  voxel temperatures: '//ft%source//', '//str(tmin)//' to '// &
           str(tmax)//' K'
    if (ft%planes) what = what//' (on the planes bounding the voxels: a voxel emits the mean '// &
                          'Planck radiance of its two planes)'
  end subroutine voxel_planck

  !> Broadband set-up (&kumo_spectral): the gas column of the profile, per g-point, from the
  !> RRTMGP k-distribution (read and computed on rank 0, broadcast), and for every g-point the
  !> mixed optics of the 1-D layers: the namelist components and, in the shortwave, Rayleigh
  !> scattering (phase function 3/4 (1 + cos^2), no depolarisation, as in RRTMGP's optics), and
  !> gas absorption. A shortwave file makes the sampling plan here (energies mu0 F_g); a
  !> longwave one keeps each g-point's Planck sources for `setup_spectral_emission`, which
  !> makes the emission tables and the plan once the atmosphere and the surface exist.
  !> `ext1d`, `ssa1d`, `phase1d` gain the gas (and Rayleigh) components at the g-point of most
  !> energy, so that the atmosphere built from them has the right shape; `spectral_set_gpoint`
  !> then switches its 1-D layers from one g-point to another. Sets the layer air density
  !> (dp / (g0 dz)) for heating rates unless &kumo_atmosphere gives it.
  subroutine setup_spectral(cfg, ext1d, ssa1d, phase1d, phases, scene, spec, error)
    type(config_t), intent(in) :: cfg
    real(wp), allocatable, intent(inout) :: ext1d(:, :), ssa1d(:, :)
    integer, allocatable, intent(inout) :: phase1d(:, :)
    type(phase_t), allocatable, intent(inout) :: phases(:)
    type(scene_t), intent(inout) :: scene
    type(spectral_scene_t), intent(out) :: spec
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: G0 = 9.80665_wp        !! standard gravity [m s-2]
    type(gas_kdist_t) :: kd
    type(spectral_column_t) :: col
    real(wp), allocatable :: z(:), zmid(:), dz(:), plev(:), tlev(:), play(:), tlay(:), rho(:), &
                             vmr(:, :), tau_abs(:, :), tau_ray(:, :), energy(:), e(:), s(:), &
                             pmid(:), h2o(:)
    character(len=:), allocatable :: state_note, gas_warn
    integer :: nz, nc, ng, k, g, iray, ic, nadd
    type(bundle_t) :: b
    real(wp) :: mu0, sca, acc, tsfc
    real(wp), allocatable :: x1(:, :), a1(:, :)
    logical :: lw
    type(truncation_t) :: tr

    nz = cfg%atm%nz
    nc = size(ext1d, 2)
    z = cfg%atm%z
    dz = z(2:nz + 1) - z(1:nz)
    zmid = 0.5_wp*(z(1:nz) + z(2:nz + 1))
    allocate (plev(0:nz), tlev(0:nz), play(nz), tlay(nz), rho(nz + 1), pmid(nz))
    if (len_trim(cfg%spectral%profile) > 0) then
      ! a standard atmosphere: levels at z_levels; layers at the geometric mean of their level
      ! pressures (exact for an isothermal layer) and at the temperature of the mid-height
      call std_atmosphere_profile(cfg%spectral%profile, z, plev, tlev, rho, error)
      if (allocated(error)) then
        call add_context(error, '&kumo_spectral profile at &kumo_atmosphere z_levels')
        return
      end if
      call std_atmosphere_profile(cfg%spectral%profile, zmid, pmid, tlay, rho(1:nz), error)
      if (allocated(error)) return
      play = sqrt(plev(0:nz - 1)*plev(1:nz))
    else
      plev = cfg%spectral%p_levels
      tlev = cfg%spectral%t_levels
      if (allocated(cfg%spectral%p_layers)) then
        play = cfg%spectral%p_layers
      else
        play = sqrt(plev(0:nz - 1)*plev(1:nz))
      end if
      if (allocated(cfg%spectral%t_layers)) then
        tlay = cfg%spectral%t_layers
      else
        tlay = 0.5_wp*(tlev(0:nz - 1) + tlev(1:nz))
      end if
    end if
    ! the gas state of an LES/CRM file's layers (kumo_gas_state), on every rank
    h2o = cfg%spectral%h2o_vmr
    state_note = ''
    if (cfg%cloud%enabled .and. cfg%spectral%gas_state == 'cloud_file') then
      call cloud_gas_state(cfg, z, plev, play, tlev, tlay, h2o, state_note, error)
      if (allocated(error)) return
    end if
    mu0 = cos(cfg%source%sza_deg*DEG2RAD)
    tsfc = cfg%spectral%t_surface
    if (tsfc <= 0.0_wp) tsfc = tlev(0)

    ! rank 0: the k-distribution and the column; every rank gets the optical depths and sources
    if (par_is_root()) then
      call read_rrtmgp_kdist(kdist_location(cfg%spectral%kdist_file, cfg%spectral%kdist_path), kd, error)
      if (.not. allocated(error)) then
        allocate (vmr(nz, kd%n_gas))
        vmr = 0.0_wp
        call gas_default_vmr(kd, play, vmr, error)
      end if
      if (.not. allocated(error)) then
        if (gas_index(kd, 'h2o') > 0) vmr(:, gas_index(kd, 'h2o')) = h2o
        if (allocated(cfg%spectral%o3_vmr) .and. gas_index(kd, 'o3') > 0) &
          vmr(:, gas_index(kd, 'o3')) = cfg%spectral%o3_vmr
        ! other gases at the constant mixing ratios of gas_names / gas_vmr
        if (allocated(cfg%spectral%gas_names)) then
          do k = 1, size(cfg%spectral%gas_names)
            if (gas_index(kd, trim(cfg%spectral%gas_names(k))) == 0) then
              call set_error(error, '&kumo_spectral: gas_names('//str(k)//') = "'// &
                             trim(cfg%spectral%gas_names(k))//'" is not a gas of '// &
                             cfg%spectral%kdist_path//'; its gases: '//join(kd%gas_names))
              exit
            end if
            vmr(:, gas_index(kd, trim(cfg%spectral%gas_names(k)))) = cfg%spectral%gas_vmr(k)
          end do
        end if
      end if
      if (allocated(error)) then
        continue                             ! the column is not made
      else if (kd%longwave) then
        call spectral_lw_column(kd, plev, tlev, play, tlay, tsfc, vmr, col, error, &
                                emissivity=max(0.0_wp, min(1.0_wp, 1.0_wp - cfg%surface%albedo)))
      else if (cfg%spectral%t_surface > 0.0_wp) then
        call set_error(error, 't_surface = '//str(cfg%spectral%t_surface)//' K is for '// &
                       'longwave k-distributions; '//cfg%spectral%kdist_path//' is a shortwave one')
      else
        call spectral_sw_column(kd, plev, play, tlay, vmr, mu0, col, error, tsi=cfg%spectral%tsi)
      end if
      if (allocated(error)) then
        if (index(error%message, '&kumo_spectral') /= 1) call add_context(error, '&kumo_spectral kdist_file')
      else
        call b%put(gas_column_warnings(z, plev, play, tlay, h2o, kd%temp_ref(1), &
                                       kd%temp_ref(kd%n_temp), maxval(kd%press_ref), tsfc, &
                                       kd%longwave, len_trim(cfg%spectral%profile) == 0))
        call b%put(kd%longwave)
        call b%put(col%gpt_band)
        call b%put(col%band_wavenumber)
        call b%put(col%tau_abs)
        call b%put(col%energy)
        if (kd%longwave) then
          call b%put(col%lev_src_bot)
          call b%put(col%lev_src_top)
          call b%put(col%sfc_src)
        else
          call b%put(col%tau_rayleigh)
        end if
      end if
    end if
    call b%share(error)
    if (allocated(error)) return
    call b%get(gas_warn)
    scene%warnings = scene%warnings//gas_warn
    call b%get(lw)
    call b%get(spec%gpt_band)
    call b%get(spec%band_wn)
    call b%get(tau_abs)
    call b%get(energy)
    ng = size(energy)
    if (cfg%spectral%gpoint > ng) then
      call set_error(error, '&kumo_spectral: gpoint = '//str(cfg%spectral%gpoint)// &
                     ' must be 0 (every g-point) or between 1 and the '//str(ng)// &
                     ' g-points of '//cfg%spectral%kdist_path)
      return
    end if
    spec%gpoint = cfg%spectral%gpoint
    if (.not. lw .and. spec%gpoint > 0) then
      ! one g-point alone: the others get no energy and are never drawn
      where ([(g, g=1, ng)] /= spec%gpoint) energy = 0.0_wp
      if (.not. (energy(spec%gpoint) > 0.0_wp)) then
        call set_error(error, '&kumo_spectral: gpoint = '//str(spec%gpoint)//' has no solar '// &
                       'energy in '//cfg%spectral%kdist_path)
        return
      end if
    end if
    if (lw) then
      call b%get(spec%src_bot)
      call b%get(spec%src_top)
      call b%get(spec%src_sfc)
      allocate (tau_ray(nz, ng))
      tau_ray = 0.0_wp
    else
      call b%get(tau_ray)
    end if
    if (lw .and. cfg%vr%absorption_estimator /= 'collision') then
      call set_error(error, '&kumo_vr: absorption_estimator = '''// &
                     trim(cfg%vr%absorption_estimator)//''' is for solar runs only; '// &
                     cfg%spectral%kdist_path//' is a longwave k-distribution, whose net-exchange '// &
                     'tallies score absorption at collisions: set absorption_estimator = '// &
                     '''collision'' (the default)')
      return
    end if
    if (lw .and. cfg%vr%similarity_theta_deg > 0.0_wp) then
      call set_error(error, '&kumo_vr: similarity_theta_deg = '// &
                     str(cfg%vr%similarity_theta_deg)//' is for solar runs only; '// &
                     cfg%spectral%kdist_path//' is a longwave k-distribution: set it to 0')
      return
    end if
    ! the namelist's components of the 1-D layers for the per-g-point mixtures below,
    ! similarity-scaled as kumo_atmosphere scales them (Rayleigh and gas have no forward peak);
    ! ext1d and ssa1d stay as given for the 3-D builds, which scale them themselves
    x1 = ext1d
    a1 = ssa1d
    if (cfg%vr%similarity_theta_deg > 0.0_wp) then
      call similarity_tables(phases, cfg%vr%similarity_theta_deg, tr, error)
      if (allocated(error)) then
        call add_context(error, '&kumo_vr')
        return
      end if
      call similarity_scale_1d(tr, phase1d, x1, a1)
    end if
    spec%longwave = lw
    if (.not. lw) then
      call spectral_plan_init(energy, spec%plan, error, floor_share=cfg%spectral%floor_share)
      if (allocated(error)) then
        call add_context(error, '&kumo_spectral')
        return
      end if
      spec%norm = spec%plan%total
      if (spec%gpoint > 0) spec%norm = cfg%spectral%tsi*mu0
    end if

    ! per g-point mixtures of the 1-D layers: components 1..nc of the namelist, then (shortwave)
    ! Rayleigh, then gas absorption (the mixing of kumo_atmosphere)
    nadd = 2
    if (lw) nadd = 1
    spec%on = .true.
    spec%n_gpt = ng
    spec%nz = nz
    spec%ncomp = nc + nadd
    spec%tsi = cfg%spectral%tsi
    spec%mu0 = mu0
    allocate (spec%ext1(nz, ng), spec%omg1(nz, ng), spec%csca1(nc + nadd, nz, ng), &
              spec%layer_class(nz, ng), e(nc + nadd), s(nc + nadd))
    do g = 1, ng
      do k = 1, nz
        e(1:nc) = x1(k, :)
        s(1:nc) = x1(k, :)*a1(k, :)
        if (.not. lw) then
          e(nc + 1) = tau_ray(k, g)/dz(k)
          s(nc + 1) = e(nc + 1)
        end if
        e(nc + nadd) = tau_abs(k, g)/dz(k)
        s(nc + nadd) = 0.0_wp
        spec%ext1(k, g) = sum(e)
        sca = sum(s)
        spec%omg1(k, g) = 1.0_wp
        if (spec%ext1(k, g) > 0.0_wp) spec%omg1(k, g) = min(1.0_wp, sca/spec%ext1(k, g))
        acc = 0.0_wp
        do ic = 1, nc + nadd
          acc = acc + s(ic)
          if (sca > 0.0_wp) then
            spec%csca1(ic, k, g) = acc/sca
          else
            spec%csca1(ic, k, g) = real(ic, wp)/(nc + nadd)
          end if
        end do
        spec%csca1(nc + nadd, k, g) = 1.0_wp
        if (spec%ext1(k, g) <= 0.0_wp) then
          spec%layer_class(k, g) = LAYER_CLEAR
        else if (spec%omg1(k, g) <= 0.0_wp .and. cfg%vr%use_absorbing_layers) then
          spec%layer_class(k, g) = LAYER_ABSORBING
        else
          spec%layer_class(k, g) = LAYER_SCATTERING
        end if
      end do
    end do
    ! the atmosphere of every g-point is checked as atmosphere_begin checks the one it builds
    if (maxval(spec%ext1) > EXT_MAX) then
      block
        integer :: at(2)
        at = maxloc(spec%ext1)
        call set_error(error, '&kumo_spectral: g-point '//str(at(2))//', layer '//str(at(1))// &
                       ' has an extinction of '//str(spec%ext1(at(1), at(2)))//' m-1 (gas '// &
                       'absorption optical depth '//str(tau_abs(at(1), at(2)))//' over '// &
                       str(dz(at(1)))//' m), more than '//str(EXT_MAX)//' m-1: check the '// &
                       'units of the profile (h2o_vmr in mol/mol, pressures in Pa, z_levels in m)')
      end block
      return
    end if
    ! what a 3-D scene needs to rebuild its atmosphere per g-point (setup_scene decides)
    spec%z = z
    spec%lx = cfg%atm%lx
    spec%ly = cfg%atm%ly
    spec%k3d_bottom = cfg%atm%k3d_bottom
    spec%ext1d = ext1d
    spec%ssa1d = ssa1d
    spec%phase1d = phase1d
    spec%tau_abs = tau_abs
    spec%tau_ray = tau_ray
    spec%floor = cfg%thermal%emission_floor
    g = maxloc(energy, 1)
    spec%g_setup = g
    if (lw) then
      ext1d = reshape([ext1d, tau_abs(:, g)/dz], [nz, nc + 1])
      ssa1d = reshape([ssa1d, spread(0.0_wp, 1, nz)], [nz, nc + 1])
      phase1d = reshape([phase1d, spread(1, 1, nz)], [nz, nc + 1])
    else
      phases = [phases, new_phase_rayleigh()]
      iray = size(phases)
      spec%iray = iray
      ext1d = reshape([ext1d, tau_ray(:, g)/dz, tau_abs(:, g)/dz], [nz, nc + 2])
      ssa1d = reshape([ssa1d, spread(1.0_wp, 1, nz), spread(0.0_wp, 1, nz)], [nz, nc + 2])
      phase1d = reshape([phase1d, spread(iray, 1, nz), spread(1, 1, nz)], [nz, nc + 2])
    end if

    if (.not. allocated(scene%air_density)) then
      scene%air_density = (plev(0:nz - 1) - plev(1:nz))/(G0*dz)
      scene%notes = scene%notes//'  layer air density (heating rates): (p_bottom - p_top)/'// &
                    '(g0 dz) of the &kumo_spectral profile, g0 = 9.80665 m s-2'//new_line('a')
    end if
    scene%notes = state_note//scene%notes
    if (spec%gpoint > 0) scene%notes = scene%notes//'  g-point '//str(spec%gpoint)// &
                                       ' alone (&kumo_spectral gpoint): the fluxes and heating '// &
                                       'rates are its own share'//new_line('a')
    if (lw) then
      scene%notes = 'broadband longwave: '//trim(cfg%spectral%kdist_file)//', '//str(ng)// &
                    ' g-points, surface temperature '//str(tsfc)//' K, emissivity '// &
                    str(max(0.0_wp, min(1.0_wp, 1.0_wp - cfg%surface%albedo)))//'; floor share '// &
                    str(cfg%spectral%floor_share)//new_line('a')//'  column optical depth: gas '// &
                    'absorption '//str(minval(sum(tau_abs, 1)))//' to '// &
                    str(maxval(sum(tau_abs, 1)))//new_line('a')//scene%notes
    else
      scene%notes = 'broadband shortwave: '//trim(cfg%spectral%kdist_file)//', '//str(ng)// &
                    ' g-points, total solar irradiance '//str(spec%tsi)//' W m-2, incident '// &
                    str(spec%plan%total)//' W m-2 on a horizontal plane; floor share '// &
                    str(spec%plan%floor_share)//new_line('a')//'  column optical depth: gas '// &
                    'absorption '//str(minval(sum(tau_abs, 1)))//' to '//str(maxval(sum(tau_abs, 1)))// &
                    ', Rayleigh '//str(minval(sum(tau_ray, 1)))//' to '//str(maxval(sum(tau_ray, 1)))// &
                    new_line('a')//scene%notes
    end if
  end subroutine setup_spectral

  !> Warnings on the gas column of a broadband run (levels z(0:nz) [m], level pressures
  !> plev(0:nz) [Pa], layer pressures play and temperatures tlay, water vapour h2o [mol/mol of
  !> dry air]) that no error catches but that point to a wrong unit or profile: vapour above
  !> SUPERSAT times saturation over liquid water at the layer's temperature and pressure
  !> (Bolton 1980, Mon. Wea. Rev. 108, 1046, eq. 10; no layer of an Earth atmosphere holds that
  !> much); a bottom pressure off the U.S. Standard Atmosphere 1976 at that height by more than
  !> a factor 2 (hPa for Pa); layers outside the k-distribution's tables (temperatures tmin..tmax
  !> K, pressures up to pmax Pa), where the optical depths are extrapolated; in the `longwave`,
  !> a surface temperature `tsfc` outside the tables, whose Planck radiance is extrapolated;
  !> with a `sounding` (pressures not from a standard atmosphere at the heights), layers whose
  !> thickness by z differs by more than HYPSO_TOL from that of the hypsometric equation with
  !> their pressures and temperatures, dz = R_d T_v / g0 ln(p_bottom / p_top) (heights in km,
  !> levels shifted by one, a sounding of another place than the grid's). The layer's one
  !> temperature stands for its mean: 10-80 km of the U.S. Standard Atmosphere as one layer is
  !> 1.11 times as thick by z as by the hypsometric equation at the mean of its level
  !> temperatures, 0.89 times at the temperature of its mid-height; hence the wide tolerance.
  function gas_column_warnings(z, plev, play, tlay, h2o, tmin, tmax, pmax, tsfc, longwave, &
                               sounding) result(text)
    real(wp), intent(in) :: z(0:), plev(0:), play(:), tlay(:), h2o(:), tmin, tmax, pmax, tsfc
    logical, intent(in) :: longwave, sounding
    character(len=:), allocatable :: text
    real(wp), parameter :: SUPERSAT = 1.5_wp
    real(wp), parameter :: HYPSO_TOL = 0.25_wp
    character(len=:), allocatable :: list
    real(wp) :: es, qs, worst, p0(1), t0(1), r0(1), dzh, ratio
    integer :: k, n
    type(error_t), allocatable :: err
    text = ''
    ! vapour beyond saturation
    list = ''
    n = 0
    worst = 0.0_wp
    do k = 1, size(play)
      es = 611.2_wp*exp(17.67_wp*(tlay(k) - 273.15_wp)/(tlay(k) - 29.65_wp))
      if (.not. (es < play(k))) cycle        ! boiling: any amount of vapour
      qs = es/(play(k) - es)                 ! saturation mixing ratio of dry air
      if (h2o(k) <= SUPERSAT*qs) cycle
      n = n + 1
      worst = max(worst, h2o(k)/qs)
      if (n <= 6) list = list//merge(', ', '  ', n > 1)//str(k)
    end do
    if (n > 6) list = list//', ...'
    if (n > 0) text = text//'the water vapour of '//str(n)//' layer(s) ('//trim(adjustl(list))// &
      ') exceeds '//str(SUPERSAT)//' times saturation over '// &
      'liquid water at the layer''s temperature and pressure (up to '// &
      str(anint(worst*10.0_wp)/10.0_wp)//' times): '// &
      'h2o_vmr is in mol/mol of dry air (not kg/kg, g/kg or ppmv) and follows the layers '// &
      'from the surface up. '
    ! the bottom pressure against the standard atmosphere at that height
    if (z(0) >= -5000.0_wp .and. z(0) <= 86000.0_wp) then
      call std_atmosphere_profile('us1976', z(0:0), p0, t0, r0, err)
      if (.not. allocated(err)) then
        if (plev(0) > 2.0_wp*p0(1) .or. plev(0) < 0.5_wp*p0(1)) text = text// &
          'the pressure at the bottom of the column ('//str(plev(0))//' Pa at '//str(z(0))// &
          ' m) is '//str(anint(1000.0_wp*plev(0)/p0(1))/1000.0_wp)//' times the U.S. '// &
          'Standard Atmosphere''s there ('//str(p0(1))//' Pa): pressures are in Pa (not hPa), '// &
          'and z_levels are heights above sea level; the gas optics and the air density of the '// &
          'heating rates follow them. '
      end if
    end if
    ! outside the k-distribution's tables
    list = ''
    n = 0
    do k = 1, size(play)
      if (tlay(k) >= tmin .and. tlay(k) <= tmax .and. play(k) <= pmax) cycle
      n = n + 1
      if (n <= 6) list = list//merge(', ', '  ', n > 1)//str(k)//' ('//str(tlay(k))//' K, '// &
                         str(play(k))//' Pa)'
    end do
    if (n > 6) list = list//', ...'
    if (n > 0) text = text//str(n)//' layer(s) lie outside the k-distribution''s tables ('// &
      str(tmin)//' to '//str(tmax)//' K, up to '//str(anint(pmax))//' Pa): '// &
      trim(adjustl(list))//'; their gas optical depths are extrapolated linearly '// &
      'beyond the tables (RRTMGP itself refuses such layers). '
    ! heights against pressures: the hypsometric thickness of each layer
    list = ''
    n = 0
    worst = 1.0_wp
    do k = 1, merge(size(play), 0, sounding)
      ! virtual temperature with h2o in mol/mol of dry air: T (1 + x) / (1 + x M_w / M_d)
      dzh = R_DRY_AIR*tlay(k)*(1.0_wp + h2o(k))/(1.0_wp + h2o(k)*MOLAR_MASS_H2O/MOLAR_MASS_DRY)/ &
            GRAVITY_STD*log(plev(k - 1)/plev(k))
      ratio = (z(k) - z(k - 1))/dzh
      if (abs(ratio - 1.0_wp) <= HYPSO_TOL) cycle
      n = n + 1
      if (abs(log(ratio)) > abs(log(worst))) worst = ratio
      if (n <= 6) list = list//merge(', ', '  ', n > 1)//str(k)//' ('//str(z(k) - z(k - 1), 4)// &
                         ' m, '//str(dzh, 4)//' m)'
    end do
    if (n > 6) list = list//', ...'
    if (n > 0) text = text//'the heights and pressures of '//str(n)//' layer(s) disagree: '// &
      'their thickness by z_levels is '//str(worst, 3)//' times that of the hypsometric '// &
      'equation with their pressures and temperatures, R_d T_v / g0 ln(p_bottom / p_top), '// &
      'or further off (layer: thickness by z_levels, by the pressures: '//trim(adjustl(list))// &
      '); z_levels are in m, and the sounding must be the grid''s: the gas optical depths '// &
      'follow the pressures, the clouds and voxels the heights, and the air density of the '// &
      'heating rates both. '
    if (longwave .and. (tsfc < tmin .or. tsfc > tmax)) then
      text = text//'the surface temperature '//str(tsfc)//' K lies outside the '// &
             'k-distribution''s tables ('//str(tmin)//' to '//str(tmax)//' K): its Planck '// &
             'radiance is extrapolated linearly (to 0 far below)'
      if (tsfc < T_COLD) text = text//'; temperatures are in K, not degrees Celsius'
      text = text//'. '
    end if
  end function gas_column_warnings

  !> The gas state of a &kumo_cloud file's layers for a broadband run (&kumo_spectral gas_state
  !> = 'cloud_file'): rank 0 reads the column means of temperature, pressure and water vapour
  !> per layer, where an LES/CRM netCDF file has them, and every rank puts them into the
  !> profile (kumo_gas_state). Other cloud formats carry no gas state: the profile stays, and
  !> `note` says so.
  subroutine cloud_gas_state(cfg, z, plev, play, tlev, tlay, h2o, note, error)
    type(config_t), intent(in) :: cfg
    real(wp), intent(in) :: z(0:)
    real(wp), intent(inout) :: plev(0:), play(:), tlev(0:), tlay(:), h2o(:)
    character(len=:), allocatable, intent(inout) :: note
    type(error_t), allocatable, intent(out) :: error
    type(cloud_input_t) :: c
    type(cloud_request_t) :: req
    character(len=:), allocatable :: notes, what
    logical :: has_t, has_p, has_q
    real(wp) :: fb, ft
    integer :: kb, kt, n

    if (trim(cfg%cloud%req%format) /= 'les') then
      note = '  gas state: the &kumo_spectral profile (a '//trim(cfg%cloud%req%format)// &
             ' cloud file holds no temperature, pressure or water vapour)'//new_line('a')
      return
    end if
    req = cfg%cloud%req
    req%state_profile = .true.
    req%pressure_profile = .false.
    call read_cloud_on_root(req, c, error, grid_only=.true.)
    if (allocated(error)) then
      call add_context(error, '&kumo_spectral gas_state = ''cloud_file''')
      return
    end if
    notes = ''
    if (allocated(c%notes)) notes = c%notes
    n = c%nz
    has_t = allocated(c%t_profile)
    has_p = allocated(c%pressure)
    has_q = allocated(c%h2o_profile)
    kb = cfg%atm%k3d_bottom
    kt = kb + n - 1
    if (kb < 1 .or. kt > size(play)) then
      call set_error(error, '&kumo_spectral gas_state = ''cloud_file'': the cloud file''s '// &
                     str(n)//' layers do not fit the column from layer '//str(kb))
      return
    end if
    if (.not. (has_t .or. has_p .or. has_q)) then
      note = '  gas state: the &kumo_spectral profile (the cloud file has no temperature, '// &
             'pressure or water vapour)'//new_line('a')//indent(notes)
      return
    end if
    ! an unallocated profile is an absent argument (Fortran 2008)
    call gas_state_merge(z, kb, n, plev, play, tlev, tlay, h2o, error, p_file=c%pressure, &
                         t_file=c%t_profile, h2o_file=c%h2o_profile, f_below=fb, f_above=ft)
    if (allocated(error)) then
      call add_context(error, '&kumo_spectral gas_state = ''cloud_file'' ('// &
                       cfg%cloud%req%path//')')
      return
    end if
    what = ''
    if (has_t) what = what//', temperature'
    if (has_p) what = what//', pressure'
    if (has_q) what = what//', water vapour'
    note = '  gas state of layers '//str(kb)//' to '//str(kt)//' ('//str(z(kb - 1))//' to '// &
           str(z(kt))//' m): the cloud file''s '//what(3:)//' (column means per layer), '// &
           'the &kumo_spectral profile elsewhere'
    if (has_p) note = note//'; the profile''s pressures scaled by '//str(fb)//' below and '// &
                      str(ft)//' above to meet the file''s'
    note = note//new_line('a')//indent(notes)
  contains
    !> Each line of `text` indented by four blanks.
    function indent(text) result(out)
      character(len=*), intent(in) :: text
      character(len=:), allocatable :: out
      integer :: i
      out = ''
      if (len(text) == 0) return
      out = '    '
      do i = 1, len(text)
        out = out//text(i:i)
        if (text(i:i) == new_line('a') .and. i < len(text)) out = out//'    '
      end do
      if (text(len(text):len(text)) /= new_line('a')) out = out//new_line('a')
    end function indent
  end subroutine cloud_gas_state

  !> Broadband longwave, once the atmosphere and the surface exist: for every g-point the
  !> emission table of its layers (the layers' own Planck sources at their bottom and top,
  !> linear in optical depth in between) and of the surface (eps B_sfc, eps = 1 - albedo), and
  !> the sampling plan. The plan's energies are the g-points' total emitted powers P_g (a
  !> batch estimate is sum_g P_g x the g-point's per-photon mean, whatever the plan draws), its
  !> probabilities follow an importance from the radiative exchange of the g-point in the same
  !> column without scattering (exact): half in proportion to F_up(top) + F_down(surface) + the
  !> sum over layers and the surface of |net power|, half to the sum over layers of |net
  !> power| per unit mass (heating). Emission alone would send nearly every photon into
  !> g-points so opaque that they exchange almost nothing (docs/broadband.md). The emission
  !> tables use escape sampling (kumo_emission). When no layer scatters at
  !> any g-point (clear sky, absorbing clouds) and the surface is a uniform Lambert one, every
  !> batch is the exact sum over g-points of `exact_thermal_batch`, with no photons.
  !> `scene%src%em` ends up as the broadband summary (total and per-layer emitted powers) that
  !> the outputs read; the batches install each g-point's own table.
  subroutine setup_spectral_emission(cfg, scene, spec, error)
    type(config_t), intent(in) :: cfg
    type(scene_t), intent(inout) :: scene
    type(spectral_scene_t), intent(inout) :: spec
    type(error_t), allocatable, intent(out) :: error
    type(thermal_column_t) :: col
    type(emission_t) :: em, em_sum, em_g
    real(wp), allocatable :: t3(:, :, :)
    real(wp), allocatable :: energy(:), importance(:), tau(:), fu(:), fd(:), &
                             net(:), xflux(:), xheat(:), mass(:)
    real(wp) :: eps
    integer :: g, nz
    nz = spec%nz
    if (spec%three_d .and. len_trim(cfg%atm%scene_file) > 0) then
      ! voxel temperatures would need each g-point's Planck fractions per voxel: refused, never
      ! silently replaced by the layers' sources
      call scene_temperature_on_root(resolve_path(cfg%atm%scene_file, cfg_path(cfg)), cfg, t3, error)
      if (allocated(error)) return
      if (allocated(t3)) then
        call set_error(error, '&kumo_spectral: the scene file '//trim(cfg%atm%scene_file)// &
                       ' has voxel temperatures; broadband longwave runs take the temperatures '// &
                       'of the &kumo_spectral profile only (voxel temperatures are not available'// &
                       ' yet): remove the variable temperature or use &kumo_thermal for one band')
        return
      end if
    end if
    if (.not. spec%three_d) allocate (spec%em(spec%n_gpt))
    allocate (energy(spec%n_gpt), importance(spec%n_gpt), &
              fu(0:nz), fd(0:nz), net(nz), xflux(spec%n_gpt), &
              xheat(spec%n_gpt))
    ! mass per unit area of each layer (heating per unit net power)
    mass = scene%air_density*(scene%atm%z(1:nz) - scene%atm%z(0:nz - 1))
    do g = 1, spec%n_gpt
      call spectral_set_optics(spec, g, scene%atm, error)
      if (allocated(error)) return
      call gpoint_emission(spec, g, scene, em, error)
      if (allocated(error)) return
      energy(g) = em%power
      ! copies independent of the node's storage, which the next g-point's table reuses; the
      ! voxels' emitted powers are an output, which rank 0 writes: with the voxels on the node,
      ! the other ranks keep no per-voxel array at all
      if (g == spec%gpoint) then
        em_g = em
        call emission_detach(em_g, keep_voxels=par_is_root(), atm=scene%atm)
      end if
      ! totals for the outputs
      if (g == 1) then
        em_sum = em
        call emission_detach(em_sum, keep_voxels=par_is_root(), atm=scene%atm)
      else
        em_sum%emit_sfc = em_sum%emit_sfc + em%emit_sfc
        em_sum%emit_layer = em_sum%emit_layer + em%emit_layer
        if (size(em_sum%emit_vox) > 0) &
          call emission_voxel_power_add(em, scene%atm, em_sum%emit_vox)
      end if
      ! a 1-D column keeps every g-point's table; a 3-D scene rebuilds it per g-point
      if (.not. spec%three_d) then
        spec%em(g) = em
        call emission_bind(spec%em(g))
      end if
      ! the same column without scattering, in the diffusivity approximation (a few per cent,
      ! which is all an importance needs; the exact solution's O(nz^2) exponential integrals
      ! were most of the set-up)
      tau = scene%atm%ext1*(1.0_wp - scene%atm%omg1)*(scene%atm%z(1:nz) - scene%atm%z(0:nz - 1))
      eps = em%eps_mean
      call thermal_column_init_layers(col, tau, spec%src_bot(:, g), spec%src_top(:, g), eps, &
                                      spec%src_sfc(g), 0.0_wp, error)
      if (allocated(error)) then
        call add_context(error, '&kumo_spectral: g-point '//str(g))
        return
      end if
      call thermal_column_fluxes_diffusivity(col, fu, fd, net)
      xflux(g) = fu(nz) + fd(0) + sum(abs(net)) + abs(eps*fd(0) - em%emit_sfc)
      xheat(g) = sum(abs(net)/mass)
    end do
    if (spec%node) call note_table_storage(em, cfg%control%verbose)
    ! half by the fluxes and net powers (W m-2), half by the heating rates (per unit mass), never
    ! below a tiny share of the g-point's emission (a g-point with energy is drawn)
    importance = 0.5_wp*xflux/max(tiny(1.0_wp), sum(xflux)) + 0.5_wp*xheat/max(tiny(1.0_wp), sum(xheat))
    importance = max(importance, 1.0e-9_wp*energy/sum(energy))
    if (spec%gpoint > 0) then
      ! one g-point alone: the others get no energy (never drawn) and leave the summary
      where ([(g, g=1, spec%n_gpt)] /= spec%gpoint) energy = 0.0_wp
      em_sum = em_g
    end if
    call spectral_plan_init(energy, spec%plan, error, floor_share=cfg%spectral%floor_share, &
                            importance=importance)
    if (allocated(error)) then
      call add_context(error, '&kumo_spectral')
      return
    end if
    spec%norm = spec%plan%total
    ! the broadband summary the outputs read: total powers, no single band
    spec%em_sum = em_sum
    spec%em_sum%power = sum(energy)
    spec%em_sum%has_band = .false.
    spec%em_sum%radiance_units = 'W m-2 sr-1'
    spec%em_sum%flux_units = 'W m-2'
    spec%em_sum%to_band_units = 1.0_wp
    call emission_bind(spec%em_sum)
    scene%src%em = spec%em_sum
    call emission_bind(scene%src%em)
    ! exact per g-point (decided in setup_scene once the detectors exist), or traced: never
    ! the summary's own exact column
    scene%exact_thermal = .false.
    scene%notes = scene%notes//'  emitted power '//str(spec%em_sum%power)//' W m-2 (layers '// &
                  str(sum(spec%em_sum%emit_layer))//', surface '//str(spec%em_sum%emit_sfc)// &
                  '); g-points drawn by their exchange without scattering, the largest share '// &
                  str(maxval(spec%plan%prob))//' to g-point '//str(maxloc(spec%plan%prob, 1))// &
                  new_line('a')
  end subroutine setup_spectral_emission

  !> Switch the scene to g-point g: the optics of its 1-D layers (copies of precomputed
  !> totals, albedos, cumulative scattering fractions and classes, no allocation) or, in a 3-D
  !> scene, the atmosphere rebuilt from the scene file's voxels and the g-point's gas (and
  !> Rayleigh) layers, which inside the 3-D region are the voxels' background; in the longwave
  !> also the g-point's emission table (stored for 1-D columns, rebuilt for 3-D scenes).
  subroutine spectral_set_gpoint(spec, g, scene, error)
    type(spectral_scene_t), intent(inout) :: spec
    integer, intent(in) :: g
    type(scene_t), intent(inout) :: scene
    type(error_t), allocatable, intent(out) :: error
    call spectral_set_optics(spec, g, scene%atm, error)
    if (allocated(error)) return
    if (spec%truncated) then
      ! the delta fractions stay; an atmosphere built anew gets them back, the layers' mix of
      ! them follows the g-point's optics
      if (scene%atm%truncated .and. allocated(scene%atm%ext1_lev)) then
        call atmosphere_refresh_truncation(scene%atm)
      else
        call atmosphere_set_truncation(scene%atm, spec%trunc)
      end if
    end if
    if (spec%forcing) then
      if (spec%cf(g) <= 0.0_wp) spec%cf(g) = collision_forcing(scene%atm, scene%mu0, &
                                                               spec%cf_tau_min)
      scene%vr%cf_factor = spec%cf(g)
    end if
    if (.not. spec%longwave) return
    if (allocated(spec%em)) then
      scene%src%em = spec%em(g)
      call emission_bind(scene%src%em)
    else
      call gpoint_emission(spec, g, scene, scene%src%em, error)
    end if
    scene%src%em%iph_iso = spec%iph_iso
  end subroutine spectral_set_gpoint

  !> The optics of g-point g in the atmosphere (see spectral_set_gpoint).
  subroutine spectral_set_optics(spec, g, atm, error)
    type(spectral_scene_t), intent(inout) :: spec
    integer, intent(in) :: g
    type(atmosphere_t), intent(inout) :: atm
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: e(:, :), w(:, :)
    integer, allocatable :: ip(:, :)
    type(phase_t), allocatable :: ph(:)
    integer :: nz, n_out_liq, n_out_ice, b
    logical :: done, new_band
    if (.not. spec%three_d) then
      atm%ext1(:) = spec%ext1(:, g)
      atm%omg1(:) = spec%omg1(:, g)
      atm%csca1(1:spec%ncomp, :) = spec%csca1(:, :, g)
      atm%layer_class(:) = spec%layer_class(:, g)
      return
    end if
    nz = spec%nz
    call gpoint_background(spec, g, e, w, ip)
    if (spec%cloud_on) then
      ! the cloud's voxels at the g-point's band over its gas layers, swapped into the voxel
      ! arrays: within a band only the gas, at another band also the cloud's optics, phase
      ! indices and blends (its writer forms them first). Where a swap declines, the atmosphere
      ! is built anew; its phase functions (every band's) move out of it and back in, uncopied.
      ! Voxels the node shares are rewritten, by a share of the layers on each of its ranks,
      ! once no rank of the node traces the last g-point any more.
      if (spec%node) call par_node_sync()
      b = spec%gpt_band(g)
      new_band = b /= spec%atm_band
      if (new_band .and. atm%voxel_writer .and. spec%cloud%band /= b) &
        call spectral_cloud_band(spec%cloud, b, n_out_liq, n_out_ice)
      ! a band's checks, and the uniform layers after a switch to g-point g, come out the same
      ! at every batch: found at the first switch, then handed in
      if (.not. allocated(spec%uni3)) then
        allocate (spec%band_checked(maxval(spec%gpt_band)), spec%uni3(atm%n3, spec%n_gpt), &
                  spec%uni_known(spec%n_gpt))
        spec%band_checked = .false.
        spec%uni_known = .false.
      end if
      if (spec%node) then
        call atmosphere_swap_background(atm, e, w, spec%cloud%cext, spec%cloud%cssa, &
                                        spec%aopts, spec%sv_layout, done, sync=par_node_sync, &
                                        part=par_node_rank(), nparts=par_node_size(), &
                                        new_band=new_band, ciph=spec%cloud%ciph, &
                                        cwph=spec%cloud%cwph, checked=spec%band_checked(b), &
                                        uniform3=spec%uni3(:, g), &
                                        uniform3_known=spec%uni_known(g), &
                                        same_clear=spec%cloud%wet_exact)
      else
        call atmosphere_swap_background(atm, e, w, spec%cloud%cext, spec%cloud%cssa, &
                                        spec%aopts, spec%sv_layout, done, new_band=new_band, &
                                        ciph=spec%cloud%ciph, cwph=spec%cloud%cwph, &
                                        checked=spec%band_checked(b), &
                                        uniform3=spec%uni3(:, g), &
                                        uniform3_known=spec%uni_known(g), &
                                        same_clear=spec%cloud%wet_exact)
      end if
      if (done) then
        if (new_band) then
          spec%band_checked(b) = .true.
          spec%uni3(:, g) = atm%uniform3
          spec%uni_known(g) = .true.
          spec%atm_band = b
        end if
        return
      end if
      call move_alloc(atm%phases, ph)
      if (spec%node) then
        call atmosphere_begin(atm, spec%z, spec%lx, spec%ly, e, w, ip, ph, spec%aopts, error, &
                              spec%k3d_bottom, spec%cloud%nx, spec%cloud%ny, spec%cloud%nz, &
                              spec%cloud%nc3, blend=.true., storage=node_voxels)
      else
        call atmosphere_begin(atm, spec%z, spec%lx, spec%ly, e, w, ip, ph, spec%aopts, error, &
                              spec%k3d_bottom, spec%cloud%nx, spec%cloud%ny, spec%cloud%nz, &
                              spec%cloud%nc3, blend=.true.)
      end if
      if (allocated(error)) return
      if (atm%voxel_writer) call spectral_cloud_put(spec%cloud, atm)   ! the band's (above)
      spec%atm_band = b
      if (spec%node) then
        call atmosphere_end(atm, spec%aopts, error, sv_layout=spec%sv_layout, sync=par_node_sync)
      else
        call atmosphere_end(atm, spec%aopts, error, sv_layout=spec%sv_layout)
      end if
    else if (spec%node) then
      ! a scene file's voxels in the node's window: its first rank (which alone holds the
      ! fields) rebuilds them once no rank of the node traces the last g-point any more
      call par_node_sync()
      call atmosphere_init(atm, spec%z, spec%lx, spec%ly, e, w, ip, spec%phases, spec%aopts, &
                           error, spec%k3d_bottom, spec%ext3, spec%ssa3, spec%iph3, &
                           n3d=spec%n3d, storage=node_voxels, sync=par_node_sync)
    else if (allocated(spec%iph3)) then
      call atmosphere_init(atm, spec%z, spec%lx, spec%ly, e, w, ip, spec%phases, spec%aopts, &
                           error, spec%k3d_bottom, spec%ext3, spec%ssa3, spec%iph3)
    else
      call atmosphere_init(atm, spec%z, spec%lx, spec%ly, e, w, ip, spec%phases, spec%aopts, &
                           error, spec%k3d_bottom, spec%ext3, spec%ssa3)
    end if
  end subroutine spectral_set_optics

  !> The 1-D components of every layer at g-point g, (nz, ncomp): the namelist's layers, then in
  !> the shortwave Rayleigh scattering, then the gas's absorption; extinction [m-1], albedo and
  !> phase index. Inside the 3-D region they are the voxels' background.
  subroutine gpoint_background(spec, g, e, w, ip)
    type(spectral_scene_t), intent(in) :: spec
    integer, intent(in) :: g
    real(wp), allocatable, intent(out) :: e(:, :), w(:, :)
    integer, allocatable, intent(out) :: ip(:, :)
    real(wp), allocatable :: dz(:)
    integer :: nz
    nz = spec%nz
    dz = spec%z(2:nz + 1) - spec%z(1:nz)     ! z is 1-based here (levels 0..nz)
    if (spec%longwave) then
      e = reshape([spec%ext1d, spec%tau_abs(:, g)/dz], [nz, size(spec%ext1d, 2) + 1])
      w = reshape([spec%ssa1d, spread(0.0_wp, 1, nz)], [nz, size(spec%ext1d, 2) + 1])
      ip = reshape([spec%phase1d, spread(1, 1, nz)], [nz, size(spec%ext1d, 2) + 1])
    else
      e = reshape([spec%ext1d, spec%tau_ray(:, g)/dz, spec%tau_abs(:, g)/dz], &
                  [nz, size(spec%ext1d, 2) + 2])
      w = reshape([spec%ssa1d, spread(1.0_wp, 1, nz), spread(0.0_wp, 1, nz)], &
                  [nz, size(spec%ext1d, 2) + 2])
      ip = reshape([spec%phase1d, spread(spec%iray, 1, nz), spread(1, 1, nz)], &
                   [nz, size(spec%ext1d, 2) + 2])
    end if
  end subroutine gpoint_background

  !> The emission table of g-point g for the atmosphere as it is (set to g): the layers' own
  !> bottom and top Planck sources, the surface's, escape sampling.
  !> Over a cloud file the table draws the voxels layer by layer (kumo_emission, `voxel_abs`):
  !> the cloud's part of their absorption is summed over rows once per band (`spec%va`), the
  !> gas's part is the layer's, so a switch forms the table without a sweep over the voxels,
  !> and every rank forms its own (it is small: one entry per layer).
  subroutine gpoint_emission(spec, g, scene, em, error)
    type(spectral_scene_t), intent(inout) :: spec
    integer, intent(in) :: g
    type(scene_t), intent(in) :: scene
    type(emission_t), intent(out) :: em
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: b_lev(:), kb(:), e(:, :), w(:, :)
    integer, allocatable :: ip(:, :)
    integer :: kr, k
    allocate (b_lev(0:spec%nz))
    ! level values: only what voxels would read, and voxels take the layers' own mean
    b_lev(0) = spec%src_bot(1, g)
    b_lev(1:spec%nz) = spec%src_top(:, g)
    if (spec%cloud_on .and. scene%atm%n3 > 0) then
      if (spec%va_band /= spec%atm_band) then
        call voxel_abs_init(spec%va, scene%atm, spec%cloud%cext, spec%cloud%cssa, &
                            scene%atm%k3_lo - scene%atm%kf_lo)
        spec%va_band = spec%atm_band
      end if
      ! what every voxel of a layer absorbs: its background (spectral_set_optics)
      call gpoint_background(spec, g, e, w, ip)
      allocate (kb(scene%atm%n3))
      do kr = 1, scene%atm%n3
        k = scene%atm%k3_lo + kr - 1
        kb(kr) = sum(e(k, :)*(1.0_wp - w(k, :)), mask=e(k, :) > 0.0_wp)
      end do
      call emission_init(em, scene%atm, scene%sfc, b_lev, spec%src_sfc(g), 0.0_wp, 0.0_wp, &
                         spec%floor, error, b_layer_bottom=spec%src_bot(:, g), &
                         b_layer_top=spec%src_top(:, g), escape_sampling=.true., &
                         voxel_abs=spec%va, layer_abs=kb)
    else if (spec%node) then
      ! in the node's storage (the last g-point's table is no longer read: spectral_set_optics)
      call emission_init(em, scene%atm, scene%sfc, b_lev, spec%src_sfc(g), 0.0_wp, 0.0_wp, &
                         spec%floor, error, b_layer_bottom=spec%src_bot(:, g), &
                         b_layer_top=spec%src_top(:, g), escape_sampling=.true., &
                         storage=node_table, sync=par_node_sync)
    else
      call emission_init(em, scene%atm, scene%sfc, b_lev, spec%src_sfc(g), 0.0_wp, 0.0_wp, &
                         spec%floor, error, b_layer_bottom=spec%src_bot(:, g), &
                         b_layer_top=spec%src_top(:, g), escape_sampling=.true.)
    end if
    if (allocated(error)) call add_context(error, '&kumo_spectral: g-point '//str(g))
  end subroutine gpoint_emission

  !> Storage for the voxels of a broadband run with several ranks (spectral_scene_t node): one
  !> window of the node, used again by every g-point (kumo_parallel par_node_window).
  subroutine node_voxels(nbytes, base, writer)
    integer(i8), intent(in) :: nbytes
    type(c_ptr), intent(out) :: base
    logical, intent(out) :: writer
    call par_node_window(1, nbytes, base, writer)
  end subroutine node_voxels

  !> The same for the cloud's optics of the current band (spectral_cloud_place).
  subroutine node_cloud(nbytes, base, writer)
    integer(i8), intent(in) :: nbytes
    type(c_ptr), intent(out) :: base
    logical, intent(out) :: writer
    call par_node_window(3, nbytes, base, writer)
  end subroutine node_cloud

  !> The same for each g-point's emission table in the longwave.
  subroutine node_table(nbytes, base, writer)
    integer(i8), intent(in) :: nbytes
    type(c_ptr), intent(out) :: base
    logical, intent(out) :: writer
    call par_node_window(2, nbytes, base, writer)
  end subroutine node_table

  !> The RRTMGP cloud-optics file of a broadband run with a cloud file: &kumo_spectral
  !> cloud_optics_file if given (found like the k-distribution, kdist_location), otherwise
  !> cloudysky_sw.nc or cloudysky_lw.nc (by the kind of the k-distribution, `longwave`) in
  !> the k-distribution's folder or, failing that, in the folder scripts/fetch-rrtmgp.sh fills.
  function cloud_optics_location(cfg, longwave) result(loc)
    type(config_t), intent(in) :: cfg
    logical, intent(in) :: longwave
    character(len=:), allocatable :: loc, kd, name
    integer :: slash
    if (allocated(cfg%spectral%cloud_optics_path)) then
      loc = kdist_location(cfg%spectral%cloud_optics_file, cfg%spectral%cloud_optics_path)
      return
    end if
    kd = kdist_location(cfg%spectral%kdist_file, cfg%spectral%kdist_path)
    name = merge('cloudysky_lw.nc', 'cloudysky_sw.nc', longwave)
    slash = index(kd, '/', back=.true.)
    loc = kdist_location(name, kd(1:slash)//name)
  end function cloud_optics_location

  !> Where broadband runs keep kumo's band-averaged Mie tables unless &kumo_cloud mie_cache
  !> says: kumo-band-mie-sw.nc or kumo-band-mie-lw.nc in the k-distribution's folder (a file
  !> whose request differs is computed again and replaced).
  function band_mie_default_cache(cfg, longwave) result(path)
    type(config_t), intent(in) :: cfg
    logical, intent(in) :: longwave
    character(len=:), allocatable :: path, kd
    kd = kdist_location(cfg%spectral%kdist_file, cfg%spectral%kdist_path)
    path = kd(1:index(kd, '/', back=.true.))//'kumo-band-mie-'//merge('lw', 'sw', longwave)//'.nc'
  end function band_mie_default_cache

  !> The namelist's path ('' when the configuration was not read from a file).
  function cfg_path(cfg) result(path)
    type(config_t), intent(in) :: cfg
    character(len=:), allocatable :: path
    path = ''
    if (allocated(cfg%path)) path = cfg%path
  end function cfg_path

  !> Radiance detectors, cameras and the variance reduction that serves them. Truncation and
  !> collision forcing act on local estimates only, so they are set up only when radiances or
  !> cameras are requested: a flux run pays for neither.
  subroutine setup_estimators(cfg, scene, error)
    type(config_t), intent(in) :: cfg
    type(scene_t), intent(inout) :: scene
    type(error_t), allocatable, intent(out) :: error
    type(camera_t), allocatable :: cams(:)
    type(truncation_t) :: tr
    integer :: i, kind

    allocate (cams(cfg%cam%n))
    do i = 1, cfg%cam%n
      kind = CAMERA_PINHOLE
      if (cfg%cam%kind(i) == 'orthographic') kind = CAMERA_ORTHOGRAPHIC
      call camera_init(cams(i), kind, cfg%cam%pos(:, i), cfg%cam%look_zenith_deg(i), &
                       cfg%cam%look_azimuth_deg(i), cfg%cam%roll_deg(i), cfg%cam%fov_deg(i), &
                       cfg%cam%width(i), cfg%cam%npx(i), cfg%cam%npy(i), cfg%atm%lx, cfg%atm%ly, &
                       scene%atm%z(scene%atm%nz), error)
      if (allocated(error)) then
        call add_context(error, '&kumo_camera: camera '//str(i))
        return
      end if
    end do
    if (allocated(cfg%rad%mu)) then
      ! numerical diffusion: the spread is `diffusion` x half the mean spacing of the photons
      ! of the run at the top, sqrt(lx ly / N)/2, x sqrt(pi a) (MCARaTS, state-of-the-art B5);
      ! it shrinks as the photon count grows
      call detectors_init(scene%det, cfg%rad%mu, cfg%rad%phi_deg, cfg%rad%levels, cams, &
                          cfg%vr%zeta_min, cfg%atm%lx, cfg%atm%ly, &
                          cfg%vr%diffusion*0.5_wp*sqrt(cfg%atm%lx*cfg%atm%ly/ &
                          (real(cfg%control%n_photons_per_batch, wp)*cfg%control%n_batches)), &
                          cfg%vr%diffusion_max, cfg%vr%ddis_eps)
    else   ! a configuration built in code without radiances
      call detectors_init(scene%det, [real(wp) ::], [real(wp) ::], [integer ::], cams, &
                          cfg%vr%zeta_min, cfg%atm%lx, cfg%atm%ly)
    end if
    if (.not. scene%det%active) return

    if (cfg%vr%trunc_levels > 1) then
      call truncation_init(tr, scene%atm%phases, cfg%vr%trunc_theta_max_deg, &
                           cfg%vr%trunc_levels, &
                           cfg%vr%trunc_peak, error)
      if (allocated(error)) then
        call add_context(error, '&kumo_vr: truncation')
        return
      end if
      call atmosphere_set_truncation(scene%atm, tr)
    end if

    scene%vr%cf_factor = collision_forcing(scene%atm, scene%mu0, cfg%vr%cf_tau_min)
    ! forcing raises the column's optical depth along the sun's path to cf_tau_min, so a photon
    ! makes about that many collisions on each crossing: a large value is a runaway cost
    if (scene%vr%cf_factor > 1.0_wp .and. cfg%vr%cf_tau_min > CF_WARN_TAU) &
      scene%warnings = scene%warnings//'collision forcing to cf_tau_min = '// &
        str(cfg%vr%cf_tau_min)//' (factor '//str(scene%vr%cf_factor)//' on the extinction): '// &
        'a photon makes about '//str(cfg%vr%cf_tau_min)//' collisions on each crossing of '// &
        'the atmosphere and the time per photon grows in proportion; the presets use 1 to 3. '
    ! Truncation is an approximation: its bias grows with the angle and towards grazing views.
    ! A camera pixel sees light travelling against its view direction L; the pixels of a camera
    ! look up to camera_half_angle away from L.
    if (scene%atm%truncated) then
      if (cfg%vr%trunc_theta_max_deg > TRUNC_WARN_DEG) scene%warnings = scene%warnings// &
        'trunc_theta_max_deg = '//str(cfg%vr%trunc_theta_max_deg)//' is beyond '// &
        str(nint(TRUNC_WARN_DEG))//' degrees (the standard preset''s), where the bias of '// &
        'truncated radiances grows quickly with the angle (plane-parallel Henyey-Greenstein '// &
        'slabs against DISORT: up to 2.7 % at 40 degrees, the quick preset''s, 4.8 % at 50, '// &
        '7 % at 60, 15 % at 89; docs/radiances.md); the standard preset''s 30 keeps it within '// &
        'about 0.5 % from |mu| = 0.5 to 1. '
      if (cfg%vr%trunc_theta_max_deg > TRUNC_GRAZING_DEG) then
        block
          character(len=:), allocatable :: list
          real(wp) :: zen
          list = ''
          do i = 1, size(scene%det%uz)
            if (abs(scene%det%uz(i)) >= TRUNC_GRAZING_MU) cycle
            if (len(list) > 0) list = list//', '
            list = list//str(i)
          end do
          if (len(list) > 0) scene%warnings = scene%warnings//'radiance direction(s) '//list// &
            ' are closer to the horizon than |rad_mu| = '//str(TRUNC_GRAZING_MU)//', where '// &
            'truncated radiances are biased (plane-parallel Henyey-Greenstein slabs against '// &
            'DISORT at |mu| 0.2 to 0.4: -1.5 to +1.2 % with the standard preset, +1.9 % near '// &
            'the sun''s direction at the surface, against within 0.55 % from |mu| = 0.5 up; '// &
            'docs/radiances.md); vr_preset = "unbiased" has no such bias, and '// &
            'trunc_theta_max_deg = 15 none measurable, at about twice the time to a given error. '
          ! a camera reaches |mu| < TRUNC_GRAZING_MU when its cone about L meets the zenith
          ! angles between acos(TRUNC_GRAZING_MU) and acos(-TRUNC_GRAZING_MU)
          do i = 1, size(cams)
            zen = acos(max(-1.0_wp, min(1.0_wp, cams(i)%look(3))))
            if (max(acos(TRUNC_GRAZING_MU) - zen, zen - acos(-TRUNC_GRAZING_MU)) <= &
                camera_half_angle(cams(i))) scene%warnings = scene%warnings//'camera '// &
              str(i)//' sees directions closer to the horizon than |mu| = '// &
              str(TRUNC_GRAZING_MU)//', where truncated radiances are biased (-1.5 to +1.9 % '// &
              'at |mu| 0.2 to 0.4 with the standard preset; docs/radiances.md); vr_preset = '// &
              '"unbiased" has no such bias, and trunc_theta_max_deg = 15 none measurable. '
          end do
        end block
      end if
    end if
    ! Truncation biases radiances near the exact backscatter (hot-spot) direction of a 3-D
    ! field: the delta part sends forward-scattered light straight back along the sun's own
    ! path, which overstates how well the way out repeats the way in (measured on the I3RC LES:
    ! +1.9 % at the hot spot, within 0.3 % from 5 degrees away; docs/radiances.md). A camera
    ! holds the hot spot when a pixel looks along the sun's beam.
    if (scene%atm%truncated .and. scene%atm%n3 > 0 .and. &
        .not. (scene%src%em%on .and. scene%src%em%solar_power <= 0.0_wp)) then
      do i = 1, size(scene%det%ux)
        if (-(scene%det%ux(i)*scene%src%ux + scene%det%uy(i)*scene%src%uy + &
              scene%det%uz(i)*scene%src%uz) >= cos(HOTSPOT_WARN_DEG*DEG2RAD)) then
          scene%warnings = scene%warnings//'radiance direction '//str(i)//' is within '// &
            str(nint(HOTSPOT_WARN_DEG))//' degrees of the exact backscatter (hot-spot) '// &
            'direction, where the truncation of forward peaks (trunc_theta_max_deg = '// &
            str(cfg%vr%trunc_theta_max_deg)//') biases 3-D radiances high by up to about 2 % '// &
            '(docs/radiances.md); vr_preset = "unbiased" or trunc_theta_max_deg = 8 keeps '// &
            'the bias below 0.5 %. '
        end if
      end do
      do i = 1, size(cams)
        if (acos(max(-1.0_wp, min(1.0_wp, dot_product(cams(i)%look, &
                 [scene%src%ux, scene%src%uy, scene%src%uz])))) <= &
            camera_half_angle(cams(i)) + HOTSPOT_WARN_DEG*DEG2RAD) &
          scene%warnings = scene%warnings//'camera '//str(i)//' sees within '// &
            str(nint(HOTSPOT_WARN_DEG))//' degrees of the exact backscatter (hot-spot) '// &
            'direction, where the truncation of forward peaks biases 3-D radiances high by up '// &
            'to about 2 % (docs/radiances.md); vr_preset = "unbiased" or '// &
            'trunc_theta_max_deg = 8 keeps the bias below 0.5 %. '
      end do
    end if
    do i = 1, size(cams)
      if (cams(i)%capped) scene%warnings = scene%warnings//'camera '//str(i)// &
        ' sees the periodic scene up to the horizon; copies beyond '// &
        str(MAX_IMAGE_SHIFTS)//' domain lengths are left out (pixels near the horizon are low). '
    end do

    scene%det%ddis_mu_cone = cos(DDIS_CONE_DEG*DEG2RAD)
    deallocate (scene%det%ddis_phase)
    allocate (scene%det%ddis_phase(size(scene%atm%phases)))
    scene%det%ddis_phase = ddis_phases(scene%atm%phases)
    call detectors_bounds(scene%det, scene%atm)   ! roulette of weak contributions before P

    ! local estimates with a forward peak and no variance reduction converge very slowly (one
    ! rare near-forward scattering dominates)
    if (spiky_without_vr(scene%atm%phases, cfg%vr%zeta_min, scene%atm%truncated)) then
      scene%warnings = scene%warnings//'radiances are requested for a phase function with a forward peak '// &
                       '(P(0) > '//str(SPIKY_PEAK)//') with local-estimate roulette and '// &
                       'truncation off: pixel radiances will be very noisy; vr_preset = '// &
                       '"unbiased" (roulette) or "standard" (also truncation) is recommended'
    end if
  end subroutine setup_estimators

  !> Rank 0 reads the 3-D optical properties and broadcasts them; every rank ends with the same
  !> arrays, or the same error.
  subroutine read_scene_on_root(cfg, path, ext3, ssa3, iph3, error)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: path
    real(wp), allocatable, intent(out) :: ext3(:, :, :, :), ssa3(:, :, :, :)
    integer, allocatable, intent(out) :: iph3(:, :, :, :)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: b
    integer :: i
    logical :: has_iph
    if (par_is_root()) then
      call read_scene_3d(path, cfg%atm%nx, cfg%atm%ny, cfg%atm%nz3, cfg%atm%n_components_3d, &
                         ext3, ssa3, iph3, has_iph, error)
      if (.not. allocated(error)) then
        call b%put(ext3)
        call b%put(ssa3)
        call b%put(has_iph)
        if (has_iph) call b%put(iph3)
      end if
    end if
    call b%share(error)
    if (allocated(error)) return
    call b%get(ext3)
    call b%get(ssa3)
    call b%get(has_iph)
    if (has_iph) then
      call b%get(iph3)
    else
      if (allocated(iph3)) deallocate (iph3)
      allocate (iph3(size(ext3, 1), size(ext3, 2), size(ext3, 3), size(ext3, 4)))
      do i = 1, size(ext3, 4)
        iph3(:, :, :, i) = cfg%atm%phase3d(i)
      end do
    end if
  end subroutine read_scene_on_root

  !> The voxel fields of a scene file (`scene_file`), read on rank 0 (read_scene_3d), on the
  !> first rank of every node alone (its leader): extinction, albedo and, when the file has
  !> them (`has_iph`), the phase indices. Every rank gets their shape `shp`, or rank 0's error.
  !> Every rank calls it.
  subroutine scene_fields_on_leaders(cfg, path, ext3, ssa3, iph3, has_iph, shp, error)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: path
    real(wp), allocatable, intent(out) :: ext3(:, :, :, :), ssa3(:, :, :, :)
    integer, allocatable, intent(out) :: iph3(:, :, :, :)
    logical, intent(out) :: has_iph
    integer, intent(out) :: shp(4)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: bg
    integer, allocatable :: shape_read(:)
    has_iph = .false.
    if (par_is_root()) then
      call read_scene_3d(path, cfg%atm%nx, cfg%atm%ny, cfg%atm%nz3, cfg%atm%n_components_3d, &
                         ext3, ssa3, iph3, has_iph, error)
      if (.not. allocated(error)) then
        shape_read = shape(ext3)
        call bg%put(shape_read)
      end if
    end if
    call bg%share(error)
    if (allocated(error)) return
    call bg%get(shape_read)
    shp = shape_read
    ! one node: rank 0 is its only leader and keeps what it read
    if (par_node_leader() .and. par_node_size() < par_size()) then
      block
        ! freed at the end of the block, before the voxel arrays are allocated
        type(bundle_t) :: b
        if (par_is_root()) then
          call b%put(ext3)
          call b%put(ssa3)
          call b%put(has_iph)
          if (has_iph) call b%put(iph3)
          deallocate (ext3, ssa3)
          if (allocated(iph3)) deallocate (iph3)
        end if
        call b%share(error, leaders=.true.)
        call b%get(ext3)
        call b%get(ssa3)
        call b%get(has_iph)
        if (has_iph) call b%get(iph3)
      end block
    end if
    if (.not. has_iph .and. allocated(iph3)) deallocate (iph3)
  end subroutine scene_fields_on_leaders

  !> The atmosphere of a scene file (`scene_file`) on several ranks, one copy per node: rank 0
  !> reads the file (read_scene_3d) and every rank gets the sizes of its voxel fields, or rank
  !> 0's error; the fields themselves go to the first rank of each node alone (the node's
  !> leader), which puts them into voxel arrays in memory the node shares (kumo_parallel
  !> par_node_storage), through atmosphere_init as on one rank, so its values are those of one
  !> rank, bit for bit.
  !> Every rank calls it (the window and its barrier are collective).
  subroutine scene_on_ranks(cfg, path, ext1d, ssa1d, phase1d, phases, aopts, atm, error)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: path
    real(wp), intent(in) :: ext1d(:, :), ssa1d(:, :)
    integer, intent(in) :: phase1d(:, :)
    type(phase_t), intent(in) :: phases(:)
    type(atmosphere_options_t), intent(in) :: aopts
    type(atmosphere_t), intent(inout) :: atm
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: ext3(:, :, :, :), ssa3(:, :, :, :)
    integer, allocatable :: iph3(:, :, :, :)
    integer :: shp(4)
    logical :: has_iph
    call scene_fields_on_leaders(cfg, path, ext3, ssa3, iph3, has_iph, shp, error)
    if (allocated(error)) return
    ! the node leaders put the fields into the window; the other ranks give only their shape
    call atmosphere_init(atm, cfg%atm%z, cfg%atm%lx, cfg%atm%ly, ext1d, ssa1d, phase1d, phases, &
                         aopts, error, cfg%atm%k3d_bottom, ext3, ssa3, iph3, &
                         iph3_const=cfg%atm%phase3d(1:shp(4)), n3d=shp(1:4), &
                         storage=par_node_storage, sync=par_node_sync)
    if (allocated(error)) return
    call note_voxel_storage(atm, cfg%control%verbose)
  end subroutine scene_on_ranks

  !> The cloud's atmosphere on every rank. Rank 0 reads the cloud file (liquid water, then ice
  !> water and the ice optics table when the file has ice) and every rank gets them
  !> (read_cloud_on_root, mie_table_put/get), and so does the water Mie table, which rank 0
  !> alone reads from the cache or computes; the atmosphere is then built from them without
  !> MPI, on rank 0 first so that its error, if any, is every rank's.
  !>
  !> On several ranks the cloud (water content, liquid and ice if any; an optics file; an
  !> MCARaTS file) is kept once per node: only the first rank of each node gets the fields, and
  !> the ranks of a node build one atmosphere whose voxel arrays lie in memory the node shares
  !> (kumo_parallel par_node_storage: an MPI-3 shared-memory window), filled by that first rank.
  !> What an MCARaTS file's values decide before the build (mcarats_scan: tables used, blends,
  !> the absorption perturbation and its check) rank 0 finds and shares. The ranks then build
  !> together (the window and its barrier are collective); they read the same inputs and
  !> values, so they meet the same errors. The run log says what each rank holds. Thermal runs
  !> that take the file's temperatures keep them with the node's first rank too, which checks
  !> them (rank 0's verdict is every rank's) and alone forms the voxels' Planck radiances
  !> (setup_thermal); the other ranks get only what describes them (`cloud_t` without `t`).
  subroutine cloud_on_ranks(cfg, ext1d, ssa1d, phase1d, phases, aopts, atm, notes, warnings, &
                            error, cloud_t, shared)
    type(config_t), intent(in) :: cfg
    real(wp), intent(in) :: ext1d(:, :), ssa1d(:, :)
    integer, intent(in) :: phase1d(:, :)
    type(phase_t), allocatable, intent(inout) :: phases(:)
    type(atmosphere_options_t), intent(in) :: aopts
    type(atmosphere_t), intent(out) :: atm
    character(len=:), allocatable, intent(out) :: notes, warnings
    type(error_t), allocatable, intent(out) :: error
    !> thermal runs with a spectral interval: the cloud file's temperatures, if it has them
    type(cloud_temperature_t), intent(out) :: cloud_t
    !> several ranks build the scene together (setup_scene per_node): one copy per node
    logical, intent(in) :: shared
    type(bundle_t) :: b, bi, bl, bm
    type(cloud_input_t) :: c, c_ice
    type(mcarats_scan_t) :: scan
    integer, allocatable :: used(:)
    type(cloud_request_t) :: req
    type(mie_table_t) :: ice, liq
    character(len=:), allocatable :: liq_action
    logical :: want_t, has_t
    want_t = cfg%thermal%enabled .and. .not. allocated(cfg%thermal%planck_levels)
    req = cfg%cloud%req
    req%temperature = want_t
    call read_cloud_on_root(req, c, error, part='liquid', per_node=shared, has_temperature=has_t)
    if (allocated(error)) return
    if (shared .and. want_t) then
      ! the temperatures, on the node leaders alone, checked there before the collective build
      ! (build_cloud_atmosphere would check them on the leaders only): rank 0's verdict and
      ! what describes them on every rank
      block
        type(bundle_t) :: bt
        if (par_node_leader()) call take_temperature(c, cfg%cloud%req%path, cloud_t, error)
        call bt%share(error)
        if (allocated(error)) return
        if (has_t .and. .not. par_node_leader()) then
          cloud_t%found = .true.
          cloud_t%planes = c%t_planes
          cloud_t%perturbation = c%t_perturbation
          cloud_t%source = c%t_source
        end if
      end block
    end if
    if (shared .and. c%content /= cfg%cloud%grid%content) then
      ! every rank holds rank 0's content code: they all stop here alike
      call set_error(error, cfg%cloud%req%path//': the file''s content (code '//str(c%content)// &
                     ') is not the one its grid announced (code '// &
                     str(cfg%cloud%grid%content)//')')
      return
    end if
    if (shared .and. c%content == CLOUD_MCARATS) then
      ! what the voxel values decide, from rank 0 (which has them) to every rank
      if (par_is_root()) then
        call mcarats_scan(c, cfg%cloud%req%mcarats, cfg%cloud%req%path, scan, error)
        if (.not. allocated(error)) then
          used = merge(1, 0, scan%used)
          call bm%put(used)
          call bm%put(scan%blend)
          call bm%put(scan%has_abs)
          call bm%put(scan%abs_notes)
        end if
      end if
      call bm%share(error)
      if (allocated(error)) return
      call bm%get(used)
      scan%used = used == 1
      call bm%get(scan%blend)
      call bm%get(scan%has_abs)
      call bm%get(scan%abs_notes)
    end if
    if (c%has_ice) then
      call read_cloud_on_root(cfg%cloud%req, c_ice, error, part='ice', per_node=shared)
      if (allocated(error)) return
      ! the ice optics table, read on rank 0 and shared like the fields
      if (par_is_root()) then
        call ice_table(cfg%cloud, cfg%source%wavelength_um, ice, error)
        if (.not. allocated(error)) call mie_table_put(bi, ice)
      end if
      call bi%share(error)
      if (allocated(error)) return
      call mie_table_get(bi, ice)
    end if
    if (c%content == CLOUD_WATER .or. c%content == CLOUD_EXT_REFF) then
      ! the water Mie table, read from the cache or computed on rank 0 alone and shared
      if (par_is_root()) then
        call water_table(cfg%cloud, cfg%source%wavelength_um, liq, liq_action, error)
        if (.not. allocated(error)) then
          call bl%put(liq_action)
          call mie_table_put(bl, liq)
        end if
      end if
      call bl%share(error)
      if (allocated(error)) return
      call bl%get(liq_action)
      call mie_table_get(bl, liq)
    else
      liq_action = ''
    end if
    if (shared) then
      call build(error, par_node_storage, par_node_sync, scan)
      call b%share(error)   ! rank 0's error, if any, on every rank
      if (allocated(error)) return
      call note_voxel_storage(atm, cfg%control%verbose)
      return
    end if
    if (par_is_root()) call build(error)
    call b%share(error)   ! rank 0's error, if any, on every rank
    if (allocated(error) .or. par_is_root()) return
    call build(error)
  contains
    !> The atmosphere from the cloud, with the voxels in `storage` (one copy per node) and what
    !> rank 0 found in an MCARaTS file's values (`mca`) when given.
    subroutine build(err, storage, sync, mca)
      type(error_t), allocatable, intent(out) :: err
      procedure(voxel_storage_i), optional :: storage
      procedure(voxel_sync_i), optional :: sync
      type(mcarats_scan_t), intent(in), optional :: mca
      if (want_t .and. .not. shared) then
        call build_cloud_atmosphere(cfg%cloud, c, c_ice, cfg%source%wavelength_um, &
                                    cfg%phase%n_table, cfg%atm%z, cfg%atm%lx, cfg%atm%ly, &
                                    cfg%atm%k3d_bottom, ext1d, ssa1d, phase1d, phases, aopts, &
                                    atm, notes, warnings, err, cloud_t, ice_tab=ice, &
                                    liq_tab=liq, liq_action=liq_action, storage=storage, &
                                    sync=sync, mca=mca)
      else
        call build_cloud_atmosphere(cfg%cloud, c, c_ice, cfg%source%wavelength_um, &
                                    cfg%phase%n_table, cfg%atm%z, cfg%atm%lx, cfg%atm%ly, &
                                    cfg%atm%k3d_bottom, ext1d, ssa1d, phase1d, phases, aopts, &
                                    atm, notes, warnings, err, ice_tab=ice, liq_tab=liq, &
                                    liq_action=liq_action, storage=storage, sync=sync, mca=mca)
      end if
    end subroutine build
  end subroutine cloud_on_ranks

  !> A line for the run log (rank 0, verbose >= 1): where each rank's voxel arrays live (bytes
  !> it allocated itself, and bytes of the node's shared window it allocated: the node's first
  !> rank alone). Every rank calls it. It is printed, not kept in the scene's notes, which the
  !> output file keeps: the file does not depend on the rank count.
  subroutine note_voxel_storage(atm, verbose)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: verbose
    integer(i8) :: mine
    mine = 0_i8
    if (atm%voxels_borrowed .and. atm%voxel_writer) mine = atm%voxel_bytes_borrowed
    call note_rank_bytes('voxel arrays: one copy per node in shared memory ('// &
                         str(atm%voxel_bytes_borrowed)//' bytes, '//str(par_node_size())// &
                         ' ranks on the node of rank 0)', atm%voxel_bytes_own, mine, verbose)
  end subroutine note_voxel_storage

  !> A line for the run log (rank 0, verbose >= 1), as note_voxel_storage: where each rank's
  !> emission table (its per-voxel arrays and cumulative table) lives. Every rank calls it.
  subroutine note_table_storage(em, verbose)
    type(emission_t), intent(in) :: em
    integer, intent(in) :: verbose
    integer(i8) :: mine
    if (em%layered) then
      ! over a cloud file: each rank's own table of one entry per layer (gpoint_emission)
      call note_rank_bytes('emission table: one per rank, voxels drawn layer by layer ('// &
                           str(em%table_bytes_own)//' bytes)', em%table_bytes_own, 0_i8, verbose)
      return
    end if
    mine = 0_i8
    if (em%on_node .and. em%table_writer) mine = em%table_bytes_borrowed
    call note_rank_bytes('emission table: one copy per node in shared memory ('// &
                         str(em%table_bytes_borrowed)//' bytes)', em%table_bytes_own, mine, verbose)
  end subroutine note_table_storage

  !> Rank 0 prints `head` and the bytes every rank allocated itself (`own`) and in the node's
  !> shared window (`win`). Every rank calls it.
  subroutine note_rank_bytes(head, own, win, verbose)
    character(len=*), intent(in) :: head
    integer(i8), intent(in) :: own, win
    integer, intent(in) :: verbose
    integer(i8), allocatable :: owns(:), wins(:)
    integer :: r
    character(len=:), allocatable :: notes
    allocate (owns(par_size()), wins(par_size()))
    call par_gather_i8(own, owns)
    call par_gather_i8(win, wins)
    if (par_rank() /= 0 .or. verbose < 1) return
    notes = head//'; bytes allocated per rank (own, shared window):'
    do r = 1, size(owns)
      notes = notes//' rank '//str(r - 1)//' '//str(owns(r))//' '//str(wins(r))//';'
    end do
    write (output_unit, '(a)') notes
    flush (output_unit)
  end subroutine note_rank_bytes

  !> Rank 0 reads a phase-function table (angle [deg], value) and broadcasts it.
  subroutine phase_table_on_root(path, ang, val, error)
    character(len=*), intent(in) :: path
    real(wp), allocatable, intent(out) :: ang(:), val(:)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: b
    if (par_is_root()) then
      call read_two_columns(path, ang, val, error)
      if (.not. allocated(error)) then
        call b%put(ang)
        call b%put(val)
      end if
    end if
    call b%share(error)
    if (allocated(error)) return
    call b%get(ang)
    call b%get(val)
  end subroutine phase_table_on_root

  !> Rank 0 reads the BRDF map and broadcasts it.
  subroutine brdf_map_on_root(path, default_kind, bmap, error)
    character(len=*), intent(in) :: path
    integer, intent(in) :: default_kind
    type(brdf_params_t), allocatable, intent(out) :: bmap(:, :)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: b
    integer :: nx, ny
    integer, allocatable :: kind(:, :)
    real(wp), allocatable :: c(:, :, :)
    if (par_is_root()) then
      call read_brdf_map(path, default_kind, nx, ny, kind, c, error)
      if (.not. allocated(error)) then
        call b%put(kind)
        call b%put(c)
      end if
    end if
    call b%share(error)
    if (allocated(error)) return
    call b%get(kind)
    call b%get(c)
    call brdf_map_from(kind, c, bmap)
  end subroutine brdf_map_on_root

  !> A BRDF map from its kind codes (nx, ny) and parameters (BRDF_NPAR, nx, ny).
  subroutine brdf_map_from(kind, c, bmap)
    integer, intent(in) :: kind(:, :)
    real(wp), intent(in) :: c(:, :, :)
    type(brdf_params_t), allocatable, intent(out) :: bmap(:, :)
    integer :: i, j
    allocate (bmap(size(kind, 1), size(kind, 2)))
    do j = 1, size(kind, 2)
      do i = 1, size(kind, 1)
        bmap(i, j)%kind = kind(i, j)
        bmap(i, j)%c = c(:, i, j)
      end do
    end do
  end subroutine brdf_map_from

  !> Rank 0 reads an MCARaTS surface file (&kumo_surface surface_file, binary, pixel counts
  !> and enabled models from the namelist) and broadcasts kumo's BRDF map of it; the notes
  !> say what the file held and what was taken from the namelist.
  subroutine mcarats_surface_on_root(cfg, path, bmap, notes, error)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: path
    type(brdf_params_t), allocatable, intent(out) :: bmap(:, :)
    character(len=:), allocatable, intent(out) :: notes
    type(error_t), allocatable, intent(out) :: error
    type(mcarats_surface_t) :: sfc
    type(bundle_t) :: b
    integer :: i, j, nxb, nyb, it
    integer, allocatable :: kind(:, :)
    real(wp), allocatable :: c(:, :, :)
    character(len=*), parameter :: KIND_NAMES(0:4) = &
      [character(len=7) :: 'black', 'Lambert', 'DSM', 'RPV', 'LSRT']
    nxb = cfg%surface%surface_nxb
    nyb = cfg%surface%surface_nyb
    if (par_is_root()) then
      call read_mcarats_surface(path, nxb, nyb, mcarats_surface_npsfc(cfg%surface%surface_mbrdf), &
                                sfc, error, cfg%surface%surface_idread)
      if (.not. allocated(error)) call mcarats_surface_brdf(sfc, cfg%surface%surface_mbrdf, path, &
                                                            bmap, error)
      if (.not. allocated(error)) then
        allocate (kind(nxb, nyb), c(BRDF_NPAR, nxb, nyb))
        do j = 1, nyb
          do i = 1, nxb
            kind(i, j) = bmap(i, j)%kind
            c(:, i, j) = bmap(i, j)%c
          end do
        end do
        call b%put(kind)
        call b%put(c)
        notes = 'surface file '//path//' (MCARaTS): dataset '//str(sfc%idread)//' of '// &
                str(sfc%ndatasets)//', '//str(nxb)//' x '//str(nyb)//' pixels:'
        do it = 0, 4
          if (any(sfc%brdf_type == it)) notes = notes//' '//trim(KIND_NAMES(it))//' '// &
                                                str(count(sfc%brdf_type == it))
        end do
        notes = notes//'; its temperatures are not used (solar radiation only)'//new_line('a')// &
                'the file does not give its pixel counts (surface_nxb, surface_nyb) and the '// &
                'extent they cover (the domain lx x ly = '//str(cfg%atm%lx)//' x '// &
                str(cfg%atm%ly)//' m); taken from the namelist'//new_line('a')
        call b%put(notes)
      end if
    end if
    call b%share(error)
    if (allocated(error)) return
    call b%get(kind)
    call b%get(c)
    call b%get(notes)
    call brdf_map_from(kind, c, bmap)
  end subroutine mcarats_surface_on_root

  !> Rank 0 reads the voxel temperatures of the scene file, if it has them, and broadcasts them
  !> (t3 not allocated when the file has none). With `leaders` = .true. only the first rank of
  !> every node gets them (one scene per node: it alone forms the voxels' Planck radiances); every
  !> rank gets `found`, whether the file has them, and rank 0's error.
  subroutine scene_temperature_on_root(path, cfg, t3, error, leaders, found)
    character(len=*), intent(in) :: path
    type(config_t), intent(in) :: cfg
    real(wp), allocatable, intent(out) :: t3(:, :, :)
    type(error_t), allocatable, intent(out) :: error
    logical, intent(in), optional :: leaders
    logical, intent(out), optional :: found
    type(bundle_t) :: b, bt
    logical :: has, node
    node = .false.
    if (present(leaders)) node = leaders .and. par_size() > 1
    has = .false.
    if (par_is_root()) then
      call read_scene_temperature(path, cfg%atm%nx, cfg%atm%ny, cfg%atm%nz3, t3, has, error)
      if (.not. allocated(error)) then
        call b%put(has)
        if (has .and. .not. node) call b%put(t3)
      end if
    end if
    call b%share(error)
    if (present(found)) found = .false.
    if (allocated(error)) return
    call b%get(has)
    if (present(found)) found = has
    if (.not. has) then
      if (allocated(t3)) deallocate (t3)
    else if (.not. node) then
      call b%get(t3)
    else if (par_node_leader() .and. par_node_size() < par_size()) then
      ! the node leaders: rank 0's values (on one node rank 0 keeps what it read)
      if (par_is_root()) then
        call bt%put(t3)
        deallocate (t3)
      end if
      call bt%share(error, leaders=.true.)
      call bt%get(t3)
    end if
  end subroutine scene_temperature_on_root

  !> Rank 0 reads a 2-D map (the surface temperature map, `temperature`, or the albedo map)
  !> and broadcasts it.
  subroutine map_on_root(path, varname, temperature, map, error)
    character(len=*), intent(in) :: path, varname
    logical, intent(in) :: temperature
    real(wp), allocatable, intent(out) :: map(:, :)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: b
    integer :: nx, ny
    if (par_is_root()) then
      if (temperature) then
        call read_temperature_map(path, varname, nx, ny, map, error)
      else
        call read_albedo_map(path, varname, nx, ny, map, error)
      end if
      if (.not. allocated(error)) call b%put(map)
    end if
    call b%share(error)
    if (.not. allocated(error)) call b%get(map)
  end subroutine map_on_root

end module kumo_scene_setup
