! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_units and kumo_les_netcdf: LES / CRM cloud fields from netCDF.
!>
!> The test writes its own small netCDF files (in the current directory; CTest runs it in the
!> build tree) in several conventions, reads them back and compares the converted values with
!> values computed here from the numbers written: unit relations (1 g = 1e-3 kg, 1 km = 1000 m,
!> 1 hPa = 100 Pa, 1 cm-3 = 1e6 m-3), the ideal-gas density of dry air and, for droplet number,
!> the volume of a sphere. Files with one defect each check that the error names the variable,
!> the index or the rule.
module test_kumo_les_netcdf
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use netcdf, only: nf90_create, nf90_close, nf90_def_dim, nf90_def_var, nf90_put_att, &
                    nf90_put_var, nf90_redef, nf90_enddef, nf90_inquire_dimension, &
                    nf90_strerror, NF90_NOERR, NF90_CLOBBER, NF90_FLOAT, NF90_DOUBLE
  use kumo_kinds, only: wp, dp, sp, vp
  use kumo_error, only: error_t, str
  use kumo_units, only: unit_factor, normalize_units, QTY_WATER_CONTENT, QTY_LENGTH, QTY_RADIUS, &
                        QTY_NUMBER, QTY_TEMPERATURE, QTY_PRESSURE, QTY_AIR_DENSITY
  use kumo_les_netcdf, only: les_names_t, les_field_t, read_les_field, K_CONTINENTAL
  use kumo_testing, only: unittest_t, new_unittest, check, check_close
  implicit none
  private
  public :: collect_les_netcdf

  !> Grid of every file: sizes all different, so a transposition shows.
  integer, parameter :: NX = 3, NY = 2, NZ = 4, NT = 3
  !> Values stored as float32 are rounded once, by at most 2^-24 relative (6e-8); the readers'
  !> unit factors add a few double-precision roundings. 1e-6 relative is well above both and far
  !> below any wrong factor (>= 1e-3 away) or a neighbouring cell's value (>= 1e-3 relative).
  real(dp), parameter :: TOL_FLOAT = 1.0e-6_dp
  !> Doubles: only the readers' multiplications (a few eps).
  real(dp), parameter :: TOL_DOUBLE = 1.0e-12_dp
  !> Fields are stored in kumo's voxel precision (single): one rounding, half an ulp.
  real(dp), parameter :: TOL_STORED = 1.2e-7_dp
  !> Gas constant of dry air from the U.S. Standard Atmosphere 1976 constants, R* = 8.31432
  !> J mol-1 K-1 and M0 = 28.9644 g mol-1 (287.053); the reader uses CODATA 2018 R and Picard et
  !> al. (2008) M_a (287.047), 1.9e-5 relative away.
  real(dp), parameter :: R_D_TEST = 8.31432_dp/28.9644e-3_dp
  real(dp), parameter :: PI_TEST = 3.14159265358979323846_dp
  character(len=*), parameter :: MICRO = char(194)//char(181)     ! U+00B5, UTF-8
  character(len=*), parameter :: GREEK_MU = char(206)//char(188)  ! U+03BC, UTF-8

