! SPDX-License-Identifier: BSD-3-Clause
!> Surface BRDF kernels: black, Lambert, rough ocean (DSM), RPV and LSRT models; evaluation,
!> directional albedo, setup-time tables and exact direction sampling for the photon loop.
!>
!> **Direction convention.** Every direction is a unit propagation vector u = (ux, uy, uz).
!> The incoming photon travels downward, u_in(3) < 0; the reflected photon travels upward,
!> u_out(3) > 0. The cosines are mu_in = -u_in(3) > 0 and mu_out = u_out(3) > 0. The relative
!> azimuth dphi is the angle between the horizontal parts of the two *propagation* vectors:
!>
!> * cos_dphi = +1: the photon keeps its horizontal heading (forward side; the specular
!>   direction is mu_out = mu_in, cos_dphi = +1, where a calm sea shows its glint);
!> * cos_dphi = -1: the photon goes back towards where it came from (the hot spot is
!>   mu_out = mu_in, cos_dphi = -1).
!>
!> The phase angle g between the reversed incident direction (towards the Sun) and the
!> reflected direction is cos g = -u_in . u_out = mu_in mu_out - sin(th_in) sin(th_out) cos_dphi
!> (g = 0 at the hot spot). Lucht et al. (2000) and Rahman et al. (1993) measure their
!> relative azimuth from the hot spot, phi = pi - dphi.
!>
!> **Normalisation.** `brdf_eval` returns the BRDF R in 1/sr: R = dL_out/(L_in mu_in dOmega_in),
!> a Lambert surface has R = albedo/pi. The published RPV and LSRT formulas give the
!> reflectance factor BRF = pi R; here R = BRF/pi for both (as MCARaTS does).
!>
!> **Parameters** (`brdf_params_t`, a kind code and five reals in the MCARaTS order, so a
!> MCARaTS surface record `type, param(1:5)` maps one to one; a 2-D surface map is an array
!> `type(brdf_params_t) :: map(nx, ny)`):
!>
!> | kind | c(1) | c(2) | c(3) | c(4) | c(5) |
!> |---|---|---|---|---|---|
!> | `BRDF_BLACK` = 0 | - | - | - | - | - |
!> | `BRDF_LAMBERT` = 1 | albedo | - | - | - | - |
!> | `BRDF_DSM` = 2 | diffuse albedo a_d | diffuse fraction f_d | index n_r | n_i | sigma^2 |
!> | `BRDF_RPV` = 3 | rho0 | k | Theta | hot-spot h | - |
!> | `BRDF_LSRT` = 4 | k_iso | k_geo | k_vol | - | - |
!>
!> DSM: refractive index n_r + i n_i of the water, sigma^2 the total mean-square facet slope.
!> Note the LSRT order (iso, geo, vol) of MCARaTS; MODIS MCD43 products list (iso, vol, geo).
!>
!> **Photon loop.** Build one `brdf_table_t` per distinct parameter set with `brdf_table_init`
!> (validation, directional albedo table in mu_in, sampling envelopes; 10-100 ms). At
!> a reflection: multiply the weight by `brdf_albedo(tab, mu_in)` (<= 1), use
!> `brdf_table_eval(tab, ...)`/`brdf_albedo(tab, mu_in)` as the angular density of local
!> estimates, and draw the new direction with `brdf_sample`, whose distribution is
!> R mu_out/alpha(mu_in) of the same model. Where the model's albedo exceeds 1 (RPV, LSRT at
!> grazing incidence), alpha is set to 1 and the BRDF scaled down by the same factor
!> (`brdf_table_eval`); `brdf_eval` is the unscaled model.
!>
!> Nothing here allocates, reads or writes files, or keeps module state: every procedure used
!> in the photon loop is pure and safe to call from several threads.
module kumo_brdf
  use kumo_kinds, only: wp, i8
  use kumo_constants, only: PI, TWO_PI
  use kumo_error, only: error_t, set_error, str, to_lower
  use kumo_math, only: within, gauss_legendre01
  use kumo_rng, only: rng_t, rng_next_uniform, sample_azimuth
  implicit none
  private
  public :: BRDF_BLACK, BRDF_LAMBERT, BRDF_DSM, BRDF_RPV, BRDF_LSRT, BRDF_NAMES, BRDF_NPAR
  public :: BRDF_NPAR_USED, BRDF_NMU, BRDF_NALB, BRDF_NALB_MAX
  public :: brdf_params_t, brdf_table_t
  public :: brdf_params, brdf_kind_from_name, brdf_validate
  public :: brdf_eval, brdf_eval_dir, brdf_albedo_quad
  public :: brdf_table_init, brdf_albedo, brdf_table_eval, brdf_table_eval_dir, brdf_sample
  public :: lambert_direction
  public :: lsrt_grid_t, lsrt_grid_init, brdf_table_init_grid
  public :: cox_munk_slope_variance, fresnel_reflectance, dsm_shadowing
  public :: ross_thick_kernel, li_sparse_r_kernel, lsrt_kernel_albedos, lsrt_negative_fraction

  integer, parameter :: BRDF_BLACK = 0    !! no reflection
  integer, parameter :: BRDF_LAMBERT = 1  !! isotropic reflection, R = albedo/pi
  integer, parameter :: BRDF_DSM = 2      !! diffuse plus rough Fresnel facets (water)
  integer, parameter :: BRDF_RPV = 3      !! Rahman-Pinty-Verstraete
  integer, parameter :: BRDF_LSRT = 4     !! Li-Sparse-Reciprocal / Ross-Thick kernels

  !> Names of the kinds, indexed by kind code (lower case, as in a namelist).
  character(len=7), parameter :: BRDF_NAMES(0:4) = [character(len=7) :: &
                                                    'black', 'lambert', 'dsm', 'rpv', 'lsrt']
  integer, parameter :: BRDF_NPAR = 5  !! parameter slots per surface
  !> Number of parameters each kind uses (MCARaTS: Lambert 1, DSM 5, RPV 4, LSRT 3).
  integer, parameter :: BRDF_NPAR_USED(0:4) = [0, 1, 5, 4, 3]

  !> Nodes of the mu_in tables, uniform in x = sqrt(mu_in): mu_j = ((j - 1)/(BRDF_NMU - 1))^2,
  !> denser towards grazing incidence where the albedos change fastest. The first node is
  !> evaluated at MU_NODE0 instead of 0, where RPV and LSRT diverge.
  integer, parameter :: BRDF_NMU = 21
  real(wp), parameter :: MU_NODE0 = 1.0e-10_wp
  !> Largest accepted fraction of (cosine-weighted) direction pairs where the LSRT kernel sum
  !> is negative and clamped to 0 (`brdf_validate`).
  real(wp), parameter :: LSRT_NEG_MAX = 0.25_wp
  !> Nodes of the dense albedo table (`brdf_table_init`), uniform in sqrt(mu_in) like the
  !> envelope nodes; the envelopes keep BRDF_NMU. With cubic interpolation the albedo is within
  !> 1e-6 relative of the quadrature wherever it is smooth; where it is not (the clipping of a
  !> negative LSRT kernel sum starts or ends at some mu_in), nodes are added adaptively: every
  !> interval with mu_in >= ALB_CHECK_MU is checked at its midpoint against the quadrature
  !> and halved while the error exceeds ALB_TOL, up to BRDF_NALB_MAX nodes in all.
  integer, parameter :: BRDF_NALB = 121
  integer, parameter :: BRDF_NALB_MAX = 241
  real(wp), parameter :: ALB_TOL = 2.0e-7_wp
  real(wp), parameter :: ALB_CHECK_MU = 0.01_wp

  !> Hemispheric quadrature for RPV and LSRT: panels of N_A Gauss-Legendre nodes in mu_out
  !> (split at the hot spot mu_out = mu_in and, for LSRT, where the Li-Sparse overlap clamp
  !> starts on the principal plane) times panels of N_P nodes in dphi on [0, pi] (the
  !> integrand is even in dphi; LSRT rows are split where they cross the clamp curve).
  integer, parameter :: N_A = 12
  integer, parameter :: N_P = 16
  integer, parameter :: MAX_PANELS = 10
  integer, parameter :: MAX_ROWS = MAX_PANELS*N_A
  integer, parameter :: MAX_PHI_PANELS = 7
  integer, parameter :: MAX_PHI = MAX_PHI_PANELS*N_P
  integer, parameter :: N_PROF = MAX_ROWS + 3  !! rows of the envelope scan
  !> RPV quadrature near the hot spot (mu_out = mu_in, dphi = pi), where the hot-spot term
  !> and a backward Henyey-Greenstein peak are sharp: the mu_out panels on both sides of mu_in
  !> are graded geometrically (lengths HOT_RATIO^k of the side, at most HOT_MU_MAX levels) and
  !> each row's dphi panel towards pi likewise, until a panel is HOT_RES times the peak width
  !> (`rpv_width`). Without it the albedo of a sharp hot spot (h = 0.3, or Theta = -0.9 with
  !> h = 0.05) was off by 8e-6 (4.6e-4) relative; with it 5e-8 against the same quadrature with
  !> 64 x 96 nodes per panel.
  integer, parameter :: HOT_MU_MAX = 4
  real(wp), parameter :: HOT_RES = 0.2_wp
  real(wp), parameter :: HOT_RATIO = 0.25_wp

  !> Slope-space quadrature for the DSM specular albedo: N_PSI midpoints in the slope azimuth,
  !> N_W Gauss-Legendre nodes in s = tan(th_n)/sigma on [0, min(s_c, S_MAX)]; the slope
  !> density beyond S_MAX is below exp(-42).
  integer, parameter :: N_PSI = 24
  integer, parameter :: N_W = 24
  real(wp), parameter :: S_MAX = 6.5_wp
  !> DSM envelope scan: slopes with tan^2(th_n)/sigma^2 <= T_TAIL (probability
  !> 1 - exp(-28) = 1 - 7e-13), N_SR radii by N_SPSI azimuths.
  real(wp), parameter :: T_TAIL = 28.0_wp
  integer, parameter :: N_SR = 32
  integer, parameter :: N_SPSI = 24

  !> The envelope bins in mu_in: the first table interval [0, mu_2] is split at these
  !> fractions of mu_2 = 0.0025 (for RPV with k < 1/2 the bound grows as mu_in^(2k-1) towards
  !> grazing incidence), the others are the table intervals.
  integer, parameter :: N_GRAZ = 4
  real(wp), parameter :: GRAZ_EDGES(N_GRAZ) = [1.0e-4_wp, 1.0e-3_wp, 1.0e-2_wp, 0.1_wp]
  integer, parameter :: N_ENV = BRDF_NMU - 1 + N_GRAZ

  !> The sampling envelopes are the largest ratio found on the scan grids times this margin.
  real(wp), parameter :: ENV_MARGIN = 1.15_wp
  !> Slope range of the linear envelope a1 mu + a0 (MCARaTS range, keeps a0 >= 0.005/pi).
  real(wp), parameter :: A1_MIN = -0.5_wp/PI, A1_MAX = 0.99_wp/PI
  integer, parameter :: N_A1 = 64
  !> Rejection loops end after this many tries (the last proposal is taken and counted).
  integer, parameter :: MAX_TRIES = 100000

  real(wp), parameter :: SQRT_PI = sqrt(PI)

  !> One surface's BRDF: a kind code and its parameters (see the module table for c).
  type :: brdf_params_t
    integer :: kind = BRDF_BLACK          !! BRDF_BLACK ... BRDF_LSRT
    real(wp) :: c(BRDF_NPAR) = 0.0_wp     !! parameters in the MCARaTS order
  end type brdf_params_t

  !> Setup-time tables of one parameter set, for the photon loop (fixed size, no allocation:
  !> an array of tables is one contiguous block, about 4.4 kB per table).
  type :: brdf_table_t
    type(brdf_params_t) :: p               !! the model
    !> Albedo table: alpha_model(mu) = T(mu) mu^(-t_pow), T interpolated cubically between
    !> the nodes mu_j. RPV: t_pow = 1 - k; LSRT: 1; DSM: 0 and T is the specular albedo.
    real(wp) :: t_pow = 0.0_wp
    real(wp) :: t(BRDF_NMU) = 0.0_wp
    !> The same on n_alb >= BRDF_NALB nodes at x = sqrt(mu_in) = xa (used instead of t when
    !> n_alb >= BRDF_NALB): BRDF_NALB uniform nodes, then (alb_uniform false) adaptive ones.
    integer :: n_alb = BRDF_NMU
    logical :: alb_uniform = .true.
    real(wp) :: xa(BRDF_NALB_MAX) = 0.0_wp
    real(wp) :: ta(BRDF_NALB_MAX) = 0.0_wp
    !> Exact model albedo (quadrature) at the solar mu_in given at setup: every direct-beam
    !> photon arrives with exactly this mu_in, so its albedo carries no interpolation error.
    real(wp) :: mu_sun = -1.0_wp
    real(wp) :: alpha_sun = 0.0_wp
    !> Envelopes per bin of mu_in (the intervals [mu_j, mu_j+1], the first one split at
    !> GRAZ_EDGES): slope a1 of the linear envelope (RPV, LSRT) and bound b on the ratio of
    !> target to proposal (RPV, LSRT: mu R/(alpha (a1 mu + a0)); DSM: R_F f_s cos(v)/mu_n of
    !> the facet sampler).
    real(wp) :: a1(N_ENV) = 0.0_wp
    real(wp) :: env(N_ENV) = 0.0_wp
    integer :: n_clamped = 0               !! nodes where the model albedo exceeds 1
    real(wp) :: mu_clamped = 0.0_wp        !! largest such node mu (0: none)
    real(wp) :: interp_err = 0.0_wp        !! largest relative albedo error at the midpoints
  end type brdf_table_t

  !> Kernel values shared by the LSRT tables of a surface map (`lsrt_grid_init`, once per
  !> run, about 30 ms), from which `brdf_table_init_grid` builds the table of one parameter
  !> set in about 0.1 ms instead of the 20-40 ms of `brdf_table_init`.
  !>
  !> * Albedo nodes: the Ross-Thick and Li-Sparse-R kernels at the points of the hemispheric
  !>   quadrature of `brdf_albedo_quad`, with its panels split at the hot spot and the
  !>   Li-Sparse clamp curve (both independent of the weights) but not at the zero curve of the
  !>   clipped kernel sum, which depends on the weights. The albedo max(0, sum) integrated on
  !>   these points is exact to 1e-9 where the sum stays positive; where it is clipped the kink
  !>   inside a panel costs accuracy: against `brdf_albedo_quad`, up to 4e-3 relative for
  !>   typical weights (alb_N98: 0.3, 0.07, 0.03; MODIS-like 0.25, 0.04, 0.1) and 7e-3 where
  !>   clipping is strong (k_geo ~ k_iso), measured at mu_in >= 0.01 (the unit tests).
  !> * Envelopes: per envelope bin and sample of mu_in, per row of mu_out, the largest and
  !>   smallest value of each kernel over the row. The sum's row maximum is bounded by the sum
  !>   of the weighted extremes, a true bound that is looser than the scan of `brdf_table_init`
  !>   (more tries per sample where the two kernels peak in different places).
  type :: lsrt_grid_t
    integer :: n_pts(BRDF_NMU) = 0                 !! quadrature points per node
    real(wp), allocatable :: w(:, :)               !! weight x mu_out x 2, (point, node)
    real(wp), allocatable :: kg(:, :), kv(:, :)    !! Li-Sparse-R, Ross-Thick (point, node)
    integer :: n_rows(5, N_ENV) = 0                !! profile rows per bin sample
    !> per (row, sample, bin): mu_out and the kernels' extremes over the row
    real(wp), allocatable :: pmu(:, :, :), gmax(:, :, :), gmin(:, :, :)
    real(wp), allocatable :: vmax(:, :, :), vmin(:, :, :)
  end type lsrt_grid_t

  !> Slopes of the linear envelope tried per bin by `brdf_table_init_grid`.
  integer, parameter :: N_A1_GRID = 8

