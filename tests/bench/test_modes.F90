! SPDX-License-Identifier: BSD-3-Clause
!> Transport modes F3D, ICA and P3D (mode_3d, p3d_orders in &kumo_control).
!>
!> * ICA on the I3RC step cloud (Cahalan et al. 2005: optical depths 2 and 18, HG g = 0.85)
!>   gives in every column the plane-parallel answer of kumo's 1-D path; on a step cloud of
!>   optical depths 1 and 10 every column's fluxes and radiances match DISORT
!>   (reference/disort_pp.csv), sun at 60 degrees, black and Lambert surfaces.
!> * P3D with p3d_orders = 0 is ICA and with more orders than any photon has is F3D, photon by
!>   photon (identical output).
!> * On a horizontally uniform field F3D, ICA and the 1-D path agree (k sigma).
!> * Column budget: in ICA nothing moves sideways (horizontal transport 0 in every column to
!>   round-off when no roulette acts); in F3D it is 0 over the domain and not in the columns;
!>   R + T + A + H closes per column and the energy closure is 1 in every mode.
module test_modes_suite
  use kumo_kinds, only: wp, dp, i8
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_sigma
  use kumo_config, only: config_t
  use kumo_results, only: result_set_t
  use kumo_test_scenes, only: slab_config, run_config, run_pair, get_scalar, get_array, &
                              attach_scene
  use kumo_test_text, only: disort_value
  use kumo_error, only: str
  implicit none
  private
  public :: collect_modes

  real(dp), parameter :: K = 4.0_dp
  integer, parameter :: NCOL = 32     !! columns of the step cloud
  real(wp), parameter :: THICK = 250.0_wp, PERIOD = 500.0_wp

