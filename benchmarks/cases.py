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
* :func:`srv02_norm_optimal` — norm-optimal ILC (Riccati form) on an SRV02-type rotary servo
  (K/(s(tau s + 1)), K = 1.53 rad/(V s), tau = 0.0254 s) under a PID loop at 1 kHz, learning
  at the loop's reference (issue 34's "SRV02-type servo" case).
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
           "robot_circle_pd", "robot_circle_norm_optimal", "ROBOT_LONG_TS", "robot_scenario_pd",
           "srv02_norm_optimal"]

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

#: An SRV02-type rotary servo (Quanser SRV02, high gear): theta/V = K/(s (tau s + 1)), K in
#: rad/(V s), tau in s (the manufacturer's nominal model), sampled at 1 kHz
SRV02_K, SRV02_TAU, SRV02_TS = 1.53, 0.0254, 1e-3
#: the PID loop around it (kp, ki, kd, derivative filter tf) and the norm-optimal weight
SRV02_PID, SRV02_NO_WEIGHT = (8.0, 2.0, 0.3, 0.01), 1e-4


def _srv02_problem(N: int):
    """The SRV02-type servo under PID, learning at the loop's reference: a quarter-turn
    minimum-jerk move over the first 80 % of the trial (N samples at 1 kHz)."""
    from ilc_analysis.problem import LoopReference, pid

    N = int(N)
    plant = control.tf([SRV02_K], [SRV02_TAU, 1.0, 0.0])
    tau = np.clip((1 + np.arange(N)) / (0.8 * N), 0.0, 1.0)
    y_d = (np.pi / 4 * (10 * tau**3 - 15 * tau**4 + 6 * tau**5))[:, None]
    kp, ki, kd, tf = SRV02_PID
    return ilc.ILCProblem(plant, ts=SRV02_TS, N=N, reference=y_d,
                          learning_at=LoopReference(pid(kp, ki, kd, tf=tf)),
                          name=f"SRV02-type servo under PID, N={N}")


def srv02_norm_optimal(N: int):
    """Norm-optimal ILC (Riccati form, the exact model) on the SRV02-type servo loop;
    ``(problem, law)``."""
    problem = _srv02_problem(N)
    return problem, ilc.NormOptimalLaw.from_problem(problem,
                                                    weight_input_change=SRV02_NO_WEIGHT)


# ---------------------------------------------------------------------------------------------
# issue 34: the standard SISO law shapes at 1 kHz whose bounds must decide at N = 2 000
# ---------------------------------------------------------------------------------------------
#: sample time of the issue-34 shapes [s] (1 kHz)
SHAPE_TS = 1e-3
#: the motion plant of the shapes: a positioning axis seen as a second-order system,
#: natural frequency 20 Hz, damping 0.7, unit static gain
SHAPE_MOTION = (2.0 * np.pi * 20.0, 0.7)
#: the lag of the shapes: a fast first-order actuator (a current loop), time constant 1 ms
SHAPE_LAG_TAU = 1e-3
#: learning gain of the P-type and Q/L shapes, and their lead: the motion plant's low-frequency
#: delay 2 zeta / omega_n = 11 ms in samples
SHAPE_GAIN, SHAPE_LEAD = 0.5, 11


def _shape_problem(plant, N: int, name: str, **kw):
    return ilc.ILCProblem(plant, ts=SHAPE_TS, N=int(N), reference=np.zeros((int(N), 1)),
                          name=name, **kw)


def _motion(N: int):
    wn, zeta = SHAPE_MOTION
    return _shape_problem(control.tf([wn ** 2], [1.0, 2.0 * zeta * wn, wn ** 2]), N,
                          "motion axis (20 Hz, zeta 0.7) at 1 kHz")


def _lag(N: int, **kw):
    return _shape_problem(control.tf([1.0], [SHAPE_LAG_TAU, 1.0]), N,
                          "first-order lag (1 ms) at 1 kHz", **kw)


def shape_p_lead_butterworth(N: int):
    """P-type with a lead and a zero-phase Butterworth Q (30 Hz, order 2) on the motion axis:
    ``u+ = Q(u + 0.5 e(k + 11))``. The two passes run from rest (``ends='zero-state'``, the
    convention of IterativeLearningControl.jl): with scipy's odd extension the filter amplifies
    the trial's ends (its lifted norm is 1.06 - 2.2 for cut-offs 200 - 20 Hz here), so
    ||T||_2 > 1 for every gain; :func:`shape_p_lead_odd_forgetting` is that case."""
    law = PDLaw(ilc.PDGains([[0.0]], [[0.0]], [[SHAPE_GAIN]], [[0.0]], lead=SHAPE_LEAD),
                q_filter=ilc.QFilter.butterworth(30.0, 2, ends="zero-state"),
                name="P-type, lead 11, zero-phase Butterworth Q")
    return _motion(N), law


