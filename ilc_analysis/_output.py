r"""Files and directories written all at once or not at all, and input files read within bounds.

An output is first written to a temporary sibling of its target (same directory, so the final
:func:`os.replace` is a rename on one file system) and moved into place only when everything
was written. On any failure — an exception, Ctrl-C (``KeyboardInterrupt``), ``SystemExit`` —
the temporary copy is removed and the target is left as it was. An existing output directory
is replaced as a whole: renamed aside, the new one renamed in, the old one removed.

A directory target is guarded by a lock file beside it (``.<name>.lock``, a
:class:`filelock.FileLock`: portable, no :mod:`fcntl`), taken without waiting: a second run into
the same directory is refused at once (:class:`OutputBusyError`) instead of mixing its files
with the first run's (:func:`held_lock`; the learner's state file waits for its lock instead).
The lock file is removed, while still held, when the run ends. Temporary directories left by a
killed run (SIGKILL) are removed by the next run into the same target, which holds the lock.

Every output directory the toolkit creates holds a marker file, :data:`OUTPUT_MARKER` (the
command and the toolkit's version). An existing directory is replaced only if it holds that
marker (or is empty), and only by the command the marker names: never because the names of
its files look like the toolkit's (a user's own ``summary.json`` is not an output of this
toolkit), and a ``simulate`` run never replaces a study's results.

Nothing a run reads is destroyed by what it writes: the command line registers the files it
reads (:func:`tracking_inputs`; every reader goes through :func:`check_input_file`), and an
output file that is one of them, or an output directory that holds one, is refused before it
is replaced (the commands also check the files named on their command line before any work).
An output file replaces an existing one only if that file is of the kind the command writes
(``replaces=``: a design file, the arrays of an identified plant, ...).

Paths are checked before any work is done (:func:`check_output_path`,
:func:`check_input_file`); every error is a :class:`~ilc_analysis.exceptions.ParameterError`
naming the option.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import re
import shutil
import stat
import tempfile
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from pathlib import Path

from ._version import __version__
from .exceptions import ParameterError

PathArgument = str | os.PathLike[str]
"""A path as the command line and the API take it."""

__all__ = ["OutputBusyError", "check_output_path", "check_input_file", "output_directory",
           "output_file", "held_lock", "is_output_directory", "write_output_marker",
           "marker_command", "tracking_inputs", "not_tracking", "note_input",
           "check_not_inputs",
           "OUTPUT_MARKER", "MAX_INPUT_BYTES"]

#: Name of the marker file written into every output directory (:func:`write_output_marker`).
#: A directory holding it (a regular file), or an empty one, may be replaced by the next run;
#: any other existing directory is refused, whatever its files are called, so neither
#: ``--out ~`` nor ``--out`` naming a user's directory of results can delete them.
OUTPUT_MARKER = ".ilc-analysis-output"
#: Largest input file (gains, scenario) read, in bytes: a gains file of time-varying gains for
#: a 20 000-sample trial of a 2-input, 3-output plant is about 10 MB.
MAX_INPUT_BYTES = 16 * 2**20


class OutputBusyError(ParameterError):
    """Another run is writing the same output directory (its lock is held)."""


# ---------------------------------------------------------------------------------------------
# the files a run reads
# ---------------------------------------------------------------------------------------------
#: (shown path, what it was read as, (st_dev, st_ino)) of every input file of the current run
_INPUTS: contextvars.ContextVar[list | None] = contextvars.ContextVar("ilc_inputs",
                                                                     default=None)


@contextlib.contextmanager
def tracking_inputs() -> Iterator[None]:
    """Context manager: register every file read through :func:`check_input_file` in the
    block, so that :func:`output_file` and :func:`output_directory` refuse to replace one of
    them (the command line runs each command inside one; the Python API does not, since a
    session may well read a design and later write the same path on purpose)."""
    token = _INPUTS.set([])
    try:
        yield
    finally:
        _INPUTS.reset(token)


@contextlib.contextmanager
def not_tracking() -> Iterator[None]:
    """Context manager: reads in the block are not registered as inputs (a check of what an
    existing output file holds before it is replaced)."""
    token = _INPUTS.set(None)
    try:
        yield
    finally:
        _INPUTS.reset(token)


def note_input(path: Path, option: str) -> None:
    """Register ``path`` (read as ``option``) as an input of the current run, if inputs are
    tracked (:func:`tracking_inputs`)."""
    inputs = _INPUTS.get()
    if inputs is None:
        return
    with contextlib.suppress(OSError):
        st = os.stat(path)
        inputs.append((str(path), option, (st.st_dev, st.st_ino)))


def _same_file(a: os.stat_result, key: tuple) -> bool:
    return (a.st_dev, a.st_ino) == key


def _refuse_inputs(target: Path, option: str, shown: str, *, directory: bool) -> None:
    """Refuse to replace ``target`` when it is (or, as a directory, holds) a file the current
    run read (:func:`tracking_inputs`)."""
    for path, what, key in _INPUTS.get() or ():
        try:
            if directory:
                real = Path(path).resolve()
                hit = target == real or target in real.parents
            else:
                hit = _same_file(os.stat(target), key)
        except OSError:
            continue
        if hit:
            where = "holds" if directory else "is"
            raise ParameterError(f"{option} {shown!r} {where} {what} {path!r}, which this run "
                                 f"reads: writing {option} would replace it; choose another "
                                 f"path")


def check_not_inputs(outputs: Mapping[str, PathArgument | None],
                     inputs: Mapping[str, PathArgument | Sequence[PathArgument | None] | None], *,
                     directories: Collection[str] = ()) -> None:
    """Refuse, before any work, an output that is one of the run's input files (or, for an
    output directory, holds one).

    Parameters
    ----------
    outputs : mapping
        Option (``'--out'``) -> path, for each output given (None: not given).
    inputs : mapping
        Option or argument (``'--problem'``, ``'DESIGN'``) -> a path or a list of paths.
    directories : collection of str
        The options of ``outputs`` that name directories (replaced as a whole).

    Raises
    ------
    ParameterError
        Naming both: ``--out 'x.toml' is also --problem 'x.toml' ...``.
    """
    for option, out in outputs.items():
        if out is None:
            continue
        target = Path(os.fspath(out)).resolve()
        if option in directories and target.exists() and not target.is_dir():
            continue                       # check_output_path says what it is instead
        for name, value in inputs.items():
            paths: Sequence[PathArgument | None] = (
                value if isinstance(value, list | tuple) else [value])  # type: ignore[list-item]
            for p in paths:
                if p is None:
                    continue
                real = Path(os.fspath(p)).resolve()
                if option in directories:
                    hit = target == real or target in real.parents
                else:
                    hit = target == real or (real.exists() and target.exists()
                                             and os.path.samefile(real, target))
                if hit:
                    how = "holds" if option in directories else "is also"
                    raise ParameterError(
                        f"{option} {os.fspath(out)!r} {how} {name} {os.fspath(p)!r}, which "
                        f"this run reads: writing {option} would replace it; choose another "
                        f"path")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _nonempty(path, option: str) -> str:
    if isinstance(path, os.PathLike):
        path = os.fspath(path)
    if not isinstance(path, str) or not path.strip():
        raise ParameterError(f"{option} must be a non-empty path; got {path!r}")
    if "\0" in path:
        raise ParameterError(f"{option} must not contain a NUL character; got {path!r}")
    return path


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISREG, "a file"), (stat.S_ISDIR, "a directory"),
                       (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "neither a file nor a directory"


def is_output_directory(directory: Path) -> bool:
    """Whether ``directory`` was written by this toolkit: it holds :data:`OUTPUT_MARKER` as a
    regular file (not a symbolic link or a directory of that name)."""
    try:
        return stat.S_ISREG(os.lstat(Path(directory) / OUTPUT_MARKER).st_mode)
    except OSError:
        return False


_MARKER_COMMAND = re.compile(r"Written by (\S[^\n]*?) \((?:ilc-analysis )?[^)\n]*\)")


def marker_command(directory: Path) -> str | None:
    """The command named by the marker of ``directory`` (``'ilc-analysis study'``), or None
    when the marker names none (an empty marker: any command may replace the directory)."""
    try:
        with open(Path(directory) / OUTPUT_MARKER, encoding="utf-8", errors="replace") as f:
            text = f.read(4096)
    except OSError:
        return None
    match = _MARKER_COMMAND.search(text)
    return match.group(1) if match else None


def write_output_marker(directory: Path, command: str) -> None:
    """Write :data:`OUTPUT_MARKER` into ``directory``: what wrote it (``command``, e.g.
    ``'ilc-analysis simulate'``) and the toolkit's version. Its presence is what lets a later
    run replace the directory (:func:`check_output_path`)."""
    (Path(directory) / OUTPUT_MARKER).write_text(
        f"Written by {command} (ilc-analysis {__version__}). The next run into this "
        "directory may replace it as a whole; remove this file to protect the directory.\n")


def check_output_path(path, option: str, *, directory: bool = False,
                      suffixes: Collection[str] = (), command: str | None = None,
                      replaces: Callable[[Path], str | None] | None = None) -> Path:
    """Check an output path before any work is done; return it resolved (symlinks followed).

    Parameters
    ----------
    path : str or path-like
        The user's value.
    option : str
        The option's name as the user typed it (e.g. ``'--out'``), used in every message.
    directory : bool
        The target is a directory (else a regular file).
    suffixes : collection of str
        Allowed file suffixes (files only; empty = any).
    command : str, optional
        The command that will write the directory (``'ilc-analysis simulate'``): an existing
        output directory whose marker names another command is refused (what one command
        wrote is never replaced by another).
    replaces : callable, optional
        For a file: ``replaces(existing_path)`` returns None when an existing file at the
        target is of the kind the command writes (so it may be replaced), else what it is
        instead (the file is then refused).

    Raises
    ------
    ParameterError
        Empty path; an existing target of the wrong kind; a missing or read-only parent
        directory; an existing non-empty directory without :data:`OUTPUT_MARKER` (whatever its
        files are called: :func:`is_output_directory`), written by another command, or one
        that contains the current directory; an existing file ``replaces`` refuses; a wrong
        suffix.
    """
    text = _nonempty(path, option)
    target = Path(text).resolve()
    if suffixes and target.suffix not in suffixes:
        raise ParameterError(f"{option} must end in {' or '.join(suffixes)}; "
                             f"got {text!r}")
    if target.parent == target:
        raise ParameterError(f"{option} must not be the root directory; got {text!r}")
    try:
        st = target.stat()
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise ParameterError(f"{option} {text!r} cannot be examined: {exc.strerror}") from exc
    parent = target.parent
    if not parent.is_dir():
        raise ParameterError(f"{option} {text!r}: its directory {str(parent)!r} does not exist "
                             "(create it first)")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ParameterError(f"{option} {text!r}: its directory {str(parent)!r} is not "
                             "writable")
    if st is None:
        return target
    if directory:
        if not stat.S_ISDIR(st.st_mode):
            raise ParameterError(f"{option} {text!r} exists and is {_kind(st.st_mode)}, not a "
                                 "directory")
        cwd = Path.cwd().resolve()
        if target == cwd or target in cwd.parents:
            raise ParameterError(f"{option} {text!r} contains the current directory; it would "
                                 "be replaced as a whole: choose a new directory")
        try:
            names = {p.name for p in target.iterdir()}
        except OSError as exc:
            raise ParameterError(f"{option} {text!r} cannot be read: {exc.strerror}") from exc
        if names and not is_output_directory(target):
            held = sorted(names)
            shown = ", ".join(held[:3]) + (", ..." if len(held) > 3 else "")
            raise ParameterError(f"{option} {text!r} exists and is not an ilc-analysis output "
                                 f"directory (it holds {shown} and no {OUTPUT_MARKER} marker); "
                                 "the run would replace it or write into it: choose a new or "
                                 "empty directory, or move its files away first")
        writer = marker_command(target) if names else None
        if command is not None and writer is not None and writer != command:
            raise ParameterError(f"{option} {text!r} holds the output of `{writer}` (its "
                                 f"{OUTPUT_MARKER} marker); `{command}` would replace it: "
                                 "choose a new or empty directory (one command never replaces "
                                 "another's results)")
        if not os.access(target, os.W_OK | os.X_OK):
            raise ParameterError(f"{option} {text!r} is not writable")
    elif not stat.S_ISREG(st.st_mode):
        raise ParameterError(f"{option} {text!r} exists and is {_kind(st.st_mode)}; expected "
                             "a file path")
    elif replaces is not None and (other := replaces(target)) is not None:
        raise ParameterError(f"{option} {text!r} exists and is {other}: it would be replaced; "
                             "choose another path, or move the file away first")
    return target


def check_input_file(path, option: str, max_bytes: int = MAX_INPUT_BYTES) -> Path:
    """Check that ``path`` is a readable regular file of at most ``max_bytes`` bytes.

    A directory, FIFO or device is refused before it is opened (reading a FIFO would block
    forever, a device may never end).

    Raises
    ------
    ParameterError
        Naming ``option``: missing, unreadable, not a regular file, or too large.
    """
    text = _nonempty(path, option)
    p = Path(text)
    try:
        st = p.stat()
    except FileNotFoundError as exc:
        raise ParameterError(f"{option} {text!r} does not exist") from exc
    except OSError as exc:
        raise ParameterError(f"{option} {text!r} cannot be examined: {exc.strerror}") from exc
    if not stat.S_ISREG(st.st_mode):
        raise ParameterError(f"{option} {text!r} is {_kind(st.st_mode)}; expected a regular "
                             "file")
    if st.st_size > max_bytes:
        raise ParameterError(f"{option} {text!r} has {st.st_size} bytes; at most {max_bytes} "
                             "are read")
    if not os.access(p, os.R_OK):
        raise ParameterError(f"{option} {text!r} is not readable (permission denied)")
    note_input(p, option)
    return p


@contextlib.contextmanager
def held_lock(target: Path, option: str, shown: str, *, timeout: float = 0.0,
              busy: str = "is being written by another ilc-analysis run") -> Iterator[Path]:
    """Context manager: hold the lock of ``target`` (the file ``.<name>.lock`` beside it).

    A :class:`filelock.FileLock` (``flock`` on Unix, ``LockFileEx`` on Windows; no
    :mod:`fcntl` import here, so the toolkit also starts where it is missing). The lock file
    is removed while still held when the block ends: a process that opened it meanwhile finds,
    once it gets the lock, that the file is unlinked and retries on a fresh one (filelock
    checks the link count), so removing it never lets two processes in.

    Parameters
    ----------
    target : Path
        The guarded file or directory (resolved).
    option, shown : str
        The option's name and the user's value, for the message.
    timeout : float
        Seconds to wait for the lock; 0 refuses at once if it is held.
    busy : str
        What the holder is doing, for the message.

    Raises
    ------
    OutputBusyError
        The lock is still held after ``timeout`` seconds.
    """
    from filelock import FileLock, Timeout

    lock_path = target.parent / f".{target.name}.lock"
    lock = FileLock(lock_path, timeout=timeout)
    try:
        lock.acquire()
    except Timeout as exc:
        waited = f" for {timeout:g} s" if timeout > 0 else ""
        raise OutputBusyError(f"{option} {shown!r} {busy} (lock {str(lock_path)!r} is held"
                              f"{waited}); wait for it to finish, then run the command again "
                              "(or choose another path)") from exc
    try:
        yield lock_path
    finally:
        with contextlib.suppress(OSError):     # Windows cannot remove an open file: it stays
            os.unlink(lock_path)
        lock.release()


def _remove_stale(target: Path) -> None:
    """Remove temporary siblings of ``target`` left by a killed run (SIGKILL, power loss).

    Only the holder of the lock creates them, so with the lock held none is in use."""
    for pattern in (f".{target.name}.tmp-*", f".{target.name}.old-*"):
        for stale in target.parent.glob(pattern):
            shutil.rmtree(stale, ignore_errors=True)


def _install_directory(tmp: Path, target: Path) -> None:
    """Move ``tmp`` to ``target``; an existing ``target`` is renamed aside, then removed."""
    if not target.exists():
        os.rename(tmp, target)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
    os.replace(target, old)                  # rename(2) may replace an empty directory
    try:
        os.rename(tmp, target)
    except BaseException:
        os.replace(old, target)
        raise
    shutil.rmtree(old, ignore_errors=True)


@contextlib.contextmanager
def output_directory(path, option: str = "--out", *,
                     command: str = "ilc-analysis") -> Iterator[Path]:
    """Context manager: a temporary directory that becomes ``path`` when the block succeeds.

    The target is checked first (:func:`check_output_path`) and locked for the whole block;
    the block writes into the yielded temporary directory (a sibling of ``path``), which
    already holds :data:`OUTPUT_MARKER` naming ``command``. On success it is renamed to
    ``path`` (an existing output directory there is replaced); on any exception,
    ``KeyboardInterrupt`` included, it is removed and ``path`` is untouched.

    Raises
    ------
    OutputBusyError
        Another run holds the lock of ``path``.
    ParameterError
        See :func:`check_output_path`.
    """
    shown = os.fspath(path) if isinstance(path, str | os.PathLike) else path
    target = check_output_path(path, option, directory=True, command=command)
    _refuse_inputs(target, option, shown, directory=True)
    with held_lock(target, option, shown):
        # as it is now, under the lock
        check_output_path(path, option, directory=True, command=command)
        _remove_stale(target)
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-", dir=target.parent))
        try:
            os.chmod(tmp, 0o777 & ~_umask())
            write_output_marker(tmp, command)
            yield tmp
            # a long run: what the user put at ``path`` meanwhile is refused, not removed
            check_output_path(path, option, directory=True, command=command)
            _refuse_inputs(target, option, shown, directory=True)
            _install_directory(tmp, target)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise


@contextlib.contextmanager
def output_file(path, option: str = "--out", *, suffixes: Collection[str] = (),
                replaces: Callable[[Path], str | None] | None = None,
                in_place: bool = False) -> Iterator[Path]:
    """Context manager: a temporary file (same directory and suffix) that replaces ``path``
    (:func:`os.replace`) when the block succeeds, and is removed if it fails.

    Parameters
    ----------
    path, option, suffixes, replaces
        As for :func:`check_output_path`.
    in_place : bool
        The file is an input of the run that the run updates (a learner's state file): it
        may be replaced although the run read it.

    Raises
    ------
    ParameterError
        See :func:`check_output_path`; the target is a file the run read
        (:func:`tracking_inputs`), unless ``in_place``.
    """
    shown = os.fspath(path) if isinstance(path, str | os.PathLike) else path
    target = check_output_path(path, option, suffixes=suffixes, replaces=replaces)
    if not in_place:
        _refuse_inputs(target, option, shown, directory=False)
    fd, name = tempfile.mkstemp(prefix=f".{target.stem}.tmp-", suffix=target.suffix,
                                dir=target.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        os.chmod(tmp, 0o666 & ~_umask())
        yield tmp
        if not in_place:
            _refuse_inputs(target, option, shown, directory=False)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
