! SPDX-License-Identifier: BSD-3-Clause
!> Error objects: library code returns them, only programs stop.
!>
!> "No error" is an unallocated `type(error_t), allocatable` variable. Messages name the input
!> and the bound that was violated, e.g. `&kumo_control: n_batches = 1 must be >= 2`.
module kumo_error
  use, intrinsic :: iso_fortran_env, only: error_unit, int64, real64
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  implicit none
  private
  public :: error_t, set_error, add_context, stop_on_error, str, to_lower, join

  !> Text of a number for messages: `str(3)` is '3', `str(0.25d0)` is '0.25'.
  interface str
    module procedure str_int, str_int64, str_real
  end interface str

  !> A list for messages: `join(['a', 'b'])` is 'a, b', `join([2, 1], ',', '()')` is '(2,1)'.
  !> Items are separated by `sep` (default ', ', blanks kept) and enclosed in the two
  !> characters of `brackets` if given. Names lose their trailing blanks; numbers are written
  !> as `str` writes them.
  interface join
    module procedure join_names, join_ints, join_reals
  end interface join

  !> An error with its message.
  type :: error_t
    character(len=:), allocatable :: message  !! what went wrong, naming the input and the bound
  end type error_t

contains

  !> Create an error with the given message.
  subroutine set_error(error, message)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in) :: message
    allocate (error)
    error%message = message
  end subroutine set_error

  !> Prefix an existing error with the name of the calling context.
  subroutine add_context(error, context)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: context
    if (allocated(error)) error%message = context//': '//error%message
  end subroutine add_context

  !> Print the message and stop with a non-zero exit code. Only programs call this.
  subroutine stop_on_error(error)
    type(error_t), allocatable, intent(in) :: error
    if (.not. allocated(error)) return
    write (error_unit, '(a)') 'kumo error: '//error%message
    error stop 1
  end subroutine stop_on_error

  pure function str_int(i) result(s)
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    character(len=24) :: buf
    write (buf, '(i0)') i
    s = trim(buf)
  end function str_int

  pure function str_int64(i) result(s)
    integer(int64), intent(in) :: i
    character(len=:), allocatable :: s
    character(len=24) :: buf
    write (buf, '(i0)') i
    s = trim(buf)
  end function str_int64

  !> Plain decimal form for moderate magnitudes, scientific form otherwise; 10 significant
  !> digits at most, or `digits` (x rounded to them, for logs), trailing zeros removed
  !> (0.01 -> '0.01', 2.5e-7 -> '2.5E-07', str(27.3456, 3) -> '27.3').
  pure function str_real(x, digits) result(s)
    real(real64), intent(in) :: x
    integer, intent(in), optional :: digits
    character(len=:), allocatable :: s
    character(len=40) :: buf
    integer :: ie, nd
    real(real64) :: v, scale
    v = x
    if (present(digits)) then
      if (abs(x) >= 1.0e-290_real64 .and. abs(x) <= huge(x)) then   ! scale stays finite
        scale = 10.0_real64**(digits - 1 - floor(log10(abs(x))))
        v = anint(x*scale)/scale
      end if
    end if
    if (ieee_is_nan(v)) then
      s = 'NaN'
      return
    end if
    if (v == 0.0_real64) then
      s = '0'
      return
    end if
    if (abs(v) >= 1.0e-4_real64 .and. abs(v) < 1.0e9_real64) then
      nd = max(0, 9 - int(floor(log10(abs(v)))))
      write (buf, '(f40.'//str_int(nd)//')') v
      s = trim(adjustl(buf))
      call strip_zeros(s)
    else if (abs(v) > huge(v)) then
      s = merge(' Inf', '-Inf', v > 0.0_real64)
      s = trim(adjustl(s))
    else
      write (buf, '(es18.9e3)') v
      s = trim(adjustl(buf))
      ie = index(s, 'E')
      read (s(ie + 1:), *) nd
      s = s(1:ie - 1)
      call strip_zeros(s)
      if (abs(nd) < 100) then
        write (buf, '(a,sp,i3.2)') 'E', nd
      else
        write (buf, '(a,sp,i0)') 'E', nd      ! three digits: i3.2 would print ***
      end if
      s = s//trim(buf)
    end if
  contains
    pure subroutine strip_zeros(t)
      character(len=:), allocatable, intent(inout) :: t
      if (index(t, '.') == 0) return
      do while (t(len(t):len(t)) == '0')
        t = t(1:len(t) - 1)
      end do
      if (t(len(t):len(t)) == '.') t = t(1:len(t) - 1)
    end subroutine strip_zeros
  end function str_real

  pure function join_names(items, sep, brackets) result(s)
    character(len=*), intent(in) :: items(:)            !! names; trailing blanks are dropped
    character(len=*), intent(in), optional :: sep       !! between two items; default ', '
    character(len=2), intent(in), optional :: brackets  !! opening and closing character
    character(len=:), allocatable :: s
    integer :: i
    s = ''
    do i = 1, size(items)
      if (i > 1) then
        if (present(sep)) then
          s = s//sep
        else
          s = s//', '
        end if
      end if
      s = s//trim(items(i))
    end do
    if (present(brackets)) s = brackets(1:1)//s//brackets(2:2)
  end function join_names

  pure function join_ints(items, sep, brackets) result(s)
    integer, intent(in) :: items(:)
    character(len=*), intent(in), optional :: sep
    character(len=2), intent(in), optional :: brackets
    character(len=:), allocatable :: s
    s = join_names(int_field(items), sep, brackets)
  end function join_ints

  pure function join_reals(items, sep, brackets) result(s)
    real(real64), intent(in) :: items(:)
    character(len=*), intent(in), optional :: sep
    character(len=2), intent(in), optional :: brackets
    character(len=:), allocatable :: s
    s = join_names(real_field(items), sep, brackets)
  end function join_reals

  !> `str(i)` in a field long enough for any default integer.
  elemental function int_field(i) result(field)
    integer, intent(in) :: i
    character(len=12) :: field
    field = str_int(i)
  end function int_field

  !> `str(x)` in a field long enough for any value it writes ('-0.0001234567891' is 16 long).
  elemental function real_field(x) result(field)
    real(real64), intent(in) :: x
    character(len=24) :: field
    field = str_real(x)
  end function real_field

  !> Lower-case copy of an ASCII string (namelist keywords are case-insensitive).
  pure function to_lower(s) result(t)
    character(len=*), intent(in) :: s
    character(len=len(s)) :: t
    integer :: i, c
    t = s
    do i = 1, len(s)
      c = iachar(s(i:i))
      if (c >= iachar('A') .and. c <= iachar('Z')) t(i:i) = achar(c + 32)
    end do
  end function to_lower
end module kumo_error
