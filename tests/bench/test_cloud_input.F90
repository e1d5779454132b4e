! SPDX-License-Identifier: BSD-3-Clause
!> Cloud files in whole runs (&kumo_cloud): the same cloud through every route gives one answer.
!>
!> * LES netCDF against the equivalent optical-property file. A small cloud is written as an
!>   LES file (liquid water in kg m-3, effective radius in m, coordinates in km, stretched
!>   layers with edges). The test then builds the optics itself, from the Mie table kumo
!>   cached and the test's own unit conversion and radius interpolation (the mixture of the
!>   two bracketing table populations whose effective radius is the voxel's, LWC shares
!>   f = (1/r - 1/r2)/(1/r1 - 1/r2)), writes them as a kumo scene file with the table's phase
!>   functions as text tables, and runs that with another seed. Reflectance, transmittance,
!>   absorptance and the layer absorption profile agree within 4 sigma of the difference.
!> * The same cloud as a MYSTIC flag-3 file and as an I3RC two-parameter LWC file gives the LES
!>   answer to rounding with the same seed: only the reader differs.
!> * Henyey-Greenstein optics as a MYSTIC flag-1 file (analytic HG) and as an SHDOM property
!>   file (Legendre moments g^l summed into a table) agree within 4 sigma with different seeds.
!> * A Mie phase function of the I3RC LES stratocumulus (`les_stcu_w213.prp`, its 14th table:
!>   230 Legendre moments, g = 0.8517) in a homogeneous slab written as a property file gives
!>   the reflectance and transmittance of an independent discrete-ordinates solution within
!>   4 sigma, at SZA 0 and 60.
module test_cloud_input_suite
  use kumo_kinds, only: wp, dp
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_sigma
  use kumo_results, only: result_set_t
  use kumo_test_scenes, only: run_config, run_namelist, run_groups, get_scalar, get_array
  use kumo_mie, only: mie_table_t
  use kumo_mie_table, only: read_mie_table
  use kumo_netcdf, only: write_scene_3d
  use kumo_error, only: str
  use kumo_shdom_files, only: prp_field_t, read_prp_file
  use kumo_test_text, only: shared_dir
  use netcdf, only: nf90_create, nf90_def_dim, nf90_def_var, nf90_enddef, nf90_put_var, &
                    nf90_close, nf90_put_att, nf90_clobber, nf90_double, NF90_GLOBAL
  implicit none
  private
  public :: collect_cloud_input

  integer, parameter :: NX = 6, NY = 5, NZ = 4
  real(wp), parameter :: DX_KM = 0.1_wp, DY_KM = 0.12_wp
  !> layer edges [km]: stretched, starting above the ground
  real(wp), parameter :: ZE_KM(0:NZ) = [0.5_wp, 0.6_wp, 0.75_wp, 0.85_wp, 1.0_wp]
  real(dp), parameter :: K = 4.0_dp

