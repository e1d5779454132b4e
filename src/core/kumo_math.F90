! SPDX-License-Identifier: BSD-3-Clause
!> Small geometry helpers for photon directions, and Gauss-Legendre quadrature.
module kumo_math
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use kumo_kinds, only: wp
  use kumo_constants, only: PI
  implicit none
  private
  public :: rotate_direction, within, wrap, gauss_legendre01, first_not_below, arccos, UZ_MIN, &
            GL5_X, GL5_W

  !> Smallest |uz| a photon may travel with. Plane crossings divide by uz; directions closer to
  !> the horizontal are nudged to this value and the nudge is counted as an anomaly.
  real(wp), parameter :: UZ_MIN = 1.0e-10_wp

  !> 5-point Gauss-Legendre nodes and weights on [-1, 1] (exact for polynomials of degree 9).
  real(wp), parameter :: GL5_X(5) = [-sqrt(5.0_wp + 2.0_wp*sqrt(10.0_wp/7.0_wp))/3.0_wp, &
                                     -sqrt(5.0_wp - 2.0_wp*sqrt(10.0_wp/7.0_wp))/3.0_wp, 0.0_wp, &
                                     sqrt(5.0_wp - 2.0_wp*sqrt(10.0_wp/7.0_wp))/3.0_wp, &
                                     sqrt(5.0_wp + 2.0_wp*sqrt(10.0_wp/7.0_wp))/3.0_wp]
  real(wp), parameter :: GL5_W(5) = [(322.0_wp - 13.0_wp*sqrt(70.0_wp))/900.0_wp, &
                                     (322.0_wp + 13.0_wp*sqrt(70.0_wp))/900.0_wp, &
                                     128.0_wp/225.0_wp, &
                                     (322.0_wp + 13.0_wp*sqrt(70.0_wp))/900.0_wp, &
                                     (322.0_wp - 13.0_wp*sqrt(70.0_wp))/900.0_wp]

  !> arccos: pi and pi/2 as the nearest double plus the remainder, and the coefficients c_k of
  !> R(z) = (asin(sqrt(z)) - sqrt(z))/z^(3/2) = sum c_k z^k on [0, 1/4], from Chebyshev
  !> interpolation of degree 12 in 50-digit arithmetic (largest error 1.5e-17; c_0 = 1/6 and
  !> c_1 = 3/40 are the Taylor coefficients to 16 digits).
  real(wp), parameter :: PI_HI = 3.141592653589793116_wp, PI_LO = 1.2246467991473532e-16_wp
  real(wp), parameter :: PIO2_HI = 1.5707963267948965580_wp, PIO2_LO = 6.123233995736766e-17_wp
  real(wp), parameter :: ASIN_C(0:12) = [0.16666666666666667827_wp, 0.074999999999984329332_wp, &
    0.044642857146355429783_wp, 0.030381944138531247287_wp, 0.022372172942149887875_wp, &
    0.017352392720869972942_wp, 0.013971212973552933304_wp, 0.011479177415184905896_wp, &
    0.010322814350185779287_wp, 0.0054575067186403583004_wp, 0.017400879442694022443_wp, &
    -0.014851887071247203224_wp, 0.028757851367421564708_wp]

