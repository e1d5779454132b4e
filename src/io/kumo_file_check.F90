! SPDX-License-Identifier: BSD-3-Clause
!> Completeness checks of input files before they are read: a file whose header is intact but
!> whose data end early (a partial copy, a full disk, an interrupted write) must be refused,
!> never read as zeros.
!>
!> * netCDF classic (CDF-1, CDF-2 = 64-bit offset, CDF-5 = 64-bit data): the netCDF-C library
!>   returns zeros (or fill values) for data beyond the end of a classic file. kumo parses the
!>   header itself, after the NetCDF Classic Format Specification (Unidata, "NetCDF File
!>   Format Specifications", CDF-1/2 and CDF-5 grammar: magic, numrecs, dim_list, gatt_list,
!>   var_list with each variable's begin offset), computes where each variable's data end, and
!>   compares with the file size. The first variable whose data lie beyond the end is named.
!> * netCDF-4 (HDF5): the superblock records the end-of-file address (HDF5 File Format
!>   Specification Version 3.0, section II.A, superblock versions 0 to 3). A file shorter than
!>   that is refused with both sizes; the HDF5 library itself only says "HDF error".
!> * Text files (SHDOM/I3RC, MYSTIC, phase-function tables): a file cut inside its last line
!>   would be read as a shorter number ("0.95" cut to "0.9") or a sparse file with fewer
!>   points. Every text file kumo reads must end with a line end (`check_text_complete`).
!> * Binary files without a header (MCARaTS) are checked against the sizes of their `.ctl`
!>   by their reader.
module kumo_file_check
  use, intrinsic :: iso_fortran_env, only: int8, int64
  use kumo_error, only: error_t, set_error, str
  implicit none
  private
  public :: check_netcdf_complete, check_text_complete, file_size_of

  integer, parameter :: NC_DIMENSION = 10, NC_VARIABLE = 11, NC_ATTRIBUTE = 12
  !> Bytes of one value of each external netCDF type 1..11 (byte, char, short, int, float,
  !> double, ubyte, ushort, uint, int64, uint64).
  integer, parameter :: TYPE_SIZE(11) = [1, 1, 2, 4, 4, 8, 1, 2, 4, 8, 8]
  integer(int64), parameter :: STREAMING = 4294967295_int64  !! numrecs 0xFFFFFFFF
  integer(int8), parameter :: HDF5_SIGNATURE(8) = &
    int([-119, 72, 68, 70, 13, 10, 26, 10], int8)  !! \211HDF\r\n\032\n (0x89 as a signed byte)

  !> A byte reader over a file opened for stream access.
  type :: byte_reader_t
    integer :: unit = -1
    integer(int64) :: pos = 1      !! next byte (1-based)
    integer(int64) :: size = 0     !! file size in bytes
    logical :: short = .false.     !! a read went past the end of the file
    logical :: big_endian = .true. !! netCDF classic is big-endian, HDF5 little-endian
    integer :: nsz = 4             !! bytes of a count in a classic header (8 in CDF-5)
  end type byte_reader_t

contains

  !> Size of the file `path` in bytes, or -1 if it cannot be opened.
  function file_size_of(path) result(nbytes)
    character(len=*), intent(in) :: path
    integer(int64) :: nbytes
    integer :: unit, ios
    nbytes = -1
    open (newunit=unit, file=path, status='old', action='read', access='stream', &
          form='unformatted', iostat=ios)
    if (ios /= 0) return
    inquire (unit=unit, size=nbytes)
    close (unit)
  end function file_size_of

  !> Refuse a text file whose last line has no line end (the file was probably cut short).
  !> An empty or missing file is left to the reader.
  subroutine check_text_complete(path, error)
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(out) :: error
    integer :: unit, ios
    integer(int64) :: nbytes
    character(len=1) :: last
    open (newunit=unit, file=path, status='old', action='read', access='stream', &
          form='unformatted', iostat=ios)
    if (ios /= 0) return
    inquire (unit=unit, size=nbytes)
    if (nbytes > 0) then
      read (unit, pos=nbytes, iostat=ios) last
      if (ios == 0 .and. last /= achar(10)) then
        call set_error(error, trim(path)//': the last line has no line end, so the file may '// &
                       'be cut short (partly written or partly copied); if the file is '// &
                       'complete, end its last line with a line end')
      end if
    end if
    close (unit)
  end subroutine check_text_complete

  !> Refuse a netCDF file whose data end before its header says they do. `at` prefixes the
  !> message (it names the reading routine and the file). Files that are neither classic nor
  !> HDF5 are left to the netCDF library (which reports them itself).
  subroutine check_netcdf_complete(at, path, error)
    character(len=*), intent(in) :: at    !! context for messages, e.g. 'read_scene_3d(a.nc)'
    character(len=*), intent(in) :: path  !! the file
    type(error_t), allocatable, intent(out) :: error
    type(byte_reader_t) :: r
    integer(int8) :: magic(8)
    integer :: ios
    open (newunit=r%unit, file=path, status='old', action='read', access='stream', &
          form='unformatted', iostat=ios)
    if (ios /= 0) return                   ! the library's open reports a missing file
    inquire (unit=r%unit, size=r%size)
    if (r%size >= 4) then
      magic = 0
      read (r%unit, pos=1, iostat=ios) magic(1:min(8_int64, r%size))
      if (all(magic(1:3) == int([67, 68, 70], int8))) then            ! 'CDF'
        call check_classic(at, r, int(magic(4)), error)
      else if (r%size >= 8 .and. all(magic == HDF5_SIGNATURE)) then
        call check_hdf5(at, r, 0_int64, error)
      else
        call find_hdf5_superblock(at, r, error)
      end if
    end if
    close (r%unit)
  end subroutine check_netcdf_complete

  !> Classic formats: walk the header, then compare every variable's data end with the size.
  subroutine check_classic(at, r, version, error)
    character(len=*), intent(in) :: at
    type(byte_reader_t), intent(inout) :: r
    integer, intent(in) :: version
    type(error_t), allocatable, intent(out) :: error
    integer :: nsz, osz                     ! bytes of counts/lengths, of offsets
    integer(int64) :: numrecs, ndims, nvars, i, j, tag, n, vtype, first_end
    integer(int64), allocatable :: dim_len(:), begin(:), nbytes(:), data_end(:)
    logical, allocatable :: is_rec(:)
    character(len=:), allocatable :: name, first_name
    character(len=:), allocatable, dimension(:) :: names
    integer(int64) :: recsize, nrecvars, ndv, dimid, prod
    if (version /= 1 .and. version /= 2 .and. version /= 5) return   ! not ours to judge
    nsz = merge(8, 4, version == 5)
    osz = merge(4, 8, version == 1)
    r%nsz = nsz
    r%pos = 5
    numrecs = get_uint(r, nsz)
    ! dimensions
    tag = get_uint(r, 4)
    ndims = get_uint(r, nsz)
    if (r%short) goto 900
    if (tag /= NC_DIMENSION .and. .not. (tag == 0 .and. ndims == 0)) goto 910
    if (ndims < 0 .or. ndims > r%size) goto 910
    allocate (dim_len(0:max(ndims - 1, 0_int64)))
    do i = 0, ndims - 1
      call skip_name(r)
      dim_len(i) = get_uint(r, nsz)
      if (r%short) goto 900
    end do
    ! global attributes
    call skip_att_list(r, nsz)
    if (r%short) goto 900
    ! variables
    tag = get_uint(r, 4)
    nvars = get_uint(r, nsz)
    if (r%short) goto 900
    if (tag /= NC_VARIABLE .and. .not. (tag == 0 .and. nvars == 0)) goto 910
    if (nvars < 0 .or. nvars > r%size) goto 910
    allocate (begin(nvars), nbytes(nvars), is_rec(nvars), data_end(nvars))
    allocate (character(len=256) :: names(nvars))
    recsize = 0
    nrecvars = 0
    do i = 1, nvars
      n = get_uint(r, nsz)
      if (r%short .or. n < 0 .or. n > r%size) goto 900
      name = get_chars(r, n)
      names(i) = name
      ndv = get_uint(r, nsz)
      if (r%short .or. ndv < 0 .or. ndv > 1024) goto 910
      prod = 1
      is_rec(i) = .false.
      do j = 1, ndv
        dimid = get_uint(r, nsz)
        if (r%short) goto 900
        if (dimid < 0 .or. dimid >= ndims) goto 910
        if (j == 1 .and. dim_len(dimid) == 0) then
          is_rec(i) = .true.
        else
          prod = prod * dim_len(dimid)
        end if
      end do
      call skip_att_list(r, nsz)
      vtype = get_uint(r, 4)
      n = get_uint(r, nsz)                  ! vsize (may be clipped for huge variables)
      begin(i) = get_uint(r, osz)
      if (r%short) goto 900
      if (vtype < 1 .or. vtype > size(TYPE_SIZE)) goto 910
      nbytes(i) = prod * TYPE_SIZE(vtype)
      if (is_rec(i)) then
        nrecvars = nrecvars + 1
        recsize = recsize + pad4(nbytes(i))
      end if
    end do
    ! One record variable alone is not padded (the classic format's special case).
    if (nrecvars == 1) recsize = sum(nbytes, mask=is_rec)
    do i = 1, nvars
      if (.not. is_rec(i)) then
        data_end(i) = begin(i) + nbytes(i)
      else if (numrecs == STREAMING .or. numrecs == 0) then
        data_end(i) = 0                     ! nothing to check
      else
        data_end(i) = begin(i) + (numrecs - 1) * recsize + nbytes(i)
      end if
    end do
    ! the first variable (in file order) whose data are not all there
    first_end = -1
    do i = 1, nvars
      if (data_end(i) > r%size .and. nbytes(i) > 0) then
        if (first_end < 0) then
          first_end = i
        else if (begin(i) < begin(first_end)) then
          first_end = i
        end if
      end if
    end do
    if (first_end > 0) then
      first_name = trim(names(first_end))
      n = count(data_end > r%size .and. nbytes > 0)
      call set_error(error, at//': the file is cut short (partly written or partly copied?): '// &
                     'variable '''//first_name//''' needs '//str(data_end(first_end))// &
                     ' bytes, but the file has '//str(r%size)//' bytes ('//str(n)//' of '// &
                     str(nvars)//' variables incomplete; netCDF classic format CDF-'// &
                     str(version)//')')
    end if
    return
900 call set_error(error, at//': the netCDF header is cut short (the file has '// &
                   str(r%size)//' bytes)')
    return
910 call set_error(error, at//': the netCDF classic header is corrupt near byte '//str(r%pos))
  end subroutine check_classic

  !> Look for an HDF5 superblock after a user block (offsets 512, 1024, 2048, ...).
  subroutine find_hdf5_superblock(at, r, error)
    character(len=*), intent(in) :: at
    type(byte_reader_t), intent(inout) :: r
    type(error_t), allocatable, intent(out) :: error
    integer(int64) :: base
    integer(int8) :: sig(8)
    integer :: ios
    base = 512
    do while (base + 8 <= r%size)
      read (r%unit, pos=base + 1, iostat=ios) sig
      if (ios /= 0) return
      if (all(sig == HDF5_SIGNATURE)) then
        call check_hdf5(at, r, base, error)
        return
      end if
      base = 2 * base
    end do
  end subroutine find_hdf5_superblock

  !> HDF5: the superblock's end-of-file address (relative to the base address) must be covered.
  subroutine check_hdf5(at, r, base, error)
    character(len=*), intent(in) :: at
    type(byte_reader_t), intent(inout) :: r
    integer(int64), intent(in) :: base     !! offset of the signature (0-based)
    type(error_t), allocatable, intent(out) :: error
    integer :: version, osz
    integer(int64) :: base_addr, eof_addr
    r%big_endian = .false.
    r%pos = base + 9
    version = int(get_uint(r, 1))
    select case (version)
    case (0, 1)
      ! versions (free space, root group, shared header: 3 bytes + reserved 1), offsets, lengths
      r%pos = base + 14
      osz = int(get_uint(r, 1))
      r%pos = base + 25                    ! after reserved, leaf K, internal K, flags
      if (version == 1) r%pos = r%pos + 4  ! indexed storage K and reserved
      if (osz /= 2 .and. osz /= 4 .and. osz /= 8) return
      base_addr = get_uint(r, osz)
      call skip(r, int(osz, int64))        ! free-space info address
      eof_addr = get_uint(r, osz)
    case (2, 3)
      osz = int(get_uint(r, 1))
      call skip(r, 2_int64)                ! size of lengths, consistency flags
      if (osz /= 2 .and. osz /= 4 .and. osz /= 8) return
      base_addr = get_uint(r, osz)
      call skip(r, int(osz, int64))        ! superblock extension address
      eof_addr = get_uint(r, osz)
    case default
      return
    end select
    if (r%short) then
      call set_error(error, at//': the HDF5 superblock is cut short (the file has '// &
                     str(r%size)//' bytes)')
      return
    end if
    if (eof_addr < 0) return               ! undefined address: nothing recorded
    if (base_addr + eof_addr > r%size) then
      call set_error(error, at//': the file is cut short (partly written or partly copied?): '// &
                     'its HDF5 superblock records '//str(base_addr + eof_addr)// &
                     ' bytes, but the file has '//str(r%size)//' bytes; no variable of it '// &
                     'can be trusted')
    end if
  end subroutine check_hdf5

  !> Skip a name (count, characters padded to 4 bytes).
  subroutine skip_name(r)
    type(byte_reader_t), intent(inout) :: r
    integer(int64) :: n
    n = get_uint(r, r%nsz)
    if (r%short) return
    call skip(r, pad4(n))
  end subroutine skip_name

  !> Skip an attribute list (ABSENT or NC_ATTRIBUTE nelems [attr ...]).
  subroutine skip_att_list(r, nsz)
    type(byte_reader_t), intent(inout) :: r
    integer, intent(in) :: nsz
    integer(int64) :: tag, natts, i, atype, n
    tag = get_uint(r, 4)
    natts = get_uint(r, nsz)
    if (r%short) return
    if (natts < 0 .or. natts > r%size) then
      r%short = .true.
      return
    end if
    do i = 1, natts
      n = get_uint(r, nsz)
      if (r%short .or. n < 0 .or. n > r%size) then
        r%short = .true.
        return
      end if
      call skip(r, pad4(n))                ! name
      atype = get_uint(r, 4)
      n = get_uint(r, nsz)
      if (r%short) return
      if (atype < 1 .or. atype > size(TYPE_SIZE) .or. n < 0 .or. n > r%size) then
        r%short = .true.
        return
      end if
      call skip(r, pad4(n * TYPE_SIZE(atype)))
    end do
  end subroutine skip_att_list

  pure integer(int64) function pad4(n)
    integer(int64), intent(in) :: n
    pad4 = n + modulo(-n, 4_int64)
  end function pad4

  subroutine skip(r, n)
    type(byte_reader_t), intent(inout) :: r
    integer(int64), intent(in) :: n
    r%pos = r%pos + n
    if (r%pos - 1 > r%size) r%short = .true.
  end subroutine skip

  !> Unsigned integer of `nbytes` bytes at the current position, in the reader's byte order.
  function get_uint(r, nbytes) result(v)
    type(byte_reader_t), intent(inout) :: r
    integer, intent(in) :: nbytes
    integer(int64) :: v
    integer(int8) :: b(8)
    integer :: i, ios
    v = 0
    if (r%short) return
    if (r%pos - 1 + nbytes > r%size) then
      r%short = .true.
      return
    end if
    read (r%unit, pos=r%pos, iostat=ios) b(1:nbytes)
    if (ios /= 0) then
      r%short = .true.
      return
    end if
    r%pos = r%pos + nbytes
    if (.not. r%big_endian) then
      do i = nbytes, 1, -1
        v = ior(ishft(v, 8), iand(int(b(i), int64), 255_int64))
      end do
    else
      do i = 1, nbytes
        v = ior(ishft(v, 8), iand(int(b(i), int64), 255_int64))
      end do
    end if
  end function get_uint

  function get_chars(r, n) result(s)
    type(byte_reader_t), intent(inout) :: r
    integer(int64), intent(in) :: n
    character(len=:), allocatable :: s
    integer :: ios
    allocate (character(len=min(n, 256_int64)) :: s)
    if (r%pos - 1 + n > r%size) then
      r%short = .true.
      s = ''
      return
    end if
    if (len(s) > 0) read (r%unit, pos=r%pos, iostat=ios) s
    call skip(r, pad4(n))
  end function get_chars
end module kumo_file_check
