! SPDX-License-Identifier: BSD-3-Clause
!> Thermal emission without photons where the answer is exact: a plane-parallel column that
!> absorbs and emits but does not scatter, over a uniform Lambert surface, without the sun.
!>
!> Such a column has a closed-form solution (kumo_thermal_column: exponential integrals, to
!> round-off). When a thermal scene is of that kind, a batch's tallies are filled from it
!> instead of tracing photons: the fluxes at the levels, the absorbed and net power of the
!> layers and of the surface, and the radiances of the level detectors, each as the batch
!> would score it on average. Every batch is then the same, and every standard error 0. The
!> photon loop (`trace_batch`) remains the path for everything else, and for these columns when
!> `&kumo_vr use_exact_thermal = .false.` (tests compare the two).
module kumo_exact_column
  use kumo_kinds, only: wp, i8
  use kumo_constants, only: PI
  use kumo_error, only: error_t
  use kumo_atmosphere, only: LAYER_3D
  use kumo_tally, only: tally_layout_t, tally_t, score_flux, score_layer_abs, score_net_layer, &
                        score_surface_abs, score_net_surface, score_source, score_radiance
  use kumo_scene, only: scene_t
  use kumo_thermal_column, only: thermal_column_t, thermal_column_init_layers, thermal_column_fluxes, &
                                 thermal_column_radiance
  implicit none
  private
  public :: exact_thermal_possible, exact_thermal_batch

contains

  !> The scene is a thermal, non-scattering, plane-parallel column over a uniform Lambert
  !> surface, without the sun and without cameras.
  logical function exact_thermal_possible(scn) result(ok)
    type(scene_t), intent(in) :: scn
    ok = scn%src%em%on
    if (.not. ok) return
    ok = scn%src%em%solar_power <= 0.0_wp .and. scn%atm%n3 == 0 .and. &
         .not. scn%sfc%use_brdf .and. scn%sfc%uniform .and. size(scn%det%cams) == 0 .and. &
         .not. allocated(scn%src%em%b_sfc_map)
    if (.not. ok) return
    ok = all(scn%atm%omg1 <= 0.0_wp .or. scn%atm%ext1 <= 0.0_wp) .and. &
         all(scn%atm%layer_class /= LAYER_3D)
  end function exact_thermal_possible

  !> Fill the tallies of a batch of `n_photons` from the exact solution (the caller has reset
  !> `tal`; see exact_thermal_possible).
  subroutine exact_thermal_batch(scn, lay, n_photons, tal, error)
    type(scene_t), intent(in) :: scn
    type(tally_layout_t), intent(in) :: lay
    integer(i8), intent(in) :: n_photons
    type(tally_t), intent(inout) :: tal
    type(error_t), allocatable, intent(out) :: error
    type(thermal_column_t) :: col
    real(wp), allocatable :: tau(:), fu(:), fd(:), fdir(:), div(:), net(:)
    real(wp) :: eps, scale, rad
    integer :: nz, k, d, slot
    nz = scn%atm%nz
    associate (em => scn%src%em, atm => scn%atm)
      tau = atm%ext1*(atm%z(1:nz) - atm%z(0:nz - 1))
      eps = 1.0_wp - scn%sfc%albedo(1, 1)
      call thermal_column_init_layers(col, tau, em%b_bot, em%b_top_lay, eps, em%b_sfc, em%b_top, error)
      if (allocated(error)) return
      allocate (fu(0:nz), fd(0:nz), fdir(0:nz), div(0:nz), net(nz))
      call thermal_column_fluxes(col, fu, fd, fdir, div, net)
      ! tallies are sums over the batch's photons in units of the total source power P
      scale = real(n_photons, wp)/em%power
      do k = 0, nz
        call score_flux(lay, tal, k, .true., 1, fu(k)*scale)
        call score_flux(lay, tal, k, .false., 1, fd(k)*scale)
      end do
      do k = 1, nz
        call score_layer_abs(lay, tal, k, (net(k) + em%emit_layer(k))*scale)
        call score_net_layer(lay, tal, k, net(k)*scale)
      end do
      call score_surface_abs(lay, tal, eps*fd(0)*scale)
      call score_net_surface(lay, tal, (eps*fd(0) - em%emit_sfc)*scale)
      call score_source(lay, tal, real(n_photons, wp))
      ! level detectors: pi I/P per photon; downward at the top, the radiance coming in from
      ! above is added by the output, as for traced photons
      do d = 1, lay%n_rad_dir
        do k = 0, nz
          slot = lay%rad_slot(k)
          if (slot == 0) cycle
          rad = thermal_column_radiance(col, k, scn%det%uz(d))
          if (k == nz .and. scn%det%uz(d) < 0.0_wp) rad = rad - em%b_top
          call score_radiance(lay, tal, d, slot, PI*rad*scale)
        end do
      end do
    end associate
  end subroutine exact_thermal_batch

end module kumo_exact_column
