! SPDX-License-Identifier: BSD-3-Clause
!> Input files whose data end early must be refused, naming the file and the variable, by
!> every reader: netCDF scene, albedo map, BRDF map, 1-D variables, LES field and Mie-table
!> cache, in the classic (CDF-1, CDF-2, CDF-5) and netCDF-4 formats; and the text readers
!> (SHDOM/I3RC LWC and property files, MYSTIC, two-column tables) for a file cut inside its
!> last line.
!>
!> The netCDF files are written by ncgen from CDL text (an independent writer), then cut with
!> Fortran stream I/O. The complete file must read; the cut one must fail with the file name
!> and, for the classic formats, the name of the first variable whose data are incomplete.
module test_input_integrity_suite
  use, intrinsic :: iso_fortran_env, only: int8, int64
  use kumo_kinds, only: wp
  use kumo_testing, only: error_t, unittest_t, new_unittest, check, check_error_words
  use kumo_test_text, only: write_text
  use kumo_netcdf, only: read_scene_3d, read_albedo_map, read_brdf_map, read_var_1d
  use kumo_les_netcdf, only: les_names_t, les_field_t, read_les_field
  use kumo_mie_table, only: read_mie_table, mie_table_cached
  use kumo_mie, only: mie_table_t, DIST_GAMMA
  use kumo_shdom_files, only: lwc_field_t, prp_field_t, read_lwc_file, read_prp_file
  use kumo_mystic_file, only: mystic_cloud_t, read_mystic_file
  use kumo_textio, only: read_two_columns
  use kumo_file_check, only: file_size_of
  use kumo_brdf, only: BRDF_LAMBERT
  implicit none
  private
  public :: collect_input_integrity

  character(len=1), parameter :: NL = new_line('a')
  !> ncgen -k: 1 classic, 2 64-bit offset, 5 64-bit data (CDF-5), 3 netCDF-4 (HDF5)
  character(len=1), parameter :: KINDS(4) = ['1', '2', '5', '3']
  character(len=8), parameter :: KIND_NAMES(4) = [character(len=8) :: 'CDF-1', 'CDF-2', &
                                                   'CDF-5', 'netCDF-4']

