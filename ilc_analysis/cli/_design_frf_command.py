"""``ilc-analysis design-frf``: a learning law and its robust certificate from FRF measurement
files, written as a design file (docs/measured-data.md).

``design-frf MEAS.csv [MEAS2.csv ...] --ts TS --out design.toml`` reads the measurements
(:func:`ilc_analysis.model.read_frf`: CSV or ``.mat``; several files or a ``repeat`` column give
the mean and a normal tolerance radius, ``--coverage`` of the machine's responses with
``--confidence`` at each frequency, or ``--radius`` gives it),
designs L (a regularised zero-phase FIR inverse) and Q (the widest certified cut-off)
with :func:`ilc_analysis.synthesis.design_from_frf`, prints the certificate and writes the design
file (:func:`ilc_analysis.design.save_frf_design`); ``ilc-analysis check design.toml`` re-checks
it from the same files. ``--reference``, ``--inputs`` and ``--outputs`` add the keys ``learn``
needs (:func:`ilc_analysis.design.load_frf_run`); ``[simulation]``, a model to simulate on, is
left to the user. The design is judged on the trial it runs, the finite N-sample trial
(:func:`ilc_analysis.analysis.finite_trial_condition`; ``--tail`` states the bound of the
impulse response after one period its upper bound needs), and on the N-periodic trial (the
robust frequency condition Q is chosen by). Exit 0 when the finite trial is proven to contract,
1 otherwise (the file is still written, with its verdicts; as ``check``), 2 on bad input.
"""

from __future__ import annotations

import argparse
import shlex
import sys

