! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_phase: normalisation, exactness of the analytic inverse CDFs, tables built
!> from Henyey-Greenstein and from the Deirmendjian C.1 cloud phase function, phase functions
!> from Legendre moments, the depolarised Rayleigh phase function, input validation.
!>
!> The C.1 table (I3RC Phase 1 file `C.1_PF`) is read from the path given as the first
!> command-line argument; CTest passes `${KUMO_SHARED_DIR}/data/i3rc/phase1_inputs/C.1_PF`.
!> The C.1 Legendre moments (`C.1_leg_coef`, 300 values chi_l) are read from the same folder.
!> The 490-term Legendre series of the I3RC SHDOM property file `les_stcu_w213.prp` is read
!> from the sibling folder `les_examples`.
!> Sampling formulas are tested with stratified deviates u = (i - 1/2)/n, no generator.
module test_kumo_phase
  use, intrinsic :: iso_fortran_env, only: real128
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_positive_inf
  use kumo_test_text, only: read_table
  use kumo_kinds, only: wp
  use kumo_constants, only: PI, DEG2RAD
  use kumo_error, only: str
  use kumo_phase, only: PHASE_ISOTROPIC, PHASE_RAYLEIGH, PHASE_HG, PHASE_TABLE, PHASE_NAMES, &
                        PHASE_N_INV_DEFAULT, phase_t, phase_kind_from_name, new_phase_isotropic, &
                        new_phase_rayleigh, new_phase_rayleigh_depol, new_phase_hg, &
                        phase_from_table, phase_from_legendre, phase_sample_mu, phase_eval, phase_inv_xi, &
                        isotropic_sample_mu, rayleigh_sample_mu, hg_sample_mu, rayleigh_eval, &
                        hg_eval
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  implicit none
  private
  public :: collect_phase

  integer, parameter :: qp = real128
  real(wp), parameter :: HG_GS(6) = [0.0_wp, 0.3_wp, 0.85_wp, -0.5_wp, 0.99_wp, -0.95_wp]

  ! 5-point Gauss-Legendre nodes and weights on [-1, 1] (tabulated values).
  real(wp), parameter :: GX(5) = [-0.90617984593866399_wp, &
                                  -0.53846931010568309_wp, 0.0_wp, &
                                  0.53846931010568309_wp, &
                                  0.90617984593866399_wp]
  real(wp), parameter :: GW(5) = [0.23692688505618909_wp, &
                                  0.47862867049936647_wp, &
                                  0.56888888888888889_wp, &
                                  0.47862867049936647_wp, &
                                  0.23692688505618909_wp]

