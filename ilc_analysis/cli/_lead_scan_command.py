"""``ilc-analysis lead-scan``: the model-based scan behind the scenario's ``lead``, or the same
scan on the problem of a design file (:func:`ilc_analysis.synthesis.scan_problem_leads`)."""

from __future__ import annotations

import argparse
import math
import sys
import tomllib

from ..paper import load_scenario
from ..paper._lead_scan import DEFAULT_LEADS, scenario_lead_scan
from ._common import CLIError, check_scenario_size, emit_json, load_input, options_named
from ._design_support import add_design_argument, design_argument
from ._synthesize_command import CLI_TARGET


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "lead-scan",
        description="For every candidate lead, synthesise and certify lifted PD gains and "
                    "predict max |e_inf| / max |e_1| on the lifted model (no simulation): of "
                    "a scenario (--scenario; the paper scenario's lead is chosen from this "
                    "table) or of the problem of a design file (DESIGN.toml; time-invariant "
                    "gains, objective mean, target 0.99, the forgetting factor of "
                    "--forgetting). --shortlist K ranks the leads by the floor of their "
                    "unbounded least-squares gains (one linear solve each) and synthesises only "
                    "the best K. --q-cutoffs scans the DCT Q-filter cut-off with every lead. "
                    "Exit status: 0 a lead is certified, 1 none is, 2 bad input.")
    add_design_argument(p, "scan on its problem's lifted system")
    p.add_argument("--scenario", metavar="FILE.toml",
                   help="scenario file (default: the packaged paper.toml; not with DESIGN)")
    p.add_argument("--leads", type=int, nargs="+", default=None,
                   metavar="SAMPLES", help="candidate leads in samples (default: "
                   + " ".join(map(str, DEFAULT_LEADS)) + "; for a design, those shorter than "
                   "its trial)")
    p.add_argument("--shortlist", type=int, metavar="K",
                   help="synthesise only the K leads with the best least-squares prediction "
                        "(default: every lead)")
    p.add_argument("--q-cutoffs", type=float, nargs="+", metavar="HZ",
                   help="candidate cut-offs of the DCT Q-filter in Hz, each scanned with every "
                        "lead (0: no filter; default: the scenario's q_cutoff only; a design: "
                        "no filter)")
    p.add_argument("--forgetting", type=float, default=None, metavar="A",
                   help="DESIGN only: the constant forgetting factor a in [0, 1) of every "
                        "candidate (default 0: none; a scenario uses its own)")
    p.add_argument("--json", action="store_true",
                   help="print a JSON object (every candidate's synthesis result, predicted "
                        "ratio and the best candidate) instead of the table")
    p.set_defaults(run=run)


def _design_scan(args, design):
    from ..laws._qfilter import QFilter
    from ..synthesis import scan_problem_leads

    problem = design.problem
    leads = args.leads if args.leads is not None else \
        [lead for lead in DEFAULT_LEADS if lead < problem.N]
    a = 0.0 if args.forgetting is None else args.forgetting
    if not (math.isfinite(a) and 0.0 <= a < 1.0):
        raise CLIError(f"--forgetting must be a constant factor a in [0, 1) (0: none); got "
                       f"{args.forgetting}")
    options: dict = {}
    if args.q_cutoffs is not None:
        nyquist = 0.5 / problem.ts
        for c in args.q_cutoffs:
            if not (math.isfinite(c) and 0.0 <= c < nyquist):
                raise CLIError(f"--q-cutoffs: each cut-off must be a finite frequency in "
                               f"[0, {nyquist:g}) Hz (0: no filter; below the Nyquist frequency "
                               f"of ts = {problem.ts:g} s); got {c}")
        options["q_filters"] = [QFilter.dct(c) if c > 0 else None for c in args.q_cutoffs]
    with options_named(lead="--leads", leads="--leads", shortlist="--shortlist",
                       q_filters="--q-cutoffs", forgetting="--forgetting"):
        return scan_problem_leads(problem, leads, forgetting=a or None,
                                  shortlist=args.shortlist, objective="mean",
                                  target=CLI_TARGET, **options)


def _scenario(path: str):
    """The scenario file of --scenario; a design file given there is named as one."""
    try:
        return load_input(path, "--scenario", load_scenario)
    except CLIError as exc:
        if _is_design_file(path):
            raise CLIError(f"--scenario {path!r} is a design file, not a scenario file: give it "
                           f"as the positional argument, 'ilc-analysis lead-scan {path}'"
                           ) from exc
        raise


def _is_design_file(path: str) -> bool:
    from ..design._file import DESIGN_FORMAT

    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except (OSError, ValueError):
        return False
    return data.get("format") == DESIGN_FORMAT


def run(args: argparse.Namespace) -> int:
    design = design_argument(args, conflicts={"scenario": "--scenario"})
    if design is None:
        if args.forgetting is not None:
            raise CLIError("--forgetting applies to a design file (DESIGN.toml); a scenario "
                           "uses its own forgetting factor")
        scenario = load_scenario() if args.scenario is None else _scenario(args.scenario)
        check_scenario_size(scenario)
        with options_named(lead="--leads", leads="--leads", shortlist="--shortlist",
                           q_cutoff="--q-cutoffs", q_cutoffs="--q-cutoffs"):
            scan = scenario_lead_scan(scenario, list(DEFAULT_LEADS) if args.leads is None
                                      else args.leads, shortlist=args.shortlist,
                                      q_cutoffs=args.q_cutoffs)
    else:
        scan = _design_scan(args, design)
    if args.json:
        emit_json(scan.as_dict())
    else:
        print(scan.table())
    if scan.best_index is None:         # a negative result: exit 1 (cli.main), as synthesize
        print("ilc-analysis lead-scan: no lead is certified (every candidate's certificate "
              "failed: the scan has no best lead)", file=sys.stderr)
        return 1
    return 0
