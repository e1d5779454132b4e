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
!> The presets that set these from one word (`vr_preset`) are read with the namelist.
module kumo_vr
  use kumo_kinds, only: wp
  use kumo_rng, only: rng_t, rng_uniform
  use kumo_phase, only: phase_t, phase_eval
  use kumo_atmosphere, only: atmosphere_t, LAYER_3D
  use kumo_tally, only: tally_layout_t, tally_t
  implicit none
  private
  public :: vr_t, roulette, collision_forcing, ddis_phases, spiky_without_vr, &
            SPIKY_PEAK, DDIS_PEAK, DDIS_CONE_DEG

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

end module kumo_vr
