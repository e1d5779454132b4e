! SPDX-License-Identifier: BSD-3-Clause
!> kumo's own liquid-cloud optics per spectral band: Mie tables (kumo_mie, docs/mie.md) averaged
!> over each band's wavenumber interval with a source weighting. See docs/cloud-optics-bands.md.
!>
!> For band [nu1, nu2] the interval is cut into n_b equal parts and the Mie table of the
!> size distributions is computed at each part's midpoint nu_j (wavelength 1e4/nu_j um,
!> refractive index of water from kumo_water_index). With the source weight
!> w_j = B_nu(nu_j, T_source) dnu (Planck's function per wavenumber) and the per-node values
!> k_j (extinction per liquid water content), w_j, g_j, P_j:
!>
!>     k   = sum w_j k_j / sum w_j                         (extinction: source-weighted mean)
!>     ssa = sum w_j k_j ssa_j / sum w_j k_j               (weighted by extinction)
!>     g   = sum w_j k_j ssa_j g_j / sum w_j k_j ssa_j     (weighted by scattering)
!>     P   = sum w_j k_j ssa_j P_j / sum w_j k_j ssa_j     (weighted by scattering)
!>
!> so that a band-averaged medium removes, scatters and redistributes the source-weighted
!> energy of the band like the spectrally resolved medium in the optically thin limit. The
!> weights are chosen by `t_source_k`: longwave bands use the Planck function at the cloud's
!> temperature (kumo's default T_CLOUD_K = 280 K), shortwave bands the Planck function of the
!> Sun's effective temperature, T_SUN_K = 5772 K (IAU 2015 Resolution B3, the nominal solar
!> effective temperature; Prsa et al. 2016, Astron. J. 152, 41, doi:10.3847/0004-6256/152/2/41),
!> since the k-distribution files give the solar source per g-point but not its shape within a
!> band. Parts of a band outside the refractive-index table (0.2 to 200 um, i.e. 50 to
!> 50000 cm-1) are left out of the average; `wn_lo_used`, `wn_hi_used` record what was used.
!>
!> The number of parts is n_b = max(n, ceiling(n ln(nu2/nu1)/0.3)) for the requested n, so wide
!> bands get more nodes: with 8 equal nodes the solar-weighted ssa of the 820-2680 cm-1 band was
!> 0.015 off, with the rule's 32 it agrees with 64 nodes to 1e-4. With n = 8 the averages of the
!> RRTMGP bands move by at most 1.1e-3 when n is doubled (docs/cloud-optics-bands.md).
module kumo_band_mie
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str
  use kumo_mie, only: mie_table_t, mie_table_build, DIST_GAMMA, DLNR_DEFAULT
  use kumo_water_index, only: water_index, water_index_range
  use kumo_planck, only: planck_wavenumber
  implicit none
  private

  public :: band_mie_t, band_mie_build, band_mie_table, T_SUN_K, T_CLOUD_K, T_FLAT

  !> Effective temperature of the Sun [K] (IAU 2015 Resolution B3).
  real(wp), parameter :: T_SUN_K = 5772.0_wp
  !> Default source temperature of longwave band averages [K], a typical liquid-cloud temperature.
  real(wp), parameter :: T_CLOUD_K = 280.0_wp
  !> `t_source_k` value that selects equal weights per wavenumber instead of a Planck function.
  real(wp), parameter :: T_FLAT = 0.0_wp
  !> Bands wider than this in ln(wavenumber) get proportionally more nodes.
  real(wp), parameter :: LN_NU_SCALE = 0.3_wp

  !> Band-averaged optics of liquid clouds for a list of effective radii.
  type :: band_mie_t
    integer :: nband = 0                      !! number of bands
    integer :: n_nodes = 0                    !! requested nodes per band (n above)
    integer, allocatable :: nodes(:)          !! nodes used per band (n_b above)
    integer :: dist = DIST_GAMMA              !! size distribution (kumo_mie kind code)
    real(wp) :: v_eff = 0.0_wp                !! effective variance
    real(wp) :: t_source_k = 0.0_wp           !! temperature of the Planck weighting [K]
    real(wp) :: dlnr = DLNR_DEFAULT           !! phase-function radius step in ln r
    real(wp), allocatable :: wn_lo(:)         !! band lower limit [cm-1]
    real(wp), allocatable :: wn_hi(:)         !! band upper limit [cm-1]
    real(wp), allocatable :: wn_lo_used(:)    !! lower limit of the averaged part [cm-1]
    real(wp), allocatable :: wn_hi_used(:)    !! upper limit of the averaged part [cm-1]
    real(wp), allocatable :: r_eff_um(:)      !! effective radii [um]
    real(wp), allocatable :: ext_per_lwc(:, :)  !! (radius, band) [m2 g-1] = [m-1 / (g m-3)]
    real(wp), allocatable :: ssa(:, :)        !! (radius, band) single-scattering albedo
    real(wp), allocatable :: g(:, :)          !! (radius, band) asymmetry parameter
    real(wp), allocatable :: angle_deg(:)     !! scattering angles [deg] (kumo_mie's grid)
    real(wp), allocatable :: phase(:, :, :)   !! (angle, radius, band), (1/2) Int P dmu = 1
  end type band_mie_t

contains

  !> Band averages of the Mie tables of `r_eff_um` (strictly increasing) for the bands
  !> [wn_lo(b), wn_hi(b)] cm-1, with at least `n_nodes` midpoint nodes per band (more in wide
  !> bands, see the module description) and Planck weighting at
  !> `t_source_k` (see the module description; T_FLAT = 0 weights all wavenumbers equally, for
  !> comparisons). `dist` and `v_eff` as kumo_mie (kumo's default:
  !> DIST_GAMMA, v_eff = 0.1); `dlnr` the phase-function radius step (DLNR_DEFAULT).
  subroutine band_mie_build(wn_lo, wn_hi, t_source_k, dist, v_eff, r_eff_um, n_nodes, table, &
                            error, dlnr)
    real(wp), intent(in) :: wn_lo(:), wn_hi(:)   !! band limits [cm-1]
    real(wp), intent(in) :: t_source_k           !! source temperature of the weights [K]
    integer, intent(in) :: dist                  !! DIST_GAMMA or DIST_LOGNORMAL
    real(wp), intent(in) :: v_eff                !! effective variance
    real(wp), intent(in) :: r_eff_um(:)          !! effective radii [um]
    integer, intent(in) :: n_nodes               !! wavenumber nodes per band, >= 1
    type(band_mie_t), intent(out) :: table
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: dlnr       !! phase-function step in ln r
    character(len=*), parameter :: CTX = 'band_mie_build: '
    type(mie_table_t) :: mono
    real(wp), allocatable :: sw(:), swk(:), swks(:)
    real(wp) :: wl_min, wl_max, nu_min, nu_max, lo, hi, dnu, nu, w, step
    complex(wp) :: m
    integer :: nb, nr, b, j, i, nn

    step = DLNR_DEFAULT
    if (present(dlnr)) step = dlnr
    nb = size(wn_lo)
    nr = size(r_eff_um)
    if (nb < 1 .or. size(wn_hi) /= nb) then
      call set_error(error, CTX//'band limits: '//str(size(wn_lo))//' lower and '// &
                     str(size(wn_hi))//' upper limits; need the same number >= 1')
      return
    end if
    if (n_nodes < 1) then
      call set_error(error, CTX//'n_nodes = '//str(n_nodes)//' must be >= 1')
      return
    end if
    if (.not. (t_source_k >= 0.0_wp .and. t_source_k < 1.0e5_wp)) then
      call set_error(error, CTX//'t_source_k = '//str(t_source_k)//' K must be within [0, 1e5)')
      return
    end if
    if (nr < 1) then
      call set_error(error, CTX//'at least one effective radius is needed')
      return
    end if
    call water_index_range(wl_min, wl_max)
    nu_min = 1.0e4_wp/wl_max
    nu_max = 1.0e4_wp/wl_min

    table%nband = nb
    table%n_nodes = n_nodes
    table%dist = dist
    table%v_eff = v_eff
    table%t_source_k = t_source_k
    table%dlnr = step
    table%wn_lo = wn_lo
    table%wn_hi = wn_hi
    table%r_eff_um = r_eff_um
    allocate (table%wn_lo_used(nb), table%wn_hi_used(nb), table%nodes(nb))
    allocate (table%ext_per_lwc(nr, nb), table%ssa(nr, nb), table%g(nr, nb), source=0.0_wp)
    allocate (sw(nr), swk(nr), swks(nr))

    do b = 1, nb
      if (.not. (wn_lo(b) >= 0.0_wp .and. wn_hi(b) > wn_lo(b))) then
        call set_error(error, CTX//'band '//str(b)//' has limits '//str(wn_lo(b))//' to '// &
                       str(wn_hi(b))//' cm-1; need 0 <= lower < upper')
        return
      end if
      lo = max(wn_lo(b), nu_min)
      hi = min(wn_hi(b), nu_max)
      if (.not. (hi > lo)) then
        call set_error(error, CTX//'band '//str(b)//' ('//str(wn_lo(b))//' to '//str(wn_hi(b))// &
                       ' cm-1) lies outside the refractive index table of water ('// &
                       str(nu_min)//' to '//str(nu_max)//' cm-1)')
        return
      end if
      table%wn_lo_used(b) = lo
      table%wn_hi_used(b) = hi
      nn = max(n_nodes, ceiling(n_nodes*log(hi/lo)/LN_NU_SCALE))
      table%nodes(b) = nn
      dnu = (hi - lo)/real(nn, wp)
      sw = 0.0_wp
      swk = 0.0_wp
      swks = 0.0_wp
      do j = 1, nn
        nu = lo + (real(j, wp) - 0.5_wp)*dnu
        call water_index(1.0e4_wp/nu, m, error)
        if (.not. allocated(error)) then
          call mie_table_build(1.0e4_wp/nu, m, dist, v_eff, r_eff_um, mono, error, dlnr=step)
        end if
        if (allocated(error)) then
          error%message = CTX//'band '//str(b)//', '//str(nu)//' cm-1: '//error%message
          return
        end if
        if (.not. allocated(table%phase)) then
          table%angle_deg = mono%angle_deg
          allocate (table%phase(size(mono%angle_deg), nr, nb), source=0.0_wp)
        end if
        if (t_source_k > 0.0_wp) then
          w = planck_wavenumber(nu, t_source_k)*dnu
        else
          w = dnu
        end if
        do i = 1, nr
          sw(i) = sw(i) + w
          swk(i) = swk(i) + w*mono%ext_per_lwc(i)
          swks(i) = swks(i) + w*mono%ext_per_lwc(i)*mono%ssa(i)
          table%g(i, b) = table%g(i, b) + w*mono%ext_per_lwc(i)*mono%ssa(i)*mono%g(i)
          table%phase(:, i, b) = table%phase(:, i, b) + &
                                 (w*mono%ext_per_lwc(i)*mono%ssa(i))*mono%phase(:, i)
        end do
      end do
      if (.not. (minval(sw) > 0.0_wp)) then
        call set_error(error, CTX//'band '//str(b)//': the Planck weight at '//str(t_source_k)// &
                       ' K underflows over '//str(lo)//' to '//str(hi)//' cm-1')
        return
      end if
      table%ext_per_lwc(:, b) = swk/sw
      table%ssa(:, b) = min(1.0_wp, swks/swk)
      table%g(:, b) = table%g(:, b)/swks
      do i = 1, nr
        table%phase(:, i, b) = table%phase(:, i, b)/swks(i)
      end do
    end do
  end subroutine band_mie_build

  !> Band `band` of `bm` as a one-wavelength `mie_table_t`, so the tools of kumo_mie
  !> (mie_table_bracket) and kumo_phase (phase_from_table) apply to it. Its `wavelength_um` is
  !> the band centre's and `m` the refractive index there: labels only, the values are the
  !> band averages.
  subroutine band_mie_table(bm, band, table, error)
    type(band_mie_t), intent(in) :: bm
    integer, intent(in) :: band
    type(mie_table_t), intent(out) :: table
    type(error_t), allocatable, intent(out) :: error
    complex(wp) :: m
    if (band < 1 .or. band > bm%nband) then
      call set_error(error, 'band_mie_table: band = '//str(band)//' must be within 1 ... '// &
                     str(bm%nband))
      return
    end if
    table%wavelength_um = 2.0e4_wp/(bm%wn_lo_used(band) + bm%wn_hi_used(band))
    call water_index(table%wavelength_um, m, error)
    if (allocated(error)) return
    table%m = m
    table%dist = bm%dist
    table%v_eff = bm%v_eff
    table%dlnr = bm%dlnr
    table%r_eff_um = bm%r_eff_um
    table%ext_per_lwc = bm%ext_per_lwc(:, band)
    table%ssa = bm%ssa(:, band)
    table%g = bm%g(:, band)
    table%angle_deg = bm%angle_deg
    table%phase = bm%phase(:, :, band)
  end subroutine band_mie_table

end module kumo_band_mie
