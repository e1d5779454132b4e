! SPDX-License-Identifier: BSD-3-Clause
!> Scenes for tests, built in code: slabs, layered columns and small 3-D fields.
module kumo_test_scenes
  use kumo_kinds, only: wp, dp, i8
  use kumo_error, only: error_t, set_error, str
  use kumo_phase, only: PHASE_ISOTROPIC, PHASE_RAYLEIGH, PHASE_HG
  use kumo_config, only: config_t
  use kumo_scene_setup, only: load_config
  use kumo_test_text, only: write_text
  use kumo_results, only: result_set_t, find_var
  use kumo_driver, only: simulate, run_summary_t
  use kumo_netcdf, only: write_scene_3d
  implicit none
  private
  public :: slab_config, set_layers, set_phases, run_config, run_namelist, run_groups, run_pair, &
            get_scalar, get_array, attach_scene

contains

  !> One homogeneous layer of optical depth `tau` (1000 m thick) over a Lambert surface.
  !> `phase` = 'iso', 'rayleigh' or a Henyey-Greenstein g given by `g`.
  function slab_config(tau, omega, phase, g, sza_deg, albedo, n_photons, n_batches) result(cfg)
    real(wp), intent(in) :: tau, omega, g, sza_deg, albedo
    character(len=*), intent(in) :: phase
    integer(i8), intent(in) :: n_photons
    integer, intent(in) :: n_batches
    type(config_t) :: cfg
    cfg%path = 'test.nml'
    cfg%atm%nz = 1
    cfg%atm%z = [0.0_wp, 1000.0_wp]
    cfg%atm%lx = 1000.0_wp
    cfg%atm%ly = 1000.0_wp
    cfg%atm%n_components = 1
    allocate (cfg%atm%ext1d(1, 1), cfg%atm%ssa1d(1, 1), cfg%atm%phase1d(1, 1))
    cfg%atm%ext1d = tau/1000.0_wp
    cfg%atm%ssa1d = omega
    cfg%atm%phase1d = 1
    cfg%atm%phase3d = [1]
    call set_phases(cfg, [character(len=8) :: phase], [g])
    cfg%surface%albedo = albedo
    cfg%source%sza_deg = sza_deg
    cfg%output%flux_levels = [0, 1]
    cfg%control%n_photons_per_batch = n_photons
    cfg%control%n_batches = n_batches
    cfg%control%seed = 7_i8
    cfg%control%verbose = 0
  end function slab_config

  !> A plane-parallel column of layers 1000 m thick, given top first: optical depth `tau`,
  !> single-scattering albedo `omega` and a phase function of its own per layer (`names` and `g`
  !> as in set_phases). kumo counts layers from the bottom.
  subroutine set_layers(cfg, tau, omega, names, g)
    type(config_t), intent(inout) :: cfg
    real(wp), intent(in) :: tau(:), omega(:), g(:)
    character(len=*), intent(in) :: names(:)
    real(wp), parameter :: DZ = 1000.0_wp
    integer :: nz, k, l
    nz = size(tau)
    cfg%atm%nz = nz
    cfg%atm%z = [(DZ*k, k=0, nz)]
    cfg%atm%lx = 1000.0_wp
    cfg%atm%ly = 1000.0_wp
    cfg%atm%n_components = 1
    allocate (cfg%atm%ext1d(nz, 1), cfg%atm%ssa1d(nz, 1), cfg%atm%phase1d(nz, 1))
    do l = 1, nz
      k = nz + 1 - l
      cfg%atm%ext1d(k, 1) = tau(l)/DZ
      cfg%atm%ssa1d(k, 1) = omega(l)
      cfg%atm%phase1d(k, 1) = l
    end do
    cfg%atm%phase3d = [1]
    call set_phases(cfg, names, g)
  end subroutine set_layers

  !> Set the phase-function list: names 'iso', 'rayleigh', 'hg' with asymmetry parameters g.
  subroutine set_phases(cfg, names, g)
    type(config_t), intent(inout) :: cfg
    character(len=*), intent(in) :: names(:)
    real(wp), intent(in) :: g(:)
    integer :: i
    cfg%phase%n_phase = size(names)
    allocate (cfg%phase%kind(size(names)), cfg%phase%kind_name(size(names)), &
              cfg%phase%file(size(names)))
    cfg%phase%g = g
    cfg%phase%file = ''
    do i = 1, size(names)
      select case (trim(names(i)))
      case ('iso')
        cfg%phase%kind(i) = PHASE_ISOTROPIC
        cfg%phase%kind_name(i) = 'isotropic'
      case ('rayleigh')
        cfg%phase%kind(i) = PHASE_RAYLEIGH
        cfg%phase%kind_name(i) = 'rayleigh'
      case default
        cfg%phase%kind(i) = PHASE_HG
        cfg%phase%kind_name(i) = 'hg'
      end select
    end do
  end subroutine set_phases

  !> Write a 3-D region (nx, ny, nz3, 1) to `path` and point the configuration at it.
  subroutine attach_scene(cfg, path, k3d_bottom, ext, ssa, phase_index, error, write_file, &
                          temperature)
    type(config_t), intent(inout) :: cfg
    character(len=*), intent(in) :: path
    integer, intent(in) :: k3d_bottom
    real(wp), intent(in) :: ext(:, :, :), ssa(:, :, :)
    integer, intent(in) :: phase_index
    type(error_t), allocatable, intent(out) :: error
    logical, intent(in), optional :: write_file  !! .false.: only point at the file (other ranks)
    real(wp), intent(in), optional :: temperature(:, :, :)  !! voxel temperatures [K]
    real(wp), allocatable :: e4(:, :, :, :), s4(:, :, :, :)
    logical :: do_write
    do_write = .true.
    if (present(write_file)) do_write = write_file
    if (do_write) then
      e4 = reshape(ext, [shape(ext), 1])
      s4 = reshape(ssa, [shape(ssa), 1])
      call write_scene_3d(path, e4, s4, error=error, temperature=temperature)
      if (allocated(error)) return
    end if
    cfg%atm%scene_file = path
    cfg%atm%k3d_bottom = k3d_bottom
    cfg%atm%nx = size(ext, 1)
    cfg%atm%ny = size(ext, 2)
    cfg%atm%nz3 = size(ext, 3)
    cfg%atm%n_components_3d = 1
    cfg%atm%phase3d = [phase_index]
  end subroutine attach_scene

  !> Run a configuration; an error from kumo becomes the test's error.
  subroutine run_config(cfg, set, error, summary)
    type(config_t), intent(in) :: cfg
    type(result_set_t), intent(out) :: set
    type(error_t), allocatable, intent(out) :: error
    type(run_summary_t), intent(out), optional :: summary
    type(run_summary_t) :: s
    call simulate(cfg, set, s, error)
    if (present(summary)) summary = s
  end subroutine run_config

  !> The namelist groups of a small test run: &kumo_control (quiet), &kumo_source with `source`
  !> inside, &kumo_surface with `surface` inside if given, and &kumo_output writing `out`.
  function run_groups(n_photons, n_batches, seed, source, out, surface) result(text)
    integer, intent(in) :: n_photons, n_batches, seed
    character(len=*), intent(in) :: source, out
    character(len=*), intent(in), optional :: surface
    character(len=:), allocatable :: text
    character(len=*), parameter :: NL = new_line('a')
    text = '&kumo_control n_photons_per_batch = '//str(n_photons)//', n_batches = '// &
           str(n_batches)//', seed = '//str(seed)//', verbose = 0 /'//NL// &
           '&kumo_source '//source//' /'//NL
    if (present(surface)) text = text//'&kumo_surface '//surface//' /'//NL
    text = text//'&kumo_output file = '''//out//''' /'//NL
  end function run_groups

  !> Write the namelist `text` to `path`, read it as a user's file and run it.
  subroutine run_namelist(path, text, set, error)
    character(len=*), intent(in) :: path, text
    type(result_set_t), intent(out) :: set
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    call write_text(path, text)
    call load_config(path, cfg, error)
    if (allocated(error)) return
    call run_config(cfg, set, error)
  end subroutine run_namelist

  !> Run two configurations, `a` first (an error of `a` skips `b`), for tests that compare them.
  subroutine run_pair(a, set_a, b, set_b, error, summary_a, summary_b)
    type(config_t), intent(in) :: a, b
    type(result_set_t), intent(out) :: set_a, set_b
    type(error_t), allocatable, intent(out) :: error
    type(run_summary_t), intent(out), optional :: summary_a, summary_b
    call run_config(a, set_a, error, summary_a)
    if (allocated(error)) return
    call run_config(b, set_b, error, summary_b)
  end subroutine run_pair

  !> Mean and standard error of a scalar output.
  subroutine get_scalar(set, name, mean, stderr, error)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: name
    real(dp), intent(out) :: mean, stderr
    type(error_t), allocatable, intent(inout) :: error
    integer :: i
    mean = 0.0_dp
    stderr = 0.0_dp
    i = find_var(set, name)
    if (i == 0) then
      if (.not. allocated(error)) call set_error(error, 'output '//name//' is missing')
      return
    end if
    mean = set%vars(i)%mean(1)
    if (allocated(set%vars(i)%stderr)) stderr = set%vars(i)%stderr(1)
  end subroutine get_scalar

  !> Mean and standard error of an array output (flattened).
  subroutine get_array(set, name, mean, stderr, error)
    type(result_set_t), intent(in) :: set
    character(len=*), intent(in) :: name
    real(dp), allocatable, intent(out) :: mean(:), stderr(:)
    type(error_t), allocatable, intent(inout) :: error
    integer :: i
    i = find_var(set, name)
    if (i == 0) then
      if (.not. allocated(error)) call set_error(error, 'output '//name//' is missing')
      allocate (mean(0), stderr(0))
      return
    end if
    mean = set%vars(i)%mean
    if (allocated(set%vars(i)%stderr)) then
      stderr = set%vars(i)%stderr
    else
      allocate (stderr(size(mean)))
      stderr = 0.0_dp
    end if
  end subroutine get_array
end module kumo_test_scenes
