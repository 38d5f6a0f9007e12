"""Shared fixtures: small LTI problems and one example law of every registered law kind.

:data:`LAW_FACTORIES` is keyed by the kinds of :data:`ilc_analysis.laws.LAW_KINDS`
(``tests/test_law_conformance.py`` fails when a registered kind has no entry): each factory
builds, on a problem, the laws of that kind the conformance suite checks (model-based laws
need the problem to be built on).
"""

from __future__ import annotations

import os
from collections.abc import Callable

import control
import numpy as np
import pytest
from hypothesis import settings

from ilc_analysis.laws import (
    ConstrainedNormOptimalLaw,
    FixedForgetting,
    GradientLaw,
    InverseModelLaw,
    LearningLaw,
    NonlinearNormOptimalLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QFilter,
    QLLaw,
    TimeReversalLaw,
    VariableForgetting,
)
from ilc_analysis.problem import ILCProblem, LoopReference, pid

#: Hypothesis profiles. ``suite`` (the default): every run draws the same examples (seeded from
#: each test; a suite that fails on one run in many fails an unrelated change, and fresh draws
#: did so twice: a subnormal draw that overflowed in a test, a true counterexample found once)
#: and no per-example deadline (the suite never depends on timing: a loaded 2-core machine runs
#: an example ten times slower). ``explore`` (``ILC_HYPOTHESIS_PROFILE=explore make test``):
#: fresh random draws, to search for new counterexamples; a failure prints the seed to replay.
HYPOTHESIS_PROFILES = {"suite": {"derandomize": True}, "explore": {"derandomize": False}}
for _name, _options in HYPOTHESIS_PROFILES.items():
    settings.register_profile(_name, deadline=None, print_blob=True, **_options)
_profile = os.environ.get("ILC_HYPOTHESIS_PROFILE", "suite")
if _profile not in HYPOTHESIS_PROFILES:
    raise pytest.UsageError(f"ILC_HYPOTHESIS_PROFILE must be one of "
                            f"{sorted(HYPOTHESIS_PROFILES)}; got {_profile!r}")
settings.load_profile(_profile)

#: the per-test limit [s] of a test marked slow without a timeout of its own (pytest-timeout;
#: the others get ``timeout`` of [tool.pytest.ini_options]): the slow tests take up to about
#: four minutes on a loaded 2-core machine
SLOW_TEST_TIMEOUT = 1800


def pytest_collection_modifyitems(config, items):
    """A test marked ``slow`` gets :data:`SLOW_TEST_TIMEOUT` unless it sets its own limit."""
    for item in items:
        if item.get_closest_marker("slow") and not item.get_closest_marker("timeout"):
            item.add_marker(pytest.mark.timeout(SLOW_TEST_TIMEOUT))


#: sample time and trial length of the conformance problems (small: the suite must be fast)
TS, N = 0.2, 16


def _reference(n_y: int) -> np.ndarray:
    t = TS * np.arange(N)
    return np.column_stack([np.sin(2 * np.pi * t / (N * TS) + c) for c in range(n_y)])


def siso_problem() -> ILCProblem:
    """A damped second-order plant 1/(s^2 + s + 1), ZOH-sampled, learning at its input."""
    return ILCProblem(control.tf([1.0], [1.0, 1.0, 1.0]), TS, N, _reference(1), name="siso")


def mimo_problem() -> ILCProblem:
    """A coupled 2x2 first-order plant (relative degree 1 per channel, minimum phase)."""
    sys = control.ss([[-1.0, 0.3], [0.0, -2.0]], [[1.0, 0.2], [0.1, 1.0]], np.eye(2),
                     np.zeros((2, 2)))
    return ILCProblem(sys, TS, N, _reference(2), name="mimo-2x2")


def pid_loop_problem() -> ILCProblem:
    """The SISO plant under PID control, learning at the loop's reference."""
    return ILCProblem(control.tf([1.0], [1.0, 1.0, 1.0]), TS, N, _reference(1),
                      learning_at=LoopReference(pid(2.0, 1.0, 0.1, 0.02)), name="pid-loop")


#: the conformance problems by name
PROBLEMS: dict[str, Callable[[], ILCProblem]] = {
    "siso": siso_problem, "mimo": mimo_problem, "pid-loop": pid_loop_problem}


def _eye(pr: ILCProblem, gain: float) -> np.ndarray:
    return gain * np.eye(pr.n_u, pr.n_y)


def _beta(pr: ILCProblem, fraction: float) -> float:
    return fraction * 2.0 / np.linalg.norm(pr.lifted.G, 2) ** 2


