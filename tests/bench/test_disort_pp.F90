! SPDX-License-Identifier: BSD-3-Clause
!> Benchmark: kumo against the 102 plane-parallel DISORT cases of `reference/disort_pp.csv`.
!>
!> Every case of the table (one isotropic or Henyey-Greenstein layer, or a Rayleigh layer over
!> an HG layer, over a Lambert surface) is run through `simulate` with a small photon budget and
!> every flux quantity of the table is compared with the reference: R, T_total, T_direct,
!> T_diffuse, A_atm, A_surface, each A_layer<k>, and F_up, F_dif_down, F_dir_down at every level
!> (TOA, interface_1, BOA). Radiances are not compared (kumo has no radiance tally yet). Each
!> layer is 1000 m thick, so its extinction is tau/1000 m-1.
!>
!> Pass rule (STYLE section 8.2): |x - ref| <= k*sigma + floor with k = 4 and sigma the batch
!> standard error of kumo's estimate, with two refinements that are fixed in advance:
!>
!> * floor = 1e-6 where |ref| < 1e-6: exact zeros (A_layer of omega = 1 layers, the diffuse
!>   flux entering at the top, F_up at the bottom over a black surface; DISORT writes these as
!>   0 or as round-off up to 5e-10) and values the budget cannot resolve (the diffuse
!>   transmittance of absorbing tau = 32 slabs, ~5e-8). Everything else gets a round-off
!>   allowance of 1e-12 only.
!> * direct-beam quantities (T_direct, F_dir_down) are counts of unscattered photons of weight
!>   1, a binomial variable whose standard error sqrt(p (1 - p)/N) is known exactly; with a
!>   handful of expected photons (exp(-10/mu0) ~ 1e-5 at N ~ 1e5) the batch estimate is 0 or
!>   badly low, so sigma = max(batch sigma, binomial sigma) is used there.
!>
!> Physical zeros must moreover come out exactly 0 in kumo, and energy_closure must be 1 to
!> 1e-10. The error bars themselves are checked over all comparisons that are resolved
!> (|ref| >= 1e-6 and sigma > 1e-8, which leaves out exact quantities such as
!> F_dir_down(TOA) = 1): the RMS of (x - ref)/sigma must lie within [0.7, 1.3] and fewer than
!> 10 % may exceed 2 sigma. With a batch standard error from 40 batches the deviations
!> follow Student's t with 39 degrees of freedom: RMS 1.03, 5.2 % beyond 2 sigma, 0.47 % beyond
!> 3 sigma, 0.027 % beyond 4 sigma (Gaussian: 4.6 %, 0.27 %, 0.006 %; with 10 batches the
!> 4-sigma tail would be 0.31 %, several failures in ~1000 comparisons, hence 40). The
!> comparisons beyond 3 sigma are listed in the output. Many comparisons of a case are
!> correlated (R = F_up(TOA), A_atm = A_layer1, ...), so these fractions scatter more than
!> binomially.
!>
!> Photon budget: 40 batches of a size chosen per case from its optical thickness,
!> single-scattering albedo and surface albedo, for roughly equal run time per case (about
!> 9 s of CPU time in all in a Release build; printed at the end). Every case has its own
!> seed: cases that differ only in omega or albedo would otherwise follow the same photon paths
!> (absorption acts on weights) and their deviations would come in correlated clusters. The
!> path of the shared data folder is the first command-line argument (CTest passes
!> `${KUMO_SHARED_DIR}`).
module test_kumo_disort_pp
  use, intrinsic :: iso_fortran_env, only: output_unit, iostat_end, int64
  use kumo_test_text, only: split, open_text, shared_dir
  use kumo_kinds, only: dp, i8
  use kumo_error, only: error_t, set_error, str
  use kumo_config, only: config_t
  use kumo_driver, only: simulate, run_summary_t
  use kumo_results, only: result_set_t, find_var
  use kumo_testing, only: unittest_t, new_unittest, check
  use kumo_test_scenes, only: set_layers
  use kumo_test_reference, only: TINY_REF, SIGMA_EXACT, tiny_floor, direct_sigma, &
                                 check_error_bars, check_all_passed, run_once_t, run_once
  implicit none
  private
  public :: collect_disort_pp

  real(dp), parameter :: K_SIGMA = 4.0_dp        !! allowed deviation in standard errors
  integer, parameter :: N_BATCHES = 40
  integer(i8), parameter :: SEED = 20240611_i8
  integer, parameter :: MAXL = 4                 !! most layers in a case
  integer, parameter :: N_CASES_EXPECTED = 102
  integer, parameter :: FLD = 128                !! length of a text field of the table

  !> One reference value of a case.
  type :: ref_row_t
    character(len=FLD) :: quantity = ''
    character(len=FLD) :: level = ''
    real(dp) :: value = 0.0_dp
  end type ref_row_t

  !> One case of the table: layers (top first), geometry and reference values.
  type :: case_t
    character(len=FLD) :: id = ''
    character(len=FLD) :: group = ''
    character(len=FLD) :: spec = ''
    real(dp) :: sza = 0.0_dp, albedo = 0.0_dp
    integer :: nl = 0
    character(len=8) :: phase(MAXL) = ''         !! 'iso', 'rayleigh' or 'hg'
    real(dp) :: tau(MAXL) = 0.0_dp, omega(MAXL) = 0.0_dp, g(MAXL) = 0.0_dp
    integer :: n_rows_all = 0                    !! rows in the file, radiances included
    type(ref_row_t), allocatable :: rows(:)      !! flux rows only
  end type case_t

  !> One kumo-versus-DISORT comparison.
  type :: comparison_t
    integer :: icase = 0
    character(len=32) :: label = ''
    real(dp) :: x = 0.0_dp, sigma_hat = 0.0_dp, sigma = 0.0_dp, ref = 0.0_dp, floor = 0.0_dp
    logical :: zero = .false.       !! zero by physics: kumo must give exactly 0
    logical :: resolved = .false.   !! enters the error-bar statistics
    logical :: passed = .false.
  end type comparison_t

  type(case_t), allocatable :: cases(:)
  type(comparison_t), allocatable :: cmp(:)
  real(dp), allocatable :: closure_err(:)
  type(run_once_t) :: runs

