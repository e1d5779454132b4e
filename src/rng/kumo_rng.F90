! SPDX-License-Identifier: BSD-3-Clause
!> Pseudo-random numbers: xoshiro256** seeded by splitmix64 from a (seed, stream) pair.
!>
!> Generator: xoshiro256** 1.0 (D. Blackman and S. Vigna, "Scrambled linear pseudorandom number
!> generators", ACM Trans. Math. Softw. 47(4), 36, 2021; preprint arXiv:1805.01407, 2018).
!> Period 2^256 - 1, 256 bits of state, passes BigCrush and PractRand.
!>
!> Seeding: splitmix64 (G. L. Steele, D. Lea and C. H. Flood, "Fast splittable pseudorandom
!> number generators", OOPSLA 2014), as recommended by Blackman and Vigna. A stream is the pair
!> (seed, stream id); kumo uses the global batch index as stream id, so the numbers a batch
!> sees do not depend on the rank or thread that runs it.
!>
!> All state is in `rng_t`: there is no module state, so each thread owns its own generator.
!>
!> The algorithms need 64-bit two's-complement wrap-around on multiplication and addition,
!> which standard Fortran leaves undefined for signed integers: this file is compiled with
!> `-fwrapv` (gfortran). Right shifts use the logical `shiftr` (F2008), as in the C originals.
module kumo_rng
  use kumo_kinds, only: wp, i8
  implicit none
  private
  public :: rng_t, rng_init, rng_uniform, rng_next_uniform, rng_next_u64, splitmix64_next
  public :: sample_azimuth

  !> State of one xoshiro256** stream. Initialise it with `rng_init`; the default state
  !> (1, 2, 3, 4) is only the published reference state, never all zero.
  type :: rng_t
    integer(i8) :: s(4) = [1_i8, 2_i8, 3_i8, 4_i8]  !! the four 64-bit state words
  end type rng_t

  ! splitmix64 constants, written as signed decimals because the hexadecimal values exceed
  ! huge(1_i8): 0x9E3779B97F4A7C15 (golden-ratio increment), 0xBF58476D1CE4E5B9 and
  ! 0x94D049BB133111EB (finaliser multipliers, Stafford's "Mix13").
  integer(i8), parameter :: SM_GAMMA = -7046029254386353131_i8
  integer(i8), parameter :: SM_MUL1 = -4658895280553007687_i8
  integer(i8), parameter :: SM_MUL2 = -7723592293110705685_i8

  !> 2^-53: spacing of the doubles in [0.5, 1), used to map 53 random bits to [0, 1).
  real(wp), parameter :: TWO_POW_M53 = 0.5_wp**53

contains

  !> Initialise `rng` for the stream `(seed, stream)`.
  !>
  !> The splitmix64 step H(x) (advance the state x by the golden-ratio increment, then apply
  !> the finaliser) is a bijection of the 64-bit integers. The start state of the splitmix64
  !> sequence is k = H(H(seed) xor stream), so for a fixed seed distinct streams get distinct
  !> start states, and vice versa; the four xoshiro words are the next four splitmix64 outputs
  !> from k. Two streams can share state words only if their start states differ by 1, 2 or 3
  !> splitmix64 increments, which for hashed start states has probability 6/2^64 per pair.
  !> Because the finaliser maps only 0 to 0, at most one of the four words can be zero, so the
  !> state is never all zero. The result depends on (seed, stream) only.
  pure subroutine rng_init(rng, seed, stream)
    type(rng_t), intent(out) :: rng  !! generator to initialise
    integer(i8), intent(in) :: seed    !! global seed (any value)
    integer(i8), intent(in) :: stream  !! stream id: the global batch index (any value)
    integer(i8) :: x, key
    integer :: i

    x = seed
    call splitmix64_next(x, key)
    x = ieor(key, stream)
    call splitmix64_next(x, key)
    x = key
    do i = 1, 4
      call splitmix64_next(x, rng%s(i))
    end do
  end subroutine rng_init

  !> One splitmix64 step: advance `state` and return the next output `x`.
  !> From state 0 the first output is 0xE220A8397B1DCDAF.
  pure subroutine splitmix64_next(state, x)
    integer(i8), intent(inout) :: state  !! splitmix64 state (a counter)
    integer(i8), intent(out) :: x        !! next output, all 64 bits random
    state = state + SM_GAMMA
    x = state
    x = ieor(x, shiftr(x, 30))*SM_MUL1
    x = ieor(x, shiftr(x, 27))*SM_MUL2
    x = ieor(x, shiftr(x, 31))
  end subroutine splitmix64_next

  !> Next 64-bit output of xoshiro256** (all bits random; as a signed integer it may be
  !> negative). From the state (1, 2, 3, 4) the outputs are 11520, 0, 1509978240,
  !> 1215971899390074240, ...
  pure subroutine rng_next_u64(rng, x)
    type(rng_t), intent(inout) :: rng  !! generator, advanced by one step
    integer(i8), intent(out) :: x      !! next output
    integer(i8) :: t

    x = ishftc(rng%s(2)*5_i8, 7)*9_i8
    t = shiftl(rng%s(2), 17)
    rng%s(3) = ieor(rng%s(3), rng%s(1))
    rng%s(4) = ieor(rng%s(4), rng%s(2))
    rng%s(2) = ieor(rng%s(2), rng%s(3))
    rng%s(1) = ieor(rng%s(1), rng%s(4))
    rng%s(3) = ieor(rng%s(3), t)
    rng%s(4) = ishftc(rng%s(4), 45)
  end subroutine rng_next_u64

  !> Uniform deviate in [0, 1) from the top 53 bits of the next output (all multiples of 2^-53
  !> are equally likely; 0 is possible, 1 is not). Use `max(u, tiny)` or `1 - u` before a log.
  function rng_uniform(rng) result(u)
    type(rng_t), intent(inout) :: rng  !! generator, advanced by one step
    real(wp) :: u                      !! deviate in [0, 1)
    integer(i8) :: x
    call rng_next_u64(rng, x)
    u = real(shiftr(x, 11), wp)*TWO_POW_M53
  end function rng_uniform

  !> Subroutine form of `rng_uniform` (same number for the same state) for use in `pure` code,
  !> where a function may not modify its argument.
  pure subroutine rng_next_uniform(rng, u)
    type(rng_t), intent(inout) :: rng  !! generator, advanced by one step
    real(wp), intent(out) :: u         !! deviate in [0, 1)
    integer(i8) :: x
    call rng_next_u64(rng, x)
    u = real(shiftr(x, 11), wp)*TWO_POW_M53
  end subroutine rng_next_uniform

  !> Cosine and sine of an azimuth uniform in [0, 2 pi), by the polar method (seed text App. A6):
  !> a point uniform in the unit disc, accepted with probability pi/4, whose doubled angle is
  !> again uniform. No trigonometric function is evaluated.
  pure subroutine sample_azimuth(rng, c, s)
    type(rng_t), intent(inout) :: rng
    real(wp), intent(out) :: c, s
    real(wp) :: a, b, r2
    do
      call rng_next_uniform(rng, a)
      call rng_next_uniform(rng, b)
      a = 2.0_wp*a - 1.0_wp
      b = 2.0_wp*b - 1.0_wp
      r2 = a*a + b*b
      if (r2 <= 1.0_wp .and. r2 > 1.0e-12_wp) exit
    end do
    c = (a*a - b*b)/r2
    s = 2.0_wp*a*b/r2
  end subroutine sample_azimuth
end module kumo_rng
