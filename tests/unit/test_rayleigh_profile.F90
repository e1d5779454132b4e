! SPDX-License-Identifier: BSD-3-Clause
!> Pressure profiles of the Rayleigh layers (&kumo_atmosphere rayleigh_profile): a sounding
!> ('levels', pressure_levels_hpa) and the pressure of the &kumo_cloud LES file ('cloud_file').
!>
!> Each case is read from a namelist and set up by `setup_scene`, as in a run; the layer optical
!> depths kumo uses are the 1-D extinction of the scene's atmosphere (ext1, which holds only the
!> molecules here) times the layer thickness. References, computed here:
!>
!> * an isothermal hydrostatic sounding p = p0 exp(-z/H): the optical depth of the air between
!>   two pressures, tau = sigma N_A (p_bottom - p_top)/(m_a g) (Bodhaine, Wood, Dutton and
!>   Slusser 1999, J. Atmos. Oceanic Technol. 16, 1854-1861, hereafter B99; kumo's
!>   seed-digest section 3.2, eq. 2.2.10), with N_A and m_a as given by B99, g of List (1968)
!>   as given by B99 (kumo_rayleigh's gravity_bodhaine, checked against B99 in test_rayleigh)
!>   taken at the mass-weighted height of the layer, and sigma from kumo_rayleigh (checked
!>   against B99's eq. 29 in test_rayleigh). The layer air density is (p_bottom - p_top)/(g0 dz);
!> * outside the cloud file's levels: the US 1976 standard atmosphere (us1976_state, checked
!>   against the standard's tables in test_rayleigh) scaled to the file's edge pressure,
!>   integrated by brute force in 1 m steps;
!> * the 'us1976' run of the same levels (itself checked against the brute-force integral of
!>   the standard), for a cloud file holding US 1976 pressures at its layer centres, to a
!>   tolerance derived from the log-p interpolation error;
!> * a 3-D pressure field against a file holding its horizontal-mean profile.
!>
!> Bad inputs: no pressure variable, a missing named variable, a pressure that grows with
!> height, a bad value inside a 3-D field, 'cloud_file' without a cloud file or with a text
!> format, pressure_levels_hpa missing, of the wrong length, not falling, or given for another
!> profile, and an unknown profile name.
module test_rayleigh_profile_suite
  use kumo_kinds, only: wp
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  use kumo_error, only: str
  use kumo_config, only: config_t
  use kumo_scene_setup, only: load_config
  use kumo_test_text, only: write_text
  use kumo_driver, only: scene_t, setup_scene
  use kumo_rayleigh, only: rayleigh_cross_section, gravity_bodhaine
  use kumo_std_atmosphere, only: us1976_state
  use netcdf, only: nf90_create, nf90_def_dim, nf90_def_var, nf90_enddef, nf90_put_var, &
                    nf90_close, nf90_put_att, nf90_clobber, nf90_double, nf90_float, &
                    NF90_NOERR, nf90_strerror
  implicit none
  private
  public :: collect_rayleigh_profile

  real(wp), parameter :: WL_UM = 0.55_wp       !! wavelength [um]
  real(wp), parameter :: CO2_PPM = 400.0_wp    !! kumo's default CO2
  real(wp), parameter :: LAT_DEG = 45.0_wp     !! kumo's default latitude
  real(wp), parameter :: P0 = 101325.0_wp      !! surface pressure of the sounding [Pa]
  real(wp), parameter :: H = 8000.0_wp         !! scale height of the sounding [m]
  !> Avogadro's number as used by B99 [mol-1]
  real(wp), parameter :: N_A = 6.0221367e23_wp
  !> Standard gravity [m s-2] of the layer air density
  real(wp), parameter :: G0 = 9.80665_wp
  !> The isothermal cases: kumo integrates the same hydrostatic formula with 5-point
  !> Gauss-Legendre quadrature over profile pieces (exact to ~1e-13 for these smooth integrands)
  !> and interpolates log p linearly, which is exact for p0 exp(-z/H). The reference takes g at
  !> the mass-weighted height of the layer; 1/g departs from a straight line in z by ~2.5e-14
  !> m-2 z^2 (B99's gravity), so for layers of up to 4 km (mass variance < 1.4e6 m2) the
  !> reference is exact to 4e-8. Tolerance 1e-7.
  real(wp), parameter :: TOL_EXACT = 1.0e-7_wp
  character(len=1), parameter :: NL = new_line('a')

contains

  function collect_rayleigh_profile() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('levels_isothermal_vs_b99', test_levels_isothermal), &
             new_unittest('cloud_file_isothermal_vs_b99', test_cloud_isothermal), &
             new_unittest('cloud_file_us1976_equals_us1976', test_cloud_us1976), &
             new_unittest('pressure_3d_equals_mean_profile', test_3d_equals_profile), &
             new_unittest('bad_cloud_file_pressure', test_bad_cloud), &
             new_unittest('bad_levels_and_profile_names', test_bad_levels)]
  end function collect_rayleigh_profile

  ! ------------------------------------------------------------------------------------------
  ! References
  ! ------------------------------------------------------------------------------------------

  !> Pressure of the isothermal sounding [Pa].
  elemental real(wp) function p_iso(z)
    real(wp), intent(in) :: z
    p_iso = P0*exp(-z/H)
  end function p_iso

  !> sigma N_A/m_a [m2 kg-1 ... times Pa/g gives tau]: B99, m_a = 15.0556 C + 28.9595 g/mol
  !> with C the CO2 volume fraction.
  real(wp) function tau_per_mass()
    real(wp) :: m_a
    m_a = 1.0e-3_wp*(28.9595_wp + 15.0556_wp*1.0e-6_wp*CO2_PPM)
    tau_per_mass = rayleigh_cross_section(WL_UM, CO2_PPM)*N_A/m_a
  end function tau_per_mass

  !> B99's layer optical depth of the isothermal sounding between a and b, g at the layer's
  !> mass-weighted height a + H - d exp(-d/H)/(1 - exp(-d/H)), d = b - a.
  real(wp) function tau_iso(a, b)
    real(wp), intent(in) :: a, b
    real(wp) :: d, zbar
    d = b - a
    zbar = a + H - d*exp(-d/H)/(1.0_wp - exp(-d/H))
    tau_iso = tau_per_mass()*(p_iso(a) - p_iso(b))/gravity_bodhaine(LAT_DEG, zbar)
  end function tau_iso

  !> Brute-force optical depth between a and b of p(z) = p_ref p76(z)/p76(z_ref): the sum of
  !> sigma N_A/m_a (p(z_i) - p(z_i+1))/g(midpoint) over steps of about 1 m.
  real(wp) function tau_us_scaled(a, b, p_ref, z_ref)
    real(wp), intent(in) :: a, b, p_ref, z_ref
    real(wp) :: scale, pa, pb, za, zb, t, rho
    integer :: i, n
    call us1976_state(z_ref, pa, t, rho)
    scale = p_ref/pa
    n = max(1, nint(b - a))
    tau_us_scaled = 0.0_wp
    za = a
    call us1976_state(za, pa, t, rho)
    do i = 1, n
      zb = a + (b - a)*i/real(n, wp)
      call us1976_state(zb, pb, t, rho)
      tau_us_scaled = tau_us_scaled + scale*(pa - pb)/gravity_bodhaine(LAT_DEG, 0.5_wp*(za + zb))
      za = zb
      pa = pb
    end do
    tau_us_scaled = tau_per_mass()*tau_us_scaled
  end function tau_us_scaled

  !> US 1976 pressure at z [Pa].
  elemental real(wp) function p76(z)
    real(wp), intent(in) :: z
    real(wp) :: t, rho
    call us1976_state(z, p76, t, rho)
  end function p76

  ! ------------------------------------------------------------------------------------------
  ! Input files
  ! ------------------------------------------------------------------------------------------

  !> A 2 x 2-column LES file, clear (lwc = 0), with layer edges `ze` [m] and a pressure:
  !> kind 'profile_hpa': p(z) in hPa; 'profile_time': p(time, z) in Pa; '3d_time':
  !> p(time, z, y, x) in Pa, `p3` per column; 'none': no pressure. With a time dimension
  !> (2 steps) the pressure asked for is step 2, step 1 holds 1.1 times it.
  subroutine write_les(path, ze, kind, p, p3, pname)
    character(len=*), intent(in) :: path, kind
    real(wp), intent(in) :: ze(0:)
    real(wp), intent(in), optional :: p(:)           !! per layer [Pa]
    real(wp), intent(in), optional :: p3(:, :, :)    !! (2, 2, nz) [Pa]
    character(len=*), intent(in), optional :: pname  !! pressure variable name (default 'p')
    integer :: nc, ix, iy, iz, it, ize, vx, vy, vze, vl, vr, vp, nz, s(40), n
    logical :: timed
    character(len=:), allocatable :: name
    real(wp), allocatable :: zero(:, :, :, :)
    nz = size(ze) - 1
    timed = kind /= 'profile_hpa' .and. kind /= 'none'
    name = 'p'
    if (present(pname)) name = pname
    n = 0
    s = NF90_NOERR
    call put(nf90_create(path, nf90_clobber, nc))
    call put(nf90_def_dim(nc, 'x', 2, ix))
    call put(nf90_def_dim(nc, 'y', 2, iy))
    call put(nf90_def_dim(nc, 'z', nz, iz))
    call put(nf90_def_dim(nc, 'z_edges', nz + 1, ize))
    if (timed) call put(nf90_def_dim(nc, 'time', 2, it))
    call put(nf90_def_var(nc, 'x', nf90_double, [ix], vx))
    call put(nf90_put_att(nc, vx, 'units', 'm'))
    call put(nf90_def_var(nc, 'y', nf90_double, [iy], vy))
    call put(nf90_put_att(nc, vy, 'units', 'm'))
    call put(nf90_def_var(nc, 'z_edges', nf90_double, [ize], vze))
    call put(nf90_put_att(nc, vze, 'units', 'm'))
    if (timed) then
      call put(nf90_def_var(nc, 'lwc', nf90_float, [ix, iy, iz, it], vl))
      call put(nf90_def_var(nc, 'reff', nf90_float, [ix, iy, iz, it], vr))
    else
      call put(nf90_def_var(nc, 'lwc', nf90_float, [ix, iy, iz], vl))
      call put(nf90_def_var(nc, 'reff', nf90_float, [ix, iy, iz], vr))
    end if
    call put(nf90_put_att(nc, vl, 'units', 'g m-3'))
    call put(nf90_put_att(nc, vr, 'units', 'um'))
    select case (kind)
    case ('profile_hpa')
      call put(nf90_def_var(nc, name, nf90_double, [iz], vp))
      call put(nf90_put_att(nc, vp, 'units', 'hPa'))
    case ('profile_time')
      call put(nf90_def_var(nc, name, nf90_double, [iz, it], vp))
      call put(nf90_put_att(nc, vp, 'units', 'Pa'))
    case ('3d_time')
      call put(nf90_def_var(nc, name, nf90_double, [ix, iy, iz, it], vp))
      call put(nf90_put_att(nc, vp, 'units', 'Pa'))
    case default
      continue   ! 'none': no pressure variable
    end select
    call put(nf90_enddef(nc))
    call put(nf90_put_var(nc, vx, [50.0_wp, 150.0_wp]))
    call put(nf90_put_var(nc, vy, [50.0_wp, 150.0_wp]))
    call put(nf90_put_var(nc, vze, ze))
    allocate (zero(2, 2, nz, merge(2, 1, timed)))
    zero = 0.0_wp
    call put(nf90_put_var(nc, vl, zero))
    call put(nf90_put_var(nc, vr, zero))
    select case (kind)
    case ('profile_hpa')
      call put(nf90_put_var(nc, vp, 0.01_wp*p))
    case ('profile_time')
      call put(nf90_put_var(nc, vp, reshape([1.1_wp*p, p], [nz, 2])))
    case ('3d_time')
      call put(nf90_put_var(nc, vp, reshape([1.1_wp*p3, p3], [2, 2, nz, 2])))
    case default
      continue
    end select
    call put(nf90_close(nc))
    if (any(s(1:n) /= NF90_NOERR)) error stop 'test_rayleigh_profile: writing a netCDF file failed'
  contains
    subroutine put(status)
      integer, intent(in) :: status
      n = n + 1
      s(n) = status
      if (status /= NF90_NOERR) write (*, '(a)') path//': '//trim(nf90_strerror(status))
    end subroutine put
  end subroutine write_les

  !> Namelist groups common to every case, plus `atm` (the inside of &kumo_atmosphere) and
  !> `cloud` (a cloud file, '' for none) with more &kumo_cloud settings in `cloud_extra`.
  function case_namelist(atm, cloud, cloud_extra) result(text)
    character(len=*), intent(in) :: atm, cloud
    character(len=*), intent(in), optional :: cloud_extra
    character(len=:), allocatable :: text
    text = '&kumo_control n_photons_per_batch = 10, n_batches = 2, verbose = 0 /'//NL// &
           '&kumo_atmosphere rayleigh = .true., '//atm//' /'//NL// &
           '&kumo_source wavelength_um = '//str(WL_UM)//', solar_flux = 1000.0 /'//NL// &
           '&kumo_output file = ''rayleigh_profile_out.nc'' /'//NL
    if (len(cloud) > 0) then
      text = text//'&kumo_cloud cloud_file = '''//cloud//''', n_reff = 2, reff_min_um = 1.0, '// &
             'reff_max_um = 2.0'
      if (present(cloud_extra)) text = text//', '//cloud_extra
      text = text//' /'//NL
    end if
  end function case_namelist

  !> Read the namelist `text` (written to `path`) and set up its scene.
  subroutine setup_case(path, text, cfg, scene, error)
    character(len=*), intent(in) :: path, text
    type(config_t), intent(out) :: cfg
    type(scene_t), intent(out) :: scene
    type(error_t), allocatable, intent(out) :: error
    call write_text(path, text)
    call load_config(path, cfg, error)
    if (allocated(error)) return
    call setup_scene(cfg, scene, error)
  end subroutine setup_case

  !> The error of reading the namelist `text`; the test fails unless it contains `expected`.
  subroutine expect_config_error(error, path, text, expected)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path, text, expected
    type(config_t) :: cfg
    type(error_t), allocatable :: err
    if (allocated(error)) return
    call write_text(path, text)
    call load_config(path, cfg, err)
    if (.not. allocated(err)) then
      call check(error, .false., path//': accepted; expected an error containing "'// &
                 expected//'"')
    else
      call check(error, index(err%message, expected) > 0, path//': message "'//err%message// &
                 '" does not contain "'//expected//'"')
    end if
  end subroutine expect_config_error

  !> Levels as a namelist list.
  function join(v) result(s)
    real(wp), intent(in) :: v(:)
    character(len=:), allocatable :: s
    character(len=32) :: buf
    integer :: i
    s = ''
    do i = 1, size(v)
      write (buf, '(es25.17e3)') v(i)
      if (i > 1) s = s//', '
      s = s//trim(adjustl(buf))
    end do
  end function join

  !> Layer optical depths of the scene's 1-D layers.
  function layer_tau(scene) result(tau)
    type(scene_t), intent(in) :: scene
    real(wp), allocatable :: tau(:)
    associate (z => scene%atm%z, nz => scene%atm%nz)
      tau = scene%atm%ext1*(z(1:nz) - z(0:nz - 1))
    end associate
  end function layer_tau

  ! ------------------------------------------------------------------------------------------
  ! Tests
  ! ------------------------------------------------------------------------------------------

  !> 'levels' with the isothermal sounding: layer optical depths and air densities.
  subroutine test_levels_isothermal(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: Z(0:7) = [0.0_wp, 250.0_wp, 500.0_wp, 1000.0_wp, 2000.0_wp, &
                                      4000.0_wp, 8000.0_wp, 12000.0_wp]
    type(config_t) :: cfg
    type(scene_t) :: scene
    real(wp), allocatable :: tau(:)
    integer :: k
    call setup_case('rp_levels.nml', case_namelist('nz = 7, z_levels = '//join(Z)// &
                    ', rayleigh_profile = ''levels'', pressure_levels_hpa = '// &
                    join(0.01_wp*p_iso(Z)), ''), cfg, scene, error)
    if (allocated(error)) return
    tau = layer_tau(scene)
    do k = 1, 7
      call check_close(error, tau(k), tau_iso(Z(k - 1), Z(k)), rel_tol=TOL_EXACT, &
                       label='tau of layer '//str(k))
      ! the same pressures over the standard gravity; only rounding differs
      call check_close(error, scene%air_density(k), (p_iso(Z(k - 1)) - p_iso(Z(k)))/ &
                       (G0*(Z(k) - Z(k - 1))), rel_tol=1.0e-12_wp, &
                       label='air density of layer '//str(k))
    end do
    call check(error, index(scene%notes, 'pressure_levels_hpa') > 0, &
               'the notes do not name the sounding: '//scene%notes)
  end subroutine test_levels_isothermal

  !> 'cloud_file' with the isothermal sounding as a profile in hPa at the layer centres of a file
  !> from 500 to 1500 m; levels below (0-500 m) and above (to 6 km) come from the scaled US 1976.
  subroutine test_cloud_isothermal(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: ze(0:10), zl(0:13), zm(10)
    type(config_t) :: cfg
    type(scene_t) :: scene
    real(wp), allocatable :: tau(:)
    real(wp) :: ref
    integer :: k
    ze = [(500.0_wp + 100.0_wp*k, k=0, 10)]
    zm = 0.5_wp*(ze(:9) + ze(1:))
    zl = [0.0_wp, ze, 3000.0_wp, 6000.0_wp]
    call write_les('rp_iso.nc', ze, 'profile_hpa', p_iso(zm))
    call setup_case('rp_iso.nml', case_namelist('nz = 13, z_levels = '//join(zl)// &
                    ', rayleigh_profile = ''cloud_file''', 'rp_iso.nc'), cfg, scene, error)
    if (allocated(error)) return
    tau = layer_tau(scene)
    do k = 1, 13
      if (k == 1) then
        ref = tau_us_scaled(zl(0), zl(1), p_iso(ze(0)), ze(0))
      else if (k <= 11) then
        ref = tau_iso(zl(k - 1), zl(k))
      else
        ref = tau_us_scaled(zl(k - 1), zl(k), p_iso(ze(10)), ze(10))
      end if
      call check_close(error, tau(k), ref, rel_tol=TOL_EXACT, label='tau of layer '//str(k))
    end do
    call check_close(error, scene%air_density(1), (p_iso(500.0_wp)*(1.0_wp - p76(0.0_wp)/ &
                     p76(500.0_wp)))/(G0*(-500.0_wp)), rel_tol=1.0e-12_wp, &
                     label='air density of the layer below the file')
    call check_close(error, scene%air_density(5), (p_iso(ze(3)) - p_iso(ze(4)))/(G0*100.0_wp), &
                     rel_tol=1.0e-12_wp, label='air density of layer 5')
    call check(error, index(scene%notes, '"p" of') > 0 .and. &
               index(scene%notes, 'a profile') > 0 .and. &
               index(scene%notes, 'below the file: US 1976 scaled') > 0 .and. &
               index(scene%notes, 'above the file: US 1976 scaled') > 0, &
               'the notes do not say where the pressure came from: '//scene%notes)
  end subroutine test_cloud_isothermal

  !> 'cloud_file' whose layers hold the US 1976 pressure at their centres against 'us1976'.
  !>
  !> Tolerance: kumo puts the file's pressures on the layer edges along straight lines in log p
  !> through neighbouring centres (100 m apart), extrapolated by half a layer at the file's
  !> bottom and top. The error of a straight line through points 100 m apart, at most 50 m
  !> outside them, is at most (1/2)(50 m)(150 m) |d2 ln p/dz2|, and for the standard
  !> d2 ln p/dz2 = g M L/(R T^2) <= 9.81 x 0.0290 x 0.0065/(8.314 x 275^2) = 2.95e-9 m-2 below
  !> 2 km (L = 6.5 K/km, T >= 275 K): delta = 1.1e-5 in ln p. A layer's optical depth is
  !> proportional to p_bottom - p_top, so its relative error is at most
  !> delta (p_bottom + p_top)/(p_bottom - p_top); the layers outside the file are the standard
  !> scaled by the edge pressure, relative error at most delta.
  subroutine test_cloud_us1976(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: DELTA = 0.5_wp*50.0_wp*150.0_wp*2.95e-9_wp
    real(wp) :: ze(0:15), zl(0:19), zm(15), tol
    type(config_t) :: cfg
    type(scene_t) :: a, b
    real(wp), allocatable :: ta(:), tb(:)
    integer :: k
    ze = [(500.0_wp + 100.0_wp*k, k=0, 15)]
    zm = 0.5_wp*(ze(:14) + ze(1:))
    zl = [0.0_wp, ze, 4000.0_wp, 8000.0_wp, 12000.0_wp]
    call write_les('rp_us.nc', ze, 'profile_hpa', p76(zm))
    call setup_case('rp_us_file.nml', case_namelist('nz = 19, z_levels = '//join(zl)// &
                    ', rayleigh_profile = ''cloud_file''', 'rp_us.nc'), cfg, a, error)
    if (allocated(error)) return
    call setup_case('rp_us_std.nml', case_namelist('nz = 19, z_levels = '//join(zl)// &
                    ', rayleigh_profile = ''us1976''', 'rp_us.nc'), cfg, b, error)
    if (allocated(error)) return
    ta = layer_tau(a)
    tb = layer_tau(b)
    ! 'us1976' itself: the standard's pressure at every 100 m, so each layer's p_bottom - p_top
    ! is exact and only g is weighted differently from the brute-force sum
    do k = 1, 19
      call check_close(error, tb(k), tau_us_scaled(zl(k - 1), zl(k), p76(0.0_wp), 0.0_wp), &
                       rel_tol=TOL_EXACT, label='tau of layer '//str(k)//' (us1976 vs B99)')
      call check_close(error, b%air_density(k), (p76(zl(k - 1)) - p76(zl(k)))/ &
                       (G0*(zl(k) - zl(k - 1))), rel_tol=1.0e-12_wp, &
                       label='air density of layer '//str(k)//' (us1976)')
    end do
    do k = 1, 19
      tol = DELTA
      if (k >= 2 .and. k <= 16) tol = DELTA*(p76(zl(k - 1)) + p76(zl(k)))/ &
                                      (p76(zl(k - 1)) - p76(zl(k)))
      call check_close(error, ta(k), tb(k), rel_tol=tol, label='tau of layer '//str(k)// &
                       ' (cloud_file vs us1976)')
      call check_close(error, a%air_density(k), b%air_density(k), rel_tol=tol, &
                       label='air density of layer '//str(k)//' (cloud_file vs us1976)')
    end do
    ! the interior edges' errors cancel in the column; its ends carry the scaled standard
    tol = DELTA*(p76(zl(0)) + p76(zl(19)))/(p76(zl(0)) - p76(zl(19)))
    call check_close(error, sum(ta), sum(tb), rel_tol=tol, label='column optical depth')
  end subroutine test_cloud_us1976

  !> A 3-D pressure field (with a time dimension, step 2 read) gives what its horizontal-mean
  !> profile gives. The columns differ by +-2 % around the mean, so a wrong average or a wrong
  !> layer or time step shows at the 1e-2 level; the mean is formed to rounding (1e-15 of p),
  !> which the layer differences p_bottom - p_top (1 % of p) amplify to < 1e-12.
  subroutine test_3d_equals_profile(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: DEV(2, 2) = reshape([0.02_wp, -0.02_wp, -0.02_wp, 0.02_wp], [2, 2])
    real(wp) :: ze(0:6), zm(6), p3(2, 2, 6)
    type(config_t) :: cfg
    type(scene_t) :: a, b
    real(wp), allocatable :: ta(:), tb(:)
    integer :: k
    ze = [(100.0_wp*k, k=0, 6)]
    zm = 0.5_wp*(ze(:5) + ze(1:))
    do k = 1, 6
      p3(:, :, k) = p_iso(zm(k))*(1.0_wp + DEV)
    end do
    call write_les('rp_3d_t.nc', ze, '3d_time', p3=p3)
    call write_les('rp_prof_t.nc', ze, 'profile_time', p_iso(zm))
    call setup_case('rp_3d.nml', case_namelist('rayleigh_profile = ''cloud_file''', &
                    'rp_3d_t.nc', 'les_time_index = 2'), cfg, a, error)
    if (allocated(error)) return
    call setup_case('rp_prof.nml', case_namelist('rayleigh_profile = ''cloud_file''', &
                    'rp_prof_t.nc', 'les_time_index = 2'), cfg, b, error)
    if (allocated(error)) return
    ta = layer_tau(a)
    tb = layer_tau(b)
    do k = 1, 6
      call check_close(error, ta(k), tb(k), rel_tol=1.0e-12_wp, label='tau of layer '//str(k)// &
                       ' (3-D vs profile)')
      call check_close(error, ta(k), tau_iso(ze(k - 1), ze(k)), rel_tol=TOL_EXACT, &
                       label='tau of layer '//str(k)//' (3-D vs B99)')
    end do
    call check(error, index(a%notes, 'a 3-D field averaged over the columns of each layer') > 0, &
               'the notes do not say that the 3-D pressure was averaged: '//a%notes)
  end subroutine test_3d_equals_profile

  !> Cloud files that cannot give the profile.
  subroutine test_bad_cloud(error)
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: ze(0:3), p3(2, 2, 3)
    character(len=*), parameter :: CF = 'rayleigh_profile = ''cloud_file'''
    integer :: u
    ze = [500.0_wp, 600.0_wp, 700.0_wp, 800.0_wp]
    call write_les('rp_nop.nc', ze, 'none')
    call expect_config_error(error, 'rp_bad1.nml', case_namelist(CF, 'rp_nop.nc'), &
                             'no pressure variable; tried pressure, pres, p, PRES')
    call write_les('rp_pname.nc', ze, 'profile_hpa', [950.0e2_wp, 940.0e2_wp, 930.0e2_wp], &
                   pname='PRES')
    call expect_config_error(error, 'rp_bad2.nml', case_namelist(CF, 'rp_pname.nc', &
                             'les_pressure = ''pa'''), 'pressure variable "pa" not found in '// &
                             'the file')
    call write_les('rp_up.nc', ze, 'profile_hpa', [950.0e2_wp, 940.0e2_wp, 945.0e2_wp])
    call expect_config_error(error, 'rp_bad3.nml', case_namelist(CF, 'rp_up.nc'), &
                             'must fall with height, but layer 3 (z = 700 to 800 m) has '// &
                             '94500 Pa >= 94000 Pa of layer 2')
    p3 = 9.0e4_wp
    p3(2, 1, 3) = -1.0_wp
    call write_les('rp_neg_t.nc', ze, '3d_time', p3=p3)
    call expect_config_error(error, 'rp_bad4.nml', case_namelist(CF, 'rp_neg_t.nc', &
                             'les_time_index = 2'), &
                             'value -1 at (x,y,z) = (2,1,3), time step 2 must be > 0')
    call expect_config_error(error, 'rp_bad5.nml', case_namelist('nz = 1, z_levels = 0, '// &
                             '1000, '//CF, ''), 'needs a cloud file (&kumo_cloud cloud_file)')
    ! a MYSTIC file (flag 3): a text format without pressure
    open (newunit=u, file='rp_cloud.mystic', status='replace', action='write')
    write (u, '(a)') '2 2 3 3'
    write (u, '(a)') '0.1 0.1 0.5 0.6 0.7 0.8'
    write (u, '(a)') '1 1 1 0.1 8.0'
    close (u)
    call expect_config_error(error, 'rp_bad6.nml', case_namelist(CF, 'rp_cloud.mystic', &
                             'cloud_format = ''mystic'''), 'only LES netCDF files '// &
                             '(cloud_format = ''les'') have a pressure variable')
  end subroutine test_bad_cloud

  !> Soundings and profile names that are wrong.
  subroutine test_bad_levels(error)
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: LEV = 'nz = 2, z_levels = 0, 1000, 2000, rayleigh_profile '// &
                                         '= ''levels'''
    call expect_config_error(error, 'rp_lev1.nml', case_namelist(LEV, ''), &
                             'needs pressure_levels_hpa, the pressure at each of the nz + 1 = 3')
    call expect_config_error(error, 'rp_lev2.nml', case_namelist(LEV// &
                             ', pressure_levels_hpa = 1000, 900', ''), &
                             'pressure_levels_hpa has 2 values but needs nz + 1 = 3')
    call expect_config_error(error, 'rp_lev3.nml', case_namelist(LEV// &
                             ', pressure_levels_hpa = 1000, 900, 800, 700', ''), &
                             'pressure_levels_hpa has 4 values but needs nz + 1 = 3')
    call expect_config_error(error, 'rp_lev4.nml', case_namelist(LEV// &
                             ', pressure_levels_hpa = 1000, 900, 950', ''), &
                             'pressure_levels_hpa(2) = 950 must be < pressure_levels_hpa(1) = 900')
    call expect_config_error(error, 'rp_lev5.nml', case_namelist(LEV// &
                             ', pressure_levels_hpa = 1000, 0, -5', ''), &
                             'pressure_levels_hpa(1) = 0 must be finite and > 0 [hPa]')
    call expect_config_error(error, 'rp_lev6.nml', case_namelist('nz = 2, z_levels = 0, '// &
                             '1000, 2000, pressure_levels_hpa = 1000, 900, 800', ''), &
                             'pressure_levels_hpa is given but rayleigh_profile = ''us1976''')
    call expect_config_error(error, 'rp_lev7.nml', case_namelist('nz = 2, z_levels = 0, '// &
                             '1000, 2000, rayleigh_profile = ''afgl''', ''), &
                             'rayleigh_profile = ''afgl'' must be one of us1976 (standard '// &
                             'atmospheres), levels (the sounding pressure_levels_hpa) or '// &
                             'cloud_file')
  end subroutine test_bad_levels

end module test_rayleigh_profile_suite

program test_rayleigh_profile
  use test_rayleigh_profile_suite, only: collect_rayleigh_profile
  use kumo_testing, only: run_unittests
  use kumo_parallel, only: par_init, par_finalize
  implicit none
  integer :: n_failed
  ! setup_scene reads cloud files on rank 0 and broadcasts them (one rank in this test)
  call par_init()
  call run_unittests('rayleigh pressure profiles', collect_rayleigh_profile(), n_failed)
  call par_finalize()
  if (n_failed > 0) error stop 1
end program test_rayleigh_profile
