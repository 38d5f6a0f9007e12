"""``ilc-analysis export``: a certified design file's law as C99 for the machine's processor.

A thin layer over :func:`ilc_analysis.export.export`::

    ilc-analysis export design.toml --out law_c                     # double precision
    ilc-analysis export design.toml --out law_c --precision single --ram 65536 --json
    cd law_c && cc -std=c99 -O2 *.c -lm -o ilc_host
    ./ilc_host input_1.csv trial_1.csv > input_2.csv                # beside `learn`

The certificate is re-verified first; a design without one, or whose certificate does not hold,
is refused unless ``--uncertified`` (the header then says so); ``--certify`` certifies a design
file that holds none (a hand-written one) on its own operator first, so it is exported only when
that certificate holds. Exit status: 0 written; 2 refused
(no certificate that holds, a law without self-contained C, single precision the certificate's
margin cannot absorb, the ``--ram`` budget exceeded: the message says why) or bad input;
nothing is written then.
"""

from __future__ import annotations

import argparse

from ..exceptions import ExportRefusedError
from ._common import emit_json
from ._design_support import add_allow_code_option, is_frf_design_file, read_full_design

__all__ = ["register", "run"]


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "export",
        description="Write the design's certified law as self-contained C99 (one header, no "
                    "allocation, libm only): the between-trial update, the in-trial step of a "
                    "law with a current-trial part, the state between runs, and a host driver "
                    "ilc_host.c that reads and writes learn's CSV files (build: cc -std=c99 -O2 "
                    "on the directory's .c files, with -lm). Prints the footprint (RAM, flash, "
                    "operations per trial) and, in single precision, the proven error floor its "
                    "rounding adds. "
                    "Exit status: 0 written, 2 refused or bad input (nothing written).")
    p.add_argument("design", metavar="DESIGN.toml", help="design file (docs/design-file.md)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output directory (created, or replaced as a whole when everything "
                        "is written)")
    p.add_argument("--precision", choices=("double", "single"), default="double",
                   help="the arithmetic of the generated code (default double; single comes "
                        "with a proven bound of the floor its rounding adds, and is refused "
                        "where the certificate's margin cannot absorb it)")
    p.add_argument("--ram", type=int, metavar="BYTES", default=None,
                   help="refuse (exit 2) when the update needs more RAM than this (work, state "
                        "and the trial's buffers)")
    p.add_argument("--certify", action="store_true",
                   help="a design file without a certificate (a hand-written one, as "
                        "examples/dc_motor): certify it now on its own operator "
                        "(Design.certify, what check computes) and export it only when that "
                        "certificate holds")
    p.add_argument("--uncertified", action="store_true",
                   help="export a design without a certificate that holds, saying so in the "
                        "header (double precision only)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    add_allow_code_option(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..export import export

    if is_frf_design_file(args.design):
        raise ExportRefusedError(
            f"DESIGN {args.design!r}", "it is a design from measured FRF data (no plant model "
            "or lifted operator for the export's certificate re-check and rounding analysis); "
            "export a design file with a plant model")
    design = read_full_design(args.design, "DESIGN", allow_code=args.allow_code)
    if args.certify and not design.certificate:
        design = design.certify()
    result = export(design, args.out, precision=args.precision, ram=args.ram,
                    uncertified=args.uncertified, allow_code=args.allow_code)
    if args.json:
        emit_json({"design": str(args.design), **result.as_dict()})
    else:
        print(result.summary())
    return 0
