! SPDX-License-Identifier: BSD-3-Clause
!> The photon loop: trace the photons of one batch through the atmosphere and tally them.
!>
!> Forward Monte Carlo with weights (seed text chapter 2-3): photons enter at the top with the
!> solar direction; free paths are sampled in optical depth; at a collision the weight is
!> multiplied by the cell's single-scattering albedo (the rest is absorbed there), Russian
!> roulette keeps the weight in a window, the scattering component is drawn by its scattering
!> coefficient and a new direction from its phase function. Fluxes are counted where photons
!> cross levels (method I of the seed text, section 3.8.2), absorption where it happens.
!>
!> Per layer class (see kumo_atmosphere): clear layers are crossed in one step, purely absorbing
!> layers multiply the weight by exp(-tau) along the path and deposit the difference, uniform
!> scattering layers are traced analytically, and the 3-D region uses maximum-cross-section
!> (null-collision) tracking inside super-voxels (seed text section 4.1). Photons carry the
!> index of their layer and super-voxel; positions are set exactly onto faces when crossing them,
!> and a position that round-off puts outside its cell is clamped back (and counted).
!>
!> No allocation, I/O or polymorphic dispatch happens in here.
module kumo_transport
  use kumo_kinds, only: wp, dp, i8
  use kumo_constants, only: DEG2RAD
  use kumo_rng, only: rng_t, rng_uniform, sample_azimuth
  use kumo_math, only: rotate_direction, wrap, UZ_MIN
  use kumo_phase, only: phase_sample_mu
  use kumo_truncation, only: trunc_sample_mu
  use kumo_local_estimate, only: detectors_t, le_particle, le_surface, ddis_factor, &
                                 ddis_direction
  use kumo_atmosphere, only: atmosphere_t, column_of, column_xy, LAYER_CLEAR, &
                             LAYER_ABSORBING, LAYER_SCATTERING, LAYER_3D
  use kumo_surface, only: surface_t
  use kumo_brdf, only: brdf_albedo, brdf_sample
  use kumo_tally, only: tally_layout_t, tally_t, ANOM_UZ_NUDGED, ANOM_EVENT_CAP, &
                        ANOM_STEP_CAP, ANOM_POSITION_REPAIR, ANOM_BRDF_ENVELOPE
  implicit none
  private
  public :: source_t, tracer_options_t, source_init, trace_batch

  !> The solar source: a parallel beam entering at the top of the domain.
  !>
  !> Entry points are stratified when nsx*nsy > 1 and a batch has at least nsx*nsy photons: the
  !> photons of a batch take the cells of an nsx x nsy grid in turn, from a random first cell,
  !> each at a uniform random point of its cell, and the grid is shifted by (shift_x, shift_y)
  !> (the drift of the direct beam from the top to the surface, so that the cells fall onto the
  !> columns or surface pixels below). Every entry point is still uniform over the domain, so
  !> the estimates stay unbiased; each batch covers the domain evenly, so per-column and
  !> per-pixel results vary less between batches.
  type :: source_t
    real(wp) :: ux = 0.0_wp, uy = 0.0_wp, uz = -1.0_wp  !! propagation direction of the beam
    integer :: nsx = 1, nsy = 1                         !! grid of entry cells (1 x 1: off)
    real(wp) :: shift_x = 0.0_wp, shift_y = 0.0_wp      !! grid offset [m]
  end type source_t

  !> Settings of the photon loop.
  type :: tracer_options_t
    real(wp) :: rr_threshold = 0.25_wp  !! Russian roulette below this weight ...
    real(wp) :: rr_weight = 0.5_wp      !! ... survivors continue with this weight
    integer(i8) :: max_events = 100000000_i8 !! collisions + reflections per photon
    integer(i8) :: max_steps = 100000000000_i8 !! flight steps per photon (1000 x max_events)
    real(wp) :: cf_factor = 1.0_wp      !! collision forcing: extinction multiplied by this (>= 1)
    !> Transport mode: photons move horizontally only while their scattering order (scatterings
    !> and reflections so far) is below n_3d; afterwards they stay in their column. huge: F3D;
    !> 0: ICA (every column a plane-parallel atmosphere); N: P3D.
    integer :: n_3d = huge(1)
  end type tracer_options_t

  integer, parameter :: EV_COLLISION = 1, EV_ESCAPE = 2, EV_SURFACE = 3, EV_KILLED = 4
  !> Most DDIS secondaries queued per photon (secondaries do not split again).
  integer, parameter :: MAX_PENDING = 64

