"""``ilc-analysis model``: linearisation, eigenvalues, relative degree, Markov parameters.

Of a registry model (``--model``, ``--param``) or of the plant of a design file
(``ilc-analysis model design.toml``): the plant at the problem's initial state, and, when the
learning acts at a loop (``[problem.learning_at]``), also the continuous loop the learned signal
drives (:attr:`~ilc_analysis.problem.ILCProblem.continuous_composite`).
"""

from __future__ import annotations

import argparse

import numpy as np

from ..exceptions import InternalError
from ..model import DiscretePlant, ModelReport, model_report
from ..problem import PlantInput
from ..problem._compose import as_model
from ._common import CLIError, add_model_options, emit_json, parse_vector, plant_from_args
from ._design_support import add_design_argument, design_argument


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "model",
        description="Linearise a registry model (--model, --param) or the plant of a design "
                    "file (DESIGN.toml) at an operating point and report A, B, C, eigenvalues, "
                    "relative degree per output, Markov parameters (and, for the paper's "
                    "robot, the paper's printed errors). For a design whose learning acts at "
                    "a loop, the continuous loop the learned signal drives is reported too.")
    add_design_argument(p, "report on its plant at the problem's initial state")
    add_model_options(p)
    p.add_argument("--x0", metavar="X1,X2,...", help="operating-point state of the plant "
                   "(default: a registry model upright at rest; a design's [problem].x0)")
    p.add_argument("--u0", metavar="U1,...", help="operating-point input of the plant "
                   "(default: zero; a design learning at the plant input: its first nominal "
                   "input)")
    p.add_argument("--json", action="store_true", help="print a JSON object instead of text")
    p.set_defaults(run=run)


def _design_reports(args, design) -> list[tuple[str, ModelReport]]:
    """(label, ModelReport) of the design's plant and, learning at a loop, of that loop."""
    problem = design.problem
    if problem is None:
        raise InternalError("read_full_design refuses a design without a problem")
    plant = as_model(problem.plant, problem.ts)
    if isinstance(plant, DiscretePlant):
        raise CLIError(f"DESIGN {args.design!r}: its plant is sampled (dt = {problem.ts:g} s); "
                       f"'model' reports on continuous plants (eigenvalues in s, relative "
                       f"degree of the ODE). Use 'ilc-analysis lifted {args.design}' for the "
                       f"sampled trial's G")
    plant_input = isinstance(problem.learning_at, PlantInput)
    x0 = parse_vector(args.x0, plant.n_x, "--x0")
    u0 = parse_vector(args.u0, plant.n_u, "--u0")
    if x0 is None:
        x0 = np.asarray(problem.x0)[:plant.n_x]
    if u0 is None:
        u0 = np.asarray(problem.u_nominal)[0] if plant_input else np.zeros(plant.n_u)
    out = [("plant", model_report(plant, x0, u0, paper_defects=False))]
    loop = problem.continuous_composite
    if not plant_input and loop is not None:
        out.append(("loop", model_report(loop, np.asarray(problem.x0),
                                         np.asarray(problem.u_nominal)[0],
                                         paper_defects=False)))
    return out


def run(args: argparse.Namespace) -> int:
    design = design_argument(args, conflicts={"model": "--model", "param": "--param"})
    if design is None:
        plant = plant_from_args(args)
        x0 = parse_vector(args.x0, plant.n_x, "--x0")
        u0 = parse_vector(args.u0, plant.n_u, "--u0")
        report = model_report(plant, x0, u0)
        if args.json:
            emit_json(report.as_dict())
        else:
            print(report.to_text())
        return 0
    reports = _design_reports(args, design)
    problem = design.problem
    if problem is None:
        raise InternalError("read_full_design refuses a design without a problem")
    if args.json:
        data = reports[0][1].as_dict()
        if len(reports) > 1:
            data["loop"] = reports[1][1].as_dict()
        emit_json(data)
        return 0
    print(f"{args.design}: the plant of problem {problem.name!r}")
    print(reports[0][1].to_text())
    if len(reports) > 1:
        print()
        print(f"The loop the learned signal drives ({problem.learning_at.describe()['kind']}"
              f"; input: the learned signal, outputs: the plant outputs):")
        print(reports[1][1].to_text())
    return 0
