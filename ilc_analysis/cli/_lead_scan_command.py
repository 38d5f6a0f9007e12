"""``ilc-analysis lead-scan``: the model-based scan behind the scenario's ``lead``."""

from __future__ import annotations

import argparse
import sys

from ..paper import load_scenario
from ..paper._lead_scan import DEFAULT_LEADS, scenario_lead_scan
from ._common import check_scenario_size, load_input, options_named


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "lead-scan",
        description="For every candidate lead, synthesise and certify the scenario's gains "
                    "and predict max |e_inf| / max |e_1| on the lifted model (no simulation). "
                    "The paper scenario's lead is chosen from this table. --shortlist K ranks "
                    "the leads by the floor of their unbounded least-squares gains (one linear "
                    "solve each) and synthesises only the best K. --q-cutoffs scans the "
                    "scenario's DCT Q-filter cut-off with every lead. Exit status: 0 a lead is "
                    "certified, 1 none is, 2 bad input.")
    p.add_argument("--scenario", metavar="FILE.toml",
                   help="scenario file (default: the packaged paper.toml)")
    p.add_argument("--leads", type=int, nargs="+", default=list(DEFAULT_LEADS),
                   metavar="SAMPLES", help="candidate leads in samples (default: "
                   + " ".join(map(str, DEFAULT_LEADS)) + ")")
    p.add_argument("--shortlist", type=int, metavar="K",
                   help="synthesise only the K leads with the best least-squares prediction "
                        "(default: every lead)")
    p.add_argument("--q-cutoffs", type=float, nargs="+", metavar="HZ",
                   help="candidate cut-offs of the DCT Q-filter in Hz, each scanned with every "
                        "lead (0: no filter; default: the scenario's q_cutoff only)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    scenario = load_scenario() if args.scenario is None \
        else load_input(args.scenario, "--scenario", load_scenario)
    check_scenario_size(scenario)
    with options_named(lead="--leads", leads="--leads", shortlist="--shortlist",
                       q_cutoff="--q-cutoffs", q_cutoffs="--q-cutoffs"):
        scan = scenario_lead_scan(scenario, args.leads, shortlist=args.shortlist,
                                  q_cutoffs=args.q_cutoffs)
    print(scan.table())
    if scan.best_index is None:         # a negative result: exit 1 (cli.main), as synthesize
        print("ilc-analysis lead-scan: no lead is certified (every candidate's certificate "
              "failed: the scan has no best lead)", file=sys.stderr)
        return 1
    return 0
