"""Speed of one constrained norm-optimal ILC update at N = 2000 (issue 14).

The plant is NOT the paper robot: its lifted system along the circle is LTV (G from per-sample
Jacobians) and :class:`~ilc_analysis.laws.ConstrainedNormOptimalLaw` has the banded state-space
QP only for an LTI plant (``plant=``); with G's dense rows (6000 x 4000, 12 M non-zeros) the QP
does not solve in minutes (measured: N = 500 with a 2x2 plant already took 10 s). So: a 2-input,
2-output LTI plant of the robot's size (two coupled damped oscillators, 4 states, ZOH at
Ts = 1 ms, N = 2000: 4000 input changes, 8000 states, 4000 errors in the QP), learning a sine /
cosine from rest with input bounds |u| <= 1.5 and rate bounds |u(k) - u(k-1)| <= 0.05, both
active, R = 1e-4, Q = 1.

Measured in one run:

* ``constrained_update_N2000``: the first ``law.update`` (builds the QP's sparsity and the CasADi
  OSQP conic, solves cold, default tolerance 1e-8 with polishing);
* the warm-started second update (trial 2 predicted through G), as a comment line;
* ``ratio constrained_vs_cvxpy``: the same QP (same variables, Hessian, constraint matrix and
  bounds) written in cvxpy and solved by its default solver (Clarabel), timed from building the
  problem to the solution, over the first update's time. The distance between the two solutions
  is printed as a comment.

Run: ``.venv/bin/python benchmarks/bench_constrained.py``
"""

from __future__ import annotations

import time

import control
import cvxpy as cp
import numpy as np

from ilc_analysis.laws import ConstrainedNormOptimalLaw
from ilc_analysis.lifting import lift
from ilc_analysis.model import DiscretePlant

N = 2000
TS = 1e-3
U_MAX, RATE = 1.5, 0.05
R, Q = 1e-4, 1.0


def plant() -> DiscretePlant:
    A = np.array([[0.0, 1.0, 0.0, 0.0], [-100.0, -12.0, 30.0, 0.0],
                  [0.0, 0.0, 0.0, 1.0], [20.0, 0.0, -200.0, -15.0]])
    B = np.array([[0.0, 0.0], [100.0, 20.0], [0.0, 0.0], [10.0, 150.0]])
    C = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
    return DiscretePlant.from_statespace(control.c2d(control.ss(A, B, C, 0.0), TS))


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def cvxpy_solve(law: ConstrainedNormOptimalLaw, u0: np.ndarray, e0: np.ndarray):
    """The law's QP (its own matrices and bounds) in cvxpy: min 1/2 x'Hx s.t. bounds."""
    H, A, _ = law._structure
    lbx, ubx, lba, uba = law._bounds(u0, e0)
    x = cp.Variable(H.shape[0])
    eq = lba == uba
    cons = [A[eq] @ x == lba[eq]]
    for mask, side in ((~eq & np.isfinite(uba), "upper"), (~eq & np.isfinite(lba), "lower")):
        if side == "upper":
            cons.append(A[mask] @ x <= uba[mask])
        else:
            cons.append(A[mask] @ x >= lba[mask])
    fx = np.isfinite(lbx)
    cons.append(x[np.flatnonzero(fx)] >= lbx[fx])
    fx = np.isfinite(ubx)
    cons.append(x[np.flatnonzero(fx)] <= ubx[fx])
    prob = cp.Problem(cp.Minimize(0.5 * cp.quad_form(x, H, assume_PSD=True)), cons)
    prob.solve()
    q = u0.size
    return u0 + x.value[:q].reshape(u0.shape), prob.status


def main() -> None:
    dp = plant()
    ls = lift(dp, N)
    t = TS * np.arange(N)
    y_d = np.column_stack([np.sin(2 * np.pi * t / (N * TS)),
                           np.cos(2 * np.pi * t / (N * TS)) - 1.0])
    r = y_d.reshape(-1) - ls.d
    u0 = np.zeros((N, 2))
    e0 = (r - ls.G @ u0.reshape(-1)).reshape(N, 2)
    law = ConstrainedNormOptimalLaw(ls, Q, R, input_bounds=(-U_MAX, U_MAX), rate_bounds=RATE,
                                    plant=dp, initial_input=u0)
    first, u1 = timed(lambda: law.update(u0, e0, TS))
    e1 = (r - ls.G @ u1.reshape(-1)).reshape(N, 2)
    second, _ = timed(lambda: law.update(u1, e1, TS))
    cert = law.history[0]
    active_u = int(np.sum(np.abs(u1) > U_MAX - 1e-6))
    active_r = int(np.sum(np.abs(np.diff(u1, axis=0)) > RATE - 1e-6))
    print(f"# 2-input LTI plant (not the robot: see the docstring), N = {N}; QP variables "
          f"{law._structure[0].shape[0]}, constraint non-zeros {law._structure[1].nnz}; "
          f"{active_u} input and {active_r} rate bounds active; status {cert.status}, "
          f"predicted cost {cert.cost_before:.4g} -> {cert.cost_after:.4g}")
    print(f"bench constrained_update_N{N}: {first:.3f} s")
    print(f"# warm-started second update: {second:.3f} s")
    t_cvx, (u_cvx, status) = timed(lambda: cvxpy_solve(law, u0, e0))

    def cost(u):
        du = (u - u0).reshape(-1)
        e = e0.reshape(-1) - ls.G @ du
        return Q * e @ e + R * du @ du

    worst = max(law._violations(u_cvx, None).values())
    print(f"# cvxpy (default solver) same QP: {t_cvx:.3f} s, status {status}, max |u_casadi - "
          f"u_cvxpy| = {np.max(np.abs(u_cvx - u1)):.2e}; cost casadi {cost(u1):.10g}, cvxpy "
          f"{cost(u_cvx):.10g} (largest bound violation of cvxpy's input {worst:.1e})")
    print(f"ratio constrained_vs_cvxpy: {t_cvx / first:.1f} x")


if __name__ == "__main__":
    main()
