! SPDX-License-Identifier: BSD-3-Clause
!> Checkpoint files: the accumulated batch sums of an unfinished run, so that a job killed at its
!> wall-time limit can be continued (`kumo --resume`) to the result an uninterrupted run gives.
!>
!> A checkpoint `<output>.ckpt` is written by rank 0 only: to `<output>.ckpt.tmp` (created
!> exclusively after a stale one is removed), renamed over the previous checkpoint after it was
!> closed without error, so a job killed while writing leaves the last complete checkpoint. It
!> holds the configuration's fingerprint, the run's progress (batches done, the start of the
!> current round), the per-batch records, and for every batch slot (the rank that ran the batch
!> in the job that started the case) its sums S1, S2 and counts. The driver (kumo_driver)
!> decides when to write and moves the slots between ranks; this module reads and writes files.
!>
!> The fingerprint is a list of (label, hash) items: the namelist text, the content of every
!> input file the configuration names, and the kumo build (version, compiler and options). A
!> checkpoint whose items differ is refused, naming the first item that differs. The hash is a
!> pair of polynomial hashes of the bytes modulo the primes 2^31 - 1 and 2^31 - 19 (62 bits):
!> it detects changed files, it is not a cryptographic digest.
module kumo_checkpoint
  use, intrinsic :: iso_fortran_env, only: compiler_version, compiler_options, int32, int64
  use, intrinsic :: iso_c_binding, only: c_null_char, c_int
  use kumo_kinds, only: dp, i8
  use kumo_constants, only: KUMO_VERSION
  use kumo_error, only: error_t, set_error, str
  use kumo_netcdf, only: c_rename, c_remove
  implicit none
  private
  public :: fingerprint_t, ckpt_header_t, fingerprint_add_text, fingerprint_add_file, &
            fingerprint_add_build, ckpt_create, ckpt_put_slot, ckpt_commit, ckpt_open, &
            ckpt_get_slot, ckpt_close, ckpt_remove, text_hash, CKPT_SUFFIX

  character(len=*), parameter :: CKPT_SUFFIX = '.ckpt'  !! appended to the output file name
  character(len=*), parameter :: TMP_SUFFIX = '.tmp'
  character(len=8), parameter :: MAGIC = 'KUMOCKPT'
  character(len=8), parameter :: END_MAGIC = 'KUMOEND.'
  integer(int32), parameter :: FORMAT_VERSION = 1
  integer(i8), parameter :: P1 = 2147483647_i8, P2 = 2147483629_i8   !! 2^31 - 1, 2^31 - 19
  integer(i8), parameter :: B1 = 257_i8, B2 = 65599_i8
  integer, parameter :: CHUNK = 1048576                               !! bytes read at a time

  !> What a checkpoint belongs to: labelled hashes.
  type :: fingerprint_t
    character(len=:), allocatable :: labels   !! labels, each ended by a line end
    integer(i8), allocatable :: hash(:)
  end type fingerprint_t

  !> The run's progress at the checkpoint.
  type :: ckpt_header_t
    integer :: n_slots = 0       !! batch slots: batch b belongs to slot mod(b - 1, n_slots)
    integer :: ib_round = 1      !! first batch of the round in progress
    integer :: n_done = 0        !! batches 1..n_done are done
    integer :: n_values = 0      !! length of S1 and S2
    integer :: n_counts = 0      !! counts per slot (batches, photons, work, anomalies)
    real(dp) :: cpu = 0.0_dp     !! CPU time spent so far, over all ranks [s]
  end type ckpt_header_t

