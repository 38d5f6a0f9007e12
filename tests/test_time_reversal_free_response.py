"""Issue 24 item 6: the time-reversal law's extra experiments run on the plant, so its free
response (initial state, known disturbance) enters the measured gradient. The analysis models
it (an affine update, ``LiftedLaw.parts['offset']``) and its error floor is the simulated
limit; ``free_response`` (the measured free response, or ``'paired'``) removes it."""

from __future__ import annotations

import control
import numpy as np
import pytest

from ilc_analysis.analysis._law_analysis import analyze
from ilc_analysis.laws import TimeReversalLaw
from ilc_analysis.laws._gradient import adjoint_blocks, gradient_step_bound
from ilc_analysis.problem import ILCProblem
from ilc_analysis.simulation import simulate


def _problem(ts: float, N: int = 15) -> ILCProblem:
    """1/(s+1), not at rest (x0 = 1), the issue's case."""
    y_d = np.sin(np.linspace(0.0, 2.0, N))[:, None]
    return ILCProblem(control.tf([1.0], [1.0, 1.0]), ts=ts, N=N, reference=y_d, x0=[1.0],
                      name="first order, x0 = 1")


def _error_norms(problem, law, iterations: int) -> np.ndarray:
    e = simulate(problem, law, iterations).dataset["e"].values
    return np.linalg.norm(e.reshape(e.shape[0], -1), axis=1)


def _floor_by_numpy(problem, beta: float, f=None) -> np.ndarray:
    """e_inf = -G (beta G^T G)^-1 c, c = beta J (d - f) (SISO, G invertible): independent of the
    package's floor code."""
    G = np.asarray(problem.lifted.G)
    d = np.asarray(problem.lifted.d)
    rest = d if f is None else d - f
    c = beta * rest[::-1]
    return -G @ np.linalg.solve(beta * G.T @ G, c)


def test_the_issue_case_ends_above_the_first_error_and_the_analysis_says_so():
    """ts = 0.1: the simulation ends ~4x above the first trial's error; the analysis said
    'converges monotonically, no error floor' (floor 'not applicable')."""
    problem = _problem(0.1)
    beta = 0.5 * gradient_step_bound(problem.lifted)
    res = analyze(problem, TimeReversalLaw(beta))
    floor = res["error_floor"]
    assert floor.verdict == "fails"
    assert floor.details["ratio_to_initial"] > 1.0
    assert "BUT it converges to an error" in res.summary()
    np.testing.assert_allclose(floor.value, np.linalg.norm(_floor_by_numpy(problem, beta)),
                               rtol=1e-8)
    norms = _error_norms(problem, TimeReversalLaw(beta), 40)
    assert norms[-1] > 2.0 * norms[0]                     # the simulation does end above it


def test_predicted_floor_is_the_simulated_limit():
    """ts = 0.5 (||T||_2 = 0.93): after 400 trials the simulated error is the predicted floor."""
    problem = _problem(0.5)
    beta = 0.5 * gradient_step_bound(problem.lifted)
    law = TimeReversalLaw(beta)
    res = analyze(problem, law)
    e_limit = simulate(problem, law, 400).dataset["e"].values[-1].reshape(-1)
    expected = _floor_by_numpy(problem, beta)
    np.testing.assert_allclose(e_limit, expected, rtol=1e-7, atol=1e-9)
    assert res["error_floor"].value == pytest.approx(np.linalg.norm(e_limit), rel=1e-7)
    assert res["error_floor"].verdict != "not applicable"


@pytest.mark.parametrize("compensation", ["measured", "paired"])
def test_free_response_compensation_gives_zero_floor(compensation):
    problem = _problem(0.5)
    beta = 0.5 * gradient_step_bound(problem.lifted)
    fr = (np.asarray(problem.lifted.d).reshape(problem.N, 1) if compensation == "measured"
          else "paired")
    law = TimeReversalLaw(beta, free_response=fr)
    res = analyze(problem, law)
    assert res["error_floor"].value == 0.0
    assert res["error_floor"].verdict == "not applicable"
    assert not np.any(law.experiment_offset(problem.lifted))
    norms = _error_norms(problem, law, 400)
    assert norms[-1] < 1e-6 * norms[0]


def test_offset_is_what_update_measures_mimo():
    """MIMO: the constant of experiment_offset is exactly what update adds beyond beta R(G) e
    when each experiment returns G v + d (the lifted plant with its free response)."""
    A = np.array([[0.6, 0.1, 0.0], [0.0, 0.3, 0.2], [0.1, 0.0, 0.5]])
    B = np.array([[1.0, 0.0], [0.2, 1.0], [0.0, 0.3]])
    C = np.array([[1.0, 0.0, 0.2], [0.0, 1.0, 0.0]])
    sys = control.ss(A, B, C, np.zeros((2, 2)), 0.1)
    N = 6
    y_d = np.column_stack([np.linspace(0, 1, N), np.cos(np.linspace(0, 1, N))])
    problem = ILCProblem(sys, ts=0.1, N=N, reference=y_d, x0=[1.0, -0.5, 0.3])
    ls = problem.lifted
    G, d = np.asarray(ls.G), np.asarray(ls.d)
    rng = np.random.default_rng(3)
    u = rng.standard_normal((N, 2))
    e = rng.standard_normal((N, 2))
    f = rng.standard_normal((N, 2))
    for law in (TimeReversalLaw(0.3), TimeReversalLaw(0.3, free_response=f)):
        new = law.update(u, e, 0.1, experiment=lambda v: (G @ v.reshape(-1) + d).reshape(N, 2))
        linear = u.reshape(-1) + 0.3 * adjoint_blocks(G, 2, 2) @ e.reshape(-1)
        c = new.reshape(-1) - linear
        np.testing.assert_allclose(c, law.experiment_offset(ls), rtol=1e-12, atol=1e-12)
        # known answer: c(t, j) = beta sum_i (d - f)(N-1-t, i) for each input j
        rest = d.reshape(N, 2) - (0.0 if law.free_response is None else f)
        expected = 0.3 * np.repeat(rest[::-1].sum(axis=1)[:, None], 2, axis=1)
        np.testing.assert_allclose(c.reshape(N, 2), expected, rtol=1e-12, atol=1e-12)
        # and the lifted law's next_input is the same affine map
        lifted = law.lifted(ls)
        r = problem.r
        np.testing.assert_allclose(
            lifted.next_input(G, u.reshape(-1), r),
            law.update(u, (r - G @ u.reshape(-1)).reshape(N, 2), 0.1,
                       experiment=lambda v: (G @ v.reshape(-1) + d).reshape(N, 2)).reshape(-1),
            rtol=1e-12, atol=1e-12)


def test_at_rest_no_offset_no_floor():
    """A problem at rest (d = 0): no constant term, no floor, as before."""
    y_d = np.sin(np.linspace(0.0, 2.0, 15))[:, None]
    problem = ILCProblem(control.tf([1.0], [1.0, 1.0]), ts=0.5, N=15, reference=y_d)
    law = TimeReversalLaw(0.5 * gradient_step_bound(problem.lifted))
    assert "offset" in law.lifted(problem.lifted).parts
    assert not np.any(law.experiment_offset(problem.lifted))
    assert analyze(problem, law)["error_floor"].verdict == "not applicable"
