! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_rayleigh and kumo_std_atmosphere.
!>
!> References: Bodhaine, Wood, Dutton and Slusser (1999), J. Atmos. Oceanic Technol. 16,
!> 1854-1861 (B99): their fit of the cross-section (eq. 29) and of the sea-level optical depth
!> (eq. 30), stated accurate to 0.01 % for 0.25-0.85 um and 0.05 % for 0.85-1 um against their
!> full calculation, and the molar masses quoted in their text; U.S. Standard Atmosphere 1976
!> (NOAA/NASA/USAF 1976): Table 4 (layer bases) and Table I (geometric heights). Independent
!> checks written here: brute-force integration of the hydrostatic optical depth, the closed
!> form of the phase-function CDF, Gauss-Legendre normalisation, and kumo_phase's Rayleigh
!> sampler for rho = 0.
module test_kumo_rayleigh
  use kumo_kinds, only: wp
  use kumo_math, only: gauss_legendre01
  use kumo_phase, only: rayleigh_eval, rayleigh_sample_mu
  use kumo_rayleigh, only: RAYLEIGH_WL_MIN_UM, RAYLEIGH_WL_MAX_UM, CO2_DEFAULT_PPM, AVOGADRO, &
                           air_refractivity, king_factor_air, depol_from_king, king_from_depol, &
                           rayleigh_cross_section, air_molar_mass, gravity_bodhaine, &
                           column_gravity_height, rayleigh_layer_tau, rayleigh_column_tau, &
                           rayleigh_extinction, rayleigh_check_inputs, rayleigh_depol_eval, &
                           rayleigh_depol_sample_mu, rayleigh_depol_check
  use kumo_std_atmosphere, only: STD_ATM_US1976, std_atmosphere_kind_from_name, &
                                 std_atmosphere_profile, us1976_state
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  implicit none
  private
  public :: collect_rayleigh

  real(wp), parameter :: P_SEA = 101325.0_wp   !! 1013.25 hPa [Pa]
  real(wp), parameter :: R0_US76 = 6356766.0_wp  !! r0 of the 1976 standard [m]

