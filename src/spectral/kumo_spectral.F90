! SPDX-License-Identifier: BSD-3-Clause
!> The spectral layer of broadband runs: per-g-point optical properties of a gas column and the
!> Monte Carlo spectral integration plan that gives each photon its g-point and weight.
!>
!> 1. Columns (`spectral_column_t`, built by `spectral_sw_column` or `spectral_lw_column` from
!>    level pressures, layer pressures and temperatures and the gas amounts, with the RRTMGP
!>    k-distributions of `kumo_gas_optics`): for each g-point g and layer l (bottom to top) the
!>    gas absorption optical depth, and in the shortwave the Rayleigh optical depth and the
!>    single-scattering albedo tau_R / (tau_abs + tau_R); the source of each g-point:
!>    * shortwave: the solar flux at the top of the atmosphere normal to the beam, scaled to the
!>      total solar irradiance (TSI) asked for, and the source energy S_g = mu0 F_g (W m-2 on a
!>      horizontal surface: sum_g S_g = TSI mu0);
!>    * longwave: the Planck sources of the layers, of their bottom and top levels (with the
!>      layer's Planck fractions) and of the surface, and the source energy S_g, the power emitted
!>      per unit area by the column and the surface,
!>          S_g = pi eps B_sfc,g + sum_l 4 pi tau_l,g (B_bot,l,g + B_top,l,g) / 2,
!>      the emission of a layer whose Planck radiance is linear in optical depth between its
!>      level values (kumo's thermal convention, `kumo_thermal_column`) and of a Lambert surface
!>      of emissivity eps. Also the power that leaves each layer through its faces (the rest is
!>      absorbed again inside the emitting layer),
!>          E_g = pi eps B_sfc,g + sum_l 4 pi (B_bot,l,g + B_top,l,g) / 2 (1/2 - E_3(tau_l,g)),
!>      exact for the linear source (the slope terms of the two faces cancel); E_3 is the
!>      exponential integral, 1/2 - E_3(tau) -> tau for thin layers and 1/2 for opaque ones.
!>      In the RFMIP column of the tests (lw-g128) the layers emit 2.6e6 W m-2, 99.9 % of it in
!>      g-points whose column optical depth exceeds 10, and almost all of it is absorbed again
!>      in the emitting layer; 9.6e3 W m-2 leave the layers, the surface emits 408 W m-2
!>      (docs/broadband.md discusses what this means for longwave sampling).
!>    Arrays are (n_layer, n_gpt): the column of one g-point is contiguous, as a photon of that
!>    g-point reads it. A column of 100 layers takes 100 x 112 x 8 bytes = 90 kB per quantity
!>    in the shortwave (g112), 102 kB in the longwave (g128).
!>
!> 2. The sampling plan (`spectral_plan_t`, `spectral_plan_init`): g-point g is drawn with
!>    probability
!>        p_g = (1 - a) S_g / S + a / N+     (S_g > 0),      p_g = 0     (S_g = 0),
!>    S = sum_g S_g, N+ the number of g-points with S_g > 0 and a in [0, 1) the floor share
!>    (default 0: pure source-proportional sampling). The mixture with the uniform distribution
!>    (a defensive mixture, Hesterberg 1995, Technometrics 37, 185) gives every g-point with
!>    energy at least the probability a / N+ and bounds every weight by S / (n (1 - a)).
!>    Optionally the probabilities follow an importance I_g instead of S_g (same formula with I
!>    in place of S; I_g > 0 wherever S_g > 0); the weights below still carry S_g.
!>
!> 3. A batch (`spectral_batch_t`, `spectral_begin_batch`): n photons are spread over the
!>    g-points by systematic sampling of the cumulative table C_g = p_1 + ... + p_g with one
!>    uniform number u: photon i (i = 1..n) takes the g-point whose interval [C_{g-1}, C_g)
!>    holds (i - 1 + u) / n. g-point g then gets n_g = ceil(n C_g - u) - ceil(n C_{g-1} - u)
!>    photons, floor(n p_g) or ceil(n p_g) of them (E[n_g] = n p_g), the counts add up to n, and
!>    the photons of one g-point are consecutive. Each photon of g-point g carries the weight
!>        w_g = S_g / n_g            if n p_g >= 1 (then n_g >= 1 in every batch),
!>        w_g = S_g / (n p_g)        otherwise,
!>    in W m-2. Both make E[n_g w_g] = S_g, so a tally that adds w_g times the photon's score
!>    (its contribution per unit source) is unbiased for the sum over g-points. The first form
!>    removes the noise of the counts from the estimate: the weights of a batch add up to S
!>    exactly when every g-point with energy has n p_g >= 1 (with a > 0: from n >= N+ / a on).
!>
!> The plan and batch routines are pure or check their inputs and never stop; no netCDF, no MPI.
module kumo_spectral
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp, i8
  use kumo_constants, only: PI, FOUR_PI
  use kumo_error, only: error_t, set_error, str
  use kumo_rng, only: rng_t, rng_uniform
  use kumo_expint, only: expint_d
  use kumo_gas_optics, only: gas_kdist_t, gas_optical_depth, gas_planck_source, &
                             gas_solar_source, gas_col_dry, gas_index
  implicit none
  private

  public :: spectral_column_t, spectral_sw_column, spectral_lw_column, spectral_column_bytes
  public :: spectral_plan_t, spectral_plan_init, spectral_probabilities
  public :: spectral_batch_t, spectral_begin_batch, spectral_batch_from_u
  public :: spectral_counts, spectral_weights, spectral_photon_gpoint

  !> Per-g-point optical properties and sources of one gas column (layers 1..n_layer from the
  !> bottom). Built by spectral_sw_column or spectral_lw_column.
  type :: spectral_column_t
    logical :: longwave = .false.
    integer :: n_layer = 0, n_gpt = 0, n_band = 0
    integer, allocatable :: gpt_band(:)             !! (n_gpt) band of each g-point
    real(wp), allocatable :: band_wavenumber(:, :)  !! (2, n_band) cm-1
    real(wp), allocatable :: col_dry(:)             !! (n_layer) dry-air column, molecules m-2
    real(wp), allocatable :: tau_abs(:, :)          !! (n_layer, n_gpt) gas absorption
    real(wp), allocatable :: tau_rayleigh(:, :)     !! (n_layer, n_gpt) shortwave
    real(wp), allocatable :: ssa(:, :)              !! (n_layer, n_gpt) shortwave
    ! Shortwave
    real(wp) :: mu0 = 1.0_wp                        !! cosine of the solar zenith angle
    real(wp) :: tsi = 0.0_wp                        !! total solar irradiance, W m-2
    real(wp), allocatable :: solar_flux(:)          !! (n_gpt) TOA, normal to the beam, W m-2
    ! Longwave
    real(wp) :: emissivity = 1.0_wp                 !! surface emissivity (Lambert)
    real(wp), allocatable :: lay_src(:, :)          !! (n_layer, n_gpt) W m-2 sr-1 at tlay
    real(wp), allocatable :: lev_src_bot(:, :)      !! (n_layer, n_gpt) at the layer's bottom
    real(wp), allocatable :: lev_src_top(:, :)      !! (n_layer, n_gpt) at the layer's top
    real(wp), allocatable :: sfc_src(:)             !! (n_gpt) W m-2 sr-1 at tsfc
    real(wp), allocatable :: emission_sfc(:)        !! (n_gpt) pi eps sfc_src, W m-2
    real(wp), allocatable :: emission_atm(:)        !! (n_gpt) emitted by the layers, W m-2
    real(wp), allocatable :: escape_atm(:)          !! (n_gpt) leaving the emitting layers, W m-2
    real(wp), allocatable :: energy_escape(:)       !! (n_gpt) emission_sfc + escape_atm, W m-2
    ! Both
    real(wp), allocatable :: energy(:)              !! (n_gpt) source energy S_g, W m-2
  end type spectral_column_t

  !> How g-points are drawn: energies, probabilities and their cumulative table.
  type :: spectral_plan_t
    integer :: n_gpt = 0
    integer :: n_active = 0                         !! g-points with S_g > 0
    real(wp) :: floor_share = 0.0_wp                !! a
    real(wp) :: total = 0.0_wp                      !! S, W m-2
    real(wp), allocatable :: energy(:)              !! (n_gpt) S_g, W m-2
    real(wp), allocatable :: importance(:)          !! (n_gpt) I_g (= S_g by default)
    real(wp), allocatable :: prob(:)                !! (n_gpt) p_g
    real(wp), allocatable :: cum(:)                 !! (0:n_gpt) C_g, C_0 = 0, C_n_gpt = 1
  end type spectral_plan_t

  !> One batch: how many photons each g-point gets, where they start, their weight.
  type :: spectral_batch_t
    integer(i8) :: n = 0                            !! photons in the batch
    real(wp) :: u = 0.0_wp                          !! the systematic-sampling offset
    integer(i8), allocatable :: count(:)            !! (n_gpt) n_g
    integer(i8), allocatable :: first(:)            !! (n_gpt) index of the first photon of g
    real(wp), allocatable :: weight(:)              !! (n_gpt) w_g, W m-2 per photon
  end type spectral_batch_t

contains

  ! ------------------------------------------------------------------------------------------
  ! Columns
  ! ------------------------------------------------------------------------------------------

  !> Shortwave column: absorption and Rayleigh optical depths, single-scattering albedo, solar
  !> flux per g-point scaled to `tsi` (default: the file's) and the source energy mu0 F_g.
  !> `col_dry` (molecules m-2 per layer) is computed from `plev` and water vapour when absent.
  subroutine spectral_sw_column(kd, plev, play, tlay, vmr, mu0, col, error, col_dry, tsi, &
                                mg_index, sb_index)
    type(gas_kdist_t), intent(in) :: kd
    real(wp), intent(in) :: plev(0:)                !! level pressure, Pa; plev(0) at the bottom
    real(wp), intent(in) :: play(:)                 !! layer pressure, Pa
    real(wp), intent(in) :: tlay(:)                 !! layer temperature, K
    real(wp), intent(in) :: vmr(:, :)               !! (n_layer, kd%n_gas) mol/mol of dry air
    real(wp), intent(in) :: mu0                     !! cosine of the solar zenith angle, (0, 1]
    type(spectral_column_t), intent(out) :: col
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: col_dry(:)    !! (n_layer) molecules m-2
    real(wp), intent(in), optional :: tsi           !! total solar irradiance, W m-2
    real(wp), intent(in), optional :: mg_index, sb_index  !! NRLSSI2 indices (kumo_gas_optics)
    integer :: nl

    if (kd%longwave) then
      call set_error(error, 'spectral_sw_column: the k-distribution ' // source_name(kd) // &
                     ' is a longwave one')
      return
    end if
    if (outside(mu0, tiny(1.0_wp), 1.0_wp)) then
      call set_error(error, 'spectral_sw_column: mu0 = ' // str(mu0) // ' must be within (0, 1]')
      return
    end if
    call column_common(kd, plev, play, vmr, col, error, col_dry)
    if (allocated(error)) return
    nl = col%n_layer
    allocate (col%tau_rayleigh(nl, kd%n_gpt), col%ssa(nl, kd%n_gpt), col%solar_flux(kd%n_gpt))
    call gas_optical_depth(kd, play, tlay, vmr, col%col_dry, col%tau_abs, error, &
                           tau_rayleigh=col%tau_rayleigh)
    if (allocated(error)) return
    where (col%tau_abs + col%tau_rayleigh > 0)
      col%ssa = col%tau_rayleigh / (col%tau_abs + col%tau_rayleigh)
    else where
      col%ssa = 0
    end where
    call gas_solar_source(kd, col%solar_flux, error, tsi, mg_index, sb_index)
    if (allocated(error)) return
    col%mu0 = mu0
    col%tsi = sum(col%solar_flux)
    col%energy = mu0 * col%solar_flux
  end subroutine spectral_sw_column

  !> Longwave column: absorption optical depths, Planck sources of layers, levels and surface,
  !> and the emitted power per g-point (surface of emissivity `emissivity`, default 1).
  subroutine spectral_lw_column(kd, plev, tlev, play, tlay, tsfc, vmr, col, error, col_dry, &
                                emissivity)
    type(gas_kdist_t), intent(in) :: kd
    real(wp), intent(in) :: plev(0:)                !! level pressure, Pa; plev(0) at the bottom
    real(wp), intent(in) :: tlev(0:)                !! level temperature, K
    real(wp), intent(in) :: play(:)                 !! layer pressure, Pa
    real(wp), intent(in) :: tlay(:)                 !! layer temperature, K
    real(wp), intent(in) :: tsfc                    !! surface temperature, K
    real(wp), intent(in) :: vmr(:, :)               !! (n_layer, kd%n_gas) mol/mol of dry air
    type(spectral_column_t), intent(out) :: col
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: col_dry(:)    !! (n_layer) molecules m-2
    real(wp), intent(in), optional :: emissivity    !! surface emissivity, [0, 1]
    integer :: nl, g

    if (.not. kd%longwave) then
      call set_error(error, 'spectral_lw_column: the k-distribution ' // source_name(kd) // &
                     ' is a shortwave one')
      return
    end if
    if (present(emissivity)) then
      if (outside(emissivity, 0.0_wp, 1.0_wp)) then
        call set_error(error, 'spectral_lw_column: emissivity = ' // str(emissivity) // &
                       ' must be within [0, 1]')
        return
      end if
      col%emissivity = emissivity
    end if
    call column_common(kd, plev, play, vmr, col, error, col_dry)
    if (allocated(error)) return
    col%longwave = .true.
    nl = col%n_layer
    allocate (col%lay_src(nl, kd%n_gpt), col%lev_src_bot(nl, kd%n_gpt), &
              col%lev_src_top(nl, kd%n_gpt), col%sfc_src(kd%n_gpt))
    call gas_optical_depth(kd, play, tlay, vmr, col%col_dry, col%tau_abs, error)
    if (allocated(error)) return
    call gas_planck_source(kd, play, tlay, tlev, tsfc, vmr, col%lay_src, col%lev_src_bot, &
                           col%lev_src_top, col%sfc_src, error)
    if (allocated(error)) return
    col%emission_sfc = PI * col%emissivity * col%sfc_src
    allocate (col%emission_atm(kd%n_gpt), col%escape_atm(kd%n_gpt))
    do g = 1, kd%n_gpt
      col%emission_atm(g) = FOUR_PI * sum(col%tau_abs(:, g) * 0.5_wp * &
                                          (col%lev_src_bot(:, g) + col%lev_src_top(:, g)))
      col%escape_atm(g) = FOUR_PI * sum(expint_d(3, col%tau_abs(:, g)) * 0.5_wp * &
                                        (col%lev_src_bot(:, g) + col%lev_src_top(:, g)))
    end do
    col%energy = col%emission_sfc + col%emission_atm
    col%energy_escape = col%emission_sfc + col%escape_atm
  end subroutine spectral_lw_column

  !> Bytes held by the arrays of a column.
  pure function spectral_column_bytes(col) result(nbytes)
    type(spectral_column_t), intent(in) :: col
    integer(i8) :: nbytes
    nbytes = 0
    if (allocated(col%tau_abs)) nbytes = nbytes + 8_i8 * size(col%tau_abs, kind=i8)
    if (allocated(col%tau_rayleigh)) nbytes = nbytes + 8_i8 * size(col%tau_rayleigh, kind=i8)
    if (allocated(col%ssa)) nbytes = nbytes + 8_i8 * size(col%ssa, kind=i8)
    if (allocated(col%lay_src)) nbytes = nbytes + 8_i8 * size(col%lay_src, kind=i8)
    if (allocated(col%lev_src_bot)) nbytes = nbytes + 8_i8 * size(col%lev_src_bot, kind=i8)
    if (allocated(col%lev_src_top)) nbytes = nbytes + 8_i8 * size(col%lev_src_top, kind=i8)
    if (allocated(col%col_dry)) nbytes = nbytes + 8_i8 * size(col%col_dry, kind=i8)
    if (allocated(col%solar_flux)) nbytes = nbytes + 8_i8 * size(col%solar_flux, kind=i8)
    if (allocated(col%sfc_src)) nbytes = nbytes + 8_i8 * size(col%sfc_src, kind=i8)
    if (allocated(col%emission_sfc)) nbytes = nbytes + 8_i8 * size(col%emission_sfc, kind=i8)
    if (allocated(col%emission_atm)) nbytes = nbytes + 8_i8 * size(col%emission_atm, kind=i8)
    if (allocated(col%escape_atm)) nbytes = nbytes + 8_i8 * size(col%escape_atm, kind=i8)
    if (allocated(col%energy_escape)) nbytes = nbytes + 8_i8 * size(col%energy_escape, kind=i8)
    if (allocated(col%energy)) nbytes = nbytes + 8_i8 * size(col%energy, kind=i8)
  end function spectral_column_bytes

  !> Checks and fields shared by both kinds of column; allocates tau_abs.
  subroutine column_common(kd, plev, play, vmr, col, error, col_dry)
    type(gas_kdist_t), intent(in) :: kd
    real(wp), intent(in) :: plev(0:), play(:), vmr(:, :)
    type(spectral_column_t), intent(inout) :: col
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: col_dry(:)
    integer :: nl, ih2o, l
    real(wp), allocatable :: h2o(:)

    nl = size(play)
    if (nl < 1) then
      call set_error(error, 'spectral column: no layers')
      return
    end if
    if (size(plev) /= nl + 1) then
      call set_error(error, 'spectral column: plev has ' // str(size(plev)) // ' levels, ' // &
                     str(nl) // ' layers need ' // str(nl + 1))
      return
    end if
    do l = 1, nl
      if (.not. (play(l) <= plev(l - 1) .and. play(l) >= plev(l))) then
        call set_error(error, 'spectral column: layer ' // str(l) // ' pressure ' // &
                       str(play(l)) // ' Pa is not between its levels ' // str(plev(l - 1)) // &
                       ' and ' // str(plev(l)) // ' Pa')
        return
      end if
    end do
    col%n_layer = nl
    col%n_gpt = kd%n_gpt
    col%n_band = kd%n_band
    col%gpt_band = kd%gpt_band
    col%band_wavenumber = kd%band_wavenumber
    allocate (col%col_dry(nl), col%tau_abs(nl, kd%n_gpt))
    if (present(col_dry)) then
      if (size(col_dry) /= nl) then
        call set_error(error, 'spectral column: col_dry has ' // str(size(col_dry)) // &
                       ' values, expected ' // str(nl))
        return
      end if
      col%col_dry = col_dry
    else
      ih2o = gas_index(kd, 'h2o')
      allocate (h2o(nl), source=0.0_wp)
      if (ih2o > 0 .and. size(vmr, 2) >= ih2o .and. size(vmr, 1) == nl) h2o = vmr(:, ih2o)
      call gas_col_dry(plev, h2o, col%col_dry, error)
      if (allocated(error)) return
    end if
  end subroutine column_common

  !> True unless x is finite and within [lo, hi]; safe for NaN under floating-point traps (no
  !> ordered comparison is made with a NaN).
  elemental logical function outside(x, lo, hi)
    real(wp), intent(in) :: x, lo, hi
    if (.not. ieee_is_finite(x)) then
      outside = .true.
    else
      outside = x < lo .or. x > hi
    end if
  end function outside

  function source_name(kd) result(name)
    type(gas_kdist_t), intent(in) :: kd
    character(len=:), allocatable :: name
    name = '(tables built in memory)'
    if (allocated(kd%source)) name = kd%source
  end function source_name

  ! ------------------------------------------------------------------------------------------
  ! Sampling plan
  ! ------------------------------------------------------------------------------------------

  !> Probabilities of the g-points: p_g = (1 - a) S_g / S + a / N+ where S_g > 0, 0 elsewhere.
  !> Assumes energy >= 0 with a positive sum and 0 <= a < 1 (spectral_plan_init checks).
  pure function spectral_probabilities(energy, floor_share) result(prob)
    real(wp), intent(in) :: energy(:)               !! S_g >= 0, W m-2
    real(wp), intent(in) :: floor_share             !! a in [0, 1)
    real(wp) :: prob(size(energy))
    real(wp) :: total
    integer :: n_active
    total = sum(energy)
    n_active = count(energy > 0)
    where (energy > 0)
      prob = (1 - floor_share) * (energy / total) + floor_share / n_active
    else where
      prob = 0
    end where
  end function spectral_probabilities

  !> Plan of a run from the source energy of each g-point (W m-2; e.g. `col%energy`), the
  !> floor share a (default 0) and optionally an importance I_g that the probabilities follow
  !> instead of the energies (e.g. `col%energy_escape` in the longwave).
  subroutine spectral_plan_init(energy, plan, error, floor_share, importance)
    real(wp), intent(in) :: energy(:)
    type(spectral_plan_t), intent(out) :: plan
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: floor_share
    real(wp), intent(in), optional :: importance(:)
    integer :: g, ng

    ng = size(energy)
    if (ng < 1) then
      call set_error(error, 'spectral_plan_init: no g-points')
      return
    end if
    do g = 1, ng
      if (outside(energy(g), 0.0_wp, huge(1.0_wp))) then
        call set_error(error, 'spectral_plan_init: energy of g-point ' // str(g) // ' = ' // &
                       str(energy(g)) // ' W m-2 must be finite and >= 0')
        return
      end if
    end do
    if (outside(sum(energy), tiny(1.0_wp), huge(1.0_wp))) then
      call set_error(error, 'spectral_plan_init: the energies add up to ' // str(sum(energy)) // &
                     ' W m-2; need a positive, finite total')
      return
    end if
    if (present(floor_share)) then
      if (outside(floor_share, 0.0_wp, nearest(1.0_wp, -1.0_wp))) then
        call set_error(error, 'spectral_plan_init: floor_share = ' // str(floor_share) // &
                       ' must be within [0, 1)')
        return
      end if
      plan%floor_share = floor_share
    end if
    plan%importance = energy
    if (present(importance)) then
      if (size(importance) /= ng) then
        call set_error(error, 'spectral_plan_init: importance has ' // str(size(importance)) // &
                       ' values for ' // str(ng) // ' g-points')
        return
      end if
      do g = 1, ng
        if (outside(importance(g), 0.0_wp, huge(1.0_wp)) .or. &
            (energy(g) > 0 .and. .not. importance(g) > 0)) then
          call set_error(error, 'spectral_plan_init: importance of g-point ' // str(g) // ' = ' // &
                         str(importance(g)) // ' must be finite, >= 0, and > 0 where the ' // &
                         'energy is > 0 (energy ' // str(energy(g)) // ' W m-2)')
          return
        end if
      end do
      if (.not. ieee_is_finite(sum(importance))) then
        call set_error(error, 'spectral_plan_init: the importances add up to ' // &
                       str(sum(importance)) // '; need a finite total')
        return
      end if
      ! a g-point without energy is never drawn, whatever its importance: its photons would
      ! carry no weight (and a batch of them alone would launch none)
      plan%importance = merge(importance, 0.0_wp, energy > 0)
    end if
    plan%n_gpt = ng
    plan%energy = energy
    plan%total = sum(energy)
    plan%n_active = count(plan%importance > 0)
    plan%prob = spectral_probabilities(plan%importance, plan%floor_share)
    allocate (plan%cum(0:ng))
    plan%cum(0) = 0
    do g = 1, ng
      plan%cum(g) = plan%cum(g - 1) + plan%prob(g)
    end do
    ! The table ends at exactly 1; g-points without energy keep an empty interval (also at the
    ! end of the table, where the sum may round to slightly below or above 1).
    do g = ng, 1, -1
      if (plan%prob(g) > 0) exit
    end do
    plan%cum(1:g - 1) = min(plan%cum(1:g - 1), 1.0_wp)
    plan%cum(g:ng) = 1
  end subroutine spectral_plan_init

  !> Photons per g-point of a batch of n by systematic sampling with offset u in [0, 1):
  !> n_g = N(C_g) - N(C_{g-1}), N(C) = ceil(n C - u) photons i have (i - 1 + u) / n < C.
  pure function spectral_counts(cum, n, u) result(counts)
    real(wp), intent(in) :: cum(0:)                 !! C_0 = 0 .. C_n_gpt = 1
    integer(i8), intent(in) :: n                    !! photons in the batch, >= 1
    real(wp), intent(in) :: u                       !! offset, [0, 1)
    integer(i8) :: counts(ubound(cum, 1))
    integer(i8) :: below, prev
    integer :: g, ng
    ng = ubound(cum, 1)
    prev = 0
    do g = 1, ng
      if (g == ng .or. cum(g) >= 1) then
        below = n                                   ! exactly, whatever n C - u rounds to
      else if (.not. (cum(g) > cum(g - 1))) then
        below = prev
      else
        below = min(n, max(0_i8, ceiling(real(n, wp) * cum(g) - u, i8)))
      end if
      counts(g) = below - prev
      prev = below
    end do
  end function spectral_counts

  !> Weights of the photons of each g-point (W m-2): S_g / n_g where n p_g >= 1 (and n_g >= 1),
  !> S_g / (n p_g) elsewhere, 0 for g-points without energy.
  pure function spectral_weights(energy, prob, counts, n) result(weight)
    real(wp), intent(in) :: energy(:), prob(:)
    integer(i8), intent(in) :: counts(:), n
    real(wp) :: weight(size(energy))
    integer :: g
    do g = 1, size(energy)
      if (prob(g) <= 0) then
        weight(g) = 0
      else if (real(n, wp) * prob(g) >= 1 .and. counts(g) >= 1) then
        weight(g) = energy(g) / real(counts(g), wp)
      else
        weight(g) = energy(g) / (real(n, wp) * prob(g))
      end if
    end do
  end function spectral_weights

  !> A batch of n photons for a given offset u (pure; spectral_begin_batch draws u).
  pure subroutine spectral_batch_from_u(plan, n, u, batch)
    type(spectral_plan_t), intent(in) :: plan
    integer(i8), intent(in) :: n
    real(wp), intent(in) :: u
    type(spectral_batch_t), intent(out) :: batch
    integer :: g
    batch%n = n
    batch%u = u
    batch%count = spectral_counts(plan%cum, n, u)
    allocate (batch%first(plan%n_gpt))
    batch%first(1) = 1
    do g = 2, plan%n_gpt
      batch%first(g) = batch%first(g - 1) + batch%count(g - 1)
    end do
    batch%weight = spectral_weights(plan%energy, plan%prob, batch%count, n)
  end subroutine spectral_batch_from_u

  !> Start a batch of n photons: one uniform number from `rng` fixes every photon's g-point.
  subroutine spectral_begin_batch(plan, n, rng, batch, error)
    type(spectral_plan_t), intent(in) :: plan
    integer(i8), intent(in) :: n
    type(rng_t), intent(inout) :: rng
    type(spectral_batch_t), intent(out) :: batch
    type(error_t), allocatable, intent(out) :: error
    if (plan%n_gpt < 1 .or. .not. allocated(plan%cum)) then
      call set_error(error, 'spectral_begin_batch: the plan is not set up (spectral_plan_init)')
      return
    end if
    if (n < 1) then
      call set_error(error, 'spectral_begin_batch: n = ' // str(n) // ' photons, must be >= 1')
      return
    end if
    call spectral_batch_from_u(plan, n, rng_uniform(rng), batch)
  end subroutine spectral_begin_batch

  !> The g-point of photon ip (1..n) of a batch (binary search over the first photons).
  pure integer function spectral_photon_gpoint(batch, ip) result(g)
    type(spectral_batch_t), intent(in) :: batch
    integer(i8), intent(in) :: ip
    integer :: lo, hi, mid
    lo = 1
    hi = size(batch%first)
    ! Last g with first(g) <= ip and a photon; g-points without photons share their successor's
    ! first index, so the search ends on the one that has photons.
    do while (lo < hi)
      mid = (lo + hi + 1) / 2
      if (batch%first(mid) <= ip) then
        lo = mid
      else
        hi = mid - 1
      end if
    end do
    g = lo
  end function spectral_photon_gpoint

end module kumo_spectral
