! SPDX-License-Identifier: BSD-3-Clause
!> Orchestration: configuration → scene setup → batches over ranks → reduction → results.
!>
!> `simulate` runs a validated configuration and returns the result set (on rank 0); tests call
!> it directly. `run_case` is what the program does: read the namelist, check that the output
!> can be written, simulate, log and write the netCDF file.
module kumo_driver
  use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
  use kumo_kinds, only: wp, dp, i8
  use kumo_constants, only: KUMO_VERSION, DEG2RAD, SECONDS_PER_DAY, PI
  use kumo_error, only: error_t, set_error, add_context, str, join
  use kumo_rng, only: rng_t, rng_init
  use kumo_phase, only: phase_t, new_phase_isotropic, new_phase_rayleigh, new_phase_hg, phase_from_table, &
                        new_phase_rayleigh_depol, &
                        PHASE_ISOTROPIC, PHASE_RAYLEIGH, PHASE_HG, PHASE_TABLE, phase_eval
  use kumo_atmosphere, only: atmosphere_t, atmosphere_options_t, atmosphere_init, &
                             atmosphere_set_truncation, LAYER_CLASS_NAMES, LAYER_3D
  use kumo_truncation, only: truncation_t, truncation_init
  use kumo_camera, only: camera_t, camera_init, CAMERA_PINHOLE, CAMERA_ORTHOGRAPHIC, &
                         MAX_IMAGE_SHIFTS
  use kumo_local_estimate, only: detectors_t, detectors_init
  use kumo_surface, only: surface_t, surface_init, surface_init_brdf, surface_init_brdf_map
  use kumo_brdf, only: brdf_params_t, BRDF_NPAR
  use kumo_tally, only: tally_layout_t, tally_t, stats_t, layout_init, tally_reset, stats_init, &
                        stats_add_batch, stats_mean, stats_stderr, N_ANOMALIES, ANOMALY_NAMES
  use kumo_source, only: solar_source, source_stratify
  use kumo_vr, only: collision_forcing, ddis_phases, spiky_without_vr, SPIKY_PEAK, DDIS_CONE_DEG
  use kumo_scene, only: scene_t
  use kumo_transport, only: trace_batch
  use kumo_results, only: result_set_t, add_dim, add_var, add_attr, find_var
  use kumo_config, only: config_t, read_config, config_echo, resolve_path
  use kumo_cloud_scene, only: build_cloud_atmosphere, rayleigh_layers
  use kumo_rayleigh, only: depol_from_king, king_factor_air
  use kumo_textio, only: read_two_columns, read_whole_file
  use kumo_netcdf, only: write_results, check_writable, read_scene_3d, read_albedo_map, &
                         read_brdf_map
  use kumo_mcarats_files, only: mcarats_surface_t, read_mcarats_surface, mcarats_surface_npsfc, &
                                mcarats_surface_brdf
  use kumo_parallel, only: par_rank, par_size, par_is_root, par_sum_to_root, &
                           par_allreduce_sum, par_wtime, par_bcast_int, par_bcast_real, PAR_IS_MPI
  implicit none
  private
  public :: run_case, simulate, scene_t, setup_scene, run_summary_t

  !> Figures of a finished run, for the log and for tests.
  type :: run_summary_t
    integer(i8) :: n_photons = 0_i8
    integer(i8) :: n_batches = 0_i8
    integer :: n_ranks = 1
    real(dp) :: wall_time = 0.0_dp      !! [s]
    real(dp) :: cpu_time = 0.0_dp       !! summed over ranks [s]
    real(dp) :: setup_time = 0.0_dp     !! [s]
    integer(i8) :: anomalies(N_ANOMALIES) = 0_i8
    integer(i8) :: flight_steps = 0_i8  !! flight steps of all photons (null collisions included)
    integer(i8) :: events = 0_i8        !! collisions and reflections of all photons
  end type run_summary_t

