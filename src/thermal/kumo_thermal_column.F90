! SPDX-License-Identifier: BSD-3-Clause
!> Exact thermal radiation of a plane-parallel, non-scattering (purely absorbing and emitting)
!> layered atmosphere: fluxes, radiances and flux divergences in closed form.
!>
!> The column has nz layers numbered 1..nz from the bottom, levels 0..nz (level 0 = surface,
!> level nz = top). Layer k lies between levels k-1 and k and has absorption optical depth
!> tau(k) >= 0. The Planck radiance B varies linearly in optical depth inside each layer between
!> the level values b(k-1) and b(k) (the convention of DISORT, Stamnes et al. 1988, Appl. Opt.
!> 27, 2502), which keeps optically thick layers right. The boundaries:
!>
!> * top: an isotropic downward radiance i_top (sky or emission above the column) and an
!>   optional collimated beam of flux beam_flux [W m-2] normal to the beam, travelling down with
!>   direction cosine beam_mu0 (as DISORT's FBEAM, UMU0);
!> * surface: Lambertian with emissivity eps: it emits eps b_surface and reflects the fraction
!>   1 - eps of the incident flux isotropically (Kirchhoff's law for a Lambert surface).
!>
!> Radiances in W m-2 sr-1 (or the band units of kumo_planck), fluxes in W m-2 (same prefix).
!> Direction cosines mu > 0 travel upward, mu < 0 downward (kumo's uz sign).
!>
!> Method: the formal solution of dI/ds = B - I along a path, integrated by parts so that the
!> level Planck value appears explicitly. For the upward radiance at level i,
!>
!>     I(mu) = b(i) + (I_s - b(0)) exp(-tau_b/mu)
!>             + sum_{k<=i} (b(k-1) - b(k)) exp(-t_k/mu) f(tau(k)/mu),   f(s) = (1 - e^-s)/s,
!>
!> where tau_b is the optical depth between level i and the surface, t_k that between level i
!> and the top of layer k, and I_s the radiance leaving the surface. Downward radiances are
!> the mirror image with i_top and b(nz).
!>
!> A layer may also have its own bottom and top values bb(k), bt(k), so that B jumps at a
!> level (RRTMGP's Planck sources: the level value of a g-point carries the Planck fraction of
!> the layer on either side; `thermal_column_init_layers`). The same integration by parts then
!> adds, for every level j strictly between level i and the far boundary, the jump seen along
!> the path (upstream minus downstream value) times exp(-t_j/mu):
!>
!>     I(mu > 0) = bt(i) + (I_s - bb(1)) exp(-tau_b/mu) + sum_{0<j<i} (bt(j) - bb(j+1)) exp(-t_j/mu)
!>                 + sum_{k<=i} (bb(k) - bt(k)) exp(-t_k/mu) f(tau(k)/mu),
!>
!> with bt(0) read as bb(1) at the surface; downward the mirror image. With bb(k) = b(k-1) and
!> bt(k) = b(k) the jumps vanish and the form above is recovered. The point divergence at a
!> level where B jumps is taken with B there the mean of its two sides. Angular integration turns exp(-t/mu) f(tau/mu) into
!> divided differences of exponential integrals: (E_{n+1}(t) - E_{n+1}(t + tau))/tau with n = 2
!> for mean radiances and n = 3 for fluxes (kumo_expint). In this form the net flux and the
!> point flux divergence 4 pi (Jbar - B) contain no b(i) terms, so they come out without
!> cancellation in optically thick or isothermal columns (where they vanish: an isothermal
!> column at temperature T over a black surface at T under a sky of B(T) has I = B(T)
!> everywhere and zero divergence to round-off).
module kumo_thermal_column
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
  use kumo_kinds, only: wp
  use kumo_constants, only: PI, TWO_PI
  use kumo_error, only: error_t, set_error, str
  use kumo_expint, only: expint_e, expint_divdiff
  use kumo_planck, only: spectral_band_t, band_radiance, check_temperatures
  implicit none
  private
  public :: thermal_column_t, thermal_column_init, thermal_column_from_temperatures, &
            thermal_column_init_layers
  public :: thermal_column_fluxes, thermal_column_radiance, thermal_column_fluxes_diffusivity

  !> Diffusivity factor of the two-stream fluxes of thermal_column_fluxes_diffusivity: flux
  !> transmission 2 E_3(tau) replaced by exp(-D tau) (Elsasser 1942; the value of RRTMG and
  !> most band models)
  real(wp), parameter :: DIFFUSIVITY = 1.66_wp

  !> A non-scattering column with its boundary conditions. Build it with thermal_column_init
  !> or thermal_column_from_temperatures (both validate).
  type :: thermal_column_t
    integer :: nz = 0
    real(wp), allocatable :: tau(:)      !! (nz) absorption optical depth of layer k
    real(wp), allocatable :: tau_cum(:)  !! (0:nz) optical depth between the surface and level i
    real(wp), allocatable :: bb(:)       !! (nz) Planck radiance at the bottom of layer k
    real(wp), allocatable :: bt(:)       !! (nz) Planck radiance at the top of layer k
    real(wp) :: emissivity = 1.0_wp      !! surface emissivity (1 - Lambert albedo)
    real(wp) :: b_surface = 0.0_wp       !! Planck radiance of the surface temperature
    real(wp) :: i_top = 0.0_wp           !! isotropic downward radiance at the top
    real(wp) :: beam_flux = 0.0_wp       !! collimated flux normal to the beam at the top
    real(wp) :: beam_mu0 = 1.0_wp        !! cosine of the beam's zenith angle, (0, 1]
    real(wp) :: i_surface = 0.0_wp       !! radiance leaving the surface (set by init)
  end type thermal_column_t

contains

  !> Set up a column from optical depths and level Planck radiances, validating everything;
  !> the surface-leaving radiance is computed here.
  subroutine thermal_column_init(col, tau, b_level, emissivity, b_surface, i_top, error, beam_flux, beam_mu0)
    type(thermal_column_t), intent(out) :: col
    real(wp), intent(in) :: tau(:)        !! (nz) layer absorption optical depths, bottom to top
    real(wp), intent(in) :: b_level(0:)   !! (0:nz) Planck radiance at the levels
    real(wp), intent(in) :: emissivity    !! surface emissivity in [0, 1]
    real(wp), intent(in) :: b_surface     !! Planck radiance of the surface, >= 0
    real(wp), intent(in) :: i_top         !! isotropic downward radiance at the top, >= 0
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: beam_flux  !! collimated flux normal to the beam, >= 0
    real(wp), intent(in), optional :: beam_mu0   !! cosine of the beam zenith angle, (0, 1]
    integer :: k, nz
    nz = size(tau)
    if (size(b_level) /= nz + 1) then
      call set_error(error, 'thermal column: '//str(size(b_level))//' level Planck values for '//str(nz) &
                     //' layers; expected '//str(nz + 1))
      return
    end if
    do k = 0, nz
      if (.not. nonneg(b_level(k))) then
        call set_error(error, 'thermal column: Planck radiance at level '//str(k)//' = '//text(b_level(k)) &
                       //' must be finite and >= 0')
        return
      end if
    end do
    call thermal_column_init_layers(col, tau, b_level(0:nz - 1), b_level(1:nz), emissivity, b_surface, &
                                    i_top, error, beam_flux, beam_mu0)
  end subroutine thermal_column_init

  !> Set up a column whose layers have their own Planck radiances at their bottom (`b_bottom`)
  !> and top (`b_top`), B linear in optical depth in between (jumps at the levels allowed).
  subroutine thermal_column_init_layers(col, tau, b_bottom, b_top, emissivity, b_surface, i_top, error, &
                                        beam_flux, beam_mu0)
    type(thermal_column_t), intent(out) :: col
    real(wp), intent(in) :: tau(:)        !! (nz) layer absorption optical depths, bottom to top
    real(wp), intent(in) :: b_bottom(:)   !! (nz) Planck radiance at the bottom of each layer
    real(wp), intent(in) :: b_top(:)      !! (nz) Planck radiance at the top of each layer
    real(wp), intent(in) :: emissivity    !! surface emissivity in [0, 1]
    real(wp), intent(in) :: b_surface     !! Planck radiance of the surface, >= 0
    real(wp), intent(in) :: i_top         !! isotropic downward radiance at the top, >= 0
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: beam_flux  !! collimated flux normal to the beam, >= 0
    real(wp), intent(in), optional :: beam_mu0   !! cosine of the beam zenith angle, (0, 1]
    integer :: k, nz
    nz = size(tau)
    if (nz < 1 .or. size(b_bottom) /= nz .or. size(b_top) /= nz) then
      call set_error(error, 'thermal column: '//str(nz)//' layers with '//str(size(b_bottom))// &
                     ' bottom and '//str(size(b_top))//' top Planck values; expected at least one '// &
                     'layer and one value of each per layer')
      return
    end if
    do k = 1, nz
      if (.not. nonneg(tau(k))) then
        call set_error(error, 'thermal column: tau('//str(k)//') = '//text(tau(k))//' must be finite and >= 0')
        return
      end if
      if (.not. (nonneg(b_bottom(k)) .and. nonneg(b_top(k)))) then
        call set_error(error, 'thermal column: Planck radiances of layer '//str(k)//' = '// &
                       text(b_bottom(k))//', '//text(b_top(k))//' must be finite and >= 0')
        return
      end if
    end do
    if (ieee_is_nan(emissivity)) then
      call set_error(error, 'thermal column: surface emissivity = NaN must be in [0, 1]')
    else if (emissivity < 0.0_wp .or. emissivity > 1.0_wp) then
      call set_error(error, 'thermal column: surface emissivity = '//str(emissivity)//' must be in [0, 1]')
    else if (.not. nonneg(b_surface)) then
      call set_error(error, 'thermal column: surface Planck radiance = '//text(b_surface)//' must be finite and >= 0')
    else if (.not. nonneg(i_top)) then
      call set_error(error, 'thermal column: top radiance = '//text(i_top)//' must be finite and >= 0')
    end if
    if (allocated(error)) return
    if (present(beam_flux)) then
      if (.not. nonneg(beam_flux)) then
        call set_error(error, 'thermal column: beam flux = '//text(beam_flux)//' must be finite and >= 0')
        return
      end if
      col%beam_flux = beam_flux
    end if
    if (present(beam_mu0)) then
      if (ieee_is_nan(beam_mu0)) then
        call set_error(error, 'thermal column: beam mu0 = NaN must be in (0, 1]')
        return
      else if (beam_mu0 <= 0.0_wp .or. beam_mu0 > 1.0_wp) then
        call set_error(error, 'thermal column: beam mu0 = '//str(beam_mu0)//' must be in (0, 1]')
        return
      end if
      col%beam_mu0 = beam_mu0
    end if
    col%nz = nz
    col%tau = tau
    col%bb = b_bottom
    col%bt = b_top
    allocate (col%tau_cum(0:nz))
    col%tau_cum(0) = 0.0_wp
    do k = 1, nz
      col%tau_cum(k) = col%tau_cum(k - 1) + tau(k)
    end do
    col%emissivity = emissivity
    col%b_surface = b_surface
    col%i_top = i_top
    col%i_surface = emissivity*b_surface &
                    + (1.0_wp - emissivity)*(downward_diffuse_flux(col, 0) + direct_flux(col, 0))/PI
  end subroutine thermal_column_init_layers

  !> Set up a column from level temperatures [K] and a spectral band (kumo_planck): b(i) =
  !> band_radiance(band, t_level(i)), the surface from t_surface. Temperatures are validated.
  subroutine thermal_column_from_temperatures(col, tau, t_level, t_surface, emissivity, band, error, &
                                              i_top, beam_flux, beam_mu0)
    type(thermal_column_t), intent(out) :: col
    real(wp), intent(in) :: tau(:)        !! (nz) layer absorption optical depths, bottom to top
    real(wp), intent(in) :: t_level(0:)   !! (0:nz) level temperatures [K]
    real(wp), intent(in) :: t_surface     !! surface (skin) temperature [K]
    real(wp), intent(in) :: emissivity    !! surface emissivity in [0, 1]
    type(spectral_band_t), intent(in) :: band
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: i_top      !! downward radiance at the top (default 0)
    real(wp), intent(in), optional :: beam_flux, beam_mu0
    real(wp) :: top
    call check_temperatures(t_level, 'thermal column: level temperature', error)
    if (allocated(error)) return
    call check_temperatures(t_surface, 'thermal column: surface temperature', error)
    if (allocated(error)) return
    top = 0.0_wp
    if (present(i_top)) top = i_top
    call thermal_column_init(col, tau, band_radiance(band, t_level), emissivity, band_radiance(band, t_surface), &
                             top, error, beam_flux, beam_mu0)
  end subroutine thermal_column_from_temperatures

  !> Fluxes and divergences at all levels and layers (without `flux_div`, the mean radiances
  !> that it needs, half the work, are not formed).
  pure subroutine thermal_column_fluxes(col, flux_up, flux_down, flux_direct, flux_div, layer_net)
    type(thermal_column_t), intent(in) :: col
    real(wp), intent(out) :: flux_up(0:)      !! (0:nz) upward flux [W m-2]
    real(wp), intent(out) :: flux_down(0:)    !! (0:nz) diffuse downward flux [W m-2]
    real(wp), intent(out) :: flux_direct(0:)  !! (0:nz) direct (beam) flux on a horizontal plane
    !> (0:nz) Int I dOmega - 4 pi B = -d(net flux)/d(tau) at the level [W m-2 per unit optical
    !> depth], the beam included (DISORT's DFDT for a non-scattering medium): > 0 means net
    !> absorption there.
    real(wp), intent(out), optional :: flux_div(0:)
    !> (nz) absorbed minus emitted power of layer k per unit area [W m-2] = net downward flux at
    !> its top minus that at its bottom (> 0 warms the layer).
    real(wp), intent(out) :: layer_net(:)
    real(wp) :: net(0:col%nz), up_part, down_part
    integer :: i, k
    do i = 0, col%nz
      call sums(col, i, 3, down_part, up_part)
      flux_down(i) = PI*b_down(col, i) + down_part
      flux_up(i) = PI*b_up(col, i) + up_part
      flux_direct(i) = direct_flux(col, i)
      net(i) = PI*(b_down(col, i) - b_up(col, i)) + down_part - up_part + flux_direct(i)
      if (.not. present(flux_div)) cycle
      call sums(col, i, 2, down_part, up_part)
      flux_div(i) = down_part + up_part + direct_flux(col, i)/col%beam_mu0
    end do
    do k = 1, col%nz
      layer_net(k) = net(k) - net(k - 1)
    end do
  end subroutine thermal_column_fluxes

  !> Approximate fluxes of the same column, with the diffusivity approximation: each hemisphere's
  !> flux crosses a layer of optical depth tau with transmission exp(-D tau), D = DIFFUSIVITY,
  !> instead of 2 E_3(tau); B linear in optical depth inside each layer, jumps at the levels and
  !> the boundaries as in thermal_column_fluxes (no beam). O(nz) exponentials instead of O(nz^2)
  !> exponential integrals, for uses that need a few per cent (the importance of the g-points of
  !> a broadband longwave run). Isothermal columns come out exactly (zero net flux); an optically
  !> thin layer emits D tau pi B per hemisphere instead of 2 tau pi B.
  pure subroutine thermal_column_fluxes_diffusivity(col, flux_up, flux_down, layer_net)
    type(thermal_column_t), intent(in) :: col
    real(wp), intent(out) :: flux_up(0:)      !! (0:nz) upward flux [W m-2]
    real(wp), intent(out) :: flux_down(0:)    !! (0:nz) downward flux [W m-2]
    real(wp), intent(out) :: layer_net(:)     !! (nz) net downward flux at the top minus the bottom
    real(wp) :: t, g
    integer :: k
    flux_down(col%nz) = PI*col%i_top
    do k = col%nz, 1, -1
      call layer_factors(col%tau(k), t, g)
      flux_down(k - 1) = flux_down(k)*t + &
                         PI*(col%bb(k) - col%bt(k)*t - (col%bb(k) - col%bt(k))*g)
    end do
    flux_up(0) = PI*col%emissivity*col%b_surface + (1.0_wp - col%emissivity)*flux_down(0)
    do k = 1, col%nz
      call layer_factors(col%tau(k), t, g)
      flux_up(k) = flux_up(k - 1)*t + PI*(col%bt(k) - col%bb(k)*t - (col%bt(k) - col%bb(k))*g)
    end do
    do k = 1, col%nz
      layer_net(k) = (flux_down(k) - flux_up(k)) - (flux_down(k - 1) - flux_up(k - 1))
    end do
  contains
    !> t = exp(-x) and g = (1 - t)/x for x = D tau (the series of g below x = 1e-3)
    pure subroutine layer_factors(tau, t, g)
      real(wp), intent(in) :: tau
      real(wp), intent(out) :: t, g
      real(wp) :: x
      x = DIFFUSIVITY*tau
      t = exp(-x)
      if (x < 1.0e-3_wp) then
        g = 1.0_wp - x*(0.5_wp - x*(1.0_wp/6.0_wp - x/24.0_wp))
      else
        g = (1.0_wp - t)/x
      end if
    end subroutine layer_factors
  end subroutine thermal_column_fluxes_diffusivity

  !> Diffuse radiance at level i (0..nz) in direction mu (> 0 upward, < 0 downward, |mu| <= 1).
  !> i_surface, if given, replaces the Lambertian surface-leaving radiance for this direction
  !> (e.g. a surface with a BRDF whose upward radiance is known).
  pure real(wp) function thermal_column_radiance(col, i, mu, i_surface) result(rad)
    type(thermal_column_t), intent(in) :: col
    integer, intent(in) :: i
    real(wp), intent(in) :: mu
    real(wp), intent(in), optional :: i_surface
    real(wp) :: m, is, t
    integer :: k
    m = abs(mu)
    if (mu > 0.0_wp) then
      is = col%i_surface
      if (present(i_surface)) is = i_surface
      rad = b_up(col, i) + (is - col%bb(1))*attenuation(col%tau_cum(i), m)
      do k = 1, i
        t = col%tau_cum(i) - col%tau_cum(k)
        rad = rad + (col%bb(k) - col%bt(k))*attenuation(t, m)*escape(col%tau(k), m)
        if (k < i) rad = rad + (col%bt(k) - col%bb(k + 1))*attenuation(t, m)
      end do
    else
      rad = b_down(col, i) + (col%i_top - col%bt(col%nz))* &
            attenuation(col%tau_cum(col%nz) - col%tau_cum(i), m)
      do k = i + 1, col%nz
        t = col%tau_cum(k - 1) - col%tau_cum(i)
        rad = rad + (col%bt(k) - col%bb(k))*attenuation(t, m)*escape(col%tau(k), m)
        if (k > i + 1) rad = rad + (col%bb(k) - col%bt(k - 1))*attenuation(t, m)
      end do
    end if
  end function thermal_column_radiance

  !> The parts of 2 pi Int_0^1 mu^(n-2) I dmu (n = 3: flux, n = 2: mean radiance) beyond the
  !> level's own pi b(i) (n = 3) or 2 pi b(i) (n = 2), for the downward and upward hemispheres.
  pure subroutine sums(col, i, n, down_part, up_part)
    type(thermal_column_t), intent(in) :: col
    integer, intent(in) :: i, n
    real(wp), intent(out) :: down_part, up_part
    real(wp) :: t
    integer :: k
    up_part = (col%i_surface - col%bb(1))*expint_e(n, col%tau_cum(i))
    do k = 1, i
      t = col%tau_cum(i) - col%tau_cum(k)
      up_part = up_part + (col%bb(k) - col%bt(k))*expint_divdiff(n + 1, t, col%tau(k))
      ! a jump of B at level k (between level i and the surface)
      if (k < i) up_part = up_part + (col%bt(k) - col%bb(k + 1))*expint_e(n, t)
    end do
    down_part = (col%i_top - col%bt(col%nz))*expint_e(n, col%tau_cum(col%nz) - col%tau_cum(i))
    do k = i + 1, col%nz
      t = col%tau_cum(k - 1) - col%tau_cum(i)
      down_part = down_part + (col%bt(k) - col%bb(k))*expint_divdiff(n + 1, t, col%tau(k))
      ! a jump of B at level k - 1 (between level i and the top)
      if (k > i + 1) down_part = down_part + (col%bb(k) - col%bt(k - 1))*expint_e(n, t)
    end do
    up_part = TWO_PI*up_part
    down_part = TWO_PI*down_part
  end subroutine sums

  !> Diffuse downward flux at level i (needed before i_surface is known).
  pure real(wp) function downward_diffuse_flux(col, i) result(f)
    type(thermal_column_t), intent(in) :: col
    integer, intent(in) :: i
    real(wp) :: up_part, down_part
    call sums(col, i, 3, down_part, up_part)
    f = PI*b_down(col, i) + down_part
  end function downward_diffuse_flux

  !> The Planck radiance on the lower side of level i (upward radiation leaves it from there).
  pure real(wp) function b_up(col, i) result(b)
    type(thermal_column_t), intent(in) :: col
    integer, intent(in) :: i
    if (i >= 1) then
      b = col%bt(i)
    else
      b = col%bb(1)
    end if
  end function b_up

  !> The Planck radiance on the upper side of level i.
  pure real(wp) function b_down(col, i) result(b)
    type(thermal_column_t), intent(in) :: col
    integer, intent(in) :: i
    if (i < col%nz) then
      b = col%bb(i + 1)
    else
      b = col%bt(col%nz)
    end if
  end function b_down

  !> Direct beam flux on a horizontal plane at level i.
  pure real(wp) function direct_flux(col, i) result(f)
    type(thermal_column_t), intent(in) :: col
    integer, intent(in) :: i
    f = col%beam_flux*col%beam_mu0*attenuation(col%tau_cum(col%nz) - col%tau_cum(i), col%beam_mu0)
  end function direct_flux

  !> exp(-t/mu), 0 for mu = 0 or huge t/mu.
  elemental real(wp) function attenuation(t, mu) result(a)
    real(wp), intent(in) :: t, mu
    a = 0.0_wp
    if (t >= 745.0_wp*mu) return
    a = exp(-t/mu)
  end function attenuation

  !> f(tau/mu) = (1 - exp(-s))/s, s = tau/mu (limit 1 at s = 0).
  elemental real(wp) function escape(tau, mu) result(f)
    real(wp), intent(in) :: tau, mu
    real(wp) :: s
    if (tau >= 1.0e300_wp*mu) then
      f = 0.0_wp
      return
    end if
    s = tau/mu
    if (s < 1.0e-5_wp) then
      f = 1.0_wp - s*(0.5_wp - s/6.0_wp)
    else if (s > 745.0_wp) then
      f = 1.0_wp/s
    else
      f = -expm1_neg(s)/s
    end if
  end function escape

  !> exp(-s) - 1 for s >= 1e-5 (no cancellation issue at that size beyond 1e-11 relative; the
  !> form below keeps full precision via Kahan's correction).
  elemental real(wp) function expm1_neg(s) result(y)
    real(wp), intent(in) :: s
    real(wp) :: u
    u = exp(-s)
    if (u == 1.0_wp) then
      y = -s
    else
      y = (u - 1.0_wp)*(-s)/log(u)
    end if
  end function expm1_neg

  !> Finite and >= 0 (NaN tested first, no invalid-operation flag).
  elemental logical function nonneg(x) result(ok)
    real(wp), intent(in) :: x
    ok = .false.
    if (ieee_is_nan(x)) return
    ok = x >= 0.0_wp .and. ieee_is_finite(x)
  end function nonneg

  !> Text of a value for messages, NaN included.
  function text(x) result(s)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: s
    if (ieee_is_nan(x)) then
      s = 'NaN'
    else
      s = str(x)
    end if
  end function text

end module kumo_thermal_column
