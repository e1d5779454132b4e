! SPDX-License-Identifier: BSD-3-Clause
!> The photon loop: trace the photons of one batch through a scene and tally them.
!>
!> Forward Monte Carlo with weights (seed text chapter 2-3), written as the flowchart of the seed
!> text: a source launches a photon (kumo_source); it flies a sampled optical path (`fly`); the
!> flight ends in a collision (`collide`: absorption, then the scattering component), a
!> reflection at the surface (`reflect`) or an escape at the top; after a collision the photon
!> scatters (`scatter`: truncation, local estimates, roulette, a new direction, DDIS); fluxes
!> are scored where photons cross levels (method I of the seed text, section 3.8.2), absorption
!> where it happens, each through its named procedure of kumo_tally (`score_flux`,
!> `score_layer_abs`, ...), which alone knows the buffer layout. Variance-reduction settings
!> come from kumo_vr, the scene from kumo_scene.
!>
!> Per layer class (see kumo_atmosphere): clear layers are crossed in one step, purely absorbing
!> layers multiply the weight by exp(-tau) along the path and deposit the difference, uniform
!> scattering layers are traced analytically, and the 3-D region uses maximum-cross-section
!> (null-collision) tracking inside super-voxels (seed text section 4.1). Absorption is scored
!> at real collisions, or (`vr_t%abs_estimator`, kumo_vr) as its expectation along the flights:
!> w k_abs s for every piece of path, voxel by voxel (`absorb_path`), or w k_abs / k_majorant
!> at every tentative collision of the 3-D walk, or along the flights for the voxels alone and
!> at collisions for the layers (`track_voxels`); the random walk is the same. Photons carry the
!> index of their layer and super-voxel; positions are set exactly onto faces when crossing them,
!> and a position that round-off puts outside its cell is clamped back (and counted).
!>
!> No allocation, I/O or polymorphic dispatch happens in here. The event procedures are called
!> from one place each, so the compiler inlines them into one loop.
module kumo_transport
  use kumo_kinds, only: wp, dp, i8
  use kumo_rng, only: rng_t, rng_uniform, sample_azimuth
  use kumo_math, only: rotate_direction, wrap, UZ_MIN
  use kumo_phase, only: phase_sample_mu
  use kumo_truncation, only: trunc_sample_mu
  use kumo_local_estimate, only: detectors_t, le_particle, le_surface, ddis_factor, &
                                 ddis_direction, le_boundary_emission
  use kumo_voxel_walk, only: voxel_walk_t, walk_segment, walk_next, walk_layer
  use kumo_atmosphere, only: atmosphere_t, column_of, column_xy, voxel_ext, voxel_omg, &
                             similarity_blend_weight, &
                             LAYER_CLEAR, LAYER_ABSORBING, LAYER_SCATTERING, LAYER_3D
  use kumo_brdf, only: brdf_albedo, brdf_sample, lambert_direction
  use kumo_tally, only: tally_layout_t, tally_t, ANOM_UZ_NUDGED, ANOM_EVENT_CAP, &
                        ANOM_STEP_CAP, ANOM_POSITION_REPAIR, ANOM_BRDF_ENVELOPE, score_flux, &
                        score_flux_map, score_layer_abs, score_voxel_abs, score_surface_abs, &
                        score_roulette, score_lost, score_source, score_net_layer, &
                        score_net_surface, score_net_voxel, tally_flush, &
                        radiance_maps_integrate
  use kumo_photon, only: photon_t
  use kumo_source, only: launch_plan_t, source_begin_batch, source_launch
  use kumo_emission, only: emission_b_point, emission_b_segment, emission_b_surface, &
                           EMIT_SOLAR, EMIT_TOP, EMIT_SURFACE, EMIT_LAYER, emission_t
  use kumo_vr, only: roulette, ABS_COLLISION, ABS_TRACK, ABS_TENTATIVE, ABS_TRACK_VOXELS
  use kumo_scene, only: scene_t
  use kumo_progress, only: progress_t, progress_look
  implicit none
  private
  public :: trace_batch

  !> How a flight ends: it goes on (EV_NONE), or the photon collides, escapes at the top,
  !> reaches the surface, or was killed by roulette on its way.
  integer, parameter :: EV_NONE = 0, EV_COLLISION = 1, EV_ESCAPE = 2, EV_SURFACE = 3, &
                        EV_KILLED = 4
  !> Where score_net books the absorbed weight besides layers 1..nz: nowhere, or the surface.
  integer, parameter :: CELL_NONE = 0, CELL_SURFACE = -1
  !> Most DDIS secondaries queued per photon (secondaries do not split again).
  integer, parameter :: MAX_PENDING = 64

  !> What stays the same for every photon of a batch.
  type :: batch_t
    logical :: track_xy  !! horizontal positions matter in the 1-D layers
    logical :: forced    !! collision forcing on
    logical :: plain     !! no local estimates, forcing or truncation: the plain scattering
    real(wp) :: inv_cf   !! 1/(collision-forcing factor)
    logical :: thermal   !! thermal emission: net-exchange tallies (kumo_emission)
    !> absorption scored along the flights (ABS_TRACK, ABS_TENTATIVE, ABS_TRACK_VOXELS)
    logical :: track
    !> ... for the layers and the domain too, not at collisions (ABS_TRACK, ABS_TENTATIVE)
    logical :: track_layers
    integer :: est3      !! ABS_* estimator of the 3-D null-collision walk
  end type batch_t

  !> DDIS secondaries of the current photon waiting to be traced, last in first out: position,
  !> direction and weight (r), layer, order and truncation level (i).
  type :: pending_t
    integer :: n = 0
    real(wp) :: r(7, MAX_PENDING)
    integer :: i(3, MAX_PENDING)
  end type pending_t

