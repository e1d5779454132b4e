! SPDX-License-Identifier: BSD-3-Clause
!> Physical and mathematical constants, and the kumo version string.
module kumo_constants
  use kumo_kinds, only: wp
  implicit none
  private
  public :: PI, TWO_PI, FOUR_PI, DEG2RAD, RAD2DEG, SECONDS_PER_DAY, CP_DRY_AIR, KUMO_VERSION

  character(len=*), parameter :: KUMO_VERSION = '0.1.0'        !! kumo release
  real(wp), parameter :: PI = 3.141592653589793238462643383279502884_wp
  real(wp), parameter :: TWO_PI = 2.0_wp*PI
  real(wp), parameter :: FOUR_PI = 4.0_wp*PI
  real(wp), parameter :: DEG2RAD = PI/180.0_wp
  real(wp), parameter :: RAD2DEG = 180.0_wp/PI
  real(wp), parameter :: SECONDS_PER_DAY = 86400.0_wp
  !> Specific heat of dry air at constant pressure [J kg-1 K-1] (WMO International
  !> Meteorological Tables value, 1004.64).
  real(wp), parameter :: CP_DRY_AIR = 1004.64_wp
end module kumo_constants
