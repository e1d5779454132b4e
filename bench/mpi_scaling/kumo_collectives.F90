! SPDX-License-Identifier: BSD-3-Clause
!> Timing of the MPI operations kumo's collective costs are made of, at the sizes of real runs.
!>
!> A stand-alone benchmark (not linked into kumo) that calls the same MPI operations with the
!> same data types as kumo does:
!>
!> * `pingpong`: MPI_Send/MPI_Recv between ranks 0 and 1, one-way time t(m) = alpha + beta m
!>   for messages of m bytes (half the round trip), from 8 B to 64 MiB;
!> * `bcast`: MPI_Bcast of single-precision reals from rank 0, as `par_bcast_single` shares
!>   the voxel fields of a cloud file (`bundle_t%share`); the time is the slowest rank's;
!> * `fold`: the end of a run as `fold_slots` (src/driver/kumo_driver.F90) does it today: every
!>   rank in turn sends its slot's S1 and S2 (n doubles each) to rank 0, which adds them in
!>   slot order; the time is rank 0's;
!> * `tree`: the same sums folded in a fixed binary tree instead (at step k the rank r with
!>   mod(r, 2^(k+1)) = 0 receives the partial S1 and S2 of rank r + 2^k and adds them), which
!>   fixes the order of the additions as the slot order does; time on rank 0;
!> * `reduce`: one MPI_Reduce (MPI_SUM) of the 2n doubles S1 and S2, the library's collective
!>   (time on rank 0, after a barrier so that all ranks start together);
!> * `allreduce`: MPI_Allreduce of 3 P doubles, the per-round exchange of the target-error
!>   decision (three numbers per slot).
!>
!> Each line printed by rank 0 is `kind P bytes seconds` (median of the repetitions). Usage:
!>
!>     mpirun -np P kumo_collectives [max_doubles [reps]]
!>
!> `max_doubles` (default 10000000) bounds the tally sizes n of `fold` and `reduce`, `reps`
!> (default 5) the repetitions of the large messages (small ones are repeated more).
program kumo_collectives
  use mpi_f08
  use, intrinsic :: iso_fortran_env, only: dp => real64, sp => real32, i8 => int64, output_unit
  implicit none
  integer :: rank, nranks, reps, k, nbytes
  integer(i8) :: max_doubles
  character(len=32) :: arg
  !> Tally sizes (doubles per sum) of the fold and reduce timings.
  integer(i8), parameter :: TALLY_N(*) = [10000_i8, 100000_i8, 300000_i8, 1000000_i8, &
                                          3000000_i8, 10000000_i8]
  !> Broadcast sizes (single-precision values): a 64 x 64 x 16 LES field, 1e6 voxels, and two
  !> fields (water content and effective radius) of 256 x 256 x 100 and of 400 x 400 x 64.
  integer(i8), parameter :: BCAST_N(*) = [65536_i8, 1000000_i8, 13107200_i8, 20480000_i8]

  call MPI_Init()
  call MPI_Comm_rank(MPI_COMM_WORLD, rank)
  call MPI_Comm_size(MPI_COMM_WORLD, nranks)
  max_doubles = 10000000_i8
  reps = 5
  if (command_argument_count() >= 1) then
    call get_command_argument(1, arg)
    read (arg, *) max_doubles
  end if
  if (command_argument_count() >= 2) then
    call get_command_argument(2, arg)
    read (arg, *) reps
  end if

  if (nranks >= 2) then
    do k = 3, 26
      nbytes = 2**k
      call time_pingpong(nbytes, merge(200, max(reps, 3), nbytes <= 65536))
    end do
  end if
  do k = 1, size(BCAST_N)
    call time_bcast(BCAST_N(k), merge(50, reps, BCAST_N(k) <= 100000_i8))
  end do
  do k = 1, size(TALLY_N)
    if (TALLY_N(k) > max_doubles) exit
    call time_fold(TALLY_N(k), merge(20, reps, TALLY_N(k) <= 100000_i8))
    call time_tree(TALLY_N(k), merge(20, reps, TALLY_N(k) <= 100000_i8))
    call time_reduce(TALLY_N(k), merge(20, reps, TALLY_N(k) <= 100000_i8))
  end do
  call time_allreduce(3*nranks, 200)
  call MPI_Finalize()

