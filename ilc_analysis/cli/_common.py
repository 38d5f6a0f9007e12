"""Options shared by the subcommands: model choice, parameter overrides, output format."""

from __future__ import annotations

import argparse
import contextlib
import errno
import json
import os
import re
import sys
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from .._output import check_input_file
from .._validation import MAX_ITERATIONS, MAX_LIFTED_ENTRIES, MAX_SUBSTEPS
from ..exceptions import ParameterError, ShapeError

if TYPE_CHECKING:
    from ..model import RobotParameters

__all__ = ["add_model_options", "plant_from_args", "params_from_args", "parse_vector",
           "model_parameters_from_args",
           "emit_json", "CLIError", "load_input", "c_stdout_to_stderr", "check_trial_length",
           "check_scenario_size", "write_stdout", "options_named", "add_progress_options",
           "progress_choice", "RegistryNames"]

T = TypeVar("T")
#: The registry model of ``--model`` when it is not given.
DEFAULT_MODEL = "planar"


class CLIError(ParameterError):
    """A bad command-line value; reported on stderr with exit code 2."""


class RegistryNames:
    """The names of the model registry (plus ``extra``) as an argparse ``choices``, read from
    :data:`ilc_analysis.model.BUILTIN_MODELS` only when argparse looks at them (a value to
    check, a command's help): building the parser, as ``ilc-analysis --help`` does for every
    command, imports no model (and so not python-control)."""

    def __init__(self, *extra: str) -> None:
        self.extra = extra

    def _names(self) -> list[str]:
        from ..model import BUILTIN_MODELS

        return sorted(set(BUILTIN_MODELS) | set(self.extra))

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __contains__(self, name: object) -> bool:
        return name in self._names()

    def __len__(self) -> int:
        return len(self._names())


def add_progress_options(parser: argparse.ArgumentParser, *, top_level: bool) -> None:
    """``--progress`` / ``--no-progress``: progress bars on stderr (default: only when stderr is
    a terminal, never with ``--json``; :mod:`ilc_analysis._progress`).

    Accepted before the command (``top_level``, default None: not given) and after it (the
    command's parser, where the default is suppressed so a flag given before the command is
    kept)."""
    parser.add_argument("--progress", action=argparse.BooleanOptionalAction,
                        default=None if top_level else argparse.SUPPRESS,
                        help="progress on stderr for long work (analysis, synthesis, "
                             "simulation, lead scan, study): bars on a terminal, one line per "
                             "stage of a synthesis elsewhere; default: shown unless --json is "
                             "given (bars only on a terminal; environment: ILC_PROGRESS=1 or 0)")
    parser.add_argument("--quiet", dest="progress", action="store_false",
                        default=None if top_level else argparse.SUPPRESS,
                        help="no progress output at all (the same as --no-progress)")


def progress_choice(args: argparse.Namespace) -> bool | None:
    """The progress setting the options ask for: True (``--progress``), False
    (``--no-progress``, or ``--json`` without ``--progress``: stderr stays clean for the
    program reading the JSON), else None (ILC_PROGRESS, then whether stderr is a terminal)."""
    chosen = getattr(args, "progress", None)
    if chosen is None and getattr(args, "json", False):
        return False
    return chosen


def add_model_options(parser: argparse.ArgumentParser) -> None:
    """--model (any name of the model registry) and repeated --param NAME=VALUE."""
    parser.add_argument("--model", choices=RegistryNames(), default=None,
                        help="built-in model of the registry (ilc_analysis.model."
                             f"BUILTIN_MODELS; default: {DEFAULT_MODEL})")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="override a parameter of the model, e.g. --param m=0.6 "
                             "(repeatable; the names are the model's: "
                             "ilc_analysis.model.BUILTIN_MODELS[name].defaults)")


def _param_overrides(args: argparse.Namespace, known) -> dict[str, float]:
    """The --param NAME=VALUE overrides as floats; names outside ``known`` are errors."""
    known = tuple(known)
    changes: dict[str, float] = {}
    for item in args.param:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise CLIError(f"--param expects NAME=VALUE; got {item!r}")
        if name not in known:
            model = (f" for model {args.model or DEFAULT_MODEL!r}" if hasattr(args, "model")
                     else "")
            raise CLIError(f"--param: unknown parameter {name!r}{model}; known: "
                           f"{', '.join(known) or '(none)'}")
        try:
            changes[name] = float(value)
        except ValueError as exc:
            raise CLIError(f"--param {name}: expected a number; got {value!r}") from exc
    return changes


