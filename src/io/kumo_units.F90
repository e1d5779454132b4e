! SPDX-License-Identifier: BSD-3-Clause
!> Units attributes of model output files: the factor from the file's unit to kumo's unit.
!>
!> Only the units that LES / cloud-resolving-model files use for the quantities kumo reads are
!> accepted, each under the spellings found in practice. Spellings are first brought to one form:
!>
!> * the micro sign (U+00B5) and the Greek small letter mu (U+03BC), both UTF-8, become `u`;
!> * `**` and `^` before an exponent are dropped (`m**-3`, `m^-3` -> `m-3`);
!> * `/` divides by the unit after it (`kg/m3`, `kg/m^3` -> `kg m-3`; `1/cm3` -> `cm-3`);
!> * `.` and `*` between units become spaces; runs of blanks become one; a factor `1` is dropped.
!>
!> The result must then be one of the accepted units of the requested quantity (table in
!> `QUANTITY_NAMES` and `accepted_units`). Anything else, and a blank units attribute, is an
!> error that lists the accepted units: a number whose scale is unknown is never used.
!>
!> Some quantities may be given per mass of air (mixing ratios `kg kg-1`, number per kilogram
!> `kg-1`). For these `per_air_mass` is true and the factor converts to kumo's unit *per kg of
!> air*; the caller multiplies by the air density [kg m-3] to get kumo's per-volume unit.
module kumo_units
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, join
  implicit none
  private
  public :: unit_factor, normalize_units, accepted_units
  public :: QTY_WATER_CONTENT, QTY_LENGTH, QTY_RADIUS, QTY_NUMBER, QTY_TEMPERATURE, QTY_PRESSURE, &
            QTY_AIR_DENSITY, QTY_HUMIDITY, QUANTITY_NAMES

  !> Quantities and kumo's unit for each (index into QUANTITY_NAMES).
  enum, bind(c)
    enumerator :: QTY_WATER_CONTENT = 1  !! condensed water content [g m-3]
    enumerator :: QTY_LENGTH             !! coordinates [m]
    enumerator :: QTY_RADIUS             !! particle effective radius [um]
    enumerator :: QTY_NUMBER             !! particle number concentration [m-3]
    enumerator :: QTY_TEMPERATURE        !! temperature [K]
    enumerator :: QTY_PRESSURE           !! pressure [Pa]
    enumerator :: QTY_AIR_DENSITY        !! air density [kg m-3]
    enumerator :: QTY_HUMIDITY           !! water vapour per mass of air [kg kg-1]
  end enum
  !> Name of each quantity and its unit in kumo, for messages.
  character(len=*), parameter :: QUANTITY_NAMES(8) = [character(len=40) :: &
                                                      'water content (kumo unit g m-3)', &
                                                      'length (kumo unit m)', &
                                                      'effective radius (kumo unit um)', &
                                                      'number concentration (kumo unit m-3)', &
                                                      'temperature (kumo unit K)', &
                                                      'pressure (kumo unit Pa)', &
                                                      'air density (kumo unit kg m-3)', &
                                                      'water vapour (kumo unit kg kg-1)']

  !> One accepted unit: normalised spelling, factor to kumo's unit, per mass of air or not.
  type :: unit_entry_t
    character(len=16) :: name = ''
    real(wp) :: factor = 1.0_wp
    logical :: per_air_mass = .false.
  end type unit_entry_t

  character(len=*), parameter :: MICRO_SIGN = char(194)//char(181)   ! U+00B5 in UTF-8
  character(len=*), parameter :: GREEK_MU = char(206)//char(188)     ! U+03BC in UTF-8

