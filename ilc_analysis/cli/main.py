"""Entry point of the ``ilc-analysis`` console command.

Exit status (every anticipated failure is one line on stderr, never a traceback):

* 0 — success;
* 1 — a numerical failure or a negative result: a solver failed (:class:`SolverError`), a
  certificate failed its re-check (:class:`CertificateError`), no certificate was found
  (``synthesize``; ``lead-scan``: no lead is certified), a learning run diverged
  (``reproduce``: the outputs are written and say where), the feedback loop learned on is
  unstable (:class:`UnstableLoopError`), out of memory, or an output could not be written;
* 2 — bad input (a message naming the option or parameter and the expected form), including
  an output directory that another run is writing, or an optional extra the command needs
  and the install lacks (the message names it: ``ilc-analysis[studies]`` for ``study``);
* 130 — interrupted (Ctrl-C); 143 — terminated (SIGTERM). Partial outputs are removed;
* 141 — standard output was closed early (e.g. ``| head``); nothing more is printed.

Progress: long work (analysis, synthesis, simulation, lead scan, study) shows tqdm bars on
standard error when stderr is a terminal. ``--progress`` shows them anywhere (a log file, a
pipe), ``--no-progress`` never; ``--json`` implies ``--no-progress`` unless ``--progress`` is
given. Both flags are accepted before or after the command; without either, the environment
variable ``ILC_PROGRESS`` (1 or 0) decides before the terminal test. ``reproduce``'s stage lines
follow the same choice.

``ilc-analysis --version`` prints the package's version (:data:`ilc_analysis.__version__`).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys

from .._output import tracking_inputs
from .._progress import set_progress
from .._validation import printable
from .._version import __version__
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

#: command -> (its private module, which has register(subparsers); the line ``ilc-analysis
#: --help`` shows for it). Add a line to add a command. A command's module is imported only to
#: run the command or show its own help (and by build_parser() for the documentation):
#: ``ilc-analysis --help`` imports none of them, and so none of the libraries they need
#: (python-control, matplotlib, CasADi...; tests/test_lazy_imports.py).
_COMMANDS = {
    "model": ("_model_command", "report on a model's or a design's plant (linearisation)"),
    "lifted": ("_lifted_command",
               "lifted trial matrices y = G u + d of a model or a design's problem"),
    "check": ("_check_command",
              "re-verify a design file's certificate, or the conditions of a gain set"),
    "reproduce": ("_reproduce_command",
                  "run the paper's Section 5 scenario and write figures and a report"),
    "synthesize": ("_synthesize_command",
                   "synthesise certified learning gains (cvxpy / lifted / frequency)"),
    "simulate": ("_simulate_command",
                 "simulate learning trials of a design file (netCDF + figures)"),
    "learn": ("_learn_command", "per-trial learning on a real machine, through CSV files"),
    "trial": ("_trial_command",
              "one simulated trial of a design on an input file: the record learn reads"),
    "lead-scan": ("_lead_scan_command",
                  "synthesise gains per candidate lead and predict each one's floor"),
    "study": ("_study_command",
              "run a robustness / design study (design x variations) on Dask"),
    "design-frf": ("_design_frf_command",
                   "design a Q/L law from FRF measurement files, with its certificate"),
    "identify": ("_identify_command",
                 "identify the lifted model (Markov parameters, bounds) from recorded trials"),
    "export": ("_export_command",
               "write a certified design's law as C99 for the machine's processor"),
}
_COMMAND_MODULES = tuple(module for module, _ in _COMMANDS.values())


class _Commands:
    """The subparsers as a command module's ``register`` sees them: ``add_parser(name, ...)``
    gives the command its line of :data:`_COMMANDS` as its help."""

    def __init__(self, subparsers) -> None:
        self._subparsers = subparsers

    def add_parser(self, name: str, **kwargs) -> argparse.ArgumentParser:
        # a help= of the module's own would differ from what `ilc-analysis --help` shows:
        # tests/test_lazy_imports.py compares the two listings
        kwargs.setdefault("help", _COMMANDS[name][1])
        return self._subparsers.add_parser(name, **kwargs)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of the command line.

    Parameters
    ----------
    command : str, optional
        None (the documentation's CLI pages): every command's parser in full. A command's name:
        that command's parser in full and the others as their one line of help only, so that
        only the module of the command that runs is imported; ``''``: all of them as their line
        of help.
    """
    parser = argparse.ArgumentParser(
        prog="ilc-analysis",
        description="Iterative learning control for your plant: from a design file (the "
                    "plant as a transfer function, state space, ODE, FRF data or recorded "
                    "trials; the reference; where learning acts: the plant input or your "
                    "feedback loop's reference or input; the law), check whether the law "
                    "converges (a proof or 'unknown', with what to change), synthesise "
                    "certified gains, simulate trials, and run the law trial by trial on the "
                    "machine (learn; trial rehearses the loop). The paper of Dong et al. "
                    "(2019) is the worked case (reproduce).",
        epilog="Exit status: 0 success; 1 numerical failure or negative result (no "
               "certificate, solver failure, diverged run); 2 bad input; 130 interrupted.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}",
                        help="print the version of ilc-analysis and exit")
    add_progress_options(parser, top_level=True)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (module, help_line) in _COMMANDS.items():
        if command is None or command == name:
            importlib.import_module(f"{__package__}.{module}").register(_Commands(sub))
        else:
            sub.add_parser(name, help=help_line)
    for command_parser in {id(p): p for p in sub.choices.values()}.values():
        add_progress_options(command_parser, top_level=False)
    return parser


def _command_in(argv: list[str]) -> str:
    """The command ``argv`` names: its first word that is not an option (the options before
    the command take no value), or ``''`` when there is none or it is not a command (argparse
    then says so, listing the commands)."""
    word = next((a for a in argv if not a.startswith("-")), "")
    return word if word in _COMMANDS else ""


#: most characters of the one line a failure prints (the rest is counted, not printed)
MAX_MESSAGE_CHARS = 2000


def _one_line(exc: BaseException) -> str:
    """The message of ``exc`` as one printable line of bounded length: control characters a
    file smuggled into it (a terminal's escape sequences) escaped, at most
    :data:`MAX_MESSAGE_CHARS` characters."""
    text = printable(" ".join(str(exc).split())) or type(exc).__name__
    if len(text) > MAX_MESSAGE_CHARS:
        text = f"{text[:MAX_MESSAGE_CHARS]}... ({len(text) - MAX_MESSAGE_CHARS} more characters)"
    return text


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
        argv = sys.argv[1:] if argv is None else list(argv)
        parser = build_parser(_command_in(argv))
        args = parser.parse_args(argv)
        command = args.command
        redirect = c_stdout_to_stderr() if getattr(args, "json", False) \
            else contextlib.nullcontext()
        chosen = progress_choice(args)
        previous = set_progress(chosen) if chosen is not None else None
        try:
            with redirect, tracking_inputs():    # no output replaces a file the run reads
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
