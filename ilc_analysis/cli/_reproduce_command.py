"""``ilc-analysis reproduce``: the paper's Section 5 end to end (what ``make reproduce`` runs).

The outputs are written to a temporary directory beside ``--out`` and renamed into place when
everything is written (:func:`ilc_analysis._output.output_directory`): an interrupted or failed
run leaves ``--out`` as it was, and a second run into the same ``--out`` is refused while the
first one runs. Exit status: 0 both laws ran every iteration; 1 a law diverged (the outputs are
written and the report says in which iteration and at what time); 2 bad input.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from .._output import output_directory
from ..design import save_design
from ..design._design import certificate_text
from ..design._paper_designs import PAPER_DESIGN_FILES, paper_run_designs
from ..exceptions import InternalError
from ..paper import load_scenario
from ..paper._pipeline import LAW_LABELS, run_paper, write_paper_outputs
from ..paper._report import diverged_text, number, times
from ._common import check_scenario_size, load_input


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
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    start = time.perf_counter()

    def progress(message: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - start:6.1f} s] {message}", file=sys.stderr,
                  flush=True)

    # checked and locked before any work; renamed into place only when everything is written
    with output_directory(args.out, "--out", command="ilc-analysis reproduce") as tmp:
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
    for label, facts in result.facts.items():
        state = diverged_text(facts) if facts.diverged \
            else f"{facts.iterations_run} iterations"
        print(f"{label:>8} law: max |e| {number(facts.first_max_error)} -> "
              f"{number(facts.last_max_error)} ({times(facts.reduction)}), max |pitch| "
              f"{number(facts.max_pitch_overall, 3)} rad, {state}")
    for label, design in designs.items():
        cert = design.certificate
        if cert is None:
            raise InternalError("paper_run_designs certifies each (certified_design)")
        print(f"design ({label}): {os.path.join(args.out, PAPER_DESIGN_FILES[label])} "
              f"[{certificate_text(cert)}]")
    print(f"report: {os.path.join(args.out, 'report.md')}")
    progress("done")
    return 1 if any(result.facts[label].diverged for label in LAW_LABELS) else 0
