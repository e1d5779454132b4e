! SPDX-License-Identifier: BSD-3-Clause
!> Emission tables that draw the voxels of the 3-D region layer by layer (kumo_emission
!> emission_init `voxel_abs`, `layer_abs`; broadband longwave runs over cloud files), against
!> the table with one entry per voxel built from the same atmosphere:
!>
!> * the total power and each layer's emission agree (to the rounding of the voxel arrays), and
!>   so do the voxels' emitted powers (emission_voxel_power);
!> * photons launched from the layered table over many batches (of many photons, and of so few
!>   that a layer gets one to three per batch) carry each voxel's share of the power, within 5
!>   standard errors of the batch means (and three photons), voxel by voxel; a voxel that does not
!>   absorb never emits; every photon starts inside the voxel it names;
!> * bad input is refused: one part of the absorption without the other, with voxel Planck
!>   radiances, with a wrong number of layers.
module test_emission_layered_suite
  use kumo_kinds, only: wp, i8
  use kumo_error, only: str
  use kumo_testing, only: error_t, unittest_t, new_unittest, check
  use kumo_phase, only: phase_t, new_phase_isotropic
  use kumo_atmosphere, only: atmosphere_t, atmosphere_options_t, atmosphere_init, &
                             atmosphere_swap_background
  use kumo_surface, only: surface_t, surface_init
  use kumo_rng, only: rng_t, rng_init, rng_uniform
  use kumo_photon, only: photon_t
  use kumo_emission, only: emission_t, emission_init, emission_entry, emission_launch, &
                           emission_voxel_power, voxel_abs_t, voxel_abs_init, EMIT_VOXEL
  implicit none
  private
  public :: collect_emission_layered

  integer, parameter :: NX = 70, NY = 3, N3 = 2   ! rows of three runs of voxels (kumo_emission VA_RUN)
  !> the voxel component (cloud) of the two 3-D layers; pointers, as voxel_abs_t keeps them
  real(wp), pointer, contiguous :: cext(:, :, :, :) => null(), cssa(:, :, :, :) => null()