contains

  !> Factor that converts values in `units` to kumo's unit of `quantity`.
  !>
  !> kumo value = file value * factor (times the air density [kg m-3] if `per_air_mass`).
  subroutine unit_factor(units, quantity, factor, per_air_mass, error)
    character(len=*), intent(in) :: units           !! the units attribute as found in the file
    integer, intent(in) :: quantity                 !! one of the QTY_* codes
    real(wp), intent(out) :: factor                 !! multiply file values by this
    logical, intent(out) :: per_air_mass            !! value is per kg of air (needs air density)
    type(error_t), allocatable, intent(out) :: error
    type(unit_entry_t), allocatable :: table(:)
    character(len=:), allocatable :: norm
    integer :: i

    factor = 0.0_wp
    per_air_mass = .false.
    if (quantity < 1 .or. quantity > size(QUANTITY_NAMES)) then
      call set_error(error, 'unit_factor: unknown quantity code')
      return
    end if
    norm = normalize_units(units)
    if (quantity == QTY_HUMIDITY .and. trim(adjustl(units)) == '1') then
      factor = 1.0_wp                  ! the CF canonical unit of specific humidity
      return
    end if
    if (len_trim(units) == 0) then
      call set_error(error, 'units attribute is blank; '//accepted_text(quantity))
      return
    end if
    call unit_table(quantity, table)
    do i = 1, size(table)
      if (norm == trim(table(i)%name)) then
        factor = table(i)%factor
        per_air_mass = table(i)%per_air_mass
        return
      end if
    end do
    call set_error(error, 'units "'//units//'" not accepted for '// &
                   trim(QUANTITY_NAMES(quantity))//'; '//accepted_text(quantity))
  end subroutine unit_factor

  !> The accepted units of a quantity, normalised spelling, comma-separated.
  function accepted_units(quantity) result(text)
    integer, intent(in) :: quantity  !! one of the QTY_* codes
    character(len=:), allocatable :: text
    type(unit_entry_t), allocatable :: table(:)
    integer :: i
    text = ''
    if (quantity < 1 .or. quantity > size(QUANTITY_NAMES)) return
    call unit_table(quantity, table)
    text = join([(table(i)%name, i = 1, size(table))])
  end function accepted_units

  !> Bring a units string to kumo's normal spelling (see the module description).
  pure function normalize_units(units) result(norm)
    character(len=*), intent(in) :: units  !! units as written in the file
    character(len=:), allocatable :: norm
    character(len=:), allocatable :: s, term, exponent
    integer :: i, n
    logical :: divide, sign

    ! Multi-byte micro signs, then exponent markers.
    s = replace_all(units, MICRO_SIGN, 'u')
    s = replace_all(s, GREEK_MU, 'u')
    s = replace_all(s, '**', '')
    s = replace_all(s, '^', '')
    ! Term by term: letters, then an optional signed integer exponent.
    norm = ''
    divide = .false.
    i = 1
    n = len(s)
    do while (i <= n)
      select case (s(i:i))
      case (' ', '.', '*', achar(9))
        i = i + 1
      case ('/')
        if (divide) then             ! "a/b/c" is ambiguous: leave it unrecognised
          norm = units
          return
        end if
        divide = .true.
        i = i + 1
      case default
        term = ''
        do while (i <= n)
          if (.not. is_letter(s(i:i))) exit
          term = term//s(i:i)
          i = i + 1
        end do
        exponent = ''
        do while (i <= n)
          sign = len(exponent) == 0 .and. (s(i:i) == '-' .or. s(i:i) == '+')
          if (.not. (is_digit(s(i:i)) .or. sign)) exit
          exponent = exponent//s(i:i)
          i = i + 1
        end do
        if (len(term) == 0 .and. len(exponent) == 0) then   ! a character we do not know
          norm = units
          return
        end if
        if (len(term) == 0) then     ! a bare number: only the factor 1 ("1/cm3") is allowed
          if (exponent /= '1') then
            norm = units
            return
          end if
          cycle
        end if
        if (exponent(1:min(1, len(exponent))) == '+') exponent = exponent(2:)
        if (divide) then
          if (len(exponent) == 0) then
            exponent = '-1'
          else if (exponent(1:1) == '-') then
            exponent = exponent(2:)
          else
            exponent = '-'//exponent
          end if
          divide = .false.
        end if
        if (exponent == '1') exponent = ''
        if (len(norm) > 0) norm = norm//' '
        norm = norm//term//exponent
      end select
    end do
    if (divide) norm = units         ! trailing "/": unrecognised
  end function normalize_units

  ! ------------------------------------------------------------------------------------------------

  !> Accepted units per quantity. Factors are exact decimal unit relations (SI prefixes;
  !> 1 mb = 1 hPa = 100 Pa; 1 micron = 1 um).
  subroutine unit_table(quantity, table)
    integer, intent(in) :: quantity
    type(unit_entry_t), allocatable, intent(out) :: table(:)
    select case (quantity)
    case (QTY_WATER_CONTENT)
      table = [unit_entry_t('g m-3', 1.0_wp, .false.), unit_entry_t('kg m-3', 1.0e3_wp, .false.), &
               unit_entry_t('g kg-1', 1.0_wp, .true.), unit_entry_t('kg kg-1', 1.0e3_wp, .true.)]
    case (QTY_LENGTH)
      table = [unit_entry_t('m', 1.0_wp, .false.), unit_entry_t('km', 1.0e3_wp, .false.), &
               unit_entry_t('um', 1.0e-6_wp, .false.), unit_entry_t('micron', 1.0e-6_wp, .false.), &
               unit_entry_t('microns', 1.0e-6_wp, .false.), &
               unit_entry_t('micrometer', 1.0e-6_wp, .false.), &
               unit_entry_t('micrometers', 1.0e-6_wp, .false.), &
               unit_entry_t('micrometre', 1.0e-6_wp, .false.), &
               unit_entry_t('micrometres', 1.0e-6_wp, .false.)]
    case (QTY_RADIUS)
      table = [unit_entry_t('um', 1.0_wp, .false.), unit_entry_t('micron', 1.0_wp, .false.), &
               unit_entry_t('microns', 1.0_wp, .false.), &
               unit_entry_t('micrometer', 1.0_wp, .false.), &
               unit_entry_t('micrometers', 1.0_wp, .false.), &
               unit_entry_t('micrometre', 1.0_wp, .false.), &
               unit_entry_t('micrometres', 1.0_wp, .false.), &
               unit_entry_t('m', 1.0e6_wp, .false.)]
    case (QTY_NUMBER)
      table = [unit_entry_t('m-3', 1.0_wp, .false.), unit_entry_t('cm-3', 1.0e6_wp, .false.), &
               unit_entry_t('kg-1', 1.0_wp, .true.)]
    case (QTY_TEMPERATURE)
      table = [unit_entry_t('K', 1.0_wp, .false.)]
    case (QTY_PRESSURE)
      table = [unit_entry_t('Pa', 1.0_wp, .false.), unit_entry_t('hPa', 1.0e2_wp, .false.), &
               unit_entry_t('mb', 1.0e2_wp, .false.), unit_entry_t('mbar', 1.0e2_wp, .false.)]
    case (QTY_AIR_DENSITY)
      table = [unit_entry_t('kg m-3', 1.0_wp, .false.), unit_entry_t('g m-3', 1.0e-3_wp, .false.)]
    case (QTY_HUMIDITY)
      ! the ratio itself: per_air_mass stays false (nothing to multiply by the air density)
      table = [unit_entry_t('kg kg-1', 1.0_wp, .false.), unit_entry_t('g kg-1', 1.0e-3_wp, .false.)]
    case default
      allocate (table(0))
    end select
  end subroutine unit_table

  !> "accepted units: a, b, c (also written ...)" for messages.
  function accepted_text(quantity) result(text)
    integer, intent(in) :: quantity
    character(len=:), allocatable :: text
    text = 'accepted units for '//trim(QUANTITY_NAMES(quantity))//': '//accepted_units(quantity)
    select case (quantity)
    case (QTY_HUMIDITY)
      text = text//' or 1 (also written kg/kg, g/kg)'
    case (QTY_WATER_CONTENT, QTY_AIR_DENSITY, QTY_NUMBER)
      text = text//' (also written with "/", "^" or "**", e.g. kg/m3, kg/m^3, kg m^-3, '// &
             'kg m**-3, g/kg, 1/cm3)'
    case (QTY_LENGTH, QTY_RADIUS)
      text = text//' (the micro sign and Greek mu are accepted for u)'
    case default
      continue                       ! temperature and pressure have no other spellings
    end select
  end function accepted_text

  pure function replace_all(s, old, new) result(t)
    character(len=*), intent(in) :: s, old, new
    character(len=:), allocatable :: t
    integer :: i
    t = ''
    i = 1
    do while (i <= len(s))
      if (i + len(old) - 1 <= len(s)) then
        if (s(i:i + len(old) - 1) == old) then
          t = t//new
          i = i + len(old)
          cycle
        end if
      end if
      t = t//s(i:i)
      i = i + 1
    end do
  end function replace_all

  pure logical function is_letter(c)
    character(len=1), intent(in) :: c
    is_letter = (c >= 'a' .and. c <= 'z') .or. (c >= 'A' .and. c <= 'Z')
  end function is_letter

  pure logical function is_digit(c)
    character(len=1), intent(in) :: c
    is_digit = c >= '0' .and. c <= '9'
  end function is_digit
end module kumo_units
