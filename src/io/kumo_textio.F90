! SPDX-License-Identifier: BSD-3-Clause
!> Small text-file readers: two-column tables (e.g. tabulated phase functions) and whole files.
module kumo_textio
  use, intrinsic :: iso_fortran_env, only: iostat_end, iostat_eor
  use, intrinsic :: iso_c_binding, only: c_char, c_ptr, c_null_char, c_associated
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str
  use kumo_file_check, only: check_text_complete
  implicit none
  private
  public :: read_two_columns, read_whole_file, read_line, same_file

  interface
    !> realpath(3): the canonical absolute path (links resolved), or a null pointer.
    function c_realpath(path, resolved) bind(c, name='realpath') result(p)
      import :: c_char, c_ptr
      character(kind=c_char), intent(in) :: path(*)
      character(kind=c_char), intent(out) :: resolved(*)
      type(c_ptr) :: p
    end function c_realpath
  end interface

contains

  !> Read a table of two numbers per line; blank lines and lines starting with '#' or '!' are
  !> skipped. Any other line that does not hold two numbers is an error naming the line.
  subroutine read_two_columns(path, a, b, error)
    character(len=*), intent(in) :: path
    real(wp), allocatable, intent(out) :: a(:), b(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: unit, ios, n, line_no, pass
    character(len=1024) :: msg
    character(len=:), allocatable :: line
    real(wp) :: va, vb
    call check_text_complete(path, error)   ! (before the open: a file is open on one unit only)
    if (allocated(error)) return
    open (newunit=unit, file=path, status='old', action='read', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call set_error(error, 'cannot open table file "'//trim(path)//'": '//trim(msg))
      return
    end if
    do pass = 1, 2
      n = 0
      line_no = 0
      rewind (unit)
      do
        call read_line(unit, line, ios)
        if (ios == iostat_end) exit
        line_no = line_no + 1
        if (ios /= 0) then
          call set_error(error, trim(path)//': cannot read line '//str(line_no))
          close (unit)
          return
        end if
        line = adjustl(line)
        if (len_trim(line) == 0) cycle
        if (line(1:1) == '#' .or. line(1:1) == '!') cycle
        read (line, *, iostat=ios) va, vb
        if (ios /= 0) then
          call set_error(error, trim(path)//': line '//str(line_no)// &
                         ' does not hold two numbers: "'//trim(line)//'"')
          close (unit)
          return
        end if
        n = n + 1
        if (pass == 2) then
          a(n) = va
          b(n) = vb
        end if
      end do
      if (pass == 1) allocate (a(n), b(n))
    end do
    close (unit)
    if (n == 0) call set_error(error, trim(path)//': no data lines')
  end subroutine read_two_columns

  !> The whole text of a file, lines joined with new-line characters.
  subroutine read_whole_file(path, text, error)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: text
    type(error_t), allocatable, intent(out) :: error
    integer :: unit, ios
    character(len=:), allocatable :: line
    character(len=512) :: msg
    open (newunit=unit, file=path, status='old', action='read', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call set_error(error, 'cannot open "'//trim(path)//'": '//trim(msg))
      return
    end if
    text = ''
    do
      call read_line(unit, line, ios)
      if (ios /= 0) exit
      text = text//trim(line)//new_line('a')
    end do
    close (unit)
  end subroutine read_whole_file

  !> Read one line of any length from a formatted sequential unit. `ios` is 0, iostat_end at
  !> the end of the file, or another error code.
  subroutine read_line(unit, line, ios)
    integer, intent(in) :: unit
    character(len=:), allocatable, intent(out) :: line
    integer, intent(out) :: ios
    character(len=1024) :: buf
    integer :: nread
    line = ''
    do
      read (unit, '(a)', advance='no', iostat=ios, size=nread) buf
      if (ios == iostat_end) return
      line = line//buf(1:nread)
      if (ios == iostat_eor) then
        ios = 0
        return
      end if
      if (ios /= 0) return
    end do
  end subroutine read_line

  !> True when paths `a` and `b` name the same file (after resolving links, `.` and `..`); a
  !> path that does not exist yet is resolved through its directory.
  logical function same_file(a, b)
    character(len=*), intent(in) :: a, b
    same_file = canonical(a) == canonical(b)
  end function same_file

  !> Canonical absolute form of a path (itself, unchanged, when it cannot be resolved).
  function canonical(path) result(c)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: c, dir, base
    integer :: slash
    c = resolved(path)
    if (len(c) > 0) return
    slash = index(path, '/', back=.true.)
    if (slash == 0) then
      dir = '.'
      base = path
    else
      dir = path(1:max(1, slash - 1))
      base = path(slash + 1:)
    end if
    c = resolved(dir)
    if (len(c) > 0) then
      c = c//'/'//base
    else
      c = path
    end if
  end function canonical

  !> realpath of an existing path, '' if it cannot be resolved.
  function resolved(path) result(c)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: c
    character(kind=c_char) :: buf(4097)
    integer :: n, i
    buf = c_null_char
    c = ''
    if (.not. c_associated(c_realpath(trim(path)//c_null_char, buf))) return
    n = 0
    do while (n < size(buf))
      if (buf(n + 1) == c_null_char) exit
      n = n + 1
    end do
    c = repeat(' ', n)
    do i = 1, n
      c(i:i) = buf(i)
    end do
  end function resolved

end module kumo_textio