contains

  function collect_cloud_input() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('les_equals_optical_property_file', test_les_vs_optics), &
             new_unittest('mystic_and_lwc_files_equal_les', test_text_formats), &
             new_unittest('hg_as_legendre_equals_hg', test_hg_routes), &
             new_unittest('mie_slab_from_property_file_equals_disort', test_mie_slab_disort), &
             new_unittest('mie_slab_similarity_scaled_equals_disort', test_mie_slab_similarity)]
  end function collect_cloud_input

  !> The test cloud: LWC [g m-3] and r_eff [um]; some voxels clear, radii across the table.
  subroutine cloud(lwc, reff)
    real(wp), intent(out) :: lwc(NX, NY, NZ), reff(NX, NY, NZ)
    integer :: i, j, kk
    do kk = 1, NZ
      do j = 1, NY
        do i = 1, NX
          lwc(i, j, kk) = 0.05_wp*real(mod(i*3 + j*5 + kk*7, 11), wp)
          reff(i, j, kk) = 4.5_wp + 1.1_wp*real(mod(i + 2*j + 3*kk, 10), wp)
          if (lwc(i, j, kk) == 0.0_wp) reff(i, j, kk) = 0.0_wp
        end do
      end do
    end do
  end subroutine cloud

  !> Write the cloud as an LES netCDF file in SI units with km coordinates.
  subroutine write_les(path)
    character(len=*), intent(in) :: path
    real(wp) :: lwc(NX, NY, NZ), reff(NX, NY, NZ)
    integer :: nc, dx_, dy_, dz_, dze, vx, vy, vze, vl, vr, s, i
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
    s = nf90_put_att(nc, vl, 'units', 'kg m-3')
    s = nf90_def_var(nc, 'reff', nf90_double, [dx_, dy_, dz_], vr)
    s = nf90_put_att(nc, vr, 'units', 'm')
    s = nf90_put_att(nc, NF90_GLOBAL, 'title', 'kumo test cloud')
    s = nf90_enddef(nc)
    s = nf90_put_var(nc, vx, [((i - 0.5_wp)*DX_KM, i=1, NX)])
    s = nf90_put_var(nc, vy, [((i - 0.5_wp)*DY_KM, i=1, NY)])
    s = nf90_put_var(nc, vze, ZE_KM)
    s = nf90_put_var(nc, vl, lwc*1.0e-3_wp)
    s = nf90_put_var(nc, vr, reff*1.0e-6_wp)
    s = nf90_close(nc)
  end subroutine write_les

  function common_groups(seed, out) result(text)
    integer, intent(in) :: seed
    character(len=*), intent(in) :: out
    character(len=:), allocatable :: text
    text = run_groups(4000, 20, seed, 'sza_deg = 30.0, wavelength_um = 2.13', out, 'albedo = 0.2')
  end function common_groups

  function cloud_group(file, fmt) result(text)
    character(len=*), intent(in) :: file, fmt
    character(len=:), allocatable :: text
    text = '&kumo_cloud cloud_file = '''//file//''', cloud_format = '''//fmt//''', '// &
           'mie_cache = ''cloud_mie_test.nc'', n_reff = 6, reff_min_um = 4.0, '// &
           'reff_max_um = 16.0, v_eff = 0.1 /'//new_line('a')
  end function cloud_group

  !> |a - b| <= k sigma of the difference for R, T, A and the layer absorption.
  subroutine compare_runs(a, b, error)
    type(result_set_t), intent(in) :: a, b
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), parameter :: NAMES(3) = [character(len=22) :: 'reflectance', &
                                               'transmittance', 'absorptance_atmosphere']
    real(dp) :: ma, sa, mb, sb
    real(dp), allocatable :: va(:), ea(:), vb(:), eb(:)
    integer :: i
    do i = 1, size(NAMES)
      call get_scalar(a, trim(NAMES(i)), ma, sa, error)
      call get_scalar(b, trim(NAMES(i)), mb, sb, error)
      if (allocated(error)) return
      call check_sigma(error, ma - mb, 0.0_dp, sqrt(sa**2 + sb**2), K, trim(NAMES(i)))
    end do
    call get_array(a, 'absorptance_layer', va, ea, error)
    call get_array(b, 'absorptance_layer', vb, eb, error)
    if (allocated(error)) return
    call check(error, size(va) == size(vb), 'absorptance_layer sizes differ')
    do i = 1, size(va)
      call check_sigma(error, va(i) - vb(i), 0.0_dp, sqrt(ea(i)**2 + eb(i)**2), K, &
                       'absorptance_layer('//str(i)//')', abs_floor=1.0e-12_dp)
    end do
  end subroutine compare_runs

  subroutine test_les_vs_optics(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: a, b
    type(mie_table_t) :: t
    real(wp) :: lwc(NX, NY, NZ), reff(NX, NY, NZ), f, r, r1, r2
    real(wp) :: ext(NX, NY, NZ, 2), ssa(NX, NY, NZ, 2)
    integer :: iph(NX, NY, NZ, 2), i, j, kk, n, i1, u, ia
    character(len=:), allocatable :: nml, phases
    real(dp) :: ra, sa
    real(dp), allocatable :: va(:), ea(:), vb(:), eb(:)
    character(len=*), parameter :: RADIANCE = '&kumo_radiance rad_mu = 1.0, rad_phi_deg = 0.0, '// &
                                              'rad_levels = 5, radiance_maps = .false. /'
    call write_les('cloud_les_test.nc')
    ! the nadir radiance at the top as well: local estimates with the voxels' phase functions
    call run_namelist('cloud_les_test.nml', common_groups(1, 'cloud_les_out.nc')// &
                      cloud_group('cloud_les_test.nc', 'les')//RADIANCE, a, error)
    if (allocated(error)) return
    call get_scalar(a, 'reflectance', ra, sa, error)
    if (allocated(error)) return
    call check(error, ra > 0.05_dp .and. ra < 0.9_dp, 'LES cloud reflectance '//str(ra)// &
               ' is not that of a cloud')
    if (allocated(error)) return

    ! the equivalent optics, from the cached table
    call read_mie_table('cloud_mie_test.nc', t, error)
    if (allocated(error)) return
    n = size(t%r_eff_um)
    call cloud(lwc, reff)
    do kk = 1, NZ
      do j = 1, NY
        do i = 1, NX
          r = reff(i, j, kk)
          if (lwc(i, j, kk) <= 0.0_wp) then
            ext(i, j, kk, :) = 0.0_wp
            ssa(i, j, kk, :) = 1.0_wp
            iph(i, j, kk, :) = 1
            cycle
          end if
          i1 = 1
          do while (i1 < n - 1 .and. t%r_eff_um(i1 + 1) < r)
            i1 = i1 + 1
          end do
          r1 = t%r_eff_um(i1)
          r2 = t%r_eff_um(i1 + 1)
          f = (1.0_wp/r - 1.0_wp/r2)/(1.0_wp/r1 - 1.0_wp/r2)
          ext(i, j, kk, 1) = f*lwc(i, j, kk)*t%ext_per_lwc(i1)
          ext(i, j, kk, 2) = (1.0_wp - f)*lwc(i, j, kk)*t%ext_per_lwc(i1 + 1)
          ssa(i, j, kk, :) = [t%ssa(i1), t%ssa(i1 + 1)]
          iph(i, j, kk, :) = [i1, i1 + 1]
        end do
      end do
    end do
    call write_scene_3d('cloud_optics_test.nc', ext, ssa, iph, error)
    if (allocated(error)) return
    phases = ''
    do i = 1, n
      open (newunit=u, file='cloud_pf'//str(i)//'.txt', status='replace', action='write')
      do ia = 1, size(t%angle_deg)
        write (u, '(es24.16, 1x, es24.16)') t%angle_deg(ia), t%phase(ia, i)
      end do
      close (u)
      phases = phases//'  phase_kind('//str(i)//') = ''table'', phase_file('//str(i)// &
               ') = ''cloud_pf'//str(i)//'.txt'''//new_line('a')
    end do
    nml = common_groups(2, 'cloud_optics_out.nc')// &
          '&kumo_atmosphere nz = 5, z_levels = 0.0, 500.0, 600.0, 750.0, 850.0, 1000.0, '// &
          'lx = 600.0, ly = 600.0, scene_file = ''cloud_optics_test.nc'', k3d_bottom = 2, '// &
          'nx = 6, ny = 5, nz3 = 4, n_components_3d = 2 /'//new_line('a')// &
          '&kumo_phase n_phase = '//str(n)//new_line('a')//phases//'/'//new_line('a')//RADIANCE
    call run_namelist('cloud_optics_test.nml', nml, b, error)
    if (allocated(error)) return
    call compare_runs(a, b, error)
    call get_array(a, 'radiance', va, ea, error)
    call get_array(b, 'radiance', vb, eb, error)
    if (allocated(error)) return
    do i = 1, size(va)
      call check_sigma(error, va(i) - vb(i), 0.0_dp, sqrt(ea(i)**2 + eb(i)**2), K, &
                       'radiance('//str(i)//')')
    end do
  end subroutine test_les_vs_optics

  subroutine test_text_formats(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: a, b, c
    real(wp) :: lwc(NX, NY, NZ), reff(NX, NY, NZ)
    real(dp) :: ma, sa, mb, sb, mc, sc
    integer :: u, kk
    call cloud(lwc, reff)
    call write_les('cloud_les_test2.nc')
    open (newunit=u, file='cloud_test.mystic', status='replace', action='write')
    write (u, '(3i4, a)') NX, NY, NZ, ' 3'
    write (u, '(7f8.3)') DX_KM, DY_KM, ZE_KM
    call write_points(u, lwc, reff)
    close (u)
    open (newunit=u, file='cloud_test.lwc', status='replace', action='write')
    write (u, '(a)') '2  parameter LWC file'
    write (u, '(3i4)') NX, NY, NZ
    write (u, '(2f8.3)') DX_KM, DY_KM
    write (u, '(5f8.3)') ZE_KM
    write (u, '(5f8.2)') [(280.0_wp, kk=0, NZ)]
    call write_points(u, lwc, reff)
    close (u)
    call run_namelist('cloud_les_test2.nml', common_groups(5, 'cloud_les_out2.nc')// &
                      cloud_group('cloud_les_test2.nc', 'les'), a, error)
    if (allocated(error)) return
    call run_namelist('cloud_mystic_test.nml', common_groups(5, 'cloud_mystic_out.nc')// &
                      cloud_group('cloud_test.mystic', 'mystic'), b, error)
    if (allocated(error)) return
    call run_namelist('cloud_lwc_test.nml', common_groups(5, 'cloud_lwc_out.nc')// &
                      cloud_group('cloud_test.lwc', 'lwc'), c, error)
    if (allocated(error)) return
    call get_scalar(a, 'reflectance', ma, sa, error)
    call get_scalar(b, 'reflectance', mb, sb, error)
    call get_scalar(c, 'reflectance', mc, sc, error)
    if (allocated(error)) return
    ! same seed, same optics: the same photon paths, so equal to rounding (the text files
    ! hold 17 digits)
    call check(error, abs(ma - mb) <= 1.0e-9_dp*ma .and. abs(ma - mc) <= 1.0e-9_dp*ma, &
               'reflectance LES '//str(ma)//', MYSTIC '//str(mb)//', LWC file '//str(mc)// &
               ' differ with the same seed')
  end subroutine test_text_formats

  !> One line "ix iy iz lwc reff" per cloudy cell (MYSTIC flag 3 and LWC files alike).
  subroutine write_points(u, lwc, reff)
    integer, intent(in) :: u
    real(wp), intent(in) :: lwc(NX, NY, NZ), reff(NX, NY, NZ)
    integer :: i, j, kk
    do kk = 1, NZ
      do j = 1, NY
        do i = 1, NX
          if (lwc(i, j, kk) > 0.0_wp) write (u, '(3i4, 2es24.16)') i, j, kk, lwc(i, j, kk), &
            reff(i, j, kk)
        end do
      end do
    end do
  end subroutine write_points

  subroutine test_hg_routes(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: a, b
    real(wp), parameter :: G(2) = [0.8_wp, 0.6_wp]
    integer, parameter :: NLEG = 300
    real(wp) :: lwc(NX, NY, NZ), reff(NX, NY, NZ), e
    integer :: u, v, i, j, kk, l, ip
    call cloud(lwc, reff)
    open (newunit=u, file='cloud_hg.mystic', status='replace', action='write')
    write (u, '(3i4, a)') NX, NY, NZ, ' 1'
    write (u, '(7f8.3)') DX_KM, DY_KM, ZE_KM
    open (newunit=v, file='cloud_hg.prp', status='replace', action='write')
    write (v, '(a)') 'Tabulated phase function property file'
    write (v, '(3i4)') NX, NY, NZ
    write (v, '(7f8.3)') DX_KM, DY_KM, ZE_KM
    write (v, '(i4)') 2
    do ip = 1, 2
      write (v, '(i5, *(1x, es22.14))') NLEG, [((2*l + 1)*G(ip)**l, l=1, NLEG)]
    end do
    do kk = 1, NZ
      do j = 1, NY
        do i = 1, NX
          e = 20.0_wp*lwc(i, j, kk)       ! [km-1]
          ip = 1 + mod(i + j, 2)
          write (v, '(3i4, f7.1, es24.16, f10.6, i3)') i, j, kk, 280.0, e, 0.99_wp, ip
          if (e > 0.0_wp) write (u, '(3i4, es24.16, 2f10.6)') i, j, kk, e, G(ip), 0.99_wp
        end do
      end do
    end do
    close (u)
    close (v)
    call run_namelist('cloud_hg_mystic.nml', common_groups(7, 'cloud_hg_out1.nc')// &
                      '&kumo_cloud cloud_file = ''cloud_hg.mystic'', cloud_format = ''mystic'' /', &
                      a, error)
    if (allocated(error)) return
    call run_namelist('cloud_hg_prp.nml', common_groups(8, 'cloud_hg_out2.nc')// &
                      '&kumo_cloud cloud_file = ''cloud_hg.prp'', cloud_format = ''prp'' /', &
                      b, error)
    if (allocated(error)) return
    call compare_runs(a, b, error)
  end subroutine test_hg_routes

  !> A slab of optical depth 7.6 and albedo 0.976 (the domain means of les_stcu_w213.prp) with
  !> the file's 14th phase function, 0.4 km thick over a black surface, as a one-column
  !> property file whose moments are those read from the shipped file. References: the
  !> discrete-ordinates solver PythonicDISORT 1.8 (D. J. X. Ho, J. Open Source Softw. 9, 6442,
  !> 2024), 128 streams with delta-M scaling; 32, 64 and 128 streams agree to 6e-6, so the
  !> references are exact next to the Monte Carlo error. They were computed from the moments
  !> in the text of the file, so a misread moment shows here too.
  subroutine test_mie_slab_disort(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: set
    call mie_slab_vs_disort('cloud_mie_slab', 20, '', 'R', 'T', set, error)
  end subroutine test_mie_slab_disort

  !> The slab of test_mie_slab_disort with similarity-scaled truncation at 20 degrees
  !> (&kumo_vr similarity_theta_deg): R and T of the scaled medium hold against the same
  !> discrete-ordinates references of the original one (the scaling's bias for this phase
  !> function, 5e-5 to 8e-5 in R, is far below the Monte Carlo error), and the photons make
  !> far fewer collisions than in the original medium (tau' = tau (1 - omega f), f = 0.45).
  subroutine test_mie_slab_similarity(error)
    type(error_t), allocatable, intent(out) :: error
    type(result_set_t) :: set
    real(dp) :: ev_plain, ev_sim
    call mie_slab_vs_disort('cloud_mie_slab_sim', 40, new_line('a')// &
                            '&kumo_vr similarity_theta_deg = 20 /', 'scaled R', 'scaled T', set, &
                            error)
    if (allocated(error)) return
    ev_sim = num_attr(set, 'events_per_photon')
    call run_namelist('cloud_mie_slab_plain.nml', run_groups(2000, 4, 43, 'sza_deg = 60', &
                      'cloud_mie_slab_plain.nc')//'&kumo_cloud cloud_file = '// &
                      '''cloud_mie_slab.prp'', cloud_format = ''prp'' /', set, error)
    if (allocated(error)) return
    ev_plain = num_attr(set, 'events_per_photon')
    call check(error, ev_sim < 0.75_dp*ev_plain, 'collisions per photon: '//str(ev_sim)// &
               ' scaled against '//str(ev_plain)//' in the original medium; expected < 0.75 x')
  end subroutine test_mie_slab_similarity

  !> The Mie slab (write_mie_slab, table 14) at SZA 0 and 60 (seeds seed0 + 1, + 2; `extra`
  !> added to the namelist): R and T within K sigma of the discrete-ordinates references.
  !> `set` is the run at SZA 60.
  subroutine mie_slab_vs_disort(stem, seed0, extra, r_label, t_label, set, error)
    character(len=*), intent(in) :: stem, extra, r_label, t_label
    integer, intent(in) :: seed0
    type(result_set_t), intent(out) :: set
    type(error_t), allocatable, intent(out) :: error
    real(dp), parameter :: SZA(2) = [0.0_dp, 60.0_dp]
    real(dp), parameter :: R_REF(2) = [0.2421156_dp, 0.4012363_dp]
    real(dp), parameter :: T_REF(2) = [0.4968688_dp, 0.3010482_dp]
    real(dp) :: r, sr, t, st
    integer :: i
    call write_mie_slab(14, error)
    if (allocated(error)) return
    do i = 1, 2
      call run_namelist(stem//'.nml', run_groups(10000, 20, seed0 + i, 'sza_deg = '// &
                        str(SZA(i)), stem//'.nc')//'&kumo_cloud cloud_file = '// &
                        '''cloud_mie_slab.prp'', cloud_format = ''prp'' /'//extra, set, error)
      if (allocated(error)) return
      call get_scalar(set, 'reflectance', r, sr, error)
      call get_scalar(set, 'transmittance', t, st, error)
      if (allocated(error)) return
      call check_sigma(error, r, R_REF(i), sr, K, r_label//' at SZA '//str(SZA(i)))
      call check_sigma(error, t, T_REF(i), st, K, t_label//' at SZA '//str(SZA(i)))
      if (allocated(error)) return
    end do
  end subroutine mie_slab_vs_disort

  !> A numeric attribute of a result set (-1 if absent).
  real(dp) function num_attr(set, name) result(v)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: name
    integer :: i
    v = -1.0_dp
    if (.not. allocated(set%attrs)) return
    do i = 1, size(set%attrs)
      if (set%attrs(i)%name == name .and. allocated(set%attrs(i)%num)) v = set%attrs(i)%num(1)
    end do
  end function num_attr

  !> The slab of test_mie_slab_disort as a one-column property file, cloud_mie_slab.prp, with
  !> the moments of table `table` of the shipped les_stcu_w213.prp.
  subroutine write_mie_slab(table, error)
    integer, intent(in) :: table
    type(error_t), allocatable, intent(out) :: error
    type(prp_field_t) :: prp
    type(error_t), allocatable :: err
    integer :: u, l, n
    call read_prp_file(shared_dir//'/data/i3rc/les_examples/les_stcu_w213.prp', prp, err)
    if (allocated(err)) then
      call check(error, .false., 'les_stcu_w213.prp: '//err%message)
      return
    end if
    n = prp%nleg(table)
    call check(error, n == 230, 'table '//str(table)//' has '//str(n)//' moments, not 230')
    if (allocated(error)) return
    open (newunit=u, file='cloud_mie_slab.prp', status='replace', action='write')
    write (u, '(a)') 'Tabulated phase function property file'
    write (u, '(a)') '1 1 1'
    write (u, '(a)') '0.0550 0.0550 0.0 0.4'
    write (u, '(a)') '1'
    write (u, '(i5, *(1x, es22.14))') n, [((2*l + 1)*prp%chi(l, table), l=1, n)]
    write (u, '(a)') '1 1 1 280.0 19.0 0.976 1'     ! 19 km-1 over 0.4 km: tau = 7.6
    close (u)
  end subroutine write_mie_slab

end module test_cloud_input_suite

program test_cloud_input
  use test_cloud_input_suite, only: collect_cloud_input
  use kumo_test_text, only: run_shared_suite
  implicit none
  call run_shared_suite('test_cloud_input', 'data/i3rc/les_examples', &
                        'cloud files in whole runs', collect_cloud_input())
end program test_cloud_input
