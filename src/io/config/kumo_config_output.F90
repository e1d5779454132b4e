! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_output: the output file and its optional products.
!>
!> The parsing and validation of this namelist group (read_output), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_output
  use kumo_config_base
  use kumo_error, only: error_t
  use kumo_math, only: within
  implicit none
  private
  public :: read_output

contains

  subroutine read_output(unit, present, nz, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    integer, intent(in) :: nz
    type(output_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    character(len=PATH_LEN) :: file
    integer :: flux_levels(MAX_LAYERS + 1), map_levels(MAX_LAYERS + 1), ios, i, deflate_level
    logical :: column_fluxes, voxel_absorption
    character(len=512) :: msg
    namelist /kumo_output/ file, flux_levels, column_fluxes, map_levels, voxel_absorption, &
                           deflate_level
    file = cfg%file
    deflate_level = cfg%deflate_level
    flux_levels = IUNSET
    map_levels = IUNSET
    column_fluxes = cfg%column_fluxes
    voxel_absorption = cfg%voxel_absorption
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_output, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_output', present, ios, msg, error, probe)
    if (allocated(error)) return
    call require(len_trim(file) > 0, '&kumo_output: ', 'file', rule='must not be empty', &
                 error=error)
    if (allocated(error)) return
    call level_list('kumo_output', 'flux_levels', flux_levels, nz, [(i, i=0, nz)], &
                    cfg%flux_levels, error)
    if (allocated(error)) return
    ! the per-column maps: at the flux levels, or at a list of their own
    call level_list('kumo_output', 'map_levels', map_levels, nz, cfg%flux_levels, &
                    cfg%map_levels, error)
    if (allocated(error)) return
    call require(column_fluxes .or. all(map_levels == IUNSET), '&kumo_output: ', 'map_levels', &
                 rule='chooses the levels of the per-column flux maps: it needs column_fluxes '// &
                 '= .true.', error=error)
    if (allocated(error)) return
    call require(deflate_level >= 0 .and. deflate_level <= 9, '&kumo_output: ', 'deflate_level', &
                 deflate_level, 'must be within 0..9 (0: no compression)', error)
    if (allocated(error)) return
    cfg%deflate_level = deflate_level
    cfg%file = file
    cfg%column_fluxes = column_fluxes
    cfg%voxel_absorption = voxel_absorption
  contains
    !> Read one assignment of &kumo_output (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_output, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_output, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_output
end module kumo_config_output