contains

  ! ------------------------------------------------------------------------------------------
  ! Parameters
  ! ------------------------------------------------------------------------------------------

  !> Parameter set from a kind code and up to five parameters (missing ones are 0).
  pure function brdf_params(kind, c) result(p)
    integer, intent(in) :: kind      !! BRDF_BLACK ... BRDF_LSRT
    real(wp), intent(in) :: c(:)     !! parameters in the MCARaTS order
    type(brdf_params_t) :: p
    integer :: n
    p%kind = kind
    n = min(size(c), BRDF_NPAR)
    p%c(1:n) = c(1:n)
  end function brdf_params

  !> Kind code of a BRDF name ('black', 'lambert', 'dsm', 'rpv', 'lsrt'; case and surrounding
  !> blanks ignored); -1 and an error for an unknown name.
  subroutine brdf_kind_from_name(name, kind, error)
    character(len=*), intent(in) :: name
    integer, intent(out) :: kind
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    do i = 0, 4
      if (trim(adjustl(to_lower(name))) == trim(BRDF_NAMES(i))) then
        kind = i
        return
      end if
    end do
    kind = -1
    call set_error(error, "brdf kind '"//trim(adjustl(name))// &
                   "' must be one of black, lambert, dsm, rpv, lsrt")
  end subroutine brdf_kind_from_name

  !> Check a parameter set. The message names the model, the parameter, its value and bound.
  !> Ranges: Lambert albedo in [0, 1]; DSM a_d, f_d in [0, 1], n_r in [1, 100], n_i in
  !> [0, 100], sigma^2 in (0, 100] (MCARaTS limits 100); RPV rho0 in [0, 1], k in (0, 2],
  !> |Theta| < 1, h > 0; LSRT weights >= 0 and finite, and a kernel sum negative (clamped to
  !> 0) for at most LSRT_NEG_MAX of the direction pairs (`lsrt_negative_fraction`).
  subroutine brdf_validate(p, error)
    type(brdf_params_t), intent(in) :: p
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: frac
    select case (p%kind)
    case (BRDF_BLACK)
    case (BRDF_LAMBERT)
      call in_closed(p%c(1), 0.0_wp, 1.0_wp, 'lambert albedo', error)
    case (BRDF_DSM)
      call in_closed(p%c(1), 0.0_wp, 1.0_wp, 'dsm diffuse albedo a_d', error)
      if (allocated(error)) return
      call in_closed(p%c(2), 0.0_wp, 1.0_wp, 'dsm diffuse fraction f_d', error)
      if (allocated(error)) return
      call in_closed(p%c(3), 1.0_wp, 100.0_wp, 'dsm refractive index real part n_r', error)
      if (allocated(error)) return
      call in_closed(p%c(4), 0.0_wp, 100.0_wp, 'dsm refractive index imaginary part n_i', error)
      if (allocated(error)) return
      if (.not. (within(p%c(5), 0.0_wp, 100.0_wp) .and. p%c(5) > 0.0_wp)) then
        call set_error(error, 'brdf dsm slope variance sigma2 = '//str(p%c(5))// &
                       ' must satisfy 0 < sigma2 <= 100')
      end if
    case (BRDF_RPV)
      call in_closed(p%c(1), 0.0_wp, 1.0_wp, 'rpv rho0', error)
      if (allocated(error)) return
      if (.not. (within(p%c(2), 0.0_wp, 2.0_wp) .and. p%c(2) > 0.0_wp)) then
        call set_error(error, 'brdf rpv k = '//str(p%c(2))//' must satisfy 0 < k <= 2')
        return
      end if
      if (.not. (within(p%c(3), -1.0_wp, 1.0_wp) .and. abs(p%c(3)) < 1.0_wp)) then
        call set_error(error, 'brdf rpv Theta = '//str(p%c(3))//' must satisfy |Theta| < 1')
        return
      end if
      if (.not. (within(p%c(4), 0.0_wp, huge(1.0_wp)) .and. p%c(4) > 0.0_wp)) then
        call set_error(error, 'brdf rpv hot-spot parameter h = '//str(p%c(4))// &
                       ' must be > 0 (1 in the original model)')
      end if
    case (BRDF_LSRT)
      call non_negative(p%c(1), 'lsrt k_iso', error)
      if (allocated(error)) return
      call non_negative(p%c(2), 'lsrt k_geo', error)
      if (allocated(error)) return
      call non_negative(p%c(3), 'lsrt k_vol', error)
      if (allocated(error)) return
      frac = lsrt_negative_fraction(p)
      if (frac > LSRT_NEG_MAX) then
        call set_error(error, 'brdf lsrt weights k_iso = '//str(p%c(1))//', k_geo = '// &
                       str(p%c(2))//', k_vol = '//str(p%c(3))//' give a kernel sum that is '// &
                       'negative for '//str(nint(100*frac))//' % of the pairs of incident '// &
                       'and reflected directions (cosine-weighted; at most '// &
                       str(nint(100*LSRT_NEG_MAX))//' % accepted); it would be clamped to 0 '// &
                       'there, which changes the surface: check the weights and their order '// &
                       '(k_iso, k_geo, k_vol)')
      end if
    case default
      call set_error(error, 'brdf kind = '//str(p%kind)//' must be within [0, 4] '// &
                     '(0 black, 1 lambert, 2 dsm, 3 rpv, 4 lsrt)')
    end select
  end subroutine brdf_validate

  subroutine in_closed(x, lo, hi, name, error)
    real(wp), intent(in) :: x, lo, hi
    character(len=*), intent(in) :: name
    type(error_t), allocatable, intent(out) :: error
    if (.not. within(x, lo, hi)) then
      call set_error(error, 'brdf '//name//' = '//str(x)//' must be within ['//str(lo)// &
                     ', '//str(hi)//']')
    end if
  end subroutine in_closed

  subroutine non_negative(x, name, error)
    real(wp), intent(in) :: x
    character(len=*), intent(in) :: name
    type(error_t), allocatable, intent(out) :: error
    if (.not. within(x, 0.0_wp, huge(1.0_wp))) then
      call set_error(error, 'brdf '//name//' = '//str(x)//' must be >= 0 and finite')
    end if
  end subroutine non_negative

  ! ------------------------------------------------------------------------------------------
  ! Helpers of the models
  ! ------------------------------------------------------------------------------------------

  !> Mean-square slope of the sea surface for the wind speed at 12.5 m, sigma^2 = 0.003 +
  !> 0.00512 U (Cox and Munk 1954, J. Opt. Soc. Am. 44, 838-850, clean surface, isotropic
  !> fit); negative speeds count as 0.
  elemental function cox_munk_slope_variance(wind_speed) result(sigma2)
    real(wp), intent(in) :: wind_speed  !! wind speed [m s-1]
    real(wp) :: sigma2                  !! total mean-square slope <zx^2 + zy^2>
    sigma2 = 0.003_wp + 0.00512_wp*max(0.0_wp, wind_speed)
  end function cox_munk_slope_variance

  !> Fresnel reflectance of unpolarised light, R_F = (|r_s|^2 + |r_p|^2)/2, at a surface of
  !> complex refractive index m = n_r + i n_i (relative to the incident medium) and incidence
  !> cosine cos_i (Born and Wolf, Principles of Optics, sec. 13.2; Liou 2002, An Introduction
  !> to Atmospheric Radiation, sec. 5.2). With w = sqrt(m^2 - sin^2), principal branch
  !> (Re, Im >= 0 for n_i >= 0): r_s = (cos_i - w)/(cos_i + w), r_p = (m^2 cos_i - w)/(m^2 cos_i
  !> + w). Grazing incidence (cos_i <= 0) gives 1.
  elemental function fresnel_reflectance(n_r, n_i, cos_i) result(r)
    real(wp), intent(in) :: n_r    !! real part of the refractive index (>= 1)
    real(wp), intent(in) :: n_i    !! imaginary part (>= 0)
    real(wp), intent(in) :: cos_i  !! cosine of the angle of incidence on the facet
    real(wp) :: r
    real(wp) :: c, s2, w, m2r, rs, rp
    complex(wp) :: m2, wc, rsc, rpc
    c = min(1.0_wp, cos_i)
    if (c <= 0.0_wp) then
      r = 1.0_wp
      return
    end if
    s2 = (1.0_wp - c)*(1.0_wp + c)
    if (n_i == 0.0_wp) then
      m2r = n_r*n_r
      w = sqrt(max(0.0_wp, m2r - s2))
      rs = (c - w)/(c + w)
      rp = (m2r*c - w)/(m2r*c + w)
      r = 0.5_wp*(rs*rs + rp*rp)
    else
      m2 = cmplx(n_r*n_r - n_i*n_i, 2.0_wp*n_r*n_i, kind=wp)
      wc = sqrt(m2 - s2)
      rsc = (c - wc)/(c + wc)
      rpc = (m2*c - wc)/(m2*c + wc)
      r = 0.5_wp*(real(rsc, wp)**2 + aimag(rsc)**2 + real(rpc, wp)**2 + aimag(rpc)**2)
    end if
  end function fresnel_reflectance

  !> Smith's shadowing term Lambda(mu) for an isotropic Gaussian slope distribution of total
  !> mean-square slope sigma^2: Lambda = [exp(-nu^2)/(sqrt(pi) nu) - erfc(nu)]/2 with
  !> nu = mu/(sigma sqrt(1 - mu^2)) (Smith 1967, IEEE Trans. Antennas Propag. 15, 668-671;
  !> Tsang et al. 1985, Theory of Microwave Remote Sensing; Nakajima and Tanaka 1983, JQSRT 29,
  !> 521-537). The bidirectional shadowing factor is f_s = 1/(1 + Lambda(mu_in) +
  !> Lambda(mu_out)). Lambda(1) = 0; Lambda grows as 1/(2 sqrt(pi) nu) towards the horizon.
  elemental function dsm_shadowing(mu, sigma) result(lam)
    real(wp), intent(in) :: mu     !! cosine of the direction's zenith angle
    real(wp), intent(in) :: sigma  !! rms slope sqrt(sigma^2)
    real(wp) :: lam
    real(wp) :: nu
    if (mu >= 1.0_wp) then
      lam = 0.0_wp
      return
    end if
    if (mu <= 0.0_wp) then
      lam = 1.0e30_wp
      return
    end if
    nu = mu/(sigma*sqrt((1.0_wp - mu)*(1.0_wp + mu)))
    if (nu > 6.0_wp) then        ! Lambda(6) < 1e-18
      lam = 0.0_wp
    else
      nu = max(nu, 1.0e-25_wp)
      lam = 0.5_wp*(exp(-nu*nu)/(SQRT_PI*nu) - erfc(nu))
    end if
  end function dsm_shadowing

  !> sin(theta) from mu = cos(theta) without cancellation near |mu| = 1.
  elemental function sin_of(mu) result(s)
    real(wp), intent(in) :: mu
    real(wp) :: s
    s = sqrt(max(0.0_wp, (1.0_wp - mu)*(1.0_wp + mu)))
  end function sin_of

  !> Ross-Thick volume-scattering kernel (Roujean et al. 1992, JGR 97, 20455-20468; Wanner et
  !> al. 1995, JGR 100, 21077-21089; Lucht et al. 2000, IEEE TGRS 38, 977-998, eq. 38):
  !> f_v = [(pi/2 - xi) cos xi + sin xi]/(mu_in + mu_out) - pi/4, xi the phase angle
  !> (cos xi = mu_in mu_out - sin sin cos_dphi in the module's azimuth convention).
  elemental function ross_thick_kernel(mu_in, mu_out, cos_dphi) result(f)
    real(wp), intent(in) :: mu_in, mu_out  !! cosines of the incident and reflected zenith
    real(wp), intent(in) :: cos_dphi       !! cosine of the relative azimuth (see module)
    real(wp) :: f
    f = ross_thick_core(mu_in, mu_out, cos_phase(mu_in, mu_out, cos_dphi))
  end function ross_thick_kernel

  !> Cosine of the phase angle between the reversed incident and the reflected direction.
  elemental function cos_phase(mu_in, mu_out, cos_dphi) result(cg)
    real(wp), intent(in) :: mu_in, mu_out, cos_dphi
    real(wp) :: cg
    cg = mu_in*mu_out - sin_of(mu_in)*sin_of(mu_out)*cos_dphi
  end function cos_phase

  pure function ross_thick_core(mu0, mu1, cg) result(f)
    real(wp), intent(in) :: mu0, mu1, cg
    real(wp) :: f
    real(wp) :: c, xi
    c = min(1.0_wp, max(-1.0_wp, cg))
    xi = acos(c)
    f = ((0.5_wp*PI - xi)*c + sin_of(c))/(mu0 + mu1) - 0.25_wp*PI
  end function ross_thick_core

  !> Li-Sparse-Reciprocal geometric kernel with crown shape b/r = 1 and relative height
  !> h/b = 2 (Wanner et al. 1995; Lucht et al. 2000, eqs. 39-44). With b/r = 1 the primed
  !> angles equal the true ones, and the overlap parameter is cos t = (h/b) sin xi/(mu_in +
  !> mu_out) (the form of Lucht's eq. 42 after multiplying by mu_in mu_out), clamped to
  !> [-1, 1]; then f_g = {[(t - sin t cos t)/pi - 1](mu_in + mu_out) + (1 + cos xi)/2}/
  !> (mu_in mu_out). At the hot spot f_g = (1 - mu)/mu^2.
  elemental function li_sparse_r_kernel(mu_in, mu_out, cos_dphi) result(f)
    real(wp), intent(in) :: mu_in, mu_out  !! cosines of the incident and reflected zenith
    real(wp), intent(in) :: cos_dphi       !! cosine of the relative azimuth (see module)
    real(wp) :: f
    f = li_sparse_core(mu_in, mu_out, cos_phase(mu_in, mu_out, cos_dphi))
  end function li_sparse_r_kernel

  pure function li_sparse_core(mu0, mu1, cg) result(f)
    real(wp), intent(in) :: mu0, mu1, cg
    real(wp) :: f
    real(wp), parameter :: H_OVER_B = 2.0_wp
    real(wp) :: c, ct, t, st
    c = min(1.0_wp, max(-1.0_wp, cg))
    ct = min(1.0_wp, H_OVER_B*sin_of(c)/(mu0 + mu1))
    t = acos(ct)
    st = sin_of(ct)
    f = (((t - st*ct)/PI - 1.0_wp)*(mu0 + mu1) + 0.5_wp*(1.0_wp + c))/(mu0*mu1)
  end function li_sparse_core

  ! ------------------------------------------------------------------------------------------
  ! Evaluation
  ! ------------------------------------------------------------------------------------------

  !> BRDF [1/sr] of the model for incident and reflected cosines and the relative azimuth of
  !> the module convention (cos_dphi = +1 forward/specular, -1 back/hot spot). 0 unless
  !> mu_in > 0 and mu_out > 0. Reciprocal: R(mu_in, mu_out, c) = R(mu_out, mu_in, c).
  elemental function brdf_eval(p, mu_in, mu_out, cos_dphi) result(r)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu_in     !! cosine of the incident zenith angle, > 0
    real(wp), intent(in) :: mu_out    !! cosine of the reflected zenith angle, > 0
    real(wp), intent(in) :: cos_dphi  !! cosine of the relative azimuth
    real(wp) :: r
    real(wp) :: s0, s1
    if (.not. (mu_in > 0.0_wp .and. mu_out > 0.0_wp)) then
      r = 0.0_wp
      return
    end if
    s0 = sin_of(mu_in)
    s1 = sin_of(mu_out)
    r = eval_core(p, min(mu_in, 1.0_wp), min(mu_out, 1.0_wp), s0, s1, s0*s1*cos_dphi)
  end function brdf_eval

  !> BRDF [1/sr] for the propagation vectors of the incoming (u_in(3) < 0) and reflected
  !> (u_out(3) > 0) photon; 0 for other pairs.
  pure function brdf_eval_dir(p, u_in, u_out) result(r)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: u_in(3)   !! incoming propagation direction, unit vector
    real(wp), intent(in) :: u_out(3)  !! reflected propagation direction, unit vector
    real(wp) :: r
    real(wp) :: mu0, mu1
    mu0 = min(1.0_wp, -u_in(3))
    mu1 = min(1.0_wp, u_out(3))
    if (.not. (mu0 > 0.0_wp .and. mu1 > 0.0_wp)) then
      r = 0.0_wp
      return
    end if
    r = eval_core(p, mu0, mu1, sin_of(mu0), sin_of(mu1), u_in(1)*u_out(1) + u_in(2)*u_out(2))
  end function brdf_eval_dir

  !> The models, with mu0 = mu_in, mu1 = mu_out in (0, 1], s = sin(theta) and
  !> sscd = s0 s1 cos_dphi (the dot product of the horizontal parts of u_in and u_out).
  !> Every expression is symmetric in (mu0, s0) <-> (mu1, s1).
  pure function eval_core(p, mu0, mu1, s0, s1, sscd) result(r)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu0, mu1, s0, s1, sscd
    real(wp) :: r
    select case (p%kind)
    case (BRDF_LAMBERT)
      r = p%c(1)/PI
    case (BRDF_DSM)
      r = p%c(2)*p%c(1)/PI
      if (p%c(2) < 1.0_wp) r = r + (1.0_wp - p%c(2))*dsm_specular(p, mu0, mu1, s0, s1, sscd)
    case (BRDF_RPV)
      r = rpv_core(p, mu0, mu1, s0, s1, sscd)
    case (BRDF_LSRT)
      r = lsrt_core(p, mu0, mu1, mu0*mu1 - sscd)
    case default
      r = 0.0_wp
    end select
  end function eval_core

  !> Rough-surface specular BRDF (Cox and Munk 1954; Nakajima and Tanaka 1983, JQSRT 29,
  !> 521-537; seed text eq. 3.6.40): R_s = R_F(v) f_s P(zx, zy)/(4 mu0 mu1 mu_n^4), with the
  !> facet normal n along h = Omega0 + Omega1 (Omega0 = -u_in, Omega1 = u_out), cos v = |h|/2,
  !> mu_n = h_z/|h|, the isotropic Gaussian slope density P = exp(-tan^2(th_n)/sigma^2)/
  !> (pi sigma^2) and f_s = 1/(1 + Lambda(mu0) + Lambda(mu1)). |h|^2 is summed from
  !> non-negative terms so it stays accurate (and > 0) at grazing angles.
  pure function dsm_specular(p, mu0, mu1, s0, s1, sscd) result(r)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu0, mu1, s0, s1, sscd
    real(wp) :: r
    real(wp) :: sigma2, ds, hh2, hz, h2, e, cosv, fs
    sigma2 = p%c(5)
    ds = (mu1 - mu0)*(mu1 + mu0)/(s0 + s1 + tiny(1.0_wp))   ! s0 - s1
    hh2 = ds*ds + 2.0_wp*max(0.0_wp, s0*s1 - sscd)          ! |h_horizontal|^2
    hz = mu0 + mu1
    e = exp(-hh2/(hz*hz*sigma2))
    if (e <= 0.0_wp) then
      r = 0.0_wp
      return
    end if
    h2 = hh2 + hz*hz
    cosv = 0.5_wp*sqrt(h2)
    fs = 1.0_wp/(1.0_wp + dsm_shadowing(mu0, sqrt(sigma2)) + dsm_shadowing(mu1, sqrt(sigma2)))
    r = fresnel_reflectance(p%c(3), p%c(4), cosv)*fs*e*(h2/(hz*hz))**2/ &
        (4.0_wp*PI*sigma2*mu0*mu1)
  end function dsm_specular

  !> RPV BRDF (Rahman, Pinty and Verstraete 1993, JGR 98, 20791-20801, with the hot-spot
  !> sharpness h of MCARaTS): R = rho0 F(g) [1 + H] [mu0 mu1 (mu0 + mu1)]^(k-1)/pi, F the
  !> Henyey-Greenstein function of the phase angle, (1 - Theta^2)/(1 + Theta^2 + 2 Theta cos g)^1.5
  !> (Theta < 0: backward scattering), H = (1 - rho0) mu0 mu1/(h mu0 mu1 + mu0 mu1 G) with the
  !> hot-spot distance mu0 mu1 G = sqrt(mu0^2 + mu1^2 - 2 mu0 mu1 cos g), evaluated as a sum of
  !> non-negative terms (s0 mu1 - s1 mu0)^2 + 2 mu0 mu1 (s0 s1 + sscd).
  pure function rpv_core(p, mu0, mu1, s0, s1, sscd) result(r)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu0, mu1, s0, s1, sscd
    real(wp) :: r
    real(wp) :: rho0, k, th, cg, f, d, gd, hh, m01
    rho0 = p%c(1)
    k = p%c(2)
    th = p%c(3)
    m01 = mu0*mu1
    cg = m01 - sscd
    f = 1.0_wp + th*th + 2.0_wp*th*cg
    f = (1.0_wp - th*th)/(f*sqrt(f))
    d = s0*mu1 - s1*mu0
    gd = sqrt(d*d + 2.0_wp*m01*max(0.0_wp, s0*s1 + sscd))
    hh = (1.0_wp - rho0)*m01/(p%c(4)*m01 + gd)
    r = rho0*f*(1.0_wp + hh)/PI
    if (k /= 1.0_wp) r = r*exp((k - 1.0_wp)*log(m01*(mu0 + mu1)))   ! cheaper than **
  end function rpv_core

  !> LSRT BRDF (Lucht et al. 2000): max(0, k_iso + k_geo f_g + k_vol f_v)/pi, negative kernel
  !> sums set to 0 as in MCARaTS.
  pure function lsrt_core(p, mu0, mu1, cg) result(r)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu0, mu1, cg
    real(wp) :: r
    r = p%c(1)
    if (p%c(2) /= 0.0_wp) r = r + p%c(2)*li_sparse_core(mu0, mu1, cg)
    if (p%c(3) /= 0.0_wp) r = r + p%c(3)*ross_thick_core(mu0, mu1, cg)
    r = max(0.0_wp, r)/PI
  end function lsrt_core

  ! ------------------------------------------------------------------------------------------
  ! Directional albedo by fixed quadratures (setup time)
  ! ------------------------------------------------------------------------------------------

  !> Directional albedo alpha(mu_in) = Int R mu_out dOmega_out of the (unscaled) model, by the
  !> fixed quadratures of the module (setup time, not for the photon loop). Lambert: the
  !> albedo; black: 0.
  !>
  !> RPV, LSRT: panels of 12 Gauss-Legendre nodes in mu_out times panels of 16 in dphi on
  !> [0, pi] (about 800 BRDF evaluations for RPV, 1,500-5,000 for LSRT). The panels end where
  !> the integrand has a kink: the hot spot; for LSRT also the curve where the Li-Sparse
  !> overlap cos t reaches 1 (closed form per row, bisection on the principal plane) and the
  !> zero curve of the clipped kernel sum (scan and bisection). Each panel maps its Gauss nodes
  !> by x = u^2 (3 - 2u), which flattens the (x - x_k)^(3/2) behaviour at those curves.
  !> DSM: the specular part is integrated over facet slopes, where R_s mu_out dOmega_out =
  !> R_F f_s (cos v/mu_n)/mu_in P dzx dzy; in polar slope coordinates (tan th_n = sigma s,
  !> azimuth psi about Omega0) P dzx dzy = 2 s e^(-s^2) ds dpsi/(2 pi), and the reflected ray
  !> is above the horizon for s < s_c(psi) (closed form); 24 midpoints in psi on [0, pi]
  !> (periodic, smooth integrand: geometric convergence) times 24 Gauss nodes in s on
  !> [0, min(s_c, 6.5)]: 576 evaluations, and the glint is resolved for any sigma^2.
  !>
  !> Accuracy against converged midpoint rules in (mu_out, dphi) (unit tests and a wider
  !> survey): DSM 1e-6 relative or better; RPV 5e-8 with the graded panels at the hot spot
  !> (HOT_MU_MAX; before them 8e-6 for h = 0.3 and 5e-4 for h = 0.05, Theta = -0.9), measured
  !> against the same rule with 64 x 96 nodes per panel; LSRT 1e-9 with or without clipping
  !> (5e-7 at a few mu_in); LSRT kernel integrals within 1e-5 of the published black-sky values,
  !> 1e-15 at mu_in = 1.
  elemental function brdf_albedo_quad(p, mu_in) result(alpha)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu_in  !! cosine of the incident zenith angle, in (0, 1]
    real(wp) :: alpha
    real(wp) :: prof_mu(N_PROF), prof_y(N_PROF), mu0, rmax, a_s
    mu0 = min(1.0_wp, max(mu_in, MU_NODE0))
    select case (p%kind)
    case (BRDF_LAMBERT)
      alpha = p%c(1)
    case (BRDF_DSM)
      alpha = p%c(2)*p%c(1)
      if (p%c(2) < 1.0_wp) then
        call dsm_scan(p, mu0, .false., a_s, rmax)
        alpha = alpha + (1.0_wp - p%c(2))*a_s
      end if
    case (BRDF_RPV, BRDF_LSRT)
      call hemi_scan(p, mu0, .false., .true., alpha, prof_mu, prof_y)
    case default
      alpha = 0.0_wp
    end select
  end function brdf_albedo_quad

  !> Black-sky (directional) integrals of the LSRT kernels, A(mu_in) = (1/pi) Int f mu_out
  !> dOmega_out, of Ross-Thick (a_vol) and Li-Sparse-R (a_geo), unclipped, by the quadrature
  !> of `brdf_albedo_quad` (Lucht et al. 2000, eq. 47; the isotropic kernel gives 1).
  elemental subroutine lsrt_kernel_albedos(mu_in, a_vol, a_geo)
    real(wp), intent(in) :: mu_in   !! cosine of the incident zenith angle, in (0, 1]
    real(wp), intent(out) :: a_vol  !! black-sky integral of the Ross-Thick kernel
    real(wp), intent(out) :: a_geo  !! black-sky integral of the Li-Sparse-R kernel
    real(wp) :: xa(N_A), wa(N_A), xp(N_P), wp1(N_P)
    real(wp) :: mu1(MAX_ROWS), w1(MAX_ROWS), cphi(MAX_PHI), wphi(MAX_PHI)
    real(wp) :: mu0, s0, s1, cg, sv, sg
    integer :: i, j, n_rows, n_phi
    type(brdf_params_t) :: p
    call panel_nodes(N_A, xa, wa)
    call panel_nodes(N_P, xp, wp1)
    mu0 = min(1.0_wp, max(mu_in, MU_NODE0))
    s0 = sin_of(mu0)
    p = brdf_params(BRDF_LSRT, [1.0_wp, 1.0_wp, 1.0_wp])
    call hemi_rows(p, .false., mu0, xa, wa, n_rows, mu1, w1)
    a_vol = 0.0_wp
    a_geo = 0.0_wp
    do i = 1, n_rows
      s1 = sin_of(mu1(i))
      call phi_nodes(p, .false., mu0, mu1(i), s0, s1, xp, wp1, n_phi, cphi, wphi)
      sv = 0.0_wp
      sg = 0.0_wp
      do j = 1, n_phi
        cg = mu0*mu1(i) - s0*s1*cphi(j)
        sv = sv + wphi(j)*ross_thick_core(mu0, mu1(i), cg)
        sg = sg + wphi(j)*li_sparse_core(mu0, mu1(i), cg)
      end do
      a_vol = a_vol + w1(i)*mu1(i)*sv
      a_geo = a_geo + w1(i)*mu1(i)*sg
    end do
    ! (1/pi) Int_0^1 dmu Int_0^2pi dphi = (2/pi) Int_0^1 dmu Int_0^pi dphi
    a_vol = 2.0_wp*a_vol/PI
    a_geo = 2.0_wp*a_geo/PI
  end subroutine lsrt_kernel_albedos

  !> Rows of the hemispheric quadrature in mu_out: panels of N_A nodes between the points where
  !> the integrand is not smooth: the hot spot mu_out = mu0 and, for LSRT, the mu_out where the
  !> curve cos t = 1 of the Li-Sparse kernel (sin xi = (mu0 + mu_out)/2) and, with `clip`, the
  !> zero curve of the kernel sum meet the principal plane (scan and bisection).
  pure subroutine hemi_rows(p, clip, mu0, xa, wa, n, mu1, w1)
    type(brdf_params_t), intent(in) :: p
    logical, intent(in) :: clip
    real(wp), intent(in) :: mu0, xa(N_A), wa(N_A)
    integer, intent(out) :: n
    real(wp), intent(out) :: mu1(MAX_ROWS), w1(MAX_ROWS)
    real(wp) :: br(MAX_PANELS + 1), d
    integer :: nb, k, i, sgn
    nb = 1
    br(1) = 0.0_wp
    if (p%kind == BRDF_LSRT) then
      do sgn = -1, 1, 2
        call add_plane_roots(p, 1, mu0, sgn, br, nb)
        if (clip) call add_plane_roots(p, 2, mu0, sgn, br, nb)
      end do
    end if
    nb = nb + 1
    br(nb) = mu0
    nb = nb + 1
    br(nb) = 1.0_wp
    if (p%kind == BRDF_RPV) then
      do k = 1, rpv_levels(HOT_RES*rpv_width(p), HOT_MU_MAX)
        nb = nb + 1
        br(nb) = mu0*(1.0_wp - HOT_RATIO**k)
        nb = nb + 1
        br(nb) = mu0 + (1.0_wp - mu0)*HOT_RATIO**k
      end do
    end if
    call sort_unique(br, nb)
    n = 0
    do k = 1, nb - 1
      d = br(k + 1) - br(k)
      do i = 1, N_A
        n = n + 1
        mu1(n) = br(k) + d*xa(i)
        w1(n) = d*wa(i)
      end do
    end do
  end subroutine hemi_rows

  !> Append the roots in (0, 1) of plane_fun(p, code, mu0, ., sgn) to br(1:nb) (64-point scan,
  !> bisection), as long as there is room for the two further breaks of `hemi_rows`.
  pure subroutine add_plane_roots(p, code, mu0, sgn, br, nb)
    type(brdf_params_t), intent(in) :: p
    integer, intent(in) :: code, sgn
    real(wp), intent(in) :: mu0
    real(wp), intent(inout) :: br(:)
    integer, intent(inout) :: nb
    integer, parameter :: N_SCAN = 64
    real(wp) :: x0, x1, f0, f1, xm, fm, xl, fl, xr
    integer :: k, it
    x0 = 0.0_wp
    f0 = plane_fun(p, code, mu0, 1.0e-9_wp, sgn)
    do k = 1, N_SCAN
      x1 = real(k, wp)/N_SCAN
      f1 = plane_fun(p, code, mu0, x1, sgn)
      if ((f0 > 0.0_wp .neqv. f1 > 0.0_wp) .and. nb < size(br) - 2) then
        xl = x0
        fl = f0
        xr = x1
        xm = x0
        do it = 1, 60
          xm = 0.5_wp*(xl + xr)
          fm = plane_fun(p, code, mu0, xm, sgn)
          if (fm > 0.0_wp .eqv. fl > 0.0_wp) then
            xl = xm
            fl = fm
          else
            xr = xm
          end if
        end do
        nb = nb + 1
        br(nb) = xm
      end if
      x0 = x1
      f0 = f1
    end do
  end subroutine add_plane_roots

  !> On the principal plane (sgn = +1: forward, cos dphi = 1; -1: hot-spot side), for LSRT:
  !> code 1, sin xi - (mu0 + mu)/2 (zero where the Li-Sparse clamp starts); code 2, the
  !> unclipped kernel sum.
  pure function plane_fun(p, code, mu0, mu, sgn) result(f)
    type(brdf_params_t), intent(in) :: p
    integer, intent(in) :: code, sgn
    real(wp), intent(in) :: mu0, mu
    real(wp) :: f
    real(wp) :: s0, s1
    s0 = sin_of(mu0)
    s1 = sin_of(mu)
    if (code == 1) then
      f = abs(s0*mu + sgn*mu0*s1) - 0.5_wp*(mu0 + mu)
    else
      f = lsrt_sum(p, mu0, mu, mu0*mu - sgn*s0*s1)
    end if
  end function plane_fun

  !> Fraction of the pairs of incident and reflected directions, weighted by mu_in mu_out
  !> dOmega_in dOmega_out, where the LSRT kernel sum is negative (midpoint rule, 24 x 24 x 24
  !> cells in mu_in, mu_out and dphi on [0, pi]).
  pure function lsrt_negative_fraction(p) result(frac)
    type(brdf_params_t), intent(in) :: p
    real(wp) :: frac
    integer, parameter :: N = 24
    real(wp) :: mu0, mu1, s0, s1, w, wsum, wneg
    integer :: i, j, k
    wsum = 0.0_wp
    wneg = 0.0_wp
    do i = 1, N
      mu0 = (i - 0.5_wp)/N
      s0 = sin_of(mu0)
      do j = 1, N
        mu1 = (j - 0.5_wp)/N
        s1 = sin_of(mu1)
        w = mu0*mu1
        do k = 1, N
          wsum = wsum + w
          if (lsrt_sum(p, mu0, mu1, mu0*mu1 - s0*s1*cos((k - 0.5_wp)*PI/N)) < 0.0_wp) &
            wneg = wneg + w
        end do
      end do
    end do
    frac = wneg/wsum
  end function lsrt_negative_fraction

  !> Unclipped LSRT kernel sum k_iso + k_geo f_g + k_vol f_v for cos(phase angle) cg.
  pure function lsrt_sum(p, mu0, mu1, cg) result(f)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu0, mu1, cg
    real(wp) :: f
    f = p%c(1)
    if (p%c(2) /= 0.0_wp) f = f + p%c(2)*li_sparse_core(mu0, mu1, cg)
    if (p%c(3) /= 0.0_wp) f = f + p%c(3)*ross_thick_core(mu0, mu1, cg)
  end function lsrt_sum

  !> Nodes (cos dphi) and weights (summing to pi) in dphi on [0, pi] for one row: panels of
  !> N_P nodes, split for LSRT where the row crosses the Li-Sparse curve cos t = 1, i.e.
  !> cos xi = +-sqrt(1 - (mu0 + mu1)^2/4), and, with `clip`, where the kernel sum changes sign
  !> (32-point scan, bisection).
  pure subroutine phi_nodes(p, clip, mu0, mu1, s0, s1, xp, wp1, n, cphi, wphi)
    type(brdf_params_t), intent(in) :: p
    logical, intent(in) :: clip
    real(wp), intent(in) :: mu0, mu1, s0, s1, xp(N_P), wp1(N_P)
    integer, intent(out) :: n
    real(wp), intent(out) :: cphi(MAX_PHI), wphi(MAX_PHI)
    integer, parameter :: N_SCAN = 32
    real(wp) :: br(MAX_PHI_PANELS + 1), c, x, d, x0, x1, f0, f1, xm, fm
    integer :: nb, k, i, sgn, it
    nb = 1
    br(1) = 0.0_wp
    if (p%kind == BRDF_LSRT .and. s0*s1 > 0.0_wp) then
      c = sqrt(max(0.0_wp, 1.0_wp - 0.25_wp*(mu0 + mu1)**2))
      do sgn = -1, 1, 2
        x = (mu0*mu1 + sgn*c)/(s0*s1)
        if (abs(x) < 1.0_wp) then
          nb = nb + 1
          br(nb) = acos(x)
        end if
      end do
      if (clip) then
        x0 = 0.0_wp
        f0 = lsrt_sum(p, mu0, mu1, mu0*mu1 - s0*s1)
        do k = 1, N_SCAN
          x1 = k*PI/N_SCAN
          f1 = lsrt_sum(p, mu0, mu1, mu0*mu1 - s0*s1*cos(x1))
          if ((f0 > 0.0_wp .neqv. f1 > 0.0_wp) .and. nb < MAX_PHI_PANELS) then
            xm = x0
            d = x1
            do it = 1, 60
              xm = 0.5_wp*(x0 + d)
              fm = lsrt_sum(p, mu0, mu1, mu0*mu1 - s0*s1*cos(xm))
              if (fm > 0.0_wp .eqv. f0 > 0.0_wp) then
                x0 = xm
              else
                d = xm
              end if
            end do
            nb = nb + 1
            br(nb) = xm
          end if
          x0 = x1
          f0 = f1
        end do
      end if
    end if
    if (p%kind == BRDF_RPV .and. s0*s1 > 0.0_wp) then
      ! scale of the hot-spot peak across this row, in dphi
      x = sqrt((s0*mu1 - s1*mu0)**2 + rpv_width(p)**2)/sqrt(s0*s1)
      d = PI
      do k = 1, rpv_levels(HOT_RES*x/PI, MAX_PHI_PANELS - 1)
        d = d*HOT_RATIO
        nb = nb + 1
        br(nb) = PI - d
      end do
    end if
    nb = nb + 1
    br(nb) = PI
    call sort_unique(br, nb)
    n = 0
    do k = 1, nb - 1
      d = br(k + 1) - br(k)
      do i = 1, N_P
        n = n + 1
        cphi(n) = cos(br(k) + d*xp(i))
        wphi(n) = d*wp1(i)
      end do
    end do
  end subroutine phi_nodes

  !> Width of the RPV hot-spot peak in the phase angle: the hot-spot term (1 - rho0)/(h + G)
  !> has the width h in the tangent distance G, the Henyey-Greenstein factor of Theta < 0 the
  !> width 1 - |Theta| in g; 1 for a broad peak.
  pure function rpv_width(p) result(w)
    type(brdf_params_t), intent(in) :: p
    real(wp) :: w
    w = min(1.0_wp, p%c(4))
    if (p%c(3) < 0.0_wp) w = min(w, 1.0_wp + p%c(3))
    w = max(w, 1.0e-3_wp)
  end function rpv_width

  !> Levels n of the geometric grading (panel lengths HOT_RATIO^k, k = 1 ... n, of the
  !> interval) towards the RPV hot spot: the smallest n with HOT_RATIO^n <= frac, at most n_max.
  pure function rpv_levels(frac, n_max) result(n)
    real(wp), intent(in) :: frac
    integer, intent(in) :: n_max
    integer :: n
    n = 0
    do while (HOT_RATIO**n > frac .and. n < n_max)
      n = n + 1
    end do
  end function rpv_levels

  !> Sort x(1:n) ascending and drop entries within 1e-12 of their predecessor.
  pure subroutine sort_unique(x, n)
    real(wp), intent(inout) :: x(:)
    integer, intent(inout) :: n
    integer :: i, j, m
    real(wp) :: v
    do i = 2, n
      v = x(i)
      j = i - 1
      do while (j >= 1)
        if (x(j) <= v) exit
        x(j + 1) = x(j)
        j = j - 1
      end do
      x(j + 1) = v
    end do
    m = 1
    do i = 2, n
      if (x(i) - x(m) > 1.0e-12_wp) then
        m = m + 1
        x(m) = x(i)
      end if
    end do
    n = m
  end subroutine sort_unique

  !> Hemispheric quadrature of R mu_out for RPV and LSRT at mu0, and (with `profile`) the
  !> largest mu_out R over dphi on each row of mu_out: the quadrature rows, mu_out -> 0, the
  !> hot-spot row mu_out = mu0 and mu_out = 1, each over the quadrature nodes and dphi = 0, pi.
  pure subroutine hemi_scan(p, mu0, profile, accurate, alpha, prof_mu, prof_y)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu0
    logical, intent(in) :: profile
    logical, intent(in) :: accurate    !! split LSRT rows at the clipping curve (albedo only)
    real(wp), intent(out) :: alpha
    real(wp), intent(out) :: prof_mu(N_PROF), prof_y(N_PROF)
    real(wp) :: xa(N_A), wa(N_A), xp(N_P), wp1(N_P)
    real(wp) :: mu1(MAX_ROWS), w1(MAX_ROWS), cphi(MAX_PHI), wphi(MAX_PHI)
    real(wp) :: s0, s1, sr, rmax, r, m
    integer :: i, j, n_rows, n_phi, n
    logical :: clip
    call panel_nodes(N_A, xa, wa)
    call panel_nodes(N_P, xp, wp1)
    s0 = sin_of(mu0)
    clip = accurate .and. p%kind == BRDF_LSRT .and. (p%c(2) > 0.0_wp .or. &
                                                     p%c(1) < 0.25_wp*PI*p%c(3))
    call hemi_rows(p, clip, mu0, xa, wa, n_rows, mu1, w1)
    alpha = 0.0_wp
    prof_mu = 0.0_wp
    prof_y = 0.0_wp
    n = 0
    do i = 1, n_rows + 3
      if (i <= n_rows) then
        m = mu1(i)
      else if (.not. profile) then
        exit
      else                         ! extra profile rows: grazing, hot spot, zenith
        m = merge(1.0e-9_wp, merge(mu0, 1.0_wp, i == n_rows + 2), i == n_rows + 1)
      end if
      s1 = sin_of(m)
      call phi_nodes(p, clip, mu0, m, s0, s1, xp, wp1, n_phi, cphi, wphi)
      sr = 0.0_wp
      rmax = 0.0_wp
      do j = 1, n_phi
        r = eval_core(p, mu0, m, s0, s1, s0*s1*cphi(j))
        sr = sr + wphi(j)*r
        rmax = max(rmax, r)
      end do
      if (i <= n_rows) alpha = alpha + w1(i)*m*sr
      if (profile) then
        rmax = max(rmax, eval_core(p, mu0, m, s0, s1, s0*s1), eval_core(p, mu0, m, s0, s1, -s0*s1))
        n = n + 1
        prof_mu(n) = m
        prof_y(n) = m*rmax
      end if
    end do
    alpha = 2.0_wp*alpha   ! Int_0^2pi dphi = 2 Int_0^pi dphi
  end subroutine hemi_scan

  !> DSM specular albedo at mu0 by the slope-space quadrature (see `brdf_albedo_quad`); with
  !> `scan`, also rmax, the largest R_F f_s cos(v)/mu_n over slopes with tan^2 th_n <=
  !> T_TAIL sigma^2 whose reflection goes upward (the bound of the facet sampler).
  pure subroutine dsm_scan(p, mu0, scan, alpha_s, rmax)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu0
    logical, intent(in) :: scan
    real(wp), intent(out) :: alpha_s, rmax
    real(wp) :: xw(N_W), ww(N_W), sigma, s0, lam0, psi, cp, sp, q, rc, sc, inner, s, r
    integer :: i, j
    sigma = sqrt(p%c(5))
    s0 = sin_of(mu0)
    lam0 = dsm_shadowing(mu0, sigma)
    call gauss_legendre01(N_W, xw, ww)
    alpha_s = 0.0_wp
    do i = 1, N_PSI
      psi = (i - 0.5_wp)*PI/N_PSI
      cp = cos(psi)
      sp = sin(psi)
      ! upward reflection for slope radius r < r_c: mu0 r^2 + 2 s0 cos(psi) r - mu0 < 0
      q = sqrt((s0*cp)**2 + mu0*mu0)
      if (cp >= 0.0_wp) then
        rc = mu0/(s0*cp + q)
      else
        rc = (q - s0*cp)/mu0
      end if
      sc = min(rc/sigma, S_MAX)
      inner = 0.0_wp
      do j = 1, N_W
        s = sc*xw(j)
        r = sigma*s
        inner = inner + ww(j)*2.0_wp*s*exp(-s*s)*facet_ratio(p, mu0, s0, lam0, sigma, r*cp, r*sp)
      end do
      alpha_s = alpha_s + sc*inner
    end do
    alpha_s = alpha_s/(N_PSI*mu0)
    rmax = 0.0_wp
    if (.not. scan) return
    do i = 0, N_SPSI
      psi = i*PI/N_SPSI
      cp = cos(psi)
      sp = sin(psi)
      do j = 0, N_SR
        r = sigma*sqrt(T_TAIL)*j/N_SR
        rmax = max(rmax, facet_ratio(p, mu0, s0, lam0, sigma, r*cp, r*sp))
      end do
    end do
  end subroutine dsm_scan

  !> R_F(v) f_s cos(v)/mu_n for the facet of slopes (zx, zy), with Omega0 = (s0, 0, mu0);
  !> 0 if the facet faces away or the reflected ray goes downward.
  pure function facet_ratio(p, mu0, s0, lam0, sigma, zx, zy) result(f)
    type(brdf_params_t), intent(in) :: p
    real(wp), intent(in) :: mu0, s0, lam0, sigma, zx, zy
    real(wp) :: f
    real(wp) :: c, nn, mu1
    f = 0.0_wp
    c = mu0 - s0*zx                       ! cos(v)/mu_n = Omega0 . (-zx, -zy, 1)
    if (c <= 0.0_wp) return
    nn = 1.0_wp + zx*zx + zy*zy
    mu1 = 2.0_wp*c/nn - mu0
    if (mu1 <= 0.0_wp) return
    f = fresnel_reflectance(p%c(3), p%c(4), c/sqrt(nn))*c/ &
        (1.0_wp + lam0 + dsm_shadowing(mu1, sigma))
  end function facet_ratio

  ! ------------------------------------------------------------------------------------------
  ! Tables for the photon loop
  ! ------------------------------------------------------------------------------------------

  !> Validate `p` and build its table: the model albedo at the BRDF_NMU nodes (uniform in
  !> sqrt(mu_in)) and, per envelope bin (the node intervals, the first one split geometrically
  !> towards grazing incidence), the sampling envelope. Each bound is the largest target /
  !> proposal ratio found at the bin's two edges and three inner points on the scan grids (the
  !> quadrature rows plus the grazing, hot-spot and zenith rows and the principal plane for
  !> RPV/LSRT; a 33 x 25 polar slope grid out to tan^2 th_n = 28 sigma^2 for DSM), times 1.15.
  !> For RPV and LSRT the ratio is normalised by the interpolated albedo, as in the sampler,
  !> and the slope a1 of the proposal a1 mu + a0 is chosen per bin to minimise the bound (the
  !> expected number of tries). Nodes where the model albedo exceeds 1 are counted in
  !> `n_clamped`. (Cost of the whole table: see below.)
  !>
  !> The albedo is interpolated (cubic in sqrt(mu_in)) on BRDF_NALB = 121 uniform nodes plus
  !> adaptive ones: each interval with mu_in >= 0.01 is checked at its midpoint against the
  !> quadrature and halved while the error exceeds ALB_TOL = 2e-7 (the onsets of LSRT clipping
  !> are kinks in the albedo: 17-36 nodes added there; RPV and DSM need none or one). Measured
  !> at the midpoints between the final nodes: below 2e-7 relative for every kind (the unit
  !> tests), against 8e-5 (clipped LSRT) and 5e-6 (sharp RPV hot spot) on the uniform nodes
  !> alone. `interp_err` reports the largest error found by these checks and at the envelope
  !> bin midpoints (including the grazing bins). With `mu0`, the albedo at mu_in = mu0 (the
  !> direct beam) is the quadrature value itself. Whole table, measured on a loaded 2-core
  !> machine: 12-18 ms (DSM), 24-54 ms (RPV, the sharpest hot spots dearest), 80-100 ms (LSRT
  !> with clipping); about half of it is the midpoint checks.
  subroutine brdf_table_init(tab, p, error, mu0)
    type(brdf_table_t), intent(out) :: tab
    type(brdf_params_t), intent(in) :: p
    type(error_t), allocatable, intent(out) :: error
    !> cosine of the solar zenith angle (-uz of the direct beam): its albedo is stored exactly
    real(wp), intent(in), optional :: mu0
    real(wp) :: edge(N_ENV + 1), al_e(N_ENV + 1), rm_e(N_ENV + 1)
    real(wp) :: pm_e(N_PROF, N_ENV + 1), py_e(N_PROF, N_ENV + 1)
    real(wp) :: mu_s(5), al_s(5), rm_s(5), pm_s(N_PROF, 5), py_s(N_PROF, 5)
    real(wp) :: a_node, a_mid, a_ref, rm, pm(N_PROF), py(N_PROF)
    integer :: j, m, e

    call brdf_validate(p, error)
    if (allocated(error)) return
    tab%p = p
    if (p%kind == BRDF_BLACK .or. p%kind == BRDF_LAMBERT) then
      tab%t = merge(p%c(1), 0.0_wp, p%kind == BRDF_LAMBERT)
      return
    end if
    call set_sun(tab, mu0)
    select case (p%kind)
    case (BRDF_RPV)
      tab%t_pow = 1.0_wp - p%c(2)
    case (BRDF_LSRT)
      tab%t_pow = 1.0_wp
    case default
      tab%t_pow = 0.0_wp
    end select

    ! Bin edges (the table nodes are edges 1 and N_GRAZ + 2 ... N_ENV + 1) with their albedo
    ! and envelope data; the albedo table.
    do e = 1, N_ENV + 1
      edge(e) = env_edge(e)
      call scan_at(edge(e), e > N_GRAZ, al_e(e), rm_e(e), pm_e(:, e), py_e(:, e))
    end do
    do j = 1, BRDF_NMU
      e = merge(1, j + N_GRAZ, j == 1)     ! node j is edge e
      tab%t(j) = al_e(e)*edge(e)**tab%t_pow
    end do
    ! The dense albedo table (every fourth dense mu_in node r^2, r = (j-1)/(BRDF_NALB-1), is
    ! a node of t: the same values are reused).
    do j = 1, BRDF_NALB
      if (mod(j - 1, (BRDF_NALB - 1)/(BRDF_NMU - 1)) == 0) then
        tab%ta(j) = tab%t((j - 1)/((BRDF_NALB - 1)/(BRDF_NMU - 1)) + 1)
      else
        a_node = (real(j - 1, wp)/(BRDF_NALB - 1))**2
        call scan_at(a_node, .true., a_ref, rm, pm, py)
        tab%ta(j) = a_ref*a_node**tab%t_pow
      end if
      tab%xa(j) = real(j - 1, wp)/(BRDF_NALB - 1)
    end do
    tab%n_alb = BRDF_NALB
    call refine_albedo()

    ! Envelope per bin from its two edges and three inner samples.
    do e = 1, N_ENV
      al_s(1:2) = al_e(e:e + 1)
      rm_s(1:2) = rm_e(e:e + 1)
      pm_s(:, 1:2) = pm_e(:, e:e + 1)
      py_s(:, 1:2) = py_e(:, e:e + 1)
      call bin_samples(e, mu_s)
      do m = 1, 3
        call scan_at(mu_s(m + 2), e > N_GRAZ + 1 .and. m == 2, al_s(m + 2), rm_s(m + 2), &
                     pm_s(:, m + 2), py_s(:, m + 2))
        if (e > N_GRAZ + 1 .and. m == 2) call note_interp(mu_s(4), al_s(4))
      end do
      if (p%kind == BRDF_DSM) then
        tab%env(e) = ENV_MARGIN*maxval(rm_s)
      else
        ! normalised like the sampler's ratio: by the albedo interpolated from the table
        do m = 1, 5
          al_s(m) = model_albedo(tab, mu_s(m))
        end do
        call best_linear_envelope(pm_s, py_s, al_s, tab%a1(e), tab%env(e))
        tab%env(e) = ENV_MARGIN*tab%env(e)
      end if
    end do
    ! interpolation error in the middle of the first table interval
    call scan_at((0.5_wp/(BRDF_NMU - 1))**2, .true., a_ref, rm, pm, py)
    call note_interp((0.5_wp/(BRDF_NMU - 1))**2, a_ref)

    ! Clamp count: nodes whose model albedo exceeds 1.
    tab%n_clamped = 0
    tab%mu_clamped = 0.0_wp
    do j = 1, BRDF_NMU
      e = merge(1, j + N_GRAZ, j == 1)
      a_node = model_albedo(tab, edge(e))
      if (a_node > 1.0_wp) then
        tab%n_clamped = tab%n_clamped + 1
        tab%mu_clamped = max(tab%mu_clamped, edge(e))
      end if
    end do
  contains
    !> Check each interval of the dense table with mu_in >= ALB_CHECK_MU at its midpoint against
    !> the quadrature and halve it (the midpoint becomes a node) while the relative error of the
    !> tabulated quantity exceeds ALB_TOL and there is room; the largest error left is kept in
    !> interp_err. Intervals are checked left to right, halves before the next interval.
    subroutine refine_albedo()
      integer, parameter :: MAX_STACK = 64
      real(wp) :: st_lo(MAX_STACK), st_hi(MAX_STACK), xl, xr, xm, tq, ti, err
      integer :: n_st, i, pass
      logical :: changed
      do i = 1, BRDF_NALB - 1
        xl = real(i - 1, wp)/(BRDF_NALB - 1)
        if (xl*xl < ALB_CHECK_MU) cycle
        n_st = 1
        st_lo(1) = xl
        st_hi(1) = real(i, wp)/(BRDF_NALB - 1)
        do while (n_st > 0)
          xl = st_lo(n_st)
          xr = st_hi(n_st)
          n_st = n_st - 1
          xm = 0.5_wp*(xl + xr)
          call scan_at(xm*xm, .true., a_ref, rm, pm, py)
          tq = a_ref*(xm*xm)**tab%t_pow
          ti = dense_t(tab, xm*xm)
          err = abs(ti - tq)/max(abs(tq), tiny(1.0_wp))
          if (err > ALB_TOL .and. tab%n_alb < BRDF_NALB_MAX .and. n_st <= MAX_STACK - 2) then
            call insert_node(xm, tq)
            st_lo(n_st + 1:n_st + 2) = [xm, xl]     ! the left half is checked first
            st_hi(n_st + 1:n_st + 2) = [xr, xm]
            n_st = n_st + 2
          else
            tab%interp_err = max(tab%interp_err, err)
          end if
        end do
      end do
      ! an added node changes the interpolation of the intervals around it: check again those
      ! whose four nodes include an added one, until none is halved
      do pass = 1, 4
        changed = .false.
        i = 1
        do while (i < tab%n_alb - 1)
          xl = tab%xa(i)
          xr = tab%xa(i + 1)
          i = i + 1
          if (xl*xl < ALB_CHECK_MU .or. tab%alb_uniform) cycle
          if (all(is_uniform(tab%xa(max(i - 2, 1):min(i + 1, tab%n_alb))))) cycle
          xm = 0.5_wp*(xl + xr)
          call scan_at(xm*xm, .true., a_ref, rm, pm, py)
          tq = a_ref*(xm*xm)**tab%t_pow
          err = abs(dense_t(tab, xm*xm) - tq)/max(abs(tq), tiny(1.0_wp))
          if (err > ALB_TOL .and. tab%n_alb < BRDF_NALB_MAX) then
            call insert_node(xm, tq)
            changed = .true.
            i = i - 1               ! check the left half next
          else
            tab%interp_err = max(tab%interp_err, err)
          end if
        end do
        if (.not. changed) exit
      end do
    end subroutine refine_albedo
    !> True for the nodes of the uniform part of the dense table.
    elemental logical function is_uniform(x)
      real(wp), intent(in) :: x
      is_uniform = abs(x*(BRDF_NALB - 1) - nint(x*(BRDF_NALB - 1))) < 1.0e-9_wp
    end function is_uniform
    !> Insert the node x (value v) into the dense table, keeping xa ascending.
    subroutine insert_node(x, v)
      real(wp), intent(in) :: x, v
      integer :: i
      i = tab%n_alb
      do while (tab%xa(i) > x)
        tab%xa(i + 1) = tab%xa(i)
        tab%ta(i + 1) = tab%ta(i)
        i = i - 1
      end do
      tab%xa(i + 1) = x
      tab%ta(i + 1) = v
      tab%n_alb = tab%n_alb + 1
      tab%alb_uniform = .false.
    end subroutine insert_node
    !> Albedo (DSM: specular part) and envelope data at mu.
    subroutine scan_at(mu, accurate, al, rmx, pmu, py_)
      real(wp), intent(in) :: mu
      logical, intent(in) :: accurate
      real(wp), intent(out) :: al, rmx, pmu(N_PROF), py_(N_PROF)
      rmx = 0.0_wp
      pmu = 0.0_wp
      py_ = 0.0_wp
      if (p%kind == BRDF_DSM) then
        al = 0.0_wp
        if (p%c(2) < 1.0_wp) call dsm_scan(p, mu, .true., al, rmx)
      else
        call hemi_scan(p, mu, .true., accurate, al, pmu, py_)
      end if
    end subroutine scan_at
    !> Record the relative error of the interpolated albedo at mu (quadrature value al).
    subroutine note_interp(mu, al)
      real(wp), intent(in) :: mu, al
      a_mid = model_albedo(tab, mu)
      a_ref = al
      if (p%kind == BRDF_DSM) a_ref = p%c(2)*p%c(1) + (1.0_wp - p%c(2))*al
      if (a_ref > 0.0_wp) tab%interp_err = max(tab%interp_err, abs(a_mid - a_ref)/a_ref)
    end subroutine note_interp
  end subroutine brdf_table_init

  !> Tabulate the LSRT kernels for `brdf_table_init_grid` (see `lsrt_grid_t`).
  subroutine lsrt_grid_init(grid)
    type(lsrt_grid_t), intent(out) :: grid
    real(wp) :: xa(N_A), wa(N_A), xp(N_P), wp1(N_P), mu_s(5)
    real(wp) :: mu1(MAX_ROWS), w1(MAX_ROWS), cphi(MAX_PHI), wphi(MAX_PHI)
    real(wp) :: mu0, s0, s1, cg, m, g, v
    integer :: j, e, i, k, n, n_rows, n_phi, is
    type(brdf_params_t) :: p
    call panel_nodes(N_A, xa, wa)
    call panel_nodes(N_P, xp, wp1)
    p = brdf_params(BRDF_LSRT, [1.0_wp, 1.0_wp, 1.0_wp])   ! any weights: breaks are shared
    allocate (grid%w(MAX_ROWS*MAX_PHI, BRDF_NMU), grid%kg(MAX_ROWS*MAX_PHI, BRDF_NMU), &
              grid%kv(MAX_ROWS*MAX_PHI, BRDF_NMU))
    grid%w = 0.0_wp
    grid%kg = 0.0_wp
    grid%kv = 0.0_wp
    do j = 1, BRDF_NMU
      e = merge(1, j + N_GRAZ, j == 1)
      mu0 = env_edge(e)
      s0 = sin_of(mu0)
      call hemi_rows(p, .false., mu0, xa, wa, n_rows, mu1, w1)
      n = 0
      do i = 1, n_rows
        s1 = sin_of(mu1(i))
        call phi_nodes(p, .false., mu0, mu1(i), s0, s1, xp, wp1, n_phi, cphi, wphi)
        do k = 1, n_phi
          n = n + 1
          cg = mu0*mu1(i) - s0*s1*cphi(k)
          grid%w(n, j) = 2.0_wp*w1(i)*mu1(i)*wphi(k)
          grid%kg(n, j) = li_sparse_core(mu0, mu1(i), cg)
          grid%kv(n, j) = ross_thick_core(mu0, mu1(i), cg)
        end do
      end do
      grid%n_pts(j) = n
    end do
    allocate (grid%pmu(N_PROF, 5, N_ENV), grid%gmax(N_PROF, 5, N_ENV), &
              grid%gmin(N_PROF, 5, N_ENV), grid%vmax(N_PROF, 5, N_ENV), &
              grid%vmin(N_PROF, 5, N_ENV))
    grid%pmu = 0.0_wp
    grid%gmax = 0.0_wp
    grid%gmin = 0.0_wp
    grid%vmax = 0.0_wp
    grid%vmin = 0.0_wp
    do e = 1, N_ENV
      call bin_samples(e, mu_s)
      do is = 1, 5
        mu0 = mu_s(is)
        s0 = sin_of(mu0)
        call hemi_rows(p, .false., mu0, xa, wa, n_rows, mu1, w1)
        do i = 1, n_rows + 3      ! the quadrature rows, then grazing, hot-spot and zenith rows
          if (i <= n_rows) then
            m = mu1(i)
          else
            m = merge(1.0e-9_wp, merge(mu0, 1.0_wp, i == n_rows + 2), i == n_rows + 1)
          end if
          s1 = sin_of(m)
          call phi_nodes(p, .false., mu0, m, s0, s1, xp, wp1, n_phi, cphi, wphi)
          cphi(n_phi + 1:n_phi + 2) = [1.0_wp, -1.0_wp]      ! the principal plane
          grid%pmu(i, is, e) = m
          grid%gmax(i, is, e) = -huge(1.0_wp)
          grid%gmin(i, is, e) = huge(1.0_wp)
          grid%vmax(i, is, e) = -huge(1.0_wp)
          grid%vmin(i, is, e) = huge(1.0_wp)
          do k = 1, n_phi + 2
            cg = mu0*m - s0*s1*cphi(k)
            g = li_sparse_core(mu0, m, cg)
            v = ross_thick_core(mu0, m, cg)
            grid%gmax(i, is, e) = max(grid%gmax(i, is, e), g)
            grid%gmin(i, is, e) = min(grid%gmin(i, is, e), g)
            grid%vmax(i, is, e) = max(grid%vmax(i, is, e), v)
            grid%vmin(i, is, e) = min(grid%vmin(i, is, e), v)
          end do
        end do
        grid%n_rows(is, e) = n_rows + 3
      end do
    end do
  end subroutine lsrt_grid_init

  !> Table of an LSRT parameter set from the shared kernel values of `grid` (surface maps with
  !> many distinct LSRT pixels). The table has the layout and meaning of `brdf_table_init`'s;
  !> the albedo nodes come from the shared quadrature and the envelopes from the kernels'
  !> row extremes (see `lsrt_grid_t`); `interp_err` is not measured (0).
  subroutine brdf_table_init_grid(tab, p, grid, error, mu0)
    type(brdf_table_t), intent(out) :: tab
    type(brdf_params_t), intent(in) :: p
    type(lsrt_grid_t), intent(in) :: grid
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: mu0  !! solar mu_in, stored exactly (brdf_table_init)
    real(wp) :: py(N_PROF, 5), al_s(5), mu_s(5), a
    integer :: j, e, is, n, nr
    if (p%kind /= BRDF_LSRT) then
      call brdf_table_init(tab, p, error, mu0)
      return
    end if
    call brdf_validate(p, error)
    if (allocated(error)) return
    tab%p = p
    call set_sun(tab, mu0)
    tab%t_pow = 1.0_wp
    do j = 1, BRDF_NMU
      n = grid%n_pts(j)
      a = sum(grid%w(1:n, j)*max(0.0_wp, p%c(1) + p%c(2)*grid%kg(1:n, j) + &
                                 p%c(3)*grid%kv(1:n, j)))/PI
      e = merge(1, j + N_GRAZ, j == 1)
      tab%t(j) = a*env_edge(e)
      if (a > 1.0_wp) then
        tab%n_clamped = tab%n_clamped + 1
        tab%mu_clamped = max(tab%mu_clamped, env_edge(e))
      end if
    end do
    do e = 1, N_ENV
      call bin_samples(e, mu_s)
      py = 0.0_wp
      do is = 1, 5
        nr = grid%n_rows(is, e)
        py(1:nr, is) = grid%pmu(1:nr, is, e)*max(0.0_wp, p%c(1) + &
                       merge(p%c(2)*grid%gmax(1:nr, is, e), p%c(2)*grid%gmin(1:nr, is, e), &
                             p%c(2) >= 0.0_wp) + &
                       merge(p%c(3)*grid%vmax(1:nr, is, e), p%c(3)*grid%vmin(1:nr, is, e), &
                             p%c(3) >= 0.0_wp))/PI
        al_s(is) = model_albedo(tab, mu_s(is))
      end do
      call best_linear_envelope(grid%pmu(:, :, e), py, al_s, tab%a1(e), tab%env(e), N_A1_GRID)
      tab%env(e) = ENV_MARGIN*tab%env(e)
    end do
  end subroutine brdf_table_init_grid

  !> Store the exact (quadrature) model albedo at the solar mu_in, if given and in (0, 1].
  subroutine set_sun(tab, mu0)
    type(brdf_table_t), intent(inout) :: tab
    real(wp), intent(in), optional :: mu0
    if (.not. present(mu0)) return
    if (.not. (mu0 > 0.0_wp .and. mu0 <= 1.0_wp)) return
    tab%mu_sun = mu0
    tab%alpha_sun = brdf_albedo_quad(tab%p, mu0)
  end subroutine set_sun

  !> Lower edge of envelope bin e (e = N_ENV + 1: the upper edge 1): the grazing edges, then
  !> the table nodes (the first at MU_NODE0).
  pure function env_edge(e) result(mu)
    integer, intent(in) :: e
    real(wp) :: mu
    if (e == 1) then
      mu = MU_NODE0
    else if (e <= N_GRAZ + 1) then
      mu = GRAZ_EDGES(e - 1)/real(BRDF_NMU - 1, wp)**2
    else
      mu = (real(e - N_GRAZ - 1, wp)/real(BRDF_NMU - 1, wp))**2
    end if
  end function env_edge

  !> Envelope bin of mu_in.
  pure function env_bin(mu) result(e)
    real(wp), intent(in) :: mu
    integer :: e
    real(wp) :: x
    x = mu*real(BRDF_NMU - 1, wp)**2        ! mu/mu_2
    if (x >= 1.0_wp) then
      e = min(int(sqrt(mu)*(BRDF_NMU - 1)), BRDF_NMU - 2) + 1 + N_GRAZ
    else
      e = 1
      do while (e <= N_GRAZ)
        if (x < GRAZ_EDGES(e)) exit
        e = e + 1
      end do
    end if
  end function env_bin

  !> The five values of mu_in at which the envelope of bin e is formed: its edges, then three
  !> inner points at 1/4, 1/2 and 3/4 of its width in sqrt(mu) (of its log-width in the
  !> grazing bins and the first table interval).
  pure subroutine bin_samples(e, mu_s)
    integer, intent(in) :: e
    real(wp), intent(out) :: mu_s(5)
    real(wp), parameter :: FRAC(3) = [0.25_wp, 0.5_wp, 0.75_wp]
    real(wp) :: lo, hi
    integer :: m
    lo = env_edge(e)
    hi = env_edge(e + 1)
    mu_s(1:2) = [lo, hi]
    do m = 1, 3
      if (e <= N_GRAZ + 1) then
        mu_s(m + 2) = lo*(hi/lo)**FRAC(m)
      else
        mu_s(m + 2) = (sqrt(lo) + (sqrt(hi) - sqrt(lo))*FRAC(m))**2
      end if
    end do
  end subroutine bin_samples

  !> Slope a1 in [A1_MIN, A1_MAX] of the proposal density a1 mu + a0 in (mu_out, phi)
  !> (a0 = 1/(2 pi) - a1/2, normalised on the hemisphere) that minimises the bound
  !> b = max mu R/(alpha (a1 mu + a0)) over three profiles, and that bound.
  pure subroutine best_linear_envelope(prof_mu, prof_y, alpha, a1, b, n_slopes)
    real(wp), intent(in) :: prof_mu(:, :), prof_y(:, :), alpha(:)
    real(wp), intent(out) :: a1, b
    integer, intent(in), optional :: n_slopes  !! slopes tried (default N_A1)
    real(wp) :: x, a0, bx
    integer :: i, m, n
    n = N_A1
    if (present(n_slopes)) n = n_slopes
    a1 = 0.0_wp
    b = huge(1.0_wp)
    do i = 0, n
      x = A1_MIN + (A1_MAX - A1_MIN)*i/n
      a0 = 0.5_wp/PI - 0.5_wp*x
      bx = 0.0_wp
      do m = 1, size(alpha)
        if (alpha(m) > 0.0_wp) then
          bx = max(bx, maxval(prof_y(:, m)/(x*prof_mu(:, m) + a0))/alpha(m))
        end if
      end do
      if (bx < b) then
        b = bx
        a1 = x
      end if
    end do
    if (b <= 0.0_wp) b = 1.0_wp
  end subroutine best_linear_envelope

  !> Interval index j (mu in [mu_j, mu_j+1]) and the 4-point Lagrange weights in
  !> x = sqrt(mu) of nodes j0 ... j0+3 for mu.
  pure subroutine interp_weights(mu, j, j0, w, n_nodes)
    real(wp), intent(in) :: mu
    integer, intent(out) :: j, j0
    real(wp), intent(out) :: w(4)
    integer, intent(in), optional :: n_nodes  !! nodes of the table (default BRDF_NMU)
    real(wp) :: x, d
    integer :: nn
    nn = BRDF_NMU
    if (present(n_nodes)) nn = n_nodes
    x = sqrt(min(1.0_wp, max(0.0_wp, mu)))*(nn - 1)
    j = min(int(x), nn - 2) + 1
    j0 = min(max(j - 1, 1), nn - 3)
    d = x - (j0 - 1)     ! position relative to node j0, in node spacings
    w(1) = -(d - 1.0_wp)*(d - 2.0_wp)*(d - 3.0_wp)/6.0_wp
    w(2) = d*(d - 2.0_wp)*(d - 3.0_wp)/2.0_wp
    w(3) = -d*(d - 1.0_wp)*(d - 3.0_wp)/2.0_wp
    w(4) = d*(d - 1.0_wp)*(d - 2.0_wp)/6.0_wp
  end subroutine interp_weights

  !> The dense table's quantity T at mu (cubic interpolation in x = sqrt(mu) on the four
  !> nodes around it): uniform nodes directly, adaptive ones after a binary search.
  pure function dense_t(tab, mu) result(v)
    type(brdf_table_t), intent(in) :: tab
    real(wp), intent(in) :: mu
    real(wp) :: v
    real(wp) :: w(4), x, xs(4)
    integer :: j, j0, lo, hi, mid
    if (tab%alb_uniform) then
      call interp_weights(mu, j, j0, w, BRDF_NALB)
      v = dot_product(w, tab%ta(j0:j0 + 3))
      return
    end if
    x = sqrt(min(1.0_wp, max(0.0_wp, mu)))
    lo = 1
    hi = tab%n_alb
    do while (hi - lo > 1)          ! xa(lo) <= x < xa(hi)
      mid = (lo + hi)/2
      if (tab%xa(mid) <= x) then
        lo = mid
      else
        hi = mid
      end if
    end do
    j0 = min(max(lo - 1, 1), tab%n_alb - 3)
    xs = tab%xa(j0:j0 + 3)
    w(1) = (x - xs(2))*(x - xs(3))*(x - xs(4))/((xs(1) - xs(2))*(xs(1) - xs(3))*(xs(1) - xs(4)))
    w(2) = (x - xs(1))*(x - xs(3))*(x - xs(4))/((xs(2) - xs(1))*(xs(2) - xs(3))*(xs(2) - xs(4)))
    w(3) = (x - xs(1))*(x - xs(2))*(x - xs(4))/((xs(3) - xs(1))*(xs(3) - xs(2))*(xs(3) - xs(4)))
    w(4) = (x - xs(1))*(x - xs(2))*(x - xs(3))/((xs(4) - xs(1))*(xs(4) - xs(2))*(xs(4) - xs(3)))
    v = dot_product(w, tab%ta(j0:j0 + 3))
  end function dense_t

  !> Model (unclamped) albedo from the table at mu_in; for DSM the diffuse part is added.
  pure function model_albedo(tab, mu_in) result(alpha)
    type(brdf_table_t), intent(in) :: tab
    real(wp), intent(in) :: mu_in
    real(wp) :: alpha
    real(wp) :: w(4), mu
    integer :: j, j0
    select case (tab%p%kind)
    case (BRDF_LAMBERT)
      alpha = tab%p%c(1)
    case (BRDF_DSM, BRDF_RPV, BRDF_LSRT)
      if (mu_in == tab%mu_sun) then          ! the direct beam: exact
        alpha = tab%alpha_sun
        return
      end if
      mu = min(1.0_wp, max(mu_in, MU_NODE0))
      if (tab%n_alb >= BRDF_NALB) then
        alpha = max(0.0_wp, dense_t(tab, mu))
      else
        call interp_weights(mu, j, j0, w)
        alpha = max(0.0_wp, dot_product(w, tab%t(j0:j0 + 3)))
      end if
      if (tab%p%kind == BRDF_DSM) then
        alpha = tab%p%c(2)*tab%p%c(1) + (1.0_wp - tab%p%c(2))*alpha
      else if (tab%t_pow == 1.0_wp) then
        alpha = alpha/mu
      else if (tab%t_pow /= 0.0_wp) then
        alpha = alpha*exp(-tab%t_pow*log(mu))
      end if
    case default
      alpha = 0.0_wp
    end select
  end function model_albedo

  !> Directional albedo used in the photon loop: the model albedo from the table, at most 1.
  !> The weight of a photon reflected from direction mu_in is multiplied by it.
  elemental function brdf_albedo(tab, mu_in) result(alpha)
    type(brdf_table_t), intent(in) :: tab
    real(wp), intent(in) :: mu_in  !! cosine of the incident zenith angle, in (0, 1]
    real(wp) :: alpha
    alpha = min(1.0_wp, model_albedo(tab, mu_in))
  end function brdf_albedo

  !> BRDF [1/sr] used in the photon loop: the model, divided by its albedo where that exceeds
  !> 1 (so that the used albedo is 1). Same conventions as `brdf_eval`.
  elemental function brdf_table_eval(tab, mu_in, mu_out, cos_dphi) result(r)
    type(brdf_table_t), intent(in) :: tab
    real(wp), intent(in) :: mu_in, mu_out, cos_dphi
    real(wp) :: r
    r = brdf_eval(tab%p, mu_in, mu_out, cos_dphi)/max(1.0_wp, model_albedo(tab, mu_in))
  end function brdf_table_eval

  !> `brdf_table_eval` for propagation vectors (conventions of `brdf_eval_dir`).
  pure function brdf_table_eval_dir(tab, u_in, u_out) result(r)
    type(brdf_table_t), intent(in) :: tab
    real(wp), intent(in) :: u_in(3), u_out(3)
    real(wp) :: r
    r = brdf_eval_dir(tab%p, u_in, u_out)/max(1.0_wp, model_albedo(tab, -u_in(3)))
  end function brdf_table_eval_dir

  ! ------------------------------------------------------------------------------------------
  ! Sampling
  ! ------------------------------------------------------------------------------------------

  !> Draw the reflected direction for the incoming direction u_in (u_in(3) < 0), distributed
  !> as R mu_out/alpha(mu_in) of the table's model, u_out(3) > 0 (>= 0 for the cosine-weighted
  !> directions of `lambert_direction`).
  !>
  !> * Lambert: cosine-weighted (`lambert_direction`).
  !> * RPV, LSRT: rejection from the density a1 mu + a0 in (mu_out, phi) (seed text
  !>   eqs. 3.6.91-104, cancellation-free root), accepted with probability
  !>   mu R/(alpha (a1 mu + a0))/b, b tries on average (about 2 for typical RPV and LSRT
  !>   parameters, 5-25 for sharp hot spots or LSRT dominated by k_vol >> k_iso near the
  !>   zenith; more only at grazing incidence, mu_in < 0.0025).
  !> * DSM: diffuse (cosine) with probability f_d a_d/alpha, otherwise specular: facet slopes
  !>   from the Gaussian slope density (polar method), reflected about the facet, and accepted
  !>   with probability R_F(v) f_s cos(v)/mu_n/b (the Jacobian factor cos(v)/mu_n of the
  !>   corrected seed eq. 3.6.52); facets facing away or reflecting downward are rejected.
  !>
  !> The bound b of an interval comes from a scan with a 15 % margin, so a ratio above it is
  !> possible in principle (DSM: only for slopes beyond tan^2 th_n = 28 sigma^2, probability
  !> < 1e-12 per try). Such a proposal is accepted and counted in `n_violations`: it is
  !> under-represented by the factor b/ratio. So is a loop that reaches 100,000 tries (the last
  !> proposal is taken). The tests check the count is 0. A black surface returns the mirror
  !> direction (its weight is 0 anyway).
  !>
  !> Cost (gfortran -O3, one core, without link-time inlining of the generator), per call:
  !> Lambert 190 instructions (22 ns); DSM 700-1,000 (110-170 ns); RPV 1,150 (150 ns) for
  !> typical parameters, 2,300 (250 ns) with a sharp hot spot; LSRT 1,150-1,500 (190-240 ns).
  !> Mostly libm (pow/exp/log, erfc, two acos per LSRT evaluation) and the generator.
  pure subroutine brdf_sample(tab, u_in, rng, u_out, n_violations)
    type(brdf_table_t), intent(in) :: tab
    real(wp), intent(in) :: u_in(3)              !! incoming propagation direction, uz < 0
    type(rng_t), intent(inout) :: rng            !! random-number stream
    real(wp), intent(out) :: u_out(3)            !! reflected propagation direction, uz > 0
    integer(i8), intent(inout) :: n_violations   !! incremented per envelope violation
    real(wp) :: mu0, xi, a_d, a_s
    mu0 = min(1.0_wp, max(-u_in(3), MU_NODE0))
    select case (tab%p%kind)
    case (BRDF_LAMBERT)
      call sample_cosine(rng, u_out)
    case (BRDF_DSM)
      a_d = tab%p%c(2)*tab%p%c(1)
      a_s = (1.0_wp - tab%p%c(2))*model_albedo_spec(tab, mu0)
      call rng_next_uniform(rng, xi)
      if (xi*(a_d + a_s) < a_d .or. a_s <= 0.0_wp) then
        call sample_cosine(rng, u_out)
      else
        call sample_facets(tab, u_in, mu0, rng, u_out, n_violations)
      end if
    case (BRDF_RPV, BRDF_LSRT)
      call sample_linear(tab, u_in, mu0, rng, u_out, n_violations)
    case default
      u_out = [u_in(1), u_in(2), abs(u_in(3))]
    end select
  end subroutine brdf_sample

  !> DSM specular albedo from the table (without the (1 - f_d) factor).
  pure function model_albedo_spec(tab, mu0) result(a)
    type(brdf_table_t), intent(in) :: tab
    real(wp), intent(in) :: mu0
    real(wp) :: a
    real(wp) :: w(4)
    integer :: j, j0
    if (mu0 == tab%mu_sun .and. tab%p%c(2) < 1.0_wp) then
      a = max(0.0_wp, (tab%alpha_sun - tab%p%c(2)*tab%p%c(1))/(1.0_wp - tab%p%c(2)))
    else if (tab%n_alb >= BRDF_NALB) then
      a = max(0.0_wp, dense_t(tab, mu0))
    else
      call interp_weights(mu0, j, j0, w)
      a = max(0.0_wp, dot_product(w, tab%t(j0:j0 + 3)))
    end if
  end function model_albedo_spec

  !> A reflected direction of a Lambert surface: cosine-weighted over the upper hemisphere,
  !> mu = sqrt(xi) and a polar-method azimuth. The one sampler of Lambert reflection in kumo:
  !> Lambert surfaces and albedo maps (`reflect`, kumo_transport), the Lambert BRDF kernel and
  !> the diffuse part of DSM. uz lies in [0, 1) (0 with probability 2^-53; the photon loop
  !> nudges directions closer to the horizontal than UZ_MIN).
  pure subroutine lambert_direction(rng, ux, uy, uz)
    type(rng_t), intent(inout) :: rng
    real(wp), intent(out) :: ux, uy, uz
    real(wp) :: xi, mu, cphi, sphi
    call rng_next_uniform(rng, xi)
    uz = sqrt(xi)
    call sample_azimuth(rng, cphi, sphi)
    mu = sqrt(max(0.0_wp, 1.0_wp - uz*uz))
    ux = mu*cphi
    uy = mu*sphi
  end subroutine lambert_direction

  !> Cosine-weighted upward direction (lambert_direction) as a vector.
  pure subroutine sample_cosine(rng, u_out)
    type(rng_t), intent(inout) :: rng
    real(wp), intent(out) :: u_out(3)
    call lambert_direction(rng, u_out(1), u_out(2), u_out(3))
  end subroutine sample_cosine

  !> RPV and LSRT: rejection from the linear-in-mu density of the interval's envelope.
  pure subroutine sample_linear(tab, u_in, mu0, rng, u_out, n_violations)
    type(brdf_table_t), intent(in) :: tab
    real(wp), intent(in) :: u_in(3), mu0
    type(rng_t), intent(inout) :: rng
    real(wp), intent(out) :: u_out(3)
    integer(i8), intent(inout) :: n_violations
    real(wp) :: a1, a0, b, alpha, s0, xi, q, mu1, s1, cp, sp, ratio
    integer :: e, try
    alpha = model_albedo(tab, mu0)
    if (alpha <= 1.0e-12_wp) then      ! nothing is reflected; any direction will do
      call sample_cosine(rng, u_out)
      return
    end if
    e = env_bin(mu0)
    a1 = tab%a1(e)
    a0 = 0.5_wp/PI - 0.5_wp*a1
    b = tab%env(e)
    s0 = sin_of(mu0)
    do try = 1, MAX_TRIES
      call rng_next_uniform(rng, xi)
      q = xi/PI
      mu1 = q/(a0 + sqrt(a0*a0 + a1*q))   ! root of a1 mu^2 + 2 a0 mu = xi/pi
      call sample_azimuth(rng, cp, sp)
      s1 = sin_of(mu1)
      u_out = [s1*cp, s1*sp, mu1]
      if (mu1 <= 0.0_wp) cycle
      ratio = mu1*eval_core(tab%p, mu0, mu1, s0, s1, u_in(1)*u_out(1) + u_in(2)*u_out(2))/ &
              (alpha*(a1*mu1 + a0))
      if (ratio > b) then
        n_violations = n_violations + 1
        return
      end if
      call rng_next_uniform(rng, xi)
      if (xi*b < ratio) return
    end do
    n_violations = n_violations + 1
  end subroutine sample_linear

  !> DSM specular part: facet slopes from the Gaussian, reflected ray, rejection.
  pure subroutine sample_facets(tab, u_in, mu0, rng, u_out, n_violations)
    type(brdf_table_t), intent(in) :: tab
    real(wp), intent(in) :: u_in(3), mu0
    type(rng_t), intent(inout) :: rng
    real(wp), intent(out) :: u_out(3)
    integer(i8), intent(inout) :: n_violations
    real(wp) :: b, sigma, lam0, a, bb, r2, g, zx, zy, c, nn, mu1, ratio, xi, f
    integer :: try
    b = tab%env(env_bin(mu0))
    sigma = sqrt(tab%p%c(5))
    lam0 = dsm_shadowing(mu0, sigma)
    u_out = [u_in(1), u_in(2), mu0]
    do try = 1, MAX_TRIES
      ! two independent N(0, sigma^2/2) slopes (Marsaglia polar method)
      do
        call rng_next_uniform(rng, a)
        call rng_next_uniform(rng, bb)
        a = 2.0_wp*a - 1.0_wp
        bb = 2.0_wp*bb - 1.0_wp
        r2 = a*a + bb*bb
        if (r2 < 1.0_wp .and. r2 > 0.0_wp) exit
      end do
      g = sigma*sqrt(-log(r2)/r2)
      zx = a*g
      zy = bb*g
      ! Omega0 = -u_in; facet normal along N = (-zx, -zy, 1); c = Omega0 . N = cos(v)/mu_n
      c = -u_in(3) + u_in(1)*zx + u_in(2)*zy
      if (c <= 0.0_wp) cycle
      nn = 1.0_wp + zx*zx + zy*zy
      f = 2.0_wp*c/nn
      mu1 = f + u_in(3)
      if (mu1 <= 0.0_wp) cycle
      ! squeeze: Lambda(mu1) >= 0, so the ratio without it bounds the ratio from above and
      ! a proposal failing that bound is rejected without evaluating Lambda (erfc, exp)
      ratio = fresnel_reflectance(tab%p%c(3), tab%p%c(4), c/sqrt(nn))*c/(1.0_wp + lam0)
      call rng_next_uniform(rng, xi)
      if (xi*b >= ratio) cycle
      ratio = ratio*(1.0_wp + lam0)/(1.0_wp + lam0 + dsm_shadowing(mu1, sigma))
      if (ratio > b .or. xi*b < ratio) then
        if (ratio > b) n_violations = n_violations + 1
        u_out = [-f*zx + u_in(1), -f*zy + u_in(2), mu1]   ! Omega1 = 2 (Omega0 . n) n - Omega0
        u_out = u_out/norm2(u_out)
        return
      end if
    end do
    n_violations = n_violations + 1
  end subroutine sample_facets

  ! ------------------------------------------------------------------------------------------
  ! Quadrature nodes
  ! ------------------------------------------------------------------------------------------

  !> Nodes and weights on [0, 1] of one quadrature panel: Gauss-Legendre in u, mapped by
  !> x = u^2 (3 - 2u) (dx = 6 u (1 - u) du). The map flattens the integrand at both panel
  !> ends, where the panels put the hot spot and the Li-Sparse clamp, whose (x - x_k)^(3/2)
  !> behaviour would otherwise limit Gauss-Legendre to about 5e-5 with 12 nodes (1e-15 with
  !> the map, at mu_in = 1).
  pure subroutine panel_nodes(n, x, w)
    integer, intent(in) :: n
    real(wp), intent(out) :: x(n), w(n)
    real(wp) :: u(n)
    call gauss_legendre01(n, u, w)
    x = u*u*(3.0_wp - 2.0_wp*u)
    w = w*6.0_wp*u*(1.0_wp - u)
  end subroutine panel_nodes

end module kumo_brdf
