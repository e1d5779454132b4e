! SPDX-License-Identifier: BSD-3-Clause
!> Thermal emission with the voxel temperatures of a cloud file (&kumo_cloud with &kumo_thermal).
!>
!> * An LES file whose temperature is 275 K everywhere, in an isothermal enclosure (t_levels,
!>   t_surface and t_top 275 K, black surface, a gray gas in every layer): every radiance is
!>   B(T) and every flux pi B(T) within 4 sigma, every net power (layer, voxel, surface) is 0 to
!>   round-off (1e-9 of the emitted power).
!> * The mapping onto the 3-D region: with a temperature field T(i, j, k) = 270 + i + 2 j + 3 k
!>   the emitted power of every voxel is the isothermal one times B(T(i, j, k))/B(275 K)
!>   (1e-6), for the temperature variable, for a potential temperature with a 3-D pressure
!>   (T = theta (p/p0)^(2/7)), and for the temperature profile of an LWC file (a voxel between
!>   two heights emits the mean Planck radiance of the two).
!>   An MCARaTS file: t_levels plus tmpa3d per level, the mean Planck radiance of the two levels;
!>   a perturbation that makes a temperature negative is refused.
!> * A file without temperature: the voxels emit the level values, and the log says so.
!> * Bad input: a temperature of the wrong shape, a negative and a NaN temperature are refused
!>   with a message naming the file and the variable.
module test_kumo_thermal_cloud
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use, intrinsic :: iso_fortran_env, only: real32
  use kumo_kinds, only: wp, dp
  use kumo_constants, only: PI
  use kumo_error, only: error_t, str
  use kumo_results, only: result_set_t, find_var
  use kumo_testing, only: unittest_t, new_unittest, check
  use kumo_test_scenes, only: run_namelist, run_groups
  use kumo_planck, only: spectral_band_t, band_from_wavenumbers, band_radiance
  use netcdf, only: nf90_create, nf90_def_dim, nf90_def_var, nf90_enddef, nf90_put_var, &
                    nf90_close, nf90_put_att, nf90_clobber, nf90_double
  implicit none
  private
  public :: collect_thermal_cloud

  integer, parameter :: NX = 4, NY = 3, NZ = 3
  real(wp), parameter :: DX_KM = 0.1_wp, DY_KM = 0.12_wp
  !> layer edges of the cloud [km], above a layer from the ground
  real(wp), parameter :: ZE_KM(0:NZ) = [0.5_wp, 0.6_wp, 0.75_wp, 0.85_wp]
  real(wp), parameter :: T0 = 275.0_wp
  real(wp), parameter :: NU1 = 900.0_wp, NU2 = 960.0_wp
  real(dp), parameter :: K_SIGMA = 4.0_dp
  character(len=*), parameter :: NL = new_line('a')

