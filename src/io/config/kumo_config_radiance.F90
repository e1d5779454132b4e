! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_radiance: radiance directions and levels.
!>
!> The parsing and validation of this namelist group (read_radiance), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_radiance
  use kumo_config_base
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, str
  use kumo_math, only: within
  implicit none
  private
  public :: read_radiance

contains

  subroutine read_radiance(unit, present, nz, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    integer, intent(in) :: nz
    type(radiance_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: rad_mu(MAX_DIR), rad_phi_deg(MAX_DIR)
    integer :: rad_levels(MAX_LAYERS + 1), ios, n, i
    logical :: radiance_maps
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_radiance: '
    namelist /kumo_radiance/ rad_mu, rad_phi_deg, rad_levels, radiance_maps
    rad_mu = UNSET
    rad_phi_deg = UNSET
    rad_levels = IUNSET
    radiance_maps = cfg%maps
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_radiance, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_radiance', present, ios, msg, error, probe)
    if (allocated(error)) return
    n = count(rad_mu /= UNSET)
    call require(all(rad_mu(n + 1:) == UNSET), CTX, 'rad_mu', rule='must be a list without gaps', &
                 error=error)
    call require(all(rad_phi_deg(n + 1:) == UNSET), CTX, 'rad_phi_deg', &
                 rule='has more entries than rad_mu ('//str(n)//')', error=error)
    if (allocated(error)) return
    do i = 1, n
      call require(within(abs(rad_mu(i)), 1.0e-6_wp, 1.0_wp), CTX, 'rad_mu('//str(i)//')', &
                   rad_mu(i), 'must satisfy 1e-6 <= |rad_mu| <= 1 (> 0: upward, < 0: downward)', &
                   error)
      if (allocated(error)) return
      if (rad_phi_deg(i) == UNSET) rad_phi_deg(i) = 0.0_wp
      call require(ieee_is_finite(rad_phi_deg(i)), CTX, 'rad_phi_deg('//str(i)//')', &
                   rule='must be finite', error=error)
      if (allocated(error)) return
    end do
    call level_list('kumo_radiance', 'rad_levels', rad_levels, nz, [0, nz], cfg%levels, error)
    if (allocated(error)) return
    cfg%mu = rad_mu(1:n)
    cfg%phi_deg = rad_phi_deg(1:n)
    cfg%maps = radiance_maps
  contains
    !> Read one assignment of &kumo_radiance (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_radiance, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_radiance, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_radiance
end module kumo_config_radiance
