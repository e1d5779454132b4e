! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_spectral: the g-point sampling plan (systematic allocation, weights, floor
!> share; exact expectations over the batch offset; an estimator of a broadband transmission
!> within 4 standard errors of the exact sum over g-points) and the spectral columns against the
!> per-g-point optical depths and sources of jax-rrtmgp that the 1-D reference fluxes of
!> tests/data/broadband/{sw,lw}_gpoint_reference.txt were computed with
!> (bench/broadband/make_gpoint_reference.py).
!>
!> Tolerance of the column comparison: as in test_gas_optics (same gas optics, both codes in
!> double precision, the file keeps 10 significant digits): 1e-8 relative plus 1e-12 of the
!> largest value of the row.
!>
!> With the third argument `mc` the program runs instead the Monte Carlo check of the chain
!> (label bench): kumo's photon loop (`trace_batch`, one plane-parallel scene per g-point built
!> from kumo's spectral column) with the g-points and weights of the plan reproduces the
!> broadband shortwave fluxes at every level and the heating rate of every layer of the
!> discrete-ordinates reference within 4.5 standard errors.
!>
!> Arguments: the folder of the k-distribution files (CMake KUMO_RRTMGP_DIR, filled by
!> scripts/fetch-rrtmgp.sh), the folder of the reference files, optionally `mc` and then
!> optionally a floor share for both columns of the Monte Carlo check (docs/broadband.md).
module test_spectral_suite
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use kumo_kinds, only: wp, i8
  use kumo_constants, only: PI, STEFAN_BOLTZMANN, RAD2DEG
  use kumo_error, only: str
  use kumo_rng, only: rng_t, rng_init, rng_uniform
  use kumo_phase, only: new_phase_rayleigh
  use kumo_atmosphere, only: atmosphere_options_t, atmosphere_init
  use kumo_surface, only: surface_init
  use kumo_camera, only: camera_t
  use kumo_local_estimate, only: detectors_init
  use kumo_tally, only: tally_layout_t, tally_t, layout_init, tally_reset
  use kumo_source, only: solar_source
  use kumo_scene, only: scene_t
  use kumo_transport, only: trace_batch
  use kumo_expint, only: expint_e
  use kumo_gas_optics, only: gas_kdist_t, gas_index
  use kumo_rrtmgp_file, only: read_rrtmgp_kdist
  use kumo_spectral, only: spectral_column_t, spectral_sw_column, spectral_lw_column, &
                           spectral_column_bytes, spectral_plan_t, spectral_plan_init, &
                           spectral_batch_t, spectral_begin_batch, spectral_batch_from_u, &
                           spectral_photon_gpoint
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_sigma, &
                          check_error_words
  implicit none
  private
  public :: collect_spectral, collect_spectral_mc, rrtmgp_dir, reference_dir, mc_floor_share

  real(wp), parameter :: REL_TOL = 1.0e-8_wp
  real(wp), parameter :: ROW_FLOOR = 1.0e-12_wp
  character(len=:), allocatable :: rrtmgp_dir, reference_dir
  !> Floor share of the Monte Carlo check for both columns (4th argument); negative: the test's
  !> own choice (0.05 for RFMIP, 0 for the U.S. Standard).
  real(wp) :: mc_floor_share = -1

  !> One column of the reference file.
  type :: ref_column_t
    character(len=32) :: name = ''
    character(len=64) :: kdist = ''
    integer :: nl = 0, ng = 0
    real(wp) :: mu0 = 0, albedo = 0, tsi = 0, tsfc = 0, emissivity = 0
    real(wp), allocatable :: plev(:), tlev(:), play(:), tlay(:), cd(:), vmr(:, :)
    real(wp), allocatable :: solar(:), tau(:, :), tray(:, :), sfc(:), bot(:, :), top(:, :)
    real(wp) :: direct_sfc = 0                      !! broadband direct flux at the surface
    real(wp), allocatable :: bb(:, :)               !! (0:nl, 5) broadband row (SW: up, dif, dir, errors)
    real(wp), allocatable :: heat(:, :)             !! (nl, 2) heating K/day and its error
  end type ref_column_t