contains

  function collect_thermal_cloud() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('les_isothermal_enclosure', test_isothermal), &
             new_unittest('les_voxel_mapping', test_mapping), &
             new_unittest('les_without_temperature', test_no_temperature), &
             new_unittest('lwc_file_profile', test_lwc_profile), &
             new_unittest('mcarats_tmpa3d', test_mcarats), &
             new_unittest('bad_temperatures', test_bad)]
  end function collect_thermal_cloud

  !> The test cloud: LWC [g m-3] and r_eff [um]; some voxels clear.
  subroutine cloud(lwc, reff)
    real(wp), intent(out) :: lwc(NX, NY, NZ), reff(NX, NY, NZ)
    integer :: i, j, k
    do k = 1, NZ
      do j = 1, NY
        do i = 1, NX
          lwc(i, j, k) = 0.08_wp*real(mod(i*3 + j*5 + k*7, 6), wp)
          reff(i, j, k) = 5.0_wp + 1.3_wp*real(mod(i + 2*j + 3*k, 7), wp)
          if (lwc(i, j, k) == 0.0_wp) reff(i, j, k) = 0.0_wp
        end do
      end do
    end do
  end subroutine cloud

  !> The varying temperature field [K]: distinct along every axis, exact in single precision.
  pure function t_field() result(t)
    real(wp) :: t(NX, NY, NZ)
    integer :: i, j, k
    do k = 1, NZ
      do j = 1, NY
        do i = 1, NX
          t(i, j, k) = 270.0_wp + i + 2*j + 3*k
        end do
      end do
    end do
  end function t_field

  !> An LES file with the cloud and, as `kind` says, 'temperature' (values t), 'theta' (the
  !> potential temperature of t with a 3-D pressure), 'none', or the bad variants 'shape' (a
  !> temperature over (y, x) only).
  subroutine write_les(path, kind, t)
    character(len=*), intent(in) :: path, kind
    real(wp), intent(in) :: t(NX, NY, NZ)
    real(wp) :: lwc(NX, NY, NZ), reff(NX, NY, NZ), p(NX, NY, NZ)
    integer :: nc, dx_, dy_, dz_, dze, vx, vy, vze, vl, vr, vt, vp_, s, i, j, k
    call cloud(lwc, reff)
    s = nf90_create(path, nf90_clobber, nc)
    s = nf90_def_dim(nc, 'x', NX, dx_)
    s = nf90_def_dim(nc, 'y', NY, dy_)
    s = nf90_def_dim(nc, 'z', NZ, dz_)
    s = nf90_def_dim(nc, 'z_edges', NZ + 1, dze)
    s = nf90_def_var(nc, 'x', nf90_double, [dx_], vx)
    s = nf90_put_att(nc, vx, 'units', 'km')
    s = nf90_def_var(nc, 'y', nf90_double, [dy_], vy)
    s = nf90_put_att(nc, vy, 'units', 'km')
    s = nf90_def_var(nc, 'z_edges', nf90_double, [dze], vze)
    s = nf90_put_att(nc, vze, 'units', 'km')
    s = nf90_def_var(nc, 'lwc', nf90_double, [dx_, dy_, dz_], vl)
    s = nf90_put_att(nc, vl, 'units', 'g m-3')
    s = nf90_def_var(nc, 'reff', nf90_double, [dx_, dy_, dz_], vr)
    s = nf90_put_att(nc, vr, 'units', 'um')
    select case (kind)
    case ('temperature')
      s = nf90_def_var(nc, 'temperature', nf90_double, [dx_, dy_, dz_], vt)
      s = nf90_put_att(nc, vt, 'units', 'K')
    case ('shape')
      s = nf90_def_var(nc, 'temperature', nf90_double, [dx_, dy_], vt)
      s = nf90_put_att(nc, vt, 'units', 'K')
    case ('theta')
      s = nf90_def_var(nc, 'theta', nf90_double, [dx_, dy_, dz_], vt)
      s = nf90_put_att(nc, vt, 'units', 'K')
      s = nf90_def_var(nc, 'p', nf90_double, [dx_, dy_, dz_], vp_)
      s = nf90_put_att(nc, vp_, 'units', 'hPa')
    case default   ! 'none': no temperature
    end select
    s = nf90_enddef(nc)
    s = nf90_put_var(nc, vx, [((i - 0.5_wp)*DX_KM, i=1, NX)])
    s = nf90_put_var(nc, vy, [((i - 0.5_wp)*DY_KM, i=1, NY)])
    s = nf90_put_var(nc, vze, ZE_KM)
    s = nf90_put_var(nc, vl, lwc)
    s = nf90_put_var(nc, vr, reff)
    select case (kind)
    case ('temperature')
      s = nf90_put_var(nc, vt, t)
    case ('shape')
      s = nf90_put_var(nc, vt, t(:, :, 1))
    case ('theta')
      do k = 1, NZ
        do j = 1, NY
          do i = 1, NX
            p(i, j, k) = 950.0_wp - 10.0_wp*k + 0.5_wp*i - 0.25_wp*j   ! [hPa]
          end do
        end do
      end do
      s = nf90_put_var(nc, vt, t*(1000.0_wp/p)**(2.0_wp/7.0_wp))
      s = nf90_put_var(nc, vp_, p)
    case default
    end select
    s = nf90_close(nc)
  end subroutine write_les

  !> The namelist of a thermal run with the cloud file `file`: an isothermal enclosure at T0
  !> (levels, surface, top), a gray gas, 900-960 cm-1, the droplet optics at 10.7 um.
  function thermal_nml(file, fmt, out, n_photons, n_batches, radiances) result(text)
    character(len=*), intent(in) :: file, fmt, out
    integer, intent(in) :: n_photons, n_batches
    logical, intent(in) :: radiances
    character(len=:), allocatable :: text
    text = run_groups(n_photons, n_batches, 17, 'wavelength_um = 10.7', out, 'albedo = 0.0')// &
           '&kumo_atmosphere nz = 5, z_levels = 0.0, 500.0, 600.0, 750.0, 850.0, 2000.0, '// &
           'n_components = 1, ext1d(:,1) = 1.5e-4, 1.5e-4, 1.5e-4, 1.5e-4, 5.0e-5, '// &
           'ssa1d(:,1) = 0.0, 0.0, 0.0, 0.0, 0.0, phase1d(:,1) = 1, 1, 1, 1, 1, '// &
           'air_density = 1.2, 1.15, 1.12, 1.1, 1.0 /'//NL// &
           '&kumo_cloud cloud_file = '''//file//''', cloud_format = '''//fmt//''', '// &
           'mie_cache = ''thermal_cloud_mie.nc'', n_reff = 6, reff_min_um = 4.0, '// &
           'reff_max_um = 16.0, v_eff = 0.1 /'//NL// &
           '&kumo_thermal t_levels = 6*275.0, t_surface = 275.0, t_top = 275.0, '// &
           'wavenumber_lo = 900.0, wavenumber_hi = 960.0 /'//NL
    if (radiances) text = text//'&kumo_radiance rad_mu = 1.0, 0.4, -0.5, -1.0, '// &
                          'rad_phi_deg = 0.0, 40.0, 190.0, 0.0, rad_levels = 0, 2, 4, 5 /'//NL
  end function thermal_nml

  !> Every radiance B(T0), every flux pi B(T0) (4 sigma); every net power 0 to round-off.
  subroutine test_isothermal(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: set
    type(spectral_band_t) :: band
    real(dp) :: b, emitted
    integer :: n_bad
    character(len=:), allocatable :: what
    real(wp) :: t(NX, NY, NZ)
    t = T0
    call write_les('thermal_cloud_iso.nc', 'temperature', t)
    call run_namelist('thermal_cloud_iso.nml', thermal_nml('thermal_cloud_iso.nc', 'les', &
                      'thermal_cloud_iso_out.nc', 3000, 30, .true.), set, error)
    if (allocated(error)) return
    call has_note(set, 'voxel temperatures: variable "temperature" of thermal_cloud_iso.nc', &
                  error)
    if (allocated(error)) return
    call band_from_wavenumbers(NU1, NU2, band, error)
    if (allocated(error)) return
    b = band_radiance(band, T0)
    n_bad = 0
    what = ''
    call within('radiance_wm2sr', b)
    call within('flux_up_wm2', PI*b)
    call within('flux_down_wm2', PI*b)
    call check(error, n_bad == 0, str(n_bad)//' values differ from B(T) or pi B(T) by more '// &
               'than 4 sigma:'//what)
    if (allocated(error)) return
    emitted = sum(set%vars(find_var(set, 'emitted_power_layer'))%mean)
    call check(error, emitted > 0.0_dp, 'nothing emitted')
    if (allocated(error)) return
    call zero('net_power_layer')
    call zero('net_power_surface')
    call zero('net_power_density_voxel')
    call zero('heating_rate_voxel')
  contains
    subroutine within(name, ref)
      character(len=*), intent(in) :: name
      real(dp), intent(in) :: ref
      integer :: iv, i
      iv = find_var(set, name)
      if (iv == 0) then
        n_bad = n_bad + 1
        what = what//' '//name//' missing;'
        return
      end if
      do i = 1, size(set%vars(iv)%mean)
        associate (x => set%vars(iv)%mean(i), s => set%vars(iv)%stderr(i))
          if (abs(x - ref) > K_SIGMA*s + 1.0e-9_dp*ref) then
            n_bad = n_bad + 1
            what = what//' '//name//'('//str(i)//') = '//str(x)//' +- '//str(s)//';'
          end if
        end associate
      end do
    end subroutine within
    subroutine zero(name)
      character(len=*), intent(in) :: name
      integer :: iv
      if (allocated(error)) return
      iv = find_var(set, name)
      call check(error, iv > 0, name//' missing')
      if (allocated(error)) return
      ! the voxel Planck radiances are kept in single precision, as the voxel optics (6e-8
      ! relative): a voxel and a layer at the same temperature differ by that much
      call check(error, maxval(abs(set%vars(iv)%mean)) <= 1.0e-9_dp*emitted, name// &
                 ' is not zero in an isothermal enclosure: '//str(maxval(abs(set%vars(iv)%mean))))
    end subroutine zero
  end subroutine test_isothermal

  !> Emitted power per voxel of a run from `file` over that of the isothermal file: B(T)/B(T0).
  subroutine test_mapping(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: iso, var, th
    real(dp), allocatable :: ratio(:)
    real(wp) :: t(NX, NY, NZ)
    type(spectral_band_t) :: band
    t = T0
    call write_les('thermal_cloud_iso.nc', 'temperature', t)
    call run_namelist('thermal_cloud_map0.nml', thermal_nml('thermal_cloud_iso.nc', 'les', &
                      'thermal_cloud_map0.nc', 200, 2, .false.), iso, error)
    if (allocated(error)) return
    t = t_field()
    call write_les('thermal_cloud_var.nc', 'temperature', t)
    call run_namelist('thermal_cloud_map1.nml', thermal_nml('thermal_cloud_var.nc', 'les', &
                      'thermal_cloud_map1.nc', 200, 2, .false.), var, error)
    if (allocated(error)) return
    call write_les('thermal_cloud_theta.nc', 'theta', t)
    call run_namelist('thermal_cloud_map2.nml', thermal_nml('thermal_cloud_theta.nc', 'les', &
                      'thermal_cloud_map2.nc', 200, 2, .false.), th, error)
    if (allocated(error)) return
    call has_note(th, 'potential temperature "theta" and pressure "p"', error)
    if (allocated(error)) return
    call band_from_wavenumbers(NU1, NU2, band, error)
    if (allocated(error)) return
    ratio = reshape(band_radiance(band, t)/band_radiance(band, T0), [NX*NY*NZ])
    call compare_emission(iso, var, ratio, 1.0e-6_dp, 'LES temperature', error)
    if (allocated(error)) return
    ! theta and p pass through single precision: T to ~1e-7 relative, B to ~1e-6
    call compare_emission(iso, th, ratio, 1.0e-5_dp, 'LES potential temperature', error)
  end subroutine test_mapping

  !> A file without temperature: the voxels emit the level values (275 K), and the log says so.
  subroutine test_no_temperature(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: iso, none
    real(wp) :: t(NX, NY, NZ)
    t = T0
    call write_les('thermal_cloud_iso.nc', 'temperature', t)
    call run_namelist('thermal_cloud_map0.nml', thermal_nml('thermal_cloud_iso.nc', 'les', &
                      'thermal_cloud_map0.nc', 200, 2, .false.), iso, error)
    if (allocated(error)) return
    call write_les('thermal_cloud_none.nc', 'none', t)
    call run_namelist('thermal_cloud_none.nml', thermal_nml('thermal_cloud_none.nc', 'les', &
                      'thermal_cloud_none_out.nc', 200, 2, .false.), none, error)
    if (allocated(error)) return
    call has_note(none, 'voxel temperatures: the cloud file has none; the voxels take t_levels', &
                  error)
    if (allocated(error)) return
    ! the voxel Planck radiances of a file are single precision, the level values double
    call compare_emission(iso, none, spread(1.0_dp, 1, NX*NY*NZ), 2.0e-7_dp, 'no temperature', &
                          error)
  end subroutine test_no_temperature

  !> An I3RC LWC file: its temperature profile (one value per height) gives each voxel the mean
  !> Planck radiance of its two bounding heights.
  subroutine test_lwc_profile(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: iso, prof
    type(spectral_band_t) :: band
    real(wp), parameter :: TP(0:NZ) = [281.0_wp, 279.5_wp, 283.0_wp, 290.0_wp]
    real(dp) :: ratio(NX*NY*NZ), bl
    integer :: k
    call write_lwc('thermal_cloud_iso.lwc', spread(T0, 1, NZ + 1))
    call write_lwc('thermal_cloud_prof.lwc', TP)
    call run_namelist('thermal_cloud_lwc0.nml', thermal_nml('thermal_cloud_iso.lwc', 'lwc', &
                      'thermal_cloud_lwc0.nc', 200, 2, .false.), iso, error)
    if (allocated(error)) return
    call run_namelist('thermal_cloud_lwc1.nml', thermal_nml('thermal_cloud_prof.lwc', 'lwc', &
                      'thermal_cloud_lwc1.nc', 200, 2, .false.), prof, error)
    if (allocated(error)) return
    call has_note(prof, 'the temperature profile (line 5) of thermal_cloud_prof.lwc', error)
    if (allocated(error)) return
    call band_from_wavenumbers(NU1, NU2, band, error)
    if (allocated(error)) return
    do k = 1, NZ
      bl = 0.5_dp*(band_radiance(band, TP(k - 1)) + band_radiance(band, TP(k)))
      ratio((k - 1)*NX*NY + 1:k*NX*NY) = bl/band_radiance(band, T0)
    end do
    call compare_emission(iso, prof, ratio, 1.0e-6_dp, 'LWC file temperature profile', error)
  end subroutine test_lwc_profile

  !> The cloud as a 2-parameter LWC file (heights as cell boundaries) with temperatures tp.
  subroutine write_lwc(path, tp)
    character(len=*), intent(in) :: path
    real(wp), intent(in) :: tp(0:NZ)
    real(wp) :: lwc(NX, NY, NZ), reff(NX, NY, NZ)
    integer :: u, i, j, k
    call cloud(lwc, reff)
    open (newunit=u, file=path, status='replace', action='write')
    write (u, '(a)') '2 parameter LWC file'
    write (u, '(3i5)') NX, NY, NZ
    write (u, '(2f10.5)') DX_KM, DY_KM
    write (u, '(*(f10.5))') ZE_KM
    write (u, '(*(f10.3))') tp
    do k = 1, NZ
      do j = 1, NY
        do i = 1, NX
          if (lwc(i, j, k) > 0.0_wp) write (u, '(3i5, 2f12.6)') i, j, k, lwc(i, j, k), reff(i, j, k)
        end do
      end do
    end do
    close (u)
  end subroutine write_lwc

  !> An MCARaTS 3-D atmosphere (binary, one isotropic component, mtprof = 1) in layers 2..4:
  !> voxel (i, j, k) emits the mean of B(t_levels + tmpa3d) at its two levels.
  subroutine test_mcarats(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: iso, pert, set
    type(error_t), allocatable :: run_error
    type(spectral_band_t) :: band
    real(real32) :: tmpa(NX, NY, NZ + 1)
    real(dp) :: ratio(NX, NY, NZ)
    integer :: i, j, k
    tmpa = 0.0
    call write_mcarats('thermal_cloud_iso.atm', tmpa)
    do k = 1, NZ + 1
      do j = 1, NY
        do i = 1, NX
          tmpa(i, j, k) = 0.5*i - 0.25*j + 2.0*k - 3.0
        end do
      end do
    end do
    call write_mcarats('thermal_cloud_pert.atm', tmpa)
    call run_namelist('thermal_cloud_mca0.nml', mcarats_nml('thermal_cloud_iso.atm', &
                      'thermal_cloud_mca0.nc'), iso, error)
    if (allocated(error)) return
    call run_namelist('thermal_cloud_mca1.nml', mcarats_nml('thermal_cloud_pert.atm', &
                      'thermal_cloud_mca1.nc'), pert, error)
    if (allocated(error)) return
    call has_note(pert, 'tmpa3d of thermal_cloud_pert.atm (per level) added to t_levels', error)
    if (allocated(error)) return
    call band_from_wavenumbers(NU1, NU2, band, error)
    if (allocated(error)) return
    do k = 1, NZ
      do j = 1, NY
        do i = 1, NX
          ratio(i, j, k) = 0.5_dp*(band_radiance(band, T0 + real(tmpa(i, j, k), wp)) + &
                                   band_radiance(band, T0 + real(tmpa(i, j, k + 1), wp)))/ &
                           band_radiance(band, T0)
        end do
      end do
    end do
    call compare_emission(iso, pert, reshape(ratio, [NX*NY*NZ]), 1.0e-6_dp, 'MCARaTS tmpa3d', &
                          error)
    if (allocated(error)) return
    tmpa(3, 2, 2) = -400.0
    call write_mcarats('thermal_cloud_pert.atm', tmpa)
    call run_namelist('thermal_cloud_mca2.nml', mcarats_nml('thermal_cloud_pert.atm', &
                      'thermal_cloud_mca2.nc'), set, run_error)
    call check(error, allocated(run_error), 'a voxel at -125 K was accepted')
    if (allocated(error)) return
    call check(error, index(run_error%message, 'tmpa3d of thermal_cloud_pert.atm') > 0 .and. &
               index(run_error%message, 'voxel (3,2,1)') > 0 .and. &
               index(run_error%message, 'must be > 0') > 0, 'unclear message: '// &
               run_error%message)
  end subroutine test_mcarats

  !> MCARaTS binary atmosphere: tmpa3d (NZ + 1 records), absg3d (NZ, zero), then extp3d,
  !> omgp3d and apfp3d (isotropic, -2.5) of one component, float32 records of NX*NY values.
  subroutine write_mcarats(path, tmpa)
    character(len=*), intent(in) :: path
    real(real32), intent(in) :: tmpa(NX, NY, NZ + 1)
    real(wp) :: lwc(NX, NY, NZ), reff(NX, NY, NZ)
    integer :: u
    call cloud(lwc, reff)
    open (newunit=u, file=path, status='replace', action='write', access='stream', &
          form='unformatted')
    write (u) tmpa, spread(spread(spread(0.0_real32, 1, NX), 2, NY), 3, NZ), &
      real(0.02_wp*lwc, real32), spread(spread(spread(0.5_real32, 1, NX), 2, NY), 3, NZ), &
      spread(spread(spread(-2.5_real32, 1, NX), 2, NY), 3, NZ)
    close (u)
  end subroutine write_mcarats

  function mcarats_nml(file, out) result(text)
    character(len=*), intent(in) :: file, out
    character(len=:), allocatable :: text
    text = run_groups(200, 2, 17, 'wavelength_um = 10.7', out, 'albedo = 0.0')// &
           '&kumo_atmosphere nz = 5, z_levels = 0.0, 500.0, 600.0, 750.0, 850.0, 2000.0, '// &
           'k3d_bottom = 2, nx = 4, ny = 3, nz3 = 3, lx = 400.0, ly = 360.0, '// &
           'n_components = 1, ext1d(:,1) = 5*1.5e-4, ssa1d(:,1) = 5*0.0, phase1d(:,1) = 5*1, '// &
           'air_density = 1.2, 1.15, 1.12, 1.1, 1.0 /'//NL// &
           '&kumo_cloud cloud_file = '''//file//''', cloud_format = ''mcarats'', '// &
           'mcarats_np3d = 1, mcarats_nkd = 1, mcarats_mtprof = 1 /'//NL// &
           '&kumo_thermal t_levels = 6*275.0, t_surface = 275.0, t_top = 275.0, '// &
           'wavenumber_lo = 900.0, wavenumber_hi = 960.0 /'//NL
  end function mcarats_nml

  !> Bad temperatures: wrong shape, negative, NaN: refused, the message names file and variable.
  subroutine test_bad(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: set
    real(wp) :: t(NX, NY, NZ)
    t = T0
    call write_les('thermal_cloud_bad.nc', 'shape', t)
    call expect_failure('thermal_cloud_bad.nc', 'dimensions are (y, x)', error)
    if (allocated(error)) return
    t(2, 3, 2) = -3.0_wp
    call write_les('thermal_cloud_bad.nc', 'temperature', t)
    call expect_failure('thermal_cloud_bad.nc', '-3', error)
    if (allocated(error)) return
    t(2, 3, 2) = ieee_value(t(1, 1, 1), ieee_quiet_nan)
    call write_les('thermal_cloud_bad.nc', 'temperature', t)
    call expect_failure('thermal_cloud_bad.nc', 'NaN', error)
  contains
    subroutine expect_failure(file, part, error)
      character(len=*), intent(in) :: file, part
      type(error_t), allocatable, intent(out) :: error
      type(error_t), allocatable :: run_error
      call run_namelist('thermal_cloud_bad.nml', thermal_nml(file, 'les', &
                        'thermal_cloud_bad_out.nc', 100, 2, .false.), set, run_error)
      call check(error, allocated(run_error), file//': a bad temperature was accepted')
      if (allocated(error)) return
      call check(error, index(run_error%message, file) > 0 .and. &
                 index(run_error%message, 'temperature') > 0 .and. &
                 index(run_error%message, part) > 0, 'the message does not name the file, '// &
                 'the variable and "'//part//'": '//run_error%message)
    end subroutine expect_failure
  end subroutine test_bad

  !> emitted_power_density_voxel of `b` = that of `a` times `ratio` (to `tol` relative).
  subroutine compare_emission(a, b, ratio, tol, what, error)
    type(result_set_t), intent(in) :: a, b
    real(dp), intent(in) :: ratio(:), tol
    character(len=*), intent(in) :: what
    type(error_t), allocatable, intent(out) :: error
    integer :: ia, ib, i, n_bad
    real(dp) :: worst
    ia = find_var(a, 'emitted_power_density_voxel')
    ib = find_var(b, 'emitted_power_density_voxel')
    call check(error, ia > 0 .and. ib > 0, 'emitted_power_density_voxel missing')
    if (allocated(error)) return
    call check(error, size(a%vars(ia)%mean) == size(ratio) .and. &
               size(b%vars(ib)%mean) == size(ratio), what//': '// &
               str(size(b%vars(ib)%mean))//' voxels, expected '//str(size(ratio)))
    if (allocated(error)) return
    n_bad = 0
    worst = 0.0_dp
    do i = 1, size(ratio)
      associate (ea => a%vars(ia)%mean(i), eb => b%vars(ib)%mean(i))
        call check(error, ea > 0.0_dp, what//': voxel '//str(i)//' does not emit')
        if (allocated(error)) return
        worst = max(worst, abs(eb/(ea*ratio(i)) - 1.0_dp))
        if (abs(eb - ea*ratio(i)) > tol*ea*ratio(i)) n_bad = n_bad + 1
      end associate
    end do
    call check(error, n_bad == 0, what//': '//str(n_bad)//' voxels emit other than B(T)/B(T0) '// &
               'times the isothermal power; largest relative difference '//str(worst))
  end subroutine compare_emission

  !> The run's scene_notes contain `text`.
  subroutine has_note(set, text, error)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: text
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    do i = 1, size(set%attrs)
      if (set%attrs(i)%name /= 'scene_notes') cycle
      if (.not. allocated(set%attrs(i)%value)) exit
      call check(error, index(set%attrs(i)%value, text) > 0, 'the run log does not say "'// &
                 text//'": '//set%attrs(i)%value)
      return
    end do
    call check(error, .false., 'no scene_notes in the results')
  end subroutine has_note

end module test_kumo_thermal_cloud

program test_thermal_cloud
  use kumo_test_text, only: run_suite
  use test_kumo_thermal_cloud, only: collect_thermal_cloud
  implicit none
  call run_suite('thermal_cloud', collect_thermal_cloud())
end program test_thermal_cloud
