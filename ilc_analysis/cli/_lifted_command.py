"""``ilc-analysis lifted``: the lifted matrices G, d (and the shift) of a robot model.

Nominal trial: the planar robot is lifted at the upright equilibrium at rest (u = 0), where the
nonlinear lifting equals the LTI lifting of the linearisation; the mobile robots are lifted
along the paper's circle (docs/theory.md §10) with the constant sustaining torques
(:func:`ilc_analysis.paper.circle_nominal`). ``--linearize`` lifts the exact zero-order-hold
discretisation of the upright linearisation instead.
"""

from __future__ import annotations

import argparse

import numpy as np

from .._output import check_output_path, output_file
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

#: Largest number of entries of G printed by ``--json`` (nested lists grow fast with N).
JSON_MAX_ENTRIES = 250_000
_DEFAULT_TS, _DEFAULT_N = 0.01, 200
_SUFFIXES = (".npz", ".mat")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "lifted",
        description="Build the lifted (trial-domain) matrices y = G u + d of a robot model: "
                    "the planar robot at the upright equilibrium, the mobile robots along the "
                    "paper's circle (X=1, Y=0, psi=pi/2, v=pi, psi_dot=pi, with the constant "
                    "torques that sustain it). Writes G, d, shift, ts, N to .npz or .mat.")
    add_model_options(p)
    p.add_argument("--ts", type=float, default=_DEFAULT_TS,
                   help=f"sample time in seconds (default {_DEFAULT_TS})")
    p.add_argument("-N", dest="N", type=int, default=_DEFAULT_N,
                   help=f"trial length in samples (default {_DEFAULT_N})")
    p.add_argument("--out", metavar="PATH", help="write G, d, shift, ts, N to PATH "
                   "(.npz for numpy, .mat for MATLAB)")
    p.add_argument("--json", action="store_true",
                   help=f"print a JSON object with keys G, d, shift, ts, N (small N only: at "
                        f"most {JSON_MAX_ENTRIES} entries of G)")
    p.add_argument("--linearize", action="store_true",
                   help="lift the zero-order-hold discretisation of the upright linearisation "
                        "(exact LTI Toeplitz) instead of the nonlinear RK4 plant")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    plant = plant_from_args(args)
    if args.out is not None:
        check_output_path(args.out, "--out", suffixes=_SUFFIXES)
    if args.N < 1:
        raise CLIError(f"-N (trial length in samples) must be >= 1; got {args.N}")
    if not (np.isfinite(args.ts) and args.ts > 0):
        raise CLIError(f"--ts (sample time) must be positive and finite; got {args.ts}")
    check_trial_length(args.N, plant.n_y, plant.n_u, "-N")
    n_entries = args.N * plant.n_y * args.N * plant.n_u
    if args.json and n_entries > JSON_MAX_ENTRIES:
        raise CLIError(f"G would have {n_entries} entries (N = {args.N}); too large for --json "
                       f"(at most {JSON_MAX_ENTRIES}). Use --out G.npz (or G.mat) or a smaller "
                       "-N")
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
    if args.out is not None:
        with output_file(args.out, "--out", suffixes=_SUFFIXES) as tmp:   # all or nothing
            sysl.save(tmp)
    if args.json:
        emit_json({"G": sysl.G.tolist(), "d": sysl.d.tolist(), "shift": sysl.shift,
                   "ts": sysl.ts, "N": sysl.N})
    else:
        print(f"{plant.name}: lifted along the {nominal}")
        print(f"  G: {sysl.G.shape[0]} x {sysl.G.shape[1]} ({sysl.kind}), shift s = "
              f"{sysl.shift}, ts = {sysl.ts:g} s, N = {sysl.N}")
        print(f"  inputs {list(sysl.input_names)}, outputs y(s..N-1+s) "
              f"{list(sysl.output_names)}")
        print(f"  max |G| = {np.max(np.abs(sysl.G)):.4g}, max |d| = "
              f"{np.max(np.abs(sysl.d)):.4g}")
        if args.out is not None:
            print(f"  wrote {args.out}")
    return 0
