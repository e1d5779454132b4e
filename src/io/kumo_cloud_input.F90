! SPDX-License-Identifier: BSD-3-Clause
!> One cloud field from any of the files kumo reads, in one form for the scene builder.
!>
!> `read_cloud_input` reads an LES/CRM netCDF file, an SHDOM/I3RC LWC file, an SHDOM property
!> file or a MYSTIC 3-D cloud file (the readers of kumo_les_netcdf, kumo_shdom_files and
!> kumo_mystic_file) and returns a `cloud_input_t`: the grid of the 3-D region (columns and
!> layer edges) and, per voxel, either water content and effective radius (optics still to be
!> computed), extinction and effective radius (single-scattering albedo and phase function
!> still to be computed), or complete optics (extinction, albedo, phase-function index).
!>
!> Files whose values sit on grid points (SHDOM's convention: nz heights instead of nz + 1
!> boundaries) keep their nz planes; layer k of the region lies between planes k and k + 1 and
!> is the equal mixture of the two (`points`), which keeps SHDOM's column optical depth of a
!> property varying linearly between the planes.
!>
!> An MCARaTS 3-D atmosphere (`from_mcarats`, kumo_mcarats_files) keeps its own form
!> (`CLOUD_MCARATS`: several components per voxel, each with an MCARaTS phase-function code, and
!> the tabulated phase functions); kumo_cloud_scene turns it into voxel components.
module kumo_cloud_input
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp, vp
  use kumo_error, only: error_t, set_error, str, to_lower
  use kumo_math, only: first_not_below
  use kumo_les_netcdf, only: les_names_t, les_field_t, read_les_field
  use kumo_shdom_files, only: lwc_field_t, prp_field_t, read_lwc_file, read_prp_file, &
                              set_reff_from_droplet_number
  use kumo_mystic_file, only: mystic_cloud_t, read_mystic_file, MYSTIC_EXT_G_SSA, &
                              MYSTIC_EXT_REFF, MYSTIC_LWC_REFF
  use kumo_mcarats_files, only: mcarats_request_t, mcarats_atm_t, mcarats_phase_t, &
                                grads_ctl_t, read_mcarats_atm, read_mcarats_atm_ctl, &
                                read_mcarats_phase, read_mcarats_phase_ctl, &
                                mcarats_atm_ctl_sizes, mcarats_phase_ctl_sizes, is_ctl_path
  implicit none
  private
  public :: cloud_input_t, cloud_request_t, read_cloud_input, cloud_format_check, locate
  public :: CLOUD_FORMAT_NAMES, CLOUD_WATER, CLOUD_EXT_REFF, CLOUD_OPTICS, CLOUD_MCARATS

  !> Formats, as named in the namelist (`&kumo_cloud cloud_format`).
  character(len=8), parameter :: CLOUD_FORMAT_NAMES(5) = &
    [character(len=8) :: 'les', 'lwc', 'prp', 'mystic', 'mcarats']

  integer, parameter :: CLOUD_WATER = 1     !! lwc [g m-3] and reff [um]
  integer, parameter :: CLOUD_EXT_REFF = 2  !! ext [m-1] and reff [um] (MYSTIC flag 2)
  integer, parameter :: CLOUD_OPTICS = 3    !! ext [m-1], ssa and a phase-function index
  integer, parameter :: CLOUD_MCARATS = 4   !! MCARaTS components (ext, omg, apf code), absg

  !> What to read and the facts a file may lack.
  type :: cloud_request_t
    character(len=8) :: format = 'les'           !! one of CLOUD_FORMAT_NAMES
    character(len=:), allocatable :: path        !! the cloud file
    type(les_names_t) :: names                   !! LES variable names (blank: defaults)
    integer :: time_index = -1                   !! LES time step, -1: no time dimension
    real(wp) :: k_factor = 0.80_wp               !! Martin et al. (1994) k for r_e from number
    logical :: z_edges_from_midpoints = .false.  !! LES: edges midway between stretched centres
    real(wp) :: droplet_number_cm3 = 0.0_wp      !! 1-parameter LWC files: N [cm-3]
    !> LES grid-only reads: also the pressure of every layer (required; `cloud_input_t%pressure`)
    logical :: pressure_profile = .false.
    !> LES grid-only reads: also the gas state of every layer for broadband runs (column means
    !> of temperature, pressure and water vapour where the file has them; `cloud_input_t`'s
    !> t_profile, pressure and h2o_profile)
    logical :: state_profile = .false.
    type(mcarats_request_t) :: mcarats           !! MCARaTS files: sizes and grid from the namelist
    !> thermal runs: also the temperatures the file has (LES: the temperature, or a potential
    !> temperature and the pressure, read only then; the other formats hold theirs anyway)
    logical :: temperature = .false.
  end type cloud_request_t

  !> A cloud field on the voxels of the 3-D region. Read on rank 0 and shared whole
  !> (kumo_cloud_share): a new component needs one line in cloud_input_put and cloud_input_get.
  type :: cloud_input_t
    character(len=8) :: format = ''
    integer :: nx = 0, ny = 0                  !! columns
    integer :: nz = 0                          !! layers of the 3-D region
    real(wp) :: dx = 0.0_wp, dy = 0.0_wp       !! column widths [m]
    real(wp), allocatable :: z(:)              !! layer edges z(0:nz), bottom first [m]
    !> values on nz + 1 planes (the third dimension of the arrays); layer k mixes planes k, k+1
    logical :: points = .false.
    integer :: content = CLOUD_WATER           !! CLOUD_WATER, _EXT_REFF, _OPTICS or _MCARATS
    ! Fields are kept in the voxel precision (vp), as the atmosphere stores them.
    real(vp), allocatable :: lwc(:, :, :)      !! liquid water content [g m-3] (CLOUD_WATER)
    real(vp), allocatable :: reff(:, :, :)     !! droplet effective radius [um], 0 where empty
    real(vp), allocatable :: ext(:, :, :)      !! extinction [m-1] (CLOUD_EXT_REFF, CLOUD_OPTICS)
    real(vp), allocatable :: ssa(:, :, :)      !! single-scattering albedo (CLOUD_OPTICS)
    integer, allocatable :: iphase(:, :, :)    !! phase-function index (CLOUD_OPTICS)
    !> CLOUD_OPTICS phase functions: Legendre moments chi(0:nleg, nphase) (property files) ...
    real(wp), allocatable :: chi(:, :)
    !> ... or Henyey-Greenstein asymmetry parameters (MYSTIC flag 1), one per distinct value
    real(wp), allocatable :: hg_g(:)
    logical :: has_ice = .false.               !! LES ice water present
    real(vp), allocatable :: iwc(:, :, :)      !! ice water content [g m-3]
    real(vp), allocatable :: reff_ice(:, :, :) !! ice effective radius [um]
    !> LES grid-only reads with `pressure_profile`: pressure of each layer [Pa], bottom first,
    !> in double precision; a 3-D variable is averaged over the columns of each layer
    real(wp), allocatable :: pressure(:)
    character(len=:), allocatable :: pressure_source !! variable and whether it was averaged
    !> LES grid-only reads with `state_profile`: per layer, bottom first, the column mean of
    !> the temperature [K] and of the water vapour's volume mixing ratio of dry air
    !> [mol mol-1], when the file has them
    real(wp), allocatable :: t_profile(:), h2o_profile(:)
    !> temperatures of the file, when requested and present (not for `grid_only` reads):
    !> (nx, ny, nt) or a profile (1, 1, nt); nt = nz (one per voxel) or nz + 1 (`t_planes`: on
    !> the planes or levels that bound the layers, the voxel between planes k and k + 1)
    real(vp), allocatable :: temperature(:, :, :)
    logical :: t_planes = .false.
    !> MCARaTS tmpa3d: perturbations to add to the level temperatures of the namelist
    logical :: t_perturbation = .false.
    character(len=:), allocatable :: t_source      !! file and variable, for the run log
    type(mcarats_atm_t) :: mca_atm             !! CLOUD_MCARATS: the dataset read
    type(mcarats_phase_t) :: mca_phase         !! CLOUD_MCARATS: its tables (npf = 0: none)
    character(len=:), allocatable :: notes     !! how the file was read, for the run log
    character(len=:), allocatable :: missing   !! what the file does not give
    !> water contents beyond any cloud's (WATER_CONTENT_MAX), for the run's warnings
    character(len=:), allocatable :: warnings
  end type cloud_input_t

  !> [g m-3] liquid or ice water content beyond which a voxel warns: more than any cloud holds
  !> (the densest convective cores hold a few g m-3), so most likely another unit
  real(wp), parameter :: WATER_CONTENT_MAX = 10.0_wp

  character(len=1), parameter :: NL = new_line('a')

