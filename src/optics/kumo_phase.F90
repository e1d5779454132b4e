! SPDX-License-Identifier: BSD-3-Clause
!> Phase functions: evaluation and sampling of the scattering-angle cosine.
!>
!> Conventions used throughout:
!>
!> * mu is the cosine of the scattering angle Theta (mu = 1: forward, mu = -1: backward).
!> * Normalisation (1/4pi) Int P dOmega = (1/2) Int_{-1}^{1} P dmu = 1, so the isotropic phase
!>   function is P = 1, Rayleigh P = 3/4 (1 + mu^2) (with a depolarisation ratio rho > 0,
!>   Chandrasekhar's form, see kumo_rayleigh) and Henyey-Greenstein
!>   P = (1 - g^2)/(1 + g^2 - 2 g mu)^(3/2).
!> * Every sampler is the inverse of the cumulative distribution accumulated from the backward
!>   direction, F(mu) = (1/2) Int_{-1}^{mu} P dmu': the deviate u = 0 gives mu = -1 and u -> 1
!>   gives mu -> 1, and mu is non-decreasing in u. Samplers take the deviate as an argument.
!>
!> Tabulated phase functions are converted once, at setup, into an inverse-CDF table (as the
!> I3RC model's `inversePhaseFunctions` and MCARaTS do, there on an equally spaced deviate
!> grid; here with steps of their own in each of 64 pieces of equal probability, as long as
!> interpolation allows, so that the tables of a scene stay in the cache), so sampling is one
!> table interpolation per scattering event. Between the angles of the input table, P is
!> interpolated linearly in the scattering angle of log P where both neighbouring values are
!> positive (exact for an exponential decay of the forward peak; keeps P > 0 between positive
!> nodes) and linearly in angle otherwise. The CDF of that interpolant is integrated in Theta,
!> not in mu, so a forward peak such as the Deirmendjian C.1 cloud (P(0) ~ 1700) is resolved:
!> on a log-linear interval, P sin(Theta) and P sin(Theta) cos(Theta) are an exponential times
!> a sine, whose integrals have closed forms (see `loglin_piece`); the rarer linear intervals,
!> next to zero values, are integrated with 5-point Gauss-Legendre quadrature on pieces of at
!> most LIN_STEP_DEG. The CDF is thus exact (to rounding) at the input angles, and each point
!> of the inverse table is solved to rounding inside the one interval that brackets it.
!> `phase_eval` uses the same interpolant, so sampling and evaluation describe the same
!> function.
!>
!> A Legendre series P(mu) = sum_l (2l+1) chi_l P_l(mu), as listed by SHDOM property files and
!> Mie codes, is summed once on a grid of angles (`phase_from_legendre`) and handed to the
!> same table construction.
module kumo_phase
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
  use kumo_kinds, only: wp
  use kumo_math, only: GL_X => GL5_X, GL_W => GL5_W, first_not_below, arccos
  use kumo_constants, only: PI, DEG2RAD
  use kumo_error, only: error_t, set_error, add_context, str, to_lower, join
  use kumo_rayleigh, only: DEPOL_MAX, rayleigh_depol_eval, rayleigh_depol_sample_mu
  implicit none
  private
  public :: PHASE_ISOTROPIC, PHASE_RAYLEIGH, PHASE_HG, PHASE_TABLE, PHASE_NAMES
  public :: PHASE_N_INV_DEFAULT
  public :: phase_t, phase_kind_from_name
  public :: new_phase_isotropic, new_phase_rayleigh, new_phase_rayleigh_depol, new_phase_hg
  public :: phase_from_table, phase_from_legendre
  public :: phase_sample_mu, phase_eval, phase_inv_xi
  public :: isotropic_sample_mu, rayleigh_sample_mu, hg_sample_mu, rayleigh_eval, hg_eval

  integer, parameter :: PHASE_ISOTROPIC = 1  !! P = 1
  integer, parameter :: PHASE_RAYLEIGH = 2   !! P = 3/4 (1 + mu^2), or depolarised (rho > 0)
  integer, parameter :: PHASE_HG = 3         !! Henyey-Greenstein with asymmetry parameter g
  integer, parameter :: PHASE_TABLE = 4      !! tabulated P(Theta), sampled from an inverse CDF

  !> Names of the kinds, indexed by kind code (namelist strings, lower case).
  character(len=9), parameter :: PHASE_NAMES(4) = [character(len=9) :: &
                                                   'isotropic', 'rayleigh', 'hg', 'table']

  !> Default resolution of the inverse-CDF table: its finest step in probability is at most
  !> 1/(n_inv - 1) (the MCARaTS default is 20,000 uniform points).
  integer, parameter :: PHASE_N_INV_DEFAULT = 20000
  !> Pieces of equal probability of the inverse-CDF table; each has its own step.
  integer, parameter :: INV_PIECES = 64
  !> Interpolation between the kept nodes of the inverse CDF stays within this much
  !> probability of the finest grid's nodes (sampling a table then moves no probability by more
  !> than INV_TOL plus the finest grid's own interpolation error).
  real(wp), parameter :: INV_TOL = 1.0e-7_wp

  !> Input angles 0 and 180 deg may be off by this much [deg].
  real(wp), parameter :: ANGLE_TOL_DEG = 1.0e-6_wp
  !> Bins of the scattering angle that `phase_eval` starts its search of a table from: two per
  !> table angle, between 256 and 8192 (32 KiB) per table.
  integer, parameter :: GUIDE_PER_NODE = 2, GUIDE_MIN = 256, GUIDE_MAX = 8192
  !> Largest quadrature piece of a linearly interpolated table interval [deg]. On a piece of
  !> width h the integrand (a + c Theta) sin(Theta) cos(Theta)^m has a 10th derivative of at
  !> most ~ 2^10 (|a + c Theta| + 10 |c|), so the 5-point Gauss-Legendre remainder,
  !> h^11 (5!)^4/(11 (10!)^3) f^(10) = 3.9e-13 h^11 f^(10), is below 1e-26 of the largest value
  !> times the piece for h = 1 deg (0.0175 rad): exact to rounding.
  real(wp), parameter :: LIN_STEP_DEG = 1.0_wp
  !> `loglin_piece` sums the power series of (e^w - 1)/w for |w| <= this, w = (beta + i omega) s;
  !> beyond it the closed form (e^w - 1)/w loses at most a factor ~4 to cancellation.
  real(wp), parameter :: SERIES_W_MAX = 0.5_wp
  !> Terms of that series (w^0 ... w^(K-1)) for |w|^2 <= SERIES_W2(m): K = SERIES_TERMS(m), the
  !> fewest for which the first term left out, |w|^K/(K+1)!, is below 5e-17 (1/2 ulp of the sum,
  !> which is >= 0.78 for |w| <= 1/2): 0.5^15/16! = 1.5e-18, 0.25^12/13! = 9.6e-18,
  !> 0.125^10/11! = 2.3e-17, 0.0625^9/10! = 4.0e-18, (1/32)^8/9! = 2.5e-18.
  real(wp), parameter :: SERIES_W2(5) = [SERIES_W_MAX**2, 0.25_wp**2, 0.125_wp**2, &
                                         0.0625_wp**2, 0.03125_wp**2]
  integer, parameter :: SERIES_TERMS(5) = [15, 12, 10, 9, 8]

  ! Angle grid of `phase_from_legendre` for a series of highest degree L. A polynomial of degree
  ! L in mu = cos(Theta) is a trigonometric polynomial of degree L in Theta: its narrowest
  ! features (the forward diffraction peak, the glory) are ~ pi/L wide, i.e. w = 180/L deg.
  ! Steps of w/16 within 24 w of 0 and 180 deg and w/4 in between, at most 0.25 deg, keep the
  ! interpolant of `phase_from_table` within 5e-4 of the series (relative, where P > 0.01) for
  ! the Legendre moments of the C.1 cloud (300 terms), of an SHDOM property file of cloud
  ! droplets at 2.13 um (nleg 19-490) and of Henyey-Greenstein g = 0.85, 0.95, 0.99 (400, 1000,
  ! 3000 terms); the mean cosine is kept to 3e-6 and (1/2) Int |P_table - P| dmu < 3e-5.
  ! That is 4 L + 577 points for L >= 180 and 721 points (a 0.25 deg grid) for L <= 45.
  !> Largest step of the grid [deg].
  real(wp), parameter :: LEG_STEP_MAX_DEG = 0.25_wp
  !> Steps per 180/L deg near 0 and 180 deg, and in between.
  integer, parameter :: LEG_FINE_PER_WIDTH = 16, LEG_MID_PER_WIDTH = 4
  !> Steps of the fine zone at each end (its width is 384/16 = 24 times 180/L deg).
  integer, parameter :: LEG_ZONE_STEPS = 384
  !> chi(0) must be 1 and every |chi_l| <= 1 within this tolerance.
  real(wp), parameter :: LEG_CHI_TOL = 1.0e-6_wp

  !> A phase function ready for evaluation and sampling. Build it with a constructor
  !> (`new_phase_isotropic`, `new_phase_rayleigh`, `new_phase_rayleigh_depol`, `new_phase_hg`,
  !> `phase_from_table`, `phase_from_legendre`); the tables are allocated for `PHASE_TABLE`
  !> only. (The constructors of the analytic kinds carry a `new_` prefix because Fortran names
  !> are case-insensitive: `phase_hg` would clash with the kind code `PHASE_HG`.)
  type :: phase_t
    integer :: kind = PHASE_ISOTROPIC  !! one of PHASE_ISOTROPIC, _RAYLEIGH, _HG, _TABLE
    real(wp) :: g = 0.0_wp             !! asymmetry parameter <mu> (computed for tables)
    !> Depolarisation ratio rho of PHASE_RAYLEIGH, 0 <= rho < 6/7; 0 is P = 3/4 (1 + mu^2).
    real(wp) :: depol = 0.0_wp
    !> Factor the input table was multiplied by to be normalised (1 for analytic kinds);
    !> 1/norm_factor = (1/2) Int P_input sin(Theta) dTheta of the interpolated input.
    real(wp) :: norm_factor = 1.0_wp
    !> Inverse CDF at its nodes: mu_inv(j) = F^-1(xi_j), F accumulated from mu = -1;
    !> non-decreasing from mu_inv(1) = -1 to the last node's 1 (if P vanishes on an end range
    !> of angles, the inner end of that range). The nodes divide [0, 1] into INV_PIECES pieces
    !> of equal probability; piece p (0-based) has inv_m(p) equal steps in xi, its nodes are
    !> mu_inv(inv_off(p) + 1 .. inv_off(p) + inv_m(p) + 1) (the last one is the first of piece
    !> p + 1), so xi of node inv_off(p) + i + 1 is (p + i/inv_m(p))/INV_PIECES
    !> (`phase_inv_xi`). Each piece has as few steps as keep its interpolation (quadratic
    !> through three nodes) within INV_TOL in probability of the finest grid: see
    !> `phase_from_table`.
    real(wp), allocatable :: mu_inv(:)
    integer, allocatable :: inv_off(:)     !! (0:INV_PIECES-1) nodes before each piece
    real(wp), allocatable :: inv_m(:)      !! (0:INV_PIECES-1) steps of each piece
    real(wp), allocatable :: mu_tab(:)     !! input angles as cosines, ascending (-1 ... 1)
    real(wp), allocatable :: theta_tab(:)  !! the same angles [rad], descending (pi ... 0)
    real(wp), allocatable :: p_tab(:)      !! normalised P at mu_tab
    real(wp), allocatable :: lp_tab(:)     !! log(p_tab) where p_tab > 0 (for interpolation)
    real(wp), allocatable :: inv_dth(:)    !! 1/(theta_tab(i+1) - theta_tab(i)) per interval
    !> Where `phase_eval` starts looking for the interval of an angle: guide(b + 1) is the
    !> interval holding the largest angle of bin b of theta (n_guide equal bins over [0, pi]).
    integer, allocatable :: guide(:)
    real(wp) :: guide_scale = 0.0_wp       !! n_guide/pi: bin of theta = int(theta guide_scale)
  end type phase_t

