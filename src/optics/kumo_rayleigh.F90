! SPDX-License-Identifier: BSD-3-Clause
!> Rayleigh scattering by dry air: cross-section, King factor, depolarisation, optical depth of
!> pressure layers and the depolarised Rayleigh phase function.
!>
!> The optical depth follows Bodhaine, Wood, Dutton and Slusser (1999), "On Rayleigh optical
!> depth calculations", J. Atmos. Oceanic Technol. 16, 1854-1861 (cited below as B99):
!>
!> * refractive index of standard air (288.15 K, 1013.25 hPa) at 300 ppm CO2, Peck and Reeder
!>   (1972) (B99 eq. 4):
!>   (n_300 - 1) 1e8 = 8060.51 + 2480990/(132.274 - lambda^-2) + 17455.7/(39.32957 - lambda^-2),
!>   lambda in um, scaled to another CO2 amount with Edlen's factor (B99 eq. 19)
!>   (n_CO2 - 1)/(n_300 - 1) = 1 + 0.54 (C - 0.0003), C in parts per volume;
!> * King factors of Bates (1984): F(N2) = 1.034 + 3.17e-4 lambda^-2,
!>   F(O2) = 1.096 + 1.385e-3 lambda^-2 + 1.448e-4 lambda^-4, F(Ar) = 1, F(CO2) = 1.15, mixed
!>   by volume percent 78.084 N2, 20.946 O2, 0.934 Ar and C_CO2 (CO2 in percent, B99);
!> * cross-section per molecule
!>   sigma = 24 pi^3 (n_s^2 - 1)^2 / (lambda^4 N_s^2 (n_s^2 + 2)^2) F_air,
!>   N_s = 2.546899e19 cm-3, molecules per cm3 of standard air;
!> * optical depth of the air between two pressures under hydrostatic equilibrium
!>   tau = sigma N_A Delta p / (m_a g), with the mean molar mass of dry air
!>   m_a = 15.0556 C + 28.9595 g/mol (C in parts per volume), the gravity of List (1968) as a
!>   function of latitude and height and, for a whole column above a station at height z, the
!>   mass-weighted height z_c = 0.73737 z + 5517.56 m at which g is taken.
!>
!> The depolarisation ratio follows from the King factor, rho = 6 (F - 1)/(3 + 7 F)
!> (inverse of the King relation F = (6 + 3 rho)/(6 - 7 rho)). The phase function with
!> depolarisation is Chandrasekhar's (Radiative Transfer, 1950, chapter I) in kumo's normalisation
!> ((1/2) Int_{-1}^{1} P dmu = 1, see kumo_phase):
!>
!>     P(mu) = 3/(4 (1 + 2 gamma)) [(1 + 3 gamma) + (1 - gamma) mu^2],  gamma = rho/(2 - rho).
!>
!> Units: wavelength in micrometres (`wavelength_um`), CO2 in ppm by volume (`co2_ppm`),
!> everything else SI (m, Pa, m2, m s-2, kg mol-1).
module kumo_rayleigh
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_constants, only: PI, DEG2RAD
  use kumo_math, only: GL5_X, GL5_W
  use kumo_error, only: error_t, set_error, str
  implicit none
  private
  public :: RAYLEIGH_WL_MIN_UM, RAYLEIGH_WL_MAX_UM, CO2_MAX_PPM, CO2_DEFAULT_PPM
  public :: AVOGADRO, N_STD_AIR, DEPOL_MAX
  public :: air_refractivity, king_factor_air, depol_from_king, king_from_depol
  public :: rayleigh_cross_section, air_molar_mass, gravity_bodhaine, column_gravity_height
  public :: rayleigh_layer_tau, rayleigh_column_tau, rayleigh_extinction
  public :: rayleigh_check_inputs
  public :: rayleigh_depol_eval, rayleigh_depol_sample_mu, rayleigh_depol_check

  !> Wavelength range of the formula [um]: the range of the Peck and Reeder (1972) dispersion
  !> formula for the refractive index (0.23-1.69 um). Bates' (1984) King factors are fits over
  !> 0.2-1 um; above 1 um their lambda^-2 terms change F_air by less than 1e-4.
  real(wp), parameter :: RAYLEIGH_WL_MIN_UM = 0.23_wp
  real(wp), parameter :: RAYLEIGH_WL_MAX_UM = 1.69_wp
  !> Largest accepted CO2 amount [ppm]: Edlen's correction and the molar-mass formula are
  !> linear expansions around today's air; 2000 ppm covers past and projected climates.
  real(wp), parameter :: CO2_MAX_PPM = 2000.0_wp
  !> CO2 amount of B99's reference calculations and fits [ppm].
  real(wp), parameter :: CO2_DEFAULT_PPM = 360.0_wp
  !> Avogadro's number as used by B99 [mol-1] (Cohen and Taylor 1987 value, B990).
  real(wp), parameter :: AVOGADRO = 6.0221367e23_wp
  !> Molecules per m3 of standard air, 288.15 K and 1013.25 hPa (B99: 2.546899e19 cm-3).
  real(wp), parameter :: N_STD_AIR = 2.546899e25_wp
  !> The King factor (6 + 3 rho)/(6 - 7 rho) is finite for rho < 6/7.
  real(wp), parameter :: DEPOL_MAX = 6.0_wp/7.0_wp

  ! Volume percentages of the permanent gases of dry air (B99, after Bates 1984).
  real(wp), parameter :: PCT_N2 = 78.084_wp, PCT_O2 = 20.946_wp, PCT_AR = 0.934_wp

