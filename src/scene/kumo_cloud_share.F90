! SPDX-License-Identifier: BSD-3-Clause
!> A cloud file read once, on rank 0, and shared with every rank.
!>
!> `read_cloud_on_root` is read_cloud_input (kumo_cloud_input) for a run on several ranks: rank 0
!> reads the file (and its companions: the MCARaTS phase-function file), puts the
!> `cloud_input_t` it got into a `bundle_t` (`cloud_input_put`), and every rank, rank 0 too,
!> takes it out of the shared bundle (`cloud_input_get`): all ranks hold rank 0's bits, or
!> rank 0's error. The scene is then built from it without MPI (kumo_cloud_scene,
!> kumo_spectral_cloud). `mie_table_put` and `mie_table_get` carry an optics table in the
!> Mie-table layout the same way (a cloud file's ice optics table, read on rank 0).
!>
!> `cloud_input_put` and `cloud_input_get` are the one pack/unpack pair of the type: every
!> component, arrays only when allocated. A component added to `cloud_input_t` (or to the
!> MCARaTS types it holds) needs one line in each, at the same place (see "fields" below);
!> test_cloud_share checks that a full round trip returns every component.
module kumo_cloud_share
  use kumo_kinds, only: wp, vp
  use kumo_error, only: error_t
  use kumo_bundle, only: bundle_t
  use kumo_parallel, only: par_is_root, par_node_leader, par_node_size, par_size
  use kumo_cloud_input, only: cloud_input_t, cloud_request_t, read_cloud_input
  use kumo_mcarats_files, only: mcarats_atm_t, mcarats_phase_t
  use kumo_mie, only: mie_table_t
  implicit none
  private
  public :: read_cloud_on_root, cloud_input_put, cloud_input_get, mie_table_put, mie_table_get

  !> Put an allocatable item with its allocation status (nothing more when not allocated).
  interface put_opt
    module procedure put_opt_r1, put_opt_r2, put_opt_r3, put_opt_r4, put_opt_i3, &
                     put_opt_text
  end interface put_opt

  !> Take an item of put_opt: allocated as rank 0's was, or left unallocated.
  interface get_opt
    module procedure get_opt_r1, get_opt_r2, get_opt_r3, get_opt_r4, get_opt_i3, &
                     get_opt_text
  end interface get_opt

contains

  !> Read a cloud file on rank 0 (read_cloud_input with the same arguments) and give every rank
  !> what it read, or its error. Every rank must call it. With `alone` = .true. the calling
  !> process reads the file itself and talks to no other rank (`kumo --check`); the result is
  !> the same. With `grid_only` only the grid travels (format, sizes, widths, layer edges, the
  !> pressure and gas-state profiles when requested, and the reader's notes), whatever the
  !> reader returned besides. With `per_node` = .true. only the first rank of every node (its
  !> leader, kumo_parallel par_node_leader) gets the fields; the other ranks get the grid (as
  !> with `grid_only`) and what their phase functions are made of (`small_put`: Legendre
  !> series, Henyey-Greenstein g, MCARaTS tables), and never hold a copy of the fields: the
  !> node's leader builds the voxels in memory the node shares (build_cloud_atmosphere's
  !> `storage`). The temperatures, when `req` asks for them, are fields too: the other ranks get
  !> only what describes them (planes, perturbations, their source; `temperature_put`), and
  !> `has_temperature` says on every rank whether the file gave them. On one node rank 0 is the
  !> only leader: it keeps what it read, and no copy of the fields travels or waits in a bundle
  !> beside it.
  subroutine read_cloud_on_root(req, cloud, error, grid_only, part, alone, per_node, &
                                has_temperature)
    type(cloud_request_t), intent(in) :: req
    type(cloud_input_t), intent(out) :: cloud
    type(error_t), allocatable, intent(out) :: error
    logical, intent(in), optional :: grid_only
    character(len=*), intent(in), optional :: part
    logical, intent(in), optional :: alone
    logical, intent(in), optional :: per_node
    !> the file gave temperatures (as rank 0 read it: also on ranks that do not receive them)
    logical, intent(out), optional :: has_temperature
    type(bundle_t) :: b, bg
    logical :: here, grid, reader, node, has_t
    has_t = .false.
    if (present(has_temperature)) has_temperature = .false.
    here = .false.
    if (present(alone)) here = alone
    grid = .false.
    if (present(grid_only)) grid = grid_only
    node = .false.
    if (present(per_node)) node = per_node .and. .not. here .and. .not. grid
    reader = here
    if (.not. here) reader = par_is_root()
    if (node .and. par_node_size() == par_size()) then
      ! one node: rank 0 is its only leader and keeps what it read; only the grid travels
      if (reader) then
        call read_cloud_input(req, cloud, error, grid_only, part)
        if (.not. allocated(error)) then
          call cloud_input_put(bg, cloud, .true.)
          call small_put(bg, cloud)
          if (req%temperature) call temperature_put(bg, cloud)
        end if
      end if
      call bg%share(error)
      if (present(has_temperature)) has_temperature = allocated(cloud%temperature)
      if (allocated(error) .or. reader) return
      call cloud_input_get(bg, cloud)
      call small_get(bg, cloud)
      if (req%temperature) call temperature_get(bg, cloud, has_t)
      if (present(has_temperature)) has_temperature = has_t
      return
    end if
    if (reader) then
      block
        ! rank 0's copy is freed before the bundle's is taken out: one copy besides the bundle
        type(cloud_input_t) :: c
        call read_cloud_input(req, c, error, grid_only, part)
        if (.not. allocated(error)) call cloud_input_put(b, c, grid)
        if (.not. allocated(error) .and. node) then
          call cloud_input_put(bg, c, .true.)
          call small_put(bg, c)
          if (req%temperature) call temperature_put(bg, c)
        end if
      end block
    end if
    if (node) then
      ! every rank: the grid and rank 0's error; the node leaders: the fields
      call bg%share(error)
      if (allocated(error)) return
      if (par_node_leader()) then
        call b%share(error, leaders=.true.)
        call cloud_input_get(b, cloud)
        if (present(has_temperature)) has_temperature = allocated(cloud%temperature)
      else
        call cloud_input_get(bg, cloud)
        call small_get(bg, cloud)
        if (req%temperature) call temperature_get(bg, cloud, has_t)
        if (present(has_temperature)) has_temperature = has_t
      end if
      return
    end if
    if (.not. here) call b%share(error)
    if (allocated(error)) return
    call cloud_input_get(b, cloud)
    if (present(has_temperature)) has_temperature = allocated(cloud%temperature)
  end subroutine read_cloud_on_root

  !> Put a cloud input into a bundle: every component (the grid alone with `grid_only`).
  subroutine cloud_input_put(b, c, grid_only)
    type(bundle_t), intent(inout) :: b
    type(cloud_input_t), intent(in) :: c
    logical, intent(in) :: grid_only
    call b%put(grid_only)
    ! the grid
    call b%put(c%format)
    call b%put(c%nx)
    call b%put(c%ny)
    call b%put(c%nz)
    call b%put(c%content)
    call b%put(c%dx)
    call b%put(c%dy)
    call b%put(c%points)
    call b%put(c%has_ice)
    call put_opt(b, c%z)
    call put_opt(b, c%pressure)
    call put_opt(b, c%pressure_source)
    call put_opt(b, c%t_profile)
    call put_opt(b, c%h2o_profile)
    call put_opt(b, c%notes)
    call put_opt(b, c%warnings)
    if (grid_only) return
    ! fields: a new component of cloud_input_t takes one line here and one in cloud_input_get
    call put_vox(b, c%lwc)
    call put_vox(b, c%reff)
    call put_vox(b, c%ext)
    call put_vox(b, c%ssa)
    call put_opt(b, c%iphase)
    call put_opt(b, c%chi)
    call put_opt(b, c%hg_g)
    call put_vox(b, c%iwc)
    call put_vox(b, c%reff_ice)
    call put_vox(b, c%temperature)
    call b%put(c%t_planes)
    call b%put(c%t_perturbation)
    call put_opt(b, c%t_source)
    call put_mcarats(b, c%mca_atm, c%mca_phase)
    call put_opt(b, c%missing)
  end subroutine cloud_input_put

  !> Take a cloud input out of a bundle of cloud_input_put, components in the same order.
  subroutine cloud_input_get(b, c)
    type(bundle_t), intent(inout) :: b
    type(cloud_input_t), intent(out) :: c
    character(len=:), allocatable :: fmt
    logical :: grid_only
    call b%get(grid_only)
    call b%get(fmt)
    c%format = fmt
    call b%get(c%nx)
    call b%get(c%ny)
    call b%get(c%nz)
    call b%get(c%content)
    call b%get(c%dx)
    call b%get(c%dy)
    call b%get(c%points)
    call b%get(c%has_ice)
    call get_opt(b, c%z)
    call get_opt(b, c%pressure)
    call get_opt(b, c%pressure_source)
    call get_opt(b, c%t_profile)
    call get_opt(b, c%h2o_profile)
    call get_opt(b, c%notes)
    call get_opt(b, c%warnings)
    if (grid_only) return
    ! fields, as in cloud_input_put
    call get_vox(b, c%lwc)
    call get_vox(b, c%reff)
    call get_vox(b, c%ext)
    call get_vox(b, c%ssa)
    call get_opt(b, c%iphase)
    call get_opt(b, c%chi)
    call get_opt(b, c%hg_g)
    call get_vox(b, c%iwc)
    call get_vox(b, c%reff_ice)
    call get_vox(b, c%temperature)
    call b%get(c%t_planes)
    call b%get(c%t_perturbation)
    call get_opt(b, c%t_source)
    call get_mcarats(b, c%mca_atm, c%mca_phase)
    call get_opt(b, c%missing)
  end subroutine cloud_input_get

  !> Put what a rank without the fields of a cloud file needs besides its grid to build the same
  !> phase functions as the node's leader (read_cloud_on_root per_node): the phase functions of
  !> an optics file (Legendre series or Henyey-Greenstein g) and of an MCARaTS file (its
  !> distinct Henyey-Greenstein g, its tables and sizes), which are small beside the fields.
  subroutine small_put(b, c)
    type(bundle_t), intent(inout) :: b
    type(cloud_input_t), intent(in) :: c
    call put_opt(b, c%chi)
    call put_opt(b, c%hg_g)
    call put_opt(b, c%missing)
    call b%put(c%mca_atm%nx)
    call b%put(c%mca_atm%ny)
    call b%put(c%mca_atm%nz3)
    call b%put(c%mca_atm%mtprof)
    call b%put(c%mca_atm%nkd)
    call b%put(c%mca_atm%np3d)
    call b%put(c%mca_atm%idread)
    call b%put(c%mca_atm%ndatasets)
    call put_opt(b, c%mca_atm%missing)
    call b%put(c%mca_phase%nang)
    call b%put(c%mca_phase%npf)
    call b%put(c%mca_phase%reversed)
    call put_opt(b, c%mca_phase%angle_deg)
    call put_opt(b, c%mca_phase%p_file)
    call put_opt(b, c%mca_phase%p)
  end subroutine small_put

  !> Take the items of small_put out of a bundle, in the same order.
  subroutine small_get(b, c)
    type(bundle_t), intent(inout) :: b
    type(cloud_input_t), intent(inout) :: c
    call get_opt(b, c%chi)
    call get_opt(b, c%hg_g)
    call get_opt(b, c%missing)
    call b%get(c%mca_atm%nx)
    call b%get(c%mca_atm%ny)
    call b%get(c%mca_atm%nz3)
    call b%get(c%mca_atm%mtprof)
    call b%get(c%mca_atm%nkd)
    call b%get(c%mca_atm%np3d)
    call b%get(c%mca_atm%idread)
    call b%get(c%mca_atm%ndatasets)
    call get_opt(b, c%mca_atm%missing)
    call b%get(c%mca_phase%nang)
    call b%get(c%mca_phase%npf)
    call b%get(c%mca_phase%reversed)
    call get_opt(b, c%mca_phase%angle_deg)
    call get_opt(b, c%mca_phase%p_file)
    call get_opt(b, c%mca_phase%p)
  end subroutine small_get

  !> Put what describes the temperatures of a cloud file (thermal runs) for the ranks that do
  !> not receive them (read_cloud_on_root per_node): whether the file has them, on planes or
  !> voxels, as perturbations or not, and their source. The values stay with the node's leader,
  !> which alone forms the Planck radiances of the voxels (kumo_scene_setup setup_thermal).
  subroutine temperature_put(b, c)
    type(bundle_t), intent(inout) :: b
    type(cloud_input_t), intent(in) :: c
    call b%put(allocated(c%temperature))
    call b%put(c%t_planes)
    call b%put(c%t_perturbation)
    call put_opt(b, c%t_source)
  end subroutine temperature_put

  !> Take the items of temperature_put out of a bundle, in the same order (`has_t`: the file has
  !> temperatures; `c%temperature` stays unallocated).
  subroutine temperature_get(b, c, has_t)
    type(bundle_t), intent(inout) :: b
    type(cloud_input_t), intent(inout) :: c
    logical, intent(out) :: has_t
    call b%get(has_t)
    call b%get(c%t_planes)
    call b%get(c%t_perturbation)
    call get_opt(b, c%t_source)
  end subroutine temperature_get

  !> Put an optics table in the Mie-table layout (a cloud file's ice optics table) into a bundle.
  subroutine mie_table_put(b, t)
    type(bundle_t), intent(inout) :: b
    type(mie_table_t), intent(in) :: t
    call b%put(t%wavelength_um)
    call b%put(real(t%m, wp))
    call b%put(aimag(t%m))
    call b%put(t%dist)
    call b%put(t%v_eff)
    call b%put(t%dlnr)
    call put_opt(b, t%r_eff_um)
    call put_opt(b, t%ext_per_lwc)
    call put_opt(b, t%ssa)
    call put_opt(b, t%g)
    call put_opt(b, t%angle_deg)
    call put_opt(b, t%phase)
  end subroutine mie_table_put

  !> Take a table of mie_table_put out of a bundle.
  subroutine mie_table_get(b, t)
    type(bundle_t), intent(inout) :: b
    type(mie_table_t), intent(out) :: t
    real(wp) :: re, im
    call b%get(t%wavelength_um)
    call b%get(re)
    call b%get(im)
    t%m = cmplx(re, im, wp)
    call b%get(t%dist)
    call b%get(t%v_eff)
    call b%get(t%dlnr)
    call get_opt(b, t%r_eff_um)
    call get_opt(b, t%ext_per_lwc)
    call get_opt(b, t%ssa)
    call get_opt(b, t%g)
    call get_opt(b, t%angle_deg)
    call get_opt(b, t%phase)
  end subroutine mie_table_get

  !> The MCARaTS atmosphere and phase functions of a cloud input (empty for other formats).
  subroutine put_mcarats(b, a, p)
    type(bundle_t), intent(inout) :: b
    type(mcarats_atm_t), intent(in) :: a
    type(mcarats_phase_t), intent(in) :: p
    call b%put(a%nx)
    call b%put(a%ny)
    call b%put(a%nz3)
    call b%put(a%mtprof)
    call b%put(a%nkd)
    call b%put(a%np3d)
    call b%put(a%idread)
    call b%put(a%ndatasets)
    call put_opt(b, a%tmpa)
    call put_opt(b, a%absg)
    call put_opt(b, a%ext)
    call put_opt(b, a%omg)
    call put_opt(b, a%apf)
    call put_opt(b, a%missing)
    call b%put(p%nang)
    call b%put(p%npf)
    call b%put(p%reversed)
    call put_opt(b, p%angle_deg)
    call put_opt(b, p%p_file)
    call put_opt(b, p%p)
  end subroutine put_mcarats

  subroutine get_mcarats(b, a, p)
    type(bundle_t), intent(inout) :: b
    type(mcarats_atm_t), intent(out) :: a
    type(mcarats_phase_t), intent(out) :: p
    call b%get(a%nx)
    call b%get(a%ny)
    call b%get(a%nz3)
    call b%get(a%mtprof)
    call b%get(a%nkd)
    call b%get(a%np3d)
    call b%get(a%idread)
    call b%get(a%ndatasets)
    call get_opt(b, a%tmpa)
    call get_opt(b, a%absg)
    call get_opt(b, a%ext)
    call get_opt(b, a%omg)
    call get_opt(b, a%apf)
    call get_opt(b, a%missing)
    call b%get(p%nang)
    call b%get(p%npf)
    call b%get(p%reversed)
    call get_opt(b, p%angle_deg)
    call get_opt(b, p%p_file)
    call get_opt(b, p%p)
  end subroutine get_mcarats

  ! ---- optional items ---------------------------------------------------------------------------

  subroutine put_opt_r1(b, x)
    type(bundle_t), intent(inout) :: b
    real(wp), allocatable, intent(in) :: x(:)
    call b%put(allocated(x))
    if (allocated(x)) call b%put(x)
  end subroutine put_opt_r1

  subroutine put_opt_r2(b, x)
    type(bundle_t), intent(inout) :: b
    real(wp), allocatable, intent(in) :: x(:, :)
    call b%put(allocated(x))
    if (allocated(x)) call b%put(x)
  end subroutine put_opt_r2

  subroutine put_opt_r3(b, x)
    type(bundle_t), intent(inout) :: b
    real(wp), allocatable, intent(in) :: x(:, :, :)
    call b%put(allocated(x))
    if (allocated(x)) call b%put(x)
  end subroutine put_opt_r3

  subroutine put_opt_r4(b, x)
    type(bundle_t), intent(inout) :: b
    real(wp), allocatable, intent(in) :: x(:, :, :, :)
    call b%put(allocated(x))
    if (allocated(x)) call b%put(x)
  end subroutine put_opt_r4

  !> Voxel fields (precision vp), apart from the generic put_opt so that vp = wp also builds.
  subroutine put_vox(b, x)
    type(bundle_t), intent(inout) :: b
    real(vp), allocatable, intent(in) :: x(:, :, :)
    call b%put(allocated(x))
    if (allocated(x)) call b%put(x)
  end subroutine put_vox

  subroutine put_opt_i3(b, x)
    type(bundle_t), intent(inout) :: b
    integer, allocatable, intent(in) :: x(:, :, :)
    call b%put(allocated(x))
    if (allocated(x)) call b%put(x)
  end subroutine put_opt_i3

  subroutine put_opt_text(b, x)
    type(bundle_t), intent(inout) :: b
    character(len=:), allocatable, intent(in) :: x
    call b%put(allocated(x))
    if (allocated(x)) call b%put(x)
  end subroutine put_opt_text

  subroutine get_opt_r1(b, x)
    type(bundle_t), intent(inout) :: b
    real(wp), allocatable, intent(out) :: x(:)
    logical :: has
    call b%get(has)
    if (has) call b%get(x)
  end subroutine get_opt_r1

  subroutine get_opt_r2(b, x)
    type(bundle_t), intent(inout) :: b
    real(wp), allocatable, intent(out) :: x(:, :)
    logical :: has
    call b%get(has)
    if (has) call b%get(x)
  end subroutine get_opt_r2

  subroutine get_opt_r3(b, x)
    type(bundle_t), intent(inout) :: b
    real(wp), allocatable, intent(out) :: x(:, :, :)
    logical :: has
    call b%get(has)
    if (has) call b%get(x)
  end subroutine get_opt_r3

  subroutine get_opt_r4(b, x)
    type(bundle_t), intent(inout) :: b
    real(wp), allocatable, intent(out) :: x(:, :, :, :)
    logical :: has
    call b%get(has)
    if (has) call b%get(x)
  end subroutine get_opt_r4

  subroutine get_vox(b, x)
    type(bundle_t), intent(inout) :: b
    real(vp), allocatable, intent(out) :: x(:, :, :)
    logical :: has
    call b%get(has)
    if (has) call b%get(x)
  end subroutine get_vox

  subroutine get_opt_i3(b, x)
    type(bundle_t), intent(inout) :: b
    integer, allocatable, intent(out) :: x(:, :, :)
    logical :: has
    call b%get(has)
    if (has) call b%get(x)
  end subroutine get_opt_i3

  subroutine get_opt_text(b, x)
    type(bundle_t), intent(inout) :: b
    character(len=:), allocatable, intent(out) :: x
    logical :: has
    call b%get(has)
    if (has) call b%get(x)
  end subroutine get_opt_text

end module kumo_cloud_share
