! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_gas_optics and kumo_rrtmgp_file: RRTMGP gas optics against reference values
!> of the independent implementation jax-rrtmgp 0.5.0 (float64), produced by
!> bench/gas_optics/make_gas_reference.py and stored with their inputs in
!> tests/data/gas_optics/reference.txt (RFMIP clear-sky sites, U.S. Standard Atmosphere 1976, an
!> RCEMIP moist tropical column, three layers outside the tables; a subset of layers, every
!> g-point).
!>
!> Tolerance: both codes evaluate the same interpolation formulas in double precision, so they
!> differ only by round-off and by how the uniform reference grids are parametrised (kumo takes
!> the ln p step from the end points of press_ref, jax-rrtmgp from the first two); the reference
!> file keeps 10 significant digits (rounding: 5e-10 relative at most). Measured differences
!> before rounding were below 5e-11 relative; the test allows REL_TOL = 1e-8 relative, plus an
!> absolute floor of 1e-12 times the largest value of the same row (the g-points of one layer),
!> for values that are zero in one code and round-off above zero in the other. Any error in the
!> physics (a wrong table node, weight, scaling or unit) shows up at 1e-3 relative or more.
!>
!> Arguments: the folder of the k-distribution files (CMake KUMO_RRTMGP_DIR, filled by
!> scripts/fetch-rrtmgp.sh) and the reference file.
module test_gas_optics_suite
  use kumo_kinds, only: wp
  use kumo_error, only: str
  use kumo_gas_optics, only: gas_kdist_t, gas_index, gas_optical_depth, gas_planck_source, &
                             gas_solar_source, kdist_memory_bytes, gas_col_dry, &
                             NRLSSI2_MG_OFFSET, NRLSSI2_SB_OFFSET, gas_default_vmr
  use kumo_rrtmgp_file, only: read_rrtmgp_kdist
  use kumo_testing, only: error_t, unittest_t, new_unittest, check
  use netcdf, only: nf90_create, nf90_def_dim, nf90_enddef, nf90_close, NF90_CLOBBER
  implicit none
  private
  public :: collect_gas_optics, rrtmgp_dir, reference_file

  real(wp), parameter :: REL_TOL = 1.0e-8_wp     !! relative tolerance against jax-rrtmgp
  real(wp), parameter :: ROW_FLOOR = 1.0e-12_wp  !! absolute floor, relative to the row maximum
  character(len=:), allocatable :: rrtmgp_dir, reference_file

  !> A k-distribution loaded once per file name.
  type :: cached_t
    character(len=64) :: name = ''
    type(gas_kdist_t) :: kd
  end type cached_t
  type(cached_t), target :: cache(4)

