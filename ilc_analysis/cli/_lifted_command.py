"""``ilc-analysis lifted``: the lifted matrices G, d (and the shift) of a model or a design.

A design file (``ilc-analysis lifted design.toml``): its problem's lifted system
:attr:`~ilc_analysis.problem.ILCProblem.lifted`, :math:`y = G v + d` from the learned signal
(the plant input, or the loop's reference or input) to the plant outputs on the problem's
window, lifted along its nominal trajectory; N, ts and the shift are the problem's.

Nominal trial: the planar robot is lifted at the upright equilibrium at rest (u = 0), where the
nonlinear lifting equals the LTI lifting of the linearisation; the mobile robots are lifted
along the paper's circle (docs/theory.md §10) with the constant sustaining torques
(:func:`ilc_analysis.paper.circle_nominal`). ``--linearize`` lifts the exact zero-order-hold
discretisation of the upright linearisation instead.
"""

from __future__ import annotations

import argparse

import numpy as np

from .._array_files import other_arrays
from .._output import check_not_inputs, check_output_path, output_file
from ..lifting import lift
from ..model import discretize
from ..paper._circle import CIRCLE_STATE_NAMES, circle_nominal
from ._common import (
    CLIError,
    add_model_options,
    check_trial_length,
    emit_json,
    plant_from_args,
)
from ._design_support import add_design_argument, design_argument

#: Largest number of entries of G printed by ``--json`` (nested lists grow fast with N).
JSON_MAX_ENTRIES = 250_000
_DEFAULT_TS, _DEFAULT_N = 0.01, 200
_CONFLICTS = {"model": "--model", "param": "--param", "ts": "--ts", "N": "-N",
              "linearize": "--linearize"}
_SUFFIXES = (".npz", ".mat")


#: what ``--out`` may replace: a file of the arrays LiftedSystem.save writes
_LIFTED_ARRAYS = other_arrays(("G", "d", "shift", "ts", "N", "n_u", "n_y", "t0", "kind",
                               "input_names", "output_names", "u_nominal"))

def register(subparsers) -> None:
    p = subparsers.add_parser(
        "lifted",
        description="Build the lifted (trial-domain) matrices y = G u + d of a design file's "
                    "problem (DESIGN.toml: its plant, loop, trial and nominal trajectory) or of "
                    "a registry model: the planar robot at the upright equilibrium, the mobile "
                    "robots along the paper's circle (X=1, Y=0, psi=pi/2, v=pi, psi_dot=pi, "
                    "with the constant torques that sustain it). Writes G, d, shift, ts, N to "
                    ".npz or .mat.")
    add_design_argument(p, "lift its problem (N, ts, shift and nominal trajectory are the "
                           "problem's)")
    add_model_options(p)
    p.add_argument("--ts", type=float, default=None,
                   help=f"sample time in seconds of a registry model (default {_DEFAULT_TS})")
    p.add_argument("-N", dest="N", type=int, default=None,
                   help=f"trial length in samples of a registry model (default {_DEFAULT_N})")
    p.add_argument("--out", metavar="PATH", help="write G, d, shift, ts, N to PATH "
                   "(.npz for numpy, .mat for MATLAB)")
    p.add_argument("--json", action="store_true",
                   help=f"print a JSON object with keys G, d, shift, ts, N (small N only: at "
                        f"most {JSON_MAX_ENTRIES} entries of G)")
    p.add_argument("--linearize", action="store_true",
                   help="lift the zero-order-hold discretisation of the upright linearisation "
                        "(exact LTI Toeplitz) instead of the nonlinear RK4 plant")
    p.set_defaults(run=run)


def _check_json_size(args, N: int, n_y: int, n_u: int, option: str) -> None:
    n_entries = N * n_y * N * n_u
    if args.json and n_entries > JSON_MAX_ENTRIES:
        raise CLIError(f"G would have {n_entries} entries (N = {N}); too large for --json "
                       f"(at most {JSON_MAX_ENTRIES}). Use --out G.npz (or G.mat) or a smaller "
                       f"{option}")


