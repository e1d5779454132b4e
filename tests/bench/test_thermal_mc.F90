! SPDX-License-Identifier: BSD-3-Clause
!> Benchmark: kumo's Monte Carlo thermal emission in 1-D and 3-D.
!>
!> * Against an independent discrete-ordinates solver (`tests/data/thermal/
!>   thermal_1d_reference.csv`, PythonicDISORT, 64-400 streams): thin and thick absorbing layers,
!>   a temperature inversion, a cloud layer with Henyey-Greenstein g = 0.85 and with the C.1 Mie
!>   phase function (its 300 Legendre moments as a table), and a scattering haze, over a Lambert surface with emissivity < 1 and under an isotropic top radiance. kumo
!>   integrates the band Planck function itself from the temperatures. Every flux (up and down
!>   at every level) and every radiance of the file must agree within 4 sigma + the
!>   reference's own error (its `solver_error`, the change from the coarser stream number) +
!>   1e-6 relative.
!> * Isothermal enclosures: an isothermal atmosphere (clear, absorbing, scattering layers; and a
!>   3-D field of random voxels) over a black surface at the same temperature under a sky of
!>   B(T): every radiance is B(T) and every flux pi B(T), within 4.5 sigma (5 for the 360
!>   per-column radiances; see K_SIGMA_ENCLOSURE), their RMS deviation 0.7-1.3 sigma, and every net power
!>   (layer, voxel, surface) is zero to round-off: the net-exchange estimator makes it exact.
!> * Energy closure: launched = escaped + absorbed (to 1e-10 relative) in every run.
module test_kumo_thermal_mc
  use kumo_kinds, only: wp, dp, i8
  use kumo_constants, only: PI
  use kumo_error, only: error_t, set_error, str
  use kumo_config, only: config_t
  use kumo_results, only: result_set_t, find_var, add_dim, add_var
  use kumo_netcdf, only: write_results
  use kumo_testing, only: unittest_t, new_unittest, check
  use kumo_test_text, only: split, open_text
  use kumo_test_scenes, only: set_phases, run_config, attach_scene
  use kumo_planck, only: spectral_band_t, band_from_wavenumbers, band_radiance
  use kumo_rng, only: rng_t, rng_init, rng_uniform
  use kumo_brdf, only: brdf_params, BRDF_RPV
  use kumo_phase, only: PHASE_TABLE
  implicit none
  private
  public :: collect_thermal_mc, set_table

  real(dp), parameter :: K_SIGMA = 4.0_dp
  !> The 360 per-column radiances of the 3-D enclosure: with 40 batches the deviations follow
  !> Student's t with 39 degrees of freedom (local estimates add a heavier tail), whose 4-sigma
  !> tail (2.7e-4 two-sided) would fail one of 360 values one run in ten; 5 sigma (1.3e-5) keeps
  !> false alarms below 1 %, while the RMS check below keeps the power to see a bias.
  real(dp), parameter :: K_SIGMA_MAPS = 5.0_dp
  !> The enclosures' radiances and fluxes: about 100 values over the enclosure runs, so a 4-sigma
  !> rule per value (2.7e-4 two-sided for t with 39 degrees of freedom) would raise a false alarm
  !> in about 3 % of runs; 4.5 sigma (6e-5) keeps it below 1 %, and the RMS check keeps the power
  !> to see a bias. (Twelve seeds of the surface-map enclosure: RMS 1.00 sigma, largest 3.4.)
  real(dp), parameter :: K_SIGMA_ENCLOSURE = 4.5_dp
  character(len=16), parameter :: CASES(6) = [character(len=16) :: 'thin_absorbing', &
    'thick_absorbing', 'inversion', 'cloud_hg', 'haze_hg', 'cloud_c1']

  type :: row_t
    character(len=24) :: id = '', q = ''
    integer :: i = 0
    real(dp) :: mu = 0.0_dp, v = 0.0_dp, err = 0.0_dp
  end type row_t

  !> Comparison counts over the cases of a run: all, failed, beyond 2 sigma, the sum of squared
  !> deviations in sigma, and the failures' descriptions.
  type :: tally_of_cases_t
    integer :: n_cmp = 0, n_fail = 0, n2 = 0
    real(dp) :: ss = 0.0_dp
    character(len=:), allocatable :: fails
  end type tally_of_cases_t

  character(len=:), allocatable :: table_path
  type(row_t), allocatable :: rows(:)

