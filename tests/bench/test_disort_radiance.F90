! SPDX-License-Identifier: BSD-3-Clause
!> Benchmark: kumo's radiances (local estimates at levels) against DISORT.
!>
!> Part 1, `reference/disort_pp.csv`: every one of the 102 plane-parallel cases (one isotropic
!> or Henyey-Greenstein g = 0.85 layer, or Rayleigh over HG, over a Lambert surface; layers
!> 1000 m thick, extinction tau/1000 m-1) is run with radiance detectors at every level of the
!> table (TOA, interface_1, BOA = kumo levels nz, 1, 0) in all 24 directions of the table
!> (mu in {+-1, +-0.8, +-0.5, +-0.2} x phi_rel in {0, 90, 180}; rad_phi_deg = phi0 + phi_rel
!> with phi0 = 0, both propagation azimuths) and every `pi_I_over_mu0F0` row is compared with
!> kumo's `radiance`, which is the same quantity (diffuse only, pi I/(mu0 F0)).
!>
!> Part 2, DISOTEST problem 5 (DISORT v2.0 "correct answers", `data/disort/`): cloud C.1, tau 64,
!> mu0 = 1, black surface; a: omega 1, intensities at tau 0, 32, 64; b: omega 0.9, at tau 3.2,
!> 12.8, 48; UMU = -1, -0.5, -0.1, 0.1, 0.5, 1 (DISORT's sign convention: UMU > 0 is upward-
!> travelling light, the same as kumo's propagation cosine), PHI = 0 (irrelevant at mu0 = 1).
!> Conversion: DISOTEST runs FBEAM = pi with UMU0 = 1, so the incident flux on a horizontal
!> plane is mu0 FBEAM = pi and kumo's pi I/(mu0 F0) = pi UU/pi = UU: the published UU is
!> compared as it is (no factor). UU is diffuse only, like kumo's radiance. The layers are cut
!> at the output depths (as in test_analytic): a: 32 | 32; b: 3.2 | 9.6 | 35.2 | 16. DISORT used
!> the 299-moment series of Garcia & Siewert; kumo the tabulated C.1 phase function of the I3RC
!> (the two agree to 1e-5 relative at 0, 1, 5, 30, 90 and 180 degrees).
!> The DISOTEST intensities are a 48-stream solution and carry errors of their own: cdisort 2.1.3
!> (pydisort 1.8.13, the solver of disort_pp.csv) reproduces them exactly with 48 streams and
!> the Nakajima-Tanaka correction, and with 200 streams gives values up to 1.8 % different
!> outside the beam direction (5b, tau 3.2, mu = 1: 0.086585 against 0.0881626) and 2.2 % and
!> 8 % different in it (5b, mu = -1: 69.442 against 67.9623 at tau 3.2; 0.22304 against
!> 0.205706 at tau 12.8; kumo agrees with the 200-stream values). So the DISOTEST rows get a
!> reference allowance of 2 % of the value (10 % in the beam direction) plus half a unit of its
!> last printed digit, and stay out of the error-bar statistics.
!>
!> Pass rule: |x - ref| <= 5 sigma + floor (5, not the 4 of test_disort_pp: see "Caveat" below
!> for why one row in ~3000 lies beyond 4 sigma in most runs), sigma the batch standard error
!> from 40 batches, floor = 1e-6 where |ref| < 1e-6 and 1e-12 otherwise, raised to a resolution
!> floor where the budget cannot resolve the reference: the local-estimate roulette compares a
!> contribution in reflectance units, pi a/|mu|, with zeta_min (times the real-scattering
!> probability of a forced collision); one below it survives as zeta_min, one above it is
!> attenuated no further than to zeta_min. So a photon adds to a radiance nothing or at least
!> about zeta_min, the estimate from N photons comes in quanta of up to zeta_min/N, and a
!> reference of a few quanta is often estimated as 0 (a Poisson count with a batch sigma of 0).
!> The floor is 8 quanta, below which a Poisson count is 0 with probability <= exp(-8) = 3e-4,
!> the order of the t(39) tail at 4 sigma. It matters only for the deep radiances of thick
!> absorbing cases (BOA of iso omega 0.99 tau 32: 1e-4 to 3e-3 at 10000 photons; DISOTEST 5b at
!> tau 48: 3e-6 to 3e-5); everywhere else it is far below 4 sigma.
!> Exact zeros (downward radiances at TOA; upward radiances at BOA over a black surface) must
!> come out exactly 0 with a zero standard error. The error bars are checked over the resolved
!> comparisons of disort_pp.csv (|ref| >= 1e-6 and >= 80 quanta, sigma > 1e-8): RMS of
!> (x - ref)/sigma within [0.7, 1.3] and fewer than 10 % beyond 2 sigma (Student's t with 39
!> degrees of freedom: RMS 1.03, 5.2 %).
!>
!> Forward peak: the rows exactly in the direction of the beam below the top (sza 0: mu = -1 at
!> every phi_rel; sza 60: mu = -0.5, phi_rel = 0; at BOA, interface_1 and DISOTEST's inner
!> levels; reference README, "Caveats") are point values of a sharp peak. kumo's estimate is a
!> point-direction local estimate and targets exactly that value without bias, so these rows
!> are kept in the k-sigma test; but one contribution there can be P(0)/4 times the photon
!> weight (20 for HG 0.85, 430 for C.1), so their batch error bars come from a skewed
!> distribution and they are left out of the RMS and 2-sigma statistics (they are listed
!> separately in the output, with their own RMS).
!>
!> Caveat: why 5 sigma per row (measured with 8 seed sets, i.e. other values of SEED). The error
!> bars are honest on the whole (RMS 0.96 to 1.10, 4.0 to 6.8 % beyond 2 sigma), but with about
!> 3200 compared radiances even Student's t(39) puts 0.9 of them beyond 4 sigma per run (so a
!> 4-sigma rule per row fails in more than half of the runs of a correct code), and the local
!> estimates of forward-peaked phase functions have heavier tails than that: a photon already
!> travelling close to a detector direction and scattering into the peak adds P(Theta)/4 times
!> its weight (divided by |mu|), rare and large for grazing directions (|mu| <= 0.2) and the
!> aureole in the HG layers and for every direction of C.1 (P(0) = 1713). Runs that miss those
!> events come out low with a small sigma. Only 3 of the 8 seed sets passed every row at
!> 4 sigma; the failures were 4.1 to 8.9 sigma, mostly such rows and DISOTEST rows, and cases
!> rerun with 30 to 40 times the photons agreed with DISORT within 2.8 sigma at 0.1 - 0.2 %
!> precision (no bias). At 5 sigma t(39) leaves 0.04 rows per run; the two C.1 columns get 4
!> times the photons of the cost model to thin their tails. A bias is caught by the error-bar
!> statistics below long before it reaches 5 sigma in single rows.
!> Variance reduction: the "unbiased" preset, set explicitly: local-estimate roulette
!> zeta_min = 0.3, collision forcing to a column optical depth of 1, no truncation, directional
!> importance sampling ddis_eps = 0.1. Photon budget: 40 batches of a size chosen per case from
!> a cost model (see photons_per_batch), about 35 s of CPU time in all in a Release build and
!> 2.4 times that in a Debug build; every case has its own seed. The shared data folder is the
!> first command-line argument.
module test_kumo_disort_radiance
  use, intrinsic :: iso_fortran_env, only: output_unit, iostat_end
  use kumo_kinds, only: wp, dp, i8
  use kumo_constants, only: DEG2RAD
  use kumo_error, only: error_t, set_error, str
  use kumo_config, only: config_t
  use kumo_phase, only: PHASE_TABLE
  use kumo_results, only: result_set_t
  use kumo_test_text, only: split, open_text, shared_dir, half_last_digit
  use kumo_test_scenes, only: set_layers, run_config, get_array
  use kumo_testing, only: unittest_t, new_unittest, check
  use kumo_test_reference, only: TINY_REF, SIGMA_EXACT, tiny_floor, depth_level, &
                                 check_error_bars, check_all_passed, run_once_t, run_once
  implicit none
  private
  public :: collect_disort_radiance

  real(dp), parameter :: K_SIGMA = 5.0_dp        !! allowed deviation in standard errors
  real(dp), parameter :: ZETA_MIN = 0.3_dp       !! local-estimate roulette ("unbiased" preset)
  !> Resolution floor in quanta zeta_min/(|mu| N) (see the module text) and the least number of
  !> quanta of a reference that enters the error-bar statistics.
  real(dp), parameter :: N_QUANTA_FLOOR = 8.0_dp, N_QUANTA_RESOLVED = 80.0_dp
  integer, parameter :: N_BATCHES = 40
  integer(i8), parameter :: SEED = 20240917_i8
  real(dp), parameter :: PHI0 = 0.0_dp           !! propagation azimuth of the beam [deg]
  integer, parameter :: MAXL = 4                 !! most layers in a case
  integer, parameter :: FLD = 128                !! length of a text field
  integer, parameter :: N_PP_CASES = 102
  !> Relative error of the DISOTEST intensities (48 streams) outside and in the beam direction,
  !> from re-runs with 200 streams (see the module text).
  real(dp), parameter :: DISOTEST_REL = 0.02_dp, DISOTEST_REL_BEAM = 0.10_dp
  !> DISOTEST problem 5: output cosines (UMU) in the order of the imu index.
  real(dp), parameter :: UMU5(6) = [-1.0_dp, -0.5_dp, -0.1_dp, 0.1_dp, 0.5_dp, 1.0_dp]
  character(len=9), parameter :: GROUPS(4) = &
    [character(len=9) :: 'isotropic', 'hg', 'two_layer', 'disotest5']

  !> A layered column over a Lambert surface and its reference radiances.
  type :: column_t
    character(len=FLD) :: id = ''
    character(len=FLD) :: group = ''
    real(dp) :: sza = 0.0_dp, albedo = 0.0_dp
    integer :: nl = 0                                      !! layers, top first below
    character(len=8) :: phase(MAXL) = ''                   !! 'iso', 'rayleigh', 'hg', 'c1'
    real(dp) :: tau(MAXL) = 0.0_dp, omega(MAXL) = 0.0_dp, g(MAXL) = 0.0_dp
    integer :: n_rows = 0                                  !! rows of the file, fluxes included
    ! one entry per reference radiance
    character(len=16), allocatable :: where(:)             !! level name of the reference
    integer, allocatable :: level(:)                       !! kumo level index (0 = surface)
    real(dp), allocatable :: mu(:), phi_rel(:), ref(:)
    real(dp), allocatable :: extra(:)                      !! tolerance for printed digits
    !> relative uncertainty of the reference outside and in the beam direction
    real(dp) :: ref_rel(2) = 0.0_dp
  end type column_t

  !> One kumo-versus-reference radiance.
  type :: comparison_t
    integer :: icol = 0
    integer :: irow = 0
    real(dp) :: x = 0.0_dp, sigma = 0.0_dp, ref = 0.0_dp, limit = 0.0_dp
    logical :: zero = .false.      !! zero by physics: kumo must give exactly 0
    logical :: peak = .false.      !! exactly in the beam direction below the top
    logical :: resolved = .false.  !! enters the error-bar statistics (if not peak)
    logical :: passed = .false.
  end type comparison_t

  type(column_t), allocatable :: cols(:)
  type(comparison_t), allocatable :: cmp(:)
  type(run_once_t) :: runs

