! SPDX-License-Identifier: BSD-3-Clause
!> A set of named results (mean and standard error on named dimensions) and global attributes.
!>
!> kumo_output fills a `result_set_t`; the netCDF writer turns it into a file. Nothing here
!> knows about netCDF, so the layout of the output is decided in one place (kumo_output) and
!> written generically.
!>
!> A large product can be deferred (defer_var): the set then keeps the batch sums of the
!> tallies (keep_sums) and the variable only says which entries of them it is formed from and
!> with which factors; its values are formed piece by piece when they are written (var_values),
!> so a run's output never holds a copy of its per-column or per-voxel products.
!> materialize_vars forms them all, for code that reads a set's values.
module kumo_results
  use kumo_kinds, only: dp, i8
  use kumo_error, only: str
  use kumo_tally, only: stats_t, stats_mean, stats_stderr
  implicit none
  private
  public :: result_dim_t, result_var_t, result_attr_t, result_set_t
  public :: add_dim, add_var, take_var, add_attr, add_num_attr, find_var, find_dim, result_values_bytes
  public :: defer_var, keep_sums, var_size, var_has_stderr, var_values, materialize_vars

  integer, parameter :: NAME_LEN = 64

  !> A dimension of the output, optionally with a coordinate variable.
  type :: result_dim_t
    character(len=NAME_LEN) :: name = ''             !! dimension name
    integer :: size = 0                              !! number of entries
    real(dp), allocatable :: coord(:)                !! coordinate values (written if allocated)
    character(len=:), allocatable :: units           !! units of the coordinate
    character(len=:), allocatable :: long_name       !! description of the coordinate
    character(len=:), allocatable :: standard_name   !! CF standard name of the coordinate
    character(len=1) :: axis = ' '                   !! CF axis of the coordinate ('Z': a height, positive up)
  end type result_dim_t

  !> One output quantity: mean and standard error, flattened in Fortran order of its dims.
  type :: result_var_t
    character(len=NAME_LEN) :: name = ''             !! variable name
    character(len=:), allocatable :: long_name       !! description (CF long_name)
    character(len=:), allocatable :: units           !! CF units string
    integer :: ndims = 0                             !! number of dimensions (0 = scalar)
    character(len=NAME_LEN) :: dim_names(4) = ''     !! dimension names, first varies fastest
    real(dp), allocatable :: mean(:)                 !! mean over batches
    real(dp), allocatable :: stderr(:)               !! standard error of the mean (if allocated)
    character(len=:), allocatable :: standard_name   !! CF standard name (if allocated)
    character(len=:), allocatable :: coordinates     !! CF auxiliary/scalar coordinates (if allocated)
    ! A deferred variable (src_lo >= 0) has no `mean` and `stderr`: its values are the entries
    ! src_lo + 1 .. src_lo + n_src of the set's sums (mean and standard error over the batches),
    ! those of block k (`block` entries each) times fac_a(k) and then times fac_b(k) when these
    ! are allocated.
    integer :: src_lo = -1                           !! first entry - 1 in the sums (-1: not deferred)
    integer :: n_src = 0                             !! number of values
    integer :: block = 1                             !! entries per factor
    real(dp), allocatable :: fac_a(:), fac_b(:)      !! factors per block, applied in this order
  end type result_var_t

  !> A global attribute: text, or a number when `num` is allocated (then `value` holds the
  !> number as text too, for code that reads attributes as text).
  type :: result_attr_t
    character(len=NAME_LEN) :: name = ''             !! attribute name
    character(len=:), allocatable :: value           !! attribute text
    real(dp), allocatable :: num(:)                  !! numeric value (written as a number)
  end type result_attr_t

  !> Everything that goes into one output file.
  type :: result_set_t
    type(result_dim_t), allocatable :: dims(:)
    type(result_var_t), allocatable :: vars(:)
    type(result_attr_t), allocatable :: attrs(:)
    integer :: deflate = 0                           !! deflate level of the variables (0: none)
    type(stats_t) :: sums                            !! the batch sums of deferred variables
  end type result_set_t

