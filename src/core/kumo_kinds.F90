! SPDX-License-Identifier: BSD-3-Clause
!> Kind parameters: working precision for geometry and optics, tallies and counters.
module kumo_kinds
  use, intrinsic :: iso_fortran_env, only: real32, real64, int32, int64
  implicit none
  private
  public :: sp, dp, wp, vp, i4, i8

  integer, parameter :: sp = real32  !! single precision
  integer, parameter :: dp = real64  !! double precision (tallies and statistics always use it)
  integer, parameter :: wp = dp      !! working precision for geometry and optics
  !> precision of the per-voxel optics of the 3-D region (extinction, albedo, scattering
  !> fractions, phase blend weights): single, which halves the memory of large fields; every
  !> computation with them is done in wp
  integer, parameter :: vp = sp
  integer, parameter :: i4 = int32   !! default integers
  integer, parameter :: i8 = int64   !! photon counters and random-number state
end module kumo_kinds
