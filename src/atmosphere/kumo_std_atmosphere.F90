! SPDX-License-Identifier: BSD-3-Clause
!> Named standard atmospheres: pressure, temperature and air density on given heights.
!>
!> 'us1976': the U.S. Standard Atmosphere 1976 (NOAA, NASA and USAF, 1976, U.S. Standard
!> Atmosphere, 1976, U.S. Government Printing Office, Washington D.C., NOAA-S/T 76-1562),
!> computed from its definition up to 86 km geometric height:
!>
!> * geopotential height H = r0 z/(r0 + z), r0 = 6356.766 km;
!> * molecular-scale temperature T_M linear in H within seven layers with bases
!>   H_b = 0, 11, 20, 32, 47, 51, 71 km' and gradients L_b = -6.5, 0, 1, 2.8, 0, -2.8, -2.0
!>   K/km' (Table 4), T_M = 288.15 K and p = 101325 Pa at H = 0;
!> * hydrostatic pressure (eqs. 33a, 33b)
!>   p = p_b [T_M,b/(T_M,b + L_b (H - H_b))]^(g0' M0/(R* L_b))   (L_b /= 0),
!>   p = p_b exp(-g0' M0 (H - H_b)/(R* T_M,b))                   (L_b = 0),
!>   g0' = 9.80665 m2 s-2 m'-1, M0 = 28.9644 kg/kmol, R* = 8.31432e3 J kmol-1 K-1;
!> * kinetic temperature T = T_M M/M0, with M/M0 = 1 below 80 km and tabulated from 80 to
!>   86 km (Table 8);
!> * air density rho = p M0/(R* T_M) (with T M0/M = T_M).
!>
!> The profile is defined from -5 km to 86 km geometric height.
module kumo_std_atmosphere
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str, to_lower, join
  implicit none
  private
  public :: STD_ATM_US1976, STD_ATMOSPHERE_NAMES, US1976_Z_MIN, US1976_Z_MAX
  public :: std_atmosphere_kind_from_name, std_atmosphere_profile, us1976_state

  integer, parameter :: STD_ATM_US1976 = 1  !! U.S. Standard Atmosphere 1976

  !> Names accepted by `std_atmosphere_kind_from_name`, indexed by kind code.
  character(len=6), parameter :: STD_ATMOSPHERE_NAMES(1) = [character(len=6) :: 'us1976']

  real(wp), parameter :: US1976_Z_MIN = -5000.0_wp  !! lowest defined geometric height [m]
  real(wp), parameter :: US1976_Z_MAX = 86000.0_wp  !! highest defined geometric height [m]

  ! Constants of the standard (U.S. Standard Atmosphere 1976).
  real(wp), parameter :: G0P = 9.80665_wp        !! g0' [m2 s-2 m'-1]
  real(wp), parameter :: R_STAR = 8.31432e3_wp   !! gas constant [J kmol-1 K-1]
  real(wp), parameter :: M0 = 28.9644_wp         !! sea-level mean molar mass [kg kmol-1]
  real(wp), parameter :: R0 = 6356766.0_wp       !! effective Earth radius [m]
  real(wp), parameter :: T0 = 288.15_wp          !! sea-level temperature [K]
  real(wp), parameter :: P0 = 101325.0_wp        !! sea-level pressure [Pa]
  !> Layer bases H_b [m'] and gradients L_b [K/m'] (Table 4 of the standard).
  real(wp), parameter :: H_BASE(7) = [0.0_wp, 11000.0_wp, 20000.0_wp, 32000.0_wp, &
                                      47000.0_wp, 51000.0_wp, 71000.0_wp]
  real(wp), parameter :: LAPSE(7) = [-6.5e-3_wp, 0.0_wp, 1.0e-3_wp, 2.8e-3_wp, 0.0_wp, &
                                     -2.8e-3_wp, -2.0e-3_wp]
  !> M/M0 at geometric heights 80.0, 80.5, ..., 86.0 km (Table 8 of the standard).
  real(wp), parameter :: M_RATIO(13) = [1.000000_wp, 0.999996_wp, 0.999989_wp, 0.999971_wp, &
                                        0.999941_wp, 0.999909_wp, 0.999870_wp, 0.999829_wp, &
                                        0.999786_wp, 0.999741_wp, 0.999694_wp, 0.999641_wp, &
                                        0.999579_wp]

contains

  !> Kind code of a standard atmosphere from its name (case-insensitive). Unknown names give an
  !> error listing the allowed ones.
  subroutine std_atmosphere_kind_from_name(name, kind, error)
    character(len=*), intent(in) :: name  !! e.g. 'us1976'
    integer, intent(out) :: kind          !! STD_ATM_* code; -1 if unknown
    type(error_t), allocatable, intent(out) :: error
    integer :: i
    do i = 1, size(STD_ATMOSPHERE_NAMES)
      if (trim(adjustl(to_lower(name))) == trim(STD_ATMOSPHERE_NAMES(i))) then
        kind = i
        return
      end if
    end do
    kind = -1
    call set_error(error, "standard atmosphere '"//trim(adjustl(name))// &
                   "' must be one of "//join(STD_ATMOSPHERE_NAMES))
  end subroutine std_atmosphere_kind_from_name

  !> Pressure, temperature and air density of the named standard atmosphere at heights `z`.
  !> Every height must lie within the range where the atmosphere is defined.
  subroutine std_atmosphere_profile(name, z, p, t, rho_air, error)
    character(len=*), intent(in) :: name  !! standard atmosphere, one of STD_ATMOSPHERE_NAMES
    real(wp), intent(in) :: z(:)          !! geometric heights above sea level [m]
    real(wp), intent(out) :: p(:)         !! pressure [Pa], same size as z
    real(wp), intent(out) :: t(:)         !! (kinetic) temperature [K], same size as z
    real(wp), intent(out) :: rho_air(:)   !! air density [kg m-3], same size as z
    type(error_t), allocatable, intent(out) :: error
    integer :: kind, i
    call std_atmosphere_kind_from_name(name, kind, error)
    if (allocated(error)) return
    if (size(p) /= size(z) .or. size(t) /= size(z) .or. size(rho_air) /= size(z)) then
      call set_error(error, 'std_atmosphere_profile: p, t and rho_air must have the size of '// &
                     'z, '//str(size(z)))
      return
    end if
    do i = 1, size(z)
      if (.not. (ieee_is_finite(z(i)) .and. z(i) >= US1976_Z_MIN &
                 .and. z(i) <= US1976_Z_MAX)) then
        call set_error(error, "standard atmosphere '"//trim(STD_ATMOSPHERE_NAMES(kind))// &
                       "': z("//str(i)//') = '//str(z(i))//' m must be within ['// &
                       str(US1976_Z_MIN)//', '//str(US1976_Z_MAX)//'] m')
        return
      end if
    end do
    select case (kind)
    case (STD_ATM_US1976)
      call us1976_state(z, p, t, rho_air)
    case default
      call set_error(error, 'std_atmosphere_profile: no profile for kind '//str(kind))
    end select
  end subroutine std_atmosphere_profile

  !> U.S. Standard Atmosphere 1976 at geometric height `z` in [-5, 86] km (not checked).
  elemental subroutine us1976_state(z, p, t, rho_air)
    real(wp), intent(in) :: z          !! geometric height above sea level [m]
    real(wp), intent(out) :: p         !! pressure [Pa]
    real(wp), intent(out) :: t         !! kinetic temperature [K]
    real(wp), intent(out) :: rho_air   !! air density [kg m-3]
    real(wp) :: h, tb, pb, tm, w
    integer :: ib, i
    h = R0*z/(R0 + z)
    ! base temperature and pressure of each layer up to the one holding h
    tb = T0
    pb = P0
    ib = 1
    do i = 1, 6
      if (h < H_BASE(i + 1)) exit
      call layer_top(tb, pb, LAPSE(i), H_BASE(i + 1) - H_BASE(i))
      ib = i + 1
    end do
    tm = tb
    p = pb
    call layer_top(tm, p, LAPSE(ib), h - H_BASE(ib))
    rho_air = p*M0/(R_STAR*tm)
    if (z <= 80000.0_wp) then
      t = tm
    else
      w = min((z - 80000.0_wp)/500.0_wp, 11.999999_wp)
      i = int(w) + 1
      w = w - (i - 1)
      t = tm*((1.0_wp - w)*M_RATIO(i) + w*M_RATIO(i + 1))
    end if
  end subroutine us1976_state

  !> Advance molecular-scale temperature and pressure by dh [m'] through a layer of gradient
  !> `lapse` [K/m'] (eqs. 33a, 33b of the standard).
  elemental subroutine layer_top(tm, p, lapse, dh)
    real(wp), intent(inout) :: tm  !! T_M at the start, on return at the end [K]
    real(wp), intent(inout) :: p   !! pressure at the start, on return at the end [Pa]
    real(wp), intent(in) :: lapse  !! dT_M/dH [K/m']
    real(wp), intent(in) :: dh     !! height step [m']
    real(wp) :: t_end
    if (lapse == 0.0_wp) then
      p = p*exp(-G0P*M0*dh/(R_STAR*tm))
    else
      t_end = tm + lapse*dh
      p = p*(tm/t_end)**(G0P*M0/(R_STAR*lapse))
      tm = t_end
    end if
  end subroutine layer_top

end module kumo_std_atmosphere
