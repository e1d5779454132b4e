! SPDX-License-Identifier: BSD-3-Clause
!> Cloud files in broadband runs: the cloud's optics per band of the k-distribution, put into
!> the atmosphere of each g-point (docs/broadband.md, "Cloud files"; docs/cloud-optics-bands.md).
!>
!> The fields stay as the file gives them (liquid water content and effective radius, and ice
!> water content and effective radius when the file has ice); what changes from band to band is
!> the table that turns them into optics:
!>
!> * liquid, `liquid_optics = 'mie'` (default): kumo's Mie tables averaged over each band with a
!>   source weighting (kumo_band_mie: the Planck function of the Sun's effective temperature in
!>   the shortwave, of 280 K in the longwave), with the full phase function of every table
!>   radius; the radii are those of &kumo_cloud (reff_min_um, reff_max_um, n_reff, geometric),
!>   the size distribution too. Computing them for all bands takes minutes (7 min for the 14
!>   shortwave bands and 40 radii up to 40 um), so they are kept in a file and reused while
!>   the request matches: &kumo_cloud mie_cache, or by default `default_cache` (beside the
!>   k-distribution);
!> * liquid, `liquid_optics = 'rrtmgp'`: RRTMGP's look-up table (Pincus, Mlawer and Delamere
!>   2019), Henyey-Greenstein phase functions with the table's asymmetry parameter;
!> * ice: RRTMGP's table for the roughness class `ice_roughness`, Henyey-Greenstein.
!>
!> A voxel whose radius lies between two table radii is the mixture of the two tabulated
!> populations that has that effective radius, with the blend of their phase functions, as in
!> monochromatic runs (kumo_cloud_scene); radii outside a table are clamped to its ends and
!> counted in a warning. Only the table radii's phase functions exist: n_band x n_radii of them.
module kumo_spectral_cloud
  use kumo_kinds, only: wp, i8
  use kumo_error, only: error_t, set_error, str
  use kumo_phase, only: phase_t, phase_from_table, new_phase_hg
  use kumo_mie, only: mie_table_t, dist_kind_from_name
  use kumo_band_mie, only: band_mie_t, band_mie_table, T_SUN_K, T_CLOUD_K
  use kumo_band_mie_file, only: band_mie_cached
  use kumo_band_cloud, only: band_cloud_t, band_cloud_check_bands, ICE_SMOOTH, ICE_MEDIUM, &
                             ICE_ROUGH
  use kumo_rrtmgp_cloud_file, only: read_rrtmgp_cloud_optics
  use kumo_cloud_input, only: cloud_input_t, cloud_request_t, CLOUD_WATER
  use kumo_cloud_share, only: read_cloud_on_root
  use kumo_kinds, only: vp
  use kumo_cloud_scene, only: mie_voxel, table_radii
  use kumo_atmosphere, only: atmosphere_t, atmosphere_put_layer, voxel_storage_i
  use, intrinsic :: iso_c_binding, only: c_ptr, c_f_pointer, c_intptr_t
  use kumo_bundle, only: bundle_t
  use kumo_parallel, only: par_is_root
  use kumo_config, only: cloud_cfg_t, spectral_cfg_t
  implicit none
  private
  public :: spectral_cloud_t, spectral_cloud_init, spectral_cloud_band, spectral_cloud_put, &
            spectral_cloud_place

  !> Nodes per band of the band-averaged Mie tables (kumo_band_mie: wide bands get more).
  integer, parameter :: MIE_NODES = 8
  !> Most bytes the optics of the voxels with water of every band may take to be kept between
  !> the visits of a band (24 bytes per voxel, component and band); beyond, they are formed at
  !> every visit.
  integer(i8), parameter :: KEEP_BYTES = 64_i8*1024_i8**2

  !> A cloud file's fields and its optics tables per band.
  type :: spectral_cloud_t
    type(cloud_input_t) :: liq                    !! lwc, reff (g m-3, um)
    type(cloud_input_t) :: ice                    !! iwc, reff_ice, when has_ice
    logical :: has_ice = .false.
    integer :: n_band = 0
    integer :: nx = 0, ny = 0, nz = 0             !! voxels of the cloud file
    integer :: nc3 = 1                            !! voxel components (species x planes)
    type(mie_table_t), allocatable :: liq_tab(:)  !! (n_band) liquid optics per band
    type(mie_table_t), allocatable :: ice_tab(:)  !! (n_band) ice optics per band
    integer, allocatable :: off_liq(:)            !! (n_band) phase functions before the band's
    integer, allocatable :: off_ice(:)
    !> the voxel components of band `band` as they are put into an atmosphere (nx, ny, nz,
    !> nc3): extinction [m-1], albedo, phase index, blend weight (spectral_cloud_band)
    integer :: band = 0
    !> the voxels with water (the only ones whose components differ from band to band): of
    !> layer k and component ic, the columns ix + (iy - 1) nx in wet_col(wet_ptr(l) + 1 :
    !> wet_ptr(l + 1)), l = k + (ic - 1) nz; found at the first band
    integer, allocatable :: wet_ptr(:), wet_col(:)
    !> every table's extinction per water is positive, so that the voxels with extinction are
    !> the voxels with water at every band (atmosphere_swap_background's same_clear)
    logical :: wet_exact = .false.
    !> the optics of the voxels with water of each band visited, in the order of wet_col
    !> (when they fit KEEP_BYTES): extinction and albedo (2, n_wet, n_band), phase index and
    !> blend weight (n_wet, n_band), and the band's counts of radii outside the tables (2,
    !> n_band; -1 until the band is kept)
    real(wp), allocatable :: kept_c(:, :, :)
    integer, allocatable :: kept_iph(:, :)
    real(vp), allocatable :: kept_wph(:, :)
    integer, allocatable :: kept_out(:, :)
    real(wp), pointer, contiguous :: cext(:, :, :, :) => null(), cssa(:, :, :, :) => null()
    integer, pointer, contiguous :: ciph(:, :, :, :) => null()
    real(vp), pointer, contiguous :: cwph(:, :, :, :) => null()
    !> where the four lie unless spectral_cloud_place put them in the caller's storage
    real(wp), allocatable :: c_own(:)
    integer, allocatable :: ciph_own(:)
    real(vp), allocatable :: cwph_own(:)
  end type spectral_cloud_t

