! SPDX-License-Identifier: BSD-3-Clause
!> Optics of the 3-D region from a cloud file (&kumo_cloud), and Rayleigh layers.
!>
!> `build_cloud_atmosphere` reads the cloud file and builds the atmosphere with it: the cloud's
!> phase functions join the scene's list, and its voxel optics are put into the atmosphere one
!> species and one layer at a time, so that no copy of the whole field exists besides the
!> atmosphere's own arrays and the one species being read.
!>
!> * Water content and effective radius: the Mie table of the namelist's size distribution at
!>   the run's wavelength (from the cache file when it matches). A voxel with radius r between
!>   table radii r1 < r2 is the mixture of the two tabulated populations that has effective
!>   radius r (`mie_table_bracket`): its extinction and albedo are the mixture's, and its phase
!>   function the blend (1 - w) P(r1) + w P(r2) with w the share of r2 in the scattering
!>   (MCARaTS's fractional phase index), sampled exactly by taking table r2 with probability w.
!>   Radii outside the table are clamped to its ends and counted in a warning.
!> * Extinction and effective radius (MYSTIC flag 2): as above, with the file's extinction.
!> * Complete optics (SHDOM property files, MYSTIC flag 1): the file's phase functions
!>   (Legendre series or Henyey-Greenstein).
!> * Files on grid points: every plane is a component of the two layers it bounds, with half
!>   of its value in each.
!> * Ice water (LES files) uses an optics table in the Mie-table layout named by
!>   `ice_optics_file`; kumo has no ice-crystal optics of its own. It is read after the liquid
!>   water has been put into the atmosphere.
module kumo_cloud_scene
  use kumo_kinds, only: wp, vp
  use kumo_error, only: error_t, set_error, str
  use kumo_phase, only: phase_t, phase_from_table, new_phase_hg, phase_from_legendre
  use kumo_mie, only: mie_table_t, mie_table_build, mie_table_bracket, dist_kind_from_name
  use kumo_water_index, only: water_index
  use kumo_mie_table, only: mie_table_cached, read_mie_table
  use kumo_rayleigh, only: rayleigh_extinction
  use kumo_std_atmosphere, only: std_atmosphere_profile
  use kumo_cloud_input, only: cloud_input_t, read_cloud_input, CLOUD_WATER, CLOUD_EXT_REFF, &
                              CLOUD_OPTICS
  use kumo_atmosphere, only: atmosphere_t, atmosphere_options_t, atmosphere_begin, &
                             atmosphere_put_layer, atmosphere_end
  use kumo_config, only: cloud_cfg_t
  implicit none
  private
  public :: build_cloud_atmosphere, rayleigh_layers

  !> Standard gravity [m s-2] (CGPM 1901), for layer air densities from pressure differences.
  real(wp), parameter :: G0 = 9.80665_wp
  !> Step of the pressure profile handed to the Rayleigh integration [m].
  real(wp), parameter :: PROFILE_STEP = 100.0_wp

  character(len=1), parameter :: NL = new_line('a')

contains

  !> Read the cloud file of `ccfg`, compute its voxel optics at `wavelength_um` and build the
  !> atmosphere: levels `z`, domain lx x ly, the 1-D components `ext1d`, `ssa1d`, `iph1d`
  !> (nz, ncomp1) and the cloud in the 3-D region from layer `k3_lo`. `phases` (the namelist's
  !> and the molecules') gets the cloud's appended and moves into the atmosphere.
  subroutine build_cloud_atmosphere(ccfg, wavelength_um, n_table, z, lx, ly, k3_lo, ext1d, &
                                    ssa1d, iph1d, phases, aopts, atm, notes, warnings, error)
    type(cloud_cfg_t), intent(in) :: ccfg
    real(wp), intent(in) :: wavelength_um   !! [um]; 0 when not given (optics files only)
    integer, intent(in) :: n_table          !! inverse-CDF table size of tabulated phases
    real(wp), intent(in) :: z(0:), lx, ly
    integer, intent(in) :: k3_lo
    real(wp), intent(in) :: ext1d(:, :), ssa1d(:, :)
    integer, intent(in) :: iph1d(:, :)
    type(phase_t), allocatable, intent(inout) :: phases(:)
    type(atmosphere_options_t), intent(in) :: aopts
    type(atmosphere_t), intent(out) :: atm
    character(len=:), allocatable, intent(out) :: notes, warnings
    type(error_t), allocatable, intent(out) :: error
    type(cloud_input_t) :: c
    type(mie_table_t) :: liq, ice
    type(phase_t), allocatable :: more(:)
    integer :: nplanes, nspecies, nneg, i, n_out_liq, n_out_ice, offset, offset_ice
    character(len=:), allocatable :: action

    call read_cloud_input(ccfg%req, c, error, part='liquid')
    if (allocated(error)) return
    notes = 'cloud file '//ccfg%req%path//' ('//trim(c%format)//'): '//c%notes//NL
    warnings = ''
    if (len(c%missing) > 0) notes = notes//'the file does not give '//c%missing// &
                                    '; taken from the namelist'//NL
    nplanes = merge(2, 1, c%points)
    n_out_liq = 0
    n_out_ice = 0
    offset = size(phases)

    select case (c%content)
    case (CLOUD_WATER, CLOUD_EXT_REFF)
      call water_table(ccfg, wavelength_um, liq, action, error)
      if (allocated(error)) return
      notes = notes//'Mie table of water, '//trim(ccfg%size_distribution)//' v_eff = '// &
              str(ccfg%v_eff)//', '//str(size(liq%r_eff_um))//' radii '// &
              str(liq%r_eff_um(1))//' ... '//str(liq%r_eff_um(size(liq%r_eff_um)))// &
              ' um at '//str(wavelength_um)//' um: '//action//NL
      call table_phases(liq, n_table, more, error)
      if (allocated(error)) return
      phases = [phases, more]
      nspecies = 1
      offset_ice = size(phases)
      if (c%has_ice) then
        call ice_table(ccfg, wavelength_um, ice, error)
        if (allocated(error)) return
        notes = notes//'ice optics table '//trim(ccfg%ice_optics_file)//', '// &
                str(size(ice%r_eff_um))//' radii'//NL
        call table_phases(ice, n_table, more, error)
        if (allocated(error)) return
        phases = [phases, more]
        nspecies = 2
      end if
      call atmosphere_begin(atm, z, lx, ly, ext1d, ssa1d, iph1d, phases, aopts, error, k3_lo, &
                            c%nx, c%ny, c%nz, nspecies*nplanes, blend=.true.)
      if (allocated(error)) return
      if (c%content == CLOUD_WATER) then
        call mie_voxels(c, c%lwc, c%reff, liq, offset, .false., atm, 0, n_out_liq)
        deallocate (c%lwc)
      else
        call mie_voxels(c, c%ext, c%reff, liq, offset, .true., atm, 0, n_out_liq)
        deallocate (c%ext)
      end if
      deallocate (c%reff)
      if (nspecies == 2) then
        call read_cloud_input(ccfg%req, c, error, part='ice')
        if (allocated(error)) return
        call mie_voxels(c, c%iwc, c%reff_ice, ice, offset_ice, .false., atm, nplanes, n_out_ice)
      end if
    case (CLOUD_OPTICS)
      if (allocated(c%chi)) then
        allocate (more(size(c%chi, 2)))
        do i = 1, size(c%chi, 2)
          more(i) = phase_from_legendre(c%chi(:, i), n_table, error, nneg)
          if (allocated(error)) then
            error%message = ccfg%req%path//': phase function '//str(i)//': '//error%message
            return
          end if
          if (nneg > 0) notes = notes//'phase function '//str(i)//': its Legendre '// &
                                'series is negative at '//str(nneg)//' angles, set to 0'//NL
        end do
      else
        allocate (more(size(c%hg_g)))
        do i = 1, size(c%hg_g)
          more(i) = new_phase_hg(c%hg_g(i), error)
          if (allocated(error)) return
        end do
      end if
      phases = [phases, more]
      call atmosphere_begin(atm, z, lx, ly, ext1d, ssa1d, iph1d, phases, aopts, error, k3_lo, &
                            c%nx, c%ny, c%nz, nplanes)
      if (allocated(error)) return
      call optics_voxels(c, offset, atm)
    case default
      call set_error(error, ccfg%req%path//': unknown kind of cloud content '//str(c%content))
      return
    end select
    call atmosphere_end(atm, aopts, error)
    if (allocated(error)) return
    if (n_out_liq > 0) warnings = warnings//str(n_out_liq)//' cloud voxel values have an '// &
      'effective radius outside the Mie table ('//str(ccfg%reff_min_um)//' - '// &
      str(ccfg%reff_max_um)//' um) and were given the nearest table radius; '// &
      'widen reff_min_um/reff_max_um to avoid it. '
    if (n_out_ice > 0) warnings = warnings//str(n_out_ice)//' ice voxel values have an '// &
      'effective radius outside the ice optics table and were given the nearest table radius. '
  end subroutine build_cloud_atmosphere

  !> The ice optics table named by the namelist, checked against the run's wavelength.
  subroutine ice_table(ccfg, wavelength_um, table, error)
    type(cloud_cfg_t), intent(in) :: ccfg
    real(wp), intent(in) :: wavelength_um
    type(mie_table_t), intent(out) :: table
    type(error_t), allocatable, intent(out) :: error
    if (len_trim(ccfg%ice_optics_file) == 0) then
      call set_error(error, ccfg%req%path//': the file has ice water; kumo needs its '// &
                     'optics as a table (&kumo_cloud ice_optics_file) or les_iwc = ''none'' '// &
                     'to leave the ice out')
      return
    end if
    call read_mie_table(trim(ccfg%ice_optics_file), table, error)
    if (allocated(error)) return
    if (abs(table%wavelength_um - wavelength_um) > 1.0e-6_wp*wavelength_um) then
      call set_error(error, trim(ccfg%ice_optics_file)//': the ice optics table is for '// &
                     str(table%wavelength_um)//' um, the run for '//str(wavelength_um)//' um')
    end if
  end subroutine ice_table

  !> Complete optics into components 1 (and 2 for points): extinction, albedo, phase index.
  subroutine optics_voxels(c, offset, atm)
    type(cloud_input_t), intent(in) :: c
    integer, intent(in) :: offset
    type(atmosphere_t), intent(inout) :: atm
    integer :: ip, np, k
    np = merge(2, 1, c%points)
    do ip = 1, np
      do k = 1, c%nz
        call atmosphere_put_layer(atm, ip, k, real(c%ext(:, :, k + ip - 1), wp)/np, &
                                  real(c%ssa(:, :, k + ip - 1), wp), &
                                  c%iphase(:, :, k + ip - 1) + offset)
      end do
    end do
  end subroutine optics_voxels

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

  !> One component per plane from water content or extinction and effective radius: the
  !> mixture of the two bracketing table populations, with its phase-function blend; into
  !> components first + 1 (and first + 2 for points).
  subroutine mie_voxels(c, amount, reff, table, offset, is_ext, atm, first, n_out)
    type(cloud_input_t), intent(in) :: c
    real(vp), intent(in) :: amount(:, :, :)  !! water content [g m-3] or extinction [m-1]
    real(vp), intent(in) :: reff(:, :, :)    !! effective radius [um]
    type(mie_table_t), intent(in) :: table
    integer, intent(in) :: offset, first
    logical, intent(in) :: is_ext            !! amount is the extinction
    type(atmosphere_t), intent(inout) :: atm
    integer, intent(inout) :: n_out
    integer :: ix, iy, k, ip, np, i1, i2, nr
    real(wp) :: a, r, f, w_phase, e1, e2, scale
    real(wp), allocatable :: ext(:, :), ssa(:, :), wph(:, :)
    integer, allocatable :: iph(:, :)
    logical :: inside
    np = merge(2, 1, c%points)
    nr = size(table%r_eff_um)
    allocate (ext(c%nx, c%ny), ssa(c%nx, c%ny), wph(c%nx, c%ny), iph(c%nx, c%ny))
    do ip = 1, np
      do k = 1, c%nz
        do iy = 1, c%ny
          do ix = 1, c%nx
            a = amount(ix, iy, k + ip - 1)/np
            if (a <= 0.0_wp) then
              ext(ix, iy) = 0.0_wp
              ssa(ix, iy) = table%ssa(1)
              iph(ix, iy) = offset + 1
              wph(ix, iy) = 0.0_wp
              cycle
            end if
            r = reff(ix, iy, k + ip - 1)
            if (r < table%r_eff_um(1) .or. r > table%r_eff_um(nr)) then
              n_out = n_out + 1
              r = min(max(r, table%r_eff_um(1)), table%r_eff_um(nr))
            end if
            ! i2 = i1 + 1, or i1 for a table of one radius
            call mie_table_bracket(table%r_eff_um, table%ext_per_lwc, table%ssa, r, i1, i2, f, &
                                   w_phase, inside)
            e1 = f*table%ext_per_lwc(i1)
            e2 = (1.0_wp - f)*table%ext_per_lwc(i2)
            if (is_ext) then
              scale = a/(e1 + e2)      ! the file's extinction
            else
              scale = a                ! extinction = water content x extinction per water
            end if
            ext(ix, iy) = (e1 + e2)*scale
            ssa(ix, iy) = (e1*table%ssa(i1) + e2*table%ssa(i2))/(e1 + e2)
            iph(ix, iy) = offset + i1
            wph(ix, iy) = merge(1.0_wp - w_phase, 0.0_wp, i2 > i1)
          end do
        end do
        call atmosphere_put_layer(atm, first + ip, k, ext, ssa, iph, wph)
      end do
    end do
  end subroutine mie_voxels

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