contains

  function collect_gas_optics() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('against_jax_rrtmgp', test_reference), &
             new_unittest('band_planck_closure', test_planck_closure), &
             new_unittest('solar_source_sum', test_solar_sum), &
             new_unittest('bad_inputs', test_bad_inputs), &
             new_unittest('reader_errors', test_reader_errors)]
  end function collect_gas_optics

  !> The k-distribution `name` from the cache folder.
  subroutine load(name, kd, error)
    character(len=*), intent(in) :: name
    type(gas_kdist_t), pointer, intent(out) :: kd
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    type(error_t), allocatable :: err
    do i = 1, size(cache)
      if (cache(i)%name == name) then
        kd => cache(i)%kd
        return
      end if
    end do
    do i = 1, size(cache)
      if (len_trim(cache(i)%name) == 0) exit
    end do
    if (i > size(cache)) i = size(cache)
    call read_rrtmgp_kdist(rrtmgp_dir // '/' // name, cache(i)%kd, err)
    if (allocated(err)) then
      call check(error, .false., err%message // ' (run scripts/fetch-rrtmgp.sh to fetch the files)')
      return
    end if
    cache(i)%name = name
    kd => cache(i)%kd
    write (*, '(a, f0.1, a)') '  loaded ' // name // ': ', kdist_memory_bytes(kd) / 1.0e6_wp, &
      ' MB of tables'
  end subroutine load

  !> Every number of the reference file against kumo.
  subroutine test_reference(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: LINE_LEN = 16384
    character(len=LINE_LEN) :: line
    character(len=32) :: key, cname
    character(len=64) :: fname
    character(len=32), allocatable :: names(:)
    integer :: u, ios, nl, ng, k, idx, i, g, nrows, ncases
    integer, allocatable :: lay_id(:), map(:)
    real(wp), allocatable :: p(:), t(:), cd(:), tlev(:), vmr(:, :), row(:), vin(:)
    real(wp), allocatable :: tau(:, :), tray(:, :), src(:, :, :), sfc(:), sol(:), got(:)
    real(wp), allocatable :: vdef(:, :)
    real(wp) :: tsfc, tsi, diff, worst, worst_all, cdry(1)
    type(gas_kdist_t), pointer :: kd
    type(error_t), allocatable :: err
    logical :: computed

    open (newunit=u, file=reference_file, status='old', action='read', iostat=ios)
    call check(error, ios == 0, 'cannot open the reference file ' // reference_file)
    if (allocated(error)) return
    nrows = 0
    ncases = 0
    worst_all = 0
    computed = .false.
    do
      read (u, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (len_trim(line) == 0 .or. line(1:1) == '#') cycle
      read (line, *) key
      select case (trim(key))
      case ('case')
        read (line, *) key, cname, fname, nl, ng
        call load(trim(fname), kd, error)
        if (allocated(error)) exit
        if (allocated(names)) deallocate (names, map, lay_id, p, t, cd, tlev, vmr, vin)
        allocate (names(ng), map(ng), lay_id(nl), p(nl), t(nl), cd(nl), tlev(0:2*nl - 1), &
                  vmr(nl, kd%n_gas), vin(7 + ng))
        vmr = 0
        k = 0
        computed = .false.
        worst = 0
        ncases = ncases + 1
      case ('gases')
        read (line, *) key, names
        do i = 1, ng
          map(i) = gas_index(kd, names(i))
          call check(error, map(i) > 0, 'gas ' // trim(names(i)) // ' of the reference is not in ' &
                     // trim(fname))
        end do
        if (allocated(error)) exit
      case ('surface')
        read (line, *) key, tsfc, tsi
      case ('layer')
        k = k + 1
        read (line, *) key, lay_id(k), vin
        p(k) = vin(1)
        t(k) = vin(2)
        cd(k) = vin(3)
        tlev(2*k - 2) = vin(4)
        tlev(2*k - 1) = vin(5)
        do i = 1, ng
          vmr(k, map(i)) = vin(7 + i)
        end do
        ! The columns built in the reference script use kumo's default gases (RFMIP present-day
        ! means, stored there in single precision, and the RCEMIP ozone profile).
        if (cname == 'us1976' .or. cname == 'tropical_rcemip' .or. cname == 'out_of_table') then
          vdef = vmr(k:k, :)
          call gas_default_vmr(kd, p(k:k), vdef, err)
          if (allocated(err)) then
            call check(error, .false., err%message)
            exit
          end if
          do i = 1, kd%n_gas
            call check(error, abs(vdef(1, i) - vmr(k, i)) <= 1.0e-6_wp * vmr(k, i), trim(cname) // &
                       ' layer ' // str(lay_id(k)) // ': default ' // trim(kd%gas_names(i)) // ' ' // &
                       str(vdef(1, i)) // ', reference ' // str(vmr(k, i)))
          end do
          if (allocated(error)) exit
        end if
        ! The dry-air column of the reference follows from the level pressures and water vapour.
        call gas_col_dry(vin(6:7), [vmr(k, gas_index(kd, 'h2o'))], cdry, err)
        if (allocated(err)) then
          call check(error, .false., err%message)
          exit
        end if
        call check(error, abs(cdry(1) - cd(k)) <= 1.0e-13_wp * cd(k), trim(cname) // ' layer ' // &
                   str(lay_id(k)) // ': gas_col_dry ' // str(cdry(1)) // ', reference ' // str(cd(k)))
        if (allocated(error)) exit
      case ('end')
        write (*, '(a, es9.2)') '  ' // trim(cname) // ' ' // trim(fname) // &
          ': largest relative difference ', worst
        worst_all = max(worst_all, worst)
      case default
        if (.not. computed) then
          call compute_case(kd, p, t, cd, tlev, tsfc, tsi, vmr, tau, tray, src, sfc, sol, err)
          if (allocated(err)) then
            call check(error, .false., trim(cname) // ': ' // err%message)
            exit
          end if
          computed = .true.
          if (allocated(row)) deallocate (row, got)
          allocate (row(kd%n_gpt), got(kd%n_gpt))
        end if
        read (line, *, iostat=ios) key, idx, row
        call check(error, ios == 0, 'reference row "' // trim(key) // '" of ' // trim(cname) // &
                   ' does not hold ' // str(kd%n_gpt) // ' values')
        if (allocated(error)) exit
        i = findloc(lay_id, idx, 1)
        select case (trim(key))
        case ('tau')
          got = tau(i, :)
        case ('tau_rayleigh')
          got = tray(i, :)
        case ('lay_src')
          got = src(i, :, 1)
        case ('lev_src_bot')
          got = src(i, :, 2)
        case ('lev_src_top')
          got = src(i, :, 3)
        case ('sfc_src')
          got = sfc
        case ('solar_src')
          got = sol
        case default
          call check(error, .false., 'unknown reference row ' // trim(key))
          exit
        end select
        if (idx > 0) call check(error, i > 0, 'reference row for unknown layer ' // str(idx))
        if (allocated(error)) exit
        do g = 1, kd%n_gpt
          diff = abs(got(g) - row(g))
          if (diff > REL_TOL * abs(row(g)) + ROW_FLOOR * maxval(abs(row))) then
            call check(error, .false., trim(cname) // ' ' // trim(fname) // ' ' // trim(key) // &
                       ' layer ' // str(idx) // ' g-point ' // str(g) // ': kumo ' // &
                       str(got(g)) // ', jax-rrtmgp ' // str(row(g)))
            exit
          end if
          if (abs(row(g)) > ROW_FLOOR * maxval(abs(row))) worst = max(worst, diff / abs(row(g)))
        end do
        if (allocated(error)) exit
        nrows = nrows + 1
      end select
    end do
    close (u)
    if (allocated(error)) return
    write (*, '(a, i0, a, i0, a, es9.2)') '  ', ncases, ' cases, ', nrows, &
      ' rows of g-point values; largest relative difference ', worst_all
    call check(error, ncases >= 14 .and. nrows >= 100, 'the reference file holds only ' // &
               str(ncases) // ' cases and ' // str(nrows) // ' rows')
  end subroutine test_reference

  !> All quantities of one case; level temperatures come as pairs (bottom, top) per layer.
  subroutine compute_case(kd, p, t, cd, tpair, tsfc, tsi, vmr, tau, tray, src, sfc, sol, error)
    type(gas_kdist_t), intent(in) :: kd
    real(wp), intent(in) :: p(:), t(:), cd(:), tpair(0:), tsfc, tsi, vmr(:, :)
    real(wp), allocatable, intent(out) :: tau(:, :), tray(:, :), src(:, :, :), sfc(:), sol(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: nl, l
    real(wp) :: tlev(0:size(p)), bot(size(p), kd%n_gpt), top(size(p), kd%n_gpt)
    nl = size(p)
    allocate (tau(nl, kd%n_gpt), tray(nl, kd%n_gpt), src(nl, kd%n_gpt, 3), sfc(kd%n_gpt), &
              sol(kd%n_gpt))
    if (kd%longwave) then
      call gas_optical_depth(kd, p, t, vmr, cd, tau, error)
      if (allocated(error)) return
      ! The layers of a case are not adjacent: evaluate the bottom and the top sources with
      ! level temperatures set from each layer's own pair.
      tlev(0:nl - 1) = [(tpair(2*l - 2), l = 1, nl)]
      tlev(nl) = tpair(2*nl - 1)
      call gas_planck_source(kd, p, t, tlev, tsfc, vmr, src(:, :, 1), bot, top, sfc, error)
      if (allocated(error)) return
      src(:, :, 2) = bot
      tlev(1:nl) = [(tpair(2*l - 1), l = 1, nl)]
      tlev(0) = tpair(0)
      call gas_planck_source(kd, p, t, tlev, tsfc, vmr, src(:, :, 1), bot, top, sfc, error)
      if (allocated(error)) return
      src(:, :, 3) = top
    else
      call gas_optical_depth(kd, p, t, vmr, cd, tau, error, tau_rayleigh=tray)
      if (allocated(error)) return
      call gas_solar_source(kd, sol, error, tsi=tsi)
    end if
  end subroutine compute_case

  !> The Planck fractions of a band partition its band source: the layer sources summed over a
  !> band equal the file's band-integrated Planck radiance at the layer temperature (the tables'
  !> fractions sum to 1 within 1.7e-4; allowed 1e-3).
  subroutine test_planck_closure(error)
    type(error_t), allocatable, intent(out) :: error
    type(gas_kdist_t), pointer :: kd
    real(wp) :: p(3), t(3), tlev(0:3), vmr(3, 19), lay(3, 128), bot(3, 128), top(3, 128), sfc(128)
    real(wp) :: s, b, x
    integer :: l, ib, j
    call load('rrtmgp-gas-lw-g128.nc', kd, error)
    if (allocated(error)) return
    call check(error, kd%n_gas == 19 .and. kd%n_gpt == 128, 'lw-g128 has ' // str(kd%n_gas) // &
               ' gases and ' // str(kd%n_gpt) // ' g-points, expected 19 and 128')
    if (allocated(error)) return
    p = [95000.0_wp, 20000.0_wp, 500.0_wp]
    t = [290.3_wp, 221.7_wp, 250.2_wp]
    tlev = [291.0_wp, 250.0_wp, 215.0_wp, 260.0_wp]
    vmr = 0
    vmr(:, gas_index(kd, 'h2o')) = [1.5e-2_wp, 1.0e-4_wp, 4.0e-6_wp]
    vmr(:, gas_index(kd, 'co2')) = 4.0e-4_wp
    vmr(:, gas_index(kd, 'o3')) = [3.0e-8_wp, 2.0e-7_wp, 5.0e-6_wp]
    call gas_planck_source(kd, p, t, tlev, 295.0_wp, vmr, lay, bot, top, sfc, error)
    if (allocated(error)) return
    do l = 1, 3
      do ib = 1, kd%n_band
        s = sum(lay(l, kd%band_gpt(1, ib):kd%band_gpt(2, ib)))
        x = (t(l) - kd%temp_ref(1)) + 1   ! the Planck table is on a 1 K grid from temp_ref(1)
        j = int(x)
        b = (1 - (x - j)) * kd%planck_band(j, ib) + (x - j) * kd%planck_band(j + 1, ib)
        call check(error, abs(s - b) <= 1.0e-3_wp * b, 'layer ' // str(l) // ' band ' // str(ib) &
                   // ': sum of g-point sources ' // str(s) // ' /= band source ' // str(b))
        if (allocated(error)) return
      end do
    end do
    ! Total over bands close to sigma T^4 / pi (the bands cover 10-3250 cm-1).
    s = sum(lay(1, :))
    b = 5.670374419e-8_wp * t(1)**4 / 3.141592653589793_wp
    call check(error, abs(s - b) < 0.01_wp * b, 'band sum ' // str(s) // ' W m-2 sr-1 vs ' // &
               'sigma T^4 / pi ' // str(b))
  end subroutine test_planck_closure

  subroutine test_solar_sum(error)
    type(error_t), allocatable, intent(out) :: error
    type(gas_kdist_t), pointer :: kd
    real(wp) :: src(112), quiet(112)
    call load('rrtmgp-gas-sw-g112.nc', kd, error)
    if (allocated(error)) return
    call gas_solar_source(kd, src, error, tsi=1361.0_wp)
    if (allocated(error)) return
    call check(error, abs(sum(src) - 1361.0_wp) < 1.0e-9_wp .and. all(src >= 0), &
               'solar source sums to ' // str(sum(src)) // ', expected 1361')
    if (allocated(error)) return
    call gas_solar_source(kd, src, error)
    if (allocated(error)) return
    call check(error, abs(sum(src) - kd%tsi_default) < 1.0e-9_wp .and. kd%tsi_default > 1300, &
               'default solar source sums to ' // str(sum(src)) // ', tsi_default ' // &
               str(kd%tsi_default))
    if (allocated(error)) return
    ! NRLSSI2 offsets: with the file's default indices the three terms add up to its tsi_default
    ! (unnormalised; agreement 4e-10 relative).
    quiet = src
    src = kd%solar_quiet + (kd%mg_default - NRLSSI2_MG_OFFSET) * kd%solar_facular &
          + (kd%sb_default - NRLSSI2_SB_OFFSET) * kd%solar_sunspot
    call check(error, abs(sum(src) - kd%tsi_default) < 1.0e-8_wp * kd%tsi_default, &
               'quiet + facular + sunspot terms at the default indices sum to ' // str(sum(src)) // &
               ', tsi_default ' // str(kd%tsi_default))
    if (allocated(error)) return
    call gas_solar_source(kd, src, error, mg_index=kd%mg_default)
    if (allocated(error)) return
    call check(error, abs(sum(src) - kd%tsi_default) < 1.0e-9_wp .and. &
               maxval(abs(src - quiet) / quiet) > 1.0e-3_wp, 'solar variability changes nothing')
    if (allocated(error)) return
    call gas_solar_source(kd, src, error, mg_index=NRLSSI2_MG_OFFSET, sb_index=NRLSSI2_SB_OFFSET)
    if (allocated(error)) return
    call check(error, maxval(abs(src - quiet) / quiet) < 1.0e-12_wp, &
               'at the NRLSSI2 offsets the spectrum is not the quiet sun')
  end subroutine test_solar_sum

  subroutine test_bad_inputs(error)
    type(error_t), allocatable, intent(out) :: error
    type(gas_kdist_t), pointer :: kd, ksw
    type(error_t), allocatable :: err
    real(wp) :: vmr(2, 19), tau(2, 128), lay(2, 128), bot(2, 128), top(2, 128), sfc(128), s(112)
    call load('rrtmgp-gas-lw-g128.nc', kd, error)
    if (allocated(error)) return
    call load('rrtmgp-gas-sw-g112.nc', ksw, error)
    if (allocated(error)) return
    vmr = 1.0e-4_wp
    call gas_optical_depth(kd, [1.0e5_wp, -3.0_wp], [280.0_wp, 250.0_wp], vmr, [1.0e29_wp, 1.0e28_wp], &
                           tau, err)
    call expect(error, err, 'layer 2 pressure = -3')
    call gas_optical_depth(kd, [1.0e5_wp, 3.0e4_wp], [280.0_wp, 250.0_wp], vmr(:, 1:3), &
                           [1.0e29_wp, 1.0e28_wp], tau, err)
    call expect(error, err, 'vmr (2, 3) (expected (2, 19))')
    vmr(1, 2) = -1.0e-6_wp
    call gas_optical_depth(kd, [1.0e5_wp, 3.0e4_wp], [280.0_wp, 250.0_wp], vmr, &
                           [1.0e29_wp, 1.0e28_wp], tau, err)
    call expect(error, err, 'negative or non-finite volume mixing ratio (co2 = -1E-06')
    vmr(1, 2) = 1.0e-6_wp
    call gas_optical_depth(kd, [1.0e5_wp, 3.0e4_wp], [280.0_wp, 250.0_wp], vmr, &
                           [1.0e29_wp, 1.0e28_wp], tau, err, tau_rayleigh=lay)
    call expect(error, err, 'Rayleigh optical depth asked of a longwave')
    call gas_planck_source(kd, [1.0e5_wp, 3.0e4_wp], [280.0_wp, 250.0_wp], [280.0_wp, 260.0_wp], &
                           280.0_wp, vmr, lay, bot, top, sfc, err)
    call expect(error, err, 'tlev has 2 levels, expected 3')
    call gas_solar_source(kd, s, err)
    call expect(error, err, 'no solar source')
    call gas_solar_source(ksw, s, err, tsi=-1.0_wp)
    call expect(error, err, 'tsi = -1')
  end subroutine test_bad_inputs

  !> Missing files and variables are reported by name.
  subroutine test_reader_errors(error)
    type(error_t), allocatable, intent(out) :: error
    type(gas_kdist_t) :: kd
    type(error_t), allocatable :: err
    integer :: ncid, dimid, status
    call read_rrtmgp_kdist('no_such_rrtmgp_file.nc', kd, err)
    call expect(error, err, 'RRTMGP file no_such_rrtmgp_file.nc: ')
    status = nf90_create('rrtmgp_incomplete.nc', NF90_CLOBBER, ncid)
    if (status == 0) status = nf90_def_dim(ncid, 'absorber', 19, dimid)
    if (status == 0) status = nf90_enddef(ncid)
    if (status == 0) status = nf90_close(ncid)
    call check(error, status == 0, 'cannot write rrtmgp_incomplete.nc')
    if (allocated(error)) return
    call read_rrtmgp_kdist('rrtmgp_incomplete.nc', kd, err)
    call expect(error, err, 'rrtmgp_incomplete.nc: dimension bnd missing')
  end subroutine test_reader_errors

  subroutine expect(error, err, text)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: text
    if (allocated(error)) return
    if (.not. allocated(err)) then
      call check(error, .false., 'no error; expected one containing "' // text // '"')
    else
      call check(error, index(err%message, text) > 0, 'message "' // err%message // &
                 '" does not contain "' // text // '"')
    end if
  end subroutine expect

end module test_gas_optics_suite

program test_gas_optics
  use kumo_testing, only: run_unittests
  use test_gas_optics_suite, only: collect_gas_optics, rrtmgp_dir, reference_file
  implicit none
  integer :: n_failed, n
  character(len=4096) :: arg
  if (command_argument_count() < 2) then
    write (*, '(a)') 'usage: test_gas_optics <folder of the RRTMGP files> <reference file>'
    error stop 2
  end if
  call get_command_argument(1, arg, length=n)
  rrtmgp_dir = arg(1:n)
  call get_command_argument(2, arg, length=n)
  reference_file = arg(1:n)
  call run_unittests('gas_optics', collect_gas_optics(), n_failed)
  if (n_failed > 0) error stop 1
end program test_gas_optics
