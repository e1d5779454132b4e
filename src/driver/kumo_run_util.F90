! SPDX-License-Identifier: BSD-3-Clause
!> Small services of a run, below the driver: the namelist text (read on rank 0, trimmed for
!> the output), rank 0's errors shared with every rank, the check that the output is none of
!> the run's inputs, the relative standard error of a target-error run, and the test hooks
!> that the regression tests drive through environment variables (KUMO_TEST_FAIL_RANK,
!> KUMO_TEST_KILL_AFTER_CHECKPOINT; not for users, docs/design.md).
module kumo_run_util
  use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
  use, intrinsic :: iso_c_binding, only: c_int
  use kumo_kinds, only: dp
  use kumo_error, only: error_t, set_error
  use kumo_config, only: config_t, input_file_t, config_inputs
  use kumo_textio, only: read_line, same_file
  use kumo_parallel, only: par_is_root, par_bcast_int, par_bcast_text
  implicit none
  private
  public :: share_error, read_text, trim_lines, refuse_input_as_output, relative_error, &
            test_failure_hook, env_int, kill_self

  !> Signal number of SIGKILL (POSIX), for the test hook KUMO_TEST_KILL_AFTER_CHECKPOINT.
  integer(c_int), parameter :: SIGKILL = 9_c_int

  interface
    !> C `raise` (signal.h): send a signal to this process.
    function c_raise(sig) bind(c, name='raise') result(status)
      import :: c_int
      implicit none
      integer(c_int), value, intent(in) :: sig
      integer(c_int) :: status
    end function c_raise
  end interface

contains

  !> Rank 0's error (or success) on every rank, with the same message: for work only rank 0
  !> does (reading the namelist, checking the output path, reading a checkpoint).
  subroutine share_error(error)
    type(error_t), allocatable, intent(inout) :: error
    integer :: status(1)
    character(len=:), allocatable :: message
    status = 0
    if (par_is_root() .and. allocated(error)) status = 1
    call par_bcast_int(status)
    if (status(1) == 0) return
    if (par_is_root()) message = error%message
    call par_bcast_text(message)
    if (.not. par_is_root()) call set_error(error, message)
  end subroutine share_error

  !> The whole text of the file `path`, lines as they are, each ended by a line end.
  subroutine read_text(path, text, error)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: text
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: line
    character(len=512) :: msg
    integer :: unit, ios
    text = ''
    open (newunit=unit, file=path, status='old', action='read', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call set_error(error, 'cannot open namelist file "'//trim(path)//'": '//trim(msg))
      return
    end if
    do
      call read_line(unit, line, ios)
      if (ios /= 0) exit
      text = text//line//new_line('a')
    end do
    close (unit)
  end subroutine read_text

  !> `text` with the trailing blanks of every line removed (the form the output stores).
  pure function trim_lines(text) result(out)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: out
    integer :: i0, i1
    out = ''
    i0 = 1
    do while (i0 <= len(text))
      i1 = index(text(i0:), new_line('a'))
      if (i1 == 0) then
        i1 = len(text) + 1
      else
        i1 = i0 + i1 - 1
      end if
      out = out//trim(text(i0:i1 - 1))//new_line('a')
      i0 = i1 + 1
    end do
  end function trim_lines

  !> The output file must not be one of the run's own inputs (the namelist, a scene, surface,
  !> cloud or phase file) nor its Mie cache: writing it would destroy what the run is made from.
  subroutine refuse_input_as_output(cfg, path, error)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(out) :: error
    type(input_file_t), allocatable :: inputs(:)
    character(len=:), allocatable :: out
    integer :: i
    out = trim(cfg%output%file)
    inputs = config_inputs(cfg, path)
    do i = 1, size(inputs)
      if (same_file(out, inputs(i)%path)) then
        call set_error(error, '&kumo_output file = '''//out//''' is this run''s '// &
                       inputs(i)%label//' ('//inputs(i)%path//'); kumo does not overwrite '// &
                       'its own input: choose another output file')
        return
      end if
    end do
    if (cfg%cloud%enabled .and. len_trim(cfg%cloud%mie_cache) > 0) then
      if (same_file(out, trim(cfg%cloud%mie_cache))) call set_error(error, &
        '&kumo_output file = '''//out//''' is this run''s &kumo_cloud mie_cache; '// &
        'choose another output file')
    end if
  end subroutine refuse_input_as_output

  !> Relative standard error of a mean from its batch sums (S1, S2, number of batches): huge
  !> for fewer than two batches or a zero mean.
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

  !> Test hook (tests/mpi/failing_rank.sh): with the environment variable KUMO_TEST_FAIL_RANK
  !> set to a rank, that rank fails after the scene set-up as if an input it reads could not be
  !> read, while the other ranks go on. Not for users (docs/design.md).
  subroutine test_failure_hook(cfg, rank, error)
    type(config_t), intent(in) :: cfg
    integer, intent(in) :: rank
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: what
    if (env_int('KUMO_TEST_FAIL_RANK') /= rank) return
    what = 'the scene input'
    if (allocated(cfg%path)) what = cfg%path
    call set_error(error, 'cannot read '//what//': input unreadable on this rank (failure '// &
                   'injected by the test hook KUMO_TEST_FAIL_RANK)')
  end subroutine test_failure_hook

  !> A non-negative integer from the environment variable `name`; -1 when it is not set or not
  !> such a number.
  integer function env_int(name) result(value)
    character(len=*), intent(in) :: name
    character(len=32) :: text
    integer :: length, status, ios
    value = -1
    call get_environment_variable(name, text, length, status)
    if (status /= 0 .or. length == 0) return
    read (text, *, iostat=ios) value
    if (ios /= 0 .or. value < 0) value = -1
  end function env_int

  !> Test hook (tests/regression/checkpoint.sh): end this process with SIGKILL, as a batch
  !> system does at the wall-time limit.
  subroutine kill_self()
    integer(c_int) :: status
    flush (output_unit)
    flush (error_unit)
    status = c_raise(SIGKILL)
  end subroutine kill_self

end module kumo_run_util
