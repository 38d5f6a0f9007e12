"""Constrained norm-optimal ILC with a step size and an input-magnitude weight (issue 27).

The cost of one step (ilc_analysis.laws._constrained) is the norm-optimal J with its
first-order term scaled by the step size alpha; its minimiser is the projected Newton step of
Liao-McPherson et al.:

    u_{i+1} = argmin_{v admissible} (v - u)' W (v - u) + 2 alpha (v - u)' g,
    W = G'QG + R + S,  g = S u - G'Q e.

Known answers computed here with numpy only (G from the sampled plant's matrices, the
unconstrained step u + alpha W^-1 (G'Qe - Su) and its lifted operator
T = I - alpha W^-1 (G'QG + S)), both QP forms (stage form through HPIPM, lifted form through
OSQP) and the unconstrained NormOptimalLaw (dense and Riccati); with active input and output
bounds the QP's solution is cvxpy's on the dense form above. Properties: for any alpha in
(0, 1] the step lowers the norm-optimal cost J, and alpha scales the unconstrained step.
"""

from __future__ import annotations

import control
import cvxpy as cp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import DesignFileError, ParameterError
from ilc_analysis.laws import (
    ConstrainedNormOptimalLaw,
    NormOptimalLaw,
    describe_law,
    law_from_description,
)
from ilc_analysis.problem import ILCProblem

N, TS = 24, 0.1
PLANT = control.ss([[0.0, 1.0], [-2.0, -0.8]], [[0.0], [1.0]], [[1.0, 0.0]], 0.0)
PROBLEM = ILCProblem(PLANT, ts=TS, N=N, reference=np.sin(np.arange(N) / 4.0)[:, None])
QW, RW, SW = 50.0, 0.02, 0.5


def _numpy_G(problem) -> np.ndarray:
    """The lifted G from the sampled plant's matrices: block (j, k) = C A^(j+s-1-k) B."""
    A, B, C, D = (np.asarray(M, float) for M in problem.dplant.matrices[:4])
    s = problem.shift
    h = [D] + [C @ np.linalg.matrix_power(A, k - 1) @ B for k in range(1, N + s)]
    G = np.zeros((N, N))
    for j in range(N):
        for k in range(j + s + 1):
            if k < N:
                G[j, k] = h[j + s - k][0, 0]
    return G


G = _numpy_G(PROBLEM)
W = QW * G.T @ G + (RW + SW) * np.eye(N)


def _trial(seed: int = 0):
    rng = np.random.default_rng(seed)
    return 0.2 * rng.normal(size=(N, 1)), rng.normal(size=(N, 1))


def _closed_form(u, e, alpha, S=SW):
    Wa = QW * G.T @ G + (RW + S) * np.eye(N)
    return u.ravel() + alpha * np.linalg.solve(Wa, QW * G.T @ e.ravel() - S * u.ravel())


def _cost(u, e, v, S=SW):
    """The norm-optimal cost J(v) = ||e - G(v - u)||_Q^2 + ||v||_S^2 + ||v - u||_R^2."""
    d = v - u.ravel()
    return (QW * np.sum((e.ravel() - G @ d) ** 2) + S * np.sum(v ** 2) + RW * np.sum(d ** 2))


def test_the_numpy_model_is_the_problems_lifting():
    assert np.max(np.abs(G - PROBLEM.lifted.G)) <= 1e-12 * np.max(np.abs(G))


# ---------------------------------------------------------------------------------------------
# known answers: the unconstrained step in closed form
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("alpha", [0.25, 0.6, 1.0])
@pytest.mark.parametrize("form", ["stages", "lifted"])
def test_unconstrained_step_is_the_closed_form(form, alpha):
    u, e = _trial()
    model = PROBLEM if form == "stages" else PROBLEM.lifted
    law = ConstrainedNormOptimalLaw(model, QW, RW, weight_input=SW, step_size=alpha,
                                    tolerance=1e-11,
                                    **({} if form == "stages" else {"solver": "osqp"}))
    got = law.update(u, e, TS).ravel()
    want = _closed_form(u, e, alpha)
    assert np.max(np.abs(got - want)) <= 1e-7 * np.max(np.abs(want))
    cert = law.history[-1]
    # the certificate: J(u_i) before, J_alpha at the step after (numpy)
    J0 = QW * np.sum(e ** 2) + SW * np.sum(u ** 2)
    d = want - u.ravel()
    J_alpha = J0 + 2 * alpha * (SW * u.ravel() - QW * G.T @ e.ravel()) @ d + d @ W @ d
    assert cert.cost_before == pytest.approx(J0, rel=1e-12)
    assert cert.cost_after == pytest.approx(J_alpha, rel=1e-7)
    assert cert.predicted_decrease > 0