contains


  !> All tests of this suite.
  function collect_disort_pp() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('reference_table_complete', test_table), &
             new_unittest('all_fluxes_within_4_sigma', test_within_sigma), &
             new_unittest('physical_zeros_exact', test_zeros), &
             new_unittest('energy_closure', test_closure), &
             new_unittest('error_bars_honest', test_honest)]
  end function collect_disort_pp

  ! ------------------------------------------------------------------------------------------
  ! Tests
  ! ------------------------------------------------------------------------------------------

  subroutine test_table(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: i, n_iso, n_hg, n_two, n_flux
    call load_table(error)
    if (allocated(error)) return
    call check(error, size(cases) == N_CASES_EXPECTED, 'expected 102 cases')
    if (allocated(error)) return
    n_iso = count(cases%group == 'isotropic')
    n_hg = count(cases%group == 'hg')
    n_two = count(cases%group == 'two_layer')
    call check(error, n_iso == 62 .and. n_hg == 36 .and. n_two == 4, &
               'expected 62 isotropic, 36 hg and 4 two_layer cases')
    do i = 1, size(cases)
      if (allocated(error)) return
      ! one-layer cases: 61 rows (13 flux rows); two-layer cases: 89 rows (17 flux rows)
      n_flux = merge(13, 17, cases(i)%nl == 1)
      call check(error, cases(i)%n_rows_all == merge(61, 89, cases(i)%nl == 1) .and. &
                 size(cases(i)%rows) == n_flux, trim(cases(i)%id)//': unexpected number of rows')
    end do
  end subroutine test_table

  subroutine test_within_sigma(error)
    type(error_t), allocatable, intent(out) :: error
    call run_once(runs, run_all, error)
    if (allocated(error)) return
    call check_all_passed(error, cmp%passed, 'comparisons beyond 4 sigma + floor', describe)
  end subroutine test_within_sigma

  subroutine test_zeros(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: i, n_zero
    call run_once(runs, run_all, error)
    if (allocated(error)) return
    n_zero = 0
    do i = 1, size(cmp)
      if (.not. cmp(i)%zero) cycle
      n_zero = n_zero + 1
      call check(error, is_exactly(cmp(i)%x, 0.0_dp) .and. is_exactly(cmp(i)%sigma_hat, 0.0_dp), &
                 'zero by physics but kumo gives '//describe(i))
      if (allocated(error)) return
    end do
    call check(error, n_zero > 0, 'no physical zeros found in the table')
  end subroutine test_zeros

  subroutine test_closure(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    call run_once(runs, run_all, error)
    if (allocated(error)) return
    do i = 1, size(cases)
      call check(error, closure_err(i) <= 1.0e-10_dp, trim(cases(i)%id)// &
                 ': |energy_closure - 1| = '//str(closure_err(i))//' > 1e-10')
      if (allocated(error)) return
    end do
  end subroutine test_closure

  subroutine test_honest(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp) :: rms, f2
    integer :: n
    call run_once(runs, run_all, error)
    if (allocated(error)) return
    call deviation_stats(n, rms, f2)
    call check_error_bars(error, 'comparisons', n, 900, rms, f2)
  end subroutine test_honest

  ! ------------------------------------------------------------------------------------------
  ! Running the cases
  ! ------------------------------------------------------------------------------------------

  !> Read the table and run every case (once, through run_once).
  subroutine run_all(error)
    type(error_t), allocatable, intent(out) :: error
    type(comparison_t), allocatable :: c(:)
    integer :: i, j, n, n3
    integer(int64) :: t0, t1, rate
    real(dp) :: c0, c1, ct0, ct1
    integer(i8) :: nphot
    real(dp) :: worst, rms, f2, dev
    character(len=:), allocatable :: worst_label

    call load_table(error)
    if (allocated(error)) return
    allocate (cmp(0), closure_err(size(cases)))
    write (output_unit, '(a)') '# kumo vs DISORT, k = 4; per case: photons, cpu time [s], '// &
      'comparisons, worst |x - ref|/sigma and where'
    call system_clock(t0, rate)
    call cpu_time(ct0)
    do i = 1, size(cases)
      call cpu_time(c0)
      call run_case_compare(i, c, nphot, closure_err(i), error)
      if (allocated(error)) return
      call cpu_time(c1)
      worst = 0.0_dp
      worst_label = '-'
      do j = 1, size(c)
        if (c(j)%sigma > 0.0_dp) then
          dev = abs(c(j)%x - c(j)%ref)/c(j)%sigma
          if (dev > worst) then
            worst = dev
            worst_label = trim(c(j)%label)
          end if
        end if
      end do
      write (output_unit, '(a40,1x,i9,1x,f7.3,1x,i3,1x,f6.2,1x,a,a)') cases(i)%id, nphot, &
        c1 - c0, size(c), worst, worst_label, &
        trim(merge('  FAIL', '      ', any(.not. c%passed)))
      cmp = [cmp, c]
    end do
    call system_clock(t1)
    call cpu_time(ct1)
    call deviation_stats(n, rms, f2)
    n3 = 0
    do j = 1, size(cmp)
      if (cmp(j)%resolved) then
        if (abs(cmp(j)%x - cmp(j)%ref) > 3.0_dp*cmp(j)%sigma) n3 = n3 + 1
      end if
    end do
    write (output_unit, '(a)') '# run time: cpu '//str(ct1 - ct0)//' s, wall '// &
      str(real(t1 - t0, dp)/rate)//' s; '// &
      str(size(cmp))//' comparisons, '//str(count(.not. cmp%passed))// &
      ' beyond 4 sigma + floor; '//str(count(cmp%zero))//' physical zeros'
    write (output_unit, '(a)') '# resolved comparisons (|ref| >= 1e-6, sigma > 1e-8): '//str(n)// &
      '; RMS (x - ref)/sigma = '//str(rms)//'; beyond 2 sigma: '//str(100.0_dp*f2)// &
      ' %; beyond 3 sigma: '//str(n3)//' ('//str(100.0_dp*n3/max(1, n))//' %)'
    call group_summary('isotropic')
    call group_summary('hg')
    call group_summary('two_layer')
    do j = 1, size(cmp)
      if (.not. cmp(j)%resolved) cycle
      if (abs(cmp(j)%x - cmp(j)%ref) > 3.0_dp*cmp(j)%sigma) then
        write (output_unit, '(a)') '#   > 3 sigma: '//describe(j)
      end if
    end do
  end subroutine run_all

  !> Print the comparison count, max |x - ref|/sigma and RMS (x - ref)/sigma of one group.
  subroutine group_summary(group)
    character(len=*), intent(in) :: group
    integer :: j, n, nr
    real(dp) :: d, dmax, ss
    n = 0
    nr = 0
    dmax = 0.0_dp
    ss = 0.0_dp
    do j = 1, size(cmp)
      if (cases(cmp(j)%icase)%group /= group) cycle
      n = n + 1
      if (.not. cmp(j)%resolved) cycle
      nr = nr + 1
      d = (cmp(j)%x - cmp(j)%ref)/cmp(j)%sigma
      dmax = max(dmax, abs(d))
      ss = ss + d*d
    end do
    write (output_unit, '(a)') '# group '//group//': '//str(n)//' comparisons, '//str(nr)// &
      ' resolved; max |dev| '//str(dmax)//' sigma; RMS dev '//str(sqrt(ss/max(1, nr)))
  end subroutine group_summary

  !> Statistics of (x - ref)/sigma over the resolved comparisons.
  subroutine deviation_stats(n, rms, frac2)
    integer, intent(out) :: n
    real(dp), intent(out) :: rms, frac2
    integer :: j, n2
    real(dp) :: d
    n = 0
    n2 = 0
    rms = 0.0_dp
    do j = 1, size(cmp)
      if (.not. cmp(j)%resolved) cycle
      d = (cmp(j)%x - cmp(j)%ref)/cmp(j)%sigma
      n = n + 1
      rms = rms + d*d
      if (abs(d) > 2.0_dp) n2 = n2 + 1
    end do
    rms = sqrt(rms/max(1, n))
    frac2 = real(n2, dp)/max(1, n)
  end subroutine deviation_stats

  !> Photons per batch of a case, inverse to the cost of a photon so that every case takes a
  !> similar time (about 4 ms per batch). The cost model, in microseconds per photon, was fitted
  !> to Release timings: 0.1 + 0.35 tau^0.8 for conservative layers (collisions grow with the
  !> optical thickness), capped by absorption (about 1/(1 - omega) collisions), times
  !> (1 + albedo) for the extra passes through the layer after surface reflections.
  integer(i8) function photons_per_batch(cs) result(n)
    type(case_t), intent(in) :: cs
    real(dp), parameter :: US_PER_BATCH = 4000.0_dp
    real(dp) :: cost, tau_sum, w
    tau_sum = sum(cs%tau(1:cs%nl))
    w = minval(cs%omega(1:cs%nl))
    cost = 0.1_dp + min(0.35_dp*tau_sum**0.8_dp, 0.1_dp/max(1.0e-6_dp, 1.0_dp - w))
    cost = cost*(1.0_dp + cs%albedo)
    n = max(300_i8, min(20000_i8, nint(US_PER_BATCH/cost, i8)))
  end function photons_per_batch

  !> Run case i and compare every flux row with kumo.
  subroutine run_case_compare(i, c, nphot, closure, error)
    integer, intent(in) :: i
    type(comparison_t), allocatable, intent(out) :: c(:)
    integer(i8), intent(out) :: nphot
    real(dp), intent(out) :: closure
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    integer :: nz, k, l, j, iv, idx, ilayer
    character(len=FLD) :: q, lev
    character(len=24) :: vname
    logical :: direct

    associate (cs => cases(i))
      nz = cs%nl
      call set_layers(cfg, cs%tau(1:nz), cs%omega(1:nz), cs%phase(1:nz), cs%g(1:nz))
      cfg%surface%albedo = cs%albedo
      cfg%source%sza_deg = cs%sza
      cfg%output%flux_levels = [(k, k=0, nz)]
      cfg%control%n_photons_per_batch = photons_per_batch(cs)
      cfg%control%n_batches = N_BATCHES
      ! one seed per case: cases that differ only in omega or albedo would otherwise follow
      ! the same photon paths, and their deviations would not be independent
      cfg%control%seed = SEED + i
      cfg%control%verbose = 0
      nphot = cfg%control%n_photons_per_batch*N_BATCHES

      call simulate(cfg, set, summary, error)
      if (allocated(error)) then
        error%message = trim(cs%id)//': '//error%message
        return
      end if
      iv = find_var(set, 'energy_closure')
      closure = abs(set%vars(iv)%mean(1) - 1.0_dp)

      allocate (c(size(cs%rows)))
      do j = 1, size(cs%rows)
        q = cs%rows(j)%quantity
        lev = cs%rows(j)%level
        idx = 1
        ilayer = 0
        select case (trim(q))
        case ('R')
          vname = 'reflectance'
        case ('T_total')
          vname = 'transmittance'
        case ('T_direct')
          vname = 'transmittance_direct'
        case ('T_diffuse')
          vname = 'transmittance_diffuse'
        case ('A_atm')
          vname = 'absorptance_atmosphere'
        case ('A_surface')
          vname = 'absorptance_surface'
        case ('F_up')
          vname = 'flux_up'
        case ('F_dif_down')
          vname = 'flux_down_diffuse'
        case ('F_dir_down')
          vname = 'flux_down_direct'
        case default
          if (q(1:7) == 'A_layer') then
            vname = 'absorptance_layer'
            read (q(8:), *) ilayer          ! counted from the top
            idx = nz + 1 - ilayer
          else
            call set_error(error, trim(cs%id)//': unknown quantity "'//trim(q)//'"')
            return
          end if
        end select
        if (len_trim(lev) > 0) then
          if (lev == 'TOA') then
            idx = nz + 1
          else if (lev == 'BOA') then
            idx = 1
          else if (lev(1:10) == 'interface_') then
            read (lev(11:), *) l            ! below the l-th layer from the top
            idx = nz - l + 1
          else
            call set_error(error, trim(cs%id)//': unknown level "'//trim(lev)//'"')
            return
          end if
        end if
        iv = find_var(set, trim(vname))
        if (iv == 0) then
          call set_error(error, 'kumo result has no variable '//trim(vname))
          return
        end if
        c(j)%icase = i
        c(j)%label = trim(q)
        if (len_trim(lev) > 0) c(j)%label = trim(q)//'('//trim(lev)//')'
        c(j)%x = set%vars(iv)%mean(idx)
        c(j)%sigma_hat = set%vars(iv)%stderr(idx)
        c(j)%ref = cs%rows(j)%value
        c(j)%sigma = c(j)%sigma_hat
        direct = q == 'T_direct' .or. q == 'F_dir_down'
        if (direct) c(j)%sigma = direct_sigma(c(j)%sigma_hat, c(j)%ref, nphot)
        ! zero by physics
        c(j)%zero = (q == 'F_dif_down' .and. lev == 'TOA') .or. &
                    (q == 'F_up' .and. lev == 'BOA' .and. is_exactly(cs%albedo, 0.0_dp)) .or. &
                    (q == 'A_atm' .and. all(is_exactly(cs%omega(1:nz), 1.0_dp)))
        if (ilayer > 0) c(j)%zero = is_exactly(cs%omega(ilayer), 1.0_dp)
        c(j)%floor = tiny_floor(c(j)%ref)
        c(j)%passed = abs(c(j)%x - c(j)%ref) <= K_SIGMA*c(j)%sigma + c(j)%floor
        c(j)%resolved = abs(c(j)%ref) >= TINY_REF .and. c(j)%sigma > SIGMA_EXACT
      end do
    end associate
  end subroutine run_case_compare

  ! ------------------------------------------------------------------------------------------
  ! Reading the reference table
  ! ------------------------------------------------------------------------------------------

  !> Read reference/disort_pp.csv into `cases` (once).
  subroutine load_table(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: path
    character(len=512) :: line
    character(len=FLD) :: f(12)
    integer :: unit, ios, nf, ic, line_no, n
    type(ref_row_t) :: row
    type(case_t) :: new_case

    if (allocated(cases)) return
    if (.not. allocated(shared_dir)) then
      call set_error(error, 'the shared data folder was not given on the command line')
      return
    end if
    path = shared_dir//'/reference/disort_pp.csv'
    call open_text(path, unit, error)
    if (allocated(error)) return
    allocate (cases(0))
    line_no = 0
    do
      read (unit, '(a)', iostat=ios) line
      if (ios == iostat_end) exit
      line_no = line_no + 1
      if (ios /= 0) then
        call set_error(error, path//': read error at line '//str(line_no))
        exit
      end if
      if (line_no == 1) cycle                     ! header
      if (len_trim(line) == 0) cycle
      call split(line, ',', f, nf)
      if (nf /= 12) then
        call set_error(error, path//': line '//str(line_no)//' has '//str(nf)//' fields')
        exit
      end if
      ! key on case_id: find it or add a new case
      ic = 0
      do n = size(cases), 1, -1
        if (cases(n)%id == f(1)) then
          ic = n
          exit
        end if
      end do
      if (ic == 0) then
        new_case = case_t()
        new_case%id = f(1)
        new_case%group = f(2)
        new_case%spec = f(3)
        read (f(4), *, iostat=ios) new_case%sza
        if (ios == 0) read (f(7), *, iostat=ios) new_case%albedo
        if (ios /= 0) then
          call set_error(error, path//': bad sza or albedo at line '//str(line_no))
          exit
        end if
        call parse_layers(f(3), new_case, error)
        if (allocated(error)) exit
        allocate (new_case%rows(0))
        cases = [cases, new_case]
        ic = size(cases)
      end if
      cases(ic)%n_rows_all = cases(ic)%n_rows_all + 1
      if (f(8) == 'pi_I_over_mu0F0') cycle
      row%quantity = f(8)
      row%level = f(9)
      read (f(12), *, iostat=ios) row%value
      if (ios /= 0) then
        call set_error(error, path//': bad value at line '//str(line_no))
        exit
      end if
      cases(ic)%rows = [cases(ic)%rows, row]
    end do
    close (unit)
    if (allocated(error) .and. allocated(cases)) deallocate (cases)
  end subroutine load_table

  !> Parse a layer_spec ("iso:tau=T:omega=W|hg:g=G:tau=T:omega=W|...", top first).
  subroutine parse_layers(spec, cs, error)
    character(len=*), intent(in) :: spec
    type(case_t), intent(inout) :: cs
    type(error_t), allocatable, intent(out) :: error
    character(len=FLD) :: layers(MAXL + 1), parts(8)
    integer :: nl, np, l, p, eq, ios
    real(dp) :: v
    call split(spec, '|', layers, nl)
    if (nl < 1 .or. nl > MAXL) then
      call set_error(error, 'layer_spec "'//trim(spec)//'": 1..'//str(MAXL)//' layers expected')
      return
    end if
    cs%nl = nl
    do l = 1, nl
      call split(layers(l), ':', parts, np)
      if (np > size(parts)) then
        call set_error(error, 'layer_spec "'//trim(spec)//'": more than '//str(size(parts))// &
                       ' items in layer '//str(l))
        return
      end if
      select case (trim(parts(1)))
      case ('iso', 'rayleigh', 'hg')
        cs%phase(l) = parts(1)
      case default
        call set_error(error, 'layer_spec "'//trim(spec)//'": unknown layer kind "'// &
                       trim(parts(1))//'"')
        return
      end select
      cs%tau(l) = -1.0_dp
      cs%omega(l) = -1.0_dp
      cs%g(l) = 0.0_dp
      do p = 2, np
        eq = index(parts(p), '=')
        ios = 1
        if (eq > 1) read (parts(p)(eq + 1:), *, iostat=ios) v
        if (ios /= 0) then
          call set_error(error, 'layer_spec "'//trim(spec)//'": bad item "'//trim(parts(p))//'"')
          return
        end if
        select case (parts(p)(1:eq - 1))
        case ('tau')
          cs%tau(l) = v
        case ('omega')
          cs%omega(l) = v
        case ('g')
          cs%g(l) = v
        case default
          call set_error(error, 'layer_spec "'//trim(spec)//'": unknown key "'// &
                         parts(p)(1:eq - 1)//'"')
          return
        end select
      end do
      if (cs%tau(l) < 0.0_dp .or. cs%omega(l) < 0.0_dp) then
        call set_error(error, 'layer_spec "'//trim(spec)//'": tau or omega missing')
        return
      end if
    end do
  end subroutine parse_layers


  ! ------------------------------------------------------------------------------------------
  ! Text helpers
  ! ------------------------------------------------------------------------------------------

  !> Text of comparison j.
  function describe(j) result(s)
    integer, intent(in) :: j
    character(len=:), allocatable :: s
    associate (c => cmp(j))
      s = trim(cases(c%icase)%id)//' '//trim(c%label)//': kumo '//str(c%x)//' +- '// &
          str(c%sigma)//', DISORT '//str(c%ref)
      if (c%sigma > 0.0_dp) s = s//', dev '//str((c%x - c%ref)/c%sigma)//' sigma'
    end associate
  end function describe

  !> x == v, written without == to keep -Wcompare-reals quiet.
  elemental logical function is_exactly(x, v)
    real(dp), intent(in) :: x, v
    is_exactly = .not. (x > v .or. x < v)
  end function is_exactly


end module test_kumo_disort_pp

program test_disort_pp
  use test_kumo_disort_pp, only: collect_disort_pp
  use kumo_test_text, only: run_shared_suite
  implicit none
  call run_shared_suite('test_disort_pp', 'reference/disort_pp.csv', &
                        'kumo vs DISORT plane-parallel (reference/disort_pp.csv)', &
                        collect_disort_pp())
end program test_disort_pp
