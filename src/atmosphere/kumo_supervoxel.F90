! SPDX-License-Identifier: BSD-3-Clause
!> Super-voxel majorant grid for maximum-cross-section (null-collision) tracking in the 3-D region.
!>
!> The 3-D region is split vertically into super-layers and each super-layer horizontally into
!> blocks of bx x by voxels. Each block stores the largest extinction of its voxels (the majorant).
!> Merging follows the rule of the MCARaTS model (seed text section 4.1.2; state-of-the-art notes
!> 1.A, A2): keep merging while the merged blocks stay optically small (mean majorant optical size
!> times `fsupg` <= 1) or the real/majorant ratio stays high (mean extinction / majorant times
!> `fsupi` >= 1). Bigger super-voxels mean fewer face crossings; a lower real/majorant ratio means
!> more null collisions; the rule balances the two. A block whose majorant is exactly zero is
!> clear: photons cross it without sampling a collision.
module kumo_supervoxel
  use kumo_kinds, only: wp, vp
  implicit none
  private
  public :: supervoxel_grid_t, supervoxel_options_t, build_supervoxels, supervoxel_majorants
  public :: supervoxel_copy_layout
  public :: merge_ok, columns_merge_ok   ! for the tests: the two must agree

  !> Options of the super-voxel builder.
  type :: supervoxel_options_t
    logical :: enabled = .true.   !! .false.: one majorant for the whole 3-D region
    real(wp) :: fsupg = 2.0_wp    !! merge while mean majorant optical size <= 1/fsupg ...
    real(wp) :: fsupi = 1.3_wp    !! ... or mean real/majorant ratio >= 1/fsupi
    integer :: max_layers = 50    !! most layers in one super-layer
  end type supervoxel_options_t

  !> Majorant grid. Super-layer s covers region layers kb(s)..kt(s) (1 = lowest region layer),
  !> blocks are bx(s) x by(s) voxels, nbx(s) x nby(s) of them; the majorant of block (jx, jy)
  !> is maj(off(s) + jx + (jy - 1)*nbx(s)).
  type :: supervoxel_grid_t
    integer :: ns = 0
    integer, allocatable :: kb(:), kt(:), bx(:), by(:), nbx(:), nby(:), off(:)
    integer, allocatable :: sl_of_layer(:)   !! super-layer of each region layer
    real(wp), allocatable :: maj(:)          !! majorant extinction per block [m-1]
  end type supervoxel_grid_t

