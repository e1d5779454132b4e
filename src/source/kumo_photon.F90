! SPDX-License-Identifier: BSD-3-Clause
!> The state of one photon packet, as the sources launch it and the photon loop carries it.
module kumo_photon
  use kumo_kinds, only: wp, i8
  implicit none
  private
  public :: photon_t

  !> A photon packet: where it is, where it goes, what it carries and what it has done.
  type :: photon_t
    real(wp) :: x = 0.0_wp, y = 0.0_wp, z = 0.0_wp     !! position [m]
    real(wp) :: ux = 0.0_wp, uy = 0.0_wp, uz = -1.0_wp !! direction of propagation (unit)
    real(wp) :: w = 1.0_wp        !! weight (energy carried, in units of the launch weight)
    integer :: iz = 1             !! layer the photon is in (1 .. nz, from the bottom)
    integer :: order = 0          !! scatterings and reflections so far (0: direct)
    integer :: lev = 1            !! truncation level of the next scattering (1: none)
    logical :: column = .false.   !! keeps its column (ICA, and P3D beyond its 3-D orders)
    logical :: secondary = .false. !! a DDIS secondary (does not split again)
    integer(i8) :: n_events = 0_i8 !! collisions and reflections so far
    integer(i8) :: n_steps = 0_i8  !! flight steps so far (null collisions and faces included)
    ! Thermal emission (kumo_emission): where the photon was emitted, for the net-exchange
    ! bookkeeping of heating rates; all zero for solar photons.
    integer :: emitter = 0        !! EMIT_* kind of its source (0: the sun)
    integer :: em_k = 0           !! layer of the emission point (atmospheric emission)
    integer :: em_v = 0           !! voxel of the emission point (1 .. ncol*n3; 0: a 1-D layer)
    real(wp) :: rbe = 0.0_wp      !! 1/B at the emission point (0: not a thermal photon)
    real(wp) :: w_entry = 0.0_wp  !! weight of its table entry (before a surface's eps(mu)/<eps>)
  end type photon_t

end module kumo_photon
