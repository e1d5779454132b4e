! SPDX-License-Identifier: BSD-3-Clause
!> The command line of the program: parsing, `--help`, `--version` and `--check`.
!>
!> Everything here reports through `error_t` or returns text; only `kumo_main` prints and ends
!> the run.
module kumo_cli
  use, intrinsic :: iso_fortran_env, only: compiler_version, compiler_options
  use kumo_error, only: error_t, set_error, str
  use kumo_constants, only: KUMO_VERSION
  use kumo_config, only: config_t, config_echo, input_file_t, config_inputs
  use kumo_scene_setup, only: load_config
  use kumo_netcdf, only: check_writable
  use kumo_parallel, only: PAR_IS_MPI
  use kumo_build_info, only: BUILD_GIT_COMMIT, BUILD_TYPE
  implicit none
  private
  public :: cli_t, parse_command_line, help_text, version_text, check_case
  public :: CLI_RUN, CLI_HELP, CLI_VERSION, CLI_CHECK

  integer, parameter :: CLI_RUN = 1      !! run the case
  integer, parameter :: CLI_HELP = 2     !! print the help
  integer, parameter :: CLI_VERSION = 3  !! print the version
  integer, parameter :: CLI_CHECK = 4    !! validate the case, run nothing

  !> What the command line asks for.
  type :: cli_t
    integer :: action = CLI_RUN
    character(len=:), allocatable :: path  !! the namelist file (CLI_RUN, CLI_CHECK)
    logical :: resume = .false.            !! continue from the checkpoint <output>.ckpt
  end type cli_t

  character(len=1), parameter :: NL = new_line('a')