def params_from_args(args: argparse.Namespace) -> RobotParameters:
    """RobotParameters with the --param overrides applied (unknown names are errors; a value
    the parameters refuse is a CLIError naming --param)."""
    from ..model import RobotParameters

    changes = _param_overrides(args, RobotParameters.names())
    with options_named(prefix="--param"):
        return RobotParameters().replace(**changes)


def model_parameters_from_args(args: argparse.Namespace) -> dict[str, float]:
    """The --param overrides of the registry model ``--model`` (names checked against it)."""
    from ..model import BUILTIN_MODELS

    return _param_overrides(args, BUILTIN_MODELS[args.model or DEFAULT_MODEL].defaults)


def plant_from_args(args: argparse.Namespace):
    """The Plant of the model registry selected by --model (default :data:`DEFAULT_MODEL`) and
    --param (a value the model refuses is a CLIError naming --param)."""
    from ..model import builtin_model

    changes = model_parameters_from_args(args)
    with options_named(prefix="--param"):
        return builtin_model(args.model or DEFAULT_MODEL, **changes)


@contextlib.contextmanager
def options_named(prefix: str | None = None, **options: str) -> Iterator[None]:
    """Name the command-line option in a ParameterError / ShapeError raised by the block.

    The package's validators name their own parameters (``lead``, ``shortlist``,
    ``q_cutoff``, ``bounds``...); at the command line the user typed an option. A message that
    starts with one of the names in ``options`` (``internal_name="--option"``) is re-raised as
    a :class:`CLIError` prefixed with that option; with ``prefix``, every such message is
    prefixed with it. Others pass through unchanged (they name a file's key already).

    Examples
    --------
    >>> with options_named(shortlist="--shortlist"):  # doctest: +SKIP
    ...     scan(shortlist=0)     # CLIError: --shortlist: shortlist ... must be an integer >= 1
    """
    try:
        yield
    except CLIError:
        raise
    except (ParameterError, ShapeError) as exc:
        text = str(exc)
        for name, option in options.items():
            if re.match(rf"{re.escape(name)}\b", text):
                raise CLIError(f"{option}: {text}") from exc
        if prefix is not None:
            raise CLIError(f"{prefix}: {text}") from exc
        raise


def parse_vector(text: str | None, size: int, name: str) -> np.ndarray | None:
    """Parse 'a,b,c' into a float vector of length ``size`` (None passes through)."""
    if text is None:
        return None
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as exc:
        raise CLIError(f"{name} expects {size} comma-separated numbers; got {text!r}") from exc
    if len(values) != size:
        raise CLIError(f"{name} expects {size} comma-separated numbers; got {len(values)}")
    if not all(np.isfinite(values)):
        raise CLIError(f"{name} expects {size} finite numbers (no nan or inf, nothing beyond "
                       f"the range of a double); got {text!r}")
    return np.array(values)


def _largest_trial(n_y: int, n_u: int) -> int:
    return int((MAX_LIFTED_ENTRIES / (n_y * n_u)) ** 0.5)


def check_trial_length(N: int, n_y: int, n_u: int, option: str, *, minimum: int = 1) -> int:
    r"""``N`` if the lifted matrix :math:`(N n_y) \times (N n_u)` fits
    :data:`~ilc_analysis._validation.MAX_LIFTED_ENTRIES`, else a CLIError naming ``option``
    with the largest N allowed for this plant (checked before anything is built)."""
    if isinstance(N, bool) or not isinstance(N, int | np.integer) or N < minimum:
        raise CLIError(f"{option} (trial length in samples) must be an integer >= {minimum}; "
                       f"got {N!r}")
    largest = _largest_trial(n_y, n_u)
    if N > largest:
        gib = N * n_y * N * n_u * 8 / 2**30
        raise CLIError(f"{option} {N}: the lifted matrix would take {gib:.3g} GiB; "
                       f"{option} must be at most {largest} for {n_u} input(s) and {n_y} "
                       "output(s)")
    return int(N)