contains

  function collect_emission_layered() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('layered_equals_per_voxel_table', test_totals), &
             new_unittest('layered_photons_carry_voxel_powers', test_photons), &
             new_unittest('layered_bad_input', test_bad_input), &
             new_unittest('run_sums_from_the_swap_list', test_swap_list)]
  end function collect_emission_layered

  !> Four layers, layers 2 and 3 in the 3-D region (70 x 3 columns). The background absorbs in
  !> layer 2 and only scatters in layer 3; the cloud absorbs in most voxels, not at all in
  !> voxel (1, 1) of layer 3 (no cloud: it emits nothing), in voxel (2, 1) of layer 3 (a cloud
  !> that only scatters) nor in the second run of voxels of row 3 of layer 3 (none of them
  !> emits).
  subroutine scene(atm, sfc, b_lev, kb, error)
    type(atmosphere_t), intent(out) :: atm
    type(surface_t), intent(out) :: sfc
    real(wp), allocatable, intent(out) :: b_lev(:), kb(:)
    type(error_t), allocatable, intent(out) :: error
    type(phase_t) :: phases(1)
    type(atmosphere_options_t) :: opts
    real(wp) :: e1(4, 1), w1(4, 1)
    integer :: iph3(NX, NY, N3, 1), ix, iy, kr
    phases(1) = new_phase_isotropic()
    if (associated(cext)) deallocate (cext, cssa)
    allocate (cext(NX, NY, N3, 1), cssa(NX, NY, N3, 1))
    do kr = 1, N3
      do iy = 1, NY
        do ix = 1, NX
          cext(ix, iy, kr, 1) = 2.0e-3_wp*(1 + mod(3*ix + 5*iy + 7*kr, 11))
          cssa(ix, iy, kr, 1) = 0.3_wp + 0.005_wp*ix
        end do
      end do
    end do
    cext(1, 1, 2, 1) = 0.0_wp
    cssa(2, 1, 2, 1) = 1.0_wp
    cext(3:5, 2, 1, 1) = 0.0_wp          ! clear voxels in layer 2 (the background absorbs)
    cext(33:64, 3, 2, 1) = 0.0_wp        ! a run without absorption in layer 3
    e1(:, 1) = [2.0e-4_wp, 1.0e-4_wp, 5.0e-5_wp, 2.0e-5_wp]
    w1(:, 1) = [0.2_wp, 0.4_wp, 1.0_wp, 0.5_wp]
    iph3 = 1
    call atmosphere_init(atm, [0.0_wp, 500.0_wp, 1000.0_wp, 2000.0_wp, 3000.0_wp], 500.0_wp, &
                         400.0_wp, e1, w1, reshape([1, 1, 1, 1], [4, 1]), phases, opts, error, &
                         2, cext, cssa, iph3)
    if (allocated(error)) return
    call surface_init(sfc, reshape([0.1_wp], [1, 1]), 500.0_wp, 400.0_wp, error)
    if (allocated(error)) return
    b_lev = [9.0_wp, 8.5_wp, 8.0_wp, 7.0_wp, 6.5_wp]
    kb = e1(2:3, 1)*(1.0_wp - w1(2:3, 1))
  end subroutine scene

  !> The per-voxel table and the layered one of the scene.
  subroutine tables(atm, sfc, flat, lay, error)
    type(atmosphere_t), intent(out) :: atm
    type(surface_t), intent(out) :: sfc
    type(emission_t), intent(out) :: flat, lay
    type(error_t), allocatable, intent(out) :: error
    real(wp), allocatable :: b_lev(:), kb(:)
    type(voxel_abs_t) :: va
    call scene(atm, sfc, b_lev, kb, error)
    if (allocated(error)) return
    call emission_init(flat, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, error)
    if (allocated(error)) return
    call voxel_abs_init(va, atm, cext, cssa, atm%k3_lo - atm%kf_lo)
    call emission_init(lay, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, error, &
                       voxel_abs=va, layer_abs=kb)
  end subroutine tables

  !> After a background swap voxel_abs_init and the voxels' emitted powers read only the voxels
  !> the swap lists as having components (the others: their layer's values); both must be
  !> those of the sweep over every voxel, bit for bit.
  subroutine test_swap_list(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(surface_t) :: sfc
    type(atmosphere_options_t) :: opts
    type(voxel_abs_t) :: swept, listed
    type(emission_t) :: lay
    real(wp), allocatable :: b_lev(:), kb(:), p_built(:)
    real(wp) :: e1(4, 1), w1(4, 1)
    logical :: done
    call scene(atm, sfc, b_lev, kb, error)
    if (allocated(error)) return
    call check(error, .not. allocated(atm%cloud_ptr), 'a new build has no list')
    if (allocated(error)) return
    call voxel_abs_init(swept, atm, cext, cssa, atm%k3_lo - atm%kf_lo)
    call emission_init(lay, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, error, &
                       voxel_abs=swept, layer_abs=kb)
    if (allocated(error)) return
    p_built = emission_voxel_power(lay, atm)
    ! the scene's own background swapped in again: the voxels without components now hold
    ! VOXEL_CLEAR, and the voxels' powers come from the list, the same to the last bit
    e1(:, 1) = [2.0e-4_wp, 1.0e-4_wp, 5.0e-5_wp, 2.0e-5_wp]
    w1(:, 1) = [0.2_wp, 0.4_wp, 1.0_wp, 0.5_wp]
    call atmosphere_swap_background(atm, e1, w1, cext, cssa, opts, atm%sv, done)
    call check(error, done .and. allocated(atm%cloud_ptr), 'the swap lists the voxels')
    if (allocated(error)) return
    call check(error, all(emission_voxel_power(lay, atm) == p_built), &
               'the voxels'' powers from the list equal those of the build')
    if (allocated(error)) return
    e1(:, 1) = [3.0e-4_wp, 1.5e-4_wp, 5.0e-5_wp, 2.0e-5_wp]
    w1(:, 1) = [0.3_wp, 0.4_wp, 1.0_wp, 0.5_wp]
    call atmosphere_swap_background(atm, e1, w1, cext, cssa, opts, atm%sv, done)
    call check(error, done .and. allocated(atm%cloud_ptr), 'the swap lists the voxels')
    if (allocated(error)) return
    call check(error, atm%cloud_ptr(N3 + 1) > 0 .and. &
               atm%cloud_ptr(N3 + 1) > atm%cloud_ptr(N3), 'the list has runs in both layers')
    if (allocated(error)) return
    call voxel_abs_init(listed, atm, cext, cssa, atm%k3_lo - atm%kf_lo)
    call check(error, all(listed%kc_blk == swept%kc_blk) .and. any(swept%kc_blk > 0.0_wp), &
               'the run sums from the list equal the sweep''s')
  end subroutine test_swap_list

  subroutine test_totals(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(surface_t) :: sfc
    type(emission_t) :: flat, lay
    real(wp), allocatable :: pf(:), pl(:)
    call tables(atm, sfc, flat, lay, error)
    if (allocated(error)) return
    call check(error, atm%n3 == N3 .and. lay%layered .and. .not. flat%layered, &
               'the scene has two 3-D layers and the layered table draws them by layer')
    if (allocated(error)) return
    call check(error, lay%n_ent == flat%n_ent - NX*NY*N3 + N3, &
               'one table entry per 3-D layer instead of one per voxel')
    if (allocated(error)) return
    call check(error, abs(lay%power/flat%power - 1.0_wp) < 1.0e-6_wp, &
               'total power as the per-voxel table''s')
    if (allocated(error)) return
    call check(error, all(abs(lay%emit_layer - flat%emit_layer) <= 1.0e-6_wp*flat%emit_layer), &
               'each layer''s emission as the per-voxel table''s')
    if (allocated(error)) return
    pf = emission_voxel_power(flat)
    pl = emission_voxel_power(lay, atm)
    call check(error, size(pl) == size(pf), 'a power for every voxel')
    if (allocated(error)) return
    call check(error, all(abs(pl - pf) <= 1.0e-12_wp*maxval(pf)), &
               'the voxels'' emitted powers as the per-voxel table''s')
  end subroutine test_totals

  !> Photons launched as kumo_source does (photon j of a batch at uj = (j - 1 + u)/n on the
  !> table, u once per batch): 400 batches of 3000, and 40000 batches of 8, where a layer gets
  !> one to three photons per batch (a weight that made each batch carry each layer's power
  !> exactly would favour the voxels early in the layer's order there by tens of per cent).
  subroutine test_photons(error)
    type(error_t), allocatable, intent(out) :: error
    call photons(400, 3000, error)
    if (allocated(error)) return
    call photons(40000, 8, error)
  end subroutine test_photons

  subroutine photons(nb, np, error)
    integer, intent(in) :: nb, np
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(surface_t) :: sfc
    type(emission_t) :: flat, lay
    type(rng_t) :: rng
    type(photon_t) :: p
    real(wp), allocatable :: expect(:), s1(:), s2(:), batch(:), mean(:), se(:), wmax(:), tol(:)
    real(wp) :: u, uj, st1, st2, mt
    integer :: ib, j, ie, ix, iy, kr, k, nv, bad
    logical :: inside
    character(len=:), allocatable :: runs
    runs = str(nb)//' batches of '//str(np)//': '
    call tables(atm, sfc, flat, lay, error)
    if (allocated(error)) return
    nv = NX*NY*N3
    ! the share of the power of each voxel, by the per-voxel table, in units of the layered P
    expect = emission_voxel_power(flat)/(NX*NY)/lay%power
    allocate (s1(nv), s2(nv), batch(nv), wmax(nv), source=0.0_wp)
    st1 = 0.0_wp
    st2 = 0.0_wp
    call rng_init(rng, 12345_i8, 0_i8)
    inside = .true.
    do ib = 1, nb
      batch = 0.0_wp
      u = rng_uniform(rng)
      do j = 1, np
        uj = (real(j - 1, wp) + u)/real(np, wp)
        ie = emission_entry(lay, uj)
        if (ie <= lay%e_vox) cycle
        call emission_launch(lay, atm, sfc, rng, ie, int(np, i8), u, uj, p)
        if (p%emitter /= EMIT_VOXEL) cycle
        kr = (p%em_v - 1)/(NX*NY) + 1
        iy = (p%em_v - 1 - (kr - 1)*NX*NY)/NX + 1
        ix = p%em_v - (kr - 1)*NX*NY - (iy - 1)*NX
        k = atm%k3_lo + kr - 1
        if (p%x < (ix - 1)*atm%dx .or. p%x >= ix*atm%dx .or. p%y < (iy - 1)*atm%dy .or. &
            p%y >= iy*atm%dy .or. p%z < atm%z(k - 1) .or. p%z > atm%z(k)) inside = .false.
        batch(p%em_v) = batch(p%em_v) + p%w
        wmax(p%em_v) = max(wmax(p%em_v), p%w)
      end do
      batch = batch/np
      st1 = st1 + sum(batch)
      st2 = st2 + sum(batch)**2
      s1 = s1 + batch
      s2 = s2 + batch**2
    end do
    call check(error, inside, runs//'every photon starts inside the voxel it names')
    if (allocated(error)) return
    mean = s1/nb
    se = sqrt(max(0.0_wp, s2/nb - mean**2)/(nb - 1))
    call check(error, s1(1 + NX*NY) == 0.0_wp .and. s1(2 + NX*NY) == 0.0_wp .and. &
               all(s1(33 + 2*NX + NX*NY:64 + 2*NX + NX*NY) == 0.0_wp), &
               runs//'voxels that do not absorb emit no photons')
    if (allocated(error)) return
    ! 420 voxels: 5 standard errors leave a chance of about 2e-4 that a right table fails.
    ! The launch is systematic: a voxel gets the same number of photons in nearly every batch,
    ! and when it gets one more in a few batches only, the batch means may not show it (their
    ! scatter is then 0). Its share is exact to within a few such photons over all the batches,
    ! 3 wmax / (np nb), wmax the largest weight of one of its photons.
    tol = 5.0_wp*se + 3.0_wp*wmax/(real(np, wp)*nb) + 1.0e-12_wp
    bad = count(abs(mean - expect) > tol)
    call check(error, bad == 0, runs//str(bad)//' voxels off their power share by more '// &
               'than 5 standard errors and 3 photons (largest ratio '// &
               str(maxval(abs(mean - expect)/tol))//')')
    if (allocated(error)) return
    mt = st1/nb
    call check(error, abs(mt - sum(expect)) <= 5.0_wp*sqrt(max(0.0_wp, st2/nb - mt**2)/(nb - 1)) + &
               1.0e-12_wp, runs//'the photons carry the voxels'' total power, within 5 standard errors')
  end subroutine photons

  subroutine test_bad_input(error)
    type(error_t), allocatable, intent(out) :: error
    type(atmosphere_t) :: atm
    type(surface_t) :: sfc
    type(emission_t) :: em
    type(voxel_abs_t) :: va
    type(error_t), allocatable :: err
    real(wp), allocatable :: b_lev(:), kb(:), b3(:, :, :)
    call scene(atm, sfc, b_lev, kb, error)
    if (allocated(error)) return
    call voxel_abs_init(va, atm, cext, cssa, 0)
    call emission_init(em, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, err, voxel_abs=va)
    call check(error, allocated(err), 'the voxel part without the layers'' part is refused')
    if (allocated(error)) return
    deallocate (err)
    allocate (b3(NX, NY, N3), source=8.0_wp)
    call emission_init(em, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, err, b3=b3, &
                       voxel_abs=va, layer_abs=kb)
    call check(error, allocated(err), 'voxel Planck radiances with layered drawing are refused')
    if (allocated(error)) return
    deallocate (err)
    call emission_init(em, atm, sfc, b_lev, 9.5_wp, 0.0_wp, 0.0_wp, 0.1_wp, err, &
                       voxel_abs=va, layer_abs=[kb, 1.0_wp])
    call check(error, allocated(err), 'the absorption of the wrong number of layers is refused')
    if (allocated(error)) return
    call check(error, index(err%message, '3 layers given for a 3-D region of 2') > 0, &
               'the message gives both counts: '//err%message)
  end subroutine test_bad_input

end module test_emission_layered_suite

program test_emission_layered
  use kumo_testing, only: run_unittests
  use test_emission_layered_suite, only: collect_emission_layered
  implicit none
  integer :: n_failed
  call run_unittests('emission_layered', collect_emission_layered(), n_failed)
  if (n_failed > 0) error stop 1
end program test_emission_layered
