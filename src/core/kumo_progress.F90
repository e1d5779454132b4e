! SPDX-License-Identifier: BSD-3-Clause
!> Progress lines of a run on standard error (rank 0): batches done, photons per second, and
!> the time left (a fixed number of batches) or the target's relative error (target-error
!> mode). The first line comes after `first` seconds, the next ones every `every` seconds.
!>
!> The driver reports at the end of each batch (`progress_batch_done`). A batch that lasts
!> longer than the interval would leave a job silent, so `trace_batch` also looks at the clock
!> from inside a batch (`progress_look`): every `stride` photons, a stride sized so that the
!> looks come about every LOOK_EVERY seconds. Between looks the photon loop pays one integer
!> comparison per photon.
!>
!> Batches done are counted from rank 0's batch: the other ranks trace theirs alongside, so
!> while rank 0 is a fraction f into batch ib, about ib - 1 + f * n_ranks batches are done.
module kumo_progress
  use, intrinsic :: iso_fortran_env, only: error_unit
  use kumo_kinds, only: dp, i8
  use kumo_error, only: str
  implicit none
  private
  public :: progress_t, progress_start, progress_batch_begin, progress_batch_done, progress_look
  public :: PROGRESS_FIRST, PROGRESS_EVERY

  !> For runs longer than a few seconds: the first line after PROGRESS_FIRST seconds, then one
  !> every PROGRESS_EVERY seconds.
  real(dp), parameter :: PROGRESS_FIRST = 5.0_dp, PROGRESS_EVERY = 15.0_dp
  !> Seconds between two looks at the clock inside a batch.
  real(dp), parameter :: LOOK_EVERY = 0.25_dp

  type :: progress_t
    logical :: on = .false.
    real(dp) :: first = PROGRESS_FIRST   !! seconds before the first line
    real(dp) :: every = PROGRESS_EVERY   !! seconds between lines
    real(dp) :: t0 = 0.0_dp          !! start of tracing [s]
    real(dp) :: next = 0.0_dp        !! time of the next line [s]
    real(dp) :: rel = -1.0_dp        !! relative error of the target after the last round
    real(dp) :: target = 0.0_dp      !! target relative error (0: a fixed number of batches)
    character(len=:), allocatable :: target_name
    integer :: n0 = 0                !! batches done before this run (resumed from a checkpoint)
    integer :: n_planned = 0         !! last batch of the current round
    integer :: n_ranks = 1
    integer(i8) :: n_phot = 1        !! photons per batch
    ! inside rank 0's current batch
    integer :: ib = 0                !! the batch
    integer(i8) :: base = 0          !! its photons traced by earlier calls of trace_batch
    integer(i8) :: next_look = 0     !! its photon count at which to look at the clock next
    integer(i8) :: stride = 64       !! photons between looks
    integer(i8) :: n_look = 0        !! its photon count at the last look
    real(dp) :: t_look = 0.0_dp      !! time of the last look [s]
  end type progress_t

