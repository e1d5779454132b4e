! SPDX-License-Identifier: BSD-3-Clause
!> Super-voxel majorant grid and layer classes: the majorant bounds every voxel of its block,
!> uniform fields merge into one block, clear blocks have a zero majorant, and the merge stops
!> where the MCARaTS rule says it must.
module test_supervoxel_suite
  use kumo_kinds, only: wp, vp
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close
  use kumo_supervoxel, only: supervoxel_grid_t, supervoxel_options_t, build_supervoxels, &
                             supervoxel_majorants, merge_ok, columns_merge_ok
  use kumo_atmosphere, only: atmosphere_t, atmosphere_options_t, atmosphere_init, &
                             atmosphere_begin, atmosphere_put_layer, atmosphere_end, &
                             atmosphere_swap_background, EXT_MAX, voxel_ext, voxel_omg, VOXEL_CLEAR, &
                             similarity_blend_weight, &
                             LAYER_CLEAR, LAYER_ABSORBING, LAYER_SCATTERING, LAYER_3D
  use kumo_phase, only: phase_t, new_phase_isotropic, new_phase_hg
  implicit none
  private
  public :: collect_supervoxel

contains

  function collect_supervoxel() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('majorant_bounds_every_voxel', test_bounds), &
             new_unittest('uniform_field_is_one_block', test_uniform), &
             new_unittest('clear_blocks_have_zero_majorant', test_clear), &
             new_unittest('thick_contrasted_field_stays_fine', test_thick), &
             new_unittest('disabled_means_one_global_majorant', test_disabled), &
             new_unittest('layer_classes', test_classes), &
             new_unittest('component_mixing', test_mixing), &
             new_unittest('voxels_put_by_layer_with_blends', test_put_layers), &
             new_unittest('similarity_scales_each_component_and_blend', test_similarity), &
             new_unittest('kept_blocks_new_majorants', test_kept_layout), &
             new_unittest('carried_column_sums_merge_alike', test_columns_merge), &
             new_unittest('swapped_background_equals_a_new_build', test_swap_background), &
             new_unittest('swapped_band_equals_a_new_build', test_swap_band)]
  end function collect_supervoxel

  !> Every voxel of a and b has the same extinction and albedo as the photon loop reads them
  !> (voxel_ext, voxel_omg: a voxel without components holds VOXEL_CLEAR after a swap).
  logical function same_voxel_optics(a, b) result(same)
    type(atmosphere_t), intent(in) :: a, b
    integer :: ix, iy, kr
    same = a%nx == b%nx .and. a%ny == b%ny .and. a%n3 == b%n3
    if (.not. same) return
    do kr = 1, a%n3
      do iy = 1, a%ny
        do ix = 1, a%nx
          same = same .and. voxel_ext(a, ix, iy, kr) == voxel_ext(b, ix, iy, kr) .and. &
                 voxel_omg(a, ix, iy, kr) == voxel_omg(b, ix, iy, kr) .and. &
                 voxel_ext(a, ix, iy, kr) >= 0.0_vp .and. voxel_omg(a, ix, iy, kr) >= 0.0_vp
        end do
      end do
    end do
  end function same_voxel_optics

  function field(nx, ny, nz) result(ext)
    integer, intent(in) :: nx, ny, nz
    real(vp) :: ext(nx, ny, nz)
    integer :: i, j, k
    do k = 1, nz
      do j = 1, ny
        do i = 1, nx
          ext(i, j, k) = real(max(0.0_wp, 1.0e-3_wp*(sin(0.9_wp*i) + cos(1.7_wp*j) + 0.2_wp*k)), vp)
        end do
      end do
    end do
  end function field

  !> The vertical merge test of build_supervoxels carries each column's maximum and sum from
  !> one group of layers to the next (columns_merge_ok); it must answer as merge_ok does on the
  !> layers themselves, for every group, on fields with clear columns and a range of merge
  !> factors (answers of both kinds occur).
  subroutine test_columns_merge(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: NX = 9, NY = 6, NZ = 8
    type(supervoxel_options_t) :: opts
    real(vp) :: ext(NX, NY, NZ), cmax(NX, NY)
    real(wp) :: csum(NX, NY), dz(NZ), f
    integer :: kb, kt, k, n_yes, n_no, ifac
    logical :: a, b
    ext = field(NX, NY, NZ)
    ext(:, 2, :) = 0.0_vp                       ! a clear row of columns
    ext(3, :, 4) = 50.0_vp*ext(3, :, 4)         ! a dense patch in one layer
    dz = [(10.0_wp + 7.0_wp*k, k=1, NZ)]
    n_yes = 0
    n_no = 0
    do ifac = 0, 6
      f = 0.25_wp*2.0_wp**ifac
      opts%fsupg = f
      opts%fsupi = 1.0_wp + 0.1_wp*ifac
      do kb = 1, NZ - 1
        cmax = ext(:, :, kb)
        csum = 0.0_wp + real(ext(:, :, kb), wp)*dz(kb)
        do kt = kb, NZ - 1
          a = merge_ok(ext(:, :, kb:kt + 1), dz(kb:kt + 1), 40.0_wp, 30.0_wp, 1, 1, opts)
          b = columns_merge_ok(cmax, csum, ext(:, :, kt + 1), dz(kb:kt + 1), 40.0_wp, 30.0_wp, &
                               opts)
          call check(error, a .eqv. b, 'the carried sums merge as the layers do')
          if (allocated(error)) return
          if (a) then
            n_yes = n_yes + 1
          else
            n_no = n_no + 1
          end if
          cmax = max(cmax, ext(:, :, kt + 1))
          csum = csum + real(ext(:, :, kt + 1), wp)*dz(kt + 1)
        end do
      end do
    end do
    call check(error, n_yes > 0 .and. n_no > 0, 'both answers occur')
  end subroutine test_columns_merge

  subroutine test_bounds(error)
    type(error_t), allocatable, intent(out) :: error
    type(supervoxel_grid_t) :: sv
    type(supervoxel_options_t) :: opts
    real(vp) :: ext(13, 7, 5)
    integer :: s, i, j, k, jx, jy
    ext = field(13, 7, 5)
    call build_supervoxels(ext, 50.0_wp, 50.0_wp, [100.0_wp, 100.0_wp, 50.0_wp, 200.0_wp, &
                           100.0_wp], opts, sv)
    call check(error, sv%ns >= 1 .and. sv%kb(1) == 1 .and. sv%kt(sv%ns) == 5, &
               'super-layers cover the region')
    do k = 1, 5
      s = sv%sl_of_layer(k)
      call check(error, k >= sv%kb(s) .and. k <= sv%kt(s), 'layer inside its super-layer')
      do j = 1, 7
        do i = 1, 13
          jx = (i - 1)/sv%bx(s) + 1
          jy = (j - 1)/sv%by(s) + 1
          call check(error, sv%maj(sv%off(s) + jx + (jy - 1)*sv%nbx(s)) >= ext(i, j, k), &
                     'majorant below a voxel extinction')
          if (allocated(error)) return
        end do
      end do
    end do
  end subroutine test_bounds

  !> Blocks kept from another field (broadband runs: the set-up's g-point) with the majorants
  !> of a new one: the same blocks, every majorant the largest extinction of its block, and for
  !> the field the blocks were made for, the same majorants as the full build.
  subroutine test_kept_layout(error)
    type(error_t), allocatable, intent(out) :: error
    type(supervoxel_grid_t) :: sv, kept
    type(supervoxel_options_t) :: opts
    real(vp) :: ext(13, 7, 5), ext2(13, 7, 5), mx
    real(wp) :: dz(5)
    integer :: s, i, j, k, jx, jy, b
    ext = field(13, 7, 5)
    dz = [100.0_wp, 100.0_wp, 50.0_wp, 200.0_wp, 100.0_wp]
    call build_supervoxels(ext, 50.0_wp, 50.0_wp, dz, opts, sv)
    call supervoxel_majorants(ext, sv, kept)
    call check(error, all(kept%maj == sv%maj), 'same field: the majorants of the full build')
    ! a new field: a layer-wise background added (the gas of another g-point)
    do k = 1, 5
      ext2(:, :, k) = ext(:, :, k) + real(1.0e-2_wp*k, vp)
    end do
    call supervoxel_majorants(ext2, sv, kept)
    call check(error, kept%ns == sv%ns .and. all(kept%bx == sv%bx) .and. all(kept%by == sv%by) &
               .and. all(kept%kb == sv%kb) .and. all(kept%kt == sv%kt), 'the blocks are kept')
    if (allocated(error)) return
    do s = 1, kept%ns
      do jy = 1, kept%nby(s)
        do jx = 1, kept%nbx(s)
          mx = 0
          do k = kept%kb(s), kept%kt(s)
            do j = (jy - 1)*kept%by(s) + 1, min(7, jy*kept%by(s))
              do i = (jx - 1)*kept%bx(s) + 1, min(13, jx*kept%bx(s))
                mx = max(mx, ext2(i, j, k))
              end do
            end do
          end do
          b = kept%off(s) + jx + (jy - 1)*kept%nbx(s)
          call check(error, kept%maj(b) == mx, 'block majorant = largest extinction in it')
          if (allocated(error)) return
        end do
      end do
    end do
  end subroutine test_kept_layout

  subroutine test_uniform(error)
    type(error_t), allocatable, intent(out) :: error
    type(supervoxel_grid_t) :: sv
    type(supervoxel_options_t) :: opts
    real(vp) :: ext(16, 16, 4)
    ext = 0.05_vp   ! optically thick voxels, but uniform: real/majorant = 1 everywhere
    call build_supervoxels(ext, 100.0_wp, 100.0_wp, [100.0_wp, 100.0_wp, 100.0_wp, 100.0_wp], &
                           opts, sv)
    call check(error, sv%ns == 1, 'uniform layers merge into one super-layer')
    call check(error, sv%nbx(1) == 1 .and. sv%nby(1) == 1, 'uniform field merges into one block')
    call check_close(error, sv%maj(1), real(0.05_vp, wp), label='majorant of the uniform field')
  end subroutine test_uniform

  subroutine test_clear(error)
    type(error_t), allocatable, intent(out) :: error
    type(supervoxel_grid_t) :: sv
    type(supervoxel_options_t) :: opts
    real(vp) :: ext(8, 8, 1)
    ext = 0.0_wp
    ext(1:2, 1:2, 1) = 5.0_wp    ! a tiny, very dense cloud in one corner
    ext(2, 2, 1) = 0.5_wp
    call build_supervoxels(ext, 10.0_wp, 10.0_wp, [10.0_wp], opts, sv)
    call check(error, count(sv%maj == 0.0_wp) >= 1, 'a clear block keeps a zero majorant')
    call check(error, maxval(sv%maj) == 5.0_wp, 'the dense block keeps its maximum')
  end subroutine test_clear

  subroutine test_thick(error)
    type(error_t), allocatable, intent(out) :: error
    type(supervoxel_grid_t) :: sv
    type(supervoxel_options_t) :: opts
    real(vp) :: ext(8, 8, 1)
    integer :: i
    ! alternate thick and thin columns: merging would make optically thick blocks whose
    ! real/majorant ratio is 0.5 -> both criteria fail, so voxels stay single
    do i = 1, 8
      ext(i, :, 1) = merge(1.0_wp, 0.0_wp, mod(i, 2) == 0)
    end do
    call build_supervoxels(ext, 10.0_wp, 10.0_wp, [10.0_wp], opts, sv)
    call check(error, sv%bx(1) == 1, 'thick contrasted columns are not merged along x')
  end subroutine test_thick

  subroutine test_disabled(error)
    type(error_t), allocatable, intent(out) :: error
    type(supervoxel_grid_t) :: sv
    type(supervoxel_options_t) :: opts
    real(vp) :: ext(13, 7, 5)
    ext = field(13, 7, 5)
    opts%enabled = .false.
    call build_supervoxels(ext, 50.0_wp, 50.0_wp, [100.0_wp, 100.0_wp, 100.0_wp, 100.0_wp, 100.0_wp], &
                           opts, sv)
    call check(error, sv%ns == 1 .and. size(sv%maj) == 1, 'one block')
    call check_close(error, sv%maj(1), real(maxval(ext), wp), label='global majorant')
  end subroutine test_disabled

  subroutine test_classes(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(atmosphere_options_t) :: opts
    type(phase_t) :: ph(1)
    real(wp) :: ext1(4, 1), ssa1(4, 1)
    integer :: iph1(4, 1)
    ph(1) = new_phase_isotropic()
    ext1(:, 1) = [0.0_wp, 1.0e-3_wp, 1.0e-3_wp, 1.0e-3_wp]
    ssa1(:, 1) = [1.0_wp, 0.0_wp, 0.5_wp, 1.0_wp]
    iph1 = 1
    call atmosphere_init(atm, [0.0_wp, 1.0_wp, 2.0_wp, 3.0_wp, 4.0_wp], 10.0_wp, 10.0_wp, ext1, &
                         ssa1, iph1, ph, opts, error)
    if (allocated(error)) return
    call check(error, all(atm%layer_class == [LAYER_CLEAR, LAYER_ABSORBING, LAYER_SCATTERING, &
                                             LAYER_SCATTERING]), 'classes of 1-D layers')
    opts%use_absorbing_layers = .false.
    call atmosphere_init(atm, [0.0_wp, 1.0_wp, 2.0_wp, 3.0_wp, 4.0_wp], 10.0_wp, 10.0_wp, ext1, &
                         ssa1, iph1, ph, opts, error)
    if (allocated(error)) return
    call check(error, atm%layer_class(2) == LAYER_SCATTERING, 'absorbing fast path off')
    opts%use_1d_layers = .false.
    call atmosphere_init(atm, [0.0_wp, 1.0_wp, 2.0_wp, 3.0_wp, 4.0_wp], 10.0_wp, 10.0_wp, ext1, &
                         ssa1, iph1, ph, opts, error)
    if (allocated(error)) return
    call check(error, all(atm%layer_class == LAYER_3D) .and. atm%n3 == 4, &
               'without 1-D layers every layer is traced in 3-D')
    call atmosphere_init(atm, [0.0_wp, 1.0_wp, 1.0_wp, 3.0_wp, 4.0_wp], 10.0_wp, 10.0_wp, ext1, &
                         ssa1, iph1, ph, opts, error)
    call check(error, allocated(error), 'levels that do not increase are rejected')
    if (allocated(error)) then
      if (index(error%message, 'increase strictly') > 0) deallocate (error)
    end if
  end subroutine test_classes

  subroutine test_mixing(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(atmosphere_options_t) :: opts
    type(phase_t) :: ph(2)
    real(wp) :: ext1(1, 2), ssa1(1, 2)
    integer :: iph1(1, 2)
    ph = new_phase_isotropic()
    ext1(1, :) = [1.0e-3_wp, 3.0e-3_wp]
    ssa1(1, :) = [1.0_wp, 0.5_wp]
    iph1(1, :) = [1, 2]
    call atmosphere_init(atm, [0.0_wp, 1.0_wp], 10.0_wp, 10.0_wp, ext1, ssa1, iph1, ph, opts, error)
    if (allocated(error)) return
    ! sigma_s = 1e-3 + 1.5e-3; omega = 2.5e-3 / 4e-3; scatterer 1 with probability 1/2.5
    call check_close(error, atm%ext1(1), 4.0e-3_wp, label='total extinction')
    call check_close(error, atm%omg1(1), 0.625_wp, label='mixture single-scattering albedo')
    call check_close(error, atm%csca1(1, 1), 0.4_wp, label='scattering fraction of component 1')
    call check_close(error, atm%csca1(2, 1), 1.0_wp, label='cumulative fraction ends at 1')
  end subroutine test_mixing

  !> Voxels put layer by layer: a 1-D background (molecules) under two 3-D components, one of
  !> them blending two phase tables. Totals, albedo and the cumulative fraction follow from the
  !> component values by hand; blend weights are kept per component; storage for what does
  !> not vary is dropped; bad weights and a blend past the last table are rejected.
  subroutine test_put_layers(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(atmosphere_options_t) :: opts
    type(phase_t), allocatable :: ph(:)
    real(wp) :: ext1(3, 1), ssa1(3, 1), e(2, 1), s(2, 1), w(2, 1), sca
    integer :: iph1(3, 1), ip(2, 1), i
    ph = [(new_phase_isotropic(), i=1, 4)]
    ext1(:, 1) = [1.0e-5_wp, 2.0e-5_wp, 0.0_wp]   ! layer 3 (above the region) is clear
    ssa1 = 1.0_wp
    iph1 = 1
    call atmosphere_begin(atm, [0.0_wp, 100.0_wp, 200.0_wp, 300.0_wp], 20.0_wp, 10.0_wp, ext1, &
                          ssa1, iph1, ph, opts, error, k3_lo=1, nx=2, ny=1, n3f=2, nc3=2, &
                          blend=.true.)
    if (allocated(error)) return
    call check(error, .not. allocated(ph), 'the phase functions move into the atmosphere')
    call check(error, atm%ncomp == 3, 'background + 2 components')
    ! component 1: droplets blending tables 2 and 3; component 2: table 4, no blend
    e(:, 1) = [1.0e-2_wp, 0.0_wp]
    s(:, 1) = [0.9_wp, 1.0_wp]
    ip(:, 1) = [2, 2]
    w(:, 1) = [0.25_wp, 0.0_wp]
    call atmosphere_put_layer(atm, 1, 1, e, s, ip, w)
    call atmosphere_put_layer(atm, 1, 2, e, s, ip, w)
    e(:, 1) = [3.0e-3_wp, 4.0e-3_wp]
    s(:, 1) = [0.5_wp, 0.5_wp]
    ip = 4
    call atmosphere_put_layer(atm, 2, 1, e, s, ip)
    call atmosphere_put_layer(atm, 2, 2, 0.0_wp*e, s, ip)
    call atmosphere_end(atm, opts, error)
    if (allocated(error)) return
    ! voxel (1, 1, 1): sigma = 1e-5 + 1e-2 + 3e-3, sigma_s = 1e-5 + 9e-3 + 1.5e-3
    sca = 1.0e-5_wp + 9.0e-3_wp + 1.5e-3_wp
    call check_close(error, real(atm%ext3(1, 1, 1), wp), 1.301e-2_wp, rel_tol=1.0e-6_wp, &
                     label='total extinction')
    call check_close(error, real(atm%omg3(1, 1, 1), wp), sca/1.301e-2_wp, rel_tol=1.0e-6_wp, &
                     label='mixture albedo')
    call check_close(error, real(atm%csca3(1, 1, 1, 1), wp), 1.0e-5_wp/sca, rel_tol=1.0e-5_wp, &
                     label='fraction of the background')
    call check_close(error, real(atm%csca3(2, 1, 1, 1), wp), (1.0e-5_wp + 9.0e-3_wp)/sca, &
                     rel_tol=1.0e-6_wp, label='cumulative fraction up to the droplets')
    call check(error, size(atm%csca3, 1) == 2, 'one fraction fewer than components')
    ! voxel (2, 1, 2): only the background and component 2 (empty): all scattering by molecules
    call check_close(error, real(atm%ext3(2, 1, 2), wp), 2.0e-5_wp + 4.0e-3_wp*0.0_wp, &
                     rel_tol=1.0e-6_wp, label='extinction of the background-only voxel')
    call check(error, associated(atm%wph3), 'blend weights kept')
    if (allocated(error)) return
    call check_close(error, real(atm%wph3(2, 1, 1, 1), wp), 0.25_wp, rel_tol=1.0e-7_wp, &
                     label='blend weight of the droplet component')
    call check(error, atm%iph3(2, 1, 1, 1) == 2 .and. atm%iph3(3, 2, 1, 2) == 4, &
               'phase indices per component')
    ! without blends or varying indices nothing per-voxel is kept
    e(:, 1) = [1.0e-2_wp, 2.0e-2_wp]
    call one_layer(3, 0.0_wp)
    if (allocated(error)) return
    call check(error, .not. associated(atm%wph3) .and. .not. associated(atm%iph3) .and. &
               all(atm%iph3_const == [1, 3]), 'constant phase and no blend stored once')
    ! a blend past the last table, and a weight above 1
    call one_layer(4, 0.5_wp)
    call check(error, allocated(error), 'a blend with table 5 of 4 is rejected')
    if (.not. allocated(error)) return
    if (index(error%message, 'iph + 1') == 0) return
    deallocate (error)
    call one_layer(2, 1.5_wp)
    call check(error, allocated(error), 'a blend weight of 1.5 is rejected')
    if (.not. allocated(error)) return
    if (index(error%message, 'outside 0..1') > 0) deallocate (error)
  contains
    !> One 3-D layer (layer 2) of one component with phase index iph_all and blend weight w_all.
    subroutine one_layer(iph_all, w_all)
      integer, intent(in) :: iph_all
      real(wp), intent(in) :: w_all
      ph = [(new_phase_isotropic(), i=1, 4)]
      call atmosphere_begin(atm, [0.0_wp, 100.0_wp, 200.0_wp, 300.0_wp], 20.0_wp, 10.0_wp, &
                            ext1, ssa1, iph1, ph, opts, error, k3_lo=2, nx=2, ny=1, n3f=1, &
                            nc3=1, blend=.true.)
      if (allocated(error)) return
      ip = iph_all
      w = w_all
      call atmosphere_put_layer(atm, 1, 1, e, s, ip, w)
      call atmosphere_end(atm, opts, error)
    end subroutine one_layer
  end subroutine test_put_layers

  !> Similarity-scaled truncation (opts%similarity_deg): each component's extinction becomes
  !> e (1 - a f) and its albedo a (1 - f)/(1 - a f) before the voxels are mixed, f the delta
  !> fraction of its phase function (of a blend, the weighted sum), and a blend's weight of the
  !> second table in the normalised rest is w (1 - f2)/(1 - f) (the voxel keeps w); components without a forward peak (isotropic)
  !> and the 1-D layers' isotropic background are unchanged, an HG 1-D component is scaled.
  subroutine test_similarity(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(atmosphere_options_t) :: opts
    type(phase_t), allocatable :: ph(:)
    type(error_t), allocatable :: err
    real(wp) :: ext1(3, 2), ssa1(3, 2), e(2, 1), s(2, 1), w(2, 1), f2, f3, fb, eb, ab, eh, ah
    integer :: iph1(3, 2), ip(2, 1)
    ph = [new_phase_isotropic(), new_phase_hg(0.8_wp, err), new_phase_hg(0.9_wp, err)]
    call check(error, .not. allocated(err), 'HG phase functions')
    if (allocated(error)) return
    ext1(:, 1) = [1.0e-5_wp, 2.0e-5_wp, 0.0_wp]   ! isotropic background
    ext1(:, 2) = [0.0_wp, 0.0_wp, 5.0e-3_wp]      ! an HG 1-D layer above the region
    ssa1 = 0.95_wp
    iph1(:, 1) = 1
    iph1(:, 2) = 2
    opts%similarity_deg = 20.0_wp
    call atmosphere_begin(atm, [0.0_wp, 100.0_wp, 200.0_wp, 300.0_wp], 20.0_wp, 10.0_wp, ext1, &
                          ssa1, iph1, ph, opts, error, k3_lo=1, nx=2, ny=1, n3f=2, nc3=1, &
                          blend=.true.)
    if (allocated(error)) return
    call check(error, atm%similar, 'the atmosphere is scaled')
    if (allocated(error)) return
    f2 = atm%sim%f(2, 2)
    f3 = atm%sim%f(2, 3)
    call check(error, f2 > 0.1_wp .and. f3 > f2 .and. atm%sim%f(2, 1) == 0.0_wp, &
               'delta fractions of HG 0.8 and 0.9 at 20 degrees, none for isotropic')
    if (allocated(error)) return
    ! column 1 blends tables 2 and 3 (w = 0.25), column 2 is table 3 alone
    e(:, 1) = [1.0e-2_wp, 2.0e-2_wp]
    s(:, 1) = [0.9_wp, 0.99_wp]
    ip(:, 1) = [2, 3]
    w(:, 1) = [0.25_wp, 0.0_wp]
    call atmosphere_put_layer(atm, 1, 1, e, s, ip, w)
    call atmosphere_put_layer(atm, 1, 2, e, s, ip, w)
    call atmosphere_end(atm, opts, error)
    if (allocated(error)) return
    fb = 0.75_wp*f2 + 0.25_wp*f3
    eb = 1.0e-2_wp*(1.0_wp - 0.9_wp*fb)
    ab = 0.9_wp*(1.0_wp - fb)/(1.0_wp - 0.9_wp*fb)
    call check_close(error, real(atm%ext3(1, 1, 1), wp), 1.0e-5_wp + eb, rel_tol=1.0e-6_wp, &
                     label='extinction of the blended voxel')
    call check_close(error, real(atm%omg3(1, 1, 1), wp), (0.95e-5_wp + eb*ab)/(1.0e-5_wp + eb), &
                     rel_tol=1.0e-6_wp, label='albedo of the blended voxel')
    call check_close(error, real(atm%wph3(2, 1, 1, 1), wp), 0.25_wp, rel_tol=1.0e-7_wp, &
                     label='the voxel keeps the blend weight')
    call check_close(error, similarity_blend_weight(atm%sim, 2, 0.25_wp), &
                     0.25_wp*(1.0_wp - f3)/(1.0_wp - fb), rel_tol=1.0e-12_wp, &
                     label='weight of the second table in the scaled blend')
    eh = 2.0e-2_wp*(1.0_wp - 0.99_wp*f3)
    call check_close(error, real(atm%ext3(2, 1, 2), wp), 2.0e-5_wp + eh, rel_tol=1.0e-6_wp, &
                     label='extinction of the voxel of table 3')
    ! absorption is kept: e (1 - a) before and after
    call check_close(error, eb*(1.0_wp - ab), 1.0e-2_wp*0.1_wp, rel_tol=1.0e-12_wp, &
                     label='absorption of the scaled component')
    ! 1-D layers: the isotropic background as given, the HG layer above the region scaled
    eh = 5.0e-3_wp*(1.0_wp - 0.95_wp*f2)
    ah = 0.95_wp*(1.0_wp - f2)/(1.0_wp - 0.95_wp*f2)
    call check_close(error, atm%ext1(3), eh, rel_tol=1.0e-12_wp, label='scaled 1-D layer')
    call check_close(error, atm%omg1(3), ah, rel_tol=1.0e-12_wp, label='its albedo')
    call check_close(error, atm%ext1(1), 1.0e-5_wp, rel_tol=1.0e-12_wp, &
                     label='isotropic 1-D background unchanged')
    if (allocated(error)) return
    ! a new build takes the tables over only when they were formed from the same phase functions
    ph = [new_phase_isotropic(), new_phase_hg(0.7_wp, err), new_phase_hg(0.9_wp, err)]
    call atmosphere_begin(atm, [0.0_wp, 100.0_wp, 200.0_wp, 300.0_wp], 20.0_wp, 10.0_wp, ext1, &
                          ssa1, iph1, ph, opts, error)
    if (allocated(error)) return
    call check(error, atm%sim%f(2, 2) < f2 .and. atm%sim%f(2, 3) == f3, &
               'other phase functions, other tables (HG 0.7 cuts less than 0.8)')
    if (allocated(error)) return
    ph = [new_phase_isotropic(), new_phase_hg(0.8_wp, err), new_phase_hg(0.9_wp, err)]
    call atmosphere_begin(atm, [0.0_wp, 100.0_wp, 200.0_wp, 300.0_wp], 20.0_wp, 10.0_wp, ext1, &
                          ssa1, iph1, ph, opts, error)
    if (allocated(error)) return
    call check(error, atm%sim%f(2, 2) == f2 .and. atm%sim%f(2, 3) == f3, &
               'the first phase functions again, the first tables again')
  end subroutine test_similarity

  !> A broadband run switches the gas of a g-point by atmosphere_swap_background: the voxels,
  !> layers and majorants must equal, to the last bit, those of a new build with the new
  !> background. The field has voxels without components (most of a cloud field), voxels with
  !> only the second component, a zero extinction with a non-zero albedo (no component), and a
  !> layer whose background loses its scattering.
  subroutine test_swap_background(error)
    type(error_t), allocatable, intent(out) :: error
    logical :: sim
    integer :: i
    ! each case also with similarity-scaled truncation (forward-peaked phase functions, 1-D
    ! components and blends scaled as a build scales them)
    do i = 1, 2
      sim = i == 2
      call swap_background_case(error, 2, .false., sim)
      if (allocated(error)) return
      call swap_background_case(error, 1, .false., sim)
      if (allocated(error)) return
      ! a layer full of voxels with components: its blocks take the other layers' clear values
      ! one by one (clear_part)
      call swap_background_case(error, 1, .true., sim)
      if (allocated(error)) return
    end do
  end subroutine test_swap_background

  !> n phase functions: isotropic, or (`sim`) Henyey-Greenstein with g = 0.6 + 0.05 i, which
  !> similarity-scaled truncation at 20 degrees cuts.
  function test_phases(n, sim) result(ph)
    integer, intent(in) :: n
    logical, intent(in) :: sim
    type(phase_t), allocatable :: ph(:)
    type(error_t), allocatable :: err
    integer :: i
    allocate (ph(n))
    do i = 1, n
      if (sim) then
        ph(i) = new_phase_hg(0.6_wp + 0.05_wp*i, err)
      else
        ph(i) = new_phase_isotropic()
      end if
    end do
  end function test_phases

  subroutine swap_background_case(error, nc3, full, sim)
    type(error_t), allocatable, intent(out) :: error
    integer, intent(in) :: nc3
    logical, intent(in) :: full   !! the first layer of the field has components in every voxel
    logical, intent(in) :: sim    !! similarity-scaled truncation at 20 degrees
    integer, parameter :: NX = 7, NY = 5, NF = 3, NZ = 5
    type(atmosphere_t) :: swapped, built
    type(atmosphere_options_t) :: opts
    type(supervoxel_grid_t) :: layout
    type(phase_t), allocatable :: ph(:)
    real(wp) :: cext(NX, NY, NF, nc3), cssa(NX, NY, NF, nc3), wph(NX, NY, NF, nc3)
    real(wp) :: ext_a(NZ, 2), ext_b(NZ, 2), ssa1(NZ, 2), z(0:NZ)
    integer :: iph(NX, NY, NF, nc3), iph1(NZ, 2), i, j, k, c
    logical :: done
    z = [(200.0_wp*k, k=0, NZ)]
    if (sim) opts%similarity_deg = 20.0_wp
    ssa1(:, 1) = 1.0_wp     ! molecules
    ssa1(:, 2) = 0.0_wp     ! gas absorption
    iph1(:, 1) = 1
    iph1(:, 2) = 1
    ext_a(:, 1) = [4.0e-6_wp, 3.0e-6_wp, 2.0e-6_wp, 1.5e-6_wp, 1.0e-6_wp]
    ext_a(:, 2) = [1.0e-4_wp, 7.0e-5_wp, 3.0e-5_wp, 1.0e-5_wp, 0.0_wp]
    ext_b(:, 1) = 0.3_wp*ext_a(:, 1)
    ext_b(3, 1) = 0.0_wp    ! no molecular scattering in one layer of the region
    ext_b(:, 2) = [2.0e-3_wp, 9.0e-4_wp, 0.0_wp, 4.0e-4_wp, 1.0e-7_wp]
    do c = 1, nc3
      do k = 1, NF
        do j = 1, NY
          do i = 1, NX
            cext(i, j, k, c) = max(0.0_wp, 1.0e-2_wp*(sin(1.3_wp*i*c) + cos(0.7_wp*j + k)) - 5.0e-3_wp)
            cssa(i, j, k, c) = 0.999_wp - 0.01_wp*c - 1.0e-4_wp*i
            iph(i, j, k, c) = 1 + c
            wph(i, j, k, c) = merge(0.25_wp*(mod(i + j, 3)), 0.0_wp, c == 1)
          end do
        end do
      end do
    end do
    if (nc3 > 1) then
      cext(2, 3, 2, 1) = 0.0_wp   ! only the second component
      cext(2, 3, 2, 2) = 3.0e-3_wp
    end if
    cext(4, 1, 1, :) = 0.0_wp   ! no extinction, albedo still 0.5: no component
    cssa(4, 1, 1, :) = 0.5_wp
    if (full) cext(:, :, 1, 1) = cext(:, :, 1, 1) + 2.0e-4_wp
    call check(error, count(all(cext == 0.0_wp, dim=4)) > NX*NY, 'the field has clear voxels')
    if (allocated(error)) return
    call build(swapped, ext_a)
    if (allocated(error)) return
    call check(error, swapped%similar .eqv. sim, 'similarity-scaled as asked')
    if (allocated(error)) return
    layout = swapped%sv
    call atmosphere_swap_background(swapped, ext_b, ssa1, cext, cssa, opts, layout, done)
    call check(error, done, 'the background was swapped')
    if (allocated(error)) return
    call build(built, ext_b, layout)
    if (allocated(error)) return
    call check(error, all(swapped%ext1 == built%ext1) .and. all(swapped%omg1 == built%omg1) .and. &
               all(swapped%csca1 == built%csca1) .and. all(swapped%layer_class == built%layer_class), &
               'the layers equal a new build')
    call check(error, same_voxel_optics(swapped, built), &
               'the voxel extinction and albedo equal a new build')
    call check(error, all(swapped%csca3 == built%csca3), &
               'the cumulative scattering fractions equal a new build')
    call check(error, all(swapped%sv%maj == built%sv%maj), 'the majorants equal a new build')
    if (allocated(error)) return
    ! the swap lists the voxels with components and marks the others as their layer's
    call check(error, allocated(swapped%cloud_ptr), &
               'the first swap listed the voxels with components')
    if (allocated(error)) return
    i = swapped%cloud_ptr(swapped%n3 + 1)
    call check(error, sum(swapped%cloud_run(2, 1:i) - swapped%cloud_run(1, 1:i) + 1) == &
               count(any(cext /= 0.0_wp, dim=4)), 'every voxel with components is listed')
    call check(error, count(swapped%ext3 == VOXEL_CLEAR) == swapped%nx*swapped%ny*swapped%n3 - &
               count(any(cext /= 0.0_wp, dim=4)), 'every other voxel holds its layer''s values')
    if (full) call check(error, .not. all(swapped%clear_all) .and. &
                         size(swapped%clear_part, 2) > 0, &
                         'blocks with a layer full of components take the other layers one by one')
    if (allocated(error)) return
    ext_b(:, 2) = [5.0e-4_wp, 0.0_wp, 2.0e-3_wp, 1.0e-6_wp, 3.0e-7_wp]
    ext_b(:, 1) = 0.5_wp*ext_a(:, 1)
    call atmosphere_swap_background(swapped, ext_b, ssa1, cext, cssa, opts, layout, done)
    call check(error, done, 'the background was swapped again')
    if (allocated(error)) return
    call build(built, ext_b, layout)
    if (allocated(error)) return
    call check(error, same_voxel_optics(swapped, built) .and. &
               all(swapped%csca3 == built%csca3) .and. all(swapped%sv%maj == built%sv%maj), &
               'after a second swap the voxels and majorants equal a new build')
    if (allocated(error)) return
    ! a gas beyond EXT_MAX in the region: the swap declines, so that a build refuses it
    ext_b(3, 2) = 2.0_wp*EXT_MAX
    call atmosphere_swap_background(swapped, ext_b, ssa1, cext, cssa, opts, layout, done)
    call check(error, .not. done, 'a swap to voxels denser than EXT_MAX is declined')
  contains
    subroutine build(atm, ext1, sv_layout)
      type(atmosphere_t), intent(inout) :: atm
      real(wp), intent(in) :: ext1(:, :)
      type(supervoxel_grid_t), intent(in), optional :: sv_layout
      ph = test_phases(4, sim)
      call atmosphere_begin(atm, z, 700.0_wp, 500.0_wp, ext1, ssa1, iph1, ph, opts, error, &
                            k3_lo=2, nx=NX, ny=NY, n3f=NF, nc3=nc3, blend=.true.)
      if (allocated(error)) return
      do c = 1, nc3
        do k = 1, NF
          if (c == 1) then
            call atmosphere_put_layer(atm, c, k, cext(:, :, k, c), cssa(:, :, k, c), &
                                      iph(:, :, k, c), wph(:, :, k, c))
          else
            call atmosphere_put_layer(atm, c, k, cext(:, :, k, c), cssa(:, :, k, c), &
                                      iph(:, :, k, c))
          end if
        end do
      end do
      call end_build(atm, opts, error, sv_layout)
    end subroutine build
  end subroutine swap_background_case
  !> A switch to another band (voxel components with other values, other clear voxels, other
  !> phase indices and blends) gives the atmosphere a new build of that band gives, to the last
  !> bit, and leaves it to a new build whenever that would store the voxels otherwise or fail.
  subroutine test_swap_band(error)
    type(error_t), allocatable, intent(out) :: error
    logical :: sim
    integer :: i
    do i = 1, 2
      sim = i == 2   ! and with similarity-scaled truncation
      call swap_band_case(error, 2, sim)
      if (allocated(error)) return
      ! one component: the band's largest component extinctions per block are found anew
      call swap_band_case(error, 1, sim)
      if (allocated(error)) return
    end do
  end subroutine test_swap_band

  subroutine swap_band_case(error, nc3, sim)
    type(error_t), allocatable, intent(out) :: error
    integer, intent(in) :: nc3
    logical, intent(in) :: sim
    integer, parameter :: NX = 6, NY = 5, NF = 3, NZ = 5, NP = 7
    type(atmosphere_t) :: swapped, built
    type(atmosphere_options_t) :: opts
    type(supervoxel_grid_t) :: layout
    type(phase_t), allocatable :: ph(:)
    real(wp), dimension(NX, NY, NF, nc3) :: cext_a, cssa_a, cext_b, cssa_b, cext_c, cssa_c
    real(vp), dimension(NX, NY, NF, nc3) :: wph_a, wph_b, wph_x, wph_c
    integer, dimension(NX, NY, NF, nc3) :: iph_a, iph_b, iph_x, iph_c
    real(wp) :: ext1(NZ, 2), ssa1(NZ, 2), z(0:NZ)
    integer :: iph1(NZ, 2), i, j, k, c
    logical :: done
    logical, allocatable :: u_b(:)
    z = [(250.0_wp*k, k=0, NZ)]
    if (sim) opts%similarity_deg = 20.0_wp
    ssa1(:, 1) = 1.0_wp
    ssa1(:, 2) = 0.0_wp
    iph1 = 1
    ext1(:, 1) = [4.0e-6_wp, 3.0e-6_wp, 2.0e-6_wp, 1.5e-6_wp, 1.0e-6_wp]
    ext1(:, 2) = [1.0e-4_wp, 7.0e-5_wp, 3.0e-5_wp, 1.0e-5_wp, 2.0e-6_wp]
    do c = 1, nc3
      do k = 1, NF
        do j = 1, NY
          do i = 1, NX
            cext_a(i, j, k, c) = max(0.0_wp, 1.0e-2_wp*(sin(1.3_wp*i*c) + cos(0.7_wp*j + k)) - 5.0e-3_wp)
            cssa_a(i, j, k, c) = 0.999_wp - 0.01_wp*c - 1.0e-4_wp*i
            iph_a(i, j, k, c) = 1 + c + mod(i, 2)
            wph_a(i, j, k, c) = real(0.25_wp*mod(i + j + c, 3), vp)
          end do
        end do
      end do
    end do
    ! band b: other values, other voxels with components, its own tables
    cext_b = 1.7_wp*cext_a
    where (cext_a == 0.0_wp) cext_b = 2.0e-3_wp*cssa_a
    cext_b(1:3, :, 2, :) = 0.0_wp
    cssa_b = 0.9_wp*cssa_a
    iph_b = iph_a + 2
    wph_b = 0.5_vp*wph_a
    ! its top layer of the field without components and with one table: the same everywhere
    cext_b(:, :, NF, :) = 0.0_wp
    iph_b(:, :, NF, :) = 5
    wph_b(:, :, NF, :) = 0.0_vp
    call build(swapped, cext_a, cssa_a, iph_a, wph_a)
    if (allocated(error)) return
    layout = swapped%sv
    ! a gas switch first, so that columns with components are noted for band a
    call atmosphere_swap_background(swapped, ext1, ssa1, cext_a, cssa_a, opts, layout, done)
    call check(error, done, 'the background was swapped')
    if (allocated(error)) return
    call switch_band(cext_b, cssa_b, iph_b, wph_b, .false., 'band b')
    if (allocated(error)) return
    call check(error, built%uniform3(NF) .and. .not. built%uniform3(1), &
               'the test has a uniform layer and one that is not')
    if (allocated(error)) return
    u_b = swapped%uniform3
    ! the next gas switch visits the columns band b has components in
    ext1(:, 2) = 3.0_wp*ext1(:, 2)
    call atmosphere_swap_background(swapped, ext1, ssa1, cext_b, cssa_b, opts, layout, done)
    call check(error, done, 'the background was swapped in band b')
    if (allocated(error)) return
    call build(built, cext_b, cssa_b, iph_b, wph_b, layout)
    if (allocated(error)) return
    call compare('after a gas switch in the new band')
    if (allocated(error)) return
    ! a band without any blend: a build drops the weights, so the swap declines
    wph_x = 0.0_vp
    call declines(iph_b, wph_x, 'a band without blends')
    if (allocated(error)) return
    ! indices a build refuses: beyond the tables, or a blend with a table beyond them
    iph_x = iph_b
    iph_x(2, 2, 1, 1) = NP + 1
    call declines(iph_x, wph_b, 'an index beyond the tables')
    if (allocated(error)) return
    iph_x = iph_b
    wph_x = wph_b
    iph_x(3, 1, 1, nc3) = NP
    wph_x(3, 1, 1, nc3) = 0.5_vp
    call declines(iph_x, wph_x, 'a blend with a table beyond the last')
    if (allocated(error)) return
    wph_x(3, 1, 1, nc3) = 1.5_vp
    iph_x(3, 1, 1, nc3) = 2
    call declines(iph_x, wph_x, 'a weight above 1')
    if (allocated(error)) return
    ! and back to band a, after the declined swaps
    call switch_band(cext_a, cssa_a, iph_a, wph_a, .false., 'band a, after the declined swaps')
    if (allocated(error)) return
    ! band b again with the same gas, handed what the first switch found
    ext1(:, 2) = ext1(:, 2)/3.0_wp
    call atmosphere_swap_background(swapped, ext1, ssa1, cext_b, cssa_b, opts, layout, done, &
                                    new_band=.true., ciph=iph_b, cwph=wph_b, checked=.true., &
                                    uniform3=u_b, uniform3_known=.true.)
    call check(error, done, 'band b was swapped in again with its known checks')
    if (allocated(error)) return
    call build(built, cext_b, cssa_b, iph_b, wph_b, layout)
    if (allocated(error)) return
    call compare('in band b again, with its known checks')
    if (allocated(error)) return
    ! band c has components in the voxels of band a and no others, and its voxels without
    ! components have band a's indices and weights (a cloud file's voxels without water):
    ! with same_clear a switch keeps the list of band a and writes only the voxels in it
    cext_c = 1.3_wp*cext_a
    cssa_c = 0.95_wp*cssa_a
    iph_c = iph_a
    wph_c = wph_a
    do k = 1, NF
      do j = 1, NY
        do i = 1, NX
          if (all(cext_a(i, j, k, :) == 0.0_wp)) cycle
          iph_c(i, j, k, :) = iph_a(i, j, k, :) + 2
          wph_c(i, j, k, :) = 0.5_vp*wph_a(i, j, k, :)
        end do
      end do
    end do
    call check(error, any(cext_a == 0.0_wp) .and. any(iph_c /= iph_a), &
               'the test has voxels without components and indices that change')
    if (allocated(error)) return
    call atmosphere_swap_background(swapped, ext1, ssa1, cext_a, cssa_a, opts, layout, done, &
                                    new_band=.true., ciph=iph_a, cwph=wph_a)
    if (allocated(error)) return
    call switch_band(cext_c, cssa_c, iph_c, wph_c, .true., 'band c with same_clear')
    if (allocated(error)) return
    ext1(:, 2) = 2.0_wp*ext1(:, 2)
    call atmosphere_swap_background(swapped, ext1, ssa1, cext_c, cssa_c, opts, layout, done)
    call build(built, cext_c, cssa_c, iph_c, wph_c, layout)
    if (allocated(error)) return
    call compare('after a gas switch in band c')
    if (allocated(error)) return
    call switch_band(cext_a, cssa_a, iph_a, wph_a, .true., 'band a with same_clear')
    if (allocated(error)) return
    ! bands d and e: field layer 1 without components and with one index and weight (a uniform
    ! layer), layer NF without components but with indices that vary (not uniform). With
    ! same_clear a switch keeps those layers' uniformity from the switch before, which must be
    ! what a new build finds.
    cext_b = cext_a
    cext_b(:, :, 1, :) = 0.0_wp
    cext_b(:, :, NF, :) = 0.0_wp
    iph_b = iph_a
    wph_b = wph_a
    iph_b(:, :, 1, :) = 2
    wph_b(:, :, 1, :) = 0.0_vp
    wph_b(:, :, NF, :) = 0.0_vp
    call switch_band(cext_b, cssa_a, iph_b, wph_b, .false., 'band d')
    if (allocated(error)) return
    call check(error, swapped%cloud_ptr(2) == swapped%cloud_ptr(1) .and. &
               swapped%uniform3(1) .and. .not. swapped%uniform3(NF), &
               'band d has a uniform layer without components and one that is not uniform')
    if (allocated(error)) return
    cext_c = 1.2_wp*cext_b
    iph_c = iph_b
    wph_c = wph_b
    where (cext_b > 0.0_wp) iph_c = iph_b + 2
    call switch_band(cext_c, cssa_a, iph_c, wph_c, .true., 'band e with same_clear')
    if (allocated(error)) return
    ! an atmosphere that stores no blend weights cannot take a band's
    wph_x = 0.0_vp
    call build(swapped, cext_a, cssa_a, iph_a, wph_x)
    if (allocated(error)) return
    call check(error, .not. associated(swapped%wph3), 'a build without blends drops the weights')
    if (allocated(error)) return
    call atmosphere_swap_background(swapped, ext1, ssa1, cext_b, cssa_b, opts, swapped%sv, done, &
                                    new_band=.true., ciph=iph_b, cwph=wph_b)
    call check(error, .not. done, 'without stored weights a band switch is left to a new build')
  contains
    !> A switch to a band (with `same_clear` or not) gives what a new build of it gives.
    subroutine switch_band(cext, cssa, iph, wph, same_clear, what)
      real(wp), intent(in) :: cext(:, :, :, :), cssa(:, :, :, :)
      integer, intent(in) :: iph(:, :, :, :)
      real(vp), intent(in) :: wph(:, :, :, :)
      logical, intent(in) :: same_clear
      character(len=*), intent(in) :: what
      call atmosphere_swap_background(swapped, ext1, ssa1, cext, cssa, opts, layout, done, &
                                      new_band=.true., ciph=iph, cwph=wph, same_clear=same_clear)
      call check(error, done, what//' was swapped in')
      if (allocated(error)) return
      call build(built, cext, cssa, iph, wph, layout)
      if (allocated(error)) return
      call compare('in '//what)
    end subroutine switch_band

    !> A switch to band b with these indices and weights is left to a new build.
    subroutine declines(ciph, cwph, what)
      integer, intent(in) :: ciph(:, :, :, :)
      real(vp), intent(in) :: cwph(:, :, :, :)
      character(len=*), intent(in) :: what
      call atmosphere_swap_background(swapped, ext1, ssa1, cext_b, cssa_b, opts, layout, done, &
                                      new_band=.true., ciph=ciph, cwph=cwph)
      call check(error, .not. done, what//' is left to a new build')
    end subroutine declines

    subroutine compare(when)
      character(len=*), intent(in) :: when
      call check(error, all(swapped%ext1 == built%ext1) .and. all(swapped%omg1 == built%omg1) &
                 .and. all(swapped%csca1 == built%csca1), 'the layers equal a new build '//when)
      if (allocated(error)) return
      call check(error, same_voxel_optics(swapped, built) .and. &
                 all(swapped%csca3 == built%csca3), 'the voxel optics equal a new build '//when)
      if (allocated(error)) return
      call check(error, associated(swapped%iph3) .and. associated(built%iph3) .and. &
                 associated(swapped%wph3) .and. associated(built%wph3), &
                 'both store phase indices and weights '//when)
      if (allocated(error)) return
      call check(error, all(swapped%iph3 == built%iph3) .and. all(swapped%wph3 == built%wph3) .and. &
                 all(swapped%iph3_const == built%iph3_const), &
                 'the phase indices and weights equal a new build '//when)
      if (allocated(error)) return
      call check(error, all(swapped%uniform3 .eqv. built%uniform3), &
                 'the uniform layers are those of a new build '//when)
      if (allocated(error)) return
      call check(error, all(swapped%sv%maj == built%sv%maj), 'the majorants equal a new build '//when)
    end subroutine compare

    subroutine build(atm, cext, cssa, iph, wph, sv_layout)
      type(atmosphere_t), intent(inout) :: atm
      real(wp), intent(in) :: cext(:, :, :, :), cssa(:, :, :, :)
      integer, intent(in) :: iph(:, :, :, :)
      real(vp), intent(in) :: wph(:, :, :, :)
      type(supervoxel_grid_t), intent(in), optional :: sv_layout
      ph = test_phases(NP, sim)
      call atmosphere_begin(atm, z, 600.0_wp, 500.0_wp, ext1, ssa1, iph1, ph, opts, error, &
                            k3_lo=2, nx=NX, ny=NY, n3f=NF, nc3=nc3, blend=.true.)
      if (allocated(error)) return
      do c = 1, nc3
        do k = 1, NF
          call atmosphere_put_layer(atm, c, k, cext(:, :, k, c), cssa(:, :, k, c), &
                                    iph(:, :, k, c), real(wph(:, :, k, c), wp))
        end do
      end do
      call end_build(atm, opts, error, sv_layout)
    end subroutine build
  end subroutine swap_band_case
  !> atmosphere_end, keeping the blocks of `sv_layout` when it is given (the swap tests)
  subroutine end_build(atm, opts, error, sv_layout)
    type(atmosphere_t), intent(inout) :: atm
    type(atmosphere_options_t), intent(in) :: opts
    type(error_t), allocatable, intent(out) :: error
    type(supervoxel_grid_t), intent(in), optional :: sv_layout
    if (present(sv_layout)) then
      call atmosphere_end(atm, opts, error, sv_layout=sv_layout)
    else
      call atmosphere_end(atm, opts, error)
    end if
  end subroutine end_build
end module test_supervoxel_suite

program test_supervoxel
  use kumo_testing, only: run_unittests
  use test_supervoxel_suite, only: collect_supervoxel
  implicit none
  integer :: n_failed
  call run_unittests('supervoxel', collect_supervoxel(), n_failed)
  if (n_failed > 0) error stop 1
end program test_supervoxel
