"""Speed of one constrained norm-optimal ILC update for the robot at N = 2000 (issue 14).

The problem: the paper's balanced robot (7 states, 2 torque commands, outputs X, Y, psi) on
the paper's circle over one lap, sampled at 1 kHz (N = 2000, ts = 1 ms, RK4 with the scenario's
sub-steps), linearised along the circle's realisable input u_d. The law:
:class:`~ilc_analysis.laws.ConstrainedNormOptimalLaw` in stage form (the robot's per-sample
Jacobians, HPIPM through ``casadi.conic``) with Q = 1, R = 1e-3 sigma^2 where sigma^2 is
estimated by power iteration on the stage model (no dense G: at N = 2000 it has 24 million
entries), torque bounds |u| <= 0.15 N m, rate bounds |u(k) - u(k-1)| <= 2e-4 N m and the pitch
bound |theta| <= 0.06 rad, from the scenario's first trial (u0 = 0.1 N m, simulated).

Measured in one run (process CPU seconds):

* ``constrained_setup_N2000``: building the law and its QP solver (once per law: the stage
  Jacobians along u_d, the QP's stage structure, the HPIPM instance); target <= 2 s;
* ``constrained_update_N2000``: one ``law.update`` after trial 1 (the per-trial cost: the
  stage data, HPIPM's solve, the solution's cost and its constraint check), median of three;
* ``ratio constrained_vs_cvxpy_clarabel``: the same QP (the law's own H, A, g and bounds: the
  same variables and constraints) written in cvxpy and solved by Clarabel, timed from building
  the problem to the solution, over the update's time; target >= 3. Both costs must agree to
  1e-6 relative (exit 1 otherwise); the distance between the two steps and Clarabel's own
  solve time are printed as comments.

The double-mass servo case (issue 27): the two-mass drive under notebook 05's PID, learning
the loop's reference, at N = 471 (``benchmarks/cases.py``), with the constrained ILC of
Liao-McPherson et al. (the form of IterativeLearningControl2.jl's ``ConstrainedILC``): Q = 1000,
input weight S = 1e-3 on the learned reference, step size alpha = 0.5, a change weight
R = 1e-6 (the toolkit requires R > 0), the reference within +-0.15 m and the output below
0.105 m (5 % overshoot of the 0.1 m move; the plain PID loop overshoots to 0.131 m):

* ``constrained_servo_setup_N471``: building the law and its stage QP (HPIPM);
* ``constrained_servo_update_N471``: one stage-form update after trial 1;
* ``constrained_servo_update_lifted_N471``: the same step in the lifted form (G's rows, OSQP);
* ``ratio constrained_servo_dense_vs_stage``: the same step written densely as that package
  does, min (v - u)'W(v - u) + 2 alpha (v - u)'g with the model-derived W = G'QG + R + S
  (471 x 471) in cvxpy, over the stage-form update; the distance between the solutions is
  printed as a comment, with ten simulated trials' error norms.

``--small``: the robot at N = 200 and the servo at N = 100.

Run: ``.venv/bin/python benchmarks/bench_constrained.py [robot|servo] [--small]`` (default: both)
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import cvxpy as cp
import numpy as np
from harness import bench, c_stdout_to_stderr, comment, cpu, load, pick, ratio, target

from ilc_analysis.laws import ConstrainedNormOptimalLaw
from ilc_analysis.lifting import TrialMap
from ilc_analysis.paper._config import paper_scenario
from ilc_analysis.paper._designs import scenario_problem
from ilc_analysis.paper._pipeline import scenario_disturbances
from ilc_analysis.simulation import simulate

N = pick(2000, 200)
TORQUE, RATE, THETA = 0.15, 2e-4, 0.06
SETUP_TARGET, RATIO_TARGET = 2.0, 3.0


def timed(fn):
    return cpu(fn)


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
    """The law's stage QP (same H, A, g and bounds) in cvxpy, solved by Clarabel:
    min 1/2 z'Hz + g'z s.t. bounds."""
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
    prob.solve(solver=cp.CLARABEL)
    du, _, _ = qp.trajectories(stages, z.value)
    return du, prob.status, float(prob.value), prob.solver_stats.solve_time


def robot() -> bool:
    sc = paper_scenario()
    sc = dataclasses.replace(sc, ts=sc.horizon / N)
    problem = scenario_problem(sc, disturbances=scenario_disturbances(sc, seed=0))[0]
    tm = TrialMap(problem.dplant, N, problem.shift, x0=problem.x0, t0=problem.t0)
    sigma2 = sigma_max_squared(tm, problem.u_nominal)

    def build():
        law = ConstrainedNormOptimalLaw(
            problem, 1.0, 1e-3 * sigma2, input_bounds=(-TORQUE, TORQUE), rate_bounds=RATE,
            state_bounds={"theta": (-THETA, THETA)})
        law.stage_qp.prepare()     # the QP's structure and its solver instance
        return law

    setup, law = timed(build)
    u0 = problem.initial_input()
    X, Y = tm.trajectory(u0)      # the first trial (the model's plant, no disturbance)
    e0 = problem.reference - Y

    def update():
        law.reset()
        return law.update(u0, e0, problem.ts, states=X)

    t_update, u1 = cpu(update, 3)
    cert = law.history[-1]
    qp = law.stage_qp
    active_u = int(np.sum(np.abs(u1) > TORQUE - 1e-6))
    active_r = int(np.sum(np.abs(np.diff(u1, axis=0)) > RATE - 1e-6))
    comment(f"robot (mobile_balanced), N = {problem.N}, ts = {problem.ts:g} s; QP variables "
            f"{qp.n_var}, constraints {qp.n_con}; {active_u} torque and {active_r} rate bounds "
            f"active; status {cert.status} ({cert.solver_status}); KKT residuals "
            f"{ {k: float(f'{v:.2g}') for k, v in cert.residuals.items()} }; predicted cost "
            f"{cert.cost_before:.4g} -> {cert.cost_after:.4g}; predicted violations "
            f"{cert.predicted_violation}")
    bench(f"constrained_setup_N{N}", setup)
    bench(f"constrained_update_N{N}", t_update)
    t_cvx, (du_cvx, status, value, solve_wall) = timed(
        lambda: cvxpy_solve(qp, law.stages, e0, u0, None, X))
    cost_cvx = value + cert.cost_before
    agree = abs(cost_cvx - cert.cost_after) <= 1e-6 * max(abs(cert.cost_after), 1.0)
    comment(f"cvxpy + Clarabel on the same QP: {t_cvx:.3f} s of CPU (Clarabel's own solve "
            f"{solve_wall:.3f} s wall), status {status}, max |du_hpipm - du_clarabel| = "
            f"{np.max(np.abs(du_cvx - (u1 - u0))):.2e}; cost hpipm {cert.cost_after:.10g}, "
            f"clarabel {cost_cvx:.10g} ({'agree' if agree else 'DISAGREE'} to 1e-6)")
    bench(f"cvxpy_clarabel_N{N}", t_cvx)
    ratio(f"constrained_update_N{N}_vs_cvxpy_clarabel", t_cvx / t_update)
    target(f"constrained_setup_N{N}", setup <= SETUP_TARGET,
           f"{setup:.2f} s of CPU, bound {SETUP_TARGET:g} s; {load()}")
    target(f"constrained_update_N{N}", t_cvx / t_update >= RATIO_TARGET,
           f"{t_cvx / t_update:.2f} x cvxpy + Clarabel, at least {RATIO_TARGET:g} x")
    return agree


#: the servo case's law (module docstring)
SERVO_N, SERVO_Q, SERVO_R, SERVO_S, SERVO_ALPHA = pick(471, 100), 1000.0, 1e-6, 1e-3, 0.5
SERVO_R_BOUND, SERVO_Y_MAX = 0.15, 0.105


def servo_law(problem, **options):
    return ConstrainedNormOptimalLaw(
        problem, SERVO_Q, SERVO_R, weight_input=SERVO_S, step_size=SERVO_ALPHA,
        input_bounds=(-SERVO_R_BOUND, SERVO_R_BOUND), output_bounds=(None, SERVO_Y_MAX),
        **options)


def servo() -> bool:
    sys.path.insert(0, str(Path(__file__).parent))
    from cases import _servo_problem

    problem = _servo_problem(SERVO_N)
    G = problem.lifted.G

    def build():
        law = servo_law(problem)
        law.stage_qp.prepare()
        return law

    setup, law = timed(build)
    u0 = problem.initial_input()
    y0 = (G @ u0.reshape(-1) + problem.lifted.d).reshape(u0.shape)
    e0 = problem.reference - y0
    update, u1 = timed(lambda: law.update(u0, e0, problem.ts))
    cert = law.history[-1]
    lifted = servo_law(problem.lifted, reference=problem.reference, initial_input=u0,
                       solver="osqp")
    with c_stdout_to_stderr():
        t_lifted, u1_lifted = timed(lambda: lifted.update(u0, e0, problem.ts))
    # the dense projected Newton step with the model-derived weight
    N = SERVO_N
    W = SERVO_Q * G.T @ G + (SERVO_R + SERVO_S) * np.eye(N)
    g = SERVO_S * u0.reshape(-1) - SERVO_Q * G.T @ e0.reshape(-1)
    y_now = (problem.reference - e0).reshape(-1)

    def dense():
        d = cp.Variable(N)
        v = u0.reshape(-1) + d
        prob = cp.Problem(cp.Minimize(cp.quad_form(d, W, assume_PSD=True)
                                      + 2 * SERVO_ALPHA * g @ d),
                          [v >= -SERVO_R_BOUND, v <= SERVO_R_BOUND, y_now + G @ d <= SERVO_Y_MAX])
        prob.solve()
        return v.value, prob.status

    with c_stdout_to_stderr():
        t_dense, (u1_dense, status) = timed(dense)
    runs = simulate(problem, servo_law(problem), 10).dataset["e_norm"].values
    print(f"# double-mass servo under PID (loop reference), N = {N}, ts = {problem.ts:g} s; "
          f"stage QP {law.stage_qp.n_var} variables; status {cert.status} "
          f"({cert.solver_status}); cost {cert.cost_before:.4g} -> {cert.cost_after:.4g}; "
          f"{int(np.sum(np.abs(u1) > SERVO_R_BOUND - 1e-6))} reference and "
          f"{int(np.sum(y_now + G @ (u1 - u0).reshape(-1) > SERVO_Y_MAX - 1e-6))} output "
          f"bounds active")
    print(f"# max |u_stage - u_lifted| = {np.max(np.abs(u1 - u1_lifted)):.2e}, max |u_stage - "
          f"u_dense (cvxpy, {status})| = {np.max(np.abs(u1.reshape(-1) - u1_dense)):.2e}")
    print(f"# ||e||_2 over ten simulated trials: {np.array2string(runs, precision=3)}")
    bench(f"constrained_servo_setup_N{N}", setup)
    bench(f"constrained_servo_update_N{N}", update)
    bench(f"constrained_servo_update_lifted_N{N}", t_lifted)
    comment(f"dense step in cvxpy: {t_dense:.3f} s")
    ratio("constrained_servo_dense_vs_stage", t_dense / update)
    return cert.status == "solved"


def main() -> int:
    which = [a for a in sys.argv[1:] if a != "--small"] or ["servo", "robot"]
    ok = True
    for name in which:
        if name not in ("servo", "robot"):
            raise SystemExit(f"usage: bench_constrained.py [robot|servo] [--small]; got "
                             f"{name!r}")
        ok &= {"servo": servo, "robot": robot}[name]()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
