! SPDX-License-Identifier: BSD-3-Clause
!> Serial build of kumo_parallel: one rank, every operation is trivial.
module kumo_parallel
  use, intrinsic :: iso_c_binding, only: c_int
  use kumo_kinds, only: dp, i8
  implicit none
  private
  public :: par_init, par_finalize, par_rank, par_size, par_is_root, par_sum_to_root, &
            par_allreduce_sum, par_abort, par_barrier, par_wtime, par_bcast_int, par_bcast_real, PAR_IS_MPI
  public :: par_stop

  logical, parameter :: PAR_IS_MPI = .false.  !! this build runs on one process

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

  subroutine par_bcast_int(buf)
    integer, intent(inout) :: buf(:)
    if (size(buf) < 0) buf = 0
  end subroutine par_bcast_int

  subroutine par_bcast_real(buf)
    real(dp), intent(inout) :: buf(:)
    if (size(buf) < 0) buf = 0.0_dp
  end subroutine par_bcast_real

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
