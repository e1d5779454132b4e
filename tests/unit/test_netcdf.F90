! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_netcdf: result files, atomic writes, scene and albedo-map input.
!>
!> Files are created in the current directory (CTest runs the test in the build tree) and removed
!> at the end of each test. Files with deliberately broken content are made with `write_results`,
!> which writes whatever a result set holds, so this test needs no netCDF calls of its own.
module test_kumo_netcdf
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_positive_inf
  use kumo_kinds, only: wp, dp
  use kumo_error, only: error_t, str
  use kumo_results, only: result_set_t, add_dim, add_var, add_attr
  use kumo_netcdf, only: write_results, check_writable, read_scene_3d, write_scene_3d, &
                         read_albedo_map, read_var_1d, read_text_attr
  use kumo_testing, only: unittest_t, new_unittest, check
  implicit none
  private
  public :: collect_netcdf

  character(len=*), parameter :: MISSING_DIR_PATH = 'kumo_no_such_dir/out.nc'
  !> Scene used throughout: nx, ny, nz3, ncomp (all different, so a transposition shows).
  integer, parameter :: NX = 3, NY = 2, NZ = 4, NC = 2
  !> netCDF's default fill value for doubles (missing data).
  real(dp), parameter :: FILL_DOUBLE = 9.9692099683868690e+36_dp
  character(len=*), parameter :: NO_DIMS(0) = [character(len=1) ::]

  !> A scene as written by write_scene_3d and as read back by read_scene_3d.
  type :: scene_t
    real(wp), allocatable :: ext(:, :, :, :), ssa(:, :, :, :)
    integer, allocatable :: phase(:, :, :, :)   !! phase_index; not allocated: none
    logical :: has_phase = .false.
  end type scene_t

