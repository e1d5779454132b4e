! SPDX-License-Identifier: BSD-3-Clause
!> Complex refractive index of liquid water, m = n + i k, from 0.2 to 200 um.
!>
!> Table: G. M. Hale and M. R. Querry, "Optical constants of water in the 200-nm to 200-um
!> wavelength region", Appl. Opt. 12, 555-563 (1973), Table I (water at 25 C), all 169
!> wavelengths (values as distributed in machine-readable form by the refractiveindex.info
!> database, main/H2O/Hale; spot-checked against the absorption coefficients
!> mu_a = 4 pi k/lambda that Prahl's Oregon Medical Laser Center compilation lists from the
!> same table: 0.069 cm-1 at 200 nm and 0.0067 cm-1 at 300 nm give k = 1.10e-7 and 1.60e-8).
!>
!> Interpolation between table wavelengths: n linearly in wavelength, k linearly in
!> wavelength of ln k (k spans ten decades and varies roughly exponentially between nodes;
!> linear interpolation of k itself would overweight the larger neighbour). Wavelengths
!> outside [0.2, 200] um are an error, never an extrapolation.
module kumo_water_index
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kumo_kinds, only: wp
  use kumo_error, only: error_t, set_error, str
  implicit none
  private
  public :: water_index, water_index_range, WATER_INDEX_SOURCE

  !> Citation stored with tables built from this index.
  character(len=*), parameter :: WATER_INDEX_SOURCE = &
    'Hale and Querry (1973), Appl. Opt. 12, 555-563, liquid water at 25 C'

  integer, parameter :: NHQ = 169  !! number of table wavelengths
  !> Wavelength [um].
  real(wp), parameter :: HQ_WAVELENGTH_UM(NHQ) = [ &
    0.200_wp, 0.225_wp, 0.250_wp, 0.275_wp, 0.300_wp, 0.325_wp, 0.350_wp, 0.375_wp, &
    0.400_wp, 0.425_wp, 0.450_wp, 0.475_wp, 0.500_wp, 0.525_wp, 0.550_wp, 0.575_wp, &
    0.600_wp, 0.625_wp, 0.650_wp, 0.675_wp, 0.700_wp, 0.725_wp, 0.750_wp, 0.775_wp, &
    0.800_wp, 0.825_wp, 0.850_wp, 0.875_wp, 0.900_wp, 0.925_wp, 0.950_wp, 0.975_wp, &
    1.0_wp, 1.2_wp, 1.4_wp, 1.6_wp, 1.8_wp, 2.0_wp, 2.2_wp, 2.4_wp, &
    2.6_wp, 2.65_wp, 2.70_wp, 2.75_wp, 2.80_wp, 2.85_wp, 2.90_wp, 2.95_wp, &
    3.00_wp, 3.05_wp, 3.10_wp, 3.15_wp, 3.20_wp, 3.25_wp, 3.30_wp, 3.35_wp, &
    3.40_wp, 3.45_wp, 3.50_wp, 3.6_wp, 3.7_wp, 3.8_wp, 3.9_wp, 4.0_wp, &
    4.1_wp, 4.2_wp, 4.3_wp, 4.4_wp, 4.5_wp, 4.6_wp, 4.7_wp, 4.8_wp, &
    4.9_wp, 5.0_wp, 5.1_wp, 5.2_wp, 5.3_wp, 5.4_wp, 5.5_wp, 5.6_wp, &
    5.7_wp, 5.8_wp, 5.9_wp, 6.0_wp, 6.1_wp, 6.2_wp, 6.3_wp, 6.4_wp, &
    6.5_wp, 6.6_wp, 6.7_wp, 6.8_wp, 6.9_wp, 7.0_wp, 7.1_wp, 7.2_wp, &
    7.3_wp, 7.4_wp, 7.5_wp, 7.6_wp, 7.7_wp, 7.8_wp, 7.9_wp, 8.0_wp, &
    8.2_wp, 8.4_wp, 8.6_wp, 8.8_wp, 9.0_wp, 9.2_wp, 9.4_wp, 9.6_wp, &
    9.8_wp, 10.0_wp, 10.5_wp, 11.0_wp, 11.5_wp, 12.0_wp, 12.5_wp, 13.0_wp, &
    13.5_wp, 14.0_wp, 14.5_wp, 15.0_wp, 15.5_wp, 16.0_wp, 16.5_wp, 17.0_wp, &
    17.5_wp, 18.0_wp, 18.5_wp, 19.0_wp, 19.5_wp, 20.0_wp, 21.0_wp, 22.0_wp, &
    23.0_wp, 24.0_wp, 25.0_wp, 26.0_wp, 27.0_wp, 28.0_wp, 29.0_wp, 30.0_wp, &
    32.0_wp, 34.0_wp, 36.0_wp, 38.0_wp, 40.0_wp, 42.0_wp, 44.0_wp, 46.0_wp, &
    48.0_wp, 50.0_wp, 60.0_wp, 70.0_wp, 80.0_wp, 90.0_wp, 100.0_wp, 110.0_wp, &
    120.0_wp, 130.0_wp, 140.0_wp, 150.0_wp, 160.0_wp, 170.0_wp, 180.0_wp, 190.0_wp, &
    200.0_wp]
  !> Real part n.
  real(wp), parameter :: HQ_N(NHQ) = [ &
    1.396_wp, 1.373_wp, 1.362_wp, 1.354_wp, 1.349_wp, 1.346_wp, 1.343_wp, 1.341_wp, &
    1.339_wp, 1.338_wp, 1.337_wp, 1.336_wp, 1.335_wp, 1.334_wp, 1.333_wp, 1.333_wp, &
    1.332_wp, 1.332_wp, 1.331_wp, 1.331_wp, 1.331_wp, 1.330_wp, 1.330_wp, 1.330_wp, &
    1.329_wp, 1.329_wp, 1.329_wp, 1.328_wp, 1.328_wp, 1.328_wp, 1.327_wp, 1.327_wp, &
    1.327_wp, 1.324_wp, 1.321_wp, 1.317_wp, 1.312_wp, 1.306_wp, 1.296_wp, 1.279_wp, &
    1.242_wp, 1.219_wp, 1.188_wp, 1.157_wp, 1.142_wp, 1.149_wp, 1.201_wp, 1.292_wp, &
    1.371_wp, 1.426_wp, 1.467_wp, 1.483_wp, 1.478_wp, 1.467_wp, 1.450_wp, 1.432_wp, &
    1.420_wp, 1.410_wp, 1.400_wp, 1.385_wp, 1.374_wp, 1.364_wp, 1.357_wp, 1.351_wp, &
    1.346_wp, 1.342_wp, 1.338_wp, 1.334_wp, 1.332_wp, 1.330_wp, 1.330_wp, 1.330_wp, &
    1.328_wp, 1.325_wp, 1.322_wp, 1.317_wp, 1.312_wp, 1.305_wp, 1.298_wp, 1.289_wp, &
    1.277_wp, 1.262_wp, 1.248_wp, 1.265_wp, 1.319_wp, 1.363_wp, 1.357_wp, 1.347_wp, &
    1.339_wp, 1.334_wp, 1.329_wp, 1.324_wp, 1.321_wp, 1.317_wp, 1.314_wp, 1.312_wp, &
    1.309_wp, 1.307_wp, 1.304_wp, 1.302_wp, 1.299_wp, 1.297_wp, 1.294_wp, 1.291_wp, &
    1.286_wp, 1.281_wp, 1.275_wp, 1.269_wp, 1.262_wp, 1.255_wp, 1.247_wp, 1.239_wp, &
    1.229_wp, 1.218_wp, 1.185_wp, 1.153_wp, 1.126_wp, 1.111_wp, 1.123_wp, 1.146_wp, &
    1.177_wp, 1.210_wp, 1.241_wp, 1.270_wp, 1.297_wp, 1.325_wp, 1.351_wp, 1.376_wp, &
    1.401_wp, 1.423_wp, 1.443_wp, 1.461_wp, 1.476_wp, 1.480_wp, 1.487_wp, 1.500_wp, &
    1.511_wp, 1.521_wp, 1.531_wp, 1.539_wp, 1.545_wp, 1.549_wp, 1.551_wp, 1.551_wp, &
    1.546_wp, 1.536_wp, 1.527_wp, 1.522_wp, 1.519_wp, 1.522_wp, 1.530_wp, 1.541_wp, &
    1.555_wp, 1.587_wp, 1.703_wp, 1.821_wp, 1.886_wp, 1.924_wp, 1.957_wp, 1.966_wp, &
    2.004_wp, 2.036_wp, 2.056_wp, 2.069_wp, 2.081_wp, 2.094_wp, 2.107_wp, 2.119_wp, &
    2.130_wp]
  !> Imaginary part k.
  real(wp), parameter :: HQ_K(NHQ) = [ &
    1.10e-7_wp, 4.90e-8_wp, 3.35e-8_wp, 2.35e-8_wp, 1.60e-8_wp, 1.08e-8_wp, &
    6.50e-9_wp, 3.50e-9_wp, 1.86e-9_wp, 1.30e-9_wp, 1.02e-9_wp, 9.35e-10_wp, &
    1.00e-9_wp, 1.32e-9_wp, 1.96e-9_wp, 3.60e-9_wp, 1.09e-8_wp, 1.39e-8_wp, &
    1.64e-8_wp, 2.23e-8_wp, 3.35e-8_wp, 9.15e-8_wp, 1.56e-7_wp, 1.48e-7_wp, &
    1.25e-7_wp, 1.82e-7_wp, 2.93e-7_wp, 3.91e-7_wp, 4.86e-7_wp, 1.06e-6_wp, &
    2.93e-6_wp, 3.48e-6_wp, 2.89e-6_wp, 9.89e-6_wp, 1.38e-4_wp, 8.55e-5_wp, &
    1.15e-4_wp, 1.10e-3_wp, 2.89e-4_wp, 9.56e-4_wp, 3.17e-3_wp, 6.70e-3_wp, &
    0.019_wp, 0.059_wp, 0.115_wp, 0.185_wp, 0.268_wp, 0.298_wp, &
    0.272_wp, 0.240_wp, 0.192_wp, 0.135_wp, 0.0924_wp, 0.0610_wp, &
    0.0368_wp, 0.0261_wp, 0.0195_wp, 0.0132_wp, 0.0094_wp, 0.00515_wp, &
    0.00360_wp, 0.00340_wp, 0.00380_wp, 0.00460_wp, 0.00562_wp, 0.00688_wp, &
    0.00845_wp, 0.0103_wp, 0.0134_wp, 0.0147_wp, 0.0157_wp, 0.0150_wp, &
    0.0137_wp, 0.0124_wp, 0.0111_wp, 0.0101_wp, 0.0098_wp, 0.0103_wp, &
    0.0116_wp, 0.0142_wp, 0.0203_wp, 0.0330_wp, 0.0622_wp, 0.107_wp, &
    0.131_wp, 0.0880_wp, 0.0570_wp, 0.0449_wp, 0.0392_wp, 0.0356_wp, &
    0.0337_wp, 0.0327_wp, 0.0322_wp, 0.0320_wp, 0.0320_wp, 0.0321_wp, &
    0.0322_wp, 0.0324_wp, 0.0326_wp, 0.0328_wp, 0.0331_wp, 0.0335_wp, &
    0.0339_wp, 0.0343_wp, 0.0351_wp, 0.0361_wp, 0.0372_wp, 0.0385_wp, &
    0.0399_wp, 0.0415_wp, 0.0433_wp, 0.0454_wp, 0.0479_wp, 0.0508_wp, &
    0.0662_wp, 0.0968_wp, 0.142_wp, 0.199_wp, 0.259_wp, 0.305_wp, &
    0.343_wp, 0.370_wp, 0.388_wp, 0.402_wp, 0.414_wp, 0.422_wp, &
    0.428_wp, 0.429_wp, 0.429_wp, 0.426_wp, 0.421_wp, 0.414_wp, &
    0.404_wp, 0.393_wp, 0.382_wp, 0.373_wp, 0.367_wp, 0.361_wp, &
    0.356_wp, 0.350_wp, 0.344_wp, 0.338_wp, 0.333_wp, 0.328_wp, &
    0.324_wp, 0.329_wp, 0.343_wp, 0.361_wp, 0.385_wp, 0.409_wp, &
    0.436_wp, 0.462_wp, 0.488_wp, 0.514_wp, 0.587_wp, 0.576_wp, &
    0.547_wp, 0.536_wp, 0.532_wp, 0.531_wp, 0.526_wp, 0.514_wp, &
    0.500_wp, 0.495_wp, 0.496_wp, 0.497_wp, 0.499_wp, 0.501_wp, &
    0.504_wp]

