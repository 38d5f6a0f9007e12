"""Constrained norm-optimal ILC (issue 14, first part): a QP per trial through CasADi.

Known answers: with inactive bounds the update is NormOptimalLaw's (1e-9, at a solver tolerance
of 1e-11: the default 1e-8 gives ~1e-8); with active input
(and rate) bounds the QP's solution is cvxpy's on the same problem (1e-6), for every CasADi
plugin; the lifted form is the unconstrained law. Bad input names the parameter; an unreachable
output bound is an infeasible status naming the bound, channel and sample. A simulated run keeps
every trial's applied input within its bounds.
"""

from __future__ import annotations

import control
import cvxpy as cp
import numpy as np
import pytest

from ilc_analysis.exceptions import DesignFileError, ParameterError, ShapeError
from ilc_analysis.laws import (
    ConstrainedNormOptimalLaw,
    InfeasibleTrialError,
    NormOptimalLaw,
    describe_law,
    law_from_description,
)
from ilc_analysis.problem import ILCProblem
from ilc_analysis.simulation import simulate

N, TS = 30, 0.05
# two inputs, two coupled outputs (two damped oscillators), discretised with ZOH by ILCProblem
PLANT2 = control.ss([[0.0, 1.0, 0.0, 0.0], [-1.0, -1.2, 0.3, 0.0],
                     [0.0, 0.0, 0.0, 1.0], [0.2, 0.0, -2.0, -1.5]],
                    [[0.0, 0.0], [1.0, 0.2], [0.0, 0.0], [0.1, 1.5]],
                    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]], 0.0)
PLANT1 = control.tf([1.0], [1.0, 1.0, 1.0])
WE, WD = 1.0, 0.01


def _reference(n_y: int, amplitude: float = 1.0) -> np.ndarray:
    t = TS * np.arange(N)
    return amplitude * np.column_stack(
        [np.sin(2 * np.pi * t / (N * TS) + c) for c in range(n_y)])


PROBLEM2 = ILCProblem(PLANT2, ts=TS, N=N, reference=_reference(2))
LS2 = PROBLEM2.lifted


def _first_trial(problem):
    u0 = problem.initial_input()
    y = (problem.lifted.G @ u0.reshape(-1) + problem.lifted.d).reshape(N, problem.n_y)
    return u0, problem.reference - y


def _cvxpy_step(ls, u, e, lower, upper, rate=None):
    """The same QP in cvxpy (Clarabel, tight tolerances)."""
    du = cp.Variable(u.size)
    unew = u.reshape(-1) + du
    cost = WE * cp.sum_squares(e.reshape(-1) - ls.G @ du) + WD * cp.sum_squares(du)
    cons = [unew >= np.tile(lower, N), unew <= np.tile(upper, N)]
    if rate is not None:
        n_u = u.shape[1]
        cons += [cp.abs(unew[n_u:] - unew[:-n_u]) <= rate]
    cp.Problem(cp.Minimize(cost), cons).solve(solver=cp.CLARABEL, tol_gap_abs=1e-12,
                                              tol_gap_rel=1e-12, tol_feas=1e-12)
    return unew.value.reshape(u.shape)


# ---------------------------------------------------------------------------------------------
# known answers
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("solver", ["osqp", "qpoases", "proxqp"])
def test_inactive_bounds_equal_norm_optimal(solver):
    u0, e0 = _first_trial(PROBLEM2)
    law = ConstrainedNormOptimalLaw(LS2, WE, WD, input_bounds=(-1e3, 1e3), rate_bounds=1e3,
                                    output_bounds=(-1e3, 1e3), reference=PROBLEM2.reference,
                                    solver=solver, tolerance=1e-11)
    want = NormOptimalLaw(LS2, weight_input_change=WD, weight_error=WE).update(u0, e0, TS)
    got = law.update(u0, e0, TS)
    assert np.max(np.abs(got - want)) <= 1e-9
    cert = law.history[-1]
    assert cert.status == "solved" and cert.trial == 0
    assert all(v == 0.0 for v in cert.measured_violation.values())
    assert all(v <= 1e-9 for v in cert.predicted_violation.values())
    # the certificate's cost is the unconstrained optimum's
    e1 = e0.reshape(-1) - LS2.G @ (want - u0).reshape(-1)
    j = WE * e1 @ e1 + WD * np.sum((want - u0) ** 2)
    assert cert.cost_after == pytest.approx(j, rel=1e-8)
    assert cert.predicted_decrease > 0


