"""Speed of the lifted convergence checks (issue 5): structured vs dense numpy.

The balanced mobile robot (the paper scenario's model) along the paper's circle, one lap
T = 2 s sampled at Ts = 1 ms: N = 2000, G of 6000 x 4000 (linear time-varying: the Jacobian of
the trial map along the input that sustains the circle). Gains: the documented default gain
set of ``ilc-analysis check --scenario paper`` (constant), constant forgetting a = 0.15.
T = (I + L2 G)^-1 (I - A - L1 G) is 4000 x 4000.

* ``check_N2000`` — structured: the spectral radius from T's diagonal blocks (exact: T is block
  lower-triangular) and ||T||_2 by Lanczos (ARPACK ``svds``) on products with G, the sparse
  L1, L2 and triangular solves with I + L2 G; T is never formed.
* the dense baseline — form T with numpy/scipy, ``numpy.linalg.eigvals`` and
  ``numpy.linalg.norm(T, 2)``. Its eigenvalues are *not* accurate here (each diagonal block's
  eigenvalues form a defective cluster); the spectral radius is therefore also checked against
  the diagonal blocks of the dense T, and the plain dense value is printed for the record.

Both must agree to 1e-6 relative (||T||_2; rho against the dense diagonal blocks).
The lifting itself (``lift``) is timed separately: both methods start from G.

``check_clustered_N2000`` (issue 12, item 11) — the whole dense ``analyze(ILCProblem, PDLaw,
engine='dense')`` (the matrix-free engine's numbers are in ``bench_matrix_free.py``)
(lifting, theorem, lifted checks, frequency condition) on a case whose ||T||_2 < 1 has clustered
top singular values, where ARPACK with an unbounded iteration count took 35 s at N = 500, 434 s
at N = 2000 and over 20 minutes inside ``analyze``. Built as: the first-order lag 30/(s + 30)
sampled at Ts = 0.01 s (pole 0.74), N = 2000, the P-type gain Psi1 = 0.5 (no derivative, no
current-trial term, no forgetting), so T = I - 0.5 G is lower-triangular Toeplitz with diagonal
0.870, ||T||_2 = 0.926 and its top singular values within about 1e-8 of each other (the finite
section of a smooth symbol that peaks at one frequency). Lanczos stops at its product budget, a
dense eigen-solver of the Gram matrix answers, and the powers decrease, so the first k with
||T^k||_2 <= 1/10 needs one more norm (k = 30). The value must not exceed 10 s; the run also
checks ||T||_2 and that k against a dense computation.

Times are process CPU seconds. ``--small``: N = 200 (both cases), for the test suite.

Run: ``.venv/bin/python benchmarks/bench_conditions.py [--small]``
"""

from __future__ import annotations

import sys

import control
import numpy as np
from harness import bench, comment, cpu, load, pick, ratio, target

import ilc_analysis as ilc
from ilc_analysis.analysis._structured import structured_learning_operator
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.lifting import learning_operator, lift
from ilc_analysis.model import Plant, balanced_mobile_robot, discretize
from ilc_analysis.paper import circle_nominal, paper_default_gains

N = pick(2000, 200)
TS = 0.001
A_FORGET = 0.15
RTOL = 1e-6


def timed(fn):
    return cpu(fn)


def clustered() -> tuple[float, bool]:
    """``analyze`` on the clustered case (module docstring); returns (seconds, agrees)."""
    plant = control.ss([[-30.0]], [[30.0]], [[1.0]], [[0.0]])
    gains = ilc.PDGains([[0.0]], [[0.0]], [[0.5]], [[0.0]])
    problem = ilc.ILCProblem(plant, ts=0.01, N=N, reference=np.zeros((N, 1)))
    t, report = timed(lambda: ilc.analyze(problem, ilc.PDLaw(gains), engine="dense"))
    checks = report.lifted["a=0"]
    ls = lift(discretize(Plant.from_statespace(plant), 0.01), N)
    L1, L2 = learning_operators(gains, N, ls.shift, 0.01)
    T = learning_operator(ls.G, L1, L2, 0.0)
    sv = np.linalg.svd(T, compute_uv=False)
    k = report["iterations_to_reduce"].value
    ok = (abs(report["norm_2"].value - sv[0]) <= RTOL * sv[0]
          and np.linalg.norm(np.linalg.matrix_power(T, k), 2) <= 0.1
          < np.linalg.norm(np.linalg.matrix_power(T, k - 1), 2))
    comment(f"clustered: top singular values {sv[0]:.12g}, {sv[1]:.12g} (gap "
          f"{sv[0] - sv[1]:.2g}); ||T||_2 by {checks.norm_2_method}; k = {k} with "
          f"{len(checks.norm_history)} power norms; verdict: {report.summary()}")
    return t, ok


def main() -> int:
    plant = balanced_mobile_robot()
    dp = discretize(plant, TS)
    circle = circle_nominal(plant, N, TS)
    t_lift, ls = timed(lambda: lift(dp, N, x0=circle.x0, u_nominal=circle.u_nominal))
    gains = paper_default_gains("mobile", plant)
    L1, L2 = learning_operators(gains, N, ls.shift, TS, n_u=plant.n_u, n_y=plant.n_y)
    comment(f"lift (context, not part of either timing): {t_lift:.2f} s, G {ls.G.shape}")

    def structured():
        op = structured_learning_operator(ls.G, L1, L2, A_FORGET, n_u=plant.n_u, n_y=plant.n_y)
        rho, _ = op.spectral_radius()
        norm2, _ = op.norm_2()
        return type(op).__name__, rho, norm2

    t_s, (kind, rho_s, n2_s) = timed(structured)

    def dense():
        T = learning_operator(ls.G, L1, L2, A_FORGET)
        rho = float(np.max(np.abs(np.linalg.eigvals(T))))
        norm2 = float(np.linalg.norm(T, 2))
        return T, rho, norm2

    t_d, (T, rho_d, n2_d) = timed(dense)
    nu = plant.n_u
    blocks = np.stack([T[k * nu:(k + 1) * nu, k * nu:(k + 1) * nu] for k in range(N)])
    rho_blocks = float(np.max(np.abs(np.linalg.eigvals(blocks))))

    comment(f"structured operator: {kind}")
    comment(f"rho: structured {rho_s:.12g}, dense diagonal blocks {rho_blocks:.12g}, "
          f"dense eigvals {rho_d:.6g} (inaccurate: defective clusters)")
    comment(f"||T||_2: structured {n2_s:.12g}, dense {n2_d:.12g}")
    bench(f"check_N{N}", t_s)
    bench(f"check_dense_N{N}", t_d)
    ratio("check_vs_dense", t_d / t_s)
    ok = (abs(n2_s - n2_d) <= RTOL * n2_d and abs(rho_s - rho_blocks) <= RTOL * rho_blocks)
    comment(f"agreement to {RTOL:g} relative: {'yes' if ok else 'NO'}")
    t_c, ok_c = clustered()
    bench(f"check_clustered_N{N}", t_c)
    comment(f"clustered case agrees with the dense computation: {'yes' if ok_c else 'NO'}; "
            f"{load()}")
    target(f"check_clustered_N{N}", t_c <= 10.0, f"{t_c:.2f} s of CPU, bound 10 s")
    return 0 if (ok and ok_c) else 1


if __name__ == "__main__":
    sys.exit(main())
