! SPDX-License-Identifier: BSD-3-Clause
!> Readers for the SHDOM / I3RC cloud files: the 1- and 2-parameter LWC files and the
!> tabulated-phase-function property file (".prp").
!>
!> Both formats are plain text read in free format (Evans, SHDOM documentation "Property file
!> format"; Pincus and Evans, I3RC community Monte Carlo model, Tools/PhysicalPropertiesToDomain
!> and Tools/OpticalPropertiesToDomain). Lengths in the files are in km and extinction in km-1
!> (SHDOM: "extinction in units inverse of the grid spacing units"); kumo returns metres and
!> m-1 (the optional `length_unit` argument, in metres, covers files written in other units).
!>
!> **Vertical levels.** The header lists either nz levels (SHDOM: properties given at grid
!> points z(1..nz), linearly interpolated between them) or nz+1 levels (I3RC: boundaries of nz
!> uniform cells). The reader tells them apart by the number of values on the line and says
!> which in `z_are_boundaries`. kumo layers: with boundaries, cell iz spans z(iz)..z(iz+1) and
!> holds the listed value; with grid points, layer iz spans z(iz)..z(iz+1) (nz-1 layers) and its
!> value is the mean of the two points, which keeps the optical depth of SHDOM's linear profile.
!> Horizontally, point (ix, iy) is at ((ix-1) dx, (iy-1) dy) and the domain is periodic,
!> nx dx by ny dy.
!>
!> **Omitted points.** An LWC file may leave points out: they hold no water (the I3RC converter
!> initialises its arrays to zero "in case there are missing grid points"). A property file
!> must list every point (SHDOM rejects a phase-function index outside 1..numphase, which is
!> what an unlisted point would carry). A point listed twice is an error in both.
!>
!> The small line and number readers at the end are shared with kumo_mystic_file.
module kumo_shdom_files
  use, intrinsic :: iso_fortran_env, only: iostat_end, iostat_eor
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_constants, only: PI
  use kumo_error, only: error_t, set_error, str
  use kumo_file_check, only: check_text_complete
  implicit none
  private
  public :: lwc_field_t, prp_field_t, read_lwc_file, read_prp_file
  public :: reff_from_droplet_number, set_reff_from_droplet_number
  ! shared with kumo_mystic_file
  public :: text_file_t, text_open, text_close, text_next_line, text_next_token, count_fields
  public :: read_line_reals, where_line, point_name, first_unlisted, size_error

  real(wp), parameter :: KM = 1000.0_wp  !! default length unit of the files [m]

  !> Liquid water field of an SHDOM/I3RC 1- or 2-parameter LWC file.
  type :: lwc_field_t
    integer :: n_params = 0              !! 1 (LWC only) or 2 (LWC and r_eff)
    integer :: nx = 0, ny = 0, nz = 0    !! grid sizes (points or cells, see z_are_boundaries)
    logical :: z_are_boundaries = .true. !! nz+1 cell boundaries (I3RC) or nz grid points (SHDOM)
    real(wp) :: dx = 0.0_wp              !! grid spacing in x [m]
    real(wp) :: dy = 0.0_wp              !! grid spacing in y [m]
    real(wp), allocatable :: z(:)        !! heights as given, increasing [m]
    real(wp), allocatable :: temperature(:) !! temperature at each z [K]
    real(wp), allocatable :: lwc(:, :, :)   !! liquid water content (nx, ny, nz) [g m-3]
    real(wp), allocatable :: reff(:, :, :)  !! effective radius (nx, ny, nz) [um]; 0 where no water
    !! and everywhere in a 1-parameter file until set_reff_from_droplet_number
    logical, allocatable :: listed(:, :, :) !! point listed in the file (others hold no water)
    integer :: n_listed = 0              !! number of listed points
    !> What the file does not say and the caller must supply (from the namelist).
    character(len=:), allocatable :: missing
  end type lwc_field_t

  !> Optical properties of an SHDOM tabulated-phase-function property file.
  type :: prp_field_t
    integer :: nx = 0, ny = 0, nz = 0    !! grid sizes
    logical :: z_are_boundaries = .true. !! nz+1 cell boundaries (I3RC) or nz grid points (SHDOM)
    real(wp) :: dx = 0.0_wp              !! grid spacing in x [m]
    real(wp) :: dy = 0.0_wp              !! grid spacing in y [m]
    real(wp), allocatable :: z(:)        !! heights as given, increasing [m]
    real(wp), allocatable :: temperature(:, :, :) !! (nx, ny, nz) [K]
    real(wp), allocatable :: extinction(:, :, :)  !! (nx, ny, nz) [m-1]
    real(wp), allocatable :: ssa(:, :, :)         !! single-scattering albedo (nx, ny, nz)
    integer, allocatable :: iphase(:, :, :)       !! phase-function index, 1..nphase
    integer :: nphase = 0                !! number of tabulated phase functions
    integer :: nleg_max = 0              !! largest Legendre degree of the table
    integer, allocatable :: nleg(:)      !! Legendre degree of each phase function
    !> Normalised Legendre moments chi(l, iphase), l = 0..nleg_max: P(mu) = sum (2l+1) chi_l
    !> P_l(mu), chi_0 = 1, chi_1 = g; zero beyond nleg(iphase).
    real(wp), allocatable :: chi(:, :)
    !> What the file does not say and the caller must supply (from the namelist).
    character(len=:), allocatable :: missing
  end type prp_field_t

  !> A text file read line by line, with the line number for messages.
  type :: text_file_t
    integer :: unit = 0                        !! Fortran unit (from newunit=, negative)
    logical :: is_open = .false.               !! the unit is open
    character(len=:), allocatable :: path      !! file name for messages
    integer :: line_no = 0                     !! number of the current line (1-based)
    character(len=:), allocatable :: line      !! current line
    integer :: pos = 1                         !! next unread character of `line`
  end type text_file_t