contains

  !> Build the majorant grid for extinction `ext(nx, ny, n3)` on voxels of size dx x dy x dz(k).
  subroutine build_supervoxels(ext, dx, dy, dz, opts, sv)
    real(vp), intent(in) :: ext(:, :, :)      !! total extinction per voxel [m-1]
    real(wp), intent(in) :: dx, dy            !! voxel size [m]
    real(wp), intent(in) :: dz(:)             !! layer thickness of each region layer [m]
    type(supervoxel_options_t), intent(in) :: opts
    type(supervoxel_grid_t), intent(out) :: sv
    integer :: nx, ny, n3, k, kb, kt, s, nblk, bxs, bys
    integer :: kbs(size(dz)), kts(size(dz)), bxv(size(dz)), byv(size(dz))
    real(vp), allocatable :: cmax(:, :)
    real(wp), allocatable :: csum(:, :)
    nx = size(ext, 1)
    ny = size(ext, 2)
    n3 = size(ext, 3)
    s = 0
    if (.not. opts%enabled) then
      s = 1
      kbs(1) = 1
      kts(1) = n3
      bxv(1) = nx
      byv(1) = ny
    else
      allocate (cmax(nx, ny), csum(nx, ny))
      kb = 1
      do while (kb <= n3)
        kt = kb
        ! each column's largest extinction and its sum times dz over layers kb .. kt, carried
        ! from one test to the next (merge_ok with blocks of one column, without reading the
        ! layers again)
        cmax = ext(:, :, kb)
        csum = 0.0_wp + real(ext(:, :, kb), wp)*dz(kb)
        do while (kt < n3 .and. kt - kb + 1 < opts%max_layers)
          if (.not. columns_merge_ok(cmax, csum, ext(:, :, kt + 1), dz(kb:kt + 1), dx, dy, &
                                     opts)) exit
          kt = kt + 1
          cmax = max(cmax, ext(:, :, kt))
          csum = csum + real(ext(:, :, kt), wp)*dz(kt)
        end do
        s = s + 1
        kbs(s) = kb
        kts(s) = kt
        call merge_horizontally(ext(:, :, kb:kt), dz(kb:kt), dx, dy, opts, bxs, bys)
        bxv(s) = bxs
        byv(s) = bys
        kb = kt + 1
      end do
    end if
    sv%ns = s
    sv%kb = kbs(1:s)
    sv%kt = kts(1:s)
    sv%bx = bxv(1:s)
    sv%by = byv(1:s)
    allocate (sv%nbx(s), sv%nby(s), sv%off(s), sv%sl_of_layer(n3))
    nblk = 0
    do k = 1, s
      sv%nbx(k) = (nx + sv%bx(k) - 1)/sv%bx(k)
      sv%nby(k) = (ny + sv%by(k) - 1)/sv%by(k)
      sv%off(k) = nblk
      nblk = nblk + sv%nbx(k)*sv%nby(k)
      sv%sl_of_layer(sv%kb(k):sv%kt(k)) = k
    end do
    allocate (sv%maj(nblk))
    do k = 1, s
      call block_majorants(ext(:, :, sv%kb(k):sv%kt(k)), sv%bx(k), sv%by(k), &
                           sv%maj(sv%off(k) + 1:sv%off(k) + sv%nbx(k)*sv%nby(k)))
    end do
  end subroutine build_supervoxels

  !> The blocks of `layout` (a grid built by build_supervoxels for a field of the same shape)
  !> with the majorants of `ext`: a grid that is valid for `ext` without the merge search. The
  !> blocks need not be the ones build_supervoxels would choose for `ext` (they only set how
  !> far a photon flies between null collisions); broadband runs use it when the extinction
  !> changes from one g-point to the next.
  subroutine supervoxel_majorants(ext, layout, sv)
    real(vp), intent(in) :: ext(:, :, :)
    type(supervoxel_grid_t), intent(in) :: layout
    type(supervoxel_grid_t), intent(out) :: sv
    integer :: k
    call supervoxel_copy_layout(layout, sv)
    do k = 1, sv%ns
      call block_majorants(ext(:, :, sv%kb(k):sv%kt(k)), sv%bx(k), sv%by(k), &
                           sv%maj(sv%off(k) + 1:sv%off(k) + sv%nbx(k)*sv%nby(k)))
    end do
  end subroutine supervoxel_majorants

  !> The blocks of `layout` in `sv`, with room for their majorants (not set).
  subroutine supervoxel_copy_layout(layout, sv)
    type(supervoxel_grid_t), intent(in) :: layout
    type(supervoxel_grid_t), intent(inout) :: sv
    sv%ns = layout%ns
    sv%kb = layout%kb
    sv%kt = layout%kt
    sv%bx = layout%bx
    sv%by = layout%by
    sv%nbx = layout%nbx
    sv%nby = layout%nby
    sv%off = layout%off
    sv%sl_of_layer = layout%sl_of_layer
    if (allocated(sv%maj)) then
      if (size(sv%maj) /= size(layout%maj)) deallocate (sv%maj)
    end if
    if (.not. allocated(sv%maj)) allocate (sv%maj(size(layout%maj)))
  end subroutine supervoxel_copy_layout

  !> Double the block size along x or y while the merge rule allows it (smaller extent first).
  subroutine merge_horizontally(ext, dz, dx, dy, opts, bx, by)
    real(vp), intent(in) :: ext(:, :, :)
    real(wp), intent(in) :: dz(:), dx, dy
    type(supervoxel_options_t), intent(in) :: opts
    integer, intent(out) :: bx, by
    logical :: can_x, can_y
    bx = 1
    by = 1
    do
      can_x = bx < size(ext, 1)
      can_y = by < size(ext, 2)
      if (can_x .and. (.not. can_y .or. bx*dx <= by*dy)) then
        if (merge_ok(ext, dz, dx, dy, 2*bx, by, opts)) then
          bx = 2*bx
          cycle
        end if
        can_x = .false.
      end if
      if (can_y) then
        if (merge_ok(ext, dz, dx, dy, bx, 2*by, opts)) then
          by = 2*by
          cycle
        end if
      end if
      if (can_x) then
        if (merge_ok(ext, dz, dx, dy, 2*bx, by, opts)) then
          bx = 2*bx
          cycle
        end if
      end if
      exit
    end do
    bx = min(bx, size(ext, 1))
    by = min(by, size(ext, 2))
  end subroutine merge_horizontally

  !> merge_ok for blocks of one column over the layers of `dz`, the last of which is `enew`,
  !> from each column's maximum `cmax` and sum of extinction times dz `csum` over the others:
  !> the same numbers in the same order, so the same answer to the last bit.
  logical function columns_merge_ok(cmax, csum, enew, dz, dx, dy, opts) result(ok)
    real(vp), intent(in) :: cmax(:, :), enew(:, :)
    real(wp), intent(in) :: csum(:, :)
    real(wp), intent(in) :: dz(:), dx, dy
    type(supervoxel_options_t), intent(in) :: opts
    integer :: i, j, n_blocks, n_nonclear
    real(wp) :: smax, smean, vol, size_opt, ratio, h, length
    h = sum(dz)
    vol = real(1, wp)*h
    length = min(dx, dy, h)
    size_opt = 0.0_wp
    ratio = 0.0_wp
    n_blocks = size(cmax)
    n_nonclear = 0
    do j = 1, size(cmax, 2)
      do i = 1, size(cmax, 1)
        smax = max(cmax(i, j), enew(i, j))
        if (smax <= 0.0_wp) cycle
        n_nonclear = n_nonclear + 1
        smean = (csum(i, j) + real(enew(i, j), wp)*dz(size(dz)))/vol
        size_opt = size_opt + smax*length
        ratio = ratio + smean/smax
      end do
    end do
    ok = merge_rule(size_opt, ratio, n_blocks, n_nonclear, opts)
  end function columns_merge_ok

  !> Does the merge rule accept blocks of bx x by voxels spanning all layers of `ext`?
  logical function merge_ok(ext, dz, dx, dy, bx, by, opts) result(ok)
    real(vp), intent(in) :: ext(:, :, :)
    real(wp), intent(in) :: dz(:), dx, dy
    integer, intent(in) :: bx, by
    type(supervoxel_options_t), intent(in) :: opts
    integer :: nx, ny, i0, j0, i1, j1, k, n_blocks, n_nonclear
    real(wp) :: smax, smean, vol, size_opt, ratio, h, length
    nx = size(ext, 1)
    ny = size(ext, 2)
    h = sum(dz)
    size_opt = 0.0_wp
    ratio = 0.0_wp
    n_blocks = 0
    n_nonclear = 0
    do j0 = 1, ny, by
      j1 = min(ny, j0 + by - 1)
      do i0 = 1, nx, bx
        i1 = min(nx, i0 + bx - 1)
        n_blocks = n_blocks + 1
        smax = maxval(ext(i0:i1, j0:j1, :))
        if (smax <= 0.0_wp) cycle
        n_nonclear = n_nonclear + 1
        smean = 0.0_wp
        do k = 1, size(ext, 3)
          smean = smean + sum(ext(i0:i1, j0:j1, k))*dz(k)
        end do
        vol = real((i1 - i0 + 1)*(j1 - j0 + 1), wp)*h
        smean = smean/vol
        length = min(real(i1 - i0 + 1, wp)*dx, real(j1 - j0 + 1, wp)*dy, h)
        size_opt = size_opt + smax*length
        ratio = ratio + smean/smax
      end do
    end do
    ok = merge_rule(size_opt, ratio, n_blocks, n_nonclear, opts)
  end function merge_ok

  !> The merge rule from the sums over the blocks of their optical size (majorant times
  !> length) and of their mean-to-majorant ratio (`n_nonclear` blocks with a majorant > 0 of
  !> `n_blocks`): merge while the blocks stay optically small or nearly uniform.
  pure logical function merge_rule(size_opt, ratio, n_blocks, n_nonclear, opts) result(ok)
    real(wp), intent(in) :: size_opt, ratio
    integer, intent(in) :: n_blocks, n_nonclear
    type(supervoxel_options_t), intent(in) :: opts
    ok = .true.
    if (n_nonclear == 0) return
    ok = (size_opt/n_blocks)*opts%fsupg <= 1.0_wp .or. (ratio/n_nonclear)*opts%fsupi >= 1.0_wp
  end function merge_rule

  !> Largest extinction in each block of bx x by voxels (over all layers of `ext`).
  subroutine block_majorants(ext, bx, by, maj)
    real(vp), intent(in) :: ext(:, :, :)
    integer, intent(in) :: bx, by
    real(wp), intent(out) :: maj(:)
    integer :: nx, ny, nbx, nby, ix, iy, k, jx, jy, i0, i1, j0, j1
    real(vp), allocatable :: col(:)
    real(vp) :: m
    ! for each row of blocks, first the maximum over its rows and layers voxel column by voxel
    ! column (a streaming, vectorisable sweep), then over each block's columns (the maximum
    ! does not depend on the order of its operands, so this is the maximum of every block's
    ! section to the last bit, as maxval would give it)
    nx = size(ext, 1)
    ny = size(ext, 2)
    nbx = (nx + bx - 1)/bx
    nby = (ny + by - 1)/by
    allocate (col(nx))
    do jy = 1, nby
      j0 = (jy - 1)*by + 1
      j1 = min(ny, jy*by)
      col = -huge(1.0_vp)
      do k = 1, size(ext, 3)
        do iy = j0, j1
          do ix = 1, nx
            col(ix) = max(col(ix), ext(ix, iy, k))
          end do
        end do
      end do
      do jx = 1, nbx
        i0 = (jx - 1)*bx + 1
        i1 = min(nx, jx*bx)
        m = -huge(1.0_vp)
        do ix = i0, i1
          m = max(m, col(ix))
        end do
        maj((jy - 1)*nbx + jx) = real(m, wp)
      end do
    end do
  end subroutine block_majorants
end module kumo_supervoxel
