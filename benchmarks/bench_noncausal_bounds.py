"""Issue 34: the standard SISO law shapes at 1 kHz decided on the operator engine at N = 2 000.

The shapes (``benchmarks/cases.py``, :data:`cases.SHAPES`, true ||T||_2 between 0.5 and 0.99):
P-type with a lead and a zero-phase Butterworth Q; the same with scipy's odd-extension
Butterworth and forgetting; Q/L with a zero-phase Q and an advance; an inverse model with a DCT
Q; norm-optimal ILC built on the dense ``problem.lifted``; gradient ILC with
beta = 1/sigma_max(G)^2; a causal P-type law at a PI loop's reference. Each is analysed by
``ilc.analyze(problem, law, engine='operator')`` (every condition, defaults) and, in the same
run, by ``engine='dense'``; the problem and the law are built before the clock starts.

Lines: ``bench shape_NAME: VALUE s`` (process CPU time of the operator engine's analyze),
``ratio shape_NAME_vs_dense: VALUE x`` (the dense engine's CPU time over it), and a comment
line with the verdicts and the ||T||_2 interval. Target: each shape decided (``norm_2`` and
``spectral_radius`` hold) in at most 2 s, reported as a ``# target ...: met/MISSED`` comment (a
loaded machine can miss it); exit status 1 only for a wrong result: an operator-engine verdict
that the dense engine contradicts (``holds`` against ``fails`` or the reverse).

Run: ``PYTHONPATH=$PWD MPLBACKEND=Agg .venv/bin/python benchmarks/bench_noncausal_bounds.py``
(``--small``: the shapes at N = 200, the operator checks kept matrix-free, same lines;
``--no-dense``: without the dense baseline).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import cases  # noqa: E402

#: the issue's trial length and target
N_FULL, TARGET_SECONDS = 2_000, 2.0
N_SMALL = 200


def _timed(problem, law, engine: str):
    import ilc_analysis as ilc
    from ilc_analysis.exceptions import ILCWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ILCWarning)
        t0 = time.process_time()
        res = ilc.analyze(problem, law, engine=engine)
        return res, time.process_time() - t0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--small", action="store_true", help=f"the shapes at N = {N_SMALL}")
    parser.add_argument("--no-dense", action="store_true", help="skip the dense baseline")
    args = parser.parse_args(argv)
    N = N_SMALL if args.small else N_FULL
    from threadpoolctl import threadpool_limits

    if args.small:          # below 500 rows the operator checks would form T: stay matrix-free
        import ilc_analysis.analysis._operator_checks as operator_checks

        operator_checks.DENSE_MAX = 0

    missed, wrong = [], []
    with threadpool_limits(limits=1, user_api="blas"):
        for name, build in cases.SHAPES.items():
            problem, law = build(N)
            res, seconds = _timed(problem, law, "operator")
            checks = next(iter(res.lifted.values()))
            verdicts = {c: res.verdict(c) for c in ("norm_2", "spectral_radius", "norm_inf",
                                                    "transient_peak", "error_norm_2")
                        if c in res}
            print(f"# {name} (N={N}): ||T||_2 in [{checks.norm_2_lower}, "
                  f"{checks.norm_2_upper}]; {verdicts}", flush=True)
            print(f"bench shape_{name}: {seconds:.3f} s", flush=True)
            decided = verdicts.get("norm_2") == "holds" and \
                verdicts.get("spectral_radius") == "holds"
            if not args.small:
                print(f"# target shape_{name}: "
                      f"{'met' if decided and seconds <= TARGET_SECONDS else 'MISSED'} "
                      f"(norm_2 {verdicts.get('norm_2')}, spectral_radius "
                      f"{verdicts.get('spectral_radius')} in {seconds:.2f} s CPU; target "
                      f"decided in <= {TARGET_SECONDS:g} s)", flush=True)
            if not decided:
                missed.append(name)
            if not args.no_dense:
                dense, dense_s = _timed(problem, law, "dense")
                dense_verdicts = {c: dense.verdict(c) for c in verdicts}
                print(f"# {name}: dense ||T||_2 = {next(iter(dense.lifted.values())).norm_2:.6g}"
                      f", verdicts {list(dense_verdicts.values())}", flush=True)
                print(f"ratio shape_{name}_vs_dense: {dense_s / max(seconds, 1e-9):.3g} x",
                      flush=True)
                wrong += [f"{name}.{c}: operator {o}, dense {dense_verdicts[c]}"
                          for c, o in verdicts.items()
                          if {o, dense_verdicts[c]} == {"holds", "fails"}]
    if missed:
        print(f"# undecided: {', '.join(missed)}")
    for line in wrong:
        print(f"# WRONG {line}")
    return 1 if wrong else 0

if __name__ == "__main__":
    sys.exit(main())
