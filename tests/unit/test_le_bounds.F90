! SPDX-License-Identifier: BSD-3-Clause
!> The bound table of the level detectors' roulette (kumo_local_estimate, detectors_bounds and
!> density_bound): on a dense grid of scattering-angle cosines, including the table nodes and
!> the bin edges, the bound is never below the angular density P^/(4 pi) that the local estimate
!> uses (phase_eval, or trunc_eval/(1 - f) when truncated), for a sharp tabulated forward peak,
!> Henyey-Greenstein with g of either sign, Rayleigh and isotropic; and it is tight where the
!> function is flat (isotropic: the bound is the value itself up to the safety factor). The DDIS
!> weight factor (ddis_factor) is the balance heuristic P_in/(P_in + eps mean_d P_d 1[cone_d]),
!> and exactly 1 outside every detector's cone.
module test_le_bounds_suite
  use kumo_kinds, only: wp
  use kumo_constants, only: PI, DEG2RAD
  use kumo_testing, only: error_t, unittest_t, new_unittest, check
  use kumo_phase, only: phase_t, new_phase_isotropic, new_phase_rayleigh, new_phase_hg, &
                        phase_from_table, phase_eval, hg_eval
  use kumo_truncation, only: truncation_init, trunc_eval
  use kumo_atmosphere, only: atmosphere_t
  use kumo_camera, only: camera_t
  use kumo_local_estimate, only: detectors_t, detectors_init, detectors_bounds, density_bound, &
                                 ddis_factor
  implicit none
  private
  public :: collect_le_bounds

  integer, parameter :: N_GRID = 400000   !! test points in mu (bins of the table: 128)

