! SPDX-License-Identifier: BSD-3-Clause
!> Radiances by local estimation (seed text section 3.9; digest sections 15 and 19.2).
!>
!> At every scattering and surface reflection the photon adds, to every detector, the
!> probability that the light it scatters reaches the detector without a further collision:
!> psi = w p(Omega_d) T, with p the angular density of the scattered light per steradian
!> (P/(4 pi) for particles, mu_d/pi for a Lambert surface) and T = exp(-tau) along the line of
!> sight. Two kinds of detectors:
!>
!> * level detectors: the radiance crossing a level in a direction Omega_d, averaged over the
!>   domain and per column (pixel maps). A horizontal area A receives psi/(A |mu_d|) per unit
!>   solid angle, so the tally is pi psi/|mu_d|, which after division by the photons is
!>   pi I/(mu0 F0) (the bidirectional reflectance factor at the top for mu_d > 0).
!> * cameras (module kumo_camera): each periodic image of the event that projects into the
!>   image adds psi times the camera's factor (1/(d^2 solid angle) for a pinhole,
!>   1/area for an orthographic pixel), times pi lx ly so that pixels are pi I/(mu0 F0) too.
!>
!> Contributions are Russian-rouletted with Iwabuchi's rule (digest 19.2 a, the zeta_min rule of
!> MCARaTS and the I3RC model): with a = w p and a_min = zeta_min/pi, a contribution a < a_min
!> survives with probability a/a_min as a_min; otherwise the line of sight is traced only until
!> its optical depth exceeds tau_lim + tau_free, tau_lim = ln(a/a_min), tau_free ~ Exp(1), and
!> the contribution is a exp(-min(tau, tau_lim)). Its expectation is a exp(-tau): unbiased, and
!> weak contributions through thick cloud cost no tracing.
!>
!> Optical depths along lines of sight are integrated exactly: layer by layer through the 1-D
!> layers and voxel by voxel through the 3-D region (the voxel walk of kumo_voxel_walk, which
!> the track-length absorption score of the flights takes too). With truncation the extinction is the
!> truncated one of the truncation level the light has after scattering into Omega_d (the delta
!> part of the phase function keeps light on the line of sight).
module kumo_local_estimate
  use kumo_kinds, only: wp
  use kumo_constants, only: PI
  use kumo_rng, only: rng_t, rng_uniform
  use kumo_math, only: wrap, rotate_direction
  use kumo_phase, only: phase_t, phase_eval, phase_sample_mu, PHASE_TABLE
  use kumo_truncation, only: trunc_eval, trunc_sample_mu
  use kumo_atmosphere, only: atmosphere_t, column_of, sigma_trunc_3d, voxel_ext, LAYER_CLEAR, &
                             LAYER_3D
  use kumo_voxel_walk, only: voxel_walk_t, walk_segment, walk_next, walk_layer
  use kumo_camera, only: camera_t, camera_project
  use kumo_tally, only: tally_layout_t, tally_t, score_radiance, score_radiance_map, score_camera, &
                        score_radiance_map_block
  use kumo_surface, only: surface_t
  use kumo_brdf, only: brdf_albedo, brdf_table_eval_dir
  use kumo_emission, only: emission_surface_eps
  implicit none
  private
  public :: detectors_t, detectors_init, le_particle, le_surface, le_boundary_emission, &
            ddis_factor, ddis_direction
  public :: detectors_bounds, density_bound

  real(wp), parameter :: INV_4PI = 0.25_wp/PI
  !> Bins of the bound table of the angular densities (uniform in the scattering-angle cosine)
  integer, parameter :: N_BOUND = 128
  !> Safety factor on the bounds: covers rounding in the evaluation of the interpolant
  real(wp), parameter :: BOUND_MARGIN = 1.001_wp

  !> What local estimates are tallied into.
  type :: detectors_t
    logical :: active = .false.            !! any level direction or camera
    integer :: n_dir = 0                   !! level-detector directions
    real(wp), allocatable :: ux(:), uy(:), uz(:) !! (n_dir) propagation directions
    integer, allocatable :: levels(:)      !! radiance levels, ascending
    real(wp) :: a_min = 0.0_wp             !! zeta_min/pi; 0: no roulette of contributions
    type(camera_t), allocatable :: cams(:) !! cameras
    real(wp) :: cam_scale = 1.0_wp         !! pi lx ly
    ! Numerical diffusion of radiance-map samples (seed text section 4.2.5; biased per pixel)
    real(wp) :: diff_scale = 0.0_wp        !! spread half-width [m] per sqrt(pi a); 0 = off
    integer :: diff_max = 0                !! largest half-width [columns]
    ! Detector directional importance sampling (Buras and Mayer 2011)
    real(wp) :: ddis_eps = 0.0_wp          !! chance of a DDIS secondary per scattering; 0 = off
    real(wp) :: ddis_mu_cone = -2.0_wp     !! secondaries only within this cosine of Omega_d
    logical, allocatable :: ddis_phase(:)  !! (n_phases) DDIS for scatterings by this phase
                                           !! function (those with a strong forward peak)
    !> (N_BOUND, truncation levels, n_phases): upper bounds of P^/(4 pi) (particle_density
    !> per unit weight) over bins of the scattering-angle cosine; unallocated: not used
    real(wp), allocatable :: p_bound(:, :, :)
  end type detectors_t

