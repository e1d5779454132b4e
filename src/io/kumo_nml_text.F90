! SPDX-License-Identifier: BSD-3-Clause
!> The text of a namelist file: its groups (with line numbers) and their assignments, read by
!> kumo itself so that group names can be checked before any namelist read and a failed read
!> can be explained in terms of the group, the variable and the line.
!>
!> Layouts accepted, as gfortran reads them: `&group ... /`, `$group ... $end` (or `&end`),
!> several groups on one line, blanks or tabs anywhere, `!` comments. Text outside groups is
!> ignored (as the compiler's reader does). Quoted strings may hold any character.
module kumo_nml_text
  use, intrinsic :: iso_fortran_env, only: iostat_end
  use kumo_error, only: error_t, set_error, str, to_lower
  use kumo_textio, only: read_line
  implicit none
  private
  public :: nml_group_t, nml_assign_t, nml_scan, nml_assignments, nml_diagnose, closest_name, &
            edit_distance, nml_probe_i, nml_find_nan, nml_find_long_string

  !> One group as written in the file.
  type :: nml_group_t
    character(len=:), allocatable :: name   !! lower case, without & or $
    integer :: line = 0                     !! line of the group name
    integer :: end_line = 0                 !! line of the closing / or $end
    integer :: body_start = 0, body_end = -1 !! the group's text (after the name) in the file text
  end type nml_group_t

  !> One `object = values` item of a group.
  type :: nml_assign_t
    character(len=:), allocatable :: object !! as written, e.g. ext1d(1,1)
    character(len=:), allocatable :: name   !! base name, lower case, e.g. ext1d
    character(len=:), allocatable :: value  !! the values as written
    integer :: line = 0                     !! line of the object name
  end type nml_assign_t

  !> Read `text` (a group, `&name ... /`) with the namelist of one group, or, when `unit` /= 0,
  !> write that namelist (with its variable names) to `unit`. Each read_* routine of
  !> kumo_config supplies one as an internal procedure.
  abstract interface
    subroutine nml_probe_i(text, unit, ios, msg)
      implicit none
      character(len=*), intent(in) :: text
      integer, intent(in) :: unit
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: msg
    end subroutine nml_probe_i
  end interface

  character(len=1), parameter :: NL = achar(10), TAB = achar(9)

contains

  !> Find the groups of a namelist file's text. Errors: a group not closed before the next
  !> one or the end of the file.
  subroutine nml_scan(text, groups, error)
    character(len=*), intent(in) :: text
    type(nml_group_t), allocatable, intent(out) :: groups(:)
    type(error_t), allocatable, intent(out) :: error
    integer :: i, j, line, n
    logical :: inside
    character(len=1) :: c, quote
    character(len=:), allocatable :: name
    type(nml_group_t) :: g
    allocate (groups(0))
    line = 1
    inside = .false.
    quote = ' '
    i = 1
    n = len(text)
    do while (i <= n)
      c = text(i:i)
      if (c == NL) then
        line = line + 1
        i = i + 1
        cycle
      end if
      if (inside .and. quote /= ' ') then
        if (c == quote) then
          if (i < n) then
            if (text(i + 1:i + 1) == quote) then   ! doubled quote inside a string
              i = i + 2
              cycle
            end if
          end if
          quote = ' '
        end if
        i = i + 1
        cycle
      end if
      if (c == '!') then                           ! comment to the end of the line
        j = index(text(i:), NL)
        if (j == 0) exit
        i = i + j - 1
        cycle
      end if
      if ((c == '&' .or. c == '$') .and. at_token_start(text, i)) then
        j = i + 1
        do while (j <= n)
          if (.not. is_name_char(text(j:j))) exit
          j = j + 1
        end do
        name = to_lower(text(i + 1:j - 1))
        if (name == 'end') then
          if (inside) then
            g%end_line = line
            g%body_end = i - 1
            groups = [groups, g]
            inside = .false.
          end if
          i = j
          cycle
        end if
        if (len(name) > 0) then
          if (inside) then
            call set_error(error, 'namelist group &'//g%name//' (line '//str(g%line)// &
                           ') is not closed with / before '//c//name//' (line '//str(line)//')')
            return
          end if
          g%name = name
          g%line = line
          g%body_start = j
          g%end_line = 0
          g%body_end = -1
          inside = .true.
          i = j
          cycle
        end if
      end if
      if (inside) then
        if (c == '/') then
          g%end_line = line
          g%body_end = i - 1
          groups = [groups, g]
          inside = .false.
        else if (c == '''' .or. c == '"') then
          quote = c
        end if
      end if
      i = i + 1
    end do
    if (inside) then
      call set_error(error, 'namelist group &'//g%name//' (line '//str(g%line)// &
                     ') has no closing / before the end of the file')
    end if
  end subroutine nml_scan

  !> The assignments of a group: each starts at a name (with optional subscripts) followed by
  !> '='; its values run to the next one. Text before the first name is returned as an item
  !> without object (name '').
  subroutine nml_assignments(text, g, items)
    character(len=*), intent(in) :: text
    type(nml_group_t), intent(in) :: g
    type(nml_assign_t), allocatable, intent(out) :: items(:)
    integer :: i, j, k, line, n, obj_end, cur_line
    character(len=1) :: quote, c
    type(nml_assign_t) :: cur
    logical :: have
    allocate (items(0))
    n = g%body_end
    line = g%line
    quote = ' '
    call reset(cur, '', '', g%line)
    have = .false.
    i = g%body_start
    do while (i <= n)
      c = text(i:i)
      if (quote /= ' ') then
        if (c == quote) quote = ' '
        if (c == NL) line = line + 1
        cur%value = cur%value//c
        i = i + 1
        cycle
      end if
      if (c == NL) line = line + 1
      if (c == '!') then
        j = index(text(i:n), NL)
        if (j == 0) exit
        i = i + j - 1
        cycle
      end if
      if (c == '''' .or. c == '"') quote = c
      if (is_name_start(c) .and. at_token_start(text, i)) then
        call match_object(text, i, n, obj_end, k)
        if (k > 0) then                            ! name [(...)] = at i..k
          call push(cur)
          cur_line = line
          call reset(cur, text(i:obj_end), to_lower(base_name(text(i:obj_end))), cur_line)
          have = .true.
          do j = i, k
            if (text(j:j) == NL) line = line + 1
          end do
          i = k + 1
          cycle
        end if
      end if
      cur%value = cur%value//c
      i = i + 1
    end do
    call push(cur)
  contains
    !> Keep the item: an assignment, or text before the first one that is not blank.
    subroutine push(a)
      type(nml_assign_t), intent(in) :: a
      type(nml_assign_t) :: b
      b = finish(a)
      if (have .or. len(b%value) > 0) items = [items, b]
    end subroutine push

    subroutine reset(a, object, name, at_line)
      type(nml_assign_t), intent(inout) :: a
      character(len=*), intent(in) :: object, name
      integer, intent(in) :: at_line
      a%object = object
      a%name = name
      a%value = ''
      a%line = at_line
    end subroutine reset

    function finish(a) result(b)
      type(nml_assign_t), intent(in) :: a
      type(nml_assign_t) :: b
      integer :: m
      b = a
      b%value = a%value
      do m = 1, len(b%value)
        if (b%value(m:m) == NL .or. b%value(m:m) == TAB) b%value(m:m) = ' '
      end do
      b%value = trim(adjustl(b%value))
      m = len(b%value)
      if (m > 0) then
        if (b%value(m:m) == ',') b%value = trim(b%value(1:m - 1))
      end if
    end function finish
  end subroutine nml_assignments

  !> Turn a failed namelist read into a message naming the group, the line, the variable and
  !> what it expects. `probe` re-reads single assignments with the group's namelist.
  function nml_diagnose(group, text, probe, compiler_msg) result(message)
    character(len=*), intent(in) :: group         !! group name, lower case
    character(len=*), intent(in) :: text          !! the whole namelist file
    procedure(nml_probe_i) :: probe
    character(len=*), intent(in) :: compiler_msg  !! the compiler's message of the failed read
    character(len=:), allocatable :: message
    type(nml_group_t), allocatable :: groups(:)
    type(nml_assign_t), allocatable :: items(:)
    type(error_t), allocatable :: scan_error
    character(len=64), allocatable :: names(:)
    character(len=512) :: msg
    integer :: ig, ia, ios, k
    logical :: known
    message = 'namelist &'//group//': '//trim(compiler_msg)
    call nml_scan(text, groups, scan_error)
    if (allocated(scan_error)) return
    ig = 0
    do ia = 1, size(groups)
      if (groups(ia)%name == group) then
        ig = ia
        exit
      end if
    end do
    if (ig == 0) return
    call nml_assignments(text, groups(ig), items)
    do ia = 1, size(items)
      msg = ''
      if (len(items(ia)%name) == 0) then
        message = 'namelist &'//group//', line '//str(items(ia)%line)//': "'// &
                  items(ia)%value//'" is not of the form name = value (compiler: '// &
                  trim(compiler_msg)//')'
        return
      end if
      call probe('&'//group//' '//items(ia)%object//' = '//items(ia)%value//' /', 0, ios, msg)
      if (ios == 0) cycle
      call variable_names(probe, names)
      known = .false.
      do k = 1, size(names)
        if (trim(names(k)) == items(ia)%name) known = .true.
      end do
      if (.not. known) then
        message = 'namelist &'//group//', line '//str(items(ia)%line)//': unknown variable '// &
                  items(ia)%name//suggestion(items(ia)%name, names)//' (compiler: '// &
                  trim(msg)//')'
      else
        message = 'namelist &'//group//', line '//str(items(ia)%line)//': '// &
                  items(ia)%object//' = '//items(ia)%value//': expected '// &
                  expected(group, items(ia)%name, probe)//' (compiler: '//trim(msg)//')'
      end if
      return
    end do
    ! each assignment reads alone: report the group's lines
    message = 'namelist &'//group//' (lines '//str(groups(ig)%line)//' to '// &
              str(groups(ig)%end_line)//'): '//trim(compiler_msg)
  end function nml_diagnose

  !> A message for the first value NaN (any case, signed, with a repeat count or a payload
  !> such as nan(q)) in group `group` of the namelist text, or '' when there is none.
  function nml_find_nan(group, text) result(message)
    character(len=*), intent(in) :: group, text
    character(len=:), allocatable :: message
    type(nml_group_t), allocatable :: groups(:)
    type(nml_assign_t), allocatable :: items(:)
    type(error_t), allocatable :: scan_error
    character(len=:), allocatable :: v, tok
    integer :: ig, ia, i, j, k
    message = ''
    call nml_scan(text, groups, scan_error)
    if (allocated(scan_error)) return
    do ig = 1, size(groups)
      if (groups(ig)%name /= group) cycle
      call nml_assignments(text, groups(ig), items)
      do ia = 1, size(items)
        v = items(ia)%value
        i = 1
        do while (i <= len(v))
          if (v(i:i) == '''' .or. v(i:i) == '"') then     ! skip a string
            j = index(v(i + 1:), v(i:i))
            if (j == 0) exit
            i = i + j + 1
            cycle
          end if
          if (index(' ,', v(i:i)) > 0) then
            i = i + 1
            cycle
          end if
          j = i
          do while (j <= len(v))
            if (index(' ,', v(j:j)) > 0) exit
            j = j + 1
          end do
          tok = to_lower(v(i:j - 1))
          k = index(tok, '*')
          if (k > 0) tok = tok(k + 1:)
          if (len(tok) > 0) then
            if (tok(1:1) == '+' .or. tok(1:1) == '-') tok = tok(2:)
          end if
          if (len(tok) >= 3) then
            if (tok(1:3) == 'nan') then
              message = items(ia)%object//' = NaN must be finite (namelist &'//group// &
                        ', line '//str(items(ia)%line)//'; kumo accepts no NaN input)'
              return
            end if
          end if
          i = j
        end do
      end do
    end do
  end function nml_find_nan

  !> A message for the first quoted string of group `group` longer than its variable (the
  !> compiler cuts it silently: a path would name another file), or ''. The variables' lengths
  !> are those of the values in the compiler's namelist output (`probe`).
  function nml_find_long_string(group, text, probe) result(message)
    character(len=*), intent(in) :: group, text
    procedure(nml_probe_i) :: probe
    character(len=:), allocatable :: message
    type(nml_group_t), allocatable :: groups(:)
    type(nml_assign_t), allocatable :: items(:)
    type(error_t), allocatable :: scan_error
    character(len=64), allocatable :: names(:)
    integer, allocatable :: lens(:)
    integer :: ig, ia, k, n
    message = ''
    call nml_scan(text, groups, scan_error)
    if (allocated(scan_error)) return
    names = [character(len=64) ::]
    lens = [integer ::]
    do ig = 1, size(groups)
      if (groups(ig)%name /= group) cycle
      call nml_assignments(text, groups(ig), items)
      do ia = 1, size(items)
        if (len(items(ia)%value) == 0) cycle
        if (items(ia)%value(1:1) /= '''' .and. items(ia)%value(1:1) /= '"') cycle
        n = quoted_length(items(ia)%value)
        if (n <= 64) cycle                   ! no variable of kumo holds fewer characters
        if (size(names) == 0) call string_lengths(probe, names, lens)
        do k = 1, size(names)
          if (trim(names(k)) == items(ia)%name .and. n > lens(k)) then
            message = 'namelist &'//group//', line '//str(items(ia)%line)//': '// &
                      items(ia)%object//' has '//str(n)//' characters, more than the '// &
                      str(lens(k))//' it holds'
            return
          end if
        end do
      end do
    end do
  end function nml_find_long_string

  !> Characters of the first quoted string of `v` (doubled quotes count once).
  pure integer function quoted_length(v) result(n)
    character(len=*), intent(in) :: v
    integer :: i
    character(len=1) :: q
    q = v(1:1)
    n = 0
    i = 2
    do while (i <= len(v))
      if (v(i:i) == q) then
        if (i < len(v)) then
          if (v(i + 1:i + 1) == q) then
            n = n + 1
            i = i + 2
            cycle
          end if
        end if
        return
      end if
      n = n + 1
      i = i + 1
    end do
  end function quoted_length

  !> Names and lengths of a group's character variables, from the compiler's namelist output
  !> (written with quotes, so each value shows the variable's full length).
  subroutine string_lengths(probe, names, lens)
    procedure(nml_probe_i) :: probe
    character(len=64), allocatable, intent(out) :: names(:)
    integer, allocatable, intent(out) :: lens(:)
    character(len=:), allocatable :: line
    character(len=512) :: msg
    integer :: u, ios, k
    allocate (names(0), lens(0))
    open (newunit=u, status='scratch', action='readwrite', form='formatted', delim='quote', &
          iostat=ios)
    if (ios /= 0) return
    call probe('', u, ios, msg)
    rewind (u)
    do
      call read_line(u, line, ios)
      if (ios /= 0) exit
      line = adjustl(line)
      k = index(line, '=')
      if (k <= 1 .or. k >= len(line)) cycle
      if (line(k + 1:k + 1) /= '"') cycle
      names = [character(len=64) :: names, to_lower(line(1:k - 1))]
      lens = [lens, quoted_length(line(k + 1:))]
    end do
    close (u)
  end subroutine string_lengths

  !> ' (did you mean x?)' for the closest of `names` within a few edits, else ''.
  function suggestion(name, names) result(s)
    character(len=*), intent(in) :: name, names(:)
    character(len=:), allocatable :: s
    s = closest_name(name, names)
    if (len(s) > 0) s = '; did you mean '//s//'?'
  end function suggestion

  !> The closest of `names` to `name` (edit distance at most max(2, len/3)), or ''.
  function closest_name(name, names) result(best)
    character(len=*), intent(in) :: name, names(:)
    character(len=:), allocatable :: best
    integer :: i, d, dbest
    best = ''
    dbest = max(2, len_trim(name)/3) + 1
    do i = 1, size(names)
      d = edit_distance(trim(name), trim(names(i)))
      if (d < dbest) then
        dbest = d
        best = trim(names(i))
      end if
    end do
  end function closest_name

  !> Levenshtein distance (insertions, deletions, substitutions).
  pure integer function edit_distance(a, b) result(d)
    character(len=*), intent(in) :: a, b
    integer :: prev(0:len(b)), cur(0:len(b)), i, j
    prev = [(j, j=0, len(b))]
    do i = 1, len(a)
      cur(0) = i
      do j = 1, len(b)
        cur(j) = min(prev(j) + 1, cur(j - 1) + 1, prev(j - 1) + merge(0, 1, a(i:i) == b(j:j)))
      end do
      prev = cur
    end do
    d = prev(len(b))
  end function edit_distance

  !> Names of a group's variables, lower case, from the compiler's namelist output.
  subroutine variable_names(probe, found)
    procedure(nml_probe_i) :: probe
    character(len=64), allocatable, intent(out) :: found(:)
    character(len=4096) :: line
    character(len=512) :: msg
    integer :: u, ios, k, q
    allocate (found(0))
    open (newunit=u, status='scratch', action='readwrite', form='formatted', delim='quote', &
          iostat=ios)
    if (ios == 0) then
      call probe('', u, ios, msg)
      rewind (u)
      do
        read (u, '(a)', iostat=ios) line
        if (ios /= 0) exit
        line = adjustl(line)
        k = index(line, '=')
        q = scan(line, '"''')
        if (k <= 1) cycle
        if (q > 0 .and. q < k) cycle
        if (.not. is_name_start(line(1:1))) cycle
        if (verify(trim(line(1:k - 1)), 'ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz'// &
                   '0123456789_%') > 0) cycle
        found = [character(len=64) :: found, to_lower(line(1:k - 1))]
      end do
      close (u)
    end if
  end subroutine variable_names

  !> What a variable takes: its type (found by reading test values) and, for arrays, how many.
  function expected(group, name, probe) result(what)
    character(len=*), intent(in) :: group, name
    procedure(nml_probe_i) :: probe
    character(len=:), allocatable :: what
    integer :: lo, hi, mid
    character(len=:), allocatable :: v
    if (reads('''x''')) then
      what = 'a quoted string'
      v = '''x'''
    else if (reads('0.5')) then
      what = 'a real number'
      v = '0.5'
    else if (reads('T')) then
      what = 'a logical (T or F)'
      v = 'T'
    else if (reads('2147483648')) then
      what = 'an integer within [-9223372036854775808, 9223372036854775807]'
      v = '0'
    else if (reads('0')) then
      what = 'an integer within [-2147483648, 2147483647]'
      v = '0'
    else
      what = 'a value of another form'
      return
    end if
    ! array size: the largest repeat count that reads
    if (.not. reads('2*'//v)) return
    lo = 2
    hi = 2
    do while (reads(str(2*hi)//'*'//v) .and. hi < 2**24)
      hi = 2*hi
    end do
    hi = 2*hi
    do while (hi - lo > 1)
      mid = (lo + hi)/2
      if (reads(str(mid)//'*'//v)) then
        lo = mid
      else
        hi = mid
      end if
    end do
    what = 'at most '//str(lo)//' values, each '//what
  contains
    logical function reads(value)
      character(len=*), intent(in) :: value
      integer :: ios
      character(len=512) :: msg
      msg = ''
      call probe('&'//group//' '//name//' = '//value//' /', 0, ios, msg)
      reads = ios == 0
    end function reads
  end function expected

  !> `&`, `$`, a name or a value starts here: at the start of the text or after a blank, tab,
  !> line end, comma or /.
  pure logical function at_token_start(text, i)
    character(len=*), intent(in) :: text
    integer, intent(in) :: i
    if (i == 1) then
      at_token_start = .true.
    else
      at_token_start = index(' ,/'//NL//TAB//achar(13), text(i - 1:i - 1)) > 0
    end if
  end function at_token_start

  !> A name [(subscripts)] followed by '=' at text(i:); obj_end is the end of the object,
  !> k the position of '=' (0 when there is none).
  pure subroutine match_object(text, i, n, obj_end, k)
    character(len=*), intent(in) :: text
    integer, intent(in) :: i, n
    integer, intent(out) :: obj_end, k
    integer :: j, depth
    k = 0
    j = i
    do while (j <= n)
      if (.not. (is_name_char(text(j:j)) .or. text(j:j) == '%')) exit
      j = j + 1
    end do
    if (j <= n) then
      if (text(j:j) == '(') then
        depth = 0
        do while (j <= n)
          if (text(j:j) == '(') depth = depth + 1
          if (text(j:j) == ')') depth = depth - 1
          if (text(j:j) == NL .or. text(j:j) == '''' .or. text(j:j) == '"') return
          j = j + 1
          if (depth == 0) exit
        end do
      end if
    end if
    obj_end = j - 1
    do while (j <= n)
      if (index(' '//TAB//NL//achar(13), text(j:j)) == 0) exit
      j = j + 1
    end do
    if (j <= n) then
      if (text(j:j) == '=') k = j
    end if
  end subroutine match_object

  pure function base_name(object) result(name)
    character(len=*), intent(in) :: object
    character(len=:), allocatable :: name
    integer :: k
    k = scan(object, '(%')
    if (k == 0) then
      name = object
    else
      name = object(1:k - 1)
    end if
  end function base_name

  pure logical function is_name_start(c)
    character(len=1), intent(in) :: c
    is_name_start = (c >= 'a' .and. c <= 'z') .or. (c >= 'A' .and. c <= 'Z')
  end function is_name_start

  pure logical function is_name_char(c)
    character(len=1), intent(in) :: c
    is_name_char = is_name_start(c) .or. (c >= '0' .and. c <= '9') .or. c == '_'
  end function is_name_char
end module kumo_nml_text