contains

  subroutine set_table(path)
    character(len=*), intent(in) :: path
    table_path = path
  end subroutine set_table

  function collect_thermal_mc() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('discrete_ordinates_1d', test_reference), &
             new_unittest('exact_non_scattering_columns', test_exact), &
             new_unittest('isothermal_1d', test_isothermal_1d), &
             new_unittest('isothermal_3d', test_isothermal_3d), &
             new_unittest('isothermal_voxel_temperatures', test_isothermal_voxels), &
             new_unittest('isothermal_brdf_surface', test_isothermal_brdf), &
             new_unittest('surface_temperature_map', test_surface_map)]
  end function collect_thermal_mc

  !> Every flux and radiance of the five cases within 4 sigma + the reference's error.
  subroutine test_reference(error)
    type(error_t), allocatable, intent(out) :: error
    type(tally_of_cases_t) :: t
    call run_cases(size(CASES), 7100_i8, .false., t, error)
    if (allocated(error)) return
    print '(a,i0,a,f6.3,a,i0)', 'discrete-ordinates comparisons: ', t%n_cmp, ', RMS deviation ', &
      sqrt(t%ss/t%n_cmp), ' sigma, beyond 2 sigma: ', t%n2
    call check(error, t%n_cmp >= 40, 'too few comparisons: '//str(t%n_cmp))
    call check(error, t%n_fail == 0, str(t%n_fail)//' comparisons beyond 4 sigma:'//t%fails)
    call check(error, sqrt(t%ss/t%n_cmp) < 1.5_dp, 'RMS deviation '//str(sqrt(t%ss/t%n_cmp))// &
               ' sigma: error bars too small')
  end subroutine test_reference

  !> The three non-scattering cases solved exactly instead of traced (the default for such
  !> columns): every flux and radiance equals the discrete-ordinates reference to its own
  !> error, with standard error 0.
  subroutine test_exact(error)
    type(error_t), allocatable, intent(out) :: error
    type(tally_of_cases_t) :: t
    call run_cases(3, 7200_i8, .true., t, error)
    if (allocated(error)) return
    call check(error, t%n_cmp >= 20, 'too few comparisons: '//str(t%n_cmp))
    call check(error, t%n_fail == 0, str(t%n_fail)//' values differ from the reference:'// &
               t%fails)
  end subroutine test_exact

  !> Run the first `n` cases of CASES (seeds seed0 + case number), traced or (`exact`) solved
  !> exactly where possible, and count their comparisons.
  subroutine run_cases(n, seed0, exact, t, error)
    integer, intent(in) :: n
    integer(i8), intent(in) :: seed0
    logical, intent(in) :: exact
    type(tally_of_cases_t), intent(out) :: t
    type(error_t), allocatable, intent(out) :: error
    integer :: c
    call read_table(error)
    if (allocated(error)) return
    t%fails = ''
    do c = 1, n
      call run_reference_case(trim(CASES(c)), seed0 + c, exact, t%n_cmp, t%n_fail, t%n2, t%ss, &
                              t%fails, error)
      if (allocated(error)) return
    end do
  end subroutine run_cases

  subroutine read_table(error)
    type(error_t), allocatable, intent(out) :: error
    integer :: u, ios, n
    character(len=256) :: line
    character(len=64) :: f(8)
    type(row_t) :: r
    if (allocated(rows)) return
    call open_text(table_path, u, error)
    if (allocated(error)) return
    allocate (rows(0))
    do
      read (u, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (line(1:1) == '#' .or. line(1:5) == 'case,') cycle
      call split(trim(line), ',', f, n)
      if (n < 5) cycle
      r%id = f(1)
      r%q = f(2)
      read (f(3), *) r%i
      r%mu = 0.0_dp
      if (len_trim(f(4)) > 0) read (f(4), *) r%mu
      read (f(5), *) r%v
      r%err = 0.0_dp
      if (n >= 6) then
        if (len_trim(f(6)) > 0) read (f(6), *) r%err
      end if
      rows = [rows, r]
    end do
    close (u)
  end subroutine read_table

  function vals(id, q) result(v)
    character(len=*), intent(in) :: id, q
    real(dp), allocatable :: v(:)
    v = pack(rows%v, rows%id == id .and. rows%q == q)
  end function vals

  subroutine run_reference_case(id, seed, exact, n_cmp, n_fail, n2, ss, fails, error)
    character(len=*), intent(in) :: id
    integer(i8), intent(in) :: seed
    logical, intent(in) :: exact   !! allow the exact solution of non-scattering columns
    integer, intent(inout) :: n_cmp, n_fail, n2
    real(dp), intent(inout) :: ss
    character(len=:), allocatable, intent(inout) :: fails
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: set
    real(dp), allocatable :: z(:), tau(:), ssa(:), g(:), mus(:)
    integer, allocatable :: ph(:)
    integer :: nz, k, j, iv, is, nd, slot
    character(len=8), allocatable :: names(:)
    real(dp) :: x, s, ref, tol
    z = vals(id, 'z_m')
    tau = vals(id, 'tau')
    ssa = vals(id, 'ssa')
    ph = nint(vals(id, 'phase'))
    nz = size(tau)
    allocate (g(nz), names(nz))
    g = 0.0_dp
    do k = 1, nz
      names(k) = 'iso'
      if (ph(k) == 1) then
        names(k) = 'hg'
        g(k) = pick(id, 'hg_g', k)
      end if
    end do
    cfg%path = 'thermal_mc.nml'
    cfg%atm%nz = nz
    cfg%atm%z = z
    cfg%atm%lx = 1000.0_wp
    cfg%atm%ly = 1000.0_wp
    cfg%atm%n_components = 1
    allocate (cfg%atm%ext1d(nz, 1), cfg%atm%ssa1d(nz, 1), cfg%atm%phase1d(nz, 1))
    cfg%atm%ext1d(:, 1) = tau/(z(2:) - z(:nz))
    cfg%atm%ssa1d(:, 1) = ssa
    cfg%atm%phase1d(:, 1) = [(k, k=1, nz)]
    cfg%atm%phase3d = [1]
    call set_phases(cfg, names, real(g, wp))
    do k = 1, nz
      if (ph(k) == 2) then
        ! the Legendre series of the file as a table kumo reads (angle [deg], value)
        call write_legendre_table('thermal_'//id//'_phase.txt', &
                                  pack(rows%v, rows%id == id .and. rows%q == 'chi_'//str(k)))
        cfg%phase%kind(k) = PHASE_TABLE
        cfg%phase%kind_name(k) = 'table'
        cfg%phase%file(k) = 'thermal_'//id//'_phase.txt'
      end if
    end do
    cfg%surface%albedo = 1.0_wp - vals1('surface_emissivity')
    cfg%thermal%enabled = .true.
    cfg%thermal%t_levels = vals(id, 'temperature_K')
    cfg%thermal%t_surface = vals1('surface_temperature_K')
    cfg%thermal%t_top = vals1('top_temperature_K')
    cfg%thermal%wavenumber_lo = vals1('band_nu1_cm-1')
    cfg%thermal%wavenumber_hi = vals1('band_nu2_cm-1')
    cfg%output%flux_levels = [(k, k=0, nz)]
    ! radiances: upward at the top, downward at the surface
    mus = pack(rows%mu, rows%id == id .and. rows%q == 'radiance')
    nd = size(mus)
    cfg%rad%mu = mus
    allocate (cfg%rad%phi_deg(nd))
    cfg%rad%phi_deg = 0.0_wp
    cfg%rad%levels = [0, nz]
    cfg%rad%maps = .false.
    cfg%control%n_photons_per_batch = 4000_i8
    if (any(tau*(1.0_dp - ssa) > 5.0_dp) .or. any(tau > 5.0_dp)) cfg%control%n_photons_per_batch = 3000_i8
    cfg%control%n_batches = 40
    if (exact) cfg%control%n_batches = 2
    cfg%vr%use_exact_thermal = exact
    cfg%control%seed = seed
    cfg%control%verbose = 0
    call run_config(cfg, set, error)
    if (allocated(error)) return
    call check(error, abs(value_of('energy_closure', 1) - 1.0_dp) < 1.0e-10_dp, id// &
               ': energy closure '//str(value_of('energy_closure', 1)))
    if (allocated(error)) return
    do j = 1, size(rows)
      if (rows(j)%id /= id) cycle
      select case (trim(rows(j)%q))
      case ('flux_up')
        x = value_of('flux_up_wm2', rows(j)%i + 1)
        s = error_of('flux_up_wm2', rows(j)%i + 1)
      case ('flux_down')
        x = value_of('flux_down_wm2', rows(j)%i + 1)
        s = error_of('flux_down_wm2', rows(j)%i + 1)
      case ('radiance')
        is = findloc(mus, rows(j)%mu, 1)
        slot = merge(1, 2, rows(j)%i == 0)
        x = value_of('radiance_wm2sr', slot + (is - 1)*2)
        s = error_of('radiance_wm2sr', slot + (is - 1)*2)
      case default
        cycle
      end select
      ref = rows(j)%v
      tol = K_SIGMA*s + rows(j)%err + 1.0e-6_dp*abs(ref)
      if (exact) then
        ! the exact solution: no Monte Carlo error; the reference's own error and the 11
        ! printed digits remain
        tol = rows(j)%err + 1.0e-8_dp*maxval(abs(vals(id, 'flux_up'))) + 1.0e-10_dp*abs(ref)
        if (s /= 0.0_dp) tol = -1.0_dp
      end if
      n_cmp = n_cmp + 1
      if (s > 0.0_dp) then
        ss = ss + ((x - ref)/s)**2
        if (abs(x - ref) > 2.0_dp*s) n2 = n2 + 1
      end if
      if (abs(x - ref) > tol) then
        n_fail = n_fail + 1
        fails = fails//' '//id//' '//trim(rows(j)%q)//'('//str(rows(j)%i)//') kumo '//str(x)// &
                ' +- '//str(s)//' ref '//str(ref)//';'
      end if
    end do
    iv = 0
  contains
    real(dp) function vals1(q) result(x1)
      character(len=*), intent(in) :: q
      real(dp), allocatable :: v(:)
      v = vals(id, q)
      x1 = 0.0_dp
      if (size(v) > 0) x1 = v(1)
    end function vals1
    real(dp) function value_of(name, pos) result(y)
      character(len=*), intent(in) :: name
      integer, intent(in) :: pos
      y = set%vars(find_var(set, name))%mean(pos)
    end function value_of
    real(dp) function error_of(name, pos) result(y)
      character(len=*), intent(in) :: name
      integer, intent(in) :: pos
      y = set%vars(find_var(set, name))%stderr(pos)
    end function error_of
  end subroutine run_reference_case

  !> Write the phase function sum_l (2l + 1) chi_l P_l(cos theta) of the moments `chi` (chi_0 =
  !> 1 first) at 0.02 degree steps, as kumo's two-column table (a strongly peaked function such
  !> as C.1 needs the fine steps near the forward direction; C.1's series is positive everywhere,
  !> a negative value would be written as 0).
  subroutine write_legendre_table(path, chi)
    character(len=*), intent(in) :: path
    real(dp), intent(in) :: chi(:)
    integer :: u, j, l
    real(dp) :: th, mu, p0, p1, p2, v
    open (newunit=u, file=path, status='replace', action='write')
    do j = 0, 9000
      th = 0.02_dp*j
      mu = cos(th*PI/180.0_dp)
      p0 = 1.0_dp
      p1 = mu
      v = chi(1) + 3.0_dp*chi(2)*mu
      do l = 2, size(chi) - 1
        p2 = ((2*l - 1)*mu*p1 - (l - 1)*p0)/l
        v = v + (2*l + 1)*chi(l + 1)*p2
        p0 = p1
        p1 = p2
      end do
      write (u, '(f8.3,1x,es23.15)') th, max(0.0_dp, v)
    end do
    close (u)
  end subroutine write_legendre_table

  real(dp) function pick(id, q, i) result(x)
    character(len=*), intent(in) :: id, q
    integer, intent(in) :: i
    integer :: j
    x = 0.0_dp
    do j = 1, size(rows)
      if (rows(j)%id == id .and. rows(j)%q == q .and. rows(j)%i == i) x = rows(j)%v
    end do
  end function pick

  !> An isothermal column (clear, absorbing, scattering layers) over a black surface under a
  !> sky of B(T): radiances B, fluxes pi B, net powers 0.
  subroutine test_isothermal_1d(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    call isothermal_config(cfg)
    call check_isothermal(cfg, .false., error)
  end subroutine test_isothermal_1d

  !> The same with a 3-D region of random voxels (extinction 0 to 0.02 m-1, single-scattering
  !> albedo 0 to 1, HG g = 0.85) in layers 2-3.
  subroutine test_isothermal_3d(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(rng_t) :: rng
    real(wp) :: ext(6, 5, 2), ssa(6, 5, 2)
    integer :: i, j, k
    call rng_init(rng, 99_i8, 1_i8)
    do k = 1, 2
      do j = 1, 5
        do i = 1, 6
          ext(i, j, k) = 0.02_wp*rng_uniform(rng)**2
          ssa(i, j, k) = rng_uniform(rng)
        end do
      end do
    end do
    call isothermal_config(cfg)
    call attach_scene(cfg, 'thermal_iso3d.nc', 2, ext, ssa, 3, error)
    if (allocated(error)) return
    cfg%rad%maps = .true.
    call check_isothermal(cfg, .true., error)
  end subroutine test_isothermal_3d

  !> The same 3-D field with its voxel temperatures in the scene file (all 275 K): the voxels
  !> emit uniformly from their own Planck radiance.
  subroutine test_isothermal_voxels(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(rng_t) :: rng
    real(wp) :: ext(4, 3, 2), ssa(4, 3, 2), t(4, 3, 2)
    integer :: i, j, k
    call rng_init(rng, 98_i8, 1_i8)
    do k = 1, 2
      do j = 1, 3
        do i = 1, 4
          ext(i, j, k) = 0.05_wp*rng_uniform(rng)**2
          ssa(i, j, k) = rng_uniform(rng)
        end do
      end do
    end do
    t = 275.0_wp
    call isothermal_config(cfg)
    call attach_scene(cfg, 'thermal_iso3d_t.nc', 2, ext, ssa, 3, error, temperature=t)
    if (allocated(error)) return
    call check_isothermal(cfg, .true., error)
    if (allocated(error)) return
    ! voxels warmer than the enclosure cool, and only they
    t = 300.0_wp
    call attach_scene(cfg, 'thermal_iso3d_t.nc', 2, ext, ssa, 3, error, temperature=t)
    if (allocated(error)) return
    call check_warm_voxels(cfg, error)
  end subroutine test_isothermal_voxels

  !> Kirchhoff's law at a BRDF surface: the isothermal enclosure over an RPV surface at the
  !> same temperature, which emits with the directional emissivity 1 - alpha(mu) and reflects by
  !> its BRDF. Only the two together give radiances B in every direction.
  subroutine test_isothermal_brdf(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    call isothermal_config(cfg)
    cfg%surface%brdf = 'rpv'
    cfg%surface%model = brdf_params(BRDF_RPV, [0.3_wp, 0.7_wp, -0.2_wp, 0.25_wp])
    call check_isothermal(cfg, .false., error)
  end subroutine test_isothermal_brdf

  !> A surface temperature map (its own grid, 2 x 2 pixels) under an albedo map on another grid
  !> (3 x 1): in an isothermal enclosure the map at the enclosure's temperature changes nothing;
  !> under a transparent atmosphere and space, the upward flux at the top is pi <eps B>, the
  !> area mean of emissivity times Planck radiance over the overlaps of the two grids (computed
  !> here on a fine sampling of the domain).
  subroutine test_surface_map(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: tfile, afile, set
    type(spectral_band_t) :: band
    real(dp) :: t(2, 2), alb(3, 1), ref, x, y
    integer :: i, j, iv
    call add_dim(afile, 'xs', 3)
    call add_dim(afile, 'ys', 1)
    alb(:, 1) = [0.0_dp, 0.3_dp, 0.1_dp]
    call add_var(afile, 'albedo', 'surface albedo', '1', ['xs', 'ys'], reshape(alb, [3]))
    call write_results('thermal_albedo_map.nc', afile, error)
    if (allocated(error)) return
    ! the enclosure: every pixel 275 K
    t = 275.0_dp
    call write_map(t)
    if (allocated(error)) return
    call isothermal_config(cfg)
    cfg%surface%albedo_file = 'thermal_albedo_map.nc'
    cfg%thermal%t_surface = -1.0_wp
    cfg%thermal%t_surface_file = 'thermal_t_surface.nc'
    call check_isothermal(cfg, .false., error)
    if (allocated(error)) return
    ! transparent column under space: flux up at the top = pi <eps B>
    t = reshape([260.0_dp, 300.0_dp, 280.0_dp, 310.0_dp], [2, 2])
    call write_map(t)
    if (allocated(error)) return
    cfg%atm%ext1d = 0.0_wp
    cfg%thermal%t_top = 0.0_wp
    cfg%rad%mu = [1.0_wp]
    cfg%rad%phi_deg = [0.0_wp]
    cfg%rad%levels = [4]
    call run_config(cfg, set, error)
    if (allocated(error)) return
    call band_from_wavenumbers(500.0_wp, 1500.0_wp, band, error)
    if (allocated(error)) return
    ref = 0.0_dp
    do j = 1, 1000
      y = (j - 0.5_dp)/1000.0_dp
      do i = 1, 1200
        x = (i - 0.5_dp)/1200.0_dp
        ref = ref + (1.0_dp - alb(int(3*x) + 1, 1))*band_radiance(band, t(int(2*x) + 1, int(2*y) + 1))
      end do
    end do
    ref = PI*ref/(1000.0_dp*1200.0_dp)
    iv = find_var(set, 'flux_up_wm2')
    associate (m => set%vars(iv)%mean(5), e => set%vars(iv)%stderr(5))
      call check(error, abs(m - ref) <= K_SIGMA*e .and. e > 0.0_dp, 'flux up at the top over '// &
                 'a surface temperature map: '//str(m)//' +- '//str(e)//', expected pi <eps B> '// &
                 '= '//str(ref))
    end associate
    if (allocated(error)) return
    ! the nadir radiance at the top averages eps B (Lambert: no direction dependence)
    iv = find_var(set, 'radiance_wm2sr')
    associate (m => set%vars(iv)%mean(1), e => set%vars(iv)%stderr(1))
      call check(error, abs(m - ref/PI) <= K_SIGMA*e + 1.0e-9_dp*ref, 'nadir radiance at the '// &
                 'top over a surface temperature map: '//str(m)//' +- '//str(e)//', expected '// &
                 str(ref/PI))
    end associate
  contains
    subroutine write_map(tt)
      real(dp), intent(in) :: tt(:, :)
      type(result_set_t) :: f
      call add_dim(f, 'xs', size(tt, 1))
      call add_dim(f, 'ys', size(tt, 2))
      call add_var(f, 't_surface', 'surface temperature', 'K', ['xs', 'ys'], reshape(tt, [size(tt)]))
      call write_results('thermal_t_surface.nc', f, error)
    end subroutine write_map
  end subroutine test_surface_map

  subroutine check_warm_voxels(cfg, error)
    type(config_t), intent(in) :: cfg
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: set
    integer :: iv
    call run_config(cfg, set, error)
    if (allocated(error)) return
    iv = find_var(set, 'net_power_density_voxel')
    call check(error, iv > 0, 'net_power_density_voxel missing')
    if (allocated(error)) return
    associate (m => set%vars(iv)%mean, e => set%vars(iv)%stderr)
      ! every exchange partner is colder: each photon of a voxel can only take power from it
      call check(error, all(m <= 0.0_dp) .and. sum(m) < -4.0_dp*sqrt(sum(e*e)), 'voxels at '// &
                 '300 K in a 275 K enclosure do not cool: largest net '//str(maxval(m))// &
                 ', sum '//str(sum(m)))
    end associate
  end subroutine check_warm_voxels

  subroutine isothermal_config(cfg)
    type(config_t), intent(out) :: cfg
    cfg%path = 'thermal_iso.nml'
    cfg%atm%nz = 4
    cfg%atm%z = [0.0_wp, 500.0_wp, 1000.0_wp, 1500.0_wp, 3000.0_wp]
    cfg%atm%lx = 1200.0_wp
    cfg%atm%ly = 1000.0_wp
    cfg%atm%n_components = 1
    allocate (cfg%atm%ext1d(4, 1), cfg%atm%ssa1d(4, 1), cfg%atm%phase1d(4, 1))
    cfg%atm%ext1d(:, 1) = [2.0e-3_wp, 0.0_wp, 4.0e-3_wp, 1.0e-3_wp]
    cfg%atm%ssa1d(:, 1) = [0.0_wp, 0.0_wp, 0.7_wp, 0.3_wp]
    cfg%atm%phase1d(:, 1) = [1, 1, 2, 3]
    cfg%atm%phase3d = [3]
    cfg%atm%air_density = [1.2_wp, 1.1_wp, 1.0_wp, 0.9_wp]
    call set_phases(cfg, [character(len=8) :: 'iso', 'rayleigh', 'hg'], [0.0_wp, 0.0_wp, 0.85_wp])
    cfg%surface%albedo = 0.0_wp
    cfg%thermal%enabled = .true.
    cfg%thermal%t_levels = [275.0_wp, 275.0_wp, 275.0_wp, 275.0_wp, 275.0_wp]
    cfg%thermal%t_surface = 275.0_wp
    cfg%thermal%t_top = 275.0_wp
    cfg%thermal%wavenumber_lo = 500.0_wp
    cfg%thermal%wavenumber_hi = 1500.0_wp
    cfg%output%flux_levels = [0, 1, 2, 3, 4]
    cfg%rad%mu = [1.0_wp, 0.3_wp, -0.6_wp, -1.0_wp]
    cfg%rad%phi_deg = [0.0_wp, 30.0_wp, 200.0_wp, 0.0_wp]
    cfg%rad%levels = [0, 2, 4]
    cfg%rad%maps = .false.
    cfg%control%n_photons_per_batch = 2500_i8
    cfg%control%n_batches = 40
    cfg%control%seed = 4242_i8
    cfg%control%verbose = 0
  end subroutine isothermal_config

  subroutine check_isothermal(cfg, three_d, error)
    type(config_t), intent(in) :: cfg
    logical, intent(in) :: three_d
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: set
    type(spectral_band_t) :: band
    real(dp) :: b, emitted
    integer :: n_bad, ns
    real(dp) :: ss
    character(len=:), allocatable :: what
    call band_from_wavenumbers(500.0_wp, 1500.0_wp, band, error)
    if (allocated(error)) return
    b = band_radiance(band, 275.0_wp)
    call run_config(cfg, set, error)
    if (allocated(error)) return
    n_bad = 0
    ns = 0
    ss = 0.0_dp
    what = ''
    call within('radiance_wm2sr', b)
    call within('flux_up_wm2', PI*b)
    call within('flux_down_wm2', PI*b)
    if (three_d .and. cfg%rad%maps) call within('radiance_map', b)
    call check(error, n_bad == 0, str(n_bad)//' values differ from B(T) or pi B(T) by more '// &
               'than 4.5 sigma (5 for maps):'//what)
    if (allocated(error)) return
    ! the RMS of n deviations scatters by about 1/sqrt(2 n): a meaningful check from 50 values
    if (ns >= 50) call check(error, sqrt(ss/ns) > 0.7_dp .and. sqrt(ss/ns) < 1.3_dp, &
                             'RMS deviation from B(T) = '//str(sqrt(ss/ns))//' sigma, outside '// &
                             '[0.7, 1.3]: error bars not honest')
    if (allocated(error)) return
    emitted = sum(set%vars(find_var(set, 'emitted_power_layer'))%mean)
    call zero('net_power_layer')
    call zero('net_power_surface')
    call zero('heating_rate_layer')
    if (three_d) call zero('net_power_density_voxel')
    if (allocated(error)) return
    call check(error, abs(set%vars(find_var(set, 'energy_closure'))%mean(1) - 1.0_dp) < 1.0e-10_dp, &
               'energy closure '//str(set%vars(find_var(set, 'energy_closure'))%mean(1)))
  contains
    subroutine within(name, ref)
      character(len=*), intent(in) :: name
      real(dp), intent(in) :: ref
      integer :: iv, i
      real(dp) :: scale, k
      iv = find_var(set, name)
      if (iv == 0) then
        n_bad = n_bad + 1
        what = what//' '//name//' missing;'
        return
      end if
      scale = 1.0_dp
      k = K_SIGMA_ENCLOSURE
      if (name == 'radiance_map') then
        scale = set%vars(find_var(set, 'source_power'))%mean(1)/PI
        k = K_SIGMA_MAPS
      end if
      do i = 1, size(set%vars(iv)%mean)
        associate (x => set%vars(iv)%mean(i)*scale, s => set%vars(iv)%stderr(i)*scale)
          if (s > 0.0_dp) then
            ss = ss + ((x - ref)/s)**2
            ns = ns + 1
          end if
          if (abs(x - ref) > k*s + 1.0e-9_dp*ref) then
            n_bad = n_bad + 1
            what = what//' '//name//'('//str(i)//') = '//str(x)//' +- '//str(s)//';'
          end if
        end associate
      end do
    end subroutine within
    subroutine zero(name)
      character(len=*), intent(in) :: name
      integer :: iv
      iv = find_var(set, name)
      call check(error, iv > 0, name//' missing')
      if (allocated(error)) return
      call check(error, maxval(abs(set%vars(iv)%mean)) <= 1.0e-9_dp*emitted, name// &
                 ' is not zero in an isothermal enclosure: '//str(maxval(abs(set%vars(iv)%mean))))
    end subroutine zero
  end subroutine check_isothermal

end module test_kumo_thermal_mc

program test_thermal_mc
  use kumo_test_text, only: run_suite
  use test_kumo_thermal_mc, only: collect_thermal_mc, set_table
  implicit none
  character(len=4096) :: arg
  call get_command_argument(1, arg)
  call set_table(trim(arg))
  call run_suite('thermal_mc', collect_thermal_mc())
end program test_thermal_mc
