! SPDX-License-Identifier: BSD-3-Clause
!> A broadband shortwave run from a namelist (&kumo_spectral) against the discrete-ordinates
!> reference of tests/data/broadband/sw_gpoint_reference.txt (column us1976: the U.S. Standard
!> Atmosphere 1976 on 35 layers, Manabe-Wetherald water vapour, RCEMIP ozone, sun at 60 degrees,
!> Lambert surface 0.2, TSI 1361 W m-2; per-g-point fluxes of PythonicDISORT summed over the
!> g-points): broadband up, diffuse down and direct down fluxes at every level (W m-2) and the
!> heating rate of every layer (K/day) within 4 standard errors plus the reference's own error
!> (the difference of its two stream numbers). And bad inputs of the group: a missing
!> k-distribution file, a longwave file, a negative TSI, no water vapour, a standard atmosphere
!> together with a sounding, a solar flux or wavelength of &kumo_source besides the
!> k-distribution's, a sounding whose pressure does not fall, too few water-vapour values.
!>
!> Arguments: the folder of the k-distribution files (KUMO_RRTMGP_DIR) and the reference file.
!> The namelists are written into the working directory.
module test_broadband_run_suite
  use kumo_kinds, only: dp
  use kumo_error, only: str
  use kumo_config, only: config_t, read_config
  use kumo_results, only: result_set_t
  use kumo_driver, only: simulate, run_summary_t
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_sigma, check_error_words
  implicit none
  private
  public :: collect_broadband_run, rrtmgp_dir, reference_file

  character(len=:), allocatable :: rrtmgp_dir, reference_file
  integer, parameter :: NZ = 35

