! SPDX-License-Identifier: BSD-3-Clause
!> Batches over ranks: the run is distributed over all ranks of the launch (2 in CI), then rank 0
!> recomputes every batch on its own from (seed, batch index) and checks that the per-batch
!> results are bit-identical, that the reduced means are the batch averages, and that the totals
!> match a serial run to rounding. In a serial build the same checks run on one rank.
module test_mpi_suite
  use kumo_kinds, only: wp, dp, i8
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  use kumo_config, only: config_t
  use kumo_results, only: result_set_t
  use kumo_driver, only: scene_t, setup_scene, run_summary_t
  use kumo_rng, only: rng_t, rng_init
  use kumo_tally, only: tally_layout_t, tally_t, layout_init, tally_reset
  use kumo_transport, only: trace_batch
  use kumo_test_scenes, only: slab_config, attach_scene, get_scalar, get_array
  use kumo_parallel, only: par_is_root, par_barrier
  implicit none
  private
  public :: collect_mpi, prepare, set_results, get_cfg

  type(config_t) :: cfg
  type(result_set_t) :: res
  type(run_summary_t) :: summary
  integer :: n_ranks_run = 0

contains

  !> Build the case (a cloud field over a layered column) on every rank.
  subroutine prepare(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: ext(6, 5, 2), ssa(6, 5, 2)
    integer :: i, j
    cfg = slab_config(0.0_wp, 1.0_wp, 'hg', 0.85_wp, 35.0_wp, 0.25_wp, 3000_i8, 7)
    deallocate (cfg%atm%z, cfg%atm%ext1d, cfg%atm%ssa1d, cfg%atm%phase1d)
    cfg%atm%nz = 3
    cfg%atm%z = [0.0_wp, 300.0_wp, 600.0_wp, 5000.0_wp]
    allocate (cfg%atm%ext1d(3, 1), cfg%atm%ssa1d(3, 1), cfg%atm%phase1d(3, 1))
    cfg%atm%ext1d(:, 1) = [1.0e-5_wp, 0.0_wp, 2.0e-5_wp]
    cfg%atm%ssa1d = 1.0_wp
    cfg%atm%phase1d = 1
    cfg%output%flux_levels = [0, 1, 2, 3]
    do j = 1, 5
      do i = 1, 6
        ext(i, j, :) = 0.01_wp*mod(i*j, 4)
      end do
    end do
    ssa = 0.97_wp
    call attach_scene(cfg, 'mpi_cloud.nc', 1, ext, ssa, 1, error, write_file=par_is_root())
    call par_barrier()
  end subroutine prepare

  function get_cfg() result(c)
    type(config_t) :: c
    c = cfg
  end function get_cfg

  subroutine set_results(set, s, nr)
    type(result_set_t), intent(in) :: set
    type(run_summary_t), intent(in) :: s
    integer, intent(in) :: nr
    res = set
    summary = s
    n_ranks_run = nr
  end subroutine set_results

  function collect_mpi() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('per_batch_results_identical', test_per_batch), &
             new_unittest('means_are_batch_averages', test_means)]
  end function collect_mpi

  subroutine test_per_batch(error)
    type(error_t), allocatable, intent(out) :: error
    type(scene_t) :: scene
    type(tally_layout_t) :: lay
    type(tally_t) :: tal
    type(rng_t) :: rng
    real(dp), allocatable :: br(:), bt(:), ba(:), e(:)
    real(dp) :: r, t, a, n
    integer :: ib, nz
    call get_array(res, 'batch_reflectance', br, e, error)
    call get_array(res, 'batch_transmittance', bt, e, error)
    call get_array(res, 'batch_absorptance', ba, e, error)
    if (allocated(error)) return
    call check(error, size(br) == cfg%control%n_batches, 'one record per batch')
    call setup_scene(cfg, scene, error)
    if (allocated(error)) return
    nz = scene%atm%nz
    call layout_init(lay, nz, scene%atm%nx*scene%atm%ny, scene%atm%n3, [integer ::], .false.)
    n = real(cfg%control%n_photons_per_batch, dp)
    do ib = 1, cfg%control%n_batches
      call rng_init(rng, cfg%control%seed, int(ib, i8))
      call tally_reset(tal, lay)
      call trace_batch(scene, lay, rng, &
                       cfg%control%n_photons_per_batch, tal)
      r = tal%buf(lay%i_up + nz + 1)/n
      t = (tal%buf(lay%i_dir + 1) + tal%buf(lay%i_dif + 1))/n
      a = sum(tal%buf(lay%i_abs + 1:lay%i_abs + nz))/n
      call check(error, r == br(ib) .and. t == bt(ib) .and. a == ba(ib), &
                 'batch results differ from the single-rank recomputation')
      if (allocated(error)) return
    end do
  end subroutine test_per_batch

  subroutine test_means(error)
    type(error_t), allocatable, intent(out) :: error
    real(dp), allocatable :: br(:), e(:)
    real(dp) :: m, s
    call get_array(res, 'batch_reflectance', br, e, error)
    call get_scalar(res, 'reflectance', m, s, error)
    if (allocated(error)) return
    call check_close(error, m, sum(br)/size(br), abs_tol=0.0_dp, rel_tol=1.0e-13_dp, &
                     label='reduced reflectance vs mean of batches')
    call check(error, summary%n_ranks == n_ranks_run, 'summary reports the ranks used')
    call check(error, summary%n_photons == cfg%control%n_photons_per_batch*cfg%control%n_batches, &
               'every photon of every batch is counted once')
  end subroutine test_means


end module test_mpi_suite

program test_mpi_batches
  use, intrinsic :: iso_fortran_env, only: output_unit
  use kumo_error, only: error_t, stop_on_error
  use kumo_testing, only: run_unittests
  use kumo_parallel, only: par_init, par_finalize, par_is_root, par_size, par_abort
  use kumo_results, only: result_set_t
  use kumo_driver, only: simulate, run_summary_t
  use test_mpi_suite, only: collect_mpi, prepare, set_results
  implicit none
  type(error_t), allocatable :: error
  type(result_set_t) :: set
  type(run_summary_t) :: summary
  integer :: n_failed
  call par_init()
  call prepare(error)
  call stop_on_error(error)
  call run_case_all(set, summary, error)
  call stop_on_error(error)
  n_failed = 0
  if (par_is_root()) then
    write (output_unit, '(a,i0,a)') '# run on ', par_size(), ' rank(s)'
    call set_results(set, summary, par_size())
    call run_unittests('mpi batches', collect_mpi(), n_failed)
  end if
  if (n_failed > 0) call par_abort(1)
  call par_finalize()
contains
  subroutine run_case_all(set, summary, error)
    use test_mpi_suite, only: get_cfg
    type(result_set_t), intent(out) :: set
    type(run_summary_t), intent(out) :: summary
    type(error_t), allocatable, intent(out) :: error
    call simulate(get_cfg(), set, summary, error)
  end subroutine run_case_all
end program test_mpi_batches