contains


  !> All tests of this suite.
  function collect_disort_radiance() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('reference_radiances_complete', test_complete), &
             new_unittest('radiances_within_5_sigma', test_sigma), &
             new_unittest('radiance_zeros_exact', test_zeros), &
             new_unittest('radiance_error_bars_honest', test_honest)]
  end function collect_disort_radiance

  ! ------------------------------------------------------------------------------------------
  ! Tests
  ! ------------------------------------------------------------------------------------------

  !> 102 cases with 48 (one layer) or 72 (two layers) radiances among 61 or 89 rows, and the
  !> 36 intensities of DISOTEST 5a and 5b; every level in 24 (DISOTEST: 6) distinct directions.
  subroutine test_complete(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: i, n_expect, n_dir, n_lev, r, k, d
    call load_columns(error)
    if (allocated(error)) return
    call check(error, size(cols) == N_PP_CASES + 2, 'expected 102 + 2 cases, found '// &
               str(size(cols)))
    do i = 1, size(cols)
      if (allocated(error)) return
      if (cols(i)%group == 'disotest5') then
        call check(error, size(cols(i)%ref) == 18, trim(cols(i)%id)//': expected 18 UU values')
      else
        n_expect = merge(48, 72, cols(i)%nl == 1)
        call check(error, size(cols(i)%ref) == n_expect .and. cols(i)%n_rows == &
                   merge(61, 89, cols(i)%nl == 1), trim(cols(i)%id)//': '// &
                   str(size(cols(i)%ref))//' radiances in '//str(cols(i)%n_rows)//' rows')
      end if
      associate (cl => cols(i))
        n_dir = 0
        do r = 1, size(cl%ref)
          d = find_direction(cl%mu(1:r - 1), cl%phi_rel(1:r - 1), cl%mu(r), cl%phi_rel(r))
          if (d == 0) n_dir = n_dir + 1
        end do
        n_lev = count([(any(cl%level == k), k=0, cl%nl)])
        call check(error, n_dir*n_lev == size(cl%ref) .and. n_dir == &
                   merge(6, 24, cl%group == 'disotest5'), trim(cl%id)//': '//str(n_dir)// &
                   ' directions on '//str(n_lev)//' levels for '//str(size(cl%ref))//' rows')
      end associate
    end do
  end subroutine test_complete

  subroutine test_sigma(error)
    type(error_t), allocatable, intent(out) :: error
    call run_once(runs, run_all, error)
    if (allocated(error)) return
    call check_all_passed(error, cmp%passed, 'radiances beyond 5 sigma + floor', describe)
  end subroutine test_sigma

  subroutine test_zeros(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: j
    call run_once(runs, run_all, error)
    if (allocated(error)) return
    call check(error, count(cmp%zero) > 0, 'no exact zeros among the references')
    do j = 1, size(cmp)
      if (.not. cmp(j)%zero) cycle
      call check(error, .not. (abs(cmp(j)%x) > 0.0_dp .or. cmp(j)%sigma > 0.0_dp), &
                 'zero by physics, but kumo gives '//describe(j))
      if (allocated(error)) return
    end do
  end subroutine test_zeros

  subroutine test_honest(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp) :: rms, f2
    integer :: n, n3
    call run_once(runs, run_all, error)
    if (allocated(error)) return
    call error_bar_stats(in_statistics(), n, rms, f2, n3)
    call check_error_bars(error, 'radiances', n, 2000, rms, f2)
  end subroutine test_honest

  ! ------------------------------------------------------------------------------------------
  ! Running
  ! ------------------------------------------------------------------------------------------

  !> Load the references and run every column (once, through run_once).
  subroutine run_all(error)
    type(error_t), allocatable, intent(out) :: error
    type(comparison_t), allocatable :: c(:)
    integer :: i, j, n, n3, ig
    integer(i8) :: npb
    real(dp) :: cpu0, cpu1, c0, c1, rms, f2, dmax
    logical, allocatable :: in_group(:)

    call load_columns(error)
    if (allocated(error)) return
    allocate (cmp(0))
    write (output_unit, '(a)') '# kumo radiances vs DISORT, k = 4; per case: photons per '// &
      'batch, cpu [s], radiances, worst |x - ref|/sigma'
    call cpu_time(cpu0)
    do i = 1, size(cols)
      npb = photons_per_batch(cols(i))
      call cpu_time(c0)
      call compare_column(i, npb, c, error)
      if (allocated(error)) return
      call cpu_time(c1)
      dmax = 0.0_dp
      do j = 1, size(c)
        if (c(j)%sigma > 0.0_dp) dmax = max(dmax, abs(c(j)%x - c(j)%ref)/c(j)%sigma)
      end do
      write (output_unit, '(a40,1x,i7,1x,f7.3,1x,i3,1x,f6.2,a)') cols(i)%id, npb, c1 - c0, &
        size(c), dmax, trim(merge('  FAIL', '      ', any(.not. c%passed)))
      cmp = [cmp, c]
    end do
    call cpu_time(cpu1)

    call error_bar_stats(in_statistics(), n, rms, f2, n3)
    write (output_unit, '(a)') '# cpu time '//str(cpu1 - cpu0)//' s; '//str(size(cmp))// &
      ' radiances, '//str(count(.not. cmp%passed))//' beyond 5 sigma + floor, '// &
      str(count(cmp%zero))//' exact zeros, '//str(count(cmp%peak))//' in the beam direction'
    write (output_unit, '(a)') '# error-bar statistics (disort_pp.csv, resolved, outside the '// &
      'beam direction): '//str(n)// &
      '; RMS (x - ref)/sigma '//str(rms)//'; beyond 2 sigma '//str(100.0_dp*f2)// &
      ' %; beyond 3 sigma '//str(n3)
    do ig = 1, size(GROUPS)
      in_group = [(cols(cmp(j)%icol)%group == GROUPS(ig), j=1, size(cmp))]
      call error_bar_stats(in_group .and. cmp%resolved .and. .not. cmp%peak, n, rms, f2, n3)
      dmax = 0.0_dp
      do j = 1, size(cmp)
        if (in_group(j) .and. cmp(j)%sigma > 0.0_dp) then
          dmax = max(dmax, abs(cmp(j)%x - cmp(j)%ref)/cmp(j)%sigma)
        end if
      end do
      write (output_unit, '(a)') '# group '//trim(GROUPS(ig))//': '//str(count(in_group))// &
        ' radiances, '//str(n)//' in the statistics: RMS '//str(rms)//', beyond 2 sigma '// &
        str(100.0_dp*f2)//' %, beyond 3 sigma '//str(n3)//'; max |dev| '//str(dmax)// &
        ' sigma (beam direction included)'
    end do
    in_group = [(cols(cmp(j)%icol)%group /= 'disotest5', j=1, size(cmp))]
    call error_bar_stats(in_group .and. cmp%peak .and. cmp%resolved, n, rms, f2, n3)
    write (output_unit, '(a)') '# beam direction (disort_pp.csv, resolved): '//str(n)// &
      ' radiances, RMS (x - ref)/sigma '//str(rms)//', beyond 2 sigma '//str(100.0_dp*f2)// &
      ' %, beyond 3 sigma '//str(n3)
    do j = 1, size(cmp)
      if (cmp(j)%peak) write (output_unit, '(a)') '#   beam direction: '//describe(j)
    end do
    do j = 1, size(cmp)
      if (cmp(j)%peak .or. .not. cmp(j)%resolved) cycle
      if (abs(cmp(j)%x - cmp(j)%ref) > 3.0_dp*cmp(j)%sigma) then
        write (output_unit, '(a)') '#   > 3 sigma: '//describe(j)
      end if
    end do
  end subroutine run_all

  !> The comparisons whose deviations enter the error-bar check: disort_pp.csv (the DISOTEST
  !> references have an error of their own), resolved, outside the beam direction.
  function in_statistics() result(mask)
    logical, allocatable :: mask(:)
    integer :: j
    mask = [(cmp(j)%resolved .and. .not. cmp(j)%peak .and. &
             cols(cmp(j)%icol)%group /= 'disotest5', j=1, size(cmp))]
  end function in_statistics

  !> Count, RMS of (x - ref)/sigma, fraction beyond 2 sigma and count beyond 3 sigma over the
  !> comparisons selected by `mask`.
  subroutine error_bar_stats(mask, n, rms, frac2, n3)
    logical, intent(in) :: mask(:)
    integer, intent(out) :: n, n3
    real(dp), intent(out) :: rms, frac2
    real(dp), allocatable :: d(:)
    d = pack((cmp%x - cmp%ref)/max(cmp%sigma, tiny(1.0_dp)), mask)
    n = size(d)
    rms = sqrt(sum(d**2)/max(1, n))
    frac2 = real(count(abs(d) > 2.0_dp), dp)/max(1, n)
    n3 = count(abs(d) > 3.0_dp)
  end subroutine error_bar_stats

  !> Photons per batch of a column: about 4 ms of Release CPU time per batch by a cost model,
  !> within [250, 10000]. The cost of a photon is dominated by its local estimates, one per
  !> scattering and detector slot; the model, in microseconds, is 0.4 + (1 + albedo) n_s +
  !> 0.6 albedo, with n_s the harmonic combination of 1.4 tau (the scatterings of a
  !> conservative layer grow about linearly with its optical depth) and 0.63/(1 - omega)
  !> (absorption ends the photon). It was fitted without directional importance sampling;
  !> with it (ddis_eps = 0.1) the measured cost is 1 to 3 times the model. The floor of 250
  !> photons holds for the thick cases (tau 10 to 64, 25 to 190 us per photon), whose
  !> per-photon contributions are broad and skewed, so that a batch is not a handful of photons.
  integer(i8) function photons_per_batch(cl) result(n)
    type(column_t), intent(in) :: cl
    real(dp), parameter :: US_PER_BATCH = 4000.0_dp
    real(dp) :: cost, n_s, w
    w = minval(cl%omega(1:cl%nl))
    n_s = 1.0_dp/(1.0_dp/(1.4_dp*sum(cl%tau(1:cl%nl))) + max(1.0e-6_dp, 1.0_dp - w)/0.63_dp)
    cost = 0.4_dp + (1.0_dp + cl%albedo)*n_s + 0.6_dp*cl%albedo
    n = max(250_i8, min(10000_i8, nint(US_PER_BATCH/cost, i8)))
    if (cl%group == 'disotest5') n = 4*n
  end function photons_per_batch

  !> Run column i with radiance detectors on all its reference levels and directions and
  !> compare every reference radiance.
  subroutine compare_column(i, npb, c, error)
    integer, intent(in) :: i
    integer(i8), intent(in) :: npb
    type(comparison_t), allocatable, intent(out) :: c(:)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: set
    real(dp), allocatable :: dir_mu(:), dir_phi(:), mean(:), stderr(:)
    integer, allocatable :: levels(:)
    integer :: r, d, s, k, idx, nd
    real(dp) :: mu0, n_total, quantum, floor_r

    associate (cl => cols(i))
      ! directions and levels: the distinct ones of the reference rows
      allocate (dir_mu(0), dir_phi(0))
      do r = 1, size(cl%ref)
        if (find_direction(dir_mu, dir_phi, cl%mu(r), cl%phi_rel(r)) == 0) then
          dir_mu = [dir_mu, cl%mu(r)]
          dir_phi = [dir_phi, cl%phi_rel(r)]
        end if
      end do
      levels = pack([(k, k=0, cl%nl)], [(any(cl%level == k), k=0, cl%nl)])
      cfg = column_config(cl, npb, SEED + i)
      cfg%rad%mu = real(dir_mu, wp)
      cfg%rad%phi_deg = real(PHI0 + dir_phi, wp)
      cfg%rad%levels = levels
      cfg%rad%maps = .false.
      call run_config(cfg, set, error)
      if (.not. allocated(error)) call get_array(set, 'radiance', mean, stderr, error)
      if (allocated(error)) then
        error%message = trim(cl%id)//': '//error%message
        return
      end if
      nd = size(dir_mu)
      if (size(mean) /= nd*size(levels)) then
        call set_error(error, trim(cl%id)//': radiance has '//str(size(mean))// &
                       ' values, expected '//str(nd*size(levels)))
        return
      end if

      mu0 = cos(cl%sza*DEG2RAD)
      n_total = real(npb*N_BATCHES, dp)
      allocate (c(size(cl%ref)))
      do r = 1, size(cl%ref)
        d = find_direction(dir_mu, dir_phi, cl%mu(r), cl%phi_rel(r))
        s = findloc(levels, cl%level(r), 1)
        idx = s + (d - 1)*size(levels)          ! radiance(rad_level, direction)
        c(r)%icol = i
        c(r)%irow = r
        c(r)%x = mean(idx)
        c(r)%sigma = stderr(idx)
        c(r)%ref = cl%ref(r)
        c(r)%zero = (cl%level(r) == cl%nl .and. cl%mu(r) < 0.0_dp) .or. &
                    (cl%level(r) == 0 .and. cl%mu(r) > 0.0_dp .and. .not. cl%albedo > 0.0_dp)
        c(r)%peak = cl%level(r) < cl%nl .and. abs(cl%mu(r) + mu0) < 1.0e-6_dp .and. &
                    (abs(mu0 - 1.0_dp) < 1.0e-6_dp .or. abs(cl%phi_rel(r)) < 1.0e-6_dp)
        ! smallest contribution of one photon to a radiance (see the module text)
        quantum = ZETA_MIN/n_total
        floor_r = max(tiny_floor(c(r)%ref), N_QUANTA_FLOOR*quantum)
        c(r)%limit = K_SIGMA*c(r)%sigma + floor_r + cl%extra(r) + &
                     merge(cl%ref_rel(2), cl%ref_rel(1), c(r)%peak)*abs(c(r)%ref)
        c(r)%passed = abs(c(r)%x - c(r)%ref) <= c(r)%limit
        c(r)%resolved = abs(c(r)%ref) >= max(TINY_REF, N_QUANTA_RESOLVED*quantum) .and. &
                        c(r)%sigma > SIGMA_EXACT
      end do
    end associate
  end subroutine compare_column

  !> Index of direction (mu, phi_rel) in the lists, 0 if absent.
  pure integer function find_direction(dir_mu, dir_phi, mu, phi_rel) result(d)
    real(dp), intent(in) :: dir_mu(:), dir_phi(:), mu, phi_rel
    integer :: k
    d = 0
    do k = 1, size(dir_mu)
      if (abs(dir_mu(k) - mu) < 1.0e-9_dp .and. abs(dir_phi(k) - phi_rel) < 1.0e-9_dp) then
        d = k
        return
      end if
    end do
  end function find_direction

  !> Configuration of a column (layers top first, 1000 m thick each), unbiased VR preset.
  function column_config(cl, npb, seed) result(cfg)
    type(column_t), intent(in) :: cl
    integer(i8), intent(in) :: npb, seed
    type(config_t) :: cfg
    integer :: nz, l
    nz = cl%nl
    cfg%path = 'test_disort_radiance'
    call set_layers(cfg, real(cl%tau(1:nz), wp), real(cl%omega(1:nz), wp), cl%phase(1:nz), &
                    real(cl%g(1:nz), wp))
    do l = 1, nz
      if (cl%phase(l) /= 'c1') cycle
      cfg%phase%kind(l) = PHASE_TABLE
      cfg%phase%kind_name(l) = 'table'
      cfg%phase%file(l) = shared_dir//'/data/i3rc/phase1_inputs/C.1_PF'
    end do
    cfg%surface%albedo = real(cl%albedo, wp)
    cfg%source%sza_deg = real(cl%sza, wp)
    cfg%source%phi0_deg = real(PHI0, wp)
    cfg%output%flux_levels = [0, nz]
    cfg%vr%preset = 'unbiased'
    cfg%vr%zeta_min = 0.3_wp
    cfg%vr%trunc_theta_max_deg = 0.0_wp
    cfg%vr%trunc_levels = 1
    cfg%vr%cf_tau_min = 1.0_wp
    cfg%vr%ddis_eps = 0.1_wp
    cfg%control%n_photons_per_batch = npb
    cfg%control%n_batches = N_BATCHES
    cfg%control%seed = seed
    cfg%control%verbose = 0
  end function column_config

  ! ------------------------------------------------------------------------------------------
  ! References
  ! ------------------------------------------------------------------------------------------

  !> The 102 cases of disort_pp.csv followed by DISOTEST 5a and 5b (once).
  subroutine load_columns(error)
    type(error_t), allocatable, intent(out) :: error
    type(column_t) :: p5(2)
    if (allocated(cols)) return
    if (.not. allocated(shared_dir)) then
      call set_error(error, 'the shared data folder was not given on the command line')
      return
    end if
    call read_pp_table(shared_dir//'/reference/disort_pp.csv', error)
    if (allocated(error)) return
    ! DISOTEST 5: layers cut at the output optical depths (see the module text)
    call disotest5_column('a', [32.0_dp, 32.0_dp], [0.0_dp, 32.0_dp, 64.0_dp], 1.0_dp, &
                          p5(1), error)
    if (.not. allocated(error)) then
      call disotest5_column('b', [3.2_dp, 9.6_dp, 35.2_dp, 16.0_dp], &
                            [3.2_dp, 12.8_dp, 48.0_dp], 0.9_dp, p5(2), error)
    end if
    if (allocated(error)) then
      deallocate (cols)
      return
    end if
    cols = [cols, p5]
  end subroutine load_columns

  !> Read disort_pp.csv: the case columns and the radiance rows (other rows are only counted).
  subroutine read_pp_table(path, error)
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(out) :: error
    character(len=512) :: line
    character(len=FLD) :: f(12)
    integer :: unit, ios, nf, lineno, ic
    real(dp) :: v(5)
    type(column_t) :: cl

    call open_text(path, unit, error)
    if (allocated(error)) return
    allocate (cols(0))
    lineno = 0
    read (unit, '(a)', iostat=ios) line            ! header
    if (ios /= 0) then
      call set_error(error, path//': cannot read the header line')
      close (unit)
      deallocate (cols)
      return
    end if
    do
      read (unit, '(a)', iostat=ios) line
      if (ios == iostat_end) exit
      lineno = lineno + 1
      if (ios /= 0) then
        call set_error(error, path//': read error at data line '//str(lineno))
        exit
      end if
      if (len_trim(line) == 0) cycle
      call split(line, ',', f, nf)
      if (nf /= 12) then
        call set_error(error, path//': data line '//str(lineno)//' has '//str(nf)//' fields')
        exit
      end if
      ic = 0
      if (size(cols) > 0) then
        if (cols(size(cols))%id == f(1)) ic = size(cols)
      end if
      if (ic == 0) then
        if (any(cols%id == f(1))) then
          call set_error(error, path//': rows of case '//trim(f(1))//' are not together')
          exit
        end if
        cl = column_t()
        cl%id = f(1)
        cl%group = f(2)
        read (f(4), *, iostat=ios) cl%sza
        if (ios == 0) read (f(7), *, iostat=ios) cl%albedo
        if (ios == 0) call read_layer_spec(f(3), cl, ios)
        if (ios /= 0) then
          call set_error(error, path//': bad case description at data line '//str(lineno))
          exit
        end if
        allocate (cl%where(0), cl%level(0), cl%mu(0), cl%phi_rel(0), cl%ref(0), cl%extra(0))
        cols = [cols, cl]
        ic = size(cols)
      end if
      cols(ic)%n_rows = cols(ic)%n_rows + 1
      if (f(8) /= 'pi_I_over_mu0F0') cycle
      read (f(10), *, iostat=ios) v(1)
      if (ios == 0) read (f(11), *, iostat=ios) v(2)
      if (ios == 0) read (f(12), *, iostat=ios) v(3)
      v(4) = real(level_index(f(9), cols(ic)%nl), dp)
      if (ios /= 0 .or. v(4) < 0.0_dp) then
        call set_error(error, path//': bad radiance row at data line '//str(lineno))
        exit
      end if
      associate (cc => cols(ic))
        cc%where = [character(len=16) :: cc%where, f(9)]
        cc%level = [cc%level, nint(v(4))]
        cc%mu = [cc%mu, v(1)]
        cc%phi_rel = [cc%phi_rel, v(2)]
        cc%ref = [cc%ref, v(3)]
        cc%extra = [cc%extra, 0.0_dp]           ! 10 significant digits: negligible
      end associate
    end do
    close (unit)
    if (allocated(error)) deallocate (cols)
  end subroutine read_pp_table

  !> kumo level of a level name of the table (TOA, interface_k, BOA) in a column of nl layers;
  !> -1 if unknown.
  integer function level_index(name, nl) result(k)
    character(len=*), intent(in) :: name
    integer, intent(in) :: nl
    integer :: ios, m
    k = -1
    select case (trim(name))
    case ('TOA')
      k = nl
    case ('BOA')
      k = 0
    case default
      if (index(name, 'interface_') /= 1) return
      read (name(11:), *, iostat=ios) m          ! below the m-th layer from the top
      if (ios == 0 .and. m >= 1 .and. m < nl) k = nl - m
    end select
  end function level_index

  !> Layers of a layer_spec such as "rayleigh:tau=0.1:omega=1|hg:g=0.85:tau=10:omega=0.9999"
  !> (top first); ios /= 0 on anything unexpected.
  subroutine read_layer_spec(spec, cl, ios)
    character(len=*), intent(in) :: spec
    type(column_t), intent(inout) :: cl
    integer, intent(out) :: ios
    character(len=FLD) :: layer(MAXL + 1), item(6)
    integer :: l, m, ni
    real(dp) :: vals(3)                  ! tau, omega, g
    call split(spec, '|', layer, cl%nl)
    ios = merge(0, 1, cl%nl >= 1 .and. cl%nl <= MAXL)
    do l = 1, min(cl%nl, MAXL)
      if (ios /= 0) return
      call split(layer(l), ':', item, ni)
      vals = [-1.0_dp, -1.0_dp, 0.0_dp]
      do m = 2, min(ni, size(item))
        select case (item(m)(1:index(item(m), '=')))
        case ('tau=')
          read (item(m)(5:), *, iostat=ios) vals(1)
        case ('omega=')
          read (item(m)(7:), *, iostat=ios) vals(2)
        case ('g=')
          read (item(m)(3:), *, iostat=ios) vals(3)
        case default
          ios = 1
        end select
        if (ios /= 0) return
      end do
      if (ni > size(item) .or. any(vals(1:2) < 0.0_dp) .or. &
          all(item(1) /= [character(len=8) :: 'iso', 'rayleigh', 'hg'])) ios = 1
      cl%phase(l) = item(1)(1:len(cl%phase))
      cl%tau(l) = vals(1)
      cl%omega(l) = vals(2)
      cl%g(l) = vals(3)
    end do
  end subroutine read_layer_spec

  !> DISOTEST problem 5, case `cas`: C.1 layers `dtau` (top first), output depths `utau`, and
  !> its UU values from the DISOTEST answers file.
  subroutine disotest5_column(cas, dtau, utau, omega, cl, error)
    character(len=1), intent(in) :: cas
    real(dp), intent(in) :: dtau(:), utau(:), omega
    type(column_t), intent(out) :: cl
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: path
    character(len=256) :: line
    character(len=FLD) :: f(7)
    integer :: unit, ios, nf, it, iu, ip, lev(size(utau))
    real(dp) :: value

    cl%id = 'disotest_5'//cas//'_c1_w'//str(omega)
    cl%group = 'disotest5'
    cl%sza = 0.0_dp
    cl%albedo = 0.0_dp
    cl%nl = size(dtau)
    cl%phase(1:cl%nl) = 'c1'
    cl%tau(1:cl%nl) = dtau
    cl%omega(1:cl%nl) = omega
    cl%ref_rel = [DISOTEST_REL, DISOTEST_REL_BEAM]
    ! the kumo level of every output depth: nl minus the layers above it
    do it = 1, size(utau)
      lev(it) = depth_level(dtau, utau(it))
      if (lev(it) < 0) then
        call set_error(error, 'DISOTEST 5'//cas//': depth '//str(utau(it))//' is not a level')
        return
      end if
    end do
    allocate (cl%where(0), cl%level(0), cl%mu(0), cl%phi_rel(0), cl%ref(0), cl%extra(0))

    path = shared_dir//'/data/disort/disotest_v2.0beta_correct_answers.csv'
    call open_text(path, unit, error)
    if (allocated(error)) return
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (line(1:2) /= '5,') cycle
      call split(line, ',', f, nf)
      if (nf /= 7 .or. f(2) /= cas .or. f(3) /= 'UU') cycle
      read (f(4), *, iostat=ios) it
      if (ios == 0) read (f(5), *, iostat=ios) iu
      if (ios == 0) read (f(6), *, iostat=ios) ip
      if (ios == 0) read (f(7), *, iostat=ios) value
      if (ios /= 0 .or. it < 1 .or. it > size(utau) .or. iu < 1 .or. iu > size(UMU5) .or. &
          ip /= 1) then
        call set_error(error, path//': unexpected UU row "'//trim(line)//'"')
        exit
      end if
      cl%where = [character(len=16) :: cl%where, 'tau='//str(utau(it))]
      cl%level = [cl%level, lev(it)]
      cl%mu = [cl%mu, UMU5(iu)]
      cl%phi_rel = [cl%phi_rel, 0.0_dp]
      cl%ref = [cl%ref, value]
      cl%extra = [cl%extra, half_last_digit(f(7))]
    end do
    close (unit)
  end subroutine disotest5_column

  ! ------------------------------------------------------------------------------------------
  ! Text
  ! ------------------------------------------------------------------------------------------

  !> Text of comparison j.
  function describe(j) result(s)
    integer, intent(in) :: j
    character(len=:), allocatable :: s
    associate (c => cmp(j), cl => cols(cmp(j)%icol))
      s = trim(cl%id)//' '//trim(cl%where(c%irow))//' mu '//str(cl%mu(c%irow))//' phi_rel '// &
          str(cl%phi_rel(c%irow))//': kumo '//str(c%x)//' +- '//str(c%sigma)//', ref '// &
          str(c%ref)
      if (c%sigma > 0.0_dp) s = s//', dev '//str((c%x - c%ref)/c%sigma)//' sigma'
      if (.not. c%passed) s = s//', |x - ref| > limit '//str(c%limit)
    end associate
  end function describe

end module test_kumo_disort_radiance

program test_disort_radiance
  use test_kumo_disort_radiance, only: collect_disort_radiance
  use kumo_test_text, only: run_shared_suite
  implicit none
  call run_shared_suite('test_disort_radiance', 'reference/disort_pp.csv and data/disort', &
                        'kumo radiances vs DISORT (reference/disort_pp.csv, DISOTEST 5)', &
                        collect_disort_radiance())
end program test_disort_radiance
