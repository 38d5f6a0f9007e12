r"""Files and directories written all at once or not at all, and input files read within bounds.

An output is first written to a temporary sibling of its target (same directory, so the final
:func:`os.replace` is a rename on one file system) and moved into place only when everything
was written. On any failure — an exception, Ctrl-C (``KeyboardInterrupt``), ``SystemExit`` —
the temporary copy is removed and the target is left as it was. An existing output directory
is replaced as a whole: renamed aside, the new one renamed in, the old one removed.

A directory target is guarded by a lock file beside it (``.<name>.lock``, :func:`fcntl.flock`,
non-blocking): a second run into the same directory is refused at once
(:class:`OutputBusyError`) instead of mixing its files with the first run's. The lock file is
removed when the run ends (a run that finds the lock file replaced after locking it retries,
so removing it is safe). Temporary directories left by a killed run (SIGKILL) are removed by
the next run into the same target, which holds the lock.

Paths are checked before any work is done (:func:`check_output_path`,
:func:`check_input_file`); every error is a :class:`~ilc_analysis.exceptions.ParameterError`
naming the option.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import shutil
import stat
import tempfile
from collections.abc import Collection, Iterator
from pathlib import Path

from .exceptions import ParameterError

__all__ = ["OutputBusyError", "check_output_path", "check_input_file", "output_directory",
           "output_file", "OUTPUT_MARKER", "MAX_INPUT_BYTES"]

#: Name of the marker file written into every output directory. A directory holding it (or
#: empty, or holding only the names the command writes) may be replaced by the next run; any
#: other existing directory is refused, so ``--out ~`` cannot delete a home directory.
OUTPUT_MARKER = ".ilc-analysis-output"
#: Largest input file (gains, scenario) read, in bytes: a gains file of time-varying gains for
#: a 20 000-sample trial of a 2-input, 3-output plant is about 10 MB.
MAX_INPUT_BYTES = 16 * 2**20
_RETRIES = 3


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


def check_output_path(path, option: str, *, directory: bool = False,
                      suffixes: Collection[str] = (), known: Collection[str] = ()) -> Path:
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
    known : collection of str
        Names the command writes into a directory: an existing directory holding only these
        (or :data:`OUTPUT_MARKER`, or nothing) may be replaced.

    Raises
    ------
    ParameterError
        Empty path; an existing target of the wrong kind; a missing or read-only parent
        directory; an existing directory that is not an output directory, or that contains
        the current directory; a wrong suffix.
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
        foreign = sorted(names - set(known) - {OUTPUT_MARKER})
        if names and OUTPUT_MARKER not in names and foreign:
            shown = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
            raise ParameterError(f"{option} {text!r} exists and is not an ilc-analysis output "
                                 f"directory (it holds {shown}); the run replaces the "
                                 "directory as a whole: choose a new or empty directory")
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


def _lock(target: Path, option: str, shown: str) -> tuple[int, Path]:
    lock = target.parent / f".{target.name}.lock"
    busy = OutputBusyError(f"{option} {shown!r} is being written by another ilc-analysis run "
                           f"(lock {str(lock)!r} is held); wait for it to finish or choose "
                           "another directory")
    for _ in range(_RETRIES):
        fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise busy from exc
            raise
        try:
            same = os.stat(lock).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
            return fd, lock
        os.close(fd)       # the previous holder removed the file after we opened it: retry
    raise busy


def _unlock(fd: int, lock: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(lock)
    os.close(fd)


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
                     known: Collection[str] = ()) -> Iterator[Path]:
    """Context manager: a temporary directory that becomes ``path`` when the block succeeds.

    The target is checked first (:func:`check_output_path`) and locked for the whole block;
    the block writes into the yielded temporary directory (a sibling of ``path``). On success
    it is renamed to ``path`` (an existing output directory there is replaced); on any
    exception, ``KeyboardInterrupt`` included, it is removed and ``path`` is untouched.

    Raises
    ------
    OutputBusyError
        Another run holds the lock of ``path``.
    ParameterError
        See :func:`check_output_path`.
    """
    shown = os.fspath(path) if isinstance(path, str | os.PathLike) else path
    target = check_output_path(path, option, directory=True, known=known)
    fd, lock = _lock(target, option, shown)
    try:
        _remove_stale(target)
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-", dir=target.parent))
        try:
            os.chmod(tmp, 0o777 & ~_umask())
            (tmp / OUTPUT_MARKER).write_text(
                "Written by ilc-analysis. The next run into this directory replaces it as a "
                "whole.\n")
            yield tmp
            _install_directory(tmp, target)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
    finally:
        _unlock(fd, lock)


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
