! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_vr: variance reduction and tracer fast paths.
!>
!> The parsing and validation of this namelist group (read_vr), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_vr
  use kumo_config_base
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, str, to_lower, join
  use kumo_math, only: within
  use kumo_vr, only: ABS_ESTIMATOR_NAMES, absorption_estimator_code
  implicit none
  private
  public :: read_vr, PRESET_NAMES

  !> Variance-reduction presets, from none to the most aggressive (see read_vr).
  character(len=16), parameter :: PRESET_NAMES(4) = &
    [character(len=16) :: 'analog', 'unbiased', 'standard', 'quick']
  ! Preset values, in the order of PRESET_NAMES (MCARaTS ladder, state-of-the-art C1, B2, B6).
  real(wp), parameter :: PRESET_ZETA(4) = [0.0_wp, 0.3_wp, 0.3_wp, 0.3_wp]
  real(wp), parameter :: PRESET_TRUNC_DEG(4) = [0.0_wp, 0.0_wp, 30.0_wp, 40.0_wp]
  integer, parameter :: PRESET_TRUNC_LEVELS(4) = [1, 1, 4, 3]
  real(wp), parameter :: PRESET_CF_TAU(4) = [0.0_wp, 1.0_wp, 2.0_wp, 3.0_wp]
  real(wp), parameter :: PRESET_DIFF(4) = [0.0_wp, 0.0_wp, 60.0_wp, 150.0_wp]
  real(wp), parameter :: PRESET_DDIS(4) = [0.0_wp, 0.1_wp, 0.1_wp, 0.1_wp]

