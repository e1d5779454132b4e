! SPDX-License-Identifier: BSD-3-Clause
!> MPI edges of kumo: start/stop, rank queries, broadcasts and the one reduction of the tallies.
!>
!> The only module that uses MPI. A serial build compiles kumo_parallel_serial.F90 instead, which
!> provides the same module with trivial bodies.
module kumo_parallel
  use mpi_f08, only: MPI_Init, MPI_Initialized, MPI_Finalize, MPI_Finalized, MPI_Comm_rank, &
    MPI_Comm_size, MPI_Reduce, MPI_Allreduce, MPI_Bcast, MPI_Barrier, MPI_Wtime, MPI_Abort, &
    MPI_COMM_WORLD, MPI_IN_PLACE, MPI_DOUBLE_PRECISION, MPI_INTEGER, MPI_INTEGER8, MPI_SUM
  use mpi_f08, only: MPI_MAX
  use mpi_f08, only: MPI_REAL
  use mpi_f08, only: MPI_Ibarrier, MPI_Test, MPI_Request, MPI_STATUS_IGNORE
  use mpi_f08, only: MPI_Send, MPI_Recv, MPI_Gather, MPI_Gatherv, MPI_CHARACTER
  use mpi_f08, only: MPI_Win_lock_all, MPI_Win_unlock_all, MPI_Win_sync, MPI_MODE_NOCHECK
  use mpi_f08, only: MPI_Comm, MPI_Win, MPI_Comm_split_type, MPI_Comm_split, MPI_Win_free, &
    MPI_Win_allocate_shared, MPI_Win_shared_query, MPI_COMM_TYPE_SHARED, MPI_INFO_NULL, &
    MPI_UNDEFINED, MPI_ADDRESS_KIND
  use, intrinsic :: iso_c_binding, only: c_int, c_ptr
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

  logical, parameter :: PAR_IS_MPI = .true.  !! this build distributes batches over MPI ranks

  interface par_sum_to_root
    module procedure sum_to_root_dp, sum_to_root_i8
  end interface par_sum_to_root

  !> Copy an array from one rank to another (point to point; the other ranks do nothing).
  interface par_move
    module procedure move_dp, move_i8
  end interface par_move

  !> Groups of ranks for broadcasts: every rank, or the first rank of every node (the node
  !> leaders, which include rank 0).
  integer, parameter :: PAR_ALL = 0, PAR_LEADERS = 1

  !> The ranks of this node (MPI_COMM_TYPE_SHARED), the node leaders, and the shared-memory
  !> windows this process holds (freed by par_finalize). Set up by par_init.
  logical, save :: node_ready = .false.
  type(MPI_Comm), save :: node_comm, leader_comm
  integer, save :: node_rank = 0, node_n = 1
  type(MPI_Win), allocatable, save :: windows(:)
  !> Reusable windows (par_node_window): one per identifier, kept and handed out again while
  !> big enough.
  integer, parameter :: N_REUSE = 4
  type(MPI_Win), save :: reuse_win(N_REUSE)
  integer(i8), save :: reuse_bytes(N_REUSE) = -1_i8
  type(c_ptr), save :: reuse_base(N_REUSE)

  !> How long [s] the ranks that failed wait for the others before ending the job with
  !> MPI_Abort: an error every rank found reaches them all well within it.
  real(dp), parameter :: ABORT_GRACE_S = 5.0_dp
  !> Tag of the point-to-point messages of par_move.
  integer, parameter :: MOVE_TAG = 4242

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
    logical :: flag
    call MPI_Initialized(flag)
    if (.not. flag) call MPI_Init()
    call node_setup()
  end subroutine par_init

  subroutine par_finalize()
    logical :: flag
    integer :: i
    call MPI_Finalized(flag)
    if (flag) return
    if (allocated(windows)) then
      do i = 1, size(windows)
        call MPI_Win_unlock_all(windows(i))
        call MPI_Win_free(windows(i))
      end do
      deallocate (windows)
    end if
    do i = 1, N_REUSE
      if (reuse_bytes(i) < 0) cycle
      call MPI_Win_unlock_all(reuse_win(i))
      call MPI_Win_free(reuse_win(i))
      reuse_bytes(i) = -1_i8
    end do
    call MPI_Finalize()
  end subroutine par_finalize

  !> The communicator of the ranks that share this node's memory and that of the node leaders
  !> (every rank calls it: par_init does; later calls do nothing).
  subroutine node_setup()
    integer :: rank, color
    if (node_ready) return
    rank = par_rank()
    call MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank, MPI_INFO_NULL, node_comm)
    call MPI_Comm_rank(node_comm, node_rank)
    call MPI_Comm_size(node_comm, node_n)
    color = MPI_UNDEFINED
    if (node_rank == 0) color = 0
    call MPI_Comm_split(MPI_COMM_WORLD, color, rank, leader_comm)
    node_ready = .true.
  end subroutine node_setup

  !> Number of ranks on this node (that can share memory).
  integer function par_node_size() result(n)
    call node_setup()
    n = node_n
  end function par_node_size

  !> This rank is its node's first (its leader).
  logical function par_node_leader() result(leader)
    call node_setup()
    leader = node_rank == 0
  end function par_node_leader

  !> This rank's place among the ranks of its node (0 for the node's first).
  integer function par_node_rank() result(r)
    call node_setup()
    r = node_rank
  end function par_node_rank

  !> Storage shared by the ranks of this node (kumo_atmosphere voxel_storage_i): an MPI-3
  !> shared-memory window of `nbytes` bytes allocated by the node's leader alone, mapped by every
  !> rank of the node at `base`; the leader is the `writer`. Every rank of the node calls it with
  !> the same `nbytes`. The window lives until par_finalize.
  subroutine par_node_storage(nbytes, base, writer)
    integer(i8), intent(in) :: nbytes
    type(c_ptr), intent(out) :: base
    logical, intent(out) :: writer
    type(MPI_Win) :: win
    call new_window(nbytes, win, base, writer)
    if (.not. allocated(windows)) allocate (windows(0))
    windows = [windows, win]
  end subroutine par_node_storage

  !> Storage shared by the ranks of this node that is used again and again, for what is rebuilt
  !> many times in a run (the voxels of each g-point of a broadband run): like par_node_storage,
  !> but the window of identifier `id` (1..4) is kept and handed out again while it holds
  !> `nbytes`; a larger request replaces it (collectively on the node). Every rank of the node
  !> calls it with the same `id` and `nbytes`, and only once none of them reads the old values.
  subroutine par_node_window(id, nbytes, base, writer)
    integer, intent(in) :: id
    integer(i8), intent(in) :: nbytes
    type(c_ptr), intent(out) :: base
    logical, intent(out) :: writer
    call node_setup()
    writer = node_rank == 0
    if (id < 1 .or. id > N_REUSE) error stop 'par_node_window: window identifier outside 1..4'
    if (reuse_bytes(id) >= nbytes) then
      base = reuse_base(id)
      return
    end if
    if (reuse_bytes(id) >= 0) then
      call MPI_Win_unlock_all(reuse_win(id))
      call MPI_Win_free(reuse_win(id))
    end if
    call new_window(nbytes, reuse_win(id), base, writer)
    reuse_bytes(id) = max(nbytes, 8_i8)
    reuse_base(id) = base
  end subroutine par_node_window

  !> A shared-memory window of the node: `nbytes` allocated by its leader (the `writer`), mapped
  !> by every rank at `base`, with a passive-target epoch for its life, so that par_node_sync may
  !> call MPI_Win_sync (the memory barrier that the separate memory model needs).
  subroutine new_window(nbytes, win, base, writer)
    integer(i8), intent(in) :: nbytes
    type(MPI_Win), intent(out) :: win
    type(c_ptr), intent(out) :: base
    logical, intent(out) :: writer
    integer(kind=MPI_ADDRESS_KIND) :: mine, got
    integer :: disp
    type(c_ptr) :: local
    call node_setup()
    writer = node_rank == 0
    mine = 0
    if (writer) mine = max(nbytes, 8_i8)
    call MPI_Win_allocate_shared(mine, 1, MPI_INFO_NULL, node_comm, local, win)
    call MPI_Win_shared_query(win, 0, got, disp, base)
    call MPI_Win_lock_all(MPI_MODE_NOCHECK, win)
  end subroutine new_window

  !> The largest value of each element over the ranks of this node, on every rank of the node.
  subroutine par_node_max(x)
    integer, intent(inout) :: x(:)
    call node_setup()
    if (size(x) == 0) return
    call MPI_Allreduce(MPI_IN_PLACE, x, size(x), MPI_INTEGER, MPI_MAX, node_comm)
  end subroutine par_node_max

  !> Returns when every rank of the node has reached it: what the leader wrote into the node's
  !> shared storage before is then seen by all (MPI_Win_sync on every window before and after a
  !> barrier of the node: the leader's stores are complete before the barrier, and the others'
  !> loads come after it, in the unified and in the separate memory model).
  subroutine par_node_sync()
    integer :: i
    call node_setup()
    if (allocated(windows)) then
      do i = 1, size(windows)
        call MPI_Win_sync(windows(i))
      end do
    end if
    do i = 1, N_REUSE
      if (reuse_bytes(i) >= 0) call MPI_Win_sync(reuse_win(i))
    end do
    call MPI_Barrier(node_comm)
    if (allocated(windows)) then
      do i = 1, size(windows)
        call MPI_Win_sync(windows(i))
      end do
    end if
    do i = 1, N_REUSE
      if (reuse_bytes(i) >= 0) call MPI_Win_sync(reuse_win(i))
    end do
  end subroutine par_node_sync

  !> Gather one integer per rank on rank 0 (`all`, size par_size(), in rank order; other ranks'
  !> `all` is not set).
  subroutine par_gather_i8(mine, all)
    integer(i8), intent(in) :: mine
    integer(i8), intent(out) :: all(:)
    integer(i8) :: buf(1)
    buf(1) = mine
    call MPI_Gather(buf, 1, MPI_INTEGER8, all, 1, MPI_INTEGER8, 0, MPI_COMM_WORLD)
  end subroutine par_gather_i8

  integer function par_rank() result(r)
    call MPI_Comm_rank(MPI_COMM_WORLD, r)
  end function par_rank

  integer function par_size() result(n)
    call MPI_Comm_size(MPI_COMM_WORLD, n)
  end function par_size

  logical function par_is_root() result(root)
    root = par_rank() == 0
  end function par_is_root

  !> Sum `buf` over ranks; the result is valid on rank 0 only.
  subroutine sum_to_root_dp(buf)
    real(dp), intent(inout) :: buf(:)
    if (par_rank() == 0) then
      call MPI_Reduce(MPI_IN_PLACE, buf, size(buf), MPI_DOUBLE_PRECISION, MPI_SUM, 0, &
                      MPI_COMM_WORLD)
    else
      call MPI_Reduce(buf, buf, size(buf), MPI_DOUBLE_PRECISION, MPI_SUM, 0, MPI_COMM_WORLD)
    end if
  end subroutine sum_to_root_dp

  subroutine sum_to_root_i8(buf)
    integer(i8), intent(inout) :: buf(:)
    if (par_rank() == 0) then
      call MPI_Reduce(MPI_IN_PLACE, buf, size(buf), MPI_INTEGER8, MPI_SUM, 0, MPI_COMM_WORLD)
    else
      call MPI_Reduce(buf, buf, size(buf), MPI_INTEGER8, MPI_SUM, 0, MPI_COMM_WORLD)
    end if
  end subroutine sum_to_root_i8

  !> Sum `buf` over ranks, result on every rank.
  subroutine par_allreduce_sum(buf)
    real(dp), intent(inout) :: buf(:)
    call MPI_Allreduce(MPI_IN_PLACE, buf, size(buf), MPI_DOUBLE_PRECISION, MPI_SUM, &
                       MPI_COMM_WORLD)
  end subroutine par_allreduce_sum

  !> Broadcast integers from rank 0 (to every rank, or with `group` = PAR_LEADERS to the node
  !> leaders, which alone call it then).
  subroutine par_bcast_int(buf, group)
    integer, intent(inout) :: buf(:)
    integer, intent(in), optional :: group
    call MPI_Bcast(buf, size(buf), MPI_INTEGER, 0, comm_of(group))
  end subroutine par_bcast_int

  !> The communicator of a group of ranks (PAR_ALL when absent).
  function comm_of(group) result(comm)
    integer, intent(in), optional :: group
    type(MPI_Comm) :: comm
    comm = MPI_COMM_WORLD
    if (present(group)) then
      if (group == PAR_LEADERS) then
        call node_setup()
        comm = leader_comm
      end if
    end if
  end function comm_of

  !> Broadcast doubles from rank 0 (in chunks, so arrays of any size fit MPI's int counts).
  subroutine par_bcast_real(buf, group)
    real(dp), intent(inout) :: buf(:)
    integer, intent(in), optional :: group
    integer(i8) :: i0, n
    integer, parameter :: CHUNK = 2**27
    n = size(buf, kind=i8)
    i0 = 1
    do while (i0 <= n)
      call MPI_Bcast(buf(i0:min(n, i0 + CHUNK - 1)), int(min(int(CHUNK, i8), n - i0 + 1)), &
                     MPI_DOUBLE_PRECISION, 0, comm_of(group))
      i0 = i0 + CHUNK
    end do
  end subroutine par_bcast_real

  !> Broadcast single-precision reals from rank 0 (in chunks, as par_bcast_real).
  subroutine par_bcast_single(buf, group)
    real(sp), intent(inout) :: buf(:)
    integer, intent(in), optional :: group
    integer(i8) :: i0, n
    integer, parameter :: CHUNK = 2**27
    n = size(buf, kind=i8)
    i0 = 1
    do while (i0 <= n)
      call MPI_Bcast(buf(i0:min(n, i0 + CHUNK - 1)), int(min(int(CHUNK, i8), n - i0 + 1)), &
                     MPI_REAL, 0, comm_of(group))
      i0 = i0 + CHUNK
    end do
  end subroutine par_bcast_single

  !> Broadcast a string from rank 0 (any length; `text` need not be allocated elsewhere).
  subroutine par_bcast_text(text, group)
    character(len=:), allocatable, intent(inout) :: text
    integer, intent(in), optional :: group
    integer :: n(1)
    n = 0
    if (par_rank() == 0) n = len(text)
    call MPI_Bcast(n, 1, MPI_INTEGER, 0, comm_of(group))
    if (par_rank() /= 0) then
      if (allocated(text)) deallocate (text)
      allocate (character(len=n(1)) :: text)
    end if
    if (n(1) > 0) call MPI_Bcast(text, n(1), MPI_CHARACTER, 0, comm_of(group))
  end subroutine par_bcast_text

  !> Rank `to` receives `buf` from rank `from` (same size on both); nothing happens on other
  !> ranks or when `from` = `to`.
  subroutine move_dp(buf, from, to)
    real(dp), intent(inout) :: buf(:)
    integer, intent(in) :: from, to
    integer :: rank
    if (from == to) return
    rank = par_rank()
    if (rank == from) then
      call MPI_Send(buf, size(buf), MPI_DOUBLE_PRECISION, to, MOVE_TAG, MPI_COMM_WORLD)
    else if (rank == to) then
      call MPI_Recv(buf, size(buf), MPI_DOUBLE_PRECISION, from, MOVE_TAG, MPI_COMM_WORLD, &
                    MPI_STATUS_IGNORE)
    end if
  end subroutine move_dp

  subroutine move_i8(buf, from, to)
    integer(i8), intent(inout) :: buf(:)
    integer, intent(in) :: from, to
    integer :: rank
    if (from == to) return
    rank = par_rank()
    if (rank == from) then
      call MPI_Send(buf, size(buf), MPI_INTEGER8, to, MOVE_TAG, MPI_COMM_WORLD)
    else if (rank == to) then
      call MPI_Recv(buf, size(buf), MPI_INTEGER8, from, MOVE_TAG, MPI_COMM_WORLD, &
                    MPI_STATUS_IGNORE)
    end if
  end subroutine move_i8

  !> End the run after an error `message` found on this rank: the message is printed and every
  !> rank stops with exit status `code`; no rank is left waiting.
  !>
  !> Rank 0 prints its message at once (`kumo error: ...`). The other ranks wait up to
  !> ABORT_GRACE_S seconds for every rank to fail too (an error all ranks found, such as an
  !> invalid namelist): then rank 0 prints each message that differs from its own once, with
  !> the ranks that reported it, and all ranks exit quietly. A rank whose error the others did
  !> not share (an input only it reads, an allocation failure, a test hook) prints
  !> `kumo error on rank R of N: ...` when the grace has passed and ends the job with MPI_Abort,
  !> wherever the other ranks are.
  subroutine par_fail(message, code)
    character(len=*), intent(in) :: message
    integer, intent(in) :: code
    type(MPI_Request) :: request
    logical :: all_here
    real(dp) :: t0
    integer :: rank, n
    rank = par_rank()
    n = par_size()
    if (rank == 0) then
      write (error_unit, '(a)') 'kumo error: '//message
      flush (error_unit)
    end if
    if (n == 1) call par_stop(code)
    call MPI_Ibarrier(MPI_COMM_WORLD, request)
    t0 = MPI_Wtime()
    do
      call MPI_Test(request, all_here, MPI_STATUS_IGNORE)
      if (all_here) exit
      if (MPI_Wtime() - t0 > ABORT_GRACE_S) exit
    end do
    if (all_here) then
      call report_other_messages(message)
      call par_stop(code)
    end if
    if (rank /= 0) then
      write (error_unit, '(a)') 'kumo error on rank '//itoa(rank)//' of '//itoa(n)//': '//message
      flush (error_unit)
    end if
    call MPI_Abort(MPI_COMM_WORLD, code)
  end subroutine par_fail

  !> Every rank failed: rank 0 gathers the messages and prints those that differ from its own,
  !> each once, with the ranks that reported it.
  subroutine report_other_messages(message)
    character(len=*), intent(in) :: message
    integer :: n, r, q, my_len(1)
    integer, allocatable :: lens(:), offs(:)
    character(len=:), allocatable :: all_text, ranks
    character(len=1) :: dummy(1)
    n = par_size()
    allocate (lens(n), offs(n))
    lens = 0
    my_len(1) = len(message)
    call MPI_Gather(my_len, 1, MPI_INTEGER, lens, 1, MPI_INTEGER, 0, MPI_COMM_WORLD)
    offs = 0
    do r = 2, n
      offs(r) = offs(r - 1) + lens(r - 1)
    end do
    if (par_rank() == 0) then
      allocate (character(len=sum(lens)) :: all_text)
      call MPI_Gatherv(message, len(message), MPI_CHARACTER, all_text, lens, offs, &
                       MPI_CHARACTER, 0, MPI_COMM_WORLD)
    else
      call MPI_Gatherv(message, len(message), MPI_CHARACTER, dummy, lens, offs, &
                       MPI_CHARACTER, 0, MPI_COMM_WORLD)
      return
    end if
    do r = 2, n
      if (text_of(r) == message) cycle
      if (any([(text_of(q) == text_of(r), q = 2, r - 1)])) cycle   ! printed with rank q
      ranks = ''
      do q = r, n
        if (text_of(q) /= text_of(r)) cycle
        if (len(ranks) > 0) ranks = ranks//', '
        ranks = ranks//itoa(q - 1)
      end do
      write (error_unit, '(a)') 'kumo error on rank'//trim(merge('s', ' ', index(ranks, ',') > 0))// &
        ' '//ranks//' of '//itoa(n)//': '//text_of(r)
    end do
    flush (error_unit)
  contains
    function text_of(i) result(t)
      integer, intent(in) :: i
      character(len=:), allocatable :: t
      t = all_text(offs(i) + 1:offs(i) + lens(i))
    end function text_of
  end subroutine report_other_messages

  pure function itoa(i) result(s)
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    character(len=12) :: buf
    write (buf, '(i0)') i
    s = trim(buf)
  end function itoa

  subroutine par_barrier()
    call MPI_Barrier(MPI_COMM_WORLD)
  end subroutine par_barrier

  real(dp) function par_wtime() result(t)
    t = MPI_Wtime()
  end function par_wtime

  !> Stop every rank with a non-zero exit code (no rank is left waiting). When every rank calls
  !> it within ABORT_GRACE_S seconds (an error all ranks found, such as an invalid namelist)
  !> MPI is finalised and each rank exits quietly (`par_stop`); otherwise (an error on some
  !> ranks only, the others busy or waiting in a collective operation) MPI_Abort ends them all.
  subroutine par_abort(code)
    integer, intent(in) :: code
    type(MPI_Request) :: request
    logical :: all_here
    real(dp) :: t0
    if (par_size() == 1) call par_stop(code)
    call MPI_Ibarrier(MPI_COMM_WORLD, request)
    t0 = MPI_Wtime()
    do
      call MPI_Test(request, all_here, MPI_STATUS_IGNORE)
      if (all_here) call par_stop(code)
      if (MPI_Wtime() - t0 > ABORT_GRACE_S) exit
    end do
    call MPI_Abort(MPI_COMM_WORLD, code)
  end subroutine par_abort

  !> End the run with exit status `code` and no STOP line. Every rank must call it (an outcome
  !> all ranks know, e.g. after a broadcast): MPI is finalised, then each process exits.
  subroutine par_stop(code)
    integer, intent(in) :: code
    call par_finalize()
    call c_exit(int(code, c_int))
  end subroutine par_stop
end module kumo_parallel