contains

  !> Trace `n_photons` photons of scene `scn`, adding into `tal` (which the caller has reset).
  subroutine trace_batch(scn, lay, rng, n_photons, tal, pg)
    type(scene_t), intent(in) :: scn
    type(tally_layout_t), intent(in) :: lay
    type(rng_t), intent(inout) :: rng
    integer(i8), intent(in) :: n_photons
    type(tally_t), intent(inout) :: tal
    !> rank 0's progress: the clock is looked at every pg%stride photons (kumo_progress)
    type(progress_t), intent(inout), optional :: pg
    type(batch_t) :: bat
    type(launch_plan_t) :: plan
    type(photon_t) :: p
    type(pending_t) :: pend
    integer(i8) :: ip, look
    integer :: k
    logical :: watch

    ! the photon at which to look at the clock next (never without progress lines)
    watch = .false.
    if (present(pg)) watch = pg%on
    look = huge(look)
    if (watch) look = max(1_i8, pg%next_look - pg%base)
    ! Horizontal positions matter only for a 3-D region, an albedo map, per-column maps or
    ! cameras; a plane-parallel scene skips their bookkeeping in the 1-D layers.
    bat%track_xy = scn%atm%n3 > 0 .or. .not. scn%sfc%uniform .or. lay%do_maps .or. &
                   lay%do_rad_maps .or. size(scn%det%cams) > 0
    ! Collision forcing (seed text section 4.2.4 a): free paths are sampled in the extinction
    ! cf_factor * sigma; see `collide`.
    bat%forced = scn%vr%cf_factor > 1.0_wp
    bat%inv_cf = 1.0_wp/scn%vr%cf_factor
    bat%plain = .not. (scn%det%active .or. bat%forced .or. scn%atm%truncated)
    bat%thermal = scn%src%em%on
    ! The expected-value absorption scores serve solar runs; the net-exchange tallies of thermal
    ! runs need the Planck radiance where the weight is absorbed, so those stay at collisions.
    bat%est3 = scn%vr%abs_estimator
    if (bat%thermal) bat%est3 = ABS_COLLISION
    ! voxels scored along the flights, but no voxel tallies: nothing to score on the way
    if (bat%est3 == ABS_TRACK_VOXELS .and. .not. lay%do_voxel) bat%est3 = ABS_COLLISION
    bat%track = bat%est3 /= ABS_COLLISION
    bat%track_layers = bat%est3 == ABS_TRACK .or. bat%est3 == ABS_TENTATIVE
    call source_begin_batch(scn%src, n_photons, rng, plan)
    do ip = 1, n_photons
      call source_launch(scn%src, plan, scn%atm, scn%sfc, rng, ip, p)
      if (bat%thermal) then
        call start_emitted(scn, lay, tal, rng, p)
      else
        call tally_level(scn%atm, lay, tal, scn%atm%nz, .false., 0, p%w, p%x, p%y)
      end if
      pend%n = 0
      history: do
        call trace_photon(scn, bat, lay, rng, tal, p, pend)
        if (pend%n == 0) exit history
        call pop_secondary(pend, p)
      end do history
      tal%work(1) = tal%work(1) + p%n_steps
      tal%work(2) = tal%work(2) + p%n_events
      if (ip >= look) then
        call progress_look(pg, pg%base + ip)
        look = pg%next_look - pg%base
      end if
    end do
    if (watch) pg%base = pg%base + n_photons
    ! layers whose net power is absorbed minus emitted: their emission, exact, per batch
    if (bat%thermal) then
      if (scn%src%em%any_abs) then
        do k = 1, lay%nz
          if (scn%src%em%by_abs(k)) call score_net_layer(lay, tal, k, &
            -(scn%src%em%emit_layer(k)*real(n_photons, wp)/scn%src%em%power*scn%src%w_unit))
        end do
      end if
    end if
    ! the voxel absorption at collisions is logged while photons fly
    call tally_flush(tal)
    ! diffused radiance-map samples were added as block differences
    call radiance_maps_integrate(lay, tal)
  end subroutine trace_batch

  !> Follow photon `p` from its current state until it escapes, is absorbed, killed or lost:
  !> flights and the events that end them.
  subroutine trace_photon(scn, bat, lay, rng, tal, p, pend)
    type(scene_t), intent(in) :: scn
    type(batch_t), intent(in) :: bat
    type(tally_layout_t), intent(in) :: lay
    type(rng_t), intent(inout) :: rng
    type(tally_t), intent(inout) :: tal
    type(photon_t), intent(inout) :: p
    type(pending_t), intent(inout) :: pend
    real(wp) :: tau, ps
    integer :: ev, ix, iy, kr, iph
    logical :: in3d, move_xy, alive

    ! ICA and P3D: beyond its 3-D orders the photon keeps its column (x, y fixed)
    p%column = p%order >= scn%n_3d
    move_xy = bat%track_xy .and. .not. p%column
    photon: do
      if (p%order >= scn%n_3d .and. .not. p%column) then
        p%column = .true.
        move_xy = .false.
      end if
      tau = -log(1.0_wp - rng_uniform(rng))
      if (bat%forced) tau = tau*bat%inv_cf
      flight: do
        p%n_steps = p%n_steps + 1
        if (p%n_steps > scn%max_steps) then
          tal%anomalies(ANOM_STEP_CAP) = tal%anomalies(ANOM_STEP_CAP) + 1
          call score_lost(lay, tal, p%w)
          return
        end if
        call fly(scn, bat, lay, tal, rng, p, move_xy, tau, ev, in3d, ix, iy, kr)
        select case (ev)
        case (EV_NONE)
          cycle flight
        case (EV_SURFACE)
          call reflect(scn, lay, tal, rng, p, alive)
          if (.not. alive) return
          exit flight
        case (EV_COLLISION)
          call collide(scn, bat, lay, tal, rng, p, in3d, ix, iy, kr, ps, iph, alive)
          if (.not. alive) return
          if (bat%plain) then
            call scatter_plain(scn, lay, tal, rng, p, iph, alive)
          else
            call scatter(scn, bat, lay, tal, rng, p, iph, ps, pend, alive)
          end if
          if (.not. alive) return
          exit flight
        case (EV_ESCAPE)
          ! the top absorbs what leaves, and emits B_top
          if (bat%thermal) call score_net(lay, tal, p, scn%src%em, p%w, scn%src%em%b_top, &
                                          CELL_NONE, 0)
          return
        case default   ! EV_KILLED
          return
        end select
      end do flight
    end do photon
  end subroutine trace_photon

  !> One flight step along the remaining optical path `tau`: through one 1-D layer, or through
  !> the 3-D region until a collision or until the photon leaves it. Levels crossed are scored.
  !> `ev` tells how it ended; for a collision, `in3d` and the voxel (ix, iy, kr) say where.
  subroutine fly(scn, bat, lay, tal, rng, p, move_xy, tau, ev, in3d, ix, iy, kr)
    type(scene_t), intent(in) :: scn
    type(batch_t), intent(in) :: bat
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    type(photon_t), intent(inout) :: p
    logical, intent(in) :: move_xy
    real(wp), intent(inout) :: tau
    integer, intent(out) :: ev, ix, iy, kr
    logical, intent(out) :: in3d
    real(wp) :: zb, d, e, wn
    integer :: cls

    cls = scn%atm%layer_class(p%iz)
    if (cls == LAYER_3D) then
      if (p%column) then
        call fly_column(scn%atm, lay, tal, p%x, p%y, p%z, p%uz, p%w, p%order, p%iz, tau, &
                        p%n_steps, scn%max_steps, bat%track, bat%track_layers, ev, ix, iy, kr)
      else
        call fly_3d(scn%atm, lay, tal, rng, p%x, p%y, p%z, p%ux, p%uy, p%uz, p%w, p%order, p%iz, &
                    tau, p%n_steps, scn%max_steps, bat%inv_cf, bat%est3, ev, ix, iy, kr)
      end if
      in3d = .true.
      return
    end if
    in3d = .false.
    ix = 0
    iy = 0
    kr = 0
    zb = level_ahead(scn%atm, p%iz, p%uz)
    d = (zb - p%z)/p%uz
    ev = EV_NONE
    select case (cls)
    case (LAYER_SCATTERING)
      e = scn%atm%ext1(p%iz)
      if (tau < e*d) then
        d = tau/e
        if (bat%track_layers) call score_track(lay, tal, p%iz, p%w*(tau*(1.0_wp - scn%atm%omg1(p%iz))))
        p%z = p%z + p%uz*d
        if (move_xy) then
          p%x = p%x + p%ux*d
          p%y = p%y + p%uy*d
          call wrap(p%x, scn%atm%lx)
          call wrap(p%y, scn%atm%ly)
        end if
        ev = EV_COLLISION
        return
      end if
      if (bat%track_layers) call score_track(lay, tal, p%iz, p%w*((e*d)*(1.0_wp - scn%atm%omg1(p%iz))))
      tau = tau - e*d
    case (LAYER_ABSORBING)
      wn = p%w*exp(-scn%atm%ext1(p%iz)*d)
      call score_layer_abs(lay, tal, p%iz, p%w - wn)
      if (bat%thermal) call score_net(lay, tal, p, scn%src%em, p%w - wn, &
        emission_b_segment(scn%src%em, scn%atm, p%iz, p%z, zb, scn%atm%ext1(p%iz)*d), p%iz, 0)
      p%w = wn
    case default ! LAYER_CLEAR
    end select
    p%z = zb
    if (move_xy) then
      p%x = p%x + p%ux*d
      p%y = p%y + p%uy*d
      call wrap(p%x, scn%atm%lx)
      call wrap(p%y, scn%atm%ly)
    end if
    call cross_level(scn%atm, lay, tal, p%x, p%y, p%uz, p%w, p%order, p%iz, ev)
    if (cls == LAYER_ABSORBING .and. ev == EV_NONE) then
      call roulette(scn%vr, lay, tal, rng, p%w)
      if (p%w <= 0.0_wp) ev = EV_KILLED
    end if
  end subroutine fly

  !> Reflection at the surface (seed text sections 3.6, 3.6.3): the absorbed part is scored, the
  !> weight is multiplied by the albedo (Lambert) or the directional albedo (BRDF), local
  !> estimates see the surface, and a new upward direction is drawn (cosine-weighted, or from
  !> BRDF mu_out / albedo). `alive` is false when the photon ends here.
  subroutine reflect(scn, lay, tal, rng, p, alive)
    type(scene_t), intent(in) :: scn
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    type(photon_t), intent(inout) :: p
    logical, intent(out) :: alive
    real(wp) :: albedo, u_out(3)
    integer :: kb

    alive = .false.
    p%n_events = p%n_events + 1
    if (scn%sfc%black) then
      call score_surface_abs(lay, tal, p%w)
      if (scn%src%em%on) call score_net(lay, tal, p, scn%src%em, p%w, &
                                        emission_b_surface(scn%src%em, p%x, p%y), CELL_SURFACE, 0)
      return
    end if
    kb = 1
    if (scn%sfc%use_brdf) then
      kb = scn%sfc%class_at(p%x, p%y)
      albedo = brdf_albedo(scn%sfc%tabs(kb), -p%uz)
    else
      albedo = scn%sfc%albedo_at(p%x, p%y)
    end if
    call score_surface_abs(lay, tal, p%w*(1.0_wp - albedo))
    if (scn%src%em%on) call score_net(lay, tal, p, scn%src%em, p%w*(1.0_wp - albedo), &
                                      emission_b_surface(scn%src%em, p%x, p%y), CELL_SURFACE, 0)
    p%w = p%w*albedo
    if (p%w <= 0.0_wp) return
    if (scn%det%active) call le_surface(scn%det, scn%atm, lay, tal, rng, scn%sfc, kb, p%x, p%y, &
                                        p%ux, p%uy, p%uz, p%w, p%lev, p%column)
    call roulette(scn%vr, lay, tal, rng, p%w)
    if (p%w <= 0.0_wp) return
    if (scn%sfc%use_brdf) then
      call brdf_sample(scn%sfc%tabs(kb), [p%ux, p%uy, p%uz], rng, u_out, &
                       tal%anomalies(ANOM_BRDF_ENVELOPE))
      p%ux = u_out(1)
      p%uy = u_out(2)
      p%uz = u_out(3)
    else
      call lambert_direction(rng, p%ux, p%uy, p%uz)
    end if
    if (p%uz < UZ_MIN) then
      p%uz = UZ_MIN
      tal%anomalies(ANOM_UZ_NUDGED) = tal%anomalies(ANOM_UZ_NUDGED) + 1
    end if
    p%order = p%order + 1
    p%z = scn%atm%z(0)
    p%iz = 1
    call tally_level(scn%atm, lay, tal, 0, .true., p%order, p%w, p%x, p%y)
    if (p%n_events > scn%max_events) then
      call lose_photon(lay, tal, ANOM_EVENT_CAP, p%w)
      return
    end if
    alive = .true.
  end subroutine reflect

  !> A collision (seed text section 3.4.3 b): the absorbed part of the weight is scored (per
  !> layer, and per voxel in the 3-D region), then the scattering component and its phase
  !> function `iph` are drawn. With collision forcing the medium has the extinction F sigma and
  !> the albedo omega' = 1 - (1 - omega)/F, so absorption is unchanged; the collision is a real
  !> scattering with probability ps = omega/(F omega') (eq. 4.2.42-45), else the photon goes on
  !> undeflected (see `scatter`).
  subroutine collide(scn, bat, lay, tal, rng, p, in3d, ix, iy, kr, ps, iph, alive)
    type(scene_t), intent(in) :: scn
    type(batch_t), intent(in) :: bat
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    type(photon_t), intent(inout) :: p
    logical, intent(in) :: in3d
    integer, intent(in) :: ix, iy, kr
    real(wp), intent(out) :: ps
    integer, intent(out) :: iph
    logical, intent(out) :: alive
    real(wp) :: omega, wn, e, wb
    integer :: ic, nc, iv

    alive = .false.
    iph = 1
    p%n_events = p%n_events + 1
    if (in3d) then
      omega = voxel_omg(scn%atm, ix, iy, kr)
    else
      omega = scn%atm%omg1(p%iz)
    end if
    ps = 1.0_wp
    if (bat%forced) then
      wn = 1.0_wp - (1.0_wp - omega)*bat%inv_cf
      if (wn > 0.0_wp) ps = omega*bat%inv_cf/wn
      wn = p%w*wn
    else
      wn = p%w*omega
    end if
    if (bat%track_layers) then
      ! absorption was scored along the flight; what the weight loses here is booked against it
      call score_roulette(lay, tal, -(p%w - wn))
    else
      call score_layer_abs(lay, tal, p%iz, p%w - wn)
      ! ABS_TRACK_VOXELS: the voxels were scored along the flight
      if (in3d .and. .not. bat%track) call score_voxel_abs(lay, tal, kr, &
                                                           ix + (iy - 1)*scn%atm%nx, p%w - wn)
    end if
    if (bat%thermal) then
      ! 1-D layers come with ix = iy = kr = 0 (fly), for which emission_b_point takes the level
      ! values
      iv = 0
      if (in3d) iv = (kr - 1)*lay%ncol + ix + (iy - 1)*scn%atm%nx
      call score_net(lay, tal, p, scn%src%em, p%w - wn, &
                     emission_b_point(scn%src%em, scn%atm, p%iz, p%z, ix, iy, kr), p%iz, iv)
    end if
    p%w = wn
    if (p%w <= 0.0_wp) return
    if (p%n_events > scn%max_events) then
      call lose_photon(lay, tal, ANOM_EVENT_CAP, p%w)
      return
    end if
    associate (atm => scn%atm)
      if (in3d) then
        nc = atm%ncomp
        ic = 1
        if (nc > 1) then
          e = rng_uniform(rng)
          do ic = 1, nc - 1
            if (e < atm%csca3(ic, ix, iy, kr)) exit
          end do
        end if
        if (associated(atm%iph3)) then
          iph = atm%iph3(ic, ix, iy, kr)
        else
          iph = atm%iph3_const(ic)
        end if
        if (associated(atm%wph3)) then
          ! a blend of tables iph and iph + 1: the photon takes table iph + 1 with
          ! probability w, which samples (1 - w) P(iph) + w P(iph + 1) exactly
          wb = atm%wph3(ic, ix, iy, kr)
          if (wb > 0.0_wp) then
            ! similarity-scaled: the weight of table iph + 1 in the blend's normalised rest
            if (atm%similar) wb = similarity_blend_weight(atm%sim, iph, wb)
            if (rng_uniform(rng) < wb) iph = iph + 1
          end if
        end if
      else
        nc = atm%ncomp1
        iph = atm%iph1(1, p%iz)
        if (nc > 1) then
          e = rng_uniform(rng)
          do ic = 1, nc
            if (e < atm%csca1(ic, p%iz)) exit
          end do
          iph = atm%iph1(min(ic, nc), p%iz)
        end if
      end if
    end associate
    alive = .true.
  end subroutine collide

  !> Scattering by phase function `iph` after a collision in a run without local estimates,
  !> collision forcing or truncation (seed text section 3.5): roulette, then a new direction.
  subroutine scatter_plain(scn, lay, tal, rng, p, iph, alive)
    type(scene_t), intent(in) :: scn
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    type(photon_t), intent(inout) :: p
    integer, intent(in) :: iph
    logical, intent(out) :: alive
    real(wp) :: mu, cphi, sphi
    alive = .false.
    call roulette(scn%vr, lay, tal, rng, p%w)
    if (p%w <= 0.0_wp) return
    p%order = p%order + 1
    if (scn%atm%similar) then
      ! similarity-scaled optics: the normalised truncated phase function
      mu = trunc_sample_mu(scn%atm%sim, scn%atm%phases(iph), iph, 2, rng_uniform(rng))
    else
      mu = phase_sample_mu(scn%atm%phases(iph), rng_uniform(rng))
    end if
    call sample_azimuth(rng, cphi, sphi)
    call rotate_direction(p%ux, p%uy, p%uz, mu, cphi, sphi)
    call nudge_uz(tal, p)
    alive = .true.
  end subroutine scatter_plain

  !> Scattering by phase function `iph` after a collision, with the variance reduction that
  !> serves radiances (seed text sections 3.5, 4.2): truncation, local estimates, roulette,
  !> the new direction, DDIS. `ps` is the chance that a forced collision is a real scattering.
  subroutine scatter(scn, bat, lay, tal, rng, p, iph, ps, pend, alive)
    type(scene_t), intent(in) :: scn
    type(batch_t), intent(in) :: bat
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    type(photon_t), intent(inout) :: p
    integer, intent(in) :: iph
    real(wp), intent(in) :: ps
    type(pending_t), intent(inout) :: pend
    logical, intent(out) :: alive
    real(wp) :: mu, cphi, sphi, uxi, uyi, uzi
    logical :: split

    alive = .false.
    associate (atm => scn%atm, det => scn%det)
      ! Truncation (seed text eq. 4.2.19): with probability f the scattering belongs to the
      ! delta peak and the photon keeps its direction; it is still a scattering.
      if (atm%truncated) then
        if (rng_uniform(rng) < atm%trunc%f(p%lev, iph)) then
          p%order = p%order + 1
          call roulette(scn%vr, lay, tal, rng, p%w)
          alive = p%w > 0.0_wp
          return
        end if
      end if
      ! local estimates before the roulette, so that a light photon (a DDIS secondary) still
      ! contributes with its own weight
      if (det%active) call le_particle(det, atm, lay, tal, rng, p%x, p%y, p%z, p%iz, p%ux, &
                                       p%uy, p%uz, p%w*ps, iph, p%lev, ps, p%column)
      call roulette(scn%vr, lay, tal, rng, p%w)
      if (p%w <= 0.0_wp) return
      if (bat%forced) then
        if (rng_uniform(rng) >= ps) then
          alive = .true.
          return
        end if
      end if
      p%order = p%order + 1
      call sample_azimuth(rng, cphi, sphi)
      uxi = p%ux
      uyi = p%uy
      uzi = p%uz
      split = .false.
      if (atm%truncated) then
        mu = trunc_sample_mu(atm%trunc, atm%phases(iph), iph, p%lev, rng_uniform(rng))
      else if (atm%similar) then
        mu = trunc_sample_mu(atm%sim, atm%phases(iph), iph, 2, rng_uniform(rng))
      else
        mu = phase_sample_mu(atm%phases(iph), rng_uniform(rng))
      end if
      call rotate_direction(p%ux, p%uy, p%uz, mu, cphi, sphi)
      if (det%ddis_eps > 0.0_wp .and. .not. p%secondary .and. pend%n < MAX_PENDING) then
        split = det%ddis_phase(iph)
      end if
      if (split) call ddis_split(atm, lay, det, tal, rng, iph, p%lev, p%order, p%iz, p%x, p%y, &
                                 p%z, uxi, uyi, uzi, p%ux, p%uy, p%uz, p%w, pend%n, pend%r, &
                                 pend%i)
      if (atm%truncated) then
        if (p%lev < atm%trunc%n_levels .and. mu <= atm%trunc%mu_peak(iph)) p%lev = p%lev + 1
      end if
    end associate
    call nudge_uz(tal, p)
    alive = .true.
  end subroutine scatter

  !> A direction after scattering that is too close to horizontal for the level-to-level walk
  !> is nudged to |uz| = UZ_MIN (and counted).
  subroutine nudge_uz(tal, p)
    type(tally_t), intent(inout) :: tal
    type(photon_t), intent(inout) :: p
    if (abs(p%uz) < UZ_MIN) then
      p%uz = sign(UZ_MIN, p%uz)
      tal%anomalies(ANOM_UZ_NUDGED) = tal%anomalies(ANOM_UZ_NUDGED) + 1
    end if
  end subroutine nudge_uz

  !> The next DDIS secondary of the current photon becomes the photon (its counts of steps and
  !> events go on: the caps apply to a photon and its secondaries together).
  subroutine pop_secondary(pend, p)
    type(pending_t), intent(inout) :: pend
    type(photon_t), intent(inout) :: p
    p%x = pend%r(1, pend%n)
    p%y = pend%r(2, pend%n)
    p%z = pend%r(3, pend%n)
    p%ux = pend%r(4, pend%n)
    p%uy = pend%r(5, pend%n)
    p%uz = pend%r(6, pend%n)
    p%w = pend%r(7, pend%n)
    p%iz = pend%i(1, pend%n)
    p%order = pend%i(2, pend%n)
    p%lev = pend%i(3, pend%n)
    pend%n = pend%n - 1
    p%secondary = .true.
  end subroutine pop_secondary

  !> DDIS split at a scattering (kumo_local_estimate, ddis_factor): the photon, now leaving along
  !> (ux, uy, uz) after arriving along (uxi, uyi, uzi), keeps its direction with a weight factor,
  !> and with probability eps a secondary is queued. Kept out of trace_batch so that the photon
  !> loop of runs without it stays small enough for the compiler to inline its hot calls.
  subroutine ddis_split(atm, lay, det, tal, rng, iph, lev, order, iz, x, y, z, uxi, uyi, uzi, &
                        ux, uy, uz, w, n_pending, pend_r, pend_i)
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(detectors_t), intent(in) :: det
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    integer, value :: iph, lev, order, iz
    real(wp), value :: x, y, z, uxi, uyi, uzi, ux, uy, uz
    real(wp), intent(inout) :: w
    integer, intent(inout) :: n_pending
    real(wp), intent(inout) :: pend_r(:, :)
    integer, intent(inout) :: pend_i(:, :)
    real(wp) :: fa, wn, wb, c2, s2, vx, vy, vz
    integer :: levb
    logical :: inside
    fa = ddis_factor(det, atm, iph, lev, uxi, uyi, uzi, ux, uy, uz)
    wn = w*fa
    inside = .false.
    if (rng_uniform(rng) < det%ddis_eps) then
      call sample_azimuth(rng, c2, s2)
      call ddis_direction(det, atm, rng, iph, lev, c2, s2, vx, vy, vz, inside)
    end if
    if (inside) then
      wb = w*ddis_factor(det, atm, iph, lev, uxi, uyi, uzi, vx, vy, vz)
      levb = lev
      if (atm%truncated) then
        if (lev < atm%trunc%n_levels .and. uxi*vx + uyi*vy + uzi*vz <= &
            atm%trunc%mu_peak(iph)) levb = lev + 1
      end if
      if (abs(vz) < UZ_MIN) vz = sign(UZ_MIN, vz)
      n_pending = n_pending + 1
      pend_r(:, n_pending) = [x, y, z, vx, vy, vz, wb]
      pend_i(:, n_pending) = [iz, order, levb]
      wn = wn + wb
    end if
    ! the split creates or removes weight, zero in expectation: booked like roulette
    call score_roulette(lay, tal, wn - w)
    w = w*fa
  end subroutine ddis_split

  !> Photon crosses the level at the end of its layer: tally it and move it to the next layer.
  !> Sets `ev` to EV_ESCAPE at the top, EV_SURFACE at the bottom, 0 otherwise.
  subroutine cross_level(atm, lay, tal, x, y, uz, w, order, iz, ev)
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    real(wp), intent(in) :: x, y, uz, w
    integer, intent(in) :: order
    integer, intent(inout) :: iz
    integer, intent(out) :: ev
    ev = 0
    if (uz > 0.0_wp) then
      call tally_level(atm, lay, tal, iz, .true., order, w, x, y)
      if (iz == atm%nz) then
        ev = EV_ESCAPE
      else
        iz = iz + 1
      end if
    else
      call tally_level(atm, lay, tal, iz - 1, .false., order, w, x, y)
      if (iz == 1) then
        ev = EV_SURFACE
      else
        iz = iz - 1
      end if
    end if
  end subroutine cross_level

  !> Count weight `w` crossing level k upward (`up`) or downward, direct if order is 0.
  subroutine tally_level(atm, lay, tal, k, up, order, w, x, y)
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: k, order
    logical, intent(in) :: up
    real(wp), intent(in) :: w, x, y
    integer :: slot
    call score_flux(lay, tal, k, up, order, w)
    if (.not. lay%do_maps) return
    slot = lay%map_slot(k)
    if (slot == 0) return
    call score_flux_map(lay, tal, slot, up, order, column_of(atm, x, y), w)
  end subroutine tally_level

  !> Null-collision flight inside the 3-D region until a real collision (ev = EV_COLLISION, with
  !> the voxel ix, iy, kr), or until the photon leaves the region through its top or bottom
  !> (ev from cross_level: 0, EV_ESCAPE or EV_SURFACE). `tau` is the optical path left to fly.
  !>
  !> The photon walks the majorant grid as a 3-D digital differential analyser: the distances
  !> to the next x face, y face and level are kept and decreased as it moves, and only the one
  !> that is crossed is recomputed, from the width of the block or layer it enters. Levels
  !> inside the region (within a super-layer or between two) are tallied here and the walk goes
  !> on, so that the caller sees the photon again only at a collision or when it leaves.
  subroutine fly_3d(atm, lay, tal, rng, x, y, z, ux, uy, uz, w, order, iz, tau, n_steps, &
                    max_steps, inv_cf, est, ev, ix, iy, kr)
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    real(wp), intent(inout) :: x, y, z, tau
    real(wp), intent(in) :: ux, uy, uz, w
    integer, intent(in) :: order
    integer, intent(inout) :: iz
    integer(i8), intent(inout) :: n_steps
    integer(i8), intent(in) :: max_steps
    real(wp), intent(in) :: inv_cf  !! 1/(collision-forcing factor)
    integer, intent(in) :: est      !! absorption estimator (ABS_*): what is scored on the way
    integer, intent(out) :: ev, ix, iy, kr
    integer :: s, jx, jy, bx, by, nbx, nby, off, ixlo, ixhi, iylo, iyhi
    real(wp) :: dxf, dyf, dzf, d, smax, bdx, bdy, xlo, ylo, rux, ruy, ruz, e
    real(wp) :: xs, ys, sl  !! ABS_TRACK(_VOXELS): start and length of the straight path in this layer
    logical :: along        !! ABS_TRACK(_VOXELS): the voxels are scored along the path
    type(voxel_walk_t) :: wk  !! ... by this voxel walk, which goes on from layer to layer
    logical :: walking

    ev = 0
    along = est == ABS_TRACK .or. est == ABS_TRACK_VOXELS
    walking = .false.
    ix = 0
    iy = 0
    ! path length per unit of x, y and z travelled (unused along an axis the photon does not
    ! move: that face distance is huge)
    rux = 0.0_wp
    ruy = 0.0_wp
    if (abs(ux) > 0.0_wp) rux = 1.0_wp/abs(ux)
    if (abs(uy) > 0.0_wp) ruy = 1.0_wp/abs(uy)
    ruz = 1.0_wp/abs(uz)
    kr = iz - atm%k3_lo + 1
    if (uz > 0.0_wp) then
      dzf = max(0.0_wp, (atm%z(iz) - z)*ruz)
    else
      dzf = max(0.0_wp, (z - atm%z(iz - 1))*ruz)
    end if
    xs = x
    ys = y
    sl = 0.0_wp

    superlayer: do
      ! enter super-layer s: the block under the photon and the distances to its x and y faces
      s = atm%sv%sl_of_layer(kr)
      bx = atm%sv%bx(s)
      by = atm%sv%by(s)
      nbx = atm%sv%nbx(s)
      nby = atm%sv%nby(s)
      off = atm%sv%off(s)
      bdx = bx*atm%dx
      bdy = by*atm%dy
      jx = min(nbx, int(x/bdx) + 1)
      jy = min(nby, int(y/bdy) + 1)
      xlo = (jx - 1)*bdx
      ylo = (jy - 1)*bdy
      if (ux > 0.0_wp) then
        dxf = max(0.0_wp, (min(atm%lx, xlo + bdx) - x)*rux)
      else if (ux < 0.0_wp) then
        dxf = max(0.0_wp, (x - xlo)*rux)
      else
        dxf = huge(1.0_wp)
      end if
      if (uy > 0.0_wp) then
        dyf = max(0.0_wp, (min(atm%ly, ylo + bdy) - y)*ruy)
      else if (uy < 0.0_wp) then
        dyf = max(0.0_wp, (y - ylo)*ruy)
      else
        dyf = huge(1.0_wp)
      end if
      smax = atm%sv%maj(off + jx + (jy - 1)*nbx)

      step: do
        n_steps = n_steps + 1
        if (n_steps > max_steps) return   ! the caller's step check stops the photon
        ! the nearest face; which one it is matters only if the photon gets there
        d = min(dzf, dxf, dyf)

        if (smax*d > tau) then
          ! tentative collision inside the block
          d = tau/smax
          sl = sl + d
          x = x + ux*d
          y = y + uy*d
          z = z + uz*d
          dxf = dxf - d
          dyf = dyf - d
          dzf = dzf - d
          ix = int(x*atm%inv_dx) + 1
          iy = int(y*atm%inv_dy) + 1
          ixlo = (jx - 1)*bx + 1
          ixhi = min(atm%nx, jx*bx)
          iylo = (jy - 1)*by + 1
          iyhi = min(atm%ny, jy*by)
          if (ix < ixlo .or. ix > ixhi .or. iy < iylo .or. iy > iyhi) then
            ix = min(ixhi, max(ixlo, ix))
            iy = min(iyhi, max(iylo, iy))
            tal%anomalies(ANOM_POSITION_REPAIR) = tal%anomalies(ANOM_POSITION_REPAIR) + 1
          end if
          e = voxel_ext(atm, ix, iy, kr)
          ! tentative collisions come at the rate smax/inv_cf: w k_abs inv_cf/smax at each is
          ! the track-length score in expectation
          if (est == ABS_TENTATIVE) call score_voxel(atm, lay, tal, iz, ix, iy, kr, &
            w*((e*(1.0_wp - voxel_omg(atm, ix, iy, kr)))*(inv_cf/smax)), .true.)
          ! real with probability e/smax; no random number is needed when the voxel is its
          ! block's majorant (always so for a block of one voxel)
          if (e < smax) then
            if (rng_uniform(rng)*smax >= e) then
              tau = -log(1.0_wp - rng_uniform(rng))*inv_cf
              cycle step
            end if
          end if
          call wrap(x, atm%lx)
          call wrap(y, atm%ly)
          if (along) call absorb_path(atm, lay, tal, iz, xs, ys, ux, uy, sl, w, est == ABS_TRACK, &
                                      wk, walking)
          ev = EV_COLLISION
          return
        end if

        ! cross the nearest face (the level where it ties with a side face, then x before y)
        tau = tau - smax*d
        sl = sl + d
        if (dzf <= dxf .and. dzf <= dyf) then
          ! a level: tally it; leave the region, or go on in the next layer
          x = x + ux*d
          y = y + uy*d
          call wrap(x, atm%lx)
          call wrap(y, atm%ly)
          dxf = dxf - d
          dyf = dyf - d
          if (uz > 0.0_wp) then
            z = atm%z(iz)
          else
            z = atm%z(iz - 1)
          end if
          if (along) then
            call absorb_path(atm, lay, tal, iz, xs, ys, ux, uy, sl, w, est == ABS_TRACK, wk, &
                             walking)
            xs = x
            ys = y
            sl = 0.0_wp
          end if
          call cross_level(atm, lay, tal, x, y, uz, w, order, iz, ev)
          if (ev /= 0 .or. iz < atm%k3_lo .or. iz > atm%k3_hi) return
          dzf = (atm%z(iz) - atm%z(iz - 1))*ruz
          kr = iz - atm%k3_lo + 1
          if (atm%sv%sl_of_layer(kr) /= s) cycle superlayer
        else if (dxf <= dyf) then
          ! an x face: the next block in x, across the periodic boundary if need be
          y = y + uy*d
          z = z + uz*d
          call wrap(y, atm%ly)
          dyf = dyf - d
          dzf = dzf - d
          if (ux > 0.0_wp) then
            jx = jx + 1
            if (jx > nbx) jx = 1
            xlo = (jx - 1)*bdx
            x = xlo
          else
            x = xlo
            jx = jx - 1
            if (jx < 1) then
              jx = nbx
              x = atm%lx
            end if
            xlo = (jx - 1)*bdx
          end if
          dxf = (min(atm%lx, xlo + bdx) - xlo)*rux
          smax = atm%sv%maj(off + jx + (jy - 1)*nbx)
        else
          ! a y face
          x = x + ux*d
          z = z + uz*d
          call wrap(x, atm%lx)
          dxf = dxf - d
          dzf = dzf - d
          if (uy > 0.0_wp) then
            jy = jy + 1
            if (jy > nby) jy = 1
            ylo = (jy - 1)*bdy
            y = ylo
          else
            y = ylo
            jy = jy - 1
            if (jy < 1) then
              jy = nby
              y = atm%ly
            end if
            ylo = (jy - 1)*bdy
          end if
          dyf = (min(atm%ly, ylo + bdy) - ylo)*ruy
          smax = atm%sv%maj(off + jx + (jy - 1)*nbx)
        end if
      end do step
    end do superlayer
  end subroutine fly_3d

  !> Height of the level a photon in layer iz meets next: the top for uz > 0, else the bottom.
  pure real(wp) function level_ahead(atm, iz, uz) result(zb)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: iz
    real(wp), intent(in) :: uz
    if (uz > 0.0_wp) then
      zb = atm%z(iz)
    else
      zb = atm%z(iz - 1)
    end if
  end function level_ahead

  !> Flight inside the 3-D region for a photon that keeps its column (ICA, and P3D beyond its
  !> 3-D orders): the column is a stack of uniform voxels, crossed layer by layer like the 1-D
  !> layers, without null collisions. Ends like fly_3d: a collision in voxel (ix, iy, kr)
  !> (ev = EV_COLLISION), or the photon leaves the region (ev from cross_level).
  subroutine fly_column(atm, lay, tal, x, y, z, uz, w, order, iz, tau, n_steps, max_steps, track, &
                        layers, ev, ix, iy, kr)
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    real(wp), intent(in) :: x, y, uz, w
    real(wp), intent(inout) :: z, tau
    integer, intent(in) :: order
    integer, intent(inout) :: iz
    integer(i8), intent(inout) :: n_steps
    integer(i8), intent(in) :: max_steps
    logical, intent(in) :: track  !! score the voxels' absorption along the path
    logical, intent(in) :: layers !! ... and the layers' (ABS_TRACK, ABS_TENTATIVE)
    integer, intent(out) :: ev, ix, iy, kr
    real(wp) :: zb, d, e
    ev = 0
    call column_xy(atm, x, y, ix, iy)
    do
      n_steps = n_steps + 1
      kr = iz - atm%k3_lo + 1
      if (n_steps > max_steps) return   ! the caller's step check stops the photon
      zb = level_ahead(atm, iz, uz)
      d = (zb - z)/uz
      e = voxel_ext(atm, ix, iy, kr)
      if (tau < e*d) then
        z = min(atm%z(iz), max(atm%z(iz - 1), z + uz*(tau/e)))
        if (track) call score_voxel(atm, lay, tal, iz, ix, iy, kr, &
                                    w*(tau*(1.0_wp - voxel_omg(atm, ix, iy, kr))), layers)
        ev = EV_COLLISION
        return
      end if
      if (track) call score_voxel(atm, lay, tal, iz, ix, iy, kr, &
                                  w*((e*d)*(1.0_wp - voxel_omg(atm, ix, iy, kr))), layers)
      tau = tau - e*d
      z = zb
      call cross_level(atm, lay, tal, x, y, uz, w, order, iz, ev)
      if (ev /= 0 .or. iz < atm%k3_lo .or. iz > atm%k3_hi) return
    end do
  end subroutine fly_column

  !> Track-length absorption score (ABS_TRACK) of a straight piece of flight of length s inside
  !> the 3-D layer iz, from (x, y) along the horizontal direction (ux, uy): w k_abs l for each
  !> voxel the piece crosses, l the length inside it, found by the voxel walk that the lines of
  !> sight take too (kumo_voxel_walk). Given the path, this is the expectation of what the collision
  !> score would deposit in each voxel before the photon collides or leaves. With `layers` the
  !> layer is scored too (ABS_TRACK); without, only the voxels (ABS_TRACK_VOXELS).
  subroutine absorb_path(atm, lay, tal, iz, x, y, ux, uy, s, w, layers, wk, walking)
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: iz
    real(wp), intent(in) :: x, y, ux, uy, s, w
    logical, intent(in) :: layers
    !> the voxel walk of the flight, and whether it ended at (x, y) in the layer before: then it
    !> goes on (walk_layer) instead of starting again, as on lines of sight
    type(voxel_walk_t), intent(inout) :: wk
    logical, intent(inout) :: walking
    real(wp) :: a, dep, ka
    integer :: kr
    logical :: last, uniform
    if (s <= 0.0_wp) return
    kr = iz - atm%k3_lo + 1
    ! a layer whose voxels all have the same optics takes them once, not at every voxel
    uniform = atm%uniform3(kr)
    ka = 0.0_wp
    if (uniform) ka = voxel_ext(atm, 1, 1, kr)*(1.0_wp - voxel_omg(atm, 1, 1, kr))
    if (uniform .and. .not. lay%do_voxel) then
      a = w*(ka*s)
      walking = .false.
    else
      call walk_layer(wk, atm, x, y, ux, uy, s, walking)
      a = 0.0_wp
      do
        call walk_segment(wk, last)
        if (.not. uniform) &
          ka = voxel_ext(atm, wk%ix, wk%iy, kr)*(1.0_wp - voxel_omg(atm, wk%ix, wk%iy, kr))
        dep = w*(ka*wk%step)
        a = a + dep
        call score_voxel_abs(lay, tal, kr, wk%ix + (wk%iy - 1)*atm%nx, dep)
        if (last) exit
        call walk_next(wk, atm)
      end do
    end if
    if (layers) call score_track(lay, tal, iz, a)
  end subroutine absorb_path

  !> An expected-value absorption score `a` in voxel (ix, iy, kr) of layer iz, and with `layers`
  !> in the layer too.
  subroutine score_voxel(atm, lay, tal, iz, ix, iy, kr, a, layers)
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: iz, ix, iy, kr
    real(wp), intent(in) :: a
    logical, intent(in) :: layers
    call score_voxel_abs(lay, tal, kr, ix + (iy - 1)*atm%nx, a)
    if (layers) call score_track(lay, tal, iz, a)
  end subroutine score_voxel

  !> An expected-value absorption score `a` in layer iz: absorbed there, and booked in the
  !> weight balance against the weight the photons lose at their collisions (`collide`), so that
  !> the balance is zero in expectation and the energy budget closes to round-off.
  subroutine score_track(lay, tal, iz, a)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: iz
    real(wp), intent(in) :: a
    call score_layer_abs(lay, tal, iz, a)
    call score_roulette(lay, tal, a)
  end subroutine score_track

  !> A photon from a run with thermal emission starts: its launch weight is booked, levels it
  !> starts on are tallied (the sun and the top: downward at the top; the surface: upward at
  !> the ground), and emission is seen by the radiance detectors.
  subroutine start_emitted(scn, lay, tal, rng, p)
    type(scene_t), intent(in) :: scn
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    type(photon_t), intent(inout) :: p
    call score_source(lay, tal, p%w)
    p%column = p%order >= scn%n_3d
    select case (p%emitter)
    case (EMIT_SOLAR)
      call tally_level(scn%atm, lay, tal, scn%atm%nz, .false., 0, p%w, p%x, p%y)
      return
    case (EMIT_TOP)
      call tally_level(scn%atm, lay, tal, scn%atm%nz, .false., p%order, p%w, p%x, p%y)
    case (EMIT_SURFACE)
      call tally_level(scn%atm, lay, tal, 0, .true., p%order, p%w, p%x, p%y)
    end select
    if (.not. scn%det%active) return
    select case (p%emitter)
    case (EMIT_TOP)
      call le_boundary_emission(scn%det, scn%atm, lay, tal, rng, scn%sfc, .true., p%x, p%y, &
                                p%w, 1.0_wp, p%column)
    case (EMIT_SURFACE)
      call le_boundary_emission(scn%det, scn%atm, lay, tal, rng, scn%sfc, .false., p%x, p%y, &
                                p%w_entry*emission_b_surface(scn%src%em, p%x, p%y), &
                                scn%src%em%eps_b_mean, p%column)
    case default
      call le_particle(scn%det, scn%atm, lay, tal, rng, p%x, p%y, p%z, p%iz, p%ux, p%uy, p%uz, &
                       p%w, scn%src%em%iph_iso, 1, 1.0_wp, p%column)
    end select
  end subroutine start_emitted

  !> Net-exchange bookkeeping (kumo_emission) of weight `dw` absorbed where the Planck radiance
  !> is `b_abs`; `cell` is the absorbing layer (1..nz), CELL_SURFACE or CELL_NONE, and `iv` the
  !> absorbing voxel ((kr - 1) ncol + icol, 0 for none). A thermal photon adds dw (b_abs/B_e - 1)
  !> to the net power of its emitter; what a cell that does not emit absorbs, and what solar
  !> photons deposit, is net power of the absorbing cell itself.
  subroutine score_net(lay, tal, p, em, dw, b_abs, cell, iv)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(photon_t), intent(in) :: p
    type(emission_t), intent(in) :: em
    real(wp), intent(in) :: dw, b_abs
    integer, intent(in) :: cell, iv
    real(wp) :: x
    logical :: cell_abs, erm
    ! a 1-D layer whose net power is absorbed minus emitted (kumo_emission, by_abs)
    cell_abs = .false.
    if (em%any_abs .and. cell >= 1) cell_abs = em%by_abs(cell)
    if (p%rbe > 0.0_wp) then
      erm = .true.
      if (p%emitter == EMIT_LAYER) then
        if (em%by_abs(p%em_k)) then
          ! the emitter's net is absorbed minus emitted: no net-exchange scores of its own
          erm = .false.
        else if (cell == p%em_k .and. b_abs > 0.0_wp) then
          ! exchange inside the emitting 1-D layer sums to zero (G(r, r') = G(r', r)): not
          ! scored, which keeps the deep photons of thick layers from adding noise to its net
          return
        end if
      end if
      if (erm) then
        x = dw*(b_abs*p%rbe - 1.0_wp)
        select case (p%emitter)
        case (EMIT_SURFACE)
          call score_net_surface(lay, tal, x)
        case (EMIT_TOP)
        case default
          call score_net_layer(lay, tal, p%em_k, x)
          if (p%em_v > 0) call score_net_voxel(lay, tal, p%em_v, x)
        end select
      end if
      if (b_abs > 0.0_wp .and. .not. cell_abs) return
    end if
    if (cell >= 1) then
      call score_net_layer(lay, tal, cell, dw)
    else if (cell == CELL_SURFACE) then
      call score_net_surface(lay, tal, dw)
    end if
    if (iv > 0) call score_net_voxel(lay, tal, iv, dw)
  end subroutine score_net

  !> Stop a photon at a loop cap: its weight is counted as lost, never silently dropped.
  subroutine lose_photon(lay, tal, which, w)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: which
    real(wp), intent(inout) :: w
    tal%anomalies(which) = tal%anomalies(which) + 1
    call score_lost(lay, tal, w)
    w = 0.0_wp
  end subroutine lose_photon

end module kumo_transport
