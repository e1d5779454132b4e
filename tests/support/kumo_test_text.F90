! SPDX-License-Identifier: BSD-3-Clause
!> Text helpers shared by the tests that read reference tables, and the path of the shared
!> reference-data folder (CTest passes it as the first command-line argument).
module kumo_test_text
  use kumo_kinds, only: wp, dp
  use kumo_error, only: set_error
  use kumo_textio, only: read_two_columns
  use kumo_testing, only: error_t, check, unittest_t, run_unittests
  use kumo_parallel, only: par_init, par_finalize
  implicit none
  private
  public :: split, read_table, open_text, write_text, shared_dir, set_shared_dir, disort_value, &
            half_last_digit, run_suite, run_shared_suite

  !> The shared data folder (data/, reference/), set from the command line.
  character(len=:), allocatable :: shared_dir

contains

  !> The main program of a suite that reads the shared data folder: starts MPI (or its stub),
  !> takes the folder from the first command-line argument and runs the tests. Stops with code 2
  !> (and a usage line naming `program_name` and what it reads, `needs`) without the argument,
  !> with code 1 when a test failed.
  subroutine run_shared_suite(program_name, needs, suite_name, tests)
    character(len=*), intent(in) :: program_name, needs, suite_name
    type(unittest_t), intent(in) :: tests(:)
    character(len=4096) :: arg
    call par_init()
    if (command_argument_count() < 1) then
      write (*, '(a)') 'usage: '//program_name//' SHARED_DIR (folder holding '//needs//')'
      error stop 2
    end if
    call get_command_argument(1, arg)
    call set_shared_dir(trim(arg))
    call finish_suite(suite_name, tests)
  end subroutine run_shared_suite

  !> The main program of a suite without arguments: starts MPI (or its stub) and runs the tests;
  !> stops with code 1 when a test failed.
  subroutine run_suite(suite_name, tests)
    character(len=*), intent(in) :: suite_name
    type(unittest_t), intent(in) :: tests(:)
    call par_init()
    call finish_suite(suite_name, tests)
  end subroutine run_suite

  !> Run the tests, shut MPI (or its stub) down and stop with code 1 when a test failed.
  subroutine finish_suite(suite_name, tests)
    character(len=*), intent(in) :: suite_name
    type(unittest_t), intent(in) :: tests(:)
    integer :: n_failed
    call run_unittests(suite_name, tests, n_failed)
    call par_finalize()
    if (n_failed > 0) error stop 1
  end subroutine finish_suite

  !> Set the shared data folder.
  subroutine set_shared_dir(path)
    character(len=*), intent(in) :: path
    shared_dir = path
  end subroutine set_shared_dir

  !> Split `s` at every `sep` into `fields(1:n)` (empty fields kept; fields beyond the size of
  !> `fields` are counted but not stored).
  subroutine split(s, sep, fields, n)
    character(len=*), intent(in) :: s
    character(len=1), intent(in) :: sep
    character(len=*), intent(inout) :: fields(:)
    integer, intent(out) :: n
    integer :: i0, i, ls
    n = 0
    i0 = 1
    fields = ''
    ls = len_trim(s)
    do i = 1, ls + 1
      if (i <= ls) then
        if (s(i:i) /= sep) cycle
      end if
      n = n + 1
      if (n <= size(fields)) fields(n) = s(i0:i - 1)
      i0 = i + 1
    end do
  end subroutine split

  !> Half a unit in the last printed digit of a number written like 1.23456E-01 (0 for a number
  !> without exponent, such as the exact zeros written as 0.0).
  real(dp) function half_last_digit(text) result(h)
    character(len=*), intent(in) :: text
    integer :: ie, ipt, ios, ex
    h = 0.0_dp
    ie = scan(text, 'Ee')
    ipt = index(text, '.')
    if (ie == 0 .or. ipt == 0 .or. ipt > ie) return
    read (text(ie + 1:), *, iostat=ios) ex
    if (ios == 0) h = 0.5_dp*10.0_dp**(ex - (ie - ipt - 1))
  end function half_last_digit

  !> Open the text file `path` for reading; failing that, the test's error is 'cannot open path'.
  subroutine open_text(path, unit, error)
    character(len=*), intent(in) :: path
    integer, intent(out) :: unit
    type(error_t), allocatable, intent(inout) :: error
    integer :: ios
    open (newunit=unit, file=path, status='old', action='read', iostat=ios)
    if (ios /= 0) call set_error(error, 'cannot open '//path)
  end subroutine open_text

  !> Write `text` and a line end to the file `path` (a namelist, a small input file), replacing it.
  subroutine write_text(path, text)
    character(len=*), intent(in) :: path, text
    integer :: u
    open (newunit=u, file=path, status='replace', action='write')
    write (u, '(a)') text
    close (u)
  end subroutine write_text

  !> Read a two-column table with kumo's own reader; a failure becomes the test's error.
  subroutine read_table(path, angle, value, error)
    character(len=*), intent(in) :: path
    real(wp), allocatable, intent(out) :: angle(:), value(:)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable :: err
    call read_two_columns(path, angle, value, err)
    if (allocated(err)) call check(error, .false., err%message)
  end subroutine read_table

  !> One value of the plane-parallel DISORT table (reference/disort_pp.csv) keyed on case_id,
  !> quantity, level, mu and phi_rel_deg, the last three as written in the file ('' when empty).
  !> A missing row or file becomes the test's error.
  function disort_value(case_id, quantity, level, mu, phi, error) result(v)
    character(len=*), intent(in) :: case_id, quantity, level, mu, phi
    type(error_t), allocatable, intent(inout) :: error
    real(dp) :: v
    character(len=512) :: line
    character(len=64) :: f(12)
    integer :: unit, ios, nf
    v = 0.0_dp
    if (allocated(error)) return
    if (.not. allocated(shared_dir)) then
      call check(error, .false., 'the shared data folder was not given on the command line')
      return
    end if
    call open_text(shared_dir//'/reference/disort_pp.csv', unit, error)
    if (allocated(error)) return
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      call split(line, ',', f, nf)
      if (nf /= 12) cycle
      if (f(1) == case_id .and. f(8) == quantity .and. f(9) == level .and. f(10) == mu .and. &
          f(11) == phi) then
        read (f(12), *, iostat=ios) v
        close (unit)
        if (ios /= 0) call check(error, .false., 'bad value in disort_pp.csv: '//trim(line))
        return
      end if
    end do
    close (unit)
    call check(error, .false., 'disort_pp.csv has no row '//case_id//','//quantity//','// &
               level//','//mu//','//phi)
  end function disort_value
end module kumo_test_text
