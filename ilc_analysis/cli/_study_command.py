"""``ilc-analysis study``: run a robustness / design study (a thin layer over
:mod:`ilc_analysis.studies`).

    ilc-analysis study STUDY.toml --out DIR [--workers N] [--scheduler ADDRESS] [--serial]

By default the points run on a Dask ``LocalCluster`` of ``--workers`` processes started for the
run; ``--scheduler tcp://host:8786`` uses an existing cluster (any number of machines: the same
command); ``--serial`` runs them in this process. Finished points are written to ``DIR`` as they
finish: the same command run again after an interruption computes only the missing points.
At the end ``DIR`` holds ``results.zarr`` (the labelled data set), ``report.md``,
``summary.json`` and ``figures/``.

Exit status: 0 when the study completed (points whose evaluation raised are counted in the
report and have their reason in ``error``), 1 when no point could be evaluated, 2 for bad
input (unknown key paths, empty axes, a scheduler that does not answer within ``--timeout``).
"""

from __future__ import annotations

import argparse
import functools
import os
import shlex
import sys

from .._output import check_output_path
from ._common import CLIError, emit_json, load_input

# ilc_analysis.studies is imported where a study runs: at module level it would add its eight
# modules (about 20 ms) to every ``ilc-analysis --help``, which loads each command module.
from ._design_support import add_allow_code_option, register_scenarios

#: most local worker processes per CPU (--workers): more only add processes (each imports the
#: toolkit, about 150 MB) competing for the same cores
WORKERS_PER_CPU = 4
#: longest wait for --scheduler to answer [s]: a scheduler that takes longer is not there
#: (``--timeout inf`` waited forever on a silent port)
MAX_SCHEDULER_TIMEOUT = 3600.0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "study",
        description="Vary a design file along the axes of a study file (plant parameters by "
                    "Monte Carlo, Latin hypercube or box vertices; law parameters, disturbances "
                    "and reset errors on grids) and compute at every point the analysis "
                    "verdicts and numbers and a simulation summary. Points run on a Dask "
                    "LocalCluster (default), an existing cluster (--scheduler) or serially; "
                    "they are stored as they finish, so an interrupted study resumes. See "
                    "docs/studies.md.")
    p.add_argument("study", metavar="STUDY.toml", help="the study file")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="results directory (created; an interrupted run of the same study in "
                        "it is resumed)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the local Dask cluster (default: the number of "
                        "CPUs)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a running Dask scheduler, e.g. tcp://host:8786 (its "
                        "workers need ilc-analysis installed and the design's files)")
    p.add_argument("--timeout", type=float, default=10.0, metavar="S",
                   help="seconds to wait for --scheduler to answer (default 10)")
    p.add_argument("--serial", action="store_true",
                   help="run the points in this process, without Dask")
    p.add_argument("--restart", action="store_true",
                   help="discard what DIR holds and start the study again")
    p.add_argument("--no-figures", action="store_true", help="no figures in DIR/figures")
    p.add_argument("--json", action="store_true",
                   help="print the summary as JSON on stdout")
    add_allow_code_option(p)
    p.set_defaults(run=run)


def _executor(args):
    from ..studies import DaskExecutor, SerialExecutor

    if args.serial:
        if args.scheduler is not None or args.workers is not None:
            raise CLIError("--serial runs in this process: it takes neither --workers nor "
                           "--scheduler")
        return SerialExecutor()
    largest = WORKERS_PER_CPU * (os.cpu_count() or 1)
    if args.workers is not None and not 1 <= args.workers <= largest:
        raise CLIError(f"--workers must be an integer in [1, {largest}] ({WORKERS_PER_CPU} per "
                       f"CPU: each is a process of its own; the points are CPU-bound); got "
                       f"{args.workers}")
    if args.scheduler is not None and args.workers is not None:
        raise CLIError("--workers sizes the local cluster; with --scheduler the cluster's own "
                       "workers run the study")
    if not 0 < args.timeout <= MAX_SCHEDULER_TIMEOUT:
        raise CLIError(f"--timeout must be a positive, finite number of seconds, at most "
                       f"{MAX_SCHEDULER_TIMEOUT:g} (an hour); got {args.timeout}")
    workers = args.workers if args.workers is not None else (os.cpu_count() or 1)
    return DaskExecutor(workers, scheduler=args.scheduler, timeout=args.timeout)


def run(args: argparse.Namespace) -> int:
    from ..studies import load_study, run_study
    from ..studies._report import publish

    register_scenarios()
    study = load_input(args.study, "STUDY.toml",
                       functools.partial(load_study, allow_code=args.allow_code))
    check_output_path(args.out, "--out", directory=True, command="ilc-analysis study")
    command = "ilc-analysis study " + " ".join(shlex.quote(a) for a in sys.argv[2:]) \
        if len(sys.argv) > 2 and sys.argv[1] == "study" else \
        f"ilc-analysis study {shlex.quote(args.study)} --out {shlex.quote(args.out)}"
    with _executor(args) as executor:
        result = run_study(study, args.out, executor=executor, progress=None,
                           restart=args.restart)
    summary = publish(result, command=command, figures=not args.no_figures)
    if args.json:
        emit_json(summary)
    else:
        print(result.summary())
        numbers = summary["numbers"]
        if "certified" in numbers:
            print(f"certified: {numbers['certified']} of {numbers['points']} "
                  f"({numbers['certified_fraction']:.1%})")
        fe = numbers.get("final_max_error", {})
        if fe.get("count"):
            print(f"final max |e|: median {fe['median']:.4g}, 95 % {fe['p95']:.4g}, max "
                  f"{fe['max']:.4g}; diverged {numbers['diverged']}")
        print(f"results: {result.directory}/results.zarr, report.md, summary.json")
    if result.failed:
        first = next(iter(v for v in result.dataset["error"].values.ravel() if v))
        print(f"{result.failed} point(s) could not be evaluated; first: {first}",
              file=sys.stderr)
    return 1 if result.failed == study.size else 0
