! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of the cloud-file readers (kumo_shdom_files, kumo_mystic_file,
!> kumo_mcarats_files).
!>
!> The shared example files (data/i3rc/les_examples, data/mcarats; data/README.md) are read and
!> checked against values taken from the files independently of kumo: single lines read by eye
!> or with grep (the line is named), and domain sums and means computed with awk (text files)
!> or numpy (binary files) while the test was written. Small files written by the tests into
!> the working directory check the other formats and that malformed input is rejected with a
!> message naming the file, the line or record and the rule.
module test_kumo_formats
  use, intrinsic :: iso_fortran_env, only: real32, int32
  use kumo_kinds, only: wp, dp
  use kumo_constants, only: PI
  use kumo_shdom_files, only: lwc_field_t, prp_field_t, read_lwc_file, read_prp_file, &
                              reff_from_droplet_number, set_reff_from_droplet_number
  use kumo_mystic_file, only: mystic_cloud_t, read_mystic_file
  use kumo_mcarats_files, only: mcarats_atm_t, mcarats_phase_t, mcarats_surface_t, &
                                read_mcarats_atm, read_mcarats_atm_ctl, read_mcarats_phase, &
                                read_mcarats_phase_ctl, read_mcarats_surface
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, &
                          check_error_words
  use kumo_test_text, only: shared_dir
  use kumo_error, only: str
  implicit none
  private
  public :: collect_formats

  character(len=*), parameter :: LES = '/data/i3rc/les_examples/'
  character(len=*), parameter :: MCA = '/data/mcarats/'
  character(len=1), parameter :: NL = new_line('a')
  !> Values printed with 4-6 significant digits, compared after kumo's km -> m conversion and
  !> double-precision parsing: 1e-12 relative is far below the printed precision and far above
  !> rounding in one multiplication.
  real(dp), parameter :: TIGHT = 1.0e-12_dp

