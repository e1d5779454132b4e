! SPDX-License-Identifier: BSD-3-Clause
!> Checkpoint files: the accumulated batch sums of an unfinished run, so that a job killed at its
!> wall-time limit can be continued (`kumo --resume`) to the result an uninterrupted run gives.
!>
!> A checkpoint is a small manifest `<output>.ckpt` and part files `<output>.ckpt.<g>.<r>`:
!> generation g (the g-th checkpoint written for this output) and the rank r that wrote it. A
!> batch slot (the rank that ran the batch in the job that started the case) has its sums S1,
!> S2 and counts in the part of the rank that holds it, so every rank writes its own slots, all
!> ranks at once, and nothing but the per-batch records goes through rank 0. The manifest holds
!> the configuration's fingerprint, the run's progress (batches done, the start of the current
!> round), the per-batch records, the generation, a stamp drawn for it (also in every part's
!> header), and the part and offset of every slot.
!>
!> A write is all or nothing: rank 0 first leaves a marker `<output>.ckpt.pending` (the
!> generation being written and the one it replaces); every rank writes `<part>.tmp` (created
!> exclusively after a stale one is removed); when all ranks report success (a reduction), each
!> renames its own; rank 0 then writes the manifest the same way (`<output>.ckpt.tmp`, renamed),
!> and only then removes the previous generation's parts and the marker. A job killed at any
!> moment leaves the previous manifest with its parts; the next write or resume finds the marker
!> and removes what the unfinished write left. On resume rank 0 reads the manifest and shares
!> it, and every rank reads its slots from whichever parts hold them (a run may resume on any
!> rank count), after checking each part's size, header, stamp and end mark.
!>
!> The fingerprint is a list of (label, hash) items: the namelist text, the content of every
!> input file the configuration names, and the kumo build (version, compiler and options). A
!> checkpoint whose items differ is refused, naming the first item that differs. The hash is a
!> pair of polynomial hashes of the bytes modulo the primes 2^31 - 1 and 2^31 - 19 (62 bits):
!> it detects changed files, it is not a cryptographic digest.
module kumo_checkpoint
  use, intrinsic :: iso_fortran_env, only: compiler_version, compiler_options, int32, int64, &
                                          output_unit, error_unit
  use, intrinsic :: iso_c_binding, only: c_null_char, c_int
  use kumo_kinds, only: dp, i8
  use kumo_constants, only: KUMO_VERSION
  use kumo_error, only: error_t, set_error, str
  use kumo_netcdf, only: c_rename, c_remove
  use kumo_tally, only: tally_layout_t, stats_t, stats_init, N_ANOMALIES
  use kumo_config, only: config_t, input_file_t, config_inputs
  use kumo_parallel, only: par_rank, par_size, par_is_root, par_sum_to_root, par_wtime, &
                           par_bcast_int, par_move, par_allreduce_sum
  use kumo_run_util, only: share_error, env_int, kill_self
  implicit none
  private
  public :: fingerprint_t, ckpt_header_t, fingerprint_add_text, fingerprint_add_file, &
            fingerprint_add_build, ckpt_remove, text_hash, CKPT_SUFFIX
  public :: checkpoint_plan_t, checkpoint_due, write_checkpoint, resume_run, &
            early_checkpoint_check, checkpoint_fingerprint

  character(len=*), parameter :: CKPT_SUFFIX = '.ckpt'  !! appended to the output file name
  character(len=*), parameter :: TMP_SUFFIX = '.tmp'
  character(len=*), parameter :: PENDING_SUFFIX = '.pending'   !! marks a write in progress
  character(len=8), parameter :: MAGIC = 'KUMOCKPT'             !! the manifest
  character(len=8), parameter :: PART_MAGIC = 'KUMOPART'        !! a part file
  character(len=8), parameter :: PENDING_MAGIC = 'KUMOPEND'     !! the marker
  character(len=8), parameter :: END_MAGIC = 'KUMOEND.'
  integer(int32), parameter :: FORMAT_VERSION = 2   !! 1: one file written by rank 0
  !> A part's header: magic, format, part index, generation, stamp, values, counts, slots.
  integer(i8), parameter :: PART_HEAD_BYTES = 8 + 4 + 4 + 8 + 8 + 4 + 4 + 4
  integer, parameter :: MSG_LEN = 2048   !! longest error message passed between ranks
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
    integer(i8) :: generation = 0 !! checkpoints written for this output so far, this one included
    integer(i8) :: stamp = 0     !! drawn once per generation; in the manifest and every part
    integer :: n_parts = 0       !! parts <output>.ckpt.<generation>.<r>, r = 0..n_parts - 1
  end type ckpt_header_t

  !> Where the slots of a checkpoint are.
  type :: ckpt_layout_t
    integer, allocatable :: part(:)            !! (0:n_slots - 1) the part that holds slot s
    integer(i8), allocatable :: offset(:)      !! (0:n_slots - 1) its byte offset in that part
    integer(i8), allocatable :: part_bytes(:)  !! (0:n_parts - 1) size of each part; 0: no file
  end type ckpt_layout_t

  !> Checkpoints of a run (run_case sets it up from the configuration and the command line).
  type :: checkpoint_plan_t
    character(len=:), allocatable :: path   !! the manifest, <output>.ckpt
    real(dp) :: interval = 0.0_dp           !! [s] between checkpoints; 0: none
    logical :: resume = .false.             !! continue from `path` if it exists
    type(fingerprint_t) :: fp               !! what the checkpoint belongs to (rank 0)
  end type checkpoint_plan_t

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
  !> Name of part `r` of generation `g`: `<path>.<g>.<r>`.
  function part_name(path, g, r) result(name)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: g
    integer, intent(in) :: r
    character(len=:), allocatable :: name
    name = path//'.'//str(g)//'.'//str(r)
  end function part_name

  !> Where every slot goes when `n_parts` ranks write: slot s to part mod(s, n_parts) (the rank
  !> that holds it), after the part header and the slots of that part before it.
  subroutine plan_layout(n_slots, n_parts, n_values, n_counts, lt)
    integer, intent(in) :: n_slots, n_parts, n_values, n_counts
    type(ckpt_layout_t), intent(out) :: lt
    integer :: s, r
    allocate (lt%part(0:n_slots - 1), lt%offset(0:n_slots - 1), lt%part_bytes(0:n_parts - 1))
    lt%part_bytes = 0
    do s = 0, n_slots - 1
      r = mod(s, n_parts)
      if (lt%part_bytes(r) == 0) lt%part_bytes(r) = PART_HEAD_BYTES
      lt%part(s) = r
      lt%offset(s) = lt%part_bytes(r)
      lt%part_bytes(r) = lt%part_bytes(r) + slot_bytes(n_values, n_counts)
    end do
    where (lt%part_bytes > 0) lt%part_bytes = lt%part_bytes + len(END_MAGIC)
  end subroutine plan_layout

  !> Bytes of one slot in a part: its counts, S1 and S2.
  pure integer(i8) function slot_bytes(n_values, n_counts) result(n)
    integer, intent(in) :: n_values, n_counts
    n = 8_i8*(n_counts + 2_i8*n_values)
  end function slot_bytes

  !> A value that tells this generation's files from those of any other write (time of day,
  !> clock count and generation, hashed).
  integer(i8) function draw_stamp(g) result(stamp)
    integer(i8), intent(in) :: g
    integer :: v(8)
    integer(i8) :: count
    character(len=160) :: text
    call date_and_time(values=v)
    call system_clock(count)
    write (text, '(8i6,2i21)') v, count, g
    stamp = text_hash(text)
  end function draw_stamp

  !> Write the manifest `path` (rank 0): `<path>.tmp` created exclusively after a stale one is
  !> removed, renamed to `path` once closed without error. On error the temporary file is removed
  !> and the previous manifest stays.
  subroutine manifest_write(path, fp, head, rec, lt, error)
    character(len=*), intent(in) :: path
    type(fingerprint_t), intent(in) :: fp
    type(ckpt_header_t), intent(in) :: head
    real(dp), intent(in) :: rec(:, :)
    type(ckpt_layout_t), intent(in) :: lt
    type(error_t), allocatable, intent(out) :: error
    integer :: unit, ios
    character(len=512) :: msg
    call open_tmp(path, 'the checkpoint', unit, error)
    if (allocated(error)) return
    write (unit, iostat=ios, iomsg=msg) MAGIC, FORMAT_VERSION, head%generation, head%stamp, &
      int(head%n_parts, int32), int(len(fp%labels), int32), fp%labels, int(size(fp%hash), int32), &
      fp%hash, int(head%n_slots, int32), int(head%ib_round, int32), int(head%n_done, int32), &
      int(head%n_values, int32), int(head%n_counts, int32), head%cpu, rec(:, 1:head%n_done), &
      lt%part_bytes, int(lt%part, int32), lt%offset, END_MAGIC
    if (ios == 0) close (unit, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fail(error, path, msg, unit)
      return
    end if
    if (c_rename(path//TMP_SUFFIX//c_null_char, path//c_null_char) /= 0) then
      call set_error(error, 'cannot rename the checkpoint '//path//TMP_SUFFIX//' to '//path)
      call remove_file(path//TMP_SUFFIX)
    end if
  end subroutine manifest_write

  !> The generation, stamp and part count of the manifest `path`; .false. when there is none
  !> of this format.
  logical function manifest_peek(path, g, stamp, n_parts) result(ok)
    character(len=*), intent(in) :: path
    integer(i8), intent(out) :: g, stamp
    integer, intent(out) :: n_parts
    character(len=8) :: magic_in
    integer(int32) :: version, n
    integer :: unit, ios
    g = 0
    stamp = 0
    n_parts = 0
    ok = .false.
    open (newunit=unit, file=path, status='old', action='read', access='stream', &
          form='unformatted', iostat=ios)
    if (ios /= 0) return
    read (unit, iostat=ios) magic_in, version, g, stamp, n
    close (unit)
    ok = ios == 0 .and. magic_in == MAGIC .and. version == FORMAT_VERSION .and. g >= 1 .and. n >= 1
    if (ok) then
      n_parts = n
    else
      g = 0
    end if
  end function manifest_peek

  !> Open the manifest `path`, check it against the fingerprint `fp` and the tally length
  !> `n_values`; `head` returns its header, `rec(3, n_done)` its records and `lt` where the
  !> slots are. The file size must be what the header implies (a cut file is refused). With
  !> `n_values` < 0 only the fingerprint is checked (before the scene is set up).
  subroutine manifest_open(path, fp, n_values, n_counts, head, rec, lt, error)
    character(len=*), intent(in) :: path
    type(fingerprint_t), intent(in) :: fp
    integer, intent(in) :: n_values, n_counts
    type(ckpt_header_t), intent(out) :: head
    real(dp), allocatable, intent(out) :: rec(:, :)
    type(ckpt_layout_t), intent(out) :: lt
    type(error_t), allocatable, intent(out) :: error
    character(len=8) :: magic_in, mark
    character(len=:), allocatable :: labels
    integer(i8), allocatable :: hash(:)
    integer(int32), allocatable :: part(:)
    integer(int32) :: version, n_labels, n_hash, n_parts, h5(5)
    integer(i8) :: size_bytes, expected, sb
    integer :: ios, unit, s
    character(len=512) :: msg

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
    read (unit, iostat=ios) version
    if (ios /= 0 .or. version /= FORMAT_VERSION) then
      call refuse('was written by another kumo version (checkpoint format '//str(int(version))// &
                  ', this kumo reads format '//str(int(FORMAT_VERSION))//')')
      return
    end if
    read (unit, iostat=ios) head%generation, head%stamp, n_parts, n_labels
    if (ios /= 0 .or. head%generation < 1 .or. n_parts < 1 .or. n_parts > size_bytes/8 .or. &
        n_labels < 0 .or. n_labels > size_bytes) then
      call refuse('is damaged (its header cannot be read)')
      return
    end if
    head%n_parts = n_parts
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
    expected = 8 + 4 + 8 + 8 + 4 + 4 + int(n_labels, i8) + 4 + 8_i8*n_hash + 5*4 + 8 + &
               8_i8*3*head%n_done + 8_i8*n_parts + 12_i8*head%n_slots + 8
    if (size_bytes /= expected) then
      call refuse('is cut short or damaged ('//str(size_bytes)//' bytes, its header implies '// &
                  str(expected)//')')
      return
    end if
    allocate (rec(3, head%n_done), lt%part_bytes(0:n_parts - 1), part(0:head%n_slots - 1), &
              lt%offset(0:head%n_slots - 1))
    read (unit, iostat=ios, iomsg=msg) rec, lt%part_bytes, part, lt%offset, mark
    if (ios /= 0) then
      call refuse('cannot be read: '//trim(msg))
      return
    end if
    lt%part = part
    sb = slot_bytes(n_values, n_counts)
    do s = 0, head%n_slots - 1
      if (lt%part(s) < 0 .or. lt%part(s) >= n_parts) exit
      if (lt%offset(s) < PART_HEAD_BYTES .or. &
          lt%offset(s) + sb + len(END_MAGIC) > lt%part_bytes(lt%part(s))) exit
    end do
    if (mark /= END_MAGIC .or. s < head%n_slots) then
      call refuse('is damaged (its table of part files is inconsistent)')
      return
    end if
    close (unit)
  contains
    subroutine refuse(why)
      character(len=*), intent(in) :: why
      call set_error(error, 'the checkpoint '//path//' '//why//'; delete it to start the case '// &
                     'anew, or run without --resume')
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
  end subroutine manifest_open

  !> Write this rank's part `<path>.<g>.<rank>.tmp` (created exclusively after a stale one is
  !> removed): the header, then the slots this rank holds (s = rank, rank + nranks, ...).
  subroutine part_write(path, g, stamp, rank, nranks, lay, n_counts, slot, error)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: g, stamp
    integer, intent(in) :: rank, nranks, n_counts
    type(tally_layout_t), intent(in) :: lay
    type(stats_t), intent(in) :: slot(0:)
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: name
    character(len=512) :: msg
    integer :: unit, ios, s
    name = part_name(path, g, rank)
    call open_tmp(name, 'the checkpoint part', unit, error)
    if (allocated(error)) return
    write (unit, iostat=ios, iomsg=msg) PART_MAGIC, FORMAT_VERSION, int(rank, int32), g, stamp, &
      int(lay%n, int32), int(n_counts, int32), int(size(slot) - rank + nranks - 1, int32)/nranks
    do s = rank, ubound(slot, 1), nranks
      if (ios /= 0) exit
      write (unit, iostat=ios, iomsg=msg) slot(s)%n_batches, slot(s)%n_photons, slot(s)%work, &
        slot(s)%anomalies, slot(s)%s1, slot(s)%s2
    end do
    if (ios == 0) write (unit, iostat=ios, iomsg=msg) END_MAGIC
    if (ios == 0) close (unit, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call set_error(error, 'cannot write the checkpoint part '//name//TMP_SUFFIX//': '//trim(msg))
      call fail(error, name, msg, unit)
    end if
  end subroutine part_write

  !> Open part `p` of the checkpoint `path` (generation `head%generation`) and check that it is
  !> whole and belongs to it: its size, its header, its end mark.
  subroutine part_open(path, head, lt, p, unit, error)
    character(len=*), intent(in) :: path
    type(ckpt_header_t), intent(in) :: head
    type(ckpt_layout_t), intent(in) :: lt
    integer, intent(in) :: p
    integer, intent(out) :: unit
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: name
    character(len=8) :: magic_in, mark
    character(len=512) :: msg
    integer(int32) :: version, p_in, n_values, n_counts, n_in
    integer(i8) :: g_in, stamp_in, size_bytes
    integer :: ios
    logical :: exists
    name = part_name(path, head%generation, p)
    unit = -1
    inquire (file=name, exist=exists)
    if (.not. exists) then
      call refuse('is missing')
      return
    end if
    open (newunit=unit, file=name, status='old', action='read', access='stream', &
          form='unformatted', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call refuse('cannot be opened: '//trim(msg))
      return
    end if
    inquire (unit=unit, size=size_bytes)
    if (size_bytes /= lt%part_bytes(p)) then
      call refuse('is cut short or damaged ('//str(size_bytes)//' bytes, the checkpoint implies '// &
                  str(lt%part_bytes(p))//')')
      return
    end if
    read (unit, iostat=ios) magic_in, version, p_in, g_in, stamp_in, n_values, n_counts, n_in
    if (ios /= 0 .or. magic_in /= PART_MAGIC .or. version /= FORMAT_VERSION) then
      call refuse('is not a part of a kumo checkpoint of format '//str(int(FORMAT_VERSION)))
      return
    end if
    if (p_in /= p .or. g_in /= head%generation .or. stamp_in /= head%stamp) then
      call refuse('belongs to another checkpoint (it is part '//str(int(p_in))//' of generation '// &
                  str(g_in)//' with stamp '//str(stamp_in)//'; the manifest is generation '// &
                  str(head%generation)//' with stamp '//str(head%stamp)//')')
      return
    end if
    read (unit, pos=size_bytes - len(END_MAGIC) + 1, iostat=ios) mark
    if (n_values /= head%n_values .or. n_counts /= head%n_counts .or. ios /= 0 .or. &
        mark /= END_MAGIC) then
      call refuse('is damaged (its header or end mark does not match the checkpoint)')
      return
    end if
  contains
    subroutine refuse(why)
      character(len=*), intent(in) :: why
      integer :: ios2
      call set_error(error, 'the checkpoint '//path//' cannot be resumed: its part '//name//' '// &
                     why//'; delete '//path//' and its parts '//path//'.* to start the case anew, '// &
                     'or run without --resume')
      if (unit /= -1) close (unit, iostat=ios2)
      unit = -1
    end subroutine refuse
  end subroutine part_open

  !> Remove the part files of generation `g` (`n_parts` of them) and their temporary files.
  subroutine remove_generation(path, g, n_parts)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: g
    integer, intent(in) :: n_parts
    integer :: r
    if (g < 1) return
    do r = 0, n_parts - 1
      call remove_file(part_name(path, g, r))
      call remove_file(part_name(path, g, r)//TMP_SUFFIX)
    end do
  end subroutine remove_generation

  !> Mark a write of generation `g_new` by `n_new` ranks in progress (`<path>.pending`, tmp and
  !> rename), naming also the generation it replaces.
  subroutine pending_write(path, g_new, n_new, g_old, n_old, error)
    character(len=*), intent(in) :: path
    integer(i8), intent(in) :: g_new, g_old
    integer, intent(in) :: n_new, n_old
    type(error_t), allocatable, intent(out) :: error
    character(len=:), allocatable :: name
    character(len=512) :: msg
    integer :: unit, ios
    name = path//PENDING_SUFFIX
    call remove_file(name//TMP_SUFFIX)
    open (newunit=unit, file=name//TMP_SUFFIX, status='new', action='write', access='stream', &
          form='unformatted', iostat=ios, iomsg=msg)
    if (ios == 0) then
      write (unit, iostat=ios, iomsg=msg) PENDING_MAGIC, g_new, int(n_new, int32), g_old, &
        int(n_old, int32)
      if (ios == 0) close (unit, iostat=ios, iomsg=msg)
      if (ios /= 0) close (unit, status='delete', iostat=ios)
    end if
    if (ios /= 0) then
      call set_error(error, 'cannot write '//name//TMP_SUFFIX//': '//trim(msg))
      call remove_file(name//TMP_SUFFIX)
    else if (c_rename(name//TMP_SUFFIX//c_null_char, name//c_null_char) /= 0) then
      call set_error(error, 'cannot rename '//name//TMP_SUFFIX//' to '//name)
      call remove_file(name//TMP_SUFFIX)
    end if
  end subroutine pending_write

  !> Finish what a write that was cut short left (rank 0): if its manifest is in place, the
  !> generation it replaced is removed, else its own parts are; then the marker.
  subroutine pending_clean(path)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: name
    character(len=8) :: magic_in
    integer(i8) :: g_new, g_old, g, stamp
    integer(int32) :: n_new, n_old
    integer :: unit, ios, n
    logical :: exists
    name = path//PENDING_SUFFIX
    call remove_file(name//TMP_SUFFIX)
    inquire (file=name, exist=exists)
    if (.not. exists) return
    open (newunit=unit, file=name, status='old', action='read', access='stream', &
          form='unformatted', iostat=ios)
    if (ios == 0) then
      read (unit, iostat=ios) magic_in, g_new, n_new, g_old, n_old
      close (unit)
      if (ios == 0 .and. magic_in == PENDING_MAGIC) then
        if (manifest_peek(path, g, stamp, n) .and. g == g_new) then
          call remove_generation(path, g_old, n_old)
        else
          call remove_generation(path, g_new, n_new)
        end if
      end if
    end if
    call remove_file(name)
  end subroutine pending_clean

  !> Delete a checkpoint, its parts and what an unfinished write left (rank 0, after the run it
  !> belongs to wrote its output).
  subroutine ckpt_remove(path)
    character(len=*), intent(in) :: path
    integer(i8) :: g, stamp
    integer :: n
    call pending_clean(path)
    if (manifest_peek(path, g, stamp, n)) call remove_generation(path, g, n)
    call remove_file(path)
    call remove_file(path//TMP_SUFFIX)
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

  !> Rank 0 decides whether a checkpoint is due (`interval` seconds after the last one); every
  !> rank gets the decision.
  logical function checkpoint_due(plan, t_last) result(due)
    type(checkpoint_plan_t), intent(in) :: plan
    real(dp), intent(in) :: t_last
    integer :: flag(1)
    flag = 0
    if (par_is_root()) then
      if (par_wtime() - t_last >= plan%interval) flag = 1
    end if
    call par_bcast_int(flag)
    due = flag(1) == 1
  end function checkpoint_due

  !> Write the checkpoint after batch `n_done` (every batch up to it is done on every rank),
  !> in the round that began with batch `ib_round`. Collective: every rank writes the slots it
  !> holds to its own part file, all at once; only the per-batch records travel to rank 0, which
  !> writes the manifest when every part is in place. A checkpoint that cannot be written is a
  !> warning: the run goes on (the previous checkpoint, if any, stays).
  subroutine write_checkpoint(plan, cfg, lay, slot, n_slots, ib_round, n_done, rec, cpu_rank)
    type(checkpoint_plan_t), intent(in) :: plan
    type(config_t), intent(in) :: cfg
    type(tally_layout_t), intent(in) :: lay
    integer, intent(in) :: n_slots, ib_round, n_done
    type(stats_t), intent(in) :: slot(0:n_slots - 1)
    real(dp), intent(in) :: rec(:, :)
    real(dp), intent(in) :: cpu_rank   !! this rank's CPU time so far (rank 0: and before)
    integer, save :: n_started = 0     !! checkpoints this process began (for the test hook)
    type(error_t), allocatable :: err
    type(ckpt_header_t) :: head
    type(ckpt_layout_t) :: lt
    real(dp), allocatable :: flat(:)
    real(dp) :: t0, failed(1)
    integer(i8) :: g_old, stamp_old
    integer :: rank, nranks, n_old, info(5), n_counts
    character(len=:), allocatable :: name
    character(len=24) :: seconds
    t0 = par_wtime()
    n_started = n_started + 1
    rank = par_rank()
    nranks = par_size()
    n_counts = 4 + N_ANOMALIES
    flat = [reshape(rec(:, 1:n_done), [3*n_done]), cpu_rank]
    call par_sum_to_root(flat)   ! each record is non-zero on one rank only: the sum is exact
    ! rank 0 finishes what an earlier write left, picks the generation and marks it pending
    info = 0
    if (rank == 0) then
      call pending_clean(plan%path)
      if (.not. manifest_peek(plan%path, g_old, stamp_old, n_old)) n_old = 0
      head%generation = g_old + 1
      head%stamp = draw_stamp(head%generation)
      call pending_write(plan%path, head%generation, nranks, g_old, n_old, err)
      if (.not. allocated(err)) info = [1, transfer([head%generation, head%stamp], info(1:4))]
    end if
    call par_bcast_int(info)
    if (info(1) == 0) then
      if (rank == 0) call warn(err%message)
      return
    end if
    head%generation = transfer(info(2:3), head%generation)
    head%stamp = transfer(info(4:5), head%stamp)
    ! every rank that holds slots writes its part; all agree before any part takes its name
    name = part_name(plan%path, head%generation, rank)
    if (rank < n_slots) call part_write(plan%path, head%generation, head%stamp, rank, nranks, lay, &
                                        n_counts, slot, err)
    failed = merge(1.0_dp, 0.0_dp, allocated(err))
    call par_allreduce_sum(failed)
    if (failed(1) < 0.5_dp .and. rank < n_slots) then
      if (c_rename(name//TMP_SUFFIX//c_null_char, name//c_null_char) /= 0) &
        call set_error(err, 'cannot rename the checkpoint part '//name//TMP_SUFFIX//' to '//name)
    end if
    if (failed(1) < 0.5_dp) then
      failed = merge(1.0_dp, 0.0_dp, allocated(err))
      call par_allreduce_sum(failed)
    end if
    if (failed(1) > 0.5_dp) then
      call remove_file(name//TMP_SUFFIX)
      call remove_file(name)
      if (allocated(err)) write (error_unit, '(a)') 'kumo: warning: rank '//str(rank)//': '// &
        err%message
      if (rank == 0) then
        call remove_file(plan%path//PENDING_SUFFIX)
        call warn(str(nint(failed(1)))//' rank(s) could not write their part of the checkpoint')
      end if
      return
    end if
    if (rank /= 0) return
    ! test hook (tests/mpi/checkpoint_parts.sh): a job killed with every part in place but no
    ! manifest yet
    if (env_int('KUMO_TEST_KILL_BEFORE_MANIFEST') == n_started) call kill_self()
    head%n_slots = n_slots
    head%ib_round = ib_round
    head%n_done = n_done
    head%n_values = lay%n
    head%n_counts = n_counts
    head%cpu = flat(size(flat))
    head%n_parts = nranks
    call plan_layout(n_slots, nranks, lay%n, n_counts, lt)
    call manifest_write(plan%path, plan%fp, head, reshape(flat(1:3*n_done), [3, n_done]), lt, err)
    if (allocated(err)) then
      call remove_generation(plan%path, head%generation, nranks)
      call remove_file(plan%path//PENDING_SUFFIX)
      call warn(err%message)
      return
    end if
    call remove_generation(plan%path, g_old, n_old)
    call remove_file(plan%path//PENDING_SUFFIX)
    write (seconds, '(f12.3)') par_wtime() - t0
    if (cfg%control%verbose >= 1) write (error_unit, '(a)') 'kumo: checkpoint after batch '// &
      str(n_done)//': '//plan%path//' (generation '//str(head%generation)//', '// &
      str(count(lt%part_bytes > 0))//' part file(s), '//str(sum(lt%part_bytes))//' bytes, '// &
      trim(adjustl(seconds))//' s)'
    flush (error_unit)
  contains
    subroutine warn(why)
      character(len=*), intent(in) :: why
      write (error_unit, '(a)') 'kumo: warning: no checkpoint after batch '//str(n_done)// &
        ' (the run goes on): '//why
      flush (error_unit)
    end subroutine warn
  end subroutine write_checkpoint

  !> Continue from the checkpoint `plan%path` if it exists (else start from the first batch):
  !> rank 0 reads the manifest, checks it against the configuration's fingerprint and shares
  !> it; every rank reads the slots it runs from the parts that hold them (a missing, cut or
  !> foreign part is refused on every rank, naming the file). Returns the slot count, the first
  !> batch of the round in progress, the batches done, their records, the CPU time before
  !> (rank 0) and the slots' sums.
  subroutine resume_run(plan, cfg, lay, n_slots, ib_next, n_done, rec, cpu_before, slot, error)
    type(checkpoint_plan_t), intent(in) :: plan
    type(config_t), intent(in) :: cfg
    type(tally_layout_t), intent(in) :: lay
    integer, intent(out) :: n_slots, ib_next, n_done
    real(dp), allocatable, intent(inout) :: rec(:, :)
    real(dp), intent(out) :: cpu_before
    type(stats_t), allocatable, intent(out) :: slot(:)
    type(error_t), allocatable, intent(out) :: error
    type(ckpt_header_t) :: head
    type(ckpt_layout_t) :: lt
    integer(i8) :: cnt(4 + N_ANOMALIES)
    integer, allocatable :: buf(:)
    integer :: info(11), s, rank, nranks, unit, p_open, ios
    character(len=512) :: msg
    logical :: exists
    rank = par_rank()
    nranks = par_size()
    cpu_before = 0.0_dp
    info = 0
    if (rank == 0) then
      inquire (file=plan%path, exist=exists)
      if (exists) then
        call pending_clean(plan%path)
        call manifest_open(plan%path, plan%fp, lay%n, size(cnt), head, rec, lt, error)
        info = [1, head%n_slots, head%ib_round, head%n_done, head%n_parts, head%n_values, &
                head%n_counts, transfer([head%generation, head%stamp], info(1:4))]
      end if
    end if
    call share_error(error)
    if (allocated(error)) return
    call par_bcast_int(info)
    n_slots = par_size()
    ib_next = 1
    n_done = 0
    if (info(1) == 0) then
      if (rank == 0 .and. cfg%control%verbose >= 1) write (output_unit, '(a)') &
        'no checkpoint '//plan%path//': the run starts from the first batch'
      return
    end if
    n_slots = info(2)
    ib_next = info(3)
    n_done = info(4)
    if (rank == 0) cpu_before = head%cpu
    head%n_slots = info(2)
    head%n_parts = info(5)
    head%n_values = info(6)
    head%n_counts = info(7)
    head%generation = transfer(info(8:9), head%generation)
    head%stamp = transfer(info(10:11), head%stamp)
    ! the table of parts: part sizes and slot offsets as pairs of default integers
    if (rank == 0) then
      buf = [lt%part, transfer(lt%offset, info(1:1), 2*n_slots), &
             transfer(lt%part_bytes, info(1:1), 2*head%n_parts)]
    else
      allocate (buf(3*n_slots + 2*head%n_parts))
      allocate (lt%part(0:n_slots - 1), lt%offset(0:n_slots - 1), &
                lt%part_bytes(0:head%n_parts - 1))
    end if
    call par_bcast_int(buf)
    lt%part = buf(1:n_slots)
    lt%offset = transfer(buf(n_slots + 1:3*n_slots), lt%offset, n_slots)
    lt%part_bytes = transfer(buf(3*n_slots + 1:), lt%part_bytes, head%n_parts)
    allocate (slot(0:n_slots - 1))
    p_open = -1
    unit = -1
    do s = rank, n_slots - 1, nranks
      if (lt%part(s) /= p_open) then
        if (unit /= -1) close (unit)
        p_open = lt%part(s)
        call part_open(plan%path, head, lt, p_open, unit, error)
        if (allocated(error)) exit
      end if
      call stats_init(slot(s), lay)
      read (unit, pos=lt%offset(s) + 1, iostat=ios, iomsg=msg) cnt, slot(s)%s1, slot(s)%s2
      if (ios /= 0) then
        call set_error(error, 'the checkpoint '//plan%path//' cannot be resumed: its part '// &
                       part_name(plan%path, head%generation, p_open)//' cannot be read: '//trim(msg))
        exit
      end if
      slot(s)%n_batches = cnt(1)
      slot(s)%n_photons = cnt(2)
      slot(s)%work = cnt(3:4)
      slot(s)%anomalies = cnt(5:)
    end do
    if (unit /= -1) close (unit, iostat=ios)
    call agree_error(error)
    if (allocated(error)) return
    if (rank == 0 .and. cfg%control%verbose >= 1) write (output_unit, '(a)') &
      'resuming from the checkpoint '//plan%path//': batches 1 to '//str(n_done)// &
      ' are done; the results will be those of an uninterrupted run on '//str(n_slots)// &
      ' rank'//trim(merge('s', ' ', n_slots > 1))//', the rank count that started the case'
  end subroutine resume_run

  !> An error found on any rank, on every rank: the message of the lowest rank that found one.
  subroutine agree_error(error)
    type(error_t), allocatable, intent(inout) :: error
    real(dp), allocatable :: failed(:)
    integer(i8) :: codes(0:MSG_LEN)
    integer :: rank, first, n, i
    character(len=:), allocatable :: message
    rank = par_rank()
    allocate (failed(0:par_size() - 1))
    failed = 0.0_dp
    if (allocated(error)) failed(rank) = 1.0_dp
    call par_allreduce_sum(failed)
    if (all(failed < 0.5_dp)) return
    first = 0
    do while (failed(first) < 0.5_dp)
      first = first + 1
    end do
    if (first /= 0) then
      codes = 0
      if (rank == first) then
        n = min(len(error%message), MSG_LEN)
        codes(0) = n
        codes(1:n) = [(int(iachar(error%message(i:i)), i8), i=1, n)]
      end if
      call par_move(codes, first, 0)
      if (rank == 0) then
        allocate (character(len=int(codes(0))) :: message)
        do i = 1, len(message)
          message(i:i) = achar(codes(i))
        end do
        call set_error(error, message)
      end if
    end if
    call share_error(error)
  end subroutine agree_error

  !> Before any work (rank 0): with --resume, a checkpoint of another configuration is refused
  !> at once; without it, an existing checkpoint that this run will replace is mentioned.
  subroutine early_checkpoint_check(plan, cfg, error)
    type(checkpoint_plan_t), intent(in) :: plan
    type(config_t), intent(in) :: cfg
    type(error_t), allocatable, intent(out) :: error
    type(ckpt_header_t) :: head
    type(ckpt_layout_t) :: lt
    real(dp), allocatable :: rec(:, :)
    logical :: exists
    inquire (file=plan%path, exist=exists)
    if (.not. exists) return
    if (plan%resume) then
      call manifest_open(plan%path, plan%fp, -1, -1, head, rec, lt, error)
    else if (plan%interval > 0.0_dp .and. cfg%control%verbose >= 1) then
      write (output_unit, '(a)') 'note: the checkpoint '//plan%path//' of an earlier run is '// &
        'replaced: this run starts from the first batch (kumo --resume continues from it)'
    end if
  end subroutine early_checkpoint_check

  !> What a checkpoint of this run belongs to: the namelist text, the content of every input
  !> file it names, the kumo build.
  subroutine checkpoint_fingerprint(cfg, path, text, fp)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: path, text
    type(fingerprint_t), intent(out) :: fp
    type(input_file_t), allocatable :: inputs(:)
    integer :: i
    call fingerprint_add_text(fp, 'the namelist text', text)
    inputs = config_inputs(cfg, path)
    do i = 2, size(inputs)   ! the namelist itself is its text
      call fingerprint_add_file(fp, 'the input file '//inputs(i)%label, inputs(i)%path)
    end do
    call fingerprint_add_build(fp)
  end subroutine checkpoint_fingerprint

  !> Open `name` plus the temporary suffix for writing, as a new stream (a stale one from an
  !> earlier attempt is removed first); `what` names the file in the error.
  subroutine open_tmp(name, what, unit, error)
    character(len=*), intent(in) :: name, what
    integer, intent(out) :: unit
    type(error_t), allocatable, intent(out) :: error
    integer :: ios
    character(len=512) :: msg
    call remove_file(name//TMP_SUFFIX)
    open (newunit=unit, file=name//TMP_SUFFIX, status='new', action='write', access='stream', &
          form='unformatted', iostat=ios, iomsg=msg)
    if (ios /= 0) call set_error(error, 'cannot create '//what//' '//name//TMP_SUFFIX//': '//trim(msg))
  end subroutine open_tmp

end module kumo_checkpoint
