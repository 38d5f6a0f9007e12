"""Speed of one constrained norm-optimal ILC update for the robot at N = 2000 (issue 14).

The problem: the paper's balanced robot (7 states, 2 torque commands, outputs X, Y, psi) on
the paper's circle over one lap, sampled at 1 kHz (N = 2000, ts = 1 ms, RK4 with the scenario's
sub-steps), linearised along the circle's realisable input u_d. The law:
:class:`~ilc_analysis.laws.ConstrainedNormOptimalLaw` in stage form (the robot's per-sample
Jacobians, HPIPM through ``casadi.conic``) with Q = 1, R = 1e-3 sigma^2 where sigma^2 is
estimated by power iteration on the stage model (no dense G: at N = 2000 it has 24 million
entries), torque bounds |u| <= 0.15 N m, rate bounds |u(k) - u(k-1)| <= 2e-4 N m and the pitch
bound |theta| <= 0.06 rad, from the scenario's first trial (u0 = 0.1 N m, simulated).

Measured in one run:

* ``constrained_setup_N2000``: building the law and its QP solver (once per law: the stage
  Jacobians along u_d, the QP's sparsity, the HPIPM instance);
* ``constrained_update_N2000``: one ``law.update`` after trial 1 (the per-trial cost);
* ``ratio constrained_vs_cvxpy``: the same QP (the law's own H, A, g and bounds: the same
  variables and constraints) written in cvxpy and solved by its default QP solver, timed from
  building the problem to the solution, over the update's time. The distance between the two
  solutions and their costs are printed as comments.

Run: ``.venv/bin/python benchmarks/bench_constrained.py``
"""

from __future__ import annotations

import dataclasses
import time

import cvxpy as cp
import numpy as np

from ilc_analysis.laws import ConstrainedNormOptimalLaw
from ilc_analysis.lifting import TrialMap
from ilc_analysis.paper._config import paper_scenario
from ilc_analysis.paper._designs import scenario_problem
from ilc_analysis.paper._pipeline import scenario_disturbances

N = 2000
TORQUE, RATE, THETA = 0.15, 2e-4, 0.06


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def sigma_max_squared(tm: TrialMap, u, iterations: int = 30) -> float:
    """sigma_max(G)^2 by power iteration on G^T G with the trial map's forward and adjoint
    products (matrix-free)."""
    v = np.ones(u.size) / np.sqrt(u.size)
    lam = 0.0
    for _ in range(iterations):
        w = tm.vjp(u, tm.jvp(u, v))
        lam = float(np.linalg.norm(w))
        v = w / lam
    return lam


def cvxpy_solve(qp, stages, e, u, y, x):
    """The law's stage QP (same H, A, g and bounds) in cvxpy: min 1/2 z'Hz + g'z s.t. bounds."""
    H, A, g, _ = qp.matrices(stages, e, None)
    lbx, ubx, lba, uba = qp.bounds(u, y, x)
    z = cp.Variable(H.shape[0])
    eq = lba == uba
    cons = [A[eq] @ z == lba[eq]]
    up, lo = ~eq & np.isfinite(uba), ~eq & np.isfinite(lba)
    if up.any():
        cons.append(A[up] @ z <= uba[up])
    if lo.any():
        cons.append(A[lo] @ z >= lba[lo])
    for mask, side in ((np.isfinite(lbx), "lower"), (np.isfinite(ubx), "upper")):
        idx = np.flatnonzero(mask)
        cons.append(z[idx] >= lbx[idx] if side == "lower" else z[idx] <= ubx[idx])
    prob = cp.Problem(cp.Minimize(0.5 * cp.quad_form(z, H, assume_PSD=True) + g @ z), cons)
    prob.solve()
    du, _, _ = qp.trajectories(stages, z.value)
    return du, prob.status, float(prob.value)


def main() -> None:
    sc = paper_scenario()
    sc = dataclasses.replace(sc, ts=sc.horizon / N)
    problem = scenario_problem(sc, disturbances=scenario_disturbances(sc, seed=0))[0]
    tm = TrialMap(problem.dplant, N, problem.shift, x0=problem.x0, t0=problem.t0)
    sigma2 = sigma_max_squared(tm, problem.u_nominal)

    def build():
        law = ConstrainedNormOptimalLaw(
            problem, 1.0, 1e-3 * sigma2, input_bounds=(-TORQUE, TORQUE), rate_bounds=RATE,
            state_bounds={"theta": (-THETA, THETA)})
        _ = law.stage_qp          # the QP's structure
        law.stage_qp._build()     # and its solver instance
        return law

    setup, law = timed(build)
    u0 = problem.initial_input()
    X, Y = tm.trajectory(u0)      # the first trial (the model's plant, no disturbance)
    e0 = problem.reference - Y
    update, u1 = timed(lambda: law.update(u0, e0, problem.ts, states=X))
    cert = law.history[-1]
    qp = law.stage_qp
    active_u = int(np.sum(np.abs(u1) > TORQUE - 1e-6))
    active_r = int(np.sum(np.abs(np.diff(u1, axis=0)) > RATE - 1e-6))
    print(f"# robot (mobile_balanced), N = {problem.N}, ts = {problem.ts:g} s; QP variables "
          f"{qp.n_var}, constraints {qp.n_con}; {active_u} torque and {active_r} rate bounds "
          f"active; status {cert.status} ({cert.solver_status}); predicted cost "
          f"{cert.cost_before:.4g} -> {cert.cost_after:.4g}; predicted violations "
          f"{cert.predicted_violation}")
    print(f"bench constrained_setup_N{N}: {setup:.3f} s")
    print(f"bench constrained_update_N{N}: {update:.3f} s")
    t_cvx, (du_cvx, status, value) = timed(
        lambda: cvxpy_solve(qp, law.stages, e0, u0, None, X))
    print(f"# cvxpy (default solver) on the same QP: {t_cvx:.3f} s, status {status}, max "
          f"|du_hpipm - du_cvxpy| = {np.max(np.abs(du_cvx - (u1 - u0))):.2e}; cost hpipm "
          f"{cert.cost_after:.10g}, cvxpy {value + cert.cost_before:.10g}")
    print(f"ratio constrained_vs_cvxpy: {t_cvx / update:.1f} x")


if __name__ == "__main__":
    main()
