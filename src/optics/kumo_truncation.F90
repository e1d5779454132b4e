! SPDX-License-Identifier: BSD-3-Clause
!> Truncation of forward peaks (MCARaTS delta-flat construction, by truncation level).
!>
!> For a truncation angle Theta_t, u_t = cos Theta_t and w_t = 1 - u_t, the part of P inside the
!> forward cone mu > u_t is replaced by a delta peak 2 f delta(1 - mu) plus a constant P_flat
!> that together keep the cone's zeroth and first moments (seed digest section 19.3):
!>
!>     s0 = (1/2) Int_{u_t}^{1} P dmu,   s1 = (1/2) Int_{u_t}^{1} P mu dmu,
!>     P_flat = 4 (s0 - s1)/w_t^2,       f = [2 s1 - (2 - w_t) s0]/w_t,
!>
!> P_trunc = P for mu <= u_t and P_flat for mu > u_t, (1/2) Int P_trunc dmu = 1 - f, and
!> g = f + (1/2) Int P_trunc mu dmu. Photons scatter with the normalised P^ = P_trunc/(1 - f)
!> (the delta part is folded into scaled extinction by the caller). The integrals are formed
!> from s0 and d1 = s0 - s1 = (1/2) Int_{u_t}^{1} P (1 - mu) dmu, which has no cancellation:
!> P_flat = 4 d1/w_t^2 and f = s0 - 2 d1/w_t.
!>
!> Levels: level 1 is not truncated; with n_levels >= 2, level l truncates at
!> Theta_t = theta_max_deg (l - 1)/(n_levels - 1). A phase function is left untruncated at a
!> level (f = 0, u_t = 1, body = 1, p_flat = 0) when its asymmetry parameter g <= 0, when
!> f <= 0 or f is not finite (f = 0 would only replace P on the cone by a flat part without
!> removing anything), or when theta_max_deg = 0 or n_levels = 1.
!>
!> Integrals: Henyey-Greenstein in closed form (with v = 1 - mu, a = 1 - g, d = a^2 + 2 g w_t):
!> s0 = (1 + g) w_t/(sqrt(d) (sqrt(d) + a)), d1 = (1 - g^2) w_t^2/((sqrt(d) + a)^2 sqrt(d)),
!> f = 2 g (1 + g) w_t^2/(sqrt(d) (sqrt(d) + a)^3), all sums of positive terms. Other kinds by
!> 5-point Gauss-Legendre quadrature of `phase_eval` in Theta on sub-intervals of at most
!> 0.01 deg; for tables the sub-intervals never straddle an input angle, so each one sees a
!> smooth piece of the interpolant, as in `phase_from_table` (a forward peak such as the
!> Deirmendjian C.1 cloud, P(0) ~ 1700, is resolved).
!>
!> Sampling reuses the original inverse CDF: the kept body mu <= u_t has probability
!> body = F(u_t) = 1 - s0 under the original P, so with x = u (1 - f) the body is sampled as
!> phase_sample_mu(ph, x) for x < body and the cone uniformly in mu for x >= body. For tables
!> `phase_sample_mu` interpolates linearly in an inverse-CDF table on n_inv points, so
!> phase_sample_mu(ph, body) equals u_t only to the interpolation error of that table:
!> (1/n_inv)^2/8 max|d2mu/dF2| = (1/n_inv)^2/2 max|P'(mu)|/P^3 in mu near u_t, i.e.
!> (1/n_inv)^2/4 |P'|/P^2 in probability. For Henyey-Greenstein-like tables |P'|/P^2 <= 3g/(1 - g),
!> so with 20,000 points and g <= 0.97 the body and the sampler's CDF disagree by < 6e-8 in
!> probability (up to ~2e-7 in mu at Theta_t = 40 deg, less for smaller angles); the unit test
!> checks 1e-7 in probability. The body branch clamps its result to mu <= u_t so that the body
!> never leaks into the cone.
module kumo_truncation
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
  use kumo_kinds, only: wp
  use kumo_math, only: GL_X => GL5_X, GL_W => GL5_W
  use kumo_constants, only: PI, DEG2RAD
  use kumo_error, only: error_t, set_error, str
  use kumo_phase, only: phase_t, phase_sample_mu, phase_eval, PHASE_HG, PHASE_TABLE
  implicit none
  private
  public :: truncation_t, truncation_init, trunc_sample_mu, trunc_eval

  !> Largest quadrature sub-interval of the cone integrals [deg].
  real(wp), parameter :: SUB_STEP_DEG = 0.01_wp
  !> Step of the scan for mu_peak of analytic kinds [deg] (tables scan their own angles).
  real(wp), parameter :: PEAK_SCAN_DEG = 0.01_wp
  !> Value of mu_peak when P(1) < pf_peak (no scattering counts as "into the peak").
  real(wp), parameter :: NO_PEAK = 2.0_wp


  !> Delta-flat truncation of a set of phase functions at every truncation level. Arrays are
  !> indexed (level, phase); untruncated entries hold f = 0, u_t = 1, body = 1, p_flat = 0.
  type :: truncation_t
    integer :: n_levels = 1                !! number of truncation levels (level 1: none)
    integer :: n_phases = 0                !! number of phase functions
    real(wp) :: theta_max_deg = 0.0_wp     !! truncation angle of the last level [deg]
    real(wp) :: pf_peak = 30.0_wp          !! P above which a scattering goes "into the peak"
    real(wp), allocatable :: f(:, :)       !! (n_levels, n_phases) delta fraction
    real(wp), allocatable :: u_t(:, :)     !! cos Theta_t (1 where not truncated)
    !> F(u_t) = 1 - s0: probability of the kept body mu <= u_t under the original P
    real(wp), allocatable :: body(:, :)
    real(wp), allocatable :: p_flat(:, :)  !! P_flat, the value of P_trunc on the cone
    !> (n_phases): a scattering into mu > mu_peak is "into the peak", i.e. P(mu) >= pf_peak
    !> on (mu_peak, 1]; 2 if P(1) < pf_peak, -1 if P >= pf_peak everywhere
    real(wp), allocatable :: mu_peak(:)
  end type truncation_t

