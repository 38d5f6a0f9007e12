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
marker (or is empty): never because the names of its files look like the toolkit's (a user's
own ``summary.json`` is not an output of this toolkit).

Paths are checked before any work is done (:func:`check_output_path`,
:func:`check_input_file`); every error is a :class:`~ilc_analysis.exceptions.ParameterError`
naming the option.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile
from collections.abc import Collection, Iterator
from pathlib import Path

from ._version import __version__
from .exceptions import ParameterError

__all__ = ["OutputBusyError", "check_output_path", "check_input_file", "output_directory",
           "output_file", "held_lock", "is_output_directory", "write_output_marker",
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


def write_output_marker(directory: Path, command: str) -> None:
    """Write :data:`OUTPUT_MARKER` into ``directory``: what wrote it (``command``, e.g.
    ``'ilc-analysis simulate'``) and the toolkit's version. Its presence is what lets a later
    run replace the directory (:func:`check_output_path`)."""
    (Path(directory) / OUTPUT_MARKER).write_text(
        f"Written by {command} (ilc-analysis {__version__}). The next run into this "
        "directory may replace it as a whole; remove this file to protect the directory.\n")


def check_output_path(path, option: str, *, directory: bool = False,
                      suffixes: Collection[str] = ()) -> Path:
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

    Raises
    ------
    ParameterError
        Empty path; an existing target of the wrong kind; a missing or read-only parent
        directory; an existing non-empty directory without :data:`OUTPUT_MARKER` (whatever its
        files are called: :func:`is_output_directory`), or one that contains the current
        directory; a wrong suffix.
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
        if not os.access(target, os.W_OK | os.X_OK):
            raise ParameterError(f"{option} {text!r} is not writable")
    elif not stat.S_ISREG(st.st_mode):
        raise ParameterError(f"{option} {text!r} exists and is {_kind(st.st_mode)}; expected "
                             "a file path")
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
    target = check_output_path(path, option, directory=True)
    with held_lock(target, option, shown):
        check_output_path(path, option, directory=True)      # as it is now, under the lock
        _remove_stale(target)
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-", dir=target.parent))
        try:
            os.chmod(tmp, 0o777 & ~_umask())
            write_output_marker(tmp, command)
            yield tmp
            # a long run: what the user put at ``path`` meanwhile is refused, not removed
            check_output_path(path, option, directory=True)
            _install_directory(tmp, target)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise


@contextlib.contextmanager
def output_file(path, option: str = "--out", *,
                suffixes: Collection[str] = ()) -> Iterator[Path]:
    """Context manager: a temporary file (same directory and suffix) that replaces ``path``
    (:func:`os.replace`) when the block succeeds, and is removed if it fails.

    Raises
    ------
    ParameterError
        See :func:`check_output_path`.
    """
    target = check_output_path(path, option, suffixes=suffixes)
    fd, name = tempfile.mkstemp(prefix=f".{target.stem}.tmp-", suffix=target.suffix,
                                dir=target.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        os.chmod(tmp, 0o666 & ~_umask())
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
