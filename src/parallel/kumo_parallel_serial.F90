! SPDX-License-Identifier: BSD-3-Clause
!> Serial build of kumo_parallel: one rank, every operation is trivial.
module kumo_parallel
  use kumo_kinds, only: dp, i8
  implicit none
  private
  public :: par_init, par_finalize, par_rank, par_size, par_is_root, par_sum_to_root, &
            par_allreduce_sum, par_abort, par_barrier, par_wtime, par_bcast_int, par_bcast_real, PAR_IS_MPI

  logical, parameter :: PAR_IS_MPI = .false.  !! this build runs on one process

  interface par_sum_to_root
    module procedure sum_to_root_dp, sum_to_root_i8
  end interface par_sum_to_root

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

  subroutine par_abort(code)
    integer, intent(in) :: code
    if (code == 2) stop 2
    stop 1
  end subroutine par_abort
end module kumo_parallel
