! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of the deferred products of a result set (kumo_results): values formed from the
!> sums piece by piece equal those formed at once, moving values into a set copies nothing, and
!> the netCDF writer writes a deferred variable slab by slab exactly as the same values held.
module test_kumo_results_defer
  use kumo_kinds, only: dp
  use kumo_error, only: error_t, str
  use kumo_tally, only: stats_t, stats_mean, stats_stderr
  use kumo_results, only: result_set_t, add_dim, add_var, take_var, defer_var, keep_sums, &
                          var_size, var_has_stderr, var_values, materialize_vars, find_var
  use kumo_netcdf, only: write_results
  use netcdf, only: nf90_open, nf90_close, nf90_inq_varid, nf90_get_var, NF90_NOWRITE, NF90_NOERR
  use kumo_testing, only: unittest_t, new_unittest, check
  implicit none
  private
  public :: collect_results_defer

  integer, parameter :: NX = 3, NY = 2, NZ = 4   !! a 3 x 2 x 4 product
  integer, parameter :: LO = 5                   !! its entries in the sums: LO + 1 .. LO + 24

contains

  function collect_results_defer() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('deferred_values_in_pieces', test_pieces), &
             new_unittest('materialize_forms_every_value', test_materialize), &
             new_unittest('take_var_moves_values', test_take_var), &
             new_unittest('writer_slabs_equal_held_values', test_writer)]
  end function collect_results_defer

  !> Sums of 3 batches over 40 entries, with spread (no standard error of 0).
  subroutine make_sums(st)
    type(stats_t), intent(out) :: st
    integer :: i
    allocate (st%s1(40), st%s2(40))
    do i = 1, 40
      st%s1(i) = 0.3_dp*i + 0.01_dp*mod(7*i, 11)
      st%s2(i) = st%s1(i)**2/3.0_dp + 0.02_dp*(1 + mod(3*i, 5))
    end do
    st%n_batches = 3
  end subroutine make_sums

  !> A set with the product deferred: per layer (block of NX*NY) times fa and then fb.
  subroutine deferred_set(set, fa, fb)
    type(result_set_t), intent(out) :: set
    real(dp), intent(in) :: fa(NZ), fb(NZ)
    type(stats_t) :: st
    call make_sums(st)
    call add_dim(set, 'x', NX)
    call add_dim(set, 'y', NY)
    call add_dim(set, 'z', NZ)
    call add_var(set, 'before', 'a held variable', '1', ['x'], [1.0_dp, 2.0_dp, 3.0_dp])
    call defer_var(set, 'v', 'a deferred variable', 'W m-3', ['x', 'y', 'z'], LO, NX*NY*NZ, &
                   NX*NY, fa, fb)
    call keep_sums(set, st)
  end subroutine deferred_set

  !> Every value, formed at once from the sums as build_results did: mean times fa then fb.
  subroutine direct(fa, fb, m, e)
    real(dp), intent(in) :: fa(NZ), fb(NZ)
    real(dp), intent(out) :: m(NX*NY*NZ), e(NX*NY*NZ)
    type(stats_t) :: st
    integer :: k, j
    call make_sums(st)
    m = stats_mean(st, LO + 1, LO + NX*NY*NZ)
    e = stats_stderr(st, LO + 1, LO + NX*NY*NZ)
    do j = 1, NX*NY*NZ
      k = (j - 1)/(NX*NY) + 1
      m(j) = m(j)*fa(k)*fb(k)
      e(j) = e(j)*fa(k)*fb(k)
    end do
  end subroutine direct

  subroutine test_pieces(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp), parameter :: fa(NZ) = [0.5_dp, 0.25_dp, 2.0_dp, 3.0_dp]
    real(dp), parameter :: fb(NZ) = [7.0_dp, 1.5_dp, 0.1_dp, 9.0_dp]
    type(result_set_t) :: set
    real(dp) :: m(NX*NY*NZ), e(NX*NY*NZ), pm(5), pe(5)
    integer :: iv, j0
    call deferred_set(set, fa, fb)
    call direct(fa, fb, m, e)
    iv = find_var(set, 'v')
    call check(error, var_size(set%vars(iv)) == NX*NY*NZ .and. var_has_stderr(set%vars(iv)) &
               .and. .not. allocated(set%vars(iv)%mean) .and. size(set%sums%s1) == 40, &
               'deferred variable: size '//str(var_size(set%vars(iv)))// &
               ', or values held, or the sums not kept')
    if (allocated(error)) return
    ! pieces of 5 that straddle the layers, the last one short
    do j0 = 0, NX*NY*NZ - 1, 5
      associate (n => min(5, NX*NY*NZ - j0))
        call var_values(set, iv, j0, pm(1:n), pe(1:n))
        call check(error, all(pm(1:n) == m(j0 + 1:j0 + n)) .and. all(pe(1:n) == e(j0 + 1:j0 + n)), &
                   'values '//str(j0 + 1)//'.. differ from those formed at once')
      end associate
      if (allocated(error)) return
    end do
  end subroutine test_pieces

  subroutine test_materialize(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp), parameter :: fa(NZ) = 1.0_dp/[46.875_dp, 50.0_dp, 100.0_dp, 3.0_dp], &
                           fb(NZ) = [1361.0_dp, 1361.0_dp, 1361.0_dp, 1361.0_dp]
    type(result_set_t) :: set
    real(dp) :: m(NX*NY*NZ), e(NX*NY*NZ)
    integer :: iv
    call deferred_set(set, fa, fb)
    call direct(fa, fb, m, e)
    call materialize_vars(set)
    iv = find_var(set, 'v')
    call check(error, allocated(set%vars(iv)%mean) .and. allocated(set%vars(iv)%stderr) .and. &
               set%vars(iv)%src_lo < 0, 'materialize_vars left the variable deferred')
    if (allocated(error)) return
    call check(error, all(set%vars(iv)%mean == m) .and. all(set%vars(iv)%stderr == e), &
               'materialized values differ from those formed at once')
    if (allocated(error)) return
    call check(error, .not. allocated(set%sums%s1) .and. .not. allocated(set%sums%s2), &
               'materialize_vars kept the sums')
    if (allocated(error)) return
    call check(error, all(set%vars(find_var(set, 'before'))%mean == [1.0_dp, 2.0_dp, 3.0_dp]), &
               'the held variable changed')
  end subroutine test_materialize

  subroutine test_take_var(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: set
    real(dp), allocatable :: m(:), e(:)
    integer :: i, j
    do i = 1, 6
      m = [(real(i*j, dp), j=1, 4)]
      e = 0.1_dp*m
      call take_var(set, 'v'//str(i), 'variable', '1', ['n'], m, e)
      call check(error, .not. allocated(m) .and. .not. allocated(e), &
                 'take_var left its arguments allocated')
      if (allocated(error)) return
    end do
    ! the set grew six times: every variable keeps its values
    do i = 1, 6
      call check(error, all(set%vars(i)%mean == [(real(i*j, dp), j=1, 4)]) .and. &
                 all(set%vars(i)%stderr == 0.1_dp*[(real(i*j, dp), j=1, 4)]), &
                 'variable '//str(i)//' lost its values as the set grew')
      if (allocated(error)) return
    end do
  end subroutine test_take_var

  subroutine test_writer(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp), parameter :: fa(NZ) = [0.5_dp, 0.25_dp, 2.0_dp, 3.0_dp]
    real(dp), parameter :: fb(NZ) = [7.0_dp, 1.5_dp, 0.1_dp, 9.0_dp]
    type(result_set_t) :: a, b
    type(error_t), allocatable :: err
    real(dp) :: ma(NX, NY, NZ), mb(NX, NY, NZ), ea(NX, NY, NZ), eb(NX, NY, NZ)
    call deferred_set(a, fa, fb)
    call deferred_set(b, fa, fb)
    call materialize_vars(b)
    call write_results('results_defer_a.nc', a, err)
    if (.not. allocated(err)) call write_results('results_defer_b.nc', b, err)
    call check(error, .not. allocated(err), 'write_results failed')
    if (allocated(error)) return
    call read_v('results_defer_a.nc', ma, ea)
    call read_v('results_defer_b.nc', mb, eb)
    call check(error, all(ma == mb) .and. all(ea == eb), &
               'the deferred variable was written other than the same values held')
    if (allocated(error)) return
    call check(error, all(reshape(ma, [NX*NY*NZ]) == b%vars(find_var(b, 'v'))%mean), &
               'the written values are not in Fortran order of (x, y, z)')
  contains
    subroutine read_v(path, m, e)
      character(len=*), intent(in) :: path
      real(dp), intent(out) :: m(NX, NY, NZ), e(NX, NY, NZ)
      integer :: ncid, id
      m = -1.0_dp
      e = -1.0_dp
      if (nf90_open(path, NF90_NOWRITE, ncid) /= NF90_NOERR) return
      if (nf90_inq_varid(ncid, 'v', id) == NF90_NOERR) then
        if (nf90_get_var(ncid, id, m) /= NF90_NOERR) m = -1.0_dp
      end if
      if (nf90_inq_varid(ncid, 'v_stderr', id) == NF90_NOERR) then
        if (nf90_get_var(ncid, id, e) /= NF90_NOERR) e = -1.0_dp
      end if
      if (nf90_close(ncid) /= NF90_NOERR) m = -1.0_dp
    end subroutine read_v
  end subroutine test_writer
end module test_kumo_results_defer

program test_results_defer
  use test_kumo_results_defer, only: collect_results_defer
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_results deferred products', collect_results_defer(), n_failed)
  if (n_failed > 0) error stop 1
end program test_results_defer
