"""``ilc-analysis design-frf``: a learning law and its robust certificate from FRF measurement
files, written as a design file (docs/measured-data.md).

``design-frf MEAS.csv [MEAS2.csv ...] --ts TS --out design.toml`` reads the measurements
(:func:`ilc_analysis.model.read_frf`: CSV or ``.mat``; several files or a ``repeat`` column give
the mean and the max-deviation envelope times ``--spread-factor``, or ``--radius`` gives it),
designs L (a regularised zero-phase FIR inverse) and Q (the widest certified cut-off)
with :func:`ilc_analysis.synthesis.design_from_frf`, prints the certificate and writes the design
file (:func:`ilc_analysis.design.save_frf_design`); ``ilc-analysis check design.toml`` re-checks
it from the same files. Exit 0 when the design is certified, 1 when no cut-off on the grid makes
the robust condition hold (the file is still written, with its failing verdict), 2 on bad
input.
"""

from __future__ import annotations

import argparse
import shlex
import sys

from ..design import save_frf_design
from ..model import DEFAULT_SPREAD_FACTOR, read_frf
from ..synthesis import design_from_frf
from ..synthesis._frf_design import DEFAULT_FRF_TAPS, DEFAULT_REGULARIZATION
from ._common import emit_json


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "design-frf",
        description="Read FRF measurements (CSV or .mat), design a regularised zero-phase FIR "
                    "inverse L and the widest certified DCT Q-filter, and write a design file "
                    "that 'check' re-verifies from the same files.")
    p.add_argument("measurements", nargs="+", metavar="MEAS.csv",
                   help="measurement files on one grid: the DFT bins k/(N ts) of the trial")
    p.add_argument("--ts", type=float, required=True, help="sample time [s]")
    p.add_argument("--shift", type=int, default=1, help="output shift s of the trial "
                   "(default 1)")
    p.add_argument("--spread-factor", type=float, default=DEFAULT_SPREAD_FACTOR,
                   help="kappa of the radius kappa * max_i ‖G_i - mean‖ "
                        f"(default {DEFAULT_SPREAD_FACTOR:g})")
    p.add_argument("--radius", type=float, default=None,
                   help="a given uncertainty radius (replaces the estimate)")
    p.add_argument("--half-length", type=int, default=DEFAULT_FRF_TAPS,
                   help=f"M: 2M + 1 FIR taps (default {DEFAULT_FRF_TAPS})")
    p.add_argument("--regularization", type=float, default=DEFAULT_REGULARIZATION,
                   help="epsilon of beta = epsilon max|G|^2 "
                        f"(default {DEFAULT_REGULARIZATION:g})")
    p.add_argument("--band", type=float, default=None, dest="band_hz",
                   help="invert up to this frequency [Hz] (default: the whole grid)")
    p.add_argument("--q-order", type=int, default=2, help="DCT Butterworth order of Q "
                   "(default 2)")
    p.add_argument("--out", required=True, metavar="DESIGN.toml", help="design file to write")
    p.add_argument("--json", action="store_true", help="print a JSON object instead of text")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    frf = read_frf(args.measurements, args.ts, radius=args.radius, factor=args.spread_factor)
    design = design_from_frf(frf, shift=args.shift, half_length=args.half_length,
                             regularization=args.regularization, band_hz=args.band_hz,
                             q_order=args.q_order)
    command = "ilc-analysis " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    save_frf_design(design, args.out, args.measurements, ts=args.ts,
                    spread_factor=args.spread_factor, radius=args.radius, command=command)
    code = 0 if design.certified else 1
    if args.json:
        emit_json({"out": str(args.out), "data": frf.as_dict(), **design.as_dict(),
                   "exit_status": code})
        return code
    cutoff = "none" if design.cutoff_hz is None else f"{design.cutoff_hz:g} Hz"
    print(f"[data] {frf.measurements} measurement(s), {frf.n_f} frequencies, "
          f"{frf.uncertainty}")
    print(f"[law] FIR inverse, {2 * design.half_length + 1} taps, beta = {design.beta:.3g}; "
          f"Q cut-off {cutoff}")
    print(f"[certificate] {design.condition.verdict}: {design.condition.reason}")
    print(f"wrote {args.out}")
    return code
