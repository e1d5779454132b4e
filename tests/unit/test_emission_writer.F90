! SPDX-License-Identifier: BSD-3-Clause
!> The emission table in the caller's storage with the voxels' Planck radiances in the writer's
!> hands alone (kumo_emission emission_init `b3_by_writer`, as one scene per node uses it): the
!> storage is one buffer here, taken first by a "writer" that passes b3 and then by a "reader"
!> that passes none.
!>
!> * The reader's table (total power, the layers' emission, cumulative table, launch weights,
!>   voxel Planck radiances) equals bit for bit the one a single process builds with b3 and no
!>   storage.
!> * The flag without storage is refused.
!> * A writer without b3, or with a negative one, fails with its own message, and the reader
!>   that comes after it on the same storage fails too instead of using the table.
module test_emission_writer_suite
  use, intrinsic :: iso_c_binding, only: c_ptr, c_loc
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use kumo_kinds, only: wp, i8
  use kumo_testing, only: error_t, unittest_t, new_unittest, check
  use kumo_phase, only: phase_t, new_phase_isotropic
  use kumo_atmosphere, only: atmosphere_t, atmosphere_options_t, atmosphere_init
  use kumo_surface, only: surface_t, surface_init
  use kumo_emission, only: emission_t, emission_init
  implicit none
  private
  public :: collect_emission_writer

  real(wp), allocatable, target :: buf(:)   !! the storage the writer and the reader share
  logical :: as_writer = .true.             !! the next call of fake_storage is the writer's