contains

  !> All tests of this suite.
  function collect_phase() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('kind_from_name', test_kind_from_name), &
             new_unittest('normalisation_analytic', test_norm_analytic), &
             new_unittest('isotropic_and_rayleigh_moments', test_moments_iso_rayleigh), &
             new_unittest('hg_mean_cosine_equals_g', test_hg_mean_cosine), &
             new_unittest('hg_inverse_cdf', test_hg_inverse), &
             new_unittest('hg_sample_high_precision', test_hg_precision), &
             new_unittest('hg_edges_and_small_g', test_hg_edges), &
             new_unittest('hg_eval_forward_peak', test_hg_eval_peak), &
             new_unittest('rayleigh_inverse_exact', test_rayleigh_inverse), &
             new_unittest('new_phase_hg_rejects_bad_g', test_hg_constructor), &
             new_unittest('table_from_hg', test_table_from_hg), &
             new_unittest('table_c1_cloud', test_table_c1), &
             new_unittest('table_with_zero_range', test_table_zeros), &
             new_unittest('table_validation_errors', test_table_errors), &
             new_unittest('legendre_hg_series', test_legendre_hg), &
             new_unittest('legendre_special_cases', test_legendre_special), &
             new_unittest('legendre_depolarised_rayleigh_series', test_legendre_depol), &
             new_unittest('legendre_c1_moments', test_legendre_c1), &
             new_unittest('legendre_negative_series', test_legendre_negative), &
             new_unittest('legendre_validation_errors', test_legendre_errors), &
             new_unittest('rayleigh_depol_closed_form', test_rayleigh_depol), &
             new_unittest('rayleigh_depol_zero_is_plain', test_rayleigh_depol_zero), &
             new_unittest('rayleigh_depol_rejects_bad_rho', test_rayleigh_depol_errors), &
             new_unittest('samples_within_bounds', test_bounds), &
             new_unittest('table_brute_force_hg_peak', test_brute_hg_peak), &
             new_unittest('table_brute_force_zeros', test_brute_zeros), &
             new_unittest('table_brute_force_prp_490_terms', test_brute_prp), &
             new_unittest('table_search_guide', test_search_guide)]
  end function collect_phase

  ! ------------------------------------------------------------------------------------------
  ! Helpers
  ! ------------------------------------------------------------------------------------------

  !> (1/2) Int_a^b P(cos t) sin t cos(t)^moment dt by 5-point Gauss-Legendre quadrature.
  function gl_piece(ph, a, b, moment) result(s)
    type(phase_t), intent(in) :: ph
    real(wp), intent(in) :: a, b    !! limits [rad]
    integer, intent(in) :: moment   !! 0: normalisation, 1: mean cosine
    real(wp) :: s
    real(wp) :: t, f
    integer :: q
    s = 0.0_wp
    do q = 1, 5
      t = 0.5_wp*(a + b) + 0.5_wp*(b - a)*GX(q)
      f = phase_eval(ph, cos(t))*sin(t)
      if (moment == 1) f = f*cos(t)
      s = s + GW(q)*f
    end do
    s = 0.25_wp*(b - a)*s
  end function gl_piece

  !> (1/2) Int_0^pi P(cos t) sin t cos(t)^moment dt on n_int equal intervals in t; with n_int a
  !> multiple of 1800, the nodes of a 0.1 deg table are interval ends.
  function norm_integral(ph, n_int, moment) result(s)
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: n_int
    integer, intent(in) :: moment   !! 0: normalisation, 1: mean cosine
    real(wp) :: s
    real(wp) :: h
    integer :: i
    h = PI/n_int
    s = 0.0_wp
    do i = 1, n_int
      s = s + gl_piece(ph, (i - 1)*h, i*h, moment)
    end do
  end function norm_integral

  !> Largest |F(mu(j)) - xi(j)|, with F(mu) = (1/2) Int_{-1}^{mu} P dmu' integrated
  !> independently from `phase_eval` (in angle, 0.01 deg intervals, so the nodes of 0.1 deg
  !> tables are interval ends).
  function cdf_error(ph, mu, xi) result(max_err)
    type(phase_t), intent(in) :: ph
    real(wp), intent(in) :: mu(:), xi(:)
    real(wp) :: max_err
    integer, parameter :: n_int = 18000
    real(wp) :: c(0:n_int)
    real(wp) :: h, theta, f
    integer :: j, k
    h = PI/n_int
    c(n_int) = 0.0_wp           ! c(k) = (1/2) Int_{k h}^{pi} P sin t dt
    do k = n_int - 1, 0, -1
      c(k) = c(k + 1) + gl_piece(ph, k*h, (k + 1)*h, 0)
    end do
    max_err = 0.0_wp
    do j = 1, size(mu)
      theta = acos(mu(j))
      k = min(int(theta/h), n_int - 1)
      f = c(k + 1) + gl_piece(ph, theta, (k + 1)*h, 0)
      max_err = max(max_err, abs(f - xi(j)))
    end do
  end function cdf_error

  !> Largest |F(mu_inv(j)) - xi_j| over the nodes of the inverse-CDF table (cdf_error).
  function inverse_node_error(ph) result(max_err)
    type(phase_t), intent(in) :: ph
    real(wp) :: max_err
    max_err = cdf_error(ph, ph%mu_inv, phase_inv_xi(ph))
  end function inverse_node_error

  !> Largest |F(phase_sample_mu(ph, u)) - u| over u = (i - 1/2)/n, i = 1..n (cdf_error): what
  !> sampling moves in probability, nodes and the interpolation between them together.
  function sample_cdf_error(ph, n) result(max_err)
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: n
    real(wp) :: max_err
    real(wp), allocatable :: u(:), mu(:)
    integer :: i
    u = [((i - 0.5_wp)/n, i=1, n)]
    allocate (mu(n))
    do i = 1, n
      mu(i) = phase_sample_mu(ph, u(i))
    end do
    max_err = cdf_error(ph, mu, u)
  end function sample_cdf_error

  !> Henyey-Greenstein CDF from mu = -1, evaluated in quadruple precision:
  !> F(mu) = (1 - g^2)/(2g) [(1 + g^2 - 2 g mu)^(-1/2) - 1/(1 + g)], F = (1 + mu)/2 for g = 0.
  elemental function hg_cdf(g, mu) result(f)
    real(wp), intent(in) :: g, mu
    real(wp) :: f
    real(qp) :: gq, mq
    gq = real(g, qp)
    mq = real(mu, qp)
    if (abs(g) < tiny(1.0_wp)) then
      f = real(0.5_qp*(1.0_qp + mq), wp)
    else
      f = real((1.0_qp - gq*gq)/(2.0_qp*gq)*(1.0_qp/sqrt(1.0_qp + gq*gq - 2.0_qp*gq*mq) - &
                                             1.0_qp/(1.0_qp + gq)), wp)
    end if
  end function hg_cdf

  !> Textbook HG inverse CDF evaluated in quadruple precision (reference values).
  function hg_inverse_qp(g, u) result(mu)
    real(wp), intent(in) :: g, u
    real(wp) :: mu
    real(qp) :: gq, uq, s
    gq = real(g, qp)
    uq = real(u, qp)
    if (abs(g) < tiny(1.0_wp)) then
      mu = real(2.0_qp*uq - 1.0_qp, wp)
    else
      s = (1.0_qp - gq*gq)/(1.0_qp - gq + 2.0_qp*gq*uq)
      mu = real((1.0_qp + gq*gq - s*s)/(2.0_qp*gq), wp)
    end if
  end function hg_inverse_qp

  !> Path of the C.1 phase-function file: the first command-line argument ('' if absent).
  function c1_path() result(path)
    character(len=:), allocatable :: path
    character(len=4096) :: buf
    integer :: length, stat
    call get_command_argument(1, buf, length, stat)
    if (stat /= 0 .or. length == 0) then
      path = ''
    else
      path = buf(1:length)
    end if
  end function c1_path

  !> Read the 300 C.1 Legendre moments chi_0 ... chi_299 (one value per line) from the file
  !> `C.1_leg_coef` next to the C.1_PF file named on the command line.
  subroutine read_c1_moments(chi, error)
    real(wp), allocatable, intent(out) :: chi(:)
    type(error_t), allocatable, intent(inout) :: error
    character(len=:), allocatable :: path
    integer :: unit, stat, l
    path = c1_path()
    call check(error, len(path) > 0, 'no path of C.1_PF on the command line (CTest passes '// &
               '${KUMO_SHARED_DIR}/data/i3rc/phase1_inputs/C.1_PF)')
    if (allocated(error)) return
    path = path(1:index(path, '/', back=.true.))//'C.1_leg_coef'
    open (newunit=unit, file=path, status='old', action='read', iostat=stat)
    call check(error, stat == 0, 'cannot open '//path)
    if (allocated(error)) return
    allocate (chi(0:299))
    do l = 0, 299
      read (unit, *, iostat=stat) chi(l)
      if (stat /= 0) exit
    end do
    close (unit)
    call check(error, stat == 0, 'cannot read 300 values from '//path)
  end subroutine read_c1_moments

  !> Closed-form depolarised Rayleigh phase function (Chandrasekhar 1950, Radiative Transfer,
  !> chapter I, normalised to (1/2) Int P dmu = 1), written out here independently of
  !> kumo_rayleigh: P = a + b mu^2 with a = 3 (1 + 3 gamma)/(4 (1 + 2 gamma)),
  !> b = 3 (1 - gamma)/(4 (1 + 2 gamma)), gamma = rho/(2 - rho).
  subroutine depol_coefficients(rho, a, b)
    real(wp), intent(in) :: rho
    real(wp), intent(out) :: a, b
    real(wp) :: gam
    gam = rho/(2.0_wp - rho)
    a = 3.0_wp*(1.0_wp + 3.0_wp*gam)/(4.0_wp*(1.0_wp + 2.0_wp*gam))
    b = 3.0_wp*(1.0_wp - gam)/(4.0_wp*(1.0_wp + 2.0_wp*gam))
  end subroutine depol_coefficients

  ! ------------------------------------------------------------------------------------------
  ! Brute-force reference of a table construction
  ! ------------------------------------------------------------------------------------------

  !> The table interpolant written out here: at theta in cell j (t(j) <= theta <= t(j+1),
  !> angles ascending [rad]), v(j)^(1-f) v(j+1)^f if both values are > 0, else
  !> (1-f) v(j) + f v(j+1), f = (theta - t(j))/(t(j+1) - t(j)).
  pure function interp_cell(t, v, j, theta) result(p)
    real(wp), intent(in) :: t(:), v(:)
    integer, intent(in) :: j
    real(wp), intent(in) :: theta
    real(wp) :: p, f
    f = (theta - t(j))/(t(j + 1) - t(j))
    if (v(j) > 0.0_wp .and. v(j + 1) > 0.0_wp) then
      p = exp((1.0_wp - f)*log(v(j)) + f*log(v(j + 1)))
    else
      p = (1.0_wp - f)*v(j) + f*v(j + 1)
    end if
  end function interp_cell

  !> (1/2) Int_a^b P sin(t) cos(t)^moment dt inside cell j by Simpson's rule on one panel.
  pure function simpson_panel(t, v, j, a, b, moment) result(s)
    real(wp), intent(in) :: t(:), v(:)
    integer, intent(in) :: j, moment
    real(wp), intent(in) :: a, b
    real(wp) :: s, m
    m = 0.5_wp*(a + b)
    s = (b - a)/12.0_wp*(integrand(a) + 4.0_wp*integrand(m) + integrand(b))
  contains
    pure real(wp) function integrand(x)
      real(wp), intent(in) :: x
      integrand = interp_cell(t, v, j, x)*sin(x)*cos(x)**moment
    end function integrand
  end function simpson_panel

  !> Compare a phase_t built from the table (t ascending from 0 to pi [rad], v >= 0, any scale)
  !> with composite Simpson quadrature of the interpolant on `m_panels` panels per table cell:
  !> norm_factor = 1/T with T = (1/2) Int P sin, g = (1/2) Int P sin cos / T, and every
  !> `stride`-th mu_inv(j) from j = 2 against the root of F(theta) = xi_j T, F integrated
  !> from 180 deg, found by bisection inside the panel that brackets it.
  subroutine check_brute_force(error, what, t, v, ph, m_panels, stride, tol)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: what
    real(wp), intent(in) :: t(:), v(:)
    type(phase_t), intent(in) :: ph
    integer, intent(in) :: m_panels, stride
    real(wp), intent(in) :: tol  !! on norm_factor (relative), g and mu_inv (absolute)
    real(wp), allocatable :: node(:), c(:), xis(:)
    integer, allocatable :: cell(:)
    real(wp) :: total, first, target, lo, hi, mid, f_mid, mu_ref, max_err, h
    integer :: n, np, j, m, k, it, n_inv, n_cmp
    if (allocated(error)) return
    n = size(t)
    np = (n - 1)*m_panels
    allocate (node(0:np), c(0:np), cell(np))
    node(0) = t(1)
    do j = 1, n - 1
      h = (t(j + 1) - t(j))/m_panels
      do m = 1, m_panels
        k = (j - 1)*m_panels + m
        cell(k) = j
        node(k) = t(j) + m*h
      end do
      node(j*m_panels) = t(j + 1)
    end do
    c(np) = 0.0_wp          ! c(k) = (1/2) Int_node(k)^pi P sin
    first = 0.0_wp
    do k = np, 1, -1
      c(k - 1) = c(k) + simpson_panel(t, v, cell(k), node(k - 1), node(k), 0)
      first = first + simpson_panel(t, v, cell(k), node(k - 1), node(k), 1)
    end do
    total = c(0)
    call check_close(error, ph%norm_factor*total, 1.0_wp, rel_tol=tol, &
                     label=what//': norm_factor against 1/(Simpson integral)')
    call check_close(error, ph%g, first/total, abs_tol=tol, label=what//': g against Simpson')
    if (allocated(error)) return
    n_inv = size(ph%mu_inv)
    xis = phase_inv_xi(ph)
    max_err = 0.0_wp
    n_cmp = 0
    k = np
    do j = 2, n_inv - 1, stride   ! the ends are the ends of zero ranges, not roots
      target = xis(j)*total
      ! panel k (node(k-1) ... node(k)) with c(k) <= target <= c(k-1); as j ascends, k descends
      do while (c(k - 1) < target .and. k > 1)
        k = k - 1
      end do
      lo = node(k - 1)      ! F(lo) >= target >= F(hi)
      hi = node(k)
      do it = 1, 60
        mid = 0.5_wp*(lo + hi)
        f_mid = c(k) + simpson_panel(t, v, cell(k), mid, node(k), 0)
        if (f_mid >= target) then
          lo = mid
        else
          hi = mid
        end if
      end do
      mu_ref = cos(0.5_wp*(lo + hi))
      max_err = max(max_err, abs(ph%mu_inv(j) - mu_ref))
      n_cmp = n_cmp + 1
    end do
    call check(error, n_cmp >= 100, what//': fewer than 100 mu_inv entries compared')
    call check_close(error, max_err, 0.0_wp, abs_tol=tol, &
                     label=what//': max |mu_inv - Simpson root| over sampled entries')
  end subroutine check_brute_force

  !> Fail unless `err` is allocated and its message contains every string in `parts`.
  subroutine expect_error(error, err, parts, what)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: parts(:)
    character(len=*), intent(in) :: what
    integer :: i
    if (allocated(error)) return
    call check(error, allocated(err), what//': no error reported')
    if (allocated(error)) return
    do i = 1, size(parts)
      call check(error, index(err%message, trim(parts(i))) > 0, &
                 what//': message "'//err%message//'" lacks "'//trim(parts(i))//'"')
    end do
  end subroutine expect_error

  ! ------------------------------------------------------------------------------------------
  ! Tests
  ! ------------------------------------------------------------------------------------------

  subroutine test_kind_from_name(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    integer :: kind, i
    do i = 1, size(PHASE_NAMES)
      call phase_kind_from_name(PHASE_NAMES(i), kind, err)
      call check(error, .not. allocated(err) .and. kind == i, 'name '//PHASE_NAMES(i))
    end do
    call phase_kind_from_name('  HG ', kind, err)
    call check(error, kind == PHASE_HG .and. .not. allocated(err), "'  HG ' is not hg")
    call phase_kind_from_name('Rayleigh', kind, err)
    call check(error, kind == PHASE_RAYLEIGH, "'Rayleigh' is not rayleigh")
    call phase_kind_from_name('TABLE', kind, err)
    call check(error, kind == PHASE_TABLE, "'TABLE' is not table")
    call phase_kind_from_name('Isotropic', kind, err)
    call check(error, kind == PHASE_ISOTROPIC, "'Isotropic' is not isotropic")
    call phase_kind_from_name('mie', kind, err)
    call check(error, kind == 0, 'kind of an unknown name is not 0')
    call expect_error(error, err, [character(len=40) :: "'mie'", &
                                   'isotropic, rayleigh, hg, table'], 'unknown name')
  end subroutine test_kind_from_name

  !> (1/2) Int P dmu = 1 for isotropic, Rayleigh and HG (quadrature in angle).
  subroutine test_norm_analytic(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    integer :: i
    character(len=24) :: label
    call check_close(error, norm_integral(new_phase_isotropic(), 200, 0), 1.0_wp, &
                     abs_tol=1.0e-12_wp, label='isotropic')
    call check_close(error, norm_integral(new_phase_rayleigh(), 200, 0), 1.0_wp, &
                     abs_tol=1.0e-12_wp, label='rayleigh')
    do i = 1, size(HG_GS)
      ph = new_phase_hg(HG_GS(i), err)
      call check(error, .not. allocated(err), 'new_phase_hg failed')
      write (label, '(a, f0.2)') 'hg g = ', HG_GS(i)
      call check_close(error, norm_integral(ph, 3600, 0), 1.0_wp, abs_tol=1.0e-12_wp, &
                       label=trim(label))
      call check_close(error, norm_integral(ph, 3600, 1), HG_GS(i), abs_tol=1.0e-12_wp, &
                       label=trim(label)//' first moment')
    end do
  end subroutine test_norm_analytic

  !> Stratified means of mu and mu^2: isotropic 0 and 1/3, Rayleigh 0 and 2/5.
  subroutine test_moments_iso_rayleigh(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: n = 100000
    real(wp) :: u, m1i, m2i, m1r, m2r, mu
    integer :: i
    m1i = 0.0_wp
    m2i = 0.0_wp
    m1r = 0.0_wp
    m2r = 0.0_wp
    do i = 1, n
      u = (i - 0.5_wp)/n
      mu = isotropic_sample_mu(u)
      m1i = m1i + mu/n
      m2i = m2i + mu*mu/n
      mu = rayleigh_sample_mu(u)
      m1r = m1r + mu/n
      m2r = m2r + mu*mu/n
    end do
    call check_close(error, m1i, 0.0_wp, abs_tol=1.0e-12_wp, label='isotropic <mu>')
    call check_close(error, m2i, 1.0_wp/3.0_wp, abs_tol=1.0e-9_wp, label='isotropic <mu^2>')
    call check_close(error, m1r, 0.0_wp, abs_tol=1.0e-12_wp, label='rayleigh <mu>')
    call check_close(error, m2r, 0.4_wp, abs_tol=1.0e-9_wp, label='rayleigh <mu^2>')
  end subroutine test_moments_iso_rayleigh

  !> Stratified mean of hg_sample_mu(g, u) equals g (midpoint rule in u: error O(1/n^2),
  !> 3e-9 for g = 0.99 and n = 1e5).
  subroutine test_hg_mean_cosine(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: n = 100000
    real(wp) :: mean, mu
    integer :: i, k
    character(len=24) :: label
    do k = 1, size(HG_GS)
      mean = 0.0_wp
      do i = 1, n
        mu = hg_sample_mu(HG_GS(k), (i - 0.5_wp)/n)
        call check(error, abs(mu) <= 1.0_wp, 'sampled mu outside [-1, 1]')
        if (allocated(error)) return
        mean = mean + mu/n
      end do
      write (label, '(a, f0.2)') '<mu>, g = ', HG_GS(k)
      call check_close(error, mean, HG_GS(k), abs_tol=1.0e-7_wp, label=trim(label))
    end do
  end subroutine test_hg_mean_cosine

  !> F(hg_sample_mu(g, u)) = u with the closed-form HG CDF. Rounding mu to double precision
  !> moves F by up to (P/2) eps/2, hence the tolerance 1e-15 + P(mu) eps.
  subroutine test_hg_inverse(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: n = 1000
    real(wp) :: u, mu
    integer :: i, k
    character(len=40) :: label
    do k = 1, size(HG_GS)
      do i = 0, n
        u = real(i, wp)/n
        mu = hg_sample_mu(HG_GS(k), u)
        write (label, '(a, f0.2, a, f0.3)') 'F(mu), g = ', HG_GS(k), ', u = ', u
        call check_close(error, hg_cdf(HG_GS(k), mu), u, &
                         abs_tol=1.0e-15_wp + hg_eval(HG_GS(k), mu)*epsilon(1.0_wp), &
                         label=trim(label))
        if (allocated(error)) return
      end do
    end do
  end subroutine test_hg_inverse

  !> hg_sample_mu agrees with the textbook inverse evaluated in quadruple precision to about
  !> one rounding of mu, also for g -> +-1 near the forward and backward directions, where the
  !> textbook formula in double precision loses many digits.
  subroutine test_hg_precision(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: gs(9) = [0.999999_wp, -0.999999_wp, 0.9999_wp, 0.9_wp, 1.0e-8_wp, &
                                    -1.0e-5_wp, 1.0e-3_wp, 0.0_wp, 0.5_wp]
    real(wp) :: us(9)
    real(wp) :: mu, ref
    integer :: i, k
    character(len=60) :: label
    us = [0.0_wp, 1.0e-12_wp, 1.0e-6_wp, 0.3_wp, 0.5_wp, 0.7_wp, 1.0_wp - 1.0e-9_wp, &
          1.0_wp - 2.0_wp*epsilon(1.0_wp), 1.0_wp]
    do k = 1, size(gs)
      do i = 1, size(us)
        mu = hg_sample_mu(gs(k), us(i))
        ref = hg_inverse_qp(gs(k), us(i))
        write (label, '(a, es10.3, a, es22.15)') 'mu, g = ', gs(k), ', u = ', us(i)
        call check_close(error, mu, ref, abs_tol=2.0_wp*epsilon(1.0_wp), &
                         rel_tol=4.0_wp*epsilon(1.0_wp), label=trim(label))
        if (allocated(error)) return
      end do
    end do
  end subroutine test_hg_precision

  !> u = 0 and u = 1 give exactly -1 and +1; g = 0 gives 2u - 1; tiny g is continuous with it.
  subroutine test_hg_edges(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: i, k
    real(wp) :: u
    do k = 1, size(HG_GS)
      call check_close(error, hg_sample_mu(HG_GS(k), 0.0_wp), -1.0_wp, abs_tol=0.0_wp, &
                       rel_tol=0.0_wp, label='mu(u = 0)')
      call check_close(error, hg_sample_mu(HG_GS(k), 1.0_wp), 1.0_wp, abs_tol=0.0_wp, &
                       rel_tol=0.0_wp, label='mu(u = 1)')
    end do
    do i = 0, 100
      u = i/100.0_wp
      call check_close(error, hg_sample_mu(0.0_wp, u), 2.0_wp*u - 1.0_wp, &
                       abs_tol=2.0_wp*epsilon(1.0_wp), label='g = 0')
      call check_close(error, hg_sample_mu(1.0e-7_wp, u), 2.0_wp*u - 1.0_wp, &
                       abs_tol=1.0e-6_wp, label='g = 1e-7')
      call check_close(error, hg_sample_mu(-1.0e-7_wp, u), 2.0_wp*u - 1.0_wp, &
                       abs_tol=1.0e-6_wp, label='g = -1e-7')
    end do
  end subroutine test_hg_edges

  !> hg_eval at the peaks: P(1) = (1 + g)/(1 - g)^2, P(-1) = (1 - g)/(1 + g)^2.
  subroutine test_hg_eval_peak(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: gs(4) = [0.999999_wp, 0.85_wp, -0.5_wp, -0.9999_wp]
    integer :: k
    do k = 1, size(gs)
      call check_close(error, hg_eval(gs(k), 1.0_wp), (1.0_wp + gs(k))/(1.0_wp - gs(k))**2, &
                       rel_tol=1.0e-13_wp, label='P(1)')
      call check_close(error, hg_eval(gs(k), -1.0_wp), (1.0_wp - gs(k))/(1.0_wp + gs(k))**2, &
                       rel_tol=1.0e-13_wp, label='P(-1)')
    end do
    call check_close(error, rayleigh_eval(0.5_wp), 0.9375_wp, label='rayleigh P(0.5)')
  end subroutine test_hg_eval_peak

  !> Rayleigh: F(sample(u)) = u for F(mu) = (mu^3 + 3 mu + 4)/8, agreement with Cardano's
  !> formula in quadruple precision, exact end points, symmetry mu(1 - u) = -mu(u).
  subroutine test_rayleigh_inverse(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: n = 2048   ! dyadic u: 1 - u is exact, so symmetry must be exact
    real(wp) :: u, mu, us(7)
    real(qp) :: q, x
    integer :: i
    character(len=60) :: label
    do i = 0, n
      u = real(i, wp)/n
      mu = rayleigh_sample_mu(u)
      write (label, '(a, f0.4)') 'F(mu), u = ', u
      call check_close(error, (mu**3 + 3.0_wp*mu + 4.0_wp)/8.0_wp, u, abs_tol=4.0e-16_wp, &
                       label=trim(label))
      call check_close(error, rayleigh_sample_mu(1.0_wp - u), -mu, abs_tol=0.0_wp, &
                       rel_tol=0.0_wp, label='symmetry')
      if (allocated(error)) return
    end do
    us = [1.0e-12_wp, 0.1_wp, 0.5_wp - 1.0e-9_wp, 0.5_wp, 0.5_wp + 1.0e-12_wp, 0.8_wp, &
          1.0_wp - 1.0e-10_wp]
    do i = 1, size(us)
      q = 4.0_qp*real(us(i), qp) - 2.0_qp
      x = (q + sqrt(q*q + 1.0_qp))**(1.0_qp/3.0_qp)
      write (label, '(a, es22.15)') 'mu vs quad precision, u = ', us(i)
      call check_close(error, rayleigh_sample_mu(us(i)), real(x - 1.0_qp/x, wp), &
                       abs_tol=2.0_wp*epsilon(1.0_wp), rel_tol=4.0_wp*epsilon(1.0_wp), &
                       label=trim(label))
    end do
    call check_close(error, rayleigh_sample_mu(0.0_wp), -1.0_wp, abs_tol=0.0_wp, &
                     rel_tol=0.0_wp, label='mu(0)')
    call check_close(error, rayleigh_sample_mu(1.0_wp), 1.0_wp, abs_tol=0.0_wp, &
                     rel_tol=0.0_wp, label='mu(1)')
  end subroutine test_rayleigh_inverse

  subroutine test_hg_constructor(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    ph = new_phase_hg(0.85_wp, err)
    call check(error, .not. allocated(err) .and. ph%kind == PHASE_HG, 'g = 0.85 rejected')
    call check_close(error, ph%g, 0.85_wp, label='g')
    ph = new_phase_hg(1.0_wp, err)
    call expect_error(error, err, [character(len=16) :: 'g = 1 must', '|g| < 1'], 'g = 1')
    ph = new_phase_hg(-1.5_wp, err)
    call expect_error(error, err, [character(len=16) :: 'g = -1.5', '|g| < 1'], 'g = -1.5')
    ph = new_phase_hg(ieee_value(1.0_wp, ieee_quiet_nan), err)
    call expect_error(error, err, [character(len=16) :: 'NaN', '|g| < 1'], 'g = NaN')
  end subroutine test_hg_constructor

  !> A table of HG g = 0.85 on 0..180 deg by 0.1 deg reproduces g, the normalisation, the
  !> values and the CDF of the analytic function.
  subroutine test_table_from_hg(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: g = 0.85_wp
    integer, parameter :: n = 1801
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp) :: angle(n), value(n), u, mu, maxdiff
    integer :: i
    angle = [(0.1_wp*i, i=0, n - 1)]
    value = 3.0_wp*hg_eval(g, cos(angle*DEG2RAD))    ! deliberately not normalised
    ph = phase_from_table(angle, value, error=err)
    call check(error, .not. allocated(err), 'phase_from_table failed')
    if (allocated(error)) return
    call check(error, ph%kind == PHASE_TABLE, 'kind is not PHASE_TABLE')
    call check(error, size(ph%mu_inv) < PHASE_N_INV_DEFAULT/2, &
               'the inverse CDF keeps nodes that linear interpolation does not need')
    call check_close(error, ph%g, g, abs_tol=1.0e-3_wp, label='g (tolerance 1e-3)')
    call check_close(error, ph%g, g, abs_tol=1.0e-5_wp, label='g (tolerance 1e-5)')
    call check_close(error, ph%norm_factor, 1.0_wp/3.0_wp, rel_tol=1.0e-5_wp, label='norm_factor')
    call check_close(error, norm_integral(ph, 18000, 0), 1.0_wp, abs_tol=1.0e-10_wp, &
                     label='normalisation of the table')
    call check_close(error, ph%mu_inv(1), -1.0_wp, abs_tol=0.0_wp, label='mu_inv(1)')
    call check_close(error, ph%mu_inv(size(ph%mu_inv)), 1.0_wp, abs_tol=0.0_wp, &
                     label='mu_inv(n_inv)')
    call check(error, all(ph%mu_inv(2:) >= ph%mu_inv(:size(ph%mu_inv) - 1)), &
               'mu_inv is not non-decreasing')
    ! values between the nodes (0.05 deg offsets)
    maxdiff = 0.0_wp
    do i = 0, 1799
      mu = cos((0.1_wp*i + 0.05_wp)*DEG2RAD)
      maxdiff = max(maxdiff, abs(phase_eval(ph, mu)/hg_eval(g, mu) - 1.0_wp))
    end do
    ! log-linear interpolation error near the peak: |d2 ln P/dtheta2| dtheta^2/8 = 4.3e-5
    call check_close(error, maxdiff, 0.0_wp, abs_tol=1.0e-4_wp, label='max relative P error')
    ! CDF: F_HG(sample(u)) = u
    maxdiff = 0.0_wp
    do i = 0, 100000
      u = i/100000.0_wp
      maxdiff = max(maxdiff, abs(hg_cdf(g, phase_sample_mu(ph, u)) - u))
    end do
    ! differs from the HG CDF by the interpolation error of the 0.1 deg table (3e-6) ...
    call check_close(error, maxdiff, 0.0_wp, abs_tol=1.0e-5_wp, label='max |F_HG(mu(u)) - u|')
    ! ... but inverts the CDF of the interpolated table to rounding at its nodes
    call check_close(error, inverse_node_error(ph), 0.0_wp, abs_tol=1.0e-11_wp, &
                     label='max |F_table(mu_inv(j)) - xi_j|')
    ! and within 1e-7 (the kept nodes' tolerance) plus the finest grid's own error between them
    ! (1.0e-7 measured)
    call check_close(error, sample_cdf_error(ph, 200000), 0.0_wp, abs_tol=1.5e-7_wp, &
                     label='max |F_table(mu(u)) - u|')
  end subroutine test_table_from_hg

  !> The Deirmendjian C.1 cloud table: g = 0.848 (published first Legendre moment chi_1,
  !> Garcia & Siewert 1985 Table 17: beta_1/3 = 2.544/3) within 2e-3; the input is normalised
  !> to 1e-3, the normalised table integrates to 1 and sampling reproduces its first moment.
  subroutine test_table_c1(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    character(len=:), allocatable :: path
    real(wp), allocatable :: angle(:), value(:)
    type(phase_t) :: ph
    real(wp) :: mean
    integer :: i, n
    path = c1_path()
    call check(error, len(path) > 0, 'no path of C.1_PF on the command line (CTest passes '// &
               '${KUMO_SHARED_DIR}/data/i3rc/phase1_inputs/C.1_PF)')
    if (allocated(error)) return
    call read_table(path, angle, value, error)
    if (allocated(error)) return
    call check(error, size(angle) == 1801, 'C.1_PF does not have 1801 lines')
    if (allocated(error)) return
    ph = phase_from_table(angle, value, PHASE_N_INV_DEFAULT, err)
    call check(error, .not. allocated(err), 'phase_from_table failed on C.1_PF')
    if (allocated(error)) return
    call check_close(error, ph%g, 0.848_wp, abs_tol=2.0e-3_wp, label='g of C.1')
    call check_close(error, ph%norm_factor, 1.0_wp, abs_tol=1.0e-3_wp, label='norm_factor')
    call check_close(error, norm_integral(ph, 18000, 0), 1.0_wp, abs_tol=1.0e-9_wp, &
                     label='normalisation of the table')
    call check_close(error, norm_integral(ph, 18000, 1), ph%g, abs_tol=1.0e-9_wp, &
                     label='first moment by quadrature vs ph%g')
    call check_close(error, phase_eval(ph, 1.0_wp), value(1)*ph%norm_factor, rel_tol=1.0e-14_wp, &
                     label='P(0 deg)')
    call check_close(error, phase_eval(ph, -1.0_wp), value(1801)*ph%norm_factor, &
                     rel_tol=1.0e-14_wp, label='P(180 deg)')
    n = 200000
    mean = 0.0_wp
    do i = 1, n
      mean = mean + phase_sample_mu(ph, (i - 0.5_wp)/n)/n
    end do
    call check_close(error, mean, ph%g, abs_tol=1.0e-8_wp, label='stratified <mu> vs g')
    call check_close(error, inverse_node_error(ph), 0.0_wp, abs_tol=1.0e-11_wp, &
                     label='max |F_table(mu_inv(j)) - xi_j|')
    ! within 1e-7 of the finest grid, whose own interpolation error is largest in its first
    ! steps (u < 1e-4, beyond 178.5 deg, where the glory bends the CDF): 3.5e-7 there
    call check_close(error, sample_cdf_error(ph, 200000), 0.0_wp, abs_tol=5.0e-7_wp, &
                     label='max |F_table(mu(u)) - u|')
  end subroutine test_table_c1

  !> A table that vanishes beyond 120 deg: no sample falls there, mu_inv(1) = cos(120 deg).
  subroutine test_table_zeros(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp) :: mu
    integer :: i
    ph = phase_from_table([0.0_wp, 60.0_wp, 120.0_wp, 180.0_wp], [1.0_wp, 1.0_wp, 0.0_wp, 0.0_wp], &
                          1000, err)
    call check(error, .not. allocated(err), 'phase_from_table failed')
    if (allocated(error)) return
    call check_close(error, ph%mu_inv(1), -0.5_wp, abs_tol=1.0e-14_wp, label='mu_inv(1)')
    do i = 0, 10000
      mu = phase_sample_mu(ph, i/10000.0_wp)
      call check(error, mu >= -0.5_wp - 1.0e-14_wp, 'sample in the zero range')
      if (allocated(error)) return
    end do
    call check_close(error, phase_eval(ph, -0.8_wp), 0.0_wp, abs_tol=0.0_wp, label='P(-0.8)')
    call check_close(error, norm_integral(ph, 18000, 0), 1.0_wp, abs_tol=1.0e-10_wp, &
                     label='normalisation')
    call check_close(error, inverse_node_error(ph), 0.0_wp, abs_tol=1.0e-11_wp, &
                     label='max |F_table(mu_inv(j)) - xi_j|')
  end subroutine test_table_zeros

  !> Every invalid table gives a message naming the index, the value and the bound.
  subroutine test_table_errors(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp) :: nan, inf
    real(wp), parameter :: a3(3) = [0.0_wp, 90.0_wp, 180.0_wp], v3(3) = [2.0_wp, 1.0_wp, 1.0_wp]
    nan = ieee_value(1.0_wp, ieee_quiet_nan)
    inf = ieee_value(1.0_wp, ieee_positive_inf)

    ph = phase_from_table(a3, v3(1:2), error=err)
    call expect_error(error, err, [character(len=40) :: 'different sizes', '(3 and 2)'], 'sizes')
    ph = phase_from_table([0.0_wp], [1.0_wp], error=err)
    call expect_error(error, err, [character(len=40) :: 'has 1 point(s)', 'at least 2'], &
                      'one point')
    ph = phase_from_table(a3, v3, 1, err)
    call expect_error(error, err, [character(len=40) :: 'n_inv = 1', '>= 2'], 'n_inv')
    ph = phase_from_table([0.0_wp, nan, 180.0_wp], v3, error=err)
    call expect_error(error, err, [character(len=40) :: 'angle_deg(2) = NaN', 'not finite'], &
                      'NaN angle')
    ph = phase_from_table([0.5_wp, 90.0_wp, 180.0_wp], v3, error=err)
    call expect_error(error, err, [character(len=40) :: 'angle_deg(1) = 0.5', 'must be 0', &
                                   '1e-6 deg'], 'first angle')
    ph = phase_from_table([0.0_wp, 90.0_wp, 179.0_wp], v3, error=err)
    call expect_error(error, err, [character(len=40) :: 'angle_deg(3) = 179 must', 'must be 180', &
                                   '1e-6 deg'], 'last angle')
    ph = phase_from_table([0.0_wp, 90.0_wp, 90.0_wp, 180.0_wp], [v3, 1.0_wp], error=err)
    call expect_error(error, err, [character(len=48) :: 'angle_deg(3) = 90 must', &
                                   'must be > angle_deg(2) = 90 (angles', 'strictly increasing'], &
                      'repeated angle')
    ph = phase_from_table([-5.0e-7_wp, -1.0e-7_wp, 180.0_wp], v3, error=err)
    call expect_error(error, err, [character(len=48) :: 'angle_deg(2) = -1E-07', &
                                   'strictly between 0 and 180'], 'interior angle')
    ph = phase_from_table(a3, [2.0_wp, -1.0_wp, 1.0_wp], error=err)
    call expect_error(error, err, [character(len=40) :: 'value(2) = -1 must', 'finite and >= 0'], &
                      'negative value')
    ph = phase_from_table(a3, [2.0_wp, 1.0_wp, nan], error=err)
    call expect_error(error, err, [character(len=40) :: 'value(3) = NaN', 'finite and >= 0'], &
                      'NaN value')
    ph = phase_from_table(a3, [inf, 1.0_wp, 1.0_wp], error=err)
    call expect_error(error, err, [character(len=40) :: 'value(1) = Inf', 'finite and >= 0'], &
                      'infinite value')
    ph = phase_from_table(a3, [0.0_wp, 0.0_wp, 0.0_wp], error=err)
    call expect_error(error, err, [character(len=40) :: 'all 3 values are 0', &
                                   'positive integral'], 'all zero')
    ! tolerated end points: within 1e-6 deg
    ph = phase_from_table([-5.0e-7_wp, 90.0_wp, 180.0_wp + 5.0e-7_wp], v3, 100, err)
    call check(error, .not. allocated(err), 'end points within 1e-6 deg rejected')
  end subroutine test_table_errors

  !> Henyey-Greenstein moments chi_l = g^l, g = 0.85, l <= 400 (the tail
  !> sum_{l > 400} (2l+1) g^l < 1e-25 is negligible) against the closed form. Tolerances: at
  !> the grid angles the series is exact to rounding; between them P is interpolated linearly
  !> in angle of log P, with steps h = 180/(16*400) deg = 4.9e-4 rad near the forward peak, so
  !> the error is below h^2/8 max|(ln P)''| = 3.4e-6 ((ln P)'' = -3g/(1 - g)^2 = -113 rad^-2 at
  !> 0 deg, smaller elsewhere); normalising the interpolant changes P by as much again: 1e-5.
  !> g and the CDF differ from HG by at most (1/2) Int |P_table - P_HG| dmu, the same bound: 1e-5
  !> (the CDF also carries the linear interpolation of the inverse-CDF table, which
  !> `table_from_hg` bounds by the same 1e-5).
  subroutine test_legendre_hg(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: g = 0.85_wp
    integer, parameter :: nleg = 400, n = 100000
    type(error_t), allocatable :: err
    type(phase_t) :: ph, coarse
    real(wp) :: chi(0:nleg), angles(12), mu, mean, maxdiff, u
    integer :: l, i, nneg
    character(len=40) :: label
    angles = [0.0_wp, 0.013_wp, 0.5_wp, 1.0_wp, 2.7_wp, 5.0_wp, 17.3_wp, 45.0_wp, 90.0_wp, &
              133.3_wp, 179.99_wp, 180.0_wp]
    chi = [(g**l, l=0, nleg)]
    ph = phase_from_legendre(chi, PHASE_N_INV_DEFAULT, err, nneg)
    call check(error, .not. allocated(err), 'phase_from_legendre failed')
    if (allocated(error)) return
    call check(error, ph%kind == PHASE_TABLE, 'kind is not PHASE_TABLE')
    call check(error, nneg == 0, 'negative values in a positive series')
    ! n_inv sets the finest grid (64 pieces of 4 steps for 200 points): passed on, it limits
    ! the nodes
    coarse = phase_from_legendre(chi, 200, err, nneg)
    call check(error, size(coarse%mu_inv) <= 257 .and. size(ph%mu_inv) > 257, &
               'n_inv not passed on')
    do i = 1, size(angles)
      mu = cos(angles(i)*DEG2RAD)
      write (label, '(a, f0.3, a)') 'P(', angles(i), ' deg)'
      call check_close(error, phase_eval(ph, mu), hg_eval(g, mu), rel_tol=1.0e-5_wp, &
                       label=trim(label))
    end do
    call check_close(error, ph%g, chi(1), abs_tol=1.0e-5_wp, label='g of the table vs chi(1)')
    mean = 0.0_wp
    maxdiff = 0.0_wp
    do i = 1, n
      u = (i - 0.5_wp)/n
      mu = phase_sample_mu(ph, u)
      mean = mean + mu/n
      maxdiff = max(maxdiff, abs(hg_cdf(g, mu) - u))
    end do
    call check_close(error, mean, chi(1), abs_tol=1.0e-5_wp, label='stratified <mu> vs chi(1)')
    call check_close(error, maxdiff, 0.0_wp, abs_tol=1.0e-5_wp, label='max |F_HG(mu(u)) - u|')
  end subroutine test_legendre_hg

  !> nleg = 0 (also after dropping trailing zeros) is isotropic; {1, 0, 0.1} is the analytic
  !> Rayleigh kind, 3/4 (1 + mu^2) exactly, as SHDOM writes it (a_2 = 0.5, chi_2 = 0.5/5).
  subroutine test_legendre_special(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp) :: mu, u
    integer :: i, k, nneg
    ph = phase_from_legendre([1.0_wp], 100, err, nneg)
    call check(error, .not. allocated(err) .and. ph%kind == PHASE_ISOTROPIC .and. nneg == 0, &
               '{1} is not isotropic')
    ph = phase_from_legendre([1.0_wp, 0.0_wp, 0.0_wp], 100, err)
    call check(error, .not. allocated(err) .and. ph%kind == PHASE_ISOTROPIC, &
               '{1, 0, 0} is not isotropic')
    call check_close(error, phase_eval(ph, 0.3_wp), 1.0_wp, abs_tol=0.0_wp, label='P(0.3)')
    do k = 1, 2
      if (k == 1) then
        ph = phase_from_legendre([1.0_wp, 0.0_wp, 0.1_wp], 100, err, nneg)
      else
        ph = phase_from_legendre([1.0_wp, 0.0_wp, 0.5_wp/5.0_wp, 0.0_wp, 0.0_wp], 100, err, nneg)
      end if
      call check(error, .not. allocated(err) .and. ph%kind == PHASE_RAYLEIGH .and. nneg == 0, &
                 '{1, 0, 0.1} is not Rayleigh')
      if (allocated(error)) return
      do i = 0, 20
        mu = -1.0_wp + 0.1_wp*i
        call check_close(error, phase_eval(ph, mu), 0.75_wp*(1.0_wp + mu*mu), abs_tol=0.0_wp, &
                         label='Rayleigh series, P(mu)')
        u = 0.05_wp*i
        call check_close(error, phase_sample_mu(ph, u), rayleigh_sample_mu(u), abs_tol=0.0_wp, &
                         label='Rayleigh series, sample')
      end do
    end do
    ! a moment just outside the Rayleigh value goes through the table
    ph = phase_from_legendre([1.0_wp, 0.0_wp, 0.1_wp + 1.0e-9_wp], 100, err)
    call check(error, .not. allocated(err) .and. ph%kind == PHASE_TABLE, &
               '{1, 0, 0.1 + 1e-9} is not a table')
  end subroutine test_legendre_special

  !> The depolarised Rayleigh function as a series, P = a + b mu^2 = 1 + 5 chi_2 P_2(mu) with
  !> chi_2 = b/7.5, against the closed form (independent check of the summation and of
  !> kumo_rayleigh's formula). The grid step is 0.25 deg (L = 2) and |(ln P)''| <= 1 rad^-2, so
  !> the interpolation error is below (4.4e-3)^2/8 = 2.4e-6 relative: tolerance 1e-5. The
  !> function and the grid are symmetric about 90 deg, so g vanishes to rounding.
  subroutine test_legendre_depol(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: rhos(2) = [0.0279_wp, 0.5_wp]
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp) :: a, b, mu
    integer :: i, k
    do k = 1, size(rhos)
      call depol_coefficients(rhos(k), a, b)
      ph = phase_from_legendre([1.0_wp, 0.0_wp, b/7.5_wp], PHASE_N_INV_DEFAULT, err)
      call check(error, .not. allocated(err) .and. ph%kind == PHASE_TABLE, &
                 'depolarised series is not a table')
      if (allocated(error)) return
      do i = 0, 16
        mu = cos(real(i, wp)*11.3_wp*DEG2RAD)
        call check_close(error, phase_eval(ph, mu), a + b*mu*mu, rel_tol=1.0e-5_wp, &
                         label='series vs a + b mu^2')
      end do
      call check_close(error, ph%g, 0.0_wp, abs_tol=1.0e-12_wp, label='g')
    end do
  end subroutine test_legendre_depol

  !> The C.1 cloud from its 300 Legendre moments (I3RC `C.1_leg_coef`, equal to Garcia &
  !> Siewert 1985 Table 17, beta_l/(2l+1)). The first moment of the series is chi_1 = 0.848
  !> exactly; the table's g differs by the first moment of the interpolation error, which is below
  !> its L1 size (1/2) Int |P_table - P| dmu = 2.8e-5 plus the renormalisation 1.6e-5 (measured
  !> with 16 points per grid interval when the grid was chosen): tolerance 5e-5. The I3RC table
  !> C.1_PF was computed from the same moments: it matches the series to 1.2e-4 at all 1801
  !> angles (7-digit values); with the interpolation error between grid angles (< 5e-4) the
  !> phase function must match C.1_PF to 1e-3 relative.
  subroutine test_legendre_c1(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: n = 200000
    type(error_t), allocatable :: err
    real(wp), allocatable :: chi(:), angle(:), value(:)
    type(phase_t) :: ph
    real(wp) :: mean, worst, rel
    integer :: i, nneg, iworst
    character(len=60) :: label
    call read_c1_moments(chi, error)
    if (allocated(error)) return
    ph = phase_from_legendre(chi, PHASE_N_INV_DEFAULT, err, nneg)
    call check(error, .not. allocated(err), 'phase_from_legendre failed on C.1_leg_coef')
    if (allocated(error)) return
    call check(error, nneg == 0, 'the C.1 series is negative somewhere')
    call check_close(error, ph%g, 0.848_wp, abs_tol=5.0e-5_wp, label='g of C.1 from moments')
    mean = 0.0_wp
    do i = 1, n
      mean = mean + phase_sample_mu(ph, (i - 0.5_wp)/n)/n
    end do
    call check_close(error, mean, 0.848_wp, abs_tol=5.0e-5_wp, label='stratified <mu>')
    call read_table(c1_path(), angle, value, error)
    if (allocated(error)) return
    worst = 0.0_wp
    iworst = 1
    do i = 1, size(angle)
      rel = abs(phase_eval(ph, cos(angle(i)*DEG2RAD))/value(i) - 1.0_wp)
      if (rel > worst) then
        worst = rel
        iworst = i
      end if
    end do
    write (label, '(a, f0.1, a)') 'max relative difference from C.1_PF (at ', angle(iworst), &
      ' deg)'
    call check_close(error, worst, 0.0_wp, abs_tol=1.0e-3_wp, label=trim(label))
  end subroutine test_legendre_c1

  !> {1, 0.9}: P = 1 + 2.7 mu is negative for mu < mu0 = -1/2.7. L = 1 is summed on the
  !> 0.25 deg grid, so the negative count is the number of grid angles with 1 + 2.7 cos < 0;
  !> beyond the first of them P = 0 and nothing is sampled there. For mu >= 0 the function is
  !> (1 + 2.7 mu)/N, N = (1/2) Int_{mu0}^{1} (1 + 2.7 mu) dmu = (1 - mu0)/2 + 0.675 (1 - mu0^2);
  !> the interpolant differs from it only in the one grid interval holding the zero (its area
  !> error is ~ P' h^2 < 1e-4 of N) and by log-linear interpolation error < 2e-5, hence 1e-4.
  subroutine test_legendre_negative(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp) :: mu0, norm, mu, mu_cut
    integer :: i, nneg, expected
    mu0 = -1.0_wp/2.7_wp
    ph = phase_from_legendre([1.0_wp, 0.9_wp], 2000, err, nneg)
    call check(error, .not. allocated(err) .and. ph%kind == PHASE_TABLE, 'conversion failed')
    if (allocated(error)) return
    expected = 0
    do i = 0, 720
      if (1.0_wp + 2.7_wp*cos(0.25_wp*i*DEG2RAD) < 0.0_wp) expected = expected + 1
    end do
    call check(error, expected == 274, 'test set-up: expected 274 negative grid angles')
    call check(error, nneg == expected, 'n_negative is not the number of negative grid angles')
    ! first grid angle past the zero: mu there and below has P = 0
    mu_cut = cos((0.25_wp*ceiling(acos(mu0)/DEG2RAD/0.25_wp))*DEG2RAD)
    call check_close(error, phase_eval(ph, mu_cut), 0.0_wp, abs_tol=0.0_wp, label='P at cut')
    call check_close(error, phase_eval(ph, -0.8_wp), 0.0_wp, abs_tol=0.0_wp, label='P(-0.8)')
    call check(error, ph%mu_inv(1) >= mu_cut - 1.0e-12_wp, 'mu_inv(1) below the zero range')
    do i = 0, 1000
      call check(error, phase_sample_mu(ph, i/1000.0_wp) >= mu_cut - 1.0e-12_wp, &
                 'sample where P = 0')
      if (allocated(error)) return
    end do
    norm = 0.5_wp*(1.0_wp - mu0) + 0.675_wp*(1.0_wp - mu0*mu0)
    do i = 0, 10
      mu = 0.1_wp*i
      call check_close(error, phase_eval(ph, mu), (1.0_wp + 2.7_wp*mu)/norm, rel_tol=1.0e-4_wp, &
                       label='clipped series, P(mu >= 0)')
    end do
  end subroutine test_legendre_negative

  !> Invalid moments give messages naming the index, the value and the rule.
  subroutine test_legendre_errors(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp) :: nan, inf
    real(wp) :: empty(0:-1)
    integer :: nneg
    nan = ieee_value(1.0_wp, ieee_quiet_nan)
    inf = ieee_value(1.0_wp, ieee_positive_inf)
    ph = phase_from_legendre([0.9_wp, 0.5_wp], 100, err, nneg)
    call expect_error(error, err, [character(len=48) :: 'phase_from_legendre: ', &
                                   'chi(0) = 0.9 must be 1 (within 1e-6)'], 'chi(0) = 0.9')
    call check(error, ph%kind == PHASE_ISOTROPIC .and. nneg == 0, 'result on error')
    ph = phase_from_legendre([1.0_wp + 2.0e-6_wp], 100, err)
    call expect_error(error, err, [character(len=48) :: 'chi(0) = 1.000002 must be 1'], &
                      'chi(0) = 1 + 2e-6')
    ph = phase_from_legendre([1.0_wp, 0.5_wp, 0.2_wp, 1.2_wp], 100, err)
    call expect_error(error, err, [character(len=48) :: 'chi(3) = 1.2 must satisfy', &
                                   '|chi_l| <= 1 (within 1e-6)'], 'chi(3) = 1.2')
    ph = phase_from_legendre([1.0_wp, 0.5_wp, -1.5_wp], 100, err)
    call expect_error(error, err, [character(len=48) :: 'chi(2) = -1.5 must satisfy'], &
                      'chi(2) = -1.5')
    ph = phase_from_legendre([1.0_wp, nan], 100, err)
    call expect_error(error, err, [character(len=48) :: 'chi(1) = NaN is not finite'], 'NaN')
    ph = phase_from_legendre([inf, 0.5_wp], 100, err)
    call expect_error(error, err, [character(len=48) :: 'chi(0) = Inf is not finite'], 'Inf')
    ph = phase_from_legendre(empty, 100, err)
    call expect_error(error, err, [character(len=48) :: 'chi is empty'], 'empty')
    ph = phase_from_legendre([1.0_wp, 0.5_wp], 1, err)
    call expect_error(error, err, [character(len=48) :: 'phase_from_legendre: n_inv = 1', &
                                   'must be >= 2'], 'n_inv')
    ! within the tolerances: accepted
    ph = phase_from_legendre([1.0_wp + 9.0e-7_wp, -1.0_wp - 9.0e-7_wp], 100, err)
    call check(error, .not. allocated(err), 'moments within 1e-6 of the bounds rejected')
  end subroutine test_legendre_errors

  !> The depolarised Rayleigh phase_t against the closed form written out in this test
  !> (agreement to rounding), its normalisation and the exactness of its sampler: F(mu(u)) = u
  !> with F(mu) = (1 + a mu + b mu^3/3)/2 (a few roundings of mu times P/2 <= 0.6: 2e-15).
  subroutine test_rayleigh_depol(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: rhos(3) = [0.0279_wp, 0.5_wp, 0.85_wp]
    real(wp), parameter :: mus(7) = [-1.0_wp, -0.6_wp, -0.1_wp, 0.0_wp, 0.25_wp, 0.9_wp, 1.0_wp]
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp) :: a, b, mu, u
    integer :: i, k
    character(len=40) :: label
    do k = 1, size(rhos)
      ph = new_phase_rayleigh_depol(rhos(k), err)
      call check(error, .not. allocated(err), 'new_phase_rayleigh_depol failed')
      if (allocated(error)) return
      call check(error, ph%kind == PHASE_RAYLEIGH, 'kind is not PHASE_RAYLEIGH')
      call check_close(error, ph%g, 0.0_wp, abs_tol=0.0_wp, label='g')
      call check_close(error, ph%depol, rhos(k), abs_tol=0.0_wp, label='depol')
      call depol_coefficients(rhos(k), a, b)
      do i = 1, size(mus)
        write (label, '(a, f0.4, a, f0.2)') 'rho = ', rhos(k), ', P at mu = ', mus(i)
        call check_close(error, phase_eval(ph, mus(i)), a + b*mus(i)**2, &
                         rel_tol=4.0_wp*epsilon(1.0_wp), label=trim(label))
      end do
      call check_close(error, norm_integral(ph, 200, 0), 1.0_wp, abs_tol=1.0e-12_wp, &
                       label='normalisation')
      call check_close(error, norm_integral(ph, 200, 1), 0.0_wp, abs_tol=1.0e-12_wp, &
                       label='first moment')
      do i = 0, 1000
        u = i/1000.0_wp
        mu = phase_sample_mu(ph, u)
        call check_close(error, 0.5_wp*(1.0_wp + a*mu + b*mu**3/3.0_wp), u, &
                         abs_tol=2.0e-15_wp, label='F(mu(u)) - u')
        if (allocated(error)) return
      end do
    end do
    ! P(0) = 3 (1 + 3 gamma)/(4 (1 + 2 gamma)) = 0.76032 for rho = 0.0279, not 3/4
    ph = new_phase_rayleigh_depol(0.0279_wp, err)
    call check_close(error, phase_eval(ph, 0.0_wp), 0.76032_wp, abs_tol=1.0e-5_wp, &
                     label='P(0), rho = 0.0279')
  end subroutine test_rayleigh_depol

  !> rho = 0 gives the plain Rayleigh phase_t: same evaluation and samples, bit for bit.
  subroutine test_rayleigh_depol_zero(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph0, ph
    real(wp) :: x
    integer :: i
    ph0 = new_phase_rayleigh()
    ph = new_phase_rayleigh_depol(0.0_wp, err)
    call check(error, .not. allocated(err), 'rho = 0 rejected')
    if (allocated(error)) return
    call check(error, ph%kind == ph0%kind, 'kind differs')
    call check_close(error, ph%depol, 0.0_wp, abs_tol=0.0_wp, label='depol')
    do i = 0, 997
      x = i/997.0_wp
      call check_close(error, phase_sample_mu(ph, x), rayleigh_sample_mu(x), abs_tol=0.0_wp, &
                       label='sample, rho = 0')
      call check_close(error, phase_sample_mu(ph0, x), rayleigh_sample_mu(x), abs_tol=0.0_wp, &
                       label='sample, plain')
      call check_close(error, phase_eval(ph, 2.0_wp*x - 1.0_wp), rayleigh_eval(2.0_wp*x - 1.0_wp), &
                       abs_tol=0.0_wp, label='P, rho = 0')
      if (allocated(error)) return
    end do
  end subroutine test_rayleigh_depol_zero

  !> rho outside [0, 6/7) or NaN is rejected with a message naming the value and the bound.
  subroutine test_rayleigh_depol_errors(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    ph = new_phase_rayleigh_depol(-0.01_wp, err)
    call expect_error(error, err, [character(len=48) :: 'new_phase_rayleigh_depol: ', &
                                   'depol = -0.01 must', '0 <= depol < 6/7'], 'rho = -0.01')
    call check(error, ph%kind == PHASE_ISOTROPIC, 'result on error')
    ph = new_phase_rayleigh_depol(6.0_wp/7.0_wp, err)
    call expect_error(error, err, [character(len=48) :: 'depol = 0.857', '0 <= depol < 6/7'], &
                      'rho = 6/7')
    ph = new_phase_rayleigh_depol(0.9_wp, err)
    call expect_error(error, err, [character(len=48) :: 'depol = 0.9 must'], 'rho = 0.9')
    ph = new_phase_rayleigh_depol(ieee_value(1.0_wp, ieee_quiet_nan), err)
    call expect_error(error, err, [character(len=48) :: 'depol = NaN must'], 'rho = NaN')
    ph = new_phase_rayleigh_depol(0.857_wp, err)
    call check(error, .not. allocated(err) .and. ph%kind == PHASE_RAYLEIGH, &
               'rho = 0.857 < 6/7 rejected')
  end subroutine test_rayleigh_depol_errors

  !> Samples of every kind lie in [-1, 1] at the extreme deviates.
  subroutine test_bounds(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: phs(7)
    real(wp) :: us(4), mu, tol
    integer :: i, k
    us = [0.0_wp, epsilon(1.0_wp), 1.0_wp - epsilon(1.0_wp)/2.0_wp, 1.0_wp]
    phs(1) = new_phase_isotropic()
    phs(2) = new_phase_rayleigh()
    phs(3) = new_phase_hg(0.999_wp, err)
    phs(4) = new_phase_hg(-0.999_wp, err)
    phs(5) = phase_from_table([0.0_wp, 1.0_wp, 180.0_wp], [1.0e4_wp, 1.0_wp, 0.5_wp], 50, err)
    call check(error, .not. allocated(err), 'constructor failed')
    phs(6) = new_phase_rayleigh_depol(0.5_wp, err)
    call check(error, .not. allocated(err), 'constructor failed')
    phs(7) = phase_from_legendre([(0.9_wp**k, k=0, 200)], 50, err)
    call check(error, .not. allocated(err), 'constructor failed')
    do k = 1, size(phs)
      do i = 1, size(us)
        mu = phase_sample_mu(phs(k), us(i))
        call check(error, mu >= -1.0_wp .and. mu <= 1.0_wp, 'sample outside [-1, 1]')
      end do
      ! exact end points, except the depolarised Rayleigh sampler (hyperbolic Cardano
      ! formula, kumo_rayleigh), which reaches +-1 to one rounding
      tol = 0.0_wp
      if (k == 6) tol = epsilon(1.0_wp)
      call check_close(error, phase_sample_mu(phs(k), 0.0_wp), -1.0_wp, abs_tol=tol, &
                       label='mu(u = 0)')
      call check_close(error, phase_sample_mu(phs(k), 1.0_wp), 1.0_wp, abs_tol=tol, &
                       label='mu(u = 1)')
    end do
  end subroutine test_bounds
  !> Forward-peaked HG g = 0.95 tabulated on 0.1 deg steps to 10 deg and on 1 deg steps beyond
  !> (steep narrow log-linear intervals and wide ones) against the brute-force Simpson
  !> reference. Tolerance 1e-10: Simpson's error per panel of width h is (h^5/2880) max|f''''|
  !> with f = P sin; on a log-linear cell |f''''| <= (|b| + 1)^4 P, b = d ln P/dtheta, at most
  !> 1.5 sqrt(g)/(1 - g) = 29 rad^-1 for this HG, so with 64 panels per cell (h <= 2.7e-4 rad)
  !> the relative error of T and g is below 1e-13; rounding in the 2e4 panel sums adds ~1e-13.
  subroutine test_brute_hg_peak(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: g = 0.95_wp
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp), allocatable :: angle(:), value(:)
    integer :: i
    angle = [[(0.1_wp*i, i=0, 99)], [(1.0_wp*i, i=10, 180)]]
    value = 7.0_wp*hg_eval(g, cos(angle*DEG2RAD))
    ph = phase_from_table(angle, value, PHASE_N_INV_DEFAULT, err)
    call check(error, .not. allocated(err), 'phase_from_table failed')
    if (allocated(error)) return
    call check_brute_force(error, 'HG 0.95', angle*DEG2RAD, value, ph, 64, 7, 1.0e-10_wp)
  end subroutine test_brute_hg_peak

  !> A table with zero values (linear pieces next to them, a zero range inside, P(0) = 0) and
  !> constant and log-linear cells of 10 to 60 deg, against the brute-force Simpson reference
  !> of `test_brute_hg_peak`. On the linear cells |f''''| of (a + c t) sin t is at most
  !> |a + c t| + 4 |c|; on the log-linear cells |b| <= ln 4/(10 deg) = 8 rad^-1; with 2000
  !> panels per cell (h <= 5.2e-4 rad) Simpson's relative error is below 1e-15: tolerance 1e-10
  !> as there.
  subroutine test_brute_zeros(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp), parameter :: angle(9) = [0.0_wp, 5.0_wp, 30.0_wp, 90.0_wp, 100.0_wp, 120.0_wp, &
                                       150.0_wp, 160.0_wp, 180.0_wp]
    real(wp), parameter :: value(9) = [0.0_wp, 3.0_wp, 1.0_wp, 0.0_wp, 0.0_wp, 0.5_wp, &
                                       0.5_wp, 2.0_wp, 0.5_wp]
    ph = phase_from_table(angle, value, 5000, err)
    call check(error, .not. allocated(err), 'phase_from_table failed')
    if (allocated(error)) return
    call check_brute_force(error, 'zeros', angle*DEG2RAD, value, ph, 2000, 3, 1.0e-10_wp)
  end subroutine test_brute_zeros

  !> The 490-term series of `les_stcu_w213.prp` (cloud droplets at 2.13 um, I3RC): the angles
  !> of the built table (ph%theta_tab) carry the series summed here independently (upward
  !> Legendre recurrence, negative sums set to 0), and the construction is compared with the
  !> brute-force Simpson reference of that table. Tolerance 1e-10: on the 2537-angle grid
  !> (steps 180/(16*490) deg = 4e-4 rad near 0) the forward peak has |b| < 300 rad^-1, so with
  !> 8 panels per cell (h <= 5e-5 rad, |b| h <= 0.015) Simpson's relative error per cell is
  !> below (|b| h)^4/2880 ~ 2e-11, far less where |b| is smaller; the two series sums differ
  !> by rounding (~1e-14 relative).
  subroutine test_brute_prp(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    character(len=:), allocatable :: path
    character(len=512) :: line
    real(wp), allocatable :: a(:), chi(:), t(:), v(:), p_prev(:), p_cur(:), p_next(:), x(:)
    integer :: unit, stat, nphase, ip, nleg, l, n
    path = c1_path()
    call check(error, len(path) > 0, 'no path of C.1_PF on the command line (CTest passes '// &
               '${KUMO_SHARED_DIR}/data/i3rc/phase1_inputs/C.1_PF)')
    if (allocated(error)) return
    path = path(1:index(path, '/phase1_inputs/', back=.true.))//'les_examples/les_stcu_w213.prp'
    open (newunit=unit, file=path, status='old', action='read', iostat=stat)
    call check(error, stat == 0, 'cannot open '//path)
    if (allocated(error)) return
    ! title, grid size, grid spacing and levels, the number of phase functions, then each as
    ! nleg and (2l+1) chi_l, l = 1 ... nleg (SHDOM's tabulated property format); the last one
    ! has 490 terms
    read (unit, '(a)', iostat=stat) line
    if (stat == 0) read (unit, '(a)', iostat=stat) line
    if (stat == 0) read (unit, '(a)', iostat=stat) line
    if (stat == 0) read (unit, *, iostat=stat) nphase
    nleg = 0
    do ip = 1, nphase
      if (stat /= 0) exit
      read (unit, *, iostat=stat) nleg
      if (stat /= 0) exit
      backspace (unit)
      if (allocated(a)) deallocate (a)
      allocate (a(nleg))
      read (unit, *, iostat=stat) nleg, a
    end do
    close (unit)
    call check(error, stat == 0 .and. nleg == 490, 'cannot read the 490-term series of '//path)
    if (allocated(error)) return
    allocate (chi(0:nleg))
    chi(0) = 1.0_wp
    chi(1:) = [(a(l)/real(2*l + 1, wp), l=1, nleg)]
    ph = phase_from_legendre(chi, PHASE_N_INV_DEFAULT, err)
    call check(error, .not. allocated(err), 'phase_from_legendre failed')
    if (allocated(error)) return
    call check(error, ph%kind == PHASE_TABLE, 'the series did not give a table')
    if (allocated(error)) return
    n = size(ph%theta_tab)
    t = ph%theta_tab(n:1:-1)          ! ascending, 0 ... pi
    x = cos(t)
    p_prev = [(1.0_wp, l=1, n)]
    p_cur = x
    v = 1.0_wp + 3.0_wp*chi(1)*x
    do l = 1, nleg - 1
      p_next = (real(2*l + 1, wp)*x*p_cur - real(l, wp)*p_prev)/real(l + 1, wp)
      v = v + real(2*l + 3, wp)*chi(l + 1)*p_next
      p_prev = p_cur
      p_cur = p_next
    end do
    v = max(v, 0.0_wp)
    call check_brute_force(error, 'prp 490 terms', t, v, ph, 8, 11, 1.0e-10_wp)
  end subroutine test_brute_prp

  !> `phase_eval` finds a table's interval from a guide of angle bins: on a table with angles
  !> 1e-3 deg apart near the forward direction and 7 deg apart elsewhere (many nodes per bin and
  !> many bins per interval), at every node, just beside it and at 2e5 spread cosines, its value
  !> is the interpolant of the interval found by a plain scan (the largest i <= n - 1 with
  !> mu_tab(i) <= mu).
  subroutine test_search_guide(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: n_fine = 2001, n_coarse = 25
    type(error_t), allocatable :: err
    type(phase_t) :: ph
    real(wp), allocatable :: angle(:), value(:), mus(:)
    integer :: i, n, n_bad
    angle = [(1.0e-3_wp*i, i=0, n_fine - 1), (2.0_wp + 7.0_wp*i, i=1, n_coarse)]
    angle(size(angle)) = 180.0_wp
    value = hg_eval(0.9_wp, cos(angle*DEG2RAD)) + 0.01_wp*angle
    ph = phase_from_table(angle, value, error=err)
    call check(error, .not. allocated(err), 'phase_from_table failed')
    if (allocated(error)) return
    n = size(ph%mu_tab)
    mus = [ph%mu_tab, (nearest(ph%mu_tab(i), 1.0_wp), i=1, n - 1), &
           (nearest(ph%mu_tab(i), -1.0_wp), i=2, n), (cos(PI*(i + 0.5_wp)/2.0e5_wp), i=0, 199999), &
           (1.0_wp - 1.0e-10_wp*i, i=0, 999)]
    n_bad = 0
    do i = 1, size(mus)
      if (abs(phase_eval(ph, mus(i)) - scanned(mus(i))) > 1.0e-13_wp*scanned(mus(i))) n_bad = n_bad + 1
    end do
    call check(error, n_bad == 0, str(n_bad)//' of '//str(size(mus))//' cosines differ from the '// &
               'interpolant of the scanned interval')
  contains
    real(wp) function scanned(mu) result(p)
      real(wp), intent(in) :: mu
      real(wp) :: f
      integer :: lo
      lo = 1
      do while (lo < n - 1)
        if (ph%mu_tab(lo + 1) > mu) exit
        lo = lo + 1
      end do
      f = min(1.0_wp, max(0.0_wp, (acos(mu) - ph%theta_tab(lo))*ph%inv_dth(lo)))
      p = exp(ph%lp_tab(lo) + f*(ph%lp_tab(lo + 1) - ph%lp_tab(lo)))
    end function scanned
  end subroutine test_search_guide
end module test_kumo_phase

program test_phase
  use test_kumo_phase, only: collect_phase
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_phase', collect_phase(), n_failed)
  if (n_failed > 0) error stop 1
end program test_phase
