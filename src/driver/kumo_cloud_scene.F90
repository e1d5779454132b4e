! SPDX-License-Identifier: BSD-3-Clause
!> Optics of the 3-D region from a cloud file (&kumo_cloud), and Rayleigh layers.
!>
!> `build_cloud_optics` reads the whole cloud file and returns voxel components for
!> `atmosphere_init`: extinction, single-scattering albedo and phase-function index per voxel,
!> with the phase functions they refer to.
!>
!> * Water content and effective radius: the Mie table of the namelist's size distribution at
!>   the run's wavelength (from the cache file when it matches). A voxel with radius r between
!>   table radii r1 < r2 is the mixture of the two tabulated populations that has effective
!>   radius r (`mie_table_bracket`); the two are two components of the voxel, so the photon
!>   chooses the population by its share of the scattering coefficient and then scatters with
!>   that population's phase function. This is exactly the blended phase function
!>   w P(r1) + (1 - w) P(r2) with w the scattering share (MCARaTS's fractional phase index),
!>   sampled without a blended table. Radii outside the table are clamped to its ends and
!>   counted in a warning.
!> * Extinction and effective radius (MYSTIC flag 2): as above, with the extinction split by
!>   the two populations' shares of it.
!> * Complete optics (SHDOM property files, MYSTIC flag 1): one component, with the file's
!>   phase functions (Legendre series or Henyey-Greenstein).
!> * Files on grid points: every plane is a component of the two layers it bounds, with half
!>   of its value in each.
!> * Ice water (LES files) uses an optics table in the Mie-table layout named by
!>   `ice_optics_file`; kumo has no ice-crystal optics of its own.
!> * MCARaTS 3-D atmospheres: `mcarats_optics` (one or two components per MCARaTS component,
!>   one for the gas-absorption perturbation).
module kumo_cloud_scene
  use kumo_kinds, only: wp, dp
  use kumo_error, only: error_t, set_error, str
  use kumo_phase, only: phase_t, phase_from_table, new_phase_hg, phase_from_legendre, &
                        new_phase_isotropic, new_phase_rayleigh
  use kumo_mie, only: mie_table_t, mie_table_build, mie_table_bracket, dist_kind_from_name
  use kumo_water_index, only: water_index
  use kumo_mie_table, only: mie_table_cached, read_mie_table
  use kumo_rayleigh, only: rayleigh_extinction
  use kumo_std_atmosphere, only: std_atmosphere_profile
  use kumo_cloud_input, only: cloud_input_t, read_cloud_input, CLOUD_WATER, CLOUD_EXT_REFF, &
                              CLOUD_OPTICS, CLOUD_MCARATS
  use kumo_mcarats_files, only: mcarats_request_t
  use kumo_config, only: cloud_cfg_t
  implicit none
  private
  public :: cloud_optics_t, build_cloud_optics, rayleigh_layers

  !> Standard gravity [m s-2] (CGPM 1901), for layer air densities from pressure differences.
  real(wp), parameter :: G0 = 9.80665_wp
  !> Step of the pressure profile handed to the Rayleigh integration [m].
  real(wp), parameter :: PROFILE_STEP = 100.0_wp

  !> Voxel components of the 3-D region and their phase functions.
  type :: cloud_optics_t
    real(wp), allocatable :: ext(:, :, :, :)   !! (nx, ny, nz, ncomp) extinction [m-1]
    real(wp), allocatable :: ssa(:, :, :, :)   !! (nx, ny, nz, ncomp) single-scattering albedo
    integer, allocatable :: iph(:, :, :, :)    !! (nx, ny, nz, ncomp) index into `phases`
    type(phase_t), allocatable :: phases(:)    !! the phase functions of the cloud
    character(len=:), allocatable :: notes     !! for the run log
    character(len=:), allocatable :: warnings  !! for the log and the output file
  end type cloud_optics_t

  character(len=1), parameter :: NL = new_line('a')

contains

  !> Read the cloud file of `ccfg` and compute the voxel optics at `wavelength_um`.
  !> `phase_offset` is added to every phase index (the phase functions of the namelist and of
  !> the molecules come first in the scene's list).
  subroutine build_cloud_optics(ccfg, wavelength_um, n_table, phase_offset, opt, error)
    type(cloud_cfg_t), intent(in) :: ccfg
    real(wp), intent(in) :: wavelength_um   !! [um]; 0 when not given (optics files only)
    integer, intent(in) :: n_table          !! inverse-CDF table size of tabulated phases
    integer, intent(in) :: phase_offset
    type(cloud_optics_t), intent(out) :: opt
    type(error_t), allocatable, intent(out) :: error
    type(cloud_input_t) :: c
    type(mie_table_t) :: liq, ice
    type(phase_t), allocatable :: more(:)
    integer :: nplanes, ncomp, nneg, i, n_out_liq, n_out_ice, ic
    character(len=:), allocatable :: action

    call read_cloud_input(ccfg%req, c, error)
    if (allocated(error)) return
    opt%notes = 'cloud file '//ccfg%req%path//' ('//trim(c%format)//'): '//c%notes//NL
    opt%warnings = ''
    if (len(c%missing) > 0) opt%notes = opt%notes//'the file does not give '//c%missing// &
                                        '; taken from the namelist'//NL
    nplanes = merge(2, 1, c%points)
    n_out_liq = 0
    n_out_ice = 0

    select case (c%content)
    case (CLOUD_WATER, CLOUD_EXT_REFF)
      call water_table(ccfg, wavelength_um, liq, action, error)
      if (allocated(error)) return
      opt%notes = opt%notes//'Mie table of water, '//trim(ccfg%size_distribution)// &
                  ' v_eff = '//str(ccfg%v_eff)//', '//str(size(liq%r_eff_um))//' radii '// &
                  str(liq%r_eff_um(1))//' ... '//str(liq%r_eff_um(size(liq%r_eff_um)))// &
                  ' um at '//str(wavelength_um)//' um: '//action//NL
      ncomp = 2*nplanes
      if (c%has_ice) then
        if (len_trim(ccfg%ice_optics_file) == 0) then
          call set_error(error, ccfg%req%path//': the file has ice water; kumo needs its '// &
                         'optics as a table (&kumo_cloud ice_optics_file) or les_iwc = ''none'' '// &
                         'to leave the ice out')
          return
        end if
        call read_mie_table(trim(ccfg%ice_optics_file), ice, error)
        if (allocated(error)) return
        if (abs(ice%wavelength_um - wavelength_um) > 1.0e-6_wp*wavelength_um) then
          call set_error(error, trim(ccfg%ice_optics_file)//': the ice optics table is for '// &
                         str(ice%wavelength_um)//' um, the run for '//str(wavelength_um)//' um')
          return
        end if
        opt%notes = opt%notes//'ice optics table '//trim(ccfg%ice_optics_file)//', '// &
                    str(size(ice%r_eff_um))//' radii'//NL
        ncomp = ncomp + 2
      end if
      allocate (opt%ext(c%nx, c%ny, c%nz, ncomp), opt%ssa(c%nx, c%ny, c%nz, ncomp), &
                opt%iph(c%nx, c%ny, c%nz, ncomp))
      call table_phases(liq, n_table, opt%phases, error)
      if (allocated(error)) return
      if (c%content == CLOUD_WATER) then
        call mie_voxels(c, c%lwc, c%reff, liq, phase_offset, .false., opt, 1, n_out_liq)
      else
        call mie_voxels(c, c%ext, c%reff, liq, phase_offset, .true., opt, 1, n_out_liq)
      end if
      if (c%has_ice) then
        call table_phases(ice, n_table, more, error)
        if (allocated(error)) return
        opt%phases = [opt%phases, more]
        call mie_voxels(c, c%iwc, c%reff_ice, ice, phase_offset + size(liq%r_eff_um), .false., &
                        opt, 2*nplanes + 1, n_out_ice)
      end if
    case (CLOUD_OPTICS)
      ncomp = nplanes
      allocate (opt%ext(c%nx, c%ny, c%nz, ncomp), opt%ssa(c%nx, c%ny, c%nz, ncomp), &
                opt%iph(c%nx, c%ny, c%nz, ncomp))
      if (allocated(c%chi)) then
        allocate (opt%phases(size(c%chi, 2)))
        do i = 1, size(c%chi, 2)
          opt%phases(i) = phase_from_legendre(c%chi(:, i), n_table, error, nneg)
          if (allocated(error)) then
            error%message = ccfg%req%path//': phase function '//str(i)//': '//error%message
            return
          end if
          if (nneg > 0) opt%notes = opt%notes//'phase function '//str(i)//': its Legendre '// &
                                    'series is negative at '//str(nneg)//' angles, set to 0'//NL
        end do
      else
        allocate (opt%phases(size(c%hg_g)))
        do i = 1, size(c%hg_g)
          opt%phases(i) = new_phase_hg(c%hg_g(i), error)
          if (allocated(error)) return
        end do
      end if
      do ic = 1, nplanes
        opt%ext(:, :, :, ic) = c%ext(:, :, ic:ic + c%nz - 1)/nplanes
        opt%ssa(:, :, :, ic) = c%ssa(:, :, ic:ic + c%nz - 1)
        opt%iph(:, :, :, ic) = c%iphase(:, :, ic:ic + c%nz - 1) + phase_offset
      end do
    case (CLOUD_MCARATS)
      call mcarats_optics(c, ccfg%req%mcarats, ccfg%req%path, n_table, phase_offset, opt, error)
      if (allocated(error)) return
    case default
      call set_error(error, ccfg%req%path//': unknown kind of cloud content '//str(c%content))
      return
    end select
    if (n_out_liq > 0) opt%warnings = opt%warnings//str(n_out_liq)//' cloud voxel values '// &
      'have an effective radius outside the Mie table ('//str(ccfg%reff_min_um)//' - '// &
      str(ccfg%reff_max_um)//' um) and were given the nearest table radius; '// &
      'widen reff_min_um/reff_max_um to avoid it. '
    if (n_out_ice > 0) opt%warnings = opt%warnings//str(n_out_ice)//' ice voxel values have '// &
      'an effective radius outside the ice optics table and were given the nearest table radius. '
  end subroutine build_cloud_optics

  !> The Mie table of water droplets, from the cache or computed.
  subroutine water_table(ccfg, wavelength_um, table, action, error)
    type(cloud_cfg_t), intent(in) :: ccfg
    real(wp), intent(in) :: wavelength_um
    type(mie_table_t), intent(out) :: table
    character(len=:), allocatable, intent(out) :: action
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: r(:)
    complex(wp) :: m
    integer :: dist, i, n
    n = ccfg%n_reff
    allocate (r(n))
    do i = 1, n
      r(i) = ccfg%reff_min_um*(ccfg%reff_max_um/ccfg%reff_min_um)**(real(i - 1, wp)/(n - 1))
    end do
    r(n) = ccfg%reff_max_um
    call dist_kind_from_name(ccfg%size_distribution, dist, error)
    if (allocated(error)) return
    if (len_trim(ccfg%mie_cache) > 0) then
      call mie_table_cached(trim(ccfg%mie_cache), wavelength_um, dist, ccfg%v_eff, r, table, &
                            action, error)
      if (.not. allocated(error) .and. action /= 'read') action = action//' (cache '// &
                                                                   trim(ccfg%mie_cache)//')'
    else
      call water_index(wavelength_um, m, error)
      if (allocated(error)) return
      call mie_table_build(wavelength_um, m, dist, ccfg%v_eff, r, table, error)
      action = 'computed (no mie_cache given)'
    end if
  end subroutine water_table

  !> Phase functions of every radius of a table.
  subroutine table_phases(table, n_table, phases, error)
    type(mie_table_t), intent(in) :: table
    integer, intent(in) :: n_table
    type(phase_t), allocatable, intent(out) :: phases(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    allocate (phases(size(table%r_eff_um)))
    do i = 1, size(table%r_eff_um)
      phases(i) = phase_from_table(table%angle_deg, table%phase(:, i), n_table, error)
      if (allocated(error)) then
        error%message = 'Mie table radius '//str(table%r_eff_um(i))//' um: '//error%message
        return
      end if
    end do
  end subroutine table_phases

  !> Two components per plane (the bracketing table radii) from water content or extinction
  !> and effective radius, into components first, first + 1 (and first + 2, + 3 for points).
  subroutine mie_voxels(c, amount, reff, table, offset, is_ext, opt, first, n_out)
    type(cloud_input_t), intent(in) :: c
    real(wp), intent(in) :: amount(:, :, :)  !! water content [g m-3] or extinction [m-1]
    real(wp), intent(in) :: reff(:, :, :)    !! effective radius [um]
    type(mie_table_t), intent(in) :: table
    integer, intent(in) :: offset, first
    logical, intent(in) :: is_ext            !! amount is the extinction
    type(cloud_optics_t), intent(inout) :: opt
    integer, intent(inout) :: n_out
    integer :: ix, iy, k, ip, np, i1, i2, ic, nr
    real(wp) :: a, r, f, w_phase, e1, e2, scale
    logical :: inside
    np = merge(2, 1, c%points)
    nr = size(table%r_eff_um)
    do ip = 1, np
      ic = first + 2*(ip - 1)
      do k = 1, c%nz
        do iy = 1, c%ny
          do ix = 1, c%nx
            a = amount(ix, iy, k + ip - 1)/np
            if (a <= 0.0_wp) then
              opt%ext(ix, iy, k, ic:ic + 1) = 0.0_wp
              opt%ssa(ix, iy, k, ic:ic + 1) = table%ssa(1)
              opt%iph(ix, iy, k, ic:ic + 1) = offset + 1
              cycle
            end if
            r = reff(ix, iy, k + ip - 1)
            if (r < table%r_eff_um(1) .or. r > table%r_eff_um(nr)) then
              n_out = n_out + 1
              r = min(max(r, table%r_eff_um(1)), table%r_eff_um(nr))
            end if
            ! (w_phase, the phase-function weight, is implied by the two components' shares)
            call mie_table_bracket(table%r_eff_um, table%ext_per_lwc, table%ssa, r, i1, i2, f, &
                                   w_phase, inside)
            e1 = f*table%ext_per_lwc(i1)
            e2 = (1.0_wp - f)*table%ext_per_lwc(i2)
            if (is_ext) then
              scale = a/(e1 + e2)      ! the file's extinction, split by the populations' shares
            else
              scale = a                ! extinction = water content x extinction per water
            end if
            opt%ext(ix, iy, k, ic) = e1*scale
            opt%ext(ix, iy, k, ic + 1) = e2*scale
            opt%ssa(ix, iy, k, ic) = table%ssa(i1)
            opt%ssa(ix, iy, k, ic + 1) = table%ssa(i2)
            opt%iph(ix, iy, k, ic) = offset + i1
            opt%iph(ix, iy, k, ic + 1) = offset + i2
          end do
        end do
      end do
    end do
  end subroutine mie_voxels

  !> Voxel components of an MCARaTS 3-D atmosphere (Iwabuchi, MCARaTS 0.10 `mcarAtm`,
  !> `mcarSca`). Each MCARaTS component keeps its extinction and albedo; its phase-function code
  !> apf gives the kumo phase function: (-3, -2] isotropic, (-2, -1] Rayleigh (no
  !> depolarisation), (-1, 1) Henyey-Greenstein with g = apf (one phase function per distinct
  !> g), >= 1 table ipf = int(apf) of the phase-function file blended with table ipf + 1 as
  !> P = (1 - r) P_ipf + r P_ipf+1, r = apf - ipf. A component with blends becomes two kumo
  !> components with extinction (1 - r) ext and r ext, the same albedo and the two tables: the
  !> photon chooses a component by its share of the scattering coefficient, (1 - r) : r, so it
  !> scatters with exactly the blended phase function (as `mie_voxels` does for radius blends).
  !> The gas-absorption perturbation of k-term `m%ikd` is one more component with albedo 0
  !> when it is not zero everywhere. MCARaTS adds it to the 1-D gas absorption (Atm_abs1d),
  !> which kumo takes from the 1-D components of the region's layers, added to every voxel
  !> (`m%abs1d`): so the perturbation may be negative where the voxel's absorption
  !> coefficient stays >= 0; a voxel where it would not is an error.
  subroutine mcarats_optics(c, m, path, n_table, offset, opt, error)
    type(cloud_input_t), intent(in) :: c           !! the file read (content CLOUD_MCARATS)
    type(mcarats_request_t), intent(in) :: m       !! the namelist's request (k-term, abs1d)
    character(len=*), intent(in) :: path           !! the atmosphere file, for messages
    integer, intent(in) :: n_table                 !! inverse-CDF table size of the tables
    integer, intent(in) :: offset                  !! added to every phase index
    type(cloud_optics_t), intent(inout) :: opt
    type(error_t), allocatable, intent(out) :: error
    integer :: nx, ny, nz, np, npf, nph, i_iso, i_ray, i_hg, ip, ic, k, ix, iy, ipf, j, j2, ncomp
    integer :: n_iso, n_ray, n_hg, n_tab, n_blend
    integer, allocatable :: slot(:), first(:)
    logical, allocatable :: used(:), blended(:)
    logical :: has_abs
    real(wp) :: apf, r, e, tot, a1d, amin, amax

    associate (a => c%mca_atm, pf => c%mca_phase)
      nx = a%nx
      ny = a%ny
      nz = a%nz3
      np = a%np3d
      npf = pf%npf
      ! tables referenced by some voxel, and components with fractional codes
      allocate (used(npf), blended(np), first(np), slot(npf))
      used = .false.
      blended = .false.
      do ip = 1, np
        do k = 1, nz
          do iy = 1, ny
            do ix = 1, nx
              apf = a%apf(ix, iy, k, ip)
              if (apf < 1.0_wp) cycle
              ipf = int(apf)
              used(ipf) = .true.
              if (apf > ipf) then   ! then ipf < npf: the reader keeps apf <= npf
                used(ipf + 1) = .true.
                blended(ip) = .true.
              end if
            end do
          end do
        end do
      end do

      ! the phase functions: isotropic, Rayleigh, the distinct HG g, the tables used
      nph = 0
      i_iso = 0
      i_ray = 0
      if (any(a%apf <= -2.0_wp)) then
        nph = nph + 1
        i_iso = nph
      end if
      if (any(a%apf > -2.0_wp .and. a%apf <= -1.0_wp)) then
        nph = nph + 1
        i_ray = nph
      end if
      i_hg = nph
      nph = nph + size(c%hg_g)
      slot = 0
      do ipf = 1, npf
        if (.not. used(ipf)) cycle
        nph = nph + 1
        slot(ipf) = nph
      end do
      allocate (opt%phases(max(nph, 1)))
      opt%phases(1) = new_phase_isotropic()    ! (the absorption component's, if nothing else)
      if (i_iso > 0) opt%phases(i_iso) = new_phase_isotropic()
      if (i_ray > 0) opt%phases(i_ray) = new_phase_rayleigh()
      do j = 1, size(c%hg_g)
        opt%phases(i_hg + j) = new_phase_hg(c%hg_g(j), error)
        if (allocated(error)) then
          error%message = path//': apf = '//str(c%hg_g(j))//': '//error%message
          return
        end if
      end do
      do ipf = 1, npf
        if (slot(ipf) == 0) cycle
        opt%phases(slot(ipf)) = phase_from_table(pf%angle_deg, pf%p(:, ipf), n_table, error)
        if (allocated(error)) then
          error%message = 'phase function '//str(ipf)//' of the MCARaTS '// &
                          'phase-function file: '//error%message
          return
        end if
      end do

      ! components: one per MCARaTS component, two where it has blends, one for absorption
      has_abs = any(a%absg(:, :, :, m%ikd) /= 0.0_wp)
      ncomp = 0
      do ip = 1, np
        first(ip) = ncomp + 1
        ncomp = ncomp + merge(2, 1, blended(ip))
      end do
      if (has_abs) ncomp = ncomp + 1
      allocate (opt%ext(nx, ny, nz, ncomp), opt%ssa(nx, ny, nz, ncomp), opt%iph(nx, ny, nz, ncomp))
      n_iso = 0
      n_ray = 0
      n_hg = 0
      n_tab = 0
      n_blend = 0
      do ip = 1, np
        ic = first(ip)
        do k = 1, nz
          do iy = 1, ny
            do ix = 1, nx
              apf = a%apf(ix, iy, k, ip)
              e = a%ext(ix, iy, k, ip)
              r = 0.0_wp
              if (apf <= -2.0_wp) then
                j = i_iso
                if (e > 0.0_wp) n_iso = n_iso + 1
              else if (apf <= -1.0_wp) then
                j = i_ray
                if (e > 0.0_wp) n_ray = n_ray + 1
              else if (apf < 1.0_wp) then
                j = i_hg + hg_slot(c%hg_g, apf)
                if (e > 0.0_wp) n_hg = n_hg + 1
              else
                ipf = int(apf)
                r = apf - ipf
                j = slot(ipf)
                if (e > 0.0_wp) n_tab = n_tab + 1
                if (r > 0.0_wp .and. e > 0.0_wp) n_blend = n_blend + 1
              end if
              j2 = j
              if (r > 0.0_wp) j2 = slot(ipf + 1)
              opt%ext(ix, iy, k, ic) = (1.0_wp - r)*e
              opt%ssa(ix, iy, k, ic) = a%omg(ix, iy, k, ip)
              opt%iph(ix, iy, k, ic) = offset + j
              if (blended(ip)) then
                opt%ext(ix, iy, k, ic + 1) = r*e
                opt%ssa(ix, iy, k, ic + 1) = a%omg(ix, iy, k, ip)
                opt%iph(ix, iy, k, ic + 1) = offset + j2
              end if
            end do
          end do
        end do
      end do
      opt%notes = opt%notes//'apf codes of the voxel values with extinction > 0: '// &
                  str(n_iso)//' isotropic, '//str(n_ray)//' Rayleigh, '//str(n_hg)// &
                  ' Henyey-Greenstein ('//str(size(c%hg_g))//' distinct g), '//str(n_tab)// &
                  ' tabulated ('//str(n_blend)//' blending two tables); kumo uses '// &
                  str(count(used))//' of the '//str(npf)//' tables'//NL
      if (any(blended)) then
        opt%notes = opt%notes//'a component with blended codes is two kumo components, '// &
                    'extinction (1 - r) ext and r ext with tables int(apf) and int(apf) + 1'//NL
      end if

      if (.not. has_abs) then
        opt%notes = opt%notes//'gas absorption perturbation (absg3d) of k-term '//str(m%ikd)// &
                    ': 0 everywhere'//NL
        return
      end if
      opt%ext(:, :, :, ncomp) = a%absg(:, :, :, m%ikd)
      opt%ssa(:, :, :, ncomp) = 0.0_wp
      opt%iph(:, :, :, ncomp) = offset + 1
      amin = huge(1.0_wp)
      do k = 1, nz
        a1d = 0.0_wp
        if (allocated(m%abs1d)) a1d = m%abs1d(k)
        do iy = 1, ny
          do ix = 1, nx
            tot = a1d + a%absg(ix, iy, k, m%ikd) + &
                  sum(a%ext(ix, iy, k, :)*(1.0_wp - a%omg(ix, iy, k, :)))
            amin = min(amin, tot)
            if (tot >= 0.0_wp) cycle
            call set_error(error, path//': absg3d k-term '//str(m%ikd)//' layer '//str(k)// &
                           ' (kumo layer '//str(m%k3d_bottom + k - 1)//'), ix = '//str(ix)// &
                           ', iy = '//str(iy)//': the perturbation '// &
                           str(a%absg(ix, iy, k, m%ikd))//' m-1 makes the absorption '// &
                           'coefficient of the voxel '//str(tot)//' m-1 < 0 (1-D absorption '// &
                           str(a1d)//' m-1). MCARaTS adds absg3d to Atm_abs1d; kumo takes '// &
                           'that from the absorbing 1-D components of &kumo_atmosphere '// &
                           '(ext1d with ssa1d < 1) in the 3-D layers: give it there')
            return
          end do
        end do
      end do
      amax = maxval(a%absg(:, :, :, m%ikd))
      opt%notes = opt%notes//'gas absorption perturbation (absg3d) of k-term '//str(m%ikd)// &
                  ': '//str(minval(a%absg(:, :, :, m%ikd)))//' ... '//str(amax)// &
                  ' m-1, one more component (albedo 0) added to the 1-D absorption of the '// &
                  'layers; smallest absorption coefficient of a voxel '//str(amin)//' m-1'//NL
    end associate
  end subroutine mcarats_optics

  !> Position of g in the sorted, distinct list gs (g must be in it).
  pure integer function hg_slot(gs, g) result(i)
    real(wp), intent(in) :: gs(:), g
    integer :: lo, hi
    lo = 1
    hi = size(gs)
    do while (lo < hi)
      i = (lo + hi)/2
      if (gs(i) < g) then
        lo = i + 1
      else
        hi = i
      end if
    end do
    i = lo
  end function hg_slot

  !> Rayleigh extinction of dry air in every layer [m-1] and the layers' air density
  !> [kg m-3] (mass per area Δp/g over the thickness) from a named standard atmosphere.
  subroutine rayleigh_layers(z, wavelength_um, profile, co2_ppm, latitude_deg, ext, rho, error)
    real(wp), intent(in) :: z(0:)            !! levels [m]
    real(wp), intent(in) :: wavelength_um, co2_ppm, latitude_deg
    character(len=*), intent(in) :: profile
    real(wp), allocatable, intent(out) :: ext(:), rho(:)
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: zp(:), p(:), t(:), r(:), pl(:), tl(:), rl(:)
    integer :: nz, k, j, nsub, n
    nz = size(z) - 1
    ! profile: every level and steps of at most PROFILE_STEP between them
    allocate (zp(0))
    do k = 1, nz
      nsub = max(1, ceiling((z(k) - z(k - 1))/PROFILE_STEP))
      zp = [zp, (z(k - 1) + (z(k) - z(k - 1))*j/real(nsub, wp), j=0, nsub - 1)]
    end do
    zp = [zp, z(nz)]
    n = size(zp)
    allocate (p(n), t(n), r(n))
    call std_atmosphere_profile(profile, zp, p, t, r, error)
    if (allocated(error)) return
    call rayleigh_extinction(wavelength_um, z, zp, p, latitude_deg, co2_ppm, ext, error)
    if (allocated(error)) return
    allocate (pl(0:nz), tl(0:nz), rl(0:nz))
    call std_atmosphere_profile(profile, z, pl, tl, rl, error)
    if (allocated(error)) return
    rho = (pl(0:nz - 1) - pl(1:nz))/(G0*(z(1:nz) - z(0:nz - 1)))
  end subroutine rayleigh_layers

end module kumo_cloud_scene
