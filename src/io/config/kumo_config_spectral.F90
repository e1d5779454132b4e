! SPDX-License-Identifier: BSD-3-Clause
!> &kumo_spectral: broadband runs.
!>
!> The parsing and validation of this namelist group (read_spectral), called by kumo_config's
!> read_config; the types and the helpers the groups share are in kumo_config_base.
module kumo_config_spectral
  use kumo_config_base
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str, to_lower
  use kumo_math, only: within
  use kumo_std_atmosphere, only: std_atmosphere_kind_from_name
  implicit none
  private
  public :: read_spectral, kdist_location

contains

  !> &kumo_spectral: broadband runs, shortwave or longwave as the k-distribution file is. The group's presence switches them on (spectral =
  !> .false. keeps them off). The gas profile is a standard atmosphere at the levels of
  !> &kumo_atmosphere (`profile`) or level pressures and temperatures given here; water vapour
  !> per layer is always given; ozone per layer optionally.
  subroutine read_spectral(unit, present, nml_path, nz, cfg, error)
    integer, intent(in) :: unit
    logical, intent(in) :: present
    character(len=*), intent(in) :: nml_path
    integer, intent(in) :: nz
    type(spectral_cfg_t), intent(inout) :: cfg
    type(error_t), allocatable, intent(out) :: error
    real(wp) :: p_levels(MAX_LAYERS + 1), t_levels(MAX_LAYERS + 1), p_layers(MAX_LAYERS), &
                t_layers(MAX_LAYERS), h2o_vmr(MAX_LAYERS), o3_vmr(MAX_LAYERS)
    real(wp) :: tsi, floor_share, t_surface
    integer, parameter :: MAX_GASES = 32
    character(len=16) :: gas_names(MAX_GASES)
    real(wp) :: gas_vmr(MAX_GASES)
    integer :: ng
    character(len=PATH_LEN) :: kdist_file, cloud_optics_file
    character(len=16) :: profile
    character(len=8) :: liquid_optics, ice_roughness
    character(len=16) :: gas_state
    integer :: gpoint
    logical :: spectral
    integer :: ios, kind, i
    character(len=512) :: msg
    character(len=*), parameter :: CTX = '&kumo_spectral: '
    type(error_t), allocatable :: err
    namelist /kumo_spectral/ spectral, kdist_file, profile, p_levels, t_levels, p_layers, &
      t_layers, h2o_vmr, o3_vmr, tsi, floor_share, t_surface, liquid_optics, cloud_optics_file, &
      ice_roughness, gas_state, gpoint, gas_names, gas_vmr
    spectral = present
    kdist_file = cfg%kdist_file
    profile = cfg%profile
    p_levels = UNSET
    t_levels = UNSET
    p_layers = UNSET
    t_layers = UNSET
    h2o_vmr = UNSET
    o3_vmr = UNSET
    tsi = cfg%tsi
    floor_share = cfg%floor_share
    t_surface = cfg%t_surface
    liquid_optics = cfg%liquid_optics
    cloud_optics_file = cfg%cloud_optics_file
    ice_roughness = cfg%ice_roughness
    gas_state = cfg%gas_state
    gpoint = cfg%gpoint
    gas_names = ''
    gas_vmr = UNSET
    rewind (unit)
    msg = ''
    read (unit, nml=kumo_spectral, iostat=ios, iomsg=msg)
    call check_read(unit, 'kumo_spectral', present, ios, msg, error, probe)
    if (allocated(error)) return
    cfg%enabled = spectral
    if (.not. spectral) return
    call require(len_trim(kdist_file) > 0, CTX, 'kdist_file', &
                 rule='is needed: an RRTMGP k-distribution, shortwave (rrtmgp-gas-sw-g112.nc or '// &
                 'rrtmgp-gas-sw-g224.nc) or longwave (rrtmgp-gas-lw-g128.nc or '// &
                 'rrtmgp-gas-lw-g256.nc); scripts/fetch-rrtmgp.sh fetches them', error=error)
    if (t_surface /= cfg%t_surface) call require(within(t_surface, SMALL, BIG), CTX, &
                                                 't_surface', t_surface, 'must be finite and '// &
                                                 '> 0 [K] (surface temperature, longwave)', error)
    call require(within(tsi, SMALL, BIG), CTX, 'tsi', tsi, &
                 'must be finite and > 0 [W m-2] (total solar irradiance)', error)
    call require(within(floor_share, 0.0_wp, nearest(1.0_wp, -1.0_wp)), CTX, 'floor_share', &
                 floor_share, 'must satisfy 0 <= floor_share < 1', error)
    call require(liquid_optics == 'mie' .or. liquid_optics == 'rrtmgp', CTX, 'liquid_optics', &
                 liquid_optics, 'must be ''mie'' (kumo''s band-averaged Mie tables) or '// &
                 '''rrtmgp'' (RRTMGP''s cloud-optics table)', error)
    call require(ice_roughness == 'smooth' .or. ice_roughness == 'medium' .or. &
                 ice_roughness == 'rough', CTX, 'ice_roughness', ice_roughness, 'must be '// &
                 '''smooth'', ''medium'' or ''rough'' (the ice-crystal surfaces of RRTMGP''s '// &
                 'ice optics)', error)
    call require(gas_state == 'cloud_file' .or. gas_state == 'profile', CTX, 'gas_state', &
                 gas_state, 'must be ''cloud_file'' (temperature, pressure and water vapour of '// &
                 'the &kumo_cloud file in its layers, where it has them) or ''profile''', error)
    call require(gpoint >= 0, CTX, 'gpoint', gpoint, 'must be 0 (every g-point) or the '// &
                 'index of one g-point of the k-distribution', error)
    if (allocated(error)) return
    if (len_trim(profile) > 0) then
      call std_atmosphere_kind_from_name(profile, kind, err)
      if (allocated(err)) then
        call set_error(error, CTX//'profile: '//err%message)
        return
      end if
      call require(count(p_levels /= UNSET) + count(t_levels /= UNSET) + &
                   count(p_layers /= UNSET) + count(t_layers /= UNSET) == 0, CTX, 'profile', &
                   profile, 'cannot be given with p_levels, t_levels, p_layers or t_layers: '// &
                   'a standard atmosphere or a sounding', error)
    else
      call level_values('p_levels', p_levels, nz + 1, 'pressures [Pa] (levels 0..nz)', &
                        SMALL, cfg%p_levels)
      call level_values('t_levels', t_levels, nz + 1, 'temperatures [K] (levels 0..nz)', &
                        SMALL, cfg%t_levels)
      if (allocated(error)) return
      do i = 2, nz + 1
        call require(cfg%p_levels(i) < cfg%p_levels(i - 1), CTX, 'p_levels('//str(i)//')', &
                     cfg%p_levels(i), 'must be below p_levels('//str(i - 1)//') = '// &
                     str(cfg%p_levels(i - 1))//' Pa: pressure falls from the surface up', error)
      end do
      if (count(p_layers /= UNSET) > 0) call level_values('p_layers', p_layers, nz, &
                                                         'pressures [Pa] (layers 1..nz)', SMALL, cfg%p_layers)
      if (count(t_layers /= UNSET) > 0) call level_values('t_layers', t_layers, nz, &
                                                         'temperatures [K] (layers 1..nz)', SMALL, cfg%t_layers)
      if (allocated(error)) return
      if (allocated(cfg%p_layers)) then
        do i = 1, nz
          call require(cfg%p_layers(i) <= cfg%p_levels(i) .and. &
                       cfg%p_layers(i) >= cfg%p_levels(i + 1), CTX, 'p_layers('//str(i)//')', &
                       cfg%p_layers(i), 'must lie between its levels '// &
                       str(cfg%p_levels(i))//' and '//str(cfg%p_levels(i + 1))//' Pa', error)
        end do
      end if
    end if
    call require(count(h2o_vmr /= UNSET) > 0, CTX, 'h2o_vmr', rule='is needed: the water '// &
                 'vapour of each layer 1..nz [mol/mol of dry air] (0 for a dry atmosphere)', &
                 error=error)
    if (allocated(error)) return
    call level_values('h2o_vmr', h2o_vmr, nz, 'volume mixing ratios (layers 1..nz)', 0.0_wp, &
                      cfg%h2o_vmr)
    if (count(o3_vmr /= UNSET) > 0) call level_values('o3_vmr', o3_vmr, nz, &
                                                     'volume mixing ratios (layers 1..nz)', 0.0_wp, cfg%o3_vmr)
    if (allocated(error)) return
    ! a volume mixing ratio is at most 1 mol/mol (RRTMGP's own bound): larger values are
    ! another unit (g/kg, ppmv), which would give the gas optics a column of pure vapour
    call at_most_one('h2o_vmr', cfg%h2o_vmr)
    if (allocated(cfg%o3_vmr)) call at_most_one('o3_vmr', cfg%o3_vmr)
    if (allocated(error)) return
    cfg%kdist_file = kdist_file
    ! where the run will read it (a bare name may be in the folder scripts/fetch-rrtmgp.sh
    ! fills), so that --check, the checkpoints' list of inputs and messages name that file
    cfg%kdist_path = kdist_location(kdist_file, resolve_path(kdist_file, nml_path))
    cfg%profile = profile
    cfg%tsi = tsi
    cfg%floor_share = floor_share
    cfg%t_surface = t_surface
    cfg%liquid_optics = liquid_optics
    cfg%ice_roughness = ice_roughness
    cfg%gas_state = gas_state
    cfg%gpoint = gpoint
    ! other gases at constant mixing ratios: names without gaps, one value each
    do i = 1, MAX_GASES
      gas_names(i) = to_lower(gas_names(i))
    end do
    ng = count(gas_names /= '')
    call require(all(gas_names(1:ng) /= '') .and. all(gas_names(ng + 1:) == ''), CTX, &
                 'gas_names', rule='must be given without gaps from gas_names(1)', error=error)
    call require(count(gas_vmr /= UNSET) == ng .and. all(gas_vmr(1:ng) /= UNSET), CTX, &
                 'gas_vmr', rule='must give one value for each of the '//str(ng)// &
                 ' gas_names, in the same order', error=error)
    do i = 1, ng
      call require(within(gas_vmr(i), 0.0_wp, 1.0_wp), CTX, 'gas_vmr('//str(i)//')', gas_vmr(i), &
                   'must be a volume mixing ratio between 0 and 1 [mol/mol of dry air]', error)
      call require(all(gas_names(i) /= [character(len=16) :: 'h2o', 'o3']), CTX, &
                   'gas_names('//str(i)//')', gas_names(i), 'is given per layer by '// &
                   trim(gas_names(i))//'_vmr, not as a constant', error)
      call require(count(gas_names(1:ng) == gas_names(i)) == 1, CTX, &
                   'gas_names('//str(i)//')', gas_names(i), 'is given twice', error)
    end do
    if (allocated(error)) return
    cfg%gas_names = gas_names(1:ng)
    cfg%gas_vmr = gas_vmr(1:ng)
    cfg%cloud_optics_file = cloud_optics_file
    if (len_trim(cloud_optics_file) > 0) cfg%cloud_optics_path = &
      kdist_location(cloud_optics_file, resolve_path(cloud_optics_file, nml_path))
  contains
    !> n values of `name`, without gaps, each finite and >= lo.
    subroutine level_values(name, given, n, what, lo, out)
      character(len=*), intent(in) :: name, what
      real(wp), intent(in) :: given(:)
      integer, intent(in) :: n
      real(wp), intent(in) :: lo
      real(wp), allocatable, intent(out) :: out(:)
      integer :: m, j
      if (allocated(error)) return
      m = count(given /= UNSET)
      if (m == n .and. any(given(n + 1:) /= UNSET)) then
        ! as many values as needed, but not at positions 1..n (e.g. a comment right after
        ! "name =" reads as an empty first value)
        call require(.false., CTX, name, rule='needs '//str(n)//' '//what//' at positions '// &
                     '1..'//str(n)//'; '//str(m)//' are given, the last at position '// &
                     str(findloc(given /= UNSET, .true., back=.true., dim=1))//' (an empty '// &
                     'value, e.g. a comment right after "'//name//' =", takes position 1)', &
                     error=error)
      else
        call require(m == n .and. all(given(n + 1:) == UNSET), CTX, name, rule='needs '// &
                     str(n)//' '//what//', '//str(m)//' given', error=error)
      end if
      do j = 1, min(m, n)
        call require(within(given(j), lo, BIG), CTX, name//'('//str(j)//')', given(j), &
                     'must be finite and >= '//str(lo), error)
      end do
      if (.not. allocated(error)) out = given(1:n)
    end subroutine level_values
    !> Each value of a volume mixing ratio profile at most 1 mol/mol; the error names the first
    !> that is not and the units it may have been given in.
    subroutine at_most_one(name, v)
      character(len=*), intent(in) :: name
      real(wp), intent(in) :: v(:)
      integer :: j
      if (allocated(error)) return
      j = findloc(v > 1.0_wp, .true., dim=1)
      if (j > 0) call require(.false., CTX, name//'('//str(j)//')', v(j), 'must be a volume '// &
                              'mixing ratio between 0 and 1 [mol/mol of dry air], not g/kg or '// &
                              'ppmv (largest value '//str(maxval(v))//')', error)
    end subroutine at_most_one
    !> Read one assignment of &kumo_spectral (or write the namelist), for check_read.
    subroutine probe(text, out_unit, ios, msg)
      character(len=*), intent(in) :: text
      integer, intent(in) :: out_unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
      if (out_unit /= 0) then
        write (out_unit, nml=kumo_spectral, iostat=ios, iomsg=msg)
      else
        read (text, nml=kumo_spectral, iostat=ios, iomsg=msg)
      end if
    end subroutine probe
  end subroutine read_spectral

  !> Where the k-distribution is: `path` (kdist_file resolved against the namelist's folder)
  !> if it exists; otherwise, for a bare file name, the folder scripts/fetch-rrtmgp.sh fills
  !> ($KUMO_DATA_DIR, else $XDG_CACHE_HOME/kumo/rrtmgp, else $HOME/.cache/kumo/rrtmgp) if the
  !> file is there; else `path` (whose reading then fails with the name the user gave).
  function kdist_location(name, path) result(loc)
    character(len=*), intent(in) :: name, path
    character(len=:), allocatable :: loc, dir
    logical :: there
    loc = path
    inquire (file=path, exist=there)
    if (there .or. index(name, '/') > 0) return
    dir = env_text('KUMO_DATA_DIR')
    if (len(dir) == 0) then
      dir = env_text('XDG_CACHE_HOME')
      if (len(dir) == 0) then
        dir = env_text('HOME')
        if (len(dir) == 0) return
        dir = dir//'/.cache'
      end if
      dir = dir//'/kumo/rrtmgp'
    end if
    inquire (file=dir//'/'//trim(name), exist=there)
    if (there) loc = dir//'/'//trim(name)
  end function kdist_location

  !> The value of an environment variable ('' if unset).
  function env_text(var) result(val)
    character(len=*), intent(in) :: var
    character(len=:), allocatable :: val
    integer :: n, st
    call get_environment_variable(var, length=n, status=st)
    if (st /= 0 .or. n == 0) then
      val = ''
      return
    end if
    allocate (character(len=n) :: val)
    call get_environment_variable(var, val)
  end function env_text
end module kumo_config_spectral
