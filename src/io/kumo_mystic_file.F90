! SPDX-License-Identifier: BSD-3-Clause
!> Reader for the MYSTIC (libRadtran) 3-D cloud file, `wc_file 3D`, flags 1 to 3.
!>
!> ASCII, sparse (Mayer 2009 and the libRadtran user guide, option `wc_file 3D`):
!>
!>     nx ny nz flag
!>     dx dy z(1) ... z(nz+1)          [km; z are the boundaries of the nz layers]
!>     ix iy iz  <values>              [one cell per line]
!>
!> with <values> = `ext g ssa` (flag 1: extinction [km-1], asymmetry parameter of a
!> Henyey-Greenstein phase function, single-scattering albedo), `ext reff` (flag 2: km-1, um)
!> or `lwc reff` (flag 3: g m-3, um). Cells not listed hold no cloud. kumo returns metres,
!> m-1, g m-3 and um, arrays shaped (nx, ny, nz) with x fastest; cell (ix, iy, iz) spans
!> [(ix-1) dx, ix dx) x [(iy-1) dy, iy dy) x [z(iz), z(iz+1)).
!>
!> Flags 2 and 3 need optical properties for r_eff (libRadtran's `wc_properties`), and all
!> flags need the wavelength for everything else; `missing` says so.
module kumo_mystic_file
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str
  use kumo_shdom_files, only: text_file_t, text_open, text_close, text_next_line, &
                              count_fields, read_line_reals, where_line, point_name, size_error
  implicit none
  private
  public :: mystic_cloud_t, read_mystic_file
  public :: MYSTIC_EXT_G_SSA, MYSTIC_EXT_REFF, MYSTIC_LWC_REFF

  integer, parameter :: MYSTIC_EXT_G_SSA = 1  !! flag 1: ext [km-1], g, ssa
  integer, parameter :: MYSTIC_EXT_REFF = 2   !! flag 2: ext [km-1], reff [um]
  integer, parameter :: MYSTIC_LWC_REFF = 3   !! flag 3: lwc [g m-3], reff [um]

  !> A MYSTIC 3-D water-cloud file. Only the arrays of the file's flag are allocated.
  type :: mystic_cloud_t
    integer :: nx = 0, ny = 0, nz = 0   !! cells in x, y, z
    integer :: flag = 0                 !! 1, 2 or 3 (see MYSTIC_* constants)
    real(wp) :: dx = 0.0_wp             !! cell size in x [m]
    real(wp) :: dy = 0.0_wp             !! cell size in y [m]
    real(wp), allocatable :: z(:)       !! nz+1 layer boundaries, increasing [m]
    real(wp), allocatable :: ext(:, :, :)  !! extinction [m-1] (flags 1, 2)
    real(wp), allocatable :: g(:, :, :)    !! HG asymmetry parameter, |g| < 1 (flag 1)
    real(wp), allocatable :: ssa(:, :, :)  !! single-scattering albedo (flag 1)
    real(wp), allocatable :: lwc(:, :, :)  !! liquid water content [g m-3] (flag 3)
    real(wp), allocatable :: reff(:, :, :) !! effective radius [um] (flags 2, 3); 0 where empty
    logical, allocatable :: listed(:, :, :) !! cell listed in the file (others hold no cloud)
    integer :: n_listed = 0             !! number of listed cells
    !> What the file does not say and the caller must supply (from the namelist).
    character(len=:), allocatable :: missing
  end type mystic_cloud_t

contains

  !> Read a MYSTIC 3-D cloud file (flags 1-3). Every line is checked: counts, index ranges,
  !> duplicates, NaN, negative extinction or water, ssa outside [0, 1], |g| >= 1.
  subroutine read_mystic_file(path, cloud, error, length_unit)
    character(len=*), intent(in) :: path                !! file name
    type(mystic_cloud_t), intent(out) :: cloud          !! the cloud read
    type(error_t), allocatable, intent(out) :: error    !! unallocated on success
    real(wp), intent(in), optional :: length_unit       !! file length unit [m] (default 1000)
    type(text_file_t) :: tf
    real(wp) :: unit_m
    unit_m = 1000.0_wp
    if (present(length_unit)) unit_m = length_unit
    call text_open(path, tf, error)
    if (allocated(error)) return
    call mystic_body(tf, unit_m, cloud, error)
    call text_close(tf)
  end subroutine read_mystic_file

  subroutine mystic_body(tf, unit_m, cloud, error)
    type(text_file_t), intent(inout) :: tf
    real(wp), intent(in) :: unit_m
    type(mystic_cloud_t), intent(inout) :: cloud
    type(error_t), allocatable, intent(out) :: error
    integer :: n(4), nf, ios, k, ix, iy, iz, ncol, nmax(3)
    real(wp) :: v(3)
    real(wp), allocatable :: head(:)
    integer, allocatable :: first_line(:, :, :)
    logical :: found
    character(len=2), parameter :: NAMES(3) = ['nx', 'ny', 'nz']
    character(len=*), parameter :: COLUMNS(3) = ['ix iy iz ext g ssa', 'ix iy iz ext reff ', &
                                                 'ix iy iz lwc reff ']

    call text_next_line(tf, found)
    if (.not. found) then
      call set_error(error, tf%path//': empty file')
      return
    end if
    nf = count_fields(tf%line)
    if (nf /= 4) then
      call set_error(error, where_line(tf)//': holds '//str(nf)//' values; expected nx ny nz flag')
      return
    end if
    read (tf%line, *, iostat=ios) n
    if (ios /= 0) then
      call set_error(error, where_line(tf)//': cannot read nx ny nz flag (integers) from "'// &
                     trim(tf%line)//'"')
      return
    end if
    do k = 1, 3
      if (n(k) < 1) then
        call set_error(error, where_line(tf)//': '//NAMES(k)//' = '//str(n(k))//' must be >= 1')
        return
      end if
    end do
    if (n(4) < 1 .or. n(4) > 3) then
      call set_error(error, where_line(tf)//': flag = '//str(n(4))//' must be 1 (ext g ssa), '// &
                     '2 (ext reff) or 3 (lwc reff)')
      return
    end if
    cloud%nx = n(1)
    cloud%ny = n(2)
    cloud%nz = n(3)
    cloud%flag = n(4)
    nmax = n(1:3)

    call text_next_line(tf, found)
    if (.not. found) then
      call set_error(error, tf%path//': ends after line 1 (expected dx dy z(1) ... z(nz+1); '// &
                     'truncated file?)')
      return
    end if
    allocate (head(cloud%nz + 3))
    call read_line_reals(tf, cloud%nz + 3, head, 'dx dy and nz+1 = '//str(cloud%nz + 1)// &
                         ' layer boundaries', error)
    if (allocated(error)) return
    do k = 1, size(head)
      if (.not. ieee_is_finite(head(k))) then
        call set_error(error, where_line(tf)//': value '//str(k)//' = '//str(head(k))// &
                       ' must be finite')
        return
      end if
    end do
    if (head(1) <= 0.0_wp .or. head(2) <= 0.0_wp) then
      call set_error(error, where_line(tf)//': dx = '//str(head(1))//', dy = '//str(head(2))// &
                     ' must be > 0')
      return
    end if
    do k = 4, size(head)
      if (head(k) <= head(k - 1)) then
        call set_error(error, where_line(tf)//': layer boundaries must increase, but z('// &
                       str(k - 2)//') = '//str(head(k))//' <= z('//str(k - 3)//') = '// &
                       str(head(k - 1)))
        return
      end if
    end do
    cloud%dx = head(1)*unit_m
    cloud%dy = head(2)*unit_m
    cloud%z = head(3:)*unit_m

    associate (nx => cloud%nx, ny => cloud%ny, nz => cloud%nz)
      select case (cloud%flag)
      case (MYSTIC_EXT_G_SSA)
        allocate (cloud%ext(nx, ny, nz), cloud%g(nx, ny, nz), cloud%ssa(nx, ny, nz), &
                  source=0.0_wp, stat=ios)
        ncol = 3
      case (MYSTIC_EXT_REFF)
        allocate (cloud%ext(nx, ny, nz), cloud%reff(nx, ny, nz), source=0.0_wp, stat=ios)
        ncol = 2
      case default
        allocate (cloud%lwc(nx, ny, nz), cloud%reff(nx, ny, nz), source=0.0_wp, stat=ios)
        ncol = 2
      end select
      if (ios == 0) allocate (first_line(nx, ny, nz), source=0, stat=ios)
      if (ios /= 0) then
        call size_error(tf, [nx, ny, nz], ncol + 1, error)
        return
      end if
    end associate

    do
      call text_next_line(tf, found)
      if (.not. found) exit
      nf = count_fields(tf%line)
      if (nf /= 3 + ncol) then
        call set_error(error, where_line(tf)//': holds '//str(nf)//' values; expected '// &
                       str(3 + ncol)//' ('//trim(COLUMNS(cloud%flag))//') for flag '// &
                       str(cloud%flag))
        return
      end if
      read (tf%line, *, iostat=ios) n(1:3), v(1:ncol)
      if (ios /= 0) then
        call set_error(error, where_line(tf)//': cannot read '//trim(COLUMNS(cloud%flag))// &
                       ' (indices integers) from "'//trim(tf%line)//'"')
        return
      end if
      do k = 1, 3
        if (n(k) < 1 .or. n(k) > nmax(k)) then
          call set_error(error, where_line(tf)//': i'//NAMES(k) (2:2)//' = '//str(n(k))// &
                         ' must be within [1, '//NAMES(k)//' = '//str(nmax(k))//']')
          return
        end if
      end do
      ix = n(1)
      iy = n(2)
      iz = n(3)
      if (first_line(ix, iy, iz) > 0) then
        call set_error(error, where_line(tf)//': cell '//point_name(ix, iy, iz)// &
                       ' is listed twice (first on line '//str(first_line(ix, iy, iz))//')')
        return
      end if
      first_line(ix, iy, iz) = tf%line_no
      do k = 1, ncol
        if (.not. ieee_is_finite(v(k))) then
          call set_error(error, where_line(tf)//': '//column_name(cloud%flag, k)//' = '// &
                         str(v(k))//' must be finite')
          return
        end if
      end do
      select case (cloud%flag)
      case (MYSTIC_EXT_G_SSA)
        if (v(1) < 0.0_wp) then
          call set_error(error, where_line(tf)//': ext = '//str(v(1))//' km-1 must be >= 0')
        else if (abs(v(2)) >= 1.0_wp) then
          call set_error(error, where_line(tf)//': g = '//str(v(2))//' must satisfy |g| < 1')
        else if (v(3) < 0.0_wp .or. v(3) > 1.0_wp) then
          call set_error(error, where_line(tf)//': ssa = '//str(v(3))//' must be within [0, 1]')
        end if
        if (allocated(error)) return
        cloud%ext(ix, iy, iz) = v(1)/unit_m
        cloud%g(ix, iy, iz) = v(2)
        cloud%ssa(ix, iy, iz) = v(3)
      case default
        if (v(1) < 0.0_wp) then
          call set_error(error, where_line(tf)//': '//column_name(cloud%flag, 1)//' = '// &
                         str(v(1))//' '//merge('km-1 ', 'g m-3', cloud%flag == MYSTIC_EXT_REFF)// &
                         ' must be >= 0')
        else if (v(2) < 0.0_wp .or. (v(1) > 0.0_wp .and. v(2) <= 0.0_wp)) then
          call set_error(error, where_line(tf)//': reff = '//str(v(2))// &
                         ' um must be > 0 (>= 0 where the cell is empty)')
        end if
        if (allocated(error)) return
        if (cloud%flag == MYSTIC_EXT_REFF) then
          cloud%ext(ix, iy, iz) = v(1)/unit_m
        else
          cloud%lwc(ix, iy, iz) = v(1)
        end if
        cloud%reff(ix, iy, iz) = v(2)
      end select
    end do
    cloud%listed = first_line > 0
    cloud%n_listed = count(cloud%listed)
    select case (cloud%flag)
    case (MYSTIC_EXT_G_SSA)
      cloud%missing = 'wavelength (the file holds optical properties for one, unnamed)'
    case (MYSTIC_EXT_REFF)
      cloud%missing = 'wavelength, and single-scattering albedo and phase function for r_eff '// &
                      '(a Mie table, libRadtran wc_properties)'
    case default
      cloud%missing = 'wavelength and the droplet optical properties (Mie table) for r_eff'
    end select
  end subroutine mystic_body

  pure function column_name(flag, k) result(s)
    integer, intent(in) :: flag, k
    character(len=:), allocatable :: s
    character(len=4), parameter :: C1(3) = ['ext ', 'g   ', 'ssa '], C2(2) = ['ext ', 'reff'], &
                                   C3(2) = ['lwc ', 'reff']
    select case (flag)
    case (MYSTIC_EXT_G_SSA)
      s = trim(C1(k))
    case (MYSTIC_EXT_REFF)
      s = trim(C2(k))
    case default
      s = trim(C3(k))
    end select
  end function column_name
end module kumo_mystic_file