contains

  function collect_modes() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('ica_step_cloud_equals_1d_columns', test_ica_step), &
             new_unittest('ica_columns_match_disort', test_ica_disort), &
             new_unittest('p3d_limits_are_ica_and_f3d', test_p3d_limits), &
             new_unittest('uniform_field_f3d_equals_ica_and_1d', test_uniform), &
             new_unittest('column_budget_per_mode', test_budget)]
  end function collect_modes

  !> The step cloud: one layer 250 m thick, 32 columns of 15.625 m along x, the first half of
  !> optical depth tau_lo, the second tau_hi; HG g = 0.85; fluxes at the surface and the top.
  function step_config(tau_lo, tau_hi, omega, sza, albedo, mode, path, error) result(cfg)
    real(wp), intent(in) :: tau_lo, tau_hi, omega, sza, albedo
    character(len=*), intent(in) :: mode, path
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    real(wp) :: ext(NCOL, 1, 1), ssa(NCOL, 1, 1)
    cfg = slab_config(0.0_wp, omega, 'hg', 0.85_wp, sza, albedo, 32000_i8, 20)
    cfg%atm%z = [0.0_wp, THICK]
    cfg%atm%lx = PERIOD
    cfg%atm%ly = PERIOD/NCOL
    ext(1:NCOL/2, 1, 1) = tau_lo/THICK
    ext(NCOL/2 + 1:, 1, 1) = tau_hi/THICK
    ssa = omega
    call attach_scene(cfg, path, 1, ext, ssa, 1, error)
    cfg%control%mode_3d = mode
  end function step_config

  !> Per-column value at map slot `slot` of an (x, y, level)-ordered map.
  pure real(dp) function at(m, ic, slot) result(v)
    real(dp), intent(in) :: m(:)
    integer, intent(in) :: ic, slot
    v = m(ic + (slot - 1)*NCOL)
  end function at

  !> Compare every column of an ICA step-cloud run with plane-parallel values: R (flux_up at
  !> the top), T (total down at the surface), and the radiance maps (x, y, rad_level, direction).
  subroutine compare_columns(res, r_ref, t_ref, r_sig, t_sig, rad_ref, rad_sig, label, error)
    type(result_set_t), intent(in) :: res
    real(dp), intent(in) :: r_ref(2), t_ref(2), r_sig(2), t_sig(2) !! (thin, thick) columns
    real(dp), intent(in) :: rad_ref(:, :), rad_sig(:, :) !! (level x direction, thin/thick)
    character(len=*), intent(in) :: label
    type(error_t), allocatable, intent(inout) :: error
    real(dp), allocatable :: up(:), eup(:), dr(:), edr(:), df(:), edf(:), rm(:), er(:)
    real(dp), allocatable :: dn(:), edn(:)
    real(dp) :: t, et
    integer :: ic, h, j
    call get_array(res, 'flux_up_map', up, eup, error)
    call get_array(res, 'flux_down_direct_map', dr, edr, error)
    call get_array(res, 'flux_down_diffuse_map', df, edf, error)
    call get_array(res, 'flux_down_map', dn, edn, error)
    call get_array(res, 'radiance_map', rm, er, error)
    if (allocated(error)) return
    do ic = 1, NCOL
      h = merge(1, 2, ic <= NCOL/2)
      call check_sigma(error, at(up, ic, 2), r_ref(h), sqrt(at(eup, ic, 2)**2 + r_sig(h)**2), &
                       K, label//': R of column '//str(ic))
      t = at(dn, ic, 1)
      et = at(edn, ic, 1)
      call check(error, abs(t - (at(dr, ic, 1) + at(df, ic, 1))) < 1.0e-12_dp, &
                 label//': total downward map = direct + diffuse, column '//str(ic))
      call check_sigma(error, t, t_ref(h), sqrt(et**2 + t_sig(h)**2), K, &
                       label//': T of column '//str(ic))
      do j = 1, size(rad_ref, 1)
        call check_sigma(error, rm(ic + (j - 1)*NCOL), rad_ref(j, h), &
                         sqrt(er(ic + (j - 1)*NCOL)**2 + rad_sig(j, h)**2), K, &
                         label//': radiance '//str(j)//' of column '//str(ic), &
                         abs_floor=1.0e-12_dp)
      end do
      if (allocated(error)) return
    end do
  end subroutine compare_columns

  !> Radiance requests of the tests: nadir and mu 0.5 (phi 0) at the top, mu -0.5 (phi 0) at
  !> the surface, with maps. Output order (rad_level fastest): (bottom, top) per direction.
  subroutine ask_radiances(cfg)
    type(config_t), intent(inout) :: cfg
    cfg%rad%mu = [1.0_wp, 0.5_wp, -0.5_wp]
    cfg%rad%phi_deg = [0.0_wp, 0.0_wp, 0.0_wp]
    cfg%rad%levels = [0, 1]
    cfg%rad%maps = .true.
  end subroutine ask_radiances

  subroutine test_ica_step(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: ica, pp
    type(result_set_t) :: res, r1
    real(dp) :: r_ref(2), t_ref(2), r_sig(2), t_sig(2), rad(6, 2), rsig(6, 2)
    real(dp), allocatable :: m(:), e(:)
    real(wp) :: taus(2)
    integer :: h
    taus = [2.0_wp, 18.0_wp]
    ! the I3RC experiment 2 geometry: sun at 60 degrees, photons travelling towards +x
    ica = step_config(taus(1), taus(2), 1.0_wp, 60.0_wp, 0.0_wp, 'ica', 'modes_step.nc', error)
    if (allocated(error)) return
    call ask_radiances(ica)
    call run_config(ica, res, error)
    if (allocated(error)) return
    do h = 1, 2
      pp = slab_config(taus(h), 1.0_wp, 'hg', 0.85_wp, 60.0_wp, 0.0_wp, 100000_i8, 20)
      pp%control%seed = 100_i8 + h
      call ask_radiances(pp)
      call run_config(pp, r1, error)
      if (allocated(error)) return
      call get_scalar(r1, 'reflectance', r_ref(h), r_sig(h), error)
      call get_scalar(r1, 'transmittance', t_ref(h), t_sig(h), error)
      call get_array(r1, 'radiance', m, e, error)
      if (allocated(error)) return
      rad(:, h) = m
      rsig(:, h) = e
    end do
    call compare_columns(res, r_ref, t_ref, r_sig, t_sig, rad, rsig, 'ICA step cloud 2/18', error)
  end subroutine test_ica_step

  subroutine test_ica_disort(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: ica
    type(result_set_t) :: res
    real(dp) :: r_ref(2), t_ref(2), rad(6, 2), zero2(2), zero62(6, 2)
    character(len=40) :: id
    character(len=8), parameter :: MU(3) = [character(len=8) :: '1', '0.5', '-0.5']
    character(len=4), parameter :: LEV(2) = [character(len=4) :: 'BOA', 'TOA']
    real(wp) :: albedo
    integer :: h, j, l, ia
    zero2 = 0.0_dp
    zero62 = 0.0_dp
    do ia = 1, 2
      albedo = merge(0.0_wp, 0.3_wp, ia == 1)
      ica = step_config(1.0_wp, 10.0_wp, merge(1.0_wp, 0.999_wp, ia == 1), 60.0_wp, albedo, &
                        'ica', 'modes_step_disort.nc', error)
      if (allocated(error)) return
      ica%control%seed = 20_i8 + ia
      call ask_radiances(ica)
      call run_config(ica, res, error)
      if (allocated(error)) return
      do h = 1, 2
        if (ia == 1) then
          id = 'hg0.85_w1_tau'//trim(merge('1 ', '10', h == 1))//'_sza60_alb0'
        else
          id = 'hg0.85_w0.999_tau'//trim(merge('1 ', '10', h == 1))//'_sza60_alb0.3'
        end if
        r_ref(h) = disort_value(trim(id), 'R', '', '', '', error)
        t_ref(h) = disort_value(trim(id), 'T_total', '', '', '', error)
        do j = 1, 3
          do l = 1, 2
            rad(l + 2*(j - 1), h) = disort_value(trim(id), 'pi_I_over_mu0F0', LEV(l), &
                                                 trim(MU(j)), '0', error)
          end do
        end do
      end do
      if (allocated(error)) return
      call compare_columns(res, r_ref, t_ref, zero2, zero2, rad, zero62, &
                           'ICA vs DISORT, albedo '//str(albedo), error)
      if (allocated(error)) return
    end do
  end subroutine test_ica_disort

  subroutine test_p3d_limits(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: a, b
    type(result_set_t) :: ra, rb
    character(len=24), parameter :: NAMES(3) = [character(len=24) :: 'flux_up_map', &
      'flux_down_diffuse_map', 'radiance_map']
    real(dp), allocatable :: ma(:), ea(:), mb(:), eb(:)
    integer :: pass, i
    do pass = 1, 2
      a = step_config(2.0_wp, 18.0_wp, 0.99_wp, 60.0_wp, 0.2_wp, &
                      trim(merge('ica', 'f3d', pass == 1)), 'modes_p3d.nc', error)
      if (allocated(error)) return
      a%control%n_photons_per_batch = 4000_i8
      a%control%n_batches = 4
      call ask_radiances(a)
      b = a
      b%control%mode_3d = 'p3d'
      b%control%p3d_orders = merge(0, 1000000, pass == 1)
      call run_pair(a, ra, b, rb, error)
      if (allocated(error)) return
      do i = 1, size(NAMES)
        call get_array(ra, trim(NAMES(i)), ma, ea, error)
        call get_array(rb, trim(NAMES(i)), mb, eb, error)
        if (allocated(error)) return
        call check(error, all(ma == mb) .and. all(ea == eb), 'p3d_orders = '// &
                   str(b%control%p3d_orders)//' must give the '//trim(a%control%mode_3d)// &
                   ' result exactly: '//trim(NAMES(i)))
        if (allocated(error)) return
      end do
    end do
  end subroutine test_p3d_limits

  subroutine test_uniform(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: c1, c3
    type(result_set_t) :: r1, r3
    real(wp) :: ext(4, 3, 1), ssa(4, 3, 1)
    real(dp), allocatable :: m1(:), e1(:), m3(:), e3(:)
    real(dp) :: a, ea, b, eb
    character(len=24), parameter :: NAMES(4) = [character(len=24) :: 'reflectance', &
      'transmittance', 'absorptance_atmosphere', 'transmittance_direct']
    integer :: mode, i
    c1 = slab_config(5.0_wp, 0.99_wp, 'hg', 0.85_wp, 50.0_wp, 0.2_wp, 20000_i8, 20)
    call ask_radiances(c1)
    call run_config(c1, r1, error)
    if (allocated(error)) return
    do mode = 1, 3
      c3 = c1
      c3%atm%ext1d = 0.0_wp
      ext = c1%atm%ext1d(1, 1)
      ssa = 0.99_wp
      call attach_scene(c3, 'modes_uniform.nc', 1, ext, ssa, 1, error)
      if (allocated(error)) return
      c3%control%mode_3d = trim(merge('f3d', 'ica', mode == 1))
      if (mode == 3) then
        c3%control%mode_3d = 'p3d'
        c3%control%p3d_orders = 2
      end if
      c3%control%seed = 30_i8 + mode
      call run_config(c3, r3, error)
      if (allocated(error)) return
      do i = 1, size(NAMES)
        call get_scalar(r1, trim(NAMES(i)), a, ea, error)
        call get_scalar(r3, trim(NAMES(i)), b, eb, error)
        call check_sigma(error, b, a, sqrt(ea**2 + eb**2), K, trim(c3%control%mode_3d)// &
                         ' vs 1-D: '//trim(NAMES(i)), abs_floor=1.0e-12_dp)
      end do
      call get_array(r1, 'radiance', m1, e1, error)
      call get_array(r3, 'radiance', m3, e3, error)
      if (allocated(error)) return
      do i = 1, size(m1)
        call check_sigma(error, m3(i), m1(i), sqrt(e1(i)**2 + e3(i)**2), K, &
                         trim(c3%control%mode_3d)//' vs 1-D: radiance '//str(i), &
                         abs_floor=1.0e-12_dp)
      end do
      if (allocated(error)) return
    end do
  end subroutine test_uniform

  subroutine test_budget(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: res
    real(dp), allocatable :: h(:), eh(:), a(:), ea(:), up(:), eup(:), dr(:), edr(:), df(:), edf(:)
    real(dp) :: closure, ec, bal, ebal
    integer :: mode, ic, n_signif
    character(len=3), parameter :: MODES(3) = ['f3d', 'ica', 'p3d']
    do mode = 1, 3
      ! conservative scattering over a black surface: weights stay 1, no roulette acts
      cfg = step_config(2.0_wp, 18.0_wp, 1.0_wp, 60.0_wp, 0.0_wp, MODES(mode), 'modes_budget.nc', &
                        error)
      if (allocated(error)) return
      cfg%control%seed = 40_i8 + mode
      call run_config(cfg, res, error)
      if (allocated(error)) return
      call get_scalar(res, 'energy_closure', closure, ec, error)
      call get_scalar(res, 'roulette_weight_balance', bal, ebal, error)
      call get_array(res, 'horizontal_transport_map', h, eh, error)
      call get_array(res, 'absorptance_column', a, ea, error)
      call get_array(res, 'flux_up_map', up, eup, error)
      call get_array(res, 'flux_down_direct_map', dr, edr, error)
      call get_array(res, 'flux_down_diffuse_map', df, edf, error)
      if (allocated(error)) return
      call check(error, abs(closure - 1.0_dp) < 1.0e-12_dp .and. bal == 0.0_dp, &
                 MODES(mode)//': energy closure 1 and no roulette')
      call check(error, size(h) == NCOL .and. maxval(abs(a)) == 0.0_dp, &
                 MODES(mode)//': one column budget per column, nothing absorbed')
      if (allocated(error)) return
      ! R + T + A + H = incident flux of the column (net flux in at the top), per column
      do ic = 1, NCOL
        call check(error, abs(at(up, ic, 2) + at(dr, ic, 1) + at(df, ic, 1) + a(ic) + h(ic) &
                              - at(dr, ic, 2)) < 1.0e-12_dp, &
                   MODES(mode)//': R + T + A + H = incident, column '//str(ic))
      end do
      call check(error, abs(sum(h)) < 1.0e-12_dp*NCOL, &
                 MODES(mode)//': no net horizontal transport over the periodic domain')
      n_signif = count(abs(h) > K*eh)
      select case (MODES(mode))
      case ('ica')
        call check(error, maxval(abs(h)) < 1.0e-12_dp, &
                   'ica: no horizontal transport in any column')
      case default
        call check(error, n_signif >= NCOL/2, MODES(mode)//': horizontal transport is '// &
                   'resolved in only '//str(n_signif)//' of '//str(NCOL)//' columns')
      end select
      if (allocated(error)) return
    end do
  end subroutine test_budget
end module test_modes_suite

program test_modes
  use test_modes_suite, only: collect_modes
  use kumo_test_text, only: run_shared_suite
  implicit none
  call run_shared_suite('test_modes', 'reference/disort_pp.csv', &
                        'transport modes F3D, ICA, P3D', &
                        collect_modes())
end program test_modes
