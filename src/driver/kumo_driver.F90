! SPDX-License-Identifier: BSD-3-Clause
!> Orchestration: configuration → scene setup → batches over ranks → reduction → results.
!>
!> `simulate` runs a validated configuration and returns the result set (on rank 0); tests call
!> it directly. `run_case` is what the program does: read the namelist, check that the output
!> can be written, simulate, log and write the netCDF file. The scene is built by
!> kumo_scene_setup, the photons are traced by kumo_transport, the products are laid out by
!> kumo_output; checkpoints are written and read by kumo_checkpoint, and the small services of
!> a run (namelist text, shared errors, test hooks) are in kumo_run_util.
module kumo_driver
  use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
  use kumo_kinds, only: wp, dp, i8
  use kumo_constants, only: KUMO_VERSION
  use kumo_error, only: error_t, str
  use kumo_rng, only: rng_t, rng_init
  use kumo_tally, only: tally_layout_t, tally_t, stats_t, layout_init, tally_reset, stats_init, &
                        stats_add_batch, batch_budget, tally_free, N_ANOMALIES
  use kumo_scene, only: scene_t
  use kumo_transport, only: trace_batch
  use kumo_exact_column, only: exact_thermal_possible, exact_thermal_batch
  use kumo_results, only: result_set_t, add_attr
  use kumo_config, only: config_t, config_echo
  use kumo_netcdf, only: write_results, check_writable
  use kumo_parallel, only: par_rank, par_size, par_is_root, par_sum_to_root, par_allreduce_sum, &
                           par_wtime, par_bcast_text, par_move, par_node_max
  use kumo_checkpoint, only: checkpoint_plan_t, checkpoint_due, write_checkpoint, resume_run, &
                             early_checkpoint_check, checkpoint_fingerprint, ckpt_remove, &
                             CKPT_SUFFIX
  use kumo_run_util, only: share_error, read_text, trim_lines, refuse_input_as_output, &
                           relative_error, test_failure_hook, env_int, kill_self
  use kumo_scene_setup, only: load_config, setup_scene, spectral_scene_t, spectral_set_gpoint
  use kumo_spectral, only: spectral_begin_batch
  use kumo_output, only: run_summary_t, build_results, log_summary, log_memory, peak_resident_bytes
  use kumo_vr, only: runaway_cost_check
  use kumo_atmosphere, only: atmosphere_column_tau
  use kumo_progress, only: progress_t, progress_start, progress_batch_begin, progress_batch_done, &
                           PROGRESS_FIRST, PROGRESS_EVERY
  implicit none
  private
  public :: run_case, simulate, scene_t, setup_scene, run_summary_t, checkpoint_plan_t, check_setup

  !> Entries of the sums moved per message when the slots are folded (8 MiB): the receiving
  !> rank adds each piece as it arrives.
  integer, parameter :: FOLD_PIECE = 1048576

