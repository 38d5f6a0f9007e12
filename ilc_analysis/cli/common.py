"""Options shared by the subcommands: model choice, parameter overrides, output format."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from ..exceptions import ParameterError
from ..model import ROBOT_MODELS, RobotParameters, robot_model

__all__ = ["add_model_options", "plant_from_args", "params_from_args", "parse_vector",
           "emit_json", "CLIError"]


class CLIError(ParameterError):
    """A bad command-line value; reported on stderr with exit code 2."""


def add_model_options(parser: argparse.ArgumentParser) -> None:
    """--model and repeated --param NAME=VALUE."""
    parser.add_argument("--model", choices=sorted(ROBOT_MODELS), default="planar",
                        help="built-in robot model (default: planar)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="override a robot parameter, e.g. --param m=0.6 (repeatable); "
                             f"names: {', '.join(RobotParameters.names())}")


def params_from_args(args: argparse.Namespace) -> RobotParameters:
    """RobotParameters with the --param overrides applied (unknown names are errors)."""
    changes: dict[str, float] = {}
    for item in args.param:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise CLIError(f"--param expects NAME=VALUE; got {item!r}")
        if name not in RobotParameters.names():
            raise CLIError(f"--param: unknown parameter {name!r}; known: "
                           f"{', '.join(RobotParameters.names())}")
        try:
            changes[name] = float(value)
        except ValueError as exc:
            raise CLIError(f"--param {name}: expected a number; got {value!r}") from exc
    return RobotParameters().replace(**changes)


def plant_from_args(args: argparse.Namespace):
    """The robot Plant selected by --model and --param."""
    return robot_model(args.model, params_from_args(args))


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
    return np.array(values)


def emit_json(obj) -> None:
    """Print ``obj`` as JSON on stdout."""
    json.dump(obj, sys.stdout, indent=2, allow_nan=False)
    sys.stdout.write("\n")
