! SPDX-License-Identifier: BSD-3-Clause
!> Checks of tests/data/thermal/thermal_1d_reference.csv (plane-parallel thermal-emission cases
!> computed by bench/thermal/make_thermal_reference.py with the independent discrete-ordinates
!> solver PythonicDISORT) and of kumo against it:
!>
!> * the file is complete and consistent (every case has its inputs and results, level and
!>   layer counts agree, scattering layers carry their phase function);
!> * the band Planck values of the file (scipy's adaptive quadrature to 1e-13, CODATA 2018
!>   constants) equal kumo_planck's band_radiance to the 11 digits printed in the file (3e-11
!>   relative: half a unit of the last digit is up to 1.5e-11);
!> * for every case without scattering, the exact column of kumo_thermal_column reproduces the
!>   fluxes at every level and the radiances of the file. Tolerance: 3 times the file's
!>   solver_error (the change of the reference between its two stream numbers; the
!>   discrete-ordinates fluxes are Gauss sums over the angle, whose error is largest in the thin
!>   layer) plus 1e-9 of the largest flux or radiance of the case (the 11 printed digits).
!>   Measured: 1.4e-8 of the largest flux in the thin layer (solver_error 3.8e-7 there), below
!>   5e-11 elsewhere; radiances within 1.4e-9.
!>
!> The scattering cases (Henyey-Greenstein g = 0.85 and the C.1 Mie phase function) are
!> references for Monte Carlo tests of thermal emission.
!>
!> tests/data/thermal/disort_thermal_problems.csv (DISORT problems 6, 7, 9c with their inputs)
!> is checked for consistency of its inputs with its answers: the direct flux is
!> fbeam umu0 exp(-utau/umu0) and the diffuse downward flux at the top is
!> pi (fisot + temis B(ttemp)) with the file's Planck value, both to the 6 printed digits.
module test_kumo_thermal_reference
  use kumo_kinds, only: wp
  use kumo_planck, only: spectral_band_t, band_from_wavenumbers, band_radiance
  use kumo_thermal_column, only: thermal_column_t, thermal_column_init, thermal_column_fluxes, &
                                 thermal_column_radiance
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  implicit none
  private
  public :: collect_thermal_reference, set_reference_file

  character(len=:), allocatable :: reference_file, disort_file

  !> One row of the file.
  type :: row_t
    character(len=32) :: case = ' '
    character(len=32) :: quantity = ' '
    integer :: index = 0
    logical :: has_mu = .false.
    real(wp) :: mu = 0.0_wp
    real(wp) :: value = 0.0_wp
    real(wp) :: solver_error = 0.0_wp
  end type row_t

