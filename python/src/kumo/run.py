# SPDX-License-Identifier: BSD-3-Clause
"""Running the kumo program: finding it, serial and MPI runs, errors as exceptions."""

from __future__ import annotations

import functools
import os
import re
import shutil
import subprocess
import sys
import threading
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import f90nml

from .namelist import write_namelist
from .results import open_results

DEFAULT_OUTPUT = "kumo_out.nc"   #: &kumo_output file when the namelist does not set it


class KumoError(RuntimeError):
    """kumo rejected a case or a run failed. ``str(error)`` is kumo's own message.

    Attributes: ``returncode`` (1 invalid case or failed run, 2 wrong command line, other
    values from the MPI launcher or a crash), ``stdout``, ``stderr``, ``command``.
    """

    def __init__(self, message, returncode=None, stdout="", stderr="", command=()):
        super().__init__(message)
        self.returncode = returncode
        self.stdout = stdout
        self.stderr = stderr
        self.command = list(command)


class KumoWarning(UserWarning):
    """A warning of kumo's run (``kumo: warning: ...`` on its standard error, and the output's
    ``warnings`` attribute): a setting that biases a result beyond its standard error, or an
    input that looks like another unit. :func:`run_kumo` and :func:`run` issue one per warning,
    with kumo's text, so that a Python caller sees what the command line shows."""


WARNING_PREFIX = "kumo: warning: "
#: kumo's progress lines on standard error (docs/user-guide.md, "Progress"), e.g.
#: ``kumo: 0.4 of 2 batches (20 %), 450000 photons/s, about 3 s left``
PROGRESS_LINE = re.compile(r"kumo: [0-9.]+ (of [0-9]+ )?batches")


def kumo_warnings(stderr: str) -> list:
    """The warnings of a kumo run's standard error (kumo writes each on one line), one text
    each, without the prefix."""
    return [line[len(WARNING_PREFIX):].strip() for line in stderr.splitlines()
            if line.startswith(WARNING_PREFIX)]


@dataclass
class Completed:
    """A finished kumo process: the command, its exit status and output, the output file."""
    command: list
    returncode: int
    stdout: str
    stderr: str
    output: Path | None


def find_executable(exe=None) -> Path:
    """The kumo program: ``exe`` if given, else ``$KUMO_EXE``, else ``kumo`` on ``PATH``.
    ``exe`` and ``$KUMO_EXE`` may be paths or program names found on ``PATH``."""
    candidates = []
    if exe is not None:
        candidates.append(("the exe argument", str(exe)))
    elif os.environ.get("KUMO_EXE"):
        candidates.append(("KUMO_EXE", os.environ["KUMO_EXE"]))
    else:
        found = shutil.which("kumo")
        if found is None:
            raise KumoError("kumo program not found: pass exe=..., set the KUMO_EXE environment "
                            "variable (e.g. KUMO_EXE=build/kumo) or put kumo on PATH")
        candidates.append(("PATH", found))
    source, path = candidates[0]
    path = Path(path).expanduser()
    if not path.is_file() and os.sep not in str(path) and shutil.which(str(path)):
        path = Path(shutil.which(str(path)))      # a program name, e.g. exe="kumo-mpi"
    if not path.is_file() or not os.access(path, os.X_OK):
        raise KumoError(f"kumo program from {source} = {path} is not an executable file")
    return path.resolve()


