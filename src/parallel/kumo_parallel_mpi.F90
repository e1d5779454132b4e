! SPDX-License-Identifier: BSD-3-Clause
!> MPI edges of kumo: start/stop, rank queries, broadcasts and the one reduction of the tallies.
!>
!> The only module that uses MPI. A serial build compiles kumo_parallel_serial.F90 instead, which
!> provides the same module with trivial bodies.
module kumo_parallel
  use mpi_f08, only: MPI_Init, MPI_Initialized, MPI_Finalize, MPI_Finalized, MPI_Comm_rank, &
    MPI_Comm_size, MPI_Reduce, MPI_Allreduce, MPI_Bcast, MPI_Barrier, MPI_Wtime, MPI_Abort, &
    MPI_COMM_WORLD, MPI_IN_PLACE, MPI_DOUBLE_PRECISION, MPI_INTEGER, MPI_INTEGER8, MPI_SUM
  use mpi_f08, only: MPI_Ibarrier, MPI_Test, MPI_Request, MPI_STATUS_IGNORE
  use, intrinsic :: iso_c_binding, only: c_int
  use kumo_kinds, only: dp, i8
  implicit none
  private
  public :: par_init, par_finalize, par_rank, par_size, par_is_root, par_sum_to_root, &
            par_allreduce_sum, par_abort, par_barrier, par_wtime, par_bcast_int, par_bcast_real, PAR_IS_MPI
  public :: par_stop

  logical, parameter :: PAR_IS_MPI = .true.  !! this build distributes batches over MPI ranks

  interface par_sum_to_root
    module procedure sum_to_root_dp, sum_to_root_i8
  end interface par_sum_to_root

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
  end subroutine par_init

  subroutine par_finalize()
    logical :: flag
    call MPI_Finalized(flag)
    if (.not. flag) call MPI_Finalize()
  end subroutine par_finalize

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

  !> Broadcast integers from rank 0.
  subroutine par_bcast_int(buf)
    integer, intent(inout) :: buf(:)
    call MPI_Bcast(buf, size(buf), MPI_INTEGER, 0, MPI_COMM_WORLD)
  end subroutine par_bcast_int

  !> Broadcast doubles from rank 0 (in chunks, so arrays of any size fit MPI's int counts).
  subroutine par_bcast_real(buf)
    real(dp), intent(inout) :: buf(:)
    integer(i8) :: i0, n
    integer, parameter :: CHUNK = 2**27
    n = size(buf, kind=i8)
    i0 = 1
    do while (i0 <= n)
      call MPI_Bcast(buf(i0:min(n, i0 + CHUNK - 1)), int(min(int(CHUNK, i8), n - i0 + 1)), &
                     MPI_DOUBLE_PRECISION, 0, MPI_COMM_WORLD)
      i0 = i0 + CHUNK
    end do
  end subroutine par_bcast_real

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
    real(dp), parameter :: ABORT_GRACE_S = 5.0_dp
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
