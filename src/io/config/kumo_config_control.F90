! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_control: the photon budget, seed, stopping rule and solver mode.
!>
!> The parsing and validation of this namelist group (read_control), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_control
  use kumo_config_base
  use kumo_kinds, only: wp, i8
  use kumo_error, only: error_t, str, to_lower, join
  use kumo_math, only: within
  implicit none
  private
  public :: read_control, TARGET_NAMES, MODE_NAMES

  character(len=16), parameter :: TARGET_NAMES(3) = &
    [character(len=16) :: 'reflectance', 'transmittance', 'absorptance']
  !> Transport modes: full 3-D, independent columns, 3-D for the first scattering orders.
  character(len=8), parameter :: MODE_NAMES(3) = [character(len=8) :: 'f3d', 'ica', 'p3d']

contains

  subroutine read_control(unit, present, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(control_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    integer(i8) :: n_photons_per_batch, seed, max_photons, max_events
    integer :: n_batches, verbose, ios, p3d_orders
    real(wp) :: target_rel_error, checkpoint_interval
    logical :: one_scene_per_node
    character(len=16) :: target_output
    character(len=8) :: mode_3d
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_control: '
    namelist /kumo_control/ n_photons_per_batch, n_batches, seed, target_rel_error, &
      target_output, max_photons, max_events, verbose, mode_3d, p3d_orders, checkpoint_interval, &
      one_scene_per_node
    n_photons_per_batch = cfg%n_photons_per_batch
    n_batches = cfg%n_batches
    seed = cfg%seed
    target_rel_error = cfg%target_rel_error
    target_output = cfg%target_output
    max_photons = cfg%max_photons
    max_events = cfg%max_events
    verbose = cfg%verbose
    mode_3d = cfg%mode_3d
    p3d_orders = cfg%p3d_orders
    checkpoint_interval = cfg%checkpoint_interval
    one_scene_per_node = cfg%one_scene_per_node
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_control, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_control', present, ios, msg, error, probe)
    if (allocated(error)) return
    cfg%n_photons_per_batch = n_photons_per_batch
    cfg%n_batches = n_batches
    cfg%seed = seed
    cfg%target_rel_error = target_rel_error
    cfg%target_output = to_lower(target_output)
    cfg%max_photons = max_photons
    cfg%max_events = max_events
    cfg%verbose = verbose
    cfg%mode_3d = to_lower(mode_3d)
    cfg%p3d_orders = p3d_orders
    cfg%checkpoint_interval = checkpoint_interval
    cfg%one_scene_per_node = one_scene_per_node
    call require(n_photons_per_batch >= 1, CTX, 'n_photons_per_batch', n_photons_per_batch, &
                 'must be >= 1', error)
    call require(n_batches >= 2, CTX, 'n_batches', n_batches, &
                 'must be >= 2 (batches give the standard error)', error)
    call require(seed >= 0, CTX, 'seed', seed, 'must be >= 0', error)
    call require(within(target_rel_error, 0.0_wp, BIG), CTX, 'target_rel_error', &
                 target_rel_error, 'must be >= 0 (0 = fixed photon budget)', error)
    call require(findloc(TARGET_NAMES == cfg%target_output, .true., 1) > 0, CTX, 'target_output', &
                 target_output, 'must be one of '//join(TARGET_NAMES), error)
    call require(max_photons >= 1, CTX, 'max_photons', max_photons, 'must be >= 1', error)
    if (.not. allocated(error)) then
      call require(n_photons_per_batch <= MAX_TOTAL_PHOTONS/n_batches, CTX, &
                   'n_photons_per_batch', n_photons_per_batch, 'times n_batches = '// &
                   str(n_batches)//' must be <= 2^53 = '//str(MAX_TOTAL_PHOTONS)// &
                   ' photons (beyond, counts overflow or lose exactness in the tallies)', error)
      call require(max_photons <= MAX_TOTAL_PHOTONS, CTX, 'max_photons', max_photons, &
                   'must be <= 2^53 = '//str(MAX_TOTAL_PHOTONS), error)
    end if
    call require(max_events >= 1, CTX, 'max_events', max_events, 'must be >= 1', error)
    call require(findloc(MODE_NAMES == cfg%mode_3d, .true., 1) > 0, CTX, 'mode_3d', mode_3d, &
                 'must be one of '//join(MODE_NAMES), error)
    call require(p3d_orders >= 0, CTX, 'p3d_orders', p3d_orders, 'must be >= 0', error)
    call require(within(checkpoint_interval, 0.0_wp, BIG), CTX, 'checkpoint_interval', &
                 checkpoint_interval, 'must be >= 0 s (0 = no checkpoints)', error)
  contains
    !> Read one assignment of &kumo_control (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_control, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_control, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_control
end module kumo_config_control
