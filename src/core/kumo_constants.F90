! SPDX-License-Identifier: BSD-3-Clause
!> Physical and mathematical constants, and the kumo version string.
module kumo_constants
  use kumo_kinds, only: wp
  implicit none
  private
  public :: PI, TWO_PI, FOUR_PI, DEG2RAD, RAD2DEG, SECONDS_PER_DAY, CP_DRY_AIR, KUMO_VERSION
  public :: PLANCK_H, SPEED_OF_LIGHT, BOLTZMANN_K, STEFAN_BOLTZMANN

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
  !> Planck constant [J s], speed of light in vacuum [m s-1] and Boltzmann constant [J K-1]:
  !> exact values of the SI since 2019 (CODATA 2018, Tiesinga et al. 2021, Rev. Mod. Phys. 93,
  !> 025010).
  real(wp), parameter :: PLANCK_H = 6.62607015e-34_wp
  real(wp), parameter :: SPEED_OF_LIGHT = 299792458.0_wp
  real(wp), parameter :: BOLTZMANN_K = 1.380649e-23_wp
  !> Stefan-Boltzmann constant [W m-2 K-4], 2 pi^5 k^4/(15 h^3 c^2) = 5.670374419e-8 (CODATA
  !> 2018, exact value truncated to 10 digits in the tables).
  real(wp), parameter :: STEFAN_BOLTZMANN = 2.0_wp*PI**5*BOLTZMANN_K**4/(15.0_wp*PLANCK_H**3*SPEED_OF_LIGHT**2)
end module kumo_constants
