! SPDX-License-Identifier: BSD-3-Clause
!> Planck function: spectral radiance of a black body, its integral over a spectral band, the
!> temperature derivatives and the inverse (brightness temperature).
!>
!> Units (SI except where a spectroscopic unit is the common one, as named in each argument):
!>
!> * temperature `t` in K;
!> * wavelength `lambda` in m; spectral radiance per wavelength in W m-2 sr-1 m-1
!>   (multiply by 1e-6 for W m-2 sr-1 um-1);
!> * wavenumber `nu` in cm-1; spectral radiance per wavenumber in W m-2 sr-1 (cm-1)-1;
!> * band radiance (integral over a wavenumber or wavelength interval) in W m-2 sr-1.
!>
!> Formulas (Planck's law, e.g. Liou 2002, An Introduction to Atmospheric Radiation, eq. 1.2.1)
!> with the exact SI constants h, c, k of `kumo_constants` and c1 = 2 h c^2, c2 = h c/k:
!>
!>     B_lambda(T) = c1 lambda^-5 / (exp(x) - 1),   x = c2/(lambda T)
!>     B_nu(T)     = c1 nu^3 / (exp(x) - 1),          x = c2 nu/T   (nu in m-1; x 100 per cm-1)
!>
!> The band radiance over [nu1, nu2] is (2 k^4 T^4 / (h^3 c^2)) Int_{x1}^{x2} t^3/(e^t - 1) dt,
!> whose integral over all wavenumbers is pi^4/15, so that the full band gives sigma T^4/pi.
!> The integral is taken from two convergent expansions of its antiderivatives:
!>
!> * below x = 2: Int_0^x t^3/(e^t - 1) dt = x^3/3 - x^4/8 + sum_j c_j x^(2j+3)/(2j+3), with
!>   c_j = B_2j/(2j)! from the Bernoulli numbers (Abramowitz and Stegun 1964, eqs. 23.1.1 and
!>   Table 23.2); the series converges for x < 2 pi and 18 terms reach 1e-17 at x = 2;
!> * above x = 2: Int_x^inf t^3/(e^t - 1) dt = sum_n exp(-n x) (x^3/n + 3 x^2/n^2 + 6 x/n^3
!>   + 6/n^4) (expand 1/(e^t - 1) = sum_n exp(-n t) and integrate term by term), at most 21
!>   terms to 1e-17.
!>
!> When the band integral is less than a tenth of the antiderivative values it is the difference
!> of (a narrow band: cancellation), it is instead integrated directly by 20-point Gauss-Legendre
!> quadrature on panels of width <= 0.5 in x. The integrand is analytic with its nearest
!> singularities at +-2 pi i, so one such panel is exact to round-off. The temperature derivative
!> uses the same scheme on t^4 e^t/(e^t - 1)^2 (antiderivatives x^3/3 - sum_j c_j (2j-1)
!> x^(2j+3)/(2j+3) and sum_n exp(-n x) (x^4 + 4 x^3/n + 12 x^2/n^2 + 24 x/n^3 + 24/n^4), total
!> 4 pi^4/15). The relative error of band radiances and derivatives is below 1e-12 for every
!> band and temperature whose value is a normal double (tests/unit/test_planck.F90); values
!> below about 1e-300 underflow to 0.
!>
!> The elemental functions do not validate their arguments (they are meant for validated fields
!> and the hot path); temperatures <= 0 give 0. User input goes through the validating
!> routines: `check_temperatures`, the `spectral_band_t` constructors and
!> `band_brightness_temperature`.
module kumo_planck
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan, ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_constants, only: PI, PLANCK_H, SPEED_OF_LIGHT, BOLTZMANN_K
  use kumo_error, only: error_t, set_error, str
  use kumo_math, only: gauss_legendre01
  implicit none
  private
  public :: planck_wavelength, planck_wavenumber, dplanck_dt_wavelength, dplanck_dt_wavenumber
  public :: planck_band_wavenumber, planck_band_wavelength
  public :: dplanck_band_dt_wavenumber, dplanck_band_dt_wavelength
  public :: brightness_temperature_wavelength, brightness_temperature_wavenumber
  public :: spectral_band_t, band_from_wavenumbers, band_from_wavelengths
  public :: band_monochromatic_wavelength, band_monochromatic_wavenumber
  public :: band_radiance, band_dradiance_dt, band_brightness_temperature, band_units
  public :: check_temperatures, PLANCK_C1, PLANCK_C2
  public :: BAND_INTEGRATED, BAND_MONO_WAVELENGTH, BAND_MONO_WAVENUMBER

  !> First radiation constant for radiance, 2 h c^2 [W m2 sr-1].
  real(wp), parameter :: PLANCK_C1 = 2.0_wp*PLANCK_H*SPEED_OF_LIGHT**2
  !> Second radiation constant, h c/k [m K] (1.438776877e-2).
  real(wp), parameter :: PLANCK_C2 = PLANCK_H*SPEED_OF_LIGHT/BOLTZMANN_K
  !> 2 k^4/(h^3 c^2) [W m-2 sr-1 K-4]: band radiance = this * T^4 * Int t^3/(e^t - 1) dt.
  real(wp), parameter :: C_BAND = 2.0_wp*(BOLTZMANN_K/PLANCK_H)**3*BOLTZMANN_K/SPEED_OF_LIGHT**2
  !> Kinds of `spectral_band_t`.
  integer, parameter :: BAND_INTEGRATED = 1, BAND_MONO_WAVELENGTH = 2, BAND_MONO_WAVENUMBER = 3

  !> Where the antiderivatives switch from the power series to the exponential series.
  real(wp), parameter :: X_SWITCH = 2.0_wp
  !> Beyond this x the integrands are below the smallest double (x^4 exp(-x) < 1e-310).
  real(wp), parameter :: X_CUT = 745.0_wp
  !> Integral of t^3/(e^t - 1) over [0, inf) = pi^4/15.
  real(wp), parameter :: TOTAL_PLANCK = PI**4/15.0_wp
  !> c_j = B_2j/(2j)!, j = 1..18 (from the exact rational Bernoulli numbers).
  real(wp), parameter :: BERN(18) = [8.33333333333333287e-02_wp, -1.38888888888888894e-03_wp, &
                                     3.30687830687830710e-05_wp, -8.26719576719576754e-07_wp, &
                                     2.08767569878681002e-08_wp, -5.28419013868749322e-10_wp, &
                                     1.33825365306846789e-11_wp, -3.38968029632258272e-13_wp, &
                                     8.58606205627784517e-15_wp, -2.17486869855806192e-16_wp, &
                                     5.50900282836022953e-18_wp, -1.39544646858125223e-19_wp, &
                                     3.53470703962946728e-21_wp, -8.95351742703754628e-23_wp, &
                                     2.26795245233768293e-24_wp, -5.74479066887220246e-26_wp, &
                                     1.45517247561486496e-27_wp, -3.68599494066531029e-29_wp]

  !> A spectral interval for thermal emission: a band integrated over wavenumbers (given in
  !> cm-1 or as a wavelength interval) or a single wavelength or wavenumber (spectral
  !> radiance). Build it with a constructor, which validates the input.
  type :: spectral_band_t
    integer :: kind = BAND_INTEGRATED
    real(wp) :: nu1 = 0.0_wp        !! lower wavenumber [m-1] (band), or the wavenumber (mono)
    real(wp) :: nu2 = 0.0_wp        !! upper wavenumber [m-1]; huge() stands for infinity
    real(wp) :: dnu = 0.0_wp        !! nu2 - nu1 [m-1] from the unrounded input limits
    real(wp) :: wavelength = 0.0_wp !! the wavelength [m] of BAND_MONO_WAVELENGTH
  end type spectral_band_t

  !> Validate temperatures (scalar or array): finite and >= 0.
  interface check_temperatures
    module procedure check_temperature_scalar, check_temperature_array
  end interface check_temperatures

contains

  ! ---------------------------------------------------------------------------------------
  ! Monochromatic Planck function
  ! ---------------------------------------------------------------------------------------

  !> Spectral radiance per wavelength B_lambda(T) [W m-2 sr-1 m-1]; lambda in m, t in K.
  elemental real(wp) function planck_wavelength(lambda, t) result(b)
    real(wp), intent(in) :: lambda, t
    b = 0.0_wp
    if (t <= 0.0_wp .or. lambda <= 0.0_wp) return
    b = planck_x(PLANCK_C1/lambda**5, lambda*t)
  end function planck_wavelength

  !> Spectral radiance per wavenumber B_nu(T) [W m-2 sr-1 (cm-1)-1]; nu in cm-1, t in K.
  elemental real(wp) function planck_wavenumber(nu, t) result(b)
    real(wp), intent(in) :: nu, t
    real(wp) :: nu_m
    b = 0.0_wp
    if (t <= 0.0_wp .or. nu <= 0.0_wp) return
    nu_m = 100.0_wp*nu
    b = 100.0_wp*planck_x(PLANCK_C1*nu_m**3, t/nu_m)
  end function planck_wavenumber

  !> dB_lambda/dT [W m-2 sr-1 m-1 K-1]; lambda in m, t in K.
  elemental real(wp) function dplanck_dt_wavelength(lambda, t) result(db)
    real(wp), intent(in) :: lambda, t
    db = 0.0_wp
    if (t <= 0.0_wp .or. lambda <= 0.0_wp) return
    db = dplanck_x(PLANCK_C1/lambda**5, lambda*t, t)
  end function dplanck_dt_wavelength

  !> dB_nu/dT [W m-2 sr-1 (cm-1)-1 K-1]; nu in cm-1, t in K.
  elemental real(wp) function dplanck_dt_wavenumber(nu, t) result(db)
    real(wp), intent(in) :: nu, t
    real(wp) :: nu_m
    db = 0.0_wp
    if (t <= 0.0_wp .or. nu <= 0.0_wp) return
    nu_m = 100.0_wp*nu
    db = 100.0_wp*dplanck_x(PLANCK_C1*nu_m**3, t/nu_m, t)
  end function dplanck_dt_wavenumber

  !> a/(exp(x) - 1) with x = c2/lt, without overflow for large x.
  elemental real(wp) function planck_x(a, lt) result(b)
    real(wp), intent(in) :: a   !! c1 lambda^-5 or c1 nu^3
    real(wp), intent(in) :: lt  !! lambda T or T/nu [m K]
    real(wp) :: x
    b = 0.0_wp
    if (lt <= PLANCK_C2/X_CUT) return
    x = PLANCK_C2/lt
    if (x > 1.0_wp) then
      b = a*exp(-x)/(1.0_wp - exp(-x))
    else
      b = a/expm1(x)
    end if
  end function planck_x

  !> d/dT of a/(exp(x) - 1), x = c2/lt: a/(exp(x) - 1) * x/(T (1 - exp(-x))).
  elemental real(wp) function dplanck_x(a, lt, t) result(db)
    real(wp), intent(in) :: a, lt, t
    real(wp) :: x
    db = 0.0_wp
    if (lt <= PLANCK_C2/X_CUT) return
    x = PLANCK_C2/lt
    db = planck_x(a, lt)*x/(t*(-expm1(-x)))
  end function dplanck_x

  !> Brightness temperature [K] of a spectral radiance per wavelength [W m-2 sr-1 m-1] at
  !> lambda [m] (closed-form inverse of planck_wavelength). Radiance <= 0 gives 0.
  elemental real(wp) function brightness_temperature_wavelength(radiance, lambda) result(t)
    real(wp), intent(in) :: radiance, lambda
    t = 0.0_wp
    if (.not. (radiance > 0.0_wp) .or. lambda <= 0.0_wp) return
    t = PLANCK_C2/(lambda*log1p_ratio(PLANCK_C1/lambda**5, radiance))
  end function brightness_temperature_wavelength

  !> Brightness temperature [K] of a spectral radiance per wavenumber [W m-2 sr-1 (cm-1)-1] at
  !> nu [cm-1] (closed-form inverse of planck_wavenumber). Radiance <= 0 gives 0.
  elemental real(wp) function brightness_temperature_wavenumber(radiance, nu) result(t)
    real(wp), intent(in) :: radiance, nu
    real(wp) :: nu_m
    t = 0.0_wp
    if (.not. (radiance > 0.0_wp) .or. nu <= 0.0_wp) return
    nu_m = 100.0_wp*nu
    t = PLANCK_C2*nu_m/log1p_ratio(100.0_wp*PLANCK_C1*nu_m**3, radiance)
  end function brightness_temperature_wavenumber

  !> log(1 + a/r) for a, r > 0, without overflow of a/r.
  elemental real(wp) function log1p_ratio(a, r) result(l)
    real(wp), intent(in) :: a, r
    real(wp) :: q
    q = log(a) - log(r)
    if (q > 40.0_wp) then
      l = q + exp(-q)
    else
      l = log1p(exp(q))
    end if
  end function log1p_ratio

  ! ---------------------------------------------------------------------------------------
  ! Band-integrated Planck function
  ! ---------------------------------------------------------------------------------------

  !> Planck radiance integrated over wavenumbers [nu1, nu2] (cm-1) [W m-2 sr-1]. nu2 = huge()
  !> (or +Inf) integrates to infinity; nu1 = 0 and nu2 = huge() give sigma T^4/pi. Expects
  !> 0 <= nu1 <= nu2 (0 otherwise).
  elemental real(wp) function planck_band_wavenumber(nu1, nu2, t) result(b)
    real(wp), intent(in) :: nu1, nu2, t
    b = band_planck_m(100.0_wp*nu1, scale_nu(nu2), wavenumber_width(nu1, nu2), t, 0)
  end function planck_band_wavenumber

  !> dB_band/dT over wavenumbers [nu1, nu2] (cm-1) [W m-2 sr-1 K-1].
  elemental real(wp) function dplanck_band_dt_wavenumber(nu1, nu2, t) result(b)
    real(wp), intent(in) :: nu1, nu2, t
    b = band_planck_m(100.0_wp*nu1, scale_nu(nu2), wavenumber_width(nu1, nu2), t, 1)
  end function dplanck_band_dt_wavenumber

  !> Planck radiance integrated over wavelengths [lambda1, lambda2] (m) [W m-2 sr-1].
  !> lambda1 = 0 reaches infinite wavenumber; lambda2 = huge() (or +Inf) reaches 0.
  elemental real(wp) function planck_band_wavelength(lambda1, lambda2, t) result(b)
    real(wp), intent(in) :: lambda1, lambda2, t
    b = band_planck_m(inverse_length(lambda2), inverse_length(lambda1), wavelength_width(lambda1, lambda2), t, 0)
  end function planck_band_wavelength

  !> dB_band/dT over wavelengths [lambda1, lambda2] (m) [W m-2 sr-1 K-1].
  elemental real(wp) function dplanck_band_dt_wavelength(lambda1, lambda2, t) result(b)
    real(wp), intent(in) :: lambda1, lambda2, t
    b = band_planck_m(inverse_length(lambda2), inverse_length(lambda1), wavelength_width(lambda1, lambda2), t, 1)
  end function dplanck_band_dt_wavelength

  !> 100 (nu2 - nu1) [m-1] for nu in cm-1; huge() for an open band.
  elemental real(wp) function wavenumber_width(nu1, nu2) result(dnu)
    real(wp), intent(in) :: nu1, nu2
    if (nu2 >= huge(1.0_wp)/100.0_wp) then
      dnu = huge(1.0_wp)
    else
      dnu = 100.0_wp*(nu2 - nu1)
    end if
  end function wavenumber_width

  !> 1/lambda1 - 1/lambda2 [m-1] without cancellation: (lambda2 - lambda1)/(lambda1 lambda2).
  elemental real(wp) function wavelength_width(lambda1, lambda2) result(dnu)
    real(wp), intent(in) :: lambda1, lambda2
    if (lambda1 <= 1.0_wp/huge(1.0_wp) .or. lambda2 >= huge(1.0_wp)) then
      dnu = huge(1.0_wp)
    else
      dnu = (lambda2 - lambda1)/lambda1/lambda2
    end if
  end function wavelength_width

  !> A wavenumber in cm-1 to m-1, keeping huge() and +Inf as huge().
  elemental real(wp) function scale_nu(nu) result(nu_m)
    real(wp), intent(in) :: nu
    if (nu >= huge(1.0_wp)/100.0_wp) then
      nu_m = huge(1.0_wp)
    else
      nu_m = 100.0_wp*nu
    end if
  end function scale_nu

  !> 1/lambda [m-1], with 1/0 = huge() and 1/huge() = 0.
  elemental real(wp) function inverse_length(lambda) result(nu)
    real(wp), intent(in) :: lambda
    if (lambda <= 1.0_wp/huge(1.0_wp)) then
      nu = huge(1.0_wp)
    else if (lambda >= huge(1.0_wp)) then
      nu = 0.0_wp
    else
      nu = 1.0_wp/lambda
    end if
  end function inverse_length

  !> Band integral over [nu1, nu2] (m-1) of the Planck function (which = 0) or of its
  !> temperature derivative (which = 1); dnu = nu2 - nu1 from the caller's exact inputs (the
  !> scaled limits carry rounding errors that would dominate in narrow bands).
  elemental real(wp) function band_planck_m(nu1, nu2, dnu, t, which) result(b)
    real(wp), intent(in) :: nu1, nu2, dnu, t
    integer, intent(in) :: which
    real(wp) :: x1, x2, dx
    b = 0.0_wp
    if (.not. (t > 0.0_wp) .or. .not. (nu2 > nu1) .or. nu1 < 0.0_wp) return
    x1 = x_of(nu1, t)
    x2 = x_of(nu2, t)
    ! The width from the exact difference nu2 - nu1 (Sterbenz) keeps narrow bands accurate.
    dx = x2 - x1
    if (x2 < X_CUT .and. dnu < huge(1.0_wp)) dx = PLANCK_C2*dnu/t
    if (which == 0) then
      b = C_BAND*t**4*planck_integral(x1, x2, dx, which)
    else
      b = C_BAND*t**3*planck_integral(x1, x2, dx, which)
    end if
  end function band_planck_m

  !> x = c2 nu/T capped at X_CUT (beyond which nothing is representable).
  elemental real(wp) function x_of(nu, t) result(x)
    real(wp), intent(in) :: nu, t
    if (nu >= X_CUT*(t/PLANCK_C2)) then
      x = X_CUT
    else
      x = PLANCK_C2*nu/t
    end if
  end function x_of

  !> Int_{x1}^{x2} g(t) dt, g = t^3/(e^t - 1) (which = 0) or t^4 e^t/(e^t - 1)^2 (which = 1),
  !> for 0 <= x1 <= x2 <= X_CUT; dx = x2 - x1 computed without the rounding of x1 and x2.
  pure real(wp) function planck_integral(x1, x2, dx, which) result(s)
    real(wp), intent(in) :: x1, x2, dx
    integer, intent(in) :: which
    real(wp) :: m, total
    s = 0.0_wp
    if (x2 <= x1 .or. x1 >= X_CUT) return
    total = TOTAL_PLANCK
    if (which == 1) total = 4.0_wp*TOTAL_PLANCK
    if (x2 <= X_SWITCH) then
      m = lower_antiderivative(x2, which)
      s = m - lower_antiderivative(x1, which)
    else if (x1 >= X_SWITCH) then
      m = upper_tail(x1, which)
      s = m - upper_tail(x2, which)
    else
      m = total
      s = total - lower_antiderivative(x1, which) - upper_tail(x2, which)
    end if
    ! Narrow band: the difference lost digits; integrate directly.
    if (s < 0.1_wp*m) s = direct_integral(x1, dx, which)
  end function planck_integral

  !> Int_0^x g (power series with Bernoulli coefficients), 0 <= x <= X_SWITCH.
  pure real(wp) function lower_antiderivative(x, which) result(s)
    real(wp), intent(in) :: x
    integer, intent(in) :: which
    real(wp) :: p, x2, term
    integer :: j
    x2 = x*x
    p = x*x2
    if (which == 0) then
      s = p/3.0_wp - x*p/8.0_wp
    else
      s = p/3.0_wp
    end if
    do j = 1, size(BERN)
      p = p*x2
      if (which == 0) then
        term = BERN(j)*p/real(2*j + 3, wp)
      else
        term = -BERN(j)*real(2*j - 1, wp)*p/real(2*j + 3, wp)
      end if
      s = s + term
      if (abs(term) <= 1.0e-17_wp*abs(s)) exit
    end do
  end function lower_antiderivative

  !> Int_x^inf g (series in exp(-n x)), x >= X_SWITCH.
  pure real(wp) function upper_tail(x, which) result(s)
    real(wp), intent(in) :: x
    integer, intent(in) :: which
    real(wp) :: e, rn, term
    integer :: n
    s = 0.0_wp
    if (x >= X_CUT) return
    do n = 1, 100
      if (n*x > X_CUT) exit
      e = exp(-n*x)
      rn = 1.0_wp/n
      if (which == 0) then
        term = e*(x**3*rn + 3.0_wp*x**2*rn**2 + 6.0_wp*x*rn**3 + 6.0_wp*rn**4)
      else
        term = e*(x**4 + 4.0_wp*x**3*rn + 12.0_wp*x**2*rn**2 + 24.0_wp*x*rn**3 + 24.0_wp*rn**4)
      end if
      s = s + term
      if (term <= 1.0e-17_wp*s) exit
    end do
  end function upper_tail

  !> Int_{x1}^{x1+dx} g by 20-point Gauss-Legendre panels of width <= 0.5.
  pure real(wp) function direct_integral(x1, dx, which) result(s)
    real(wp), intent(in) :: x1, dx
    integer, intent(in) :: which
    integer, parameter :: NG = 20
    real(wp) :: xg(NG), wg(NG), h, a
    integer :: np, ip, i
    call gauss_legendre01(NG, xg, wg)
    np = max(1, min(4000, ceiling(dx/0.5_wp)))
    h = dx/np
    s = 0.0_wp
    do ip = 1, np
      a = x1 + (ip - 1)*h
      do i = 1, NG
        s = s + wg(i)*planck_integrand(a + h*xg(i), which)
      end do
    end do
    s = s*h
  end function direct_integral

  !> t^3/(e^t - 1) (which = 0) or t^4 e^t/(e^t - 1)^2 (which = 1); limits t^2 and t^2 at 0.
  elemental real(wp) function planck_integrand(t, which) result(g)
    real(wp), intent(in) :: t
    integer, intent(in) :: which
    real(wp) :: em
    g = 0.0_wp
    if (t <= 0.0_wp .or. t >= X_CUT) return
    em = expm1(t)
    if (which == 0) then
      g = t**3/em
    else if (t > 1.0_wp) then
      g = t**4*exp(-t)/(1.0_wp - exp(-t))**2
    else
      g = t**4*(1.0_wp + em)/em**2
    end if
  end function planck_integrand

  ! ---------------------------------------------------------------------------------------
  ! Accurate exp(x) - 1 and log(1 + x) (Fortran 2008 has neither)
  ! ---------------------------------------------------------------------------------------

  !> exp(x) - 1 to full relative precision (Kahan's method: Higham 2002, Accuracy and
  !> Stability of Numerical Algorithms, 2nd ed., section 1.14.1).
  elemental real(wp) function expm1(x) result(y)
    real(wp), intent(in) :: x
    real(wp) :: u
    if (abs(x) < 1.0e-5_wp) then
      y = x*(1.0_wp + x*(0.5_wp + x/6.0_wp))
      return
    end if
    u = exp(x)
    if (u == 1.0_wp) then
      y = x
    else if (u - 1.0_wp == -1.0_wp) then
      y = -1.0_wp
    else
      y = (u - 1.0_wp)*x/log(u)
    end if
  end function expm1

  !> log(1 + x) to full relative precision for x > -1 (same reference).
  elemental real(wp) function log1p(x) result(y)
    real(wp), intent(in) :: x
    real(wp) :: u
    u = 1.0_wp + x
    if (u == 1.0_wp) then
      y = x
    else
      y = log(u)*x/(u - 1.0_wp)
    end if
  end function log1p

  ! ---------------------------------------------------------------------------------------
  ! Validated spectral bands
  ! ---------------------------------------------------------------------------------------

  !> A band integrated over wavenumbers [nu1, nu2] in cm-1, 0 <= nu1 < nu2; nu2 may be
  !> huge() or +Inf (to infinity).
  subroutine band_from_wavenumbers(nu1, nu2, band, error)
    real(wp), intent(in) :: nu1, nu2
    type(spectral_band_t), intent(out) :: band
    type(error_t), allocatable, intent(out) :: error
    if (ieee_is_nan(nu1) .or. ieee_is_nan(nu2)) then
      call set_error(error, 'thermal band: wavenumbers must not be NaN')
    else if (nu1 < 0.0_wp .or. .not. ieee_is_finite(nu1)) then
      call set_error(error, 'thermal band: lower wavenumber = '//str(nu1)//' cm-1 must be finite and >= 0')
    else if (.not. (nu2 > nu1)) then
      call set_error(error, 'thermal band: upper wavenumber = '//str(nu2)//' cm-1 must be > lower wavenumber = ' &
                     //str(nu1)//' cm-1')
    end if
    if (allocated(error)) return
    band%kind = BAND_INTEGRATED
    band%nu1 = 100.0_wp*nu1
    band%nu2 = scale_nu(nu2)
    band%dnu = wavenumber_width(nu1, nu2)
  end subroutine band_from_wavenumbers

  !> A band integrated over wavelengths [lambda1, lambda2] in m, 0 <= lambda1 < lambda2;
  !> lambda2 may be huge() or +Inf.
  subroutine band_from_wavelengths(lambda1, lambda2, band, error)
    real(wp), intent(in) :: lambda1, lambda2
    type(spectral_band_t), intent(out) :: band
    type(error_t), allocatable, intent(out) :: error
    if (ieee_is_nan(lambda1) .or. ieee_is_nan(lambda2)) then
      call set_error(error, 'thermal band: wavelengths must not be NaN')
    else if (lambda1 < 0.0_wp .or. .not. ieee_is_finite(lambda1)) then
      call set_error(error, 'thermal band: lower wavelength = '//str(lambda1)//' m must be finite and >= 0')
    else if (.not. (lambda2 > lambda1)) then
      call set_error(error, 'thermal band: upper wavelength = '//str(lambda2)//' m must be > lower wavelength = ' &
                     //str(lambda1)//' m')
    end if
    if (allocated(error)) return
    band%kind = BAND_INTEGRATED
    band%nu1 = inverse_length(lambda2)
    band%nu2 = inverse_length(lambda1)
    band%dnu = wavelength_width(lambda1, lambda2)
  end subroutine band_from_wavelengths

  !> A single wavelength [m] > 0: radiances per wavelength (W m-2 sr-1 m-1).
  subroutine band_monochromatic_wavelength(lambda, band, error)
    real(wp), intent(in) :: lambda
    type(spectral_band_t), intent(out) :: band
    type(error_t), allocatable, intent(out) :: error
    if (.not. (lambda > 0.0_wp .and. ieee_is_finite(lambda))) then
      call set_error(error, 'thermal wavelength = '//str(lambda)//' m must be finite and > 0')
      return
    end if
    band%kind = BAND_MONO_WAVELENGTH
    band%wavelength = lambda
    band%nu1 = 1.0_wp/lambda
    band%nu2 = band%nu1
  end subroutine band_monochromatic_wavelength

  !> A single wavenumber [cm-1] > 0: radiances per wavenumber (W m-2 sr-1 (cm-1)-1).
  subroutine band_monochromatic_wavenumber(nu, band, error)
    real(wp), intent(in) :: nu
    type(spectral_band_t), intent(out) :: band
    type(error_t), allocatable, intent(out) :: error
    if (.not. (nu > 0.0_wp .and. ieee_is_finite(nu))) then
      call set_error(error, 'thermal wavenumber = '//str(nu)//' cm-1 must be finite and > 0')
      return
    end if
    band%kind = BAND_MONO_WAVENUMBER
    band%nu1 = 100.0_wp*nu
    band%nu2 = band%nu1
  end subroutine band_monochromatic_wavenumber

  !> Planck radiance of the band at temperature t [K] (validated, >= 0), in band_units(band).
  elemental real(wp) function band_radiance(band, t) result(b)
    type(spectral_band_t), intent(in) :: band
    real(wp), intent(in) :: t
    select case (band%kind)
    case (BAND_MONO_WAVELENGTH)
      b = planck_wavelength(band%wavelength, t)
    case (BAND_MONO_WAVENUMBER)
      b = planck_wavenumber(band%nu1/100.0_wp, t)
    case default
      b = band_planck_m(band%nu1, band%nu2, band%dnu, t, 0)
    end select
  end function band_radiance

  !> Temperature derivative of band_radiance [band_units(band) K-1].
  elemental real(wp) function band_dradiance_dt(band, t) result(db)
    type(spectral_band_t), intent(in) :: band
    real(wp), intent(in) :: t
    select case (band%kind)
    case (BAND_MONO_WAVELENGTH)
      db = dplanck_dt_wavelength(band%wavelength, t)
    case (BAND_MONO_WAVENUMBER)
      db = dplanck_dt_wavenumber(band%nu1/100.0_wp, t)
    case default
      db = band_planck_m(band%nu1, band%nu2, band%dnu, t, 1)
    end select
  end function band_dradiance_dt

  !> Units of band_radiance.
  pure function band_units(band) result(units)
    type(spectral_band_t), intent(in) :: band
    character(len=:), allocatable :: units
    select case (band%kind)
    case (BAND_MONO_WAVELENGTH)
      units = 'W m-2 sr-1 m-1'
    case (BAND_MONO_WAVENUMBER)
      units = 'W m-2 sr-1 (cm-1)-1'
    case default
      units = 'W m-2 sr-1'
    end select
  end function band_units

  !> Brightness temperature t [K] of a radiance in band_units(band): the temperature whose
  !> band_radiance equals it. Closed form for single wavelengths or wavenumbers; for bands,
  !> Newton's method on log B(T) inside a bracket that only shrinks (bisection whenever a step
  !> leaves it), to 1e-13 relative. radiance = 0 gives 0; negative or NaN radiance is an error.
  subroutine band_brightness_temperature(band, radiance, t, error)
    type(spectral_band_t), intent(in) :: band
    real(wp), intent(in) :: radiance
    real(wp), intent(out) :: t
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: lo, hi, b, db, t_new, x_mid
    integer :: it
    t = 0.0_wp
    if (ieee_is_nan(radiance)) then
      call set_error(error, 'brightness temperature: radiance = NaN must be finite and >= 0')
      return
    else if (.not. (radiance >= 0.0_wp .and. ieee_is_finite(radiance))) then
      call set_error(error, 'brightness temperature: radiance = '//str(radiance)//' must be finite and >= 0')
      return
    end if
    if (radiance == 0.0_wp) return
    select case (band%kind)
    case (BAND_MONO_WAVELENGTH)
      t = brightness_temperature_wavelength(radiance, band%wavelength)
      return
    case (BAND_MONO_WAVENUMBER)
      t = brightness_temperature_wavenumber(radiance, band%nu1/100.0_wp)
      return
    end select
    ! First guess: the monochromatic inverse at the band centre (or at x = 3.9 for an open band,
    ! near the peak of t^3/(e^t - 1)) for the mean spectral radiance.
    if (band%nu2 < huge(1.0_wp)) then
      x_mid = 0.5_wp*(band%nu1 + band%nu2)
      t = PLANCK_C2*x_mid/log1p_ratio(PLANCK_C1*x_mid**3*(band%nu2 - band%nu1), radiance)
    else
      t = (radiance/(C_BAND*TOTAL_PLANCK))**0.25_wp
    end if
    if (.not. (t > 0.0_wp .and. ieee_is_finite(t))) t = 300.0_wp
    lo = 0.0_wp
    hi = huge(1.0_wp)
    do it = 1, 400
      b = band_planck_m(band%nu1, band%nu2, band%dnu, t, 0)
      if (b < radiance) then
        lo = t
      else
        hi = t
      end if
      if (b > 0.0_wp) then
        db = band_planck_m(band%nu1, band%nu2, band%dnu, t, 1)
        t_new = t - log(b/radiance)*b/db
      else
        t_new = 2.0_wp*t
      end if
      if (.not. (t_new > lo .and. t_new < hi)) then
        if (hi >= huge(1.0_wp)) then
          t_new = 2.0_wp*max(t, lo)
        else
          t_new = 0.5_wp*(lo + hi)
        end if
      end if
      if (abs(t_new - t) <= 1.0e-13_wp*t_new) then
        t = t_new
        return
      end if
      t = t_new
    end do
    call set_error(error, 'brightness temperature: no convergence for radiance = '//str(radiance))
  end subroutine band_brightness_temperature

  ! ---------------------------------------------------------------------------------------
  ! Temperature validation
  ! ---------------------------------------------------------------------------------------

  !> A temperature must be finite and >= 0 K; `name` names it in the message.
  subroutine check_temperature_scalar(t, name, error)
    real(wp), intent(in) :: t
    character(len=*), intent(in) :: name
    type(error_t), allocatable, intent(out) :: error
    if (ieee_is_nan(t)) then
      call set_error(error, name//' = NaN K: temperatures must be finite and >= 0')
    else if (t < 0.0_wp .or. .not. ieee_is_finite(t)) then
      call set_error(error, name//' = '//str(t)//' K must be finite and >= 0')
    end if
  end subroutine check_temperature_scalar

  !> All temperatures of an array must be finite and >= 0 K; the message names the first bad
  !> element by its position in array element order (1-based).
  subroutine check_temperature_array(t, name, error)
    real(wp), intent(in) :: t(:)
    character(len=*), intent(in) :: name
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    do i = 1, size(t)
      call check_temperature_scalar(t(i), name//'('//str(i)//')', error)
      if (allocated(error)) return
    end do
  end subroutine check_temperature_array

end module kumo_planck
