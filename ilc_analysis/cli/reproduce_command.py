"""``ilc-analysis reproduce``: the paper's Section 5 end to end (what ``make reproduce`` runs)."""

from __future__ import annotations

import argparse
import sys
import time

from ..scenarios import load_scenario
from ..scenarios.pipeline import run_paper, write_paper_outputs


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "reproduce", help="run the paper's Section 5 scenario and write figures and a report",
        description="Model -> lifted matrices -> synthesised gains -> convergence analysis -> "
                    "simulation of the proposed (variable forgetting) and the traditional "
                    "(fixed forgetting) law -> Figures 4-6, results data, analysis, gains, "
                    "summary.json and report.md.")
    p.add_argument("--out", default="results", metavar="DIR",
                   help="output directory (default: results)")
    p.add_argument("--scenario", metavar="FILE.toml",
                   help="scenario file (default: the packaged paper.toml)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario)
    start = time.perf_counter()

    def progress(message: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - start:6.1f} s] {message}", file=sys.stderr,
                  flush=True)

    result = run_paper(scenario, progress=progress)
    progress(f"writing outputs to {args.out}")
    paths = write_paper_outputs(result, args.out)
    for label, facts in result.facts.items():
        state = (f"diverged at iteration {facts.diverged_iteration}" if facts.diverged
                 else f"{facts.iterations_run} iterations")
        print(f"{label:>8} law: max |e| {facts.first_max_error:.4g} -> "
              f"{facts.last_max_error:.4g} ({facts.reduction:.3g}x), max |pitch| "
              f"{facts.max_pitch_overall:.3g} rad, {state}")
    print(f"report: {paths['report.md']}")
    progress("done")
    return 0
