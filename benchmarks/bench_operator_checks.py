"""Speed and memory of the lifted checks: the matrix-free engine and the dense worst case
(issue 26).

Each case runs in a fresh subprocess (peak RSS by ``resource.getrusage``):

* ``operator_banded_N20000``: :func:`~ilc_analysis.analysis._operator_checks.operator_checks`
  on a 20 000 x 20 000 sparse banded block lower-triangular T (a ``MatrixOperator`` of a
  sparse matrix, ||T||_2 > 1, rho < 1: the full transient walk within the product budget);
* ``dense_diverging_N250`` / ``_N500``: :func:`~ilc_analysis.analysis.lifted_checks` on a
  dense block lower-triangular T (N samples, 2 inputs) with rho = 1.001 and slow growth, the
  case that took 4 x 200 dense SVDs before (issue 26: > 20 min in analyze);
* ``dense_slow_N250`` / ``_N500``: the same with rho = 0.999 (the walk is not diverging: it
  goes sequentially within SEQUENTIAL_WALK_WORK, then by powers of two).

Printed per case: ``bench CASE: SECONDS s`` (process CPU of the checks),
``bench CASE_peak_rss: MiB`` and the verdicts as a comment. ``--small``: N = 2 000 and 50.

Run: ``PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_operator_checks.py [--small]``
(``OPENBLAS_NUM_THREADS=1`` on a loaded machine: a multi-threaded BLAS under contention makes
a 500 x 500 SVD 40 times slower).
"""

from __future__ import annotations

import json
import subprocess
import sys

SMALL = "--small" in sys.argv[1:]
CASES = (["operator_banded_N2000", "dense_diverging_N50"] if SMALL else
         ["operator_banded_N20000", "dense_diverging_N250", "dense_diverging_N500",
          "dense_slow_N250", "dense_slow_N500"])


def _dense_case(N: int, rho: float):
    import numpy as np

    rng = np.random.default_rng(0)
    b = 2
    blocks = [np.array([[rho, 0.0], [0.3, 0.5]])] + [
        0.9 ** k * rng.standard_normal((b, b)) * 0.01 for k in range(1, N)]
    T = np.zeros((N * b, N * b))
    for i in range(N):
        for j in range(i + 1):
            T[i * b:(i + 1) * b, j * b:(j + 1) * b] = blocks[i - j]
    return T


def run(case: str) -> dict:
    import resource
    import time

    import numpy as np
    import scipy.sparse

    from ilc_analysis.analysis import lifted_checks
    from ilc_analysis.analysis._operator_checks import operator_checks
    from ilc_analysis.lifting import MatrixOperator

    if case.startswith("operator_banded"):
        n = int(case.rsplit("N", 1)[1])
        rng = np.random.default_rng(0)
        diags = [rng.uniform(-0.9, 0.9, n)] + [0.3 * rng.standard_normal(n - k)
                                               for k in range(1, 5)]
        M = scipy.sparse.diags(diags, [0, -1, -2, -3, -4], format="csr")
        T = MatrixOperator(M, (1, 1))
        start = time.process_time()
        chk = operator_checks(T)
    else:
        kind, size = case.split("_")[1], int(case.rsplit("N", 1)[1])
        T = _dense_case(size, 1.001 if kind == "diverging" else 0.999)
        start = time.process_time()
        chk = lifted_checks(T, block_size=2, warn=False)
    seconds = time.process_time() - start
    d = chk.as_dict()
    return {"case": case, "seconds": round(seconds, 3),
            "peak_rss_mib": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
            **{k: d[k] for k in ("spectral_radius_verdict", "norm_2", "norm_2_upper",
                                 "norm_2_verdict", "transient_peak", "transient_peak_upper",
                                 "transient_verdict", "iterations_to_reduce", "powers_stopped",
                                 "powers_evaluated")}}


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] != "--small":
        print(json.dumps(run(sys.argv[1])))
        return
    for case in CASES:
        out = subprocess.run([sys.executable, __file__, case], capture_output=True, text=True,
                             check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"bench {case}: {r['seconds']:.4g} s")
        print(f"bench {case}_peak_rss: {r['peak_rss_mib']:.0f} MiB")
        print("# " + json.dumps(r))


if __name__ == "__main__":
    main()