contains

  !> Running hash state (h1, h2) of a byte sequence.
  pure subroutine hash_bytes(h, text)
    integer(i8), intent(inout) :: h(2)
    character(len=*), intent(in) :: text
    integer :: i
    integer(i8) :: c
    do i = 1, len(text)
      c = int(iachar(text(i:i)), i8) + 1_i8
      h(1) = mod(h(1)*B1 + c, P1)
      h(2) = mod(h(2)*B2 + c, P2)
    end do
  end subroutine hash_bytes

  pure integer(i8) function finish(h) result(x)
    integer(i8), intent(in) :: h(2)
    x = h(1)*2147483648_i8 + h(2)
  end function finish

  !> Hash of a text.
  pure integer(i8) function text_hash(text) result(x)
    character(len=*), intent(in) :: text
    integer(i8) :: h(2)
    h = [1_i8, 1_i8]
    call hash_bytes(h, text)
    x = finish(h)
  end function text_hash

  subroutine add_item(fp, label, hash)
    type(fingerprint_t), intent(inout) :: fp
    character(len=*), intent(in) :: label
    integer(i8), intent(in) :: hash
    if (.not. allocated(fp%labels)) then
      fp%labels = ''
      allocate (fp%hash(0))
    end if
    fp%labels = fp%labels//label//new_line('a')
    fp%hash = [fp%hash, hash]
  end subroutine add_item

  !> Add a text (such as the namelist) to the fingerprint.
  subroutine fingerprint_add_text(fp, label, text)
    type(fingerprint_t), intent(inout) :: fp
    character(len=*), intent(in) :: label, text
    call add_item(fp, label, text_hash(text))
  end subroutine fingerprint_add_text

  !> Add the content of the file `path` to the fingerprint (a file that cannot be read gets the
  !> hash -1: the run itself will report it).
  subroutine fingerprint_add_file(fp, label, path)
    type(fingerprint_t), intent(inout) :: fp
    character(len=*), intent(in) :: label, path
    integer(i8) :: h(2), size_bytes, pos
    integer :: unit, ios, n
    character(len=:), allocatable :: buf
    open (newunit=unit, file=path, status='old', action='read', access='stream', &
          form='unformatted', iostat=ios)
    if (ios /= 0) then
      call add_item(fp, label, -1_i8)
      return
    end if
    inquire (unit=unit, size=size_bytes)
    h = [1_i8, 1_i8]
    allocate (character(len=CHUNK) :: buf)
    pos = 0
    do while (pos < size_bytes .and. ios == 0)
      n = int(min(int(CHUNK, i8), size_bytes - pos))
      read (unit, iostat=ios) buf(1:n)
      if (ios == 0) call hash_bytes(h, buf(1:n))
      pos = pos + n
    end do
    close (unit)
    if (ios /= 0 .or. size_bytes < 0) then
      call add_item(fp, label, -1_i8)
    else
      call add_item(fp, label, finish(h))
    end if
  end subroutine fingerprint_add_file

  !> Add the kumo build (version, compiler, options) to the fingerprint: another build may round
  !> differently, so its batches would not continue the same sums.
  subroutine fingerprint_add_build(fp)
    type(fingerprint_t), intent(inout) :: fp
    call fingerprint_add_text(fp, 'kumo build (version, compiler, options)', &
                              KUMO_VERSION//' '//compiler_version()//' '//compiler_options())
  end subroutine fingerprint_add_build

  !> Create `<path>.tmp` (after removing a stale one, exclusively) and write the fingerprint,
  !> the header and the per-batch records `rec(3, n_done)`.
  subroutine ckpt_create(path, fp, head, rec, unit, error)
    character(len=*), intent(in) :: path
    type(fingerprint_t), intent(in) :: fp
    type(ckpt_header_t), intent(in) :: head
    real(dp), intent(in) :: rec(:, :)
    integer, intent(out) :: unit
    type(error_t), allocatable, intent(out) :: error
    integer :: ios
    character(len=512) :: msg
    call remove_file(path//TMP_SUFFIX)
    open (newunit=unit, file=path//TMP_SUFFIX, status='new', action='write', access='stream', &
          form='unformatted', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call set_error(error, 'cannot create the checkpoint '//path//TMP_SUFFIX//': '//trim(msg))
      return
    end if
    write (unit, iostat=ios, iomsg=msg) MAGIC, FORMAT_VERSION, int(len(fp%labels), int32), &
      fp%labels, int(size(fp%hash), int32), fp%hash, int(head%n_slots, int32), &
      int(head%ib_round, int32), int(head%n_done, int32), int(head%n_values, int32), &
      int(head%n_counts, int32), head%cpu, rec(:, 1:head%n_done)
    if (ios /= 0) call fail(error, path, msg, unit)
  end subroutine ckpt_create

  !> Append one slot's counts and sums.
  subroutine ckpt_put_slot(unit, path, counts, s1, s2, error)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: counts(:)
    real(dp), intent(in) :: s1(:), s2(:)
    type(error_t), allocatable, intent(inout) :: error
    integer :: ios
    character(len=512) :: msg
    if (allocated(error)) return
    write (unit, iostat=ios, iomsg=msg) counts, s1, s2
    if (ios /= 0) call fail(error, path, msg, unit)
  end subroutine ckpt_put_slot

  !> Write the end mark, close `<path>.tmp` and rename it to `<path>`; on any error (earlier or
  !> here) the temporary file is removed and the previous checkpoint stays.
  subroutine ckpt_commit(unit, path, error)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(inout) :: error
    integer :: ios
    character(len=512) :: msg
    if (allocated(error)) return
    write (unit, iostat=ios, iomsg=msg) END_MAGIC
    if (ios == 0) close (unit, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fail(error, path, msg, unit)
      return
    end if
    if (c_rename(path//TMP_SUFFIX//c_null_char, path//c_null_char) /= 0) then
      call set_error(error, 'cannot rename the checkpoint '//path//TMP_SUFFIX//' to '//path)
      call remove_file(path//TMP_SUFFIX)
    end if
  end subroutine ckpt_commit

  !> Open the checkpoint `path` for reading and check it against the fingerprint `fp` and the
  !> tally length `n_values`; `head` returns its header and `rec(3, n_done)` its records. The
  !> file size must be what the header implies (a cut file is refused). With `n_values` < 0 only
  !> the fingerprint is checked (before the scene is set up) and the file is closed.
  subroutine ckpt_open(path, fp, n_values, n_counts, head, rec, unit, error)
    character(len=*), intent(in) :: path
    type(fingerprint_t), intent(in) :: fp
    integer, intent(in) :: n_values, n_counts
    type(ckpt_header_t), intent(out) :: head
    real(dp), allocatable, intent(out) :: rec(:, :)
    integer, intent(out) :: unit
    type(error_t), allocatable, intent(out) :: error
    character(len=8) :: magic_in
    character(len=:), allocatable :: labels
    integer(i8), allocatable :: hash(:)
    integer(int32) :: version, n_labels, n_hash, h5(5)
    integer(i8) :: size_bytes, expected
    integer :: ios
    character(len=512) :: msg
    character(len=*), parameter :: REDO = '; delete it to start the case anew, or run without --resume'

    open (newunit=unit, file=path, status='old', action='read', access='stream', &
          form='unformatted', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call set_error(error, 'cannot open the checkpoint '//path//': '//trim(msg))
      return
    end if
    inquire (unit=unit, size=size_bytes)
    read (unit, iostat=ios) magic_in
    if (ios /= 0 .or. magic_in /= MAGIC) then
      call refuse('is not a kumo checkpoint')
      return
    end if
    read (unit, iostat=ios) version, n_labels
    if (ios /= 0 .or. version /= FORMAT_VERSION .or. n_labels < 0 .or. n_labels > size_bytes) then
      call refuse('was written by another kumo version (checkpoint format '//str(int(version))// &
                  ', this kumo reads format '//str(int(FORMAT_VERSION))//')')
      return
    end if
    allocate (character(len=n_labels) :: labels)
    read (unit, iostat=ios) labels, n_hash
    if (ios == 0 .and. n_hash >= 0 .and. n_hash < size_bytes/8) then
      allocate (hash(n_hash))
      read (unit, iostat=ios) hash
    end if
    if (ios /= 0 .or. .not. allocated(hash)) then
      call refuse('is damaged (its fingerprint cannot be read)')
      return
    end if
    call compare_fingerprints(labels, hash)
    if (allocated(error)) return
    if (n_values < 0) then
      close (unit)
      return
    end if
    read (unit, iostat=ios) h5, head%cpu
    if (ios /= 0) then
      call refuse('is damaged (its header cannot be read)')
      return
    end if
    head%n_slots = h5(1)
    head%ib_round = h5(2)
    head%n_done = h5(3)
    head%n_values = h5(4)
    head%n_counts = h5(5)
    if (head%n_values /= n_values .or. head%n_counts /= n_counts .or. head%n_slots < 1 .or. &
        head%n_done < 0 .or. head%ib_round < 1 .or. head%ib_round > head%n_done + 1) then
      call refuse('does not match this run''s tallies ('//str(head%n_values)//' values, '// &
                  'this run has '//str(n_values)//')')
      return
    end if
    expected = 8 + 4 + 4 + int(n_labels, i8) + 4 + 8_i8*n_hash + 5*4 + 8 + &
               8_i8*3*head%n_done + int(head%n_slots, i8)*8_i8*(n_counts + 2_i8*n_values) + 8
    if (size_bytes /= expected) then
      call refuse('is cut short or damaged ('//str(size_bytes)//' bytes, its header implies '// &
                  str(expected)//')')
      return
    end if
    allocate (rec(3, head%n_done))
    read (unit, iostat=ios, iomsg=msg) rec
    if (ios /= 0) call refuse('cannot be read: '//trim(msg))
  contains
    subroutine refuse(why)
      character(len=*), intent(in) :: why
      call set_error(error, 'the checkpoint '//path//' '//why//REDO)
      close (unit)
    end subroutine refuse

    !> The first item of the fingerprint that differs names what changed.
    subroutine compare_fingerprints(labels_file, hash_file)
      character(len=*), intent(in) :: labels_file
      integer(i8), intent(in) :: hash_file(:)
      integer :: i, a, b
      character(len=:), allocatable :: item
      if (labels_file /= fp%labels .or. size(hash_file) /= size(fp%hash)) then
        call refuse('was written for another configuration: the input files it names differ')
        return
      end if
      a = 1
      do i = 1, size(hash_file)
        b = a + index(fp%labels(a:), new_line('a')) - 1
        item = fp%labels(a:b - 1)
        if (hash_file(i) /= fp%hash(i)) then
          call refuse('was written for another configuration: '//item//' differs (a '// &
                      'checkpoint continues only the same namelist, inputs and kumo build)')
          return
        end if
        a = b + 1
      end do
    end subroutine compare_fingerprints
  end subroutine ckpt_open

  !> Read the next slot's counts and sums.
  subroutine ckpt_get_slot(unit, path, counts, s1, s2, error)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: path
    integer(i8), intent(out) :: counts(:)
    real(dp), intent(out) :: s1(:), s2(:)
    type(error_t), allocatable, intent(inout) :: error
    integer :: ios
    character(len=512) :: msg
    counts = 0
    s1 = 0.0_dp
    s2 = 0.0_dp
    if (allocated(error)) return
    read (unit, iostat=ios, iomsg=msg) counts, s1, s2
    if (ios /= 0) call set_error(error, 'the checkpoint '//path//' cannot be read: '//trim(msg))
  end subroutine ckpt_get_slot

  !> Check the end mark and close.
  subroutine ckpt_close(unit, path, error)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: path
    type(error_t), allocatable, intent(inout) :: error
    character(len=8) :: mark
    integer :: ios
    if (.not. allocated(error)) then
      read (unit, iostat=ios) mark
      if (ios /= 0 .or. mark /= END_MAGIC) call set_error(error, 'the checkpoint '//path// &
                                                           ' has no end mark (cut short)')
    end if
    close (unit)
  end subroutine ckpt_close

  !> Delete a checkpoint (after the run it belongs to wrote its output).
  subroutine ckpt_remove(path)
    character(len=*), intent(in) :: path
    call remove_file(path)
  end subroutine ckpt_remove

  !> Close and delete the temporary file after a failed write.
  subroutine fail(error, path, msg, unit)
    type(error_t), allocatable, intent(inout) :: error
    character(len=*), intent(in) :: path, msg
    integer, intent(in) :: unit
    integer :: ios
    if (.not. allocated(error)) call set_error(error, 'cannot write the checkpoint '//path// &
                                               TMP_SUFFIX//': '//trim(msg))
    close (unit, status='delete', iostat=ios)
    if (ios /= 0) call remove_file(path//TMP_SUFFIX)
  end subroutine fail

  subroutine remove_file(path)
    character(len=*), intent(in) :: path
    integer(c_int) :: status
    status = c_remove(path//c_null_char)
  end subroutine remove_file

end module kumo_checkpoint
