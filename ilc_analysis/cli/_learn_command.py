"""``ilc-analysis learn``: drive a real machine trial by trial from its logs.

A thin layer over :class:`ilc_analysis.simulation.Learner` (its state survives between
processes in the ``--state`` file) and the toolkit's CSV format
(:func:`~ilc_analysis.simulation.read_trial_csv`, :func:`~ilc_analysis.simulation.write_input_csv`:
a header line of channel names, one row per sample)::

    ilc-analysis learn design.toml --state state.json --out input_1.csv       # first trial
    # ... the machine runs input_1.csv and logs its outputs to trial_1.csv ...
    ilc-analysis learn design.toml --state state.json --measured trial_1.csv --out input_2.csv

* ``--out``: the next run's input, ``(N, n_u)`` at times t0 + k ts, k = 0..N-1, columns
  ``problem.input_names``; for a PD law with current-trial gains it is the feed-forward to which
  the machine's loop adds the feedback (the command says so);
* ``--measured``: the **full record** of the run, N + s rows (y(k) at t0 + k ts,
  k = 0..N+s-1, the same clock as the input), columns ``problem.output_names``; the learner cuts
  the output window itself and refuses any other length;
* a law with extra experiments per iteration (time reversal) asks for them in order: the
  command says which run the written input is for.

A design from measured FRF data (``[plant] frf = [...]``, ``docs/measured-data.md``) has no
plant model: the learner runs on its trial (:func:`~ilc_analysis.design.load_frf_run`: the
file's ``[problem]`` must give ``N`` and ``reference``), starting from a zero input.

The next input is written first and the state after it, each atomically (a temporary file
renamed into place): a run interrupted between the two, or whose input cannot be written,
leaves the state at the previous trial, and repeating the command with the same log writes
the same input.

Concurrent calls on one ``--state`` are serialised: each holds the state's lock (the file
``.<state>.lock`` beside it, a portable :class:`filelock.FileLock`) from reading the state,
through the update and writing ``--out``, to writing the state, so no update is lost and the
state always belongs to the input last written. A call that cannot get the lock within
:data:`STATE_LOCK_TIMEOUT` seconds is refused (exit 2, naming ``--state``; nothing written).

Exit status: 0 written; 2 bad input (nothing written), including a state saved for another
design, an update that diverges (the state is left unchanged) and a state locked by another
call for longer than :data:`STATE_LOCK_TIMEOUT`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .._output import check_not_inputs, check_output_path, held_lock
from ..exceptions import InternalError
from ..simulation import Learner, read_trial_csv, write_input_csv
from ._common import CLIError, emit_json
from ._design_support import add_allow_code_option, baseline_hint, first_trial, read_run

__all__ = ["register", "run", "STATE_LOCK_TIMEOUT"]

#: Seconds a call waits for another call on the same ``--state`` to finish before it refuses
#: (exit 2). An update takes well under a second plus the time to read the logs; a minute
#: covers a slow disk without leaving a stuck call waiting for ever.
STATE_LOCK_TIMEOUT = 60.0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "learn",
        description="First call (no --measured): write the first trial's input to --out and "
                    "create the learner state --state. Each later call: read the measured "
                    "record of the last run (--measured, N + s rows, header = output names), "
                    "learn, write the next run's input to --out (header = input names) and "
                    "update --state. Calls on one --state run one at a time (a call waits "
                    f"up to {STATE_LOCK_TIMEOUT:g} s for another, then is refused). Exit "
                    "status: 0 written, 2 bad input (nothing written).")
    p.add_argument("design", metavar="DESIGN.toml", help="design file (docs/design-file.md)")
    p.add_argument("--state", required=True, metavar="STATE.json",
                   help="learner state file (created by the first call, updated by each)")
    p.add_argument("--out", required=True, metavar="NEXT_INPUT.csv",
                   help="the next run's input (CSV; replaced as a whole)")
    p.add_argument("--measured", metavar="TRIAL.csv", default=None,
                   help="the last run's measured outputs, the full record of N + s samples "
                        "(absent: start, writing the first input)")
    p.add_argument("--applied", metavar="INPUT.csv", default=None,
                   help="the input the machine actually applied in the last trial (feedback "
                        "included), N rows, if it logs it (default: the feed-forward plus the "
                        "current-trial feedback recomputed from the measured error)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_allow_code_option(p)
    p.set_defaults(run=run)


def _same(a, b) -> bool:
    return Path(a).resolve() == Path(b).resolve()


def run(args: argparse.Namespace) -> int:
    out = check_output_path(args.out, "--out")
    state = check_output_path(args.state, "--state")
    if _same(out, state):
        raise CLIError(f"--out and --state must be different files; both are {args.out!r}")
    for option, path in (("--measured", args.measured), ("--applied", args.applied)):
        if path is not None and (_same(path, out) or _same(path, state)):
            raise CLIError(f"{option} {path!r} is also --out or --state: it would be "
                           f"overwritten; write the next input and the state elsewhere")
    check_not_inputs({"--out": args.out, "--state": args.state}, {"DESIGN": args.design})
    if args.measured is None and args.applied is not None:
        raise CLIError("--applied needs --measured (it belongs to a measured trial)")
    _check_state_exists(args, state)                 # early, before the design is built
    problem, law = read_run(args.design, "DESIGN", allow_code=args.allow_code)
    if problem is None:
        raise InternalError("read_run refuses a design without one")
    with held_lock(state, "--state", str(args.state), timeout=STATE_LOCK_TIMEOUT,
                   busy="is being updated by another ilc-analysis learn call"):
        _check_state_exists(args, state)             # again: another call may have created it
        learner, u = _learn(args, problem, law)
        write_input_csv(args.out, u, problem.input_names, option="--out")
        learner.save_state(args.state, option="--state")
    _print(args, problem, learner)
    return 0


def _check_state_exists(args: argparse.Namespace, state: Path) -> None:
    """The first call (no ``--measured``) creates the state; every later call needs it."""
    if args.measured is None:
        if state.exists():
            raise CLIError(f"--state {args.state!r} exists: pass --measured TRIAL.csv to learn "
                           f"from the last run, or remove the state file to start over")
    elif not state.exists():
        raise CLIError(f"--state {args.state!r} does not exist: start with a call without "
                       f"--measured (it writes the first input and creates the state)")


def _learn(args: argparse.Namespace, problem, law):
    """The learner (started, or loaded from ``--state``) and the input it gives next."""
    if args.measured is None:
        learner = Learner(problem, law)
        u = learner.first_input()
    else:
        learner = Learner.load_state(args.state, problem, law, option="--state")
        y = read_trial_csv(args.measured, problem.output_names, rows=learner.record_length,
                           option="--measured")
        applied = None
        if args.applied is not None:
            if learner.experiment != 0:
                raise CLIError("--applied is for a trial; the pending run was an extra "
                               "experiment (applied open loop)")
            applied = read_trial_csv(args.applied, problem.input_names, rows=problem.N,
                                     option="--applied")
        u = learner.update(y, u_applied=applied)
    return learner, u


def _print(args: argparse.Namespace, problem, learner) -> None:
    feedback = learner.current_trial_feedback is not None and learner.experiment == 0
    if args.json:
        emit_json({"design": str(args.design), "out": str(args.out), "state": str(args.state),
                   "iteration": learner.iteration, "experiment": learner.experiment,
                   "experiments_per_iteration": learner.experiments_per_iteration,
                   "record_length": learner.record_length,
                   "input_names": list(problem.input_names),
                   "output_names": list(problem.output_names),
                   "output_is_feedforward": feedback, "first_trial": first_trial(problem),
                   "description": learner.describe()})
    else:
        run_name = ("trial" if learner.experiment == 0 else
                    f"extra experiment {learner.experiment} of "
                    f"{learner.experiments_per_iteration - 1} (open loop)")
        print(f"wrote {args.out}: input of the {run_name} of iteration {learner.iteration} "
              f"({problem.N} rows, columns {', '.join(problem.input_names)})")
        if learner.iteration == 1 and learner.experiment == 0:
            print(f"trial 1 runs {first_trial(problem)}: the baseline the learning is "
                  f"measured against")
            if (hint := baseline_hint(problem)) is not None:
                print(f"note: {hint}")
        print(f"state {args.state}: {learner.iteration - 1} trial(s) learned from")
        print(f"log the run's outputs, {learner.record_length} rows from t0 (columns "
              f"{', '.join(problem.output_names)}), and pass them with --measured")
        if feedback:
            print("the input is a feed-forward: the machine's loop adds the current-trial "
                  "feedback Psi2 e(k) + Phi2 (e(k) - e(k-1))/ts (see the design's [law])")
