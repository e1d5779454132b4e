! SPDX-License-Identifier: BSD-3-Clause
!> A set of named results (mean and standard error on named dimensions) and global attributes.
!>
!> kumo_output fills a `result_set_t`; the netCDF writer turns it into a file. Nothing here
!> knows about netCDF, so the layout of the output is decided in one place (kumo_output) and
!> written generically.
module kumo_results
  use kumo_kinds, only: dp
  use kumo_error, only: str
  implicit none
  private
  public :: result_dim_t, result_var_t, result_attr_t, result_set_t
  public :: add_dim, add_var, add_attr, add_num_attr, find_var, find_dim

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

  !> Add a variable; `stderr` may be omitted for exact (non-statistical) quantities.
  subroutine add_var(set, name, long_name, units, dim_names, mean, stderr)
    type(result_set_t), intent(inout) :: set
    character(len=*), intent(in) :: name, long_name, units
    character(len=*), intent(in) :: dim_names(:)
    real(dp), intent(in) :: mean(:)
    real(dp), intent(in), optional :: stderr(:)
    type(result_var_t) :: v
    v%name = name
    v%long_name = long_name
    v%units = units
    v%ndims = size(dim_names)
    v%dim_names(1:v%ndims) = dim_names
    v%mean = mean
    if (present(stderr)) v%stderr = stderr
    if (.not. allocated(set%vars)) allocate (set%vars(0))
    set%vars = [set%vars, v]
  end subroutine add_var

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