contains

  !> The program's job: namelist file in, netCDF file out. The namelist file is read once, on
  !> rank 0, and its text broadcast: every rank parses the same text. With `resume`, the run
  !> continues from the checkpoint `<output>.ckpt` when there is one (kumo_checkpoint).
  subroutine run_case(path, error, resume)
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(out) :: error
    logical, intent(in), optional :: resume
    type(config_t) :: cfg
    type(result_set_t) :: set
    type(run_summary_t) :: summary
    type(checkpoint_plan_t) :: plan
    character(len=:), allocatable :: raw_text, nml_text

    call read_case(path, cfg, raw_text, error)
    if (allocated(error)) return
    nml_text = trim_lines(raw_text)   ! the namelist attribute of the output
    if (par_is_root()) then
      call refuse_input_as_output(cfg, path, error)
      if (.not. allocated(error)) call check_writable(trim(cfg%output%file), error)
    end if
    call share_error(error)
    if (allocated(error)) return
    plan%path = trim(cfg%output%file)//CKPT_SUFFIX
    plan%interval = cfg%control%checkpoint_interval
    if (present(resume)) plan%resume = resume
    if (par_is_root() .and. (plan%interval > 0.0_dp .or. plan%resume)) then
      call checkpoint_fingerprint(cfg, path, raw_text, plan%fp)
      call early_checkpoint_check(plan, cfg, error)
    end if
    call share_error(error)
    if (allocated(error)) return
    if (par_is_root() .and. cfg%control%verbose >= 1) then
      write (output_unit, '(a)') 'kumo '//KUMO_VERSION//': '//trim(path)
      write (output_unit, '(a)') config_echo(cfg)
      flush (output_unit)   ! a batch job's log shows the configuration while it runs
    end if
    ! the large products are formed as they are written (kumo_output, build_results)
    call simulate(cfg, set, summary, error, nml_text, plan, defer_output=.true.)
    if (allocated(error)) return
    if (par_is_root()) then
      call write_results(trim(cfg%output%file), set, error)
      if (allocated(error)) return
      ! the output is written: the checkpoint of this run is of no further use
      if (plan%interval > 0.0_dp .or. plan%resume) call ckpt_remove(plan%path)
      if (cfg%control%verbose >= 1) call log_summary(set, summary, trim(cfg%output%file))
      if (cfg%control%verbose >= 2) call log_memory(summary)
    end if
  end subroutine run_case

  !> The namelist file `path`, read once on rank 0 and its text broadcast, parsed by every rank.
  subroutine read_case(path, cfg, raw_text, error)
    character(len=*), intent(in) :: path
    type(config_t), intent(out) :: cfg
    character(len=:), allocatable, intent(out) :: raw_text
    type(error_t), allocatable, intent(out) :: error
    if (par_is_root()) call read_text(path, raw_text, error)
    call share_error(error)
    if (allocated(error)) return
    call par_bcast_text(raw_text)
    call load_config(path, cfg, error, text=raw_text)
  end subroutine read_case

  !> `kumo --check` after the files were checked: set the scene up on every rank exactly as a
  !> run does (every input file read, optics formed, every set-up rule and warning applied) and
  !> report it on rank 0 (notes and the scene's summary on standard output, warnings on
  !> standard error), without tracing a photon. Missing Mie caches are written, as a run would.
  subroutine check_setup(path, error)
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(scene_t) :: scene
    type(spectral_scene_t) :: spec
    character(len=:), allocatable :: raw_text
    real(dp) :: t0
    logical :: exact

    call read_case(path, cfg, raw_text, error)
    if (allocated(error)) return
    t0 = par_wtime()
    call prepare_scene(cfg, scene, spec, exact, error)
    if (allocated(error)) return
    if (par_is_root()) then
      call announce_scene(scene, spec, .true.)
      t0 = par_wtime() - t0
      if (t0 < 0.01_dp) then
        write (output_unit, '(a)') 'scene set up in under 0.01 s; no photon was traced'
      else
        write (output_unit, '(a)') 'scene set up in '//str(t0, 2)// &
          ' s; no photon was traced'
      end if
    end if
  end subroutine check_setup

  !> The scene of a run, set up on every rank (setup_scene), with the checks of work that grows
  !> without bound with the geometry (kumo_vr, refused or warned about); `exact`: a
  !> non-scattering thermal column, every batch from the exact solution and no photons.
  subroutine prepare_scene(cfg, scene, spec, exact, error)
    type(config_t), intent(in) :: cfg
    type(scene_t), intent(out) :: scene
    type(spectral_scene_t), intent(out) :: spec
    logical, intent(out) :: exact
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: cost_warnings
    real(wp), allocatable :: dmu(:), dphi(:)

    exact = .false.
    call setup_scene(cfg, scene, error, spec, per_node=cfg%control%one_scene_per_node)
    if (allocated(error)) return
    allocate (dmu(0), dphi(0))
    if (allocated(cfg%rad%mu)) dmu = cfg%rad%mu
    if (allocated(cfg%rad%phi_deg)) dphi = cfg%rad%phi_deg
    if (size(dphi) < size(dmu)) dphi = [dphi, spread(0.0_wp, 1, size(dmu) - size(dphi))]
    call runaway_cost_check(scene%atm, dmu, dphi, [scene%src%ux, scene%src%uy, scene%src%uz], &
                            scene%n_3d > 0, cost_warnings, error)
    if (allocated(error)) return
    scene%warnings = scene%warnings//cost_warnings
    exact = scene%exact_thermal .and. exact_thermal_possible(scene)
    if (exact) scene%notes = scene%notes//'thermal emission of a non-scattering column: solved '// &
      'exactly (exponential integrals), no photons traced; standard errors are 0'//new_line('a')
  end subroutine prepare_scene

  !> Rank 0's report of a scene set up: its notes and summary on standard output (`log`), its
  !> warnings on standard error (always).
  subroutine announce_scene(scene, spec, log)
    type(scene_t), intent(in) :: scene
    type(spectral_scene_t), intent(in) :: spec
    logical, intent(in) :: log
    if (log) then
      write (output_unit, '(a)', advance='no') scene%notes
      write (output_unit, '(a)') scene_summary(scene, spec)
      flush (output_unit)
    end if
    if (len(scene%warnings) > 0) write (error_unit, '(a)') 'kumo: warning: '//scene%warnings
  end subroutine announce_scene

  !> Two lines that let a user see at a glance whether the scene is the one meant: the grid, and
  !> the vertical optical depth of its columns (smallest, mean, largest: a file in the wrong
  !> units shows here as optical depths a thousand times too small or too large).
  function scene_summary(scene, spec) result(text)
    type(scene_t), intent(in) :: scene
    type(spectral_scene_t), intent(in) :: spec
    character(len=:), allocatable :: text
    real(wp) :: tmin, tmean, tmax
    integer :: ix, iy
    associate (atm => scene%atm)
      text = 'scene: '//str(atm%nz)//trim(merge(' layers', ' layer ', atm%nz > 1))// &
             ' from '//str(atm%z(0), 6)//' to '//str(atm%z(atm%nz), 6)//' m'
      if (atm%n3 > 0) then
        text = text//'; 3-D region '//str(atm%nx)//' x '//str(atm%ny)//' columns of '// &
               str(atm%dx, 6)//' m x '//str(atm%dy, 6)//' m, layers '// &
               str(atm%k3_lo)//' to '//str(atm%k3_hi)
      else
        text = text//', plane-parallel'
      end if
      if (spec%on) then
        text = text//new_line('a')//'  broadband: '//str(spec%n_gpt)//' g-points, each with '// &
               'its own optical depths'
        return
      end if
      call atmosphere_column_tau(atm, tmin, tmean, tmax, ix, iy)
      if (atm%n3 > 0 .and. (atm%nx > 1 .or. atm%ny > 1)) then
        text = text//new_line('a')//'  vertical optical depth of the columns: smallest '// &
               str(tmin, 4)//', mean '//str(tmean, 4)//', largest '// &
               str(tmax, 4)//' (column '//str(ix)//', '//str(iy)//')'
      else
        text = text//new_line('a')//'  vertical optical depth: '//str(tmax, 4)
      end if
      if (atm%similar) text = text//', of the similarity-scaled medium'
    end associate
  end function scene_summary

  !> Run the batches of a configuration on all ranks and gather the results on rank 0.
  !>
  !> Batch b (seed, stream b) belongs to slot mod(b - 1, n_slots), and slot s is run by rank
  !> mod(s, N). n_slots is the rank count N, or that of the run that wrote the checkpoint a run
  !> resumes from: each slot adds its batches in increasing order, and the slots' sums are added
  !> in slot order on rank 0, so a resumed run on any rank count repeats the floating-point
  !> operations of an uninterrupted run on the first run's rank count, bit for bit.
  !> `ckpt` (run_case) asks for checkpoints and resumption; without it neither happens. With
  !> `defer_output`, the large products of `set` are formed when it is written (build_results).
  subroutine simulate(cfg, set, summary, error, nml_text, ckpt, defer_output)
    type(config_t), intent(in) :: cfg
    type(result_set_t), intent(out) :: set
    type(run_summary_t), intent(out) :: summary
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: nml_text
    type(checkpoint_plan_t), intent(in), optional :: ckpt
    logical, intent(in), optional :: defer_output
    type(scene_t) :: scene
    type(tally_layout_t) :: lay
    type(tally_t) :: tal, tal_g
    type(spectral_scene_t) :: spec
    type(stats_t) :: st
    type(stats_t), allocatable :: slot(:)
    type(rng_t) :: rng
    type(checkpoint_plan_t) :: plan
    real(dp), allocatable :: rec(:, :), tmp(:, :), buf(:)
    real(dp) :: t0, t1, c0, c1, cpu, cpu_before, buf2(3), rel, t_ckpt
    integer(i8) :: nphot, counts(4 + N_ANOMALIES)
    integer :: ib, ib_next, nb_round, rank, nranks, itarget, nb_done, n_slots, s, n_done, &
               ib_last, n_ckpt, kill_after, ib_first, iw, j
    logical :: mine
    integer, allocatable :: map_levels(:), cam_npix(:)
    logical :: maps, voxel, rad_maps, checkpoints, exact
    type(progress_t) :: pg

    t0 = par_wtime()
    rank = par_rank()
    nranks = par_size()
    call prepare_scene(cfg, scene, spec, exact, error)
    if (allocated(error)) return
    summary%setup_time = par_wtime() - t0

    maps = cfg%output%column_fluxes .and. scene%atm%n3 > 0 .and. &
           (scene%atm%nx > 1 .or. scene%atm%ny > 1)
    voxel = cfg%output%voxel_absorption .and. scene%atm%n3 > 0
    if (maps) then
      map_levels = cfg%output%map_level_list()
    else
      allocate (map_levels(0))
    end if
    rad_maps = cfg%rad%maps .and. scene%atm%n3 > 0 .and. (scene%atm%nx > 1 .or. scene%atm%ny > 1)
    allocate (cam_npix(cfg%cam%n))
    if (cfg%cam%n > 0) cam_npix = cfg%cam%npx*cfg%cam%npy
    call layout_init(lay, scene%atm%nz, scene%atm%nx*scene%atm%ny, scene%atm%n3, map_levels, &
                     voxel, scene%det%n_dir, scene%det%levels, rad_maps, cam_npix, &
                     [scene%atm%k3_lo - 1, scene%atm%k3_hi], thermal=scene%src%em%on, &
                     map_nx=scene%atm%nx, rad_map_blocks=scene%det%diff_scale > 0.0_wp, &
                     weighted=spec%on)
    if (par_is_root()) call announce_scene(scene, spec, cfg%control%verbose >= 1)
    call tally_reset(tal, lay)
    call test_failure_hook(cfg, rank, error)
    if (allocated(error)) return
    if (present(ckpt)) plan = ckpt

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
    ib_next = 1
    n_done = 0
    n_slots = nranks
    cpu = 0.0_dp
    cpu_before = 0.0_dp
    allocate (rec(3, 0))
    if (plan%resume) then
      call resume_run(plan, cfg, lay, n_slots, ib_next, n_done, rec, cpu_before, slot, error)
      if (allocated(error)) return
    end if
    if (.not. allocated(slot)) then
      allocate (slot(0:n_slots - 1))
      do s = 0, n_slots - 1
        if (mod(s, nranks) == rank) call stats_init(slot(s), lay)
      end do
    end if
    checkpoints = plan%interval > 0.0_dp
    n_ckpt = 0
    kill_after = env_int('KUMO_TEST_KILL_AFTER_CHECKPOINT')
    block
      real(dp) :: first, every
      integer :: ms
      first = PROGRESS_FIRST
      every = PROGRESS_EVERY
      ! test hook: lines every KUMO_TEST_PROGRESS_MS milliseconds
      ms = env_int('KUMO_TEST_PROGRESS_MS')
      if (ms > 0) then
        first = 1.0e-3_dp*ms
        every = first
      end if
      call progress_start(pg, par_is_root() .and. cfg%control%verbose >= 1, n_done, nphot, &
                          nranks, cfg%control%target_rel_error, cfg%control%target_output, &
                          first, every)
    end block
    t_ckpt = par_wtime()
    do
      allocate (tmp(3, ib_next + nb_round - 1))
      tmp = 0.0_dp
      tmp(:, 1:size(rec, 2)) = rec
      call move_alloc(tmp, rec)
      call cpu_time(c0)
      ib_last = ib_next + nb_round - 1
      ib_first = max(ib_next, n_done + 1)
      if (spec%node) then
        ! A broadband run whose ranks share a node's voxels: the ranks of a node switch
        ! g-points together. The batches go in windows of n_slots (slot 0 first); in step j of
        ! a window every rank traces the batch of its j-th slot, or none, and joins the node's
        ! switches all the same. The same batches go to the same slots as below, so the
        ! results are those of any other run; checkpoints come after whole windows.
        do iw = (ib_first - 1)/n_slots, (ib_last - 1)/n_slots
          do j = 0, (n_slots - 1)/nranks
            s = rank + j*nranks
            ib = iw*n_slots + s + 1
            mine = s < n_slots .and. ib >= ib_first .and. ib <= ib_last
            if (mine) then
              call rng_init(rng, cfg%control%seed, int(ib, i8))
              call tally_reset(tal, lay)
              call progress_batch_begin(pg, ib, ib_last)
            end if
            call trace_spectral_batch(spec, scene, lay, rng, nphot, tal, tal_g, error, &
                                      active=mine, pg=pg)
            if (allocated(error)) return
            if (mine) call batch_done()
          end do
          ib = min((iw + 1)*n_slots, ib_last)
          if (checkpoints .and. .not. (ib == ib_last .and. cfg%control%target_rel_error <= 0.0_dp)) &
            call checkpoint_if_due()
        end do
        ib_first = ib_last + 1     ! the loop below has nothing left to do
      end if
      do ib = ib_first, ib_last
        s = mod(ib - 1, n_slots)
        if (mod(s, nranks) == rank) then
          call rng_init(rng, cfg%control%seed, int(ib, i8))
          call tally_reset(tal, lay)
          call progress_batch_begin(pg, ib, ib_last)
          if (exact) then
            call exact_thermal_batch(scene, lay, nphot, tal, error)
            if (allocated(error)) return
          else if (spec%on) then
            call trace_spectral_batch(spec, scene, lay, rng, nphot, tal, tal_g, error, pg=pg)
            if (allocated(error)) return
          else
            call trace_batch(scene, lay, rng, nphot, tal, pg)
          end if
          call batch_done()
        end if
        ! checkpoints: rank 0 decides at the same batches on every rank (all batches up to ib
        ! are then done); none after the last batch of a fixed budget
        if (checkpoints .and. (mod(ib, nranks) == 0 .or. ib == ib_last) .and. &
            .not. (ib == ib_last .and. cfg%control%target_rel_error <= 0.0_dp)) &
          call checkpoint_if_due()
      end do
      call cpu_time(c1)
      cpu = cpu + (c1 - c0)
      ib_next = ib_next + nb_round
      if (cfg%control%target_rel_error <= 0.0_dp) exit
      ! every rank takes the same decision from the same global sums, added in slot order
      allocate (buf(3*n_slots))
      buf = 0.0_dp
      do s = 0, n_slots - 1
        if (mod(s, nranks) == rank) buf(3*s + 1:3*s + 3) = &
          [slot(s)%s1(itarget), slot(s)%s2(itarget), real(slot(s)%n_batches, dp)]
      end do
      call par_allreduce_sum(buf)
      buf2 = buf(1:3)
      do s = 1, n_slots - 1
        buf2 = buf2 + buf(3*s + 1:3*s + 3)
      end do
      deallocate (buf)
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
    summary%peak_rss_batches = peak_resident_bytes()
    summary%sums_bytes = 16_i8*lay%n
    ! the batches are done: what follows needs the sums alone, so the batch buffers (each as
    ! large as the sums) are given back before the fold and the results
    call tally_free(tal)
    call tally_free(tal_g)
    if (allocated(spec%exact_buf)) deallocate (spec%exact_buf)

    counts = 0
    do s = 0, n_slots - 1
      if (mod(s, nranks) /= rank) cycle
      counts(1) = counts(1) + slot(s)%n_batches
      counts(2) = counts(2) + slot(s)%n_photons
      counts(3:4) = counts(3:4) + slot(s)%work
      counts(5:) = counts(5:) + slot(s)%anomalies
    end do
    call par_sum_to_root(counts)
    call fold_slots(slot, n_slots, st)
    block
      real(dp), allocatable :: flat(:)
      flat = reshape(rec, [size(rec)])
      flat = [flat, cpu]
      call par_sum_to_root(flat)
      rec = reshape(flat(1:size(rec)), shape(rec))
      cpu = flat(size(flat)) + cpu_before
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
    call build_results(cfg, scene, lay, st, rec(:, 1:nb_done), summary, set, defer_output)
    if (present(nml_text)) call add_attr(set, 'namelist', nml_text)

  contains

    !> Batch ib, traced into `tal`, goes into its slot s, the per-batch records and the progress.
    subroutine batch_done()
      call stats_add_batch(slot(s), lay, tal, nphot)
      rec(:, ib) = batch_budget(lay, tal)/real(nphot, dp)
      call progress_batch_done(pg, ib, ib_last)
    end subroutine batch_done

    !> A checkpoint of the batches up to ib (all done on every rank) when rank 0 says one is due.
    subroutine checkpoint_if_due()
      if (.not. checkpoint_due(plan, t_ckpt)) return
      call cpu_time(c1)
      call write_checkpoint(plan, cfg, lay, slot, n_slots, ib_next, ib, rec, &
                            cpu_before + cpu + (c1 - c0))
      t_ckpt = par_wtime()
      n_ckpt = n_ckpt + 1
      if (n_ckpt == kill_after .and. rank == 0) call kill_self()
    end subroutine checkpoint_if_due
  end subroutine simulate

  !> One batch of a broadband run: the plan spreads the batch's photons over the g-points
  !> (one uniform number of the batch's stream); each g-point with photons gets its optics in
  !> the 1-D layers (and, in the longwave, its emission table) and its photons are traced (the
  !> stream continues, so a batch depends on its index only, on any rank count). g-point g's
  !> photons start with the weight f_g = w_g n / S instead of 1 (and play roulette with its
  !> thresholds times f_g), straight into the batch's tallies: a photon then counts as 1/n of
  !> the total source S (TSI mu0, or the total emitted power), as in a monochromatic run, and
  !> the batch estimate is sum_g w_g x (g-point g's tallies), which is unbiased for the sum over
  !> g-points (docs/broadband.md). A longwave column that scatters nowhere is summed exactly
  !> over all g-points instead, each from the exact solution with weight P_g / S.
  !> When the ranks of a node share the voxels (spec%node), every rank of the node calls this
  !> together, `active` = .false. on a rank without a batch: each g-point that any of them
  !> traces is switched to by all.
  subroutine trace_spectral_batch(spec, scene, lay, rng, nphot, tal, tal_g, error, active, pg)
    type(spectral_scene_t), intent(inout) :: spec
    type(scene_t), intent(inout) :: scene
    type(tally_layout_t), intent(in) :: lay
    type(rng_t), intent(inout) :: rng
    integer(i8), intent(in) :: nphot
    type(tally_t), intent(inout) :: tal, tal_g
    type(error_t), allocatable, intent(out) :: error
    logical, intent(in), optional :: active
    type(progress_t), intent(inout), optional :: pg   !! rank 0's progress, looked at while tracing
    type(error_t), allocatable :: err
    real(dp) :: f, rr_threshold, rr_weight
    integer :: g
    integer, allocatable :: want(:)
    logical :: tracing
    if (spec%exact) then
      ! every batch is the same: computed once (for this batch size), then copied
      if (.not. allocated(spec%exact_buf) .or. spec%exact_n /= nphot) then
        do g = 1, spec%n_gpt
          call spectral_set_gpoint(spec, g, scene, error)
          if (allocated(error)) return
          call tally_reset(tal_g, lay)
          call exact_thermal_batch(scene, lay, nphot, tal_g, error)
          if (allocated(error)) return
          tal%buf = tal%buf + (spec%plan%energy(g)/spec%plan%total)*tal_g%buf
        end do
        scene%src%em = spec%em_sum
        spec%exact_buf = tal%buf
        spec%exact_n = nphot
      else
        tal%buf = spec%exact_buf
      end if
      return
    end if
    ! the plan and nphot >= 1 are checked at set-up: no error can occur here (the g-point
    ! switch of a 3-D scene repeats the set-up's atmosphere with other numbers)
    tracing = .true.
    if (present(active)) tracing = active
    allocate (want(spec%n_gpt))
    want = 0
    if (tracing) then
      call spectral_begin_batch(spec%plan, nphot, rng, spec%batch, err)
      where (spec%batch%count > 0) want = 1
    end if
    if (spec%node) call par_node_max(want)
    rr_threshold = scene%vr%rr_threshold
    rr_weight = scene%vr%rr_weight
    do g = 1, spec%n_gpt
      if (want(g) == 0) cycle
      call spectral_set_gpoint(spec, g, scene, error)
      if (allocated(error)) exit
      if (.not. tracing) cycle
      if (spec%batch%count(g) == 0) cycle
      ! the g-point's photons start with weight f and play roulette on the same scale
      f = spec%batch%weight(g)*real(nphot, dp)/spec%norm
      scene%src%w_unit = f
      scene%vr%rr_threshold = rr_threshold*f
      scene%vr%rr_weight = rr_weight*f
      call trace_batch(scene, lay, rng, spec%batch%count(g), tal, pg)
    end do
    scene%src%w_unit = 1.0_wp
    scene%vr%rr_threshold = rr_threshold
    scene%vr%rr_weight = rr_weight
    if (spec%longwave) scene%src%em = spec%em_sum
  end subroutine trace_spectral_batch

  !> The sums of all slots on rank 0, added in a fixed binary tree over the slots,
  !> ((S_0 + S_1) + (S_2 + S_3)) + ..., so that the order depends on the slot count alone (the
  !> rank count, or that of the run that wrote a checkpoint), never on timing. In each of the
  !> log2(n_slots) steps the ranks exchange in disjoint pairs, instead of rank 0 receiving every
  !> slot in turn (which grows with the rank count: docs/performance.md "Scaling to many ranks").
  !> With up to three slots the order is that of the plain sum (((S_0 + S_1) + S_2). All ranks
  !> walk the pairs in the same order, so the blocking moves always meet. The slots are taken
  !> apart (their arrays move into `st` or are freed).
  subroutine fold_slots(slot, n_slots, st)
    integer, intent(in) :: n_slots
    type(stats_t), intent(inout) :: slot(0:n_slots - 1)
    type(stats_t), intent(out) :: st
    real(dp), allocatable :: x(:)
    integer :: s, t, step, rank, nranks, os, ot
    rank = par_rank()
    nranks = par_size()
    step = 1
    do while (step < n_slots)
      do s = 0, n_slots - 1 - step, 2*step
        t = s + step          ! slot t is added to slot s, on the rank that owns s
        os = mod(s, nranks)
        ot = mod(t, nranks)
        if (rank == ot .and. ot /= os) then
          call send_sums(slot(t)%s1, ot, os)
          call send_sums(slot(t)%s2, ot, os)
          deallocate (slot(t)%s1, slot(t)%s2)
        else if (rank == os) then
          if (ot == os) then
            slot(s)%s1 = slot(s)%s1 + slot(t)%s1
            slot(s)%s2 = slot(s)%s2 + slot(t)%s2
            deallocate (slot(t)%s1, slot(t)%s2)
          else
            call add_sums(slot(s)%s1, x, ot, os)
            call add_sums(slot(s)%s2, x, ot, os)
          end if
        end if
      end do
      step = 2*step
    end do
    if (rank == 0) then   ! slot 0 is rank 0's and now holds the sum
      call move_alloc(slot(0)%s1, st%s1)
      call move_alloc(slot(0)%s2, st%s2)
    end if
  end subroutine fold_slots

  !> Send the sums `a` from rank `from` to rank `to` in pieces of FOLD_PIECE entries, as
  !> add_sums receives them.
  subroutine send_sums(a, from, to)
    real(dp), intent(inout) :: a(:)
    integer, intent(in) :: from, to
    integer :: j, k
    do j = 0, size(a) - 1, FOLD_PIECE
      k = min(FOLD_PIECE, size(a) - j)
      call par_move(a(j + 1:j + k), from, to)
    end do
  end subroutine send_sums

  !> Add to the sums `a` those sent by send_sums, piece by piece through the buffer `x` (one
  !> piece): the receiving rank never holds a second copy of the sums.
  subroutine add_sums(a, x, from, to)
    real(dp), intent(inout) :: a(:)
    real(dp), allocatable, intent(inout) :: x(:)
    integer, intent(in) :: from, to
    integer :: j, k
    if (.not. allocated(x)) allocate (x(min(FOLD_PIECE, size(a))))
    do j = 0, size(a) - 1, FOLD_PIECE
      k = min(FOLD_PIECE, size(a) - j)
      call par_move(x(1:k), from, to)
      a(j + 1:j + k) = a(j + 1:j + k) + x(1:k)
    end do
  end subroutine add_sums

end module kumo_driver