contains

  !> CDL text of a small test file.
  function scene_cdl() result(cdl)
    character(len=:), allocatable :: cdl
    cdl = 'netcdf s {'//NL//'dimensions:'//NL// &
      ' x = 8 ; y = 4 ; z = 2 ; component = 1 ;'//NL//'variables:'//NL// &
      ' double extinction(component, z, y, x) ; extinction:units = "m-1" ;'//NL// &
      ' double ssa(component, z, y, x) ; ssa:units = "1" ;'//NL//'data:'//NL// &
      ' extinction = '//rep(64, '0.01')//' ;'//NL//' ssa = '//rep(64, '0.9')//' ;'//NL//'}'//NL
  end function scene_cdl

  !> CDL text of a small test file.
  function albedo_cdl() result(cdl)
    character(len=:), allocatable :: cdl
    cdl = 'netcdf a {'//NL//'dimensions:'//NL// &
      ' xs = 16 ; ys = 8 ;'//NL//'variables:'//NL//' double albedo(ys, xs) ;'//NL// &
      ' albedo:units = "1" ;'//NL//'data:'//NL//' albedo = '//rep(128, '0.3')//' ;'//NL//'}'//NL
  end function albedo_cdl

  !> CDL text of a small test file.
  function brdf_cdl() result(cdl)
    character(len=:), allocatable :: cdl
    cdl = 'netcdf b {'//NL//'dimensions:'//NL// &
      ' xs = 16 ; ys = 8 ;'//NL//'variables:'//NL//' int brdf_kind(ys, xs) ;'//NL// &
      ' double albedo(ys, xs) ;'//NL//'data:'//NL//' brdf_kind = '//rep(128, '1')//' ;'//NL// &
      ' albedo = '//rep(128, '0.3')//' ;'//NL//'}'//NL
  end function brdf_cdl

  !> CDL text of a small test file.
  function les_cdl() result(cdl)
    character(len=:), allocatable :: cdl
    cdl = 'netcdf l {'//NL//'dimensions:'//NL// &
      ' x = 4 ; y = 4 ; z = 4 ; z_edges = 5 ;'//NL//'variables:'//NL// &
      ' double x(x) ; x:units = "m" ;'//NL//' double y(y) ; y:units = "m" ;'//NL// &
      ' double z_edges(z_edges) ; z_edges:units = "m" ;'//NL// &
      ' float lwc(z, y, x) ; lwc:units = "g m-3" ;'//NL// &
      ' float reff(z, y, x) ; reff:units = "um" ;'//NL//'data:'//NL// &
      ' x = 50, 150, 250, 350 ;'//NL//' y = 50, 150, 250, 350 ;'//NL// &
      ' z_edges = 500, 550, 600, 650, 700 ;'//NL//' lwc = '//rep(64, '0.2')//' ;'//NL//' reff = '//rep(64, '10')//' ;'//NL// &
      '}'//NL
  end function les_cdl

  !> CDL text of a small test file.
  function record_cdl() result(cdl)
    character(len=:), allocatable :: cdl
    cdl = 'netcdf r {'//NL//'dimensions:'//NL// &
      ' time = UNLIMITED ; n = 5 ;'//NL//'variables:'//NL//' double a(time, n) ;'//NL// &
      ' double b(time, n) ;'//NL//'data:'//NL//' a = '//rep(20, '1')//' ;'//NL//' b = '//rep(20, '2')//' ;'//NL//'}'//NL
  end function record_cdl

  !> `n` copies of `v`, comma-separated (CDL has no repeat count).
  function rep(n, v) result(s)
    integer, intent(in) :: n
    character(len=*), intent(in) :: v
    character(len=:), allocatable :: s
    integer :: i
    s = v
    do i = 2, n
      s = s//', '//v
    end do
  end function rep

  function collect_input_integrity() result(tests)
    type(unittest_t), allocatable :: tests(:)
    tests = [new_unittest('netcdf_scene_cut', test_scene), &
             new_unittest('netcdf_albedo_map_cut', test_albedo), &
             new_unittest('netcdf_brdf_map_cut', test_brdf), &
             new_unittest('netcdf_1d_variable_cut', test_var_1d), &
             new_unittest('netcdf_record_variables_cut', test_records), &
             new_unittest('netcdf_les_field_cut', test_les), &
             new_unittest('netcdf_header_cut', test_header), &
             new_unittest('mie_table_cache_cut', test_mie), &
             new_unittest('text_files_cut', test_text)]
  end function collect_input_integrity

  !> Write `cdl` as netCDF of kind KINDS(ik) to `path` with ncgen.
  subroutine make_nc(error, cdl, path, ik)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: cdl, path
    integer, intent(in) :: ik
    integer :: stat, cstat
    call write_text(path//'.cdl', cdl)
    call execute_command_line('ncgen -k '//KINDS(ik)//' -o '//path//' '//path//'.cdl', &
                              exitstat=stat, cmdstat=cstat)
    call check(error, stat == 0 .and. cstat == 0, 'ncgen -k '//KINDS(ik)//' failed on '//path)
  end subroutine make_nc

  !> Copy the first `nbytes` bytes of `src` to `dst` (a partly copied file).
  subroutine cut_copy(src, dst, nbytes)
    character(len=*), intent(in) :: src, dst
    integer(int64), intent(in) :: nbytes
    integer(int8), allocatable :: bytes(:)
    integer :: u
    allocate (bytes(nbytes))
    open (newunit=u, file=src, access='stream', form='unformatted', status='old', action='read')
    read (u) bytes
    close (u)
    open (newunit=u, file=dst, access='stream', form='unformatted', status='replace', &
          action='write')
    write (u) bytes
    close (u)
  end subroutine cut_copy

  !> Bytes to cut: the last 8 of a classic file (inside the last variable's data), 40 % of an
  !> HDF5 file (its data and metadata are spread through it).
  integer(int64) function cut_size(path, ik)
    character(len=*), intent(in) :: path
    integer, intent(in) :: ik
    if (ik <= 3) then
      cut_size = file_size_of(path) - 8
    else
      cut_size = file_size_of(path)*6/10
    end if
  end function cut_size

  !> The message of a cut file: the file, "cut short", and for classic files the variable.
  subroutine check_cut(error, err, path, ik, var)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: path, var
    integer, intent(in) :: ik
    character(len=64) :: words(4)
    words(1) = path
    words(2) = 'cut short'
    if (ik <= 3) then
      words(3) = 'variable '''//var//''''
      words(4) = KIND_NAMES(ik)
    else
      words(3) = 'HDF5 superblock records'
      words(4) = 'bytes, but the file has'
    end if
    call check_error_words(error, err, words)
  end subroutine check_cut

  subroutine no_error(error, err, what)
    type(error_t), allocatable, intent(inout) :: error
    type(error_t), allocatable, intent(in) :: err
    character(len=*), intent(in) :: what
    if (allocated(err)) then
      call check(error, .false., what//': '//err%message)
    end if
  end subroutine no_error

  subroutine test_scene(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp), allocatable :: ext(:, :, :, :), ssa(:, :, :, :)
    integer, allocatable :: pidx(:, :, :, :)
    logical :: has_pi
    integer :: ik
    do ik = 1, size(KINDS)
      call make_nc(error, scene_cdl(), 'integ_scene.nc', ik)
      if (allocated(error)) return
      call read_scene_3d('integ_scene.nc', 8, 4, 2, 1, ext, ssa, pidx, has_pi, err)
      call no_error(error, err, 'complete '//KIND_NAMES(ik)//' scene')
      if (allocated(error)) return
      call check(error, all(abs(ssa - 0.9_wp) < 1.0e-12_wp), 'complete scene read')
      call cut_copy('integ_scene.nc', 'integ_scene_cut.nc', cut_size('integ_scene.nc', ik))
      call read_scene_3d('integ_scene_cut.nc', 8, 4, 2, 1, ext, ssa, pidx, has_pi, err)
      call check_cut(error, err, 'integ_scene_cut.nc', ik, 'ssa')
      if (allocated(error)) return
    end do
  end subroutine test_scene

  subroutine test_albedo(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp), allocatable :: albedo(:, :)
    integer :: ik, nxs, nys
    do ik = 1, size(KINDS)
      call make_nc(error, albedo_cdl(), 'integ_albedo.nc', ik)
      if (allocated(error)) return
      call read_albedo_map('integ_albedo.nc', 'albedo', nxs, nys, albedo, err)
      call no_error(error, err, 'complete '//KIND_NAMES(ik)//' albedo map')
      call cut_copy('integ_albedo.nc', 'integ_albedo_cut.nc', cut_size('integ_albedo.nc', ik))
      call read_albedo_map('integ_albedo_cut.nc', 'albedo', nxs, nys, albedo, err)
      call check_cut(error, err, 'integ_albedo_cut.nc', ik, 'albedo')
      if (allocated(error)) return
    end do
  end subroutine test_albedo

  subroutine test_brdf(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    integer, allocatable :: kind(:, :)
    real(wp), allocatable :: c(:, :, :)
    integer :: ik, nxs, nys
    do ik = 1, size(KINDS)
      call make_nc(error, brdf_cdl(), 'integ_brdf.nc', ik)
      if (allocated(error)) return
      call read_brdf_map('integ_brdf.nc', BRDF_LAMBERT, nxs, nys, kind, c, err)
      call no_error(error, err, 'complete '//KIND_NAMES(ik)//' BRDF map')
      call cut_copy('integ_brdf.nc', 'integ_brdf_cut.nc', cut_size('integ_brdf.nc', ik))
      call read_brdf_map('integ_brdf_cut.nc', BRDF_LAMBERT, nxs, nys, kind, c, err)
      call check_cut(error, err, 'integ_brdf_cut.nc', ik, 'albedo')
      if (allocated(error)) return
    end do
  end subroutine test_brdf

  subroutine test_var_1d(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp), allocatable :: v(:)
    integer :: ik
    do ik = 1, size(KINDS)
      call make_nc(error, les_cdl(), 'integ_var.nc', ik)
      if (allocated(error)) return
      call read_var_1d('integ_var.nc', 'x', v, err)
      call no_error(error, err, 'complete '//KIND_NAMES(ik)//' file')
      ! the file is refused as a whole even though x itself is complete: its last variable
      ! (reff) is not, so the file is a partial copy
      call cut_copy('integ_var.nc', 'integ_var_cut.nc', cut_size('integ_var.nc', ik))
      call read_var_1d('integ_var_cut.nc', 'x', v, err)
      call check_cut(error, err, 'integ_var_cut.nc', ik, 'reff')
      if (allocated(error)) return
    end do
  end subroutine test_var_1d

  !> Record (UNLIMITED) variables are interleaved record by record: cutting the last record
  !> leaves b incomplete; a file with all records is accepted (the padding rule of the classic
  !> format must not flag it).
  subroutine test_records(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp), allocatable :: v(:)
    integer :: ik
    do ik = 1, 3
      call make_nc(error, record_cdl(), 'integ_rec.nc', ik)
      if (allocated(error)) return
      call read_var_1d('integ_rec.nc', 'a', v, err)
      call no_error(error, err, 'complete '//KIND_NAMES(ik)//' record file')
      call cut_copy('integ_rec.nc', 'integ_rec_cut.nc', file_size_of('integ_rec.nc') - 4)
      call read_var_1d('integ_rec_cut.nc', 'a', v, err)
      call check_cut(error, err, 'integ_rec_cut.nc', ik, 'b')
      ! a whole record missing: a is incomplete too, and comes first in the file
      call cut_copy('integ_rec.nc', 'integ_rec_cut.nc', file_size_of('integ_rec.nc') - 80)
      call read_var_1d('integ_rec_cut.nc', 'a', v, err)
      call check_cut(error, err, 'integ_rec_cut.nc', ik, 'a')
      if (allocated(error)) return
    end do
  end subroutine test_records

  subroutine test_les(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(les_names_t) :: names
    type(les_field_t) :: field
    integer :: ik
    do ik = 1, size(KINDS)
      call make_nc(error, les_cdl(), 'integ_les.nc', ik)
      if (allocated(error)) return
      call read_les_field('integ_les.nc', names, -1, field, err)
      call no_error(error, err, 'complete '//KIND_NAMES(ik)//' LES file')
      call cut_copy('integ_les.nc', 'integ_les_cut.nc', cut_size('integ_les.nc', ik))
      call read_les_field('integ_les_cut.nc', names, -1, field, err)
      call check_cut(error, err, 'integ_les_cut.nc', ik, 'reff')
      if (allocated(error)) return
    end do
  end subroutine test_les

  !> A file cut inside its header: the classic header walk and the HDF5 superblock say so.
  subroutine test_header(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    real(wp), allocatable :: v(:)
    integer :: ik
    do ik = 1, size(KINDS)
      call make_nc(error, les_cdl(), 'integ_head.nc', ik)
      if (allocated(error)) return
      call cut_copy('integ_head.nc', 'integ_head_cut.nc', 40_int64)
      call read_var_1d('integ_head_cut.nc', 'x', v, err)
      call check_error_words(error, err, [character(len=32) :: 'integ_head_cut.nc', 'cut short'])
      if (allocated(error)) return
    end do
  end subroutine test_header

  !> The Mie-table cache: a cut file is refused by the reader and recomputed by the cache,
  !> which says why.
  subroutine test_mie(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(mie_table_t) :: table
    character(len=:), allocatable :: action
    call mie_table_cached('integ_mie.nc', 0.86_wp, DIST_GAMMA, 0.1_wp, [8.0_wp], table, &
                          action, err)
    call no_error(error, err, 'Mie table')
    if (allocated(error)) return
    call cut_copy('integ_mie.nc', 'integ_mie_cut.nc', file_size_of('integ_mie.nc')*6/10)
    call read_mie_table('integ_mie_cut.nc', table, err)
    call check_error_words(error, err, [character(len=32) :: 'integ_mie_cut.nc', 'cut short'])
    call mie_table_cached('integ_mie_cut.nc', 0.86_wp, DIST_GAMMA, 0.1_wp, [8.0_wp], table, &
                          action, err)
    call no_error(error, err, 'Mie table recomputed')
    call check(error, index(action, 'computed: existing file unreadable') > 0 .and. &
               index(action, 'cut short') > 0, 'cache action: '//action)
  end subroutine test_mie

  !> Text files cut inside their last line ("0.25" read as "0.2" would go unnoticed).
  subroutine test_text(error)
    type(error_t), allocatable, intent(out) :: error
    type(error_t), allocatable :: err
    type(lwc_field_t) :: lwc
    type(prp_field_t) :: prp
    type(mystic_cloud_t) :: mys
    real(wp), allocatable :: a(:), b(:)
    character(len=*), parameter :: LWC_TEXT = '2 parameter LWC file'//NL//'2 1 1'//NL// &
      '0.1 0.1'//NL//'0.5 0.6'//NL//'280 279'//NL//'1 1 1 0.25 8'//NL//'2 1 1 0.25 8'
    character(len=*), parameter :: PRP_TEXT = 'Tabulated phase function property file'// &
      NL//'2 1 1'//NL//'0.1 0.1 0.5 0.6'//NL//'1'//NL//'1 1.5'//NL// &
      '1 1 1 280 10 0.99 1'//NL//'2 1 1 280 10 0.99 1'
    character(len=*), parameter :: MYS_TEXT = '2 1 1 3'//NL//'0.1 0.1 0.5 0.6'//NL// &
      '1 1 1 0.25 8'//NL//'2 1 1 0.25 8'
    call write_raw('integ.lwc', LWC_TEXT//NL)
    call read_lwc_file('integ.lwc', lwc, err)
    call no_error(error, err, 'complete LWC file')
    call write_raw('integ.lwc', LWC_TEXT(1:len(LWC_TEXT) - 2))
    call read_lwc_file('integ.lwc', lwc, err)
    call check_error_words(error, err, [character(len=32) :: 'integ.lwc', 'no line end'])
    call write_raw('integ.prp', PRP_TEXT//NL)
    call read_prp_file('integ.prp', prp, err)
    call no_error(error, err, 'complete property file')
    call write_raw('integ.prp', PRP_TEXT(1:len(PRP_TEXT) - 1))
    call read_prp_file('integ.prp', prp, err)
    call check_error_words(error, err, [character(len=32) :: 'integ.prp', 'no line end'])
    call write_raw('integ.mys', MYS_TEXT//NL)
    call read_mystic_file('integ.mys', mys, err)
    call no_error(error, err, 'complete MYSTIC file')
    call write_raw('integ.mys', MYS_TEXT(1:len(MYS_TEXT) - 1))
    call read_mystic_file('integ.mys', mys, err)
    call check_error_words(error, err, [character(len=32) :: 'integ.mys', 'no line end'])
    ! absurd header sizes (1e16 points, beyond any address space): an error naming the file
    ! and the sizes, not a crash
    call write_raw('integ.lwc', '2 parameter LWC file'//NL//'100000000 100000000 1'//NL// &
                   '0.1 0.1'//NL//'0.5 0.6'//NL//'280 279'//NL//'1 1 1 0.25 8'//NL)
    call read_lwc_file('integ.lwc', lwc, err)
    call check_error_words(error, err, [character(len=40) :: 'integ.lwc', 'cannot allocate', &
                                        '100000000 x 100000000 x 1'])
    call write_raw('integ.txt', '0 1.0'//NL//'180 0.5'//NL)
    call read_two_columns('integ.txt', a, b, err)
    call no_error(error, err, 'complete table')
    call write_raw('integ.txt', '0 1.0'//NL//'180 0.5')
    call read_two_columns('integ.txt', a, b, err)
    call check_error_words(error, err, [character(len=32) :: 'integ.txt', 'no line end'])
  end subroutine test_text

  !> Write `text` exactly, without adding a line end.
  subroutine write_raw(path, text)
    character(len=*), intent(in) :: path, text
    integer :: u
    open (newunit=u, file=path, access='stream', form='unformatted', status='replace', &
          action='write')
    write (u) text
    close (u)
  end subroutine write_raw
end module test_input_integrity_suite

program test_input_integrity
  use kumo_testing, only: run_unittests
  use test_input_integrity_suite, only: collect_input_integrity
  implicit none
  integer :: n_failed
  call run_unittests('input_integrity', collect_input_integrity(), n_failed)
  if (n_failed > 0) error stop 1
end program test_input_integrity
