! SPDX-License-Identifier: BSD-3-Clause
!> Orchestration: configuration → scene setup → batches over ranks → reduction → results.
!>
!> `simulate` runs a validated configuration and returns the result set (on rank 0); tests call
!> it directly. `run_case` is what the program does: read the namelist, check that the output
!> can be written, simulate, log and write the netCDF file. The scene is built by
!> kumo_scene_setup, the photons are traced by kumo_transport, the products are laid out by
!> kumo_output.
module kumo_driver
  use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
  use kumo_kinds, only: wp, dp, i8
  use kumo_constants, only: KUMO_VERSION
  use kumo_error, only: error_t, set_error, str
  use kumo_rng, only: rng_t, rng_init
  use kumo_tally, only: tally_layout_t, tally_t, stats_t, layout_init, tally_reset, stats_init, &
                        stats_add_batch, N_ANOMALIES
  use kumo_scene, only: scene_t
  use kumo_transport, only: trace_batch
  use kumo_results, only: result_set_t, add_attr
  use kumo_config, only: config_t, read_config, config_echo, input_file_t, config_inputs
  use kumo_textio, only: read_whole_file, same_file
  use kumo_netcdf, only: write_results, check_writable
  use kumo_parallel, only: par_rank, par_size, par_is_root, par_sum_to_root, par_allreduce_sum, &
                           par_wtime, par_bcast_int
  use kumo_scene_setup, only: setup_scene
  use kumo_output, only: run_summary_t, build_results, log_summary
  use kumo_vr, only: runaway_cost_check
  implicit none
  private
  public :: run_case, simulate, scene_t, setup_scene, run_summary_t

  !> Progress on rank 0 (standard error), for runs longer than a few seconds: the first line
  !> after PROGRESS_FIRST seconds, then one every PROGRESS_EVERY seconds.
  real(dp), parameter :: PROGRESS_FIRST = 5.0_dp, PROGRESS_EVERY = 15.0_dp
  type :: progress_t
    logical :: on = .false.
    real(dp) :: t0 = 0.0_dp          !! start of tracing [s]
    real(dp) :: next = 0.0_dp        !! time of the next line [s]
    real(dp) :: rel = -1.0_dp        !! relative error of the target after the last round
  end type progress_t

