"""The worst cases of issue 26 as importable definitions: ``(problem, law)`` pairs.

Shared by ``benchmarks/profile_worst_cases.py`` (where the dense path spends its time) and
``benchmarks/bench_matrix_free.py`` (the must-show targets). Each function builds the problem
and the law only; the caller times ``ilc.analyze(problem, law)``.

* :func:`robot_diverging_pd` — the paper scenario (balanced mobile robot along the paper's
  circle, ``ilc_analysis.paper.scenario_problem``: LTV lifting, 2 inputs, 3 outputs) with the
  documented default gain set of ``ilc-analysis check --scenario paper``
  (:func:`~ilc_analysis.paper.paper_default_gains`: an LQR current-trial loop, previous-trial
  gains half of it) and the scenario's variable forgetting factor (δ = 0.85, Λ = 6), the
  previous-trial gains Φ1, Ψ1 taken with the opposite sign (:data:`LEARNING_SIGN`): an
  untuned law. Why: ``check --scenario paper --model mobile_balanced -N 50`` reports
  ρ(T) = 1.0076 at rest, but along the circle the default gains give ρ(T) = 0.99984 < 1 at
  a = 0 (||T||_2 = 1.87); with the sign flipped, ρ(T) = 1.0090 at a = 0 (from the diagonal
  blocks of the dense T, N = 62): the learning diverges slowly once the forgetting has
  decayed, and the transient walk runs to its horizon.
* :func:`robot_norm_optimal` — norm-optimal ILC on the same lifted robot,
  ``NormOptimalLaw(problem.lifted, weight_input_change=ROBOT_NO_WEIGHT)`` (ρ(T) ≈ 1: the small
  singular values of G learn slowly).
* :func:`siso_pd_clustered` — ``benchmarks/bench_conditions.py``'s clustered case: the lag
  30/(s + 30) at Ts = 0.01 s, P-type gain Ψ1 = 0.5, so T = I - 0.5 G is lower-triangular
  Toeplitz with ||T||_2 = 0.926 and top singular values clustered within ~1e-8.
* :func:`siso_norm_optimal` — norm-optimal ILC on the same SISO lifted plant,
  weight_input_change = SISO_NO_WEIGHT.
"""

from __future__ import annotations

import dataclasses

import control
import numpy as np

import ilc_analysis as ilc
from ilc_analysis.laws import PDGains, PDLaw, VariableForgetting
from ilc_analysis.paper import paper_default_gains, paper_scenario, scenario_problem

__all__ = ["robot_diverging_pd", "robot_norm_optimal", "siso_pd_clustered", "siso_norm_optimal",
           "LEARNING_SIGN", "ROBOT_NO_WEIGHT", "SISO_NO_WEIGHT", "SISO_TS", "CASES",
           "robot_circle_pd", "robot_circle_norm_optimal", "ROBOT_LONG_TS", "robot_scenario_pd"]

#: sign of the previous-trial gains Phi1, Psi1 relative to the default set (module docstring)
LEARNING_SIGN = -1.0
#: R = W_Delta of the robot's norm-optimal law (the front door's example weight)
ROBOT_NO_WEIGHT = 1e-4
#: R = W_Delta of the SISO norm-optimal law
SISO_NO_WEIGHT = 1e-2
#: sample time of the SISO cases [s]
SISO_TS = 0.01


def _robot_problem(N: int):
    sc = paper_scenario()
    problem, _, _ = scenario_problem(sc, N=int(N))
    return sc, problem


def robot_diverging_pd(N: int):
    """The paper robot along its circle with the untuned default PD gain set (module
    docstring); returns ``(problem, law)``."""
    sc, problem = _robot_problem(N)
    g = paper_default_gains(sc.model, problem.plant)
    gains = PDGains(LEARNING_SIGN * np.asarray(g.Phi1), g.Phi2, LEARNING_SIGN * np.asarray(g.Psi1),
                    g.Psi2)
    law = PDLaw(gains, VariableForgetting(delta=sc.delta, Lambda=sc.Lambda),
                name="robot default gains (untuned)")
    return problem, law