contains

  !> acos(x) for x in [-1, 1], within one unit in the last place of the library's value, for the
  !> phase-function evaluations of the photon loop: one polynomial, one square root and no
  !> branches (the library's acos takes about 1.4 times as long per call, and its two ranges
  !> branch at random on scattering angles). asin(a) = a + a^3 R(a^2) for |x| <= 1/2;
  !> acos(x) = 2 asin(sqrt((1 - x)/2)) beyond, and pi minus that for x < 0; both with
  !> z <= 1/4, where R is a polynomial (ASIN_C), summed in Estrin's order.
  elemental real(wp) function arccos(x) result(t)
    real(wp), intent(in) :: x
    real(wp) :: a, z, s, r, z2, z4, z8
    logical :: inner
    a = abs(x)
    inner = a <= 0.5_wp
    z = merge(a*a, 0.5_wp - 0.5_wp*a, inner)
    s = merge(a, sqrt(z), inner)
    z2 = z*z
    z4 = z2*z2
    z8 = z4*z4
    r = ((ASIN_C(0) + ASIN_C(1)*z) + z2*(ASIN_C(2) + ASIN_C(3)*z)) &
        + z4*((ASIN_C(4) + ASIN_C(5)*z) + z2*(ASIN_C(6) + ASIN_C(7)*z)) &
        + z8*(((ASIN_C(8) + ASIN_C(9)*z) + z2*(ASIN_C(10) + ASIN_C(11)*z)) + z4*ASIN_C(12))
    r = s + s*z*r                 ! asin(s)
    ! inner: pi/2 - sign(x) r; beyond: 2 r for x > 0, pi - 2 r for x < 0
    t = merge(PIO2_HI - (sign(r, x) - PIO2_LO), &
              merge(PI_HI - (2.0_wp*r - PI_LO), 2.0_wp*r, x < 0.0_wp), inner)
  end function arccos

  !> lo <= x <= hi, false for NaN. NaN is tested before any comparison, so input validation does
  !> not raise the invalid-operation flag (which debug builds trap).
  elemental logical function within(x, lo, hi) result(ok)
    real(wp), intent(in) :: x, lo, hi
    ok = .false.
    if (ieee_is_nan(x)) return
    ok = x >= lo .and. x <= hi
  end function within

  !> Turn the unit vector (ux, uy, uz) by the polar angle whose cosine is `mu` and the azimuth
  !> given by (cos_phi, sin_phi) about the original direction (rotation formula of the seed text,
  !> App. A5, eq. A5.5/A5.6). The result is renormalised to remove round-off drift by one Newton
  !> step for 1/sqrt(q) at q = 1, 1.5 - q/2: the rotation of a unit vector has q = 1 to a few
  !> ulp, so the step leaves an error of order (q - 1)^2, below rounding, without the square
  !> root and division of the exact factor (they lie on the dependency chain of every
  !> scattering). An input off unit length by d comes out off by about 1.5 d^2.
  pure subroutine rotate_direction(ux, uy, uz, mu, cos_phi, sin_phi)
    real(wp), intent(inout) :: ux, uy, uz  !! direction cosines, unit length
    real(wp), intent(in) :: mu              !! cosine of the turning (scattering) angle
    real(wp), intent(in) :: cos_phi, sin_phi !! azimuth of the turn about the old direction
    real(wp) :: sin_t, s, t, vx, vy, vz, norm
    sin_t = sqrt(max(0.0_wp, 1.0_wp - mu*mu))
    s = sqrt(max(0.0_wp, ux*ux + uy*uy))
    if (s < 1.0e-8_wp) then
      vx = sin_t*cos_phi
      vy = sin_t*sin_phi
      vz = mu*sign(1.0_wp, uz)
    else
      t = sin_t/s
      vx = mu*ux + t*(cos_phi*ux*uz - sin_phi*uy)
      vy = mu*uy + t*(cos_phi*uy*uz + sin_phi*ux)
      vz = mu*uz - sin_t*cos_phi*s
    end if
    norm = 1.5_wp - 0.5_wp*(vx*vx + vy*vy + vz*vz)
    ux = vx*norm
    uy = vy*norm
    uz = vz*norm
  end subroutine rotate_direction

  !> The first index i of the ascending list x with x(i) >= v (size(x) when there is none),
  !> by bisection.
  pure integer function first_not_below(x, v) result(i)
    real(wp), intent(in) :: x(:), v
    integer :: lo, hi
    lo = 1
    hi = size(x)
    do while (lo < hi)
      i = (lo + hi)/2
      if (x(i) < v) then
        lo = i + 1
      else
        hi = i
      end if
    end do
    i = lo
  end function first_not_below

  !> Map a coordinate back into the periodic interval [0, l). A photon that has just crossed
  !> the boundary is less than one period out: x + l or x - l is then what modulo gives (x - l
  !> is exact there, and modulo adds l to the remainder x of a negative x), without the
  !> library's fmod.
  pure subroutine wrap(x, l)
    real(wp), intent(inout) :: x
    real(wp), intent(in) :: l
    if (x >= 0.0_wp .and. x < l) return
    if (x < 0.0_wp .and. x > -l) then
      x = x + l
    else if (x >= l .and. x < 2.0_wp*l) then
      x = x - l
    else
      x = modulo(x, l)
    end if
    if (x >= l) x = 0.0_wp
  end subroutine wrap

  !> Gauss-Legendre nodes x and weights w on [0, 1] (Newton iteration on the Legendre
  !> recurrence from the Tricomi initial guesses; weights sum to 1).
  pure subroutine gauss_legendre01(n, x, w)
    integer, intent(in) :: n
    real(wp), intent(out) :: x(n), w(n)
    real(wp) :: z, p0, p1, p2, dp, dz
    integer :: i, k, it
    do i = 1, (n + 1)/2
      z = cos(PI*(i - 0.25_wp)/(n + 0.5_wp))
      do it = 1, 100
        p0 = 1.0_wp
        p1 = z
        do k = 2, n
          p2 = ((2*k - 1)*z*p1 - (k - 1)*p0)/k
          p0 = p1
          p1 = p2
        end do
        if (n == 1) p0 = 1.0_wp
        dp = n*(z*p1 - p0)/(z*z - 1.0_wp)
        dz = p1/dp
        z = z - dz
        if (abs(dz) < 1.0e-15_wp) exit
      end do
      ! dp of the last step, at a node that moved by less than 1e-15 since
      x(i) = 0.5_wp*(1.0_wp - z)
      x(n + 1 - i) = 0.5_wp*(1.0_wp + z)
      w(i) = 1.0_wp/((1.0_wp - z*z)*dp*dp)
      w(n + 1 - i) = w(i)
    end do
  end subroutine gauss_legendre01

end module kumo_math
