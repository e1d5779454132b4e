! SPDX-License-Identifier: BSD-3-Clause
!> Rank 0's inputs for every rank: one pack-and-broadcast for what rank 0 alone reads.
!>
!> Rank 0 reads a file and puts what it read into a `bundle_t` (scalars, allocated allocatable
!> arrays of doubles and integers of rank 1 to 4, so that their bounds travel with them,
!> single-precision arrays of rank 3 (the voxel fields of cloud files, kept in single precision
!> so that the bundle is no larger than they are), logicals, text); `share` broadcasts the
!> bundle and rank 0's error, if the read failed, in up to five messages; every rank then takes
!> the items out in the order they were put in, each array with rank 0's bounds. Values travel
!> as they are (doubles as doubles, singles as singles), so every rank holds rank 0's bits. A
!> failed read gives every rank rank 0's message. With one rank (and in the serial build)
!> `share` moves nothing and `get` returns the values put in.
!>
!> ```fortran
!> type(bundle_t) :: b
!> if (par_is_root()) then
!>   call read_albedo_map(path, name, nx, ny, alb, error)
!>   if (.not. allocated(error)) call b%put(alb)
!> end if
!> call b%share(error)             ! every rank: rank 0's error, or none
!> if (allocated(error)) return
!> call b%get(alb)                 ! every rank: rank 0's array
!> ```
module kumo_bundle
  use kumo_kinds, only: dp, sp
  use kumo_error, only: error_t, set_error
  use kumo_parallel, only: par_size, par_is_root, par_bcast_int, par_bcast_real, par_bcast_text, &
                           par_bcast_single, PAR_ALL, PAR_LEADERS
  implicit none
  private
  public :: bundle_t

  !> Items put on rank 0, shared, then taken out in the same order on every rank. Integers hold
  !> each array's bounds before its values (integer arrays) or alone (real arrays); text items
  !> are concatenated with their lengths among the integers.
  type :: bundle_t
    private
    integer, allocatable :: ints(:)
    real(dp), allocatable :: reals(:)
    real(sp), allocatable :: singles(:)
    character(len=:), allocatable :: text
    integer :: ni = 0, nr = 0, nt = 0   !! filled lengths
    integer :: ki = 0, kr = 0, kt = 0   !! taken so far
    integer :: ns = 0, ks = 0           !! singles: filled, taken
  contains
    procedure, private :: put_r0, put_r1, put_r2, put_r3, put_r4
    procedure, private :: put_i0, put_i1, put_i2, put_i3, put_i4, put_l0, put_text, put_s3
    procedure, private :: get_r0, get_r1, get_r2, get_r3, get_r4
    procedure, private :: get_i0, get_i1, get_i2, get_i3, get_i4, get_l0, get_text, get_s3
    !> Add a value (rank 0; on other ranks a `put` before `share` is discarded by it).
    generic :: put => put_r0, put_r1, put_r2, put_r3, put_r4, put_i0, put_i1, put_i2, put_i3, &
                      put_i4, put_l0, put_text, put_s3
    !> Take the next value out, allocating arrays with rank 0's bounds.
    generic :: get => get_r0, get_r1, get_r2, get_r3, get_r4, get_i0, get_i1, get_i2, get_i3, &
                      get_i4, get_l0, get_text, get_s3
    procedure :: share
  end type bundle_t

