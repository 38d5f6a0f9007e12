"""``ilc-analysis reproduce``: the paper's Section 5 end to end (what ``make reproduce`` runs).

The outputs are written to a temporary directory beside ``--out`` and renamed into place when
everything is written (:func:`ilc_analysis._output.output_directory`): an interrupted or failed
run leaves ``--out`` as it was, and a second run into the same ``--out`` is refused while the
first one runs. Exit status: 0 both laws ran every iteration; 1 a law diverged (the outputs are
written and the report says in which iteration and at what time); 2 bad input.

Each stage is announced on stderr with the time since the start (``[  12.3 s] simulation:
...``), besides the progress bars of the long loops, when progress is shown (the CLI's
convention, :mod:`ilc_analysis.cli.main`: on a terminal, or asked with ``--progress`` or
``ILC_PROGRESS=1``; never with ``--no-progress`` or ``--quiet``, nor with ``--json`` unless
``--progress`` is given). ``--json`` prints one JSON document on stdout:
the facts of each law's run (``laws``), the design files written with their certificates
(``designs``), the report's path and whether a law diverged.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from threadpoolctl import threadpool_limits

from .._output import check_not_inputs, output_directory
from .._progress import progress_enabled
from ..design import save_design
from ..design._design import certificate_text
from ..exceptions import InternalError
from ..paper import load_scenario
from ..paper._designs import PAPER_DESIGN_FILES, paper_run_designs
from ..paper._pipeline import LAW_LABELS, run_paper, write_paper_outputs
from ..paper._report import diverged_text, number, times
from ._common import check_scenario_size, emit_json, load_input


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "reproduce",
        description="Model -> lifted matrices -> synthesised gains -> convergence analysis -> "
                    "simulation of the proposed (variable forgetting) and the traditional "
                    "(fixed forgetting) law -> Figures 4-6, results data, analysis, gains, "
                    "summary.json, report.md and one design file per law (design_*.toml: "
                    "check, simulate and learn read them). Exit status: 0 done, 1 a law diverged "
                    "(outputs written; the report says where), 2 bad input.")
    p.add_argument("--out", default="results", metavar="DIR",
                   help="output directory (default: results); replaced as a whole when the "
                        "run succeeds, untouched when it fails")
    p.add_argument("--scenario", metavar="FILE.toml",
                   help="scenario file (default: the packaged paper.toml)")
    p.add_argument("--json", action="store_true",
                   help="print a JSON summary (the laws' facts, the design files, the report)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    quiet = not progress_enabled()     # main() applied --progress / --quiet / --json

    def progress(message: str) -> None:
        if not quiet:
            print(f"[{time.perf_counter() - start:6.1f} s] {message}", file=sys.stderr,
                  flush=True)

    # checked and locked before any work; renamed into place only when everything is written.
    # BLAS on one thread: the run's matrices have a few hundred rows, and on the shared 2-core
    # machine a second BLAS thread only spins (the design files' certificates took 33 s of CPU
    # with two threads at load 17, 1.8 s with one)
    check_not_inputs({"--out": args.out}, {"--scenario": args.scenario}, directories={"--out"})
    with threadpool_limits(limits=1, user_api="blas"), \
            output_directory(args.out, "--out", command="ilc-analysis reproduce") as tmp:
        scenario = load_scenario() if args.scenario is None \
            else load_input(args.scenario, "--scenario", load_scenario)
        check_scenario_size(scenario)
        result = run_paper(scenario, progress=progress)
        progress(f"writing outputs to {args.out}")
        write_paper_outputs(result, tmp, atomic=False)
        progress("design files: one per law on the run's problem")
        designs = paper_run_designs(result)
        for label, design in designs.items():
            save_design(design, tmp / PAPER_DESIGN_FILES[label], option="--out",
                        command="ilc-analysis reproduce")
    diverged = any(result.facts[label].diverged for label in LAW_LABELS)
    report = os.path.join(args.out, "report.md")
    certified = {}
    for label, design in designs.items():
        cert = design.certificate
        if cert is None:
            raise InternalError("paper_run_designs certifies each (certified_design)")
        certified[label] = (os.path.join(args.out, PAPER_DESIGN_FILES[label]),
                            certificate_text(cert))
    if args.json:
        emit_json({"out": str(args.out), "report": report, "diverged": diverged,
                   "laws": {label: facts.as_dict() for label, facts in result.facts.items()},
                   "designs": {label: {"path": path, "certificate": text}
                               for label, (path, text) in certified.items()}})
        return 1 if diverged else 0
    for label, facts in result.facts.items():
        state = diverged_text(facts) if facts.diverged \
            else f"{facts.iterations_run} iterations"
        print(f"{label:>8} law: max |e| {number(facts.first_max_error)} -> "
              f"{number(facts.last_max_error)} ({times(facts.reduction)}), max |pitch| "
              f"{number(facts.max_pitch_overall, 3)} rad, {state}")
    for label, (path, text) in certified.items():
        print(f"design ({label}): {path} [{text}]")
    print(f"report: {report}")
    progress("done")
    return 1 if diverged else 0
