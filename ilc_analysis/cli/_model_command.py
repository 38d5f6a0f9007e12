"""``ilc-analysis model``: linearisation, eigenvalues, relative degree, Markov parameters."""

from __future__ import annotations

import argparse

from ..model import model_report
from ._common import add_model_options, emit_json, parse_vector, plant_from_args


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "model",
        description="Linearise a robot model at an operating point and report A, B, C, "
                    "eigenvalues, relative degree per output, Markov parameters and the paper's "
                    "printed errors.")
    add_model_options(p)
    p.add_argument("--x0", metavar="X1,X2,...", help="operating-point state (default: upright, "
                   "at rest)")
    p.add_argument("--u0", metavar="U1,...", help="operating-point input (default: zero)")
    p.add_argument("--json", action="store_true", help="print a JSON object instead of text")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    plant = plant_from_args(args)
    x0 = parse_vector(args.x0, plant.n_x, "--x0")
    u0 = parse_vector(args.u0, plant.n_u, "--u0")
    report = model_report(plant, x0, u0)
    if args.json:
        emit_json(report.as_dict())
    else:
        print(report.to_text())
    return 0