contains

  function collect_le_bounds() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('bounds_untruncated', test_untruncated), &
             new_unittest('bounds_truncated', test_truncated), &
             new_unittest('no_table_without_roulette', test_no_roulette), &
             new_unittest('ddis_factor_is_the_balance_heuristic', test_ddis_factor)]
  end function collect_le_bounds

  !> Henyey-Greenstein g = 0.97 tabulated on 0, 0.1, ..., 180 deg (P(0) about 2200), HG
  !> 0.85 and -0.4 in closed form, Rayleigh, isotropic.
  function test_phases() result(phases)
    type(phase_t) :: phases(5)
    type(error_t), allocatable :: err
    real(wp) :: angle(1801)
    integer :: j
    angle = [(0.1_wp*j, j=0, 1800)]
    angle(1801) = 180.0_wp
    phases(1) = phase_from_table(angle, hg_eval(0.97_wp, cos(angle*DEG2RAD)), error=err)
    if (allocated(err)) error stop 'phase_from_table failed in the test set-up'
    phases(2) = new_phase_hg(0.85_wp, err)
    if (allocated(err)) error stop 'new_phase_hg failed in the test set-up'
    phases(3) = new_phase_hg(-0.4_wp, err)
    if (allocated(err)) error stop 'new_phase_hg failed in the test set-up'
    phases(4) = new_phase_rayleigh()
    phases(5) = new_phase_isotropic()
  end function test_phases

  !> Detectors with one direction and roulette zeta_min 0.3.
  subroutine make_detectors(det, zeta_min)
    type(detectors_t), intent(out) :: det
    real(wp), intent(in) :: zeta_min
    type(camera_t) :: cams(0)
    call detectors_init(det, [1.0_wp], [0.0_wp], [1], cams, zeta_min, 1.0_wp, 1.0_wp)
  end subroutine make_detectors

  !> Density of the local estimate at mu (as particle_density of kumo_local_estimate).
  real(wp) function density(atm, iph, lev, mu) result(a)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: iph, lev
    real(wp), intent(in) :: mu
    if (atm%truncated) then
      a = trunc_eval(atm%trunc, atm%phases(iph), iph, lev, mu)/ &
          (4.0_wp*PI*(1.0_wp - atm%trunc%f(lev, iph)))
    else
      a = phase_eval(atm%phases(iph), mu)/(4.0_wp*PI)
    end if
  end function density

  !> The bound holds at every grid point, every table node of the sharp table and every bin
  !> edge; the isotropic function's bound is its value times the safety factor.
  subroutine check_bounds(error, atm, n_lev)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: n_lev
    type(detectors_t) :: det
    integer :: iph, lev, i, n_bad
    real(wp) :: mu
    call make_detectors(det, 0.3_wp)
    call detectors_bounds(det, atm)
    call check(error, allocated(det%p_bound), 'bound table built')
    if (allocated(error)) return
    n_bad = 0
    do iph = 1, size(atm%phases)
      do lev = 1, n_lev
        do i = 0, N_GRID
          mu = -1.0_wp + 2.0_wp*real(i, wp)/N_GRID
          call one(mu)
        end do
        do i = 1, size(atm%phases(1)%mu_tab)
          call one(atm%phases(1)%mu_tab(i))
        end do
        do i = 0, 128
          call one(-1.0_wp + 2.0_wp*real(i, wp)/128)
          call one(nearest(-1.0_wp + 2.0_wp*real(i, wp)/128, 1.0_wp))
          call one(nearest(-1.0_wp + 2.0_wp*real(i, wp)/128, -1.0_wp))
        end do
      end do
    end do
    call check(error, n_bad == 0, 'the bound is below the density at some cosines')
    if (allocated(error)) return
    ! isotropic (last phase, untruncated at every level): tight up to the safety factor
    call check(error, abs(density_bound(det, size(atm%phases), 1, 0.3_wp)*4.0_wp*PI - 1.001_wp) &
               < 1.0e-12_wp, 'isotropic bound is the value times the safety factor')
  contains
    subroutine one(m)
      real(wp), intent(in) :: m
      real(wp) :: mm, a, b
      mm = min(1.0_wp, max(-1.0_wp, m))
      a = density(atm, iph, lev, mm)
      b = density_bound(det, iph, lev, mm)
      if (b < a) n_bad = n_bad + 1
    end subroutine one
  end subroutine check_bounds

  subroutine test_untruncated(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    atm%phases = test_phases()
    atm%truncated = .false.
    call check_bounds(error, atm, 1)
  end subroutine test_untruncated

  !> The standard preset's truncation: 30 deg, 4 levels.
  subroutine test_truncated(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    atm%phases = test_phases()
    call truncation_init(atm%trunc, atm%phases, 30.0_wp, 4, 30.0_wp, error)
    if (allocated(error)) return
    atm%truncated = .true.
    call check_bounds(error, atm, 4)
  end subroutine test_truncated

  subroutine test_no_roulette(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(detectors_t) :: det
    atm%phases = test_phases()
    call make_detectors(det, 0.0_wp)
    call detectors_bounds(det, atm)
    call check(error, .not. allocated(det%p_bound), 'no table when contributions are not rouletted')
  end subroutine test_no_roulette

  !> Two detector directions (nadir and mu 0.5 at phi 180), eps 0.1, cones of 15 deg, the sharp
  !> table: for photons arriving along fixed directions and leaving along directions spread over
  !> the sphere (many inside the cones), the factor against the formula evaluated here.
  subroutine test_ddis_factor(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(detectors_t) :: det
    type(camera_t) :: cams(0)
    real(wp) :: ui(3), v(3), p_in, p_d, c, expect, fac, t, ph, worst
    integer :: i, j, d, n_in, n_out
    real(wp), parameter :: arrive(3, 3) = reshape([0.6_wp, 0.0_wp, 0.8_wp, 0.0_wp, 0.0_wp, &
                                                   1.0_wp, 0.3_wp, -0.4_wp, -0.866_wp], [3, 3])
    atm%phases = test_phases()
    atm%truncated = .false.
    call detectors_init(det, [1.0_wp, 0.5_wp], [0.0_wp, 180.0_wp], [1, 1], cams, 0.3_wp, &
                        1.0_wp, 1.0_wp, ddis_eps=0.1_wp)
    det%ddis_mu_cone = cos(15.0_wp*DEG2RAD)
    worst = 0.0_wp
    n_in = 0
    n_out = 0
    do j = 1, 3
      ui = arrive(:, j)
      do i = 1, 4000
        t = acos(1.0_wp - 2.0_wp*(real(i, wp) - 0.5_wp)/4000.0_wp)   ! polar angle, even in mu
        ph = real(i, wp)*2.39996_wp                                  ! golden-angle azimuths
        v = [sin(t)*cos(ph), sin(t)*sin(ph), cos(t)]
        p_in = phase_eval(atm%phases(1), dot_product(ui, v))
        p_d = 0.0_wp
        do d = 1, 2
          c = det%ux(d)*v(1) + det%uy(d)*v(2) + det%uz(d)*v(3)
          if (c >= det%ddis_mu_cone) p_d = p_d + phase_eval(atm%phases(1), c)
        end do
        fac = ddis_factor(det, atm, 1, 1, ui(1), ui(2), ui(3), v(1), v(2), v(3))
        if (p_d > 0.0_wp) then
          n_in = n_in + 1
          expect = p_in/(p_in + 0.1_wp*p_d/2.0_wp)
          worst = max(worst, abs(fac - expect)/expect)
        else
          n_out = n_out + 1
          call check(error, fac == 1.0_wp, 'outside every cone the factor must be exactly 1')
          if (allocated(error)) return
        end if
      end do
    end do
    call check(error, n_in > 100 .and. n_out > 100, 'directions inside and outside the cones')
    if (allocated(error)) return
    call check(error, worst <= 1.0e-14_wp, 'inside a cone the factor is P_in/(P_in + eps mean P_d)')
  end subroutine test_ddis_factor
end module test_le_bounds_suite

program test_le_bounds
  use kumo_testing, only: run_unittests
  use test_le_bounds_suite, only: collect_le_bounds
  implicit none
  integer :: n_failed
  call run_unittests('le_bounds', collect_le_bounds(), n_failed)
  if (n_failed > 0) error stop 1
end program test_le_bounds