@pytest.mark.parametrize("solver", ["osqp", "qpoases", "proxqp"])
def test_active_input_bounds_match_cvxpy(solver):
    u0, e0 = _first_trial(PROBLEM2)
    free = NormOptimalLaw(LS2, weight_input_change=WD, weight_error=WE).update(u0, e0, TS)
    lower, upper = np.array([-0.5, -0.4]), np.array([0.5, 0.6])
    assert np.any(free < lower) and np.any(free > upper)      # the bounds bind
    law = ConstrainedNormOptimalLaw(LS2, WE, WD, input_bounds=(lower, upper), solver=solver)
    got = law.update(u0, e0, TS)
    want = _cvxpy_step(LS2, u0, e0, lower, upper)
    assert np.max(np.abs(got - want)) <= 1e-6
    assert np.sum(np.isclose(got, np.tile(upper, (N, 1)), atol=1e-7)) >= 1


def test_active_rate_bounds_match_cvxpy():
    u0, e0 = _first_trial(PROBLEM2)
    lower, upper = np.array([-0.5, -0.4]), np.array([0.5, 0.6])
    law = ConstrainedNormOptimalLaw(LS2, WE, WD, input_bounds=(lower, upper), rate_bounds=0.05)
    got = law.update(u0, e0, TS)
    want = _cvxpy_step(LS2, u0, e0, lower, upper, rate=0.05)
    assert np.max(np.abs(got - want)) <= 1e-6
    assert np.max(np.abs(np.diff(got, axis=0))) == pytest.approx(0.05, abs=1e-7)   # it binds


@pytest.mark.parametrize("problem", [PROBLEM2, ILCProblem(PLANT1, ts=TS, N=N,
                                                            reference=_reference(1))])
def test_state_space_form_equals_the_lifted_form(problem):
    """The banded QP (plant's states) and the QP with G give the same step (1e-7, both solved
    by qpOASES, an active-set method: two different but equivalent QPs)."""
    u0, e0 = _first_trial(problem)
    kw = {"input_bounds": (-0.5, 0.5), "rate_bounds": 0.1, "solver": "qpoases"}
    with_g = ConstrainedNormOptimalLaw(problem.lifted, WE, WD, **kw)
    with_x = ConstrainedNormOptimalLaw(problem.lifted, WE, WD, plant=problem.dplant, **kw)
    a, b = with_g.update(u0, e0, TS), with_x.update(u0, e0, TS)
    assert np.max(np.abs(a - b)) <= 1e-7
    assert with_x.history[-1].cost_after == pytest.approx(with_g.history[-1].cost_after,
                                                          rel=1e-7)


def test_plant_that_is_not_the_model_is_refused():
    other = ILCProblem(PLANT2 * 2.0, ts=TS, N=N, reference=_reference(2))
    with pytest.raises(ParameterError, match=r"plant does not match model"):
        ConstrainedNormOptimalLaw(LS2, WE, WD, plant=other.dplant)


def test_lifted_is_the_unconstrained_norm_optimal_law():
    law = ConstrainedNormOptimalLaw(LS2, WE, WD, input_bounds=(-0.5, 0.5))
    lifted = law.lifted(LS2)
    ref = NormOptimalLaw(LS2, weight_input_change=WD, weight_error=WE).lifted(LS2)
    np.testing.assert_array_equal(lifted.L1, ref.L1)
    assert lifted.Q is None and "UNCONSTRAINED" in lifted.description