contains

  !> The program's job: namelist file in, netCDF file out.
  subroutine run_case(path, error)
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    character(len=:), allocatable :: nml_text
    integer :: status(1)

    call read_config(path, cfg, error)
    if (allocated(error)) return
    call read_whole_file(path, nml_text, error)
    if (allocated(error)) return
    status = 0
    if (par_is_root()) then
      call check_writable(trim(cfg%output%file), error)
      if (allocated(error)) status = 1
    end if
    call par_bcast_int(status)
    if (status(1) /= 0) then
      if (.not. allocated(error)) call set_error(error, 'output file cannot be written')
      return
    end if
    if (par_is_root() .and. cfg%control%verbose >= 1) then
      write (output_unit, '(a)') 'kumo '//KUMO_VERSION//': '//trim(path)
      write (output_unit, '(a)') config_echo(cfg)
    end if
    call simulate(cfg, set, summary, error, nml_text)
    if (allocated(error)) return
    if (par_is_root()) then
      call write_results(trim(cfg%output%file), set, error)
      if (allocated(error)) return
      if (cfg%control%verbose >= 1) call log_summary(set, summary, trim(cfg%output%file))
    end if
  end subroutine run_case

  !> Build the scene (phase functions, atmosphere, surface, source) from a configuration.
  subroutine setup_scene(cfg, scene, error)
    type(config_t), intent(in) :: cfg
    type(scene_t), intent(out) :: scene
    type(error_t), allocatable, intent(out) :: error
    type(phase_t), allocatable :: phases(:)
    type(atmosphere_options_t) :: aopts
    real(wp), allocatable :: ang(:), val(:), ext3(:, :, :, :), ssa3(:, :, :, :), alb(:, :)
    type(brdf_params_t), allocatable :: bmap(:, :)
    integer, allocatable :: iph3(:, :, :, :), phase1d(:, :)
    integer :: i
    character(len=:), allocatable :: nml_path
    real(wp), allocatable :: ext1d(:, :), ssa1d(:, :), ray_ext(:), ray_rho(:)
    character(len=:), allocatable :: ray_notes
    real(wp) :: depol
    character(len=:), allocatable :: cloud_notes, cloud_warnings
    character(len=:), allocatable :: sfc_notes

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
        call read_two_columns(resolve_path(cfg%phase%file(i), nml_path), ang, val, error)
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
    aopts%use_1d_layers = cfg%vr%use_1d_layers
    aopts%use_absorbing_layers = cfg%vr%use_absorbing_layers
    aopts%sv%enabled = cfg%vr%use_supervoxels
    aopts%sv%fsupg = cfg%vr%sv_fsupg
    aopts%sv%fsupi = cfg%vr%sv_fsupi
    aopts%sv%max_layers = cfg%vr%sv_max_layers
    if (cfg%cloud%enabled) then
      call cloud_on_ranks(cfg, ext1d, ssa1d, phase1d, phases, aopts, scene%atm, cloud_notes, &
                          cloud_warnings, error)
      if (allocated(error)) return
      scene%notes = scene%notes//cloud_notes
      scene%warnings = scene%warnings//cloud_warnings
    else
      if (len_trim(cfg%atm%scene_file) > 0) then
        call read_scene_on_root(cfg, resolve_path(cfg%atm%scene_file, nml_path), ext3, ssa3, &
                                iph3, error)
        if (allocated(error)) return
      end if
      if (allocated(ext3)) then
        call atmosphere_init(scene%atm, cfg%atm%z, cfg%atm%lx, cfg%atm%ly, ext1d, ssa1d, &
                             phase1d, phases, aopts, error, cfg%atm%k3d_bottom, ext3, ssa3, iph3)
      else
        call atmosphere_init(scene%atm, cfg%atm%z, cfg%atm%lx, cfg%atm%ly, ext1d, ssa1d, &
                             phase1d, phases, aopts, error)
      end if
      if (allocated(error)) return
    end if

    if (len_trim(cfg%surface%albedo_file) > 0) then
      call read_albedo_on_root(resolve_path(cfg%surface%albedo_file, nml_path), &
                               trim(cfg%surface%albedo_var), alb, error)
      if (allocated(error)) return
    else
      allocate (alb(1, 1))
      alb = cfg%surface%albedo
    end if
    if (len_trim(cfg%surface%surface_file) > 0) then
      call mcarats_surface_on_root(cfg, resolve_path(cfg%surface%surface_file, nml_path), bmap, &
                                   sfc_notes, error)
      if (allocated(error)) return
      call surface_init_brdf_map(scene%sfc, bmap, cfg%atm%lx, cfg%atm%ly, error)
      call add_context(error, trim(cfg%surface%surface_file))
      scene%notes = scene%notes//sfc_notes
    else if (len_trim(cfg%surface%brdf_file) > 0) then
      call brdf_map_on_root(resolve_path(cfg%surface%brdf_file, nml_path), cfg%surface%model%kind, &
                            bmap, error)
      if (allocated(error)) return
      call surface_init_brdf_map(scene%sfc, bmap, cfg%atm%lx, cfg%atm%ly, error)
      call add_context(error, trim(cfg%surface%brdf_file))
    else if (cfg%surface%brdf == 'lambert') then
      call surface_init(scene%sfc, alb, cfg%atm%lx, cfg%atm%ly, error)
    else
      call surface_init_brdf(scene%sfc, cfg%surface%model, cfg%atm%lx, cfg%atm%ly, error)
    end if
    if (allocated(error)) return

    scene%src = solar_source(cfg%source%sza_deg, cfg%source%phi0_deg)
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
    scene%vr%rr_threshold = cfg%vr%rr_threshold
    scene%vr%rr_weight = cfg%vr%rr_weight
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
  end subroutine setup_scene

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
    do i = 1, size(cams)
      if (cams(i)%capped) scene%warnings = scene%warnings//'camera '//str(i)// &
        ' sees the periodic scene up to the horizon; copies beyond '// &
        str(MAX_IMAGE_SHIFTS)//' domain lengths are left out (pixels near the horizon are low). '
    end do

    scene%det%ddis_mu_cone = cos(DDIS_CONE_DEG*DEG2RAD)
    deallocate (scene%det%ddis_phase)
    allocate (scene%det%ddis_phase(size(scene%atm%phases)))
    scene%det%ddis_phase = ddis_phases(scene%atm%phases)

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
    integer :: status(2), i, n(4)
    logical :: has_iph
    real(dp), allocatable :: buf(:)
    n = [cfg%atm%nx, cfg%atm%ny, cfg%atm%nz3, cfg%atm%n_components_3d]
    status = 0
    if (par_is_root()) then
      call read_scene_3d(path, n(1), n(2), n(3), n(4), ext3, ssa3, iph3, has_iph, error)
      if (allocated(error)) status(1) = 1
      if (has_iph) status(2) = 1
    end if
    call share_read_status(status, path, error)
    if (allocated(error)) return
    if (.not. par_is_root()) allocate (ext3(n(1), n(2), n(3), n(4)), ssa3(n(1), n(2), n(3), n(4)))
    if (status(2) == 0) then
      if (allocated(iph3)) deallocate (iph3)
      allocate (iph3(n(1), n(2), n(3), n(4)))
      do i = 1, n(4)
        iph3(:, :, :, i) = cfg%atm%phase3d(i)
      end do
    else if (.not. par_is_root()) then
      allocate (iph3(n(1), n(2), n(3), n(4)))
    end if
    if (par_size() == 1) return
    buf = reshape(ext3, [size(ext3)])
    call par_bcast_real(buf)
    ext3 = reshape(buf, shape(ext3))
    buf = reshape(ssa3, [size(ssa3)])
    call par_bcast_real(buf)
    ssa3 = reshape(buf, shape(ssa3))
    if (status(2) /= 0) then
      buf = real(reshape(iph3, [size(iph3)]), dp)
      call par_bcast_real(buf)
      iph3 = reshape(nint(buf), shape(iph3))
    end if
  end subroutine read_scene_on_root

  !> The cloud's atmosphere on every rank. Rank 0 goes first, so that a Mie table it computes
  !> is in the cache before the other ranks look for it; they then read it instead of
  !> computing it.
  subroutine cloud_on_ranks(cfg, ext1d, ssa1d, phase1d, phases, aopts, atm, notes, warnings, &
                            error)
    type(config_t), intent(in) :: cfg
    real(wp), intent(in) :: ext1d(:, :), ssa1d(:, :)
    integer, intent(in) :: phase1d(:, :)
    type(phase_t), allocatable, intent(inout) :: phases(:)
    type(atmosphere_options_t), intent(in) :: aopts
    type(atmosphere_t), intent(out) :: atm
    character(len=:), allocatable, intent(out) :: notes, warnings
    type(error_t), allocatable, intent(out) :: error
    integer :: status(1)
    status = 0
    if (par_is_root()) then
      call build(error)
      if (allocated(error)) status = 1
    end if
    call share_read_status(status, cfg%cloud%req%path, error)
    if (allocated(error) .or. par_is_root()) return
    call build(error)
  contains
    subroutine build(err)
      type(error_t), allocatable, intent(out) :: err
      call build_cloud_atmosphere(cfg%cloud, cfg%source%wavelength_um, cfg%phase%n_table, &
                                  cfg%atm%z, cfg%atm%lx, cfg%atm%ly, cfg%atm%k3d_bottom, ext1d, &
                                  ssa1d, phase1d, phases, aopts, atm, notes, warnings, err)
    end subroutine build
  end subroutine cloud_on_ranks

  !> Give every rank rank 0's read status (status(1) /= 0: failed; the rest: sizes); ranks
  !> other than 0 get an error naming the file when the read failed.
  subroutine share_read_status(status, path, error)
    integer, intent(inout) :: status(:)
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(inout) :: error
    call par_bcast_int(status)
    if (status(1) /= 0 .and. .not. allocated(error)) then
      call set_error(error, 'reading '//path//' failed on rank 0')
    end if
  end subroutine share_read_status

  !> Rank 0 reads the BRDF map and broadcasts it.
  subroutine brdf_map_on_root(path, default_kind, bmap, error)
    character(len=*), intent(in) :: path
    integer, intent(in) :: default_kind
    type(brdf_params_t), allocatable, intent(out) :: bmap(:, :)
    type(error_t), allocatable, intent(out) :: error
    integer :: status(3), i, j
    integer, allocatable :: kind(:, :)
    real(wp), allocatable :: c(:, :, :)
    real(dp), allocatable :: buf(:)
    status = 0
    if (par_is_root()) then
      call read_brdf_map(path, default_kind, status(2), status(3), kind, c, error)
      if (allocated(error)) status(1) = 1
    end if
    call share_read_status(status, path, error)
    if (allocated(error)) return
    if (par_size() > 1) then
      if (.not. par_is_root()) allocate (kind(status(2), status(3)), &
                                         c(BRDF_NPAR, status(2), status(3)))
      buf = [real(reshape(kind, [size(kind)]), dp), reshape(c, [size(c)])]
      call par_bcast_real(buf)
      kind = reshape(nint(buf(1:size(kind))), shape(kind))
      c = reshape(buf(size(kind) + 1:), shape(c))
    end if
    allocate (bmap(status(2), status(3)))
    do j = 1, status(3)
      do i = 1, status(2)
        bmap(i, j)%kind = kind(i, j)
        bmap(i, j)%c = c(:, i, j)
      end do
    end do
  end subroutine brdf_map_on_root

  !> Rank 0 reads an MCARaTS surface file (&kumo_surface surface_file, binary, pixel counts
  !> and enabled models from the namelist) and broadcasts kumo's BRDF map of it; the notes
  !> (rank 0 only) say what the file held and what was taken from the namelist.
  subroutine mcarats_surface_on_root(cfg, path, bmap, notes, error)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: path
    type(brdf_params_t), allocatable, intent(out) :: bmap(:, :)
    character(len=:), allocatable, intent(out) :: notes
    type(error_t), allocatable, intent(out) :: error
    type(mcarats_surface_t) :: sfc
    integer :: status(1), i, j, nxb, nyb, it
    integer, allocatable :: kind(:, :)
    real(wp), allocatable :: c(:, :, :)
    real(dp), allocatable :: buf(:)
    character(len=*), parameter :: KIND_NAMES(0:4) = &
      [character(len=7) :: 'black', 'Lambert', 'DSM', 'RPV', 'LSRT']
    nxb = cfg%surface%surface_nxb
    nyb = cfg%surface%surface_nyb
    notes = ''
    status = 0
    if (par_is_root()) then
      call read_mcarats_surface(path, nxb, nyb, mcarats_surface_npsfc(cfg%surface%surface_mbrdf), &
                                sfc, error, cfg%surface%surface_idread)
      if (.not. allocated(error)) call mcarats_surface_brdf(sfc, cfg%surface%surface_mbrdf, path, &
                                                            bmap, error)
      if (allocated(error)) status = 1
    end if
    call share_read_status(status, path, error)
    if (allocated(error)) return
    if (par_is_root()) then
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
    end if
    if (par_size() == 1) return
    allocate (kind(nxb, nyb), c(BRDF_NPAR, nxb, nyb))
    if (par_is_root()) then
      do j = 1, nyb
        do i = 1, nxb
          kind(i, j) = bmap(i, j)%kind
          c(:, i, j) = bmap(i, j)%c
        end do
      end do
    else
      allocate (bmap(nxb, nyb))
    end if
    buf = [real(reshape(kind, [size(kind)]), dp), reshape(c, [size(c)])]
    call par_bcast_real(buf)
    kind = reshape(nint(buf(1:size(kind))), shape(kind))
    c = reshape(buf(size(kind) + 1:), shape(c))
    do j = 1, nyb
      do i = 1, nxb
        bmap(i, j)%kind = kind(i, j)
        bmap(i, j)%c = c(:, i, j)
      end do
    end do
  end subroutine mcarats_surface_on_root

  !> Rank 0 reads the albedo map and broadcasts it.
  subroutine read_albedo_on_root(path, varname, alb, error)
    character(len=*), intent(in) :: path, varname
    real(wp), allocatable, intent(out) :: alb(:, :)
    type(error_t), allocatable, intent(out) :: error
    integer :: status(3)
    real(dp), allocatable :: buf(:)
    status = 0
    if (par_is_root()) then
      call read_albedo_map(path, varname, status(2), status(3), alb, error)
      if (allocated(error)) status(1) = 1
    end if
    call share_read_status(status, path, error)
    if (allocated(error)) return
    if (par_size() == 1) return
    if (.not. par_is_root()) allocate (alb(status(2), status(3)))
    buf = reshape(alb, [size(alb)])
    call par_bcast_real(buf)
    alb = reshape(buf, shape(alb))
  end subroutine read_albedo_on_root

  !> Run the batches of a configuration on all ranks and gather the results on rank 0.
  subroutine simulate(cfg, set, summary, error, nml_text)
    type(config_t), intent(in) :: cfg
    type(result_set_t), intent(out) :: set
    type(run_summary_t), intent(out) :: summary
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: nml_text
    type(scene_t) :: scene
    type(tally_layout_t) :: lay
    type(tally_t) :: tal
    type(stats_t) :: st
    type(rng_t) :: rng
    real(dp), allocatable :: rec(:, :), tmp(:, :)
    real(dp) :: t0, t1, c0, c1, cpu, buf2(3), rel
    integer(i8) :: nphot, counts(4 + N_ANOMALIES)
    integer :: ib, ib_next, nb_round, rank, nranks, itarget, nb_done
    integer, allocatable :: map_levels(:), cam_npix(:)
    logical :: maps, voxel, rad_maps

    t0 = par_wtime()
    rank = par_rank()
    nranks = par_size()
    call setup_scene(cfg, scene, error)
    if (allocated(error)) return
    summary%setup_time = par_wtime() - t0

    maps = cfg%output%column_fluxes .and. scene%atm%n3 > 0 .and. &
           (scene%atm%nx > 1 .or. scene%atm%ny > 1)
    voxel = cfg%output%voxel_absorption .and. scene%atm%n3 > 0
    if (maps) then
      map_levels = cfg%output%flux_levels
    else
      allocate (map_levels(0))
    end if
    rad_maps = cfg%rad%maps .and. scene%atm%n3 > 0 .and. (scene%atm%nx > 1 .or. scene%atm%ny > 1)
    allocate (cam_npix(cfg%cam%n))
    if (cfg%cam%n > 0) cam_npix = cfg%cam%npx*cfg%cam%npy
    call layout_init(lay, scene%atm%nz, scene%atm%nx*scene%atm%ny, scene%atm%n3, map_levels, &
                     voxel, scene%det%n_dir, scene%det%levels, rad_maps, cam_npix, &
                     [scene%atm%k3_lo - 1, scene%atm%k3_hi])
    if (par_is_root() .and. len(scene%notes) > 0 .and. cfg%control%verbose >= 1) then
      write (output_unit, '(a)', advance='no') scene%notes
    end if
    if (par_is_root() .and. len(scene%warnings) > 0) write (error_unit, '(a)') &
      'kumo: warning: '//scene%warnings
    call stats_init(st, lay)
    call tally_reset(tal, lay)

    select case (trim(cfg%control%target_output))
    case ('transmittance')
      itarget = lay%i_dn + 1
    case ('absorptance')
      itarget = lay%i_atm + 1
    case default
      itarget = lay%i_up + lay%nz + 1
    end select

    nphot = cfg%control%n_photons_per_batch
    nb_round = cfg%control%n_batches
    allocate (rec(3, 0))
    ib_next = 1
    cpu = 0.0_dp
    do
      allocate (tmp(3, ib_next + nb_round - 1))
      tmp = 0.0_dp
      tmp(:, 1:size(rec, 2)) = rec
      call move_alloc(tmp, rec)
      call cpu_time(c0)
      do ib = ib_next, ib_next + nb_round - 1
        if (mod(ib - 1, nranks) /= rank) cycle
        call rng_init(rng, cfg%control%seed, int(ib, i8))
        call tally_reset(tal, lay)
        call trace_batch(scene, lay, rng, nphot, tal)
        call stats_add_batch(st, lay, tal, nphot)
        rec(1, ib) = tal%buf(lay%i_up + lay%nz + 1)/real(nphot, dp)
        rec(2, ib) = (tal%buf(lay%i_dir + 1) + tal%buf(lay%i_dif + 1))/real(nphot, dp)
        rec(3, ib) = sum(tal%buf(lay%i_abs + 1:lay%i_abs + lay%nz))/real(nphot, dp)
      end do
      call cpu_time(c1)
      cpu = cpu + (c1 - c0)
      ib_next = ib_next + nb_round
      if (cfg%control%target_rel_error <= 0.0_dp) exit
      ! every rank takes the same decision from the same global sums
      buf2 = [st%s1(itarget), st%s2(itarget), real(st%n_batches, dp)]
      call par_allreduce_sum(buf2)
      rel = relative_error(buf2)
      if (par_is_root() .and. cfg%control%verbose >= 2) then
        write (output_unit, '(a)') '  batches '//str(ib_next - 1)//': '// &
          trim(cfg%control%target_output)//' relative standard error '//str(rel)
      end if
      if (rel <= cfg%control%target_rel_error) exit
      if (int(ib_next - 1 + nb_round, i8)*nphot > cfg%control%max_photons) exit
    end do
    nb_done = ib_next - 1

    counts(1) = st%n_batches
    counts(2) = st%n_photons
    counts(3:4) = st%work
    counts(5:) = st%anomalies
    call par_sum_to_root(st%s1)
    call par_sum_to_root(st%s2)
    call par_sum_to_root(counts)
    block
      real(dp), allocatable :: flat(:)
      flat = reshape(rec, [size(rec)])
      flat = [flat, cpu]
      call par_sum_to_root(flat)
      rec = reshape(flat(1:size(rec)), shape(rec))
      cpu = flat(size(flat))
    end block
    st%n_batches = counts(1)
    st%n_photons = counts(2)
    st%work = counts(3:4)
    st%anomalies = counts(5:)
    t1 = par_wtime()

    summary%n_photons = st%n_photons
    summary%n_batches = st%n_batches
    summary%n_ranks = nranks
    summary%wall_time = t1 - t0
    summary%cpu_time = cpu
    summary%anomalies = st%anomalies
    summary%flight_steps = st%work(1)
    summary%events = st%work(2)
    if (.not. par_is_root()) return
    call build_results(cfg, scene, lay, st, rec(:, 1:nb_done), summary, set)
    if (present(nml_text)) call add_attr(set, 'namelist', nml_text)
  end subroutine simulate

  pure real(dp) function relative_error(b) result(rel)
    real(dp), intent(in) :: b(3)  !! S1, S2, number of batches
    real(dp) :: m, v
    if (b(3) < 2.0_dp) then
      rel = huge(1.0_dp)
      return
    end if
    m = b(1)/b(3)
    v = max(0.0_dp, b(2)/b(3) - m*m)/(b(3) - 1.0_dp)
    if (m == 0.0_dp) then
      rel = huge(1.0_dp)
    else
      rel = sqrt(v)/abs(m)
    end if
  end function relative_error

  !> Lay out every product with its standard error, units and provenance.
  subroutine build_results(cfg, scene, lay, st, rec, summary, set)
    type(config_t), intent(in) :: cfg
    type(scene_t), intent(in) :: scene
    type(tally_layout_t), intent(in) :: lay
    type(stats_t), intent(in) :: st
    real(dp), intent(in) :: rec(:, :)
    type(run_summary_t), intent(in) :: summary
    type(result_set_t), intent(inout) :: set
    integer :: nz, k, n_out, i, ncol, kr
    integer, allocatable :: lev(:)
    real(dp), allocatable :: z(:), zmid(:), dz(:), m(:), e(:), fac(:)
    real(dp) :: f_hor
    integer :: tv(8)
    character(len=*), parameter :: NORM = ' normalised by the incident solar flux on a horizontal plane'
    character(len=32) :: stamp
    associate (atm => scene%atm)
      nz = atm%nz
      z = atm%z
      zmid = 0.5_dp*(z(1:nz) + z(0:nz - 1))
      dz = z(1:nz) - z(0:nz - 1)
      lev = cfg%output%flux_levels
      n_out = size(lev)
      ncol = lay%ncol
      f_hor = cfg%source%solar_flux*scene%mu0   ! incident flux on a horizontal plane [W m-2]

      call add_dim(set, 'level', n_out, coord=z(lev), units='m', &
                   long_name='height of the flux levels')
      call add_dim(set, 'layer', nz, coord=zmid, units='m', long_name='height of the layer centres')
      call add_dim(set, 'batch', size(rec, 2))

      ! domain-mean fluxes at the chosen levels
      call put('flux_up', 'upward flux'//NORM, lay%i_up + lev + 1)
      call put('flux_down', 'downward flux (direct + diffuse)'//NORM, lay%i_dn + lev + 1)
      call put('flux_down_direct', 'downward direct (unscattered) flux'//NORM, lay%i_dir + lev + 1)
      call put('flux_down_diffuse', 'downward diffuse flux'//NORM, lay%i_dif + lev + 1)
      call put('reflectance', 'upward flux at the top of the atmosphere'//NORM, [lay%i_up + nz + 1])
      call put('transmittance', 'downward flux at the surface (direct + diffuse)'//NORM, &
               [lay%i_dn + 1])
      call put('transmittance_direct', 'downward direct flux at the surface'//NORM, [lay%i_dir + 1])
      call put('transmittance_diffuse', 'downward diffuse flux at the surface'//NORM, &
               [lay%i_dif + 1])
      call put('absorptance_atmosphere', 'power absorbed by the atmosphere'//NORM, [lay%i_atm + 1])
      call put('absorptance_surface', 'power absorbed by the surface'//NORM, [lay%i_sfc + 1])
      call put('absorptance_layer', 'power absorbed in each layer'//NORM, &
               [(lay%i_abs + k, k=1, nz)], dims=['layer'])
      call put('roulette_weight_balance', 'net weight created by Russian roulette and DDIS'// &
               ' splitting'//NORM// &
               ' (zero in expectation)', [lay%i_rr + 1])
      call put('weight_lost', 'weight of photons stopped at a loop cap'//NORM, [lay%i_lost + 1])
      call put('energy_closure', 'reflectance + absorptance_atmosphere + absorptance_surface'// &
               ' - roulette_weight_balance + weight_lost (1 to round-off)', [lay%i_closure + 1])

      ! heating of the layers
      if (f_hor > 0.0_dp) then
        fac = f_hor/dz
        m = stats_mean(st, lay%i_abs + 1, lay%i_abs + nz)*fac
        e = stats_stderr(st, lay%i_abs + 1, lay%i_abs + nz)*fac
        call add_var(set, 'flux_up_wm2', 'upward flux', 'W m-2', ['level'], &
                     stats_mean1(lay%i_up + lev + 1)*f_hor, stats_err1(lay%i_up + lev + 1)*f_hor)
        call add_var(set, 'flux_down_wm2', 'downward flux (direct + diffuse)', 'W m-2', &
                     ['level'], stats_mean1(lay%i_dn + lev + 1)*f_hor, &
                     stats_err1(lay%i_dn + lev + 1)*f_hor)
        call add_var(set, 'flux_down_direct_wm2', 'downward direct flux', 'W m-2', ['level'], &
                     stats_mean1(lay%i_dir + lev + 1)*f_hor, stats_err1(lay%i_dir + lev + 1)*f_hor)
        call add_var(set, 'flux_down_diffuse_wm2', 'downward diffuse flux', 'W m-2', ['level'], &
                     stats_mean1(lay%i_dif + lev + 1)*f_hor, stats_err1(lay%i_dif + lev + 1)*f_hor)
        call add_var(set, 'absorbed_power_density_layer', 'layer-mean absorbed power per volume', &
                     'W m-3', ['layer'], m, e)
        if (allocated(scene%air_density)) then
          fac = SECONDS_PER_DAY/(scene%air_density*cfg%atm%cp_air)
          call add_var(set, 'heating_rate_layer', 'layer-mean heating rate', 'K day-1', &
                       ['layer'], m*fac, e*fac)
        end if
      else
        fac = 1.0_dp/dz
        call add_var(set, 'absorbed_power_density_layer', 'layer-mean absorbed power per volume'// &
                     ' per unit incident solar flux on a horizontal plane', 'm-1', ['layer'], &
                     stats_mean(st, lay%i_abs + 1, lay%i_abs + nz)*fac, &
                     stats_err1([(lay%i_abs + k, k=1, nz)])*fac)
      end if

      ! per-column maps and voxel absorption of the 3-D region
      if (lay%do_maps .or. lay%do_voxel) then
        call add_dim(set, 'x', atm%nx, coord=[((i - 0.5_dp)*atm%dx, i=1, atm%nx)], units='m', &
                     long_name='x of the column centres')
        call add_dim(set, 'y', atm%ny, coord=[((i - 0.5_dp)*atm%dy, i=1, atm%ny)], units='m', &
                     long_name='y of the column centres')
      end if
      if (lay%do_maps) then
        call put('flux_up_map', 'upward flux per column'//NORM, &
                 [(lay%i_map_up + i, i=1, n_out*ncol)], dims=['x    ', 'y    ', 'level'])
        call put('flux_down_direct_map', 'downward direct flux per column'//NORM, &
                 [(lay%i_map_dir + i, i=1, n_out*ncol)], dims=['x    ', 'y    ', 'level'])
        call put('flux_down_diffuse_map', 'downward diffuse flux per column'//NORM, &
                 [(lay%i_map_dif + i, i=1, n_out*ncol)], dims=['x    ', 'y    ', 'level'])
        call put('flux_down_map', 'total (direct + diffuse) downward flux per column'//NORM, &
                 [(lay%i_map_dn + i, i=1, n_out*ncol)], dims=['x    ', 'y    ', 'level'])
      end if
      if (lay%do_voxel) then
        call add_dim(set, 'z3d', atm%n3, coord=zmid(atm%k3_lo:atm%k3_hi), units='m', &
                     long_name='height of the layer centres of the 3-D region')
        call put('absorptance_voxel', 'power absorbed per voxel per unit column area'//NORM, &
                 [(lay%i_vox + i, i=1, atm%n3*ncol)], dims=['x  ', 'y  ', 'z3d'])
        if (allocated(fac)) deallocate (fac)
        allocate (fac(atm%n3*ncol))
        do kr = 1, atm%n3
          fac((kr - 1)*ncol + 1:kr*ncol) = 1.0_dp/dz(atm%k3_lo + kr - 1)
        end do
        m = stats_mean(st, lay%i_vox + 1, lay%i_vox + atm%n3*ncol)*fac
        e = stats_stderr(st, lay%i_vox + 1, lay%i_vox + atm%n3*ncol)*fac
        if (f_hor > 0.0_dp) then
          call add_var(set, 'absorbed_power_density_voxel', 'absorbed power per volume', &
                       'W m-3', ['x  ', 'y  ', 'z3d'], m*f_hor, e*f_hor)
          if (allocated(scene%air_density)) then
            do kr = 1, atm%n3
              fac((kr - 1)*ncol + 1:kr*ncol) = f_hor*SECONDS_PER_DAY/ &
                (scene%air_density(atm%k3_lo + kr - 1)*cfg%atm%cp_air)
            end do
            call add_var(set, 'heating_rate_voxel', 'heating rate', 'K day-1', &
                         ['x  ', 'y  ', 'z3d'], m*fac, e*fac)
          end if
        else
          call add_var(set, 'absorbed_power_density_voxel', 'absorbed power per volume per'// &
                       ' unit incident solar flux on a horizontal plane', 'm-1', &
                       ['x  ', 'y  ', 'z3d'], m, e)
        end if
      end if

      if (lay%do_budget) then
        call put('absorptance_column', 'power absorbed in the 3-D region of each column per'// &
                 ' unit column area'//NORM, [(lay%i_col_abs + i, i=1, ncol)], dims=['x', 'y'])
        call put('horizontal_transport_map', 'net power leaving the 3-D region of each'// &
                 ' column through its sides, per unit column area'//NORM// &
                 ' (net flux in at the top - net flux out at the bottom - absorptance_column)', &
                 [(lay%i_htr + i, i=1, ncol)], dims=['x', 'y'])
      end if

      call radiance_results()

      call add_var(set, 'batch_reflectance', 'reflectance of each batch', '1', ['batch'], rec(1, :))
      call add_var(set, 'batch_transmittance', 'transmittance of each batch', '1', ['batch'], &
                   rec(2, :))
      call add_var(set, 'batch_absorptance', 'atmospheric absorptance of each batch', '1', &
                   ['batch'], rec(3, :))

      call date_and_time(values=tv)
      write (stamp, '(i4.4,"-",i2.2,"-",i2.2,"T",i2.2,":",i2.2,":",i2.2)') tv(1:3), tv(5:7)
      call add_attr(set, 'title', 'kumo Monte Carlo radiative transfer results')
      call add_attr(set, 'source', 'kumo '//KUMO_VERSION)
      call add_attr(set, 'history', trim(stamp)//' kumo '//cfg%path)
      call add_attr(set, 'kumo_version', KUMO_VERSION)
      call add_attr(set, 'configuration', config_echo(cfg))
      call add_attr(set, 'seed', str(cfg%control%seed))
      call add_attr(set, 'n_photons', str(summary%n_photons))
      call add_attr(set, 'n_batches', str(summary%n_batches))
      call add_attr(set, 'n_photons_per_batch', str(cfg%control%n_photons_per_batch))
      call add_attr(set, 'n_ranks', str(summary%n_ranks))
      call add_attr(set, 'parallel', merge('MPI   ', 'serial', PAR_IS_MPI))
      call add_attr(set, 'wall_time_s', str(summary%wall_time))
      call add_attr(set, 'cpu_time_s', str(summary%cpu_time))
      call add_attr(set, 'setup_time_s', str(summary%setup_time))
      call add_attr(set, 'solar_zenith_angle_deg', str(cfg%source%sza_deg))
      if (cfg%source%wavelength_um > 0.0_wp) call add_attr(set, 'wavelength_um', &
                                                           str(cfg%source%wavelength_um))
      call add_attr(set, 'normalisation', 'fluxes and absorptances are divided by the incident'// &
                    ' solar flux on a horizontal plane, mu0*F0; *_wm2 and power densities use F0 = '// &
                    str(cfg%source%solar_flux)//' W m-2')
      call add_attr(set, 'flight_steps_per_photon', &
                    str(real(summary%flight_steps, dp)/real(max(1_i8, summary%n_photons), dp)))
      call add_attr(set, 'events_per_photon', &
                    str(real(summary%events, dp)/real(max(1_i8, summary%n_photons), dp)))
      call add_attr(set, 'layer_classes', classes())
      call add_attr(set, 'collision_forcing_factor', str(scene%vr%cf_factor))
      call add_attr(set, 'truncation_levels', str(atm%trunc%n_levels))
      call add_attr(set, 'vr_preset', trim(cfg%vr%preset))
      call add_attr(set, 'mode_3d', trim(cfg%control%mode_3d))
      if (cfg%control%mode_3d == 'p3d') call add_attr(set, 'p3d_orders', str(cfg%control%p3d_orders))
      if (len(scene%warnings) > 0) call add_attr(set, 'warnings', scene%warnings)
      if (len(scene%notes) > 0) call add_attr(set, 'scene_notes', scene%notes)
      call add_attr(set, 'supervoxels', sv_text())
      do i = 1, N_ANOMALIES
        call add_attr(set, 'anomaly_'//trim(ANOMALY_NAMES(i)), str(summary%anomalies(i)))
      end do
    end associate

  contains

    !> Radiances at levels (domain means and maps) and camera images, as pi I/(mu0 F0), and
    !> in W m-2 sr-1 when F0 is known.
    subroutine radiance_results()
      integer :: nd, nl, nn, c, np
      real(dp), allocatable :: mr(:), er(:)
      character(len=:), allocatable :: cn
      character(len=*), parameter :: RNORM = 'pi times radiance divided by the incident solar'// &
        ' flux on a horizontal plane (diffuse light only; the bidirectional reflectance factor'// &
        ' for upward light at the top)'
      nd = lay%n_rad_dir
      nl = lay%n_rad_lev
      if (nd > 0) then
        call add_dim(set, 'direction', nd, coord=real(cfg%rad%mu, dp), units='1', &
                     long_name='cosine of the propagation direction from the upward vertical'// &
                     ' (> 0: upward light, seen by a downward-looking sensor)')
        call add_var(set, 'direction_phi', 'azimuth of the propagation direction (same frame '// &
                     'as phi0_deg: from +x towards +y)', 'degree', ['direction'], &
                     real(cfg%rad%phi_deg, dp))
        call add_dim(set, 'rad_level', nl, coord=z(cfg%rad%levels), units='m', &
                     long_name='height of the radiance levels')
        nn = nd*nl
        call put('radiance', RNORM, [(lay%i_rad + i, i=1, nn)], &
                 dims=['rad_level', 'direction'])
        if (f_hor > 0.0_dp) then
          mr = stats_mean1([(lay%i_rad + i, i=1, nn)])*f_hor/PI
          er = stats_err1([(lay%i_rad + i, i=1, nn)])*f_hor/PI
          call add_var(set, 'radiance_wm2sr', 'diffuse radiance', 'W m-2 sr-1', &
                       ['rad_level', 'direction'], mr, er)
        end if
        if (lay%do_rad_maps) then
          if (.not. (lay%do_maps .or. lay%do_voxel)) then
            call add_dim(set, 'x', scene%atm%nx, units='m', long_name='x of the column centres', &
                         coord=[((i - 0.5_dp)*scene%atm%dx, i=1, scene%atm%nx)])
            call add_dim(set, 'y', scene%atm%ny, units='m', long_name='y of the column centres', &
                         coord=[((i - 0.5_dp)*scene%atm%dy, i=1, scene%atm%ny)])
          end if
          call put('radiance_map', RNORM//', per column', &
                   [(lay%i_rad_map + i, i=1, nn*ncol)], &
                   dims=['x        ', 'y        ', 'rad_level', 'direction'])
        end if
      end if
      do c = 1, size(lay%i_cam)
        cn = 'camera'//str(c)
        np = cfg%cam%npx(c)*cfg%cam%npy(c)
        call add_dim(set, cn//'_x', cfg%cam%npx(c), long_name='pixel column of camera '//str(c))
        call add_dim(set, cn//'_y', cfg%cam%npy(c), long_name='pixel row of camera '//str(c))
        call put(cn//'_radiance', RNORM//', mean over each pixel of camera '//str(c), &
                 [(lay%i_cam(c) + i, i=1, np)], dims=[cn//'_x', cn//'_y'])
        if (f_hor > 0.0_dp) then
          call add_var(set, cn//'_radiance_wm2sr', 'radiance, mean over each pixel', &
                       'W m-2 sr-1', [cn//'_x', cn//'_y'], &
                       stats_mean1([(lay%i_cam(c) + i, i=1, np)])*f_hor/PI, &
                       stats_err1([(lay%i_cam(c) + i, i=1, np)])*f_hor/PI)
        end if
      end do
    end subroutine radiance_results

    subroutine put(name, long_name, idx, dims)
      character(len=*), intent(in) :: name, long_name
      integer, intent(in) :: idx(:)
      character(len=*), intent(in), optional :: dims(:)
      if (present(dims)) then
        call add_var(set, name, long_name, '1', dims, stats_mean1(idx), stats_err1(idx))
      else if (size(idx) == 1) then
        call add_var(set, name, long_name, '1', [character(len=1) ::], stats_mean1(idx), &
                     stats_err1(idx))
      else
        call add_var(set, name, long_name, '1', ['level'], stats_mean1(idx), stats_err1(idx))
      end if
    end subroutine put

    function stats_mean1(idx) result(v)
      integer, intent(in) :: idx(:)
      real(dp) :: v(size(idx))
      integer :: j
      do j = 1, size(idx)
        v(j) = st%s1(idx(j))/real(st%n_batches, dp)
      end do
    end function stats_mean1

    function stats_err1(idx) result(v)
      integer, intent(in) :: idx(:)
      real(dp) :: v(size(idx))
      integer :: j
      real(dp) :: tmp(1)
      do j = 1, size(idx)
        tmp = stats_stderr(st, idx(j), idx(j))
        v(j) = tmp(1)
      end do
    end function stats_err1

    function classes() result(s)
      character(len=:), allocatable :: s
      s = join(LAYER_CLASS_NAMES(scene%atm%layer_class(1:scene%atm%nz)))
    end function classes

    function sv_text() result(s)
      character(len=:), allocatable :: s
      integer :: j
      s = str(scene%atm%sv%ns)//' super-layers'
      do j = 1, scene%atm%sv%ns
        s = s//'; layers '//str(scene%atm%k3_lo + scene%atm%sv%kb(j) - 1)//'-'// &
            str(scene%atm%k3_lo + scene%atm%sv%kt(j) - 1)//': blocks of '// &
            str(scene%atm%sv%bx(j))//'x'//str(scene%atm%sv%by(j))//' voxels'
      end do
    end function sv_text
  end subroutine build_results

  !> Print the headline numbers, their standard errors and the anomaly counts.
  subroutine log_summary(set, summary, path)
    type(result_set_t), intent(in) :: set
    type(run_summary_t), intent(in) :: summary
    character(len=*), intent(in) :: path
    character(len=24), parameter :: names(5) = [character(len=24) :: 'reflectance', &
      'transmittance', 'absorptance_atmosphere', 'absorptance_surface', 'energy_closure']
    integer :: i, j
    write (output_unit, '(a)') 'photons '//str(summary%n_photons)//' in '// &
      str(summary%n_batches)//' batches on '//str(summary%n_ranks)//' rank(s); wall '// &
      str(summary%wall_time)//' s, cpu '//str(summary%cpu_time)//' s'
    do i = 1, size(names)
      do j = 1, size(set%vars)
        if (trim(set%vars(j)%name) == trim(names(i))) then
          write (output_unit, '(2x,a24,f12.6,a,f10.6)') names(i), set%vars(j)%mean(1), ' +- ', &
            set%vars(j)%stderr(1)
        end if
      end do
    end do
    call log_radiances(set)
    do i = 1, N_ANOMALIES
      if (summary%anomalies(i) > 0) write (output_unit, '(a)') '  anomaly '// &
        trim(ANOMALY_NAMES(i))//': '//str(summary%anomalies(i))
    end do
    write (output_unit, '(a)') 'wrote '//path
  end subroutine log_summary

  !> The domain-mean radiances, one line per direction and level, leaving out exact zeros (no
  !> light enters at the top; a black surface reflects none); at most MAX_LINES lines.
  subroutine log_radiances(set)
    type(result_set_t), intent(in) :: set
    integer, parameter :: MAX_LINES = 12
    integer :: iv, iphi, idir, ilev, nd, nl, j, k, lines
    real(dp) :: mu, phi, z
    iv = find_var(set, 'radiance')
    iphi = find_var(set, 'direction_phi')
    idir = 0
    ilev = 0
    do j = 1, size(set%dims)
      if (trim(set%dims(j)%name) == 'direction') idir = j
      if (trim(set%dims(j)%name) == 'rad_level') ilev = j
    end do
    if (iv == 0 .or. iphi == 0 .or. idir == 0 .or. ilev == 0) return
    nd = set%dims(idir)%size
    nl = set%dims(ilev)%size
    lines = 0
    do j = 1, nd
      mu = set%dims(idir)%coord(j)
      phi = set%vars(iphi)%mean(j)
      do k = 1, nl
        z = set%dims(ilev)%coord(k)
        if (set%vars(iv)%mean(k + (j - 1)*nl) == 0.0_dp .and. &
            set%vars(iv)%stderr(k + (j - 1)*nl) == 0.0_dp) cycle
        lines = lines + 1
        if (lines > MAX_LINES) then
          write (output_unit, '(a)') '  radiance: ... (all in the file)'
          return
        end if
        write (output_unit, '(2x,a,f7.4,a,f7.1,a,f9.1,a,f12.6,a,f10.6)') 'radiance mu', mu, &
          ' phi', phi, ' z', z, ' m', set%vars(iv)%mean(k + (j - 1)*nl), ' +- ', &
          set%vars(iv)%stderr(k + (j - 1)*nl)
      end do
    end do
  end subroutine log_radiances
end module kumo_driver