contains

  !> Detectors for directions (mu, phi_deg) at `levels`, cameras `cams`, roulette `zeta_min`.
  !> With `diff_scale` > 0, each radiance-map sample a is spread evenly over the columns within
  !> diff_scale sqrt(pi a) metres (at most `diff_max` columns) of where it crosses the level.
  subroutine detectors_init(det, mu, phi_deg, levels, cams, zeta_min, lx, ly, diff_scale, &
                            diff_max, ddis_eps)
    type(detectors_t), intent(out) :: det
    real(wp), intent(in) :: mu(:), phi_deg(:)
    integer, intent(in) :: levels(:)
    type(camera_t), intent(in) :: cams(:)
    real(wp), intent(in) :: zeta_min, lx, ly
    real(wp), intent(in), optional :: diff_scale
    integer, intent(in), optional :: diff_max
    real(wp), intent(in), optional :: ddis_eps   !! DDIS share (needs level directions)
    real(wp) :: s
    integer :: i
    det%n_dir = size(mu)
    allocate (det%ux(det%n_dir), det%uy(det%n_dir), det%uz(det%n_dir))
    do i = 1, det%n_dir
      s = sqrt(max(0.0_wp, 1.0_wp - mu(i)**2))
      det%ux(i) = s*cos(phi_deg(i)*PI/180.0_wp)
      det%uy(i) = s*sin(phi_deg(i)*PI/180.0_wp)
      det%uz(i) = mu(i)
    end do
    det%levels = levels
    if (det%n_dir == 0) det%levels = [integer ::]
    det%cams = cams
    det%a_min = zeta_min/PI
    det%cam_scale = PI*lx*ly
    det%active = det%n_dir > 0 .or. size(cams) > 0
    if (present(diff_scale) .and. present(diff_max)) then
      det%diff_scale = diff_scale
      det%diff_max = diff_max
    end if
    if (present(ddis_eps) .and. det%n_dir > 0) det%ddis_eps = ddis_eps
    allocate (det%ddis_phase(0))
  end subroutine detectors_init

  !> The bound table p_bound of the level detectors' roulette (see le_particle): for every
  !> phase function and truncation level of `atm`, the largest angular density per unit weight,
  !> P^(mu)/(4 pi) (P_trunc/(4 pi (1 - f)) when truncated), over each of N_BOUND equal bins of
  !> mu in [-1, 1]. Every phase-function kind is monotone in angle between its table nodes
  !> (tables: log-linear or linear in angle; Henyey-Greenstein: monotone; Rayleigh:
  !> a + b mu^2, b >= 0; isotropic: constant), so the maximum over a bin is the largest of its
  !> values at the bin's ends and at the table nodes inside it. Without roulette of
  !> contributions (zeta_min = 0) nothing is built.
  subroutine detectors_bounds(det, atm)
    type(detectors_t), intent(inout) :: det
    type(atmosphere_t), intent(in) :: atm
    integer :: n_lev, iph, lev, k
    real(wp) :: m1, m2, ut, pmax, scale
    if (allocated(det%p_bound)) deallocate (det%p_bound)
    if (det%n_dir == 0 .or. det%a_min <= 0.0_wp .or. size(atm%phases) == 0) return
    n_lev = 1
    if (atm%truncated) n_lev = atm%trunc%n_levels
    allocate (det%p_bound(N_BOUND, n_lev, size(atm%phases)))
    do iph = 1, size(atm%phases)
      do lev = 1, n_lev
        scale = BOUND_MARGIN*INV_4PI
        ut = 1.0_wp
        if (atm%truncated) then
          scale = scale/(1.0_wp - atm%trunc%f(lev, iph))
          ut = atm%trunc%u_t(lev, iph)
        end if
        do k = 1, N_BOUND
          m1 = -1.0_wp + 2.0_wp*real(k - 1, wp)/N_BOUND
          m2 = -1.0_wp + 2.0_wp*real(k, wp)/N_BOUND
          if (k == N_BOUND) m2 = 1.0_wp
          pmax = 0.0_wp
          if (atm%truncated .and. m2 > ut) pmax = atm%trunc%p_flat(lev, iph)
          if (m1 <= ut) pmax = max(pmax, phase_max(atm%phases(iph), m1, min(m2, ut)))
          det%p_bound(k, lev, iph) = scale*pmax
        end do
      end do
    end do
  end subroutine detectors_bounds

  !> Upper bound of the angular density per unit weight (P^/(4 pi), as in particle_density) of
  !> phase function iph at truncation level lev for the scattering-angle cosine mu, from the
  !> table of detectors_bounds (which must have been built and cover iph and lev).
  pure real(wp) function density_bound(det, iph, lev, mu) result(b)
    type(detectors_t), intent(in) :: det
    integer, intent(in) :: iph, lev
    real(wp), intent(in) :: mu
    integer :: k
    k = min(N_BOUND, max(1, int((mu + 1.0_wp)*(0.5_wp*N_BOUND)) + 1))
    b = det%p_bound(k, lev, iph)
  end function density_bound

  !> Largest value of phase function ph over mu in [m1, m2] (see detectors_bounds).
  real(wp) function phase_max(ph, m1, m2) result(pmax)
    type(phase_t), intent(in) :: ph
    real(wp), intent(in) :: m1, m2
    integer :: i
    pmax = max(phase_eval(ph, m1), phase_eval(ph, m2))
    if (ph%kind == PHASE_TABLE) then
      do i = 1, size(ph%mu_tab)
        if (ph%mu_tab(i) > m1 .and. ph%mu_tab(i) < m2) pmax = max(pmax, phase_eval(ph, ph%mu_tab(i)))
      end do
    end if
  end function phase_max

  !> Local estimates of a particle scattering at (x, y, z) in layer iz, for a photon arriving in
  !> direction (ux, uy, uz) with weight `w` (the expected scattered weight: after absorption,
  !> times the probability that the collision is a real, non-delta scattering), phase function
  !> `iph` at truncation level `lev`.
  subroutine le_particle(det, atm, lay, tal, rng, x, y, z, iz, ux, uy, uz, w, iph, lev, ps, &
                         column)
    type(detectors_t), intent(in) :: det
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    real(wp), value :: x, y, z, ux, uy, uz, w
    integer, value :: iz, iph, lev
    !> probability that the collision is a real scattering (collision forcing); the roulette
    !> threshold is scaled by it so that forced collisions are rouletted like real ones
    real(wp), value :: ps
    !> the light stays in the column of the event (ICA, P3D beyond its 3-D orders): lines of
    !> sight run vertically through that column, with their true slant path lengths
    logical, value :: column
    integer :: d, c, mx, my, ipix, lev_t
    real(wp) :: mu, a, vx, vy, vz, dist, factor, a_up, a_thr, u
    logical :: hit, bounded
    bounded = allocated(det%p_bound) .and. det%a_min > 0.0_wp .and. size(det%levels) > 0
    ! (phase functions added after the table was built, e.g. the isotropic one of thermal
    ! emission, are evaluated as before)
    if (bounded) bounded = iph <= size(det%p_bound, 3) .and. lev <= size(det%p_bound, 2)
    do d = 1, det%n_dir
      mu = ux*det%ux(d) + uy*det%uy(d) + uz*det%uz(d)
      if (bounded) then
        ! Roulette before the phase function is evaluated: when even the bound a_up >= a of
        ! the contribution is below the roulette threshold, the uniform deviate of the
        ! roulette is drawn now; u a_thr >= a_up drops the contribution as u a_thr >= a would,
        ! otherwise a is evaluated and rouletted with the same u: the same decisions, the same
        ! random numbers, one phase-function evaluation less for most weak contributions.
        a_up = w*density_bound(det, iph, lev, mu)
        a_thr = det%a_min*abs(det%uz(d))*ps
        if (a_up < a_thr) then
          if (a_up <= 0.0_wp) cycle
          u = rng_uniform(rng)
          if (u*a_thr >= a_up) cycle
          call particle_density(atm, iph, lev, mu, w, a, lev_t)
          call level_estimate(det, atm, lay, tal, rng, x, y, z, iz, iz, d, a, ps, lev_t, column, u)
          cycle
        end if
      end if
      call particle_density(atm, iph, lev, mu, w, a, lev_t)
      call level_estimate(det, atm, lay, tal, rng, x, y, z, iz, iz, d, a, ps, lev_t, column)
    end do
    do c = 1, size(det%cams)
      do my = det%cams(c)%my_lo, det%cams(c)%my_hi
        do mx = det%cams(c)%mx_lo, det%cams(c)%mx_hi
          call camera_project(det%cams(c), x + mx*atm%lx, y + my*atm%ly, z, ipix, dist, &
                              vx, vy, vz, factor, hit)
          if (.not. hit) cycle
          mu = ux*vx + uy*vy + uz*vz
          call particle_density(atm, iph, lev, mu, w, a, lev_t)
          call camera_estimate(det, atm, lay, tal, rng, x, y, z, iz, vx, vy, vz, dist, &
                               factor, a, ps, lev_t, c, ipix, column)
        end do
      end do
    end do
  end subroutine le_particle

  !> Detector directional importance sampling (DDIS; Buras and Mayer 2011, JQSRT 112, 434),
  !> here as a split: at a scattering the photon continues in a direction drawn from its phase
  !> function, and with probability eps a secondary photon is started in a direction drawn from
  !> the same phase function about a level-detector direction Omega_d, kept only if it lies in
  !> the cone Omega_d . Omega >= ddis_mu_cone. The secondaries then have the density
  !> eps mean_d P(Omega_d . Omega) 1[cone_d], and with the balance heuristic of multiple
  !> importance sampling (Veach 1997) each of the two photons carries
  !> w P(Omega_in . Omega) / (P(Omega_in . Omega) + eps mean_d P(Omega_d . Omega) 1[cone_d]),
  !> which keeps the sum unbiased. Secondaries travel along the detector directions with small weights, so
  !> the rare huge local estimates of a forward peak become frequent small ones, while the
  !> primary photon keeps (nearly) its weight. This function returns that weight factor for a
  !> photon arriving along u_in and leaving along v.
  real(wp) function ddis_factor(det, atm, iph, lev, uxi, uyi, uzi, vx, vy, vz) result(fac)
    type(detectors_t), intent(in) :: det
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: iph, lev
    real(wp), intent(in) :: uxi, uyi, uzi, vx, vy, vz
    real(wp) :: p_in, p_d, c
    integer :: d
    p_d = 0.0_wp
    do d = 1, det%n_dir
      c = det%ux(d)*vx + det%uy(d)*vy + det%uz(d)*vz
      if (c >= det%ddis_mu_cone) p_d = p_d + phase_value(atm, iph, lev, c)
    end do
    ! outside every cone (most directions) the factor is p_in/p_in = 1: no evaluation of p_in
    fac = 1.0_wp
    if (p_d <= 0.0_wp) return
    p_d = p_d/det%n_dir
    p_in = phase_value(atm, iph, lev, uxi*vx + uyi*vy + uzi*vz)
    fac = p_in/(p_in + det%ddis_eps*p_d)
  end function ddis_factor

  !> Direction of a DDIS secondary: the phase function iph about a level-detector direction
  !> chosen at random; (cphi, sphi) is a uniform azimuth.
  subroutine ddis_direction(det, atm, rng, iph, lev, cphi, sphi, vx, vy, vz, inside)
    type(detectors_t), intent(in) :: det
    type(atmosphere_t), intent(in) :: atm
    type(rng_t), intent(inout) :: rng
    integer, intent(in) :: iph, lev
    real(wp), intent(in) :: cphi, sphi
    real(wp), intent(out) :: vx, vy, vz
    logical, intent(out) :: inside   !! within the cone about the detector direction
    integer :: d
    real(wp) :: m
    d = min(det%n_dir, int(rng_uniform(rng)*det%n_dir) + 1)
    vx = det%ux(d)
    vy = det%uy(d)
    vz = det%uz(d)
    m = sample_cos(atm, iph, lev, rng_uniform(rng))
    inside = m >= det%ddis_mu_cone
    call rotate_direction(vx, vy, vz, m, cphi, sphi)
  end subroutine ddis_direction

  !> Cosine of a scattering angle drawn from phase function iph at truncation level lev.
  real(wp) function sample_cos(atm, iph, lev, u) result(m)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: iph, lev
    real(wp), intent(in) :: u
    if (atm%truncated) then
      m = trunc_sample_mu(atm%trunc, atm%phases(iph), iph, lev, u)
    else
      m = phase_sample_mu(atm%phases(iph), u)
    end if
  end function sample_cos

  !> Phase function iph (truncated at level lev) at the scattering-angle cosine mu, up to a
  !> factor that is the same for every angle.
  real(wp) function phase_value(atm, iph, lev, mu) result(p)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: iph, lev
    real(wp), intent(in) :: mu
    real(wp) :: m
    m = min(1.0_wp, max(-1.0_wp, mu))
    if (atm%truncated) then
      p = trunc_eval(atm%trunc, atm%phases(iph), iph, lev, m)
    else
      p = phase_eval(atm%phases(iph), m)
    end if
  end function phase_value

  !> Local estimates of a surface reflection at (x, y), Lambert or BRDF; `w` is the reflected
  !> weight (after multiplication by the directional albedo), `kb` the BRDF class of the pixel
  !> (BRDF surfaces only).
  subroutine le_surface(det, atm, lay, tal, rng, sfc, kb, x, y, ux, uy, uz, w, lev, column)
    type(detectors_t), intent(in) :: det
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    type(surface_t), intent(in) :: sfc
    integer, value :: kb
    real(wp), value :: x, y, w
    real(wp), value :: ux, uy, uz   !! incoming direction (BRDF surfaces)
    integer, value :: lev
    logical, value :: column   !! as in le_particle
    integer :: d, c, mx, my, ipix
    real(wp) :: a, vx, vy, vz, dist, factor, z0, w_pi
    logical :: hit
    z0 = atm%z(0)
    ! Lambert: BRDF/albedo = 1/pi; a BRDF: R(in, out)/alpha(mu_in), w already times alpha
    w_pi = w/PI
    if (sfc%use_brdf) w_pi = w/brdf_albedo(sfc%tabs(kb), -uz)
    do d = 1, det%n_dir
      if (det%uz(d) <= 0.0_wp) cycle
      if (sfc%use_brdf) then
        a = w_pi*det%uz(d)*brdf_table_eval_dir(sfc%tabs(kb), [ux, uy, uz], &
                                               [det%ux(d), det%uy(d), det%uz(d)])
      else
        a = w_pi*det%uz(d)
      end if
      call level_estimate(det, atm, lay, tal, rng, x, y, z0, 1, 0, d, a, 1.0_wp, lev, column)
    end do
    do c = 1, size(det%cams)
      do my = det%cams(c)%my_lo, det%cams(c)%my_hi
        do mx = det%cams(c)%mx_lo, det%cams(c)%mx_hi
          call camera_project(det%cams(c), x + mx*atm%lx, y + my*atm%ly, z0, ipix, dist, &
                              vx, vy, vz, factor, hit)
          if (.not. hit .or. vz <= 0.0_wp) cycle
          if (sfc%use_brdf) then
            a = w_pi*vz*brdf_table_eval_dir(sfc%tabs(kb), [ux, uy, uz], [vx, vy, vz])
          else
            a = w_pi*vz
          end if
          call camera_estimate(det, atm, lay, tal, rng, x, y, z0, 1, vx, vy, vz, dist, &
                               factor, a, 1.0_wp, lev, c, ipix, column)
        end do
      end do
    end do
  end subroutine le_surface

  !> Local estimates of thermal emission by a boundary at (x, y): the surface (`top` false),
  !> whose emission has the angular density eps(mu) mu/(pi <eps B>) per steradian for the weight
  !> `w` = (entry weight) B(x, y) (`eps_mean` is then <eps B>, the domain mean), or the top,
  !> whose isotropic downward radiance has mu/pi.
  subroutine le_boundary_emission(det, atm, lay, tal, rng, sfc, top, x, y, w, eps_mean, column)
    type(detectors_t), intent(in) :: det
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    type(surface_t), intent(in) :: sfc
    logical, value :: top
    real(wp), value :: x, y, w, eps_mean
    logical, value :: column   !! as in le_particle
    integer :: d, c, mx, my, ipix, iz, k_up
    real(wp) :: a, vx, vy, vz, dist, factor, z0, s
    logical :: hit
    if (top) then
      z0 = atm%z(atm%nz)
      iz = atm%nz
      k_up = atm%nz + 1
      s = -1.0_wp
    else
      z0 = atm%z(0)
      iz = 1
      k_up = 0
      s = 1.0_wp
    end if
    do d = 1, det%n_dir
      if (s*det%uz(d) <= 0.0_wp) cycle
      a = boundary_density(det%uz(d))
      call level_estimate(det, atm, lay, tal, rng, x, y, z0, iz, k_up, d, a, 1.0_wp, 1, column)
    end do
    do c = 1, size(det%cams)
      do my = det%cams(c)%my_lo, det%cams(c)%my_hi
        do mx = det%cams(c)%mx_lo, det%cams(c)%mx_hi
          call camera_project(det%cams(c), x + mx*atm%lx, y + my*atm%ly, z0, ipix, dist, &
                              vx, vy, vz, factor, hit)
          if (.not. hit .or. s*vz <= 0.0_wp) cycle
          a = boundary_density(vz)
          call camera_estimate(det, atm, lay, tal, rng, x, y, z0, iz, vx, vy, vz, dist, &
                               factor, a, 1.0_wp, 1, c, ipix, column)
        end do
      end do
    end do
  contains
    real(wp) function boundary_density(uz) result(dens)
      real(wp), intent(in) :: uz
      dens = w*abs(uz)/PI
      if (.not. top .and. eps_mean > 0.0_wp) dens = dens*emission_surface_eps(sfc, x, y, uz)/eps_mean
    end function boundary_density
  end subroutine le_boundary_emission

  !> Angular density times weight, a = w P^(mu)/(4 pi), of a particle scattering by the cosine
  !> `mu` of the scattering angle, and the truncation level the light has afterwards.
  subroutine particle_density(atm, iph, lev, mu, w, a, lev_t)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: iph, lev
    real(wp), intent(in) :: mu, w
    real(wp), intent(out) :: a
    integer, intent(out) :: lev_t
    real(wp) :: m
    m = min(1.0_wp, max(-1.0_wp, mu))
    if (atm%truncated) then
      a = w*INV_4PI*trunc_eval(atm%trunc, atm%phases(iph), iph, lev, m)/ &
          (1.0_wp - atm%trunc%f(lev, iph))
      lev_t = lev
      if (lev < atm%trunc%n_levels .and. m <= atm%trunc%mu_peak(iph)) lev_t = lev + 1
    else
      a = w*INV_4PI*phase_eval(atm%phases(iph), m)
      lev_t = 1
    end if
  end subroutine particle_density

  !> Roulette of a contribution (see the module text) against the threshold a_min: returns false
  !> if it is dropped; otherwise `a` (possibly raised to a_min), tau_lim and the optical depth
  !> at which the trace may stop. Any a_min > 0 is unbiased; it sets only the efficiency.
  logical function roulette_contribution(rng, a, a_min, tau_lim, tau_stop, u_pre) result(keep)
    type(rng_t), intent(inout) :: rng
    real(wp), intent(inout) :: a
    real(wp), intent(in) :: a_min
    real(wp), intent(out) :: tau_lim, tau_stop
    real(wp), intent(in), optional :: u_pre   !! the roulette's uniform deviate, drawn already
    real(wp) :: u
    keep = a > 0.0_wp
    tau_lim = huge(1.0_wp)
    tau_stop = huge(1.0_wp)
    if (.not. keep .or. a_min <= 0.0_wp) return
    if (a < a_min) then
      if (present(u_pre)) then
        u = u_pre
      else
        u = rng_uniform(rng)
      end if
      if (u*a_min >= a) then
        keep = .false.
        return
      end if
      a = a_min
      tau_lim = 0.0_wp
    else
      tau_lim = log(a/a_min)
    end if
    tau_stop = tau_lim - log(1.0_wp - rng_uniform(rng))
  end function roulette_contribution

  !> Contributions of one event to the level detectors of direction d. The event lies in layer
  !> iz (a particle) or on the surface (iz = 1, k_up = 0); upward light reaches the levels
  !> k >= k_up, downward light the levels k <= iz - 1.
  !> The roulette compares the contribution in reflectance units, pi a/|mu_d|, with zeta_min
  !> (times `ps` for forced collisions).
  subroutine level_estimate(det, atm, lay, tal, rng, x, y, z, iz, k_up, d, a_in, ps, lev_t, &
                            column, u_pre)
    type(detectors_t), intent(in) :: det
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    real(wp), intent(in) :: x, y, z, a_in, ps
    integer, intent(in) :: iz, k_up, d, lev_t
    logical, intent(in) :: column   !! the line of sight stays in the column of the event
    !> the roulette's uniform deviate, drawn already (le_particle; only when a_in is below the
    !> roulette threshold)
    real(wp), intent(in), optional :: u_pre
    real(wp) :: a, tau_lim, tau_stop, tau, psi0, xc, yc, zc, vx, vy, vz
    integer :: i, j, kd, izc, slot, n_lev
    if (size(det%levels) == 0) return
    a = a_in
    if (.not. roulette_contribution(rng, a, det%a_min*abs(det%uz(d))*ps, tau_lim, tau_stop, &
                                    u_pre)) then
      return
    end if
    vx = det%ux(d)
    vy = det%uy(d)
    vz = det%uz(d)
    if (column) then
      vx = 0.0_wp
      vy = 0.0_wp
    end if
    psi0 = PI*a/abs(vz)
    xc = x
    yc = y
    zc = z
    izc = iz
    tau = 0.0_wp
    n_lev = size(det%levels)
    do j = 1, n_lev
      if (vz > 0.0_wp) then
        i = j
        kd = det%levels(i)
        if (kd < k_up) cycle
      else
        i = n_lev + 1 - j
        kd = det%levels(i)
        if (kd > iz - 1) cycle
      end if
      call trace_to_level(atm, xc, yc, zc, izc, vx, vy, vz, kd, lev_t, tau, tau_stop)
      if (tau > tau_stop) return
      slot = lay%rad_slot(kd)
      call score_radiance(lay, tal, d, slot, psi0*exp(-min(tau, tau_lim)))
      if (lay%do_rad_maps) then
        ! the layout's choice, so that the samples come as the blocks its batch end integrates
        if (lay%rad_map_blocks) then
          call spread_sample(det, atm, lay, tal, d, slot, xc, yc, a, psi0*exp(-min(tau, tau_lim)))
        else
          call score_radiance_map(lay, tal, d, slot, column_of(atm, xc, yc), &
                                  psi0*exp(-min(tau, tau_lim)))
        end if
      end if
    end do
  end subroutine level_estimate

  !> Numerical diffusion (seed text section 4.2.5, Iwabuchi 2006): add the map sample `v` of
  !> direction d at the radiance level of `slot` evenly over the block of columns within
  !> r = diff_scale sqrt(pi a) of (x, y), periodic. Larger samples spread further; the sum over
  !> the map, and so the domain mean, is unchanged.
  subroutine spread_sample(det, atm, lay, tal, d, slot, x, y, a, v)
    type(detectors_t), intent(in) :: det
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    integer, intent(in) :: d, slot
    real(wp), intent(in) :: x, y, a, v
    real(wp) :: r, share
    integer :: nrx, nry, ix0, iy0, xlo(2), xhi(2), ylo(2), yhi(2), i, j
    r = det%diff_scale*sqrt(PI*a)
    nrx = min(det%diff_max, int(r*atm%inv_dx), (atm%nx - 1)/2)
    nry = min(det%diff_max, int(r*atm%inv_dy), (atm%ny - 1)/2)
    ix0 = min(atm%nx, max(1, int(x*atm%inv_dx) + 1))
    iy0 = min(atm%ny, max(1, int(y*atm%inv_dy) + 1))
    share = v/real((2*nrx + 1)*(2*nry + 1), wp)
    ! The columns ix0 - nrx .. ix0 + nrx (2 nrx + 1 <= nx, so no column twice) as at most two
    ! runs after the periodic wrap, and the rows likewise: at most four blocks, each added as
    ! the corners of its 2-D difference (the map is formed at the end of the batch).
    call wrap_runs(ix0, nrx, atm%nx, xlo, xhi)
    call wrap_runs(iy0, nry, atm%ny, ylo, yhi)
    do j = 1, 2
      if (ylo(j) > yhi(j)) cycle
      do i = 1, 2
        if (xlo(i) > xhi(i)) cycle
        call score_radiance_map_block(lay, tal, d, slot, xlo(i), xhi(i), ylo(j), yhi(j), share)
      end do
    end do
  contains
    !> i0 - nr .. i0 + nr on a periodic axis of n cells as runs [lo(1), hi(1)] and
    !> [lo(2), hi(2)] (the second empty, lo > hi, unless the wrap splits it)
    pure subroutine wrap_runs(i0, nr, n, lo, hi)
      integer, intent(in) :: i0, nr, n
      integer, intent(out) :: lo(2), hi(2)
      lo = [i0 - nr, 1]
      hi = [i0 + nr, 0]
      if (lo(1) < 1) then
        lo = [1, lo(1) + n]
        hi = [hi(1), n]
      else if (hi(1) > n) then
        hi = [n, hi(1) - n]
      end if
    end subroutine wrap_runs
  end subroutine spread_sample

  !> Contribution of one event to pixel ipix of camera c through the line of sight
  !> (vx, vy, vz) of length dist.
  subroutine camera_estimate(det, atm, lay, tal, rng, x, y, z, iz, vx, vy, vz, dist, factor, &
                             a_in, ps, lev_t, c, ipix, column)
    type(detectors_t), intent(in) :: det
    type(atmosphere_t), intent(in) :: atm
    type(tally_layout_t), intent(in) :: lay
    type(tally_t), intent(inout) :: tal
    type(rng_t), intent(inout) :: rng
    real(wp), intent(in) :: x, y, z, vx, vy, vz, dist, factor, a_in, ps
    integer, intent(in) :: iz, lev_t, c, ipix
    logical, intent(in) :: column   !! the line of sight stays in the column of the event
    real(wp) :: a, tau_lim, tau_stop, tau
    a = a_in
    if (.not. roulette_contribution(rng, a, det%a_min*ps, tau_lim, tau_stop)) return
    if (column) then
      call trace_distance(atm, x, y, z, iz, 0.0_wp, 0.0_wp, vz, dist, lev_t, tau, tau_stop)
    else
      call trace_distance(atm, x, y, z, iz, vx, vy, vz, dist, lev_t, tau, tau_stop)
    end if
    if (tau > tau_stop) return
    call score_camera(lay, tal, c, ipix, det%cam_scale*a*factor*exp(-min(tau, tau_lim)))
  end subroutine camera_estimate

  !> Add the optical depth from (x, y, z) in layer iz along (vx, vy, vz) up or down to level kd;
  !> on return the position is on level kd and iz is the layer beyond it. Stops early once
  !> tau > tau_stop.
  subroutine trace_to_level(atm, x, y, z, iz, vx, vy, vz, kd, lev_t, tau, tau_stop)
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(inout) :: x, y, z, tau
    integer, intent(inout) :: iz
    real(wp), intent(in) :: vx, vy, vz, tau_stop
    integer, intent(in) :: kd, lev_t
    real(wp) :: zb, s
    type(voxel_walk_t) :: wk
    logical :: walking
    walking = .false.
    if (vz > 0.0_wp) then
      do while (iz <= kd)
        zb = atm%z(iz)
        s = (zb - z)/vz
        call layer_segment(atm, iz, x, y, vx, vy, s, lev_t, tau, tau_stop, wk, walking)
        z = zb
        iz = iz + 1
        if (tau > tau_stop) return
      end do
    else
      do while (iz > kd)
        zb = atm%z(iz - 1)
        s = (zb - z)/vz
        call layer_segment(atm, iz, x, y, vx, vy, s, lev_t, tau, tau_stop, wk, walking)
        z = zb
        iz = iz - 1
        if (tau > tau_stop) return
      end do
    end if
  end subroutine trace_to_level

  !> Add the optical depth along (vx, vy, vz) over the distance `dist` from (x, y, z) in layer
  !> iz, or until the path leaves the atmosphere at the top (nothing scatters above).
  subroutine trace_distance(atm, x, y, z, iz, vx, vy, vz, dist, lev_t, tau, tau_stop)
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(in) :: x, y, z, vx, vy, vz, dist, tau_stop
    integer, intent(in) :: iz, lev_t
    real(wp), intent(out) :: tau
    real(wp) :: xc, yc, zc, left, s, zb
    integer :: k
    type(voxel_walk_t) :: wk
    logical :: walking
    walking = .false.
    xc = x
    yc = y
    zc = z
    k = iz
    left = dist
    tau = 0.0_wp
    do while (left > 0.0_wp)
      if (vz > 0.0_wp) then
        zb = atm%z(k)
      else
        zb = atm%z(k - 1)
      end if
      if (vz /= 0.0_wp) then
        s = (zb - zc)/vz
      else
        s = huge(1.0_wp)
      end if
      s = max(0.0_wp, s)
      if (s >= left) then
        call layer_segment(atm, k, xc, yc, vx, vy, left, lev_t, tau, tau_stop, wk, walking)
        return
      end if
      call layer_segment(atm, k, xc, yc, vx, vy, s, lev_t, tau, tau_stop, wk, walking)
      if (tau > tau_stop) return
      left = left - s
      zc = zb
      if (vz > 0.0_wp) then
        if (k == atm%nz) return
        k = k + 1
      else
        if (k == 1) return
        k = k - 1
      end if
    end do
  end subroutine trace_distance

  !> Optical depth of a straight segment of length s inside layer iz, starting at (x, y) with
  !> horizontal direction (vx, vy); (x, y) move to the end of the segment (wrapped) when the
  !> horizontal position matters.
  subroutine layer_segment(atm, iz, x, y, vx, vy, s, lev_t, tau, tau_stop, wk, walking)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: iz, lev_t
    real(wp), intent(inout) :: x, y, tau
    real(wp), intent(in) :: vx, vy, s, tau_stop
    !> the voxel walk of the path, and whether it ended at the bottom or top of this layer in
    !> the layer before (then it goes on instead of starting again; false after any other layer)
    type(voxel_walk_t), intent(inout) :: wk
    logical, intent(inout) :: walking
    integer :: kr
    select case (atm%layer_class(iz))
    case (LAYER_CLEAR)
    case (LAYER_3D)
      kr = iz - atm%k3_lo + 1
      if (atm%uniform3(kr)) then
        tau = tau + sigma_trunc_3d(atm, 1, 1, kr, lev_t)*s
      else
        call segment_3d(atm, kr, x, y, vx, vy, s, lev_t, tau, tau_stop, wk, walking)
        return
      end if
    case default
      if (lev_t > 1) then
        tau = tau + atm%ext1_lev(iz, lev_t)*s
      else
        tau = tau + atm%ext1(iz)*s
      end if
    end select
    walking = .false.
    x = x + vx*s
    y = y + vy*s
    call wrap(x, atm%lx)
    call wrap(y, atm%ly)
  end subroutine layer_segment

  !> layer_segment in 3-D layer kr whose voxels differ: the voxels the segment crosses, until
  !> the optical depth exceeds tau_stop. A walk that ended on this layer's boundary in the
  !> layer before (`walking`) goes on; otherwise one starts at (x, y).
  subroutine segment_3d(atm, kr, x, y, vx, vy, s, lev_t, tau, tau_stop, wk, walking)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: kr, lev_t
    real(wp), intent(inout) :: x, y, tau
    real(wp), intent(in) :: vx, vy, s, tau_stop
    type(voxel_walk_t), intent(inout) :: wk
    logical, intent(inout) :: walking
    real(wp) :: sig
    logical :: last
    call walk_layer(wk, atm, x, y, vx, vy, s, walking)
    do
      call walk_segment(wk, last)
      if (lev_t > 1) then
        sig = sigma_trunc_3d(atm, wk%ix, wk%iy, kr, lev_t)
      else
        sig = voxel_ext(atm, wk%ix, wk%iy, kr)
      end if
      tau = tau + sig*wk%step
      if (last) exit
      if (tau > tau_stop) return
      call walk_next(wk, atm)
    end do
    x = x + vx*s
    y = y + vy*s
    call wrap(x, atm%lx)
    call wrap(y, atm%ly)
  end subroutine segment_3d
end module kumo_local_estimate