def test_describe_round_trip_through_the_registry():
    law = ConstrainedNormOptimalLaw(LS2, [1.0, 2.0], 0.1, input_bounds={"upper": [0.5, 0.6]},
                                    rate_bounds=[0.1, 0.2], output_bounds=(-2.0, 2.0),
                                    reference=PROBLEM2.reference, solver="proxqp")
    again = law_from_description(describe_law(law), PROBLEM2)
    assert isinstance(again, ConstrainedNormOptimalLaw)
    assert again.describe() == law.describe()
    assert describe_law(law)["kind"] == "constrained-norm-optimal"


# ---------------------------------------------------------------------------------------------
# infeasible and bad input
# ---------------------------------------------------------------------------------------------
def test_unreachable_output_bound_is_an_infeasible_status_naming_it():
    u0, e0 = _first_trial(PROBLEM2)
    lower = np.full((N, 2), -np.inf)
    lower[20, 1] = 5.0                  # y1 >= 5 at window sample 20, inputs within +-0.5
    law = ConstrainedNormOptimalLaw(LS2, WE, WD, input_bounds=(-0.5, 0.5),
                                    output_bounds=(lower, None), reference=PROBLEM2.reference)
    u_next, cert = law.solve(u0, e0)
    assert u_next is None and cert.status == "infeasible"
    assert "output_bounds lower bound 5 on channel 1" in cert.binding
    assert "window sample 20" in cert.binding
    with pytest.raises(InfeasibleTrialError, match=r"infeasible: output_bounds lower bound 5 "
                                                   r"on channel 1 .* window sample 20"):
        law.update(u0, e0, TS)
    assert [c.status for c in law.history] == ["infeasible", "infeasible"]


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"input_bounds": (1.0, -1.0)}, ParameterError,
     r"input_bounds are inconsistent: lower > upper at sample 0, channel 0"),
    ({"output_bounds": ([0.0, 1.0], [0.5, 0.5]), "reference": np.zeros((N, 2))},
     ParameterError, r"output_bounds are inconsistent: lower > upper at sample 0, channel 1"),
    ({"input_bounds": (0.1, 1.0), "initial_input": np.zeros((N, 2))}, ParameterError,
     r"bounds exclude initial_input: input_bounds \[0.1, 1\] on channel 0"),
    ({"rate_bounds": 0.1, "initial_input": np.outer(np.arange(N), [0.0, 0.5])},
     ParameterError, r"bounds exclude initial_input: rate_bounds .* channel 1"),
    ({"weight_input_change": -1.0}, ParameterError,
     r"weight_input_change \(R\) must be positive definite"),
    ({"weight_error": np.diag(np.r_[1.0, -1.0, np.ones(2 * N - 2)])}, ParameterError,
     r"weight_error \(Q\) must be positive semi-definite"),
    ({"input_bounds": ([0.0, 0.0, 0.0], 1.0)}, ShapeError,
     r"input_bounds lower must be a scalar, shape \(2,\) per channel"),
    ({"rate_bounds": 0.0}, ParameterError, r"rate_bounds must be > 0"),
    ({"output_bounds": (-1.0, 1.0)}, ParameterError, r"output_bounds need reference"),
    ({"reference": np.zeros((N, 3))}, ShapeError, r"reference"),
    ({"input_bounds": (-1.0, 1.0, 2.0)}, ParameterError, r"input_bounds must be a pair"),
    ({"input_bounds": (np.nan, 1.0)}, ParameterError, r"input_bounds lower must not contain"),
    ({"solver": "gurobi"}, ParameterError, r"solver must be one of"),
])
def test_bad_input_names_the_parameter(kwargs, error, match):
    kw = {"weight_error": WE, "weight_input_change": WD, **kwargs}
    with pytest.raises(error, match=match):
        ConstrainedNormOptimalLaw(LS2, **kw)


def test_bad_trial_signals():
    law = ConstrainedNormOptimalLaw(LS2, WE, WD, input_bounds=(-1.0, 1.0))
    with pytest.raises(ShapeError, match=r"u_i must have shape \(30, 2\)"):
        law.update(np.zeros((N - 1, 2)), np.zeros((N - 1, 2)), TS)
    with pytest.raises(ShapeError, match=r"e_i"):
        law.update(np.zeros((N, 2)), np.zeros((N, 1)), TS)
    with pytest.raises(ParameterError, match=r"sample time"):
        law.update(np.zeros((N, 2)), np.zeros((N, 2)), 2 * TS)