contains

  function collect_les_netcdf() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('units_spellings', test_units_spellings), &
             new_unittest('units_rejected', test_units_rejected), &
             new_unittest('gm3_um_centres_km', test_gm3_um_centres_km), &
             new_unittest('kgm3_m_edges_time_step_2', test_kgm3_edges_time), &
             new_unittest('mixing_ratio_with_p_and_t', test_mixing_ratio_pt), &
             new_unittest('p_and_t_unread_when_unneeded', test_pt_unread_when_unneeded), &
             new_unittest('droplet_number_gives_reff', test_droplet_number), &
             new_unittest('number_per_kg_with_density', test_number_per_kg_density), &
             new_unittest('stretched_z_centres', test_stretched_z), &
             new_unittest('error_missing_units', test_err_missing_units), &
             new_unittest('error_unknown_units', test_err_unknown_units), &
             new_unittest('error_negative_lwc', test_err_negative), &
             new_unittest('error_nan', test_err_nan), &
             new_unittest('error_fill_value', test_err_fill), &
             new_unittest('error_non_uniform_x', test_err_non_uniform_x), &
             new_unittest('error_dimension_order', test_err_dim_order), &
             new_unittest('error_missing_variable', test_err_missing_var), &
             new_unittest('error_time_index', test_err_time_index), &
             new_unittest('error_mixing_ratio_without_density', test_err_no_density), &
             new_unittest('error_ice_without_radius', test_err_ice_no_radius), &
             new_unittest('gas_state_t_p_mixing_ratio', test_state_t_p_r), &
             new_unittest('gas_state_theta_specific_humidity', test_state_theta_q), &
             new_unittest('gas_state_absent', test_state_absent)]
  end function collect_les_netcdf

  ! ------------------------------------------------------------------------------------------------
  ! Units
  ! ------------------------------------------------------------------------------------------------

  !> Broadband gas state (grid-only read with state_profile): a 3-D temperature in K, a pressure
  !> profile in hPa and a water vapour mixing ratio in g/kg (no standard_name: taken as a mass
  !> mixing ratio r). Per layer: the mean temperature, 100 x the hPa values, and the mean of
  !> r M_d/M_w with the molar masses of dry air and water, 28.9644 and 18.0153 g/mol (U.S.
  !> Standard Atmosphere 1976; CRC Handbook).
  subroutine test_state_t_p_r(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_state1.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, d(3), ix, iy, iz
    real(dp) :: t(NX, NY, NZ), r(NX, NY, NZ), p(NZ)
    do iz = 1, NZ
      p(iz) = 1000.0_dp - 20.0_dp*iz
      do iy = 1, NY
        do ix = 1, NX
          t(ix, iy, iz) = 290.0_dp + ix - 0.5_dp*iy - 2.0_dp*iz
          r(ix, iy, iz) = 10.0_dp - 0.5_dp*ix + 0.25_dp*iy - iz          ! g/kg
        end do
      end do
    end do
    call basic_grid(PATH, ncid, d, error)
    call nc_var(ncid, 'lwc', d, flat(lwc_ref(1)), &
                'g m-3', NF90_DOUBLE, error)
    call nc_var(ncid, 'temperature', d, flat(t), 'K', NF90_DOUBLE, error)
    call nc_var(ncid, 'pres', [d(3)], p, 'hPa', NF90_DOUBLE, error)
    call nc_var(ncid, 'qv', d, flat(r), 'g/kg', NF90_DOUBLE, error)
    call nc_close(ncid, error)
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err, grid_only=.true., state_profile=.true.)
    call no_error(error, err)
    if (allocated(error)) return
    call check(error, allocated(fld%t_profile) .and. allocated(fld%pressure_profile) .and. &
               allocated(fld%h2o_profile), 'a profile of the state is missing')
    if (allocated(error)) return
    do iz = 1, NZ
      call check_close(error, fld%t_profile(iz), sum(t(:, :, iz))/(NX*NY), rel_tol=TOL_DOUBLE, label= &
                       'mean temperature of layer '//str(iz))
      call check_close(error, fld%pressure_profile(iz), 100.0_dp*p(iz), rel_tol=TOL_DOUBLE, label= &
                       'pressure of layer '//str(iz))
      call check_close(error, fld%h2o_profile(iz), &
                       1.0e-3_dp*sum(r(:, :, iz))/(NX*NY)*28.9644_dp/18.0153_dp, rel_tol=TOL_DOUBLE, label= &
                       'water vapour of layer '//str(iz))
    end do
    call check(error, index(fld%notes, 'mass mixing ratio') > 0, &
               'notes do not say the vapour is taken as a mixing ratio: '//fld%notes)
    call remove_file(PATH)
  end subroutine test_state_t_p_r

  !> A potential temperature with a 3-D pressure in Pa, and a specific humidity ('hus', kg/kg):
  !> T = theta (p/1000 hPa)^(2/7) voxel by voxel, then the layer mean; vmr = mean of
  !> q/(1 - q) M_d/M_w.
  subroutine test_state_theta_q(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_state2.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, d(3), ix, iy, iz
    real(dp) :: th(NX, NY, NZ), q(NX, NY, NZ), p(NX, NY, NZ), tm, qm
    do iz = 1, NZ
      do iy = 1, NY
        do ix = 1, NX
          th(ix, iy, iz) = 295.0_dp + 0.3_dp*ix + 0.2_dp*iy + iz
          p(ix, iy, iz) = 95000.0_dp - 1000.0_dp*iz + 10.0_dp*ix - 7.0_dp*iy
          q(ix, iy, iz) = 0.015_dp - 0.001_dp*iz + 1.0e-4_dp*ix
        end do
      end do
    end do
    call basic_grid(PATH, ncid, d, error)
    call nc_var(ncid, 'lwc', d, flat(lwc_ref(1)), &
                'g m-3', NF90_DOUBLE, error)
    call nc_var(ncid, 'theta', d, flat(th), 'K', NF90_DOUBLE, error)
    call nc_var(ncid, 'p', d, flat(p), 'Pa', NF90_DOUBLE, error)
    call nc_var(ncid, 'hus', d, flat(q), 'kg kg-1', NF90_DOUBLE, error)
    call nc_close(ncid, error)
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err, grid_only=.true., state_profile=.true.)
    call no_error(error, err)
    if (allocated(error)) return
    call check(error, allocated(fld%t_profile) .and. allocated(fld%h2o_profile), &
               'temperature or water vapour missing')
    if (allocated(error)) return
    do iz = 1, NZ
      tm = sum(th(:, :, iz)*(p(:, :, iz)/1.0e5_dp)**(2.0_dp/7.0_dp))/(NX*NY)
      qm = sum(q(:, :, iz)/(1.0_dp - q(:, :, iz)))/(NX*NY)*28.9644_dp/18.0153_dp
      call check_close(error, fld%t_profile(iz), tm, rel_tol=TOL_DOUBLE, label='temperature of layer '//str(iz))
      call check_close(error, fld%pressure_profile(iz), sum(p(:, :, iz))/(NX*NY), rel_tol=TOL_DOUBLE, &
                       label='pressure of layer '//str(iz))
      call check_close(error, fld%h2o_profile(iz), qm, rel_tol=TOL_DOUBLE, label='water vapour of layer '//str(iz))
    end do
    call check(error, index(fld%notes, 'specific humidity') > 0 .and. index(fld%notes, 'theta') > 0, &
               'notes do not say how the state was obtained: '//fld%notes)
    call remove_file(PATH)
  end subroutine test_state_theta_q

  !> A file without temperature, pressure or water vapour: nothing allocated, and the notes
  !> say what was tried.
  subroutine test_state_absent(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_state3.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    call write_basic(PATH, error)
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err, grid_only=.true., state_profile=.true.)
    call no_error(error, err)
    if (allocated(error)) return
    call check(error, .not. (allocated(fld%t_profile) .or. allocated(fld%pressure_profile) .or. &
                             allocated(fld%h2o_profile)), 'a state profile from nothing')
    call check(error, index(fld%notes, 'no temperature') > 0 .and. index(fld%notes, 'no pressure') > 0 &
               .and. index(fld%notes, 'no water vapour (tried qv') > 0, 'notes: '//fld%notes)
    call remove_file(PATH)
  end subroutine test_state_absent

  subroutine test_units_spellings(error)
    type(error_t), allocatable, intent(out) :: error
    ! Water content to g m-3 (1 kg = 1000 g); mixing ratios per kg of air.
    call expect('kg m-3', QTY_WATER_CONTENT, 1.0e3_dp, .false.)
    call expect('kg/m3', QTY_WATER_CONTENT, 1.0e3_dp, .false.)
    call expect('kg/m^3', QTY_WATER_CONTENT, 1.0e3_dp, .false.)
    call expect('kg m^-3', QTY_WATER_CONTENT, 1.0e3_dp, .false.)
    call expect('kg m**-3', QTY_WATER_CONTENT, 1.0e3_dp, .false.)
    call expect('kg.m-3', QTY_WATER_CONTENT, 1.0e3_dp, .false.)
    call expect('g m-3', QTY_WATER_CONTENT, 1.0_dp, .false.)
    call expect('g/m3', QTY_WATER_CONTENT, 1.0_dp, .false.)
    call expect(' g  m-3 ', QTY_WATER_CONTENT, 1.0_dp, .false.)
    call expect('kg kg-1', QTY_WATER_CONTENT, 1.0e3_dp, .true.)
    call expect('kg/kg', QTY_WATER_CONTENT, 1.0e3_dp, .true.)
    call expect('g kg-1', QTY_WATER_CONTENT, 1.0_dp, .true.)
    call expect('g/kg', QTY_WATER_CONTENT, 1.0_dp, .true.)
    ! Lengths to m, radii to um.
    call expect('m', QTY_LENGTH, 1.0_dp, .false.)
    call expect('km', QTY_LENGTH, 1.0e3_dp, .false.)
    call expect('um', QTY_LENGTH, 1.0e-6_dp, .false.)
    call expect(MICRO//'m', QTY_LENGTH, 1.0e-6_dp, .false.)
    call expect(GREEK_MU//'m', QTY_LENGTH, 1.0e-6_dp, .false.)
    call expect('microns', QTY_LENGTH, 1.0e-6_dp, .false.)
    call expect('m', QTY_RADIUS, 1.0e6_dp, .false.)
    call expect('um', QTY_RADIUS, 1.0_dp, .false.)
    call expect(MICRO//'m', QTY_RADIUS, 1.0_dp, .false.)
    call expect(GREEK_MU//'m', QTY_RADIUS, 1.0_dp, .false.)
    call expect('micron', QTY_RADIUS, 1.0_dp, .false.)
    call expect('micrometers', QTY_RADIUS, 1.0_dp, .false.)
    ! Number: 1 cm-3 = 1e6 m-3; per kg of air.
    call expect('m-3', QTY_NUMBER, 1.0_dp, .false.)
    call expect('cm-3', QTY_NUMBER, 1.0e6_dp, .false.)
    call expect('cm^-3', QTY_NUMBER, 1.0e6_dp, .false.)
    call expect('1/cm3', QTY_NUMBER, 1.0e6_dp, .false.)
    call expect('/m3', QTY_NUMBER, 1.0_dp, .false.)
    call expect('kg-1', QTY_NUMBER, 1.0_dp, .true.)
    call expect('1/kg', QTY_NUMBER, 1.0_dp, .true.)
    ! Temperature, pressure (1 hPa = 1 mb = 100 Pa), air density.
    call expect('K', QTY_TEMPERATURE, 1.0_dp, .false.)
    call expect('Pa', QTY_PRESSURE, 1.0_dp, .false.)
    call expect('hPa', QTY_PRESSURE, 1.0e2_dp, .false.)
    call expect('mb', QTY_PRESSURE, 1.0e2_dp, .false.)
    call expect('kg m-3', QTY_AIR_DENSITY, 1.0_dp, .false.)
    call expect('kg/m3', QTY_AIR_DENSITY, 1.0_dp, .false.)
    call check(error, normalize_units('kg/m^3') == 'kg m-3', 'normalize kg/m^3: "'// &
               normalize_units('kg/m^3')//'"')
  contains
    subroutine expect(units, quantity, factor, per_air)
      character(len=*), intent(in) :: units
      integer, intent(in) :: quantity
      real(dp), intent(in) :: factor
      logical, intent(in) :: per_air
      type(error_t), allocatable :: err
      real(wp) :: f
      logical :: p
      if (allocated(error)) return
      call unit_factor(units, quantity, f, p, err)
      if (allocated(err)) then
        call check(error, .false., '"'//units//'" rejected: '//err%message)
        return
      end if
      call check_close(error, f, factor, rel_tol=TOL_DOUBLE, label='factor of "'//units//'"')
      call check(error, p .eqv. per_air, 'per_air_mass of "'//units//'"')
    end subroutine expect
  end subroutine test_units_spellings

  subroutine test_units_rejected(error)
    type(error_t), allocatable, intent(out) :: error
    call reject('', QTY_WATER_CONTENT, 'blank')
    call reject('g/cm3', QTY_WATER_CONTENT, 'kg m-3, g kg-1, kg kg-1')
    call reject('kg m-3', QTY_LENGTH, 'accepted units for length')
    call reject('mm', QTY_RADIUS, 'um, micron')
    call reject('degC', QTY_TEMPERATURE, 'accepted units for temperature (kumo unit K): K')
    call reject('kg/m/s', QTY_WATER_CONTENT, 'not accepted')
    call reject('1', QTY_WATER_CONTENT, 'not accepted')
    call reject('kg kg-1', QTY_AIR_DENSITY, 'not accepted')
    call reject('atm', QTY_PRESSURE, 'Pa, hPa, mb')
  contains
    subroutine reject(units, quantity, expected)
      character(len=*), intent(in) :: units, expected
      integer, intent(in) :: quantity
      type(error_t), allocatable :: err
      real(wp) :: f
      logical :: p
      if (allocated(error)) return
      call unit_factor(units, quantity, f, p, err)
      call check(error, allocated(err), '"'//units//'" accepted')
      if (allocated(error)) return
      call check(error, index(err%message, expected) > 0, 'message for "'//units// &
                 '" lacks "'//expected//'": '//err%message)
    end subroutine reject
  end subroutine test_units_rejected

  ! ------------------------------------------------------------------------------------------------
  ! Conventions read correctly
  ! ------------------------------------------------------------------------------------------------

  !> g m-3, radii in micrometres (micro sign), centres in km (float), ice as a second species.
  subroutine test_gm3_um_centres_km(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_a.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err

    call write_basic(PATH, error)
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err)
    call no_error(error, err)
    if (allocated(error)) return
    call check(error, fld%nx == NX .and. fld%ny == NY .and. fld%nz == NZ, 'grid sizes')
    ! x centres 0.05, 0.15, 0.25 km -> 100 m; y 0.025, 0.075 km -> 50 m; z 0.1 .. 0.7 km.
    call check_close(error, fld%dx, 100.0_dp, rel_tol=TOL_FLOAT, label='dx')
    call check_close(error, fld%dy, 50.0_dp, rel_tol=TOL_FLOAT, label='dy')
    call check_array(error, fld%z_edges, [0.0_dp, 200.0_dp, 400.0_dp, 600.0_dp, 800.0_dp], &
                     TOL_FLOAT, 'z_edges', abs_tol=1.0e-4_dp)
    call check_field(error, fld%lwc, lwc_ref(1), 1.0_dp, TOL_FLOAT, 'lwc')
    call check_field(error, fld%reff, reff_ref(), 1.0_dp, TOL_FLOAT, 'reff')
    call check(error, fld%has_ice, 'ice not found')
    if (allocated(error)) return
    call check_field(error, fld%iwc, 0.1_dp*lwc_ref(1), 1.0_dp, TOL_FLOAT, 'iwc')
    call check_field(error, fld%reff_ice, 3.0_dp*reff_ref(), 1.0_dp, TOL_FLOAT, 'reff_ice')
    call check(error, .not. fld%reff_computed, 'reff_computed set for a file with reff')
    call check(error, .not. (fld%has_temperature .or. fld%has_pressure), 'T or p invented')
    call check(error, index(fld%notes, 'z edges midway between centres "z"') > 0, &
               'notes lack the origin of the z edges: '//fld%notes)
    call check(error, trim(fld%used%lwc) == 'lwc' .and. trim(fld%used%reff) == 're' .and. &
               trim(fld%used%iwc) == 'iwc' .and. trim(fld%used%reff_ice) == 'rei', &
               'names used: '//trim(fld%used%lwc)//' '//trim(fld%used%reff))
    ! Switching ice off by name.
    names%iwc = 'none'
    call read_les_field(PATH, names, -1, fld, err)
    call no_error(error, err)
    call check(error, .not. fld%has_ice .and. .not. allocated(fld%iwc), 'iwc = none ignored')
    call remove_file(PATH)
  end subroutine test_gm3_um_centres_km

  !> kg m-3, radius in m, edges in m (stretched z), time dimension of 3, step 2 chosen, an ice
  !> mixing ratio, and temperature and pressure profiles over (time, z) for its air density.
  subroutine test_kgm3_edges_time(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_b.nc'
    real(dp), parameter :: Z_EDGES(NZ + 1) = [0.0_dp, 100.0_dp, 250.0_dp, 500.0_dp, 1000.0_dp]
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, dx_, dy_, dz_, dt_, dxe, dye, dze, it, k
    real(dp) :: lwc4(NX, NY, NZ, NT), reff4(NX, NY, NZ, NT), t2(NZ, NT), p2(NZ, NT)
    real(dp) :: iwc_ref(NX, NY, NZ)

    do it = 1, NT                  ! each step different, so the wrong step shows
      lwc4(:, :, :, it) = 1.0e-3_dp*it*lwc_ref(1)     ! kg m-3
      reff4(:, :, :, it) = 1.0e-6_dp*(reff_ref() + it) ! m
      do k = 1, NZ
        t2(k, it) = 290.0_dp - 6.5e-3_dp*(k*100.0_dp) + it
        p2(k, it) = 1.0e5_dp - 1.1e3_dp*k - 10.0_dp*it               ! Pa
      end do
    end do
    ! ice (qi in kg kg-1 = 2e-4 kg kg-1 times the liquid pattern) times rho = p / (R_d T) at
    ! step 2, in g m-3
    do k = 1, NZ
      iwc_ref(:, :, k) = 1.0e3_dp*0.2_dp*lwc4(:, :, k, 2)*p2(k, 2)/(R_D_TEST*t2(k, 2))
    end do
    call nc_create(PATH, ncid, error)
    call nc_dim(ncid, 'time', NT, dt_, error)
    call nc_dim(ncid, 'z', NZ, dz_, error)
    call nc_dim(ncid, 'y', NY, dy_, error)
    call nc_dim(ncid, 'x', NX, dx_, error)
    call nc_dim(ncid, 'x_edges', NX + 1, dxe, error)
    call nc_dim(ncid, 'y_edges', NY + 1, dye, error)
    call nc_dim(ncid, 'z_edges', NZ + 1, dze, error)
    call nc_var(ncid, 'x_edges', [dxe], [0.0_dp, 100.0_dp, 200.0_dp, 300.0_dp], 'm', &
                NF90_DOUBLE, error)
    call nc_var(ncid, 'y_edges', [dye], [1000.0_dp, 1050.0_dp, 1100.0_dp], 'm', NF90_DOUBLE, &
                error)
    call nc_var(ncid, 'z_edges', [dze], Z_EDGES, 'm', NF90_DOUBLE, error)
    call nc_var(ncid, 'LWC', [dx_, dy_, dz_, dt_], reshape(lwc4, [size(lwc4)]), 'kg m**-3', &
                NF90_DOUBLE, error)
    call nc_var(ncid, 'reff', [dx_, dy_, dz_, dt_], reshape(reff4, [size(reff4)]), 'm', &
                NF90_DOUBLE, error)
    call nc_var(ncid, 'temperature', [dz_, dt_], reshape(t2, [size(t2)]), 'K', NF90_DOUBLE, &
                error)
    call nc_var(ncid, 'pressure', [dz_, dt_], reshape(p2, [size(p2)]), 'Pa', NF90_DOUBLE, error)
    call nc_var(ncid, 'qi', [dx_, dy_, dz_, dt_], reshape(0.2_dp*lwc4, [size(lwc4)]), &
                'kg kg-1', NF90_DOUBLE, error)
    call nc_var(ncid, 'rei', [dx_, dy_, dz_, dt_], reshape(reff4, [size(reff4)]), 'm', &
                NF90_DOUBLE, error)
    call nc_close(ncid, error)
    if (allocated(error)) return

    call read_les_field(PATH, names, 2, fld, err)
    call no_error(error, err)
    if (allocated(error)) return
    call check_close(error, fld%dx, 100.0_dp, rel_tol=TOL_DOUBLE, label='dx')
    call check_close(error, fld%dy, 50.0_dp, rel_tol=TOL_DOUBLE, label='dy')
    call check_array(error, fld%z_edges, Z_EDGES, TOL_DOUBLE, 'z_edges')
    ! kg m-3 -> g m-3 is times 1000; step 2 of the values written above.
    call check_field(error, fld%lwc, lwc4(:, :, :, 2), 1.0e3_dp, TOL_DOUBLE, 'lwc')
    call check_field(error, fld%reff, reff4(:, :, :, 2), 1.0e6_dp, TOL_DOUBLE, 'reff')
    call check(error, fld%has_temperature, 'temperature profile not read')
    if (allocated(error)) return
    call check(error, all(shape(fld%temperature) == [1, 1, NZ]), 'profile shape')
    if (allocated(error)) return
    call check_array(error, real(fld%temperature(1, 1, :), dp), t2(:, 2), TOL_STORED, &
                     'temperature')
    call check(error, fld%has_pressure, 'pressure profile not read')
    if (allocated(error)) return
    call check_array(error, real(fld%pressure(1, 1, :), dp), p2(:, 2), TOL_STORED, 'pressure')
    call check(error, fld%has_ice, 'ice not found')
    if (allocated(error)) return
    ! 4e-5: the two R_d values (1.9e-5 apart) and float storage, as in test_mixing_ratio_pt
    call check_field(error, fld%iwc, iwc_ref, 1.0_dp, 4.0e-5_dp, 'iwc')
    call remove_file(PATH)
  end subroutine test_kgm3_edges_time

  !> A model's 3-D temperature and pressure next to water contents per volume are not needed
  !> (no mixing ratio): they are not read, so they cost no memory; the water is read as usual.
  subroutine test_pt_unread_when_unneeded(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_pt.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, d(3)
    real(dp) :: t(NX, NY, NZ), p(NX, NY, NZ)
    t = 280.0_dp
    p = 9.0e4_dp
    call basic_grid(PATH, ncid, d, error)
    call nc_var(ncid, 'lwc', d, flat(lwc_ref(1)), 'g m-3', NF90_FLOAT, error)
    call nc_var(ncid, 'reff', d, flat(reff_ref()), 'um', NF90_FLOAT, error)
    call nc_var(ncid, 'TABS', d, flat(t), 'K', NF90_FLOAT, error)
    call nc_var(ncid, 'p', d, flat(p), 'Pa', NF90_FLOAT, error)
    call nc_close(ncid, error)
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err)
    call no_error(error, err)
    if (allocated(error)) return
    call check_field(error, fld%lwc, lwc_ref(1), 1.0_dp, TOL_FLOAT, 'lwc')
    call check(error, .not. (fld%has_temperature .or. fld%has_pressure .or. &
                             allocated(fld%temperature) .or. allocated(fld%pressure)), &
               'temperature or pressure read although nothing needs them')
    call check(error, len_trim(fld%used%temperature) == 0 .and. &
               len_trim(fld%used%pressure) == 0, 'T or p reported as used')
    call remove_file(PATH)
  end subroutine test_pt_unread_when_unneeded

  !> Mixing ratios (kg kg-1 liquid, g/kg ice) with a pressure profile in hPa and 3-D T.
  subroutine test_mixing_ratio_pt(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_c.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, d(3), ix, iy, iz
    real(dp) :: q(NX, NY, NZ), t(NX, NY, NZ), p(NZ), rho(NX, NY, NZ)

    do iz = 1, NZ
      p(iz) = 1000.0_dp - 20.0_dp*iz                       ! hPa
      do iy = 1, NY
        do ix = 1, NX
          t(ix, iy, iz) = 285.0_dp + ix - 0.5_dp*iy - 2.0_dp*iz
          rho(ix, iy, iz) = 100.0_dp*p(iz)/(R_D_TEST*t(ix, iy, iz))   ! kg m-3, ideal gas
        end do
      end do
    end do
    q = 1.0e-3_dp*lwc_ref(1)                                   ! kg kg-1
    call basic_grid(PATH, ncid, d, error)
    call nc_var(ncid, 'qc', d, flat(q), 'kg kg-1', NF90_FLOAT, error)
    call nc_var(ncid, 'reff', d, flat(reff_ref()), 'um', NF90_FLOAT, error)
    call nc_var(ncid, 'qi', d, flat(0.5_dp*q*1.0e3_dp), 'g/kg', NF90_FLOAT, error)
    call nc_var(ncid, 'rei', d, flat(2.0_dp*reff_ref()), GREEK_MU//'m', NF90_FLOAT, error)
    call nc_var(ncid, 'TABS', d, flat(t), 'K', NF90_FLOAT, error)
    call nc_var(ncid, 'p', [d(3)], p, 'hPa', NF90_FLOAT, error)
    call nc_close(ncid, error)
    if (allocated(error)) return

    call read_les_field(PATH, names, -1, fld, err)
    call no_error(error, err)
    if (allocated(error)) return
    ! g m-3 = 1000 g/kg * q [kg/kg] * rho [kg m-3]; 4e-5 covers the two R_d values (1.9e-5
    ! apart) and float storage (6e-8); a wrong unit factor or cell is >= 1e-3 away.
    call check_field(error, fld%lwc, 1.0e3_dp*q*rho, 1.0_dp, 4.0e-5_dp, 'lwc')
    call check_field(error, fld%iwc, 0.5e3_dp*q*rho, 1.0_dp, 4.0e-5_dp, 'iwc')
    call check_field(error, fld%pressure, spread(spread(100.0_dp*p, 1, 1), 1, 1), 1.0_dp, &
                     TOL_FLOAT, 'pressure')
    call check_field(error, fld%temperature, t, 1.0_dp, TOL_FLOAT, 'temperature')
    call check(error, index(fld%notes, 'R_d') > 0, 'notes do not say how rho was obtained')
    ! One species at a time (as a run reads large fields): the same values, the other species
    ! not read, and the liquid pass still reports that there is ice.
    call read_les_field(PATH, names, -1, fld, err, part='liquid')
    call no_error(error, err)
    if (allocated(error)) return
    call check_field(error, fld%lwc, 1.0e3_dp*q*rho, 1.0_dp, 4.0e-5_dp, 'lwc (liquid part)')
    call check(error, fld%has_ice .and. .not. allocated(fld%iwc), &
               'liquid part: ice reported but not read')
    call read_les_field(PATH, names, -1, fld, err, part='ice')
    call no_error(error, err)
    if (allocated(error)) return
    call check_field(error, fld%iwc, 0.5e3_dp*q*rho, 1.0_dp, 4.0e-5_dp, 'iwc (ice part)')
    call check_field(error, fld%reff_ice, 2.0_dp*reff_ref(), 1.0_dp, TOL_FLOAT, 'rei (ice part)')
    call check(error, .not. (allocated(fld%lwc) .or. allocated(fld%reff)), &
               'ice part: liquid not read')
    call remove_file(PATH)
  end subroutine test_mixing_ratio_pt

  !> Droplet number instead of r_eff: r_e = r_v / k^(1/3) where the file's LWC was made from a
  !> chosen volume-mean radius r_v and N as LWC = (4/3) pi r_v^3 rho_w N.
  subroutine test_droplet_number(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_d.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, d(3)
    real(dp) :: rv(NX, NY, NZ), n_cm3(NX, NY, NZ), lwc(NX, NY, NZ), expected(NX, NY, NZ)

    rv = reff_ref()                               ! um
    n_cm3 = 50.0_dp + 10.0_dp*lwc_ref(1)          ! cm-3
    ! g m-3: (4/3) pi (rv 1e-6 m)^3 * 1e6 g m-3 * (N 1e6 m-3)
    lwc = 4.0_dp/3.0_dp*PI_TEST*(rv*1.0e-6_dp)**3*1.0e6_dp*(n_cm3*1.0e6_dp)
    lwc(1, 1, 1) = 0.0_dp                         ! clear cell: radius 0, even with N = 0
    n_cm3(1, 1, 1) = 0.0_dp
    call basic_grid(PATH, ncid, d, error)
    call nc_var(ncid, 'lwc', d, flat(lwc), 'g m-3', NF90_DOUBLE, error)
    call nc_var(ncid, 'nc', d, flat(n_cm3), 'cm-3', NF90_DOUBLE, error)
    call nc_close(ncid, error)
    if (allocated(error)) return

    call read_les_field(PATH, names, -1, fld, err)
    call no_error(error, err)
    if (allocated(error)) return
    expected = rv/0.8_dp**(1.0_dp/3.0_dp)          ! default k = 0.80 (maritime)
    expected(1, 1, 1) = 0.0_dp
    call check(error, fld%reff_computed, 'reff_computed not set')
    call check_field(error, fld%reff, expected, 1.0_dp, 1.0e-10_dp, 'reff (k = 0.8)')
    call check(error, index(fld%notes, 'Martin') > 0, 'notes do not say reff was computed')
    call check(error, trim(fld%used%number) == 'nc', 'number name used')
    ! Continental k.
    call read_les_field(PATH, names, -1, fld, err, k_factor=K_CONTINENTAL)
    call no_error(error, err)
    if (allocated(error)) return
    expected = rv/0.67_dp**(1.0_dp/3.0_dp)
    expected(1, 1, 1) = 0.0_dp
    call check_field(error, fld%reff, expected, 1.0_dp, 1.0e-10_dp, 'reff (k = 0.67)')
    call remove_file(PATH)
  end subroutine test_droplet_number

  !> Number per kg of air and a density profile: N [m-3] = N [kg-1] * rho.
  subroutine test_number_per_kg_density(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_e.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, d(3), iz
    real(dp) :: rv(NX, NY, NZ), n_kg(NX, NY, NZ), lwc(NX, NY, NZ), rho(NZ)

    rho = [(1.2_dp - 0.1_dp*iz, iz=1, NZ)]
    rv = reff_ref()
    n_kg = 1.0e8_dp*(1.0_dp + lwc_ref(1))
    do iz = 1, NZ
      lwc(:, :, iz) = 4.0_dp/3.0_dp*PI_TEST*(rv(:, :, iz)*1.0e-6_dp)**3*1.0e6_dp* &
                      n_kg(:, :, iz)*rho(iz)
    end do
    call basic_grid(PATH, ncid, d, error)
    call nc_var(ncid, 'lwc', d, flat(lwc), 'g m-3', NF90_DOUBLE, error)
    call nc_var(ncid, 'cdnc', d, flat(n_kg), '1/kg', NF90_DOUBLE, error)
    call nc_var(ncid, 'rho', [d(3)], rho, 'kg m-3', NF90_DOUBLE, error)
    call nc_close(ncid, error)
    if (allocated(error)) return
    names%number = 'cdnc'
    call read_les_field(PATH, names, -1, fld, err)
    call no_error(error, err)
    if (allocated(error)) return
    call check_field(error, fld%reff, rv/0.8_dp**(1.0_dp/3.0_dp), 1.0_dp, 1.0e-10_dp, 'reff')
    call check(error, trim(fld%used%air_density) == 'rho', 'density name used')
    call remove_file(PATH)
  end subroutine test_number_per_kg_density

  !> Stretched z centres: an error by default, midpoint edges when asked for.
  subroutine test_stretched_z(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_f.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err

    call write_basic(PATH, error, z_km=[0.05_dp, 0.15_dp, 0.3_dp, 0.5_dp])
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err)
    call expect_error(error, err, [character(len=64) :: &
        'test_les_f.nc:z)', 'not uniform     ', 'give z edges    '])
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err, z_edges_from_midpoints=.true.)
    call no_error(error, err)
    if (allocated(error)) return
    ! Midpoints 100, 225, 400 m; outer edges half a step beyond: 50 - 50, 500 + 100.
    call check_array(error, fld%z_edges, [0.0_dp, 100.0_dp, 225.0_dp, 400.0_dp, 600.0_dp], &
                     TOL_FLOAT, 'z_edges', abs_tol=1.0e-4_dp)
    call remove_file(PATH)
  end subroutine test_stretched_z

  ! ------------------------------------------------------------------------------------------------
  ! Bad files
  ! ------------------------------------------------------------------------------------------------

  subroutine test_err_missing_units(error)
    type(error_t), allocatable, intent(out) :: error
    call bad_basic(error, 'test_les_bad1.nc', [character(len=64) :: 'lwc)                     ', &
                                               'units attribute missing  ', &
                                               'g m-3, kg m-3            '], lwc_units='')
  end subroutine test_err_missing_units

  subroutine test_err_unknown_units(error)
    type(error_t), allocatable, intent(out) :: error
    call bad_basic(error, 'test_les_bad2.nc', [character(len=64) :: &
        'lwc)                         ', &
                                               'units "g/cm3" not accepted   ', &
                                               'g m-3, kg m-3, g kg-1, kg kg-1'], &
                   lwc_units='g/cm3')
  end subroutine test_err_unknown_units

  subroutine test_err_negative(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp) :: lwc(NX, NY, NZ)
    lwc = lwc_ref(1)
    lwc(2, 1, 3) = -0.01_dp
    call bad_basic(error, 'test_les_bad3.nc', [character(len=64) :: 'lwc)                    ', &
                                               'at (x,y,z) = (2,1,3)    ', &
                                               'must be >= 0            '], lwc=lwc)
  end subroutine test_err_negative

  subroutine test_err_nan(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp) :: lwc(NX, NY, NZ)
    lwc = lwc_ref(1)
    lwc(3, 2, 1) = ieee_value(1.0_dp, ieee_quiet_nan)
    call bad_basic(error, 'test_les_bad4.nc', [character(len=64) :: 'lwc)                    ', &
                                               'value NaN               ', &
                                               'at (x,y,z) = (3,2,1)    ', &
                                               'is not finite           '], lwc=lwc)
  end subroutine test_err_nan

  subroutine test_err_fill(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp) :: lwc(NX, NY, NZ)
    lwc = lwc_ref(1)
    lwc(1, 2, 4) = -999.0_dp
    call bad_basic(error, 'test_les_bad5.nc', [character(len=64) :: &
        'lwc)                         ', &
                                               'at (x,y,z) = (1,2,4)         ', &
                                               'fill value (missing data)    '], lwc=lwc, &
                   fill=-999.0_dp)
  end subroutine test_err_fill

  subroutine test_err_non_uniform_x(error)
    type(error_t), allocatable, intent(out) :: error
    call bad_basic(error, 'test_les_bad6.nc', [character(len=64) :: &
        'test_les_bad6.nc:x)          ', &
                                               'spacing is not uniform       ', &
                                               'step 1 to 2 is 100.0000      '], &
                   x_km=[0.05_dp, 0.15_dp, 0.3_dp])
  end subroutine test_err_non_uniform_x

  !> lwc(x, y, z) in ncdump order (Fortran z, y, x): reported, not transposed.
  subroutine test_err_dim_order(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_bad7.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, d(3)
    call basic_grid(PATH, ncid, d, error)
    call nc_var(ncid, 'lwc', [d(3), d(2), d(1)], flat(lwc_ref(1)), 'g m-3', NF90_FLOAT, error)
    call nc_close(ncid, error)
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err)
    call expect_error(error, err, [character(len=64) :: &
        'lwc)                                             ', &
                                   'dimensions are (x, y, z) in ncdump order         ', &
                                   'expected (z, y, x)                               ', &
                                   'does not transpose                               '])
    call remove_file(PATH)
  end subroutine test_err_dim_order

  subroutine test_err_missing_var(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_bad8.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, d(3)
    call basic_grid(PATH, ncid, d, error)
    call nc_var(ncid, 'cloud', d, flat(lwc_ref(1)), 'g m-3', NF90_FLOAT, error)
    call nc_close(ncid, error)
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err)
    call expect_error(error, err, [character(len=64) :: 'no liquid water variable            ', &
                                   'tried lwc, LWC, ql, qc, QC, qcl     '])
    if (allocated(error)) return
    names%lwc = 'cloud_water'
    call read_les_field(PATH, names, -1, fld, err)
    call expect_error(error, err, [character(len=64) :: '"cloud_water" not found'])
    if (allocated(error)) return
    ! lwc found under a given name, but neither reff nor number: both lists named.
    names%lwc = 'cloud'
    call read_les_field(PATH, names, -1, fld, err)
    call expect_error(error, err, [character(len=64) :: &
        'tried reff, r_eff  ', 'tried nc, Nc, NC   '])
    call remove_file(PATH)
  end subroutine test_err_missing_var

  subroutine test_err_time_index(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_bad9.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, d(3), dt_
    real(dp) :: lwc4(NX, NY, NZ, NT)
    lwc4 = 1.0_dp
    call basic_grid(PATH, ncid, d, error, time_dim=dt_)
    call nc_var(ncid, 'lwc', [d, dt_], reshape(lwc4, [size(lwc4)]), 'g m-3', NF90_FLOAT, error)
    call nc_var(ncid, 'reff', [d, dt_], reshape(lwc4, [size(lwc4)]), 'um', NF90_FLOAT, error)
    call nc_close(ncid, error)
    if (allocated(error)) return
    call read_les_field(PATH, names, 4, fld, err)
    call expect_error(error, err, [character(len=64) :: &
        'time index 4 is outside 1 to 3', 'dimension "time"            '])
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err)
    call expect_error(error, err, [character(len=64) :: 'has a time dimension "time" of length 3'])
    if (allocated(error)) return
    call read_les_field(PATH, names, 0, fld, err)
    call expect_error(error, err, [character(len=64) :: 'time index 0 must be >= 1'])
    if (allocated(error)) return
    call read_les_field(PATH, names, 3, fld, err)      ! the last step is fine
    call no_error(error, err)
    call remove_file(PATH)
    ! A file without time: a time index is an error.
    call write_basic(PATH, error)
    if (allocated(error)) return
    call read_les_field(PATH, names, 2, fld, err)
    call expect_error(error, err, [character(len=64) :: 'no time dimension; use -1'])
    call remove_file(PATH)
  end subroutine test_err_time_index

  subroutine test_err_no_density(error)
    type(error_t), allocatable, intent(out) :: error
    call bad_basic(error, 'test_les_bad10.nc', [character(len=64) :: &
        '"lwc" is given per mass of air    ', &
                                                'needs the air density             ', &
                                                'tried rho, rho_air                ', &
                                                'no pressure (tried pressure, pres,', &
                                                'no temperature                    '], &
                   lwc_units='kg/kg')
  end subroutine test_err_no_density

  subroutine test_err_ice_no_radius(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_les_bad11.nc'
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    integer :: ncid, d(3)
    call basic_grid(PATH, ncid, d, error)
    call nc_var(ncid, 'lwc', d, flat(lwc_ref(1)), 'g m-3', NF90_FLOAT, error)
    call nc_var(ncid, 'reff', d, flat(reff_ref()), 'um', NF90_FLOAT, error)
    call nc_var(ncid, 'IWC', d, flat(lwc_ref(1)), 'g m-3', NF90_FLOAT, error)
    call nc_close(ncid, error)
    if (allocated(error)) return
    call read_les_field(PATH, names, -1, fld, err)
    call expect_error(error, err, [character(len=64) :: &
        'ice water "IWC" needs an ice effective radius', &
                                   'tried reff_ice, r_eff_ice                    '])
    call remove_file(PATH)
  end subroutine test_err_ice_no_radius

  ! ------------------------------------------------------------------------------------------------
  ! Reference fields and files
  ! ------------------------------------------------------------------------------------------------

  !> Liquid water [g m-3]: distinct in every cell (a transposition or offset shows), >= 0.
  pure function lwc_ref(scale) result(v)
    integer, intent(in) :: scale
    real(dp) :: v(NX, NY, NZ)
    integer :: ix, iy, iz
    do concurrent(ix=1:NX, iy=1:NY, iz=1:NZ)
      v(ix, iy, iz) = scale*(0.1_dp*ix + 0.01_dp*iy + 0.001_dp*iz)
    end do
  end function lwc_ref

  !> Effective radius [um], distinct in every cell.
  pure function reff_ref() result(v)
    real(dp) :: v(NX, NY, NZ)
    integer :: ix, iy, iz
    do concurrent(ix=1:NX, iy=1:NY, iz=1:NZ)
      v(ix, iy, iz) = 5.0_dp + ix + 0.1_dp*iy + 0.5_dp*iz
    end do
  end function reff_ref

  pure function flat(a) result(v)
    real(dp), intent(in) :: a(:, :, :)
    real(dp) :: v(size(a))
    v = reshape(a, [size(a)])
  end function flat

  !> Dimensions z, y, x (ncdump order) and float centre coordinates in km.
  subroutine basic_grid(path, ncid, d, error, x_km, z_km, time_dim)
    character(len=*), intent(in) :: path
    integer, intent(out) :: ncid, d(3)
    type(error_t), allocatable, intent(inout) :: error
    real(dp), intent(in), optional :: x_km(NX), z_km(NZ)
    integer, intent(out), optional :: time_dim
    real(dp) :: x(NX), z(NZ)
    x = [0.05_dp, 0.15_dp, 0.25_dp]
    z = [0.1_dp, 0.3_dp, 0.5_dp, 0.7_dp]
    if (present(x_km)) x = x_km
    if (present(z_km)) z = z_km
    call nc_create(path, ncid, error)
    if (present(time_dim)) call nc_dim(ncid, 'time', NT, time_dim, error)
    call nc_dim(ncid, 'z', NZ, d(3), error)
    call nc_dim(ncid, 'y', NY, d(2), error)
    call nc_dim(ncid, 'x', NX, d(1), error)
    call nc_var(ncid, 'x', [d(1)], x, 'km', NF90_FLOAT, error)
    call nc_var(ncid, 'y', [d(2)], [0.025_dp, 0.075_dp], 'km', NF90_FLOAT, error)
    call nc_var(ncid, 'z', [d(3)], z, 'km', NF90_FLOAT, error)
  end subroutine basic_grid

  !> The convention of test_gm3_um_centres_km, with one thing changed on request.
  subroutine write_basic(path, error, lwc, lwc_units, fill, x_km, z_km)
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(inout) :: error
    real(dp), intent(in), optional :: lwc(NX, NY, NZ)
    character(len=*), intent(in), optional :: lwc_units
    real(dp), intent(in), optional :: fill
    real(dp), intent(in), optional :: x_km(NX), z_km(NZ)
    integer :: ncid, d(3)
    real(dp) :: values(NX, NY, NZ)
    character(len=:), allocatable :: units
    values = lwc_ref(1)
    if (present(lwc)) values = lwc
    units = 'g m-3'
    if (present(lwc_units)) units = lwc_units
    call basic_grid(path, ncid, d, error, x_km, z_km)
    ! NaN goes through a double variable (float conversion of NaN is the library's business).
    if (present(lwc)) then
      call nc_var(ncid, 'lwc', d, flat(values), units, NF90_DOUBLE, error, fill)
    else
      call nc_var(ncid, 'lwc', d, flat(values), units, NF90_FLOAT, error, fill)
    end if
    call nc_var(ncid, 're', d, flat(reff_ref()), MICRO//'m', NF90_FLOAT, error)
    call nc_var(ncid, 'iwc', d, flat(0.1_dp*lwc_ref(1)), 'g/m3', NF90_FLOAT, error)
    call nc_var(ncid, 'rei', d, flat(3.0_dp*reff_ref()), 'micron', NF90_FLOAT, error)
    call nc_close(ncid, error)
  end subroutine write_basic

  !> Write a basic file with one defect, read it, expect an error containing every `expected`.
  subroutine bad_basic(error, path, expected, lwc, lwc_units, fill, x_km)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in) :: path
    character(len=*), intent(in) :: expected(:)
    real(dp), intent(in), optional :: lwc(NX, NY, NZ)
    character(len=*), intent(in), optional :: lwc_units
    real(dp), intent(in), optional :: fill
    real(dp), intent(in), optional :: x_km(NX)
    type(les_field_t) :: fld
    type(les_names_t) :: names
    type(error_t), allocatable :: err
    call write_basic(path, error, lwc, lwc_units, fill, x_km)
    if (allocated(error)) return
    call read_les_field(path, names, -1, fld, err)
    call expect_error(error, err, expected)
    call check(error, .not. allocated(fld%lwc), 'lwc left allocated after an error')
    call remove_file(path)
  end subroutine bad_basic

  ! ------------------------------------------------------------------------------------------------
  ! Checks
  ! ------------------------------------------------------------------------------------------------

  subroutine no_error(error, err)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    if (allocated(err)) call check(error, .false., 'unexpected error: '//err%message)
  end subroutine no_error

  subroutine expect_error(error, err, expected)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: expected(:)
    integer :: i
    call check(error, allocated(err), 'no error; expected one with "'//trim(expected(1))//'"')
    if (allocated(error)) return
    do i = 1, size(expected)
      call check(error, index(err%message, trim(expected(i))) > 0, 'message lacks "'// &
                 trim(expected(i))//'": '//err%message)
    end do
  end subroutine expect_error

  !> actual = factor * expected elementwise, relative tolerance; the message names the cell.
  subroutine check_field(error, actual, expected, factor, rel_tol, label)
    type(error_t), allocatable, intent(inout) :: error
    real(vp), allocatable, intent(in) :: actual(:, :, :)
    real(dp), intent(in) :: expected(:, :, :)
    real(dp), intent(in) :: factor, rel_tol   !! raised to TOL_STORED at least
    character(len=*), intent(in) :: label
    integer :: ix, iy, iz
    character(len=40) :: place
    if (allocated(error)) return
    call check(error, allocated(actual), label//' not allocated')
    if (allocated(error)) return
    call check(error, all(shape(actual) == shape(expected)), label//': wrong shape')
    if (allocated(error)) return
    do iz = 1, size(actual, 3)
      do iy = 1, size(actual, 2)
        do ix = 1, size(actual, 1)
          write (place, '(a,i0,a,i0,a,i0,a)') '(', ix, ',', iy, ',', iz, ')'
          call check_close(error, real(actual(ix, iy, iz), dp), factor*expected(ix, iy, iz), &
                           rel_tol=max(rel_tol, TOL_STORED), label=label//trim(place))
          if (allocated(error)) return
        end do
      end do
    end do
  end subroutine check_field

  subroutine check_array(error, actual, expected, rel_tol, label, abs_tol)
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(in) :: actual(:)
    real(dp), intent(in) :: expected(:)
    real(dp), intent(in) :: rel_tol
    character(len=*), intent(in) :: label
    real(dp), intent(in), optional :: abs_tol
    integer :: i
    character(len=12) :: buf
    if (allocated(error)) return
    call check(error, size(actual) == size(expected), label//': wrong size')
    do i = 1, size(expected)
      if (allocated(error)) return
      write (buf, '(i0)') i
      call check_close(error, actual(i), expected(i), abs_tol=abs_tol, rel_tol=rel_tol, &
                       label=label//'('//trim(buf)//')')
    end do
  end subroutine check_array

  ! ------------------------------------------------------------------------------------------------
  ! netCDF writing (classic format; each call checked)
  ! ------------------------------------------------------------------------------------------------

  subroutine nc_ok(error, status, what)
    type(error_t), allocatable, intent(inout) :: error
    integer, intent(in) :: status
    character(len=*), intent(in) :: what
    if (status == NF90_NOERR) return
    call check(error, .false., 'writing the test file, '//what//': '//trim(nf90_strerror(status)))
  end subroutine nc_ok

  subroutine nc_create(path, ncid, error)
    character(len=*), intent(in) :: path
    integer, intent(out) :: ncid
    type(error_t), allocatable, intent(inout) :: error
    call nc_ok(error, nf90_create(path, NF90_CLOBBER, ncid), 'create '//path)
  end subroutine nc_create

  subroutine nc_dim(ncid, name, n, dimid, error)
    integer, intent(in) :: ncid, n
    character(len=*), intent(in) :: name
    integer, intent(out) :: dimid
    type(error_t), allocatable, intent(inout) :: error
    dimid = -1
    if (allocated(error)) return
    call nc_ok(error, nf90_def_dim(ncid, name, n, dimid), 'dimension '//name)
  end subroutine nc_dim

  !> Define and write a variable (Fortran dimension order); units '' writes no attribute.
  subroutine nc_var(ncid, name, dimids, values, units, xtype, error, fill)
    integer, intent(in) :: ncid
    character(len=*), intent(in) :: name
    integer, intent(in) :: dimids(:)
    real(dp), intent(in) :: values(:)
    character(len=*), intent(in) :: units
    integer, intent(in) :: xtype
    type(error_t), allocatable, intent(inout) :: error
    real(dp), intent(in), optional :: fill
    integer :: varid, i, status, counts(size(dimids))
    if (allocated(error)) return
    do i = 1, size(dimids)
      call nc_ok(error, nf90_inquire_dimension(ncid, dimids(i), len=counts(i)), name)
    end do
    status = nf90_redef(ncid)        ! fails harmlessly when still in define mode after create
    call nc_ok(error, nf90_def_var(ncid, name, xtype, dimids, varid), name)
    if (len(units) > 0) call nc_ok(error, nf90_put_att(ncid, varid, 'units', units), name)
    if (present(fill)) then
      if (xtype == NF90_FLOAT) then
        call nc_ok(error, nf90_put_att(ncid, varid, '_FillValue', real(fill, sp)), name)
      else
        call nc_ok(error, nf90_put_att(ncid, varid, '_FillValue', fill), name)
      end if
    end if
    call nc_ok(error, nf90_enddef(ncid), name)
    if (allocated(error)) return
    call nc_ok(error, nf90_put_var(ncid, varid, values, start=spread(1, 1, size(dimids)), &
                                   count=counts), name)
  end subroutine nc_var

  subroutine nc_close(ncid, error)
    integer, intent(in) :: ncid
    type(error_t), allocatable, intent(inout) :: error
    call nc_ok(error, nf90_close(ncid), 'close')
  end subroutine nc_close

  subroutine remove_file(path)
    character(len=*), intent(in) :: path
    integer :: unit, ios
    logical :: exists
    inquire (file=path, exist=exists)
    if (.not. exists) return
    open (newunit=unit, file=path, status='old', iostat=ios)
    if (ios /= 0) return
    close (unit, status='delete', iostat=ios)
    if (ios /= 0) return                  ! a stale file is overwritten by the next test anyway
  end subroutine remove_file
end module test_kumo_les_netcdf

program test_les_netcdf
  use test_kumo_les_netcdf, only: collect_les_netcdf
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_les_netcdf', collect_les_netcdf(), n_failed)
  if (n_failed > 0) error stop 1
end program test_les_netcdf
