! SPDX-License-Identifier: BSD-3-Clause
! A stand-alone kernel that sizes multi-photon interleaving before it is built into kumo's photon
! loop: the null-collision walk of a broken-cloud voxel field (N x N columns of 3840/N m, 20
! layers of 100 m, one majorant per layer, Henyey-Greenstein 0.85, albedo 0.99, SZA 60, black
! surface), with one photon in flight, or two advanced in turn one flight step each, so that
! their independent dependency chains (free path, voxel look-up, collision test, turn) can
! overlap in the processor. Each slot has its own xoshiro256** stream. Not part of kumo.
!
!   gfortran -O3 -funroll-loops -march=x86-64-v2 walk_interleave.f90 -o walk_interleave
!   ./walk_interleave N K NPHOT       (K = 1 or 2)
!
! Prints the wall time per photon, R, T and flight steps per photon. run_interleave.sh times
! both K side by side on three grid sizes (docs/performance.md, multi-photon interleaving).
program walk_interleave
  implicit none
  integer, parameter :: dp = kind(1.0d0), i8 = selected_int_kind(18), sp = kind(1.0)
  integer, parameter :: NZ = 20, KMAX = 2
  real(dp), parameter :: LX = 3840.0_dp, ZTOP = 2000.0_dp, G = 0.85_dp, OMEGA = 0.99_dp
  real(dp), parameter :: TWO53 = 2.0_dp**(-53), PI = 3.141592653589793_dp
  real(sp), allocatable :: ext(:, :, :)
  real(dp) :: smax(NZ), dz, dx, inv_dx
  integer :: n, k, kk
  integer(i8) :: nphot, launched, done, nsteps
  character(len=32) :: arg
  ! photon state per slot
  real(dp) :: x(KMAX), y(KMAX), z(KMAX), ux(KMAX), uy(KMAX), uz(KMAX), w(KMAX), tau(KMAX)
  integer :: iz(KMAX)
  logical :: alive(KMAX)
  integer(i8) :: s(4, KMAX)
  real(dp) :: rsum, tsum
  integer(i8) :: c0, c1, crate

  if (command_argument_count() /= 3) stop 'usage: walk_interleave N K NPHOT'
  call get_command_argument(1, arg)
  read (arg, *) n
  call get_command_argument(2, arg)
  read (arg, *) k
  call get_command_argument(3, arg)
  read (arg, *) nphot
  if (n < 1 .or. k < 1 .or. k > KMAX .or. nphot < 1) &
    stop 'walk_interleave: need N >= 1, K = 1 or 2, NPHOT >= 1'
  call make_field(n)
  dz = ZTOP/NZ
  dx = LX/n
  inv_dx = 1.0_dp/dx
  do kk = 1, k
    s(:, kk) = [int(z'9E3779B97F4A7C15', i8) + kk, 12345_i8*kk + 1, 987654321_i8 + 7*kk, 55_i8 + kk]
    alive(kk) = .false.
  end do
  launched = 0
  done = 0
  nsteps = 0
  rsum = 0
  tsum = 0
  call system_clock(c0, crate)
  do kk = 1, k
    call launch(kk)
  end do
  if (k == 2) then
    do while (done < nphot)
      if (alive(1)) call step(1)
      if (alive(2)) call step(2)
    end do
  else
    do while (done < nphot)
      if (alive(1)) call step(1)
    end do
  end if
  call system_clock(c1)
  write (*, '(a,i5,a,i2,a,f9.2,a,f8.5,a,f8.5,a,f7.2)') 'N ', n, ' K ', k, ' ns/photon ', &
    real(c1 - c0, dp)/crate/real(done, dp)*1.0e9_dp, ' R ', rsum/done, ' T ', tsum/done, &
    ' steps/photon ', real(nsteps, dp)/done

