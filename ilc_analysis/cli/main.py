"""Entry point of the ``ilc-analysis`` console command."""

from __future__ import annotations

import argparse
import importlib
import sys

from ..exceptions import ILCError

# One module per subcommand, each with register(subparsers); add a line to add a command.
_COMMAND_MODULES = (
    "model_command",
    "lifted_command",
    "check_command",
    "reproduce_command",
    "synthesize_command",
    "lead_scan_command",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ilc-analysis",
        description="Verify, synthesise and simulate iterative learning control laws "
                    "(Dong et al. 2019, open-closed-loop PD-ILC with a variable forgetting "
                    "factor).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in _COMMAND_MODULES:
        importlib.import_module(f"{__package__}.{name}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (2 for bad input, as argparse does)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except (ILCError, ValueError) as exc:
        print(f"ilc-analysis {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