contains

  !> Set up the truncation of every phase function at every level.
  subroutine truncation_init(tr, phases, theta_max_deg, n_levels, pf_peak, error)
    type(truncation_t), intent(out) :: tr   !! the truncation tables
    type(phase_t), intent(in) :: phases(:)  !! phase functions, indexed by phase number
    real(wp), intent(in) :: theta_max_deg   !! truncation angle of the last level, [0, 90) [deg]
    !> P value (normalisation (1/2) Int P dmu = 1) above which mu counts as "into the peak", > 0
    real(wp), intent(in) :: pf_peak
    integer, intent(in) :: n_levels         !! number of levels (>= 1; level 1 not truncated)
    type(error_t), allocatable, intent(out) :: error  !! set if an argument is out of range
    character(len=*), parameter :: CTX = 'truncation_init: '
    real(wp) :: theta_prev, theta_t, u_t, w_t, s0, d1, f
    integer :: iph, lev, nph
    logical :: bad

    if (n_levels < 1) then
      call set_error(error, CTX//'n_levels = '//str(n_levels)//' must be >= 1')
      return
    end if
    bad = ieee_is_nan(theta_max_deg)   ! tested first: an ordered comparison with NaN may trap
    if (.not. bad) bad = theta_max_deg < 0.0_wp .or. theta_max_deg >= 90.0_wp
    if (bad) then
      call set_error(error, CTX//'theta_max_deg = '//str(theta_max_deg)// &
                     ' must lie in [0, 90)')
      return
    end if
    bad = .not. ieee_is_finite(pf_peak)
    if (.not. bad) bad = pf_peak <= 0.0_wp
    if (bad) then
      call set_error(error, CTX//'pf_peak = '//str(pf_peak)//' must be finite and > 0')
      return
    end if

    nph = size(phases)
    tr%n_levels = n_levels
    tr%n_phases = nph
    tr%theta_max_deg = theta_max_deg
    tr%pf_peak = pf_peak
    allocate (tr%f(n_levels, nph), tr%u_t(n_levels, nph), tr%body(n_levels, nph), &
              tr%p_flat(n_levels, nph), tr%mu_peak(nph))
    tr%f = 0.0_wp
    tr%u_t = 1.0_wp
    tr%body = 1.0_wp
    tr%p_flat = 0.0_wp

    do iph = 1, nph
      tr%mu_peak(iph) = peak_mu(phases(iph), pf_peak)
      if (n_levels < 2 .or. theta_max_deg <= 0.0_wp) cycle
      if (.not. (phases(iph)%g > 0.0_wp)) cycle
      ! The cone integrals grow with the level: accumulate them from the previous angle.
      s0 = 0.0_wp
      d1 = 0.0_wp
      theta_prev = 0.0_wp
      do lev = 2, n_levels
        theta_t = theta_max_deg*DEG2RAD*real(lev - 1, wp)/real(n_levels - 1, wp)
        u_t = cos(theta_t)
        w_t = 1.0_wp - u_t                 ! exact (Sterbenz) for u_t >= 1/2
        if (.not. (w_t > 0.0_wp)) cycle    ! Theta_t below rounding: nothing to truncate
        if (phases(iph)%kind == PHASE_HG) then
          call hg_cone(phases(iph)%g, w_t, s0, d1, f)
        else
          call cone_moments(phases(iph), theta_prev, acos(u_t), s0, d1)
          theta_prev = acos(u_t)
          f = s0 - 2.0_wp*d1/w_t
        end if
        if (.not. ieee_is_finite(f)) cycle
        if (f <= 0.0_wp .or. f >= 1.0_wp) cycle
        tr%f(lev, iph) = f
        tr%u_t(lev, iph) = u_t
        tr%body(lev, iph) = 1.0_wp - s0
        tr%p_flat(lev, iph) = 4.0_wp*d1/(w_t*w_t)
      end do
    end do
  end subroutine truncation_init

  !> Sample mu from the normalised truncated phase function P^ of phase `iph` at level `lev`
  !> with one deviate: the body from the original inverse CDF, the cone uniformly in mu.
  !> mu is non-decreasing in u, as for `phase_sample_mu`.
  pure function trunc_sample_mu(tr, ph, iph, lev, u) result(mu)
    type(truncation_t), intent(in) :: tr  !! truncation tables
    type(phase_t), intent(in) :: ph       !! the phase function number iph
    integer, intent(in) :: iph            !! phase number
    integer, intent(in) :: lev            !! truncation level
    real(wp), intent(in) :: u             !! uniform deviate in [0, 1)
    real(wp) :: mu                        !! cosine of the scattering angle
    real(wp) :: x, body, u_t, den

    body = tr%body(lev, iph)
    u_t = tr%u_t(lev, iph)
    x = u*(1.0_wp - tr%f(lev, iph))
    if (x < body) then
      mu = min(phase_sample_mu(ph, x), u_t)
    else
      den = 1.0_wp - tr%f(lev, iph) - body   ! probability of the flat part, 2 d1/w_t
      if (den > 0.0_wp) then
        mu = min(1.0_wp, u_t + (1.0_wp - u_t)*min(1.0_wp, (x - body)/den))
      else
        mu = u_t                             ! no flat part: u -> 1 ends the body
      end if
    end if
  end function trunc_sample_mu

  !> Truncated phase function P_trunc = (1 - f) P^: P for mu <= u_t, P_flat on the cone.
  pure function trunc_eval(tr, ph, iph, lev, mu) result(p)
    type(truncation_t), intent(in) :: tr  !! truncation tables
    type(phase_t), intent(in) :: ph       !! the phase function number iph
    integer, intent(in) :: iph            !! phase number
    integer, intent(in) :: lev            !! truncation level
    real(wp), intent(in) :: mu            !! cosine of the scattering angle
    real(wp) :: p                         !! P_trunc(mu), (1/2) Int P_trunc dmu = 1 - f
    if (mu > tr%u_t(lev, iph)) then
      p = tr%p_flat(lev, iph)
    else
      p = phase_eval(ph, mu)
    end if
  end function trunc_eval

  ! ------------------------------------------------------------------------------------------
  ! Private helpers
  ! ------------------------------------------------------------------------------------------

  !> Cone integrals of Henyey-Greenstein in closed form (see the module header).
  pure subroutine hg_cone(g, w_t, s0, d1, f)
    real(wp), intent(in) :: g     !! asymmetry parameter, 0 < g < 1
    real(wp), intent(in) :: w_t   !! 1 - u_t
    real(wp), intent(out) :: s0   !! (1/2) Int_{u_t}^1 P dmu
    real(wp), intent(out) :: d1   !! (1/2) Int_{u_t}^1 P (1 - mu) dmu
    real(wp), intent(out) :: f    !! delta fraction s0 - 2 d1/w_t
    real(wp) :: a, r, b
    a = 1.0_wp - g
    r = sqrt(a*a + 2.0_wp*g*w_t)
    b = r + a
    s0 = (1.0_wp + g)*w_t/(r*b)
    d1 = (1.0_wp - g)*(1.0_wp + g)*w_t*w_t/(b*b*r)
    f = 2.0_wp*g*(1.0_wp + g)*w_t*w_t/(r*b*b*b)
  end subroutine hg_cone

  !> Add (1/2) Int P sin(Theta) dTheta to s0 and (1/2) Int P (1 - cos Theta) sin(Theta) dTheta
  !> to d1 over [t_a, t_b] [rad]. Tables are split at their input angles.
  pure subroutine cone_moments(ph, t_a, t_b, s0, d1)
    type(phase_t), intent(in) :: ph
    real(wp), intent(in) :: t_a, t_b    !! limits [rad], t_a <= t_b
    real(wp), intent(inout) :: s0, d1
    real(wp) :: lo, hi
    integer :: i
    if (ph%kind == PHASE_TABLE) then
      do i = size(ph%theta_tab) - 1, 1, -1   ! theta_tab descends: start at the forward end
        lo = max(t_a, ph%theta_tab(i + 1))
        hi = min(t_b, ph%theta_tab(i))
        if (ph%theta_tab(i + 1) >= t_b) exit
        if (hi > lo) call gl_moments(ph, lo, hi, s0, d1)
      end do
    else
      call gl_moments(ph, t_a, t_b, s0, d1)
    end if
  end subroutine cone_moments

  !> Composite 5-point Gauss-Legendre on [lo, hi] in sub-intervals of at most SUB_STEP_DEG.
  pure subroutine gl_moments(ph, lo, hi, s0, d1)
    type(phase_t), intent(in) :: ph
    real(wp), intent(in) :: lo, hi      !! limits [rad], lo < hi
    real(wp), intent(inout) :: s0, d1
    real(wp) :: a, b, half, mid, t, ps, h0, h1
    integer :: nsub, k, q
    nsub = max(1, ceiling((hi - lo)/(SUB_STEP_DEG*DEG2RAD)))
    do k = 1, nsub
      a = lo + (hi - lo)*real(k - 1, wp)/real(nsub, wp)
      b = lo + (hi - lo)*real(k, wp)/real(nsub, wp)
      if (k == nsub) b = hi
      half = 0.5_wp*(b - a)
      mid = 0.5_wp*(b + a)
      h0 = 0.0_wp
      h1 = 0.0_wp
      do q = 1, size(GL_X)
        t = mid + half*GL_X(q)
        ps = GL_W(q)*phase_eval(ph, cos(t))*sin(t)
        h0 = h0 + ps
        h1 = h1 + ps*2.0_wp*sin(0.5_wp*t)**2     ! 1 - cos t without cancellation
      end do
      s0 = s0 + 0.5_wp*half*h0
      d1 = d1 + 0.5_wp*half*h1
    end do
  end subroutine gl_moments

  !> Smallest mu such that P >= pf_peak on (mu, 1]; NO_PEAK if P(1) < pf_peak, -1 if
  !> P >= pf_peak everywhere. The angle is scanned from 0 (on the input angles for tables,
  !> between which the interpolant is monotone; on a PEAK_SCAN_DEG grid otherwise) up to the
  !> first node with P < pf_peak, then the crossing is located by bisection in angle.
  pure function peak_mu(ph, pf_peak) result(mu_peak)
    type(phase_t), intent(in) :: ph
    real(wp), intent(in) :: pf_peak
    real(wp) :: mu_peak
    integer, parameter :: N_BISECT = 200
    real(wp) :: t_in, t_out, t_mid
    integer :: i, n, it

    if (phase_eval(ph, 1.0_wp) < pf_peak) then
      mu_peak = NO_PEAK
      return
    end if
    t_in = 0.0_wp        ! P >= pf_peak on [0, t_in]
    t_out = -1.0_wp      ! first node with P < pf_peak (none found yet)
    if (ph%kind == PHASE_TABLE) then
      n = size(ph%theta_tab)
      do i = n - 1, 1, -1
        if (ph%p_tab(i) < pf_peak) then
          t_out = ph%theta_tab(i)
          exit
        end if
        t_in = ph%theta_tab(i)
      end do
    else
      n = ceiling(180.0_wp/PEAK_SCAN_DEG)
      do i = 1, n
        t_mid = min(PI, real(i, wp)*PEAK_SCAN_DEG*DEG2RAD)
        if (phase_eval(ph, cos(t_mid)) < pf_peak) then
          t_out = t_mid
          exit
        end if
        t_in = t_mid
      end do
    end if
    if (t_out < 0.0_wp) then
      mu_peak = -1.0_wp
      return
    end if
    do it = 1, N_BISECT
      t_mid = 0.5_wp*(t_in + t_out)
      if (t_mid <= t_in .or. t_mid >= t_out) exit
      if (phase_eval(ph, cos(t_mid)) >= pf_peak) then
        t_in = t_mid
      else
        t_out = t_mid
      end if
    end do
    mu_peak = cos(t_in)
  end function peak_mu

end module kumo_truncation