contains

  !> All tests of this suite.
  function collect_rayleigh() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('cross_section_vs_b99_eq29', test_cross_section_fit), &
             new_unittest('sea_level_tau_vs_b99_eq30', test_column_tau_fit), &
             new_unittest('molar_mass_and_gravity_b99', test_molar_mass_gravity), &
             new_unittest('king_factor_and_depolarisation', test_king_depol), &
             new_unittest('lambda_minus_four_dominance', test_lambda4), &
             new_unittest('layer_tau_additive', test_additive), &
             new_unittest('extinction_vs_brute_force', test_brute_force), &
             new_unittest('us1976_column_vs_b99_eq30', test_us1976_column), &
             new_unittest('us1976_layer_bases_table4', test_us1976_bases), &
             new_unittest('us1976_geometric_table1', test_us1976_geometric), &
             new_unittest('phase_normalisation', test_phase_norm), &
             new_unittest('phase_sampler_inverts_cdf', test_phase_sampler), &
             new_unittest('bad_rayleigh_inputs', test_bad_rayleigh), &
             new_unittest('bad_atmosphere_inputs', test_bad_atmosphere)]
  end function collect_rayleigh

  !> B99 eq. 29: sigma [1e-28 cm2] for 360 ppm CO2, lambda in um.
  pure function b99_sigma_fit(l) result(s)
    real(wp), intent(in) :: l
    real(wp) :: s
    s = (1.0455996_wp - 341.29061_wp/l**2 - 0.90230850_wp*l**2) &
        /(1.0_wp + 0.0027059889_wp/l**2 - 85.968563_wp*l**2)
  end function b99_sigma_fit

  !> Error unless `err` is allocated and its message contains `text`.
  subroutine expect_error(error, err, text)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: text
    if (allocated(error)) return
    if (.not. allocated(err)) then
      call check(error, .false., 'no error; expected one containing "'//text//'"')
    else
      call check(error, index(err%message, text) > 0, 'message "'//err%message// &
                 '" does not contain "'//text//'"')
    end if
  end subroutine expect_error

  ! ------------------------------------------------------------------------------------------
  ! Bodhaine et al. (1999)
  ! ------------------------------------------------------------------------------------------

  !> Full calculation against B99's fit (eq. 29) at 360 ppm. Tolerance = B99's stated accuracy
  !> of the fit: 1e-4 for 0.25-0.85 um, 5e-4 for 0.85-1 um.
  subroutine test_cross_section_fit(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    real(wp) :: l, tol
    do i = 0, 75
      l = 0.25_wp + 0.01_wp*i
      tol = merge(1.0e-4_wp, 5.0e-4_wp, l <= 0.85_wp)
      ! 1e-28 cm2 = 1e-32 m2
      call check_close(error, rayleigh_cross_section(l, CO2_DEFAULT_PPM), &
                       1.0e-32_wp*b99_sigma_fit(l), rel_tol=tol, label='sigma('//wl(l)//')')
      if (allocated(error)) return
    end do
  end subroutine test_cross_section_fit

  !> Sea-level column (1013.25 hPa, 45 deg, 360 ppm) against B99 eq. 30,
  !> tau = 0.0021520 x (eq. 29). Tolerance: fit accuracy as above plus 2.5e-5 for the
  !> five-digit constant 0.0021520.
  subroutine test_column_tau_fit(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    real(wp) :: l, tol
    do i = 0, 15
      l = 0.25_wp + 0.05_wp*i
      tol = merge(1.25e-4_wp, 5.25e-4_wp, l <= 0.85_wp)
      call check_close(error, rayleigh_column_tau(l, P_SEA, 45.0_wp, 0.0_wp, CO2_DEFAULT_PPM), &
                       0.0021520_wp*b99_sigma_fit(l), rel_tol=tol, label='tau('//wl(l)//')')
      if (allocated(error)) return
    end do
  end subroutine test_column_tau_fit

  !> B99's text: m_a = 28.9595 g/mol without CO2 and 28.9649 at 360 ppm (rounding 5e-5);
  !> g at 45 deg and sea level is 980.6160 cm s-2 (List's g0 where cos 2phi = 0); g falls by
  !> 3.085462e-6 m s-2 per m near the ground and z_c = 5517.56 m for a sea-level station.
  subroutine test_molar_mass_gravity(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: dgdz
    call check_close(error, air_molar_mass(0.0_wp), 28.9595e-3_wp, abs_tol=1.0e-12_wp, &
                     rel_tol=0.0_wp, label='m_a(0 ppm)')
    call check_close(error, air_molar_mass(360.0_wp), 28.9649e-3_wp, abs_tol=5.0e-8_wp, &
                     rel_tol=0.0_wp, label='m_a(360 ppm)')
    call check_close(error, gravity_bodhaine(45.0_wp, 0.0_wp), 9.806160_wp, abs_tol=1.0e-12_wp, &
                     rel_tol=0.0_wp, label='g(45 deg, 0 m)')
    ! Normal gravity is larger at the poles than at the equator (by 0.53 %).
    call check(error, gravity_bodhaine(90.0_wp, 0.0_wp) > gravity_bodhaine(0.0_wp, 0.0_wp), &
               'g(pole) <= g(equator)')
    call check_close(error, gravity_bodhaine(90.0_wp, 0.0_wp)/gravity_bodhaine(0.0_wp, 0.0_wp), &
                     1.0053_wp, abs_tol=2.0e-4_wp, rel_tol=0.0_wp, label='g(pole)/g(equator)')
    dgdz = (gravity_bodhaine(45.0_wp, 1.0_wp) - gravity_bodhaine(45.0_wp, -1.0_wp))/2.0_wp
    call check_close(error, dgdz, -3.085462e-6_wp, rel_tol=1.0e-6_wp, label='dg/dz')
    call check_close(error, column_gravity_height(0.0_wp), 5517.56_wp, rel_tol=1.0e-14_wp, &
                     label='z_c(0)')
    call gravity_vs_inverse_square(error)
  end subroutine test_molar_mass_gravity

  !> List's polynomial in z follows the inverse-square law g0 (R/(R + z))^2
  !> = g0 (1 - 2 z/R + 3 z^2/R^2 - 4 z^3/R^3 + ...): with R from its linear term
  !> (R = 2 g0/3.085462e-4 = 6356 km at 45 deg), the third derivative, taken here as a third
  !> difference (exact for a cubic), must be -24 g0/R^3 within 2 % (List's 1.517e-17 against
  !> 4 g0/R^3 = 1.527e-17 cm s-2 m-3).
  subroutine gravity_vs_inverse_square(error)
    type(error_t), allocatable, intent(inout) :: error
    real(wp), parameter :: h = 20000.0_wp
    real(wp) :: g0, r, d3
    g0 = gravity_bodhaine(45.0_wp, 0.0_wp)
    r = 2.0_wp*9.806160_wp/3.085462e-6_wp
    d3 = (gravity_bodhaine(45.0_wp, 3.0_wp*h) - 3.0_wp*gravity_bodhaine(45.0_wp, 2.0_wp*h) &
          + 3.0_wp*gravity_bodhaine(45.0_wp, h) - g0)/h**3
    call check_close(error, d3, -24.0_wp*g0/r**3, rel_tol=0.02_wp, label='d3g/dz3')
  end subroutine gravity_vs_inverse_square

  !> King factor of air in the visible: Young (1981) gives F = 1.048 (quoted in B99), i.e.
  !> rho = 0.0279; B99's Bates-based F at 0.55 um must lie within 0.1 % of it. F and rho are
  !> inverses of each other; F grows towards the UV; F(N2) = 1.034 + ... < F_air < F(O2).
  subroutine test_king_depol(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    real(wp) :: rho, f
    call check_close(error, king_factor_air(0.55_wp, CO2_DEFAULT_PPM), 1.048_wp, &
                     rel_tol=1.0e-3_wp, label='F_air(0.55 um)')
    call check_close(error, depol_from_king(1.048_wp), 0.0279_wp, abs_tol=5.0e-5_wp, &
                     rel_tol=0.0_wp, label='rho(F = 1.048)')
    do i = 0, 8
      rho = 0.1_wp*i
      call check_close(error, depol_from_king(king_from_depol(rho)), rho, abs_tol=1.0e-14_wp, &
                       label='rho round trip')
    end do
    do i = 1, 74
      f = king_factor_air(0.25_wp + 0.01_wp*i, CO2_DEFAULT_PPM)
      call check(error, f < king_factor_air(0.24_wp + 0.01_wp*i, CO2_DEFAULT_PPM), &
                 'F_air does not decrease with wavelength')
      if (allocated(error)) return
    end do
    f = king_factor_air(0.4_wp, 0.0_wp)
    call check(error, f > 1.034_wp + 3.17e-4_wp/0.16_wp .and. &
               f < 1.096_wp + 1.385e-3_wp/0.16_wp + 1.448e-4_wp/0.16_wp**2, &
               'F_air(0.4 um) not between F(N2) and F(O2)')
    ! More CO2 (F = 1.15) raises F_air and n - 1.
    call check(error, king_factor_air(0.5_wp, 1000.0_wp) > king_factor_air(0.5_wp, 0.0_wp), &
               'F_air does not grow with CO2')
    call check(error, air_refractivity(0.5_wp, 1000.0_wp) > air_refractivity(0.5_wp, 0.0_wp), &
               'n - 1 does not grow with CO2')
  end subroutine test_king_depol

  !> sigma ~ lambda^-4 times slowly varying factors: the local exponent -dln sigma/dln lambda
  !> lies in (4, 4.4) over 0.3-1 um, falls with wavelength, and tends to 4 (within 0.03 at
  !> 1 um: the dispersion of n and of F only adds a few percent of lambda^-4).
  subroutine test_lambda4(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    real(wp) :: l, e, e_prev
    e_prev = huge(1.0_wp)
    do i = 0, 14
      l = 0.3_wp + 0.05_wp*i
      e = log(rayleigh_cross_section(0.999_wp*l, 360.0_wp) &
              /rayleigh_cross_section(1.001_wp*l, 360.0_wp))/log(1.001_wp/0.999_wp)
      call check(error, e > 4.0_wp .and. e < 4.4_wp .and. e < e_prev, &
                 'exponent '//wl(e)//' at '//wl(l)//' um not in (4, 4.4) or not falling')
      if (allocated(error)) return
      e_prev = e
    end do
    call check(error, e < 4.03_wp, 'exponent at 1 um not within 0.03 of 4')
    ! Doubling the wavelength divides sigma by about 16.
    call check_close(error, rayleigh_cross_section(0.4_wp, 360.0_wp) &
                     /rayleigh_cross_section(0.8_wp, 360.0_wp), 16.0_wp, rel_tol=0.1_wp, &
                     label='sigma(0.4)/sigma(0.8)')
  end subroutine test_lambda4

  !> Optical depth adds over layers: the extinction on a fine grid, times thickness, summed over
  !> the sublayers of each coarse layer, equals the coarse optical depth (to rounding; both use
  !> the same exact-in-pieces quadrature). Also the layer formula with fixed g is additive in
  !> pressure.
  subroutine test_additive(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp) :: z_prof(31), p_prof(31), t(31), rho(31), z_fine(41), z_coarse(5)
    real(wp), allocatable :: e_fine(:), e_coarse(:)
    real(wp) :: tau_fine, t1, t2, t12
    integer :: i, k
    z_prof = [(1000.0_wp*i, i=0, 30)]
    call std_atmosphere_profile('us1976', z_prof, p_prof, t, rho, err)
    call check(error, .not. allocated(err), 'std_atmosphere_profile failed')
    if (allocated(error)) return
    z_coarse = [0.0_wp, 1300.0_wp, 7000.0_wp, 17250.0_wp, 30000.0_wp]
    ! 10 sublayers per coarse layer
    do k = 1, 4
      do i = 0, 9
        z_fine(10*(k - 1) + i + 1) = z_coarse(k) + (z_coarse(k + 1) - z_coarse(k))*i/10.0_wp
      end do
    end do
    z_fine(41) = z_coarse(5)
    call rayleigh_extinction(0.5_wp, z_fine, z_prof, p_prof, 30.0_wp, 400.0_wp, e_fine, err)
    call check(error, .not. allocated(err), 'rayleigh_extinction failed (fine)')
    if (allocated(error)) return
    call rayleigh_extinction(0.5_wp, z_coarse, z_prof, p_prof, 30.0_wp, 400.0_wp, e_coarse, err)
    call check(error, .not. allocated(err), 'rayleigh_extinction failed (coarse)')
    if (allocated(error)) return
    do k = 1, 4
      tau_fine = 0.0_wp
      do i = 10*(k - 1) + 1, 10*k
        tau_fine = tau_fine + e_fine(i)*(z_fine(i + 1) - z_fine(i))
      end do
      call check_close(error, tau_fine, e_coarse(k)*(z_coarse(k + 1) - z_coarse(k)), &
                       rel_tol=1.0e-12_wp, label='coarse layer tau')
      if (allocated(error)) return
    end do
    t1 = rayleigh_layer_tau(0.4_wp, 90000.0_wp, 60000.0_wp, 10.0_wp, 3000.0_wp, 400.0_wp)
    t2 = rayleigh_layer_tau(0.4_wp, 60000.0_wp, 20000.0_wp, 10.0_wp, 3000.0_wp, 400.0_wp)
    t12 = rayleigh_layer_tau(0.4_wp, 90000.0_wp, 20000.0_wp, 10.0_wp, 3000.0_wp, 400.0_wp)
    call check_close(error, t1 + t2, t12, rel_tol=1.0e-14_wp, label='fixed-g layer tau additive')
  end subroutine test_additive

  !> One kumo layer spanning several profile intervals against a midpoint rule written here:
  !> tau = sigma N_A/m_a Sum (p(z_i) - p(z_i+1))/g(z_i+1/2) on 1 m steps, p interpolated
  !> exponentially between profile points. Midpoint error ~ (dz/H)^2/24 ~ 1e-9: tol 1e-8.
  subroutine test_brute_force(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp), parameter :: z_prof(4) = [-200.0_wp, 1500.0_wp, 4000.0_wp, 9000.0_wp]
    real(wp), parameter :: p_prof(4) = [104000.0_wp, 84000.0_wp, 61000.0_wp, 30000.0_wp]
    real(wp), parameter :: z_lev(3) = [0.0_wp, 350.0_wp, 8200.0_wp]
    real(wp), allocatable :: ext(:)
    real(wp) :: s, za, zb, pa, pb, sigma
    integer :: k, i, n
    call rayleigh_extinction(0.35_wp, z_lev, z_prof, p_prof, -60.0_wp, 280.0_wp, ext, err)
    call check(error, .not. allocated(err), 'rayleigh_extinction failed')
    if (allocated(error)) return
    sigma = rayleigh_cross_section(0.35_wp, 280.0_wp)
    do k = 1, 2
      n = nint(z_lev(k + 1) - z_lev(k))
      s = 0.0_wp
      do i = 0, n - 1
        za = z_lev(k) + i
        zb = za + 1.0_wp
        pa = p_exp(za)
        pb = p_exp(zb)
        s = s + (pa - pb)/gravity_bodhaine(-60.0_wp, 0.5_wp*(za + zb))
      end do
      s = sigma*AVOGADRO*s/air_molar_mass(280.0_wp)
      call check_close(error, ext(k)*(z_lev(k + 1) - z_lev(k)), s, rel_tol=1.0e-8_wp, &
                       label='layer tau')
    end do
  contains
    pure function p_exp(z) result(p)
      real(wp), intent(in) :: z
      real(wp) :: p
      integer :: j
      j = 1
      do while (j < 3 .and. z > z_prof(j + 1))
        j = j + 1
      end do
      p = p_prof(j)*(p_prof(j + 1)/p_prof(j))**((z - z_prof(j))/(z_prof(j + 1) - z_prof(j)))
    end function p_exp
  end subroutine test_brute_force

  !> The US 1976 atmosphere on 0.5 km levels to 86 km, layer by layer, against B99 eq. 30
  !> (sea level, 45 deg). The layer sum integrates 1/g over the real mass distribution (mass-
  !> mean height 7.36 km), while eq. 30 takes g at z_c = 5.52 km: the layer sum is larger by
  !> 0.057 % (dg/dz x 1.84 km / g). Tolerance 2e-4 around that offset, which covers the fit
  !> accuracy (1.25e-4) and the 3.7e-6 of the column above 86 km.
  subroutine test_us1976_column(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp) :: z(173), p(173), t(173), rho(173)
    real(wp), allocatable :: ext(:)
    real(wp) :: l
    integer :: i, j
    z = [(500.0_wp*i, i=0, 172)]
    call std_atmosphere_profile('US1976', z, p, t, rho, err)
    call check(error, .not. allocated(err), 'std_atmosphere_profile failed')
    if (allocated(error)) return
    do j = 0, 3
      l = 0.3_wp + 0.15_wp*j
      call rayleigh_extinction(l, z, z, p, 45.0_wp, 360.0_wp, ext, err)
      call check(error, .not. allocated(err), 'rayleigh_extinction failed')
      if (allocated(error)) return
      call check_close(error, sum(ext*500.0_wp)/(1.00057_wp*0.0021520_wp*b99_sigma_fit(l)), &
                       1.0_wp, rel_tol=2.0e-4_wp, label='column tau/(1.00057 eq. 30)')
      if (allocated(error)) return
    end do
  end subroutine test_us1976_column

  ! ------------------------------------------------------------------------------------------
  ! U.S. Standard Atmosphere 1976
  ! ------------------------------------------------------------------------------------------

  !> Table 4 of the standard: geopotential heights H_b [km'], molecular-scale temperatures
  !> T_M,b [K] and pressures P_b [Pa] of the layer bases (7 significant digits: rel. tol.
  !> 1e-6). Below 80 km the kinetic temperature equals T_M.
  subroutine test_us1976_bases(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: hb(7) = [0.0_wp, 11.0_wp, 20.0_wp, 32.0_wp, 47.0_wp, 51.0_wp, 71.0_wp]
    real(wp), parameter :: tb(7) = [288.15_wp, 216.65_wp, 216.65_wp, 228.65_wp, 270.65_wp, &
                                    270.65_wp, 214.65_wp]
    real(wp), parameter :: pb(7) = [1.01325e5_wp, 2.263206e4_wp, 5.474889e3_wp, &
                                    8.680187e2_wp, 1.109063e2_wp, 6.693887e1_wp, 3.956420_wp]
    real(wp) :: z, p, t, rho
    integer :: i
    do i = 1, 7
      z = R0_US76*1000.0_wp*hb(i)/(R0_US76 - 1000.0_wp*hb(i))   ! geometric height of geopotential H
      call us1976_state(z, p, t, rho)
      call check_close(error, p, pb(i), rel_tol=1.0e-6_wp, label='P_b')
      call check_close(error, t, tb(i), abs_tol=1.0e-9_wp, rel_tol=0.0_wp, label='T_b')
      if (allocated(error)) return
    end do
  end subroutine test_us1976_bases

  !> Table I of the standard at geometric heights (5 significant digits: rel. tol. 1e-4 for
  !> p and rho; temperatures to 0.005 K): 0, 11, 20, 32 and 86 km; at 86 km the kinetic
  !> temperature is T_M M/M0 = 186.87 K.
  subroutine test_us1976_geometric(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp), parameter :: z(5) = [0.0_wp, 11000.0_wp, 20000.0_wp, 32000.0_wp, 86000.0_wp]
    real(wp), parameter :: p_ref(5) = [1.01325e5_wp, 2.2700e4_wp, 5.5293e3_wp, 8.8906e2_wp, &
                                       3.7338e-1_wp]
    real(wp), parameter :: t_ref(5) = [288.150_wp, 216.774_wp, 216.650_wp, 228.490_wp, &
                                       186.87_wp]
    real(wp) :: p(5), t(5), rho(5)
    integer :: kind, i
    call std_atmosphere_kind_from_name(' Us1976 ', kind, err)
    call check(error, kind == STD_ATM_US1976 .and. .not. allocated(err), 'name lookup')
    if (allocated(error)) return
    call std_atmosphere_profile('us1976', z, p, t, rho, err)
    call check(error, .not. allocated(err), 'std_atmosphere_profile failed')
    if (allocated(error)) return
    do i = 1, 5
      call check_close(error, p(i), p_ref(i), rel_tol=1.0e-4_wp, label='p')
      call check_close(error, t(i), t_ref(i), abs_tol=5.0e-3_wp, rel_tol=0.0_wp, label='T')
    end do
    call check_close(error, rho(1), 1.2250_wp, rel_tol=1.0e-4_wp, label='rho(0)')
  end subroutine test_us1976_geometric

  ! ------------------------------------------------------------------------------------------
  ! Phase function
  ! ------------------------------------------------------------------------------------------

  !> (1/2) Int_{-1}^{1} P dmu = 1 (5-point Gauss-Legendre, exact for the quadratic); the
  !> side/forward ratio P(0)/P(1) = (1 + 3 gamma)/(2 (1 + gamma)) (1/2 without depolarisation);
  !> rho = 0 reproduces kumo_phase's 3/4 (1 + mu^2).
  subroutine test_phase_norm(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: x(5), w(5), rho, gam, s
    integer :: i, j
    call gauss_legendre01(5, x, w)
    do j = 0, 5
      rho = 0.15_wp*j
      s = 0.0_wp
      do i = 1, 5
        s = s + w(i)*rayleigh_depol_eval(rho, 2.0_wp*x(i) - 1.0_wp)   ! (1/2) x 2 dx
      end do
      call check_close(error, s, 1.0_wp, rel_tol=1.0e-14_wp, label='normalisation')
      gam = rho/(2.0_wp - rho)
      call check_close(error, rayleigh_depol_eval(rho, 0.0_wp)/rayleigh_depol_eval(rho, 1.0_wp), &
                       (1.0_wp + 3.0_wp*gam)/(2.0_wp + 2.0_wp*gam), rel_tol=1.0e-14_wp, &
                       label='P(90 deg)/P(0 deg)')
    end do
    do i = -10, 10
      call check_close(error, rayleigh_depol_eval(0.0_wp, 0.1_wp*i), rayleigh_eval(0.1_wp*i), &
                       rel_tol=1.0e-15_wp, label='rho = 0')
    end do
  end subroutine test_phase_norm

  !> The sampler is the inverse of the CDF F(mu) = (1/2) Int_{-1}^{mu} P dmu', integrated here
  !> in closed form; monotone; u = 0, 1/2, 1 give -1, 0, 1; rho = 0 agrees with kumo_phase.
  subroutine test_phase_sampler(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: rho, u, mu, mu_prev, cdf, gam, c0, c2
    integer :: i, j
    do j = 0, 4
      rho = 0.2_wp*j
      gam = rho/(2.0_wp - rho)
      c0 = 0.75_wp*(1.0_wp + 3.0_wp*gam)/(1.0_wp + 2.0_wp*gam)
      c2 = 0.75_wp*(1.0_wp - gam)/(1.0_wp + 2.0_wp*gam)
      mu_prev = -2.0_wp
      do i = 0, 1000
        u = i/1000.0_wp
        mu = rayleigh_depol_sample_mu(rho, u)
        cdf = 0.5_wp*(c0*(mu + 1.0_wp) + c2*(mu**3 + 1.0_wp)/3.0_wp)
        call check_close(error, cdf, u, abs_tol=1.0e-14_wp, rel_tol=0.0_wp, label='F(mu(u))')
        call check(error, mu >= mu_prev, 'sampler not monotone')
        if (allocated(error)) return
        mu_prev = mu
      end do
      call check_close(error, rayleigh_depol_sample_mu(rho, 0.0_wp), -1.0_wp, abs_tol=1.0e-15_wp, &
                       label='mu(0)')
      call check_close(error, rayleigh_depol_sample_mu(rho, 0.5_wp), 0.0_wp, abs_tol=1.0e-15_wp, &
                       label='mu(1/2)')
      call check_close(error, rayleigh_depol_sample_mu(rho, 1.0_wp), 1.0_wp, abs_tol=1.0e-15_wp, &
                       label='mu(1)')
    end do
    do i = 0, 100
      call check_close(error, rayleigh_depol_sample_mu(0.0_wp, 0.01_wp*i), &
                       rayleigh_sample_mu(0.01_wp*i), abs_tol=1.0e-14_wp, label='rho = 0')
    end do
  end subroutine test_phase_sampler

  ! ------------------------------------------------------------------------------------------
  ! Bad input
  ! ------------------------------------------------------------------------------------------

  subroutine test_bad_rayleigh(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp), allocatable :: ext(:)
    real(wp), parameter :: zp(3) = [0.0_wp, 5000.0_wp, 10000.0_wp]
    real(wp), parameter :: pp(3) = [1.0e5_wp, 5.4e4_wp, 2.6e4_wp]
    real(wp), parameter :: zl(3) = [0.0_wp, 1000.0_wp, 2000.0_wp]
    call rayleigh_check_inputs(0.2_wp, 400.0_wp, 0.0_wp, err)
    call expect_error(error, err, 'wavelength_um = 0.2 must be within [0.23, 1.69]')
    call rayleigh_check_inputs(2.0_wp, 400.0_wp, 0.0_wp, err)
    call expect_error(error, err, 'wavelength_um = 2 must be within')
    call rayleigh_check_inputs(0.5_wp, 400.0e3_wp, 0.0_wp, err)
    call expect_error(error, err, 'co2_ppm = 400000 must be within [0, 2000]')
    call rayleigh_check_inputs(0.5_wp, -1.0_wp, 0.0_wp, err)
    call expect_error(error, err, 'co2_ppm = -1 must be within')
    call rayleigh_check_inputs(0.5_wp, 400.0_wp, 95.0_wp, err)
    call expect_error(error, err, 'latitude_deg = 95 must be within [-90, 90]')
    call rayleigh_check_inputs(RAYLEIGH_WL_MIN_UM, 0.0_wp, -90.0_wp, err)
    call check(error, .not. allocated(err), 'lower bounds rejected')
    call rayleigh_check_inputs(RAYLEIGH_WL_MAX_UM, 2000.0_wp, 90.0_wp, err)
    call check(error, .not. allocated(err), 'upper bounds rejected')
    if (allocated(error)) return

    call rayleigh_extinction(0.1_wp, zl, zp, pp, 0.0_wp, 400.0_wp, ext, err)
    call expect_error(error, err, 'wavelength_um = 0.1')
    call rayleigh_extinction(0.5_wp, zl, zp, [1.0e5_wp, -5.0_wp, 2.6e4_wp], 0.0_wp, 400.0_wp, &
                             ext, err)
    call expect_error(error, err, 'p_prof(2) = -5 must be a finite pressure > 0')
    call rayleigh_extinction(0.5_wp, zl, zp, [1.0e5_wp, 5.4e4_wp, 6.0e4_wp], 0.0_wp, 400.0_wp, &
                             ext, err)
    call expect_error(error, err, 'p_prof(3) = 60000 must be < p_prof(2) = 54000')
    call rayleigh_extinction(0.5_wp, [0.0_wp, 2000.0_wp, 2000.0_wp], zp, pp, 0.0_wp, 400.0_wp, &
                             ext, err)
    call expect_error(error, err, 'z_levels(3) = 2000 must be > z_levels(2) = 2000')
    call rayleigh_extinction(0.5_wp, zl, [0.0_wp, 6000.0_wp, 5000.0_wp], pp, 0.0_wp, 400.0_wp, &
                             ext, err)
    call expect_error(error, err, 'z_prof(3) = 5000 must be > z_prof(2) = 6000')
    call rayleigh_extinction(0.5_wp, [0.0_wp, 12000.0_wp], zp, pp, 0.0_wp, 400.0_wp, ext, err)
    call expect_error(error, err, 'z_levels from 0 to 12000 m must lie within the pressure '// &
                      'profile, z_prof from 0 to 10000 m')
    call rayleigh_extinction(0.5_wp, zl, zp(1:2), pp, 0.0_wp, 400.0_wp, ext, err)
    call expect_error(error, err, 'z_prof has 2 values but p_prof has 3')
    call rayleigh_extinction(0.5_wp, [0.0_wp], zp, pp, 0.0_wp, 400.0_wp, ext, err)
    call expect_error(error, err, 'z_levels has 1 values; at least 2 are needed')
    call rayleigh_depol_check(0.9_wp, err)
    call expect_error(error, err, 'depolarisation ratio rho = 0.9 must satisfy 0 <= rho < 6/7')
    call rayleigh_depol_check(-0.01_wp, err)
    call expect_error(error, err, 'rho = -0.01 must satisfy')
    call rayleigh_depol_check(0.0279_wp, err)
    call check(error, .not. allocated(err), 'rho = 0.0279 rejected')
  end subroutine test_bad_rayleigh

  subroutine test_bad_atmosphere(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp) :: p(2), t(2), rho(2), p1(1)
    integer :: kind
    call std_atmosphere_kind_from_name('standard', kind, err)
    call expect_error(error, err, "standard atmosphere 'standard' must be one of us1976")
    call check(error, kind == -1, 'kind of an unknown name /= -1')
    call std_atmosphere_profile('us1976', [0.0_wp, 90000.0_wp], p, t, rho, err)
    call expect_error(error, err, "standard atmosphere 'us1976': z(2) = 90000 m must be "// &
                      'within [-5000, 86000] m')
    call std_atmosphere_profile('us1976', [0.0_wp, 1000.0_wp], p1, t, rho, err)
    call expect_error(error, err, 'p, t and rho_air must have the size of z, 2')
  end subroutine test_bad_atmosphere

  !> Short text of a wavelength or exponent for labels.
  function wl(x) result(s)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: s
    character(len=16) :: buf
    write (buf, '(f0.3)') x
    s = trim(buf)
  end function wl

end module test_kumo_rayleigh

program test_rayleigh
  use test_kumo_rayleigh, only: collect_rayleigh
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_rayleigh', collect_rayleigh(), n_failed)
  if (n_failed > 0) error stop 1
end program test_rayleigh
