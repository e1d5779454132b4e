! SPDX-License-Identifier: BSD-3-Clause
!> Serial build of kumo_parallel: one rank, every operation is trivial.
module kumo_parallel
  use, intrinsic :: iso_c_binding, only: c_int, c_ptr, c_loc
  use, intrinsic :: iso_fortran_env, only: error_unit
  use kumo_kinds, only: dp, sp, i8
  implicit none
  private
  public :: par_init, par_finalize, par_rank, par_size, par_is_root, par_sum_to_root, &
            par_allreduce_sum, par_abort, par_barrier, par_wtime, par_bcast_int, par_bcast_real, PAR_IS_MPI
  public :: par_stop, par_fail, par_bcast_text, par_move, par_bcast_single
  public :: par_node_size, par_node_leader, par_node_storage, par_node_sync, par_gather_i8
  public :: par_node_window, par_node_max, par_node_rank
  public :: PAR_ALL, PAR_LEADERS

  logical, parameter :: PAR_IS_MPI = .false.  !! this build runs on one process
  integer, parameter :: PAR_ALL = 0, PAR_LEADERS = 1   !! groups of ranks (one rank here)

  interface par_sum_to_root
    module procedure sum_to_root_dp, sum_to_root_i8
  end interface par_sum_to_root

  interface par_move
    module procedure move_dp, move_i8
  end interface par_move

  !> The C library's exit(): ends the process with an exit status and, unlike STOP with a code,
  !> prints nothing (Fortran 2008 has no quiet STOP). Fortran units are flushed and closed by
  !> the run-time library's exit handlers.
  interface
    subroutine c_exit(status) bind(c, name='exit')
      import :: c_int
      implicit none
      integer(c_int), value, intent(in) :: status
    end subroutine c_exit
  end interface

contains

  subroutine par_init()
  end subroutine par_init

  subroutine par_finalize()
  end subroutine par_finalize

  integer function par_rank() result(r)
    r = 0
  end function par_rank

  integer function par_size() result(n)
    n = 1
  end function par_size

  logical function par_is_root() result(root)
    root = .true.
  end function par_is_root

  subroutine sum_to_root_dp(buf)
    real(dp), intent(inout) :: buf(:)
    if (size(buf) < 0) buf = 0.0_dp
  end subroutine sum_to_root_dp

  subroutine sum_to_root_i8(buf)
    integer(i8), intent(inout) :: buf(:)
    if (size(buf) < 0) buf = 0_i8
  end subroutine sum_to_root_i8

  subroutine par_allreduce_sum(buf)
    real(dp), intent(inout) :: buf(:)
    if (size(buf) < 0) buf = 0.0_dp
  end subroutine par_allreduce_sum

  subroutine par_bcast_int(buf, group)
    integer, intent(inout) :: buf(:)
    integer, intent(in), optional :: group
    if (size(buf) < 0) buf = 0
  end subroutine par_bcast_int

  subroutine par_bcast_real(buf, group)
    real(dp), intent(inout) :: buf(:)
    integer, intent(in), optional :: group
    if (size(buf) < 0) buf = 0.0_dp
  end subroutine par_bcast_real

  subroutine par_bcast_text(text, group)
    character(len=:), allocatable, intent(inout) :: text
    integer, intent(in), optional :: group
    if (.not. allocated(text)) text = ''
  end subroutine par_bcast_text

  subroutine par_bcast_single(buf, group)
    real(sp), intent(inout) :: buf(:)
    integer, intent(in), optional :: group
    if (size(buf) < 0) buf = 0.0_sp
  end subroutine par_bcast_single

  !> One rank per node.
  integer function par_node_size() result(n)
    n = 1
  end function par_node_size

  logical function par_node_leader() result(leader)
    leader = .true.
  end function par_node_leader

  !> This rank's place among the ranks of its node (the only one).
  integer function par_node_rank() result(r)
    r = 0
  end function par_node_rank

  !> Storage of the node for one process: an ordinary allocation of `nbytes`, kept until the
  !> process ends (as the MPI build keeps its windows until par_finalize); this process writes.
  subroutine par_node_storage(nbytes, base, writer)
    integer(i8), intent(in) :: nbytes
    type(c_ptr), intent(out) :: base
    logical, intent(out) :: writer
    integer(i8), pointer, contiguous :: words(:)
    allocate (words(max(1_i8, (nbytes + 7_i8)/8_i8)))
    base = c_loc(words)
    writer = .true.
  end subroutine par_node_storage

  !> Reusable storage of one process (par_node_window of the MPI build): the allocation of
  !> identifier `id` (1..4) is handed out again while it holds `nbytes`, else replaced.
  subroutine par_node_window(id, nbytes, base, writer)
    integer, intent(in) :: id
    integer(i8), intent(in) :: nbytes
    type(c_ptr), intent(out) :: base
    logical, intent(out) :: writer
    type :: words_t
      integer(i8), pointer, contiguous :: w(:) => null()
    end type words_t
    type(words_t), save :: kept(4)
    if (id < 1 .or. id > 4) error stop 'par_node_window: window identifier outside 1..4'
    if (associated(kept(id)%w)) then
      if (8_i8*size(kept(id)%w, kind=i8) < nbytes) deallocate (kept(id)%w)
    end if
    if (.not. associated(kept(id)%w)) allocate (kept(id)%w(max(1_i8, (nbytes + 7_i8)/8_i8)))
    base = c_loc(kept(id)%w)
    writer = .true.
  end subroutine par_node_window

  !> One rank per node: the values are the node's largest.
  subroutine par_node_max(x)
    integer, intent(inout) :: x(:)
    if (size(x) < 0) x = 0
  end subroutine par_node_max

  subroutine par_node_sync()
  end subroutine par_node_sync

  subroutine par_gather_i8(mine, all)
    integer(i8), intent(in) :: mine
    integer(i8), intent(out) :: all(:)
    all(1) = mine
  end subroutine par_gather_i8

  !> One rank: `from` and `to` are both 0, nothing moves.
  subroutine move_dp(buf, from, to)
    real(dp), intent(inout) :: buf(:)
    integer, intent(in) :: from, to
    if (from /= to) buf = buf
  end subroutine move_dp

  subroutine move_i8(buf, from, to)
    integer(i8), intent(inout) :: buf(:)
    integer, intent(in) :: from, to
    if (from /= to) buf = buf
  end subroutine move_i8

  !> Print `kumo error: message` and end the run with exit status `code`.
  subroutine par_fail(message, code)
    character(len=*), intent(in) :: message
    integer, intent(in) :: code
    write (error_unit, '(a)') 'kumo error: '//message
    flush (error_unit)
    call par_stop(code)
  end subroutine par_fail

  subroutine par_barrier()
  end subroutine par_barrier

  real(dp) function par_wtime() result(t)
    integer(i8) :: count, rate
    call system_clock(count, rate)
    t = real(count, dp)/real(rate, dp)
  end function par_wtime

  !> End the run with exit status `code`, without a STOP line.
  subroutine par_abort(code)
    integer, intent(in) :: code
    call par_stop(code)
  end subroutine par_abort

  !> End the run with exit status `code` and no STOP line.
  subroutine par_stop(code)
    integer, intent(in) :: code
    call c_exit(int(code, c_int))
  end subroutine par_stop
end module kumo_parallel
