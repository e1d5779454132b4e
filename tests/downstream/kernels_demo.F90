! SPDX-License-Identifier: BSD-3-Clause
!> kumo's kernel library used from another program: plane-parallel scenes built in code, traced
!> with trace_batch, checked against exact answers. Exit status 0 when all agree.
program kernels_demo
  use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
  use kumo_kinds, only: wp, dp, i8
  use kumo_constants, only: KUMO_VERSION
  use kumo_error, only: error_t
  use kumo_rng, only: rng_t, rng_init
  use kumo_phase, only: new_phase_isotropic
  use kumo_atmosphere, only: atmosphere_options_t, atmosphere_init
  use kumo_surface, only: surface_init
  use kumo_camera, only: camera_t
  use kumo_local_estimate, only: detectors_init
  use kumo_tally, only: tally_layout_t, tally_t, layout_init, tally_reset
  use kumo_source, only: solar_source
  use kumo_scene, only: scene_t
  use kumo_transport, only: trace_batch
  implicit none
  type(error_t), allocatable :: error
  type(scene_t) :: scn
  real(dp) :: r, t
  integer :: n_bad

  n_bad = 0
  write (output_unit, '(a)') 'kumo '//KUMO_VERSION//' kernels from an installed library'

  ! Nothing between the sun and a Lambert surface of albedo 0.3: every photon comes back with
  ! weight 0.3, so R = 0.3 and T = 1 exactly.
  call one_layer(0.0_wp, 0.3_wp, 40.0_wp, scn, error)
  call stop_on(error)
  call run(scn, 2000_i8, 11_i8, r, t)
  call expect('transparent over Lambert 0.3: R', r, 0.3_dp)
  call expect('transparent over Lambert 0.3: T', t, 1.0_dp)

  ! A purely absorbing layer of optical depth 0.7 over a black surface, sun at 60 degrees: it is
  ! crossed analytically, so T = exp(-tau/mu0) and R = 0.
  call one_layer(0.7e-3_wp, 0.0_wp, 60.0_wp, scn, error, ssa=0.0_wp)
  call stop_on(error)
  call run(scn, 500_i8, 12_i8, r, t)
  call expect('absorbing layer tau 0.7, sza 60: T', t, exp(-0.7_dp/real(scn%mu0, dp)))
  call expect('absorbing layer tau 0.7, sza 60: R', r, 0.0_dp)

  if (n_bad > 0) then
    write (error_unit, '(a,i0,a)') 'kernels_demo: ', n_bad, ' check(s) failed'
    error stop 1
  end if
  write (output_unit, '(a)') 'kernels_demo: all checks passed'

contains

  !> One layer 1000 m thick (extinction `ext` [m-1], single-scattering albedo `ssa`, isotropic)
  !> over a Lambert surface of albedo `albedo`, domain 1 km x 1 km, sun at `sza_deg`.
  subroutine one_layer(ext, albedo, sza_deg, scn, error, ssa)
    real(wp), intent(in) :: ext, albedo, sza_deg
    type(scene_t), intent(out) :: scn
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: ssa
    type(atmosphere_options_t) :: aopts
    type(camera_t) :: cams(0)
    real(wp) :: omega
    omega = 1.0_wp
    if (present(ssa)) omega = ssa
    call atmosphere_init(scn%atm, [0.0_wp, 1000.0_wp], 1000.0_wp, 1000.0_wp, &
                         reshape([ext], [1, 1]), reshape([omega], [1, 1]), &
                         reshape([1], [1, 1]), [new_phase_isotropic()], aopts, error)
    if (allocated(error)) return
    call surface_init(scn%sfc, reshape([albedo], [1, 1]), 1000.0_wp, 1000.0_wp, error)
    if (allocated(error)) return
    scn%src = solar_source(sza_deg, 0.0_wp)
    scn%mu0 = -scn%src%uz
    call detectors_init(scn%det, [real(wp) ::], [real(wp) ::], [integer ::], cams, 0.0_wp, &
                        scn%atm%lx, scn%atm%ly)
  end subroutine one_layer

  !> One batch of `n` photons: reflectance (upward flux at the top) and transmittance (direct
  !> plus diffuse downward flux at the surface) per incident photon.
  subroutine run(scn, n, seed, r, t)
    type(scene_t), intent(in) :: scn
    integer(i8), intent(in) :: n, seed
    real(dp), intent(out) :: r, t
    type(tally_layout_t) :: lay
    type(tally_t) :: tal
    type(rng_t) :: rng
    call layout_init(lay, scn%atm%nz, scn%atm%nx*scn%atm%ny, scn%atm%n3, [integer ::], .false.)
    call rng_init(rng, seed, 1_i8)
    call tally_reset(tal, lay)
    call trace_batch(scn, lay, rng, n, tal)
    r = tal%buf(lay%i_up + lay%nz + 1)/real(n, dp)
    t = (tal%buf(lay%i_dir + 1) + tal%buf(lay%i_dif + 1))/real(n, dp)
  end subroutine run

  subroutine expect(what, got, want)
    character(len=*), intent(in) :: what
    real(dp), intent(in) :: got, want
    character(len=*), parameter :: fmt = '(a,": ",es23.16," (exact ",es23.16,")",a)'
    if (abs(got - want) <= 1.0e-13_dp) then
      write (output_unit, fmt) what, got, want, ''
    else
      write (output_unit, fmt) what, got, want, '  WRONG'
      n_bad = n_bad + 1
    end if
  end subroutine expect

  subroutine stop_on(error)
    type(error_t), allocatable, intent(in) :: error
    if (allocated(error)) then
      write (error_unit, '(a)') 'kernels_demo: '//error%message
      error stop 1
    end if
  end subroutine stop_on

end program kernels_demo
