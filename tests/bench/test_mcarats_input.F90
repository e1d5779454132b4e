! SPDX-License-Identifier: BSD-3-Clause
!> MCARaTS input files in whole runs (&kumo_cloud cloud_format = 'mcarats', &kumo_surface
!> surface_file).
!>
!> * A small MCARaTS atmosphere and phase-function file written here (binary, two components,
!>   two k-terms): every kind of apf code (isotropic, Rayleigh, Henyey-Greenstein, tables with
!>   and without a fractional blend), a gas-absorption perturbation with negative values and
!>   temperatures kumo must ignore. The atmosphere kumo builds (every voxel's extinction,
!>   albedo, scattering fractions, phase indices and blend weights) is checked value by value
!>   against the MCARaTS rules evaluated here, and the run is compared with the same scene
!>   written by the test in kumo's own route (a netCDF scene file whose components the test
!>   computes: the blend as the two tables' shares (1 - r) ext and r ext, the total gas
!>   absorption abs1d + absg3d as one voxel component with the 1-D absorber taken out of the
!>   3-D layers; text tables and HG entries in &kumo_phase), with another seed: reflectance,
!>   transmittance, absorptance and the layer absorption agree within K = 4 standard errors of
!>   the difference.
!> * The shipped MCARaTS example (data/mcarats/les05_0213.atm + .sca, through their .ctl and as
!>   binary files with the sizes in the namelist): grid, phase functions, every voxel of the
!>   atmosphere against the file's float32 records read here as raw bytes, the same atmosphere
!>   by both routes, and a short run whose energy budget closes.
!> * The surface: an MCARaTS Lambert map gives exactly the run of the same map as kumo's
!>   netCDF albedo_file, and a map of mixed kinds exactly that of kumo's netCDF brdf_file (same
!>   seed; kumo represents both); a kind the namelist does not enable, or wrong pixel counts,
!>   are rejected with the file and the rule in the message.
module test_mcarats_input_suite
  use, intrinsic :: iso_fortran_env, only: real32
  use kumo_kinds, only: wp, dp, vp
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_sigma, &
                          check_error_words
  use kumo_config, only: config_t
  use kumo_scene_setup, only: load_config
  use kumo_results, only: result_set_t
  use kumo_test_scenes, only: run_config, run_namelist, run_groups, get_scalar, get_array
  use kumo_test_text, only: shared_dir, write_text
  use kumo_netcdf, only: write_scene_3d, BRDF_MAP_VARS
  use kumo_cloud_scene, only: build_cloud_atmosphere
  use kumo_cloud_input, only: cloud_input_t, read_cloud_input
  use kumo_atmosphere, only: atmosphere_t, atmosphere_options_t
  use kumo_phase, only: phase_t, new_phase_isotropic, PHASE_ISOTROPIC, PHASE_RAYLEIGH, PHASE_HG, &
                        PHASE_TABLE
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
  !> The atmosphere keeps voxel optics in single precision (vp): each value is a sum of up to
  !> four terms rounded to vp after every addition, or a ratio of two such sums rounded once
  !> more, so at most 7 roundings of 2**-24 relative each (partial sums stay within 10 % of
  !> the total here); 8 epsilon(vp) = 16 * 2**-24 bounds that with room. An error in a
  !> component (a missing perturbation, a wrong albedo) is 1e-3 or more.
  real(dp), parameter :: REL_VP = 8*real(epsilon(1.0_vp), dp)

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
    text = run_groups(1500, 40, seed, 'sza_deg = 35.0, phi0_deg = 30.0', out, 'albedo = 0.15')
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

  !> The same scene as voxel components of kumo's own scene-file route (test_small_run), with
  !> phase indices in the order of its &kumo_phase: Rayleigh 1 (the 1-D molecules), isotropic
  !> 2, Rayleigh 3, HG g = -0.4, 0.7 (4, 5), tables 6..8; component 1; component 2 as two
  !> components at (1 - r) ext and r ext with tables int(apf) and int(apf) + 1 (a photon
  !> chooses them by their share of the scattering, which is the blend); absorption. Built
  !> here from the MCARaTS rules of docs/mcarats-interface.md section 3.2.
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

  !> The atmosphere kumo builds from the small files: every voxel's total extinction, mixture
  !> albedo, cumulative scattering fractions, phase indices and blend weights against the
  !> MCARaTS rules (docs/mcarats-interface.md section 3.2) applied here to the float32 values
  !> the test wrote. Components: the 1-D absorber (ABS1D in the 3-D layers), MCARaTS
  !> components 1 and 2, the gas-absorption perturbation of k-term 2. Phase functions after
  !> NOFF placeholders: isotropic, Rayleigh, HG g = -0.4, 0.7 (sorted), tables 1..3.
  subroutine test_small_components(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: NOFF = 3
    type(config_t) :: cfg
    type(atmosphere_t) :: atm
    character(len=:), allocatable :: notes
    real(real32) :: e(NX, NY, NZ3, NP3D), w(NX, NY, NZ3, NP3D), a(NX, NY, NZ3, NP3D)
    real(real32) :: absg(NX, NY, NZ3, NKD), tmp(NX, NY, NZ3 + 1)
    real(dp) :: ext, sca, sca1, code, r
    integer :: i, j, kk, ipf, iph(4), iph_exp(4)
    call write_small_files()
    call write_text('mca_small.nml', small_mcarats_nml(1, 'mca_small_out.nc', ABS1D))
    call load_config('mca_small.nml', cfg, error)
    if (allocated(error)) return
    call check(error, cfg%cloud%grid%nx == NX .and. cfg%cloud%grid%nz == NZ3 .and. &
               abs(cfg%cloud%grid%dx - 100.0_wp) < 1.0e-12_wp .and. cfg%atm%k3d_bottom == K3D, &
               'grid of the region from the namelist')
    if (allocated(error)) return
    call build_atm(cfg, NOFF, ABS1D, 500, atm, notes, error)
    if (allocated(error)) return
    call check(error, size(atm%phases) == NOFF + 7 .and. atm%ncomp == 4 .and. &
               atm%k3_lo == K3D .and. atm%n3 == NZ3, 'phase functions '//str(size(atm%phases))// &
               ' (expected '//str(NOFF)//' + 7: isotropic, Rayleigh, 2 HG, 3 tables), '// &
               'components '//str(atm%ncomp)//' (expected 4), 3-D layers '//str(atm%k3_lo)// &
               '..'//str(atm%k3_hi)//' (expected '//str(K3D)//'..'//str(K3D + NZ3 - 1)//')')
    if (allocated(error)) return
    call check(error, atm%phases(NOFF + 1)%kind == PHASE_ISOTROPIC .and. &
               atm%phases(NOFF + 2)%kind == PHASE_RAYLEIGH .and. &
               atm%phases(NOFF + 3)%kind == PHASE_HG .and. &
               atm%phases(NOFF + 4)%kind == PHASE_HG .and. &
               all(atm%phases(NOFF + 5:NOFF + 7)%kind == PHASE_TABLE), 'phase-function kinds')
    call check_close(error, atm%phases(NOFF + 3)%g, real(-0.4_real32, dp), rel_tol=0.0_dp, &
                     label='first HG g (sorted)')
    call check_close(error, atm%phases(NOFF + 4)%g, real(0.7_real32, dp), rel_tol=0.0_dp, &
                     label='second HG g')
    ! a table's g from kumo's quadrature of the sampled HG (1-degree steps): the tables keep
    ! their file order
    do ipf = 1, NPF
      call check_close(error, atm%phases(NOFF + 4 + ipf)%g, GTAB(ipf), abs_tol=2.0e-3_dp, &
                       label='table '//str(ipf)//' g')
    end do
    call check(error, associated(atm%wph3) .and. associated(atm%csca3), 'blend weights and '// &
               'scattering fractions are stored')
    if (allocated(error)) return

    call small_fields(e, w, a, absg, tmp)
    do kk = 1, NZ3
      do j = 1, NY
        do i = 1, NX
          ! the MCARaTS rules: apf <= -2 isotropic, <= -1 Rayleigh, < 1 HG, else tables
          code = real(a(i, j, kk, 1), dp)
          if (code <= -2.0_dp) then
            iph_exp(2) = NOFF + 1
          else if (code <= -1.0_dp) then
            iph_exp(2) = NOFF + 2
          else if (code < 0.0_dp) then
            iph_exp(2) = NOFF + 3
          else
            iph_exp(2) = NOFF + 4
          end if
          code = real(a(i, j, kk, 2), dp)
          ipf = int(code)
          r = code - ipf
          iph_exp(1) = 1
          iph_exp(3) = NOFF + 4 + ipf
          iph_exp(4) = NOFF + 1
          ext = ABS1D + real(e(i, j, kk, 1), dp) + real(e(i, j, kk, 2), dp) + &
                real(absg(i, j, kk, 2), dp)
          sca1 = real(e(i, j, kk, 1), dp)*real(w(i, j, kk, 1), dp)
          sca = sca1 + real(e(i, j, kk, 2), dp)*real(w(i, j, kk, 2), dp)
          call check_close(error, real(atm%ext3(i, j, kk), dp), ext, rel_tol=REL_VP, &
                           label='ext3'//at(i, j, kk))
          call check_close(error, real(atm%omg3(i, j, kk), dp), sca/ext, rel_tol=REL_VP, &
                           label='omg3'//at(i, j, kk))
          call check_close(error, real(atm%csca3(1, i, j, kk), dp), 0.0_dp, abs_tol=0.0_dp, &
                           label='csca3(1) (1-D absorber)'//at(i, j, kk))
          call check_close(error, real(atm%csca3(2, i, j, kk), dp), sca1/sca, rel_tol=REL_VP, &
                           label='csca3(2)'//at(i, j, kk))
          call check_close(error, real(atm%csca3(3, i, j, kk), dp), 1.0_dp, rel_tol=REL_VP, &
                           label='csca3(3)'//at(i, j, kk))
          call voxel_phases(atm, i, j, kk, iph)
          call check(error, all(iph == iph_exp), 'phase indices'//at(i, j, kk)//': '// &
                     str(iph(1))//', '//str(iph(2))//', '//str(iph(3))//', '//str(iph(4))// &
                     ', expected '//str(iph_exp(1))//', '//str(iph_exp(2))//', '// &
                     str(iph_exp(3))//', '//str(iph_exp(4)))
          call check_close(error, real(atm%wph3(3, i, j, kk), dp), r, abs_tol=REL_VP, &
                           label='blend weight of component 2'//at(i, j, kk))
          call check(error, atm%wph3(1, i, j, kk) == 0.0_vp .and. &
                     atm%wph3(2, i, j, kk) == 0.0_vp .and. atm%wph3(4, i, j, kk) == 0.0_vp, &
                     'blend weights of the other components'//at(i, j, kk))
          if (allocated(error)) return
        end do
      end do
    end do
    ! 23 of the 36 codes of component 2 are fractional (1.2, 2.7, 1.4)
    call check(error, index(notes, '23 blending two tables') > 0 .and. &
               index(notes, 'its temperatures (tmpa3d) are not used (no &kumo_thermal)') > 0, &
               'notes: '//notes)
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

  !> The shipped example through its .ctl files: the grid from the namelist and the .ctl, and
  !> every voxel of the atmosphere kumo builds against the file's float32 records read here
  !> byte by byte (GrADS layout of the .ctl: 22 records tmpa3d, then 21 each of abst3d,
  !> extp3d, omgp3d, apfp3d, each nx x ny values, x fastest). Components: the namelist's 1-D
  !> absorber, the one MCARaTS component, the gas-absorption perturbation. Then the binary
  !> files with the sizes in the namelist give the same atmosphere, and a short run closes its
  !> energy budget.
  subroutine test_les05(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: NOFF = 1, LX = 60, LY = 60, LZ = 21, NREC = 22 + 4*LZ, LNPF = 60
    real(wp), parameter :: ABS_M1 = 1.2e-5_wp
    type(config_t) :: cfg, cfg_bin
    type(atmosphere_t) :: atm, atm_bin
    type(result_set_t) :: res
    character(len=:), allocatable :: nml, notes
    real(real32), allocatable :: rec(:, :, :)
    real(dp) :: m, s, r, sr, e, om, g, ext, sca
    logical :: used(LNPF)
    integer :: u, i, j, kk, ipf, iph(3), iph_exp(3), n_bad
    call write_text('mca_les05.nml', les05_atmosphere(ABS_M1, '')// &
                    les05_cloud('les05_0213.atm.ctl', 'les05_0213.sca.ctl', ''))
    call load_config('mca_les05.nml', cfg, error)
    if (allocated(error)) return
    ! the .ctl: XDEF 60, YDEF 60, 21 layers; the namelist: 30 m columns from layer 10 (250 m)
    call check(error, cfg%atm%nx == LX .and. cfg%atm%ny == LY .and. cfg%atm%nz3 == LZ .and. &
               cfg%cloud%grid%nz == LZ, 'sizes from the .ctl')
    call check_close(error, cfg%cloud%grid%dx, 30.0_dp, rel_tol=TIGHT, label='dx')
    call check_close(error, cfg%cloud%grid%z(0), 250.0_dp, rel_tol=TIGHT, label='region bottom')
    call check_close(error, cfg%cloud%grid%z(21), 460.0_dp, rel_tol=TIGHT, label='region top')
    if (allocated(error)) return
    call build_atm(cfg, NOFF, ABS_M1, 1000, atm, notes, error)
    if (allocated(error)) return

    ! the raw file
    allocate (rec(LX, LY, NREC))
    open (newunit=u, file=shared_dir//'/data/mcarats/les05_0213.atm', access='stream', &
          form='unformatted', status='old', action='read')
    read (u) rec
    close (u)
    ! the tables the apf codes name: numpy found 1 and 32..60, all whole numbers (no blend)
    used = .false.
    n_bad = 0
    do kk = 1, LZ
      do j = 1, LY
        do i = 1, LX
          g = real(rec(i, j, 22 + 3*LZ + kk), dp)
          if (g >= 1.0_dp .and. g <= LNPF .and. g == aint(g)) then
            used(int(g)) = .true.
          else
            n_bad = n_bad + 1
          end if
        end do
      end do
    end do
    call check(error, n_bad == 0 .and. count(used) == 30, str(n_bad)//' apf codes are not '// &
               'whole table numbers, '//str(count(used))//' tables used (expected 0, 30)')
    if (allocated(error)) return
    ! isotropic, Rayleigh, no HG, the 30 tables; the 1-D absorber, the cloud, the perturbation
    ! (non-zero somewhere)
    call check(error, size(atm%phases) == NOFF + 2 + 30 .and. atm%ncomp == 3 .and. &
               .not. associated(atm%wph3), 'phases '//str(size(atm%phases))//' (expected '// &
               str(NOFF + 32)//'), components '//str(atm%ncomp)//' (expected 3), no blend')
    if (allocated(error)) return
    do kk = 1, LZ
      do j = 1, LY
        do i = 1, LX
          g = real(rec(i, j, 22 + kk), dp)            ! abst3d
          e = real(rec(i, j, 22 + LZ + kk), dp)       ! extp3d
          om = real(rec(i, j, 22 + 2*LZ + kk), dp)    ! omgp3d
          ipf = int(rec(i, j, 22 + 3*LZ + kk))        ! apfp3d
          ext = ABS_M1 + e + g
          sca = e*om
          call check_close(error, real(atm%ext3(i, j, kk), dp), ext, rel_tol=REL_VP, &
                           label='ext3'//at(i, j, kk))
          call check_close(error, real(atm%omg3(i, j, kk), dp), sca/ext, rel_tol=REL_VP, &
                           label='omg3'//at(i, j, kk))
          if (sca > 0.0_dp) then   ! the cloud scatters all; else equal fractions
            call check(error, atm%csca3(1, i, j, kk) == 0.0_vp .and. &
                       atm%csca3(2, i, j, kk) == 1.0_vp, 'csca3'//at(i, j, kk))
          else
            call check(error, abs(real(atm%csca3(1, i, j, kk), dp) - 1.0_dp/3) < REL_VP .and. &
                       abs(real(atm%csca3(2, i, j, kk), dp) - 2.0_dp/3) < REL_VP, &
                       'csca3'//at(i, j, kk))
          end if
          ! table ipf is the count(used(1:ipf))-th table after isotropic and Rayleigh
          iph_exp = [1, NOFF + 2 + count(used(1:ipf)), NOFF + 1]
          call voxel_phases(atm, i, j, kk, iph)
          call check(error, all(iph == iph_exp), 'phase indices'//at(i, j, kk)//': '// &
                     str(iph(2))//', '//str(iph(3))//', expected '//str(iph_exp(2))//', '// &
                     str(iph_exp(3)))
          if (allocated(error)) return
        end do
      end do
    end do
    ! the last phase function is table 60: its forward/backward ratio is the file's
    ! (les05_0213.sca: a record of the 203 angles 0 ... 180 deg, then the 60 tables),
    ! whatever the normalisation
    deallocate (rec)
    allocate (rec(203, 1, 1 + LNPF))
    open (newunit=u, file=shared_dir//'/data/mcarats/les05_0213.sca', access='stream', &
          form='unformatted', status='old', action='read')
    read (u) rec
    close (u)
    call check(error, rec(1, 1, 1) == 0.0 .and. rec(203, 1, 1) == 180.0, 'angles of '// &
               'les05_0213.sca: '//str(real(rec(1, 1, 1), dp))//' ... '// &
               str(real(rec(203, 1, 1), dp))//', expected 0 ... 180')
    associate (p => atm%phases(NOFF + 32)%p_tab)
      call check_close(error, p(size(p))/p(1), real(rec(1, 1, 1 + LNPF), dp)/ &
                       real(rec(203, 1, 1 + LNPF), dp), rel_tol=TIGHT, &
                       label='P(0)/P(180) of table 60')
    end associate
    if (allocated(error)) return

    ! the same files as binaries, with the sizes in the namelist (conf_hr0213: Atm_nx, Atm_ny,
    ! Atm_nz3, Atm_mtprof; Sca_nangi, Sca_npf): the same atmosphere
    nml = les05_atmosphere(ABS_M1, ', nx = 60, ny = 60, nz3 = 21')// &
          les05_cloud('les05_0213.atm', 'les05_0213.sca', &
                      ', mcarats_mtprof = 1, mcarats_nang = 203, mcarats_npf = 60')
    call write_text('mca_les05_bin.nml', nml)
    call load_config('mca_les05_bin.nml', cfg_bin, error)
    if (allocated(error)) return
    call build_atm(cfg_bin, NOFF, ABS_M1, 1000, atm_bin, notes, error)
    if (allocated(error)) return
    call check(error, all(atm_bin%ext3 == atm%ext3) .and. all(atm_bin%omg3 == atm%omg3) .and. &
               all(atm_bin%csca3 == atm%csca3) .and. all(atm_bin%iph3 == atm%iph3) .and. &
               size(atm_bin%phases) == size(atm%phases), &
               'binary files with namelist sizes give another atmosphere than the .ctl route')
    if (allocated(error)) return

    ! a short run: the budget closes in every batch, and the cloud reflects
    call write_text('mca_les05_run.nml', les05_atmosphere(ABS_M1, '')// &
                    les05_cloud('les05_0213.atm.ctl', 'les05_0213.sca.ctl', '')// &
                    '&kumo_control n_photons_per_batch = 400, n_batches = 3, verbose = 0 /'// &
                    new_line('a')//'&kumo_surface albedo = 0.2 /'//new_line('a')// &
                    '&kumo_output file = ''mca_les05_out.nc'' /')
    call load_config('mca_les05_run.nml', cfg, error)
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
    type(atmosphere_t) :: atm
    character(len=:), allocatable :: notes
    type(error_t), allocatable :: err
    ! the smallest perturbation is -1.1268867e-06 m-1 (numpy); 1e-6 m-1 of 1-D absorption
    ! leaves some voxels negative
    call write_text('mca_les05_neg.nml', les05_atmosphere(1.0e-6_wp, '')// &
                    les05_cloud('les05_0213.atm.ctl', 'les05_0213.sca.ctl', ''))
    call load_config('mca_les05_neg.nml', cfg, error)
    if (allocated(error)) return
    call build_atm(cfg, 1, 1.0e-6_wp, 1000, atm, notes, err)
    call check_error_words(error, err, [character(len=60) :: 'les05_0213.atm.ctl: absg3d k-term 1', &
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
    real(dp) :: ra, sa, rb, sb
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
    ! the same surface and seed: the same photons, so the same numbers
    call check_same_run(a, 'mca_lambert_ref.nml', nml, 'MCARaTS Lambert map', 'albedo_file', error)
    if (allocated(error)) return
    ! and the map matters: the mean albedo 0.425 as a uniform surface gives another answer
    nml = surface_nml('&kumo_surface albedo = 0.425 /', 11, 'mca_uniform_out.nc')
    call run_namelist('mca_uniform.nml', nml, b, error)
    if (allocated(error)) return
    call get_scalar(a, 'reflectance', ra, sa, error)
    call get_scalar(b, 'reflectance', rb, sb, error)
    if (allocated(error)) return
    call check(error, ra /= rb, 'the map gives the uniform surface''s reflectance')
  end subroutine test_surface_lambert

  !> 3 x 2 pixels of every kind (two Lambert, black, DSM, RPV, LSRT): the MCARaTS file (five
  !> parameter fields) against kumo's netCDF BRDF map of the same float32 values.
  subroutine test_surface_mixed(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: a
    real(real32) :: rec(3, 2, 7)
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
    call check_same_run(a, 'mca_mixed_ref.nml', nml, 'MCARaTS mixed map', 'brdf_file', error)
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
    call load_config('mca_rpv.nml', cfg, error)
    if (allocated(error)) return
    call run_config(cfg, res, err)
    call check_error_words(error, err, [character(len=60) :: 'mca_rpv.sfc: pixel (ix=2, iy=1)', &
                                   'BRDF type 3 (RPV) is not enabled', 'mbrdf = 1, 1, 0, 1'])
    if (allocated(error)) return
    ! 2 x 1 pixels of 2 + 4 records (Lambert and RPV enabled) read as 3 x 1 pixels: 48 bytes,
    ! less than one dataset of 6 records x 3 values
    call write_f32('mca_rpv.sfc', reshape(rec(:, :, 1:6), [12]))
    nml = surface_nml('&kumo_surface surface_file = ''mca_rpv.sfc'', surface_nxb = 3, '// &
                      'surface_nyb = 1, surface_mbrdf = 1, 0, 1, 0 /', 1, 'mca_rpv_out.nc')
    call write_text('mca_rpv3.nml', nml)
    call load_config('mca_rpv3.nml', cfg, error)
    if (allocated(error)) return
    call run_config(cfg, res, err)
    call check_error_words(error, err, [character(len=60) :: 'mca_rpv.sfc: 48 bytes', &
                                   'fewer than one dataset of 6 records x 3', '72 bytes'])
  end subroutine test_surface_errors

  ! ------------------------------------------------------------------------------------------
  ! Helpers
  ! ------------------------------------------------------------------------------------------

  !> The atmosphere kumo builds from the cloud file of `cfg` at table size `n_table`, with
  !> `noff` isotropic phase functions standing for the scene's own before the cloud's and one
  !> 1-D component in every layer: an absorber of `abs_m1` [m-1] (albedo 0), the 1-D gas
  !> absorption of these tests' namelists in the 3-D layers.
  subroutine build_atm(cfg, noff, abs_m1, n_table, atm, notes, error)
    type(config_t), intent(in) :: cfg
    integer, intent(in) :: noff, n_table
    real(wp), intent(in) :: abs_m1
    type(atmosphere_t), intent(out) :: atm
    character(len=:), allocatable, intent(out) :: notes
    type(error_t), allocatable, intent(out) :: error
    type(phase_t), allocatable :: phases(:)
    type(atmosphere_options_t) :: aopts
    real(wp), allocatable :: ext1d(:, :), ssa1d(:, :)
    integer, allocatable :: iph1d(:, :)
    character(len=:), allocatable :: warnings
    type(cloud_input_t) :: c, c_ice
    integer :: i, nz
    call read_cloud_input(cfg%cloud%req, c, error, part='liquid')
    if (allocated(error)) return
    nz = cfg%atm%nz
    allocate (phases(noff), ext1d(nz, 1), ssa1d(nz, 1), iph1d(nz, 1))
    do i = 1, noff
      phases(i) = new_phase_isotropic()
    end do
    ext1d = abs_m1
    ssa1d = 0.0_wp
    iph1d = 1
    call build_cloud_atmosphere(cfg%cloud, c, c_ice, 0.0_wp, n_table, cfg%atm%z, cfg%atm%lx, &
                                cfg%atm%ly, cfg%atm%k3d_bottom, ext1d, ssa1d, iph1d, phases, &
                                aopts, atm, notes, warnings, error)
  end subroutine build_atm

  !> The phase indices of the components of voxel (i, j) of 3-D layer kr (iph3 is dropped
  !> when every voxel has the same).
  subroutine voxel_phases(atm, i, j, kr, iph)
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: i, j, kr
    integer, intent(out) :: iph(:)
    if (associated(atm%iph3)) then
      iph = atm%iph3(:, i, j, kr)
    else
      iph = atm%iph3_const
    end if
  end subroutine voxel_phases

  !> " at (i,j,k)" for messages.
  function at(i, j, k) result(s)
    integer, intent(in) :: i, j, k
    character(len=:), allocatable :: s
    s = ' at ('//str(i)//','//str(j)//','//str(k)//')'
  end function at

  !> A real with 17 significant digits: read back, it is the same double.
  function r17(x) result(s)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: s
    character(len=32) :: buf
    write (buf, '(es24.16)') x
    s = trim(adjustl(buf))
  end function r17

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

  !> Run the namelist `nml` (written to `path`) and require the reflectance and the surface
  !> absorptance of run `a` to the last bit: the same surface given another way, same seed.
  subroutine check_same_run(a, path, nml, label, other, error)
    type(result_set_t), intent(in) :: a
    character(len=*), intent(in) :: path, nml, label, other
    type(error_t), allocatable, intent(inout) :: error
    type(result_set_t) :: b
    real(dp) :: ra, rb, ta, tb, s
    call run_namelist(path, nml, b, error)
    if (allocated(error)) return
    call get_scalar(a, 'reflectance', ra, s, error)
    call get_scalar(b, 'reflectance', rb, s, error)
    call get_scalar(a, 'absorptance_surface', ta, s, error)
    call get_scalar(b, 'absorptance_surface', tb, s, error)
    if (allocated(error)) return
    call check(error, ra == rb .and. ta == tb, label//': R '//str(ra)//', surface '// &
               'absorptance '//str(ta)//'; '//other//': '//str(rb)//', '//str(tb))
  end subroutine check_same_run

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

end module test_mcarats_input_suite

program test_mcarats_input
  use test_mcarats_input_suite, only: collect_mcarats_input
  use kumo_test_text, only: run_shared_suite
  implicit none
  call run_shared_suite('test_mcarats_input', 'data/mcarats', 'MCARaTS input files in runs', &
                        collect_mcarats_input())
end program test_mcarats_input
