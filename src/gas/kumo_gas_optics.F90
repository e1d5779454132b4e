! SPDX-License-Identifier: BSD-3-Clause
!> Gas optics from RRTMGP k-distributions: absorption optical depth per g-point, Rayleigh optical
!> depth (shortwave), Planck sources (longwave) and the solar source per g-point.
!>
!> The method is that of Pincus, Mlawer and Delamere (2019), "Balancing accuracy, efficiency, and
!> flexibility in radiation calculations for dynamical models", JAMES 11, 3074-3089,
!> doi:10.1029/2019MS001621 (P19), with the table layout documented by the variables of the
!> k-distribution files (`kmajor`, `kminor_lower/upper`, `vmr_ref`, `key_species`, ...).
!>
!> * Each band has two key ("major") species per atmosphere part (lower: p > `press_ref_trop`,
!>   upper: p <= `press_ref_trop`); key species 0 stands for dry air (volume mixing ratio 1), and
!>   a part with no key species at all (0, 0) uses CO2 for both (the tables' convention).
!>   For a layer at (p, T) with mixing ratios r1, r2 of the key species, at each of the two
!>   reference temperatures T_j bracketing T the binary-mixing parameter is
!>       eta_j = r1 / (r1 + R_j r2),  R_j = vmr_ref(1, T_j) / vmr_ref(2, T_j)
!>   (0.5 when r1 + R_j r2 = 0), and the major optical depth is
!>       tau_major = N_dry sum_j w_j (r1 + R_j r2) k(eta_j, ln p, T_j),
!>   k interpolated linearly in eta (nodes 0..1) and ln p, w_j the linear weights in T.
!>   The pressure axis of `kmajor` holds the reference pressures of the lower atmosphere, then
!>   those of the upper atmosphere starting again at the tropopause node: an upper-atmosphere
!>   layer in pressure interval j reads nodes j+1, j+2.
!> * Minor absorbers: for every minor interval of the band (lower or upper table),
!>       tau_minor = N_dry r_m k_m(eta_j, T_j) [p / T / (100 Pa/hPa)] [s or (1 - s)],
!>   k_m interpolated in eta and T as above (without the r1 + R r2 factor); the density factor
!>   p/T (p in hPa) applies where `minor_scales_with_density` is set, and the scaling gas factor s
!>   (its mixing ratio relative to moist air, r_s / (1 + r_h2o)), or its complement 1 - s where
!>   `scale_by_complement` is set, where a scaling gas is named.
!> * Rayleigh optical depth (shortwave): N_dry (1 + r_h2o) k_R(eta_j, T_j), same interpolation as
!>   the minor absorbers, tables `rayl_lower`, `rayl_upper`.
!> * Planck sources (longwave): Planck fraction f_g(eta, ln p, T) interpolated like `kmajor` but
!>   without the r1 + R r2 factor and with the T and ln p weights clamped to the table, times the
!>   band-integrated Planck radiance B_b(T) (`totplnk`, on a 1 K grid from the smallest to the
!>   largest reference temperature), linear in T. The layer source uses the layer temperature,
!>   the sources at the bottom and top of a layer the level temperatures with the layer's
!>   fractions, the surface source the surface temperature with the fractions of the lowest layer.
!> * Solar source: `solar_source_quiet` per g-point normalised to sum 1 and scaled to the total
!>   solar irradiance asked for; optionally with the facular and sunspot terms of the NRLSSI2
!>   model, quiet + (Mg - Mg_0) facular + (SB - SB_0) sunspot, before the scaling.
!>
!> Outside the reference tables (T below 160 K or above 355 K; p above 1096 hPa or below 1 Pa for
!> these files) the interpolation is extended linearly along the end interval and the result
!> floored at zero (the Planck fraction is clamped instead); this is the behaviour of jax-rrtmgp,
!> against which kumo is verified (docs/gas-optics.md).
!>
!> Units: pressure Pa, temperature K, mixing ratios mol/mol of dry air, dry-air column
!> molecules m-2, optical depths 1, Planck sources W m-2 sr-1 per g-point, solar source W m-2 per
!> g-point. The tables keep the files' own cm2 per molecule; the 1e-4 m2/cm2 is applied here.
!>
!> Memory of the tables (8-byte reals): `kmajor` n_temp x (n_press+1) x n_eta x n_gpt
!> (14 x 60 x 9 x 128: 7.7 MB for lw-g128, 6.8 MB for sw-g112, twice that for g256/g224), the same
!> again for the Planck fractions (longwave), the minor tables 14 x 9 x n_contributors (0.8 MB for
!> lw-g128) and the Rayleigh tables 2 x 14 x 9 x n_gpt (0.2 MB for sw-g112). One longwave plus one
!> shortwave set at 128/112 g-points takes 24 MB (`kdist_memory_bytes`).
module kumo_gas_optics
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp, i8
  use kumo_error, only: error_t, set_error, str, to_lower
  implicit none
  private

  public :: gas_kdist_t, minor_table_t, GAS_NAME_LEN
  public :: gas_index, kdist_finish, kdist_memory_bytes
  public :: gas_optical_depth, gas_planck_source, gas_solar_source, gas_col_dry
  public :: AVOGADRO_CODATA, GRAVITY_STD, MOLAR_MASS_DRY, MOLAR_MASS_H2O
  public :: NRLSSI2_MG_OFFSET, NRLSSI2_SB_OFFSET
  public :: gas_default_vmr, rcemip_ozone

  integer, parameter :: GAS_NAME_LEN = 32          !! length of gas names in the files
  real(wp), parameter :: CM2_TO_M2 = 1.0e-4_wp     !! the tables are in cm2 per molecule
  real(wp), parameter :: PA_TO_HPA = 0.01_wp       !! the density scaling uses p in hPa
  real(wp), parameter :: AVOGADRO_CODATA = 6.02214076e23_wp  !! mol-1 (SI 2019, exact)
  real(wp), parameter :: GRAVITY_STD = 9.80665_wp            !! m s-2, standard gravity
  real(wp), parameter :: MOLAR_MASS_DRY = 28.9644e-3_wp      !! kg mol-1, dry air (US 1976)
  real(wp), parameter :: MOLAR_MASS_H2O = 18.0153e-3_wp      !! kg mol-1, water
  !> Offsets of the facular (Mg II index) and sunspot (sunspot darkening index) terms of the
  !> NRLSSI2 solar-variability model (Coddington et al. 2016, BAMS 97, 1265,
  !> doi:10.1175/BAMS-D-14-00265.1) as the RRTMGP shortwave files use them: with the files'
  !> `mg_default` and `sb_default` the three terms sum to their `tsi_default`.
  real(wp), parameter :: NRLSSI2_MG_OFFSET = 0.14959542_wp
  real(wp), parameter :: NRLSSI2_SB_OFFSET = 0.00066696_wp

  !> Minor absorbers of one atmosphere part (lower or upper): one entry per minor interval, a
  !> contiguous range of g-points of one band where one gas absorbs.
  type :: minor_table_t
    integer :: n = 0                                 !! number of minor intervals
    integer, allocatable :: gas(:)                   !! absorbing gas, index into gas_names
    integer, allocatable :: gpt(:, :)                !! (2, n) first and last g-point
    logical, allocatable :: scales_with_density(:)   !! multiply by p/T (p in hPa)
    integer, allocatable :: scaling_gas(:)           !! gas scaling the absorption, 0 for none
    logical, allocatable :: scale_by_complement(:)   !! scale by 1 - s instead of s
    integer, allocatable :: kstart(:)                !! contributor column of the first g-point
    real(wp), allocatable :: kminor(:, :, :)         !! (contributor, eta, temperature), cm2
    integer, allocatable :: band_first(:)            !! (n_band) first interval of each band
    integer, allocatable :: band_last(:)             !! (n_band) last interval (< first: none)
  end type minor_table_t

  !> One k-distribution (a longwave or a shortwave file). Filled by the reader in kumo_io
  !> (`kumo_rrtmgp_file`), then `kdist_finish` derives the index arrays and checks consistency.
  type :: gas_kdist_t
    character(len=:), allocatable :: source          !! where it was read from (for messages)
    logical :: longwave = .false.                    !! Planck tables present (else solar)
    integer :: n_gas = 0, n_band = 0, n_gpt = 0
    integer :: n_temp = 0, n_press = 0, n_eta = 0
    character(len=GAS_NAME_LEN), allocatable :: gas_names(:)   !! (n_gas) lower case
    integer, allocatable :: band_gpt(:, :)           !! (2, n_band) first, last g-point
    real(wp), allocatable :: band_wavenumber(:, :)   !! (2, n_band) cm-1
    integer, allocatable :: gpt_band(:)              !! (n_gpt) band of each g-point
    real(wp), allocatable :: temp_ref(:)             !! (n_temp) K, uniform
    real(wp), allocatable :: press_ref(:)            !! (n_press) Pa, uniform in ln p, decreasing
    real(wp) :: press_ref_trop = 0                   !! Pa, lower/upper atmosphere boundary
    integer, allocatable :: key_species(:, :, :)     !! (2, 2 parts, n_band), 0 = dry air
    real(wp), allocatable :: vmr_ref(:, :, :)        !! (2 parts, 0:n_gas, n_temp)
    real(wp), allocatable :: kmajor(:, :, :, :)      !! (n_gpt, n_eta, n_press+1, n_temp), cm2
    type(minor_table_t) :: minor(2)                  !! lower, upper
    real(wp), allocatable :: rayleigh(:, :, :, :)    !! (n_gpt, n_eta, n_temp, 2 parts), cm2; SW
    real(wp), allocatable :: planck_fraction(:, :, :, :)  !! like kmajor; LW
    real(wp), allocatable :: planck_band(:, :)       !! (n_temp_planck, n_band) W m-2 sr-1; LW
    real(wp), allocatable :: solar_quiet(:)          !! (n_gpt) W m-2; SW, quiet sun
    real(wp), allocatable :: solar_facular(:)        !! (n_gpt) W m-2 per unit Mg index; SW
    real(wp), allocatable :: solar_sunspot(:)        !! (n_gpt) W m-2 per unit SB index; SW
    real(wp) :: tsi_default = 0                      !! W m-2; SW
    real(wp) :: mg_default = 0, sb_default = 0       !! default solar indices; SW
    ! Derived by kdist_finish.
    real(wp) :: dtemp = 0, dlnp = 0, ln_press_ref1 = 0, dtemp_planck = 0
  end type gas_kdist_t

  !> Where a layer sits in the tables (computed once per layer).
  type :: locus_t
    integer :: it, ip, part            !! temperature and pressure interval, 1 lower / 2 upper
    real(wp) :: ft, fp                 !! fractions (unbounded outside the tables)
  end type locus_t

contains

  !> Index of gas `name` in `kd%gas_names` (case-insensitive), 0 if the file does not know it.
  pure integer function gas_index(kd, name) result(idx)
    type(gas_kdist_t), intent(in) :: kd
    character(len=*), intent(in) :: name
    integer :: i
    idx = 0
    do i = 1, kd%n_gas
      if (trim(kd%gas_names(i)) == to_lower(trim(adjustl(name)))) then
        idx = i
        return
      end if
    end do
  end function gas_index

  !> Derived quantities and consistency checks after the tables are filled.
  subroutine kdist_finish(kd, error)
    type(gas_kdist_t), intent(inout) :: kd
    type(error_t), allocatable, intent(out) :: error
    integer :: b, part, i, co2
    character(len=:), allocatable :: where

    where = 'gas optics tables'
    if (allocated(kd%source)) where = 'gas optics tables of ' // kd%source
    if (kd%n_temp < 2 .or. kd%n_press < 2 .or. kd%n_eta < 2) then
      call set_error(error, where // ': need at least 2 temperatures, pressures and eta nodes, got ' &
                     // str(kd%n_temp) // ', ' // str(kd%n_press) // ', ' // str(kd%n_eta))
      return
    end if
    if (any(kd%press_ref <= 0)) then
      call set_error(error, where // ': press_ref must be positive')
      return
    end if
    kd%dtemp = (kd%temp_ref(kd%n_temp) - kd%temp_ref(1)) / (kd%n_temp - 1)
    kd%ln_press_ref1 = log(kd%press_ref(1))
    kd%dlnp = (log(kd%press_ref(1)) - log(kd%press_ref(kd%n_press))) / (kd%n_press - 1)
    if (kd%dtemp <= 0 .or. kd%dlnp <= 0) then
      call set_error(error, where // ': temp_ref must increase and press_ref decrease')
      return
    end if
    if (kd%longwave) then
      if (size(kd%planck_band, 1) < 2) then
        call set_error(error, where // ': totplnk needs at least 2 temperatures')
        return
      end if
      kd%dtemp_planck = (kd%temp_ref(kd%n_temp) - kd%temp_ref(1)) / (size(kd%planck_band, 1) - 1)
    end if
    if (allocated(kd%gpt_band)) deallocate(kd%gpt_band)
    allocate(kd%gpt_band(kd%n_gpt), source=0)
    do b = 1, kd%n_band
      if (kd%band_gpt(1, b) < 1 .or. kd%band_gpt(2, b) > kd%n_gpt .or. &
          kd%band_gpt(1, b) > kd%band_gpt(2, b)) then
        call set_error(error, where // ': band ' // str(b) // ' has g-points ' // &
                       str(kd%band_gpt(1, b)) // '..' // str(kd%band_gpt(2, b)) // &
                       ', outside 1..' // str(kd%n_gpt))
        return
      end if
      kd%gpt_band(kd%band_gpt(1, b):kd%band_gpt(2, b)) = b
    end do
    if (any(kd%gpt_band == 0)) then
      call set_error(error, where // ': some g-points belong to no band')
      return
    end if
    if (any(kd%key_species < 0) .or. any(kd%key_species > kd%n_gas)) then
      call set_error(error, where // ': key_species outside 0..' // str(kd%n_gas))
      return
    end if
    ! A band part without key species (0, 0) takes CO2 for both, the convention of the RRTMGP
    ! tables (their kmajor vanishes there at the nodes atmospheric states reach).
    co2 = gas_index(kd, 'co2')
    do b = 1, kd%n_band
      do part = 1, 2
        if (all(kd%key_species(:, part, b) == 0) .and. co2 > 0) kd%key_species(:, part, b) = co2
      end do
    end do
    do part = 1, 2
      associate (m => kd%minor(part))
        if (allocated(m%band_first)) deallocate(m%band_first, m%band_last)
        allocate(m%band_first(kd%n_band), source=1)
        allocate(m%band_last(kd%n_band), source=0)
        do i = 1, m%n
          if (m%gpt(1, i) < 1 .or. m%gpt(2, i) > kd%n_gpt .or. m%gpt(1, i) > m%gpt(2, i)) then
            call set_error(error, where // ': minor interval ' // str(i) // ' has g-points ' // &
                           str(m%gpt(1, i)) // '..' // str(m%gpt(2, i)))
            return
          end if
          b = kd%gpt_band(m%gpt(1, i))
          if (kd%gpt_band(m%gpt(2, i)) /= b) then
            call set_error(error, where // ': minor interval ' // str(i) // ' spans two bands')
            return
          end if
          if (m%band_last(b) < m%band_first(b)) then
            m%band_first(b) = i
          else if (m%band_last(b) /= i - 1) then
            call set_error(error, where // ': the minor intervals of band ' // str(b) // &
                           ' are not contiguous')
            return
          end if
          m%band_last(b) = i
          if (m%gas(i) < 1 .or. m%gas(i) > kd%n_gas .or. m%scaling_gas(i) < 0 .or. &
              m%scaling_gas(i) > kd%n_gas) then
            call set_error(error, where // ': minor interval ' // str(i) // ' names an unknown gas')
            return
          end if
          if (m%kstart(i) < 1 .or. m%kstart(i) + m%gpt(2, i) - m%gpt(1, i) > size(m%kminor, 1)) then
            call set_error(error, where // ': minor interval ' // str(i) // ' has kminor_start ' // &
                           str(m%kstart(i)) // ' outside 1..' // str(size(m%kminor, 1)))
            return
          end if
        end do
      end associate
    end do
  end subroutine kdist_finish

  !> Bytes held by the tables of `kd`.
  pure function kdist_memory_bytes(kd) result(nbytes)
    type(gas_kdist_t), intent(in) :: kd
    integer(i8) :: nbytes
    integer :: part
    nbytes = 0
    if (allocated(kd%kmajor)) nbytes = nbytes + 8_i8 * size(kd%kmajor, kind=i8)
    if (allocated(kd%planck_fraction)) nbytes = nbytes + 8_i8 * size(kd%planck_fraction, kind=i8)
    if (allocated(kd%rayleigh)) nbytes = nbytes + 8_i8 * size(kd%rayleigh, kind=i8)
    if (allocated(kd%planck_band)) nbytes = nbytes + 8_i8 * size(kd%planck_band, kind=i8)
    if (allocated(kd%vmr_ref)) nbytes = nbytes + 8_i8 * size(kd%vmr_ref, kind=i8)
    do part = 1, 2
      if (allocated(kd%minor(part)%kminor)) then
        nbytes = nbytes + 8_i8 * size(kd%minor(part)%kminor, kind=i8)
      end if
    end do
  end function kdist_memory_bytes

  !> Absorption optical depth per g-point of a column of layers and, for a shortwave
  !> k-distribution, the Rayleigh optical depth.
  !>
  !> `vmr(layer, gas)` holds mixing ratios (mol/mol of dry air) in the order of `kd%gas_names`;
  !> gases the caller does not know are 0. Layers may be in any order (kumo: bottom to top).
  subroutine gas_optical_depth(kd, play, tlay, vmr, col_dry, tau, error, tau_rayleigh)
    type(gas_kdist_t), intent(in) :: kd
    real(wp), intent(in) :: play(:)          !! layer pressure, Pa
    real(wp), intent(in) :: tlay(:)          !! layer temperature, K
    real(wp), intent(in) :: vmr(:, :)        !! (n_layer, kd%n_gas) mol/mol of dry air
    real(wp), intent(in) :: col_dry(:)       !! dry-air column of each layer, molecules m-2
    real(wp), intent(out) :: tau(:, :)       !! (n_layer, kd%n_gpt) absorption optical depth
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(out), optional :: tau_rayleigh(:, :)  !! (n_layer, kd%n_gpt), shortwave only
    integer :: l, b, part, g, g1, g2, i, je(2), c, s, ih2o, jp, jt1, jt2
    type(locus_t) :: loc
    real(wp) :: wt(2), fe(2), mix(2), v(0:kd%n_gas), col, kk, scale, sgas, dry_fact
    real(wp) :: we(2, 2), w(4, 2), tg(kd%n_gpt), rg(kd%n_gpt)

    call check_column(kd, 'gas_optical_depth', play, tlay, vmr, col_dry, error)
    if (allocated(error)) return
    if (any(shape(tau) /= [size(play), kd%n_gpt])) then
      call set_error(error, 'gas_optical_depth: tau has shape ' // shape_text(shape(tau)) // &
                     ', expected ' // shape_text([size(play), kd%n_gpt]))
      return
    end if
    if (present(tau_rayleigh)) then
      if (kd%longwave) then
        call set_error(error, 'gas_optical_depth: Rayleigh optical depth asked of a longwave ' // &
                       'k-distribution')
        return
      end if
      if (any(shape(tau_rayleigh) /= [size(play), kd%n_gpt])) then
        call set_error(error, 'gas_optical_depth: tau_rayleigh has shape ' // &
                       shape_text(shape(tau_rayleigh)) // ', expected ' // &
                       shape_text([size(play), kd%n_gpt]))
        return
      end if
    end if
    ih2o = gas_index(kd, 'h2o')

    do l = 1, size(play)
      loc = locate(kd, play(l), tlay(l), clamp=.false.)
      part = loc%part
      jp = loc%ip + part - 1
      jt1 = loc%it
      jt2 = loc%it + 1
      wt = [1 - loc%ft, loc%ft]
      v(0) = 1
      v(1:) = vmr(l, :)
      col = col_dry(l) * CM2_TO_M2
      dry_fact = 1
      if (ih2o > 0) dry_fact = 1 / (1 + v(ih2o))
      do b = 1, kd%n_band
        g1 = kd%band_gpt(1, b)
        g2 = kd%band_gpt(2, b)
        call binary_mixing(kd, loc, b, v, mix, je, fe)
        ! Weights of the eta nodes at each temperature node.
        we(1, :) = wt * (1 - fe)
        we(2, :) = wt * fe
        ! Major species: trilinear in eta, ln p (and T), weighted by r1 + R r2 at each T node.
        w(:, 1) = mix(1) * [we(1, 1) * (1 - loc%fp), we(1, 1) * loc%fp, &
                            we(2, 1) * (1 - loc%fp), we(2, 1) * loc%fp]
        w(:, 2) = mix(2) * [we(1, 2) * (1 - loc%fp), we(1, 2) * loc%fp, &
                            we(2, 2) * (1 - loc%fp), we(2, 2) * loc%fp]
        do g = g1, g2
          kk = w(1, 1) * kd%kmajor(g, je(1), jp, jt1) + w(2, 1) * kd%kmajor(g, je(1), jp + 1, jt1) &
               + w(3, 1) * kd%kmajor(g, je(1) + 1, jp, jt1) &
               + w(4, 1) * kd%kmajor(g, je(1) + 1, jp + 1, jt1) &
               + w(1, 2) * kd%kmajor(g, je(2), jp, jt2) + w(2, 2) * kd%kmajor(g, je(2), jp + 1, jt2) &
               + w(3, 2) * kd%kmajor(g, je(2) + 1, jp, jt2) &
               + w(4, 2) * kd%kmajor(g, je(2) + 1, jp + 1, jt2)
          tg(g) = col * max(kk, 0.0_wp)
        end do
        ! Minor absorbers of this band and atmosphere part: bilinear in eta and T.
        associate (m => kd%minor(part))
          do i = m%band_first(b), m%band_last(b)
            scale = col * v(m%gas(i))
            if (m%scales_with_density(i)) then
              scale = scale * PA_TO_HPA * play(l) / tlay(l)
              s = m%scaling_gas(i)
              if (s > 0) then
                sgas = v(s) * dry_fact
                if (m%scale_by_complement(i)) sgas = 1 - sgas
                scale = scale * sgas
              end if
            end if
            c = m%kstart(i) - m%gpt(1, i)
            do g = m%gpt(1, i), m%gpt(2, i)
              kk = we(1, 1) * m%kminor(c + g, je(1), jt1) + we(2, 1) * m%kminor(c + g, je(1) + 1, jt1) &
                   + we(1, 2) * m%kminor(c + g, je(2), jt2) + we(2, 2) * m%kminor(c + g, je(2) + 1, jt2)
              tg(g) = tg(g) + scale * max(kk, 0.0_wp)
            end do
          end do
        end associate
        ! Rayleigh scattering (shortwave tables).
        if (present(tau_rayleigh)) then
          scale = col
          if (ih2o > 0) scale = col * (1 + v(ih2o))
          do g = g1, g2
            kk = we(1, 1) * kd%rayleigh(g, je(1), jt1, part) + we(2, 1) * kd%rayleigh(g, je(1) + 1, jt1, part) &
                 + we(1, 2) * kd%rayleigh(g, je(2), jt2, part) &
                 + we(2, 2) * kd%rayleigh(g, je(2) + 1, jt2, part)
            rg(g) = scale * max(kk, 0.0_wp)
          end do
        end if
      end do
      tau(l, :) = tg
      if (present(tau_rayleigh)) tau_rayleigh(l, :) = rg
    end do
  end subroutine gas_optical_depth

  !> Longwave Planck sources per g-point (radiances, W m-2 sr-1): in each layer at the layer
  !> temperature, at the bottom and top of each layer at the level temperatures (with the layer's
  !> Planck fractions), and at the surface temperature (with the lowest layer's fractions).
  !> Levels are numbered 0..n_layer from the bottom, as kumo's layers.
  subroutine gas_planck_source(kd, play, tlay, tlev, tsfc, vmr, lay_src, lev_src_bot, &
                               lev_src_top, sfc_src, error)
    type(gas_kdist_t), intent(in) :: kd
    real(wp), intent(in) :: play(:)          !! layer pressure, Pa (layer 1 at the bottom)
    real(wp), intent(in) :: tlay(:)          !! layer temperature, K
    real(wp), intent(in) :: tlev(0:)         !! level temperature, K; tlev(0) bottom of layer 1
    real(wp), intent(in) :: tsfc             !! surface temperature, K
    real(wp), intent(in) :: vmr(:, :)        !! (n_layer, kd%n_gas) mol/mol of dry air
    real(wp), intent(out) :: lay_src(:, :)      !! (n_layer, n_gpt) source at tlay
    real(wp), intent(out) :: lev_src_bot(:, :)  !! (n_layer, n_gpt) source at tlev(l-1)
    real(wp), intent(out) :: lev_src_top(:, :)  !! (n_layer, n_gpt) source at tlev(l)
    real(wp), intent(out) :: sfc_src(:)         !! (n_gpt) source at tsfc
    type(error_t), allocatable, intent(out) :: error
    integer :: l, b, g, k, je(2), nl
    type(locus_t) :: loc
    real(wp) :: wt(2), fe(2), mix(2), v(0:kd%n_gas), pf, blay, bbot, btop, bsfc
    real(wp) :: col1(size(play))

    nl = size(play)
    if (.not. kd%longwave) then
      call set_error(error, 'gas_planck_source: the k-distribution has no Planck tables ' // &
                     '(a shortwave file?)')
      return
    end if
    col1 = 1
    call check_column(kd, 'gas_planck_source', play, tlay, vmr, col1, error)
    if (allocated(error)) return
    if (size(tlev) /= nl + 1) then
      call set_error(error, 'gas_planck_source: tlev has ' // str(size(tlev)) // &
                     ' levels, expected ' // str(nl + 1))
      return
    end if
    if (.not. all(ieee_is_finite(tlev)) .or. any(tlev <= 0) .or. .not. ieee_is_finite(tsfc) &
        .or. tsfc <= 0) then
      call set_error(error, 'gas_planck_source: level and surface temperatures must be ' // &
                     'positive and finite')
      return
    end if
    if (any(shape(lay_src) /= [nl, kd%n_gpt]) .or. any(shape(lev_src_bot) /= [nl, kd%n_gpt]) &
        .or. any(shape(lev_src_top) /= [nl, kd%n_gpt]) .or. size(sfc_src) /= kd%n_gpt) then
      call set_error(error, 'gas_planck_source: source arrays must be ' // &
                     shape_text([nl, kd%n_gpt]) // ' and (' // str(kd%n_gpt) // ')')
      return
    end if

    do l = 1, nl
      loc = locate(kd, play(l), tlay(l), clamp=.true.)
      wt = [1 - loc%ft, loc%ft]
      v(0) = 1
      v(1:) = vmr(l, :)
      do b = 1, kd%n_band
        call binary_mixing(kd, loc, b, v, mix, je, fe)
        blay = planck_band(kd, b, tlay(l))
        bbot = planck_band(kd, b, tlev(l - 1))
        btop = planck_band(kd, b, tlev(l))
        if (l == 1) bsfc = planck_band(kd, b, tsfc)
        do g = kd%band_gpt(1, b), kd%band_gpt(2, b)
          pf = 0
          do k = 1, 2
            pf = pf + wt(k) * interp_ep(kd%planck_fraction, g, je(k), fe(k), &
                                          loc%ip + loc%part - 1, loc%fp, loc%it + k - 1)
          end do
          lay_src(l, g) = pf * blay
          lev_src_bot(l, g) = pf * bbot
          lev_src_top(l, g) = pf * btop
          if (l == 1) sfc_src(g) = pf * bsfc
        end do
      end do
    end do
  end subroutine gas_planck_source

  !> Solar irradiance at the top of the atmosphere per g-point (W m-2, on a surface normal to
  !> the beam): the quiet-sun spectrum of the file scaled to sum to `tsi` (W m-2; the file's
  !> `tsi_default` when absent). With `mg_index` or `sb_index` (the other one then takes the
  !> file's default, `kd%mg_default` or `kd%sb_default`) the spectrum is that of the NRLSSI2
  !> model, quiet + (mg_index - NRLSSI2_MG_OFFSET) facular + (sb_index - NRLSSI2_SB_OFFSET)
  !> sunspot, before the scaling.
  subroutine gas_solar_source(kd, src, error, tsi, mg_index, sb_index)
    type(gas_kdist_t), intent(in) :: kd
    real(wp), intent(out) :: src(:)          !! (n_gpt) W m-2
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: tsi    !! total solar irradiance, W m-2
    real(wp), intent(in), optional :: mg_index  !! NRLSSI2 facular (Mg II) index
    real(wp), intent(in), optional :: sb_index  !! NRLSSI2 sunspot darkening index
    real(wp) :: total, mg, sb
    if (.not. allocated(kd%solar_quiet)) then
      call set_error(error, 'gas_solar_source: the k-distribution has no solar source ' // &
                     '(a longwave file?)')
      return
    end if
    if (size(src) /= kd%n_gpt) then
      call set_error(error, 'gas_solar_source: src has ' // str(size(src)) // &
                     ' elements, expected ' // str(kd%n_gpt))
      return
    end if
    total = kd%tsi_default
    if (present(tsi)) total = tsi
    if (.not. ieee_is_finite(total) .or. total < 0) then
      call set_error(error, 'gas_solar_source: tsi = ' // str(total) // ' must be >= 0')
      return
    end if
    if (present(mg_index) .or. present(sb_index)) then
      mg = kd%mg_default
      sb = kd%sb_default
      if (present(mg_index)) mg = mg_index
      if (present(sb_index)) sb = sb_index
      if (.not. allocated(kd%solar_facular) .or. .not. allocated(kd%solar_sunspot)) then
        call set_error(error, 'gas_solar_source: the k-distribution has no facular and sunspot ' &
                       // 'terms')
        return
      end if
      src = kd%solar_quiet + (mg - NRLSSI2_MG_OFFSET) * kd%solar_facular &
            + (sb - NRLSSI2_SB_OFFSET) * kd%solar_sunspot
      if (any(src < 0) .or. .not. all(ieee_is_finite(src))) then
        call set_error(error, 'gas_solar_source: mg_index = ' // str(mg) // ' and sb_index = ' // &
                       str(sb) // ' give a negative solar source')
        return
      end if
    else
      src = kd%solar_quiet
    end if
    src = total * src / sum(src)
  end subroutine gas_solar_source

  !> Dry-air column of each layer between pressure levels, molecules m-2, for a hydrostatic layer
  !> of dry air and water vapour: N_A (p_bottom - p_top) / (g (M_d + M_w r_w)), r_w the
  !> water-vapour volume mixing ratio relative to dry air.
  subroutine gas_col_dry(plev, vmr_h2o, col_dry, error, gravity)
    real(wp), intent(in) :: plev(0:)         !! level pressure, Pa; plev(0) bottom of layer 1
    real(wp), intent(in) :: vmr_h2o(:)       !! (n_layer) mol/mol of dry air
    real(wp), intent(out) :: col_dry(:)      !! (n_layer) molecules m-2
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: gravity  !! m s-2 (default GRAVITY_STD)
    real(wp) :: g
    integer :: l, nl
    nl = size(vmr_h2o)
    g = GRAVITY_STD
    if (present(gravity)) g = gravity
    if (size(plev) /= nl + 1 .or. size(col_dry) /= nl) then
      call set_error(error, 'gas_col_dry: ' // str(nl) // ' layers need ' // str(nl + 1) // &
                     ' levels and ' // str(nl) // ' outputs, got ' // str(size(plev)) // ' and ' // &
                     str(size(col_dry)))
      return
    end if
    if (.not. ieee_is_finite(g) .or. g <= 0) then
      call set_error(error, 'gas_col_dry: gravity = ' // str(g) // ' m s-2, must be > 0')
      return
    end if
    do l = 1, nl
      if (.not. (plev(l - 1) > plev(l) .and. plev(l) >= 0) .or. .not. ieee_is_finite(plev(l - 1))) then
        call set_error(error, 'gas_col_dry: level pressures must decrease upwards and be >= 0; ' // &
                       'levels ' // str(l - 1) // ', ' // str(l) // ': ' // str(plev(l - 1)) // &
                       ', ' // str(plev(l)) // ' Pa')
        return
      end if
      if (.not. ieee_is_finite(vmr_h2o(l)) .or. vmr_h2o(l) < 0) then
        call set_error(error, 'gas_col_dry: layer ' // str(l) // ' water vapour = ' // &
                       str(vmr_h2o(l)) // ', must be >= 0')
        return
      end if
      col_dry(l) = AVOGADRO_CODATA * (plev(l - 1) - plev(l)) / &
                   (g * (MOLAR_MASS_DRY + MOLAR_MASS_H2O * vmr_h2o(l)))
    end do
  end subroutine gas_col_dry

  !> Default mixing ratios (mol/mol of dry air) of every gas except water vapour, which the
  !> caller supplies: the well-mixed gases at the present-day global means of RFMIP (experiment
  !> "present day", year 2014; Pincus, Forster and Stevens 2016, GMD 9, 3447, concentrations of
  !> Meinshausen et al. 2017, GMD 10, 2057), ozone from the RCEMIP profile (`rcemip_ozone`),
  !> NO2 zero. Columns of gases the file does not know are left alone.
  subroutine gas_default_vmr(kd, play, vmr, error)
    type(gas_kdist_t), intent(in) :: kd
    real(wp), intent(in) :: play(:)          !! layer pressure, Pa
    real(wp), intent(inout) :: vmr(:, :)     !! (n_layer, kd%n_gas); the h2o column is kept
    type(error_t), allocatable, intent(out) :: error
    character(len=8), parameter :: NAMES(17) = [character(len=8) :: 'co2', 'n2o', 'co', 'ch4', &
      'o2', 'n2', 'ccl4', 'cfc11', 'cfc12', 'cfc22', 'hfc143a', 'hfc125', 'hfc23', 'hfc32', &
      'hfc134a', 'cf4', 'no2']
    real(wp), parameter :: VALUES(17) = [397.547e-6_wp, 326.988e-9_wp, 120.0e-9_wp, &
      1831.471e-9_wp, 0.209_wp, 0.781_wp, 83.06993e-12_wp, 233.0799e-12_wp, 520.5810e-12_wp, &
      229.5421e-12_wp, 15.25278e-12_wp, 15.355e-12_wp, 26.89044e-12_wp, 8.336969e-12_wp, &
      80.51573e-12_wp, 81.09249e-12_wp, 0.0_wp]
    integer :: i, j
    if (size(vmr, 1) /= size(play) .or. size(vmr, 2) /= kd%n_gas) then
      call set_error(error, 'gas_default_vmr: vmr has shape ' // shape_text(shape(vmr)) // &
                     ', expected ' // shape_text([size(play), kd%n_gas]))
      return
    end if
    if (any(.not. ieee_is_finite(play)) .or. any(play <= 0)) then
      call set_error(error, 'gas_default_vmr: layer pressures must be positive')
      return
    end if
    do i = 1, size(NAMES)
      j = gas_index(kd, NAMES(i))
      if (j > 0) vmr(:, j) = VALUES(i)
    end do
    j = gas_index(kd, 'o3')
    if (j > 0) vmr(:, j) = rcemip_ozone(play)
  end subroutine gas_default_vmr

  !> Ozone mixing ratio of RCEMIP (Wing et al. 2018, GMD 11, 793, doi:10.5194/gmd-11-793-2018,
  !> their analytic fit to a tropical profile): 3.6478 p^0.83209 exp(-p/11.3515) ppmv, p in hPa.
  elemental real(wp) function rcemip_ozone(p) result(o3)
    real(wp), intent(in) :: p                !! pressure, Pa
    real(wp) :: ph
    ph = p * PA_TO_HPA
    o3 = 3.6478e-6_wp * ph**0.83209_wp * exp(-ph / 11.3515_wp)
  end function rcemip_ozone

  ! ---------------------------------------------------------------------------------------------

  !> Temperature and ln p intervals and fractions of a layer; which atmosphere part it is in.
  !> With `clamp` the fractions are limited to [0, 1] (held at the end of the table).
  pure function locate(kd, p, t, clamp) result(loc)
    type(gas_kdist_t), intent(in) :: kd
    real(wp), intent(in) :: p, t
    logical, intent(in) :: clamp
    type(locus_t) :: loc
    real(wp) :: x
    x = (t - kd%temp_ref(1)) / kd%dtemp
    loc%it = min(max(floor(x) + 1, 1), kd%n_temp - 1)
    loc%ft = x - (loc%it - 1)
    x = (kd%ln_press_ref1 - log(p)) / kd%dlnp
    loc%ip = min(max(floor(x) + 1, 1), kd%n_press - 1)
    loc%fp = x - (loc%ip - 1)
    if (clamp) then
      loc%ft = min(max(loc%ft, 0.0_wp), 1.0_wp)
      loc%fp = min(max(loc%fp, 0.0_wp), 1.0_wp)
    end if
    loc%part = 1
    if (p <= kd%press_ref_trop) loc%part = 2
  end function locate

  !> Binary-mixing weight (r1 + R r2), eta interval and fraction at the two temperature nodes.
  pure subroutine binary_mixing(kd, loc, b, v, mix, je, fe)
    type(gas_kdist_t), intent(in) :: kd
    type(locus_t), intent(in) :: loc
    integer, intent(in) :: b
    real(wp), intent(in) :: v(0:)
    real(wp), intent(out) :: mix(2), fe(2)
    integer, intent(out) :: je(2)
    integer :: k, s1, s2, jt
    real(wp) :: ratio, eta, x
    s1 = kd%key_species(1, loc%part, b)
    s2 = kd%key_species(2, loc%part, b)
    do k = 1, 2
      jt = loc%it + k - 1
      ratio = kd%vmr_ref(loc%part, s1, jt) / kd%vmr_ref(loc%part, s2, jt)
      mix(k) = v(s1) + ratio * v(s2)
      eta = 0.5_wp
      if (mix(k) > 0) eta = v(s1) / mix(k)
      x = eta * (kd%n_eta - 1)
      je(k) = min(max(floor(x) + 1, 1), kd%n_eta - 1)
      fe(k) = x - (je(k) - 1)
    end do
  end subroutine binary_mixing

  !> Bilinear interpolation of table(g, eta, p, T) in eta and p at one temperature node.
  pure real(wp) function interp_ep(table, g, je, fe, jp, fp, jt) result(val)
    real(wp), intent(in) :: table(:, :, :, :)
    integer, intent(in) :: g, je, jp, jt
    real(wp), intent(in) :: fe, fp
    val = (1 - fe) * ((1 - fp) * table(g, je, jp, jt) + fp * table(g, je, jp + 1, jt)) &
          + fe * ((1 - fp) * table(g, je + 1, jp, jt) + fp * table(g, je + 1, jp + 1, jt))
  end function interp_ep

  !> Band-integrated Planck radiance of band b at temperature t, W m-2 sr-1 (linear in t,
  !> extended along the end interval outside the table, floored at zero).
  pure real(wp) function planck_band(kd, b, t) result(val)
    type(gas_kdist_t), intent(in) :: kd
    integer, intent(in) :: b
    real(wp), intent(in) :: t
    integer :: j, n
    real(wp) :: x
    n = size(kd%planck_band, 1)
    x = (t - kd%temp_ref(1)) / kd%dtemp_planck
    j = min(max(floor(x) + 1, 1), n - 1)
    x = x - (j - 1)
    val = max((1 - x) * kd%planck_band(j, b) + x * kd%planck_band(j + 1, b), 0.0_wp)
  end function planck_band

  !> Shared input checks of a column.
  subroutine check_column(kd, routine, play, tlay, vmr, col_dry, error)
    type(gas_kdist_t), intent(in) :: kd
    character(len=*), intent(in) :: routine
    real(wp), intent(in) :: play(:), tlay(:), vmr(:, :), col_dry(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: nl, l
    nl = size(play)
    if (.not. allocated(kd%kmajor) .or. .not. allocated(kd%gpt_band)) then
      call set_error(error, routine // ': the k-distribution is not loaded (kdist_finish not called)')
      return
    end if
    if (size(tlay) /= nl .or. size(col_dry) /= nl .or. size(vmr, 1) /= nl .or. &
        size(vmr, 2) /= kd%n_gas) then
      call set_error(error, routine // ': inputs for ' // str(nl) // ' layers: tlay has ' // &
                     str(size(tlay)) // ', col_dry ' // str(size(col_dry)) // ', vmr ' // &
                     shape_text(shape(vmr)) // ' (expected ' // shape_text([nl, kd%n_gas]) // ')')
      return
    end if
    do l = 1, nl
      if (.not. ieee_is_finite(play(l)) .or. play(l) <= 0) then
        call set_error(error, routine // ': layer ' // str(l) // ' pressure = ' // str(play(l)) // &
                       ' Pa, must be > 0')
        return
      end if
      if (.not. ieee_is_finite(tlay(l)) .or. tlay(l) <= 0) then
        call set_error(error, routine // ': layer ' // str(l) // ' temperature = ' // &
                       str(tlay(l)) // ' K, must be > 0')
        return
      end if
      if (.not. ieee_is_finite(col_dry(l)) .or. col_dry(l) < 0) then
        call set_error(error, routine // ': layer ' // str(l) // ' dry-air column = ' // &
                       str(col_dry(l)) // ' molecules m-2, must be >= 0')
        return
      end if
      if (.not. all(ieee_is_finite(vmr(l, :))) .or. any(vmr(l, :) < 0)) then
        call set_error(error, routine // ': layer ' // str(l) // ' has a negative or ' // &
                       'non-finite volume mixing ratio (' // trim(kd%gas_names(minloc(vmr(l, :), 1))) &
                       // ' = ' // str(minval(vmr(l, :))) // ')')
        return
      end if
    end do
  end subroutine check_column

  pure function shape_text(s) result(text)
    integer, intent(in) :: s(:)
    character(len=:), allocatable :: text
    integer :: i
    text = '('
    do i = 1, size(s)
      text = text // str(s(i))
      if (i < size(s)) text = text // ', '
    end do
    text = text // ')'
  end function shape_text

end module kumo_gas_optics
