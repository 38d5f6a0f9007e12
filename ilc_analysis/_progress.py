r"""Progress bars for long work: tqdm on standard error, off unless someone is watching.

Every loop that may take more than a couple of seconds (a synthesis' iterations, the trials of
a simulation, the points of a study, the leads of a scan, the powers of :math:`T` in the
transient walk) runs inside :func:`progress`::

    with progress(total=len(items), desc="lead scan", unit="lead") as bar:
        for item in items:
            ...
            bar.update()

or, for a plain loop over a sequence, ``for item in tracked(items, desc="lead scan",
unit="lead"):``. Work made of a few long stages of different kinds (a synthesis: the model, the
proposal, the candidates, the certificate) reports them with :func:`stages`::

    with stages(4, desc="synthesize") as report:
        report.stage("building the model")
        ...
        report.note("about 40 s of work (N = 20000, 13 candidate leads)")
        report.stage("proposing the Q-filter (lead 16)")

so that someone watching can tell slow from stuck.

Whether a bar is shown (:func:`progress_enabled`), in order of precedence:

1. :func:`set_progress` ``(True | False)`` — the program's choice (the CLI's ``--progress`` /
   ``--no-progress``; ``--json`` implies ``--no-progress`` unless ``--progress`` is given);
2. the environment variable ``ILC_PROGRESS`` — ``1``/``true``/``yes``/``on`` or
   ``0``/``false``/``no``/``off``;
3. automatically: only when standard error is a terminal (never in a pipe, a log file, a
   test run or a batch job).

A bar asked for explicitly (1 or 2) is drawn at once; an automatic one only once its loop has
run for :data:`AUTO_DELAY` seconds (short loops leave the terminal alone). Bars are cleared
when their loop ends. Disabled, :func:`progress` yields an object whose methods do nothing, so
instrumented loops cost nothing measurable.

Stages (:func:`stages`) are shown wherever bars may be (1 or 2 above, or automatically): on a
terminal as a bar of stages with the current one after it, and where standard error is not a
terminal (a log file, a pipe, a batch job, a notebook) as one line per stage,
``synthesize: stage 2/4 proposing the Q-filter (lead 16)`` (automatic bars stay off there).
``set_progress(False)`` (the CLI's ``--no-progress`` and ``--quiet``) or ``ILC_PROGRESS=0``
silences them too.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import threading
from collections.abc import Iterable, Iterator
from typing import TypeVar

from .exceptions import ParameterError

__all__ = ["progress", "tracked", "stages", "current_stages", "StageReport", "set_progress",
           "progress_enabled", "silenced", "ProgressBar", "ENV_VARIABLE", "AUTO_DELAY"]

#: the environment variable that turns bars on (1) or off (0) when the program has not chosen
ENV_VARIABLE = "ILC_PROGRESS"
#: seconds an automatic bar (standard error is a terminal, nothing asked) waits before drawing
AUTO_DELAY = 2.0

_Item = TypeVar("_Item")
_TRUE = frozenset({"1", "true", "yes", "on"})
_FALSE = frozenset({"0", "false", "no", "off", ""})
_lock = threading.Lock()
_setting: list[bool | None] = [None]        # the program's choice; None: not chosen
_local = threading.local()                  # .silenced: depth of silenced() blocks (thread)


def set_progress(enabled: bool | None) -> bool | None:
    """Show progress bars (``True``), never show them (``False``), or decide from the
    environment and the terminal (``None``, the initial state; module docstring).

    Parameters
    ----------
    enabled : bool or None
        The choice; ``None`` returns to the automatic behaviour.

    Returns
    -------
    bool or None
        The previous choice (to restore it: ``set_progress(previous)``).

    Raises
    ------
    ParameterError
        ``enabled`` is not True, False or None.
    """
    if enabled is not None and not isinstance(enabled, bool):
        raise ParameterError(f"enabled must be True, False or None; got {enabled!r}")
    with _lock:
        previous, _setting[0] = _setting[0], enabled
    return previous


def _from_environment() -> bool | None:
    value = os.environ.get(ENV_VARIABLE)
    if value is None:
        return None
    word = value.strip().lower()
    if word in _TRUE:
        return True
    if word in _FALSE:
        return False
    raise ParameterError(f"environment variable {ENV_VARIABLE} must be 1 or 0 (or true/false, "
                         f"yes/no, on/off); got {value!r}")


def _stderr_is_terminal() -> bool:
    try:
        return bool(sys.stderr is not None and sys.stderr.isatty())
    except (AttributeError, ValueError, OSError):      # replaced, closed or detached stream
        return False


@contextlib.contextmanager
def silenced() -> Iterator[None]:
    """No bars from this thread inside the block, whatever the setting: for work that is
    itself one unit of an outer bar (a study's points run analyses and simulations; their
    own bars, in worker threads or processes, would only clutter the terminal)."""
    _local.silenced = getattr(_local, "silenced", 0) + 1
    try:
        yield
    finally:
        _local.silenced -= 1


def _choice() -> tuple[bool, bool]:
    """(shown, asked explicitly)."""
    if getattr(_local, "silenced", 0):
        return False, True
    with _lock:
        chosen = _setting[0]
    if chosen is not None:
        return chosen, True
    env = _from_environment()
    if env is not None:
        return env, True
    return _stderr_is_terminal(), False


def progress_enabled() -> bool:
    """Whether :func:`progress` shows a bar now (module docstring: the choice, then
    ``ILC_PROGRESS``, then whether standard error is a terminal).

    Returns
    -------
    bool

    Raises
    ------
    ParameterError
        ``ILC_PROGRESS`` is set to something other than 1/0, true/false, yes/no, on/off.
    """
    return _choice()[0]


class ProgressBar:
    """What :func:`progress` yields: :meth:`update`, :meth:`stage` and :meth:`set_postfix`,
    safe to call from several threads; a no-op when no bar is shown."""

    def __init__(self, bar=None) -> None:
        self._bar = bar
        self._lock = threading.Lock()

    @property
    def shown(self) -> bool:
        """Whether a bar is drawn (False: every method does nothing)."""
        return self._bar is not None

    def update(self, n: int | float = 1) -> None:
        """Advance the bar by ``n`` units.

        Parameters
        ----------
        n : int or float
            Units done since the last call (default 1).
        """
        if self._bar is not None:
            with self._lock:
                self._bar.update(n)

    def stage(self, text: str) -> None:
        """Show what the work is doing now after the bar (e.g. ``"frequency condition"``),
        redrawn at once: for work counted in a few long steps, whose bar would otherwise sit
        unchanged for the whole of a step.

        Parameters
        ----------
        text : str
            The stage, shown until the next call.
        """
        if self._bar is not None:
            with self._lock:
                self._bar.set_postfix_str(text, refresh=True)

    def set_postfix(self, **values) -> None:
        """Show ``name=value`` pairs after the bar (e.g. the current bound).

        Parameters
        ----------
        **values
            The pairs, shown in the order given.
        """
        if self._bar is not None:
            with self._lock:
                self._bar.set_postfix(values, refresh=False)


@functools.cache
def _tqdm_class():
    """tqdm without its monitor thread (it only shortens the refresh of a stalled bar, and a
    thread started from a library call outlives the call)."""
    from tqdm import tqdm

    class _Tqdm(tqdm):
        monitor_interval = 0

    return _Tqdm


@contextlib.contextmanager
def progress(total: int | None = None, *, desc: str, unit: str = "it") -> Iterator[ProgressBar]:
    """A progress bar on standard error for the block, if bars are shown
    (:func:`progress_enabled`); cleared when the block ends.

    Parameters
    ----------
    total : int, optional
        Number of units the loop will do (None: unknown; the bar counts without a percentage).
    desc : str
        What is being done (``"synthesis"``, ``"trials"``...), shown before the bar.
    unit : str
        Name of one unit (default ``"it"``).

    Yields
    ------
    ProgressBar
        Call ``update(n)`` as work is done.
    """
    shown, asked = _choice()
    if not shown:
        yield ProgressBar()
        return
    with _tqdm_class()(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
              dynamic_ncols=True, delay=0.0 if asked else AUTO_DELAY) as bar:
        yield ProgressBar(bar)


def tracked(items: Iterable[_Item], *, desc: str, unit: str = "it",
            total: int | None = None) -> Iterator[_Item]:
    """The items of ``items``, one :func:`progress` unit each (the bar closes when the loop
    ends, also on ``break`` or an exception).

    Parameters
    ----------
    items : iterable
        What the loop runs over.
    desc, unit
        As for :func:`progress`.
    total : int, optional
        Number of items (default ``len(items)`` when it has one).

    Yields
    ------
    object
        The items, unchanged.
    """
    if total is None:
        try:
            total = len(items)  # type: ignore[arg-type]
        except TypeError:                        # an iterator: no length
            total = None
    with progress(total=total, desc=desc, unit=unit) as bar:
        for item in items:
            yield item
            bar.update()


class StageReport:
    """What :func:`stages` yields: :meth:`stage` starts the next stage, :meth:`note` adds a line
    (an estimate); both do nothing when progress is off."""

    def __init__(self, total: int, desc: str, mode: str, bar=None) -> None:
        self._total, self._desc, self._mode, self._bar = total, desc, mode, bar
        self._count = 0
        self._lock = threading.Lock()

    @property
    def shown(self) -> bool:
        """Whether the stages are shown (False: every method does nothing)."""
        return self._mode != "off"

    @property
    def count(self) -> int:
        """Stages started so far."""
        return self._count

    def stage(self, text: str) -> None:
        """Start the next stage (numbered from 1 of the total), described by ``text``.

        Parameters
        ----------
        text : str
            What the stage does, e.g. ``"proposing the Q-filter (lead 16)"``.
        """
        with self._lock:
            self._count += 1
            line = f"{self._desc}: stage {self._count}/{self._total} {text}"
            if self._mode == "lines":
                _write_line(line)
            elif self._mode == "bar":
                self._bar.update(1 if self._count > 1 else 0)
                self._bar.set_postfix_str(f"{self._count}/{self._total} {text}", refresh=True)

    def update(self, text: str) -> None:
        """Say what the current stage is doing now (a line with the same stage number, or the
        bar's text), e.g. the next candidate of a stage that runs over several.

        Parameters
        ----------
        text : str
            The stage's new description.
        """
        with self._lock:
            line = f"{self._desc}: stage {max(self._count, 1)}/{self._total} {text}"
            if self._mode == "lines":
                _write_line(line)
            elif self._mode == "bar":
                self._bar.set_postfix_str(f"{max(self._count, 1)}/{self._total} {text}",
                                          refresh=True)

    def note(self, text: str) -> None:
        """A line of its own (e.g. how long the work will take), above the bar on a terminal.

        Parameters
        ----------
        text : str
            The line, printed after ``<desc>: ``.
        """
        with self._lock:
            if self._mode == "lines":
                _write_line(f"{self._desc}: {text}")
            elif self._mode == "bar":
                self._bar.write(f"{self._desc}: {text}", file=sys.stderr)


def _write_line(line: str) -> None:
    with contextlib.suppress(AttributeError, ValueError, OSError):    # a closed stream
        sys.stderr.write(line + "\n")        # progress goes to stderr, never stdout
        sys.stderr.flush()


@contextlib.contextmanager
def stages(total: int, *, desc: str) -> Iterator[StageReport]:
    """Report ``total`` stages of work (module docstring): a bar of stages on a terminal, one
    line per stage elsewhere, nothing when progress is off.

    Parameters
    ----------
    total : int
        The number of stages (>= 1).
    desc : str
        What is being done (``"synthesize"``), the start of every line.

    Yields
    ------
    StageReport
        Call ``stage(text)`` at the start of each stage.
    """
    if isinstance(total, bool) or not isinstance(total, int) or total < 1:
        raise ParameterError(f"total must be an integer >= 1 (the number of stages); got "
                             f"{total!r}")
    shown, asked = _choice()
    stack = _stage_stack()
    if not shown and asked:                    # off by choice, or silenced()
        report = StageReport(total, desc, "off")
    elif not _stderr_is_terminal():
        report = StageReport(total, desc, "lines")
    else:
        with _tqdm_class()(total=total, desc=desc, unit="stage", file=sys.stderr, leave=False,
                           dynamic_ncols=True, delay=0.0 if asked else AUTO_DELAY,
                           bar_format="{desc}: {n_fmt}/{total_fmt} stages [{elapsed}]"
                                      "{postfix}") as bar:
            report = StageReport(total, desc, "bar", bar)
            stack.append(report)
            try:
                yield report
            finally:
                stack.pop()
            bar.update(total - bar.n)
        return
    stack.append(report)
    try:
        yield report
    finally:
        stack.pop()


def _stage_stack() -> list:
    if not hasattr(_local, "stages"):
        _local.stages = []
    return _local.stages


def current_stages() -> StageReport:
    """The innermost :func:`stages` report of this thread (so that a function deep in the work
    can say which stage it is in), or one that shows nothing when there is none."""
    stack = _stage_stack()
    return stack[-1] if stack else StageReport(1, "", "off")