contains

  !> Check a format name (case-insensitive) and return it in lower case.
  subroutine cloud_format_check(name, fmt, error)
    character(len=*), intent(in) :: name
    character(len=8), intent(out) :: fmt
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    fmt = trim(adjustl(to_lower(name)))
    do i = 1, size(CLOUD_FORMAT_NAMES)
      if (fmt == CLOUD_FORMAT_NAMES(i)) return
    end do
    call set_error(error, 'cloud_format = "'//trim(name)//'" must be one of les (LES/CRM '// &
                   'netCDF), lwc (SHDOM/I3RC LWC file), prp (SHDOM property file), mystic '// &
                   '(MYSTIC wc_file 3D), mcarats (MCARaTS 3-D atmosphere file)')
  end subroutine cloud_format_check

  !> Read a cloud file. With `grid_only`, only the grid (nx, ny, nz, dx, dy, z) is guaranteed
  !> (the LES reader then reads coordinates only, the property-file reader its header; the
  !> other text files are read whole). `part` ('liquid' or 'ice') reads one species of an LES
  !> file (`has_ice` still tells whether there is ice); the other formats have liquid water only
  !> and ignore it.
  subroutine read_cloud_input(req, cloud, error, grid_only, part)
    type(cloud_request_t), intent(in) :: req
    type(cloud_input_t), intent(out) :: cloud
    type(error_t), allocatable, intent(out) :: error
    logical, intent(in), optional :: grid_only
    character(len=*), intent(in), optional :: part
    logical :: grid
    grid = .false.
    if (present(grid_only)) grid = grid_only
    cloud%format = req%format
    cloud%notes = ''
    cloud%missing = ''
    select case (trim(req%format))
    case ('les')
      call from_les(req, grid, cloud, error, part)
    case ('lwc')
      call from_lwc(req, cloud, error)
    case ('prp')
      call from_prp(req, grid, cloud, error)
    case ('mystic')
      call from_mystic(req, cloud, error)
    case ('mcarats')
      call from_mcarats(req, grid, cloud, error)
    case default
      call set_error(error, 'cloud_format "'//trim(req%format)//'" is unknown')
    end select
    cloud%warnings = ''
    if (allocated(error)) return
    call dense_water(cloud%lwc, 'liquid')
    call dense_water(cloud%iwc, 'ice')
  contains
    !> A warning when the water content `w` [g m-3] of some voxels exceeds WATER_CONTENT_MAX.
    subroutine dense_water(w, what)
      real(vp), allocatable, intent(in) :: w(:, :, :)
      character(len=*), intent(in) :: what
      integer :: n
      if (.not. allocated(w)) return
      n = count(w > WATER_CONTENT_MAX)
      if (n > 0) cloud%warnings = cloud%warnings//req%path//': '//str(n)//' voxel value(s) '// &
        'of '//what//' water content exceed '//str(WATER_CONTENT_MAX)//' g m-3 (up to '// &
        str(real(maxval(w), wp))//' g m-3), more than clouds hold: check the units of '// &
        'the file''s variable (g/kg or kg/kg, g m-3 or kg m-3) or its units attribute. '
    end subroutine dense_water
  end subroutine read_cloud_input

  subroutine from_les(req, grid, cloud, error, part)
    type(cloud_request_t), intent(in) :: req
    logical, intent(in) :: grid
    type(cloud_input_t), intent(inout) :: cloud
    type(error_t), allocatable, intent(out) :: error
    character(len=*), intent(in), optional :: part
    type(les_field_t) :: f
    call read_les_field(req%path, req%names, req%time_index, f, error, req%k_factor, &
                        req%z_edges_from_midpoints, grid, part, req%pressure_profile, &
                        req%temperature .and. .not. grid, req%state_profile .and. grid)
    if (allocated(error)) return
    call set_grid(cloud, f%nx, f%ny, f%nz, f%dx, f%dy, f%z_edges, .false.)
    if (allocated(f%pressure_profile)) then
      call move_alloc(f%pressure_profile, cloud%pressure)
      cloud%pressure_source = 'variable "'//trim(f%used%pressure)//'" of '//req%path
      if (f%pressure_averaged) then
        cloud%pressure_source = cloud%pressure_source//', a 3-D field averaged over the '// &
                                'columns of each layer'
      else
        cloud%pressure_source = cloud%pressure_source//', a profile'
      end if
    end if
    if (allocated(f%t_profile)) call move_alloc(f%t_profile, cloud%t_profile)
    if (allocated(f%h2o_profile)) call move_alloc(f%h2o_profile, cloud%h2o_profile)
    if (grid) then
      if (req%state_profile) cloud%notes = f%notes
      return
    end if
    cloud%content = CLOUD_WATER
    if (allocated(f%lwc)) call move_alloc(f%lwc, cloud%lwc)
    if (allocated(f%reff)) call move_alloc(f%reff, cloud%reff)
    cloud%has_ice = f%has_ice
    if (allocated(f%iwc)) call move_alloc(f%iwc, cloud%iwc)
    if (allocated(f%reff_ice)) call move_alloc(f%reff_ice, cloud%reff_ice)
    if (req%temperature .and. f%has_temperature) then
      call move_alloc(f%temperature, cloud%temperature)
      if (f%temperature_from_theta) then
        cloud%t_source = 'potential temperature "'//trim(f%used%potential_temperature)// &
                         '" and pressure "'//trim(f%used%pressure)//'" of '//req%path
      else
        cloud%t_source = 'variable "'//trim(f%used%temperature)//'" of '//req%path
      end if
      if (size(cloud%temperature, 1) == 1 .and. size(cloud%temperature, 2) == 1 .and. &
          f%nx*f%ny > 1) cloud%t_source = cloud%t_source//' (a profile)'
    end if
    cloud%notes = f%notes
    cloud%missing = 'the wavelength'
  end subroutine from_les

  subroutine from_lwc(req, cloud, error)
    type(cloud_request_t), intent(in) :: req
    type(cloud_input_t), intent(inout) :: cloud
    type(error_t), allocatable, intent(out) :: error
    type(lwc_field_t) :: f
    call read_lwc_file(req%path, f, error)
    if (allocated(error)) return
    if (f%n_params == 1) then
      if (.not. req%droplet_number_cm3 > 0.0_wp) then
        call set_error(error, req%path//': a 1-parameter LWC file has no effective radius; '// &
                       'give the droplet number concentration (&kumo_cloud '// &
                       'droplet_number_cm3 > 0)')
        return
      end if
      call set_reff_from_droplet_number(f, req%droplet_number_cm3, error)
      if (allocated(error)) return
      cloud%notes = 'r_eff from LWC and the namelist droplet number '// &
                    str(req%droplet_number_cm3)//' cm-3 (gamma distribution, alpha = 7)'//NL
    else
      cloud%notes = ''
      if (req%droplet_number_cm3 > 0.0_wp) cloud%notes = 'droplet_number_cm3 is not used: '// &
                                                         'the file gives r_eff'//NL
    end if
    call set_grid(cloud, f%nx, f%ny, f%nz, f%dx, f%dy, f%z, .not. f%z_are_boundaries)
    cloud%content = CLOUD_WATER
    if (req%temperature) then
      ! one temperature per height: the layer edges (boundaries) or the planes (points)
      cloud%temperature = reshape(real(f%temperature, vp), [1, 1, size(f%temperature)])
      cloud%t_planes = .true.
      cloud%t_source = 'the temperature profile (line 5) of '//req%path
    end if
    call take(f%lwc, cloud%lwc)
    call take(f%reff, cloud%reff)
    cloud%notes = cloud%notes//'LWC file: '//str(f%n_listed)//' points listed, heights as '// &
                  merge('cell boundaries', 'grid points    ', f%z_are_boundaries)
    cloud%missing = 'the wavelength and the droplet optics'
  end subroutine from_lwc

  subroutine from_prp(req, grid, cloud, error)
    type(cloud_request_t), intent(in) :: req
    logical, intent(in) :: grid
    type(cloud_input_t), intent(inout) :: cloud
    type(error_t), allocatable, intent(out) :: error
    type(prp_field_t) :: f
    call read_prp_file(req%path, f, error, grid_only=grid)
    if (allocated(error)) return
    call set_grid(cloud, f%nx, f%ny, f%nz, f%dx, f%dy, f%z, .not. f%z_are_boundaries)
    cloud%content = CLOUD_OPTICS
    cloud%missing = 'the wavelength'
    if (grid) return
    call take(f%extinction, cloud%ext)
    call take(f%ssa, cloud%ssa)
    if (req%temperature) then
      call take(f%temperature, cloud%temperature)
      cloud%t_planes = cloud%points
      cloud%t_source = 'the column temp of '//req%path
    end if
    call move_alloc(f%iphase, cloud%iphase)
    call move_alloc(f%chi, cloud%chi)
    cloud%notes = 'property file: '//str(f%nphase)//' phase functions of up to '// &
                  str(f%nleg_max)//' Legendre terms, heights as '// &
                  merge('cell boundaries', 'grid points    ', f%z_are_boundaries)
    cloud%missing = 'the wavelength'
  end subroutine from_prp

  subroutine from_mystic(req, cloud, error)
    type(cloud_request_t), intent(in) :: req
    type(cloud_input_t), intent(inout) :: cloud
    type(error_t), allocatable, intent(out) :: error
    type(mystic_cloud_t) :: f
    real(wp), allocatable :: gs(:)
    integer :: n, ix, iy, iz
    call read_mystic_file(req%path, f, error)
    if (allocated(error)) return
    call set_grid(cloud, f%nx, f%ny, f%nz, f%dx, f%dy, f%z, .false.)
    select case (f%flag)
    case (MYSTIC_EXT_G_SSA)
      cloud%content = CLOUD_OPTICS
      call take(f%ext, cloud%ext)
      call take(f%ssa, cloud%ssa)
      ! one Henyey-Greenstein phase function per distinct g (exact values, no binning)
      gs = [0.0_wp, pack(f%g, f%listed)]
      call sort_unique_exact(gs, n)
      cloud%hg_g = gs(1:n)
      allocate (cloud%iphase(f%nx, f%ny, f%nz))
      do iz = 1, f%nz
        do iy = 1, f%ny
          do ix = 1, f%nx
            cloud%iphase(ix, iy, iz) = locate(cloud%hg_g, merge(f%g(ix, iy, iz), 0.0_wp, &
                                                                 f%listed(ix, iy, iz)))
          end do
        end do
      end do
      cloud%notes = 'MYSTIC file, flag 1 (ext, g, ssa): '//str(f%n_listed)//' cells, '// &
                    str(n)//' distinct Henyey-Greenstein g'
      cloud%missing = 'the wavelength'
    case (MYSTIC_EXT_REFF)
      cloud%content = CLOUD_EXT_REFF
      call take(f%ext, cloud%ext)
      call take(f%reff, cloud%reff)
      cloud%notes = 'MYSTIC file, flag 2 (ext, r_eff): '//str(f%n_listed)//' cells'
      cloud%missing = 'the wavelength, the single-scattering albedo and phase function'
    case default
      cloud%content = CLOUD_WATER
      call take(f%lwc, cloud%lwc)
      call take(f%reff, cloud%reff)
      cloud%notes = 'MYSTIC file, flag 3 (LWC, r_eff): '//str(f%n_listed)//' cells'
      cloud%missing = 'the wavelength and the droplet optics'
    end select
  end subroutine from_mystic

  !> An MCARaTS 3-D atmosphere (`req%path`: the binary file or its `.ctl`) and its phase
  !> functions (`req%mcarats%phase_path`). With a `.ctl` the sizes come from it and sizes given
  !> in the namelist must agree; a binary file takes them from the namelist (`req%mcarats`).
  !> The grid (column widths, layer edges) always comes from the namelist. With `grid_only`,
  !> the descriptors are checked and the sizes they give set (nx = ny = nz = 0 for a binary
  !> file: they are the namelist's); nothing else is read. Codes apf >= 1 need the phase file.
  subroutine from_mcarats(req, grid, cloud, error)
    type(cloud_request_t), intent(in) :: req
    logical, intent(in) :: grid
    type(cloud_input_t), intent(inout) :: cloud
    type(error_t), allocatable, intent(out) :: error
    type(grads_ctl_t) :: ctl
    integer :: nz3, mtprof, nkd, np3d, nang, npf, ip, k, loc(2), n
    logical :: atm_ctl, has_phase
    real(wp), allocatable :: gs(:)
    character(len=:), allocatable :: src

    associate (m => req%mcarats)
      atm_ctl = is_ctl_path(req%path)
      has_phase = .false.
      if (allocated(m%phase_path)) has_phase = len_trim(m%phase_path) > 0
      cloud%content = CLOUD_MCARATS
      if (atm_ctl) then
        call mcarats_atm_ctl_sizes(req%path, ctl, nz3, mtprof, nkd, np3d, error)
        if (allocated(error)) return
        call agree('mcarats_np3d', m%np3d, np3d, req%path, 'np3d')
        call agree('mcarats_nkd', m%nkd, nkd, req%path, 'nkd')
        call agree('mcarats_mtprof', m%mtprof, mtprof, req%path, 'mtprof')
        if (allocated(error)) return
        cloud%nx = ctl%nx
        cloud%ny = ctl%ny
        cloud%nz = nz3
      else
        nkd = m%nkd
      end if
      if (m%ikd > nkd) then
        call set_error(error, 'mcarats_ikd = '//str(m%ikd)//' must be within 1..nkd = '// &
                       str(nkd)//' (k-terms of '//req%path//')')
        return
      end if
      if (has_phase) then
        if (is_ctl_path(m%phase_path)) then
          call mcarats_phase_ctl_sizes(m%phase_path, ctl, nang, npf, error)
          if (allocated(error)) return
          call agree('mcarats_nang', m%nang, nang, m%phase_path, 'nang')
          call agree('mcarats_npf', m%npf, npf, m%phase_path, 'npf')
          if (allocated(error)) return
        end if
      end if
      if (grid) return

      ! the phase functions first: their number bounds the apf codes
      if (has_phase) then
        if (is_ctl_path(m%phase_path)) then
          call read_mcarats_phase_ctl(m%phase_path, cloud%mca_phase, error)
        else
          call read_mcarats_phase(m%phase_path, m%nang, m%npf, cloud%mca_phase, error)
        end if
        if (allocated(error)) return
        npf = cloud%mca_phase%npf
      end if
      if (atm_ctl) then
        if (has_phase) then
          call read_mcarats_atm_ctl(req%path, cloud%mca_atm, error, m%idread, npf)
        else
          call read_mcarats_atm_ctl(req%path, cloud%mca_atm, error, m%idread)
        end if
      else
        if (has_phase) then
          call read_mcarats_atm(req%path, m%nx, m%ny, m%nz3, m%mtprof, m%nkd, m%np3d, &
                                cloud%mca_atm, error, m%idread, npf=npf)
        else
          call read_mcarats_atm(req%path, m%nx, m%ny, m%nz3, m%mtprof, m%nkd, m%np3d, &
                                cloud%mca_atm, error, m%idread)
        end if
      end if
      if (allocated(error)) return
      associate (a => cloud%mca_atm)
        if ((m%nx > 0 .and. m%nx /= a%nx) .or. (m%ny > 0 .and. m%ny /= a%ny) .or. &
            (m%nz3 > 0 .and. m%nz3 /= a%nz3)) then
          call set_error(error, req%path//': '//str(a%nx)//' x '//str(a%ny)//' x '// &
                         str(a%nz3)//' voxels; the namelist has nx, ny, nz3 = '//str(m%nx)// &
                         ', '//str(m%ny)//', '//str(m%nz3))
          return
        end if
        if (.not. allocated(m%z)) then
          call set_error(error, req%path//': the heights of the 3-D region are not known '// &
                         '(&kumo_atmosphere z_levels and k3d_bottom)')
          return
        end if
        if (size(m%z) /= a%nz3 + 1) then
          call set_error(error, req%path//': '//str(a%nz3)//' layers but '//str(size(m%z))// &
                         ' layer edges from the namelist')
          return
        end if
        if (.not. has_phase) then
          do ip = 1, a%np3d
            do k = 1, a%nz3
              if (all(a%apf(:, :, k, ip) < 1.0_wp)) cycle
              loc = maxloc(a%apf(:, :, k, ip))
              call set_error(error, req%path//': apfp3d comp. '//str(ip)//' layer '//str(k)// &
                             ', ix = '//str(loc(1))//', iy = '//str(loc(2))//': apf = '// &
                             str(a%apf(loc(1), loc(2), k, ip))//' names a tabulated phase '// &
                             'function, but no phase-function file is given (&kumo_cloud '// &
                             'mcarats_phase_file)')
              return
            end do
          end do
        end if
        call set_grid(cloud, a%nx, a%ny, a%nz3, m%dx, m%dy, m%z, .false.)
        cloud%content = CLOUD_MCARATS
        ! one Henyey-Greenstein phase function per distinct g = apf in (-1, 1), as for MYSTIC
        gs = pack(a%apf, a%apf > -1.0_wp .and. a%apf < 1.0_wp)
        call sort_unique_exact(gs, n)
        cloud%hg_g = gs(1:n)
        src = 'binary, sizes from the namelist'
        if (atm_ctl) src = 'sizes from its .ctl'
        cloud%notes = 'MCARaTS 3-D atmosphere ('//src//'): dataset '//str(a%idread)// &
                      ' of '//str(a%ndatasets)//', '//str(a%nx)//' x '//str(a%ny)//' x '// &
                      str(a%nz3)//' voxels, '//str(a%np3d)//' component(s), '//str(a%nkd)// &
                      ' k-term(s) (absorption perturbation of k-term '//str(m%ikd)// &
                      ' used), mtprof = '//str(a%mtprof)
        if (req%temperature) then
          cloud%temperature = real(a%tmpa, vp)
          cloud%t_planes = a%mtprof == 1
          cloud%t_perturbation = .true.
          cloud%t_source = 'tmpa3d of '//req%path//' ('// &
                           trim(merge('per level', 'per layer', a%mtprof == 1))// &
                           ') added to t_levels of &kumo_thermal'
        else
          cloud%notes = cloud%notes//NL//'its temperatures (tmpa3d) are not used (no '// &
                        '&kumo_thermal)'
        end if
        if (has_phase) then
          cloud%notes = cloud%notes//NL//'phase functions '//m%phase_path//': '// &
                        str(cloud%mca_phase%npf)//' tables of '//str(cloud%mca_phase%nang)// &
                        ' angles'
        end if
        cloud%missing = 'the column widths '//str(m%dx)//' x '//str(m%dy)// &
                        ' m (lx/nx, ly/ny) and the layer edges '//str(m%z(lbound(m%z, 1)))// &
                        ' ... '//str(m%z(ubound(m%z, 1)))//' m (z_levels of layers '// &
                        str(m%k3d_bottom)//'..'//str(m%k3d_bottom + a%nz3 - 1)// &
                        ', k3d_bottom = Atm_iz3l)'
        if (.not. atm_ctl) then
          cloud%missing = cloud%missing//', its sizes (nx, ny, nz3; mcarats_np3d, '// &
                          'mcarats_nkd, mcarats_mtprof)'
        end if
        if (has_phase .and. .not. is_ctl_path(m%phase_path)) then
          cloud%missing = cloud%missing//', the phase file''s sizes (mcarats_nang, mcarats_npf)'
        end if
      end associate
    end associate

  contains
    !> A size given in the namelist (>= 0) must equal the descriptor's.
    subroutine agree(name, given, found, path, what)
      character(len=*), intent(in) :: name, path, what
      integer, intent(in) :: given, found
      if (allocated(error) .or. given < 0 .or. given == found) return
      call set_error(error, name//' = '//str(given)//' disagrees with '//path//', which '// &
                     'gives '//what//' = '//str(found)//' (leave '//name//' out to take it)')
    end subroutine agree
  end subroutine from_mcarats

  !> Move a field read in working precision into the cloud's voxel precision.
  subroutine take(from, to)
    real(wp), allocatable, intent(inout) :: from(:, :, :)
    real(vp), allocatable, intent(out) :: to(:, :, :)
    to = real(from, vp)
    deallocate (from)
  end subroutine take

  !> Grid of the region from a file's heights: nz + 1 boundaries, or nz grid points.
  subroutine set_grid(cloud, nx, ny, nz_file, dx, dy, z, points)
    type(cloud_input_t), intent(inout) :: cloud
    integer, intent(in) :: nx, ny, nz_file
    real(wp), intent(in) :: dx, dy, z(:)
    logical, intent(in) :: points
    cloud%nx = nx
    cloud%ny = ny
    cloud%dx = dx
    cloud%dy = dy
    cloud%points = points
    if (points) then
      cloud%nz = nz_file - 1
    else
      cloud%nz = nz_file
    end if
    allocate (cloud%z(0:cloud%nz))
    cloud%z = z(1:cloud%nz + 1)
  end subroutine set_grid

  !> Sort x ascending (heap sort) and keep one copy of each value: x(1:n).
  pure subroutine sort_unique_exact(x, n)
    real(wp), intent(inout) :: x(:)
    integer, intent(out) :: n
    integer :: i, m, last
    real(wp) :: t
    m = size(x)
    do i = m/2, 1, -1
      call sift(x, i, m)
    end do
    do last = m, 2, -1
      t = x(1)
      x(1) = x(last)
      x(last) = t
      call sift(x, 1, last - 1)
    end do
    n = min(m, 1)
    do i = 2, m
      if (x(i) /= x(n)) then
        n = n + 1
        x(n) = x(i)
      end if
    end do
  end subroutine sort_unique_exact

  !> Restore the max-heap x(start:hi) below x(start).
  pure subroutine sift(x, start, hi)
    real(wp), intent(inout) :: x(:)
    integer, intent(in) :: start, hi
    integer :: root, child
    real(wp) :: v
    root = start
    v = x(root)
    do
      child = 2*root
      if (child > hi) exit
      if (child < hi) then
        if (x(child + 1) > x(child)) child = child + 1
      end if
      if (x(child) <= v) exit
      x(root) = x(child)
      root = child
    end do
    x(root) = v
  end subroutine sift

  !> Index of the value v in the sorted, distinct list x (v must be present).
  pure integer function locate(x, v) result(i)
    real(wp), intent(in) :: x(:), v
    i = first_not_below(x, v)
  end function locate

end module kumo_cloud_input
