"""IterativeLearningControl.jl's problem form ``ILCProblem(; r, P, C)`` read directly (issue 27):
``ILCProblem.from_reference_plant_controller`` and its design-file form, against the package's
definitions computed here with numpy only: G_r = PC/(1 + PC), G_u = P/(1 + PC), lifted as
lower-triangular Toeplitz matrices of their Markov parameters with h_0 on the diagonal, trials from
rest on the samples of r, y_k = G_r (r + a_k) (location :ref) or G_r r + G_u a_k (:input).
"""

from __future__ import annotations

import control
import numpy as np
import pytest

from ilc_analysis.design import load_design
from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.problem import ILCProblem, LoopInput, LoopReference

TS, N = 0.05, 25
AP = np.array([[1.0, 0.05], [-0.1, 0.95]])
BP = np.array([[0.00125], [0.05]])
CP = np.array([[1.0, 0.0]])
AC, BC, CC, DC = np.array([[1.0]]), np.array([[0.05]]), np.array([[1.0]]), np.array([[3.0]])
P = control.ss(AP, BP, CP, 0.0, TS)
C = control.ss(AC, BC, CC, DC, TS)


def _r():
    return np.sin(np.linspace(0.0, 2.0, N))[None, :] + 0.2


def _toeplitz_h0(B):
    """The package's lifted matrix of the loop input B -> y: h_0 = D = 0 on the diagonal."""
    A = np.block([[AP - BP @ DC @ CP, BP @ CC], [-BC @ CP, AC]])
    Ccl = np.hstack([CP, np.zeros((1, 1))])
    h = [0.0]
    Ak = np.eye(3)
    for _ in range(N - 1):
        h.append(float((Ccl @ Ak @ B)[0, 0]))
        Ak = Ak @ A
    G = np.zeros((N, N))
    for j in range(N):
        for k in range(j + 1):
            G[j, k] = h[j - k]
    return G


G_R = _toeplitz_h0(np.vstack([BP @ DC, BC]))
G_U = _toeplitz_h0(np.vstack([BP, np.zeros((1, 1))]))


def _lsim(r, a, location):
    """The package's simulate: lsim([Gr Gu], [r + a; 0]) or [r; a], from rest."""
    xp, xc = np.zeros(2), np.zeros(1)
    y = np.zeros(N)
    for k in range(N):
        y[k] = (CP @ xp)[0]
        ref = r[k] + a[k] if location == "ref" else r[k]
        u = CC @ xc + DC @ (ref - y[k:k + 1])
        if location == "input":
            u = u + a[k]
        xp, xc = AP @ xp + BP @ u, AC @ xc + BC @ (ref - y[k:k + 1])
    return y