contains

  !> Add a dimension (with optional coordinate values).
  subroutine add_dim(set, name, size, coord, units, long_name)
    type(result_set_t), intent(inout) :: set
    character(len=*), intent(in) :: name
    integer, intent(in) :: size
    real(dp), intent(in), optional :: coord(:)
    character(len=*), intent(in), optional :: units, long_name
    type(result_dim_t) :: d
    d%name = name
    d%size = size
    if (present(coord)) d%coord = coord
    d%units = ''
    if (present(units)) d%units = units
    d%long_name = ''
    if (present(long_name)) d%long_name = long_name
    if (.not. allocated(set%dims)) allocate (set%dims(0))
    set%dims = [set%dims, d]
  end subroutine add_dim

  !> Add a variable; `stderr` may be omitted for exact (non-statistical) quantities. The values
  !> are copied (see take_var for large arrays).
  subroutine add_var(set, name, long_name, units, dim_names, mean, stderr)
    type(result_set_t), intent(inout) :: set
    character(len=*), intent(in) :: name, long_name, units
    character(len=*), intent(in) :: dim_names(:)
    real(dp), intent(in) :: mean(:)
    real(dp), intent(in), optional :: stderr(:)
    type(result_var_t) :: v
    call describe_var(v, name, long_name, units, dim_names)
    v%mean = mean
    if (present(stderr)) v%stderr = stderr
    call push_var(set, v)
  end subroutine add_var

  !> Add a variable whose values are moved in, not copied: `mean` (and `stderr`) are
  !> deallocated on return. For the large per-column and per-voxel products, so that a result
  !> set never holds a second copy of them.
  subroutine take_var(set, name, long_name, units, dim_names, mean, stderr)
    type(result_set_t), intent(inout) :: set
    character(len=*), intent(in) :: name, long_name, units
    character(len=*), intent(in) :: dim_names(:)
    real(dp), allocatable, intent(inout) :: mean(:)
    real(dp), allocatable, intent(inout), optional :: stderr(:)
    type(result_var_t) :: v
    call describe_var(v, name, long_name, units, dim_names)
    call move_alloc(mean, v%mean)
    if (present(stderr)) call move_alloc(stderr, v%stderr)
    call push_var(set, v)
  end subroutine take_var

  !> Add a deferred variable (see the module's text): the values are entries lo + 1 .. lo + n of
  !> the sums that keep_sums will give the set, block k of `block` entries times fac_a(k) and
  !> then fac_b(k) when present; with a standard error.
  subroutine defer_var(set, name, long_name, units, dim_names, lo, n, block, fac_a, fac_b)
    type(result_set_t), intent(inout) :: set
    character(len=*), intent(in) :: name, long_name, units
    character(len=*), intent(in) :: dim_names(:)
    integer, intent(in) :: lo, n
    integer, intent(in), optional :: block
    real(dp), intent(in), optional :: fac_a(:), fac_b(:)
    type(result_var_t) :: v
    call describe_var(v, name, long_name, units, dim_names)
    v%src_lo = lo
    v%n_src = n
    if (present(block)) v%block = block
    if (present(fac_a)) v%fac_a = fac_a
    if (present(fac_b)) v%fac_b = fac_b
    call push_var(set, v)
  end subroutine defer_var

  !> The set takes the sums of the tallies (moved, not copied) for its deferred variables.
  subroutine keep_sums(set, st)
    type(result_set_t), intent(inout) :: set
    type(stats_t), intent(inout) :: st
    call move_alloc(st%s1, set%sums%s1)
    call move_alloc(st%s2, set%sums%s2)
    set%sums%n_batches = st%n_batches
    set%sums%n_photons = st%n_photons
  end subroutine keep_sums

  !> Number of values of a variable.
  pure integer function var_size(v) result(n)
    type(result_var_t), intent(in) :: v
    n = 0
    if (v%src_lo >= 0) then
      n = v%n_src
    else if (allocated(v%mean)) then
      n = size(v%mean)
    end if
  end function var_size

  !> Whether a variable has standard errors (deferred variables always have).
  pure logical function var_has_stderr(v)
    type(result_var_t), intent(in) :: v
    var_has_stderr = v%src_lo >= 0 .or. allocated(v%stderr)
  end function var_has_stderr

  !> Values j0 + 1 .. j0 + size(mean) of variable iv (flattened, Fortran order of its dims), and
  !> their standard errors, formed from the sums if the variable is deferred.
  subroutine var_values(set, iv, j0, mean, stderr)
    type(result_set_t), intent(in) :: set
    integer, intent(in) :: iv, j0
    real(dp), intent(out), optional, contiguous :: mean(:), stderr(:)
    integer :: lo, hi
    associate (v => set%vars(iv))
      if (v%src_lo < 0) then
        if (present(mean)) mean = v%mean(j0 + 1:j0 + size(mean))
        if (present(stderr)) stderr = v%stderr(j0 + 1:j0 + size(stderr))
        return
      end if
      lo = v%src_lo + j0 + 1
      if (present(mean)) then
        hi = lo + size(mean) - 1
        mean = stats_mean(set%sums, lo, hi)
        call apply_factors(v, j0, mean)
      end if
      if (present(stderr)) then
        hi = lo + size(stderr) - 1
        stderr = stats_stderr(set%sums, lo, hi)
        call apply_factors(v, j0, stderr)
      end if
    end associate
  end subroutine var_values

  !> Values j0 + 1 .. of deferred variable `v`: times fac_a, then times fac_b, of their block.
  pure subroutine apply_factors(v, j0, x)
    type(result_var_t), intent(in) :: v
    integer, intent(in) :: j0
    real(dp), intent(inout), contiguous :: x(:)
    if (allocated(v%fac_a)) call by_block(v%fac_a, x)
    if (allocated(v%fac_b)) call by_block(v%fac_b, x)
  contains
    !> y(j) times f of the block of value j0 + j, one block's run of values at a time
    pure subroutine by_block(f, y)
      real(dp), intent(in) :: f(:)
      real(dp), intent(inout) :: y(:)
      integer :: j, je, k
      j = 1
      do while (j <= size(y))
        k = (j0 + j - 1)/v%block + 1
        je = min(size(y), k*v%block - j0)
        y(j:je) = y(j:je)*f(k)
        j = je + 1
      end do
    end subroutine by_block
  end subroutine apply_factors

  !> Form the values of every deferred variable and let the set drop the sums: for code that
  !> reads the values of a set (the tests, a program that calls kumo as a library).
  subroutine materialize_vars(set)
    type(result_set_t), intent(inout) :: set
    real(dp), allocatable :: m(:), e(:)
    integer :: i
    if (.not. allocated(set%vars)) return
    do i = 1, size(set%vars)
      associate (v => set%vars(i))
        if (v%src_lo < 0) cycle
        allocate (m(v%n_src), e(v%n_src))
        call var_values(set, i, 0, m, e)
        call move_alloc(m, v%mean)
        call move_alloc(e, v%stderr)
        v%src_lo = -1
        v%n_src = 0
        if (allocated(v%fac_a)) deallocate (v%fac_a)
        if (allocated(v%fac_b)) deallocate (v%fac_b)
      end associate
    end do
    if (allocated(set%sums%s1)) deallocate (set%sums%s1)
    if (allocated(set%sums%s2)) deallocate (set%sums%s2)
  end subroutine materialize_vars

  !> Bytes of the values a result set holds (means, standard errors, coordinates).
  pure integer(i8) function result_values_bytes(set) result(nb)
    type(result_set_t), intent(in) :: set
    integer :: i
    nb = 0_i8
    if (allocated(set%vars)) then
      do i = 1, size(set%vars)
        if (allocated(set%vars(i)%mean)) nb = nb + &
          storage_size(set%vars(i)%mean, i8)/8*size(set%vars(i)%mean, kind=i8)
        if (allocated(set%vars(i)%stderr)) nb = nb + &
          storage_size(set%vars(i)%stderr, i8)/8*size(set%vars(i)%stderr, kind=i8)
      end do
    end if
    if (allocated(set%dims)) then
      do i = 1, size(set%dims)
        if (allocated(set%dims(i)%coord)) nb = nb + &
          storage_size(set%dims(i)%coord, i8)/8*size(set%dims(i)%coord, kind=i8)
      end do
    end if
  end function result_values_bytes

  subroutine describe_var(v, name, long_name, units, dim_names)
    type(result_var_t), intent(inout) :: v
    character(len=*), intent(in) :: name, long_name, units
    character(len=*), intent(in) :: dim_names(:)
    v%name = name
    v%long_name = long_name
    v%units = units
    v%ndims = size(dim_names)
    v%dim_names(1:v%ndims) = dim_names
  end subroutine describe_var

  !> Append `v` to the set's variables, moving the values of every variable (never copying
  !> them: an array constructor [set%vars, v] would hold the whole set twice, briefly three
  !> times). `v` is taken apart.
  subroutine push_var(set, v)
    type(result_set_t), intent(inout) :: set
    type(result_var_t), intent(inout) :: v
    type(result_var_t), allocatable :: grown(:)
    integer :: i, n
    n = 0
    if (allocated(set%vars)) n = size(set%vars)
    allocate (grown(n + 1))
    do i = 1, n
      call move_var(set%vars(i), grown(i))
    end do
    call move_var(v, grown(n + 1))
    call move_alloc(grown, set%vars)
  end subroutine push_var

  !> Move every component of `a` into `b` (the arrays by move_alloc).
  subroutine move_var(a, b)
    type(result_var_t), intent(inout) :: a, b
    b%name = a%name
    if (allocated(a%long_name)) call move_alloc(a%long_name, b%long_name)
    if (allocated(a%units)) call move_alloc(a%units, b%units)
    b%ndims = a%ndims
    b%dim_names = a%dim_names
    b%src_lo = a%src_lo
    b%n_src = a%n_src
    b%block = a%block
    if (allocated(a%fac_a)) call move_alloc(a%fac_a, b%fac_a)
    if (allocated(a%fac_b)) call move_alloc(a%fac_b, b%fac_b)
    if (allocated(a%mean)) call move_alloc(a%mean, b%mean)
    if (allocated(a%stderr)) call move_alloc(a%stderr, b%stderr)
    if (allocated(a%standard_name)) call move_alloc(a%standard_name, b%standard_name)
    if (allocated(a%coordinates)) call move_alloc(a%coordinates, b%coordinates)
  end subroutine move_var

  !> Add a global text attribute.
  subroutine add_attr(set, name, value)
    type(result_set_t), intent(inout) :: set
    character(len=*), intent(in) :: name, value
    type(result_attr_t) :: a
    a%name = name
    a%value = value
    if (.not. allocated(set%attrs)) allocate (set%attrs(0))
    set%attrs = [set%attrs, a]
  end subroutine add_attr

  !> Add a numeric global attribute.
  subroutine add_num_attr(set, name, value)
    type(result_set_t), intent(inout) :: set
    character(len=*), intent(in) :: name
    real(dp), intent(in) :: value
    type(result_attr_t) :: a
    a%name = name
    a%num = [value]
    a%value = str(value)
    if (.not. allocated(set%attrs)) allocate (set%attrs(0))
    set%attrs = [set%attrs, a]
  end subroutine add_num_attr

  !> Index of the dimension with the given name, 0 if absent.
  pure integer function find_dim(set, name) result(idx)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: name
    integer :: i
    idx = 0
    if (.not. allocated(set%dims)) return
    do i = 1, size(set%dims)
      if (trim(set%dims(i)%name) == trim(name)) then
        idx = i
        return
      end if
    end do
  end function find_dim

  !> Index of the variable with the given name, 0 if absent.
  pure integer function find_var(set, name) result(idx)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: name
    integer :: i
    idx = 0
    if (.not. allocated(set%vars)) return
    do i = 1, size(set%vars)
      if (trim(set%vars(i)%name) == trim(name)) then
        idx = i
        return
      end if
    end do
  end function find_var
end module kumo_results