contains

  subroutine read_vr(unit, present, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(vr_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: rr_threshold, rr_weight, sv_fsupg, sv_fsupi
    integer :: sv_max_layers, ios, ip
    logical :: use_supervoxels, use_1d_layers, use_absorbing_layers, stratify_source, &
               use_exact_thermal
    character(len=16) :: vr_preset, absorption_estimator
    real(wp) :: zeta_min, trunc_theta_max_deg, trunc_peak, cf_tau_min, diffusion, ddis_eps, &
                similarity_theta_deg
    integer :: trunc_levels, diffusion_max
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_vr: '
    namelist /kumo_vr/ rr_threshold, rr_weight, use_supervoxels, sv_fsupg, sv_fsupi, &
      sv_max_layers, use_1d_layers, use_absorbing_layers, use_exact_thermal, vr_preset, zeta_min, &
      trunc_theta_max_deg, trunc_levels, trunc_peak, cf_tau_min, diffusion, diffusion_max, &
      ddis_eps, stratify_source, absorption_estimator, similarity_theta_deg
    rr_threshold = cfg%rr_threshold
    rr_weight = cfg%rr_weight
    use_supervoxels = cfg%use_supervoxels
    sv_fsupg = cfg%sv_fsupg
    sv_fsupi = cfg%sv_fsupi
    sv_max_layers = cfg%sv_max_layers
    use_1d_layers = cfg%use_1d_layers
    use_absorbing_layers = cfg%use_absorbing_layers
    use_exact_thermal = cfg%use_exact_thermal
    stratify_source = cfg%stratify_source
    vr_preset = cfg%preset
    zeta_min = UNSET
    trunc_theta_max_deg = UNSET
    trunc_levels = IUNSET
    trunc_peak = cfg%trunc_peak
    cf_tau_min = UNSET
    diffusion = UNSET
    diffusion_max = cfg%diffusion_max
    ddis_eps = UNSET
    absorption_estimator = cfg%absorption_estimator
    similarity_theta_deg = cfg%similarity_theta_deg
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_vr, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_vr', present, ios, msg, error, probe)
    if (allocated(error)) return
    ! The preset gives every technique a value; a variable set in the namelist overrides it.
    ip = findloc(PRESET_NAMES == to_lower(adjustl(vr_preset)), .true., 1)
    call require(ip > 0, CTX, 'vr_preset', vr_preset, 'must be one of '//join(PRESET_NAMES), error)
    if (allocated(error)) return
    cfg%preset = PRESET_NAMES(ip)
    if (zeta_min == UNSET) zeta_min = PRESET_ZETA(ip)
    if (trunc_theta_max_deg == UNSET) trunc_theta_max_deg = PRESET_TRUNC_DEG(ip)
    if (trunc_levels == IUNSET) trunc_levels = PRESET_TRUNC_LEVELS(ip)
    if (cf_tau_min == UNSET) cf_tau_min = PRESET_CF_TAU(ip)
    if (diffusion == UNSET) diffusion = PRESET_DIFF(ip)
    if (ddis_eps == UNSET) ddis_eps = PRESET_DDIS(ip)
    call require(within(zeta_min, 0.0_wp, BIG), CTX, 'zeta_min', zeta_min, &
                 'must be >= 0 (0 = off)', error)
    call require(within(trunc_theta_max_deg, 0.0_wp, 89.0_wp), CTX, 'trunc_theta_max_deg', &
                 trunc_theta_max_deg, 'must be within [0, 89] (0 = no truncation)', error)
    call require(trunc_levels >= 1 .and. trunc_levels <= 16, CTX, 'trunc_levels', trunc_levels, &
                 'must be within 1..16 (1 = no truncation)', error)
    call require(within(trunc_peak, SMALL, BIG), CTX, 'trunc_peak', trunc_peak, 'must be > 0', &
                 error)
    call require(within(cf_tau_min, 0.0_wp, 1.0e6_wp), CTX, 'cf_tau_min', cf_tau_min, &
                 'must be within [0, 1e6] (0 = no collision forcing)', error)
    call require(within(diffusion, 0.0_wp, 1.0e6_wp), CTX, 'diffusion', diffusion, &
                 'must be within [0, 1e6] (0 = no numerical diffusion)', error)
    call require(within(ddis_eps, 0.0_wp, 0.9_wp), CTX, 'ddis_eps', ddis_eps, &
                 'must be within [0, 0.9] (0 = no directional importance sampling)', error)
    call require(within(similarity_theta_deg, 0.0_wp, 60.0_wp), CTX, 'similarity_theta_deg', &
                 similarity_theta_deg, 'must be within [0, 60] (0 = off)', error)
    call require(diffusion_max >= 0 .and. diffusion_max <= 1000, CTX, 'diffusion_max', &
                 diffusion_max, 'must be within 0..1000 [columns]', error)
    if (allocated(error)) return
    if (trunc_levels == 1 .or. trunc_theta_max_deg == 0.0_wp) then
      trunc_levels = 1
      trunc_theta_max_deg = 0.0_wp
    end if
    cfg%zeta_min = zeta_min
    cfg%trunc_theta_max_deg = trunc_theta_max_deg
    cfg%trunc_levels = trunc_levels
    cfg%trunc_peak = trunc_peak
    cfg%cf_tau_min = cf_tau_min
    cfg%diffusion = diffusion
    cfg%diffusion_max = diffusion_max
    cfg%ddis_eps = ddis_eps
    cfg%similarity_theta_deg = similarity_theta_deg
    call require(within(rr_weight, SMALL, BIG), CTX, 'rr_weight', rr_weight, 'must be > 0', error)
    call require(within(rr_threshold, 0.0_wp, rr_weight), CTX, 'rr_threshold', rr_threshold, &
                 'must be within [0, rr_weight = '//str(rr_weight)//']', error)
    if (.not. allocated(error) .and. rr_threshold > 0.0_wp) then
      call require(rr_weight <= RR_RATIO_MAX*rr_threshold, CTX, 'rr_weight', rr_weight, &
                   'must be <= '//str(RR_RATIO_MAX)//' x rr_threshold = '//str(rr_threshold)// &
                   ': a photon below rr_threshold survives the roulette with probability '// &
                   'at most rr_threshold/rr_weight = '//str(rr_threshold/rr_weight)// &
                   ', so nearly every photon is killed and the few survivors, of weight '// &
                   'rr_weight, dominate the result (set rr_threshold = 0 for no roulette)', error)
    end if
    call require(within(sv_fsupg, SMALL, BIG) .and. within(sv_fsupi, SMALL, BIG), CTX, &
                 'sv_fsupg and sv_fsupi', rule='must be > 0', error=error)
    call require(sv_max_layers >= 1, CTX, 'sv_max_layers', sv_max_layers, 'must be >= 1', error)
    cfg%rr_threshold = rr_threshold
    cfg%rr_weight = rr_weight
    cfg%use_supervoxels = use_supervoxels
    cfg%sv_fsupg = sv_fsupg
    cfg%sv_fsupi = sv_fsupi
    cfg%sv_max_layers = sv_max_layers
    cfg%use_1d_layers = use_1d_layers
    cfg%use_absorbing_layers = use_absorbing_layers
    cfg%use_exact_thermal = use_exact_thermal
    cfg%stratify_source = stratify_source
    ip = absorption_estimator_code(absorption_estimator)
    call require(ip >= 0, CTX, 'absorption_estimator', absorption_estimator, 'must be one of '// &
                 join(ABS_ESTIMATOR_NAMES), error)
    if (ip >= 0) cfg%absorption_estimator = ABS_ESTIMATOR_NAMES(ip)
  contains
    !> Read one assignment of &kumo_vr (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_vr, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_vr, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_vr
end module kumo_config_vr
