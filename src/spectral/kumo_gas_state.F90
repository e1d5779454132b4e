! SPDX-License-Identifier: BSD-3-Clause
!> The gas state of a broadband column whose layers kb..kt come from a cloud file (an LES or
!> cloud-resolving model's temperature, pressure and water vapour, each a mean over the file's
!> columns per layer), joined to the profile of &kumo_spectral above and below
!> (docs/broadband.md, "Gas state from the cloud file").
!>
!> * Temperature: the file's layers take its temperatures; the levels that touch them are
!>   interpolated linearly in height between the midpoints of the layers on either side (the
!>   profile's layer where the file ends), or extrapolated from the two nearest layers at the
!>   ground or the top of the column. Levels and layers outside are the profile's.
!> * Pressure: the file's layers take its pressures; the levels between two of them are
!>   interpolated in log p linearly in height between their midpoints; the two outer levels
!>   keep the profile's ratio of level to adjacent layer pressure. The profile above is then
!>   multiplied by one factor, so that it meets the file's top level, and the profile below by
!>   another: the hydrostatic shape of the profile is kept (p(z) scaled by a constant solves
!>   dp/dz = -g p/(R T) with the same T), while the mass of the column above the file, and so
!>   its gas amounts, are the file's. The levels must then fall strictly with height and
!>   every layer pressure lie between its levels, or the state is refused.
!> * Water vapour: the file's layers take its volume mixing ratios.
!>
!> Pure: no file, no MPI; kumo_scene_setup reads the file on rank 0 and shares the profiles.
module kumo_gas_state
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str
  implicit none
  private
  public :: gas_state_merge

contains

  !> Put the state of the file's n layers kb..kb + n - 1 into the column (levels z(0:nz) [m],
  !> level pressures plev(0:nz) [Pa] and temperatures tlev(0:nz) [K], layer pressures play,
  !> temperatures tlay and water-vapour mixing ratios h2o (nz)). Each of `p_file`, `t_file`,
  !> `h2o_file` (n values, bottom first) is optional.
  !> `f_below` and `f_above` return the factors applied to the profile's pressures below and
  !> above the file (1 without `p_file`).
  subroutine gas_state_merge(z, kb, n, plev, play, tlev, tlay, h2o, error, p_file, t_file, &
                             h2o_file, f_below, f_above)
    real(wp), intent(in) :: z(0:)
    integer, intent(in) :: kb, n
    real(wp), intent(inout) :: plev(0:), play(:), tlev(0:), tlay(:), h2o(:)
    type(error_t), allocatable, intent(out) :: error
    real(wp), intent(in), optional :: p_file(:), t_file(:), h2o_file(:)
    real(wp), intent(out), optional :: f_below, f_above
    real(wp), allocatable :: zm(:), pnew(:)
    real(wp) :: fb, ft, w
    integer :: nz, kt, k

    fb = 1.0_wp
    ft = 1.0_wp
    if (present(f_below)) f_below = fb
    if (present(f_above)) f_above = ft
    nz = size(play)
    kt = kb + n - 1
    if (n < 1 .or. kb < 1 .or. kt > nz .or. size(z) /= nz + 1 .or. size(plev) /= nz + 1 .or. &
        size(tlev) /= nz + 1 .or. size(tlay) /= nz .or. size(h2o) /= nz .or. &
        .not. (fits(p_file) .and. fits(t_file) .and. fits(h2o_file))) then
      call set_error(error, 'gas_state_merge: the file''s layers ('//str(max(n, 0))// &
                     ' from layer '//str(kb)//', profiles of the same length) must lie within '// &
                     'the column''s '//str(nz)//' layers')
      return
    end if
    zm = 0.5_wp*(z(0:nz - 1) + z(1:nz))

    if (present(h2o_file)) then
      if (bad(h2o_file >= 0.0_wp, 'water vapour of the cloud file is negative or not a number')) &
        return
      h2o(kb:kt) = h2o_file
    end if

    if (present(t_file)) then
      if (bad(t_file > 0.0_wp, 'temperature of the cloud file is not positive')) return
      tlay(kb:kt) = t_file
      do k = kb - 1, kt
        tlev(k) = between(k)
      end do
      if (any(.not. (tlev(kb - 1:kt) > 0.0_wp))) then
        call set_error(error, 'the level temperatures interpolated from the cloud file are not '// &
                       'positive (levels '//str(kb - 1)//' to '//str(kt)//'): check its '// &
                       'temperature')
        return
      end if
    end if

    if (present(p_file)) then
      if (bad(p_file > 0.0_wp, 'pressure of the cloud file is not positive')) return
      allocate (pnew(kb - 1:kt))
      pnew(kb - 1) = p_file(1)*plev(kb - 1)/play(kb)
      pnew(kt) = p_file(n)*plev(kt)/play(kt)
      do k = kb, kt - 1
        w = (z(k) - zm(k))/(zm(k + 1) - zm(k))
        pnew(k) = exp((1.0_wp - w)*log(p_file(k - kb + 1)) + w*log(p_file(k - kb + 2)))
      end do
      fb = pnew(kb - 1)/plev(kb - 1)
      ft = pnew(kt)/plev(kt)
      plev(0:kb - 2) = fb*plev(0:kb - 2)
      play(1:kb - 1) = fb*play(1:kb - 1)
      plev(kt + 1:nz) = ft*plev(kt + 1:nz)
      play(kt + 1:nz) = ft*play(kt + 1:nz)
      plev(kb - 1:kt) = pnew
      play(kb:kt) = p_file
      do k = 1, nz
        if (.not. (plev(k) < plev(k - 1))) then
          call set_error(error, 'with the cloud file''s pressure the level pressures do not '// &
                         'fall with height: '//str(plev(k - 1))//' Pa at '//str(z(k - 1))// &
                         ' m, '//str(plev(k))//' Pa at '//str(z(k))//' m (the file''s layers '// &
                         'are '//str(kb)//' to '//str(kt)//' of the column): check its pressure')
          return
        end if
        if (.not. (play(k) <= plev(k - 1) .and. play(k) >= plev(k))) then
          call set_error(error, 'with the cloud file''s pressure, layer '//str(k)//' ('// &
                         str(z(k - 1))//' to '//str(z(k))//' m) has '//str(play(k))// &
                         ' Pa, outside its levels '//str(plev(k - 1))//' and '//str(plev(k))// &
                         ' Pa: check the file''s pressure')
          return
        end if
      end do
      if (present(f_below)) f_below = fb
      if (present(f_above)) f_above = ft
    end if

  contains

    !> A profile of the file, when given, has n values.
    logical function fits(x)
      real(wp), intent(in), optional :: x(:)
      fits = .true.
      if (present(x)) fits = size(x) == n
    end function fits

    !> False when every value is `ok`; else the error names the first layer that is not.
    logical function bad(ok, what)
      logical, intent(in) :: ok(:)
      character(len=*), intent(in) :: what
      bad = .not. all(ok)
      if (bad) call set_error(error, 'the '//what//' in layer '// &
                              str(kb - 1 + findloc(ok, .false., 1))//' of the column')
    end function bad

    !> Level k from the layer temperatures: linear in height between the midpoints of layers k
    !> and k + 1, or from the two nearest layers at the ends of the column.
    real(wp) function between(k) result(t)
      integer, intent(in) :: k
      integer :: a, b
      if (nz == 1) then
        t = tlay(1)
        return
      end if
      a = min(max(k, 1), nz - 1)
      b = a + 1
      t = tlay(a) + (z(k) - zm(a))*(tlay(b) - tlay(a))/(zm(b) - zm(a))
    end function between
  end subroutine gas_state_merge
end module kumo_gas_state