contains

  !> Progress of a run that starts tracing now: `n0` batches were done before (a resumed run),
  !> batches of `n_phot` photons over `n_ranks` ranks; `target` > 0 in target-error mode.
  subroutine progress_start(pg, on, n0, n_phot, n_ranks, target, target_name, first, every)
    type(progress_t), intent(out) :: pg
    logical, intent(in) :: on
    integer, intent(in) :: n0, n_ranks
    integer(i8), intent(in) :: n_phot
    real(dp), intent(in) :: target, first, every
    character(len=*), intent(in) :: target_name
    pg%on = on
    pg%first = first
    pg%every = every
    pg%t0 = wall_clock()
    pg%next = pg%t0 + first
    pg%n0 = n0
    pg%n_phot = max(1_i8, n_phot)
    pg%n_ranks = max(1, n_ranks)
    pg%target = target
    pg%target_name = trim(target_name)
  end subroutine progress_start

  !> Rank 0 starts tracing batch `ib`; `n_planned` is the last batch of the round.
  subroutine progress_batch_begin(pg, ib, n_planned)
    type(progress_t), intent(inout) :: pg
    integer, intent(in) :: ib, n_planned
    if (.not. pg%on) return
    pg%ib = ib
    pg%n_planned = n_planned
    pg%base = 0
    pg%n_look = 0
    pg%t_look = wall_clock()
    pg%next_look = pg%stride
  end subroutine progress_batch_begin

  !> Rank 0 has finished batch `ib` of a round that ends with batch `n_planned`.
  subroutine progress_batch_done(pg, ib, n_planned)
    type(progress_t), intent(inout) :: pg
    integer, intent(in) :: ib, n_planned
    if (.not. pg%on) return
    pg%n_planned = n_planned
    call report(pg, real(ib - 1 + pg%n_ranks, dp), wall_clock())
  end subroutine progress_batch_done

  !> From inside rank 0's batch: `n` of its photons are traced. Sizes the stride to the next
  !> look from the photons traced since the last one, and prints a line when one is due.
  subroutine progress_look(pg, n)
    type(progress_t), intent(inout) :: pg
    integer(i8), intent(in) :: n
    real(dp) :: t, dt, f
    t = wall_clock()
    dt = t - pg%t_look
    if (dt > 0.0_dp) then
      ! at most doubled per look, so one quick stretch cannot put the next look far off
      pg%stride = max(1_i8, min(2*pg%stride, int(real(n - pg%n_look, dp)*LOOK_EVERY/dt, i8)))
    else
      pg%stride = 2*pg%stride
    end if
    pg%n_look = n
    pg%t_look = t
    pg%next_look = n + pg%stride
    f = min(1.0_dp, real(n, dp)/real(pg%n_phot, dp))
    call report(pg, real(pg%ib - 1, dp) + f*pg%n_ranks, t)
  end subroutine progress_look

  !> A line when one is due at time t, with `done_in` batches done (fractional inside a batch).
  subroutine report(pg, done_in, t)
    type(progress_t), intent(inout) :: pg
    real(dp), intent(in) :: done_in, t
    real(dp) :: rate, done
    character(len=:), allocatable :: line
    done = done_in
    if (pg%target <= 0.0_dp) done = min(done, real(pg%n_planned, dp))
    if (t < pg%next .or. done <= pg%n0) return
    pg%next = t + pg%every
    rate = (done - pg%n0)*real(pg%n_phot, dp)/max(t - pg%t0, 1.0e-9_dp)
    if (pg%target > 0.0_dp) then
      line = 'kumo: '//batches(done)//' batches, '//str(real(nint(rate), dp))//' photons/s'
      if (pg%rel >= 0.0_dp) line = line//', '//pg%target_name//' relative error '// &
        str(pg%rel, 3)//' (target '//str(pg%target)//')'
    else
      line = 'kumo: '//batches(done)//' of '//str(pg%n_planned)//' batches ('// &
             str(nint(100.0_dp*done/pg%n_planned))//' %), '// &
             str(real(nint(rate), dp))//' photons/s, about '// &
             str(nint(max(0.0_dp, (t - pg%t0)*(pg%n_planned - done)/(done - pg%n0))))// &
             ' s left'
    end if
    write (error_unit, '(a)') line
    flush (error_unit)
  end subroutine report

  !> Batches done: a whole number, or with one decimal inside a batch.
  function batches(done) result(s)
    real(dp), intent(in) :: done
    character(len=:), allocatable :: s
    if (abs(done - anint(done)) < 0.05_dp) then
      s = str(nint(done))
    else
      s = str(anint(10.0_dp*done)/10.0_dp)
    end if
  end function batches

  !> Wall-clock time [s] from the system clock (64-bit counts).
  real(dp) function wall_clock() result(t)
    integer(i8) :: count, rate
    call system_clock(count, rate)
    t = real(count, dp)/real(max(rate, 1_i8), dp)
  end function wall_clock

end module kumo_progress
