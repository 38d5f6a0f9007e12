"""Inverse-model ILC of loops whose controller integrates (issue 27): ``dc_cutoff``.

Learning at the input of a PI or PID loop (LoopInput) gives the model a zero at z = 1: the
exact inverse integrates and QLLaw.inverse_model refuses it. With ``dc_cutoff`` f_c the learning
filter is L' = gamma H(z) P_s^-1(z), H = (1 - z^-1)/(1 - rho z^-1), rho = exp(-2 pi f_c ts).

Known answers computed here with numpy only, on the double-mass servo loop (notebook 05's
two-mass drive and PID, learning at the plant input) and a DC motor under a PI loop: the lifted
L1 = gamma T_H G^-1 and T = I - gamma T_H (T_H the Toeplitz matrix of h_0 = 1,
h_k = (rho - 1) rho^(k-1), G from the model's matrices), the frequency response
L'(z) P_s(z) = gamma H(z) and the finite gain at z = 1, gamma / ((1 - rho) P_s'(1)); the
analysis' verdicts (||T||_2 < 1, rho(T) = |1 - gamma|, sup |T(e^jw)| = 1 at DC). Property: the
lifted identity T = I - gamma T_H for random PI loops and cut-offs. Errors name the parameter.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis import ILCProblem, analyze, load_design, simulate
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import InverseModelLaw, QLLaw, describe_law, law_from_description
from ilc_analysis.problem import LoopInput, LoopReference, pid
from ilc_analysis.testing import check_law

TS = 0.01
M1, M2, K, C = 1.0, 0.5, 200.0, 1.0
DRIVE_A = np.array([[0.0, 1.0, 0.0, 0.0], [-K / M1, -C / M1, K / M1, C / M1],
                    [0.0, 0.0, 0.0, 1.0], [K / M2, C / M2, -K / M2, -C / M2]])
DRIVE_B = np.array([[0.0], [1.0 / M1], [0.0], [0.0]])
SERVO_PID = pid(6.0, 4.0, 4.0, tf=0.05)


def _move(N: int, duration: float) -> np.ndarray:
    tau = np.clip((1 + np.arange(N)) * TS / duration, 0.0, 1.0)
    return (0.1 * (10 * tau**3 - 15 * tau**4 + 6 * tau**5))[:, None]


def servo_problem(N: int = 120, output=(1.0, 0.0, 0.0, 0.0)) -> ILCProblem:
    """The two-mass drive under notebook 05's PID, learning a feed-forward at the plant input."""
    drive = control.ss(DRIVE_A, DRIVE_B, np.array([output]), 0.0)
    return ILCProblem(drive, ts=TS, N=N, reference=_move(N, 0.8),
                      learning_at=LoopInput(SERVO_PID), name="servo, loop input")


def motor_problem(N: int = 100, kp: float = 2.0, ki: float = 5.0) -> ILCProblem:
    """A DC motor's position 10 / (s (0.1 s + 1)) under a PI loop, learning at its input."""
    motor = control.tf([10.0], [0.1, 1.0, 0.0])
    return ILCProblem(motor, ts=TS, N=N, reference=_move(N, 0.6),
                      learning_at=LoopInput(pid(kp, ki)), name="DC motor, PI")


def _rho(f_c: float) -> float:
    return float(np.exp(-2 * np.pi * f_c * TS))


def _toeplitz_H(N: int, rho: float) -> np.ndarray:
    h = np.concatenate([[1.0], (rho - 1.0) * rho ** np.arange(N - 1)])
    idx = np.subtract.outer(np.arange(N), np.arange(N))
    return np.where(idx >= 0, h[np.clip(idx, 0, None)], 0.0)