contains

  !> All tests of this suite.
  function collect_formats() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('lwc_real_file', test_lwc_real), &
             new_unittest('prp_real_file_cells', test_prp_real), &
             new_unittest('prp_real_file_grid_points', test_prp_2d), &
             new_unittest('lwc_one_parameter_reff', test_lwc_one_param), &
             new_unittest('lwc_malformed', test_lwc_bad), &
             new_unittest('prp_small_and_malformed', test_prp_bad), &
             new_unittest('mystic_flags', test_mystic), &
             new_unittest('mystic_malformed', test_mystic_bad), &
             new_unittest('mcarats_atm_real_file', test_mcarats_atm), &
             new_unittest('mcarats_phase_real_file', test_mcarats_phase), &
             new_unittest('mcarats_small_and_malformed', test_mcarats_bad), &
             new_unittest('mcarats_surface', test_mcarats_surface)]
  end function collect_formats

  ! ------------------------------------------------------------------------------------------
  ! Real files
  ! ------------------------------------------------------------------------------------------

  subroutine test_lwc_real(error)
    type(error_t), allocatable, intent(out) :: error
    type(lwc_field_t) :: f
    type(error_t), allocatable :: err
    call read_lwc_file(shared_dir//LES//'i3rc_les_stcu.lwc', f, err)
    call no_error(error, err)
    if (allocated(error)) return
    call check(error, f%n_params == 2 .and. f%nx == 64 .and. f%ny == 64 .and. f%nz == 16, &
               'sizes (line 2: 64 64 16, 2-parameter)')
    ! line 4 holds 17 = nz+1 heights: I3RC cell boundaries
    call check(error, f%z_are_boundaries .and. size(f%z) == 17, 'nz+1 boundaries expected')
    call check_close(error, f%dx, 55.0_dp, rel_tol=TIGHT, label='dx (line 3: 0.055 km)')
    call check_close(error, f%z(1), 425.0_dp, rel_tol=TIGHT, label='z(1) (line 4)')
    call check_close(error, f%z(17), 825.0_dp, rel_tol=TIGHT, label='z(17) (line 4)')
    call check_close(error, f%temperature(1), 283.88_dp, rel_tol=TIGHT, label='T(1) (line 5)')
    call check_close(error, f%temperature(17), 286.19_dp, rel_tol=TIGHT, label='T(17) (line 5)')
    ! line 32255: "32 32 10 0.0958  6.82"; line 3876: "4 50 15 4.2644 24.18" (largest LWC)
    call check_close(error, f%lwc(32, 32, 10), 0.0958_dp, rel_tol=TIGHT, label='lwc(32,32,10)')
    call check_close(error, f%reff(32, 32, 10), 6.82_dp, rel_tol=TIGHT, label='reff(32,32,10)')
    call check_close(error, f%lwc(4, 50, 15), 4.2644_dp, rel_tol=TIGHT, label='lwc(4,50,15)')
    call check_close(error, maxval(f%reff), 24.18_dp, rel_tol=TIGHT, label='max reff')
    ! awk 'NR>5 && NF==5 {s+=$4; if ($4>0) n++}': s = 8455.5556, n = 24789 (65536 lines).
    ! Summing 65536 values of <= 5 significant digits in double precision: 1e-10 relative.
    call check_close(error, sum(f%lwc), 8455.5556_dp, rel_tol=1.0e-10_dp, label='total LWC')
    call check(error, count(f%lwc > 0.0_wp) == 24789, 'cloudy points: '//str(count(f%lwc > 0)))
    call check(error, f%n_listed == 64*64*16, 'every point is listed in this file')
    call check(error, index(f%missing, 'wavelength') > 0 .and. &
               index(f%missing, 'droplet number') == 0, 'missing: '//f%missing)
  end subroutine test_lwc_real

  subroutine test_prp_real(error)
    type(error_t), allocatable, intent(out) :: error
    type(prp_field_t) :: p
    type(error_t), allocatable :: err
    call read_prp_file(shared_dir//LES//'les_stcu_w213.prp', p, err)
    call no_error(error, err)
    if (allocated(error)) return
    call check(error, p%nx == 64 .and. p%ny == 64 .and. p%nz == 18, 'sizes (line 2)')
    ! line 3: dx dy and 19 = nz+1 heights, 0.0 ... 1.0 km
    call check(error, p%z_are_boundaries .and. size(p%z) == 19, 'nz+1 boundaries expected')
    call check_close(error, p%z(19), 1000.0_dp, rel_tol=TIGHT, label='z(19)')
    call check(error, p%nphase == 27 .and. p%nleg(27) == 490 .and. p%nleg_max == 490, &
               'phase table: line 4 "27"; phase 27 has 490 terms (line 49)')
    ! line 5: phase 1 has no terms (isotropic); line 6 "2 0.00000 0.50000" is Rayleigh,
    ! P = 1 + P_2/2, so chi_2 = 0.5/5 = 0.1
    call check(error, p%nleg(1) == 0 .and. p%chi(0, 1) == 1.0_wp .and. all(p%chi(1:, 1) == 0), &
               'phase 1 isotropic')
    call check_close(error, p%chi(2, 2), 0.1_dp, rel_tol=TIGHT, label='Rayleigh chi_2')
    call check_close(error, p%chi(1, 2), 0.0_dp, abs_tol=0.0_dp, label='Rayleigh chi_1')
    ! line 46: phase 26 begins "470 2.63085 4.04220"; its last term (line 48) is 0.00001
    call check_close(error, p%chi(1, 26), 2.63085_dp/3, rel_tol=TIGHT, label='g of phase 26')
    call check_close(error, p%chi(2, 26), 4.04220_dp/5, rel_tol=TIGHT, label='chi_2 of phase 26')
    call check_close(error, p%chi(470, 26), 1.0e-5_dp/941, rel_tol=TIGHT, label='chi_470')
    call check(error, all(p%chi(471:, 26) == 0.0_wp), 'zero beyond nleg')
    ! line 4405 (largest extinction): "4 50 16 281.7 281.1206 0.952531 26"
    call check_close(error, p%extinction(4, 50, 16), 0.2811206_dp, rel_tol=TIGHT, label='ext')
    call check_close(error, p%temperature(4, 50, 16), 281.7_dp, rel_tol=TIGHT, label='temp')
    call check_close(error, p%ssa(4, 50, 16), 0.952531_dp, rel_tol=TIGHT, label='ssa')
    call check(error, p%iphase(4, 50, 16) == 26, 'iphase(4,50,16)')
    ! line 36331: "32 32 10 282.1 0.0000 0.000000 1"
    call check(error, p%extinction(32, 32, 10) == 0.0_wp .and. p%iphase(32, 32, 10) == 1, &
               'clear point (32,32,10)')
    ! awk mean of column 5 over the 73728 point lines: 16.832981281196 km-1
    call check_close(error, sum(p%extinction)/size(p%extinction), 16.832981281196e-3_dp, &
                     rel_tol=1.0e-10_dp, label='mean extinction [m-1]')
    call check(error, index(p%missing, 'wavelength') > 0, 'missing: '//p%missing)
  end subroutine test_prp_real

  subroutine test_prp_2d(error)
    type(error_t), allocatable, intent(out) :: error
    type(prp_field_t) :: p
    type(error_t), allocatable :: err
    call read_prp_file(shared_dir//LES//'les2y21w16.prp', p, err)
    call no_error(error, err)
    if (allocated(error)) return
    ! line 2 "64 1 30"; line 3 holds dx dy and 30 = nz heights: SHDOM grid points
    call check(error, p%nx == 64 .and. p%ny == 1 .and. p%nz == 30, 'sizes')
    call check(error, .not. p%z_are_boundaries .and. size(p%z) == 30, 'nz grid levels expected')
    call check_close(error, p%z(2), 50.0_dp, rel_tol=TIGHT, label='z(2) (0.05 km)')
    call check(error, p%nphase == 52 .and. p%nleg(52) == 637, 'phase table (line 4: 52)')
    ! line 83: phase 44 begins "532 2.59683 3.97957"
    call check_close(error, p%chi(1, 44), 2.59683_dp/3, rel_tol=TIGHT, label='g of phase 44')
    ! line 1516: "47 1 24 283.9 102.935 0.989085 44"
    call check_close(error, p%extinction(47, 1, 24), 0.102935_dp, rel_tol=TIGHT, label='ext')
    call check(error, p%iphase(47, 1, 24) == 44, 'iphase(47,1,24)')
    ! awk mean of column 5 over the 1920 point lines: 6.6960265625 km-1
    call check_close(error, sum(p%extinction)/size(p%extinction), 6.6960265625e-3_dp, &
                     rel_tol=1.0e-10_dp, label='mean extinction [m-1]')
  end subroutine test_prp_2d

  !> The 1-parameter file leaves r_eff to the droplet number. Reference: the gamma distribution
  !> n(r) ~ r^7 exp(-10 r / reff) integrated numerically here (midpoint rule) gives the LWC of
  !> N droplets per cm3 with a chosen reff; kumo's closed form must return that reff.
  subroutine test_lwc_one_param(error)
    type(error_t), allocatable, intent(out) :: error
    type(lwc_field_t) :: f
    type(error_t), allocatable :: err
    real(dp) :: re, n_cm3, dr, r, w, m0, m3, lwc
    integer :: i
    character(len=*), parameter :: FILE = 'formats_one_param.lwc'
    call write_text(FILE, '1 parameter file'//NL//'2 1 2'//NL//'0.1 0.1'//NL// &
                    '0.5 0.6 0.7'//NL//'280 279 278'//NL//'1 1 1 0.25'//NL//'2 1 2 0.0'//NL)
    call read_lwc_file(FILE, f, err)
    call no_error(error, err)
    if (allocated(error)) return
    call check(error, f%n_params == 1 .and. f%n_listed == 2 .and. .not. f%listed(2, 1, 1), &
               'two of four points listed')
    call check(error, index(f%missing, 'droplet number') > 0, 'missing: '//f%missing)
    call check(error, all(f%reff == 0.0_wp), 'reff unknown before the droplet number')
    ! numerical reference: reff = 8 um, N = 100 cm-3
    re = 8.0_dp
    n_cm3 = 100.0_dp
    dr = 60.0_dp*re/200000
    m0 = 0.0_dp
    m3 = 0.0_dp
    do i = 1, 200000
      r = (i - 0.5_dp)*dr
      w = r**7*exp(-10.0_dp*r/re)
      m0 = m0 + w
      m3 = m3 + w*r**3
    end do
    ! lwc [g m-3] = 4/3 pi rho_w N <r^3>, rho_w = 1e6 g m-3, N in m-3, r in m
    lwc = 4.0_dp/3.0_dp*PI*1.0e6_dp*(n_cm3*1.0e6_dp)*(m3/m0)*1.0e-18_dp
    ! midpoint rule on a smooth integrand with 2e5 steps: relative error << 1e-9
    call check_close(error, reff_from_droplet_number(lwc, n_cm3), re, rel_tol=1.0e-9_dp, &
                     label='reff from numerical gamma LWC')
    call set_reff_from_droplet_number(f, n_cm3, err)
    call no_error(error, err)
    call check_close(error, f%reff(1, 1, 1), reff_from_droplet_number(0.25_dp, n_cm3), &
                     rel_tol=TIGHT, label='field reff')
    call check(error, f%reff(2, 1, 2) == 0.0_wp, 'no droplets, no radius')
    call check(error, index(f%missing, 'droplet number') == 0, 'droplet number now known')
    call set_reff_from_droplet_number(f, -5.0_dp, err)
    call check_error_words(error, err, ['droplet number = -5', 'must be > 0        '])
  end subroutine test_lwc_one_param

  subroutine test_lwc_bad(error)
    type(error_t), allocatable, intent(out) :: error
    type(lwc_field_t) :: f
    type(error_t), allocatable :: err
    character(len=*), parameter :: HEAD = '2 parameter LWC file'//NL//'2 2 1'//NL//'0.1 0.1'// &
                                   NL//'0.5 0.6'//NL//'280 279'//NL
    character(len=*), parameter :: FILE = 'formats_bad.lwc'
    ! truncated inside the header
    call write_text(FILE, '2 parameter LWC file'//NL//'2 2 1'//NL//'0.1 0.1'//NL)
    call read_lwc_file(FILE, f, err)
    call check_error_words(error, err, [character(len=40) :: FILE, 'ends after line 3', 'header'])
    ! heights: neither nz nor nz+1
    call write_text(FILE, '2'//NL//'2 2 1'//NL//'0.1 0.1'//NL//'0.5 0.6 0.7'//NL//'1 2 3'//NL)
    call read_lwc_file(FILE, f, err)
    call check_error_words(error, err, [character(len=40) :: 'line 4', 'holds 3 heights'])
    ! wrong count of values on a point line (truncated line)
    call write_text(FILE, HEAD//'1 1 1 0.1 8'//NL//'2 1 1 0.2'//NL)
    call read_lwc_file(FILE, f, err)
    call check_error_words(error, err, [character(len=40) :: 'line 7', 'holds 4 values', &
                                   'expected 5 (ix iy iz lwc reff)'])
    ! negative water
    call write_text(FILE, HEAD//'1 1 1 -0.1 8'//NL)
    call read_lwc_file(FILE, f, err)
    call check_error_words(error, err, [character(len=40) :: FILE//' line 6', 'lwc = -0.1 g m-3', &
                                   'must be >= 0'])
    ! NaN
    call write_text(FILE, HEAD//'1 1 1 0.1 8'//NL//'1 2 1 NaN 8'//NL)
    call read_lwc_file(FILE, f, err)
    call check_error_words(error, err, [character(len=40) :: 'line 7', 'lwc = NaN', 'must be finite'])
    ! index out of range
    call write_text(FILE, HEAD//'3 1 1 0.1 8'//NL)
    call read_lwc_file(FILE, f, err)
    call check_error_words(error, err, [character(len=40) :: 'line 6', 'ix = 3', &
                                   'must be within [1, nx = 2]'])
    ! duplicate point
    call write_text(FILE, HEAD//'1 1 1 0.1 8'//NL//'2 2 1 0.1 8'//NL//'1 1 1 0.2 9'//NL)
    call read_lwc_file(FILE, f, err)
    call check_error_words(error, err, [character(len=40) :: 'line 8', 'point (1, 1, 1)', &
                                   'listed twice (first on line 6)'])
    ! water without a radius
    call write_text(FILE, HEAD//'1 1 1 0.1 0'//NL)
    call read_lwc_file(FILE, f, err)
    call check_error_words(error, err, [character(len=40) :: 'reff = 0', 'must be > 0 where lwc > 0'])
    ! multi-component particle files are not LWC files
    call write_text(FILE, '3'//NL//'2 2 1'//NL)
    call read_lwc_file(FILE, f, err)
    call check_error_words(error, err, [character(len=40) :: 'line 1', 'format type = 3'])
    ! the file itself must exist
    call read_lwc_file('formats_no_such_file.lwc', f, err)
    call check_error_words(error, err, [character(len=40) :: 'cannot open', 'formats_no_such_file'])
  end subroutine test_lwc_bad

  subroutine test_prp_bad(error)
    type(error_t), allocatable, intent(out) :: error
    type(prp_field_t) :: p
    type(error_t), allocatable :: err
    character(len=:), allocatable :: head, pts
    character(len=*), parameter :: FILE = 'formats_bad.prp'
    ! 2 x 1 x 2 grid points, two phase functions (the second, HG g = 0.5, over two lines)
    head = 'Tabulated phase function property file'//NL//'2 1 2'//NL//'0.5 0.5 0.0 1.0'//NL// &
           '2'//NL//'0'//NL//'3 1.5 1.25'//NL//'  0.875'//NL
    pts = '1 1 1 280 0.0 0.0 1'//NL//'2 1 1 280 2.0 0.99 2'//NL//'1 1 2 270 1.0 1.0 2'//NL
    call write_text(FILE, head//pts//'2 1 2 270 0.0 0.0 1'//NL)
    call read_prp_file(FILE, p, err)
    call no_error(error, err)
    if (allocated(error)) return
    call check(error, .not. p%z_are_boundaries .and. p%nleg(2) == 3, 'small file layout')
    ! HG: chi_l = g^l
    call check_close(error, p%chi(1, 2), 0.5_dp, rel_tol=TIGHT, label='HG chi_1')
    call check_close(error, p%chi(3, 2), 0.125_dp, rel_tol=TIGHT, label='HG chi_3')
    call check_close(error, p%extinction(2, 1, 1), 2.0e-3_dp, rel_tol=TIGHT, label='km-1 -> m-1')
    ! a point missing
    call write_text(FILE, head//pts)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'lists 3 of nx*ny*nz = 4', &
                                   'first missing is (2, 1, 2)'])
    ! phase-function index out of range
    call write_text(FILE, head//pts//'2 1 2 270 0.0 0.0 3'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'line 11', 'iphase = 3', &
                                   'within [1, numphase = 2]'])
    ! NaN extinction, negative extinction, ssa above one
    call write_text(FILE, head//pts//'2 1 2 270 nan 0.0 1'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'line 11', 'ext = NaN', 'finite'])
    call write_text(FILE, head//pts//'2 1 2 270 -1.0 0.0 1'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'line 11', 'ext = -1 km-1', '>= 0'])
    call write_text(FILE, head//pts//'2 1 2 270 1.0 1.5 1'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'ssa = 1.5', 'within [0, 1]'])
    ! duplicate point
    call write_text(FILE, head//pts//'2 1 1 270 1.0 0.5 1'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'line 11', 'point (2, 1, 1)', &
                                   'listed twice (first on line 9)'])
    ! trailing value on a point line
    call write_text(FILE, head//pts//'2 1 2 270 1.0 0.5 1 7'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'line 11', 'holds 8 values', &
                                   'expected 7'])
    ! numphase too small: the next coefficients are left over
    call write_text(FILE, 'T'//NL//'2 1 2'//NL//'0.5 0.5 0.0 1.0'//NL//'1'//NL//'1 1.5 1.25'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'line 5', 'unexpected "1.25"', &
                                   'numphase too small'])
    ! |chi_1| > 1, i.e. a_1 > 3
    call write_text(FILE, 'T'//NL//'2 1 2'//NL//'0.5 0.5 0.0 1.0'//NL//'1'//NL//'1 3.3'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'line 5', '|chi_1| = 1.1 > 1'])
    ! truncated inside the phase table
    call write_text(FILE, 'T'//NL//'2 1 2'//NL//'0.5 0.5 0.0 1.0'//NL//'2'//NL//'3 1.5'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'ends after line 5', &
                                   'phase-function table'])
    ! another SHDOM property format
    call write_text(FILE, 'E'//NL//'2 1 2'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'line 1', 'does not begin with ''T'''])
    ! levels must increase
    call write_text(FILE, 'T'//NL//'2 1 2'//NL//'0.5 0.5 1.0 1.0'//NL)
    call read_prp_file(FILE, p, err)
    call check_error_words(error, err, [character(len=40) :: 'line 3', 'heights must increase'])
  end subroutine test_prp_bad

  subroutine test_mystic(error)
    type(error_t), allocatable, intent(out) :: error
    type(mystic_cloud_t) :: c
    type(error_t), allocatable :: err
    character(len=*), parameter :: FILE = 'formats_mystic.dat'
    ! flag 1: ext [km-1] g ssa
    call write_text(FILE, '3 2 2 1'//NL//'0.1 0.2 1.0 1.5 2.5'//NL//'1 1 1 10.0 0.85 0.999'// &
                    NL//'3 2 2 20.0 -0.2 1.0'//NL)
    call read_mystic_file(FILE, c, err)
    call no_error(error, err)
    if (allocated(error)) return
    call check(error, c%flag == 1 .and. c%nx == 3 .and. c%ny == 2 .and. c%nz == 2, 'flag 1 sizes')
    call check_close(error, c%dx, 100.0_dp, rel_tol=TIGHT, label='dx')
    call check_close(error, c%dy, 200.0_dp, rel_tol=TIGHT, label='dy')
    call check_close(error, c%z(3), 2500.0_dp, rel_tol=TIGHT, label='top boundary')
    call check_close(error, c%ext(3, 2, 2), 0.02_dp, rel_tol=TIGHT, label='ext [m-1]')
    call check_close(error, c%g(3, 2, 2), -0.2_dp, rel_tol=TIGHT, label='g')
    call check_close(error, c%ssa(1, 1, 1), 0.999_dp, rel_tol=TIGHT, label='ssa')
    call check(error, c%n_listed == 2 .and. c%ext(2, 1, 1) == 0.0_wp, 'unlisted cells empty')
    call check(error, .not. allocated(c%lwc) .and. index(c%missing, 'wavelength') > 0, &
               'flag 1: only the wavelength is missing')
    ! flag 2: ext reff
    call write_text(FILE, '1 1 1 2'//NL//'1 1 0 1'//NL//'1 1 1 5.0 12.5'//NL)
    call read_mystic_file(FILE, c, err)
    call no_error(error, err)
    call check_close(error, c%ext(1, 1, 1), 5.0e-3_dp, rel_tol=TIGHT, label='flag 2 ext')
    call check_close(error, c%reff(1, 1, 1), 12.5_dp, rel_tol=TIGHT, label='flag 2 reff')
    call check(error, index(c%missing, 'phase function') > 0, 'flag 2 needs optics for reff')
    ! flag 3: lwc reff
    call write_text(FILE, '2 1 1 3'//NL//'1 1 0 1'//NL//'2 1 1 0.3 9.0'//NL)
    call read_mystic_file(FILE, c, err)
    call no_error(error, err)
    call check_close(error, c%lwc(2, 1, 1), 0.3_dp, rel_tol=TIGHT, label='flag 3 lwc')
    call check(error, c%lwc(1, 1, 1) == 0.0_wp .and. index(c%missing, 'Mie') > 0, 'flag 3')
  end subroutine test_mystic

  subroutine test_mystic_bad(error)
    type(error_t), allocatable, intent(out) :: error
    type(mystic_cloud_t) :: c
    type(error_t), allocatable :: err
    character(len=*), parameter :: FILE = 'formats_bad_mystic.dat'
    character(len=*), parameter :: HEAD3 = '2 1 1 3'//NL//'1 1 0 1'//NL
    call write_text(FILE, HEAD3//'1 1 1 -0.3 9.0'//NL)
    call read_mystic_file(FILE, c, err)
    call check_error_words(error, err, [character(len=40) :: 'line 3', 'lwc = -0.3 g m-3', '>= 0'])
    call write_text(FILE, HEAD3//'1 1 1 0.3 9.0'//NL//'1 1 1 0.2 8.0'//NL)
    call read_mystic_file(FILE, c, err)
    call check_error_words(error, err, [character(len=40) :: 'line 4', 'cell (1, 1, 1)', &
                                   'listed twice (first on line 3)'])
    call write_text(FILE, HEAD3//'1 1 1 0.3'//NL)
    call read_mystic_file(FILE, c, err)
    call check_error_words(error, err, [character(len=40) :: 'line 3', 'holds 4 values', &
                                   'expected 5 (ix iy iz lwc reff)'])
    call write_text(FILE, HEAD3//'1 1 2 0.3 9.0'//NL)
    call read_mystic_file(FILE, c, err)
    call check_error_words(error, err, [character(len=40) :: 'line 3', 'iz = 2', '[1, nz = 1]'])
    call write_text(FILE, HEAD3//'1 1 1 inf 9.0'//NL)
    call read_mystic_file(FILE, c, err)
    call check_error_words(error, err, [character(len=40) :: 'line 3', 'lwc = Inf', 'finite'])
    call write_text(FILE, '1 1 1 1'//NL//'1 1 0 1'//NL//'1 1 1 5.0 1.0 0.9'//NL)
    call read_mystic_file(FILE, c, err)
    call check_error_words(error, err, [character(len=40) :: 'line 3', 'g = 1', '|g| < 1'])
    call write_text(FILE, '1 1 1 4'//NL//'1 1 0 1'//NL)
    call read_mystic_file(FILE, c, err)
    call check_error_words(error, err, [character(len=40) :: 'line 1', 'flag = 4'])
    call write_text(FILE, '1 1 2 3'//NL//'1 1 0 1'//NL)
    call read_mystic_file(FILE, c, err)
    call check_error_words(error, err, [character(len=40) :: 'line 2', 'holds 4 values', &
                                   'nz+1 = 3 layer boundaries'])
    call write_text(FILE, '1 1 2 3'//NL)
    call read_mystic_file(FILE, c, err)
    call check_error_words(error, err, [character(len=40) :: 'ends after line 1', 'truncated'])
  end subroutine test_mystic_bad

  ! ------------------------------------------------------------------------------------------
  ! MCARaTS binary files
  ! ------------------------------------------------------------------------------------------

  subroutine test_mcarats_atm(error)
    type(error_t), allocatable, intent(out) :: error
    type(mcarats_atm_t) :: a
    type(error_t), allocatable :: err
    call read_mcarats_atm_ctl(shared_dir//MCA//'les05_0213.atm.ctl', a, err, npf=60)
    call no_error(error, err)
    if (allocated(error)) return
    ! .ctl: XDEF 60, YDEF 60, tmpa3d 22 levels, abst3d/extp3d/omgp3d/apfp3d 21, TDEF 1
    call check(error, a%nx == 60 .and. a%ny == 60 .and. a%nz3 == 21 .and. a%mtprof == 1 .and. &
               a%nkd == 1 .and. a%np3d == 1 .and. a%ndatasets == 1, 'sizes from the .ctl')
    ! numpy, np.fromfile(..., '<f4').reshape(106, 60, 60) as [record, iy, ix]; float32 values
    ! compared after conversion to double: exact
    call check_close(error, a%tmpa(1, 1, 1), real(-0.012359619_real32, dp), rel_tol=TIGHT, &
                     label='tmpa3d(1,1,1) (record 1)')
    call check_close(error, a%tmpa(60, 60, 22), real(-0.0046081543_real32, dp), rel_tol=TIGHT, &
                     label='tmpa3d(60,60,22) (record 22)')
    ! largest extinction at ix=5, iy=36, layer 19: 0.19806351 m-1, omg 0.97181225, apf 60
    call check_close(error, a%ext(5, 36, 19, 1), real(0.19806351_real32, dp), rel_tol=TIGHT, &
                     label='extp3d(5,36,19)')
    call check_close(error, a%omg(5, 36, 19, 1), real(0.97181225_real32, dp), rel_tol=TIGHT, &
                     label='omgp3d(5,36,19)')
    call check(error, a%apf(5, 36, 19, 1) == 60.0_wp .and. maxval(a%apf) == 60.0_wp, 'apf')
    ! numpy double-precision mean of extp3d: 0.0386287741; sum of omgp3d: 74943.8772 (both
    ! printed to 9 digits, hence 1e-8 relative)
    call check_close(error, sum(a%ext)/size(a%ext), 0.0386287741_dp, rel_tol=1.0e-8_dp, &
                     label='mean extinction')
    call check_close(error, sum(a%omg), 74943.8772_dp, rel_tol=1.0e-8_dp, label='sum omg')
    call check(error, index(a%missing, 'Atm_zgrd0') > 0, 'missing: '//a%missing)
    ! the same file with the namelist sizes of conf_rs0213 (nz3 = 21, mtprof = 1)
    call read_mcarats_atm(shared_dir//MCA//'les05_0213.atm', 60, 60, 21, 1, 1, 1, a, err)
    call no_error(error, err)
    ! wrong sizes (mtprof = 0) do not fit the file size: rejected, not guessed
    call read_mcarats_atm(shared_dir//MCA//'les05_0213.atm', 60, 60, 21, 0, 1, 1, a, err)
    call check_error_words(error, err, [character(len=48) :: '1526400 bytes', &
                                   'not a whole number of datasets'])
    ! fewer tabulated phase functions than the apf codes use
    call read_mcarats_atm_ctl(shared_dir//MCA//'les05_0213.atm.ctl', a, err, npf=59)
    call check_error_words(error, err, [character(len=48) :: 'apfp3d comp. 1 layer', &
                                   'must be within (-3, npf = 59]'])
  end subroutine test_mcarats_atm

  subroutine test_mcarats_phase(error)
    type(error_t), allocatable, intent(out) :: error
    type(mcarats_phase_t) :: p
    type(error_t), allocatable :: err
    real(dp) :: mu
    integer :: i
    call read_mcarats_phase_ctl(shared_dir//MCA//'les05_0213.sca.ctl', p, err)
    call no_error(error, err)
    if (allocated(error)) return
    ! .ctl: XDEF 203, phs 60 levels; numpy: angles 0, 0.02, ..., angle(101) = 96, angle(203) = 180
    call check(error, p%nang == 203 .and. p%npf == 60 .and. .not. p%reversed, 'sizes')
    call check_close(error, p%angle_deg(101), 96.0_dp, rel_tol=TIGHT, label='angle(101)')
    call check_close(error, p%p_file(1, 60), real(1092.24462890625_real32, dp), rel_tol=TIGHT, &
                     label='P(0) of table 60 as stored')
    ! Table 1 is Rayleigh stored as P/(4 pi); normalised it must be 3/4 (1 + mu^2). The file's
    ! float32 values and the trapezoidal normalisation on 203 angles agree with it to 6.4e-5
    ! (numpy), so 1e-4 relative.
    do i = 1, p%nang, 10
      mu = cos(p%angle_deg(i)*PI/180)
      call check_close(error, p%p(i, 1), 0.75_dp*(1 + mu**2), rel_tol=1.0e-4_dp, label='Rayleigh')
    end do
    ! numpy trapezoid normalisation of table 60: P(0) = 1089.000383662012
    call check_close(error, p%p(1, 60), 1089.000383662012_dp, rel_tol=1.0e-9_dp, &
                     label='normalised P(0) of table 60')
  end subroutine test_mcarats_phase

  !> A 2 x 1 atmosphere, 1 layer, mtprof 0, one k-term and one component: 5 records of 2 values.
  subroutine test_mcarats_bad(error)
    type(error_t), allocatable, intent(out) :: error
    type(mcarats_atm_t) :: a
    type(mcarats_phase_t) :: p
    type(error_t), allocatable :: err
    real(real32) :: good(2, 5), bad(2, 5), ang(4), ph(4, 2)
    real(real32) :: nan32
    character(len=*), parameter :: FILE = 'formats_small.atm', PFILE = 'formats_small.sca'
    good = reshape([real(real32) :: 1.5, -2.0, 1e-4, 2e-4, 0.01, 0.02, 0.99, 1.0, 1.0, 0.85], &
                   [2, 5])
    call write_f32(FILE, good)
    call read_mcarats_atm(FILE, 2, 1, 1, 0, 1, 1, a, err, npf=1)
    call no_error(error, err)
    if (allocated(error)) return
    call check_close(error, a%ext(2, 1, 1, 1), real(0.02_real32, dp), rel_tol=TIGHT, label='ext')
    call check_close(error, a%apf(2, 1, 1, 1), real(0.85_real32, dp), rel_tol=TIGHT, label='apf')
    call check_close(error, a%absg(1, 1, 1, 1), real(1e-4_real32, dp), rel_tol=TIGHT, label='abs')
    ! two datasets, the second selected
    bad = good
    bad(:, 1) = [3.0, -4.0]
    call write_f32(FILE, reshape([good, bad], [2, 10]))
    call read_mcarats_atm(FILE, 2, 1, 1, 0, 1, 1, a, err, idread=2)
    call no_error(error, err)
    call check(error, a%ndatasets == 2 .and. a%tmpa(2, 1, 1) == -4.0_wp, 'dataset 2')
    ! NaN, from its bit pattern
    nan32 = transfer(int(z'7FC00000', int32), 1.0_real32)
    bad = good
    bad(2, 3) = nan32
    call write_f32(FILE, bad)
    call read_mcarats_atm(FILE, 2, 1, 1, 0, 1, 1, a, err)
    call check_error_words(error, err, [character(len=40) :: FILE//': record 3', &
                                   '(extp3d comp. 1 layer 1)', 'value 2 is NaN'])
    ! negative extinction
    bad = good
    bad(1, 3) = -0.25
    call write_f32(FILE, bad)
    call read_mcarats_atm(FILE, 2, 1, 1, 0, 1, 1, a, err)
    call check_error_words(error, err, [character(len=40) :: 'record 3 (extp3d', 'ix = 1, iy = 1', &
                                   'extp3d = -0.25', 'must be within [0, Inf)'])
    ! single-scattering albedo above one
    bad = good
    bad(2, 4) = 1.25
    call write_f32(FILE, bad)
    call read_mcarats_atm(FILE, 2, 1, 1, 0, 1, 1, a, err)
    call check_error_words(error, err, [character(len=40) :: 'record 4 (omgp3d', 'omgp3d = 1.25', &
                                   'within [0, 1]'])
    ! apf index beyond the phase-function table
    bad = good
    bad(1, 5) = 3.0
    call write_f32(FILE, bad)
    call read_mcarats_atm(FILE, 2, 1, 1, 0, 1, 1, a, err, npf=2)
    call check_error_words(error, err, [character(len=40) :: 'record 5 (apfp3d', 'apfp3d = 3', &
                                   'npf = 2]'])
    ! truncated and trailing data
    call write_f32(FILE, reshape(good(:, 1:4), [2, 4]))
    call read_mcarats_atm(FILE, 2, 1, 1, 0, 1, 1, a, err)
    call check_error_words(error, err, [character(len=40) :: '32 bytes', 'fewer than one dataset', &
                                   'truncated'])
    call write_f32(FILE, reshape([good, [real(real32) :: 7.0, 7.0, 7.0]], [13, 1]))
    call read_mcarats_atm(FILE, 2, 1, 1, 0, 1, 1, a, err)
    call check_error_words(error, err, [character(len=40) :: '52 bytes', &
                                   'not a whole number of datasets', 'trailing data'])
    ! phase functions: decreasing angles are reversed; a duplicate angle is rejected
    ang = [real(real32) :: 180, 120, 60, 0]
    ph = reshape([real(real32) :: 1, 1, 1, 1, 0.5, 0.5, 1.5, 1.5], [4, 2])
    call write_f32(PFILE, reshape([ang, ph], [4, 3]))
    call read_mcarats_phase(PFILE, 4, 2, p, err)
    call no_error(error, err)
    call check(error, p%reversed .and. p%angle_deg(2) == 60.0_wp, 'decreasing angles reversed')
    ! P = 1 everywhere integrates exactly (trapezoid of a constant)
    call check_close(error, p%p(3, 1), 1.0_dp, rel_tol=1.0e-12_dp, label='isotropic normalised')
    call check_close(error, p%p(1, 2), 1.5_dp/1.0_dp, rel_tol=1.0e-6_dp, &
                     label='table 2 reversed with its angles')
    ang = [real(real32) :: 0, 60, 60, 180]
    call write_f32(PFILE, reshape([ang, ph], [4, 3]))
    call read_mcarats_phase(PFILE, 4, 2, p, err)
    call check_error_words(error, err, [character(len=40) :: 'record 1 (angles)', 'angle 3 = 60', &
                                   'duplicate or unsorted'])
    ang = [real(real32) :: 0, 60, 120, 180]
    ph(2, 2) = -0.5
    call write_f32(PFILE, reshape([ang, ph], [4, 3]))
    call read_mcarats_phase(PFILE, 4, 2, p, err)
    call check_error_words(error, err, [character(len=40) :: 'record 3 (phase function 2)', &
                                   'value 2 = -0.5', 'must be >= 0'])
  end subroutine test_mcarats_bad

  subroutine test_mcarats_surface(error)
    type(error_t), allocatable, intent(out) :: error
    type(mcarats_surface_t) :: s
    type(error_t), allocatable :: err
    real(real32) :: rec(3, 7), bad(3, 7)
    character(len=*), parameter :: FILE = 'formats_small.sfc'
    ! 3 x 1 pixels: Lambert 0.2, DSM (0.05, 0.1, 1.33, 0, 0.02), black; npsfc = 5
    rec(:, 1) = [290.0, 291.0, 292.0]
    rec(:, 2) = [1.0, 2.0, 0.0]
    rec(:, 3) = [0.2, 0.05, 0.0]
    rec(:, 4) = [0.0, 0.1, 0.0]
    rec(:, 5) = [0.0, 1.33, 0.0]
    rec(:, 6) = [0.0, 0.0, 0.0]
    rec(:, 7) = [0.0, 0.02, 0.0]
    call write_f32(FILE, rec)
    call read_mcarats_surface(FILE, 3, 1, 5, s, err)
    call no_error(error, err)
    if (allocated(error)) return
    call check(error, all(s%brdf_type(:, 1) == [1, 2, 0]), 'BRDF types')
    call check_close(error, s%params(2, 1, 3), real(1.33_real32, dp), rel_tol=TIGHT, label='n_r')
    call check_close(error, s%temperature(3, 1), 292.0_dp, rel_tol=TIGHT, label='temperature')
    bad = rec
    bad(1, 2) = 7.0
    call write_f32(FILE, bad)
    call read_mcarats_surface(FILE, 3, 1, 5, s, err)
    call check_error_words(error, err, [character(len=40) :: 'pixel (ix=1, iy=1)', &
                                   'record 2 (BRDF type) = 7'])
    bad = rec
    bad(1, 3) = 1.5
    call write_f32(FILE, bad)
    call read_mcarats_surface(FILE, 3, 1, 5, s, err)
    call check_error_words(error, err, [character(len=40) :: 'Lambert albedo', '= 1.5', '[0, 1]'])
    ! DSM needs five parameters
    call write_f32(FILE, rec(:, 1:5))
    call read_mcarats_surface(FILE, 3, 1, 3, s, err)
    call check_error_words(error, err, [character(len=40) :: 'pixel (ix=2, iy=1)', 'DSM needs 5', &
                                   'npsfc = 3'])
    ! truncated
    call write_f32(FILE, rec(:, 1:6))
    call read_mcarats_surface(FILE, 3, 1, 5, s, err)
    call check_error_words(error, err, [character(len=40) :: 'fewer than one dataset'])
  end subroutine test_mcarats_surface

  ! ------------------------------------------------------------------------------------------
  ! Helpers
  ! ------------------------------------------------------------------------------------------

  !> Turn a reader's error into a test failure.
  subroutine no_error(error, err)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    if (allocated(err)) call check(error, .false., 'unexpected error: '//err%message)
  end subroutine no_error

  subroutine write_text(path, text)
    character(len=*), intent(in) :: path, text
    integer :: unit
    open (newunit=unit, file=path, status='replace', action='write', access='stream', &
          form='unformatted')
    write (unit) text
    close (unit)
  end subroutine write_text

  !> Raw native float32 records, as MCARaTS writes them.
  subroutine write_f32(path, values)
    character(len=*), intent(in) :: path
    real(real32), intent(in) :: values(:, :)
    integer :: unit
    open (newunit=unit, file=path, status='replace', action='write', access='stream', &
          form='unformatted')
    write (unit) values
    close (unit)
  end subroutine write_f32
end module test_kumo_formats

program test_formats
  use test_kumo_formats, only: collect_formats
  use kumo_test_text, only: run_shared_suite
  implicit none
  call run_shared_suite('test_formats', 'data/i3rc/les_examples and data/mcarats', &
                        'kumo cloud-file readers', collect_formats())
end program test_formats
