"""``ilc-analysis trial``: one trial of a design's simulation model, as the machine would log it.

The rehearsal of the machine loop: before the real machine, ``learn`` can be driven end to end
with this command standing in for it::

    ilc-analysis learn servo.toml --state state.json --out input_1.csv
    ilc-analysis trial servo.toml --input input_1.csv --out trial_1.csv
    ilc-analysis learn servo.toml --state state.json --measured trial_1.csv --out input_2.csv
    ilc-analysis trial servo.toml --input input_2.csv --out trial_2.csv --iteration 2
    ...

It reads the input ``learn`` wrote (``--input``: N rows, a header of the learned signal's
channel names, the feed-forward when the law has a current-trial part), runs one plant run of
the design's problem exactly as :func:`~ilc_analysis.simulation.simulate` runs trial
``--iteration`` (:class:`~ilc_analysis.simulation.SimulatedMachine`: the problem's sampled
plant, initial state, known disturbance, the law's current-trial feedback inside the trial,
the disturbance realisation of that iteration and seed) and writes the **full record**
``learn --measured`` expects: N + s rows, y(k) at t0 + k ts for k = 0..N+s-1, a header of the
output channel names, every value written exactly (shortest round-trip form). Driven this way
``learn`` reproduces ``simulate`` on the same design.

A design from measured FRF data runs on the model its ``[simulation]`` table names (as
``simulate`` does). A law with extra experiments per iteration (time reversal) asks ``learn``
for them in order: give ``--experiment K`` for the K-th (applied open loop, as on the machine).

Exit status: 0 written; 1 the trial diverged (a state beyond its bound or a non-finite value:
iteration, time and sample named; nothing written); 2 bad input (nothing written).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from .._output import check_output_path
from .._validation import MAX_ITERATIONS
from ..exceptions import DivergenceError, InternalError
from ..problem import ILCProblem
from ..simulation import DivergenceBounds, SimulatedMachine, read_trial_csv, write_input_csv
from ..simulation._divergence import first_violation
from ._common import CLIError, emit_json
from ._design_support import add_allow_code_option, read_run

__all__ = ["register", "run"]


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "trial",
        description="Run one trial of the design's simulation model on an input file (what "
                    "'learn' wrote) and write its record as the machine would log it: the file "
                    "'learn --measured' reads (N + s rows from t0, header = output names). "
                    "Rehearses the machine loop learn -> trial -> learn before the machine. "
                    "Exit status: 0 written, 1 the trial diverged (nothing written), 2 bad "
                    "input (nothing written).")
    p.add_argument("design", metavar="DESIGN.toml", help="design file (docs/design-file.md)")
    p.add_argument("--input", required=True, metavar="INPUT.csv",
                   help="the run's input: N rows, header = the learned signal's channel names "
                        "(as 'learn --out' writes it)")
    p.add_argument("--out", required=True, metavar="RECORD.csv",
                   help="the record to write: N + s rows from t0, header = output names "
                        "(replaced as a whole)")
    p.add_argument("--iteration", type=int, default=1, metavar="I",
                   help="the trial's number, from 1: the disturbance realisation it gets, as "
                        "in 'simulate' (default 1; without disturbances it changes nothing)")
    p.add_argument("--experiment", type=int, default=0, metavar="K",
                   help="0 the trial (default, current-trial feedback applied); K >= 1 the "
                        "K-th extra experiment of the iteration (time reversal), open loop")
    p.add_argument("--seed", type=int, default=None,
                   help="root seed of the noise streams (default: the design's "
                        "[problem.disturbances].seed, else fresh entropy, printed)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_allow_code_option(p)
    p.set_defaults(run=run)


def _check_options(args: argparse.Namespace) -> None:
    if not 1 <= args.iteration <= MAX_ITERATIONS:
        raise CLIError(f"--iteration must be an integer in [1, {MAX_ITERATIONS}] (the trial's "
                       f"number); got {args.iteration}")
    if args.experiment < 0:
        raise CLIError(f"--experiment must be 0 (the trial) or K >= 1 (an extra experiment); "
                       f"got {args.experiment}")
    if args.seed is not None and args.seed < 0:
        raise CLIError(f"--seed must be a non-negative integer (the root seed of the run's "
                       f"random streams); got {args.seed}")


def _diverged(machine: SimulatedMachine, rec, args: argparse.Namespace) -> str | None:
    """Where the run left the admissible region (the bounds of ``simulate``), or None."""
    dplant = machine.dplant
    hit = first_violation(rec.x, DivergenceBounds().limits(dplant.state_names))
    bad_y = np.flatnonzero(~np.isfinite(rec.y).all(axis=1))
    k = min(hit[0] if hit is not None else rec.x.shape[0],
            int(bad_y[0]) if bad_y.size else rec.x.shape[0])
    if k == rec.x.shape[0]:
        return None
    what = (f"state {dplant.state_names[hit[1]]} beyond its bound or non-finite"
            if hit is not None and hit[0] == k else "a non-finite output")
    return (f"the trial diverged in iteration {args.iteration} at t = {machine.t[k]:.6g} s "
            f"(sample {k}): {what}; nothing written")


def run(args: argparse.Namespace) -> int:
    _check_options(args)
    out = check_output_path(args.out, "--out")
    if out == Path(args.input).resolve():
        raise CLIError(f"--out {args.out!r} is also --input: the input would be overwritten; "
                       f"write the record elsewhere")
    problem, law = read_run(args.design, "DESIGN", allow_code=args.allow_code, simulation=True)
    if not isinstance(problem, ILCProblem):
        raise InternalError("read_run(simulation=True) gives an ILCProblem")
    u = read_trial_csv(args.input, problem.input_names, rows=problem.N, option="--input")
    machine = SimulatedMachine.from_problem(problem, law, entropy=args.seed)
    rec = machine.run(u, args.iteration, args.experiment)
    if (message := _diverged(machine, rec, args)) is not None:
        raise DivergenceError(message)
    write_input_csv(args.out, rec.y, problem.output_names, option="--out")
    run_name = ("trial" if args.experiment == 0 else
                f"extra experiment {args.experiment} (open loop)")
    if args.json:
        emit_json({"design": str(args.design), "input": str(args.input), "out": str(args.out),
                   "iteration": args.iteration, "experiment": args.experiment,
                   "rows": int(rec.y.shape[0]), "N": problem.N, "shift": problem.shift,
                   "output_names": list(problem.output_names), "seed": str(machine.entropy),
                   "feedback": machine.has_feedback and args.experiment == 0})
        return 0
    print(f"wrote {args.out}: the simulated {run_name} of iteration {args.iteration} on "
          f"{problem.name!r}, {rec.y.shape[0]} rows (N = {problem.N} + shift {problem.shift}) "
          f"from t0 = {problem.t0:g} s, columns {', '.join(problem.output_names)}")
    if machine.has_feedback and args.experiment == 0:
        print("the input was a feed-forward: the design's current-trial feedback was applied "
              "inside the trial, as the machine's loop would")
    if problem.disturbances is not None:
        print(f"disturbances: the realisation of iteration {args.iteration}, seed "
              f"{machine.entropy} (--seed to repeat it)")
    print(f"pass it to learn: ilc-analysis learn {args.design} --state STATE.json "
          f"--measured {args.out} --out NEXT.csv")
    return 0