contains

  function collect_spectral() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('floor_rule', test_floor_rule), &
             new_unittest('counts_sum_and_bounds', test_counts), &
             new_unittest('exact_expectation_over_u', test_expectation), &
             new_unittest('batch_total_exact', test_total_exact), &
             new_unittest('estimator_within_4_sigma', test_estimator), &
             new_unittest('plan_bad_inputs', test_plan_errors), &
             new_unittest('sw_column_vs_reference', test_sw_reference), &
             new_unittest('lw_column', test_lw_column), &
             new_unittest('lw_column_vs_reference', test_lw_reference), &
             new_unittest('sw_direct_sampled_vs_disort', test_sw_direct_sampled)]
  end function collect_spectral

  function collect_spectral_mc() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('sw_broadband_mc_vs_disort', test_sw_broadband_mc)]
  end function collect_spectral_mc

  !> Energies spanning eleven decades, with two g-points without energy.
  pure function test_energies() result(e)
    real(wp) :: e(24)
    integer :: g
    do g = 1, size(e)
      e(g) = 10.0_wp**(2 - mod(7 * g, 12)) * (1 + 0.1_wp * g)
    end do
    e(5) = 0
    e(24) = 0
  end function test_energies

  subroutine test_floor_rule(error)
    type(error_t), allocatable, intent(out) :: error
    type(spectral_plan_t) :: plan
    type(error_t), allocatable :: err
    real(wp) :: e(24), a
    integer :: k
    e = test_energies()
    do k = 0, 2
      a = 0.25_wp * k
      call spectral_plan_init(e, plan, err, floor_share=a)
      call check(error, .not. allocated(err), 'plan_init failed')
      if (allocated(error)) return
      call check_close(error, sum(plan%prob), 1.0_wp, rel_tol=1.0e-14_wp, label='sum of p_g')
      call check(error, plan%n_active == 22, 'n_active = ' // str(plan%n_active))
      call check(error, all(pack(plan%prob, e > 0) >= a / 22 * (1 - 1.0e-14_wp)), &
                 'a g-point with energy has p_g < a / N+ for a = ' // str(a))
      call check(error, all(pack(plan%prob, e <= 0) == 0), 'a g-point without energy has p_g > 0')
      call check_close(error, plan%prob(3), (1 - a) * e(3) / sum(e) + a / 22, rel_tol=1.0e-13_wp, &
                       label='p_3')
      call check(error, plan%cum(0) == 0 .and. plan%cum(24) == 1 .and. plan%cum(23) == 1, &
                 'cumulative table does not run from 0 to exactly 1')
      call check(error, all(plan%cum(1:) >= plan%cum(:23)), 'cumulative table decreases')
    end do
  end subroutine test_floor_rule

  !> Counts add up to n, lie within 1 of n p_g, g-points without energy get none; the photons
  !> of a g-point are consecutive (spectral_photon_gpoint agrees with first/count).
  subroutine test_counts(error)
    type(error_t), allocatable, intent(out) :: error
    type(spectral_plan_t) :: plan
    type(spectral_batch_t) :: batch
    type(error_t), allocatable :: err
    integer(i8), parameter :: NS(6) = [1_i8, 2_i8, 7_i8, 100_i8, 12345_i8, 10000000019_i8]
    real(wp) :: e(24), u, dev
    integer :: k, iu, ia, g
    integer(i8) :: ip
    e = test_energies()
    do ia = 0, 1
      call spectral_plan_init(e, plan, err, floor_share=0.1_wp * ia)
      do k = 1, size(NS)
        do iu = 0, 40
          u = min(iu / 40.0_wp, 1 - epsilon(1.0_wp))
          call spectral_batch_from_u(plan, NS(k), u, batch)
          call check(error, sum(batch%count) == NS(k), 'counts add up to ' // str(sum(batch%count)) // &
                     ', not n = ' // str(NS(k)))
          call check(error, all(batch%count >= 0), 'negative count')
          dev = maxval(abs(real(batch%count, wp) - real(NS(k), wp) * plan%prob))
          call check(error, dev < 1 + 1.0e-6_wp, 'a count is ' // str(dev) // ' from n p_g, n = ' // &
                     str(NS(k)) // ', u = ' // str(u))
          call check(error, all(pack(batch%count, e <= 0) == 0), 'a g-point without energy got photons')
          if (allocated(error)) return
          if (NS(k) <= 12345) then
            do ip = 1, NS(k)
              g = spectral_photon_gpoint(batch, ip)
              call check(error, ip >= batch%first(g) .and. ip < batch%first(g) + batch%count(g), &
                         'photon ' // str(ip) // ' maps to g-point ' // str(g) // ' outside its range')
            end do
            if (allocated(error)) return
          end if
        end do
      end do
    end do
  end subroutine test_counts

  !> E_u[n_g w_g] = S_g for every g-point and E_u[sum of the weights] = S, integrated exactly
  !> over the offset u (the counts are constant between the points u = frac(n C_g)).
  subroutine test_expectation(error)
    type(error_t), allocatable, intent(out) :: error
    type(spectral_plan_t) :: plan
    type(spectral_batch_t) :: batch
    type(error_t), allocatable :: err
    integer(i8), parameter :: NS(4) = [1_i8, 5_i8, 37_i8, 1000_i8]
    real(wp) :: e(24), brk(26), expect(24), pcount(24), x, tmp, imp(24)
    integer :: k, ia, g, i, j, nb
    e = test_energies()
    do ia = 0, 2
      if (ia < 2) then
        call spectral_plan_init(e, plan, err, floor_share=0.2_wp * ia)
      else
        ! Probabilities that follow an importance other than the energy (sqrt(S_g)); a g-point
        ! without energy but with importance is never drawn (its photons would carry no
        ! weight: a longwave gpoint run drew them, and a batch of them alone closed as 0/0).
        imp = sqrt(e)
        imp(24) = 1
        call spectral_plan_init(e, plan, err, floor_share=0.1_wp, importance=imp)
        call check(error, .not. allocated(err) .and. plan%n_active == 22, 'plan with importance')
        call check(error, plan%prob(24) == 0 .and. plan%prob(5) == 0, &
                   'a g-point without energy has p_g > 0')
        call check_close(error, plan%prob(3), 0.9_wp * imp(3) / (sum(imp) - imp(24)) + 0.1_wp / 22, &
                         rel_tol=1.0e-13_wp, label='p_3 from the importance')
        if (allocated(error)) return
      end if
      do k = 1, size(NS)
        brk(1) = 0
        brk(2) = 1
        do g = 1, 24
          x = real(NS(k), wp) * plan%cum(g)
          brk(2 + g) = x - floor(x)
        end do
        nb = 26
        do i = 2, nb                                 ! insertion sort
          tmp = brk(i)
          j = i - 1
          do while (j >= 1)
            if (brk(j) <= tmp) exit
            brk(j + 1) = brk(j)
            j = j - 1
          end do
          brk(j + 1) = tmp
        end do
        expect = 0
        pcount = 0
        do i = 1, nb - 1
          if (brk(i + 1) <= brk(i)) cycle
          call spectral_batch_from_u(plan, NS(k), 0.5_wp * (brk(i) + brk(i + 1)), batch)
          expect = expect + (brk(i + 1) - brk(i)) * batch%count * batch%weight
          pcount = pcount + (brk(i + 1) - brk(i)) * batch%count
        end do
        do g = 1, 24
          call check_close(error, expect(g), e(g), rel_tol=1.0e-12_wp, abs_tol=1.0e-14_wp * sum(e), &
                           label='E[n_g w_g] of g-point ' // str(g) // ', n = ' // str(NS(k)))
          call check_close(error, pcount(g), NS(k) * plan%prob(g), rel_tol=1.0e-12_wp, &
                           abs_tol=1.0e-12_wp, label='E[n_g] of g-point ' // str(g))
        end do
        call check_close(error, sum(expect), sum(e), rel_tol=1.0e-12_wp, label='E[sum of weights]')
        if (allocated(error)) return
      end do
    end do
  end subroutine test_expectation

  !> When every g-point with energy has n p_g >= 1 (floor share a and n >= N+ / a, or a = 0 and
  !> n large), every one gets a photon in every batch and the weights add up to S exactly.
  subroutine test_total_exact(error)
    type(error_t), allocatable, intent(out) :: error
    type(spectral_plan_t) :: plan
    type(spectral_batch_t) :: batch
    type(error_t), allocatable :: err
    real(wp) :: e(24)
    integer :: iu, g
    e = test_energies()
    call spectral_plan_init(e, plan, err, floor_share=0.2_wp)
    do iu = 0, 20
      call spectral_batch_from_u(plan, 110_i8, iu / 21.0_wp, batch)   ! N+ / a = 110
      call check(error, all(pack(batch%count, e > 0) >= 1), 'a g-point with energy got no photon')
      call check_close(error, sum(batch%count * batch%weight), sum(e), rel_tol=1.0e-13_wp, &
                       label='sum of weights, a = 0.2')
    end do
    e = [(1.0_wp + g, g = 1, 24)]
    call spectral_plan_init(e, plan, err)
    do iu = 0, 20
      call spectral_batch_from_u(plan, 1000_i8, iu / 21.0_wp, batch)
      call check_close(error, sum(batch%count * batch%weight), sum(e), rel_tol=1.0e-13_wp, &
                       label='sum of weights, a = 0')
    end do
  end subroutine test_total_exact

  !> The plan as it will be used: a photon of g-point g crosses a layer with probability
  !> T_g = exp(-tau_g / mu0) and scores w_g if it does. The batch means estimate
  !> sum_g S_g T_g, which must lie within 4 standard errors (from the spread of 400 batches).
  subroutine test_estimator(error)
    type(error_t), allocatable, intent(out) :: error
    type(spectral_plan_t) :: plan
    type(spectral_batch_t) :: batch
    type(rng_t) :: rng
    type(error_t), allocatable :: err
    integer, parameter :: NB = 400
    integer(i8), parameter :: NS(3) = [2000_i8, 20_i8, 150_i8]
    real(wp), parameter :: SHARE(3) = [0.0_wp, 0.0_wp, 0.3_wp]
    real(wp) :: e(24), trans(24), est, s1, s2, mean, sig, exact
    integer :: k, b, g
    integer(i8) :: ip
    e = test_energies()
    trans = [(exp(-0.3_wp * g), g = 1, 24)]
    exact = sum(e * trans)
    do k = 1, 3
      call spectral_plan_init(e, plan, err, floor_share=SHARE(k))
      s1 = 0
      s2 = 0
      do b = 1, NB
        call rng_init(rng, 20261127_i8, int(b + 1000 * k, i8))
        call spectral_begin_batch(plan, NS(k), rng, batch, err)
        est = 0
        do g = 1, 24
          do ip = 1, batch%count(g)
            if (rng_uniform(rng) < trans(g)) est = est + batch%weight(g)
          end do
        end do
        s1 = s1 + est
        s2 = s2 + est**2
      end do
      mean = s1 / NB
      sig = sqrt(max(s2 / NB - mean**2, 0.0_wp) / (NB - 1))
      write (*, '(a, i0, a, f5.2, a, es12.5, a, es12.5, a, es9.2)') '  n = ', NS(k), ', a = ', &
        SHARE(k), ': estimate ', mean, ', exact ', exact, ', sigma ', sig
      call check(error, sig > 0, 'no spread between batches')
      call check_sigma(error, mean, exact, sig, 4.0_wp, 'broadband transmission, n = ' // str(NS(k)))
    end do
  end subroutine test_estimator

  subroutine test_plan_errors(error)
    type(error_t), allocatable, intent(out) :: error
    type(spectral_plan_t) :: plan
    type(spectral_batch_t) :: batch
    type(rng_t) :: rng
    type(error_t), allocatable :: err
    real(wp) :: e(3)
    e = [1.0_wp, -2.0_wp, 3.0_wp]
    call spectral_plan_init(e, plan, err)
    call check_error_words(error, err, [character(len=24) :: 'g-point 2', '-2', '>= 0'])
    e = [1.0_wp, ieee_value(1.0_wp, ieee_quiet_nan), 3.0_wp]
    call spectral_plan_init(e, plan, err)
    call check_error_words(error, err, [character(len=24) :: 'g-point 2', 'finite'])
    e = 0
    call spectral_plan_init(e, plan, err)
    call check_error_words(error, err, [character(len=24) :: 'add up to', 'positive'])
    e = 1
    call spectral_plan_init(e, plan, err, floor_share=1.0_wp)
    call check_error_words(error, err, [character(len=24) :: 'floor_share', '[0, 1)'])
    call spectral_plan_init(e, plan, err, floor_share=ieee_value(1.0_wp, ieee_quiet_nan))
    call check_error_words(error, err, [character(len=24) :: 'floor_share = NaN', '[0, 1)'])
    call spectral_plan_init(e, plan, err)
    call rng_init(rng, 1_i8, 1_i8)
    call spectral_begin_batch(plan, 0_i8, rng, batch, err)
    call check_error_words(error, err, [character(len=24) :: 'n = 0', '>= 1'])
    call spectral_plan_init(e, plan, err, importance=[1.0_wp, 0.0_wp, 1.0_wp])
    call check_error_words(error, err, [character(len=24) :: 'importance of g-point 2', '> 0 where'])
    call spectral_plan_init(e, plan, err, importance=[1.0_wp, 1.0_wp])
    call check_error_words(error, err, [character(len=24) :: 'importance has 2', '3 g-points'])
  end subroutine test_plan_errors

  ! ------------------------------------------------------------------------------------------


  !> The columns of a reference file, their gases mapped onto the k-distribution `kd`.
  subroutine read_reference(kd, reference_file, cols, error)
    type(gas_kdist_t), intent(in) :: kd
    character(len=*), intent(in) :: reference_file
    type(ref_column_t), allocatable, intent(out) :: cols(:)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: LINE_LEN = 8192
    character(len=LINE_LEN) :: line
    character(len=32) :: key
    character(len=32), allocatable :: names(:)
    type(ref_column_t) :: c
    real(wp), allocatable :: row(:)
    integer :: u, ios, ngas, idx, i, nq, nqc
    allocate (cols(0))
    open (newunit=u, file=reference_file, status='old', action='read', iostat=ios)
    call check(error, ios == 0, 'cannot open the reference file ' // reference_file)
    if (allocated(error)) return
    do
      read (u, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (len_trim(line) == 0 .or. line(1:1) == '#') cycle
      read (line, *) key
      select case (trim(key))
      case ('case')
        c = ref_column_t()
        read (line, *) key, c%name, c%kdist, c%nl, ngas, c%ng
        allocate (names(ngas), c%plev(0:c%nl), c%tlev(0:c%nl), c%play(c%nl), c%tlay(c%nl), &
                  c%cd(c%nl), c%vmr(c%nl, kd%n_gas), c%solar(c%ng), c%tau(c%nl, c%ng), &
                  c%tray(c%nl, c%ng), c%sfc(c%ng), c%bot(c%nl, c%ng), c%top(c%nl, c%ng), &
                  c%bb(0:c%nl, 5), c%heat(c%nl, 2), row(3 + ngas))
        c%bb = 0
        c%vmr = 0
      case ('gases')
        read (line, *) key, names
      case ('setup')
        if (kd%longwave) then
          read (line, *) key, c%tsfc, c%emissivity, nq, nqc
        else
          read (line, *) key, c%mu0, c%albedo, c%tsi, nq, nqc
        end if
      case ('level')
        read (line, *) key, idx, c%plev(idx), c%tlev(idx)
      case ('layer')
        read (line, *) key, idx, row
        c%play(idx) = row(1)
        c%tlay(idx) = row(2)
        c%cd(idx) = row(3)
        do i = 1, size(names)
          call check(error, gas_index(kd, names(i)) > 0, 'unknown gas ' // trim(names(i)))
          if (allocated(error)) return
          c%vmr(idx, gas_index(kd, names(i))) = row(3 + i)
        end do
      case ('solar_flux')
        read (line, *) key, idx, c%solar
      case ('tau')
        read (line, *) key, idx, c%tau(idx, :)
      case ('tau_rayleigh')
        read (line, *) key, idx, c%tray(idx, :)
      case ('broadband')
        read (line, *) key, idx
        if (kd%longwave) then
          read (line, *) key, idx, c%bb(idx, 1:4)
        else
          read (line, *) key, idx, c%bb(idx, 1:5)
        end if
        if (idx == 0 .and. .not. kd%longwave) c%direct_sfc = c%bb(0, 3)
      case ('heating')
        read (line, *) key, idx, c%heat(idx, :)
      case ('sfc_src')
        read (line, *) key, idx, c%sfc
      case ('lev_src_bot')
        read (line, *) key, idx, c%bot(idx, :)
      case ('lev_src_top')
        read (line, *) key, idx, c%top(idx, :)
      case ('end')
        cols = [cols, c]
        deallocate (names, row)
      case default
        continue                                     ! per-g-point fluxes, heating: not used here
      end select
    end do
    close (u)
    call check(error, size(cols) > 0, 'no columns in ' // reference_file)
  end subroutine read_reference

  !> Largest difference relative to REL_TOL |ref| + ROW_FLOOR max|row| over a (n_layer, n_gpt)
  !> table, rows being the layers (<= 1: passes).
  pure real(wp) function worst_ratio(got, ref) result(w)
    real(wp), intent(in) :: got(:, :), ref(:, :)
    integer :: l
    w = 0
    do l = 1, size(ref, 1)
      w = max(w, maxval(abs(got(l, :) - ref(l, :)) / &
                        (REL_TOL * abs(ref(l, :)) + ROW_FLOOR * maxval(abs(ref(l, :))) + tiny(1.0_wp))))
    end do
  end function worst_ratio

  subroutine load(name, kd, error)
    character(len=*), intent(in) :: name
    type(gas_kdist_t), intent(out) :: kd
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    call read_rrtmgp_kdist(rrtmgp_dir // '/' // name, kd, err)
    if (allocated(err)) call check(error, .false., err%message // &
                                   ' (run scripts/fetch-rrtmgp.sh to fetch the files)')
  end subroutine load

  !> The shortwave column reproduces the optical depths, single-scattering albedos and solar
  !> fluxes of the reference; the broadband TOA flux on a horizontal surface is TSI mu0.
  subroutine test_sw_reference(error)
    type(error_t), allocatable, intent(out) :: error
    type(gas_kdist_t) :: kd
    type(ref_column_t), allocatable :: cols(:)
    type(spectral_column_t) :: col, col2
    type(error_t), allocatable :: err
    real(wp), allocatable :: ssa_ref(:, :)
    real(wp) :: w
    integer :: i, rep
    integer(i8) :: t0, t1, rate
    call load('rrtmgp-gas-sw-g112.nc', kd, error)
    if (allocated(error)) return
    call read_reference(kd, reference_dir // '/sw_gpoint_reference.txt', cols, error)
    if (allocated(error)) return
    do i = 1, size(cols)
      associate (c => cols(i))
        call spectral_sw_column(kd, c%plev, c%play, c%tlay, c%vmr, c%mu0, col, err, col_dry=c%cd, &
                                tsi=c%tsi)
        call check(error, .not. allocated(err), 'spectral_sw_column failed')
        if (allocated(error)) return
        w = worst_ratio(col%tau_abs, c%tau)
        write (*, '(a, es9.2)') '  ' // trim(c%name) // ': absorption optical depth, worst / tolerance ', w
        call check(error, w <= 1, trim(c%name) // ': absorption optical depth off by ' // str(w) // &
                   ' times the tolerance')
        w = worst_ratio(col%tau_rayleigh, c%tray)
        call check(error, w <= 1, trim(c%name) // ': Rayleigh optical depth off by ' // str(w) // &
                   ' times the tolerance')
        ssa_ref = c%tray / (c%tau + c%tray)
        call check(error, maxval(abs(col%ssa - ssa_ref)) < 1.0e-8_wp, trim(c%name) // &
                   ': single-scattering albedo off by ' // str(maxval(abs(col%ssa - ssa_ref))))
        call check(error, worst_ratio(reshape(col%solar_flux, [1, c%ng]), reshape(c%solar, [1, c%ng])) &
                   <= 1, trim(c%name) // ': solar flux per g-point differs')
        call check_close(error, sum(col%energy), c%tsi * c%mu0, rel_tol=1.0e-13_wp, &
                         label=trim(c%name) // ': broadband TOA flux vs TSI mu0')
        call check_close(error, col%tsi, c%tsi, rel_tol=1.0e-13_wp, label='tsi')
        call check(error, size(col%tau_abs, 1) == c%nl .and. size(col%tau_abs, 2) == 112, &
                   'tau_abs is not (n_layer, n_gpt)')
        ! The dry-air column from the level pressures (no col_dry given) is the reference's.
        call spectral_sw_column(kd, c%plev, c%play, c%tlay, c%vmr, c%mu0, col2, err)
        call check(error, .not. allocated(err), 'spectral_sw_column without col_dry failed')
        if (allocated(error)) return
        call check(error, maxval(abs(col2%col_dry / c%cd - 1)) < 1.0e-12_wp, trim(c%name) // &
                   ': dry-air column from the levels differs by ' // str(maxval(abs(col2%col_dry / c%cd - 1))))
        if (i == 1) then
          write (*, '(a, i0, a, i0, a, f0.1, a)') '  column of ', c%nl, ' layers, ', c%ng, &
            ' g-points: ', spectral_column_bytes(col) / 1.0e3_wp, ' kB'
          ! Cost of building a column (reported, not checked).
          call system_clock(t0, rate)
          do rep = 1, 50
            call spectral_sw_column(kd, c%plev, c%play, c%tlay, c%vmr, c%mu0, col2, err, col_dry=c%cd)
          end do
          call system_clock(t1)
          write (*, '(a, f0.3, a, f0.1, a)') '  spectral_sw_column: ', real(t1 - t0, wp) / rate / 50 * 1.0e3_wp, &
            ' ms per column, ', real(t1 - t0, wp) / rate / 50 / (c%nl * c%ng) * 1.0e9_wp, ' ns per layer and g-point'
        end if
      end associate
    end do
    ! Bad inputs name the input and the bound.
    associate (c => cols(1))
      call spectral_sw_column(kd, c%plev, c%play, c%tlay, c%vmr, 0.0_wp, col, err)
      call check_error_words(error, err, [character(len=24) :: 'mu0 = 0', '(0, 1]'])
      call spectral_sw_column(kd, c%plev, c%play, c%tlay, c%vmr, ieee_value(1.0_wp, ieee_quiet_nan), col, err)
      call check_error_words(error, err, [character(len=24) :: 'mu0 = NaN', '(0, 1]'])
      call spectral_sw_column(kd, c%plev(1:), c%play, c%tlay, c%vmr, 0.5_wp, col, err)
      call check_error_words(error, err, [character(len=24) :: 'plev has', 'levels'])
      call spectral_lw_column(kd, c%plev, c%tlev, c%play, c%tlay, 290.0_wp, c%vmr, col, err)
      call check_error_words(error, err, [character(len=24) :: 'shortwave one'])
    end associate
  end subroutine test_sw_reference

  !> Longwave column of the first reference profile: shapes, the surface emission summed over
  !> g-points against eps sigma T^4, the emitted power of the layers, input checks.
  subroutine test_lw_column(error)
    type(error_t), allocatable, intent(out) :: error
    type(gas_kdist_t) :: kd, kd_sw
    type(ref_column_t), allocatable :: cols(:)
    type(spectral_column_t) :: col
    type(spectral_plan_t) :: plan
    type(error_t), allocatable :: err
    real(wp), parameter :: TSFC = 294.2_wp, EPS = 0.96_wp
    real(wp) :: layer_power, opaque, tmax
    integer :: g, l, gt, go
    call load('rrtmgp-gas-sw-g112.nc', kd_sw, error)
    if (allocated(error)) return
    call read_reference(kd_sw, reference_dir // '/sw_gpoint_reference.txt', cols, error)
    if (allocated(error)) return
    call load('rrtmgp-gas-lw-g128.nc', kd, error)
    if (allocated(error)) return
    associate (c => cols(1))
      call spectral_lw_column(kd, c%plev, c%tlev, c%play, c%tlay, TSFC, c%vmr, col, err, &
                              emissivity=EPS)
      call check(error, .not. allocated(err), 'spectral_lw_column failed')
      if (allocated(error)) return
      call check(error, all(shape(col%lev_src_top) == [c%nl, 128]), 'source arrays not (n_layer, n_gpt)')
      ! The fractions and the tables' band integrals close to sigma T^4 within 1 %.
      call check_close(error, sum(col%emission_sfc), EPS * STEFAN_BOLTZMANN * TSFC**4, rel_tol=1.0e-2_wp, &
                       label='surface emission summed over g-points')
      ! Emitted power of the layers: 4 pi tau (B_bot + B_top) / 2, checked for one g-point by a
      ! loop written out here, and positive for every g-point.
      g = 37
      layer_power = 0
      do l = 1, c%nl
        layer_power = layer_power + 2 * PI * col%tau_abs(l, g) * (col%lev_src_bot(l, g) + col%lev_src_top(l, g))
      end do
      call check_close(error, col%emission_atm(g), layer_power, rel_tol=1.0e-13_wp, label='layer emission')
      call check(error, all(col%energy > 0), 'a g-point emits nothing')
      call check_close(error, sum(col%energy), sum(col%emission_sfc) + sum(col%emission_atm), &
                       rel_tol=1.0e-14_wp, label='energy')
      call spectral_plan_init(col%energy, plan, err)
      call check(error, .not. allocated(err), 'plan of the longwave column failed')
      ! Power leaving the emitting layers: 4 pi Bmean (1/2 - E3(tau)), here with E3 itself;
      ! thin layers let all of it out, opaque ones pi (B_bot + B_top).
      layer_power = 0
      do l = 1, c%nl
        layer_power = layer_power + 2 * PI * (0.5_wp - expint_e(3, col%tau_abs(l, g))) * &
                      (col%lev_src_bot(l, g) + col%lev_src_top(l, g))
      end do
      call check_close(error, col%escape_atm(g), layer_power, rel_tol=1.0e-10_wp, label='escaping power')
      call check(error, all(col%escape_atm <= col%emission_atm * (1 + 1.0e-12_wp)), &
                 'more power escapes than is emitted')
      gt = minloc(maxval(col%tau_abs, dim=1), dim=1)
      ! 1/2 - E3(tau) = tau (1 + (tau/2) (ln tau + 0.5772 - 3/2) + O(tau^2))
      tmax = maxval(col%tau_abs(:, gt))
      call check(error, tmax < 0.05_wp, 'no g-point transparent in every layer')
      call check_close(error, col%escape_atm(gt), col%emission_atm(gt), rel_tol=tmax * (1 + abs(log(tmax))), &
                       label='escaping power of the most transparent g-point')
      go = maxloc(minval(col%tau_abs, dim=1), dim=1)
      call check(error, minval(col%tau_abs(:, go)) > 40, 'no g-point opaque in every layer')
      call check_close(error, col%escape_atm(go), PI * sum(col%lev_src_bot(:, go) + col%lev_src_top(:, go)), &
                       rel_tol=1.0e-15_wp, label='escaping power of an opaque g-point')
      call check_close(error, sum(col%energy_escape), sum(col%emission_sfc) + sum(col%escape_atm), &
                       rel_tol=1.0e-14_wp, label='energy_escape')
      call spectral_plan_init(col%energy, plan, err, importance=col%energy_escape)
      call check(error, .not. allocated(err), 'plan with the escaping power as importance failed')
      ! How much of the emitted power comes from g-points whose column is opaque (tau > 10).
      opaque = sum(col%energy, mask=sum(col%tau_abs, dim=1) > 10) / sum(col%energy)
      write (*, '(a, es11.4, a, es11.4, a, es11.4, a, f6.3, a, f6.3)') '  longwave: surface emission ', &
        sum(col%emission_sfc), ' W m-2, column emission ', sum(col%emission_atm), ', leaving the layers ', &
        sum(col%escape_atm), ' W m-2; share of g-points with column tau > 10 in the emission: ', &
        opaque, ', in the escaping power: ', &
        sum(col%energy_escape, mask=sum(col%tau_abs, dim=1) > 10) / sum(col%energy_escape)
      call spectral_lw_column(kd, c%plev, c%tlev, c%play, c%tlay, TSFC, c%vmr, col, err, emissivity=1.5_wp)
      call check_error_words(error, err, [character(len=24) :: 'emissivity = 1.5', '[0, 1]'])
    end associate
  end subroutine test_lw_column

  !> The longwave column reproduces the optical depths and Planck sources of the longwave
  !> reference (layers, bottom and top levels, surface) and its emission adds them up.
  subroutine test_lw_reference(error)
    type(error_t), allocatable, intent(out) :: error
    type(gas_kdist_t) :: kd
    type(ref_column_t), allocatable :: cols(:)
    type(spectral_column_t) :: col
    type(error_t), allocatable :: err
    real(wp) :: w
    integer :: i
    call load('rrtmgp-gas-lw-g128.nc', kd, error)
    if (allocated(error)) return
    call read_reference(kd, reference_dir // '/lw_gpoint_reference.txt', cols, error)
    if (allocated(error)) return
    do i = 1, size(cols)
      associate (c => cols(i))
        call spectral_lw_column(kd, c%plev, c%tlev, c%play, c%tlay, c%tsfc, c%vmr, col, err, &
                                col_dry=c%cd, emissivity=c%emissivity)
        call check(error, .not. allocated(err), 'spectral_lw_column failed')
        if (allocated(error)) return
        w = max(worst_ratio(col%tau_abs, c%tau), worst_ratio(col%lev_src_bot, c%bot), &
                worst_ratio(col%lev_src_top, c%top), &
                worst_ratio(reshape(col%sfc_src, [1, c%ng]), reshape(c%sfc, [1, c%ng])))
        write (*, '(a, es9.2)') '  ' // trim(c%name) // ' (longwave): optical depths and sources, ' // &
          'worst / tolerance ', w
        call check(error, w <= 1, trim(c%name) // ': longwave optics off by ' // str(w) // &
                   ' times the tolerance')
        call check_close(error, sum(col%emission_sfc), PI * c%emissivity * sum(c%sfc), rel_tol=1.0e-8_wp, &
                         label='surface emission')
        call check_close(error, sum(col%emission_atm), 2 * PI * sum(c%tau * (c%bot + c%top)), &
                         rel_tol=1.0e-8_wp, label='emission of the layers')
      end associate
    end do
  end subroutine test_lw_reference

  !> End to end without the photon loop: kumo's shortwave column and the sampling plan estimate
  !> the broadband direct flux at the surface of the reference columns (photons of g-point g
  !> reach the surface with probability exp(-tau_g / mu0)), within 4 standard errors of the
  !> discrete-ordinates value; the sum over g-points of kumo's Beer's law matches it to 1e-8.
  subroutine test_sw_direct_sampled(error)
    type(error_t), allocatable, intent(out) :: error
    type(gas_kdist_t) :: kd
    type(ref_column_t), allocatable :: cols(:)
    type(spectral_column_t) :: col
    type(spectral_plan_t) :: plan
    type(spectral_batch_t) :: batch
    type(rng_t) :: rng
    type(error_t), allocatable :: err
    integer, parameter :: NB = 100
    integer(i8), parameter :: N = 4000
    real(wp), allocatable :: trans(:)
    real(wp) :: s1, s2, est, mean, sig
    integer :: i, k, b, g
    integer(i8) :: ip
    call load('rrtmgp-gas-sw-g112.nc', kd, error)
    if (allocated(error)) return
    call read_reference(kd, reference_dir // '/sw_gpoint_reference.txt', cols, error)
    if (allocated(error)) return
    do i = 1, size(cols)
      associate (c => cols(i))
        call spectral_sw_column(kd, c%plev, c%play, c%tlay, c%vmr, c%mu0, col, err, tsi=c%tsi)
        call check(error, .not. allocated(err), 'spectral_sw_column failed')
        if (allocated(error)) return
        trans = exp(-sum(col%tau_abs + col%tau_rayleigh, dim=1) / c%mu0)
        call check_close(error, sum(col%energy * trans), c%direct_sfc, rel_tol=1.0e-8_wp, &
                         label=trim(c%name) // ': direct flux at the surface, sum over g-points')
        do k = 0, 1
          call spectral_plan_init(col%energy, plan, err, floor_share=0.1_wp * k)
          s1 = 0
          s2 = 0
          do b = 1, NB
            call rng_init(rng, 77_i8 + i, int(b + 1000 * k, i8))
            call spectral_begin_batch(plan, N, rng, batch, err)
            est = 0
            do g = 1, plan%n_gpt
              do ip = 1, batch%count(g)
                if (rng_uniform(rng) < trans(g)) est = est + batch%weight(g)
              end do
            end do
            s1 = s1 + est
            s2 = s2 + est**2
          end do
          mean = s1 / NB
          sig = sqrt(max(s2 / NB - mean**2, 0.0_wp) / (NB - 1))
          write (*, '(a, f4.1, a, f10.4, a, f10.4, a, f7.4, a)') '  ' // trim(c%name) // ', a = ', 0.1_wp * k, &
            ': sampled direct flux ', mean, ', DISORT ', c%direct_sfc, ' +- ', sig, ' W m-2'
          call check_sigma(error, mean, c%direct_sfc, sig, 4.0_wp, trim(c%name) // ': sampled direct flux')
        end do
      end associate
    end do
  end subroutine test_sw_direct_sampled

  !> The whole chain in kumo's photon loop: for each reference column, one plane-parallel scene
  !> per g-point (kumo's optical depths and single-scattering albedos, Rayleigh phase function,
  !> Lambert surface, the reference's sun), photons spread over the g-points by the plan, each
  !> g-point's tallies weighted by w_g. Broadband up, diffuse and direct down fluxes at every
  !> level and the heating rate of every layer within 4.5 standard errors (100 batches) of the
  !> discrete-ordinates reference; with the floor share the TOA incoming flux is TSI mu0 in every
  !> batch.
  subroutine test_sw_broadband_mc(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: G0 = 9.80665_wp, CP = 1004.64_wp, DAY = 86400.0_wp
    integer, parameter :: NB = 100
    integer(i8), parameter :: N = 20000
    !> 3 (nz + 1) + nz = 243 (RFMIP) and 143 (U.S. Standard) comparisons: K_SIGMA = 4.5 keeps the
    !> chance that a correct code fails one of them at 0.7 % (Student t with 99 degrees of
    !> freedom, Bonferroni; at 4 sigma it would be 4 %).
    real(wp), parameter :: K_SIGMA = 4.5_wp
    type(gas_kdist_t) :: kd
    type(ref_column_t), allocatable :: cols(:)
    type(spectral_column_t) :: col
    type(spectral_plan_t) :: plan
    type(spectral_batch_t) :: batch
    type(scene_t), allocatable :: scn(:)
    type(tally_layout_t) :: lay
    type(tally_t) :: tal
    type(rng_t) :: rng
    type(error_t), allocatable :: err
    real(wp), allocatable :: acc(:), q(:, :), s1(:), s2(:), ref(:), ref_err(:)
    character(len=40), allocatable :: names(:)
    real(wp) :: mean, sig, worst, dp
    integer :: i, g, b, k, nl, nq, iw
    integer(i8) :: t0, t1, rate
    call load('rrtmgp-gas-sw-g112.nc', kd, error)
    if (allocated(error)) return
    call read_reference(kd, reference_dir // '/sw_gpoint_reference.txt', cols, error)
    if (allocated(error)) return
    do i = 1, size(cols)
      associate (c => cols(i))
        call system_clock(t0, rate)
        nl = c%nl
        call spectral_sw_column(kd, c%plev, c%play, c%tlay, c%vmr, c%mu0, col, err, tsi=c%tsi)
        call check(error, .not. allocated(err), 'spectral_sw_column failed')
        if (allocated(error)) return
        ! RFMIP column: floor share 0.05, so that N >= N+ / a and the incoming flux of every
        ! batch is exact; U.S. Standard: pure source-proportional sampling.
        if (mc_floor_share >= 0) then
          call spectral_plan_init(col%energy, plan, err, floor_share=mc_floor_share)
        else
          call spectral_plan_init(col%energy, plan, err, floor_share=merge(0.05_wp, 0.0_wp, i == 1))
        end if
        call check(error, .not. allocated(err), 'plan of the Monte Carlo check')
        if (allocated(error)) return
        if (allocated(scn)) deallocate (scn)
        allocate (scn(col%n_gpt))
        do g = 1, col%n_gpt
          call gpoint_scene(col, g, c%albedo, acos(c%mu0) * RAD2DEG, scn(g), err)
          call check(error, .not. allocated(err), 'scene of g-point ' // str(g))
          if (allocated(error)) return
        end do
        call layout_init(lay, nl, 1, 0, [integer ::], .false.)
        if (allocated(tal%buf)) deallocate (tal%buf)   ! tally_reset keeps a buffer of another size
        ! Quantities: up, diffuse down, direct down at levels 0..nl; heating of layers 1..nl.
        nq = 3 * (nl + 1) + nl
        allocate (acc(lay%n), q(nq, NB), s1(nq), s2(nq), ref(nq), ref_err(nq), names(nq))
        do b = 1, NB
          call rng_init(rng, 424242_i8 + i, int(b, i8))
          call spectral_begin_batch(plan, N, rng, batch, err)
          acc = 0
          do g = 1, col%n_gpt
            if (batch%count(g) == 0) cycle
            call tally_reset(tal, lay)
            call trace_batch(scn(g), lay, rng, batch%count(g), tal)
            acc = acc + batch%weight(g) * tal%buf
          end do
          if (plan%floor_share > 0) call check_close(error, acc(lay%i_dir + nl + 1), c%tsi * c%mu0, &
                                                     rel_tol=1.0e-12_wp, label='incoming flux of batch ' // str(b))
          q(1:nl + 1, b) = acc(lay%i_up + 1:lay%i_up + nl + 1)
          q(nl + 2:2 * nl + 2, b) = acc(lay%i_dif + 1:lay%i_dif + nl + 1)
          q(2 * nl + 3:3 * nl + 3, b) = acc(lay%i_dir + 1:lay%i_dir + nl + 1)
          do k = 1, nl
            dp = c%plev(k - 1) - c%plev(k)
            q(3 * nl + 3 + k, b) = G0 / CP * acc(lay%i_abs + k) / dp * DAY
          end do
        end do
        do k = 0, nl
          ref(k + 1) = c%bb(k, 1)
          ref_err(k + 1) = c%bb(k, 4)
          names(k + 1) = 'up flux at level ' // str(k)
          ref(nl + 2 + k) = c%bb(k, 2)
          ref_err(nl + 2 + k) = c%bb(k, 5)
          names(nl + 2 + k) = 'diffuse down flux at level ' // str(k)
          ref(2 * nl + 3 + k) = c%bb(k, 3)
          ref_err(2 * nl + 3 + k) = 0
          names(2 * nl + 3 + k) = 'direct flux at level ' // str(k)
        end do
        do k = 1, nl
          ref(3 * nl + 3 + k) = c%heat(k, 1)
          ref_err(3 * nl + 3 + k) = c%heat(k, 2)
          names(3 * nl + 3 + k) = 'heating rate of layer ' // str(k)
        end do
        s1 = sum(q, dim=2) / NB
        s2 = sum(q**2, dim=2) / NB
        worst = 0
        iw = 1
        do k = 1, nq
          mean = s1(k)
          sig = sqrt(max(s2(k) - mean**2, 0.0_wp) / (NB - 1))
          call check_sigma(error, mean, ref(k), sig, K_SIGMA, trim(c%name) // ': ' // trim(names(k)), &
                           abs_floor=ref_err(k) + 1.0e-9_wp * c%tsi)
          if (sig > 0) then
            if (abs(mean - ref(k)) / sig > worst) then
              worst = abs(mean - ref(k)) / sig
              iw = k
            end if
          end if
        end do
        ! Noise summary: relative standard error of the TOA up flux, rms and largest standard
        ! error of the heating rates.
        associate (sg => sqrt(max(s2 - s1**2, 0.0_wp) / (NB - 1)))
          write (*, '(a, f4.2, a, es9.2, a, f6.3, a, f6.3, a)') '    a = ', plan%floor_share, &
            ': relative sigma of TOA up ', sg(nl + 1) / s1(nl + 1), ', heating rates: rms sigma ', &
            sqrt(sum(sg(3 * nl + 4:)**2) / nl), ' K/day, largest ', maxval(sg(3 * nl + 4:)), ' K/day'
        end associate
        call system_clock(t1)
        write (*, '(a, 3(f0.3, a), es9.2, a)') '  ' // trim(c%name) // ': TOA up ', s1(nl + 1), ' +- ', &
          sqrt(max(s2(nl + 1) - s1(nl + 1)**2, 0.0_wp) / (NB - 1)), ' W m-2 (DISORT ', ref(nl + 1), &
          '), sigma of the surface heating rate ', sqrt(max(s2(3 * nl + 4) - s1(3 * nl + 4)**2, 0.0_wp) / (NB - 1)), &
          ' K/day'
        write (*, '(a, f0.2, a, f0.1, a, i0, a)') '    largest deviation ', worst, ' sigma (' // trim(names(iw)) // &
          '); ', real(t1 - t0, wp) / rate, ' s for ', NB * N, ' photons'
        deallocate (acc, q, s1, s2, ref, ref_err, names)
        if (allocated(error)) return
      end associate
    end do
  end subroutine test_sw_broadband_mc

  !> Plane-parallel scene of g-point g of a shortwave column: layers 1 km thick (only optical
  !> depths matter) with the gas's extinction and single-scattering albedo and the Rayleigh
  !> phase function, a Lambert surface, the sun at `sza_deg`.
  subroutine gpoint_scene(col, g, albedo, sza_deg, scn, error)
    type(spectral_column_t), intent(in) :: col
    integer, intent(in) :: g
    real(wp), intent(in) :: albedo, sza_deg
    type(scene_t), intent(out) :: scn
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: DZ = 1000.0_wp
    type(atmosphere_options_t) :: aopts
    type(camera_t) :: cams(0)
    integer :: k, nz
    nz = col%n_layer
    call atmosphere_init(scn%atm, [(DZ * k, k = 0, nz)], DZ, DZ, &
                         reshape((col%tau_abs(:, g) + col%tau_rayleigh(:, g)) / DZ, [nz, 1]), &
                         reshape(col%ssa(:, g), [nz, 1]), reshape([(1, k = 1, nz)], [nz, 1]), &
                         [new_phase_rayleigh()], aopts, error)
    if (allocated(error)) return
    call surface_init(scn%sfc, reshape([albedo], [1, 1]), DZ, DZ, error)
    if (allocated(error)) return
    scn%src = solar_source(sza_deg, 0.0_wp)
    scn%mu0 = -scn%src%uz
    call detectors_init(scn%det, [real(wp) ::], [real(wp) ::], [integer ::], cams, 0.0_wp, &
                        scn%atm%lx, scn%atm%ly)
  end subroutine gpoint_scene

end module test_spectral_suite

program test_spectral
  use test_spectral_suite, only: collect_spectral, collect_spectral_mc, rrtmgp_dir, reference_dir, &
                                 mc_floor_share
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  character(len=4096) :: arg
  if (command_argument_count() < 2) then
    write (*, '(a)') 'usage: test_spectral <rrtmgp folder> <reference folder>'
    error stop 1
  end if
  call get_command_argument(1, arg)
  rrtmgp_dir = trim(arg)
  call get_command_argument(2, arg)
  reference_dir = trim(arg)
  arg = ''
  if (command_argument_count() >= 3) call get_command_argument(3, arg)
  if (trim(arg) == 'mc') then
    if (command_argument_count() >= 4) then
      call get_command_argument(4, arg)
      read (arg, *) mc_floor_share
    end if
    call run_unittests('spectral: Monte Carlo broadband', collect_spectral_mc(), n_failed)
  else
    call run_unittests('spectral', collect_spectral(), n_failed)
  end if
  if (n_failed > 0) error stop 1
end program test_spectral
