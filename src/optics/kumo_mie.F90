! SPDX-License-Identifier: BSD-3-Clause
!> Mie scattering by homogeneous spheres and its average over a size distribution.
!>
!> Conventions:
!>
!> * Refractive index m = n + i k relative to the surrounding air, k >= 0 absorbing (Bohren &
!>   Huffman 1983, "Absorption and scattering of light by small particles", time factor
!>   exp(-i omega t)); size parameter x = 2 pi r / lambda.
!> * Phase function normalised like the rest of kumo: (1/4pi) Int P dOmega =
!>   (1/2) Int_{-1}^{1} P dmu = 1, so for one sphere P = 2 (|S1|^2 + |S2|^2)/(x^2 Qsca).
!> * Radii and wavelengths in micrometres.
!>
!> Single sphere (Bohren & Huffman ch. 4; Wiscombe 1979, NCAR/TN-140+STR and 1980, Appl. Opt.
!> 19, 1505): the series is cut after N terms, Wiscombe's criterion N = x + 4 x^(1/3) + 1
!> (x <= 8), x + 4.05 x^(1/3) + 2 (8 < x < 4200), x + 4 x^(1/3) + 2 (x >= 4200). The logarithmic
!> derivative D_n(mx) = psi_n'(mx)/psi_n(mx) is always computed by downward recurrence
!> D_{n-1} = n/z - 1/(D_n + n/z) from D = 0 at n = max(N, |mx|) + 16 + 10 (|mx|/2)^(1/3)
!> (Wiscombe starts 16 terms above with a continued-fraction value instead; starting from 0
!> with only 16 extra terms gave errors of 2e-5 in Qsca at x = 100 and 3e-3 at x = 1e4 for
!> m = 1.33 + 1e-5 i, MIEV0 test cases 10 and 11). Wiscombe allows upward
!> recurrence for weakly absorbing spheres; downward is stable for every m and costs a few per
!> cent more). The Riccati-Bessel function psi_n(x) is computed upward from sin x, cos x for
!> x >= 1; for x < 1 the upward recurrence loses about log10(1/x^2) digits per order (sin x/x -
!> cos x cancels), so the ratios psi_n/psi_{n-1} are then obtained by the stable downward
!> continued fraction and multiplied up from psi_0 = sin x. chi_n (the dominant solution) is
!> always computed upward.
!>
!> Size distributions (number density n(r) = dN/dr, any normalisation):
!>
!> * DIST_GAMMA: Hansen & Travis (1974, Space Sci. Rev. 16, 527, eq. 2.56), the modified gamma
!>   distribution with exponent 1 written in effective radius a and effective variance b:
!>   n(r) ~ r^((1 - 3b)/b) exp(-r/(a b)), 0 < b < 1/2. Deirmendjian's cloud C.1,
!>   n ~ r^6 exp(-1.5 r), is a = 6 um, b = 1/9.
!> * DIST_LOGNORMAL: n(r) ~ (1/r) exp(-(ln r - ln r_g)^2/(2 s^2)) with s^2 = ln(1 + b) and
!>   r_g = a (1 + b)^(-5/2) (Hansen & Travis eqs. 2.53-2.55).
!>
!> Integration over radius (seed digest section 3.3, eqs. 2.2.27-32): trapezoidal rule over
!> the range where the volume-weighted density r^4 n(r) (per unit ln r) exceeds TAIL_CUT times
!> its maximum (both ends negligible, so the smooth part converges faster than any power of
!> the step). Qext, Qsca and g use nodes with local step 1/(1/DLNR_EFF + x/DX_EFF) in ln r,
!> i.e. 0.005 in ln r for small drops and 0.05 in x for large ones, so the Mie ripple is
!> sampled several times per period (a uniform 0.005 ln r grid aliased it: g of the C.1 cloud
!> moved by 1e-3 when that step was halved). Measured: refining this grid 2, 4 and 8 times
!> changes ext_per_lwc and g by < 1e-4 for C.1 at 0.7 um and for r_eff = 40 um, v_eff = 0.1
!> at 0.67 um (docs/mie.md). Phase functions, whose cost is N terms times 396 cosine pairs per
!> sphere, use a uniform ln r step DLNR_DEFAULT = 0.005 and are normalised by their own sum.
!>
!> Bulk phase functions are tabulated on a fixed angle grid, symmetric about 90 deg (so each
!> cosine pair +-mu is computed at once from the parity of pi_n and tau_n): steps of 0.01 deg
!> from 0 to 1 deg, 0.05 deg to 5 deg, 0.2 deg to 20 deg and 0.5 deg to 90 deg, mirrored to
!> 180 deg: 791 angles (`mie_angle_grid`). The forward peak of a cloud of 40 um drops at
!> 0.67 um is ~ 0.06 deg wide, resolved by the 0.01 deg steps.
module kumo_mie
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_constants, only: PI, DEG2RAD
  use kumo_error, only: error_t, set_error, str, to_lower
  implicit none
  private
  public :: DIST_GAMMA, DIST_LOGNORMAL, DIST_NAMES, MIE_X_MAX, DLNR_DEFAULT, TAIL_CUT
  public :: RHO_WATER_G_M3
  public :: mie_nstop, mie_coefficients, mie_efficiencies, mie_amplitudes, mie_sphere
  public :: dist_kind_from_name, size_dist_validate, size_dist_log_density, size_dist_range
  public :: mie_angle_grid, mie_bulk_t, mie_bulk, mie_table_t, mie_table_build
  public :: mie_table_bracket

  integer, parameter :: DIST_GAMMA = 1      !! Hansen & Travis gamma distribution (r_eff, v_eff)
  integer, parameter :: DIST_LOGNORMAL = 2  !! log-normal distribution (r_eff, v_eff)
  !> Names of the distribution kinds, indexed by kind code.
  character(len=9), parameter :: DIST_NAMES(2) = [character(len=9) :: 'gamma', 'lognormal']

  !> Largest size parameter accepted (the range of Wiscombe's term-number criterion).
  real(wp), parameter :: MIE_X_MAX = 20000.0_wp
  !> Default step in ln r of the radius quadrature of the phase function.
  real(wp), parameter :: DLNR_DEFAULT = 0.005_wp
  !> Largest step in ln r of the radius quadrature of extinction, scattering and g.
  real(wp), parameter :: DLNR_EFF = 0.005_wp
  !> Largest step in size parameter of that quadrature.
  real(wp), parameter :: DX_EFF = 0.05_wp
  !> The radius range ends where r^4 n(r) falls below this fraction of its maximum.
  real(wp), parameter :: TAIL_CUT = 1.0e-10_wp
  !> Density of liquid water [g m-3].
  real(wp), parameter :: RHO_WATER_G_M3 = 1.0e6_wp

  !> Optical properties of one size distribution at one wavelength.
  type :: mie_bulk_t
    real(wp) :: ext_per_lwc = 0.0_wp  !! extinction per liquid water content [m-1 / (g m-3)]
    real(wp) :: ssa = 0.0_wp          !! single-scattering albedo
    real(wp) :: g = 0.0_wp            !! asymmetry parameter
    real(wp) :: qext = 0.0_wp         !! mean extinction efficiency <C_ext>/<pi r^2>
    real(wp), allocatable :: angle_deg(:)  !! scattering angles [deg], 0 ... 180
    real(wp), allocatable :: phase(:)      !! phase function at angle_deg, (1/2) Int P dmu = 1
  end type mie_bulk_t

  !> Optical properties of a list of effective radii at one wavelength and effective variance.
  type :: mie_table_t
    real(wp) :: wavelength_um = 0.0_wp     !! wavelength [um]
    complex(wp) :: m = (1.0_wp, 0.0_wp)    !! refractive index n + i k
    integer :: dist = DIST_GAMMA           !! DIST_GAMMA or DIST_LOGNORMAL
    real(wp) :: v_eff = 0.0_wp             !! effective variance
    real(wp) :: dlnr = DLNR_DEFAULT        !! radius quadrature step in ln r
    real(wp), allocatable :: r_eff_um(:)   !! effective radii [um], strictly increasing
    real(wp), allocatable :: ext_per_lwc(:)  !! [m-1 / (g m-3)] = [m2 g-1], per radius
    real(wp), allocatable :: ssa(:)        !! single-scattering albedo per radius
    real(wp), allocatable :: g(:)          !! asymmetry parameter per radius
    real(wp), allocatable :: angle_deg(:)  !! scattering angles [deg]
    real(wp), allocatable :: phase(:, :)   !! phase function (angle, radius)
  end type mie_table_t

contains

  ! ------------------------------------------------------------------------------------------
  ! One sphere
  ! ------------------------------------------------------------------------------------------

  !> Number of terms of the Mie series (Wiscombe 1980, eq. 5).
  elemental function mie_nstop(x) result(n)
    real(wp), intent(in) :: x  !! size parameter
    integer :: n
    real(wp) :: c
    c = x**(1.0_wp/3.0_wp)
    if (x <= 8.0_wp) then
      n = int(x + 4.0_wp*c + 1.0_wp)
    else if (x < 4200.0_wp) then
      n = int(x + 4.05_wp*c + 2.0_wp)
    else
      n = int(x + 4.0_wp*c + 2.0_wp)
    end if
    n = max(n, 1)
  end function mie_nstop

  !> Mie coefficients a_n, b_n (n = 1 .. size(a)) of a sphere; no input checks (see
  !> `mie_sphere`). size(a) = size(b) = mie_nstop(x) for a converged series.
  pure subroutine mie_coefficients(x, m, a, b)
    real(wp), intent(in) :: x         !! size parameter > 0
    complex(wp), intent(in) :: m      !! refractive index n + i k
    complex(wp), intent(out) :: a(:)  !! electric coefficients a_n
    complex(wp), intent(out) :: b(:)  !! magnetic coefficients b_n
    complex(wp), allocatable :: d(:)
    real(wp), allocatable :: psi(:)
    complex(wp) :: z, da, db, xi, xi_prev
    real(wp) :: chi, chi_prev, chi_new, r, rx
    integer :: nstop, nmx, n

    nstop = size(a)
    z = m*x
    ! Start far enough above both N and |mx| that the error of the start value D = 0 has
    ! decayed below rounding by n = max(N, |mx|): in the turning-point region of width
    ! ~ (|z|/2)^(1/3) it falls like exp(-(8/3) t^(3/2)), t in those widths; 10 widths suffice.
    nmx = max(nstop, int(abs(z))) + 16 + int(10.0_wp*(0.5_wp*abs(z))**(1.0_wp/3.0_wp))
    ! Logarithmic derivative, downward from D_nmx = 0.
    allocate (d(nmx))
    d(nmx) = (0.0_wp, 0.0_wp)
    do n = nmx, 2, -1
      d(n - 1) = n/z - 1.0_wp/(d(n) + n/z)
    end do
    ! Riccati-Bessel psi_n(x), n = 0 .. nstop (psi(n+1) holds psi_n).
    allocate (psi(nstop + 1))
    psi(1) = sin(x)
    if (x >= 1.0_wp) then
      psi(2) = psi(1)/x - cos(x)
      do n = 2, nstop
        psi(n + 1) = (2*n - 1)/x*psi(n) - psi(n - 1)
      end do
    else
      ! r_n = psi_n/psi_{n-1} = 1/((2n+1)/x - r_{n+1}); no zeros of psi_n for x < pi.
      r = 0.0_wp
      do n = nstop + 20, nstop + 1, -1
        r = 1.0_wp/((2*n + 1)/x - r)
      end do
      rx = r
      ! Store the ratios first, then multiply up.
      do n = nstop, 1, -1
        rx = 1.0_wp/((2*n + 1)/x - rx)
        psi(n + 1) = rx
      end do
      do n = 1, nstop
        psi(n + 1) = psi(n + 1)*psi(n)
      end do
    end if
    ! chi_n upward from chi_{-1} = -sin x, chi_0 = cos x; xi_n = psi_n - i chi_n.
    chi_prev = cos(x)
    chi = cos(x)/x + sin(x)
    xi_prev = cmplx(psi(1), -chi_prev, kind=wp)
    do n = 1, nstop
      if (n > 1) then
        chi_new = (2*n - 1)/x*chi - chi_prev
        chi_prev = chi
        chi = chi_new
      end if
      xi = cmplx(psi(n + 1), -chi, kind=wp)
      da = d(n)/m + n/x
      db = d(n)*m + n/x
      a(n) = (da*psi(n + 1) - psi(n))/(da*xi - xi_prev)
      b(n) = (db*psi(n + 1) - psi(n))/(db*xi - xi_prev)
      xi_prev = xi
    end do
  end subroutine mie_coefficients

  !> Extinction and scattering efficiencies and asymmetry parameter from the coefficients
  !> (Bohren & Huffman eqs. 4.61, 4.62 and p. 120).
  pure subroutine mie_efficiencies(x, a, b, qext, qsca, g)
    real(wp), intent(in) :: x          !! size parameter
    complex(wp), intent(in) :: a(:)    !! a_n
    complex(wp), intent(in) :: b(:)    !! b_n
    real(wp), intent(out) :: qext      !! extinction efficiency
    real(wp), intent(out) :: qsca      !! scattering efficiency
    real(wp), intent(out) :: g         !! asymmetry parameter <cos Theta>
    real(wp) :: se, ss, sg
    integer :: n, nstop
    nstop = size(a)
    se = 0.0_wp
    ss = 0.0_wp
    sg = 0.0_wp
    do n = 1, nstop
      se = se + (2*n + 1)*real(a(n) + b(n), wp)
      ss = ss + (2*n + 1)*(abs2(a(n)) + abs2(b(n)))
      sg = sg + real(2*n + 1, wp)/(real(n, wp)*(n + 1))*real(a(n)*conjg(b(n)), wp)
      if (n < nstop) then
        sg = sg + real(n, wp)*(n + 2)/(n + 1)* &
             real(a(n)*conjg(a(n + 1)) + b(n)*conjg(b(n + 1)), wp)
      end if
    end do
    qext = 2.0_wp*se/(x*x)
    qsca = 2.0_wp*ss/(x*x)
    if (ss > 0.0_wp) then
      g = 2.0_wp*sg/ss
    else
      g = 0.0_wp
    end if
  end subroutine mie_efficiencies

  !> Scattering amplitudes S1, S2 (Bohren & Huffman eq. 4.74) at the cosines mu, with the
  !> angular functions pi_n, tau_n by upward recurrence (eqs. 4.47).
  pure subroutine mie_amplitudes(a, b, mu, s1, s2)
    complex(wp), intent(in) :: a(:)    !! a_n
    complex(wp), intent(in) :: b(:)    !! b_n
    real(wp), intent(in) :: mu(:)      !! cosines of the scattering angle
    complex(wp), intent(out) :: s1(:)  !! S1(mu)
    complex(wp), intent(out) :: s2(:)  !! S2(mu)
    real(wp) :: p0, p1, pn, tau, c
    integer :: j, n
    do j = 1, size(mu)
      s1(j) = (0.0_wp, 0.0_wp)
      s2(j) = (0.0_wp, 0.0_wp)
      p0 = 0.0_wp
      p1 = 1.0_wp
      do n = 1, size(a)
        tau = n*mu(j)*p1 - (n + 1)*p0
        c = real(2*n + 1, wp)/(real(n, wp)*(n + 1))
        s1(j) = s1(j) + c*(a(n)*p1 + b(n)*tau)
        s2(j) = s2(j) + c*(a(n)*tau + b(n)*p1)
        pn = ((2*n + 1)*mu(j)*p1 - (n + 1)*p0)/n
        p0 = p1
        p1 = pn
      end do
    end do
  end subroutine mie_amplitudes

  !> |S1|^2 + |S2|^2 at the cosines +mu_h (ip) and -mu_h (im), mu_h >= 0, in one pass: with
  !> pi_n(-mu) = (-1)^(n-1) pi_n(mu) and tau_n(-mu) = (-1)^n tau_n(mu) the odd and even terms
  !> are summed apart.
  pure subroutine mie_intensity_pm(a, b, mu_h, ip, im)
    complex(wp), intent(in) :: a(:), b(:)
    real(wp), intent(in) :: mu_h(:)
    real(wp), intent(out) :: ip(:), im(:)
    complex(wp), allocatable :: ca(:), cb(:)
    complex(wp) :: ap(0:1), bt(0:1), at(0:1), bp(0:1), s1p, s2p, s1m, s2m
    real(wp) :: p0, p1, pn, tau, mu
    integer :: j, n, k, nstop
    nstop = size(a)
    allocate (ca(nstop), cb(nstop))
    do n = 1, nstop
      ca(n) = a(n)*(real(2*n + 1, wp)/(real(n, wp)*(n + 1)))
      cb(n) = b(n)*(real(2*n + 1, wp)/(real(n, wp)*(n + 1)))
    end do
    do j = 1, size(mu_h)
      mu = mu_h(j)
      ap = (0.0_wp, 0.0_wp)
      bt = ap
      at = ap
      bp = ap
      p0 = 0.0_wp
      p1 = 1.0_wp
      do n = 1, nstop
        k = iand(n, 1)                      ! 1: odd n, 0: even n
        tau = n*mu*p1 - (n + 1)*p0
        ap(k) = ap(k) + ca(n)*p1
        bt(k) = bt(k) + cb(n)*tau
        at(k) = at(k) + ca(n)*tau
        bp(k) = bp(k) + cb(n)*p1
        pn = ((2*n + 1)*mu*p1 - (n + 1)*p0)/n
        p0 = p1
        p1 = pn
      end do
      s1p = ap(1) + ap(0) + bt(1) + bt(0)
      s2p = at(1) + at(0) + bp(1) + bp(0)
      s1m = ap(1) - ap(0) + bt(0) - bt(1)
      s2m = at(0) - at(1) + bp(1) - bp(0)
      ip(j) = abs2(s1p) + abs2(s2p)
      im(j) = abs2(s1m) + abs2(s2m)
    end do
  end subroutine mie_intensity_pm

  !> One sphere: efficiencies, asymmetry parameter and, optionally, the phase function at
  !> given cosines, with input checks.
  subroutine mie_sphere(x, m, qext, qsca, g, error, mu, phase)
    real(wp), intent(in) :: x          !! size parameter, 0 < x <= MIE_X_MAX
    complex(wp), intent(in) :: m       !! refractive index n + i k, n > 0, k >= 0
    real(wp), intent(out) :: qext      !! extinction efficiency
    real(wp), intent(out) :: qsca      !! scattering efficiency
    real(wp), intent(out) :: g         !! asymmetry parameter
    type(error_t), allocatable, intent(out) :: error  !! set for invalid x or m
    real(wp), intent(in), optional :: mu(:)      !! cosines of the scattering angle, in [-1, 1]
    real(wp), intent(out), optional :: phase(:)  !! P(mu), (1/2) Int P dmu = 1
    complex(wp), allocatable :: a(:), b(:), s1(:), s2(:)
    integer :: nstop

    qext = 0.0_wp
    qsca = 0.0_wp
    g = 0.0_wp
    call check_x(x, 'mie_sphere', error)
    if (allocated(error)) return
    call check_m(m, 'mie_sphere', error)
    if (allocated(error)) return
    if (present(mu) .neqv. present(phase)) then
      call set_error(error, 'mie_sphere: mu and phase must be given together')
      return
    end if
    if (present(mu)) then
      if (size(phase) /= size(mu)) then
        call set_error(error, 'mie_sphere: size(phase) = '//str(size(phase))// &
                       ' must equal size(mu) = '//str(size(mu)))
        return
      end if
      if (any(.not. (abs(mu) <= 1.0_wp))) then
        call set_error(error, 'mie_sphere: every mu must be within [-1, 1]')
        return
      end if
    end if
    nstop = mie_nstop(x)
    allocate (a(nstop), b(nstop))
    call mie_coefficients(x, m, a, b)
    call mie_efficiencies(x, a, b, qext, qsca, g)
    if (present(mu)) then
      allocate (s1(size(mu)), s2(size(mu)))
      call mie_amplitudes(a, b, mu, s1, s2)
      phase = 2.0_wp*(abs2(s1) + abs2(s2))/(x*x*qsca)
    end if
  end subroutine mie_sphere

  ! ------------------------------------------------------------------------------------------
  ! Size distributions
  ! ------------------------------------------------------------------------------------------

  !> Distribution kind code of a name ('gamma' or 'lognormal', case-insensitive).
  subroutine dist_kind_from_name(name, dist, error)
    character(len=*), intent(in) :: name             !! distribution name
    integer, intent(out) :: dist                     !! kind code (0 on error)
    type(error_t), allocatable, intent(out) :: error  !! set if the name is unknown
    integer :: i
    do i = 1, size(DIST_NAMES)
      if (to_lower(trim(adjustl(name))) == trim(DIST_NAMES(i))) then
        dist = i
        return
      end if
    end do
    dist = 0
    call set_error(error, "size distribution '"//trim(adjustl(name))// &
                   "' is unknown (allowed: gamma, lognormal)")
  end subroutine dist_kind_from_name

  !> Check a distribution: known kind, r_eff > 0, v_eff > 0 (and < 1/2 for the gamma
  !> distribution, whose exponent (1 - 3b)/b must exceed -1).
  subroutine size_dist_validate(dist, r_eff, v_eff, error)
    integer, intent(in) :: dist                      !! DIST_GAMMA or DIST_LOGNORMAL
    real(wp), intent(in) :: r_eff                    !! effective radius [um]
    real(wp), intent(in) :: v_eff                    !! effective variance
    type(error_t), allocatable, intent(out) :: error  !! set if invalid
    if (dist /= DIST_GAMMA .and. dist /= DIST_LOGNORMAL) then
      call set_error(error, 'size distribution kind = '//str(dist)// &
                     ' must be DIST_GAMMA (1) or DIST_LOGNORMAL (2)')
    else if (.not. (r_eff > 0.0_wp .and. ieee_is_finite(r_eff))) then
      call set_error(error, 'effective radius r_eff = '//str(r_eff)//' um must be > 0')
    else if (.not. (v_eff > 0.0_wp .and. ieee_is_finite(v_eff))) then
      call set_error(error, 'effective variance v_eff = '//str(v_eff)//' must be > 0')
    else if (dist == DIST_GAMMA .and. v_eff >= 0.5_wp) then
      call set_error(error, 'effective variance v_eff = '//str(v_eff)// &
                     ' must be < 0.5 for the gamma distribution')
    else if (v_eff < 1.0e-3_wp) then
      call set_error(error, 'effective variance v_eff = '//str(v_eff)// &
                     ' must be >= 0.001 (narrower distributions need a finer radius grid)')
    end if
  end subroutine size_dist_validate

  !> ln n(r) up to an additive constant.
  elemental function size_dist_log_density(dist, r_eff, v_eff, r) result(ln_n)
    integer, intent(in) :: dist      !! DIST_GAMMA or DIST_LOGNORMAL
    real(wp), intent(in) :: r_eff    !! effective radius [um]
    real(wp), intent(in) :: v_eff    !! effective variance
    real(wp), intent(in) :: r        !! radius [um], > 0
    real(wp) :: ln_n
    real(wp) :: s2, ln_rg
    if (dist == DIST_GAMMA) then
      ln_n = (1.0_wp - 3.0_wp*v_eff)/v_eff*log(r) - r/(r_eff*v_eff)
    else
      s2 = log(1.0_wp + v_eff)
      ln_rg = log(r_eff) - 2.5_wp*s2
      ln_n = -log(r) - (log(r) - ln_rg)**2/(2.0_wp*s2)
    end if
  end function size_dist_log_density

  !> Radius range outside which r^4 n(r) (volume per unit ln r) is below TAIL_CUT times its
  !> maximum, and that maximum's logarithm (for scaling the weights).
  pure subroutine size_dist_range(dist, r_eff, v_eff, r_lo, r_hi, ln_peak)
    integer, intent(in) :: dist
    real(wp), intent(in) :: r_eff, v_eff
    real(wp), intent(out) :: r_lo, r_hi  !! range [um]
    real(wp), intent(out) :: ln_peak     !! max of ln(r^4 n(r))
    real(wp), parameter :: STEP = 0.01_wp
    real(wp) :: ln_r0, ln_r, cut
    ! The maximum of r^4 n: r = r_eff (1 + b) (gamma), ln r = ln r_g + 3 s^2 (log-normal).
    if (dist == DIST_GAMMA) then
      ln_r0 = log(r_eff*(1.0_wp + v_eff))
    else
      ln_r0 = log(r_eff) + 0.5_wp*log(1.0_wp + v_eff)
    end if
    ln_peak = vol_density(ln_r0)
    cut = ln_peak + log(TAIL_CUT)
    ln_r = ln_r0
    do while (vol_density(ln_r) > cut)
      ln_r = ln_r - STEP
    end do
    r_lo = exp(ln_r)
    ln_r = ln_r0
    do while (vol_density(ln_r) > cut)
      ln_r = ln_r + STEP
    end do
    r_hi = exp(ln_r)
  contains
    pure function vol_density(lr) result(f)
      real(wp), intent(in) :: lr
      real(wp) :: f
      f = 4.0_wp*lr + size_dist_log_density(dist, r_eff, v_eff, exp(lr))
    end function vol_density
  end subroutine size_dist_range

  ! ------------------------------------------------------------------------------------------
  ! Bulk properties
  ! ------------------------------------------------------------------------------------------

  !> The angle grid of tabulated bulk phase functions [deg], 0 ... 180, symmetric about 90:
  !> steps 0.01 to 1 deg, 0.05 to 5, 0.2 to 20, 0.5 to 90 (791 angles).
  pure function mie_angle_grid() result(angle_deg)
    real(wp), allocatable :: angle_deg(:)
    real(wp), parameter :: EDGES(5) = [0.0_wp, 1.0_wp, 5.0_wp, 20.0_wp, 90.0_wp]
    real(wp), parameter :: STEPS(4) = [0.01_wp, 0.05_wp, 0.2_wp, 0.5_wp]
    real(wp), allocatable :: half(:)
    integer :: nh, i, j, k, nseg
    nh = 1
    do i = 1, 4
      nh = nh + nint((EDGES(i + 1) - EDGES(i))/STEPS(i))
    end do
    allocate (half(nh))
    half(1) = 0.0_wp
    k = 1
    do i = 1, 4
      nseg = nint((EDGES(i + 1) - EDGES(i))/STEPS(i))
      do j = 1, nseg
        k = k + 1
        half(k) = EDGES(i) + j*STEPS(i)
      end do
    end do
    allocate (angle_deg(2*nh - 1))
    angle_deg(1:nh) = half
    do k = 1, nh - 1
      angle_deg(nh + k) = 180.0_wp - half(nh - k)
    end do
  end function mie_angle_grid

  !> Build the table of bulk optical properties for the effective radii `r_eff_um` at one
  !> wavelength (seed digest eqs. 2.2.21-2.2.29). All radii share one ln r grid, so each
  !> sphere's Mie series is summed once and added, with its weight, to every distribution
  !> that covers it.
  subroutine mie_table_build(wavelength_um, m, dist, v_eff, r_eff_um, table, error, dlnr, refine)
    real(wp), intent(in) :: wavelength_um       !! wavelength [um], > 0
    complex(wp), intent(in) :: m                !! refractive index n + i k
    integer, intent(in) :: dist                 !! DIST_GAMMA or DIST_LOGNORMAL
    real(wp), intent(in) :: v_eff               !! effective variance
    real(wp), intent(in) :: r_eff_um(:)         !! effective radii [um], strictly increasing
    type(mie_table_t), intent(out) :: table     !! the table
    type(error_t), allocatable, intent(out) :: error  !! set for invalid input
    real(wp), intent(in), optional :: dlnr      !! phase-function step in ln r (DLNR_DEFAULT)
    !> divides the steps of the efficiency grid (default 1; for convergence studies)
    real(wp), intent(in), optional :: refine
    character(len=*), parameter :: CTX = 'mie_table_build: '
    real(wp), allocatable :: lo(:), hi(:), lnpk(:), mu_h(:), ip(:), im(:), inten(:)
    real(wp), allocatable :: vol(:), cext(:), csca(:), gsum(:), csca_ph(:)
    complex(wp), allocatable :: a(:), b(:)
    real(wp) :: step, ln_rmin, r, x, k, w, qext, qsca, gi, area, xmax, drds, fine
    integer :: nr, nang, nh, nrad, j, i, nstop

    step = DLNR_DEFAULT
    if (present(dlnr)) step = dlnr
    fine = 1.0_wp
    if (present(refine)) fine = refine
    nr = size(r_eff_um)
    if (.not. (wavelength_um > 0.0_wp .and. ieee_is_finite(wavelength_um))) then
      call set_error(error, CTX//'wavelength = '//str(wavelength_um)//' um must be > 0')
      return
    end if
    call check_m(m, 'mie_table_build', error)
    if (allocated(error)) return
    if (nr < 1) then
      call set_error(error, CTX//'at least one effective radius is needed')
      return
    end if
    if (.not. (step > 0.0_wp .and. step <= 0.1_wp)) then
      call set_error(error, CTX//'dlnr = '//str(step)//' must be within (0, 0.1]')
      return
    end if
    allocate (lo(nr), hi(nr), lnpk(nr))
    do i = 1, nr
      call size_dist_validate(dist, r_eff_um(i), v_eff, error)
      if (allocated(error)) then
        error%message = CTX//'r_eff('//str(i)//'): '//error%message
        return
      end if
      call size_dist_range(dist, r_eff_um(i), v_eff, lo(i), hi(i), lnpk(i))
    end do
    do i = 2, nr
      if (.not. (r_eff_um(i) > r_eff_um(i - 1))) then
        call set_error(error, CTX//'r_eff('//str(i)//') = '//str(r_eff_um(i))// &
                       ' must exceed r_eff('//str(i - 1)//') = '//str(r_eff_um(i - 1)))
        return
      end if
    end do
    k = 2.0_wp*PI/wavelength_um
    xmax = k*maxval(hi)
    if (xmax > MIE_X_MAX) then
      call set_error(error, CTX//'the largest drops (r = '//str(maxval(hi))// &
                     ' um) have size parameter '//str(xmax)//' > '//str(MIE_X_MAX)// &
                     ': reduce r_eff or v_eff, or use a longer wavelength')
      return
    end if

    table%wavelength_um = wavelength_um
    table%m = m
    table%dist = dist
    table%v_eff = v_eff
    table%dlnr = step
    table%r_eff_um = r_eff_um
    table%angle_deg = mie_angle_grid()
    nang = size(table%angle_deg)
    nh = (nang + 1)/2
    mu_h = cos(table%angle_deg(1:nh)*DEG2RAD)
    mu_h(nh) = 0.0_wp
    allocate (ip(nh), im(nh), inten(nang))
    allocate (vol(nr), cext(nr), csca(nr), gsum(nr), csca_ph(nr), source=0.0_wp)
    allocate (table%phase(nang, nr), source=0.0_wp)

    ! Pass 1, efficiencies (cheap per sphere) on the fine grid: local step in ln r
    ! 1/(1/DLNR_EFF + x/DX_EFF), i.e. ~ DLNR_EFF for small spheres and a step DX_EFF in x for
    ! large ones, so the Mie ripple is sampled several times per period. The nodes are equally
    ! spaced in s(r) = ln r/DLNR_EFF + k r/DX_EFF and the trapezoidal rule is applied in s.
    ! (the last nodes of both grids may lie up to one step beyond max(hi))
    nstop = mie_nstop(1.1_wp*xmax + 1.0_wp)
    allocate (a(nstop), b(nstop))
    r = minval(lo)
    do
      x = k*r
      nstop = mie_nstop(x)
      call mie_coefficients(x, m, a(1:nstop), b(1:nstop))
      call mie_efficiencies(x, a(1:nstop), b(1:nstop), qext, qsca, gi)
      drds = 1.0_wp/(fine/(DLNR_EFF*r) + fine*k/DX_EFF)
      area = PI*r*r
      do i = 1, nr
        if (r < lo(i) .or. r > hi(i)) cycle
        w = exp(size_dist_log_density(dist, r_eff_um(i), v_eff, r) - lnpk(i))*drds
        vol(i) = vol(i) + w*area*r*(4.0_wp/3.0_wp)
        cext(i) = cext(i) + w*area*qext
        csca(i) = csca(i) + w*area*qsca
        gsum(i) = gsum(i) + w*area*qsca*gi
      end do
      if (r > maxval(hi)) exit
      r = next_node(r)
    end do

    ! Pass 2, phase functions (the costly part: every term at every angle) on a uniform grid
    ! in ln r of step `step`; normalised by their own scattering sum.
    ln_rmin = log(minval(lo))
    nrad = int((log(maxval(hi)) - ln_rmin)/step) + 1
    do j = 0, nrad
      r = exp(ln_rmin + j*step)
      x = k*r
      nstop = mie_nstop(x)
      call mie_coefficients(x, m, a(1:nstop), b(1:nstop))
      call mie_efficiencies(x, a(1:nstop), b(1:nstop), qext, qsca, gi)
      call mie_intensity_pm(a(1:nstop), b(1:nstop), mu_h, ip, im)
      inten(1:nh) = ip
      inten(nh + 1:nang) = im(nh - 1:1:-1)
      do i = 1, nr
        if (r < lo(i) .or. r > hi(i)) cycle
        ! weight of this node: n(r) dr = n(r) r d(ln r), scaled by the peak of r^4 n
        w = exp(size_dist_log_density(dist, r_eff_um(i), v_eff, r) + log(r) - lnpk(i))*step
        csca_ph(i) = csca_ph(i) + w*PI*r*r*qsca
        ! C_sca P = 2 pi r^2 (|S1|^2 + |S2|^2)/x^2 = 2 pi (|S1|^2 + |S2|^2)/k^2
        table%phase(:, i) = table%phase(:, i) + (w*2.0_wp*PI/(k*k))*inten
      end do
    end do
    ! [um^2/um^3] = [um-1] = 1e6 m-1, divided by the water density [g m-3]: m2 g-1.
    table%ext_per_lwc = cext/vol*1.0e6_wp/RHO_WATER_G_M3
    table%ssa = min(1.0_wp, csca/cext)
    table%g = gsum/csca
    do i = 1, nr
      table%phase(:, i) = table%phase(:, i)/csca_ph(i)
    end do
  contains
    !> The next node: s(r') = s(r) + 1, by Newton's method (s is convex in ln r).
    function next_node(r0) result(r1)
      real(wp), intent(in) :: r0
      real(wp) :: r1, target, f, df
      integer :: it
      target = log(r0)/DLNR_EFF*fine + k*r0/DX_EFF*fine + 1.0_wp
      r1 = r0*exp(1.0_wp/(fine/DLNR_EFF + fine*k*r0/DX_EFF))
      do it = 1, 20
        f = log(r1)/DLNR_EFF*fine + k*r1/DX_EFF*fine - target
        df = fine/(DLNR_EFF*r1) + fine*k/DX_EFF
        r1 = r1 - f/df
        if (abs(f) < 1.0e-12_wp) exit
      end do
    end function next_node
  end subroutine mie_table_build

  !> Bulk properties of one distribution (a one-radius table).
  subroutine mie_bulk(wavelength_um, m, dist, r_eff_um, v_eff, bulk, error, dlnr, refine)
    real(wp), intent(in) :: wavelength_um  !! wavelength [um]
    complex(wp), intent(in) :: m           !! refractive index n + i k
    integer, intent(in) :: dist            !! DIST_GAMMA or DIST_LOGNORMAL
    real(wp), intent(in) :: r_eff_um       !! effective radius [um]
    real(wp), intent(in) :: v_eff          !! effective variance
    type(mie_bulk_t), intent(out) :: bulk  !! the result
    type(error_t), allocatable, intent(out) :: error  !! set for invalid input
    real(wp), intent(in), optional :: dlnr    !! phase-function step in ln r
    real(wp), intent(in), optional :: refine  !! divides the steps of the efficiency grid
    type(mie_table_t) :: t
    call mie_table_build(wavelength_um, m, dist, v_eff, [r_eff_um], t, error, dlnr, refine)
    if (allocated(error)) return
    bulk%ext_per_lwc = t%ext_per_lwc(1)
    bulk%ssa = t%ssa(1)
    bulk%g = t%g(1)
    ! Q_ext = C_ext/<pi r^2> = ext_per_lwc rho (4/3) r_eff ... with <pi r^2> = 3V/(4 r_eff)
    bulk%qext = t%ext_per_lwc(1)*RHO_WATER_G_M3*1.0e-6_wp*4.0_wp*r_eff_um/3.0_wp
    bulk%angle_deg = t%angle_deg
    bulk%phase = t%phase(:, 1)
  end subroutine mie_bulk

  !> The two table radii around `r_eff` and the blending weights. A voxel with effective
  !> radius r between r1 = r_tab(i1) and r2 = r_tab(i2) is treated as a mixture of the two
  !> tabulated populations holding the fractions f and 1 - f of its liquid water, with
  !> f = (1/r - 1/r2)/(1/r1 - 1/r2): the mixture then has exactly the effective radius r
  !> (r_eff = 3V/(4A) and each population's area is 3 f V/(4 r_i)), and extinction per LWC,
  !> which is nearly proportional to 1/r_eff, is interpolated almost exactly. Extinction and
  !> scattering coefficients of the mixture are the f-weighted sums; its phase function is
  !> w P1 + (1 - w) P2 with w = f k1 w1/(f k1 w1 + (1 - f) k2 w2) (k: ext per LWC, w:
  !> single-scattering albedo), the share of the scattering coefficient, which is exactly the
  !> phase function of the mixture of the two populations (seed digest A2.1). `inside` is
  !> false (and i1 = i2 = 0) when r is outside [r_tab(1), r_tab(n)]: no extrapolation.
  pure subroutine mie_table_bracket(r_tab, ext, ssa, r_eff, i1, i2, f_lwc, w_phase, inside)
    real(wp), intent(in) :: r_tab(:)  !! table effective radii, strictly increasing
    real(wp), intent(in) :: ext(:)    !! extinction per LWC of the table radii
    real(wp), intent(in) :: ssa(:)    !! single-scattering albedo of the table radii
    real(wp), intent(in) :: r_eff     !! effective radius of the voxel
    integer, intent(out) :: i1, i2    !! indices of the bracketing radii (i2 = i1 + 1 or i1)
    real(wp), intent(out) :: f_lwc    !! share of the liquid water given to table i1
    real(wp), intent(out) :: w_phase  !! weight of P(i1) in the phase function
    logical, intent(out) :: inside    !! r_eff within the table range
    integer :: n, lo, hi, mid
    real(wp) :: s1, s2
    n = size(r_tab)
    i1 = 0
    i2 = 0
    f_lwc = 0.0_wp
    w_phase = 0.0_wp
    inside = .false.
    if (n < 1) return
    if (.not. (r_eff >= r_tab(1) .and. r_eff <= r_tab(n))) return
    inside = .true.
    if (n == 1) then
      i1 = 1
      i2 = 1
      f_lwc = 1.0_wp
      w_phase = 1.0_wp
      return
    end if
    lo = 1
    hi = n
    do while (hi - lo > 1)
      mid = (lo + hi)/2
      if (r_tab(mid) <= r_eff) then
        lo = mid
      else
        hi = mid
      end if
    end do
    i1 = lo
    i2 = hi
    f_lwc = (1.0_wp/r_eff - 1.0_wp/r_tab(i2))/(1.0_wp/r_tab(i1) - 1.0_wp/r_tab(i2))
    f_lwc = min(1.0_wp, max(0.0_wp, f_lwc))
    s1 = f_lwc*ext(i1)*ssa(i1)
    s2 = (1.0_wp - f_lwc)*ext(i2)*ssa(i2)
    if (s1 + s2 > 0.0_wp) then
      w_phase = s1/(s1 + s2)
    else
      w_phase = f_lwc
    end if
  end subroutine mie_table_bracket

  ! ------------------------------------------------------------------------------------------
  ! Helpers
  ! ------------------------------------------------------------------------------------------

  elemental function abs2(z) result(a)
    complex(wp), intent(in) :: z
    real(wp) :: a
    a = real(z, wp)**2 + aimag(z)**2
  end function abs2

  subroutine check_x(x, routine, error)
    real(wp), intent(in) :: x
    character(len=*), intent(in) :: routine
    type(error_t), allocatable, intent(out) :: error
    if (.not. (x > 0.0_wp .and. x <= MIE_X_MAX)) then
      call set_error(error, routine//': size parameter x = '//str(x)// &
                     ' must satisfy 0 < x <= '//str(MIE_X_MAX))
    end if
  end subroutine check_x

  subroutine check_m(m, routine, error)
    complex(wp), intent(in) :: m
    character(len=*), intent(in) :: routine
    type(error_t), allocatable, intent(out) :: error
    if (.not. (real(m, wp) > 0.0_wp .and. ieee_is_finite(real(m, wp)))) then
      call set_error(error, routine//': refractive index real part n = '//str(real(m, wp))// &
                     ' must be > 0')
    else if (.not. (aimag(m) >= 0.0_wp .and. ieee_is_finite(aimag(m)))) then
      call set_error(error, routine//': refractive index imaginary part k = '// &
                     str(aimag(m))//' must be >= 0 (m = n + i k, k > 0 absorbs)')
    end if
  end subroutine check_m
end module kumo_mie