def check_scenario_size(scenario, option: str = "--scenario") -> None:
    """Refuse a scenario whose trial length N = horizon / ts, iterations or RK4 sub-steps
    exceed the caps of :mod:`ilc_analysis._validation` (before any work: they set run time
    and memory), or whose u0 does not have one value per input of its model."""
    for name, cap in (("iterations", MAX_ITERATIONS), ("substeps", MAX_SUBSTEPS)):
        value = getattr(scenario, name)
        if value > cap:
            raise CLIError(f"{option}: {name} = {value} is too large; at most {cap}")
    try:
        N, plant = scenario.N, scenario.plant()
    except ParameterError as exc:
        raise CLIError(f"{option}: {exc}") from exc
    if len(scenario.u0) != plant.n_u:
        raise CLIError(f"{option}: u0 must hold {plant.n_u} value(s), one per input "
                       f"{list(plant.input_names)} of model {scenario.model!r}; got "
                       f"{len(scenario.u0)}")
    largest = _largest_trial(plant.n_y, plant.n_u)
    if N > largest:
        raise CLIError(f"{option}: the trial has N = horizon / ts = {N} samples; at "
                       f"most {largest} (the lifted matrix of {plant.n_u} input(s) and "
                       f"{plant.n_y} output(s) must fit in {MAX_LIFTED_ENTRIES} entries)")


def load_input(path, option: str, loader: Callable[[str], T]) -> T:
    """``loader(path)`` for an input file given by ``option``, every failure a CLIError.

    The file must be a readable regular file of bounded size
    (:func:`ilc_analysis._output.check_input_file`: a FIFO or device is refused before it is
    opened); undecodable text, nesting too deep for the parser and read errors become
    messages naming ``option``, as do the loader's own ParameterErrors.
    """
    check_input_file(path, option)          # its messages name the option already
    try:
        return loader(path)
    except ParameterError as exc:
        raise CLIError(f"{option}: {exc}") from exc
    except UnicodeDecodeError as exc:
        raise CLIError(f"{option} {path!r} is not UTF-8 text (byte {exc.start}: "
                       f"{exc.reason})") from exc
    except RecursionError as exc:
        raise CLIError(f"{option} {path!r} is nested too deeply to be read") from exc
    except OSError as exc:
        raise CLIError(f"{option} {path!r} cannot be read: {exc.strerror or exc}") from exc


class _Redirect:
    saved_fd: int | None = None
    """the real standard output while file descriptor 1 points at stderr"""


@contextlib.contextmanager
def c_stdout_to_stderr() -> Iterator[None]:
    """Point file descriptor 1 at standard error for the duration of the block.

    C and Fortran libraries (LAPACK's ``xerbla``, solvers) print to file descriptor 1
    directly; with ``--json`` such lines would corrupt the JSON document. Inside the block
    they go to stderr, and :func:`emit_json` writes to the real standard output.
    """
    with contextlib.suppress(Exception):
        sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:           # no file descriptor 1: nothing can corrupt it
        yield
        return
    try:
        os.dup2(2, 1)
    except OSError:
        os.close(saved)
        yield
        return
    previous, _Redirect.saved_fd = _Redirect.saved_fd, saved
    try:
        yield
    finally:
        with contextlib.suppress(Exception):
            sys.stdout.flush()
        _Redirect.saved_fd = previous
        os.dup2(saved, 1)
        os.close(saved)


@contextlib.contextmanager
def _real_stdout() -> Iterator[None]:
    saved = _Redirect.saved_fd
    if saved is None:
        yield
        return
    sys.stdout.flush()
    os.dup2(saved, 1)
    try:
        yield
        sys.stdout.flush()
    finally:
        os.dup2(2, 1)


def emit_json(obj) -> None:
    """Print ``obj`` as JSON on stdout (the real one, also inside :func:`c_stdout_to_stderr`).

    The document is serialised first, so an unserialisable value prints nothing."""
    text = json.dumps(obj, indent=2, allow_nan=False)
    with _real_stdout():
        write_stdout(text + "\n")


def write_stdout(text: str) -> None:
    """Write ``text`` to standard output in full, or raise BrokenPipeError.

    A large write to a pipe whose reader has gone away (``| head -c 10``) can be *partial*:
    the kernel accepts what fits in the pipe, and Python's buffered writer returns that count
    without an error, which ``sys.stdout.write`` ignores, so the rest was dropped silently and
    the command exited 0. Writing the bytes until all are accepted makes the next write fail
    with EPIPE, and :func:`~ilc_analysis.cli.main.main` exits 141 as documented.
    """
    buffer = getattr(sys.stdout, "buffer", None)
    if buffer is None:                      # a text-only stream (io.StringIO in a test)
        sys.stdout.write(text)
        return
    sys.stdout.flush()
    data = memoryview(text.encode(sys.stdout.encoding or "utf-8",
                                  errors=sys.stdout.errors or "strict"))
    while data:
        written = buffer.write(data)
        if written == 0:
            raise OSError(errno.EIO, "standard output accepts no more data")
        data = data[written if written is not None else len(data):]
    buffer.flush()