contains

  !> Read the command-line arguments. `--help` and `--version` win over everything else, so
  !> `kumo case.nml --help` prints the help. Errors are usage errors (exit status 2).
  subroutine parse_command_line(cli, error)
    type(cli_t), intent(out) :: cli
    type(error_t), allocatable, intent(out) :: error
    integer :: i, n
    logical :: check, help, version, options_done
    character(len=:), allocatable :: arg, path, unknown

    check = .false.
    help = .false.
    version = .false.
    options_done = .false.
    path = ''
    unknown = ''
    n = 0
    do i = 1, command_argument_count()
      arg = argument(i)
      if (.not. options_done .and. len(arg) > 1 .and. arg(1:1) == '-') then
        select case (arg)
        case ('-h', '--help')
          help = .true.
        case ('-V', '--version')
          version = .true.
        case ('-c', '--check')
          check = .true.
        case ('--resume')
          cli%resume = .true.
        case ('--')
          options_done = .true.
        case default
          if (len(unknown) == 0) unknown = arg
        end select
      else
        n = n + 1
        if (n == 1) path = arg
      end if
    end do

    if (help) then
      cli%action = CLI_HELP
    else if (version) then
      cli%action = CLI_VERSION
    else if (len(unknown) > 0) then
      call set_error(error, 'unknown option '''//unknown//'''')
    else if (n == 0) then
      call set_error(error, 'no namelist file given')
    else if (n > 1) then
      call set_error(error, 'one namelist file expected, got '//str(n)//' arguments')
    else
      cli%action = merge(CLI_CHECK, CLI_RUN, check)
      cli%path = path
    end if
  end subroutine parse_command_line

  !> The text of `kumo --help`.
  function help_text() result(text)
    character(len=:), allocatable :: text
    text = &
      'usage: kumo [options] CASE.nml'//NL// &
      NL// &
      'Runs the forward Monte Carlo radiative transfer case described by the namelist file'//NL// &
      'CASE.nml and writes the netCDF file named by &kumo_output file (default kumo_out.nc).'//NL// &
      'Relative file names inside CASE.nml are relative to the folder of CASE.nml; the output'//NL// &
      'file is relative to the working directory.'//NL// &
      NL// &
      'options:'//NL// &
      '  -h, --help             print this help and exit'//NL// &
      '  -V, --version          print the version, git commit, build type, compiler and its'//NL// &
      '                         options, and exit'//NL// &
      '  -c, --check CASE.nml   read and validate CASE.nml, check that the input files it names'//NL// &
      '                         can be read and that the output file can be written, print the'//NL// &
      '                         configuration, then set the scene up as a run does (its notes,'//NL// &
      '                         warnings, grid and column optical depths); trace no photon'//NL// &
      '  --resume               continue from the checkpoint <output>.ckpt that an earlier'//NL// &
      '                         run of the same case wrote (&kumo_control'//NL// &
      '                         checkpoint_interval); without one, start from the beginning'//NL// &
      NL// &
      'parallel runs (MPI build): mpirun -np N kumo CASE.nml spreads the batches over N ranks;'//NL// &
      'the results are the same for any N. As root add --allow-run-as-root; with more ranks than'//NL// &
      'cores add --oversubscribe (OpenMPI).'//NL// &
      NL// &
      'exit status: 0 success, 1 invalid case or failed run, 2 wrong command line.'//NL// &
      NL// &
      'documentation (in the kumo source tree): README.md; docs/user-guide.md (start here),'//NL// &
      'docs/namelist.md (every namelist variable), docs/output.md (the output file),'//NL// &
      'docs/python.md (the Python package); namelists/reference.nml lists every variable with'//NL// &
      'its default.'
  end function help_text

  !> The text of `kumo --version`: release, commit, build type, parallel layer, compiler.
  function version_text() result(text)
    character(len=:), allocatable :: text
    text = 'kumo '//KUMO_VERSION//NL// &
           'git commit: '//BUILD_GIT_COMMIT//NL// &
           'build type: '//BUILD_TYPE//NL// &
           'parallel:   '//trim(merge('MPI   ', 'serial', PAR_IS_MPI))//NL// &
           'compiler:   '//compiler_version()//NL// &
           'options:    '//compiler_options()
  end function version_text

  !> `kumo --check`: read and validate the namelist `path` with the same rules as a run, check
  !> that every input file it names exists and can be read and that the output file can be
  !> written (a probe `<file>.tmp` is created and deleted). `report` is the configuration echo
  !> and the list of files checked. With problems, `error` lists all of them, one per line.
  subroutine check_case(path, report, error)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: report
    type(error_t), allocatable, intent(out) :: error
    type(config_t) :: cfg
    type(error_t), allocatable :: err
    character(len=:), allocatable :: files, problems, cache
    type(input_file_t), allocatable :: inputs(:)
    integer :: i, n_problems
    logical :: exists

    report = ''
    call load_config(path, cfg, error, local=.true.)   ! rank 0 alone
    if (allocated(error)) return
    files = ''
    problems = ''
    inputs = config_inputs(cfg, path)
    do i = 2, size(inputs)   ! the namelist itself was read above
      call check_input(inputs(i)%label, inputs(i)%path, files, problems)
    end do
    if (cfg%cloud%enabled) then
      if (len_trim(cfg%cloud%mie_cache) > 0) then
        cache = trim(cfg%cloud%mie_cache)
        inquire (file=cache, exist=exists)
        if (exists) then
          call check_input('&kumo_cloud mie_cache', cache, files, problems)
        else
          files = files//'  &kumo_cloud mie_cache = '//cache// &
                  ': not there yet, the set-up creates it'//NL
        end if
      end if
    end if
    call check_writable(trim(cfg%output%file), err)
    if (allocated(err)) then
      problems = problems//'&kumo_output file: '//err%message//NL
    else
      files = files//'  &kumo_output file = '//trim(cfg%output%file)//': can be written'//NL
    end if

    report = 'kumo '//KUMO_VERSION//': '//path//NL//config_echo(cfg)//NL// &
             'files:'//NL//files
    n_problems = count_lines(problems)
    if (n_problems == 1) then
      call set_error(error, path//': '//problems(:len(problems) - 1))
    else if (n_problems > 1) then
      call set_error(error, path//': '//str(n_problems)//' problems:'//NL//'  '// &
                     replace_newlines(problems(:len(problems) - 1), NL//'  '))
    end if
  end subroutine check_case

  !> One input file of `--check`: it must exist, not be a folder, and open for reading.
  subroutine check_input(what, file, files, problems)
    character(len=*), intent(in) :: what, file
    character(len=:), allocatable, intent(inout) :: files, problems
    logical :: exists, is_dir
    integer :: unit, ios
    character(len=512) :: msg

    inquire (file=file, exist=exists)
    inquire (file=file//'/.', exist=is_dir)
    if (.not. exists .and. .not. is_dir) then
      problems = problems//what//' = '//file//': no such file'//NL
      return
    end if
    if (is_dir) then
      problems = problems//what//' = '//file//': is a folder, not a file'//NL
      return
    end if
    msg = ''
    open (newunit=unit, file=file, status='old', action='read', access='stream', iostat=ios, &
          iomsg=msg)
    if (ios /= 0) then
      problems = problems//what//' = '//file//': cannot be read: '//trim(msg)//NL
      return
    end if
    close (unit)
    files = files//'  '//what//' = '//file//': readable'//NL
  end subroutine check_input

  !> Number of line ends in `text`.
  pure integer function count_lines(text) result(n)
    character(len=*), intent(in) :: text
    integer :: i
    n = 0
    do i = 1, len(text)
      if (text(i:i) == NL) n = n + 1
    end do
  end function count_lines

  !> `text` with every line end replaced by `sep`.
  pure function replace_newlines(text, sep) result(out)
    character(len=*), intent(in) :: text, sep
    character(len=:), allocatable :: out
    integer :: i
    out = ''
    do i = 1, len(text)
      if (text(i:i) == NL) then
        out = out//sep
      else
        out = out//text(i:i)
      end if
    end do
  end function replace_newlines

  !> Command-line argument i, without trailing blanks.
  function argument(i) result(arg)
    integer, intent(in) :: i
    character(len=:), allocatable :: arg
    integer :: length
    call get_command_argument(i, length=length)
    allocate (character(len=length) :: arg)
    if (length > 0) call get_command_argument(i, arg)
  end function argument
end module kumo_cli