from .._output import check_not_inputs, check_output_path
from .._validation import MAX_FILTER_ORDER, MAX_SHIFT, MAX_TRIAL_SAMPLES
from ..design import save_frf_design
from ..design._file import not_a_design_file
from ..design._plant_spec import _name_list
from ..design._signals import read_signal_file
from ..model import DEFAULT_CONFIDENCE, DEFAULT_COVERAGE, read_frf
from ..synthesis import design_from_frf
from ..synthesis._frf_design import DEFAULT_FRF_TAPS, DEFAULT_REGULARIZATION
from ._common import CLIError, emit_json, options_named


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "design-frf",
        description="Read FRF measurements (CSV or .mat), design a regularised zero-phase FIR "
                    "inverse L and the widest certified DCT Q-filter, and write a design file "
                    "that 'check' re-verifies from the same files. With --reference (and "
                    "channel names) the file is ready for 'learn'; for 'simulate', add a "
                    "[simulation] table (the model to simulate on) by hand.")
    p.add_argument("measurements", nargs="+", metavar="MEAS.csv",
                   help="measurement files on one grid: the DFT bins k/(N ts) of the trial")
    p.add_argument("--ts", type=float, required=True, help="sample time [s]")
    p.add_argument("--shift", type=int, default=1, help="output shift s of the trial "
                   "(default 1)")
    p.add_argument("--coverage", type=float, default=None,
                   help="the proportion of the machine's responses the uncertainty disc holds "
                        "at each frequency (a normal tolerance region of the measurements; "
                        f"default {DEFAULT_COVERAGE:g})")
    p.add_argument("--confidence", type=float, default=None,
                   help="the confidence with which it holds them "
                        f"(default {DEFAULT_CONFIDENCE:g})")
    p.add_argument("--spread-factor", default=None, help=argparse.SUPPRESS)   # removed
    p.add_argument("--tail", type=float, default=None,
                   help="a stated bound of sum_j>=N ||g_j||, the plant's impulse response "
                        "after one period (N samples): the data cannot give it, and the "
                        "finite trial's upper bound needs it (default: none, the finite trial "
                        "can then fail or be unknown, not hold)")
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
    p.add_argument("--reference", default=None, metavar="REF.csv",
                   help="the trial's reference y_d (N rows, a header of output names), written "
                        "as [problem] reference relative to the design file: the file is then "
                        "ready for 'learn' ('simulate' also needs a [simulation] model, added "
                        "by hand)")
    p.add_argument("--inputs", default=None, metavar="NAMES",
                   help="comma-separated input channel names, written as [plant] inputs")
    p.add_argument("--outputs", default=None, metavar="NAMES",
                   help="comma-separated output channel names, written as [plant] outputs "
                        "(default: the reference CSV's header)")
    p.add_argument("--json", action="store_true", help="print a JSON object instead of text")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    # the sizes the options set, before any file is read
    for option, value, low, high, what in (
            ("--shift", args.shift, 0, MAX_SHIFT, "MAX_SHIFT: the output shift s in samples"),
            ("--half-length", args.half_length, 1, MAX_TRIAL_SAMPLES,
             "MAX_TRIAL_SAMPLES; 2M + 1 taps must also be fewer than the trial's N"),
            ("--q-order", args.q_order, 1, MAX_FILTER_ORDER, "MAX_FILTER_ORDER")):
        if not low <= value <= high:
            raise CLIError(f"{option} must be an integer in [{low}, {high}] ({what}); got "
                           f"{value}")
    # before any work: --out replaces only a design file, never one of the files read
    check_output_path(args.out, "--out", suffixes=(".toml",), replaces=not_a_design_file)
    check_not_inputs({"--out": args.out}, {"MEAS": list(args.measurements),
                                           "--reference": args.reference})
    if args.spread_factor is not None:
        raise CLIError("--spread-factor was removed: the radius is a tolerance region of the "
                       "measurements (--coverage, --confidence; default 0.95 and 0.95), or "
                       "give --radius")
    if args.radius is not None and (args.coverage is not None or args.confidence is not None):
        raise CLIError("give --radius (a given radius) or --coverage/--confidence (the "
                       "tolerance region of the measurements), not both")
    coverage = DEFAULT_COVERAGE if args.coverage is None else args.coverage
    confidence = DEFAULT_CONFIDENCE if args.confidence is None else args.confidence
    with options_named(coverage="--coverage", confidence="--confidence"):
        frf = read_frf(args.measurements, args.ts, radius=args.radius, coverage=coverage,
                       confidence=confidence)
    inputs = _names(args.inputs, "inputs", frf.n_u)
    outputs = _names(args.outputs, "outputs", frf.n_y)
    with options_named(tail="--tail"):
        design = design_from_frf(frf, shift=args.shift, half_length=args.half_length,
                                 regularization=args.regularization, band_hz=args.band_hz,
                                 q_order=args.q_order, tail=args.tail)
    if args.reference is not None:
        _check_reference(args.reference, outputs, design.condition.periodic_trial, frf.n_y)
    command = "ilc-analysis " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    save_frf_design(design, args.out, args.measurements, ts=args.ts,
                    coverage=coverage, confidence=confidence, radius=args.radius,
                    command=command,
                    reference=args.reference, inputs=inputs, outputs=outputs, tail=args.tail)
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
    print(f"[certificate] {design.finite.summary()}")
    print(f"[periodic] {design.condition.verdict}: {design.condition.reason}")
    print(f"wrote {args.out}")
    return code


def _names(text: str | None, key: str, count: int) -> list[str] | None:
    """``--inputs`` / ``--outputs``: comma-separated names, validated as ``[plant].<key>``."""
    if text is None:
        return None
    with options_named(prefix=f"--{key}"):
        return _name_list({key: [n.strip() for n in text.split(",")]}, key, count, "[plant]")


def _check_reference(path: str, outputs: list[str] | None, n: int | None, n_y: int) -> None:
    """``--reference``: read as ``learn`` will read ``[problem].reference`` (header = the output
    names, or exactly ``outputs``), N rows and one column per output of the data."""
    ref, _, _ = read_signal_file(path, "--reference", None, "reference", names=outputs)
    if ref.shape != (n, n_y):
        raise CLIError(f"--reference {path!r} must have N = {n} rows (one per sample of the "
                       f"output window) and {n_y} column(s), one per output of the FRF data; "
                       f"found shape {ref.shape}")
