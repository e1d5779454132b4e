! SPDX-License-Identifier: BSD-3-Clause
!> Variance reduction: the settings the photon loop applies and the rules that derive them from
!> the scene, in one place.
!>
!> Where each technique acts:
!> * Russian roulette with a weight window (seed text section 3.4.4): `roulette`, called by the
!>   photon loop after absorption, reflection and scattering.
!> * Collision forcing (section 4.2.4 a): `vr_t%cf_factor`, derived by `collision_forcing`; the
!>   photon loop samples free paths in cf_factor x the extinction.
!> * The absorption estimator (seed text section 3.8, analytic absorption): `vr_t%abs_estimator`,
!>   absorption scored at real collisions (ABS_COLLISION), as w k_abs s along every flight
!>   (ABS_TRACK), or as w k_abs / k_majorant at every tentative collision of the null-collision
!>   walk (ABS_TENTATIVE), or along every flight in the voxels only, the layers and the domain
!>   keeping the collision score (ABS_TRACK_VOXELS); `absorption_estimator_code` reads its name.
!> * Truncation of forward peaks (eq. 4.2.19): the ladder is built by kumo_truncation and held by
!>   the atmosphere; the photon loop samples it at scatterings.
!> * Local-estimate roulette, numerical diffusion and DDIS: held by the detectors
!>   (kumo_local_estimate); the phase functions that DDIS serves and the cone of its secondaries
!>   are decided here (`ddis_phases`, DDIS_CONE_DEG).
!> * The spiky-phase rule (`spiky_without_vr`): radiances of a forward-peaked phase function
!>   without roulette or truncation converge very slowly; the run warns.
!> * The roulette-balance rule (`roulette_balance_warning`): a weight balance that is both
!>   statistically significant and large shows that the rare survivors of the roulette were not
!>   sampled; the run warns.
!> * The runaway-cost rule (`runaway_cost_check`): lines of sight or photon paths that cross
!>   the periodic 3-D region through very many voxel columns are refused or warned about before
!>   the run starts.
!> The presets that set these from one word (`vr_preset`) are read with the namelist.
module kumo_vr
  use kumo_kinds, only: wp, vp, dp, i8
  use kumo_constants, only: PI
  use kumo_error, only: error_t, set_error, str
  use kumo_rng, only: rng_t, rng_uniform
  use kumo_phase, only: phase_t, phase_eval
  use kumo_atmosphere, only: atmosphere_t, LAYER_3D, voxel_layer
  use kumo_tally, only: tally_layout_t, tally_t, score_roulette
  implicit none
  private
  public :: vr_t, roulette, collision_forcing, ddis_phases, spiky_without_vr, &
            SPIKY_PEAK, DDIS_PEAK, DDIS_CONE_DEG
  public :: roulette_balance_warning, student_t_quantile, RR_BALANCE_MIN, RR_BALANCE_TAIL
  public :: few_batches_warning, FEW_BATCHES, loop_cap_warning
  public :: runaway_cost_check, los_crossings, LOS_CROSSINGS_WARN, LOS_CROSSINGS_MAX, &
            FLIGHT_CROSSINGS_WARN
  public :: ABS_COLLISION, ABS_TRACK, ABS_TENTATIVE, ABS_TRACK_VOXELS, ABS_ESTIMATOR_NAMES, &
            absorption_estimator_code

  !> How absorption is scored (the photons' random walk is the same for all three; so are the
  !> fluxes and radiances, to the last bit):
  !> * ABS_COLLISION: w (1 - omega) at each real collision, the weight the photon loses there;
  !> * ABS_TRACK: w k_abs s for every piece s of every flight, voxel by voxel, the expectation
  !>   of the collision score given the path (seed text section 3.8, analytic absorption);
  !> * ABS_TENTATIVE: w k_abs / k_majorant at every tentative (real or null) collision of the
  !>   3-D null-collision walk, and the track score in the 1-D layers and ICA columns.
  !> The expected-value scores of these two are booked against the weight the photons lose at their
  !> collisions in the roulette weight balance, so that the energy budget closes to round-off.
  !> * ABS_TRACK_VOXELS: the track score for the voxels of the 3-D region, the collision score
  !>   for the layers and the domain. The voxels get the track score's smaller error bars, while
  !>   the domain absorptance keeps the collision score's closure of the budget photon by photon
  !>   (what a photon neither reflects nor transmits it has absorbed), which the track score
  !>   loses in optically thick scenes. Each voxel is unbiased; the sum of the voxels of a layer
  !>   equals the layer's absorption in expectation, not batch by batch.
  integer, parameter :: ABS_COLLISION = 0, ABS_TRACK = 1, ABS_TENTATIVE = 2, ABS_TRACK_VOXELS = 3
  character(len=12), parameter :: ABS_ESTIMATOR_NAMES(0:3) = &
    [character(len=12) :: 'collision', 'track', 'tentative', 'track_voxels']

  !> The variance-reduction settings the photon loop reads.
  type :: vr_t
    real(wp) :: rr_threshold = 0.25_wp  !! Russian roulette below this weight ...
    real(wp) :: rr_weight = 0.5_wp      !! ... survivors continue with this weight
    real(wp) :: cf_factor = 1.0_wp      !! collision forcing: extinction multiplied by this (>= 1)
    integer :: abs_estimator = ABS_COLLISION  !! how absorption is scored: ABS_*
  end type vr_t

  !> A phase function whose forward value exceeds this is "spiky" for local estimates.
  real(wp), parameter :: SPIKY_PEAK = 50.0_wp
  !> Directional importance sampling is used for scatterings by phase functions whose forward
  !> value exceeds this (Mie clouds: 10^3 - 10^4); below it (e.g. HG 0.85, P(0) = 82) its
  !> secondaries cost more than they save (measured on the HG slab).
  real(wp), parameter :: DDIS_PEAK = 300.0_wp
  !> DDIS secondaries are kept only within this angle of their detector direction, where the
  !> forward peak is; outside it they are ordinary photons that cost time (LES at 2.13 um:
  !> 12 % less CPU time, the same radiance error, in a 2e7-photon run).
  real(wp), parameter :: DDIS_CONE_DEG = 15.0_wp
  !> The roulette weight balance (per launched photon weight) is reported as a problem only when
  !> its magnitude exceeds this, 0.1 % of the launched weight: a smaller bias of the energy
  !> budget is below the accuracy any user asks of a Monte Carlo flux.
  real(dp), parameter :: RR_BALANCE_MIN = 1.0e-3_dp
  !> ... and when it is significant at the two-sided tail probability of 4 standard normal
  !> deviations, erfc(4/sqrt(2)), judged with Student's t for the number of batches (with few
  !> batches the standard error is itself uncertain; t(1 d.o.f.) needs 1e4 standard errors).
  real(dp), parameter :: RR_BALANCE_TAIL = 6.334248366623996e-5_dp
  !> A run of fewer batches than this warns (few_batches_warning): its standard errors have
  !> n_batches - 1 degrees of freedom, so they are themselves uncertain by about
  !> 1/sqrt(2 (n_batches - 1)) (24 % at 10 batches, 41 % at 4, 71 % at 2) and an interval of
  !> given coverage is wider than its normal counterpart by Student's t (2.26 sigma for 95 % at
  !> 10 batches, 3.18 at 4, 12.7 at 2).
  integer(i8), parameter :: FEW_BATCHES = 10_i8
  !> A radiance direction whose line of sight crosses more voxel columns than this on its way
  !> through the 3-D region is warned about (every scattering event walks it: some 100 us per
  !> event instead of about 1 us) ...
  real(wp), parameter :: LOS_CROSSINGS_WARN = 1.0e4_wp
  !> ... and beyond this it is refused: at 10-20 ns per crossing each event would cost 10 ms or
  !> more, and a run of any useful photon count would not end.
  real(wp), parameter :: LOS_CROSSINGS_MAX = 1.0e6_wp
  !> Photon flights: a warning when light crossing the 3-D region once (diffuse light on
  !> average, or the direct beam) steps through more super-voxel blocks than this.
  real(wp), parameter :: FLIGHT_CROSSINGS_WARN = 1.0e3_wp

