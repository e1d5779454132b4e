! SPDX-License-Identifier: BSD-3-Clause
!> The output schema and the run log: which products a run writes (names, dimensions, units,
!> attributes), formed from the batch statistics of the tallies, and the summary printed at the
!> end. The netCDF writer writes any result set generically, so the output layout lives here.
module kumo_output
  use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
  use kumo_kinds, only: wp, dp, i8
  use kumo_constants, only: KUMO_VERSION, SECONDS_PER_DAY, PI
  use kumo_error, only: error_t, str, join
  use kumo_planck, only: band_brightness_temperature, band_dradiance_dt
  use kumo_emission, only: emission_voxel_power
  use kumo_atmosphere, only: LAYER_CLASS_NAMES
  use kumo_tally, only: tally_layout_t, stats_t, stats_mean, stats_stderr, N_ANOMALIES, &
                        ANOMALY_NAMES, ANOM_EVENT_CAP, ANOM_STEP_CAP
  use kumo_scene, only: scene_t
  use kumo_results, only: result_set_t, add_dim, add_var, take_var, defer_var, keep_sums, &
                          materialize_vars, var_has_stderr, add_attr, add_num_attr, find_var, &
                          find_dim
  use kumo_config, only: config_t, config_echo
  use kumo_parallel, only: PAR_IS_MPI
  use kumo_vr, only: roulette_balance_warning, few_batches_warning, loop_cap_warning
  use kumo_exact_column, only: exact_thermal_possible
  implicit none
  private
  public :: run_summary_t, build_results, log_summary, log_memory, peak_resident_bytes

  !> Entries formed at a time from the sums (stats_mean, stats_stderr) when a large product is
  !> built: no temporary array as large as the product.
  integer, parameter :: FORM_PIECE = 65536

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
    integer(i8) :: peak_rss_batches = -1_i8 !! rank 0's peak resident set after the batches [bytes]
    integer(i8) :: sums_bytes = 0_i8    !! bytes of the batch sums of the tallies (S1 and S2)
  end type run_summary_t