contains

  ! ------------------------------------------------------------------------------------------
  ! Analytic phase functions
  ! ------------------------------------------------------------------------------------------

  !> Isotropic sample: mu = 2u - 1 (uniform in [-1, 1]).
  elemental function isotropic_sample_mu(u) result(mu)
    real(wp), intent(in) :: u  !! uniform deviate in [0, 1]
    real(wp) :: mu             !! cosine of the scattering angle
    mu = 2.0_wp*u - 1.0_wp
  end function isotropic_sample_mu

  !> Rayleigh phase function P = 3/4 (1 + mu^2).
  elemental function rayleigh_eval(mu) result(p)
    real(wp), intent(in) :: mu  !! cosine of the scattering angle
    real(wp) :: p               !! phase function value
    p = 0.75_wp*(1.0_wp + mu*mu)
  end function rayleigh_eval

  !> Exact Rayleigh sample: the real root of mu^3 + 3 mu + 4 - 8u = 0, i.e. F(mu) = u with
  !> F(mu) = (mu^3 + 3 mu + 4)/8 (Cardano: mu = X - 1/X, X^3 = q + sqrt(q^2 + 1), q = 4u - 2).
  !>
  !> The root is odd in q, so it is computed for |q| and given the sign of q; with
  !> Y^3 = 1 + w, w = |q| + q^2/(1 + sqrt(1 + q^2)) and Y - 1/Y = (Y + 1) w / (Y (Y^2 + Y + 1)),
  !> every step adds positive terms: no cancellation for q < 0 or near mu = 0.
  elemental function rayleigh_sample_mu(u) result(mu)
    real(wp), intent(in) :: u  !! uniform deviate in [0, 1]
    real(wp) :: mu             !! cosine of the scattering angle
    real(wp) :: q, w, y
    q = 4.0_wp*u - 2.0_wp
    w = abs(q) + q*q/(1.0_wp + sqrt(1.0_wp + q*q))
    y = (1.0_wp + w)**(1.0_wp/3.0_wp)
    mu = sign((y + 1.0_wp)*w/(y*(y*y + y + 1.0_wp)), q)
    mu = min(1.0_wp, max(-1.0_wp, mu))
  end function rayleigh_sample_mu

  !> Henyey-Greenstein phase function P = (1 - g^2)/(1 + g^2 - 2 g mu)^(3/2), with the
  !> denominator written as a sum of non-negative terms ((1 - g)^2 + 2g (1 - mu) for g >= 0,
  !> (1 + g)^2 - 2g (1 + mu) for g < 0) so the forward peak of g -> 1 keeps full precision.
  elemental function hg_eval(g, mu) result(p)
    real(wp), intent(in) :: g   !! asymmetry parameter, |g| < 1
    real(wp), intent(in) :: mu  !! cosine of the scattering angle
    real(wp) :: p               !! phase function value
    real(wp) :: d
    if (g >= 0.0_wp) then
      d = (1.0_wp - g)**2 + 2.0_wp*g*(1.0_wp - mu)
    else
      d = (1.0_wp + g)**2 - 2.0_wp*g*(1.0_wp + mu)
    end if
    p = (1.0_wp - g)*(1.0_wp + g)/(d*sqrt(d))
  end function hg_eval

  !> Henyey-Greenstein sample by the inverse CDF. The textbook inverse
  !> mu = [1 + g^2 - ((1 - g^2)/(1 - g + 2 g u))^2]/(2g) loses digits near mu = 1 for g -> 1
  !> and is singular at g = 0; it is rewritten (exact algebra, with v = 1 - u and
  !> d = (1 - g) v + (1 + g) u = 1 - g + 2 g u) as
  !>
  !>     1 - mu = 2 v (1 - g)^2 (v + (1 + g) u) / d^2
  !>     1 + mu = 2 u (1 + g)^2 (u + (1 - g) v) / d^2
  !>
  !> Both are products of non-negative factors, accurate to a few rounding errors for every
  !> |g| < 1 (g = 0 gives mu = 2u - 1 without a special case), and the smaller one is used.
  elemental function hg_sample_mu(g, u) result(mu)
    real(wp), intent(in) :: g  !! asymmetry parameter, |g| < 1
    real(wp), intent(in) :: u  !! uniform deviate in [0, 1]
    real(wp) :: mu             !! cosine of the scattering angle
    real(wp) :: v, gm, gp, d2, one_minus_mu
    v = 1.0_wp - u
    gm = 1.0_wp - g
    gp = 1.0_wp + g
    d2 = (gm*v + gp*u)**2
    one_minus_mu = 2.0_wp*v*gm*gm*(v + gp*u)/d2
    if (one_minus_mu <= 1.0_wp) then
      mu = 1.0_wp - one_minus_mu
    else
      mu = 2.0_wp*u*gp*gp*(u + gm*v)/d2 - 1.0_wp
    end if
    mu = min(1.0_wp, max(-1.0_wp, mu))
  end function hg_sample_mu

  ! ------------------------------------------------------------------------------------------
  ! phase_t: construction, evaluation, sampling
  ! ------------------------------------------------------------------------------------------

  !> Kind code of a phase-function name (case-insensitive, surrounding blanks ignored).
  subroutine phase_kind_from_name(name, kind, error)
    character(len=*), intent(in) :: name            !! e.g. 'hg' or 'Rayleigh'
    integer, intent(out) :: kind                    !! kind code (0 on error)
    type(error_t), allocatable, intent(out) :: error  !! set if the name is unknown
    character(len=:), allocatable :: key
    integer :: i

    key = to_lower(trim(adjustl(name)))
    do i = 1, size(PHASE_NAMES)
      if (key == trim(PHASE_NAMES(i))) then
        kind = i
        return
      end if
    end do
    kind = 0
    call set_error(error, "phase function '"//trim(adjustl(name))//"' is unknown (allowed: "// &
                   join(PHASE_NAMES)//')')
  end subroutine phase_kind_from_name

  !> Isotropic phase function.
  pure function new_phase_isotropic() result(ph)
    type(phase_t) :: ph  !! P = 1, g = 0
    ph%kind = PHASE_ISOTROPIC
  end function new_phase_isotropic

  !> Rayleigh phase function (no depolarisation correction).
  pure function new_phase_rayleigh() result(ph)
    type(phase_t) :: ph  !! P = 3/4 (1 + mu^2), g = 0
    ph%kind = PHASE_RAYLEIGH
  end function new_phase_rayleigh

  !> Rayleigh phase function with depolarisation ratio rho (Chandrasekhar 1950, Radiative
  !> Transfer, chapter I; evaluated and sampled exactly by kumo_rayleigh's
  !> `rayleigh_depol_eval` and `rayleigh_depol_sample_mu`):
  !>
  !>     P(mu) = 3/(4 (1 + 2 gamma)) [(1 + 3 gamma) + (1 - gamma) mu^2],  gamma = rho/(2 - rho).
  !>
  !> rho = 0 gives the same phase_t as `new_phase_rayleigh()`, which uses the plain formulas.
  !> Dry air has rho ~ 0.028 at 0.55 um (kumo_rayleigh's `depol_from_king`).
  function new_phase_rayleigh_depol(depol, error) result(ph)
    real(wp), intent(in) :: depol                     !! depolarisation ratio, 0 <= rho < 6/7
    type(error_t), allocatable, intent(out) :: error  !! set if rho is NaN or out of range
    type(phase_t) :: ph  !! the phase function (the default, isotropic, on error), g = 0
    logical :: bad
    bad = ieee_is_nan(depol)   ! tested first: an ordered comparison with NaN may trap
    if (.not. bad) bad = depol < 0.0_wp .or. depol >= DEPOL_MAX
    if (bad) then
      call set_error(error, 'new_phase_rayleigh_depol: depol = '//str(depol)// &
                     ' must satisfy 0 <= depol < 6/7 (depolarisation ratio; the King factor '// &
                     '(6 + 3 depol)/(6 - 7 depol) diverges at 6/7)')
      return
    end if
    ph%kind = PHASE_RAYLEIGH
    ph%depol = depol
  end function new_phase_rayleigh_depol

  !> Henyey-Greenstein phase function.
  function new_phase_hg(g, error) result(ph)
    real(wp), intent(in) :: g                         !! asymmetry parameter, |g| < 1
    type(error_t), allocatable, intent(out) :: error  !! set if |g| >= 1 or g is NaN
    type(phase_t) :: ph  !! the phase function (the default, isotropic, on error)
    if (ieee_is_nan(g)) then   ! tested first: an ordered comparison with NaN may trap
      call set_error(error, 'new_phase_hg: g = '//str(g)//' must satisfy |g| < 1')
      return
    end if
    if (abs(g) >= 1.0_wp) then
      call set_error(error, 'new_phase_hg: g = '//str(g)//' must satisfy |g| < 1')
      return
    end if
    ph%kind = PHASE_HG
    ph%g = g
  end function new_phase_hg

  !> Tabulated phase function P(Theta), normalised and converted to an inverse-CDF table.
  !>
  !> The input need not be normalised: it is multiplied by `norm_factor` so that
  !> (1/2) Int P sin(Theta) dTheta = 1 for the interpolant described in the module header.
  !> The asymmetry parameter g = (1/2) Int P cos(Theta) sin(Theta) dTheta is computed in the
  !> same way (closed form on log-linear intervals, quadrature on linear ones).
  function phase_from_table(angle_deg, value, n_inv, error) result(ph)
    !> scattering angles [deg], strictly increasing, first 0 and last 180 (within 1e-6 deg)
    real(wp), intent(in) :: angle_deg(:)
    real(wp), intent(in) :: value(:)      !! phase function at angle_deg, finite, >= 0, any scale
    !> resolution of the inverse-CDF table: finest step 1/(n_inv - 1) in probability or less
    !> (>= 2, default PHASE_N_INV_DEFAULT)
    integer, intent(in), optional :: n_inv
    type(error_t), allocatable, intent(out) :: error  !! set if the table is invalid
    type(phase_t) :: ph  !! the phase function (the default, isotropic, on error)

    character(len=*), parameter :: CTX = 'phase_from_table: '
    real(wp), allocatable :: th_f(:), cum(:), sin_tab(:), cos_tab(:)
    integer, allocatable :: nsub(:), itab(:)
    logical, allocatable :: loglin(:)
    real(wp) :: total, moment1, part, dpart
    real(wp), allocatable :: mu_f(:)
    logical, allocatable :: have(:)
    integer, allocatable :: msteps(:)
    integer :: fpp, nf, k0
    integer :: n, ninv, nfine, i, j, k, m
    logical :: bad

    ! --- validation -------------------------------------------------------------------------
    n = size(angle_deg)
    if (size(value) /= n) then
      call set_error(error, CTX//'angle_deg and value have different sizes ('// &
                     str(n)//' and '//str(size(value))//')')
      return
    end if
    if (n < 2) then
      call set_error(error, CTX//'the table has '//str(n)//' point(s); at least 2 are needed')
      return
    end if
    ninv = PHASE_N_INV_DEFAULT
    if (present(n_inv)) ninv = n_inv
    if (ninv < 2) then
      call set_error(error, CTX//'n_inv = '//str(ninv)//' must be >= 2')
      return
    end if
    do i = 1, n
      if (.not. ieee_is_finite(angle_deg(i))) then
        call set_error(error, CTX//'angle_deg('//str(i)//') = '//str(angle_deg(i))// &
                       ' is not finite')
        return
      end if
    end do
    if (abs(angle_deg(1)) > ANGLE_TOL_DEG) then
      call set_error(error, CTX//'angle_deg(1) = '//str(angle_deg(1))// &
                     ' must be 0 (within 1e-6 deg)')
      return
    end if
    if (abs(angle_deg(n) - 180.0_wp) > ANGLE_TOL_DEG) then
      call set_error(error, CTX//'angle_deg('//str(n)//') = '//str(angle_deg(n))// &
                     ' must be 180 (within 1e-6 deg)')
      return
    end if
    do i = 2, n
      if (.not. (angle_deg(i) > angle_deg(i - 1))) then
        call set_error(error, CTX//'angle_deg('//str(i)//') = '//str(angle_deg(i))// &
                       ' must be > angle_deg('//str(i - 1)//') = '// &
                       str(angle_deg(i - 1))//' (angles strictly increasing)')
        return
      end if
    end do
    do i = 2, n - 1
      if (angle_deg(i) <= 0.0_wp .or. angle_deg(i) >= 180.0_wp) then
        call set_error(error, CTX//'angle_deg('//str(i)//') = '//str(angle_deg(i))// &
                       ' must lie strictly between 0 and 180')
        return
      end if
    end do
    do i = 1, n
      bad = .not. ieee_is_finite(value(i))   ! tested first: comparing NaN may trap
      if (.not. bad) bad = value(i) < 0.0_wp
      if (bad) then
        call set_error(error, CTX//'value('//str(i)//') = '//str(value(i))// &
                       ' must be finite and >= 0')
        return
      end if
    end do
    if (all(value <= 0.0_wp)) then
      call set_error(error, CTX//'all '//str(n)//' values are 0; the phase function '// &
                     'must have a positive integral')
      return
    end if

    ! --- evaluation table, ascending in mu ---------------------------------------------------
    ph%kind = PHASE_TABLE
    allocate (ph%theta_tab(n), ph%mu_tab(n), ph%p_tab(n))
    ph%theta_tab = angle_deg(n:1:-1)*DEG2RAD
    ph%theta_tab(1) = PI
    ph%theta_tab(n) = 0.0_wp
    ph%mu_tab = cos(ph%theta_tab)
    ph%mu_tab(1) = -1.0_wp
    ph%mu_tab(n) = 1.0_wp
    ph%p_tab = value(n:1:-1)
    ph%lp_tab = log(max(ph%p_tab, tiny(1.0_wp)))
    ph%inv_dth = 1.0_wp/(ph%theta_tab(2:n) - ph%theta_tab(1:n - 1))
    call build_guide(ph)

    ! --- CDF from mu = -1 at the ends of the pieces -------------------------------------------
    ! Piece k runs from th_f(k-1) down to th_f(k) (mu ascending) inside the evaluation-table
    ! interval itab(k), between theta_tab(itab(k)) and theta_tab(itab(k) + 1). A log-linear
    ! interval is one piece, integrated in closed form; a linear one is cut into pieces of at
    ! most LIN_STEP_DEG for the quadrature.
    allocate (loglin(n - 1), nsub(n - 1))
    do i = 1, n - 1
      loglin(i) = ph%p_tab(i) > 0.0_wp .and. ph%p_tab(i + 1) > 0.0_wp
      if (loglin(i)) then
        nsub(i) = 1
      else
        nsub(i) = max(1, ceiling((ph%theta_tab(i) - ph%theta_tab(i + 1))/(LIN_STEP_DEG*DEG2RAD)))
      end if
    end do
    sin_tab = sin(ph%theta_tab)
    cos_tab = cos(ph%theta_tab)
    nfine = sum(nsub)
    allocate (th_f(0:nfine), cum(0:nfine), itab(nfine))
    th_f(0) = PI
    cum(0) = 0.0_wp
    moment1 = 0.0_wp
    k = 0
    do i = 1, n - 1
      if (loglin(i)) then
        k = k + 1
        itab(k) = i
        th_f(k) = ph%theta_tab(i + 1)
        call loglin_piece(ph, i, 1.0_wp, sin_tab(i), cos_tab(i), th_f(k - 1) - th_f(k), part, &
                          dpart)
        cum(k) = cum(k - 1) + part
        ! sin(t) cos(t) = sin(2t)/2
        call loglin_piece(ph, i, 2.0_wp, 2.0_wp*sin_tab(i)*cos_tab(i), &
                          (cos_tab(i) - sin_tab(i))*(cos_tab(i) + sin_tab(i)), &
                          th_f(k - 1) - th_f(k), part, dpart)
        moment1 = moment1 + 0.5_wp*part
        cycle
      end if
      do m = 1, nsub(i)
        k = k + 1
        itab(k) = i
        if (m == nsub(i)) then
          th_f(k) = ph%theta_tab(i + 1)
        else
          th_f(k) = ph%theta_tab(i) + (ph%theta_tab(i + 1) - ph%theta_tab(i))*m/nsub(i)
        end if
        cum(k) = cum(k - 1) + table_partial(ph, i, th_f(k), th_f(k - 1), 0)
        moment1 = moment1 + table_partial(ph, i, th_f(k), th_f(k - 1), 1)
      end do
    end do
    total = cum(nfine)
    ph%norm_factor = 1.0_wp/total
    ph%g = moment1/total
    ph%p_tab = ph%p_tab*ph%norm_factor
    ph%lp_tab = ph%lp_tab + log(ph%norm_factor)
    cum = cum*ph%norm_factor                 ! from here on everything is normalised
    cum(nfine) = 1.0_wp

    ! --- inverse CDF -------------------------------------------------------------------------
    ! Nodes of a fine grid, xi_j = j/nf, nf = INV_PIECES fpp (fpp a power of two, so that the
    ! finest step is at most 1/(ninv - 1)), each solved inside the piece of the CDF that
    ! brackets it; only the nodes that the choice of steps below asks for are solved.
    fpp = 1
    do while (INV_PIECES*fpp < ninv - 1)
      fpp = 2*fpp
    end do
    nf = INV_PIECES*fpp
    allocate (mu_f(0:nf), have(0:nf))
    have = .false.
    k0 = 1
    do while (cum(k0) <= 0.0_wp .and. k0 < nfine)   ! F = 0 up to th_f(k0-1): largest such mu
      k0 = k0 + 1
    end do
    mu_f(0) = max(cos(th_f(k0 - 1)), -1.0_wp)
    have(0) = .true.
    ! Per piece, the fewest equal steps (fpp/2^k) whose interpolation (as in phase_sample_mu:
    ! quadratic through three nodes of the piece, linear for a single step) is within INV_TOL
    ! in probability at the midpoints of the steps: there the error in mu, times the density
    ! dF/dmu estimated from the smaller half step, is compared. The midpoints are the nodes of
    ! the next finer choice, so a piece costs about four solutions per node it keeps.
    allocate (ph%inv_off(0:INV_PIECES - 1), ph%inv_m(0:INV_PIECES - 1), msteps(0:INV_PIECES - 1))
    do m = 0, INV_PIECES - 1
      msteps(m) = piece_steps(m*fpp)
    end do
    allocate (ph%mu_inv(sum(msteps) + 1))
    j = 0
    do m = 0, INV_PIECES - 1
      ph%inv_off(m) = j
      ph%inv_m(m) = real(msteps(m), wp)
      do i = 0, msteps(m) - 1
        ph%mu_inv(j + i + 1) = fine_node(m*fpp + i*(fpp/msteps(m)))
      end do
      j = j + msteps(m)
    end do
    ph%mu_inv(j + 1) = min(fine_node(nf), 1.0_wp)
    do i = 2, size(ph%mu_inv)      ! non-decreasing to rounding: make it so exactly
      ph%mu_inv(i) = max(ph%mu_inv(i), ph%mu_inv(i - 1))
    end do
  contains
    !> mu at fine node j (solved on first use)
    real(wp) function fine_node(j) result(mu)
      integer, intent(in) :: j
      real(wp) :: xi, theta
      integer :: k, i
      if (.not. have(j)) then
        xi = real(j, wp)/real(nf, wp)
        if (j == nf) xi = 1.0_wp
        ! the first piece k >= k0 with cum(k) >= xi (the last piece if none)
        k = k0 - 1 + first_not_below(cum(k0:nfine), xi)
        i = itab(k)
        if (loglin(i)) then
          theta = loglin_invert(ph, i, sin_tab(i), cos_tab(i), sin_tab(i + 1), xi - cum(k - 1), &
                                cum(k) - cum(k - 1))
        else
          theta = table_invert(ph, i, th_f(k), th_f(k - 1), xi - cum(k - 1), &
                               cum(k) - cum(k - 1))
        end if
        mu_f(j) = cos(theta)
        have(j) = .true.
      end if
      mu = mu_f(j)
    end function fine_node

    !> Steps of the piece whose first fine node is `base`.
    integer function piece_steps(base) result(ms)
      integer, intent(in) :: base
      real(wp) :: dmu, lin, err, fa, fb, fq, fc
      integer :: s, h, t, a
      logical :: ok
      ms = 1
      do while (ms < fpp)
        s = fpp/ms
        h = s/2
        ok = .true.
        do t = 0, ms - 1
          a = base + t*s
          fa = fine_node(a)
          fb = fine_node(a + s)
          fq = fine_node(a + h)
          if (ms == 1) then
            lin = 0.5_wp*(fa + fb)
          else if (t + 2 <= ms) then
            fc = fine_node(a + 2*s)
            lin = quad_through(fa, fb, fc, 0.5_wp)
          else
            fc = fine_node(a - s)
            lin = quad_through(fc, fa, fb, 1.5_wp)
          end if
          lin = min(max(lin, fa), fb)
          dmu = max(0.0_wp, min(fq - fa, fb - fq))
          err = abs(lin - fq)
          if (err*real(h, wp) > INV_TOL*real(nf, wp)*dmu) then
            ok = .false.
            exit
          end if
        end do
        if (ok) exit
        ms = 2*ms
      end do
    end function piece_steps
  end function phase_from_table

  !> Phase function given by its normalised Legendre moments, P(mu) = sum_l (2l+1) chi_l P_l(mu)
  !> (chi_0 = 1, chi_1 = g; DISORT's PMOM, SHDOM's a_l/(2l+1)).
  !>
  !> Trailing zero moments are dropped; L is the highest degree left. L = 0 gives the
  !> isotropic kind and {1, 0, 0.1} (to rounding of 0.1) the analytic Rayleigh kind. Otherwise
  !> the series is summed with the upward recurrence (l + 1) P_{l+1} = (2l + 1) mu P_l - l P_{l-1},
  !> stable for |mu| <= 1, on the angle grid described with LEG_STEP_MAX_DEG (steps of
  !> 180/(16 L) deg near 0 and 180 deg, 180/(4 L) deg in between, at most 0.25 deg). Values
  !> where a truncated series is negative are set to 0 and counted in `n_negative`; the
  !> (angle, value) table then goes to `phase_from_table`, which normalises it (the factor is
  !> `norm_factor`), computes g and builds the inverse CDF.
  function phase_from_legendre(chi, n_inv, error, n_negative) result(ph)
    real(wp), intent(in) :: chi(0:)  !! normalised Legendre moments chi_l, l = 0 ... L
    !> resolution of the inverse-CDF table (>= 2; PHASE_N_INV_DEFAULT is the usual)
    integer, intent(in) :: n_inv
    type(error_t), allocatable, intent(out) :: error  !! set if the moments are invalid
    !> number of grid angles where the series was < 0 (those values are set to 0)
    integer, intent(out), optional :: n_negative
    type(phase_t) :: ph  !! the phase function (the default, isotropic, on error)

    character(len=*), parameter :: CTX = 'phase_from_legendre: '
    real(wp), allocatable :: angle(:), value(:)
    integer :: l, nleg

    if (present(n_negative)) n_negative = 0
    ! --- validation -------------------------------------------------------------------------
    if (size(chi) == 0) then
      call set_error(error, CTX//'chi is empty; at least chi(0) = 1 is needed')
      return
    end if
    do l = 0, ubound(chi, 1)
      if (.not. ieee_is_finite(chi(l))) then
        call set_error(error, CTX//'chi('//str(l)//') = '//str(chi(l))//' is not finite')
        return
      end if
    end do
    if (abs(chi(0) - 1.0_wp) > LEG_CHI_TOL) then
      call set_error(error, CTX//'chi(0) = '//str(chi(0))//' must be 1 (within 1e-6): '// &
                     'the moments must be normalised, chi_l = beta_l/(2l+1) with beta_0 = 1')
      return
    end if
    do l = 1, ubound(chi, 1)
      if (abs(chi(l)) > 1.0_wp + LEG_CHI_TOL) then
        call set_error(error, CTX//'chi('//str(l)//') = '//str(chi(l))// &
                       ' must satisfy |chi_l| <= 1 (within 1e-6), as for any non-negative '// &
                       'phase function')
        return
      end if
    end do
    if (n_inv < 2) then
      call set_error(error, CTX//'n_inv = '//str(n_inv)//' must be >= 2')
      return
    end if

    ! --- special cases ----------------------------------------------------------------------
    nleg = ubound(chi, 1)
    do while (nleg > 0)
      if (abs(chi(nleg)) > 0.0_wp) exit
      nleg = nleg - 1
    end do
    if (nleg == 0) then
      ph = new_phase_isotropic()
      return
    end if
    if (nleg == 2) then
      if (abs(chi(1)) < tiny(1.0_wp) .and. abs(chi(2) - 0.1_wp) <= 0.4_wp*epsilon(1.0_wp)) then
        ph = new_phase_rayleigh()
        return
      end if
    end if

    ! --- series on the angle grid, then the table construction ------------------------------
    call legendre_grid(nleg, angle)
    allocate (value(size(angle)))
    call legendre_series(chi(0:nleg), cos(angle*DEG2RAD), value)
    if (present(n_negative)) n_negative = count(value < 0.0_wp)
    value = max(value, 0.0_wp)
    ph = phase_from_table(angle, value, n_inv, error)
    if (allocated(error)) then
      call add_context(error, CTX//'the series (L = '//str(nleg)//') summed on '// &
                       str(size(angle))//' angles')
    end if
  end function phase_from_legendre

  !> Value of the phase function at mu (normalised: (1/2) Int P dmu = 1).
  pure function phase_eval(ph, mu) result(p)
    type(phase_t), intent(in) :: ph  !! phase function
    real(wp), intent(in) :: mu       !! cosine of the scattering angle
    real(wp) :: p                    !! phase function value
    real(wp) :: m, th
    integer :: lo, n

    select case (ph%kind)
    case (PHASE_HG)
      p = hg_eval(ph%g, mu)
    case (PHASE_RAYLEIGH)
      if (ph%depol > 0.0_wp) then
        p = rayleigh_depol_eval(ph%depol, mu)
      else
        p = rayleigh_eval(mu)
      end if
    case (PHASE_TABLE)
      ! the interval lo of m: the largest lo <= n - 1 with mu_tab(lo) <= m, found from the
      ! guess of the angle's bin by steps in the direction the comparisons say (the same lo
      ! whatever the guess)
      m = min(1.0_wp, max(-1.0_wp, mu))
      th = arccos(m)
      n = size(ph%mu_tab)
      lo = ph%guide(min(size(ph%guide) - 1, int(th*ph%guide_scale)) + 1)
      do while (lo > 1)
        if (ph%mu_tab(lo) <= m) exit
        lo = lo - 1
      end do
      do while (lo < n - 1)
        if (ph%mu_tab(lo + 1) > m) exit
        lo = lo + 1
      end do
      p = table_interp(ph, lo, th)
    case default
      p = 1.0_wp
    end select
  end function phase_eval

  !> Sample mu from the phase function with one uniform deviate (u = 0 gives the backward end,
  !> see the module header). Tables: interpolation in the inverse-CDF table (see phase_t).
  pure function phase_sample_mu(ph, u) result(mu)
    type(phase_t), intent(in) :: ph  !! phase function
    real(wp), intent(in) :: u        !! uniform deviate in [0, 1]
    real(wp) :: mu                   !! cosine of the scattering angle
    real(wp) :: x
    integer :: i, j, m, p

    select case (ph%kind)
    case (PHASE_HG)
      mu = hg_sample_mu(ph%g, u)
    case (PHASE_TABLE)
      ! the piece of u, then the step inside it
      x = min(real(INV_PIECES, wp), max(0.0_wp, u*real(INV_PIECES, wp)))
      p = min(int(x), INV_PIECES - 1)
      x = (x - p)*ph%inv_m(p)
      m = int(ph%inv_m(p))
      j = min(int(x), m - 1)
      x = x - j
      i = j + ph%inv_off(p) + 1
      ! quadratic through the step's nodes and the next one (the previous one at the end of a
      ! piece), kept between the step's nodes
      if (m == 1) then
        mu = ph%mu_inv(i) + x*(ph%mu_inv(i + 1) - ph%mu_inv(i))
      else if (j + 2 <= m) then
        mu = quad_through(ph%mu_inv(i), ph%mu_inv(i + 1), ph%mu_inv(i + 2), x)
      else
        mu = quad_through(ph%mu_inv(i - 1), ph%mu_inv(i), ph%mu_inv(i + 1), x + 1.0_wp)
      end if
      mu = min(max(mu, ph%mu_inv(i)), ph%mu_inv(i + 1))
    case (PHASE_RAYLEIGH)
      if (ph%depol > 0.0_wp) then
        mu = rayleigh_depol_sample_mu(ph%depol, u)
      else
        mu = rayleigh_sample_mu(u)
      end if
    case default
      mu = isotropic_sample_mu(u)
    end select
  end function phase_sample_mu

  !> Probabilities xi of the nodes of a table's inverse CDF (mu_inv(j) = F^-1(xi(j))).
  pure function phase_inv_xi(ph) result(xi)
    type(phase_t), intent(in) :: ph
    real(wp), allocatable :: xi(:)
    integer :: p, i, m
    allocate (xi(size(ph%mu_inv)))
    do p = 0, INV_PIECES - 1
      m = int(ph%inv_m(p))
      do i = 0, m - 1
        xi(ph%inv_off(p) + i + 1) = (real(p, wp) + real(i, wp)/real(m, wp))/INV_PIECES
      end do
    end do
    xi(size(xi)) = 1.0_wp
  end function phase_inv_xi

  ! ------------------------------------------------------------------------------------------
  ! Private helpers
  ! ------------------------------------------------------------------------------------------

  !> The quadratic through (0, fa), (1, fb), (2, fc) at t.
  pure real(wp) function quad_through(fa, fb, fc, t) result(f)
    real(wp), intent(in) :: fa, fb, fc, t
    f = 0.5_wp*fa*(t - 1.0_wp)*(t - 2.0_wp) - fb*t*(t - 2.0_wp) + 0.5_wp*fc*t*(t - 1.0_wp)
  end function quad_through

  !> The bins of `phase_eval`'s search: GUIDE_PER_NODE bins of theta per table angle (at least
  !> GUIDE_MIN, at most GUIDE_MAX), each pointing to the interval of its largest angle, so that
  !> an evaluation walks from there over the few table angles inside its bin.
  pure subroutine build_guide(ph)
    type(phase_t), intent(inout) :: ph
    integer :: nb, b, lo, n
    real(wp) :: m
    n = size(ph%mu_tab)
    nb = min(GUIDE_MAX, max(GUIDE_MIN, GUIDE_PER_NODE*n))
    allocate (ph%guide(nb))
    ph%guide_scale = real(nb, wp)/PI
    lo = 1
    do b = nb - 1, 0, -1               ! from the backward end: ascending in mu
      m = cos(real(b + 1, wp)*(PI/real(nb, wp)))
      do while (lo < n - 1)
        if (ph%mu_tab(lo + 1) > m) exit
        lo = lo + 1
      end do
      ph%guide(b + 1) = lo
    end do
  end subroutine build_guide

  !> Interpolated table value at angle theta in evaluation-table interval i (between
  !> theta_tab(i) and theta_tab(i+1)): linear in angle of log P if both ends are positive,
  !> linear in angle of P otherwise.
  pure function table_interp(ph, i, theta) result(p)
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: i
    real(wp), intent(in) :: theta  !! scattering angle [rad]
    real(wp) :: p
    real(wp) :: f, pa, pb
    f = (theta - ph%theta_tab(i))*ph%inv_dth(i)
    f = min(1.0_wp, max(0.0_wp, f))
    pa = ph%p_tab(i)
    pb = ph%p_tab(i + 1)
    if (pa > 0.0_wp .and. pb > 0.0_wp) then
      ! pa (pb/pa)^f, as one exponential of the stored logarithms
      p = exp(ph%lp_tab(i) + f*(ph%lp_tab(i + 1) - ph%lp_tab(i)))
    else
      p = pa + f*(pb - pa)
    end if
  end function table_interp

  !> (1/2) Int_{t_lo}^{t_hi} P(theta) sin(theta) cos(theta)^moment dtheta for the interpolant
  !> of evaluation-table interval i, by 5-point Gauss-Legendre quadrature.
  pure function table_partial(ph, i, t_lo, t_hi, moment) result(s)
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: i
    real(wp), intent(in) :: t_lo, t_hi  !! limits [rad], t_lo <= t_hi
    integer, intent(in) :: moment       !! 0: normalisation integral, 1: first moment
    real(wp) :: s
    real(wp) :: half, mid, t, f
    integer :: q
    half = 0.5_wp*(t_hi - t_lo)
    mid = 0.5_wp*(t_hi + t_lo)
    s = 0.0_wp
    do q = 1, size(GL_X)
      t = mid + half*GL_X(q)
      f = table_interp(ph, i, t)*sin(t)
      if (moment == 1) f = f*cos(t)
      s = s + GL_W(q)*f
    end do
    s = 0.5_wp*half*s
  end function table_partial

  !> Partial integral of a log-linear interval i (p_tab(i) > 0 and p_tab(i+1) > 0) from its
  !> larger angle t_i = theta_tab(i) down by s:
  !>
  !>     part(s) = (1/2) Int_{t_i - s}^{t_i} P(t) sin(omega t) dt,   dpart = (1/2) P sin(omega t)
  !>
  !> at t = t_i - s. With P(t_i - x) = P_i e^(beta x), beta = (ln P_(i+1) - ln P_i)/h and
  !> sin(omega (t_i - x)) = sin(omega t_i) cos(omega x) - cos(omega t_i) sin(omega x),
  !>
  !>     part(s) = (1/2) P_i [sin(omega t_i) Re Phi - cos(omega t_i) Im Phi],
  !>     Phi = Int_0^s e^(z x) dx = s (e^w - 1)/w,   z = beta + i omega,  w = z s
  !>
  !> (Int e^(b t) sin t dt = e^(b t) (b sin t - cos t)/(1 + b^2) in complex form), and dpart
  !> the same with e^w for Phi. For |w| <= SERIES_W_MAX, (e^w - 1)/w = 1 + w/2 (1 + w/3 (...))
  !> is summed as a series: no cancellation, no exponential. Beyond, e^w - 1 is formed with
  !> P_i e^(beta s) = exp(ln P_i + beta s), which never exceeds the larger end value (no
  !> overflow for steep peaks); the relative error of Im Phi is then at most
  !> ~ 2 |beta|/(s |z|^2) eps <= 4 eps/|w| <= 8 eps, and that of e^w - 1 ~ eps/|w| <= 2 eps.
  !> The combination with sin(omega t_i), cos(omega t_i) cancels by at most a factor 2 for
  !> omega = 1 (t_i >= s), so the piece is accurate to a few rounding errors relative to its
  !> value. (For omega = 2, used for g, sin(2t) changes sign at 90 deg: absolute accuracy.)
  pure subroutine loglin_piece(ph, i, omega, sw, cw, s, part, dpart)
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: i
    real(wp), intent(in) :: omega   !! 1 (normalisation, CDF) or 2 (first moment)
    real(wp), intent(in) :: sw, cw  !! sin(omega theta_tab(i)), cos(omega theta_tab(i))
    real(wp), intent(in) :: s       !! 0 <= s <= theta_tab(i) - theta_tab(i+1) [rad]
    real(wp), intent(out) :: part, dpart
    complex(wp) :: z, w, phi, p_int, p_end
    real(wp) :: beta, p0, w2
    integer :: k, nterm
    p0 = ph%p_tab(i)
    beta = -(ph%lp_tab(i + 1) - ph%lp_tab(i))*ph%inv_dth(i)
    z = cmplx(beta, omega, wp)
    w2 = (beta*beta + omega*omega)*s*s
    if (w2 <= SERIES_W2(1)) then
      nterm = SERIES_TERMS(1)
      do k = 2, size(SERIES_W2)
        if (w2 > SERIES_W2(k)) exit
        nterm = SERIES_TERMS(k)
      end do
      w = z*s
      phi = (1.0_wp, 0.0_wp)
      do k = nterm, 2, -1
        phi = 1.0_wp + phi*(w*(1.0_wp/real(k, wp)))   ! real factor: no complex division
      end do
      p_int = (p0*s)*phi
      p_end = p0 + p0*(w*phi)
    else
      p_end = exp(ph%lp_tab(i) + beta*s)*cmplx(cos(omega*s), sin(omega*s), wp)
      p_int = (p_end - p0)*conjg(z)/(beta*beta + omega*omega)   ! / z
    end if
    part = 0.5_wp*(sw*real(p_int, wp) - cw*aimag(p_int))
    dpart = 0.5_wp*(sw*real(p_end, wp) - cw*aimag(p_end))
  end subroutine loglin_piece

  !> Angle theta in log-linear interval i with (1/2) Int_theta^theta_tab(i) P sin dtheta' = r,
  !> 0 <= r <= r_max = the integral over the whole interval: safeguarded Newton iteration on
  !> s = theta_tab(i) - theta with the closed form of `loglin_piece` (bisection when a step
  !> leaves the bracket), started from the root for an integrand linear in s.
  pure function loglin_invert(ph, i, sw, cw, sw_next, r, r_max) result(theta)
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: i
    real(wp), intent(in) :: sw, cw     !! sin and cos of theta_tab(i)
    real(wp), intent(in) :: sw_next    !! sin of theta_tab(i+1)
    real(wp), intent(in) :: r, r_max
    real(wp) :: theta
    integer, parameter :: MAX_ITER = 100
    real(wp) :: h, s, lo, hi, g0, gh, a, d, res, part, dpart, step, tol, curv, sin_min
    integer :: iter
    logical :: newton, early

    h = ph%theta_tab(i) - ph%theta_tab(i + 1)
    if (r >= r_max) then
      theta = ph%theta_tab(i + 1)
      return
    else if (r <= 0.0_wp) then
      theta = ph%theta_tab(i)
      return
    end if
    ! integrand 0.5 P sin at both ends; g0 s + a s^2 = r with a = (gh - g0)/(2h)
    g0 = 0.5_wp*ph%p_tab(i)*sw
    gh = 0.5_wp*ph%p_tab(i + 1)*sw_next
    a = 0.5_wp*(gh - g0)/h
    d = g0*g0 + 4.0_wp*a*r
    s = h*(r/r_max)
    if (d >= 0.0_wp) then       ! (nested: Fortran may evaluate sqrt(d) with d < 0 otherwise)
      if (g0 + sqrt(d) > 0.0_wp) s = 2.0_wp*r/(g0 + sqrt(d))
    end if
    s = min(h, max(0.0_wp, s))
    tol = 4.0_wp*epsilon(1.0_wp)*h
    ! G'(s) = P sin(t)/2, t = theta_tab(i) - s: |G''/G'| = |beta + cot t| <= |beta| + 1/sin t,
    ! and sin t >= min of its end values on the interval (t within 0 ... pi); no such bound
    ! (and no early exit) on the intervals that end at 0 or 180 deg
    sin_min = min(sw, sw_next)
    early = sin_min > epsilon(1.0_wp)
    curv = abs((ph%lp_tab(i + 1) - ph%lp_tab(i))*ph%inv_dth(i)) + &
           1.0_wp/max(sin_min, epsilon(1.0_wp))
    lo = 0.0_wp
    hi = h
    do iter = 1, MAX_ITER
      call loglin_piece(ph, i, 1.0_wp, sw, cw, s, part, dpart)
      res = part - r                ! increases with s
      if (res < 0.0_wp) then
        lo = s
      else if (res > 0.0_wp) then
        hi = s
      else
        exit
      end if
      newton = dpart > 0.0_wp
      if (newton) then
        step = -res/dpart
        ! (a step below the rounding of s lands on the bracket end s itself: still Newton)
        newton = s + step >= lo .and. s + step <= hi
      end if
      if (.not. newton) step = 0.5_wp*(lo + hi) - s
      s = s + step
      ! converged to rounding of s, or the residual is at the rounding level of the integral
      if (abs(step) <= tol .or. hi - lo <= tol .or. abs(res) <= 4.0_wp*epsilon(1.0_wp)*r_max) exit
      ! a Newton step leaves an error of about |G''/(2 G')| step^2 <= curv step^2/2: stop when
      ! that is below tol, which saves the evaluation that would only confirm it
      if (newton .and. early) then
        if (0.5_wp*curv*step*step <= tol) exit
      end if
    end do
    theta = ph%theta_tab(i) - s
  end function loglin_invert

  !> Angle theta in [t_lo, t_hi] with (1/2) Int_theta^t_hi P sin dtheta' = r, where
  !> 0 <= r <= r_max = the integral over the whole piece (safeguarded Newton iteration,
  !> bisection when a Newton step leaves the bracket).
  pure function table_invert(ph, i, t_lo, t_hi, r, r_max) result(theta)
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: i
    real(wp), intent(in) :: t_lo, t_hi  !! piece [rad], inside table interval i
    real(wp), intent(in) :: r, r_max
    real(wp) :: theta
    integer, parameter :: MAX_ITER = 100
    real(wp) :: lo, hi, res, slope, step, mu_lo, mu_hi
    integer :: iter

    if (r >= r_max) then
      theta = t_lo
      return
    else if (r <= 0.0_wp) then
      theta = t_hi
      return
    end if
    ! start from the linear-in-mu guess (P constant on the piece)
    mu_lo = cos(t_hi)
    mu_hi = cos(t_lo)
    theta = acos(min(1.0_wp, mu_lo + (r/r_max)*(mu_hi - mu_lo)))
    theta = min(t_hi, max(t_lo, theta))
    lo = t_lo
    hi = t_hi
    do iter = 1, MAX_ITER
      res = table_partial(ph, i, theta, t_hi, 0) - r   ! decreases with theta
      if (res > 0.0_wp) then
        lo = theta
      else if (res < 0.0_wp) then
        hi = theta
      else
        return
      end if
      slope = 0.5_wp*table_interp(ph, i, theta)*sin(theta)
      if (slope > 0.0_wp) then
        step = res/slope
        if (theta + step < lo .or. theta + step > hi) step = 0.5_wp*(lo + hi) - theta
      else
        step = 0.5_wp*(lo + hi) - theta
      end if
      theta = theta + step
      if (abs(step) <= 4.0_wp*epsilon(1.0_wp)*theta .or. &
          hi - lo <= 4.0_wp*epsilon(1.0_wp)*hi) return
    end do
  end function table_invert

  !> Angles [deg] on which a Legendre series of highest degree `nleg` >= 1 is summed: steps of
  !> h_f = min(LEG_STEP_MAX_DEG, 180/(LEG_FINE_PER_WIDTH nleg)) on the LEG_ZONE_STEPS steps next
  !> to 0 and to 180 deg, steps of at most min(LEG_STEP_MAX_DEG, 180/(LEG_MID_PER_WIDTH nleg))
  !> in between; h_f everywhere if the two end zones cover 0-180 deg. Strictly increasing,
  !> first 0 and last 180 exactly.
  pure subroutine legendre_grid(nleg, angle)
    integer, intent(in) :: nleg
    real(wp), allocatable, intent(out) :: angle(:)
    real(wp) :: h_fine, h_mid, zone
    integer :: n, n_mid, i
    h_fine = min(LEG_STEP_MAX_DEG, 180.0_wp/real(LEG_FINE_PER_WIDTH*nleg, wp))
    h_mid = min(LEG_STEP_MAX_DEG, 180.0_wp/real(LEG_MID_PER_WIDTH*nleg, wp))
    zone = LEG_ZONE_STEPS*h_fine
    if (2.0_wp*zone >= 180.0_wp) then
      n = ceiling(180.0_wp/h_fine)
      allocate (angle(n + 1))
      do i = 0, n
        angle(i + 1) = 180.0_wp*real(i, wp)/real(n, wp)
      end do
    else
      n_mid = ceiling((180.0_wp - 2.0_wp*zone)/h_mid)
      n = 2*LEG_ZONE_STEPS + n_mid
      allocate (angle(n + 1))
      do i = 0, LEG_ZONE_STEPS
        angle(i + 1) = zone*real(i, wp)/real(LEG_ZONE_STEPS, wp)
        angle(n + 1 - i) = 180.0_wp - angle(i + 1)
      end do
      do i = 1, n_mid - 1
        angle(LEG_ZONE_STEPS + 1 + i) = zone + (180.0_wp - 2.0_wp*zone)*real(i, wp)/real(n_mid, wp)
      end do
    end if
  end subroutine legendre_grid

  !> s(i) = sum_{l=0}^{L} (2l+1) chi_l P_l(mu(i)), L = ubound(chi), with the upward recurrence
  !> P_{l+1} = ((2l+1)/(l+1)) mu P_l - (l/(l+1)) P_{l-1} (stable for |mu| <= 1), looping over
  !> the angles innermost so the loop vectorises.
  pure subroutine legendre_series(chi, mu, s)
    real(wp), intent(in) :: chi(0:)  !! normalised moments, L >= 1
    real(wp), intent(in) :: mu(:)    !! cosines of the angles
    real(wp), intent(out) :: s(:)    !! series at mu, size(mu)
    real(wp), allocatable :: p_prev(:), p_cur(:)
    real(wp) :: a, b, c, p_next
    integer :: l, i
    allocate (p_prev(size(mu)), source=1.0_wp)   ! P_0
    allocate (p_cur(size(mu)), source=mu)        ! P_1
    s = chi(0) + 3.0_wp*chi(1)*mu
    do l = 1, ubound(chi, 1) - 1
      a = real(2*l + 1, wp)/real(l + 1, wp)
      b = real(l, wp)/real(l + 1, wp)
      c = real(2*l + 3, wp)*chi(l + 1)
      do i = 1, size(mu)
        p_next = a*mu(i)*p_cur(i) - b*p_prev(i)
        p_prev(i) = p_cur(i)
        p_cur(i) = p_next
        s(i) = s(i) + c*p_next
      end do
    end do
  end subroutine legendre_series

end module kumo_phase
