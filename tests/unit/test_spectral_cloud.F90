! SPDX-License-Identifier: BSD-3-Clause
!> Unit test of kumo_spectral_cloud's band switch: after its first band, spectral_cloud_band
!> forms only the voxels with water. Whatever the order of the bands, each voxel with water
!> must hold what mie_layer forms for that band (bit for bit, with the same count of radii
!> outside the table), and each voxel without water the values that are the same in every
!> band (no extinction, no blend, the first band's first table).
module test_spectral_cloud_suite
  use kumo_kinds, only: wp, vp
  use kumo_spectral_cloud, only: spectral_cloud_t, spectral_cloud_band
  use kumo_cloud_scene, only: mie_layer
  use kumo_testing, only: error_t, unittest_t, new_unittest, check
  implicit none
  private
  public :: collect_spectral_cloud

contains

  function collect_spectral_cloud() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('band_switch_forms_the_voxels_with_water', test_layers), &
             new_unittest('band_switch_on_planes', test_planes)]
  end function collect_spectral_cloud

  subroutine test_layers(error)
    type(error_t), allocatable, intent(out) :: error
    call band_case(error, .false.)
  end subroutine test_layers

  subroutine test_planes(error)
    type(error_t), allocatable, intent(out) :: error
    call band_case(error, .true.)
  end subroutine test_planes

  !> Two bands with different tables, visited 2, 1, 2, 1 (the first visit fills the voxels
  !> without water); a field with voxels without water and radii on both sides of the tables.
  subroutine band_case(error, points)
    type(error_t), allocatable, intent(out) :: error
    logical, intent(in) :: points
    integer, parameter :: NX = 5, NY = 4, NZ = 3
    type(spectral_cloud_t) :: sc
    integer :: np, nplanes, i, j, k, ib, visit, n_liq, n_ice, n_ref, ip
    real(wp) :: ext(NX, NY), ssa(NX, NY), wph(NX, NY)
    integer :: iph(NX, NY)
    logical :: dry(NX, NY)
    integer, parameter :: ORDER(4) = [2, 1, 2, 1]
    np = merge(2, 1, points)
    nplanes = NZ + np - 1
    sc%n_band = 2
    sc%nx = NX
    sc%ny = NY
    sc%nz = NZ
    sc%nc3 = np
    sc%liq%nx = NX
    sc%liq%ny = NY
    sc%liq%nz = NZ
    sc%liq%points = points
    allocate (sc%liq%lwc(NX, NY, nplanes), sc%liq%reff(NX, NY, nplanes))
    do k = 1, nplanes
      do j = 1, NY
        do i = 1, NX
          sc%liq%lwc(i, j, k) = real(max(0.0_wp, sin(1.1_wp*i + 0.7_wp*j*k) - 0.2_wp), vp)
          sc%liq%reff(i, j, k) = real(1.0_wp + 4.5_wp*i + 1.3_wp*j - k, vp)
        end do
      end do
    end do
    allocate (sc%liq_tab(2), sc%off_liq(2), sc%off_ice(2))
    sc%liq_tab(1)%r_eff_um = [4.0_wp, 8.0_wp, 16.0_wp]
    sc%liq_tab(1)%ext_per_lwc = [0.2_wp, 0.11_wp, 0.05_wp]
    sc%liq_tab(1)%ssa = [0.99_wp, 0.98_wp, 0.97_wp]
    sc%liq_tab(2)%r_eff_um = [5.0_wp, 10.0_wp, 20.0_wp, 24.0_wp]
    sc%liq_tab(2)%ext_per_lwc = [0.15_wp, 0.08_wp, 0.04_wp, 0.035_wp]
    sc%liq_tab(2)%ssa = [0.9_wp, 0.85_wp, 0.8_wp, 0.75_wp]
    sc%off_liq = [2, 5]
    sc%off_ice = 0
    call check(error, any(sc%liq%lwc <= 0.0_vp) .and. any(sc%liq%lwc > 0.0_vp), &
               'the field has voxels with and without water')
    if (allocated(error)) return
    do visit = 1, size(ORDER)
      ib = ORDER(visit)
      call spectral_cloud_band(sc, ib, n_liq, n_ice)
      call check(error, sc%band == ib .and. n_ice == 0, 'the band is noted')
      if (allocated(error)) return
      n_ref = 0
      do ip = 1, np
        do k = 1, NZ
          call mie_layer(sc%liq, sc%liq%lwc, sc%liq%reff, sc%liq_tab(ib), sc%off_liq(ib), &
                         .false., k, ip, ext, ssa, iph, wph, n_ref)
          dry = sc%liq%lwc(:, :, k + ip - 1) <= 0.0_vp
          call check(error, all(dry .or. (sc%cext(:, :, k, ip) == ext .and. &
                                          sc%cssa(:, :, k, ip) == ssa .and. &
                                          sc%ciph(:, :, k, ip) == iph .and. &
                                          sc%cwph(:, :, k, ip) == real(wph, vp))), &
                     'the voxels with water are those of mie_layer at visit '//achar(48 + visit))
          if (allocated(error)) return
          call check(error, all(.not. dry .or. (sc%cext(:, :, k, ip) == 0.0_wp .and. &
                                                sc%ciph(:, :, k, ip) == sc%off_liq(1) + 1 .and. &
                                                sc%cwph(:, :, k, ip) == 0.0_vp)), &
                     'the voxels without water are the same in every band')
          if (allocated(error)) return
        end do
      end do
      call check(error, n_liq == n_ref .and. n_ref > 0, &
                 'the radii outside the table are counted as mie_layer counts them')
      if (allocated(error)) return
    end do
  end subroutine band_case
end module test_spectral_cloud_suite

program test_spectral_cloud
  use kumo_testing, only: run_unittests
  use test_spectral_cloud_suite, only: collect_spectral_cloud
  implicit none
  integer :: n_failed
  call run_unittests('spectral_cloud', collect_spectral_cloud(), n_failed)
  if (n_failed > 0) error stop 1
end program test_spectral_cloud