def shape_p_lead_odd_forgetting(N: int):
    """P-type with a lead, forgetting 0.1 and scipy's zero-phase Butterworth Q (odd extension,
    200 Hz, order 2) on the motion axis: the ends' amplification (about 1.06) is offset by
    the forgetting."""
    from ilc_analysis.laws import FixedForgetting

    law = PDLaw(ilc.PDGains([[0.0]], [[0.0]], [[SHAPE_GAIN]], [[0.0]], lead=SHAPE_LEAD),
                FixedForgetting(0.1), q_filter=ilc.QFilter.butterworth(200.0, 2),
                name="P-type, lead 11, forgetting 0.1, Butterworth Q (odd ends)")
    return _motion(N), law


def shape_ql_zero_phase_advance(N: int):
    """Q/L with a zero-phase first-order Q (30 Hz, unit static gain) and an advance of 11
    samples on the motion axis: ``u+ = Q(u + 0.5 z^11 e)``."""
    from ilc_analysis.laws import QLLaw

    q = float(np.exp(-2.0 * np.pi * 30.0 * SHAPE_TS))
    Q = control.ss([[q]], [[1.0]], [[(1.0 - q) * q]], [[1.0 - q]], SHAPE_TS)
    return _motion(N), QLLaw(SHAPE_GAIN, Q=Q, advance=SHAPE_LEAD, zero_phase=True,
                             name="Q/L, advance 11, zero-phase Q")


def shape_inverse_dct(N: int):
    """Inverse-model ILC, gamma 0.5, with a DCT Q-filter (50 Hz, order 2) on the motion axis
    (minimum-phase after sampling: its sampling zero lies inside the unit circle)."""
    from ilc_analysis.laws import InverseModelLaw

    problem = _motion(N)
    return problem, InverseModelLaw(problem.lti_system, 0.5, Q=ilc.QFilter.dct(50.0))


def _sigma_max_lag(N: int) -> float:
    r""":math:`\sigma_{\max}` of the lag's lifted G, from its symbol (the static gain of a
    first-order lag, 1, is its peak)."""
    return 1.0


def shape_norm_optimal_dense(N: int):
    """Norm-optimal ILC built on the dense lifted model (``NormOptimalLaw(problem.lifted,
    ...)``), W_delta = 0.5 on the lag. The lag, not the motion axis: the law contracts by
    W_delta / (sigma_min^2 + W_delta), and the motion axis' gain falls by 1e-4 over the band
    (||T||_2 = 0.999999); the lag's by 0.46."""
    problem = _lag(N)
    return problem, ilc.NormOptimalLaw(problem.lifted, weight_input_change=0.5,
                                       name="norm-optimal (dense model)")


def shape_gradient(N: int):
    """Gradient ILC with beta = 1 / sigma_max(G)^2 (the lag's static gain 1 is its peak
    gain) and the exact lifted model, on the lag (as :func:`shape_norm_optimal_dense`)."""
    from ilc_analysis.laws import GradientLaw

    problem = _lag(N)
    return problem, GradientLaw(1.0 / _sigma_max_lag(N) ** 2, problem.lifted,
                                name="gradient, beta = 1/sigma_max^2")


def shape_pid_loop_pd(N: int):
    """A causal P-type law (gain 0.5) at the reference of a PI loop (kp 1, ki 100) around the
    lag."""
    from ilc_analysis.problem import LoopReference, pid

    problem = _lag(N, learning_at=LoopReference(pid(1.0, 100.0)))
    return problem, PDLaw(ilc.PDGains([[0.0]], [[0.0]], [[SHAPE_GAIN]], [[0.0]]),
                          name="P-type at the PI loop's reference")


#: the issue-34 shapes (``benchmarks/bench_noncausal_bounds.py``)
SHAPES = {"p_lead_butterworth": shape_p_lead_butterworth,
          "p_lead_odd_forgetting": shape_p_lead_odd_forgetting,
          "ql_zero_phase_advance": shape_ql_zero_phase_advance,
          "inverse_dct": shape_inverse_dct, "norm_optimal_dense": shape_norm_optimal_dense,
          "gradient": shape_gradient, "pid_loop_pd": shape_pid_loop_pd}


#: name -> builder, for the scripts' command lines
CASES = {"robot_diverging_pd": robot_diverging_pd, "robot_norm_optimal": robot_norm_optimal,
         "siso_pd_clustered": siso_pd_clustered, "siso_norm_optimal": siso_norm_optimal,
         "robot_circle_pd": robot_circle_pd, "robot_scenario_pd": robot_scenario_pd,
         "robot_circle_norm_optimal": robot_circle_norm_optimal,
         "srv02_norm_optimal": srv02_norm_optimal,
         **{f"servo_{kind}": _servo_law(kind) for kind in SERVO_LAWS},
         **{f"shape_{name}": build for name, build in SHAPES.items()}}
