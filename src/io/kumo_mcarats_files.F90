! SPDX-License-Identifier: BSD-3-Clause
!> Readers for the MCARaTS binary inputs: the 3-D atmosphere (`Atm_inpfile`), the tabulated
!> phase functions (`Sca_inpfile`) and the surface (`Sfc_inpfile`), with their GrADS `.ctl`
!> descriptors.
!>
!> All three are raw float32 records of one 2-D field each, no header, native byte order
!> unless the `.ctl` or the caller says otherwise (MCARaTS 0.10: Fortran direct access,
!> `Wld_mbswap=1` swaps bytes). Sizes are not in the binary file: they come from the `.ctl`
!> (XDEF, YDEF and the level counts of VARS) or from the caller (the MCARaTS namelist values).
!> The file must hold exactly the records those sizes imply: a shorter file is truncated, a
!> longer one has trailing data, and both are errors.
!>
!> Record layout of one atmosphere dataset (Iwabuchi, MCARaTS 0.10 `mcarAtm`):
!> tmpa3d (nz3 + mtprof records, temperature perturbations [K]), absg3d (nkd x nz3, gas
!> absorption perturbations [m-1], k outer), then per 3-D component extp3d [m-1], omgp3d and
!> apfp3d (nz3 records each). A field is stored x fastest, then y.
!>
!> For a run (`&kumo_cloud cloud_format = 'mcarats'`, `&kumo_surface surface_format =
!> 'mcarats'`), `mcarats_request_t` carries what kumo's namelist supplies in place of
!> MCARaTS's own, and `mcarats_surface_brdf` turns a surface file into kumo's BRDF map.
module kumo_mcarats_files
  use, intrinsic :: iso_fortran_env, only: int8, int32, int64, real32
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str, to_lower
  use kumo_textio, only: read_line
  use kumo_brdf, only: brdf_params_t, brdf_params, BRDF_BLACK, BRDF_LAMBERT, BRDF_DSM, BRDF_RPV, &
                       BRDF_LSRT
  implicit none
  private
  public :: grads_ctl_t, grads_var_t, read_grads_ctl
  public :: mcarats_atm_t, read_mcarats_atm, read_mcarats_atm_ctl
  public :: mcarats_phase_t, read_mcarats_phase, read_mcarats_phase_ctl
  public :: mcarats_surface_t, read_mcarats_surface
  public :: mcarats_request_t, mcarats_atm_ctl_sizes, mcarats_phase_ctl_sizes, is_ctl_path
  public :: mcarats_surface_npsfc, mcarats_surface_brdf
  public :: BYTE_ORDER_NATIVE, BYTE_ORDER_LITTLE, BYTE_ORDER_BIG

  integer, parameter :: BYTE_ORDER_NATIVE = 0  !! as written on this machine (MCARaTS default)
  integer, parameter :: BYTE_ORDER_LITTLE = 1  !! little-endian
  integer, parameter :: BYTE_ORDER_BIG = 2     !! big-endian

  !> Number of BRDF parameters per MCARaTS surface type 0..4 (black, Lambert, DSM, RPV, LSRT).
  integer, parameter :: SFC_NPAR(0:4) = [0, 1, 5, 4, 3]
  character(len=7), parameter :: SFC_NAMES(0:4) = ['black  ', 'Lambert', 'DSM    ', 'RPV    ', &
                                                   'LSRT   ']

  !> One variable of a GrADS descriptor.
  type :: grads_var_t
    character(len=:), allocatable :: name   !! variable name
    integer :: nlev = 0                     !! number of levels (records per dataset)
  end type grads_var_t

  !> The parts of a GrADS `.ctl` descriptor kumo uses.
  type :: grads_ctl_t
    character(len=:), allocatable :: dset   !! data file, '^' resolved against the .ctl folder
    integer :: nx = 0, ny = 0, nz = 0, nt = 0  !! XDEF, YDEF, ZDEF, TDEF sizes
    integer :: byte_order = BYTE_ORDER_NATIVE  !! from OPTIONS (LITTLE_/BIG_ENDIAN, BYTESWAPPED)
    type(grads_var_t), allocatable :: vars(:)  !! VARS block, in file order
  end type grads_ctl_t

  !> One dataset of an MCARaTS 3-D atmosphere file, SI units, arrays (nx, ny, ...).
  type :: mcarats_atm_t
    integer :: nx = 0, ny = 0        !! horizontal cells
    integer :: nz3 = 0               !! 3-D layers
    integer :: mtprof = 0            !! 0: temperatures per layer, 1: per level (nz3+1)
    integer :: nkd = 0               !! correlated-k terms
    integer :: np3d = 0              !! 3-D scattering components
    integer :: idread = 0            !! dataset read (1-based)
    integer :: ndatasets = 0         !! datasets in the file
    real(wp), allocatable :: tmpa(:, :, :)     !! temperature perturbation (nx,ny,nz3+mtprof) [K]
    real(wp), allocatable :: absg(:, :, :, :)  !! gas absorption perturbation (nx,ny,nz3,nkd) [m-1]
    real(wp), allocatable :: ext(:, :, :, :)   !! extinction (nx,ny,nz3,np3d) [m-1]
    real(wp), allocatable :: omg(:, :, :, :)   !! single-scattering albedo (nx,ny,nz3,np3d)
    !> phase-function code (nx,ny,nz3,np3d): (-3,-2] isotropic, (-2,-1] Rayleigh, (-1,1) HG g,
    !> >= 1 tabulated index (fraction = blend with the next table)
    real(wp), allocatable :: apf(:, :, :, :)
    !> What the file does not say and the caller must supply (from the namelist).
    character(len=:), allocatable :: missing
  end type mcarats_atm_t

  !> Tabulated phase functions of an MCARaTS `.sca` file.
  type :: mcarats_phase_t
    integer :: nang = 0                  !! angles per table
    integer :: npf = 0                   !! number of tables
    logical :: reversed = .false.        !! the file listed the angles in decreasing order
    real(wp), allocatable :: angle_deg(:)   !! scattering angles, increasing, 0 to 180 [deg]
    real(wp), allocatable :: p_file(:, :)   !! P(angle, ipf) as in the file (any normalisation)
    !> P normalised so that 1/2 int P sin(theta) dtheta = 1 (trapezoidal rule in cos(theta) on
    !> the file's angles)
    real(wp), allocatable :: p(:, :)
  end type mcarats_phase_t

  !> What kumo's namelist supplies to read an MCARaTS atmosphere and its phase functions for a
  !> run: the sizes MCARaTS takes from its own namelist (`Atm_np3d`, ..., `Sca_npf`) and the
  !> grid of the 3-D region, which the binary file does not hold. A size of -1 is "not given"
  !> (taken from the `.ctl`); nx, ny, nz3 = 0 are "not known yet".
  type :: mcarats_request_t
    integer :: nx = 0, ny = 0, nz3 = 0  !! voxels of the region (&kumo_atmosphere nx, ny, nz3)
    integer :: np3d = -1                !! 3-D components (Atm_np3d)
    integer :: nkd = -1                 !! correlated-k terms (Atm_nkd)
    integer :: mtprof = -1              !! 0: temperatures per layer, 1: per level (Atm_mtprof)
    integer :: idread = 1               !! dataset read (Atm_idread)
    integer :: ikd = 1                  !! k-term whose absorption perturbation is used
    character(len=:), allocatable :: phase_path  !! phase-function file (.ctl or binary), or ''
    integer :: nang = -1, npf = -1      !! binary phase file: angles, tables (Sca_nangi, Sca_npf)
    real(wp) :: dx = 0.0_wp, dy = 0.0_wp  !! column widths [m] (lx/nx, ly/ny)
    integer :: k3d_bottom = 0           !! kumo layer of the region's first layer (Atm_iz3l)
    real(wp), allocatable :: z(:)       !! layer edges of the region, z(0:nz3) [m]
    !> absorption coefficient of the 1-D components in the region's layers (nz3) [m-1]: the
    !> 1-D gas absorption the perturbation absg3d is added to (MCARaTS Atm_abs1d)
    real(wp), allocatable :: abs1d(:)
  end type mcarats_request_t

  !> One dataset of an MCARaTS surface file, arrays (nxb, nyb[, npsfc]).
  type :: mcarats_surface_t
    integer :: nxb = 0, nyb = 0          !! surface pixels
    integer :: npsfc = 0                 !! parameter fields per dataset
    integer :: idread = 0                !! dataset read (1-based)
    integer :: ndatasets = 0             !! datasets in the file
    real(wp), allocatable :: temperature(:, :)  !! [K]
    integer, allocatable :: brdf_type(:, :)     !! 0 black, 1 Lambert, 2 DSM, 3 RPV, 4 LSRT
    real(wp), allocatable :: params(:, :, :)    !! BRDF parameters in MCARaTS order
    !> What the file does not say and the caller must supply (from the namelist).
    character(len=:), allocatable :: missing
  end type mcarats_surface_t

contains

  ! ------------------------------------------------------------------------------------------
  ! GrADS descriptor
  ! ------------------------------------------------------------------------------------------

  !> Read a GrADS `.ctl` descriptor: DSET, OPTIONS, XDEF, YDEF, ZDEF, TDEF and the VARS block.
  !> Lines starting with '*' are comments (so '*OPTIONS BIG_ENDIAN' is not an option).
  subroutine read_grads_ctl(path, ctl, error)
    character(len=*), intent(in) :: path              !! descriptor file
    type(grads_ctl_t), intent(out) :: ctl             !! the descriptor read
    type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    integer :: unit, ios, line_no, nvars, iv, k
    character(len=1024) :: line, key, word
    character(len=:), allocatable :: full
    character(len=512) :: msg
    type(grads_var_t), allocatable :: vars(:)
    logical :: in_vars

    open (newunit=unit, file=path, status='old', action='read', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call set_error(error, 'cannot open "'//trim(path)//'": '//trim(msg))
      return
    end if
    line_no = 0
    nvars = -1
    iv = 0
    in_vars = .false.
    allocate (vars(0))
    do
      call read_line(unit, full, ios)
      if (ios /= 0) exit
      line_no = line_no + 1
      if (len_trim(full) > len(line)) then
        call set_error(error, trim(path)//': line '//str(line_no)//' has '// &
                       str(len_trim(full))//' characters; a descriptor line may have at most '// &
                       str(len(line)))
        close (unit)
        return
      end if
      line = adjustl(full)
      if (len_trim(line) == 0 .or. line(1:1) == '*') cycle
      read (line, *, iostat=ios) key
      if (ios /= 0) then
        call fail('cannot read a keyword from "'//trim(line)//'"')
        return
      end if
      key = to_lower(key)
      if (in_vars) then
        if (key == 'endvars') then
          in_vars = .false.
          cycle
        end if
        iv = iv + 1
        vars = [vars, grads_var_t()]
        vars(iv)%name = trim(key)
        read (line, *, iostat=ios) word, vars(iv)%nlev
        if (ios /= 0 .or. vars(iv)%nlev < 1) then
          call fail('variable line "'//trim(line)//'" needs a name and a level count >= 1')
          return
        end if
        cycle
      end if
      select case (key)
      case ('dset')
        read (line, *, iostat=ios) word, word
        if (ios /= 0) then
          call fail('DSET needs a file name')
          return
        end if
        word = adjustl(word)
        if (word(1:1) == '^') then
          k = index(path, '/', back=.true.)
          ctl%dset = path(1:k)//trim(word(2:))
        else
          ctl%dset = trim(word)
        end if
      case ('options')
        if (index(to_lower(line), 'big_endian') > 0) ctl%byte_order = BYTE_ORDER_BIG
        if (index(to_lower(line), 'little_endian') > 0) ctl%byte_order = BYTE_ORDER_LITTLE
        if (index(to_lower(line), 'byteswapped') > 0) then
          ctl%byte_order = merge(BYTE_ORDER_BIG, BYTE_ORDER_LITTLE, native_is_little())
        end if
      case ('xdef', 'ydef', 'zdef', 'tdef')
        read (line, *, iostat=ios) word, k
        if (ios /= 0 .or. k < 1) then
          call fail(trim(key)//' needs a size >= 1: "'//trim(line)//'"')
          return
        end if
        select case (key)
        case ('xdef')
          ctl%nx = k
        case ('ydef')
          ctl%ny = k
        case ('zdef')
          ctl%nz = k
        case default
          ctl%nt = k
        end select
      case ('vars')
        read (line, *, iostat=ios) word, nvars
        if (ios /= 0 .or. nvars < 1) then
          call fail('VARS needs a count >= 1: "'//trim(line)//'"')
          return
        end if
        in_vars = .true.
      case default
        ! TITLE, UNDEF and other keywords are not needed by kumo
      end select
    end do
    close (unit)
    if (.not. allocated(ctl%dset)) then
      call set_error(error, trim(path)//': no DSET line')
    else if (ctl%nx < 1 .or. ctl%ny < 1 .or. ctl%nt < 1) then
      call set_error(error, trim(path)//': XDEF, YDEF and TDEF are required')
    else if (nvars < 0) then
      call set_error(error, trim(path)//': no VARS block')
    else if (in_vars) then
      call set_error(error, trim(path)//': VARS block has no ENDVARS (truncated file?)')
    else if (iv /= nvars) then
      call set_error(error, trim(path)//': VARS says '//str(nvars)//' variables but '// &
                     str(iv)//' are listed')
    end if
    ctl%vars = vars

  contains
    subroutine fail(what)
      character(len=*), intent(in) :: what
      call set_error(error, trim(path)//' line '//str(line_no)//': '//what)
      close (unit)
    end subroutine fail
  end subroutine read_grads_ctl

  ! ------------------------------------------------------------------------------------------
  ! 3-D atmosphere
  ! ------------------------------------------------------------------------------------------

  !> Read dataset `idread` of an MCARaTS 3-D atmosphere file with sizes as in the MCARaTS
  !> namelist (Atm_nx, Atm_ny, Atm_nz3, Atm_mtprof, Atm_nkd, Atm_np3d). With `npf`, tabulated
  !> apf codes must not exceed it.
  subroutine read_mcarats_atm(path, nx, ny, nz3, mtprof, nkd, np3d, atm, error, idread, &
                              byte_order, npf)
    character(len=*), intent(in) :: path              !! binary file
    integer, intent(in) :: nx, ny, nz3                !! field size and number of 3-D layers
    integer, intent(in) :: mtprof                     !! 0 (per layer) or 1 (per level)
    integer, intent(in) :: nkd, np3d                  !! k-terms, 3-D components
    type(mcarats_atm_t), intent(out) :: atm           !! the dataset read
    type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    integer, intent(in), optional :: idread           !! dataset, 1-based (default 1)
    integer, intent(in), optional :: byte_order       !! BYTE_ORDER_* (default native)
    integer, intent(in), optional :: npf              !! number of tabulated phase functions
    integer :: nrec, ntmp, irec0, k, ip, ikd, bo, ids
    real(wp), allocatable :: f(:, :)
    character(len=40), allocatable :: names(:)

    ids = 1
    if (present(idread)) ids = idread
    bo = BYTE_ORDER_NATIVE
    if (present(byte_order)) bo = byte_order
    if (nx < 1 .or. ny < 1 .or. nz3 < 1 .or. nkd < 1 .or. np3d < 1) then
      call set_error(error, trim(path)//': sizes nx = '//str(nx)//', ny = '//str(ny)// &
                     ', nz3 = '//str(nz3)//', nkd = '//str(nkd)//', np3d = '//str(np3d)// &
                     ' must all be >= 1')
      return
    end if
    if (mtprof /= 0 .and. mtprof /= 1) then
      call set_error(error, trim(path)//': mtprof = '//str(mtprof)//' must be 0 or 1')
      return
    end if
    ntmp = nz3 + mtprof
    nrec = ntmp + nz3*(nkd + 3*np3d)
    allocate (names(nrec))
    do k = 1, ntmp
      names(k) = 'tmpa3d level '//str(k)
    end do
    do ikd = 1, nkd
      do k = 1, nz3
        names(ntmp + (ikd - 1)*nz3 + k) = 'absg3d k-term '//str(ikd)//' layer '//str(k)
      end do
    end do
    do ip = 1, np3d
      do k = 1, nz3
        names(ntmp + nkd*nz3 + 3*(ip - 1)*nz3 + k) = 'extp3d comp. '//str(ip)//' layer '//str(k)
        names(ntmp + nkd*nz3 + (3*ip - 2)*nz3 + k) = 'omgp3d comp. '//str(ip)//' layer '//str(k)
        names(ntmp + nkd*nz3 + (3*ip - 1)*nz3 + k) = 'apfp3d comp. '//str(ip)//' layer '//str(k)
      end do
    end do
    call read_f32_records(path, nx*ny, nrec, ids, bo, names, f, atm%ndatasets, error)
    if (allocated(error)) return
    atm%nx = nx
    atm%ny = ny
    atm%nz3 = nz3
    atm%mtprof = mtprof
    atm%nkd = nkd
    atm%np3d = np3d
    atm%idread = ids
    allocate (atm%tmpa(nx, ny, ntmp), atm%absg(nx, ny, nz3, nkd), atm%ext(nx, ny, nz3, np3d), &
              atm%omg(nx, ny, nz3, np3d), atm%apf(nx, ny, nz3, np3d))
    irec0 = (ids - 1)*nrec
    do k = 1, ntmp
      atm%tmpa(:, :, k) = reshape(f(:, k), [nx, ny])
    end do
    do ikd = 1, nkd
      do k = 1, nz3
        atm%absg(:, :, k, ikd) = reshape(f(:, ntmp + (ikd - 1)*nz3 + k), [nx, ny])
      end do
    end do
    do ip = 1, np3d
      do k = 1, nz3
        atm%ext(:, :, k, ip) = reshape(f(:, ntmp + nkd*nz3 + 3*(ip - 1)*nz3 + k), [nx, ny])
        atm%omg(:, :, k, ip) = reshape(f(:, ntmp + nkd*nz3 + (3*ip - 2)*nz3 + k), [nx, ny])
        atm%apf(:, :, k, ip) = reshape(f(:, ntmp + nkd*nz3 + (3*ip - 1)*nz3 + k), [nx, ny])
      end do
    end do
    ! ranges (non-finite values were rejected while reading)
    do ip = 1, np3d
      do k = 1, nz3
        call check_field(atm%ext(:, :, k, ip), 'extp3d', 0.0_wp, huge(1.0_wp), &
                         irec0 + ntmp + nkd*nz3 + 3*(ip - 1)*nz3 + k)
        call check_field(atm%omg(:, :, k, ip), 'omgp3d', 0.0_wp, 1.0_wp, &
                         irec0 + ntmp + nkd*nz3 + (3*ip - 2)*nz3 + k)
        if (present(npf)) then
          call check_field(atm%apf(:, :, k, ip), 'apfp3d', -3.0_wp, real(npf, wp), &
                           irec0 + ntmp + nkd*nz3 + (3*ip - 1)*nz3 + k, open_low=.true.)
        else
          call check_field(atm%apf(:, :, k, ip), 'apfp3d', -3.0_wp, huge(1.0_wp), &
                           irec0 + ntmp + nkd*nz3 + (3*ip - 1)*nz3 + k, open_low=.true.)
        end if
        if (allocated(error)) return
      end do
    end do
    atm%missing = 'dx, dy (Atm_dx, Atm_dy), the heights of the layer interfaces and the '// &
                  'first 3-D layer (Atm_zgrd0, Atm_iz3l), the 1-D temperature and absorption '// &
                  'profiles the perturbations are added to (Atm_tmp1d, Atm_abs1d), and the '// &
                  'wavelength'
    if (nkd > 1) atm%missing = atm%missing//', the k-term weights (Atm_wkd0)'

  contains
    subroutine check_field(x, name, lo, hi, irec, open_low)
      real(wp), intent(in) :: x(:, :)
      character(len=*), intent(in) :: name
      real(wp), intent(in) :: lo, hi
      integer, intent(in) :: irec
      logical, intent(in), optional :: open_low
      integer :: loc(2)
      logical :: strict
      character(len=:), allocatable :: bound
      if (allocated(error)) return
      strict = .false.
      if (present(open_low)) strict = open_low
      if (strict) then
        if (all(x > lo .and. x <= hi)) return
        loc = minloc(merge(1, 0, x > lo .and. x <= hi))
      else
        if (all(x >= lo .and. x <= hi)) return
        loc = minloc(merge(1, 0, x >= lo .and. x <= hi))
      end if
      if (name == 'apfp3d') then
        bound = '(-3, '
        if (present(npf)) then
          bound = bound//'npf = '//str(npf)//']'
        else
          bound = bound//'Inf)'
        end if
      else if (hi >= huge(hi)) then
        bound = '['//str(lo)//', Inf)'
      else
        bound = '['//str(lo)//', '//str(hi)//']'
      end if
      call set_error(error, trim(path)//': record '//str(irec)//' ('//trim(names(irec - irec0))// &
                     '), ix = '//str(loc(1))//', iy = '//str(loc(2))//': '//name//' = '// &
                     str(x(loc(1), loc(2)))//' must be within '//bound)
    end subroutine check_field
  end subroutine read_mcarats_atm

  !> Read an MCARaTS 3-D atmosphere through its `.ctl` descriptor. Sizes come from it (see
  !> `mcarats_atm_ctl_sizes`).
  subroutine read_mcarats_atm_ctl(ctl_path, atm, error, idread, npf)
    character(len=*), intent(in) :: ctl_path          !! the .ctl file
    type(mcarats_atm_t), intent(out) :: atm           !! the dataset read
    type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    integer, intent(in), optional :: idread           !! dataset, 1-based (default 1)
    integer, intent(in), optional :: npf              !! number of tabulated phase functions
    type(grads_ctl_t) :: ctl
    integer :: nz3, mtprof, nkd, np3d, ids
    call mcarats_atm_ctl_sizes(ctl_path, ctl, nz3, mtprof, nkd, np3d, error)
    if (allocated(error)) return
    ids = 1
    if (present(idread)) ids = idread
    if (ids < 1 .or. ids > ctl%nt) then
      call set_error(error, trim(ctl_path)//': idread = '//str(ids)//' must be within [1, '// &
                     'TDEF = '//str(ctl%nt)//']')
      return
    end if
    call read_mcarats_atm(ctl%dset, ctl%nx, ctl%ny, nz3, mtprof, nkd, np3d, atm, error, &
                          idread=ids, byte_order=ctl%byte_order, npf=npf)
    if (allocated(error)) return
    if (atm%ndatasets /= ctl%nt) then
      call set_error(error, ctl%dset//': holds '//str(atm%ndatasets)//' datasets but '// &
                     trim(ctl_path)//' says TDEF = '//str(ctl%nt))
    end if
  end subroutine read_mcarats_atm_ctl

  !> Sizes of an MCARaTS 3-D atmosphere from its `.ctl` descriptor, without reading the data:
  !> nx, ny from XDEF, YDEF (in `ctl`); nz3 from the levels of the extinction variable;
  !> mtprof = levels of the first (temperature) variable - nz3; nkd = levels of the second
  !> (absorption) / nz3; np3d from the remaining variables, three (ext, omg, apf) per component.
  subroutine mcarats_atm_ctl_sizes(ctl_path, ctl, nz3, mtprof, nkd, np3d, error)
    character(len=*), intent(in) :: ctl_path          !! the .ctl file
    type(grads_ctl_t), intent(out) :: ctl             !! the descriptor
    integer, intent(out) :: nz3, mtprof, nkd, np3d    !! the MCARaTS sizes
    type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    integer :: nv, ip
    nz3 = 0
    mtprof = 0
    nkd = 0
    np3d = 0
    call read_grads_ctl(ctl_path, ctl, error)
    if (allocated(error)) return
    nv = size(ctl%vars)
    if (nv < 5 .or. mod(nv - 2, 3) /= 0) then
      call set_error(error, trim(ctl_path)//': '//str(nv)//' variables; an MCARaTS atmosphere '// &
                     'has tmpa3d, abst3d and three (extp3d, omgp3d, apfp3d) per component')
      return
    end if
    np3d = (nv - 2)/3
    nz3 = ctl%vars(3)%nlev
    do ip = 1, np3d
      if (any(ctl%vars(3*ip:3*ip + 2)%nlev /= nz3)) then
        call set_error(error, trim(ctl_path)//': component '//str(ip)//' variables do not all '// &
                       'have nz3 = '//str(nz3)//' levels')
        return
      end if
    end do
    mtprof = ctl%vars(1)%nlev - nz3
    if (mtprof /= 0 .and. mtprof /= 1) then
      call set_error(error, trim(ctl_path)//': '//ctl%vars(1)%name//' has '// &
                     str(ctl%vars(1)%nlev)//' levels; expected nz3 = '//str(nz3)// &
                     ' or nz3 + 1')
      return
    end if
    if (mod(ctl%vars(2)%nlev, nz3) /= 0) then
      call set_error(error, trim(ctl_path)//': '//ctl%vars(2)%name//' has '// &
                     str(ctl%vars(2)%nlev)//' levels, not a multiple of nz3 = '//str(nz3))
      return
    end if
    nkd = ctl%vars(2)%nlev/nz3
  end subroutine mcarats_atm_ctl_sizes

  ! ------------------------------------------------------------------------------------------
  ! Phase functions
  ! ------------------------------------------------------------------------------------------

  !> Read an MCARaTS binary phase-function file: after `nskip` records, one record of angles
  !> [deg] and `npf` records of P(angle); each record holds nang + nanci values (the nanci
  !> ancillary values are skipped). Angles must be distinct, monotonic (decreasing ones are
  !> reversed, as MCARaTS does) and run from 0 to 180; P must be finite and >= 0.
  subroutine read_mcarats_phase(path, nang, npf, pf, error, nskip, nanci, byte_order)
    character(len=*), intent(in) :: path              !! binary file
    integer, intent(in) :: nang, npf                  !! Sca_nangi, Sca_npf
    type(mcarats_phase_t), intent(out) :: pf          !! the tables read
    type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    integer, intent(in), optional :: nskip            !! Sca_nskip (default 0)
    integer, intent(in), optional :: nanci            !! Sca_nanci (default 0)
    integer, intent(in), optional :: byte_order       !! BYTE_ORDER_* (default native)
    real(wp), allocatable :: f(:, :)
    character(len=40), allocatable :: names(:)
    integer :: ns, na, bo, nd, i, ip, k
    real(wp) :: s, mu(2)

    ns = 0
    if (present(nskip)) ns = nskip
    na = 0
    if (present(nanci)) na = nanci
    bo = BYTE_ORDER_NATIVE
    if (present(byte_order)) bo = byte_order
    if (nang < 2 .or. npf < 1 .or. ns < 0 .or. na < 0) then
      call set_error(error, trim(path)//': nang = '//str(nang)//' must be >= 2, npf = '// &
                     str(npf)//' >= 1, nskip = '//str(ns)//' and nanci = '//str(na)//' >= 0')
      return
    end if
    allocate (names(ns + 1 + npf))
    names(1:ns) = 'skipped'
    names(ns + 1) = 'angles'
    do ip = 1, npf
      names(ns + 1 + ip) = 'phase function '//str(ip)
    end do
    call read_f32_records(path, nang + na, ns + 1 + npf, 1, bo, names, f, nd, error)
    if (allocated(error)) return
    if (nd /= 1) then
      call set_error(error, trim(path)//': holds '//str(nd*(ns + 1 + npf))//' records of '// &
                     str(nang + na)//' values; expected nskip + 1 + npf = '//str(ns + 1 + npf))
      return
    end if
    pf%nang = nang
    pf%npf = npf
    pf%angle_deg = f(1:nang, ns + 1)
    pf%p_file = f(1:nang, ns + 2:ns + 1 + npf)
    pf%reversed = pf%angle_deg(nang) < pf%angle_deg(1)
    if (pf%reversed) then
      pf%angle_deg = pf%angle_deg(nang:1:-1)
      pf%p_file = pf%p_file(nang:1:-1, :)
    end if
    do i = 2, nang
      if (pf%angle_deg(i) <= pf%angle_deg(i - 1)) then
        k = merge(nang + 2 - i, i, pf%reversed)
        call set_error(error, trim(path)//': record '//str(ns + 1)//' (angles): angle '// &
                       str(k)//' = '//str(pf%angle_deg(i))//' deg breaks the '// &
                       'strictly monotonic order (duplicate or unsorted angle)')
        return
      end if
    end do
    if (abs(pf%angle_deg(1)) > 1.0e-4_wp .or. abs(pf%angle_deg(nang) - 180.0_wp) > 1.0e-4_wp) then
      call set_error(error, trim(path)//': record '//str(ns + 1)//' (angles): the angles span '// &
                     str(pf%angle_deg(1))//' to '//str(pf%angle_deg(nang))// &
                     ' deg; they must run from 0 to 180')
      return
    end if
    allocate (pf%p(nang, npf))
    do ip = 1, npf
      do i = 1, nang
        if (pf%p_file(i, ip) < 0.0_wp) then
          k = merge(nang + 1 - i, i, pf%reversed)
          call set_error(error, trim(path)//': record '//str(ns + 1 + ip)//' (phase function '// &
                         str(ip)//'): value '//str(k)//' = '//str(pf%p_file(i, ip))// &
                         ' must be >= 0')
          return
        end if
      end do
      ! 1/2 int P dmu over [-1, 1], trapezoidal rule on the file's angles
      s = 0.0_wp
      do i = 2, nang
        mu = cos(pf%angle_deg(i - 1:i)*(acos(-1.0_wp)/180.0_wp))
        s = s + 0.25_wp*(pf%p_file(i - 1, ip) + pf%p_file(i, ip))*(mu(1) - mu(2))
      end do
      if (s <= 0.0_wp) then
        call set_error(error, trim(path)//': record '//str(ns + 1 + ip)//' (phase function '// &
                       str(ip)//'): integral is '//str(s)//'; it must be > 0')
        return
      end if
      pf%p(:, ip) = pf%p_file(:, ip)/s
    end do
  end subroutine read_mcarats_phase

  !> Read an MCARaTS phase-function file through its `.ctl` (sizes: `mcarats_phase_ctl_sizes`).
  subroutine read_mcarats_phase_ctl(ctl_path, pf, error)
    character(len=*), intent(in) :: ctl_path          !! the .ctl file
    type(mcarats_phase_t), intent(out) :: pf          !! the tables read
    type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    type(grads_ctl_t) :: ctl
    integer :: nang, npf
    call mcarats_phase_ctl_sizes(ctl_path, ctl, nang, npf, error)
    if (allocated(error)) return
    call read_mcarats_phase(ctl%dset, nang, npf, pf, error, byte_order=ctl%byte_order)
  end subroutine read_mcarats_phase_ctl

  !> Sizes of an MCARaTS phase-function file from its `.ctl`: nang from XDEF, npf from the
  !> levels of the second variable (the first holds the angles).
  subroutine mcarats_phase_ctl_sizes(ctl_path, ctl, nang, npf, error)
    character(len=*), intent(in) :: ctl_path          !! the .ctl file
    type(grads_ctl_t), intent(out) :: ctl             !! the descriptor
    integer, intent(out) :: nang, npf                 !! angles per table, tables
    type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    nang = 0
    npf = 0
    call read_grads_ctl(ctl_path, ctl, error)
    if (allocated(error)) return
    if (size(ctl%vars) /= 2 .or. ctl%ny /= 1) then
      call set_error(error, trim(ctl_path)//': a phase-function descriptor has YDEF 1 and two '// &
                     'variables (angles with 1 level, phase functions with npf levels)')
      return
    end if
    if (ctl%vars(1)%nlev /= 1) then
      call set_error(error, trim(ctl_path)//': '//ctl%vars(1)%name//' (angles) has '// &
                     str(ctl%vars(1)%nlev)//' levels; expected 1')
      return
    end if
    nang = ctl%nx
    npf = ctl%vars(2)%nlev
  end subroutine mcarats_phase_ctl_sizes

  !> A file name ending in `.ctl` (any case) names a GrADS descriptor.
  pure logical function is_ctl_path(path)
    character(len=*), intent(in) :: path
    integer :: n
    n = len_trim(path)
    is_ctl_path = .false.
    if (n >= 4) is_ctl_path = to_lower(path(n - 3:n)) == '.ctl'
  end function is_ctl_path

  ! ------------------------------------------------------------------------------------------
  ! Surface
  ! ------------------------------------------------------------------------------------------

  !> Read dataset `idread` of an MCARaTS binary surface file: records of nxb x nyb values,
  !> temperature [K], BRDF type (0 black, 1 Lambert, 2 DSM, 3 RPV, 4 LSRT, stored as a float)
  !> and npsfc parameter fields, npsfc = the largest parameter count of the enabled types
  !> (Lambert 1, DSM 5, RPV 4, LSRT 3). Parameter ranges follow the MCARaTS meanings: Lambert
  !> albedo and DSM diffuse albedo and fraction in [0, 1]; DSM refractive index in (0, 100],
  !> its imaginary part >= 0 and slope variance in (0, 100]; RPV rho0 >= 0, Theta in (-1, 1),
  !> hot-spot delta >= 0; LSRT isotropic weight >= 0.
  subroutine read_mcarats_surface(path, nxb, nyb, npsfc, sfc, error, idread, byte_order)
    character(len=*), intent(in) :: path              !! binary file
    integer, intent(in) :: nxb, nyb                   !! Sfc_nxb, Sfc_nyb
    integer, intent(in) :: npsfc                      !! parameter fields per dataset (0..5)
    type(mcarats_surface_t), intent(out) :: sfc       !! the dataset read
    type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    integer, intent(in), optional :: idread           !! dataset, 1-based (default 1)
    integer, intent(in), optional :: byte_order       !! BYTE_ORDER_* (default native)
    real(wp), allocatable :: f(:, :)
    integer :: ids, bo, nd, ix, iy, it, irec0
    real(wp) :: t, q(5)
    character(len=:), allocatable :: at, bad
    character(len=40), allocatable :: names(:)

    ids = 1
    if (present(idread)) ids = idread
    bo = BYTE_ORDER_NATIVE
    if (present(byte_order)) bo = byte_order
    if (nxb < 1 .or. nyb < 1 .or. npsfc < 0 .or. npsfc > 5) then
      call set_error(error, trim(path)//': nxb = '//str(nxb)//', nyb = '//str(nyb)// &
                     ' must be >= 1 and npsfc = '//str(npsfc)//' within [0, 5]')
      return
    end if
    allocate (names(2 + npsfc))
    names(1) = 'temperature'
    names(2) = 'BRDF type'
    do it = 1, npsfc
      names(2 + it) = 'parameter '//str(it)
    end do
    call read_f32_records(path, nxb*nyb, 2 + npsfc, ids, bo, names, f, nd, error)
    if (allocated(error)) return
    irec0 = (ids - 1)*(2 + npsfc)
    sfc%idread = ids
    sfc%ndatasets = nd
    sfc%nxb = nxb
    sfc%nyb = nyb
    sfc%npsfc = npsfc
    sfc%temperature = reshape(f(:, 1), [nxb, nyb])
    allocate (sfc%brdf_type(nxb, nyb), sfc%params(nxb, nyb, npsfc))
    do it = 1, npsfc
      sfc%params(:, :, it) = reshape(f(:, 2 + it), [nxb, nyb])
    end do
    do iy = 1, nyb
      do ix = 1, nxb
        at = trim(path)//': pixel (ix='//str(ix)//', iy='//str(iy)//'), '
        if (sfc%temperature(ix, iy) <= 0.0_wp) then
          call set_error(error, at//'record '//str(irec0 + 1)//' (temperature) = '// &
                         str(sfc%temperature(ix, iy))//' K must be > 0')
          return
        end if
        t = f(ix + (iy - 1)*nxb, 2)
        if (abs(t - anint(t)) > 1.0e-6_wp .or. t < -0.5_wp .or. t > 4.5_wp) then
          call set_error(error, at//'record '//str(irec0 + 2)//' (BRDF type) = '//str(t)// &
                         ' must be 0 (black), 1 (Lambert), 2 (DSM), 3 (RPV) or 4 (LSRT)')
          return
        end if
        it = nint(t)
        sfc%brdf_type(ix, iy) = it
        if (SFC_NPAR(it) > npsfc) then
          call set_error(error, at//trim(SFC_NAMES(it))//' needs '//str(SFC_NPAR(it))// &
                         ' parameters but the file holds npsfc = '//str(npsfc))
          return
        end if
        q = 0.0_wp
        q(1:npsfc) = sfc%params(ix, iy, :)
        bad = ''
        select case (it)
        case (1)
          if (q(1) < 0.0_wp .or. q(1) > 1.0_wp) bad = 'Lambert albedo (parameter 1) = '// &
                                                      str(q(1))//' must be within [0, 1]'
        case (2)
          if (q(1) < 0.0_wp .or. q(1) > 1.0_wp) then
            bad = 'DSM diffuse albedo (parameter 1) = '//str(q(1))//' must be within [0, 1]'
          else if (q(2) < 0.0_wp .or. q(2) > 1.0_wp) then
            bad = 'DSM diffuse fraction (parameter 2) = '//str(q(2))//' must be within [0, 1]'
          else if (q(3) <= 0.0_wp .or. q(3) > 100.0_wp) then
            bad = 'DSM refractive index (parameter 3) = '//str(q(3))//' must be within (0, 100]'
          else if (q(4) < 0.0_wp) then
            bad = 'DSM imaginary index (parameter 4) = '//str(q(4))//' must be >= 0'
          else if (q(5) <= 0.0_wp .or. q(5) > 100.0_wp) then
            bad = 'DSM slope variance (parameter 5) = '//str(q(5))//' must be within (0, 100]'
          end if
        case (3)
          if (q(1) < 0.0_wp) then
            bad = 'RPV rho0 (parameter 1) = '//str(q(1))//' must be >= 0'
          else if (abs(q(3)) >= 1.0_wp) then
            bad = 'RPV Theta (parameter 3) = '//str(q(3))//' must be within (-1, 1)'
          else if (q(4) < 0.0_wp) then
            bad = 'RPV hot-spot delta (parameter 4) = '//str(q(4))//' must be >= 0'
          end if
        case (4)
          if (q(1) < 0.0_wp) bad = 'LSRT isotropic weight (parameter 1) = '//str(q(1))// &
                                   ' must be >= 0'
        case default
          ! black: no parameters
        end select
        if (len(bad) > 0) then
          call set_error(error, at//bad)
          return
        end if
      end do
    end do
    sfc%missing = 'the surface extent the nxb x nyb pixels are mapped onto (the atmosphere '// &
                  'domain) and the wavelength'
  end subroutine read_mcarats_surface

  !> Parameter fields per pixel of an MCARaTS surface file whose enabled BRDF models are
  !> `mbrdf` (MCARaTS `Sfc_mbrdf`: Lambert, DSM, RPV, LSRT; non-zero = may appear): the largest
  !> parameter count among them (1, 5, 4, 3), 0 when none is enabled (black pixels only).
  pure integer function mcarats_surface_npsfc(mbrdf) result(npsfc)
    integer, intent(in) :: mbrdf(4)
    integer :: i
    npsfc = 0
    do i = 1, 4
      if (mbrdf(i) /= 0) npsfc = max(npsfc, SFC_NPAR(i))
    end do
  end function mcarats_surface_npsfc

  !> kumo's BRDF parameter set of every pixel of an MCARaTS surface: black, Lambert (albedo),
  !> DSM, RPV and LSRT with their parameters in the MCARaTS order, which is kumo's
  !> (`brdf_params_t`). Pixels of different kinds may be mixed; a pixel whose kind `mbrdf` does
  !> not enable (MCARaTS would not have read its parameters) is an error naming the file and
  !> the pixel. Ranges are checked by kumo's BRDF setup.
  subroutine mcarats_surface_brdf(sfc, mbrdf, path, params, error)
    type(mcarats_surface_t), intent(in) :: sfc        !! the surface read
    integer, intent(in) :: mbrdf(4)                   !! enabled models (Sfc_mbrdf)
    character(len=*), intent(in) :: path              !! the file, for messages
    type(brdf_params_t), allocatable, intent(out) :: params(:, :)  !! (nxb, nyb)
    type(error_t), allocatable, intent(out) :: error  !! unallocated on success
    integer, parameter :: KUMO_KIND(0:4) = [BRDF_BLACK, BRDF_LAMBERT, BRDF_DSM, BRDF_RPV, BRDF_LSRT]
    integer :: ix, iy, it
    allocate (params(sfc%nxb, sfc%nyb))
    do iy = 1, sfc%nyb
      do ix = 1, sfc%nxb
        it = sfc%brdf_type(ix, iy)
        if (it > 0) then
          if (mbrdf(it) == 0) then
            call set_error(error, trim(path)//': pixel (ix='//str(ix)//', iy='//str(iy)// &
                           '), BRDF type '//str(it)//' ('//trim(SFC_NAMES(it))//') is not '// &
                           'enabled by mbrdf = '//str(mbrdf(1))//', '//str(mbrdf(2))//', '// &
                           str(mbrdf(3))//', '//str(mbrdf(4))//' (MCARaTS Sfc_mbrdf)')
            return
          end if
        end if
        params(ix, iy) = brdf_params(KUMO_KIND(it), sfc%params(ix, iy, 1:SFC_NPAR(it)))
      end do
    end do
  end subroutine mcarats_surface_brdf

  ! ------------------------------------------------------------------------------------------
  ! Binary records
  ! ------------------------------------------------------------------------------------------

  !> Read records (nrec_per_dataset of nval float32 values) of dataset `ids` into f(nval, nrec).
  !> The file size must be a whole number of datasets (`ndatasets`) and ids within them.
  !> Non-finite values are rejected from their bit pattern, before any conversion.
  subroutine read_f32_records(path, nval, nrec, ids, byte_order, names, f, ndatasets, error)
    character(len=*), intent(in) :: path
    integer, intent(in) :: nval, nrec, ids, byte_order
    character(len=*), intent(in) :: names(nrec)  !! what each record holds, for messages
    real(wp), allocatable, intent(out) :: f(:, :)
    integer, intent(out) :: ndatasets
    type(error_t), allocatable, intent(out) :: error
    integer :: unit, ios, irec, i
    integer(int32), allocatable :: raw(:)
    integer(int64) :: fsize, dsize, pos
    character(len=512) :: msg
    logical :: swap

    ndatasets = 0
    open (newunit=unit, file=path, status='old', action='read', access='stream', &
          form='unformatted', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call set_error(error, 'cannot open "'//trim(path)//'": '//trim(msg))
      return
    end if
    inquire (unit=unit, size=fsize)
    dsize = 4_int64*int(nval, int64)*int(nrec, int64)
    if (fsize < dsize) then
      call set_error(error, trim(path)//': '//str(fsize)//' bytes, fewer than one dataset of '// &
                     str(nrec)//' records x '//str(nval)//' float32 values = '//str(dsize)// &
                     ' bytes (truncated file or wrong sizes)')
      close (unit)
      return
    end if
    if (mod(fsize, dsize) /= 0) then
      call set_error(error, trim(path)//': '//str(fsize)//' bytes is not a whole number of '// &
                     'datasets of '//str(dsize)//' bytes ('//str(nrec)//' records x '// &
                     str(nval)//' float32 values); truncated file, trailing data or wrong sizes')
      close (unit)
      return
    end if
    ndatasets = int(fsize/dsize)
    if (ids < 1 .or. ids > ndatasets) then
      call set_error(error, trim(path)//': dataset '//str(ids)//' requested; the file holds '// &
                     str(ndatasets))
      close (unit)
      return
    end if
    swap = (byte_order == BYTE_ORDER_BIG .and. native_is_little()) .or. &
           (byte_order == BYTE_ORDER_LITTLE .and. .not. native_is_little())
    allocate (raw(nval), f(nval, nrec))
    do irec = 1, nrec
      pos = (int(ids - 1, int64)*int(nrec, int64) + int(irec - 1, int64))*4_int64* &
            int(nval, int64) + 1_int64
      read (unit, pos=pos, iostat=ios, iomsg=msg) raw
      if (ios /= 0) then
        call set_error(error, trim(path)//': record '//str((ids - 1)*nrec + irec)//' ('// &
                       trim(names(irec))//'): '//trim(msg))
        close (unit)
        return
      end if
      if (swap) raw = swap_bytes(raw)
      do i = 1, nval
        ! exponent bits all set: Inf or NaN
        if (iand(ishft(raw(i), -23), 255_int32) == 255_int32) then
          call set_error(error, trim(path)//': record '//str((ids - 1)*nrec + irec)//' ('// &
                         trim(names(irec))//'), value '//str(i)//' is NaN or infinite')
          close (unit)
          return
        end if
      end do
      f(:, irec) = real(transfer(raw, 1.0_real32, nval), wp)
    end do
    close (unit)
  end subroutine read_f32_records

  elemental function swap_bytes(i) result(j)
    integer(int32), intent(in) :: i
    integer(int32) :: j
    j = ior(ior(ishft(iand(i, 255_int32), 24), ishft(iand(ishft(i, -8), 255_int32), 16)), &
            ior(ishft(iand(ishft(i, -16), 255_int32), 8), iand(ishft(i, -24), 255_int32)))
  end function swap_bytes

  logical function native_is_little()
    integer(int8) :: b(4)
    b = transfer(1_int32, b)
    native_is_little = b(1) == 1_int8
  end function native_is_little
end module kumo_mcarats_files
