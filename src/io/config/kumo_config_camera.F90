! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_camera: cameras.
!>
!> The parsing and validation of this namelist group (read_camera), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_camera
  use kumo_config_base
  use kumo_kinds, only: wp, i8
  use kumo_error, only: error_t, set_error, str, to_lower
  use kumo_math, only: within
  implicit none
  private
  public :: read_camera

contains

  subroutine read_camera(unit, present, atm, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(atmosphere_cfg_t), intent(in) :: atm
    type(camera_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: M = MAX_CAMERAS
    integer :: n_cameras, cam_npx(M), cam_npy(M), ios, i, n
    character(len=16) :: cam_kind(M)
    real(wp) :: cam_x(M), cam_y(M), cam_z(M), cam_look_zenith_deg(M), cam_look_azimuth_deg(M)
    real(wp) :: cam_roll_deg(M), cam_fov_deg(M), cam_width(M)
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_camera: '
    namelist /kumo_camera/ n_cameras, cam_kind, cam_x, cam_y, cam_z, cam_look_zenith_deg, &
      cam_look_azimuth_deg, cam_roll_deg, cam_fov_deg, cam_width, cam_npx, cam_npy
    n_cameras = 0
    cam_kind = 'pinhole'
    cam_x = 0.5_wp*atm%lx
    cam_y = 0.5_wp*atm%ly
    cam_z = UNSET
    cam_look_zenith_deg = 180.0_wp
    cam_look_azimuth_deg = 0.0_wp
    cam_roll_deg = 0.0_wp
    cam_fov_deg = 30.0_wp
    cam_width = atm%lx
    cam_npx = 64
    cam_npy = 64
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_camera, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_camera', present, ios, msg, error, probe)
    if (allocated(error)) return
    call require(n_cameras >= 0 .and. n_cameras <= M, CTX, 'n_cameras', n_cameras, &
                 'must be within 0..'//str(M), error)
    if (allocated(error)) return
    do i = 1, n_cameras
      cam_kind(i) = to_lower(adjustl(cam_kind(i)))
      call require(cam_kind(i) == 'pinhole' .or. cam_kind(i) == 'orthographic', CTX, &
                   'cam_kind('//str(i)//')', cam_kind(i), 'must be "pinhole" or "orthographic"', &
                   error)
      call require(cam_z(i) /= UNSET, CTX, 'cam_z('//str(i)//')', rule='must be given [m]', &
                   error=error)
      if (allocated(error)) return
      if (cam_npx(i) < 1 .or. cam_npy(i) < 1 .or. &
          int(cam_npx(i), i8)*cam_npy(i) > 16777216_i8) then
        call set_error(error, CTX//'cam_npx('//str(i)//') and cam_npy('//str(i)// &
                       ') must be >= 1, with at most 16777216 pixels')
        return
      end if
    end do
    n = n_cameras
    cfg%n = n
    cfg%kind = cam_kind(1:n)
    allocate (cfg%pos(3, n))
    cfg%pos(1, :) = cam_x(1:n)
    cfg%pos(2, :) = cam_y(1:n)
    cfg%pos(3, :) = cam_z(1:n)
    cfg%look_zenith_deg = cam_look_zenith_deg(1:n)
    cfg%look_azimuth_deg = cam_look_azimuth_deg(1:n)
    cfg%roll_deg = cam_roll_deg(1:n)
    cfg%fov_deg = cam_fov_deg(1:n)
    cfg%width = cam_width(1:n)
    cfg%npx = cam_npx(1:n)
    cfg%npy = cam_npy(1:n)
  contains
    !> Read one assignment of &kumo_camera (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_camera, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_camera, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_camera
end module kumo_config_camera