def robot_norm_optimal(N: int):
    """Norm-optimal ILC (Riccati form, on the problem's own state-space trial model) on the paper
    robot's lifting along the circle; ``(problem, law)``."""
    _, problem = _robot_problem(N)
    return problem, ilc.NormOptimalLaw.from_problem(problem, weight_input_change=ROBOT_NO_WEIGHT)


#: sample time of the long robot trials (1 kHz: N = 10 000 is 10 s, five laps of the circle)
ROBOT_LONG_TS = 1e-3


def _robot_circle_problem(N: int):
    """The paper's robot along its circle at :data:`ROBOT_LONG_TS`, lifted along the constant
    input that sustains the circle (``circle_nominal``: exact, no NLP), reference = the circle.
    The scenario's own problem at N = 10 000 is :func:`robot_scenario_pd`."""
    from ilc_analysis.model import balanced_mobile_robot
    from ilc_analysis.paper import circle_nominal

    plant = balanced_mobile_robot()
    circle = circle_nominal(plant, int(N), ROBOT_LONG_TS)
    problem = ilc.ILCProblem(plant, ts=ROBOT_LONG_TS, N=int(N), reference=circle.y_d,
                             x0=circle.x0, u_nominal=circle.u_nominal, shift=1,
                             name=f"robot on the circle, N={int(N)}")
    return plant, problem


def robot_circle_pd(N: int):
    """The paper's PD law (default gain set, the paper's variable forgetting) on the robot along
    the circle at 1 kHz; ``(problem, law)``."""
    sc = paper_scenario()
    plant, problem = _robot_circle_problem(N)
    law = PDLaw(paper_default_gains(sc.model, plant),
                VariableForgetting(delta=sc.delta, Lambda=sc.Lambda), name="paper PD law")
    return problem, law


def robot_circle_norm_optimal(N: int):
    """Norm-optimal ILC (Riccati form) on the robot along the circle at 1 kHz."""
    _, problem = _robot_circle_problem(N)
    return problem, ilc.NormOptimalLaw.from_problem(problem, weight_input_change=ROBOT_NO_WEIGHT)


def robot_scenario_pd(N: int):
    """The paper's PD law (default gain set, the paper's variable forgetting) on the paper
    scenario's own problem (``scenario_problem``: RK4 sub-steps, LTV lifting along the
    scenario's realisable input from its NLP, reference the circle) over the scenario's
    horizon (one lap, 2 s) sampled at ``horizon / N`` (N = 10 000: 5 kHz); ``(problem,
    law)``.

    Why the horizon and not the sample time is kept: at ts = 0.01 s, N = 10 000 is 100 s
    (50 laps), and the NLP's default state guess is not the simulated trial. The heading
    integrates the yaw rate to 316 rad, beyond ``lifting._inverse.GUESS_GROWTH_LIMIT``
    (10 (1 + max|x0|) = 41), so ``realizable_reference`` takes the growth for instability
    and starts ipopt from x0 repeated. ipopt then evaluates the dynamics at points with NaN
    and Inf defects on samples 9 809 to 9 998. It stops with Invalid_Number_Detected after
    106 iterations (442 s), with a fit residual of 315 and max |u_d| = 1.8e4 (measured
    2026-11-27). ``realizable_reference`` returns that result with ``success`` False, and
    ``scenario_problem`` does not check it. Passing the simulated trial as ``x_guess``
    instead, ipopt converges in one iteration (29 s, max |u_d| = 1.2e-7).
    Over the 2 s horizon at 5 kHz the default guess is kept and converges in one iteration
    too (56 s on a loaded machine, 658 MiB)."""
    base = paper_scenario()
    sc = dataclasses.replace(base, ts=base.horizon / int(N))
    problem, _, _ = scenario_problem(sc)
    law = PDLaw(paper_default_gains(sc.model, problem.plant),
                VariableForgetting(delta=sc.delta, Lambda=sc.Lambda), name="paper PD law")
    return problem, law