def _design_lifted(args, design):
    """(lifted system, label, nominal text) of a design's problem."""
    problem = design.problem
    check_trial_length(problem.N, problem.n_y, problem.n_u, "[problem].N")
    _check_json_size(args, problem.N, problem.n_y, problem.n_u, "[problem].N")
    kind = problem.learning_at.describe()["kind"]
    nominal = ("problem's nominal trajectory (LTI: exact)" if problem.is_lti else
               "problem's nominal trajectory (Jacobian of the sampled trial)")
    return problem.lifted, f"{args.design}: problem {problem.name!r} (learning at {kind})", \
        nominal


def _print(sysl, label: str, nominal: str, out) -> None:
    print(f"{label}: lifted along the {nominal}")
    print(f"  G: {sysl.G.shape[0]} x {sysl.G.shape[1]} ({sysl.kind}), shift s = "
          f"{sysl.shift}, ts = {sysl.ts:g} s, N = {sysl.N}")
    print(f"  inputs {list(sysl.input_names)}, outputs y(s..N-1+s) "
          f"{list(sysl.output_names)}")
    print(f"  max |G| = {np.max(np.abs(sysl.G)):.4g}, max |d| = "
          f"{np.max(np.abs(sysl.d)):.4g}")
    if out is not None:
        print(f"  wrote {out}")


def run(args: argparse.Namespace) -> int:
    if args.out is not None:            # before the design is built or anything computed
        check_output_path(args.out, "--out", suffixes=_SUFFIXES, replaces=_LIFTED_ARRAYS)
        check_not_inputs({"--out": args.out}, {"DESIGN": args.design})
    design = design_argument(args, conflicts=_CONFLICTS)
    if design is None:
        args.N = _DEFAULT_N if args.N is None else args.N
        args.ts = _DEFAULT_TS if args.ts is None else args.ts
        sysl, label, nominal = _model_lifted(args)
    else:
        sysl, label, nominal = _design_lifted(args, design)
    if args.out is not None:
        with output_file(args.out, "--out", suffixes=_SUFFIXES,      # all or nothing
                         replaces=_LIFTED_ARRAYS) as tmp:
            sysl.save(tmp)
    if args.json:
        emit_json({"G": sysl.G.tolist(), "d": sysl.d.tolist(), "shift": sysl.shift,
                   "ts": sysl.ts, "N": sysl.N})
    else:
        _print(sysl, label, nominal, args.out)
    return 0


def _model_lifted(args):
    """(lifted system, label, nominal text) of the registry model of --model / --param."""
    plant = plant_from_args(args)
    if args.N < 1:
        raise CLIError(f"-N (trial length in samples) must be >= 1; got {args.N}")
    if not (np.isfinite(args.ts) and args.ts > 0):
        raise CLIError(f"--ts (sample time) must be positive and finite; got {args.ts}")
    check_trial_length(args.N, plant.n_y, plant.n_u, "-N")
    _check_json_size(args, args.N, plant.n_y, plant.n_u, "-N")
    if args.linearize:
        sysl = lift(discretize(plant.linearize(), args.ts), args.N)
        nominal = "zoh discretisation of the upright linearisation"
    elif tuple(plant.state_names) == CIRCLE_STATE_NAMES:
        circle = circle_nominal(plant, args.N, args.ts)
        sysl = lift(discretize(plant, args.ts), args.N, x0=circle.x0,
                    u_nominal=circle.u_nominal)
        nominal = ("paper's circle, constant torques "
                   f"{np.array2string(circle.u, precision=6)}")
    else:
        sysl = lift(discretize(plant, args.ts), args.N)
        nominal = "upright equilibrium at rest (u = 0)"
    return sysl, plant.name, nominal
