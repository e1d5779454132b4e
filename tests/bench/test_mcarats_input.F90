! SPDX-License-Identifier: BSD-3-Clause
!> MCARaTS input files in whole runs (&kumo_cloud cloud_format = 'mcarats', &kumo_surface
!> surface_file).
!>
!> * A small MCARaTS atmosphere and phase-function file written here (binary, two components,
!>   two k-terms): every kind of apf code (isotropic, Rayleigh, Henyey-Greenstein, tables with
!>   and without a fractional blend), a gas-absorption perturbation with negative values and
!>   temperatures kumo must ignore. The voxel components kumo builds are checked value by value
!>   against the MCARaTS rules evaluated here, and the run is compared with the same scene
!>   written by the test in kumo's own route (a netCDF scene file whose components the test
!>   computes: the blend as the two tables' shares (1 - r) ext and r ext, the total gas
!>   absorption abs1d + absg3d as one voxel component with the 1-D absorber taken out of the
!>   3-D layers; text tables and HG entries in &kumo_phase), with another seed: reflectance,
!>   transmittance, absorptance and the layer absorption agree within K = 4 standard errors of
!>   the difference.
!> * The shipped MCARaTS example (data/mcarats/les05_0213.atm + .sca, through their .ctl and as
!>   binary files with the sizes in the namelist): grid, phase functions, voxel values against
!>   the file's float32 values (read with numpy), the same optics by both routes, and a short
!>   run whose energy budget closes.
!> * The surface: an MCARaTS Lambert map gives exactly the run of the same map as kumo's
!>   netCDF albedo_file, and a map of mixed kinds exactly that of kumo's netCDF brdf_file (same
!>   seed; kumo represents both); a kind the namelist does not enable, or wrong pixel counts,
!>   are rejected with the file and the rule in the message.
module test_mcarats_input_suite
  use, intrinsic :: iso_fortran_env, only: real32
  use kumo_kinds, only: wp, dp
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_sigma
  use kumo_config, only: config_t, read_config
  use kumo_results, only: result_set_t
  use kumo_test_scenes, only: run_config, get_scalar, get_array
  use kumo_test_text, only: shared_dir
  use kumo_netcdf, only: write_scene_3d, BRDF_MAP_VARS
  use kumo_cloud_scene, only: cloud_optics_t, build_cloud_optics
  use kumo_brdf, only: BRDF_NPAR
  use kumo_error, only: str
  use netcdf, only: nf90_create, nf90_def_dim, nf90_def_var, nf90_enddef, nf90_put_var, &
                    nf90_close, nf90_clobber, nf90_int, nf90_double, NF90_NOERR
  implicit none
  private
  public :: collect_mcarats_input

  !> Statistical comparisons: |a - b| <= K sigma of the difference, sigma from the two runs'
  !> own batch standard errors (40 batches each, so the estimate of sigma is good to about
  !> 11 %). With K = 4 a correct code fails one comparison with probability about 1e-4; the
  !> suite makes 8.
  real(dp), parameter :: K = 4.0_dp
  !> float32 values converted to double are compared exactly, apart from products formed in
  !> a different order (one rounding of a double)
  real(dp), parameter :: TIGHT = 1.0e-14_dp

  ! The small scene: 4 x 3 columns of 100 m, 3 layers of the 5-layer column form the 3-D region.
  integer, parameter :: NX = 4, NY = 3, NZ3 = 3, NKD = 2, NP3D = 2, NANG = 181, NPF = 3
  integer, parameter :: NZ = 5, K3D = 2
  real(wp), parameter :: ZLEV(0:NZ) = [0.0_wp, 300.0_wp, 500.0_wp, 700.0_wp, 900.0_wp, 2000.0_wp]
  !> apf codes of component 1 (both ends of the isotropic and Rayleigh ranges, three HG g) and
  !> of component 2 (tables 1..3, exact and blended; blend fractions 0.2, 0.7, 0.4, so that
  !> weights swapped between the two tables move every blend towards back-scattering)
  real(real32), parameter :: CODES1(6) = [-2.0, -1.5, 0.7, -1.0, -0.4, -2.9]
  real(real32), parameter :: CODES2(5) = [1.0, 1.2, 2.7, 3.0, 1.4]
  !> asymmetry parameters of the three tables (HG sampled on 1-degree steps): far apart, so a
  !> blend with the wrong weights changes the reflectance by many standard errors
  real(wp), parameter :: GTAB(NPF) = [0.85_wp, -0.5_wp, 0.2_wp]
  !> 1-D layers: a Rayleigh scatterer and the gas absorption the perturbation is added to
  real(wp), parameter :: EXT_RAY = 2.0e-5_wp, ABS1D = 3.0e-4_wp