contains

  ! ------------------------------------------------------------------------------------------
  ! Properties of air
  ! ------------------------------------------------------------------------------------------

  !> Refractivity n_s - 1 of standard dry air (288.15 K, 1013.25 hPa) with `co2_ppm` of CO2:
  !> Peck and Reeder (1972) at 300 ppm (B99 eq. 4) times Edlen's CO2 factor (B99 eq. 19).
  elemental function air_refractivity(wavelength_um, co2_ppm) result(dn)
    real(wp), intent(in) :: wavelength_um  !! vacuum wavelength [um]
    real(wp), intent(in) :: co2_ppm        !! CO2 volume mixing ratio [ppm]
    real(wp) :: dn                         !! n_s - 1
    real(wp) :: s2
    s2 = 1.0_wp/(wavelength_um*wavelength_um)
    dn = 1.0e-8_wp*(8060.51_wp + 2480990.0_wp/(132.274_wp - s2) + 17455.7_wp/(39.32957_wp - s2))
    dn = dn*(1.0_wp + 0.54_wp*(1.0e-6_wp*co2_ppm - 0.0003_wp))
  end function air_refractivity

  !> King factor of dry air (B99): the volume-weighted mean of Bates' (1984) factors
  !> of N2, O2, Ar and CO2 (B99), CO2 entering in volume percent.
  elemental function king_factor_air(wavelength_um, co2_ppm) result(f)
    real(wp), intent(in) :: wavelength_um  !! vacuum wavelength [um]
    real(wp), intent(in) :: co2_ppm        !! CO2 volume mixing ratio [ppm]
    real(wp) :: f                          !! King factor F_air (>= 1)
    real(wp) :: s2, f_n2, f_o2, c_pct
    s2 = 1.0_wp/(wavelength_um*wavelength_um)
    f_n2 = 1.034_wp + 3.17e-4_wp*s2
    f_o2 = 1.096_wp + 1.385e-3_wp*s2 + 1.448e-4_wp*s2*s2
    c_pct = 1.0e-4_wp*co2_ppm
    f = (PCT_N2*f_n2 + PCT_O2*f_o2 + PCT_AR*1.0_wp + c_pct*1.15_wp) &
        /(PCT_N2 + PCT_O2 + PCT_AR + c_pct)
  end function king_factor_air

  !> Depolarisation ratio rho from the King factor F = (6 + 3 rho)/(6 - 7 rho) (B99).
  elemental function depol_from_king(f) result(rho)
    real(wp), intent(in) :: f  !! King factor (>= 1)
    real(wp) :: rho            !! depolarisation ratio
    rho = 6.0_wp*(f - 1.0_wp)/(3.0_wp + 7.0_wp*f)
  end function depol_from_king

  !> King factor F = (6 + 3 rho)/(6 - 7 rho) of a depolarisation ratio 0 <= rho < 6/7.
  elemental function king_from_depol(rho) result(f)
    real(wp), intent(in) :: rho  !! depolarisation ratio
    real(wp) :: f                !! King factor
    f = (6.0_wp + 3.0_wp*rho)/(6.0_wp - 7.0_wp*rho)
  end function king_from_depol

  !> Rayleigh scattering cross-section per molecule of dry air [m2] (B99). The
  !> combination (n^2 - 1)/(n^2 + 2) is formed from n - 1 without cancellation.
  elemental function rayleigh_cross_section(wavelength_um, co2_ppm) result(sigma)
    real(wp), intent(in) :: wavelength_um  !! vacuum wavelength [um]
    real(wp), intent(in) :: co2_ppm        !! CO2 volume mixing ratio [ppm]
    real(wp) :: sigma                      !! cross-section [m2]
    real(wp) :: dn, ratio, lambda_m
    dn = air_refractivity(wavelength_um, co2_ppm)
    ratio = dn*(2.0_wp + dn)/(3.0_wp + dn*(2.0_wp + dn))   ! (n^2 - 1)/(n^2 + 2)
    lambda_m = 1.0e-6_wp*wavelength_um
    sigma = 24.0_wp*PI**3*ratio*ratio/(lambda_m**4*N_STD_AIR**2) &
            *king_factor_air(wavelength_um, co2_ppm)
  end function rayleigh_cross_section

  !> Mean molar mass of dry air [kg mol-1], m_a = 15.0556 C + 28.9595 g/mol with C the CO2
  !> volume fraction (B99: 28.9595 g/mol without CO2, 28.9649 at 360 ppm).
  elemental function air_molar_mass(co2_ppm) result(m)
    real(wp), intent(in) :: co2_ppm  !! CO2 volume mixing ratio [ppm]
    real(wp) :: m                    !! molar mass [kg mol-1]
    m = 1.0e-3_wp*(15.0556_wp*1.0e-6_wp*co2_ppm + 28.9595_wp)
  end function air_molar_mass

  !> Acceleration of gravity [m s-2] at latitude `latitude_deg` and height `z` above sea level
  !> (List 1968, B99, which are in cm s-2 with z in m):
  !> g0 = 980.6160 (1 - 0.0026373 cos 2phi + 0.0000059 cos^2 2phi),
  !> g = g0 - (3.085462e-4 + 2.27e-7 cos 2phi) z + (7.254e-11 + 1.0e-13 cos 2phi) z^2
  !>        - (1.517e-17 + 6.0e-20 cos 2phi) z^3.
  elemental function gravity_bodhaine(latitude_deg, z) result(g)
    real(wp), intent(in) :: latitude_deg  !! latitude [deg]
    real(wp), intent(in) :: z        !! height above sea level [m]
    real(wp) :: g                    !! gravity [m s-2]
    real(wp) :: c2, g0
    c2 = cos(2.0_wp*latitude_deg*DEG2RAD)
    g0 = 980.6160_wp*(1.0_wp - 0.0026373_wp*c2 + 0.0000059_wp*c2*c2)
    g = g0 - (3.085462e-4_wp + 2.27e-7_wp*c2)*z + (7.254e-11_wp + 1.0e-13_wp*c2)*z*z &
        - (1.517e-17_wp + 6.0e-20_wp*c2)*z*z*z
    g = 1.0e-2_wp*g
  end function gravity_bodhaine

  !> Height [m] at which g is taken for the whole air column above a station at height `z`:
  !> the mass-weighted column height z_c = 0.73737 z + 5517.56 (B99).
  elemental function column_gravity_height(z) result(zc)
    real(wp), intent(in) :: z  !! station height above sea level [m]
    real(wp) :: zc             !! effective height for g [m]
    zc = 0.73737_wp*z + 5517.56_wp
  end function column_gravity_height

  ! ------------------------------------------------------------------------------------------
  ! Optical depth
  ! ------------------------------------------------------------------------------------------

  !> Rayleigh optical depth of the air between pressures `p_bottom` > `p_top` [Pa], with g
  !> taken at height `z_g` (B99): tau = sigma N_A (p_bottom - p_top)/(m_a g).
  elemental function rayleigh_layer_tau(wavelength_um, p_bottom, p_top, latitude_deg, z_g, &
                                        co2_ppm) result(tau)
    real(wp), intent(in) :: wavelength_um  !! vacuum wavelength [um]
    real(wp), intent(in) :: p_bottom       !! pressure at the bottom of the layer [Pa]
    real(wp), intent(in) :: p_top          !! pressure at the top of the layer [Pa]
    real(wp), intent(in) :: latitude_deg        !! latitude [deg]
    real(wp), intent(in) :: z_g            !! height at which gravity is taken [m]
    real(wp), intent(in) :: co2_ppm        !! CO2 volume mixing ratio [ppm]
    real(wp) :: tau                        !! optical depth
    tau = rayleigh_cross_section(wavelength_um, co2_ppm)*AVOGADRO*(p_bottom - p_top) &
          /(air_molar_mass(co2_ppm)*gravity_bodhaine(latitude_deg, z_g))
  end function rayleigh_layer_tau

  !> Rayleigh optical depth of the whole column above a station at height `z_station` with
  !> surface pressure `p_surface` [Pa]: the layer formula of B99 with g at z_c.
  elemental function rayleigh_column_tau(wavelength_um, p_surface, latitude_deg, z_station, &
                                         co2_ppm) result(tau)
    real(wp), intent(in) :: wavelength_um  !! vacuum wavelength [um]
    real(wp), intent(in) :: p_surface      !! pressure at the station [Pa]
    real(wp), intent(in) :: latitude_deg        !! latitude [deg]
    real(wp), intent(in) :: z_station      !! station height above sea level [m]
    real(wp), intent(in) :: co2_ppm        !! CO2 volume mixing ratio [ppm]
    real(wp) :: tau                        !! optical depth
    tau = rayleigh_layer_tau(wavelength_um, p_surface, 0.0_wp, latitude_deg, &
                             column_gravity_height(z_station), co2_ppm)
  end function rayleigh_column_tau

  !> Check the inputs shared by the optical-depth routines: the wavelength within the range of
  !> the formula, CO2 within [0, CO2_MAX_PPM], latitude within [-90, 90].
  subroutine rayleigh_check_inputs(wavelength_um, co2_ppm, latitude_deg, error)
    real(wp), intent(in) :: wavelength_um  !! vacuum wavelength [um]
    real(wp), intent(in) :: co2_ppm        !! CO2 volume mixing ratio [ppm]
    real(wp), intent(in) :: latitude_deg        !! latitude [deg]
    type(error_t), allocatable, intent(out) :: error
    if (.not. (wavelength_um >= RAYLEIGH_WL_MIN_UM .and. wavelength_um <= RAYLEIGH_WL_MAX_UM)) then
      call set_error(error, 'rayleigh: wavelength_um = '//str(wavelength_um)// &
                     ' must be within ['//str(RAYLEIGH_WL_MIN_UM)//', '// &
                     str(RAYLEIGH_WL_MAX_UM)//'] (range of the Peck and Reeder formula)')
    else if (.not. (co2_ppm >= 0.0_wp .and. co2_ppm <= CO2_MAX_PPM)) then
      call set_error(error, 'rayleigh: co2_ppm = '//str(co2_ppm)//' must be within [0, '// &
                     str(CO2_MAX_PPM)//'] (CO2 in ppm by volume, e.g. 400)')
    else if (.not. (latitude_deg >= -90.0_wp .and. latitude_deg <= 90.0_wp)) then
      call set_error(error, 'rayleigh: latitude_deg = '//str(latitude_deg)// &
                     ' must be within [-90, 90]')
    end if
  end subroutine rayleigh_check_inputs

  !> Rayleigh extinction coefficient [m-1] of each of kumo's layers from a pressure profile.
  !>
  !> The profile p(z) is given at heights `z_prof` (increasing) and interpolated linearly in
  !> log p, i.e. p falls exponentially within each profile interval. The optical depth of the
  !> air between heights a < b is tau = sigma N_A/m_a Int_a^b (-dp/dz)/g(z) dz (hydrostatic
  !> equilibrium, B99, with height-dependent g); the integral is taken
  !> over every piece of the layer that lies in one profile interval with 5-point
  !> Gauss-Legendre quadrature, so optical depths add exactly over layers. The extinction of
  !> layer k is its optical depth divided by its thickness z_levels(k+1) - z_levels(k).
  !> kumo's levels must lie within [z_prof(1), z_prof(n)].
  subroutine rayleigh_extinction(wavelength_um, z_levels, z_prof, p_prof, latitude_deg, co2_ppm, &
                                 ext, error)
    real(wp), intent(in) :: wavelength_um  !! vacuum wavelength [um]
    real(wp), intent(in) :: z_levels(:)    !! kumo's layer boundaries, bottom first [m]
    real(wp), intent(in) :: z_prof(:)      !! heights of the pressure profile, increasing [m]
    real(wp), intent(in) :: p_prof(:)      !! pressure at z_prof [Pa], > 0
    real(wp), intent(in) :: latitude_deg        !! latitude [deg]
    real(wp), intent(in) :: co2_ppm        !! CO2 volume mixing ratio [ppm]
    !> Extinction coefficient of layer k = [z_levels(k), z_levels(k+1)] [m-1]
    real(wp), allocatable, intent(out) :: ext(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: nz, np, k, j
    real(wp) :: factor, a, b, tau

    nz = size(z_levels) - 1
    np = size(p_prof)
    call rayleigh_check_inputs(wavelength_um, co2_ppm, latitude_deg, error)
    if (allocated(error)) return
    call check_increasing('z_levels', z_levels, 2, error)
    if (allocated(error)) return
    if (size(z_prof) /= np) then
      call set_error(error, 'rayleigh: z_prof has '//str(size(z_prof))// &
                     ' values but p_prof has '//str(np)//'; they must have the same size')
      return
    end if
    call check_increasing('z_prof', z_prof, 2, error)
    if (allocated(error)) return
    do j = 1, np
      if (.not. (p_prof(j) > 0.0_wp .and. ieee_is_finite(p_prof(j)))) then
        call set_error(error, 'rayleigh: p_prof('//str(j)//') = '//str(p_prof(j))// &
                       ' must be a finite pressure > 0 [Pa]')
        return
      end if
    end do
    do j = 1, np - 1
      if (.not. (p_prof(j + 1) < p_prof(j))) then
        call set_error(error, 'rayleigh: p_prof('//str(j + 1)//') = '//str(p_prof(j + 1))// &
                       ' must be < p_prof('//str(j)//') = '//str(p_prof(j))// &
                       ' (pressure must fall with height)')
        return
      end if
    end do
    if (z_levels(1) < z_prof(1) .or. z_levels(nz + 1) > z_prof(np)) then
      call set_error(error, 'rayleigh: z_levels from '//str(z_levels(1))//' to '// &
                     str(z_levels(nz + 1))//' m must lie within the pressure profile, z_prof '// &
                     'from '//str(z_prof(1))//' to '//str(z_prof(np))//' m')
      return
    end if

    factor = rayleigh_cross_section(wavelength_um, co2_ppm)*AVOGADRO/air_molar_mass(co2_ppm)
    allocate (ext(nz))
    j = 1
    do k = 1, nz
      tau = 0.0_wp
      ! profile interval j holding the bottom of layer k
      do while (j < np - 1 .and. z_prof(j + 1) <= z_levels(k))
        j = j + 1
      end do
      a = z_levels(k)
      do
        b = min(z_levels(k + 1), z_prof(j + 1))
        tau = tau + piece_mass(z_prof(j), z_prof(j + 1), p_prof(j), p_prof(j + 1), a, b, &
                               latitude_deg)
        if (b >= z_levels(k + 1) .or. j == np - 1) exit
        j = j + 1
        a = b
      end do
      ext(k) = factor*tau/(z_levels(k + 1) - z_levels(k))
    end do
  end subroutine rayleigh_extinction

  !> Mass of air per unit area between heights a <= b [kg m-2], Int_a^b (-dp/dz)/g dz, inside
  !> the profile interval [z0, z1] where p = p0 (p1/p0)^((z - z0)/(z1 - z0)) (5-point
  !> Gauss-Legendre; the integrand is smooth, an exponential over a cubic in z).
  pure function piece_mass(z0, z1, p0, p1, a, b, latitude_deg) result(s)
    real(wp), intent(in) :: z0, z1, p0, p1, a, b, latitude_deg
    real(wp) :: s
    real(wp) :: rate, half, mid, z
    integer :: i
    s = 0.0_wp
    if (b <= a) return
    rate = log(p0/p1)/(z1 - z0)         ! -d ln p/dz, 1/scale height
    half = 0.5_wp*(b - a)
    mid = 0.5_wp*(a + b)
    do i = 1, 5
      z = mid + half*GL5_X(i)
      s = s + GL5_W(i)*rate*p0*exp(-rate*(z - z0))/gravity_bodhaine(latitude_deg, z)
    end do
    s = s*half
  end function piece_mass

  !> Error unless x(i+1) > x(i) for all i and x has at least `n_min` values.
  subroutine check_increasing(name, x, n_min, error)
    character(len=*), intent(in) :: name
    real(wp), intent(in) :: x(:)
    integer, intent(in) :: n_min
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    if (size(x) < n_min) then
      call set_error(error, 'rayleigh: '//name//' has '//str(size(x))// &
                     ' values; at least '//str(n_min)//' are needed')
      return
    end if
    do i = 1, size(x)
      if (.not. ieee_is_finite(x(i))) then
        call set_error(error, 'rayleigh: '//name//'('//str(i)//') = '//str(x(i))// &
                       ' must be finite')
        return
      end if
    end do
    do i = 1, size(x) - 1
      if (.not. (x(i + 1) > x(i))) then
        call set_error(error, 'rayleigh: '//name//'('//str(i + 1)//') = '//str(x(i + 1))// &
                       ' must be > '//name//'('//str(i)//') = '//str(x(i))// &
                       ' (levels increase upwards)')
        return
      end if
    end do
  end subroutine check_increasing

  ! ------------------------------------------------------------------------------------------
  ! Phase function with depolarisation
  ! ------------------------------------------------------------------------------------------

  !> Rayleigh phase function with depolarisation ratio `rho`,
  !> P = 3/(4 (1 + 2 gamma)) [(1 + 3 gamma) + (1 - gamma) mu^2], gamma = rho/(2 - rho);
  !> rho = 0 gives 3/4 (1 + mu^2).
  elemental function rayleigh_depol_eval(rho, mu) result(p)
    real(wp), intent(in) :: rho  !! depolarisation ratio, 0 <= rho < 6/7
    real(wp), intent(in) :: mu   !! cosine of the scattering angle
    real(wp) :: p                !! phase function value
    real(wp) :: gam
    gam = rho/(2.0_wp - rho)
    p = 0.75_wp/(1.0_wp + 2.0_wp*gam)*((1.0_wp + 3.0_wp*gam) + (1.0_wp - gam)*mu*mu)
  end function rayleigh_depol_eval

  !> Exact sample of mu for the depolarised Rayleigh phase function.
  !>
  !> With P = a + b mu^2 (a = 3(1 + 3 gamma)/(4(1 + 2 gamma)), b = 3(1 - gamma)/(4(1 + 2 gamma)),
  !> a + b/3 = 1) the CDF from mu = -1 is F(mu) = (1 + a mu + b mu^3/3)/2, so F(mu) = u is the
  !> cubic a mu + (b/3) mu^3 = v, v = 2u - 1. Its derivative a + b mu^2 > 0, so it has one real
  !> root, given without cancellation by the hyperbolic form of Cardano's solution
  !> mu = 2 sqrt(a/b) sinh(asinh(x)/3), x = (3v/(2a)) sqrt(b/a). The root is odd in v.
  elemental function rayleigh_depol_sample_mu(rho, u) result(mu)
    real(wp), intent(in) :: rho  !! depolarisation ratio, 0 <= rho < 6/7
    real(wp), intent(in) :: u    !! uniform deviate in [0, 1]
    real(wp) :: mu               !! cosine of the scattering angle
    real(wp) :: gam, a, b, r
    gam = rho/(2.0_wp - rho)
    a = 0.75_wp*(1.0_wp + 3.0_wp*gam)/(1.0_wp + 2.0_wp*gam)
    b = 0.75_wp*(1.0_wp - gam)/(1.0_wp + 2.0_wp*gam)
    r = sqrt(b/a)
    mu = 2.0_wp/r*sinh(asinh(1.5_wp*(2.0_wp*u - 1.0_wp)/a*r)/3.0_wp)
    mu = min(1.0_wp, max(-1.0_wp, mu))
  end function rayleigh_depol_sample_mu

  !> Check a depolarisation ratio: finite and 0 <= rho < 6/7 (the King factor diverges at 6/7).
  subroutine rayleigh_depol_check(rho, error)
    real(wp), intent(in) :: rho  !! depolarisation ratio
    type(error_t), allocatable, intent(out) :: error
    if (.not. (rho >= 0.0_wp .and. rho < DEPOL_MAX)) then
      call set_error(error, 'rayleigh: depolarisation ratio rho = '//str(rho)// &
                     ' must satisfy 0 <= rho < 6/7')
    end if
  end subroutine rayleigh_depol_check

end module kumo_rayleigh