contains

  subroutine make_field(n)
    integer, intent(in) :: n
    integer :: i, j, l
    real(dp) :: xx, yy, f, base, top, zc
    allocate (ext(n, n, NZ))
    do j = 1, n
      do i = 1, n
        xx = (i - 0.5_dp)/n*2*PI
        yy = (j - 0.5_dp)/n*2*PI
        f = sin(3*xx) * cos(2*yy) + 0.6_dp*sin(7*xx + 1.3_dp)*sin(5*yy + 0.4_dp) + &
            0.4_dp*cos(11*xx + 13*yy) + 0.3_dp*sin(17*xx - 19*yy + 2.0_dp)
        base = 400.0_dp
        top = base + max(0.0_dp, f)*800.0_dp
        do l = 1, NZ
          zc = (l - 0.5_dp)*ZTOP/NZ
          if (zc > base .and. zc < top) then
            ext(i, j, l) = real(0.02_dp + 0.03_dp*f*(zc - base)/800.0_dp, sp)
          else
            ext(i, j, l) = 1.0e-5
          end if
        end do
      end do
    end do
    do l = 1, NZ
      smax(l) = maxval(ext(:, :, l))
    end do
  end subroutine make_field

  function uni(kk) result(u)
    integer, intent(in) :: kk
    real(dp) :: u
    integer(i8) :: xo, t
    xo = ishftc(s(2, kk)*5_i8, 7)*9_i8
    t = shiftl(s(2, kk), 17)
    s(3, kk) = ieor(s(3, kk), s(1, kk))
    s(4, kk) = ieor(s(4, kk), s(2, kk))
    s(2, kk) = ieor(s(2, kk), s(3, kk))
    s(1, kk) = ieor(s(1, kk), s(4, kk))
    s(3, kk) = ieor(s(3, kk), t)
    s(4, kk) = ishftc(s(4, kk), 45)
    u = real(shiftr(xo, 11), dp)*TWO53
  end function uni

  subroutine launch(kk)
    integer, intent(in) :: kk
    if (launched >= nphot) then
      alive(kk) = .false.
      return
    end if
    launched = launched + 1
    x(kk) = uni(kk)*LX
    y(kk) = uni(kk)*LX
    z(kk) = ZTOP
    iz(kk) = NZ
    ux(kk) = 0.5_dp
    uy(kk) = 0.0_dp
    uz(kk) = -sqrt(0.75_dp)
    w(kk) = 1.0_dp
    tau(kk) = -log(1.0_dp - uni(kk))
    alive(kk) = .true.
  end subroutine launch

  subroutine finish(kk, up)
    integer, intent(in) :: kk
    logical, intent(in) :: up
    if (up) then
      rsum = rsum + w(kk)
    else
      tsum = tsum + w(kk)
    end if
    done = done + 1
    call launch(kk)
  end subroutine finish

  subroutine step(kk)
    integer, intent(in) :: kk
    real(dp) :: dzf, d, e, mu, phi, st, sp_, cp, vx, vy, vz, s2, t, a
    integer :: ix, iy
    nsteps = nsteps + 1
    if (uz(kk) > 0) then
      dzf = (iz(kk)*dz - z(kk))/uz(kk)
    else
      dzf = (z(kk) - (iz(kk) - 1)*dz)/(-uz(kk))
    end if
    if (smax(iz(kk))*dzf > tau(kk)) then
      d = tau(kk)/smax(iz(kk))
      x(kk) = x(kk) + ux(kk)*d
      y(kk) = y(kk) + uy(kk)*d
      z(kk) = z(kk) + uz(kk)*d
      if (x(kk) < 0 .or. x(kk) >= LX) x(kk) = modulo(x(kk), LX)
      if (y(kk) < 0 .or. y(kk) >= LX) y(kk) = modulo(y(kk), LX)
      ix = min(n, int(x(kk)*inv_dx) + 1)
      iy = min(n, int(y(kk)*inv_dx) + 1)
      e = ext(ix, iy, iz(kk))
      if (uni(kk)*smax(iz(kk)) < e) then
        ! real collision: weight, Henyey-Greenstein turn
        w(kk) = w(kk)*OMEGA
        if (w(kk) < 0.1_dp) then
          if (uni(kk) < 0.5_dp) then
            w(kk) = 2*w(kk)
          else
            done = done + 1
            call launch(kk)
            return
          end if
        end if
        t = (1 - G*G)/(1 - G + 2*G*uni(kk))
        mu = (1 + G*G - t*t)/(2*G)
        phi = 2*PI*uni(kk)
        cp = cos(phi)
        sp_ = sin(phi)
        st = sqrt(max(0.0_dp, 1 - mu*mu))
        s2 = sqrt(max(1.0e-30_dp, ux(kk)**2 + uy(kk)**2))
        a = st/s2
        vx = mu*ux(kk) + a*(cp*ux(kk)*uz(kk) - sp_*uy(kk))
        vy = mu*uy(kk) + a*(cp*uy(kk)*uz(kk) + sp_*ux(kk))
        vz = mu*uz(kk) - st*cp*s2
        vz = sign(max(abs(vz), 1.0e-3_dp), vz)
        a = 1.0_dp/sqrt(vx*vx + vy*vy + vz*vz)
        ux(kk) = vx*a
        uy(kk) = vy*a
        uz(kk) = vz*a
      end if
      tau(kk) = -log(1.0_dp - uni(kk))
    else
      tau(kk) = tau(kk) - smax(iz(kk))*dzf
      x(kk) = x(kk) + ux(kk)*dzf
      y(kk) = y(kk) + uy(kk)*dzf
      if (x(kk) < 0 .or. x(kk) >= LX) x(kk) = modulo(x(kk), LX)
      if (y(kk) < 0 .or. y(kk) >= LX) y(kk) = modulo(y(kk), LX)
      if (uz(kk) > 0) then
        z(kk) = iz(kk)*dz
        iz(kk) = iz(kk) + 1
        if (iz(kk) > NZ) call finish(kk, .true.)
      else
        z(kk) = (iz(kk) - 1)*dz
        iz(kk) = iz(kk) - 1
        if (iz(kk) < 1) call finish(kk, .false.)
      end if
    end if
  end subroutine step

end program walk_interleave
