"""``ilc-analysis simulate``: learning trials of a design file, written to an output directory.

``simulate DESIGN.toml --iterations K --out DIR`` runs ``K`` trials of the design's law on its
problem (:func:`ilc_analysis.simulation.simulate` with the problem's plant, reference, initial
state, shift and disturbances) and writes, all at once or not at all
(:func:`ilc_analysis._output.output_directory`):

* ``results.nc``: the run's data set (netCDF; :class:`~ilc_analysis.simulation.ILCResult`);
* ``outputs.png``: per output channel, the output against the reference over iterations and
  the tracking error over the trial;
* ``error_norm.png``: per output channel, max |e| and the trial's error norm ‖e‖₂ per
  iteration, on axes that show the reduction honestly, with the reduction factor in the
  titles;
* ``learned_input.png``: per input, the learned signal (the feed-forward) over iterations and
  its change since the first iteration;
* ``summary.json``: per-iteration numbers, divergence, the design it ran, what trial 1 ran
  (``first_trial``: the baseline of the reduction factor, e.g. the loop alone) and the
  reduction (``"1270× below trial 1 (zero input)"``).

The printed summary says what trial 1 ran (:attr:`ILCProblem.first_trial
<ilc_analysis.problem.ILCProblem.first_trial>`) beside the reduction factor; learning at the
plant input from a zero first trial, a square plant is reminded that a plant with its own loop
starts honestly from the reference (``[problem] initial_input = "reference"``).

A design from measured FRF data (``[plant] frf = [...]``, ``docs/measured-data.md``) runs on
the model its ``[simulation]`` table names (:func:`~ilc_analysis.design.load_frf_run`; not
used by the design or the certificate); without one it is refused (exit 2).

Every figure axis carries its channel's unit (the plant's declared units, ``[-]`` when none is
declared); :func:`ilc_analysis.plotting.run_figures` draws the same figures in Python.

Exit status: 0 every iteration ran; 1 the run diverged (the outputs are written and say in which
iteration and at what time); 2 bad input (nothing written).
"""

from __future__ import annotations

import argparse
import json
import os

from .._output import check_not_inputs, output_directory
from .._validation import MAX_ITERATIONS
from ..exceptions import InternalError
from ..plotting import save_run_figures
from ..simulation import simulate
from ._common import CLIError, emit_json
from ._design_support import add_allow_code_option, baseline_hint, read_run

__all__ = ["register", "run", "SIMULATE_FILES"]

#: the files ``simulate`` writes into its output directory
SIMULATE_FILES = ("results.nc", "outputs.png", "error_norm.png", "learned_input.png",
                  "summary.json")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "simulate",
        description="Run K trials of the design's law on its problem and write results.nc, "
                    "figures (outputs against the reference over iterations, error norm per "
                    "iteration, learned input) and summary.json into --out. Exit status: 0 "
                    "done, 1 the run diverged (outputs written; iteration and time reported), "
                    "2 bad input (nothing written).")
    p.add_argument("design", metavar="DESIGN.toml", help="design file (docs/design-file.md)")
    p.add_argument("--iterations", type=int, required=True, metavar="K",
                   help=f"number of trials (1 to {MAX_ITERATIONS})")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output directory; replaced as a whole when the run ends, untouched "
                        "on bad input")
    p.add_argument("--seed", type=int, default=None,
                   help="root seed of the noise streams (default: the design's "
                        "[problem.disturbances].seed, else fresh entropy, recorded)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_allow_code_option(p)
    p.set_defaults(run=run)


def _summary(problem, law, result, path: str, iterations: int) -> dict:
    ds = result.dataset
    div = result.divergence
    return {"design": path, "law": law.name, "problem": problem.name,
            "first_trial": result.baseline, "reduction": result.reduction(),
            "iterations_requested": iterations, "iterations_run": result.iterations,
            "max_error": [float(v) for v in result.max_error],
            "e_norm": [float(v) for v in ds["e_norm"].values],
            "experiments_total": int(ds.attrs.get("experiments_total", result.iterations)),
            "seed": str(ds.attrs.get("seed", "")),
            "diverged": result.diverged,
            "divergence": None if div is None else {
                "iteration": div.iteration, "time": div.time, "sample": div.sample,
                "reason": div.reason, "state": div.state}}


def run(args: argparse.Namespace) -> int:
    if isinstance(args.iterations, bool) or not 1 <= args.iterations <= MAX_ITERATIONS:
        raise CLIError(f"--iterations must be an integer in [1, {MAX_ITERATIONS}]; got "
                       f"{args.iterations}")
    if args.seed is not None and args.seed < 0:
        raise CLIError(f"--seed must be a non-negative integer (the root seed of the run's "
                       f"random streams); got {args.seed}")
    # before any work: --out is replaced as a whole, so it must not hold the design
    check_not_inputs({"--out": args.out}, {"DESIGN": args.design}, directories={"--out"})
    with output_directory(args.out, "--out", command="ilc-analysis simulate") as tmp:
        problem, law = read_run(args.design, "DESIGN", allow_code=args.allow_code,
                                simulation=True)
        if problem is None:
            raise InternalError("read_run refuses a design without one")
        result = simulate(problem, law, args.iterations, entropy=args.seed)
        summary = _summary(problem, law, result, args.design, args.iterations)
        result.to_netcdf(tmp / "results.nc")
        save_run_figures(result, tmp)
        (tmp / "summary.json").write_text(json.dumps(summary, indent=2, allow_nan=False)
                                          + "\n")
    if args.json:
        emit_json({**summary, "out": str(args.out)})
    else:
        me = result.max_error
        print(f"{law.name} on {problem.name!r}: {result.iterations} of "
              f"{args.iterations} iteration(s)")
        if me.size:
            print(f"  max |e|: first {me[0]:.6g}, last {me[-1]:.6g}, best {me.min():.6g}: "
                  f"{result.reduction()}")
        if (hint := baseline_hint(problem)) is not None:
            print(f"  note: {hint}")
        if (d := result.divergence) is not None:    # result.diverged
            print(f"  DIVERGED in iteration {d.iteration} at t = {d.time:.6g} s (sample "
                  f"{d.sample}): {d.reason}")
        print(f"  written to {os.path.join(args.out, 'results.nc')} and figures in {args.out}")
    return 1 if result.diverged else 0
