! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_gas_state: a cloud file's gas state put into a broadband column.
!>
!> The expectations are exact properties of the rules, not numbers of kumo's:
!> * an isothermal hydrostatic column, p(z) = p0 exp(-z/H), whose file layers hold 1.02 times
!>   its pressures: log-linear interpolation is exact for an exponential, the outer levels keep
!>   the layer-to-level ratio, and the profile above and below is scaled to meet them, so every
!>   level and layer ends at 1.02 times the original (relative 1e-13);
!> * temperatures linear in height given at the file's layers leave every level as it was;
!>   shifted by +2 K, the levels inside the file move by 2 K and the two outer ones by 1 K
!>   (the midpoint between a file layer and an unshifted profile layer of equal thickness);
!> * the file's water vapour replaces the profile's in its layers only;
!> * pressures that rise with height are refused, naming the levels.
module test_gas_state_suite
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, str
  use kumo_gas_state, only: gas_state_merge
  use kumo_testing, only: unittest_t, new_unittest, check, check_close, check_error_words
  implicit none
  private
  public :: collect_gas_state

  integer, parameter :: NZ = 8
  integer, parameter :: KB = 3, NF = 3              !! the file's layers: 3, 4, 5
  real(wp), parameter :: H = 8000.0_wp, P0 = 101325.0_wp

contains

  function collect_gas_state() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('pressure_scaled_hydrostatic', test_pressure), &
             new_unittest('temperature_levels', test_temperature), &
             new_unittest('water_vapour_layers', test_vapour), &
             new_unittest('rising_pressure_refused', test_refused)]
  end function collect_gas_state

  subroutine column(z, plev, play, tlev, tlay, h2o)
    real(wp), intent(out) :: z(0:NZ), plev(0:NZ), play(NZ), tlev(0:NZ), tlay(NZ), h2o(NZ)
    integer :: k
    z = [(250.0_wp*k, k=0, NZ)]
    plev = P0*exp(-z/H)
    play = P0*exp(-0.5_wp*(z(0:NZ - 1) + z(1:NZ))/H)
    tlev = 290.0_wp - 6.5e-3_wp*z
    tlay = 290.0_wp - 6.5e-3_wp*0.5_wp*(z(0:NZ - 1) + z(1:NZ))
    h2o = [(0.01_wp/k, k=1, NZ)]
  end subroutine column

  subroutine test_pressure(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: z(0:NZ), plev(0:NZ), play(NZ), tlev(0:NZ), tlay(NZ), h2o(NZ)
    real(wp) :: plev0(0:NZ), play0(NZ), fb, ft
    integer :: k
    call column(z, plev, play, tlev, tlay, h2o)
    plev0 = plev
    play0 = play
    call gas_state_merge(z, KB, NF, plev, play, tlev, tlay, h2o, error, &
                         p_file=1.02_wp*play0(KB:KB + NF - 1), f_below=fb, f_above=ft)
    if (allocated(error)) return
    do k = 0, NZ
      call check_close(error, plev(k), 1.02_wp*plev0(k), rel_tol=1.0e-13_wp, &
                       label='level '//str(k))
    end do
    do k = 1, NZ
      call check_close(error, play(k), 1.02_wp*play0(k), rel_tol=1.0e-13_wp, &
                       label='layer '//str(k))
    end do
    call check_close(error, fb, 1.02_wp, rel_tol=1.0e-13_wp, label='factor below')
    call check_close(error, ft, 1.02_wp, rel_tol=1.0e-13_wp, label='factor above')
  end subroutine test_pressure

  subroutine test_temperature(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: z(0:NZ), plev(0:NZ), play(NZ), tlev(0:NZ), tlay(NZ), h2o(NZ)
    real(wp) :: tlev0(0:NZ), tlay0(NZ), plev0(0:NZ), shift
    integer :: k
    call column(z, plev, play, tlev, tlay, h2o)
    tlev0 = tlev
    tlay0 = tlay
    plev0 = plev
    call gas_state_merge(z, KB, NF, plev, play, tlev, tlay, h2o, error, t_file=tlay0(KB:KB + NF - 1))
    if (allocated(error)) return
    do k = 0, NZ
      call check_close(error, tlev(k), tlev0(k), rel_tol=1.0e-13_wp, label='unshifted level '//str(k))
    end do
    call check(error, all(plev == plev0), 'pressures changed without a file pressure')
    ! shifted by 2 K: levels KB..KB+NF-2 (inside) by 2 K, levels KB-1 and KB+NF-1 by 1 K
    tlay = tlay0
    tlev = tlev0
    call gas_state_merge(z, KB, NF, plev, play, tlev, tlay, h2o, error, &
                         t_file=tlay0(KB:KB + NF - 1) + 2.0_wp)
    if (allocated(error)) return
    do k = 0, NZ
      shift = 0.0_wp
      if (k == KB - 1 .or. k == KB + NF - 1) shift = 1.0_wp
      if (k >= KB .and. k <= KB + NF - 2) shift = 2.0_wp
      call check_close(error, tlev(k), tlev0(k) + shift, abs_tol=1.0e-10_wp, &
                       label='shifted level '//str(k))
    end do
    do k = 1, NZ
      shift = merge(2.0_wp, 0.0_wp, k >= KB .and. k <= KB + NF - 1)
      call check_close(error, tlay(k), tlay0(k) + shift, abs_tol=1.0e-10_wp, &
                       label='shifted layer '//str(k))
    end do
  end subroutine test_temperature

  subroutine test_vapour(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: z(0:NZ), plev(0:NZ), play(NZ), tlev(0:NZ), tlay(NZ), h2o(NZ), h0(NZ)
    call column(z, plev, play, tlev, tlay, h2o)
    h0 = h2o
    call gas_state_merge(z, KB, NF, plev, play, tlev, tlay, h2o, error, &
                         h2o_file=[0.02_wp, 0.03_wp, 0.04_wp])
    if (allocated(error)) return
    call check(error, all(h2o(KB:KB + NF - 1) == [0.02_wp, 0.03_wp, 0.04_wp]) .and. &
               all(h2o(1:KB - 1) == h0(1:KB - 1)) .and. all(h2o(KB + NF:) == h0(KB + NF:)), &
               'water vapour not replaced in the file''s layers only')
  end subroutine test_vapour

  subroutine test_refused(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: z(0:NZ), plev(0:NZ), play(NZ), tlev(0:NZ), tlay(NZ), h2o(NZ)
    type(error_t), allocatable :: err
    call column(z, plev, play, tlev, tlay, h2o)
    call gas_state_merge(z, KB, NF, plev, play, tlev, tlay, h2o, err, &
                         p_file=[play(KB), 1.1_wp*play(KB), play(KB + 2)])
    call check_error_words(error, err, [character(len=32) :: 'with the cloud file''s pressure', &
                                                 ' Pa'])
  end subroutine test_refused
end module test_gas_state_suite

program test_gas_state
  use kumo_testing, only: run_unittests
  use test_gas_state_suite, only: collect_gas_state
  implicit none
  integer :: n_failed
  call run_unittests('gas_state', collect_gas_state(), n_failed)
  if (n_failed > 0) error stop 1
end program test_gas_state
