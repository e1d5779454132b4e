! SPDX-License-Identifier: BSD-3-Clause
!> Variance reduction: the settings the photon loop applies and the rules that derive them from
!> the scene, in one place.
!>
!> Where each technique acts:
!> * Russian roulette with a weight window (seed text section 3.4.4): `roulette`, called by the
!>   photon loop after absorption, reflection and scattering.
!> * Collision forcing (section 4.2.4 a): `vr_t%cf_factor`, derived by `collision_forcing`; the
!>   photon loop samples free paths in cf_factor x the extinction.
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
!> The presets that set these from one word (`vr_preset`) are read with the namelist.
module kumo_vr
  use kumo_kinds, only: wp, dp, i8
  use kumo_constants, only: PI
  use kumo_error, only: str
  use kumo_rng, only: rng_t, rng_uniform
  use kumo_phase, only: phase_t, phase_eval
  use kumo_atmosphere, only: atmosphere_t, LAYER_3D
  use kumo_tally, only: tally_layout_t, tally_t
  implicit none
  private
  public :: vr_t, roulette, collision_forcing, ddis_phases, spiky_without_vr, &
            SPIKY_PEAK, DDIS_PEAK, DDIS_CONE_DEG
  public :: roulette_balance_warning, student_t_quantile, RR_BALANCE_MIN, RR_BALANCE_TAIL

  !> The variance-reduction settings the photon loop reads.
  type :: vr_t
    real(wp) :: rr_threshold = 0.25_wp  !! Russian roulette below this weight ...
    real(wp) :: rr_weight = 0.5_wp      !! ... survivors continue with this weight
    real(wp) :: cf_factor = 1.0_wp      !! collision forcing: extinction multiplied by this (>= 1)
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
      tal%buf(lay%i_rr + 1) = tal%buf(lay%i_rr + 1) + (vr%rr_weight - w)
      w = vr%rr_weight
    else
      tal%buf(lay%i_rr + 1) = tal%buf(lay%i_rr + 1) - w
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
        tau_col = tau_col + sum(real(atm%ext3(:, :, k - atm%k3_lo + 1), wp))/(atm%nx*atm%ny)* &
                  (atm%z(k) - atm%z(k - 1))
      else
        tau_col = tau_col + atm%ext1(k)*(atm%z(k) - atm%z(k - 1))
      end if
    end do
    tau_col = tau_col/mu0
    factor = 1.0_wp
    if (tau_col > 0.0_wp .and. tau_col < tau_min) factor = tau_min/tau_col
  end function collision_forcing

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

end module kumo_vr