def _numpy_model(problem):
    """(A, B, C_s, D_s) of P_s = z^s P and the lifted G, from the sampled model's matrices."""
    sys = control.ss(problem.lti_system)
    A, B, Cm, D = (np.asarray(M, float) for M in (sys.A, sys.B, sys.C, sys.D))
    s, N = problem.shift, problem.N
    h = [D] + [Cm @ np.linalg.matrix_power(A, k - 1) @ B for k in range(1, N + s)]
    G = np.zeros((N, N))
    for j in range(N):
        for k in range(min(N, j + s + 1)):
            G[j, k] = h[j + s - k][0, 0]
    Cs = Cm @ np.linalg.matrix_power(A, s)
    Ds = Cm @ np.linalg.matrix_power(A, s - 1) @ B
    return A, B, Cs, Ds, G


# ---------------------------------------------------------------------------------------------
# known answers
# ---------------------------------------------------------------------------------------------
def test_the_servo_loop_input_has_a_zero_at_one_and_is_refused_without_dc_cutoff():
    pr = servo_problem()
    zeros = pr.lti_system.zeros()
    assert np.min(np.abs(zeros - 1.0)) <= 1e-8
    with pytest.raises(ParameterError, match=r"zero\(s\) at z = 1.*dc_cutoff"):
        QLLaw.inverse_model(pr.lti_system, 0.5)


@pytest.mark.parametrize("make", [servo_problem, motor_problem], ids=["servo", "dc-motor"])
@pytest.mark.parametrize(("gamma", "f_c"), [(0.5, 0.1), (1.0, 0.3)])
def test_lifted_law_is_gamma_TH_times_the_inverse_of_G(make, gamma, f_c):
    pr = make()
    law = QLLaw.inverse_model(pr.lti_system, gamma, dc_cutoff=f_c)
    _, _, _, _, G = _numpy_model(pr)
    TH = _toeplitz_H(pr.N, _rho(f_c))
    L1_want = gamma * TH @ np.linalg.inv(G)
    L1 = law.lifted(pr.lifted).L1
    assert np.max(np.abs(L1 - L1_want)) <= 1e-8 * np.max(np.abs(L1_want))
    T = law.lifted(pr.lifted).operator(G)
    assert np.max(np.abs(T - (np.eye(pr.N) - gamma * TH))) <= 1e-9


@pytest.mark.parametrize("make", [servo_problem, motor_problem], ids=["servo", "dc-motor"])
def test_frequency_response_is_gamma_H_and_the_gain_at_one_is_finite(make):
    pr = make()
    gamma, f_c = 0.8, 0.2
    rho = _rho(f_c)
    law = QLLaw.inverse_model(pr.lti_system, gamma, dc_cutoff=f_c)
    A, B, Cs, Ds, _ = _numpy_model(pr)
    n = A.shape[0]
    f = law._L                                          # the learning filter L'
    assert np.max(np.abs(np.linalg.eigvals(f.A))) < 1.0   # stable: no pole at z = 1

    def P_s(z):
        return Cs @ np.linalg.solve(z * np.eye(n) - A, B) + Ds

    z = np.exp(1j * np.linspace(0.01, np.pi, 40))
    LP = np.array([(f.response(np.array([zk]))[0] @ P_s(zk))[0, 0] for zk in z])
    H = (1 - 1 / z) / (1 - rho / z)
    assert np.max(np.abs(LP - gamma * H)) <= 1e-7
    # at z = 1: L'(1) = gamma Res_{z=1} P_s^-1 / (1 - rho) = gamma / ((1 - rho) P_s'(1))
    dP = -(Cs @ np.linalg.solve(np.eye(n) - A, np.linalg.solve(np.eye(n) - A, B)))[0, 0]
    L_dc = f.response(np.array([1.0 + 0j]))[0, 0, 0]
    assert L_dc == pytest.approx(gamma / ((1 - rho) * dP), rel=1e-6)


def _first_order_under_pi() -> ILCProblem:
    """1/(s + 1) under PI: the model's only zero is the one at z = 1."""
    return ILCProblem(control.tf([2.0], [1.0, 1.0]), ts=TS, N=40, reference=np.ones((40, 1)),
                      learning_at=LoopInput(pid(1.0, 3.0)))