contains

  !> The program's job: namelist file in, netCDF file out.
  subroutine run_case(path, error)
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    character(len=:), allocatable :: nml_text
    integer :: status(1)

    call read_config(path, cfg, error)
    if (allocated(error)) return
    call refuse_input_as_output(cfg, path, error)
    if (allocated(error)) return
    call read_whole_file(path, nml_text, error)
    if (allocated(error)) return
    status = 0
    if (par_is_root()) then
      call check_writable(trim(cfg%output%file), error)
      if (allocated(error)) status = 1
    end if
    call par_bcast_int(status)
    if (status(1) /= 0) then
      if (.not. allocated(error)) call set_error(error, 'output file cannot be written')
      return
    end if
    if (par_is_root() .and. cfg%control%verbose >= 1) then
      write (output_unit, '(a)') 'kumo '//KUMO_VERSION//': '//trim(path)
      write (output_unit, '(a)') config_echo(cfg)
      flush (output_unit)   ! a batch job's log shows the configuration while it runs
    end if
    call simulate(cfg, set, summary, error, nml_text)
    if (allocated(error)) return
    if (par_is_root()) then
      call write_results(trim(cfg%output%file), set, error)
      if (allocated(error)) return
      if (cfg%control%verbose >= 1) call log_summary(set, summary, trim(cfg%output%file))
    end if
  end subroutine run_case

  !> Run the batches of a configuration on all ranks and gather the results on rank 0.
  subroutine simulate(cfg, set, summary, error, nml_text)
    type(config_t), intent(in) :: cfg
    type(result_set_t), intent(out) :: set
    type(run_summary_t), intent(out) :: summary
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: nml_text
    type(scene_t) :: scene
    type(tally_layout_t) :: lay
    type(tally_t) :: tal
    type(stats_t) :: st
    type(rng_t) :: rng
    real(dp), allocatable :: rec(:, :), tmp(:, :)
    real(dp) :: t0, t1, c0, c1, cpu, buf2(3), rel
    integer(i8) :: nphot, counts(4 + N_ANOMALIES)
    integer :: ib, ib_next, nb_round, rank, nranks, itarget, nb_done
    integer, allocatable :: map_levels(:), cam_npix(:)
    logical :: maps, voxel, rad_maps
    type(progress_t) :: pg

    t0 = par_wtime()
    rank = par_rank()
    nranks = par_size()
    call setup_scene(cfg, scene, error)
    if (allocated(error)) return
    ! work that grows without bound with the geometry is refused or warned about (kumo_vr)
    block
      character(len=:), allocatable :: cost_warnings
      real(wp), allocatable :: dmu(:), dphi(:)
      allocate (dmu(0), dphi(0))
      if (allocated(cfg%rad%mu)) dmu = cfg%rad%mu
      if (allocated(cfg%rad%phi_deg)) dphi = cfg%rad%phi_deg
      if (size(dphi) < size(dmu)) dphi = [dphi, spread(0.0_wp, 1, size(dmu) - size(dphi))]
      call runaway_cost_check(scene%atm, dmu, dphi, [scene%src%ux, scene%src%uy, scene%src%uz], &
                              scene%n_3d > 0, cost_warnings, error)
      if (allocated(error)) return
      scene%warnings = scene%warnings//cost_warnings
    end block
    summary%setup_time = par_wtime() - t0

    maps = cfg%output%column_fluxes .and. scene%atm%n3 > 0 .and. &
           (scene%atm%nx > 1 .or. scene%atm%ny > 1)
    voxel = cfg%output%voxel_absorption .and. scene%atm%n3 > 0
    if (maps) then
      map_levels = cfg%output%flux_levels
    else
      allocate (map_levels(0))
    end if
    rad_maps = cfg%rad%maps .and. scene%atm%n3 > 0 .and. (scene%atm%nx > 1 .or. scene%atm%ny > 1)
    allocate (cam_npix(cfg%cam%n))
    if (cfg%cam%n > 0) cam_npix = cfg%cam%npx*cfg%cam%npy
    call layout_init(lay, scene%atm%nz, scene%atm%nx*scene%atm%ny, scene%atm%n3, map_levels, &
                     voxel, scene%det%n_dir, scene%det%levels, rad_maps, cam_npix, &
                     [scene%atm%k3_lo - 1, scene%atm%k3_hi])
    if (par_is_root() .and. len(scene%notes) > 0 .and. cfg%control%verbose >= 1) then
      write (output_unit, '(a)', advance='no') scene%notes
      flush (output_unit)
    end if
    if (par_is_root() .and. len(scene%warnings) > 0) write (error_unit, '(a)') &
      'kumo: warning: '//scene%warnings
    call stats_init(st, lay)
    call tally_reset(tal, lay)

    select case (trim(cfg%control%target_output))
    case ('transmittance')
      itarget = lay%i_dn + 1
    case ('absorptance')
      itarget = lay%i_atm + 1
    case default
      itarget = lay%i_up + lay%nz + 1
    end select

    nphot = cfg%control%n_photons_per_batch
    nb_round = cfg%control%n_batches
    allocate (rec(3, 0))
    ib_next = 1
    cpu = 0.0_dp
    pg%on = par_is_root() .and. cfg%control%verbose >= 1
    pg%t0 = par_wtime()
    pg%next = pg%t0 + PROGRESS_FIRST
    do
      allocate (tmp(3, ib_next + nb_round - 1))
      tmp = 0.0_dp
      tmp(:, 1:size(rec, 2)) = rec
      call move_alloc(tmp, rec)
      call cpu_time(c0)
      do ib = ib_next, ib_next + nb_round - 1
        if (mod(ib - 1, nranks) /= rank) cycle
        call rng_init(rng, cfg%control%seed, int(ib, i8))
        call tally_reset(tal, lay)
        call trace_batch(scene, lay, rng, nphot, tal)
        call stats_add_batch(st, lay, tal, nphot)
        rec(1, ib) = tal%buf(lay%i_up + lay%nz + 1)/real(nphot, dp)
        rec(2, ib) = (tal%buf(lay%i_dir + 1) + tal%buf(lay%i_dif + 1))/real(nphot, dp)
        rec(3, ib) = sum(tal%buf(lay%i_abs + 1:lay%i_abs + lay%nz))/real(nphot, dp)
        if (pg%on) call report_progress(pg, cfg, int(st%n_batches)*nranks, ib_next - 1 + nb_round)
      end do
      call cpu_time(c1)
      cpu = cpu + (c1 - c0)
      ib_next = ib_next + nb_round
      if (cfg%control%target_rel_error <= 0.0_dp) exit
      ! every rank takes the same decision from the same global sums
      buf2 = [st%s1(itarget), st%s2(itarget), real(st%n_batches, dp)]
      call par_allreduce_sum(buf2)
      rel = relative_error(buf2)
      pg%rel = rel
      if (par_is_root() .and. cfg%control%verbose >= 2) then
        write (output_unit, '(a)') '  batches '//str(ib_next - 1)//': '// &
          trim(cfg%control%target_output)//' relative standard error '//str(rel)
        flush (output_unit)
      end if
      if (rel <= cfg%control%target_rel_error) exit
      if (int(ib_next - 1 + nb_round, i8)*nphot > cfg%control%max_photons) exit
    end do
    nb_done = ib_next - 1

    counts(1) = st%n_batches
    counts(2) = st%n_photons
    counts(3:4) = st%work
    counts(5:) = st%anomalies
    call par_sum_to_root(st%s1)
    call par_sum_to_root(st%s2)
    call par_sum_to_root(counts)
    block
      real(dp), allocatable :: flat(:)
      flat = reshape(rec, [size(rec)])
      flat = [flat, cpu]
      call par_sum_to_root(flat)
      rec = reshape(flat(1:size(rec)), shape(rec))
      cpu = flat(size(flat))
    end block
    st%n_batches = counts(1)
    st%n_photons = counts(2)
    st%work = counts(3:4)
    st%anomalies = counts(5:)
    t1 = par_wtime()

    summary%n_photons = st%n_photons
    summary%n_batches = st%n_batches
    summary%n_ranks = nranks
    summary%wall_time = t1 - t0
    summary%cpu_time = cpu
    summary%anomalies = st%anomalies
    summary%flight_steps = st%work(1)
    summary%events = st%work(2)
    if (.not. par_is_root()) return
    call build_results(cfg, scene, lay, st, rec(:, 1:nb_done), summary, set)
    if (present(nml_text)) call add_attr(set, 'namelist', nml_text)
  end subroutine simulate

  !> The output file must not be one of the run's own inputs (the namelist, a scene, surface,
  !> cloud or phase file) nor its Mie cache: writing it would destroy what the run is made from.
  subroutine refuse_input_as_output(cfg, path, error)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(out) :: error
    type(input_file_t), allocatable :: inputs(:)
    character(len=:), allocatable :: out
    integer :: i
    out = trim(cfg%output%file)
    inputs = config_inputs(cfg, path)
    do i = 1, size(inputs)
      if (same_file(out, inputs(i)%path)) then
        call set_error(error, '&kumo_output file = '''//out//''' is this run''s '// &
                       inputs(i)%label//' ('//inputs(i)%path//'); kumo does not overwrite '// &
                       'its own input: choose another output file')
        return
      end if
    end do
    if (cfg%cloud%enabled .and. len_trim(cfg%cloud%mie_cache) > 0) then
      if (same_file(out, trim(cfg%cloud%mie_cache))) call set_error(error, &
        '&kumo_output file = '''//out//''' is this run''s &kumo_cloud mie_cache; '// &
        'choose another output file')
    end if
  end subroutine refuse_input_as_output

  !> A progress line on standard error when it is due: batches done (estimated over all ranks
  !> from rank 0's own), photons per second, and the time left (fixed batch count) or the
  !> current relative error of the target output (target-error mode).
  subroutine report_progress(pg, cfg, n_done, n_planned)
    type(progress_t), intent(inout) :: pg
    type(config_t), intent(in) :: cfg
    integer, intent(in) :: n_done, n_planned
    real(dp) :: t, rate
    character(len=:), allocatable :: line
    t = par_wtime()
    if (t < pg%next .or. n_done <= 0) return
    pg%next = t + PROGRESS_EVERY
    rate = real(n_done, dp)*real(cfg%control%n_photons_per_batch, dp)/max(t - pg%t0, 1.0e-9_dp)
    if (cfg%control%target_rel_error > 0.0_dp) then
      line = 'kumo: '//str(n_done)//' batches, '//str(real(nint(rate), dp))//' photons/s'
      if (pg%rel >= 0.0_dp) line = line//', '//trim(cfg%control%target_output)// &
        ' relative error '//str(pg%rel)//' (target '//str(cfg%control%target_rel_error)//')'
    else
      line = 'kumo: '//str(min(n_done, n_planned))//' of '//str(n_planned)//' batches ('// &
             str(nint(100.0_dp*min(n_done, n_planned)/n_planned))//' %), '// &
             str(real(nint(rate), dp))//' photons/s, about '// &
             str(nint(max(0.0_dp, (t - pg%t0)*(real(n_planned, dp)/n_done - 1.0_dp))))// &
             ' s left'
    end if
    write (error_unit, '(a)') line
    flush (error_unit)
  end subroutine report_progress

  pure real(dp) function relative_error(b) result(rel)
    real(dp), intent(in) :: b(3)  !! S1, S2, number of batches
    real(dp) :: m, v
    if (b(3) < 2.0_dp) then
      rel = huge(1.0_dp)
      return
    end if
    m = b(1)/b(3)
    v = max(0.0_dp, b(2)/b(3) - m*m)/(b(3) - 1.0_dp)
    if (m == 0.0_dp) then
      rel = huge(1.0_dp)
    else
      rel = sqrt(v)/abs(m)
    end if
  end function relative_error

end module kumo_driver