contains

  !> Read the cloud file (on rank 0, shared with every rank, as monochromatic runs do), make the
  !> optics tables per band of `band_wavenumber` (2, n_band) [cm-1] on rank 0 and share them,
  !> and append the tables' phase functions to `phases`. `optics_path`: the RRTMGP cloud-optics
  !> file (read when liquid_optics = 'rrtmgp' or the file has ice).
  subroutine spectral_cloud_init(ccfg, scfg, optics_path, default_cache, band_wavenumber, &
                                 longwave, n_table, phases, sc, notes, warnings, error, &
                                 per_node)
    type(cloud_cfg_t), intent(in) :: ccfg
    type(spectral_cfg_t), intent(in) :: scfg
    character(len=*), intent(in) :: optics_path
    !> the band-averaged Mie tables' file when &kumo_cloud mie_cache is not given
    character(len=*), intent(in) :: default_cache
    real(wp), intent(in) :: band_wavenumber(:, :)
    logical, intent(in) :: longwave
    integer, intent(in) :: n_table
    type(phase_t), allocatable, intent(inout) :: phases(:)
    type(spectral_cloud_t), intent(out) :: sc
    character(len=:), allocatable, intent(out) :: notes, warnings
    type(error_t), allocatable, intent(out) :: error
    !> only the first rank of every node gets the fields (read_cloud_on_root per_node): it
    !> alone forms the voxels, in storage the node shares; the others hold the grid and tables
    logical, intent(in), optional :: per_node
    type(bundle_t) :: bt
    type(phase_t), allocatable :: more(:)
    integer :: nb, ib, i, nr
    logical :: hg_liq

    notes = ''
    warnings = ''
    nb = size(band_wavenumber, 2)
    sc%n_band = nb
    hg_liq = scfg%liquid_optics == 'rrtmgp'
    ! the fields: read on rank 0 and shared (read_cloud_on_root), one error on every rank
    call read_fields(error)
    if (allocated(error)) return
    if (allocated(sc%liq%warnings)) warnings = warnings//sc%liq%warnings
    if (sc%has_ice) then
      if (allocated(sc%ice%warnings)) warnings = warnings//sc%ice%warnings
    end if
    sc%nx = sc%liq%nx
    sc%ny = sc%liq%ny
    sc%nz = sc%liq%nz
    sc%nc3 = merge(2, 1, sc%liq%points)*merge(2, 1, sc%has_ice)

    ! the tables, made on rank 0 and shared
    if (par_is_root()) then
      call make_tables(error)
      if (.not. allocated(error)) call ship(.true.)
    end if
    call bt%share(error)
    if (allocated(error)) return
    call bt%get(notes)
    if (.not. par_is_root()) then
      allocate (sc%liq_tab(nb))
      if (sc%has_ice) allocate (sc%ice_tab(nb))
      call ship(.false.)
    end if

    ! phase functions: every band's liquid radii, then every band's ice sizes
    allocate (sc%off_liq(nb), sc%off_ice(nb))
    sc%off_ice = 0
    do ib = 1, nb
      sc%off_liq(ib) = size(phases)
      nr = size(sc%liq_tab(ib)%r_eff_um)
      allocate (more(nr))
      do i = 1, nr
        if (hg_liq) then
          more(i) = new_phase_hg(sc%liq_tab(ib)%g(i), error)
        else
          more(i) = phase_from_table(sc%liq_tab(ib)%angle_deg, sc%liq_tab(ib)%phase(:, i), &
                                     n_table, error)
        end if
        if (allocated(error)) then
          error%message = 'liquid optics of band '//str(ib)//', radius '// &
                          str(sc%liq_tab(ib)%r_eff_um(i))//' um: '//error%message
          return
        end if
      end do
      phases = [phases, more]
      deallocate (more)
    end do
    if (sc%has_ice) then
      do ib = 1, nb
        sc%off_ice(ib) = size(phases)
        nr = size(sc%ice_tab(ib)%r_eff_um)
        allocate (more(nr))
        do i = 1, nr
          more(i) = new_phase_hg(sc%ice_tab(ib)%g(i), error)
          if (allocated(error)) then
            error%message = 'ice optics of band '//str(ib)//': '//error%message
            return
          end if
        end do
        phases = [phases, more]
        deallocate (more)
      end do
    end if
    notes = 'cloud file '//ccfg%req%path//' ('//trim(sc%liq%format)//'): '//sc%liq%notes// &
            new_line('a')//notes
    sc%wet_exact = .true.
    do ib = 1, nb
      if (.not. all(sc%liq_tab(ib)%ext_per_lwc > 0.0_wp)) sc%wet_exact = .false.
      if (sc%has_ice) then
        if (.not. all(sc%ice_tab(ib)%ext_per_lwc > 0.0_wp)) sc%wet_exact = .false.
      end if
    end do

  contains

    !> The numbers of the tables into the bundle (`put`, rank 0, notes first) or out of it.
    subroutine ship(put)
      logical, intent(in) :: put
      integer :: jb
      if (put) call bt%put(notes)
      do jb = 1, nb
        call xfer(sc%liq_tab(jb)%r_eff_um, put)
        call xfer(sc%liq_tab(jb)%ext_per_lwc, put)
        call xfer(sc%liq_tab(jb)%ssa, put)
        call xfer(sc%liq_tab(jb)%g, put)
        if (.not. hg_liq) then
          call xfer(sc%liq_tab(jb)%angle_deg, put)
          if (put) then
            call bt%put(sc%liq_tab(jb)%phase)
          else
            call bt%get(sc%liq_tab(jb)%phase)
          end if
        end if
        if (sc%has_ice) then
          call xfer(sc%ice_tab(jb)%r_eff_um, put)
          call xfer(sc%ice_tab(jb)%ext_per_lwc, put)
          call xfer(sc%ice_tab(jb)%ssa, put)
          call xfer(sc%ice_tab(jb)%g, put)
        end if
      end do
    end subroutine ship

    subroutine xfer(x, put)
      real(wp), allocatable, intent(inout) :: x(:)
      logical, intent(in) :: put
      if (put) then
        call bt%put(x)
      else
        call bt%get(x)
      end if
    end subroutine xfer

    subroutine read_fields(err)
      type(error_t), allocatable, intent(out) :: err
      type(cloud_request_t) :: req
      req = ccfg%req
      req%temperature = .false.
      call read_cloud_on_root(req, sc%liq, err, part='liquid', per_node=per_node)
      if (allocated(err)) return
      if (sc%liq%content /= CLOUD_WATER) then
        call set_error(err, ccfg%req%path//': broadband runs compute the cloud''s optics '// &
                       'per band from liquid (and ice) water content and effective radius; '// &
                       'this file gives optical properties at one wavelength ('// &
                       trim(sc%liq%format)//'): use an LES/CRM or water-content file, or '// &
                       'a scene file of gray voxels (&kumo_atmosphere scene_file)')
        return
      end if
      sc%has_ice = sc%liq%has_ice
      if (sc%has_ice) then
        call read_cloud_on_root(req, sc%ice, err, part='ice', per_node=per_node)
        if (allocated(err)) return
      end if
    end subroutine read_fields

    !> Rank 0: the liquid (and ice) tables of every band; `notes` says how they were made.
    subroutine make_tables(err)
      type(error_t), allocatable, intent(out) :: err
      type(band_cloud_t) :: bc
      type(band_mie_t) :: bm
      character(len=:), allocatable :: action, cache
      real(wp), allocatable :: r(:)
      real(wp) :: t_src
      integer :: dist, n, j, rough
      allocate (sc%liq_tab(nb))
      if (sc%has_ice) allocate (sc%ice_tab(nb))
      if (hg_liq .or. sc%has_ice) then
        call read_rrtmgp_cloud_optics(optics_path, bc, err)
        if (.not. allocated(err)) call band_cloud_check_bands(bc, band_wavenumber, err)
        if (allocated(err)) then
          err%message = err%message//' (&kumo_spectral cloud_optics_file)'
          return
        end if
        notes = notes//'RRTMGP cloud optics '//optics_path
        if (bc%reordered) notes = notes//' (shortwave tables put into the k-distribution''s '// &
                                  'band order, docs/cloud-optics-bands.md)'
        notes = notes//new_line('a')
      end if
      if (hg_liq) then
        n = nint((bc%liq_hi - bc%liq_lo)/bc%liq_step) + 1
        do ib = 1, nb
          sc%liq_tab(ib)%r_eff_um = [(bc%liq_lo + (j - 1)*bc%liq_step, j=1, n)]
          ! m2 kg-1 -> m2 g-1: per g m-3 of water, like kumo's Mie tables
          sc%liq_tab(ib)%ext_per_lwc = 1.0e-3_wp*bc%liq_ext(:, ib)
          sc%liq_tab(ib)%ssa = bc%liq_ssa(:, ib)
          sc%liq_tab(ib)%g = bc%liq_asy(:, ib)
        end do
        notes = notes//'liquid: RRTMGP table, '//str(n)//' radii '//str(bc%liq_lo)//' ... '// &
                str(bc%liq_hi)//' um, Henyey-Greenstein phase functions'//new_line('a')
      else
        r = table_radii(ccfg)
        n = size(r)
        call dist_kind_from_name(ccfg%size_distribution, dist, err)
        if (allocated(err)) return
        t_src = T_SUN_K
        if (longwave) t_src = T_CLOUD_K
        cache = default_cache
        if (len_trim(ccfg%mie_cache) > 0) cache = trim(ccfg%mie_cache)
        call band_mie_cached(cache, band_wavenumber(1, :), band_wavenumber(2, :), t_src, dist, &
                             ccfg%v_eff, r, MIE_NODES, bm, action, err)
        if (allocated(err) .and. len_trim(ccfg%mie_cache) == 0 .and. bm%nband == nb) then
          ! computed, but the default place cannot keep it: the run goes on
          action = action//'; not kept: '//err%message
          deallocate (err)
        end if
        if (allocated(err)) return
        action = action//' ('//cache//')'
        do ib = 1, nb
          call band_mie_table(bm, ib, sc%liq_tab(ib), err)
          if (allocated(err)) return
        end do
        notes = notes//'liquid: band-averaged Mie tables ('//trim(ccfg%size_distribution)// &
                ' v_eff = '//str(ccfg%v_eff)//', '//str(n)//' radii '//str(r(1))//' ... '// &
                str(r(n))//' um, Planck weighting at '//str(t_src)//' K): '//action//new_line('a')
      end if
      if (sc%has_ice) then
        select case (scfg%ice_roughness)
        case ('smooth')
          rough = ICE_SMOOTH
        case ('rough')
          rough = ICE_ROUGH
        case default
          rough = ICE_MEDIUM
        end select
        n = nint((bc%ice_hi - bc%ice_lo)/bc%ice_step) + 1
        do ib = 1, nb
          ! the table's sizes are diameters: radii are half of them
          sc%ice_tab(ib)%r_eff_um = [(0.5_wp*(bc%ice_lo + (j - 1)*bc%ice_step), j=1, n)]
          sc%ice_tab(ib)%ext_per_lwc = 1.0e-3_wp*bc%ice_ext(:, ib, rough)
          sc%ice_tab(ib)%ssa = bc%ice_ssa(:, ib, rough)
          sc%ice_tab(ib)%g = bc%ice_asy(:, ib, rough)
        end do
        notes = notes//'ice: RRTMGP table ('//trim(scfg%ice_roughness)//' crystals), '// &
                str(n)//' effective radii '//str(0.5_wp*bc%ice_lo)//' ... '// &
                str(0.5_wp*bc%ice_hi)//' um, Henyey-Greenstein phase functions'//new_line('a')
      end if
    end subroutine make_tables
  end subroutine spectral_cloud_init

  !> The cloud's voxel components at band `band` (liquid planes first, then ice), kept in `sc`
  !> for spectral_cloud_put and for the g-points of the band that follow (their atmospheres
  !> differ only in the gas). `n_out_liq`, `n_out_ice`: voxel values whose radius lies outside
  !> the table (clamped).
  subroutine spectral_cloud_band(sc, band, n_out_liq, n_out_ice)
    type(spectral_cloud_t), intent(inout), target :: sc
    integer, intent(in) :: band
    integer, intent(out) :: n_out_liq, n_out_ice
    integer :: np, ip, ic, k, n, j, ix, iy
    integer(i8) :: nv
    real(wp) :: w
    logical :: keep, restore
    np = merge(2, 1, sc%liq%points)
    n_out_liq = 0
    n_out_ice = 0
    if (.not. associated(sc%cext)) then
      nv = int(sc%nx, i8)*sc%ny*sc%nz*sc%nc3
      allocate (sc%c_own(2*nv))
      sc%cext(1:sc%nx, 1:sc%ny, 1:sc%nz, 1:sc%nc3) => sc%c_own(1:nv)
      sc%cssa(1:sc%nx, 1:sc%ny, 1:sc%nz, 1:sc%nc3) => sc%c_own(nv + 1:2*nv)
    end if
    if (.not. associated(sc%ciph)) then
      nv = int(sc%nx, i8)*sc%ny*sc%nz*sc%nc3
      allocate (sc%ciph_own(nv), sc%cwph_own(nv))
      sc%ciph(1:sc%nx, 1:sc%ny, 1:sc%nz, 1:sc%nc3) => sc%ciph_own(1:nv)
      sc%cwph(1:sc%nx, 1:sc%ny, 1:sc%nz, 1:sc%nc3) => sc%cwph_own(1:nv)
    end if
    if (.not. allocated(sc%wet_ptr)) call first_band()
    keep = allocated(sc%kept_out)
    restore = .false.
    if (keep) restore = sc%kept_out(1, band) >= 0
    ! the voxels with water, component by component (liquid planes, then ice planes): formed
    ! from the band's table (and kept when they fit), or copied back from the kept ones
    do ic = 1, sc%nc3
      ip = merge(ic, ic - np, ic <= np)
      do k = 1, sc%nz
        do j = sc%wet_ptr(k + (ic - 1)*sc%nz) + 1, sc%wet_ptr(k + (ic - 1)*sc%nz + 1)
          iy = (sc%wet_col(j) - 1)/sc%nx + 1
          ix = sc%wet_col(j) - (iy - 1)*sc%nx
          if (restore) then
            sc%cext(ix, iy, k, ic) = sc%kept_c(1, j, band)
            sc%cssa(ix, iy, k, ic) = sc%kept_c(2, j, band)
            sc%ciph(ix, iy, k, ic) = sc%kept_iph(j, band)
            sc%cwph(ix, iy, k, ic) = sc%kept_wph(j, band)
            cycle
          end if
          if (ic <= np) then
            call mie_voxel(real(sc%liq%lwc(ix, iy, k + ip - 1)/np, wp), &
                           sc%liq%reff(ix, iy, k + ip - 1), sc%liq_tab(band), sc%off_liq(band), &
                           .false., sc%cext(ix, iy, k, ic), sc%cssa(ix, iy, k, ic), &
                           sc%ciph(ix, iy, k, ic), w, n_out_liq)
          else
            call mie_voxel(real(sc%ice%iwc(ix, iy, k + ip - 1)/np, wp), &
                           sc%ice%reff_ice(ix, iy, k + ip - 1), sc%ice_tab(band), &
                           sc%off_ice(band), .false., sc%cext(ix, iy, k, ic), &
                           sc%cssa(ix, iy, k, ic), sc%ciph(ix, iy, k, ic), w, n_out_ice)
          end if
          sc%cwph(ix, iy, k, ic) = real(w, vp)
          if (keep) then
            sc%kept_c(:, j, band) = [sc%cext(ix, iy, k, ic), sc%cssa(ix, iy, k, ic)]
            sc%kept_iph(j, band) = sc%ciph(ix, iy, k, ic)
            sc%kept_wph(j, band) = sc%cwph(ix, iy, k, ic)
          end if
        end do
      end do
    end do
    if (restore) then
      n_out_liq = sc%kept_out(1, band)
      n_out_ice = sc%kept_out(2, band)
    else if (keep) then
      sc%kept_out(:, band) = [n_out_liq, n_out_ice]
    end if
    sc%band = band
  contains
    !> The values of the voxels without water, the same at every band (no extinction, and the
    !> first band's first table: a voxel's component without extinction is never scattered
    !> by, but its phase index must be valid), and the lists of the voxels with water.
    subroutine first_band()
      integer :: ic, l
      allocate (sc%wet_ptr(sc%nz*sc%nc3 + 1), sc%wet_col(0))
      sc%wet_ptr(1) = 0
      n = 0
      do ic = 1, sc%nc3
        do k = 1, sc%nz
          l = k + (ic - 1)*sc%nz
          sc%cext(:, :, k, ic) = 0.0_wp
          sc%cwph(:, :, k, ic) = 0.0_vp
          if (ic <= np) then
            sc%cssa(:, :, k, ic) = sc%liq_tab(band)%ssa(1)
            sc%ciph(:, :, k, ic) = sc%off_liq(1) + 1
            call list_wet(sc%liq%lwc(:, :, k + ic - 1))
          else
            sc%cssa(:, :, k, ic) = sc%ice_tab(band)%ssa(1)
            sc%ciph(:, :, k, ic) = sc%off_ice(1) + 1
            call list_wet(sc%ice%iwc(:, :, k + ic - np - 1))
          end if
          sc%wet_ptr(l + 1) = n
        end do
      end do
      ! the bands' optics of these voxels are kept when they are few enough
      if (24_i8*n*sc%n_band <= KEEP_BYTES) then
        allocate (sc%kept_c(2, n, sc%n_band), sc%kept_iph(n, sc%n_band), &
                  sc%kept_wph(n, sc%n_band), sc%kept_out(2, sc%n_band))
        sc%kept_out = -1
      end if
    end subroutine first_band

    !> the columns of `amount` with water appended to wet_col (n of them so far)
    subroutine list_wet(amount)
      real(vp), intent(in) :: amount(:, :)
      integer, allocatable :: more(:)
      integer :: ix, iy
      do iy = 1, sc%ny
        do ix = 1, sc%nx
          if (amount(ix, iy) <= 0.0_vp) cycle
          if (n == size(sc%wet_col)) then
            allocate (more(max(1024, 2*n)))
            more(1:n) = sc%wet_col(1:n)
            call move_alloc(more, sc%wet_col)
          end if
          n = n + 1
          sc%wet_col(n) = ix + (iy - 1)*sc%nx
        end do
      end do
    end subroutine list_wet
  end subroutine spectral_cloud_band

  !> Place the voxel components (cext, cssa, ciph, cwph) in the caller's storage
  !> (kumo_atmosphere voxel_storage_i, e.g. one copy shared by the processes of a node), where
  !> the storage's writer forms them (spectral_cloud_band) and every process sharing it reads
  !> them (to swap a band's voxels, and the gas of its g-points, together). Every process
  !> sharing it calls this once, before the first band.
  subroutine spectral_cloud_place(sc, storage)
    type(spectral_cloud_t), intent(inout) :: sc
    procedure(voxel_storage_i) :: storage
    integer(i8) :: nv, nb_real, nb_int
    real(wp), pointer, contiguous :: words(:)
    integer, pointer, contiguous :: ints(:)
    real(vp), pointer, contiguous :: weights(:)
    type(c_ptr) :: base
    logical :: writer
    nv = int(sc%nx, i8)*sc%ny*sc%nz*sc%nc3
    nb_real = 2*nv*(storage_size(1.0_wp)/8)
    nb_int = nv*(storage_size(1)/8)
    ! extinction and albedo, then the phase indices, then the blend weights
    call storage(nb_real + nb_int + nv*(storage_size(1.0_vp)/8), base, writer)
    call c_f_pointer(base, words, [2*nv])
    sc%cext(1:sc%nx, 1:sc%ny, 1:sc%nz, 1:sc%nc3) => words(1:nv)
    sc%cssa(1:sc%nx, 1:sc%ny, 1:sc%nz, 1:sc%nc3) => words(nv + 1:2*nv)
    call c_f_pointer(transfer(transfer(base, 0_c_intptr_t) + nb_real, base), ints, [nv])
    sc%ciph(1:sc%nx, 1:sc%ny, 1:sc%nz, 1:sc%nc3) => ints(1:nv)
    call c_f_pointer(transfer(transfer(base, 0_c_intptr_t) + nb_real + nb_int, base), &
                     weights, [nv])
    sc%cwph(1:sc%nx, 1:sc%ny, 1:sc%nz, 1:sc%nc3) => weights(1:nv)
  end subroutine spectral_cloud_place

  !> Put the voxel components of the current band (spectral_cloud_band) into an atmosphere
  !> begun with the cloud file's grid, sc%nc3 voxel components and phase blends.
  subroutine spectral_cloud_put(sc, atm)
    type(spectral_cloud_t), intent(in) :: sc
    type(atmosphere_t), intent(inout) :: atm
    integer :: ic, k
    do ic = 1, sc%nc3
      do k = 1, sc%nz
        call atmosphere_put_layer(atm, ic, k, sc%cext(:, :, k, ic), sc%cssa(:, :, k, ic), &
                                  sc%ciph(:, :, k, ic), real(sc%cwph(:, :, k, ic), wp))
      end do
    end do
  end subroutine spectral_cloud_put

end module kumo_spectral_cloud