contains

  !> All tests of this suite.
  function collect_netcdf() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('results_round_trip', test_results_round_trip), &
             new_unittest('results_dimension_order', test_results_dim_order), &
             new_unittest('results_missing_directory', test_results_missing_dir), &
             new_unittest('results_non_finite_leaves_no_file', test_results_non_finite), &
             new_unittest('results_failure_keeps_old_file', test_results_keeps_old_file), &
             new_unittest('results_invalid_sets', test_results_invalid_sets), &
             new_unittest('check_writable', test_check_writable), &
             new_unittest('scene_round_trip', test_scene_round_trip), &
             new_unittest('scene_without_phase_index', test_scene_no_phase_index), &
             new_unittest('scene_km_units_converted', test_scene_km_units), &
             new_unittest('scene_writer_validates', test_scene_writer_validates), &
             new_unittest('scene_error_dimension_size', test_scene_bad_dim_size), &
             new_unittest('scene_error_missing_variable', test_scene_missing_var), &
             new_unittest('scene_error_units', test_scene_bad_units), &
             new_unittest('scene_error_negative_extinction', test_scene_negative_ext), &
             new_unittest('scene_error_ssa_above_one', test_scene_ssa_above_one), &
             new_unittest('scene_error_fill_value', test_scene_fill_value), &
             new_unittest('scene_error_dimension_order', test_scene_dim_order), &
             new_unittest('scene_error_phase_index_type', test_scene_phase_index_type), &
             new_unittest('scene_error_missing_file', test_scene_missing_file), &
             new_unittest('albedo_map_round_trip', test_albedo_round_trip), &
             new_unittest('albedo_map_errors', test_albedo_errors), &
             new_unittest('text_attribute_missing', test_text_attr_missing)]
  end function collect_netcdf

  ! ------------------------------------------------------------------------------------------------
  ! Result files
  ! ------------------------------------------------------------------------------------------------

  subroutine test_results_round_trip(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_results.nc'
    type(result_set_t) :: set
    type(error_t), allocatable :: err
    real(dp), allocatable :: values(:)

    call sample_set(set)
    call write_set(error, PATH, set)
    call check(error, file_exists(PATH), 'output file missing after write_results')
    call check(error, .not. file_exists(PATH//'.tmp'), 'temporary file left after success')
    if (allocated(error)) return

    call read_and_compare(error, PATH, 'x', [500.0_dp, 1500.0_dp, 2500.0_dp])
    call read_and_compare(error, PATH, 'albedo_mean', [0.3_dp])
    call read_and_compare(error, PATH, 'albedo_mean_stderr', [0.01_dp])
    call read_and_compare(error, PATH, 'n_photons', [1.0e6_dp])
    call read_and_compare(error, PATH, 'flux_up', set%vars(3)%mean)
    call read_and_compare(error, PATH, 'flux_up_stderr', set%vars(3)%stderr)
    call read_and_compare(error, PATH, 'heating', set%vars(4)%mean)
    call read_and_compare(error, PATH, 'heating_stderr', set%vars(4)%stderr)
    if (allocated(error)) return

    ! No companion for a variable without standard error; no coordinate for `level`.
    call read_var_1d(PATH, 'n_photons_stderr', values, err)
    call check_message(error, err, ['n_photons_stderr'], 'n_photons_stderr must not exist')
    call read_var_1d(PATH, 'level', values, err)
    call check_message(error, err, ['level'], 'level has no coordinate variable')

    call check_text_attr(error, PATH, 'Conventions', 'CF-1.8')
    call check_text_attr(error, PATH, 'title', 'kumo unit test')
    call check_text_attr(error, PATH, 'comment', '')
    call remove_file(PATH)
  end subroutine test_results_round_trip

  !> A variable on (xs, ys) reads back with read_albedo_map, which insists on albedo(ys, xs) in
  !> ncdump order: the writer keeps Fortran order and reverses the file order.
  subroutine test_results_dim_order(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_order.nc'
    real(wp), allocatable :: albedo(:, :)
    integer :: i

    call albedo_round_trip(error, PATH, 'albedo', 3, 2, [(0.1_dp*i, i=1, 6)], albedo)
    call remove_file(PATH)
  end subroutine test_results_dim_order

  subroutine test_results_missing_dir(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: set
    type(error_t), allocatable :: err

    call sample_set(set)
    call write_results(MISSING_DIR_PATH, set, err)
    call check_message(error, err, [character(len=80) :: 'write_results', MISSING_DIR_PATH], &
                       'writing into a missing directory')
    call check(error, .not. file_exists(MISSING_DIR_PATH), 'output file exists')
    call check(error, .not. file_exists(MISSING_DIR_PATH//'.tmp'), 'temporary file exists')
  end subroutine test_results_missing_dir

  subroutine test_results_non_finite(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_nan.nc'
    type(result_set_t) :: set
    type(error_t), allocatable :: err

    call remove_file(PATH)
    ! heating(x, y, level) has shape (3, 2, 4): element (2, 1, 3) is flat index 2 + 0 + 2*6 = 14.
    call sample_set(set)
    set%vars(4)%mean(14) = ieee_value(1.0_dp, ieee_quiet_nan)
    call write_results(PATH, set, err)
    call check_message(error, err, [character(len=80) :: 'write_results('//PATH//':heating)', &
                                    'NaN', '(x,y,level) = (2,1,3)', 'not finite'], 'NaN in heating')
    call check(error, .not. file_exists(PATH), 'output file exists after NaN')
    call check(error, .not. file_exists(PATH//'.tmp'), 'temporary file exists after NaN')
    if (allocated(error)) return

    call sample_set(set)
    set%vars(3)%stderr(2) = ieee_value(1.0_dp, ieee_positive_inf)
    call write_results(PATH, set, err)
    call check_message(error, err, [character(len=80) :: ':flux_up_stderr)', 'Infinity', &
                                    '(x) = (2)'], 'Inf in flux_up_stderr')
    call check(error, .not. file_exists(PATH), 'output file exists after Inf')
    call check(error, .not. file_exists(PATH//'.tmp'), 'temporary file exists after Inf')
  end subroutine test_results_non_finite

  !> A failed write, before or after the temporary file was created, leaves an existing output
  !> file untouched and no temporary file behind.
  subroutine test_results_keeps_old_file(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_keep.nc'
    type(result_set_t) :: good, bad
    type(error_t), allocatable :: err

    call sample_set(good)
    call write_set(error, PATH, good)
    if (allocated(error)) return

    ! Fails validation: no file is created at all.
    call sample_set(bad)
    bad%vars(3)%mean(1) = ieee_value(1.0_dp, ieee_quiet_nan)
    call write_results(PATH, bad, err)
    call check_message(error, err, [character(len=80) :: ':flux_up)'], 'NaN in flux_up')
    if (allocated(error)) return

    ! Fails inside netCDF: the name "x" is already taken by the coordinate variable.
    call sample_set(bad)
    call add_var(bad, 'x', 'clashes with the coordinate x', '1', ['y'], [1.0_dp, 2.0_dp])
    call write_results(PATH, bad, err)
    call check_message(error, err, [character(len=80) :: 'write_results('//PATH//':x)', &
                                    'NetCDF'], 'variable name clash')
    call check(error, .not. file_exists(PATH//'.tmp'), 'temporary file left after a failure')
    if (allocated(error)) return

    call read_and_compare(error, PATH, 'flux_up', good%vars(3)%mean, &
                          label='flux_up of the old file')
    call read_and_compare(error, PATH, 'x', good%dims(1)%coord, label='x of the old file')
    call remove_file(PATH)
  end subroutine test_results_keeps_old_file

  subroutine test_results_invalid_sets(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_invalid.nc'
    type(result_set_t) :: set
    type(error_t), allocatable :: err

    call remove_file(PATH)
    call sample_set(set)
    call add_var(set, 'orphan', 'on an undefined dimension', '1', ['nowhere'], [1.0_dp])
    call write_results(PATH, set, err)
    call check_message(error, err, [':orphan) ', '"nowhere"'], 'undefined dimension')

    call sample_set(set)
    call add_var(set, 'short', 'too few values', '1', ['x'], [1.0_dp, 2.0_dp])
    call write_results(PATH, set, err)
    call check_message(error, err, [character(len=20) :: ':short)', '2 mean values', &
                                    'expected 3'], 'wrong number of values')

    call sample_set(set)
    set%vars(3)%stderr(1) = -1.0_dp
    call write_results(PATH, set, err)
    call check_message(error, err, [character(len=80) :: ':flux_up_stderr)', 'must be >= 0'], &
                       'negative stderr')

    call sample_set(set)
    call add_attr(set, 'Conventions', 'CF-1.6')
    call write_results(PATH, set, err)
    call check_message(error, err, [character(len=80) :: ':Conventions)'], 'Conventions in the set')
    call check(error, .not. file_exists(PATH), 'an invalid set created a file')
    call check(error, .not. file_exists(PATH//'.tmp'), 'an invalid set left a temporary file')
  end subroutine test_results_invalid_sets

  subroutine test_check_writable(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_probe.nc'
    type(error_t), allocatable :: err

    call remove_file(PATH)
    call check_writable(PATH, err)
    call check_no_error(error, err, 'check_writable on a writable path')
    call check(error, .not. file_exists(PATH), 'check_writable created the output file')
    call check(error, .not. file_exists(PATH//'.tmp'), 'check_writable left its probe file')
    if (allocated(error)) return

    call check_writable(MISSING_DIR_PATH, err)
    call check_message(error, err, [character(len=80) :: 'check_writable(', MISSING_DIR_PATH], &
                       'missing directory')
    call check_writable('.', err)
    call check_message(error, err, ['is a directory'], 'directory as output path')
  end subroutine test_check_writable

  ! ------------------------------------------------------------------------------------------------
  ! Scene files
  ! ------------------------------------------------------------------------------------------------

  subroutine test_scene_round_trip(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene.nc'
    type(scene_t) :: scene, got

    call sample_scene(scene)
    call write_scene(error, PATH, scene, 'write_scene_3d')
    call check(error, .not. file_exists(PATH//'.tmp'), 'temporary file left after success')
    if (allocated(error)) return

    call read_scene(error, PATH, got, 'read_scene_3d')
    if (allocated(error)) return
    call check(error, got%has_phase .and. allocated(got%phase), 'phase_index not read')
    if (allocated(error)) return
    call check(error, all(shape(got%ext) == [NX, NY, NZ, NC]), 'extinction has the wrong shape')
    call check(error, all(shape(got%ssa) == [NX, NY, NZ, NC]), 'ssa has the wrong shape')
    call check(error, all(shape(got%phase) == [NX, NY, NZ, NC]), 'phase_index has the wrong shape')
    if (allocated(error)) return
    call check_values(error, flat(got%ext), flat(scene%ext), 0.0_dp, 'extinction')
    call check_values(error, flat(got%ssa), flat(scene%ssa), 0.0_dp, 'ssa')
    call check(error, all(got%phase == scene%phase), 'phase_index differs after the round trip')

    ! The file holds the values in Fortran order of (x, y, z, component).
    call read_and_compare(error, PATH, 'extinction', flat(scene%ext), label='extinction (flat)')
    call remove_file(PATH)
  end subroutine test_scene_round_trip

  subroutine test_scene_no_phase_index(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_nophase.nc'
    type(scene_t) :: scene, got

    call sample_scene(scene)
    deallocate (scene%phase)                  ! written without phase_index
    call write_scene(error, PATH, scene, 'write_scene_3d without phase_index')
    if (allocated(error)) return
    call read_scene(error, PATH, got, 'read_scene_3d')
    call check(error, .not. got%has_phase, 'has_phase_index is true for a file without it')
    call check(error, .not. allocated(got%phase), 'phase_index allocated for a file without it')
    call remove_file(PATH)
  end subroutine test_scene_no_phase_index

  subroutine test_scene_km_units(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_km.nc'
    type(scene_t) :: scene, got

    call sample_scene(scene)
    call write_scene(error, PATH, scene, 'write_scene_3d in km-1', ext_units='km-1')
    if (allocated(error)) return
    ! The file holds km-1 values, 1000 times the m-1 values.
    call read_and_compare(error, PATH, 'extinction', 1000.0_dp*flat(scene%ext), 1.0e-15_dp, &
                          'extinction in the file [km-1]')
    if (allocated(error)) return
    ! The reader converts back to m-1.
    call read_scene(error, PATH, got, 'read_scene_3d of a km-1 file')
    if (allocated(error)) return
    call check_values(error, flat(got%ext), flat(scene%ext), 1.0e-15_dp, &
                      'extinction read from km-1 [m-1]')
    call remove_file(PATH)
  end subroutine test_scene_km_units

  subroutine test_scene_writer_validates(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_bad.nc'
    type(scene_t) :: scene
    type(error_t), allocatable :: err

    call remove_file(PATH)
    call sample_scene(scene)
    scene%phase(1, 2, 1, 1) = 0
    call write_scene_3d(PATH, scene%ext, scene%ssa, scene%phase, err)
    call check_message(error, err, [character(len=80) :: 'write_scene_3d('//PATH//':phase_index)', &
                                    'value 0', '(x,y,z,component) = (1,2,1,1)', 'must be >= 1'], &
                       'phase_index 0')
    call sample_scene(scene)
    call write_scene_3d(PATH, scene%ext, scene%ssa(:, :, 1:2, :), error=err)
    call check_message(error, err, [character(len=80) :: ':ssa)', 'shape'], 'ssa shape mismatch')
    call write_scene_3d(PATH, scene%ext, scene%ssa, error=err, ext_units='1/km')
    call check_message(error, err, [character(len=80) :: '"1/km"'], 'unknown ext_units')
    call check(error, .not. file_exists(PATH), 'invalid scene created a file')
    call check(error, .not. file_exists(PATH//'.tmp'), 'invalid scene left a temporary file')
  end subroutine test_scene_writer_validates

  subroutine test_scene_bad_dim_size(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_dims.nc'
    type(scene_t) :: scene

    call sample_scene(scene)
    call write_scene(error, PATH, scene, 'write_scene_3d')
    if (allocated(error)) return
    call expect_scene_error(error, PATH, NZ + 1, [character(len=80) :: &
                            'read_scene_3d('//PATH//':z)', 'size 4', 'nz3 = 5'], &
                            'wrong number of layers')
    call remove_file(PATH)
  end subroutine test_scene_bad_dim_size

  subroutine test_scene_missing_var(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_nossa.nc'
    type(result_set_t) :: set

    call scene_like_set(set, 'm-1', with_ssa=.false.)
    call expect_written_scene_error(error, PATH, set, [character(len=80) :: &
                                    'read_scene_3d('//PATH//':ssa)', 'not found'], 'missing ssa')
  end subroutine test_scene_missing_var

  subroutine test_scene_bad_units(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_units.nc'
    type(result_set_t) :: set

    call scene_like_set(set, 'm')
    call expect_written_scene_error(error, PATH, set, [character(len=80) :: ':extinction)', &
                                    'units "m"', '"m-1"', '"km-1"'], 'extinction in m')
    if (allocated(error)) return

    call scene_like_set(set, '')          ! a blank units string is not written at all
    call expect_written_scene_error(error, PATH, set, [character(len=80) :: ':extinction)', &
                                    'units attribute missing', '"m-1"'], &
                                    'extinction without units')
    if (allocated(error)) return

    call scene_like_set(set, 'm-1', ssa_units='%')
    call expect_written_scene_error(error, PATH, set, [character(len=80) :: ':ssa)', &
                                    'units "%"', '"1" or absent'], 'ssa in percent')
  end subroutine test_scene_bad_units

  subroutine test_scene_negative_ext(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_negext.nc'
    call expect_bad_scene_value(error, PATH, 'm-1', 1, [2, 1, 3, 1], -2.5_dp, &
                                [character(len=80) :: 'read_scene_3d('//PATH//':extinction)', &
                                 'value -2.5', '(x,y,z,component) = (2,1,3,1)', 'must be >= 0'], &
                                'negative extinction')
  end subroutine test_scene_negative_ext

  subroutine test_scene_ssa_above_one(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_ssa.nc'
    call expect_bad_scene_value(error, PATH, 'km-1', 2, [3, 2, 4, 2], 1.25_dp, &
                                [character(len=80) :: 'read_scene_3d('//PATH//':ssa)', &
                                 'value 1.25', '(x,y,z,component) = (3,2,4,2)', 'must be <= 1'], &
                                'ssa above 1')
  end subroutine test_scene_ssa_above_one

  subroutine test_scene_fill_value(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_fill.nc'
    call expect_bad_scene_value(error, PATH, 'm-1', 1, [1, 2, 2, 1], FILL_DOUBLE, &
                                [character(len=80) :: ':extinction)', &
                                 '(x,y,z,component) = (1,2,2,1)', 'fill value'], 'fill value')
  end subroutine test_scene_fill_value

  subroutine test_scene_dim_order(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_order.nc'
    type(result_set_t) :: set

    call scene_like_set(set, 'm-1', reversed=.true.)
    call expect_written_scene_error(error, PATH, set, [character(len=80) :: ':extinction)', &
                                    '(x, y, z, component) in ncdump order', &
                                    'expected (component, z, y, x)'], 'transposed extinction')
  end subroutine test_scene_dim_order

  subroutine test_scene_phase_index_type(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_scene_ptype.nc'
    type(result_set_t) :: set

    call scene_like_set(set, 'm-1')
    call add_var(set, 'phase_index', 'stored as double', '', &
                 [character(len=9) :: 'x', 'y', 'z', 'component'], &
                 spread(1.0_dp, 1, NX*NY*NZ*NC))
    call expect_written_scene_error(error, PATH, set, [character(len=80) :: ':phase_index)', &
                                    'integer type'], 'double phase_index')
  end subroutine test_scene_phase_index_type

  subroutine test_scene_missing_file(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_no_such_scene.nc'
    call remove_file(PATH)
    call expect_scene_error(error, PATH, NZ, [character(len=80) :: 'read_scene_3d('//PATH//')', &
                            'No such file'], 'missing file')
  end subroutine test_scene_missing_file

  ! ------------------------------------------------------------------------------------------------
  ! Albedo maps and attributes
  ! ------------------------------------------------------------------------------------------------

  subroutine test_albedo_round_trip(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_albedo.nc'
    type(error_t), allocatable :: err
    real(wp), allocatable :: albedo(:, :)
    integer :: nxs, nys, i

    ! includes exactly 0 and 1
    call albedo_round_trip(error, PATH, 'sfc_albedo', 5, 4, [(real(i - 1, dp)/19.0_dp, i=1, 20)], &
                           albedo)
    if (allocated(error)) return

    ! A blank name means the default "albedo", absent here.
    call read_albedo_map(PATH, '', nxs, nys, albedo, err)
    call check_message(error, err, [character(len=80) :: 'read_albedo_map('//PATH//':albedo)', &
                                    'not found'], 'default variable name')
    call check(error, .not. allocated(albedo), 'albedo allocated after an error')
    call remove_file(PATH)
  end subroutine test_albedo_round_trip

  subroutine test_albedo_errors(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_albedo_bad.nc'
    type(error_t), allocatable :: err
    real(wp), allocatable :: albedo(:, :)
    real(dp) :: values(6)
    integer :: nxs, nys

    values = 0.2_dp
    values(2) = 1.5_dp                                    ! (xs, ys) = (2, 1)
    call write_albedo_map(error, PATH, 'albedo', 3, 2, values)
    if (allocated(error)) return
    call read_albedo_map(PATH, 'albedo', nxs, nys, albedo, err)
    call check_message(error, err, [character(len=80) :: 'read_albedo_map('//PATH//':albedo)', &
                                    'value 1.5', '(xs,ys) = (2,1)', 'must be <= 1'], 'albedo 1.5')
    call check(error, nxs == 0 .and. nys == 0, 'sizes not reset after an error')
    call read_albedo_map('test_netcdf_no_such_map.nc', 'albedo', nxs, nys, albedo, err)
    call check_message(error, err, [character(len=80) :: 'test_netcdf_no_such_map.nc', &
                                    'No such file'], 'missing map file')
    call remove_file(PATH)
  end subroutine test_albedo_errors

  subroutine test_text_attr_missing(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: PATH = 'test_netcdf_attr.nc'
    type(result_set_t) :: set
    type(error_t), allocatable :: err
    character(len=:), allocatable :: text

    call sample_set(set)
    call write_set(error, PATH, set)
    if (allocated(error)) return
    call read_text_attr(PATH, 'no_such_attribute', text, err)
    call check_message(error, err, [character(len=80) :: PATH//':no_such_attribute)', &
                                    'not found'], 'missing attribute')
    call remove_file(PATH)
  end subroutine test_text_attr_missing

  ! ------------------------------------------------------------------------------------------------
  ! Helpers
  ! ------------------------------------------------------------------------------------------------

  !> Dimensions with and without coordinates; scalar, 1-D and 3-D variables with and without
  !> standard errors; global attributes (one empty).
  subroutine sample_set(set)
    type(result_set_t), intent(out) :: set
    real(dp) :: heating(24), heating_se(24)
    integer :: i

    heating = [(0.25_dp*i - 3.0_dp, i=1, 24)]
    heating_se = [(0.01_dp*i, i=1, 24)]
    call add_dim(set, 'x', 3, coord=[500.0_dp, 1500.0_dp, 2500.0_dp], units='m', &
                 long_name='x coordinate of the column centre')
    call add_dim(set, 'y', 2, coord=[500.0_dp, 1500.0_dp], units='m', &
                 long_name='y coordinate of the column centre')
    call add_dim(set, 'level', 4)
    call add_var(set, 'albedo_mean', 'domain-mean albedo', '1', NO_DIMS, [0.3_dp], [0.01_dp])
    call add_var(set, 'n_photons', 'number of photons traced', '1', NO_DIMS, [1.0e6_dp])
    call add_var(set, 'flux_up', 'upward flux at the top', 'W m-2', ['x'], &
                 [101.5_dp, 99.25_dp, 100.0_dp], [0.5_dp, 0.25_dp, 0.0_dp])
    call add_var(set, 'heating', 'heating rate', 'K d-1', [character(len=5) :: 'x', 'y', 'level'], &
                 heating, heating_se)
    call add_attr(set, 'title', 'kumo unit test')
    call add_attr(set, 'comment', '')
  end subroutine sample_set

  !> A small (NX, NY, NZ, NC) scene whose values depend on every index, so any transposition
  !> shows.
  subroutine sample_scene(scene)
    type(scene_t), intent(out) :: scene
    integer :: ix, iy, iz, ic
    allocate (scene%ext(NX, NY, NZ, NC), scene%ssa(NX, NY, NZ, NC), scene%phase(NX, NY, NZ, NC))
    do ic = 1, NC
      do iz = 1, NZ
        do iy = 1, NY
          do ix = 1, NX
            scene%ext(ix, iy, iz, ic) = 1.0e-4_wp*(ix + 10*iy + 100*iz + 1000*ic)
            scene%ssa(ix, iy, iz, ic) = real(ix + NX*(iy - 1), wp)/real(NX*NY, wp)  ! 1/6 .. 1
            scene%phase(ix, iy, iz, ic) = ic + NC*(iz - 1)
          end do
        end do
      end do
    end do
    scene%ext(1, 1, 1, 1) = 0.0_wp                       ! a clear voxel
    scene%ssa(1, 1, 1, 2) = 0.0_wp                       ! a purely absorbing component
    scene%has_phase = .true.
  end subroutine sample_scene

  !> A scene-like file made through write_results (which checks nothing scene-specific), to
  !> produce broken scene files.
  subroutine scene_like_set(set, ext_units, with_ssa, ssa_units, reversed)
    type(result_set_t), intent(out) :: set
    character(len=*), intent(in) :: ext_units
    logical, intent(in), optional :: with_ssa
    character(len=*), intent(in), optional :: ssa_units
    logical, intent(in), optional :: reversed
    type(scene_t) :: scene
    character(len=9) :: names(4)
    logical :: add_ssa

    call sample_scene(scene)
    names = [character(len=9) :: 'x', 'y', 'z', 'component']
    if (present(reversed)) then
      if (reversed) names = names(4:1:-1)
    end if
    add_ssa = .true.
    if (present(with_ssa)) add_ssa = with_ssa
    call add_dim(set, 'x', NX)
    call add_dim(set, 'y', NY)
    call add_dim(set, 'z', NZ)
    call add_dim(set, 'component', NC)
    call add_var(set, 'extinction', 'volume extinction coefficient', ext_units, names, &
                 flat(scene%ext))
    if (add_ssa) then
      if (present(ssa_units)) then
        call add_var(set, 'ssa', 'single-scattering albedo', ssa_units, names, flat(scene%ssa))
      else
        call add_var(set, 'ssa', 'single-scattering albedo', '1', names, flat(scene%ssa))
      end if
    end if
  end subroutine scene_like_set

  !> Position of (ix, iy, iz, ic) in a flattened (NX, NY, NZ, NC) array.
  pure integer function flat_index(ix, iy, iz, ic)
    integer, intent(in) :: ix, iy, iz, ic
    flat_index = ix + NX*((iy - 1) + NY*((iz - 1) + NZ*(ic - 1)))
  end function flat_index

  !> The values of a 4-D field in Fortran (file) order.
  pure function flat(field) result(values)
    real(wp), intent(in) :: field(:, :, :, :)
    real(wp) :: values(size(field))
    values = reshape(field, [size(field)])
  end function flat

  !> write_results of `set` to `path` (an old file removed first) must succeed.
  subroutine write_set(error, path, set)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path
    type(result_set_t), intent(in) :: set
    type(error_t), allocatable :: err
    call remove_file(path)
    call write_results(path, set, err)
    call check_no_error(error, err, 'write_results')
  end subroutine write_set

  !> write_scene_3d of `scene` to `path` (an old file removed first; without phase_index when
  !> scene%phase is not allocated) must succeed; `what` names the call in the message.
  subroutine write_scene(error, path, scene, what, ext_units)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path
    type(scene_t), intent(in) :: scene
    character(len=*), intent(in) :: what
    character(len=*), intent(in), optional :: ext_units
    type(error_t), allocatable :: err
    call remove_file(path)
    call write_scene_3d(path, scene%ext, scene%ssa, scene%phase, err, ext_units)
    call check_no_error(error, err, what)
  end subroutine write_scene

  !> read_scene_3d of an (NX, NY, NZ, NC) scene must succeed; `what` names the call.
  subroutine read_scene(error, path, scene, what)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path
    type(scene_t), intent(out) :: scene
    character(len=*), intent(in) :: what
    type(error_t), allocatable :: err
    call read_scene_3d(path, NX, NY, NZ, NC, scene%ext, scene%ssa, scene%phase, &
                       scene%has_phase, err)
    call check_no_error(error, err, what)
  end subroutine read_scene

  !> read_var_1d of `name` must succeed and give `expected` to within `rel_tol` (default 0).
  subroutine read_and_compare(error, path, name, expected, rel_tol, label)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path, name
    real(dp), intent(in) :: expected(:)
    real(dp), intent(in), optional :: rel_tol
    character(len=*), intent(in), optional :: label  !! in the message; default `name`
    real(dp), allocatable :: values(:)
    type(error_t), allocatable :: err
    real(dp) :: tol
    tol = 0.0_dp
    if (present(rel_tol)) tol = rel_tol
    call read_var_1d(path, name, values, err)
    call check_no_error(error, err, 'read_var_1d '//name)
    if (allocated(error)) return
    if (present(label)) then
      call check_values(error, values, expected, tol, label)
    else
      call check_values(error, values, expected, tol, name)
    end if
  end subroutine read_and_compare

  !> The global text attribute `name` must read back as exactly `expected` (same length too).
  subroutine check_text_attr(error, path, name, expected)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path, name, expected
    character(len=:), allocatable :: text
    type(error_t), allocatable :: err
    call read_text_attr(path, name, text, err)
    call check_no_error(error, err, 'read_text_attr '//name)
    if (allocated(error)) return
    call check(error, text == expected .and. len(text) == len(expected), &
               name//' = "'//text//'", expected "'//expected//'"')
  end subroutine check_text_attr

  !> read_scene_3d must fail with a message containing every piece, and leave nothing allocated.
  subroutine expect_scene_error(error, path, nz3, pieces, what)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path
    integer, intent(in) :: nz3
    character(len=*), intent(in) :: pieces(:)
    character(len=*), intent(in) :: what
    type(scene_t) :: scene
    type(error_t), allocatable :: err

    call read_scene_3d(path, NX, NY, nz3, NC, scene%ext, scene%ssa, scene%phase, &
                       scene%has_phase, err)
    call check_message(error, err, pieces, what)
    call check(error, .not. (allocated(scene%ext) .or. allocated(scene%ssa) .or. &
                             allocated(scene%phase) .or. scene%has_phase), &
               what//': outputs left allocated after an error')
  end subroutine expect_scene_error

  !> `set` written to `path` with write_results (which must succeed) is a scene file that
  !> read_scene_3d must reject as expect_scene_error says; the file is removed afterwards.
  subroutine expect_written_scene_error(error, path, set, pieces, what)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: pieces(:)
    character(len=*), intent(in) :: what
    call write_set(error, path, set)
    if (allocated(error)) return
    call expect_scene_error(error, path, NZ, pieces, what)
    call remove_file(path)
  end subroutine expect_written_scene_error

  !> A scene-like file whose variable `ivar` (1 extinction, 2 ssa) holds `value` at voxel
  !> `at` = (x, y, z, component) must be rejected as expect_scene_error says.
  subroutine expect_bad_scene_value(error, path, ext_units, ivar, at, value, pieces, what)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path, ext_units
    integer, intent(in) :: ivar, at(4)
    real(dp), intent(in) :: value
    character(len=*), intent(in) :: pieces(:)
    character(len=*), intent(in) :: what
    type(result_set_t) :: set
    call scene_like_set(set, ext_units)
    set%vars(ivar)%mean(flat_index(at(1), at(2), at(3), at(4))) = value
    call expect_written_scene_error(error, path, set, pieces, what)
  end subroutine expect_bad_scene_value

  !> An albedo map `name` on (xs, ys) of sizes (nxs, nys), values in Fortran order, written with
  !> write_results (which must succeed).
  subroutine write_albedo_map(error, path, name, nxs, nys, values)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: nxs, nys
    real(dp), intent(in) :: values(:)
    type(result_set_t) :: set
    call add_dim(set, 'xs', nxs)
    call add_dim(set, 'ys', nys)
    call add_var(set, name, 'surface albedo', '1', [character(len=2) :: 'xs', 'ys'], values)
    call write_set(error, path, set)
  end subroutine write_albedo_map

  !> The map written by write_albedo_map must read back with read_albedo_map with its sizes,
  !> shape and values unchanged.
  subroutine albedo_round_trip(error, path, name, nxs, nys, values, albedo)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path, name
    integer, intent(in) :: nxs, nys
    real(dp), intent(in) :: values(:)
    real(wp), allocatable, intent(out) :: albedo(:, :)
    type(error_t), allocatable :: err
    integer :: nxs_in, nys_in
    call write_albedo_map(error, path, name, nxs, nys, values)
    if (allocated(error)) return
    call read_albedo_map(path, name, nxs_in, nys_in, albedo, err)
    call check_no_error(error, err, 'read_albedo_map')
    if (allocated(error)) return
    call check(error, nxs_in == nxs .and. nys_in == nys, 'map size is not ('// &
               str(nxs)//', '//str(nys)//')')
    call check(error, all(shape(albedo) == [nxs, nys]), 'albedo has the wrong shape')
    if (allocated(error)) return
    call check_values(error, reshape(albedo, [size(albedo)]), values, 0.0_dp, 'albedo')
  end subroutine albedo_round_trip

  !> `err` must be unallocated; otherwise fail with its message.
  subroutine check_no_error(error, err, what)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: what
    if (.not. allocated(err)) return
    call check(error, .false., what//' failed: '//err%message)
  end subroutine check_no_error

  !> `err` must be allocated and its message must contain every (trimmed) piece.
  subroutine check_message(error, err, pieces, what)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: pieces(:)
    character(len=*), intent(in) :: what
    integer :: i
    call check(error, allocated(err), what//': no error reported')
    if (allocated(error)) return
    do i = 1, size(pieces)
      call check(error, index(err%message, trim(pieces(i))) > 0, what//': message "'// &
                 err%message//'" does not contain "'//trim(pieces(i))//'"')
    end do
  end subroutine check_message

  !> Same size and |actual - expected| <= rel_tol*|expected| element by element.
  subroutine check_values(error, actual, expected, rel_tol, label)
    type(error_t), allocatable, intent(inout) :: error
    real(dp), intent(in) :: actual(:), expected(:)
    real(dp), intent(in) :: rel_tol
    character(len=*), intent(in) :: label
    character(len=12) :: buffer
    integer :: i
    call check(error, size(actual) == size(expected), label//': wrong number of values')
    if (allocated(error)) return
    do i = 1, size(actual)
      if (abs(actual(i) - expected(i)) <= rel_tol*abs(expected(i))) cycle
      write (buffer, '(i0)') i
      call check(error, .false., label//': values differ at flat index '//trim(buffer))
      return
    end do
  end subroutine check_values

  logical function file_exists(path)
    character(len=*), intent(in) :: path
    inquire (file=path, exist=file_exists)
  end function file_exists

  subroutine remove_file(path)
    character(len=*), intent(in) :: path
    integer :: unit, ios
    if (.not. file_exists(path)) return
    open (newunit=unit, file=path, status='old', iostat=ios)
    if (ios /= 0) return                  ! the test that needs the file gone reports it
    close (unit, status='delete', iostat=ios)
    if (ios /= 0) return
  end subroutine remove_file
end module test_kumo_netcdf

program test_netcdf
  use test_kumo_netcdf, only: collect_netcdf
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_netcdf', collect_netcdf(), n_failed)
  if (n_failed > 0) error stop 1
end program test_netcdf
