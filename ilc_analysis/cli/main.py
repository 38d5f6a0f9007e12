"""Entry point of the ``ilc-analysis`` console command.

Exit status (every anticipated failure is one line on stderr, never a traceback):

* 0 — success;
* 1 — a numerical failure or a negative result: a solver failed (:class:`SolverError`), a
  certificate failed its re-check (:class:`CertificateError`), no certificate was found
  (``synthesize``; ``lead-scan``: no lead is certified), a learning run diverged
  (``reproduce``: the outputs are written and say where), the feedback loop learned on is
  unstable (:class:`UnstableLoopError`), out of memory, or an output could not be written;
* 2 — bad input (a message naming the option or parameter and the expected form), including
  an output directory that another run is writing;
* 130 — interrupted (Ctrl-C); 143 — terminated (SIGTERM). Partial outputs are removed;
* 141 — standard output was closed early (e.g. ``| head``); nothing more is printed.

Progress: long work (analysis, synthesis, simulation, lead scan, study) shows tqdm bars on
standard error when stderr is a terminal. ``--progress`` shows them anywhere (a log file, a
pipe), ``--no-progress`` never; ``--json`` implies ``--no-progress`` unless ``--progress`` is
given. Both flags are accepted before or after the command; without either, the environment
variable ``ILC_PROGRESS`` (1 or 0) decides before the terminal test.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys

from .._progress import set_progress
from ..exceptions import (
    CertificateError,
    DivergenceError,
    ILCError,
    SolverError,
    UnstableLoopError,
)
from ._common import add_progress_options, c_stdout_to_stderr, progress_choice

__all__ = ["main", "build_parser", "EXIT_OK", "EXIT_FAILURE", "EXIT_BAD_INPUT",
           "EXIT_INTERRUPTED", "EXIT_BROKEN_PIPE", "EXIT_TERMINATED"]

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2
#: 128 + SIGINT, 128 + SIGPIPE, 128 + SIGTERM: what a shell reports for those signals
EXIT_INTERRUPTED, EXIT_BROKEN_PIPE, EXIT_TERMINATED = 130, 141, 143

# One private module per subcommand (_<name>.py), each with register(subparsers); add a line
# to add a command.
_COMMAND_MODULES = (
    "_model_command",
    "_lifted_command",
    "_check_command",
    "_reproduce_command",
    "_synthesize_command",
    "_simulate_command",
    "_learn_command",
    "_lead_scan_command",
    "_study_command",
    "_design_frf_command",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ilc-analysis",
        description="Verify, synthesize and simulate iterative learning control laws "
                    "(Dong et al. 2019, open-closed-loop PD-ILC with a variable forgetting "
                    "factor).",
        epilog="Exit status: 0 success; 1 numerical failure or negative result (no "
               "certificate, solver failure, diverged run); 2 bad input; 130 interrupted.")
    add_progress_options(parser, top_level=True)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in _COMMAND_MODULES:
        importlib.import_module(f"{__package__}.{name}").register(sub)
    for command_parser in {id(p): p for p in sub.choices.values()}.values():
        add_progress_options(command_parser, top_level=False)
    return parser


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def _terminate(signum, frame):  # pragma: no cover - exercised through a subprocess
    raise SystemExit(EXIT_TERMINATED)


def _quiet_stdout() -> None:
    """After a broken pipe: point stdout at /dev/null so the interpreter's final flush is
    silent (the Python documentation's recipe for SIGPIPE)."""
    with contextlib.suppress(Exception):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit status (see the module docstring).

    Called without ``argv`` (the console command), SIGTERM is turned into a clean exit 143 so
    that partial outputs are removed as on Ctrl-C.
    """
    if argv is None:
        with contextlib.suppress(ValueError):       # not the main thread
            signal.signal(signal.SIGTERM, _terminate)
    command = "?"

    def fail(code: int, message: str) -> int:
        with contextlib.suppress(Exception):
            print(f"ilc-analysis {command}: {message}", file=sys.stderr, flush=True)
        return code

    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        command = args.command
        redirect = c_stdout_to_stderr() if getattr(args, "json", False) \
            else contextlib.nullcontext()
        chosen = progress_choice(args)
        previous = set_progress(chosen) if chosen is not None else None
        try:
            with redirect:
                code = int(args.run(args) or 0)
        finally:
            if chosen is not None:
                set_progress(previous)
        sys.stdout.flush()
        return code
    except KeyboardInterrupt:
        return fail(EXIT_INTERRUPTED, "interrupted")
    except BrokenPipeError:
        _quiet_stdout()
        return EXIT_BROKEN_PIPE
    except (SolverError, CertificateError, DivergenceError, UnstableLoopError) as exc:
        return fail(EXIT_FAILURE, f"failed: {_one_line(exc)}")
    except (ILCError, ValueError) as exc:
        return fail(EXIT_BAD_INPUT, f"error: {_one_line(exc)}")
    except RecursionError as exc:
        return fail(EXIT_BAD_INPUT, f"error: input nested too deeply ({_one_line(exc)})")
    except MemoryError:
        return fail(EXIT_FAILURE, "failed: out of memory (use a smaller trial length -N)")
    except OSError as exc:
        where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
        return fail(EXIT_FAILURE, f"failed: {exc.strerror or _one_line(exc)}{where}")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