def _two_by_two_under_pi() -> ILCProblem:
    """A coupled 2x2 plant under a diagonal PI: two zeros at z = 1, one per channel."""
    plant = control.ss([[-1.0, 0.3], [0.0, -2.0]], [[1.0, 0.2], [0.1, 1.0]], np.eye(2),
                       np.zeros((2, 2)))
    C = control.append(control.ss(pid(1.0, 2.0)), control.ss(pid(2.0, 1.0)))
    return ILCProblem(plant, ts=TS, N=30, reference=np.ones((30, 2)), learning_at=LoopInput(C))


@pytest.mark.parametrize("make", [_first_order_under_pi, _two_by_two_under_pi],
                         ids=["only-the-zero-at-one", "mimo-2x2"])
def test_T_is_one_minus_gamma_H_on_every_channel(make):
    pr = make()
    n = pr.n_u
    assert np.sum(np.abs(pr.lti_system.zeros() - 1.0) <= 1e-8) == n
    gamma, f_c = 0.5, 0.5
    T = QLLaw.inverse_model(pr.lti_system, gamma, dc_cutoff=f_c).lifted(pr.lifted).operator(
        pr.lifted)
    want = np.eye(pr.N * n) - gamma * np.kron(_toeplitz_H(pr.N, _rho(f_c)), np.eye(n))
    assert np.max(np.abs(T - want)) <= 1e-9


def test_the_analysis_verdicts_on_the_servo_loop():
    pr = servo_problem(N=150)
    gamma, f_c = 0.5, 0.1
    an = analyze(pr, QLLaw.inverse_model(pr.lti_system, gamma, dc_cutoff=f_c), horizon=30)
    TH = _toeplitz_H(pr.N, _rho(f_c))
    norm_want = np.linalg.norm(np.eye(pr.N) - gamma * TH, 2)
    assert norm_want < 1.0
    assert an["norm_2"].value == pytest.approx(norm_want, rel=1e-8)
    assert an.verdict("norm_2") == "holds"
    assert an["spectral_radius"].value == pytest.approx(1 - gamma, abs=1e-9)
    # no learning at DC: sup_theta |T(e^j theta)| = |1 - gamma H(1)| = 1, never a pass
    assert an["frequency"].value == pytest.approx(1.0, abs=1e-9)
    assert an["frequency"].verdict != "holds"


def test_simulated_errors_fall_as_the_analysis_says():
    pr = motor_problem()
    law = InverseModelLaw(pr.lti_system, 0.7, shift=pr.shift, dc_cutoff=0.2)
    e_norm = simulate(pr, law, 8).dataset["e_norm"].values
    assert np.all(np.diff(e_norm) <= 0.0)
    assert e_norm[-1] <= 1e-2 * e_norm[0]


def test_the_servo_law_conforms():
    pr = servo_problem(N=60)
    report = check_law(InverseModelLaw(pr.lti_system, 0.6, shift=pr.shift, dc_cutoff=0.25), pr)
    assert report.passed, report.summary()


@pytest.mark.parametrize("make", [servo_problem, motor_problem], ids=["servo", "dc-motor"])
def test_design_file_round_trip(make):
    pr = make(N=60)
    law = InverseModelLaw(pr.lti_system, 0.6, shift=pr.shift, dc_cutoff=0.25)
    d = describe_law(law)
    assert d["dc_cutoff"] == 0.25
    again = law_from_description(d, pr)
    assert describe_law(again) == d
    assert np.array_equal(again.lifted(pr.lifted).L1, law.lifted(pr.lifted).L1)


DESIGN = """format = "ilc-analysis-design/1"

[plant]
statespace = { A = [[0.0, 1.0], [0.0, -10.0]], B = [[0.0], [100.0]], C = [[1.0, 0.0]], D = [[0.0]] }

[problem]
ts = 0.01
N = 100
reference = "reference.csv"

[problem.learning_at]
kind = "loop-input"

[problem.learning_at.controller]
pid = { kp = 2.0, ki = 5.0 }

[law]
kind = "inverse-model"
gamma = 0.7
dc_cutoff = 0.2
"""


