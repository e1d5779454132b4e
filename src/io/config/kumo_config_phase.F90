! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_phase: phase functions.
!>
!> The parsing and validation of this namelist group (read_phase), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_phase
  use kumo_config_base
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, str, to_lower
  use kumo_phase, only: phase_kind_from_name
  use kumo_math, only: within
  implicit none
  private
  public :: read_phase

contains

  subroutine read_phase(unit, present, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(phase_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    integer :: n_phase, n_table, ios, i
    character(len=16) :: phase_kind(MAX_PHASE)
    real(wp) :: phase_g(MAX_PHASE)
    character(len=PATH_LEN) :: phase_file(MAX_PHASE)
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_phase: '
    namelist /kumo_phase/ n_phase, phase_kind, phase_g, phase_file, n_table
    n_phase = 1
    phase_kind = 'isotropic'
    phase_g = 0.0_wp
    phase_file = ''
    n_table = cfg%n_table
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_phase, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_phase', present, ios, msg, error, probe)
    if (allocated(error)) return
    call require(n_phase >= 1 .and. n_phase <= MAX_PHASE, CTX, 'n_phase', n_phase, &
                 'must be within 1..'//str(MAX_PHASE), error)
    call require(n_table >= 100, CTX, 'n_table', n_table, 'must be >= 100', error)
    if (allocated(error)) return
    allocate (cfg%kind(n_phase))
    do i = 1, n_phase
      call phase_kind_from_name(phase_kind(i), cfg%kind(i), error)
      if (allocated(error)) then
        error%message = '&kumo_phase: phase_kind('//str(i)//'): '//error%message
        return
      end if
      call require(within(phase_g(i), nearest(-1.0_wp, 1.0_wp), nearest(1.0_wp, -1.0_wp)), CTX, &
                   'phase_g('//str(i)//')', phase_g(i), 'must satisfy |g| < 1', error)
      call require(trim(to_lower(phase_kind(i))) /= 'table' .or. len_trim(phase_file(i)) > 0, &
                   CTX, 'phase_file('//str(i)//')', rule='is needed for a table', error=error)
      if (allocated(error)) return
    end do
    cfg%n_phase = n_phase
    cfg%kind_name = phase_kind(1:n_phase)
    cfg%g = phase_g(1:n_phase)
    cfg%file = phase_file(1:n_phase)
    cfg%n_table = n_table
  contains
    !> Read one assignment of &kumo_phase (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_phase, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_phase, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_phase
end module kumo_config_phase