@pytest.mark.parametrize("location", ["ref", "input"])
def test_the_package_problem_known_answer(location):
    r = _r()
    pr = ILCProblem.from_reference_plant_controller(r, P, C, location=location)
    assert (pr.ts, pr.N, pr.shift) == (TS, N, 0)
    assert isinstance(pr.learning_at, LoopReference if location == "ref" else LoopInput)
    assert pr.learning_at.reference_timing == "same-sample"
    np.testing.assert_array_equal(pr.reference, r.T)
    a = 0.05 * np.cos(np.arange(N))
    if location == "ref":
        np.testing.assert_allclose(pr.lifted.G, G_R, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(pr.u_nominal, r.T)         # v = r + a, a = 0 first
        v = r[0] + a
    else:
        np.testing.assert_allclose(pr.lifted.G, G_U, rtol=0, atol=1e-12)
        np.testing.assert_allclose(pr.lifted.d, G_R @ r[0], rtol=0, atol=1e-12)
        v = a
    y = pr.lifted.G @ v + pr.lifted.d
    np.testing.assert_allclose(y, _lsim(r[0], a, location), rtol=0, atol=1e-12)
    # e(0) = r(0) - y(0) cannot be changed: the loop is strictly proper
    np.testing.assert_array_equal(pr.lifted.G[0], 0.0)


def test_the_design_file_form_is_the_same_problem(tmp_path):
    r = _r()
    np.savetxt(tmp_path / "r.csv", r.T, header="y[0]", comments="", delimiter=",")
    (tmp_path / "design.toml").write_text(f"""
[plant]                               # P, discrete as the package takes it
statespace = {{ A = {AP.tolist()}, B = {BP.tolist()}, C = {CP.tolist()}, D = [[0.0]], dt = {TS} }}
[problem]
ts = {TS}
N = {N}
shift = 0                             # the window is the samples of r
reference = "r.csv"                   # r transposed: one row per sample
[problem.learning_at]
kind = "loop-reference"               # location = :ref
reference_timing = "same-sample"
[problem.learning_at.controller]      # C
ss = {{ A = {AC.tolist()}, B = {BC.tolist()}, C = {CC.tolist()}, D = {DC.tolist()}, dt = {TS} }}
[law]
kind = "norm-optimal"
weight_input_change = 0.001
""")
    from_file = load_design(tmp_path / "design.toml").problem
    direct = ILCProblem.from_reference_plant_controller(r, P, C)
    np.testing.assert_allclose(from_file.lifted.G, direct.lifted.G, rtol=0, atol=1e-15)
    np.testing.assert_allclose(from_file.u_nominal, direct.u_nominal, rtol=0, atol=1e-15)
    assert from_file.describe()["learning_at"] == direct.describe()["learning_at"]


def test_sample_time_and_layout():
    r = _r()
    # ts from C when P is continuous; a 1-D r for one output
    Pc = control.ss(np.array([[0.0, 1.0], [-2.0, -1.0]]), [[0.0], [1.0]], [[1.0, 0.0]], 0.0)
    pr = ILCProblem.from_reference_plant_controller(r[0], Pc, C)
    assert pr.ts == TS and pr.reference.shape == (N, 1)
    pr = ILCProblem.from_reference_plant_controller(r, Pc, control.ss([], [], [], [[2.0]]),
                                                    ts=0.1)
    assert pr.ts == 0.1


def test_errors_name_the_parameter():
    r = _r()
    with pytest.raises(ShapeError, match=r"r must have shape \(n_y, N\) = \(1, N\).*found shape "
                                         r"\(25, 2\)"):
        ILCProblem.from_reference_plant_controller(np.ones((N, 2)), P, C)
    with pytest.raises(ParameterError, match="location must be 'ref'"):
        ILCProblem.from_reference_plant_controller(r, P, C, location="output")
    Pc = control.tf([1.0], [1.0, 1.0])
    with pytest.raises(ParameterError, match="ts \\(sample time\\) is required"):
        ILCProblem.from_reference_plant_controller(r, Pc, control.tf([2.0], [1.0]))
    with pytest.raises(ParameterError, match="plant is discrete with dt = 0.05"):
        ILCProblem.from_reference_plant_controller(r, P, C, ts=0.1)
    with pytest.raises(ParameterError, match="controller is discrete with dt = 0.05"):
        ILCProblem.from_reference_plant_controller(r, control.ss(AP, BP, CP, 0.0, 0.1), C)


def test_save_design_writes_the_package_problem_and_reads_it_back(tmp_path):
    from ilc_analysis.design import Design, save_design
    from ilc_analysis.laws import NormOptimalLaw, PDGains, PDLaw, QFilter

    problem = ILCProblem.from_reference_plant_controller(_r(), P, C, location="input")
    for law in (NormOptimalLaw(problem.lifted, weight_input_change=1e-3),
                PDLaw(PDGains.zeros(1, 1), q_filter=QFilter.first_order(
                    2.0, passes="backward-forward", ends="zero-state"))):
        path = save_design(Design(problem, law), tmp_path / "design.toml")
        again = load_design(path)
        assert again.problem.describe()["learning_at"] == {
            **problem.describe()["learning_at"], "reference_timing": "same-sample"}
        assert again.problem.shift == 0
        np.testing.assert_allclose(again.problem.lifted.G, problem.lifted.G, rtol=0, atol=1e-15)
        np.testing.assert_allclose(again.problem.lifted.d, problem.lifted.d, rtol=0, atol=1e-15)
        assert again.law.describe() == law.describe()
