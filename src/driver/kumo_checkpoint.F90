! SPDX-License-Identifier: BSD-3-Clause
!> Checkpoint files: the accumulated batch sums of an unfinished run, so that a job killed at its
!> wall-time limit can be continued (`kumo --resume`) to the result an uninterrupted run gives.
!>
!> A checkpoint `<output>.ckpt` is written by rank 0 only: to `<output>.ckpt.tmp` (created
!> exclusively after a stale one is removed), renamed over the previous checkpoint after it was
!> closed without error, so a job killed while writing leaves the last complete checkpoint. It
!> holds the configuration's fingerprint, the run's progress (batches done, the start of the
!> current round), the per-batch records, and for every batch slot (the rank that ran the batch
!> in the job that started the case) its sums S1, S2 and counts.
!>
!> The file format (ckpt_create ... ckpt_remove) is rank 0's alone. The run-level part
!> (checkpoint_plan_t, checkpoint_due, write_checkpoint, resume_run, early_checkpoint_check,
!> checkpoint_fingerprint) is collective where it says so: it moves the slots between the ranks
!> and rank 0 and shares rank 0's decisions. The driver (kumo_driver) decides when to call it.
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
                           par_bcast_int, par_move
  use kumo_run_util, only: share_error
  implicit none
  private
  public :: fingerprint_t, ckpt_header_t, fingerprint_add_text, fingerprint_add_file, &
            fingerprint_add_build, ckpt_create, ckpt_put_slot, ckpt_commit, ckpt_open, &
            ckpt_get_slot, ckpt_close, ckpt_remove, text_hash, CKPT_SUFFIX
  public :: checkpoint_plan_t, checkpoint_due, write_checkpoint, resume_run, &
            early_checkpoint_check, checkpoint_fingerprint

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

  !> Checkpoints of a run (run_case sets it up from the configuration and the command line).
  type :: checkpoint_plan_t
    character(len=:), allocatable :: path   !! the checkpoint file, <output>.ckpt
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
  !> in the round that began with batch `ib_round`. Collective: the slots travel to rank 0,
  !> which writes them one by one. A checkpoint that cannot be written is a warning: the run
  !> goes on (the previous checkpoint, if any, stays).
  subroutine write_checkpoint(plan, cfg, lay, slot, n_slots, ib_round, n_done, rec, cpu_rank)
    type(checkpoint_plan_t), intent(in) :: plan
    type(config_t), intent(in) :: cfg
    type(tally_layout_t), intent(in) :: lay
    integer, intent(in) :: n_slots, ib_round, n_done
    type(stats_t), intent(in) :: slot(0:n_slots - 1)
    real(dp), intent(in) :: rec(:, :)
    real(dp), intent(in) :: cpu_rank   !! this rank's CPU time so far (rank 0: and before)
    type(error_t), allocatable :: err
    type(ckpt_header_t) :: head
    real(dp), allocatable :: flat(:), x1(:), x2(:)
    integer(i8) :: cnt(4 + N_ANOMALIES)
    integer :: s, owner, rank, nranks, unit
    rank = par_rank()
    nranks = par_size()
    flat = [reshape(rec(:, 1:n_done), [3*n_done]), cpu_rank]
    call par_sum_to_root(flat)   ! each record is non-zero on one rank only: the sum is exact
    allocate (x1(lay%n), x2(lay%n))
    if (rank == 0) then
      head%n_slots = n_slots
      head%ib_round = ib_round
      head%n_done = n_done
      head%n_values = lay%n
      head%n_counts = size(cnt)
      head%cpu = flat(size(flat))
      call ckpt_create(plan%path, plan%fp, head, reshape(flat(1:3*n_done), [3, n_done]), unit, &
                       err)
    end if
    do s = 0, n_slots - 1
      owner = mod(s, nranks)
      if (rank == owner) then
        cnt = [slot(s)%n_batches, slot(s)%n_photons, slot(s)%work, slot(s)%anomalies]
        x1 = slot(s)%s1
        x2 = slot(s)%s2
      end if
      call par_move(cnt, owner, 0)
      call par_move(x1, owner, 0)
      call par_move(x2, owner, 0)
      if (rank == 0) call ckpt_put_slot(unit, plan%path, cnt, x1, x2, err)
    end do
    if (rank /= 0) return
    call ckpt_commit(unit, plan%path, err)
    if (allocated(err)) then
      write (error_unit, '(a)') 'kumo: warning: no checkpoint after batch '//str(n_done)// &
        ' (the run goes on): '//err%message
    else if (cfg%control%verbose >= 1) then
      write (error_unit, '(a)') 'kumo: checkpoint after batch '//str(n_done)//': '//plan%path
    end if
    flush (error_unit)
  end subroutine write_checkpoint

  !> Continue from the checkpoint `plan%path` if it exists (else start from the first batch):
  !> rank 0 reads it and checks it against the configuration's fingerprint; every slot goes to
  !> the rank that runs it. Returns the slot count, the first batch of the round in progress,
  !> the batches done, their records and the CPU time before (rank 0) and the slots' sums.
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
    real(dp), allocatable :: x1(:), x2(:)
    integer(i8) :: cnt(4 + N_ANOMALIES)
    integer :: info(4), s, owner, rank, nranks, unit
    logical :: exists
    rank = par_rank()
    nranks = par_size()
    cpu_before = 0.0_dp
    info = 0
    if (rank == 0) then
      inquire (file=plan%path, exist=exists)
      if (exists) then
        call ckpt_open(plan%path, plan%fp, lay%n, size(cnt), head, rec, unit, error)
        info = [1, head%n_slots, head%ib_round, head%n_done]
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
    allocate (slot(0:n_slots - 1), x1(lay%n), x2(lay%n))
    do s = 0, n_slots - 1
      owner = mod(s, nranks)
      if (rank == 0) call ckpt_get_slot(unit, plan%path, cnt, x1, x2, error)
      call par_move(cnt, 0, owner)
      call par_move(x1, 0, owner)
      call par_move(x2, 0, owner)
      if (rank == owner) then
        call stats_init(slot(s), lay)
        slot(s)%n_batches = cnt(1)
        slot(s)%n_photons = cnt(2)
        slot(s)%work = cnt(3:4)
        slot(s)%anomalies = cnt(5:)
        slot(s)%s1 = x1
        slot(s)%s2 = x2
      end if
    end do
    if (rank == 0) call ckpt_close(unit, plan%path, error)
    call share_error(error)
    if (allocated(error)) return
    if (rank == 0 .and. cfg%control%verbose >= 1) write (output_unit, '(a)') &
      'resuming from the checkpoint '//plan%path//': batches 1 to '//str(n_done)// &
      ' are done; the results will be those of an uninterrupted run on '//str(n_slots)// &
      ' rank'//trim(merge('s', ' ', n_slots > 1))//', the rank count that started the case'
  end subroutine resume_run

  !> Before any work (rank 0): with --resume, a checkpoint of another configuration is refused
  !> at once; without it, an existing checkpoint that this run will replace is mentioned.
  subroutine early_checkpoint_check(plan, cfg, error)
    type(checkpoint_plan_t), intent(in) :: plan
    type(config_t), intent(in) :: cfg
    type(error_t), allocatable, intent(out) :: error
    type(ckpt_header_t) :: head
    real(dp), allocatable :: rec(:, :)
    integer :: unit
    logical :: exists
    inquire (file=plan%path, exist=exists)
    if (.not. exists) return
    if (plan%resume) then
      call ckpt_open(plan%path, plan%fp, -1, -1, head, rec, unit, error)
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

end module kumo_checkpoint