contains

  subroutine set_reference_file(path, disort_path)
    character(len=*), intent(in) :: path, disort_path
    reference_file = path
    disort_file = disort_path
  end subroutine set_reference_file

  function collect_thermal_reference() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('file_complete', test_complete), &
             new_unittest('band_planck_values', test_planck_values), &
             new_unittest('nonscattering_cases_vs_exact_column', test_nonscattering), &
             new_unittest('disort_file_consistent', test_disort_file)]
  end function collect_thermal_reference

  !> Every case has all its inputs and results with consistent sizes; at least three cases
  !> without and two with scattering.
  subroutine test_complete(error)
    type(error_t), allocatable, intent(out) :: error
    type(row_t), allocatable :: rows(:)
    character(len=32), allocatable :: names(:)
    integer :: c, nz, k, n_scat, n_clear
    real(wp) :: ssa
    call read_rows(rows, names, error)
    if (allocated(error)) return
    n_scat = 0
    n_clear = 0
    do c = 1, size(names)
      nz = nint(value_of(rows, names(c), 'nz', 0))
      call check(error, nz >= 1, trim(names(c))//': nz')
      if (allocated(error)) return
      call check(error, count_of(rows, names(c), 'z_m') == nz + 1 .and. count_of(rows, names(c), 'temperature_K') == nz + 1 &
                 .and. count_of(rows, names(c), 'planck') == nz + 1 .and. count_of(rows, names(c), 'tau') == nz &
                 .and. count_of(rows, names(c), 'ssa') == nz .and. count_of(rows, names(c), 'phase') == nz &
                 .and. count_of(rows, names(c), 'flux_up') == nz + 1 .and. count_of(rows, names(c), 'flux_down') == nz + 1 &
                 .and. count_of(rows, names(c), 'radiance') >= 2, trim(names(c))//': level or layer counts')
      call check(error, count_of(rows, names(c), 'surface_emissivity') == 1 .and. &
                 count_of(rows, names(c), 'surface_planck') == 1 .and. count_of(rows, names(c), 'top_radiance') == 1 &
                 .and. count_of(rows, names(c), 'band_nu1_cm-1') == 1 .and. count_of(rows, names(c), 'streams') == 1, &
                 trim(names(c))//': boundary or band inputs missing')
      if (allocated(error)) return
      ssa = 0.0_wp
      do k = 1, nz
        ssa = max(ssa, value_of(rows, names(c), 'ssa', k))
        if (value_of(rows, names(c), 'ssa', k) > 0.0_wp) then
          select case (nint(value_of(rows, names(c), 'phase', k)))
          case (1)
            call check(error, count_of(rows, names(c), 'hg_g', k) == 1, trim(names(c))//': hg_g missing')
          case (2)
            call check(error, count_of(rows, names(c), 'chi_'//itoa(k)) == nint(value_of(rows, names(c), 'nmom', k)) &
                       .and. abs(value_of(rows, names(c), 'chi_'//itoa(k), 0) - 1.0_wp) < 1.0e-12_wp, &
                       trim(names(c))//': Legendre moments')
          case default
            call check(error, .false., trim(names(c))//': scattering layer without a phase function')
          end select
          if (allocated(error)) return
        end if
      end do
      if (ssa > 0.0_wp) then
        n_scat = n_scat + 1
      else
        n_clear = n_clear + 1
      end if
    end do
    call check(error, n_clear >= 3 .and. n_scat >= 2, 'expected >= 3 cases without and >= 2 with scattering, found ' &
               //itoa(n_clear)//' and '//itoa(n_scat))
  end subroutine test_complete

  !> The file's band Planck values against kumo_planck.
  subroutine test_planck_values(error)
    type(error_t), allocatable, intent(out) :: error
    type(row_t), allocatable :: rows(:)
    character(len=32), allocatable :: names(:)
    type(spectral_band_t) :: band
    integer :: c, i, nz, n
    call read_rows(rows, names, error)
    if (allocated(error)) return
    n = 0
    do c = 1, size(names)
      call band_from_wavenumbers(value_of(rows, names(c), 'band_nu1_cm-1', 0), value_of(rows, names(c), 'band_nu2_cm-1', 0), &
                                 band, error)
      if (allocated(error)) return
      nz = nint(value_of(rows, names(c), 'nz', 0))
      do i = 0, nz
        call check_close(error, band_radiance(band, value_of(rows, names(c), 'temperature_K', i)), &
                         value_of(rows, names(c), 'planck', i), rel_tol=3.0e-11_wp, label=trim(names(c))//' planck '//itoa(i))
        n = n + 1
      end do
      call check_close(error, band_radiance(band, value_of(rows, names(c), 'surface_temperature_K', 0)), &
                       value_of(rows, names(c), 'surface_planck', 0), rel_tol=3.0e-11_wp, label=trim(names(c))//' surface')
      call check_close(error, band_radiance(band, value_of(rows, names(c), 'top_temperature_K', 0)), &
                       value_of(rows, names(c), 'top_radiance', 0), rel_tol=3.0e-11_wp, label=trim(names(c))//' top')
      if (allocated(error)) return
      n = n + 2
    end do
    call check(error, n >= 10, 'only '//itoa(n)//' Planck values compared')
  end subroutine test_planck_values

  !> kumo's exact non-scattering column against every case of the file without scattering.
  subroutine test_nonscattering(error)
    type(error_t), allocatable, intent(out) :: error
    type(row_t), allocatable :: rows(:)
    character(len=32), allocatable :: names(:)
    type(thermal_column_t) :: col
    real(wp), allocatable :: tau(:), b(:), fu(:), fd(:), fdir(:), div(:), net(:)
    real(wp) :: fmax, rmax, ssa
    integer :: c, i, k, j, nz, n_cases, n_values
    call read_rows(rows, names, error)
    if (allocated(error)) return
    n_cases = 0
    n_values = 0
    do c = 1, size(names)
      nz = nint(value_of(rows, names(c), 'nz', 0))
      ssa = 0.0_wp
      do k = 1, nz
        ssa = max(ssa, value_of(rows, names(c), 'ssa', k))
      end do
      if (ssa > 0.0_wp) cycle
      allocate (tau(nz), b(0:nz), fu(0:nz), fd(0:nz), fdir(0:nz), div(0:nz), net(nz))
      do k = 1, nz
        tau(k) = value_of(rows, names(c), 'tau', k)
      end do
      do i = 0, nz
        b(i) = value_of(rows, names(c), 'planck', i)
      end do
      call thermal_column_init(col, tau, b, value_of(rows, names(c), 'surface_emissivity', 0), &
                               value_of(rows, names(c), 'surface_planck', 0), value_of(rows, names(c), 'top_radiance', 0), error)
      if (allocated(error)) return
      call thermal_column_fluxes(col, fu, fd, fdir, div, net)
      fmax = maxval(pack(rows%value, rows%case == names(c) .and. &
                         (rows%quantity == 'flux_up' .or. rows%quantity == 'flux_down')))
      rmax = maxval(pack(rows%value, rows%case == names(c) .and. rows%quantity == 'radiance'))
      do j = 1, size(rows)
        if (rows(j)%case /= names(c)) cycle
        i = rows(j)%index
        select case (rows(j)%quantity)
        case ('flux_up')
          call check_close(error, fu(i), rows(j)%value, abs_tol=3.0_wp*rows(j)%solver_error + 1.0e-9_wp*fmax, &
                           label=trim(names(c))//' flux_up level '//itoa(i))
        case ('flux_down')
          call check_close(error, fd(i), rows(j)%value, abs_tol=3.0_wp*rows(j)%solver_error + 1.0e-9_wp*fmax, &
                           label=trim(names(c))//' flux_down level '//itoa(i))
        case ('radiance')
          call check(error, rows(j)%has_mu, trim(names(c))//': radiance without mu')
          if (allocated(error)) return
          call check_close(error, thermal_column_radiance(col, i, rows(j)%mu), rows(j)%value, &
                           abs_tol=3.0_wp*rows(j)%solver_error + 1.0e-9_wp*rmax, label=trim(names(c))//' radiance level ' &
                           //itoa(i))
        case default
          cycle
        end select
        if (allocated(error)) return
        n_values = n_values + 1
      end do
      n_cases = n_cases + 1
      deallocate (tau, b, fu, fd, fdir, div, net)
    end do
    call check(error, n_cases >= 3 .and. n_values >= 20, 'compared only '//itoa(n_values)//' values of ' &
               //itoa(n_cases)//' cases')
  end subroutine test_nonscattering

  !> DISORT problems file: inputs consistent with the answers (direct flux, top downward flux).
  subroutine test_disort_file(error)
    type(error_t), allocatable, intent(out) :: error
    type(row_t), allocatable :: rows(:)
    character(len=32), allocatable :: names(:)
    real(wp) :: fbeam, umu0, expected, utau
    integer :: c, j, n_fir, n_fdn
    call read_disort_rows(rows, names, error)
    if (allocated(error)) return
    n_fir = 0
    n_fdn = 0
    do c = 1, size(names)
      fbeam = value_of(rows, names(c), 'fbeam', 0)
      umu0 = value_of(rows, names(c), 'umu0', 0)
      do j = 1, size(rows)
        if (rows(j)%case /= names(c)) cycle
        utau = value_of(rows, names(c), 'utau', rows(j)%index)
        if (rows(j)%quantity == 'FIR') then
          expected = fbeam*umu0*exp(-utau/umu0)
          call check_close(error, expected, rows(j)%value, rel_tol=5.0e-6_wp, abs_tol=1.0e-30_wp, &
                           label=trim(names(c))//' FIR '//itoa(rows(j)%index))
          n_fir = n_fir + 1
        else if (rows(j)%quantity == 'FDN' .and. utau == 0.0_wp .and. nint(value_of(rows, names(c), 'plank', 0)) == 1) then
          expected = 3.141592653589793_wp*(value_of(rows, names(c), 'fisot', 0) &
                     + value_of(rows, names(c), 'temis', 0)*value_of(rows, names(c), 'planck_ttemp', 0))
          call check_close(error, expected, rows(j)%value, rel_tol=5.0e-6_wp, label=trim(names(c))//' FDN top')
          n_fdn = n_fdn + 1
        end if
        if (allocated(error)) return
      end do
    end do
    call check(error, size(names) == 14 .and. n_fir >= 40 .and. n_fdn >= 9, 'DISORT file: '//itoa(size(names)) &
               //' cases, '//itoa(n_fir)//' direct and '//itoa(n_fdn)//' top fluxes checked')
  end subroutine test_disort_file

  ! -----------------------------------------------------------------------------------------
  ! Reading the files
  ! -----------------------------------------------------------------------------------------

  !> All rows of the file and the case names in order of appearance.
  subroutine read_rows(rows, names, error)
    type(row_t), allocatable, intent(out) :: rows(:)
    character(len=32), allocatable, intent(out) :: names(:)
    type(error_t), allocatable, intent(out) :: error
    character(len=512) :: line
    character(len=64) :: fields(6)
    type(row_t) :: r
    integer :: unit, ios, p, i, start, n
    open (newunit=unit, file=reference_file, status='old', action='read', iostat=ios)
    if (ios /= 0) then
      call check(error, .false., 'cannot open '//reference_file)
      return
    end if
    allocate (rows(1024), names(0))
    n = 0
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (line(1:1) == '#' .or. len_trim(line) == 0 .or. line(1:5) == 'case,') cycle
      fields = ' '
      start = 1
      i = 1
      do p = 1, len_trim(line) + 1
        if (p > len_trim(line) .or. line(p:p) == ',') then
          if (i <= 6) fields(i) = line(start:p - 1)
          i = i + 1
          start = p + 1
        end if
      end do
      if (i /= 7) then
        call check(error, .false., 'malformed line in '//reference_file//': '//trim(line))
        close (unit)
        return
      end if
      r = row_t()
      r%case = fields(1)
      r%quantity = fields(2)
      read (fields(3), *, iostat=ios) r%index
      if (ios == 0) read (fields(5), *, iostat=ios) r%value
      if (ios == 0 .and. len_trim(fields(4)) > 0) then
        r%has_mu = .true.
        read (fields(4), *, iostat=ios) r%mu
      end if
      if (ios == 0 .and. len_trim(fields(6)) > 0) read (fields(6), *, iostat=ios) r%solver_error
      if (ios /= 0) then
        call check(error, .false., 'unreadable number in '//reference_file//': '//trim(line))
        close (unit)
        return
      end if
      n = n + 1
      if (n > size(rows)) rows = [rows, rows]
      rows(n) = r
      if (.not. any(names == r%case)) names = [character(len=32) :: names, r%case]
    end do
    close (unit)
    rows = rows(1:n)
    call check(error, n > 0 .and. size(names) > 0, 'no data in '//reference_file)
  end subroutine read_rows

  !> The rows of the DISORT problems file, with the case named <problem><case> (e.g. 9c), the
  !> index i and the value; the intensity indices j, k are not needed here.
  subroutine read_disort_rows(rows, names, error)
    type(row_t), allocatable, intent(out) :: rows(:)
    character(len=32), allocatable, intent(out) :: names(:)
    type(error_t), allocatable, intent(out) :: error
    character(len=256) :: line
    character(len=64) :: fields(7)
    type(row_t) :: r
    integer :: unit, ios, p, i, start, n
    open (newunit=unit, file=disort_file, status='old', action='read', iostat=ios)
    if (ios /= 0) then
      call check(error, .false., 'cannot open '//disort_file)
      return
    end if
    allocate (rows(1024), names(0))
    n = 0
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (line(1:1) == '#' .or. len_trim(line) == 0 .or. line(1:8) == 'problem,') cycle
      fields = ' '
      start = 1
      i = 1
      do p = 1, len_trim(line) + 1
        if (p > len_trim(line) .or. line(p:p) == ',') then
          if (i <= 7) fields(i) = line(start:p - 1)
          i = i + 1
          start = p + 1
        end if
      end do
      r = row_t()
      r%case = trim(fields(1))//trim(fields(2))
      r%quantity = fields(3)
      read (fields(4), *, iostat=ios) r%index
      if (ios == 0) read (fields(7), *, iostat=ios) r%value
      if (i /= 8 .or. ios /= 0) then
        call check(error, .false., 'malformed line in '//disort_file//': '//trim(line))
        close (unit)
        return
      end if
      n = n + 1
      if (n > size(rows)) rows = [rows, rows]
      rows(n) = r
      if (.not. any(names == r%case)) names = [character(len=32) :: names, r%case]
    end do
    close (unit)
    rows = rows(1:n)
  end subroutine read_disort_rows

  !> The value of a row (huge() if absent, which makes the comparisons fail loudly).
  real(wp) function value_of(rows, case, quantity, index) result(v)
    type(row_t), intent(in) :: rows(:)
    character(len=*), intent(in) :: case, quantity
    integer, intent(in) :: index
    integer :: j
    v = huge(1.0_wp)
    do j = 1, size(rows)
      if (rows(j)%case == case .and. rows(j)%quantity == quantity .and. rows(j)%index == index) then
        v = rows(j)%value
        return
      end if
    end do
  end function value_of

  !> Number of rows of a quantity (of one index if given).
  integer function count_of(rows, case, quantity, index) result(n)
    type(row_t), intent(in) :: rows(:)
    character(len=*), intent(in) :: case, quantity
    integer, intent(in), optional :: index
    if (present(index)) then
      n = count(rows%case == case .and. rows%quantity == quantity .and. rows%index == index)
    else
      n = count(rows%case == case .and. rows%quantity == quantity)
    end if
  end function count_of

  function itoa(i) result(s)
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    character(len=16) :: buf
    write (buf, '(i0)') i
    s = trim(buf)
  end function itoa

end module test_kumo_thermal_reference

program test_thermal_reference
  use kumo_testing, only: run_unittests
  use test_kumo_thermal_reference, only: collect_thermal_reference, set_reference_file
  implicit none
  integer :: n_failed
  character(len=4096) :: arg1, arg2
  call get_command_argument(1, arg1)
  call get_command_argument(2, arg2)
  call set_reference_file(trim(arg1), trim(arg2))
  call run_unittests('thermal_reference', collect_thermal_reference(), n_failed)
  if (n_failed > 0) error stop 1
end program test_thermal_reference
