! SPDX-License-Identifier: BSD-3-Clause
!> Exponential integrals E_n(x) = Int_1^inf exp(-x t) t^-n dt for n >= 1, x >= 0, and the
!> combinations that plane-parallel thermal transfer needs without cancellation.
!>
!> * x <= 1: the power series of Abramowitz and Stegun (1964) eq. 5.1.12,
!>   E_n(x) = (-x)^(n-1)/(n-1)! (psi(n) - ln x) - sum_{k>=0, k/=n-1} (-x)^k/(k! (k-n+1)),
!>   psi(n) = -gamma + sum_{m<n} 1/m, summed until the terms are below 1e-17 of the sum;
!> * x > 1: the continued fraction of A&S eq. 5.1.22, evaluated by the modified Lentz method
!>   to 1e-16 relative.
!>
!> Accuracy: 2e-15 relative or better for 1 <= n <= 6 on 0 < x < 700 (checked against A&S
!> Table 5.1 and against quadrature of the defining integral in tests/unit/test_thermal_column.F90).
!> Beyond x = 700 the values underflow towards 0.
!>
!> `expint_d(n, x)` = 1/(n-1) - E_n(x) (n >= 2) is the series without its constant term for
!> x <= 1, so that it keeps full relative precision as x -> 0 (it behaves like x/(n-2), or
!> x ln(1/x) for n = 2). `expint_divdiff(n, a, tau)` = (E_n(a) - E_n(a + tau))/tau, exact
!> limit E_{n-1}(a) as tau -> 0 (n >= 3): a direct difference for tau >= 1e-4; below, the
!> difference of expint_d (free of the constant 1/(n-1)) when a <= 10 tau, else 8-point
!> Gauss-Legendre quadrature of Int_0^1 E_{n-1}(a + tau s) ds, whose integrand is analytic
!> over a neighbourhood 10 times larger than the interval (error far below 1e-15).
module kumo_expint
  use kumo_kinds, only: wp
  use kumo_math, only: gauss_legendre01
  implicit none
  private
  public :: expint_e, expint_d, expint_divdiff

  real(wp), parameter :: EULER_GAMMA = 0.57721566490153286060651209008240243_wp

contains

  !> E_n(x), n >= 1, x >= 0 (E_1(0) = huge()).
  elemental real(wp) function expint_e(n, x) result(e)
    integer, intent(in) :: n
    real(wp), intent(in) :: x
    if (x <= 0.0_wp) then
      if (n == 1) then
        e = huge(1.0_wp)
      else
        e = 1.0_wp/(n - 1)
      end if
    else if (x <= 1.0_wp) then
      if (n == 1) then
        e = -EULER_GAMMA - log(x) - series_tail(1, x)
      else
        e = 1.0_wp/(n - 1) - series_d(n, x)
      end if
    else
      e = continued_fraction(n, x)
    end if
  end function expint_e

  !> 1/(n-1) - E_n(x) for n >= 2, x >= 0, to full relative precision also for small x.
  elemental real(wp) function expint_d(n, x) result(d)
    integer, intent(in) :: n
    real(wp), intent(in) :: x
    if (x <= 0.0_wp) then
      d = 0.0_wp
    else if (x <= 1.0_wp) then
      d = series_d(n, x)
    else
      d = 1.0_wp/(n - 1) - continued_fraction(n, x)
    end if
  end function expint_d

  !> (E_n(a) - E_n(a + tau))/tau for n >= 3, a >= 0, tau >= 0 (E_{n-1}(a) at tau = 0).
  elemental real(wp) function expint_divdiff(n, a, tau) result(q)
    integer, intent(in) :: n
    real(wp), intent(in) :: a, tau
    integer, parameter :: NG = 8
    real(wp) :: xg(NG), wg(NG)
    integer :: i
    if (tau >= 1.0e-4_wp) then
      if (a <= 0.0_wp) then
        q = expint_d(n, tau)/tau
      else
        q = (expint_e(n, a) - expint_e(n, a + tau))/tau
      end if
    else if (tau > 0.0_wp .and. a <= 10.0_wp*tau) then
      ! Near the logarithmic singularity of E_{n-1} at 0: difference of the constant-free series,
      ! each term accurate relative to a + tau <= 11 tau.
      q = (expint_d(n, a + tau) - expint_d(n, a))/tau
    else if (tau > 0.0_wp) then
      call gauss_legendre01(NG, xg, wg)
      q = 0.0_wp
      do i = 1, NG
        q = q + wg(i)*expint_e(n - 1, a + tau*xg(i))
      end do
    else
      q = expint_e(n - 1, a)
    end if
  end function expint_divdiff

  !> The power series of 1/(n-1) - E_n(x), n >= 2, 0 < x <= 1: the k = 0 term removed.
  elemental real(wp) function series_d(n, x) result(d)
    integer, intent(in) :: n
    real(wp), intent(in) :: x
    real(wp) :: psi, fact
    integer :: m
    psi = -EULER_GAMMA
    fact = 1.0_wp
    do m = 1, n - 1
      psi = psi + 1.0_wp/m
      fact = fact*m
    end do
    ! E_n = (-x)^(n-1)/(n-1)! (psi - ln x) + 1/(n-1) - series_tail(n, x)
    d = series_tail(n, x) - (-x)**(n - 1)/fact*(psi - log(x))
  end function series_d

  !> sum_{k>=1, k/=n-1} (-x)^k/(k! (k-n+1)), 0 < x <= 1.
  elemental real(wp) function series_tail(n, x) result(s)
    integer, intent(in) :: n
    real(wp), intent(in) :: x
    real(wp) :: p, term
    integer :: k
    s = 0.0_wp
    p = 1.0_wp
    do k = 1, 60
      p = -p*x/k          ! (-x)^k/k!
      if (k == n - 1) cycle
      term = p/(k - n + 1)
      s = s + term
      if (abs(term) <= 1.0e-17_wp*abs(s)) exit
    end do
  end function series_tail

  !> E_n(x) for x > 1 from the continued fraction (modified Lentz).
  elemental real(wp) function continued_fraction(n, x) result(e)
    integer, intent(in) :: n
    real(wp), intent(in) :: x
    real(wp), parameter :: TINY_CF = 1.0e-300_wp
    real(wp) :: b, c, d, h, an, del
    integer :: i
    e = 0.0_wp
    if (x > 740.0_wp) return
    b = x + n
    c = 1.0_wp/TINY_CF
    d = 1.0_wp/b
    h = d
    do i = 1, 500
      an = -real(i, wp)*real(n - 1 + i, wp)
      b = b + 2.0_wp
      d = 1.0_wp/(an*d + b)
      c = b + an/c
      del = c*d
      h = h*del
      if (abs(del - 1.0_wp) < 1.0e-16_wp) exit
    end do
    e = h*exp(-x)
  end function continued_fraction

end module kumo_expint