contains

  function collect_mcarats_input() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('small_scene_voxel_components', test_small_components), &
             new_unittest('small_scene_equals_scene_file_route', test_small_run), &
             new_unittest('les05_through_the_namelist', test_les05), &
             new_unittest('les05_negative_absorption_rejected', test_les05_negative), &
             new_unittest('lambert_map_equals_albedo_file', test_surface_lambert), &
             new_unittest('mixed_map_equals_brdf_file', test_surface_mixed), &
             new_unittest('surface_file_errors', test_surface_errors)]
  end function collect_mcarats_input

  ! ------------------------------------------------------------------------------------------
  ! The small scene
  ! ------------------------------------------------------------------------------------------

  !> The fields of the small scene, as float32 (what the file holds).
  subroutine small_fields(ext, omg, apf, absg, tmp)
    real(real32), intent(out) :: ext(NX, NY, NZ3, NP3D), omg(NX, NY, NZ3, NP3D)
    real(real32), intent(out) :: apf(NX, NY, NZ3, NP3D), absg(NX, NY, NZ3, NKD)
    real(real32), intent(out) :: tmp(NX, NY, NZ3 + 1)
    integer :: i, j, kk
    do kk = 1, NZ3
      do j = 1, NY
        do i = 1, NX
          ext(i, j, kk, 1) = 0.002 + 0.001*mod(i + 2*j + kk, 5)
          omg(i, j, kk, 1) = 0.9 + 0.02*mod(i + j + kk, 5)
          apf(i, j, kk, 1) = CODES1(mod(i + 2*j + 3*kk, 6) + 1)
          ext(i, j, kk, 2) = 0.004 + 0.002*mod(2*i + j + kk, 4)
          omg(i, j, kk, 2) = 0.999 - 0.01*mod(i + kk, 3)
          apf(i, j, kk, 2) = CODES2(mod(i + 3*j + 2*kk, 5) + 1)
          ! k-term 1 is far off (a wrong k-term shows); k-term 2 has negative values and a
          ! mean of 1e-4 m-1 (optical depth 0.06 over the region), so that leaving it out shows
          absg(i, j, kk, 1) = 5.0e-3
          absg(i, j, kk, 2) = 1.0e-4*(mod(i + j + kk, 5) - 1)
        end do
      end do
    end do
    do kk = 1, NZ3 + 1
      tmp(:, :, kk) = 280.0 + kk
    end do
  end subroutine small_fields

  !> Write the small scene as MCARaTS binary files: mca_small.atm (mtprof = 1) and
  !> mca_small.sca (angles, then the three tables at different scales: any normalisation).
  subroutine write_small_files()
    real(real32) :: ext(NX, NY, NZ3, NP3D), omg(NX, NY, NZ3, NP3D), apf(NX, NY, NZ3, NP3D)
    real(real32) :: absg(NX, NY, NZ3, NKD), tmp(NX, NY, NZ3 + 1), tab(NANG, 0:NPF)
    integer :: u, ip, ia
    call small_fields(ext, omg, apf, absg, tmp)
    open (newunit=u, file='mca_small.atm', status='replace', action='write', access='stream', &
          form='unformatted')
    write (u) tmp, absg
    do ip = 1, NP3D
      write (u) ext(:, :, :, ip), omg(:, :, :, ip), apf(:, :, :, ip)
    end do
    close (u)
    do ia = 1, NANG
      tab(ia, 0) = real(ia - 1, real32)
    end do
    do ip = 1, NPF
      tab(:, ip) = real(10.0_wp**(ip - 2)*hg(GTAB(ip), tab(:, 0)), real32)
    end do
    open (newunit=u, file='mca_small.sca', status='replace', action='write', access='stream', &
          form='unformatted')
    write (u) tab
    close (u)
  end subroutine write_small_files

  !> Henyey-Greenstein phase function at angles [deg].
  pure function hg(g, angle_deg) result(p)
    real(wp), intent(in) :: g
    real(real32), intent(in) :: angle_deg(:)
    real(wp) :: p(size(angle_deg))
    real(wp) :: mu(size(angle_deg))
    mu = cos(real(angle_deg, wp)*acos(-1.0_wp)/180.0_wp)
    p = (1.0_wp - g**2)/(1.0_wp + g**2 - 2.0_wp*g*mu)**1.5_wp
  end function hg

  function small_common(seed, out) result(text)
    integer, intent(in) :: seed
    character(len=*), intent(in) :: out
    character(len=:), allocatable :: text
    text = '&kumo_control n_photons_per_batch = 1500, n_batches = 40, seed = '//str(seed)// &
           ', verbose = 0 /'//new_line('a')// &
           '&kumo_source sza_deg = 35.0, phi0_deg = 30.0 /'//new_line('a')// &
           '&kumo_surface albedo = 0.15 /'//new_line('a')// &
           '&kumo_output file = '''//out//''' /'//new_line('a')
  end function small_common

  !> &kumo_atmosphere of the small scene; `abs3d` is the 1-D absorption in the 3-D layers.
  function small_atmosphere(extra, abs3d) result(text)
    character(len=*), intent(in) :: extra
    real(wp), intent(in) :: abs3d
    character(len=:), allocatable :: text
    integer :: kk
    text = '&kumo_atmosphere nz = 5, z_levels = '
    do kk = 0, NZ
      text = text//str(ZLEV(kk))//', '
    end do
    text = text//new_line('a')//'  n_components = 2, k3d_bottom = '//str(K3D)//', '// &
           'lx = 400.0, ly = 300.0'//new_line('a')// &
           '  ext1d(1:5,1) = 5*'//str(EXT_RAY)//', phase1d(1:5,1) = 5*1'//new_line('a')// &
           '  ext1d(1:5,2) = '//str(ABS1D)//', 3*'//str(abs3d)//', '//str(ABS1D)// &
           ', ssa1d(1:5,2) = 5*0.0'//new_line('a')//extra//'/'//new_line('a')
  end function small_atmosphere

  !> The MCARaTS namelist of the small scene (binary files, sizes in the namelist).
  function small_mcarats_nml(seed, out, abs3d) result(text)
    integer, intent(in) :: seed
    character(len=*), intent(in) :: out
    real(wp), intent(in) :: abs3d
    character(len=:), allocatable :: text
    text = small_common(seed, out)//small_atmosphere('  nx = 4, ny = 3, nz3 = 3'// &
                                                     new_line('a'), abs3d)// &
           '&kumo_phase n_phase = 1, phase_kind = ''rayleigh'', n_table = 4000 /'// &
           new_line('a')// &
           '&kumo_cloud cloud_file = ''mca_small.atm'', cloud_format = ''mcarats'','// &
           ' mcarats_np3d = 2, mcarats_nkd = 2, mcarats_mtprof = 1, mcarats_ikd = 2,'// &
           ' mcarats_phase_file = ''mca_small.sca'', mcarats_nang = 181, mcarats_npf = 3 /'
  end function small_mcarats_nml

  !> The voxel components kumo must build (its order: component 1; component 2 at (1 - r) and
  !> at r; absorption), with phase indices in kumo's order after the namelist's Rayleigh:
  !> isotropic 2, Rayleigh 3, HG g = -0.4, 0.7 (sorted: 4, 5), tables 6..8. Built here from
  !> the MCARaTS rules of docs/mcarats-interface.md section 3.2.
  subroutine expected_components(ext, ssa, iph)
    real(wp), intent(out) :: ext(NX, NY, NZ3, 4), ssa(NX, NY, NZ3, 4)
    integer, intent(out) :: iph(NX, NY, NZ3, 4)
    real(real32) :: e(NX, NY, NZ3, NP3D), w(NX, NY, NZ3, NP3D), a(NX, NY, NZ3, NP3D)
    real(real32) :: absg(NX, NY, NZ3, NKD), tmp(NX, NY, NZ3 + 1)
    integer :: i, j, kk, ipf
    real(wp) :: code, r
    call small_fields(e, w, a, absg, tmp)
    do kk = 1, NZ3
      do j = 1, NY
        do i = 1, NX
          code = real(a(i, j, kk, 1), wp)
          ext(i, j, kk, 1) = real(e(i, j, kk, 1), wp)
          ssa(i, j, kk, 1) = real(w(i, j, kk, 1), wp)
          if (code <= -2.0_wp) then
            iph(i, j, kk, 1) = 2
          else if (code <= -1.0_wp) then
            iph(i, j, kk, 1) = 3
          else if (code < 0.0_wp) then
            iph(i, j, kk, 1) = 4
          else
            iph(i, j, kk, 1) = 5
          end if
          code = real(a(i, j, kk, 2), wp)
          ipf = int(code)
          r = code - ipf
          ext(i, j, kk, 2) = (1.0_wp - r)*real(e(i, j, kk, 2), wp)
          ext(i, j, kk, 3) = r*real(e(i, j, kk, 2), wp)
          ssa(i, j, kk, 2:3) = real(w(i, j, kk, 2), wp)
          iph(i, j, kk, 2) = 5 + ipf
          iph(i, j, kk, 3) = 5 + merge(ipf + 1, ipf, r > 0.0_wp)
          ext(i, j, kk, 4) = real(absg(i, j, kk, 2), wp)
          ssa(i, j, kk, 4) = 0.0_wp
          iph(i, j, kk, 4) = 2
        end do
      end do
    end do
  end subroutine expected_components

  !> The voxel components and phase functions kumo builds from the small files.
  subroutine test_small_components(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(cloud_optics_t) :: opt
    real(wp) :: ext(NX, NY, NZ3, 4), ssa(NX, NY, NZ3, 4)
    integer :: iph(NX, NY, NZ3, 4), i, j, kk, ic
    call write_small_files()
    call write_text('mca_small.nml', small_mcarats_nml(1, 'mca_small_out.nc', ABS1D))
    call read_config('mca_small.nml', cfg, error)
    if (allocated(error)) return
    call check(error, cfg%cloud%grid%nx == NX .and. cfg%cloud%grid%nz == NZ3 .and. &
               abs(cfg%cloud%grid%dx - 100.0_wp) < 1.0e-12_wp .and. cfg%atm%k3d_bottom == K3D, &
               'grid of the region from the namelist')
    if (allocated(error)) return
    call build_cloud_optics(cfg%cloud, 0.0_wp, 500, 1, opt, error)
    if (allocated(error)) return
    call check(error, size(opt%phases) == 7 .and. size(opt%ext, 4) == 4, 'phase functions '// &
               str(size(opt%phases))//' (expected 7: isotropic, Rayleigh, 2 HG, 3 tables), '// &
               'components '//str(size(opt%ext, 4))//' (expected 4)')
    if (allocated(error)) return
    call check(error, opt%phases(1)%kind == 1 .and. opt%phases(2)%kind == 2 .and. &
               opt%phases(3)%kind == 3 .and. opt%phases(6)%kind == 4, 'phase-function kinds')
    call check_close(error, opt%phases(3)%g, real(-0.4_real32, dp), rel_tol=0.0_dp, &
                     label='first HG g (sorted)')
    ! the phase list after the namelist's Rayleigh (offset 1), so iph = 2 is isotropic; a
    ! table's g from kumo's quadrature of the sampled HG 0.85 (1-degree steps)
    call check_close(error, opt%phases(5)%g, GTAB(1), abs_tol=2.0e-3_dp, label='table 1 g')
    call expected_components(ext, ssa, iph)
    do ic = 1, 4
      do kk = 1, NZ3
        do j = 1, NY
          do i = 1, NX
            call check_close(error, opt%ext(i, j, kk, ic), ext(i, j, kk, ic), abs_tol=0.0_dp, &
                             rel_tol=TIGHT, label='ext comp. '//str(ic)//' voxel '//str(i)// &
                             ','//str(j)//','//str(kk))
            call check_close(error, opt%ssa(i, j, kk, ic), ssa(i, j, kk, ic), abs_tol=0.0_dp, &
                             rel_tol=0.0_dp, label='ssa comp. '//str(ic))
            call check(error, opt%iph(i, j, kk, ic) == iph(i, j, kk, ic), 'phase index '// &
                       'comp. '//str(ic)//' voxel '//str(i)//','//str(j)//','//str(kk)//': '// &
                       str(opt%iph(i, j, kk, ic))//', expected '//str(iph(i, j, kk, ic)))
            if (allocated(error)) return
          end do
        end do
      end do
    end do
    ! 23 of the 36 codes of component 2 are fractional (1.2, 2.7, 1.4)
    call check(error, index(opt%notes, '23 blending two tables') > 0 .and. &
               index(opt%notes, 'not used: kumo computes solar radiation only') > 0, &
               'notes: '//opt%notes)
  end subroutine test_small_components

  !> The small scene through the namelist, against kumo's own scene-file route.
  subroutine test_small_run(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: a, b
    real(wp) :: ext(NX, NY, NZ3, 4), ssa(NX, NY, NZ3, 4)
    integer :: iph(NX, NY, NZ3, 4), ip, ia, u
    real(real32) :: e(NX, NY, NZ3, NP3D), w(NX, NY, NZ3, NP3D), c(NX, NY, NZ3, NP3D)
    real(real32) :: absg(NX, NY, NZ3, NKD), tmp(NX, NY, NZ3 + 1), ang(NANG)
    character(len=:), allocatable :: nml
    call write_small_files()
    call run_namelist('mca_small_run.nml', small_mcarats_nml(3, 'mca_small_out.nc', ABS1D), a, &
                      error)
    if (allocated(error)) return
    ! kumo's route: the test's components, with the gas absorption of the 3-D layers moved from
    ! the 1-D absorber into the voxels as one component abs1d + absg3d (never negative)
    call expected_components(ext, ssa, iph)
    ext(:, :, :, 4) = ABS1D + ext(:, :, :, 4)
    call write_scene_3d('mca_small_scene.nc', ext, ssa, iph, error)
    if (allocated(error)) return
    call small_fields(e, w, c, absg, tmp)
    nml = small_common(4, 'mca_small_ref.nc')// &
          small_atmosphere('  scene_file = ''mca_small_scene.nc'', nx = 4, ny = 3, nz3 = 3, '// &
                           'n_components_3d = 4'//new_line('a'), 0.0_wp)// &
          '&kumo_phase n_phase = 8, n_table = 4000'//new_line('a')// &
          '  phase_kind(1:5) = ''rayleigh'', ''isotropic'', ''rayleigh'', ''hg'', ''hg'''// &
          new_line('a')//'  phase_g(4) = '//r17(real(-0.4_real32, wp))//', phase_g(5) = '// &
          r17(real(0.7_real32, wp))//new_line('a')
    do ia = 1, NANG
      ang(ia) = real(ia - 1, real32)
    end do
    do ip = 1, NPF
      open (newunit=u, file='mca_small_pf'//str(ip)//'.txt', status='replace', action='write')
      do ia = 1, NANG
        write (u, '(es24.16, 1x, es24.16)') real(ang(ia), wp), &
          real(real(10.0_wp**(ip - 2)*hg(GTAB(ip), ang(ia:ia)), real32), wp)
      end do
      close (u)
      nml = nml//'  phase_kind('//str(5 + ip)//') = ''table'', phase_file('//str(5 + ip)// &
            ') = ''mca_small_pf'//str(ip)//'.txt'''//new_line('a')
    end do
    nml = nml//'/'
    call run_namelist('mca_small_ref.nml', nml, b, error)
    if (allocated(error)) return
    call compare_runs(a, b, error)
  end subroutine test_small_run

  ! ------------------------------------------------------------------------------------------
  ! The shipped LES example
  ! ------------------------------------------------------------------------------------------

  !> The levels of data/mcarats/conf_hr0213 (Atm_zgrd0, 41 layers) and the 3-D region from
  !> layer 10 (Atm_iz3l), 60 x 30 m columns (Atm_nx, Atm_dx), with a uniform 1-D absorber of
  !> `abs_m1` [m-1] standing for Atm_abs1d.
  function les05_atmosphere(abs_m1, sizes) result(text)
    real(wp), intent(in) :: abs_m1
    character(len=*), intent(in) :: sizes
    character(len=:), allocatable :: text
    text = '&kumo_atmosphere nz = 41, k3d_bottom = 10, lx = 1800.0, ly = 1800.0'//sizes// &
           new_line('a')//'  z_levels = 0, 30, 60, 90, 120, 150, 180, 210, 230, 250, 260, '// &
           '270, 280, 290, 300, 310, 320, 330, 340, 350, 360, 370, 380, 390, 400, 410, 420, '// &
           '430, 440, 450, 460, 600, 1000, 2000, 3000, 4000, 6000, 8000, 10000, 15000, '// &
           '20000, 30000'//new_line('a')//'  ext1d(1:41,1) = 41*'//str(abs_m1)// &
           ', ssa1d(1:41,1) = 41*0.0'//new_line('a')//'/'//new_line('a')
  end function les05_atmosphere

  function les05_cloud(atm_file, phase_file, extra) result(text)
    character(len=*), intent(in) :: atm_file, phase_file, extra
    character(len=:), allocatable :: text
    text = '&kumo_cloud cloud_file = '''//shared_dir//'/data/mcarats/'//atm_file// &
           ''', cloud_format = ''mcarats'', mcarats_phase_file = '''//shared_dir// &
           '/data/mcarats/'//phase_file//''''//extra//' /'//new_line('a')// &
           '&kumo_phase n_table = 1000 /'//new_line('a')
  end function les05_cloud

  subroutine test_les05(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg, cfg_bin
    type(cloud_optics_t) :: opt, opt_bin
    type(result_set_t) :: res
    real(dp) :: m, s, r, sr
    character(len=:), allocatable :: nml
    integer, parameter :: OFFSET = 1
    call write_text('mca_les05.nml', les05_atmosphere(1.2e-5_wp, '')// &
                    les05_cloud('les05_0213.atm.ctl', 'les05_0213.sca.ctl', ''))
    call read_config('mca_les05.nml', cfg, error)
    if (allocated(error)) return
    ! the .ctl: XDEF 60, YDEF 60, 21 layers; the namelist: 30 m columns from layer 10 (250 m)
    call check(error, cfg%atm%nx == 60 .and. cfg%atm%ny == 60 .and. cfg%atm%nz3 == 21 .and. &
               cfg%cloud%grid%nz == 21, 'sizes from the .ctl')
    call check_close(error, cfg%cloud%grid%dx, 30.0_dp, rel_tol=TIGHT, label='dx')
    call check_close(error, cfg%cloud%grid%z(0), 250.0_dp, rel_tol=TIGHT, label='region bottom')
    call check_close(error, cfg%cloud%grid%z(21), 460.0_dp, rel_tol=TIGHT, label='region top')
    if (allocated(error)) return
    call build_cloud_optics(cfg%cloud, 0.0_wp, 1000, OFFSET, opt, error)
    if (allocated(error)) return
    ! numpy: the apf codes are 1 and 32..60, all whole numbers: 30 tables, no blend; one cloud
    ! component and the absorption perturbation (non-zero everywhere)
    call check(error, size(opt%phases) == 30 .and. size(opt%ext, 4) == 2, 'phases '// &
               str(size(opt%phases))//' (expected 30), components '//str(size(opt%ext, 4))// &
               ' (expected 2)')
    if (allocated(error)) return
    ! numpy, np.fromfile(..., '<f4').reshape(106, 60, 60) as [record, iy, ix]: largest
    ! extinction at ix=5, iy=36, layer 19: 0.19806351 m-1, omg 0.97181225, apf 60 (the last
    ! table, so the last phase function); absg3d there 1.1904604e-06 m-1; at (1,1,1) ext 1e-35,
    ! apf 1 (the first table), absg3d 1.4205398e-07; at (60,60,21) absg3d -4.651156e-09
    call check_close(error, opt%ext(5, 36, 19, 1), real(0.19806351_real32, dp), rel_tol=TIGHT, &
                     label='ext(5,36,19)')
    call check_close(error, opt%ssa(5, 36, 19, 1), real(0.97181225_real32, dp), rel_tol=TIGHT, &
                     label='ssa(5,36,19)')
    call check(error, opt%iph(5, 36, 19, 1) == OFFSET + 30 .and. &
               opt%iph(1, 1, 1, 1) == OFFSET + 1, 'phase indices of tables 60 and 1')
    call check_close(error, opt%ext(5, 36, 19, 2), real(1.1904604e-06_real32, dp), rel_tol=TIGHT, &
                     label='absg3d(5,36,19)')
    call check_close(error, opt%ext(1, 1, 1, 2), real(1.4205398e-07_real32, dp), rel_tol=TIGHT, &
                     label='absg3d(1,1,1)')
    call check_close(error, opt%ext(60, 60, 21, 2), real(-4.651156e-09_real32, dp), &
                     rel_tol=TIGHT, label='absg3d(60,60,21)')
    call check(error, all(opt%ssa(:, :, :, 2) == 0.0_wp), 'absorption component albedo 0')
    ! the last phase function is table 60: its forward/backward ratio is the file's (numpy:
    ! P(0) = 1092.2446, P(180) = 0.47431436 as float32), whatever the normalisation
    associate (p => opt%phases(30)%p_tab)
      call check_close(error, p(size(p))/p(1), real(1092.2446_real32, dp)/ &
                       real(0.47431436_real32, dp), rel_tol=TIGHT, label='P(0)/P(180) of table 60')
    end associate
    if (allocated(error)) return

    ! the same files as binaries, with the sizes in the namelist (conf_hr0213: Atm_nx, Atm_ny,
    ! Atm_nz3, Atm_mtprof; Sca_nangi, Sca_npf): the same optics
    nml = les05_atmosphere(1.2e-5_wp, ', nx = 60, ny = 60, nz3 = 21')// &
          les05_cloud('les05_0213.atm', 'les05_0213.sca', &
                      ', mcarats_mtprof = 1, mcarats_nang = 203, mcarats_npf = 60')
    call write_text('mca_les05_bin.nml', nml)
    call read_config('mca_les05_bin.nml', cfg_bin, error)
    if (allocated(error)) return
    call build_cloud_optics(cfg_bin%cloud, 0.0_wp, 1000, OFFSET, opt_bin, error)
    if (allocated(error)) return
    call check(error, all(opt_bin%ext == opt%ext) .and. all(opt_bin%ssa == opt%ssa) .and. &
               all(opt_bin%iph == opt%iph) .and. size(opt_bin%phases) == size(opt%phases), &
               'binary files with namelist sizes give other optics than the .ctl route')
    if (allocated(error)) return

    ! a short run: the budget closes in every batch, and the cloud reflects
    call write_text('mca_les05_run.nml', les05_atmosphere(1.2e-5_wp, '')// &
                    les05_cloud('les05_0213.atm.ctl', 'les05_0213.sca.ctl', '')// &
                    '&kumo_control n_photons_per_batch = 400, n_batches = 3, verbose = 0 /'// &
                    new_line('a')//'&kumo_surface albedo = 0.2 /'//new_line('a')// &
                    '&kumo_output file = ''mca_les05_out.nc'' /')
    call read_config('mca_les05_run.nml', cfg, error)
    if (allocated(error)) return
    call run_config(cfg, res, error)
    if (allocated(error)) return
    call get_scalar(res, 'energy_closure', m, s, error)
    call get_scalar(res, 'reflectance', r, sr, error)
    if (allocated(error)) return
    call check_close(error, m, 1.0_dp, abs_tol=1.0e-9_dp, label='energy closure')
    call check(error, s <= 1.0e-9_dp, 'energy closure varies between batches: '//str(s))
    ! a cloud (column optical depth 8 on average, up to 21) over albedo 0.2: neither dark nor
    ! white
    call check(error, r > 0.05_dp .and. r < 0.9_dp, 'reflectance '//str(r))
  end subroutine test_les05

  !> Too little 1-D absorption for the file's negative perturbations: rejected, not clamped.
  subroutine test_les05_negative(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(cloud_optics_t) :: opt
    type(error_t), allocatable :: err
    ! the smallest perturbation is -1.1268867e-06 m-1 (numpy); 1e-6 m-1 of 1-D absorption
    ! leaves some voxels negative
    call write_text('mca_les05_neg.nml', les05_atmosphere(1.0e-6_wp, '')// &
                    les05_cloud('les05_0213.atm.ctl', 'les05_0213.sca.ctl', ''))
    call read_config('mca_les05_neg.nml', cfg, error)
    if (allocated(error)) return
    call build_cloud_optics(cfg%cloud, 0.0_wp, 1000, 0, opt, err)
    call expect_error(error, err, [character(len=60) :: 'les05_0213.atm.ctl: absg3d k-term 1', &
                                   'makes the absorption coefficient of the voxel', &
                                   '1-D absorption 1E-06 m-1', 'ext1d with ssa1d < 1'])
  end subroutine test_les05_negative

  ! ------------------------------------------------------------------------------------------
  ! Surfaces
  ! ------------------------------------------------------------------------------------------

  !> A cloud slab over the surface given by `surface` (a &kumo_surface group).
  function surface_nml(surface, seed, out) result(text)
    character(len=*), intent(in) :: surface, out
    integer, intent(in) :: seed
    character(len=:), allocatable :: text
    text = '&kumo_control n_photons_per_batch = 1500, n_batches = 4, seed = '//str(seed)// &
           ', verbose = 0 /'//new_line('a')// &
           '&kumo_atmosphere nz = 1, z_levels = 0.0, 1000.0, ext1d(1,1) = 0.002, '// &
           'ssa1d(1,1) = 0.99, lx = 300.0, ly = 200.0 /'//new_line('a')// &
           '&kumo_phase phase_kind = ''hg'', phase_g = 0.8 /'//new_line('a')// &
           '&kumo_source sza_deg = 40.0 /'//new_line('a')// &
           '&kumo_output file = '''//out//''' /'//new_line('a')//surface
  end function surface_nml

  !> 3 x 2 Lambert pixels of different albedo: the MCARaTS file (Lambert only enabled, so one
  !> parameter field) against kumo's netCDF albedo map of the same float32 values.
  subroutine test_surface_lambert(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: a, b
    real(real32) :: rec(3, 2, 3)
    real(dp) :: ra, sa, rb, sb, ta, tb
    integer :: nc, dx, dy, v, st
    character(len=:), allocatable :: nml
    rec(:, :, 1) = 290.0
    rec(:, :, 2) = 1.0
    rec(:, :, 3) = reshape([0.05, 0.2, 0.35, 0.5, 0.65, 0.8], [3, 2])
    call write_f32('mca_lambert.sfc', reshape(rec, [size(rec)]))
    nml = surface_nml('&kumo_surface surface_file = ''mca_lambert.sfc'', surface_nxb = 3, '// &
                      'surface_nyb = 2, surface_mbrdf = 1, 0, 0, 0 /', 11, 'mca_lambert_out.nc')
    call run_namelist('mca_lambert.nml', nml, a, error)
    if (allocated(error)) return
    st = nf90_create('mca_lambert_ref.nc', nf90_clobber, nc)
    st = st + nf90_def_dim(nc, 'xs', 3, dx)
    st = st + nf90_def_dim(nc, 'ys', 2, dy)
    st = st + nf90_def_var(nc, 'albedo', nf90_double, [dx, dy], v)
    st = st + nf90_enddef(nc)
    st = st + nf90_put_var(nc, v, real(rec(:, :, 3), dp))
    st = st + nf90_close(nc)
    call check(error, st == NF90_NOERR, 'writing mca_lambert_ref.nc')
    if (allocated(error)) return
    nml = surface_nml('&kumo_surface albedo_file = ''mca_lambert_ref.nc'' /', 11, &
                      'mca_lambert_ref_out.nc')
    call run_namelist('mca_lambert_ref.nml', nml, b, error)
    if (allocated(error)) return
    call get_scalar(a, 'reflectance', ra, sa, error)
    call get_scalar(b, 'reflectance', rb, sb, error)
    call get_scalar(a, 'absorptance_surface', ta, sa, error)
    call get_scalar(b, 'absorptance_surface', tb, sb, error)
    if (allocated(error)) return
    ! the same surface and seed: the same photons, so the same numbers
    call check(error, ra == rb .and. ta == tb, 'MCARaTS Lambert map: R '//str(ra)//', surface '// &
               'absorptance '//str(ta)//'; albedo_file: '//str(rb)//', '//str(tb))
    if (allocated(error)) return
    ! and the map matters: the mean albedo 0.425 as a uniform surface gives another answer
    nml = surface_nml('&kumo_surface albedo = 0.425 /', 11, 'mca_uniform_out.nc')
    call run_namelist('mca_uniform.nml', nml, b, error)
    if (allocated(error)) return
    call get_scalar(b, 'reflectance', rb, sb, error)
    call check(error, ra /= rb, 'the map gives the uniform surface''s reflectance')
  end subroutine test_surface_lambert

  !> 3 x 2 pixels of every kind (two Lambert, black, DSM, RPV, LSRT): the MCARaTS file (five
  !> parameter fields) against kumo's netCDF BRDF map of the same float32 values.
  subroutine test_surface_mixed(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: a, b
    real(real32) :: rec(3, 2, 7)
    real(dp) :: ra, sa, rb, sb, aa, ab
    integer :: kinds(3, 2), nc, dx, dy, vk, vid(BRDF_NPAR, 4), i, kk, st, ix, iy
    real(dp) :: par(3, 2)
    character(len=:), allocatable :: nml
    kinds = reshape([1, 0, 2, 3, 4, 1], [3, 2])
    rec = 0.0
    rec(:, :, 1) = 295.0
    rec(:, :, 2) = real(kinds, real32)
    rec(1, 1, 3) = 0.3                                  ! Lambert
    rec(3, 1, 3:7) = [0.05, 0.2, 1.334, 0.0, 0.04]       ! DSM a_d, f_d, n_r, n_i, sigma^2
    rec(1, 2, 3:6) = [0.12, 0.7, -0.15, 0.3]            ! RPV rho0, k, Theta, h
    rec(2, 2, 3:5) = [0.2, 0.03, 0.1]                   ! LSRT k_iso, k_geo, k_vol
    rec(3, 2, 3) = 0.6                                  ! Lambert
    call write_f32('mca_mixed.sfc', reshape(rec, [size(rec)]))
    nml = surface_nml('&kumo_surface surface_file = ''mca_mixed.sfc'', surface_nxb = 3, '// &
                      'surface_nyb = 2 /', 12, 'mca_mixed_out.nc')
    call run_namelist('mca_mixed.nml', nml, a, error)
    if (allocated(error)) return
    st = nf90_create('mca_mixed_ref.nc', nf90_clobber, nc)
    st = st + nf90_def_dim(nc, 'xs', 3, dx)
    st = st + nf90_def_dim(nc, 'ys', 2, dy)
    st = st + nf90_def_var(nc, 'brdf_kind', nf90_int, [dx, dy], vk)
    vid = 0
    do kk = 1, 4
      do i = 1, BRDF_NPAR
        if (len_trim(BRDF_MAP_VARS(i, kk)) == 0) cycle
        st = st + nf90_def_var(nc, trim(BRDF_MAP_VARS(i, kk)), nf90_double, [dx, dy], vid(i, kk))
      end do
    end do
    st = st + nf90_enddef(nc)
    st = st + nf90_put_var(nc, vk, kinds)
    do kk = 1, 4
      do i = 1, BRDF_NPAR
        if (vid(i, kk) == 0) cycle
        do iy = 1, 2
          do ix = 1, 3
            par(ix, iy) = merge(real(rec(ix, iy, 2 + i), dp), 0.0_dp, kinds(ix, iy) == kk)
          end do
        end do
        st = st + nf90_put_var(nc, vid(i, kk), par)
      end do
    end do
    st = st + nf90_close(nc)
    call check(error, st == NF90_NOERR, 'writing mca_mixed_ref.nc')
    if (allocated(error)) return
    nml = surface_nml('&kumo_surface brdf_file = ''mca_mixed_ref.nc'' /', 12, &
                      'mca_mixed_ref_out.nc')
    call run_namelist('mca_mixed_ref.nml', nml, b, error)
    if (allocated(error)) return
    call get_scalar(a, 'reflectance', ra, sa, error)
    call get_scalar(b, 'reflectance', rb, sb, error)
    call get_scalar(a, 'absorptance_surface', aa, sa, error)
    call get_scalar(b, 'absorptance_surface', ab, sb, error)
    if (allocated(error)) return
    call check(error, ra == rb .and. aa == ab, 'MCARaTS mixed map: R '//str(ra)//', surface '// &
               'absorptance '//str(aa)//'; brdf_file: '//str(rb)//', '//str(ab))
  end subroutine test_surface_mixed

  !> A kind that surface_mbrdf does not enable, and pixel counts that do not fit the file.
  subroutine test_surface_errors(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(result_set_t) :: res
    type(error_t), allocatable :: err
    real(real32) :: rec(2, 1, 7)
    character(len=:), allocatable :: nml
    rec = 0.0
    rec(:, 1, 1) = 290.0
    rec(:, 1, 2) = [1.0, 3.0]
    rec(1, 1, 3) = 0.3
    rec(2, 1, 3:6) = [0.12, 0.7, -0.15, 0.3]
    call write_f32('mca_rpv.sfc', reshape(rec, [size(rec)]))
    ! Lambert, DSM and LSRT enabled (five fields): the RPV pixel is not allowed
    nml = surface_nml('&kumo_surface surface_file = ''mca_rpv.sfc'', surface_nxb = 2, '// &
                      'surface_nyb = 1, surface_mbrdf = 1, 1, 0, 1 /', 1, 'mca_rpv_out.nc')
    call write_text('mca_rpv.nml', nml)
    call read_config('mca_rpv.nml', cfg, error)
    if (allocated(error)) return
    call run_config(cfg, res, err)
    call expect_error(error, err, [character(len=60) :: 'mca_rpv.sfc: pixel (ix=2, iy=1)', &
                                   'BRDF type 3 (RPV) is not enabled', 'mbrdf = 1, 1, 0, 1'])
    if (allocated(error)) return
    ! 2 x 1 pixels of 2 + 4 records (Lambert and RPV enabled) read as 3 x 1 pixels: 48 bytes,
    ! less than one dataset of 6 records x 3 values
    call write_f32('mca_rpv.sfc', reshape(rec(:, :, 1:6), [12]))
    nml = surface_nml('&kumo_surface surface_file = ''mca_rpv.sfc'', surface_nxb = 3, '// &
                      'surface_nyb = 1, surface_mbrdf = 1, 0, 1, 0 /', 1, 'mca_rpv_out.nc')
    call write_text('mca_rpv3.nml', nml)
    call read_config('mca_rpv3.nml', cfg, error)
    if (allocated(error)) return
    call run_config(cfg, res, err)
    call expect_error(error, err, [character(len=60) :: 'mca_rpv.sfc: 48 bytes', &
                                   'fewer than one dataset of 6 records x 3', '72 bytes'])
  end subroutine test_surface_errors

  ! ------------------------------------------------------------------------------------------
  ! Helpers
  ! ------------------------------------------------------------------------------------------

  !> A real with 17 significant digits: read back, it is the same double.
  function r17(x) result(s)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: s
    character(len=32) :: buf
    write (buf, '(es24.16)') x
    s = trim(adjustl(buf))
  end function r17

  subroutine write_text(path, text)
    character(len=*), intent(in) :: path, text
    integer :: u
    open (newunit=u, file=path, status='replace', action='write')
    write (u, '(a)') text
    close (u)
  end subroutine write_text

  !> Raw native float32 values, as MCARaTS writes them.
  subroutine write_f32(path, values)
    character(len=*), intent(in) :: path
    real(real32), intent(in) :: values(:)
    integer :: u
    open (newunit=u, file=path, status='replace', action='write', access='stream', &
          form='unformatted')
    write (u) values
    close (u)
  end subroutine write_f32

  subroutine run_namelist(path, text, set, error)
    character(len=*), intent(in) :: path, text
    type(result_set_t), intent(out) :: set
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    call write_text(path, text)
    call read_config(path, cfg, error)
    if (allocated(error)) return
    call run_config(cfg, set, error)
  end subroutine run_namelist

  !> |a - b| <= K sigma of the difference for R, T, A and the layer absorption. (Where each
  !> voxel's components go is checked exactly by test_small_components.)
  subroutine compare_runs(a, b, error)
    type(result_set_t), intent(in) :: a, b
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), parameter :: NAMES(3) = &
      [character(len=22) :: 'reflectance', 'transmittance', 'absorptance_atmosphere']
    character(len=*), parameter :: MAPS(1) = [character(len=17) :: 'absorptance_layer']
    real(dp) :: ma, sa, mb, sb
    real(dp), allocatable :: va(:), ea(:), vb(:), eb(:)
    integer :: i, j
    do i = 1, size(NAMES)
      call get_scalar(a, trim(NAMES(i)), ma, sa, error)
      call get_scalar(b, trim(NAMES(i)), mb, sb, error)
      if (allocated(error)) return
      call check_sigma(error, ma - mb, 0.0_dp, sqrt(sa**2 + sb**2), K, trim(NAMES(i)))
    end do
    do j = 1, size(MAPS)
      call get_array(a, trim(MAPS(j)), va, ea, error)
      call get_array(b, trim(MAPS(j)), vb, eb, error)
      if (allocated(error)) return
      call check(error, size(va) == size(vb), trim(MAPS(j))//' sizes differ')
      if (allocated(error)) return
      do i = 1, size(va)
        call check_sigma(error, va(i) - vb(i), 0.0_dp, sqrt(ea(i)**2 + eb(i)**2), K, &
                         trim(MAPS(j))//'('//str(i)//')', abs_floor=1.0e-12_dp)
      end do
    end do
  end subroutine compare_runs

  !> The call must have failed with a message holding every one of `words`.
  subroutine expect_error(error, err, words)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: words(:)
    integer :: i
    if (allocated(error)) return
    if (.not. allocated(err)) then
      call check(error, .false., 'no error; expected one with "'//trim(words(1))//'"')
      return
    end if
    do i = 1, size(words)
      call check(error, index(err%message, trim(words(i))) > 0, 'message "'//err%message// &
                 '" lacks "'//trim(words(i))//'"')
    end do
  end subroutine expect_error
end module test_mcarats_input_suite

program test_mcarats_input
  use test_mcarats_input_suite, only: collect_mcarats_input
  use kumo_test_text, only: run_shared_suite
  implicit none
  call run_shared_suite('test_mcarats_input', 'data/mcarats', 'MCARaTS input files in runs', &
                        collect_mcarats_input())
end program test_mcarats_input