@pytest.mark.parametrize("alpha", [0.3, 1.0])
def test_norm_optimal_law_with_step_size_is_the_closed_form(alpha):
    u, e = _trial(1)
    want = _closed_form(u, e, alpha)
    T_want = np.eye(N) - alpha * np.linalg.solve(W, QW * G.T @ G + SW * np.eye(N))
    dense = NormOptimalLaw(PROBLEM.lifted, RW, QW, SW, step_size=alpha)
    riccati = NormOptimalLaw.from_problem(PROBLEM, RW, QW, SW, step_size=alpha)
    for law in (dense, riccati):
        assert np.max(np.abs(law.update(u, e, TS).ravel() - want)) <= 1e-9
    assert np.max(np.abs(dense.lifted(PROBLEM.lifted).operator(G) - T_want)) <= 1e-10
    ops = riccati.lifted_operators(PROBLEM.lifted_plant)
    T_ops = ops.operator(PROBLEM.lifted_plant.G)
    assert np.max(np.abs(T_ops.matvec(np.eye(N)) - T_want)) <= 1e-9


def test_the_lifted_form_of_the_constrained_law_carries_alpha_and_s():
    law = ConstrainedNormOptimalLaw(PROBLEM, QW, RW, weight_input=SW, step_size=0.4)
    T_want = np.eye(N) - 0.4 * np.linalg.solve(W, QW * G.T @ G + SW * np.eye(N))
    assert np.max(np.abs(law.lifted(PROBLEM.lifted).operator(G) - T_want)) <= 1e-10


# ---------------------------------------------------------------------------------------------
# known answers: active bounds, against cvxpy on the dense projected Newton step
# ---------------------------------------------------------------------------------------------
def _cvxpy_projected_step(u, e, alpha, lower, upper, y_lo=None, y_hi=None):
    """argmin (v-u)'W(v-u) + 2 alpha (v-u)'g over the bounds (Clarabel, tight tolerances)."""
    v = cp.Variable(N)
    d = v - u.ravel()
    g = SW * u.ravel() - QW * G.T @ e.ravel()
    cons = [v >= lower, v <= upper]
    if y_lo is not None:
        y_next = PROBLEM.reference.ravel() - (e.ravel() - G @ d)
        cons += [y_next >= y_lo, y_next <= y_hi]
    cp.Problem(cp.Minimize(cp.quad_form(d, W, assume_PSD=True) + 2 * alpha * g @ d),
               cons).solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12,
                           tol_feas=1e-12)
    return v.value


@pytest.mark.parametrize("alpha", [0.5, 1.0])
@pytest.mark.parametrize("form", ["stages", "lifted"])
def test_active_input_and_output_bounds_match_cvxpy(form, alpha):
    u, e = _trial(2)
    u = np.clip(u, -0.3, 0.3)
    upper = 0.5 * np.max(np.abs(_closed_form(u, e, alpha)))   # binds the unconstrained step
    # per-sample output bounds halfway between this trial's output and the next one's under
    # the input bounds alone, where that one rises: they bind, and u_i stays admissible
    y_now = PROBLEM.reference.ravel() - e.ravel()
    v_in = _cvxpy_projected_step(u, e, alpha, -upper, upper)
    y_in = y_now + G @ (v_in - u.ravel())
    y_hi = np.where(y_in > y_now + 1e-3, 0.5 * (y_now + y_in), y_now + 10.0)
    y_lo = y_now - 10.0
    model = PROBLEM if form == "stages" else PROBLEM.lifted
    law = ConstrainedNormOptimalLaw(
        model, QW, RW, weight_input=SW, step_size=alpha, input_bounds=(-upper, upper),
        output_bounds=(y_lo[:, None], y_hi[:, None]), reference=PROBLEM.reference,
        tolerance=1e-10, **({} if form == "stages" else {"solver": "osqp"}))
    got = law.update(u, e, TS).ravel()
    want = _cvxpy_projected_step(u, e, alpha, -upper, upper, y_lo, y_hi)
    y_want = y_now + G @ (want - u.ravel())
    assert np.sum(np.abs(want) >= upper - 1e-6) >= 1          # an input bound is active
    assert np.sum(y_want >= y_hi - 1e-6) >= 1                  # an output bound is active
    assert np.max(np.abs(got - want)) <= 1e-5 * upper
    cert = law.history[-1]
    assert cert.status == "solved"
    assert cert.predicted_violation["input"] == 0.0
    assert cert.predicted_violation["output"] == 0.0