contains

  ! ------------------------------------------------------------------------------------------
  ! LWC files
  ! ------------------------------------------------------------------------------------------

  !> Read a 1- or 2-parameter LWC file:
  !>
  !>     1 or 2                 [format type; 3 (multi-component) is not read]
  !>     nx ny nz
  !>     dx dy                  [km]
  !>     z(1) ... z(nz or nz+1) [km, increasing]
  !>     T(1) ... T(nz or nz+1) [K, one per height]
  !>     ix iy iz lwc [reff]    [g m-3, um; one point per line]
  !>
  !> Omitted points hold no water. A 1-parameter file leaves `reff` at zero and names the
  !> droplet number concentration in `missing`; see set_reff_from_droplet_number.
  subroutine read_lwc_file(path, field, error, length_unit)
    character(len=*), intent(in) :: path                !! file name
    type(lwc_field_t), intent(out) :: field             !! the field read
    type(error_t), allocatable, intent(out) :: error    !! unallocated on success
    real(wp), intent(in), optional :: length_unit       !! file length unit [m] (default 1000)
    type(text_file_t) :: tf
    real(wp) :: unit_m

    unit_m = KM
    if (present(length_unit)) unit_m = length_unit
    call text_open(path, tf, error)
    if (allocated(error)) return
    call lwc_body(tf, unit_m, field, error)
    call text_close(tf)
  end subroutine read_lwc_file

  subroutine lwc_body(tf, unit_m, field, error)
    type(text_file_t), intent(inout) :: tf
    real(wp), intent(in) :: unit_m
    type(lwc_field_t), intent(inout) :: field
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: vals(2)
    real(wp), allocatable :: zt(:)
    integer :: nfields, ndata, ix, iy, iz, ios, n(3)
    integer, allocatable :: first_line(:, :, :)
    logical :: found
    character(len=:), allocatable :: tok
    character(len=*), parameter :: WHO = 'LWC file'

    ! line 1: format type, then optional text ("2  parameter LWC file")
    call text_next_line(tf, found)
    if (.not. found) then
      call set_error(error, tf%path//': empty file')
      return
    end if
    call text_next_token(tf, tok, found, same_line=.true.)
    read (tok, *, iostat=ios) n(1)
    if (ios /= 0) then
      call set_error(error, where_line(tf)//': "'//tok//'" is not the format type (1 or 2) '// &
                     'of an LWC file')
      return
    end if
    if (n(1) /= 1 .and. n(1) /= 2) then
      call set_error(error, where_line(tf)//': format type = '//str(n(1))// &
                     ' must be 1 (LWC) or 2 (LWC and r_eff); kumo does not read other '// &
                     'particle files')
      return
    end if
    field%n_params = n(1)
    ! line 2: sizes
    call header_ints(tf, 3, n, 'nx ny nz', WHO, error)
    if (allocated(error)) return
    call check_sizes(tf, n, error)
    if (allocated(error)) return
    field%nx = n(1)
    field%ny = n(2)
    field%nz = n(3)
    ! line 3: dx dy
    call text_next_line(tf, found)
    if (.not. found) then
      call ended_in(tf, 'header', error)
      return
    end if
    call read_line_reals(tf, 2, vals, 'dx dy', error)
    if (allocated(error)) return
    call check_spacing(tf, vals, error)
    if (allocated(error)) return
    field%dx = vals(1)*unit_m
    field%dy = vals(2)*unit_m
    ! line 4: heights, nz (grid points) or nz+1 (cell boundaries)
    call text_next_line(tf, found)
    if (.not. found) then
      call ended_in(tf, 'header', error)
      return
    end if
    nfields = count_fields(tf%line)
    if (nfields == field%nz + 1) then
      field%z_are_boundaries = .true.
    else if (nfields == field%nz) then
      field%z_are_boundaries = .false.
    else
      call set_error(error, where_line(tf)//': holds '//str(nfields)//' heights; expected '// &
                     'nz+1 = '//str(field%nz + 1)//' cell boundaries or nz = '//str(field%nz)// &
                     ' grid levels')
      return
    end if
    allocate (zt(nfields), field%temperature(nfields))
    call read_line_reals(tf, nfields, zt, 'the heights z', error)
    if (allocated(error)) return
    call check_increasing(tf, zt, error)
    if (allocated(error)) return
    field%z = zt*unit_m
    ! line 5: temperatures, one per height
    call text_next_line(tf, found)
    if (.not. found) then
      call ended_in(tf, 'header', error)
      return
    end if
    call read_line_reals(tf, nfields, field%temperature, 'the temperatures (one per height)', &
                         error)
    if (allocated(error)) return
    do iz = 1, nfields
      if (.not. (field%temperature(iz) > 0.0_wp .and. field%temperature(iz) <= huge(1.0_wp))) then
        call set_error(error, where_line(tf)//': temperature '//str(iz)//' = '// &
                       str(field%temperature(iz))//' K must be > 0')
        return
      end if
    end do

    ! data lines
    ndata = 3 + field%n_params
    allocate (field%lwc(field%nx, field%ny, field%nz), field%reff(field%nx, field%ny, field%nz), &
              first_line(field%nx, field%ny, field%nz), stat=ios)
    if (ios /= 0) then
      call size_error(tf, [field%nx, field%ny, field%nz], 3, error)
      return
    end if
    field%lwc = 0.0_wp
    field%reff = 0.0_wp
    first_line = 0
    do
      call text_next_line(tf, found)
      if (.not. found) exit
      call point_indices(tf, ndata, [field%nx, field%ny, field%nz], first_line, &
                         merge('ix iy iz lwc reff', 'ix iy iz lwc     ', field%n_params == 2), &
                         ix, iy, iz, error)
      if (allocated(error)) return
      if (field%n_params == 2) then
        read (tf%line, *, iostat=ios) n, vals(1:2)
      else
        read (tf%line, *, iostat=ios) n, vals(1)
        vals(2) = 0.0_wp
      end if
      if (ios /= 0) then
        call set_error(error, where_line(tf)//': cannot read the values of point '// &
                       point_name(ix, iy, iz)//' from "'//trim(tf%line)//'"')
        return
      end if
      call check_value(tf, vals(1), 'lwc', 'g m-3', 0.0_wp, huge(1.0_wp), error)
      if (field%n_params == 2) then
        call check_value(tf, vals(2), 'reff', 'um', 0.0_wp, huge(1.0_wp), error)
        ! nested: Fortran does not short-circuit, and NaN must not reach a comparison
        if (.not. allocated(error)) then
          if (vals(1) > 0.0_wp .and. vals(2) <= 0.0_wp) then
            call set_error(error, where_line(tf)//': reff = '//str(vals(2))// &
                           ' um must be > 0 where lwc > 0')
          end if
        end if
      end if
      if (allocated(error)) return
      field%lwc(ix, iy, iz) = vals(1)
      field%reff(ix, iy, iz) = vals(2)
    end do
    field%listed = first_line > 0
    field%n_listed = count(field%listed)
    field%missing = 'wavelength and the droplet optical properties (Mie table) for r_eff: '// &
                    'an LWC file holds no optics'
    if (field%n_params == 1) field%missing = 'droplet number concentration (for r_eff), '// &
      field%missing
  end subroutine lwc_body

  !> Effective radius [um] of droplets with a gamma size distribution of shape alpha = 7,
  !> the 1-parameter LWC convention of the I3RC tools (Evans). For n(r) ~ r^alpha
  !> exp(-(alpha+3) r / reff), <r^3> = reff^3 (alpha+1)(alpha+2)(alpha+3)/(alpha+3)^3 =
  !> 0.72 reff^3, and lwc = (4/3) pi rho_w N <r^3>; with lwc in g m-3, rho_w = 1e6 g m-3 and N
  !> in cm-3: reff = 100 um * (0.75 lwc / (0.72 pi N))^(1/3). Zero where lwc = 0.
  elemental function reff_from_droplet_number(lwc, n_cm3) result(reff)
    real(wp), intent(in) :: lwc     !! liquid water content [g m-3], >= 0
    real(wp), intent(in) :: n_cm3   !! droplet number concentration [cm-3], > 0
    real(wp) :: reff                !! effective radius [um]
    if (lwc <= 0.0_wp) then
      reff = 0.0_wp
    else
      reff = 100.0_wp*(0.75_wp*lwc/(0.72_wp*PI*n_cm3))**(1.0_wp/3.0_wp)
    end if
  end function reff_from_droplet_number

  !> Fill `reff` of a 1-parameter LWC field from the droplet number concentration (from the
  !> namelist) and remove it from `missing`.
  subroutine set_reff_from_droplet_number(field, n_cm3, error)
    type(lwc_field_t), intent(inout) :: field         !! a field read by read_lwc_file
    real(wp), intent(in) :: n_cm3                     !! droplet number concentration [cm-3]
    type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    if (field%n_params /= 1) then
      call set_error(error, 'set_reff_from_droplet_number: the field has its own r_eff '// &
                     '(2-parameter file); a droplet number is not used')
      return
    end if
    if (.not. ieee_is_finite(n_cm3)) then
      call set_error(error, 'set_reff_from_droplet_number: droplet number = '//str(n_cm3)// &
                     ' cm-3 must be finite')
      return
    end if
    if (n_cm3 <= 0.0_wp) then
      call set_error(error, 'set_reff_from_droplet_number: droplet number = '//str(n_cm3)// &
                     ' cm-3 must be > 0')
      return
    end if
    field%reff = reff_from_droplet_number(field%lwc, n_cm3)
    field%missing = 'wavelength and the droplet optical properties (Mie table) for r_eff: '// &
                    'an LWC file holds no optics'
  end subroutine set_reff_from_droplet_number

  ! ------------------------------------------------------------------------------------------
  ! Tabulated-phase-function property file
  ! ------------------------------------------------------------------------------------------

  !> Read an SHDOM tabulated-phase-function property file:
  !>
  !>     T...                         [first line begins with 'T']
  !>     nx ny nz
  !>     dx dy z(1) ... z(nz or nz+1) [km; on one line]
  !>     numphase
  !>     nleg  a_1 ... a_nleg         [per phase function; may run over several lines]
  !>     ix iy iz temp ext ssa iphase [K, km-1; one point per line, every point once]
  !>
  !> The file lists a_l = (2l+1) chi_l, so a_1 = 3g, with a_0 = 1 left out (SHDOM: "Chi1 is 3
  !> times the asymmetry parameter", "Chi0 (which is not listed) is always 1"); kumo stores
  !> chi_l = a_l/(2l+1). Every |chi_l| must be <= 1, as for any non-negative phase function.
  subroutine read_prp_file(path, prp, error, length_unit, grid_only)
    character(len=*), intent(in) :: path                !! file name
    type(prp_field_t), intent(out) :: prp               !! the field read
    type(error_t), allocatable, intent(out) :: error    !! unallocated on success
    real(wp), intent(in), optional :: length_unit       !! file length unit [m] (default 1000)
    !> read the grid only (nx, ny, nz, dx, dy, z): the header, not the points
    logical, intent(in), optional :: grid_only
    type(text_file_t) :: tf
    real(wp) :: unit_m
    logical :: grid

    unit_m = KM
    if (present(length_unit)) unit_m = length_unit
    grid = .false.
    if (present(grid_only)) grid = grid_only
    call text_open(path, tf, error)
    if (allocated(error)) return
    call prp_body(tf, unit_m, grid, prp, error)
    call text_close(tf)
  end subroutine read_prp_file

  subroutine prp_body(tf, unit_m, grid, prp, error)
    type(text_file_t), intent(inout) :: tf
    real(wp), intent(in) :: unit_m
    logical, intent(in) :: grid   !! stop after the grid
    type(prp_field_t), intent(inout) :: prp
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: v(3), a
    real(wp), allocatable :: head(:)
    integer :: n(3), nfields, ip, l, nl, ix, iy, iz, ios, iph
    integer, allocatable :: first_line(:, :, :)
    logical :: found
    type :: leg_t
      real(wp), allocatable :: a(:)
    end type leg_t
    type(leg_t), allocatable :: table(:)
    character(len=:), allocatable :: tok
    character(len=*), parameter :: WHO = 'property file'

    call text_next_line(tf, found)
    if (.not. found) then
      call set_error(error, tf%path//': empty file')
      return
    end if
    if (tf%line(1:1) /= 'T' .and. tf%line(1:1) /= 't') then
      call set_error(error, where_line(tf)//': "'//trim(tf%line)//'" does not begin with '// &
                     '''T''; kumo reads only the tabulated-phase-function property format')
      return
    end if
    call header_ints(tf, 3, n, 'nx ny nz', WHO, error)
    if (allocated(error)) return
    call check_sizes(tf, n, error)
    if (allocated(error)) return
    prp%nx = n(1)
    prp%ny = n(2)
    prp%nz = n(3)
    call text_next_line(tf, found)
    if (.not. found) then
      call ended_in(tf, 'header', error)
      return
    end if
    nfields = count_fields(tf%line)
    if (nfields == prp%nz + 3) then
      prp%z_are_boundaries = .true.
    else if (nfields == prp%nz + 2) then
      prp%z_are_boundaries = .false.
    else
      call set_error(error, where_line(tf)//': holds '//str(nfields)//' values; expected dx dy '// &
                     'and nz+1 = '//str(prp%nz + 1)//' cell boundaries or nz = '//str(prp%nz)// &
                     ' grid levels (all on this line)')
      return
    end if
    allocate (head(nfields))
    call read_line_reals(tf, nfields, head, 'dx dy z(1) ...', error)
    if (allocated(error)) return
    call check_spacing(tf, head(1:2), error)
    if (allocated(error)) return
    call check_increasing(tf, head(3:), error)
    if (allocated(error)) return
    prp%dx = head(1)*unit_m
    prp%dy = head(2)*unit_m
    prp%z = head(3:)*unit_m
    if (grid) return
    call header_ints(tf, 1, n(1:1), 'numphase', WHO, error)
    if (allocated(error)) return
    if (n(1) < 1) then
      call set_error(error, where_line(tf)//': numphase = '//str(n(1))//' must be >= 1')
      return
    end if
    prp%nphase = n(1)

    ! phase-function table: free format, may run over lines
    allocate (table(prp%nphase), prp%nleg(prp%nphase))
    call text_next_line(tf, found)
    if (.not. found) then
      call ended_in(tf, 'phase-function table', error)
      return
    end if
    do ip = 1, prp%nphase
      call text_next_token(tf, tok, found)
      if (.not. found) then
      call ended_in(tf, 'phase-function table', error)
      return
    end if
      read (tok, *, iostat=ios) nl
      if (ios /= 0) then
        call set_error(error, where_line(tf)//': "'//tok//'" is not the Legendre degree '// &
                       '(an integer) of phase function '//str(ip))
        return
      end if
      if (nl < 0) then
        call set_error(error, where_line(tf)//': Legendre degree of phase function '//str(ip)// &
                       ' = '//str(nl)//' must be >= 0')
        return
      end if
      prp%nleg(ip) = nl
      allocate (table(ip)%a(nl))
      do l = 1, nl
        call text_next_token(tf, tok, found)
        if (.not. found) then
      call ended_in(tf, 'phase-function table', error)
      return
    end if
        read (tok, *, iostat=ios) a
        if (ios /= 0) then
          call set_error(error, where_line(tf)//': "'//tok//'" is not a number (coefficient '// &
                         str(l)//' of phase function '//str(ip)//')')
          return
        end if
        if (.not. ieee_is_finite(a)) then
          call set_error(error, where_line(tf)//': coefficient '//str(l)//' of phase function '// &
                         str(ip)//' = '//str(a)//' must be finite')
          return
        end if
        ! 1e-5 covers the 5-decimal rounding of the file at chi_l = 1
        if (abs(a) > real(2*l + 1, wp)*(1.0_wp + 1.0e-5_wp)) then
          call set_error(error, where_line(tf)//': coefficient '//str(l)//' of phase function '// &
                         str(ip)//' = '//str(a)//' gives |chi_'//str(l)//'| = '// &
                         str(abs(a)/real(2*l + 1, wp))//' > 1 (the file lists (2l+1) chi_l)')
          return
        end if
        table(ip)%a(l) = a
      end do
    end do
    call text_next_token(tf, tok, found, same_line=.true.)
    if (found) then
      call set_error(error, where_line(tf)//': unexpected "'//tok//'" after the '// &
                     str(prp%nphase)//' phase functions (numphase too small?)')
      return
    end if
    prp%nleg_max = maxval(prp%nleg)
    allocate (prp%chi(0:prp%nleg_max, prp%nphase), source=0.0_wp)
    do ip = 1, prp%nphase
      prp%chi(0, ip) = 1.0_wp
      do l = 1, prp%nleg(ip)
        prp%chi(l, ip) = table(ip)%a(l)/real(2*l + 1, wp)
      end do
    end do

    ! grid points
    allocate (prp%temperature(prp%nx, prp%ny, prp%nz), prp%extinction(prp%nx, prp%ny, prp%nz), &
              prp%ssa(prp%nx, prp%ny, prp%nz), prp%iphase(prp%nx, prp%ny, prp%nz), &
              first_line(prp%nx, prp%ny, prp%nz), stat=ios)
    if (ios /= 0) then
      call size_error(tf, [prp%nx, prp%ny, prp%nz], 5, error)
      return
    end if
    prp%temperature = 0.0_wp
    prp%extinction = 0.0_wp
    prp%ssa = 0.0_wp
    prp%iphase = 0
    first_line = 0
    do
      call text_next_line(tf, found)
      if (.not. found) exit
      call point_indices(tf, 7, [prp%nx, prp%ny, prp%nz], first_line, &
                         'ix iy iz temp ext ssa iphase', ix, iy, iz, error)
      if (allocated(error)) return
      read (tf%line, *, iostat=ios) n, v, iph
      if (ios /= 0) then
        call set_error(error, where_line(tf)//': cannot read temp ext ssa iphase (iphase an '// &
                       'integer) of point '//point_name(ix, iy, iz)//' from "'//trim(tf%line)//'"')
        return
      end if
      call check_value(tf, v(1), 'temp', 'K', tiny(1.0_wp), huge(1.0_wp), error)
      call check_value(tf, v(2), 'ext', 'km-1', 0.0_wp, huge(1.0_wp), error)
      call check_value(tf, v(3), 'ssa', '', 0.0_wp, 1.0_wp, error)
      if (allocated(error)) return
      if (iph < 1 .or. iph > prp%nphase) then
        call set_error(error, where_line(tf)//': iphase = '//str(iph)//' must be within [1, '// &
                       'numphase = '//str(prp%nphase)//']')
        return
      end if
      prp%temperature(ix, iy, iz) = v(1)
      prp%extinction(ix, iy, iz) = v(2)/unit_m
      prp%ssa(ix, iy, iz) = v(3)
      prp%iphase(ix, iy, iz) = iph
    end do
    if (any(first_line == 0)) then
      call set_error(error, tf%path//': lists '//str(count(first_line > 0))//' of nx*ny*nz = '// &
                     str(size(first_line))//' points; the first missing is '// &
                     first_unlisted(first_line)//' (a property file must list every point)')
      return
    end if
    prp%missing = 'wavelength: a property file does not record it (needed only for '// &
                  'wavelength-dependent inputs such as Rayleigh scattering or surfaces)'
  end subroutine prp_body

  ! ------------------------------------------------------------------------------------------
  ! Checks shared by the readers
  ! ------------------------------------------------------------------------------------------

  !> Memory for the grid of the header's sizes could not be had: name the file and the sizes.
  subroutine size_error(tf, n, n_arrays, error)
    type(text_file_t), intent(in) :: tf
    integer, intent(in) :: n(3)          !! nx, ny, nz from the header
    integer, intent(in) :: n_arrays      !! arrays of that size the reader needs
    type(error_t), allocatable, intent(out) :: error
    call set_error(error, tf%path//': cannot allocate '//str(n_arrays)//' arrays of nx*ny*nz '// &
                   '= '//str(n(1))//' x '//str(n(2))//' x '//str(n(3))//' = '// &
                   str(product(int(n, kind(1_8))))//' points (header sizes; too large for '// &
                   'the memory: a wrong header?)')
  end subroutine size_error

  !> The file ended inside `part` (truncated file).
  subroutine ended_in(tf, part, error)
    type(text_file_t), intent(in) :: tf
    character(len=*), intent(in) :: part
    type(error_t), allocatable, intent(out) :: error
    call set_error(error, tf%path//': ends after line '//str(tf%line_no)//' inside the '//part// &
                   ' (truncated file?)')
  end subroutine ended_in

  subroutine header_ints(tf, nexp, n, what, who, error)
    type(text_file_t), intent(inout) :: tf
    integer, intent(in) :: nexp
    integer, intent(out) :: n(nexp)
    character(len=*), intent(in) :: what, who
    type(error_t), allocatable, intent(out) :: error
    integer :: nf, ios
    logical :: found
    n = 0
    call text_next_line(tf, found)
    if (.not. found) then
      call set_error(error, tf%path//': ends after line '//str(tf%line_no)//' inside the '// &
                     who//' header (expected '//what//'; truncated file?)')
      return
    end if
    nf = count_fields(tf%line)
    if (nf /= nexp) then
      call set_error(error, where_line(tf)//': holds '//str(nf)//' values; expected '//what)
      return
    end if
    read (tf%line, *, iostat=ios) n
    if (ios /= 0) then
      call set_error(error, where_line(tf)//': cannot read '//what//' (integers) from "'// &
                     trim(tf%line)//'"')
    end if
  end subroutine header_ints

  subroutine check_sizes(tf, n, error)
    type(text_file_t), intent(in) :: tf
    integer, intent(in) :: n(3)
    type(error_t), allocatable, intent(out) :: error
    character(len=2), parameter :: NAMES(3) = ['nx', 'ny', 'nz']
    integer :: i
    do i = 1, 3
      if (n(i) < 1) then
        call set_error(error, where_line(tf)//': '//NAMES(i)//' = '//str(n(i))//' must be >= 1')
        return
      end if
    end do
  end subroutine check_sizes

  subroutine check_spacing(tf, d, error)
    type(text_file_t), intent(in) :: tf
    real(wp), intent(in) :: d(2)
    type(error_t), allocatable, intent(out) :: error
    character(len=2), parameter :: NAMES(2) = ['dx', 'dy']
    integer :: i
    do i = 1, 2
      if (.not. ieee_is_finite(d(i))) then
        call set_error(error, where_line(tf)//': '//NAMES(i)//' = '//str(d(i))//' must be finite')
        return
      end if
      if (d(i) <= 0.0_wp) then
        call set_error(error, where_line(tf)//': '//NAMES(i)//' = '//str(d(i))//' must be > 0')
        return
      end if
    end do
  end subroutine check_spacing

  subroutine check_increasing(tf, z, error)
    type(text_file_t), intent(in) :: tf
    real(wp), intent(in) :: z(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: k
    do k = 1, size(z)
      if (.not. ieee_is_finite(z(k))) then
        call set_error(error, where_line(tf)//': z('//str(k)//') = '//str(z(k))//' must be finite')
        return
      end if
    end do
    do k = 2, size(z)
      if (z(k) <= z(k - 1)) then
        call set_error(error, where_line(tf)//': heights must increase, but z('//str(k)//') = '// &
                       str(z(k))//' <= z('//str(k - 1)//') = '//str(z(k - 1)))
        return
      end if
    end do
  end subroutine check_increasing

  !> Fail unless lo <= x <= hi and x is finite. Kept as a no-op once `error` is set.
  subroutine check_value(tf, x, name, units, lo, hi, error)
    type(text_file_t), intent(in) :: tf
    real(wp), intent(in) :: x, lo, hi
    character(len=*), intent(in) :: name, units
    type(error_t), allocatable, intent(inout) :: error
    character(len=:), allocatable :: u
    if (allocated(error)) return
    u = ''
    if (len(units) > 0) u = ' '//units
    if (.not. ieee_is_finite(x)) then
      call set_error(error, where_line(tf)//': '//name//' = '//str(x)//' must be finite')
    else if (x < lo) then
      if (lo > 0.0_wp) then
        call set_error(error, where_line(tf)//': '//name//' = '//str(x)//u//' must be > 0')
      else
        call set_error(error, where_line(tf)//': '//name//' = '//str(x)//u//' must be >= '//str(lo))
      end if
    else if (x > hi) then
      call set_error(error, where_line(tf)//': '//name//' = '//str(x)//u//' must be within ['// &
                     str(lo)//', '//str(hi)//']')
    end if
  end subroutine check_value

  !> Check the field count of a point line and read its indices; they must be in range and the
  !> point not listed before (first_line remembers where each point was listed).
  subroutine point_indices(tf, nexp, nmax, first_line, columns, ix, iy, iz, error)
    type(text_file_t), intent(in) :: tf
    integer, intent(in) :: nexp, nmax(3)
    integer, intent(inout) :: first_line(:, :, :)
    character(len=*), intent(in) :: columns
    integer, intent(out) :: ix, iy, iz
    type(error_t), allocatable, intent(out) :: error
    integer :: nf, ios, idx(3), i
    character(len=2), parameter :: NAMES(3) = ['ix', 'iy', 'iz']
    character(len=2), parameter :: SIZES(3) = ['nx', 'ny', 'nz']
    ix = 0
    iy = 0
    iz = 0
    nf = count_fields(tf%line)
    if (nf /= nexp) then
      call set_error(error, where_line(tf)//': holds '//str(nf)//' values; expected '// &
                     str(nexp)//' ('//trim(columns)//')')
      return
    end if
    read (tf%line, *, iostat=ios) idx
    if (ios /= 0) then
      call set_error(error, where_line(tf)//': cannot read the indices ix iy iz (integers) '// &
                     'from "'//trim(tf%line)//'"')
      return
    end if
    do i = 1, 3
      if (idx(i) < 1 .or. idx(i) > nmax(i)) then
        call set_error(error, where_line(tf)//': '//NAMES(i)//' = '//str(idx(i))// &
                       ' must be within [1, '//SIZES(i)//' = '//str(nmax(i))//']')
        return
      end if
    end do
    ix = idx(1)
    iy = idx(2)
    iz = idx(3)
    if (first_line(ix, iy, iz) > 0) then
      call set_error(error, where_line(tf)//': point '//point_name(ix, iy, iz)// &
                     ' is listed twice (first on line '//str(first_line(ix, iy, iz))//')')
      return
    end if
    first_line(ix, iy, iz) = tf%line_no
  end subroutine point_indices

  ! ------------------------------------------------------------------------------------------
  ! Line and number readers (also used by kumo_mystic_file)
  ! ------------------------------------------------------------------------------------------

  !> Open a text file for reading.
  subroutine text_open(path, tf, error)
    character(len=*), intent(in) :: path
    type(text_file_t), intent(out) :: tf
    type(error_t), allocatable, intent(out) :: error
    integer :: ios
    character(len=512) :: msg
    tf%path = trim(path)
    tf%line = ''
    call check_text_complete(path, error)   ! (before the open: a file is open on one unit only)
    if (allocated(error)) return
    open (newunit=tf%unit, file=path, status='old', action='read', form='formatted', &
          access='sequential', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call set_error(error, 'cannot open "'//trim(path)//'": '//trim(msg))
    else
      tf%is_open = .true.
    end if
  end subroutine text_open

  !> Close the file (no-op when closed).
  subroutine text_close(tf)
    type(text_file_t), intent(inout) :: tf
    if (tf%is_open) close (tf%unit)
    tf%is_open = .false.
  end subroutine text_close

  !> Advance to the next non-blank line; `found` is false at the end of the file.
  subroutine text_next_line(tf, found)
    type(text_file_t), intent(inout) :: tf
    logical, intent(out) :: found
    character(len=4096) :: buf
    integer :: ios, nread
    found = .false.
    do
      tf%line = ''
      do
        read (tf%unit, '(a)', advance='no', iostat=ios, size=nread) buf
        if (ios == iostat_end) return
        tf%line = tf%line//buf(1:nread)
        if (ios == iostat_eor) exit
        if (ios /= 0) return
      end do
      tf%line_no = tf%line_no + 1
      tf%pos = 1
      if (len_trim(tf%line) > 0) exit
    end do
    found = .true.
  end subroutine text_next_line

  !> Next blank- or comma-separated token, going on to the following lines if needed (or,
  !> with same_line, only from the rest of the current line).
  subroutine text_next_token(tf, tok, found, same_line)
    type(text_file_t), intent(inout) :: tf
    character(len=:), allocatable, intent(out) :: tok
    logical, intent(out) :: found
    logical, intent(in), optional :: same_line
    integer :: i0, i
    logical :: one_line
    one_line = .false.
    if (present(same_line)) one_line = same_line
    tok = ''
    found = .false.
    do
      i0 = tf%pos
      do while (i0 <= len(tf%line))
        if (.not. is_separator(tf%line(i0:i0))) exit
        i0 = i0 + 1
      end do
      if (i0 <= len(tf%line)) exit
      if (one_line) return
      call text_next_line(tf, found)
      if (.not. found) return
    end do
    i = i0
    do while (i <= len(tf%line))
      if (is_separator(tf%line(i:i))) exit
      i = i + 1
    end do
    tok = tf%line(i0:i - 1)
    tf%pos = i
    found = .true.
  end subroutine text_next_token

  !> Read exactly `n` reals from the current line (the line must hold n values).
  subroutine read_line_reals(tf, n, x, what, error)
    type(text_file_t), intent(in) :: tf
    integer, intent(in) :: n
    real(wp), intent(out) :: x(n)
    character(len=*), intent(in) :: what
    type(error_t), allocatable, intent(out) :: error
    integer :: nf, ios
    x = 0.0_wp
    nf = count_fields(tf%line)
    if (nf /= n) then
      call set_error(error, where_line(tf)//': holds '//str(nf)//' values; expected '// &
                     str(n)//' ('//what//')')
      return
    end if
    read (tf%line, *, iostat=ios) x
    if (ios /= 0) call set_error(error, where_line(tf)//': cannot read '//what//' from "'// &
                                 trim(tf%line)//'"')
  end subroutine read_line_reals

  !> Number of blank- or comma-separated fields on a line.
  pure function count_fields(line) result(n)
    character(len=*), intent(in) :: line
    integer :: n
    integer :: i
    logical :: in_field
    n = 0
    in_field = .false.
    do i = 1, len(line)
      if (is_separator(line(i:i))) then
        in_field = .false.
      else if (.not. in_field) then
        in_field = .true.
        n = n + 1
      end if
    end do
  end function count_fields

  pure logical function is_separator(c)
    character(len=1), intent(in) :: c
    is_separator = c == ' ' .or. c == ',' .or. c == achar(9) .or. c == achar(13)
  end function is_separator

  !> "<file> line <n>" for messages.
  function where_line(tf) result(s)
    type(text_file_t), intent(in) :: tf
    character(len=:), allocatable :: s
    s = tf%path//' line '//str(tf%line_no)
  end function where_line

  !> "(ix, iy, iz)" for messages.
  pure function point_name(ix, iy, iz) result(s)
    integer, intent(in) :: ix, iy, iz
    character(len=:), allocatable :: s
    s = '('//str(ix)//', '//str(iy)//', '//str(iz)//')'
  end function point_name

  !> The first point (x fastest) with first_line = 0, as "(ix, iy, iz)".
  function first_unlisted(first_line) result(s)
    integer, intent(in) :: first_line(:, :, :)
    character(len=:), allocatable :: s
    integer :: ix, iy, iz
    s = 'none'
    do iz = 1, size(first_line, 3)
      do iy = 1, size(first_line, 2)
        do ix = 1, size(first_line, 1)
          if (first_line(ix, iy, iz) == 0) then
            s = point_name(ix, iy, iz)
            return
          end if
        end do
      end do
    end do
  end function first_unlisted
end module kumo_shdom_files