def test_a_design_file_holds_the_law_of_the_docs(tmp_path):
    # docs/design-file.md's example: the DC motor 100 / (s (s + 10)) under PI, in state space
    np.savetxt(tmp_path / "reference.csv", _move(100, 0.6), delimiter=",", header="y[0]",
               comments="")
    (tmp_path / "design.toml").write_text(DESIGN)
    design = load_design(tmp_path / "design.toml")
    assert isinstance(design.law, InverseModelLaw) and design.law.dc_cutoff == 0.2
    pr = design.problem
    T = design.law.lifted(pr.lifted).operator(pr.lifted)
    assert np.max(np.abs(T - (np.eye(100) - 0.7 * _toeplitz_H(100, _rho(0.2))))) <= 1e-9
    bad = DESIGN.replace("dc_cutoff = 0.2", "dc_cutoff = 80.0")
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(ParameterError, match=r"\[law\].*Nyquist"):
        load_design(tmp_path / "bad.toml")


# ---------------------------------------------------------------------------------------------
# property: T = I - gamma T_H for any PI loop at the plant input
# ---------------------------------------------------------------------------------------------
@settings(max_examples=15, deadline=None)
@given(kp=st.floats(0.5, 5.0), ki=st.floats(0.2, 10.0), f_c=st.floats(0.02, 5.0),
       gamma=st.floats(0.1, 1.9))
def test_any_pi_loop_gives_T_equal_to_one_minus_gamma_H(kp, ki, f_c, gamma):
    pr = motor_problem(N=40, kp=kp, ki=ki)
    law = QLLaw.inverse_model(pr.lti_system, gamma, dc_cutoff=f_c)
    T = law.lifted(pr.lifted).operator(pr.lifted)
    assert np.max(np.abs(T - (np.eye(pr.N) - gamma * _toeplitz_H(pr.N, _rho(f_c))))) <= 1e-7


# ---------------------------------------------------------------------------------------------
# errors
# ---------------------------------------------------------------------------------------------
def test_dc_cutoff_on_a_model_without_a_zero_at_one_is_refused():
    pr = ILCProblem(control.ss(DRIVE_A, DRIVE_B, [[1.0, 0.0, 0.0, 0.0]], 0.0), ts=TS, N=50,
                    reference=_move(50, 0.4), learning_at=LoopReference(SERVO_PID))
    with pytest.raises(ParameterError, match="dc_cutoff applies to a model with a zero"):
        QLLaw.inverse_model(pr.lti_system, 0.5, dc_cutoff=0.1)


@pytest.mark.parametrize(("f_c", "match"), [(0.0, "dc_cutoff"), (-1.0, "dc_cutoff"),
                                            (50.0, "Nyquist"), (float("inf"), "dc_cutoff")])
def test_a_bad_cutoff_is_refused_naming_it(f_c, match):
    with pytest.raises(ParameterError, match=match):
        QLLaw.inverse_model(motor_problem(N=30).lti_system, 0.5, dc_cutoff=f_c)


def test_other_unstable_zeros_are_still_refused():
    # the load position of the drive: a sampling zero outside the unit circle besides z = 1
    pr = servo_problem(N=40, output=(0.0, 0.0, 1.0, 0.0))
    with pytest.raises(ParameterError, match="not minimum-phase"):
        QLLaw.inverse_model(pr.lti_system, 0.5, dc_cutoff=0.1)


def test_a_double_integrator_in_the_controller_is_refused():
    s = control.tf("s")
    pii = (2.0 * s**2 + 3.0 * s + 1.0) / s**2
    pr = ILCProblem(control.tf([10.0], [0.1, 1.0, 1.0]), ts=TS, N=40,
                    reference=_move(40, 0.3), learning_at=LoopInput(pii))
    with pytest.raises(ParameterError, match="repeated"):
        QLLaw.inverse_model(pr.lti_system, 0.5, dc_cutoff=0.1)