contains

  !> Russian roulette with a weight window (seed text section 3.4.4): below the threshold the
  !> photon survives with probability w/W and then carries W. The net weight it creates or
  !> destroys is tallied so that the energy budget can be closed exactly.
  subroutine roulette(vr, lay, tal, rng, w)
    type(vr_t), intent(in) :: vr
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    real(wp), intent(inout) :: w
    if (w >= vr%rr_threshold) return
    if (rng_uniform(rng)*vr%rr_weight < w) then
      call score_roulette(lay, tal, vr%rr_weight - w)
      w = vr%rr_weight
    else
      call score_roulette(lay, tal, -w)
      w = 0.0_wp
    end if
  end subroutine roulette

  !> Collision-forcing factor: the extinction is raised uniformly so that the domain-mean column
  !> optical depth along the sun's path (tau/mu0) is at least `tau_min` (the MCARaTS rule,
  !> digest section 19.4 a, on the slant column so that a low sun is not forced needlessly).
  !> 1 (off) for a transparent domain or one already thick enough.
  real(wp) function collision_forcing(atm, mu0, tau_min) result(factor)
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(in) :: mu0, tau_min
    real(wp) :: tau_col
    integer :: k
    tau_col = 0.0_wp
    do k = 1, atm%nz
      if (atm%layer_class(k) == LAYER_3D) then
        tau_col = tau_col + sum(real(layer_ext(k - atm%k3_lo + 1), wp))/(atm%nx*atm%ny)* &
                  (atm%z(k) - atm%z(k - 1))
      else
        tau_col = tau_col + atm%ext1(k)*(atm%z(k) - atm%z(k - 1))
      end if
    end do
    tau_col = tau_col/mu0
    factor = 1.0_wp
    if (tau_col > 0.0_wp .and. tau_col < tau_min) factor = tau_min/tau_col
  contains
    !> The extinction of the voxels of 3-D layer kr [m-1]
    function layer_ext(kr) result(e)
      integer, intent(in) :: kr
      real(vp) :: e(atm%nx, atm%ny), w(atm%nx, atm%ny)
      call voxel_layer(atm, kr, e, w)
    end function layer_ext
  end function collision_forcing

  !> The ABS_* code of an absorption-estimator name (case-insensitive, leading blanks ignored),
  !> -1 for an unknown name.
  pure integer function absorption_estimator_code(name) result(code)
    character(len=*), intent(in) :: name
    character(len=len(name)) :: low
    integer :: i, c
    low = adjustl(name)
    do i = 1, len(low)
      c = iachar(low(i:i))
      if (c >= iachar('A') .and. c <= iachar('Z')) low(i:i) = achar(c + 32)
    end do
    code = -1
    do i = lbound(ABS_ESTIMATOR_NAMES, 1), ubound(ABS_ESTIMATOR_NAMES, 1)
      if (trim(low) == trim(ABS_ESTIMATOR_NAMES(i))) code = i
    end do
  end function absorption_estimator_code

  !> Which phase functions DDIS serves: those with a forward value above DDIS_PEAK.
  function ddis_phases(phases) result(flags)
    type(phase_t), intent(in) :: phases(:)
    logical :: flags(size(phases))
    integer :: i
    do i = 1, size(phases)
      flags(i) = phase_eval(phases(i), 1.0_wp) > DDIS_PEAK
    end do
  end function ddis_phases

  !> True when radiances of a forward-peaked phase function (P(0) > SPIKY_PEAK) would be
  !> estimated with neither local-estimate roulette nor truncation. MYSTIC stops in this
  !> situation; kumo warns.
  logical function spiky_without_vr(phases, zeta_min, truncated) result(spiky)
    type(phase_t), intent(in) :: phases(:)
    real(wp), intent(in) :: zeta_min
    logical, intent(in) :: truncated
    integer :: i
    spiky = .false.
    if (zeta_min > 0.0_wp .or. truncated) return
    do i = 1, size(phases)
      if (phase_eval(phases(i), 1.0_wp) > SPIKY_PEAK) spiky = .true.
    end do
  end function spiky_without_vr

  !> A warning when the roulette weight balance of a finished run shows that the roulette removed
  !> weight the run never got back: the balance (net weight created by roulette and DDIS splits,
  !> zero in expectation for every valid setting) is significant, |b| > t * stderr with t the
  !> Student quantile of RR_BALANCE_TAIL for n_batches - 1 degrees of freedom, and large,
  !> |b| > RR_BALANCE_MIN. That happens when the roulette survivors, rare and heavy, were too
  !> rare to be sampled (rr_weight far above the weights that reach rr_threshold): every
  !> energy-budget result is then biased by about |b|. Empty text for a sound balance.
  function roulette_balance_warning(balance, stderr, n_batches) result(text)
    real(dp), intent(in) :: balance   !! mean roulette weight balance per launched photon
    real(dp), intent(in) :: stderr    !! its standard error over the batches
    integer(i8), intent(in) :: n_batches
    character(len=:), allocatable :: text
    real(dp) :: t
    text = ''
    if (n_batches < 2_i8 .or. abs(balance) <= RR_BALANCE_MIN) return
    t = student_t_quantile(RR_BALANCE_TAIL, int(min(n_batches - 1_i8, 1000_i8)))
    if (abs(balance) <= t*stderr) return
    text = 'the Russian roulette changed the launched weight by '//str(balance)//' +- '// &
           str(stderr)//' (roulette_weight_balance; zero in expectation): its rare survivors '// &
           'were not sampled and energy-budget results are biased by about this much; lower '// &
           'rr_weight/rr_threshold in &kumo_vr (or set rr_threshold = 0) or trace more photons. '
  end function roulette_balance_warning

  !> A warning when a finished run's standard errors rest on fewer than FEW_BATCHES batches:
  !> the standard error of each output is the spread of its batch values, with n_batches - 1
  !> degrees of freedom. Empty text from FEW_BATCHES batches on.
  function few_batches_warning(n_batches) result(text)
    integer(i8), intent(in) :: n_batches
    character(len=:), allocatable :: text
    real(dp) :: t, rel
    character(len=16) :: buf
    text = ''
    if (n_batches >= FEW_BATCHES .or. n_batches < 2_i8) return
    t = student_t_quantile(0.05_dp, int(n_batches - 1_i8))
    rel = 100.0_dp/sqrt(2.0_dp*real(n_batches - 1_i8, dp))
    write (buf, '(f0.2)') t
    text = 'the standard errors rest on '//str(n_batches)//' batches (n_batches of '// &
           '&kumo_control): with '//str(n_batches - 1_i8)//' degrees of freedom they are '// &
           'themselves uncertain by about '//str(nint(rel))//' %, and a 95 % interval is +- '// &
           trim(buf)//' standard errors instead of +- 1.96; run at least '//str(FEW_BATCHES)// &
           ' batches (the same photons in more, smaller batches) for error bars to compare with. '
  end function few_batches_warning

  !> A warning when photons of a finished run were stopped at a loop cap: `n_events` at the
  !> event cap `max_events`, `n_steps` at the step cap. Their weight went to weight_lost
  !> (`lost`, a fraction of the source like the fluxes), by which every energy-budget result is
  !> low, beyond what its error bar covers. Empty text when none was stopped.
  function loop_cap_warning(n_events, n_steps, max_events, lost) result(text)
    integer(i8), intent(in) :: n_events, n_steps, max_events
    real(dp), intent(in) :: lost
    character(len=:), allocatable :: text
    text = ''
    if (n_events + n_steps <= 0_i8) return
    text = str(n_events + n_steps)//' photon(s) were stopped at a loop cap ('//str(n_events)// &
           ' at max_events = '//str(max_events)//' events, '//str(n_steps)//' at the step '// &
           'cap) and their weight was lost: weight_lost = '//str(lost)//' (a fraction of the '// &
           'source, as the fluxes), by which the reflectance, transmittance and absorptances '// &
           'are low (not covered by their error bars); raise max_events in &kumo_control for '// &
           'very thick conservative media, or report the case if the step cap was reached. '
  end function loop_cap_warning

  !> The t with P(|T| > t) = p for Student's T with nu degrees of freedom, by bisection on the
  !> closed forms of Abramowitz and Stegun (1964), eqs. 26.7.3 (odd nu) and 26.7.4 (even nu).
  pure real(dp) function student_t_quantile(p, nu) result(t)
    real(dp), intent(in) :: p   !! two-sided tail probability, 0 < p < 1
    integer, intent(in) :: nu   !! degrees of freedom, >= 1
    real(dp) :: lo, hi
    integer :: it
    lo = 0.0_dp
    hi = 1.0_dp
    do while (tail(hi) > p .and. hi < 1.0e300_dp)
      hi = 2.0_dp*hi
    end do
    do it = 1, 200
      t = 0.5_dp*(lo + hi)
      if (tail(t) > p) then
        lo = t
      else
        hi = t
      end if
      if (hi - lo <= 1.0e-12_dp*hi) exit
    end do
    t = 0.5_dp*(lo + hi)
  contains
    !> P(|T| > x) = 1 - A(x | nu).
    pure real(dp) function tail(x)
      real(dp), intent(in) :: x
      real(dp) :: th, c2, term, s
      integer :: j
      th = atan(x/sqrt(real(nu, dp)))
      c2 = cos(th)**2
      if (mod(nu, 2) == 1) then
        s = 0.0_dp
        if (nu > 1) then
          term = cos(th)
          s = term
          do j = 3, nu - 2, 2
            term = term*c2*real(j - 1, dp)/real(j, dp)
            s = s + term
          end do
        end if
        tail = 1.0_dp - 2.0_dp/PI*(th + sin(th)*s)
      else
        term = 1.0_dp
        s = term
        do j = 2, nu - 2, 2
          term = term*c2*real(j - 1, dp)/real(j, dp)
          s = s + term
        end do
        tail = 1.0_dp - sin(th)*s
      end if
    end function tail
  end function student_t_quantile

  !> Voxel columns a line of sight in direction (ux, uy, uz) crosses while it goes once through
  !> the 3-D layers that are not uniform (a uniform layer costs one step at any angle): the
  !> horizontal distance h tan(theta) per layer, divided by the voxel widths along x and y.
  pure real(wp) function los_crossings(atm, ux, uy, uz) result(n)
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(in) :: ux, uy, uz
    real(wp) :: h
    integer :: kr
    n = 0.0_wp
    if (atm%n3 <= 0 .or. .not. allocated(atm%uniform3)) return
    h = 0.0_wp
    do kr = 1, atm%n3
      if (.not. atm%uniform3(kr)) h = h + atm%z(atm%k3_lo + kr - 1) - atm%z(atm%k3_lo + kr - 2)
    end do
    n = h*(abs(ux)/atm%dx + abs(uy)/atm%dy)/max(abs(uz), tiny(1.0_wp))
  end function los_crossings

  !> Work that grows without bound with the geometry, checked before a run (issue class
  !> "runaway cost"): a radiance direction near the horizon makes every local estimate walk a
  !> line of sight through the periodic 3-D region, H tan(theta)/dx voxel columns of it; a
  !> domain much narrower than its 3-D region is tall makes every slant photon path step
  !> through many periodic copies. Beyond LOS_CROSSINGS_MAX columns a direction is refused
  !> (the error names it and the smallest |rad_mu| this scene allows); beyond
  !> LOS_CROSSINGS_WARN, or when light crossing the region once steps through more than
  !> FLIGHT_CROSSINGS_WARN super-voxel blocks, the text returned is a warning. Nothing is
  !> checked when photons never move sideways (`lateral` false: ICA) or there is no 3-D region.
  subroutine runaway_cost_check(atm, dir_mu, dir_phi_deg, sun_u, lateral, warnings, error)
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(in) :: dir_mu(:)        !! radiance directions: cosines (&kumo_radiance)
    real(wp), intent(in) :: dir_phi_deg(:)   !! and azimuths [deg]
    real(wp), intent(in) :: sun_u(3)         !! propagation direction of the direct beam
    logical, intent(in) :: lateral           !! photons (and lines of sight) move sideways
    character(len=:), allocatable, intent(out) :: warnings
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: ux, uy, n, n1, h, mu_min, diffuse, beam, bdx, bdy
    integer :: i, s
    warnings = ''
    if (.not. lateral .or. atm%n3 <= 0) return
    do i = 1, size(dir_mu)
      ux = sqrt(max(0.0_wp, 1.0_wp - dir_mu(i)**2))*cos(dir_phi_deg(i)*PI/180.0_wp)
      uy = sqrt(max(0.0_wp, 1.0_wp - dir_mu(i)**2))*sin(dir_phi_deg(i)*PI/180.0_wp)
      n = los_crossings(atm, ux, uy, dir_mu(i))
      if (n <= LOS_CROSSINGS_WARN) cycle
      ! the same direction's crossings scale as tan(theta) = sqrt(1 - mu^2)/mu: smallest |mu|
      ! within the bound, from n1 = crossings per unit tan(theta)
      n1 = n*abs(dir_mu(i))/max(sqrt(max(0.0_wp, 1.0_wp - dir_mu(i)**2)), tiny(1.0_wp))
      mu_min = 1.0_wp/sqrt(1.0_wp + (LOS_CROSSINGS_MAX/n1)**2)
      if (n > LOS_CROSSINGS_MAX) then
        call set_error(error, '&kumo_radiance rad_mu('//str(i)//') = '//str(dir_mu(i))// &
          ' (rad_phi_deg '//str(dir_phi_deg(i))//'): its line of sight crosses about '// &
          str(real(nint(n, i8), wp))//' voxel columns of the periodic 3-D region at every '// &
          'scattering event (horizontal distance / voxel width), more than the '// &
          str(LOS_CROSSINGS_MAX)//' kumo accepts (the run would not end); this scene '// &
          'allows |rad_mu| >= '//str(mu_min)//' in this azimuth, or use mode_3d = "ica"')
        return
      end if
      warnings = warnings//'radiance direction '//str(i)//' (rad_mu = '//str(dir_mu(i))// &
        ') is near the horizon: its line of sight crosses about '//str(real(nint(n, i8), wp))// &
        ' voxel columns of the 3-D region at every scattering event, and the run will be '// &
        'slow (|rad_mu| >= '//str(1.0_wp/sqrt(1.0_wp + (LOS_CROSSINGS_WARN/n1)**2))// &
        ' keeps it below '//str(LOS_CROSSINGS_WARN)//'). '
    end do
    ! photon flights: block crossings of the super-voxel grid per passage through the region,
    ! for cosine-weighted diffuse light (E[tan(theta) |cos(phi)|] = 1) and for the direct beam
    if (atm%sv%ns <= 0) return
    diffuse = 0.0_wp
    beam = 0.0_wp
    do s = 1, atm%sv%ns
      h = atm%z(atm%k3_lo + atm%sv%kt(s) - 1) - atm%z(atm%k3_lo + atm%sv%kb(s) - 2)
      bdx = atm%sv%bx(s)*atm%dx
      bdy = atm%sv%by(s)*atm%dy
      diffuse = diffuse + h*(1.0_wp/bdx + 1.0_wp/bdy)
      beam = beam + h*(abs(sun_u(1))/bdx + abs(sun_u(2))/bdy)/max(abs(sun_u(3)), tiny(1.0_wp))
    end do
    if (max(diffuse, beam) > FLIGHT_CROSSINGS_WARN) then
      warnings = warnings//'the periodic domain ('//str(atm%lx)//' m x '//str(atm%ly)// &
        ' m) is narrow for its 3-D region ('//str(atm%z(atm%k3_hi) - atm%z(atm%k3_lo - 1))// &
        ' m tall): light crossing the region once steps through about '// &
        str(real(nint(max(diffuse, beam), i8), wp))//' blocks of the majorant grid ('// &
        trim(merge('the direct beam', 'diffuse light  ', beam > diffuse))//'), and the run will be '// &
        'slow; a wider domain (more periodic columns) or the ICA mode is much cheaper. '
    end if
  end subroutine runaway_cost_check

end module kumo_vr
