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

Run: ``.venv/bin/python benchmarks/bench_conditions.py``
"""

from __future__ import annotations

import sys
import time

import numpy as np

from ilc_analysis.cli.check_command import paper_default_gains
from ilc_analysis.conditions import structured_learning_operator
from ilc_analysis.lifting import circle_nominal, learning_operator, learning_operators, lift
from ilc_analysis.model import balanced_mobile_robot, discretize

N = 2000
TS = 0.001
A_FORGET = 0.15
RTOL = 1e-6


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def main() -> int:
    plant = balanced_mobile_robot()
    dp = discretize(plant, TS)
    circle = circle_nominal(plant, N, TS)
    t_lift, ls = timed(lambda: lift(dp, N, x0=circle.x0, u_nominal=circle.u_nominal))
    gains = paper_default_gains("mobile", plant)
    L1, L2 = learning_operators(gains, N, ls.shift, TS, n_u=plant.n_u, n_y=plant.n_y)
    print(f"# lift (context, not part of either timing): {t_lift:.2f} s, G {ls.G.shape}")

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

    print(f"# structured operator: {kind}")
    print(f"# rho: structured {rho_s:.12g}, dense diagonal blocks {rho_blocks:.12g}, "
          f"dense eigvals {rho_d:.6g} (inaccurate: defective clusters)")
    print(f"# ||T||_2: structured {n2_s:.12g}, dense {n2_d:.12g}")
    print(f"bench check_N2000: {t_s:.3f} s")
    print(f"bench check_dense_N2000: {t_d:.3f} s")
    print(f"ratio check_vs_dense: {t_d / t_s:.1f} x")
    ok = (abs(n2_s - n2_d) <= RTOL * n2_d and abs(rho_s - rho_blocks) <= RTOL * rho_blocks)
    print(f"# agreement to {RTOL:g} relative: {'yes' if ok else 'NO'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