contains

  !> Broadcast rank 0's bundle and its error status: on return every rank holds rank 0's items,
  !> or, when `error` was allocated on rank 0, an error with rank 0's message (rank 0 keeps its
  !> own error unchanged). Every rank must call it; `error` on ranks other than 0 is replaced.
  !> With `leaders` = .true. the bundle goes to the first rank of every node alone (those call
  !> it, the others do not): the node's one copy of a large input (kumo_parallel PAR_LEADERS).
  subroutine share(self, error, leaders)
    class(bundle_t), intent(inout) :: self
    type(error_t), allocatable, intent(inout) :: error
    logical, intent(in), optional :: leaders
    integer :: head(5), g
    character(len=:), allocatable :: message
    g = PAR_ALL
    if (present(leaders)) then
      if (leaders) g = PAR_LEADERS
    end if
    self%ki = 0
    self%kr = 0
    self%kt = 0
    self%ks = 0
    if (par_size() == 1) return
    head = 0
    if (par_is_root()) then
      if (allocated(error)) head(1) = 1
      head(2:5) = [self%ni, self%nr, self%nt, self%ns]
    end if
    call par_bcast_int(head, g)
    if (head(1) /= 0) then
      ! rank 0 failed: its message, nothing else
      if (par_is_root()) message = error%message
      call par_bcast_text(message, g)
      if (.not. par_is_root()) call set_error(error, message)
      return
    end if
    if (.not. par_is_root()) then
      if (allocated(error)) deallocate (error)
      self%ni = head(2)
      self%nr = head(3)
      self%nt = head(4)
      self%ns = head(5)
      if (allocated(self%ints)) deallocate (self%ints)
      if (allocated(self%reals)) deallocate (self%reals)
      if (allocated(self%singles)) deallocate (self%singles)
      if (allocated(self%text)) deallocate (self%text)
      allocate (self%ints(self%ni), self%reals(self%nr), self%singles(self%ns))
      allocate (character(len=self%nt) :: self%text)
    end if
    if (self%ni > 0) call par_bcast_int(self%ints(1:self%ni), g)
    if (self%nr > 0) call par_bcast_real(self%reals(1:self%nr), g)
    if (self%ns > 0) call par_bcast_single(self%singles(1:self%ns), g)
    if (self%nt > 0) then
      if (par_is_root()) self%text = self%text(1:self%nt)
      call par_bcast_text(self%text, g)
    end if
  end subroutine share

  ! ---- storage --------------------------------------------------------------------------------

  subroutine add_ints(self, v, n)
    class(bundle_t), intent(inout) :: self
    integer, intent(in) :: n
    integer, intent(in) :: v(n)
    integer, allocatable :: more(:)
    if (.not. allocated(self%ints)) allocate (self%ints(max(64, n)))
    if (self%ni + n > size(self%ints)) then
      allocate (more(max(2*size(self%ints), self%ni + n)))
      more(1:self%ni) = self%ints(1:self%ni)
      call move_alloc(more, self%ints)
    end if
    self%ints(self%ni + 1:self%ni + n) = v
    self%ni = self%ni + n
  end subroutine add_ints

  subroutine add_reals(self, v, n)
    class(bundle_t), intent(inout) :: self
    integer, intent(in) :: n
    real(dp), intent(in) :: v(n)
    real(dp), allocatable :: more(:)
    if (.not. allocated(self%reals)) allocate (self%reals(max(64, n)))
    if (self%nr + n > size(self%reals)) then
      allocate (more(max(2*size(self%reals), self%nr + n)))
      more(1:self%nr) = self%reals(1:self%nr)
      call move_alloc(more, self%reals)
    end if
    self%reals(self%nr + 1:self%nr + n) = v
    self%nr = self%nr + n
  end subroutine add_reals

  subroutine add_singles(self, v, n)
    class(bundle_t), intent(inout) :: self
    integer, intent(in) :: n
    real(sp), intent(in) :: v(n)
    real(sp), allocatable :: more(:)
    if (.not. allocated(self%singles)) allocate (self%singles(max(64, n)))
    if (self%ns + n > size(self%singles)) then
      allocate (more(max(2*size(self%singles), self%ns + n)))
      more(1:self%ns) = self%singles(1:self%ns)
      call move_alloc(more, self%singles)
    end if
    self%singles(self%ns + 1:self%ns + n) = v
    self%ns = self%ns + n
  end subroutine add_singles

  subroutine take_ints(self, v, n)
    class(bundle_t), intent(inout) :: self
    integer, intent(in) :: n
    integer, intent(out) :: v(n)
    v = self%ints(self%ki + 1:self%ki + n)
    self%ki = self%ki + n
  end subroutine take_ints

  subroutine take_reals(self, v, n)
    class(bundle_t), intent(inout) :: self
    integer, intent(in) :: n
    real(dp), intent(out) :: v(n)
    v = self%reals(self%kr + 1:self%kr + n)
    self%kr = self%kr + n
  end subroutine take_reals

  subroutine take_singles(self, v, n)
    class(bundle_t), intent(inout) :: self
    integer, intent(in) :: n
    real(sp), intent(out) :: v(n)
    v = self%singles(self%ks + 1:self%ks + n)
    self%ks = self%ks + n
  end subroutine take_singles

  !> The bounds of the next array: `r` pairs (lower, upper).
  subroutine take_bounds(self, r, lo, hi)
    class(bundle_t), intent(inout) :: self
    integer, intent(in) :: r
    integer, intent(out) :: lo(r), hi(r)
    integer :: b(2*r)
    call take_ints(self, b, 2*r)
    lo = b(1:2*r:2)
    hi = b(2:2*r:2)
  end subroutine take_bounds

  subroutine put_bounds(self, lo, hi)
    class(bundle_t), intent(inout) :: self
    integer, intent(in) :: lo(:), hi(:)
    integer :: b(2*size(lo))
    b(1:size(b):2) = lo
    b(2:size(b):2) = hi
    call add_ints(self, b, size(b))
  end subroutine put_bounds

  ! ---- put --------------------------------------------------------------------------------------

  subroutine put_r0(self, x)
    class(bundle_t), intent(inout) :: self
    real(dp), intent(in) :: x
    call add_reals(self, [x], 1)
  end subroutine put_r0

  subroutine put_r1(self, x)
    class(bundle_t), intent(inout) :: self
    real(dp), allocatable, intent(in) :: x(:)
    call put_bounds(self, lbound(x), ubound(x))
    call add_reals(self, x, size(x))
  end subroutine put_r1

  subroutine put_r2(self, x)
    class(bundle_t), intent(inout) :: self
    real(dp), allocatable, intent(in) :: x(:, :)
    call put_bounds(self, lbound(x), ubound(x))
    call add_reals(self, x, size(x))
  end subroutine put_r2

  subroutine put_r3(self, x)
    class(bundle_t), intent(inout) :: self
    real(dp), allocatable, intent(in) :: x(:, :, :)
    call put_bounds(self, lbound(x), ubound(x))
    call add_reals(self, x, size(x))
  end subroutine put_r3

  subroutine put_r4(self, x)
    class(bundle_t), intent(inout) :: self
    real(dp), allocatable, intent(in) :: x(:, :, :, :)
    call put_bounds(self, lbound(x), ubound(x))
    call add_reals(self, x, size(x))
  end subroutine put_r4

  subroutine put_s3(self, x)
    class(bundle_t), intent(inout) :: self
    real(sp), allocatable, intent(in) :: x(:, :, :)
    call put_bounds(self, lbound(x), ubound(x))
    call add_singles(self, x, size(x))
  end subroutine put_s3

  subroutine put_i0(self, x)
    class(bundle_t), intent(inout) :: self
    integer, intent(in) :: x
    call add_ints(self, [x], 1)
  end subroutine put_i0

  subroutine put_i1(self, x)
    class(bundle_t), intent(inout) :: self
    integer, allocatable, intent(in) :: x(:)
    call put_bounds(self, lbound(x), ubound(x))
    call add_ints(self, x, size(x))
  end subroutine put_i1

  subroutine put_i2(self, x)
    class(bundle_t), intent(inout) :: self
    integer, allocatable, intent(in) :: x(:, :)
    call put_bounds(self, lbound(x), ubound(x))
    call add_ints(self, x, size(x))
  end subroutine put_i2

  subroutine put_i3(self, x)
    class(bundle_t), intent(inout) :: self
    integer, allocatable, intent(in) :: x(:, :, :)
    call put_bounds(self, lbound(x), ubound(x))
    call add_ints(self, x, size(x))
  end subroutine put_i3

  subroutine put_i4(self, x)
    class(bundle_t), intent(inout) :: self
    integer, allocatable, intent(in) :: x(:, :, :, :)
    call put_bounds(self, lbound(x), ubound(x))
    call add_ints(self, x, size(x))
  end subroutine put_i4

  subroutine put_l0(self, x)
    class(bundle_t), intent(inout) :: self
    logical, intent(in) :: x
    call add_ints(self, [merge(1, 0, x)], 1)
  end subroutine put_l0

  subroutine put_text(self, x)
    class(bundle_t), intent(inout) :: self
    character(len=*), intent(in) :: x
    character(len=:), allocatable :: more
    call add_ints(self, [len(x)], 1)
    if (.not. allocated(self%text)) allocate (character(len=max(256, len(x))) :: self%text)
    if (self%nt + len(x) > len(self%text)) then
      allocate (character(len=max(2*len(self%text), self%nt + len(x))) :: more)
      more(1:self%nt) = self%text(1:self%nt)
      call move_alloc(more, self%text)
    end if
    self%text(self%nt + 1:self%nt + len(x)) = x
    self%nt = self%nt + len(x)
  end subroutine put_text

  ! ---- get --------------------------------------------------------------------------------------

  subroutine get_r0(self, x)
    class(bundle_t), intent(inout) :: self
    real(dp), intent(out) :: x
    real(dp) :: v(1)
    call take_reals(self, v, 1)
    x = v(1)
  end subroutine get_r0

  subroutine get_r1(self, x)
    class(bundle_t), intent(inout) :: self
    real(dp), allocatable, intent(out) :: x(:)
    integer :: lo(1), hi(1)
    call take_bounds(self, 1, lo, hi)
    allocate (x(lo(1):hi(1)))
    call take_reals(self, x, size(x))
  end subroutine get_r1

  subroutine get_r2(self, x)
    class(bundle_t), intent(inout) :: self
    real(dp), allocatable, intent(out) :: x(:, :)
    integer :: lo(2), hi(2)
    call take_bounds(self, 2, lo, hi)
    allocate (x(lo(1):hi(1), lo(2):hi(2)))
    call take_reals(self, x, size(x))
  end subroutine get_r2

  subroutine get_r3(self, x)
    class(bundle_t), intent(inout) :: self
    real(dp), allocatable, intent(out) :: x(:, :, :)
    integer :: lo(3), hi(3)
    call take_bounds(self, 3, lo, hi)
    allocate (x(lo(1):hi(1), lo(2):hi(2), lo(3):hi(3)))
    call take_reals(self, x, size(x))
  end subroutine get_r3

  subroutine get_r4(self, x)
    class(bundle_t), intent(inout) :: self
    real(dp), allocatable, intent(out) :: x(:, :, :, :)
    integer :: lo(4), hi(4)
    call take_bounds(self, 4, lo, hi)
    allocate (x(lo(1):hi(1), lo(2):hi(2), lo(3):hi(3), lo(4):hi(4)))
    call take_reals(self, x, size(x))
  end subroutine get_r4

  subroutine get_s3(self, x)
    class(bundle_t), intent(inout) :: self
    real(sp), allocatable, intent(out) :: x(:, :, :)
    integer :: lo(3), hi(3)
    call take_bounds(self, 3, lo, hi)
    allocate (x(lo(1):hi(1), lo(2):hi(2), lo(3):hi(3)))
    call take_singles(self, x, size(x))
  end subroutine get_s3

  subroutine get_i0(self, x)
    class(bundle_t), intent(inout) :: self
    integer, intent(out) :: x
    integer :: v(1)
    call take_ints(self, v, 1)
    x = v(1)
  end subroutine get_i0

  subroutine get_i1(self, x)
    class(bundle_t), intent(inout) :: self
    integer, allocatable, intent(out) :: x(:)
    integer :: lo(1), hi(1)
    call take_bounds(self, 1, lo, hi)
    allocate (x(lo(1):hi(1)))
    call take_ints(self, x, size(x))
  end subroutine get_i1

  subroutine get_i2(self, x)
    class(bundle_t), intent(inout) :: self
    integer, allocatable, intent(out) :: x(:, :)
    integer :: lo(2), hi(2)
    call take_bounds(self, 2, lo, hi)
    allocate (x(lo(1):hi(1), lo(2):hi(2)))
    call take_ints(self, x, size(x))
  end subroutine get_i2

  subroutine get_i3(self, x)
    class(bundle_t), intent(inout) :: self
    integer, allocatable, intent(out) :: x(:, :, :)
    integer :: lo(3), hi(3)
    call take_bounds(self, 3, lo, hi)
    allocate (x(lo(1):hi(1), lo(2):hi(2), lo(3):hi(3)))
    call take_ints(self, x, size(x))
  end subroutine get_i3

  subroutine get_i4(self, x)
    class(bundle_t), intent(inout) :: self
    integer, allocatable, intent(out) :: x(:, :, :, :)
    integer :: lo(4), hi(4)
    call take_bounds(self, 4, lo, hi)
    allocate (x(lo(1):hi(1), lo(2):hi(2), lo(3):hi(3), lo(4):hi(4)))
    call take_ints(self, x, size(x))
  end subroutine get_i4

  subroutine get_l0(self, x)
    class(bundle_t), intent(inout) :: self
    logical, intent(out) :: x
    integer :: v(1)
    call take_ints(self, v, 1)
    x = v(1) /= 0
  end subroutine get_l0

  subroutine get_text(self, x)
    class(bundle_t), intent(inout) :: self
    character(len=:), allocatable, intent(out) :: x
    integer :: n(1)
    call take_ints(self, n, 1)
    x = self%text(self%kt + 1:self%kt + n(1))
    self%kt = self%kt + n(1)
  end subroutine get_text

end module kumo_bundle
