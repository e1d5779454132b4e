! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_expint and kumo_thermal_column (exact non-scattering thermal columns).
!>
!> References:
!> * E_n(x): Abramowitz and Stegun (1964), Tables 5.1 and 5.4, here to 16 digits as given by
!>   the Cephes routine expn (scipy.special.expn), and quadrature of the defining integral
!>   E_n(x) = Int_0^1 mu^(n-2) exp(-x/mu) dmu written here;
!> * DISORT test problem 6 (Stamnes et al. 1988; DISOTEST v2.0 "correct answers", read from
!>   data/disort/disotest_v2.0beta_correct_answers.csv in the shared directory given as the first
!>   argument): no scattering, beam FBEAM = 200 at UMU0 = 0.5, increasingly complex sources.
!>   Cases a-c (beam, black or Lambert 0.5 surface) are compared in full; cases d-h have
!>   Hapke's bidirectional surface, which this column does not model, so only the quantities
!>   that do not depend on the surface are compared (direct and diffuse downward flux, downward
!>   intensities) plus the upward intensities above the surface computed from DISORT's own
!>   intensity leaving the surface in the same direction (this exercises the transmission and
!>   the linear-in-tau internal emission exactly). Planck values use DISORT's constants
!>   (sigma = 5.67032e-8, c2 = 1.438786 cm K), emulated as in test_planck.
!>   Tolerances: intensities and direct fluxes are exact in DISORT for a non-scattering medium,
!>   so they are compared to their printed 6 digits (half a unit of the last digit, relative
!>   3e-6 of the value plus 1e-6 of the largest value of the case, DISOTEST's own noise level).
!>   DISORT's diffuse fluxes and DFDT are sums over its 8 double-Gauss streams per hemisphere,
!>   not the exact exponential integrals: they are compared to 3e-5 relative (measured
!>   differences up to 1.3e-5, e.g. 6c FUP(0) 1.48450 vs exact 1.484518).
!> * Isothermal enclosure: every radiance B(T), every divergence 0.
!> * Internal consistency: fluxes from exponential integrals = Gauss-Legendre quadrature over mu
!>   of the closed-form radiances; energy: emitted = absorbed + escaped.
module test_kumo_thermal_column
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use kumo_kinds, only: wp
  use kumo_constants, only: PI, TWO_PI, STEFAN_BOLTZMANN
  use kumo_math, only: gauss_legendre01
  use kumo_planck, only: planck_band_wavenumber, PLANCK_C2, spectral_band_t, band_from_wavenumbers, &
                         band_radiance
  use kumo_expint, only: expint_e, expint_d, expint_divdiff
  use kumo_thermal_column, only: thermal_column_t, thermal_column_init, thermal_column_from_temperatures, &
                                 thermal_column_fluxes, thermal_column_radiance, &
                                 thermal_column_init_layers, thermal_column_fluxes_diffusivity
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_error_words
  implicit none
  private
  public :: collect_thermal_column, set_shared_dir

  character(len=:), allocatable :: shared_dir

  !> One DISOTEST answer.
  type :: answer_t
    character(len=1) :: case = ' '
    character(len=3) :: quantity = ' '
    integer :: itau = 0, imu = 0, iphi = 0
    real(wp) :: value = 0.0_wp
  end type answer_t

contains

  subroutine set_shared_dir(dir)
    character(len=*), intent(in) :: dir
    shared_dir = dir
  end subroutine set_shared_dir

  !> All tests of this suite.
  function collect_thermal_column() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('expint_table_values', test_expint_table), &
             new_unittest('expint_quadrature_and_limits', test_expint_quadrature), &
             new_unittest('disort_problem_6', test_disort6), &
             new_unittest('isothermal_enclosure', test_isothermal), &
             new_unittest('fluxes_equal_angular_integrals', test_consistency), &
             new_unittest('energy_closure', test_energy), &
             new_unittest('thin_and_thick_limits', test_limits), &
             new_unittest('diffusivity_fluxes', test_diffusivity), &
             new_unittest('bad_inputs', test_bad_inputs)]
  end function collect_thermal_column

  ! -----------------------------------------------------------------------------------------
  ! Exponential integrals
  ! -----------------------------------------------------------------------------------------

  subroutine test_expint_table(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: x(8) = [1.0e-3_wp, 0.1_wp, 0.5_wp, 1.0_wp, 2.0_wp, 5.0_wp, 10.0_wp, 50.0_wp]
    real(wp) :: ref(8, 4)
    integer :: n, j
    ref(:, 1) = [6.3315393641361490e+00_wp, 1.8229239584193906e+00_wp, 5.5977359477616084e-01_wp, &
                 2.1938393439552051e-01_wp, 4.8900510708061146e-02_wp, 1.1482955912753255e-03_wp, &
                 4.1569689296853246e-06_wp, 3.7832640295504591e-24_wp]
    ref(:, 2) = [9.9266896046923891e-01_wp, 7.2254502219402039e-01_wp, 3.2664386232455322e-01_wp, &
                 1.4849550677592194e-01_wp, 3.7534261820490467e-02_wp, 9.9646904270883781e-04_wp, &
                 3.8302404656316095e-06_wp, 3.7117833188688280e-24_wp]
    ref(:, 3) = [4.9900391543645289e-01_wp, 4.1629145790827882e-01_wp, 2.2160436427517846e-01_wp, &
                 1.0969196719776020e-01_wp, 3.0133379797815909e-02_wp, 8.7780089277063875e-04_wp, &
                 3.5487625530843821e-06_wp, 3.6429094264752051e-24_wp]
    ref(:, 4) = [3.3283383197264615e-01_wp, 2.8773609074837719e-01_wp, 1.6524282585834807e-01_wp, &
                 8.6062491324560730e-02_wp, 2.5022841213660316e-02_wp, 7.8298084507742532e-04_wp, &
                 3.3041014105470102e-06_wp, 3.5765044908771762e-24_wp]
    do n = 1, 4
      do j = 1, size(x)
        call check_close(error, expint_e(n, x(j)), ref(j, n), rel_tol=5.0e-15_wp, &
                         label='E'//achar(48 + n)//'('//fmt(x(j))//')')
      end do
    end do
    call check_close(error, expint_e(3, 0.0_wp), 0.5_wp, rel_tol=1.0e-15_wp, label='E3(0)')
    call check_close(error, expint_e(2, 0.0_wp), 1.0_wp, rel_tol=1.0e-15_wp, label='E2(0)')
  end subroutine test_expint_table

  !> E_n against the defining integral; 1/(n-1) - E_n at small x against its leading terms;
  !> divided differences against differences and their limit.
  subroutine test_expint_quadrature(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: x(6) = [0.02_wp, 0.3_wp, 0.99_wp, 1.01_wp, 3.7_wp, 20.0_wp]
    integer, parameter :: NG = 20, NP = 400
    real(wp) :: xg(NG), wg(NG), s, mu, x0, expected
    integer :: n, j, ip, i
    call gauss_legendre01(NG, xg, wg)
    do n = 2, 6
      do j = 1, size(x)
        s = 0.0_wp
        do ip = 1, NP
          do i = 1, NG
            mu = (ip - 1 + xg(i))/NP
            s = s + wg(i)*mu**(n - 2)*exp(-x(j)/mu)
          end do
        end do
        s = s/NP
        call check_close(error, expint_e(n, x(j)), s, rel_tol=1.0e-12_wp, label='E'//achar(48 + n)//' quadrature')
      end do
    end do
    ! D_3(x) = x - (x^2/2)(psi(3) - ln x) - x^3/6 + ..., psi(3) = 3/2 - gamma.
    x0 = 1.0e-8_wp
    expected = x0 - 0.5_wp*x0**2*(1.5_wp - 0.5772156649015329_wp - log(x0))
    call check_close(error, expint_d(3, x0), expected, rel_tol=1.0e-15_wp, label='D3(1e-8)')
    ! D_4(x) = x/2 - x^2/2 + ...
    call check_close(error, expint_d(4, x0), 0.5_wp*x0 - 0.5_wp*x0**2, rel_tol=1.0e-15_wp, label='D4(1e-8)')
    ! Divided differences.
    call check_close(error, expint_divdiff(4, 0.7_wp, 0.3_wp), (expint_e(4, 0.7_wp) - expint_e(4, 1.0_wp))/0.3_wp, &
                     rel_tol=1.0e-14_wp, label='divdiff direct')
    call check_close(error, expint_divdiff(4, 0.7_wp, 0.0_wp), expint_e(3, 0.7_wp), rel_tol=1.0e-15_wp, &
                     label='divdiff limit')
    call check_close(error, expint_divdiff(3, 0.0_wp, 1.0e-9_wp), 1.0_wp, rel_tol=1.0e-7_wp, label='divdiff at 0')
    ! Small a and tau (series difference) and a >> tau (quadrature) against a 2000-point
    ! midpoint rule of Int_0^1 E_{n-1}(a + tau s) ds (its error ~1e-8 of the curvature term).
    call check_close(error, expint_divdiff(3, 2.0e-6_wp, 5.0e-6_wp), midpoint_e(2, 2.0e-6_wp, 5.0e-6_wp), &
                     rel_tol=1.0e-9_wp, label='divdiff small a')
    call check_close(error, expint_divdiff(4, 3.0e-3_wp, 5.0e-6_wp), midpoint_e(3, 3.0e-3_wp, 5.0e-6_wp), &
                     rel_tol=1.0e-12_wp, label='divdiff a >> tau')
    ! Just below the switch tau = 1e-4 (quadrature) against the difference (good to 1e-12 here).
    call check_close(error, expint_divdiff(4, 0.2_wp, 0.99999e-4_wp), &
                     (expint_e(4, 0.2_wp) - expint_e(4, 0.2_wp + 0.99999e-4_wp))/0.99999e-4_wp, &
                     rel_tol=1.0e-11_wp, label='divdiff switch')
    call check_close(error, expint_divdiff(3, 0.0_wp, 0.99999e-4_wp), expint_d(3, 0.99999e-4_wp)/0.99999e-4_wp, &
                     rel_tol=1.0e-11_wp, label='divdiff switch at 0')
  end subroutine test_expint_quadrature

  !> Midpoint rule for Int_0^1 E_n(a + tau s) ds with 2000 points.
  function midpoint_e(n, a, tau) result(q)
    integer, intent(in) :: n
    real(wp), intent(in) :: a, tau
    real(wp) :: q
    integer :: i
    q = 0.0_wp
    do i = 1, 2000
      q = q + expint_e(n, a + tau*(i - 0.5_wp)/2000.0_wp)
    end do
    q = q/2000.0_wp
  end function midpoint_e

  ! -----------------------------------------------------------------------------------------
  ! DISORT problem 6
  ! -----------------------------------------------------------------------------------------

  !> Band Planck radiance 0-50000 cm-1 with DISORT's constants (see test_planck).
  function b_disort(t) result(b)
    real(wp), intent(in) :: t
    real(wp) :: b
    real(wp), parameter :: C2_D = 1.438786e-2_wp, SIGMA_D = 5.67032e-8_wp
    b = planck_band_wavenumber(0.0_wp, 50000.0_wp, t*PLANCK_C2/C2_D)*(SIGMA_D/STEFAN_BOLTZMANN)*(C2_D/PLANCK_C2)**4
  end function b_disort

  !> Read the answers of one problem from the DISOTEST csv.
  subroutine read_answers(problem, answers, error)
    integer, intent(in) :: problem
    type(answer_t), allocatable, intent(out) :: answers(:)
    type(error_t), allocatable, intent(out) :: error
    character(len=256) :: line
    character(len=:), allocatable :: path
    character(len=32) :: fields(7)
    type(answer_t) :: a
    integer :: unit, ios, p, i, start, prob
    path = shared_dir//'/data/disort/disotest_v2.0beta_correct_answers.csv'
    open (newunit=unit, file=path, status='old', action='read', iostat=ios)
    if (ios /= 0) then
      call check(error, .false., 'cannot open '//path)
      return
    end if
    allocate (answers(0))
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (line(1:1) == '#' .or. len_trim(line) == 0 .or. line(1:7) == 'problem') cycle
      fields = ' '
      start = 1
      i = 1
      do p = 1, len_trim(line) + 1
        if (p > len_trim(line) .or. line(p:p) == ',') then
          fields(i) = line(start:p - 1)
          i = i + 1
          start = p + 1
          if (i > 7) exit
        end if
      end do
      read (fields(1), *) prob
      if (prob /= problem) cycle
      a%case = fields(2)(1:1)
      a%quantity = fields(3)(1:3)
      a%itau = 0; a%imu = 0; a%iphi = 0
      read (fields(4), *) a%itau
      if (len_trim(fields(5)) > 0) read (fields(5), *) a%imu
      if (len_trim(fields(6)) > 0) read (fields(6), *) a%iphi
      read (fields(7), *) a%value
      answers = [answers, a]
    end do
    close (unit)
    call check(error, size(answers) > 0, 'no answers for problem '//fmt(real(problem, wp))//' in '//path)
  end subroutine read_answers

  !> DISORT problem 6: all flux and intensity values that a Lambert/emissivity column expresses.
  subroutine test_disort6(error)
    type(error_t), allocatable, intent(out) :: error
    type(answer_t), allocatable :: ans(:)
    real(wp), parameter :: umu(4) = [-1.0_wp, -0.1_wp, 0.1_wp, 1.0_wp]
    character(len=1), parameter :: cases(8) = ['a', 'b', 'c', 'd', 'e', 'f', 'g', 'h']
    type(thermal_column_t) :: col
    type(error_t), allocatable :: err
    real(wp) :: dtau, utau_mid, b_top, b_bot, b_mid, albedo, fisot, ttemp_b, btemp_b, vmax, tol
    real(wp) :: fu(0:2), fd(0:2), fdir(0:2), div(0:2), net(2), value, i_sfc
    logical :: lambert
    integer :: ic, j, lev, n_checked
    call read_answers(6, ans, error)
    if (allocated(error)) return
    n_checked = 0
    do ic = 1, size(cases)
      ! Inputs of DISOTEST problem 6, case ic.
      dtau = 1.0_wp
      utau_mid = 0.5_wp
      if (ic == 1) dtau = 0.0_wp
      if (ic == 1) utau_mid = 0.0_wp
      if (ic == 8) dtau = 10.0_wp
      if (ic == 8) utau_mid = 1.0_wp
      albedo = 0.0_wp
      if (ic == 3) albedo = 0.5_wp
      lambert = ic <= 3
      fisot = 0.0_wp
      if (ic >= 6) fisot = 100.0_wp/PI
      ttemp_b = 0.0_wp
      if (ic >= 6) ttemp_b = b_disort(250.0_wp)
      btemp_b = 0.0_wp
      if (ic >= 5) btemp_b = b_disort(300.0_wp)
      b_top = 0.0_wp
      b_bot = 0.0_wp
      if (ic >= 7) b_top = b_disort(250.0_wp)
      if (ic >= 7) b_bot = b_disort(300.0_wp)
      ! B linear in tau from the top: split the layer at utau_mid.
      b_mid = b_top
      if (dtau > 0.0_wp) b_mid = b_top + (b_bot - b_top)*utau_mid/dtau
      call thermal_column_init(col, [dtau - utau_mid, utau_mid], [b_bot, b_mid, b_top], 1.0_wp - albedo, btemp_b, &
                               fisot + ttemp_b, err, beam_flux=200.0_wp, beam_mu0=0.5_wp)
      call check(error, .not. allocated(err), 'column init failed')
      if (allocated(error)) return
      call thermal_column_fluxes(col, fu, fd, fdir, div, net)
      vmax = maxval(abs(pack(ans%value, ans%case == cases(ic))))
      do j = 1, size(ans)
        if (ans(j)%case /= cases(ic)) cycle
        lev = 3 - ans(j)%itau        ! DISORT itau 1..3 from the top = kumo level 2..0
        tol = 3.0e-6_wp*abs(ans(j)%value) + 1.0e-6_wp*vmax
        select case (ans(j)%quantity)
        case ('FIR')
          value = fdir(lev)
        case ('FDN')
          value = fd(lev)
          tol = 3.0e-5_wp*abs(ans(j)%value) + 1.0e-6_wp*vmax
        case ('FUP')
          if (.not. lambert) cycle
          value = fu(lev)
          tol = 3.0e-5_wp*abs(ans(j)%value) + 1.0e-6_wp*vmax
        case ('DFD')
          if (.not. lambert) cycle
          value = div(lev)
          tol = 3.0e-5_wp*abs(ans(j)%value) + 1.0e-6_wp*vmax
        case ('UU')
          if (umu(ans(j)%imu) > 0.0_wp .and. .not. lambert) then
            if (lev == 0) cycle
            i_sfc = answer_of(ans, cases(ic), 'UU', 3, ans(j)%imu)
            value = thermal_column_radiance(col, lev, umu(ans(j)%imu), i_surface=i_sfc)
          else
            value = thermal_column_radiance(col, lev, umu(ans(j)%imu))
          end if
        case default
          cycle
        end select
        call check_close(error, value, ans(j)%value, abs_tol=tol, &
                         label='DISORT 6'//cases(ic)//' '//trim(ans(j)%quantity)//' itau='//fmt(real(ans(j)%itau, wp)) &
                         //' imu='//fmt(real(ans(j)%imu, wp)))
        n_checked = n_checked + 1
      end do
      if (allocated(error)) return
    end do
    ! 8 + 7 x 12 intensities and 2 x 4 + 7 x 12 fluxes exist; the Hapke cases d-h skip FUP, DFD
    ! (5 x 6) and the upward intensities at the surface (5 x 2).
    call check(error, n_checked == 8 + 8 + 7*12 + 7*12 - 5*6 - 5*2, 'DISORT 6: '//fmt(real(n_checked, wp)) &
               //' values compared')
  end subroutine test_disort6

  !> The value of one DISOTEST answer.
  function answer_of(ans, case, quantity, itau, imu) result(v)
    type(answer_t), intent(in) :: ans(:)
    character(len=*), intent(in) :: case, quantity
    integer, intent(in) :: itau, imu
    real(wp) :: v
    integer :: j
    v = -huge(1.0_wp)
    do j = 1, size(ans)
      if (ans(j)%case == case .and. ans(j)%quantity == quantity .and. ans(j)%itau == itau &
          .and. ans(j)%imu == imu) v = ans(j)%value
    end do
  end function answer_of

  ! -----------------------------------------------------------------------------------------
  ! Physical checks
  ! -----------------------------------------------------------------------------------------

  !> Isothermal column (any optical depths, thin and very thick), black surface at the same
  !> temperature, sky B(T): I = B in every direction, F = pi B, zero divergence.
  subroutine test_isothermal(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: tau(6) = [1.0e-9_wp, 0.3_wp, 50.0_wp, 2.0e-5_wp, 1.0e3_wp, 0.0_wp]
    real(wp), parameter :: mus(6) = [-1.0_wp, -0.3_wp, -0.01_wp, 0.01_wp, 0.5_wp, 1.0_wp]
    type(thermal_column_t) :: col
    type(error_t), allocatable :: err
    type(spectral_band_t) :: band
    real(wp) :: fu(0:6), fd(0:6), fdir(0:6), div(0:6), net(6), b
    integer :: i, j
    call band_from_wavenumbers(540.0_wp, 800.0_wp, band, err)
    b = band_radiance(band, 265.0_wp)
    call thermal_column_from_temperatures(col, tau, spread(265.0_wp, 1, 7), 265.0_wp, 1.0_wp, band, err, i_top=b)
    call check(error, .not. allocated(err), 'column init failed')
    if (allocated(error)) return
    call thermal_column_fluxes(col, fu, fd, fdir, div, net)
    do i = 0, 6
      call check_close(error, fu(i), PI*b, rel_tol=1.0e-14_wp, label='F_up')
      call check_close(error, fd(i), PI*b, rel_tol=1.0e-14_wp, label='F_down')
      call check_close(error, div(i), 0.0_wp, abs_tol=1.0e-14_wp*b, label='divergence')
      do j = 1, size(mus)
        call check_close(error, thermal_column_radiance(col, i, mus(j)), b, rel_tol=1.0e-14_wp, label='I')
      end do
    end do
    do i = 1, 6
      call check_close(error, net(i), 0.0_wp, abs_tol=1.0e-14_wp*b, label='layer net')
    end do
    ! Grey surface (emissivity 0.3) at the same temperature: still an enclosure.
    call thermal_column_from_temperatures(col, tau, spread(265.0_wp, 1, 7), 265.0_wp, 0.3_wp, band, err, i_top=b)
    call thermal_column_fluxes(col, fu, fd, fdir, div, net)
    call check_close(error, fu(6), PI*b, rel_tol=1.0e-14_wp, label='F_up grey surface')
    call check_close(error, thermal_column_radiance(col, 3, 0.2_wp), b, rel_tol=1.0e-14_wp, label='I grey surface')
  end subroutine test_isothermal

  !> Fluxes and divergences from exponential integrals equal the mu-integrals of the radiances
  !> (Gauss-Legendre on panels spaced geometrically from mu = 1e-12 to 1, which resolves the
  !> scale mu ~ tau of the 1e-6 layer).
  subroutine test_consistency(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: NG = 20, NP = 240
    real(wp), parameter :: tau(4) = [2.5_wp, 0.04_wp, 0.7_wp, 1.0e-6_wp]
    real(wp), parameter :: b(0:4) = [120.0_wp, 95.0_wp, 80.0_wp, 60.0_wp, 70.0_wp]  ! an inversion at the top
    type(thermal_column_t) :: col
    type(error_t), allocatable :: err
    real(wp) :: xg(NG), wg(NG), fu(0:4), fd(0:4), fdir(0:4), div(0:4), net(4), su, sd, sj, mu, iu, id
    real(wp) :: lo, hi, w
    integer :: i, ip, k
    call gauss_legendre01(NG, xg, wg)
    call thermal_column_init(col, tau, b, 0.8_wp, 130.0_wp, 15.0_wp, err, beam_flux=50.0_wp, beam_mu0=0.6_wp)
    call check(error, .not. allocated(err), 'column init failed')
    if (allocated(error)) return
    call thermal_column_fluxes(col, fu, fd, fdir, div, net)
    do i = 0, 4
      su = 0.0_wp; sd = 0.0_wp; sj = 0.0_wp
      do ip = 0, NP
        lo = 0.0_wp
        if (ip > 0) lo = 10.0_wp**(-12.0_wp + 12.0_wp*(ip - 1)/NP)
        hi = 10.0_wp**(-12.0_wp + 12.0_wp*ip/NP)
        do k = 1, NG
          mu = lo + (hi - lo)*xg(k)
          w = wg(k)*(hi - lo)
          iu = thermal_column_radiance(col, i, mu)
          id = thermal_column_radiance(col, i, -mu)
          su = su + w*mu*iu
          sd = sd + w*mu*id
          sj = sj + w*(iu + id)
        end do
      end do
      call check_close(error, fu(i), TWO_PI*su, rel_tol=1.0e-12_wp, label='F_up level '//fmt(real(i, wp)))
      call check_close(error, fd(i), TWO_PI*sd, rel_tol=1.0e-12_wp, label='F_down level '//fmt(real(i, wp)))
      call check_close(error, div(i), TWO_PI*sj + fdir(i)/0.6_wp - 4.0_wp*PI*b(i), &
                       abs_tol=1.0e-9_wp*4.0_wp*PI*b(i), label='divergence level '//fmt(real(i, wp)))
    end do
    ! Surface: Lambert reflection of 20 % of the incident flux plus emission 0.8 B_s.
    call check_close(error, fu(0), 0.8_wp*PI*130.0_wp + 0.2_wp*(fd(0) + fdir(0)), rel_tol=1.0e-14_wp, &
                     label='surface balance')
  end subroutine test_consistency

  !> Sum of layer absorption-minus-emission + surface absorption - surface emission + escape
  !> at the top - incoming at the top = 0.
  subroutine test_energy(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: tau(5) = [0.1_wp, 3.0_wp, 0.02_wp, 12.0_wp, 0.5_wp]
    real(wp), parameter :: b(0:5) = [100.0_wp, 90.0_wp, 85.0_wp, 40.0_wp, 50.0_wp, 20.0_wp]
    type(thermal_column_t) :: col
    type(error_t), allocatable :: err
    real(wp) :: fu(0:5), fd(0:5), fdir(0:5), div(0:5), net(5), surface_net
    call thermal_column_init(col, tau, b, 0.9_wp, 110.0_wp, 3.0_wp, err, beam_flux=10.0_wp, beam_mu0=0.3_wp)
    call thermal_column_fluxes(col, fu, fd, fdir, div, net)
    surface_net = fd(0) + fdir(0) - fu(0)
    call check_close(error, sum(net) + surface_net, fd(5) + fdir(5) - fu(5), rel_tol=1.0e-13_wp, &
                     label='energy closure')
    ! The thick cold layer 4 (tau 12, B 40..50 between warm neighbours) is warmed, the top layer
    ! (B 50 -> 20 under a sky of 3) cools.
    call check(error, net(4) > 0.0_wp .and. net(5) < 0.0_wp, 'signs of the layer budgets')
  end subroutine test_energy

  !> The diffusivity approximation (thermal_column_fluxes_diffusivity, D = 1.66): exact for an
  !> isothermal enclosure (jumps at the levels between equal values included) and for the top of
  !> an opaque column; within a few per cent of the exact fluxes on a column with thin and thick
  !> layers, level jumps, a grey surface and a sky; its thin-layer emission is D/2 of the exact.
  subroutine test_diffusivity(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: tau(7) = [1.0e-9_wp, 0.3_wp, 50.0_wp, 2.0e-5_wp, 0.05_wp, 2.0_wp, 0.0_wp]
    real(wp), parameter :: bb(7) = [120.0_wp, 110.0_wp, 95.0_wp, 70.0_wp, 66.0_wp, 60.0_wp, 40.0_wp]
    real(wp), parameter :: bt(7) = [112.0_wp, 96.0_wp, 72.0_wp, 67.0_wp, 61.0_wp, 42.0_wp, 40.0_wp]
    type(thermal_column_t) :: col
    type(error_t), allocatable :: err
    real(wp) :: fu(0:7), fd(0:7), fdir(0:7), net(7), au(0:7), ad(0:7), anet(7)
    real(wp) :: fu1(0:1), fd1(0:1), net1(1)
    integer :: i
    ! isothermal enclosure: every flux pi B, every layer budget zero
    call thermal_column_init_layers(col, tau, spread(80.0_wp, 1, 7), spread(80.0_wp, 1, 7), 0.4_wp, &
                                    80.0_wp, 80.0_wp, err)
    call check(error, .not. allocated(err), 'column init failed')
    if (allocated(error)) return
    call thermal_column_fluxes_diffusivity(col, au, ad, anet)
    do i = 0, 7
      call check_close(error, au(i), PI*80.0_wp, rel_tol=1.0e-14_wp, label='isothermal F_up')
      call check_close(error, ad(i), PI*80.0_wp, rel_tol=1.0e-14_wp, label='isothermal F_down')
    end do
    call check(error, all(abs(anet) <= 1.0e-12_wp*PI*80.0_wp), 'isothermal layer budgets not zero')
    if (allocated(error)) return
    ! against the exact column
    call thermal_column_init_layers(col, tau, bb, bt, 0.85_wp, 125.0_wp, 10.0_wp, err)
    call thermal_column_fluxes(col, fu, fd, fdir, layer_net=net)
    call thermal_column_fluxes_diffusivity(col, au, ad, anet)
    do i = 0, 7
      call check_close(error, au(i), fu(i), rel_tol=0.03_wp, label='F_up level '//fmt(real(i, wp)))
      call check_close(error, ad(i), fd(i), rel_tol=0.05_wp, label='F_down level '//fmt(real(i, wp)))
    end do
    ! the layer budgets within 20 % of the largest (thin layers emit D/2 = 0.83 of the exact)
    do i = 1, 7
      call check_close(error, anet(i), net(i), abs_tol=0.2_wp*maxval(abs(net)), &
                       label='layer budget '//fmt(real(i, wp)))
    end do
    ! energy: layers + surface + top
    call check_close(error, sum(anet) + ad(0) - au(0), ad(7) - au(7), rel_tol=1.0e-13_wp, &
                     label='energy closure')
    ! an opaque layer: the top sees its top value, the surface nothing
    call thermal_column_init_layers(col, [800.0_wp], [300.0_wp], [100.0_wp], 1.0_wp, 1.0e6_wp, 0.0_wp, err)
    call thermal_column_fluxes_diffusivity(col, fu1, fd1, net1)
    call check_close(error, fu1(1), PI*100.0_wp, rel_tol=1.0e-2_wp, label='opaque layer F_up')
    call check_close(error, fd1(0), PI*300.0_wp, rel_tol=1.0e-2_wp, label='opaque layer F_down')
    ! a thin layer emits D tau pi B into each hemisphere
    call thermal_column_init_layers(col, [1.0e-7_wp], [100.0_wp], [100.0_wp], 1.0_wp, 0.0_wp, 0.0_wp, err)
    call thermal_column_fluxes_diffusivity(col, fu1, fd1, net1)
    call check_close(error, fu1(1), 1.66_wp*1.0e-7_wp*PI*100.0_wp, rel_tol=1.0e-6_wp, label='thin layer F_up')
  end subroutine test_diffusivity

  !> Optically thin layer: emission = 2 pi tau B(mean) * 2 (both hemispheres) to first order;
  !> very thick column: the top sees the top level only.
  subroutine test_limits(error)
    type(error_t), allocatable, intent(out) :: error
    type(thermal_column_t) :: col
    type(error_t), allocatable :: err
    real(wp) :: fu(0:1), fd(0:1), fdir(0:1), div(0:1), net(1)
    real(wp) :: fu2(0:2), fd2(0:2), fdir2(0:2), div2(0:2), net2(2)
    real(wp) :: fu3(0:2), fd3(0:2), fdir3(0:2), div3(0:2), net3(2)
    ! Thin layer, black cold surface, no sky: cooling = 2 pi B tau Int (1/mu) mu dmu x 2 = 4 pi tau B.
    call thermal_column_init(col, [1.0e-7_wp], [100.0_wp, 100.0_wp], 1.0_wp, 0.0_wp, 0.0_wp, err)
    call thermal_column_fluxes(col, fu, fd, fdir, div, net)
    call check_close(error, net(1), -4.0_wp*PI*1.0e-7_wp*100.0_wp, rel_tol=1.0e-5_wp, label='thin layer cooling')
    call check_close(error, fu(1), TWO_PI*1.0e-7_wp*100.0_wp, rel_tol=1.0e-5_wp, label='thin layer flux')
    ! Thick lower layer: nothing from the surface reaches the top.
    call thermal_column_init(col, [800.0_wp, 1.0_wp], [300.0_wp, 200.0_wp, 100.0_wp], 1.0_wp, 1.0e6_wp, 0.0_wp, err)
    call thermal_column_fluxes(col, fu2, fd2, fdir2, div2, net2)
    call check(error, ieee_finite_all([fu2, fd2, div2, net2]), 'non-finite values in a thick column')
    call thermal_column_init(col, [800.0_wp, 1.0_wp], [300.0_wp, 200.0_wp, 100.0_wp], 1.0_wp, 0.0_wp, 0.0_wp, err)
    call thermal_column_fluxes(col, fu3, fd3, fdir3, div3, net3)
    call check_close(error, fu2(2), fu3(2), rel_tol=1.0e-14_wp, label='surface hidden by tau 800')
    ! The layer budget is the difference of the net fluxes at its boundaries.
    call check_close(error, net2(1) + fd2(0) - fu2(0), fd2(1) - fu2(1), rel_tol=1.0e-12_wp, label='thick budget')
  end subroutine test_limits

  logical function ieee_finite_all(x) result(ok)
    real(wp), intent(in) :: x(:)
    ok = all(abs(x) < huge(1.0_wp))
  end function ieee_finite_all

  subroutine test_bad_inputs(error)
    type(error_t), allocatable, intent(out) :: error
    type(thermal_column_t) :: col
    type(error_t), allocatable :: err
    type(spectral_band_t) :: band
    real(wp) :: nan
    nan = ieee_value(1.0_wp, ieee_quiet_nan)
    call thermal_column_init(col, [1.0_wp, -2.0_wp], [1.0_wp, 1.0_wp, 1.0_wp], 1.0_wp, 1.0_wp, 0.0_wp, err)
    call check_error_words(error, err, ['tau(2)', '-2    '])
    call thermal_column_init(col, [1.0_wp, 2.0_wp], [1.0_wp, 1.0_wp], 1.0_wp, 1.0_wp, 0.0_wp, err)
    call check_error_words(error, err, ['2 level Planck values', '2 layers             ', 'expected 3           '])
    call thermal_column_init(col, [1.0_wp], [1.0_wp, 1.0_wp], 1.5_wp, 1.0_wp, 0.0_wp, err)
    call check_error_words(error, err, ['emissivity', '1.5       ', '[0, 1]    '])
    call thermal_column_init(col, [1.0_wp], [1.0_wp, 1.0_wp], nan, 1.0_wp, 0.0_wp, err)
    call check_error_words(error, err, ['emissivity', 'NaN       '])
    call thermal_column_init(col, [1.0_wp], [1.0_wp, nan], 1.0_wp, 1.0_wp, 0.0_wp, err)
    call check_error_words(error, err, ['level 1', 'NaN    '])
    call thermal_column_init(col, [1.0_wp], [1.0_wp, 1.0_wp], 1.0_wp, 1.0_wp, 0.0_wp, err, beam_mu0=0.0_wp)
    call check_error_words(error, err, ['mu0   ', '(0, 1]'])
    call band_from_wavenumbers(500.0_wp, 600.0_wp, band, err)
    call thermal_column_from_temperatures(col, [1.0_wp], [250.0_wp, -3.0_wp], 280.0_wp, 1.0_wp, band, err)
    call check_error_words(error, err, ['level temperature(2)', '-3                  '])
    call thermal_column_from_temperatures(col, [1.0_wp], [250.0_wp, 240.0_wp], nan, 1.0_wp, band, err)
    call check_error_words(error, err, ['surface temperature', 'NaN                '])
  end subroutine test_bad_inputs

  function fmt(x) result(s)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: s
    character(len=32) :: buf
    write (buf, '(g0.6)') x
    s = trim(adjustl(buf))
  end function fmt

end module test_kumo_thermal_column

program test_thermal_column
  use kumo_testing, only: run_unittests
  use test_kumo_thermal_column, only: collect_thermal_column, set_shared_dir
  implicit none
  integer :: n_failed
  character(len=4096) :: arg
  call get_command_argument(1, arg)
  call set_shared_dir(trim(arg))
  call run_unittests('thermal_column', collect_thermal_column(), n_failed)
  if (n_failed > 0) error stop 1
end program test_thermal_column
