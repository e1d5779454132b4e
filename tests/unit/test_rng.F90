! SPDX-License-Identifier: BSD-3-Clause
!> Unit tests of kumo_rng: published reference outputs, determinism, range, moments, stream
!> independence and uniformity of xoshiro256** seeded by splitmix64.
!>
!> Statistical checks use fixed seeds and a 4 sigma limit; thresholds are not tuned to the seeds.
module test_kumo_rng
  use kumo_kinds, only: wp, i8
  use kumo_rng, only: rng_t, rng_init, rng_uniform, rng_next_uniform, rng_next_u64, &
                      splitmix64_next
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_close, check_sigma
  implicit none
  private
  public :: collect_rng

  integer(i8), parameter :: SEED = 20240917_i8  !! fixed seed of the statistical tests

contains

  !> All tests of this suite.
  function collect_rng() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('xoshiro256starstar_reference', test_xoshiro_reference), &
             new_unittest('splitmix64_reference', test_splitmix_reference), &
             new_unittest('uniform_uses_top_53_bits', test_uniform_bits), &
             new_unittest('deterministic_per_seed_and_stream', test_determinism), &
             new_unittest('distinct_streams_nonzero_state', test_distinct_streams), &
             new_unittest('uniform_in_unit_interval', test_range), &
             new_unittest('mean_and_variance', test_moments), &
             new_unittest('stream_independence', test_stream_independence), &
             new_unittest('chi2_uniformity_20_bins', test_chi2)]
  end function collect_rng

  !> xoshiro256** from the state (1, 2, 3, 4): outputs of the published C reference code
  !> (Blackman & Vigna), checked with an independent C build. Values above huge(1_i8) are
  !> written as their two's-complement signed equivalents.
  subroutine test_xoshiro_reference(error)
    type(error_t), allocatable, intent(out) :: error
    integer(i8) :: expected(10), x
    type(rng_t) :: rng
    integer :: i
    character(len=40) :: buf
    ! 7th and 9th as unsigned: 16172922978634559625, 10595114339597558777
    expected = [11520_i8, 0_i8, 1509978240_i8, 1215971899390074240_i8, 1216172134540287360_i8, &
                607988272756665600_i8, -2273821095074991991_i8, 8476171486693032832_i8, &
                -7851629734111992839_i8, 2904607092377533576_i8]
    rng%s = [1_i8, 2_i8, 3_i8, 4_i8]
    do i = 1, size(expected)
      call rng_next_u64(rng, x)
      write (buf, '(a, i0)') 'output ', i
      call check(error, x == expected(i), trim(buf)//' differs from the reference')
      if (allocated(error)) return
    end do
  end subroutine test_xoshiro_reference

  !> splitmix64 from state 0: 0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, 0x06C45D188009454F.
  subroutine test_splitmix_reference(error)
    type(error_t), allocatable, intent(out) :: error
    integer(i8), parameter :: expected(3) = [-2152535657050944081_i8, 7960286522194355700_i8, &
                                             487617019471545679_i8]
    integer(i8) :: state, x
    integer :: i
    state = 0_i8
    do i = 1, size(expected)
      call splitmix64_next(state, x)
      call check(error, x == expected(i), 'splitmix64 output differs from the reference')
      if (allocated(error)) return
    end do
  end subroutine test_splitmix_reference

  !> From the state (1, 2, 3, 4): 11520 = 5.625*2^11 gives 5*2^-53, 0 gives exactly 0; the
  !> function and the subroutine form agree.
  subroutine test_uniform_bits(error)
    type(error_t), allocatable, intent(out) :: error
    type(rng_t) :: a, b
    real(wp) :: u, v
    integer :: i
    a%s = [1_i8, 2_i8, 3_i8, 4_i8]
    u = rng_uniform(a)
    call check_close(error, u, 5.0_wp*0.5_wp**53, abs_tol=0.0_wp, rel_tol=0.0_wp, label='u1')
    u = rng_uniform(a)
    call check_close(error, u, 0.0_wp, abs_tol=0.0_wp, rel_tol=0.0_wp, label='u2')
    if (allocated(error)) return
    call rng_init(a, SEED, 3_i8)
    b = a
    do i = 1, 1000
      u = rng_uniform(a)
      call rng_next_uniform(b, v)
      call check_close(error, v, u, abs_tol=0.0_wp, rel_tol=0.0_wp, &
                       label='rng_next_uniform vs rng_uniform')
      if (allocated(error)) return
    end do
  end subroutine test_uniform_bits

  !> The same (seed, stream) gives the same sequence, also when a used generator is
  !> re-initialised (the result depends on (seed, stream) only).
  subroutine test_determinism(error)
    type(error_t), allocatable, intent(out) :: error
    type(rng_t) :: a, b
    integer(i8) :: x, y
    integer :: i
    call rng_init(a, 12345_i8, 678_i8)
    call rng_init(b, 999_i8, 1_i8)
    do i = 1, 17
      call rng_next_u64(b, y)
    end do
    call rng_init(b, 12345_i8, 678_i8)
    call check(error, all(a%s == b%s), 'state after rng_init depends on the previous state')
    if (allocated(error)) return
    do i = 1, 10000
      call rng_next_u64(a, x)
      call rng_next_u64(b, y)
      call check(error, x == y, 'sequences of equal (seed, stream) differ')
      if (allocated(error)) return
    end do
  end subroutine test_determinism

  !> Neighbouring seeds and streams (including 0 and -1) give distinct, non-zero states.
  subroutine test_distinct_streams(error)
    type(error_t), allocatable, intent(out) :: error
    integer(i8), parameter :: values(5) = [0_i8, 1_i8, 2_i8, -1_i8, huge(1_i8)]
    integer(i8) :: first(size(values)**2)
    type(rng_t) :: rng
    integer :: i, j, k
    k = 0
    do i = 1, size(values)
      do j = 1, size(values)
        call rng_init(rng, values(i), values(j))
        call check(error, any(rng%s /= 0_i8), 'all-zero state after rng_init')
        if (allocated(error)) return
        k = k + 1
        call rng_next_u64(rng, first(k))
      end do
    end do
    do i = 1, k - 1
      call check(error, all(first(i + 1:k) /= first(i)), &
                 'two (seed, stream) pairs give the same first output')
      if (allocated(error)) return
    end do
  end subroutine test_distinct_streams

  !> 10^6 deviates all lie in [0, 1).
  subroutine test_range(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: n = 1000000
    type(rng_t) :: rng
    real(wp) :: u, umin, umax
    integer :: i
    call rng_init(rng, SEED, 0_i8)
    umin = 1.0_wp
    umax = 0.0_wp
    do i = 1, n
      u = rng_uniform(rng)
      umin = min(umin, u)
      umax = max(umax, u)
    end do
    call check(error, umin >= 0.0_wp .and. umax < 1.0_wp, 'deviate outside [0, 1)')
  end subroutine test_range

  !> Mean 1/2 and variance 1/12 of 10^6 deviates, each within 4 standard errors:
  !> sigma(mean) = sqrt(1/(12 n)), sigma(variance) = sqrt((mu4 - sigma^4)/n) = sqrt(1/(180 n)).
  subroutine test_moments(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: n = 1000000
    type(rng_t) :: rng
    real(wp) :: u, s1, s2, mean, var
    integer :: i
    call rng_init(rng, SEED, 1_i8)
    s1 = 0.0_wp
    s2 = 0.0_wp
    do i = 1, n
      u = rng_uniform(rng) - 0.5_wp
      s1 = s1 + u
      s2 = s2 + u*u
    end do
    mean = s1/n
    var = s2/n - mean**2
    call check_sigma(error, mean + 0.5_wp, 0.5_wp, sqrt(1.0_wp/(12.0_wp*n)), label='mean')
    call check_sigma(error, var, 1.0_wp/12.0_wp, sqrt(1.0_wp/(180.0_wp*n)), label='variance')
  end subroutine test_moments

  !> Pearson correlation of paired deviates from (seed, b) and (seed, b+1), from seeds 1 and 2
  !> with the same stream, and lag-1 within one stream: |r| < 4/sqrt(n) each.
  subroutine test_stream_independence(error)
    type(error_t), allocatable, intent(out) :: error
    integer(i8), parameter :: batches(4) = [0_i8, 1_i8, 41_i8, 1000000_i8]
    type(rng_t) :: a, b
    integer(i8) :: skipped
    integer :: i
    do i = 1, size(batches)
      call rng_init(a, SEED, batches(i))
      call rng_init(b, SEED, batches(i) + 1_i8)
      call check_pair(error, a, b, 'streams (seed, b) and (seed, b+1)')
    end do
    do i = 1, 2
      call rng_init(a, 1_i8, batches(i))
      call rng_init(b, 2_i8, batches(i))
      call check_pair(error, a, b, 'seeds 1 and 2, same stream')
    end do
    call rng_init(a, SEED, 5_i8)
    b = a
    call rng_next_u64(b, skipped)   ! b runs one step ahead of a
    call check_pair(error, a, b, 'lag 1 within a stream')
  end subroutine test_stream_independence

  !> Fail unless the sample correlation of n pairs (rng_uniform(a), rng_uniform(b)) is below
  !> 4/sqrt(n) in magnitude.
  subroutine check_pair(error, a, b, what)
    type(error_t), allocatable, intent(inout) :: error
    type(rng_t), intent(inout) :: a, b
    character(len=*), intent(in) :: what
    integer, parameter :: n = 200000
    real(wp) :: x, y, sx, sy, sxx, syy, sxy, r
    integer :: i
    if (allocated(error)) return
    sx = 0.0_wp
    sy = 0.0_wp
    sxx = 0.0_wp
    syy = 0.0_wp
    sxy = 0.0_wp
    do i = 1, n
      x = rng_uniform(a) - 0.5_wp
      y = rng_uniform(b) - 0.5_wp
      sx = sx + x
      sy = sy + y
      sxx = sxx + x*x
      syy = syy + y*y
      sxy = sxy + x*y
    end do
    r = (sxy - sx*sy/n)/sqrt((sxx - sx**2/n)*(syy - sy**2/n))
    call check_sigma(error, r, 0.0_wp, 1.0_wp/sqrt(real(n, wp)), label='correlation, '//what)
  end subroutine check_pair

  !> Chi-square test of 10^5 deviates in 20 equal bins against the 0.999 quantile of the
  !> chi-square distribution with 19 degrees of freedom, 43.820 (root x of P(19/2, x/2) =
  !> 0.999, P the regularised lower incomplete gamma function, solved by bisection).
  subroutine test_chi2(error)
    type(error_t), allocatable, intent(out) :: error
    integer, parameter :: n = 100000, nbins = 20
    real(wp), parameter :: CHI2_999_DF19 = 43.820_wp
    type(rng_t) :: rng
    integer :: counts(nbins), i, ibin
    real(wp) :: expected, chi2
    character(len=32) :: buf
    call rng_init(rng, SEED, 2_i8)
    counts = 0
    do i = 1, n
      ibin = min(int(rng_uniform(rng)*nbins) + 1, nbins)
      counts(ibin) = counts(ibin) + 1
    end do
    expected = real(n, wp)/nbins
    chi2 = sum((counts - expected)**2/expected)
    write (buf, '(f0.3)') chi2
    call check(error, chi2 < CHI2_999_DF19, 'chi2 = '//trim(buf)//' >= 43.820 (df = 19, p = 0.001)')
  end subroutine test_chi2
end module test_kumo_rng

program test_rng
  use test_kumo_rng, only: collect_rng
  use kumo_testing, only: run_unittests
  implicit none
  integer :: n_failed
  call run_unittests('kumo_rng', collect_rng(), n_failed)
  if (n_failed > 0) error stop 1
end program test_rng
