! SPDX-License-Identifier: BSD-3-Clause
!> The scene: everything the photon loop reads, in one read-only object.
!>
!> A scene can be built from a namelist (kumo_driver's `setup_scene`, which reads the input
!> files) or directly in code (tests, library users): it holds no file, MPI or netCDF state, so
!> `trace_batch` runs on it with the kernel library alone.
module kumo_scene
  use kumo_kinds, only: wp, i8
  use kumo_atmosphere, only: atmosphere_t
  use kumo_surface, only: surface_t
  use kumo_source, only: source_t
  use kumo_vr, only: vr_t
  use kumo_local_estimate, only: detectors_t
  implicit none
  private
  public :: scene_t

  !> Everything the photon loop reads.
  type :: scene_t
    type(atmosphere_t) :: atm
    type(surface_t) :: sfc
    type(source_t) :: src
    type(vr_t) :: vr                         !! variance-reduction settings
    type(detectors_t) :: det                 !! radiance detectors and cameras
    !> Transport mode: photons move horizontally only while their scattering order (scatterings
    !> and reflections so far) is below n_3d; afterwards they stay in their column. huge: F3D;
    !> 0: ICA (every column a plane-parallel atmosphere); N: P3D.
    integer :: n_3d = huge(1)
    integer(i8) :: max_events = 100000000_i8 !! collisions + reflections per photon
    integer(i8) :: max_steps = 100000000000_i8 !! flight steps per photon (1000 x max_events)
    real(wp) :: mu0 = 1.0_wp                 !! cosine of the solar zenith angle
    real(wp), allocatable :: air_density(:)  !! (nz) [kg m-3] for heating rates, if known
    !> thermal runs: a non-scattering column is solved exactly instead of traced (kumo_exact_column)
    logical :: exact_thermal = .true.
    character(len=:), allocatable :: notes    !! how the scene was built, for the log
    character(len=:), allocatable :: warnings !! for the log and the output file
  end type scene_t

end module kumo_scene
