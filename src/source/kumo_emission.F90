! SPDX-License-Identifier: BSD-3-Clause
!> Thermal emission as a source of photons (seed text sections 3.2.4 b, 3.8, 3.9): every
!> absorbing cell, the surface and the top of the domain emit, by Kirchhoff's law, and in a run
!> with the sun too the solar beam is one more entry of the same table.
!>
!> **Planck source.** B is a radiance (W m-2 sr-1 for a band; per unit wavelength or wavenumber
!> for a single one), given at the levels and, optionally, per voxel of the 3-D region. Inside a
!> layer without voxel values it varies linearly in optical depth between the level values
!> (DISORT's convention; in a homogeneous layer, linearly in height), which keeps optically thick
!> layers right. The surface emits eps B_s, with eps = 1 - albedo (Lambert) or the directional
!> emissivity 1 - alpha(mu) (BRDF), and the top emits an isotropic downward radiance B_top.
!>
!> **One table, stratified.** Entry i has the power P_i per unit domain area [W m-2]: the sun
!> mu0 F0, the top pi B_top, the surface pi <eps> B_s, a 1-D layer 4 pi k_a dz <B>, a voxel
!> 4 pi k_a dz <B>/ncol. Photon j of a batch of n takes the entry holding u_j = (j - 1 + U)/n on
!> the cumulative table (systematic sampling: every entry gets floor or ceil of n q_i photons),
!> so photons go where the energy is. The probabilities are q_i = (1 - f) P_i/P + f C_i/C over
!> the emitting cells, with C_i = 4 pi k_a dz their emission per unit Planck radiance: the
!> fraction f (`emission_floor`) keeps cold cells sampled, which the net-exchange heating
!> estimator below needs. A photon carries the weight (P_i/P)/q_i in units of P, the total power
!> per unit area: every tally times P is in W m-2.
!>
!> **Heating rates by net exchange.** The heating of a cell is absorbed minus emitted power, in
!> optically thick cells a small difference of two large numbers. kumo scores it by reciprocity
!> (the emission-based reciprocity method, ERM, of Tesse et al. 2002, and the net-exchange
!> formulation of Green 1967 and Cherkaoui et al. 1996): the power emitted at r and absorbed at r'
!> is G(r, r') B(r), the reverse G(r, r') B(r'), so a photon emitted at r whose weight dw is
!> absorbed at r' (or escapes through the top, B = B_top, or is absorbed by the surface, B = B_s)
!> adds dw (B(r')/B(r) - 1) to the net power of the cell it came from. Photons absorbed where
!> they were emitted, and every exchange between cells at the same temperature, add nothing:
!> thick cells and isothermal regions get their net power without the noise of the two large
!> terms. A cell that does not emit (B = 0) has no photons of its own; its net power is what it
!> absorbs, scored directly. Solar photons add what they deposit, where they deposit it.
!>
!> **Escape sampling (optional).** In an optically thick layer almost all of the emission is
!> absorbed again inside the layer, where it adds nothing to the net power or to any flux
!> between layers. With `escape_sampling` the table draws the 1-D layers in proportion to the
!> power that leaves them, 4 pi <B> (1/2 - E_3(tau)) for absorption optical depth tau (exact for
!> B linear in optical depth; it tends to the emission 4 pi tau <B> in thin layers and to
!> 2 pi <B> in opaque ones), and places a photon in a layer with tau > 1 near its faces: optical
!> depth t from the bottom with density q(t) = (e^-t + e^-(tau - t)) / (2 (1 - e^-tau)) instead
!> of the emission's p(t) = B(t) / (tau <B>), the weight multiplied by p(t)/q(t); the floor share
!> is then spread evenly over the emitting layers instead of by capacity. All keep every
!> estimate unbiased; they remove the cost of photons that never leave their layer (broadband
!> longwave runs, where most g-points are opaque). With it, the net power of an optically thin
!> 1-D layer (tau < 1) is its absorbed power, scored from every photon that deposits energy in
!> it (smooth: with absorbing layers crossed without collisions every crossing photon
!> deposits), minus its emission, exact (`by_abs`); net exchange keeps the thick layers. The
!> two estimators may be mixed cell by cell: a cell's net power comes from its own mode only
!> (net exchange: the scores of its own photons, which cover both directions of every
!> exchange by reciprocity; absorbed minus emitted: what every photon deposits in it). The
!> exchange of a thick layer with itself sums to zero and is not scored. Without escape
!> sampling every emitting cell uses net exchange, as above.
module kumo_emission
  use, intrinsic :: iso_c_binding, only: c_ptr, c_f_pointer
  use kumo_kinds, only: wp, vp, i8
  use kumo_constants, only: PI, FOUR_PI
  use kumo_error, only: error_t, set_error, str
  use kumo_rng, only: rng_t, rng_uniform, sample_azimuth
  use kumo_math, only: UZ_MIN, gauss_legendre01
  use kumo_atmosphere, only: atmosphere_t, LAYER_3D, voxel_storage_i, voxel_sync_i, voxel_ext, &
                             voxel_omg, voxel_layer
  use kumo_surface, only: surface_t
  use kumo_brdf, only: brdf_albedo
  use kumo_photon, only: photon_t
  use kumo_planck, only: spectral_band_t
  use kumo_expint, only: expint_e
  implicit none
  private
  public :: emission_t, emission_init, emission_entry, emission_launch, emission_weight, &
            emission_b_point, emission_b_surface, &
            emission_b_segment, emission_surface_eps, emission_voxel_power, emission_bind, &
            emission_voxel_power_add, emission_detach
  public :: EMIT_SOLAR, EMIT_TOP, EMIT_SURFACE, EMIT_LAYER, EMIT_VOXEL
  public :: voxel_abs_t, voxel_abs_init

  !> Kinds of table entries (and of a photon's source).
  integer, parameter :: EMIT_SOLAR = 0, EMIT_TOP = 1, EMIT_SURFACE = 2, EMIT_LAYER = 3, &
                        EMIT_VOXEL = 4

  !> The absorption coefficients of the voxels of a 3-D region as two parts: one that every
  !> voxel of a layer has (its gas and other background, given with each table) and that of
  !> the voxel components, kc = sum over the components of ext (1 - ssa), read from their
  !> arrays (a cloud's optics in one band of a broadband run: the same for every g-point of
  !> the band). `kc_blk` holds kc summed over each run of VA_RUN voxels of a row, `kc_row` the
  !> sums of each row's runs, both formed once by voxel_abs_init (and checked there: `bad`).
  type :: voxel_abs_t
    !> (nx, ny, nf, nc) extinction [m-1] and albedo of the voxel components
    real(wp), pointer, contiguous :: cext(:, :, :, :) => null(), cssa(:, :, :, :) => null()
    integer :: koff = 0                    !! voxel layer kr has component layer kr + koff
    real(wp), allocatable :: kc_blk(:, :, :)  !! (nrun, ny, n3) kc summed over each run [m-1]
    real(wp), allocatable :: kc_row(:, :)     !! (ny, n3) sum(kc_blk(:, iy, kr)) [m-1]
    logical :: bad = .false.                  !! some kc_blk is negative or NaN
  end type voxel_abs_t

  !> Voxels of a row summed together in voxel_abs_t kc_blk: a photon drawn for a layer looks at
  !> about nx / VA_RUN run sums and VA_RUN voxels of its row instead of nx / 2 voxels.
  integer, parameter :: VA_RUN = 32

  !> The emission table of a scene and the Planck values the photon loop reads.
  type :: emission_t
    logical :: on = .false.                !! thermal emission is a source
    real(wp) :: power = 0.0_wp             !! P: total source power per unit area [W m-2]
    real(wp) :: solar_power = 0.0_wp       !! mu0 F0 of the sun in the same run (0: none)
    real(wp), allocatable :: b_lev(:)      !! (0:nz) Planck radiance at the levels
    !> (nz) Planck radiance at the bottom and top of each 1-D layer: the level values, or the
    !> layer's own (RRTMGP g-points: a level's value carries the Planck fraction of the layer)
    real(wp), allocatable :: b_bot(:), b_top_lay(:)
    !> (nx, ny, n3) per voxel, if given (has_b3); see below for the table's storage
    real(wp), pointer, contiguous :: b3(:, :, :) => null()
    real(wp) :: b_sfc = 0.0_wp             !! Planck radiance of the surface temperature
    real(wp) :: b_top = 0.0_wp             !! isotropic downward radiance at the top
    real(wp) :: eps_mean = 1.0_wp          !! surface emissivity, mean over the domain
    !> surface Planck radiance per pixel of a surface temperature map (nxt, nyt) over the domain
    !> (allocated only for a map), and the domain mean of eps B (hemispherical eps)
    real(wp), allocatable :: b_sfc_map(:, :)
    real(wp) :: inv_dxt = 1.0_wp, inv_dyt = 1.0_wp
    real(wp) :: eps_b_mean = 0.0_wp
    real(wp), allocatable :: eps_h(:)      !! hemispherical emissivity per BRDF class
    real(wp) :: floor = 0.0_wp             !! share f of the photons spread by capacity
    integer :: nz = 0, ncol = 1, n3 = 0
    integer :: e_lay = 3                   !! entry of layer k: e_lay + k
    integer :: e_vox = 0                   !! entry of voxel v (1 .. ncol*n3): e_vox + v
    integer :: n_ent = 0
    real(wp), pointer, contiguous :: cdf(:) => null()    !! (0:n_ent) cumulative probabilities q
    real(wp), pointer, contiguous :: ratio(:) => null()  !! (n_ent) launch weight (P_i/P)/q_i
    real(wp), allocatable :: emit_layer(:) !! (nz) emitted power per unit area [W m-2]
    real(wp), allocatable :: emit_vox(:)   !! (ncol*n3) per unit column area [W m-2]
    real(wp) :: emit_sfc = 0.0_wp          !! emitted by the surface [W m-2]
    real(wp) :: emit_top = 0.0_wp          !! entering at the top, pi B_top [W m-2]
    logical :: has_band = .false.          !! the spectral interval is known (temperatures
                                           !! given): brightness temperatures can be formed
    type(spectral_band_t) :: band
    !> units of the Planck radiances (the band's, per um for a single wavelength) and the
    !> factor that turns them into the band's own units (kumo_planck)
    character(len=24) :: radiance_units = 'W m-2 sr-1'
    character(len=24) :: flux_units = 'W m-2'
    real(wp) :: to_band_units = 1.0_wp
    integer :: iph_iso = 0                 !! isotropic phase function (local estimates of
                                           !! emission by cells); 0: no radiances
    logical :: escape = .false.            !! escape sampling of the 1-D layers (above)
    real(wp), allocatable :: tau_lay(:)    !! (nz) absorption optical depth of the 1-D layers
    !> (nz) 1-D layers whose net power is scored as absorbed minus emitted (exact) rather than
    !> by net exchange (with escape sampling: the optically thin ones, tau < 1)
    logical, allocatable :: by_abs(:)
    logical :: any_abs = .false.
    logical :: has_b3 = .false.            !! Planck radiances per voxel are given (b3)
    real(wp) :: cdf_sun = 0.0_wp           !! cdf(1): the sun's share of the photons
    ! Where the table lives. The photon loop reads b3, cdf and ratio through pointers, to
    ! the arrays below that this table owns (emission_init points them there; after a copy of
    ! the table they still point to the original's, until emission_bind), or, with
    ! emission_init's `storage` (e.g. one copy shared by the processes of a node), into the
    ! caller's storage (`on_node`), which also holds emit_vox_node instead of emit_vox and
    ! whose writer alone formed the values.
    real(wp), allocatable :: b3_own(:, :, :), cdf_own(:), ratio_own(:)
    logical :: on_node = .false.           !! the table lives in the caller's storage
    logical :: table_writer = .true.       !! this process formed the table's values
    real(wp), pointer, contiguous :: emit_vox_node(:) => null()
    integer(i8) :: table_bytes_own = 0_i8       !! bytes of table and voxel arrays allocated here
    integer(i8) :: table_bytes_borrowed = 0_i8  !! bytes of them in the caller's storage
    !> Voxels drawn layer by layer (emission_init's `voxel_abs`): the table has one entry per
    !> layer of the 3-D region instead of one per voxel, and a photon of a layer's entry takes a
    !> row of it by `row_cum`, the cumulative sums over the rows of nx kb + kc, and a voxel of
    !> the row in proportion to kb + kc (kumo_emission emission_launch).
    logical :: layered = .false.
    real(wp), allocatable :: kb3(:)        !! (n3) absorption every voxel of the layer has [m-1]
    real(wp), allocatable :: row_cum(:, :) !! (0:ny, n3)
    real(wp), allocatable :: kc_blk(:, :, :)  !! voxel_abs_t kc_blk
    real(wp), pointer, contiguous :: cext(:, :, :, :) => null(), cssa(:, :, :, :) => null()
    integer :: koff = 0
  end type emission_t

contains

  !> Build the emission table. `b_lev(0:nz)` Planck radiances at the levels, `b_sfc` of the
  !> surface, `b_top` the isotropic radiance entering at the top, optional `b3` per voxel of
  !> the 3-D region, `solar_power` = mu0 F0 of the sun in the same run (0: thermal alone),
  !> `floor` the share of photons spread over the emitting cells by capacity.
  !> With `storage` and `sync` the per-voxel arrays and the table lie in the caller's storage
  !> (kumo_atmosphere voxel_storage_i): its writer alone forms them, with its work arrays; every
  !> process then calls `sync` and takes the totals from the same storage. Every process sharing
  !> it calls this with the same arguments, but for `b3` when `b3_by_writer` = .true.: the
  !> voxels have Planck radiances, which the storage's writer alone passes (and checks: a bad
  !> `b3` there is every process's error); the others pass none and read the writer's copy.
  !> Without `storage` the flag is refused.
  !> With `voxel_abs` and `layer_abs` (both or neither; not with `b3` nor `storage`) the voxels'
  !> absorption coefficients are layer_abs(kr) + kc of `voxel_abs` (to the rounding of the
  !> voxel arrays, which set the photons' weights: emission_launch), and the table draws the
  !> voxels layer by layer (emission_t layered): forming it costs no work per voxel, so that a
  !> broadband run's g-point switch does not sweep the voxels for its table.
  subroutine emission_init(em, atm, sfc, b_lev, b_sfc, b_top, solar_power, floor, error, b3, &
                           b_sfc_map, b_layer_bottom, b_layer_top, escape_sampling, storage, &
                           sync, b3_by_writer, voxel_abs, layer_abs)
    type(emission_t), intent(out), target :: em
    type(atmosphere_t), intent(in) :: atm
    type(surface_t), intent(in) :: sfc
    real(wp), intent(in) :: b_lev(0:), b_sfc, b_top, solar_power, floor
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: b3(:, :, :)
    !> Planck radiance of each pixel of a surface temperature map (nxt, nyt) over the domain,
    !> instead of the uniform b_sfc
    real(wp), intent(in), optional :: b_sfc_map(:, :)
    !> (nz) each layer's own Planck radiance at its bottom and top, instead of the level values
    !> (both or neither)
    real(wp), intent(in), optional :: b_layer_bottom(:), b_layer_top(:)
    !> draw the 1-D layers by the power that leaves them, photons near the faces (above)
    logical, intent(in), optional :: escape_sampling
    procedure(voxel_storage_i), optional :: storage  !! the caller's storage for the table
    procedure(voxel_sync_i), optional :: sync        !! with `storage`
    !> with `storage`: the voxel Planck radiances are the writer's alone (above; .false.)
    logical, intent(in), optional :: b3_by_writer
    type(voxel_abs_t), intent(in), optional :: voxel_abs   !! the voxel components' part
    real(wp), intent(in), optional :: layer_abs(:)         !! (n3) the layers' part [m-1]
    real(wp), allocatable :: pw_lay(:), cap_lay(:)
    real(wp), pointer, contiguous :: words(:)
    real(wp) :: dz, ka, ptot
    integer(i8) :: nv, nw
    integer :: k, nz, ncol, kr, iy
    type(c_ptr) :: base
    logical :: by_writer
    character(len=:), allocatable :: b3_fault

    nz = atm%nz
    ncol = atm%nx*atm%ny
    if (size(b_lev) /= nz + 1) then
      call set_error(error, 'thermal emission: '//str(size(b_lev))//' level Planck values for '// &
                     str(nz + 1)//' levels')
      return
    end if
    if (any(.not. (b_lev >= 0.0_wp)) .or. .not. (b_sfc >= 0.0_wp) .or. .not. (b_top >= 0.0_wp)) then
      call set_error(error, 'thermal emission: Planck radiances must be finite and >= 0')
      return
    end if
    if (.not. (floor >= 0.0_wp .and. floor < 1.0_wp)) then
      call set_error(error, 'thermal emission: emission_floor = '//str(floor)// &
                     ' must satisfy 0 <= emission_floor < 1')
      return
    end if
    em%on = .true.
    em%nz = nz
    em%ncol = ncol
    em%n3 = atm%n3
    em%b_lev = b_lev
    if (present(b_layer_bottom) .neqv. present(b_layer_top)) then
      call set_error(error, 'thermal emission: layer Planck values need both the bottom and '// &
                     'the top of each layer')
      return
    end if
    if (present(b_layer_bottom)) then
      if (size(b_layer_bottom) /= nz .or. size(b_layer_top) /= nz) then
        call set_error(error, 'thermal emission: '//str(size(b_layer_bottom))//' and '// &
                       str(size(b_layer_top))//' layer Planck values for '//str(nz)//' layers')
        return
      end if
      if (any(.not. (b_layer_bottom >= 0.0_wp)) .or. any(.not. (b_layer_top >= 0.0_wp))) then
        call set_error(error, 'thermal emission: Planck radiances must be finite and >= 0')
        return
      end if
      em%b_bot = b_layer_bottom
      em%b_top_lay = b_layer_top
    else
      em%b_bot = b_lev(0:nz - 1)
      em%b_top_lay = b_lev(1:nz)
    end if
    em%b_sfc = b_sfc
    em%b_top = b_top
    em%floor = floor
    em%solar_power = solar_power
    by_writer = .false.
    if (present(b3_by_writer)) by_writer = b3_by_writer
    if (by_writer .and. .not. present(storage)) then
      call set_error(error, 'thermal emission: b3_by_writer needs the caller''s storage')
      return
    end if
    em%has_b3 = present(b3) .or. by_writer
    ! a fault of b3: an error here, or, when the writer alone has b3, after the storage is
    ! taken, so that every process learns it (below)
    b3_fault = ''
    if (present(b3)) then
      if (any(shape(b3) /= [atm%nx, atm%ny, atm%n3])) then
        b3_fault = 'thermal emission: voxel Planck values have shape ('// &
                   str(size(b3, 1))//','//str(size(b3, 2))//','//str(size(b3, 3))// &
                   '), the 3-D region ('//str(atm%nx)//','//str(atm%ny)//','//str(atm%n3)//')'
      else if (any(.not. (b3 >= 0.0_wp))) then
        b3_fault = 'thermal emission: voxel Planck radiances must be finite and >= 0'
      end if
    else if (by_writer) then
      b3_fault = 'thermal emission: the writer of the table has no voxel Planck radiances (b3)'
    end if
    if (len(b3_fault) > 0 .and. .not. by_writer) then
      call set_error(error, b3_fault)
      return
    end if
    call surface_emissivity(em, sfc)
    em%eps_b_mean = em%eps_mean*b_sfc
    if (present(b_sfc_map)) then
      if (any(.not. (b_sfc_map >= 0.0_wp)) .or. size(b_sfc_map) == 0) then
        call set_error(error, 'thermal emission: surface Planck radiances must be finite and >= 0')
        return
      end if
      em%b_sfc_map = b_sfc_map
      em%inv_dxt = size(b_sfc_map, 1)/atm%lx
      em%inv_dyt = size(b_sfc_map, 2)/atm%ly
      em%eps_b_mean = mean_eps_b(sfc, em%eps_h, b_sfc_map, atm%lx, atm%ly)
    end if

    if (present(voxel_abs) .neqv. present(layer_abs)) then
      call set_error(error, 'thermal emission: voxels drawn by layer need both parts of their '// &
                     'absorption')
      return
    end if
    if (present(voxel_abs)) then
      if (em%has_b3 .or. present(storage)) then
        call set_error(error, 'thermal emission: voxels drawn by layer take neither voxel '// &
                       'Planck radiances nor the caller''s storage')
        return
      end if
      if (size(layer_abs) /= atm%n3 .or. .not. allocated(voxel_abs%kc_blk) .or. &
          .not. allocated(voxel_abs%kc_row)) then
        call set_error(error, 'thermal emission: the absorption of '//str(size(layer_abs))// &
                       ' layers given for a 3-D region of '//str(atm%n3))
        return
      end if
      if (any(shape(voxel_abs%kc_blk) /= [(atm%nx + VA_RUN - 1)/VA_RUN, atm%ny, atm%n3])) then
        call set_error(error, 'thermal emission: the voxel components'' absorption is not '// &
                       'that of the 3-D region')
        return
      end if
      if (any(.not. (layer_abs >= 0.0_wp)) .or. voxel_abs%bad) then
        call set_error(error, 'thermal emission: absorption coefficients must be finite and >= 0')
        return
      end if
      em%layered = .true.
      em%kb3 = layer_abs
      em%cext => voxel_abs%cext
      em%cssa => voxel_abs%cssa
      em%koff = voxel_abs%koff
      em%kc_blk = voxel_abs%kc_blk
      allocate (em%row_cum(0:atm%ny, atm%n3))
      do kr = 1, atm%n3
        em%row_cum(0, kr) = 0.0_wp
        do iy = 1, atm%ny
          em%row_cum(iy, kr) = em%row_cum(iy - 1, kr) + (atm%nx*layer_abs(kr) + &
                               voxel_abs%kc_row(iy, kr))
        end do
      end do
    end if

    em%e_lay = 3
    em%e_vox = em%e_lay + nz
    if (em%layered) then
      em%n_ent = em%e_vox + atm%n3
    else
      em%n_ent = em%e_vox + ncol*atm%n3
    end if
    ! the 1-D layers (small: every process forms them)
    allocate (em%emit_layer(nz), em%tau_lay(nz), em%by_abs(nz), pw_lay(nz), cap_lay(nz))
    em%tau_lay = 0.0_wp
    em%by_abs = .false.
    if (present(escape_sampling)) em%escape = escape_sampling
    pw_lay = 0.0_wp
    cap_lay = 0.0_wp
    do k = 1, nz
      if (atm%layer_class(k) == LAYER_3D) cycle
      dz = atm%z(k) - atm%z(k - 1)
      ka = atm%ext1(k)*(1.0_wp - atm%omg1(k))
      cap_lay(k) = FOUR_PI*ka*dz
      pw_lay(k) = cap_lay(k)*0.5_wp*(em%b_bot(k) + em%b_top_lay(k))
      em%tau_lay(k) = ka*dz
    end do
    em%emit_layer = pw_lay
    em%emit_sfc = PI*em%eps_b_mean
    em%emit_top = PI*b_top
    if (em%escape) then
      do k = 1, nz
        em%by_abs(k) = atm%layer_class(k) /= LAYER_3D .and. em%tau_lay(k) < 1.0_wp .and. &
                       pw_lay(k) > 0.0_wp
      end do
      em%any_abs = any(em%by_abs)
    end if

    ! the table and the per-voxel arrays: here, or in the caller's storage (a header of the
    ! total power and the layers' emission first, which the other processes read)
    nv = int(ncol, i8)*atm%n3
    if (em%layered) nv = 0_i8     ! no per-voxel arrays (emission_voxel_power forms the powers)
    if (.not. present(storage)) then
      allocate (em%cdf_own(0:em%n_ent), em%ratio_own(em%n_ent), em%emit_vox(nv))
      if (em%has_b3) em%b3_own = b3
      em%table_bytes_own = (2*int(em%n_ent, i8) + 1 + merge(2, 1, em%has_b3)*nv)* &
                           (storage_size(1.0_wp)/8)
      if (em%layered) em%table_bytes_own = em%table_bytes_own + &
                                           storage_size(1.0_wp)/8*size(em%row_cum, kind=i8)
      call emission_bind(em)
      call fill_table(em%cdf, em%ratio, em%emit_vox, ptot)
    else
      nw = 1 + nz + 2*int(em%n_ent, i8) + 1 + merge(2, 1, em%has_b3)*nv
      call storage(nw*(storage_size(1.0_wp)/8), base, em%table_writer)
      em%on_node = .true.
      em%table_bytes_borrowed = nw*(storage_size(1.0_wp)/8)
      call c_f_pointer(base, words, [nw])
      em%cdf(0:em%n_ent) => words(nz + 2:nz + 2 + em%n_ent)
      em%ratio(1:em%n_ent) => words(nz + 3 + em%n_ent:nz + 2 + 2*em%n_ent)
      em%emit_vox_node(1:nv) => words(nz + 3 + 2*em%n_ent:nz + 2 + 2*em%n_ent + nv)
      if (em%has_b3) em%b3(1:atm%nx, 1:atm%ny, 1:atm%n3) => words(nw - nv + 1:nw)
      if (em%table_writer .and. len(b3_fault) > 0) then
        ! b3_by_writer and the writer's b3 is missing or bad: a total of -1 tells the others
        words(1) = -1.0_wp
      else if (em%table_writer) then
        if (em%has_b3) em%b3 = b3
        call fill_table(em%cdf, em%ratio, em%emit_vox_node, ptot)
        words(1) = ptot
        words(2:nz + 1) = em%emit_layer
      end if
      if (present(sync)) call sync()
      ptot = words(1)
      if (ptot < 0.0_wp) then
        if (em%table_writer) then
          call set_error(error, b3_fault)
        else
          call set_error(error, 'thermal emission: the voxel Planck radiances of the writer '// &
                         'of the shared table are missing or not finite and >= 0')
        end if
        return
      end if
      em%emit_layer = words(2:nz + 1)
    end if
    if (.not. (ptot > 0.0_wp)) then
      call set_error(error, 'thermal emission: nothing emits (every Planck radiance, absorption '// &
                     'coefficient and surface emissivity is zero) and there is no sun')
      return
    end if
    em%power = ptot
    em%cdf_sun = em%cdf(1)

  contains

    !> The writer's part: the powers of every entry (work arrays), the voxels' emission, the
    !> cumulative table and launch weights, the total power `ptot` (the table is left unset
    !> when nothing emits). `b3` is read from the input.
    subroutine fill_table(cdf, ratio, emit_vox, ptot)
      real(wp), intent(out) :: cdf(0:), ratio(:), emit_vox(:)
      real(wp), intent(out) :: ptot
      real(wp), allocatable :: pw(:), cap(:), ps(:)
      real(wp) :: stot, ctot, q, bb
      integer :: kr, ix, iy, v, i
      allocate (pw(em%n_ent), cap(em%n_ent))
      pw = 0.0_wp
      cap = 0.0_wp
      pw(1) = solar_power
      pw(2) = PI*b_top
      pw(3) = PI*em%eps_b_mean
      pw(em%e_lay + 1:em%e_lay + nz) = pw_lay
      cap(em%e_lay + 1:em%e_lay + nz) = cap_lay
      emit_vox = 0.0_wp
      do kr = 1, atm%n3
        k = atm%k3_lo + kr - 1
        dz = atm%z(k) - atm%z(k - 1)
        if (em%layered) then
          ! the layer's voxels as one entry: their absorption summed, B the layer's mean
          bb = 0.5_wp*(em%b_bot(k) + em%b_top_lay(k))
          cap(em%e_vox + kr) = FOUR_PI*em%row_cum(atm%ny, kr)*dz/ncol
          pw(em%e_vox + kr) = cap(em%e_vox + kr)*bb
          em%emit_layer(k) = em%emit_layer(k) + pw(em%e_vox + kr)
          cycle
        end if
        do iy = 1, atm%ny
          do ix = 1, atm%nx
            v = ix + (iy - 1)*atm%nx + (kr - 1)*ncol
            ka = real(voxel_ext(atm, ix, iy, kr), wp)* &
                 (1.0_wp - real(voxel_omg(atm, ix, iy, kr), wp))
            if (em%has_b3) then
              bb = b3(ix, iy, kr)
            else
              bb = 0.5_wp*(em%b_bot(k) + em%b_top_lay(k))
            end if
            cap(em%e_vox + v) = FOUR_PI*ka*dz/ncol
            pw(em%e_vox + v) = cap(em%e_vox + v)*bb
            emit_vox(v) = pw(em%e_vox + v)*ncol
            em%emit_layer(k) = em%emit_layer(k) + pw(em%e_vox + v)
          end do
        end do
      end do
      ptot = sum(pw)
      if (.not. (ptot > 0.0_wp)) return
      ! escape sampling: the floor is spread evenly over the emitting 1-D layers (thin, cold
      ! layers high up, whose heating rates in K/day matter as much as any, still get photons)
      if (em%escape) cap(em%e_lay + 1:em%e_lay + nz) = 1.0_wp
      ! capacity only of the cells that emit: a cell with B = 0 is scored by what it absorbs
      where (pw <= 0.0_wp) cap = 0.0_wp
      cap(1:3) = 0.0_wp
      ctot = sum(cap)
      ! the powers the table draws by: the emitted ones, or for the 1-D layers what leaves them
      ps = pw
      if (em%escape) then
        do k = 1, nz
          if (em%tau_lay(k) > 0.0_wp) ps(em%e_lay + k) = pw(em%e_lay + k)* &
            escape_fraction(em%tau_lay(k))
        end do
      end if
      stot = sum(ps)
      cdf(0) = 0.0_wp
      do i = 1, em%n_ent
        q = ps(i)/stot
        if (ctot > 0.0_wp) q = (1.0_wp - floor)*q + floor*cap(i)/ctot
        cdf(i) = cdf(i - 1) + q
        if (q > 0.0_wp) then
          ratio(i) = (pw(i)/ptot)/q
        else
          ratio(i) = 0.0_wp
        end if
      end do
      cdf = cdf/cdf(em%n_ent)
      cdf(em%n_ent) = 1.0_wp
    end subroutine fill_table
  end subroutine emission_init

  !> The voxel components' part of the voxels' absorption (voxel_abs_t) for the 3-D region of
  !> `atm`: `cext`, `cssa` (nx, ny, nf, nc) with component layer kf at the region's layer
  !> kr = kf - koff, which `va` points to (they must stay while the tables made with it draw).
  !> After a background swap of `atm` to these components (its list of the voxels with
  !> components, cloud_ptr, allocated) only the listed voxels are read.
  subroutine voxel_abs_init(va, atm, cext, cssa, koff)
    type(voxel_abs_t), intent(out) :: va
    type(atmosphere_t), intent(in) :: atm
    real(wp), pointer, contiguous, intent(in) :: cext(:, :, :, :), cssa(:, :, :, :)
    integer, intent(in) :: koff
    integer :: kr, iy, ix, r
    va%cext => cext
    va%cssa => cssa
    va%koff = koff
    allocate (va%kc_blk((atm%nx + VA_RUN - 1)/VA_RUN, atm%ny, atm%n3))
    va%kc_blk = 0.0_wp
    if (allocated(atm%cloud_ptr)) then
      ! after a swap: only the voxels it lists as having components add anything (the others
      ! add +0 exactly), in the order of the sweep below
      do kr = 1, atm%n3
        do r = atm%cloud_ptr(kr) + 1, atm%cloud_ptr(kr + 1)
          iy = atm%cloud_run(3, r)
          do ix = atm%cloud_run(1, r), atm%cloud_run(2, r)
            call add_voxel(ix, iy, kr)
          end do
        end do
      end do
    else
      do kr = 1, atm%n3
        do iy = 1, atm%ny
          do ix = 1, atm%nx
            call add_voxel(ix, iy, kr)
          end do
        end do
      end do
    end if
    ! what every table made with it reads: the rows' sums and the check of the values
    va%bad = any(.not. (va%kc_blk >= 0.0_wp))
    allocate (va%kc_row(atm%ny, atm%n3))
    do kr = 1, atm%n3
      do iy = 1, atm%ny
        va%kc_row(iy, kr) = sum(va%kc_blk(:, iy, kr))
      end do
    end do
  contains
    !> kc of voxel (ix, iy, kr) into the sum of its run
    subroutine add_voxel(ix, iy, kr)
      integer, intent(in) :: ix, iy, kr
      integer :: j
      j = (ix - 1)/VA_RUN + 1
      va%kc_blk(j, iy, kr) = va%kc_blk(j, iy, kr) + components_abs(cext, cssa, koff, ix, iy, kr)
    end subroutine add_voxel
  end subroutine voxel_abs_init

  !> kc of voxel (ix, iy, kr): the components' sum of ext (1 - ssa) (a component of extinction 0
  !> adds nothing, whatever its albedo).
  pure real(wp) function components_abs(cext, cssa, koff, ix, iy, kr) result(a)
    real(wp), intent(in) :: cext(:, :, :, :), cssa(:, :, :, :)
    integer, intent(in) :: koff, ix, iy, kr
    integer :: kf, j
    a = 0.0_wp
    kf = kr + koff
    if (kf < 1 .or. kf > size(cext, 3)) return
    do j = 1, size(cext, 4)
      if (cext(ix, iy, kf, j) > 0.0_wp) a = a + cext(ix, iy, kf, j)* &
                                            max(0.0_wp, 1.0_wp - cssa(ix, iy, kf, j))
    end do
  end function components_abs

  !> Point a table that owns its arrays (not `on_node`) to them: needed after a copy of an
  !> emission_t (intrinsic assignment copies the arrays but leaves the copy reading the
  !> original's), before the original goes away or changes.
  subroutine emission_bind(em)
    type(emission_t), intent(inout), target :: em
    if (em%on_node) return
    nullify (em%b3, em%cdf, em%ratio)
    if (allocated(em%b3_own)) em%b3 => em%b3_own
    if (allocated(em%cdf_own)) em%cdf(0:) => em%cdf_own
    if (allocated(em%ratio_own)) em%ratio => em%ratio_own
  end subroutine emission_bind

  !> Make a table that lives in the caller's storage (`on_node`) independent of it, for what it
  !> reports (the powers of the layers, voxels and surface): the voxels' powers are copied out
  !> and the table itself (cdf, ratio, b3) is let go, so the result launches no photons. Used
  !> for summaries of tables whose storage is used again (the g-points of a broadband run).
  !> With `keep_voxels` = .false. the voxels' powers are let go too (a process that does not
  !> report them).
  !> A table that draws its voxels by layer (`layered`) is detached the same way: it lets go of
  !> the voxel components it reads, and with `keep_voxels` (the default) keeps the voxels' powers,
  !> which it forms from `atm` (required then), the atmosphere it was made for.
  subroutine emission_detach(em, keep_voxels, atm)
    type(emission_t), intent(inout) :: em
    logical, intent(in), optional :: keep_voxels
    type(atmosphere_t), intent(in), optional :: atm
    logical :: keep
    keep = .true.
    if (present(keep_voxels)) keep = keep_voxels
    if (em%layered) then
      ! the voxels' powers from the atmosphere (emission_voxel_power stops without it)
      if (allocated(em%emit_vox)) deallocate (em%emit_vox)
      if (keep) em%emit_vox = emission_voxel_power(em, atm)
      deallocate (em%cdf_own, em%ratio_own, em%kb3, em%row_cum, em%kc_blk)
      nullify (em%cext, em%cssa)
      em%layered = .false.
    else if (em%on_node) then
      if (.not. keep) allocate (em%emit_vox(0))
      if (.not. allocated(em%emit_vox)) em%emit_vox = em%emit_vox_node
      nullify (em%b3, em%emit_vox_node)
      em%on_node = .false.
    else
      return
    end if
    if (.not. allocated(em%emit_vox)) allocate (em%emit_vox(0))
    nullify (em%cdf, em%ratio)
    em%table_bytes_own = storage_size(1.0_wp)/8*size(em%emit_vox, kind=i8)
    em%table_bytes_borrowed = 0_i8
  end subroutine emission_detach

  !> Fraction of the emission of a layer of absorption optical depth tau that leaves it,
  !> (1/2 - E_3(tau))/tau; 1 below tau = 1e-4, where it differs from 1 by less than 1e-3 (only
  !> the sampling probabilities use it).
  elemental real(wp) function escape_fraction(tau) result(f)
    real(wp), intent(in) :: tau
    if (tau < 1.0e-4_wp) then
      f = 1.0_wp
    else
      f = (0.5_wp - expint_e(3, tau))/tau
    end if
  end function escape_fraction

  !> Surface emissivity: 1 - albedo per pixel (Lambert), 1 - alpha(mu) per class (BRDF, its
  !> hemispherical value 1 - 2 int alpha(mu) mu dmu by 64-point Gauss-Legendre quadrature), and
  !> its mean over the domain.
  subroutine surface_emissivity(em, sfc)
    type(emission_t), intent(inout) :: em
    type(surface_t), intent(in) :: sfc
    real(wp) :: x(64), w(64)
    integer :: kb
    if (sfc%use_brdf) then
      call gauss_legendre01(64, x, w)
      allocate (em%eps_h(size(sfc%tabs)))
      do kb = 1, size(sfc%tabs)
        em%eps_h(kb) = 1.0_wp - 2.0_wp*sum(w*x*brdf_albedo(sfc%tabs(kb), x))
      end do
      if (sfc%uniform .or. .not. allocated(sfc%cls)) then
        em%eps_mean = em%eps_h(1)
      else
        em%eps_mean = sum(em%eps_h(reshape(sfc%cls, [size(sfc%cls)])))/size(sfc%cls)
      end if
    else
      allocate (em%eps_h(0))
      em%eps_mean = 1.0_wp - sum(sfc%albedo)/size(sfc%albedo)
    end if
    em%eps_mean = max(0.0_wp, min(1.0_wp, em%eps_mean))
  end subroutine surface_emissivity

  !> Planck radiance of the surface at (x, y): the map's pixel, or the uniform value.
  pure real(wp) function emission_b_surface(em, x, y) result(b)
    type(emission_t), intent(in) :: em
    real(wp), intent(in) :: x, y
    integer :: i, j
    if (allocated(em%b_sfc_map)) then
      i = min(size(em%b_sfc_map, 1), max(1, int(x*em%inv_dxt) + 1))
      j = min(size(em%b_sfc_map, 2), max(1, int(y*em%inv_dyt) + 1))
      b = em%b_sfc_map(i, j)
    else
      b = em%b_sfc
    end if
  end function emission_b_surface

  !> Domain mean of eps_h(x, y) B(x, y) for a surface whose emissivity (albedo map, or BRDF
  !> classes on the surface grid with their hemispherical emissivities `eps_h`) and temperature
  !> (map `bmap`) are piecewise constant on two different grids: the overlaps of the two grids'
  !> cells, exactly.
  function mean_eps_b(sfc, eps_h, bmap, lx, ly) result(m)
    type(surface_t), intent(in) :: sfc
    real(wp), intent(in) :: eps_h(:), bmap(:, :), lx, ly
    real(wp) :: m
    real(wp), allocatable :: xe(:), ye(:)
    real(wp) :: xc, yc, eps
    integer :: i, j, nt(2)
    nt = shape(bmap)
    xe = merge_edges(sfc%nxs, nt(1), lx)
    ye = merge_edges(sfc%nys, nt(2), ly)
    m = 0.0_wp
    do j = 1, size(ye) - 1
      yc = 0.5_wp*(ye(j) + ye(j + 1))
      do i = 1, size(xe) - 1
        xc = 0.5_wp*(xe(i) + xe(i + 1))
        if (sfc%use_brdf) then
          eps = eps_h(sfc%class_at(xc, yc))
        else
          eps = 1.0_wp - sfc%albedo_at(xc, yc)
        end if
        m = m + (xe(i + 1) - xe(i))*(ye(j + 1) - ye(j))*eps* &
            bmap(min(nt(1), int(xc*nt(1)/lx) + 1), min(nt(2), int(yc*nt(2)/ly) + 1))
      end do
    end do
    m = m/(lx*ly)
  end function mean_eps_b

  !> The cell edges of two regular grids of n1 and n2 cells over [0, l], merged and sorted.
  function merge_edges(n1, n2, l) result(e)
    integer, intent(in) :: n1, n2
    real(wp), intent(in) :: l
    real(wp), allocatable :: e(:)
    integer :: i1, i2
    real(wp) :: a, b
    allocate (e(0))
    i1 = 0
    i2 = 0
    do while (i1 <= n1 .or. i2 <= n2)
      a = huge(1.0_wp)
      b = huge(1.0_wp)
      if (i1 <= n1) a = l*i1/n1
      if (i2 <= n2) b = l*i2/n2
      if (a <= b) then
        if (size(e) == 0) then
          e = [a]
        else if (a > e(size(e))) then
          e = [e, a]
        end if
        i1 = i1 + 1
      else
        if (size(e) == 0) then
          e = [b]
        else if (b > e(size(e))) then
          e = [e, b]
        end if
        i2 = i2 + 1
      end if
    end do
  end function merge_edges

  !> Directional emissivity of the surface at (x, y) for the emission cosine mu.
  real(wp) function emission_surface_eps(sfc, x, y, mu) result(eps)
    type(surface_t), intent(in) :: sfc
    real(wp), intent(in) :: x, y, mu
    if (sfc%use_brdf) then
      eps = 1.0_wp - brdf_albedo(sfc%tabs(sfc%class_at(x, y)), mu)
    else
      eps = 1.0_wp - sfc%albedo_at(x, y)
    end if
  end function emission_surface_eps

  !> The table entry that holds u in [0, 1): the smallest i with cdf(i) > u (bisection).
  pure integer function emission_entry(em, u) result(i)
    type(emission_t), intent(in) :: em
    real(wp), intent(in) :: u
    i = table_entry(em%cdf, em%n_ent, u)
  end function emission_entry

  !> The smallest i with cdf(i) > u, for u in [0, 1) and cdf(n) = 1 (the table as a plain
  !> array: its indexing does not go through the pointer's descriptor).
  pure integer function table_entry(cdf, n, u) result(i)
    integer, intent(in) :: n
    real(wp), intent(in) :: cdf(0:n), u
    integer :: lo, hi, mid
    lo = 0             ! cdf(lo) <= u
    hi = n             ! cdf(hi) > u (cdf(n) = 1 > u)
    do while (hi - lo > 1)
      mid = (lo + hi)/2
      if (cdf(mid) > u) then
        hi = mid
      else
        lo = mid
      end if
    end do
    i = hi
  end function table_entry

  !> Launch weight of a photon from entry `ie` in a batch of `n` photons with the table shift
  !> `u`: (P_i/P) n/n_i, with n_i the photons the entry gets in this batch, when every batch
  !> gives it at least one (n q_i >= 1), so that its photons carry exactly its power in every
  !> batch; else (P_i/P)/q_i, exact on average over the shift.
  pure real(wp) function emission_weight(em, ie, n, u) result(w)
    type(emission_t), intent(in) :: em
    integer, intent(in) :: ie
    integer(i8), intent(in) :: n
    real(wp), intent(in) :: u
    w = table_weight(em%cdf, em%ratio, em%n_ent, ie, n, u)
  end function emission_weight

  !> emission_weight from the table as plain arrays.
  pure real(wp) function table_weight(cdf, ratio, n_ent, ie, n, u) result(w)
    integer, intent(in) :: n_ent, ie
    real(wp), intent(in) :: cdf(0:n_ent), ratio(n_ent)
    integer(i8), intent(in) :: n
    real(wp), intent(in) :: u
    real(wp) :: q, rn
    integer(i8) :: ni
    q = cdf(ie) - cdf(ie - 1)
    rn = real(n, wp)
    if (rn*q >= 1.0_wp) then
      ni = int(ceiling(rn*cdf(ie) - u), i8) - int(ceiling(rn*cdf(ie - 1) - u), i8)
      w = ratio(ie)*q*rn/real(max(1_i8, ni), wp)
    else
      w = ratio(ie)
    end if
  end function table_weight

  !> Launch a thermal photon from table entry `ie` (not the sun) of a batch of `n` photons with
  !> table shift `u`: position, direction, weight and its emitter. `uj` is the photon's place on
  !> the table (the entry holds it); a table that draws voxels by layer places the photon
  !> within the layer by it, so that the photons of a layer stay spread over its rows as those
  !> of a table with one entry per voxel are. Levels crossed at the launch are the caller's to
  !> tally.
  subroutine emission_launch(em, atm, sfc, rng, ie, n, u, uj, p)
    type(emission_t), intent(in) :: em
    type(atmosphere_t), intent(in) :: atm
    type(surface_t), intent(in) :: sfc
    type(rng_t), intent(inout) :: rng
    integer, intent(in) :: ie
    integer(i8), intent(in) :: n
    real(wp), intent(in) :: u, uj
    type(photon_t), intent(inout) :: p
    real(wp) :: mu, cphi, sphi, st, b, tl, et, t
    integer :: v, ix, iy, kr, k

    p%w = emission_weight(em, ie, n, u)
    p%w_entry = p%w
    p%order = 1
    p%lev = 1
    p%n_events = 0
    p%n_steps = 0
    p%secondary = .false.
    p%em_k = 0
    p%em_v = 0
    if (ie == 2) then
      ! the top: cosine-weighted downward directions
      p%emitter = EMIT_TOP
      p%x = rng_uniform(rng)*atm%lx
      p%y = rng_uniform(rng)*atm%ly
      p%z = atm%z(atm%nz)
      p%iz = atm%nz
      mu = sqrt(1.0_wp - rng_uniform(rng))
      call set_direction(p, -mu)
      b = em%b_top
    else if (ie == 3) then
      ! the surface: cosine-weighted upward directions, weight times eps(x, y, mu)/<eps>
      p%emitter = EMIT_SURFACE
      p%x = rng_uniform(rng)*atm%lx
      p%y = rng_uniform(rng)*atm%ly
      p%z = atm%z(0)
      p%iz = 1
      mu = sqrt(1.0_wp - rng_uniform(rng))
      call set_direction(p, mu)
      b = emission_b_surface(em, p%x, p%y)
      if (em%eps_b_mean > 0.0_wp) p%w = p%w*emission_surface_eps(sfc, p%x, p%y, p%uz)*b/ &
                                        em%eps_b_mean
    else if (ie <= em%e_vox) then
      ! a 1-D layer: uniform in x, y; in height with density proportional to B
      k = ie - em%e_lay
      p%emitter = EMIT_LAYER
      p%em_k = k
      p%iz = k
      p%x = rng_uniform(rng)*atm%lx
      p%y = rng_uniform(rng)*atm%ly
      if (em%escape .and. em%tau_lay(k) > 1.0_wp) then
        ! near the faces: t from q(t), weight p(t)/q(t)
        tl = em%tau_lay(k)
        et = 1.0_wp - exp(-tl)
        t = -log(1.0_wp - rng_uniform(rng)*et)
        if (rng_uniform(rng) >= 0.5_wp) t = tl - t
        t = min(tl, max(0.0_wp, t))
        p%z = atm%z(k - 1) + (t/tl)*(atm%z(k) - atm%z(k - 1))
        b = emission_b_point(em, atm, k, p%z, 0, 0, 0)
        p%w = p%w*(b/(0.5_wp*tl*(em%b_bot(k) + em%b_top_lay(k))))* &
              (2.0_wp*et/(exp(-t) + exp(-(tl - t))))
        p%w_entry = p%w
      else
        p%z = atm%z(k - 1) + linear_fraction(em%b_bot(k), em%b_top_lay(k), rng_uniform(rng))* &
              (atm%z(k) - atm%z(k - 1))
        b = emission_b_point(em, atm, k, p%z, 0, 0, 0)
      end if
      call isotropic(p)
    else
      ! a voxel: uniform in x, y; in height uniform (voxel value) or linear in B (levels)
      if (em%layered) then
        kr = ie - em%e_vox
        call layer_voxel(kr, ix, iy)
        v = ix + (iy - 1)*atm%nx + (kr - 1)*em%ncol
      else
        v = ie - em%e_vox
        kr = (v - 1)/em%ncol + 1
        iy = (v - 1 - (kr - 1)*em%ncol)/atm%nx + 1
        ix = v - (kr - 1)*em%ncol - (iy - 1)*atm%nx
      end if
      k = atm%k3_lo + kr - 1
      p%emitter = EMIT_VOXEL
      p%em_k = k
      p%em_v = v
      p%iz = k
      p%x = (ix - 1 + rng_uniform(rng))*atm%dx
      p%y = (iy - 1 + rng_uniform(rng))*atm%dy
      p%x = min(p%x, nearest(ix*atm%dx, -1.0_wp))
      p%y = min(p%y, nearest(iy*atm%dy, -1.0_wp))
      if (em%has_b3) then
        p%z = atm%z(k - 1) + rng_uniform(rng)*(atm%z(k) - atm%z(k - 1))
        b = em%b3(ix, iy, kr)
      else
        p%z = atm%z(k - 1) + linear_fraction(em%b_bot(k), em%b_top_lay(k), rng_uniform(rng))* &
              (atm%z(k) - atm%z(k - 1))
        b = emission_b_point(em, atm, k, p%z, 0, 0, 0)
      end if
      call isotropic(p)
    end if
    p%rbe = 0.0_wp
    if (b > 0.0_wp) p%rbe = 1.0_wp/b

  contains

    !> The voxel (ix, iy) of layer kr of a layered table for the photon at uj: a row by the
    !> rows' cumulative sums, then a voxel of the row in proportion to kb + kc (its selection
    !> probability within the layer, m / row_cum(ny)); the weight takes k_a / m, k_a the
    !> voxel's absorption in the voxel arrays, which the photons' absorption uses.
    subroutine layer_voxel(kr, ix, iy)
      integer, intent(in) :: kr
      integer, intent(out) :: ix, iy
      real(wp) :: q, qr, t, s, m, kb, ka
      integer :: i, jr
      kb = em%kb3(kr)
      q = em%cdf(ie) - em%cdf(ie - 1)
      t = 0.0_wp
      if (q > 0.0_wp) t = (uj - em%cdf(ie - 1))/q
      t = min(1.0_wp, max(0.0_wp, t))*em%row_cum(atm%ny, kr)
      iy = table_entry(em%row_cum(:, kr), atm%ny, t)
      ! a row without absorption only at the end of the layer (t at its total): the last one with
      do while (iy > 1 .and. .not. (em%row_cum(iy, kr) > em%row_cum(iy - 1, kr)))
        iy = iy - 1
      end do
      t = t - em%row_cum(iy - 1, kr)
      ! the run of voxels of the row, then the voxel of the run (the last with absorption when
      ! rounding leaves t at or above the sums)
      jr = 0
      s = 0.0_wp
      do i = 1, size(em%kc_blk, 1)
        q = (min(atm%nx, i*VA_RUN) - (i - 1)*VA_RUN)*kb + em%kc_blk(i, iy, kr)
        if (q > 0.0_wp) then
          jr = i
          qr = q
          s = s + q
          if (s > t) exit
        end if
      end do
      ix = 0
      m = 0.0_wp
      if (jr > 0) then
        t = t - (s - qr)
        s = 0.0_wp
        do i = (jr - 1)*VA_RUN + 1, min(atm%nx, jr*VA_RUN)
          q = kb + components_abs(em%cext, em%cssa, em%koff, i, iy, kr)
          if (q > 0.0_wp) then
            ix = i
            m = q
            s = s + q
            if (s > t) exit
          end if
        end do
      end if
      if (ix == 0) then
        ! nothing absorbs in the layer (its entry has no photons then); keep the photon valid
        ix = 1
        p%w = 0.0_wp
        p%w_entry = 0.0_wp
        return
      end if
      ka = real(voxel_ext(atm, ix, iy, kr), wp)*(1.0_wp - real(voxel_omg(atm, ix, iy, kr), wp))
      ! the plain launch weight (P_L/P)/q_L of the layer, never the one that gives the layer
      ! exactly its power in every batch (emission_weight): the photons of a batch that land in
      ! a voxel are not independent of how many the layer gets, and that weight would favour
      ! the voxels early in the layer's order
      p%w = em%ratio(ie)*(ka/m)
      p%w_entry = p%w
    end subroutine layer_voxel

    subroutine isotropic(q)
      type(photon_t), intent(inout) :: q
      call set_direction(q, 2.0_wp*rng_uniform(rng) - 1.0_wp)
    end subroutine isotropic

    subroutine set_direction(q, uz)
      type(photon_t), intent(inout) :: q
      real(wp), intent(in) :: uz
      q%uz = uz
      if (abs(q%uz) < UZ_MIN) q%uz = sign(UZ_MIN, q%uz)
      st = sqrt(max(0.0_wp, 1.0_wp - q%uz*q%uz))
      call sample_azimuth(rng, cphi, sphi)
      q%ux = st*cphi
      q%uy = st*sphi
    end subroutine set_direction
  end subroutine emission_launch

  !> Fraction t in [0, 1] of a layer's height drawn with density proportional to the linear
  !> function a + (b - a) t (a, b >= 0, not both 0), by inverting its cumulative distribution
  !> in a form without cancellation.
  pure real(wp) function linear_fraction(a, b, u) result(t)
    real(wp), intent(in) :: a, b, u
    real(wp) :: d
    d = a + sqrt(max(0.0_wp, a*a + u*(b*b - a*a)))
    if (d > 0.0_wp) then
      t = u*(a + b)/d
    else
      t = u
    end if
    t = min(1.0_wp, max(0.0_wp, t))
  end function linear_fraction

  !> Planck radiance at height z in layer k: the voxel value (ix, iy, kr) > 0 when voxel values
  !> are given and the point is in the 3-D region, else linear between the level values.
  pure real(wp) function emission_b_point(em, atm, k, z, ix, iy, kr) result(b)
    type(emission_t), intent(in) :: em
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: k, ix, iy, kr
    real(wp), intent(in) :: z
    real(wp) :: t
    if (kr > 0 .and. em%has_b3) then
      b = em%b3(ix, iy, kr)
      return
    end if
    t = (z - atm%z(k - 1))/(atm%z(k) - atm%z(k - 1))
    t = min(1.0_wp, max(0.0_wp, t))
    b = em%b_bot(k) + (em%b_top_lay(k) - em%b_bot(k))*t
  end function emission_b_point

  !> Emitted power of each voxel of the 3-D region per unit column area [W m-2], (nx*ny*n3) in
  !> the order of the voxel entries (a copy, wherever the table lives).
  !> A table that draws its voxels by layer forms them from `atm` (required then): 4 pi k_a dz
  !> B with k_a from the voxel arrays and B the layer's mean.
  function emission_voxel_power(em, atm) result(p)
    type(emission_t), intent(in) :: em
    type(atmosphere_t), intent(in), optional :: atm
    real(wp), allocatable :: p(:)
    if (em%layered) then
      if (.not. present(atm)) error stop 'emission_voxel_power: a layered table needs its atmosphere'
      allocate (p(int(atm%nx*atm%ny, i8)*atm%n3))
      call layered_power(em, atm, p, .false.)
    else if (em%on_node) then
      p = em%emit_vox_node
    else
      p = em%emit_vox
    end if
  end function emission_voxel_power

  !> acc + emission_voxel_power(em, atm), added in place (the same sums to the last bit, without
  !> a temporary of every voxel): the broadband set-up sums the voxels' emission over g-points.
  subroutine emission_voxel_power_add(em, atm, acc)
    type(emission_t), intent(in) :: em
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(inout) :: acc(:)
    if (em%layered) then
      call layered_power(em, atm, acc, .true.)
    else if (em%on_node) then
      acc = acc + em%emit_vox_node
    else
      acc = acc + em%emit_vox
    end if
  end subroutine emission_voxel_power_add

  !> The voxels' emitted powers of a table drawn by layer into p, or added to it (`add`)
  subroutine layered_power(em, atm, p, add)
    type(emission_t), intent(in) :: em
    type(atmosphere_t), intent(in) :: atm
    real(wp), intent(inout) :: p(:)
    logical, intent(in) :: add
    integer :: kr, k, ncol, j, ix, iy
    real(wp) :: c
    real(vp), allocatable :: e(:, :), w(:, :)
    real(wp), allocatable :: v(:)
    ncol = atm%nx*atm%ny
    if (allocated(atm%cloud_ptr)) then
      allocate (v(ncol))
    else
      allocate (e(atm%nx, atm%ny), w(atm%nx, atm%ny))
    end if
    do kr = 1, atm%n3
      k = atm%k3_lo + kr - 1
      c = FOUR_PI*(atm%z(k) - atm%z(k - 1))*0.5_wp*(em%b_bot(k) + em%b_top_lay(k))
      if (allocated(atm%cloud_ptr)) then
        ! after a swap every voxel that it does not list holds its layer's values (clear3): one
        ! value for all of them, then the listed voxels their own (the same numbers)
        v = c*real(atm%clear3(1, kr), wp)*(1.0_wp - real(atm%clear3(2, kr), wp))
        do j = atm%cloud_ptr(kr) + 1, atm%cloud_ptr(kr + 1)
          iy = atm%cloud_run(3, j)
          do ix = atm%cloud_run(1, j), atm%cloud_run(2, j)
            v(ix + (iy - 1)*atm%nx) = c*real(atm%ext3(ix, iy, kr), wp)* &
                                      (1.0_wp - real(atm%omg3(ix, iy, kr), wp))
          end do
        end do
        if (add) then
          p((kr - 1)*ncol + 1:kr*ncol) = p((kr - 1)*ncol + 1:kr*ncol) + v
        else
          p((kr - 1)*ncol + 1:kr*ncol) = v
        end if
      else
        call voxel_layer(atm, kr, e, w)
        call layer_power(p((kr - 1)*ncol + 1:kr*ncol), e, w, ncol)
      end if
    end do
  contains
    !> 4 pi k_a dz B of the voxels of a layer (c as formed above; e and w column by column)
    pure subroutine layer_power(pl, el, wl, n)
      integer, intent(in) :: n
      real(wp), intent(inout) :: pl(n)
      real(vp), intent(in) :: el(n), wl(n)
      if (add) then
        pl = pl + c*real(el, wp)*(1.0_wp - real(wl, wp))
      else
        pl = c*real(el, wp)*(1.0_wp - real(wl, wp))
      end if
    end subroutine layer_power
  end subroutine layered_power

  !> Mean Planck radiance of what is absorbed along a straight path through a homogeneous 1-D
  !> layer k from height z0 to z1 with absorption optical path tau: the absorption density
  !> k e^(-k s) times B, linear along the path, integrates to B0 + (B1 - B0) g(tau) with
  !> g = (1 - e^-tau (1 + tau))/(tau (1 - e^-tau)) (series below tau = 1e-3).
  pure real(wp) function emission_b_segment(em, atm, k, z0, z1, tau) result(b)
    type(emission_t), intent(in) :: em
    type(atmosphere_t), intent(in) :: atm
    integer, intent(in) :: k
    real(wp), intent(in) :: z0, z1, tau
    real(wp) :: b0, b1, g, e
    b0 = emission_b_point(em, atm, k, z0, 0, 0, 0)
    b1 = emission_b_point(em, atm, k, z1, 0, 0, 0)
    if (tau < 1.0e-3_wp) then
      g = 0.5_wp - tau/12.0_wp
    else
      e = exp(-tau)
      g = (1.0_wp - e*(1.0_wp + tau))/(tau*(1.0_wp - e))
    end if
    b = b0 + (b1 - b0)*g
  end function emission_b_segment

end module kumo_emission
