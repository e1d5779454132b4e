! SPDX-License-Identifier: BSD-3-Clause
!> The reference namelist and the namelist documentation cannot drift from the code.
!>
!> namelists/reference.nml must read and validate, every value in it except the marked
!> exceptions (nz, z_levels, the output file name) must equal the default in the code, and every
!> variable of every namelist statement in the configuration's sources (src/io/kumo_config.F90
!> and its modules of one group each, src/io/config/) must be listed in it (inside its own
!> group, in the code's group order) and have a row in its group's table in docs/namelist.md,
!> whose default column must match the code for the scalar settings.
!>
!> Command line: the paths of reference.nml, of the configuration's sources (in the order of
!> their groups) and of namelist.md, in that order.
module test_reference_nml_suite
  use kumo_kinds, only: wp, dp, i8
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  use kumo_config, only: config_t, read_config, config_echo
  use kumo_error, only: str, to_lower
  use kumo_driver, only: scene_t, setup_scene
  implicit none
  private
  public :: collect_reference_nml, set_paths

  integer, parameter :: LINE_LEN = 4096
  !> Output file written in reference.nml (the default is 'kumo_out.nc').
  character(len=*), parameter :: REF_OUTPUT_FILE = 'reference_out.nc'
  !> Variables that reference.nml lists only as a commented-out assignment, because setting
  !> them would change the defaults (air_density needs solar_flux > 0; the default of
  !> flux_levels is "all levels", which has no literal form, and that of map_levels is "the flux
  !> levels").
  character(len=16), parameter :: NAMES_COMMENTED(5) = [character(len=16) :: 'air_density', &
                                                       'flux_levels', 'map_levels', &
                                                       'planck_levels', 'planck_surface']

  character(len=:), allocatable :: ref_path, config_src_path, doc_path
  !> every source file of the configuration (config_src_path: their names, for messages)
  character(len=4096), allocatable :: config_src_paths(:)

  !> Namelist variable names found in the code, with their group.
  type :: nml_var_t
    character(len=32) :: group = ''
    character(len=32) :: name = ''
  end type nml_var_t

contains

  subroutine set_paths(ref, src, doc)
    character(len=*), intent(in) :: ref, src(:), doc
    integer :: i
    ref_path = ref
    config_src_paths = src
    config_src_path = trim(src(1))
    do i = 2, size(src)
      config_src_path = config_src_path//', '//trim(src(i))
    end do
    doc_path = doc
  end subroutine set_paths

  function collect_reference_nml() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('reference_reads_and_validates', test_validates), &
             new_unittest('reference_scalars_equal_type_defaults', test_type_defaults), &
             new_unittest('reference_equals_minimal_namelist', test_minimal), &
             new_unittest('every_variable_in_reference', test_names_in_reference), &
             new_unittest('every_variable_in_namelist_doc', test_names_in_doc), &
             new_unittest('doc_defaults_equal_code', test_doc_defaults)]
  end function collect_reference_nml

  ! --- tests -------------------------------------------------------------------------------

  subroutine test_validates(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(scene_t) :: scene
    call read_config(ref_path, cfg, error)
    if (allocated(error)) then
      error%message = ref_path//' does not validate: '//error%message
      return
    end if
    call check(error, cfg%atm%nz == 1, 'reference.nml must describe one layer (nz = 1)')
    call check(error, trim(cfg%output%file) == REF_OUTPUT_FILE, &
               'reference.nml must write '//REF_OUTPUT_FILE)
    if (allocated(error)) return
    call setup_scene(cfg, scene, error)
    if (allocated(error)) error%message = ref_path//': scene setup failed: '//error%message
  end subroutine test_validates

  !> Every scalar setting read from reference.nml equals the default-initialised config_t.
  subroutine test_type_defaults(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: r, d
    call read_config(ref_path, r, error)
    if (allocated(error)) return
    associate (rc => r%control, dc => d%control)
      call check_i8(error, rc%n_photons_per_batch, dc%n_photons_per_batch, 'n_photons_per_batch')
      call check_int(error, rc%n_batches, dc%n_batches, 'n_batches')
      call check_i8(error, rc%seed, dc%seed, 'seed')
      call check_real(error, rc%target_rel_error, dc%target_rel_error, 'target_rel_error')
      call check_str(error, rc%target_output, dc%target_output, 'target_output')
      call check_i8(error, rc%max_photons, dc%max_photons, 'max_photons')
      call check_i8(error, rc%max_events, dc%max_events, 'max_events')
      call check_int(error, rc%verbose, dc%verbose, 'verbose')
    end associate
    associate (ra => r%atm, da => d%atm)
      ! nz has no usable default (0 is invalid): reference.nml sets 1
      call check_int(error, ra%nz, 1, 'nz')
      call check_real(error, ra%lx, da%lx, 'lx')
      call check_real(error, ra%ly, da%ly, 'ly')
      call check_int(error, ra%n_components, da%n_components, 'n_components')
      call check_str(error, ra%scene_file, da%scene_file, 'scene_file')
      call check_int(error, ra%k3d_bottom, da%k3d_bottom, 'k3d_bottom')
      call check_int(error, ra%nx, da%nx, 'nx')
      call check_int(error, ra%ny, da%ny, 'ny')
      call check_int(error, ra%nz3, da%nz3, 'nz3')
      call check_int(error, ra%n_components_3d, da%n_components_3d, 'n_components_3d')
      call check_real(error, ra%cp_air, da%cp_air, 'cp_air')
      call check(error, .not. allocated(ra%air_density), &
                 'air_density must not be set in reference.nml (default: not given)')
    end associate
    call check_int(error, r%phase%n_phase, d%phase%n_phase, 'n_phase')
    call check_int(error, r%phase%n_table, d%phase%n_table, 'n_table')
    call check_real(error, r%surface%albedo, d%surface%albedo, 'albedo')
    call check_str(error, r%surface%albedo_file, d%surface%albedo_file, 'albedo_file')
    call check_str(error, r%surface%albedo_var, d%surface%albedo_var, 'albedo_var')
    call check_real(error, r%source%sza_deg, d%source%sza_deg, 'sza_deg')
    call check_real(error, r%source%phi0_deg, d%source%phi0_deg, 'phi0_deg')
    call check_real(error, r%source%solar_flux, d%source%solar_flux, 'solar_flux')
    ! the output file is the one deliberate exception
    call check_str(error, r%output%file, REF_OUTPUT_FILE, 'file')
    call check_log(error, r%output%column_fluxes, d%output%column_fluxes, 'column_fluxes')
    call check_log(error, r%output%voxel_absorption, d%output%voxel_absorption, 'voxel_absorption')
    associate (rv => r%vr, dv => d%vr)
      call check_real(error, rv%rr_threshold, dv%rr_threshold, 'rr_threshold')
      call check_real(error, rv%rr_weight, dv%rr_weight, 'rr_weight')
      call check_log(error, rv%use_supervoxels, dv%use_supervoxels, 'use_supervoxels')
      call check_real(error, rv%sv_fsupg, dv%sv_fsupg, 'sv_fsupg')
      call check_real(error, rv%sv_fsupi, dv%sv_fsupi, 'sv_fsupi')
      call check_int(error, rv%sv_max_layers, dv%sv_max_layers, 'sv_max_layers')
      call check_log(error, rv%use_1d_layers, dv%use_1d_layers, 'use_1d_layers')
      call check_log(error, rv%use_absorbing_layers, dv%use_absorbing_layers, &
                     'use_absorbing_layers')
    end associate
  end subroutine test_type_defaults

  !> reference.nml gives the same configuration as a namelist holding only its exceptions (nz,
  !> z_levels, file): so the array defaults, which the reader sets, are written correctly too.
  subroutine test_minimal(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: r, m
    character(len=*), parameter :: MIN_PATH = 'reference_minimal.nml'
    integer :: unit, k
    call read_config(ref_path, r, error)
    if (allocated(error)) return
    open (newunit=unit, file=MIN_PATH, status='replace', action='write')
    write (unit, '(a)') '&kumo_atmosphere'
    write (unit, '(a,i0)') '  nz = ', r%atm%nz
    write (unit, '(a)', advance='no') '  z_levels ='
    ! config_t%atm%z holds levels 0..nz in elements 1..nz + 1
    do k = 1, size(r%atm%z)
      if (k > 1) write (unit, '(a)', advance='no') ','
      write (unit, '(1x,es25.17e3)', advance='no') r%atm%z(k)
    end do
    write (unit, '(a)') ''
    write (unit, '(a)') '/'
    write (unit, '(a)') '&kumo_output'
    write (unit, '(a)') "  file = '"//REF_OUTPUT_FILE//"'"
    write (unit, '(a)') '/'
    close (unit)
    call read_config(MIN_PATH, m, error)
    if (allocated(error)) then
      error%message = 'minimal namelist: '//error%message
      return
    end if
    call check(error, config_echo(r) == config_echo(m), &
               'configuration echo of reference.nml differs from the defaults:'//new_line('a')// &
               first_difference(config_echo(r), config_echo(m)))
    call check_same(error, r%atm%z, m%atm%z, 'z_levels')
    call check(error, all(shape(r%atm%ext1d) == shape(m%atm%ext1d)), 'shape of ext1d')
    if (allocated(error)) return
    call check_same(error, pack(r%atm%ext1d, .true.), pack(m%atm%ext1d, .true.), 'ext1d')
    call check_same(error, pack(r%atm%ssa1d, .true.), pack(m%atm%ssa1d, .true.), 'ssa1d')
    call check(error, all(r%atm%phase1d == m%atm%phase1d), 'phase1d differs from its default')
    call check(error, size(r%atm%phase3d) == size(m%atm%phase3d), 'size of phase3d')
    if (allocated(error)) return
    call check(error, all(r%atm%phase3d == m%atm%phase3d), 'phase3d differs from its default')
    call check(error, allocated(r%atm%air_density) .eqv. allocated(m%atm%air_density), &
               'air_density')
    call check(error, all(r%phase%kind == m%phase%kind), 'phase_kind differs from its default')
    call check(error, all(r%phase%kind_name == m%phase%kind_name), 'phase_kind name')
    call check_same(error, r%phase%g, m%phase%g, 'phase_g')
    call check(error, all(r%phase%file == m%phase%file), 'phase_file differs from its default')
    call check(error, size(r%output%flux_levels) == size(m%output%flux_levels), &
               'number of flux_levels')
    if (allocated(error)) return
    call check(error, all(r%output%flux_levels == m%output%flux_levels), &
               'flux_levels differs from its default')
    call check(error, all(r%output%map_level_list() == m%output%map_level_list()), &
               'map_levels differs from its default')
    open (newunit=unit, file=MIN_PATH, status='old')
    close (unit, status='delete')
  end subroutine test_minimal

  !> Every namelist variable of the code is assigned in reference.nml, inside its group, and the
  !> groups come in the code's order.
  subroutine test_names_in_reference(error)
    type(error_t), allocatable, intent(out) :: error
    type(nml_var_t), allocatable :: vars(:)
    character(len=:), allocatable :: missing, groups_code, groups_ref, group, s
    character(len=LINE_LEN), allocatable :: lines(:)
    logical :: found, commented_only
    integer :: i, j
    call namelist_vars(vars, groups_code, error)
    if (allocated(error)) return
    call read_lines(ref_path, lines, error)
    if (allocated(error)) return
    ! group order
    groups_ref = ''
    do j = 1, size(lines)
      s = trim(adjustl(to_lower(lines(j))))
      if (len(s) > 1 .and. s(1:1) == '&') groups_ref = groups_ref//' '//first_word(s(2:))
    end do
    call check(error, groups_ref == groups_code, 'groups of reference.nml are "'//groups_ref// &
               '", expected "'//groups_code//'" (the order of kumo_config)')
    if (allocated(error)) return
    missing = ''
    do i = 1, size(vars)
      commented_only = any(NAMES_COMMENTED == vars(i)%name)
      found = .false.
      group = ''
      do j = 1, size(lines)
        s = trim(adjustl(to_lower(lines(j))))
        if (len(s) == 0) cycle
        if (s(1:1) == '&') then
          group = first_word(s(2:))
          cycle
        end if
        if (s(1:1) == '/') then
          group = ''
          cycle
        end if
        if (group /= trim(vars(i)%group)) cycle
        if (commented_only) then
          if (s(1:1) /= '!') cycle
          s = trim(adjustl(s(2:)))
        end if
        if (is_assignment(s, trim(vars(i)%name))) found = .true.
      end do
      if (.not. found) missing = missing//' '//trim(vars(i)%group)//'.'//trim(vars(i)%name)
    end do
    call check(error, len(missing) == 0, 'not assigned in its group of reference.nml'// &
               ' (commented out for '//trim(NAMES_COMMENTED(1))//', '//trim(NAMES_COMMENTED(2))// &
               '):'//missing)
  end subroutine test_names_in_reference

  !> Every namelist variable of the code has a table row in its group's section of namelist.md.
  subroutine test_names_in_doc(error)
    type(error_t), allocatable, intent(out) :: error
    type(nml_var_t), allocatable :: vars(:)
    character(len=:), allocatable :: missing, groups_code, group
    character(len=LINE_LEN), allocatable :: lines(:)
    logical :: found
    integer :: i, j
    call namelist_vars(vars, groups_code, error)
    if (allocated(error)) return
    call read_lines(doc_path, lines, error)
    if (allocated(error)) return
    missing = ''
    do i = 1, size(vars)
      found = .false.
      group = ''
      do j = 1, size(lines)
        if (lines(j)(1:1) == '#') group = doc_group(lines(j))
        if (group /= trim(vars(i)%group)) cycle
        if (index(lines(j), '| `'//trim(vars(i)%name)//'` |') == 1) found = .true.
      end do
      if (.not. found) missing = missing//' '//trim(vars(i)%group)//'.'//trim(vars(i)%name)
    end do
    call check(error, len(missing) == 0, 'no table row "| `name` |" in the section of its '// &
               'group in namelist.md:'//missing)
  end subroutine test_names_in_doc

  !> The default column of namelist.md equals the code's defaults for the scalar settings.
  subroutine test_doc_defaults(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: d
    character(len=LINE_LEN), allocatable :: lines(:)
    call read_lines(doc_path, lines, error)
    if (allocated(error)) return
    associate (c => d%control)
      call doc_num(lines, 'n_photons_per_batch', real(c%n_photons_per_batch, dp), error)
      call doc_num(lines, 'n_batches', real(c%n_batches, dp), error)
      call doc_num(lines, 'seed', real(c%seed, dp), error)
      call doc_num(lines, 'target_rel_error', c%target_rel_error, error)
      call doc_str(lines, 'target_output', c%target_output, error)
      call doc_num(lines, 'max_photons', real(c%max_photons, dp), error)
      call doc_num(lines, 'max_events', real(c%max_events, dp), error)
      call doc_num(lines, 'verbose', real(c%verbose, dp), error)
    end associate
    associate (a => d%atm)
      call doc_num(lines, 'lx', a%lx, error)
      call doc_num(lines, 'ly', a%ly, error)
      call doc_num(lines, 'n_components', real(a%n_components, dp), error)
      call doc_str(lines, 'scene_file', a%scene_file, error)
      call doc_num(lines, 'k3d_bottom', real(a%k3d_bottom, dp), error)
      call doc_num(lines, 'nx', real(a%nx, dp), error)
      call doc_num(lines, 'ny', real(a%ny, dp), error)
      call doc_num(lines, 'nz3', real(a%nz3, dp), error)
      call doc_num(lines, 'n_components_3d', real(a%n_components_3d, dp), error)
      call doc_num(lines, 'cp_air', a%cp_air, error)
    end associate
    call doc_num(lines, 'n_phase', real(d%phase%n_phase, dp), error)
    call doc_num(lines, 'n_table', real(d%phase%n_table, dp), error)
    call doc_num(lines, 'albedo', d%surface%albedo, error)
    call doc_str(lines, 'albedo_file', d%surface%albedo_file, error)
    call doc_str(lines, 'albedo_var', d%surface%albedo_var, error)
    call doc_num(lines, 'sza_deg', d%source%sza_deg, error)
    call doc_num(lines, 'phi0_deg', d%source%phi0_deg, error)
    call doc_num(lines, 'solar_flux', d%source%solar_flux, error)
    call doc_str(lines, 'file', d%output%file, error)
    call doc_log(lines, 'column_fluxes', d%output%column_fluxes, error)
    call doc_log(lines, 'voxel_absorption', d%output%voxel_absorption, error)
    associate (v => d%vr)
      call doc_num(lines, 'rr_threshold', v%rr_threshold, error)
      call doc_num(lines, 'rr_weight', v%rr_weight, error)
      call doc_log(lines, 'use_supervoxels', v%use_supervoxels, error)
      call doc_num(lines, 'sv_fsupg', v%sv_fsupg, error)
      call doc_num(lines, 'sv_fsupi', v%sv_fsupi, error)
      call doc_num(lines, 'sv_max_layers', real(v%sv_max_layers, dp), error)
      call doc_log(lines, 'use_1d_layers', v%use_1d_layers, error)
      call doc_log(lines, 'use_absorbing_layers', v%use_absorbing_layers, error)
    end associate
  end subroutine test_doc_defaults

  ! --- comparisons -------------------------------------------------------------------------

  !> Two real arrays are equal element by element (exactly).
  subroutine check_same(error, actual, expected, name)
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(in) :: actual(:), expected(:)
    character(len=*), intent(in) :: name
    integer :: i
    call check(error, size(actual) == size(expected), 'size of '//name)
    if (allocated(error)) return
    do i = 1, size(actual)
      call check_close(error, actual(i), expected(i), abs_tol=0.0_wp, rel_tol=0.0_wp, &
                       label=name//' in reference.nml differs from its default')
    end do
  end subroutine check_same

  subroutine check_int(error, actual, expected, name)
    type(error_t), allocatable, intent(inout) :: error
    integer, intent(in) :: actual, expected
    character(len=*), intent(in) :: name
    character(len=24) :: a, e
    write (a, '(i0)') actual
    write (e, '(i0)') expected
    call check(error, actual == expected, name//' = '//trim(a)//' in reference.nml, code: '//trim(e))
  end subroutine check_int

  subroutine check_i8(error, actual, expected, name)
    type(error_t), allocatable, intent(inout) :: error
    integer(i8), intent(in) :: actual, expected
    character(len=*), intent(in) :: name
    character(len=24) :: a, e
    write (a, '(i0)') actual
    write (e, '(i0)') expected
    call check(error, actual == expected, name//' = '//trim(a)//' in reference.nml, code: '//trim(e))
  end subroutine check_i8

  subroutine check_real(error, actual, expected, name)
    type(error_t), allocatable, intent(inout) :: error
    real(wp), intent(in) :: actual, expected
    character(len=*), intent(in) :: name
    call check_close(error, actual, expected, label=name//' in reference.nml vs code default')
  end subroutine check_real

  subroutine check_str(error, actual, expected, name)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: actual, expected
    character(len=*), intent(in) :: name
    call check(error, trim(actual) == trim(expected), name//" = '"//trim(actual)// &
               "' in reference.nml, code: '"//trim(expected)//"'")
  end subroutine check_str

  subroutine check_log(error, actual, expected, name)
    type(error_t), allocatable, intent(inout) :: error
    logical, intent(in) :: actual, expected
    character(len=*), intent(in) :: name
    call check(error, actual .eqv. expected, name//' in reference.nml differs from the code default')
  end subroutine check_log

  !> The default cell of the row of `name` in namelist.md, without backticks and blanks.
  function doc_default(lines, name, error) result(cell)
    character(len=*), intent(in) :: lines(:), name
    type(error_t), allocatable, intent(inout) :: error
    character(len=:), allocatable :: cell, rest
    integer :: j, k, p
    cell = ''
    if (allocated(error)) return
    do j = 1, size(lines)
      if (index(lines(j), '| `'//name//'` |') /= 1) cycle
      ! cells: | name | type | default | ...
      rest = trim(lines(j))
      do k = 1, 2
        p = index(rest(2:), '|')
        if (p == 0) exit
        rest = rest(p + 1:)
      end do
      p = index(rest(2:), '|')
      if (p == 0) exit
      cell = rest(2:p)
      do
        p = index(cell, '`')
        if (p == 0) exit
        cell = cell(1:p - 1)//cell(p + 1:)
      end do
      cell = trim(adjustl(cell))
      return
    end do
    call check(error, .false., 'namelist.md: no table row for '//name)
  end function doc_default

  subroutine doc_num(lines, name, expected, error)
    character(len=*), intent(in) :: lines(:), name
    real(dp), intent(in) :: expected
    type(error_t), allocatable, intent(inout) :: error
    character(len=:), allocatable :: cell
    real(dp) :: v
    integer :: ios
    cell = doc_default(lines, name, error)
    if (allocated(error)) return
    read (cell, *, iostat=ios) v
    call check(error, ios == 0, 'namelist.md: default of '//name//' is not a number: "'//cell//'"')
    if (allocated(error)) return
    call check_close(error, v, expected, label='namelist.md: default of '//name//' vs code')
  end subroutine doc_num

  subroutine doc_str(lines, name, expected, error)
    character(len=*), intent(in) :: lines(:), name, expected
    type(error_t), allocatable, intent(inout) :: error
    character(len=:), allocatable :: cell
    cell = doc_default(lines, name, error)
    if (allocated(error)) return
    call check(error, cell == "'"//trim(expected)//"'", 'namelist.md: default of '//name// &
               ' is "'//cell//'", code: '//"'"//trim(expected)//"'")
  end subroutine doc_str

  subroutine doc_log(lines, name, expected, error)
    character(len=*), intent(in) :: lines(:), name
    logical, intent(in) :: expected
    type(error_t), allocatable, intent(inout) :: error
    character(len=:), allocatable :: cell
    logical :: v
    integer :: ios
    cell = doc_default(lines, name, error)
    if (allocated(error)) return
    read (cell, *, iostat=ios) v
    call check(error, ios == 0, 'namelist.md: default of '//name//' is not a logical: "'//cell//'"')
    call check(error, v .eqv. expected, 'namelist.md: default of '//name//' differs from the code')
  end subroutine doc_log

  ! --- text helpers ------------------------------------------------------------------------

  !> Variables of every `namelist /group/ a, b, &` statement in the configuration's sources, and
  !> the groups in order as one blank-separated string.
  subroutine namelist_vars(vars, groups, error)
    type(nml_var_t), allocatable, intent(out) :: vars(:)
    character(len=:), allocatable, intent(out) :: groups
    type(error_t), allocatable, intent(out) :: error
    character(len=LINE_LEN), allocatable :: lines(:)
    character(len=LINE_LEN), allocatable :: more(:), both(:)
    character(len=:), allocatable :: s, group, list
    integer :: j, p, n_groups
    allocate (lines(0))
    do j = 1, size(config_src_paths)
      call read_lines(trim(config_src_paths(j)), more, error)
      if (allocated(error)) return
      allocate (both(size(lines) + size(more)))
      both(1:size(lines)) = lines
      both(size(lines) + 1:) = more
      call move_alloc(both, lines)
    end do
    allocate (vars(0))
    groups = ''
    n_groups = 0
    j = 0
    do while (j < size(lines))
      j = j + 1
      s = trim(adjustl(to_lower(lines(j))))
      if (index(s, 'namelist /') /= 1) cycle
      s = s(len('namelist /') + 1:)
      p = index(s, '/')
      group = trim(adjustl(s(1:p - 1)))
      list = s(p + 1:)
      ! continuation lines
      do while (len(list) > 0)
        if (list(len(list):len(list)) /= '&') exit
        list = list(1:len(list) - 1)
        j = j + 1
        list = list//trim(adjustl(to_lower(lines(j))))
      end do
      n_groups = n_groups + 1
      groups = groups//' '//group
      do
        p = index(list, ',')
        if (p == 0) then
          call add(trim(adjustl(list)))
          exit
        end if
        call add(trim(adjustl(list(1:p - 1))))
        list = list(p + 1:)
      end do
    end do
    call check(error, n_groups == 12 .and. size(vars) >= 60, 'found only '//str(n_groups)// &
               ' namelist statements and '//str(size(vars))//' variables in '//config_src_path)
  contains
    subroutine add(name)
      character(len=*), intent(in) :: name
      type(nml_var_t) :: v
      if (len(name) == 0) return
      v%group = group
      v%name = name
      vars = [vars, v]
    end subroutine add
  end subroutine namelist_vars

  !> All lines of a text file.
  subroutine read_lines(path, lines, error)
    character(len=*), intent(in) :: path
    character(len=LINE_LEN), allocatable, intent(out) :: lines(:)
    type(error_t), allocatable, intent(out) :: error
    character(len=LINE_LEN) :: buf
    character(len=512) :: msg
    integer :: unit, ios, n, pass
    open (newunit=unit, file=path, status='old', action='read', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call check(error, .false., 'cannot open '//path//': '//trim(msg))
      return
    end if
    do pass = 1, 2
      rewind (unit)
      n = 0
      do
        read (unit, '(a)', iostat=ios) buf
        if (ios /= 0) exit
        n = n + 1
        if (pass == 2) lines(n) = buf
      end do
      if (pass == 1) allocate (lines(n))
    end do
    close (unit)
  end subroutine read_lines

  !> Does `s` (lower case, no leading blanks) start with an assignment to `name`?
  pure logical function is_assignment(s, name) result(yes)
    character(len=*), intent(in) :: s, name
    character(len=:), allocatable :: rest
    yes = .false.
    if (len(s) <= len(name)) return
    if (s(1:len(name)) /= name) return
    if (scan(s(len(name) + 1:len(name) + 1), ' =(') == 0) return
    rest = adjustl(s(len(name) + 1:))
    if (len(rest) == 0) return
    if (rest(1:1) == '(') then
      yes = index(rest, ')') > 0 .and. index(rest, '=') > index(rest, ')')
    else
      yes = rest(1:1) == '='
    end if
  end function is_assignment

  !> Group named in a markdown heading such as "## `&kumo_control`: ...", '' if none.
  function doc_group(line) result(group)
    character(len=*), intent(in) :: line
    character(len=:), allocatable :: group
    integer :: p
    group = ''
    p = index(line, '&kumo_')
    if (p == 0) return
    group = first_word(to_lower(line(p + 1:)))
  end function doc_group

  !> Leading run of letters, digits and underscores.
  pure function first_word(s) result(w)
    character(len=*), intent(in) :: s
    character(len=:), allocatable :: w
    integer :: i
    w = ''
    do i = 1, len(s)
      if (verify(s(i:i), 'abcdefghijklmnopqrstuvwxyz0123456789_') /= 0) exit
      w = w//s(i:i)
    end do
  end function first_word



  !> The first line in which two multi-line texts differ, for messages.
  function first_difference(a, b) result(msg)
    character(len=*), intent(in) :: a, b
    character(len=:), allocatable :: msg
    character(len=1), parameter :: nl = new_line('a')
    integer :: ia, ib, ea, eb
    ia = 1
    ib = 1
    msg = ''
    do while (ia <= len(a) .and. ib <= len(b))
      ea = index(a(ia:), nl)
      eb = index(b(ib:), nl)
      if (ea == 0) ea = len(a) - ia + 2
      if (eb == 0) eb = len(b) - ib + 2
      if (a(ia:ia + ea - 2) /= b(ib:ib + eb - 2)) then
        msg = '  reference.nml: '//a(ia:ia + ea - 2)//nl//'  defaults:      '//b(ib:ib + eb - 2)
        return
      end if
      ia = ia + ea
      ib = ib + eb
    end do
  end function first_difference
end module test_reference_nml_suite

program test_reference_nml
  use kumo_testing, only: run_unittests
  use kumo_parallel, only: par_init, par_finalize
  use test_reference_nml_suite, only: collect_reference_nml, set_paths
  implicit none
  integer :: n_failed, n, i
  character(len=4096) :: ref, doc
  character(len=4096), allocatable :: src(:)
  call par_init()
  n = command_argument_count()
  if (n < 3) then
    write (*, '(a)') 'usage: test_reference_nml REFERENCE.nml KUMO_CONFIG.F90 [GROUP.F90 ...] '// &
      'NAMELIST.md'
    call par_finalize()
    error stop 2
  end if
  call get_command_argument(1, ref)
  allocate (src(n - 2))
  do i = 2, n - 1
    call get_command_argument(i, src(i - 1))
  end do
  call get_command_argument(n, doc)
  call set_paths(trim(ref), src, trim(doc))
  call run_unittests('reference_nml', collect_reference_nml(), n_failed)
  call par_finalize()
  if (n_failed > 0) error stop 1
end program test_reference_nml
