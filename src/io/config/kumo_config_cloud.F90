! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_cloud: the cloud file, what it lacks, and how kumo computes its optics.
!>
!> The parsing and validation of this namelist group (read_cloud), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_cloud
  use kumo_config_base
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str, to_lower
  use kumo_math, only: within
  use kumo_mie, only: dist_kind_from_name, size_dist_validate
  use kumo_les_netcdf, only: LES_NAME_LEN
  use kumo_cloud_input, only: cloud_format_check
  use kumo_mcarats_files, only: is_ctl_path, mcarats_request_t
  implicit none
  private
  public :: read_cloud

contains

  !> &kumo_cloud: the cloud file, what it lacks, and how kumo computes its optics. The file's
  !> grid comes from `read_grid` here, so that the levels are known to the other groups.
  subroutine read_cloud(unit, present, nml_path, cfg, error, read_grid)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    character(len=*), intent(in) :: nml_path
    type(cloud_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    procedure(cloud_grid_reader), optional :: read_grid
    character(len=PATH_LEN) :: cloud_file, mie_cache, ice_optics_file, mcarats_phase_file
    character(len=16) :: cloud_format, size_distribution
    character(len=LES_NAME_LEN) :: les_lwc, les_reff, les_number, les_iwc, les_reff_ice, &
                                   les_temperature, les_pressure, les_air_density, les_x, les_y, &
                                   les_z, les_x_edges, les_y_edges, les_z_edges, les_vapour
    integer :: les_time_index, n_reff, ios, dist
    integer :: mcarats_np3d, mcarats_nkd, mcarats_mtprof, mcarats_idread, mcarats_ikd, &
               mcarats_nang, mcarats_npf
    real(wp) :: les_k_factor, droplet_number_cm3, v_eff, reff_min_um, reff_max_um
    logical :: les_z_edges_from_midpoints
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_cloud: '
    namelist /kumo_cloud/ cloud_file, cloud_format, les_time_index, les_lwc, les_reff, &
      les_number, les_iwc, les_reff_ice, les_temperature, les_pressure, les_air_density, &
      les_vapour, les_x, les_y, les_z, les_x_edges, les_y_edges, les_z_edges, les_k_factor, &
      les_z_edges_from_midpoints, droplet_number_cm3, size_distribution, v_eff, reff_min_um, &
      reff_max_um, n_reff, mie_cache, ice_optics_file, mcarats_np3d, mcarats_nkd, mcarats_mtprof, &
      mcarats_idread, mcarats_ikd, mcarats_phase_file, mcarats_nang, mcarats_npf
    if (.not. present) return
    cloud_file = ''
    cloud_format = 'les'
    les_time_index = -1
    les_lwc = ''
    les_reff = ''
    les_number = ''
    les_iwc = ''
    les_reff_ice = ''
    les_temperature = ''
    les_pressure = ''
    les_air_density = ''
    les_vapour = ''
    les_x = ''
    les_y = ''
    les_z = ''
    les_x_edges = ''
    les_y_edges = ''
    les_z_edges = ''
    les_k_factor = cfg%req%k_factor
    les_z_edges_from_midpoints = .false.
    droplet_number_cm3 = 0.0_wp
    size_distribution = cfg%size_distribution
    v_eff = cfg%v_eff
    reff_min_um = cfg%reff_min_um
    reff_max_um = cfg%reff_max_um
    n_reff = cfg%n_reff
    mie_cache = ''
    ice_optics_file = ''
    ! MCARaTS sizes: 0 (mtprof: -1) = not given, i.e. from the .ctl or MCARaTS's default
    mcarats_np3d = 0
    mcarats_nkd = 0
    mcarats_mtprof = -1
    mcarats_idread = 1
    mcarats_ikd = 1
    mcarats_phase_file = ''
    mcarats_nang = 0
    mcarats_npf = 0
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_cloud, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_cloud', present, ios, msg, error, probe)
    if (allocated(error)) return
    call cloud_format_check(cloud_format, cfg%req%format, error)
    if (allocated(error)) then
      error%message = '&kumo_cloud: '//error%message
      return
    end if
    call require(les_time_index >= 1 .or. les_time_index == -1, CTX, 'les_time_index', &
                 les_time_index, 'must be >= 1, or -1 for a file without a time dimension', error)
    call require(les_k_factor > 0.0_wp .and. les_k_factor <= 1.0_wp, CTX, 'les_k_factor', &
                 les_k_factor, 'must satisfy 0 < les_k_factor <= 1', error)
    call require(within(droplet_number_cm3, 0.0_wp, BIG), CTX, 'droplet_number_cm3', &
                 droplet_number_cm3, 'must be finite and >= 0 (0 = not given)', error)
    call require(n_reff >= 2 .and. n_reff <= 1000, CTX, 'n_reff', n_reff, &
                 'must be within 2..1000', error)
    call require(within(reff_min_um, 0.01_wp, 1000.0_wp) .and. &
                 within(reff_max_um, 0.01_wp, 1000.0_wp) .and. reff_max_um > reff_min_um, CTX, &
                 'reff_min_um', reff_min_um, 'and reff_max_um = '//str(reff_max_um)// &
                 ' must satisfy 0.01 <= reff_min_um < reff_max_um <= 1000 [um]', error)
    if (allocated(error)) return
    call dist_kind_from_name(size_distribution, dist, error)
    if (.not. allocated(error)) call size_dist_validate(dist, reff_min_um, v_eff, error)
    if (allocated(error)) then
      error%message = '&kumo_cloud: '//error%message
      return
    end if
    call mcarats_cloud_settings(cfg%req%format, cloud_file, mcarats_np3d, mcarats_nkd, &
                                mcarats_mtprof, mcarats_idread, mcarats_ikd, mcarats_phase_file, &
                                mcarats_nang, mcarats_npf, nml_path, cfg%req%mcarats, error)
    if (allocated(error)) return
    cfg%mcarats_phase_file = mcarats_phase_file
    if (len_trim(cloud_file) == 0) return   ! no cloud file: the group's settings are unused
    cfg%enabled = .true.
    cfg%file = cloud_file
    cfg%req%path = resolve_path(cloud_file, nml_path)
    cfg%req%time_index = les_time_index
    cfg%req%names%lwc = les_lwc
    cfg%req%names%reff = les_reff
    cfg%req%names%number = les_number
    cfg%req%names%iwc = les_iwc
    cfg%req%names%reff_ice = les_reff_ice
    cfg%req%names%temperature = les_temperature
    cfg%req%names%pressure = les_pressure
    cfg%req%names%air_density = les_air_density
    cfg%req%names%vapour = les_vapour
    cfg%req%names%x = les_x
    cfg%req%names%y = les_y
    cfg%req%names%z = les_z
    cfg%req%names%x_edges = les_x_edges
    cfg%req%names%y_edges = les_y_edges
    cfg%req%names%z_edges = les_z_edges
    cfg%req%k_factor = les_k_factor
    cfg%req%z_edges_from_midpoints = les_z_edges_from_midpoints
    cfg%req%droplet_number_cm3 = droplet_number_cm3
    cfg%size_distribution = to_lower(size_distribution)
    cfg%v_eff = v_eff
    cfg%reff_min_um = reff_min_um
    cfg%reff_max_um = reff_max_um
    cfg%n_reff = n_reff
    cfg%mie_cache = ''
    if (len_trim(mie_cache) > 0) cfg%mie_cache = resolve_path(mie_cache, nml_path)
    cfg%ice_optics_file = ''
    if (len_trim(ice_optics_file) > 0) cfg%ice_optics_file = resolve_path(ice_optics_file, &
                                                                          nml_path)
    call grid_of(cfg%req, cfg%grid, error, read_grid)
    if (allocated(error)) error%message = '&kumo_cloud: '//error%message
  contains
    !> Read one assignment of &kumo_cloud (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_cloud, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_cloud, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_cloud

  !> &kumo_cloud mcarats_*: checks, and the request for `from_mcarats`. They apply to
  !> cloud_format = 'mcarats' only. A binary atmosphere file takes the sizes not given from
  !> MCARaTS's defaults (Atm_np3d = 1, Atm_nkd = 1, Atm_mtprof = 0), as MCARaTS itself does; a
  !> `.ctl` gives them (sizes given must agree, checked when it is read). A binary phase file
  !> needs mcarats_nang and mcarats_npf; there is no default to fall back on.
  subroutine mcarats_cloud_settings(fmt, cloud_file, np3d, nkd, mtprof, idread, ikd, phase_file, &
                                    nang, npf, nml_path, req, error)
    character(len=*), intent(in) :: fmt, cloud_file, phase_file, nml_path
    integer, intent(in) :: np3d, nkd, mtprof, idread, ikd, nang, npf
    type(mcarats_request_t), intent(inout) :: req
    type(error_t), allocatable, intent(out) :: error
    character(len=*), parameter :: CTX = '&kumo_cloud: '
    logical :: atm_ctl, phase_ctl
    if (trim(fmt) /= 'mcarats') then
      if (np3d /= 0 .or. nkd /= 0 .or. mtprof /= -1 .or. idread /= 1 .or. ikd /= 1 .or. &
          len_trim(phase_file) > 0 .or. nang /= 0 .or. npf /= 0) then
        call set_error(error, CTX//'the mcarats_* settings apply to cloud_format = '// &
                       '''mcarats'' only (cloud_format is '''//trim(fmt)//''')')
      end if
      return
    end if
    if (np3d < 0 .or. nkd < 0 .or. npf < 0 .or. nang < 0) then
      call set_error(error, CTX//'mcarats_np3d = '//str(np3d)//', mcarats_nkd = '//str(nkd)// &
                     ', mcarats_nang = '//str(nang)//' and mcarats_npf = '//str(npf)// &
                     ' must be >= 0 (0 = not given)')
      return
    end if
    call require(mtprof >= -1 .and. mtprof <= 1, CTX, 'mcarats_mtprof', mtprof, &
                 'must be 0 (temperatures per layer), 1 (per level) or -1 (not given)', error)
    call require(idread >= 1, CTX, 'mcarats_idread', idread, 'must be >= 1', error)
    call require(ikd >= 1, CTX, 'mcarats_ikd', ikd, 'must be >= 1', error)
    call require(nang /= 1, CTX, 'mcarats_nang', nang, &
                 'must be >= 2 (angles per phase function)', error)
    if (allocated(error)) return
    atm_ctl = is_ctl_path(cloud_file)
    phase_ctl = is_ctl_path(phase_file)
    req%np3d = merge(np3d, -1, np3d > 0)
    req%nkd = merge(nkd, -1, nkd > 0)
    req%mtprof = mtprof
    req%nang = merge(nang, -1, nang > 0)
    req%npf = merge(npf, -1, npf > 0)
    if (.not. atm_ctl) then
      ! a binary file: MCARaTS's defaults for the sizes not given
      if (req%np3d < 0) req%np3d = 1
      if (req%nkd < 0) req%nkd = 1
      if (req%mtprof < 0) req%mtprof = 0
      if (ikd > req%nkd) then
        call set_error(error, CTX//'mcarats_ikd = '//str(ikd)//' must be within 1..'// &
                       'mcarats_nkd = '//str(req%nkd))
        return
      end if
    end if
    if (len_trim(phase_file) == 0) then
      if (nang /= 0 .or. npf /= 0) then
        call set_error(error, CTX//'mcarats_nang and mcarats_npf describe mcarats_phase_file, '// &
                       'which is not given')
        return
      end if
    else if (.not. phase_ctl .and. (nang == 0 .or. npf == 0)) then
      call set_error(error, CTX//'mcarats_phase_file '''//trim(phase_file)//''' is a binary '// &
                     'file: give its sizes mcarats_nang (angles, Sca_nangi) and mcarats_npf '// &
                     '(tables, Sca_npf), or name its .ctl')
      return
    end if
    req%idread = idread
    req%ikd = ikd
    req%phase_path = ''
    if (len_trim(phase_file) > 0) req%phase_path = resolve_path(phase_file, nml_path)
  end subroutine mcarats_cloud_settings
end module kumo_config_cloud
