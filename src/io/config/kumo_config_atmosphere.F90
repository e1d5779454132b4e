! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_atmosphere: levels, 1-D layers, the 3-D region, Rayleigh layers.
!>
!> The parsing and validation of this namelist group (read_atmosphere), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_atmosphere
  use kumo_config_base
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str, to_lower, join
  use kumo_math, only: within
  use kumo_std_atmosphere, only: std_atmosphere_kind_from_name, STD_ATMOSPHERE_NAMES
  use kumo_cloud_input, only: cloud_input_t, cloud_request_t
  implicit none
  private
  public :: read_atmosphere

contains

  subroutine read_atmosphere(unit, present, cloud, cfg, error, read_grid)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    type(cloud_cfg_t), intent(in) :: cloud
    type(atmosphere_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    procedure(cloud_grid_reader), optional :: read_grid   !! present whenever cloud%enabled
    integer :: nz, n_components, k3d_bottom, nx, ny, nz3, n_components_3d, ios, k, ic
    real(wp) :: lx, ly, cp_air, co2_ppm, latitude_deg, rayleigh_depol
    logical :: rayleigh
    character(len=16) :: rayleigh_profile
    real(wp) :: z_levels(0:MAX_LAYERS), ext1d(MAX_LAYERS, MAX_COMP), ssa1d(MAX_LAYERS, MAX_COMP)
    real(wp) :: air_density(MAX_LAYERS), pressure_levels_hpa(0:MAX_LAYERS)
    integer :: phase1d(MAX_LAYERS, MAX_COMP), phase3d(MAX_COMP)
    character(len=PATH_LEN) :: scene_file
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_atmosphere: '
    namelist /kumo_atmosphere/ nz, z_levels, lx, ly, n_components, ext1d, ssa1d, phase1d, &
      scene_file, k3d_bottom, nx, ny, nz3, n_components_3d, phase3d, air_density, cp_air, &
      rayleigh, rayleigh_profile, co2_ppm, latitude_deg, rayleigh_depol, pressure_levels_hpa
    if (.not. present .and. .not. cloud%enabled) then
      call set_error(error, 'namelist group &kumo_atmosphere is required (levels and layers) '// &
                     'unless &kumo_cloud gives a cloud file')
      return
    end if
    nz = 0
    z_levels = UNSET
    lx = UNSET
    ly = UNSET
    rayleigh = cfg%rayleigh
    rayleigh_profile = cfg%rayleigh_profile
    co2_ppm = cfg%co2_ppm
    latitude_deg = cfg%latitude_deg
    rayleigh_depol = cfg%rayleigh_depol
    pressure_levels_hpa = UNSET
    n_components = cfg%n_components
    ext1d = UNSET
    ssa1d = UNSET
    phase1d = IUNSET
    scene_file = ''
    k3d_bottom = 0
    nx = IUNSET     ! (1, 1, 0 when not given; unset is told apart for MCARaTS files)
    ny = IUNSET
    nz3 = IUNSET
    n_components_3d = 1
    phase3d = 1
    air_density = UNSET
    cp_air = cfg%cp_air
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_atmosphere, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_atmosphere', present, ios, msg, error, probe)
    if (allocated(error)) return
    if (rayleigh) then
      call rayleigh_profile_check(rayleigh_profile, error)
      if (allocated(error)) return
      call require(within(co2_ppm, 0.0_wp, 2000.0_wp) .and. within(latitude_deg, -90.0_wp, &
                                                                   90.0_wp), CTX, 'co2_ppm', &
                   co2_ppm, 'must be within [0, 2000] and latitude_deg = '//str(latitude_deg)// &
                   ' within [-90, 90]', error)
      call require(rayleigh_depol < 6.0_wp/7.0_wp .and. ieee_is_finite(rayleigh_depol), CTX, &
                   'rayleigh_depol', rayleigh_depol, &
                   'must be < 6/7 (a value < 0 takes the Bodhaine et al. value)', error)
      if (allocated(error)) return
    end if
    cfg%rayleigh = rayleigh
    cfg%rayleigh_profile = to_lower(adjustl(rayleigh_profile))
    cfg%co2_ppm = co2_ppm
    cfg%latitude_deg = latitude_deg
    cfg%rayleigh_depol = rayleigh_depol
    if (cloud%enabled .and. cloud%req%format == 'mcarats') then
      call mcarats_region_sizes(cloud, lx, ly, scene_file, nx, ny, nz3, error)
      if (allocated(error)) return
    else
      if (nx == IUNSET) nx = 1
      if (ny == IUNSET) ny = 1
      if (nz3 == IUNSET) nz3 = 0
    end if
    if (cloud%enabled .and. cloud%req%format /= 'mcarats') then
      call levels_with_cloud(cloud, nz, z_levels, lx, ly, scene_file, k3d_bottom, nz3, ext1d, &
                             ssa1d, phase1d, error)
      if (allocated(error)) return
      nx = cloud%grid%nx
      ny = cloud%grid%ny
      n_components_3d = 1
      cfg%levels_from_cloud = .true.
    end if
    if (lx == UNSET) lx = cfg%lx
    if (ly == UNSET) ly = cfg%ly
    call require(nz >= 1 .and. nz <= MAX_LAYERS, CTX, 'nz', nz, &
                 'must be within 1..'//str(MAX_LAYERS), error)
    call require(n_components >= 1 .and. n_components <= MAX_COMP, CTX, 'n_components', &
                 n_components, 'must be within 1..'//str(MAX_COMP), error)
    if (allocated(error)) return
    call require(all(z_levels(0:nz) /= UNSET), CTX, 'z_levels', rule='needs nz + 1 = '// &
                 str(nz + 1)//' values (levels 0..nz, bottom first) [m]', error=error)
    call require(all(z_levels(nz + 1:) == UNSET), CTX, 'z_levels', rule='has more than '// &
                 'nz + 1 = '//str(nz + 1)//' values', error=error)
    if (allocated(error)) return
    do k = 0, nz
      if (.not. ieee_is_finite(z_levels(k))) then
        call set_error(error, CTX//'z_levels('//str(k)//') is not finite')
        return
      end if
      if (k > 0) then
        if (.not. z_levels(k) > z_levels(k - 1)) then
          call set_error(error, CTX//'z_levels must increase strictly, but z_levels('// &
                         str(k)//') = '//str(z_levels(k))//' <= z_levels('//str(k - 1)//') = '// &
                         str(z_levels(k - 1)))
          return
        end if
      end if
    end do
    call require(within(lx, SMALL, BIG) .and. within(ly, SMALL, BIG), CTX, 'lx', lx, &
                 'and ly = '//str(ly)//' must be > 0 [m]', error)
    if (allocated(error)) return
    ! Rayleigh layers are set from pressures over real heights: a top below KM_HINT looks like
    ! kilometres given where metres are expected.
    if (rayleigh .and. z_levels(nz) < KM_HINT) then
      call set_error(error, CTX//'z_levels top = '//str(z_levels(nz))//' m with rayleigh = '// &
                     '.true.: heights are in metres; '//str(z_levels(nz))//' km would be '// &
                     str(1000.0_wp*z_levels(nz))//' m (the top must be >= '//str(KM_HINT)//' m)')
      return
    end if
    if (any(ext1d(nz + 1:, :) /= UNSET) .or. any(ext1d(:, n_components + 1:) /= UNSET) .or. &
        any(ssa1d(nz + 1:, :) /= UNSET) .or. any(ssa1d(:, n_components + 1:) /= UNSET) .or. &
        any(phase1d(nz + 1:, :) /= IUNSET) .or. any(phase1d(:, n_components + 1:) /= IUNSET)) then
      call set_error(error, '&kumo_atmosphere: ext1d/ssa1d/phase1d have values beyond '// &
                     'layer nz = '//str(nz)//' or component n_components = '//str(n_components))
      return
    end if
    do ic = 1, n_components
      do k = 1, nz
        if (ext1d(k, ic) == UNSET) ext1d(k, ic) = 0.0_wp
        if (ssa1d(k, ic) == UNSET) ssa1d(k, ic) = 1.0_wp
        if (phase1d(k, ic) == IUNSET) phase1d(k, ic) = 1
        call require(within(ext1d(k, ic), 0.0_wp, BIG), CTX, 'ext1d('//str(k)//','//str(ic)//')', &
                     ext1d(k, ic), 'must be finite and >= 0 [m-1]', error)
        call require(within(ssa1d(k, ic), 0.0_wp, 1.0_wp), CTX, 'ssa1d('//str(k)//','//str(ic)// &
                     ')', ssa1d(k, ic), 'must be within [0, 1]', error)
        if (allocated(error)) return
      end do
    end do
    if (len_trim(scene_file) > 0) then
      if (k3d_bottom < 1 .or. nz3 < 1 .or. k3d_bottom + nz3 - 1 > nz) then
        call set_error(error, '&kumo_atmosphere: with scene_file, the 3-D region k3d_bottom = '// &
                       str(k3d_bottom)//' .. k3d_bottom + nz3 - 1 = '//str(k3d_bottom + nz3 - 1)// &
                       ' must lie within layers 1..nz = '//str(nz))
        return
      end if
      call require(nx >= 1 .and. ny >= 1, CTX, 'nx', nx, 'and ny = '//str(ny)//' must be >= 1', &
                   error)
      if (allocated(error)) return
    else if (cloud%enabled .and. cloud%req%format == 'mcarats') then
      if (k3d_bottom < 1 .or. k3d_bottom + nz3 - 1 > nz) then
        call set_error(error, '&kumo_atmosphere: the 3-D region of the MCARaTS file, layers '// &
                       'k3d_bottom = '//str(k3d_bottom)//' .. k3d_bottom + nz3 - 1 = '// &
                       str(k3d_bottom + nz3 - 1)//', must lie within layers 1..nz = '//str(nz)// &
                       ' (k3d_bottom is MCARaTS''s Atm_iz3l)')
        return
      end if
    else if ((k3d_bottom /= 0 .or. nz3 /= 0) .and. .not. cloud%enabled) then
      call set_error(error, '&kumo_atmosphere: k3d_bottom/nz3 are set but scene_file is empty')
      return
    end if
    ! checked with or without a scene file: phase3d(1:n_components_3d) is kept below
    call require(n_components_3d >= 1 .and. n_components_3d <= MAX_COMP, CTX, &
                 'n_components_3d', n_components_3d, 'must be within 1..'//str(MAX_COMP), error)
    call require(within(cp_air, SMALL, BIG), CTX, 'cp_air', cp_air, 'must be > 0', error)
    if (allocated(error)) return
    if (any(air_density(1:nz) /= UNSET)) then
      call require(all(air_density(1:nz) /= UNSET) .and. all(air_density(nz + 1:) == UNSET), &
                   CTX, 'air_density', rule='needs exactly nz = '//str(nz)//' values [kg m-3]', &
                   error=error)
      call require(all(within(air_density(1:nz), SMALL, BIG)), CTX, 'air_density values', &
                   rule='must be finite and > 0', error=error)
      if (allocated(error)) return
      cfg%air_density = air_density(1:nz)
    end if
    cfg%nz = nz
    cfg%z = z_levels(0:nz)
    cfg%lx = lx
    cfg%ly = ly
    cfg%n_components = n_components
    cfg%ext1d = ext1d(1:nz, 1:n_components)
    cfg%ssa1d = ssa1d(1:nz, 1:n_components)
    cfg%phase1d = phase1d(1:nz, 1:n_components)
    cfg%scene_file = scene_file
    cfg%k3d_bottom = k3d_bottom
    cfg%nx = nx
    cfg%ny = ny
    cfg%nz3 = nz3
    cfg%n_components_3d = n_components_3d
    cfg%phase3d = phase3d(1:n_components_3d)
    cfg%cp_air = cp_air
    call rayleigh_pressure(pressure_levels_hpa, cloud, cfg, error, read_grid)
  contains
    !> Read one assignment of &kumo_atmosphere (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_atmosphere, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_atmosphere, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_atmosphere

  !> The 3-D region of an MCARaTS atmosphere (cloud_format = 'mcarats'). As in MCARaTS, the
  !> levels, the region's first layer and the domain come from the namelist (z_levels,
  !> k3d_bottom, lx, ly: the binary file has no grid). Its sizes come from the `.ctl`, where
  !> nx, ny, nz3 given in the namelist must agree with it, or, for a binary file, from nx, ny,
  !> nz3, which are then required.
  subroutine mcarats_region_sizes(cloud, lx, ly, scene_file, nx, ny, nz3, error)
    type(cloud_cfg_t), intent(in) :: cloud
    real(wp), intent(in) :: lx, ly
    character(len=*), intent(in) :: scene_file
    integer, intent(inout) :: nx, ny, nz3
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: CTX = '&kumo_atmosphere with an MCARaTS cloud file: '
    if (len_trim(scene_file) > 0) then
      call set_error(error, CTX//'scene_file must not be set: the 3-D region is the MCARaTS file')
    else if (lx == UNSET .or. ly == UNSET) then
      call set_error(error, CTX//'lx and ly are required: the MCARaTS file has no horizontal '// &
                     'grid (lx = nx Atm_dx, ly = ny Atm_dy)')
    else if (cloud%grid%nx > 0) then
      call agree('nx', nx, cloud%grid%nx, 'XDEF')
      call agree('ny', ny, cloud%grid%ny, 'YDEF')
      call agree('nz3', nz3, cloud%grid%nz, 'levels of extp3d')
    else if (nx == IUNSET .or. ny == IUNSET .or. nz3 == IUNSET) then
      call set_error(error, CTX//'nx, ny and nz3 are required with a binary MCARaTS file '// &
                     '(its sizes Atm_nx, Atm_ny, Atm_nz3), or name its .ctl in cloud_file')
    else if (nx < 1 .or. ny < 1 .or. nz3 < 1) then
      call set_error(error, CTX//'nx = '//str(nx)//', ny = '//str(ny)//' and nz3 = '//str(nz3)// &
                     ' must be >= 1')
    end if
  contains
    subroutine agree(name, given, found, what)
      character(len=*), intent(in) :: name, what
      integer, intent(inout) :: given
      integer, intent(in) :: found
      if (allocated(error)) return
      if (given /= IUNSET .and. given /= found) then
        call set_error(error, CTX//name//' = '//str(given)//' disagrees with '//cloud%req%path// &
                       ' ('//what//' '//str(found)//'); leave it out to take the file''s')
      end if
      given = found
    end subroutine agree
  end subroutine mcarats_region_sizes

  !> A Rayleigh profile name: a named standard atmosphere, RAYLEIGH_LEVELS or RAYLEIGH_CLOUD_FILE.
  subroutine rayleigh_profile_check(name, error)
    character(len=*), intent(in) :: name
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: lname
    integer :: kind
    lname = trim(adjustl(to_lower(name)))
    if (lname == RAYLEIGH_LEVELS .or. lname == RAYLEIGH_CLOUD_FILE) return
    call std_atmosphere_kind_from_name(lname, kind, error)
    if (.not. allocated(error)) return
    error%message = '&kumo_atmosphere: rayleigh_profile = '''//trim(name)//''' must be one '// &
                    'of '//join(STD_ATMOSPHERE_NAMES)//' (standard atmospheres), '// &
                    RAYLEIGH_LEVELS//' (the sounding pressure_levels_hpa) or '// &
                    RAYLEIGH_CLOUD_FILE//' (the pressure of the &kumo_cloud LES file)'
  end subroutine rayleigh_profile_check

  !> The pressure of the Rayleigh layers when it does not come from a standard atmosphere:
  !> `pressure_levels_hpa` for RAYLEIGH_LEVELS, or the layer pressures of the &kumo_cloud LES
  !> file for RAYLEIGH_CLOUD_FILE, from `read_grid` (grid and a pressure profile only, no 3-D
  !> field). Runs after the levels are set (cfg%nz, cfg%z).
  subroutine rayleigh_pressure(pressure_levels_hpa, cloud, cfg, error, read_grid)
    real(wp), intent(in) :: pressure_levels_hpa(0:)  !! the namelist array, UNSET where not given
    type(cloud_cfg_t), intent(in) :: cloud
    type(atmosphere_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    procedure(cloud_grid_reader), optional :: read_grid   !! present whenever cloud%enabled
    character(len=*), parameter :: CTX = '&kumo_atmosphere: '
    character(len=:), allocatable :: ctx_cloud
    type(cloud_request_t) :: req
    type(cloud_input_t) :: c
    integer :: nz, n_given, k

    if (.not. cfg%rayleigh) return   ! every Rayleigh setting is unused
    nz = cfg%nz
    n_given = count(pressure_levels_hpa /= UNSET)
    if (n_given > 0 .and. cfg%rayleigh_profile /= RAYLEIGH_LEVELS) then
      call set_error(error, CTX//'pressure_levels_hpa is given but rayleigh_profile = '''// &
                     trim(cfg%rayleigh_profile)//'''; the sounding is used only with '// &
                     'rayleigh_profile = '''//RAYLEIGH_LEVELS//'''')
      return
    end if
    select case (trim(cfg%rayleigh_profile))
    case (RAYLEIGH_LEVELS)
      if (n_given == 0) then
        call set_error(error, CTX//'rayleigh_profile = '''//RAYLEIGH_LEVELS//''' needs '// &
                       'pressure_levels_hpa, the pressure at each of the nz + 1 = '// &
                       str(nz + 1)//' entries of z_levels [hPa]')
        return
      end if
      if (any(pressure_levels_hpa(0:nz) == UNSET) .or. &
          any(pressure_levels_hpa(nz + 1:) /= UNSET)) then
        call set_error(error, CTX//'pressure_levels_hpa has '//str(n_given)//' values but '// &
                       'needs nz + 1 = '//str(nz + 1)//', one per entry of z_levels '// &
                       '(levels 0..nz, bottom first) [hPa]')
        return
      end if
      do k = 0, nz
        if (.not. within(pressure_levels_hpa(k), SMALL, BIG)) then
          call set_error(error, CTX//'pressure_levels_hpa('//str(k)//') = '// &
                         str(pressure_levels_hpa(k))//' must be finite and > 0 [hPa]')
          return
        end if
      end do
      do k = 1, nz
        if (.not. pressure_levels_hpa(k) < pressure_levels_hpa(k - 1)) then
          call set_error(error, CTX//'pressure_levels_hpa('//str(k)//') = '// &
                         str(pressure_levels_hpa(k))//' must be < pressure_levels_hpa('// &
                         str(k - 1)//') = '//str(pressure_levels_hpa(k - 1))// &
                         ': pressure falls with height (levels bottom first)')
          return
        end if
      end do
      cfg%p_levels = 100.0_wp*pressure_levels_hpa(0:nz)
    case (RAYLEIGH_CLOUD_FILE)
      ctx_cloud = CTX//'rayleigh_profile = '''//RAYLEIGH_CLOUD_FILE//''': '
      if (.not. cloud%enabled) then
        call set_error(error, ctx_cloud//'needs a cloud file (&kumo_cloud cloud_file) '// &
                       'whose pressure gives the profile; there is none')
        return
      end if
      if (trim(cloud%req%format) /= 'les') then
        call set_error(error, ctx_cloud//'only LES netCDF files (cloud_format = ''les'') '// &
                       'have a pressure variable; the cloud file '//cloud%req%path// &
                       ' has cloud_format = '''//trim(cloud%req%format)//'''. Use '// &
                       'rayleigh_profile = '''//RAYLEIGH_LEVELS//''' with pressure_levels_hpa'// &
                       ' or a standard atmosphere')
        return
      end if
      req = cloud%req
      req%pressure_profile = .true.
      call grid_of(req, c, error, read_grid)
      if (allocated(error)) then
        error%message = ctx_cloud//error%message
        return
      end if
      if (.not. allocated(c%pressure)) then
        call set_error(error, ctx_cloud//cloud%req%path//': no pressure was read')
        return
      end if
      if (size(c%pressure) /= cloud%grid%nz) then
        call set_error(error, ctx_cloud//cloud%req%path//': '//str(size(c%pressure))// &
                       ' pressure values for '//str(cloud%grid%nz)//' layers')
        return
      end if
      associate (p => c%pressure)
        do k = 2, size(p)
          if (.not. p(k) < p(k - 1)) then
            call set_error(error, ctx_cloud//'the pressure of the cloud file ('// &
                           c%pressure_source//') must fall with height, but layer '// &
                           str(k)//' (z = '//str(cloud%grid%z(k - 1))//' to '// &
                           str(cloud%grid%z(k))//' m) has '//str(p(k))//' Pa >= '// &
                           str(p(k - 1))//' Pa of layer '//str(k - 1)//' below it')
            return
          end if
        end do
      end associate
      call move_alloc(c%pressure, cfg%p_cloud)
      cfg%p_cloud_source = c%pressure_source
    case default
      continue   ! a standard atmosphere: nothing to read
    end select
  end subroutine rayleigh_pressure

  !> Levels with a cloud file: the file's layer edges, below them a layer from the ground if
  !> the file starts above 0; or, when z_levels is given, z_levels must hold the file's edges
  !> as consecutive levels (to 1 mm), and the 3-D region is put there.
  subroutine levels_with_cloud(cloud, nz, z_levels, lx, ly, scene_file, k3d_bottom, nz3, &
                               ext1d, ssa1d, phase1d, error)
    type(cloud_cfg_t), intent(in) :: cloud
    integer, intent(inout) :: nz, k3d_bottom, nz3
    real(wp), intent(inout) :: z_levels(0:), lx, ly, ext1d(:, :), ssa1d(:, :)
    integer, intent(inout) :: phase1d(:, :)
    character(len=*), intent(in) :: scene_file
    type(error_t), allocatable, intent(out) :: error
    real(wp), parameter :: TOL = 1.0e-3_wp   ! [m]
    integer :: nzc, k, j
    real(wp) :: lxc, lyc
    character(len=*), parameter :: CTX = '&kumo_atmosphere with &kumo_cloud: '
    nzc = cloud%grid%nz
    lxc = cloud%grid%nx*cloud%grid%dx
    lyc = cloud%grid%ny*cloud%grid%dy
    if (len_trim(scene_file) > 0 .or. k3d_bottom /= 0 .or. nz3 /= 0) then
      call set_error(error, CTX//'scene_file, k3d_bottom and nz3 must not be set: the 3-D '// &
                     'region is the cloud file''s grid')
      return
    end if
    if ((lx /= UNSET .and. abs(lx - lxc) > TOL) .or. (ly /= UNSET .and. abs(ly - lyc) > TOL)) then
      call set_error(error, CTX//'lx, ly = '//str(lx)//', '//str(ly)//' differ from the '// &
                     'cloud file''s domain '//str(lxc)//' x '//str(lyc)//' m; leave them out')
      return
    end if
    lx = lxc
    ly = lyc
    if (nz == 0 .and. all(z_levels == UNSET)) then
      if (any(ext1d /= UNSET) .or. any(ssa1d /= UNSET) .or. any(phase1d /= IUNSET)) then
        call set_error(error, CTX//'ext1d, ssa1d or phase1d need z_levels (and nz): give the '// &
                       'levels of the whole column, the cloud file''s edges among them')
        return
      end if
      k = 0
      if (cloud%grid%z(0) > 0.0_wp) then
        z_levels(0) = 0.0_wp
        k = 1
      end if
      if (k + nzc > MAX_LAYERS) then
        call set_error(error, CTX//'the cloud file has '//str(nzc)//' layers; at most '// &
                       str(MAX_LAYERS)//' are possible')
        return
      end if
      z_levels(k:k + nzc) = cloud%grid%z
      nz = k + nzc
      k3d_bottom = k + 1
    else
      k3d_bottom = -1
      do k = 0, nz - nzc
        if (all(abs(z_levels(k:k + nzc) - cloud%grid%z) <= TOL)) then
          k3d_bottom = k + 1
          exit
        end if
      end do
      if (k3d_bottom < 0) then
        call set_error(error, CTX//'z_levels must contain the cloud file''s '//str(nzc + 1)// &
                       ' layer edges '//str(cloud%grid%z(0))//' ... '//str(cloud%grid%z(nzc))// &
                       ' m as consecutive levels (to 1 mm); or leave z_levels out to use them')
        return
      end if
      j = k3d_bottom - 1
      z_levels(j:j + nzc) = cloud%grid%z
    end if
    nz3 = nzc
  end subroutine levels_with_cloud
end module kumo_config_atmosphere