# ---------------------------------------------------------------------------------------------
# properties
# ---------------------------------------------------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(alpha=st.floats(0.02, 1.0), S=st.floats(0.0, 5.0), seed=st.integers(0, 2**16))
def test_any_step_size_lowers_the_norm_optimal_cost_and_scales_the_step(alpha, S, seed):
    u, e = _trial(seed)
    law = NormOptimalLaw(PROBLEM.lifted, RW, QW, S, step_size=alpha)
    full = NormOptimalLaw(PROBLEM.lifted, RW, QW, S)
    v = law.update(u, e, TS).ravel()
    v_full = full.update(u, e, TS).ravel()
    scale = 1.0 + np.max(np.abs(v_full - u.ravel()))
    assert np.max(np.abs((v - u.ravel()) - alpha * (v_full - u.ravel()))) <= 1e-9 * scale
    assert _cost(u, e, v, S) <= _cost(u, e, u.ravel(), S) * (1 + 1e-12)


@settings(max_examples=12, deadline=None)
@given(alpha=st.floats(0.05, 1.0), bound=st.floats(0.02, 0.5), seed=st.integers(0, 2**16))
def test_a_constrained_step_stays_within_its_bounds_and_lowers_the_cost(alpha, bound, seed):
    u, e = _trial(seed)
    u = np.clip(u, -bound, bound)
    law = ConstrainedNormOptimalLaw(PROBLEM, QW, RW, weight_input=SW, step_size=alpha,
                                    input_bounds=(-bound, bound))
    v = law.update(u, e, TS).ravel()
    assert np.max(np.abs(v)) <= bound
    cert = law.history[-1]
    assert cert.predicted_decrease >= -1e-7 * cert.cost_before
    # projected Newton step of length alpha <= 1 in the W-norm: J itself does not grow
    assert _cost(u, e, v) <= _cost(u, e, u.ravel()) * (1 + 1e-7)


# ---------------------------------------------------------------------------------------------
# descriptions and errors
# ---------------------------------------------------------------------------------------------
def test_describe_round_trip_keeps_the_step_size_and_the_input_weight():
    law = ConstrainedNormOptimalLaw(PROBLEM, QW, RW, weight_input=SW, step_size=0.5,
                                    input_bounds=(-2.0, 2.0))
    d = describe_law(law)
    assert (d["step_size"], d["weight_input"]) == (0.5, SW)
    again = law_from_description(d, PROBLEM)
    assert describe_law(again) == d
    no = NormOptimalLaw(PROBLEM.lifted, RW, QW, SW, step_size=0.25)
    assert describe_law(law_from_description(describe_law(no), PROBLEM)) == describe_law(no)
    plain = describe_law(ConstrainedNormOptimalLaw(PROBLEM, QW, RW))
    assert "step_size" not in plain and "weight_input" not in plain


@pytest.mark.parametrize("step_size", [0.0, -0.5, 1.5, float("nan"), True, "half"])
def test_a_bad_step_size_is_refused_naming_it(step_size):
    with pytest.raises(ParameterError, match="step_size"):
        ConstrainedNormOptimalLaw(PROBLEM, QW, RW, step_size=step_size)
    with pytest.raises(ParameterError, match="step_size"):
        NormOptimalLaw(PROBLEM.lifted, RW, step_size=step_size)


def test_a_negative_input_weight_is_refused_naming_it():
    with pytest.raises(ParameterError, match=r"weight_input \(S\)"):
        ConstrainedNormOptimalLaw(PROBLEM, QW, RW, weight_input=-1.0)


def test_design_file_errors_name_the_key():
    d = describe_law(ConstrainedNormOptimalLaw(PROBLEM, QW, RW))
    with pytest.raises(DesignFileError, match=r"\[law\]\.step_size"):
        law_from_description({**d, "step_size": 2.0}, PROBLEM)
    no = describe_law(NormOptimalLaw(PROBLEM.lifted, RW))
    with pytest.raises(DesignFileError, match=r"\[law\]\.step_size"):
        law_from_description({**no, "step_size": 0.0}, PROBLEM)


def test_the_analysis_judges_a_shorter_step_by_its_own_operator():
    # the structural proof of error_norm_2 is for the full step; alpha < 1 is judged by the
    # computed ||T_e||_2 of T_e = I - alpha G (G'QG + R)^-1 G'Q (numpy)
    from ilc_analysis import analyze

    alpha = 0.5
    an = analyze(PROBLEM, NormOptimalLaw(PROBLEM.lifted, RW, QW, step_size=alpha), horizon=20)
    Te = np.eye(N) - alpha * G @ np.linalg.solve(QW * G.T @ G + RW * np.eye(N), QW * G.T)
    cond = an["error_norm_2"]
    assert cond.details.get("proof") != "structure"
    assert cond.value == pytest.approx(np.linalg.norm(Te, 2), rel=1e-8)
    assert cond.verdict == "holds"
    T = np.eye(N) - alpha * np.linalg.solve(QW * G.T @ G + RW * np.eye(N), QW * G.T @ G)
    assert an["norm_2"].value == pytest.approx(np.linalg.norm(T, 2), rel=1e-8)