@functools.lru_cache(maxsize=None)
def _version_text(exe: str) -> str:
    proc = subprocess.run([exe, "--version"], capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise KumoError(f"{exe} --version failed (exit status {proc.returncode}): "
                        f"{proc.stderr.strip()}", proc.returncode, proc.stdout, proc.stderr)
    return proc.stdout


def version_info(exe=None) -> dict:
    """What ``kumo --version`` reports, as a dict: ``version``, ``git commit``, ``build type``,
    ``parallel`` (``MPI`` or ``serial``), ``compiler``, ``options``."""
    text = _version_text(str(find_executable(exe)))
    info = {}
    for line in text.splitlines():
        if line.startswith("kumo "):
            info["version"] = line.split(None, 1)[1].strip()
        elif ":" in line:
            key, value = line.split(":", 1)
            info[key.strip()] = value.strip()
    return info


@functools.lru_cache(maxsize=None)
def _is_open_mpi(mpiexec: str) -> bool:
    try:
        proc = subprocess.run([mpiexec, "--version"], capture_output=True, text=True,
                              check=False, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return bool(re.search(r"Open MPI|OpenRTE|open-mpi", proc.stdout + proc.stderr))


def mpi_command(np: int, mpiexec=None, mpi_args=()) -> list:
    """The launcher part of an MPI command line: ``mpirun -np N`` and, for OpenMPI, the flags
    it needs to run as root (``--allow-run-as-root``) and with more ranks than cores
    (``--oversubscribe``)."""
    launcher = mpiexec or shutil.which("mpirun") or shutil.which("mpiexec")
    if launcher is None:
        raise KumoError("np > 1 needs an MPI launcher: mpirun or mpiexec not found on PATH "
                        "(or pass mpiexec=...)")
    command = [str(launcher), "-np", str(int(np))]
    if _is_open_mpi(str(launcher)):
        if hasattr(os, "geteuid") and os.geteuid() == 0 and "--allow-run-as-root" not in mpi_args:
            command.append("--allow-run-as-root")
        if int(np) > (os.cpu_count() or 1) and "--oversubscribe" not in mpi_args:
            command.append("--oversubscribe")
    return command + [str(a) for a in mpi_args]


def _kumo_message(stderr: str, returncode: int) -> str:
    """kumo's own error message (a ``kumo error:`` or ``kumo:`` line and the indented lines
    that continue it) from its standard error, else the last lines of standard error."""
    lines = []
    in_message = False
    for line in stderr.splitlines():
        if line.startswith(("kumo error:", "kumo:")):
            in_message = True
        elif not (in_message and line.startswith((" ", "usage: kumo"))):
            in_message = False
        if in_message:
            lines.append(line)
    if lines:
        return "\n".join(lines)
    tail = "\n".join(stderr.strip().splitlines()[-10:])
    return f"kumo ended with exit status {returncode}" + (f":\n{tail}" if tail else "")


def _namelist_path(case, workdir: Path, name: str) -> Path:
    if isinstance(case, Mapping):
        return write_namelist(case, workdir / f"{name}.nml")
    path = Path(case)
    if not path.is_file():
        raise KumoError(f"namelist file {path} not found")
    return path.resolve()


def output_path(namelist, workdir=".") -> Path:
    """The output file a namelist file names (``&kumo_output file``), relative to ``workdir``
    (kumo's working directory) when it is a relative path."""
    nml = f90nml.read(str(namelist))
    file = DEFAULT_OUTPUT
    if "kumo_output" in nml and "file" in nml["kumo_output"]:
        file = str(nml["kumo_output"]["file"]).strip()
    path = Path(file)
    return path if path.is_absolute() else Path(workdir) / path


def _communicate(command, cwd, env, timeout, progress):
    """Run ``command``; return (returncode, stdout, stderr). kumo's progress lines go to
    ``progress`` (a callable taking the line) as they come."""
    proc = subprocess.Popen(command, cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    parts = {"stdout": [], "stderr": []}

    def drain(stream, key):
        for line in stream:
            parts[key].append(line)
            if key == "stderr" and progress is not None and PROGRESS_LINE.match(line):
                progress(line.rstrip("\n"))
        stream.close()

    readers = [threading.Thread(target=drain, args=(proc.stdout, "stdout"), daemon=True),
               threading.Thread(target=drain, args=(proc.stderr, "stderr"), daemon=True)]
    for reader in readers:
        reader.start()
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        for reader in readers:
            reader.join()
        raise subprocess.TimeoutExpired(command, timeout, "".join(parts["stdout"]),
                                        "".join(parts["stderr"])) from None
    for reader in readers:
        reader.join()
    return proc.returncode, "".join(parts["stdout"]), "".join(parts["stderr"])


def _print_progress(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def run_kumo(case, workdir=None, *, name: str = "case", exe=None, np: int = 1, mpiexec=None,
             mpi_args=(), args=(), timeout=None, env=None, progress=True) -> Completed:
    """Run the kumo program on ``case`` and return the finished process (no result reading).

    ``case`` is a mapping of namelist groups (written to ``<workdir>/<name>.nml``) or the path
    of a namelist file. kumo runs in ``workdir`` (default: the current directory), so a
    relative output file name lands there. ``np`` > 1 runs ``mpirun -np np`` (an MPI build of
    kumo is required); ``args`` are extra kumo options (e.g. ``["--check"]``); ``env`` adds
    environment variables. Raises :class:`KumoError` with kumo's message when it exits with a
    non-zero status, and ``subprocess.TimeoutExpired`` after ``timeout`` seconds; issues each
    warning of the run as a :class:`KumoWarning`. kumo's progress lines (a run longer than
    5 s: batches done, photons per second, time left) are printed on ``sys.stderr`` while it
    runs, or passed to ``progress`` when it is a callable, or dropped with ``progress=False``;
    they stay in ``stderr`` of the result either way.
    """
    workdir = (Path(workdir) if workdir is not None else Path.cwd()).resolve()
    workdir.mkdir(parents=True, exist_ok=True)
    program = find_executable(exe)
    nml = _namelist_path(case, workdir, name)
    # a namelist in the working directory is named as such (it is recorded in the output)
    shown = nml.name if nml.parent == workdir else str(nml)
    command = [str(program), *[str(a) for a in args], shown]
    if int(np) > 1:
        info = version_info(program)
        if info.get("parallel", "MPI") != "MPI":
            raise KumoError(f"np = {np}: {program} is a serial build (kumo --version: parallel "
                            f"{info.get('parallel')}); build with -DKUMO_ENABLE_MPI=ON")
        command = mpi_command(np, mpiexec, mpi_args) + command
    elif int(np) < 1:
        raise ValueError(f"np = {np} must be >= 1")
    run_env = None if env is None else {**os.environ, **env}
    if progress is True:
        progress = _print_progress
    elif progress is False:
        progress = None
    elif not callable(progress):
        raise TypeError(f"progress = {progress!r} must be True, False or a callable")
    returncode, stdout, stderr = _communicate(command, workdir, run_env, timeout, progress)
    if returncode != 0:
        raise KumoError(_kumo_message(stderr, returncode), returncode, stdout, stderr, command)
    for text in kumo_warnings(stderr):
        warnings.warn(text, KumoWarning, stacklevel=_caller_level())
    out = None if "--check" in args or "-c" in args else output_path(nml, workdir)
    return Completed(command, returncode, stdout, stderr, out)


def _caller_level() -> int:
    """The stack level of the first frame outside this package, for warnings.warn."""
    level, frame = 1, sys._getframe(1)
    here = os.path.dirname(os.path.abspath(__file__))
    while frame is not None and os.path.dirname(os.path.abspath(frame.f_code.co_filename)) == here:
        level += 1
        frame = frame.f_back
    return level


def run(case, workdir=None, **kwargs):
    """Run kumo on ``case`` and return its output file as an xarray Dataset.

    Arguments as :func:`run_kumo`. Every Monte Carlo product ``<name>`` comes with its standard
    error ``<name>_stderr`` (see docs/output.md); the run log (kumo's standard output) is in
    ``ds.attrs["kumo_log"]``.
    """
    done = run_kumo(case, workdir, **kwargs)
    ds = open_results(done.output)
    ds.attrs["kumo_log"] = done.stdout
    return ds


def check(case, workdir=None, **kwargs) -> str:
    """``kumo --check``: validate ``case`` and the files it names, set its scene up, trace
    nothing.

    Returns the configuration echo (every setting with its effective value) and the scene's
    summary (grid, optical depths of the columns); the set-up's warnings are issued as
    :class:`KumoWarning`; raises :class:`KumoError` listing every problem found.
    """
    kwargs = dict(kwargs)
    kwargs["args"] = ["--check", *kwargs.get("args", ())]
    kwargs["np"] = 1
    return run_kumo(case, workdir, **kwargs).stdout