def _pd(pr: ILCProblem) -> dict[str, LearningLaw]:
    zero = _eye(pr, 0.0)
    return {
        "pd": PDLaw(PDGains(Phi1=zero, Phi2=zero, Psi1=_eye(pr, 0.8), Psi2=_eye(pr, 0.5))),
        "pd-forgetting-q": PDLaw(PDGains(Phi1=zero, Phi2=_eye(pr, 0.05), Psi1=_eye(pr, 0.8),
                                         Psi2=zero, lead=1),
                                 forgetting=FixedForgetting(0.05),
                                 q_filter=QFilter.butterworth(cutoff=1.0, order=2)),
        "pd-variable-forgetting": PDLaw(PDGains(Phi1=zero, Phi2=zero, Psi1=_eye(pr, 0.5),
                                                Psi2=zero),
                                        forgetting=VariableForgetting(0.85, 6.0)),
        # IterativeLearningControl.jl's zero-phase run of a first-order (ZOH) Q
        "pd-first-order-q-backward-forward": PDLaw(
            PDGains(Phi1=zero, Phi2=zero, Psi1=_eye(pr, 0.5), Psi2=zero, lead=1),
            q_filter=QFilter.first_order(1.0, passes="backward-forward", ends="zero-state")),
    }


def _ql(pr: ILCProblem) -> dict[str, LearningLaw]:
    lowpass = control.ss([[0.6]], [[0.4]], [[1.0]], [[0.0]], TS)
    lowpass = control.append(*([lowpass] * pr.n_u)) if pr.n_u > 1 else lowpass
    return {
        "ql": QLLaw(control.ss([], [], [], _eye(pr, 0.6), TS), advance=1),
        "ql-zero-phase": QLLaw(control.ss([], [], [], _eye(pr, 0.6), TS), Q=lowpass,
                               advance=1, zero_phase=True),
    }


def _inverse_model(pr: ILCProblem) -> dict[str, LearningLaw]:
    return {"inverse-model": InverseModelLaw(pr.lti_system, 0.5, shift=pr.shift)}


def _gradient(pr: ILCProblem) -> dict[str, LearningLaw]:
    return {
        "gradient": GradientLaw(_beta(pr, 0.5), pr.lifted),
        "gradient-plant-model": GradientLaw(_beta(pr, 0.5), pr.dplant, x0=pr.x0, w=pr.w,
                                            t0=pr.t0, shift=pr.shift),
        # beta 3/sigma^2: T = I - beta G'G has the eigenvalue -2, the analysis says DIVERGES
        "gradient-diverging": GradientLaw(_beta(pr, 1.5), pr.lifted),
    }


def _norm_optimal(pr: ILCProblem) -> dict[str, LearningLaw]:
    return {
        "norm-optimal": NormOptimalLaw(pr.lifted, weight_input_change=0.1),
        "norm-optimal-input-weight": NormOptimalLaw(pr.lifted, weight_input_change=0.1,
                                                    weight_input=0.01),
        "norm-optimal-step-size": NormOptimalLaw(pr.lifted, weight_input_change=0.1,
                                                 weight_input=0.01, step_size=0.5),
    }


def _time_reversal(pr: ILCProblem) -> dict[str, LearningLaw]:
    return {"time-reversal": TimeReversalLaw(_beta(pr, 0.5)),
            "time-reversal-paired": TimeReversalLaw(_beta(pr, 0.5), free_response="paired")}


def _constrained(pr: ILCProblem) -> dict[str, LearningLaw]:
    return {"constrained-norm-optimal": ConstrainedNormOptimalLaw(pr, weight_input_change=0.1),
            "constrained-norm-optimal-lifted": ConstrainedNormOptimalLaw(
                pr.lifted, reference=pr.reference, initial_input=pr.initial_input(),
                weight_input_change=0.1, solver="osqp"),
            "constrained-norm-optimal-step-size": ConstrainedNormOptimalLaw(
                pr, weight_input_change=0.1, weight_input=0.01, step_size=0.5)}


def _nonlinear(pr: ILCProblem) -> dict[str, LearningLaw]:
    return {"nonlinear-norm-optimal": NonlinearNormOptimalLaw(pr, weight_input_change=0.1),
            "nonlinear-norm-optimal-matrix-free": NonlinearNormOptimalLaw(
                pr, weight_input_change=0.1, matrix_free=True)}


#: law kind (a key of LAW_KINDS) -> laws of that kind on a problem, by case name
LAW_FACTORIES: dict[str, Callable[[ILCProblem], dict[str, LearningLaw]]] = {
    "pd": _pd, "ql": _ql, "inverse-model": _inverse_model, "gradient": _gradient,
    "norm-optimal": _norm_optimal, "time-reversal": _time_reversal,
    "constrained-norm-optimal": _constrained, "nonlinear-norm-optimal": _nonlinear,
}


@pytest.fixture(scope="session")
def conformance_problems() -> dict[str, ILCProblem]:
    """The conformance problems, built once (their liftings are cached)."""
    return {name: make() for name, make in PROBLEMS.items()}
