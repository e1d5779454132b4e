! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_planck.
!>
!> References, all independent of the code under test:
!> * the Stefan-Boltzmann constant sigma = 5.670374419e-8 W m-2 K-4 and Wien's displacement
!>   constants b = 2.897771955e-3 m K (wavelength peak) and 5.878925757e10 Hz K-1 (frequency
!>   peak) of CODATA 2018 (Tiesinga et al. 2021, Rev. Mod. Phys. 93, 025010);
!> * monochromatic values of Planck's law evaluated with 40-digit decimal arithmetic (Python's
!>   decimal module, CODATA 2018 h, c, k), quoted to 16 digits below;
!> * DISORT's band Planck function PLKAVG as it enters the DISORT test problems (Stamnes et al.
!>   1988, DISOTEST "correct answers", see ../shared/data/README.md): the downward flux at the
!>   top of problems 6f, 7c and 9c is pi FISOT + pi B_band(TTEMP) with TEMIS = 1. PLKAVG uses
!>   sigma = 5.67032e-8 and c2 = 1.438786 cm K (DISORT source), which are emulated here exactly
!>   by B_DISORT(T) = B(T c2/c2_DISORT) (sigma_DISORT/sigma) (c2_DISORT/c2)^4, since the band
!>   radiance is (sigma/pi)(15/pi^4) T^4 Int_{x1}^{x2} t^3/(e^t - 1) dt with x = c2 nu/T;
!> * brute-force quadrature of the monochromatic function (itself checked above) over the band:
!>   composite 10-point Gauss-Legendre on 2000 panels in wavenumber.
module test_kumo_planck
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_positive_inf
  use kumo_kinds, only: wp
  use kumo_constants, only: PI, STEFAN_BOLTZMANN
  use kumo_math, only: gauss_legendre01
  use kumo_planck, only: planck_wavelength, planck_wavenumber, dplanck_dt_wavelength, &
                         dplanck_dt_wavenumber, planck_band_wavenumber, planck_band_wavelength, &
                         dplanck_band_dt_wavenumber, dplanck_band_dt_wavelength, &
                         brightness_temperature_wavelength, brightness_temperature_wavenumber, &
                         spectral_band_t, band_from_wavenumbers, band_from_wavelengths, &
                         band_monochromatic_wavelength, band_monochromatic_wavenumber, &
                         band_radiance, band_dradiance_dt, band_brightness_temperature, band_units, &
                         check_temperatures, PLANCK_C2
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_error_words
  implicit none
  private
  public :: collect_planck

  real(wp), parameter :: SIGMA_CODATA = 5.670374419e-8_wp
  real(wp), parameter :: SIGMA_DISORT = 5.67032e-8_wp
  real(wp), parameter :: C2_DISORT = 1.438786e-2_wp   !! [m K]

