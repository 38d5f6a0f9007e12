"""What the design-file commands share: reading a design from a command-line argument.

A design file (:mod:`ilc_analysis.design`, ``docs/design-file.md``) holds the plant, the ILC
problem, the law and its certificate. The commands are thin layers over
:func:`~ilc_analysis.design.load_design` / :func:`~ilc_analysis.design.save_design`,
:meth:`~ilc_analysis.design.Design.check`, :func:`~ilc_analysis.simulation.simulate` and
:class:`~ilc_analysis.simulation.Learner`; the paper scenario's designs are
:mod:`ilc_analysis.paper._designs`.
"""

from __future__ import annotations

import argparse
import functools

from ..design import Design, load_design
from ..exceptions import ParameterError
from ._common import CLIError, load_input

__all__ = ["read_design", "read_full_design", "read_run", "is_frf_design_file", "first_trial",
           "baseline_hint", "add_allow_code_option", "add_design_argument", "design_argument",
           "register_scenarios"]

#: help of --allow-code (every command that reads a design file has it)
ALLOW_CODE_HELP = ("let this run import and call the Python function a design file names "
                   "([plant] module = 'package.module:function') or deserialise the CasADi "
                   "plant it holds ([plant] casadi = '...', which can load native code); "
                   "without it such a file is refused (exit 2) and nothing is imported. Only "
                   "for files you trust (docs/design-file.md, 'Trust model')")


def add_allow_code_option(parser: argparse.ArgumentParser) -> None:
    """``--allow-code``: the explicit, per-run opt-in to code named by a design file
    (:func:`~ilc_analysis.design.load_design`'s ``allow_code``)."""
    parser.add_argument("--allow-code", action="store_true", dest="allow_code",
                        help=ALLOW_CODE_HELP)


def register_scenarios() -> tuple:
    """Register the scenarios the command line knows by name, so that a design or study file
    can name them (the generic stages import no scenario themselves): the paper's,
    ``"paper"``, which :mod:`ilc_analysis.paper` registers when it is imported.

    Returns
    -------
    tuple of ~ilc_analysis.design.Scenario
        The scenarios registered.
    """
    from ..paper._signals import PAPER_SCENARIO  # importing the paper registers it

    return (PAPER_SCENARIO,)


def read_design(path, option: str = "DESIGN", *, allow_code: bool = False) -> Design:
    """:func:`~ilc_analysis.design.load_design` of a command-line argument; every failure is a
    :class:`CLIError` naming ``option`` (exit 2): missing or unreadable file, bad TOML, and
    every :class:`~ilc_analysis.exceptions.DesignFileError` (key path and expected form; a
    module plant without ``allow_code``, i.e. ``--allow-code``, says how to opt in). The
    scenarios of :func:`register_scenarios` are nameable."""
    register_scenarios()
    return load_input(path, option, functools.partial(load_design, allow_code=allow_code))


def read_full_design(path, option: str = "DESIGN", *, allow_code: bool = False) -> Design:
    """:func:`read_design`, refusing an old gains file (it names no plant or problem)."""
    design = read_design(path, option, allow_code=allow_code)
    if design.problem is None:
        raise CLIError(f"{option} {str(path)!r} is an old gains file: it holds the gains but no "
                       f"plant, problem or reference; use a design file (docs/design-file.md; "
                       f"'ilc-analysis synthesize --out design.toml' writes one)")
    return design


def is_frf_design_file(path) -> bool:
    """The file is a design from FRF data (``[plant].frf``); False for anything unreadable
    (the ordinary path then reports why)."""
    from .._validation import read_toml_file
    from ..design import is_frf_design

    try:
        return is_frf_design(read_toml_file(path, "design file"))
    except (ParameterError, OSError):
        return False


def read_run(path, option: str = "DESIGN", *, allow_code: bool = False,
             simulation: bool = False) -> tuple:
    """``(problem, law)`` a design file runs (``learn``, ``simulate``), every failure a
    :class:`CLIError` naming ``option``: a design file's problem and law
    (:func:`read_full_design`), or for a design from FRF data
    :func:`~ilc_analysis.design.load_frf_run`: with ``simulation`` the problem on its
    ``[simulation]`` model, else the machine's model-free trial
    (:class:`~ilc_analysis.problem.TrialSpec`)."""
    if is_frf_design_file(path):
        from ..design import load_frf_run

        return load_input(path, option, functools.partial(
            load_frf_run, simulation=simulation, allow_code=allow_code))
    design = read_full_design(path, option, allow_code=allow_code)
    return design.problem, design.law


def first_trial(problem) -> str:
    """What the first trial of a run runs (``ILCProblem.first_trial``; a model-free trial of
    FRF data starts from zero input)."""
    return getattr(problem, "first_trial", "zero input")


def baseline_hint(problem) -> str | None:
    """A reminder for a run that starts from zero input at the plant input of a square plant:
    when that plant is a closed loop whose input is its reference, the honest first trial is
    the loop alone (``[problem] initial_input = "reference"``); None otherwise (a loop of the
    problem's own, a given first input, a non-square plant, or a trial without a model)."""
    from ..problem import ILCProblem, PlantInput

    if not isinstance(problem, ILCProblem) or not isinstance(problem.learning_at, PlantInput) \
            or problem.first_trial != "zero input" or problem.n_u != problem.n_y:
        return None
    return ("trial 1 ran zero input (the plant's free response). If the plant's input is the "
            "reference of its own feedback loop, start from the loop alone: [problem] "
            "initial_input = \"reference\" (Python: ILCProblem(..., u_initial=\"reference\"))")


def add_design_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """The optional positional ``DESIGN.toml`` of a command that also works on a built-in model
    (``model``, ``lifted``, ``lead-scan``), and ``--allow-code`` for the design's plant."""
    parser.add_argument("design", nargs="?", metavar="DESIGN.toml", default=None,
                        help=f"a design file (docs/design-file.md): {what} (its law and "
                             f"certificate are not used)")
    add_allow_code_option(parser)


def design_argument(args: argparse.Namespace, *, conflicts: dict[str, str]) -> Design | None:
    """The design of the positional ``DESIGN.toml`` (:func:`read_full_design`), or None when
    it is not given; ``conflicts`` maps an attribute of ``args`` to its option, and each one
    that is set (not None, not empty, not False) alongside a design is a :class:`CLIError`: the
    design fixes what the option would choose (``--model`` and ``--param`` name another plant;
    ``--ts`` and ``-N`` another trial)."""
    if args.design is None:
        if args.allow_code:
            raise CLIError("--allow-code applies to a design file (DESIGN.toml) only: the "
                           "built-in models run no user code")
        return None
    given = [option for attr, option in conflicts.items()
             if getattr(args, attr, None) not in (None, [], False)]
    if given:
        raise CLIError(f"{', '.join(given)}: not with a design file ({args.design!r} names its "
                       f"own plant and problem); give either DESIGN.toml or "
                       f"{' / '.join(conflicts.values())}")
    return read_full_design(args.design, "DESIGN", allow_code=args.allow_code)