contains

  !> Print one result line on rank 0.
  subroutine report(kind, bytes, seconds)
    character(len=*), intent(in) :: kind
    integer(i8), intent(in) :: bytes
    real(dp), intent(in) :: seconds
    if (rank /= 0) return
    write (output_unit, '(a, 1x, i0, 1x, i0, 1x, es12.5)') kind, nranks, bytes, seconds
    flush (output_unit)
  end subroutine report

  !> Median of the values (sorted copy).
  real(dp) function median(x) result(m)
    real(dp), intent(in) :: x(:)
    real(dp) :: y(size(x)), t
    integer :: i, j, n
    y = x
    n = size(y)
    do i = 2, n
      t = y(i)
      j = i - 1
      do while (j >= 1)
        if (y(j) <= t) exit
        y(j + 1) = y(j)
        j = j - 1
      end do
      y(j + 1) = t
    end do
    if (mod(n, 2) == 1) then
      m = y((n + 1)/2)
    else
      m = 0.5_dp*(y(n/2) + y(n/2 + 1))
    end if
  end function median

  !> The slowest rank's time of each repetition (every rank must call it).
  subroutine slowest(t)
    real(dp), intent(inout) :: t(:)
    call MPI_Allreduce(MPI_IN_PLACE, t, size(t), MPI_DOUBLE_PRECISION, MPI_MAX, MPI_COMM_WORLD)
  end subroutine slowest

  subroutine time_pingpong(nbytes, n_rep)
    integer, intent(in) :: nbytes, n_rep
    character(len=1), allocatable :: buf(:)
    real(dp) :: t(n_rep), t0
    integer :: i
    allocate (buf(nbytes))
    buf = 'k'
    t = 0.0_dp
    do i = 0, n_rep
      call MPI_Barrier(MPI_COMM_WORLD)
      t0 = MPI_Wtime()
      if (rank == 0) then
        call MPI_Send(buf, nbytes, MPI_CHARACTER, 1, 1, MPI_COMM_WORLD)
        call MPI_Recv(buf, nbytes, MPI_CHARACTER, 1, 2, MPI_COMM_WORLD, MPI_STATUS_IGNORE)
      else if (rank == 1) then
        call MPI_Recv(buf, nbytes, MPI_CHARACTER, 0, 1, MPI_COMM_WORLD, MPI_STATUS_IGNORE)
        call MPI_Send(buf, nbytes, MPI_CHARACTER, 0, 2, MPI_COMM_WORLD)
      end if
      if (i > 0) t(i) = 0.5_dp*(MPI_Wtime() - t0)   ! repetition 0 warms up
    end do
    call report('pingpong', int(nbytes, i8), median(t))
  end subroutine time_pingpong

  subroutine time_bcast(n, n_rep)
    integer(i8), intent(in) :: n
    integer, intent(in) :: n_rep
    real(sp), allocatable :: buf(:)
    real(dp) :: t(n_rep), t0
    integer :: i
    allocate (buf(n))
    buf = real(rank, sp)
    t = 0.0_dp
    do i = 0, n_rep
      call MPI_Barrier(MPI_COMM_WORLD)
      t0 = MPI_Wtime()
      call MPI_Bcast(buf, int(n), MPI_REAL, 0, MPI_COMM_WORLD)
      if (i > 0) t(i) = MPI_Wtime() - t0
    end do
    call slowest(t)
    if (any(buf /= 0.0_sp)) error stop 'kumo_collectives: the broadcast did not arrive'
    call report('bcast', 4_i8*n, median(t))
  end subroutine time_bcast

  !> kumo's fold_slots with one slot per rank: rank r sends S1 then S2 to rank 0, which adds
  !> them in rank order.
  subroutine time_fold(n, n_rep)
    integer(i8), intent(in) :: n
    integer, intent(in) :: n_rep
    real(dp), allocatable :: s1(:), s2(:), x(:)
    real(dp) :: t(n_rep), t0
    integer :: i, r
    allocate (s1(n), s2(n), x(n))
    t = 0.0_dp
    do i = 0, n_rep
      s1 = 1.0_dp
      s2 = 1.0_dp
      x = 0.0_dp
      call MPI_Barrier(MPI_COMM_WORLD)
      t0 = MPI_Wtime()
      do r = 1, nranks - 1
        if (rank == r) then
          call MPI_Send(s1, int(n), MPI_DOUBLE_PRECISION, 0, 7, MPI_COMM_WORLD)
          call MPI_Send(s2, int(n), MPI_DOUBLE_PRECISION, 0, 7, MPI_COMM_WORLD)
        else if (rank == 0) then
          call MPI_Recv(x, int(n), MPI_DOUBLE_PRECISION, r, 7, MPI_COMM_WORLD, MPI_STATUS_IGNORE)
          s1 = s1 + x
          call MPI_Recv(x, int(n), MPI_DOUBLE_PRECISION, r, 7, MPI_COMM_WORLD, MPI_STATUS_IGNORE)
          s2 = s2 + x
        end if
      end do
      if (i > 0) t(i) = MPI_Wtime() - t0
    end do
    if (rank == 0 .and. any(s1 /= real(nranks, dp))) error stop 'kumo_collectives: fold sum wrong'
    call report('fold', 16_i8*n, median(t))
  end subroutine time_fold

  !> The fold in a fixed binary tree: ((S_0 + S_1) + (S_2 + S_3)) + ..., whatever the timing.
  subroutine time_tree(n, n_rep)
    integer(i8), intent(in) :: n
    integer, intent(in) :: n_rep
    real(dp), allocatable :: s1(:), s2(:), x(:)
    real(dp) :: t(n_rep), t0
    integer :: i, step
    allocate (s1(n), s2(n), x(n))
    t = 0.0_dp
    do i = 0, n_rep
      s1 = 1.0_dp
      s2 = 1.0_dp
      x = 0.0_dp
      call MPI_Barrier(MPI_COMM_WORLD)
      t0 = MPI_Wtime()
      step = 1
      do while (step < nranks)
        if (mod(rank, 2*step) == 0) then
          if (rank + step < nranks) then
            call MPI_Recv(x, int(n), MPI_DOUBLE_PRECISION, rank + step, 8, MPI_COMM_WORLD, &
                          MPI_STATUS_IGNORE)
            s1 = s1 + x
            call MPI_Recv(x, int(n), MPI_DOUBLE_PRECISION, rank + step, 8, MPI_COMM_WORLD, &
                          MPI_STATUS_IGNORE)
            s2 = s2 + x
          end if
        else if (mod(rank, 2*step) == step) then
          call MPI_Send(s1, int(n), MPI_DOUBLE_PRECISION, rank - step, 8, MPI_COMM_WORLD)
          call MPI_Send(s2, int(n), MPI_DOUBLE_PRECISION, rank - step, 8, MPI_COMM_WORLD)
          exit
        end if
        step = 2*step
      end do
      if (i > 0) t(i) = MPI_Wtime() - t0
    end do
    if (rank == 0 .and. any(s1 /= real(nranks, dp))) error stop 'kumo_collectives: tree sum wrong'
    call report('tree', 16_i8*n, median(t))
  end subroutine time_tree

  !> One MPI_Reduce of S1 and S2 together (2n doubles) to rank 0.
  subroutine time_reduce(n, n_rep)
    integer(i8), intent(in) :: n
    integer, intent(in) :: n_rep
    real(dp), allocatable :: s(:), total(:)
    real(dp) :: t(n_rep), t0
    integer :: i
    allocate (s(2*n), total(2*n))
    s = 1.0_dp
    total = 0.0_dp
    t = 0.0_dp
    do i = 0, n_rep
      call MPI_Barrier(MPI_COMM_WORLD)
      t0 = MPI_Wtime()
      call MPI_Reduce(s, total, int(2*n), MPI_DOUBLE_PRECISION, MPI_SUM, 0, MPI_COMM_WORLD)
      if (i > 0) t(i) = MPI_Wtime() - t0
    end do
    if (rank == 0 .and. any(total /= real(nranks, dp))) error stop 'kumo_collectives: reduce wrong'
    call report('reduce', 16_i8*n, median(t))
  end subroutine time_reduce

  subroutine time_allreduce(n, n_rep)
    integer, intent(in) :: n, n_rep
    real(dp), allocatable :: s(:)
    real(dp) :: t(n_rep), t0
    integer :: i
    allocate (s(n))
    t = 0.0_dp
    do i = 0, n_rep
      s = 1.0_dp
      call MPI_Barrier(MPI_COMM_WORLD)
      t0 = MPI_Wtime()
      call MPI_Allreduce(MPI_IN_PLACE, s, n, MPI_DOUBLE_PRECISION, MPI_SUM, MPI_COMM_WORLD)
      if (i > 0) t(i) = MPI_Wtime() - t0
    end do
    call slowest(t)
    call report('allreduce', 8_i8*n, median(t))
  end subroutine time_allreduce
end program kumo_collectives
