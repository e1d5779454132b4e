! SPDX-License-Identifier: BSD-3-Clause
!> Optics of the 3-D region from a cloud file (&kumo_cloud), and Rayleigh layers.
!>
!> `build_cloud_atmosphere` builds the atmosphere from the fields of a cloud file, read by the
!> caller (kumo_cloud_share's `read_cloud_on_root`: on rank 0, shared with every rank): the
!> cloud's phase functions join the scene's list, and its voxel optics are put into the
!> atmosphere one species and one layer at a time, each species' fields freed once put in.
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
!>   `ice_optics_file`; kumo has no ice-crystal optics of its own. It is put into the
!>   atmosphere after the liquid water, whose fields are freed first.
!> * MCARaTS 3-D atmospheres: one component per MCARaTS component with its phase-function
!>   code turned into a kumo phase function (fractional table codes as blends), and one for the
!>   gas-absorption perturbation (`mcarats_phases`, `mcarats_voxels`).
!> * Thermal runs (`temp` present): the file's temperatures, on the voxels of the region as the
!>   optics are (`cloud_temperature_t`): LES temperature (or potential temperature and
!>   pressure), the profile of an LWC file, the temperatures of a property file, MCARaTS tmpa3d.
module kumo_cloud_scene
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp, vp
  use kumo_error, only: error_t, set_error, str
  use kumo_phase, only: phase_t, phase_from_table, new_phase_hg, phase_from_legendre, &
                        new_phase_isotropic, new_phase_rayleigh
  use kumo_mie, only: mie_table_t, mie_table_build, mie_table_bracket, dist_kind_from_name
  use kumo_water_index, only: water_index
  use kumo_mie_table, only: mie_table_cached, read_mie_table
  use kumo_rayleigh, only: rayleigh_extinction
  use kumo_std_atmosphere, only: std_atmosphere_profile
  use kumo_cloud_input, only: cloud_input_t, locate, CLOUD_WATER, CLOUD_EXT_REFF, CLOUD_OPTICS, &
                              CLOUD_MCARATS
  use kumo_mcarats_files, only: mcarats_request_t
  use kumo_atmosphere, only: voxel_storage_i, voxel_sync_i
  use kumo_atmosphere, only: atmosphere_t, atmosphere_options_t, atmosphere_begin, &
                             atmosphere_put_layer, atmosphere_end
  use kumo_config, only: cloud_cfg_t
  implicit none
  private
  public :: build_cloud_atmosphere, rayleigh_layers, cloud_temperature_t, mie_layer, mie_voxel, &
            table_radii, ice_table, water_table, mcarats_scan_t, mcarats_scan, take_temperature

  !> What the voxel values of an MCARaTS file decide before its atmosphere is built
  !> (mcarats_scan): the tables some voxel uses, whether a code blends two tables, whether the
  !> gas-absorption perturbation is a component, and the run-log lines about it. On several
  !> ranks the process holding the fields makes it for the ranks that have none.
  type :: mcarats_scan_t
    logical, allocatable :: used(:)       !! (npf) table ipf is used by some voxel
    logical :: blend = .false.            !! some code has a fraction
    logical :: has_abs = .false.          !! the absorption perturbation is not zero everywhere
    character(len=:), allocatable :: abs_notes
  end type mcarats_scan_t

  !> Temperatures of a cloud file for thermal emission, on the columns and layers of the 3-D
  !> region the file defines (voxel (ix, iy, k) is layer k3_lo + k - 1 of the atmosphere).
  type :: cloud_temperature_t
    logical :: found = .false.                !! the file has temperatures
    !> (nx, ny, nt) or a profile (1, 1, nt) [K]; nt = nz: one per voxel; nt = nz + 1
    !> (`planes`): on the planes or levels that bound the layers, voxel k between k and k + 1
    real(vp), allocatable :: t(:, :, :)
    logical :: planes = .false.
    !> MCARaTS tmpa3d: perturbations to be added to the level temperatures (t_levels)
    logical :: perturbation = .false.
    character(len=:), allocatable :: source   !! file and variable, for the run log
  end type cloud_temperature_t

  !> Standard gravity [m s-2] (CGPM 1901), for layer air densities from pressure differences.
  real(wp), parameter :: G0 = 9.80665_wp
  !> Step of the pressure profile handed to the Rayleigh integration [m].
  real(wp), parameter :: PROFILE_STEP = 100.0_wp

  character(len=1), parameter :: NL = new_line('a')

contains

  !> From the fields `c` (and `c_ice`) of the cloud file of `ccfg`, compute its voxel optics at
  !> `wavelength_um` and build the atmosphere: levels `z`, domain lx x ly, the 1-D components
  !> `ext1d`, `ssa1d`, `iph1d` (nz, ncomp1) and the cloud in the 3-D region from layer `k3_lo`.
  !> `phases` (the namelist's and the molecules') gets the cloud's appended and moves into the
  !> atmosphere. With `storage` and `sync` the voxels go into the caller's storage
  !> (atmosphere_begin): the process that is its writer puts the fields, the others hold only
  !> the grid of the file and what its phase functions are made of (read_cloud_on_root
  !> per_node), with an MCARaTS file also the writer's `mca`, and take the values the writer
  !> formed.
  subroutine build_cloud_atmosphere(ccfg, c, c_ice, wavelength_um, n_table, z, lx, ly, k3_lo, &
                                    ext1d, ssa1d, iph1d, phases, aopts, atm, notes, warnings, &
                                    error, temp, ice_tab, liq_tab, liq_action, storage, sync, &
                                    mca)
    type(cloud_cfg_t), intent(in) :: ccfg
    !> the file read with part = 'liquid' (with its temperatures when `temp` is wanted); its
    !> fields are freed as they are put into the atmosphere
    type(cloud_input_t), intent(inout) :: c
    !> the file read with part = 'ice' when c%has_ice (else not used)
    type(cloud_input_t), intent(inout) :: c_ice
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
    !> thermal runs: the file's temperatures (`found` false when it has none)
    type(cloud_temperature_t), intent(out), optional :: temp
    !> the ice optics table (ice_table) when the caller has read it; else it is read here
    type(mie_table_t), intent(in), optional :: ice_tab
    !> the water Mie table (water_table) and how it was obtained, when the caller has it; else
    !> it is made here (both or neither)
    type(mie_table_t), intent(in), optional :: liq_tab
    character(len=*), intent(in), optional :: liq_action
    procedure(voxel_storage_i), optional :: storage   !! the caller's storage for the voxels
    procedure(voxel_sync_i), optional :: sync         !! with `storage`
    !> MCARaTS files: mcarats_scan of the file's values when the caller made it (a process
    !> without the fields must give it); else it is made here
    type(mcarats_scan_t), intent(in), optional :: mca
    type(mcarats_scan_t) :: scan
    type(mie_table_t) :: liq, ice
    type(phase_t), allocatable :: more(:)
    integer :: nplanes, nspecies, nneg, i, n_out_liq, n_out_ice, offset, offset_ice
    integer, allocatable :: slot(:)
    logical :: blend, has_abs
    character(len=:), allocatable :: action

    if (present(temp)) then
      call take_temperature(c, ccfg%req%path, temp, error)
      if (allocated(error)) return
    end if
    notes = 'cloud file '//ccfg%req%path//' ('//trim(c%format)//'): '//c%notes//NL
    warnings = ''
    if (allocated(c%warnings)) warnings = c%warnings
    if (c%has_ice) then
      if (allocated(c_ice%warnings)) warnings = warnings//c_ice%warnings
    end if
    if (allocated(c%missing)) then
      if (len(c%missing) > 0) notes = notes//'the file does not give '//c%missing// &
                                    '; taken from the namelist'//NL
    end if
    nplanes = merge(2, 1, c%points)
    n_out_liq = 0
    n_out_ice = 0
    offset = size(phases)

    select case (c%content)
    case (CLOUD_WATER, CLOUD_EXT_REFF)
      if (present(liq_tab) .and. present(liq_action)) then
        liq = liq_tab
        action = liq_action
      else
        call water_table(ccfg, wavelength_um, liq, action, error)
        if (allocated(error)) return
      end if
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
        if (present(ice_tab)) then
          ice = ice_tab
        else
          call ice_table(ccfg, wavelength_um, ice, error)
          if (allocated(error)) return
        end if
        notes = notes//'ice optics table '//trim(ccfg%ice_optics_file)//', '// &
                str(size(ice%r_eff_um))//' radii'//NL
        call table_phases(ice, n_table, more, error)
        if (allocated(error)) return
        phases = [phases, more]
        nspecies = 2
      end if
      call atmosphere_begin(atm, z, lx, ly, ext1d, ssa1d, iph1d, phases, aopts, error, k3_lo, &
                            c%nx, c%ny, c%nz, nspecies*nplanes, blend=.true., storage=storage)
      if (allocated(error)) return
      if (.not. atm%voxel_writer) then
        ! the writer puts the fields; this process has none
      else if (c%content == CLOUD_WATER) then
        call mie_voxels(c, c%lwc, c%reff, liq, offset, .false., atm, 0, n_out_liq)
        deallocate (c%lwc)
      else
        call mie_voxels(c, c%ext, c%reff, liq, offset, .true., atm, 0, n_out_liq)
        deallocate (c%ext)
      end if
      if (atm%voxel_writer) deallocate (c%reff)
      if (nspecies == 2 .and. atm%voxel_writer) then
        call mie_voxels(c_ice, c_ice%iwc, c_ice%reff_ice, ice, offset_ice, .false., atm, nplanes, &
                        n_out_ice)
        deallocate (c_ice%iwc, c_ice%reff_ice)
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
                            c%nx, c%ny, c%nz, nplanes, storage=storage)
      if (allocated(error)) return
      if (atm%voxel_writer) call optics_voxels(c, offset, atm)
    case (CLOUD_MCARATS)
      if (present(mca)) then
        scan = mca
      else
        call mcarats_scan(c, ccfg%req%mcarats, ccfg%req%path, scan, error)
        if (allocated(error)) return
      end if
      call mcarats_phases(c, ccfg%req%path, n_table, scan%used, more, slot, notes, error)
      if (allocated(error)) return
      blend = scan%blend
      has_abs = scan%has_abs
      notes = notes//scan%abs_notes
      phases = [phases, more]
      call atmosphere_begin(atm, z, lx, ly, ext1d, ssa1d, iph1d, phases, aopts, error, k3_lo, &
                            c%nx, c%ny, c%nz, c%mca_atm%np3d + merge(1, 0, has_abs), blend=blend, &
                            storage=storage)
      if (allocated(error)) return
      if (atm%voxel_writer) call mcarats_voxels(c, ccfg%req%mcarats%ikd, offset, slot, has_abs, &
                                                atm, notes)
    case default
      call set_error(error, ccfg%req%path//': unknown kind of cloud content '//str(c%content))
      return
    end select
    call atmosphere_end(atm, aopts, error, sync=sync)
    if (allocated(error)) return
    if (n_out_liq > 0) warnings = warnings//str(n_out_liq)//' cloud voxel values have an '// &
      'effective radius outside the Mie table ('//str(ccfg%reff_min_um)//' - '// &
      str(ccfg%reff_max_um)//' um) and were given the nearest table radius; '// &
      'widen reff_min_um/reff_max_um to avoid it. '
    if (n_out_ice > 0) warnings = warnings//str(n_out_ice)//' ice voxel values have an '// &
      'effective radius outside the ice optics table and were given the nearest table radius. '
  end subroutine build_cloud_atmosphere

  !> Move the temperatures of a file read into `temp`, checked: shape (nx, ny) or a profile,
  !> one value per voxel layer or per bounding plane; finite, and > 0 unless perturbations.
  subroutine take_temperature(c, path, temp, error)
    type(cloud_input_t), intent(inout) :: c
    character(len=*), intent(in) :: path
    type(cloud_temperature_t), intent(out) :: temp
    type(error_t), allocatable, intent(out) :: error
    integer :: nt, loc(3)
    character(len=:), allocatable :: what
    if (.not. allocated(c%temperature)) return
    what = path//': temperatures ('//c%t_source//')'
    nt = c%nz
    if (c%t_planes) nt = c%nz + 1
    if (.not. ((size(c%temperature, 1) == c%nx .and. size(c%temperature, 2) == c%ny) .or. &
               (size(c%temperature, 1) == 1 .and. size(c%temperature, 2) == 1)) .or. &
        size(c%temperature, 3) /= nt) then
      call set_error(error, what//' have shape ('//str(size(c%temperature, 1))//','// &
                     str(size(c%temperature, 2))//','//str(size(c%temperature, 3))// &
                     '), the grid needs ('//str(c%nx)//','//str(c%ny)//','//str(nt)//')')
      return
    end if
    if (.not. all(ieee_is_finite(c%temperature))) then
      loc = findloc(ieee_is_finite(c%temperature), .false.)
      call set_error(error, what//': value at ('//str(loc(1))//','//str(loc(2))//','// &
                     str(loc(3))//') is not finite')
      return
    end if
    if (.not. c%t_perturbation .and. any(c%temperature <= 0.0_vp)) then
      loc = minloc(c%temperature)
      call set_error(error, what//': value '//str(real(minval(c%temperature), wp))// &
                     ' K at ('//str(loc(1))//','//str(loc(2))//','//str(loc(3))//') must be > 0')
      return
    end if
    temp%found = .true.
    call move_alloc(c%temperature, temp%t)
    temp%planes = c%t_planes
    temp%perturbation = c%t_perturbation
    temp%source = c%t_source
  end subroutine take_temperature

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
    integer :: dist
    r = table_radii(ccfg)
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

  !> The radii of the droplet tables: n_reff from reff_min_um to reff_max_um, geometric [um].
  function table_radii(ccfg) result(r)
    type(cloud_cfg_t), intent(in) :: ccfg
    real(wp), allocatable :: r(:)
    integer :: i, n
    n = ccfg%n_reff
    allocate (r(n))
    do i = 1, n
      r(i) = ccfg%reff_min_um*(ccfg%reff_max_um/ccfg%reff_min_um)**(real(i - 1, wp)/(n - 1))
    end do
    r(n) = ccfg%reff_max_um
  end function table_radii

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
    integer :: k, ip, np
    real(wp), allocatable :: ext(:, :), ssa(:, :), wph(:, :)
    integer, allocatable :: iph(:, :)
    np = merge(2, 1, c%points)
    allocate (ext(c%nx, c%ny), ssa(c%nx, c%ny), wph(c%nx, c%ny), iph(c%nx, c%ny))
    do ip = 1, np
      do k = 1, c%nz
        call mie_layer(c, amount, reff, table, offset, is_ext, k, ip, ext, ssa, iph, wph, n_out)
        call atmosphere_put_layer(atm, first + ip, k, ext, ssa, iph, wph)
      end do
    end do
  end subroutine mie_voxels

  !> Layer k of plane ip (1, or 2 for the upper plane of files on points) as mie_voxels puts
  !> it: extinction [m-1], albedo, phase index (after `offset` phase functions) and the blend
  !> weight of table iph + 1 of every column; `n_out` counts radii clamped to the table.
  subroutine mie_layer(c, amount, reff, table, offset, is_ext, k, ip, ext, ssa, iph, wph, n_out)
    type(cloud_input_t), intent(in) :: c
    real(vp), intent(in) :: amount(:, :, :)  !! water content [g m-3] or extinction [m-1]
    real(vp), intent(in) :: reff(:, :, :)    !! effective radius [um]
    type(mie_table_t), intent(in) :: table
    integer, intent(in) :: offset, k, ip
    logical, intent(in) :: is_ext            !! amount is the extinction
    real(wp), intent(out) :: ext(:, :), ssa(:, :), wph(:, :)   !! (nx, ny)
    integer, intent(out) :: iph(:, :)
    integer, intent(inout) :: n_out
    integer :: ix, iy, np
    np = merge(2, 1, c%points)
    ! the values of a voxel without water everywhere first (most voxels of a cloud field), then
    ! the voxels with water one by one
    ext = 0.0_wp
    ssa = table%ssa(1)
    iph = offset + 1
    wph = 0.0_wp
    do iy = 1, c%ny
      do ix = 1, c%nx
        if (amount(ix, iy, k + ip - 1) <= 0.0_vp) cycle
        call mie_voxel(real(amount(ix, iy, k + ip - 1)/np, wp), reff(ix, iy, k + ip - 1), &
                       table, offset, is_ext, ext(ix, iy), ssa(ix, iy), iph(ix, iy), &
                       wph(ix, iy), n_out)
      end do
    end do
  end subroutine mie_layer

  !> The optics of one voxel with water: `a` its share of the water content [g m-3] (or of the
  !> extinction [m-1] when `is_ext`), `r` its effective radius [um], clamped to the table
  !> (counted in `n_out`); the mixture of the two table radii around r that has that radius.
  subroutine mie_voxel(a, r_in, table, offset, is_ext, ext, ssa, iph, wph, n_out)
    real(wp), intent(in) :: a
    real(vp), intent(in) :: r_in
    type(mie_table_t), intent(in) :: table
    integer, intent(in) :: offset
    logical, intent(in) :: is_ext
    real(wp), intent(out) :: ext, ssa, wph
    integer, intent(out) :: iph
    integer, intent(inout) :: n_out
    integer :: i1, i2, nr
    real(wp) :: r, f, w_phase, e1, e2, scale
    logical :: inside
    nr = size(table%r_eff_um)
    r = r_in
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
    ext = (e1 + e2)*scale
    ssa = (e1*table%ssa(i1) + e2*table%ssa(i2))/(e1 + e2)
    iph = offset + i1
    wph = merge(1.0_wp - w_phase, 0.0_wp, i2 > i1)
  end subroutine mie_voxel

  !> The phase functions of an MCARaTS 3-D atmosphere (Iwabuchi, MCARaTS 0.10 `mcarAtm`,
  !> `mcarSca`), in the order its voxels refer to them after the scene's list: 1 isotropic,
  !> 2 Rayleigh (no depolarisation), 2 + i Henyey-Greenstein with g = c%hg_g(i), then the
  !> tables of the phase-function file that some voxel uses, in file order; slot(ipf) is the
  !> position of table ipf (0: unused). A code apf >= 1 with a fraction, r = apf - int(apf) > 0,
  !> blends table int(apf) with table int(apf) + 1, so both are then used and stand next to
  !> each other: slot(ipf + 1) = slot(ipf) + 1, as the atmosphere's blend of iph and iph + 1
  !> needs (`used` of mcarats_scan marks both). Only the file's sizes, g and tables are read,
  !> not its voxel fields.
  subroutine mcarats_phases(c, path, n_table, used, more, slot, notes, error)
    type(cloud_input_t), intent(in) :: c       !! the file read (content CLOUD_MCARATS)
    character(len=*), intent(in) :: path       !! the atmosphere file, for messages
    integer, intent(in) :: n_table             !! inverse-CDF table size of the tables
    logical, intent(in) :: used(:)             !! (npf) the tables some voxel uses (mcarats_scan)
    type(phase_t), allocatable, intent(out) :: more(:)
    integer, allocatable, intent(out) :: slot(:)
    character(len=:), allocatable, intent(inout) :: notes
    type(error_t), allocatable, intent(out) :: error
    integer :: npf, n_hg, nph, ipf, j

    associate (pf => c%mca_phase)
      npf = pf%npf
      allocate (slot(npf))
      n_hg = size(c%hg_g)
      nph = 2 + n_hg
      slot = 0
      do ipf = 1, npf
        if (.not. used(ipf)) cycle
        nph = nph + 1
        slot(ipf) = nph
      end do
      allocate (more(nph))
      more(1) = new_phase_isotropic()
      more(2) = new_phase_rayleigh()
      do j = 1, n_hg
        more(2 + j) = new_phase_hg(c%hg_g(j), error)
        if (allocated(error)) then
          error%message = path//': apf = '//str(c%hg_g(j))//': '//error%message
          return
        end if
      end do
      do ipf = 1, npf
        if (slot(ipf) == 0) cycle
        more(slot(ipf)) = phase_from_table(pf%angle_deg, pf%p(:, ipf), n_table, error)
        if (allocated(error)) then
          error%message = 'phase function '//str(ipf)//' of the MCARaTS '// &
                          'phase-function file: '//error%message
          return
        end if
      end do
      notes = notes//'MCARaTS phase functions: isotropic, Rayleigh, '//str(n_hg)// &
              ' Henyey-Greenstein, '//str(count(used))//' of the '//str(npf)//' tables'//NL
    end associate
  end subroutine mcarats_phases

  !> What the voxel values of an MCARaTS file decide (mcarats_scan_t): the tables used (a code
  !> apf >= 1 uses table int(apf), and table int(apf) + 1 too when it has a fraction, which is
  !> then a blend) and the gas-absorption perturbation (mcarats_absorption, whose error this
  !> returns).
  subroutine mcarats_scan(c, m, path, scan, error)
    type(cloud_input_t), intent(in) :: c           !! the file read, with its fields
    type(mcarats_request_t), intent(in) :: m       !! the namelist's request (k-term, abs1d)
    character(len=*), intent(in) :: path           !! the atmosphere file, for messages
    type(mcarats_scan_t), intent(out) :: scan
    type(error_t), allocatable, intent(out) :: error
    integer :: ip, k, ix, iy, ipf
    real(wp) :: apf
    associate (a => c%mca_atm)
      allocate (scan%used(c%mca_phase%npf))
      scan%used = .false.
      scan%blend = .false.
      do ip = 1, a%np3d
        do k = 1, a%nz3
          do iy = 1, a%ny
            do ix = 1, a%nx
              apf = a%apf(ix, iy, k, ip)
              if (apf < 1.0_wp) cycle
              ipf = int(apf)
              scan%used(ipf) = .true.
              if (apf > ipf) then   ! then ipf < npf: the reader keeps apf <= npf
                scan%used(ipf + 1) = .true.
                scan%blend = .true.
              end if
            end do
          end do
        end do
      end do
    end associate
    scan%abs_notes = ''
    call mcarats_absorption(c, m, path, scan%has_abs, scan%abs_notes, error)
  end subroutine mcarats_scan

  !> The gas-absorption perturbation of k-term `m%ikd` (absg3d): `has_abs` when it is not zero
  !> everywhere; it then becomes one more voxel component with albedo 0 (`mcarats_voxels`).
  !> MCARaTS adds it to the 1-D gas absorption (Atm_abs1d), which kumo takes from the 1-D
  !> components of the region's layers, added to every voxel (`m%abs1d`): so the perturbation
  !> may be negative where the voxel's absorption coefficient stays >= 0; a voxel where it
  !> would not is an error, not clamped.
  subroutine mcarats_absorption(c, m, path, has_abs, notes, error)
    type(cloud_input_t), intent(in) :: c           !! the file read (content CLOUD_MCARATS)
    type(mcarats_request_t), intent(in) :: m       !! the namelist's request (k-term, abs1d)
    character(len=*), intent(in) :: path           !! the atmosphere file, for messages
    logical, intent(out) :: has_abs
    character(len=:), allocatable, intent(inout) :: notes
    type(error_t), allocatable, intent(out) :: error
    integer :: k, ix, iy
    real(wp) :: tot, a1d, amin

    associate (a => c%mca_atm)
      has_abs = any(a%absg(:, :, :, m%ikd) /= 0.0_wp)
      if (.not. has_abs) then
        notes = notes//'gas absorption perturbation (absg3d) of k-term '//str(m%ikd)// &
                ': 0 everywhere'//NL
        return
      end if
      amin = huge(1.0_wp)
      do k = 1, a%nz3
        a1d = 0.0_wp
        if (allocated(m%abs1d)) a1d = m%abs1d(k)
        do iy = 1, a%ny
          do ix = 1, a%nx
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
      notes = notes//'gas absorption perturbation (absg3d) of k-term '//str(m%ikd)// &
              ': '//str(minval(a%absg(:, :, :, m%ikd)))//' ... '// &
              str(maxval(a%absg(:, :, :, m%ikd)))//' m-1, one more component (albedo 0) '// &
              'added to the 1-D absorption of the layers; smallest absorption coefficient '// &
              'of a voxel '//str(amin)//' m-1'//NL
    end associate
  end subroutine mcarats_absorption

  !> Put the voxels of an MCARaTS atmosphere into the atmosphere: component ip of kumo is
  !> MCARaTS component ip with its extinction and albedo, and the phase function its code
  !> names (`mcarats_code`): (-3, -2] isotropic, (-2, -1] Rayleigh, (-1, 1) Henyey-Greenstein
  !> with g = apf, >= 1 table ipf = int(apf) blended with table ipf + 1 as
  !> P = (1 - r) P_ipf + r P_ipf+1, r = apf - ipf (the atmosphere's weight of table iph + 1).
  !> With `has_abs`, component np3d + 1 is the perturbation of k-term `ikd`, albedo 0,
  !> isotropic. Phase indices are `offset` + the positions of `mcarats_phases`.
  subroutine mcarats_voxels(c, ikd, offset, slot, has_abs, atm, notes)
    type(cloud_input_t), intent(in) :: c           !! the file read (content CLOUD_MCARATS)
    integer, intent(in) :: ikd                     !! k-term of the absorption perturbation
    integer, intent(in) :: offset                  !! phase functions before the MCARaTS ones
    integer, intent(in) :: slot(:)                 !! positions of the tables (mcarats_phases)
    logical, intent(in) :: has_abs
    type(atmosphere_t), intent(inout) :: atm
    character(len=:), allocatable, intent(inout) :: notes
    integer :: ip, k, ix, iy, j, n_hg, n_iso, n_ray, n_gs, n_tab, n_blend
    integer, allocatable :: iph(:, :)
    real(wp), allocatable :: wph(:, :)
    real(wp) :: r

    associate (a => c%mca_atm)
      allocate (iph(a%nx, a%ny), wph(a%nx, a%ny))
      n_hg = size(c%hg_g)
      n_iso = 0
      n_ray = 0
      n_gs = 0
      n_tab = 0
      n_blend = 0
      do ip = 1, a%np3d
        do k = 1, a%nz3
          do iy = 1, a%ny
            do ix = 1, a%nx
              call mcarats_code(a%apf(ix, iy, k, ip), c%hg_g, slot, j, r)
              iph(ix, iy) = offset + j
              wph(ix, iy) = r
              if (.not. a%ext(ix, iy, k, ip) > 0.0_wp) cycle
              if (j == 1) then
                n_iso = n_iso + 1
              else if (j == 2) then
                n_ray = n_ray + 1
              else if (j <= 2 + n_hg) then
                n_gs = n_gs + 1
              else
                n_tab = n_tab + 1
                if (r > 0.0_wp) n_blend = n_blend + 1
              end if
            end do
          end do
          call atmosphere_put_layer(atm, ip, k, a%ext(:, :, k, ip), a%omg(:, :, k, ip), iph, wph)
        end do
      end do
      notes = notes//'apf codes of the voxel values with extinction > 0: '//str(n_iso)// &
              ' isotropic, '//str(n_ray)//' Rayleigh, '//str(n_gs)//' Henyey-Greenstein ('// &
              str(n_hg)//' distinct g), '//str(n_tab)//' tabulated ('//str(n_blend)// &
              ' blending two tables)'//NL
      if (n_blend > 0) then
        notes = notes//'a blended code takes table int(apf) + 1 with probability '// &
                'r = apf - int(apf) and table int(apf) otherwise'//NL
      end if
      if (.not. has_abs) return
      iph = offset + 1
      wph = 0.0_wp
      do k = 1, a%nz3
        call atmosphere_put_layer(atm, a%np3d + 1, k, a%absg(:, :, k, ikd), wph, iph)
      end do
    end associate
  end subroutine mcarats_voxels

  !> Position j (in the order of `mcarats_phases`) of the phase function named by the MCARaTS
  !> code `apf`, and the weight r of the next table (0 unless a table code has a fraction).
  pure subroutine mcarats_code(apf, gs, slot, j, r)
    real(wp), intent(in) :: apf        !! the code, within [-3, npf] (checked by the reader)
    real(wp), intent(in) :: gs(:)      !! the distinct Henyey-Greenstein g, sorted
    integer, intent(in) :: slot(:)     !! positions of the tables
    integer, intent(out) :: j
    real(wp), intent(out) :: r
    integer :: ipf
    r = 0.0_wp
    if (apf <= -2.0_wp) then
      j = 1
    else if (apf <= -1.0_wp) then
      j = 2
    else if (apf < 1.0_wp) then
      j = 2 + locate(gs, apf)
    else
      ipf = int(apf)
      r = apf - ipf
      j = slot(ipf)
    end if
  end subroutine mcarats_code

  !> Rayleigh extinction of dry air in every layer [m-1], the layers' air density [kg m-3]
  !> (mass per area (p_bottom - p_top)/g0 over the thickness) and a note saying where the
  !> pressure came from. The pressure profile is
  !>
  !> * a named standard atmosphere (`profile` = 'us1976'), evaluated at the levels and at steps
  !>   of at most PROFILE_STEP between them;
  !> * 'levels': `p_levels`, the pressure at every level (a sounding);
  !> * 'cloud_file': `p_file`, the pressure of each layer of a cloud file whose layer edges
  !>   `z_file` are consecutive levels, completed above and below by `cloud_file_pressure`.
  !>
  !> Between the heights of the profile p is interpolated linearly in log p
  !> (`rayleigh_extinction`); the air density uses the pressure at the levels.
  subroutine rayleigh_layers(z, wavelength_um, profile, co2_ppm, latitude_deg, ext, rho, notes, &
                             error, p_levels, z_file, p_file)
    use kumo_config, only: RAYLEIGH_LEVELS, RAYLEIGH_CLOUD_FILE
    real(wp), intent(in) :: z(0:)            !! levels [m]
    real(wp), intent(in) :: wavelength_um, co2_ppm, latitude_deg
    character(len=*), intent(in) :: profile  !! standard atmosphere, 'levels' or 'cloud_file'
    real(wp), allocatable, intent(out) :: ext(:), rho(:)
    character(len=:), allocatable, intent(out) :: notes
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: p_levels(0:)  !! 'levels': pressure at z [Pa]
    real(wp), intent(in), optional :: z_file(0:)    !! 'cloud_file': the file's layer edges [m]
    real(wp), intent(in), optional :: p_file(:)     !! 'cloud_file': its layer pressures [Pa]
    real(wp), allocatable :: zp(:), pp(:), pl(:), t(:), r(:)
    integer, allocatable :: at_level(:)
    integer :: nz
    nz = size(z) - 1
    select case (trim(profile))
    case (RAYLEIGH_LEVELS)
      if (.not. present(p_levels)) then
        call set_error(error, 'rayleigh_layers: the profile '''//RAYLEIGH_LEVELS// &
                       ''' needs the pressure at the levels')
        return
      end if
      if (size(p_levels) /= nz + 1) then
        call set_error(error, 'rayleigh_layers: '//str(size(p_levels))//' pressures for '// &
                       str(nz + 1)//' levels')
        return
      end if
      zp = z
      pp = p_levels
      allocate (pl(0:nz))
      pl(:) = p_levels
      notes = 'the sounding pressure_levels_hpa at the '//str(nz + 1)//' levels'
    case (RAYLEIGH_CLOUD_FILE)
      if (.not. (present(z_file) .and. present(p_file))) then
        call set_error(error, 'rayleigh_layers: the profile '''//RAYLEIGH_CLOUD_FILE// &
                       ''' needs the cloud file''s layer edges and pressures')
        return
      end if
      call cloud_file_pressure(z, z_file, p_file, zp, pp, pl, notes, error)
      if (allocated(error)) return
    case default
      call profile_heights(z, spread(.true., 1, nz), zp, at_level)
      allocate (pp(size(zp)), t(size(zp)), r(size(zp)))
      call std_atmosphere_profile(profile, zp, pp, t, r, error)
      if (allocated(error)) return
      allocate (pl(0:nz))
      pl(:) = pp(at_level)
      notes = 'standard atmosphere '//trim(profile)
    end select
    call rayleigh_extinction(wavelength_um, z, zp, pp, latitude_deg, co2_ppm, ext, error)
    if (allocated(error)) return
    rho = (pl(0:nz - 1) - pl(1:nz))/(G0*(z(1:nz) - z(0:nz - 1)))
  end subroutine rayleigh_layers

  !> The pressure profile of rayleigh_profile = 'cloud_file' on the levels `z` [m], from the
  !> pressure `p_file` [Pa] of each layer of a cloud file whose layer edges `z_file` are the
  !> consecutive levels z(j0..j0 + nzc):
  !>
  !> * p_file(k) is the pressure at the middle of layer k, zm(k) = (z_file(k-1) + z_file(k))/2;
  !> * an edge between two layers takes the value of the straight line in log p through the
  !>   two layers' centres; the bottom and top edges continue the line through the two lowest
  !>   and the two highest centres (the file's own scale height there). A file of one layer
  !>   has no scale height: its edges follow the US 1976 shape through its centre;
  !> * below the file (levels 0..j0) and above it (levels j0 + nzc..nz) the pressure is the
  !>   US 1976 standard atmosphere scaled to the file's edge: p(z) = p_edge p76(z)/p76(z_edge).
  !>   The air above the file's top then weighs what the file's top pressure says, spread over
  !>   height as in the standard (tropopause and stratosphere included), which an isothermal
  !>   extension at the scale height of a boundary-layer model's top would not do. Levels there
  !>   must lie within the standard's -5 to 86 km.
  !>
  !> Returns the profile heights `zp` and pressures `pp` (the levels, and steps of at most
  !> PROFILE_STEP outside the file), the pressure at the levels `pl`, and a note.
  subroutine cloud_file_pressure(z, z_file, p_file, zp, pp, pl, notes, error)
    real(wp), intent(in) :: z(0:), z_file(0:), p_file(:)
    real(wp), allocatable, intent(out) :: zp(:), pp(:), pl(:)
    character(len=:), allocatable, intent(out) :: notes
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: TOL = 1.0e-3_wp   ! [m], as for the cloud file's levels in kumo_config
    real(wp), allocatable :: pe(:), zm(:)
    real(wp) :: q(3), t(3), r(3)
    integer, allocatable :: at_level(:)
    integer :: nz, nzc, j0, j, k, i, n
    nz = size(z) - 1
    nzc = size(p_file)
    if (size(z_file) /= nzc + 1 .or. nzc < 1) then
      call set_error(error, 'rayleigh_layers: the cloud file has '//str(size(z_file))// &
                     ' layer edges and '//str(nzc)//' layer pressures')
      return
    end if
    j0 = -1
    do j = 0, nz - nzc
      if (all(abs(z(j:j + nzc) - z_file) <= TOL)) then
        j0 = j
        exit
      end if
    end do
    if (j0 < 0) then
      call set_error(error, 'rayleigh_layers: the cloud file''s layer edges '// &
                     str(z_file(0))//' ... '//str(z_file(nzc))//' m are not consecutive levels')
      return
    end if

    ! pressure at the file's layer edges
    allocate (pe(0:nzc))
    zm = 0.5_wp*(z_file(0:nzc - 1) + z_file(1:nzc))
    if (nzc >= 2) then
      do k = 0, nzc
        i = min(max(k, 1), nzc - 1)       ! the centres i, i + 1 around edge k, or nearest to it
        pe(k) = p_file(i)*(p_file(i + 1)/p_file(i))**((z_file(k) - zm(i))/(zm(i + 1) - zm(i)))
      end do
      notes = 'the layer pressures interpolated in log p to the layer edges, the bottom and '// &
              'top edges extrapolated from the two lowest and two highest layers'
    else
      call std_atmosphere_profile('us1976', [zm(1), z_file(0), z_file(1)], q, t, r, error)
      if (allocated(error)) then
        error%message = 'the edges of the cloud file''s one layer follow the US 1976 shape: '// &
                        error%message
        return
      end if
      pe = p_file(1)*q(2:3)/q(1)
      notes = 'the one layer''s pressure at its centre, its edges from the US 1976 shape '// &
              'through it'
    end if

    ! the profile: the levels, and steps outside the file
    call profile_heights(z, [(k <= j0 .or. k > j0 + nzc, k=1, nz)], zp, at_level)
    n = size(zp)
    allocate (pp(n))
    pp(at_level(j0:j0 + nzc)) = pe
    if (j0 > 0) then
      call scaled_standard(zp(1:at_level(j0)), at_level(j0), pe(0), pp(1:at_level(j0)), &
                           'from '//str(z(0))//' to '//str(z_file(0))//' m, below the file', &
                           notes, error)
      if (allocated(error)) return
    end if
    if (j0 + nzc < nz) then
      call scaled_standard(zp(at_level(j0 + nzc):n), 1, pe(nzc), pp(at_level(j0 + nzc):n), &
                           'from '//str(z_file(nzc))//' to '//str(z(nz))//' m, above the file', &
                           notes, error)
      if (allocated(error)) return
    end if
    allocate (pl(0:nz))
    pl(:) = pp(at_level)
  end subroutine cloud_file_pressure

  !> p(zs) = p_edge p76(zs)/p76(zs(iedge)) with the US 1976 standard atmosphere p76, where
  !> zs(iedge) is the file's edge. Adds a clause on `span` to `notes`.
  subroutine scaled_standard(zs, iedge, p_edge, p, span, notes, error)
    real(wp), intent(in) :: zs(:)      !! heights [m]
    integer, intent(in) :: iedge       !! index of the file's edge in zs
    real(wp), intent(in) :: p_edge     !! the file's pressure at its edge [Pa]
    real(wp), intent(out) :: p(:)      !! pressure at zs [Pa]
    character(len=*), intent(in) :: span
    character(len=:), allocatable, intent(inout) :: notes
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: q(:), t(:), r(:)
    allocate (q(size(zs)), t(size(zs)), r(size(zs)))
    call std_atmosphere_profile('us1976', zs, q, t, r, error)
    if (allocated(error)) then
      error%message = 'the levels outside the cloud file follow the US 1976 shape: '// &
                      error%message
      return
    end if
    p = p_edge*(q/q(iedge))
    notes = notes//'; '//span//': US 1976 scaled by '//str(p_edge/q(iedge))//' to the file''s '// &
            str(p_edge)//' Pa at '//str(zs(iedge))//' m'
  end subroutine scaled_standard

  !> Heights of a pressure profile: the levels z(0:nz) and, inside every layer k with split(k),
  !> equal steps of at most PROFILE_STEP. at_level(j) is the index of level j in zp.
  subroutine profile_heights(z, split, zp, at_level)
    real(wp), intent(in) :: z(0:)
    logical, intent(in) :: split(:)
    real(wp), allocatable, intent(out) :: zp(:)
    integer, allocatable, intent(out) :: at_level(:)
    integer :: nz, k, j, n
    integer, allocatable :: nsub(:)
    nz = size(z) - 1
    allocate (at_level(0:nz), nsub(nz))
    nsub = 1
    do k = 1, nz
      if (split(k)) nsub(k) = max(1, ceiling((z(k) - z(k - 1))/PROFILE_STEP))
    end do
    allocate (zp(1 + sum(nsub)))
    n = 1
    zp(1) = z(0)
    at_level(0) = 1
    do k = 1, nz
      do j = 1, nsub(k) - 1
        zp(n + j) = z(k - 1) + (z(k) - z(k - 1))*j/real(nsub(k), wp)
      end do
      n = n + nsub(k)
      zp(n) = z(k)
      at_level(k) = n
    end do
  end subroutine profile_heights

end module kumo_cloud_scene