contains

  !> Source for solar zenith angle `sza_deg` and propagation azimuth `phi0_deg` (from +x
  !> towards +y; 0 means the beam travels towards +x, i.e. the sun is at low x).
  pure function source_init(sza_deg, phi0_deg) result(src)
    real(wp), intent(in) :: sza_deg, phi0_deg
    type(source_t) :: src
    real(wp) :: st
    st = sin(sza_deg*DEG2RAD)
    src%ux = st*cos(phi0_deg*DEG2RAD)
    src%uy = st*sin(phi0_deg*DEG2RAD)
    src%uz = -cos(sza_deg*DEG2RAD)
  end function source_init

  !> Trace `n_photons` photons, adding into `tal` (which the caller has reset).
  subroutine trace_batch(atm, sfc, src, opts, lay, det, rng, n_photons, tal)
    type(atmosphere_t), intent(in) :: atm
    type(surface_t), intent(in) :: sfc
    type(source_t), intent(in) :: src
    type(tracer_options_t), intent(in) :: opts
    type(tally_layout_t), intent(in) :: lay
    type(detectors_t), intent(in) :: det
    type(rng_t), intent(inout) :: rng
    integer(i8), intent(in) :: n_photons
    type(tally_t), intent(inout) :: tal
    integer(i8) :: ip, n_events, n_steps
    real(wp) :: x, y, z, ux, uy, uz, w, tau, d, zb, e, wn, albedo, mu, cphi, sphi, omega, ps, wb
    real(wp) :: inv_cf, uxi, uyi, uzi, u_out(3)
    integer :: iz, order, cls, ev, ix, iy, kr, ic, iph, nc, lev, n_pending, kb, ns, s_cell
    integer(i8) :: s_first
    logical :: in3d, track_xy, move_xy, column, forced, secondary, split, plain, stratify
    ! DDIS secondaries waiting to be traced: position, direction, weight; layer, order, level
    real(wp) :: pend_r(7, MAX_PENDING)
    integer :: pend_i(3, MAX_PENDING)

    ! Horizontal positions matter only for a 3-D region, an albedo map, per-column maps or
    ! cameras; a plane-parallel scene skips their bookkeeping in the 1-D layers.
    track_xy = atm%n3 > 0 .or. .not. sfc%uniform .or. lay%do_maps .or. lay%do_rad_maps .or. &
               size(det%cams) > 0
    ! Collision forcing (seed text section 4.2.4 a): free paths are sampled in the extinction
    ! cf_factor * sigma; see the collision below.
    forced = opts%cf_factor > 1.0_wp
    inv_cf = 1.0_wp/opts%cf_factor
    plain = .not. (det%active .or. forced .or. atm%truncated)
    ns = src%nsx*src%nsy
    stratify = ns > 1 .and. n_photons >= ns
    s_first = 0
    if (stratify) s_first = min(int(rng_uniform(rng)*ns, i8), int(ns - 1, i8))
    do ip = 1, n_photons
      if (stratify) then
        s_cell = int(mod(s_first + ip - 1, int(ns, i8)))
        x = (mod(s_cell, src%nsx) + rng_uniform(rng))*(atm%lx/src%nsx) - src%shift_x
        y = (s_cell/src%nsx + rng_uniform(rng))*(atm%ly/src%nsy) - src%shift_y
        call wrap(x, atm%lx)
        call wrap(y, atm%ly)
      else
        x = rng_uniform(rng)*atm%lx
        y = rng_uniform(rng)*atm%ly
      end if
      z = atm%z(atm%nz)
      ux = src%ux
      uy = src%uy
      uz = src%uz
      w = 1.0_wp
      order = 0
      lev = 1
      iz = atm%nz
      n_events = 0
      n_steps = 0
      call tally_level(atm, lay, tal, atm%nz, .false., 0, w, x, y)
      n_pending = 0
      secondary = .false.

      history: do
      ! ICA and P3D: beyond its 3-D orders the photon keeps its column (x, y fixed)
      column = order >= opts%n_3d
      move_xy = track_xy .and. .not. column
      photon: do
        if (order >= opts%n_3d .and. .not. column) then
          column = .true.
          move_xy = .false.
        end if
        tau = -log(1.0_wp - rng_uniform(rng))
        if (forced) tau = tau*inv_cf
        flight: do
          n_steps = n_steps + 1
          if (n_steps > opts%max_steps) then
            tal%anomalies(ANOM_STEP_CAP) = tal%anomalies(ANOM_STEP_CAP) + 1
            tal%buf(lay%i_lost + 1) = tal%buf(lay%i_lost + 1) + w
            exit photon
          end if
          cls = atm%layer_class(iz)
          if (cls == LAYER_3D) then
            if (column) then
              call fly_column(atm, lay, tal, x, y, z, uz, w, order, iz, tau, n_steps, &
                              opts%max_steps, ev, ix, iy, kr)
            else
              call fly_3d(atm, lay, tal, rng, x, y, z, ux, uy, uz, w, order, iz, tau, n_steps, &
                          opts%max_steps, inv_cf, ev, ix, iy, kr)
            end if
            in3d = .true.
          else
            in3d = .false.
            zb = level_ahead(atm, iz, uz)
            d = (zb - z)/uz
            ev = 0
            select case (cls)
            case (LAYER_SCATTERING)
              e = atm%ext1(iz)
              if (tau < e*d) then
                d = tau/e
                z = z + uz*d
                if (move_xy) then
                  x = x + ux*d
                  y = y + uy*d
                  call wrap(x, atm%lx)
                  call wrap(y, atm%ly)
                end if
                ev = EV_COLLISION
              else
                tau = tau - e*d
              end if
            case (LAYER_ABSORBING)
              wn = w*exp(-atm%ext1(iz)*d)
              tal%buf(lay%i_abs + iz) = tal%buf(lay%i_abs + iz) + (w - wn)
              w = wn
            case default ! LAYER_CLEAR
            end select
            if (ev == 0) then
              z = zb
              if (move_xy) then
                x = x + ux*d
                y = y + uy*d
                call wrap(x, atm%lx)
                call wrap(y, atm%ly)
              end if
              call cross_level(atm, lay, tal, x, y, uz, w, order, iz, ev)
              if (cls == LAYER_ABSORBING .and. ev == 0) then
                call roulette(opts, lay, tal, rng, w)
                if (w <= 0.0_wp) exit photon
              end if
            end if
          end if

          select case (ev)
          case (0)
            cycle flight
          case (EV_ESCAPE, EV_KILLED)
            exit photon
          case (EV_SURFACE)
            ! Lambert reflection (seed text section 3.6.3): weight times albedo, then a
            ! cosine-weighted direction.
            n_events = n_events + 1
            if (sfc%black) then
              tal%buf(lay%i_sfc + 1) = tal%buf(lay%i_sfc + 1) + w
              exit photon
            end if
            ! a BRDF (seed text section 3.6): weight times the directional albedo, then a
            ! direction drawn from BRDF mu_out / albedo
            kb = 1
            if (sfc%use_brdf) then
              kb = sfc%class_at(x, y)
              albedo = brdf_albedo(sfc%tabs(kb), -uz)
            else
              albedo = sfc%albedo_at(x, y)
            end if
            tal%buf(lay%i_sfc + 1) = tal%buf(lay%i_sfc + 1) + w*(1.0_wp - albedo)
            w = w*albedo
            if (w <= 0.0_wp) exit photon
            if (det%active) call le_surface(det, atm, lay, tal, rng, sfc, kb, x, y, ux, uy, uz, &
                                            w, lev, column)
            call roulette(opts, lay, tal, rng, w)
            if (w <= 0.0_wp) exit photon
            if (sfc%use_brdf) then
              call brdf_sample(sfc%tabs(kb), [ux, uy, uz], rng, u_out, &
                               tal%anomalies(ANOM_BRDF_ENVELOPE))
              ux = u_out(1)
              uy = u_out(2)
              uz = u_out(3)
            else
              uz = sqrt(rng_uniform(rng))
              call sample_azimuth(rng, cphi, sphi)
              mu = sqrt(max(0.0_wp, 1.0_wp - uz*uz))
              ux = mu*cphi
              uy = mu*sphi
            end if
            if (uz < UZ_MIN) then
              uz = UZ_MIN
              tal%anomalies(ANOM_UZ_NUDGED) = tal%anomalies(ANOM_UZ_NUDGED) + 1
            end if
            order = order + 1
            z = atm%z(0)
            iz = 1
            call tally_level(atm, lay, tal, 0, .true., order, w, x, y)
            if (n_events > opts%max_events) then
              call lose_photon(lay, tal, ANOM_EVENT_CAP, w)
              exit photon
            end if
            exit flight
          case (EV_COLLISION)
            n_events = n_events + 1
            ! Absorption (seed text section 3.4.3 b). With collision forcing the medium has the
            ! extinction F sigma and the albedo omega' = 1 - (1 - omega)/F, so absorption is
            ! unchanged; a collision is a real scattering with probability ps = omega/(F omega'),
            ! otherwise the photon goes on undeflected (eq. 4.2.42-45).
            if (in3d) then
              omega = atm%omg3(ix, iy, kr)
            else
              omega = atm%omg1(iz)
            end if
            ps = 1.0_wp
            if (forced) then
              wn = 1.0_wp - (1.0_wp - omega)*inv_cf
              if (wn > 0.0_wp) ps = omega*inv_cf/wn
              wn = w*wn
            else
              wn = w*omega
            end if
            tal%buf(lay%i_abs + iz) = tal%buf(lay%i_abs + iz) + (w - wn)
            if (in3d .and. lay%do_voxel) then
              ic = lay%i_vox + (kr - 1)*lay%ncol + ix + (iy - 1)*atm%nx
              tal%buf(ic) = tal%buf(ic) + (w - wn)
            end if
            w = wn
            if (w <= 0.0_wp) exit photon
            if (n_events > opts%max_events) then
              call lose_photon(lay, tal, ANOM_EVENT_CAP, w)
              exit photon
            end if
            if (in3d) then
              nc = atm%ncomp
              ic = 1
              if (nc > 1) then
                e = rng_uniform(rng)
                do ic = 1, nc - 1
                  if (e < atm%csca3(ic, ix, iy, kr)) exit
                end do
              end if
              if (allocated(atm%iph3)) then
                iph = atm%iph3(ic, ix, iy, kr)
              else
                iph = atm%iph3_const(ic)
              end if
              if (allocated(atm%wph3)) then
                ! a blend of tables iph and iph + 1: the photon takes table iph + 1 with
                ! probability w, which samples (1 - w) P(iph) + w P(iph + 1) exactly
                wb = atm%wph3(ic, ix, iy, kr)
                if (wb > 0.0_wp) then
                  if (rng_uniform(rng) < wb) iph = iph + 1
                end if
              end if
            else
              nc = atm%ncomp1
              iph = atm%iph1(1, iz)
              if (nc > 1) then
                e = rng_uniform(rng)
                do ic = 1, nc
                  if (e < atm%csca1(ic, iz)) exit
                end do
                iph = atm%iph1(min(ic, nc), iz)
              end if
            end if
            if (plain) then
              ! a flux run without variance reduction: the scattering as it always was
              call roulette(opts, lay, tal, rng, w)
              if (w <= 0.0_wp) exit photon
              order = order + 1
              mu = phase_sample_mu(atm%phases(iph), rng_uniform(rng))
              call sample_azimuth(rng, cphi, sphi)
              call rotate_direction(ux, uy, uz, mu, cphi, sphi)
            else
              ! Truncation (seed text eq. 4.2.19): with probability f the scattering belongs to
              ! the delta peak and the photon keeps its direction; it is still a scattering.
              if (atm%truncated) then
                if (rng_uniform(rng) < atm%trunc%f(lev, iph)) then
                  order = order + 1
                  call roulette(opts, lay, tal, rng, w)
                  if (w <= 0.0_wp) exit photon
                  exit flight
                end if
              end if
              ! local estimates before the roulette, so that a light photon (a DDIS secondary)
              ! still contributes with its own weight
              if (det%active) call le_particle(det, atm, lay, tal, rng, x, y, z, iz, ux, uy, uz, &
                                               w*ps, iph, lev, ps, column)
              call roulette(opts, lay, tal, rng, w)
              if (w <= 0.0_wp) exit photon
              if (forced) then
                if (rng_uniform(rng) >= ps) exit flight
              end if
              order = order + 1
              call sample_azimuth(rng, cphi, sphi)
              uxi = ux
              uyi = uy
              uzi = uz
              split = .false.
              if (atm%truncated) then
                mu = trunc_sample_mu(atm%trunc, atm%phases(iph), iph, lev, rng_uniform(rng))
              else
                mu = phase_sample_mu(atm%phases(iph), rng_uniform(rng))
              end if
              call rotate_direction(ux, uy, uz, mu, cphi, sphi)
              if (det%ddis_eps > 0.0_wp .and. .not. secondary .and. n_pending < MAX_PENDING) then
                split = det%ddis_phase(iph)
              end if
              if (split) call ddis_split(atm, lay, det, tal, rng, iph, lev, order, iz, x, y, z, &
                                         uxi, uyi, uzi, ux, uy, uz, w, n_pending, pend_r, pend_i)
              if (atm%truncated) then
                if (lev < atm%trunc%n_levels .and. mu <= atm%trunc%mu_peak(iph)) lev = lev + 1
              end if
            end if
            if (abs(uz) < UZ_MIN) then
              uz = sign(UZ_MIN, uz)
              tal%anomalies(ANOM_UZ_NUDGED) = tal%anomalies(ANOM_UZ_NUDGED) + 1
            end if
            exit flight
          case default
            exit photon   ! no other event exists
          end select
        end do flight
      end do photon
      ! DDIS secondaries of this photon, last in first out
      if (n_pending == 0) exit history
      x = pend_r(1, n_pending)
      y = pend_r(2, n_pending)
      z = pend_r(3, n_pending)
      ux = pend_r(4, n_pending)
      uy = pend_r(5, n_pending)
      uz = pend_r(6, n_pending)
      w = pend_r(7, n_pending)
      iz = pend_i(1, n_pending)
      order = pend_i(2, n_pending)
      lev = pend_i(3, n_pending)
      n_pending = n_pending - 1
      secondary = .true.
      end do history
      tal%work(1) = tal%work(1) + n_steps
      tal%work(2) = tal%work(2) + n_events
    end do
  end subroutine trace_batch

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
    tal%buf(lay%i_rr + 1) = tal%buf(lay%i_rr + 1) + (wn - w)
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
    integer :: i, slot, icol
    if (up) then
      i = lay%i_up + k + 1
    else if (order == 0) then
      i = lay%i_dir + k + 1
    else
      i = lay%i_dif + k + 1
    end if
    tal%buf(i) = tal%buf(i) + w
    if (.not. lay%do_maps) return
    slot = lay%map_slot(k)
    if (slot == 0) return
    icol = column_of(atm, x, y)
    if (up) then
      i = lay%i_map_up
    else if (order == 0) then
      i = lay%i_map_dir
    else
      i = lay%i_map_dif
    end if
    i = i + (slot - 1)*lay%ncol + icol
    tal%buf(i) = tal%buf(i) + w
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
                    max_steps, inv_cf, ev, ix, iy, kr)
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
    integer, intent(out) :: ev, ix, iy, kr
    integer :: s, jx, jy, bx, by, nbx, nby, off, ixlo, ixhi, iylo, iyhi, face
    real(wp) :: dxf, dyf, dzf, d, smax, bdx, bdy, xlo, ylo, rux, ruy, ruz, e

    ev = 0
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
        if (dzf <= dxf .and. dzf <= dyf) then
          d = dzf
          face = 3
        else if (dxf <= dyf) then
          d = dxf
          face = 1
        else
          d = dyf
          face = 2
        end if

        if (smax*d > tau) then
          ! tentative collision inside the block
          d = tau/smax
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
          e = atm%ext3(ix, iy, kr)
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
          ev = EV_COLLISION
          return
        end if

        ! cross the nearest face
        tau = tau - smax*d
        if (face == 3) then
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
          call cross_level(atm, lay, tal, x, y, uz, w, order, iz, ev)
          if (ev /= 0 .or. iz < atm%k3_lo .or. iz > atm%k3_hi) return
          dzf = (atm%z(iz) - atm%z(iz - 1))*ruz
          kr = iz - atm%k3_lo + 1
          if (atm%sv%sl_of_layer(kr) /= s) cycle superlayer
        else if (face == 1) then
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
  subroutine fly_column(atm, lay, tal, x, y, z, uz, w, order, iz, tau, n_steps, max_steps, ev, &
                        ix, iy, kr)
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    real(wp), intent(in) :: x, y, uz, w
    real(wp), intent(inout) :: z, tau
    integer, intent(in) :: order
    integer, intent(inout) :: iz
    integer(i8), intent(inout) :: n_steps
    integer(i8), intent(in) :: max_steps
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
      e = atm%ext3(ix, iy, kr)
      if (tau < e*d) then
        z = min(atm%z(iz), max(atm%z(iz - 1), z + uz*(tau/e)))
        ev = EV_COLLISION
        return
      end if
      tau = tau - e*d
      z = zb
      call cross_level(atm, lay, tal, x, y, uz, w, order, iz, ev)
      if (ev /= 0 .or. iz < atm%k3_lo .or. iz > atm%k3_hi) return
    end do
  end subroutine fly_column

  !> Russian roulette with a weight window (seed text section 3.4.4): below the threshold the
  !> photon survives with probability w/W and then carries W. The net weight it creates or
  !> destroys is tallied so that the energy budget can be closed exactly.
  subroutine roulette(opts, lay, tal, rng, w)
    type(tracer_options_t), intent(in) :: opts
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    real(wp), intent(inout) :: w
    if (w >= opts%rr_threshold) return
    if (rng_uniform(rng)*opts%rr_weight < w) then
      tal%buf(lay%i_rr + 1) = tal%buf(lay%i_rr + 1) + (opts%rr_weight - w)
      w = opts%rr_weight
    else
      tal%buf(lay%i_rr + 1) = tal%buf(lay%i_rr + 1) - w
      w = 0.0_wp
    end if
  end subroutine roulette

  !> Stop a photon at a loop cap: its weight is counted as lost, never silently dropped.
  subroutine lose_photon(lay, tal, which, w)
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: which
    real(wp), intent(inout) :: w
    tal%anomalies(which) = tal%anomalies(which) + 1
    tal%buf(lay%i_lost + 1) = tal%buf(lay%i_lost + 1) + w
    w = 0.0_wp
  end subroutine lose_photon

end module kumo_transport