contains

  !> Shortest and longest wavelength of the table [um].
  pure subroutine water_index_range(wl_min_um, wl_max_um)
    real(wp), intent(out) :: wl_min_um  !! 0.2 um
    real(wp), intent(out) :: wl_max_um  !! 200 um
    wl_min_um = HQ_WAVELENGTH_UM(1)
    wl_max_um = HQ_WAVELENGTH_UM(NHQ)
  end subroutine water_index_range

  !> Refractive index of liquid water at a wavelength within the table.
  subroutine water_index(wavelength_um, m, error)
    real(wp), intent(in) :: wavelength_um            !! vacuum wavelength [um]
    complex(wp), intent(out) :: m                    !! n + i k
    type(error_t), allocatable, intent(out) :: error  !! set outside [0.2, 200] um
    integer :: lo, hi, mid
    real(wp) :: t, n, lnk
    m = (1.0_wp, 0.0_wp)
    if (.not. (wavelength_um >= HQ_WAVELENGTH_UM(1) .and. &
               wavelength_um <= HQ_WAVELENGTH_UM(NHQ) .and. ieee_is_finite(wavelength_um))) then
      call set_error(error, 'water_index: wavelength = '//str(wavelength_um)// &
                     ' um is outside the Hale and Querry (1973) table range [' // &
                     str(HQ_WAVELENGTH_UM(1))//', '//str(HQ_WAVELENGTH_UM(NHQ))//'] um')
      return
    end if
    lo = 1
    hi = NHQ
    do while (hi - lo > 1)
      mid = (lo + hi)/2
      if (HQ_WAVELENGTH_UM(mid) <= wavelength_um) then
        lo = mid
      else
        hi = mid
      end if
    end do
    t = (wavelength_um - HQ_WAVELENGTH_UM(lo))/(HQ_WAVELENGTH_UM(hi) - HQ_WAVELENGTH_UM(lo))
    n = (1.0_wp - t)*HQ_N(lo) + t*HQ_N(hi)
    lnk = (1.0_wp - t)*log(HQ_K(lo)) + t*log(HQ_K(hi))
    m = cmplx(n, exp(lnk), kind=wp)
  end subroutine water_index
end module kumo_water_index