contains

  function collect_broadband_run() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('us1976_namelist_vs_disort', test_us1976), &
             new_unittest('bad_inputs', test_bad_inputs)]
  end function collect_broadband_run

  !> The us1976 case of the reference file: water vapour per layer, broadband fluxes (0:nz, 5)
  !> and heating rates (nz, 2).
  subroutine read_us1976(h2o, bb, heat, error)
    character(len=32), intent(out) :: h2o(NZ)
    real(dp), intent(out) :: bb(0:NZ, 5), heat(NZ, 2)
    type(error_t), allocatable, intent(out) :: error
    character(len=8192) :: line
    character(len=32) :: key, w(6)
    integer :: u, ios, idx
    logical :: on
    on = .false.
    open (newunit=u, file=reference_file, status='old', action='read', iostat=ios)
    call check(error, ios == 0, 'cannot open '//reference_file)
    if (allocated(error)) return
    do
      read (u, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (len_trim(line) == 0 .or. line(1:1) == '#') cycle
      read (line, *) key
      if (trim(key) == 'case') then
        read (line, *) key, w(1)
        on = trim(w(1)) == 'us1976'
      end if
      if (.not. on) cycle
      select case (trim(key))
      case ('layer')
        read (line, *) key, idx, w(1:4)
        h2o(idx) = w(4)
      case ('broadband')
        read (line, *) key, idx, bb(idx, :)
      case ('heating')
        read (line, *) key, idx, heat(idx, :)
      case ('end')
        exit
      end select
    end do
    close (u)
  end subroutine read_us1976

  !> Write a namelist of the us1976 column with `spectral_lines` added to &kumo_spectral and
  !> `other_groups` to &kumo_source.
  subroutine write_nml(path, h2o, spectral_lines, other_groups, n_batches)
    character(len=*), intent(in) :: path, spectral_lines, other_groups
    character(len=32), intent(in) :: h2o(NZ)
    integer, intent(in) :: n_batches
    integer :: u, k
    real(dp) :: z(0:NZ)
    do k = 0, 19
      z(k) = 1000.0_dp*k
    end do
    do k = 20, NZ
      z(k) = 20000.0_dp + 4000.0_dp*(k - 20)
    end do
    open (newunit=u, file=path, status='replace', action='write')
    write (u, '(a)') '&kumo_control', '  n_photons_per_batch = 20000', &
      '  n_batches = '//str(n_batches), '  seed = 20261127', '  verbose = 0', '/'
    write (u, '(a)') '&kumo_atmosphere', '  nz = '//str(NZ), '  ext1d = '//str(NZ)//'*0.0', &
      '  ssa1d = '//str(NZ)//'*0.0'
    write (u, '(a)', advance='no') '  z_levels = '
    write (u, '(*(f0.1, :, ", "))') z
    write (u, '(a)') '/', '&kumo_surface', '  albedo = 0.2', '/', '&kumo_source', &
      '  sza_deg = 60.0', other_groups, '/'
    write (u, '(a)') '&kumo_spectral', '  kdist_file = '''//rrtmgp_dir//'/rrtmgp-gas-sw-g112.nc''', &
      '  profile = ''us1976''', '  tsi = 1361.0'
    write (u, '(a)', advance='no') '  h2o_vmr = '
    write (u, '(*(a, :, ", "))') (trim(h2o(k)), k=1, NZ)
    write (u, '(a)') spectral_lines, '/'
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

  subroutine test_us1976(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=32) :: h2o(NZ)
    real(dp) :: bb(0:NZ, 5), heat(NZ, 2), worst, dev
    type(config_t) :: cfg
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    type(error_t), allocatable :: err
    integer :: iu, idif, idir, ih, k
    character(len=:), allocatable :: where
    call read_us1976(h2o, bb, heat, error)
    if (allocated(error)) return
    call write_nml('broadband_us1976.nml', h2o, '  floor_share = 0.2', '', 100)
    call read_config('broadband_us1976.nml', cfg, err)
    call check(error, .not. allocated(err), 'read_config')
    if (allocated(error)) return
    call simulate(cfg, set, summary, err)
    if (allocated(err)) call check(error, .false., 'simulate: '//err%message// &
                                   ' (scripts/fetch-rrtmgp.sh fetches the k-distributions)')
    if (allocated(error)) return
    iu = var(set, 'flux_up_wm2', error)
    idif = var(set, 'flux_down_diffuse_wm2', error)
    idir = var(set, 'flux_down_direct_wm2', error)
    ih = var(set, 'heating_rate_layer', error)
    if (allocated(error)) return
    worst = 0
    where = ''
    do k = 0, NZ
      call cmp(set%vars(iu)%mean(k + 1), set%vars(iu)%stderr(k + 1), bb(k, 1), bb(k, 4), &
               'up flux at level '//str(k))
      call cmp(set%vars(idif)%mean(k + 1), set%vars(idif)%stderr(k + 1), bb(k, 2), bb(k, 5), &
               'diffuse down flux at level '//str(k))
      call cmp(set%vars(idir)%mean(k + 1), set%vars(idir)%stderr(k + 1), bb(k, 3), 0.0_dp, &
               'direct flux at level '//str(k))
    end do
    do k = 1, NZ
      call cmp(set%vars(ih)%mean(k), set%vars(ih)%stderr(k), heat(k, 1), heat(k, 2), &
               'heating rate of layer '//str(k))
    end do
    write (*, '(a, f0.3, a, f0.3, a, f0.3, a)') '    TOA up ', set%vars(iu)%mean(NZ + 1), ' +- ', &
      set%vars(iu)%stderr(NZ + 1), ' W m-2 (DISORT ', bb(NZ, 1), ')'
    write (*, '(a, f0.3, a, f0.3, a, f0.3, a)') '    surface-layer heating ', set%vars(ih)%mean(1), &
      ' +- ', set%vars(ih)%stderr(1), ' K/day (DISORT ', heat(1, 1), ')'
    write (*, '(a, f0.2, a, f0.3, a)') '    largest deviation ', worst, ' sigma ('//where//'); ', &
      summary%wall_time, ' s'
  contains
    subroutine cmp(m, s, r, re, label)
      real(dp), intent(in) :: m, s, r, re
      character(len=*), intent(in) :: label
      call check_sigma(error, m, r, s, 4.0_dp, label, abs_floor=re + 1.0e-9_dp*1361.0_dp)
      if (s > 0) then
        dev = abs(m - r)/s
        if (dev > worst) then
          worst = dev
          where = label
        end if
      end if
    end subroutine cmp
  end subroutine test_us1976

  subroutine test_bad_inputs(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=32) :: h2o(NZ)
    real(dp) :: bb(0:NZ, 5), heat(NZ, 2)
    call read_us1976(h2o, bb, heat, error)
    if (allocated(error)) return
    call expect('  kdist_file = ''no-such-kdist.nc''', '', &
                ['no-such-kdist.nc', '&kumo_spectral  '])
    call expect('  kdist_file = '''//rrtmgp_dir//'/rrtmgp-gas-lw-g128.nc''', '', &
                ['longwave', 'lw-g128 '])
    call expect('  tsi = -5.0', '', [character(len=32) :: 'tsi = -5', 'must be'])
    call expect('  floor_share = 1.0', '', [character(len=32) :: 'floor_share = 1', '< 1          '])
    call expect('  p_levels = 36*90000.0', '', [character(len=32) :: 'profile', 'sounding'])
    call expect('  profile = ''mars''', '', [character(len=32) :: 'mars  ', 'us1976'])
    call expect('', '  solar_flux = 1000.0', [character(len=32) :: 'solar_flux', 'tsi       '])
    call expect('', '  wavelength_um = 0.5', [character(len=32) :: 'wavelength_um', 'broadband'])
    call expect('  profile = '''''//new_line('a')//'  p_levels = 36*90000.0'//new_line('a')// &
                '  t_levels = 36*250.0', '', [character(len=32) :: 'p_levels(2) = 90000', 'pressure falls     '])
    call expect('  h2o_vmr(36) = 0.01', '', [character(len=32) :: 'h2o_vmr', 'needs 35', '36 given'])
  contains
    !> The us1976 namelist with `lines` added to &kumo_spectral and `groups` to &kumo_source fails
    !> (read_config or simulate) with a message holding `words`.
    subroutine expect(lines, groups, words)
      character(len=*), intent(in) :: lines, groups, words(:)
      type(config_t) :: cfg
      type(result_set_t) :: set
      type(run_summary_t) :: summary
      type(error_t), allocatable :: err
      if (allocated(error)) return
      call write_nml('broadband_bad.nml', h2o, lines, groups, 2)
      call read_config('broadband_bad.nml', cfg, err)
      if (.not. allocated(err)) call simulate(cfg, set, summary, err)
      call check_error_words(error, err, words)
      if (allocated(error)) call check(error, .false., '(case: '//lines//groups//')')
    end subroutine expect
  end subroutine test_bad_inputs

end module test_broadband_run_suite

program test_broadband_run
  use test_broadband_run_suite, only: collect_broadband_run, rrtmgp_dir, reference_file
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
  call par_init()
  call run_unittests('broadband run', collect_broadband_run(), n_failed)
  call par_finalize()
  if (n_failed > 0) error stop 1
end program test_broadband_run
