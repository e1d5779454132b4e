! SPDX-License-Identifier: BSD-3-Clause
!> Namelist layouts and namelist errors: every layout the compiler reads (tabs, several groups
!> on one line, `$group ... $end`) is accepted with the values it holds; misspelt, duplicated
!> or unclosed groups are refused with the line and the closest known name; a value that does
!> not read is reported with the group, the line, the variable and what the variable takes.
module test_config_layout_suite
  use kumo_kinds, only: wp, i8
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, &
                          check_error_words
  use kumo_test_text, only: write_text
  use kumo_config, only: config_t, read_config
  use kumo_nml_text, only: edit_distance, closest_name
  implicit none
  private
  public :: collect_config_layout

  character(len=1), parameter :: NL = new_line('a'), TAB = achar(9)
  character(len=*), parameter :: ATM = '&kumo_atmosphere nz = 1, z_levels = 0, 1000, '// &
                                       'ext1d(1,1) = 0.01 /'

contains

  function collect_config_layout() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('layouts_accepted', test_layouts), &
             new_unittest('group_errors', test_group_errors), &
             new_unittest('value_errors', test_value_errors), &
             new_unittest('edit_distance', test_distance)]
  end function collect_config_layout

  !> Read `text` as a namelist file; return the configuration or the error.
  subroutine read_text(text, cfg, err)
    character(len=*), intent(in) :: text
    type(config_t), intent(out) :: cfg
    type(error_t), allocatable, intent(out) :: err
    call write_text('layout.nml', text)
    call read_config('layout.nml', cfg, err)
  end subroutine read_text

  subroutine accepted(error, text, what, cfg)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: text, what
    type(config_t), intent(out) :: cfg
    type(error_t), allocatable :: err
    call read_text(text, cfg, err)
    if (allocated(err)) call check(error, .false., what//': '//err%message)
  end subroutine accepted

  subroutine test_layouts(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    ! tab-indented groups (formerly reported missing)
    call accepted(error, TAB//'&kumo_control'//NL//TAB//'n_batches = 7'//NL//TAB//'/'//NL// &
                  TAB//ATM//NL, 'tabs', cfg)
    if (allocated(error)) return
    call check(error, cfg%control%n_batches == 7 .and. cfg%atm%nz == 1, 'tabs: values read')
    ! several groups on one line
    call accepted(error, '&kumo_control n_batches = 6 / '//ATM//' &kumo_source sza_deg = 30 /'// &
                  NL, 'one line', cfg)
    if (allocated(error)) return
    call check(error, cfg%control%n_batches == 6, 'one line: n_batches')
    call check_close(error, cfg%source%sza_deg, 30.0_wp, abs_tol=0.0_wp, label='one line: sza')
    ! the old $group ... $end form, and comments with group-like text
    call accepted(error, '$kumo_control n_batches = 5 $end ! &kumo_sun is a comment'//NL// &
                  '$kumo_atmosphere nz = 1, z_levels = 0, 1000, ext1d(1,1) = 0.01 $end'//NL// &
                  '&kumo_output file = ''a&b/c.nc'' /'//NL, 'dollar form', cfg)
    if (allocated(error)) return
    call check(error, cfg%control%n_batches == 5, 'dollar form: n_batches')
    call check(error, trim(cfg%output%file) == 'a&b/c.nc', 'quoted & and / kept in a string')
    ! text outside groups is ignored, as the compiler does
    call accepted(error, 'case 12: a title line'//NL//'&kumo_control n_photons_per_batch = '// &
                  '3000000000 /'//NL//ATM//NL, 'title and a 64-bit count', cfg)
    call check(error, cfg%control%n_photons_per_batch == 3000000000_i8, '64-bit photon count')
  end subroutine test_layouts

  subroutine test_group_errors(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(error_t), allocatable :: err
    call read_text('&kumo_control n_batches = 4 /'//NL//ATM//NL//'&kumo_sourse sza_deg = 1 /'// &
                   NL, cfg, err)
    call check_error_words(error, err, [character(len=48) :: 'unknown namelist group &kumo_sourse', &
                                        '(line 3)', 'did you mean &kumo_source?'])
    call read_text('$kumo_contrl n_batches = 4 $end'//NL//ATM//NL, cfg, err)
    call check_error_words(error, err, [character(len=48) :: '&kumo_contrl', '(line 1)', &
                                        'did you mean &kumo_control?'])
    call read_text('&kumo_weather x = 1 /'//NL//ATM//NL, cfg, err)
    call check_error_words(error, err, [character(len=48) :: '&kumo_weather', 'known groups:'])
    call read_text(ATM//NL//'&kumo_control n_batches = 4 /'//NL//TAB//'&kumo_control seed = 3 /'// &
                   NL, cfg, err)
    call check_error_words(error, err, [character(len=48) :: '&kumo_control appears more than once', &
                                        '(lines 2 and 3)'])
    call read_text('&kumo_control n_batches = 4'//NL//ATM//NL, cfg, err)
    call check_error_words(error, err, [character(len=64) :: '&kumo_control (line 1)', &
                                        'not closed with / before &kumo_atmosphere (line 2)'])
    call read_text(ATM//NL//'&kumo_control n_batches = 4'//NL, cfg, err)
    call check_error_words(error, err, [character(len=48) :: '&kumo_control (line 2)', &
                                        'no closing /'])
  end subroutine test_group_errors

  subroutine test_value_errors(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(error_t), allocatable :: err
    ! integer overflow of a default integer
    call read_text(ATM//NL//'&kumo_control'//NL//'  n_batches = 99999999999'//NL//'/'//NL, cfg, err)
    call check_error_words(error, err, [character(len=64) :: '&kumo_control, line 3', &
                           'n_batches = 99999999999', 'an integer within [-2147483648, 2147483647]'])
    ! a blank inside a number ("1 e4") and a 64-bit variable
    call read_text('&kumo_control n_photons_per_batch = 1 e4 /'//NL//ATM//NL, cfg, err)
    call check_error_words(error, err, [character(len=80) :: '&kumo_control, line 1', &
                           'n_photons_per_batch = 1 e4', &
                           'an integer within [-9223372036854775808, 9223372036854775807]', 'e4'])
    ! more values than the array holds (2001 levels at most)
    call read_text('&kumo_atmosphere nz = 1,'//NL//' z_levels = 3000*0.0 /'//NL, cfg, err)
    call check_error_words(error, err, [character(len=64) :: '&kumo_atmosphere, line 2', &
                           'z_levels = 3000*0.0', 'at most 2001 values, each a real number'])
    ! a logical given a number
    call read_text('&kumo_atmosphere nz = 1, z_levels = 0, 1000, ext1d(1,1) = 0.01'//NL// &
                   '  rayleigh = 3 /'//NL, cfg, err)
    call check_error_words(error, err, [character(len=48) :: '&kumo_atmosphere, line 2', &
                           'rayleigh = 3', 'a logical (T or F)'])
    ! a misspelt variable gets the closest name
    call read_text(ATM//NL//'&kumo_surface albdo = 0.1 /'//NL, cfg, err)
    call check_error_words(error, err, [character(len=48) :: '&kumo_surface, line 2', &
                           'unknown variable albdo', 'did you mean albedo?'])
    ! a real given a word
    call read_text(ATM//NL//'&kumo_source'//NL//NL//' sza_deg = thirty /'//NL, cfg, err)
    call check_error_words(error, err, [character(len=48) :: '&kumo_source, line 4', &
                           'sza_deg = thirty', 'a real number'])
  end subroutine test_value_errors

  subroutine test_distance(error)
    type(error_t), allocatable, intent(out) :: error
    call check(error, edit_distance('kitten', 'sitting') == 3, 'kitten/sitting')
    call check(error, edit_distance('', 'abc') == 3 .and. edit_distance('abc', 'abc') == 0, &
               'empty and equal')
    call check(error, closest_name('albdo', [character(len=16) :: 'albedo', 'brdf']) == 'albedo', &
               'closest')
    call check(error, closest_name('zzzzzz', [character(len=16) :: 'albedo', 'brdf']) == '', &
               'nothing close')
  end subroutine test_distance
end module test_config_layout_suite

program test_config_layout
  use kumo_testing, only: run_unittests
  use test_config_layout_suite, only: collect_config_layout
  implicit none
  integer :: n_failed
  call run_unittests('config_layout', collect_config_layout(), n_failed)
  if (n_failed > 0) error stop 1
end program test_config_layout