def _siso_problem(N: int):
    plant = control.ss([[-30.0]], [[30.0]], [[1.0]], [[0.0]])
    return ilc.ILCProblem(plant, ts=SISO_TS, N=int(N), reference=np.zeros((int(N), 1)))


def siso_pd_clustered(N: int):
    """The SISO P-type law with clustered top singular values of T; ``(problem, law)``."""
    gains = ilc.PDGains([[0.0]], [[0.0]], [[0.5]], [[0.0]])
    return _siso_problem(N), ilc.PDLaw(gains, name="P-type, clustered singular values")


def siso_norm_optimal(N: int):
    """Norm-optimal ILC on the SISO lag; ``(problem, law)``."""
    problem = _siso_problem(N)
    return problem, ilc.NormOptimalLaw.from_problem(problem, weight_input_change=SISO_NO_WEIGHT)


def _servo_problem(N: int):
    """The two-mass drive under a PID loop, learning at the loop's reference (notebook 05; the
    double-mass servo loop of a well-known ILC package's examples), a 0.1 m minimum-jerk move
    in 1.2 s, ts = 0.01 s."""
    from ilc_analysis.problem import LoopReference, pid

    m1, m2, k, c = 1.0, 0.5, 200.0, 1.0
    A = np.array([[0.0, 1.0, 0.0, 0.0], [-k / m1, -c / m1, k / m1, c / m1],
                  [0.0, 0.0, 0.0, 1.0], [k / m2, c / m2, -k / m2, -c / m2]])
    B = np.array([[0.0], [1.0 / m1], [0.0], [0.0]])
    drive = control.ss(A, B, np.array([[1.0, 0.0, 0.0, 0.0]]), 0.0)
    tau = np.clip((1 + np.arange(int(N))) * 0.01 / 1.2, 0.0, 1.0)
    y_d = (0.1 * (10 * tau**3 - 15 * tau**4 + 6 * tau**5))[:, None]
    return ilc.ILCProblem(drive, ts=0.01, N=int(N), reference=y_d,
                          learning_at=LoopReference(pid(6.0, 4.0, 4.0, tf=0.05)),
                          name="two-mass drive under PID")


def _servo_law(kind: str):
    """One of notebook 05's five laws on the servo loop (its settings)."""
    def build(N: int):
        from ilc_analysis.laws import GradientLaw, QLLaw, TimeReversalLaw

        problem = _servo_problem(N)
        G = problem.lifted.G
        sigma_max = float(np.linalg.norm(G, 2))
        q = ilc.QFilter.dct(cutoff=5.0, order=2)
        zero = [[0.0]]
        if kind == "pd":
            law = PDLaw(PDGains(Phi1=zero, Phi2=zero, Psi1=[[0.5]], Psi2=zero,
                                lead=int(np.argmax(G[:, 0]))), q_filter=q)
        elif kind == "inverse":
            law = QLLaw.inverse_model(problem.lti_system, 0.5, Q=q)
        elif kind == "gradient":
            law = GradientLaw(1.0 / sigma_max ** 2, problem.lifted)
        elif kind == "norm_optimal":
            law = ilc.NormOptimalLaw.rho_lambda(problem.lifted, rho=0.0,
                                                lam=0.01 * sigma_max ** 2)
        else:
            peak = float(np.max(np.abs(np.fft.rfft(G[:, 0]))))
            law = TimeReversalLaw(1.0 / peak ** 2)
        return problem, law
    return build


#: the servo loop's laws (notebook 05)
SERVO_LAWS = ("pd", "inverse", "gradient", "norm_optimal", "time_reversal")


#: name -> builder, for the scripts' command lines
CASES = {"robot_diverging_pd": robot_diverging_pd, "robot_norm_optimal": robot_norm_optimal,
         "siso_pd_clustered": siso_pd_clustered, "siso_norm_optimal": siso_norm_optimal,
         "robot_circle_pd": robot_circle_pd, "robot_scenario_pd": robot_scenario_pd,
         "robot_circle_norm_optimal": robot_circle_norm_optimal,
         **{f"servo_{kind}": _servo_law(kind) for kind in SERVO_LAWS}}