def test_design_file_errors_name_the_key():
    base = describe_law(ConstrainedNormOptimalLaw(LS2, WE, WD))
    with pytest.raises(DesignFileError, match=r"\[law\]: input_bounds are inconsistent"):
        law_from_description({**base, "input_bounds": {"lower": 1.0, "upper": 0.0}}, PROBLEM2)
    with pytest.raises(DesignFileError, match=r"\[law\].input_bounds: unknown key"):
        law_from_description({**base, "input_bounds": {"low": 1.0}}, PROBLEM2)
    with pytest.raises(DesignFileError, match=r"\[law\]: the bounds exclude initial_input"):
        law_from_description({**base, "input_bounds": {"lower": 0.2}}, PROBLEM2)


# ---------------------------------------------------------------------------------------------
# a simulated run
# ---------------------------------------------------------------------------------------------
def test_simulated_trials_keep_the_input_within_its_bounds():
    problem = ILCProblem(PLANT1, ts=TS, N=N, reference=_reference(1, amplitude=0.1))
    lower, upper, rate = -1.0, 1.5, 0.3
    K = 6
    free = simulate(problem, NormOptimalLaw(problem.lifted, weight_input_change=WD), K)
    u_free = free.dataset["u"].values
    assert u_free.max() > upper and u_free.min() < lower          # unconstrained: beyond them
    assert np.max(np.abs(np.diff(u_free, axis=1))) > rate
    law = ConstrainedNormOptimalLaw(problem.lifted, WE, WD, input_bounds=(lower, upper),
                                    rate_bounds=rate, initial_input=problem.initial_input())
    res = simulate(problem, law, K)
    u = res.dataset["u"].values                      # the applied input, every trial
    assert u.shape == (K, N, 1)
    tol = 1e-9
    assert u.min() >= lower and u.max() <= upper        # the real bounds, no tolerance
    assert np.max(np.abs(np.diff(u, axis=1))) <= rate
    # the bounds bind: the rate bound and one of the input bounds are reached
    assert np.max(np.abs(np.diff(u, axis=1))) > rate - 1e-6
    assert u.max() > upper - 1e-6 or u.min() < lower + 1e-6
    # one certificate per update; the measured trials satisfy the bounds, costs decrease
    assert [c.trial for c in law.history] == list(range(K))   # simulate also builds trial K+1
    for c in law.history:
        assert c.status == "solved"
        assert max(c.measured_violation.values()) <= tol
        assert max(c.predicted_violation.values()) <= tol
        assert c.predicted_decrease >= -1e-9
    e_norm = res.dataset["e_norm"].values
    assert e_norm[-1] < 0.5 * e_norm[0]


def test_measured_trial_outside_the_bounds_is_reported_not_hidden():
    """A measured trial (e.g. an input the machine clipped differently) beyond the bounds is
    recorded in the certificate; the next input is the QP's, within them."""
    u0, e0 = _first_trial(PROBLEM2)
    law = ConstrainedNormOptimalLaw(LS2, WE, WD, input_bounds=(-0.5, 0.5), rate_bounds=0.1,
                                    output_bounds=(None, 1.5), reference=PROBLEM2.reference)
    u_bad = u0.copy()
    u_bad[10, 1] = 0.8                                   # 0.3 above the bound, a 0.8 step
    y_bad = PROBLEM2.reference - e0
    y_bad[25, 0] = 1.6                                   # 0.1 above the output bound
    u_next = law.update(u_bad, PROBLEM2.reference - y_bad, TS)
    measured = law.history[-1].measured_violation
    assert measured["input"] == pytest.approx(0.3)
    assert measured["rate"] == pytest.approx(0.7)
    assert measured["output"] == pytest.approx(0.1)
    assert law.history[-1].predicted_violation["output"] <= 1e-7
    assert np.max(np.abs(u_next)) <= 0.5
