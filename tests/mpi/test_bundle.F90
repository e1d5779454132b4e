! SPDX-License-Identifier: BSD-3-Clause
!> bundle_t: rank 0's items reach every rank with their bounds and bits, in the order put;
!> rank 0's error reaches every rank with its message; an empty bundle shares nothing; the
!> grid of a cloud file read through load_config (on rank 0 alone) reaches every rank; and a
!> cloud file of each kind of content read on rank 0 (read_cloud_on_root) is on every rank
!> what the rank reads itself, component by component. Run on several ranks in MPI builds (and
!> alone in serial builds, where share moves nothing).
module test_bundle_suite
  use kumo_kinds, only: dp, sp, vp
  use kumo_error, only: error_t, set_error, str
  use kumo_testing, only: unittest_t, new_unittest, check
  use kumo_parallel, only: par_is_root, par_rank, par_size
  use kumo_bundle, only: bundle_t
  use kumo_config, only: config_t
  use kumo_scene_setup, only: load_config
  use kumo_cloud_input, only: cloud_input_t, cloud_request_t, read_cloud_input
  use kumo_cloud_share, only: read_cloud_on_root
  implicit none
  private
  public :: collect_bundle

contains

  function collect_bundle() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('items_bounds_bits', t_items), &
             new_unittest('root_error_everywhere', t_error), &
             new_unittest('empty_bundle', t_empty), &
             new_unittest('cloud_grid_via_load_config', t_cloud_grid), &
             new_unittest('cloud_files_on_every_rank', t_cloud_files)]
  end function collect_bundle

  !> Every kind of item, with bounds other than 1 and values that round-trip only bit for bit;
  !> ranks other than 0 start with other values, and put values that share must discard.
  subroutine t_items(error)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: b
    real(dp), allocatable :: r1(:), r2(:, :), r3(:, :, :), r4(:, :, :, :)
    real(sp), allocatable :: s3(:, :, :)
    integer, allocatable :: i1(:), i2(:, :), i3(:, :, :), i4(:, :, :, :)
    real(dp) :: r0
    integer :: i0, k
    logical :: l0, l1
    character(len=:), allocatable :: t1, t2, t3
    type(error_t), allocatable :: err
    if (par_is_root()) then
      ! allocated first: an assignment to an unallocated array would take bounds 1
      allocate (r1(0:5), r3(1:2, -1:0, 2:3), i1(-2:1))
      r1 = ref_r1()
      r2 = reshape(ref_r1(), [3, 2])
      r3 = ref_r3()
      r4 = reshape([(real(k, dp)*0.1_dp, k=1, 16)], [2, 2, 2, 2])
      i1 = ref_i1()
      i2 = reshape([(k, k=1, 6)], [2, 3])
      i3 = reshape([(k, k=1, 8)], [2, 2, 2])
      i4 = reshape([(k, k=1, 16)], [2, 2, 2, 2])
      allocate (s3(0:1, 2, -1:1))
      s3 = reshape([(1.0_sp/real(k, sp), k=1, 12)], [2, 2, 3])
      call b%put(1.0_dp/3.0_dp)
      call b%put(r1)
      call b%put(r2)
      call b%put(r3)
      call b%put(r4)
      call b%put(-7)
      call b%put(i1)
      call b%put(i2)
      call b%put(i3)
      call b%put(i4)
      call b%put(.true.)
      call b%put('grid of "x"'//new_line('a')//'line 2')
      call b%put('')
      call b%put(.false.)
      call b%put(repeat('z', 300))
      call b%put(s3)
    else
      call b%put(99.0_dp)   ! discarded by share
    end if
    call b%share(err)
    call check(error, .not. allocated(err), 'share with no error on rank 0 gave one on rank '// &
               str(par_rank()))
    if (allocated(error)) return
    call b%get(r0)
    call b%get(r1)
    call b%get(r2)
    call b%get(r3)
    call b%get(r4)
    call b%get(i0)
    call b%get(i1)
    call b%get(i2)
    call b%get(i3)
    call b%get(i4)
    call b%get(l0)
    call b%get(t1)
    call b%get(t2)
    call b%get(l1)
    call b%get(t3)
    call b%get(s3)
    call check(error, r0 == 1.0_dp/3.0_dp, 'real scalar')
    call check(error, lbound(r1, 1) == 0 .and. ubound(r1, 1) == 5, 'bounds of a (0:5) array: '// &
               str(lbound(r1, 1))//':'//str(ubound(r1, 1)))
    if (allocated(error)) return
    call check(error, all(r1 == ref_r1()), 'values of a real array')
    call check(error, all(shape(r2) == [3, 2]) .and. all(r2 == reshape(ref_r1(), [3, 2])), &
               'real rank 2')
    call check(error, all(lbound(r3) == [1, -1, 2]) .and. all(r3 == ref_r3()), 'real rank 3 (bounds)')
    call check(error, all(shape(r4) == [2, 2, 2, 2]) .and. r4(2, 2, 2, 2) == 16.0_dp*0.1_dp, 'real rank 4')
    call check(error, i0 == -7, 'integer scalar')
    call check(error, lbound(i1, 1) == -2 .and. all(i1 == ref_i1()), 'integer (-2:1) array')
    call check(error, all(shape(i2) == [2, 3]) .and. i2(2, 3) == 6, 'integer rank 2')
    call check(error, sum(i3) == 36 .and. i3(2, 2, 2) == 8, 'integer rank 3')
    call check(error, sum(i4) == 136, 'integer rank 4')
    call check(error, l0 .and. .not. l1, 'logicals')
    call check(error, t1 == 'grid of "x"'//new_line('a')//'line 2' .and. len(t2) == 0 .and. &
               t3 == repeat('z', 300), 'texts')
    call check(error, all(lbound(s3) == [0, 1, -1]) .and. all(shape(s3) == [2, 2, 3]), &
               'single rank 3 (bounds)')
    if (allocated(error)) return
    call check(error, all(s3 == reshape([(1.0_sp/real(k, sp), k=1, 12)], [2, 2, 3])), &
               'single rank 3 (values)')
  end subroutine t_items

  !> Rank 0's read failed: every rank gets its message, and no items.
  subroutine t_error(error)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: b
    type(error_t), allocatable :: err
    if (par_is_root()) then
      call b%put(1)
      call set_error(err, 'cannot open "scene.nc": No such file')
    else
      call set_error(err, 'a stale error of this rank')
    end if
    call b%share(err)
    call check(error, allocated(err), 'rank '//str(par_rank())//' got no error')
    if (allocated(error)) return
    call check(error, err%message == 'cannot open "scene.nc": No such file', 'rank '// &
               str(par_rank())//' got the message "'//err%message//'"')
  end subroutine t_error

  !> Nothing put: share and no get; a second share of the same bundle after items is fine.
  subroutine t_empty(error)
    type(error_t), allocatable, intent(out) :: error
    type(bundle_t) :: b
    type(error_t), allocatable :: err
    integer :: n
    call b%share(err)
    call check(error, .not. allocated(err), 'empty bundle: an error')
    if (allocated(error)) return
    if (par_is_root()) call b%put(par_size())
    call b%share(err)
    call b%get(n)
    call check(error, n == par_size(), 'second share: '//str(n))
  end subroutine t_empty

  !> load_config with a cloud file: every rank has the file's grid (2 x 2 columns of 100 m,
  !> edges 500, 550, 600 m below which one layer from the ground is added), although only rank
  !> 0 opened the file.
  subroutine t_cloud_grid(error)
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(error_t), allocatable :: err
    integer :: unit
    if (par_is_root()) then
      ! a 2-parameter SHDOM/I3RC LWC file: nx ny nz, dx dy [km], the nz + 1 layer edges [km],
      ! their temperatures, then ix iy iz lwc reff
      open (newunit=unit, file='bundle_cloud.lwc', status='replace', action='write')
      write (unit, '(a)') '2 parameter LWC file'
      write (unit, '(a)') '2 2 2'
      write (unit, '(a)') '0.1 0.1'
      write (unit, '(a)') '0.50 0.55 0.60'
      write (unit, '(a)') '285 284 283'
      write (unit, '(a)') '1 1 1 0.1 10.0'
      close (unit)
    end if
    ! the namelist as text (as run_case passes it); only rank 0 opens the cloud file, and
    ! load_config's broadcast orders it after the write above
    call load_config('bundle_cloud.nml', cfg, err, text= &
                     "&kumo_cloud cloud_file = 'bundle_cloud.lwc', cloud_format = 'lwc' /"// &
                     new_line('a')//"&kumo_source wavelength_um = 0.55 /"//new_line('a'))
    call check(error, .not. allocated(err), 'load_config failed: '//merge_message(err))
    if (allocated(error)) return
    call check(error, cfg%cloud%grid%nx == 2 .and. cfg%cloud%grid%ny == 2 .and. &
               cfg%cloud%grid%nz == 2, 'grid sizes on rank '//str(par_rank()))
    call check(error, cfg%atm%nz == 3 .and. abs(cfg%atm%z(1 + 3) - 600.0_dp) < 1.0e-6_dp, &
               'levels on rank '//str(par_rank())//': nz = '//str(cfg%atm%nz))
    call check(error, abs(cfg%atm%lx - 200.0_dp) < 1.0e-6_dp, 'lx on rank '//str(par_rank()))
    call check(error, .not. allocated(cfg%cloud%grid%lwc), 'field data kept in the grid')
  end subroutine t_cloud_grid

  !> Cloud files with every kind of content, written by rank 0: an LWC file (water content and
  !> radius, a temperature profile), a property file (extinction, albedo, Legendre phase
  !> functions, temperatures), a MYSTIC file of flag 1 (Henyey-Greenstein g per cell) and an
  !> MCARaTS atmosphere with its phase-function file (binary, described by .ctl files). Each is
  !> read on rank 0 and shared; every rank then reads it itself and finds the same components.
  subroutine t_cloud_files(error)
    type(error_t), allocatable, intent(out) :: error
    type(cloud_request_t) :: req
    integer :: u
    if (par_is_root()) then
      open (newunit=u, file='share.lwc', status='replace', action='write')
      write (u, '(a)') '2 parameter LWC file'
      write (u, '(a)') '2 1 2'
      write (u, '(a)') '0.1 0.1'
      write (u, '(a)') '0.50 0.55 0.60'
      write (u, '(a)') '285 284 283'
      write (u, '(a)') '1 1 1 0.1 10.0'
      write (u, '(a)') '2 1 2 0.3 12.5'
      close (u)
      open (newunit=u, file='share.prp', status='replace', action='write')
      write (u, '(a)') 'Tabulated phase function property file'
      write (u, '(a)') '2 1 2'
      write (u, '(a)') '0.1 0.1 0.50 0.55 0.60'
      write (u, '(a)') '2'
      write (u, '(a)') '2 2.4 1.5'
      write (u, '(a)') '1 0.9'
      write (u, '(a)') '1 1 1 280.0 10.0 0.99 1'
      write (u, '(a)') '2 1 1 281.0 20.0 0.98 2'
      write (u, '(a)') '1 1 2 282.0 0.0 1.0 1'
      write (u, '(a)') '2 1 2 283.0 5.0 0.97 2'
      close (u)
      open (newunit=u, file='share.mystic', status='replace', action='write')
      write (u, '(a)') '2 1 2 1'
      write (u, '(a)') '0.1 0.1 0.50 0.55 0.60'
      write (u, '(a)') '1 1 1 10.0 0.85 0.99'
      write (u, '(a)') '2 1 2 20.0 0.7 0.98'
      close (u)
      call write_mcarats()
    end if
    req%temperature = .true.
    req%format = 'lwc'
    req%path = 'share.lwc'
    call same_on_every_rank(req, 'LWC file', error)
    if (allocated(error)) return
    req%format = 'prp'
    req%path = 'share.prp'
    call same_on_every_rank(req, 'property file', error)
    if (allocated(error)) return
    req%format = 'mystic'
    req%path = 'share.mystic'
    call same_on_every_rank(req, 'MYSTIC file', error)
    if (allocated(error)) return
    req%format = 'mcarats'
    req%path = 'share.atm.ctl'
    req%mcarats%phase_path = 'share.sca.ctl'
    req%mcarats%dx = 100.0_dp
    req%mcarats%dy = 100.0_dp
    req%mcarats%k3d_bottom = 2
    allocate (req%mcarats%z(0:1))
    req%mcarats%z = [500.0_dp, 700.0_dp]
    call same_on_every_rank(req, 'MCARaTS atmosphere', error)
  end subroutine t_cloud_files

  !> A 2 x 1 x 1 MCARaTS atmosphere (one component, HG g = 0.5 and a blend of tables 1 and 2)
  !> and two phase functions on four angles, raw float32 in the machine's byte order (the .ctl
  !> files give no OPTIONS) with their .ctl files.
  subroutine write_mcarats()
    integer :: u
    open (newunit=u, file='share.atm.ctl', status='replace', action='write')
    write (u, '(a)') 'DSET ^share.atm', 'TITLE two voxels', &
      'UNDEF 1.0e+37', 'XDEF 2 LINEAR 1 1', 'YDEF 1 LINEAR 1 1', 'ZDEF 1 LINEAR 1 1', &
      'TDEF 1 LINEAR 00:00Z01JAN2000 1YR', 'VARS 5', 'tmpa3d 1 99 T', 'abst3d 1 99 abs', &
      'extp3d 1 99 ext', 'omgp3d 1 99 omg', 'apfp3d 1 99 apf', 'ENDVARS'
    close (u)
    open (newunit=u, file='share.atm', status='replace', action='write', access='stream', &
          form='unformatted')
    write (u) [1.5_sp, -2.0_sp, 1.0e-4_sp, 0.0_sp, 0.01_sp, 0.02_sp, 0.9_sp, 0.999_sp, 0.5_sp, &
               1.5_sp]
    close (u)
    open (newunit=u, file='share.sca.ctl', status='replace', action='write')
    write (u, '(a)') 'DSET ^share.sca', 'TITLE two tables', &
      'UNDEF 1.0e+37', 'XDEF 4 LINEAR 1 1', 'YDEF 1 LINEAR 1 1', 'ZDEF 2 LINEAR 1 1', &
      'TDEF 1 LINEAR 00:00Z01JAN2000 1YR', 'VARS 2', 'ang 1 99 angles', 'phs 2 99 phase', &
      'ENDVARS'
    close (u)
    open (newunit=u, file='share.sca', status='replace', action='write', access='stream', &
          form='unformatted')
    write (u) [0.0_sp, 60.0_sp, 120.0_sp, 180.0_sp, 4.0_sp, 1.0_sp, 0.5_sp, 0.5_sp, 1.0_sp, &
               1.0_sp, 1.0_sp, 1.0_sp]
    close (u)
  end subroutine write_mcarats

  !> Read `req` on rank 0 and share it, read it here too, and compare every component.
  subroutine same_on_every_rank(req, what, error)
    type(cloud_request_t), intent(in) :: req
    character(len=*), intent(in) :: what
    type(error_t), allocatable, intent(out) :: error
    type(cloud_input_t) :: a, b
    type(error_t), allocatable :: err
    character(len=:), allocatable :: diff
    call read_cloud_on_root(req, a, err)
    call check(error, .not. allocated(err), what//' on rank 0: '//merge_message(err))
    if (allocated(error)) return
    call read_cloud_input(req, b, err)
    call check(error, .not. allocated(err), what//' on rank '//str(par_rank())//': '// &
               merge_message(err))
    if (allocated(error)) return
    diff = cloud_diff(a, b)
    call check(error, len(diff) == 0, what//', rank '//str(par_rank())//': shared and own '// &
               'read differ in'//diff)
  end subroutine same_on_every_rank

  !> The components in which two cloud inputs differ (' name' each; '' when none).
  function cloud_diff(a, b) result(d)
    type(cloud_input_t), intent(in) :: a, b
    character(len=:), allocatable :: d
    d = ''
    if (a%format /= b%format) d = d//' format'
    if (any([a%nx, a%ny, a%nz, a%content] /= [b%nx, b%ny, b%nz, b%content])) d = d//' sizes'
    if (a%dx /= b%dx .or. a%dy /= b%dy) d = d//' widths'
    if ((a%points .neqv. b%points) .or. (a%has_ice .neqv. b%has_ice) .or. &
        (a%t_planes .neqv. b%t_planes) .or. (a%t_perturbation .neqv. b%t_perturbation)) &
      d = d//' flags'
    if (.not. same1(a%z, b%z)) d = d//' z'
    if (.not. same1(a%pressure, b%pressure)) d = d//' pressure'
    if (.not. same1(a%t_profile, b%t_profile)) d = d//' t_profile'
    if (.not. same1(a%h2o_profile, b%h2o_profile)) d = d//' h2o_profile'
    if (.not. samev(a%lwc, b%lwc)) d = d//' lwc'
    if (.not. samev(a%reff, b%reff)) d = d//' reff'
    if (.not. samev(a%ext, b%ext)) d = d//' ext'
    if (.not. samev(a%ssa, b%ssa)) d = d//' ssa'
    if (.not. samev(a%iwc, b%iwc)) d = d//' iwc'
    if (.not. samev(a%reff_ice, b%reff_ice)) d = d//' reff_ice'
    if (.not. samev(a%temperature, b%temperature)) d = d//' temperature'
    if (allocated(a%iphase) .neqv. allocated(b%iphase)) then
      d = d//' iphase'
    else if (allocated(a%iphase)) then
      if (any(shape(a%iphase) /= shape(b%iphase))) then
        d = d//' iphase'
      else if (any(a%iphase /= b%iphase)) then
        d = d//' iphase'
      end if
    end if
    if (.not. same2(a%chi, b%chi)) d = d//' chi'
    if (.not. same1(a%hg_g, b%hg_g)) d = d//' hg_g'
    if (.not. samet(a%pressure_source, b%pressure_source)) d = d//' pressure_source'
    if (.not. samet(a%t_source, b%t_source)) d = d//' t_source'
    if (.not. samet(a%notes, b%notes)) d = d//' notes'
    if (.not. samet(a%missing, b%missing)) d = d//' missing'
    associate (p => a%mca_atm, q => b%mca_atm)
      if (any([p%nx, p%ny, p%nz3, p%mtprof, p%nkd, p%np3d, p%idread, p%ndatasets] /= &
              [q%nx, q%ny, q%nz3, q%mtprof, q%nkd, q%np3d, q%idread, q%ndatasets])) &
        d = d//' mca_atm sizes'
      if (.not. same3(p%tmpa, q%tmpa)) d = d//' mca_atm%tmpa'
      if (.not. same4(p%absg, q%absg)) d = d//' mca_atm%absg'
      if (.not. same4(p%ext, q%ext)) d = d//' mca_atm%ext'
      if (.not. same4(p%omg, q%omg)) d = d//' mca_atm%omg'
      if (.not. same4(p%apf, q%apf)) d = d//' mca_atm%apf'
      if (.not. samet(p%missing, q%missing)) d = d//' mca_atm%missing'
    end associate
    associate (p => a%mca_phase, q => b%mca_phase)
      if (p%nang /= q%nang .or. p%npf /= q%npf .or. (p%reversed .neqv. q%reversed)) &
        d = d//' mca_phase sizes'
      if (.not. same1(p%angle_deg, q%angle_deg)) d = d//' mca_phase%angle_deg'
      if (.not. same2(p%p_file, q%p_file)) d = d//' mca_phase%p_file'
      if (.not. same2(p%p, q%p)) d = d//' mca_phase%p'
    end associate
  end function cloud_diff

  logical function same1(x, y) result(same)
    real(dp), allocatable, intent(in) :: x(:), y(:)
    same = allocated(x) .eqv. allocated(y)
    if (same .and. allocated(x)) same = all(shape(x) == shape(y)) .and. &
                                        all(lbound(x) == lbound(y))
    if (same .and. allocated(x)) same = all(x == y)
  end function same1

  logical function same2(x, y) result(same)
    real(dp), allocatable, intent(in) :: x(:, :), y(:, :)
    same = allocated(x) .eqv. allocated(y)
    if (same .and. allocated(x)) same = all(shape(x) == shape(y)) .and. &
                                        all(lbound(x) == lbound(y))
    if (same .and. allocated(x)) same = all(x == y)
  end function same2

  logical function same3(x, y) result(same)
    real(dp), allocatable, intent(in) :: x(:, :, :), y(:, :, :)
    same = allocated(x) .eqv. allocated(y)
    if (same .and. allocated(x)) same = all(shape(x) == shape(y))
    if (same .and. allocated(x)) same = all(x == y)
  end function same3

  logical function same4(x, y) result(same)
    real(dp), allocatable, intent(in) :: x(:, :, :, :), y(:, :, :, :)
    same = allocated(x) .eqv. allocated(y)
    if (same .and. allocated(x)) same = all(shape(x) == shape(y))
    if (same .and. allocated(x)) same = all(x == y)
  end function same4

  logical function samev(x, y) result(same)
    real(vp), allocatable, intent(in) :: x(:, :, :), y(:, :, :)
    same = allocated(x) .eqv. allocated(y)
    if (same .and. allocated(x)) same = all(shape(x) == shape(y))
    if (same .and. allocated(x)) same = all(x == y)
  end function samev

  logical function samet(x, y) result(same)
    character(len=:), allocatable, intent(in) :: x, y
    same = allocated(x) .eqv. allocated(y)
    if (same .and. allocated(x)) same = x == y
  end function samet

  function merge_message(err) result(m)
    type(error_t), allocatable, intent(in) :: err
    character(len=:), allocatable :: m
    m = ''
    if (allocated(err)) m = err%message
  end function merge_message

  function ref_r1() result(x)
    real(dp), allocatable :: x(:)
    allocate (x(0:5))
    x = [1.0_dp/3.0_dp, -0.0_dp, huge(1.0_dp), tiny(1.0_dp), 2.0_dp/7.0_dp, -1.0e-300_dp]
  end function ref_r1

  function ref_r3() result(x)
    real(dp), allocatable :: x(:, :, :)
    integer :: i, j, k
    allocate (x(1:2, -1:0, 2:3))
    do k = 2, 3
      do j = -1, 0
        do i = 1, 2
          x(i, j, k) = real(i, dp)/real(3 + j + 7*k, dp)
        end do
      end do
    end do
  end function ref_r3

  function ref_i1() result(x)
    integer, allocatable :: x(:)
    allocate (x(-2:1))
    x = [huge(1), -huge(1), 0, 42]
  end function ref_i1

end module test_bundle_suite

program test_bundle
  use kumo_testing, only: run_unittests
  use kumo_parallel, only: par_init, par_finalize
  use test_bundle_suite, only: collect_bundle
  implicit none
  integer :: n_failed
  call par_init()
  call run_unittests('bundle', collect_bundle(), n_failed)
  call par_finalize()
  if (n_failed > 0) error stop 1
end program test_bundle
