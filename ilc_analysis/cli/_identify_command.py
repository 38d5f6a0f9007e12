"""``ilc-analysis identify``: Markov parameters and their confidence bound from recorded trials.

Each trial is a CSV file (:func:`~ilc_analysis.simulation.read_trial_csv`: a header naming
exactly the ``--inputs`` and ``--outputs`` channels, one row per sample); row k holds the input
u(k) and the output of the window y(s + k), s = ``--shift``. The identification is
:func:`~ilc_analysis.lifting.identify_markov`; ``--out`` writes its FIR realisation as the
arrays A, B, C, D, dt of a discrete plant, which a design file reads as ``[plant] file``
(with ``[problem] shift`` equal to ``--shift``).

The assumptions the bounds rest on are tested on the same records where they allow it (the
FIR length against a longer FIR and against repeated trials, whiteness and normality of the
repeat differences, at ``--test-level`` together; :mod:`ilc_analysis.lifting.
_assumption_tests`). Exit 0 when no assumption is refuted, 1 when the data refute one (each
refuted test is printed with its remedy, e.g. the FIR length to try; ``--out`` is still
written), 2 on bad input.
"""

from __future__ import annotations

import argparse

import numpy as np

from .._array_files import other_arrays
from .._output import check_not_inputs, check_output_path, output_file
from .._validation import MAX_SHIFT, MAX_STATES, MAX_TRIAL_SAMPLES
from ..lifting import NOISE_ESTIMATES, identify_markov
from ..lifting._assumption_tests import DEFAULT_TEST_LEVEL
from ..simulation import read_trial_csv
from ._common import CLIError, emit_json, options_named

#: what ``--out`` may replace: a plant file of the arrays it writes
_PLANT_ARRAYS = other_arrays(("A", "B", "C", "D", "dt"))


def _names(text: str, option: str) -> list[str]:
    names = [n.strip() for n in text.split(",")]
    if not all(names) or len(set(names)) != len(names):
        raise CLIError(f"{option} must be a comma-separated list of distinct channel names; "
                       f"got {text!r}")
    return names


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "identify",
        description="Identify the Markov parameters h_0..h_{M-1} of an LTI plant from recorded "
                    "trials (each started from rest) by least squares, with the noise level "
                    "estimated from the data and a bound on ||G - G_hat||_2 at the stated "
                    "confidence (Gaussian noise; the FIR length M is an assumption). Each "
                    "TRIAL is a CSV file whose header names exactly the --inputs and "
                    "--outputs channels; row k holds u(k) and y(s + k).")
    p.add_argument("trials", nargs="+", metavar="TRIAL.csv", help="one CSV file per trial")
    p.add_argument("--inputs", required=True, metavar="U1,U2,...",
                   help="input channel names (columns of each trial file)")
    p.add_argument("--outputs", required=True, metavar="Y1,Y2,...",
                   help="output channel names (columns of each trial file)")
    p.add_argument("--fir-length", required=True, type=int, metavar="M",
                   help="number of Markov parameters (1 <= M <= N); later ones are assumed 0")
    p.add_argument("--ts", required=True, type=float, help="sample time in seconds")
    p.add_argument("--shift", type=int, default=1,
                   help="output-window shift s of the records (default 1)")
    p.add_argument("--confidence", type=float, default=0.95,
                   help="confidence level of the bounds (default 0.95)")
    p.add_argument("--noise", choices=NOISE_ESTIMATES, default="residuals",
                   help="noise variance from the residuals (default) or from trials repeated "
                        "with identical inputs")
    p.add_argument("--test-level", type=float, default=DEFAULT_TEST_LEVEL,
                   help="level of the tests of the assumptions (FIR length, white Gaussian "
                        f"noise) together (default {DEFAULT_TEST_LEVEL:g})")
    p.add_argument("--out", metavar="PLANT.npz",
                   help="write the identified FIR plant (arrays A, B, C, D, dt) for a design "
                        "file's [plant] file")
    p.add_argument("--json", action="store_true",
                   help="print the identification (estimates, bounds, assumptions) as JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    inputs = _names(args.inputs, "--inputs")
    outputs = _names(args.outputs, "--outputs")
    if set(inputs) & set(outputs):
        raise CLIError(f"--inputs and --outputs must not share a channel; both name "
                       f"{sorted(set(inputs) & set(outputs))}")
    # the sizes the options set, before any file is read
    if not 0 <= args.shift <= MAX_SHIFT:
        raise CLIError(f"--shift must be an integer in [0, {MAX_SHIFT}] (MAX_SHIFT: the "
                       f"output-window shift s in samples); got {args.shift}")
    if not 1 <= args.fir_length <= MAX_TRIAL_SAMPLES:
        raise CLIError(f"--fir-length must be an integer in [1, {MAX_TRIAL_SAMPLES}] "
                       f"(MAX_TRIAL_SAMPLES, and at most the trials' N); got {args.fir_length}")
    if args.out is not None:
        states = max(args.fir_length - 1 + args.shift, 1) * len(inputs)
        if states > MAX_STATES:
            raise CLIError(f"--out: the FIR realisation would have {states} states "
                           f"((--fir-length - 1 + --shift) x {len(inputs)} input(s)); at most "
                           f"{MAX_STATES} (MAX_STATES, the most a design file's [plant] file "
                           f"may have): use a smaller --fir-length")
        check_output_path(args.out, "--out", suffixes=(".npz",), replaces=_PLANT_ARRAYS)
        check_not_inputs({"--out": args.out}, {"TRIAL": list(args.trials)})
    records = [read_trial_csv(path, inputs + outputs, option="TRIAL") for path in args.trials]
    us = [r[:, :len(inputs)] for r in records]
    ys = [r[:, len(inputs):] for r in records]
    with options_named(test_level="--test-level", confidence="--confidence",
                       fir_length="--fir-length", shift="--shift", ts="--ts"):
        model = identify_markov(us, ys, fir_length=args.fir_length, ts=args.ts, shift=args.shift,
                                confidence=args.confidence, noise=args.noise,
                                trial_names=[f"TRIAL {t}" for t in args.trials],
                                test_level=args.test_level)
    code = 1 if model.refuted else 0
    if args.out is not None:
        A, B, C, D = model.realization()
        with output_file(args.out, "--out", suffixes=(".npz",), replaces=_PLANT_ARRAYS) as tmp, \
                open(tmp, "wb") as f:
            np.savez(f, A=A, B=B, C=C, D=D, dt=np.float64(model.ts))
    if args.json:
        emit_json({**model.as_dict(), "inputs": inputs, "outputs": outputs,
                   "trial_files": [str(t) for t in args.trials], "exit_status": code})
        return code
    print(model.summary())
    for test in model.tests:
        print(f"  {test.text()}")
    for note in model.untested:
        print(f"  {note}")
    if args.out is not None:
        print(f"wrote {args.out} (discrete plant, {A.shape[0]} states; set [problem] "
              f"shift = {model.shift})")
    if code:
        print("the data REFUTE an assumption of the bounds: they are not claimed (see above)")
    return code
