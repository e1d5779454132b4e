! SPDX-License-Identifier: BSD-3-Clause
!> Text helpers shared by the tests that read reference tables, and the path of the shared
!> reference-data folder (CTest passes it as the first command-line argument).
module kumo_test_text
  use kumo_kinds, only: wp
  use kumo_textio, only: read_two_columns
  use kumo_testing, only: error_t, check
  implicit none
  private
  public :: split, read_table, shared_dir, set_shared_dir

  !> The shared data folder (data/, reference/), set from the command line.
  character(len=:), allocatable :: shared_dir

contains

  !> Set the shared data folder.
  subroutine set_shared_dir(path)
    character(len=*), intent(in) :: path
    shared_dir = path
  end subroutine set_shared_dir

  !> Split `s` at every `sep` into `fields(1:n)` (empty fields kept; fields beyond the size of
  !> `fields` are counted but not stored).
  subroutine split(s, sep, fields, n)
    character(len=*), intent(in) :: s
    character(len=1), intent(in) :: sep
    character(len=*), intent(inout) :: fields(:)
    integer, intent(out) :: n
    integer :: i0, i, ls
    n = 0
    i0 = 1
    fields = ''
    ls = len_trim(s)
    do i = 1, ls + 1
      if (i <= ls) then
        if (s(i:i) /= sep) cycle
      end if
      n = n + 1
      if (n <= size(fields)) fields(n) = s(i0:i - 1)
      i0 = i + 1
    end do
  end subroutine split

  !> Read a two-column table with kumo's own reader; a failure becomes the test's error.
  subroutine read_table(path, angle, value, error)
    character(len=*), intent(in) :: path
    real(wp), allocatable, intent(out) :: angle(:), value(:)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable :: err
    call read_two_columns(path, angle, value, err)
    if (allocated(err)) call check(error, .false., err%message)
  end subroutine read_table
end module kumo_test_text