contains

  function collect_emission_writer() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('reader_equals_single_process', test_reader), &
             new_unittest('flag_needs_storage', test_needs_storage), &
             new_unittest('writer_fault_is_the_readers', test_writer_fault)]
  end function collect_emission_writer

  !> The caller's storage: the writer allocates the buffer (NaN, so that a value it did not
  !> form shows), the reader takes the same one.
  subroutine fake_storage(nbytes, base, writer)
    integer(i8), intent(in) :: nbytes
    type(c_ptr), intent(out) :: base
    logical, intent(out) :: writer
    writer = as_writer
    if (as_writer) then
      if (allocated(buf)) deallocate (buf)
      allocate (buf(nbytes/(storage_size(1.0_wp)/8)))
      buf = ieee_value(1.0_wp, ieee_quiet_nan)
    end if
    base = c_loc(buf(1))
  end subroutine fake_storage

  subroutine no_sync()
  end subroutine no_sync

  !> Three layers, the middle one 3-D (3 x 2 columns of varied extinction), a gray surface, and
  !> voxel Planck radiances that differ from the layer's.
  subroutine scene(atm, sfc, b_lev, b3, error)
    type(atmosphere_t), intent(out) :: atm
    type(surface_t), intent(out) :: sfc
    real(wp), allocatable, intent(out) :: b_lev(:), b3(:, :, :)
    type(error_t), allocatable, intent(out) :: error
    type(phase_t) :: phases(1)
    type(atmosphere_options_t) :: opts
    real(wp) :: ext3(3, 2, 1, 1), ssa3(3, 2, 1, 1)
    integer :: iph3(3, 2, 1, 1), ix, iy
    phases(1) = new_phase_isotropic()
    do iy = 1, 2
      do ix = 1, 3
        ext3(ix, iy, 1, 1) = 1.0e-3_wp*(ix + 2*iy)
      end do
    end do
    ssa3 = 0.4_wp
    iph3 = 1
    call atmosphere_init(atm, [0.0_wp, 500.0_wp, 1000.0_wp, 2000.0_wp], 600.0_wp, 400.0_wp, &
                         reshape([2.0e-4_wp, 1.0e-4_wp, 5.0e-5_wp], [3, 1]), &
                         reshape([0.2_wp, 0.2_wp, 0.2_wp], [3, 1]), reshape([1, 1, 1], [3, 1]), &
                         phases, opts, error, 2, ext3, ssa3, iph3)
    if (allocated(error)) return
    call surface_init(sfc, reshape([0.1_wp], [1, 1]), 600.0_wp, 400.0_wp, error)
    if (allocated(error)) return
    b_lev = [9.0_wp, 8.5_wp, 8.0_wp, 7.0_wp]
    allocate (b3(atm%nx, atm%ny, atm%n3))
    do iy = 1, atm%ny
      do ix = 1, atm%nx
        b3(ix, iy, :) = 7.5_wp + 0.25_wp*ix - 0.5_wp*iy
      end do
    end do
  end subroutine scene

  subroutine test_reader(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(surface_t) :: sfc
    real(wp), allocatable :: b_lev(:), b3(:, :, :)
    type(emission_t) :: ref, w, r
    call scene(atm, sfc, b_lev, b3, error)
    if (allocated(error)) return
    call check(error, atm%n3 > 0, 'the test scene has a 3-D region')
    if (allocated(error)) return
    call emission_init(ref, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, error, b3=b3)
    if (allocated(error)) return
    as_writer = .true.
    call emission_init(w, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, error, b3=b3, &
                       storage=fake_storage, sync=no_sync, b3_by_writer=.true.)
    if (allocated(error)) return
    as_writer = .false.
    call emission_init(r, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, error, &
                       storage=fake_storage, sync=no_sync, b3_by_writer=.true.)
    if (allocated(error)) return
    call check(error, r%has_b3 .and. r%on_node .and. .not. r%table_writer, &
               'the reader has voxel Planck radiances, in the storage, formed by the writer')
    call check(error, r%power == ref%power, 'total power as one process forms it')
    call check(error, all(r%emit_layer == ref%emit_layer), 'layer emission as one process')
    call check(error, all(r%cdf == ref%cdf) .and. all(r%ratio == ref%ratio), &
               'cumulative table and launch weights as one process forms them')
    call check(error, all(r%b3 == b3), 'the reader reads the writer''s voxel Planck radiances')
    call check(error, r%cdf_sun == ref%cdf_sun, 'the sun''s share as one process')
  end subroutine test_reader

  subroutine test_needs_storage(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(surface_t) :: sfc
    real(wp), allocatable :: b_lev(:), b3(:, :, :)
    type(emission_t) :: em
    type(error_t), allocatable :: err
    call scene(atm, sfc, b_lev, b3, error)
    if (allocated(error)) return
    call emission_init(em, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, err, b3=b3, &
                       b3_by_writer=.true.)
    call check(error, allocated(err), 'b3_by_writer without storage is refused')
    if (allocated(error)) return
    call check(error, index(err%message, 'b3_by_writer needs the caller''s storage') > 0, &
               'the message names the flag and the storage: '//err%message)
  end subroutine test_needs_storage

  subroutine test_writer_fault(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(surface_t) :: sfc
    real(wp), allocatable :: b_lev(:), b3(:, :, :)
    type(emission_t) :: w, r
    type(error_t), allocatable :: ew, er
    integer :: ic
    call scene(atm, sfc, b_lev, b3, error)
    if (allocated(error)) return
    b3(2, 1, 1) = -1.0_wp
    do ic = 1, 2
      as_writer = .true.
      if (ic == 1) then
        ! no b3 on the writer
        call emission_init(w, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, ew, &
                           storage=fake_storage, sync=no_sync, b3_by_writer=.true.)
      else
        ! a negative Planck radiance
        call emission_init(w, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, ew, b3=b3, &
                           storage=fake_storage, sync=no_sync, b3_by_writer=.true.)
      end if
      as_writer = .false.
      call emission_init(r, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, er, &
                         storage=fake_storage, sync=no_sync, b3_by_writer=.true.)
      call check(error, allocated(ew) .and. allocated(er), 'writer and reader both fail')
      if (allocated(error)) return
      if (ic == 1) then
        call check(error, index(ew%message, 'has no voxel Planck radiances') > 0, &
                   'the writer says what it misses: '//ew%message)
      else
        call check(error, index(ew%message, 'must be finite and >= 0') > 0, &
                   'the writer names the bound: '//ew%message)
      end if
      call check(error, index(er%message, 'missing or not finite and >= 0') > 0, &
                 'the reader says the writer''s radiances are bad: '//er%message)
      if (allocated(error)) return
      deallocate (ew, er)
    end do
  end subroutine test_writer_fault
end module test_emission_writer_suite

program test_emission_writer
  use kumo_testing, only: run_unittests
  use test_emission_writer_suite, only: collect_emission_writer
  implicit none
  integer :: n_failed
  call run_unittests('emission_writer', collect_emission_writer(), n_failed)
  if (n_failed > 0) error stop 1
end program test_emission_writer