contains

  !> Lay out every product with its standard error, units and provenance.
  !>
  !> The per-column flux maps, the column budget, the camera images and the per-voxel products
  !> are deferred (kumo_results): the set takes the sums `st` (moved: `st` is empty on return) and these
  !> products are formed from them when they are written, piece by piece, so that rank 0 never
  !> holds them beside the sums. With `defer` false (the default) they are formed at the end,
  !> for callers that read the values. Other products are formed into their own arrays and
  !> moved into the set, with no temporary larger than FORM_PIECE entries.
  subroutine build_results(cfg, scene, lay, st, rec, summary, set, defer)
    type(config_t), intent(in) :: cfg
    type(scene_t), intent(in) :: scene
    type(tally_layout_t), intent(in) :: lay
    type(stats_t), intent(inout) :: st
    real(dp), intent(in) :: rec(:, :)
    type(run_summary_t), intent(in) :: summary
    type(result_set_t), intent(inout) :: set
    logical, intent(in), optional :: defer
    integer :: nz, k, n_out, i, ncol, kr, nv
    integer, allocatable :: lev(:), mlev(:)
    character(len=9) :: map_dim
    real(dp), allocatable :: z(:), zmid(:), dz(:), m(:), e(:), fac(:), ma(:), fz(:), fh(:)
    real(dp) :: f_hor
    integer :: tv(8)
    character(len=:), allocatable :: NORM, fu, band_kind
    character(len=32) :: stamp
    logical :: thermal
    thermal = scene%src%em%on
    NORM = ' normalised by the incident solar flux on a horizontal plane'
    fu = 'W m-2'
    if (thermal) then
      NORM = ' divided by the total source power per unit area (source_power)'
      fu = trim(scene%src%em%flux_units)
    end if
    associate (atm => scene%atm)
      nz = atm%nz
      z = atm%z
      zmid = 0.5_dp*(z(1:nz) + z(0:nz - 1))
      dz = z(1:nz) - z(0:nz - 1)
      lev = cfg%output%flux_levels
      n_out = size(lev)
      ncol = lay%ncol
      f_hor = cfg%source%solar_flux*scene%mu0   ! incident flux on a horizontal plane [W m-2]
      ! with emission the tallies are in units of the total source power per unit area
      if (thermal) f_hor = scene%src%em%power

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
      if (any(cfg%vr%absorption_estimator == ['collision   ', 'track_voxels'])) then
        call put('roulette_weight_balance', 'net weight created by Russian roulette and DDIS'// &
                 ' splitting'//NORM//' (zero in expectation)', [lay%i_rr + 1])
      else
        call put('roulette_weight_balance', 'net weight created by Russian roulette and DDIS'// &
                 ' splitting, and expected-value absorption scores minus the weight lost at'// &
                 ' collisions (absorption_estimator = '//trim(cfg%vr%absorption_estimator)//')'// &
                 NORM//' (zero in expectation)', [lay%i_rr + 1])
      end if
      call put('weight_lost', 'weight of photons stopped at a loop cap'//NORM, [lay%i_lost + 1])
      ! the closure's sum is relative to the weight the photons brought (kumo_tally): with
      ! emission the power they were launched with, which in broadband longwave runs leaves out
      ! the emission that each layer reabsorbs itself (photons are drawn by the power that
      ! leaves a layer), so the sum itself is below 1 there
      if (thermal) then
        call put('energy_closure', '(reflectance + absorptance_atmosphere + '// &
                 'absorptance_surface - roulette_weight_balance + weight_lost) divided by the '// &
                 'share of source_power the photons were launched with (broadband longwave runs '// &
                 'draw photons by the power that leaves each layer, not by its emission; 1 to '// &
                 'round-off)', &
                 [lay%i_closure + 1])
      else if (lay%weighted) then
        call put('energy_closure', '(reflectance + absorptance_atmosphere + '// &
                 'absorptance_surface - roulette_weight_balance + weight_lost) divided by the '// &
                 'downward flux at the top (a batch of g-points lets in mu0 TSI on average; 1 '// &
                 'to round-off)', [lay%i_closure + 1])
      else
        call put('energy_closure', 'reflectance + absorptance_atmosphere + absorptance_surface'// &
                 ' - roulette_weight_balance + weight_lost (1 to round-off)', [lay%i_closure + 1])
      end if

      ! heating of the layers
      if (f_hor > 0.0_dp) then
        fac = f_hor/dz
        m = stats_mean(st, lay%i_abs + 1, lay%i_abs + nz)*fac
        e = stats_stderr(st, lay%i_abs + 1, lay%i_abs + nz)*fac
        call add_var(set, 'flux_up_wm2', 'upward flux', fu, ['level'], &
                     stats_mean1(lay%i_up + lev + 1)*f_hor, stats_err1(lay%i_up + lev + 1)*f_hor)
        call add_var(set, 'flux_down_wm2', 'downward flux (direct + diffuse)', fu, &
                     ['level'], stats_mean1(lay%i_dn + lev + 1)*f_hor, &
                     stats_err1(lay%i_dn + lev + 1)*f_hor)
        call add_var(set, 'flux_down_direct_wm2', 'downward direct flux', fu, ['level'], &
                     stats_mean1(lay%i_dir + lev + 1)*f_hor, stats_err1(lay%i_dir + lev + 1)*f_hor)
        call add_var(set, 'flux_down_diffuse_wm2', 'downward diffuse flux', fu, ['level'], &
                     stats_mean1(lay%i_dif + lev + 1)*f_hor, stats_err1(lay%i_dif + lev + 1)*f_hor)
        ! formed per batch (kumo_tally), so its standard error includes the correlation of the
        ! up and down fluxes
        call add_var(set, 'flux_net_wm2', 'net downward flux (down - up)', fu, ['level'], &
                     stats_mean1(lay%i_fnet + lev + 1)*f_hor, stats_err1(lay%i_fnet + lev + 1)*f_hor)
        call add_var(set, 'absorbed_power_density_layer', 'layer-mean absorbed power per volume', &
                     'W m-3'//fu(6:), ['layer'], m, e)
        if (thermal) call thermal_layer_results()
        if (allocated(scene%air_density)) then
          fac = SECONDS_PER_DAY/(scene%air_density*cfg%atm%cp_air)
          call add_var(set, 'heating_rate_layer', 'layer-mean heating rate', 'K day-1'//fu(6:), &
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
        ! on the flux levels, or on levels of their own (map_levels)
        mlev = cfg%output%map_level_list()
        map_dim = 'level'
        if (size(mlev) /= n_out) then
          map_dim = 'map_level'
        else if (any(mlev /= lev)) then
          map_dim = 'map_level'
        end if
        if (map_dim == 'map_level') call add_dim(set, 'map_level', size(mlev), coord=z(mlev), &
                                                 units='m', long_name='height of the levels '// &
                                                 'of the per-column flux maps')
        call put_range('flux_up_map', 'upward flux per column'//NORM, lay%i_map_up, &
                       lay%n_map*ncol, [character(len=9) :: 'x', 'y', map_dim])
        call put_range('flux_down_direct_map', 'downward direct flux per column'//NORM, &
                       lay%i_map_dir, lay%n_map*ncol, [character(len=9) :: 'x', 'y', map_dim])
        call put_range('flux_down_diffuse_map', 'downward diffuse flux per column'//NORM, &
                       lay%i_map_dif, lay%n_map*ncol, [character(len=9) :: 'x', 'y', map_dim])
        call put_range('flux_down_map', 'total (direct + diffuse) downward flux per column'//NORM, &
                       lay%i_map_dn, lay%n_map*ncol, [character(len=9) :: 'x', 'y', map_dim])
      end if
      if (lay%do_voxel) then
        nv = atm%n3*ncol
        call add_dim(set, 'z3d', atm%n3, coord=zmid(atm%k3_lo:atm%k3_hi), units='m', &
                     long_name='height of the layer centres of the 3-D region')
        call put_range('absorptance_voxel', 'power absorbed per voxel per unit column area'//NORM, &
                       lay%i_vox, nv, ['x  ', 'y  ', 'z3d'])
        ! per volume: times 1/dz of the voxel's layer (fz), then the layer's factor
        fz = 1.0_dp/dz(atm%k3_lo:atm%k3_hi)
        if (f_hor > 0.0_dp) then
          allocate (fh(atm%n3))
          fh = f_hor
          call defer_var(set, 'absorbed_power_density_voxel', 'absorbed power per volume', &
                         'W m-3'//fu(6:), ['x  ', 'y  ', 'z3d'], lay%i_vox, nv, ncol, fz, fh)
          if (thermal) then
            ! heating from the net power (net exchange), not from what is absorbed
            ma = emission_voxel_power(scene%src%em)
            do kr = 1, atm%n3
              ma((kr - 1)*ncol + 1:kr*ncol) = ma((kr - 1)*ncol + 1:kr*ncol)*fz(kr)
            end do
            call take_var(set, 'emitted_power_density_voxel', 'emitted power per volume '// &
                          '(exact)', 'W m-3'//fu(6:), ['x  ', 'y  ', 'z3d'], ma)
            call defer_var(set, 'net_power_density_voxel', 'absorbed minus emitted power per '// &
                           'volume (net exchange estimator)', 'W m-3'//fu(6:), &
                           ['x  ', 'y  ', 'z3d'], lay%i_vnet, nv, ncol, fz, fh)
          end if
          if (allocated(scene%air_density)) then
            do kr = 1, atm%n3
              fh(kr) = f_hor*SECONDS_PER_DAY/(scene%air_density(atm%k3_lo + kr - 1)*cfg%atm%cp_air)
            end do
            call defer_var(set, 'heating_rate_voxel', 'heating rate', 'K day-1'//fu(6:), &
                           ['x  ', 'y  ', 'z3d'], merge(lay%i_vnet, lay%i_vox, thermal), nv, &
                           ncol, fz, fh)
          end if
        else
          call defer_var(set, 'absorbed_power_density_voxel', 'absorbed power per volume per'// &
                         ' unit incident solar flux on a horizontal plane', 'm-1', &
                         ['x  ', 'y  ', 'z3d'], lay%i_vox, nv, ncol, fz)
        end if
      end if

      if (lay%do_budget) then
        call put_range('absorptance_column', 'power absorbed in the 3-D region of each column per'// &
                       ' unit column area'//NORM, lay%i_col_abs, ncol, ['x', 'y'])
        call put_range('horizontal_transport_map', 'net power leaving the 3-D region of each'// &
                       ' column through its sides, per unit column area'//NORM// &
                       ' (net flux in at the top - net flux out at the bottom - absorptance_column)', &
                       lay%i_htr, ncol, ['x', 'y'])
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
      ! numbers are stored as numbers (double: the classic model has no 64-bit integers; a seed
      ! beyond 2**53 would not survive that, so it stays text)
      if (abs(cfg%control%seed) < 2_i8**53) then
        call add_num_attr(set, 'seed', real(cfg%control%seed, dp))
      else
        call add_attr(set, 'seed', str(cfg%control%seed))
      end if
      call add_num_attr(set, 'n_photons', real(summary%n_photons, dp))
      call add_num_attr(set, 'n_batches', real(summary%n_batches, dp))
      call add_num_attr(set, 'n_photons_per_batch', real(cfg%control%n_photons_per_batch, dp))
      call add_num_attr(set, 'n_ranks', real(summary%n_ranks, dp))
      call add_attr(set, 'parallel', merge('MPI   ', 'serial', PAR_IS_MPI))
      call add_num_attr(set, 'wall_time_s', summary%wall_time)
      call add_num_attr(set, 'cpu_time_s', summary%cpu_time)
      call add_num_attr(set, 'setup_time_s', summary%setup_time)
      call add_num_attr(set, 'solar_zenith_angle_deg', real(cfg%source%sza_deg, dp))
      if (cfg%source%wavelength_um > 0.0_wp) then
        call add_num_attr(set, 'wavelength_um', real(cfg%source%wavelength_um, dp))
        call add_var(set, 'wavelength', 'wavelength of the radiation', 'um', &
                     [character(len=1) ::], [real(cfg%source%wavelength_um, dp)])
      end if
      if (thermal) then
        call add_attr(set, 'normalisation', 'fluxes and absorptances are divided by the total '// &
                      'source power per unit area P = '//str(scene%src%em%power)//' '//fu// &
                      ' (source_power); *_wm2, *_power_* and radiance_wm2sr are absolute')
        call add_attr(set, 'thermal_emission', 'atmosphere, surface and top emit (Planck '// &
                      'radiances in '//trim(scene%src%em%radiance_units)//'); heating from the '// &
                      'net-exchange estimator; emission_floor = '//str(cfg%thermal%emission_floor))
        call add_num_attr(set, 'surface_emissivity', real(scene%src%em%eps_mean, dp))
        if (cfg%spectral%enabled) call add_attr(set, 'broadband', 'longwave, Monte Carlo '// &
          'integration over the g-points of '//trim(cfg%spectral%kdist_file)//' (photons by '// &
          'each g-point''s radiative exchange without scattering, floor share '// &
          str(cfg%spectral%floor_share)//'; exact sums where no layer scatters); gas profile '// &
          trim(merge(cfg%spectral%profile, 'sounding        ', len_trim(cfg%spectral%profile) > 0)))
      else if (cfg%spectral%enabled) then
        ! broadband shortwave (&kumo_spectral): F0 is the total solar irradiance
        call add_attr(set, 'normalisation', 'broadband: fluxes and absorptances are divided by '// &
                      'the total incident solar flux on a horizontal plane, mu0*TSI; *_wm2, power '// &
                      'densities and heating rates are absolute (TSI = '//str(cfg%spectral%tsi)// &
                      ' W m-2), each with its standard error')
        call add_attr(set, 'broadband', 'shortwave, Monte Carlo integration over the g-points '// &
                      'of '//trim(cfg%spectral%kdist_file)//' (photons by solar energy, floor '// &
                      'share '//str(cfg%spectral%floor_share)//'); gas profile '// &
                      trim(merge(cfg%spectral%profile, 'sounding        ', &
                                 len_trim(cfg%spectral%profile) > 0)))
        call add_num_attr(set, 'total_solar_irradiance_wm2', real(cfg%spectral%tsi, dp))
      else
        call add_attr(set, 'normalisation', 'fluxes and absorptances are divided by the incident'// &
                      ' solar flux on a horizontal plane, mu0*F0; *_wm2 and power densities use F0 = '// &
                      str(cfg%source%solar_flux)//' W m-2')
      end if
      call add_num_attr(set, 'flight_steps_per_photon', &
                        real(summary%flight_steps, dp)/real(max(1_i8, summary%n_photons), dp))
      call add_num_attr(set, 'events_per_photon', &
                        real(summary%events, dp)/real(max(1_i8, summary%n_photons), dp))
      call add_attr(set, 'layer_classes', classes())
      if (cfg%spectral%enabled .and. scene%det%active .and. cfg%vr%cf_tau_min > 0.0_wp) then
        ! broadband radiances: each g-point is forced by its own column
        call add_attr(set, 'collision_forcing', 'per g-point: the factor cf_tau_min/(tau/mu0) '// &
                      'of the g-point''s column optical depth tau, at least 1 (cf_tau_min = '// &
                      str(cfg%vr%cf_tau_min)//')')
      else
        call add_num_attr(set, 'collision_forcing_factor', real(scene%vr%cf_factor, dp))
      end if
      call add_num_attr(set, 'truncation_levels', real(atm%trunc%n_levels, dp))
      call add_attr(set, 'vr_preset', trim(cfg%vr%preset))
      call add_attr(set, 'mode_3d', trim(cfg%control%mode_3d))
      if (cfg%control%mode_3d == 'p3d') call add_num_attr(set, 'p3d_orders', &
                                                          real(cfg%control%p3d_orders, dp))
      ! warnings about the finished run (kumo_vr) join the scene's: log and file
      block
        character(len=:), allocatable :: warn, rr_warn
        real(dp) :: bal(1), bal_err(1), lost(1)
        bal = stats_mean(st, lay%i_rr + 1, lay%i_rr + 1)
        bal_err = stats_stderr(st, lay%i_rr + 1, lay%i_rr + 1)
        rr_warn = roulette_balance_warning(bal(1), bal_err(1), st%n_batches)
        if (len(rr_warn) > 0 .and. all(cfg%vr%absorption_estimator /= ['collision   ', 'track_voxels'])) &
          rr_warn = &
          rr_warn//' (with absorption_estimator = '//trim(cfg%vr%absorption_estimator)//' the '// &
          'balance also holds the expected-value absorption scores minus the weight lost at '// &
          'collisions)'
        warn = scene%warnings
        call append_warning(warn, rr_warn)
        ! error bars from few batches are themselves uncertain (checked on the batches run, so
        ! that rounds of target_rel_error and resumed checkpoints count); a column solved
        ! exactly has no statistical error to doubt
        if (.not. (scene%exact_thermal .and. exact_thermal_possible(scene))) &
          call append_warning(warn, few_batches_warning(st%n_batches))
        lost = stats_mean(st, lay%i_lost + 1, lay%i_lost + 1)
        call append_warning(warn, loop_cap_warning(summary%anomalies(ANOM_EVENT_CAP), &
                                                   summary%anomalies(ANOM_STEP_CAP), &
                                                   cfg%control%max_events, lost(1)))
        if (len(warn) > 0) call add_attr(set, 'warnings', warn)
      end block
      if (len(scene%notes) > 0) call add_attr(set, 'scene_notes', scene%notes)
      call add_attr(set, 'supervoxels', sv_text())
      do i = 1, N_ANOMALIES
        call add_num_attr(set, 'anomaly_'//trim(ANOMALY_NAMES(i)), real(summary%anomalies(i), dp))
      end do
    end associate
    band_kind = 'shortwave'
    if (thermal) then
      band_kind = 'longwave'
      if (scene%src%em%solar_power > 0.0_dp .or. fu /= 'W m-2') band_kind = ''
    end if
    call cf_annotate(set, band_kind)
    set%deflate = cfg%output%deflate_level
    call keep_sums(set, st)
    if (present(defer)) then
      if (defer) return
    end if
    call materialize_vars(set)

  contains

    !> Radiances at levels (domain means and maps) and camera images, as pi I/(mu0 F0), and
    !> in W m-2 sr-1 when F0 is known.
    subroutine radiance_results()
      integer :: nd, nl, nn, c, np
      real(dp), allocatable :: mr(:), er(:)
      character(len=:), allocatable :: cn, RNORM, ru
      RNORM = 'pi times radiance divided by the incident solar'// &
        ' flux on a horizontal plane (diffuse light only; the bidirectional reflectance factor'// &
        ' for upward light at the top)'
      ru = 'W m-2 sr-1'
      if (thermal) then
        RNORM = 'pi times radiance divided by the total source power per unit area '// &
                '(source_power; the direct solar beam left out)'
        ru = trim(scene%src%em%radiance_units)
      end if
      nd = lay%n_rad_dir
      nl = lay%n_rad_lev
      if (nd > 0) then
        ! directions are numbered: mu repeats (several azimuths), so mu and phi are auxiliary
        ! coordinates of the dimension (CF), not its coordinate variable
        call add_dim(set, 'direction', nd)
        call add_var(set, 'direction_mu', 'cosine of the propagation direction from the upward'// &
                     ' vertical (> 0: upward light, seen by a downward-looking sensor)', '1', &
                     ['direction'], real(cfg%rad%mu, dp))
        call add_var(set, 'direction_phi', 'azimuth of the propagation direction (same frame '// &
                     'as phi0_deg: from +x towards +y)', 'degree', ['direction'], &
                     real(cfg%rad%phi_deg, dp))
        call add_dim(set, 'rad_level', nl, coord=z(cfg%rad%levels), units='m', &
                     long_name='height of the radiance levels')
        nn = nd*nl
        mr = stats_mean1([(lay%i_rad + i, i=1, nn)])
        er = stats_err1([(lay%i_rad + i, i=1, nn)])
        if (thermal) call add_top(mr, 1)
        call add_var(set, 'radiance', RNORM, '1', ['rad_level', 'direction'], mr, er)
        if (f_hor > 0.0_dp) then
          mr = mr*f_hor/PI
          er = er*f_hor/PI
          call add_var(set, 'radiance_wm2sr', 'diffuse radiance', ru, &
                       ['rad_level', 'direction'], mr, er)
          if (thermal) call brightness(mr, er, 'brightness_temperature', &
                                       ['rad_level', 'direction'])
        end if
        if (lay%do_rad_maps) then
          if (.not. (lay%do_maps .or. lay%do_voxel)) then
            call add_dim(set, 'x', scene%atm%nx, units='m', long_name='x of the column centres', &
                         coord=[((i - 0.5_dp)*scene%atm%dx, i=1, scene%atm%nx)])
            call add_dim(set, 'y', scene%atm%ny, units='m', long_name='y of the column centres', &
                         coord=[((i - 0.5_dp)*scene%atm%dy, i=1, scene%atm%ny)])
          end if
          call form(lay%i_rad_map, nn*ncol, mr, er)
          if (thermal) call add_top(mr, ncol)
          call take_var(set, 'radiance_map', RNORM//', per column', '1', &
                        ['x        ', 'y        ', 'rad_level', 'direction'], mr, er)
        end if
      end if
      do c = 1, size(lay%i_cam)
        cn = 'camera'//str(c)
        np = cfg%cam%npx(c)*cfg%cam%npy(c)
        call add_dim(set, cn//'_x', cfg%cam%npx(c), coord=[(real(i, dp), i=1, cfg%cam%npx(c))], &
                     units='1', long_name='pixel column of camera '//str(c)//' (1: left)')
        call add_dim(set, cn//'_y', cfg%cam%npy(c), coord=[(real(i, dp), i=1, cfg%cam%npy(c))], &
                     units='1', long_name='pixel row of camera '//str(c)//' (1: bottom)')
        call put_range(cn//'_radiance', RNORM//', mean over each pixel of camera '//str(c), &
                       lay%i_cam(c), np, [cn//'_x', cn//'_y'])
        if (f_hor > 0.0_dp) then
          call form(lay%i_cam(c), np, mr, er)
          mr = mr*f_hor/PI
          er = er*f_hor/PI
          call add_var(set, cn//'_radiance_wm2sr', 'radiance, mean over each pixel', &
                       ru, [cn//'_x', cn//'_y'], mr, er)
          if (thermal) call brightness(mr, er, cn//'_brightness_temperature', &
                                       [cn//'_x', cn//'_y'])
        end if
      end do
    end subroutine radiance_results

    !> Thermal emission: emitted (exact), absorbed and net power of each layer and of the
    !> surface in absolute units; the layer heating that follows uses the net power.
    subroutine thermal_layer_results()
      real(dp), allocatable :: mn(:), en(:)
      associate (em => scene%src%em)
        call add_var(set, 'source_power', 'total source power per unit area (emission by the '// &
                     'atmosphere, the surface and the top, and the sun if it shines)', fu, &
                     [character(len=1) ::], [em%power])
        call add_var(set, 'emitted_power_layer', 'power emitted by each layer per unit area '// &
                     '(exact)', fu, ['layer'], em%emit_layer)
        call add_var(set, 'absorbed_power_layer', 'power absorbed by each layer per unit area', &
                     fu, ['layer'], stats_mean(st, lay%i_abs + 1, lay%i_abs + nz)*f_hor, &
                     stats_stderr(st, lay%i_abs + 1, lay%i_abs + nz)*f_hor)
        mn = stats_mean(st, lay%i_net + 1, lay%i_net + nz)*f_hor
        en = stats_stderr(st, lay%i_net + 1, lay%i_net + nz)*f_hor
        call add_var(set, 'net_power_layer', 'absorbed minus emitted power of each layer per '// &
                     'unit area (net exchange estimator)', fu, ['layer'], mn, en)
        call add_var(set, 'emitted_power_surface', 'power emitted by the surface per unit area '// &
                     '(exact)', fu, [character(len=1) ::], [em%emit_sfc])
        call add_var(set, 'net_power_surface', 'absorbed minus emitted power of the surface '// &
                     'per unit area (net exchange estimator)', fu, [character(len=1) ::], &
                     stats_mean1([lay%i_snet + 1])*f_hor, stats_err1([lay%i_snet + 1])*f_hor)
        call add_var(set, 'net_power_density_layer', 'layer-mean absorbed minus emitted power '// &
                     'per volume (net exchange estimator)', 'W m-3'//fu(6:), ['layer'], mn/dz, &
                     en/dz)
        ! the heating rates below follow from the net power
        m = mn/dz
        e = en/dz
      end associate
    end subroutine thermal_layer_results

    !> Thermal runs: downward at the top level, the radiance coming in from above (exact, in
    !> the units of `v`: pi B_top/P), for `nc` values per level and direction.
    subroutine add_top(v, nc)
      real(dp), intent(inout) :: v(:)
      integer, intent(in) :: nc
      integer :: d, i0, ts
      ts = findloc(cfg%rad%levels, scene%atm%nz, 1)
      if (ts == 0) return
      do d = 1, lay%n_rad_dir
        if (cfg%rad%mu(d) >= 0.0_wp) cycle
        i0 = ((d - 1)*lay%n_rad_lev + ts - 1)*nc
        v(i0 + 1:i0 + nc) = v(i0 + 1:i0 + nc) + PI*scene%src%em%b_top/f_hor
      end do
    end subroutine add_top

    !> Brightness temperatures of radiances `r` with standard errors `er` (to first order,
    !> er/(dB/dT)), when the spectral interval is known.
    subroutine brightness(r, er, name, dims)
      real(dp), intent(in) :: r(:), er(:)
      character(len=*), intent(in) :: name, dims(:)
      real(dp) :: t(size(r)), et(size(r)), db
      type(error_t), allocatable :: err
      integer :: j
      associate (em => scene%src%em)
        if (.not. em%has_band) return
        do j = 1, size(r)
          t(j) = 0.0_dp
          et(j) = 0.0_dp
          if (r(j) <= 0.0_dp) cycle
          call band_brightness_temperature(em%band, r(j)*em%to_band_units, t(j), err)
          if (allocated(err)) then
            t(j) = 0.0_dp
            cycle
          end if
          db = band_dradiance_dt(em%band, t(j))/em%to_band_units
          if (db > 0.0_dp) et(j) = er(j)/db
        end do
      end associate
      call add_var(set, name, 'brightness temperature of the radiance (the temperature whose '// &
                   'Planck radiance in the spectral interval equals it)', 'K', dims, t, et)
    end subroutine brightness

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

    !> A product of `n` entries from position lo + 1 of the buffer, deferred.
    subroutine put_range(name, long_name, lo, n, dims)
      character(len=*), intent(in) :: name, long_name, dims(:)
      integer, intent(in) :: lo, n
      call defer_var(set, name, long_name, '1', dims, lo, n)
    end subroutine put_range

    !> Mean and standard error of the `n` entries from position lo + 1 of the buffer, formed
    !> FORM_PIECE entries at a time.
    subroutine form(lo, n, mf, ef)
      integer, intent(in) :: lo, n
      real(dp), allocatable, intent(inout) :: mf(:), ef(:)
      integer :: j, nj
      if (allocated(mf)) deallocate (mf)
      if (allocated(ef)) deallocate (ef)
      allocate (mf(n), ef(n))
      do j = 0, n - 1, FORM_PIECE
        nj = min(FORM_PIECE, n - j)
        mf(j + 1:j + nj) = stats_mean(st, lo + j + 1, lo + j + nj)
        ef(j + 1:j + nj) = stats_stderr(st, lo + j + 1, lo + j + nj)
      end do
    end subroutine form

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

  !> A warning about the finished run (empty text: none) goes to standard error and is appended
  !> to the warnings text of the output file.
  subroutine append_warning(warn, text)
    character(len=:), allocatable, intent(inout) :: warn
    character(len=*), intent(in) :: text
    if (len(text) == 0) return
    write (error_unit, '(a)') 'kumo: warning: '//trim(text)
    if (len_trim(warn) > 0) warn = trim(warn)//' '
    warn = warn//text
  end subroutine append_warning

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
    call log_thermal(set)
    call log_radiances(set)
    do i = 1, N_ANOMALIES
      if (summary%anomalies(i) > 0) write (output_unit, '(a)') '  anomaly '// &
        trim(ANOMALY_NAMES(i))//': '//str(summary%anomalies(i))
    end do
    write (output_unit, '(a)') 'wrote '//path
    flush (output_unit)
  end subroutine log_summary

  !> The memory line of the run log (verbose >= 2, rank 0): rank 0's peak resident set after
  !> the batches and now (the output written), and the bytes of the sums of the tallies. The
  !> output stage should add little to the peak: rank 0 then holds the sums and the small
  !> products, not a copy of the large ones. Nothing is printed where the peak is unknown.
  subroutine log_memory(summary)
    type(run_summary_t), intent(in) :: summary
    integer(i8) :: now
    now = peak_resident_bytes()
    if (now < 0_i8 .or. summary%peak_rss_batches < 0_i8) return
    write (output_unit, '(a)') 'memory of rank 0: peak resident set '//str(summary%peak_rss_batches)// &
      ' bytes after the batches, '//str(now)//' bytes after the output; sums of the tallies '// &
      str(summary%sums_bytes)//' bytes'
    flush (output_unit)
  end subroutine log_memory

  !> This process's peak resident set [bytes] (VmHWM of /proc/self/status), -1 where it is not
  !> available.
  function peak_resident_bytes() result(nb)
    integer(i8) :: nb
    character(len=256) :: line
    integer :: unit, ios
    integer(i8) :: kib
    nb = -1_i8
    open (newunit=unit, file='/proc/self/status', action='read', status='old', iostat=ios)
    if (ios /= 0) return
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (line(1:6) /= 'VmHWM:') cycle
      read (line(7:), *, iostat=ios) kib
      if (ios == 0) nb = 1024_i8*kib
      exit
    end do
    close (unit)
  end function peak_resident_bytes

  !> CF metadata of a result set: standard names where CF has one (heights, fluxes in W m-2,
  !> heating rates), and the auxiliary and scalar coordinates of every result (the direction's
  !> mu and phi, the wavelength). The standard errors get their link (ancillary_variables) and
  !> the `standard_error` modifier from the writer.
  subroutine cf_annotate(set, band_kind)
    type(result_set_t), intent(inout) :: set
    !> 'shortwave', 'longwave', or '' (both in one run: no standard name for the fluxes)
    character(len=*), intent(in) :: band_kind
    integer :: i, j
    logical :: has_wl
    character(len=:), allocatable :: coords
    do i = 1, size(set%dims)
      select case (trim(set%dims(i)%name))
      case ('level', 'map_level', 'layer', 'z3d', 'rad_level')
        set%dims(i)%standard_name = 'height'
        set%dims(i)%axis = 'Z'
      end select
    end do
    has_wl = find_var(set, 'wavelength') > 0
    do i = 1, size(set%vars)
      associate (v => set%vars(i))
        if (len(band_kind) > 0) then
          select case (trim(v%name))
          case ('flux_up_wm2')
            v%standard_name = 'upwelling_'//band_kind//'_flux_in_air'
          case ('flux_down_wm2')
            v%standard_name = 'downwelling_'//band_kind//'_flux_in_air'
          case ('flux_down_direct_wm2')
            if (band_kind == 'shortwave') v%standard_name = 'direct_downwelling_shortwave_flux_in_air'
          case ('flux_down_diffuse_wm2')
            if (band_kind == 'shortwave') v%standard_name = 'diffuse_downwelling_shortwave_flux_in_air'
          case ('flux_net_wm2')
            v%standard_name = 'net_downward_'//band_kind//'_flux_in_air'
          case default
            if (index(v%name, 'heating_rate') == 1) &
              v%standard_name = 'tendency_of_air_temperature_due_to_'//band_kind//'_heating'
          end select
        end if
        if (.not. var_has_stderr(v)) cycle
        coords = ''
        do j = 1, v%ndims
          if (trim(v%dim_names(j)) == 'direction') coords = 'direction_mu direction_phi'
        end do
        if (has_wl) then
          if (len(coords) > 0) coords = coords//' '
          coords = coords//'wavelength'
        end if
        if (len(coords) > 0) v%coordinates = coords
      end associate
    end do
  end subroutine cf_annotate

  !> Thermal runs: the headline numbers in absolute units (upward flux at the highest written
  !> level, downward flux at the lowest, the net power of the atmosphere's layers and the range
  !> of the layer heating rates).
  subroutine log_thermal(set)
    type(result_set_t), intent(in) :: set
    integer :: iu, id, inet, ih, n, k
    character(len=:), allocatable :: units
    if (find_var(set, 'source_power') == 0) return
    iu = find_var(set, 'flux_up_wm2')
    id = find_var(set, 'flux_down_wm2')
    inet = find_var(set, 'net_power_layer')
    ih = find_var(set, 'heating_rate_layer')
    units = trim(set%vars(iu)%units)
    n = size(set%vars(iu)%mean)
    write (output_unit, '(2x,a24,f12.4,a,f10.4,a)') 'flux_up (top level)', set%vars(iu)%mean(n), &
      ' +- ', set%vars(iu)%stderr(n), ' '//units
    write (output_unit, '(2x,a24,f12.4,a,f10.4,a)') 'flux_down (lowest level)', &
      set%vars(id)%mean(1), ' +- ', set%vars(id)%stderr(1), ' '//units
    write (output_unit, '(2x,a24,f12.4,a,f10.4,a)') 'net power of the layers', &
      sum(set%vars(inet)%mean), ' +- ', sqrt(sum(set%vars(inet)%stderr**2)), ' '//units// &
      ' (independent errors assumed)'
    if (ih > 0) then
      k = minloc(set%vars(ih)%mean, 1)
      write (output_unit, '(2x,a24,f12.4,a,f10.4,a)') 'strongest cooling', set%vars(ih)%mean(k), &
        ' +- ', set%vars(ih)%stderr(k), ' K/day (layer '//str(k)//')'
      k = maxloc(set%vars(ih)%mean, 1)
      write (output_unit, '(2x,a24,f12.4,a,f10.4,a)') 'strongest heating', set%vars(ih)%mean(k), &
        ' +- ', set%vars(ih)%stderr(k), ' K/day (layer '//str(k)//')'
    end if
  end subroutine log_thermal

  !> The domain-mean radiances, one line per direction and level, leaving out exact zeros (no
  !> light enters at the top; a black surface reflects none); at most MAX_LINES lines.
  subroutine log_radiances(set)
    type(result_set_t), intent(in) :: set
    integer, parameter :: MAX_LINES = 12
    integer :: iv, iphi, imu, idir, ilev, nd, nl, j, k, lines
    real(dp) :: mu, phi, z
    iv = find_var(set, 'radiance')
    iphi = find_var(set, 'direction_phi')
    imu = find_var(set, 'direction_mu')
    idir = find_dim(set, 'direction')
    ilev = find_dim(set, 'rad_level')
    if (iv == 0 .or. iphi == 0 .or. imu == 0 .or. idir == 0 .or. ilev == 0) return
    nd = set%dims(idir)%size
    nl = set%dims(ilev)%size
    lines = 0
    do j = 1, nd
      mu = set%vars(imu)%mean(j)
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

end module kumo_output
