! SPDX-License-Identifier: BSD-3-Clause
!> bundle_t: rank 0's items reach every rank with their bounds and bits, in the order put;
!> rank 0's error reaches every rank with its message; an empty bundle shares nothing; and the
!> grid of a cloud file read through load_config (on rank 0 alone) reaches every rank. Run on
!> several ranks in MPI builds (and alone in serial builds, where share moves nothing).
module test_bundle_suite
  use kumo_kinds, only: dp
  use kumo_error, only: error_t, set_error, str
  use kumo_testing, only: unittest_t, new_unittest, check
  use kumo_parallel, only: par_is_root, par_rank, par_size
  use kumo_bundle, only: bundle_t
  use kumo_config, only: config_t
  use kumo_scene_setup, only: load_config
  implicit none
  private
  public :: collect_bundle

contains

  function collect_bundle() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('items_bounds_bits', t_items), &
             new_unittest('root_error_everywhere', t_error), &
             new_unittest('empty_bundle', t_empty), &
             new_unittest('cloud_grid_via_load_config', t_cloud_grid)]
  end function collect_bundle

  !> Every kind of item, with bounds other than 1 and values that round-trip only bit for bit;
  !> ranks other than 0 start with other values, and put values that share must discard.
  subroutine t_items(error)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: b
    real(dp), allocatable :: r1(:), r2(:, :), r3(:, :, :), r4(:, :, :, :)
    integer, allocatable :: i1(:), i2(:, :), i3(:, :, :), i4(:, :, :, :)
    real(dp) :: r0
    integer :: i0, k
    logical :: l0, l1
    character(len=:), allocatable :: t1, t2, t3
    type(error_t), allocatable :: err
    if (par_is_root()) then
      ! allocated first: an assignment to an unallocated array would take bounds 1
      allocate (r1(0:5), r3(1:2, -1:0, 2:3), i1(-2:1))
      r1 = ref_r1()
      r2 = reshape(ref_r1(), [3, 2])
      r3 = ref_r3()
      r4 = reshape([(real(k, dp)*0.1_dp, k=1, 16)], [2, 2, 2, 2])
      i1 = ref_i1()
      i2 = reshape([(k, k=1, 6)], [2, 3])
      i3 = reshape([(k, k=1, 8)], [2, 2, 2])
      i4 = reshape([(k, k=1, 16)], [2, 2, 2, 2])
      call b%put(1.0_dp/3.0_dp)
      call b%put(r1)
      call b%put(r2)
      call b%put(r3)
      call b%put(r4)
      call b%put(-7)
      call b%put(i1)
      call b%put(i2)
      call b%put(i3)
      call b%put(i4)
      call b%put(.true.)
      call b%put('grid of "x"'//new_line('a')//'line 2')
      call b%put('')
      call b%put(.false.)
      call b%put(repeat('z', 300))
    else
      call b%put(99.0_dp)   ! discarded by share
    end if
    call b%share(err)
    call check(error, .not. allocated(err), 'share with no error on rank 0 gave one on rank '// &
               str(par_rank()))
    if (allocated(error)) return
    call b%get(r0)
    call b%get(r1)
    call b%get(r2)
    call b%get(r3)
    call b%get(r4)
    call b%get(i0)
    call b%get(i1)
    call b%get(i2)
    call b%get(i3)
    call b%get(i4)
    call b%get(l0)
    call b%get(t1)
    call b%get(t2)
    call b%get(l1)
    call b%get(t3)
    call check(error, r0 == 1.0_dp/3.0_dp, 'real scalar')
    call check(error, lbound(r1, 1) == 0 .and. ubound(r1, 1) == 5, 'bounds of a (0:5) array: '// &
               str(lbound(r1, 1))//':'//str(ubound(r1, 1)))
    if (allocated(error)) return
    call check(error, all(r1 == ref_r1()), 'values of a real array')
    call check(error, all(shape(r2) == [3, 2]) .and. all(r2 == reshape(ref_r1(), [3, 2])), &
               'real rank 2')
    call check(error, all(lbound(r3) == [1, -1, 2]) .and. all(r3 == ref_r3()), 'real rank 3 (bounds)')
    call check(error, all(shape(r4) == [2, 2, 2, 2]) .and. r4(2, 2, 2, 2) == 16.0_dp*0.1_dp, 'real rank 4')
    call check(error, i0 == -7, 'integer scalar')
    call check(error, lbound(i1, 1) == -2 .and. all(i1 == ref_i1()), 'integer (-2:1) array')
    call check(error, all(shape(i2) == [2, 3]) .and. i2(2, 3) == 6, 'integer rank 2')
    call check(error, sum(i3) == 36 .and. i3(2, 2, 2) == 8, 'integer rank 3')
    call check(error, sum(i4) == 136, 'integer rank 4')
    call check(error, l0 .and. .not. l1, 'logicals')
    call check(error, t1 == 'grid of "x"'//new_line('a')//'line 2' .and. len(t2) == 0 .and. &
               t3 == repeat('z', 300), 'texts')
  end subroutine t_items

  !> Rank 0's read failed: every rank gets its message, and no items.
  subroutine t_error(error)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: b
    type(error_t), allocatable :: err
    if (par_is_root()) then
      call b%put(1)
      call set_error(err, 'cannot open "scene.nc": No such file')
    else
      call set_error(err, 'a stale error of this rank')
    end if
    call b%share(err)
    call check(error, allocated(err), 'rank '//str(par_rank())//' got no error')
    if (allocated(error)) return
    call check(error, err%message == 'cannot open "scene.nc": No such file', 'rank '// &
               str(par_rank())//' got the message "'//err%message//'"')
  end subroutine t_error

  !> Nothing put: share and no get; a second share of the same bundle after items is fine.
  subroutine t_empty(error)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: b
    type(error_t), allocatable :: err
    integer :: n
    call b%share(err)
    call check(error, .not. allocated(err), 'empty bundle: an error')
    if (allocated(error)) return
    if (par_is_root()) call b%put(par_size())
    call b%share(err)
    call b%get(n)
    call check(error, n == par_size(), 'second share: '//str(n))
  end subroutine t_empty

  !> load_config with a cloud file: every rank has the file's grid (2 x 2 columns of 100 m,
  !> edges 500, 550, 600 m below which one layer from the ground is added), although only rank
  !> 0 opened the file.
  subroutine t_cloud_grid(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(error_t), allocatable :: err
    integer :: unit
    if (par_is_root()) then
      ! a 2-parameter SHDOM/I3RC LWC file: nx ny nz, dx dy [km], the nz + 1 layer edges [km],
      ! their temperatures, then ix iy iz lwc reff
      open (newunit=unit, file='bundle_cloud.lwc', status='replace', action='write')
      write (unit, '(a)') '2 parameter LWC file'
      write (unit, '(a)') '2 2 2'
      write (unit, '(a)') '0.1 0.1'
      write (unit, '(a)') '0.50 0.55 0.60'
      write (unit, '(a)') '285 284 283'
      write (unit, '(a)') '1 1 1 0.1 10.0'
      close (unit)
    end if
    ! the namelist as text (as run_case passes it); only rank 0 opens the cloud file, and
    ! load_config's broadcast orders it after the write above
    call load_config('bundle_cloud.nml', cfg, err, text= &
                     "&kumo_cloud cloud_file = 'bundle_cloud.lwc', cloud_format = 'lwc' /"// &
                     new_line('a')//"&kumo_source wavelength_um = 0.55 /"//new_line('a'))
    call check(error, .not. allocated(err), 'load_config failed: '//merge_message(err))
    if (allocated(error)) return
    call check(error, cfg%cloud%grid%nx == 2 .and. cfg%cloud%grid%ny == 2 .and. &
               cfg%cloud%grid%nz == 2, 'grid sizes on rank '//str(par_rank()))
    call check(error, cfg%atm%nz == 3 .and. abs(cfg%atm%z(1 + 3) - 600.0_dp) < 1.0e-6_dp, &
               'levels on rank '//str(par_rank())//': nz = '//str(cfg%atm%nz))
    call check(error, abs(cfg%atm%lx - 200.0_dp) < 1.0e-6_dp, 'lx on rank '//str(par_rank()))
    call check(error, .not. allocated(cfg%cloud%grid%lwc), 'field data kept in the grid')
  end subroutine t_cloud_grid

  function merge_message(err) result(m)
    type(error_t), allocatable, intent(in) :: err
    character(len=:), allocatable :: m
    m = ''
    if (allocated(err)) m = err%message
  end function merge_message

  function ref_r1() result(x)
    real(dp), allocatable :: x(:)
    allocate (x(0:5))
    x = [1.0_dp/3.0_dp, -0.0_dp, huge(1.0_dp), tiny(1.0_dp), 2.0_dp/7.0_dp, -1.0e-300_dp]
  end function ref_r1

  function ref_r3() result(x)
    real(dp), allocatable :: x(:, :, :)
    integer :: i, j, k
    allocate (x(1:2, -1:0, 2:3))
    do k = 2, 3
      do j = -1, 0
        do i = 1, 2
          x(i, j, k) = real(i, dp)/real(3 + j + 7*k, dp)
        end do
      end do
    end do
  end function ref_r3

  function ref_i1() result(x)
    integer, allocatable :: x(:)
    allocate (x(-2:1))
    x = [huge(1), -huge(1), 0, 42]
  end function ref_i1

end module test_bundle_suite

program test_bundle
  use kumo_testing, only: run_unittests
  use kumo_parallel, only: par_init, par_finalize
  use test_bundle_suite, only: collect_bundle
  implicit none
  integer :: n_failed
  call par_init()
  call run_unittests('bundle', collect_bundle(), n_failed)
  call par_finalize()
  if (n_failed > 0) error stop 1
end program test_bundle