contains

  !> All tests of this suite.
  function collect_planck() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('stefan_boltzmann_full_band', test_full_band), &
             new_unittest('monochromatic_decimal_values', test_monochromatic), &
             new_unittest('wien_displacement_peaks', test_wien), &
             new_unittest('disort_plkavg_problems_6f_7c_9c', test_disort), &
             new_unittest('band_vs_brute_force_quadrature', test_brute_force), &
             new_unittest('band_derivative', test_band_derivative), &
             new_unittest('wavelength_band_equals_wavenumber_band', test_wavelength_band), &
             new_unittest('tiny_bands_and_zero_temperature', test_tiny), &
             new_unittest('brightness_temperature_round_trip', test_round_trip), &
             new_unittest('bad_inputs', test_bad_inputs)]
  end function collect_planck

  !> Brute-force Int_{nu1}^{nu2} f(nu, t) dnu (cm-1), f = B_nu (which = 0) or dB_nu/dT; the
  !> upper limit is cut where x = c2 nu/T = 700 (beyond, everything underflows).
  function brute_band(nu1, nu2, t, which) result(s)
    real(wp), intent(in) :: nu1, nu2, t
    integer, intent(in) :: which
    real(wp) :: s
    integer, parameter :: NG = 10, NP = 2000
    real(wp) :: xg(NG), wg(NG), top, h, nu
    integer :: ip, i
    call gauss_legendre01(NG, xg, wg)
    top = min(nu2, 700.0_wp*t/(100.0_wp*PLANCK_C2))
    s = 0.0_wp
    if (top <= nu1) return
    h = (top - nu1)/NP
    do ip = 1, NP
      do i = 1, NG
        nu = nu1 + (ip - 1 + xg(i))*h
        if (which == 0) then
          s = s + wg(i)*planck_wavenumber(nu, t)
        else
          s = s + wg(i)*dplanck_dt_wavenumber(nu, t)
        end if
      end do
    end do
    s = s*h
  end function brute_band

  !> B over all wavenumbers (and all wavelengths) = sigma T^4/pi.
  subroutine test_full_band(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: temps(7) = [1.0_wp, 50.0_wp, 200.0_wp, 288.15_wp, 300.0_wp, 1000.0_wp, 5800.0_wp]
    integer :: i
    real(wp) :: inf
    inf = ieee_value(1.0_wp, ieee_positive_inf)
    call check_close(error, STEFAN_BOLTZMANN, SIGMA_CODATA, rel_tol=1.0e-9_wp, label='sigma')
    do i = 1, size(temps)
      call check_close(error, planck_band_wavenumber(0.0_wp, huge(1.0_wp), temps(i)), &
                       SIGMA_CODATA*temps(i)**4/PI, rel_tol=1.0e-9_wp, label='full band T='//fmt(temps(i)))
      call check_close(error, planck_band_wavenumber(0.0_wp, inf, temps(i)), &
                       SIGMA_CODATA*temps(i)**4/PI, rel_tol=1.0e-9_wp, label='full band (Inf)')
      call check_close(error, planck_band_wavelength(0.0_wp, inf, temps(i)), &
                       SIGMA_CODATA*temps(i)**4/PI, rel_tol=1.0e-9_wp, label='full wavelength band')
      call check_close(error, dplanck_band_dt_wavenumber(0.0_wp, huge(1.0_wp), temps(i)), &
                       4.0_wp*SIGMA_CODATA*temps(i)**3/PI, rel_tol=1.0e-9_wp, label='full band dB/dT')
      ! The two halves of the spectrum split at x = 1 and x = 5 add up to the whole.
      call check_close(error, planck_band_wavenumber(0.0_wp, temps(i)/(100.0_wp*PLANCK_C2), temps(i)) &
                       + planck_band_wavenumber(temps(i)/(100.0_wp*PLANCK_C2), huge(1.0_wp), temps(i)), &
                       SIGMA_CODATA*temps(i)**4/PI, rel_tol=1.0e-9_wp, label='split at x=1')
      call check_close(error, planck_band_wavenumber(0.0_wp, 5.0_wp*temps(i)/(100.0_wp*PLANCK_C2), temps(i)) &
                       + planck_band_wavenumber(5.0_wp*temps(i)/(100.0_wp*PLANCK_C2), huge(1.0_wp), temps(i)), &
                       SIGMA_CODATA*temps(i)**4/PI, rel_tol=1.0e-9_wp, label='split at x=5')
    end do
  end subroutine test_full_band

  !> Planck's law against 40-digit decimal evaluations.
  subroutine test_monochromatic(error)
    type(error_t), allocatable, intent(out) :: error
    call check_close(error, planck_wavelength(10.0e-6_wp, 300.0_wp), 9924033.330070695_wp, &
                     rel_tol=1.0e-13_wp, label='B_lambda(10 um, 300 K)')
    call check_close(error, planck_wavelength(0.5e-6_wp, 5800.0_wp), 26882199625929.31_wp, &
                     rel_tol=1.0e-13_wp, label='B_lambda(0.5 um, 5800 K)')
    call check_close(error, planck_wavelength(3.7e-6_wp, 300.0_wp), 403287.5342153270_wp, &
                     rel_tol=1.0e-13_wp, label='B_lambda(3.7 um, 300 K)')
    call check_close(error, planck_wavenumber(1000.0_wp, 300.0_wp), 0.09924033330070695_wp, &
                     rel_tol=1.0e-13_wp, label='B_nu(1000 cm-1, 300 K)')
    call check_close(error, planck_wavenumber(667.0_wp, 220.0_wp), 0.04564972574475708_wp, &
                     rel_tol=1.0e-13_wp, label='B_nu(667 cm-1, 220 K)')
    call check_close(error, planck_wavenumber(2500.0_wp, 250.0_wp), 1.050072091583621e-4_wp, &
                     rel_tol=1.0e-13_wp, label='B_nu(2500 cm-1, 250 K)')
    ! Rayleigh-Jeans limit 2 c k T nu^2 (x = 1e-7) and Wien limit c1 nu^3 exp(-x) (x = 500).
    call check_close(error, planck_wavenumber(1.0e-7_wp*250.0_wp/(100.0_wp*PLANCK_C2), 250.0_wp), &
                     2.0_wp*299792458.0_wp*1.380649e-23_wp*250.0_wp &
                     *(1.0e-7_wp*250.0_wp/PLANCK_C2)**2*100.0_wp*(1.0_wp - 0.5e-7_wp), &
                     rel_tol=1.0e-13_wp, label='Rayleigh-Jeans')
    call check(error, planck_wavenumber(500.0_wp*10.0_wp/(100.0_wp*PLANCK_C2), 10.0_wp) > 0.0_wp, &
               'Wien tail at x = 500 must not underflow to 0')
    ! Temperature derivatives against central differences.
    call check_close(error, dplanck_dt_wavelength(10.0e-6_wp, 300.0_wp), &
                     (planck_wavelength(10.0e-6_wp, 300.001_wp) - planck_wavelength(10.0e-6_wp, 299.999_wp))/0.002_wp, &
                     rel_tol=1.0e-8_wp, label='dB_lambda/dT')
    call check_close(error, dplanck_dt_wavenumber(2500.0_wp, 250.0_wp), &
                     (planck_wavenumber(2500.0_wp, 250.001_wp) - planck_wavenumber(2500.0_wp, 249.999_wp))/0.002_wp, &
                     rel_tol=1.0e-8_wp, label='dB_nu/dT')
  end subroutine test_monochromatic

  !> The maxima of B_lambda and B_nu sit at Wien's displacement constants.
  subroutine test_wien(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: t = 255.0_wp
    real(wp) :: lmax, numax
    lmax = 2.897771955e-3_wp/t
    call check(error, planck_wavelength(lmax, t) > planck_wavelength(lmax*(1.0_wp + 1.0e-4_wp), t) .and. &
               planck_wavelength(lmax, t) > planck_wavelength(lmax*(1.0_wp - 1.0e-4_wp), t), &
               'B_lambda is not maximal at lambda = b/T')
    numax = 5.878925757e10_wp*t/299792458.0_wp/100.0_wp   ! cm-1
    call check(error, planck_wavenumber(numax, t) > planck_wavenumber(numax*(1.0_wp + 1.0e-4_wp), t) .and. &
               planck_wavenumber(numax, t) > planck_wavenumber(numax*(1.0_wp - 1.0e-4_wp), t), &
               'B_nu is not maximal at nu = 5.8789e10 Hz/K T')
  end subroutine test_wien

  !> Band values that DISOTEST's correct answers contain, to their printed 6 digits.
  subroutine test_disort(error)
    type(error_t), allocatable, intent(out) :: error
    ! 6f: FDN(top) = 321.497 = pi FISOT + pi B(250 K; 0-50000 cm-1), FISOT = 100/pi.
    call check_close(error, 100.0_wp + PI*disort_band(0.0_wp, 50000.0_wp, 250.0_wp), 321.497_wp, &
                     abs_tol=0.0005_wp, label='DISORT 6f FDN(top)')
    ! 7c: FDN(top) = 319.830 = pi 100 + pi B(100 K; 0-50000 cm-1).
    call check_close(error, 100.0_wp*PI + PI*disort_band(0.0_wp, 50000.0_wp, 100.0_wp), 319.830_wp, &
                     abs_tol=0.0005_wp, label='DISORT 7c FDN(top)')
    ! 9c: FDN(top) = 6.09217 = pi 1 + pi B(550 K; 999-1000 cm-1): a narrow band.
    call check_close(error, PI + PI*disort_band(999.0_wp, 1000.0_wp, 550.0_wp), 6.09217_wp, &
                     abs_tol=0.000005_wp, label='DISORT 9c FDN(top)')
    ! The CODATA values differ from DISORT's by the constants only: 1.9e-5 relative (6f).
    call check_close(error, planck_band_wavenumber(0.0_wp, 50000.0_wp, 250.0_wp)/disort_band(0.0_wp, 50000.0_wp, 250.0_wp), &
                     SIGMA_CODATA/SIGMA_DISORT, rel_tol=1.0e-9_wp, label='constants ratio')
  end subroutine test_disort

  !> kumo's band function with DISORT's sigma and c2 (see the module header).
  function disort_band(nu1, nu2, t) result(b)
    real(wp), intent(in) :: nu1, nu2, t
    real(wp) :: b
    b = planck_band_wavenumber(nu1, nu2, t*PLANCK_C2/C2_DISORT)*(SIGMA_DISORT/STEFAN_BOLTZMANN) &
        *(C2_DISORT/PLANCK_C2)**4
  end function disort_band

  !> Band radiances and derivatives against brute-force quadrature over many bands and
  !> temperatures (1e-10 relative; the requirement is 1e-6).
  subroutine test_brute_force(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: nu1(14) = [0.0_wp, 0.0_wp, 300.0_wp, 999.0_wp, 2702.99_wp, 10.0_wp, 0.0_wp, &
                                      5000.0_wp, 500.0_wp, 100.0_wp, 1.0_wp, 540.0_wp, 2000.0_wp, 800.0_wp]
    real(wp), parameter :: nu2(14) = [50000.0_wp, 1.0_wp, 800.0_wp, 1000.0_wp, 2703.01_wp, 20.0_wp, 350.0_wp, &
                                      6000.0_wp, 500.001_wp, 3000.0_wp, 1.5_wp, 620.0_wp, 2250.0_wp, 980.0_wp]
    real(wp), parameter :: temps(7) = [3.0_wp, 30.0_wp, 180.0_wp, 250.0_wp, 300.0_wp, 700.0_wp, 6000.0_wp]
    integer :: i, j
    real(wp) :: b, ref, floor
    do i = 1, size(nu1)
      do j = 1, size(temps)
        ref = brute_band(nu1(i), nu2(i), temps(j), 0)
        b = planck_band_wavenumber(nu1(i), nu2(i), temps(j))
        floor = 1.0e-290_wp
        call check_close(error, b, ref, abs_tol=floor, rel_tol=1.0e-10_wp, &
                         label='band ['//fmt(nu1(i))//','//fmt(nu2(i))//'] T='//fmt(temps(j)))
        ref = brute_band(nu1(i), nu2(i), temps(j), 1)
        b = dplanck_band_dt_wavenumber(nu1(i), nu2(i), temps(j))
        call check_close(error, b, ref, abs_tol=floor, rel_tol=1.0e-10_wp, &
                         label='dB/dT ['//fmt(nu1(i))//','//fmt(nu2(i))//'] T='//fmt(temps(j)))
        if (allocated(error)) return
      end do
    end do
  end subroutine test_brute_force

  !> Band derivative against central differences of the band radiance.
  subroutine test_band_derivative(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: temps(4) = [150.0_wp, 250.0_wp, 320.0_wp, 900.0_wp]
    integer :: j
    real(wp) :: d
    do j = 1, size(temps)
      d = 1.0e-4_wp*temps(j)
      call check_close(error, dplanck_band_dt_wavenumber(540.0_wp, 800.0_wp, temps(j)), &
                       (planck_band_wavenumber(540.0_wp, 800.0_wp, temps(j) + d) &
                        - planck_band_wavenumber(540.0_wp, 800.0_wp, temps(j) - d))/(2.0_wp*d), &
                       rel_tol=1.0e-7_wp, label='dB/dT 540-800 T='//fmt(temps(j)))
      call check_close(error, dplanck_band_dt_wavelength(10.0e-6_wp, 12.0e-6_wp, temps(j)), &
                       (planck_band_wavelength(10.0e-6_wp, 12.0e-6_wp, temps(j) + d) &
                        - planck_band_wavelength(10.0e-6_wp, 12.0e-6_wp, temps(j) - d))/(2.0_wp*d), &
                       rel_tol=1.0e-7_wp, label='dB/dT 10-12 um T='//fmt(temps(j)))
    end do
  end subroutine test_band_derivative

  !> A wavelength band is the wavenumber band of the reciprocal limits.
  subroutine test_wavelength_band(error)
    type(error_t), allocatable, intent(out) :: error
    call check_close(error, planck_band_wavelength(8.0e-6_wp, 12.5e-6_wp, 290.0_wp), &
                     planck_band_wavenumber(800.0_wp, 1250.0_wp, 290.0_wp), rel_tol=1.0e-13_wp, &
                     label='8-12.5 um = 800-1250 cm-1')
    call check_close(error, planck_band_wavelength(0.0_wp, 4.0e-6_wp, 5800.0_wp), &
                     planck_band_wavenumber(2500.0_wp, huge(1.0_wp), 5800.0_wp), rel_tol=1.0e-13_wp, &
                     label='0-4 um = 2500-inf cm-1')
  end subroutine test_wavelength_band

  !> Bands of relative width 1e-12 .. 1e-3 give B_nu times the width; T = 0 gives 0.
  subroutine test_tiny(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: widths(4) = [1.0e-12_wp, 1.0e-9_wp, 1.0e-6_wp, 1.0e-3_wp]
    real(wp), parameter :: centres(3) = [5.0_wp, 900.0_wp, 4000.0_wp]
    integer :: i, j
    real(wp) :: a, b, expected
    do i = 1, size(centres)
      do j = 1, size(widths)
        a = centres(i)
        b = centres(i)*(1.0_wp + widths(j))
        ! Midpoint rule: relative error about (x width)^2/24, x = c2 nu/T < 25 here.
        expected = planck_wavenumber(0.5_wp*(a + b), 260.0_wp)*(b - a)
        call check_close(error, planck_band_wavenumber(a, b, 260.0_wp), expected, &
                         rel_tol=max(1.0e-11_wp, (25.0_wp*widths(j))**2), label='tiny band at '//fmt(centres(i)))
        expected = dplanck_dt_wavenumber(0.5_wp*(a + b), 260.0_wp)*(b - a)
        call check_close(error, dplanck_band_dt_wavenumber(a, b, 260.0_wp), expected, &
                         rel_tol=max(1.0e-11_wp, (25.0_wp*widths(j))**2), label='tiny band dB/dT')
      end do
    end do
    call check(error, planck_band_wavenumber(500.0_wp, 600.0_wp, 0.0_wp) == 0.0_wp, 'band at T = 0')
    call check(error, dplanck_band_dt_wavenumber(500.0_wp, 600.0_wp, 0.0_wp) == 0.0_wp, 'dB/dT at T = 0')
    call check(error, planck_wavelength(10.0e-6_wp, 0.0_wp) == 0.0_wp, 'B_lambda at T = 0')
    call check(error, planck_wavenumber(1000.0_wp, 0.0_wp) == 0.0_wp, 'B_nu at T = 0')
    call check(error, planck_band_wavenumber(500.0_wp, 500.0_wp, 300.0_wp) == 0.0_wp, 'empty band')
    ! Extreme cold: the Wien tail underflows quietly to 0 (no overflow or NaN).
    call check(error, planck_band_wavenumber(5000.0_wp, 6000.0_wp, 1.0_wp) == 0.0_wp, 'cold Wien tail')
    call check(error, planck_band_wavenumber(5000.0_wp, 6000.0_wp, 1.0e-300_wp) == 0.0_wp, 'T = 1e-300')
    call check(error, planck_band_wavenumber(0.0_wp, 1.0e-6_wp, 1.0e6_wp) > 0.0_wp, 'hot Rayleigh-Jeans end')
  end subroutine test_tiny

  !> Brightness temperature inverts the Planck function: monochromatic and band.
  subroutine test_round_trip(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: temps(8) = [2.7_wp, 40.0_wp, 180.0_wp, 230.0_wp, 288.0_wp, 320.0_wp, 1500.0_wp, 6000.0_wp]
    type(spectral_band_t) :: bands(6)
    type(error_t), allocatable :: err
    real(wp) :: t, r
    integer :: i, j
    call band_from_wavenumbers(800.0_wp, 980.0_wp, bands(1), err)
    call band_from_wavenumbers(0.0_wp, huge(1.0_wp), bands(2), err)
    call band_from_wavenumbers(2702.99_wp, 2703.01_wp, bands(3), err)
    call band_from_wavelengths(3.5e-6_wp, 4.0e-6_wp, bands(4), err)
    call band_monochromatic_wavelength(10.8e-6_wp, bands(5), err)
    call band_monochromatic_wavenumber(667.0_wp, bands(6), err)
    call check(error, .not. allocated(err), 'band constructors')
    do i = 1, size(bands)
      do j = 1, size(temps)
        r = band_radiance(bands(i), temps(j))
        if (r < 1.0e-280_wp) cycle
        call band_brightness_temperature(bands(i), r, t, err)
        call check(error, .not. allocated(err), 'brightness temperature failed')
        if (allocated(error)) return
        call check_close(error, t, temps(j), rel_tol=1.0e-11_wp, label='Tb band '//fmt(real(i, wp)))
      end do
    end do
    call check_close(error, brightness_temperature_wavelength(planck_wavelength(11.0e-6_wp, 271.3_wp), 11.0e-6_wp), &
                     271.3_wp, rel_tol=1.0e-13_wp, label='Tb(B_lambda)')
    call check_close(error, brightness_temperature_wavenumber(planck_wavenumber(1200.0_wp, 3.0_wp), 1200.0_wp), &
                     3.0_wp, rel_tol=1.0e-13_wp, label='Tb(B_nu) deep Wien')
    call band_brightness_temperature(bands(1), 0.0_wp, t, err)
    call check(error, .not. allocated(err) .and. t == 0.0_wp, 'Tb of zero radiance is 0 K')
    call check(error, band_units(bands(1)) == 'W m-2 sr-1', 'units of a band')
    call check(error, band_units(bands(5)) == 'W m-2 sr-1 m-1', 'units per wavelength')
    call check_close(error, band_dradiance_dt(bands(6), 250.0_wp), dplanck_dt_wavenumber(667.0_wp, 250.0_wp), &
                     rel_tol=1.0e-14_wp, label='band_dradiance_dt mono')
  end subroutine test_round_trip

  !> Negative or NaN temperatures, reversed bands, bad wavelengths and radiances are errors.
  subroutine test_bad_inputs(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(spectral_band_t) :: band
    real(wp) :: nan, t
    nan = ieee_value(1.0_wp, ieee_quiet_nan)
    call check_temperatures(-1.0_wp, 'surface temperature', err)
    call check_error_words(error, err, ['surface temperature', '-1                 ', '>= 0               '])
    call check_temperatures(nan, 'surface temperature', err)
    call check_error_words(error, err, ['surface temperature', 'NaN                '])
    call check_temperatures([250.0_wp, 260.0_wp, nan], 'level temperature', err)
    call check_error_words(error, err, ['level temperature(3)', 'NaN                 '])
    call check_temperatures([250.0_wp, 0.0_wp, 300.0_wp], 'level temperature', err)
    call check(error, .not. allocated(err), 'valid temperatures rejected')
    call band_from_wavenumbers(1000.0_wp, 800.0_wp, band, err)
    call check_error_words(error, err, ['upper wavenumber', '800             ', '1000            '])
    call band_from_wavenumbers(-5.0_wp, 800.0_wp, band, err)
    call check_error_words(error, err, ['lower wavenumber', '-5              '])
    call band_from_wavenumbers(nan, 800.0_wp, band, err)
    call check_error_words(error, err, ['NaN'])
    call band_from_wavelengths(12.0e-6_wp, 10.0e-6_wp, band, err)
    call check_error_words(error, err, ['upper wavelength'])
    call band_monochromatic_wavelength(0.0_wp, band, err)
    call check_error_words(error, err, ['wavelength', '> 0       '])
    call band_monochromatic_wavenumber(-3.0_wp, band, err)
    call check_error_words(error, err, ['wavenumber', '-3        '])
    call band_from_wavenumbers(800.0_wp, 900.0_wp, band, err)
    call band_brightness_temperature(band, -1.0_wp, t, err)
    call check_error_words(error, err, ['radiance', '-1      '])
    call band_brightness_temperature(band, nan, t, err)
    call check_error_words(error, err, ['radiance'])
  end subroutine test_bad_inputs

  !> Short text of a number for labels.
  function fmt(x) result(s)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: s
    character(len=32) :: buf
    write (buf, '(g0.6)') x
    s = trim(adjustl(buf))
  end function fmt

end module test_kumo_planck

program test_planck
  use kumo_testing, only: run_unittests
  use test_kumo_planck, only: collect_planck
  implicit none
  integer :: n_failed
  call run_unittests('planck', collect_planck(), n_failed)
  if (n_failed > 0) error stop 1
end program test_planck
